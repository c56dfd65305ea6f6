//! The internal force of finite-strain bodies, its tangent and the strain energy, assembled
//! over this rank's cells (docs/method.md, finite strain; kernels in `fem::hyperelastic`).
//!
//! `f_int,alg(u_0, u_1) = sum_K P_K^T f_K(u_0|K, u_1|K)`: each rank evaluates its own cells at
//! the displacements of their nodes (owned and ghost nodes, gathered by one scatter built
//! once), and the element vectors go back to the owners' rows through the same scatter
//! (summed). The tangent `d f_int,alg / d u_1` is summed by rows ([`super::rows::RowSums`]) into
//! one matrix of the cell-graph pattern, created once and refilled (no reallocation).
//! Cells of small-strain bodies in the same run contribute `A_K (u_0 + u_1)/2` and
//! `A_K / 2`, whose energy identity holds as well.

use std::rc::Rc;

use mpi::topology::SimpleCommunicator;

use super::nodal_pressure::{is_nodal, NodalVolumes};
use super::rows::RowSums;
use super::{cell_coords, MAX_EDOFS};
use crate::bodies::Bodies;
use crate::comm::{first_failure, sum_over_ranks};
use crate::error::{Error, Result};
use crate::fem::hyperelastic::{
    midpoint_force, midpoint_force_nodal, simplex_jacobians, unit_strain_force, Law, NodalPressure,
};
use crate::fem::{kernels, Material};
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Matrix, Scatter, Vector};

/// The constitutive law of one cell.
#[derive(Debug, Clone, Copy)]
enum CellLaw {
    /// Small strain: the cell's `A_K`.
    Small(Material),
    Finite(Law),
    /// A mixed neo-Hookean simplex: its volumetric part is its nodes' (`NodalVolumes`).
    Nodal(Law),
}

/// The internal force of a run's bodies (see the module doc).
pub struct InternalForce {
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    /// The law of each of this rank's cells (in `part.local_cells` order) and its body's name.
    laws: Vec<(CellLaw, u16)>,
    body_names: Vec<String>,
    /// The values at the nodes of this rank's cells: slot `slot[v]` for mesh node `v`.
    slot: Vec<usize>,
    gather: Scatter,
    local: Vector,
    /// `u_0` at the local slots (the step's start, gathered once per step).
    u0: Vec<f64>,
    /// The tangent's row sums, kept between evaluations.
    rows: Option<super::rows::RowStorage>,
    /// The averaged nodal pressure of mixed neo-Hookean simplices, if the run has such cells.
    nodal: Option<NodalVolumes>,
    /// The 2-norm of the nodes' forces under a unit strain
    /// (`fem::hyperelastic::unit_strain_force`): round-off in the internal force is about
    /// `eps` times it.
    pub unit_force: f64,
}

/// What an evaluation found: the strain energies of both states (all ranks), or the first
/// inverted cell's message.
#[derive(Debug, Clone, PartialEq)]
pub enum Evaluation {
    Energies { w0: f64, w1: f64 },
    Inverted(String),
}

impl InternalForce {
    /// Collective (builds the scatter).
    pub fn new(
        world: &SimpleCommunicator,
        mesh: Rc<Mesh>,
        part: Rc<Partition>,
        bodies: &Bodies,
        layout: &Vector,
    ) -> Result<InternalForce> {
        use mpi::collective::SystemOperation;
        use mpi::traits::*;
        let dim = part.dim;
        let mut nodes: Vec<usize> =
            part.local_cells.iter().flat_map(|&c| mesh.cells[c].nodes().into_iter()).collect();
        nodes.sort_unstable();
        nodes.dedup();
        let mut slot = vec![usize::MAX; mesh.n_nodes()];
        let mut from = Vec::with_capacity(nodes.len() * dim);
        for (i, &v) in nodes.iter().enumerate() {
            slot[v] = i;
            for c in 0..dim {
                from.push(part.dof(v, c) as i32);
            }
        }
        let k = from.len();
        let mut offset = 0usize;
        world.scan_into(&k, &mut offset, SystemOperation::sum());
        let total = sum_over_ranks(world, k as f64) as usize;
        let local = Vector::new_mpi(k, total, 1)?;
        let first = offset - k;
        let to: Vec<i32> = (first..first + k).map(|i| i as i32).collect();
        let gather = Scatter::new(layout, &from, &local, &to)?;
        let laws = part
            .local_cells
            .iter()
            .map(|&c| {
                let r = bodies.region_of(c);
                let region = &bodies.regions[r];
                let law = match region.spec.model.is_finite_strain() {
                    true if is_nodal(mesh.cells[c].kind, &region.material) => {
                        CellLaw::Nodal(Law::new(region.spec.model, &region.material))
                    }
                    true => CellLaw::Finite(Law::new(region.spec.model, &region.material)),
                    false => CellLaw::Small(region.material),
                };
                (law, r as u16)
            })
            .collect();
        // Messages name `body[i] "GROUP"`, or the body of a scene without `[[body]]`.
        let body_names = match bodies.n_bodies() {
            0 => vec!["the body".to_string()],
            _ => bodies.regions.iter().map(|r| r.name.clone()).collect(),
        };
        // The unit-strain force of every node, summed over its cells by the owners.
        let mut scale = vec![0.0; k];
        let mut xy = [[0.0; 3]; 8];
        let mut sa = [0.0; 8];
        for &c in &part.local_cells {
            let cell = &mesh.cells[c];
            let n = cell_coords(&mesh, cell, &mut xy);
            let m = bodies.material(c);
            unit_strain_force(cell.kind, &xy[..n], m.lambda + 2.0 * m.mu, &mut sa);
            for (a, &v) in cell.nodes().iter().enumerate() {
                for i in 0..dim {
                    scale[slot[v] * dim + i] += sa[a];
                }
            }
        }
        let mut local = local;
        let mut gather = gather;
        local.with_local_slice_mut(|s| s.copy_from_slice(&scale))?;
        let mut sum = layout.duplicate()?;
        sum.zero()?;
        gather.reverse_add(&local, &mut sum)?;
        let unit_force = sum.norm2()?;
        let nodal = NodalVolumes::new(&mesh, &part, &|c| *bodies.material(c), &nodes)?;
        Ok(InternalForce {
            mesh,
            part,
            laws,
            body_names,
            slot,
            gather,
            local,
            u0: vec![0.0; k],
            rows: None,
            nodal,
            unit_force,
        })
    }

    /// The values of `x` at the local slots.
    fn gathered(&mut self, x: &Vector) -> Result<Vec<f64>> {
        self.gather.forward(x, &mut self.local)?;
        self.local.with_local_slice(|s| s.to_vec())
    }

    /// The number of local slots.
    fn slot_count(&self) -> usize {
        self.u0.len() / self.part.dim
    }

    /// A cell's coordinates and its nodes' `u_0` and `u_1` (`u1` at the local slots); the
    /// number of its nodes.
    fn cell_states(
        &self,
        c: usize,
        u1: &[f64],
        xy: &mut [[f64; 3]; 8],
        e0: &mut [f64],
        e1: &mut [f64],
    ) -> usize {
        let dim = self.part.dim;
        let cell = &self.mesh.cells[c];
        let n = cell_coords(&self.mesh, cell, xy);
        for (a, &v) in cell.nodes().iter().enumerate() {
            let s = self.slot[v] * dim;
            e0[a * dim..(a + 1) * dim].copy_from_slice(&self.u0[s..s + dim]);
            e1[a * dim..(a + 1) * dim].copy_from_slice(&u1[s..s + dim]);
        }
        n
    }

    /// This rank's shares of the nodal volumes of both states at the local slots,
    /// `sum_{K ∋ a} |K_0| J_K / (d + 1)` over its mixed neo-Hookean simplices, or the first
    /// inverted cell's message.
    fn nodal_volumes(&self, u1: &[f64]) -> (Vec<f64>, Vec<f64>, Option<String>) {
        let dim = self.part.dim;
        let ns = self.slot_count();
        let (mut a0, mut a1) = (vec![0.0; ns], vec![0.0; ns]);
        let mut xy = [[0.0; 3]; 8];
        let (mut e0, mut e1) = ([0.0; MAX_EDOFS], [0.0; MAX_EDOFS]);
        for (k, &c) in self.part.local_cells.iter().enumerate() {
            let CellLaw::Nodal(_) = self.laws[k].0 else { continue };
            let cell = &self.mesh.cells[c];
            let n = self.cell_states(c, u1, &mut xy, &mut e0, &mut e1);
            match simplex_jacobians(cell.kind, &xy[..n], &e0[..n * dim], &e1[..n * dim]) {
                Ok((w, j0, j1)) => {
                    for &v in cell.nodes().iter() {
                        a0[self.slot[v]] += w * j0 / n as f64;
                        a1[self.slot[v]] += w * j1 / n as f64;
                    }
                }
                Err(inv) => return (a0, a1, Some(self.inverted(self.laws[k].1, inv, cell.tag))),
            }
        }
        (a0, a1, None)
    }

    /// The message of an inverted cell of body `region`.
    fn inverted(&self, region: u16, inv: crate::fem::hyperelastic::Inverted, tag: u64) -> String {
        format!(
            "{} inverts at {} (det F = {:e}, gmsh element tag {})",
            self.body_names[region as usize],
            if inv.state == 0 { "the step's start" } else { "the step's end" },
            inv.det_f,
            tag
        )
    }

    /// Sets the step's start `u_0`. Collective.
    pub fn set_start(&mut self, u0: &Vector) -> Result<()> {
        self.u0 = self.gathered(u0)?;
        Ok(())
    }

    /// `force = f_int,alg(u_0, u_1)` and, with `tangent`, `d f_int,alg / d u_1` written into
    /// it. Collective; every rank returns the same [`Evaluation`] (on an inverted cell `force`
    /// and `tangent` are left as they are).
    pub fn evaluate(
        &mut self,
        u1: &Vector,
        force: &mut Vector,
        tangent: Option<&mut Matrix>,
    ) -> Result<Evaluation> {
        let world = SimpleCommunicator::world();
        let u1 = self.gathered(u1)?;
        let dim = self.part.dim;
        let mut out = vec![0.0; u1.len()];
        let graph = self.part.graph(&self.mesh);
        let mut sums = match (tangent.is_some(), self.rows.take()) {
            (true, Some(kept)) => Some(RowSums::from_storage(graph, kept)),
            (true, None) => Some(RowSums::new(graph, &self.mesh, &self.part).recording()),
            (false, kept) => {
                self.rows = kept;
                None
            }
        };
        let (mut w0, mut w1) = (0.0, 0.0);
        let mut xy = [[0.0; 3]; 8];
        let mut e0 = [0.0; MAX_EDOFS];
        let mut e1 = [0.0; MAX_EDOFS];
        let mut fe = [0.0; MAX_EDOFS];
        let mut ke = vec![0.0; MAX_EDOFS * MAX_EDOFS];
        let mut failed = None;
        // The averaged nodal pressure: the nodes' volumes of both states first (every rank's
        // cells), then their pressures back at the cells.
        let mut pressure = Vec::new();
        if self.nodal.is_some() {
            let (a0, a1, bad) = self.nodal_volumes(&u1);
            if let Some(m) = first_failure(&world, bad) {
                return Ok(Evaluation::Inverted(m));
            }
            if let Some(nodal) = self.nodal.as_mut() {
                let state = nodal.pressures(&a0, &a1, sums.is_some())?;
                w0 += state.w0;
                w1 += state.w1;
                pressure = state.pressure;
            }
        }
        let mut dforce = [0.0; MAX_EDOFS];
        let mut dvolume = [0.0; MAX_EDOFS];
        let mut dofs = Vec::with_capacity(MAX_EDOFS);
        for (k, &c) in self.part.local_cells.iter().enumerate() {
            let cell = &self.mesh.cells[c];
            let n = self.cell_states(c, &u1, &mut xy, &mut e0, &mut e1);
            let nodes = cell.nodes();
            let nd = n * dim;
            let (law, region) = self.laws[k];
            let want_k = sums.is_some();
            match law {
                CellLaw::Finite(law) | CellLaw::Nodal(law) => {
                    let kt = want_k.then_some(&mut ke[..nd * nd]);
                    let (c0, c1, f) = (&e0[..nd], &e1[..nd], &mut fe[..nd]);
                    let nodal = matches!(self.laws[k].0, CellLaw::Nodal(_));
                    let step = match nodal {
                        // The cell's share of its nodes' pressures (`NodalVolumes`).
                        true => {
                            let p = nodes.iter().map(|&v| pressure[self.slot[v]]).sum::<f64>()
                                / n as f64;
                            let np = NodalPressure {
                                pressure: p,
                                dforce: &mut dforce[..nd],
                                dvolume: &mut dvolume[..nd],
                            };
                            midpoint_force_nodal(cell.kind, &xy[..n], &law, c0, c1, np, f, kt)
                        }
                        false => midpoint_force(cell.kind, &xy[..n], &law, c0, c1, f, kt),
                    };
                    match step {
                        Ok(w) => {
                            w0 += w.w0;
                            w1 += w.w1;
                        }
                        Err(inv) => {
                            failed = Some(self.inverted(region, inv, cell.tag));
                            break;
                        }
                    }
                    if nodal && want_k {
                        super::node_dofs(&self.part, &nodes, &mut dofs);
                        let nodal = self.nodal.as_mut().expect("nodal");
                        nodal.add_rows(&self.part, &nodes, &dofs, &dforce[..nd], &dvolume[..nd])?;
                    }
                }
                CellLaw::Small(m) => {
                    kernels::stiffness(cell.kind, &xy[..n], &m, &mut ke[..nd * nd])
                        .map_err(|e| Error::Mesh(format!("{e} (gmsh element tag {})", cell.tag)))?;
                    for i in 0..nd {
                        let (mut f, mut a0, mut a1) = (0.0, 0.0, 0.0);
                        for j in 0..nd {
                            let kij = ke[i * nd + j];
                            f += kij * 0.5 * (e0[j] + e1[j]);
                            a0 += kij * e0[j];
                            a1 += kij * e1[j];
                        }
                        fe[i] = f;
                        w0 += 0.5 * e0[i] * a0;
                        w1 += 0.5 * e1[i] * a1;
                    }
                    if want_k {
                        ke[..nd * nd].iter_mut().for_each(|x| *x *= 0.5);
                    }
                }
            }
            for (a, &v) in nodes.iter().enumerate() {
                let s = self.slot[v] * dim;
                for i in 0..dim {
                    out[s + i] += fe[a * dim + i];
                }
            }
            if let Some(sums) = sums.as_mut() {
                sums.add(&self.part, self.part.cell_original[c] as usize, &nodes, &ke[..nd * nd])?;
            }
        }
        if let Some(m) = first_failure(&world, failed) {
            return Ok(Evaluation::Inverted(m));
        }
        self.local.with_local_slice_mut(|s| s.copy_from_slice(&out))?;
        force.zero()?;
        self.gather.reverse_add(&self.local, force)?;
        if let (Some(sums), Some(k)) = (sums, tangent) {
            // The nodal part's entries lie outside the cells' pattern: cleared first.
            if self.nodal.is_some() {
                k.zero_entries()?;
            }
            self.rows = Some(sums.fill_keeping(&world, k)?);
            if let Some(nodal) = self.nodal.as_mut() {
                nodal.add_tangent(k)?;
            }
        }
        Ok(Evaluation::Energies { w0: sum_over_ranks(&world, w0), w1: sum_over_ranks(&world, w1) })
    }

    /// The strain energy `sum_K int_K W(C(u))` (small-strain cells: `1/2 u_K.A_K u_K`), or the
    /// first inverted cell's message. Collective.
    pub fn energy(&mut self, u: &Vector) -> Result<std::result::Result<f64, String>> {
        let keep = std::mem::take(&mut self.u0);
        self.u0 = self.gathered(u)?;
        let mut f = u.duplicate()?;
        let e = self.evaluate(u, &mut f, None);
        self.u0 = keep;
        Ok(match e? {
            Evaluation::Energies { w1, .. } => Ok(w1),
            Evaluation::Inverted(m) => Err(m),
        })
    }
}
