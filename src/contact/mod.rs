//! Contact with rigid obstacles, frictionless or with Coulomb/Tresca friction, resolved by a
//! primal-dual active set inside each time step (docs/method.md, contact; no SNES). The normal
//! condition is described here; friction's three sets per node are in [`constraint`] and
//! [`pdas`].
//!
//! Per contact node `q`: normal `n_q` (unit, from the body towards the obstacle), gap
//! `g_q(u) = g^n_q - n_q . (u_q - u^n_q)` linearized at the start of the step (exact for a
//! plane), contact force `lambda_q >= 0`, and complementarity `g_q lambda_q = 0` at `t_{n+1}`.
//! `g^n_q` and `n_q` are those of the node at `u^n` against the obstacles placed at `t_{n+1}`
//! (moving obstacles, [`obstacle`]): of the obstacle with the smallest gap there.
//! The force enters the midpoint equation: `K du = rhs - 2 sum_q lambda_q n_q e_q`.
//!
//! Two solvers implement [`ContactSolver`]:
//! - [`pdas::ActiveSet`] (the default): every active-set iteration is one solve of the step
//!   operator with the active nodes' normal displacements prescribed (the operator projected
//!   onto their tangent planes, [`constraint::NormalConstraints`]); the forces come from the
//!   residual rows. Memory O(N + contact nodes); the operator changes only near the contact
//!   nodes and only when the active set (or a normal) changes.
//! - [`columns::ColumnActiveSet`] (`-contact_solver columns`, kept for comparison): a Schur
//!   complement on the active DOFs from one stored column `K^{-1} e_{q,c}` per node and
//!   component; exact and fast for a few dozen nodes, O(active^2) memory and one extra solve
//!   per column, which does not scale to 3D.
//!
//! Files: `interface.rs` the interface between the integrator and a contact solver
//! ([`ContactSolver`]), `step.rs` what crosses it in a step ([`StepSystem`], [`StepContact`]);
//! `nodes.rs` the contact boundary and nodes ([`ContactBoundary`], [`ContactNodes`], [`trace`]);
//! `active_set.rs` the active-set loop's bookkeeping ([`ActiveSetLoop`]); `friction.rs` the
//! friction law at one node (Coulomb and Tresca: the sets stick and slip, the slip bound and
//! the complementarity function; `pdas` turns them into the rows of
//! [`constraint::Condition`]); `cost.rs` what contact costs; this one the factory [`solver`] and its options. The files import each
//! other, never this one (no import circle).

mod active_set;
pub mod columns;
pub mod constraint;
pub mod cost;
pub mod friction;
pub mod history;
mod interface;
pub mod metrics;
pub mod mortar;
mod nodes;
pub mod obstacle;
pub mod pdas;
mod step;

use mpi::topology::SimpleCommunicator;

use crate::error::Result;
use crate::mesh::Mesh;
use crate::partition::Partition;

pub use crate::rows::ContactRow;
pub use active_set::ActiveSetLoop;
pub use interface::ContactSolver;
pub use nodes::{trace, ContactBoundary, ContactNodes, NodeFriction, StepFriction};
pub use obstacle::{Obstacle, Obstacles, Shape};
pub use step::{NodePlane, StepContact, StepSystem};

/// Which active-set solver meets the rigid obstacles (`-contact_solver`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ContactSolverKind {
    /// [`pdas::ActiveSet`]: one solve of the constrained step operator per iteration.
    #[default]
    Pdas,
    /// [`columns::ColumnActiveSet`]: a Schur complement from stored columns (for comparison).
    Columns,
}

/// The contact solver's options, as the run read them at set-up
/// (`run::options::AppOptions::read`).
#[derive(Debug, Clone)]
pub struct ContactOptions {
    /// `-contact_solver pdas|columns` (default `pdas`): the active-set solver against rigid
    /// obstacles; `columns` is the older Schur-complement solver, kept for comparison.
    pub solver: ContactSolverKind,
    /// `-contact_loose_rtol R` (default: the square root of the step solver's rtol): the
    /// relative tolerance of the `pdas` solves until the active set repeats (then one solve to
    /// full accuracy confirms it); at or below the step solver's rtol every solve is exact.
    pub loose_rtol: Option<f64>,
    /// `-contact_reference_solve` (default off; benchmark): each `pdas` step is also solved
    /// without contact, for the cost ratio in the summary.
    pub reference_solve: bool,
}

impl Default for ContactOptions {
    fn default() -> Self {
        ContactOptions { solver: ContactSolverKind::Pdas, loose_rtol: None, reference_solve: false }
    }
}

/// The contact solver `options` ask for (default pdas).
pub fn solver<'w>(
    world: &'w SimpleCommunicator,
    mesh: &Mesh,
    part: &Partition,
    boundary: ContactBoundary,
    obstacles: Obstacles,
    factor: f64,
    options: &ContactOptions,
) -> Result<Box<dyn ContactSolver + 'w>> {
    let nodes = ContactNodes::new(world, mesh, part, boundary, obstacles);
    if options.solver == ContactSolverKind::Columns && nodes.has_friction() {
        return Err(crate::error::Error::Usage(
            "-contact_solver columns has no friction: drop the option (the default pdas has)"
                .into(),
        ));
    }
    match options.solver {
        ContactSolverKind::Pdas => {
            let mut s = pdas::ActiveSet::new(nodes, factor);
            // Until the active set repeats, half the digits of the step solver's tolerance
            // (inexact semismooth Newton); then one solve to full accuracy confirms the set.
            s = s.with_loose_rtol(options.loose_rtol);
            Ok(Box::new(if options.reference_solve { s.with_reference_solve() } else { s }))
        }
        ContactSolverKind::Columns => Ok(Box::new(columns::ColumnActiveSet::new(nodes, factor))),
    }
}
