//! The primal-dual active set whose every iteration is one solve of the step operator (the
//! default contact solver).
//!
//! Per iteration with the active set `A`: the operator is constrained on `A`
//! ([`NormalConstraints`]: the active nodes' normal displacement increments prescribed from
//! their gaps), one KSP solve gives `du`, the residual rows give the forces `lambda_q` on `A`,
//! and the gaps `g_q - n_q . du_q` off `A`. The next set keeps the nodes with `lambda_q >= 0`
//! and adds those with a negative gap; the loop ends when the set repeats (it is the step's
//! first guess next time, so a step with an unchanged contact zone costs one solve). The
//! operator is rewritten, and the preconditioner rebuilt by PETSc, only when the set or an
//! active node's normal changes.

use super::constraint::NormalConstraints;
use super::{ActiveSetLoop, ContactNodes, ContactSolver, StepContact, StepSystem};
use std::time::Instant;

use crate::error::Result;
use crate::petsc::{Matrix, Vector};

pub struct ActiveSet<'w> {
    nodes: ContactNodes<'w>,
    /// Built from the step operator by `prepare`.
    constraints: Option<NormalConstraints>,
    /// The constrained right-hand side.
    b: Option<Vector>,
    /// Factor of the force in the step equation (2 for the midpoint rule's du form).
    factor: f64,
    max_iterations: usize,
    /// Solves beyond the first of each step.
    extra_solves: usize,
    /// With `-contact_reference_solve` (benchmark): each step's plain solve, for the cost ratio.
    reference: Option<ReferenceCost>,
}

/// The cost of the contact steps against one plain solve of the same step (the unconstrained
/// operator, the same right-hand side and first guess), summed over the steps that end with
/// an active node. Measured only with `-contact_reference_solve`; the plain solve's result is
/// discarded.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct ReferenceCost {
    pub steps: usize,
    pub plain_ksp_iterations: usize,
    pub plain_seconds: f64,
    /// Every solve of the active-set loop, and the operator rewrites between them.
    pub contact_ksp_iterations: usize,
    pub contact_seconds: f64,
    /// The plain solves of every step (to take them out of the run's time).
    pub plain_seconds_all_steps: f64,
}

impl<'w> ActiveSet<'w> {
    /// Measure each step against a plain solve (benchmark only: it costs that solve and two
    /// operator rewrites per step).
    pub fn with_reference_solve(mut self) -> ActiveSet<'w> {
        self.reference = Some(ReferenceCost::default());
        self
    }

    pub fn new(nodes: ContactNodes<'w>, factor: f64) -> ActiveSet<'w> {
        ActiveSet {
            nodes,
            constraints: None,
            b: None,
            factor,
            max_iterations: 50,
            extra_solves: 0,
            reference: None,
        }
    }

    /// Operator rewrites so far.
    pub fn operator_updates(&self) -> usize {
        self.constraints.as_ref().map_or(0, |c| c.updates)
    }
}

impl ContactSolver for ActiveSet<'_> {
    fn prepare(&mut self, k: &Matrix) -> Result<()> {
        self.constraints = Some(NormalConstraints::new(k, &self.nodes)?);
        self.b = Some(k.create_vecs()?.0);
        Ok(())
    }

    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { k, ksp, rhs, u, du, step, time } = sys;
        if self.constraints.is_none() {
            self.prepare(k)?;
        }
        let nc = self.nodes.len();
        let frames = self.nodes.frames(&self.nodes.trace(u)?, time);
        let normals: Vec<[f64; 3]> = frames.iter().map(|f| f.1).collect();
        let (Some(cons), Some(b)) = (self.constraints.as_mut(), self.b.as_mut()) else {
            unreachable!("prepared above")
        };
        // First guess: the last step's set, plus the nodes the last increment would push
        // through the obstacle (a growing contact zone then needs no extra iteration).
        let ndu_last = self.nodes.normal_parts(&frames, &self.nodes.trace(du)?);
        let mut active: Vec<bool> = (0..nc)
            .map(|p| self.nodes.active[p] || frames[p].0 - ndu_last[p] < -self.nodes.gap_tol)
            .collect();
        let plain = match self.reference {
            Some(_) => {
                cons.impose(k, &vec![false; nc], &normals)?;
                let mut x = du.duplicate()?;
                x.copy_from(du)?;
                let t0 = Instant::now();
                let info = ksp.solve(rhs, &mut x)?;
                Some((info.iterations, t0.elapsed().as_secs_f64()))
            }
            None => None,
        };
        let t0 = Instant::now();
        let mut lp = ActiveSetLoop::new(&active, self.max_iterations, step, time);
        let mut its = 0;
        let (lambda, trace) = loop {
            cons.impose(k, &active, &normals)?;
            cons.rhs(rhs, &active, &frames, b)?;
            its += ksp.solve(b, du)?.iterations;
            let trace = self.nodes.trace(du)?;
            let lambda = cons.forces(&self.nodes, rhs, du, &active, &normals, self.factor)?;
            let ndu = self.nodes.normal_parts(&frames, &trace);
            let gap: Vec<f64> = (0..nc).map(|p| frames[p].0 - ndu[p]).collect();
            let next = ActiveSetLoop::next_set(&active, &lambda, &gap, self.nodes.gap_tol);
            match lp.advance(&active, next, &self.nodes.tags)? {
                None => break (lambda, trace),
                Some(next) => active = next,
            }
        };
        self.extra_solves += lp.iterations - 1;
        if let (Some(r), Some((plain_its, plain_s))) = (self.reference.as_mut(), plain) {
            r.plain_seconds_all_steps += plain_s;
            if active.iter().any(|&a| a) {
                r.steps += 1;
                r.plain_ksp_iterations += plain_its;
                r.plain_seconds += plain_s;
                r.contact_ksp_iterations += its;
                r.contact_seconds += t0.elapsed().as_secs_f64();
            }
        }
        let out = self.nodes.step_contact(&frames, active.clone(), &lambda, &trace, lp.iterations);
        self.nodes.active = active;
        Ok((out, its))
    }

    fn nodes(&self) -> &ContactNodes<'_> {
        &self.nodes
    }
    fn active_mut(&mut self) -> &mut Vec<bool> {
        &mut self.nodes.active
    }
    fn extra_solves(&self) -> usize {
        self.extra_solves
    }
    fn reference_cost(&self) -> Option<ReferenceCost> {
        self.reference
    }
}
