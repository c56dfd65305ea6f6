//! The local rows of an assembled AIJ matrix as PETSc stores them: a diagonal block (this
//! rank's columns) and, on several ranks, an off-diagonal block whose columns are numbered
//! through `colmap` (the other ranks' columns in ascending order). Refilling a matrix of a
//! fixed pattern through these arrays skips `MatSetValues`' column search per entry.

use std::ptr;

use super::conv::petsc_bool;
use super::ffi;
use super::mat::Matrix;
use crate::error::{Error, Result};

/// The CSR structure of one block: row starts (`n + 1`) and column indices.
#[derive(Debug, Clone, Default)]
pub struct CsrBlock {
    pub row_start: Vec<i32>,
    pub cols: Vec<i32>,
}

/// The CSR structure of a matrix's local rows ([`Matrix::csr_blocks`]).
#[derive(Debug, Clone, Default)]
pub struct CsrBlocks {
    /// Columns local to this rank (global column minus the first owned one).
    pub diag: CsrBlock,
    /// Columns of other ranks, as positions in `colmap` (absent on one rank).
    pub off: Option<CsrBlock>,
    /// The global column of each off-diagonal position, ascending.
    pub colmap: Vec<i32>,
}

/// An AIJ matrix's diagonal block, and on several ranks its off-diagonal block with the
/// column map (lent by PETSc).
type AijBlocks = (ffi::Mat, Option<(ffi::Mat, *const i32)>);

impl Matrix {
    /// The blocks of an AIJ matrix, `None` for any other storage.
    fn aij_blocks(&self) -> Result<Option<AijBlocks>> {
        match self.type_name()?.as_str() {
            "seqaij" => Ok(Some((self.raw(), None))),
            "mpiaij" => {
                let (mut d, mut o, mut colmap): (ffi::Mat, ffi::Mat, *const i32) =
                    (ptr::null_mut(), ptr::null_mut(), ptr::null());
                // SAFETY: valid MPIAIJ handle; PETSc lends the blocks and the map (no
                // reference taken: they live as long as the matrix).
                chk!(ffi::MatMPIAIJGetSeqAIJ(self.raw(), &mut d, &mut o, &mut colmap))?;
                Ok(Some((d, Some((o, colmap)))))
            }
            _ => Ok(None),
        }
    }

    /// The CSR structure of this assembled matrix's local rows, or `None` if it is not AIJ.
    pub fn csr_blocks(&self) -> Result<Option<CsrBlocks>> {
        let Some((d, off)) = self.aij_blocks()? else { return Ok(None) };
        let diag = row_ij(d)?;
        let (off, colmap) = match off {
            None => (None, Vec::new()),
            Some((o, map)) => {
                let block = row_ij(o)?;
                let (_, n_cols) = seq_size(o)?;
                // SAFETY: PETSc's column map of the off-diagonal block has one entry per
                // column of that block.
                let colmap = unsafe { std::slice::from_raw_parts(map, n_cols) }.to_vec();
                (Some(block), colmap)
            }
        };
        Ok(Some(CsrBlocks { diag, off, colmap }))
    }

    /// Lends the values of the diagonal and off-diagonal blocks (empty on one rank) in the
    /// order of `layout` (this matrix's [`Matrix::csr_blocks`], its pattern unchanged since),
    /// then assembles the matrix (its state advances, so solvers see the change).
    /// Collective. `Err` if the matrix is not AIJ.
    pub fn with_csr_values_mut<R>(
        &mut self,
        layout: &CsrBlocks,
        f: impl FnOnce(&mut [f64], &mut [f64]) -> R,
    ) -> Result<R> {
        let Some((d, off)) = self.aij_blocks()? else {
            return Err(Error::Internal("csr values of a matrix that is not AIJ".into()));
        };
        let len = |b: &CsrBlock| b.row_start.last().copied().unwrap_or(0).max(0) as usize;
        let (dv, dn) = (values(d)?, len(&layout.diag));
        let (ov, on) = match (off, &layout.off) {
            (Some((o, _)), Some(b)) => (values(o)?, len(b)),
            (None, None) => (ptr::null_mut(), 0),
            _ => return Err(Error::Internal("csr values: the layout is another matrix's".into())),
        };
        let out = {
            // SAFETY: PETSc lends `dn` (`on`) values of the blocks until they are restored
            // below; the slices do not outlive this block.
            let ds = unsafe { std::slice::from_raw_parts_mut(dv, dn) };
            let os: &mut [f64] =
                if on > 0 { unsafe { std::slice::from_raw_parts_mut(ov, on) } } else { &mut [] };
            f(ds, os)
        };
        let mut dv = dv;
        // SAFETY: the array lent above.
        chk!(ffi::MatSeqAIJRestoreArray(d, &mut dv))?;
        if let Some((o, _)) = off {
            let mut ov = ov;
            // SAFETY: as above.
            chk!(ffi::MatSeqAIJRestoreArray(o, &mut ov))?;
        }
        self.assemble()?;
        Ok(out)
    }
}

fn seq_size(m: ffi::Mat) -> Result<(usize, usize)> {
    let (mut r, mut c) = (0, 0);
    // SAFETY: valid sequential Mat; out-pointers are locals.
    chk!(ffi::MatGetLocalSize(m, &mut r, &mut c))?;
    Ok((r.max(0) as usize, c.max(0) as usize))
}

fn values(m: ffi::Mat) -> Result<*mut f64> {
    let mut v: *mut f64 = ptr::null_mut();
    // SAFETY: valid SeqAIJ handle; PETSc lends its value array until restored.
    chk!(ffi::MatSeqAIJGetArray(m, &mut v))?;
    Ok(v)
}

/// The CSR structure of a sequential AIJ matrix, copied.
fn row_ij(m: ffi::Mat) -> Result<CsrBlock> {
    let (mut n, mut ia, mut ja, mut done): (i32, *const i32, *const i32, ffi::PetscBool) =
        (0, ptr::null(), ptr::null(), petsc_bool(false));
    let (f, t) = (petsc_bool(false), petsc_bool(false));
    // SAFETY: valid SeqAIJ handle; PETSc lends its row starts and columns until restored.
    chk!(ffi::MatGetRowIJ(m, 0, f, t, &mut n, &mut ia, &mut ja, &mut done))?;
    if done != petsc_bool(true) {
        return Err(Error::Internal("MatGetRowIJ: no CSR structure".into()));
    }
    let rows = n.max(0) as usize;
    let n = rows;
    // SAFETY: `ia` has n + 1 entries and `ja` ia[n]; copied before they are returned.
    let row_start = unsafe { std::slice::from_raw_parts(ia, n + 1) }.to_vec();
    let nnz = row_start[n].max(0) as usize;
    // SAFETY: as above.
    let cols = unsafe { std::slice::from_raw_parts(ja, nnz) }.to_vec();
    // SAFETY: the arrays lent above.
    let mut n_rows = rows as i32;
    chk!(ffi::MatRestoreRowIJ(m, 0, f, t, &mut n_rows, &mut ia, &mut ja, &mut done))?;
    Ok(CsrBlock { row_start, cols })
}
