//! Directional derivatives ("linearizations") of the 3D mortar geometry, for finite sliding
//! (Popp, Gitterle, Gee, Wall, IJNME 2010; docs/method.md, frozen and following interfaces).
//!
//! The 3D counterpart of `linearize.rs`, with its conventions: every function takes the
//! inputs of its counterpart in `dual.rs`/`segment.rs` plus the node ids, and returns the
//! counterpart's value (computed by the same expressions in the same order, so bit for bit
//! the same) together with its derivative as a [`Lin`] keyed by `(involved node, component)`,
//! components 0, 1, 2 = x, y, z. A 3D vector carries one `Lin` per component ([`Lin3`],
//! [`Vec3Lin`]). The solver uses it for the consistent force with `-mortar_jacobian
//! closed_form` (gradient.rs).
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
//!
//! Matching meshes sit on a switch at every vertex (each master node projects onto a slave
//! node). There the master nodes are kept (`>= -eps`), so the derivative returned is that of
//! the polygon of the projected master nodes: exact along motions that keep the meshes
//! matching (tested: touching matched facets moved together), one-sided otherwise (the side
//! where the master nodes move into the slave facet); across the switch a single pair's `M`
//! and `g` have a kink and their central differences do not converge (tested, with a gap).
//! CAUTION, not yet resolved: this is not the side 2D takes. In 2D a tie keeps the slave end
//! (no boundary-motion term), and the neighbouring pair, touching, has none either, so the
//! sum over the master facets around the node has the derivative of both sides. Here the
//! kept master node carries its own motion (a boundary-motion term) while the neighbouring
//! master facet's pair, of zero area at the tie, contributes nothing: the assembled
//! derivative at exactly matching meshes misses the neighbour's share. Choosing the slave
//! side at ties (a tied vertex moving with the slave edge/node it lies on) is left to the
//! next step, before this is wired into the solver.

// Deliberate: `!(a > b)` treats NaN as failing the test, which `a <= b` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::dual::{dual_basis_3d, invert_small, DualBasis};
use super::facet::Facet3;
use super::geom::*;
use super::linearize::{lin2_cross, Lin, Lin2, Vec2Lin};
use super::segment::{
    check_pair_3d, clip_rule, invert_on_plane, is_convex_ccw, polygon_area, AuxPlane, PairIntegrals,
};

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

/// `delta v + a delta s` for a vector `v` and a scalar `s`.
fn lin3_add_scalar(dv: &Lin3, a: Vec3, ds: &Lin) -> Lin3 {
    [
        Lin::combine(1.0, &dv[0], a[0], ds),
        Lin::combine(1.0, &dv[1], a[1], ds),
        Lin::combine(1.0, &dv[2], a[2], ds),
    ]
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

/// `delta x(xi) = sum_k phi_k(xi) delta x_k` at fixed `xi`.
fn position_lin(facet: &Facet3, ids: &[usize], xi: Vec2) -> Lin3 {
    let phi = facet.shape(xi);
    let nodes: Vec<Lin3> = ids.iter().map(|&k| lin3_node(k)).collect();
    let terms: Vec<(f64, &Lin3)> = (0..facet.n_nodes()).map(|k| (phi[k], &nodes[k])).collect();
    lin3_sum(&terms)
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

// ------------------------------------------------------------------------------------------
// 3. Auxiliary plane, projection, clipping, inverse map
// ------------------------------------------------------------------------------------------

/// [`AuxPlane`] with the derivatives of its centre, normal and in-plane basis.
#[derive(Clone, Debug, PartialEq)]
pub struct AuxPlaneLin {
    /// `AuxPlane::of_slave(slave)`, bit for bit.
    pub value: AuxPlane,
    pub centre: Lin3,
    pub normal: Lin3,
    pub e1: Lin3,
    pub e2: Lin3,
}

/// [`AuxPlane::of_slave`] with derivatives (slave nodes `ids`):
///
/// ```text
/// x0 = x(xi_c):                 delta x0 = sum_k phi_k(xi_c) delta x_k
/// n0 = n(xi_c)/|n(xi_c)|:       delta n0 as facet_normal_lin_3d at xi_c
/// v  = d - (d . n0) n0, d = x_1 - x_0:
///     delta v = delta d - (delta d . n0 + d . delta n0) n0 - (d . n0) delta n0
/// e1 = v/|v|:                   delta e1 = (I - e1 e1^T) delta v / |v|
/// e2 = n0 x e1:                 delta e2 = delta n0 x e1 + n0 x delta e1
/// ```
pub fn aux_plane_lin(slave: &Facet3, ids: &[usize]) -> Result<AuxPlaneLin, GeomError> {
    check_ids(slave, ids)?;
    let value = AuxPlane::of_slave(slave)?;
    let xc = slave.centre_param();
    let centre = position_lin(slave, ids, xc);
    let len = norm3(slave.normal(xc));
    let n0 = value.normal;
    let normal = normalize_lin3(n0, len, &normal_raw_lin(slave, ids, xc));
    let d = sub3(slave.nodes()[1], slave.nodes()[0]);
    let dd = lin3_sum(&[(1.0, &lin3_node(ids[1])), (-1.0, &lin3_node(ids[0]))]);
    let dn = dot3(d, n0);
    let v = sub3(d, scale3(dn, n0));
    let lv = norm3(v);
    let ddn = Lin::combine(1.0, &lin3_dot(n0, &dd), 1.0, &lin3_dot(d, &normal));
    let dv = lin3_add_scalar(&lin3_sum(&[(1.0, &dd), (-dn, &normal)]), scale3(-1.0, n0), &ddn);
    let e1 = normalize_lin3(value.e1, lv, &dv);
    let a = lin3_cross(value.e1, &normal);
    let b = lin3_cross(n0, &e1);
    let e2 = lin3_sum(&[(-1.0, &a), (1.0, &b)]);
    Ok(AuxPlaneLin { value, centre, normal, e1, e2 })
}

impl AuxPlaneLin {
    /// [`AuxPlane::coords`] of a point `x` with derivatives: `q_a = (x - x0) . e_a`,
    /// `delta q_a = e_a . (delta x - delta x0) + (x - x0) . delta e_a`.
    pub fn coords_lin(&self, x: &Vec3Lin) -> Vec2Lin {
        let value = self.value.coords(x.value);
        let r = sub3(x.value, self.value.centre);
        let dr = lin3_sum(&[(1.0, &x.lin), (-1.0, &self.centre)]);
        let part = |e: Vec3, de: &Lin3| Lin::combine(1.0, &lin3_dot(e, &dr), 1.0, &lin3_dot(r, de));
        Vec2Lin { value, lin: [part(self.value.e1, &self.e1), part(self.value.e2, &self.e2)] }
    }
}

/// [`invert_on_plane`] with derivatives: `xi` with `F(xi) = P(x(xi)) - q = 0`, `P` the plane
/// coordinates of `plane`, `x` the facet map (nodes `ids`). Implicit differentiation:
///
/// ```text
/// delta xi = -J_P^{-1} [ delta P(x(xi))|_(xi fixed) - delta q ],
/// J_P = [[t_1 . e1, t_2 . e1], [t_1 . e2, t_2 . e2]]
/// ```
///
/// with `delta P` from [`AuxPlaneLin::coords_lin`] of `x(xi)` moving as
/// `sum_k phi_k(xi) delta x_k`. Same value (bit for bit) and errors as `invert_on_plane`.
pub fn invert_on_plane_lin(
    facet: &Facet3,
    ids: &[usize],
    plane: &AuxPlaneLin,
    q: &Vec2Lin,
) -> Result<(Vec2, Lin2), GeomError> {
    check_ids(facet, ids)?;
    let xi = invert_on_plane(facet, &plane.value, q.value)?;
    let (t1, t2) = facet.tangents(xi);
    let (e1, e2) = (plane.value.e1, plane.value.e2);
    let (a, b) = (dot3(t1, e1), dot3(t2, e1));
    let (c, d) = (dot3(t1, e2), dot3(t2, e2));
    let det = a * d - b * c;
    let x = Vec3Lin { value: facet.position(xi), lin: position_lin(facet, ids, xi) };
    let p = plane.coords_lin(&x);
    let f0 = Lin::combine(1.0, &p.lin[0], -1.0, &q.lin[0]);
    let f1 = Lin::combine(1.0, &p.lin[1], -1.0, &q.lin[1]);
    Ok((xi, [Lin::combine(-d / det, &f0, b / det, &f1), Lin::combine(c / det, &f0, -a / det, &f1)]))
}

/// What a vertex of the clipped polygon is (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PolyVertex {
    /// The projection of master node `l`.
    Master(usize),
    /// The projection of slave node `k`.
    Slave(usize),
    /// The crossing of master edge `l -> l+1` with slave edge `k -> k+1` (node numbers of the
    /// facets, cyclic).
    Crossing { master_edge: usize, slave_edge: usize },
    /// A degenerate vertex on fewer than two distinct lines (collinear input).
    Other,
}

/// An edge line of the projected facets: master edge `l -> l+1` or slave edge `k -> k+1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum EdgeLine {
    Master(usize),
    Slave(usize),
}

/// A vertex with its derivative and the edge lines it lies on.
#[derive(Clone, Debug)]
struct Vert {
    p: Vec2Lin,
    lines: Vec<EdgeLine>,
}

fn kind_of(lines: &[EdgeLine], nm: usize, ns: usize) -> PolyVertex {
    let m: Vec<usize> = lines
        .iter()
        .filter_map(|l| if let EdgeLine::Master(e) = l { Some(*e) } else { None })
        .collect();
    let s: Vec<usize> = lines
        .iter()
        .filter_map(|l| if let EdgeLine::Slave(e) = l { Some(*e) } else { None })
        .collect();
    let node = |e: &[usize], n: usize| -> Option<usize> {
        // Two edges of one facet share a node: e and e+1 share node e+1.
        let (a, b) = (*e.first()?, *e.get(1)?);
        if (a + 1) % n == b {
            Some(b)
        } else if (b + 1) % n == a {
            Some(a)
        } else {
            None
        }
    };
    if let Some(l) = node(&m, nm) {
        PolyVertex::Master(l)
    } else if let Some(k) = node(&s, ns) {
        PolyVertex::Slave(k)
    } else if let (Some(&l), Some(&k)) = (m.first(), s.first()) {
        PolyVertex::Crossing { master_edge: l, slave_edge: k }
    } else {
        PolyVertex::Other
    }
}

/// `clip_polygon` on vertices with derivatives (same arithmetic, same branches; the module
/// docs give the crossing's derivative). `clip[i]` lies on slave lines `i-1` and `i`.
fn clip_polygon_lin(subject: Vec<Vert>, clip: &[Vec2Lin], eps: f64) -> Vec<Vert> {
    let mut out = subject;
    let nc = clip.len();
    for i in 0..nc {
        if out.is_empty() {
            break;
        }
        let (a, b) = (&clip[i], &clip[(i + 1) % nc]);
        let e = sub2(b.value, a.value);
        let de = [
            Lin::combine(1.0, &b.lin[0], -1.0, &a.lin[0]),
            Lin::combine(1.0, &b.lin[1], -1.0, &a.lin[1]),
        ];
        let side = |p: Vec2| cross2(e, sub2(p, a.value));
        // delta d = e x (delta p - delta a) - (p - a) x delta e
        let dside = |p: &Vec2Lin| {
            let dr = [
                Lin::combine(1.0, &p.lin[0], -1.0, &a.lin[0]),
                Lin::combine(1.0, &p.lin[1], -1.0, &a.lin[1]),
            ];
            Lin::combine(1.0, &lin2_cross(e, &dr), -1.0, &lin2_cross(sub2(p.value, a.value), &de))
        };
        let crossing = |s: &Vert, ds: f64, p: &Vert, dp: f64| -> Vert {
            let raw = ds / (ds - dp);
            let t = raw.clamp(0.0, 1.0);
            let value = add2(s.p.value, scale2(t, sub2(p.p.value, s.p.value)));
            let dt = if t == raw {
                let (dds, ddp) = (dside(&s.p), dside(&p.p));
                Lin::combine(ds, &ddp, -dp, &dds).scale(1.0 / ((ds - dp) * (ds - dp)))
            } else {
                Lin::zero()
            };
            let sp = sub2(p.p.value, s.p.value);
            let part =
                |c: usize| Lin::sum(&[(1.0 - t, &s.p.lin[c]), (t, &p.p.lin[c]), (sp[c], &dt)]);
            let common: Vec<EdgeLine> =
                s.lines.iter().filter(|l| p.lines.contains(l)).copied().collect();
            let mut lines = common;
            lines.push(EdgeLine::Slave(i));
            Vert { p: Vec2Lin { value, lin: [part(0), part(1)] }, lines }
        };
        let input = std::mem::take(&mut out);
        let mut s = input[input.len() - 1].clone();
        let mut ds = side(s.p.value);
        for p in &input {
            let dp = side(p.p.value);
            if dp >= -eps {
                if ds < -eps {
                    out.push(crossing(&s, ds, p, dp));
                }
                out.push(p.clone());
            } else if ds >= -eps {
                out.push(crossing(&s, ds, p, dp));
            }
            s = p.clone();
            ds = dp;
        }
    }
    out
}

/// `dedupe_polygon` on vertices with derivatives (the first of close neighbours is kept).
fn dedupe_polygon_lin(p: Vec<Vert>, tol: f64) -> Vec<Vert> {
    let mut out: Vec<Vert> = Vec::with_capacity(p.len());
    for q in p {
        if out.last().is_none_or(|l| norm2(sub2(q.p.value, l.p.value)) > tol) {
            out.push(q);
        }
    }
    while out.len() > 1 && norm2(sub2(out[0].p.value, out[out.len() - 1].p.value)) <= tol {
        out.pop();
    }
    out
}

// ------------------------------------------------------------------------------------------
// Pair integrals
// ------------------------------------------------------------------------------------------

/// The ids (in the caller's list of involved nodes) of a 3D pair's facet nodes: the first
/// `n_nodes` entries of each are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairIds3 {
    pub slave: [usize; 4],
    pub master: [usize; 4],
}

/// [`PairIntegrals`] of a 3D pair with the derivatives of every entry and of the polygon.
#[derive(Clone, Debug, PartialEq)]
pub struct PairIntegralsLin3 {
    /// The integrals, identical to `mortar_pair_3d`'s.
    pub value: PairIntegrals,
    /// The clipped polygon (aux-plane coordinates, counter-clockwise), what each vertex is,
    /// and the vertices' derivatives.
    pub polygon: Vec<Vec2>,
    pub kinds: Vec<PolyVertex>,
    pub polygon_lin: Vec<Lin2>,
    /// The polygon's vertex centroid `c` (the common corner of the sub-triangles) and its
    /// derivative.
    pub centre: Vec2,
    pub centre_lin: Lin2,
    /// The signed areas of the sub-triangles `(c, p_i, p_(i+1))` and their derivatives (a
    /// sub-triangle of area `<= 0`, a sliver left by clipping, contributes nothing).
    pub sub_areas: Vec<f64>,
    pub sub_areas_lin: Vec<Lin>,
    /// `delta M_jl`.
    pub m: [[Lin; 4]; 4],
    /// `delta N_j`, `N_j = int_overlap psi_j`.
    pub psi_integral: [Lin; 4],
    /// `delta g_j`.
    pub weighted_gap: [Lin; 4],
    /// `delta int_overlap 1`.
    pub overlap_measure: Lin,
}

/// [`mortar_pair_3d`](super::segment::mortar_pair_3d) with derivatives: the same input
/// (`dual` must be `dual_basis_3d(slave)`), plus the pair's node ids and the derivatives
/// `normals_lin` of `slave_normals` (e.g. from [`nodal_normals_lin_3d`]). Same value (bit for
/// bit), same `Ok(None)` and errors.
///
/// Following the steps of `mortar_pair_3d`:
///
/// 1. Aux plane ([`aux_plane_lin`]); every slave and master node projected,
///    `q = P(x)` ([`AuxPlaneLin::coords_lin`]).
/// 2. Clipped polygon: [`PolyVertex`] kinds and derivatives by the chain rule through the
///    clipping (module docs).
/// 3. Centre `c = (1/n) sum_i p_i`, `delta c = (1/n) sum_i delta p_i`; sub-triangle
///    `(c, p_i, p_(i+1))` of area `a = (p_i - c) x (p_(i+1) - c) / 2`,
///    `delta a = ((p_i - c) x (delta p_(i+1) - delta c) - (p_(i+1) - c) x (delta p_i - delta c))/2`;
///    Gauss point `q = l_0 c + l_1 p_i + l_2 p_(i+1)` (fixed barycentrics), weight `W = w a`.
/// 4. `xi_s`, `xi_m` by [`invert_on_plane_lin`] (the slave's and the master's own node ids).
/// 5. `delta psi_j = sum_k (delta A_jk phi_k + A_jk grad phi_k . delta xi_s)`
///    ([`dual_basis_lin_3d`]: `A` moves on a general quad); `delta phi_l(xi_m) =
///    grad phi_l . delta xi_m`.
/// 6. Gap `r = y(xi_m) - x(xi_s)`: `delta r = sum_l phi_l delta y_l + [t_1m t_2m] delta xi_m
///    - sum_k phi_k delta x_k - [t_1s t_2s] delta xi_s`; `delta gn_j = r . delta n_j + n_j . delta r`.
/// 7. With `w_j = W psi_j`: `delta M_jl += phi_l delta w_j + w_j delta phi_l`,
///    `delta N_j += delta w_j`, `delta g_j += gn_j delta w_j + w_j delta gn_j`,
///    `delta |overlap| += delta W`.
pub fn mortar_pair_lin_3d(
    slave: &Facet3,
    slave_normals: &[Vec3],
    dual: &DualBasis,
    master: &Facet3,
    ids: PairIds3,
    normals_lin: &[Lin3],
) -> Result<Option<PairIntegralsLin3>, GeomError> {
    let ns = slave.n_nodes();
    let nm = master.n_nodes();
    // The checks of mortar_pair_3d, and one normal derivative per slave node.
    check_pair_3d(slave, slave_normals, dual, master)?;
    if normals_lin.len() != ns {
        return fail(format!(
            "3D mortar pair: slave facet has {} nodes but {} normal derivatives",
            ns,
            normals_lin.len()
        ));
    }
    let sid = &ids.slave[..ns];
    let mid = &ids.master[..nm];
    let plane = aux_plane_lin(slave, sid)?;
    let sp: Vec<Vec2Lin> = slave
        .nodes()
        .iter()
        .zip(sid)
        .map(|(&x, &k)| plane.coords_lin(&Vec3Lin::node(k, x)))
        .collect();
    let spv: Vec<Vec2> = sp.iter().map(|p| p.value).collect();
    let s_area = polygon_area(&spv);
    let h2 = slave.size().powi(2);
    if !(s_area > 1e-14 * h2) {
        return fail("slave facet projects to a degenerate or clockwise polygon on its aux plane");
    }
    if !is_convex_ccw(&spv, 1e-12 * h2) {
        return fail("slave facet projects to a non-convex polygon on its aux plane");
    }
    let mut mp: Vec<Vert> = master
        .nodes()
        .iter()
        .zip(mid)
        .enumerate()
        .map(|(l, (&x, &k))| Vert {
            p: plane.coords_lin(&Vec3Lin::node(k, x)),
            lines: vec![EdgeLine::Master((l + nm - 1) % nm), EdgeLine::Master(l)],
        })
        .collect();
    let mpv: Vec<Vec2> = mp.iter().map(|v| v.p.value).collect();
    if !(polygon_area(&mpv) < -1e-12 * s_area) {
        return Ok(None);
    }
    mp.reverse();
    let h = s_area.sqrt();
    let poly = dedupe_polygon_lin(clip_polygon_lin(mp, &sp, 1e-13 * h2), 1e-12 * h);
    let pv: Vec<Vec2> = poly.iter().map(|v| v.p.value).collect();
    if poly.len() < 3 || !(polygon_area(&pv) > 1e-12 * s_area) {
        return Ok(None);
    }
    let kinds: Vec<PolyVertex> = poly.iter().map(|v| kind_of(&v.lines, nm, ns)).collect();
    let inv_n = 1.0 / poly.len() as f64;
    let c = pv.iter().fold([0.0; 2], |acc, &p| add2(acc, scale2(inv_n, p)));
    let dc: Lin2 = {
        let part =
            |k: usize| Lin::sum(&poly.iter().map(|v| (inv_n, &v.p.lin[k])).collect::<Vec<_>>());
        [part(0), part(1)]
    };
    let sub_lin = |a: &Lin2, b: &Lin2| -> Lin2 {
        [Lin::combine(1.0, &a[0], -1.0, &b[0]), Lin::combine(1.0, &a[1], -1.0, &b[1])]
    };

    let dual_lin = dual_basis_lin_3d(slave, sid)?;
    let rule = clip_rule(slave, master);
    let mut out = PairIntegrals::zero(ns, nm);
    out.slave_measure = s_area;
    let mut dm: [[Lin; 4]; 4] = Default::default();
    let mut dnint: [Lin; 4] = Default::default();
    let mut dgap: [Lin; 4] = Default::default();
    let mut dmeas = Lin::zero();
    let mut sub_areas = Vec::with_capacity(poly.len());
    let mut sub_areas_lin = Vec::with_capacity(poly.len());
    for i in 0..poly.len() {
        let (v1, v2) = (&poly[i], &poly[(i + 1) % poly.len()]);
        let (p1, p2) = (v1.p.value, v2.p.value);
        let area = 0.5 * cross2(sub2(p1, c), sub2(p2, c));
        let (r1, r2) = (sub2(p1, c), sub2(p2, c));
        let (dr1, dr2) = (sub_lin(&v1.p.lin, &dc), sub_lin(&v2.p.lin, &dc));
        let darea = Lin::combine(0.5, &lin2_cross(r1, &dr2), -0.5, &lin2_cross(r2, &dr1));
        sub_areas.push(area);
        sub_areas_lin.push(darea.clone());
        if !(area > 0.0) {
            continue;
        }
        for (l, w) in rule.iter() {
            let q = add2(add2(scale2(l[0], c), scale2(l[1], p1)), scale2(l[2], p2));
            let dq = {
                let part = |k: usize| {
                    Lin::sum(&[(l[0], &dc[k]), (l[1], &v1.p.lin[k]), (l[2], &v2.p.lin[k])])
                };
                [part(0), part(1)]
            };
            let ql = Vec2Lin { value: q, lin: dq };
            let (xs, dxs) = invert_on_plane_lin(slave, sid, &plane, &ql)?;
            let (xm, dxm) = invert_on_plane_lin(master, mid, &plane, &ql)?;
            let phis = slave.shape(xs);
            let psi = dual.psi(&phis);
            let gs = slave.dshape(xs);
            let dphis: Vec<Lin> =
                (0..ns).map(|k| Lin::combine(gs[k][0], &dxs[0], gs[k][1], &dxs[1])).collect();
            let dpsi: Vec<Lin> = (0..ns)
                .map(|j| {
                    let mut terms: Vec<(f64, &Lin)> = Vec::new();
                    for k in 0..ns {
                        terms.push((phis[k], &dual_lin.a[j][k]));
                        terms.push((dual.a[j][k], &dphis[k]));
                    }
                    Lin::sum(&terms)
                })
                .collect();
            let phim = master.shape(xm);
            let gm = master.dshape(xm);
            let dphim: Vec<Lin> =
                (0..nm).map(|k| Lin::combine(gm[k][0], &dxm[0], gm[k][1], &dxm[1])).collect();
            let gap = sub3(master.position(xm), slave.position(xs));
            let (tm1, tm2) = master.tangents(xm);
            let (ts1, ts2) = slave.tangents(xs);
            let dgv = {
                let ym = position_lin(master, mid, xm);
                let xsl = position_lin(slave, sid, xs);
                let a = lin3_add_scalar(&lin3_add_scalar(&ym, tm1, &dxm[0]), tm2, &dxm[1]);
                let b = lin3_add_scalar(&lin3_add_scalar(&xsl, ts1, &dxs[0]), ts2, &dxs[1]);
                lin3_sum(&[(1.0, &a), (-1.0, &b)])
            };
            let mut gn = [0.0; 4];
            for (g, n) in gn.iter_mut().zip(slave_normals.iter()) {
                *g = dot3(*n, gap);
            }
            out.add_point(w * area, &psi, &phim, &gn);
            out.add_primal(w * area, &phis, &phim, &gn);
            let wg = w * area;
            let dwg = darea.scale(*w);
            for j in 0..ns {
                let wj = wg * psi[j];
                let dwj = Lin::combine(psi[j], &dwg, wg, &dpsi[j]);
                let dgn = Lin::combine(
                    1.0,
                    &lin3_dot(gap, &normals_lin[j]),
                    1.0,
                    &lin3_dot(slave_normals[j], &dgv),
                );
                dnint[j].add_scaled(1.0, &dwj);
                dgap[j] = Lin::sum(&[(1.0, &dgap[j]), (gn[j], &dwj), (wj, &dgn)]);
                for l in 0..nm {
                    dm[j][l] = Lin::sum(&[(1.0, &dm[j][l]), (phim[l], &dwj), (wj, &dphim[l])]);
                }
            }
            dmeas.add_scaled(1.0, &dwg);
        }
    }
    Ok(Some(PairIntegralsLin3 {
        value: out,
        polygon: pv,
        kinds,
        polygon_lin: poly.into_iter().map(|v| v.p.lin).collect(),
        centre: c,
        centre_lin: dc,
        sub_areas,
        sub_areas_lin,
        m: dm,
        psi_integral: dnint,
        weighted_gap: dgap,
        overlap_measure: dmeas,
    }))
}

#[cfg(test)]
#[path = "linearize3d_tests.rs"]
mod tests;
