//! The step operator `K = 4/tau^2 M + A` of the midpoint rule, with Dirichlet rows and columns
//! eliminated, and its solver, set up once per run (PETSc tutorials' order: defaults, then
//! `KSPSetFromOptions`, then the `step_` prefix).

use std::cell::RefCell;
use std::rc::Rc;

use super::cg::{Predictor, StepCg};
use super::choice::{self, Estimate, RunFacts, Solver};
use super::layer::LayerShell;
use crate::error::Result;
use crate::mass::MassMatrix;
use crate::petsc::{Ksp, Matrix, NullSpace, Vector};

/// Solver defaults for the step operator, applied before `KSPSetFromOptions` so that the
/// command line wins: plain `-ksp_*`/`-pc_*` options, and `-step_ksp_*`/`-step_pc_*` over them.
#[derive(Debug, Clone)]
pub struct StepSolverDefaults {
    pub ksp_type: String,
    pub pc_type: String,
    pub rtol: f64,
    pub factor_solver: Option<String>,
    /// The command line or the scene set `-ksp_reuse_preconditioner` or
    /// `-step_ksp_reuse_preconditioner`: PETSc's value holds (else a multigrid preconditioner
    /// is kept, see [`StepOperator::new`]).
    pub user_reuse_preconditioner: bool,
    /// The operator stays symmetric (no friction): PETSc is told so.
    pub symmetric: bool,
    /// The step's CG written out with its products kept (`time::cg`), for steps without
    /// contact; `None`: PETSc's `KSPSolve` and the products recomputed every step.
    pub reuse: Option<Reuse>,
    /// `-step_layer_around`: the mass-free layer's rows swept around Jacobi or a block
    /// preconditioner in PETSc's KSP too (`time::layer::LayerShell`).
    pub layer: bool,
    /// `K` may be stored in A's node blocks for CG + Jacobi (3D; not with mortar pairs,
    /// whose `T^T K T` PETSc forms only from AIJ).
    pub blocked: bool,
    /// The run, when the solver is chosen knowing it (`time::choice`; not when the scene or
    /// the command line names the solver): the choice is made once `K` is assembled and one
    /// product with it timed.
    pub run: Option<RunFacts>,
}

/// The options of the step's own CG (`-step_reuse`, `-step_reuse_refresh`,
/// `-step_predictor`, `-step_energy_rtol`).
#[derive(Debug, Clone, Copy)]
pub struct Reuse {
    /// Every this many steps `K x_0`, `A u` and `M v` are computed afresh, so that round-off
    /// in the updated products cannot build up (`Midpoint::DRIFT_TARGET`).
    pub refresh: usize,
    pub predictor: Predictor,
    /// The energy error a solve may leave, relative to the energy (`time::cg`).
    pub energy_rtol: f64,
    /// `-step_layer`: with Jacobi, the mass-free layer's massless rows get their block
    /// factored exactly (`time::layer`).
    pub layer: bool,
    /// `-step_layer_local`: each rank sweeps its own part of the layer, without the
    /// couplings across the partition and without communication (`LayerBlock::new` with
    /// `local`). `None`: in 3D (where the couplings across the cut cost no iterations and the layer's
    /// guess none either), not in 2D (where that guess saves half the iterations).
    pub layer_local: Option<bool>,
}

impl Default for Reuse {
    fn default() -> Self {
        Reuse {
            refresh: 16,
            predictor: Predictor::Extrapolate,
            energy_rtol: 1e-13,
            layer: true,
            layer_local: None,
        }
    }
}

impl Reuse {
    /// Whether each rank sweeps its own part of the layer, for `dim` DOFs per node.
    pub fn layer_local_for(&self, dim: usize) -> bool {
        self.layer_local.unwrap_or(dim == 3)
    }
}

/// How stiff a step is: the CFL number `c_p tau / h_min` of the pressure wave,
/// `c_p = sqrt((lambda + 2 mu) / rho)`, over the smallest edge. `K = 4/tau^2 M + A` is
/// dominated by its mass term while the number is small (Jacobi-preconditioned CG needs a few
/// iterations); above, the stiffness dominates and CG + Jacobi needs iterations in proportion
/// to the number, while multigrid does not.
#[derive(Debug, Clone, Copy)]
pub struct Regime {
    pub cfl: f64,
    pub wave_speed: f64,
    pub h_min: f64,
}

impl Regime {
    pub fn new(e: f64, nu: f64, rho: f64, tau: f64, h_min: f64) -> Regime {
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        let wave_speed = ((lambda + 2.0 * mu) / rho).sqrt();
        Regime { cfl: wave_speed * tau / h_min, wave_speed, h_min }
    }
}

/// Above these CFL numbers the step solver defaults to CG + GAMG (README "Step solver by
/// regime": measured crossovers on 2 ranks). With contact the operator changes with the
/// active set and GAMG recomputes its coarse operators each time, so Jacobi wins longer.
pub const GAMG_ABOVE_CFL: f64 = 10.0;
pub const GAMG_ABOVE_CFL_CONTACT: f64 = 30.0;
/// Contact against obstacles in 3D: block Jacobi with ILU(0) in K's node blocks up to this
/// CFL number (ILU in RCM order: a contact step 0.39-0.52 of Jacobi's time at 20, 0.31-0.32
/// of GAMG's at 33; ILU's iterations grow in proportion to the CFL number, GAMG's as its
/// logarithm: the crossover estimated from the measured 3.5 times GAMG's iterations at 33 in
/// the mesh's order; in RCM order 1.7 times, which would move it beyond 60, not measured).
pub const CONTACT_ILU_UP_TO_CFL: f64 = 60.0;

impl StepSolverDefaults {
    /// The defaults for a regime, and the reason, for the run's report.
    pub fn for_regime(r: &Regime, contact: bool) -> (StepSolverDefaults, String) {
        let mut d = StepSolverDefaults::default();
        let limit = if contact { GAMG_ABOVE_CFL_CONTACT } else { GAMG_ABOVE_CFL };
        let why = if r.cfl > limit {
            d.pc_type = "gamg".into();
            format!(
                "CFL c_p tau/h_min = {:.2} > {limit}: stiffness-dominated steps, multigrid",
                r.cfl
            )
        } else {
            format!("CFL c_p tau/h_min = {:.2} <= {limit}: Jacobi is cheapest", r.cfl)
        };
        (d, why)
    }
}

impl Default for StepSolverDefaults {
    fn default() -> Self {
        // Measured (README "Solver choice"): the step operator is dominated by 4/tau^2 M and
        // is very well conditioned, so CG with Jacobi needs only a few iterations.
        StepSolverDefaults {
            ksp_type: "cg".into(),
            pc_type: "jacobi".into(),
            rtol: 1e-10,
            factor_solver: None,
            user_reuse_preconditioner: false,
            symmetric: true,
            reuse: Some(Reuse::default()),
            layer: false,
            blocked: true,
            run: None,
        }
    }
}

/// `K = 4/tau^2 M + A` with Dirichlet rows and columns eliminated, plus its KSP.
pub struct StepOperator {
    /// The constrained operator the KSP solves with.
    pub k: Matrix,
    /// The unconstrained operator, kept only when Dirichlet values are non-zero (their
    /// columns move to the right-hand side every step).
    pub k_free: Option<Matrix>,
    /// Global Dirichlet DOFs owned by this rank.
    pub dirichlet_dofs: Vec<i32>,
    /// Diagonal value placed on Dirichlet rows (the operator's scale, keeps it well conditioned).
    pub dirichlet_diag: f64,
    pub ksp: Ksp,
    /// The step's own CG (steps without contact), when the KSP is CG and reuse is on.
    pub cg: Option<StepCg>,
    /// How often the kept products are computed afresh.
    pub refresh: usize,
    /// The choice made knowing the run (`StepSolverDefaults::run`): the solver, its
    /// estimates, the reason, and the seconds of the product with `K` it was based on.
    pub choice: Option<(Solver, Estimate, String, f64)>,
    /// With the layer's sweep around PETSc's preconditioner (`time::layer::LayerShell`):
    /// the layer's rows over all ranks and its solver, once set up.
    pub layer: Option<Rc<RefCell<Option<(usize, String)>>>>,
}

/// Whether `local` holds on any rank. Collective.
fn any_rank(local: bool) -> bool {
    use mpi::collective::SystemOperation;
    use mpi::traits::*;
    let mut any = 0i32;
    mpi::topology::SimpleCommunicator::world().all_reduce_into(
        &(local as i32),
        &mut any,
        SystemOperation::max(),
    );
    any != 0
}

impl StepOperator {
    pub fn new(
        m: &MassMatrix,
        a: &Matrix,
        tau: f64,
        dirichlet_dofs: Vec<i32>,
        keep_free: bool,
        near_null_space: Option<&dyn Fn() -> Result<NullSpace>>,
        defaults: &StepSolverDefaults,
    ) -> Result<StepOperator> {
        // K is AIJ first: multigrid, factorizations and the mortar's `T^T K T` need it
        // (a MatDuplicate copy of block AIJ keeps PETSc's generic block kernel, 1.7 times
        // slower: `Matrix::duplicate` rebuilds such copies). In 3D,
        // where the regime's solver is CG + Jacobi, K in A's 3 x 3 blocks: its products were
        // 1.4-1.5 times faster than AIJ's (4.6 against 6.6 ms at 266k DOFs), and a contact
        // step against an obstacle 1.3 times faster (its row edits are point-wise
        // `MatSetValues`; README "A step near the floor"). In 2D AIJ is as fast.
        // Contact against obstacles in 3D up to CFL 60: block Jacobi with ILU(0) in K's node
        // blocks (per rank; the factor as large as K, refactored when the active set
        // changes): a third of Jacobi's iterations for about two products' bytes each, and
        // fewer bytes than multigrid's few costly iterations (a contact step of the ball:
        // 0.39-0.52 of Jacobi's time at CFL 20 and 162k DOFs, 0.31-0.32 of GAMG's at CFL 33
        // and 950k DOFs with half the memory; README "A step near the floor").
        let contact_ilu = defaults.blocked
            && defaults.ksp_type == "cg"
            && defaults
                .run
                .is_some_and(|r| r.contact && r.dim == 3 && r.cfl <= CONTACT_ILU_UP_TO_CFL);
        let blocked = defaults.blocked
            && defaults.ksp_type == "cg"
            && (contact_ilu
                || defaults.pc_type == "jacobi"
                    && defaults.run.is_some_and(|r| {
                        r.dim == 3 && choice::iterative(r.cfl, r.contact) == Solver::Jacobi
                    }))
            && a.is_baij()?;
        let mut k = if blocked { a.duplicate(true)? } else { a.to_aij()? };
        m.add_to(&mut k, 4.0 / (tau * tau))?;
        let k_free = if keep_free { Some(k.duplicate(true)?) } else { None };
        let mut diag = k.create_vecs()?.0;
        k.get_diagonal(&mut diag)?;
        let dirichlet_diag = diag.norm_inf()?.max(f64::MIN_POSITIVE);
        k.zero_rows_columns(&dirichlet_dofs, dirichlet_diag, None, None)?;
        k.set_option_symmetric(defaults.symmetric)?;
        // The solver for the run's length, once one product with K is timed.
        let mut defaults = defaults.clone();
        let choice = match defaults.run {
            Some(run) => {
                let (mut x, mut y) = k.create_vecs()?;
                x.set(1.0)?;
                let matmult = time_product(&k, &x, &mut y, 5)?;
                let (solver, estimate, mut why) = choice::choose(&run, matmult);
                match solver {
                    Solver::Jacobi | Solver::Multigrid if contact_ilu && blocked => {
                        defaults.pc_type = "bjacobi".into();
                        let sub = "-step_sub_pc_type";
                        let order = "-step_sub_pc_factor_mat_ordering_type";
                        if !crate::petsc::Petsc::options_given(sub)? {
                            crate::petsc::Petsc::options_set(sub, Some("ilu"))?;
                            // Reverse Cuthill-McKee: ILU(0) in that order took 24-29% fewer
                            // iterations on the ball than in the mesh's (natural) order.
                            if !crate::petsc::Petsc::options_given(order)? {
                                crate::petsc::Petsc::options_set(order, Some("rcm"))?;
                            }
                        }
                        why = format!(
                            "CFL {:.3} <= {CONTACT_ILU_UP_TO_CFL}, contact: block Jacobi with ILU(0) in K's node blocks, RCM order",
                            run.cfl
                        );
                    }
                    Solver::Jacobi => defaults.pc_type = "jacobi".into(),
                    Solver::Multigrid => defaults.pc_type = "gamg".into(),
                    Solver::Cholesky => {
                        defaults.ksp_type = "preonly".into();
                        defaults.pc_type = "cholesky".into();
                        defaults.factor_solver = Some("mumps".into());
                    }
                }
                Some((solver, estimate, why, matmult))
            }
            None => None,
        };
        let defaults = &defaults;
        // K in A's blocks stays only for CG + Jacobi or block Jacobi (the choice may have
        // factored).
        if k.is_baij()? && !(defaults.ksp_type == "cg" && pointwise(&defaults.pc_type)) {
            k = k.to_aij()?;
            k.set_option_symmetric(defaults.symmetric)?;
            crate::phase::release_free_memory();
        }
        // Built without a prefix first so the plain -ksp_*/-pc_* options (the main solver's)
        // apply; then the prefix step_ is set and -step_ksp_*/-step_pc_* override them.
        let mut ksp = Ksp::new("")?;
        ksp.set_operators(&k, &k)?;
        ksp.set_type(&defaults.ksp_type)?;
        ksp.set_pc_type(&defaults.pc_type)?;
        if let Some(s) = &defaults.factor_solver {
            ksp.set_pc_factor_solver_type(s)?;
        }
        ksp.set_tolerances(Some(defaults.rtol), Some(1e-50), None, Some(10_000))?;
        ksp.set_from_options()?;
        ksp.set_options_prefix("step_")?;
        ksp.set_from_options()?;
        // A multigrid preconditioner is built once from the unconstrained operator and kept
        // when a contact solver rewrites rows near the contact: recomputing its coarse
        // operators at every active-set change cost more than the few extra iterations
        // (README "Step solver by regime"). `-step_ksp_reuse_preconditioner false` rebuilds.
        let multigrid = matches!(ksp.pc_type()?.as_str(), "gamg" | "hypre" | "ml" | "mg");
        // The rigid-body modes (dim (dim + 1) / 2 vectors) only for multigrid, which builds
        // its coarse spaces from them (before `set_up`); Jacobi and factorizations ignore them.
        if let Some(build) = near_null_space.filter(|_| multigrid) {
            k.set_near_null_space(&build()?)?;
        }
        if multigrid && !defaults.user_reuse_preconditioner {
            ksp.set_reuse_preconditioner(true)?;
        }
        // The previous step's increment is a good first guess for an iterative solver (du
        // changes smoothly in time); a direct solve (preonly) must start from zero.
        let iterative = ksp.ksp_type()? != "preonly";
        ksp.set_initial_guess_nonzero(iterative)?;
        ksp.set_up()?;
        let massless = massless_rows(m, &k)?;
        let cg = match defaults.reuse {
            Some(r) if ksp.ksp_type()? == "cg" => {
                Some(StepCg::new(&k, &ksp, ksp.rtol()?, &r, massless.clone())?)
            }
            _ => None,
        };
        // With `-step_layer_around` the solves through PETSc's KSP (contact steps; with a
        // preconditioner other than Jacobi, every step) sweep the layer's rows around that
        // preconditioner (`time::layer::LayerShell`), refactored when a contact solver
        // rewrites K.
        let pc = ksp.pc_type()?;
        let sweep = defaults.layer
            && ksp.ksp_type()? == "cg"
            && matches!(pc.as_str(), "jacobi" | "pbjacobi" | "bjacobi" | "ilu" | "icc" | "sor")
            && any_rank(!massless.is_empty());
        let contact_layer = if sweep {
            let info = Rc::new(RefCell::new(None));
            let local = defaults.reuse.unwrap_or_default().layer_local_for(k.block_size()?);
            let shell = LayerShell::new(massless, k.block_size()?, local, info.clone());
            ksp.wrap_pc(&format!("the mass-free layer's sweep around {pc}"), Box::new(shell))?;
            ksp.pc_set_up()?;
            Some(info)
        } else {
            None
        };
        let refresh = defaults.reuse.map_or(1, |r| r.refresh.max(1));
        Ok(StepOperator {
            k,
            k_free,
            dirichlet_dofs,
            dirichlet_diag,
            ksp,
            cg,
            refresh,
            choice,
            layer: contact_layer,
        })
    }
}

/// Local indices of the rows without mass (`M`'s diagonal exactly zero: the mass-free
/// layer's contact DOFs; none for `M` and the lumped mass).
fn massless_rows(m: &MassMatrix, k: &Matrix) -> Result<Vec<usize>> {
    let mut d = k.create_vecs()?.0;
    m.get_diagonal(&mut d)?;
    d.with_local_slice(|d| (0..d.len()).filter(|&i| d[i] == 0.0).collect())
}

/// Preconditioners that work on K in A's node blocks as fast as on AIJ (or faster).
fn pointwise(pc_type: &str) -> bool {
    matches!(pc_type, "jacobi" | "bjacobi")
}

/// Seconds of one product `y = k x`: the slowest rank's mean of `reps` after one. Collective.
/// (The run's summary reports it; the choice by run length bases its estimates on it.)
pub fn time_product(k: &Matrix, x: &Vector, y: &mut Vector, reps: usize) -> Result<f64> {
    use mpi::collective::SystemOperation;
    use mpi::traits::*;
    k.mult(x, y)?;
    let world = mpi::topology::SimpleCommunicator::world();
    world.barrier();
    let t0 = std::time::Instant::now();
    for _ in 0..reps.max(1) {
        k.mult(x, y)?;
    }
    let local = t0.elapsed().as_secs_f64() / reps.max(1) as f64;
    let mut t = 0.0;
    world.all_reduce_into(&local, &mut t, SystemOperation::max());
    Ok(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regime_uses_the_pressure_wave_speed() {
        // c_p^2 = (lambda + 2 mu) / rho = E (1 - nu) / (rho (1 + nu) (1 - 2 nu)).
        let r = Regime::new(100.0, 0.3, 1.0, 0.01, 0.02);
        let c = (100.0f64 * 0.7 / (1.3 * 0.4)).sqrt();
        assert!((r.wave_speed - c).abs() < 1e-12 * c);
        assert!((r.cfl - c * 0.01 / 0.02).abs() < 1e-12);
    }

    #[test]
    fn regime_picks_jacobi_until_the_crossover() {
        let at = |cfl: f64, contact| {
            let r = Regime { cfl, wave_speed: 1.0, h_min: 1.0 };
            StepSolverDefaults::for_regime(&r, contact).0.pc_type
        };
        assert_eq!(at(0.5, false), "jacobi");
        assert_eq!(at(GAMG_ABOVE_CFL * 1.01, false), "gamg");
        assert_eq!(at(GAMG_ABOVE_CFL * 1.01, true), "jacobi");
        assert_eq!(at(GAMG_ABOVE_CFL_CONTACT * 1.01, true), "gamg");
    }
}
