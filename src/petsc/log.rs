//! Timing, memory and profiling-stage helpers.

use super::conv::cstring;
use super::ffi;
use super::init::ensure_live;
use crate::error::Result;

/// Wall-clock seconds since an arbitrary origin (`MPI_Wtime`).
pub fn wtime() -> f64 {
    // SAFETY: MPI_Wtime has no preconditions beyond MPI being linked.
    unsafe { ffi::MPI_Wtime() }
}

/// Resident memory of this process in bytes (`PetscMemoryGetCurrentUsage`).
pub fn memory_current() -> Result<f64> {
    let mut m = 0.0;
    // SAFETY: out-pointer; works whether or not PETSc tracks the maximum.
    chk!(ffi::PetscMemoryGetCurrentUsage(&mut m))?;
    Ok(m)
}

/// Peak resident memory of this process in bytes, as sampled by PETSc since `Petsc::init`
/// (which enables the sampling with `PetscMemorySetGetMaximumUsage`).
pub fn memory_maximum() -> Result<f64> {
    let mut m = 0.0;
    // SAFETY: out-pointer; sampling was enabled in Petsc::init.
    chk!(ffi::PetscMemoryGetMaximumUsage(&mut m))?;
    Ok(m)
}

/// A named profiling stage for `-log_view` (assembly, factorization, time loop, ...).
#[derive(Debug, Clone, Copy)]
pub struct LogStage(ffi::PetscLogStage);

impl LogStage {
    /// Registers a stage (collective; do it once per name).
    pub fn register(name: &str) -> Result<LogStage> {
        ensure_live()?;
        let n = cstring(name)?;
        let mut st: ffi::PetscLogStage = 0;
        // SAFETY: valid C string (PETSc copies it); out-pointer.
        chk!(ffi::PetscLogStageRegister(n.as_ptr(), &mut st))?;
        Ok(LogStage(st))
    }

    /// Makes this the current stage until [`pop`](LogStage::pop).
    pub fn push(&self) -> Result<()> {
        // SAFETY: a registered stage id.
        chk!(ffi::PetscLogStagePush(self.0))
    }

    /// Returns to the previous stage.
    pub fn pop(&self) -> Result<()> {
        // SAFETY: pops the stage stack; PETSc errors if it is empty.
        chk!(ffi::PetscLogStagePop())
    }
}
