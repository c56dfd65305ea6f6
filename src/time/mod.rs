//! The implicit midpoint rule (paper (6.1), docs/method.md, the midpoint rule).
//!
//! ```text
//!   M (v^{n+1} - v^n)/tau + A (u^{n+1} + u^n)/2 = f^{n+1/2},   (u^{n+1} - u^n)/tau = (v^{n+1} + v^n)/2
//! ```
//! With `du = u^{n+1} - u^n` this is one linear solve per step with the constant step operator
//!
//! ```text
//!   (4/tau^2 M + A) du = 2 f^{n+1/2} + (4/tau) M v^n - 2 A u^n,   v^{n+1} = 2 du/tau - v^n,
//! ```
//! `f^{n+1/2} = (f(t_n) + f(t_{n+1}))/2`. The operator and its preconditioner/factorization are
//! built once per run. The discrete energy `E^n = 1/2 v.Mv + 1/2 u.Au` obeys exactly
//! `E^{n+1} - E^n = f^{n+1/2} . du` (dot the first equation with du = tau (v^{n+1}+v^n)/2), so the
//! energy balance is a built-in check of the integrator at every step.

pub mod cg;
pub mod choice;
pub mod dirichlet;
pub mod layer;
pub mod midpoint;
pub mod newton;
pub mod operator;

pub use cg::Predictor;
pub use dirichlet::Dirichlet;
pub use midpoint::{Corrections, Energy, Forces, Midpoint, ReuseReport, StepReport};
pub use operator::{Regime, Reuse, StepOperator, StepSolverDefaults};
