//! Lowest-order (P1/Q1) finite-element building blocks: element kinds, quadrature rules,
//! shape functions and the element kernels of dynamic linear elasticity.

pub mod element;
pub mod hyperelastic;
pub mod kernels;
pub mod quadrature;
pub mod shape;
pub mod stress;

pub use element::ElementKind;
pub use kernels::{
    body_force, boundary_weights, divergence_row, error_sq, mass, mass_lumped, mass_lumped_diag,
    measure, min_det_jacobian, stiffness, traction, Material, MAX_DOFS, MAX_NODES,
};
pub use quadrature::gauss;
pub use shape::{physical_gradients, shape, shape_grad_ref, surface_measure};
