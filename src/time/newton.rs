//! The energy-momentum midpoint step of finite-strain bodies: a Newton loop of our own around
//! the step's KSP (docs/method.md, finite strain).
//!
//! With `du = u_1 - u_0` the step's equation, times 2 as the linear step's,
//!
//! ```text
//!   r(du) = 4/tau^2 M du - 4/tau M v_0 - (f_0 + f_1) + 2 f_int,alg(u_0, u_0 + du) = 0,
//!   v_1 = 2 du/tau - v_0,
//! ```
//! is solved by Newton: `K_T delta = -r`, `K_T = 4/tau^2 M + 2 d f_int,alg / d u_1`
//! (unsymmetric: GMRES by default), `du += delta`. Dirichlet DOFs take their increment before
//! the first iteration and keep it (`delta_D = 0`).
//!
//! The step's energy error is exact and cheap: dotting `r/2` with `du`,
//! `E_1 - E_0 - f^{n+1/2}.du - r_D.du_D/2 = du.r_F/2` (`F` the free rows), since
//! `1/2 v_1.M v_1 - 1/2 v_0.M v_0 = 2/tau^2 du.M (du - tau v_0)` and
//! `f_int,alg.du = W(u_1) - W(u_0)`. So Newton stops when both the residual and this energy
//! error are small: the residual relative to the size of the terms that cancel in it, the
//! energy error relative to the energy. A full Newton step that makes the residual grow is
//! halved (backtracking) until it does not, at most [`Newton::MAX_HALVINGS`] times; a step
//! that inverts an element is halved too.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::assembly::finite_strain::{Evaluation, InternalForce};
use crate::contact::{ContactSolver, StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::mass::MassMatrix;
use crate::petsc::{Ksp, Matrix, Vector};

/// The Newton loop's tolerances (`-newton_rtol`, `-newton_energy_rtol`, `-newton_max_it`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonOptions {
    /// The residual's 2-norm relative to the sum of the norms of its terms.
    pub rtol: f64,
    /// The step's energy error `|du.r_F|/2` relative to the energy.
    pub energy_rtol: f64,
    /// Newton iterations (linear solves) per step at most.
    pub max_it: usize,
    /// Print each iteration's residual and energy error (`-newton_monitor`).
    pub monitor: bool,
    /// `-newton_tangent_reuse X`: steps without contact keep the last tangent and its
    /// preconditioner while an iteration with it shrinks the residual at least by this
    /// factor (a chord iteration: one internal force and one solve); 0: a new tangent every
    /// iteration (Newton, quadratic).
    pub tangent_reuse: f64,
}

impl Default for NewtonOptions {
    fn default() -> Self {
        NewtonOptions {
            rtol: 1e-10,
            energy_rtol: 1e-14,
            max_it: 25,
            monitor: false,
            tangent_reuse: 0.0,
        }
    }
}

/// What the Newton loops did so far.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NewtonStats {
    /// Steps solved.
    pub steps: usize,
    /// Newton iterations (tangent solves) of all steps.
    pub iterations: usize,
    /// The most of one step.
    pub max_iterations: usize,
    /// Halved Newton corrections (backtracking).
    pub halvings: usize,
    /// Iterations that solved with a kept tangent (`-newton_tangent_reuse`).
    #[serde(default)]
    pub kept_tangent: usize,
    /// Iterations that solved with the step's tangent once only the energy error was left
    /// (chord iterations).
    #[serde(default)]
    pub energy_chords: usize,
    /// The largest energy error a converged step left, relative to the energy.
    pub max_energy_error: f64,
    /// Newton iterations of the last step.
    #[serde(skip)]
    pub last: usize,
    /// Evaluations of the internal force alone and with its tangent, and their seconds (the
    /// slowest rank's in a run's summary).
    #[serde(default)]
    pub force_evaluations: usize,
    #[serde(default)]
    pub force_seconds: f64,
    #[serde(default)]
    pub tangent_evaluations: usize,
    #[serde(default)]
    pub tangent_seconds: f64,
    /// Time steps with a node in contact at their end: their Newton iterations (every solve
    /// of the step, the energy correction's too) and wall seconds; and the same of the steps
    /// without (plain Newton steps), for the cost of a contact step.
    #[serde(default)]
    pub contact_steps: usize,
    #[serde(default)]
    pub contact_iterations: usize,
    #[serde(default)]
    pub contact_seconds: f64,
    #[serde(default)]
    pub plain_steps: usize,
    #[serde(default)]
    pub plain_iterations: usize,
    #[serde(default)]
    pub plain_seconds: f64,
    /// Newton iterations whose contact active set cycled on the linearization and was taken
    /// as it was (the next iteration linearizes anew).
    #[serde(default)]
    pub cycled: usize,
    /// Steps solved again from the other first guess (the step's start `du = 0`, or the
    /// extrapolated increment) after Newton failed from the first.
    #[serde(default)]
    pub restarts: usize,
}

impl NewtonStats {
    /// Books one time step: `contact` whether a node is in contact at its end, its Newton
    /// iterations and wall seconds.
    pub fn book_step(&mut self, contact: bool, iterations: usize, seconds: f64) {
        if contact {
            self.contact_steps += 1;
            self.contact_iterations += iterations;
            self.contact_seconds += seconds;
        } else {
            self.plain_steps += 1;
            self.plain_iterations += iterations;
            self.plain_seconds += seconds;
        }
    }
}

/// One step's result.
#[derive(Debug, Clone)]
pub struct NewtonStep {
    /// Newton iterations (tangent solves) and their KSP iterations.
    pub iterations: usize,
    pub ksp_iterations: usize,
    /// The strain energy at `u_1`.
    pub strain_energy: f64,
    /// The work of the Dirichlet reactions, `r_D.du_D/2`.
    pub dirichlet_work: f64,
    /// The contact solver's result of the last iteration (scenes with contact).
    pub contact: Option<StepContact>,
}

/// The pieces of the integrator one Newton step works with.
pub struct StepInputs<'a> {
    pub m: &'a MassMatrix,
    /// The step operator's matrix, refilled with `K_T` each iteration, and its solver.
    pub k: &'a mut Matrix,
    pub ksp: &'a mut Ksp,
    /// Dirichlet DOFs owned by this rank (global) and their increments over the step.
    pub dirichlet: &'a [i32],
    pub dirichlet_du: &'a [f64],
    pub dirichlet_diag: f64,
    pub u: &'a Vector,
    pub mv: &'a Vector,
    /// `f_0 + f_1` (None without loads).
    pub f_sum: Option<&'a Vector>,
    /// The step's increment: in, the first guess; out, the solution.
    pub du: &'a mut Vector,
    pub tau: f64,
    /// The energy the energy error is measured against.
    pub energy: f64,
    /// The step, for messages.
    pub step: usize,
    pub time: f64,
}

/// The Newton loop's state, set up once per run.
pub struct Newton {
    pub force: InternalForce,
    /// `d f_int,alg / d u_1` and `4/tau^2 M`, both in the step operator's structure.
    tangent: Matrix,
    inertia: Matrix,
    pub opts: NewtonOptions,
    pub stats: NewtonStats,
    f_int: Vector,
    r: Vector,
    /// With contact: `r + c`, the contact forces `c = 2 B^T lambda` of the last solve, and
    /// the linearized step's right-hand side (as given, and with the Dirichlet rows set).
    rc: Vector,
    c: Vector,
    rhs: Vector,
    rhs_free: Vector,
    mdu: Vector,
    delta: Vector,
    u1: Vector,
    /// The body of each owned node and the bodies' names (messages name the body with the
    /// largest residual).
    node_body: Vec<u32>,
    body_names: Vec<String>,
    dim: usize,
    /// The step operator and its preconditioner hold the last tangent with the Dirichlet
    /// rows eliminated (no contact solver or static solve has rewritten it since).
    kept: bool,
    /// `tangent` holds an evaluated tangent (of a step or of the static layer problem).
    tangent_ready: bool,
}

impl Newton {
    /// At most this many halvings of one Newton correction.
    pub const MAX_HALVINGS: usize = 12;

    /// `k` is the step operator (`4/tau^2 M + A`, unconstrained or not: only its structure
    /// is used): the tangent and the inertia term `4/tau^2 M` are kept in its structure, so
    /// that each iteration forms `K_T = 4/tau^2 M + 2 T` by two plain array operations.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        force: InternalForce,
        layout: &Vector,
        k: &Matrix,
        m: &MassMatrix,
        tau: f64,
        opts: NewtonOptions,
        node_body: Vec<u32>,
        body_names: Vec<String>,
        dim: usize,
    ) -> Result<Newton> {
        let tangent = k.duplicate(false)?;
        let mut inertia = k.duplicate(false)?;
        m.add_to(&mut inertia, 4.0 / (tau * tau))?;
        let dup = || layout.duplicate();
        Ok(Newton {
            force,
            tangent,
            inertia,
            opts,
            stats: NewtonStats::default(),
            f_int: dup()?,
            r: dup()?,
            rc: dup()?,
            c: dup()?,
            rhs: dup()?,
            rhs_free: dup()?,
            mdu: dup()?,
            delta: dup()?,
            u1: dup()?,
            node_body,
            body_names,
            dim,
            kept: false,
            tangent_ready: false,
        })
    }

    /// The last evaluated tangent of the internal force (`d f_int,alg / d u_1` of the last
    /// step's first guess, or the static tangent of a layer projection), without Dirichlet
    /// rows or contact conditions; `None` before the first evaluation.
    pub fn last_tangent(&self) -> Option<&Matrix> {
        self.tangent_ready.then_some(&self.tangent)
    }

    /// The strain energy at `u`. Collective.
    pub fn strain_energy(&mut self, u: &Vector) -> Result<f64> {
        self.force.energy(u)?.map_err(|m| Error::Solver(format!("the initial state: {m}")))
    }

    /// `r(du)` into `self.r` with the Dirichlet rows zeroed, and with contact `r + c` (`c` the
    /// last contact solve's forces `2 B^T lambda`) into `self.rc`; returns (`|r + c|`, the
    /// norms' sum the residual is measured against, `du.(r + c)_F/2`, `du_D.r_D/2`, the sum
    /// of the terms' works `|du.term|/2`, the scale of the energy error next to the energy).
    /// Collective.
    fn residual(&mut self, s: &mut StepInputs, contact: bool) -> Result<(f64, f64, f64, f64, f64)> {
        let (tau, lo) = (s.tau, s.du.ownership_range().0);
        s.m.mult(s.du, &mut self.mdu)?;
        let ci = 4.0 / (tau * tau);
        let cv = 4.0 / tau;
        let mut parts = [0.0f64; 5];
        let mut works = [0.0f64; 4];
        let mut reaction = 0.0;
        let mut work = 0.0;
        let fsum = s.f_sum;
        Vector::with_slices(
            [&self.mdu, s.mv, &self.f_int, &*s.du],
            [&mut self.r],
            |[mdu, mv, fi, du], [r]| {
                for i in 0..r.len() {
                    r[i] = ci * mdu[i] - cv * mv[i] + 2.0 * fi[i];
                    parts[0] += (ci * mdu[i]).powi(2);
                    parts[1] += (cv * mv[i]).powi(2);
                    parts[2] += (2.0 * fi[i]).powi(2);
                    works[0] += 0.5 * ci * mdu[i] * du[i];
                    works[1] += 0.5 * cv * mv[i] * du[i];
                    works[2] += fi[i] * du[i];
                }
                for &d in s.dirichlet {
                    let i = d as usize - lo;
                    reaction += 0.5 * du[i] * r[i];
                }
            },
        )?;
        if let Some(f) = fsum {
            Vector::with_slices([f, &*s.du], [&mut self.r], |[f, du], [r]| {
                for i in 0..r.len() {
                    r[i] -= f[i];
                    parts[3] += f[i] * f[i];
                    works[3] += 0.5 * f[i] * du[i];
                }
                // The loads' part of the reaction rows.
                for &d in s.dirichlet {
                    let i = d as usize - lo;
                    reaction -= 0.5 * du[i] * f[i];
                }
            })?;
        }
        self.r.with_local_slice_mut(|r| {
            for &d in s.dirichlet {
                r[d as usize - lo] = 0.0;
            }
        })?;
        let total = if contact {
            Vector::with_slices([&self.r, &self.c], [&mut self.rc], |[r, c], [rc]| {
                for i in 0..rc.len() {
                    rc[i] = r[i] + c[i];
                    parts[4] += c[i] * c[i];
                }
            })?;
            &self.rc
        } else {
            &self.r
        };
        Vector::with_slices([total, &*s.du], [], |[r, du], []| {
            for i in 0..r.len() {
                work += 0.5 * du[i] * r[i];
            }
        })?;
        let world = SimpleCommunicator::world();
        let local = [
            parts[0], parts[1], parts[2], parts[3], parts[4], work, reaction, works[0], works[1],
            works[2], works[3],
        ];
        let mut all = [0.0f64; 11];
        world.all_reduce_into(&local[..], &mut all[..], SystemOperation::sum());
        let norm = total.norm2()?;
        let scale = all[..5].iter().map(|x| x.sqrt()).sum::<f64>();
        let work_scale = all[7..].iter().map(|x| x.abs()).sum::<f64>();
        Ok((norm, scale, all[5], all[6], work_scale))
    }

    /// `u_1 = u_0 + du` and the internal force there. Collective.
    fn evaluate(&mut self, s: &StepInputs, tangent: bool) -> Result<Evaluation> {
        let t0 = std::time::Instant::now();
        self.u1.waxpy(1.0, s.du, s.u)?;
        let k = if tangent { Some(&mut self.tangent) } else { None };
        let e = self.force.evaluate(&self.u1, &mut self.f_int, k);
        let seconds = t0.elapsed().as_secs_f64();
        if tangent {
            self.tangent_ready = true;
            self.stats.tangent_evaluations += 1;
            self.stats.tangent_seconds += seconds;
        } else {
            self.stats.force_evaluations += 1;
            self.stats.force_seconds += seconds;
        }
        e
    }

    /// The body with the largest residual entry, and that entry. Collective.
    fn worst_body(&self) -> Result<(String, f64)> {
        let n = self.body_names.len();
        let mut local = vec![0.0f64; n];
        self.r.with_local_slice(|r| {
            for (i, x) in r.iter().enumerate() {
                let b =
                    (self.node_body.get(i / self.dim).copied().unwrap_or(0) as usize).min(n - 1);
                local[b] = local[b].max(x.abs());
            }
        })?;
        let mut all = vec![0.0f64; n];
        SimpleCommunicator::world().all_reduce_into(
            &local[..],
            &mut all[..],
            SystemOperation::max(),
        );
        let (b, x) =
            all.iter().enumerate().fold((0, 0.0), |m, (b, &x)| if x > m.1 { (b, x) } else { m });
        Ok((self.body_names[b].clone(), x))
    }

    /// One step: `s.du` from its first guess to the solution, with the contact solver
    /// inside each iteration when there is one. Collective.
    pub fn step<'c>(
        &mut self,
        mut s: StepInputs,
        mut contact: Option<&mut (dyn ContactSolver + 'c)>,
    ) -> Result<NewtonStep> {
        let opts = self.opts;
        let with_contact = contact.is_some();
        let lo = s.du.ownership_range().0;
        s.du.with_local_slice_mut(|du| {
            for (k, &d) in s.dirichlet.iter().enumerate() {
                du[d as usize - lo] = s.dirichlet_du[k];
            }
        })?;
        self.force.set_start(s.u)?;
        // A first guess that inverts an element is halved like a Newton correction.
        self.delta.copy_from(s.du)?;
        self.delta.with_local_slice_mut(|x| {
            for &d in s.dirichlet {
                x[d as usize - lo] = 0.0;
            }
        })?;
        self.c.zero()?;
        let where_ =
            |s: &StepInputs| format!("step {} (t = {})", s.step, crate::console::time(s.time));
        let mut iterations = 0;
        let mut ksp_iterations = 0;
        let mut halvings = 0;
        let mut halved = 0;
        let mut last_norm = f64::INFINITY;
        let mut used_kept = false;
        if with_contact {
            self.kept = false;
        }
        let mut history: Vec<f64> = Vec::new();
        let mut report: Option<StepContact> = None;
        let mut set_settled = false;
        // The tangent is evaluated with the force where it will be needed: at the first
        // guess, unless the last step needed no correction or a kept tangent is used. `fresh`:
        // the last evaluation has the tangent at the current iterate.
        let reuse_across = !with_contact && opts.tangent_reuse > 0.0 && self.kept;
        let mut want_tangent = !reuse_across && (self.stats.steps == 0 || self.stats.last > 0);
        // This step's tangent is in the step operator (Dirichlet rows eliminated).
        let mut step_tangent = false;
        loop {
            let fresh = want_tangent;
            want_tangent = false;
            let w1 = match self.evaluate(&s, fresh)? {
                Evaluation::Energies { w1, .. } => w1,
                Evaluation::Inverted(_) if halvings < Self::MAX_HALVINGS => {
                    // Back along the last correction: du -= delta/2.
                    self.delta.scale(0.5)?;
                    s.du.axpy(-1.0, &self.delta)?;
                    halvings += 1;
                    halved += 1;
                    continue;
                }
                Evaluation::Inverted(m) => {
                    return Err(Error::Solver(format!("{}: {m}", where_(&s))));
                }
            };
            let (norm, scale, error, reaction, work_scale) = self.residual(&mut s, with_contact)?;
            // The energy error next to the energy, or to the step's works when it is smaller
            // (a body starting at rest under loads).
            let energy_scale = s.energy.abs().max(work_scale).max(f64::MIN_POSITIVE);
            // A kept tangent that does not shrink the residual enough is replaced; one that
            // makes it grow, before any halving.
            let rate = if opts.tangent_reuse > 0.0 { opts.tangent_reuse } else { 0.1 };
            let stale = used_kept && norm > rate * last_norm;
            used_kept = false;
            if stale {
                self.kept = false;
                step_tangent = false;
            }
            // A contact solve is a full step of the constrained problem: not halved.
            if norm > last_norm
                && iterations > 0
                && halvings < Self::MAX_HALVINGS
                && !with_contact
                && !stale
            {
                self.delta.scale(0.5)?;
                s.du.axpy(-1.0, &self.delta)?;
                halvings += 1;
                halved += 1;
                continue;
            }
            history.push(norm);
            if opts.monitor && SimpleCommunicator::world().rank() == 0 {
                println!(
                    "step {} Newton {iterations}: residual {norm:.6e} (relative {:.3e}), energy error {:.3e} of the energy",
                    s.step,
                    norm / scale.max(f64::MIN_POSITIVE),
                    error.abs() / energy_scale
                );
            }
            // Round-off leaves the residual at a few eps times the terms that cancel in it,
            // and the internal force at about eps times the unit-strain forces (a rotated
            // body at rest: C = R^T R = I + O(eps)). At that floor the step is done when the
            // energy error is too, or when the residual no longer falls (round-off).
            let at_floor = norm <= 100.0 * f64::EPSILON * (scale + 2.0 * self.force.unit_force);
            let energy_ok = error.abs() <= opts.energy_rtol * energy_scale;
            let stalled = history.len() >= 2 && norm > 0.5 * history[history.len() - 2];
            let floor = at_floor && (energy_ok || stalled);
            let converged = ((norm <= opts.rtol * scale && energy_ok) || floor)
                // With contact: at least one constrained solve whose active set settled (its
                // inner loop converged on the linearization at the iterate before; with the
                // residual in tolerance that is the set of the iterate itself).
                && (!with_contact || (iterations > 0 && set_settled));
            if converged {
                self.stats.steps += 1;
                self.stats.last = iterations;
                self.stats.iterations += iterations;
                self.stats.max_iterations = self.stats.max_iterations.max(iterations);
                self.stats.halvings += halved;
                self.stats.max_energy_error =
                    self.stats.max_energy_error.max(error.abs() / energy_scale);
                return Ok(NewtonStep {
                    iterations,
                    ksp_iterations,
                    strain_energy: w1,
                    dirichlet_work: reaction,
                    contact: report,
                });
            }
            if iterations >= opts.max_it {
                let (body, worst) = self.worst_body()?;
                let last: Vec<String> =
                    history.iter().rev().take(3).rev().map(|x| format!("{x:.3e}")).collect();
                return Err(Error::Solver(format!(
                    "{}: Newton did not converge in {} iterations{}; the largest residual is in {body} ({worst:.3e}); last residuals {} against {:.3e} (-newton_rtol {:e}), energy error {:.3e} of the energy (-newton_energy_rtol {:e}); try a smaller tau or -newton_max_it",
                    where_(&s),
                    opts.max_it,
                    if report.as_ref().is_some_and(|r| r.cycled) {
                        " (the contact active set cycled on the last linearization)"
                    } else {
                        ""
                    },
                    last.join(", "),
                    opts.rtol * scale,
                    opts.rtol,
                    error.abs() / energy_scale,
                    opts.energy_rtol
                )));
            }
            last_norm = norm;
            // A chord iteration keeps the tangent and its preconditioner: with
            // `-newton_tangent_reuse`, or when only the energy error is left (the residual is
            // in tolerance: the step's tangent shrinks it by orders of magnitude at the cost
            // of a solve). Otherwise K_T = 4/tau^2 M + 2 T.
            let energy_only = norm <= opts.rtol * scale && step_tangent;
            let chord = !with_contact && ((opts.tangent_reuse > 0.0 && self.kept) || energy_only);
            if chord && energy_only {
                self.stats.energy_chords += 1;
            } else if chord {
                self.stats.kept_tangent += 1;
            } else {
                if !fresh {
                    match self.evaluate(&s, true)? {
                        Evaluation::Energies { .. } => {}
                        Evaluation::Inverted(m) => {
                            return Err(Error::Solver(format!("{}: {m}", where_(&s))))
                        }
                    }
                }
                s.k.copy_values_from(&self.inertia)?;
                s.k.axpy(2.0, &self.tangent, crate::petsc::Pattern::Same)?;
                if let Some(solver) = contact.as_deref_mut() {
                    let (rep, its) = self.contact_iteration(&mut s, solver, iterations)?;
                    ksp_iterations += its;
                    // A set taken from a cycle is not settled: another iteration.
                    set_settled = !rep.cycled;
                    if rep.cycled {
                        self.stats.cycled += 1;
                    }
                    report = Some(rep);
                    iterations += 1;
                    halvings = 0;
                    continue;
                }
                // Dirichlet rows and columns eliminated; delta_D = 0.
                s.k.zero_rows_columns(s.dirichlet, s.dirichlet_diag, None, None)?;
                s.ksp.set_operators(s.k, s.k)?;
                self.kept = true;
                step_tangent = true;
            }
            self.r.scale(-1.0)?;
            self.delta.zero()?;
            // Inexact Newton: the solve need only bring the linear error to a tenth of
            // Newton's tolerance (the iteration's quadratic term is below it near the
            // solution); never tighter than the solver's own rtol, never looser than 1e-2
            // (or that rtol, if it is looser).
            let base_rtol = s.ksp.rtol()?;
            let eta =
                (0.1 * opts.rtol * scale / norm.max(f64::MIN_POSITIVE)).min(1e-2).max(base_rtol);
            s.ksp.set_tolerances(Some(eta), None, None, None)?;
            let info = s.ksp.solve(&self.r, &mut self.delta);
            s.ksp.set_tolerances(Some(base_rtol), None, None, None)?;
            ksp_iterations += info.map_err(|e| in_iteration(e, &s, iterations))?.iterations;
            s.du.axpy(1.0, &self.delta)?;
            iterations += 1;
            halvings = 0;
            used_kept = chord;
        }
    }

    /// One Newton iteration with the contact solver inside: it sees the linearized step
    /// `K_T du = K_T du^k - r(du^k) [- 2 B^T lambda]` in the increment itself, as the linear
    /// step's, so its constraints and forces are those of the new increment. `s.k` holds the
    /// unconstrained `K_T`. Leaves `delta = du^{k+1} - du^k` (for an inverted iterate's
    /// halving) and the contact forces `c = 2 B^T lambda = rhs - K_T du^{k+1}` on the free
    /// rows. Returns the solver's step data and KSP iterations. Collective.
    fn contact_iteration(
        &mut self,
        s: &mut StepInputs,
        solver: &mut dyn ContactSolver,
        iterations: usize,
    ) -> Result<(StepContact, usize)> {
        let lo = s.du.ownership_range().0;
        s.k.mult(s.du, &mut self.rhs)?;
        self.rhs.axpy(-1.0, &self.r)?;
        self.rhs_free.copy_from(&self.rhs)?;
        s.k.zero_rows_columns(s.dirichlet, s.dirichlet_diag, Some(&*s.du), Some(&mut self.rhs))?;
        solver.operator_replaced(s.k)?;
        self.delta.copy_from(s.du)?;
        let system = StepSystem {
            k: s.k,
            ksp: s.ksp,
            rhs: &self.rhs,
            u: s.u,
            du: s.du,
            step: s.step,
            time: s.time,
            tau: s.tau,
            linearization: true,
        };
        let solved = solver.solve(system);
        let (rep, its) = solved.map_err(|e| in_iteration(e, s, iterations))?;
        self.delta.aypx(-1.0, s.du)?;
        // K_T unconstrained: 4/tau^2 M du + 2 T du.
        self.tangent.mult(s.du, &mut self.c)?;
        s.m.mult(s.du, &mut self.mdu)?;
        let ci = 4.0 / (s.tau * s.tau);
        Vector::with_slices([&self.rhs_free, &self.mdu], [&mut self.c], |[b, mdu], [c]| {
            for i in 0..c.len() {
                c[i] = b[i] - ci * mdu[i] - 2.0 * c[i];
            }
            for &d in s.dirichlet {
                c[d as usize - lo] = 0.0;
            }
        })?;
        Ok((rep, its))
    }

    /// Puts the free massless DOFs (`free`, local) in static equilibrium at the current state,
    /// `f_int,C(u) = f_C` with every other DOF held: Newton with the static tangent
    /// `d f_int(u)/du = 2 d f_int,alg(u, u)/d u_1` (the algorithmic force is symmetric in its
    /// two states), the held rows and columns eliminated (`diag` on their diagonal), on the
    /// step operator's matrix and solver (each step refills them). `u` is changed in place.
    /// Returns the largest change and the KSP iterations. Collective.
    #[allow(clippy::too_many_arguments)]
    pub fn static_massless(
        &mut self,
        k: &mut Matrix,
        ksp: &mut Ksp,
        u: &mut Vector,
        loads: Option<&Vector>,
        free: &[bool],
        diag: f64,
    ) -> Result<(f64, usize)> {
        self.kept = false;
        let (lo, _) = u.ownership_range();
        let held: Vec<i32> =
            (0..free.len()).filter(|&i| !free[i]).map(|i| (lo + i) as i32).collect();
        let start = u.duplicate()?;
        let mut start = start;
        start.copy_from(u)?;
        let mut its = 0;
        let mut first = None;
        for _ in 0..self.opts.max_it {
            self.force.set_start(u)?;
            let evaluation = self.force.evaluate(u, &mut self.f_int, Some(&mut self.tangent))?;
            self.tangent_ready = true;
            match evaluation {
                Evaluation::Energies { .. } => {}
                Evaluation::Inverted(m) => {
                    return Err(Error::Solver(format!("the massless layer's equilibrium: {m}")))
                }
            }
            self.r.copy_from(&self.f_int)?;
            if let Some(f) = loads {
                self.r.axpy(-1.0, f)?;
            }
            let mut scale = 0.0f64;
            self.r.with_local_slice_mut(|r| {
                for i in 0..r.len() {
                    if free[i] {
                        scale = scale.max(r[i].abs());
                    } else {
                        r[i] = 0.0;
                    }
                }
            })?;
            let norm = self.r.norm2()?;
            let reference = *first.get_or_insert(norm);
            let floor = 1e2 * f64::EPSILON * self.force.unit_force;
            if norm <= 1e-12 * reference || norm <= floor {
                break;
            }
            k.copy_values_from(&self.tangent)?;
            k.scale(2.0)?;
            k.zero_rows_columns(&held, diag, None, None)?;
            ksp.set_operators(k, k)?;
            self.r.scale(-1.0)?;
            self.delta.zero()?;
            its += ksp.solve(&self.r, &mut self.delta)?.iterations;
            u.axpy(1.0, &self.delta)?;
        }
        start.axpy(-1.0, u)?;
        Ok((start.norm_inf()?, its))
    }
}

/// A solver error of Newton iteration `iterations + 1` of the step, said so (the contact
/// solver's own messages stay as they are).
fn in_iteration(e: Error, s: &StepInputs, iterations: usize) -> Error {
    match e {
        Error::Solver(m) if !m.starts_with("contact") => Error::Solver(format!(
            "step {} (t = {}): Newton iteration {}: {m}",
            s.step,
            crate::console::time(s.time),
            iterations + 1
        )),
        other => other,
    }
}
