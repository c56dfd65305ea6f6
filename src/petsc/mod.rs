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

use crate::error::{Error, Result};
use std::ffi::{CStr, CString};

/// Calls one PETSc function and maps a non-zero error code to `Error::Petsc`.
///
/// Usage: `chk!(ffi::MatMult(a, x, y))?`. The call itself is `unsafe`; each call site states
/// why it is sound in a `// SAFETY:` comment.
macro_rules! chk {
    ($($f:ident)::+ ( $($arg:expr),* $(,)? )) => {{
        // SAFETY: the caller's `// SAFETY:` comment covers this call's arguments.
        #[allow(unused_unsafe)]
        let code: $crate::petsc::ffi::PetscErrorCode = unsafe { $($f)::+($($arg),*) };
        $crate::petsc::check(code, stringify!($($f)::+), file!(), line!())
    }};
}

pub mod ffi;
mod init;
mod is;
mod ksp;
mod log;
mod mat;
mod scatter;
mod vec;

pub use init::Petsc;
pub use is::IndexSet;
pub use ksp::{Ksp, SolveInfo};
pub use log::{memory_current, memory_maximum, wtime, LogStage};
pub use mat::{MatNonzeroInfo, Matrix, NullSpace, Pattern};
pub use scatter::Scatter;
pub use vec::Vector;

/// Maps a PETSc error code to `Result`, naming the call (last path segment) and location.
#[doc(hidden)]
pub fn check(code: ffi::PetscErrorCode, call: &str, file: &str, line: u32) -> Result<()> {
    if code == 0 {
        return Ok(());
    }
    let call = call.rsplit("::").next().unwrap_or(call).trim();
    Err(Error::Petsc {
        call: call.to_owned(),
        code,
        location: format!("{file}:{line}"),
        message: error_message(code),
    })
}

/// PETSc's text for an error: the specific message of the failing call if PETSc recorded one
/// (e.g. "Unable to find requested KSP type nonsense"), else the generic text of the code.
fn error_message(code: ffi::PetscErrorCode) -> String {
    let mut text: *const std::os::raw::c_char = std::ptr::null();
    let mut specific: *mut std::os::raw::c_char = std::ptr::null_mut();
    // SAFETY: PetscErrorMessage only writes the two out-pointers, which point to static or
    // PETSc-owned strings that stay valid while we copy them.
    let ok = unsafe { ffi::PetscErrorMessage(code, &mut text, &mut specific) } == 0;
    let read = |p: *const std::os::raw::c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: non-null, NUL-terminated C string from PETSc.
            unsafe { CStr::from_ptr(p) }.to_string_lossy().trim().replace('\n', " ")
        }
    };
    if !ok {
        return String::new();
    }
    let s = read(specific);
    if s.is_empty() {
        read(text)
    } else {
        s
    }
}

/// Converts a size or index to a 32-bit `PetscInt`, failing instead of truncating.
pub(crate) fn to_int(n: usize, what: &str) -> Result<ffi::PetscInt> {
    ffi::PetscInt::try_from(n)
        .map_err(|_| Error::Solver(format!("{what} = {n} does not fit a 32-bit PetscInt")))
}

/// Converts a PETSc size (never negative once set) back to `usize`.
pub(crate) fn to_usize(n: ffi::PetscInt) -> usize {
    usize::try_from(n).unwrap_or(0)
}

pub(crate) fn petsc_bool(b: bool) -> ffi::PetscBool {
    if b {
        ffi::PetscBool_PETSC_TRUE
    } else {
        ffi::PetscBool_PETSC_FALSE
    }
}

/// Makes a C string for a PETSc name/option; interior NULs are a caller bug reported as error.
pub(crate) fn cstring(s: &str) -> Result<CString> {
    CString::new(s).map_err(|_| Error::Solver(format!("string {s:?} contains a NUL byte")))
}

/// Copies a (possibly null) C string owned by PETSc into a `String`.
pub(crate) fn from_cstr(p: *const std::os::raw::c_char) -> String {
    if p.is_null() {
        return String::new();
    }
    // SAFETY: PETSc returned a valid NUL-terminated string that outlives this copy.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

/// Errors unless PETSc is initialized and not finalized: creating or destroying objects
/// outside that window is undefined behaviour in C, so constructors check it first.
pub(crate) fn ensure_live() -> Result<()> {
    if init::is_live() {
        Ok(())
    } else {
        Err(Error::Petsc {
            call: "PetscInitialized (Petsc::init not called, or PETSc already finalized)".into(),
            code: 73, // PETSC_ERR_ORDER: object in wrong state
            location: format!("{}:{}", file!(), line!()),
            message: String::new(),
        })
    }
}

/// Fails with a clear message when two slices that must match in length do not.
pub(crate) fn check_len(what: &str, expected: usize, got: usize) -> Result<()> {
    if expected == got {
        Ok(())
    } else {
        Err(Error::Solver(format!("{what}: expected {expected} entries, got {got}")))
    }
}
