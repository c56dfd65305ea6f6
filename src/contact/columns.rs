//! The older active-set solver, kept for comparison (`-contact_solver columns`): a
//! Schur complement `S = B K^{-1} B^T` on the active contact DOFs. The columns
//! `K^{-1} e_{q,c}` are solved once per contact node and component, the first time the node is
//! active, and kept with their values at all contact DOFs (their "trace"). A step is then one
//! solve with `K`, a few active-set iterations on small dense systems (identical on every
//! rank), and one update `du = du0 - sum_q mu_q K^{-1} B^T e_q`.
//!
//! Exact and cheap for a few dozen contact nodes; the stored columns cost `dim` distributed
//! vectors per node ever active and the dense systems O(active^2), which is why
//! [`super::pdas`] is the default.

use super::active_set::ActiveSetLoop;
use super::interface::ContactSolver;
use super::nodes::ContactNodes;
use super::step::{StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::petsc::{Ksp, Vector};

struct Column {
    /// `K^{-1} e_{q,c}` for each component c.
    w: Vec<Vector>,
    /// Values of the columns at all contact DOFs: `trace[(c * n_contact + p) * dim + d]`.
    trace: Vec<f64>,
}

/// The Schur-complement active set for one body and one obstacle.
pub struct ColumnActiveSet<'w> {
    nodes: ContactNodes<'w>,
    columns: Vec<Option<Column>>,
    /// Factor of the force in the step equation (2 for the midpoint rule's du form).
    factor: f64,
    max_iterations: usize,
    /// Column solves done so far.
    column_solves: usize,
}

impl<'w> ColumnActiveSet<'w> {
    pub fn new(nodes: ContactNodes<'w>, factor: f64) -> ColumnActiveSet<'w> {
        let n = nodes.len();
        ColumnActiveSet {
            nodes,
            columns: (0..n).map(|_| None).collect(),
            factor,
            max_iterations: 50,
            column_solves: 0,
        }
    }

    fn ensure_column(&mut self, k: usize, ksp: &mut Ksp, template: &Vector) -> Result<()> {
        if self.columns[k].is_some() {
            return Ok(());
        }
        let d = self.nodes.dim;
        let mut w = Vec::with_capacity(d);
        let mut traces = Vec::with_capacity(d * self.nodes.dofs.len());
        for c in 0..d {
            let mut e = template.duplicate()?;
            e.zero()?;
            let (dof, owned) = self.nodes.dofs[k * d + c];
            if owned {
                e.set_values(&[dof], &[1.0], false)?;
            }
            e.assemble()?;
            let mut x = template.duplicate()?;
            x.zero()?;
            ksp.solve(&e, &mut x)?;
            self.column_solves += 1;
            traces.extend(self.nodes.trace(&x)?);
            w.push(x);
        }
        self.columns[k] = Some(Column { w, trace: traces });
        Ok(())
    }

    /// One step: solve `K du = rhs - factor sum_q lambda_q n_q e_q` with the active-set loop.
    fn solve_step(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { ksp, rhs, u, du, step, time, .. } = sys;
        let d = self.nodes.dim;
        let nc = self.nodes.len();
        let frames = self.nodes.frames(&self.nodes.trace(u)?, time);
        let info = ksp.solve(rhs, du)?;
        let d0 = self.nodes.trace(du)?;
        let mut active = self.nodes.active.clone();
        let mut lp = ActiveSetLoop::new(&active, self.max_iterations, step, time);
        let mut mu: Vec<f64>;
        let mut tr: Vec<f64>;
        loop {
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
                    "contact at step {step} (t = {}): the active-set system is singular ({m} active nodes)",
                    crate::console::time(time)
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
            let ndu = self.nodes.normal_parts(&frames, &tr);
            let gap: Vec<f64> = (0..nc).map(|p| frames[p].0 - ndu[p]).collect();
            let next = ActiveSetLoop::next_set(&active, &mu, &gap, self.nodes.gap_tol);
            match lp.advance(&active, next, &self.nodes.tags)? {
                None => break,
                Some(next) => active = next,
            }
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
        let lambda: Vec<f64> = mu.iter().map(|m| m / self.factor).collect();
        let out =
            self.nodes.step_contact(&frames, active.clone(), &lambda, &tr, lp.iterations, None);
        self.nodes.active = active;
        Ok((out, info.iterations))
    }
}

impl<'w> ContactSolver for ColumnActiveSet<'w> {
    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        self.solve_step(sys)
    }
    fn nodes(&self) -> &ContactNodes<'_> {
        &self.nodes
    }
    fn active_mut(&mut self) -> &mut Vec<bool> {
        &mut self.nodes.active
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
}
