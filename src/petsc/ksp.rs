//! Linear solvers (PETSc `KSP` with its `PC`).

use super::conv::{cstring, from_cstr, petsc_bool, to_int, to_usize};
use super::ffi;
use super::init::{self, ensure_live};
use super::mat::Matrix;
use super::vec::Vector;
use crate::error::{Error, Result};
use std::ffi::CString;
use std::ptr;

/// Outcome of a converged [`Ksp::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveInfo {
    /// Iterations taken (1 for a direct solve with `preonly`).
    pub iterations: usize,
    /// Final (preconditioned, by default) residual norm as reported by KSP.
    pub residual_norm: f64,
    /// `KSPConvergedReason` (positive: converged).
    pub reason: i32,
}

/// An owned Krylov solver on `PETSC_COMM_WORLD` (`KSPDestroy` on drop).
///
/// Typical use: `new(prefix)`, `set_operators`, defaults via `set_type`/`set_pc_type`/...,
/// then `set_from_options()` LAST so the command line (`-<prefix>ksp_type ...`) wins.
pub struct Ksp {
    ksp: ffi::KSP,
    prefix: String,
    factor_solver: Option<CString>,
    /// The type of the preconditioner a shell wraps ([`Ksp::wrap_pc`]).
    wrapped: Option<String>,
}

impl Ksp {
    /// Creates a solver whose options are read with `prefix` (e.g. `"mass_"` reads
    /// `-mass_ksp_type`); an empty prefix reads the plain options.
    pub fn new(prefix: &str) -> Result<Ksp> {
        Ksp::create(init::Petsc::comm_world(), prefix)
    }

    /// A solver private to this rank (`MPI_COMM_SELF`), with options read with `prefix`.
    pub fn new_self(prefix: &str) -> Result<Ksp> {
        Ksp::create(init::Petsc::comm_self(), prefix)
    }

    fn create(comm: ffi::MPI_Comm, prefix: &str) -> Result<Ksp> {
        ensure_live()?;
        let mut ksp: ffi::KSP = ptr::null_mut();
        // SAFETY: PETSc is live; `comm` is a valid communicator; `ksp` is an out-pointer.
        chk!(ffi::KSPCreate(comm, &mut ksp))?;
        let mut out = Ksp { ksp, prefix: String::new(), factor_solver: None, wrapped: None };
        if !prefix.is_empty() {
            out.set_options_prefix(prefix)?;
        }
        Ok(out)
    }

    /// Changes the options prefix (also of the PC); the next `set_from_options` reads options
    /// with the new prefix.
    pub fn set_options_prefix(&mut self, prefix: &str) -> Result<()> {
        let p = cstring(prefix)?;
        // SAFETY: valid handle and C string (PETSc copies it).
        chk!(ffi::KSPSetOptionsPrefix(self.ksp, p.as_ptr()))?;
        self.prefix = prefix.to_owned();
        Ok(())
    }

    /// The raw handle. Ownership stays here.
    pub fn raw(&self) -> ffi::KSP {
        self.ksp
    }

    /// The preconditioner's handle (owned by the KSP).
    pub(super) fn pc_handle(&self) -> Result<ffi::PC> {
        self.pc()
    }

    pub(super) fn set_wrapped(&mut self, inner_type: String) {
        self.wrapped = Some(inner_type);
    }

    /// Whether a shell wraps the configured preconditioner ([`Ksp::wrap_pc`]).
    pub fn is_wrapped(&self) -> bool {
        self.wrapped.is_some()
    }

    fn pc(&self) -> Result<ffi::PC> {
        let mut pc: ffi::PC = ptr::null_mut();
        // SAFETY: valid handle; the PC stays owned by the KSP.
        chk!(ffi::KSPGetPC(self.ksp, &mut pc))?;
        Ok(pc)
    }

    /// Sets the operator `a` and the matrix `p` the preconditioner is built from (often the
    /// same). PETSc keeps references, so the matrices may be dropped before the solver.
    pub fn set_operators(&mut self, a: &Matrix, p: &Matrix) -> Result<()> {
        // SAFETY: valid handles; PETSc takes its own references.
        chk!(ffi::KSPSetOperators(self.ksp, a.raw(), p.raw()))
    }

    /// Krylov method, e.g. `"cg"`, `"gmres"`, `"preonly"`.
    pub fn set_type(&mut self, ksp_type: &str) -> Result<()> {
        let t = cstring(ksp_type)?;
        // SAFETY: valid handle and C string.
        chk!(ffi::KSPSetType(self.ksp, t.as_ptr()))
    }

    /// Preconditioner, e.g. `"jacobi"`, `"gamg"`, `"cholesky"`, `"lu"`.
    pub fn set_pc_type(&mut self, pc_type: &str) -> Result<()> {
        let t = cstring(pc_type)?;
        let pc = self.pc()?;
        // SAFETY: valid PC and C string.
        chk!(ffi::PCSetType(pc, t.as_ptr()))?;
        // The factor package only sticks to a factor PC: re-apply it after a type change.
        if let Some(s) = &self.factor_solver {
            // SAFETY: valid PC and C string; a no-op for non-factor PCs.
            chk!(ffi::PCFactorSetMatSolverType(pc, s.as_ptr()))?;
        }
        Ok(())
    }

    /// Factorization package for LU/Cholesky PCs, e.g. `"mumps"`. Remembered, so it applies
    /// whether called before or after [`set_pc_type`](Ksp::set_pc_type).
    pub fn set_pc_factor_solver_type(&mut self, solver: &str) -> Result<()> {
        let s = cstring(solver)?;
        let pc = self.pc()?;
        // SAFETY: valid PC and C string; PETSc copies the name.
        chk!(ffi::PCFactorSetMatSolverType(pc, s.as_ptr()))?;
        self.factor_solver = Some(s);
        Ok(())
    }

    /// The factorization package in use (e.g. `"mumps"`; `"petsc"` by default; empty for
    /// non-factor PCs).
    pub fn pc_factor_solver_type(&self) -> Result<String> {
        let pc = self.pc()?;
        let mut t: ffi::MatSolverType = ptr::null();
        // SAFETY: valid PC; PETSc owns the returned string (null for non-factor PCs).
        chk!(ffi::PCFactorGetMatSolverType(pc, &mut t))?;
        Ok(from_cstr(t))
    }

    /// The relative tolerance in force.
    pub fn rtol(&self) -> Result<f64> {
        let (mut rtol, mut atol, mut dtol, mut its) = (0.0, 0.0, 0.0, 0);
        // SAFETY: valid handle; out-pointers.
        chk!(ffi::KSPGetTolerances(self.ksp, &mut rtol, &mut atol, &mut dtol, &mut its))?;
        Ok(rtol)
    }

    /// The largest number of iterations in force.
    pub fn max_it(&self) -> Result<usize> {
        let (mut rtol, mut atol, mut dtol, mut its) = (0.0, 0.0, 0.0, 0);
        // SAFETY: valid handle; out-pointers.
        chk!(ffi::KSPGetTolerances(self.ksp, &mut rtol, &mut atol, &mut dtol, &mut its))?;
        Ok(to_usize(its))
    }

    /// Convergence tolerances; `None` keeps PETSc's current value (`PETSC_DEFAULT`).
    pub fn set_tolerances(
        &mut self,
        rtol: Option<f64>,
        atol: Option<f64>,
        dtol: Option<f64>,
        max_its: Option<usize>,
    ) -> Result<()> {
        let def = f64::from(ffi::PETSC_DEFAULT);
        let its = match max_its {
            Some(n) => to_int(n, "Ksp max_its")?,
            None => ffi::PETSC_DEFAULT,
        };
        // SAFETY: valid handle; PETSC_DEFAULT means "unchanged" for every argument.
        chk!(ffi::KSPSetTolerances(
            self.ksp,
            rtol.unwrap_or(def),
            atol.unwrap_or(def),
            dtol.unwrap_or(def),
            its
        ))
    }

    /// Use the incoming `x` of [`solve`](Ksp::solve) as initial guess (time stepping).
    pub fn set_initial_guess_nonzero(&mut self, nonzero: bool) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::KSPSetInitialGuessNonzero(self.ksp, petsc_bool(nonzero)))
    }

    /// Keep the preconditioner built so far when the operator's values change (PETSc's
    /// `-ksp_reuse_preconditioner`).
    pub fn set_reuse_preconditioner(&mut self, reuse: bool) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::KSPSetReusePreconditioner(self.ksp, petsc_bool(reuse)))
    }

    /// Reads `-<prefix>ksp_*` / `-<prefix>pc_*` options. Call it after the programmatic
    /// defaults so the command line overrides them.
    pub fn set_from_options(&mut self) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::KSPSetFromOptions(self.ksp))
    }

    /// Builds the preconditioner now (e.g. to time the factorization separately).
    pub fn set_up(&mut self) -> Result<()> {
        // SAFETY: valid handle with operators set.
        chk!(ffi::KSPSetUp(self.ksp))
    }

    /// Solves `A x = b`. A negative converged reason becomes `Error::Solver` naming the
    /// prefix, the reason and the iteration count.
    ///
    /// A nonzero initial guess whose residual is already beyond the divergence tolerance
    /// relative to `b` (`DIVERGED_DTOL` before the first iteration: `b` is tiny, e.g. a body
    /// that starts in equilibrium, while the guess is the last step's motion) is dropped and
    /// the solve starts again from zero.
    pub fn solve(&mut self, b: &Vector, x: &mut Vector) -> Result<SolveInfo> {
        let info = self.solve_once(b, x)?;
        if info.reason == ffi::KSPConvergedReason_KSP_DIVERGED_DTOL && info.iterations == 0 {
            x.zero()?;
            let again = self.solve_once(b, x)?;
            return self.checked(again);
        }
        self.checked(info)
    }

    fn solve_once(&mut self, b: &Vector, x: &mut Vector) -> Result<SolveInfo> {
        // SAFETY: valid handles; `b` and `x` are distinct by the borrow rules.
        chk!(ffi::KSPSolve(self.ksp, b.raw(), x.raw()))?;
        let mut reason: ffi::KSPConvergedReason = 0;
        let mut its: ffi::PetscInt = 0;
        let mut rnorm = 0.0;
        // SAFETY: valid handle; out-pointers.
        chk!(ffi::KSPGetConvergedReason(self.ksp, &mut reason))?;
        // SAFETY: as above.
        chk!(ffi::KSPGetIterationNumber(self.ksp, &mut its))?;
        // SAFETY: as above.
        chk!(ffi::KSPGetResidualNorm(self.ksp, &mut rnorm))?;
        Ok(SolveInfo { iterations: to_usize(its), residual_norm: rnorm, reason })
    }

    /// A negative converged reason as `Error::Solver`.
    fn checked(&self, info: SolveInfo) -> Result<SolveInfo> {
        let (reason, rnorm) = (info.reason, info.residual_norm);
        if reason < 0 {
            let mut s: *const std::os::raw::c_char = ptr::null();
            // SAFETY: valid handle; the returned string is a static PETSc constant.
            chk!(ffi::KSPGetConvergedReasonString(self.ksp, &mut s))?;
            let name = from_cstr(s);
            return Err(Error::Solver(format!(
                "KSP (prefix {:?}, {}/{}) diverged: {} ({reason}) after {} iterations, residual norm {:e}",
                self.prefix,
                self.ksp_type()?,
                self.pc_type()?,
                name,
                info.iterations,
                rnorm
            )));
        }
        Ok(info)
    }

    /// Builds the preconditioner alone now (a shell's set-up runs at once, not at the first
    /// solve). Collective.
    pub fn pc_set_up(&mut self) -> Result<()> {
        let pc = self.pc()?;
        // SAFETY: valid PC with operators set.
        chk!(ffi::PCSetUp(pc))
    }

    /// Applies the preconditioner (set up with the solver) to `r`: `z = B r`. For Krylov
    /// loops written outside PETSc (`time::cg`).
    pub fn pc_apply(&self, r: &Vector, z: &mut Vector) -> Result<()> {
        let pc = self.pc()?;
        // SAFETY: valid PC and vectors; `r` and `z` are distinct by the borrow rules.
        chk!(ffi::PCApply(pc, r.raw(), z.raw()))
    }

    /// The Krylov method in use (empty before it is set or defaulted at setup).
    pub fn ksp_type(&self) -> Result<String> {
        let mut t: ffi::KSPType = ptr::null();
        // SAFETY: valid handle; PETSc owns the returned string.
        chk!(ffi::KSPGetType(self.ksp, &mut t))?;
        Ok(from_cstr(t))
    }

    /// The preconditioner in use (empty before it is set or defaulted at setup); of a shell
    /// made by [`Ksp::wrap_pc`], the wrapped one's.
    pub fn pc_type(&self) -> Result<String> {
        if let Some(t) = &self.wrapped {
            return Ok(t.clone());
        }
        let pc = self.pc()?;
        let mut t: ffi::PCType = ptr::null();
        // SAFETY: valid PC; PETSc owns the returned string.
        chk!(ffi::PCGetType(pc, &mut t))?;
        Ok(from_cstr(t))
    }

    /// The options prefix given at creation.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// Prints the solver configuration to stdout (rank 0; collective).
    pub fn view(&self) -> Result<()> {
        // SAFETY: valid handle; a null viewer means stdout on the solver's communicator.
        chk!(ffi::KSPView(self.ksp, ptr::null_mut()))
    }
}

impl Drop for Ksp {
    fn drop(&mut self) {
        if !self.ksp.is_null() && init::is_live() {
            // SAFETY: this wrapper owns the handle; destroyed once, while PETSc is live.
            unsafe { ffi::KSPDestroy(&mut self.ksp) };
        }
    }
}
