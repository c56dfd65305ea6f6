//! The mass-free layer's velocity: the time derivative of its static response.
//!
//! The massless DOFs `C` have no dynamics: each step puts them in static equilibrium with the
//! massive DOFs `I`, the loads and the contact forces (docs/method.md, massless DOFs). Their velocity is the
//! derivative of that response, with every DOF that carried a contact force in the step held
//! (`H`: the active nodes, and with pairs the master nodes they press on) and the free
//! massless DOFs `F = C \ H`:
//!
//! ```text
//!   K_FF v_F = f'_F - K_FR w_R,   R = I + H,   w_I = v_I,   w_H = (u_H^{n+1} - u_H^{n-1}) / 2 tau,
//! ```
//! `K` the stiffness (small strain: `A`; finite strain: the tangent of the step's internal
//! force, the static problem's Jacobian up to O(tau)), `f'` the loads' rate over the step.
//! The held DOFs move with their chord velocity over the last two steps, `(u^{n+1} -
//! u^{n-1}) / 2 tau` (their constrained increments can alternate from step to step, which
//! the mean over two removes; on a resting obstacle its normal part is zero once in contact). The midpoint recursion
//! `v = 2 du/tau - v` is never used on massless DOFs: it fixes only `v^{n+1} + v^n` there and
//! leaves an undamped `(-1)^n` sawtooth. Between settlements (the velocity is written only at
//! output steps) they hold `du/tau`; `M`'s rows and columns there are zero, so neither value
//! enters the dynamics, the energy or the momenta.
//!
//! A rigid motion of a free body is a static response (`K w = 0` for translations, and for
//! infinitesimal rotations at small strain), so the layer then moves with the body exactly.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::Midpoint;
use crate::error::Result;
use crate::petsc::{Matrix, Vector};
use crate::time::layer::LayerBlock;

/// The factored layer blocks of the velocity problem and the held DOFs they were factored
/// for; whether the velocity is settled for the current state.
#[derive(Default)]
pub struct LayerRate {
    /// `A_FF` (small strain; refactored only when the held DOFs change) and the tangent's
    /// (finite strain; refactored at every settlement, the tangent changes every step).
    on_a: Option<LayerBlock>,
    on_a_held: Option<Vec<i32>>,
    on_tangent: Option<LayerBlock>,
    /// The DOFs that carried a contact force in the last step (global, same on every rank).
    pub loaded: Vec<i32>,
    /// This rank's massless DOFs' increments of the last step and of the one before, as
    /// many as recorded since the start (at most 2).
    chords: [Vec<f64>; 2],
    recorded: usize,
    /// The loads changed in the last step (their rate enters the right-hand side).
    pub load_rate: bool,
    /// The massless velocities are the static response's derivative for the current state.
    pub settled: bool,
    /// `w` and `K w`.
    work: Option<(Vector, Vector)>,
}

impl Midpoint {
    /// After a step: the massless DOFs' velocity is `du/tau` until it is settled, `loaded` the
    /// DOFs that carried a contact force (held by the settlement).
    pub(super) fn after_step_layer(&mut self, loaded: Vec<i32>, load_rate: bool) -> Result<()> {
        self.layer_rate.loaded = loaded;
        self.layer_rate.load_rate = load_rate;
        self.layer_rate.settled = false;
        self.massless()?;
        let Some((local, true)) = self.massless.as_ref() else { return Ok(()) };
        let inv = 1.0 / self.tau;
        let rate = &mut self.layer_rate;
        rate.chords.swap(0, 1);
        rate.recorded = (rate.recorded + 1).min(2);
        let chord = &mut rate.chords[0];
        chord.clear();
        Vector::with_slices([&self.du], [&mut self.v], |[du], [v]| {
            for (i, &m) in local.iter().enumerate() {
                if m {
                    v[i] = du[i] * inv;
                    chord.push(du[i]);
                }
            }
        })
    }

    /// The contact DOFs the next settlement holds (the start of a run: the initial active
    /// set's; global, the same on every rank).
    pub fn set_loaded_dofs(&mut self, loaded: Vec<i32>) {
        self.layer_rate.loaded = loaded;
        self.layer_rate.settled = false;
    }

    /// The velocity is settled as it is (a restart's checkpoint holds the settled one), and
    /// the restored `du` is the last step's increment.
    pub(super) fn layer_velocity_restored(&mut self) -> Result<()> {
        self.layer_rate.settled = true;
        self.layer_rate.load_rate = false;
        self.layer_rate.recorded = 0;
        self.massless()?;
        let Some((local, true)) = self.massless.as_ref() else { return Ok(()) };
        let chord = &mut self.layer_rate.chords[0];
        chord.clear();
        self.du.with_local_slice(|du| {
            chord.extend(local.iter().zip(du).filter(|(&m, _)| m).map(|(_, &d)| d))
        })?;
        self.layer_rate.recorded = 1;
        Ok(())
    }

    /// Puts the massless DOFs' velocity to the time derivative of their static response (the
    /// module's doc); nothing without massless DOFs or when already settled. Collective.
    pub fn settle_layer_velocity(&mut self) -> Result<()> {
        self.massless()?;
        let (local, any) = self.massless.as_ref().expect("found").clone();
        if !any || self.layer_rate.settled {
            return Ok(());
        }
        let (lo, hi) = self.u.ownership_range();
        let held: Vec<bool> = {
            let mut h = vec![false; hi - lo];
            for &g in &self.layer_rate.loaded {
                let g = g as usize;
                if (lo..hi).contains(&g) {
                    h[g - lo] = true;
                }
            }
            h
        };
        let (mut w, mut kw) = match self.layer_rate.work.take() {
            Some(pair) => pair,
            None => (self.u.duplicate()?, self.u.duplicate()?),
        };
        // w: the massive velocities, the held DOFs' chord velocity over the last two steps
        // (their constrained increments may alternate from step to step: the mean of two
        // removes that), zero on the free layer.
        let tau = self.tau;
        let stepped = self.layer_rate.recorded > 0;
        let [c0, c1] = &self.layer_rate.chords;
        let chord = |j: usize| match self.layer_rate.recorded {
            2 => 0.5 * (c0[j] + c1[j]) / tau,
            _ => c0[j] / tau,
        };
        Vector::with_slices([&self.v], [&mut w], |[v], [w]| {
            let mut j = 0;
            for i in 0..w.len() {
                w[i] = match (local[i], held[i]) {
                    (false, _) => v[i],
                    (true, true) if stepped => chord(j),
                    (true, true) => v[i],
                    (true, false) => 0.0,
                };
                j += local[i] as usize;
            }
        })?;
        let tangent = self.newton.as_ref().and_then(|n| n.last_tangent());
        let rows: Vec<usize> = local.iter().enumerate().filter(|m| *m.1).map(|m| m.0).collect();
        let loaded = &self.layer_rate.loaded;
        let block = match tangent {
            Some(k) => {
                k.mult(&w, &mut kw)?;
                let slot = &mut self.layer_rate.on_tangent;
                factored(slot, k, rows, "lu", loaded, None)?
            }
            None => {
                self.a.mult(&w, &mut kw)?;
                let slot = &mut self.layer_rate.on_a;
                factored(
                    slot,
                    &self.a,
                    rows,
                    "cholesky",
                    loaded,
                    Some(&mut self.layer_rate.on_a_held),
                )?
            }
        };
        // r_F = f'_F - (K w)_F, with the loads' rate over the last step.
        let rate = self.layer_rate.load_rate;
        let own: Vec<f64> =
            Vector::with_slices([&kw, &self.f_now, &self.f_next], [], |[kw, f1, f0], []| {
                block
                    .own_rows()
                    .iter()
                    .map(|&i| match (held[i], rate) {
                        (true, _) => 0.0,
                        (false, true) => (f1[i] - f0[i]) / tau - kw[i],
                        (false, false) => -kw[i],
                    })
                    .collect()
            })?;
        let d = block.solve_own(&own)?;
        let rows = block.own_rows();
        Vector::with_slices([&w], [&mut self.v], |[w], [v]| {
            for (j, &i) in rows.iter().enumerate() {
                v[i] = if held[i] { w[i] } else { d[j] };
            }
        })?;
        self.layer_rate.work = Some((w, kw));
        self.layer_rate.settled = true;
        Ok(())
    }
}

/// The layer block of `k` in `slot` (built on first use under the `massless_velocity_`
/// options, `pc` its factorization), factored with `loaded` held; with `last_held`, only when
/// they differ from the last factorization's (`k` constant). Collective.
fn factored<'s>(
    slot: &'s mut Option<LayerBlock>,
    k: &Matrix,
    rows: Vec<usize>,
    pc: &str,
    loaded: &[i32],
    last_held: Option<&mut Option<Vec<i32>>>,
) -> Result<&'s mut LayerBlock> {
    if slot.is_none() {
        *slot = LayerBlock::with_solver(k, rows, None, "massless_velocity_", pc, "qmd")?;
    }
    let block = slot.as_mut().expect("some rank has massless rows");
    match last_held {
        Some(last) => {
            // Refactoring is collective: every rank decides alike.
            let differs = (last.as_deref() != Some(loaded)) as i32;
            let mut any = 0;
            SimpleCommunicator::world().all_reduce_into(&differs, &mut any, SystemOperation::max());
            if any != 0 {
                block.factor_holding(k, None, loaded)?;
                *last = Some(loaded.to_vec());
            }
        }
        None => block.factor_holding(k, None, loaded)?,
    }
    Ok(block)
}
