//! Directional derivatives ("linearizations") of the 3D mortar geometry, for finite sliding
//! (issue 24; Popp, Gitterle, Gee, Wall, IJNME 2010; METHOD.md 5c).
//!
//! The 3D counterpart of `linearize.rs`, with its conventions: every function takes the
//! inputs of its counterpart in `dual.rs`/`segment.rs` plus the node ids, and returns the
//! counterpart's value (computed by the same expressions in the same order, so bit for bit
//! the same) together with its derivative as a [`Lin`] keyed by `(involved node, component)`,
//! components 0, 1, 2 = x, y, z. A 3D vector carries one `Lin` per component ([`Lin3`],
//! [`Vec3Lin`]). Nothing here is used by the solver yet.
//!
//! Notation: a facet `x(xi) = sum_k phi_k(xi) x_k`, tangents `t_1 = x_xi`, `t_2 = x_eta`,
//! raw normal `n = t_1 x t_2`, `J = |n|`; `delta` is the directional derivative and
//! `delta x(xi)` at fixed `xi` is `sum_k phi_k(xi) delta x_k`.
//!
//! # The clipped polygon
//!
//! Its vertices are of three kinds ([`PolyVertex`]): a projected master node, a projected slave
//! node, or the crossing of a master edge with a slave edge. All are differentiated by the
//! chain rule through the very operations `clip_polygon` performs: a kept vertex carries its
//! derivative; a crossing `p = s + t (p' - s)`, `t = d / (d - d')` with the signed distances
//! `d = e x (s - a)` to the clip edge `a -> b`, `e = b - a`, has
//!
//! ```text
//! delta d = delta e x (s - a) + e x (delta s - delta a)
//! delta t = (d delta d' - d' delta d) / (d - d')^2
//! delta p = delta s + t (delta p' - delta s) + (p' - s) delta t
//! ```
//!
//! which is exact for both kinds of crossing: a master edge against a slave edge (the
//! "intersection" vertex), and, after an earlier clip, a point sliding along slave edge i-1
//! against slave edge i (the projected slave node; its derivative comes out as that of the
//! projected slave node because the arithmetic is the same function).
//!
//! # Switching points
//!
//! The integrals are piecewise smooth: a vertex changes kind when a node crosses an edge of
//! the other facet's projection. The derivative returned is ONE-SIDED, that of the branch
//! `clip_polygon` takes with its tolerance `eps`: a point with signed distance `>= -eps` is
//! inside (kept with its own derivative), so on a tie the node is kept and the crossing
//! dropped; a crossing parameter `t` clamped to `[0, 1]` has `delta t = 0`; a vertex removed as
//! a duplicate (`dedupe_polygon`) passes its derivative to none, the one kept keeps its own;
//! a pair without overlap has no derivative. The tests check both sides of a switch away from
//! it (a slave node just inside and just outside the master).

// Deliberate: `!(a > b)` treats NaN as failing the test, which `a <= b` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::dual::{dual_basis_3d, invert_small, DualBasis};
use super::facet::Facet3;
use super::geom::*;
use super::linearize::Lin;

// ------------------------------------------------------------------------------------------
// 3D vectors with derivatives
// ------------------------------------------------------------------------------------------

/// The derivative of a 3D vector: one [`Lin`] per component.
pub type Lin3 = [Lin; 3];

/// A 3D vector with its derivative.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vec3Lin {
    pub value: Vec3,
    pub lin: Lin3,
}

impl Vec3Lin {
    /// The position of involved node `node`, `x`: its derivative is `delta x_node`.
    pub fn node(node: usize, x: Vec3) -> Vec3Lin {
        Vec3Lin { value: x, lin: lin3_node(node) }
    }
}

/// `delta x_node` as a vector.
pub fn lin3_node(node: usize) -> Lin3 {
    [Lin::unit(node, 0), Lin::unit(node, 1), Lin::unit(node, 2)]
}

/// `a . delta v`.
pub fn lin3_dot(a: Vec3, dv: &Lin3) -> Lin {
    Lin::sum(&[(a[0], &dv[0]), (a[1], &dv[1]), (a[2], &dv[2])])
}

/// `a x delta v` (so `delta v x b = -(b x delta v)`).
pub fn lin3_cross(a: Vec3, dv: &Lin3) -> Lin3 {
    [
        Lin::combine(a[1], &dv[2], -a[2], &dv[1]),
        Lin::combine(a[2], &dv[0], -a[0], &dv[2]),
        Lin::combine(a[0], &dv[1], -a[1], &dv[0]),
    ]
}

/// `sum_k s_k delta v_k` for vectors.
pub fn lin3_sum(terms: &[(f64, &Lin3)]) -> Lin3 {
    let part = |c: usize| Lin::sum(&terms.iter().map(|&(s, v)| (s, &v[c])).collect::<Vec<_>>());
    [part(0), part(1), part(2)]
}

/// The derivative along the perturbation `dir` (`dir[a][c]` = `delta x_(a,c)`), 3D nodes.
pub fn lin_apply3(l: &Lin, dir: &[Vec3]) -> f64 {
    l.entries().iter().map(|&((a, c), v)| v * dir[a][c]).sum()
}

/// `delta u = (I - u u^T) delta v / |v|` for the unit vector `u = v/|v|`.
fn normalize_lin3(u: Vec3, len: f64, dv: &Lin3) -> Lin3 {
    let along = lin3_dot(u, dv);
    [
        Lin::combine(1.0 / len, &dv[0], -u[0] / len, &along),
        Lin::combine(1.0 / len, &dv[1], -u[1] / len, &along),
        Lin::combine(1.0 / len, &dv[2], -u[2] / len, &along),
    ]
}

/// `(delta t_1, delta t_2)` at fixed `xi`: `delta t_a = sum_k dphi_k/dxi_a delta x_k`.
fn tangents_lin(facet: &Facet3, ids: &[usize], xi: Vec2) -> (Lin3, Lin3) {
    let d = facet.dshape(xi);
    let nodes: Vec<Lin3> = ids.iter().map(|&k| lin3_node(k)).collect();
    let part = |a: usize| {
        let terms: Vec<(f64, &Lin3)> = (0..facet.n_nodes()).map(|k| (d[k][a], &nodes[k])).collect();
        lin3_sum(&terms)
    };
    (part(0), part(1))
}

/// `delta n = delta t_1 x t_2 + t_1 x delta t_2` at fixed `xi`.
fn normal_raw_lin(facet: &Facet3, ids: &[usize], xi: Vec2) -> Lin3 {
    let (t1, t2) = facet.tangents(xi);
    let (dt1, dt2) = tangents_lin(facet, ids, xi);
    let a = lin3_cross(t2, &dt1);
    let b = lin3_cross(t1, &dt2);
    lin3_sum(&[(-1.0, &a), (1.0, &b)])
}

fn check_ids(facet: &Facet3, ids: &[usize]) -> Result<(), GeomError> {
    if ids.len() != facet.n_nodes() {
        return fail(format!("facet of {} nodes given {} ids", facet.n_nodes(), ids.len()));
    }
    Ok(())
}

// ------------------------------------------------------------------------------------------
// 1. Normals
// ------------------------------------------------------------------------------------------

/// Unit normal `e = n/|n|`, `n = t_1 x t_2`, of a tri3 or (possibly warped) quad4 facet (nodes
/// `ids`) at `xi`, and `delta e = (I - e e^T) delta n / |n|` with
/// `delta n = delta t_1 x t_2 + t_1 x delta t_2`, `delta t_a = sum_k dphi_k/dxi_a delta x_k`
/// (on a tri3 `t_a` are constant; on a warped quad4 they depend on `xi`, and so does `e`).
/// Err on a degenerate facet (`|n| <= 1e-14 size^2`, as `nodal_normals_3d`).
pub fn facet_normal_lin_3d(facet: &Facet3, ids: &[usize], xi: Vec2) -> Result<Vec3Lin, GeomError> {
    check_ids(facet, ids)?;
    let n = facet.normal(xi);
    let len = norm3(n);
    if !(len > 1e-14 * facet.size().powi(2) && len.is_finite()) {
        return fail(format!("facet {:?} is degenerate (no normal)", ids));
    }
    let e = scale3(1.0 / len, n);
    Ok(Vec3Lin { value: e, lin: normalize_lin3(e, len, &normal_raw_lin(facet, ids, xi)) })
}

/// [`nodal_normals_3d`](super::dual::nodal_normals_3d) with derivatives, on the same input
/// (`coords` is the list of involved nodes): `n_j = m_j/|m_j|`, `m_j = sum_(e around j) s e_e`
/// with `e_e` the facet unit normal at its parametric centre ([`facet_normal_lin_3d`]), `s = -1`
/// when `reverse`; `delta n_j = (I - n_j n_j^T) delta m_j / |m_j|`. Values bit for bit those of
/// `nodal_normals_3d`, the same errors; nodes on no facet get zero and no derivative.
pub fn nodal_normals_lin_3d<F: AsRef<[usize]>>(
    coords: &[Vec3],
    facets: &[F],
    reverse: bool,
) -> Result<Vec<Vec3Lin>, GeomError> {
    let sign = if reverse { -1.0 } else { 1.0 };
    let mut sum = vec![[0.0; 3]; coords.len()];
    let mut dsum: Vec<Lin3> = vec![Lin3::default(); coords.len()];
    let mut used = vec![false; coords.len()];
    for nodes in facets {
        let nodes = nodes.as_ref();
        let f = Facet3::from_nodes(coords, nodes)?;
        let xc = f.centre_param();
        let n = f.normal(xc);
        let len = norm3(n);
        if !(len > 1e-14 * f.size().powi(2) && len.is_finite()) {
            return fail(format!("facet {:?} is degenerate (no normal at its centre)", nodes));
        }
        let e = scale3(1.0 / len, n);
        let de = normalize_lin3(e, len, &normal_raw_lin(&f, nodes, xc));
        for &k in nodes {
            sum[k] = add3(sum[k], scale3(sign / len, n));
            for c in 0..3 {
                dsum[k][c].add_scaled(sign, &de[c]);
            }
            used[k] = true;
        }
    }
    let mut out = Vec::with_capacity(coords.len());
    for ((m, dm), &u) in sum.into_iter().zip(dsum.iter()).zip(used.iter()) {
        if !u {
            out.push(Vec3Lin { value: m, lin: Lin3::default() });
            continue;
        }
        let len = norm3(m);
        if !(len > 1e-8) {
            return fail(format!("node {} has opposite facet normals that cancel", out.len()));
        }
        let n = scale3(1.0 / len, m);
        out.push(Vec3Lin { value: n, lin: normalize_lin3(n, len, dm) });
    }
    Ok(out)
}

// ------------------------------------------------------------------------------------------
// 2. Jacobian, D and the dual basis
// ------------------------------------------------------------------------------------------

/// Surface Jacobian `J = |n|` of a facet at `xi` and `delta J = n . delta n / J`.
pub fn jacobian_lin_3d(facet: &Facet3, ids: &[usize], xi: Vec2) -> (f64, Lin) {
    let n = facet.normal(xi);
    let j = facet.jacobian(xi);
    (j, lin3_dot(scale3(1.0 / j, n), &normal_raw_lin(facet, ids, xi)))
}

/// [`dual_basis_3d`] with derivatives.
#[derive(Clone, Debug, PartialEq)]
pub struct DualBasisLin {
    /// `dual_basis_3d(facet)`, bit for bit.
    pub value: DualBasis,
    /// `delta d_j`, `d_j = D_jj = int_e phi_j`.
    pub d: [Lin; 4],
    /// `delta A_ik`.
    pub a: [[Lin; 4]; 4],
}

/// [`dual_basis_3d`] of a tri3/quad4 slave facet (nodes `ids`) with derivatives. With the
/// facet quadrature `(xi_g, w_g)` and `W_g = w_g J(xi_g)`:
///
/// ```text
/// d_j  = sum_g W_g phi_j(xi_g),           delta d_j  = sum_g phi_j delta W_g
/// M_ij = sum_g W_g phi_i phi_j,           delta M_ij = sum_g phi_i phi_j delta W_g
/// A    = D M^{-1},                        delta A    = delta D M^{-1} - D M^{-1} delta M M^{-1}
/// ```
///
/// with `delta W_g = w_g delta J(xi_g)` ([`jacobian_lin_3d`]). On an affine triangle `J` is
/// constant, `d_j = J/6` and `M_ij = J (1 + delta_ij)/24`, so
/// `A = D M^{-1} = [[3,-1,-1],[-1,3,-1],[-1,-1,3]]` whatever the nodes: the `J`s cancel and the
/// formula above gives `delta A = (delta J / J)(A - A) = 0` (to round-off; the tests check it
/// by differences). On a general (non-parallelogram or warped) quad `J` varies over the facet
/// and `A` moves with the nodes. Err as `dual_basis_3d`.
pub fn dual_basis_lin_3d(facet: &Facet3, ids: &[usize]) -> Result<DualBasisLin, GeomError> {
    check_ids(facet, ids)?;
    let value = dual_basis_3d(facet)?;
    let n = facet.n_nodes();
    let mut m = [[0.0; 4]; 4];
    let mut dd: [Lin; 4] = Default::default();
    let mut dm: [[Lin; 4]; 4] = Default::default();
    for (xi, w) in facet.quadrature() {
        let phi = facet.shape(xi);
        let wj = w * facet.jacobian(xi);
        let (_, dj) = jacobian_lin_3d(facet, ids, xi);
        let dwj = dj.scale(w);
        for i in 0..n {
            dd[i].add_scaled(phi[i], &dwj);
            for j in 0..n {
                m[i][j] += wj * phi[i] * phi[j];
                dm[i][j].add_scaled(phi[i] * phi[j], &dwj);
            }
        }
    }
    let minv = invert_small(&m, n)?;
    let d = value.d;
    let mut da: [[Lin; 4]; 4] = Default::default();
    for i in 0..n {
        for k in 0..n {
            // delta A_ik = delta d_i Minv_ik - d_i sum_(a,b) Minv_ia delta M_ab Minv_bk
            let mut terms: Vec<(f64, &Lin)> = vec![(minv[i][k], &dd[i])];
            for (a, row) in dm.iter().enumerate().take(n) {
                for (b, dmab) in row.iter().enumerate().take(n) {
                    terms.push((-d[i] * minv[i][a] * minv[b][k], dmab));
                }
            }
            da[i][k] = Lin::sum(&terms);
        }
    }
    Ok(DualBasisLin { value, d: dd, a: da })
}

#[cfg(test)]
#[path = "linearize3d_tests.rs"]
mod tests;
