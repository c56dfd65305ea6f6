//! The C glue every wrapper uses: PETSc error codes to `Result` (with the call, the location
//! and PETSc's message), checked integer and string conversions.

use super::ffi;
use crate::error::{Error, Result};
use std::ffi::{CStr, CString};

/// Maps a PETSc error code to `Result`, naming the call (last path segment) and location.
#[doc(hidden)]
pub fn check(code: ffi::PetscErrorCode, call: &str, file: &str, line: u32) -> Result<()> {
    if code == 0 {
        return Ok(());
    }
    // A call that failed because a callback written in Rust did: that callback's error.
    if let Some(e) = super::shell::take_failure() {
        return Err(e);
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

/// Fails with a clear message when two slices that must match in length do not.
pub(crate) fn check_len(what: &str, expected: usize, got: usize) -> Result<()> {
    if expected == got {
        Ok(())
    } else {
        Err(Error::Solver(format!("{what}: expected {expected} entries, got {got}")))
    }
}
