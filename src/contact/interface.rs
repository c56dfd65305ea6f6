//! The interface between the integrator and a contact solver: the [`ContactSolver`] trait
//! (a step's system in, the contact forces and per-node rows out).

use super::cost::{MortarCost, ReferenceCost};
use super::nodes::{ContactBoundary, ContactNodes};
use super::step::{StepContact, StepSystem};
use crate::error::Result;
use crate::petsc::{Matrix, Vector};

/// A contact solver inside the time step: it gets the step's right-hand side and the state at
/// `t_n`, solves `K du = rhs - factor B^T lambda` with the contact conditions at `t_{n+1}`
/// (`factor` comes from the integrator), and reports the contact forces and per-node data.
pub trait ContactSolver {
    /// Called once with the step operator before the first step (collective).
    fn prepare(&mut self, _k: &Matrix) -> Result<()> {
        Ok(())
    }
    /// The step operator was replaced by a new unconstrained one of the same pattern (each
    /// Newton iteration of finite-strain bodies): what the solver read from the old one is
    /// read again (collective).
    fn operator_replaced(&mut self, k: &Matrix) -> Result<()> {
        self.prepare(k)
    }
    /// Whether the solver can follow an operator that changes every Newton iteration
    /// ([`ContactSolver::operator_replaced`] cheap; finite strain).
    fn follows_operator_changes(&self) -> bool {
        false
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
    /// With friction: node-steps held slipping to end a stick/slip cycle, so far.
    fn held_slipping(&self) -> usize {
        0
    }
    /// The contact steps' cost against plain solves, when measured.
    fn reference_cost(&self) -> Option<ReferenceCost> {
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
    /// The global DOFs whose rows carried a contact force in the last step (the active
    /// nodes', all components; with pairs also the master nodes they press on), the same on
    /// every rank: the mass-free layer's velocity holds them
    /// ([`crate::time::Midpoint::settle_layer_velocity`]).
    fn loaded_dofs(&self) -> Vec<i32> {
        let nodes = self.nodes();
        let dim = nodes.dim;
        let mut dofs = Vec::new();
        for (k, &a) in self.active().iter().enumerate() {
            if a {
                dofs.extend((0..dim).map(|c| nodes.dofs[k * dim + c].0));
            }
        }
        dofs
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
    fn mortar_cost(&self) -> Option<MortarCost> {
        None
    }
    /// Whether the geometry follows the bodies inside the step: then a step whose active set
    /// stays also does contact work (the midpoint rule's error on the moving geometry), which
    /// the integrator's energy correction puts back too.
    fn geometry_follows(&self) -> bool {
        false
    }
    /// Whether after [`ContactSolver::solve`] the step operator holds the constrained
    /// operator of the step's final active set, `K~ = P K P + sum_q d_q n_q n_q^T` (the
    /// active nodes' normal increments fixed, symmetric; rigid obstacles without friction):
    /// then `(K~ w)_C = 0` on the contact rows is the layer's static response that keeps the
    /// contact forces (the energy correction's kick, `time::Midpoint`).
    fn constrained_operator(&self) -> bool {
        false
    }
}
