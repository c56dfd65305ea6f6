//! Errors against a reference run read from HDF5 files: the lowest contact node's pressure
//! history (contact scenes; fields are compared in `fieldnorm`).

use std::path::Path;

use crate::error::{Error, Result};

/// Relative L2 difference over time of the lowest contact node's pressure,
/// `sqrt(sum_n (p(t_n) - p_ref(t_n))^2 / sum_n p_ref(t_n)^2)` over the run's times `t_n`,
/// with the reference interpolated linearly in time (exact when both share the time grid).
pub fn pressure_error(run: &Path, reference: &Path) -> Result<f64> {
    let a = crate::post::read_curves(run)?;
    let b = crate::post::read_curves(reference)?;
    if a.lowest_pressure.is_empty() {
        return Err(Error::Io(format!("{}: no lowest-node pressure history", run.display())));
    }
    if b.lowest_pressure.is_empty() {
        return Err(Error::Io(format!("{}: no lowest-node pressure history", reference.display())));
    }
    let bt = &b.time[..b.lowest_pressure.len().min(b.time.len())];
    let (mut num, mut den) = (0.0, 0.0);
    for (t, p) in a.time.iter().zip(&a.lowest_pressure) {
        let q = interpolate(bt, &b.lowest_pressure, *t);
        num += (p - q) * (p - q);
        den += q * q;
    }
    relative(num, den)
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
}
