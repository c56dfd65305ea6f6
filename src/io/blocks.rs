//! The mesh as the run file stores it, cut in the blocks each rank writes: nodes
//! `natural_range(n_nodes)`, cells `natural_range(n_cells)` in the file's cell order (kinds one
//! after the other), and each physical group's sorted node list at an offset. No rank needs
//! the whole mesh to write its blocks; [`MeshBlocks::whole`] cuts them from a whole mesh.

use crate::mesh::{file_cell_kinds, natural_cell_index, natural_range, ElementKind, Mesh};

/// This rank's blocks of the stored mesh (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct MeshBlocks {
    pub dim: usize,
    pub n_nodes: usize,
    /// (kind, number of cells of the whole mesh) in the file's order (gmsh type order).
    pub kinds: Vec<(ElementKind, usize)>,
    /// Coordinates and gmsh tags of the nodes of `natural_range(n_nodes, rank, size)`.
    pub coords: Vec<[f64; 3]>,
    pub tags: Vec<u64>,
    /// The cells of `natural_range(n_cells, rank, size)`: their nodes (original indices), one
    /// cell after the other (each with its kind's number of nodes, kinds in file order), and
    /// their ranks.
    pub cells: Vec<u64>,
    pub cell_rank: Vec<i32>,
    /// Per physical group (mesh order): its name, the offset of this rank's part of its sorted
    /// node list, the part, and the list's length.
    pub groups: Vec<(String, usize, Vec<u64>, usize)>,
}

impl MeshBlocks {
    pub fn n_cells(&self) -> usize {
        self.kinds.iter().map(|k| k.1).sum()
    }

    /// The blocks of a whole mesh whose cells went to ranks `cell_rank`.
    pub fn whole(mesh: &Mesh, cell_rank: &[usize], rank: usize, size: usize) -> MeshBlocks {
        let (lo, hi) = natural_range(mesh.n_nodes(), rank, size);
        let kinds = file_cell_kinds(mesh);
        let natural = natural_cell_index(mesh);
        let mut by_natural = vec![0; mesh.cells.len()];
        for (c, &k) in natural.iter().enumerate() {
            by_natural[k] = c;
        }
        let (clo, chi) = natural_range(mesh.cells.len(), rank, size);
        let groups = (mesh.groups.iter())
            .map(|g| {
                let nodes = mesh.group_nodes(&g.name).unwrap_or_default();
                let (a, b) = natural_range(nodes.len(), rank, size);
                let part = nodes[a..b].iter().map(|&v| v as u64).collect();
                (g.name.clone(), a, part, nodes.len())
            })
            .collect();
        MeshBlocks {
            dim: mesh.dim,
            n_nodes: mesh.n_nodes(),
            kinds: (kinds.iter())
                .map(|&k| (k, mesh.cells.iter().filter(|c| c.kind == k).count()))
                .collect(),
            coords: mesh.coords[lo..hi].to_vec(),
            tags: mesh.node_tags[lo..hi].to_vec(),
            cells: (by_natural[clo..chi].iter())
                .flat_map(|&c| mesh.cells[c].nodes().into_iter().map(|v| v as u64))
                .collect(),
            cell_rank: by_natural[clo..chi].iter().map(|&c| cell_rank[c] as i32).collect(),
            groups,
        }
    }
}
