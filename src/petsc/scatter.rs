//! Scatters between distributed vectors (PETSc `VecScatter`): to natural (gmsh) node order for
//! output, and to the ghosted values an element loop needs.

use super::ffi;
use super::init::{self, ensure_live};
use super::is::IndexSet;
use super::vec::Vector;
use crate::error::Result;
use std::ptr;

/// An owned `VecScatter` from entries `from_idx` of one vector to entries `to_idx` of another
/// (both global indices, listed by the rank that receives them). `VecScatterDestroy` on drop.
pub struct Scatter {
    sc: ffi::VecScatter,
}

impl Scatter {
    pub fn new(from: &Vector, from_idx: &[i32], to: &Vector, to_idx: &[i32]) -> Result<Scatter> {
        ensure_live()?;
        let is_from = IndexSet::from_global(from_idx)?;
        let is_to = IndexSet::from_global(to_idx)?;
        let mut sc: ffi::VecScatter = ptr::null_mut();
        // SAFETY: all handles are valid; `sc` is an out-pointer. The index sets are copied.
        chk!(ffi::VecScatterCreate(from.raw(), is_from.raw(), to.raw(), is_to.raw(), &mut sc))?;
        Ok(Scatter { sc })
    }

    /// `to[to_idx] = from[from_idx]` (INSERT_VALUES, forward).
    pub fn forward(&mut self, from: &Vector, to: &mut Vector) -> Result<()> {
        self.scatter(from, to, ffi::ScatterMode_SCATTER_FORWARD, ffi::InsertMode_INSERT_VALUES)
    }

    /// `to[to_idx] += from[from_idx]` (ADD_VALUES, forward): entries listed several times (by
    /// one rank or by several) are summed, which is how element contributions to shared nodes
    /// are assembled.
    pub fn forward_add(&mut self, from: &Vector, to: &mut Vector) -> Result<()> {
        self.scatter(from, to, ffi::ScatterMode_SCATTER_FORWARD, ffi::InsertMode_ADD_VALUES)
    }

    /// The reverse direction: `from[from_idx] = to[to_idx]` (INSERT_VALUES).
    pub fn reverse(&mut self, to: &Vector, from: &mut Vector) -> Result<()> {
        self.scatter(to, from, ffi::ScatterMode_SCATTER_REVERSE, ffi::InsertMode_INSERT_VALUES)
    }

    /// The reverse direction, summed: `from[from_idx] += to[to_idx]` (ADD_VALUES): element
    /// contributions gathered at the nodes of a rank's cells go to their owners' rows.
    pub fn reverse_add(&mut self, to: &Vector, from: &mut Vector) -> Result<()> {
        self.scatter(to, from, ffi::ScatterMode_SCATTER_REVERSE, ffi::InsertMode_ADD_VALUES)
    }

    fn scatter(
        &mut self,
        x: &Vector,
        y: &mut Vector,
        mode: ffi::ScatterMode,
        insert: ffi::InsertMode,
    ) -> Result<()> {
        // SAFETY: the vectors have the layouts the scatter was created with (in the order
        // `mode` expects); `&mut` excludes aliasing.
        chk!(ffi::VecScatterBegin(self.sc, x.raw(), y.raw(), insert, mode))?;
        // SAFETY: as above; completes the scatter begun above.
        chk!(ffi::VecScatterEnd(self.sc, x.raw(), y.raw(), insert, mode))
    }
}

impl Drop for Scatter {
    fn drop(&mut self) {
        if !self.sc.is_null() && init::is_live() {
            // SAFETY: this wrapper owns the handle; destroyed once, while PETSc is live.
            unsafe { ffi::VecScatterDestroy(&mut self.sc) };
        }
    }
}
