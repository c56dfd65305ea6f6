//! Preconditioners written in Rust around the one a KSP was configured with (PETSc's
//! `PCSHELL`): [`Ksp::wrap_pc`] moves the KSP's preconditioner inside a shell whose set-up
//! and application are a [`PcShell`]'s. PETSc calls the set-up whenever the operator changed
//! (a contact solver rewriting rows), so what the shell builds from the operator follows it
//! as the wrapped preconditioner's factors do.

use std::cell::RefCell;
use std::os::raw::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::ptr;

use super::ffi;
use super::init::{self, Petsc};
use super::ksp::Ksp;
use super::mat::Matrix;
use super::vec::Vector;
use crate::error::{Error, Result};

/// A preconditioner `B` around the wrapped one.
pub trait PcShell {
    /// The operator is new or changed: rebuild what depends on it (the wrapped
    /// preconditioner is set up already). Collective.
    fn set_up(&mut self, op: &Matrix) -> Result<()>;
    /// `z = B r`; `inner(s, y)` applies the wrapped preconditioner. Collective.
    fn apply(
        &mut self,
        r: &Vector,
        z: &mut Vector,
        inner: &mut dyn FnMut(&Vector, &mut Vector) -> Result<()>,
    ) -> Result<()>;
}

/// What the shell's callbacks get: the wrapped preconditioner (one reference held) and the
/// Rust side.
struct Context {
    inner: ffi::PC,
    shell: Box<dyn PcShell>,
}

thread_local! {
    /// The error a callback returned, handed to the `Result` of the PETSc call that failed
    /// because of it ([`super::conv::check`]).
    static FAILED: RefCell<Option<Error>> = const { RefCell::new(None) };
}

/// The error of the last failed callback, if one is waiting.
pub(crate) fn take_failure() -> Option<Error> {
    FAILED.with(|f| f.borrow_mut().take())
}

/// PETSc's `PETSC_ERR_LIB`: "error in library called by PETSc".
const ERR_LIB: ffi::PetscErrorCode = 76;

/// Runs a callback's body: no panic crosses into C, and an error is kept for the caller.
fn guarded(f: impl FnOnce() -> Result<()>) -> ffi::PetscErrorCode {
    let failure = match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => return 0,
        Ok(Err(e)) => e,
        Err(_) => Error::Solver("a preconditioner written in Rust (PCSHELL) panicked".into()),
    };
    FAILED.with(|f| *f.borrow_mut() = Some(failure));
    ERR_LIB
}

/// The shell's context.
///
/// # Safety
/// `pc` is a shell made by [`Ksp::wrap_pc`], whose context is a live `Context`; PETSc calls
/// the callbacks one at a time, so the reference is unique while a callback runs.
unsafe fn context<'a>(pc: ffi::PC) -> Result<&'a mut Context> {
    let mut ctx: *mut c_void = ptr::null_mut();
    // SAFETY: valid shell PC; PETSc writes the context pointer into `ctx`.
    chk!(ffi::PCShellGetContext(pc, (&mut ctx as *mut *mut c_void).cast()))?;
    if ctx.is_null() {
        return Err(Error::Solver("a shell preconditioner without its context".into()));
    }
    // SAFETY: set by `wrap_pc` from `Box::into_raw(Box<Context>)`, freed only by `destroy`.
    Ok(unsafe { &mut *ctx.cast::<Context>() })
}

unsafe extern "C" fn set_up(pc: ffi::PC) -> ffi::PetscErrorCode {
    guarded(|| {
        // SAFETY: PETSc calls this for the shell made by `wrap_pc`.
        let ctx = unsafe { context(pc)? };
        // SAFETY: the wrapped PC is valid while the context lives; PCSetUp rebuilds it only
        // if its operator changed.
        chk!(ffi::PCSetUp(ctx.inner))?;
        let (mut a, mut p): (ffi::Mat, ffi::Mat) = (ptr::null_mut(), ptr::null_mut());
        // SAFETY: valid PC; the operators stay owned by it.
        chk!(ffi::PCGetOperators(pc, &mut a, &mut p))?;
        let op = Matrix::borrowed(p)?;
        ctx.shell.set_up(&op)
    })
}

unsafe extern "C" fn apply(pc: ffi::PC, x: ffi::Vec, y: ffi::Vec) -> ffi::PetscErrorCode {
    guarded(|| {
        // SAFETY: as in `set_up`.
        let ctx = unsafe { context(pc)? };
        let r = Vector::borrowed(x)?;
        let mut z = Vector::borrowed(y)?;
        let inner = ctx.inner;
        let mut wrapped = |s: &Vector, t: &mut Vector| -> Result<()> {
            // SAFETY: the wrapped PC is set up (PCApply sets it up otherwise); distinct vectors.
            chk!(ffi::PCApply(inner, s.raw(), t.raw()))
        };
        ctx.shell.apply(&r, &mut z, &mut wrapped)
    })
}

unsafe extern "C" fn destroy(pc: ffi::PC) -> ffi::PetscErrorCode {
    guarded(|| {
        // SAFETY: as in `set_up`; the box is taken back once, here, when PETSc destroys the
        // shell.
        let ctx = unsafe { context(pc)? };
        // SAFETY: made by `Box::into_raw` in `wrap_pc`.
        let mut ctx = unsafe { Box::from_raw(ctx as *mut Context) };
        // SAFETY: clear the pointer so that nothing can reach the freed context.
        chk!(ffi::PCShellSetContext(pc, ptr::null_mut()))?;
        if init::is_live() {
            // SAFETY: the reference `wrap_pc` took on the wrapped PC.
            chk!(ffi::PCDestroy(&mut ctx.inner))?;
        }
        Ok(())
    })
}

impl Ksp {
    /// Moves this solver's preconditioner (configured and with its operators) inside a
    /// shell that applies `shell` around it, named `name` in `-ksp_view`. [`Ksp::pc_type`]
    /// then reports the wrapped type. Collective; call after `set_from_options` (options
    /// read later would replace the shell).
    pub fn wrap_pc(&mut self, name: &str, shell: Box<dyn PcShell>) -> Result<()> {
        let inner_type = self.pc_type()?;
        let inner = self.pc_handle()?;
        let mut pc: ffi::PC = ptr::null_mut();
        // SAFETY: PETSc is live; out-pointer.
        chk!(ffi::PCCreate(Petsc::comm_world(), &mut pc))?;
        // From here `pc` is released on every path: PCDestroy frees the context once the
        // destroy callback is set.
        let made = (|| -> Result<()> {
            // SAFETY: fresh PC; PCSHELL is a NUL-terminated type name.
            chk!(ffi::PCSetType(pc, c"shell".as_ptr()))?;
            // The wrapped PC outlives the KSP's hold on it: one reference for the context.
            // SAFETY: valid PC handle (a PetscObject).
            chk!(ffi::PetscObjectReference(inner as ffi::PetscObject))?;
            let ctx = Box::into_raw(Box::new(Context { inner, shell }));
            // SAFETY: valid shell PC; the context lives until `destroy`.
            chk!(ffi::PCShellSetContext(pc, ctx.cast()))?;
            // SAFETY: as above; the callbacks match PETSc's signatures.
            chk!(ffi::PCShellSetDestroy(pc, Some(destroy)))?;
            // SAFETY: as above.
            chk!(ffi::PCShellSetSetUp(pc, Some(set_up)))?;
            // SAFETY: as above.
            chk!(ffi::PCShellSetApply(pc, Some(apply)))?;
            let label = super::conv::cstring(name)?;
            // SAFETY: valid shell PC and C string (PETSc copies it).
            chk!(ffi::PCShellSetName(pc, label.as_ptr()))?;
            let (mut a, mut p): (ffi::Mat, ffi::Mat) = (ptr::null_mut(), ptr::null_mut());
            // SAFETY: valid PCs; the operators are referenced by the shell too.
            chk!(ffi::PCGetOperators(inner, &mut a, &mut p))?;
            // SAFETY: as above.
            chk!(ffi::PCSetOperators(pc, a, p))?;
            // SAFETY: valid KSP and PC; the KSP takes its own reference and drops the old PC's.
            chk!(ffi::KSPSetPC(self.raw(), pc))
        })();
        // SAFETY: our creation reference (the KSP holds its own if it took the shell).
        let destroyed = chk!(ffi::PCDestroy(&mut pc));
        made?;
        destroyed?;
        self.set_wrapped(inner_type);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failing_callback_keeps_its_error_and_returns_a_petsc_code() {
        let code = guarded(|| Err(Error::Solver("the layer could not be factored".into())));
        assert_eq!(code, ERR_LIB);
        let e = take_failure().expect("kept");
        assert!(e.to_string().contains("the layer could not be factored"), "{e}");
        assert!(take_failure().is_none());
        assert_eq!(guarded(|| Ok(())), 0);
        let code = guarded(|| panic!("no unwinding into C"));
        assert_eq!(code, ERR_LIB);
        assert!(take_failure().expect("kept").to_string().contains("panicked"));
    }
}
