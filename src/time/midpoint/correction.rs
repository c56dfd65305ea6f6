//! The energy correction of contact steps with massless DOFs (`Midpoint::correct_energy`)
//! and its scalar model: the step's energy error as a function of the correction's size `xi`,
//! from two solves.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::Midpoint;
use crate::contact::{ContactSolver, StepContact};
use crate::error::Result;
use crate::petsc::Vector;

/// Solves of a corrected step beyond its first, at most.
pub const MAX_SOLVES: usize = 8;

/// The root of the step's energy error `F(xi) = W(xi) - xi q(xi) + debt` nearest the last
/// sample, where the contact work `W` and `q = m.du` are the lines through two solves' samples
/// `a = (xi_a, W_a, q_a)` and `b = (xi_b, W_b, q_b)`:
///
/// ```text
/// F(xi) = -q' xi^2 + (W' - q_a + xi_a q') xi + (W_a - xi_a W' + debt),
/// W' = (W_b - W_a) / (xi_b - xi_a),   q' = (q_b - q_a) / (xi_b - xi_a)
/// ```
///
/// exact when the solve is affine in `xi` between the samples (a fixed active set). Of the
/// two roots the one nearer `xi_b` (the quadratic term is the correction's `O(xi tau^2)`
/// effect on its own work, small); without a real root, the model's Newton step from `xi_b`.
/// `None` when the samples cannot define a model (equal `xi`, or a flat model).
pub fn model_root(a: (f64, f64, f64), b: (f64, f64, f64), debt: f64) -> Option<f64> {
    let d = b.0 - a.0;
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let (w1, q1) = ((b.1 - a.1) / d, (b.2 - a.2) / d);
    let (qa, qb, qc) = (-q1, w1 - a.2 + a.0 * q1, a.1 - a.0 * w1 + debt);
    let disc = qb * qb - 4.0 * qa * qc;
    let root = if qa != 0.0 && disc >= 0.0 {
        // Both roots without cancellation: the small one 2c / (-b - sgn(b) sqrt(disc)), the
        // other (-b - sgn(b) sqrt(disc)) / 2a.
        let s = -qb - qb.signum() * disc.sqrt();
        let r1 = if s != 0.0 { 2.0 * qc / s } else { f64::NAN };
        let r2 = s / (2.0 * qa);
        if !r1.is_finite() || (r2.is_finite() && (r2 - b.0).abs() < (r1 - b.0).abs()) {
            r2
        } else {
            r1
        }
    } else {
        // Newton on the model from xi_b.
        let f = (qa * b.0 + qb) * b.0 + qc;
        let df = 2.0 * qa * b.0 + qb;
        b.0 - f / df
    };
    root.is_finite().then_some(root)
}

impl Midpoint {
    /// `x -= sum_{b,c} (e_bc.x / e_bc.M1) (M1)_bc` on each body `b` (the groups given to
    /// [`Midpoint::configure_massless`]) and component `c`, with the Dirichlet rows set to
    /// zero first: the correction force `-xi M du` so projected has no resultant on any body
    /// (it exchanges energy with each body's motion relative to its mean translation and
    /// leaves every body's momentum balance, impulse = momentum change, as it was). `M1` is
    /// `M` times ones (the mass per DOF), built once.
    fn without_translations(&mut self, x: &mut Vector) -> Result<()> {
        let lo = self.first_dof;
        let dim = self.dim.max(1);
        if self.m_ones.is_none() {
            let mut ones = self.u.duplicate()?;
            ones.set(1.0)?;
            let mut m1 = self.u.duplicate()?;
            self.m.mult(&ones, &mut m1)?;
            m1.with_local_slice_mut(|v| {
                for &d in self.dirichlet.dofs() {
                    v[d as usize - lo] = 0.0;
                }
            })?;
            self.m_ones = Some(m1);
        }
        let m1 = self.m_ones.as_ref().expect("built above");
        let ng = self.n_groups.max(1);
        let group = |i: usize| self.groups.get(i / dim).map_or(0, |&g| g as usize);
        let mut sums = vec![0.0f64; 2 * ng * dim];
        x.with_local_slice_mut(|v| {
            for &d in self.dirichlet.dofs() {
                v[d as usize - lo] = 0.0;
            }
        })?;
        x.with_local_slice(|v| {
            m1.with_local_slice(|m| {
                for i in 0..v.len() {
                    let k = group(i) * dim + i % dim;
                    sums[k] += v[i];
                    sums[ng * dim + k] += m[i];
                }
            })
        })??;
        let mut all = vec![0.0f64; sums.len()];
        SimpleCommunicator::world().all_reduce_into(
            &sums[..],
            &mut all[..],
            SystemOperation::sum(),
        );
        let ratio: Vec<f64> = (0..ng * dim)
            .map(|k| if all[ng * dim + k] > 0.0 { all[k] / all[ng * dim + k] } else { 0.0 })
            .collect();
        m1.with_local_slice(|m| {
            x.with_local_slice_mut(|v| {
                for i in 0..v.len() {
                    v[i] -= ratio[group(i) * dim + i % dim] * m[i];
                }
            })
        })??;
        Ok(())
    }

    /// The energy correction of a step whose active set changed (a node arrived or left
    /// within it; METHOD.md and README "Impacts that keep their energy"). With the contact
    /// conditions at `t_{n+1}` and the force at the midpoint, an arriving node does the work
    /// `W = -lambda^{n+1/2} g^n <= 0` (it closes the gap `g^n` under the force of the whole
    /// step): O(tau^2) per node and impact, never a gain, but it adds up over repeated
    /// impacts. Like a discrete gradient (Gonzalez 1996) the massive rows then get the force
    /// `-xi m` along `m = P M du0` (`du0` the step's uncorrected increment; `P` takes out the
    /// mean translation per component, [`Midpoint::without_translations`], so the force has
    /// no resultant and the momentum balance, impulse = momentum change, is untouched), with
    /// `xi` such that the step keeps the energy exactly: `F(xi) = W(xi) - xi m.du(xi) + debt
    /// = 0`. At a fixed active set the solve is affine in its right-hand side, so `du(xi)`,
    /// the contact work `W(xi) = -sum lambda_q g_q` and `m.du(xi)` are affine in `xi` and `F`
    /// is a quadratic known from two solves: the uncorrected one and one at `xi_1 = (W_0 +
    /// debt) / m.du0` (what a step that did not respond would need). Its root `xi*` and the
    /// increment `du(xi*)` (interpolated) follow in closed form; one more solve from that
    /// increment, near its solution already, confirms them and gives the contact data.
    /// Should the active set change between solves, the same model through the last two
    /// solves is a secant step (at most [`MAX_SOLVES`] solves). Only losses are put back (a
    /// gain an unsettled correction leaves is taken back by the next steps), so the energy
    /// never exceeds `E^0 + W_loads` beyond the step tolerance (following the bodies, beyond
    /// the work collected while it stays below [`Midpoint::DRIFT_RTOL`]: a remainder within
    /// `slack` joins it instead of another solve). A step whose motion is too small to carry
    /// the correction (`|xi| tau^2 > 1/2`, e.g. a body arriving in pure translation, or tau
    /// far beyond the contact time) hands the work on to the next steps
    /// (`Corrections::pending`), which put it back when they can; so does the energy a
    /// release projection removes. The correction modifies the scheme only in the steps where
    /// the active set changes (and those that take pending work);
    /// `-massless_energy_correction false` turns it off. Returns the extra solves' KSP
    /// iterations, the last contact data and the step's contact work with the correction's.
    pub(super) fn correct_energy<'c>(
        &mut self,
        first: &StepContact,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
        n: usize,
        t_next: f64,
        slack: f64,
    ) -> Result<(usize, Option<StepContact>, f64)> {
        let work = first.work;
        // Blends only on a fixed geometry: one that follows the bodies makes the constrained
        // operator depend on the solution.
        let can_blend = self.blend && !contact.as_deref().is_some_and(|s| s.geometry_follows());
        let scale = self.energy.total().abs().max(self.energy.kinetic).max(f64::MIN_POSITIVE);
        let tol = (1e-10 * scale).max(slack);
        let debt = self.corrections.pending;
        // The contact steps only ever lose energy (`-lambda g^n <= 0`, a gain is solver noise
        // below `tol`); a gain left pending is what an unconverged correction put back too
        // much, and is taken back like a loss is put back.
        if (work + debt).abs() <= tol {
            // Within the slack: collected with the steady steps' work.
            self.drift += if slack > 0.0 { work + debt } else { 0.0 };
            self.corrections.pending = 0.0;
            return Ok((0, None, work));
        }
        if self.rhs_corr.is_none() {
            self.rhs_corr = Some(self.u.duplicate()?);
            self.corr = Some((self.u.duplicate()?, self.u.duplicate()?, self.u.duplicate()?));
        }
        // The direction m = P M du0 (M du without the Dirichlet rows: their increment is
        // prescribed), and du0 kept as the first sample's increment.
        let (mut m, force, mut prev) = self.corr.take().expect("allocated");
        let q0 = (|| -> Result<f64> {
            self.m.mult(&self.du, &mut m)?;
            self.without_translations(&mut m)?;
            prev.copy_from(&self.du)?;
            m.dot(&self.du)
        })();
        self.corr = Some((m, force, prev));
        let q0 = q0?;
        // Samples (xi, W, m.du): `a` the solve before the last (its increment in `prev`), `b`
        // the last (in `du`).
        let (mut a, mut b) = ((0.0, work, q0), (0.0, work, q0));
        // The contact data of the two samples (for a blend instead of the confirming solve).
        let (mut contact_a, mut contact_b) = (first.clone(), first.clone());
        let mut xi = if q0 > 0.0 { (work + debt) / q0 } else { f64::INFINITY };
        let (mut its, mut last, mut total, mut corr_work) = (0, None, work, 0.0);
        for k in 0..MAX_SOLVES {
            // Too large (or not a number: no motion relative to the mean): hand it on.
            if !xi.is_finite() || xi.abs() * self.tau * self.tau > 0.5 {
                if self.corrections_this_step == 0 {
                    self.corrections.skipped += 1;
                }
                break;
            }
            let (m, force, prev) = self.corr.as_mut().expect("allocated");
            let mut blend = None;
            if k > 0 {
                // Start from the model's increment, du_a + t (du_b - du_a); du_b becomes the
                // sample before the last.
                let t = (xi - a.0) / (b.0 - a.0);
                if can_blend {
                    blend = StepContact::blend(&contact_a, &contact_b, t);
                }
                Vector::with_slices([], [&mut self.du, prev], |[], [du, prev]| {
                    for i in 0..du.len() {
                        let d = du[i];
                        du[i] = prev[i] + t * (d - prev[i]);
                        prev[i] = d;
                    }
                })?;
            }
            // The du form is the midpoint equation times 2.
            force.copy_from(m)?;
            force.scale(-2.0 * xi)?;
            // Both samples on one active set: the solve is affine in xi between them, so the
            // interpolated increment is the solution at xi and its contact data the blend of
            // theirs (feasible, or `blend` is None). No confirming solve then: one extra
            // solve a corrected step.
            if let Some(c) = blend {
                let q = m.dot(&self.du)?;
                corr_work = -xi * q;
                total = c.work + corr_work;
                if (total + debt).abs() <= tol {
                    self.corrections.closed_form += 1;
                    last = Some(c);
                    break;
                }
            }
            self.rhs_corr.as_mut().expect("allocated").waxpy(1.0, force, &self.rhs)?;
            let (i, c) = self.solve_system(true, contact.as_deref_mut(), n, t_next)?;
            its += i;
            self.corrections.extra_solves += 1;
            self.corrections.iterations += i;
            self.corrections_this_step += 1;
            let w = c.as_ref().map_or(0.0, |c| c.work);
            let q = self.corr.as_ref().expect("allocated").0.dot(&self.du)?;
            if let Some(c) = &c {
                contact_a = std::mem::replace(&mut contact_b, c.clone());
            }
            // 1/2 force.du, the correction force's work.
            corr_work = -xi * q;
            total = w + corr_work;
            last = c;
            if (total + debt).abs() <= tol {
                break;
            }
            if k + 1 == MAX_SOLVES {
                self.corrections.unconverged += 1;
                break;
            }
            (a, b) = (b, (xi, w, q));
            match model_root(a, b, debt) {
                Some(next) => xi = next,
                None => {
                    self.corrections.unconverged += 1;
                    break;
                }
            }
        }
        // What is left (a step too slow to carry it, or not converged) waits for the next
        // steps.
        self.corrections.pending = debt + total;
        if self.corrections.pending.abs() <= tol {
            self.drift += if slack > 0.0 { self.corrections.pending } else { 0.0 };
            self.corrections.pending = 0.0;
        }
        if self.corrections_this_step > 0 {
            self.corrections.steps += 1;
            self.corrections.energy += corr_work;
            // The reactions at Dirichlet rows see the correction force too.
            if let Some((_, _, full)) = self.lifting.as_mut() {
                full.axpy(1.0, &self.corr.as_ref().expect("allocated").1)?;
            }
        }
        self.corrections_this_step = 0;
        if let Some(c) = last.as_mut() {
            c.work = total;
        }
        Ok((its, last, total))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solve affine in xi: W(xi) = w0 + w1 xi, m.du(xi) = q0 + q1 xi.
    fn sample(xi: f64, (w0, w1, q0, q1): (f64, f64, f64, f64)) -> (f64, f64, f64) {
        (xi, w0 + w1 * xi, q0 + q1 * xi)
    }

    fn residual(xi: f64, (w0, w1, q0, q1): (f64, f64, f64, f64), debt: f64) -> f64 {
        w0 + w1 * xi - xi * (q0 + q1 * xi) + debt
    }

    #[test]
    fn the_root_of_an_affine_response_is_exact() {
        // A loss W0 < 0, a response that lowers m.du (the correction force slows the motion)
        // and changes the contact work a little.
        for &(p, debt) in &[
            ((-1e-6, 2e-4, 0.5, -0.05), 0.0),
            ((-3e-9, -1e-3, 2.0, 0.3), -1e-9),
            ((-1e-6, 0.0, 0.5, 0.0), 2e-7),
        ] {
            let a = sample(0.0, p);
            let xi1 = (p.0 + debt) / p.2;
            let b = sample(xi1, p);
            let xi = model_root(a, b, debt).expect("a root");
            let scale = p.0.abs() + debt.abs();
            assert!(
                residual(xi, p, debt).abs() <= 1e-12 * scale,
                "{p:?}: F = {}",
                residual(xi, p, debt)
            );
            // The root near the first guess, not the far one of the quadratic.
            assert!((xi - xi1).abs() <= 0.2 * xi1.abs(), "{xi} against {xi1}");
        }
    }

    #[test]
    fn samples_that_cannot_define_a_model_give_none() {
        let a = (1.0, -1e-6, 0.5);
        assert_eq!(model_root(a, a, 0.0), None);
        // A flat model (F constant and nonzero) has no root.
        assert_eq!(model_root((0.0, -1e-6, 0.0), (1.0, -1e-6, 0.0), 0.0), None);
    }

    #[test]
    fn without_a_real_root_the_newton_step_lowers_the_model() {
        // F(xi) = -1 + 2 xi - 2 xi^2 (q' = 2): no real root; the vertex lies at xi = 0.5.
        let p = (-1.0, 0.0, -2.0, 2.0);
        let (a, b) = (sample(0.0, p), sample(1.0, p));
        let xi = model_root(a, b, 0.0).expect("a step");
        assert!(residual(xi, p, 0.0).abs() < residual(1.0, p, 0.0).abs());
    }
}
