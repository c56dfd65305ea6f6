//! Reductions of one number over the ranks, the ones every phase of a run needs.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

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
