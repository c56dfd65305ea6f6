//! The stress-type output fields of a run: `stress`, `strain`, `von_mises`, `effective_stress`,
//! `pressure` as cell values and `<name>_nodal` as their lumped L2 projection to the nodes
//! (the quantities and the per-cell integrals: [`crate::fem::stress`]).
//!
//! Built at the first step a stress-type field is due (a run without one never builds it), then
//! used only at the steps such a field is due, and only for the quantities due then.
//!
//! - Work on this rank's own cells only (`Partition::local_cells`), each with its own material
//!   (`Bodies::material`), from the displacement at their nodes, ghosts included: the run's
//!   local view (`Views::local_values`, one `VecScatter` built once).
//! - Cell values: each rank puts its cells' values into a vector laid out by its own cells; a
//!   scatter built once (per number of components) INSERTs them into a vector laid out by the
//!   writer's natural cell blocks (`Output::block(Location::Cell)`: cells in the file's order,
//!   [`crate::io::natural_cell_index`]), whose local part is the block this rank writes.
//! - Nodal projections `Q_i = sum_K int_K phi_i Q_h / sum_K int_K phi_i`: each rank puts its
//!   cells' numerators into a vector over the nodes of its cells; a scatter built once ADDs
//!   them (ADD_VALUES: a node shared by cells of several ranks gets every contribution) into a
//!   vector laid out by the natural node blocks the writer writes; divided there by the
//!   denominators, assembled the same way once.
//!
//! Every sum over cells is the same whatever the partition but for the order of additions, so
//! the files agree across rank counts to rounding.

use std::rc::Rc;
use std::time::Instant;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::assembly;
use crate::assembly::nodal_pressure::{self, NodalDilatation};
use crate::bodies::Bodies;
use crate::error::{Error, Result};
use crate::fem::stress::{
    integrate, integrate_dilatation, integrate_finite, integrate_finite_pressure, lumped_weights,
    samples, Quantity, Sample, MAX_SAMPLES,
};
use crate::fem::MAX_NODES;
use crate::io::{natural_range, Location};
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Scatter, Vector};
use crate::run::views::Views;

/// A scatter from this rank's own entries to the natural blocks, with its two vectors.
struct Mover {
    components: usize,
    scatter: Scatter,
    from: Vector,
    to: Vector,
}

impl Mover {
    /// From `n_from` local entries (per component) to the natural layout of `n_natural` global
    /// entries; entry `i` goes to natural entry `target(i)`.
    fn new(
        world: &SimpleCommunicator,
        components: usize,
        n_from: usize,
        n_natural: usize,
        target: impl Fn(usize) -> usize,
    ) -> Result<Mover> {
        let c = components;
        let k = n_from * c;
        let mut end = 0usize;
        world.scan_into(&k, &mut end, SystemOperation::sum());
        let mut total = 0usize;
        world.all_reduce_into(&k, &mut total, SystemOperation::sum());
        let from = Vector::new_mpi(k, total, c)?;
        let (lo, hi) = natural_range(n_natural, world.rank() as usize, world.size() as usize);
        let to = Vector::new_mpi((hi - lo) * c, n_natural * c, c)?;
        let first = end - k;
        let idx = |i: usize| -> Result<i32> {
            i32::try_from(i).map_err(|_| Error::Internal(format!("index {i} exceeds PetscInt")))
        };
        let mut from_idx = Vec::with_capacity(k);
        let mut to_idx = Vec::with_capacity(k);
        for i in 0..n_from {
            let t = target(i);
            for j in 0..c {
                from_idx.push(idx(first + i * c + j)?);
                to_idx.push(idx(t * c + j)?);
            }
        }
        let scatter = Scatter::new(&from, &from_idx, &to, &to_idx)?;
        Ok(Mover { components, scatter, from, to })
    }

    /// Move `values` (this rank's entries, components interlaced) and return this rank's
    /// natural block: inserted (`add` false) or summed (`add` true).
    fn apply(&mut self, values: &[f64], add: bool) -> Result<Vec<f64>> {
        self.from.with_local_slice_mut(|s| s.copy_from_slice(values))?;
        self.to.zero()?;
        if add {
            self.scatter.forward_add(&self.from, &mut self.to)?;
        } else {
            self.scatter.forward(&self.from, &mut self.to)?;
        }
        self.to.with_local_slice(|s| s.to_vec())
    }
}

/// The stress-type fields of a run (see the module doc).
pub struct StressOutput {
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    dim: usize,
    n_nodes: usize,
    n_cells: usize,
    /// The nodes of this rank's cells, in the order of the local view's values.
    nodes: Vec<usize>,
    /// The natural (file) index of each of this rank's cells (`Partition::local_cells` order).
    natural: Vec<usize>,
    cell_movers: Vec<Mover>,
    node_movers: Vec<Mover>,
    /// `sum_K int_K phi_i` over this rank's natural node block (the projection's denominators).
    lumped: Vec<f64>,
    /// Wall time of the stress work so far (this rank).
    pub seconds: f64,
}

/// The cell's coordinates and displacement from the local view (`slot[v]`: node v's place in
/// `u_local`); returns the number of nodes.
fn gather(
    mesh: &Mesh,
    cell: usize,
    dim: usize,
    u_local: &[f64],
    slot: &[usize],
    xy: &mut [[f64; 3]; MAX_NODES],
    ue: &mut [f64; assembly::MAX_EDOFS],
) -> usize {
    let c = &mesh.cells[cell];
    let n = assembly::cell_coords(mesh, c, xy);
    for (a, &v) in c.nodes().iter().enumerate() {
        for i in 0..dim {
            ue[a * dim + i] = u_local[slot[v] * dim + i];
        }
    }
    n
}

/// A node vector in the layout of `like` (a displacement), at each node's first component.
fn spread(nodes: &Vector, like: &Vector, dim: usize) -> Result<Vector> {
    let mut out = like.duplicate()?;
    nodes.with_local_slice(|t| {
        out.with_local_slice_mut(|s| {
            s.fill(0.0);
            for (i, &x) in t.iter().enumerate() {
                s[i * dim] = x;
            }
        })
    })??;
    Ok(out)
}

impl StressOutput {
    /// Set up for this rank's cells: the natural cell indices, the nodal denominators (one
    /// assembly). `nodes` are the nodes of this rank's cells in the order of the local view
    /// (`slot[nodes[i]] == i`). Collective.
    pub fn new(
        world: &SimpleCommunicator,
        mesh: Rc<Mesh>,
        part: Rc<Partition>,
        nodes: &[usize],
        slot: &[usize],
    ) -> Result<StressOutput> {
        let t0 = Instant::now();
        let natural = part.local_cells.iter().map(|&c| part.cell_natural[c] as usize).collect();
        let mut out = StressOutput {
            mesh: Rc::clone(&mesh),
            part: Rc::clone(&part),
            dim: mesh.dim,
            n_nodes: part.n_global_nodes(),
            n_cells: part.n_global_cells,
            nodes: nodes.to_vec(),
            natural,
            cell_movers: Vec::new(),
            node_movers: Vec::new(),
            lumped: Vec::new(),
            seconds: 0.0,
        };
        // Denominators: sum_K int_K phi_i with the stress rule (displacement irrelevant).
        let zero = vec![0.0; nodes.len() * mesh.dim];
        let mut local = vec![0.0; nodes.len()];
        let mut xy = [[0.0; 3]; MAX_NODES];
        let mut ue = [0.0; assembly::MAX_EDOFS];
        let mut s = [Sample::default(); MAX_SAMPLES];
        let mut m = [0.0; MAX_NODES];
        for &c in &part.local_cells {
            let n = gather(&mesh, c, mesh.dim, &zero, slot, &mut xy, &mut ue);
            let k = samples(mesh.cells[c].kind, &xy[..n], &ue[..n * mesh.dim], &mut s)
                .map_err(|e| cell_error(&mesh, c, e))?;
            lumped_weights(&s[..k], n, &mut m);
            for (a, &v) in mesh.cells[c].nodes().iter().enumerate() {
                local[slot[v]] += m[a];
            }
        }
        out.lumped = out.node_mover(world, 1)?.apply(&local, true)?;
        out.seconds += t0.elapsed().as_secs_f64();
        Ok(out)
    }

    fn cell_mover(&mut self, world: &SimpleCommunicator, c: usize) -> Result<&mut Mover> {
        if let Some(i) = self.cell_movers.iter().position(|m| m.components == c) {
            return Ok(&mut self.cell_movers[i]);
        }
        let natural = &self.natural;
        let m = Mover::new(world, c, natural.len(), self.n_cells, |i| natural[i])?;
        self.cell_movers.push(m);
        Ok(self.cell_movers.last_mut().expect("mover"))
    }

    fn node_mover(&mut self, world: &SimpleCommunicator, c: usize) -> Result<&mut Mover> {
        if let Some(i) = self.node_movers.iter().position(|m| m.components == c) {
            return Ok(&mut self.node_movers[i]);
        }
        let nodes = &self.nodes;
        let original = &self.part.node_original;
        let m = Mover::new(world, c, nodes.len(), self.n_nodes, |i| original[nodes[i]])?;
        self.node_movers.push(m);
        Ok(self.node_movers.last_mut().expect("mover"))
    }

    /// This rank's natural blocks of the `wanted` fields (quantity and cell values or nodal
    /// projection), in that order, components interlaced, from the displacement at the nodes
    /// of this rank's cells (`u_local`, node v at `slot[v]`). One pass over this rank's cells
    /// computes every quantity wanted. `theta_local` and `pressure_local`: the nodes' averaged
    /// dilatations (linear mixed simplices) and pressures (neo-Hookean ones) at the slots.
    /// Collective (every rank must want the same fields).
    #[allow(clippy::too_many_arguments)] // the local values of u, theta and the pressure
    pub fn compute(
        &mut self,
        world: &SimpleCommunicator,
        bodies: &Bodies,
        u_local: &[f64],
        theta_local: Option<&[f64]>,
        pressure: Option<&[f64]>,
        slot: &[usize],
        wanted: &[(Quantity, Location)],
    ) -> Result<Vec<Vec<f64>>> {
        let t0 = Instant::now();
        let dim = self.dim;
        let (mesh, part) = (Rc::clone(&self.mesh), Rc::clone(&self.part));
        // The distinct quantities, each with its cell and nodal buffers when wanted.
        struct Job {
            q: Quantity,
            cell: Option<Vec<f64>>,
            nodal: Option<Vec<f64>>,
        }
        let mut jobs: Vec<Job> = Vec::new();
        for &(q, loc) in wanted {
            let i = match jobs.iter().position(|j| j.q == q) {
                Some(i) => i,
                None => {
                    jobs.push(Job { q, cell: None, nodal: None });
                    jobs.len() - 1
                }
            };
            let c = q.components();
            match loc {
                Location::Cell => jobs[i].cell = Some(vec![0.0; part.local_cells.len() * c]),
                Location::Nodal => jobs[i].nodal = Some(vec![0.0; self.nodes.len() * c]),
            }
        }
        let mut xy = [[0.0; 3]; MAX_NODES];
        let mut ue = [0.0; assembly::MAX_EDOFS];
        let mut s = [Sample::default(); MAX_SAMPLES];
        let mut cv = [0.0; 6];
        let mut nv = [0.0; MAX_NODES * 6];
        for (i, &c) in part.local_cells.iter().enumerate() {
            let n = gather(&mesh, c, dim, u_local, slot, &mut xy, &mut ue);
            let kind = mesh.cells[c].kind;
            let k = samples(kind, &xy[..n], &ue[..n * dim], &mut s)
                .map_err(|e| cell_error(&mesh, c, e))?;
            let mat = bodies.material(c);
            let law = bodies.law(c);
            for job in &mut jobs {
                let nc = job.q.components();
                let nodal = nodal_pressure::is_nodal(kind, mat);
                match (&law, theta_local) {
                    (Some(law), _) if nodal && pressure.is_some() => {
                        let p = pressure.expect("nodal pressures");
                        let nodes = mesh.cells[c].nodes();
                        let mean = nodes.iter().map(|&v| p[slot[v] * dim]).sum::<f64>()
                            / nodes.len() as f64;
                        let (q, given) = (job.q, Some(mean));
                        integrate_finite_pressure(&s[..k], n, dim, law, given, q, &mut cv, &mut nv)
                    }
                    (Some(law), _) => {
                        integrate_finite(&s[..k], n, dim, law, job.q, &mut cv, &mut nv)
                    }
                    // The averaged nodal pressure: the mean of the cell's nodal dilatations.
                    (None, Some(theta)) if nodal_pressure::is_nodal(kind, mat) => {
                        let nodes = mesh.cells[c].nodes();
                        let mean = nodes.iter().map(|&v| theta[slot[v] * dim]).sum::<f64>()
                            / nodes.len() as f64;
                        integrate_dilatation(&s[..k], n, dim, mat, mean, job.q, &mut cv, &mut nv)
                    }
                    (None, _) => integrate(&s[..k], n, dim, mat, job.q, &mut cv, &mut nv),
                };
                if let Some(cell) = job.cell.as_mut() {
                    cell[i * nc..(i + 1) * nc].copy_from_slice(&cv[..nc]);
                }
                if let Some(nodal) = job.nodal.as_mut() {
                    for (a, &v) in mesh.cells[c].nodes().iter().enumerate() {
                        let at = slot[v] * nc;
                        for j in 0..nc {
                            nodal[at + j] += nv[a * nc + j];
                        }
                    }
                }
            }
        }
        let mut blocks = Vec::with_capacity(wanted.len());
        for &(q, loc) in wanted {
            let job = jobs.iter().find(|j| j.q == q).expect("job");
            let c = q.components();
            blocks.push(match loc {
                Location::Cell => {
                    let vals = job.cell.as_ref().expect("cell values");
                    self.cell_mover(world, c)?.apply(vals, false)?
                }
                Location::Nodal => {
                    let vals = job.nodal.as_ref().expect("nodal values");
                    let mut sums = self.node_mover(world, c)?.apply(vals, true)?;
                    for (i, m) in self.lumped.iter().enumerate() {
                        for v in &mut sums[i * c..(i + 1) * c] {
                            *v /= m;
                        }
                    }
                    sums
                }
            });
        }
        self.seconds += t0.elapsed().as_secs_f64();
        Ok(blocks)
    }
}

fn cell_error(mesh: &Mesh, c: usize, e: Error) -> Error {
    Error::Mesh(format!("stress: {e} (gmsh element tag {})", mesh.cells[c].tag))
}

/// The stress-type fields of a run as the output asks for them: the [`StressOutput`] is built
/// at the first step one is due (a run without one never builds it).
pub struct StressFields<'a> {
    world: &'a SimpleCommunicator,
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    output: Option<StressOutput>,
    /// The averaged nodal dilatation (mixed bodies' simplices), built with the output.
    nodal: Option<NodalDilatation>,
}

impl<'a> StressFields<'a> {
    pub fn new(world: &'a SimpleCommunicator, mesh: Rc<Mesh>, part: Rc<Partition>) -> Self {
        StressFields { world, mesh, part, output: None, nodal: None }
    }

    /// This rank's natural blocks of the stress-type fields `wanted` (in that order), from the
    /// displacement `u`. Timed, with the fetch of `u`'s local values, as `Timings::stress`.
    pub fn blocks(
        &mut self,
        views: &mut Views,
        bodies: &Bodies,
        u: &Vector,
        wanted: &[(Quantity, Location)],
    ) -> Result<Vec<Vec<f64>>> {
        let t0 = Instant::now();
        if self.output.is_none() {
            self.nodal = NodalDilatation::build(&self.mesh, &self.part, &|c| *bodies.material(c))?;
        }
        // The nodal dilatations in the displacement's layout (first component), fetched alike.
        // (Small strain only: a finite-strain run's mixed simplices are neo-Hookean.)
        let theta = match &self.nodal {
            Some(nodal) if !bodies.finite_strain() => {
                let theta = nodal.dilatation(u)?;
                Some(views.local_values(&spread(&theta, u, self.part.dim)?)?.0)
            }
            _ => None,
        };
        // Mixed neo-Hookean simplices: their nodes' pressures from the current volumes.
        let pressure = match &self.nodal {
            Some(nodal) if bodies.finite_strain() => {
                let (vals, view) = views.local_values(u)?;
                let slot = view.slot.clone();
                let p = self.finite_pressure(nodal, bodies, &vals, &slot)?;
                Some(views.local_values(&spread(&p, u, self.part.dim)?)?.0)
            }
            _ => None,
        };
        let (vals, view) = views.local_values(u)?;
        let fetch = t0.elapsed().as_secs_f64();
        if self.output.is_none() {
            let (mesh, part) = (Rc::clone(&self.mesh), Rc::clone(&self.part));
            self.output = Some(StressOutput::new(self.world, mesh, part, &view.nodes, &view.slot)?);
        }
        let stress = self.output.as_mut().expect("stress output");
        stress.seconds += fetch;
        let (theta, pressure) = (theta.as_deref(), pressure.as_deref());
        stress.compute(self.world, bodies, &vals, theta, pressure, &view.slot, wanted)
    }

    /// The nodes' pressures of mixed neo-Hookean simplices (`NodalDilatation::finite_pressure`,
    /// a node vector): each rank adds its cells' `|K_0| J_K / (d + 1)` to their nodes' current
    /// volumes (`u_local` at the local slots). Collective.
    fn finite_pressure(
        &self,
        nodal: &NodalDilatation,
        bodies: &Bodies,
        u_local: &[f64],
        slot: &[usize],
    ) -> Result<Vector> {
        let (mesh, part) = (&self.mesh, &self.part);
        let dim = part.dim;
        let mut current = nodal.volume.duplicate()?;
        current.zero()?;
        let mut xy = [[0.0; 3]; MAX_NODES];
        let mut ue = [0.0; assembly::MAX_EDOFS];
        for &c in &part.local_cells {
            let kind = mesh.cells[c].kind;
            if !(nodal_pressure::is_nodal(kind, bodies.material(c)) && bodies.law(c).is_some()) {
                continue;
            }
            let n = gather(mesh, c, dim, u_local, slot, &mut xy, &mut ue);
            let u = &ue[..n * dim];
            // An inverted cell stopped the run's step already: here it counts as it is.
            let (w, j, _) = crate::fem::hyperelastic::simplex_jacobians(kind, &xy[..n], u, u)
                .unwrap_or((0.0, 0.0, 0.0));
            for v in mesh.cells[c].nodes() {
                let row = [(part.dof(v, 0) / dim) as i32];
                current.set_values(&row, &[w * j / n as f64], true)?;
            }
        }
        current.assemble()?;
        nodal.finite_pressure(&current)
    }

    /// Wall time of the stress work so far on this rank (zero before the first stress field).
    pub fn seconds(&self) -> f64 {
        self.output.as_ref().map_or(0.0, |s| s.seconds)
    }
}
