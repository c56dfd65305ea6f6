//! What crosses the interface of a contact solver in one step: the step's linear system
//! ([`StepSystem`]) and what the solver found ([`StepContact`]); a slave node's plane
//! ([`NodePlane`]).

use crate::petsc::{Ksp, Matrix, Vector};
use crate::rows::ContactRow;

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
    /// The step being solved (`n + 1`), its end time `t_{n+1}` and length `tau`.
    pub step: usize,
    pub time: f64,
    pub tau: f64,
}

/// What the contact solver found in one step (all per contact node, same on every rank).
#[derive(Debug, Clone, Default)]
pub struct StepContact {
    pub row: ContactRow,
    pub normals: Vec<[f64; 3]>,
    /// Work of the contact forces in this step, `-sum_q lambda_q n_q . du_q` (<= 0).
    pub work: f64,
    /// With friction: the frictional dissipation of the step, `sum_q t_q . s_q >= 0` (the
    /// tangential force's work against the slip; the body loses it).
    pub dissipation: f64,
    /// With friction against a moving obstacle: the work its tangential force does by
    /// carrying the body along, `-sum_q t_q . w_q` (the body's tangential work is this minus
    /// the dissipation).
    pub tangential_work: f64,
    /// `sum_q lambda_q n_q + t_q` (the force the obstacle takes; the body gets its negative);
    /// of a pair with obstacles beside it, over the slave nodes only.
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
    /// With friction: per contact node, the tangential force its body got, `-t_q` as the
    /// solve applied it (a pair's `t_q` may be restated at the midpoint in `row.tangential`).
    pub friction_nodal: Vec<[f64; 3]>,
    /// With friction between two bodies: per master node, friction's part of `master_nodal`,
    /// `sum_q (M_ql / D_qq) t_q` (empty otherwise).
    pub master_friction: Vec<[f64; 3]>,
    /// Per contact node: a force beside `-force n` (the rest of the consistent force of an
    /// interface that follows the bodies; empty otherwise).
    pub contact_nodal: Vec<[f64; 3]>,
}

/// A slave node's plane in the mortar basis, `(c_q, n_q)`: `n_q . y_q <= c_q`.
pub type NodePlane = (f64, [f64; 3]);
