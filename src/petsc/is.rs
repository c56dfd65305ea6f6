//! Index sets (PETSc `IS`), for scatters and row selections.

use super::conv::{to_int, to_usize};
use super::ffi;
use super::init::{self, ensure_live};
use crate::error::Result;
use std::ptr;

/// An owned general index set on `PETSC_COMM_WORLD` (`ISDestroy` on drop).
pub struct IndexSet {
    is: ffi::IS,
}

impl IndexSet {
    /// This rank's part of a distributed index set: a copy of `indices` (global numbers).
    pub fn from_global(indices: &[i32]) -> Result<IndexSet> {
        ensure_live()?;
        let n = to_int(indices.len(), "IndexSet length")?;
        let mut is: ffi::IS = ptr::null_mut();
        // SAFETY: `indices` holds n entries and PETSc copies them (PETSC_COPY_VALUES).
        chk!(ffi::ISCreateGeneral(
            init::Petsc::comm_world(),
            n,
            indices.as_ptr(),
            ffi::PetscCopyMode_PETSC_COPY_VALUES,
            &mut is
        ))?;
        Ok(IndexSet { is })
    }

    /// The raw handle. Ownership stays here.
    pub fn raw(&self) -> ffi::IS {
        self.is
    }

    /// Number of indices on this rank.
    pub fn local_len(&self) -> Result<usize> {
        let mut n: ffi::PetscInt = 0;
        // SAFETY: valid handle; out-pointer.
        chk!(ffi::ISGetLocalSize(self.is, &mut n))?;
        Ok(to_usize(n))
    }

    /// A copy of this rank's indices.
    pub fn indices(&self) -> Result<Vec<i32>> {
        let n = self.local_len()?;
        let mut p: *const ffi::PetscInt = ptr::null();
        // SAFETY: valid handle; out-pointer to PETSc-owned storage.
        chk!(ffi::ISGetIndices(self.is, &mut p))?;
        let v = if n == 0 || p.is_null() {
            Vec::new()
        } else {
            // SAFETY: PETSc returned `n` indices, valid until ISRestoreIndices below.
            unsafe { std::slice::from_raw_parts(p, n) }.to_vec()
        };
        // SAFETY: restores the array obtained above.
        chk!(ffi::ISRestoreIndices(self.is, &mut p))?;
        Ok(v)
    }
}

impl Drop for IndexSet {
    fn drop(&mut self) {
        if !self.is.is_null() && init::is_live() {
            // SAFETY: this wrapper owns the handle; destroyed once, while PETSc is live.
            unsafe { ffi::ISDestroy(&mut self.is) };
        }
    }
}
