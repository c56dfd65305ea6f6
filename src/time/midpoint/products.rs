//! The step's kept products: with the step's own CG (`time::cg`) a step without
//! contact updates `A u` and `M v` from `K du` and one product `M du` instead of recomputing
//! them, and every `StepOperator::refresh` steps computes them afresh and measures the drift.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::Midpoint;
use crate::error::Result;
use crate::petsc::Vector;

/// What keeping the step's products did (the step's own CG, `time::cg`): `A u` and `M v` are
/// updated as `A u += K du - 4/tau^2 M du`, `M v = 2/tau M du - M v`, and every
/// `StepOperator::refresh` steps computed afresh, where the updated ones are compared with
/// them.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ReuseReport {
    /// Steps solved by the step's own CG.
    pub steps: usize,
    /// Products with `K` of those solves (iterations, and `K x_0` where it was not known).
    pub products: usize,
    /// Steps where the products were computed afresh.
    pub refreshes: usize,
    /// The largest difference between updated and recomputed `M v` relative to the largest
    /// entry of `M v`, and of `A u` (free rows) relative to the largest entry of the step's
    /// right-hand side (where `A u` enters), over the refreshes.
    pub drift_au: f64,
    pub drift_mv: f64,
    /// The largest difference of the potential and kinetic energies, relative to the energy.
    pub drift_energy: f64,
    /// Steps between refreshes (`-step_reuse_refresh`, [`Midpoint::DRIFT_TARGET`]).
    #[serde(default)]
    pub interval: usize,
    /// Steps since the last refresh.
    #[serde(skip)]
    pub since_refresh: usize,
    /// Rows of the mass-free layer's block the step's preconditioner solves exactly or by
    /// ICC (`time::layer`; 0: none).
    #[serde(default)]
    pub layer_rows: usize,
}

impl Midpoint {
    /// The kept products' energies may drift from the recomputed ones by this much of the
    /// energy before a refresh puts them right: an order below the tightest energy balance
    /// the tests ask (1e-9 over 1000 steps). The drift is round-off in `K du - 4/tau^2 M du`,
    /// about `eps / (omega tau)` of the energy a step, summed over the steps between
    /// refreshes: measured on the beam (tau = 1e-5) 2e-12 to 2e-11 after 16-30 steps, 1e-10
    /// to 4e-10 after 64-100, varying from interval to interval; hence the default interval
    /// of 16 steps (`-step_reuse_refresh`).
    pub const DRIFT_TARGET: f64 = 1e-10;

    /// `u += du`, `v = 2 du/tau - v` and the products `M v`, `A u` and energies updated from
    /// `K du` (the step's own CG kept it) and one product `M du`:
    ///
    /// ```text
    ///   M v^{n+1} = 2/tau M du - M v^n,   A u^{n+1} = A u^n + K du - 4/tau^2 M du,
    /// ```
    /// in one pass with the energies' sums. `K` has the Dirichlet rows and columns eliminated,
    /// so `K du` is `(4/tau^2 M + A) du` on the free rows when `du_D = 0` (no lifting): the
    /// Dirichlet rows of `A u` are not updated (their `u` is zero, they enter neither the
    /// energy nor the right-hand side). At a refresh step the products are computed afresh
    /// and the updated ones compared with them ([`ReuseReport`]).
    pub(super) fn advance_with_products(&mut self) -> Result<()> {
        let tau = self.tau;
        let c = 4.0 / (tau * tau);
        self.m.mult(&self.du, &mut self.mdu)?;
        let lo = self.first_dof;
        let dofs = self.dirichlet.dofs();
        let kx = self.op.cg.as_ref().expect("the step's own CG").kx();
        let local = Vector::with_slices(
            [&self.du, kx, &self.mdu],
            [&mut self.u, &mut self.v, &mut self.mv, &mut self.au],
            |[du, kx, mdu], [u, v, mv, au]| {
                let (mut ke, mut pe) = (0.0, 0.0);
                for i in 0..u.len() {
                    u[i] += du[i];
                    v[i] = 2.0 / tau * du[i] - v[i];
                    mv[i] = 2.0 / tau * mdu[i] - mv[i];
                    au[i] += kx[i] - c * mdu[i];
                    ke += v[i] * mv[i];
                    pe += u[i] * au[i];
                }
                for &d in dofs {
                    let i = d as usize - lo;
                    au[i] -= kx[i] - c * mdu[i];
                }
                [ke, pe]
            },
        )?;
        let mut sums = [0.0; 2];
        SimpleCommunicator::world().all_reduce_into(
            &local[..],
            &mut sums[..],
            SystemOperation::sum(),
        );
        let (kinetic, potential) = (0.5 * sums[0], 0.5 * sums[1]);
        if !self.fresh_step {
            self.energy.kinetic = kinetic;
            self.energy.potential = potential;
            self.reuse.since_refresh += 1;
            return Ok(());
        }
        // Afresh, and how far the updated products had drifted (M du and the right-hand side,
        // done with, hold the updated ones). A u enters the step through the right-hand side
        // (and the energy): its drift is measured against the right-hand side's scale.
        let rhs_scale = self.rhs.norm_inf()?.max(f64::MIN_POSITIVE);
        self.mdu.copy_from(&self.mv)?;
        self.rhs.copy_from(&self.au)?;
        self.update_energies()?;
        self.mdu.axpy(-1.0, &self.mv)?;
        self.rhs.axpy(-1.0, &self.au)?;
        let dofs = self.dirichlet.dofs();
        self.rhs.with_local_slice_mut(|x| {
            for &d in dofs {
                x[d as usize - lo] = 0.0;
            }
        })?;
        let drift = [
            self.mdu.norm_inf()? / self.mv.norm_inf()?.max(f64::MIN_POSITIVE),
            self.rhs.norm_inf()? / rhs_scale,
        ];
        let scale = (self.energy.kinetic + self.energy.potential).max(f64::MIN_POSITIVE);
        let e =
            (kinetic - self.energy.kinetic).abs().max((potential - self.energy.potential).abs())
                / scale;
        self.reuse.drift_mv = self.reuse.drift_mv.max(drift[0]);
        self.reuse.drift_au = self.reuse.drift_au.max(drift[1]);
        self.reuse.drift_energy = self.reuse.drift_energy.max(e);
        self.reuse.refreshes += 1;
        self.reuse.since_refresh = 0;
        Ok(())
    }

    /// What keeping the step's products did so far.
    pub fn reuse(&self) -> ReuseReport {
        let own = self.op.cg.as_ref().map_or(0, |cg| cg.layer_rows());
        let around = self.op.layer.as_ref().and_then(|i| i.borrow().as_ref().map(|l| l.0));
        let layer_rows = own.max(around.unwrap_or(0));
        ReuseReport { layer_rows, ..self.reuse }
    }

    /// The loads' work of the step, `f^{n+1/2}.du` (`f^{n+1/2} = f_now` for steady loads).
    pub(super) fn load_work(&self, varying: bool) -> Result<f64> {
        let local = if varying {
            Vector::with_slices([&self.f_now, &self.f_next, &self.du], [], |[f0, f1, du], []| {
                0.5 * f0.iter().zip(f1).zip(du).map(|((a, b), d)| (a + b) * d).sum::<f64>()
            })?
        } else {
            Vector::with_slices([&self.f_now, &self.du], [], |[f, du], []| {
                f.iter().zip(du).map(|(a, d)| a * d).sum::<f64>()
            })?
        };
        let mut sum = 0.0;
        SimpleCommunicator::world().all_reduce_into(&local, &mut sum, SystemOperation::sum());
        Ok(sum)
    }
}
