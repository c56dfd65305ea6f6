//! The node graph of this rank's matrix rows: for each owned node, the global numbers of the
//! nodes it shares a cell with (sorted). Every matrix of the solver has this pattern (the
//! mass-free layer's `E_K^T M_K E_K` couples the nodes of one cell, its partner), so it is
//! built once and gives both the exact preallocation and the slots rows are summed into.
//! With the ghost layer, every cell containing an owned node is local: the rows are complete.

use super::Partition;
use crate::mesh::topology::node_cells;
use crate::mesh::Mesh;

#[derive(Debug, Clone, PartialEq)]
pub struct NodeGraph {
    /// Row `i` is the owned node of global number `first + i`: its columns are
    /// `cols[start[i]..start[i + 1]]`.
    pub start: Vec<usize>,
    /// Global node numbers, sorted within each row; 32 bits as PETSc's indices are (the
    /// global DOF count is below 2^31).
    pub cols: Vec<u32>,
    /// The global number of the first owned node.
    pub first: usize,
}

impl NodeGraph {
    pub fn build(mesh: &Mesh, part: &Partition) -> NodeGraph {
        let (off, list) = node_cells(mesh);
        let mut mark = vec![usize::MAX; mesh.n_nodes()];
        let mut start = Vec::with_capacity(part.owned_nodes.len() + 1);
        let mut cols = Vec::new();
        start.push(0);
        for &v in &part.owned_nodes {
            let row0 = cols.len();
            for &c in &list[off[v]..off[v + 1]] {
                for w in mesh.cells[c].nodes() {
                    if mark[w] != v {
                        mark[w] = v;
                        cols.push(part.node_global[w] as u32);
                    }
                }
            }
            cols[row0..].sort_unstable();
            start.push(cols.len());
        }
        NodeGraph { start, cols, first: part.node_offsets[part.rank] }
    }

    pub fn n_rows(&self) -> usize {
        self.start.len() - 1
    }

    /// The slot of column `col` (a global node number) in row `row`, if the pattern has it.
    #[inline]
    pub fn slot(&self, row: usize, col: usize) -> Option<usize> {
        let (a, b) = (self.start[row], self.start[row + 1]);
        self.cols[a..b].binary_search(&(col as u32)).ok().map(|k| a + k)
    }

    /// Exact preallocation per DOF row: columns in the diagonal block (owned by this rank)
    /// and off it, for `dim` components per node.
    pub fn preallocation(&self, part: &Partition) -> (Vec<i32>, Vec<i32>) {
        self.preallocation_for(part, part.dim)
    }

    /// The same for `dim` components per node (1: a node matrix).
    pub fn preallocation_for(&self, part: &Partition, dim: usize) -> (Vec<i32>, Vec<i32>) {
        let (lo, hi) = (part.node_offsets[part.rank], part.node_offsets[part.rank + 1]);
        let mut d_nnz = Vec::with_capacity(self.n_rows() * dim);
        let mut o_nnz = Vec::with_capacity(self.n_rows() * dim);
        for i in 0..self.n_rows() {
            let row = &self.cols[self.start[i]..self.start[i + 1]];
            let d = row.iter().filter(|&&g| (lo..hi).contains(&(g as usize))).count() as i32;
            let o = row.len() as i32 - d;
            for _ in 0..dim {
                d_nnz.push(d * dim as i32);
                o_nnz.push(o * dim as i32);
            }
        }
        (d_nnz, o_nnz)
    }
}
