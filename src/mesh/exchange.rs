//! The one message pattern of the distributed mesh front end: every rank sends each rank a
//! buffer of 64-bit words (possibly empty) and receives one from each (one all-to-all).
//!
//! Integers, tags and coordinates (by their bits) all travel as `u64` words, so each step of
//! the reader and of the distribution is "fill one buffer per destination, exchange, read the
//! buffers per source in rank order". What a rank sends and receives is its share of the
//! mesh; nothing here is as large as the whole.

use crate::error::{Error, Result};
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

/// The words received from every rank, in rank order.
pub struct Received {
    pub words: Vec<u64>,
    /// Rank `r`'s words are `words[start[r]..start[r + 1]]`.
    pub start: Vec<usize>,
}

impl Received {
    /// The words rank `r` sent.
    pub fn from(&self, r: usize) -> &[u64] {
        &self.words[self.start[r]..self.start[r + 1]]
    }
    pub fn n_ranks(&self) -> usize {
        self.start.len() - 1
    }
}

/// Send `send[r]` to rank `r` for every `r` (collective); `send` has one buffer per rank.
pub fn exchange(world: &SimpleCommunicator, send: Vec<Vec<u64>>) -> Result<Received> {
    let size = world.size() as usize;
    debug_assert_eq!(send.len(), size);
    let counts = send
        .iter()
        .map(|b| i32::try_from(b.len()))
        .collect::<std::result::Result<Vec<i32>, _>>()
        .map_err(|_| Error::Mpi("a message of the mesh front end exceeds 2^31 words".into()));
    // Every rank takes part in the count exchange even if its own counts overflowed.
    let ok = counts.is_ok();
    let counts = counts.unwrap_or_else(|_| vec![0; size]);
    let mut all_ok = 0i32;
    world.all_reduce_into(&(ok as i32), &mut all_ok, mpi::collective::SystemOperation::min());
    if all_ok == 0 {
        return Err(Error::Mpi("a message of the mesh front end exceeds 2^31 words".into()));
    }
    let mut recv_counts = vec![0i32; size];
    world.all_to_all_into(&counts[..], &mut recv_counts[..]);
    let flat: Vec<u64> = send.concat();
    drop(send);
    let sd = displacements(&counts);
    let rd = displacements(&recv_counts);
    let total: usize = recv_counts.iter().map(|&c| c as usize).sum();
    if rd.last().is_some_and(|&d| d < 0) || total > i32::MAX as usize {
        return Err(Error::Mpi("a rank receives more than 2^31 words of mesh data".into()));
    }
    let mut words = vec![0u64; total];
    world.all_to_all_varcount_into(
        &Partition::new(&flat[..], &counts[..], &sd[..]),
        &mut PartitionMut::new(&mut words[..], &recv_counts[..], &rd[..]),
    );
    let mut start = Vec::with_capacity(size + 1);
    start.push(0);
    for &c in &recv_counts {
        start.push(start.last().copied().unwrap_or(0) + c as usize);
    }
    Ok(Received { words, start })
}

fn displacements(counts: &[i32]) -> Vec<i32> {
    counts.iter().scan(0i32, |s, &c| Some(std::mem::replace(s, s.wrapping_add(c)))).collect()
}

/// One empty buffer per rank.
pub fn buffers(size: usize) -> Vec<Vec<u64>> {
    vec![Vec::new(); size]
}

/// A coordinate as a word and back (bit-exact).
#[inline]
pub fn word(x: f64) -> u64 {
    x.to_bits()
}
#[inline]
pub fn real(w: u64) -> f64 {
    f64::from_bits(w)
}
