//! Frictionless contact with rigid obstacles, resolved by a primal-dual active set inside
//! each time step (METHOD.md section 5; no SNES).
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
//! Files: this one holds the interface between the integrator and a contact solver
//! ([`ContactSolver`], [`StepSystem`], [`StepContact`]) and the factory [`solver`];
//! `nodes.rs` the contact boundary and nodes ([`ContactBoundary`], [`ContactNodes`], [`trace`]);
//! `active_set.rs` the active-set loop's bookkeeping ([`ActiveSetLoop`]).

mod active_set;
pub mod columns;
pub mod constraint;
pub mod history;
pub mod metrics;
pub mod mortar;
mod nodes;
pub mod obstacle;
pub mod pdas;

use mpi::topology::SimpleCommunicator;

use crate::error::Result;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Ksp, Matrix, Vector};

pub use crate::rows::ContactRow;
pub use active_set::ActiveSetLoop;
pub use nodes::{trace, ContactBoundary, ContactNodes};
pub use obstacle::{Obstacle, Obstacles, Shape};

/// A contact solver inside the time step: it gets the step's right-hand side and the state at
/// `t_n`, solves `K du = rhs - factor B^T lambda` with the contact conditions at `t_{n+1}`
/// (`factor` comes from the integrator), and reports the contact forces and per-node data.
pub trait ContactSolver {
    /// Called once with the step operator before the first step (collective).
    fn prepare(&mut self, _k: &Matrix) -> Result<()> {
        Ok(())
    }
    /// Solves one step (see [`StepSystem`]). Returns the step's contact data and the KSP
    /// iterations of its solves.
    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)>;
    /// The contact nodes (boundary, obstacles, per-node geometry, active set).
    fn nodes(&self) -> &ContactNodes<'_>;
    /// The active set, to continue from a checkpoint's.
    fn active_mut(&mut self) -> &mut Vec<bool>;
    /// The active set after the last step.
    fn active(&self) -> &[bool] {
        &self.nodes().active
    }
    /// Continue from a checkpoint's active set.
    fn set_active(&mut self, active: Vec<bool>) {
        *self.active_mut() = active;
    }
    /// Solves with the step operator beyond one per step, so far.
    fn extra_solves(&self) -> usize;
    /// The contact steps' cost against plain solves, when measured.
    fn reference_cost(&self) -> Option<pdas::ReferenceCost> {
        None
    }
    /// The contact boundary (nodes, weights, group).
    fn boundary(&self) -> &ContactBoundary {
        &self.nodes().boundary
    }
    /// Contact nodes that penetrate an obstacle at displacement `u` and time `time`: (mesh
    /// node index, index of the obstacle).
    fn penetrating(&self, u: &Vector, time: f64) -> Result<Vec<(usize, usize)>> {
        self.nodes().penetrating(u, time)
    }
    /// Index (among the contact nodes) of the node closest to an obstacle at t = 0.
    fn lowest(&self) -> usize {
        self.nodes().lowest()
    }
    fn n_nodes(&self) -> usize {
        self.boundary().nodes.len()
    }
    /// A slave/master pair of deformable bodies (not rigid obstacles).
    fn is_pair(&self) -> bool {
        false
    }
    /// The master nodes of the pairs (mesh indices, ascending; empty against obstacles).
    fn master_nodes(&self) -> &[usize] {
        &[]
    }
    /// What the mortar interface cost so far on this rank (two-body pairs).
    fn mortar_cost(&self) -> Option<mortar::MortarCost> {
        None
    }
}

/// One step's linear system as the integrator hands it to the contact solver.
pub struct StepSystem<'a> {
    /// The operator `ksp` solves with: the solver may change it near the contact nodes (and
    /// restores it when the contact ends).
    pub k: &'a mut Matrix,
    pub ksp: &'a mut Ksp,
    /// The right-hand side of `K du = rhs - factor B^T lambda`.
    pub rhs: &'a Vector,
    /// `u^n`.
    pub u: &'a Vector,
    /// Holds the previous increment (the first guess) and gets the result.
    pub du: &'a mut Vector,
    /// The step being solved (`n + 1`) and its end time `t_{n+1}`.
    pub step: usize,
    pub time: f64,
}

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
    /// obstacles; `columns` is the first wave's, kept for comparison.
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

/// What the contact solver found in one step (all per contact node, same on every rank).
#[derive(Debug, Clone, Default)]
pub struct StepContact {
    pub row: ContactRow,
    pub normals: Vec<[f64; 3]>,
    /// Work of the contact forces in this step, `-sum_q lambda_q n_q . du_q` (<= 0).
    pub work: f64,
    /// `sum_q lambda_q n_q` (the force the obstacle takes; the body gets its negative); of a
    /// pair with obstacles beside it, over the slave nodes only.
    pub resultant: [f64; 3],
    /// Of a pair with obstacles beside it: `sum_q lambda_q n_q` over the nodes that meet the
    /// obstacles (the obstacles' force; that body gets its negative). Zero otherwise.
    pub obstacle_force: [f64; 3],
    /// The force on the master body of a two-body pair, `sum_l (M^T lambda)_l n`, i.e.
    /// `sum_q (sum_l M_ql / D_qq) lambda_q n_q` (zero against rigid obstacles).
    pub master_force: [f64; 3],
    /// Per master node `l` (of [`ContactSolver::master_nodes`]): its share
    /// `sum_q (M_ql / D_qq) lambda_q n_q` of `master_force` (empty against rigid obstacles).
    pub master_nodal: Vec<[f64; 3]>,
}

/// A slave node's plane in the mortar basis, `(c_q, n_q)`: `n_q . y_q <= c_q`.
pub type NodePlane = (f64, [f64; 3]);
