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

use super::active_set::ActiveSetLoop;
use super::constraint::NormalConstraints;
pub use super::cost::ReferenceCost;
use super::interface::ContactSolver;
use super::nodes::ContactNodes;
use super::step::{StepContact, StepSystem};
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
    /// Relative tolerance of the solves until the active set repeats (`-contact_loose_rtol`,
    /// default the square root of the step solver's); at or below the step solver's own,
    /// every solve is exact.
    loose_rtol: Option<f64>,
    /// Solves beyond the first of each step.
    extra_solves: usize,
    /// With `-contact_reference_solve` (benchmark): each step's plain solve, for the cost ratio.
    reference: Option<ReferenceCost>,
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
            loose_rtol: None,
            extra_solves: 0,
            reference: None,
        }
    }

    /// Solve with relative tolerance `rtol` until the active set repeats, then to full
    /// accuracy.
    pub fn with_loose_rtol(mut self, rtol: Option<f64>) -> ActiveSet<'w> {
        self.loose_rtol = rtol;
        self
    }

    /// The contact nodes (e.g. to move the planes of a two-body contact).
    pub fn nodes_mut(&mut self) -> &mut ContactNodes<'w> {
        &mut self.nodes
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
        let tight = ksp.rtol()?;
        let rhs_norm = rhs.norm2()?;
        let loose = self.loose_rtol.unwrap_or(tight.sqrt());
        // Inexact solves only pay when the set may change: not while every node stays away
        // from the obstacle by more than the largest normal motion of the last step.
        let reach = ndu_last.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
        let quiet = (0..nc).all(|p| !active[p] && frames[p].0 - ndu_last[p] > reach);
        let mut exact = quiet || loose <= tight;
        let mut confirmations = 0;
        let (lambda, trace) = loop {
            cons.impose(k, &active, &normals)?;
            cons.rhs(rhs, &active, &frames, b)?;
            if b.norm2()? <= tight * rhs_norm {
                // The constrained right-hand side is below the accuracy the step asks for
                // (e.g. bodies at rest in equilibrium): du = 0 solves it to that accuracy, and a
                // relative tolerance on round-off could never be met.
                du.zero()?;
            } else {
                if !exact {
                    ksp.set_tolerances(Some(loose), None, None, None)?;
                }
                let info = ksp.solve(b, du);
                if !exact {
                    ksp.set_tolerances(Some(tight), None, None, None)?;
                }
                its += info?.iterations;
            }
            let trace = self.nodes.trace(du)?;
            let lambda = cons.forces(&self.nodes, rhs, du, &active, &normals, self.factor)?;
            let ndu = self.nodes.normal_parts(&frames, &trace);
            let gap: Vec<f64> = (0..nc).map(|p| frames[p].0 - ndu[p]).collect();
            let next = ActiveSetLoop::next_set(&active, &lambda, &gap, self.nodes.gap_tol);
            if !exact && (next == active || lp.seen(&next)) {
                // The inexact solves found their set (or cycle among nearby sets): from here
                // on solve to full accuracy, starting from where they ended. That solve
                // confirms the set; it is counted as a solve, not as an active-set iteration.
                exact = true;
                confirmations += 1;
                lp.restart(&next);
                active = next;
                continue;
            }
            match lp.advance(&active, next, &self.nodes.tags)? {
                None => break (lambda, trace),
                Some(next) => active = next,
            }
        };
        self.extra_solves += lp.iterations - 1 + confirmations;
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
