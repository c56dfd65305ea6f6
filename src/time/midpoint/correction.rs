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
use crate::time::layer::LayerBlock;

/// Solves of a corrected step beyond its first, at most.
pub const MAX_SOLVES: usize = 8;

/// The largest kick `|xi|` ([`Midpoint::kick`]): a larger one would change the step's
/// motion relative to the mean by more than a quarter (the solves' form hands on at the
/// same size of response, `|xi| tau^2 > 1/2`); the work is handed on then.
pub const MAX_KICK: f64 = 0.25;

/// Iterations of CG with Jacobi that smooth the kick's direction towards the response to the
/// force `P M du` ([`Midpoint::kick`]).
pub const KICK_ITERATIONS: usize = 4;

/// What [`Midpoint::kick`] did.
pub(super) enum Kick {
    /// Settled: the step's contact data (gaps of the moved nodes), its work with the
    /// correction's, and the KSP iterations that smoothed the direction.
    Done(Box<StepContact>, f64, usize),
    /// The step cannot carry it (no motion relative to the mean, or too small a one); the
    /// smoothing's KSP iterations.
    HandOn(usize),
    /// Not applicable here (the solver's form, friction, a moving Dirichlet boundary, an
    /// inactive node the kick would push into the obstacle): the correction's solves.
    Solve,
}

/// The kick `xi` whose work `alpha xi^2 - beta xi` equals `target`, the root of smaller size
/// (`target` small: `-target / beta`); without a real root (a gain to take back larger than
/// the kick can), the vertex `beta / (2 alpha)`, which takes back the most. `None` for
/// `alpha <= 0` (no motion to kick) or a root that is not a number.
pub fn kick_size(alpha: f64, beta: f64, target: f64) -> Option<f64> {
    if alpha <= 0.0 || !alpha.is_finite() || !beta.is_finite() {
        return None;
    }
    let disc = beta * beta + 4.0 * alpha * target;
    let xi = if disc < 0.0 {
        beta / (2.0 * alpha)
    } else {
        let s = beta + beta.signum() * disc.sqrt();
        if s == 0.0 {
            return None;
        }
        -2.0 * target / s
    };
    xi.is_finite().then_some(xi)
}

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
    pub(super) fn without_translations(&mut self, x: &mut Vector) -> Result<()> {
        self.remove_translations(x, false)
    }

    /// `x -= sum_{b,c} (e_bc.M x / e_bc.M1) e_bc` on each body and component, the Dirichlet
    /// rows zero before and after: the displacement `x` so changed has no mean translation,
    /// `1_b^T M x = 0` (`M` symmetric: `1^T M x = (M1).x`). Collective.
    fn without_mean_translations(&mut self, x: &mut Vector) -> Result<()> {
        self.remove_translations(x, true)?;
        let lo = self.first_dof;
        x.with_local_slice_mut(|v| {
            for &d in self.dirichlet.dofs() {
                v[d as usize - lo] = 0.0;
            }
        })
    }

    /// [`Midpoint::without_translations`] (`displacement` false: `x` a force) or
    /// [`Midpoint::without_mean_translations`] (true).
    fn remove_translations(&mut self, x: &mut Vector, displacement: bool) -> Result<()> {
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
                    sums[k] += if displacement { m[i] * v[i] } else { v[i] };
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
                    let r = ratio[group(i) * dim + i % dim];
                    v[i] -= if displacement { r } else { r * m[i] };
                }
            })
        })??;
        Ok(())
    }

    /// The energy correction of a step whose active set changed (a node arrived or left
    /// within it). Where the contact solver allows it the step is settled without a solve
    /// ([`Midpoint::kick`]); otherwise by the solves below, which are the correction's
    /// general form (pairs, friction, a geometry that follows the bodies, a moving Dirichlet
    /// boundary, or a kick that would push an inactive node into an obstacle; docs/method.md,
    /// impacts and the energy correction).
    ///
    /// With the contact
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
    #[allow(clippy::too_many_arguments)]
    pub(super) fn correct_energy<'c>(
        &mut self,
        first: &StepContact,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
        n: usize,
        t_next: f64,
        slack: f64,
        loads: (bool, bool),
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
        if let Some(solver) = contact.as_deref() {
            match self.kick(first, solver, -(work + debt), loads)? {
                Kick::Done(c, total, its) => {
                    let c = *c;
                    self.corrections.steps += 1;
                    self.corrections.iterations += its;
                    self.corrections.kicked += 1;
                    self.corrections.energy += total - work;
                    self.corrections.pending = debt + total;
                    if self.corrections.pending.abs() <= tol {
                        self.corrections.pending = 0.0;
                    }
                    return Ok((its, Some(c), total));
                }
                Kick::HandOn(its) => {
                    self.corrections.skipped += 1;
                    self.corrections.iterations += its;
                    self.corrections.pending = debt + work;
                    return Ok((its, None, work));
                }
                Kick::Solve => {}
            }
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

impl Midpoint {
    /// The energy correction without a solve: the step's increment is moved along
    /// `w`, `du <- du - xi w`, where `w` is the step's increment on the massive DOFs without
    /// each body's mean translation ([`Midpoint::without_mean_translations`]) and, on the
    /// massless layer, its static response in the constrained operator of the step's final
    /// active set, `w_C = -K~_CC^{-1} K~_CA w_A` ([`LayerBlock::static_response`], an exact
    /// factorization of the surface-sized block). The moved increment solves the step with
    /// the extra force `-xi K~ w`, which is zero on the layer's free rows (the massless nodes
    /// stay in equilibrium: no period-2 mode) and on the active nodes' normals keeps `n . w =
    /// 0` (their gaps and contact forces stay), and has no resultant on a free body (`1^T M w
    /// = 0`, `A 1 = 0`): contact at `t_{n+1}` and every body's momentum balance are kept. Its
    /// work is exact in closed form: with `u1 = u^n + du`, `v1 = 2 du / tau - v^n`, the
    /// energy at `t_{n+1}` changes by
    ///
    /// ```text
    ///   E(xi) - E(0) = alpha xi^2 - (beta + f.w) xi,
    ///   alpha = 2/tau^2 w.M w + 1/2 w.A w,   beta = 2/tau w.M v1 + w.A u1 - f.w,
    /// ```
    /// (`f = f^{n+1/2}`: the loads' work changes by `-xi f.w`), so `xi` solves `alpha xi^2 -
    /// beta xi = target` ([`kick_size`]). Only where the contact solver's operator is that
    /// `K~` ([`ContactSolver::constrained_operator`]: rigid obstacles, no friction, a fixed
    /// geometry), every contact DOF is massless, and without a moving Dirichlet boundary; an
    /// inactive node the kick would push into an obstacle falls back to the solves.
    /// Collective.
    pub(super) fn kick(
        &mut self,
        first: &StepContact,
        solver: &dyn ContactSolver,
        target: f64,
        (loads, varying): (bool, bool),
    ) -> Result<Kick> {
        let plain = first.row.tangential.is_empty()
            && first.contact_nodal.is_empty()
            && first.friction_nodal.is_empty();
        if !self.kick
            || !solver.constrained_operator()
            || solver.is_pair()
            || solver.geometry_follows()
            || !plain
            || self.lifting.is_some()
            || !self.kick_ready(solver)?
        {
            return Ok(Kick::Solve);
        }
        let (dim, tau) = (self.dim.max(1), self.tau);
        // The layer block of K~, factored again when the active set or a normal changed.
        let key: Vec<(bool, [f64; 3])> = first
            .row
            .active
            .iter()
            .enumerate()
            .map(|(q, &a)| (a, if a { first.normals[q] } else { [0.0; 3] }))
            .collect();
        match self.kick_layer.as_mut() {
            Some((Some(block), old)) if *old != key => {
                block.factor(&self.op.k, None)?;
                *old = key;
            }
            Some(_) => {}
            None => {
                let rows: Vec<usize> =
                    self.massless()?.iter().enumerate().filter(|m| *m.1).map(|m| m.0).collect();
                let block = LayerBlock::with_solver(
                    &self.op.k,
                    rows,
                    None,
                    "massless_kick_",
                    "cholesky",
                    // Refactored at every corrected step: quotient minimum degree took half
                    // the time of nested dissection on the ball's 1335 rows (3 ms against 6).
                    "qmd",
                )?;
                self.kick_layer = Some((block, key));
            }
        }
        let mut layer = self.kick_layer.take();
        let Some((Some(block), _)) = layer.as_mut() else {
            self.kick_layer = layer;
            return Ok(Kick::Solve);
        };
        if self.kick_vectors.is_none() {
            self.kick_vectors =
                Some((self.u.duplicate()?, self.u.duplicate()?, self.u.duplicate()?));
        }
        let (mut w, mut mw, mut aw) = self.kick_vectors.take().expect("allocated");
        let mut smoothing_its = 0;
        let sizes = (|| -> Result<(f64, f64, Vec<f64>)> {
            // w: the massive increment without its mean translation, smoothed towards the
            // response to the force P M du, the layer's static response on the massless rows.
            w.copy_from(&self.du)?;
            self.without_mean_translations(&mut w)?;
            // A few iterations of CG with Jacobi towards the response to the force
            // P M du (the direction the solves' correction puts the energy back along), from
            // w: they take the stiff modes out of w, which the midpoint rule would carry on
            // as a period-2 oscillation at CFL > 1 (w = P du unsmoothed doubled the disc's
            // osc2 at hc = 0.025, tau = 2e-6: 4.6e-3 against the solves' 2.6e-3; Jacobi
            // sweeps did not remove it, 4 iterations of the disc's CG + Jacobi do: 2.5e-3).
            if KICK_ITERATIONS > 0 {
                self.m.mult(&self.du, &mut mw)?;
                self.without_translations(&mut mw)?;
                mw.scale(4.0 / (tau * tau))?;
                smoothing_its = self.jacobi_cg(&mw, &mut w, &mut aw, KICK_ITERATIONS)?;
                self.without_mean_translations(&mut w)?;
            }
            block.static_response(&mut w)?;
            // The layer's rows of the kick's force, K~ w, against the massive rows' (a check
            // of the static response with the operator itself: zero up to round-off).
            self.op.k.mult(&w, &mut aw)?;
            let massless = &self.massless.as_ref().expect("found").0;
            let mut big = [0.0f64; 2];
            aw.with_local_slice(|kw| {
                for (x, &c) in kw.iter().zip(massless) {
                    let k = usize::from(!c);
                    big[k] = big[k].max(x.abs());
                }
            })?;
            let mut all_big = [0.0f64; 2];
            SimpleCommunicator::world().all_reduce_into(
                &big[..],
                &mut all_big[..],
                SystemOperation::max(),
            );
            if all_big[1] > 0.0 {
                let r = all_big[0] / all_big[1];
                self.corrections.kick_residual = self.corrections.kick_residual.max(r);
            }
            self.m.mult(&w, &mut mw)?;
            self.a.mult(&w, &mut aw)?;
            let mut local = [0.0f64; 4];
            Vector::with_slices(
                [&w, &mw, &aw, &self.du, &self.u, &self.v],
                [],
                |[w, mw, aw, du, u, v], []| {
                    for i in 0..w.len() {
                        local[0] += mw[i] * w[i];
                        local[1] += aw[i] * w[i];
                        local[2] += mw[i] * (2.0 * du[i] / tau - v[i]);
                        local[3] += aw[i] * (u[i] + du[i]);
                    }
                },
            )?;
            // f^{n+1/2}.w (f_now stands for both ends of the step when the loads are constant).
            let f_w = match (loads, varying) {
                (false, _) => 0.0,
                (true, false) => self.f_now.dot(&w)?,
                (true, true) => 0.5 * (self.f_now.dot(&w)? + self.f_next.dot(&w)?),
            };
            let mut all = [0.0f64; 4];
            SimpleCommunicator::world().all_reduce_into(
                &local[..],
                &mut all[..],
                SystemOperation::sum(),
            );
            let alpha = 2.0 / (tau * tau) * all[0] + 0.5 * all[1];
            let beta = 2.0 / tau * all[2] + all[3] - f_w;
            // The contact nodes' normal motion under the kick (inactive nodes' gaps).
            let trace = solver.nodes().trace(&w)?;
            let normal: Vec<f64> = (0..first.normals.len())
                .map(|q| (0..dim).map(|c| first.normals[q][c] * trace[q * dim + c]).sum())
                .collect();
            Ok((alpha, beta, normal))
        })();
        let result = match sizes {
            Err(e) => Err(e),
            Ok((alpha, beta, normal)) => match kick_size(alpha, beta, target) {
                Some(xi) if xi.abs() <= MAX_KICK => {
                    let gap_tol = solver.nodes().gap_tol;
                    let mut c = first.clone();
                    for (q, g) in c.row.gap.iter_mut().enumerate() {
                        *g += xi * normal[q];
                    }
                    let feasible =
                        c.row.gap.iter().zip(&c.row.active).all(|(&g, &a)| a || g >= -gap_tol);
                    if feasible {
                        self.du.axpy(-xi, &w)?;
                        let work = alpha * xi * xi - beta * xi;
                        c.work = first.work + work;
                        let total = c.work;
                        Ok(Kick::Done(Box::new(c), total, smoothing_its))
                    } else {
                        Ok(Kick::Solve)
                    }
                }
                _ => Ok(Kick::HandOn(smoothing_its)),
            },
        };
        self.kick_vectors = Some((w, mw, aw));
        self.kick_layer = layer;
        result
    }

    /// At most `n` iterations of CG with Jacobi on the step operator (the constrained `K~`
    /// of the last solve) for `K~ x = b` from `x`; `d` is a work vector. Jacobi, not the step
    /// solver's preconditioner: a capped solve keeps the preconditioner's error, and block
    /// Jacobi/ILU with one block per rank would make the kick depend on the number of
    /// ranks. Returns the iterations done. Collective.
    fn jacobi_cg(&mut self, b: &Vector, x: &mut Vector, d: &mut Vector, n: usize) -> Result<usize> {
        if self.kick_cg.is_none() {
            self.kick_cg = Some((self.u.duplicate()?, self.u.duplicate()?, self.u.duplicate()?));
        }
        let (mut r, mut p, mut q) = self.kick_cg.take().expect("allocated");
        let result = (|| -> Result<usize> {
            let k = &self.op.k;
            k.get_diagonal(d)?;
            d.with_local_slice_mut(|d| {
                for x in d.iter_mut() {
                    *x = if *x != 0.0 { 1.0 / *x } else { 0.0 };
                }
            })?;
            // r = b - K x, p = z = D^{-1} r.
            k.mult(x, &mut r)?;
            r.aypx(-1.0, b)?;
            p.pointwise_mult(&r, d)?;
            let mut rz = r.dot(&p)?;
            let mut done = 0;
            for _ in 0..n {
                if rz <= 0.0 || !rz.is_finite() {
                    break;
                }
                k.mult(&p, &mut q)?;
                let pq = p.dot(&q)?;
                if pq <= 0.0 || !pq.is_finite() {
                    break;
                }
                let alpha = rz / pq;
                x.axpy(alpha, &p)?;
                r.axpy(-alpha, &q)?;
                done += 1;
                // z = D^{-1} r into q (free now), p = z + beta p.
                q.pointwise_mult(&r, d)?;
                let rz_new = r.dot(&q)?;
                p.aypx(rz_new / rz, &q)?;
                rz = rz_new;
            }
            Ok(done)
        })();
        self.kick_cg = Some((r, p, q));
        result
    }

    /// Whether every contact DOF is massless or Dirichlet (found once; collective).
    fn kick_ready(&mut self, solver: &dyn ContactSolver) -> Result<bool> {
        if let Some(ready) = self.kick_ready {
            return Ok(ready);
        }
        let lo = self.first_dof;
        let fixed: std::collections::HashSet<i32> = self.dirichlet.dofs().iter().copied().collect();
        let massless = self.massless()?.to_vec();
        let massive = solver
            .nodes()
            .dofs
            .iter()
            .filter(|&&(g, own)| own && !fixed.contains(&g) && !massless[g as usize - lo])
            .count() as f64;
        let mut all = 0.0;
        SimpleCommunicator::world().all_reduce_into(&massive, &mut all, SystemOperation::sum());
        self.kick_ready = Some(all == 0.0);
        Ok(all == 0.0)
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
    fn the_kick_puts_back_its_target_with_the_smaller_root() {
        // alpha xi^2 - beta xi = target: a loss to put back (target > 0) for either sign of
        // beta, a gain to take back (target < 0) within reach, a tiny target (no
        // cancellation).
        for &(alpha, beta, target) in &[
            (3.0, 2.0, 1e-3),
            (3.0, -2.0, 1e-3),
            (0.5, 1.0, -0.1),
            (2.0, 1e-3, 1e-14),
            (1e6, -40.0, 2e-9),
        ] {
            let xi = kick_size(alpha, beta, target).expect("a root");
            let work = alpha * xi * xi - beta * xi;
            assert!((work - target).abs() <= 1e-12 * target.abs(), "{work} against {target}");
            // The other root, target / (alpha xi) with opposite sign, is the larger.
            let other = -target / (alpha * xi);
            assert!(xi.abs() <= other.abs(), "{xi} is the larger root ({other})");
        }
        // No real root: the vertex, where the work is least.
        let xi = kick_size(1.0, 1.0, -1.0).expect("the vertex");
        assert!((xi - 0.5).abs() < 1e-15);
        assert_eq!(kick_size(0.0, 1.0, 1.0), None, "nothing to kick");
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
