//! Errors against a reference run read from HDF5 files: the lowest contact node's pressure
//! history (contact scenes) or the displacement field at one time (other scenes).

use std::collections::HashMap;
use std::path::Path;

use crate::error::{Error, Result};

fn h5err(path: &Path, what: &str, e: impl std::fmt::Display) -> Error {
    Error::Io(format!("{}: {what}: {e}", path.display()))
}

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

struct Field {
    coords: Vec<[f64; 3]>,
    /// The displacement at the requested time, [nodes * dim].
    u: Vec<f64>,
    dim: usize,
}

fn read_field(path: &Path, time: f64) -> Result<Field> {
    let file = hdf5::File::open(path).map_err(|e| h5err(path, "open", e))?;
    let ds = |name: &str| file.dataset(name).map_err(|e| h5err(path, name, e));
    let times = ds("time")?.read_raw::<f64>().map_err(|e| h5err(path, "time", e))?;
    let tol = 1e-9 * time.abs().max(1e-300);
    let Some(k) = times.iter().position(|t| (t - time).abs() <= tol.max(1e-12 * time.abs())) else {
        return Err(Error::Io(format!(
            "{}: no displacement written at t = {time:e} (output.every must divide the error step)",
            path.display()
        )));
    };
    let d = ds("fields/displacement")?;
    let shape = d.shape();
    if shape.len() != 3 || k >= shape[0] {
        return Err(Error::Io(format!(
            "{}: fields/displacement has shape {shape:?}",
            path.display()
        )));
    }
    let all = d.read_raw::<f64>().map_err(|e| h5err(path, "fields/displacement", e))?;
    let (n, dim) = (shape[1], shape[2]);
    let u = all[k * n * dim..(k + 1) * n * dim].to_vec();
    let c = ds("mesh/coordinates")?.read_raw::<f64>().map_err(|e| h5err(path, "coordinates", e))?;
    let coords = c.chunks(3).map(|x| [x[0], x[1], x[2]]).collect::<Vec<_>>();
    if coords.len() != n {
        return Err(Error::Io(format!(
            "{}: {} coordinates for {n} nodes",
            path.display(),
            coords.len()
        )));
    }
    Ok(Field { coords, u, dim })
}

/// Relative nodal L2 (root mean square) difference of the displacement at `time`:
/// `|u - u_ref| / |u_ref|` over the run's nodes, each matched with the reference node at the
/// same coordinates (nested meshes, e.g. the same mesh or a refinement of it).
pub fn field_error(run: &Path, reference: &Path, time: f64) -> Result<f64> {
    let a = read_field(run, time)?;
    let b = read_field(reference, time)?;
    if a.dim != b.dim {
        return Err(Error::Io("the run and the reference differ in dimension".into()));
    }
    let scale =
        b.coords.iter().flat_map(|c| c.iter()).fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
    let key = |c: &[f64; 3]| {
        let q = |x: f64| (x / scale * 1e8).round() as i64;
        (q(c[0]), q(c[1]), q(c[2]))
    };
    let index: HashMap<(i64, i64, i64), usize> =
        b.coords.iter().enumerate().map(|(i, c)| (key(c), i)).collect();
    let dim = a.dim;
    let (mut num, mut den) = (0.0, 0.0);
    for (i, c) in a.coords.iter().enumerate() {
        let Some(&j) = index.get(&key(c)) else {
            return Err(Error::Io(format!(
                "{}: node at ({}, {}, {}) is not a node of the reference {} (meshes not nested)",
                run.display(),
                c[0],
                c[1],
                c[2],
                reference.display()
            )));
        };
        for d in 0..dim {
            let e = a.u[i * dim + d] - b.u[j * dim + d];
            num += e * e;
            den += b.u[j * dim + d] * b.u[j * dim + d];
        }
    }
    relative(num, den)
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
