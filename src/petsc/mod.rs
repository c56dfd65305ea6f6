//! Safe wrappers over the PETSc objects the solver uses (Vec, Mat, KSP, IS, MatNullSpace).
//!
//! This module is the only place in the solver with `unsafe`. Every PETSc call goes through
//! `chk!`, which turns a non-zero `PetscErrorCode` into
//! `crate::error::Error::Petsc` naming the call and the source line.
//!
//! Lifetimes: [`Petsc`] is the init guard. Every handle ([`Vector`], [`Matrix`], [`Ksp`],
//! [`NullSpace`], [`IndexSet`]) must be dropped before it, so declare the guard first in
//! `main` (after the `mpi::initialize()` universe) and it drops last. Handles are `!Send` and
//! `!Sync` (they hold raw pointers): PETSc objects are not thread-safe.
//! All objects live on `PETSC_COMM_WORLD`.

/// Calls one PETSc function and maps a non-zero error code to `Error::Petsc`.
///
/// Usage: `chk!(ffi::MatMult(a, x, y))?`. The call itself is `unsafe`; each call site states
/// why it is sound in a `// SAFETY:` comment.
macro_rules! chk {
    ($($f:ident)::+ ( $($arg:expr),* $(,)? )) => {{
        // SAFETY: the caller's `// SAFETY:` comment covers this call's arguments.
        #[allow(unused_unsafe)]
        let code: $crate::petsc::ffi::PetscErrorCode = unsafe { $($f)::+($($arg),*) };
        $crate::petsc::conv::check(code, stringify!($($f)::+), file!(), line!())
    }};
}

#[doc(hidden)]
pub mod conv;
mod csr;
pub mod ffi;
mod init;
mod is;
mod ksp;
mod log;
mod mat;
mod options;
mod scatter;
mod shell;
mod vec;

pub use csr::{CsrBlock, CsrBlocks};
pub use init::Petsc;
pub use is::IndexSet;
pub use ksp::{Ksp, SolveInfo};
pub use log::{memory_current, memory_maximum, wtime, LogStage};
pub use mat::{MatNonzeroInfo, Matrix, NullSpace, Pattern};
pub use options::OptionsBlock;
pub use scatter::Scatter;
pub use shell::PcShell;
pub use vec::Vector;
