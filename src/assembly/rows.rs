//! Matrices summed by rows before PETSc sees them: element blocks are added into this rank's
//! rows of the node graph (`partition::graph`), `dim x dim` per node pair; blocks of rows
//! owned by other ranks (an own cell's ghost nodes: surface-sized) are sent to their owners
//! in one all-to-all; then each owned node row goes to PETSc in one `MatSetValues` call with
//! sorted columns. Per-element insertion into PETSc (hash lookups, the stash for off-rank
//! rows) cost most of the assembly before.
//!
//! Every entry is summed over its cells in increasing original cell index, whatever the
//! partition: rows touched only by own cells as the cells come (local order is original
//! order), rows on the partition's seams (a ghost cell in their star) from their
//! contributions sorted by cell. So the matrices are the same to the last bit on any number
//! of ranks, and what differs between rank counts is only the solver's arithmetic.

use mpi::topology::SimpleCommunicator;

use crate::comm::all_to_all_rows;
use crate::error::{Error, Result};
use crate::mesh::Mesh;
use crate::partition::graph::NodeGraph;
use crate::partition::Partition;
use crate::petsc::{CsrBlocks, Matrix};

/// The storage of a [`RowSums`] kept between assemblies of one pattern: its blocks and its
/// seam rows.
pub struct RowStorage {
    blocks: Vec<f64>,
    seam: Vec<bool>,
    dim: usize,
    /// Where each block goes in the matrix's own arrays (found after the first fill; `None`
    /// while not found or when the matrix is not AIJ of this graph's node pattern).
    csr: Option<CsrFill>,
    /// The graph slots the first assembly found for its cells, in the order they came.
    slots: SlotCache,
}

/// The graph slots of each added cell's node pairs in rows summed here (not the seam's or
/// other ranks'), recorded by the first assembly of a kept storage and replayed by the
/// next ones, which add the same cells in the same order: no search per pair.
#[derive(Default)]
struct SlotCache {
    /// The cells in the order they were added, and where their slots start.
    cells: Vec<u32>,
    start: Vec<u32>,
    slots: Vec<u32>,
    /// Replaying: the next cell's index in `cells`.
    replay: Option<usize>,
    /// Recording (the first assembly of a storage that will be kept).
    record: bool,
}

/// The matrix's CSR structure and, per graph slot, the offset of its `dim` columns in each
/// of its node's `dim` rows (the same in all of them), [`OFF_BLOCK`] set for the
/// off-diagonal block.
struct CsrFill {
    layout: CsrBlocks,
    offset: Vec<u32>,
}

/// The flag of an offset into the off-diagonal block.
const OFF_BLOCK: u32 = 1 << 31;

impl CsrFill {
    #[allow(clippy::needless_range_loop)] // slots index the graph and the offsets alike
    /// The map of `graph`'s blocks (`d` components per node) into `mat`'s arrays, `None` if
    /// some block's columns are not `d` consecutive entries of every row of its node.
    fn find(graph: &NodeGraph, d: usize, mat: &Matrix) -> Result<Option<CsrFill>> {
        let Some(layout) = mat.csr_blocks()? else { return Ok(None) };
        if mat.ownership_range().0 != graph.first * d {
            return Ok(None);
        }
        let n_rows = graph.n_rows();
        let (first, last) = (graph.first, graph.first + n_rows);
        let mut offset = vec![0u32; graph.cols.len()];
        for i in 0..n_rows {
            for ci in 0..d {
                let lr = i * d + ci;
                for s in graph.start[i]..graph.start[i + 1] {
                    let h = graph.cols[s] as usize;
                    let (block, col, flag) = if (first..last).contains(&h) {
                        (&layout.diag, ((h - first) * d) as i32, 0)
                    } else {
                        let Some(off) = layout.off.as_ref() else { return Ok(None) };
                        let Ok(c) = layout.colmap.binary_search(&((h * d) as i32)) else {
                            return Ok(None);
                        };
                        let consecutive =
                            (0..d).all(|j| layout.colmap.get(c + j) == Some(&((h * d + j) as i32)));
                        if !consecutive {
                            return Ok(None);
                        }
                        (off, c as i32, OFF_BLOCK)
                    };
                    let (a, b) = (block.row_start[lr] as usize, block.row_start[lr + 1] as usize);
                    let row = &block.cols[a..b];
                    let Ok(p) = row.binary_search(&col) else { return Ok(None) };
                    if p + d > row.len() || (0..d).any(|j| row[p + j] != col + j as i32) {
                        return Ok(None);
                    }
                    let o = p as u32 | flag;
                    if ci == 0 {
                        offset[s] = o;
                    } else if offset[s] != o {
                        return Ok(None);
                    }
                }
            }
        }
        Ok(Some(CsrFill { layout, offset }))
    }
}

/// This rank's rows being summed (see the module doc).
pub struct RowSums<'g> {
    graph: &'g NodeGraph,
    dim: usize,
    /// `dim x dim` blocks, one per graph slot, row-major.
    blocks: Vec<f64>,
    /// Blocks for other ranks: rows of `3 + dim^2` words (row node, column node, original
    /// cell, values).
    away: Vec<u64>,
    away_rank: Vec<usize>,
    /// Owned rows on a seam (some cell of their star is another rank's).
    seam: Vec<bool>,
    /// Their contributions from own cells, summed at the end with the others' in cell order.
    deferred: Vec<u64>,
    /// Kept from a [`RowStorage`].
    csr: Option<CsrFill>,
    slots: SlotCache,
}

impl<'g> RowSums<'g> {
    pub fn new(graph: &'g NodeGraph, mesh: &Mesh, part: &Partition) -> RowSums<'g> {
        RowSums::with_components(graph, mesh, part, part.dim)
    }

    /// Rows of `dim` components per node (1: a node matrix, such as the scalar mass).
    pub fn with_components(
        graph: &'g NodeGraph,
        mesh: &Mesh,
        part: &Partition,
        dim: usize,
    ) -> RowSums<'g> {
        let mut seam = vec![false; graph.n_rows()];
        for (c, e) in mesh.cells.iter().enumerate() {
            if part.cell_rank[c] as usize != part.rank {
                for v in e.nodes() {
                    if part.owns(v) {
                        seam[part.node_global[v] - graph.first] = true;
                    }
                }
            }
        }
        RowSums {
            graph,
            dim,
            blocks: vec![0.0; graph.cols.len() * dim * dim],
            away: Vec::new(),
            away_rank: Vec::new(),
            seam,
            deferred: Vec::new(),
            csr: None,
            slots: SlotCache::default(),
        }
    }

    /// Add the dense block `vals` ((nodes.len() dim)^2, row-major, interlaced) coupling
    /// `nodes` (local node indices), the contribution of the cell of original index `cell`.
    pub fn add(
        &mut self,
        part: &Partition,
        cell: usize,
        nodes: &[usize],
        vals: &[f64],
    ) -> Result<()> {
        // The block loops with the block size known to the compiler (unrolled).
        match self.dim {
            1 => self.add_dim::<1>(part, cell, nodes, vals),
            2 => self.add_dim::<2>(part, cell, nodes, vals),
            3 => self.add_dim::<3>(part, cell, nodes, vals),
            d => Err(Error::Internal(format!("assembly: {d} components per node"))),
        }
    }

    #[inline(always)]
    fn add_dim<const D: usize>(
        &mut self,
        part: &Partition,
        cell: usize,
        nodes: &[usize],
        vals: &[f64],
    ) -> Result<()> {
        let nd = nodes.len() * D;
        // The cell's global node numbers, once (on the stack for cells; the mass-free
        // layer's blocks may couple more source nodes).
        let mut stack = [0usize; 32];
        let mut heap = Vec::new();
        let global: &mut [usize] = if nodes.len() <= stack.len() {
            &mut stack[..nodes.len()]
        } else {
            heap.resize(nodes.len(), 0);
            &mut heap
        };
        for (g, &v) in global.iter_mut().zip(nodes) {
            *g = part.node_global[v];
        }
        // A kept storage's slots: replayed when recorded, else recorded.
        let mut replay = None;
        if let Some(k) = self.slots.replay {
            if self.slots.cells.get(k) != Some(&(cell as u32)) {
                return Err(Error::Internal(format!(
                    "assembly: cell {cell} came where the recorded order has another"
                )));
            }
            replay = Some(self.slots.start[k] as usize);
            self.slots.replay = Some(k + 1);
        } else if self.slots.record {
            self.slots.cells.push(cell as u32);
            self.slots.start.push(self.slots.slots.len() as u32);
        }
        for (a, &v) in nodes.iter().enumerate() {
            let g = global[a];
            let row = g.wrapping_sub(self.graph.first);
            if part.owns(v) && !self.seam[row] {
                let (lo, hi) = (self.graph.start[row], self.graph.start[row + 1]);
                let cols = &self.graph.cols[lo..hi];
                for (b, &h) in global.iter().enumerate() {
                    let slot = match replay.as_mut() {
                        Some(at) => {
                            *at += 1;
                            self.slots.slots[*at - 1] as usize
                        }
                        None => {
                            let k = cols.binary_search(&(h as u32)).map_err(|_| {
                                Error::Internal(format!(
                                    "assembly: node pair ({g}, {h}) outside the pattern"
                                ))
                            })?;
                            if self.slots.record {
                                self.slots.slots.push((lo + k) as u32);
                            }
                            lo + k
                        }
                    };
                    let out = &mut self.blocks[slot * D * D..(slot + 1) * D * D];
                    for i in 0..D {
                        let src = &vals[(a * D + i) * nd + b * D..(a * D + i) * nd + b * D + D];
                        for j in 0..D {
                            out[i * D + j] += src[j];
                        }
                    }
                }
            } else {
                let own = part.owns(v);
                let out = if own { &mut self.deferred } else { &mut self.away };
                for (b, &h) in global.iter().enumerate() {
                    out.extend([g as u64, h as u64, cell as u64]);
                    for i in 0..D {
                        for j in 0..D {
                            out.push(vals[(a * D + i) * nd + b * D + j].to_bits());
                        }
                    }
                    if !own {
                        self.away_rank.push(part.node_owner[v]);
                    }
                }
            }
        }
        Ok(())
    }

    /// Send the other ranks' blocks, add what came, and hand every row to `mat` (collective).
    pub fn into_matrix(self, world: &SimpleCommunicator, mut mat: Matrix) -> Result<Matrix> {
        self.fill(world, &mut mat)?;
        Ok(mat)
    }

    /// [`RowSums::into_matrix`] into an existing matrix of this pattern. An AIJ matrix gets
    /// every entry of the pattern inserted, so it needs no zeroing and keeps its storage; a
    /// block AIJ one is added to.
    pub fn fill(mut self, world: &SimpleCommunicator, mat: &mut Matrix) -> Result<()> {
        self.write(world, mat)
    }

    /// [`RowSums::fill`], keeping the row storage for the next assembly of the same pattern
    /// ([`RowSums::from_storage`]: no new allocation, the seam rows not found again).
    pub fn fill_keeping(
        mut self,
        world: &SimpleCommunicator,
        mat: &mut Matrix,
    ) -> Result<RowStorage> {
        // Refills after the first go straight into the matrix's arrays (the pattern is
        // fixed: the same structure every time).
        let csr = match self.csr.take() {
            Some(csr) => {
                self.gather(world)?;
                self.write_csr(mat, &csr)?;
                Some(csr)
            }
            None => {
                self.write(world, mat)?;
                CsrFill::find(self.graph, self.dim, mat)?
            }
        };
        let mut slots = std::mem::take(&mut self.slots);
        slots.replay = slots.record.then_some(0);
        Ok(RowStorage { blocks: self.blocks, seam: self.seam, dim: self.dim, csr, slots })
    }

    /// Sums whose storage will be kept ([`RowSums::fill_keeping`]) and refilled by the same
    /// cells in the same order: the graph slots found now are replayed then.
    pub fn recording(mut self) -> RowSums<'g> {
        self.slots.record = true;
        self
    }

    /// Sums restarted on a kept storage (its blocks zeroed).
    pub fn from_storage(graph: &'g NodeGraph, mut storage: RowStorage) -> RowSums<'g> {
        storage.blocks.fill(0.0);
        RowSums {
            graph,
            dim: storage.dim,
            blocks: storage.blocks,
            away: Vec::new(),
            away_rank: Vec::new(),
            seam: storage.seam,
            deferred: Vec::new(),
            csr: storage.csr,
            slots: storage.slots,
        }
    }

    /// Every row's blocks into `mat`'s arrays through `csr` (see [`CsrFill`]). Collective
    /// (the matrix is assembled).
    fn write_csr(&self, mat: &mut Matrix, csr: &CsrFill) -> Result<()> {
        let d = self.dim;
        let g = self.graph;
        let (diag, off) = (&csr.layout.diag, csr.layout.off.as_ref());
        mat.with_csr_values_mut(&csr.layout, |dv, ov| {
            for i in 0..g.n_rows() {
                for ci in 0..d {
                    let lr = i * d + ci;
                    let a0 = diag.row_start[lr] as usize;
                    let b0 = off.map_or(0, |o| o.row_start[lr] as usize);
                    for s in g.start[i]..g.start[i + 1] {
                        let o = csr.offset[s];
                        let src = &self.blocks[(s * d + ci) * d..(s * d + ci + 1) * d];
                        let dst = if o & OFF_BLOCK == 0 {
                            &mut dv[a0 + o as usize..a0 + o as usize + d]
                        } else {
                            let p = b0 + (o & !OFF_BLOCK) as usize;
                            &mut ov[p..p + d]
                        };
                        dst.copy_from_slice(src);
                    }
                }
            }
        })
    }

    /// Send the other ranks' blocks and add what came (seam rows in cell order). Collective.
    fn gather(&mut self, world: &SimpleCommunicator) -> Result<()> {
        let d = self.dim;
        let width = 3 + d * d;
        let ranks = std::mem::take(&mut self.away_rank);
        let mut came = all_to_all_rows(world, width, &self.away, |k| ranks[k]);
        self.away = Vec::new();
        // The seam rows: every contribution, own and received, in (entry, cell) order.
        came.append(&mut self.deferred);
        let mut order: Vec<usize> = (0..came.len() / width).collect();
        order
            .sort_unstable_by_key(|&k| (came[k * width], came[k * width + 1], came[k * width + 2]));
        for k in order {
            let r = &came[k * width..(k + 1) * width];
            let (g, h) = (r[0] as usize, r[1] as usize);
            let row = g.checked_sub(self.graph.first).filter(|&x| x < self.graph.n_rows());
            let slot = row.and_then(|row| self.graph.slot(row, h)).ok_or_else(|| {
                Error::Internal(format!(
                    "assembly: received node pair ({g}, {h}) outside this rank's rows"
                ))
            })?;
            for (k, &bits) in r[3..].iter().enumerate() {
                self.blocks[slot * d * d + k] += f64::from_bits(bits);
            }
        }
        Ok(())
    }

    fn write(&mut self, world: &SimpleCommunicator, mat: &mut Matrix) -> Result<()> {
        self.gather(world)?;
        let d = self.dim;
        let mut rows = vec![0i32; d];
        let mut cols = Vec::new();
        let mut vals = Vec::new();
        if mat.is_baij()? {
            // One block row per node: the blocks as they are (row-major `d x d` each, the
            // layout `MatSetValuesBlocked` takes for one block row is the same interlaced one).
            for i in 0..self.graph.n_rows() {
                let (a, b) = (self.graph.start[i], self.graph.start[i + 1]);
                cols.clear();
                cols.extend(self.graph.cols[a..b].iter().map(|&h| h as i32));
                vals.clear();
                for ci in 0..d {
                    for s in a..b {
                        vals.extend_from_slice(
                            &self.blocks[(s * d + ci) * d..(s * d + ci + 1) * d],
                        );
                    }
                }
                mat.add_values_blocked(&[(self.graph.first + i) as i32], &cols, &vals)?;
            }
            mat.assemble()?;
            return Ok(());
        }
        for i in 0..self.graph.n_rows() {
            let (a, b) = (self.graph.start[i], self.graph.start[i + 1]);
            cols.clear();
            for &h in &self.graph.cols[a..b] {
                for j in 0..d {
                    cols.push((h as usize * d + j) as i32);
                }
            }
            vals.clear();
            for ci in 0..d {
                rows[ci] = ((self.graph.first + i) * d + ci) as i32;
                for s in a..b {
                    vals.extend_from_slice(&self.blocks[(s * d + ci) * d..(s * d + ci + 1) * d]);
                }
            }
            mat.set_values(&rows, &cols, &vals, false)?;
        }
        mat.assemble()
    }
}
