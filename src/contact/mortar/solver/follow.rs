//! Finite sliding ([`InterfaceMode::Follow`]): the rounds of a contact step on the interface at
//! the step's midpoint, the planes shifted onto the end-of-step weighted gaps, and the rest of
//! the consistent contact force (docs/method.md, frozen and following interfaces).

use std::collections::HashMap;

use super::{largest_difference, MortarActiveSet};
use crate::contact::interface::ContactSolver;
use crate::contact::step::{NodePlane, StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::petsc::Vector;

/// Following: rounds with the whole gap linearization in the basis change before a step goes on
/// without it (`rows.rs`).
const ROWS_ROUNDS: usize = 8;

/// Following: a step is done when the rest of the consistent force changed by less than this
/// fraction of the largest nodal contact force in its last round.
const REST_RTOL: f64 = 1e-6;

impl MortarActiveSet<'_> {
    /// Finite sliding: rounds of the active set, each on the interface evaluated at the
    /// midpoint configuration of the last round's result, with the planes shifted so that
    /// they predict the weighted gaps at the end of the step; done when neither moves any
    /// more (`geometry_tol`). While no node is active or about to be, the interface is
    /// re-evaluated only as the update distance says, like the frozen one's approach.
    pub(super) fn solve_following(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { k, ksp, rhs, u, du, step, time, tau, linearization } = sys;
        const MAX_ROUNDS: usize = 100;
        // A step solved again (the energy correction) starts from its shifts, unless a node
        // lost its master (its plane is gone: the step starts afresh).
        if self.shift_step != step || self.shift.iter().any(|x| !x.is_finite()) {
            self.shift.iter_mut().for_each(|x| *x = 0.0);
            self.shift_step = step;
            self.rows_off = false;
        }
        // With the gap rows a round may overshoot into a configuration whose interface cannot
        // be evaluated (a slave face tipping over a master edge): the step then starts again
        // from here without them.
        let start = match self.rows_enabled && !self.rows_off {
            true => {
                let mut v = du.duplicate()?;
                v.copy_from(du)?;
                Some((v, self.rest.clone(), self.inner.nodes().active.clone()))
            }
            false => None,
        };
        let mut its = 0;
        let mut rounds = 0;
        loop {
            rounds += 1;
            let t0 = std::time::Instant::now();
            let mid = self.midpoint_trace(u, du)?;
            let moved = largest_difference(&mid, &self.evaluated_at);
            let near = self.inner.nodes().active.iter().any(|&a| a) || rounds > 1;
            self.cost.step_seconds += t0.elapsed().as_secs_f64();
            // In contact T, D, M, the normals and T^T K T may lag behind the midpoint by
            // `operator_lag` (1e-3 of a facet): the planes' shifts keep the gaps exact and the
            // rest is taken against the main terms T applied, so the lag changes only how fast
            // the rounds converge. The Jacobians of the consistent force follow the midpoint to
            // `move_tol` (1e-4 of a facet: the forces' direction and share to that fraction).
            // With the gap rows the basis change is Newton's operator: it follows to `move_tol`.
            let lag =
                if self.rows_enabled && !self.rows_off { self.move_tol } else { self.operator_lag };
            let limit = if near { lag } else { self.update_distance };
            // Newton with the rows where the gaps are smooth; where a node crosses a kink (a
            // master edge, a node whose partners change) it may cycle: after ROWS_ROUNDS
            // rounds the step goes on with the main terms only and the lagged rest (the
            // slower, sure fixed point), evaluated afresh.
            let drop_rows = rounds == ROWS_ROUNDS && !self.gap_rows.is_empty();
            if drop_rows {
                self.rows_off = true;
                self.cost.rows_dropped += 1;
            }
            if moved > limit || drop_rows {
                match self.update(k, mid) {
                    Err(Error::Geometry(_)) if start.is_some() && !self.rows_off => {
                        self.go_back(du, start.as_ref().expect("matched"))?;
                        continue;
                    }
                    r => r?,
                }
            } else {
                if near && largest_difference(&mid, &self.jacobians_at) > self.move_tol {
                    self.jacobians.clear();
                    self.jacobians_at = mid;
                }
                if rounds > 1 {
                    self.inner.nodes_mut().node_planes = Some(self.shifted_planes());
                }
            }
            let applied = self.rest.clone();
            self.load_rest()?;
            let sys = StepSystem {
                k: &mut *k,
                ksp: &mut *ksp,
                rhs,
                u,
                du: &mut *du,
                step,
                time,
                tau,
                linearization,
            };
            let (mut out, n) = self.round(sys)?;
            its += n;
            if !out.row.active.iter().any(|&a| a) {
                if applied.iter().any(|&x| x != 0.0) {
                    // The rest of the force of the last contact step was applied as a guess:
                    // solve again without it.
                    self.rest.iter_mut().for_each(|x| *x = 0.0);
                    continue;
                }
                if rounds == 1 && !self.penetrates_at_end(u, du)? {
                    return Ok((out, its));
                }
            }
            // Where the planes put the slave nodes at the end of the step, against the
            // weighted gaps there: the shift that moves each plane onto the truth.
            let t1 = std::time::Instant::now();
            let e0 = self.cost.evaluation_seconds;
            let end = self.end_trace(u, du)?;
            let predicted = self.predicted_gaps(&end);
            // Only the nodes in contact or within the update distance of it can miss their
            // plane by anything that matters in this step: the others keep the prediction.
            let near: Vec<bool> = (predicted.iter().zip(&out.row.active))
                .map(|(g, &a)| {
                    a || g.is_some_and(|g| g < self.update_distance.min(self.pair.reach))
                })
                .collect();
            let truth = match self.end_gaps(&end, &near) {
                Err(Error::Geometry(_)) if start.is_some() && !self.rows_off => {
                    self.go_back(du, start.as_ref().expect("matched"))?;
                    continue;
                }
                r => r?,
            };
            let truth: Vec<Option<f64>> = (truth.into_iter().zip(&predicted).zip(&near))
                .map(|((t, &pr), &n)| if n { t } else { pr })
                .collect();
            self.cost.step_seconds +=
                t1.elapsed().as_secs_f64() - (self.cost.evaluation_seconds - e0);
            let mut off = 0.0f64;
            for (p, (t, pr)) in truth.iter().zip(&predicted).enumerate() {
                let (Some(pr), Some(t)) = (pr, t) else {
                    if pr.is_some() && out.row.active[p] {
                        off = f64::INFINITY; // an active node with no master left under it
                    }
                    if pr.is_some() {
                        self.shift[p] = f64::INFINITY;
                    }
                    continue;
                };
                let delta = t - pr;
                if out.row.active[p] || *t < -self.geometry_tol {
                    off = off.max(delta.abs());
                }
                self.shift[p] += delta;
            }
            let mid = self.midpoint_trace(u, du)?;
            let moved = largest_difference(&mid, &self.jacobians_at);
            // The rest of the consistent force at this midpoint, with this round's forces.
            let t2 = std::time::Instant::now();
            self.rest = self.consistent_rest(&out)?;
            self.cost.gradient_seconds += t2.elapsed().as_secs_f64();
            let fmax = out.row.force.iter().fold(0.0f64, |a, f| a.max(f.abs()));
            let changed = largest_difference(&self.rest, &applied);
            let largest = (moved, off, changed);
            if moved <= self.move_tol && off <= self.geometry_tol && changed <= REST_RTOL * fmax {
                if out.row.active.iter().any(|&a| a) {
                    self.cost.following_solves += 1;
                    self.cost.rounds += rounds;
                    if self.counted_step != step {
                        self.cost.following_steps += 1;
                        self.counted_step = step;
                    }
                }
                self.extra_rounds += rounds - 1;
                self.rest_into(&applied, &mut out, du)?;
                if largest_difference(&mid, &self.evaluated_at) > self.move_tol {
                    // (Where D cannot be had at the midpoint, the forces stay stated with T's.)
                    match self.forces_at_midpoint(&mid, &mut out) {
                        Err(Error::Geometry(_)) => {}
                        r => r?,
                    }
                }
                return Ok((out, its));
            }
            if rounds == MAX_ROUNDS {
                return Err(Error::Solver(format!(
                    "mortar: the interface did not settle in {MAX_ROUNDS} rounds at step {step} (t = {}): the midpoint moved {:.3e} since its evaluation, the planes miss the end-of-step gaps by {:.3e}, tolerance {:.3e} (-mortar_geometry_tol); the consistent force changed by {:.3e}",
                    crate::console::time(time),
                    largest.0, largest.1, self.geometry_tol, largest.2
                )));
            }
        }
    }

    /// `sum_q lambda_q grad g~_q` at the pair displacement `mid` with the forces of `out`
    /// (`lambda_q = f_q / D_qq`), minus the main terms the solve applied (`-f_q n_q` on the
    /// slave nodes, `sum_q (M_ql / D_qq) f_q n_q` on the master nodes): per pair node and
    /// component, the same on every rank (collective).
    fn consistent_rest(&mut self, out: &StepContact) -> Result<Vec<f64>> {
        let dim = self.pair.part.dim;
        let mut lambda: HashMap<usize, f64> = HashMap::new();
        for &p in &self.slots {
            if out.row.force[p] != 0.0 && self.d_evaluated[p] > 0.0 {
                let v = self.inner.nodes().boundary.nodes[p];
                lambda.insert(v, out.row.force[p] / self.d_evaluated[p]);
            }
        }
        let loaded: Vec<usize> = if lambda.is_empty() {
            Vec::new()
        } else {
            let keys: std::collections::HashSet<usize> = lambda.keys().copied().collect();
            self.owned_facets_around(&keys)
        };
        // The Jacobians at the configuration the interface was evaluated on (a stale Jacobian,
        // kept for 1e-3 of a facet, made the energy error of the discs 5 times and of the 3D
        // slide 700 times larger for a third less time).
        self.ensure_jacobians(&loaded)?;
        let at = self.pair.slots();
        let mut local = vec![0.0; self.pair.dofs.len()];
        if !lambda.is_empty() {
            for i in &loaded {
                let f = &self.pair.slave[*i];
                let jac = &self.jacobians[i];
                for (j, v) in f.nodes.iter().enumerate() {
                    let Some(&lam) = lambda.get(v) else { continue };
                    for (kk, w) in jac.moving.iter().enumerate() {
                        let Some(&k) = at.get(w) else { continue };
                        for c in 0..dim {
                            local[k * dim + c] += lam * jac.d[j][kk][c];
                        }
                    }
                }
            }
        }
        let nodes = self.inner.nodes();
        let mut rest = vec![0.0; local.len()];
        mpi::traits::CommunicatorCollectives::all_reduce_into(
            nodes.world,
            &local[..],
            &mut rest[..],
            mpi::collective::SystemOperation::sum(),
        );
        if lambda.is_empty() {
            return Ok(rest);
        }
        for &p in &self.slots {
            let k = at[&nodes.boundary.nodes[p]];
            for c in 0..dim {
                rest[k * dim + c] += out.row.force[p] * out.normals[p][c];
            }
        }
        // (The normal part only: friction's tangential forces are applied through the basis
        // change, with no rest.)
        for (l, f) in self.master_normal.iter().enumerate() {
            let k = at[&self.master[l]];
            for c in 0..dim {
                rest[k * dim + c] -= f[c];
            }
        }
        // And what the rows applied through the basis change.
        for (r, f) in rest.iter_mut().zip(self.row_forces(out)) {
            *r -= f;
        }
        Ok(rest)
    }

    /// The rest of the consistent force into the hat's vector (owned DOFs).
    fn load_rest(&mut self) -> Result<()> {
        let lo = self.pair.part.first_dof();
        let h = self.hat.as_mut().expect("built in solve");
        let rest = &self.rest;
        let dofs = &self.pair.dofs;
        h.rest.with_local_slice_mut(|v| {
            v.iter_mut().for_each(|x| *x = 0.0);
            for (k, &(dof, owned)) in dofs.iter().enumerate() {
                if owned {
                    v[dof as usize - lo] = rest[k];
                }
            }
        })?;
        Ok(())
    }

    /// The step's contact data with the rest of the consistent force `applied` (as the last
    /// round solved with it): its work over `du`, its share of each body's force.
    fn rest_into(&mut self, applied: &[f64], out: &mut StepContact, du: &Vector) -> Result<()> {
        // The rows' forces are in the inner solver's work already, not in its nodal forces.
        let rows = self.row_forces(out);
        let lagged = applied.iter().any(|&x| x != 0.0);
        if !lagged && !rows.iter().any(|&x| x != 0.0) {
            return Ok(());
        }
        let dim = self.pair.part.dim;
        let h = self.hat.as_ref().expect("built in solve");
        if lagged {
            out.work += h.rest.dot(du)?;
        }
        let applied: Vec<f64> = applied.iter().zip(&rows).map(|(a, r)| a + r).collect();
        let at = self.pair.slots();
        let nodes = self.inner.nodes();
        let mut is_slave = vec![false; applied.len() / dim];
        for &p in &self.slots {
            is_slave[at[&nodes.boundary.nodes[p]]] = true;
        }
        let m_of: HashMap<usize, usize> =
            self.master.iter().enumerate().map(|(l, &v)| (v, l)).collect();
        let p_of: HashMap<usize, usize> =
            self.slots.iter().map(|&p| (nodes.boundary.nodes[p], p)).collect();
        // Beside friction's tangential forces (if any), the rest's share.
        out.contact_nodal.resize(nodes.len(), [0.0; 3]);
        for (k, &v) in self.pair.nodes.iter().enumerate() {
            for c in 0..dim {
                let f = applied[k * dim + c];
                if is_slave[k] {
                    // The slave body gets -resultant.
                    out.resultant[c] -= f;
                    out.contact_nodal[p_of[&v]][c] += f;
                } else {
                    out.master_force[c] += f;
                    if let Some(&l) = m_of.get(&v) {
                        out.master_nodal[l][c] += f;
                    }
                }
            }
        }
        Ok(())
    }

    /// The pair's nodes' displacements at the midpoint `u + du/2` (every rank).
    fn midpoint_trace(&mut self, u: &Vector, du: &Vector) -> Result<Vec<f64>> {
        let h = self.hat.as_mut().expect("built in solve");
        h.mid.waxpy(0.5, du, u)?;
        self.pair.trace(self.inner.nodes().world, &h.mid)
    }

    /// The pair's nodes' displacements at the end `u + du` (every rank).
    fn end_trace(&mut self, u: &Vector, du: &Vector) -> Result<Vec<f64>> {
        let h = self.hat.as_mut().expect("built in solve");
        h.mid.waxpy(1.0, du, u)?;
        self.pair.trace(self.inner.nodes().world, &h.mid)
    }

    /// Whether a slave node ends the step behind its plane (approach: the first round found
    /// no contact, yet the linearization may be off at the end).
    fn penetrates_at_end(&mut self, u: &Vector, du: &Vector) -> Result<bool> {
        let end = self.end_trace(u, du)?;
        let predicted = self.predicted_gaps(&end);
        Ok(predicted.iter().flatten().any(|&g| g < -self.geometry_tol))
    }

    /// Per contact node: the gap the current planes give at the pair displacement `end`
    /// (`c_q - n_q . (x_q + u~_q)`, `u~_q = u_q - sum_l (M_ql / D_qq) u_l`); `None` off the
    /// slave nodes and where no plane holds.
    fn predicted_gaps(&self, end: &[f64]) -> Vec<Option<f64>> {
        let dim = self.pair.part.dim;
        let at = self.pair.slots();
        let nodes = self.inner.nodes();
        let planes = nodes.node_planes.as_ref().expect("a pair's planes");
        let mut ut: Vec<[f64; 3]> = vec![[0.0; 3]; nodes.len()];
        for &p in &self.slots {
            let k = at[&nodes.boundary.nodes[p]];
            for c in 0..dim {
                ut[p][c] = end[k * dim + c];
            }
        }
        for &(p, l, w) in &self.couplings {
            let k = at[&self.master[l]];
            for c in 0..dim {
                ut[p][c] -= w * end[k * dim + c];
            }
        }
        // The rows, along the plane's normal.
        for r in &self.gap_rows {
            let n = planes[r.p].map_or([0.0; 3], |(_, n)| n);
            let wu: f64 = (0..dim).map(|c| r.w[c] * end[r.k * dim + c]).sum();
            for c in 0..dim {
                ut[r.p][c] -= wu * n[c];
            }
        }
        (0..nodes.len())
            .map(|p| match planes[p] {
                Some((c, n))
                    if c < f64::MAX / 2.0
                        && self.base_planes[p].is_some_and(|b| b.0 < f64::MAX) =>
                {
                    let x = self.pair.mesh.coords[nodes.boundary.nodes[p]];
                    Some(c - (0..dim).map(|i| n[i] * (x[i] + ut[p][i])).sum::<f64>())
                }
                _ => None,
            })
            .collect()
    }

    /// The slave facets around the contact nodes `near` marks: their nodes' sums are whole.
    fn facets_around(&self, near: &[bool]) -> Vec<bool> {
        let nodes = &self.inner.nodes().boundary.nodes;
        let asked: std::collections::HashSet<usize> =
            (0..near.len()).filter(|&p| near[p]).map(|p| nodes[p]).collect();
        self.pair.slave.iter().map(|f| f.nodes.iter().any(|v| asked.contains(v))).collect()
    }

    /// Per contact node marked `near`: the weighted gap at the pair displacement `end`, per
    /// unit of `D` (`g_q / D_qq`, a length); `None` elsewhere, off the slave nodes and where no
    /// master lies under the node's support (collective: one interface evaluation of the slave
    /// facets around the nodes asked for).
    fn end_gaps(&mut self, end: &[f64], near: &[bool]) -> Result<Vec<Option<f64>>> {
        let world = self.inner.nodes().world;
        let only = self.facets_around(near);
        let iface = self.pair.evaluate(world, end, &mut self.cost, Some(&only))?;
        let covered = iface.m_row_sums();
        let mut out = vec![None; self.inner.nodes().len()];
        for (q, &p) in self.slots.iter().enumerate() {
            if covered[q] > 0.0 && iface.d[q] > 0.0 {
                out[p] = Some(iface.gap[q] / iface.d[q]);
            }
        }
        Ok(out)
    }

    /// Back to the step's start (`du`, the rest, the active set) without the gap rows, the
    /// interface evaluated afresh in the next round.
    fn go_back(&mut self, du: &mut Vector, start: &(Vector, Vec<f64>, Vec<bool>)) -> Result<()> {
        du.copy_from(&start.0)?;
        self.rest.clone_from(&start.1);
        self.inner.nodes_mut().active.clone_from(&start.2);
        self.shift.iter_mut().for_each(|x| *x = 0.0);
        self.rows_off = true;
        self.cost.rows_dropped += 1;
        self.evaluated_at.iter_mut().for_each(|x| *x = f64::INFINITY);
        Ok(())
    }

    /// The slave nodes' forces `f_q = lambda_q D_qq` with `D` at the midpoint `mid` rather than
    /// where `T` was evaluated (it may lag by `operator_lag`): the multipliers `lambda_q = f_q /
    /// D_qq(T)` are the step's solution, `D` only how a node's force is stated (collective: an
    /// evaluation of the slave facets around the active nodes).
    fn forces_at_midpoint(&mut self, mid: &[f64], out: &mut StepContact) -> Result<()> {
        let world = self.inner.nodes().world;
        let only = self.facets_around(&out.row.active);
        let iface = self.pair.evaluate(world, mid, &mut self.cost, Some(&only))?;
        // The force applied stays: what the main term no longer states joins the rest's share.
        out.contact_nodal.resize(out.row.force.len(), [0.0; 3]);
        for (q, &p) in self.slots.iter().enumerate() {
            if out.row.active[p] && self.d_evaluated[p] > 0.0 && iface.d[q] > 0.0 {
                let ratio = iface.d[q] / self.d_evaluated[p];
                let f = out.row.force[p] * ratio;
                for c in 0..3 {
                    out.contact_nodal[p][c] += (f - out.row.force[p]) * out.normals[p][c];
                }
                out.row.force[p] = f;
                // Friction's tangential force is stated alike (the force applied, `-t` in
                // `contact_nodal`, stays).
                if let Some(t) = out.row.tangential.get_mut(p) {
                    *t = t.map(|x| x * ratio);
                }
            }
        }
        Ok(())
    }

    /// The evaluated planes moved by `shift`.
    pub(super) fn shifted_planes(&self) -> Vec<Option<NodePlane>> {
        (self.base_planes.iter().zip(&self.shift))
            .map(|(b, s)| {
                b.map(|(c, n)| if c < f64::MAX { ((c + s).min(f64::MAX), n) } else { (c, n) })
            })
            .collect()
    }
}
