//! The partitions that reproduce older runs from distributed data: METIS (`metis`) and the
//! equal-count slabs (`x-slabs`, `y-slabs`) run on rank 0 over data gathered there, exactly as
//! `partition_cells` and `slabs` run them on a whole mesh, and the ranks are scattered back.
//!
//! Rank 0 receives only what the partitioner needs: for METIS the connectivity (original node
//! indices of every cell in original order: 4 bytes per cell node plus 4 per cell), for slabs
//! one centroid coordinate per cell (8 bytes). That is volume-sized on one rank, which is why
//! the scalable default is `rcb`; these are kept so that old runs can be repeated.

use super::{metis_parts, slab_cut};
use crate::error::{Error, Result};
use crate::mesh::natural_range;
use crate::mesh::share::{agree, Share};
use mpi::collective::SystemOperation;
use mpi::datatype::{Partition as Parts, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// METIS on rank 0 over the gathered connectivity: this rank's cells' ranks (collective).
pub fn metis(world: &SimpleCommunicator, share: &Share) -> Result<Vec<usize>> {
    let size = world.size() as usize;
    if size <= 1 || share.n_cells == 0 {
        return Ok(vec![0; share.cells.len()]);
    }
    let counts: Vec<metis::Idx> =
        share.cells.iter().map(|c| c.nodes().len() as metis::Idx).collect();
    let nodes: Vec<metis::Idx> =
        (share.cells.iter()).flat_map(|c| c.nodes().into_iter().map(|v| v as metis::Idx)).collect();
    let counts = gather(world, &counts)?;
    let nodes = gather(world, &nodes)?;
    let parts = match (counts, nodes) {
        (Some(counts), Some(eind)) => {
            let mut eptr = Vec::with_capacity(counts.len() + 1);
            eptr.push(0 as metis::Idx);
            for c in counts {
                eptr.push(eptr[eptr.len() - 1] + c);
            }
            metis_parts(&eptr, &eind, share.dim, size)
        }
        _ => Ok(vec![]),
    };
    let parts = agree(world, parts)?;
    scatter(world, &parts, share.n_cells)
}

/// Equal-count slabs of `cx` (this rank's cells' centroid coordinates) on rank 0 (collective).
pub fn slabs(world: &SimpleCommunicator, cx: &[f64], n_cells: usize) -> Result<Vec<usize>> {
    let size = world.size() as usize;
    let all = gather(world, cx)?;
    let parts = all.map(|cx| slab_cut(&cx, size)).unwrap_or_default();
    scatter(world, &parts, n_cells)
}

/// Every rank's `local` concatenated on rank 0 (None elsewhere; collective).
fn gather<T>(world: &SimpleCommunicator, local: &[T]) -> Result<Option<Vec<T>>>
where
    T: mpi::datatype::Equivalence + Default + Clone,
{
    let mut total = 0u64;
    world.all_reduce_into(&(local.len() as u64), &mut total, SystemOperation::sum());
    if total > i32::MAX as u64 {
        return Err(too_large());
    }
    let root = world.process_at_rank(0);
    let n = local.len() as i32;
    if world.rank() != 0 {
        root.gather_into(&n);
        root.gather_varcount_into(local);
        return Ok(None);
    }
    let mut counts = vec![0i32; world.size() as usize];
    root.gather_into_root(&n, &mut counts[..]);
    let displs: Vec<i32> =
        counts.iter().scan(0i32, |s, &c| Some(std::mem::replace(s, *s + c))).collect();
    let mut all = vec![T::default(); total as usize];
    let mut into = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
    root.gather_varcount_into_root(local, &mut into);
    Ok(Some(all))
}

fn too_large() -> Error {
    Error::Partition("the gathered mesh data exceed 2^31 entries: use --partition rcb".into())
}

/// Rank 0's `parts` (every cell's rank, original order) sent back in the cell blocks
/// `natural_range(n_cells, r, size)` (collective).
fn scatter(world: &SimpleCommunicator, parts: &[usize], n_cells: usize) -> Result<Vec<usize>> {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let (a, b) = natural_range(n_cells, rank, size);
    let mut mine = vec![0u64; b - a];
    let root = world.process_at_rank(0);
    if rank == 0 {
        let all: Vec<u64> = parts.iter().map(|&p| p as u64).collect();
        let counts: Vec<i32> = (0..size)
            .map(|r| natural_range(n_cells, r, size))
            .map(|(a, b)| (b - a) as i32)
            .collect();
        let displs: Vec<i32> =
            (0..size).map(|r| natural_range(n_cells, r, size).0 as i32).collect();
        let from = Parts::new(&all[..], &counts[..], &displs[..]);
        root.scatter_varcount_into_root(&from, &mut mine[..]);
    } else {
        root.scatter_varcount_into(&mut mine[..]);
    }
    Ok(mine.into_iter().map(|p| p as usize).collect())
}
