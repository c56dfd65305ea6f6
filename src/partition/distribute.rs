//! Each rank's part of the mesh built from the shares the ranks read (`mesh::share`), without
//! any rank holding the whole mesh: the same `(Mesh, Partition)` as [`super::local::localize`]
//! cuts out of a whole mesh, field for field.
//!
//! 1. Partition: every rank computes the ranks of the cells of its block (`rcb` from the
//!    distributed centroids; `metis` and the slabs on rank 0 over gathered connectivity or
//!    coordinates, to repeat old runs: `gathered`).
//! 2. Node directory: the rank of a node's natural block (`natural_range`) learns from the cell
//!    readers the ranks of the cells touching it (its "touch list", sorted); the owner is the
//!    first (lowest) of them, and an exclusive scan over the ranks of the per-owner counts gives
//!    the global numbers (owned nodes contiguous per rank, in original order).
//! 3. Delivery: each reader asks the directory about the nodes of its cells and boundary
//!    elements (owner, global number, tag, coordinates, touch list) and sends every cell to each
//!    rank in the touch lists of its nodes, with those nodes: that is the cell's own rank and
//!    every rank with an own cell sharing a node with it, i.e. exactly the ranks whose ghost
//!    layer holds it. A boundary element goes the same way to every rank with an own cell on
//!    one of its nodes, which is `localize`'s rule.
//! 4. Each rank sorts what it received by original index: its local cells, nodes and boundary
//!    elements in increasing original order, as `localize` orders them.

use super::{gathered, rcb, Partition, Strategy};
use crate::comm::block_range;
use crate::error::{Error, Result};
use crate::mesh::exchange::{buffers, exchange, real, word};
use crate::mesh::share::{read_share, Share, ASCII_WHOLE_LIMIT};
use crate::mesh::{natural_range, Element, ElementKind, Mesh};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::path::Path;
use std::time::Instant;

/// Wall times of the front end on this rank, in seconds.
#[derive(Debug, Clone, Copy, Default)]
pub struct FrontTimes {
    /// Reading the share of the file and numbering the nodes.
    pub read: f64,
    /// Computing the cell ranks.
    pub partition: f64,
    /// Node directory, ghost layer, migration and the local view.
    pub distribute: f64,
}

/// This rank's part of the mesh file at `path` under `strategy`, read without any rank holding
/// the whole mesh (collective).
pub fn read_local(
    world: &SimpleCommunicator,
    path: &Path,
    strategy: Strategy,
) -> Result<(Mesh, Partition)> {
    read_local_timed(world, path, strategy, ASCII_WHOLE_LIMIT).map(|(m, p, _)| (m, p))
}

/// [`read_local`] with the phases' times and the ASCII size limit (`mesh::share`).
pub fn read_local_timed(
    world: &SimpleCommunicator,
    path: &Path,
    strategy: Strategy,
    ascii_limit: u64,
) -> Result<(Mesh, Partition, FrontTimes)> {
    let t = Instant::now();
    let share = read_share(world, path, ascii_limit)?;
    let read = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let ranks = cell_ranks(world, &share, strategy)?;
    let partition = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (mesh, part) = localize_share(world, &share, &ranks)?;
    let distribute = t.elapsed().as_secs_f64();
    Ok((mesh, part, FrontTimes { read, partition, distribute }))
}

/// The rank of each cell of this rank's share (collective).
pub fn cell_ranks(
    world: &SimpleCommunicator,
    share: &Share,
    strategy: Strategy,
) -> Result<Vec<usize>> {
    let size = world.size() as usize;
    match strategy {
        Strategy::Metis => gathered::metis(world, share),
        Strategy::SlabsX | Strategy::SlabsY => {
            let axis = if strategy == Strategy::SlabsX { 0 } else { 1 };
            let cx: Vec<f64> = centroids(world, share)?.iter().map(|c| c[axis]).collect();
            gathered::slabs(world, &cx, share.n_cells)
        }
        Strategy::Rcb => {
            let cent = centroids(world, share)?;
            let mut ranks = rcb::rcb_distributed(world, &cent, share.cell_first, share.dim, size);
            drop(cent);
            super::band::refine_distributed(world, share, &mut ranks, size)?;
            Ok(ranks)
        }
    }
}

/// The centroids of this rank's cells, their nodes' coordinates asked of the directory.
fn centroids(world: &SimpleCommunicator, share: &Share) -> Result<Vec<[f64; 3]>> {
    let need = nodes_of(&share.cells);
    let words = ask(world, share, &need, |i, out| {
        out.extend(share.coords[i].iter().map(|&x| word(x)));
    })?;
    let coords: Vec<[f64; 3]> =
        words.chunks_exact(3).map(|w| [real(w[0]), real(w[1]), real(w[2])]).collect();
    let mut xs = Vec::with_capacity(8);
    Ok((share.cells.iter())
        .map(|c| {
            xs.clear();
            xs.extend(c.nodes().iter().map(|v| coords[need.binary_search(v).expect("asked")]));
            rcb::centroid(&xs)
        })
        .collect())
}

/// Whether each of this rank's cells has a node in cells of two ranks or more (collective).
pub(super) fn on_interface(
    world: &SimpleCommunicator,
    share: &Share,
    cell_rank: &[usize],
) -> Result<Vec<bool>> {
    let dir = NodeDirectory::build(world, share, cell_rank)?;
    let need = nodes_of(&share.cells);
    let shared = ask(world, share, &need, |i, out| out.push((dir.touch(i).len() > 1) as u64))?;
    Ok((share.cells.iter())
        .map(|c| c.nodes().iter().any(|v| shared[need.binary_search(v).expect("asked")] == 1))
        .collect())
}

/// The sorted distinct nodes of some elements.
fn nodes_of(elements: &[Element]) -> Vec<usize> {
    let mut v: Vec<usize> = elements.iter().flat_map(|e| e.nodes().into_iter()).collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// The rank of each node's natural block.
fn block_of(n_nodes: usize, size: usize) -> impl Fn(usize) -> usize {
    let starts: Vec<usize> = (0..size).map(|r| block_range(n_nodes, r, size).0).collect();
    move |v| starts.partition_point(|&s| s <= v) - 1
}

/// Ask the ranks of the natural blocks about the nodes `need` (sorted original indices):
/// `answer(i, out)` appends the words about node `first + i` of the answering rank's block.
/// Returns the answers' words in the order of `need` (collective).
fn ask(
    world: &SimpleCommunicator,
    share: &Share,
    need: &[usize],
    answer: impl Fn(usize, &mut Vec<u64>),
) -> Result<Vec<u64>> {
    let size = world.size() as usize;
    let dest = block_of(share.n_nodes, size);
    let mut send = buffers(size);
    for &v in need {
        send[dest(v)].push(v as u64);
    }
    let got = exchange(world, send)?;
    let mut reply = buffers(size);
    for (r, out) in reply.iter_mut().enumerate() {
        for &v in got.from(r) {
            answer(v as usize - share.node_first, out);
        }
    }
    drop(got);
    // `need` is sorted and the blocks are in rank order: the answers come back in its order.
    Ok(exchange(world, reply)?.words)
}

/// This rank's part of the node directory: for each node of its natural block, the ranks of
/// the cells touching it, its owner (the lowest of them) and its global number.
struct NodeDirectory {
    touch_start: Vec<usize>,
    touch: Vec<usize>,
    global: Vec<usize>,
    node_offsets: Vec<usize>,
}

impl NodeDirectory {
    fn build(world: &SimpleCommunicator, share: &Share, cell_rank: &[usize]) -> Result<Self> {
        let size = world.size() as usize;
        let dest = block_of(share.n_nodes, size);
        let mut pairs: Vec<(usize, usize)> = (share.cells.iter().zip(cell_rank))
            .flat_map(|(c, &r)| c.nodes().into_iter().map(move |v| (v, r)))
            .collect();
        pairs.sort_unstable();
        pairs.dedup();
        let mut send = buffers(size);
        for (v, r) in pairs {
            send[dest(v)].extend([v as u64, r as u64]);
        }
        let got = exchange(world, send)?;
        let n = share.coords.len();
        let mut pairs: Vec<(usize, usize)> = (got.words.chunks_exact(2))
            .map(|w| (w[0] as usize - share.node_first, w[1] as usize))
            .collect();
        drop(got);
        pairs.sort_unstable();
        pairs.dedup();
        let mut touch_start = vec![0usize; n + 1];
        for &(i, _) in &pairs {
            touch_start[i + 1] += 1;
        }
        for i in 0..n {
            touch_start[i + 1] += touch_start[i];
        }
        let touch: Vec<usize> = pairs.into_iter().map(|(_, r)| r).collect();
        if let Some(i) = (0..n).find(|&i| touch_start[i] == touch_start[i + 1]) {
            return Err(Error::Internal(format!(
                "node {} is in no cell of the distributed mesh",
                share.node_first + i
            )));
        }
        let owner = |i: usize| touch[touch_start[i]];
        let (node_offsets, mut next) = numbering(world, (0..n).map(owner), size);
        let global = (0..n)
            .map(|i| {
                next[owner(i)] += 1;
                next[owner(i)] - 1
            })
            .collect();
        Ok(NodeDirectory { touch_start, touch, global, node_offsets })
    }

    fn touch(&self, i: usize) -> &[usize] {
        &self.touch[self.touch_start[i]..self.touch_start[i + 1]]
    }

    /// Words about node `i` of the block: owner, global number, gmsh tag, coordinates, the
    /// number of touching ranks and those ranks.
    fn describe(&self, share: &Share, i: usize, out: &mut Vec<u64>) {
        let t = self.touch(i);
        out.extend([t[0] as u64, self.global[i] as u64, share.node_tags[i]]);
        out.extend(share.coords[i].iter().map(|&x| word(x)));
        out.push(t.len() as u64);
        out.extend(t.iter().map(|&r| r as u64));
    }
}

/// The node offsets per rank and, for this rank's block, the first global number of each
/// owner's nodes in it, from the owners of the block's nodes (collective: a scan and a sum of
/// one count per rank).
fn numbering(
    world: &SimpleCommunicator,
    owners: impl Iterator<Item = usize>,
    size: usize,
) -> (Vec<usize>, Vec<usize>) {
    let mut count = vec![0u64; size];
    for o in owners {
        count[o] += 1;
    }
    let mut before = vec![0u64; size];
    world.exclusive_scan_into(&count[..], &mut before[..], SystemOperation::sum());
    if world.rank() == 0 {
        before.iter_mut().for_each(|b| *b = 0);
    }
    let mut total = vec![0u64; size];
    world.all_reduce_into(&count[..], &mut total[..], SystemOperation::sum());
    let mut offsets = vec![0usize; size + 1];
    for r in 0..size {
        offsets[r + 1] = offsets[r] + total[r] as usize;
    }
    let next = (0..size).map(|r| offsets[r] + before[r] as usize).collect();
    (offsets, next)
}

/// What the directory said about one node this rank asked for.
struct NodeInfo {
    owner: u64,
    global: u64,
    tag: u64,
    x: [u64; 3],
    /// Range in the touch list of all answers.
    touch: (usize, usize),
}

/// Parse the directory's answers (see [`NodeDirectory::describe`]), in the order asked.
fn parse_answers(words: &[u64], n: usize) -> Result<(Vec<NodeInfo>, Vec<usize>)> {
    let mut info = Vec::with_capacity(n);
    let mut touch = Vec::new();
    let mut p = 0usize;
    let bad = || Error::Internal("node directory answer cut short".into());
    for _ in 0..n {
        let w = words.get(p..p + 7).ok_or_else(bad)?;
        let k = w[6] as usize;
        let list = words.get(p + 7..p + 7 + k).ok_or_else(bad)?;
        let start = touch.len();
        touch.extend(list.iter().map(|&r| r as usize));
        info.push(NodeInfo {
            owner: w[0],
            global: w[1],
            tag: w[2],
            x: [w[3], w[4], w[5]],
            touch: (start, touch.len()),
        });
        p += 7 + k;
    }
    Ok((info, touch))
}

/// Words of a delivered cell: original index, rank, natural index, gmsh type, tag, entity,
/// 8 original nodes (padded); of a boundary element: index, gmsh type, tag, entity, 8 nodes;
/// of a node: original index, owner, global number, tag, 3 coordinates.
const CELL_WORDS: usize = 14;
const BND_WORDS: usize = 12;
const NODE_WORDS: usize = 7;

fn push_element(out: &mut Vec<u64>, ids: &[u64], e: &Element) {
    out.extend_from_slice(ids);
    out.extend([e.kind.gmsh_type() as u64, e.tag, e.entity as i64 as u64]);
    let mut nodes = [u64::MAX; 8];
    for (k, &v) in e.nodes().iter().enumerate() {
        nodes[k] = v as u64;
    }
    out.extend_from_slice(&nodes);
}

/// The element in words `w` (after its `n_ids` ids), its nodes mapped by `local`.
fn pull_element(w: &[u64], n_ids: usize, local: impl Fn(u64) -> usize) -> Result<Element> {
    let kind = ElementKind::from_gmsh(w[n_ids] as i32)
        .ok_or_else(|| Error::Internal(format!("delivered element of gmsh type {}", w[n_ids])))?;
    let nodes: Vec<usize> =
        w[n_ids + 3..n_ids + 3 + kind.n_nodes()].iter().map(|&v| local(v)).collect();
    Ok(Element::new(kind, &nodes, w[n_ids + 1], w[n_ids + 2] as i64 as i32))
}

/// The ranks that receive an element: the union of its nodes' touch lists.
fn receivers(e: &Element, need: &[usize], info: &[NodeInfo], touch: &[usize]) -> Vec<usize> {
    let mut to: Vec<usize> = Vec::with_capacity(8);
    for v in e.nodes() {
        let n = &info[need.binary_search(&v).expect("asked")];
        to.extend_from_slice(&touch[n.touch.0..n.touch.1]);
    }
    to.sort_unstable();
    to.dedup();
    to
}

/// This rank's part of the mesh from the shares and the ranks of this rank's cells
/// (collective); see the module doc.
pub fn localize_share(
    world: &SimpleCommunicator,
    share: &Share,
    cell_rank: &[usize],
) -> Result<(Mesh, Partition)> {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let dir = NodeDirectory::build(world, share, cell_rank)?;
    let mut need = nodes_of(&share.cells);
    need.extend(nodes_of(&share.boundary));
    need.sort_unstable();
    need.dedup();
    let words = ask(world, share, &need, |i, out| dir.describe(share, i, out))?;
    let (info, touch) = parse_answers(&words, need.len())?;
    drop(words);

    let mut cells_to = buffers(size);
    let mut nodes_for: Vec<Vec<usize>> = vec![Vec::new(); size];
    for (i, c) in share.cells.iter().enumerate() {
        let ids =
            [(share.cell_first + i) as u64, cell_rank[i] as u64, share.cell_natural[i] as u64];
        for d in receivers(c, &need, &info, &touch) {
            push_element(&mut cells_to[d], &ids, c);
            nodes_for[d].extend(c.nodes().iter().map(|v| need.binary_search(v).expect("asked")));
        }
    }
    let mut bnd_to = buffers(size);
    for (i, b) in share.boundary.iter().enumerate() {
        for d in receivers(b, &need, &info, &touch) {
            push_element(&mut bnd_to[d], &[(share.boundary_first + i) as u64], b);
        }
    }
    let mut nodes_to = buffers(size);
    for (d, mut list) in nodes_for.into_iter().enumerate() {
        list.sort_unstable();
        list.dedup();
        for k in list {
            let n = &info[k];
            nodes_to[d].extend([need[k] as u64, n.owner, n.global, n.tag]);
            nodes_to[d].extend_from_slice(&n.x);
        }
    }
    let cells = exchange(world, cells_to)?.words;
    let nodes = exchange(world, nodes_to)?.words;
    let bnd = exchange(world, bnd_to)?.words;
    assemble(share, &dir, rank, size, &cells, &nodes, &bnd)
}

/// Rows of `width` words sorted by their first word, duplicates (same first word) dropped.
fn sorted_rows(words: &[u64], width: usize) -> Vec<&[u64]> {
    let mut rows: Vec<&[u64]> = words.chunks_exact(width).collect();
    rows.sort_unstable_by_key(|r| r[0]);
    rows.dedup_by_key(|r| r[0]);
    rows
}

/// The local mesh and partition from the rows this rank received.
fn assemble(
    share: &Share,
    dir: &NodeDirectory,
    rank: usize,
    size: usize,
    cells: &[u64],
    nodes: &[u64],
    bnd: &[u64],
) -> Result<(Mesh, Partition)> {
    let nodes = sorted_rows(nodes, NODE_WORDS);
    let cells = sorted_rows(cells, CELL_WORDS);
    let bnd = sorted_rows(bnd, BND_WORDS);
    let original: Vec<usize> = nodes.iter().map(|r| r[0] as usize).collect();
    let local = |v: u64| original.binary_search(&(v as usize)).unwrap_or(usize::MAX);
    let mesh_cells =
        (cells.iter()).map(|r| pull_element(r, 3, local)).collect::<Result<Vec<Element>>>()?;
    if mesh_cells.iter().any(|c| c.nodes().contains(&usize::MAX)) {
        return Err(Error::Internal("a delivered cell came without its nodes".into()));
    }
    let boundary =
        bnd.iter().map(|r| pull_element(r, 1, local)).collect::<Result<Vec<Element>>>()?;
    let mesh = Mesh {
        dim: share.dim,
        coords: nodes.iter().map(|r| [real(r[4]), real(r[5]), real(r[6])]).collect(),
        node_tags: nodes.iter().map(|r| r[3]).collect(),
        cells: mesh_cells,
        boundary,
        groups: share.groups.clone(),
    };
    let node_owner: Vec<usize> = nodes.iter().map(|r| r[1] as usize).collect();
    let cell_rank: Vec<usize> = cells.iter().map(|r| r[1] as usize).collect();
    let part = Partition {
        rank,
        size,
        dim: share.dim,
        owned_nodes: (0..nodes.len()).filter(|&l| node_owner[l] == rank).collect(),
        local_cells: (0..cells.len()).filter(|&l| cell_rank[l] == rank).collect(),
        cell_rank: cell_rank.iter().map(|&r| r as u32).collect(),
        node_owner,
        node_global: nodes.iter().map(|r| r[2] as usize).collect(),
        node_offsets: dir.node_offsets.clone(),
        node_original: original.clone(),
        cell_original: cells.iter().map(|r| r[0] as u32).collect(),
        cell_natural: cells.iter().map(|r| r[2] as u32).collect(),
        n_global_cells: share.n_cells,
        natural_global: dir.global.clone(),
        graph: std::sync::OnceLock::new(),
    };
    debug_assert_eq!(natural_range(share.n_nodes, rank, size).0, share.node_first);
    Ok((mesh, part))
}
