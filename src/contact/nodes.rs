//! The contact nodes: the contact boundary (nodes and boundary weights of the contact groups)
//! and [`ContactNodes`], what every rank holds of it during the run (reference positions, gmsh
//! tags, global DOFs, the obstacles or the pair's planes, the active set), with the per-node
//! geometry the solvers share: traces, gaps and normals, the step's contact data.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::friction::FrictionLaw;
use super::obstacle::{self, Obstacles};
use super::step::{NodePlane, StepContact};
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::Vector;
use crate::rows::ContactRow;

/// The contact boundary as every rank sees it: nodes (original indices, sorted), their
/// boundary weights `D_qq = int_{Gamma_C} phi_q ds`, and coordinates.
#[derive(Debug, Clone)]
pub struct ContactBoundary {
    pub group: String,
    pub nodes: Vec<usize>,
    pub weights: Vec<f64>,
}

impl ContactBoundary {
    pub fn build(mesh: &Mesh, group: &str) -> Result<ContactBoundary> {
        Self::build_groups(mesh, &[group])
    }

    /// The boundary of several groups (several pairs' slave groups), named by them joined
    /// with ", "; a facet in two groups counts once, a node on facets of two groups sums them.
    pub fn build_groups(mesh: &Mesh, groups: &[&str]) -> Result<ContactBoundary> {
        let mut elems = Vec::new();
        let mut seen = std::collections::HashSet::new();
        for g in groups {
            for e in crate::mesh::topology::boundary_group(mesh, g)? {
                let mut key = e.nodes().to_vec();
                key.sort_unstable();
                if seen.insert(key) {
                    elems.push(e);
                }
            }
        }
        let group = groups.join(", ");
        let mut nodes: Vec<usize> = elems.iter().flat_map(|e| e.nodes().into_iter()).collect();
        nodes.sort_unstable();
        nodes.dedup();
        let mut slot = std::collections::HashMap::new();
        for (k, &v) in nodes.iter().enumerate() {
            slot.insert(v, k);
        }
        let mut weights = vec![0.0; nodes.len()];
        let mut w = [0.0; 4];
        for e in &elems {
            let xy = mesh.element_coords(e);
            let n = e.kind.n_nodes();
            kernels::boundary_weights(e.kind, &xy, &mut w[..n]);
            for (i, &v) in e.nodes().iter().enumerate() {
                weights[slot[&v]] += w[i];
            }
        }
        Ok(ContactBoundary { group, nodes, weights })
    }

    /// The union of two boundaries that share no node (a pair's slave group and the group
    /// meeting obstacles beside it), each node with its own group's weight; named after
    /// `self`. An error names both groups when they share a node.
    pub fn union(self, other: ContactBoundary, mesh: &Mesh) -> Result<ContactBoundary> {
        let mut all: Vec<(usize, f64)> =
            self.nodes.iter().copied().zip(self.weights.iter().copied()).collect();
        all.extend(other.nodes.iter().copied().zip(other.weights.iter().copied()));
        all.sort_unstable_by_key(|&(v, _)| v);
        if let Some(w) = all.windows(2).find(|w| w[0].0 == w[1].0) {
            return Err(Error::Scene(format!(
                "contact.boundary = \"{}\" and contact.slave = \"{}\" share gmsh node {}: the group that meets the obstacles must be another part of the boundary than the slave side",
                other.group, self.group, mesh.node_tags[w[0].0]
            )));
        }
        Ok(ContactBoundary {
            group: self.group,
            nodes: all.iter().map(|&(v, _)| v).collect(),
            weights: all.iter().map(|&(_, w)| w).collect(),
        })
    }
}

/// Values of a distributed vector at a list of global DOFs `(dof, owned here)`, on every rank:
/// owners contribute, a sum over ranks assembles them (each DOF has exactly one owner, so the
/// sum is exact). Collective; `first_dof` is this rank's first owned DOF.
pub fn trace(
    world: &SimpleCommunicator,
    dofs: &[(i32, bool)],
    first_dof: usize,
    x: &Vector,
) -> Result<Vec<f64>> {
    let mut local = vec![0.0; dofs.len()];
    x.with_local_slice(|s| {
        for (i, &(dof, owned)) in dofs.iter().enumerate() {
            if owned {
                local[i] = s[dof as usize - first_dof];
            }
        }
    })?;
    let mut global = vec![0.0; local.len()];
    world.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
    Ok(global)
}

/// The contact nodes as every rank sees them: boundary, obstacles, reference positions, gmsh
/// tags and global DOFs. O(contact nodes) on every rank; no loop over the mesh after `new`.
pub struct ContactNodes<'w> {
    pub world: &'w SimpleCommunicator,
    pub boundary: ContactBoundary,
    pub obstacles: Obstacles,
    coords: Vec<[f64; 3]>,
    pub tags: Vec<u64>,
    pub dim: usize,
    /// Global DOF of (contact node k, component c), and whether this rank owns it.
    pub dofs: Vec<(i32, bool)>,
    pub first_dof: usize,
    /// Gap tolerance: penetration below this counts as contact (1e-12 of the size of the
    /// contact boundary).
    pub gap_tol: f64,
    /// The active set of the last step (the next step's first guess).
    pub active: Vec<bool>,
    /// Instead of the obstacles, one plane per slave node, `(c_q, n_q)`: node q must keep
    /// `n_q . y_q <= c_q` (two-body contact in the mortar basis,
    /// [`super::mortar::MortarActiveSet`]). `None` for the nodes that meet the obstacles beside
    /// a pair (`u~ = u` there).
    pub node_planes: Option<Vec<Option<NodePlane>>>,
    /// The friction law per obstacle, and last the pair's planes' (`None`: frictionless).
    pub friction: Vec<Option<FrictionLaw>>,
}

/// One contact node's friction in a step: the law of what it meets (Tresca's bound as the
/// node's force, the traction bound times its weight `D_qq`) and that side's displacement over
/// the step (an obstacle's translation; zero for a pair's plane).
#[derive(Debug, Clone, Copy)]
pub struct NodeFriction {
    pub law: FrictionLaw,
    pub motion: [f64; 3],
}

impl<'w> ContactNodes<'w> {
    pub fn new(
        world: &'w SimpleCommunicator,
        mesh: &Mesh,
        part: &Partition,
        boundary: ContactBoundary,
        obstacles: Obstacles,
    ) -> ContactNodes<'w> {
        let dim = part.dim;
        let n = boundary.nodes.len();
        let mut dofs = Vec::with_capacity(boundary.nodes.len() * dim);
        for &v in &boundary.nodes {
            for c in 0..dim {
                dofs.push((part.dof(v, c) as i32, part.owns(v)));
            }
        }
        let coords: Vec<[f64; 3]> = boundary.nodes.iter().map(|&v| mesh.coords[v]).collect();
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for x in &coords {
            for i in 0..3 {
                lo[i] = lo[i].min(x[i]);
                hi[i] = hi[i].max(x[i]);
            }
        }
        let diag = (0..3).map(|i| (hi[i] - lo[i]).max(0.0).powi(2)).sum::<f64>().sqrt();
        ContactNodes {
            world,
            tags: boundary.nodes.iter().map(|&v| mesh.node_tags[v]).collect(),
            coords,
            boundary,
            dim,
            dofs,
            first_dof: part.first_dof(),
            gap_tol: 1e-12 * diag.max(f64::MIN_POSITIVE),
            active: vec![false; n],
            node_planes: None,
            friction: obstacles.0.iter().map(|o| o.friction).collect(),
            obstacles,
        }
    }

    /// Whether any contact node has friction.
    pub fn has_friction(&self) -> bool {
        self.friction.iter().any(Option::is_some)
    }

    /// Per contact node with friction: its law and the displacement of what it meets over
    /// the step `time - tau .. time` (`closest`: each node's obstacle index, from
    /// [`ContactNodes::closest`]).
    pub fn node_friction(
        &self,
        closest: &[(usize, f64, [f64; 3])],
        time: f64,
        tau: f64,
    ) -> Vec<Option<NodeFriction>> {
        let motions: Vec<[f64; 3]> = (self.obstacles.0.iter())
            .map(|o| match &o.motion {
                None => [0.0; 3],
                Some(d) => {
                    let (a, b) = (d.eval([0.0; 3], time - tau), d.eval([0.0; 3], time));
                    [0, 1, 2].map(|i| b[i] - a[i])
                }
            })
            .collect();
        closest
            .iter()
            .zip(&self.boundary.weights)
            .map(|(&(o, _, _), &w)| {
                // Tresca's bound is a traction: the node's share is `s D_qq`.
                let law = match self.friction.get(o).copied().flatten()? {
                    FrictionLaw::Tresca { bound } => FrictionLaw::Tresca { bound: bound * w },
                    coulomb => coulomb,
                };
                Some(NodeFriction { law, motion: motions.get(o).copied().unwrap_or([0.0; 3]) })
            })
            .collect()
    }

    pub fn len(&self) -> usize {
        self.coords.len()
    }

    pub fn is_empty(&self) -> bool {
        self.coords.is_empty()
    }

    /// Values of a distributed vector at all contact DOFs, on every rank (owners contribute,
    /// a sum over ranks assembles them: each entry has exactly one owner, so the sum is exact).
    pub fn trace(&self, x: &Vector) -> Result<Vec<f64>> {
        trace(self.world, &self.dofs, self.first_dof, x)
    }

    /// For every contact node at displacement `u` (trace given), with the obstacles placed at
    /// `time`: the obstacle with the smallest gap (its index), that gap and its normal.
    pub fn closest(&self, u_trace: &[f64], time: f64) -> Vec<(usize, f64, [f64; 3])> {
        let d = self.dim;
        let placed = self.obstacles.at(time);
        self.coords
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                let mut y = x;
                for c in 0..d {
                    y[c] += u_trace[k * d + c];
                }
                match self.node_planes.as_ref().and_then(|p| p[k]) {
                    // Index past the obstacles (0 for a pair alone): the pair's plane.
                    Some((c, n)) => {
                        (self.obstacles.0.len(), c - (0..d).map(|i| n[i] * y[i]).sum::<f64>(), n)
                    }
                    None => obstacle::closest(&placed, y),
                }
            })
            .collect()
    }

    /// Gaps and normals of all contact nodes at displacement `u` (trace given) against the
    /// obstacles at `time` (the end of the step: `t_{n+1}`): each node's closest obstacle.
    pub fn frames(&self, u_trace: &[f64], time: f64) -> Vec<(f64, [f64; 3])> {
        self.closest(u_trace, time).into_iter().map(|(_, g, n)| (g, n)).collect()
    }

    /// `n_q . x_q` for every contact node, from a trace.
    pub fn normal_parts(&self, frames: &[(f64, [f64; 3])], trace: &[f64]) -> Vec<f64> {
        let d = self.dim;
        frames
            .iter()
            .enumerate()
            .map(|(p, f)| (0..d).map(|c| f.1[c] * trace[p * d + c]).sum())
            .collect()
    }

    /// Contact nodes that penetrate an obstacle at displacement `u` and `time` (beyond the
    /// tolerance): (mesh node index, obstacle index).
    pub fn penetrating(&self, u: &Vector, time: f64) -> Result<Vec<(usize, usize)>> {
        let tr = self.trace(u)?;
        Ok(self
            .closest(&tr, time)
            .iter()
            .enumerate()
            .filter(|(_, (_, g, _))| *g < -self.gap_tol)
            .map(|(k, &(o, _, _))| (self.boundary.nodes[k], o))
            .collect())
    }

    /// The contact node closest to an obstacle in the reference configuration at t = 0.
    /// Of a pair with obstacles beside it: the slave node closest to the master (the node whose
    /// pressure the paper plots).
    pub fn lowest(&self) -> usize {
        let gaps = self.closest(&vec![0.0; self.len() * self.dim], 0.0);
        let slave = |k: &usize| self.node_planes.as_ref().is_none_or(|p| p[*k].is_some());
        (0..gaps.len())
            .filter(slave)
            .min_by(|&a, &b| {
                gaps[a]
                    .1
                    .partial_cmp(&gaps[b].1)
                    .unwrap_or(std::cmp::Ordering::Equal)
                    .then(a.cmp(&b))
            })
            .unwrap_or(0)
    }

    /// The step's contact data from the converged iteration: forces `lambda` (of the
    /// midpoint equation; zero off the active set), the increment's trace, the frames at `t_n`,
    /// and with friction the nodes' tangential data.
    pub fn step_contact(
        &self,
        frames: &[(f64, [f64; 3])],
        active: Vec<bool>,
        lambda: &[f64],
        du_trace: &[f64],
        iterations: usize,
        friction: Option<StepFriction>,
    ) -> StepContact {
        let nc = self.len();
        let ndu = self.normal_parts(frames, du_trace);
        let mut out = StepContact {
            row: ContactRow {
                force: vec![0.0; nc],
                gap: (0..nc).map(|p| frames[p].0 - ndu[p]).collect(),
                active,
                iterations,
                ..ContactRow::default()
            },
            normals: frames.iter().map(|f| f.1).collect(),
            work: 0.0,
            dissipation: 0.0,
            tangential_work: 0.0,
            resultant: [0.0; 3],
            obstacle_force: [0.0; 3],
            master_force: [0.0; 3],
            master_nodal: Vec::new(),
            master_friction: Vec::new(),
            friction_nodal: Vec::new(),
            contact_nodal: Vec::new(),
            cycled: false,
        };
        for p in 0..nc {
            if out.row.active[p] {
                let lam = lambda[p];
                out.row.force[p] = lam;
                out.work -= lam * ndu[p];
                // Beside a pair, the nodes without a plane meet the obstacles.
                let on_obstacle = self.node_planes.as_ref().is_some_and(|pl| pl[p].is_none());
                let sum = if on_obstacle { &mut out.obstacle_force } else { &mut out.resultant };
                for (c, s) in sum.iter_mut().enumerate().take(self.dim) {
                    *s += lam * frames[p].1[c];
                }
            }
        }
        if let Some(f) = friction {
            for p in (0..nc).filter(|&p| out.row.active[p]) {
                let (t, s, w) = (f.tangential[p], f.slip[p], f.motion_t[p]);
                out.dissipation += (0..3).map(|i| t[i] * s[i]).sum::<f64>();
                out.tangential_work -= (0..3).map(|i| t[i] * w[i]).sum::<f64>();
                let on_obstacle = self.node_planes.as_ref().is_some_and(|pl| pl[p].is_none());
                let sum = if on_obstacle { &mut out.obstacle_force } else { &mut out.resultant };
                for (c, x) in sum.iter_mut().enumerate() {
                    *x += t[c];
                }
            }
            out.contact_nodal = f.tangential.iter().map(|t| t.map(|x| -x)).collect();
            out.friction_nodal.clone_from(&out.contact_nodal);
            out.row.tangential = f.tangential;
            out.row.state = f.state;
            out.row.slip = f.slip;
        }
        out
    }
}

/// A step's friction data per contact node, from the converged iteration (zero off
/// contact): the tangential force on the obstacle side `t_q`, the set
/// ([`crate::rows::STATE_SLIP`], ...), the slip increment `s_q` and the tangential
/// displacement `w_q` of the obstacle side over the step.
#[derive(Debug, Clone, Default)]
pub struct StepFriction {
    pub tangential: Vec<[f64; 3]>,
    pub state: Vec<u8>,
    pub slip: Vec<[f64; 3]>,
    pub motion_t: Vec<[f64; 3]>,
}
