//! The step's conjugate gradients, written out around PETSc's `MatMult` and `PCApply` so that
//! the step keeps what the solve computes (issue 27):
//!
//! - `K x` of the solution, summed as `K x_0 + sum alpha_i K p_i` from the products CG makes
//!   anyway: the next step's initial residual `b - K x_0` then needs no product (the guess is
//!   the last increment, or its extrapolation from the last two with their known products),
//!   and the integrator updates `A u` and `M v` from it instead of recomputing them;
//! - Jacobi applied inside the vector passes (three passes over memory an iteration instead of
//!   PETSc's six vector operations); any other preconditioner through `PCApply`.
//!
//! Stopping test, in the step's own terms. With `r = b - K x`, the midpoint rule's energy
//! identity holds up to `-1/2 x.r` (METHOD.md section 4: `E^{n+1} - E^n - W = 1/2 du.(K du - b)`),
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
                let r = LayerBlock::report(own, local)?;
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
