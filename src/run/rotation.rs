//! How far each body has turned: the rotation of the polar decomposition `F = R U` of its mean
//! deformation gradient `F_B = I + (1/|B|) int_B grad u dV`. A small-strain body that turns
//! grows without stress (its points move along the rotation's tangents): past
//! [`WARN_DEGREES`] the run says so once per body, naming the finite-strain model as the fix.
//!
//! `int_B grad u dV = sum_a u_a (x) g_a` with `g_a = int_B grad N_a dV`, which vanishes at
//! every node inside the body (`int_B grad N_a = int_dB N_a n dS`): the nodes' `g_a` are
//! summed once by their owners, and a step costs a loop over the owned surface nodes and one
//! small reduction.

use mpi::collective::SystemOperation;
use mpi::traits::*;

use super::domain::Domain;
use crate::assembly::cell_coords;
use crate::comm::all_to_all_rows;
use crate::console::Console;
use crate::error::Result;
use crate::fem::hyperelastic::{rotation, rotation_angle_degrees};
use crate::fem::{gauss, physical_gradients};
use crate::petsc::Vector;
use crate::report::BodyRotation;

/// A small-strain body turned further than this is warned about.
pub const WARN_DEGREES: f64 = 5.0;

/// Each body's largest rotation so far, and the warnings given.
pub struct BodyRotations {
    dim: usize,
    /// Per owned node with a non-zero `g`: (local DOF of its first component, region, `g/|B|`).
    terms: Vec<(usize, usize, [f64; 3])>,
    /// Per region: its name, whether it is small-strain, the largest angle and its time,
    /// whether it was warned about.
    regions: Vec<(String, bool, f64, f64, bool)>,
}

impl BodyRotations {
    /// Collective.
    pub fn new(d: &Domain) -> Result<BodyRotations> {
        let (mesh, part, bodies) = (&d.mesh, &d.part, &d.bodies);
        let dim = part.dim;
        let nr = bodies.regions.len();
        // Partial g_a (and the regions' volumes) from this rank's cells.
        let mut volume = vec![0.0f64; nr];
        let mut partial: std::collections::HashMap<(usize, usize), [f64; 3]> = Default::default();
        let mut xy = [[0.0; 3]; 8];
        let mut g = [[0.0f64; 3]; 8];
        for &c in &part.local_cells {
            let cell = &mesh.cells[c];
            let n = cell_coords(mesh, cell, &mut xy);
            let r = bodies.region_of(c);
            let order = if matches!(
                cell.kind,
                crate::fem::ElementKind::Tri3 | crate::fem::ElementKind::Tet4
            ) {
                0
            } else {
                2
            };
            for (xi, w) in gauss(cell.kind, order) {
                let det = physical_gradients(cell.kind, &xy[..n], xi, &mut g[..n]);
                volume[r] += w * det;
                for (a, &v) in cell.nodes().iter().enumerate() {
                    let e = partial.entry((v, r)).or_insert([0.0; 3]);
                    for i in 0..dim {
                        e[i] += w * det * g[a][i];
                    }
                }
            }
        }
        let mut all = vec![0.0f64; nr];
        d.world.all_reduce_into(&volume[..], &mut all[..], SystemOperation::sum());
        // To the owners: (node global, region, g).
        let mut rows: Vec<u64> = Vec::new();
        let mut dest: Vec<usize> = Vec::new();
        let mut keys: Vec<_> = partial.into_iter().collect();
        keys.sort_by_key(|((v, r), _)| (part.node_global[*v], *r));
        for ((v, r), gv) in keys {
            rows.extend([part.node_global[v] as u64, r as u64]);
            rows.extend(gv.map(f64::to_bits));
            dest.push(part.node_owner[v]);
        }
        let came = all_to_all_rows(d.world, 5, &rows, |k| dest[k]);
        let first_node = part.node_offsets[part.rank];
        let mut summed: std::collections::BTreeMap<(usize, usize), [f64; 3]> = Default::default();
        for row in came.chunks_exact(5) {
            let e = summed.entry((row[0] as usize, row[1] as usize)).or_insert([0.0; 3]);
            for i in 0..3 {
                e[i] += f64::from_bits(row[2 + i]);
            }
        }
        // Interior nodes' sums cancel to round-off: kept only above it.
        let mut terms = Vec::new();
        for ((node, r), gv) in summed {
            let scale = all[r].max(f64::MIN_POSITIVE);
            let size = (gv[0] * gv[0] + gv[1] * gv[1] + gv[2] * gv[2]).sqrt();
            if size > 1e-12 * scale.powf((dim as f64 - 1.0) / dim as f64) {
                terms.push(((node - first_node) * dim, r, gv.map(|x| x / scale)));
            }
        }
        let regions = bodies
            .regions
            .iter()
            .map(|reg| {
                let name = match (bodies.n_bodies(), &reg.group) {
                    (0, _) => "the body".to_string(),
                    (_, _) => reg.name.clone(),
                };
                (name, !reg.spec.model.is_finite_strain() && reg.n_cells > 0, 0.0, 0.0, false)
            })
            .collect();
        Ok(BodyRotations { dim, terms, regions })
    }

    /// The rotation of each region at the displacement `u` (time `t`); warns once about a
    /// small-strain body past [`WARN_DEGREES`]. Collective.
    pub fn step(&mut self, d: &Domain, console: &Console, u: &Vector, t: f64) -> Result<()> {
        let nr = self.regions.len();
        let dim = self.dim;
        let mut local = vec![0.0f64; nr * 9];
        u.with_local_slice(|x| {
            for &(dof, r, g) in &self.terms {
                for i in 0..dim {
                    for j in 0..dim {
                        local[r * 9 + i * 3 + j] += x[dof + i] * g[j];
                    }
                }
            }
        })?;
        let mut all = vec![0.0f64; nr * 9];
        d.world.all_reduce_into(&local[..], &mut all[..], SystemOperation::sum());
        for (r, reg) in self.regions.iter_mut().enumerate() {
            let mut f = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
            for i in 0..dim {
                for j in 0..dim {
                    f[i][j] += all[r * 9 + i * 3 + j];
                }
            }
            let angle = rotation_angle_degrees(&rotation(&f));
            if angle > reg.2 {
                reg.2 = angle;
                reg.3 = t;
            }
            if reg.1 && !reg.4 && angle > WARN_DEGREES {
                reg.4 = true;
                console.warn(format!(
                    "{} has turned {angle:.1} degrees at t = {}: a small-strain (linear) body that turns grows without stress; give it model = \"neo_hookean\" (or \"saint_venant_kirchhoff\") to step it at finite strain",
                    reg.0,
                    crate::console::time(t)
                ));
            }
        }
        Ok(())
    }

    /// The largest rotation of each body with cells (the cells outside every `[[body]]` of a
    /// scene with bodies only when they have cells).
    pub fn summary(&self, d: &Domain) -> Vec<BodyRotation> {
        self.regions
            .iter()
            .zip(&d.bodies.regions)
            .filter(|(_, reg)| reg.n_cells > 0)
            .map(|(r, _)| BodyRotation { body: r.0.clone(), degrees: r.2, time: r.3 })
            .collect()
    }
}
