//! Segment-based mortar integrals of one slave facet against one master facet: projection
//! in 2D, auxiliary-plane clipping in 3D.

use super::dual::DualBasis;
use super::facet::{
    dshape_quad4, shape_line2, shape_quad4, triangle_rule_deg2, triangle_rule_deg5, Facet2, Facet3,
};
use super::geom::*;
use crate::fem::quadrature::gauss_legendre;

// ------------------------------------------------------------------------------------------
// Pair integrals
// ------------------------------------------------------------------------------------------

/// Mortar integrals of one slave facet s against one master facet m over their overlap.
/// Indices are local: j over the slave facet's nodes, l over the master facet's nodes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairIntegrals {
    pub n_slave: usize,
    pub n_master: usize,
    /// `M_jl = int_overlap psi_j (phi_l o projection)`.
    pub m: [[f64; 4]; 4],
    /// `N_j = int_overlap psi_j` (= `sum_l M_jl`, since the master `phi_l` sum to 1).
    pub psi_integral: [f64; 4],
    /// `g_j = int_overlap psi_j n_j . (x_m(projection) - x_s)`, `n_j` the slave nodal normal
    /// (outward, towards the master): positive when the bodies are apart.
    pub weighted_gap: [f64; 4],
    /// Measure of the overlap, `int_overlap 1`.
    pub overlap_measure: f64,
    /// Measure of the whole slave facet, in the overlap's measure (2D: its length; 3D: its
    /// polygon's area on the auxiliary plane): the covered fraction is
    /// `sum overlap_measure / slave_measure` over the facet's pairs.
    pub slave_measure: f64,
    /// The same integrals with the standard slave functions `phi_k` in place of `psi_j`
    /// (rows k): `int phi_k (phi_l o projection)`, `int phi_k n_j . (x_m - x_s)` (column j),
    /// and the overlap's Gram matrix `int phi_k phi_i` and `int phi_k`. Linear in the slave
    /// function, they give the integrals of any dual basis on the covered part
    /// ([`PairIntegrals::with_dual`]).
    pub phi_m: [[f64; 4]; 4],
    pub phi_gap: [[f64; 4]; 4],
    pub phi_phi: [[f64; 4]; 4],
    pub phi_integral: [f64; 4],
}

impl PairIntegrals {
    pub(crate) fn zero(n_slave: usize, n_master: usize) -> PairIntegrals {
        PairIntegrals {
            n_slave,
            n_master,
            m: [[0.0; 4]; 4],
            psi_integral: [0.0; 4],
            weighted_gap: [0.0; 4],
            overlap_measure: 0.0,
            slave_measure: 0.0,
            phi_m: [[0.0; 4]; 4],
            phi_gap: [[0.0; 4]; 4],
            phi_phi: [[0.0; 4]; 4],
            phi_integral: [0.0; 4],
        }
    }

    /// Adds one quadrature point to the standard-function integrals: weight `w`, slave values
    /// `phi`, master values `phi_m`, gaps `gn` as in [`PairIntegrals::add_point`].
    pub(crate) fn add_primal(&mut self, w: f64, phi: &[f64; 4], phi_m: &[f64; 4], gn: &[f64; 4]) {
        for k in 0..self.n_slave {
            let wp = w * phi[k];
            self.phi_integral[k] += wp;
            for l in 0..self.n_master {
                self.phi_m[k][l] += wp * phi_m[l];
            }
            for j in 0..self.n_slave {
                self.phi_gap[k][j] += wp * gn[j];
                self.phi_phi[k][j] += wp * phi[j];
            }
        }
    }

    /// `M`, `N` and the weighted gaps of the dual basis `psi_j = sum_k a_jk phi_k` instead of
    /// the one integrated (exact: they are linear in the slave function).
    pub fn with_dual(&self, a: &[[f64; 4]; 4]) -> PairIntegrals {
        let mut out = *self;
        for j in 0..self.n_slave {
            let row = |f: &dyn Fn(usize) -> f64| (0..self.n_slave).map(|k| a[j][k] * f(k)).sum();
            for l in 0..self.n_master {
                out.m[j][l] = row(&|k| self.phi_m[k][l]);
            }
            out.psi_integral[j] = row(&|k| self.phi_integral[k]);
            out.weighted_gap[j] = row(&|k| self.phi_gap[k][j]);
        }
        out
    }

    /// Adds one quadrature point: weight `w`, dual values `psi`, master values `phi_m`, and the
    /// gap vector `x_m - x_s` dotted with each slave nodal normal (`gn[j]`).
    pub(crate) fn add_point(&mut self, w: f64, psi: &[f64; 4], phi_m: &[f64; 4], gn: &[f64; 4]) {
        for j in 0..self.n_slave {
            let wp = w * psi[j];
            self.psi_integral[j] += wp;
            self.weighted_gap[j] += wp * gn[j];
            for (m, p) in self.m[j].iter_mut().zip(phi_m).take(self.n_master) {
                *m += wp * p;
            }
        }
        self.overlap_measure += w;
    }
}

/// Parametric tolerance for "a projection lands inside the other facet".
pub(crate) const PARAM_TOL: f64 = 1e-12;

/// Projects a master point `y` onto the slave line along the slave normal field
/// `n(xi) = sum_k phi_k(xi) n_k` (Popp et al. 2009): find `xi` with `x(xi) + alpha n(xi) = y`,
/// i.e. `f(xi) = (x(xi) - y) x n(xi) = 0` (2D cross product). With `x = x0 + xi t`,
/// `n = n0 + xi dn`, this is the quadratic `a xi^2 + b xi + c = 0`, `a = t x dn`,
/// `b = t x n0 + (x0 - y) x dn`, `c = (x0 - y) x n0`. Returns the root of smaller magnitude,
/// `c/q` with `q = -(b + sign(b) sqrt(b^2 - 4ac))/2` (stable; it is the root that tends to
/// the linear solution `-c/b` as the normals become parallel, and the one Newton from 0 finds).
/// None if no real root exists. The root may lie outside [-1, 1].
pub fn project_onto_slave_2d(slave: &Facet2, slave_normals: &[Vec2; 2], y: Vec2) -> Option<f64> {
    let x0 = scale2(0.5, add2(slave.x[0], slave.x[1]));
    let t = slave.tangent();
    let n0 = scale2(0.5, add2(slave_normals[0], slave_normals[1]));
    let dn = scale2(0.5, sub2(slave_normals[1], slave_normals[0]));
    let r = sub2(x0, y);
    let a = cross2(t, dn);
    let b = cross2(t, n0) + cross2(r, dn);
    let c = cross2(r, n0);
    let disc = b * b - 4.0 * a * c;
    if !(disc >= 0.0) {
        return None;
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    if q == 0.0 {
        // b = 0 and a c = 0: a double root at 0 if c = 0 and a != 0; otherwise degenerate.
        return if a != 0.0 && c == 0.0 { Some(0.0) } else { None };
    }
    let xi = c / q;
    xi.is_finite().then_some(xi)
}

/// Projects a point `x` along direction `n` onto the master line: find `eta` with
/// `x_m(eta) = x + alpha n`, i.e. `(x_m(eta) - x) x n = 0`, linear in `eta`:
/// `eta = -((y0 - x) x n) / (t_m x n)`, `y0` the master midpoint, `t_m` its tangent.
/// None if `n` is (nearly) parallel to the master line. May lie outside [-1, 1].
pub fn project_onto_master_2d(master: &Facet2, x: Vec2, n: Vec2) -> Option<f64> {
    let y0 = scale2(0.5, add2(master.x[0], master.x[1]));
    let tm = master.tangent();
    let den = cross2(tm, n);
    if !(den.abs() > 1e-12 * norm2(tm) * norm2(n)) {
        return None;
    }
    let eta = -cross2(sub2(y0, x), n) / den;
    eta.is_finite().then_some(eta)
}

/// The input checks of a 2D slave/master pair (finite coordinates and normals, a line2 dual
/// basis, facets of positive length); `Ok(false)` when the master facet faces the same way as
/// the slave (the back of the master body: no overlap). Shared by [`mortar_pair_2d`] and its
/// linearization, so that both refuse and skip the same pairs.
pub(crate) fn check_pair_2d(
    slave: &Facet2,
    slave_normals: &[Vec2; 2],
    dual: &DualBasis,
    master: &Facet2,
) -> Result<bool, GeomError> {
    if !slave.is_finite()
        || !master.is_finite()
        || !all_finite(&[
            slave_normals[0][0],
            slave_normals[0][1],
            slave_normals[1][0],
            slave_normals[1][1],
        ])
    {
        return fail("2D mortar pair has non-finite coordinates or normals");
    }
    if dual.n != 2 {
        return fail(format!("2D mortar pair needs a line2 dual basis, got {} nodes", dual.n));
    }
    if !(slave.jacobian() > 0.0) || !(master.jacobian() > 0.0) {
        return fail("2D mortar pair with a zero-length facet");
    }
    Ok(dot2(slave.normal(), master.normal()) <= 0.0)
}

/// Segment-based mortar integrals of a line2 slave facet against a line2 master facet
/// (Popp, Gee, Wall 2009).
///
/// 1. Projections: slave node k onto the master along its nodal normal `n_k`
///    (`project_onto_master_2d`); master node onto the slave along the interpolated slave normal
///    field (`project_onto_slave_2d`).
/// 2. Segment `[xi_a, xi_b]` in slave parameters: the min and max of the slave end points
///    (-1 or +1) whose projection lies on the master and of the master node projections that
///    lie on the slave (`Ok(None)` if it is empty or of zero length).
/// 3. 5-point Gauss on the segment, weight `w (xi_b - xi_a)/2 J_s` (slave Jacobian: the
///    integrals are over the slave surface, consistent with `D`); at each point
///    `xi_m = project_onto_master_2d(x_s(xi), n(xi))`, then
///    `M_jl += w psi_j(xi) phi_l(xi_m)`, `N_j += w psi_j`,
///    `g_j += w psi_j n_j . (x_m(xi_m) - x_s(xi))`.
///
/// `dual` must be `dual_basis_2d(slave)`. Err on degenerate facets or inconsistent input.
pub fn mortar_pair_2d(
    slave: &Facet2,
    slave_normals: &[Vec2; 2],
    dual: &DualBasis,
    master: &Facet2,
) -> Result<Option<PairIntegrals>, GeomError> {
    if !check_pair_2d(slave, slave_normals, dual, master)? {
        return Ok(None);
    }
    let js = slave.jacobian();
    let inside = |p: f64| (-1.0 - PARAM_TOL..=1.0 + PARAM_TOL).contains(&p);
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |xi: f64| {
        let xi = xi.clamp(-1.0, 1.0);
        lo = lo.min(xi);
        hi = hi.max(xi);
    };
    for (k, end) in [(0usize, -1.0), (1usize, 1.0)] {
        if let Some(eta) = project_onto_master_2d(master, slave.x[k], slave_normals[k]) {
            if inside(eta) {
                take(end);
            }
        }
    }
    for y in master.x {
        if let Some(xi) = project_onto_slave_2d(slave, slave_normals, y) {
            if inside(xi) {
                take(xi);
            }
        }
    }
    if !(hi - lo > 2.0 * PARAM_TOL) {
        return Ok(None);
    }
    let (mid, half) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let mut out = PairIntegrals::zero(2, 2);
    out.slave_measure = 2.0 * js;
    for (s, w) in gauss_legendre(5) {
        let xi = mid + half * s;
        let phi = shape_line2(xi);
        let psi = dual.psi(&[phi[0], phi[1], 0.0, 0.0]);
        let xs = slave.position(xi);
        let n = add2(scale2(phi[0], slave_normals[0]), scale2(phi[1], slave_normals[1]));
        let eta = project_onto_master_2d(master, xs, n)
            .ok_or_else(|| GeomError("slave point does not project onto the master line".into()))?;
        let pm = shape_line2(eta);
        let gap = sub2(master.position(eta), xs);
        let gn = [dot2(slave_normals[0], gap), dot2(slave_normals[1], gap), 0.0, 0.0];
        out.add_point(w * half * js, &psi, &[pm[0], pm[1], 0.0, 0.0], &gn);
        out.add_primal(w * half * js, &[phi[0], phi[1], 0.0, 0.0], &[pm[0], pm[1], 0.0, 0.0], &gn);
    }
    Ok(Some(out))
}

/// Auxiliary plane of a 3D slave facet (Puso & Laursen 2004; Popp et al. 2010): through the
/// facet centre `x0 = x_s(xi_c)` with unit normal `n0 = n_s(xi_c)/|n_s(xi_c)|`, and an
/// in-plane orthonormal basis `(e1, e2)` with `e1 x e2 = n0` (so the slave polygon is
/// counter-clockwise in plane coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AuxPlane {
    pub centre: Vec3,
    pub normal: Vec3,
    pub e1: Vec3,
    pub e2: Vec3,
}

impl AuxPlane {
    /// The auxiliary plane of `slave`; Err if the facet has no normal at its centre.
    pub fn of_slave(slave: &Facet3) -> Result<AuxPlane, GeomError> {
        let xc = slave.centre_param();
        let centre = slave.position(xc);
        let n = slave.normal(xc);
        let h = slave.size();
        let len = norm3(n);
        if !(len > 1e-14 * h * h) {
            return fail("slave facet is degenerate (no normal at its centre)");
        }
        let normal = scale3(1.0 / len, n);
        // e1 along the first edge projected into the plane: any in-plane direction would do.
        let d = sub3(slave.nodes()[1], slave.nodes()[0]);
        let v = sub3(d, scale3(dot3(d, normal), normal));
        let lv = norm3(v);
        if !(lv > 1e-12 * h) {
            return fail("slave facet's first edge is parallel to its normal");
        }
        let e1 = scale3(1.0 / lv, v);
        let e2 = cross3(normal, e1);
        Ok(AuxPlane { centre, normal, e1, e2 })
    }

    /// Plane coordinates of the projection of `x` along the plane normal:
    /// `q = ((x - x0) . e1, (x - x0) . e2)`.
    pub fn coords(&self, x: Vec3) -> Vec2 {
        let r = sub3(x, self.centre);
        [dot3(r, self.e1), dot3(r, self.e2)]
    }

    /// The point of the plane with coordinates `q`: `x0 + q_1 e1 + q_2 e2`.
    pub fn point(&self, q: Vec2) -> Vec3 {
        add3(self.centre, add3(scale3(q[0], self.e1), scale3(q[1], self.e2)))
    }
}

/// Inverts "facet map, then projection onto the plane": finds `xi` with
/// `P(x(xi)) = q`, `P` = `AuxPlane::coords` ([`PlaneInverse`]: in closed form on a tri3, by
/// Newton on a quad4). Err if the facet is seen edge-on, Newton does not converge, or the
/// result lies more than 1e-6 outside the reference element.
pub fn invert_on_plane(facet: &Facet3, plane: &AuxPlane, q: Vec2) -> Result<Vec2, GeomError> {
    PlaneInverse::new(facet, plane)?.apply(facet, q)
}

/// The inverse of "facet map, then projection onto `plane`" for one facet, set up once for
/// all the quadrature points of a pair. The projection `P` is affine, so the projected map is
/// the facet's interpolation of its projected nodes `p_k = P(x_k)`:
///
/// A tri3's is affine, `P(x(xi)) = p_1 + J_P xi`, `J_P = [p_2 - p_1, p_3 - p_1]`:
/// `xi = J_P^{-1} (q - p_1)`. A quad4's is bilinear, `sum_k phi_k(xi) p_k`: Newton with its 2x2
/// Jacobian from the facet centre, converged when the residual is below 1e-13 h or the step
/// below 1e-14 (at most 50 steps).
pub enum PlaneInverse {
    Affine { q0: Vec2, inv: [[f64; 2]; 2] },
    Bilinear { p: [Vec2; 4], h: f64 },
}

impl PlaneInverse {
    /// Err if a tri3 is seen edge-on (singular `J_P`).
    pub fn new(facet: &Facet3, plane: &AuxPlane) -> Result<PlaneInverse, GeomError> {
        let x = match facet {
            Facet3::Quad4(x) => {
                let p = [
                    plane.coords(x[0]),
                    plane.coords(x[1]),
                    plane.coords(x[2]),
                    plane.coords(x[3]),
                ];
                return Ok(PlaneInverse::Bilinear { p, h: facet.size() });
            }
            Facet3::Tri3(x) => x,
        };
        let (t1, t2) = (sub3(x[1], x[0]), sub3(x[2], x[0]));
        let (a, b) = (dot3(t1, plane.e1), dot3(t2, plane.e1));
        let (c, d) = (dot3(t1, plane.e2), dot3(t2, plane.e2));
        let det = a * d - b * c;
        if !(det.abs() > 1e-14 * norm3(t1) * norm3(t2)) {
            return fail("facet is edge-on to the auxiliary plane (singular projected Jacobian)");
        }
        let inv = [[d / det, -b / det], [-c / det, a / det]];
        Ok(PlaneInverse::Affine { q0: plane.coords(x[0]), inv })
    }

    /// `xi` with `P(x(xi)) = q`, checked to lie in the reference element (to 1e-6).
    pub fn apply(&self, facet: &Facet3, q: Vec2) -> Result<Vec2, GeomError> {
        match self {
            PlaneInverse::Affine { q0, inv } => {
                let r = sub2(q, *q0);
                let xi = [inv[0][0] * r[0] + inv[0][1] * r[1], inv[1][0] * r[0] + inv[1][1] * r[1]];
                check_in_reference(facet, xi)
            }
            PlaneInverse::Bilinear { p, h } => invert_bilinear(facet, p, *h, q),
        }
    }
}

/// Newton on `sum_k phi_k(xi) p_k = q` (a quad4's projected corners `p`, its size `h`).
fn invert_bilinear(facet: &Facet3, p: &[Vec2; 4], h: f64, q: Vec2) -> Result<Vec2, GeomError> {
    let mut xi = [0.0, 0.0];
    for _ in 0..50 {
        let (phi, d) = (shape_quad4(xi), dshape_quad4(xi));
        let (mut r, mut t1, mut t2) = ([-q[0], -q[1]], [0.0; 2], [0.0; 2]);
        for k in 0..4 {
            r = add2(r, scale2(phi[k], p[k]));
            t1 = add2(t1, scale2(d[k][0], p[k]));
            t2 = add2(t2, scale2(d[k][1], p[k]));
        }
        if norm2(r) <= 1e-13 * h {
            return check_in_reference(facet, xi);
        }
        let (a, b, c, dd) = (t1[0], t2[0], t1[1], t2[1]);
        let det = a * dd - b * c;
        // (The tangents of a quad on [-1, 1]^2 are about h/2 long.)
        if !(det.abs() > 2.5e-15 * h * h) {
            return fail("facet is edge-on to the auxiliary plane (singular projected Jacobian)");
        }
        let dxi = [-(dd * r[0] - b * r[1]) / det, -(-c * r[0] + a * r[1]) / det];
        xi = add2(xi, dxi);
        if dxi[0].abs().max(dxi[1].abs()) < 1e-14 {
            return check_in_reference(facet, xi);
        }
    }
    fail("Newton inversion of the projected facet map did not converge in 50 steps")
}

/// The rule integrating a pair over each triangle of its clip polygon, as (barycentric
/// coordinates, weight): degree 2 where both facets are tri3 (every map is affine, so
/// `psi_j phi_l`, `psi_j n_j . (x_m - x_s)` and `phi_j phi_l` are quadratic in the plane
/// coordinates and the rule is exact), degree 5 where a quad4's bilinear map enters.
pub fn clip_rule(slave: &Facet3, master: &Facet3) -> Vec<([f64; 3], f64)> {
    match (slave, master) {
        (Facet3::Tri3(_), Facet3::Tri3(_)) => triangle_rule_deg2().to_vec(),
        _ => triangle_rule_deg5().to_vec(),
    }
}

pub(crate) fn check_in_reference(facet: &Facet3, xi: Vec2) -> Result<Vec2, GeomError> {
    let tol = 1e-6;
    let ok = match facet {
        Facet3::Tri3(_) => xi[0] >= -tol && xi[1] >= -tol && xi[0] + xi[1] <= 1.0 + tol,
        Facet3::Quad4(_) => xi[0].abs() <= 1.0 + tol && xi[1].abs() <= 1.0 + tol,
    };
    if ok && xi[0].is_finite() && xi[1].is_finite() {
        Ok(xi)
    } else {
        fail(format!("projected point maps outside its facet (xi = {:?})", xi))
    }
}

/// Signed area of a polygon by the shoelace formula `A = 1/2 sum_i p_i x p_(i+1)`
/// (positive for counter-clockwise vertices).
pub fn polygon_area(p: &[Vec2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| cross2(p[i], p[(i + 1) % n])).sum::<f64>() * 0.5
}

/// True if the polygon (counter-clockwise) is convex: every turn `(p_i - p_(i-1)) x
/// (p_(i+1) - p_i) >= -tol`.
pub(crate) fn is_convex_ccw(p: &[Vec2], tol: f64) -> bool {
    let n = p.len();
    (0..n).all(|i| {
        let (a, b, c) = (p[(i + n - 1) % n], p[i], p[(i + 1) % n]);
        cross2(sub2(b, a), sub2(c, b)) >= -tol
    })
}

/// Sutherland-Hodgman clipping of `subject` by the convex counter-clockwise polygon `clip`:
/// for each clip edge `a -> b`, keep the part of the current polygon with
/// `(b - a) x (p - a) >= -eps` (left of the edge), inserting edge crossings at
/// `p + t (p' - p)`, `t = d / (d - d')`. `eps` absorbs round-off on shared or collinear edges
/// (coincident meshes). The subject may be non-convex; the result is then still the
/// intersection, possibly with degenerate zero-area slivers.
pub fn clip_polygon(subject: &[Vec2], clip: &[Vec2], eps: f64) -> Vec<Vec2> {
    let mut out: Vec<Vec2> = subject.to_vec();
    let nc = clip.len();
    for i in 0..nc {
        if out.is_empty() {
            break;
        }
        let (a, b) = (clip[i], clip[(i + 1) % nc]);
        let e = sub2(b, a);
        let side = |p: Vec2| cross2(e, sub2(p, a));
        let input = std::mem::take(&mut out);
        let mut s = input[input.len() - 1];
        let mut ds = side(s);
        for &p in &input {
            let dp = side(p);
            let crossing = |s: Vec2, ds: f64, p: Vec2, dp: f64| {
                let t = (ds / (ds - dp)).clamp(0.0, 1.0);
                add2(s, scale2(t, sub2(p, s)))
            };
            if dp >= -eps {
                if ds < -eps {
                    out.push(crossing(s, ds, p, dp));
                }
                out.push(p);
            } else if ds >= -eps {
                out.push(crossing(s, ds, p, dp));
            }
            s = p;
            ds = dp;
        }
    }
    out
}

/// Removes consecutive (cyclically) vertices closer than `tol`.
pub(crate) fn dedupe_polygon(p: Vec<Vec2>, tol: f64) -> Vec<Vec2> {
    let mut out: Vec<Vec2> = Vec::with_capacity(p.len());
    for q in p {
        if out.last().is_none_or(|&l| norm2(sub2(q, l)) > tol) {
            out.push(q);
        }
    }
    while out.len() > 1 && norm2(sub2(out[0], out[out.len() - 1])) <= tol {
        out.pop();
    }
    out
}

/// The input checks of a 3D slave/master pair: one normal and one dual function per slave
/// node, finite coordinates and normals. Shared by [`mortar_pair_3d`] and its linearization.
pub(crate) fn check_pair_3d(
    slave: &Facet3,
    slave_normals: &[Vec3],
    dual: &DualBasis,
    master: &Facet3,
) -> Result<(), GeomError> {
    let ns = slave.n_nodes();
    if slave_normals.len() != ns || dual.n != ns {
        return fail(format!(
            "3D mortar pair: slave facet has {} nodes but {} normals and a dual basis of {}",
            ns,
            slave_normals.len(),
            dual.n
        ));
    }
    if !slave.is_finite() || !master.is_finite() || !slave_normals.iter().all(|n| all_finite(n)) {
        return fail("3D mortar pair has non-finite coordinates or normals");
    }
    Ok(())
}

/// Segment-based mortar integrals of a tri3/quad4 slave facet against a tri3/quad4 master
/// facet in 3D (Puso & Laursen 2004; Popp, Gee, Wohlmuth, Wall 2010).
///
/// 1. Auxiliary plane at the slave centre (`AuxPlane::of_slave`); both facets' nodes are
///    projected onto it along `n0`. The slave polygon is counter-clockwise and must be convex
///    (else Err). A master facing the slave projects clockwise (its normal opposes `n0`) and is
///    reversed; a master projecting counter-clockwise or edge-on gives `Ok(None)`.
/// 2. Sutherland-Hodgman clip of the master polygon by the slave polygon; `Ok(None)` if the
///    clip polygon has fewer than 3 vertices or area below `1e-12` of the slave's.
/// 3. The clip polygon is split into triangles `(c, p_i, p_(i+1))`, `c` its vertex centroid,
///    each integrated with [`clip_rule`] (3 points between two tri3, else 7). Each point `q`
///    maps back to `xi_s` on the slave and `xi_m` on the master ([`PlaneInverse`], projection
///    along `n0`), and `M_jl += w psi_j(xi_s) phi_l(xi_m)`, `N_j += w psi_j`,
///    `g_j += w psi_j n_j . (x_m(xi_m) - x_s(xi_s))`.
///
/// Integration measure: the weight `w` is the area on the AUXILIARY PLANE, i.e. the
/// integrals are over the slave facet's projection onto its aux plane (Popp et al. 2010).
/// For planar slave facets this is the slave surface itself, so `sum_l M_jl = D_jj` on full
/// overlap; for a warped quad the two differ by O(warp^2) (then `sum_j N_j` over a fully
/// overlapped facet is the projected polygon's area, not `sum_j d_j`).
///
/// `dual` must be `dual_basis_3d(slave)`; `slave_normals` holds the slave nodal normals
/// (used for the gap only: the projection direction is `n0`).
pub fn mortar_pair_3d(
    slave: &Facet3,
    slave_normals: &[Vec3],
    dual: &DualBasis,
    master: &Facet3,
) -> Result<Option<PairIntegrals>, GeomError> {
    let ns = slave.n_nodes();
    let nm = master.n_nodes();
    check_pair_3d(slave, slave_normals, dual, master)?;
    let plane = AuxPlane::of_slave(slave)?;
    let sp: Vec<Vec2> = slave.nodes().iter().map(|&x| plane.coords(x)).collect();
    let s_area = polygon_area(&sp);
    let h2 = slave.size().powi(2);
    if !(s_area > 1e-14 * h2) {
        return fail("slave facet projects to a degenerate or clockwise polygon on its aux plane");
    }
    if !is_convex_ccw(&sp, 1e-12 * h2) {
        return fail("slave facet projects to a non-convex polygon on its aux plane");
    }
    let mut mp: Vec<Vec2> = master.nodes().iter().map(|&x| plane.coords(x)).collect();
    // Facing masters project clockwise; counter-clockwise = back side, ~0 = edge-on.
    if !(polygon_area(&mp) < -1e-12 * s_area) {
        return Ok(None);
    }
    mp.reverse();
    let h = s_area.sqrt();
    let poly = dedupe_polygon(clip_polygon(&mp, &sp, 1e-13 * h2), 1e-12 * h);
    if poly.len() < 3 || !(polygon_area(&poly) > 1e-12 * s_area) {
        return Ok(None);
    }
    let inv_n = 1.0 / poly.len() as f64;
    let c = poly.iter().fold([0.0; 2], |acc, &p| add2(acc, scale2(inv_n, p)));
    let rule = clip_rule(slave, master);
    let (slave_inverse, master_inverse) =
        (PlaneInverse::new(slave, &plane)?, PlaneInverse::new(master, &plane)?);
    let mut out = PairIntegrals::zero(ns, nm);
    out.slave_measure = s_area;
    for i in 0..poly.len() {
        let (p1, p2) = (poly[i], poly[(i + 1) % poly.len()]);
        let area = 0.5 * cross2(sub2(p1, c), sub2(p2, c));
        if !(area > 0.0) {
            continue; // collinear sliver left by clipping: contributes nothing
        }
        for (l, w) in rule.iter() {
            let q = add2(add2(scale2(l[0], c), scale2(l[1], p1)), scale2(l[2], p2));
            let xs = slave_inverse.apply(slave, q)?;
            let xm = master_inverse.apply(master, q)?;
            let phi = slave.shape(xs);
            let psi = dual.psi(&phi);
            let gap = sub3(master.position(xm), slave.position(xs));
            let mut gn = [0.0; 4];
            for (g, n) in gn.iter_mut().zip(slave_normals.iter()) {
                *g = dot3(*n, gap);
            }
            out.add_point(w * area, &psi, &master.shape(xm), &gn);
            out.add_primal(w * area, &phi, &master.shape(xm), &gn);
        }
    }
    Ok(Some(out))
}
