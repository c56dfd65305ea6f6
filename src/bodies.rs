//! The bodies of a scene, for their momentum balance: every physical group of the mesh's
//! dimension is a body (e.g. "upper" and "lower" of the two-disc mesh).
//!
//! A body's momentum is `sum_{i in body} (M v)_i` per component. No cell joins two bodies, so
//! `M` (and `M_H`, whose layer and partner cells stay inside one body) and `A` are block
//! diagonal by body, `1_c^T A = 0` on a free body, and the midpoint rule gives
//! `p^{n+1} - p^n = tau (f - f_contact)^{n+1/2}` summed over the body's DOFs exactly: the
//! momentum change of a free body equals the impulse of the contact forces on it.
//!
//! Built from this rank's own cells (a node's owner owns a cell that holds it): no loop over
//! the whole mesh, O(owned nodes) memory.

use std::collections::HashSet;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::error::Result;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::Vector;

/// One body's momentum and the impulse the contact gave it (per component, `dim` entries).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BodySummary {
    pub name: String,
    /// `sum (M v)` over the body's DOFs at the start and the end of the run.
    pub momentum_initial: Vec<f64>,
    pub momentum_final: Vec<f64>,
    /// `tau sum_n` of the contact forces on the body (zero for a body no contact touches).
    pub contact_impulse: Vec<f64>,
}

pub struct Bodies {
    pub names: Vec<String>,
    /// Per body: this rank's owned nodes of the body (mesh indices).
    owned: Vec<HashSet<usize>>,
    /// Per body: the first local DOF of each of them.
    local_dofs: Vec<Vec<usize>>,
    dim: usize,
}

impl Bodies {
    /// The physical groups of dimension `mesh.dim`, in the mesh's order.
    pub fn new(mesh: &Mesh, part: &Partition) -> Result<Bodies> {
        let mut names = Vec::new();
        let mut owned = Vec::new();
        for g in mesh.groups.iter().filter(|g| g.dim == mesh.dim) {
            let mut set = HashSet::new();
            for &c in &part.local_cells {
                let cell = &mesh.cells[c];
                if g.entities.contains(&cell.entity) {
                    set.extend(cell.nodes().iter().copied().filter(|&v| part.owns(v)));
                }
            }
            names.push(g.name.clone());
            owned.push(set);
        }
        let lo = part.first_dof();
        let local_dofs = owned
            .iter()
            .map(|set| {
                let mut v: Vec<usize> = set.iter().map(|&n| part.dof(n, 0) - lo).collect();
                v.sort_unstable();
                v
            })
            .collect();
        Ok(Bodies { names, owned, local_dofs, dim: part.dim })
    }

    /// Momentum `sum (M v)` of every body, from `mv = M v` (collective; identical on every
    /// rank).
    pub fn momenta(&self, world: &SimpleCommunicator, mv: &Vector) -> Result<Vec<[f64; 3]>> {
        let d = self.dim;
        let mut local = vec![0.0; 3 * self.owned.len()];
        mv.with_local_slice(|s| {
            for (b, dofs) in self.local_dofs.iter().enumerate() {
                for &k in dofs {
                    for c in 0..d {
                        local[3 * b + c] += s[k + c];
                    }
                }
            }
        })?;
        let mut all = vec![0.0; local.len()];
        world.all_reduce_into(&local[..], &mut all[..], SystemOperation::sum());
        Ok(all.chunks(3).map(|p| [p[0], p[1], p[2]]).collect())
    }

    /// The body that holds the nodes of boundary group `group` (collective), if one does.
    pub fn holding(
        &self,
        world: &SimpleCommunicator,
        mesh: &Mesh,
        group: &str,
    ) -> Result<Option<usize>> {
        let nodes = mesh.group_nodes(group)?;
        let local: Vec<f64> = self
            .owned
            .iter()
            .map(|set| nodes.iter().filter(|v| set.contains(v)).count() as f64)
            .collect();
        let mut all = vec![0.0; local.len()];
        world.all_reduce_into(&local[..], &mut all[..], SystemOperation::sum());
        Ok(all.iter().position(|&n| n as usize == nodes.len() && !nodes.is_empty()))
    }
}
