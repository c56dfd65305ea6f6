//! Directional derivatives ("linearizations") of the 2D mortar geometry, for finite sliding
//! (Popp, Gee, Wall, IJNME 2009; docs/method.md, frozen and following interfaces).
//!
//! Everything here is a pure function of the same inputs as its counterpart in
//! `dual.rs`/`segment.rs` plus node ids, and returns the counterpart's value (computed by the
//! same expressions, so bit for bit the same) together with its derivative with respect to
//! the coordinates of every node it depends on. The solver uses it for the consistent force
//! of an interface that follows the bodies with `-mortar_jacobian closed_form` (gradient.rs).
//!
//! # Convention
//!
//! A derivative is a [`Lin`]: a sparse linear form `delta q = sum_(a,c) v_(a,c) delta x_(a,c)`
//! stored as the sorted list of `((a, c), v)`, where `a` is an index into the CALLER's list of
//! involved nodes and `c` the coordinate component (0 = x, 1 = y). The caller chooses the list:
//! for one slave/master facet pair it holds the two slave facet nodes, the two master facet
//! nodes and the slave neighbours that enter the averaged nodal normals; the functions take the
//! ids of the nodes they touch (`ids`, `PairIds2`) and never look at the list itself. A vector
//! quantity carries one `Lin` per component ([`Lin2`], [`Vec2Lin`]).
//!
//! Notation in the formulas below: `a x b = a_x b_y - a_y b_x` (2D cross product),
//! `phi_1 = (1 - xi)/2`, `phi_2 = (1 + xi)/2`, `phi' = (-1/2, 1/2)`; slave facet `x_1 -> x_2`
//! with `t = (x_2 - x_1)/2`, `J = |t|`; master facet `y_1 -> y_2` with `t_m = (y_2 - y_1)/2`;
//! `delta` is the directional derivative.
//!
//! # Switching points
//!
//! The integrals of one pair are piecewise smooth in the coordinates: the segment end switches
//! between a slave node (fixed `xi = -1` or `+1`) and a master node's projection, and the
//! overlap appears or vanishes. At a switching point the derivative returned is ONE-SIDED: on
//! a tie between a slave end and a master node's projection the slave end is kept (the
//! derivative of the side where the master covers the slave node), a projection within the
//! tolerance outside `[-1, 1]` that is clamped has derivative zero, and a pair without overlap
//! (`Ok(None)`, also at the touching point) has derivative zero. Summed over the master facets
//! around the switching node the first derivatives agree from both sides (the integrand is
//! continuous across a master node), the second derivatives do not: at matching meshes the
//! central differences of an assembled `M` converge only to first order (the test
//! `matching_meshes_assembled` shows it, and that Richardson extrapolation restores h^2).

// Deliberate: `!(a > b)` treats NaN as failing the test, which `a <= b` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use super::dual::{dual_basis_2d, DualBasis};
use super::facet::{dshape_line2, shape_line2, Facet2};
use super::geom::*;
use super::segment::{
    check_pair_2d, project_onto_master_2d, project_onto_slave_2d, PairIntegrals, PARAM_TOL,
};
use crate::fem::quadrature::gauss_legendre;

// ------------------------------------------------------------------------------------------
// The sparse derivative
// ------------------------------------------------------------------------------------------

/// A coordinate of an involved node: `(node, component)`, node an index into the caller's list
/// of involved nodes, component 0 (x) or 1 (y).
pub type NodeComp = (usize, usize);

/// A directional derivative `delta q = sum v_(a,c) delta x_(a,c)`: the entries `((a, c), v)`
/// sorted by `(a, c)`, each key at most once (see the module docs for the node numbering).
/// Entries that cancel to 0.0 are kept: the pattern is the set of coordinates the quantity
/// can depend on.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lin {
    entries: Vec<(NodeComp, f64)>,
}

/// The derivative of a 2D vector: one [`Lin`] per component.
pub type Lin2 = [Lin; 2];

impl Lin {
    /// The zero derivative (no entries).
    pub fn zero() -> Lin {
        Lin { entries: Vec::new() }
    }

    /// `delta x_(node, comp)`: the derivative of one coordinate.
    pub fn unit(node: usize, comp: usize) -> Lin {
        Lin { entries: vec![((node, comp), 1.0)] }
    }

    /// From any entries: sorted, duplicate keys summed.
    pub fn from_entries(entries: impl IntoIterator<Item = (NodeComp, f64)>) -> Lin {
        let mut e: Vec<(NodeComp, f64)> = entries.into_iter().collect();
        e.sort_by_key(|&(k, _)| k);
        let mut out: Vec<(NodeComp, f64)> = Vec::with_capacity(e.len());
        for (k, v) in e {
            match out.last_mut() {
                Some(last) if last.0 == k => last.1 += v,
                _ => out.push((k, v)),
            }
        }
        Lin { entries: out }
    }

    /// The entries `((node, comp), value)`, sorted.
    pub fn entries(&self) -> &[(NodeComp, f64)] {
        &self.entries
    }

    /// The coefficient of `delta x_(node, comp)` (0 if absent).
    pub fn get(&self, node: usize, comp: usize) -> f64 {
        match self.entries.binary_search_by_key(&(node, comp), |&(k, _)| k) {
            Ok(i) => self.entries[i].1,
            Err(_) => 0.0,
        }
    }

    /// True if every coefficient is exactly zero (or there are none).
    pub fn is_zero(&self) -> bool {
        self.entries.iter().all(|&(_, v)| v == 0.0)
    }

    /// Largest coefficient magnitude.
    pub fn max_abs(&self) -> f64 {
        self.entries.iter().fold(0.0, |m, &(_, v)| m.max(v.abs()))
    }

    /// `s * self`.
    pub fn scale(&self, s: f64) -> Lin {
        Lin { entries: self.entries.iter().map(|&(k, v)| (k, s * v)).collect() }
    }

    /// `self + other`.
    pub fn add(&self, other: &Lin) -> Lin {
        Lin::combine(1.0, self, 1.0, other)
    }

    /// `a x + b y` (a merge of the two sorted lists).
    pub fn combine(a: f64, x: &Lin, b: f64, y: &Lin) -> Lin {
        let (p, q) = (&x.entries, &y.entries);
        let mut out = Vec::with_capacity(p.len() + q.len());
        let (mut i, mut j) = (0, 0);
        while i < p.len() || j < q.len() {
            if j == q.len() || (i < p.len() && p[i].0 < q[j].0) {
                out.push((p[i].0, a * p[i].1));
                i += 1;
            } else if i == p.len() || q[j].0 < p[i].0 {
                out.push((q[j].0, b * q[j].1));
                j += 1;
            } else {
                out.push((p[i].0, a * p[i].1 + b * q[j].1));
                i += 1;
                j += 1;
            }
        }
        Lin { entries: out }
    }

    /// `sum_k s_k x_k`.
    pub fn sum(terms: &[(f64, &Lin)]) -> Lin {
        Lin::from_entries(
            terms.iter().flat_map(|&(s, x)| x.entries.iter().map(move |&(k, v)| (k, s * v))),
        )
    }

    /// `self += s * other`.
    pub fn add_scaled(&mut self, s: f64, other: &Lin) {
        *self = Lin::combine(1.0, self, s, other);
    }

    /// The derivative along the perturbation `dir` (`dir[a][c]` = `delta x_(a,c)`):
    /// `sum v_(a,c) dir[a][c]`. Panics if an entry's node is beyond `dir`.
    pub fn apply(&self, dir: &[Vec2]) -> f64 {
        self.entries.iter().map(|&((a, c), v)| v * dir[a][c]).sum()
    }
}

/// `delta x_node` as a vector: `[delta x_(node,0), delta x_(node,1)]`.
pub fn lin2_node(node: usize) -> Lin2 {
    [Lin::unit(node, 0), Lin::unit(node, 1)]
}

/// `a . delta v`.
pub fn lin2_dot(a: Vec2, dv: &Lin2) -> Lin {
    Lin::combine(a[0], &dv[0], a[1], &dv[1])
}

/// `a x delta v = a_x delta v_y - a_y delta v_x` (so `delta v x b = -(b x delta v)`).
pub fn lin2_cross(a: Vec2, dv: &Lin2) -> Lin {
    Lin::combine(a[0], &dv[1], -a[1], &dv[0])
}

/// `sum_k s_k delta v_k` for vectors.
pub fn lin2_sum(terms: &[(f64, &Lin2)]) -> Lin2 {
    let part = |c: usize| Lin::sum(&terms.iter().map(|&(s, v)| (s, &v[c])).collect::<Vec<_>>());
    [part(0), part(1)]
}

/// `delta v + a delta s` for a vector `v` and a scalar `s` (e.g. `delta x + t delta xi`).
fn lin2_add_scalar(dv: &Lin2, a: Vec2, ds: &Lin) -> Lin2 {
    [Lin::combine(1.0, &dv[0], a[0], ds), Lin::combine(1.0, &dv[1], a[1], ds)]
}

/// A 2D vector with its derivative.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vec2Lin {
    pub value: Vec2,
    pub lin: Lin2,
}

impl Vec2Lin {
    /// The position of involved node `node`, `x`: its derivative is `delta x_node`.
    pub fn node(node: usize, x: Vec2) -> Vec2Lin {
        Vec2Lin { value: x, lin: lin2_node(node) }
    }
}

/// The derivative of the unit vector `u = v/|v|` from that of `v`:
/// `delta u = (I - u u^T) delta v / |v|`.
fn normalize_lin(u: Vec2, len: f64, dv: &Lin2) -> Lin2 {
    let along = lin2_dot(u, dv);
    [
        Lin::combine(1.0 / len, &dv[0], -u[0] / len, &along),
        Lin::combine(1.0 / len, &dv[1], -u[1] / len, &along),
    ]
}

// ------------------------------------------------------------------------------------------
// Normals
// ------------------------------------------------------------------------------------------

/// Unit normal of a line facet `x_a -> x_b` (nodes `ids`), as `nodal_normals_2d` uses it:
/// `e = s n~/|n~|`, `n~ = (t_y, -t_x)`, `t = (x_b - x_a)/2`, `s = -1` when `reverse`.
///
/// Derivative: `delta n~ = (delta t_y, -delta t_x)`, `delta t = (delta x_b - delta x_a)/2`, and
/// `delta e = (I - e e^T) s delta n~ / |n~|` (only the part normal to `e` survives: rotating
/// the facet turns `e`, stretching it does not).
/// Err on a zero-length or non-finite facet.
pub fn facet_normal_lin_2d(
    facet: &Facet2,
    ids: [usize; 2],
    reverse: bool,
) -> Result<Vec2Lin, GeomError> {
    let sign = if reverse { -1.0 } else { 1.0 };
    let n = facet.normal();
    let len = norm2(n);
    if !(len > 0.0 && len.is_finite()) {
        return fail(format!("line facet {:?} has zero or non-finite length", ids));
    }
    let e = scale2(sign / len, n);
    Ok(Vec2Lin { value: e, lin: normalize_lin(e, len, &facet_normal_raw_lin(ids, sign)) })
}

/// `s delta n~ = s (delta t_y, -delta t_x)`, `t = (x_b - x_a)/2`.
fn facet_normal_raw_lin(ids: [usize; 2], sign: f64) -> Lin2 {
    let h = 0.5 * sign;
    [
        Lin::from_entries([((ids[1], 1), h), ((ids[0], 1), -h)]),
        Lin::from_entries([((ids[1], 0), -h), ((ids[0], 0), h)]),
    ]
}

/// [`nodal_normals_2d`](super::dual::nodal_normals_2d) with derivatives, on the same input
/// (`coords` is the list of involved nodes: the Lin node ids are indices into it):
/// `n_j = m_j/|m_j|`, `m_j = sum_(e around j) e_e` (unit facet normals, `reverse` flips them).
///
/// Derivative: `delta m_j = sum_e delta e_e` ([`facet_normal_lin_2d`]) and
/// `delta n_j = (I - n_j n_j^T) delta m_j / |m_j|`: node j's normal depends on the nodes of
/// its facets, i.e. on its neighbours along the surface. Values are bit for bit those of
/// `nodal_normals_2d`; the same errors; nodes on no facet get zero and no derivative.
pub fn nodal_normals_lin_2d(
    coords: &[Vec2],
    facets: &[[usize; 2]],
    reverse: bool,
) -> Result<Vec<Vec2Lin>, GeomError> {
    let sign = if reverse { -1.0 } else { 1.0 };
    let mut sum = vec![[0.0; 2]; coords.len()];
    let mut dsum: Vec<Lin2> = vec![Lin2::default(); coords.len()];
    let mut used = vec![false; coords.len()];
    for nodes in facets {
        let f = Facet2::from_nodes(coords, *nodes)?;
        let n = f.normal();
        let len = norm2(n);
        if !(len > 0.0 && len.is_finite()) {
            return fail(format!("line facet {:?} has zero or non-finite length", nodes));
        }
        let e = scale2(sign / len, n);
        let de = normalize_lin(e, len, &facet_normal_raw_lin(*nodes, sign));
        for &k in nodes {
            sum[k] = add2(sum[k], scale2(sign / len, n));
            for c in 0..2 {
                dsum[k][c].add_scaled(1.0, &de[c]);
            }
            used[k] = true;
        }
    }
    let mut out = Vec::with_capacity(coords.len());
    for ((m, dm), &u) in sum.into_iter().zip(dsum.iter()).zip(used.iter()) {
        if !u {
            out.push(Vec2Lin { value: m, lin: Lin2::default() });
            continue;
        }
        let len = norm2(m);
        if !(len > 1e-8) {
            return fail(format!("node {} has opposite facet normals that cancel", out.len()));
        }
        let n = scale2(1.0 / len, m);
        out.push(Vec2Lin { value: n, lin: normalize_lin(n, len, dm) });
    }
    Ok(out)
}

// ------------------------------------------------------------------------------------------
// Jacobian, D and the dual basis
// ------------------------------------------------------------------------------------------

/// Jacobian `J = |t|`, `t = (x_2 - x_1)/2`, of a line facet (nodes `ids`), and
/// `delta J = t . delta t / J`, `delta t = (delta x_2 - delta x_1)/2`.
pub fn jacobian_lin_2d(facet: &Facet2, ids: [usize; 2]) -> (f64, Lin) {
    let t = facet.tangent();
    let j = facet.jacobian();
    let dt = [
        Lin::from_entries([((ids[1], 0), 0.5), ((ids[0], 0), -0.5)]),
        Lin::from_entries([((ids[1], 1), 0.5), ((ids[0], 1), -0.5)]),
    ];
    (j, lin2_dot(scale2(1.0 / j, t), &dt))
}

/// [`dual_basis_2d`] of a line2 slave facet (nodes `ids`) and the derivatives of its `D`
/// entries `d_j = int_e phi_j = J int phi_j dxi = J`: `delta d_j = (d_j / J) delta J`.
///
/// The dual coefficients have no derivative: with `J` constant on a line,
/// `D_e = J diag(1, 1)` and `M_e = J [[2/3, 1/3], [1/3, 2/3]]`, so
/// `A_e = D_e M_e^{-1} = [[2, -1], [-1, 2]]` whatever the nodes (the `J`s cancel; the test
/// `dual_coefficients_do_not_move` checks it by differences). Err as `dual_basis_2d`.
pub fn dual_basis_lin_2d(facet: &Facet2, ids: [usize; 2]) -> Result<(DualBasis, Lin2), GeomError> {
    let dual = dual_basis_2d(facet)?;
    let (j, dj) = jacobian_lin_2d(facet, ids);
    Ok((dual, [dj.scale(dual.d[0] / j), dj.scale(dual.d[1] / j)]))
}

// ------------------------------------------------------------------------------------------
// Projections
// ------------------------------------------------------------------------------------------

/// [`project_onto_master_2d`] with its derivative: `eta` with `G(eta) = (y(eta) - x) x n = 0`,
/// `y(eta) = phi_1(eta) y_1 + phi_2(eta) y_2` the master line (nodes `master_ids`), `x` and
/// `n` any point and direction with their derivatives (a slave node and its nodal normal, or a
/// quadrature point and the interpolated normal). Implicit differentiation,
/// `G_eta delta eta + delta G = 0`:
///
/// ```text
/// delta eta = -[ (phi_1 delta y_1 + phi_2 delta y_2 - delta x) x n + (y(eta) - x) x delta n ]
///             / (t_m x n)
/// ```
///
/// None where `project_onto_master_2d` gives None (ray parallel to the master).
pub fn project_onto_master_lin_2d(
    master: &Facet2,
    master_ids: [usize; 2],
    x: &Vec2Lin,
    n: &Vec2Lin,
) -> Option<(f64, Lin)> {
    let eta = project_onto_master_2d(master, x.value, n.value)?;
    let den = cross2(master.tangent(), n.value);
    let pm = shape_line2(eta);
    let r = sub2(master.position(eta), x.value);
    // delta y(eta) - delta x at fixed eta.
    let dy = lin2_sum(&[
        (pm[0], &lin2_node(master_ids[0])),
        (pm[1], &lin2_node(master_ids[1])),
        (-1.0, &x.lin),
    ]);
    // delta u x n = -(n x delta u).
    let dg = Lin::combine(-1.0, &lin2_cross(n.value, &dy), 1.0, &lin2_cross(r, &n.lin));
    Some((eta, dg.scale(-1.0 / den)))
}

/// [`project_onto_slave_2d`] with its derivative: `xi` with
/// `F(xi) = (x(xi) - y) x n(xi) = 0`, `x(xi) = phi_1 x_1 + phi_2 x_2` the slave line (nodes
/// `slave_ids`), `n(xi) = phi_1 n_1 + phi_2 n_2` the interpolated nodal normals (with their
/// derivatives), `y` the master node `y_id`. Implicit differentiation:
///
/// ```text
/// F_xi     = t x n(xi) + (x(xi) - y) x dn,        dn = (n_2 - n_1)/2,
/// delta xi = -[ (phi_1 delta x_1 + phi_2 delta x_2 - delta y) x n(xi)
///               + (x(xi) - y) x (phi_1 delta n_1 + phi_2 delta n_2) ] / F_xi
/// ```
///
/// (`F` is the quadratic of `project_onto_slave_2d`; at its root `|F_xi| = sqrt(b^2 - 4ac)`.)
/// None where `project_onto_slave_2d` gives None, or at a double root (`F_xi = 0`: no
/// derivative).
pub fn project_onto_slave_lin_2d(
    slave: &Facet2,
    slave_ids: [usize; 2],
    normals: &[Vec2Lin; 2],
    y: Vec2,
    y_id: usize,
) -> Option<(f64, Lin)> {
    let nv = [normals[0].value, normals[1].value];
    let xi = project_onto_slave_2d(slave, &nv, y)?;
    let p = shape_line2(xi);
    let n = add2(scale2(p[0], nv[0]), scale2(p[1], nv[1]));
    let dn_dxi = scale2(0.5, sub2(nv[1], nv[0]));
    let r = sub2(slave.position(xi), y);
    let fxi = cross2(slave.tangent(), n) + cross2(r, dn_dxi);
    if !(fxi.abs() > 0.0 && fxi.is_finite()) {
        return None;
    }
    let dr = lin2_sum(&[
        (p[0], &lin2_node(slave_ids[0])),
        (p[1], &lin2_node(slave_ids[1])),
        (-1.0, &lin2_node(y_id)),
    ]);
    let dn = lin2_sum(&[(p[0], &normals[0].lin), (p[1], &normals[1].lin)]);
    let df = Lin::combine(-1.0, &lin2_cross(n, &dr), 1.0, &lin2_cross(r, &dn));
    Some((xi, df.scale(-1.0 / fxi)))
}

// ------------------------------------------------------------------------------------------
// Pair integrals
// ------------------------------------------------------------------------------------------

/// The ids (in the caller's list of involved nodes) of a pair's facet nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PairIds2 {
    pub slave: [usize; 2],
    pub master: [usize; 2],
}

/// What a segment end is: slave node `k` (fixed at `xi = -1` or `+1`) or the projection of
/// master node `l` onto the slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentEnd {
    Slave(usize),
    Master(usize),
}

/// [`PairIntegrals`] of a 2D pair with the derivatives of every entry and of the segment.
#[derive(Clone, Debug, PartialEq)]
pub struct PairIntegralsLin {
    /// The integrals, identical to `mortar_pair_2d`'s.
    pub value: PairIntegrals,
    /// The segment `[xi_a, xi_b]` in slave parameters, what defines each end, and the ends'
    /// derivatives.
    pub segment: [f64; 2],
    pub ends: [SegmentEnd; 2],
    pub segment_lin: Lin2,
    /// `delta M_jl`.
    pub m: [[Lin; 2]; 2],
    /// `delta N_j`, `N_j = int_overlap psi_j` (the pair's share of `D_jj`).
    pub psi_integral: Lin2,
    /// `delta g_j`.
    pub weighted_gap: Lin2,
    /// `delta int_overlap 1`.
    pub overlap_measure: Lin,
}

/// [`mortar_pair_2d`](super::segment::mortar_pair_2d) with derivatives: the same input
/// (`dual` must be `dual_basis_2d(slave)`), plus the pair's node ids and the derivatives
/// `normals_lin` of `slave_normals` (from [`nodal_normals_lin_2d`], or any other normal field
/// with its derivative). Same value (bit for bit), same `Ok(None)` and errors, plus an Err if a
/// master node projects at a double root (no derivative).
///
/// The formulas, following the steps of `mortar_pair_2d` (derived here by implicit
/// differentiation of its defining equations; Popp, Gee, Wall 2009 linearize the same steps):
///
/// 1. Segment ends. A slave end `xi = -1, +1` (kept while its node's projection
///    `eta_k` lies on the master) has `delta xi = 0`; a master node's projection `xi_l` has the
///    derivative of [`project_onto_slave_lin_2d`]. `xi_a`, `xi_b` are the min and max of the
///    candidates (see the module docs for ties). `mid = (xi_a + xi_b)/2`,
///    `half = (xi_b - xi_a)/2`, and the same for their derivatives.
/// 2. Gauss point `xi_g = mid + half s_g`: `delta xi_g = delta mid + s_g delta half`; weight
///    `W_g = w_g half J`, `delta W_g = w_g (J delta half + half delta J)`.
/// 3. Slave point `x_g = x(xi_g)`: `delta x_g = phi_1 delta x_1 + phi_2 delta x_2 + t delta xi_g`;
///    normal `n_g = phi_1 n_1 + phi_2 n_2`:
///    `delta n_g = phi_1 delta n_1 + phi_2 delta n_2 + (n_2 - n_1)/2 delta xi_g`.
/// 4. Master parameter `eta_g` of `x_g` along `n_g` ([`project_onto_master_lin_2d`]).
/// 5. Dual functions: `A_e` is constant ([`dual_basis_lin_2d`]), so
///    `delta psi_j(xi_g) = psi_j'(xi_g) delta xi_g`, `psi_j' = sum_k A_jk phi_k'`; master
///    functions `delta phi_l(eta_g) = phi_l' delta eta_g`.
/// 6. Gap `r_g = y(eta_g) - x_g`:
///    `delta r_g = phi_1(eta_g) delta y_1 + phi_2(eta_g) delta y_2 + t_m delta eta_g - delta x_g`,
///    `gn_j = n_j . r_g`, `delta gn_j = r_g . delta n_j + n_j . delta r_g`.
/// 7. With `w_j = W_g psi_j`, `delta w_j = psi_j delta W_g + W_g delta psi_j`:
///    `delta M_jl += phi_l delta w_j + w_j delta phi_l`, `delta N_j += delta w_j`,
///    `delta g_j += gn_j delta w_j + w_j delta gn_j`, `delta |overlap| += delta W_g`.
pub fn mortar_pair_lin_2d(
    slave: &Facet2,
    slave_normals: &[Vec2; 2],
    dual: &DualBasis,
    master: &Facet2,
    ids: PairIds2,
    normals_lin: &[Lin2; 2],
) -> Result<Option<PairIntegralsLin>, GeomError> {
    // The checks of mortar_pair_2d.
    if !check_pair_2d(slave, slave_normals, dual, master)? {
        return Ok(None);
    }
    let js = slave.jacobian();
    let normals = [
        Vec2Lin { value: slave_normals[0], lin: normals_lin[0].clone() },
        Vec2Lin { value: slave_normals[1], lin: normals_lin[1].clone() },
    ];

    // 1. Segment ends.
    let inside = |p: f64| (-1.0 - PARAM_TOL..=1.0 + PARAM_TOL).contains(&p);
    let mut lo: Option<(f64, Lin, SegmentEnd)> = None;
    let mut hi: Option<(f64, Lin, SegmentEnd)> = None;
    let mut take = |raw: f64, d: Lin, end: SegmentEnd| {
        let xi = raw.clamp(-1.0, 1.0);
        let d = if xi == raw { d } else { Lin::zero() };
        if lo.as_ref().is_none_or(|l| xi < l.0) {
            lo = Some((xi, d.clone(), end));
        }
        if hi.as_ref().is_none_or(|h| xi > h.0) {
            hi = Some((xi, d, end));
        }
    };
    for (k, end) in [(0usize, -1.0), (1usize, 1.0)] {
        if let Some(eta) = project_onto_master_2d(master, slave.x[k], slave_normals[k]) {
            if inside(eta) {
                take(end, Lin::zero(), SegmentEnd::Slave(k));
            }
        }
    }
    for (l, y) in master.x.into_iter().enumerate() {
        if let Some(xi) = project_onto_slave_2d(slave, slave_normals, y) {
            if inside(xi) {
                let Some((_, d)) =
                    project_onto_slave_lin_2d(slave, ids.slave, &normals, y, ids.master[l])
                else {
                    return fail("master node projects onto the slave at a double root");
                };
                take(xi, d, SegmentEnd::Master(l));
            }
        }
    }
    let (Some((lo, dlo, end_lo)), Some((hi, dhi, end_hi))) = (lo, hi) else {
        return Ok(None);
    };
    if !(hi - lo > 2.0 * PARAM_TOL) {
        return Ok(None);
    }
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let dmid = Lin::combine(0.5, &dlo, 0.5, &dhi);
    let dhalf = Lin::combine(-0.5, &dlo, 0.5, &dhi);

    let (_, djs) = jacobian_lin_2d(slave, ids.slave);
    let t = slave.tangent();
    let dn_dxi = scale2(0.5, sub2(slave_normals[1], slave_normals[0]));
    let tm = master.tangent();
    let dphi = dshape_line2();
    // psi_j' = sum_k A_jk phi_k' (constant on a line).
    let dpsi = [
        dual.a[0][0] * dphi[0] + dual.a[0][1] * dphi[1],
        dual.a[1][0] * dphi[0] + dual.a[1][1] * dphi[1],
    ];
    let xs_node = [lin2_node(ids.slave[0]), lin2_node(ids.slave[1])];
    let ym_node = [lin2_node(ids.master[0]), lin2_node(ids.master[1])];

    let mut out = PairIntegrals::zero(2, 2);
    out.slave_measure = 2.0 * js;
    let mut dm: [[Lin; 2]; 2] = Default::default();
    let mut dn_int: Lin2 = Default::default();
    let mut dgap: Lin2 = Default::default();
    let mut dmeas = Lin::zero();
    for (s, w) in gauss_legendre(5) {
        // 2. The point and its weight.
        let xi = mid + half * s;
        let dxi = Lin::combine(1.0, &dmid, s, &dhalf);
        let wg = w * half * js;
        let dwg = Lin::combine(w * js, &dhalf, w * half, &djs);
        // 3. Slave point and interpolated normal.
        let phi = shape_line2(xi);
        let psi = dual.psi(&[phi[0], phi[1], 0.0, 0.0]);
        let xs = slave.position(xi);
        let dxs =
            lin2_add_scalar(&lin2_sum(&[(phi[0], &xs_node[0]), (phi[1], &xs_node[1])]), t, &dxi);
        let n = add2(scale2(phi[0], slave_normals[0]), scale2(phi[1], slave_normals[1]));
        let dn = lin2_add_scalar(
            &lin2_sum(&[(phi[0], &normals_lin[0]), (phi[1], &normals_lin[1])]),
            dn_dxi,
            &dxi,
        );
        // 4. Its master parameter.
        let (eta, deta) = project_onto_master_lin_2d(
            master,
            ids.master,
            &Vec2Lin { value: xs, lin: dxs.clone() },
            &Vec2Lin { value: n, lin: dn },
        )
        .ok_or_else(|| GeomError("slave point does not project onto the master line".into()))?;
        // 5.-6. Master functions and gap.
        let pm = shape_line2(eta);
        let gap = sub2(master.position(eta), xs);
        let dr = lin2_add_scalar(
            &lin2_sum(&[(pm[0], &ym_node[0]), (pm[1], &ym_node[1]), (-1.0, &dxs)]),
            tm,
            &deta,
        );
        let gn = [dot2(slave_normals[0], gap), dot2(slave_normals[1], gap), 0.0, 0.0];
        // 7. Accumulate (values exactly as mortar_pair_2d).
        out.add_point(w * half * js, &psi, &[pm[0], pm[1], 0.0, 0.0], &gn);
        out.add_primal(w * half * js, &[phi[0], phi[1], 0.0, 0.0], &[pm[0], pm[1], 0.0, 0.0], &gn);
        for j in 0..2 {
            let wj = wg * psi[j];
            let dwj = Lin::combine(psi[j], &dwg, wg * dpsi[j], &dxi);
            let dgn = Lin::combine(
                1.0,
                &lin2_dot(gap, &normals_lin[j]),
                1.0,
                &lin2_dot(slave_normals[j], &dr),
            );
            dn_int[j].add_scaled(1.0, &dwj);
            dgap[j] = Lin::sum(&[(1.0, &dgap[j]), (gn[j], &dwj), (wj, &dgn)]);
            for l in 0..2 {
                dm[j][l] = Lin::sum(&[(1.0, &dm[j][l]), (pm[l], &dwj), (wj * dphi[l], &deta)]);
            }
        }
        dmeas.add_scaled(1.0, &dwg);
    }
    Ok(Some(PairIntegralsLin {
        value: out,
        segment: [lo, hi],
        ends: [end_lo, end_hi],
        segment_lin: [dlo, dhi],
        m: dm,
        psi_integral: dn_int,
        weighted_gap: dgap,
        overlap_measure: dmeas,
    }))
}

#[cfg(test)]
#[path = "linearize_tests.rs"]
mod tests;
