//! Dual mortar geometry for frictionless two-body contact on non-matching meshes.
//!
//! References: Wohlmuth (2000) for the dual Lagrange multiplier basis; Popp, Gee, Wall (2009)
//! for segment-based integration in 2D; Popp, Gee, Wohlmuth, Wall (2010) and Puso & Laursen
//! (2004) for the auxiliary-plane clipping in 3D.
//!
//! Facets are lowest order: `Line2` in 2D, `Tri3` and `Quad4` (bilinear, possibly warped) in 3D.
//!
//! Conventions used throughout:
//! * Reference elements: line2 `xi in [-1, 1]`, nodes at -1, +1; tri3 `xi, eta >= 0,
//!   xi + eta <= 1`, nodes (0,0), (1,0), (0,1); quad4 `[-1, 1]^2`, nodes (-1,-1), (1,-1), (1,1),
//!   (-1,1).
//! * Orientation: the facet normal is `n = x_xi x x_eta` in 3D (outward when the nodes run
//!   counter-clockwise seen from outside the body) and `n = (t_y, -t_x)` with `t = dx/dxi` in
//!   2D, i.e. a line from `a` to `b` has the body on its LEFT (the order gmsh uses for the
//!   boundary lines of a counter-clockwise domain). `nodal_normals_*` take a `reverse` flag for
//!   the opposite convention.
//! * Slave normals point out of the slave body, towards the master. Master facets must face the
//!   slave (`n_m . n_s < 0`); a master facet facing away is the back of the master body and a
//!   pair with it has no overlap (`Ok(None)`).
//! * Weighted gap: `g_j = int psi_j n_j . (x_m(proj) - x_s)`, positive when the bodies are apart.
//! * Errors: library functions never panic on degenerate input; they return `Err(GeomError)`
//!   with a one-line message. "No overlap" is not an error: it is `Ok(None)`.
//! * Tolerance tests are written `!(x > tol)` on purpose: they are also true for NaN.

// Deliberate: `!(a > b)` treats NaN as failing the test, which `a <= b` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod dual;
mod facet;
mod geom;
mod gradient;
mod interface;
mod linearize;
mod linearize3d;
mod normals;
mod search;
mod segment;
mod solver;
#[cfg(test)]
mod tests;

pub use dual::*;
pub use facet::*;
pub use geom::*;
pub use interface::*;
pub use linearize::*;
pub use linearize3d::*;
pub use normals::*;
pub use search::*;
pub use segment::*;
pub use solver::*;
