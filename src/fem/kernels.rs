//! Element kernels of linear elasticity for P1/Q1 elements (plane strain in 2D, 3D).
//!
//! Conventions (shared with the assembler):
//! - node coordinates `coords: &[[f64; 3]]` in the node ordering of [`ElementKind`] (gmsh);
//!   z is ignored in 2D;
//! - spatial dimension `d = kind.dim()` for cells; interlaced DOFs: local dof = `a * d + i`
//!   for node `a` and component `i`;
//! - element matrices are dense row-major `(n d) x (n d)` slices, OVERWRITTEN by the kernels;
//!   element vectors have length `n d` and are also overwritten;
//! - reference elements and quadrature rules: see [`super::shape`] and [`super::quadrature`].
//!
//! Kernels do not allocate: they work on fixed-size stack arrays (at most [`MAX_NODES`] nodes,
//! [`MAX_DOFS`] dofs) and read shape values / reference gradients at the quadrature points from
//! tables cached once per `(kind, order)` in `OnceLock`s.

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use std::sync::{Mutex, OnceLock};

use super::element::ElementKind;
use super::quadrature::gauss;
use super::shape::{jacobian_det, map_gradients, shape, shape_grad_ref, surface_measure};
use crate::error::{Error, Result};

/// Largest number of nodes of a supported element (Hex8).
pub const MAX_NODES: usize = 8;
/// Largest number of element dofs (Hex8 in 3D).
pub const MAX_DOFS: usize = 24;

/// Isotropic linear elastic material: Lame parameters and density.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    pub lambda: f64,
    pub mu: f64,
    pub rho: f64,
    /// `formulation = "mixed"`. On quadrilaterals and hexahedra the mean-dilatation (Q1/P0)
    /// form: the volumetric strain of the `lambda` term is its cell average, the constant
    /// pressure `p = lambda theta_bar` condensed cell by cell ([`stiffness`]). On triangles and
    /// tetrahedra the averaged nodal pressure, assembled over node patches
    /// (`assembly::nodal_pressure`; the cell kernel leaves them as they are).
    pub mean_dilatation: bool,
}

impl Material {
    /// From Young's modulus `e`, Poisson's ratio `nu` and density `rho`:
    /// lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu)).
    /// (The same Lame parameters serve 3D and 2D plane strain.) No validation: nu = 1/2 gives
    /// an infinite lambda; callers validate the scene values.
    pub fn from_young_poisson(e: f64, nu: f64, rho: f64) -> Material {
        Material {
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: e / (2.0 * (1.0 + nu)),
            rho,
            mean_dilatation: false,
        }
    }

    /// Pressure and shear wave speeds (c_p, c_s) = (sqrt((lambda + 2 mu)/rho), sqrt(mu/rho)).
    pub fn wave_speeds(&self) -> (f64, f64) {
        (((self.lambda + 2.0 * self.mu) / self.rho).sqrt(), (self.mu / self.rho).sqrt())
    }
}

// ---------------------------------------------------------------------------------------------
// Cached reference tables.

/// Quadrature points, weights, shape values and reference gradients of one `(kind, order)`.
pub(super) struct Table {
    pub(super) xi: Vec<[f64; 3]>,
    pub(super) w: Vec<f64>,
    pub(super) n: Vec<[f64; MAX_NODES]>,
    pub(super) dn: Vec<[[f64; 3]; MAX_NODES]>,
}

const MAX_CACHED_ORDER: usize = 16;
type Row = [OnceLock<Table>; MAX_CACHED_ORDER + 1];
static TABLES: [Row; 6] = [const { [const { OnceLock::new() }; MAX_CACHED_ORDER + 1] }; 6];
/// Orders above `MAX_CACHED_ORDER`: built once per key and leaked (bounded by the number of
/// distinct orders used).
static EXTRA: Mutex<Vec<(ElementKind, usize, &'static Table)>> = Mutex::new(Vec::new());

fn kind_index(kind: ElementKind) -> usize {
    match kind {
        ElementKind::Point1 => 0,
        ElementKind::Line2 => 1,
        ElementKind::Tri3 => 2,
        ElementKind::Quad4 => 3,
        ElementKind::Tet4 => 4,
        ElementKind::Hex8 => 5,
    }
}

fn build_table(kind: ElementKind, order: usize) -> Table {
    let rule = gauss(kind, order);
    let mut t = Table {
        xi: Vec::with_capacity(rule.len()),
        w: Vec::with_capacity(rule.len()),
        n: Vec::with_capacity(rule.len()),
        dn: Vec::with_capacity(rule.len()),
    };
    for (xi, w) in rule {
        let mut n = [0.0; MAX_NODES];
        let mut dn = [[0.0; 3]; MAX_NODES];
        shape(kind, xi, &mut n);
        shape_grad_ref(kind, xi, &mut dn);
        t.xi.push(xi);
        t.w.push(w);
        t.n.push(n);
        t.dn.push(dn);
    }
    t
}

pub(super) fn table(kind: ElementKind, order: usize) -> &'static Table {
    if order <= MAX_CACHED_ORDER {
        return TABLES[kind_index(kind)][order].get_or_init(|| build_table(kind, order));
    }
    let mut extra = EXTRA.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(&(_, _, t)) = extra.iter().find(|(k, o, _)| *k == kind && *o == order) {
        return t;
    }
    let t: &'static Table = Box::leak(Box::new(build_table(kind, order)));
    extra.push((kind, order, t));
    t
}

/// Quadrature order of the stiffness rule: 1 point on simplices (exact for affine P1),
/// 2 Gauss points per direction on tensor elements.
pub(super) fn stiffness_order(kind: ElementKind) -> usize {
    match kind {
        ElementKind::Tri3 | ElementKind::Tet4 | ElementKind::Point1 => 0,
        ElementKind::Line2 | ElementKind::Quad4 | ElementKind::Hex8 => 2,
    }
}

/// Quadrature order of the mass rule: degree 2 on simplices, 2 points per direction on tensor
/// elements (exact for N_a N_b on parallelograms/parallelepipeds; also exact on any planar
/// bilinear quad since det J is then linear).
fn mass_order(_kind: ElementKind) -> usize {
    2
}

pub(super) fn check_len(what: &str, kind: ElementKind, got: usize, need: usize) {
    assert!(got >= need, "{what} for {}: slice of length {got}, need {need}", kind.name());
}

pub(super) fn inverted(kind: ElementKind, det: f64, q: usize) -> Error {
    Error::Mesh(format!(
        "inverted or degenerate {} ({kind:?}): det J = {det:e} at quadrature point {q}",
        kind.name()
    ))
}

// ---------------------------------------------------------------------------------------------
// Stiffness.

/// Element stiffness K_e = int_K B^T C B dx for isotropic C (plane strain in 2D).
///
/// In index form, for nodes a, b and components i, j < d = `kind.dim()`:
///
/// K[(a d + i), (b d + j)] = int_K lambda dN_a/dx_i dN_b/dx_j + mu dN_a/dx_j dN_b/dx_i
///                           + mu delta_ij grad N_a . grad N_b dx,
///
/// which is B^T C B with C = lambda I (x) I + 2 mu I_sym (so 1/2 u^T K u = int 1/2 sigma:eps).
/// Quadrature: 1 point on Tri3/Tet4 (exact on affine simplices), 2 Gauss points per direction
/// on Line2/Quad4/Hex8 (exact on parallelograms/parallelepipeds; full integration on
/// distorted elements). `out` has length >= (n d)^2 and is overwritten (row-major).
///
/// With `mat.mean_dilatation` (quadrilaterals and hexahedra; ignored on simplices, whose
/// strain is constant) the `lambda` term takes the cell's mean dilatation instead
/// (B-bar, the Q1/P0 element with its pressure condensed):
///
/// K[(a d + i), (b d + j)] = lambda / |K| b_a,i b_b,j + (the two mu terms),
/// b_a = int_K grad N_a dx,
///
/// the stiffness of the energy `int_K mu eps:eps dx + lambda/2 |K| theta_bar^2`,
/// `theta_bar = 1/|K| int_K div u dx`: one volumetric constraint per cell instead of one per
/// quadrature point, so no locking as `lambda/mu` grows.
///
/// Errors: `Error::Mesh("inverted or degenerate <kind> ...")` if det J <= 0 (or NaN) at a
/// quadrature point; `out` then holds garbage.
pub fn stiffness(
    kind: ElementKind,
    coords: &[[f64; 3]],
    mat: &Material,
    out: &mut [f64],
) -> Result<()> {
    match kind {
        ElementKind::Point1 => Ok(()),
        ElementKind::Line2 => stiffness_impl::<2, 1, 2>(kind, coords, mat, out),
        ElementKind::Tri3 => stiffness_impl::<3, 2, 1>(kind, coords, mat, out),
        ElementKind::Quad4 => stiffness_impl::<4, 2, 4>(kind, coords, mat, out),
        ElementKind::Tet4 => stiffness_impl::<4, 3, 1>(kind, coords, mat, out),
        ElementKind::Hex8 => stiffness_impl::<8, 3, 8>(kind, coords, mat, out),
    }
}

/// `Q` = number of quadrature points of the stiffness rule of `kind`.
#[inline(always)]
fn stiffness_impl<const N: usize, const D: usize, const Q: usize>(
    kind: ElementKind,
    coords: &[[f64; 3]],
    mat: &Material,
    out: &mut [f64],
) -> Result<()> {
    let nd = N * D;
    check_len("stiffness coords", kind, coords.len(), N);
    check_len("stiffness out", kind, out.len(), nd * nd);
    let out = &mut out[..nd * nd];
    let t = table(kind, stiffness_order(kind));
    assert_eq!(t.w.len(), Q, "stiffness rule size of {}", kind.name());
    // Physical gradients at all quadrature points, and the same scaled by w_q det J_q.
    let mut gq = [[[0.0f64; 3]; N]; Q];
    let mut gw = [[[0.0f64; 3]; N]; Q];
    for q in 0..Q {
        let mut g = t.dn[q];
        let det = map_gradients(D, N, coords, &mut g);
        if det.is_nan() || det <= 0.0 {
            return Err(inverted(kind, det, q));
        }
        let w = t.w[q] * det;
        for a in 0..N {
            for i in 0..D {
                gq[q][a][i] = g[a][i];
                gw[q][a][i] = w * g[a][i];
            }
        }
    }
    // Mean dilatation: b_a = int grad N_a and |K|.
    let mean = mat.mean_dilatation && Q > 1;
    let mut b_int = [[0.0f64; 3]; N];
    let mut volume = 0.0;
    if mean {
        for q in 0..Q {
            volume += t.w[q] * jacobian_det(D, N, coords, &t.dn[q]);
            for a in 0..N {
                for i in 0..D {
                    b_int[a][i] += gw[q][a][i];
                }
            }
        }
    }
    // For each node pair b >= a: G[i][j] = int dN_a/dx_i dN_b/dx_j dx, then
    // K_ab[i][j] = lambda G[i][j] + mu G[j][i] + mu delta_ij tr G; block (b, a) = K_ab^T.
    let (l, m) = (mat.lambda, mat.mu);
    for a in 0..N {
        for b in a..N {
            let mut gab = [[0.0f64; D]; D];
            for q in 0..Q {
                let ga = &gw[q][a];
                let gb = &gq[q][b];
                for i in 0..D {
                    for j in 0..D {
                        gab[i][j] += ga[i] * gb[j];
                    }
                }
            }
            let mut tr = 0.0;
            for k in 0..D {
                tr += gab[k][k];
            }
            for i in 0..D {
                for j in 0..D {
                    let vol =
                        if mean { l / volume * b_int[a][i] * b_int[b][j] } else { l * gab[i][j] };
                    let mut v = vol + m * gab[j][i];
                    if i == j {
                        v += m * tr;
                    }
                    out[(a * D + i) * nd + b * D + j] = v;
                    out[(b * D + j) * nd + a * D + i] = v;
                }
            }
        }
    }
    Ok(())
}

/// The divergence row of a cell, `b[a][i] = int_K dN_a/dx_i dx` (so that
/// `int_K div u dx = sum_a b_a . u_a`), into `out[..n]`; returns the measure `|K|`. With the
/// stiffness rule (exact on affine simplices, where `b_a = |K| grad N_a`). The averaged nodal
/// pressure's volumetric constraint is assembled from it (`assembly::nodal_pressure`).
///
/// Errors: `Error::Mesh("inverted or degenerate <kind> ...")` if det J <= 0 (or NaN).
pub fn divergence_row(kind: ElementKind, coords: &[[f64; 3]], out: &mut [[f64; 3]]) -> Result<f64> {
    let (n, d) = (kind.n_nodes(), kind.dim());
    check_len("divergence_row coords", kind, coords.len(), n);
    check_len("divergence_row out", kind, out.len(), n);
    let t = table(kind, stiffness_order(kind));
    out[..n].iter_mut().for_each(|b| *b = [0.0; 3]);
    let mut volume = 0.0;
    for q in 0..t.w.len() {
        let mut g = t.dn[q];
        let det = map_gradients(d, n, coords, &mut g);
        if det.is_nan() || det <= 0.0 {
            return Err(inverted(kind, det, q));
        }
        let w = t.w[q] * det;
        volume += w;
        for a in 0..n {
            for i in 0..d {
                out[a][i] += w * g[a][i];
            }
        }
    }
    Ok(volume)
}

// ---------------------------------------------------------------------------------------------
// Mass.

/// Scalar mass matrix m_ab = int_K rho N_a N_b dx (n x n, row-major into `m`); returns n.
fn scalar_mass(
    kind: ElementKind,
    coords: &[[f64; 3]],
    rho: f64,
    m: &mut [f64; MAX_NODES * MAX_NODES],
) -> usize {
    match kind {
        ElementKind::Point1 => {
            m[0] = rho;
            1
        }
        ElementKind::Line2 => scalar_mass_impl::<2, 1>(kind, coords, rho, m),
        ElementKind::Tri3 => scalar_mass_impl::<3, 2>(kind, coords, rho, m),
        ElementKind::Quad4 => scalar_mass_impl::<4, 2>(kind, coords, rho, m),
        ElementKind::Tet4 => scalar_mass_impl::<4, 3>(kind, coords, rho, m),
        ElementKind::Hex8 => scalar_mass_impl::<8, 3>(kind, coords, rho, m),
    }
}

#[inline(always)]
fn scalar_mass_impl<const N: usize, const D: usize>(
    kind: ElementKind,
    coords: &[[f64; 3]],
    rho: f64,
    m: &mut [f64; MAX_NODES * MAX_NODES],
) -> usize {
    check_len("mass coords", kind, coords.len(), N);
    let t = table(kind, mass_order(kind));
    let mut mm = [[0.0f64; N]; N];
    for q in 0..t.w.len() {
        let w = rho * t.w[q] * jacobian_det(D, N, coords, &t.dn[q]);
        let nq = &t.n[q];
        for a in 0..N {
            let wa = w * nq[a];
            for b in a..N {
                mm[a][b] += wa * nq[b];
            }
        }
    }
    for a in 0..N {
        for b in a..N {
            m[a * N + b] = mm[a][b];
            m[b * N + a] = mm[a][b];
        }
    }
    N
}

/// Consistent mass M_e = int_K rho N_a N_b dx I_d:
/// M[(a d + i), (b d + j)] = delta_ij int_K rho N_a N_b dx.
///
/// Quadrature: degree-2 rule on Tri3/Tet4 (3/4 points, exact on affine simplices),
/// 2 Gauss points per direction on Line2/Quad4/Hex8 (exact on parallelograms, parallelepipeds
/// and any planar quad; not exact on non-parallelepiped hexes). The sign of det J is not
/// checked here (use [`stiffness`] or [`min_det_jacobian`]). `out` (length >= (n d)^2) is
/// overwritten.
pub fn mass(kind: ElementKind, coords: &[[f64; 3]], rho: f64, out: &mut [f64]) {
    let mut m = [0.0; MAX_NODES * MAX_NODES];
    let n = scalar_mass(kind, coords, rho, &mut m);
    let d = kind.dim();
    let nd = n * d;
    check_len("mass out", kind, out.len(), nd * nd);
    out[..nd * nd].fill(0.0);
    for a in 0..n {
        for b in 0..n {
            let v = m[a * n + b];
            for i in 0..d {
                out[(a * d + i) * nd + b * d + i] = v;
            }
        }
    }
}

/// The node block of [`mass`]: `m[a n + b] = int_K rho N_a N_b dx` (`n x n`, row-major;
/// `mass = m ⊗ I_d`). `out` (length >= n^2) is overwritten.
pub fn mass_nodes(kind: ElementKind, coords: &[[f64; 3]], rho: f64, out: &mut [f64]) {
    let mut m = [0.0; MAX_NODES * MAX_NODES];
    let n = scalar_mass(kind, coords, rho, &mut m);
    check_len("mass_nodes out", kind, out.len(), n * n);
    out[..n * n].copy_from_slice(&m[..n * n]);
}

/// The node block of [`mass_lumped`]: `int_K rho N_a dx` on the diagonal of an `n x n` block
/// (row-major). `out` (length >= n^2) is overwritten.
pub fn mass_lumped_nodes(kind: ElementKind, coords: &[[f64; 3]], rho: f64, out: &mut [f64]) {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("mass_lumped_nodes out", kind, out.len(), n * n);
    let mut diag = [0.0; MAX_DOFS];
    mass_lumped_diag(kind, coords, rho, &mut diag);
    out[..n * n].fill(0.0);
    for a in 0..n {
        out[a * n + a] = diag[a * d];
    }
}

/// Row-sum lumped mass diagonal: diag[a d + i] = sum_b int_K rho N_a N_b dx = int_K rho N_a dx
/// (same quadrature as [`mass`], so it equals the row sums of the consistent mass exactly up to
/// rounding). `out` has length >= n d and is overwritten. For P1 this is rho |K| / (d + 1) per
/// node; for Q1 on parallelograms rho |K| / 2^d.
pub fn mass_lumped_diag(kind: ElementKind, coords: &[[f64; 3]], rho: f64, out: &mut [f64]) {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("mass_lumped_diag coords", kind, coords.len(), n);
    check_len("mass_lumped_diag out", kind, out.len(), n * d);
    let t = table(kind, mass_order(kind));
    let mut l = [0.0; MAX_NODES];
    for q in 0..t.w.len() {
        let w = rho * t.w[q] * jacobian_det(d, n, coords, &t.dn[q]);
        for a in 0..n {
            l[a] += w * t.n[q][a];
        }
    }
    for a in 0..n {
        for i in 0..d {
            out[a * d + i] = l[a];
        }
    }
}

/// Row-sum lumped mass as a full `(n d) x (n d)` matrix (zeros off the diagonal) so that the
/// same assembler as for [`mass`] can be used. Diagonal as in [`mass_lumped_diag`].
pub fn mass_lumped(kind: ElementKind, coords: &[[f64; 3]], rho: f64, out: &mut [f64]) {
    let nd = kind.n_nodes() * kind.dim();
    check_len("mass_lumped out", kind, out.len(), nd * nd);
    let mut diag = [0.0; MAX_DOFS];
    mass_lumped_diag(kind, coords, rho, &mut diag);
    out[..nd * nd].fill(0.0);
    for k in 0..nd {
        out[k * nd + k] = diag[k];
    }
}

// ---------------------------------------------------------------------------------------------
// Loads.

/// Physical point x(xi) = sum_a N_a x_a.
#[inline]
fn point(n: usize, nq: &[f64; MAX_NODES], coords: &[[f64; 3]]) -> [f64; 3] {
    let mut x = [0.0; 3];
    for a in 0..n {
        for i in 0..3 {
            x[i] += nq[a] * coords[a][i];
        }
    }
    x
}

/// Body-force load f_e[a d + i] = int_K N_a f_i(x) dx with the rule of [`gauss`]`(kind, order)`
/// (order = polynomial degree integrated exactly on affine elements; f of degree p needs
/// order p + 1). `f` returns a 3-vector of which the first d = `kind.dim()` components are
/// used. `out` (length >= n d) is overwritten. det J is used with its sign.
pub fn body_force(
    kind: ElementKind,
    coords: &[[f64; 3]],
    f: &dyn Fn([f64; 3]) -> [f64; 3],
    order: usize,
    out: &mut [f64],
) {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("body_force coords", kind, coords.len(), n);
    check_len("body_force out", kind, out.len(), n * d);
    out[..n * d].fill(0.0);
    let t = table(kind, order);
    for q in 0..t.w.len() {
        let det = jacobian_det(d, n, coords, &t.dn[q]);
        let x = point(n, &t.n[q], coords);
        let fx = f(x);
        let w = t.w[q] * det;
        for a in 0..n {
            let wa = w * t.n[q][a];
            for i in 0..d {
                out[a * d + i] += wa * fx[i];
            }
        }
    }
}

/// Boundary load t_e[a dim + i] = int_F N_a g_i(x, n(x)) ds over a boundary facet:
/// `Line2` for dim = 2, `Tri3`/`Quad4` for dim = 3 (also `Point1` for dim = 1, where the
/// normal passed to `g` is 0). `n` is the unit normal of [`surface_measure`] (right of the
/// direction of travel for Line2, right-hand rule for faces), which is outward when the facet
/// nodes are ordered as in `ElementKind::facets()` of the adjacent cell. Rule:
/// [`gauss`]`(facet_kind, order)`. `out` (length >= n dim) is overwritten.
pub fn traction(
    facet_kind: ElementKind,
    coords: &[[f64; 3]],
    g: &dyn Fn([f64; 3], [f64; 3]) -> [f64; 3],
    dim: usize,
    order: usize,
    out: &mut [f64],
) {
    let n = facet_kind.n_nodes();
    assert!(
        dim == facet_kind.dim() + 1 && dim <= 3,
        "traction: a {} is not a facet in dimension {dim}",
        facet_kind.name()
    );
    check_len("traction coords", facet_kind, coords.len(), n);
    check_len("traction out", facet_kind, out.len(), n * dim);
    out[..n * dim].fill(0.0);
    let t = table(facet_kind, order);
    for q in 0..t.w.len() {
        let (ds, nrm) = surface_measure(facet_kind, coords, t.xi[q]);
        let x = point(n, &t.n[q], coords);
        let gx = g(x, nrm);
        let w = t.w[q] * ds;
        for a in 0..n {
            let wa = w * t.n[q][a];
            for i in 0..dim {
                out[a * dim + i] += wa * gx[i];
            }
        }
    }
}

/// Boundary weights w[a] = int_F N_a ds of a facet (diagonal D of the dual-mortar coupling),
/// for `Line2` (in 2D, z ignored), `Tri3`/`Quad4` (in 3D) or `Point1` (w = 1). Rule of order 2
/// (exact on affine facets and on planar bilinear quads). `out` (length >= n) is overwritten.
pub fn boundary_weights(facet_kind: ElementKind, coords: &[[f64; 3]], out: &mut [f64]) {
    let n = facet_kind.n_nodes();
    check_len("boundary_weights coords", facet_kind, coords.len(), n);
    check_len("boundary_weights out", facet_kind, out.len(), n);
    out[..n].fill(0.0);
    let t = table(facet_kind, 2);
    for q in 0..t.w.len() {
        let (ds, _) = surface_measure(facet_kind, coords, t.xi[q]);
        let w = t.w[q] * ds;
        for a in 0..n {
            out[a] += w * t.n[q][a];
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors, geometry.

/// Squared element errors of the finite-element field u_h = sum_a N_a u_a (interlaced
/// `u_nodal[a d + i]`) against `exact(x) = (u(x), grad u(x))` with `grad[i][j] = du_i/dx_j`:
///
/// returns ( int_K |u_h - u|^2 dx , int_K |grad u_h - grad u|^2 dx )  (Frobenius norm),
///
/// i.e. the squared L2 error and squared H1-seminorm error, summing over components
/// i, j < d = `kind.dim()`, with the rule [`gauss`]`(kind, order)` (order >= 2 p for an exact
/// field of degree p on affine elements).
pub fn error_sq(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u_nodal: &[f64],
    exact: &dyn Fn([f64; 3]) -> ([f64; 3], [[f64; 3]; 3]),
    order: usize,
) -> (f64, f64) {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("error_sq coords", kind, coords.len(), n);
    check_len("error_sq u_nodal", kind, u_nodal.len(), n * d);
    let t = table(kind, order);
    let (mut e0, mut e1) = (0.0, 0.0);
    for q in 0..t.w.len() {
        let mut g = t.dn[q];
        let det = map_gradients(d, n, coords, &mut g);
        let x = point(n, &t.n[q], coords);
        let (u, gu) = exact(x);
        let w = t.w[q] * det;
        let mut s0 = 0.0;
        let mut s1 = 0.0;
        for i in 0..d {
            let mut uh = 0.0;
            let mut guh = [0.0; 3];
            for a in 0..n {
                let ua = u_nodal[a * d + i];
                uh += t.n[q][a] * ua;
                for j in 0..d {
                    guh[j] += ua * g[a][j];
                }
            }
            s0 += (uh - u[i]) * (uh - u[i]);
            for j in 0..d {
                s1 += (guh[j] - gu[i][j]) * (guh[j] - gu[i][j]);
            }
        }
        e0 += w * s0;
        e1 += w * s1;
    }
    (e0, e1)
}

/// Measure (length/area/volume) of a cell: int_K 1 dx = sum_q w_q det J(xi_q), with the
/// stiffness rule (exact for P1, and for Q1 since det J has degree <= 2 per direction).
/// Signed: negative for inverted simplices. Coordinates are read in `kind.dim()` dimensions
/// (for facets embedded in a higher dimension use [`boundary_weights`] and sum).
pub fn measure(kind: ElementKind, coords: &[[f64; 3]]) -> f64 {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("measure coords", kind, coords.len(), n);
    let t = table(kind, stiffness_order(kind));
    let mut v = 0.0;
    for q in 0..t.w.len() {
        v += t.w[q] * jacobian_det(d, n, coords, &t.dn[q]);
    }
    v
}

/// Smallest det J over the element's corner nodes (reference vertices). For simplices det J is
/// constant (= 2 area for Tri3, 6 volume for Tet4); for Q1 the corner values are the ones the
/// mesh checker needs (a bilinear quad is valid iff all four are > 0; for a trilinear hex
/// positive corner values are necessary but not sufficient). Not normalized: for a
/// scale-free quality divide by `measure / reference measure`.
pub fn min_det_jacobian(kind: ElementKind, coords: &[[f64; 3]]) -> f64 {
    let n = kind.n_nodes();
    let d = kind.dim();
    check_len("min_det_jacobian coords", kind, coords.len(), n);
    let mut m = f64::INFINITY;
    for a in 0..n {
        let mut g = [[0.0; 3]; MAX_NODES];
        shape_grad_ref(kind, super::shape::reference_node(kind, a), &mut g);
        let det = map_gradients(d, n, coords, &mut g);
        m = if det.is_nan() { f64::NAN } else { m.min(det) };
        if m.is_nan() {
            return m;
        }
    }
    m
}

#[cfg(test)]
#[path = "kernels_tests.rs"]
mod tests;
