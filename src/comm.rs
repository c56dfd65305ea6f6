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
