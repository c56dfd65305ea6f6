//! The contact surface every rank holds whole: the facets of the contact groups, the cells
//! within two node rings of them (the layer cells and their vertex neighbours: what the contact
//! boundary check, the facet orientation and the mortar interface look at), and their nodes,
//! as a small [`Mesh`] with its own [`Partition`] view (global DOFs, owners, cell ranks).
//!
//! No rank holds the whole mesh, but contact needs the whole contact zone on every rank (the
//! active set, the mortar segments between facets of different ranks). Its size follows the
//! surface, not the volume, so it is gathered: each facet and cell comes from the one rank that
//! owns it, nodes from their owners. Entities are in original order (facets by gmsh tag), so
//! the surface, and everything contact computes on it, is the same on every rank and for every
//! partition.

use super::Partition;
use crate::comm::gather_all;
use crate::error::{Error, Result};
use crate::mesh::{Element, ElementKind, Mesh};
use mpi::topology::SimpleCommunicator;

/// The gathered contact surface (see the module doc).
pub struct Surface {
    pub mesh: Mesh,
    pub part: Partition,
    /// Original indices of the nodes on the facets of the groups (sorted).
    pub contact_nodes: Vec<usize>,
}

impl Surface {
    /// The original indices (sorted) of the nodes on the facets of `groups`, checked as contact
    /// boundaries (`mesh::topology::boundary_group`: errors name the group).
    pub fn original_nodes(&self, groups: &[&str]) -> Result<Vec<usize>> {
        let mut nodes = Vec::new();
        for g in groups {
            for e in crate::mesh::topology::boundary_group(&self.mesh, g)? {
                nodes.extend(e.nodes().into_iter().map(|v| self.part.node_original[v]));
            }
        }
        nodes.sort_unstable();
        nodes.dedup();
        Ok(nodes)
    }
}

/// Words of one gathered element: kind, gmsh tag, entity, original, natural, rank, 8 nodes.
const ELEMENT_WORDS: usize = 14;

fn pack(out: &mut Vec<u64>, e: &Element, ids: [usize; 3], original_nodes: impl Fn(usize) -> usize) {
    out.push(e.kind.gmsh_type() as u64);
    out.push(e.tag);
    out.push(e.entity as i64 as u64);
    out.extend(ids.iter().map(|&i| i as u64));
    let mut nodes = [u64::MAX; 8];
    for (k, &v) in e.nodes().iter().enumerate() {
        nodes[k] = original_nodes(v) as u64;
    }
    out.extend_from_slice(&nodes);
}

/// One gathered element: the element (nodes still original indices) and its three ids.
fn unpack(w: &[u64]) -> Result<(Element, [usize; 3])> {
    let kind = ElementKind::from_gmsh(w[0] as i32)
        .ok_or_else(|| Error::Internal(format!("gathered element of gmsh type {}", w[0])))?;
    let nodes: Vec<usize> = w[6..6 + kind.n_nodes()].iter().map(|&v| v as usize).collect();
    let e = Element::new(kind, &nodes, w[1], w[2] as i64 as i32);
    Ok((e, [w[3] as usize, w[4] as usize, w[5] as usize]))
}

/// Gather the surface of `groups` (contact boundaries, pair sides, layer groups) from this
/// rank's part of the mesh. Collective. Groups that are missing or not of dimension `dim - 1`
/// contribute nothing here: the contact set-up names them in its error.
pub fn gather(
    world: &SimpleCommunicator,
    mesh: &Mesh,
    part: &Partition,
    groups: &[&str],
) -> Result<Surface> {
    let orig = |v: usize| part.node_original[v];
    // 1. The facets of the groups, each from the owner of its smallest node.
    let mut entities: Vec<i32> = (mesh.groups.iter())
        .filter(|g| g.dim + 1 == mesh.dim && groups.contains(&g.name.as_str()))
        .flat_map(|g| g.entities.iter().copied())
        .collect();
    entities.sort_unstable();
    let mut words = Vec::new();
    for e in &mesh.boundary {
        if e.kind.dim() + 1 == mesh.dim
            && entities.binary_search(&e.entity).is_ok()
            && part.boundary_rank(e) == part.rank
        {
            pack(&mut words, e, [0, 0, part.rank], orig);
        }
    }
    let all = gather_all(world, &words);
    let mut facets: Vec<Element> =
        all.chunks(ELEMENT_WORDS).map(|w| unpack(w).map(|x| x.0)).collect::<Result<_>>()?;
    facets.sort_by_key(|e| e.tag);
    let mut contact_nodes: Vec<usize> = facets.iter().flat_map(|e| e.nodes().to_vec()).collect();
    contact_nodes.sort_unstable();
    contact_nodes.dedup();

    // 2. Own cells within two node rings of the facets: the cells touching a node of a layer
    //    cell (every local cell touching a node of an own cell is here, ghosts included).
    let on_contact: Vec<bool> =
        (0..mesh.n_nodes()).map(|v| contact_nodes.binary_search(&orig(v)).is_ok()).collect();
    let mut near = vec![false; mesh.n_nodes()];
    for e in &mesh.cells {
        if e.nodes().iter().any(|&v| on_contact[v]) {
            for v in e.nodes() {
                near[v] = true;
            }
        }
    }
    words.clear();
    for &c in &part.local_cells {
        let e = &mesh.cells[c];
        if e.nodes().iter().any(|&v| near[v]) {
            pack(
                &mut words,
                e,
                [part.cell_original[c] as usize, part.cell_natural[c] as usize, part.rank],
                orig,
            );
        }
    }
    let all = gather_all(world, &words);
    let mut cells: Vec<(Element, [usize; 3])> =
        all.chunks(ELEMENT_WORDS).map(unpack).collect::<Result<_>>()?;
    cells.sort_by_key(|c| c.1[0]);

    // 3. Their nodes, from the owners.
    let mut nodes: Vec<usize> = cells.iter().flat_map(|c| c.0.nodes().to_vec()).collect();
    nodes.extend_from_slice(&contact_nodes);
    nodes.sort_unstable();
    nodes.dedup();
    let mut ids = Vec::new();
    let mut xyz = Vec::new();
    for &v in &part.owned_nodes {
        if nodes.binary_search(&orig(v)).is_ok() {
            ids.extend([orig(v) as u64, mesh.node_tags[v], part.node_global[v] as u64]);
            xyz.extend_from_slice(&mesh.coords[v]);
        }
    }
    let ids = gather_all(world, &ids);
    let xyz = gather_all(world, &xyz);
    let mut order: Vec<usize> = (0..ids.len() / 3).collect();
    order.sort_by_key(|&i| ids[3 * i]);
    if order.len() != nodes.len() {
        return Err(Error::Internal(format!(
            "contact surface: {} nodes gathered for {} (ownership broken)",
            order.len(),
            nodes.len()
        )));
    }
    let local = |v: usize| nodes.binary_search(&v).expect("surface node");
    let relabel = |e: &Element| {
        let l: Vec<usize> = e.nodes().into_iter().map(|v| local(v)).collect();
        Element::new(e.kind, &l, e.tag, e.entity)
    };
    let node_global: Vec<usize> = order.iter().map(|&i| ids[3 * i + 2] as usize).collect();
    let offsets = &part.node_offsets;
    let node_owner: Vec<usize> =
        node_global.iter().map(|&g| offsets.partition_point(|&o| o <= g) - 1).collect();
    let surface = Mesh {
        dim: mesh.dim,
        coords: order.iter().map(|&i| [xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]]).collect(),
        node_tags: order.iter().map(|&i| ids[3 * i + 1]).collect(),
        cells: cells.iter().map(|c| relabel(&c.0)).collect(),
        boundary: facets.iter().map(relabel).collect(),
        groups: mesh.groups.clone(),
    };
    let surface_part = Partition {
        rank: part.rank,
        size: part.size,
        dim: part.dim,
        cell_rank: cells.iter().map(|c| c.1[2] as u32).collect(),
        owned_nodes: (0..nodes.len()).filter(|&l| node_owner[l] == part.rank).collect(),
        node_owner,
        node_global,
        node_offsets: part.node_offsets.clone(),
        local_cells: (0..cells.len()).filter(|&l| cells[l].1[2] == part.rank).collect(),
        node_original: nodes,
        cell_original: cells.iter().map(|c| c.1[0] as u32).collect(),
        cell_natural: cells.iter().map(|c| c.1[1] as u32).collect(),
        n_global_cells: part.n_global_cells,
        natural_global: Vec::new(),
        graph: std::sync::OnceLock::new(),
    };
    Ok(Surface { mesh: surface, part: surface_part, contact_nodes })
}
