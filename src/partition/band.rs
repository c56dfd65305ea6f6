//! The interface smoothing of `refine` on a distributed partition: each rank holds the band
//! cells of its block of cells (those with a node in cells of two ranks, found through the node
//! directory), their facet neighbours are matched through a directory of facets (a facet goes
//! to the rank given by a hash of its sorted nodes; two band cells with the same facet are
//! neighbours), and each rank tells the holders of its band cells' neighbours their parts, at
//! the start and after every round. Only band cells and their facets travel: surface-sized.

use super::distribute::on_interface;
use super::refine::{bounds, grant, max_facets, Band, Counter, ROUNDS};
use crate::error::Result;
use crate::mesh::exchange::{buffers, exchange};
use crate::mesh::natural_range;
use crate::mesh::share::Share;
use crate::mesh::topology::facet_key;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// Sums over the ranks by MPI: an exclusive scan and a sum.
struct Ranks<'a>(&'a SimpleCommunicator);

impl Counter for Ranks<'_> {
    fn before_and_total(&self, x: &[u64]) -> (Vec<u64>, Vec<u64>) {
        let mut before = vec![0u64; x.len()];
        self.0.exclusive_scan_into(x, &mut before[..], SystemOperation::sum());
        if self.0.rank() == 0 {
            before.iter_mut().for_each(|b| *b = 0);
        }
        let mut total = vec![0u64; x.len()];
        self.0.all_reduce_into(x, &mut total[..], SystemOperation::sum());
        (before, total)
    }
}

/// Smooth the ranks `part` of this rank's cells (collective); the same moves as
/// `refine::refine` on the whole mesh.
pub fn refine_distributed(
    world: &SimpleCommunicator,
    share: &Share,
    part: &mut [usize],
    nparts: usize,
) -> Result<()> {
    if nparts <= 1 {
        return Ok(());
    }
    let mut band = build(world, share, part)?;
    let mut local = vec![0u64; nparts];
    part.iter().for_each(|&p| local[p] += 1);
    let mut counts = vec![0u64; nparts];
    world.all_reduce_into(&local[..], &mut counts[..], SystemOperation::sum());
    let limits = bounds(share.n_cells, nparts);
    for round in 0..ROUNDS {
        let wishes = band.wishes(round % 2 == 0, nparts);
        let granted = grant(&wishes, &mut counts, limits, max_facets(share.dim), &Ranks(world));
        let mut moved = Vec::new();
        for (w, _) in wishes.iter().zip(&granted).filter(|(_, &g)| g) {
            band.part[w.slot] = w.to;
            band.moved[w.slot] = true;
            part[band.cells[w.slot] - share.cell_first] = w.to;
            moved.push(w.slot);
        }
        tell_neighbours(world, share.n_cells, &mut band, &moved)?;
    }
    Ok(())
}

/// The rank holding cell `c` (the blocks `natural_range(n_cells, r, size)`).
fn holder(n_cells: usize, size: usize) -> impl Fn(usize) -> usize {
    let starts: Vec<usize> = (0..size).map(|r| natural_range(n_cells, r, size).0).collect();
    move |c| starts.partition_point(|&s| s <= c) - 1
}

/// A facet's directory rank: a hash of its sorted nodes.
fn facet_rank(key: &[u64; 4], size: usize) -> usize {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &k in key {
        h = (h ^ k).wrapping_mul(0x0000_0100_0000_01b3);
        h ^= h >> 29;
    }
    (h % size as u64) as usize
}

/// This rank's band cells with their neighbours and the neighbours' parts (collective).
fn build(world: &SimpleCommunicator, share: &Share, part: &[usize]) -> Result<Band> {
    let size = world.size() as usize;
    let inside = on_interface(world, share, part)?;
    let mine: Vec<usize> = (0..share.cells.len()).filter(|&i| inside[i]).collect();
    // Facets of the band cells to their directory ranks.
    let mut send = buffers(size);
    for &i in &mine {
        let e = &share.cells[i];
        for f in e.kind.facets() {
            let key = facet_key(&e.nodes(), f).map(|v| v as u64);
            let to = &mut send[facet_rank(&key, size)];
            to.extend_from_slice(&key);
            to.push((share.cell_first + i) as u64);
        }
    }
    let got = exchange(world, send)?;
    let mut rows: Vec<&[u64]> = got.words.chunks_exact(5).collect();
    rows.sort_unstable();
    // Facets of exactly two band cells: each cell's holder learns the other.
    let hold = holder(share.n_cells, size);
    let mut pairs = buffers(size);
    let mut k = 0;
    while k < rows.len() {
        let n = rows[k..].iter().take_while(|r| r[..4] == rows[k][..4]).count();
        if n == 2 {
            let (a, b) = (rows[k][4], rows[k + 1][4]);
            pairs[hold(a as usize)].extend([a, b]);
            pairs[hold(b as usize)].extend([b, a]);
        }
        k += n;
    }
    drop(rows);
    drop(got);
    let got = exchange(world, pairs)?;
    let mut pairs: Vec<(usize, usize)> =
        got.words.chunks_exact(2).map(|w| (w[0] as usize, w[1] as usize)).collect();
    pairs.sort_unstable();
    let mut band = Band { start: vec![0], ..Band::default() };
    let mut k = 0;
    for &i in &mine {
        let c = share.cell_first + i;
        band.cells.push(c);
        band.n_facets.push(share.cells[i].kind.facets().len());
        band.part.push(part[i]);
        band.moved.push(false);
        while k < pairs.len() && pairs[k].0 == c {
            band.nbr.push(pairs[k].1);
            band.nbr_part.push(usize::MAX);
            k += 1;
        }
        band.start.push(band.nbr.len());
    }
    let all: Vec<usize> = (0..band.cells.len()).collect();
    tell_neighbours(world, share.n_cells, &mut band, &all)?;
    Ok(band)
}

/// Send the parts of the band cells `slots` to the holders of their neighbours, and update
/// this rank's neighbour parts from what the others send (collective).
fn tell_neighbours(
    world: &SimpleCommunicator,
    n_cells: usize,
    band: &mut Band,
    slots: &[usize],
) -> Result<()> {
    let size = world.size() as usize;
    let hold = holder(n_cells, size);
    let mut send = buffers(size);
    for &i in slots {
        for &n in &band.nbr[band.start[i]..band.start[i + 1]] {
            send[hold(n)].extend([n as u64, band.cells[i] as u64, band.part[i] as u64]);
        }
    }
    let got = exchange(world, send)?;
    for w in got.words.chunks_exact(3) {
        let (cell, nbr, p) = (w[0] as usize, w[1] as usize, w[2] as usize);
        let i = band.cells.binary_search(&cell).expect("a band cell of this rank");
        let k = (band.start[i]..band.start[i + 1])
            .find(|&k| band.nbr[k] == nbr)
            .expect("a neighbour of the cell");
        band.nbr_part[k] = p;
    }
    Ok(())
}
