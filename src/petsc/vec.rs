//! Distributed vectors (PETSc `Vec`).

use super::conv::{check_len, to_int, to_usize};
use super::ffi;
use super::init::{self, ensure_live};
use crate::error::Result;
use std::ptr;

/// An owned PETSc vector on `PETSC_COMM_WORLD` (`VecDestroy` on drop).
///
/// Sizes and the ownership range are read once at creation: they never change for a `Vec`.
pub struct Vector {
    v: ffi::Vec,
    local: usize,
    global: usize,
    range: (usize, usize),
}

impl Vector {
    /// Creates a distributed vector with `local_n` owned entries (summing to `global_n`) and
    /// block size `block_size` (the number of dofs per node; 1 for scalar fields).
    pub fn new_mpi(local_n: usize, global_n: usize, block_size: usize) -> Result<Vector> {
        ensure_live()?;
        let n = to_int(local_n, "Vector local size")?;
        let gn = to_int(global_n, "Vector global size")?;
        let bs = to_int(block_size.max(1), "Vector block size")?;
        let mut v: ffi::Vec = ptr::null_mut();
        // SAFETY: PETSc is live; `v` is an out-pointer.
        chk!(ffi::VecCreate(init::Petsc::comm_world(), &mut v))?;
        // Own the handle right away so that a later failure still destroys it.
        let mut out = Vector { v, local: 0, global: 0, range: (0, 0) };
        // SAFETY: `v` is a freshly created Vec; VECSTANDARD is a NUL-terminated type name.
        chk!(ffi::VecSetSizes(v, n, gn))?;
        // SAFETY: as above; block size is set before the type so the layout uses it.
        chk!(ffi::VecSetBlockSize(v, bs))?;
        // SAFETY: as above.
        chk!(ffi::VecSetType(v, ffi::VECSTANDARD.as_ptr().cast()))?;
        out.read_layout()?;
        Ok(out)
    }

    /// A sequential vector of `n` entries private to this rank (`MPI_COMM_SELF`).
    pub fn new_seq(n: usize) -> Result<Vector> {
        ensure_live()?;
        let mut v: ffi::Vec = ptr::null_mut();
        // SAFETY: PETSc is live; `v` is an out-pointer.
        chk!(ffi::VecCreateSeq(
            init::Petsc::comm_self(),
            to_int(n, "Vector::new_seq size")?,
            &mut v
        ))?;
        Vector::from_raw(v)
    }

    /// Wraps a handle this module just created (takes ownership) and reads its layout.
    pub(crate) fn from_raw(v: ffi::Vec) -> Result<Vector> {
        let mut out = Vector { v, local: 0, global: 0, range: (0, 0) };
        out.read_layout()?;
        Ok(out)
    }

    /// A handle PETSc lends (a callback's argument): referenced here, so that dropping the
    /// wrapper only releases that reference.
    pub(crate) fn borrowed(v: ffi::Vec) -> Result<Vector> {
        // SAFETY: a valid Vec handle (a PetscObject); the reference is released by `Drop`.
        chk!(ffi::PetscObjectReference(v as ffi::PetscObject))?;
        Vector::from_raw(v)
    }

    fn read_layout(&mut self) -> Result<()> {
        let (mut n, mut gn, mut lo, mut hi) = (0, 0, 0, 0);
        // SAFETY: `self.v` is a valid Vec whose sizes are set; out-pointers are locals.
        chk!(ffi::VecGetLocalSize(self.v, &mut n))?;
        // SAFETY: as above.
        chk!(ffi::VecGetSize(self.v, &mut gn))?;
        // SAFETY: as above.
        chk!(ffi::VecGetOwnershipRange(self.v, &mut lo, &mut hi))?;
        self.local = to_usize(n);
        self.global = to_usize(gn);
        self.range = (to_usize(lo), to_usize(hi));
        Ok(())
    }

    /// The raw handle, for calls this wrapper does not cover. Ownership stays here.
    pub fn raw(&self) -> ffi::Vec {
        self.v
    }

    /// A new vector with the same layout; values are NOT copied (see [`copy_from`]).
    ///
    /// [`copy_from`]: Vector::copy_from
    pub fn duplicate(&self) -> Result<Vector> {
        let mut v: ffi::Vec = ptr::null_mut();
        // SAFETY: `self.v` is valid; `v` is an out-pointer.
        chk!(ffi::VecDuplicate(self.v, &mut v))?;
        Vector::from_raw(v)
    }

    /// `self = x` (same layout required).
    pub fn copy_from(&mut self, x: &Vector) -> Result<()> {
        // SAFETY: both handles are valid; `&mut self` excludes aliasing with `x`.
        chk!(ffi::VecCopy(x.v, self.v))
    }

    /// Sets every entry to `value`.
    pub fn set(&mut self, value: f64) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::VecSet(self.v, value))
    }

    /// Sets every entry to zero.
    pub fn zero(&mut self) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::VecZeroEntries(self.v))
    }

    /// Number of entries owned by this rank.
    pub fn local_size(&self) -> usize {
        self.local
    }

    /// Total number of entries.
    pub fn global_size(&self) -> usize {
        self.global
    }

    /// Global indices `[lo, hi)` owned by this rank.
    pub fn ownership_range(&self) -> (usize, usize) {
        self.range
    }

    /// Inserts (`add == false`) or adds (`add == true`) values at global indices (any rank's
    /// entries; off-rank ones are sent during [`assemble`](Vector::assemble)). Do not mix
    /// insert and add without an `assemble` in between.
    pub fn set_values(&mut self, idx: &[i32], vals: &[f64], add: bool) -> Result<()> {
        check_len("Vector::set_values values", idx.len(), vals.len())?;
        let n = to_int(idx.len(), "Vector::set_values count")?;
        let mode = if add { ffi::InsertMode_ADD_VALUES } else { ffi::InsertMode_INSERT_VALUES };
        // SAFETY: idx and vals hold n entries each; PETSc copies them.
        chk!(ffi::VecSetValues(self.v, n, idx.as_ptr(), vals.as_ptr(), mode))
    }

    /// Finishes `set_values` (collective): communicates off-rank entries.
    pub fn assemble(&mut self) -> Result<()> {
        // SAFETY: valid handle; Begin/End are paired.
        chk!(ffi::VecAssemblyBegin(self.v))?;
        // SAFETY: as above.
        chk!(ffi::VecAssemblyEnd(self.v))
    }

    /// Reads the owned entries through a slice; the array is restored even if `f` panics.
    pub fn with_local_slice<R>(&self, f: impl FnOnce(&[f64]) -> R) -> Result<R> {
        let mut p: *const f64 = ptr::null();
        // SAFETY: valid handle; `p` is an out-pointer.
        chk!(ffi::VecGetArrayRead(self.v, &mut p))?;
        struct Restore(ffi::Vec, *const f64);
        impl Drop for Restore {
            fn drop(&mut self) {
                // SAFETY: restores exactly the array obtained by VecGetArrayRead above.
                unsafe { ffi::VecRestoreArrayRead(self.0, &mut self.1) };
            }
        }
        let guard = Restore(self.v, p);
        let slice: &[f64] = if self.local == 0 || p.is_null() {
            &[]
        } else {
            // SAFETY: PETSc returned `local` contiguous owned entries, valid until restore,
            // which happens after `f` returns (the guard drops after `slice`'s last use).
            unsafe { std::slice::from_raw_parts(p, self.local) }
        };
        let r = f(slice);
        drop(guard);
        Ok(r)
    }

    /// Writes the owned entries through a slice; the array is restored even if `f` panics.
    pub fn with_local_slice_mut<R>(&mut self, f: impl FnOnce(&mut [f64]) -> R) -> Result<R> {
        let mut p: *mut f64 = ptr::null_mut();
        // SAFETY: valid handle; `p` is an out-pointer.
        chk!(ffi::VecGetArray(self.v, &mut p))?;
        struct Restore(ffi::Vec, *mut f64);
        impl Drop for Restore {
            fn drop(&mut self) {
                // SAFETY: restores exactly the array obtained by VecGetArray above.
                unsafe { ffi::VecRestoreArray(self.0, &mut self.1) };
            }
        }
        let guard = Restore(self.v, p);
        let slice: &mut [f64] = if self.local == 0 || p.is_null() {
            &mut []
        } else {
            // SAFETY: `local` contiguous owned entries, exclusively borrowed via `&mut self`,
            // valid until the restore after `f` returns.
            unsafe { std::slice::from_raw_parts_mut(p, self.local) }
        };
        let r = f(slice);
        drop(guard);
        Ok(r)
    }

    /// Reads the owned entries of `read` and writes those of `write` in one closure: loops that
    /// fuse several vector operations into one pass over memory (the step's CG and state
    /// update). The arrays are restored even if `f` panics; all vectors must have the same
    /// local size. The borrow rules keep a vector from being both read and written.
    pub fn with_slices<const R: usize, const W: usize, T>(
        read: [&Vector; R],
        write: [&mut Vector; W],
        f: impl FnOnce([&[f64]; R], [&mut [f64]; W]) -> T,
    ) -> Result<T> {
        struct Restore(Vec<(ffi::Vec, *mut f64, bool)>);
        impl Drop for Restore {
            fn drop(&mut self) {
                for (v, p, w) in self.0.iter_mut() {
                    // SAFETY: restores exactly the arrays obtained below, once each.
                    unsafe {
                        if *w {
                            ffi::VecRestoreArray(*v, p);
                        } else {
                            let mut q = *p as *const f64;
                            ffi::VecRestoreArrayRead(*v, &mut q);
                        }
                    }
                }
            }
        }
        let n = read.first().map(|v| v.local).or(write.first().map(|v| v.local)).unwrap_or(0);
        for l in read.iter().map(|v| v.local).chain(write.iter().map(|v| v.local)) {
            check_len("Vector::with_slices local sizes", n, l)?;
        }
        let mut guard = Restore(Vec::with_capacity(R + W));
        for v in &read {
            let mut p: *const f64 = ptr::null();
            // SAFETY: valid handle; `p` is an out-pointer; restored by the guard.
            chk!(ffi::VecGetArrayRead(v.v, &mut p))?;
            guard.0.push((v.v, p as *mut f64, false));
        }
        for v in &write {
            let mut p: *mut f64 = ptr::null_mut();
            // SAFETY: as above, for writing.
            chk!(ffi::VecGetArray(v.v, &mut p))?;
            guard.0.push((v.v, p, true));
        }
        let ptrs: Vec<*mut f64> = guard.0.iter().map(|g| g.1).collect();
        let slice = |p: *mut f64| -> *mut f64 {
            if n == 0 || p.is_null() {
                ptr::NonNull::dangling().as_ptr()
            } else {
                p
            }
        };
        // SAFETY: PETSc returned `n` contiguous owned entries per vector, valid until the
        // guard restores them after `f`; the written vectors are distinct `&mut` borrows, so
        // no slice aliases another that is written.
        let reads: [&[f64]; R] =
            std::array::from_fn(|i| unsafe { std::slice::from_raw_parts(slice(ptrs[i]), n) });
        let writes: [&mut [f64]; W] = std::array::from_fn(|i| unsafe {
            std::slice::from_raw_parts_mut(slice(ptrs[R + i]), n)
        });
        let r = f(reads, writes);
        drop(guard);
        Ok(r)
    }

    /// Dot product `self . x` (collective).
    pub fn dot(&self, x: &Vector) -> Result<f64> {
        let mut d = 0.0;
        // SAFETY: valid handles; `d` is an out-pointer.
        chk!(ffi::VecDot(self.v, x.v, &mut d))?;
        Ok(d)
    }

    fn norm(&self, t: ffi::NormType) -> Result<f64> {
        let mut n = 0.0;
        // SAFETY: valid handle; `n` is an out-pointer for a single norm.
        chk!(ffi::VecNorm(self.v, t, &mut n))?;
        Ok(n)
    }

    /// Euclidean norm (collective).
    pub fn norm2(&self) -> Result<f64> {
        self.norm(ffi::NormType_NORM_2)
    }

    /// Max-abs norm (collective).
    pub fn norm_inf(&self) -> Result<f64> {
        self.norm(ffi::NormType_NORM_INFINITY)
    }

    /// `self += alpha * x`.
    pub fn axpy(&mut self, alpha: f64, x: &Vector) -> Result<()> {
        // SAFETY: valid, distinct handles (`&mut self` vs `&x`).
        chk!(ffi::VecAXPY(self.v, alpha, x.v))
    }

    /// `self = x + alpha * self`.
    pub fn aypx(&mut self, alpha: f64, x: &Vector) -> Result<()> {
        // SAFETY: valid, distinct handles.
        chk!(ffi::VecAYPX(self.v, alpha, x.v))
    }

    /// `self = alpha * x + y`.
    pub fn waxpy(&mut self, alpha: f64, x: &Vector, y: &Vector) -> Result<()> {
        // SAFETY: valid handles; `self` is distinct from `x` and `y`.
        chk!(ffi::VecWAXPY(self.v, alpha, x.v, y.v))
    }

    /// `self *= alpha`.
    pub fn scale(&mut self, alpha: f64) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::VecScale(self.v, alpha))
    }

    /// `self[i] = x[i] * y[i]`.
    pub fn pointwise_mult(&mut self, x: &Vector, y: &Vector) -> Result<()> {
        // SAFETY: valid handles; `self` is distinct from `x` and `y`.
        chk!(ffi::VecPointwiseMult(self.v, x.v, y.v))
    }

    /// Sum of all entries (collective).
    pub fn sum(&self) -> Result<f64> {
        let mut s = 0.0;
        // SAFETY: valid handle; `s` is an out-pointer.
        chk!(ffi::VecSum(self.v, &mut s))?;
        Ok(s)
    }

    /// The whole vector on every rank (collective, O(global size) memory per rank: for tests
    /// and small outputs only).
    pub fn gather_all(&self) -> Result<Vec<f64>> {
        let mut ctx: ffi::VecScatter = ptr::null_mut();
        let mut all: ffi::Vec = ptr::null_mut();
        // SAFETY: valid handle; out-pointers for the scatter and the sequential copy.
        chk!(ffi::VecScatterCreateToAll(self.v, &mut ctx, &mut all))?;
        struct Scatter(ffi::VecScatter);
        impl Drop for Scatter {
            fn drop(&mut self) {
                // SAFETY: destroys the scatter created above, once.
                unsafe { ffi::VecScatterDestroy(&mut self.0) };
            }
        }
        let ctx = Scatter(ctx);
        let all = Vector::from_raw(all)?;
        let (ins, fwd) = (ffi::InsertMode_INSERT_VALUES, ffi::ScatterMode_SCATTER_FORWARD);
        // SAFETY: the scatter was made for exactly (self, all); Begin/End are paired.
        chk!(ffi::VecScatterBegin(ctx.0, self.v, all.v, ins, fwd))?;
        // SAFETY: as above.
        chk!(ffi::VecScatterEnd(ctx.0, self.v, all.v, ins, fwd))?;
        all.with_local_slice(|s| s.to_vec())
    }

    /// Values at global indices owned by this rank (PETSc errors on other ranks' entries).
    pub fn get_values(&self, idx: &[i32]) -> Result<Vec<f64>> {
        let n = to_int(idx.len(), "Vector::get_values count")?;
        let mut out = vec![0.0; idx.len()];
        // SAFETY: idx and out hold n entries each.
        chk!(ffi::VecGetValues(self.v, n, idx.as_ptr(), out.as_mut_ptr()))?;
        Ok(out)
    }
}

impl Drop for Vector {
    fn drop(&mut self) {
        if !self.v.is_null() && init::is_live() {
            // SAFETY: this wrapper owns the handle; destroyed once, while PETSc is live.
            unsafe { ffi::VecDestroy(&mut self.v) };
        }
    }
}
