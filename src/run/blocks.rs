//! The run file's mesh blocks (`io::MeshBlocks`) from this rank's part of the mesh: owned
//! nodes, own cells and owned group nodes are routed to the ranks whose natural blocks hold
//! them (`comm::route_to_blocks`), so the file is the same for every rank count and no rank
//! gathers the mesh.

use mpi::collective::SystemOperation;
use mpi::traits::*;

use super::domain::Domain;
use crate::comm::{offset_and_total, route_to_blocks, route_to_blocks_dense};
use crate::error::{Error, Result};
use crate::io::MeshBlocks;
use crate::mesh::ElementKind;

/// gmsh element types are below this (the kinds massfree reads).
const GMSH_TYPES: usize = 32;

pub fn mesh_blocks(d: &Domain) -> Result<MeshBlocks> {
    let (mesh, part, world) = (&d.mesh, &d.part, d.world);
    let n_nodes = part.n_global_nodes();
    // Nodes: original index, gmsh tag, coordinates (bits).
    let mut rows = Vec::with_capacity(part.owned_nodes.len() * 5);
    for &v in &part.owned_nodes {
        rows.extend([part.node_original[v] as u64, mesh.node_tags[v]]);
        rows.extend(mesh.coords[v].map(f64::to_bits));
    }
    let nodes = route_to_blocks_dense(world, n_nodes, 5, rows)?;
    let coords = nodes.chunks(5).map(|r| [r[2], r[3], r[4]].map(f64::from_bits)).collect();
    let tags = nodes.chunks(5).map(|r| r[1]).collect();
    drop(nodes);

    // Cells: natural index, rank, nodes (original, padded to the largest kind's count). This
    // is the largest exchange of the run's output: rows as narrow as the kinds allow, sent in
    // natural order (no copy) and placed, not sorted.
    let mut count = vec![0u64; GMSH_TYPES];
    for &c in &part.local_cells {
        count[mesh.cells[c].kind.gmsh_type() as usize] += 1;
    }
    let mut total = vec![0u64; GMSH_TYPES];
    world.all_reduce_into(&count[..], &mut total[..], SystemOperation::sum());
    let kinds: Vec<(ElementKind, usize)> = (0..GMSH_TYPES)
        .filter(|&t| total[t] > 0)
        .map(|t| {
            let k = ElementKind::from_gmsh(t as i32)
                .ok_or_else(|| Error::Internal(format!("cells of gmsh type {t}")))?;
            Ok((k, total[t] as usize))
        })
        .collect::<Result<_>>()?;
    let width = 2 + kinds.iter().map(|k| k.0.n_nodes()).max().unwrap_or(0);
    let mut rows = Vec::with_capacity(part.local_cells.len() * width);
    for &c in &part.local_cells {
        let at = rows.len();
        rows.extend([part.cell_natural[c] as u64, part.rank as u64]);
        rows.extend(mesh.cells[c].nodes().into_iter().map(|v| part.node_original[v] as u64));
        rows.resize(at + width, u64::MAX);
    }
    let placed = route_to_blocks_dense(world, part.n_global_cells, width, rows)?;
    let cell_rank = placed.chunks(width).map(|r| r[1] as i32).collect();
    let cells = (placed.chunks(width))
        .flat_map(|r| r[2..].iter().copied().filter(|&v| v != u64::MAX))
        .collect();
    drop(placed);

    // Groups: each owned node of a group (its owner holds every element touching it).
    let mut groups = Vec::with_capacity(mesh.groups.len());
    for g in &mesh.groups {
        let mut mine: Vec<u64> = (mesh.group_nodes(&g.name)?.into_iter())
            .filter(|&v| part.owns(v))
            .map(|v| part.node_original[v] as u64)
            .collect();
        mine.sort_unstable();
        let block = route_to_blocks(world, n_nodes, 1, &mine);
        let (offset, total) = offset_and_total(world, block.len());
        groups.push((g.name.clone(), offset, block, total));
    }
    Ok(MeshBlocks { dim: mesh.dim, n_nodes, kinds, coords, tags, cells, cell_rank, groups })
}
