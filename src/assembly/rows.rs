//! Matrices summed by rows before PETSc sees them: element blocks are added into this rank's
//! rows of the node graph (`partition::graph`), `dim x dim` per node pair; blocks of rows
//! owned by other ranks (an own cell's ghost nodes: surface-sized) are sent to their owners
//! in one all-to-all; then each owned node row goes to PETSc in one `MatSetValues` call with
//! sorted columns. Per-element insertion into PETSc (hash lookups, the stash for off-rank
//! rows) cost most of the assembly before.

use mpi::topology::SimpleCommunicator;

use crate::comm::all_to_all_rows;
use crate::error::{Error, Result};
use crate::partition::graph::NodeGraph;
use crate::partition::Partition;
use crate::petsc::Matrix;

/// This rank's rows being summed (see the module doc).
pub struct RowSums<'g> {
    graph: &'g NodeGraph,
    dim: usize,
    /// `dim x dim` blocks, one per graph slot, row-major.
    blocks: Vec<f64>,
    /// Blocks for other ranks: rows of `2 + dim^2` words (row node, column node, values).
    away: Vec<u64>,
    away_rank: Vec<usize>,
}

impl<'g> RowSums<'g> {
    pub fn new(graph: &'g NodeGraph, dim: usize) -> RowSums<'g> {
        RowSums {
            graph,
            dim,
            blocks: vec![0.0; graph.cols.len() * dim * dim],
            away: Vec::new(),
            away_rank: Vec::new(),
        }
    }

    /// Add the dense block `vals` ((nodes.len() dim)^2, row-major, interlaced) coupling
    /// `nodes` (local node indices).
    pub fn add(&mut self, part: &Partition, nodes: &[usize], vals: &[f64]) -> Result<()> {
        let d = self.dim;
        let nd = nodes.len() * d;
        for (a, &v) in nodes.iter().enumerate() {
            let g = part.node_global[v];
            if part.owns(v) {
                let row = g - self.graph.first;
                for (b, &w) in nodes.iter().enumerate() {
                    let slot = self.graph.slot(row, part.node_global[w]).ok_or_else(|| {
                        Error::Internal(format!("assembly: node pair ({g}, {}) outside the pattern", part.node_global[w]))
                    })?;
                    let out = &mut self.blocks[slot * d * d..(slot + 1) * d * d];
                    for i in 0..d {
                        for j in 0..d {
                            out[i * d + j] += vals[(a * d + i) * nd + b * d + j];
                        }
                    }
                }
            } else {
                for (b, &w) in nodes.iter().enumerate() {
                    self.away.extend([g as u64, part.node_global[w] as u64]);
                    for i in 0..d {
                        for j in 0..d {
                            self.away.push(vals[(a * d + i) * nd + b * d + j].to_bits());
                        }
                    }
                    self.away_rank.push(part.node_owner[v]);
                }
            }
        }
        Ok(())
    }

    /// Send the other ranks' blocks, add what came, and hand every row to `mat` (collective).
    pub fn into_matrix(mut self, world: &SimpleCommunicator, mut mat: Matrix) -> Result<Matrix> {
        let d = self.dim;
        let width = 2 + d * d;
        let ranks = std::mem::take(&mut self.away_rank);
        let came = all_to_all_rows(world, width, &self.away, |k| ranks[k]);
        self.away = Vec::new();
        for r in came.chunks(width) {
            let (g, h) = (r[0] as usize, r[1] as usize);
            let row = g.checked_sub(self.graph.first).filter(|&x| x < self.graph.n_rows());
            let slot = row.and_then(|row| self.graph.slot(row, h)).ok_or_else(|| {
                Error::Internal(format!("assembly: received node pair ({g}, {h}) outside this rank's rows"))
            })?;
            for (k, &bits) in r[2..].iter().enumerate() {
                self.blocks[slot * d * d + k] += f64::from_bits(bits);
            }
        }
        let mut rows = vec![0i32; d];
        let mut cols = Vec::new();
        let mut vals = Vec::new();
        for i in 0..self.graph.n_rows() {
            let (a, b) = (self.graph.start[i], self.graph.start[i + 1]);
            cols.clear();
            for &h in &self.graph.cols[a..b] {
                for j in 0..d {
                    cols.push((h * d + j) as i32);
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
        mat.assemble()?;
        Ok(mat)
    }
}
