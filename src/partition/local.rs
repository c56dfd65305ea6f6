//! This rank's part of a mesh: its own cells, one layer of ghost cells (every cell sharing a
//! node with an own cell), their nodes in local numbering, and the maps back to the original
//! (natural) numbering that users see.
//!
//! [`localize`] cuts it out of a whole mesh (the replicated path, kept to repeat old runs and
//! to check the distributed one against); the distributed reader builds the same thing without
//! any rank holding the whole mesh. Both follow one rule set, so their results are identical:
//! - local nodes and cells are in increasing original index (own and ghost interleaved);
//! - a node's owner is the lowest rank among all cells of the whole mesh that contain it, and
//!   owned nodes are numbered contiguously per rank in original order (as the replicated
//!   [`Partition`] numbers them);
//! - a boundary element (facet, edge, point of a physical group) is kept where one of its nodes
//!   is a node of an own cell: then every cell containing it is local (so a facet's cell count
//!   is right), and every group node this rank owns is found.
//!
//! With the vertex-neighbour ghost layer, every cell containing a node of an own cell is local:
//! a row of an owned node can be assembled, and a node's cell star is complete, from local data.

use super::Partition;
use crate::mesh::{natural_cell_index, natural_range, Element, Mesh};

/// This rank's part of `mesh` under the cell partition `cell_rank`, and its partition view.
pub fn localize(mesh: &Mesh, cell_rank: &[usize], rank: usize, size: usize) -> (Mesh, Partition) {
    let n = mesh.n_nodes();
    let whole = Partition::from_cell_ranks(mesh, rank, size, cell_rank.to_vec());
    // Own cells' nodes; every cell touching one of them is local (own or ghost).
    let mut touched = vec![false; n];
    for (c, e) in mesh.cells.iter().enumerate() {
        if cell_rank[c] == rank {
            for v in e.nodes() {
                touched[v] = true;
            }
        }
    }
    let cells: Vec<usize> = (0..mesh.cells.len())
        .filter(|&c| mesh.cells[c].nodes().iter().any(|&v| touched[v]))
        .collect();
    let mut local_of = vec![usize::MAX; n];
    for &c in &cells {
        for v in mesh.cells[c].nodes() {
            local_of[v] = 0;
        }
    }
    let mut nodes = Vec::new();
    for v in 0..n {
        if local_of[v] == 0 {
            local_of[v] = nodes.len();
            nodes.push(v);
        }
    }
    let relabel = |e: &Element| {
        let l: Vec<usize> = e.nodes().into_iter().map(|v| local_of[v]).collect();
        Element::new(e.kind, &l, e.tag, e.entity)
    };
    let boundary: Vec<Element> = (mesh.boundary.iter())
        .filter(|e| e.nodes().iter().any(|&v| touched[v]))
        .map(relabel)
        .collect();
    let local = Mesh {
        dim: mesh.dim,
        coords: nodes.iter().map(|&v| mesh.coords[v]).collect(),
        node_tags: nodes.iter().map(|&v| mesh.node_tags[v]).collect(),
        cells: cells.iter().map(|&c| relabel(&mesh.cells[c])).collect(),
        boundary,
        groups: mesh.groups.clone(),
    };
    let natural = natural_cell_index(mesh);
    let (lo, hi) = natural_range(n, rank, size);
    let part = Partition {
        rank,
        size,
        dim: mesh.dim,
        cell_rank: cells.iter().map(|&c| cell_rank[c] as u32).collect(),
        node_owner: nodes.iter().map(|&v| whole.node_owner[v]).collect(),
        node_global: nodes.iter().map(|&v| whole.node_global[v]).collect(),
        node_offsets: whole.node_offsets.clone(),
        // Local order is original order, and so is the global order of owned nodes.
        owned_nodes: (0..nodes.len()).filter(|&l| whole.node_owner[nodes[l]] == rank).collect(),
        local_cells: (0..cells.len()).filter(|&l| cell_rank[cells[l]] == rank).collect(),
        node_original: nodes,
        cell_natural: cells.iter().map(|&c| natural[c] as u32).collect(),
        cell_original: cells.iter().map(|&c| c as u32).collect(),
        n_global_cells: mesh.cells.len(),
        natural_global: whole.node_global[lo..hi].to_vec(),
        graph: std::sync::OnceLock::new(),
    };
    (local, part)
}
