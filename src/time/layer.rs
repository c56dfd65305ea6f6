//! The mass-free layer's rows in the step's preconditioner.
//!
//! With `M_H` the DOFs of the contact nodes carry no mass, so their rows of
//! `K = 4/tau^2 M_H + A` hold stiffness only: `K_CC = A_CC` is orders of magnitude below the
//! mass-dominated rows at small CFL, coupled to its neighbours as strongly as to itself, and
//! Jacobi leaves its spread of eigenvalues in the preconditioned operator (40% more CG
//! iterations on the beam than with `M`). The layer is one cell thick, so `K_CC` is
//! surface-sized: this rank's part of it is factored exactly (sparse Cholesky, once per
//! operator), and the preconditioner is the symmetric block Gauss-Seidel sweep
//!
//! ```text
//!   y_C = K_CC^{-1} r_C,   z_I = D_II^{-1} (r_I - K_IC y_C),   z_C = K_CC^{-1} (r_C - K_CI z_I)
//! ```
//! (`D_II`: K's diagonal on the massive rows), i.e. `B = P^{-1}` with the SPD
//! `P = [[D_II + K_IC K_CC^{-1} K_CI, K_IC], [K_CI, K_CC]]`: `P - K` is zero outside the
//! massive block, so `B K` has the eigenvalue 1 on the layer and Jacobi's spectrum on the
//! Schur complement `K_II - K_IC K_CC^{-1} K_CI = 4/tau^2 M_II + (a stiffness below A_II)`:
//! the iterations of `M`. An error confined to the layer (the massless DOFs are quasi-static
//! and the extrapolated guess misses them most) is removed in one iteration.
//!
//! The layer is surface-sized, so every rank holds the whole `K_CC` (gathered once, factored
//! by the `step_layer_` solver: exactly in 2D, a chain without fill; by ICC(0) in 3D, as many
//! iterations as the exact factor on the block at CFL 1 for a quarter of its solve's bytes)
//! and its rows of `K_AC` (`A`: the massive rows coupled to the layer) with the layer's
//! global numbering. The sweep is then exact where the partition cuts the layer too (a block
//! per rank, leaving out the couplings across the cut, took 1.5 iterations a step on the beam
//! cut across its layer against 1.2 with the cut away from it), and costs two collectives of
//! the layer's size an application: gathering `r_C`, summing `K_CA z_A` (PETSc's redundant
//! solver and submatrices took 4 messages and 0.25 ms an application on 2 ranks).
//!
//! In 3D each rank sweeps its own part instead ([`LayerBlock::new`] with `local`,
//! `-step_layer_local`): there the couplings across the cut cost no iterations (the block at
//! CFL 1: 361 against 362) and the whole layer's two solves an application on every rank
//! most of `M_H`'s extra time (1.12 against 0.96 times `M`'s).

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::comm::gather_all;
use crate::error::{Error, Result};
use crate::petsc::{Ksp, Matrix, Petsc, Vector};

/// The mass-free layer's blocks of the step operator and the solver of `K_CC`.
pub struct LayerBlock {
    /// Local indices (within the owned range) of this rank's massless DOFs; in the layer's
    /// numbering they are `first..first + rows.len()`.
    rows: Vec<usize>,
    first: usize,
    /// Global DOF of each layer row over all ranks (ascending: ranks own ascending ranges);
    /// with `local`, this rank's only.
    layer_dofs: Vec<i32>,
    /// Each rank factors its own rows' block only, without the couplings across the
    /// partition and without communication ([`LayerBlock::new`] with `local`).
    local: bool,
    /// This rank's massive rows coupled to the layer (local indices), Jacobi's `1/K_ii`
    /// there, and `K_AC` in CSR over them with layer columns.
    adjacent: Vec<usize>,
    d_adjacent: Vec<f64>,
    kac_start: Vec<usize>,
    kac_cols: Vec<u32>,
    kac_vals: Vec<f64>,
    /// The whole `K_CC`'s solver (on this rank, the same on every rank).
    ksp: Ksp,
    rc: Vector,
    zc: Vector,
    /// The whole layer's `r_C`, then `r_C - K_CA z_A`; `K_CA z_A`'s sum over the ranks.
    gathered: Vec<f64>,
    summed: Vec<f64>,
    /// Each rank's number of layer rows and their offsets (for gathering `r_C`), and this
    /// rank's `K_CA z_A` over the whole layer.
    counts: Vec<i32>,
    displs: Vec<i32>,
    partial: Vec<f64>,
    /// This rank's part of the last `z_C`, and `-D^{-1} K_AC y_C` on the coupled rows.
    z_own: Vec<f64>,
    /// The whole `K_CC` (for the guess's product) and its pattern (row starts, columns).
    kcc: Option<Matrix>,
    kcc_pattern: Option<(Vec<i32>, Vec<i32>)>,
    /// This rank's layer values of the last three solutions (newest first) and how many of
    /// them are from consecutive solves ([`LayerBlock::guess`]).
    history: [Vec<f64>; 3],
    recorded: usize,
    dz: Vec<f64>,
}

impl LayerBlock {
    /// The massless rows of `k` (local indices `rows`, sorted), their blocks and the solver
    /// of `K_CC` under the `step_layer_` options (ICC(0) in 3D, Cholesky in 2D); `d` is
    /// Jacobi's inverse diagonal of `k` (local; `None` for the sweep around another
    /// preconditioner, [`LayerBlock::apply_around`]), `dim` the DOFs per node. Collective.
    ///
    /// `local = false`: the whole layer's block on every rank; `None` when no rank has a
    /// massless row. `local = true`: each rank's own rows only, the block `K_CC` of this
    /// rank's massless rows and the couplings `K_AC` within this rank, no communication in
    /// the sweep. The preconditioner stays symmetric (block-diagonal over the ranks, each
    /// block the sweep of the module's doc on the rank's rows). `None` on a rank without
    /// massless rows; nothing after the construction is collective.
    pub fn new(
        k: &Matrix,
        rows: Vec<usize>,
        d: Option<&[f64]>,
        dim: usize,
        local: bool,
    ) -> Result<Option<LayerBlock>> {
        let pc = if dim == 3 { "icc" } else { "cholesky" };
        Self::build(k, rows, d, "step_layer_", pc, "nd", local)
    }

    /// [`LayerBlock::new`] with the solver of `K_CC` under the options prefix `prefix`,
    /// its preconditioner `pc` and the factor's ordering unless the options say otherwise
    /// (`cholesky`: exact).
    pub fn with_solver(
        k: &Matrix,
        rows: Vec<usize>,
        d: Option<&[f64]>,
        prefix: &str,
        pc: &str,
        ordering: &str,
    ) -> Result<Option<LayerBlock>> {
        Self::build(k, rows, d, prefix, pc, ordering, false)
    }

    fn build(
        k: &Matrix,
        rows: Vec<usize>,
        d: Option<&[f64]>,
        prefix: &str,
        pc: &str,
        ordering: &str,
        local: bool,
    ) -> Result<Option<LayerBlock>> {
        let world = SimpleCommunicator::world();
        let (lo, _) = k.ownership_range();
        let own: Vec<i32> = rows.iter().map(|&i| (lo + i) as i32).collect();
        let (layer_dofs, counts) = if local {
            (own.clone(), vec![own.len() as i32])
        } else {
            let mut counts = vec![0i32; world.size() as usize];
            world.all_gather_into(&(own.len() as i32), &mut counts[..]);
            (gather_all(&world, &own), counts)
        };
        let displs: Vec<i32> =
            counts.iter().scan(0, |s, &c| Some(std::mem::replace(s, *s + c))).collect();
        // Defaults under the command line's and the scene's options (`set_from_options` in
        // [`LayerBlock::factor_holding`]), entered on every rank alike, also on one without
        // rows of its own (`local`), so that the database is the same everywhere.
        let defaults: [(String, &str); 2] = [
            (format!("-{prefix}pc_type"), pc),
            (format!("-{prefix}pc_factor_mat_ordering_type"), ordering),
        ];
        for (name, value) in &defaults {
            if !Petsc::options_given(name)? {
                Petsc::options_set(name, Some(value))?;
            }
        }
        if layer_dofs.is_empty() {
            return Ok(None);
        }
        let first = layer_dofs.partition_point(|&g| g < lo as i32);
        let mut ksp = Ksp::new_self(prefix)?;
        ksp.set_type("preonly")?;
        let n = layer_dofs.len();
        let mut block = LayerBlock {
            rows,
            first,
            layer_dofs,
            local,
            adjacent: Vec::new(),
            d_adjacent: Vec::new(),
            kac_start: Vec::new(),
            kac_cols: Vec::new(),
            kac_vals: Vec::new(),
            ksp,
            rc: Vector::new_seq(n)?,
            zc: Vector::new_seq(n)?,
            gathered: vec![0.0; n],
            summed: vec![0.0; n],
            counts: Vec::new(),
            displs: Vec::new(),
            partial: vec![0.0; n],
            z_own: Vec::new(),
            dz: Vec::new(),
            kcc: None,
            kcc_pattern: None,
            history: Default::default(),
            recorded: 0,
        };
        block.counts = counts;
        block.displs = displs;
        block.factor(k, d)?;
        Ok(Some(block))
    }

    /// The layer's rows over all ranks and the solver of `K_CC` as the block's KSP has it
    /// (after the defaults and the options: `cholesky`, `icc`, ...), from the first rank that
    /// has a block (`block`: this rank's, `None` with `local` on a rank without layer rows):
    /// the same report on every rank. No option is read here (`run::options`). Collective.
    pub fn report(
        block: Option<&LayerBlock>,
        own_rows: usize,
        local: bool,
    ) -> Result<(usize, String)> {
        let world = SimpleCommunicator::world();
        let mut total = 0usize;
        world.all_reduce_into(&own_rows, &mut total, SystemOperation::sum());
        let mine = match block {
            Some(b) => b.ksp.pc_type()?,
            None => String::new(),
        };
        let mut lengths = vec![0i32; world.size() as usize];
        world.all_gather_into(&(mine.len() as i32), &mut lengths[..]);
        // In rank order: the first rank with a block starts the gathered bytes.
        let bytes = gather_all(&world, mine.as_bytes());
        let first = lengths.iter().copied().find(|&l| l > 0).unwrap_or(0) as usize;
        let mut solver = String::from_utf8_lossy(&bytes[..first]).into_owned();
        if local {
            solver += " on each rank's own part (-step_layer_local)";
        }
        Ok((total, solver))
    }

    /// The layer row of a global DOF, if it is one.
    fn layer_row(&self, g: i32) -> Option<usize> {
        self.layer_dofs.binary_search(&g).ok()
    }

    /// Gathers `K_CC`, collects this rank's `K_AC` and factors `K_CC` (again, after `k`
    /// changed; `d` as in [`LayerBlock::new`]). Collective.
    pub fn factor(&mut self, k: &Matrix, d: Option<&[f64]>) -> Result<()> {
        self.factor_holding(k, d, &[])
    }

    /// [`LayerBlock::factor`] with the layer rows of the global DOFs `held` (any rank may
    /// list any; their union counts) taken out of `K_CC`: their rows and columns become the
    /// identity's, so that a solve leaves them at zero. The pattern stays, so the refactoring
    /// is numeric only. Collective.
    pub fn factor_holding(&mut self, k: &Matrix, d: Option<&[f64]>, held: &[i32]) -> Result<()> {
        let world = SimpleCommunicator::world();
        let (lo, hi) = k.ownership_range();
        // This rank's rows of K_CC as (row, column, value) in the layer's numbering.
        let mut lengths = Vec::with_capacity(self.rows.len());
        let (mut cols, mut vals) = (Vec::new(), Vec::new());
        for &r in &self.rows {
            let before = cols.len();
            k.with_row(lo + r, |c, v| {
                for (&g, &x) in c.iter().zip(v) {
                    if let Some(j) = self.layer_row(g) {
                        cols.push(j as i32);
                        vals.push(x);
                    }
                }
            })?;
            lengths.push((cols.len() - before) as i32);
        }
        let (lengths, cols, vals) = if self.local {
            (lengths, cols, vals)
        } else {
            (gather_all(&world, &lengths), gather_all(&world, &cols), gather_all(&world, &vals))
        };
        let mut start = Vec::with_capacity(lengths.len() + 1);
        start.push(0i32);
        for l in &lengths {
            start.push(start.last().unwrap() + l);
        }
        let held = if self.local { held.to_vec() } else { gather_all(&world, held) };
        let mut vals = vals;
        if !held.is_empty() {
            let mut out = vec![false; lengths.len()];
            for &g in &held {
                if let Some(j) = self.layer_row(g) {
                    out[j] = true;
                }
            }
            for r in 0..lengths.len() {
                for e in start[r] as usize..start[r + 1] as usize {
                    let c = cols[e] as usize;
                    if out[r] || out[c] {
                        vals[e] = if c == r { 1.0 } else { 0.0 };
                    }
                }
            }
        }
        // The pattern never changes: the values go into the matrix factored before, so that
        // PETSc keeps its ordering and symbolic factorization (a contact step refactors
        // numerically only; the symbolic Cholesky took two thirds of a refactorization of the
        // ball's 1335 rows).
        match (self.kcc.as_mut(), &self.kcc_pattern) {
            (Some(kcc), Some((s0, c0))) if *s0 == start && *c0 == cols => {
                for r in 0..lengths.len() {
                    let (a, b) = (start[r] as usize, start[r + 1] as usize);
                    kcc.set_values(&[r as i32], &cols[a..b], &vals[a..b], false)?;
                }
                kcc.assemble()?;
                self.ksp.set_operators(kcc, kcc)?;
            }
            _ => {
                let kcc = Matrix::new_seq_csr(&start, &cols, &vals)?;
                self.ksp.set_operators(&kcc, &kcc)?;
                self.kcc = Some(kcc);
                self.kcc_pattern = Some((start, cols));
            }
        }
        self.ksp.set_from_options()?;
        self.ksp.set_up().map_err(|e| match e {
            Error::Petsc { message, .. } => Error::Solver(format!(
                "the mass-free layer's block K_CC ({} rows) could not be factored: {message}",
                self.layer_dofs.len()
            )),
            other => other,
        })?;
        // K_AC: this rank's massive rows with entries in layer columns (any rank's). K's
        // pattern never changes (a contact solver rewrites values), so after the first scan
        // of all rows only the coupled ones are read again.
        let candidates: Vec<usize> = if self.adjacent.is_empty() {
            let massless: std::collections::HashSet<usize> = self.rows.iter().copied().collect();
            (0..hi - lo).filter(|i| !massless.contains(i)).collect()
        } else {
            std::mem::take(&mut self.adjacent)
        };
        self.adjacent.clear();
        self.kac_start = vec![0];
        self.kac_cols.clear();
        self.kac_vals.clear();
        for i in candidates {
            let before = self.kac_cols.len();
            k.with_row(lo + i, |c, v| {
                for (&g, &x) in c.iter().zip(v) {
                    if let Some(j) = self.layer_row(g) {
                        self.kac_cols.push(j as u32);
                        self.kac_vals.push(x);
                    }
                }
            })?;
            if self.kac_cols.len() > before {
                self.adjacent.push(i);
                self.kac_start.push(self.kac_cols.len());
            }
        }
        self.d_adjacent = d.map_or(Vec::new(), |d| self.adjacent.iter().map(|&i| d[i]).collect());
        self.dz = vec![0.0; self.adjacent.len()];
        self.z_own = vec![0.0; self.rows.len()];
        Ok(())
    }

    /// Keeps this rank's layer values of the solution `x` (local slice owner) for the guess.
    pub fn record(&mut self, x: &Vector) -> Result<()> {
        self.history.rotate_right(1);
        let rows = &self.rows;
        let newest = &mut self.history[0];
        newest.clear();
        x.with_local_slice(|x| newest.extend(rows.iter().map(|&i| x[i])))?;
        self.recorded = (self.recorded + 1).min(3);
        Ok(())
    }

    /// The solutions recorded are not consecutive any more (K or the state changed).
    pub fn forget(&mut self) {
        self.recorded = 0;
    }

    /// The layer rows' share of the step's guess. The midpoint rule fixes only
    /// `u^{n+1} + u^n` of a massless DOF (its row is the static equation at the midpoint), so
    /// an error a solve leaves there stays as a mode `(-1)^n`, undamped, and the solves'
    /// errors add up in it over the run (1.6% of the guess's error in the energy norm on the
    /// beam after 150 steps). The two-point extrapolation `2 du^n - du^{n-1}` misses that mode
    /// by three times its size, and the first CG iteration, which fits the smooth rest,
    /// cannot remove both: two iterations a step instead of one. On the layer rows the guess
    /// is `du^n + du^{n-1} - du^{n-2}`, exact for increments changing linearly in time and for
    /// the alternating mode; elsewhere it stays two-point (three points there doubled the
    /// error of smooth motions: 5.5 iterations a step against 5.0 on the 3D block).
    ///
    /// The difference `D = -du^n + 2 du^{n-1} - du^{n-2}` on the layer rows and its product
    /// `K D` (`K_CC D` and `K_AC D`: surface-sized) are taken out of the previous solution
    /// `x_prev` and its product `kx_prev`, so that the two-point extrapolation of the caller
    /// makes the layer's guess. Nothing happens before three consecutive solutions.
    /// Collective.
    ///
    /// With each rank's own block ([`LayerBlock::new`] with `local`) there is no layer
    /// guess: its product would miss the couplings across the partition, which the kept
    /// products must not (the solve would converge to another right-hand side).
    pub fn guess(&mut self, xp: &mut Vector, kxp: &mut Vector) -> Result<()> {
        if self.recorded < 3 || self.local {
            return Ok(());
        }
        let [h1, h2, h3] = &self.history;
        let own: Vec<f64> = (0..self.rows.len()).map(|j| -h1[j] + 2.0 * h2[j] - h3[j]).collect();
        self.gather(&own);
        let all = &self.gathered;
        self.rc.with_local_slice_mut(|rc| rc.copy_from_slice(all))?;
        self.kcc.as_ref().expect("factored").mult(&self.rc, &mut self.zc)?;
        let (rows, adjacent, first) = (&self.rows, &self.adjacent, self.first);
        let (start, cols, vals) = (&self.kac_start, &self.kac_cols, &self.kac_vals);
        self.zc.with_local_slice(|kd| {
            Vector::with_slices([], [xp, kxp], |[], [xp, kxp]| {
                for (j, &i) in rows.iter().enumerate() {
                    xp[i] -= own[j];
                    kxp[i] -= kd[first + j];
                }
                for (a, &i) in adjacent.iter().enumerate() {
                    let kd_a: f64 =
                        (start[a]..start[a + 1]).map(|e| vals[e] * all[cols[e] as usize]).sum();
                    kxp[i] -= kd_a;
                }
            })
        })?
    }

    /// Every rank's values `own` on its layer rows, in the layer's order, into `gathered`.
    /// Collective.
    fn gather(&mut self, own: &[f64]) {
        if self.local {
            self.gathered.copy_from_slice(own);
            return;
        }
        SimpleCommunicator::world().all_gather_varcount_into(
            own,
            &mut mpi::datatype::PartitionMut::new(
                &mut self.gathered[..],
                &self.counts[..],
                &self.displs[..],
            ),
        );
    }

    /// The sweep's second layer solve, `z_C = K_CC^{-1} (r_C - K_CA z_A)` from the whole
    /// `r_C` and this rank's `K_CA z_A` (summed over the ranks here); returns the right-hand
    /// side (a buffer to keep). Collective.
    fn solve_second(&mut self, rc_all: Vec<f64>, partial: Vec<f64>) -> Result<Vec<f64>> {
        if self.local {
            self.summed.copy_from_slice(&partial);
        } else {
            SimpleCommunicator::world().all_reduce_into(
                &partial[..],
                &mut self.summed[..],
                SystemOperation::sum(),
            );
        }
        self.partial = partial;
        let mut t = rc_all;
        for (t, s) in t.iter_mut().zip(&self.summed) {
            *t -= s;
        }
        self.solve(&t)?;
        Ok(t)
    }

    /// `x = K_CC^{-1} b` with the whole layer's vectors, the same on every rank.
    fn solve(&mut self, b: &[f64]) -> Result<()> {
        self.rc.with_local_slice_mut(|rc| rc.copy_from_slice(b))?;
        self.ksp.solve(&self.rc, &mut self.zc)?;
        Ok(())
    }

    /// The sweep of the module's doc on the local slice `r` of the residual: this rank's
    /// `z_C` and the change of `z` on its coupled massive rows, kept for
    /// [`LayerBlock::add_last`]; returns this rank's change of `r.z` against Jacobi with zero
    /// on the layer rows. Collective.
    pub fn apply(&mut self, r: &[f64]) -> Result<f64> {
        // The whole r_C on every rank; y_C = K_CC^{-1} r_C.
        let own: Vec<f64> = self.rows.iter().map(|&i| r[i]).collect();
        self.gather(&own);
        let rc_all = std::mem::take(&mut self.gathered);
        self.solve(&rc_all)?;
        // dz = -D^{-1} K_AC y_C, z_A = D^{-1} r_A + dz, and this rank's K_CA z_A.
        let mut partial = std::mem::take(&mut self.partial);
        partial.iter_mut().for_each(|x| *x = 0.0);
        let mut rz_adjacent = 0.0;
        self.zc.with_local_slice(|y| {
            for a in 0..self.adjacent.len() {
                let span = self.kac_start[a]..self.kac_start[a + 1];
                let w: f64 =
                    span.clone().map(|e| self.kac_vals[e] * y[self.kac_cols[e] as usize]).sum();
                let ra = r[self.adjacent[a]];
                let dz = -self.d_adjacent[a] * w;
                let za = self.d_adjacent[a] * ra + dz;
                self.dz[a] = dz;
                rz_adjacent += ra * dz;
                for e in span {
                    partial[self.kac_cols[e] as usize] += self.kac_vals[e] * za;
                }
            }
        })?;
        // z_C = K_CC^{-1} (r_C - K_CA z_A).
        let t = self.solve_second(rc_all, partial)?;
        let (first, n) = (self.first, self.rows.len());
        let rz_layer = self.zc.with_local_slice(|z| {
            self.z_own.copy_from_slice(&z[first..first + n]);
            own.iter().zip(&self.z_own).map(|(a, b)| a * b).sum::<f64>()
        })?;
        self.gathered = t;
        Ok(rz_layer + rz_adjacent)
    }

    /// The same sweep around any preconditioner `inner` of the whole operator (block
    /// Jacobi with ILU, ...), whose restriction to the massive rows takes Jacobi's place:
    ///
    /// ```text
    ///   y_C = K_CC^{-1} r_C,   z_I = [B (r_I - K_IC y_C, 0)]_I,   z_C = K_CC^{-1} (r_C - K_CI z_I)
    /// ```
    /// `[B]_II` is SPD when `B` is, so the sweep stays symmetric. The layer's work is
    /// surface-sized as in [`LayerBlock::apply`]; `s` is a work vector like `r`. Collective.
    pub fn apply_around(
        &mut self,
        r: &Vector,
        z: &mut Vector,
        s: &mut Vector,
        inner: &mut dyn FnMut(&Vector, &mut Vector) -> Result<()>,
    ) -> Result<()> {
        let own: Vec<f64> = r.with_local_slice(|r| self.rows.iter().map(|&i| r[i]).collect())?;
        self.gather(&own);
        let rc_all = std::mem::take(&mut self.gathered);
        self.solve(&rc_all)?;
        // s = (r_I - K_IC y_C, 0).
        s.copy_from(r)?;
        let (rows, adjacent) = (&self.rows, &self.adjacent);
        let (start, cols, vals) = (&self.kac_start, &self.kac_cols, &self.kac_vals);
        self.zc.with_local_slice(|y| {
            s.with_local_slice_mut(|s| {
                for &i in rows {
                    s[i] = 0.0;
                }
                for (a, &i) in adjacent.iter().enumerate() {
                    s[i] -= (start[a]..start[a + 1])
                        .map(|e| vals[e] * y[cols[e] as usize])
                        .sum::<f64>();
                }
            })
        })??;
        inner(s, z)?;
        // K_CA z_A over the ranks; z_C = K_CC^{-1} (r_C - K_CA z_A).
        let mut partial = std::mem::take(&mut self.partial);
        partial.iter_mut().for_each(|x| *x = 0.0);
        z.with_local_slice(|z| {
            for (a, &i) in adjacent.iter().enumerate() {
                for e in start[a]..start[a + 1] {
                    partial[cols[e] as usize] += vals[e] * z[i];
                }
            }
        })?;
        let t = self.solve_second(rc_all, partial)?;
        let first = self.first;
        self.zc.with_local_slice(|zc| {
            z.with_local_slice_mut(|z| {
                for (j, &i) in self.rows.iter().enumerate() {
                    z[i] = zc[first + j];
                }
            })
        })??;
        self.gathered = t;
        Ok(())
    }

    /// This rank's layer rows (local indices, sorted), the order of [`LayerBlock::solve_own`].
    pub fn own_rows(&self) -> &[usize] {
        &self.rows
    }

    /// `x_C = K_CC^{-1} r_C` from every rank's layer values `own` (in [`LayerBlock::own_rows`]
    /// order): this rank's part of `x_C`. Collective.
    pub fn solve_own(&mut self, own: &[f64]) -> Result<Vec<f64>> {
        self.gather(own);
        let all = std::mem::take(&mut self.gathered);
        self.solve(&all)?;
        self.gathered = all;
        let (first, n) = (self.first, self.rows.len());
        self.zc.with_local_slice(|z| z[first..first + n].to_vec())
    }

    /// The layer's static response to the massive DOFs of `w`: `w_C = -K_CC^{-1} K_CA w_A`
    /// (the layer rows of `w` are overwritten), i.e. `(K w)_C = 0`: the massless rows in
    /// equilibrium with the rest of `w`. Collective.
    pub fn static_response(&mut self, w: &mut Vector) -> Result<()> {
        let mut partial = std::mem::take(&mut self.partial);
        partial.iter_mut().for_each(|x| *x = 0.0);
        let (adjacent, start, cols, vals) =
            (&self.adjacent, &self.kac_start, &self.kac_cols, &self.kac_vals);
        w.with_local_slice(|z| {
            for (a, &i) in adjacent.iter().enumerate() {
                for e in start[a]..start[a + 1] {
                    partial[cols[e] as usize] += vals[e] * z[i];
                }
            }
        })?;
        self.solve_second(vec![0.0; self.layer_dofs.len()], partial)?;
        let first = self.first;
        self.zc.with_local_slice(|zc| {
            w.with_local_slice_mut(|w| {
                for (j, &i) in self.rows.iter().enumerate() {
                    w[i] = zc[first + j];
                }
            })
        })?
    }

    /// Adds the last [`LayerBlock::apply`]'s `z_C` onto the layer rows of `p` (which Jacobi
    /// left zero) and its change of `z` onto the coupled rows.
    pub fn add_last(&self, p: &mut [f64]) -> Result<()> {
        for (j, &i) in self.rows.iter().enumerate() {
            p[i] += self.z_own[j];
        }
        for (a, &i) in self.adjacent.iter().enumerate() {
            p[i] += self.dz[a];
        }
        Ok(())
    }
}

/// The sweep as a PETSc preconditioner around the step KSP's own (`PCSHELL`,
/// [`crate::petsc::Ksp::wrap_pc`]): what the contact steps solve with, whose operator a
/// contact solver rewrites near the contact nodes, i.e. in the layer's rows. PETSc sets the
/// shell up again whenever the operator changed, and then `K_CC` is gathered and factored
/// again and `K_AC` collected again (surface-sized, beside the wrapped preconditioner's own
/// refactorization).
pub struct LayerShell {
    rows: Vec<usize>,
    dim: usize,
    local: bool,
    /// Set up once: with `local` a rank without layer rows has no block, and must not build
    /// again (the construction is collective, the later set-ups are not).
    built: bool,
    block: Option<LayerBlock>,
    s: Option<Vector>,
    /// The layer's rows over all ranks and its solver, once set up (for the reports).
    info: std::rc::Rc<std::cell::RefCell<Option<(usize, String)>>>,
}

impl LayerShell {
    /// For this rank's massless rows (local indices, sorted) with `dim` DOFs per node
    /// (`local`: each rank's own block, [`LayerBlock::new`] with `local`); `info` receives
    /// the layer's size and solver at each set-up.
    pub fn new(
        rows: Vec<usize>,
        dim: usize,
        local: bool,
        info: std::rc::Rc<std::cell::RefCell<Option<(usize, String)>>>,
    ) -> LayerShell {
        LayerShell { rows, dim, local, built: false, block: None, s: None, info }
    }
}

impl crate::petsc::PcShell for LayerShell {
    fn set_up(&mut self, op: &Matrix) -> Result<()> {
        if let Some(b) = self.block.as_mut() {
            return b.factor(op, None);
        }
        if !self.built {
            self.built = true;
            let rows = std::mem::take(&mut self.rows);
            let own = rows.len();
            self.block = LayerBlock::new(op, rows, None, self.dim, self.local)?;
            let report = LayerBlock::report(self.block.as_ref(), own, self.local)?;
            self.s = Some(op.create_vecs()?.0);
            if report.0 > 0 {
                *self.info.borrow_mut() = Some(report);
            }
        }
        Ok(())
    }

    fn apply(
        &mut self,
        r: &Vector,
        z: &mut Vector,
        inner: &mut dyn FnMut(&Vector, &mut Vector) -> Result<()>,
    ) -> Result<()> {
        match (self.block.as_mut(), self.s.as_mut()) {
            (Some(b), Some(s)) => b.apply_around(r, z, s, inner),
            _ => inner(r, z),
        }
    }
}
