//! Stability metrics of a run (the hard-case suite): energy rise and loss against
//! the work done, penetration, chatter of the pressure and of the total contact force,
//! contact episodes per node and impact, active-set and KSP iterations, non-finite values.
//!
//! One pure function, [`measure`], computes them from per-step series: the run calls it on
//! its in-memory history and stores the result in its summary (`stability`, also in the HDF5
//! file's `summary` attribute); `massfree suite` calls it on the series read back from the
//! HDF5 file (`report::stability_from_file`), both through [`RunSeries`], so the two agree by construction and the file alone suffices.
//!
//! Definitions (docs/method.md: the midpoint rule, contact, chatter), with `E^n` the discrete energy, `W^n` the work of
//! the loads and of the Dirichlet reactions up to step n (not the contact work):
//! - `E_ref = max_n max(|E^n|, |E^0 + W^n|)` (never a zero initial energy alone);
//! - energy rise `max_n (E^n - E^0 - W^n) / E_ref`: the contact work with fixed obstacles is
//!   `-lambda g^n <= 0` per step, so theory says <= solver tolerance;
//! - energy loss `(E^0 + W^N - E^N) / E_ref` at the end, and per impact;
//! - energy drift `max_n |E^n - E^0 - W^n| / E_ref` (the long free-vibration run);
//! - an impact is a contact episode of the body: a step with some active node after a step
//!   with none;
//! - penetration `max(0, -min gap)` over the steps after the start and all contact nodes (the
//!   gap the solver enforces at `t_{n+1}`; for a pair the weighted gap over `D_qq`; a slave
//!   node without master facet, gap 1.8e308, is skipped);
//! - osc2 and TV index (`contact::metrics`) of the lowest contact node's pressure over each
//!   of its episodes, and of the total contact force over each impact: the largest;
//! - episodes per node and impact: within each impact, how many times each node that touches
//!   enters contact (1 = no flicker): the largest and the mean.

use crate::contact::metrics::{contact_period, episodes, osc2, tv_index};

/// The stability metrics of one run (every field defaults to zero when read from an older
/// summary).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Stability {
    /// `E^0`.
    pub energy_initial: f64,
    /// `max_n max(|E^n|, |E^0 + W^n|)`.
    pub energy_ref: f64,
    /// `max_n (E^n - E^0 - W^n) / E_ref` (W: loads and Dirichlet reactions, not contact).
    pub energy_rise: f64,
    /// `(E^0 + W^N - E^N) / E_ref` at the last step.
    pub energy_loss: f64,
    /// `max_n |E^n - E^0 - W^n| / E_ref`.
    pub energy_drift: f64,
    /// Contact episodes of the body (steps with an active node after one without).
    pub impacts: usize,
    /// `energy_loss / impacts` (0 without impacts).
    pub loss_per_impact: f64,
    /// Steps with an active contact node.
    pub contact_steps: usize,
    /// `max(0, -min gap)` over all contact nodes and steps.
    pub penetration: f64,
    /// The largest side of the mesh's bounding box (the scale of the penetration check).
    pub body_size: f64,
    /// Largest total contact force `sum_q lambda_q`.
    pub force_max: f64,
    /// osc2 and TV index of the lowest node's pressure, the largest over its episodes.
    pub pressure_osc2: f64,
    pub pressure_tv_index: f64,
    /// osc2 and TV index of the total contact force, the largest over the impacts.
    pub force_osc2: f64,
    pub force_tv_index: f64,
    /// Episodes per node within an impact: largest and mean over (impact, node that touched).
    pub episodes_per_impact_max: usize,
    pub episodes_per_impact_mean: f64,
    /// Active-set iterations per contact step: mean and largest.
    pub pdas_iterations_mean: f64,
    pub pdas_iterations_max: usize,
    /// KSP iterations per step: mean and largest.
    pub ksp_iterations_mean: f64,
    pub ksp_iterations_max: usize,
    /// Non-finite values among the energies, works and contact series (and, from a file,
    /// the written fields).
    pub non_finite: usize,
}

/// Per-step energy series, index 0 = the start (all of the same length).
pub struct EnergySeries<'a> {
    pub total: &'a [f64],
    pub external_work: &'a [f64],
    pub dirichlet_work: &'a [f64],
    pub contact_work: &'a [f64],
}

/// Per-step contact series, row-major `[steps + 1][nodes]`, row 0 = the start.
pub struct ContactSeries<'a> {
    pub nodes: usize,
    pub force: &'a [f64],
    pub gap: &'a [f64],
    pub active: &'a [bool],
    pub weights: &'a [f64],
    /// Active-set iterations per step (`[steps + 1]`).
    pub iterations: &'a [f64],
    /// The lowest contact node (index among the contact nodes).
    pub lowest: usize,
}

/// A run's series as one value: what the run keeps in memory and what the HDF5 file stores
/// (`/energy`, `/contact`), built by either and measured by one function.
pub struct RunSeries {
    /// Per step from the start: total energy, work of the loads, of the Dirichlet reactions,
    /// of the contact.
    pub total: Vec<f64>,
    pub external_work: Vec<f64>,
    pub dirichlet_work: Vec<f64>,
    pub contact_work: Vec<f64>,
    pub contact: Option<ContactColumns>,
    /// The largest side of the mesh's bounding box.
    pub body_size: f64,
    /// KSP iterations in all and the largest of one step.
    pub ksp_iterations: usize,
    pub ksp_iterations_step_max: usize,
}

/// The owned contact series of [`RunSeries`] (see [`ContactSeries`]).
pub struct ContactColumns {
    pub nodes: usize,
    pub force: Vec<f64>,
    pub gap: Vec<f64>,
    pub active: Vec<bool>,
    pub weights: Vec<f64>,
    pub iterations: Vec<f64>,
    pub lowest: usize,
}

impl RunSeries {
    /// The stability metrics of the series ([`measure`]).
    pub fn measure(&self) -> Stability {
        let energy = EnergySeries {
            total: &self.total,
            external_work: &self.external_work,
            dirichlet_work: &self.dirichlet_work,
            contact_work: &self.contact_work,
        };
        let steps = self.total.len().saturating_sub(1);
        let ksp = (self.ksp_iterations, self.ksp_iterations_step_max, steps);
        let contact = self.contact.as_ref().map(|c| ContactSeries {
            nodes: c.nodes,
            force: &c.force,
            gap: &c.gap,
            active: &c.active,
            weights: &c.weights,
            iterations: &c.iterations,
            lowest: c.lowest,
        });
        measure(&energy, contact.as_ref(), self.body_size, ksp)
    }
}

/// Gaps at or above this are "no master facet within reach" (the writer's 1.8e308).
const NO_FACET: f64 = 1e300;

/// The metrics of a run from its series; `ksp` = (KSP iterations in all, the largest of one
/// step, steps).
pub fn measure(
    energy: &EnergySeries,
    contact: Option<&ContactSeries>,
    body_size: f64,
    ksp: (usize, usize, usize),
) -> Stability {
    let mut s = Stability { body_size, ..Default::default() };
    let n = energy.total.len();
    let finite = |x: &f64| x.is_finite();
    s.non_finite = [energy.total, energy.external_work, energy.dirichlet_work, energy.contact_work]
        .iter()
        .map(|v| v.iter().filter(|x| !finite(x)).count())
        .sum();
    if n > 0 {
        let e0 = energy.total[0];
        let work = |k: usize| energy.external_work[k] + energy.dirichlet_work[k];
        let w0 = work(0);
        s.energy_initial = e0;
        let e_ref = (0..n)
            .map(|k| energy.total[k].abs().max((e0 + work(k) - w0).abs()))
            .fold(0.0f64, f64::max);
        s.energy_ref = e_ref;
        let scale = if e_ref > 0.0 { e_ref } else { 1.0 };
        let change = |k: usize| (energy.total[k] - e0 - (work(k) - w0)) / scale;
        // change(0) = 0: the rise is never negative.
        s.energy_rise = (0..n).map(change).fold(0.0, f64::max);
        s.energy_loss = -change(n - 1);
        s.energy_drift = (0..n).map(|k| change(k).abs()).fold(0.0, f64::max);
        // NaN anywhere makes the energy metrics NaN, not silently zero.
        if s.non_finite > 0 {
            s.energy_rise = f64::NAN;
            s.energy_loss = f64::NAN;
            s.energy_drift = f64::NAN;
        }
    }
    let (ksp_total, ksp_max, steps) = ksp;
    s.ksp_iterations_mean = if steps > 0 { ksp_total as f64 / steps as f64 } else { 0.0 };
    s.ksp_iterations_max = ksp_max;
    if let Some(c) = contact {
        contact_metrics(&mut s, c);
        s.loss_per_impact = if s.impacts > 0 { s.energy_loss / s.impacts as f64 } else { 0.0 };
    }
    s
}

fn contact_metrics(s: &mut Stability, c: &ContactSeries) {
    let nc = c.nodes;
    let rows = c.force.len().checked_div(nc).unwrap_or(c.iterations.len());
    s.non_finite += c.force.iter().filter(|x| !x.is_finite()).count();
    // Row 0's gaps are NaN by design (no step yet).
    s.non_finite += c.gap.iter().skip(nc).filter(|x| !x.is_finite()).count();
    let min_gap = c
        .gap
        .iter()
        .skip(nc)
        .filter(|g| g.is_finite() && **g < NO_FACET)
        .fold(f64::INFINITY, |a, &b| a.min(b));
    s.penetration = if min_gap.is_finite() { (-min_gap).max(0.0) } else { 0.0 };
    if c.gap.iter().skip(nc).any(|g| g.is_nan()) {
        s.penetration = f64::NAN;
    }
    let node_active = |k: usize, a: usize, b: usize| -> Vec<bool> {
        (a..=b).map(|n| c.active[n * nc + k]).collect()
    };
    let any: Vec<bool> =
        (0..rows).map(|n| c.active[n * nc..(n + 1) * nc].iter().any(|&a| a)).collect();
    let total: Vec<f64> = (0..rows).map(|n| c.force[n * nc..(n + 1) * nc].iter().sum()).collect();
    s.force_max = total.iter().copied().fold(0.0, f64::max);
    s.contact_steps = any.iter().filter(|&&a| a).count();
    let its: Vec<f64> = (1..rows).filter(|&n| any[n]).map(|n| c.iterations[n]).collect();
    if !its.is_empty() {
        s.pdas_iterations_mean = its.iter().sum::<f64>() / its.len() as f64;
        s.pdas_iterations_max = its.iter().copied().fold(0.0, f64::max) as usize;
    }
    // The impacts: maximal runs of steps with an active node.
    let impacts = runs(&any);
    s.impacts = impacts.len();
    let (mut eps_sum, mut eps_count) = (0usize, 0usize);
    for &(a, b) in &impacts {
        s.force_osc2 = s.force_osc2.max(osc2(&total, (a, b)));
        s.force_tv_index = s.force_tv_index.max(tv_index(&total, (a, b)));
        for k in 0..nc {
            let e = episodes(&node_active(k, a, b));
            if e > 0 {
                s.episodes_per_impact_max = s.episodes_per_impact_max.max(e);
                eps_sum += e;
                eps_count += 1;
            }
        }
    }
    s.episodes_per_impact_mean =
        if eps_count > 0 { eps_sum as f64 / eps_count as f64 } else { 0.0 };
    // The lowest node's pressure over each of its episodes.
    if nc > 0 && rows > 0 {
        let k = c.lowest.min(nc - 1);
        let w = c.weights.get(k).copied().unwrap_or(1.0);
        let p: Vec<f64> = (0..rows).map(|n| c.force[n * nc + k] / w).collect();
        let act = node_active(k, 0, rows - 1);
        for per in runs(&act) {
            s.pressure_osc2 = s.pressure_osc2.max(osc2(&p, per));
            s.pressure_tv_index = s.pressure_tv_index.max(tv_index(&p, per));
        }
    }
}

/// The maximal runs `[first, last]` of `true` in `flags`.
pub fn runs(flags: &[bool]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut start = None;
    for (i, &f) in flags.iter().enumerate() {
        match (f, start) {
            (true, None) => start = Some(i),
            (false, Some(a)) => {
                out.push((a, i - 1));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(a) = start {
        out.push((a, flags.len() - 1));
    }
    debug_assert_eq!(out.len(), episodes(flags));
    debug_assert!(out.first().map(|r| r.0) == contact_period(flags).map(|p| p.0));
    out
}

/// The largest side of the bounding box of `coords`.
pub fn body_size(coords: &[[f64; 3]]) -> f64 {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for x in coords {
        for i in 0..3 {
            lo[i] = lo[i].min(x[i]);
            hi[i] = hi[i].max(x[i]);
        }
    }
    (0..3).map(|i| hi[i] - lo[i]).filter(|d| d.is_finite()).fold(0.0, f64::max)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn energy<'a>(total: &'a [f64], ext: &'a [f64], zero: &'a [f64]) -> EnergySeries<'a> {
        EnergySeries { total, external_work: ext, dirichlet_work: zero, contact_work: zero }
    }

    #[test]
    fn rise_loss_and_drift_against_the_work() {
        let z = [0.0; 4];
        // Loads do work 1, 2, 3; the energy follows but for a loss of 0.5 at step 2.
        let total = [10.0, 11.0, 11.5, 12.5];
        let ext = [0.0, 1.0, 2.0, 3.0];
        let s = measure(&energy(&total, &ext, &z), None, 1.0, (40, 12, 3));
        assert_eq!(s.energy_ref, 13.0);
        assert_eq!(s.energy_rise, 0.0);
        assert!((s.energy_loss - 0.5 / 13.0).abs() < 1e-15);
        assert!((s.energy_drift - 0.5 / 13.0).abs() < 1e-15);
        assert!((s.ksp_iterations_mean - 40.0 / 3.0).abs() < 1e-15);
        assert_eq!((s.ksp_iterations_max, s.non_finite), (12, 0));
        // A rise above the work is seen, relative to E_ref.
        let total = [10.0, 11.2, 12.0, 13.0];
        let s = measure(&energy(&total, &ext, &z), None, 1.0, (0, 0, 3));
        assert!((s.energy_rise - 0.2 / 13.0).abs() < 1e-15);
        // A zero initial energy: E_ref comes from the work and the energy.
        let total = [0.0, 1.0, 2.0, 2.0];
        let s = measure(&energy(&total, &ext, &z), None, 1.0, (0, 0, 3));
        assert_eq!(s.energy_ref, 3.0);
        assert!((s.energy_loss - 1.0 / 3.0).abs() < 1e-15);
        // NaN is never hidden.
        let total = [1.0, f64::NAN, 1.0, 1.0];
        let s = measure(&energy(&total, &ext, &z), None, 1.0, (0, 0, 3));
        assert_eq!(s.non_finite, 1);
        assert!(s.energy_rise.is_nan());
    }

    #[test]
    fn impacts_penetration_and_episodes() {
        // Two nodes, 8 rows (row 0 the start); two impacts: rows 1-3 and 5-6. Node 1 flickers
        // in the first impact (on, off, on).
        let nc = 2;
        let act = [
            [false, false],
            [true, true],
            [true, false],
            [true, true],
            [false, false],
            [true, false],
            [true, false],
            [false, false],
        ];
        let active: Vec<bool> = act.iter().flatten().copied().collect();
        let force: Vec<f64> = active.iter().map(|&a| if a { 1.0 } else { 0.0 }).collect();
        let mut gap: Vec<f64> = active.iter().map(|&a| if a { 0.0 } else { 0.1 }).collect();
        gap[0] = f64::NAN;
        gap[1] = f64::NAN;
        gap[2 * 3 + 1] = -2e-9; // row 3, node 1
        gap[2 * 7] = 1.7e308; // no master facet: skipped
        let its = [0.0, 2.0, 1.0, 1.0, 0.0, 3.0, 1.0, 0.0];
        let c = ContactSeries {
            nodes: nc,
            force: &force,
            gap: &gap,
            active: &active,
            weights: &[0.5, 0.5],
            iterations: &its,
            lowest: 0,
        };
        let total = [1.0, 1.0, 0.99, 0.99, 0.99, 0.98, 0.98, 0.98];
        let z = [0.0; 8];
        let s = measure(&energy(&total, &z, &z), Some(&c), 2.0, (0, 0, 7));
        assert_eq!(s.impacts, 2);
        assert_eq!(s.contact_steps, 5);
        assert!((s.energy_loss - 0.02).abs() < 1e-15);
        assert!((s.loss_per_impact - 0.01).abs() < 1e-15);
        assert_eq!(s.penetration, 2e-9);
        assert_eq!(s.episodes_per_impact_max, 2);
        // (impact 1: node 0 once, node 1 twice; impact 2: node 0 once) = 4 / 3
        assert!((s.episodes_per_impact_mean - 4.0 / 3.0).abs() < 1e-15);
        assert_eq!(s.pdas_iterations_max, 3);
        assert!((s.pdas_iterations_mean - 8.0 / 5.0).abs() < 1e-15);
        assert_eq!(s.force_max, 2.0);
        assert_eq!(s.non_finite, 0);
        // The lowest node's pressure is 2 in each of its two episodes: a flat hump.
        assert_eq!(s.pressure_osc2, 0.0);
        assert!((s.pressure_tv_index - 1.0).abs() < 1e-15);
    }

    #[test]
    fn runs_and_size() {
        assert_eq!(runs(&[false, true, true, false, true]), vec![(1, 2), (4, 4)]);
        assert!(runs(&[false, false]).is_empty());
        assert_eq!(body_size(&[[0.0, 0.0, 0.0], [1.0, 3.0, 0.0]]), 3.0);
    }
}
