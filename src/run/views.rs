//! Two views of a distributed vector that the run's output and diagnostics need, each a
//! scatter built once at first use:
//! - [`Views::to_natural`]: this rank's block of the natural (gmsh) node order, the order of
//!   every dataset a user sees (`io::natural_range`), components interlaced;
//! - [`Views::local_values`]: the values at the nodes of this rank's cells, ghosts included,
//!   for element loops (stress output, errors against an exact solution).

use std::rc::Rc;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::comm::sum_over_ranks;
use crate::error::Result;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Scatter, Vector};

/// The values of a distributed vector at the nodes of this rank's cells, ghosts included: a
/// scatter built once into a vector holding them on this rank.
pub struct LocalView {
    scatter: Scatter,
    values: Vector,
    /// The nodes of this rank's cells, sorted: node `nodes[i]` at slot i.
    pub nodes: Vec<usize>,
    /// The slot of each node in the values (`usize::MAX` for nodes of no cell of this rank).
    pub slot: Vec<usize>,
}

/// The natural-order and local views of the run's vectors (all of one layout).
pub struct Views<'a> {
    world: &'a SimpleCommunicator,
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    /// Scatter to this rank's block of natural (gmsh) node order, built on first use.
    natural: Option<(Scatter, Vector)>,
    /// Values at the nodes of this rank's cells, built on first use.
    local: Option<LocalView>,
}

impl<'a> Views<'a> {
    pub fn new(world: &'a SimpleCommunicator, mesh: Rc<Mesh>, part: Rc<Partition>) -> Views<'a> {
        Views { world, mesh, part, natural: None, local: None }
    }

    /// Scatter from the solver's layout to this rank's block of natural (gmsh) node order.
    fn natural_scatter(&self, x: &Vector) -> Result<(Scatter, Vector)> {
        let dim = self.part.dim;
        let (lo, hi) = self.part.natural_block();
        let y = Vector::new_mpi((hi - lo) * dim, self.part.n_global_dofs(), dim)?;
        let mut from = Vec::with_capacity((hi - lo) * dim);
        let mut to = Vec::with_capacity((hi - lo) * dim);
        for node in lo..hi {
            for c in 0..dim {
                from.push(self.part.natural_dof(node, c) as i32);
                to.push((node * dim + c) as i32);
            }
        }
        let sc = Scatter::new(x, &from, &y, &to)?;
        Ok((sc, y))
    }

    /// This rank's natural block of `x` (interlaced components).
    pub fn to_natural(&mut self, x: &Vector) -> Result<Vec<f64>> {
        if self.natural.is_none() {
            self.natural = Some(self.natural_scatter(x)?);
        }
        let (sc, y) = self.natural.as_mut().expect("natural scatter");
        sc.forward(x, y)?;
        let mut out = Vec::new();
        y.with_local_slice(|s| out.extend_from_slice(s))?;
        Ok(out)
    }

    /// Fill `x` (solver layout) from this rank's natural block (the inverse of `to_natural`).
    pub fn from_natural(&mut self, block: &[f64], x: &mut Vector) -> Result<()> {
        if self.natural.is_none() {
            self.natural = Some(self.natural_scatter(x)?);
        }
        let (sc, y) = self.natural.as_mut().expect("natural scatter");
        y.with_local_slice_mut(|s| s.copy_from_slice(block))?;
        sc.reverse(y, x)
    }

    /// Values of `x` at the nodes of this rank's cells (ghosts included), for element loops,
    /// with the view that says which slot holds which node.
    pub fn local_values(&mut self, x: &Vector) -> Result<(Vec<f64>, &LocalView)> {
        if self.local.is_none() {
            self.local = Some(self.local_view(x)?);
        }
        let view = self.local.as_mut().expect("local view");
        view.scatter.forward(x, &mut view.values)?;
        let mut vals = Vec::new();
        view.values.with_local_slice(|s| vals.extend_from_slice(s))?;
        Ok((vals, view))
    }

    fn local_view(&self, x: &Vector) -> Result<LocalView> {
        let dim = self.part.dim;
        let mut nodes: Vec<usize> = (self.part.local_cells.iter())
            .flat_map(|&c| self.mesh.cells[c].nodes().into_iter())
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        let mut slot = vec![usize::MAX; self.mesh.n_nodes()];
        let mut from = Vec::with_capacity(nodes.len() * dim);
        for (i, &v) in nodes.iter().enumerate() {
            slot[v] = i;
            for c in 0..dim {
                from.push(self.part.dof(v, c) as i32);
            }
        }
        // A distributed vector holding, on each rank, the values its cells touch.
        let k = from.len();
        let mut offset = 0usize;
        self.world.scan_into(&k, &mut offset, SystemOperation::sum());
        let total = sum_over_ranks(self.world, k as f64) as usize;
        let values = Vector::new_mpi(k, total, 1)?;
        let first = offset - k;
        let to: Vec<i32> = (first..first + k).map(|i| i as i32).collect();
        let scatter = Scatter::new(x, &from, &values, &to)?;
        Ok(LocalView { scatter, values, nodes, slot })
    }
}
