//! The step operator `K = 4/tau^2 M + A` of the midpoint rule, with Dirichlet rows and columns
//! eliminated, and its solver, set up once per run (PETSc tutorials' order: defaults, then
//! `KSPSetFromOptions`, then the `step_` prefix).

use crate::error::Result;
use crate::petsc::{Ksp, Matrix, NullSpace, Pattern};

/// Solver defaults for the step operator, applied before `KSPSetFromOptions` so that the
/// command line wins: plain `-ksp_*`/`-pc_*` options, and `-step_ksp_*`/`-step_pc_*` over them.
#[derive(Debug, Clone)]
pub struct StepSolverDefaults {
    pub ksp_type: String,
    pub pc_type: String,
    pub rtol: f64,
    pub factor_solver: Option<String>,
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
}

impl StepOperator {
    pub fn new(
        m: &Matrix,
        a: &Matrix,
        tau: f64,
        dirichlet_dofs: Vec<i32>,
        keep_free: bool,
        near_null_space: Option<&NullSpace>,
        defaults: &StepSolverDefaults,
    ) -> Result<StepOperator> {
        let mut k = a.duplicate(true)?;
        // Every mass matrix's pattern lies within the stiffness's (nodes sharing a cell; the
        // mass-free layer does not widen it, METHOD.md 3).
        k.axpy(4.0 / (tau * tau), m, Pattern::Subset)?;
        let k_free = if keep_free { Some(k.duplicate(true)?) } else { None };
        let mut diag = k.create_vecs()?.0;
        k.get_diagonal(&mut diag)?;
        let dirichlet_diag = diag.norm_inf()?.max(f64::MIN_POSITIVE);
        k.zero_rows_columns(&dirichlet_dofs, dirichlet_diag, None, None)?;
        k.set_option_symmetric(true)?;
        if let Some(ns) = near_null_space {
            k.set_near_null_space(ns)?;
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
        // The previous step's increment is a good first guess for an iterative solver (du
        // changes smoothly in time); a direct solve (preonly) must start from zero.
        let iterative = ksp.ksp_type()? != "preonly";
        ksp.set_initial_guess_nonzero(iterative)?;
        ksp.set_up()?;
        Ok(StepOperator { k, k_free, dirichlet_dofs, dirichlet_diag, ksp })
    }
}
