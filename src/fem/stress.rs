//! Stress-type quantities of a finite-element displacement on one cell: the small strain,
//! Hooke's law, von Mises stress, the paper's effective stress, the hydrostatic pressure, their
//! cell averages and the integrals of their lumped L2 projection to the nodes.
//!
//! Pure functions without allocation, in the conventions of [`super::kernels`] (node
//! coordinates in gmsh order, interlaced nodal displacements `u[a d + i]`, `d = kind.dim()`).
//!
//! - Tensors are always 3 x 3 ([`Tensor`]), also in 2D, where plane strain gives
//!   `eps_xz = eps_yz = eps_zz = 0`, `sigma_xz = sigma_yz = 0` and
//!   `sigma_zz = lambda (eps_xx + eps_yy) = nu (sigma_xx + sigma_yy)`.
//! - Output stores a symmetric tensor as six components in the order of [`TENSOR6`]:
//!   xx, xy, xz, yy, yz, zz (XDMF's `Tensor6` order), in 2D too. This constant is the one place
//!   that order is defined.
//! - Quadrature ("the stress rule"): the stiffness rule, i.e. the centroid on P1 cells (the
//!   strain is constant there, so every value below is exact) and 2 x 2 / 2 x 2 x 2 Gauss points
//!   on Q1 cells. A cell's value of a quantity `Q` is its cell average with that rule,
//!   `Q_K = sum_q w_q det J_q Q(x_q) / sum_q w_q det J_q`, and the lumped L2 projection to the
//!   nodes is `Q_i = sum_K sum_q w_q det J_q N_i(x_q) Q(x_q) / sum_K sum_q w_q det J_q N_i(x_q)`
//!   (`sum_K int_K phi_i Q_h / sum_K int_K phi_i`). Every quantity is evaluated at the points
//!   and then averaged: for the linear ones (strain, stress, pressure) that is the quantity of
//!   the averaged strain; von Mises of a Q1 cell is the average of the point values, which is
//!   at least von Mises of the average stress (a norm is convex).

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use super::element::ElementKind;
use super::kernels::{check_len, inverted, stiffness_order, table, Material, MAX_NODES};
use super::shape::{map_gradients, physical_gradients};
use crate::error::Result;

/// A 3 x 3 tensor, `t[i][j]`.
pub type Tensor = [[f64; 3]; 3];

/// The stored order of a symmetric tensor's six components: xx, xy, xz, yy, yz, zz (XDMF's
/// `Tensor6`). Change it here and everything that writes or names components follows.
pub const TENSOR6: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];

/// Names of the components of [`TENSOR6`], in its order.
pub fn tensor6_names() -> [String; 6] {
    let axis = ["x", "y", "z"];
    TENSOR6.map(|(i, j)| format!("{}{}", axis[i], axis[j]))
}

/// The six stored components of a symmetric tensor (order [`TENSOR6`]).
pub fn tensor6(t: &Tensor) -> [f64; 6] {
    TENSOR6.map(|(i, j)| t[i][j])
}

/// The symmetric tensor of six stored components (order [`TENSOR6`]).
pub fn from_tensor6(v: &[f64]) -> Tensor {
    let mut t = [[0.0; 3]; 3];
    for (k, &(i, j)) in TENSOR6.iter().enumerate() {
        t[i][j] = v[k];
        t[j][i] = v[k];
    }
    t
}

/// `tr t = t_xx + t_yy + t_zz`.
pub fn trace(t: &Tensor) -> f64 {
    t[0][0] + t[1][1] + t[2][2]
}

/// Small strain `eps = sym grad u = (grad u + grad u^T) / 2` of `u_h = sum_a N_a u_a` from the
/// physical gradients `g[a] = grad N_a` of `n` nodes, `eps_ij = sum_a (u_a,i g_a,j + u_a,j
/// g_a,i) / 2` for `i, j < d`; the other entries (2D: xz, yz, zz) are 0 (plane strain).
pub fn strain(d: usize, n: usize, g: &[[f64; 3]], u_nodal: &[f64]) -> Tensor {
    let gu = gradient(d, n, g, u_nodal);
    let mut eps = [[0.0; 3]; 3];
    for i in 0..d {
        for j in 0..d {
            eps[i][j] = 0.5 * (gu[i][j] + gu[j][i]);
        }
    }
    eps
}

/// The displacement gradient `gu[i][j] = du_i/dx_j = sum_a u_a,i g_a,j` (`i, j < d`, the
/// other entries 0).
pub fn gradient(d: usize, n: usize, g: &[[f64; 3]], u_nodal: &[f64]) -> Tensor {
    let mut gu = [[0.0; 3]; 3];
    for a in 0..n {
        for i in 0..d {
            let ua = u_nodal[a * d + i];
            for j in 0..d {
                gu[i][j] += ua * g[a][j];
            }
        }
    }
    gu
}

/// Small strain `eps = sym grad u_h` of a cell at reference point `xi` (see [`strain`]).
/// Errors: `Error::Mesh` for an inverted or degenerate cell (det J <= 0 at `xi`).
pub fn strain_at(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u_nodal: &[f64],
    xi: [f64; 3],
) -> Result<Tensor> {
    let (n, d) = (kind.n_nodes(), kind.dim());
    check_len("strain_at coords", kind, coords.len(), n);
    check_len("strain_at u_nodal", kind, u_nodal.len(), n * d);
    let mut g = [[0.0; 3]; MAX_NODES];
    let det = physical_gradients(kind, coords, xi, &mut g);
    if det.is_nan() || det <= 0.0 {
        return Err(inverted(kind, det, 0));
    }
    Ok(strain(d, n, &g, u_nodal))
}

/// Hooke's law `sigma = lambda tr(eps) I + 2 mu eps` (isotropic). With a plane-strain `eps`
/// (`eps_zz = eps_xz = eps_yz = 0`) this gives `sigma_zz = lambda (eps_xx + eps_yy)`, which
/// equals `nu (sigma_xx + sigma_yy)` since `lambda = 2 mu nu / (1 - 2 nu)`.
pub fn hooke(eps: &Tensor, mat: &Material) -> Tensor {
    let tr = trace(eps);
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = 2.0 * mat.mu * eps[i][j];
        }
        s[i][i] += mat.lambda * tr;
    }
    s
}

/// Von Mises stress `sqrt(3/2 s:s)`, `s = sigma - tr(sigma)/3 I` the deviator of the full 3 x 3
/// tensor (`sigma_zz` included in 2D). Uniaxial `sigma`: `|sigma|`; pure shear `tau`:
/// `sqrt(3) |tau|`; hydrostatic: 0.
pub fn von_mises(s: &Tensor) -> f64 {
    let m = trace(s) / 3.0;
    let mut ss = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let dev = s[i][j] - if i == j { m } else { 0.0 };
            ss += dev * dev;
        }
    }
    (1.5 * ss).sqrt()
}

/// The effective stress of Hager & Wohlmuth 2009 (Fig. 7.3),
/// `sigma_eff = sum_{i,j=1}^d |sigma_ij - delta_ij tr_d(sigma)/d|^2`, with `d` the mesh
/// dimension and `tr_d` the trace over those `d` axes: in 2D the in-plane components only
/// (`sigma_zz` does not enter, and the in-plane trace is divided by 2). A square (units of
/// stress squared), not its root, as in the paper. 3D uniaxial `sigma`: `2/3 sigma^2`; 2D
/// uniaxial: `sigma^2 / 2`; pure shear `tau`: `2 tau^2`.
pub fn effective_stress(s: &Tensor, d: usize) -> f64 {
    let m = (0..d).map(|i| s[i][i]).sum::<f64>() / d as f64;
    let mut e = 0.0;
    for i in 0..d {
        for j in 0..d {
            let dev = s[i][j] - if i == j { m } else { 0.0 };
            e += dev * dev;
        }
    }
    e
}

/// Hydrostatic pressure `p = -tr(sigma)/3` (full 3 x 3 trace, `sigma_zz` included in 2D):
/// positive in compression.
pub fn pressure(s: &Tensor) -> f64 {
    -trace(s) / 3.0
}

/// The stress-type quantities a run can write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// `sigma`, 6 components ([`TENSOR6`]).
    Stress,
    /// `eps` (the tensor, not engineering shear strains), 6 components ([`TENSOR6`]).
    Strain,
    /// [`von_mises`], 1 component.
    VonMises,
    /// [`effective_stress`], 1 component.
    EffectiveStress,
    /// [`pressure`], 1 component.
    Pressure,
}

impl Quantity {
    pub const ALL: [Quantity; 5] = [
        Quantity::Stress,
        Quantity::Strain,
        Quantity::VonMises,
        Quantity::EffectiveStress,
        Quantity::Pressure,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Quantity::Stress => "stress",
            Quantity::Strain => "strain",
            Quantity::VonMises => "von_mises",
            Quantity::EffectiveStress => "effective_stress",
            Quantity::Pressure => "pressure",
        }
    }

    pub fn components(self) -> usize {
        match self {
            Quantity::Stress | Quantity::Strain => TENSOR6.len(),
            _ => 1,
        }
    }

    /// The quantity's components at one point, from the strain and the stress there
    /// (`d` the mesh dimension), into `out[..self.components()]`.
    pub fn eval(self, eps: &Tensor, sigma: &Tensor, d: usize, out: &mut [f64]) {
        match self {
            Quantity::Stress => out[..6].copy_from_slice(&tensor6(sigma)),
            Quantity::Strain => out[..6].copy_from_slice(&tensor6(eps)),
            Quantity::VonMises => out[0] = von_mises(sigma),
            Quantity::EffectiveStress => out[0] = effective_stress(sigma, d),
            Quantity::Pressure => out[0] = pressure(sigma),
        }
    }
}

/// A quadrature point of the stress rule on a cell: its weight `w_q det J_q`, the shape
/// values `N_a(x_q)` and the strain there.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sample {
    pub weight: f64,
    pub n: [f64; MAX_NODES],
    pub eps: Tensor,
    /// The displacement gradient `grad u` there (finite strain: `F = I + grad u`).
    pub grad: Tensor,
}

/// Most points of the stress rule (Hex8: 2 x 2 x 2).
pub const MAX_SAMPLES: usize = 8;

/// The strain of `u_h` at the points of the stress rule of a cell (centroid for P1, 2 x 2 /
/// 2 x 2 x 2 Gauss for Q1), into `out[..count]`; returns the count.
/// Errors: `Error::Mesh` for an inverted or degenerate cell (det J <= 0 at a point).
pub fn samples(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u_nodal: &[f64],
    out: &mut [Sample; MAX_SAMPLES],
) -> Result<usize> {
    let (n, d) = (kind.n_nodes(), kind.dim());
    check_len("stress samples coords", kind, coords.len(), n);
    check_len("stress samples u_nodal", kind, u_nodal.len(), n * d);
    let t = table(kind, stiffness_order(kind));
    assert!(t.w.len() <= MAX_SAMPLES, "stress rule of {} too large", kind.name());
    for q in 0..t.w.len() {
        let mut g = t.dn[q];
        let det = map_gradients(d, n, coords, &mut g);
        if det.is_nan() || det <= 0.0 {
            return Err(inverted(kind, det, q));
        }
        let grad = gradient(d, n, &g, u_nodal);
        let mut eps = [[0.0; 3]; 3];
        for i in 0..d {
            for j in 0..d {
                eps[i][j] = 0.5 * (grad[i][j] + grad[j][i]);
            }
        }
        out[q] = Sample { weight: t.w[q] * det, n: t.n[q], eps, grad };
    }
    Ok(t.w.len())
}

/// The lumped weights `m_a = int_K N_a = sum_q w_q det J_q N_a(x_q)` of a cell's `n` nodes
/// (the denominators of the lumped projection), into `out[..n]`.
pub fn lumped_weights(samples: &[Sample], n: usize, out: &mut [f64]) {
    out[..n].fill(0.0);
    for s in samples {
        for a in 0..n {
            out[a] += s.weight * s.n[a];
        }
    }
}

/// One quantity on one cell of material `mat` (mesh dimension `d`, `n` nodes), from its
/// [`samples`]: the cell average `cell[k] = sum_q w_q Q_k(x_q) / sum_q w_q` (`w_q` the
/// weights `w_q det J_q`) into `cell[..c]`, and the numerators of the lumped projection
/// `nodal[a c + k] = sum_q w_q N_a(x_q) Q_k(x_q)` into `nodal[..n c]` (`c` =
/// `q.components()`; both overwritten). Returns the cell's measure `sum_q w_q`.
pub fn integrate(
    samples: &[Sample],
    n: usize,
    d: usize,
    mat: &Material,
    q: Quantity,
    cell: &mut [f64],
    nodal: &mut [f64],
) -> f64 {
    // Mean dilatation: the pressure part takes the cell's mean volumetric strain.
    if mat.mean_dilatation && samples.len() > 1 {
        let (mut th, mut vol) = (0.0, 0.0);
        for s in samples {
            th += s.weight * trace(&s.eps);
            vol += s.weight;
        }
        return integrate_dilatation(samples, n, d, mat, th / vol, q, cell, nodal);
    }
    integrate_with(samples, n, d, |s| (s.eps, hooke(&s.eps, mat)), q, cell, nodal)
}

/// [`integrate`] with the pressure part of the stress taken at the dilatation `theta`:
/// `sigma = 2 mu eps + lambda theta I` (the mixed formulations: the cell's mean dilatation on
/// quadrilaterals and hexahedra, the mean of its nodes' averaged dilatations on triangles and
/// tetrahedra, `assembly::nodal_pressure`).
#[allow(clippy::too_many_arguments)] // integrate's arguments and the dilatation
pub fn integrate_dilatation(
    samples: &[Sample],
    n: usize,
    d: usize,
    mat: &Material,
    theta: f64,
    q: Quantity,
    cell: &mut [f64],
    nodal: &mut [f64],
) -> f64 {
    integrate_with(
        samples,
        n,
        d,
        |s| {
            let mut sigma = hooke(&s.eps, mat);
            let p = mat.lambda * (theta - trace(&s.eps));
            (0..3).for_each(|i| sigma[i][i] += p);
            (s.eps, sigma)
        },
        q,
        cell,
        nodal,
    )
}

/// [`integrate`] for a finite-strain law: at each point the Green-Lagrange strain
/// `E = (F^T F - I)/2` and the Cauchy stress `sigma = F S F^T / J` of the deformed body
/// (`F = I + grad u`; averaged with the reference weights).
pub fn integrate_finite(
    samples: &[Sample],
    n: usize,
    d: usize,
    law: &crate::fem::hyperelastic::Law,
    q: Quantity,
    cell: &mut [f64],
    nodal: &mut [f64],
) -> f64 {
    integrate_finite_pressure(samples, n, d, law, None, q, cell, nodal)
}

/// [`integrate_finite`] with, if `given`, the pressure part of the stress given: the
/// point-wise law without `lambda` plus `given I` (the averaged nodal pressure of mixed
/// neo-Hookean simplices: the mean of the cell's nodes' `L_a/V_a ln(theta_a)/theta_a`).
#[allow(clippy::too_many_arguments)] // integrate_finite's arguments and the pressure
pub fn integrate_finite_pressure(
    samples: &[Sample],
    n: usize,
    d: usize,
    law: &crate::fem::hyperelastic::Law,
    given: Option<f64>,
    q: Quantity,
    cell: &mut [f64],
    nodal: &mut [f64],
) -> f64 {
    use crate::fem::hyperelastic::{cauchy_stress, det, right_cauchy_green, Law, Model};
    let deformation = |s: &Sample| {
        let mut f = s.grad;
        for (i, row) in f.iter_mut().enumerate() {
            row[i] += 1.0;
        }
        f
    };
    // Mean dilatation (neo-Hooke): the point-wise law without lambda and the cell's pressure
    // `lambda ln(theta)/theta`, theta the mean Jacobian (the element's energy, hyperelastic).
    let mean = law.mean_dilatation && law.model == Model::NeoHookean && samples.len() > 1;
    let (point_law, pressure) = if let Some(p) = given {
        (Law { lambda: 0.0, ..*law }, p)
    } else if mean {
        let (mut th, mut vol) = (0.0, 0.0);
        for s in samples {
            th += s.weight * det(&deformation(s));
            vol += s.weight;
        }
        let th = th / vol;
        (Law { lambda: 0.0, ..*law }, law.lambda * th.ln() / th)
    } else {
        (*law, 0.0)
    };
    let point = |s: &Sample| {
        let f = deformation(s);
        let c = right_cauchy_green(&f);
        let mut e = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                e[i][j] = 0.5 * (c[i][j] - if i == j { 1.0 } else { 0.0 });
            }
        }
        let mut sigma = cauchy_stress(&point_law, &f);
        (0..3).for_each(|i| sigma[i][i] += pressure);
        (e, sigma)
    };
    integrate_with(samples, n, d, point, q, cell, nodal)
}

/// [`integrate`] with the strain and the stress at each point given by `point`.
fn integrate_with(
    samples: &[Sample],
    n: usize,
    d: usize,
    point: impl Fn(&Sample) -> (Tensor, Tensor),
    q: Quantity,
    cell: &mut [f64],
    nodal: &mut [f64],
) -> f64 {
    let c = q.components();
    cell[..c].fill(0.0);
    nodal[..n * c].fill(0.0);
    let mut measure = 0.0;
    let mut val = [0.0; 6];
    for s in samples {
        let (eps, sigma) = point(s);
        q.eval(&eps, &sigma, d, &mut val);
        measure += s.weight;
        for k in 0..c {
            cell[k] += s.weight * val[k];
        }
        for a in 0..n {
            let wa = s.weight * s.n[a];
            for k in 0..c {
                nodal[a * c + k] += wa * val[k];
            }
        }
    }
    for v in &mut cell[..c] {
        *v /= measure;
    }
    measure
}

/// The cell value (cell average with the stress rule) of quantity `q` of `u_h` on one cell of
/// material `mat`, into `out[..q.components()]` (see [`samples`] and [`integrate`]).
pub fn cell_value(
    kind: ElementKind,
    coords: &[[f64; 3]],
    u_nodal: &[f64],
    mat: &Material,
    q: Quantity,
    out: &mut [f64],
) -> Result<()> {
    let mut s = [Sample::default(); MAX_SAMPLES];
    let k = samples(kind, coords, u_nodal, &mut s)?;
    let mut nodal = [0.0; MAX_NODES * 6];
    integrate(&s[..k], kind.n_nodes(), kind.dim(), mat, q, out, &mut nodal);
    Ok(())
}

#[cfg(test)]
#[path = "stress_tests.rs"]
mod tests;
