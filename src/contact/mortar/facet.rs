//! Facet quadrature, shape functions and geometry (line2 in 2D, tri3 and quad4 in 3D).

use super::geom::*;
use crate::fem::quadrature::gauss_legendre;

// ------------------------------------------------------------------------------------------
// Quadrature
// ------------------------------------------------------------------------------------------

/// 7-point rule of degree 5 on a triangle (Radon 1948; Dunavant 1985 degree 5), as
/// (barycentric coordinates, weight) with weights summing to 1, so that
/// `int_T f dA ~= |T| sum_q w_q f(x_q)`.
/// Points: centroid (w = 9/40); `(a, b, b)` and permutations with
/// `a = (9 -+ 2 sqrt 15)/21`, `b = (6 +- sqrt 15)/21`, `w = (155 +- sqrt 15)/1200`.
pub fn triangle_rule_deg5() -> [([f64; 3], f64); 7] {
    let s = 15f64.sqrt();
    let (a1, b1, w1) = ((9.0 - 2.0 * s) / 21.0, (6.0 + s) / 21.0, (155.0 + s) / 1200.0);
    let (a2, b2, w2) = ((9.0 + 2.0 * s) / 21.0, (6.0 - s) / 21.0, (155.0 - s) / 1200.0);
    let c = 1.0 / 3.0;
    [
        ([c, c, c], 9.0 / 40.0),
        ([a1, b1, b1], w1),
        ([b1, a1, b1], w1),
        ([b1, b1, a1], w1),
        ([a2, b2, b2], w2),
        ([b2, a2, b2], w2),
        ([b2, b2, a2], w2),
    ]
}

/// 3-point rule of degree 2 on a triangle (Strang and Fix), as (barycentric coordinates,
/// weight) with weights summing to 1: `(2/3, 1/6, 1/6)` and permutations, `w = 1/3`.
pub fn triangle_rule_deg2() -> [([f64; 3], f64); 3] {
    let (a, b, w) = (2.0 / 3.0, 1.0 / 6.0, 1.0 / 3.0);
    [([a, b, b], w), ([b, a, b], w), ([b, b, a], w)]
}

// ------------------------------------------------------------------------------------------
// Shape functions
// ------------------------------------------------------------------------------------------

/// Line2 shape functions `phi_1 = (1 - xi)/2`, `phi_2 = (1 + xi)/2`, `xi in [-1, 1]`.
pub fn shape_line2(xi: f64) -> [f64; 2] {
    [0.5 * (1.0 - xi), 0.5 * (1.0 + xi)]
}

/// Line2 derivatives `dphi/dxi = (-1/2, 1/2)` (constant).
pub fn dshape_line2() -> [f64; 2] {
    [-0.5, 0.5]
}

/// Tri3 shape functions `phi = (1 - xi - eta, xi, eta)` on the unit reference triangle.
pub fn shape_tri3(xi: Vec2) -> [f64; 3] {
    [1.0 - xi[0] - xi[1], xi[0], xi[1]]
}

/// Tri3 derivatives `[dphi_k/dxi, dphi_k/deta]`: (-1,-1), (1,0), (0,1) (constant).
pub fn dshape_tri3() -> [[f64; 2]; 3] {
    [[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]]
}

/// Corner coordinates `(xi_k, eta_k)` of the quad4 reference nodes, counter-clockwise.
pub const QUAD4_CORNERS: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// Quad4 bilinear shape functions `phi_k = (1 + xi_k xi)(1 + eta_k eta)/4` on `[-1, 1]^2`.
pub fn shape_quad4(xi: Vec2) -> [f64; 4] {
    let mut phi = [0.0; 4];
    for (p, c) in phi.iter_mut().zip(QUAD4_CORNERS.iter()) {
        *p = 0.25 * (1.0 + c[0] * xi[0]) * (1.0 + c[1] * xi[1]);
    }
    phi
}

/// Quad4 derivatives `dphi_k/dxi = xi_k (1 + eta_k eta)/4`, `dphi_k/deta = eta_k (1 + xi_k xi)/4`.
pub fn dshape_quad4(xi: Vec2) -> [[f64; 2]; 4] {
    let mut d = [[0.0; 2]; 4];
    for (dk, c) in d.iter_mut().zip(QUAD4_CORNERS.iter()) {
        *dk = [0.25 * c[0] * (1.0 + c[1] * xi[1]), 0.25 * c[1] * (1.0 + c[0] * xi[0])];
    }
    d
}

// ------------------------------------------------------------------------------------------
// Facets
// ------------------------------------------------------------------------------------------

/// A 2-node line facet in 2D, nodes `x[0] -> x[1]` (body on the left, see module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Facet2 {
    pub x: [Vec2; 2],
}

impl Facet2 {
    /// Facet from a node list into a coordinate array; Err on a bad index.
    pub fn from_nodes(coords: &[Vec2], nodes: [usize; 2]) -> Result<Facet2, GeomError> {
        match (coords.get(nodes[0]), coords.get(nodes[1])) {
            (Some(&a), Some(&b)) => Ok(Facet2 { x: [a, b] }),
            _ => fail(format!("line facet {:?} refers to a node beyond {}", nodes, coords.len())),
        }
    }

    /// Position `x(xi) = sum_k phi_k(xi) x_k`.
    pub fn position(&self, xi: f64) -> Vec2 {
        let p = shape_line2(xi);
        add2(scale2(p[0], self.x[0]), scale2(p[1], self.x[1]))
    }

    /// Tangent `t = dx/dxi = (x_2 - x_1)/2` (constant on a line).
    pub fn tangent(&self) -> Vec2 {
        scale2(0.5, sub2(self.x[1], self.x[0]))
    }

    /// Unnormalized outward normal `n = (t_y, -t_x)`, `|n| = J = L/2`.
    pub fn normal(&self) -> Vec2 {
        let t = self.tangent();
        [t[1], -t[0]]
    }

    /// Jacobian `J = |dx/dxi| = L/2`.
    pub fn jacobian(&self) -> f64 {
        norm2(self.tangent())
    }

    pub(crate) fn is_finite(&self) -> bool {
        all_finite(&[self.x[0][0], self.x[0][1], self.x[1][0], self.x[1][1]])
    }
}

/// A 3D facet: a 3-node triangle or a 4-node bilinear quadrilateral (nodes counter-clockwise
/// seen from the side the normal points to).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Facet3 {
    Tri3([Vec3; 3]),
    Quad4([Vec3; 4]),
}

impl Facet3 {
    /// Facet from a node list of length 3 (tri3) or 4 (quad4); Err otherwise or on a bad index.
    pub fn from_nodes(coords: &[Vec3], nodes: &[usize]) -> Result<Facet3, GeomError> {
        let get = |k: usize| -> Result<Vec3, GeomError> {
            coords.get(nodes[k]).copied().ok_or_else(|| {
                GeomError(format!("facet {:?} refers to a node beyond {}", nodes, coords.len()))
            })
        };
        match nodes.len() {
            3 => Ok(Facet3::Tri3([get(0)?, get(1)?, get(2)?])),
            4 => Ok(Facet3::Quad4([get(0)?, get(1)?, get(2)?, get(3)?])),
            n => fail(format!(
                "facet {:?} has {} nodes; only tri3 and quad4 are supported",
                nodes, n
            )),
        }
    }

    /// Number of nodes (3 or 4).
    pub fn n_nodes(&self) -> usize {
        self.nodes().len()
    }

    /// Nodal coordinates.
    pub fn nodes(&self) -> &[Vec3] {
        match self {
            Facet3::Tri3(x) => x,
            Facet3::Quad4(x) => x,
        }
    }

    /// Shape functions at `xi`, padded with zeros to length 4 (entries beyond `n_nodes` are 0).
    pub fn shape(&self, xi: Vec2) -> [f64; 4] {
        match self {
            Facet3::Tri3(_) => {
                let p = shape_tri3(xi);
                [p[0], p[1], p[2], 0.0]
            }
            Facet3::Quad4(_) => shape_quad4(xi),
        }
    }

    /// Parametric derivatives `[dphi_k/dxi, dphi_k/deta]`, padded with zeros to length 4.
    pub fn dshape(&self, xi: Vec2) -> [[f64; 2]; 4] {
        match self {
            Facet3::Tri3(_) => {
                let d = dshape_tri3();
                [d[0], d[1], d[2], [0.0, 0.0]]
            }
            Facet3::Quad4(_) => dshape_quad4(xi),
        }
    }

    /// Position `x(xi) = sum_k phi_k(xi) x_k`.
    pub fn position(&self, xi: Vec2) -> Vec3 {
        let phi = self.shape(xi);
        self.nodes().iter().zip(phi.iter()).fold([0.0; 3], |acc, (x, p)| add3(acc, scale3(*p, *x)))
    }

    /// Covariant tangents `(x_xi, x_eta) = (sum_k dphi_k/dxi x_k, sum_k dphi_k/deta x_k)`.
    pub fn tangents(&self, xi: Vec2) -> (Vec3, Vec3) {
        let d = self.dshape(xi);
        let mut t1 = [0.0; 3];
        let mut t2 = [0.0; 3];
        for (x, dk) in self.nodes().iter().zip(d.iter()) {
            t1 = add3(t1, scale3(dk[0], *x));
            t2 = add3(t2, scale3(dk[1], *x));
        }
        (t1, t2)
    }

    /// Unnormalized normal `n = x_xi x x_eta`; its length is the surface Jacobian.
    pub fn normal(&self, xi: Vec2) -> Vec3 {
        let (t1, t2) = self.tangents(xi);
        cross3(t1, t2)
    }

    /// Surface Jacobian `J = |x_xi x x_eta|` (`dA = J dxi deta`).
    pub fn jacobian(&self, xi: Vec2) -> f64 {
        norm3(self.normal(xi))
    }

    /// Parametric centre: (1/3, 1/3) for tri3, (0, 0) for quad4.
    pub fn centre_param(&self) -> Vec2 {
        match self {
            Facet3::Tri3(_) => [1.0 / 3.0, 1.0 / 3.0],
            Facet3::Quad4(_) => [0.0, 0.0],
        }
    }

    /// Reference quadrature `(xi, w)` with `sum w f(xi) ~= int_ref f`: tri3 uses the 7-point
    /// degree-5 rule (reference area 1/2), quad4 the 3x3 Gauss rule (exact to degree 5 per
    /// variable: `phi_i phi_j J` is at most cubic per variable on a planar quad, since there `J`
    /// is affine in `(xi, eta)`; on a warped quad `J` is a square root and 3x3 is approximate).
    pub fn quadrature(&self) -> Vec<(Vec2, f64)> {
        match self {
            Facet3::Tri3(_) => {
                triangle_rule_deg5().iter().map(|(l, w)| ([l[1], l[2]], 0.5 * w)).collect()
            }
            Facet3::Quad4(_) => {
                let g = gauss_legendre(3);
                let mut out = Vec::with_capacity(9);
                for &(a, wa) in g.iter() {
                    for &(b, wb) in g.iter() {
                        out.push(([a, b], wa * wb));
                    }
                }
                out
            }
        }
    }

    /// Largest distance between two nodes (a length scale for tolerances).
    pub(crate) fn size(&self) -> f64 {
        let x = self.nodes();
        let mut h: f64 = 0.0;
        for i in 0..x.len() {
            for j in i + 1..x.len() {
                h = h.max(norm3(sub3(x[i], x[j])));
            }
        }
        h
    }

    pub(crate) fn is_finite(&self) -> bool {
        self.nodes().iter().all(|x| all_finite(x))
    }
}
