//! Reductions of one number over the ranks, the ones every phase of a run needs.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::error::{Error, Result};

/// The largest `x` over the ranks (collective).
pub fn max_over_ranks(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut y = 0.0;
    world.all_reduce_into(&x, &mut y, SystemOperation::max());
    y
}

/// The sum of `x` over the ranks (collective).
pub fn sum_over_ranks(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut y = 0.0;
    world.all_reduce_into(&x, &mut y, SystemOperation::sum());
    y
}

/// Every rank learns whether any rank failed, and the message of the lowest such rank
/// (collective): a local failure then ends the same way on every rank instead of leaving the
/// others waiting in the next collective call.
pub fn first_failure(world: &SimpleCommunicator, local: Option<String>) -> Option<String> {
    let size = world.size();
    let mine = if local.is_some() { world.rank() } else { size };
    let mut first = size;
    world.all_reduce_into(&mine, &mut first, SystemOperation::min());
    if first == size {
        return None;
    }
    let root = world.process_at_rank(first);
    let mut bytes = local.map(String::into_bytes).unwrap_or_default();
    let mut len = bytes.len() as u64;
    root.broadcast_into(&mut len);
    bytes.resize(len as usize, 0);
    root.broadcast_into(&mut bytes[..]);
    let text = String::from_utf8_lossy(&bytes).into_owned();
    Some(if first == 0 { text } else { format!("{text} (rank {first})") })
}

/// Every rank's `local` values, concatenated in rank order (collective; for surface-sized data
/// only: the result is as large as all ranks' parts together).
pub fn gather_all<T>(world: &SimpleCommunicator, local: &[T]) -> Vec<T>
where
    T: mpi::datatype::Equivalence + Default + Clone,
{
    let n = world.size() as usize;
    let mut counts = vec![0i32; n];
    world.all_gather_into(&(local.len() as i32), &mut counts[..]);
    let displs: Vec<i32> =
        counts.iter().scan(0, |s, &c| Some(std::mem::replace(s, *s + c))).collect();
    let total = counts.iter().sum::<i32>() as usize;
    let mut all = vec![T::default(); total];
    world.all_gather_varcount_into(
        local,
        &mut mpi::datatype::PartitionMut::new(&mut all[..], &counts[..], &displs[..]),
    );
    all
}

/// Rows of `width` words, each sent to the rank whose block `natural_range(n, r, size)` holds
/// its first word (a global index below `n`; blocks as [`block_range`]); returns the rows this rank received, sorted by
/// that index (collective: one all-to-all). What each rank sends and receives is its share:
/// nothing here is as large as the whole.
pub fn route_to_blocks(
    world: &SimpleCommunicator,
    n: usize,
    width: usize,
    rows: &[u64],
) -> Vec<u64> {
    let size = world.size() as usize;
    let starts: Vec<usize> = (0..size).map(|r| block_range(n, r, size).0).collect();
    let dest = |i: u64| starts.partition_point(|&s| s <= i as usize).max(1) - 1;
    let mut got = all_to_all_rows(world, width, rows, |k| dest(rows[k * width]));
    let mut order: Vec<usize> = (0..got.len() / width).collect();
    order.sort_by_key(|&k| got[k * width]);
    let sorted: Vec<u64> =
        order.iter().flat_map(|&k| got[k * width..(k + 1) * width].iter().copied()).collect();
    got.clear();
    sorted
}

/// [`route_to_blocks`] when every index of `0..n` comes in exactly one row (a field over the
/// nodes or the cells): each row is put at its place in this rank's block, no sort and no
/// copies beyond the exchange's; `rows` is freed as soon as it is sent. An index missing or
/// twice is an internal error.
pub fn route_to_blocks_dense(
    world: &SimpleCommunicator,
    n: usize,
    width: usize,
    rows: Vec<u64>,
) -> Result<Vec<u64>> {
    let size = world.size() as usize;
    let starts: Vec<usize> = (0..size).map(|r| block_range(n, r, size).0).collect();
    let dest = |i: u64| starts.partition_point(|&s| s <= i as usize).max(1) - 1;
    let got = all_to_all_rows(world, width, &rows, |k| dest(rows[k * width]));
    drop(rows);
    let (lo, hi) = block_range(n, world.rank() as usize, size);
    let mut placed = vec![u64::MAX; (hi - lo) * width];
    let mut seen = vec![false; hi - lo];
    for r in got.chunks_exact(width) {
        let i = (r[0] as usize).wrapping_sub(lo);
        if i >= hi - lo || std::mem::replace(&mut seen[i], true) {
            return Err(Error::Internal(format!(
                "route_to_blocks_dense: index {} twice or outside {lo}..{hi}",
                r[0]
            )));
        }
        placed[i * width..(i + 1) * width].copy_from_slice(r);
    }
    if seen.iter().any(|&s| !s) {
        return Err(Error::Internal(format!(
            "route_to_blocks_dense: an index of {lo}..{hi} is missing"
        )));
    }
    Ok(placed)
}

/// Rows of `width` words, row `k` sent to rank `dest(k)`; returns the rows this rank received,
/// in rank order (collective: one all-to-all).
pub fn all_to_all_rows(
    world: &SimpleCommunicator,
    width: usize,
    rows: &[u64],
    dest: impl Fn(usize) -> usize,
) -> Vec<u64> {
    let size = world.size() as usize;
    let n_rows = rows.len() / width.max(1);
    let mut counts = vec![0i32; size];
    let mut sorted = true;
    let mut last = 0;
    for k in 0..n_rows {
        let r = dest(k);
        counts[r] += width as i32;
        sorted &= r >= last;
        last = r;
    }
    // Rows already in rank order (fields routed in index order) are sent as they are.
    let copy;
    let send: &[u64] = if sorted {
        &rows[..n_rows * width]
    } else {
        let mut order: Vec<usize> = (0..n_rows).collect();
        order.sort_by_key(|&k| dest(k));
        let mut buf = Vec::with_capacity(rows.len());
        for &k in &order {
            buf.extend_from_slice(&rows[k * width..(k + 1) * width]);
        }
        copy = buf;
        &copy
    };
    let mut recv_counts = vec![0i32; size];
    world.all_to_all_into(&counts[..], &mut recv_counts[..]);
    let displs = |c: &[i32]| -> Vec<i32> {
        c.iter().scan(0, |s, &x| Some(std::mem::replace(s, *s + x))).collect()
    };
    let (sd, rd) = (displs(&counts), displs(&recv_counts));
    let mut recv = vec![0u64; recv_counts.iter().sum::<i32>() as usize];
    world.all_to_all_varcount_into(
        &mpi::datatype::Partition::new(send, &counts[..], &sd[..]),
        &mut mpi::datatype::PartitionMut::new(&mut recv[..], &recv_counts[..], &rd[..]),
    );
    recv
}

/// The exclusive prefix sum of `x` over the ranks and its total (collective).
pub fn offset_and_total(world: &SimpleCommunicator, x: usize) -> (usize, usize) {
    let mut inclusive = 0usize;
    world.scan_into(&x, &mut inclusive, SystemOperation::sum());
    let mut total = 0usize;
    world.all_reduce_into(&x, &mut total, SystemOperation::sum());
    (inclusive - x, total)
}

/// The even split of `0..n` over the ranks: rank `r` gets `n r / size .. n (r + 1) / size`
/// (the natural node and cell blocks, `mesh::natural_range`).
pub fn block_range(n: usize, rank: usize, size: usize) -> (usize, usize) {
    (n * rank / size, n * (rank + 1) / size)
}
