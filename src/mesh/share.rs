//! Distributed reading of an MSH 4.1 file: each rank reads only its share of the nodes and
//! elements, and the ranks together number the nodes as `msh::read_msh` does, so that no rank
//! ever holds the whole mesh.
//!
//! A binary file is read by byte ranges: every rank scans the block headers (`blocks`), then
//! reads its even share of the node entries, of the cells (the elements of the highest
//! dimension, in file order) and of the boundary elements (lower-dimensional elements of an
//! entity with a physical tag). The original numbering of `read_msh` (nodes used by cells,
//! sorted by gmsh tag) is found through a directory: the range of gmsh tags is split evenly over
//! the ranks, each rank's directory part receives the nodes and the node tags the cells use in
//! its range, marks the used ones, and an exclusive scan over the ranks numbers them. Each rank
//! ends with its block `natural_range(n_nodes, rank, size)` of the original nodes and with its
//! cells and boundary elements in original node indices ([`Share`]). Checks and messages are
//! those of `read_msh`, and the first error in file order is the one reported.
//!
//! An ASCII file cannot be cut at byte offsets: up to [`ASCII_WHOLE_LIMIT`] bytes every rank
//! parses it whole with `read_msh` and keeps its share (small: a few 10^5 cells); above, rank 0
//! has gmsh convert it once to a binary file in a `.cache` folder beside it, which is then read
//! as above.

use super::blocks::{read_at, scan, ElementBlock, Layout, NodeBlock, Scan};
use super::exchange::{buffers, exchange, real, word};
use super::{natural_range, Element, Mesh, PhysicalGroup};
use crate::comm::offset_and_total;
use crate::error::{Error, Result};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::fs::File;
use std::path::Path;

/// ASCII files up to this size are parsed whole on every rank (see the module doc).
pub const ASCII_WHOLE_LIMIT: u64 = 16 << 20;

/// A rank's share of a mesh file: contiguous blocks of the original nodes, of the cells (file
/// order) and of the boundary elements (file order), elements in original node indices.
#[derive(Debug, Clone, PartialEq)]
pub struct Share {
    pub dim: usize,
    pub groups: Vec<PhysicalGroup>,
    pub n_nodes: usize,
    /// Original index of `coords[0]`: the block is `natural_range(n_nodes, rank, size)`.
    pub node_first: usize,
    pub coords: Vec<[f64; 3]>,
    pub node_tags: Vec<u64>,
    pub n_cells: usize,
    /// Original index of `cells[0]`: the block is `natural_range(n_cells, rank, size)`.
    pub cell_first: usize,
    pub cells: Vec<Element>,
    /// Row of each cell in the file's cell datasets (`mesh::natural_cell_index`).
    pub cell_natural: Vec<usize>,
    pub n_boundary: usize,
    /// Index in the whole mesh's `boundary` of `boundary[0]` (block as the cells').
    pub boundary_first: usize,
    pub boundary: Vec<Element>,
}

/// Read this rank's share of the mesh file at `path` (collective). ASCII files larger than
/// `ascii_limit` bytes are converted to binary first (see the module doc).
pub fn read_share(world: &SimpleCommunicator, path: &Path, ascii_limit: u64) -> Result<Share> {
    let source = path.display().to_string();
    let layout = agree(world, open_and_scan(path, &source))?;
    match layout {
        Some((file, layout)) => read_binary(world, &file, &layout, &source),
        None => {
            let len = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
            if len <= ascii_limit {
                let mesh = agree(world, super::msh::read_msh(path))?;
                Ok(Share::cut(mesh, world.rank() as usize, world.size() as usize))
            } else {
                let binary = super::convert::to_binary(world, path)?;
                let bsource = binary.display().to_string();
                match agree(world, open_and_scan(&binary, &bsource))? {
                    Some((file, layout)) => read_binary(world, &file, &layout, &bsource),
                    None => Err(Error::Mesh(format!("{bsource}: gmsh wrote an ASCII file"))),
                }
            }
        }
    }
}

/// The file and its layout, or None for an ASCII file.
fn open_and_scan(path: &Path, source: &str) -> Result<Option<(File, Layout)>> {
    let file = File::open(path)
        .map_err(|e| Error::Mesh(format!("cannot read mesh file {source}: {e}")))?;
    Ok(match scan(&file, source)? {
        Scan::Binary(layout) => Some((file, layout)),
        Scan::Ascii => None,
    })
}

/// A local result made collective: an error on any rank is the error on every rank (that of
/// the lowest failing rank, the first in file order where ranks read in file order), so that no
/// rank goes on into the next collective call alone.
pub fn agree<T>(world: &SimpleCommunicator, r: Result<T>) -> Result<T> {
    let size = world.size();
    let mine = if r.is_err() { world.rank() } else { size };
    let mut first = size;
    world.all_reduce_into(&mine, &mut first, SystemOperation::min());
    if first == size {
        return r;
    }
    let root = world.process_at_rank(first);
    let mut bytes = match &r {
        Err(e) if world.rank() == first => encode(e),
        _ => Vec::new(),
    };
    let mut len = bytes.len() as u64;
    root.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    Err(decode(&bytes))
}

/// An error as bytes (kind, then message) and back: only the kinds the reader returns.
fn encode(e: &Error) -> Vec<u8> {
    let (kind, text) = match e {
        Error::Mesh(m) => (b'M', m.clone()),
        Error::Partition(m) => (b'P', m.clone()),
        Error::Mpi(m) => (b'X', m.clone()),
        Error::Internal(m) => (b'I', m.clone()),
        other => (b'I', other.to_string()),
    };
    let mut b = vec![kind];
    b.extend(text.into_bytes());
    b
}

fn decode(b: &[u8]) -> Error {
    let text = String::from_utf8_lossy(b.get(1..).unwrap_or_default()).into_owned();
    match b.first() {
        Some(b'M') => Error::Mesh(text),
        Some(b'P') => Error::Partition(text),
        Some(b'X') => Error::Mpi(text),
        _ => Error::Internal(text),
    }
}

impl Share {
    /// This rank's share of a whole mesh (the small-file path, and the reference in tests).
    pub fn cut(mesh: Mesh, rank: usize, size: usize) -> Share {
        let (n0, n1) = natural_range(mesh.n_nodes(), rank, size);
        let (c0, c1) = natural_range(mesh.cells.len(), rank, size);
        let (b0, b1) = natural_range(mesh.boundary.len(), rank, size);
        let natural = super::natural_cell_index(&mesh);
        Share {
            dim: mesh.dim,
            n_nodes: mesh.n_nodes(),
            node_first: n0,
            coords: mesh.coords[n0..n1].to_vec(),
            node_tags: mesh.node_tags[n0..n1].to_vec(),
            n_cells: mesh.cells.len(),
            cell_first: c0,
            cells: mesh.cells[c0..c1].to_vec(),
            cell_natural: natural[c0..c1].to_vec(),
            n_boundary: mesh.boundary.len(),
            boundary_first: b0,
            boundary: mesh.boundary[b0..b1].to_vec(),
            groups: mesh.groups,
        }
    }
}

/// Marks of a tag query's answer.
const MISSING: u64 = u64::MAX;
const UNUSED: u64 = u64::MAX - 1;

/// The binary path (see the module doc).
fn read_binary(
    world: &SimpleCommunicator,
    file: &File,
    layout: &Layout,
    source: &str,
) -> Result<Share> {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let dim = layout.dim(source)?;
    let nodes = agree(world, read_node_entries(file, layout, rank, size, source))?;
    let cell_blocks: Vec<&ElementBlock> =
        layout.elements.iter().filter(|b| b.kind.dim() == dim).collect();
    let bnd_blocks: Vec<&ElementBlock> = (layout.elements.iter())
        .filter(|b| b.kind.dim() < dim && layout.has_physical(b.kind.dim(), b.entity))
        .collect();
    let n_cells: usize = cell_blocks.iter().map(|b| b.n).sum();
    let n_boundary: usize = bnd_blocks.iter().map(|b| b.n).sum();
    let (c0, c1) = natural_range(n_cells, rank, size);
    let (b0, b1) = natural_range(n_boundary, rank, size);
    let cells = agree(world, read_elements(file, &cell_blocks, c0, c1, source))?;
    let bnd = agree(world, read_elements(file, &bnd_blocks, b0, b1, source))?;

    let mut dir = TagDirectory::new(world, nodes)?;
    let cell_tags = unique_tags(&cells);
    let bnd_tags = unique_tags(&bnd);
    let (cell_idx, bnd_idx, n_nodes) = dir.number(world, &cell_tags, &bnd_tags)?;
    if let Some(t) = min_over_ranks(world, dir.duplicate) {
        return Err(Error::Mesh(format!("{source}: node tag {t} appears twice")));
    }
    let cells = agree(world, resolve(&cells, &cell_tags, &cell_idx, dim, source))?;
    let boundary = agree(world, resolve(&bnd, &bnd_tags, &bnd_idx, dim, source))?;
    let (node_first, coords, node_tags) = dir.natural_block(world, n_nodes)?;
    let cell_natural = natural_indices(&cell_blocks, c0, c1);
    Ok(Share {
        dim,
        groups: layout.groups.clone(),
        n_nodes,
        node_first,
        coords,
        node_tags,
        n_cells,
        cell_first: c0,
        cells,
        cell_natural,
        n_boundary,
        boundary_first: b0,
        boundary,
    })
}

/// The smallest `Some` over the ranks.
fn min_over_ranks(world: &SimpleCommunicator, x: Option<u64>) -> Option<u64> {
    let mut m = u64::MAX;
    world.all_reduce_into(&x.unwrap_or(u64::MAX), &mut m, SystemOperation::min());
    (m != u64::MAX).then_some(m)
}

/// 8-byte little-endian words from bytes.
fn words(bytes: &[u8]) -> impl Iterator<Item = u64> + '_ {
    bytes.chunks_exact(8).map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
}

/// Rows `lo..hi` of `row` words each of the table at byte offset `at`, passed to `each` in
/// order (read in chunks, so the bytes in memory stay small).
fn read_rows(
    file: &File,
    at: u64,
    row: usize,
    (lo, hi): (usize, usize),
    source: &str,
    mut each: impl FnMut(&[u64]),
) -> Result<()> {
    const CHUNK_ROWS: usize = 1 << 16;
    let mut i = lo;
    while i < hi {
        let m = (hi - i).min(CHUNK_ROWS);
        let bytes = read_at(file, at + (i * row * 8) as u64, m * row * 8, source)?;
        let w: Vec<u64> = words(&bytes).collect();
        w.chunks_exact(row).for_each(&mut each);
        i += m;
    }
    Ok(())
}

/// This rank's even share of the node entries in file order: (gmsh tag, coordinates).
fn read_node_entries(
    file: &File,
    layout: &Layout,
    rank: usize,
    size: usize,
    source: &str,
) -> Result<Vec<(u64, [f64; 3])>> {
    let total: usize = layout.nodes.iter().map(|b| b.n).sum();
    let range = natural_range(total, rank, size);
    let mut out = Vec::with_capacity(range.1 - range.0);
    // One block at a time: tags and coordinates are apart in the file.
    let mut first = 0usize;
    for b in &layout.nodes {
        let (lo, hi) = (range.0.max(first), range.1.min(first + b.n));
        if lo < hi {
            let local = (lo - first, hi - first);
            let start = out.len();
            read_rows(file, b.at, 1, local, source, |r| out.push((r[0], [0.0; 3])))?;
            let mut k = start;
            read_rows(file, b.coords_at(), NodeBlock::row_words(b), local, source, |r| {
                out[k].1 = [real(r[0]), real(r[1]), real(r[2])];
                k += 1;
            })?;
        }
        first += b.n;
    }
    Ok(out)
}

/// Elements `a..b` of `blocks` (counted one after the other), node tags not yet resolved.
struct RawElements {
    blocks: Vec<usize>,
    tags: Vec<u64>,
    /// Node tags, `kind.n_nodes()` per element.
    nodes: Vec<u64>,
    start: Vec<usize>,
    kinds: Vec<(super::ElementKind, i32)>,
}

fn read_elements(
    file: &File,
    blocks: &[&ElementBlock],
    a: usize,
    b: usize,
    source: &str,
) -> Result<RawElements> {
    let mut e = RawElements {
        blocks: Vec::with_capacity(b - a),
        tags: Vec::with_capacity(b - a),
        nodes: Vec::new(),
        start: vec![0],
        kinds: blocks.iter().map(|b| (b.kind, b.entity)).collect(),
    };
    // Blocks of one row width at a time, so that `read_rows` sees one width.
    let mut first = 0usize;
    for (k, blk) in blocks.iter().enumerate() {
        let (lo, hi) = (a.max(first), b.min(first + blk.n));
        if lo < hi {
            let range = (lo - first, hi - first);
            read_rows(file, blk.at, blk.row_words(), range, source, |r| {
                e.blocks.push(k);
                e.tags.push(r[0]);
                e.nodes.extend_from_slice(&r[1..]);
                e.start.push(e.nodes.len());
            })?;
        }
        first += blk.n;
    }
    Ok(e)
}

/// The sorted distinct node tags of some elements.
fn unique_tags(e: &RawElements) -> Vec<u64> {
    let mut t = e.nodes.clone();
    t.sort_unstable();
    t.dedup();
    t
}

/// The elements with node tags replaced by original indices (`idx[k]` answers `tags[k]`), or
/// the first failure in file order with `read_msh`'s message.
fn resolve(
    e: &RawElements,
    tags: &[u64],
    idx: &[u64],
    dim: usize,
    source: &str,
) -> Result<Vec<Element>> {
    let mut out = Vec::with_capacity(e.tags.len());
    let mut nodes = [0usize; 8];
    for i in 0..e.tags.len() {
        let (kind, entity) = e.kinds[e.blocks[i]];
        for (k, &t) in e.nodes[e.start[i]..e.start[i + 1]].iter().enumerate() {
            let v = idx[tags.binary_search(&t).expect("queried tag")];
            if v == MISSING {
                return Err(Error::Mesh(format!(
                    "{source}: {} (gmsh element tag {}) references node tag {t}, which is not \
                     in $Nodes",
                    kind.name(),
                    e.tags[i]
                )));
            }
            if v == UNUSED {
                return Err(Error::Mesh(format!(
                    "{source}: boundary {} (gmsh element tag {}, entity {entity}) uses node tag \
                     {t}, which belongs to no {dim}D cell",
                    kind.name(),
                    e.tags[i]
                )));
            }
            nodes[k] = v as usize;
        }
        out.push(Element::new(kind, &nodes[..kind.n_nodes()], e.tags[i], entity));
    }
    Ok(out)
}

/// The natural (file dataset) index of cells `a..b` of the cell blocks: kinds in gmsh type
/// order, file order within a kind (`mesh::natural_cell_index`).
fn natural_indices(blocks: &[&ElementBlock], a: usize, b: usize) -> Vec<usize> {
    let mut kinds: Vec<i32> =
        blocks.iter().filter(|b| b.n > 0).map(|b| b.kind.gmsh_type()).collect();
    kinds.sort_unstable();
    kinds.dedup();
    // Cells of the kinds before each kind, then of the same kind in earlier blocks.
    let mut seen: Vec<usize> = vec![0; kinds.len()];
    for blk in blocks {
        if let Some(k) = kinds.iter().position(|&t| t == blk.kind.gmsh_type()) {
            for s in &mut seen[k + 1..] {
                *s += blk.n;
            }
        }
    }
    let mut out = Vec::with_capacity(b - a);
    let mut first = 0usize;
    for blk in blocks.iter().filter(|b| b.n > 0) {
        let k = kinds.iter().position(|&t| t == blk.kind.gmsh_type()).expect("kind");
        let (lo, hi) = (a.max(first), b.min(first + blk.n));
        out.extend((lo..hi.max(lo)).map(|g| seen[k] + g - first));
        seen[k] += blk.n;
        first += blk.n;
    }
    out
}

/// This rank's part of the directory of gmsh node tags: the tags in its range, sorted, with
/// their coordinates.
struct TagDirectory {
    tags: Vec<u64>,
    coords: Vec<[f64; 3]>,
    /// The smallest tag seen twice here.
    duplicate: Option<u64>,
    /// The whole range of tags, `lo..=hi` (empty if hi < lo).
    lo: u64,
    hi: u64,
    /// Original index of each tag (or UNUSED), once numbered.
    original: Vec<u64>,
}

impl TagDirectory {
    /// The rank of the directory part holding `tag`.
    fn rank_of(&self, tag: u64, size: usize) -> usize {
        if tag < self.lo || tag > self.hi {
            return 0;
        }
        let span = (self.hi - self.lo) as u128 + 1;
        ((tag - self.lo) as u128 * size as u128 / span) as usize
    }

    /// Send every node entry read to its directory rank (collective).
    fn new(world: &SimpleCommunicator, nodes: Vec<(u64, [f64; 3])>) -> Result<TagDirectory> {
        let size = world.size() as usize;
        let lo_local = nodes.iter().map(|n| n.0).min().unwrap_or(u64::MAX);
        let hi_local = nodes.iter().map(|n| n.0).max().unwrap_or(0);
        let (mut lo, mut hi) = (0u64, 0u64);
        world.all_reduce_into(&lo_local, &mut lo, SystemOperation::min());
        world.all_reduce_into(&hi_local, &mut hi, SystemOperation::max());
        let mut dir = TagDirectory {
            tags: vec![],
            coords: vec![],
            duplicate: None,
            lo,
            hi,
            original: vec![],
        };
        let mut send = buffers(size);
        for (t, x) in nodes {
            send[dir.rank_of(t, size)].extend([t, word(x[0]), word(x[1]), word(x[2])]);
        }
        let got = exchange(world, send)?;
        let mut rows: Vec<&[u64]> = got.words.chunks_exact(4).collect();
        rows.sort_by_key(|r| r[0]);
        dir.duplicate = rows.windows(2).find(|w| w[0][0] == w[1][0]).map(|w| w[0][0]);
        dir.tags = rows.iter().map(|r| r[0]).collect();
        dir.coords = rows.iter().map(|r| [real(r[1]), real(r[2]), real(r[3])]).collect();
        Ok(dir)
    }

    /// Mark the tags the cells use, number them over the ranks in tag order, and answer the
    /// cells' and the boundary elements' tags (collective): original indices (MISSING for a
    /// tag not in $Nodes, UNUSED for one no cell uses), and the number of original nodes.
    fn number(
        &mut self,
        world: &SimpleCommunicator,
        cell_tags: &[u64],
        bnd_tags: &[u64],
    ) -> Result<(Vec<u64>, Vec<u64>, usize)> {
        let size = world.size() as usize;
        let mut send = buffers(size);
        let n_cell_q = |b: &mut Vec<u64>| b.push(0);
        send.iter_mut().for_each(n_cell_q);
        for &t in cell_tags {
            let d = self.rank_of(t, size);
            send[d].push(t);
            send[d][0] += 1;
        }
        for &t in bnd_tags {
            send[self.rank_of(t, size)].push(t);
        }
        let got = exchange(world, send)?;
        let find = |t: u64| self.tags.binary_search(&t).ok();
        let mut used = vec![false; self.tags.len()];
        for r in 0..size {
            let q = got.from(r);
            for &t in &q[1..1 + q[0] as usize] {
                if let Some(i) = find(t) {
                    used[i] = true;
                }
            }
        }
        let n_used = used.iter().filter(|&&u| u).count();
        let (first, n_nodes) = offset_and_total(world, n_used);
        let mut next = first as u64;
        self.original = used
            .iter()
            .map(|&u| {
                if u {
                    next += 1;
                    next - 1
                } else {
                    UNUSED
                }
            })
            .collect();
        let mut reply = buffers(size);
        for (r, out) in reply.iter_mut().enumerate() {
            let q = got.from(r);
            out.extend(q[1..].iter().map(|&t| find(t).map_or(MISSING, |i| self.original[i])));
        }
        let back = exchange(world, reply)?;
        // Answers come back per directory rank in the order asked.
        let mut pos = vec![0usize; size];
        for r in 0..size {
            pos[r] = back.start[r];
        }
        let mut answer = |tags: &[u64]| -> Vec<u64> {
            tags.iter()
                .map(|&t| {
                    let d = self.rank_of(t, size);
                    pos[d] += 1;
                    back.words[pos[d] - 1]
                })
                .collect()
        };
        let cell_idx = answer(cell_tags);
        let bnd_idx = answer(bnd_tags);
        Ok((cell_idx, bnd_idx, n_nodes))
    }

    /// The used nodes sent to the rank of their natural block (collective): that block's
    /// first original index, coordinates and gmsh tags.
    #[allow(clippy::type_complexity)]
    fn natural_block(
        &self,
        world: &SimpleCommunicator,
        n_nodes: usize,
    ) -> Result<(usize, Vec<[f64; 3]>, Vec<u64>)> {
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let starts: Vec<usize> = (0..size).map(|r| natural_range(n_nodes, r, size).0).collect();
        let mut send = buffers(size);
        for (i, &o) in self.original.iter().enumerate() {
            if o != UNUSED {
                let d = starts.partition_point(|&s| s <= o as usize) - 1;
                let x = self.coords[i];
                send[d].extend([o, self.tags[i], word(x[0]), word(x[1]), word(x[2])]);
            }
        }
        let got = exchange(world, send)?;
        let (lo, hi) = natural_range(n_nodes, rank, size);
        let mut coords = vec![[0.0; 3]; hi - lo];
        let mut tags = vec![0u64; hi - lo];
        for r in got.words.chunks_exact(5) {
            let i = r[0] as usize - lo;
            tags[i] = r[1];
            coords[i] = [real(r[2]), real(r[3]), real(r[4])];
        }
        Ok((lo, coords, tags))
    }
}
