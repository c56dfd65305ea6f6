//! Finite sliding: the active slave nodes' whole gap linearization in the basis change.
//!
//! The planes of [`super::planes`] carry only the main terms of `grad g~_q` (`-D_qq n_q` on the
//! slave node, `M_ql n_q` on the master nodes). Where the two surfaces are inclined to each
//! other (the edge of a Hertz contact) the rest, the tangential derivatives of the dual
//! functions, segment ends, projections and normals, moves the gap as much: a round then
//! predicts the end-of-step gap to a factor of about 0.1 only and the shifts converge linearly
//! (six or seven rounds on the oblique balls). Here the rest's derivatives `w_qk = (grad_k g~_q
//! - main) / D_qq` of the active nodes join the basis change:
//!
//! ```text
//! n_q . u~_q = n_q . u_q - sum_l (M_ql / D_qq) n_q . u_l - sum_k w_qk . u_k
//! E[(q,c),(l,c')] = n_q[c] n_q[c'] M_ql / D_qq   (master l: the main terms, along n_q only)
//! E[(q,c),(k,c')] += n_q[c] w_qk[c']             (master k, and slave k with w_qk . n_k = 0)
//! ```
//!
//! With the main terms along the normal only and the slave columns tangential to their own
//! node's normal, `E^2 = 0` still (a slave row's image is along its normal, which the slave
//! columns do not see), so `T = I + E` and `T^{-1} = I - E`. The constraint of an active node is
//! then the whole linearized gap and `T^T` applies the whole consistent force `sum_q lambda_q
//! grad g~_q` but for the slave columns' normal parts, which stay in the lagged rest: each
//! round is a Newton step of the geometry. The tangential ũ components are free DOFs either
//! way, so the step's solution does not depend on how they are chosen.

use std::collections::{HashMap, HashSet};

use super::super::gradient;
use super::super::interface::{gather, merge, MortarInterface};
use super::MortarActiveSet;
use crate::contact::interface::ContactSolver;
use crate::contact::step::StepContact;
use crate::error::Result;
use crate::partition::Partition;
use crate::petsc::Matrix;

/// Entries of `w` below this (dimensionless: the main terms are of order one) are the
/// differences' noise: aligned surfaces have none.
const ROW_FLOOR: f64 = 1e-6;

/// One entry of an active slave node's linearized gap beyond the main terms.
#[derive(Debug, Clone, Copy)]
pub(super) struct GapRow {
    /// The slave node's index in the interface (`iface.slave`) and among the contact nodes.
    pub q: usize,
    pub p: usize,
    /// The moving node (mesh index) and its slot in the pair's trace.
    pub node: usize,
    pub k: usize,
    /// `w_qk`: the derivative of `g~_q / D_qq` by the node's position, beyond the main terms.
    pub w: [f64; 3],
}

impl MortarActiveSet<'_> {
    /// The Jacobians of this rank's slave facets `facets` at the evaluation point, computed
    /// where not cached yet.
    pub(super) fn ensure_jacobians(&mut self, facets: &[usize]) -> Result<()> {
        let missing: Vec<usize> =
            facets.iter().copied().filter(|i| !self.jacobians.contains_key(i)).collect();
        if missing.is_empty() {
            return Ok(());
        }
        let dim = self.pair.part.dim;
        let at = self.pair.slots();
        let at_eval = &self.jacobians_at;
        let x = |v: usize| {
            let mut p = self.pair.mesh.coords[v];
            if let Some(&k) = at.get(&v) {
                for c in 0..dim {
                    p[c] += at_eval[k * dim + c];
                }
            }
            p
        };
        let (part, tags) = (&self.pair.part, &self.pair.mesh.node_tags);
        let column = |f: &super::super::interface::SurfaceFacet, v: usize| {
            super::super::interface::column_is_mine(f, tags[v], part)
        };
        let jacobians = |which: &[usize]| {
            gradient::facet_jacobians(
                dim,
                &self.pair.slave,
                which,
                &self.pair.master,
                &self.adjacency,
                &x,
                self.pair.reach,
                !self.closed_form,
                &column,
            )
        };
        // A facet whose perturbed geometry cannot be integrated (a warped face tipping over
        // an edge projects to a non-convex polygon) is left out of the derivatives at this
        // evaluation, and counted.
        let jac = match jacobians(&missing) {
            Ok(j) => j,
            Err(_) => {
                let mut out = Vec::with_capacity(missing.len());
                for &i in &missing {
                    out.push(jacobians(&[i]).map(|mut j| j.remove(0)).unwrap_or_else(|_| {
                        self.cost.jacobians_skipped += 1;
                        gradient::FacetJacobian::default()
                    }));
                }
                out
            }
        };
        self.jacobians.extend(missing.into_iter().zip(jac));
        Ok(())
    }

    /// The slave facets with a node among `nodes` (mesh indices) whose derivatives this rank
    /// takes a share of: every rank where the facets are spread (each its columns,
    /// [`column_is_mine`](super::super::interface::column_is_mine)), else the facets it
    /// integrates.
    pub(super) fn owned_facets_around(&self, nodes: &HashSet<usize>) -> Vec<usize> {
        (0..self.pair.slave.len())
            .filter(|&i| {
                let f = &self.pair.slave[i];
                (f.worker != usize::MAX || f.is_mine(&self.pair.part))
                    && f.nodes.iter().any(|v| nodes.contains(v))
            })
            .collect()
    }

    /// The rows of the slave nodes active now, at the interface `iface` just evaluated (on
    /// `self.evaluated_at`); the same on every rank (collective).
    pub(super) fn gap_rows(
        &mut self,
        iface: &MortarInterface,
        slots: &[usize],
    ) -> Result<Vec<GapRow>> {
        let dim = self.pair.part.dim;
        let active = &self.inner.nodes().active;
        let covered = iface.m_row_sums();
        // Only nodes whose support the master covers whole: at a master edge the gap is only
        // piecewise smooth (the covered part ends there), and a Newton step on it overshoots
        // (a cube tipping over a plate's edge was driven into faces that cannot be projected).
        let asked: HashSet<usize> = (0..iface.slave.len())
            .filter(|&q| {
                active[slots[q]] && iface.d[q] > 0.0 && covered[q] >= (1.0 - 1e-6) * iface.d[q]
            })
            .map(|q| iface.slave[q])
            .collect();
        let any = crate::comm::max_over_ranks(self.inner.nodes().world, asked.len() as f64);
        if any == 0.0 {
            return Ok(Vec::new());
        }
        let slave_of: HashMap<usize, usize> =
            iface.slave.iter().enumerate().map(|(q, &v)| (v, q)).collect();
        let facets = self.owned_facets_around(&asked);
        self.ensure_jacobians(&facets)?;
        // This rank's facets' parts of d g~_q / d x_v: (q, 3 v + c).
        let mut local: Vec<(u32, u32, f64)> = Vec::new();
        for i in &facets {
            let f = &self.pair.slave[*i];
            let jac = &self.jacobians[i];
            for (j, v) in f.nodes.iter().enumerate() {
                if !asked.contains(v) {
                    continue;
                }
                let q = slave_of[v] as u32;
                for (kk, &w) in jac.moving.iter().enumerate() {
                    for c in 0..dim {
                        local.push((q, (3 * w + c) as u32, jac.d[j][kk][c]));
                    }
                }
            }
        }
        let all = merge(&gather(self.inner.nodes().world, &local));
        let mut grad: HashMap<(usize, usize), [f64; 3]> = HashMap::new();
        for (q, key, value) in all {
            let (v, c) = (key as usize / 3, key as usize % 3);
            grad.entry((q as usize, v)).or_insert([0.0; 3])[c] += value;
        }
        // The main terms, `-D_qq n_q` at the slave node and `M_ql n_q` at the master nodes.
        let mut main: HashMap<(usize, usize), f64> = HashMap::new();
        for &(q, l, m) in &iface.m {
            main.insert((q as usize, iface.master[l as usize]), m);
        }
        let at = self.pair.slots();
        let mut keys: Vec<(usize, usize)> = grad.keys().copied().collect();
        keys.sort_unstable();
        let mut w_of: Vec<((usize, usize), [f64; 3])> = Vec::new();
        for (q, v) in keys {
            if !at.contains_key(&v) {
                continue;
            }
            let (n, d) = (iface.normals[q], iface.d[q]);
            let g = grad[&(q, v)];
            let mut w = [0.0; 3];
            let m = main.get(&(q, v)).copied().unwrap_or(0.0);
            let own = if v == iface.slave[q] { -d } else { 0.0 };
            for c in 0..dim {
                w[c] = (g[c] - (own + m) * n[c]) / d;
            }
            // A slave column keeps only what is tangential to its own node's normal.
            if let Some(&s) = slave_of.get(&v) {
                let nv = iface.normals[s];
                let along: f64 = (0..dim).map(|c| w[c] * nv[c]).sum();
                for c in 0..dim {
                    w[c] -= along * nv[c];
                }
            }
            // The differences' noise (aligned surfaces have none of these terms): left out.
            if w.iter().any(|&x| x.abs() > ROW_FLOOR) {
                w_of.push(((q, v), w));
            }
        }
        // A rigid translation leaves the gap as it is: the slave columns' normal parts left
        // out are given back on the node's master columns (in proportion to `M_ql`), so that
        // every row sums to zero and the forces it applies have no resultant in any round.
        let mut lost: HashMap<usize, [f64; 3]> = HashMap::new();
        for ((q, _), w) in &w_of {
            let e = lost.entry(*q).or_insert([0.0; 3]);
            for c in 0..3 {
                e[c] += w[c];
            }
        }
        let mut masters: HashMap<usize, Vec<(usize, f64)>> = HashMap::new();
        for &(q, l, m) in &iface.m {
            masters.entry(q as usize).or_default().push((iface.master[l as usize], m));
        }
        let mut all: HashMap<(usize, usize), [f64; 3]> = w_of.into_iter().collect();
        for (q, s) in lost {
            let Some(ms) = masters.get(&q) else { continue };
            let total: f64 = ms.iter().map(|&(_, m)| m).sum();
            if total <= 0.0 {
                continue;
            }
            for &(v, m) in ms {
                if !at.contains_key(&v) {
                    continue;
                }
                let e = all.entry((q, v)).or_insert([0.0; 3]);
                for c in 0..3 {
                    e[c] -= s[c] * m / total;
                }
            }
        }
        let mut keys: Vec<(usize, usize)> = all.keys().copied().collect();
        keys.sort_unstable();
        let rows = keys
            .into_iter()
            .map(|(q, v)| GapRow { q, p: slots[q], node: v, k: at[&v], w: all[&(q, v)] })
            .collect();
        Ok(rows)
    }

    /// The forces the rows apply through `T^T` with the round's nodal forces: `f_q w_qk` on
    /// node k (per pair node and component, as the rest).
    pub(super) fn row_forces(&self, out: &StepContact) -> Vec<f64> {
        let dim = self.pair.part.dim;
        let mut f = vec![0.0; self.pair.dofs.len()];
        for r in &self.gap_rows {
            let fq = out.row.force[r.p];
            if fq != 0.0 {
                for c in 0..dim {
                    f[r.k * dim + c] += fq * r.w[c];
                }
            }
        }
        f
    }
}

/// `E` (or `T = I + E` with `identity`) of the following interface: the main terms along the
/// slave normals and the rows (module docs); rows owned as the partition says.
pub(super) fn transfer_following(
    part: &Partition,
    iface: &MortarInterface,
    rows: &[GapRow],
    identity: bool,
) -> Result<Matrix> {
    let dim = part.dim;
    // Per slave node: column node -> the 3-vector `w` with `E[(q,c),(k,c')] = n_q[c] w[c']`.
    let mut per: Vec<HashMap<usize, [f64; 3]>> = vec![HashMap::new(); iface.slave.len()];
    for &(q, l, m) in &iface.m {
        let (q, n) = (q as usize, iface.normals[q as usize]);
        let e = per[q].entry(iface.master[l as usize]).or_insert([0.0; 3]);
        for c in 0..3 {
            e[c] += m / iface.d[q] * n[c];
        }
    }
    for r in rows {
        let e = per[r.q].entry(r.node).or_insert([0.0; 3]);
        for c in 0..3 {
            e[c] += r.w[c];
        }
    }
    let mut out: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
    for (q, cols) in per.iter().enumerate() {
        let v = iface.slave[q];
        if !part.owns(v) || cols.is_empty() {
            continue;
        }
        let n = iface.normals[q];
        let mut keys: Vec<usize> = cols.keys().copied().collect();
        keys.sort_unstable();
        for c in 0..dim {
            let entries = (keys.iter())
                .flat_map(|k| (0..dim).map(move |cc| (part.dof(*k, cc), n[c] * cols[k][cc])))
                .collect();
            out.push((part.dof(v, c), entries));
        }
    }
    super::basis_change(part, &out, identity)
}
