//! Normal constraints `n_q . du_q = g_q` on the active contact nodes, imposed on the step
//! operator itself, so that an active-set iteration is one ordinary sparse solve.
//!
//! With `N_q = e_q n_q n_q^T e_q^T` (node q's normal direction), `P = I - sum_{q in A} N_q` and
//! `du_p = sum_{q in A} g_q n_q e_q`, the constrained step is
//!
//! ```text
//! K~ du = b,   K~ = P K P + sum_q d_q N_q,   b = P (rhs - K du_p) + sum_q d_q g_q n_q e_q.
//! ```
//!
//! Its solution has `n_q . du_q = g_q` on A and `P (rhs - K du) = 0`: the residual is normal
//! at the active nodes and is the contact force, `factor lambda_q = n_q . (rhs - K du)_q`
//! (Hueber and Wohlmuth's primal-dual active set with node-local constraints; the rotation
//! to normal/tangential DOFs is implicit in `P`). `K~` is SPD with `K`'s pattern;
//! `d_q = n_q^T K_qq n_q` keeps its diagonal on `K`'s scale, so Jacobi (or any PETSc
//! preconditioner, or a direct solver) applies unchanged.
//!
//! Memory O(contact nodes): the original rows of the owned nodes that share a cell with a
//! contact node (to restore and to transform them) and `K`'s rows at the owned contact DOFs
//! as a small distributed matrix (for the forces). Changing the active set rewrites only the
//! rows next to the nodes that were or are active; nothing else of `K` is touched.

use std::collections::HashMap;

use mpi::collective::SystemOperation;
use mpi::traits::*;

use super::nodes::ContactNodes;
use crate::error::{Error, Result};
use crate::petsc::{Matrix, Vector};

/// The original rows of one owned node (all `dim` components share the columns).
struct NodeRows {
    dof0: i32,
    cols: Vec<i32>,
    /// `dim x cols.len()`, row-major.
    vals: Vec<f64>,
    /// Contact-node column blocks in this row: (position of the block's first column, contact
    /// node index).
    blocks: Vec<(u32, u32)>,
    /// For a contact node: its index and the position of its diagonal block.
    contact: Option<(u32, u32)>,
}

impl NodeRows {
    /// `n^T K_qq n` from the original diagonal block of a contact node.
    fn normal_stiffness(&self, dim: usize, n: &[f64; 3]) -> f64 {
        let (_, pos) = self.contact.expect("a contact node's rows");
        let nc = self.cols.len();
        let mut s = 0.0;
        for a in 0..dim {
            for b in 0..dim {
                s += n[a] * self.vals[a * nc + pos as usize + b] * n[b];
            }
        }
        s
    }
}

pub struct NormalConstraints {
    dim: usize,
    first_dof: usize,
    rows: Vec<NodeRows>,
    /// Per contact node: the rows (indices into `rows`) with a column block of that node.
    near: Vec<Vec<u32>>,
    /// Per contact node: its own rows, if this rank owns it.
    own: Vec<Option<u32>>,
    /// `K`'s rows at the owned contact DOFs (other rows empty), for the forces.
    k_c: Matrix,
    k_c_du: Vector,
    /// The active set and normals the operator holds now.
    applied: (Vec<bool>, Vec<[f64; 3]>),
    /// Rows currently differing from the original.
    dirty: Vec<u32>,
}

impl NormalConstraints {
    /// Reads the rows next to the contact nodes from the step operator `k` (collective; one
    /// pass over this rank's rows, once per run).
    pub fn new(k: &Matrix, nodes: &ContactNodes) -> Result<NormalConstraints> {
        let dim = nodes.dim;
        let nc = nodes.len();
        let (lo, hi) = k.ownership_range();
        let di = dim as i32;
        let slot: HashMap<i32, u32> = (0..nc).map(|q| (nodes.dofs[q * dim].0, q as u32)).collect();
        let mut rows = Vec::new();
        for r0 in (lo..hi).step_by(dim) {
            let first = k.with_row(r0, |cols, vals| {
                cols.iter()
                    .any(|c| c % di == 0 && slot.contains_key(c))
                    .then(|| (cols.to_vec(), vals.to_vec()))
            })?;
            let Some((cols, mut vals)) = first else { continue };
            for c in 1..dim {
                let same = k.with_row(r0 + c, |cc, vv| {
                    vals.extend_from_slice(vv);
                    cc == &cols[..]
                })?;
                if !same {
                    return Err(Error::Solver(format!(
                        "contact: the step operator's rows {r0}..{} differ in their columns (the constraint needs node blocks)",
                        r0 + dim
                    )));
                }
            }
            let mut blocks = Vec::new();
            let mut contact = None;
            for (pos, c) in cols.iter().enumerate() {
                let Some(&q) = (c % di == 0).then(|| slot.get(c)).flatten() else { continue };
                let full = (1..dim).all(|j| cols.get(pos + j) == Some(&(c + j as i32)));
                if !full {
                    return Err(Error::Solver(format!(
                        "contact: row {r0} of the step operator lacks part of the block of contact node {} (gmsh tag)",
                        nodes.tags[q as usize]
                    )));
                }
                blocks.push((pos as u32, q));
                if *c == r0 as i32 {
                    contact = Some((q, pos as u32));
                }
            }
            rows.push(NodeRows { dof0: r0 as i32, cols, vals, blocks, contact });
        }
        let mut near = vec![Vec::new(); nc];
        let mut own = vec![None; nc];
        for (r, row) in rows.iter().enumerate() {
            for &(_, q) in &row.blocks {
                near[q as usize].push(r as u32);
            }
            if let Some((q, _)) = row.contact {
                own[q as usize] = Some(r as u32);
            }
        }
        // K_C: the owned contact nodes' rows, exactly preallocated.
        let n_local = hi - lo;
        let (mut d_nnz, mut o_nnz) = (vec![0i32; n_local], vec![0i32; n_local]);
        for row in rows.iter().filter(|r| r.contact.is_some()) {
            let inside = row.cols.iter().filter(|&&c| (lo..hi).contains(&(c as usize))).count();
            for c in 0..dim {
                let i = row.dof0 as usize - lo + c;
                d_nnz[i] = inside as i32;
                o_nnz[i] = (row.cols.len() - inside) as i32;
            }
        }
        let mut k_c = Matrix::new_aij(n_local, k.size().0, dim, &d_nnz, &o_nnz)?;
        for row in rows.iter().filter(|r| r.contact.is_some()) {
            let ids: Vec<i32> = (0..di).map(|c| row.dof0 + c).collect();
            k_c.set_values(&ids, &row.cols, &row.vals, false)?;
        }
        k_c.assemble()?;
        let k_c_du = k_c.create_vecs()?.0;
        Ok(NormalConstraints {
            dim,
            first_dof: lo,
            rows,
            near,
            own,
            k_c,
            k_c_du,
            applied: (vec![false; nc], vec![[0.0; 3]; nc]),
            dirty: Vec::new(),
        })
    }

    /// Makes `k` the constrained operator `K~` for the active set and normals (collective;
    /// every rank passes the same arguments). Returns whether `k` changed.
    pub fn impose(
        &mut self,
        k: &mut Matrix,
        active: &[bool],
        normals: &[[f64; 3]],
    ) -> Result<bool> {
        let (was, held) = &self.applied;
        let same = was == active && (0..active.len()).all(|q| !active[q] || held[q] == normals[q]);
        if same {
            return Ok(false);
        }
        let mut now: Vec<u32> = (0..active.len())
            .filter(|&q| active[q])
            .flat_map(|q| self.near[q].iter().copied())
            .collect();
        now.sort_unstable();
        now.dedup();
        let mut touched: Vec<u32> = now.iter().chain(&self.dirty).copied().collect();
        touched.sort_unstable();
        touched.dedup();
        let di = self.dim as i32;
        for &r in &touched {
            let row = &self.rows[r as usize];
            let ids: Vec<i32> = (0..di).map(|c| row.dof0 + c).collect();
            let vals = self.transformed(row, active, normals);
            k.set_values(&ids, &row.cols, &vals, false)?;
        }
        k.assemble()?;
        self.dirty = now;
        self.applied = (active.to_vec(), normals.to_vec());
        Ok(true)
    }

    /// One node's rows of `K~ = P K P + sum_q d_q N_q`.
    fn transformed(&self, row: &NodeRows, active: &[bool], normals: &[[f64; 3]]) -> Vec<f64> {
        let d = self.dim;
        let nc = row.cols.len();
        let mut v = row.vals.clone();
        // Right factor P: every active column block b becomes b (I - n n^T).
        for &(pos, q) in &row.blocks {
            if !active[q as usize] {
                continue;
            }
            let n = &normals[q as usize];
            for c in 0..d {
                let b = &mut v[c * nc + pos as usize..c * nc + pos as usize + d];
                let s: f64 = (0..d).map(|i| b[i] * n[i]).sum();
                for i in 0..d {
                    b[i] -= s * n[i];
                }
            }
        }
        // Left factor P and the normal diagonal, for an active node's own rows.
        if let Some((q, pos)) = row.contact {
            if active[q as usize] {
                let n = &normals[q as usize];
                for col in 0..nc {
                    let s: f64 = (0..d).map(|c| v[c * nc + col] * n[c]).sum();
                    for c in 0..d {
                        v[c * nc + col] -= s * n[c];
                    }
                }
                let dq = row.normal_stiffness(d, n);
                for a in 0..d {
                    for b in 0..d {
                        v[a * nc + pos as usize + b] += dq * n[a] * n[b];
                    }
                }
            }
        }
        v
    }

    /// The constrained right-hand side `b = P (rhs - K du_p) + sum_q d_q g_q n_q e_q`, with
    /// the gaps and normals `frames` of the contact nodes.
    pub fn rhs(
        &self,
        rhs: &Vector,
        active: &[bool],
        frames: &[(f64, [f64; 3])],
        b: &mut Vector,
    ) -> Result<()> {
        b.copy_from(rhs)?;
        let (d, lo) = (self.dim, self.first_dof);
        b.with_local_slice_mut(|x| {
            // - K du_p: du_p lives on the active nodes, so only rows next to them see it.
            for row in &self.rows {
                let nc = row.cols.len();
                let base = row.dof0 as usize - lo;
                for &(pos, q) in &row.blocks {
                    let (g, n) = frames[q as usize];
                    if !active[q as usize] || g == 0.0 {
                        continue;
                    }
                    for c in 0..d {
                        let kb = &row.vals[c * nc + pos as usize..c * nc + pos as usize + d];
                        x[base + c] -= g * (0..d).map(|i| kb[i] * n[i]).sum::<f64>();
                    }
                }
            }
            // P, and the prescribed normal part, on the active nodes this rank owns.
            for (q, r) in self.own.iter().enumerate() {
                let (Some(r), true) = (r, active[q]) else { continue };
                let row = &self.rows[*r as usize];
                let (g, n) = frames[q];
                let base = row.dof0 as usize - lo;
                let s: f64 = (0..d).map(|c| x[base + c] * n[c]).sum();
                let dq = row.normal_stiffness(d, &n);
                for c in 0..d {
                    x[base + c] += (dq * g - s) * n[c];
                }
            }
        })
    }

    /// The contact forces `lambda_q = n_q . (rhs - K du)_q / factor` of the active nodes
    /// (zero elsewhere), on every rank.
    pub fn forces(
        &mut self,
        nodes: &ContactNodes,
        rhs: &Vector,
        du: &Vector,
        active: &[bool],
        normals: &[[f64; 3]],
        factor: f64,
    ) -> Result<Vec<f64>> {
        self.k_c.mult(du, &mut self.k_c_du)?;
        let (d, lo) = (self.dim, self.first_dof);
        let mut local = vec![0.0; active.len()];
        rhs.with_local_slice(|f| {
            self.k_c_du.with_local_slice(|y| {
                for (q, r) in self.own.iter().enumerate() {
                    let (Some(r), true) = (r, active[q]) else { continue };
                    let base = self.rows[*r as usize].dof0 as usize - lo;
                    let n = normals[q];
                    local[q] =
                        (0..d).map(|c| n[c] * (f[base + c] - y[base + c])).sum::<f64>() / factor;
                }
            })
        })??;
        let mut global = vec![0.0; local.len()];
        nodes.world.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
        Ok(global)
    }

    /// Original rows kept next to the contact boundary (for the memory report).
    pub fn kept_values(&self) -> usize {
        self.rows.iter().map(|r| r.vals.len()).sum()
    }
}
