//! The step's conjugate gradients, written out around PETSc's `MatMult` and `PCApply` so that
//! the step keeps what the solve computes:
//!
//! - `K x` of the solution, summed as `K x_0 + sum alpha_i K p_i` from the products CG makes
//!   anyway: the next step's initial residual `b - K x_0` then needs no product (the guess is
//!   the last increment, or its extrapolation from the last two with their known products),
//!   and the integrator updates `A u` and `M v` from it instead of recomputing them;
//! - Jacobi applied inside the vector passes (three passes over memory an iteration instead of
//!   PETSc's six vector operations); any other preconditioner through `PCApply`.
//!
//! Stopping test, in the step's own terms. With `r = b - K x`, the midpoint rule's energy
//! identity holds up to `-1/2 x.r` (docs/method.md, the midpoint rule: `E^{n+1} - E^n - W = 1/2 du.(K du - b)`),
//! and the error of `x` in the energy norm is `|e|_K^2 = r.K^{-1}r ~ r.Br`. So CG stops when
//!
//! ```text
//!   r.Br <= rtol^2 x.Kx     (the increment's error in the energy norm, relative)
//!   |x.r| <= 2 energy_tol E (the step's energy error, relative to the energy scale E)
//! ```
//! `x.Kx = x.b - x.r` and `x.r` are sums in the pass that updates `x` and `r`: no extra work.
//! CG keeps `p_j.r_k = 0` (j < k), so `x_k.r_k = x_0.r_k`: a solve from zero keeps the energy
//! to round-off whatever its tolerance, a predicted guess to `x_0.r_k`. Without prescribed
//! non-zero increments the solution is instead scaled onto its own direction
//! ([`StepCg::set_scale`]), which makes `x.r` zero and the second test moot.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::layer::LayerBlock;
use crate::error::{Error, Result};
use crate::petsc::{Ksp, Matrix, Vector};

/// The first guess of a step's solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Predictor {
    /// Zero: the energy error of the solve is round-off whatever the tolerance.
    Zero,
    /// The last increment (what PETSc's nonzero initial guess gave).
    Last,
    /// `2 du^n - du^{n-1}`: exact for a motion whose increments change linearly in time.
    Extrapolate,
}

impl Predictor {
    pub fn parse(s: &str) -> Option<Predictor> {
        match s {
            "zero" => Some(Predictor::Zero),
            "last" => Some(Predictor::Last),
            "extrapolate" => Some(Predictor::Extrapolate),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Predictor::Zero => "zero",
            Predictor::Last => "last",
            Predictor::Extrapolate => "extrapolate",
        }
    }
}

/// What one solve did.
#[derive(Debug, Clone, Copy, Default)]
pub struct CgInfo {
    pub iterations: usize,
    /// Products with `K` (the iterations, plus one when `K x_0` was not known).
    pub products: usize,
    /// `sqrt(r.Br / x.Kx)` at the end.
    pub relative_error: f64,
    /// `-1/2 x.r`: the step's energy error from the solve.
    pub energy_error: f64,
}

enum Precond {
    /// The inverse of `K`'s diagonal, applied inside the passes; with the mass-free layer's
    /// block (`time::layer`) zero on its rows, which the block's factor takes instead.
    Jacobi(Vec<f64>, Option<Box<LayerBlock>>),
    /// PETSc's preconditioner of the step's KSP (set up), and `z = B r`.
    Petsc(Vector),
}

/// Preconditioned CG for the step operator, keeping `K x` of its solutions.
pub struct StepCg {
    rtol: f64,
    energy_tol: f64,
    max_it: usize,
    predictor: Predictor,
    pc: Precond,
    r: Vector,
    p: Vector,
    q: Vector,
    /// `K x` of the last solution, and the solution and its product before it.
    kx: Vector,
    x_prev: Vector,
    kx_prev: Vector,
    /// How many of the last solutions have their products in `kx`, `kx_prev` (0, 1 or 2).
    known: usize,
    /// Scale the solution onto its own direction ([`StepCg::set_scale`]).
    scale: bool,
    /// `K` changed since the layer's block was factored ([`StepCg::forget`]).
    stale_layer: bool,
    /// The layer block's rows over all ranks and its solver (the same on every rank).
    layer_report: Option<(usize, String)>,
}

/// The layer's block applied to `r` and added onto `p` (whose layer rows Jacobi left zero);
/// this rank's `r_C . z_C`.
fn with_layer(layer: &mut LayerBlock, r: &Vector, p: &mut Vector) -> Result<f64> {
    let rz = r.with_local_slice(|r| layer.apply(r))??;
    p.with_local_slice_mut(|p| layer.add_last(p))??;
    Ok(rz)
}

fn sum_over_ranks<const N: usize>(local: [f64; N]) -> [f64; N] {
    let mut all = [0.0; N];
    SimpleCommunicator::world().all_reduce_into(&local[..], &mut all[..], SystemOperation::sum());
    all
}

/// This rank's `[r.z, x.b, x.r]`.
fn local_sums(r: &Vector, z: &Vector, x: &Vector, b: &Vector) -> Result<[f64; 3]> {
    Vector::with_slices([r, z, x, b], [], |[r, z, x, b], []| {
        let (mut rz, mut xb, mut xr) = (0.0, 0.0, 0.0);
        for i in 0..r.len() {
            rz += r[i] * z[i];
            xb += x[i] * b[i];
            xr += x[i] * r[i];
        }
        [rz, xb, xr]
    })
}

impl StepCg {
    /// For the operator `k` whose KSP `ksp` is set up: Jacobi inside the passes when the
    /// KSP's preconditioner is `jacobi`, else PETSc's through `PCApply`. With Jacobi, the
    /// `massless` rows (local indices, sorted; the mass-free layer's) get their block's
    /// factor instead (`time::layer`) if `reuse.layer`, unless empty on every rank
    /// (`reuse.layer_local`, by default in 3D: each rank's own block, [`LayerBlock::new`]
    /// with `local`). The energy tolerance and the predictor are `reuse`'s. Collective.
    pub fn new(
        k: &Matrix,
        ksp: &Ksp,
        rtol: f64,
        reuse: &super::operator::Reuse,
        massless: Vec<usize>,
    ) -> Result<StepCg> {
        let (energy_tol, predictor) = (reuse.energy_rtol, reuse.predictor);
        let (use_layer, local) = (reuse.layer, reuse.layer_local_for(k.block_size()?));
        let (r, _) = k.create_vecs()?;
        let mut report = None;
        let pc = if ksp.pc_type()? == "jacobi" {
            let mut d = r.duplicate()?;
            k.get_diagonal(&mut d)?;
            // PETSc's Jacobi takes 1 for a zero diagonal entry; K's are positive.
            let mut d: Vec<f64> = d.with_local_slice(|d| {
                d.iter().map(|&x| if x != 0.0 { 1.0 / x } else { 1.0 }).collect()
            })?;
            if use_layer {
                for &i in &massless {
                    d[i] = 0.0;
                }
            }
            let own = massless.len();
            let layer = if use_layer {
                LayerBlock::new(k, massless, Some(&d), k.block_size()?, local)?
            } else {
                None
            };
            // The same on every rank, also one without layer rows of its own.
            if use_layer {
                let r = LayerBlock::report(layer.as_ref(), own, local)?;
                report = (r.0 > 0).then_some(r);
            }
            Precond::Jacobi(d, layer.map(Box::new))
        } else {
            Precond::Petsc(r.duplicate()?)
        };
        Ok(StepCg {
            rtol,
            energy_tol,
            max_it: ksp.max_it()?,
            predictor,
            pc,
            p: r.duplicate()?,
            q: r.duplicate()?,
            kx: r.duplicate()?,
            x_prev: r.duplicate()?,
            kx_prev: r.duplicate()?,
            r,
            known: 0,
            scale: false,
            stale_layer: false,
            layer_report: report,
        })
    }

    /// Rows of the mass-free layer's block over all ranks (0: plain Jacobi or PETSc's
    /// preconditioner).
    pub fn layer_rows(&self) -> usize {
        self.layer_report.as_ref().map_or(0, |r| r.0)
    }

    /// The layer block's rows over all ranks and its solver (`cholesky`, `icc`, ...), if
    /// there is one (on every rank).
    pub fn layer_solver(&self) -> Option<(usize, String)> {
        self.layer_report.clone()
    }

    /// `true`: each solution `x` is scaled by `s = x.b / x.Kx`, the minimum of the step's
    /// energy functional `1/2 y.Ky - y.b` on the line through `x`: then `x.r = 0` and the
    /// step keeps the energy identity to round-off, whatever the tolerance, with no energy
    /// test (the residual changes by `(1 - s) Kx`, `|1 - s| = |x.r| / x.Kx`: within the
    /// tolerance). Only for right-hand sides whose prescribed rows are zero (a scaled `x`
    /// would scale non-zero prescribed increments).
    pub fn set_scale(&mut self, scale: bool) {
        self.scale = scale;
    }

    /// `K` changed, or the increment was set from outside: the next solve computes `K x_0`.
    pub fn forget(&mut self) {
        self.known = 0;
        self.stale_layer = true;
        if let Precond::Jacobi(_, Some(layer)) = &mut self.pc {
            layer.forget();
        }
    }

    /// `K x` of the last solution (valid after [`StepCg::solve`]).
    pub fn kx(&self) -> &Vector {
        &self.kx
    }

    pub fn rtol(&self) -> f64 {
        self.rtol
    }

    /// Solves `K x = b`; `x` holds the last solution on entry (the guess is made from it).
    /// `energy` is the energy scale of the step's energy test; `fresh` computes `K x_0` with a
    /// product even when it is known (so that round-off in the summed products cannot build
    /// up over many steps). Collective.
    pub fn solve(
        &mut self,
        k: &Matrix,
        ksp: &Ksp,
        b: &Vector,
        x: &mut Vector,
        energy: f64,
        fresh: bool,
    ) -> Result<CgInfo> {
        let mut info = CgInfo::default();
        if std::mem::take(&mut self.stale_layer) {
            if let Precond::Jacobi(d, Some(layer)) = &mut self.pc {
                layer.factor(k, Some(d))?;
            }
        }
        let known = self.known;
        // The first guess, and its product where it is known; the common case (extrapolated
        // from known products) is made inside the first pass below.
        let extrapolate = self.predictor == Predictor::Extrapolate && known >= 2;
        let fused = extrapolate && !fresh && matches!(self.pc, Precond::Jacobi(..));
        // The layer's rows extrapolated in their own way (`LayerBlock::guess`), folded into
        // the previous solution so that the two-point extrapolation below makes them.
        if extrapolate {
            if let Precond::Jacobi(_, Some(layer)) = &mut self.pc {
                layer.guess(&mut self.x_prev, &mut self.kx_prev)?;
            }
        }
        match self.predictor {
            Predictor::Zero => {
                x.zero()?;
                self.kx.zero()?;
            }
            _ if fused => {}
            _ if extrapolate => self.extrapolate(x)?,
            _ => self.keep_previous(x)?,
        }
        if self.predictor != Predictor::Zero && (fresh || known == 0) {
            k.mult(x, &mut self.kx)?;
            info.products += 1;
        }
        // r = b - K x0, the first search direction and the sums of the stopping test.
        let (mut sums, bb) = self.first_pass(ksp, x, b, fused)?;
        // A zero right-hand side: the solution is zero (the guess may be far from it, and the
        // relative test would follow x to zero without reaching it).
        if bb == 0.0 {
            x.zero()?;
            self.kx.zero()?;
            self.known = 1;
            if let Precond::Jacobi(_, Some(layer)) = &mut self.pc {
                layer.forget();
            }
            return Ok(info);
        }
        let mut rz = sums[0];
        let mut converged = self.converged(sums, energy, &mut info);
        let mut last = sums;
        while !converged {
            if info.iterations == self.max_it {
                return Err(Error::Solver(format!(
                    "step CG (the step's own, -step_reuse) diverged: DIVERGED_ITS after {} iterations (-ksp_max_it), relative error {:.2e}",
                    self.max_it, info.relative_error
                )));
            }
            k.mult(&self.p, &mut self.q)?;
            info.products += 1;
            info.iterations += 1;
            let pq = self.p.dot(&self.q)?;
            if !(pq > 0.0) {
                return Err(Error::Solver(format!(
                    "step CG: p.Kp = {pq:e} after {} iterations: the step operator is not positive definite",
                    info.iterations
                )));
            }
            let alpha = rz / pq;
            sums = self.update(ksp, alpha, x, b)?;
            last = sums;
            converged = self.converged(sums, energy, &mut info);
            if !converged {
                let beta = sums[0] / rz;
                self.next_direction(beta)?;
            }
            rz = sums[0];
        }
        // Kx = b - r, and x on its own direction: x.r = 0, so the step keeps the energy to
        // round-off.
        let [_, xb, xr] = last;
        let s = if self.scale && xb - xr > 0.0 && xr != 0.0 { xb / (xb - xr) } else { 1.0 };
        if s != 1.0 {
            info.energy_error = 0.0;
        }
        Vector::with_slices([b, &self.r], [x, &mut self.kx], |[b, r], [x, kx]| {
            for i in 0..x.len() {
                x[i] *= s;
                kx[i] = s * (b[i] - r[i]);
            }
        })?;
        // The extrapolation's second point is known when the first was, and only from the
        // same sum of products: after a fresh product `kx_prev` still carries the old sum's
        // round-off, and extrapolating from the mixed pair would hand it on, grown by the
        // steps since the last refresh, to every later refresh.
        self.known = match self.predictor {
            Predictor::Extrapolate if known >= 1 && !fresh => 2,
            _ => 1,
        };
        if let Precond::Jacobi(_, Some(layer)) = &mut self.pc {
            layer.record(x)?;
        }
        Ok(info)
    }

    /// `x = 2 x - x_prev`, `Kx = 2 Kx - Kx_prev` (known products), the old ones kept.
    fn extrapolate(&mut self, x: &mut Vector) -> Result<()> {
        Vector::with_slices(
            [],
            [x, &mut self.x_prev, &mut self.kx, &mut self.kx_prev],
            |[], [x, xp, kx, kxp]| {
                for i in 0..x.len() {
                    let (xo, ko) = (x[i], kx[i]);
                    x[i] = 2.0 * xo - xp[i];
                    kx[i] = 2.0 * ko - kxp[i];
                    xp[i] = xo;
                    kxp[i] = ko;
                }
            },
        )
    }

    /// The first pass: (with `extrapolate`, the guess extrapolated first,
    /// [`StepCg::extrapolate`]) `r = b - Kx`, `p = B r` and the sums `[r.Br, x.b, x.r]` over
    /// the ranks, with `b.b`.
    fn first_pass(
        &mut self,
        ksp: &Ksp,
        x: &mut Vector,
        b: &Vector,
        extrapolate: bool,
    ) -> Result<([f64; 3], f64)> {
        let local = match &mut self.pc {
            Precond::Jacobi(d, layer) => {
                let mut sums = Vector::with_slices(
                    [b],
                    [
                        x,
                        &mut self.x_prev,
                        &mut self.kx,
                        &mut self.kx_prev,
                        &mut self.r,
                        &mut self.p,
                    ],
                    |[b], [x, xp, kx, kxp, r, p]| {
                        let (mut rz, mut xb, mut xr, mut bb) = (0.0, 0.0, 0.0, 0.0);
                        for i in 0..x.len() {
                            if extrapolate {
                                let (xo, ko) = (x[i], kx[i]);
                                x[i] = 2.0 * xo - xp[i];
                                kx[i] = 2.0 * ko - kxp[i];
                                xp[i] = xo;
                                kxp[i] = ko;
                            }
                            r[i] = b[i] - kx[i];
                            p[i] = d[i] * r[i];
                            rz += r[i] * p[i];
                            xb += x[i] * b[i];
                            xr += x[i] * r[i];
                            bb += b[i] * b[i];
                        }
                        [rz, xb, xr, bb]
                    },
                )?;
                if let Some(layer) = layer {
                    sums[0] += with_layer(layer, &self.r, &mut self.p)?;
                }
                sums
            }
            Precond::Petsc(z) => {
                let bb = Vector::with_slices([b, &self.kx], [&mut self.r], |[b, kx], [r]| {
                    let mut bb = 0.0;
                    for i in 0..r.len() {
                        r[i] = b[i] - kx[i];
                        bb += b[i] * b[i];
                    }
                    bb
                })?;
                ksp.pc_apply(&self.r, z)?;
                self.p.copy_from(z)?;
                let [rz, xb, xr] = local_sums(&self.r, z, x, b)?;
                [rz, xb, xr, bb]
            }
        };
        let [rz, xb, xr, bb] = sum_over_ranks(local);
        Ok(([rz, xb, xr], bb))
    }

    /// Before a new guess replaces `x`: the last solution and its product move to `x_prev`,
    /// `kx_prev` (the extrapolation's second point).
    fn keep_previous(&mut self, x: &Vector) -> Result<()> {
        if self.predictor == Predictor::Extrapolate {
            self.x_prev.copy_from(x)?;
            self.kx_prev.copy_from(&self.kx)?;
        }
        Ok(())
    }

    /// `x += alpha p`, `r -= alpha Kp`, `z = B r` and the sums `[r.z, x.b, x.r]` over the
    /// ranks (with Jacobi in one pass; `K x` is `b - r`, formed at the end).
    fn update(&mut self, ksp: &Ksp, alpha: f64, x: &mut Vector, b: &Vector) -> Result<[f64; 3]> {
        let local = match &mut self.pc {
            Precond::Jacobi(d, layer) => {
                let mut sums = Vector::with_slices(
                    [&self.p, &self.q, b],
                    [x, &mut self.r],
                    |[p, q, b], [x, r]| {
                        let (mut rz, mut xb, mut xr) = (0.0, 0.0, 0.0);
                        for i in 0..r.len() {
                            x[i] += alpha * p[i];
                            r[i] -= alpha * q[i];
                            rz += r[i] * d[i] * r[i];
                            xb += x[i] * b[i];
                            xr += x[i] * r[i];
                        }
                        [rz, xb, xr]
                    },
                )?;
                if let Some(layer) = layer {
                    sums[0] += self.r.with_local_slice(|r| layer.apply(r))??;
                }
                sums
            }
            Precond::Petsc(z) => {
                Vector::with_slices([&self.p, &self.q], [x, &mut self.r], |[p, q], [x, r]| {
                    for i in 0..r.len() {
                        x[i] += alpha * p[i];
                        r[i] -= alpha * q[i];
                    }
                })?;
                ksp.pc_apply(&self.r, z)?;
                local_sums(&self.r, z, x, b)?
            }
        };
        Ok(sum_over_ranks(local))
    }

    /// The stopping test of the module's doc from `[r.Br, x.b, x.r]`.
    fn converged(&self, [rz, xb, xr]: [f64; 3], energy: f64, info: &mut CgInfo) -> bool {
        let xkx = xb - xr;
        info.relative_error = if xkx > 0.0 { (rz / xkx).max(0.0).sqrt() } else { f64::INFINITY };
        info.energy_error = -0.5 * xr;
        // A zero right-hand side from a zero guess: r = 0.
        if rz <= 0.0 {
            return true;
        }
        rz <= self.rtol * self.rtol * xkx
            && (self.scale || xr.abs() <= 2.0 * self.energy_tol * energy)
    }

    /// `p = B r + beta p`.
    fn next_direction(&mut self, beta: f64) -> Result<()> {
        match &self.pc {
            Precond::Jacobi(d, layer) => {
                Vector::with_slices([&self.r], [&mut self.p], |[r], [p]| {
                    for i in 0..p.len() {
                        p[i] = d[i] * r[i] + beta * p[i];
                    }
                })?;
                match layer {
                    Some(layer) => self.p.with_local_slice_mut(|p| layer.add_last(p))?,
                    None => Ok(()),
                }
            }
            Precond::Petsc(z) => self.p.aypx(beta, z),
        }
    }
}

#[cfg(test)]
mod tests {
    //! The own CG on a small SPD matrix through PETSc (one rank). MPI and PETSc start once
    //! per process, so everything is one `#[test]`.

    use super::*;
    use crate::petsc::Petsc;
    use crate::time::operator::Reuse;

    /// Grid side: `K` has `N = SIDE^2` rows.
    const SIDE: usize = 12;
    const N: usize = SIDE * SIDE;
    /// Most entries in a row of `K` (the 5-point stencil).
    const W: usize = 5;
    /// Solves between fresh products, as the run's `-step_reuse_refresh` default.
    const REFRESH: usize = 16;
    const RTOL: f64 = 1e-8;

    /// `K = diag(m) + L` like the step operator `4/tau^2 M + A`: `m_i` in [0.5, 1.5] (a
    /// varying "mass"), `L` the 5-point stencil with coefficients in [1, 2] (Dirichlet outside
    /// the grid). Symmetric, strictly diagonally dominant with a positive diagonal: SPD.
    fn operator() -> Result<Matrix> {
        let at = |i: usize, j: usize| i * SIDE + j;
        let coef = |a: usize, b: usize| 1.0 + ((a * 7 + b * 3) % 11) as f64 / 10.0;
        let mut rows: Vec<Vec<(i32, f64)>> = vec![Vec::new(); N];
        for i in 0..SIDE {
            for j in 0..SIDE {
                let p = at(i, j);
                let mass = 0.5 + ((i * 5 + j * 3) % 7) as f64 / 6.0;
                let mut diag = mass;
                for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                    let (a, b) = (i as i64 + di, j as i64 + dj);
                    let q = (a >= 0 && a < SIDE as i64 && b >= 0 && b < SIDE as i64)
                        .then(|| at(a as usize, b as usize));
                    // The edge's coefficient, the same from both of its ends.
                    let c = coef(p.min(q.unwrap_or(usize::MAX)), p.max(q.unwrap_or(N)));
                    diag += c;
                    if let Some(q) = q {
                        rows[p].push((q as i32, -c));
                    }
                }
                rows[p].push((p as i32, diag));
            }
        }
        let nnz: Vec<i32> = rows.iter().map(|r| r.len() as i32).collect();
        let mut k = Matrix::new_aij(N, N, 1, &nnz, &vec![0; N])?;
        for (p, row) in rows.iter().enumerate() {
            let (cols, vals): (Vec<i32>, Vec<f64>) = row.iter().copied().unzip();
            k.set_values(&[p as i32], &cols, &vals, false)?;
        }
        k.assemble()?;
        Ok(k)
    }

    /// The right-hand side of step `n`: smooth in time, as a step's load and inertia terms.
    fn rhs(n: usize, b: &mut Vector) -> Result<()> {
        b.with_local_slice_mut(|b| {
            for (i, v) in b.iter_mut().enumerate() {
                let t = 0.05 * n as f64;
                *v = (t + 0.1 * i as f64).sin() + 0.5 * (0.3 * t - 0.02 * i as f64).cos();
            }
        })
    }

    fn norm_inf(v: &[f64]) -> f64 {
        v.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    /// `REFRESH + 4` solves with the kept products (a fresh product every `REFRESH`, as the
    /// integrator does), under the preconditioner `pc`, optionally scaled
    /// ([`StepCg::set_scale`]); checks every solution against products computed afresh.
    fn check(pc: &str, scale: bool) -> Result<String> {
        let k = operator()?;
        // The matrix's infinity norm and 1 / diagonal (Jacobi's B; `none`: B = I).
        let mut norm_k: f64 = 0.0;
        let mut dinv = vec![0.0; N];
        for i in 0..N {
            k.with_row(i, |c, v| {
                norm_k = norm_k.max(v.iter().map(|x| x.abs()).sum());
                let d = v[c.iter().position(|&c| c as usize == i).expect("diagonal")];
                dinv[i] = if pc == "jacobi" { 1.0 / d } else { 1.0 };
            })?;
        }
        let mut ksp = Ksp::new("cgtest_")?;
        ksp.set_operators(&k, &k)?;
        ksp.set_type("cg")?;
        ksp.set_pc_type(pc)?;
        ksp.set_tolerances(Some(RTOL), Some(1e-50), None, Some(10_000))?;
        ksp.set_up()?;
        let reuse = Reuse::default();
        let mut cg = StepCg::new(&k, &ksp, RTOL, &reuse, Vec::new())?;
        cg.set_scale(scale);
        let (mut x, mut b) = k.create_vecs()?;
        let mut y = x.duplicate()?;
        // Round-off of the kept product: each update summed into it (an iteration's
        // `r -= alpha K p` with `K p` from a product of at most W terms, `x += alpha p`; the
        // guess's `2 Kx - Kx_prev`; the first product; `b - r` at the end) errs by at most
        // C eps (|K| X + |b|) in the infinity norm, C = 2 W + 5 (first order in eps), where X
        // bounds the iterates: three times the largest solution (the extrapolated guess
        // `2 x^n - x^{n-1}`; CG's iterates between guess and solution stay within it). The
        // two-point guess carries the difference of the previous solves on: after solve m of
        // a chain started by a product, the differences of solve k weigh 1 (k the first) or
        // m - k + 1. Comparing with a fresh product adds W eps |K| X.
        let c = (2 * W + 5) as f64;
        let eps = f64::EPSILON;
        let mut chain: Vec<f64> = Vec::new();
        let (mut worst_ratio, mut worst_residual) = (0.0f64, 0.0f64);
        let (mut largest_x, mut margin, mut iterations) = (0.0f64, f64::INFINITY, 0);
        for n in 0..REFRESH + 4 {
            rhs(n, &mut b)?;
            let fresh = n > 0 && n % REFRESH == 0;
            let info = cg.solve(&k, &ksp, &b, &mut x, 1.0, fresh)?;
            if n == 0 || fresh {
                chain.clear();
            }
            chain.push((info.iterations + 2) as f64);
            iterations += info.iterations;
            k.mult(&x, &mut y)?;
            let (xs, ys, ks, bs) = (
                x.with_local_slice(|s| s.to_vec())?,
                y.with_local_slice(|s| s.to_vec())?,
                cg.kx().with_local_slice(|s| s.to_vec())?,
                b.with_local_slice(|s| s.to_vec())?,
            );
            largest_x = largest_x.max(norm_inf(&xs));
            let big_x = 3.0 * largest_x;
            let scale_of = norm_k * big_x + norm_inf(&bs);
            let m = chain.len();
            let weights: f64 = chain
                .iter()
                .enumerate()
                .map(|(j, u)| if j == 0 { *u } else { (m - j) as f64 * u })
                .sum();
            let bound = c * eps * scale_of * weights + W as f64 * eps * norm_k * big_x;
            let gap: Vec<f64> = ks.iter().zip(&ys).map(|(a, b)| a - b).collect();
            let gap_inf = norm_inf(&gap);
            assert!(
                gap_inf <= bound,
                "{pc}, scale {scale}, solve {n}: kept K x differs from K x by {gap_inf:e}, more than the round-off bound {bound:e}"
            );
            worst_ratio = worst_ratio.max(gap_inf / (eps * norm_k * big_x));
            margin = margin.min(bound / gap_inf);
            // The solve's own test holds for the true residual b - K x up to the difference
            // of the kept product: |r|_B <= rtol |x|_K + |gap|_B.
            let r: Vec<f64> = bs.iter().zip(&ys).map(|(b, y)| b - y).collect();
            let r_b = r.iter().zip(&dinv).map(|(r, d)| r * r * d).sum::<f64>().sqrt();
            let x_k = xs.iter().zip(&ys).map(|(x, y)| x * y).sum::<f64>().sqrt();
            let gap_b = gap.iter().zip(&dinv).map(|(g, d)| g * g * d).sum::<f64>().sqrt();
            if scale {
                // Scaled onto its own direction: x.r = 0 up to the kept product's difference
                // and the round-off of forming s (x.b's terms).
                let xr: f64 = xs.iter().zip(&r).map(|(x, r)| x * r).sum();
                let x1: f64 = xs.iter().map(|x| x.abs()).sum();
                let xb: f64 = xs.iter().zip(&bs).map(|(x, b)| (x * b).abs()).sum();
                let allowed = x1 * (bound + 4.0 * eps * norm_inf(&bs)) + 4.0 * N as f64 * eps * xb;
                assert!(
                    xr.abs() <= allowed,
                    "{pc}, solve {n}: scaled x.r = {xr:e}, more than {allowed:e}"
                );
            } else {
                assert!(
                    r_b <= RTOL * x_k + gap_b,
                    "{pc}, solve {n}: |b - Kx|_B = {r_b:e} > rtol |x|_K + |gap|_B = {:e}",
                    RTOL * x_k + gap_b
                );
            }
            worst_residual = worst_residual.max(r_b / x_k);
        }
        Ok(format!(
            "{pc}, scale {scale}: {:.1} iterations a solve; kept K x - K x at most {worst_ratio:.1} eps |K| X, the bound at least {margin:.0} times the difference; |b - Kx|_B / |x|_K at most {worst_residual:.2e} (rtol {RTOL:e})",
            iterations as f64 / (REFRESH + 4) as f64
        ))
    }

    #[test]
    fn kept_products_equal_recomputed_ones_and_the_solutions_meet_the_tolerance() {
        let universe = mpi::initialize().expect("MPI initialized once");
        let petsc = Petsc::init(&["cg-test".to_string()], "").expect("PetscInitialize");
        assert_eq!(petsc.size(), 1, "one rank");
        for (pc, scale) in [("jacobi", false), ("jacobi", true), ("none", false)] {
            match check(pc, scale) {
                Ok(line) => println!("{line}"),
                Err(e) => panic!("{pc}: {e}"),
            }
        }
        drop(petsc);
        drop(universe);
    }
}
