//! The check behind the hidden `massfree mesh-check` command: a rank's part of the mesh built by
//! the distributed front end (`distribute::read_local`) against the one cut out of the whole
//! mesh (`read_msh`, the strategy on the whole mesh, `local::localize`), field by field and
//! bit for bit; and, for measurements, either path alone with its times and peak memory.

use super::distribute::{read_local_timed, FrontTimes};
use super::local::localize;
use super::{Partition, Strategy};
use crate::comm::max_over_ranks;
use crate::error::{Error, Result};
use crate::mesh::msh::read_msh;
use crate::mesh::topology::facet_map;
use crate::mesh::Mesh;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use std::path::Path;
use std::time::Instant;

/// Which path(s) `mesh-check` runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Paths {
    /// Both, compared.
    Compare,
    /// Only the distributed front end (times, peak memory).
    Distributed,
    /// Only the replicated path (times, peak memory).
    Replicated,
}

/// Run the check and print one line per rank (collective). A mismatch is an error, after the
/// lines saying what differs.
pub fn mesh_check(
    world: &SimpleCommunicator,
    path: &Path,
    strategy: Strategy,
    ascii_limit: u64,
    paths: Paths,
) -> Result<()> {
    let rank = world.rank() as usize;
    match paths {
        Paths::Distributed => {
            let (mesh, part, t) = read_local_timed(world, path, strategy, ascii_limit)?;
            report_alone(world, "distributed", &mesh, &part, t);
            Ok(())
        }
        Paths::Replicated => {
            let (mesh, part, t) = replicated(world, path, strategy)?;
            report_alone(world, "replicated", &mesh, &part, t);
            Ok(())
        }
        Paths::Compare => {
            let dist = read_local_timed(world, path, strategy, ascii_limit);
            let (m1, p1, _) = match dist {
                Ok(d) => d,
                Err(e) => return same_error(world, path, e),
            };
            let (m2, p2, _) = replicated(world, path, strategy)?;
            let diff = differences(&m1, &p1, &m2, &p2);
            let line = if diff.is_empty() {
                format!("rank {rank}: same ({})", sizes(&m1, &p1))
            } else {
                format!("rank {rank}: DIFFERENT: {}", diff.join(", "))
            };
            println!("{line}");
            if rank == 0 {
                println!("{}", partition_quality(world, path, strategy)?);
            }
            let mut bad = 0u8;
            world.all_reduce_into(&(!diff.is_empty() as u8), &mut bad, SystemOperation::max());
            if bad != 0 {
                return Err(Error::Mesh(format!(
                    "{}: the distributed and the replicated mesh views differ",
                    path.display()
                )));
            }
            Ok(())
        }
    }
}

/// The replicated path with its times: every rank reads the whole mesh, partitions it and
/// cuts its part out (`--replicated-mesh`, and the reference of `mesh-check`).
pub fn replicated(
    world: &SimpleCommunicator,
    path: &Path,
    strategy: Strategy,
) -> Result<(Mesh, Partition, FrontTimes)> {
    let (rank, size) = (world.rank() as usize, world.size() as usize);
    let t = Instant::now();
    let whole = read_msh(path)?;
    let read = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let cell_rank = strategy.cell_ranks(&whole, size)?;
    let partition = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (mesh, part) = localize(&whole, &cell_rank, rank, size);
    let distribute = t.elapsed().as_secs_f64();
    Ok((mesh, part, FrontTimes { read, partition, distribute }))
}

/// The distributed path failed: so must the replicated one, with the same message.
fn same_error(world: &SimpleCommunicator, path: &Path, e: Error) -> Result<()> {
    match read_msh(path) {
        Err(r) if r == e => {
            if world.rank() == 0 {
                println!("both paths fail alike");
            }
            Err(e)
        }
        Err(r) => Err(Error::Mesh(format!(
            "the paths fail differently: distributed: {e}; replicated: {r}"
        ))),
        Ok(_) => Err(Error::Mesh(format!("only the distributed path fails: {e}"))),
    }
}

/// "cells own/ghost A/B, nodes N (owned M), boundary K".
fn sizes(mesh: &Mesh, part: &Partition) -> String {
    let own = part.local_cells.len();
    format!(
        "cells own/ghost {own}/{}, nodes {} (owned {}), boundary {}",
        mesh.cells.len() - own,
        mesh.n_nodes(),
        part.owned_nodes.len(),
        mesh.boundary.len()
    )
}

/// The names of the fields that differ (bitwise for coordinates).
fn differences(m1: &Mesh, p1: &Partition, m2: &Mesh, p2: &Partition) -> Vec<String> {
    let bits = |m: &Mesh| -> Vec<[u64; 3]> {
        m.coords.iter().map(|x| [x[0].to_bits(), x[1].to_bits(), x[2].to_bits()]).collect()
    };
    let checks = [
        ("dim", m1.dim == m2.dim),
        ("coords", bits(m1) == bits(m2)),
        ("node_tags", m1.node_tags == m2.node_tags),
        ("cells", m1.cells == m2.cells),
        ("boundary", m1.boundary == m2.boundary),
        ("groups", m1.groups == m2.groups),
        ("part.rank/size/dim", (p1.rank, p1.size, p1.dim) == (p2.rank, p2.size, p2.dim)),
        ("cell_rank", p1.cell_rank == p2.cell_rank),
        ("node_owner", p1.node_owner == p2.node_owner),
        ("node_global", p1.node_global == p2.node_global),
        ("node_offsets", p1.node_offsets == p2.node_offsets),
        ("owned_nodes", p1.owned_nodes == p2.owned_nodes),
        ("local_cells", p1.local_cells == p2.local_cells),
        ("node_original", p1.node_original == p2.node_original),
        ("cell_original", p1.cell_original == p2.cell_original),
        ("cell_natural", p1.cell_natural == p2.cell_natural),
        ("n_global_cells", p1.n_global_cells == p2.n_global_cells),
        ("natural_global", p1.natural_global == p2.natural_global),
    ];
    checks.iter().filter(|c| !c.1).map(|c| c.0.to_string()).collect()
}

/// "partition STRATEGY: cells per rank MIN..MAX (ideal X), shared nodes S, cut facets C" of
/// the whole mesh (rank 0, for the tests' balance and shape checks): S nodes are in cells of
/// two ranks or more (they make the ghost layers and the messages), C facets are between cells
/// of two ranks.
fn partition_quality(
    world: &SimpleCommunicator,
    path: &Path,
    strategy: Strategy,
) -> Result<String> {
    let size = world.size() as usize;
    let whole = read_msh(path)?;
    let ranks = strategy.cell_ranks(&whole, size)?;
    let mut count = vec![0usize; size];
    ranks.iter().for_each(|&r| count[r] += 1);
    let all: Vec<usize> = (0..whole.cells.len()).collect();
    let cut = facet_map(&whole, &all)
        .values()
        .filter(|&&(a, b, n)| n == 2 && ranks[a] != ranks[b])
        .count();
    let mut first = vec![usize::MAX; whole.n_nodes()];
    let mut shared = vec![false; whole.n_nodes()];
    for (c, e) in whole.cells.iter().enumerate() {
        for v in e.nodes() {
            shared[v] |= first[v] != usize::MAX && first[v] != ranks[c];
            first[v] = ranks[c];
        }
    }
    Ok(format!(
        "partition {strategy:?}: cells per rank {}..{} (ideal {:.1}), shared nodes {}, cut facets {cut}",
        count.iter().min().unwrap_or(&0),
        count.iter().max().unwrap_or(&0),
        whole.cells.len() as f64 / size as f64,
        shared.iter().filter(|&&s| s).count()
    ))
}

/// Peak resident memory of this process (VmHWM), in MiB.
pub fn peak_memory_mb() -> f64 {
    crate::phase::status_mib("VmHWM:")
}

/// Times (max over the ranks) on rank 0, peak memory on every rank.
fn report_alone(
    world: &SimpleCommunicator,
    what: &str,
    mesh: &Mesh,
    part: &Partition,
    t: FrontTimes,
) {
    let rank = world.rank();
    let (read, partition, distribute) = (
        max_over_ranks(world, t.read),
        max_over_ranks(world, t.partition),
        max_over_ranks(world, t.distribute),
    );
    if rank == 0 {
        println!(
            "{what}: read {read:.2} s, partition {partition:.2} s, distribute {distribute:.2} s"
        );
    }
    println!("rank {rank}: {what} ({}), peak memory {:.0} MB", sizes(mesh, part), peak_memory_mb());
}
