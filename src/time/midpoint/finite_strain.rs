//! The midpoint step of finite-strain bodies (`time::newton`): the integrator's state, loads,
//! Dirichlet increments and energy accounting around one Newton loop.

use super::{Midpoint, StepReport};
use crate::contact::ContactSolver;
use crate::error::Result;
use crate::time::newton::{Newton, StepInputs};
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

    /// One step `n -> n + 1` of the energy-momentum midpoint rule, with the contact solver
    /// inside each Newton iteration when there is one.
    pub(super) fn step_finite_strain<'c>(
        &mut self,
        n: usize,
        forces: &dyn Forces,
        contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<StepReport> {
        let tau = self.tau;
        let t_next = self.time_at(n + 1);
        let (loads, varying) = (forces.present(), forces.time_dependent());
        if loads && varying {
            forces.assemble(t_next, &mut self.f_next)?;
        }
        // f_0 + f_1 (the step's rhs vector is free here).
        if loads {
            self.rhs.waxpy(1.0, &self.f_now, if varying { &self.f_next } else { &self.f_now })?;
        }
        let lo = self.first_dof;
        let dofs = self.dirichlet.dofs().to_vec();
        let mut du_d = vec![0.0; dofs.len()];
        self.u.with_local_slice(|x| {
            for (i, &dof) in dofs.iter().enumerate() {
                du_d[i] = self.dirichlet.value(i, t_next) - x[dof as usize - lo];
            }
        })?;
        // The first guess: the motion at constant velocity.
        self.du.copy_from(&self.v)?;
        self.du.scale(tau)?;
        let energy = self.energy.kinetic + self.energy.potential;
        let newton = self.newton.as_mut().expect("finite strain");
        let step = newton.step(
            StepInputs {
                m: &self.m,
                k: &mut self.op.k,
                ksp: &mut self.op.ksp,
                dirichlet: &dofs,
                dirichlet_du: &du_d,
                dirichlet_diag: self.op.dirichlet_diag,
                u: &self.u,
                mv: &self.mv,
                f_sum: loads.then_some(&self.rhs),
                du: &mut self.du,
                tau,
                energy,
                step: n + 1,
                time: t_next,
            },
            contact,
        )?;
        self.ksp_iterations += step.ksp_iterations;
        if loads {
            self.energy.external_work += self.load_work(varying)?;
        }
        self.energy.dirichlet_work += step.dirichlet_work;
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
        Ok(StepReport {
            time: t_next,
            ksp_iterations: step.ksp_iterations,
            newton_iterations: step.iterations,
            contact: step.contact,
        })
    }
}
