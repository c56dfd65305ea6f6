//! Frictionless contact with a rigid obstacle, resolved by a primal-dual active set inside
//! each time step (METHOD.md section 5; no SNES).
//!
//! Per contact node `q`: normal `n_q` (unit, from the body towards the obstacle), gap
//! `g_q(u) = g^n_q - n_q . (u_q - u^n_q)` linearized at the start of the step (exact for a
//! plane), contact force `lambda_q >= 0`, and complementarity `g_q lambda_q = 0` at `t_{n+1}`.
//! The force enters the midpoint equation: `K du = rhs - 2 sum_q lambda_q n_q e_q`.
//!
//! Speed by design: `K` is constant, so the constrained solve is done with a Schur complement
//! on the active contact DOFs, `S = B K^{-1} B^T`. The columns `K^{-1} e_{q,c}` are solved once
//! per contact node, the first time the node is active, and kept with their values at all
//! contact DOFs (their "trace"). A step is then one solve with `K` (as without contact), a few
//! active-set iterations on small dense systems (identical on every rank), and one update
//! `du = du0 - sum_q mu_q K^{-1} B^T e_q`. The preconditioner is never rebuilt.

pub mod history;
pub mod metrics;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Ksp, Vector};
use crate::scene;

/// The rigid obstacle.
#[derive(Debug, Clone)]
pub enum Obstacle {
    /// The half-space `(y - point) . normal >= 0` is free; `normal` points into it (towards the body).
    Plane { point: [f64; 3], normal: [f64; 3] },
    /// A rigid ball (disc in 2D); the body stays outside it.
    Sphere { center: [f64; 3], radius: f64 },
}

fn pad(v: &[f64]) -> [f64; 3] {
    let mut a = [0.0; 3];
    a[..v.len().min(3)].copy_from_slice(&v[..v.len().min(3)]);
    a
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

impl Obstacle {
    pub fn from_scene(o: &scene::Obstacle) -> Obstacle {
        match o {
            scene::Obstacle::Plane { point, normal } => {
                Obstacle::Plane { point: pad(point), normal: pad(normal) }
            }
            scene::Obstacle::Sphere { center, radius } => {
                Obstacle::Sphere { center: pad(center), radius: *radius }
            }
        }
    }

    /// Gap and unit normal (pointing from the body towards the obstacle) at position `y`.
    pub fn gap_normal(&self, y: [f64; 3]) -> (f64, [f64; 3]) {
        match self {
            Obstacle::Plane { point, normal } => {
                let d = [y[0] - point[0], y[1] - point[1], y[2] - point[2]];
                (dot(d, *normal), [-normal[0], -normal[1], -normal[2]])
            }
            Obstacle::Sphere { center, radius } => {
                let d = [y[0] - center[0], y[1] - center[1], y[2] - center[2]];
                let r = dot(d, d).sqrt();
                if r == 0.0 {
                    return (-radius, [0.0, -1.0, 0.0]);
                }
                (r - radius, [-d[0] / r, -d[1] / r, -d[2] / r])
            }
        }
    }
}

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
        let elems = crate::mesh::topology::boundary_group(mesh, group)?;
        let mut nodes: Vec<usize> = elems.iter().flat_map(|e| e.nodes().iter().copied()).collect();
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
        Ok(ContactBoundary { group: group.to_string(), nodes, weights })
    }
}

/// One step on the contact boundary, per contact node in the order of the boundary's nodes:
/// the one row type that the solver returns, the history keeps, the file stores (with the
/// pressure `force / weight` beside it) and `post` reads back.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactRow {
    /// Midpoint contact force `lambda_q` (of the unscaled equation).
    pub force: Vec<f64>,
    /// Gap at `t_{n+1}` (NaN before the first step).
    pub gap: Vec<f64>,
    pub active: Vec<bool>,
    /// Active-set iterations of the step.
    pub iterations: usize,
}

impl ContactRow {
    /// Pressure `lambda_q / D_qq` with the boundary weights `D_qq`.
    pub fn pressure(&self, weights: &[f64]) -> Vec<f64> {
        self.force.iter().zip(weights).map(|(f, w)| f / w).collect()
    }
}

/// A contact solver inside the time step: it gets the step's right-hand side and the state at
/// `t_n`, solves `K du = rhs - factor B^T lambda` with the contact conditions at `t_{n+1}`
/// (`factor` comes from the integrator), and reports the contact forces and per-node data.
/// The rigid-obstacle active set is the first implementation.
pub trait ContactSolver {
    /// `u` is `u^n`; `du` holds the previous increment (initial guess) and gets the result.
    /// Returns the step's contact data and the KSP iterations of its solves.
    fn solve(
        &mut self,
        ksp: &mut Ksp,
        rhs: &Vector,
        u: &Vector,
        du: &mut Vector,
        step: usize,
        time: f64,
    ) -> Result<(StepContact, usize)>;
    /// The contact boundary (nodes, weights, group).
    fn boundary(&self) -> &ContactBoundary;
    /// The active set after the last step.
    fn active(&self) -> &[bool];
    /// Continue from a checkpoint's active set.
    fn set_active(&mut self, active: Vec<bool>);
    /// Contact nodes (mesh node indices) that penetrate the obstacle at displacement `u`.
    fn penetrating(&self, u: &Vector) -> Result<Vec<usize>>;
    /// Index (among the contact nodes) of the node closest to the obstacle at t = 0.
    fn lowest(&self) -> usize;
    /// Solves with the step operator beyond the one per step (e.g. Schur-complement columns).
    fn extra_solves(&self) -> usize;
    fn n_nodes(&self) -> usize {
        self.boundary().nodes.len()
    }
}

/// What the contact solver found in one step (all per contact node, same on every rank).
#[derive(Debug, Clone, Default)]
pub struct StepContact {
    pub row: ContactRow,
    pub normals: Vec<[f64; 3]>,
    /// Work of the contact forces in this step, `-sum_q lambda_q n_q . du_q` (<= 0).
    pub work: f64,
    /// `sum_q lambda_q n_q` (the force the obstacle takes; the body gets its negative).
    pub resultant: [f64; 3],
}

struct Column {
    /// `K^{-1} e_{q,c}` for each component c.
    w: Vec<Vector>,
    /// Values of the columns at all contact DOFs: `trace[(c * n_contact + p) * dim + d]`.
    trace: Vec<f64>,
}

/// The primal-dual active-set solver for one body and one obstacle.
pub struct ActiveSet<'w> {
    world: &'w SimpleCommunicator,
    pub boundary: ContactBoundary,
    pub obstacle: Obstacle,
    /// Reference position and gmsh tag of each contact node (the solver needs no more of the
    /// mesh).
    coords: Vec<[f64; 3]>,
    tags: Vec<u64>,
    dim: usize,
    /// Global DOF of (contact node k, component c), and whether this rank owns it.
    dofs: Vec<(i32, bool)>,
    first_dof: usize,
    columns: Vec<Option<Column>>,
    /// The active set of the last step (the next step's first guess).
    pub active: Vec<bool>,
    /// Factor of the force in the step equation (2 for the midpoint rule's du form).
    factor: f64,
    /// Gap tolerance: penetration below this counts as contact (a fraction of the mesh scale).
    gap_tol: f64,
    pub max_iterations: usize,
    /// Column solves done so far (for the benchmark).
    pub column_solves: usize,
}

impl<'w> ActiveSet<'w> {
    pub fn new(
        world: &'w SimpleCommunicator,
        mesh: &Mesh,
        part: &Partition,
        boundary: ContactBoundary,
        obstacle: Obstacle,
        factor: f64,
    ) -> ActiveSet<'w> {
        let dim = part.dim;
        let mut dofs = Vec::with_capacity(boundary.nodes.len() * dim);
        for &v in &boundary.nodes {
            for c in 0..dim {
                dofs.push((part.dof(v, c) as i32, part.owns(v)));
            }
        }
        // Mesh scale: the bounding box diagonal.
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for x in &mesh.coords {
            for i in 0..3 {
                lo[i] = lo[i].min(x[i]);
                hi[i] = hi[i].max(x[i]);
            }
        }
        let diag = (0..3).map(|i| (hi[i] - lo[i]).powi(2)).sum::<f64>().sqrt();
        let n = boundary.nodes.len();
        ActiveSet {
            world,
            coords: boundary.nodes.iter().map(|&v| mesh.coords[v]).collect(),
            tags: boundary.nodes.iter().map(|&v| mesh.node_tags[v]).collect(),
            boundary,
            obstacle,
            dim,
            dofs,
            first_dof: part.first_dof(),
            columns: (0..n).map(|_| None).collect(),
            active: vec![false; n],
            factor,
            gap_tol: 1e-12 * diag,
            max_iterations: 50,
            column_solves: 0,
        }
    }

    /// Values of a distributed vector at all contact DOFs, on every rank (owners contribute,
    /// a sum over ranks assembles them: each entry has exactly one owner, so the sum is exact).
    pub fn trace(&self, x: &Vector) -> Result<Vec<f64>> {
        let mut local = vec![0.0; self.dofs.len()];
        let lo = self.first_dof;
        x.with_local_slice(|s| {
            for (i, &(dof, owned)) in self.dofs.iter().enumerate() {
                if owned {
                    local[i] = s[dof as usize - lo];
                }
            }
        })?;
        let mut global = vec![0.0; local.len()];
        self.world.all_reduce_into(&local[..], &mut global[..], SystemOperation::sum());
        Ok(global)
    }

    /// Gaps and normals of all contact nodes at displacement `u` (trace given).
    pub fn frames(&self, u_trace: &[f64]) -> Vec<(f64, [f64; 3])> {
        let d = self.dim;
        self.coords
            .iter()
            .enumerate()
            .map(|(k, &x)| {
                let mut y = x;
                for c in 0..d {
                    y[c] += u_trace[k * d + c];
                }
                self.obstacle.gap_normal(y)
            })
            .collect()
    }

    /// Contact nodes that penetrate the obstacle at displacement `u` (beyond the tolerance).
    fn penetrating_nodes(&self, u: &Vector) -> Result<Vec<usize>> {
        let tr = self.trace(u)?;
        Ok(self
            .frames(&tr)
            .iter()
            .enumerate()
            .filter(|(_, (g, _))| *g < -self.gap_tol)
            .map(|(k, _)| self.boundary.nodes[k])
            .collect())
    }

    fn ensure_column(&mut self, k: usize, ksp: &mut Ksp, template: &Vector) -> Result<()> {
        if self.columns[k].is_some() {
            return Ok(());
        }
        let d = self.dim;
        let mut w = Vec::with_capacity(d);
        let mut traces = Vec::with_capacity(d * self.dofs.len());
        for c in 0..d {
            let mut e = template.duplicate()?;
            e.zero()?;
            let (dof, owned) = self.dofs[k * d + c];
            if owned {
                e.set_values(&[dof], &[1.0], false)?;
            }
            e.assemble()?;
            let mut x = template.duplicate()?;
            x.zero()?;
            ksp.solve(&e, &mut x)?;
            self.column_solves += 1;
            traces.extend(self.trace(&x)?);
            w.push(x);
        }
        self.columns[k] = Some(Column { w, trace: traces });
        Ok(())
    }

    /// One step: solve `K du = rhs - factor sum_q lambda_q n_q e_q` with the active-set loop.
    /// `u` is `u^n`; `du` holds the previous increment (initial guess) and gets the result.
    fn solve_step(
        &mut self,
        ksp: &mut Ksp,
        rhs: &Vector,
        u: &Vector,
        du: &mut Vector,
        step: usize,
        time: f64,
    ) -> Result<(StepContact, usize)> {
        let d = self.dim;
        let nc = self.n_nodes();
        let frames = self.frames(&self.trace(u)?);
        let info = ksp.solve(rhs, du)?;
        let d0 = self.trace(du)?;
        let mut active = self.active.clone();
        let mut history: Vec<Vec<bool>> = vec![active.clone()];
        let mut mu: Vec<f64>;
        let mut tr: Vec<f64>;
        let mut iterations = 0;
        loop {
            iterations += 1;
            let idx: Vec<usize> = (0..nc).filter(|&k| active[k]).collect();
            for &k in &idx {
                self.ensure_column(k, ksp, rhs)?;
            }
            // Column of the active node q as seen at all contact DOFs: sum_c n_qc trace_q[c].
            let col_at = |q: usize, p: usize, dd: usize| -> f64 {
                let col = self.columns[q].as_ref().expect("column");
                (0..d).map(|c| frames[q].1[c] * col.trace[(c * nc + p) * d + dd]).sum()
            };
            let m = idx.len();
            let mut s = vec![0.0; m * m];
            let mut b = vec![0.0; m];
            for (i, &p) in idx.iter().enumerate() {
                let np = frames[p].1;
                b[i] = (0..d).map(|dd| np[dd] * d0[p * d + dd]).sum::<f64>() - frames[p].0;
                for (j, &q) in idx.iter().enumerate() {
                    s[i * m + j] = (0..d).map(|dd| np[dd] * col_at(q, p, dd)).sum();
                }
            }
            let sol = solve_spd(&mut s, &mut b, m).ok_or_else(|| {
                Error::Solver(format!(
                    "contact at step {step} (t = {time:e}): the active-set system is singular ({m} active nodes)"
                ))
            })?;
            mu = vec![0.0; nc];
            for (i, &q) in idx.iter().enumerate() {
                mu[q] = sol[i];
            }
            tr = d0.clone();
            for &q in &idx {
                for p in 0..nc {
                    for dd in 0..d {
                        tr[p * d + dd] -= mu[q] * col_at(q, p, dd);
                    }
                }
            }
            // Active-set update: lambda_q - c g_q > 0, with lambda = 0 off the set and g = 0 on it.
            let lam_scale = mu.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
            let mut next = vec![false; nc];
            for p in 0..nc {
                let np = frames[p].1;
                let gap = frames[p].0 - (0..d).map(|dd| np[dd] * tr[p * d + dd]).sum::<f64>();
                next[p] = if active[p] { mu[p] > -1e-12 * lam_scale } else { gap < -self.gap_tol };
            }
            if next == active {
                break;
            }
            if history.contains(&next) {
                let flips: Vec<String> = (0..nc)
                    .filter(|&k| next[k] != active[k])
                    .map(|k| self.tags[k].to_string())
                    .collect();
                return Err(Error::Solver(format!(
                    "contact at step {step} (t = {time:e}): the active set cycles; gmsh nodes {} flip",
                    flips.join(", ")
                )));
            }
            if iterations >= self.max_iterations {
                return Err(Error::Solver(format!(
                    "contact at step {step} (t = {time:e}): the active set did not settle in {} iterations",
                    self.max_iterations
                )));
            }
            history.push(next.clone());
            active = next;
        }
        // du = du0 - sum_q mu_q sum_c n_qc K^{-1} e_{q,c}
        for q in (0..nc).filter(|&k| active[k]) {
            let col = self.columns[q].as_ref().expect("column");
            for c in 0..d {
                let a = mu[q] * frames[q].1[c];
                if a != 0.0 {
                    du.axpy(-a, &col.w[c])?;
                }
            }
        }
        let mut out = StepContact {
            row: ContactRow {
                force: vec![0.0; nc],
                gap: vec![0.0; nc],
                active: active.clone(),
                iterations,
            },
            normals: frames.iter().map(|f| f.1).collect(),
            work: 0.0,
            resultant: [0.0; 3],
        };
        for p in 0..nc {
            let np = frames[p].1;
            let ndu: f64 = (0..d).map(|dd| np[dd] * tr[p * d + dd]).sum();
            out.row.gap[p] = frames[p].0 - ndu;
            if active[p] {
                let lam = mu[p] / self.factor;
                out.row.force[p] = lam;
                out.work -= lam * ndu;
                for c in 0..d {
                    out.resultant[c] += lam * np[c];
                }
            }
        }
        self.active = active;
        Ok((out, info.iterations))
    }
}

impl ContactSolver for ActiveSet<'_> {
    fn solve(
        &mut self,
        ksp: &mut Ksp,
        rhs: &Vector,
        u: &Vector,
        du: &mut Vector,
        step: usize,
        time: f64,
    ) -> Result<(StepContact, usize)> {
        self.solve_step(ksp, rhs, u, du, step, time)
    }
    fn boundary(&self) -> &ContactBoundary {
        &self.boundary
    }
    fn active(&self) -> &[bool] {
        &self.active
    }
    fn set_active(&mut self, active: Vec<bool>) {
        self.active = active;
    }
    fn penetrating(&self, u: &Vector) -> Result<Vec<usize>> {
        self.penetrating_nodes(u)
    }
    fn lowest(&self) -> usize {
        let gap = |k: usize| self.obstacle.gap_normal(self.coords[k]).0;
        (0..self.coords.len())
            .min_by(|&a, &b| {
                gap(a).partial_cmp(&gap(b)).unwrap_or(std::cmp::Ordering::Equal).then(a.cmp(&b))
            })
            .unwrap_or(0)
    }
    fn extra_solves(&self) -> usize {
        self.column_solves
    }
}

/// Solve the small dense SPD system `S x = b` (Cholesky, in place); None if not positive
/// definite. Every rank solves the same system with the same data, so all agree.
fn solve_spd(s: &mut [f64], b: &mut [f64], m: usize) -> Option<Vec<f64>> {
    for j in 0..m {
        let mut dsum = s[j * m + j];
        for k in 0..j {
            dsum -= s[j * m + k] * s[j * m + k];
        }
        if dsum <= 0.0 || !dsum.is_finite() {
            return None;
        }
        let djj = dsum.sqrt();
        s[j * m + j] = djj;
        for i in j + 1..m {
            let mut v = s[i * m + j];
            for k in 0..j {
                v -= s[i * m + k] * s[j * m + k];
            }
            s[i * m + j] = v / djj;
        }
    }
    for i in 0..m {
        let mut v = b[i];
        for k in 0..i {
            v -= s[i * m + k] * b[k];
        }
        b[i] = v / s[i * m + i];
    }
    for i in (0..m).rev() {
        let mut v = b[i];
        for k in i + 1..m {
            v -= s[k * m + i] * b[k];
        }
        b[i] = v / s[i * m + i];
    }
    Some(b.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_solves_spd_and_refuses_indefinite() {
        let mut s = vec![4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let a = s.clone();
        let mut b = vec![1.0, 2.0, 3.0];
        let x = solve_spd(&mut s, &mut b, 3).unwrap();
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a[i * 3 + j] * x[j]).sum();
            assert!((r - [1.0, 2.0, 3.0][i]).abs() < 1e-14);
        }
        let mut s = vec![1.0, 2.0, 2.0, 1.0];
        assert!(solve_spd(&mut s, &mut [1.0, 1.0], 2).is_none());
    }

    #[test]
    fn plane_and_sphere_gaps() {
        let plane = Obstacle::Plane { point: [0.0, 1.0, 0.0], normal: [0.0, 1.0, 0.0] };
        let (g, n) = plane.gap_normal([3.0, 1.5, 0.0]);
        assert!((g - 0.5).abs() < 1e-15 && n == [0.0, -1.0, 0.0]);
        let ball = Obstacle::Sphere { center: [0.0, 0.0, 0.0], radius: 1.0 };
        let (g, n) = ball.gap_normal([0.0, 3.0, 0.0]);
        assert!((g - 2.0).abs() < 1e-15 && (n[1] + 1.0).abs() < 1e-15);
    }
}
