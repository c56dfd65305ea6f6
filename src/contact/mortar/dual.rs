//! Dual (biorthogonal) shape functions on slave facets and averaged nodal normals.

use super::facet::{shape_line2, Facet2, Facet3};
use super::geom::*;
use crate::fem::quadrature::gauss_legendre;

// ------------------------------------------------------------------------------------------
// Dual basis
// ------------------------------------------------------------------------------------------

/// Dual shape functions of one slave facet: `psi_i = sum_k a[i][k] phi_k`, and the facet's
/// `D_e = diag(d)` with `d_j = int_e phi_j` (= `int_e psi_j`).
///
/// Biorthogonality `int_e psi_i phi_j = delta_ij int_e phi_j` holds by construction,
/// `A_e = D_e M_e^{-1}`, `M_e = (int_e phi_i phi_j)`. It makes the mortar matrix
/// `D_jk = int psi_j phi_k = delta_jk int phi_k` diagonal, so the slave surface contribution
/// to `D` is `D_jj += d_j` summed over the facets around node j.
/// Closed forms on affine facets (derived in the tests): line2 `psi_1 = 2 phi_1 - phi_2`;
/// tri3 `psi_i = 3 phi_i - phi_j - phi_k = 4 phi_i - 1`; parallelogram quad4
/// `psi_i = 4 phi_i - 2 phi_(i+1) + phi_(i+2) - 2 phi_(i+3)` (the tensor product of line2).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DualBasis {
    /// Number of nodes of the facet (2, 3 or 4); entries beyond it are zero.
    pub n: usize,
    /// Coefficients `A_e`, row i gives `psi_i`.
    pub a: [[f64; 4]; 4],
    /// `D_e` diagonal: `d_j = int_e phi_j`.
    pub d: [f64; 4],
}

impl DualBasis {
    /// `psi_i = sum_k A_ik phi_k` from the standard shape function values.
    pub fn psi(&self, phi: &[f64; 4]) -> [f64; 4] {
        let mut psi = [0.0; 4];
        for (i, p) in psi.iter_mut().enumerate().take(self.n) {
            *p = (0..self.n).map(|k| self.a[i][k] * phi[k]).sum();
        }
        psi
    }
}

/// Inverse of the leading `n x n` block by Gauss-Jordan with partial pivoting; Err when a pivot
/// falls below `1e-12 max|m_ij|` (singular Gram matrix = degenerate facet).
pub(crate) fn invert_small(m: &[[f64; 4]; 4], n: usize) -> Result<[[f64; 4]; 4], GeomError> {
    let scale = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .fold(0.0f64, |s, (i, j)| s.max(m[i][j].abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return fail("Gram matrix of the facet is zero or not finite");
    }
    let mut a = *m;
    let mut inv = [[0.0; 4]; 4];
    for (i, row) in inv.iter_mut().enumerate().take(n) {
        row[i] = 1.0;
    }
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap_or(c);
        if !(a[p][c].abs() > 1e-12 * scale) {
            return fail("Gram matrix of the facet is singular");
        }
        a.swap(c, p);
        inv.swap(c, p);
        let piv = a[c][c];
        for k in 0..n {
            a[c][k] /= piv;
            inv[c][k] /= piv;
        }
        for r in 0..n {
            if r != c {
                let f = a[r][c];
                for k in 0..n {
                    a[r][k] -= f * a[c][k];
                    inv[r][k] -= f * inv[c][k];
                }
            }
        }
    }
    Ok(inv)
}

/// `A_e = D_e M_e^{-1}` from samples `(phi(xi_q), w_q J(xi_q))` of a facet quadrature.
pub(crate) fn dual_from_samples(
    n: usize,
    samples: &[([f64; 4], f64)],
    size: f64,
) -> Result<DualBasis, GeomError> {
    let mut d = [0.0; 4];
    let mut m = [[0.0; 4]; 4];
    for (phi, w) in samples {
        for i in 0..n {
            d[i] += w * phi[i];
            for j in 0..n {
                m[i][j] += w * phi[i] * phi[j];
            }
        }
    }
    // The measure sum_j d_j must be a fair fraction of size^dim: a zero-area facet has no duals.
    let measure: f64 = d.iter().sum();
    let dim = if n == 2 { 1 } else { 2 };
    if !(measure > 1e-14 * size.powi(dim)) {
        return fail(format!("degenerate facet (measure {:e}, size {:e})", measure, size));
    }
    let minv = invert_small(&m, n)?;
    let mut a = [[0.0; 4]; 4];
    for i in 0..n {
        for k in 0..n {
            a[i][k] = d[i] * minv[i][k];
        }
    }
    Ok(DualBasis { n, a, d })
}

/// Dual basis of a line2 slave facet: `D_e = diag(int phi_j)`, `M_e = (int phi_i phi_j)` with a
/// 3-point Gauss rule (exact: the integrand is quadratic, `J = L/2` constant),
/// `A_e = D_e M_e^{-1}`.
pub fn dual_basis_2d(facet: &Facet2) -> Result<DualBasis, GeomError> {
    if !facet.is_finite() {
        return fail("line facet has non-finite coordinates");
    }
    let j = facet.jacobian();
    let samples: Vec<([f64; 4], f64)> = gauss_legendre(3)
        .iter()
        .map(|&(x, w)| {
            let p = shape_line2(x);
            ([p[0], p[1], 0.0, 0.0], w * j)
        })
        .collect();
    dual_from_samples(2, &samples, 2.0 * j)
}

/// Dual basis of a tri3 or quad4 slave facet with the facet's actual Jacobian:
/// `D_e = diag(int_e phi_j J)`, `M_e = (int_e phi_i phi_j J)`, `A_e = D_e M_e^{-1}`
/// (rule: `Facet3::quadrature`, exact on triangles and planar quads).
pub fn dual_basis_3d(facet: &Facet3) -> Result<DualBasis, GeomError> {
    if !facet.is_finite() {
        return fail("facet has non-finite coordinates");
    }
    let samples: Vec<([f64; 4], f64)> = facet
        .quadrature()
        .iter()
        .map(|&(xi, w)| (facet.shape(xi), w * facet.jacobian(xi)))
        .collect();
    dual_from_samples(facet.n_nodes(), &samples, facet.size())
}

// ------------------------------------------------------------------------------------------
// Averaged nodal normals
// ------------------------------------------------------------------------------------------

/// Unit normal at each node of a 2D slave surface: `n_j = sum_e n_e / |sum_e n_e|` over the line
/// facets e around node j, `n_e` the unit normal `(t_y, -t_x)/|t|` (body on the left of a->b),
/// negated when `reverse` (body on the right). Nodes not on any facet get `[0, 0]`.
/// Err on a bad index, a zero-length facet, or a node where the normals cancel.
pub fn nodal_normals_2d(
    coords: &[Vec2],
    facets: &[[usize; 2]],
    reverse: bool,
) -> Result<Vec<Vec2>, GeomError> {
    let sign = if reverse { -1.0 } else { 1.0 };
    let mut sum = vec![[0.0; 2]; coords.len()];
    let mut used = vec![false; coords.len()];
    for nodes in facets {
        let f = Facet2::from_nodes(coords, *nodes)?;
        let n = f.normal();
        let len = norm2(n);
        if !(len > 0.0 && len.is_finite()) {
            return fail(format!("line facet {:?} has zero or non-finite length", nodes));
        }
        for &k in nodes {
            sum[k] = add2(sum[k], scale2(sign / len, n));
            used[k] = true;
        }
    }
    normalize_sums(sum, &used, |v| norm2(*v), |s, v| scale2(s, *v))
}

/// Unit normal at each node of a 3D slave surface: `n_j = sum_e n_e / |sum_e n_e|` with `n_e`
/// the unit normal of facet e at its parametric centre, `x_xi x x_eta` (outward for nodes
/// counter-clockwise seen from outside), negated when `reverse`. Facets are node lists of
/// length 3 (tri3) or 4 (quad4). Nodes not on any facet get `[0, 0, 0]`.
/// Err on a bad facet, a degenerate facet, or a node where the normals cancel.
pub fn nodal_normals_3d<F: AsRef<[usize]>>(
    coords: &[Vec3],
    facets: &[F],
    reverse: bool,
) -> Result<Vec<Vec3>, GeomError> {
    let sign = if reverse { -1.0 } else { 1.0 };
    let mut sum = vec![[0.0; 3]; coords.len()];
    let mut used = vec![false; coords.len()];
    for nodes in facets {
        let nodes = nodes.as_ref();
        let f = Facet3::from_nodes(coords, nodes)?;
        let n = f.normal(f.centre_param());
        let len = norm3(n);
        if !(len > 1e-14 * f.size().powi(2) && len.is_finite()) {
            return fail(format!("facet {:?} is degenerate (no normal at its centre)", nodes));
        }
        for &k in nodes {
            sum[k] = add3(sum[k], scale3(sign / len, n));
            used[k] = true;
        }
    }
    normalize_sums(sum, &used, |v| norm3(*v), |s, v| scale3(s, *v))
}

pub(crate) fn normalize_sums<V: Copy>(
    mut sum: Vec<V>,
    used: &[bool],
    norm: impl Fn(&V) -> f64,
    scale: impl Fn(f64, &V) -> V,
) -> Result<Vec<V>, GeomError> {
    for (k, v) in sum.iter_mut().enumerate() {
        if used[k] {
            let len = norm(v);
            // Unit normals summing to (almost) zero: a knife edge, no meaningful normal.
            if !(len > 1e-8) {
                return fail(format!("node {} has opposite facet normals that cancel", k));
            }
            *v = scale(1.0 / len, v);
        }
    }
    Ok(sum)
}
