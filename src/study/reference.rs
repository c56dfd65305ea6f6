//! Errors against a reference run read from HDF5 files, for contact scenes: the lowest
//! contact node's pressure history and the total contact force history, each as a relative
//! L2 difference in time (fields are compared in `fieldnorm`).
//!
//! A history is the sequence of values `y_n` at the step times `t_n` (`t_0 = 0`, one value
//! per step). It stands for its piecewise-linear interpolant `y(t)`: the time integrator is
//! second order, and the interpolant is the continuous function the samples define without
//! adding or smoothing anything. The error of a run against a reference is
//!
//! ```text
//! e = || y - y_ref ||_{L2(0,T)} / || y_ref ||_{L2(0,T)}
//! ```
//!
//! over the times both runs cover. Runs with different time steps are compared on the common
//! grid, the union of both runs' times: on each of its intervals both interpolants are linear,
//! so `d = y - y_ref` is linear and `int d^2 = h (d_0^2 + d_0 d_1 + d_1^2) / 3` exactly
//! (Simpson's rule, exact for the quadratic `d^2`). The quadrature thus adds no error of its
//! own and loses no sample of either run (interpolating the reference onto the run's coarser
//! grid alone would skip the reference's peaks between the run's steps; a midpoint or
//! trapezoidal sum on one grid would weight the two runs differently).

use std::cmp::Ordering;
use std::path::Path;

use crate::error::{Error, Result};
use crate::io::layout::{self, RunReader};

/// A scalar history: values `y[n]` at increasing times `t[n]`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct History {
    pub t: Vec<f64>,
    pub y: Vec<f64>,
}

/// The two contact histories of a run.
#[derive(Debug, Clone, Default)]
pub struct ContactHistories {
    /// Pressure of the lowest contact node (closest to the obstacle at t = 0).
    pub lowest_pressure: History,
    /// Total contact force `sum_q lambda_q` (the nodal forces' sum).
    pub total_force: History,
}

/// Reads the lowest node's pressure and the total contact force of a run's HDF5 file.
pub fn read_contact(path: &Path) -> Result<ContactHistories> {
    let curves = crate::post::read_curves(path)?;
    if curves.lowest_pressure.is_empty() {
        return Err(Error::Io(format!("{}: no lowest-node pressure history", path.display())));
    }
    let run = RunReader::open(path)?;
    let force = run.table(&layout::contact("force"))?;
    let total: Vec<f64> = force.rows().into_iter().map(|r| r.sum()).collect();
    let n = curves.time.len().min(curves.lowest_pressure.len()).min(total.len());
    let t = curves.time[..n].to_vec();
    Ok(ContactHistories {
        lowest_pressure: History { t: t.clone(), y: curves.lowest_pressure[..n].to_vec() },
        total_force: History { t, y: total[..n].to_vec() },
    })
}

/// Relative L2-in-time differences of a run's contact histories to a reference run's:
/// (lowest node's pressure, total contact force).
pub fn contact_errors(run: &ContactHistories, reference: &ContactHistories) -> Result<(f64, f64)> {
    Ok((
        relative_l2_in_time(&run.lowest_pressure, &reference.lowest_pressure)?,
        relative_l2_in_time(&run.total_force, &reference.total_force)?,
    ))
}

/// `|| y - y_ref ||_{L2} / || y_ref ||_{L2}` of the piecewise-linear interpolants over the
/// times both cover, integrated exactly on the union of the two time grids (module doc).
pub fn relative_l2_in_time(run: &History, reference: &History) -> Result<f64> {
    let (num, den) = l2_squared_in_time(run, reference)?;
    relative(num, den)
}

/// `(int (y - y_ref)^2 dt, int y_ref^2 dt)` over the common time interval, exact for the
/// piecewise-linear interpolants.
pub fn l2_squared_in_time(run: &History, reference: &History) -> Result<(f64, f64)> {
    for (h, what) in [(run, "run"), (reference, "reference")] {
        if h.t.len() < 2 || h.t.len() != h.y.len() {
            return Err(Error::Solver(format!(
                "the {what}'s history has {} times and {} values (at least 2 each, as many values as times)",
                h.t.len(),
                h.y.len()
            )));
        }
        if h.t.windows(2).any(|w| w[1].partial_cmp(&w[0]) != Some(Ordering::Greater)) {
            return Err(Error::Solver(format!("the {what}'s times do not increase")));
        }
    }
    let a = run.t[0].max(reference.t[0]);
    let b = run.t[run.t.len() - 1].min(reference.t[reference.t.len() - 1]);
    // Also when a bound is NaN.
    if b.partial_cmp(&a) != Some(Ordering::Greater) {
        return Err(Error::Solver(format!(
            "the run's and the reference's times do not overlap ({}..{} and {}..{})",
            run.t[0],
            run.t[run.t.len() - 1],
            reference.t[0],
            reference.t[reference.t.len() - 1]
        )));
    }
    // The union of both grids within [a, b]; times closer than a rounding error are one.
    let mut grid: Vec<f64> = run
        .t
        .iter()
        .chain(&reference.t)
        .copied()
        .filter(|&t| t >= a && t <= b)
        .chain([a, b])
        .collect();
    grid.sort_by(f64::total_cmp);
    let eps = 1e-12 * (b - a);
    grid.dedup_by(|x, y| (*x - *y).abs() <= eps);
    let (mut num, mut den) = (0.0, 0.0);
    let at = |h: &History, t: f64| interpolate(&h.t, &h.y, t);
    let (mut d0, mut r0) = (at(run, grid[0]) - at(reference, grid[0]), at(reference, grid[0]));
    for w in grid.windows(2) {
        let dt = w[1] - w[0];
        let r1 = at(reference, w[1]);
        let d1 = at(run, w[1]) - r1;
        num += dt * (d0 * d0 + d0 * d1 + d1 * d1) / 3.0;
        den += dt * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0;
        (d0, r0) = (d1, r1);
    }
    Ok((num, den))
}

fn relative(num: f64, den: f64) -> Result<f64> {
    if den > 0.0 {
        Ok((num / den).sqrt())
    } else if num == 0.0 {
        Ok(0.0)
    } else {
        Err(Error::Solver("the reference is identically zero: no relative error".into()))
    }
}

/// Linear interpolation of `(ts, ys)` at `t` (constant beyond the ends).
pub fn interpolate(ts: &[f64], ys: &[f64], t: f64) -> f64 {
    let n = ts.len().min(ys.len());
    if n == 0 {
        return f64::NAN;
    }
    if t <= ts[0] {
        return ys[0];
    }
    if t >= ts[n - 1] {
        return ys[n - 1];
    }
    let k = ts[..n].partition_point(|&s| s <= t);
    let (t0, t1, y0, y1) = (ts[k - 1], ts[k], ys[k - 1], ys[k]);
    if t1 == t0 {
        y1
    } else {
        y0 + (y1 - y0) * (t - t0) / (t1 - t0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn h(t: &[f64], y: &[f64]) -> History {
        History { t: t.to_vec(), y: y.to_vec() }
    }

    #[test]
    fn interpolation() {
        let ts = [0.0, 1.0, 2.0];
        let ys = [0.0, 10.0, 0.0];
        assert_eq!(interpolate(&ts, &ys, 0.5), 5.0);
        assert_eq!(interpolate(&ts, &ys, 1.0), 10.0);
        assert_eq!(interpolate(&ts, &ys, 1.75), 2.5);
        assert_eq!(interpolate(&ts, &ys, -1.0), 0.0);
        assert_eq!(interpolate(&ts, &ys, 3.0), 0.0);
    }

    #[test]
    fn linear_histories_on_different_grids() {
        // y = t on 3 points, y_ref = 2t on 5 points of [0, 1]: d = -t,
        // int d^2 = 1/3, int y_ref^2 = 4/3, e = sqrt(1/4) = 1/2 exactly.
        let run = h(&[0.0, 0.5, 1.0], &[0.0, 0.5, 1.0]);
        let refr = h(&[0.0, 0.25, 0.5, 0.75, 1.0], &[0.0, 0.5, 1.0, 1.5, 2.0]);
        let (num, den) = l2_squared_in_time(&run, &refr).unwrap();
        assert!((num - 1.0 / 3.0).abs() < 1e-15 && (den - 4.0 / 3.0).abs() < 1e-15);
        assert!((relative_l2_in_time(&run, &refr).unwrap() - 0.5).abs() < 1e-15);
        assert_eq!(relative_l2_in_time(&refr, &refr).unwrap(), 0.0);
    }

    #[test]
    fn a_peak_between_the_runs_steps_counts() {
        // The reference is the hat 0 -> 1 -> 0 on [0, 1/2, 1]; the run has steps of 1/3 and
        // samples the hat exactly (0, 2/3, 2/3, 0): its interpolant is a trapezoid that cuts
        // the peak. d = 2t - 2/3 on [1/3, 1/2] (and mirrored): int d^2 = 2 * 4 (1/6)^3 / 3
        // = 1/81; int hat^2 = 1/3; e = sqrt(3/81) = 1/sqrt(27). Sampling the reference at the
        // run's times only would give 0.
        let refr = h(&[0.0, 0.5, 1.0], &[0.0, 1.0, 0.0]);
        let run = h(&[0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0], &[0.0, 2.0 / 3.0, 2.0 / 3.0, 0.0]);
        let e = relative_l2_in_time(&run, &refr).unwrap();
        assert!((e - 1.0 / 27f64.sqrt()).abs() < 1e-14, "{e}");
        // Symmetric in the grids: the same value with the roles of the grids swapped.
        let (num, _) = l2_squared_in_time(&refr, &run).unwrap();
        assert!((num - 1.0 / 81.0).abs() < 1e-15);
    }

    #[test]
    fn only_the_common_interval_counts() {
        // The run stops at t = 1, the reference goes on to t = 2 with y_ref = 1: over [0, 1]
        // y = 0 gives e = 1; y = 1 gives 0.
        let refr = h(&[0.0, 1.0, 2.0], &[1.0, 1.0, 1.0]);
        assert_eq!(relative_l2_in_time(&h(&[0.0, 1.0], &[0.0, 0.0]), &refr).unwrap(), 1.0);
        assert_eq!(relative_l2_in_time(&h(&[0.0, 1.0], &[1.0, 1.0]), &refr).unwrap(), 0.0);
    }

    #[test]
    fn bad_histories_are_errors() {
        let ok = h(&[0.0, 1.0], &[1.0, 1.0]);
        assert!(relative_l2_in_time(&h(&[0.0], &[1.0]), &ok).is_err());
        assert!(relative_l2_in_time(&h(&[0.0, 1.0], &[1.0]), &ok).is_err());
        assert!(relative_l2_in_time(&h(&[1.0, 0.0], &[1.0, 1.0]), &ok).is_err());
        assert!(relative_l2_in_time(&h(&[2.0, 3.0], &[1.0, 1.0]), &ok).is_err());
        assert!(relative_l2_in_time(&ok, &h(&[0.0, 1.0], &[0.0, 0.0])).is_err());
    }
}
