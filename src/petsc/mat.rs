//! Sparse distributed matrices (PETSc `Mat`, AIJ format) and near null spaces.

use super::conv::{check_len, petsc_bool, to_int, to_usize};
use super::ffi;
use super::init::{self, ensure_live};
use super::vec::Vector;
use crate::error::{Error, Result};
use std::ptr;

/// Nonzero statistics summed over all ranks (`MatGetInfo` with `MAT_GLOBAL_SUM`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatNonzeroInfo {
    /// Nonzeros allocated by the preallocation.
    pub allocated: f64,
    /// Nonzeros actually stored.
    pub used: f64,
    /// Number of mallocs during assembly (0 when the preallocation was exact or generous).
    pub mallocs: f64,
}

/// An owned square AIJ matrix on `PETSC_COMM_WORLD` (`MatDestroy` on drop).
/// How the nonzero pattern of a matrix relates to another's (PETSc `MatStructure`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Pattern {
    Same,
    Subset,
    Different,
}

pub struct Matrix {
    m: ffi::Mat,
    range: (usize, usize),
    size: (usize, usize),
}

impl Matrix {
    /// Creates a square AIJ matrix with `local_rows` owned rows (and columns), exactly
    /// preallocated: `d_nnz[i]` / `o_nnz[i]` are the nonzeros of local row `i` in the
    /// diagonal / off-diagonal block. Inserting outside the preallocation is an error
    /// (`MAT_NEW_NONZERO_ALLOCATION_ERR`), because a silent malloc there costs minutes.
    /// `MAT_KEEP_NONZERO_PATTERN` is set too: row zeroing keeps explicit zeros.
    pub fn new_aij(
        local_rows: usize,
        global_rows: usize,
        block_size: usize,
        d_nnz: &[i32],
        o_nnz: &[i32],
    ) -> Result<Matrix> {
        ensure_live()?;
        check_len("Matrix::new_aij d_nnz", local_rows, d_nnz.len())?;
        check_len("Matrix::new_aij o_nnz", local_rows, o_nnz.len())?;
        let n = to_int(local_rows, "Matrix local rows")?;
        let gn = to_int(global_rows, "Matrix global rows")?;
        let bs = to_int(block_size.max(1), "Matrix block size")?;
        let mut m: ffi::Mat = ptr::null_mut();
        // SAFETY: PETSc is live; `m` is an out-pointer.
        chk!(ffi::MatCreate(init::Petsc::comm_world(), &mut m))?;
        let mut out = Matrix { m, range: (0, 0), size: (0, 0) };
        // SAFETY: `m` is a fresh Mat; sizes are consistent ints.
        chk!(ffi::MatSetSizes(m, n, n, gn, gn))?;
        // SAFETY: MATAIJ is a NUL-terminated type name; AIJ is Seq on 1 rank, MPI otherwise.
        chk!(ffi::MatSetType(m, ffi::MATAIJ.as_ptr().cast()))?;
        // SAFETY: valid Mat, before preallocation as PETSc requires.
        chk!(ffi::MatSetBlockSize(m, bs))?;
        // On one rank the whole row is in the "diagonal" block.
        let seq_nnz: Vec<i32> = d_nnz.iter().zip(o_nnz).map(|(d, o)| d + o).collect();
        // SAFETY: arrays hold `local_rows` entries; the call is a no-op on MPI matrices.
        chk!(ffi::MatSeqAIJSetPreallocation(m, 0, seq_nnz.as_ptr()))?;
        // SAFETY: as above; a no-op on sequential matrices.
        chk!(ffi::MatMPIAIJSetPreallocation(m, 0, d_nnz.as_ptr(), 0, o_nnz.as_ptr()))?;
        out.set_option(ffi::MatOption_MAT_NEW_NONZERO_ALLOCATION_ERR, true)?;
        // Zeroed rows keep explicit zeros, so the pattern never shrinks and SAME_NONZERO_PATTERN
        // stays valid for matrices assembled alike (e.g. `axpy` after Dirichlet zeroing).
        out.set_option(ffi::MatOption_MAT_KEEP_NONZERO_PATTERN, true)?;
        out.read_layout()?;
        Ok(out)
    }

    /// A rectangular AIJ matrix: `local_rows` of `global_rows` rows (row block size 1) by
    /// `local_cols` of `global_cols` columns in blocks of `col_block_size`, exactly
    /// preallocated as [`Matrix::new_aij`] (e.g. a node-by-DOF operator).
    pub fn new_aij_rect(
        (local_rows, global_rows): (usize, usize),
        (local_cols, global_cols, col_block_size): (usize, usize, usize),
        d_nnz: &[i32],
        o_nnz: &[i32],
    ) -> Result<Matrix> {
        ensure_live()?;
        check_len("Matrix::new_aij_rect d_nnz", local_rows, d_nnz.len())?;
        check_len("Matrix::new_aij_rect o_nnz", local_rows, o_nnz.len())?;
        let (m_l, m_g) = (to_int(local_rows, "Matrix rows")?, to_int(global_rows, "Matrix rows")?);
        let (n_l, n_g) = (to_int(local_cols, "Matrix cols")?, to_int(global_cols, "Matrix cols")?);
        let cbs = to_int(col_block_size.max(1), "Matrix column block size")?;
        let mut m: ffi::Mat = ptr::null_mut();
        // SAFETY: PETSc is live; `m` is an out-pointer.
        chk!(ffi::MatCreate(init::Petsc::comm_world(), &mut m))?;
        let mut out = Matrix { m, range: (0, 0), size: (0, 0) };
        // SAFETY: `m` is a fresh Mat; sizes are consistent ints.
        chk!(ffi::MatSetSizes(m, m_l, n_l, m_g, n_g))?;
        // SAFETY: MATAIJ is a NUL-terminated type name.
        chk!(ffi::MatSetType(m, ffi::MATAIJ.as_ptr().cast()))?;
        // SAFETY: valid Mat, before preallocation as PETSc requires.
        chk!(ffi::MatSetBlockSizes(m, 1, cbs))?;
        let seq_nnz: Vec<i32> = d_nnz.iter().zip(o_nnz).map(|(d, o)| d + o).collect();
        // SAFETY: arrays hold `local_rows` entries; each call is a no-op on the other type.
        chk!(ffi::MatSeqAIJSetPreallocation(m, 0, seq_nnz.as_ptr()))?;
        // SAFETY: as above.
        chk!(ffi::MatMPIAIJSetPreallocation(m, 0, d_nnz.as_ptr(), 0, o_nnz.as_ptr()))?;
        out.set_option(ffi::MatOption_MAT_NEW_NONZERO_ALLOCATION_ERR, true)?;
        out.read_layout()?;
        Ok(out)
    }

    /// The options [`Matrix::new_aij`] sets, again on a matrix that PETSc rebuilt (an `axpy`
    /// with [`Pattern::Different`] replaces the storage): zeroed rows keep their pattern,
    /// and new nonzeros are errors.
    pub fn keep_pattern(&mut self) -> Result<()> {
        self.set_option(ffi::MatOption_MAT_NEW_NONZERO_ALLOCATION_ERR, true)?;
        self.set_option(ffi::MatOption_MAT_KEEP_NONZERO_PATTERN, true)
    }

    /// A square sequential AIJ matrix private to this rank (`MPI_COMM_SELF`), from its rows
    /// in CSR form (`row_start` has `n + 1` entries; PETSc copies the arrays and assembles).
    pub fn new_seq_csr(row_start: &[i32], cols: &[i32], vals: &[f64]) -> Result<Matrix> {
        ensure_live()?;
        let n = row_start.len().saturating_sub(1);
        check_len("Matrix::new_seq_csr values", cols.len(), vals.len())?;
        check_len(
            "Matrix::new_seq_csr columns",
            row_start.last().map_or(0, |&e| e as usize),
            cols.len(),
        )?;
        let ni = to_int(n, "Matrix::new_seq_csr rows")?;
        let mut m: ffi::Mat = ptr::null_mut();
        // SAFETY: PETSc is live; `m` is an out-pointer.
        chk!(ffi::MatCreate(init::Petsc::comm_self(), &mut m))?;
        let mut out = Matrix { m, range: (0, 0), size: (0, 0) };
        // SAFETY: fresh Mat; consistent sizes.
        chk!(ffi::MatSetSizes(m, ni, ni, ni, ni))?;
        // SAFETY: MATAIJ on a one-process communicator is SeqAIJ.
        chk!(ffi::MatSetType(m, ffi::MATAIJ.as_ptr().cast()))?;
        // SAFETY: the arrays hold n + 1, nnz and nnz entries; PETSc copies them.
        chk!(ffi::MatSeqAIJSetPreallocationCSR(
            m,
            row_start.as_ptr(),
            cols.as_ptr(),
            vals.as_ptr()
        ))?;
        out.read_layout()?;
        Ok(out)
    }

    /// A square block AIJ matrix (BAIJ): `bs x bs` blocks (one per node pair of a DOF matrix,
    /// `bs` = components), each stored with one column index, so about 30% less memory than
    /// AIJ for 3D elasticity, and products without per-entry index loads. `d_nnz`/`o_nnz`
    /// count blocks per block row. Options as [`Matrix::new_aij`]'s.
    pub fn new_baij(
        local_rows: usize,
        global_rows: usize,
        bs: usize,
        d_nnz: &[i32],
        o_nnz: &[i32],
    ) -> Result<Matrix> {
        ensure_live()?;
        let bsi = to_int(bs.max(1), "Matrix block size")?;
        check_len("Matrix::new_baij d_nnz", local_rows / bs.max(1), d_nnz.len())?;
        check_len("Matrix::new_baij o_nnz", local_rows / bs.max(1), o_nnz.len())?;
        let n = to_int(local_rows, "Matrix local rows")?;
        let gn = to_int(global_rows, "Matrix global rows")?;
        let mut m: ffi::Mat = ptr::null_mut();
        // SAFETY: PETSc is live; `m` is an out-pointer.
        chk!(ffi::MatCreate(init::Petsc::comm_world(), &mut m))?;
        let mut out = Matrix { m, range: (0, 0), size: (0, 0) };
        // SAFETY: `m` is a fresh Mat; sizes are consistent ints.
        chk!(ffi::MatSetSizes(m, n, n, gn, gn))?;
        // SAFETY: MATBAIJ is a NUL-terminated type name (Seq on 1 rank, MPI otherwise).
        chk!(ffi::MatSetType(m, ffi::MATBAIJ.as_ptr().cast()))?;
        // SAFETY: valid Mat, before preallocation.
        chk!(ffi::MatSetBlockSize(m, bsi))?;
        let seq_nnz: Vec<i32> = d_nnz.iter().zip(o_nnz).map(|(d, o)| d + o).collect();
        // SAFETY: arrays hold one entry per block row; a no-op on MPI matrices.
        chk!(ffi::MatSeqBAIJSetPreallocation(m, bsi, 0, seq_nnz.as_ptr()))?;
        // SAFETY: as above; a no-op on sequential matrices.
        chk!(ffi::MatMPIBAIJSetPreallocation(m, bsi, 0, d_nnz.as_ptr(), 0, o_nnz.as_ptr()))?;
        out.set_option(ffi::MatOption_MAT_NEW_NONZERO_ALLOCATION_ERR, true)?;
        out.set_option(ffi::MatOption_MAT_KEEP_NONZERO_PATTERN, true)?;
        out.read_layout()?;
        Ok(out)
    }

    /// Adds the dense block `vals` at block rows `rows` x block columns `cols` (node
    /// numbers): row-major over the DOFs, `rows.len() bs x cols.len() bs`, as `set_values`
    /// takes it for the rows' and columns' DOFs. For BAIJ matrices; AIJ ones accept it too.
    pub fn add_values_blocked(&mut self, rows: &[i32], cols: &[i32], vals: &[f64]) -> Result<()> {
        let nr = to_int(rows.len(), "Matrix::add_values_blocked rows")?;
        let nc = to_int(cols.len(), "Matrix::add_values_blocked cols")?;
        // SAFETY: rows/cols hold nr, nc block indices and vals the (nr bs) x (nc bs) values
        // (the caller's layout, checked by PETSc's block size); PETSc copies them.
        chk!(ffi::MatSetValuesBlocked(
            self.m,
            nr,
            rows.as_ptr(),
            nc,
            cols.as_ptr(),
            vals.as_ptr(),
            ffi::InsertMode_ADD_VALUES
        ))
    }

    /// This matrix as AIJ, a new matrix with the same values and pattern (a copy when it
    /// already is AIJ): what multigrid, factorizations and row edits work on.
    pub fn to_aij(&self) -> Result<Matrix> {
        if !self.is_baij()? {
            return self.duplicate(true);
        }
        let mut c: ffi::Mat = ptr::null_mut();
        // SAFETY: valid assembled handle; `c` is an out-pointer (MAT_INITIAL_MATRIX).
        chk!(ffi::MatConvert(
            self.m,
            ffi::MATAIJ.as_ptr().cast(),
            ffi::MatReuse_MAT_INITIAL_MATRIX,
            &mut c
        ))?;
        let mut out = Matrix::from_raw(c)?;
        out.set_option(ffi::MatOption_MAT_NEW_NONZERO_ALLOCATION_ERR, true)?;
        out.set_option(ffi::MatOption_MAT_KEEP_NONZERO_PATTERN, true)?;
        Ok(out)
    }

    /// The row block size (`MatGetBlockSizes`): the DOFs per node of a DOF matrix.
    pub fn block_size(&self) -> Result<usize> {
        let (mut rbs, mut cbs) = (0, 0);
        // SAFETY: valid handle; out-pointers are locals.
        chk!(ffi::MatGetBlockSizes(self.m, &mut rbs, &mut cbs))?;
        Ok(to_usize(rbs).max(1))
    }

    /// The column block size (`MatGetBlockSizes`): a rectangular matrix's DOFs per node of
    /// its columns (a square DOF matrix's equals [`Matrix::block_size`]).
    pub fn column_block_size(&self) -> Result<usize> {
        let (mut rbs, mut cbs) = (0, 0);
        // SAFETY: valid handle; out-pointers are locals.
        chk!(ffi::MatGetBlockSizes(self.m, &mut rbs, &mut cbs))?;
        Ok(to_usize(cbs).max(1))
    }

    /// Whether the storage is (non-symmetric) block AIJ: `seqbaij` or `mpibaij`.
    fn is_plain_baij(&self) -> Result<bool> {
        let name = self.type_name()?;
        Ok(name == "seqbaij" || name == "mpibaij")
    }

    /// PETSc's name of the storage (`seqaij`, `mpibaij`, ...).
    pub(super) fn type_name(&self) -> Result<String> {
        let mut t: ffi::MatType = ptr::null();
        // SAFETY: valid handle; PETSc returns a pointer to its static type name.
        chk!(ffi::MatGetType(self.m, &mut t))?;
        // SAFETY: `t` is a NUL-terminated C string owned by PETSc.
        Ok(unsafe { std::ffi::CStr::from_ptr(t) }.to_string_lossy().to_string())
    }

    /// A BAIJ copy built as [`new_baij`](Matrix::new_baij) builds one, with exact
    /// preallocation, instead of `MatDuplicate`: PETSc's `MatDuplicate_SeqBAIJ` (3.18, and
    /// still on main) creates the copy with `MatSetType(MATSEQBAIJ)`, whose operation table
    /// has the generic `MatMult_SeqBAIJ_N`, and never runs the block-size switch of
    /// `MatSeqBAIJSetPreallocation_SeqBAIJ` that selects `MatMult_SeqBAIJ_3` and friends. A
    /// duplicated 3 x 3 BAIJ matrix multiplied 6.5 times slower than its original.
    fn baij_copy(&self, copy_values: bool) -> Result<Matrix> {
        let (mut rbs, mut cbs) = (0, 0);
        // SAFETY: valid handle; out-pointers are locals.
        chk!(ffi::MatGetBlockSizes(self.m, &mut rbs, &mut cbs))?;
        let bs = to_usize(rbs).max(1);
        let (lo, hi) = self.range;
        let (mut clo, mut chi) = (0, 0);
        // SAFETY: valid handle; out-pointers are locals.
        chk!(ffi::MatGetOwnershipRangeColumn(self.m, &mut clo, &mut chi))?;
        let nb = (hi - lo) / bs;
        let (mut d_nnz, mut o_nnz) = (vec![0i32; nb], vec![0i32; nb]);
        for ib in 0..nb {
            // BAIJ rows list whole blocks: one column in `bs` starts a block.
            self.with_row(lo + ib * bs, |cols, _| {
                for &c in cols.iter().filter(|&&c| c % rbs == 0) {
                    if c >= clo && c < chi {
                        d_nnz[ib] += 1;
                    } else {
                        o_nnz[ib] += 1;
                    }
                }
            })?;
        }
        let mut out = Matrix::new_baij(hi - lo, self.size.0, bs, &d_nnz, &o_nnz)?;
        for r in lo..hi {
            let row = [to_int(r, "Matrix::duplicate row")?];
            self.with_row(r, |cols, vals| {
                // SAFETY: `out` is a preallocated BAIJ with this row's blocks; PETSc copies
                // the `cols.len()` indices and values.
                chk!(ffi::MatSetValues(
                    out.m,
                    1,
                    row.as_ptr(),
                    cols.len() as i32,
                    cols.as_ptr(),
                    vals.as_ptr(),
                    ffi::InsertMode_INSERT_VALUES
                ))
            })??;
        }
        out.assemble()?;
        if !copy_values {
            // SAFETY: valid assembled handle; keeps the pattern.
            chk!(ffi::MatZeroEntries(out.m))?;
        }
        Ok(out)
    }

    /// Whether the storage is block AIJ.
    pub fn is_baij(&self) -> Result<bool> {
        Ok(self.type_name()?.contains("baij"))
    }

    fn from_raw(m: ffi::Mat) -> Result<Matrix> {
        let mut out = Matrix { m, range: (0, 0), size: (0, 0) };
        out.read_layout()?;
        Ok(out)
    }

    /// A handle PETSc lends (a callback's argument): referenced here, so that dropping the
    /// wrapper only releases that reference.
    pub(crate) fn borrowed(m: ffi::Mat) -> Result<Matrix> {
        // SAFETY: a valid Mat handle (a PetscObject); the reference is released by `Drop`.
        chk!(ffi::PetscObjectReference(m as ffi::PetscObject))?;
        Matrix::from_raw(m)
    }

    fn read_layout(&mut self) -> Result<()> {
        let (mut lo, mut hi, mut r, mut c) = (0, 0, 0, 0);
        // SAFETY: valid, preallocated Mat; out-pointers are locals.
        chk!(ffi::MatGetOwnershipRange(self.m, &mut lo, &mut hi))?;
        // SAFETY: as above.
        chk!(ffi::MatGetSize(self.m, &mut r, &mut c))?;
        self.range = (to_usize(lo), to_usize(hi));
        self.size = (to_usize(r), to_usize(c));
        Ok(())
    }

    fn set_option(&mut self, op: ffi::MatOption, flag: bool) -> Result<()> {
        // SAFETY: valid handle; `op` is a MatOption constant from the bindings.
        chk!(ffi::MatSetOption(self.m, op, petsc_bool(flag)))
    }

    /// `self ⊗ I_dof` with interlaced components (PETSc's MAIJ): the products of a node
    /// matrix applied to each of `dof` components alike, without storing the DOF matrix. It
    /// supports products only (`mult`, `mult_add`, `mult_transpose`).
    pub fn maij(&self, dof: usize) -> Result<Matrix> {
        let mut out: ffi::Mat = ptr::null_mut();
        // SAFETY: valid, assembled AIJ matrix; MAIJ takes a reference to it.
        chk!(ffi::MatCreateMAIJ(self.m, to_int(dof, "MAIJ components")?, &mut out))?;
        Matrix::from_raw(out)
    }

    /// The raw handle, for calls this wrapper does not cover. Ownership stays here.
    pub fn raw(&self) -> ffi::Mat {
        self.m
    }

    /// Inserts or adds (`add`) the dense block `vals` (row-major, `rows.len() x cols.len()`)
    /// at global `rows` x `cols`. Negative indices are skipped (PETSc convention). Rows of
    /// other ranks are allowed and sent during [`assemble`](Matrix::assemble).
    pub fn set_values(
        &mut self,
        rows: &[i32],
        cols: &[i32],
        vals: &[f64],
        add: bool,
    ) -> Result<()> {
        check_len("Matrix::set_values values (rows x cols)", rows.len() * cols.len(), vals.len())?;
        let nr = to_int(rows.len(), "Matrix::set_values rows")?;
        let nc = to_int(cols.len(), "Matrix::set_values cols")?;
        let mode = if add { ffi::InsertMode_ADD_VALUES } else { ffi::InsertMode_INSERT_VALUES };
        // SAFETY: rows/cols/vals hold nr, nc and nr*nc entries; PETSc copies them.
        chk!(ffi::MatSetValues(self.m, nr, rows.as_ptr(), nc, cols.as_ptr(), vals.as_ptr(), mode))
    }

    /// Final assembly (collective): communicates off-rank entries, compresses storage.
    pub fn assemble(&mut self) -> Result<()> {
        let t = ffi::MatAssemblyType_MAT_FINAL_ASSEMBLY;
        // SAFETY: valid handle; Begin/End are paired.
        chk!(ffi::MatAssemblyBegin(self.m, t))?;
        // SAFETY: as above.
        chk!(ffi::MatAssemblyEnd(self.m, t))
    }

    /// `y = A x`.
    pub fn mult(&self, x: &Vector, y: &mut Vector) -> Result<()> {
        // SAFETY: valid handles; `y` is distinct from `x` by the borrow rules.
        chk!(ffi::MatMult(self.m, x.raw(), y.raw()))
    }

    /// `y = A^T x`.
    pub fn mult_transpose(&self, x: &Vector, y: &mut Vector) -> Result<()> {
        // SAFETY: valid handles; `y` is distinct from `x` by the borrow rules.
        chk!(ffi::MatMultTranspose(self.m, x.raw(), y.raw()))
    }

    /// `P^T A P` as a new matrix (`A` = self, square; PETSc's `MatPtAP`).
    pub fn ptap(&self, p: &Matrix) -> Result<Matrix> {
        let mut c: ffi::Mat = ptr::null_mut();
        // Distributed: PETSc's "backend" product (local sequential products assembled by
        // COO), whose numeric part is the cheap one (the oblique 3D balls' `T^T K T`
        // rebuilds: 2.5 -> 1.8 s, the plain Newton steps of a pair a quarter faster).
        if self.type_name()? == "mpiaij" && p.type_name()? == "mpiaij" {
            // SAFETY: valid assembled handles; `c` is an out-pointer, then the product matrix,
            // set up in PETSc's documented order (type, algorithm, fill, options, symbolic,
            // numeric); the algorithm's name is a static C string.
            chk!(ffi::MatProductCreate(self.m, p.m, ptr::null_mut(), &mut c))?;
            let mut c = Matrix { m: c, range: (0, 0), size: (0, 0) }; // freed on an error
            chk!(ffi::MatProductSetType(c.m, ffi::MatProductType_MATPRODUCT_PtAP))?;
            chk!(ffi::MatProductSetAlgorithm(c.m, c"backend".as_ptr()))?;
            chk!(ffi::MatProductSetFill(c.m, ffi::PETSC_DEFAULT as f64))?;
            chk!(ffi::MatProductSetFromOptions(c.m))?;
            // (Its rows keep P's node blocks, which GAMG aggregates by: without them the
            // friction test's step took 4 times the iterations.)
            let bs = p.column_block_size()? as i32;
            chk!(ffi::MatSetBlockSizes(c.m, bs, bs))?;
            chk!(ffi::MatProductSymbolic(c.m))?;
            chk!(ffi::MatProductNumeric(c.m))?;
            c.read_layout()?;
            return Ok(c);
        }
        // SAFETY: valid assembled handles; `c` is an out-pointer (MAT_INITIAL_MATRIX).
        chk!(ffi::MatPtAP(
            self.m,
            p.m,
            ffi::MatReuse_MAT_INITIAL_MATRIX,
            ffi::PETSC_DEFAULT as f64,
            &mut c
        ))?;
        Matrix::from_raw(c)
    }

    /// `A^T B` as a new matrix (`A` = self; PETSc's `MatProduct` of type `AtB`), with DOF
    /// blocks of `block_size`; [`Matrix::product_again`] recomputes it from the same two
    /// matrices' new values.
    pub fn transpose_times(&self, b: &Matrix, block_size: usize) -> Result<Matrix> {
        let mut c: ffi::Mat = ptr::null_mut();
        // SAFETY: valid assembled handles; `c` is an out-pointer, then the product matrix,
        // set up in PETSc's documented order (type, fill, options, symbolic, numeric).
        chk!(ffi::MatProductCreate(self.m, b.m, ptr::null_mut(), &mut c))?;
        let mut c = Matrix { m: c, range: (0, 0), size: (0, 0) }; // freed on an error
        chk!(ffi::MatProductSetType(c.m, ffi::MatProductType_MATPRODUCT_AtB))?;
        chk!(ffi::MatProductSetFill(c.m, ffi::PETSC_DEFAULT as f64))?;
        chk!(ffi::MatProductSetFromOptions(c.m))?;
        let bs = to_int(block_size.max(1), "Matrix block size")?;
        chk!(ffi::MatSetBlockSizes(c.m, bs, bs))?;
        chk!(ffi::MatProductSymbolic(c.m))?;
        chk!(ffi::MatProductNumeric(c.m))?;
        c.read_layout()?;
        Ok(c)
    }

    /// A product of [`Matrix::transpose_times`] recomputed from its factors' current values
    /// (their patterns unchanged; PETSc's `MatProductNumeric`).
    pub fn product_again(&mut self) -> Result<()> {
        // SAFETY: `self` is a product matrix whose factors PETSc still references.
        chk!(ffi::MatProductNumeric(self.m))
    }

    /// Every stored entry set to zero, the pattern kept (`MatZeroEntries`).
    pub fn zero_entries(&mut self) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::MatZeroEntries(self.m))
    }

    /// Row `i` scaled by `d_i` (`MatDiagonalScale(A, d, NULL)`).
    pub fn scale_rows(&mut self, d: &Vector) -> Result<()> {
        // SAFETY: valid handles; `d` has the row layout (PETSc checks it).
        chk!(ffi::MatDiagonalScale(self.m, d.raw(), ptr::null_mut()))
    }

    /// `c = P^T A P` again, in place: `c` came from [`Matrix::ptap`] of a matrix with this
    /// one's nonzero pattern and the same `P` (PETSc's `MatPtAP` with `MAT_REUSE_MATRIX`: the
    /// numeric part only; values written into `c` since are overwritten).
    pub fn ptap_into(&self, p: &Matrix, c: &mut Matrix) -> Result<()> {
        // SAFETY: valid assembled handles; `c.m` is the product's own handle, updated in place.
        chk!(ffi::MatPtAP(
            self.m,
            p.m,
            ffi::MatReuse_MAT_REUSE_MATRIX,
            ffi::PETSC_DEFAULT as f64,
            &mut c.m
        ))
    }

    /// `z = y + A x`.
    pub fn mult_add(&self, x: &Vector, y: &Vector, z: &mut Vector) -> Result<()> {
        // SAFETY: valid handles; `z` is distinct from `x` (PETSc allows z == y, not needed).
        chk!(ffi::MatMultAdd(self.m, x.raw(), y.raw(), z.raw()))
    }

    /// A matrix with the same layout and nonzero pattern; values copied if `copy_values`,
    /// zero otherwise.
    pub fn duplicate(&self, copy_values: bool) -> Result<Matrix> {
        if self.is_plain_baij()? {
            return self.baij_copy(copy_values);
        }
        let op = if copy_values {
            ffi::MatDuplicateOption_MAT_COPY_VALUES
        } else {
            ffi::MatDuplicateOption_MAT_DO_NOT_COPY_VALUES
        };
        let mut m: ffi::Mat = ptr::null_mut();
        // SAFETY: valid assembled handle; `m` is an out-pointer.
        chk!(ffi::MatDuplicate(self.m, op, &mut m))?;
        Matrix::from_raw(m)
    }

    /// `self += alpha * x`. `pattern` states how x's nonzero pattern relates to self's:
    /// `Same` and `Subset` are fast paths (no new allocation); `Different` merges patterns.
    pub fn axpy(&mut self, alpha: f64, x: &Matrix, pattern: Pattern) -> Result<()> {
        let s = match pattern {
            Pattern::Same => ffi::MatStructure_SAME_NONZERO_PATTERN,
            Pattern::Subset => ffi::MatStructure_SUBSET_NONZERO_PATTERN,
            Pattern::Different => ffi::MatStructure_DIFFERENT_NONZERO_PATTERN,
        };
        // SAFETY: valid, distinct handles (`&mut self` vs `&x`).
        chk!(ffi::MatAXPY(self.m, alpha, x.m, s))
    }

    /// `self = x` entry by entry for matrices of the same nonzero structure (`MatCopy` with
    /// `SAME_NONZERO_PATTERN`: one copy of the value arrays).
    pub fn copy_values_from(&mut self, x: &Matrix) -> Result<()> {
        // SAFETY: valid handles of the same layout and structure (PETSc checks the sizes).
        chk!(ffi::MatCopy(x.m, self.m, ffi::MatStructure_SAME_NONZERO_PATTERN))
    }

    /// `self *= alpha`.
    pub fn scale(&mut self, alpha: f64) -> Result<()> {
        // SAFETY: valid handle.
        chk!(ffi::MatScale(self.m, alpha))
    }

    /// Zeros the given global rows and columns (collective; each rank may list any rows) and
    /// puts `diag` on their diagonal. With `x` and `b`, fixes `b` so that the solution keeps
    /// `x`'s values in those rows (Dirichlet conditions, symmetry preserved).
    pub fn zero_rows_columns(
        &mut self,
        rows: &[i32],
        diag: f64,
        x: Option<&Vector>,
        b: Option<&mut Vector>,
    ) -> Result<()> {
        let what = "Matrix::zero_rows_columns rows";
        self.zero(ffi::MatZeroRowsColumns, "MatZeroRowsColumns", what, rows, diag, x, b)
    }

    /// Like [`zero_rows_columns`](Matrix::zero_rows_columns) but keeps the columns (breaks
    /// symmetry; `b[row] = diag * x[row]` when both vectors are given).
    pub fn zero_rows(
        &mut self,
        rows: &[i32],
        diag: f64,
        x: Option<&Vector>,
        b: Option<&mut Vector>,
    ) -> Result<()> {
        self.zero(ffi::MatZeroRows, "MatZeroRows", "Matrix::zero_rows rows", rows, diag, x, b)
    }

    /// The body of both: `zero` is `MatZeroRows` or `MatZeroRowsColumns` (named `call` in
    /// errors); `what` names the row count if it does not fit a `PetscInt`.
    #[allow(clippy::too_many_arguments)]
    fn zero(
        &mut self,
        zero: ZeroRows,
        call: &str,
        what: &str,
        rows: &[i32],
        diag: f64,
        x: Option<&Vector>,
        b: Option<&mut Vector>,
    ) -> Result<()> {
        let n = to_int(rows.len(), what)?;
        let xr = x.map_or(ptr::null_mut(), Vector::raw);
        let br = b.map_or(ptr::null_mut(), |b| b.raw());
        // SAFETY: valid handles or null (allowed by PETSc); `rows` holds n entries.
        let code = unsafe { zero(self.m, n, rows.as_ptr(), diag, xr, br) };
        super::conv::check(code, call, file!(), line!())
    }

    /// `d = diag(A)`.
    pub fn get_diagonal(&self, d: &mut Vector) -> Result<()> {
        // SAFETY: valid handles.
        chk!(ffi::MatGetDiagonal(self.m, d.raw()))
    }

    /// Attaches a near null space (e.g. rigid body modes) for algebraic multigrid. PETSc
    /// keeps its own reference, so `ns` may be dropped afterwards.
    pub fn set_near_null_space(&mut self, ns: &NullSpace) -> Result<()> {
        // SAFETY: valid handles; PETSc increments the null space's reference count.
        chk!(ffi::MatSetNearNullSpace(self.m, ns.sp))
    }

    /// Whether `A == A^T` up to `tol` (collective; an expensive check for tests).
    pub fn is_symmetric(&self, tol: f64) -> Result<bool> {
        let mut flg = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: valid assembled handle; `flg` is an out-pointer.
        chk!(ffi::MatIsSymmetric(self.m, tol, &mut flg))?;
        Ok(flg == ffi::PetscBool_PETSC_TRUE)
    }

    /// Frobenius norm (collective).
    pub fn norm_frobenius(&self) -> Result<f64> {
        let mut n = 0.0;
        // SAFETY: valid assembled handle; `n` is an out-pointer.
        chk!(ffi::MatNorm(self.m, ffi::NormType_NORM_FROBENIUS, &mut n))?;
        Ok(n)
    }

    /// Global nonzero statistics (collective).
    pub fn nonzero_info(&self) -> Result<MatNonzeroInfo> {
        let mut info = ffi::MatInfo::default();
        // SAFETY: valid handle; `info` is an out-pointer to a MatInfo.
        chk!(ffi::MatGetInfo(self.m, ffi::MatInfoType_MAT_GLOBAL_SUM, &mut info))?;
        Ok(MatNonzeroInfo {
            allocated: info.nz_allocated,
            used: info.nz_used,
            mallocs: info.mallocs,
        })
    }

    /// Nonzeros allocated, summed over ranks (collective).
    pub fn info_nonzeros_allocated(&self) -> Result<f64> {
        Ok(self.nonzero_info()?.allocated)
    }

    /// Nonzeros used, summed over ranks (collective).
    pub fn info_nonzeros_used(&self) -> Result<f64> {
        Ok(self.nonzero_info()?.used)
    }

    /// Column indices and values of one owned global row (assembled matrix).
    pub fn get_row(&self, global_row: usize) -> Result<(Vec<i32>, Vec<f64>)> {
        self.with_row(global_row, |c, v| (c.to_vec(), v.to_vec()))
    }

    /// Calls `f` with the column indices and values of one owned global row, without copying.
    pub fn with_row<R>(&self, global_row: usize, f: impl FnOnce(&[i32], &[f64]) -> R) -> Result<R> {
        let (lo, hi) = self.range;
        if global_row < lo || global_row >= hi {
            return Err(Error::Solver(format!(
                "Matrix::get_row: row {global_row} is not owned by this rank (owns {lo}..{hi})"
            )));
        }
        let row = to_int(global_row, "Matrix::get_row row")?;
        let mut ncols: ffi::PetscInt = 0;
        let mut cols: *const ffi::PetscInt = ptr::null();
        let mut vals: *const f64 = ptr::null();
        // SAFETY: valid assembled handle, owned row; out-pointers are locals.
        chk!(ffi::MatGetRow(self.m, row, &mut ncols, &mut cols, &mut vals))?;
        let n = to_usize(ncols);
        let out = if n == 0 || cols.is_null() || vals.is_null() {
            f(&[], &[])
        } else {
            // SAFETY: PETSc returned `ncols` entries in each array, valid until MatRestoreRow.
            unsafe { f(std::slice::from_raw_parts(cols, n), std::slice::from_raw_parts(vals, n)) }
        };
        // SAFETY: restores the row obtained above with the same arguments.
        chk!(ffi::MatRestoreRow(self.m, row, &mut ncols, &mut cols, &mut vals))?;
        Ok(out)
    }

    /// Global rows `[lo, hi)` owned by this rank.
    pub fn ownership_range(&self) -> (usize, usize) {
        self.range
    }

    /// Global `(rows, cols)`.
    pub fn size(&self) -> (usize, usize) {
        self.size
    }

    /// Declares the matrix symmetric (or not) for good: `MAT_SYMMETRIC` plus
    /// `MAT_SYMMETRY_ETERNAL`, so the flag survives reassembly and solvers (Cholesky, CG,
    /// GAMG) may rely on it.
    pub fn set_option_symmetric(&mut self, symmetric: bool) -> Result<()> {
        self.set_option(ffi::MatOption_MAT_SYMMETRIC, symmetric)?;
        self.set_option(ffi::MatOption_MAT_SYMMETRY_ETERNAL, symmetric)
    }

    /// Declares the matrix symmetric positive definite for good (`MAT_SPD`, `MAT_SPD_ETERNAL`).
    pub fn set_option_spd(&mut self, spd: bool) -> Result<()> {
        self.set_option(ffi::MatOption_MAT_SPD, spd)?;
        self.set_option(ffi::MatOption_MAT_SPD_ETERNAL, spd)
    }

    /// Vectors compatible with the matrix: `(x, b)` with `x` laid out like the columns (the
    /// solution) and `b` like the rows (the right-hand side).
    pub fn create_vecs(&self) -> Result<(Vector, Vector)> {
        let mut x: ffi::Vec = ptr::null_mut();
        let mut b: ffi::Vec = ptr::null_mut();
        // SAFETY: valid handle; out-pointers.
        chk!(ffi::MatCreateVecs(self.m, &mut x, &mut b))?;
        let x = Vector::from_raw(x);
        let b = Vector::from_raw(b);
        Ok((x?, b?))
    }
}

impl Drop for Matrix {
    fn drop(&mut self) {
        if !self.m.is_null() && init::is_live() {
            // SAFETY: this wrapper owns the handle; destroyed once, while PETSc is live.
            unsafe { ffi::MatDestroy(&mut self.m) };
        }
    }
}

/// A (near) null space of a matrix (`MatNullSpaceDestroy` on drop).
pub struct NullSpace {
    sp: ffi::MatNullSpace,
}

impl NullSpace {
    /// Rigid body modes (3 in 2D, 6 in 3D) from the owned nodes' coordinates: `coords` has
    /// block size = dimension and the same layout as the displacement vector.
    pub fn rigid_body_modes(coords: &Vector) -> Result<NullSpace> {
        ensure_live()?;
        let mut sp: ffi::MatNullSpace = ptr::null_mut();
        // SAFETY: valid coordinate vector; `sp` is an out-pointer.
        chk!(ffi::MatNullSpaceCreateRigidBody(coords.raw(), &mut sp))?;
        Ok(NullSpace { sp })
    }

    /// The raw handle. Ownership stays here.
    pub fn raw(&self) -> ffi::MatNullSpace {
        self.sp
    }

    /// Number of basis vectors (not counting the constant vector flag).
    pub fn num_vectors(&self) -> Result<usize> {
        let mut has_const = ffi::PetscBool_PETSC_FALSE;
        let mut n: ffi::PetscInt = 0;
        let mut vecs: *const ffi::Vec = ptr::null();
        // SAFETY: valid handle; out-pointers; the returned array stays owned by PETSc.
        chk!(ffi::MatNullSpaceGetVecs(self.sp, &mut has_const, &mut n, &mut vecs))?;
        Ok(to_usize(n))
    }

    /// Whether `A v ≈ 0` for every basis vector `v` (collective; for tests).
    pub fn is_null_space_of(&self, a: &Matrix) -> Result<bool> {
        let mut flg = ffi::PetscBool_PETSC_FALSE;
        // SAFETY: valid handles; `flg` is an out-pointer.
        chk!(ffi::MatNullSpaceTest(self.sp, a.m, &mut flg))?;
        Ok(flg == ffi::PetscBool_PETSC_TRUE)
    }
}

impl Drop for NullSpace {
    fn drop(&mut self) {
        if !self.sp.is_null() && init::is_live() {
            // SAFETY: this wrapper owns one reference; released once, while PETSc is live.
            unsafe { ffi::MatNullSpaceDestroy(&mut self.sp) };
        }
    }
}

/// The signature shared by `MatZeroRows` and `MatZeroRowsColumns`.
type ZeroRows = unsafe extern "C" fn(
    ffi::Mat,
    ffi::PetscInt,
    *const ffi::PetscInt,
    ffi::PetscScalar,
    ffi::Vec,
    ffi::Vec,
) -> ffi::PetscErrorCode;
