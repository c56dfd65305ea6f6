//! METIS element partition, node ownership, and the global DOF numbering.
//!
//! Every rank holds the whole mesh and runs METIS with the same fixed seed, so all ranks
//! agree on the partition without communication. A node is owned by the smallest rank among
//! the elements that contain it; owned nodes are numbered contiguously per rank (in original
//! order within a rank), DOFs are interlaced `node * dim + component` with block size `dim`.
//! Users only ever see the original (gmsh) node order, so results can be compared entry by
//! entry across rank counts.

pub mod band;
pub mod distribute;
pub mod gathered;
pub mod graph;
pub mod local;
pub mod rcb;
pub mod refine;
pub mod surface;
pub mod verify;

use crate::error::{Error, Result};
use crate::mesh::Mesh;

/// The fixed METIS seed: the partition must be the same on every rank and every run.
pub const METIS_SEED: i32 = 7;

#[derive(Debug, Clone)]
pub struct Partition {
    pub rank: usize,
    pub size: usize,
    pub dim: usize,
    /// Rank of each cell (METIS part). The per-cell arrays are 32-bit (12 bytes a cell less:
    /// 46 MB per rank at 3.9M DOFs on 2 ranks).
    pub cell_rank: Vec<u32>,
    /// Owning rank of each node.
    pub node_owner: Vec<usize>,
    /// Global (PETSc) node number of each original node.
    pub node_global: Vec<usize>,
    /// Rank r owns global node numbers `node_offsets[r]..node_offsets[r+1]`.
    pub node_offsets: Vec<usize>,
    /// Original indices of the nodes this rank owns, in global order.
    pub owned_nodes: Vec<usize>,
    /// Cells this rank assembles.
    pub local_cells: Vec<usize>,
    /// Original (natural) index of each node of this rank's mesh: its row in every nodal
    /// dataset a user sees. The identity when the rank holds the whole mesh.
    pub node_original: Vec<usize>,
    /// Index in the file's cell order of each cell of this rank's mesh.
    pub cell_original: Vec<u32>,
    /// Row of each cell of this rank's mesh in the file's cell datasets (kinds one after the
    /// other, see `io::natural_cell_index`).
    pub cell_natural: Vec<u32>,
    /// Cells of the whole mesh.
    pub n_global_cells: usize,
    /// Global node number of each node of this rank's natural block
    /// (`natural_block(n_global_nodes, rank, size)`): what output and restart scatter through.
    pub natural_global: Vec<usize>,
    /// The node graph of the rows, built once (every matrix shares the pattern).
    graph: std::sync::OnceLock<graph::NodeGraph>,
}

/// METIS keeps its random-number state in globals: calls from several threads (tests) must
/// not interleave, or the "fixed seed" partition changes.
static METIS_LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// METIS k-way partition of the cells' dual graph (cells adjacent when they share a facet).
pub fn partition_cells(mesh: &Mesh, nparts: usize) -> Result<Vec<usize>> {
    let ne = mesh.cells.len();
    if nparts <= 1 || ne == 0 {
        return Ok(vec![0; ne]);
    }
    let mut eptr: Vec<metis::Idx> = Vec::with_capacity(ne + 1);
    let mut eind: Vec<metis::Idx> = Vec::new();
    eptr.push(0);
    for c in &mesh.cells {
        eind.extend(c.nodes().into_iter().map(|v| v as metis::Idx));
        eptr.push(eind.len() as metis::Idx);
    }
    metis_parts(&eptr, &eind, mesh.dim, nparts)
}

/// METIS k-way partition of the cells given by their connectivity (`eptr`, `eind`: original
/// node indices, cells in original order) in dimension `dim`, with the fixed seed.
pub fn metis_parts(
    eptr: &[metis::Idx],
    eind: &[metis::Idx],
    dim: usize,
    nparts: usize,
) -> Result<Vec<usize>> {
    let ne = eptr.len() - 1;
    if nparts <= 1 || ne == 0 {
        return Ok(vec![0; ne]);
    }
    if ne < nparts {
        return Err(Error::Partition(format!(
            "the mesh has {ne} cells, fewer than the {nparts} ranks: use fewer ranks or a finer mesh"
        )));
    }
    // Facet neighbours: 2 shared nodes in 2D (an edge), 3 in 3D (a triangle or part of a quad face).
    let ncommon = if dim == 2 { 2 } else { 3 };
    let _guard = METIS_LOCK.lock().unwrap_or_else(|e| e.into_inner());
    let dual = metis::mesh_to_dual(eptr, eind, ncommon)
        .map_err(|e| Error::Partition(format!("METIS_MeshToDual failed: {e}")))?;
    let mut part: Vec<metis::Idx> = vec![0; ne];
    metis::Graph::new(1, nparts as metis::Idx, dual.xadj(), dual.adjncy())
        .map_err(|e| Error::Partition(format!("METIS graph: {e}")))?
        .set_option(metis::option::Seed(METIS_SEED))
        .part_kway(&mut part)
        .map_err(|e| Error::Partition(format!("METIS_PartGraphKway failed: {e}")))?;
    Ok(part.into_iter().map(|p| p as usize).collect())
}

/// How the cells are split over the ranks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Strategy {
    /// METIS k-way on the dual graph (small interfaces; the default before `Rcb`: repeats
    /// older runs).
    Metis,
    /// Equal-count slabs of cell centroids along x: a predictable cut through x = median,
    /// e.g. to make a contact zone straddle the partition boundary.
    SlabsX,
    /// The same along y: e.g. two bodies stacked in y each on its own rank(s), so that a
    /// contact pair's slave and master sides live on different ranks.
    SlabsY,
    /// Recursive coordinate bisection of the cell centroids (`rcb`): equal counts, box-shaped
    /// parts; computed from distributed data without a replicated graph or a gather (the
    /// default).
    #[default]
    Rcb,
}

impl Strategy {
    /// The rank of every cell of a whole mesh.
    pub fn cell_ranks(self, mesh: &Mesh, size: usize) -> Result<Vec<usize>> {
        Ok(match self {
            Strategy::Metis => partition_cells(mesh, size)?,
            Strategy::SlabsX => slabs(mesh, size, 0),
            Strategy::SlabsY => slabs(mesh, size, 1),
            Strategy::Rcb => rcb::rcb(mesh, size),
        })
    }

    pub fn from_name(name: &str) -> Option<Strategy> {
        match name {
            "metis" => Some(Strategy::Metis),
            "x-slabs" => Some(Strategy::SlabsX),
            "y-slabs" => Some(Strategy::SlabsY),
            "rcb" => Some(Strategy::Rcb),
            _ => None,
        }
    }
}

/// Cells sorted by centroid coordinate `axis` (ties by index), cut into `nparts` equal-count
/// slabs.
pub fn slabs(mesh: &Mesh, nparts: usize, axis: usize) -> Vec<usize> {
    let cx: Vec<f64> = mesh
        .cells
        .iter()
        .map(|c| {
            c.nodes().into_iter().map(|v| mesh.coords[v][axis]).sum::<f64>()
                / c.nodes().len() as f64
        })
        .collect();
    slab_cut(&cx, nparts)
}

/// The cells sorted by `cx` (ties by index), cut into `nparts` equal-count slabs.
pub fn slab_cut(cx: &[f64], nparts: usize) -> Vec<usize> {
    let mut order: Vec<usize> = (0..cx.len()).collect();
    order.sort_by(|&a, &b| cx[a].total_cmp(&cx[b]).then(a.cmp(&b)));
    let n = order.len();
    let mut part = vec![0; n];
    for (i, &c) in order.iter().enumerate() {
        part[c] = i * nparts / n.max(1);
    }
    part
}

impl Partition {
    /// Partition `mesh` over `size` ranks (METIS) and derive this rank's view.
    pub fn new(mesh: &Mesh, rank: usize, size: usize) -> Result<Partition> {
        Self::with_strategy(mesh, rank, size, Strategy::Metis)
    }

    pub fn with_strategy(
        mesh: &Mesh,
        rank: usize,
        size: usize,
        strategy: Strategy,
    ) -> Result<Partition> {
        Ok(Self::from_cell_ranks(mesh, rank, size, strategy.cell_ranks(mesh, size)?))
    }

    /// Ownership and numbering from a given cell partition (deterministic).
    pub fn from_cell_ranks(
        mesh: &Mesh,
        rank: usize,
        size: usize,
        cell_rank: Vec<usize>,
    ) -> Partition {
        let n = mesh.n_nodes();
        let mut node_owner = vec![usize::MAX; n];
        for (ci, c) in mesh.cells.iter().enumerate() {
            for v in c.nodes() {
                node_owner[v] = node_owner[v].min(cell_rank[ci]);
            }
        }
        let mut counts = vec![0usize; size + 1];
        for &o in &node_owner {
            counts[o + 1] += 1;
        }
        for r in 0..size {
            counts[r + 1] += counts[r];
        }
        let node_offsets = counts.clone();
        let mut next = counts;
        let mut node_global = vec![0usize; n];
        for v in 0..n {
            let o = node_owner[v];
            node_global[v] = next[o];
            next[o] += 1;
        }
        let owned_nodes: Vec<usize> = (0..n).filter(|&v| node_owner[v] == rank).collect();
        let local_cells: Vec<usize> =
            (0..mesh.cells.len()).filter(|&c| cell_rank[c] == rank).collect();
        let (lo, hi) = crate::mesh::natural_range(n, rank, size);
        let natural_global = node_global[lo..hi].to_vec();
        Partition {
            rank,
            size,
            dim: mesh.dim,
            cell_rank: cell_rank.iter().map(|&r| r as u32).collect(),
            node_owner,
            node_global,
            node_offsets,
            owned_nodes,
            local_cells,
            node_original: (0..n).collect(),
            cell_original: (0..mesh.cells.len() as u32).collect(),
            cell_natural: crate::mesh::natural_cell_index(mesh)
                .into_iter()
                .map(|c| c as u32)
                .collect(),
            n_global_cells: mesh.cells.len(),
            natural_global,
            graph: std::sync::OnceLock::new(),
        }
    }

    pub fn n_owned_nodes(&self) -> usize {
        self.node_offsets[self.rank + 1] - self.node_offsets[self.rank]
    }
    /// This rank's block of the natural (original) node order: what it writes and reads of
    /// every nodal dataset.
    pub fn natural_block(&self) -> (usize, usize) {
        crate::mesh::natural_range(self.n_global_nodes(), self.rank, self.size)
    }
    /// This rank's block of the natural cell order (cell datasets).
    pub fn natural_cell_block(&self) -> (usize, usize) {
        crate::mesh::natural_range(self.n_global_cells, self.rank, self.size)
    }
    /// Global DOF of component `comp` of original node `natural` in this rank's natural block.
    pub fn natural_dof(&self, natural: usize, comp: usize) -> usize {
        self.natural_global[natural - self.natural_block().0] * self.dim + comp
    }
    pub fn n_global_nodes(&self) -> usize {
        self.node_offsets[self.size]
    }
    pub fn n_owned_dofs(&self) -> usize {
        self.n_owned_nodes() * self.dim
    }
    pub fn n_global_dofs(&self) -> usize {
        self.n_global_nodes() * self.dim
    }
    /// First global DOF owned by this rank.
    pub fn first_dof(&self) -> usize {
        self.node_offsets[self.rank] * self.dim
    }
    /// Global DOF of component `comp` of original node `node`.
    #[inline]
    pub fn dof(&self, node: usize, comp: usize) -> usize {
        self.node_global[node] * self.dim + comp
    }
    /// The rank that integrates a boundary element: the owner of its smallest node
    /// (deterministic; local order is original order).
    pub fn boundary_rank(&self, e: &crate::mesh::Element) -> usize {
        let v = *e.nodes().iter().min().expect("boundary element has nodes");
        self.node_owner[v]
    }
    pub fn owns(&self, node: usize) -> bool {
        self.node_owner[node] == self.rank
    }

    /// The node graph of this rank's rows (built once: every matrix shares it).
    pub fn graph(&self, mesh: &Mesh) -> &graph::NodeGraph {
        self.graph.get_or_init(|| graph::NodeGraph::build(mesh, self))
    }

    /// Exact preallocation for a matrix coupling nodes that share a cell: per owned DOF row,
    /// the number of columns in the diagonal block (owned by this rank) and off it.
    pub fn preallocation(&self, mesh: &Mesh) -> (Vec<i32>, Vec<i32>) {
        self.graph(mesh).preallocation(self)
    }
}
