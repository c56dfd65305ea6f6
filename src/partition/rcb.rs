//! Recursive coordinate bisection (`--partition rcb`): the scalable default partition.
//!
//! The cells' centroids are cut in two along the longest side of their bounding box, the
//! parts' sizes in proportion to the ranks each side gets (`k / 2` and `k - k / 2` of `k`),
//! and each side again, until every part is one rank's. A cut is the `n_left`-th smallest key
//! `(centroid coordinate, original cell index)` (total order, ties by index), so the result
//! depends only on the mesh, the rank count and nothing else, and the parts have equal counts
//! (within one cell per level) and the shape of boxes: their interfaces are planes, with about
//! as many cut facets as METIS's on simple bodies (measured in the distributed mesh test).
//!
//! [`rcb`] computes it on a whole mesh (the replicated path); [`rcb_distributed`] computes the
//! same cuts with every rank holding only its block of cells: bounding boxes and counts are
//! reductions, and each cut is found by a 16-way search over the keys in which every round is
//! one reduction of 15 counts per part; no rank gathers the cells or a graph.

use crate::mesh::Mesh;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// The mean of the points, per axis in the order given (the slabs' formula).
pub fn centroid(points: &[[f64; 3]]) -> [f64; 3] {
    let n = points.len() as f64;
    let mean = |a: usize| points.iter().map(|x| x[a]).sum::<f64>() / n;
    [mean(0), mean(1), mean(2)]
}

/// The cut key of a cell: its centroid coordinate's bits in `total_cmp` order, then its index.
fn key(x: f64, index: usize) -> u128 {
    let b = x.to_bits();
    let ordered = if b >> 63 == 1 { !b } else { b | 1 << 63 };
    (ordered as u128) << 64 | index as u128
}

/// One part still to be cut: the ranks `r0..r0 + k`.
#[derive(Debug, Clone, Copy)]
struct Part {
    r0: usize,
    k: usize,
}

impl Part {
    fn children(self) -> [Part; 2] {
        let kl = self.k / 2;
        [Part { r0: self.r0, k: kl }, Part { r0: self.r0 + kl, k: self.k - kl }]
    }
    /// How many of `n` cells go to the first child.
    fn n_left(self, n: u64) -> u64 {
        (n as u128 * (self.k / 2) as u128 / self.k as u128) as u64
    }
}

/// The axis of the longest side of a box (the first of equal ones).
fn longest(lo: &[f64; 3], hi: &[f64; 3], dim: usize) -> usize {
    let mut axis = 0;
    for a in 1..dim {
        if hi[a] - lo[a] > hi[axis] - lo[axis] {
            axis = a;
        }
    }
    axis
}

/// The rank of every cell of a whole mesh: the cuts, then the interfaces smoothed
/// (`refine`).
pub fn rcb(mesh: &Mesh, nparts: usize) -> Vec<usize> {
    let mut part = cuts(mesh, nparts);
    super::refine::refine(mesh, &mut part, nparts);
    part
}

/// The bisection alone on a whole mesh.
pub fn cuts(mesh: &Mesh, nparts: usize) -> Vec<usize> {
    let cent: Vec<[f64; 3]> =
        mesh.cells.iter().map(|c| centroid(&mesh.element_coords(c))).collect();
    let mut part = vec![0; cent.len()];
    let mut todo =
        vec![((0..cent.len()).collect::<Vec<usize>>(), Part { r0: 0, k: nparts.max(1) })];
    while let Some((mut cells, p)) = todo.pop() {
        if p.k == 1 {
            cells.iter().for_each(|&c| part[c] = p.r0);
            continue;
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &c in &cells {
            for a in 0..3 {
                lo[a] = lo[a].min(cent[c][a]);
                hi[a] = hi[a].max(cent[c][a]);
            }
        }
        let axis = longest(&lo, &hi, mesh.dim);
        cells.sort_by_key(|&c| key(cent[c][axis], c));
        let right = cells.split_off(p.n_left(cells.len() as u64) as usize);
        let [l, r] = p.children();
        todo.push((cells, l));
        todo.push((right, r));
    }
    part
}

/// The search for one cut: the key at position `n_left` among the part's keys lies in
/// `lo..=hi`, and `below` keys of the part (over all ranks) are smaller than `lo`.
struct Cut {
    lo: u128,
    hi: u128,
    n_left: u64,
    below: u64,
    /// This rank's keys in `lo..=hi` and how many of its keys are below `lo`.
    keys: Vec<u128>,
    local_below: u64,
}

/// Pivots per round of the search: `WAYS - 1` counts per part per reduction.
const WAYS: u128 = 16;

impl Cut {
    fn done(&self) -> bool {
        self.lo == self.hi
    }
    /// The pivots of this round (at most `WAYS - 1`, all in `lo + 1..=hi`).
    fn pivots(&self) -> Vec<u128> {
        if self.done() {
            return vec![];
        }
        let step = (self.hi - self.lo) / WAYS + 1;
        (1..WAYS).map(|j| self.lo.saturating_add(j * step)).take_while(|&p| p <= self.hi).collect()
    }
    /// Narrow to the sub-interval holding the cut, given the global counts below each pivot.
    fn narrow(&mut self, pivots: &[u128], below: &[u64]) {
        let j = below.iter().take_while(|&&c| c <= self.n_left).count();
        if j > 0 {
            self.lo = pivots[j - 1];
            self.below = below[j - 1];
        }
        if j < pivots.len() {
            self.hi = pivots[j] - 1;
        }
        let (lo, hi) = (self.lo, self.hi);
        self.local_below += self.keys.iter().filter(|&&k| k < lo).count() as u64;
        self.keys.retain(|&k| k >= lo && k <= hi);
    }
}

/// The rank of each of this rank's cells, given their centroids and the original index of
/// the first (this rank holds a contiguous block); the same as [`rcb`] on the whole mesh
/// (collective).
pub fn rcb_distributed(
    world: &SimpleCommunicator,
    cent: &[[f64; 3]],
    first: usize,
    dim: usize,
    nparts: usize,
) -> Vec<usize> {
    let mut which = vec![0usize; cent.len()];
    let mut parts = vec![Part { r0: 0, k: nparts.max(1) }];
    while parts.iter().any(|p| p.k > 1) {
        let (lo, hi, n) = boxes(world, cent, &which, parts.len());
        let axes: Vec<usize> = (0..parts.len()).map(|g| longest(&lo[g], &hi[g], dim)).collect();
        let mut cuts: Vec<Cut> = (0..parts.len())
            .map(|g| Cut {
                lo: key(lo[g][axes[g]], 0),
                hi: key(hi[g][axes[g]], usize::MAX),
                n_left: parts[g].n_left(n[g]),
                below: 0,
                keys: vec![],
                local_below: 0,
            })
            .collect();
        for (i, &g) in which.iter().enumerate() {
            cuts[g].keys.push(key(cent[i][axes[g]], first + i));
        }
        for (g, c) in cuts.iter_mut().enumerate() {
            if parts[g].k == 1 || n[g] == 0 {
                c.hi = c.lo;
            }
        }
        search(world, &mut cuts);
        let mut next = Vec::with_capacity(2 * parts.len());
        let mut child = Vec::with_capacity(parts.len());
        for p in &parts {
            child.push(next.len());
            if p.k == 1 {
                next.push(*p);
            } else {
                next.extend(p.children());
            }
        }
        for (i, g) in which.iter_mut().enumerate() {
            let split = parts[*g].k > 1 && key(cent[i][axes[*g]], first + i) >= cuts[*g].lo;
            *g = child[*g] + split as usize;
        }
        parts = next;
    }
    which.iter().map(|&g| parts[g].r0).collect()
}

/// Per part: the bounding box of the centroids and the number of cells (collective).
#[allow(clippy::type_complexity)]
fn boxes(
    world: &SimpleCommunicator,
    cent: &[[f64; 3]],
    which: &[usize],
    n_parts: usize,
) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<u64>) {
    let mut lo = vec![f64::INFINITY; 3 * n_parts];
    let mut hi = vec![f64::NEG_INFINITY; 3 * n_parts];
    let mut n = vec![0u64; n_parts];
    for (x, &g) in cent.iter().zip(which) {
        for a in 0..3 {
            lo[3 * g + a] = lo[3 * g + a].min(x[a]);
            hi[3 * g + a] = hi[3 * g + a].max(x[a]);
        }
        n[g] += 1;
    }
    let (mut glo, mut ghi, mut gn) = (lo.clone(), hi.clone(), n.clone());
    world.all_reduce_into(&lo[..], &mut glo[..], SystemOperation::min());
    world.all_reduce_into(&hi[..], &mut ghi[..], SystemOperation::max());
    world.all_reduce_into(&n[..], &mut gn[..], SystemOperation::sum());
    let three = |v: &[f64]| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    (three(&glo), three(&ghi), gn)
}

/// Run the searches of all cuts together until each has found its key (collective: one
/// reduction of `WAYS - 1` counts per cut per round).
fn search(world: &SimpleCommunicator, cuts: &mut [Cut]) {
    let w = (WAYS - 1) as usize;
    loop {
        // Every rank narrows the same intervals from the same counts: they agree on the end.
        if cuts.iter().all(Cut::done) {
            return;
        }
        let pivots: Vec<Vec<u128>> = cuts.iter().map(Cut::pivots).collect();
        let mut counts = vec![0u64; w * cuts.len()];
        for (g, c) in cuts.iter().enumerate() {
            let p = &pivots[g];
            let slot = &mut counts[w * g..w * g + p.len()];
            let mut bucket = vec![0u64; p.len() + 1];
            for &k in &c.keys {
                bucket[p.partition_point(|&q| q <= k)] += 1;
            }
            // Bucket b holds the keys in p[b-1]..p[b]: those below p[j] are the ones below lo
            // and buckets 0..=j.
            let mut acc = c.local_below;
            for j in 0..p.len() {
                acc += bucket[j];
                slot[j] = acc;
            }
        }
        let mut global = vec![0u64; counts.len()];
        world.all_reduce_into(&counts[..], &mut global[..], SystemOperation::sum());
        for (g, c) in cuts.iter_mut().enumerate() {
            let p = &pivots[g];
            if !p.is_empty() {
                c.narrow(p, &global[w * g..w * g + p.len()]);
            }
        }
    }
}
