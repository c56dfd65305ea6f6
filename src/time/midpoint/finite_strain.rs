//! The midpoint step of finite-strain bodies (`time::newton`): the integrator's state, loads,
//! Dirichlet increments and energy accounting around one Newton loop.

use super::{Midpoint, StepReport};
use crate::contact::ContactSolver;
use crate::contact::StepContact;
use crate::error::Result;
use crate::petsc::Vector;
use crate::time::newton::{Newton, NewtonStep, StepInputs};
use crate::time::Forces;

impl Midpoint {
    /// Step finite-strain bodies with `newton` from now on (the energies recomputed with the
    /// strain energy). Collective.
    pub fn set_finite_strain(&mut self, newton: Newton) -> Result<()> {
        self.newton = Some(Box::new(newton));
        self.update_energies()
    }

    /// Whether the bodies step at finite strain.
    pub fn is_finite_strain(&self) -> bool {
        self.newton.is_some()
    }

    /// The Newton loops' statistics (finite strain only).
    pub fn newton_stats(&self) -> Option<crate::time::newton::NewtonStats> {
        self.newton.as_ref().map(|n| n.stats)
    }

    /// [`Midpoint::project_massless`] for finite-strain bodies: the massless rows' nonlinear
    /// static problem (`Newton::static_massless`), `hold` (global DOFs) kept. Returns the
    /// largest change. Collective; energies not refreshed.
    pub(super) fn project_massless_finite(
        &mut self,
        massless: &[bool],
        loads: bool,
        hold: &[i32],
    ) -> Result<f64> {
        let (lo, hi) = self.u.ownership_range();
        let mut free = massless.to_vec();
        for &g in hold {
            let g = g as usize;
            if (lo..hi).contains(&g) {
                free[g - lo] = false;
            }
        }
        let newton = self.newton.as_mut().expect("finite strain");
        let loads = loads.then_some(&self.f_now);
        let diag = self.op.dirichlet_diag;
        let (change, its) = newton.static_massless(
            &mut self.op.k,
            &mut self.op.ksp,
            &mut self.u,
            loads,
            &free,
            diag,
        )?;
        self.ksp_iterations += its;
        Ok(change)
    }

    /// One Newton solve of the step from the current `du` with `f_sum` (`f_0 + f_1`, or
    /// with the energy correction's force) as the loads. Collective.
    #[allow(clippy::too_many_arguments)]
    fn newton_pass<'c>(
        &mut self,
        n: usize,
        t_next: f64,
        dofs: &[i32],
        du_d: &[f64],
        f_sum: Option<&Vector>,
        contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<NewtonStep> {
        let energy = self.energy.kinetic + self.energy.potential;
        let newton = self.newton.as_mut().expect("finite strain");
        let step = newton.step(
            StepInputs {
                m: &self.m,
                k: &mut self.op.k,
                ksp: &mut self.op.ksp,
                dirichlet: dofs,
                dirichlet_du: du_d,
                dirichlet_diag: self.op.dirichlet_diag,
                u: &self.u,
                mv: &self.mv,
                f_sum,
                du: &mut self.du,
                tau: self.tau,
                energy,
                step: n + 1,
                time: t_next,
            },
            contact,
        )?;
        self.ksp_iterations += step.ksp_iterations;
        Ok(step)
    }

    /// One step `n -> n + 1` of the energy-momentum midpoint rule, with the contact solver
    /// inside each Newton iteration when there is one. With massless DOFs, as the linear
    /// step: a step whose active set changed gets the energy correction's force (its solves,
    /// [`Midpoint::correct_energy_finite`]), and released nodes are put back in static
    /// equilibrium (the nonlinear static problem of the layer).
    pub(super) fn step_finite_strain<'c>(
        &mut self,
        n: usize,
        forces: &dyn Forces,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<StepReport> {
        let started = std::time::Instant::now();
        let tau = self.tau;
        let t_next = self.time_at(n + 1);
        let (loads, varying) = (forces.present(), forces.time_dependent());
        if loads && varying {
            forces.assemble(t_next, &mut self.f_next)?;
        }
        // f_0 + f_1, in a vector kept between steps (outside `self`: the Newton solves borrow
        // the integrator).
        let mut f_sum = match self.f_sum.take() {
            Some(v) => v,
            None => self.u.duplicate()?,
        };
        if loads {
            f_sum.waxpy(1.0, &self.f_now, if varying { &self.f_next } else { &self.f_now })?;
        } else {
            f_sum.zero()?;
        }
        let lo = self.first_dof;
        let dofs = self.dirichlet.dofs().to_vec();
        let mut du_d = vec![0.0; dofs.len()];
        self.u.with_local_slice(|x| {
            for (i, &dof) in dofs.iter().enumerate() {
                du_d[i] = self.dirichlet.value(i, t_next) - x[dof as usize - lo];
            }
        })?;
        // The first guess: the last two increments extrapolated, `2 du_n - du_{n-1}` (off by
        // O(tau^3) where the motion is smooth, against O(tau^2) for `tau v_n`: the beam at
        // CFL 1 took 1.6 solves per step instead of 2.0); before there are two, the motion at
        // constant velocity, or with massless DOFs (whose midpoint velocity is not their
        // motion) the last increment.
        let mut prev = match self.du_prev.take() {
            Some(v) => v,
            None => self.du.duplicate()?,
        };
        if self.increments >= 2 {
            prev.aypx(-1.0, &self.du)?; // du_n - du_{n-1}
            self.du.axpy(1.0, &prev)?;
            prev.aypx(-1.0, &self.du)?; // du_n again
        } else {
            prev.copy_from(&self.du)?;
            if n == 0 || !self.has_massless() {
                self.du.copy_from(&self.v)?;
                self.du.scale(tau)?;
            }
        }
        self.du_prev = Some(prev);
        let before: Option<Vec<bool>> = contact.as_deref().map(|c| c.active().to_vec());
        let fs = loads.then_some(&f_sum);
        // The extrapolated guess runs the last motion on: into a nearly incompressible body
        // that an obstacle stops, it lies far from the step's solution (the neo-Hookean disc
        // at nu = 0.499, tau = 0.01: Newton diverged in the third step) where the step's
        // start does not. A failed step is solved once more from the other guess, and after
        // a restart from rest the next REST_GUESSES steps start from rest (a failed attempt
        // costs Newton's iteration limit). Against obstacles without friction only (a pair's
        // interface and friction's slip states move inside the attempt).
        const REST_GUESSES: usize = 10;
        let retry = contact
            .as_deref()
            .is_none_or(|c| !c.is_pair() && c.nodes().friction.iter().all(Option::is_none));
        let extrapolated = if retry && self.rest_guesses > 0 {
            self.rest_guesses -= 1;
            let mut kept = self.du.duplicate()?;
            kept.copy_from(&self.du)?;
            self.du.zero()?;
            Some(kept)
        } else {
            None
        };
        let first = self.newton_pass(n, t_next, &dofs, &du_d, fs, contact.as_deref_mut());
        let mut step = match first {
            Err(crate::error::Error::Solver(_)) if retry => {
                if let (Some(c), Some(b)) = (contact.as_deref_mut(), before.as_ref()) {
                    c.set_active(b.clone());
                }
                match &extrapolated {
                    Some(guess) => self.du.copy_from(guess)?,
                    None => {
                        self.du.zero()?;
                        self.rest_guesses = REST_GUESSES;
                    }
                }
                if let Some(newton) = self.newton.as_mut() {
                    newton.stats.restarts += 1;
                }
                self.newton_pass(n, t_next, &dofs, &du_d, fs, contact.as_deref_mut())?
            }
            other => other?,
        };
        let mut iterations = step.iterations;
        let mut ksp_iterations = step.ksp_iterations;
        let mut dirichlet_work = step.dirichlet_work;
        let mut hold: Vec<i32> = Vec::new();
        let mut project = false;
        if let Some(c) = step.contact.clone() {
            let changed = before.as_deref().is_some_and(|b| b != c.row.active.as_slice());
            let follows = contact.as_deref().is_some_and(|s| s.geometry_follows());
            if let Some(slack) = self.correction_due(changed, follows, c.work) {
                let (extra, corrected) = self.correct_energy_finite(
                    &c,
                    &f_sum,
                    (n, t_next),
                    &dofs,
                    &du_d,
                    slack,
                    contact.as_deref_mut(),
                )?;
                if let Some(s) = corrected {
                    iterations += s.iterations;
                    dirichlet_work = s.dirichlet_work;
                    step = s;
                }
                ksp_iterations += extra;
            }
            let c = step.contact.as_ref().expect("a contact step");
            // Released massless nodes: put back in static equilibrium (held: the nodes still
            // active), as the linear step does.
            // Pairs are left as they are (their constraints live in the mortar basis).
            let b = before.as_deref().unwrap_or_default();
            let solver = contact.as_deref().expect("contact solver");
            if !solver.is_pair() && b.iter().zip(&c.row.active).any(|(&was, &is)| was && !is) {
                let nodes = solver.nodes();
                let dim = nodes.dim;
                for (k, &a) in c.row.active.iter().enumerate() {
                    if a {
                        hold.extend((0..dim).map(|i| nodes.dofs[k * dim + i].0));
                    }
                }
                project = true;
            }
        }
        if loads {
            self.energy.external_work += self.load_work(varying)?;
        }
        self.energy.dirichlet_work += dirichlet_work;
        if let Some(c) = &step.contact {
            self.energy.contact_work += c.work + c.tangential_work;
            self.energy.friction_dissipation += c.dissipation;
        }
        if loads && varying {
            std::mem::swap(&mut self.f_now, &mut self.f_next);
        }
        self.u.axpy(1.0, &self.du)?;
        // v^{n+1} = 2 du / tau - v^n
        self.v.scale(-1.0)?;
        self.v.axpy(2.0 / tau, &self.du)?;
        self.m.mult(&self.v, &mut self.mv)?;
        self.energy.kinetic = 0.5 * self.v.dot(&self.mv)?;
        self.energy.potential = step.strain_energy;
        if project {
            self.release(loads, &hold)?;
        }
        let loaded = contact.as_deref().map_or_else(Vec::new, |c| c.loaded_dofs());
        self.after_step_layer(loaded, loads && varying)?;
        self.f_sum = Some(f_sum);
        self.increments += 1;
        let touching = step.contact.as_ref().is_some_and(|c| c.row.active.iter().any(|&a| a));
        if let Some(newton) = self.newton.as_mut() {
            newton.stats.book_step(touching, iterations, started.elapsed().as_secs_f64());
        }
        Ok(StepReport {
            time: t_next,
            ksp_iterations,
            newton_iterations: iterations,
            contact: step.contact,
        })
    }

    /// The energy correction of a finite-strain contact step (the solves of
    /// [`Midpoint::correct_energy`]): the force `-2 xi m`, `m = P M du_0` (`du_0` the first
    /// solve's increment, `P` without each body's translation), joins the loads, each `xi`
    /// a Newton solve of the step, until the contact work and the correction's, `-xi m.du`,
    /// cancel with the pending debt; `xi` by the scalar model through the last two solves
    /// (`model_root`). A step too slow to carry it hands the work on. Returns the extra KSP
    /// iterations and the corrected step (its contact work with the correction's).
    #[allow(clippy::too_many_arguments)]
    fn correct_energy_finite<'c>(
        &mut self,
        first: &StepContact,
        f_sum: &Vector,
        (n, t_next): (usize, f64),
        dofs: &[i32],
        du_d: &[f64],
        slack: f64,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<(usize, Option<NewtonStep>)> {
        let work = first.work;
        let scale = self.energy.total().abs().max(self.energy.kinetic).max(f64::MIN_POSITIVE);
        let tol = (1e-10 * scale).max(slack);
        let debt = self.corrections.pending;
        if (work + debt).abs() <= tol {
            // Within the slack: collected with the steady steps' work.
            self.drift += if slack > 0.0 { work + debt } else { 0.0 };
            self.corrections.pending = 0.0;
            return Ok((0, None));
        }
        // M du_0, and m = P M du_0 projected again before each solve at that solve's starting
        // midpoint positions (the moment of the force is taken where the step applies it).
        let mut mdu0 = self.u.duplicate()?;
        self.m.mult(&self.du, &mut mdu0)?;
        let mut m = mdu0.duplicate()?;
        m.copy_from(&mdu0)?;
        self.without_rigid_motions(&mut m)?;
        let q0 = m.dot(&self.du)?;
        let mut forced = f_sum.duplicate()?;
        let mut b = (0.0, work, q0);
        let mut xi = if q0 > 0.0 { (work + debt) / q0 } else { f64::INFINITY };
        let (mut its, mut last, mut total, mut corr_work) = (0, None::<NewtonStep>, work, 0.0);
        let mut solves = 0;
        for k in 0..super::correction::MAX_SOLVES {
            if !xi.is_finite() || xi.abs() * self.tau * self.tau > 0.5 {
                if solves == 0 {
                    self.corrections.skipped += 1;
                }
                break;
            }
            if k > 0 {
                m.copy_from(&mdu0)?;
                self.without_rigid_motions(&mut m)?;
            }
            // The du form is the midpoint equation times 2: the force -2 xi m.
            forced.waxpy(-2.0 * xi, &m, f_sum)?;
            let s =
                self.newton_pass(n, t_next, dofs, du_d, Some(&forced), contact.as_deref_mut())?;
            solves += 1;
            its += s.ksp_iterations;
            self.corrections.extra_solves += 1;
            self.corrections.iterations += s.ksp_iterations;
            let w = s.contact.as_ref().map_or(0.0, |c| c.work);
            let q = m.dot(&self.du)?;
            corr_work = -xi * q;
            total = w + corr_work;
            last = Some(s);
            if (total + debt).abs() <= tol {
                break;
            }
            if k + 1 == super::correction::MAX_SOLVES {
                self.corrections.unconverged += 1;
                break;
            }
            let a = std::mem::replace(&mut b, (xi, w, q));
            match super::correction::model_root(a, b, debt) {
                Some(next) => xi = next,
                None => {
                    self.corrections.unconverged += 1;
                    break;
                }
            }
        }
        self.corrections.pending = debt + total;
        if self.corrections.pending.abs() <= tol {
            self.corrections.pending = 0.0;
        }
        if solves > 0 {
            self.corrections.steps += 1;
            self.corrections.energy += corr_work;
        }
        if let Some(c) = last.as_mut().and_then(|s| s.contact.as_mut()) {
            c.work = total;
        }
        Ok((its, last))
    }
}
