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
//! With friction (docs/method.md, friction, Hueber, Stadler and Wohlmuth 2008) a node's rows are one of
//! three [`Condition`]s, each `L_q (rhs - K du)_q + D_q (y_q - du_q) + h_q = 0` with the
//! directions `C_q` of `y_q` prescribed (the columns along them move to the right-hand side):
//! - normal (frictionless, or Tresca/Coulomb slip's normal part): `C = n n^T`, `L = I - n n^T`,
//!   `D = d n n^T`, `y = g n`: the tangential residual vanishes;
//! - stick: `C = I`, `L = 0`, `D = d I`, `y = g n + w_t` (no slip relative to the obstacle,
//!   which moves by `w` in the step);
//! - slip along `z^` with slip bound `b`: `C = n n^T`, `L = z^ (z^ - mu n)^T + (1 - r) Q`,
//!   `D = d n n^T + r c_t factor Q`, `Q = I - n n^T - z^ z^T` (3D only), `r = b^0 / |z^0|`; the row along
//!   `z^` says `t . z^ = mu lambda` (Coulomb; Tresca: `t . z^ = s`, `h = -factor s z^`), the
//!   rows across it are the semi-smooth Newton step of `t = b z / |z|` in the slip direction.
//!   Coulomb's row couples the normal residual into the tangential one: the operator is then
//!   not symmetric (friction is not associative), so the step solver is GMRES.
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

/// What the constrained operator imposes at one contact node (see the module's doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    /// Not in contact: the node's rows are `K`'s.
    Free,
    /// `n . du = g`, no tangential force (frictionless contact).
    Normal { n: [f64; 3], g: f64 },
    /// `du = g n + w_t`: `w_t` the obstacle's tangential displacement over the step (zero
    /// against a resting obstacle).
    Stick { n: [f64; 3], g: f64, w_t: [f64; 3] },
    /// `n . du = g` and the tangential traction `b z^` (`b = mu lambda`, or given in `h`).
    Slip {
        n: [f64; 3],
        g: f64,
        w_t: [f64; 3],
        /// The slip direction `z^` (unit, in the tangent plane).
        dir: [f64; 3],
        /// Coulomb's coefficient (0 with a given bound).
        mu: f64,
        /// `-factor s z^` for Tresca's bound `s` (zero for Coulomb).
        h: [f64; 3],
        /// `b^0 / |z^0|` of the last iterate, in [0, 1]: the weight of the slip-direction
        /// rows' constraint part (3D).
        ratio: f64,
        /// `c_t factor`: the complementarity parameter on the operator's scale.
        c_f: f64,
    },
}

impl Condition {
    pub fn is_active(&self) -> bool {
        !matches!(self, Condition::Free)
    }

    /// The normal and gap of an active node.
    pub fn normal(&self) -> Option<([f64; 3], f64)> {
        match *self {
            Condition::Free => None,
            Condition::Normal { n, g }
            | Condition::Stick { n, g, .. }
            | Condition::Slip { n, g, .. } => Some((n, g)),
        }
    }

    /// The prescribed displacement `y_q` and the constrained directions `C_q` (`dim x dim`).
    fn target(&self, dim: usize) -> ([f64; 3], [[f64; 3]; 3]) {
        let nn = |n: &[f64; 3]| outer(n, n, dim);
        match *self {
            Condition::Free => ([0.0; 3], [[0.0; 3]; 3]),
            Condition::Normal { n, g } => (n.map(|x| g * x), nn(&n)),
            Condition::Stick { n, g, w_t } => {
                let mut c = [[0.0; 3]; 3];
                for (i, row) in c.iter_mut().enumerate().take(dim) {
                    row[i] = 1.0;
                }
                ([0, 1, 2].map(|i| g * n[i] + w_t[i]), c)
            }
            Condition::Slip { n, g, w_t, .. } => ([0, 1, 2].map(|i| g * n[i] + w_t[i]), nn(&n)),
        }
    }

    /// The left factor `L_q`, the added diagonal block `D_q` (with the node's stiffness scale
    /// `d`) and the constant `h_q` of a stick or slip node.
    fn rows(&self, dim: usize, d: f64) -> ([[f64; 3]; 3], [[f64; 3]; 3], [f64; 3]) {
        let mut l = [[0.0; 3]; 3];
        let mut dm = [[0.0; 3]; 3];
        match *self {
            Condition::Free | Condition::Normal { .. } => {
                unreachable!("the frictionless rows are built apart")
            }
            Condition::Stick { .. } => {
                for (i, row) in dm.iter_mut().enumerate().take(dim) {
                    row[i] = d;
                }
                (l, dm, [0.0; 3])
            }
            Condition::Slip { n, dir, mu, h, ratio, c_f, .. } => {
                for i in 0..dim {
                    for j in 0..dim {
                        let id = if i == j { 1.0 } else { 0.0 };
                        let q = id - n[i] * n[j] - dir[i] * dir[j];
                        l[i][j] = dir[i] * (dir[j] - mu * n[j]) + (1.0 - ratio) * q;
                        dm[i][j] = d * n[i] * n[j] + ratio * c_f * q;
                    }
                }
                (l, dm, h)
            }
        }
    }
}

/// What of a condition the operator depends on (not the gap or the obstacle's motion,
/// which enter the right-hand side only).
fn operator_part(c: &Condition) -> Condition {
    match *c {
        Condition::Free => Condition::Free,
        Condition::Normal { n, .. } => Condition::Normal { n, g: 0.0 },
        Condition::Stick { n, .. } => Condition::Stick { n, g: 0.0, w_t: [0.0; 3] },
        Condition::Slip { n, dir, mu, ratio, c_f, .. } => {
            Condition::Slip { n, g: 0.0, w_t: [0.0; 3], dir, mu, h: [0.0; 3], ratio, c_f }
        }
    }
}

/// `a b^T` on the first `dim` components.
fn outer(a: &[f64; 3], b: &[f64; 3], dim: usize) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..dim {
        for j in 0..dim {
            m[i][j] = a[i] * b[j];
        }
    }
    m
}

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
    /// The conditions the operator holds now (their operator parts, [`operator_part`]).
    applied: Vec<Condition>,
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
            applied: vec![Condition::Free; nc],
            dirty: Vec::new(),
        })
    }

    /// The step operator was replaced by a new unconstrained one of the same pattern (a
    /// finite-strain Newton iteration's tangent): read the kept rows and `K_C` again; the
    /// operator holds no condition now. Collective.
    pub fn refresh(&mut self, k: &Matrix) -> Result<()> {
        let di = self.dim as i32;
        for row in self.rows.iter_mut() {
            let mut vals = Vec::with_capacity(row.vals.len());
            for c in 0..di {
                let same = k.with_row((row.dof0 + c) as usize, |cc, vv| {
                    vals.extend_from_slice(vv);
                    cc == &row.cols[..]
                })?;
                if !same {
                    return Err(Error::Solver(format!(
                        "contact: row {} of the new step operator has other columns than the old one's",
                        row.dof0 + c
                    )));
                }
            }
            row.vals = vals;
        }
        for row in self.rows.iter().filter(|r| r.contact.is_some()) {
            let ids: Vec<i32> = (0..di).map(|c| row.dof0 + c).collect();
            self.k_c.set_values(&ids, &row.cols, &row.vals, false)?;
        }
        self.k_c.assemble()?;
        self.applied.iter_mut().for_each(|c| *c = Condition::Free);
        self.dirty.clear();
        Ok(())
    }

    /// Makes `k` the constrained operator `K~` for the nodes' conditions (collective; every
    /// rank passes the same conditions). Returns whether `k` changed.
    pub fn impose(&mut self, k: &mut Matrix, conds: &[Condition]) -> Result<bool> {
        let key: Vec<Condition> = conds.iter().map(operator_part).collect();
        if self.applied == key {
            return Ok(false);
        }
        let mut now: Vec<u32> = (0..conds.len())
            .filter(|&q| conds[q].is_active())
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
            let vals = self.transformed(row, conds);
            k.set_values(&ids, &row.cols, &vals, false)?;
        }
        k.assemble()?;
        self.dirty = now;
        self.applied = key;
        Ok(true)
    }

    /// One node's rows of `K~ = L K P + sum_q D_q` (the frictionless rows:
    /// `P K P + sum_q d_q N_q`).
    fn transformed(&self, row: &NodeRows, conds: &[Condition]) -> Vec<f64> {
        let d = self.dim;
        let nc = row.cols.len();
        let mut v = row.vals.clone();
        // Right factor P: every active column block b becomes b (I - n n^T), or 0 (stick).
        for &(pos, q) in &row.blocks {
            let cond = &conds[q as usize];
            let Some((n, _)) = cond.normal() else { continue };
            let stick = matches!(cond, Condition::Stick { .. });
            for c in 0..d {
                let b = &mut v[c * nc + pos as usize..c * nc + pos as usize + d];
                if stick {
                    b.iter_mut().for_each(|x| *x = 0.0);
                    continue;
                }
                let s: f64 = (0..d).map(|i| b[i] * n[i]).sum();
                for i in 0..d {
                    b[i] -= s * n[i];
                }
            }
        }
        // Left factor and the prescribed rows, for an active node's own rows.
        let Some((q, pos)) = row.contact else { return v };
        let cond = &conds[q as usize];
        match *cond {
            Condition::Free => {}
            Condition::Normal { n, .. } => {
                for col in 0..nc {
                    let s: f64 = (0..d).map(|c| v[c * nc + col] * n[c]).sum();
                    for c in 0..d {
                        v[c * nc + col] -= s * n[c];
                    }
                }
                let dq = row.normal_stiffness(d, &n);
                for a in 0..d {
                    for b in 0..d {
                        v[a * nc + pos as usize + b] += dq * n[a] * n[b];
                    }
                }
            }
            Condition::Stick { n, .. } | Condition::Slip { n, .. } => {
                let (l, dm, _) = cond.rows(d, row.normal_stiffness(d, &n));
                let old = v.clone();
                for col in 0..nc {
                    for a in 0..d {
                        v[a * nc + col] = (0..d).map(|c| l[a][c] * old[c * nc + col]).sum();
                    }
                }
                for a in 0..d {
                    for b in 0..d {
                        v[a * nc + pos as usize + b] += dm[a][b];
                    }
                }
            }
        }
        v
    }

    /// The constrained right-hand side `b = L (rhs - K du_p) + sum_q (D_q y_q + h_q)` for the
    /// nodes' conditions (`du_p`: the prescribed parts `C_q y_q`).
    pub fn rhs(&self, rhs: &Vector, conds: &[Condition], b: &mut Vector) -> Result<()> {
        b.copy_from(rhs)?;
        let (d, lo) = (self.dim, self.first_dof);
        b.with_local_slice_mut(|x| {
            // - K du_p: du_p lives on the active nodes, so only rows next to them see it.
            for row in &self.rows {
                let nc = row.cols.len();
                let base = row.dof0 as usize - lo;
                for &(pos, q) in &row.blocks {
                    let cond = &conds[q as usize];
                    match *cond {
                        Condition::Free => {}
                        Condition::Normal { n, g } | Condition::Slip { n, g, .. } => {
                            if g == 0.0 {
                                continue;
                            }
                            for c in 0..d {
                                let kb =
                                    &row.vals[c * nc + pos as usize..c * nc + pos as usize + d];
                                x[base + c] -= g * (0..d).map(|i| kb[i] * n[i]).sum::<f64>();
                            }
                        }
                        Condition::Stick { .. } => {
                            let (y, _) = cond.target(d);
                            for c in 0..d {
                                let kb =
                                    &row.vals[c * nc + pos as usize..c * nc + pos as usize + d];
                                x[base + c] -= (0..d).map(|i| kb[i] * y[i]).sum::<f64>();
                            }
                        }
                    }
                }
            }
            // L, and the prescribed rows, on the active nodes this rank owns.
            for (q, r) in self.own.iter().enumerate() {
                let Some(r) = r else { continue };
                let cond = &conds[q];
                let Some((n, g)) = cond.normal() else { continue };
                let row = &self.rows[*r as usize];
                let base = row.dof0 as usize - lo;
                let dq = row.normal_stiffness(d, &n);
                if let Condition::Normal { .. } = cond {
                    let s: f64 = (0..d).map(|c| x[base + c] * n[c]).sum();
                    for c in 0..d {
                        x[base + c] += (dq * g - s) * n[c];
                    }
                    continue;
                }
                let (l, dm, h) = cond.rows(d, dq);
                let (y, _) = cond.target(d);
                let old: Vec<f64> = (0..d).map(|c| x[base + c]).collect();
                for a in 0..d {
                    x[base + a] =
                        (0..d).map(|c| l[a][c] * old[c] + dm[a][c] * y[c]).sum::<f64>() + h[a];
                }
            }
        })
    }

    /// The residual `(rhs - K du)_q` of every active node (zero elsewhere), on every rank:
    /// `factor` times the force the node exerts on the obstacle (`lambda_q n_q` plus the
    /// tangential traction).
    pub fn residuals(
        &mut self,
        nodes: &ContactNodes,
        rhs: &Vector,
        du: &Vector,
        conds: &[Condition],
    ) -> Result<Vec<[f64; 3]>> {
        self.k_c.mult(du, &mut self.k_c_du)?;
        let (d, lo) = (self.dim, self.first_dof);
        let mut local = vec![0.0; conds.len() * 3];
        rhs.with_local_slice(|f| {
            self.k_c_du.with_local_slice(|y| {
                for (q, r) in self.own.iter().enumerate() {
                    let (Some(r), true) = (r, conds[q].is_active()) else { continue };
                    let base = self.rows[*r as usize].dof0 as usize - lo;
                    for c in 0..d {
                        local[q * 3 + c] = f[base + c] - y[base + c];
                    }
                }
            })
        })??;
        let mut global = vec![0.0; local.len()];
        nodes.world.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
        Ok(global.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
    }

    /// The contact forces `lambda_q = n_q . (rhs - K du)_q / factor` of the active nodes (zero
    /// elsewhere) from their residuals.
    pub fn normal_forces(
        residuals: &[[f64; 3]],
        conds: &[Condition],
        dim: usize,
        factor: f64,
    ) -> Vec<f64> {
        (0..conds.len())
            .map(|q| match conds[q].normal() {
                Some((n, _)) => (0..dim).map(|c| n[c] * residuals[q][c]).sum::<f64>() / factor,
                None => 0.0,
            })
            .collect()
    }

    /// Every contact node's stiffness scale `n^T K_qq n` along `normal(q)` (on every rank;
    /// collective), the `d_q` of the prescribed rows.
    pub fn normal_stiffness(&self, nodes: &ContactNodes, normals: &[[f64; 3]]) -> Vec<f64> {
        let mut local = vec![0.0; normals.len()];
        for (q, r) in self.own.iter().enumerate() {
            if let Some(r) = r {
                local[q] = self.rows[*r as usize].normal_stiffness(self.dim, &normals[q]);
            }
        }
        let mut global = vec![0.0; local.len()];
        nodes.world.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
        global
    }

    /// Original rows kept next to the contact boundary (for the memory report).
    pub fn kept_values(&self) -> usize {
        self.rows.iter().map(|r| r.vals.len()).sum()
    }
}

#[cfg(test)]
mod tests {
    //! The slip rows against the nonlinear slip condition they linearize (docs/method.md, friction).
    //!
    //! A slipping node's rows, `L r + D (y - du) + h` in its residual `r = (rhs - K du)_q =
    //! factor (lambda n + t)` and its increment `du`, are the semi-smooth Newton step at the
    //! last iterate `x0 = (r0, du0)` of
    //!
    //! ```text
    //! G(r, du) = d (g - n . du) n + factor (t - b z / |z|),
    //!     lambda = n . r / factor, t = (I - n n^T) r / factor, s = (I - n n^T) du - w_t,
    //!     z = t + c_t s, b = slip_bound(law, lambda, 0, c_t) (mu lambda, or Tresca's bound),
    //! ```
    //!
    //! with the direction `z^ = z0 / |z0|` and `ratio = b0 / |z0|` of that iterate (as `pdas`
    //! builds them): the rows must be `G`'s affine model there, `G(x0) + G'(x0) (x - x0)`.
    //! Their Jacobian `[L, -D]` is compared with central differences of `G`, their value at
    //! `x0` with `G(x0)`.

    use super::*;
    use crate::contact::friction::{slip_bound, FrictionLaw};

    /// xorshift64*: the same states on every run.
    struct Rng(u64);

    impl Rng {
        /// Uniform in [-1, 1).
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            let x = (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64;
            2.0 * x / (1u64 << 53) as f64 - 1.0
        }

        fn vector(&mut self, dim: usize) -> [f64; 3] {
            [0, 1, 2].map(|i| if i < dim { self.next() } else { 0.0 })
        }
    }

    fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    fn tangential(x: &[f64; 3], n: &[f64; 3]) -> [f64; 3] {
        let s = dot(x, n);
        [0, 1, 2].map(|i| x[i] - s * n[i])
    }

    /// One slipping node: its frame, the law's numbers and the last iterate `x0 = (r0, du0)`.
    struct Node {
        dim: usize,
        n: [f64; 3],
        g: f64,
        w_t: [f64; 3],
        d: f64,
        factor: f64,
        c_t: f64,
        law: FrictionLaw,
        x0: [f64; 6],
    }

    /// The scales of the variables: a residual component, a displacement component.
    const R_SCALE: f64 = 1e-2;
    const DU_SCALE: f64 = 1e-4;

    impl Node {
        fn split(x: &[f64; 6]) -> ([f64; 3], [f64; 3]) {
            ([x[0], x[1], x[2]], [x[3], x[4], x[5]])
        }

        /// `(t, z, b)` at `x`.
        fn law_at(&self, x: &[f64; 6]) -> ([f64; 3], [f64; 3], f64) {
            let (r, du) = Node::split(x);
            let lambda = dot(&r, &self.n) / self.factor;
            let t = tangential(&r, &self.n).map(|v| v / self.factor);
            let du_t = tangential(&du, &self.n);
            let z = [0, 1, 2].map(|i| t[i] + self.c_t * (du_t[i] - self.w_t[i]));
            // The bound as the active set takes it for a node in contact (gap 0).
            (t, z, slip_bound(self.law, lambda, 0.0, self.c_t))
        }

        /// The nonlinear condition `G(x)` (see the module's doc).
        fn condition(&self, x: &[f64; 6]) -> [f64; 3] {
            let (_, du) = Node::split(x);
            let (t, z, b) = self.law_at(x);
            let len = dot(&z, &z).sqrt();
            let gap = self.g - dot(&self.n, &du);
            [0, 1, 2].map(|i| self.d * gap * self.n[i] + self.factor * (t[i] - b * z[i] / len))
        }

        /// The slip condition the active set builds from the iterate `x0`.
        fn slip(&self) -> Condition {
            let (_, z, b) = self.law_at(&self.x0);
            let len = dot(&z, &z).sqrt();
            let (mu, h) = match self.law {
                FrictionLaw::Coulomb { mu } => (mu, [0.0; 3]),
                FrictionLaw::Tresca { bound } => (0.0, z.map(|v| -self.factor * bound * v / len)),
            };
            Condition::Slip {
                n: self.n,
                g: self.g,
                w_t: self.w_t,
                dir: z.map(|v| v / len),
                mu,
                h,
                ratio: (b / len).min(1.0),
                c_f: self.c_t * self.factor,
            }
        }

        /// The node's rows `L r + D (y - du) + h` at `x`, and their Jacobian `[L, -D]`
        /// (`dim x 2 dim`: the columns of `r`, then those of `du`).
        fn rows_at(&self, cond: &Condition, x: &[f64; 6]) -> ([f64; 3], Vec<Vec<f64>>) {
            let dim = self.dim;
            let (l, dm, h) = cond.rows(dim, self.d);
            let (y, _) = cond.target(dim);
            let (r, du) = Node::split(x);
            let value = [0, 1, 2].map(|a| {
                (0..dim).map(|c| l[a][c] * r[c] + dm[a][c] * (y[c] - du[c])).sum::<f64>() + h[a]
            });
            let jac = (0..dim)
                .map(|a| (0..dim).map(|c| l[a][c]).chain((0..dim).map(|c| -dm[a][c])).collect())
                .collect();
            (value, jac)
        }
    }

    /// Random slipping nodes: a unit normal, a tangential obstacle motion, an iterate with
    /// `lambda0 > 0` whose `|z0|` is beyond the bound `b0` (the slip set; `z = 0`, where `G`
    /// has no derivative, kept away), `c_t` as `pdas` scales it (0.01 d / factor).
    fn nodes(dim: usize, law: fn(&mut Rng) -> FrictionLaw, count: usize) -> Vec<Node> {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ (dim as u64));
        let mut out = Vec::new();
        while out.len() < count {
            let n = rng.vector(dim);
            let len = dot(&n, &n).sqrt();
            if len < 0.1 {
                continue;
            }
            let n = n.map(|v| v / len);
            let factor = 2.0 * (1.0 + rng.next().abs());
            let d = 1e3 * (1.0 + rng.next().abs());
            let c_t = 0.01 * d / factor * (0.5 + rng.next().abs());
            let lambda0 = R_SCALE * (0.2 + rng.next().abs());
            let t0 = tangential(&rng.vector(dim), &n).map(|v| R_SCALE * v);
            let r0 = [0, 1, 2].map(|i| factor * (lambda0 * n[i] + t0[i]));
            let du0 = rng.vector(dim).map(|v| DU_SCALE * v);
            let w_t = tangential(&rng.vector(dim), &n).map(|v| DU_SCALE * v);
            let g = DU_SCALE * rng.next();
            let law = law(&mut rng);
            let x0 = [r0[0], r0[1], r0[2], du0[0], du0[1], du0[2]];
            let node = Node { dim, n, g, w_t, d, factor, c_t, law, x0 };
            let (_, z, b) = node.law_at(&node.x0);
            if b > 0.0 && dot(&z, &z).sqrt() > 1.05 * b {
                out.push(node);
            }
        }
        out
    }

    fn coulomb(rng: &mut Rng) -> FrictionLaw {
        FrictionLaw::Coulomb { mu: 0.1 + 0.9 * rng.next().abs() }
    }

    fn tresca(rng: &mut Rng) -> FrictionLaw {
        FrictionLaw::Tresca { bound: R_SCALE * (0.1 + rng.next().abs()) }
    }

    /// The largest difference between the rows' Jacobian and central differences of the
    /// condition at `x0`, relative to the largest entry of its block (`L`, the columns of `r`;
    /// `D`, those of `du`: three orders of magnitude apart); and the rows' value at `x0`
    /// against `G(x0)`, relative to the condition's terms.
    fn mismatch(node: &Node) -> (f64, f64) {
        let dim = node.dim;
        let cond = node.slip();
        let (value, jac) = node.rows_at(&cond, &node.x0);
        let g0 = node.condition(&node.x0);
        let terms = node.d * DU_SCALE + node.factor * R_SCALE;
        let value_error = (0..dim).map(|a| (value[a] - g0[a]).abs()).fold(0.0, f64::max);
        let mut error = 0.0f64;
        for block in 0..2 {
            let cols = block * dim..(block + 1) * dim;
            let scale = (0..dim)
                .flat_map(|a| cols.clone().map(move |j| (a, j)))
                .fold(0.0f64, |m, (a, j)| m.max(jac[a][j].abs()));
            for j in cols {
                // The variable (r's component j, or du's j - dim) moved by 1e-5 of its scale:
                // the truncation error step^2 / 6 G''' is then about 1e-10 of the derivative,
                // the round-off eps |G| / step about as small.
                let (col, step) = match block {
                    0 => (j, 1e-5 * node.factor * R_SCALE),
                    _ => (3 + j - dim, 1e-5 * DU_SCALE),
                };
                let (mut xp, mut xm) = (node.x0, node.x0);
                xp[col] += step;
                xm[col] -= step;
                let (gp, gm) = (node.condition(&xp), node.condition(&xm));
                for a in 0..dim {
                    let fd = (gp[a] - gm[a]) / (2.0 * step);
                    error = error.max((fd - jac[a][j]).abs() / scale);
                }
            }
        }
        (error, value_error / terms)
    }

    #[test]
    fn the_slip_rows_are_the_derivative_of_the_slip_condition() {
        let laws: [(&str, fn(&mut Rng) -> FrictionLaw); 2] =
            [("Coulomb", coulomb), ("Tresca", tresca)];
        for dim in [2, 3] {
            for (name, law) in laws {
                let mut worst = (0.0f64, 0.0f64);
                for (k, node) in nodes(dim, law, 50).iter().enumerate() {
                    let (jac, value) = mismatch(node);
                    // Central differences with the steps above: 1e-6 leaves four orders of
                    // magnitude for their error; the value is a few roundings.
                    assert!(
                        jac < 1e-6,
                        "{dim}D {name}, state {k}: the slip rows' Jacobian is off by {jac:e} (relative)"
                    );
                    assert!(
                        value < 1e-12,
                        "{dim}D {name}, state {k}: the slip rows at their own iterate are off the condition by {value:e}"
                    );
                    worst = (worst.0.max(jac), worst.1.max(value));
                }
                eprintln!(
                    "{dim}D {name}: Jacobian against central differences {:.1e}, value at the iterate {:.1e}",
                    worst.0, worst.1
                );
            }
        }
    }
}
