//! The implicit midpoint rule as an integrator: it owns the step operator, the state
//! `(u^n, v^n)` with the products `M v^n`, `A u^n`, the Dirichlet lifting and the energy and
//! work accounting, and advances one step at a time: `step(forces, contact) -> StepReport`.
//!
//! One step (docs/method.md, the midpoint rule, paper (6.1)):
//!
//! ```text
//!   K du = 2 f^{n+1/2} + (4/tau) M v^n - 2 A u^n  [- 2 B^T lambda],   K = 4/tau^2 M + A,
//!   u^{n+1} = u^n + du,   v^{n+1} = 2 du/tau - v^n,
//! ```
//! with `du_D = g(t_{n+1}) - u^n_D` on Dirichlet DOFs. The energy `E^n = 1/2 v.Mv + 1/2 u.Au`
//! obeys `E^{n+1} - E^n = f^{n+1/2}.du - lambda.B du + r_D.du_D` exactly (the three works are
//! accumulated in [`Energy`]), which the run checks at every step.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

mod correction;
mod finite_strain;
mod layer_velocity;
mod products;
mod rigid;

pub use products::ReuseReport;

use super::cg::Predictor;
use super::dirichlet::Dirichlet;
use super::operator::StepOperator;
use crate::contact::{ContactSolver, StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::mass::MassMatrix;
use crate::petsc::{Matrix, Vector};

/// The external forces `f(t)` (body forces and tractions, assembled).
pub trait Forces {
    /// Whether there are any: without, nothing is assembled or added.
    fn present(&self) -> bool;
    /// Whether they change in time: if not, `f` is assembled once.
    fn time_dependent(&self) -> bool;
    /// `out = f(t)`.
    fn assemble(&self, t: f64, out: &mut Vector) -> Result<()>;
}

/// No external forces.
pub struct NoForces;

impl Forces for NoForces {
    fn present(&self) -> bool {
        false
    }
    fn time_dependent(&self) -> bool {
        false
    }
    fn assemble(&self, _t: f64, _out: &mut Vector) -> Result<()> {
        Ok(())
    }
}

pub use crate::rows::Energy;

/// What one step did.
pub struct StepReport {
    /// The time the step reached, `t_{n+1}`.
    pub time: f64,
    /// KSP iterations of the step's solves.
    pub ksp_iterations: usize,
    /// Newton iterations of the step (finite strain; 0 for the linear step).
    pub newton_iterations: usize,
    /// The contact solver's result (scenes with contact).
    pub contact: Option<StepContact>,
}

/// The implicit midpoint rule for `M u'' + A u = f` with Dirichlet data and contact.
pub struct Midpoint {
    tau: f64,
    op: StepOperator,
    m: MassMatrix,
    a: Matrix,
    dirichlet: Dirichlet,
    first_dof: usize,
    u: Vector,
    v: Vector,
    du: Vector,
    /// The first guess of a contact step's solve ([`Midpoint::set_contact_predictor`]) and
    /// the increment of the step before, for the extrapolation.
    contact_predictor: Predictor,
    du_last: Option<(Vector, usize)>,
    mv: Vector,
    au: Vector,
    rhs: Vector,
    f_now: Vector,
    f_next: Vector,
    /// For non-zero Dirichlet values: `(du_D padded, K du_D, rhs before its rows are replaced)`.
    lifting: Option<(Vector, Vector, Vector)>,
    energy: Energy,
    ksp_iterations: usize,
    /// This rank's massless DOFs and whether any rank has some (found on first use).
    massless: Option<(Vec<bool>, bool)>,
    /// Steps after which released massless contact nodes were put back in static equilibrium,
    /// and the energy that removed (<= 0, counted as contact work).
    release_projections: usize,
    release_energy: f64,
    /// `M du` (the step's own CG: `A u` and `M v` are updated from it and `K du`).
    mdu: Vector,
    /// What the kept products did ([`ReuseReport`]).
    reuse: ReuseReport,
    /// This step computes its products afresh.
    fresh_step: bool,
    /// `u` before the last consistent initialization (to take it back).
    before_projection: Option<Vector>,
    /// Steps whose contact work the energy correction took back, its extra solves, and the
    /// energy it put back (the negative of the contact work it cancelled).
    corrections: Corrections,
    /// Solves of the current step's correction so far.
    corrections_this_step: usize,
    /// Contact work of steps whose active set stayed while the geometry follows the bodies
    /// (the midpoint rule's error on the moving geometry), collected until it exceeds
    /// [`Midpoint::DRIFT_RTOL`] of the energy and then put back like an activation's.
    drift: f64,
    /// The bound of `drift` as a fraction of the energy ([`Midpoint::DRIFT_RTOL`] unless
    /// `-massless_drift_rtol` says otherwise).
    drift_rtol: f64,
    /// Settle a corrected step from two solves on one active set without a confirming solve
    /// (`-massless_correction_blend`).
    blend: bool,
    /// Settle a corrected step without a solve where the contact solver allows it
    /// (`-massless_correction_kick`, [`Midpoint::kick`]).
    kick: bool,
    /// The kick's state: whether every contact DOF is massless or Dirichlet (found once),
    /// the layer block of the constrained operator and the active set and normals it was
    /// factored for, and its work vectors `(w, M w, A w)`.
    kick_layer: Option<KickLayer>,
    kick_ready: Option<bool>,
    kick_vectors: Option<(Vector, Vector, Vector)>,
    kick_cg: Option<(Vector, Vector, Vector)>,
    /// `A_CC` of the whole layer for the projection of released nodes (built on first use).
    release_layer: Option<super::layer::LayerBlock>,
    /// Whether the energy of steps whose active set changed is corrected.
    correct: bool,
    /// The energy correction's right-hand side and work vectors `(P M du0, -2 xi P M du0,
    /// the increment of the solve before the last)`.
    rhs_corr: Option<Vector>,
    corr: Option<(Vector, Vector, Vector)>,
    /// Components per node (the correction works per component).
    dim: usize,
    /// The Newton loop of finite-strain bodies (`None`: the linear step), and its step's
    /// loads `f_0 + f_1` (kept between steps).
    newton: Option<Box<super::newton::Newton>>,
    f_sum: Option<Vector>,
    /// Finite strain: the increment before the last (for the first guess), and the number of
    /// increments made since the start or a restart.
    du_prev: Option<Vector>,
    increments: usize,
    /// Finite strain: steps left that start from rest (`du = 0`) after a step needed its
    /// restart from there ([`Midpoint::step_finite_strain`]).
    rest_guesses: usize,
    /// `M 1` without the Dirichlet rows (built on first use).
    m_ones: Option<Vector>,
    /// The body of each owned node (in DOF order): the correction keeps each body's momentum.
    groups: Vec<u32>,
    /// The number of bodies over all ranks.
    n_groups: usize,
    /// Finite strain: the reference position of each owned DOF (the correction's force then
    /// has no moment either).
    reference: Option<Vec<f64>>,
    /// The mass-free layer's velocity (the derivative of its static response).
    layer_rate: layer_velocity::LayerRate,
}

/// The kick's layer block of the constrained operator (none without massless rows) and the
/// active set and normals it was factored for.
type KickLayer = (Option<super::layer::LayerBlock>, Vec<(bool, [f64; 3])>);

/// What the energy correction of contact steps did ([`Midpoint::configure_massless`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Corrections {
    /// Whether the run corrects (`-massless_energy_correction`, on by default with massless
    /// DOFs).
    #[serde(default)]
    pub enabled: bool,
    /// Steps that were corrected.
    pub steps: usize,
    /// Solves beyond each corrected step's first.
    pub extra_solves: usize,
    /// KSP iterations of those solves (the second of a step starts at its solution and
    /// mostly takes none).
    #[serde(default)]
    pub iterations: usize,
    /// Steps whose motion was too small to carry the correction (their work was handed on).
    pub skipped: usize,
    /// The energy the correction put back (sum of `-xi m.du`, `m = P M du0`).
    pub energy: f64,
    /// Contact work not yet taken back: of steps too slow to carry the correction, handed on
    /// to the next steps (they are corrected until it is gone).
    #[serde(default)]
    pub pending: f64,
    /// Corrected steps whose correction did not settle in the solves allowed (the rest is
    /// pending).
    #[serde(default)]
    pub unconverged: usize,
    /// Corrected steps settled without the confirming solve: both solves on one active set,
    /// the increment and the contact data interpolated at the model's root.
    #[serde(default)]
    pub closed_form: usize,
    /// Corrected steps settled without a solve of the step ([`Midpoint::kick`]; the
    /// iterations that smooth its direction are counted in `iterations`).
    #[serde(default)]
    pub kicked: usize,
    /// The largest force a kick left on the massless rows (and the active normals) relative
    /// to its largest on the massive rows, `max |(K~ w)_C| / max |(K~ w)_I|`: zero up to
    /// round-off when the layer's static response is right.
    #[serde(default)]
    pub kick_residual: f64,
}

impl Midpoint {
    /// Factor of the contact force in the step equation: the du form is the midpoint equation
    /// times 2, so `K du = rhs - 2 B^T lambda` with `lambda` the midpoint contact force.
    pub const CONTACT_FORCE_FACTOR: f64 = 2.0;

    /// Start from `u0`, `v0` (Dirichlet values at t = 0 are imposed on `u0`) at time `t0`.
    pub fn new(
        op: StepOperator,
        m: MassMatrix,
        a: Matrix,
        dirichlet: Dirichlet,
        tau: f64,
        mut u: Vector,
        v: Vector,
        t0: f64,
        forces: &dyn Forces,
    ) -> Result<Midpoint> {
        let first_dof = u.ownership_range().0;
        let set = |u: &mut Vector| -> Result<()> {
            u.with_local_slice_mut(|x| {
                for (i, &dof) in dirichlet.dofs().iter().enumerate() {
                    x[dof as usize - first_dof] = dirichlet.value(i, t0);
                }
            })
        };
        if !dirichlet.dofs().is_empty() {
            set(&mut u)?;
        }
        let dup = || u.duplicate();
        let lifting = if op.k_free.is_some() { Some((dup()?, dup()?, dup()?)) } else { None };
        let mut mp = Midpoint {
            tau,
            du: dup()?,
            contact_predictor: Predictor::Last,
            du_last: None,
            mv: dup()?,
            au: dup()?,
            mdu: dup()?,
            reuse: ReuseReport::default(),
            fresh_step: false,
            rhs: dup()?,
            f_now: dup()?,
            f_next: dup()?,
            lifting,
            op,
            m,
            a,
            dirichlet,
            first_dof,
            u,
            v,
            energy: Energy::default(),
            ksp_iterations: 0,
            massless: None,
            release_projections: 0,
            release_energy: 0.0,
            before_projection: None,
            corrections: Corrections::default(),
            corrections_this_step: 0,
            drift: 0.0,
            drift_rtol: Self::DRIFT_RTOL,
            blend: true,
            kick: true,
            kick_layer: None,
            kick_ready: None,
            kick_vectors: None,
            kick_cg: None,
            release_layer: None,
            correct: false,
            rhs_corr: None,
            corr: None,
            dim: 1,
            newton: None,
            f_sum: None,
            du_prev: None,
            increments: 0,
            rest_guesses: 0,
            m_ones: None,
            groups: Vec::new(),
            n_groups: 1,
            reference: None,
            layer_rate: Default::default(),
        };
        mp.reuse.interval = mp.op.refresh;
        mp.refresh(forces, t0)?;
        Ok(mp)
    }

    /// Consistent initial data for the massless DOFs (rows of `M` that are exactly zero, the
    /// mass-free layer's contact DOFs, not Dirichlet): their rows of the equation of motion are
    /// static, `(A u)_C = f_C`, and the midpoint rule keeps their residual
    /// `r^n = f^n_C - (A u^n)_C` only up to sign, `r^{n+1} = -r^n + O(tau^2)`: an initial
    /// displacement that violates them sets off a period-2 oscillation of those nodes that
    /// never decays. So `u_C` is replaced by the solution of `A_CC u_C = f_C(t) - A_CN u_N`
    /// ([`Midpoint::project_massless`]). Returns the largest change (`None` without massless
    /// DOFs). Collective.
    /// `hold`: global DOFs kept as they are (contact nodes whose equilibrium needs their
    /// contact force, e.g. bodies touching at t = 0). [`Midpoint::undo_massless`] takes the
    /// change back.
    pub fn make_massless_consistent(
        &mut self,
        forces: &dyn Forces,
        t: f64,
        hold: &[i32],
    ) -> Result<Option<f64>> {
        if forces.present() {
            forces.assemble(t, &mut self.f_now)?;
        }
        let mut before = self.u.duplicate()?;
        before.copy_from(&self.u)?;
        let change = self.project_massless(forces.present(), hold)?;
        self.before_projection = Some(before);
        self.refresh(forces, t)?;
        Ok(change)
    }

    /// Back to the state before the last [`Midpoint::make_massless_consistent`].
    pub fn undo_massless(&mut self, forces: &dyn Forces, t: f64) -> Result<()> {
        if let Some(before) = self.before_projection.take() {
            self.u.copy_from(&before)?;
            self.refresh(forces, t)?;
        }
        Ok(())
    }

    /// The massless DOFs (exact zeros on `M`'s diagonal, Dirichlet DOFs excluded) of this rank,
    /// found once.
    fn massless(&mut self) -> Result<&[bool]> {
        if self.massless.is_none() {
            let mut diag = self.u.duplicate()?;
            self.m.get_diagonal(&mut diag)?;
            let (lo, hi) = self.u.ownership_range();
            let mut fixed = vec![false; hi - lo];
            for &d in self.dirichlet.dofs() {
                if (lo..hi).contains(&(d as usize)) {
                    fixed[d as usize - lo] = true;
                }
            }
            let local: Vec<bool> = diag.with_local_slice(|m| {
                m.iter().zip(&fixed).map(|(&x, &f)| x == 0.0 && !f).collect()
            })?;
            let count = local.iter().filter(|&&c| c).count() as f64;
            let mut all = 0.0;
            SimpleCommunicator::world().all_reduce_into(&count, &mut all, SystemOperation::sum());
            self.massless = Some((local, all > 0.0));
        }
        Ok(&self.massless.as_ref().expect("set above").0)
    }

    /// Puts the massless DOFs but those in `hold` (global indices, any rank may list any) in
    /// static equilibrium at the current state: `A_FF d_F = (f - A u)_F` on the free massless
    /// DOFs `F`, the minimizer of the potential `1/2 u.Au - f.u` over `u_F` (`f = f_now` with
    /// `loads`, else 0), `u += d`. `A_CC` of the whole layer is gathered and factored exactly
    /// ([`LayerBlock`], surface-sized), the held rows taken out: its pattern never changes, so
    /// each projection refactors numerically (on the ball, 180 steps with 24 releases, the
    /// CG + Jacobi solve of the whole system this replaced cost a fifth of `M_H^0`'s stepping
    /// beyond `M`'s). Returns `|d|_inf` (`None` without massless DOFs). Collective; energies
    /// not refreshed.
    fn project_massless(&mut self, loads: bool, hold: &[i32]) -> Result<Option<f64>> {
        self.massless()?;
        let (local, any) = self.massless.as_ref().expect("found").clone();
        if !any {
            return Ok(None);
        }
        if self.newton.is_some() {
            return self.project_massless_finite(&local, loads, hold).map(Some);
        }
        // r = f - A u
        let mut r = self.u.duplicate()?;
        if loads {
            r.copy_from(&self.f_now)?;
        }
        let mut au = self.u.duplicate()?;
        self.a.mult(&self.u, &mut au)?;
        r.axpy(-1.0, &au)?;
        if self.release_layer.is_none() {
            let rows: Vec<usize> = local.iter().enumerate().filter(|m| *m.1).map(|m| m.0).collect();
            self.release_layer = super::layer::LayerBlock::with_solver(
                &self.a,
                rows,
                None,
                "massless_release_",
                "cholesky",
                "qmd",
            )?;
        }
        let block = self.release_layer.as_mut().expect("some rank has massless rows");
        block.factor_holding(&self.a, None, hold)?;
        let (lo, hi) = self.u.ownership_range();
        let held: std::collections::HashSet<usize> = hold
            .iter()
            .map(|&g| g as usize)
            .filter(|g| (lo..hi).contains(g))
            .map(|g| g - lo)
            .collect();
        let own: Vec<f64> = r.with_local_slice(|r| {
            block.own_rows().iter().map(|&i| if held.contains(&i) { 0.0 } else { r[i] }).collect()
        })?;
        let d = block.solve_own(&own)?;
        let rows = block.own_rows();
        let mut change = 0.0f64;
        self.u.with_local_slice_mut(|u| {
            for (j, &i) in rows.iter().enumerate() {
                u[i] += d[j];
                change = change.max(d[j].abs());
            }
        })?;
        let mut all = 0.0;
        SimpleCommunicator::world().all_reduce_into(&change, &mut all, SystemOperation::max());
        Ok(Some(all))
    }

    /// Recompute what follows from `u`, `v` at time `t`: the loads `f(t)`, `M v`, `A u` and the
    /// energies (after `new`, or after the state was replaced by a restart).
    pub fn refresh(&mut self, forces: &dyn Forces, t: f64) -> Result<()> {
        if forces.present() {
            forces.assemble(t, &mut self.f_now)?;
            self.f_next.copy_from(&self.f_now)?;
        }
        self.update_energies()
    }

    fn update_energies(&mut self) -> Result<()> {
        self.m.mult(&self.v, &mut self.mv)?;
        self.energy.kinetic = 0.5 * self.v.dot(&self.mv)?;
        if let Some(newton) = self.newton.as_mut() {
            self.energy.potential = newton.strain_energy(&self.u)?;
            return Ok(());
        }
        self.a.mult(&self.u, &mut self.au)?;
        self.energy.potential = 0.5 * self.u.dot(&self.au)?;
        Ok(())
    }

    /// Correct the energy of contact steps from now on ([`Midpoint::correct_energy`]) when
    /// `correct` and there are massless DOFs, steady steps' work collected up to `drift_rtol`
    /// of the energy (`None`: [`Midpoint::DRIFT_RTOL`]); `dim` components per node, `groups`
    /// the body of each owned node in DOF order (the correction keeps each body's momentum;
    /// empty: one body). Collective.
    /// Whether a corrected step whose two solves share an active set is settled without a
    /// confirming solve (default true).
    pub fn set_correction_blend(&mut self, blend: bool) {
        self.blend = blend;
    }

    /// Whether a corrected step is settled without a solve where the contact solver allows
    /// it ([`Midpoint::kick`]; default true).
    pub fn set_correction_kick(&mut self, kick: bool) {
        self.kick = kick;
    }

    pub fn configure_massless(
        &mut self,
        correct: bool,
        drift_rtol: Option<f64>,
        dim: usize,
        groups: Vec<u32>,
    ) -> Result<()> {
        self.dim = dim;
        // The number of bodies, the same on every rank (a rank may own nodes of few of them).
        let local = groups.iter().copied().max().map_or(1, |g| g as usize + 1) as f64;
        let mut n = 0.0f64;
        SimpleCommunicator::world().all_reduce_into(&local, &mut n, SystemOperation::max());
        self.n_groups = n as usize;
        self.groups = groups;
        self.massless()?;
        let any = self.massless.as_ref().expect("found").1;
        self.correct = correct && any;
        self.drift_rtol = drift_rtol.unwrap_or(Self::DRIFT_RTOL);
        self.corrections.enabled = self.correct;
        Ok(())
    }

    /// Whether any rank has massless DOFs (once they were looked for: by the consistent
    /// initialization or the choice of the scheme).
    pub fn has_massless(&self) -> bool {
        self.massless.as_ref().is_some_and(|m| m.1)
    }

    /// What the energy correction did so far.
    /// The work of steady contact steps (geometry following the bodies) left uncorrected up
    /// to this fraction of the energy: their midpoint error is O(tau^2) a step (a slave
    /// node crossing a master node's kink), of either sign, and putting it back takes the
    /// step's solves again.
    pub const DRIFT_RTOL: f64 = 1e-7;

    pub fn corrections(&self) -> Corrections {
        // What the steady steps collected is pending as well (a restart puts it back).
        Corrections { pending: self.corrections.pending + self.drift, ..self.corrections }
    }

    /// The first guess of contact steps' solves (`-step_predictor`; default here the last
    /// increment, as PETSc's nonzero initial guess gives). The run sets extrapolation
    /// without massless DOFs: the increments change smoothly in time (`2 du^n - du^{n-1}`
    /// took 7% fewer CG + Jacobi iterations, 2% fewer with block ILU, per contact step on
    /// the ball at 162k DOFs).
    pub fn set_contact_predictor(&mut self, predictor: Predictor) {
        self.contact_predictor = predictor;
        self.du_last = None;
    }

    /// `du` before the first solve of step `n` (`n -> n + 1`) with contact: zero, kept, or
    /// `2 du^n - du^{n-1}`. `du` holds the last step's increment from `n = 1` on (a restart's
    /// too); the extrapolation needs the one before, recorded at step `n - 1` (a step without
    /// the contact solver, or the first of a run, keeps `du` and records it).
    fn predict_contact_step(&mut self, n: usize) -> Result<()> {
        match self.contact_predictor {
            Predictor::Zero => self.du.zero()?,
            Predictor::Last => {}
            Predictor::Extrapolate => match self.du_last.as_mut() {
                Some((last, k)) if *k + 1 == n => {
                    Vector::with_slices([], [&mut self.du, last], |[], [du, last]| {
                        for i in 0..du.len() {
                            let d = du[i];
                            du[i] = 2.0 * d - last[i];
                            last[i] = d;
                        }
                    })?;
                    *k = n;
                }
                Some((last, k)) => {
                    last.copy_from(&self.du)?;
                    *k = n;
                }
                None if n >= 1 => {
                    let mut last = self.du.duplicate()?;
                    last.copy_from(&self.du)?;
                    self.du_last = Some((last, n));
                }
                None => {}
            },
        }
        Ok(())
    }

    /// Solves the step's system (`rhs`, or `rhs_corr` when `corrected`) with the contact
    /// solver when there is one.
    fn solve_system<'c>(
        &mut self,
        corrected: bool,
        contact: Option<&mut (dyn ContactSolver + 'c)>,
        n: usize,
        t_next: f64,
    ) -> Result<(usize, Option<StepContact>)> {
        let with_step = |e: Error| match e {
            Error::Solver(m) if !m.starts_with("contact") => {
                Error::Solver(format!("step {} (t = {}): {m}", n + 1, crate::console::time(t_next)))
            }
            other => other,
        };
        if contact.is_some() && !corrected {
            self.predict_contact_step(n)?;
        }
        let rhs = if corrected { self.rhs_corr.as_ref().expect("allocated") } else { &self.rhs };
        match contact {
            None => {
                if let Some(cg) = self.op.cg.as_mut() {
                    let scale = self.energy.kinetic + self.energy.potential;
                    // Prescribed increments are zero without the lifting.
                    cg.set_scale(self.lifting.is_none());
                    let (k, ksp) = (&self.op.k, &self.op.ksp);
                    let info = cg
                        .solve(k, ksp, rhs, &mut self.du, scale, self.fresh_step)
                        .map_err(with_step)?;
                    self.reuse.steps += 1;
                    self.reuse.products += info.products;
                    return Ok((info.iterations, None));
                }
                let info = self.op.ksp.solve(rhs, &mut self.du).map_err(with_step)?;
                Ok((info.iterations, None))
            }
            Some(solver) => {
                let (c, its) = solver
                    .solve(StepSystem {
                        k: &mut self.op.k,
                        ksp: &mut self.op.ksp,
                        rhs,
                        u: &self.u,
                        du: &mut self.du,
                        step: n + 1,
                        time: t_next,
                        tau: self.tau,
                        linearization: false,
                    })
                    .map_err(with_step)?;
                Ok((its, Some(c)))
            }
        }
    }

    /// Whether a contact step gets the energy correction, and the slack it may leave: with
    /// massless DOFs, a step whose active set changed, or that takes pending work, or whose
    /// geometry follows the bodies. Following, a step that keeps its active set does work too
    /// (the midpoint's error on the moving geometry): collected while small (`drift_rtol` of
    /// the energy), then put back with the activations' (`None` while collecting); what a
    /// correction leaves below a tenth of that bound joins the drift instead of another solve.
    pub(super) fn correction_due(
        &mut self,
        changed: bool,
        follows: bool,
        work: f64,
    ) -> Option<f64> {
        if !self.correct {
            return None;
        }
        let scale = self.energy.total().abs().max(self.energy.kinetic);
        if follows
            && !changed
            && self.corrections.pending == 0.0
            && (self.drift + work).abs() <= self.drift_rtol * scale
        {
            self.drift += work;
            return None;
        }
        if !(changed || follows || self.corrections.pending != 0.0) {
            return None;
        }
        self.corrections.pending += std::mem::take(&mut self.drift);
        Some(if follows { 0.1 * self.drift_rtol * scale } else { 0.0 })
    }

    /// One step `n -> n + 1`, with the contact solver inside it when there is one.
    pub fn step<'c>(
        &mut self,
        n: usize,
        forces: &dyn Forces,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<StepReport> {
        if self.newton.is_some() {
            return self.step_finite_strain(n, forces, contact);
        }
        let tau = self.tau;
        let t_next = self.time_at(n + 1);
        // f(t_{n+1}) when it changes (else f_now stands for both ends of the step).
        let (loads, varying) = (forces.present(), forces.time_dependent());
        if loads && varying {
            forces.assemble(t_next, &mut self.f_next)?;
        }
        // rhs = 2 f^{n+1/2} + (4/tau) M v^n - 2 A u^n, f^{n+1/2} = (f(t_n) + f(t_{n+1}))/2,
        // in one pass.
        let cv = 4.0 / tau;
        let (mv, au) = (&self.mv, &self.au);
        match (loads, varying) {
            (true, true) => Vector::with_slices(
                [mv, au, &self.f_now, &self.f_next],
                [&mut self.rhs],
                |[mv, au, f0, f1], [rhs]| {
                    for i in 0..rhs.len() {
                        rhs[i] = cv * mv[i] - 2.0 * au[i] + f0[i] + f1[i];
                    }
                },
            )?,
            (true, false) => Vector::with_slices(
                [mv, au, &self.f_now],
                [&mut self.rhs],
                |[mv, au, f], [rhs]| {
                    for i in 0..rhs.len() {
                        rhs[i] = cv * mv[i] - 2.0 * au[i] + 2.0 * f[i];
                    }
                },
            )?,
            (false, _) => Vector::with_slices([mv, au], [&mut self.rhs], |[mv, au], [rhs]| {
                for i in 0..rhs.len() {
                    rhs[i] = cv * mv[i] - 2.0 * au[i];
                }
            })?,
        }
        // The step's own CG solves steps without contact; a contact solver rewrites K.
        let own_cg = contact.is_none() && self.op.cg.is_some();
        if let (Some(cg), false) = (self.op.cg.as_mut(), own_cg) {
            cg.forget();
        }
        self.fresh_step = own_cg && self.reuse.since_refresh + 1 >= self.op.refresh;
        if let Some((_, _, full)) = self.lifting.as_mut() {
            full.copy_from(&self.rhs)?;
        }
        self.dirichlet_rows(t_next)?;
        // The active set before the step (obstacle contact): nodes it loses are released.
        let before: Option<Vec<bool>> = contact.as_deref().map(|c| c.active().to_vec());
        let (mut its, mut report) = self.solve_system(false, contact.as_deref_mut(), n, t_next)?;
        let mut hold: Vec<i32> = Vec::new();
        let mut project = false;
        if let Some(c) = report.as_mut() {
            let changed = before.as_deref().is_some_and(|b| b != c.row.active.as_slice());
            let follows = contact.as_deref().is_some_and(|s| s.geometry_follows());
            if let Some(slack) = self.correction_due(changed, follows, c.work) {
                let (extra_its, last, work) = self.correct_energy(
                    c,
                    contact.as_deref_mut(),
                    n,
                    t_next,
                    slack,
                    (loads, varying),
                )?;
                its += extra_its;
                if let Some(new) = last {
                    *c = new;
                }
                c.work = work;
            }
            let changed = before.as_deref().is_some_and(|b| b != c.row.active.as_slice());
            if changed {
                // Released massless nodes: their static rows lose the contact force at once,
                // and the midpoint rule would carry that residual on as a period-2 jump of
                // the node. Held: the nodes still active (all their DOFs). Pairs are left as
                // they are (their constraints live in the mortar basis).
                let solver = contact.as_deref().expect("contact solver");
                let nodes = solver.nodes();
                let b = before.as_deref().unwrap_or_default();
                let released =
                    !solver.is_pair() && b.iter().zip(&c.row.active).any(|(&was, &is)| was && !is);
                if released {
                    let dim = nodes.dim;
                    for (k, &a) in c.row.active.iter().enumerate() {
                        if a {
                            hold.extend((0..dim).map(|i| nodes.dofs[k * dim + i].0));
                        }
                    }
                    project = true;
                }
            }
        }
        if let Some(c) = &report {
            self.energy.contact_work += c.work + c.tangential_work;
            self.energy.friction_dissipation += c.dissipation;
        }
        self.ksp_iterations += its;
        if loads {
            self.energy.external_work += self.load_work(varying)?;
        }
        self.reaction_work()?;
        if loads && varying {
            std::mem::swap(&mut self.f_now, &mut self.f_next);
        }
        if own_cg && self.lifting.is_none() {
            self.advance_with_products()?;
        } else {
            self.u.axpy(1.0, &self.du)?;
            // v^{n+1} = 2 du / tau - v^n
            self.v.scale(-1.0)?;
            self.v.axpy(2.0 / tau, &self.du)?;
            self.update_energies()?;
        }
        if project {
            self.release(forces.present(), &hold)?;
        }
        let loaded = contact.as_deref().map_or_else(Vec::new, |c| c.loaded_dofs());
        self.after_step_layer(loaded, loads && varying)?;
        Ok(StepReport { time: t_next, ksp_iterations: its, newton_iterations: 0, contact: report })
    }

    /// After a step that released massless contact nodes: the massless DOFs but `hold` put
    /// back in static equilibrium, the energy that took booked as contact work (and, with the
    /// correction, put back by the next steps). Collective.
    fn release(&mut self, loads: bool, hold: &[i32]) -> Result<()> {
        let before = self.energy.total();
        if self.project_massless(loads, hold)?.is_some() {
            self.update_energies()?;
            let removed = self.energy.total() - before;
            self.energy.contact_work += removed;
            self.release_energy += removed;
            self.release_projections += 1;
            if self.correct {
                self.corrections.pending += removed;
            }
        }
        Ok(())
    }

    /// Steps after which released massless contact nodes were put back in static
    /// equilibrium, and the energy that took (<= 0; part of the contact work).
    pub fn release_projections(&self) -> (usize, f64) {
        (self.release_projections, self.release_energy)
    }

    /// The constrained rows of the right-hand side: `diag * du_D` with
    /// `du_D = g(t_{n+1}) - u^n_D`; for non-zero values the known columns `K[:, D] du_D` move
    /// to the right-hand side (the lifting).
    fn dirichlet_rows(&mut self, t_next: f64) -> Result<()> {
        // Decided on the scene, not on this rank's DOFs: the product below is collective,
        // and a rank may own no constrained DOF.
        if !self.dirichlet.present {
            return Ok(());
        }
        let lo = self.first_dof;
        let dofs = self.dirichlet.dofs();
        let mut du_d = vec![0.0; dofs.len()];
        if let Some((w, kw, _)) = self.lifting.as_mut() {
            self.u.with_local_slice(|x| {
                for (i, &dof) in dofs.iter().enumerate() {
                    du_d[i] = self.dirichlet.value(i, t_next) - x[dof as usize - lo];
                }
            })?;
            w.zero()?;
            w.with_local_slice_mut(|x| {
                for (i, &dof) in dofs.iter().enumerate() {
                    x[dof as usize - lo] = du_d[i];
                }
            })?;
            self.op.k_free.as_ref().expect("unconstrained operator").mult(w, kw)?;
            self.rhs.axpy(-1.0, kw)?;
        }
        let diag = self.op.dirichlet_diag;
        self.rhs.with_local_slice_mut(|x| {
            for (i, &dof) in dofs.iter().enumerate() {
                x[dof as usize - lo] = diag * du_d[i];
            }
        })
    }

    /// Work of the reactions `r_D` at non-zero Dirichlet boundaries: `K0 du = rhs + 2 r` on the
    /// constrained rows, so the step's work is `r . du`.
    fn reaction_work(&mut self) -> Result<()> {
        let (Some((_, kdu, full)), Some(k0)) = (self.lifting.as_mut(), self.op.k_free.as_ref())
        else {
            return Ok(());
        };
        k0.mult(&self.du, kdu)?;
        kdu.axpy(-1.0, full)?;
        let lo = self.first_dof;
        let mut w = 0.0;
        kdu.with_local_slice(|r| {
            self.du.with_local_slice(|d| {
                for &dof in self.dirichlet.dofs() {
                    let i = dof as usize - lo;
                    w += 0.5 * r[i] * d[i];
                }
            })
        })??;
        let mut sum = 0.0;
        SimpleCommunicator::world().all_reduce_into(&w, &mut sum, SystemOperation::sum());
        self.energy.dirichlet_work += sum;
        Ok(())
    }

    pub fn tau(&self) -> f64 {
        self.tau
    }
    /// The time of step n, `t_n = n tau` (the one place it is computed).
    pub fn time_at(&self, n: usize) -> f64 {
        n as f64 * self.tau
    }
    pub fn energy(&self) -> &Energy {
        &self.energy
    }
    /// KSP iterations of all steps so far.
    pub fn ksp_iterations(&self) -> usize {
        self.ksp_iterations
    }
    pub fn u(&self) -> &Vector {
        &self.u
    }
    pub fn v(&self) -> &Vector {
        &self.v
    }
    /// The last increment `u^{n+1} - u^n` (the next solve's initial guess).
    pub fn du(&self) -> &Vector {
        &self.du
    }
    /// `M v` of the current state (the momentum per component is its sum).
    /// The mass matrix of the step (`M` or `M_H`).
    pub fn mass(&self) -> &MassMatrix {
        &self.m
    }
    pub fn mv(&self) -> &Vector {
        &self.mv
    }
    pub fn operator(&self) -> &StepOperator {
        &self.op
    }

    /// Replace the state by a checkpoint's `u`, `v`, `du` (set through the closure) and the
    /// running work totals; then `refresh` recomputes the rest.
    pub fn restore(
        &mut self,
        set: impl FnOnce(&mut Vector, &mut Vector, &mut Vector) -> Result<()>,
        works: Energy,
        ksp_iterations: usize,
        pending_correction: f64,
    ) -> Result<()> {
        set(&mut self.u, &mut self.v, &mut self.du)?;
        self.increments = 0;
        self.layer_velocity_restored()?;
        if let Some(cg) = self.op.cg.as_mut() {
            cg.forget();
        }
        self.energy = works;
        self.ksp_iterations = ksp_iterations;
        // The contact work the energy correction had still to put back: the next steps put it
        // back as the uninterrupted run's would.
        self.corrections.pending = pending_correction;
        Ok(())
    }
}
