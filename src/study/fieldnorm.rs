//! Errors of a run's displacement against a reference run's, integrated with quadrature:
//! `|| u_H - u_ref ||_{L2}` and `| u_H - u_ref |_{H1}` over the domain, relative to the
//! reference's norms. The integrals run over the reference's (finer) cells with an
//! order-4 rule; the run's solution is evaluated there by locating the run's cell that holds
//! each reference cell (meshes must be nested, e.g. the same mesh for a time study or a
//! uniform refinement for a space study) and inverting its map.

use std::path::Path;

use crate::error::{Error, Result};
use crate::fem::element::ElementKind;
use crate::fem::{kernels, shape};
use crate::io::layout::RunReader;

/// A mesh and one displacement field read from a run's HDF5 file.
pub struct FieldMesh {
    pub coords: Vec<[f64; 3]>,
    pub cells: Vec<(ElementKind, Vec<usize>)>,
    pub u: Vec<f64>,
    pub dim: usize,
}

/// Read the mesh and the displacement written at `time` (per-field axis, else /time).
pub fn read(path: &Path, time: f64) -> Result<FieldMesh> {
    let run = RunReader::open(path)?;
    let (u, dim) = run.field_at("displacement", time)?;
    Ok(FieldMesh { coords: run.coordinates()?, cells: run.cells()?, u, dim })
}

/// Reference coordinates of `x` in a cell, by Newton's method on the (bi/tri)linear map
/// (exact in one step for simplices). None if it does not converge.
fn inverse_map(kind: ElementKind, xy: &[[f64; 3]], x: [f64; 3], dim: usize) -> Option<[f64; 3]> {
    let n = kind.n_nodes();
    let mut xi = match kind {
        ElementKind::Tri3 => [1.0 / 3.0, 1.0 / 3.0, 0.0],
        ElementKind::Tet4 => [0.25, 0.25, 0.25],
        _ => [0.0; 3],
    };
    let mut nn = [0.0; 8];
    let mut dn = [[0.0; 3]; 8];
    for _ in 0..30 {
        shape::shape(kind, xi, &mut nn[..n]);
        shape::shape_grad_ref(kind, xi, &mut dn[..n]);
        let mut r = [0.0; 3];
        let mut j = [[0.0; 3]; 3];
        for a in 0..n {
            for i in 0..dim {
                r[i] += nn[a] * xy[a][i];
                for k in 0..dim {
                    j[i][k] += dn[a][k] * xy[a][i];
                }
            }
        }
        for i in 0..dim {
            r[i] = x[i] - r[i];
        }
        let step = solve(j, r, dim)?;
        let mut norm: f64 = 0.0;
        for i in 0..dim {
            xi[i] += step[i];
            norm = norm.max(step[i].abs());
        }
        // xi is O(1): 1e-10 is far below what matters and above the rounding of large coordinates.
        if norm < 1e-10 {
            return Some(xi);
        }
    }
    None
}

fn solve(j: [[f64; 3]; 3], r: [f64; 3], dim: usize) -> Option<[f64; 3]> {
    if dim == 2 {
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        if det.abs() < 1e-300 {
            return None;
        }
        return Some([
            (r[0] * j[1][1] - r[1] * j[0][1]) / det,
            (j[0][0] * r[1] - j[1][0] * r[0]) / det,
            0.0,
        ]);
    }
    let det = j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1])
        - j[0][1] * (j[1][0] * j[2][2] - j[1][2] * j[2][0])
        + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0]);
    if det.abs() < 1e-300 {
        return None;
    }
    let mut out = [0.0; 3];
    for c in 0..3 {
        let mut m = j;
        for i in 0..3 {
            m[i][c] = r[i];
        }
        out[c] = (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))
            / det;
    }
    Some(out)
}

fn inside(kind: ElementKind, xi: [f64; 3]) -> bool {
    let t = 1e-8;
    match kind {
        ElementKind::Tri3 => xi[0] >= -t && xi[1] >= -t && xi[0] + xi[1] <= 1.0 + t,
        ElementKind::Tet4 => {
            xi[0] >= -t && xi[1] >= -t && xi[2] >= -t && xi[0] + xi[1] + xi[2] <= 1.0 + t
        }
        ElementKind::Quad4 => xi[0].abs() <= 1.0 + t && xi[1].abs() <= 1.0 + t,
        ElementKind::Hex8 => xi.iter().all(|v| v.abs() <= 1.0 + t),
        _ => false,
    }
}

/// Buckets of cells on a uniform grid over the mesh's bounding box (by cell bounding boxes).
struct Locator {
    lo: [f64; 3],
    size: [f64; 3],
    n: [usize; 3],
    buckets: Vec<Vec<usize>>,
}

impl Locator {
    fn new(m: &FieldMesh) -> Locator {
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for x in &m.coords {
            for i in 0..3 {
                lo[i] = lo[i].min(x[i]);
                hi[i] = hi[i].max(x[i]);
            }
        }
        let per_axis = ((m.cells.len() as f64).powf(1.0 / m.dim as f64).ceil() as usize).max(1);
        let mut n = [1usize; 3];
        let mut size = [1.0; 3];
        for i in 0..m.dim {
            n[i] = per_axis;
            size[i] = ((hi[i] - lo[i]) / per_axis as f64).max(1e-300);
        }
        let mut buckets = vec![Vec::new(); n[0] * n[1] * n[2]];
        for (c, (_, nodes)) in m.cells.iter().enumerate() {
            let (mut a, mut b) = ([f64::MAX; 3], [f64::MIN; 3]);
            for &v in nodes {
                for i in 0..3 {
                    a[i] = a[i].min(m.coords[v][i]);
                    b[i] = b[i].max(m.coords[v][i]);
                }
            }
            let idx = |x: f64, i: usize| {
                (((x - lo[i]) / size[i]).floor().max(0.0) as usize).min(n[i] - 1)
            };
            for i0 in idx(a[0], 0)..=idx(b[0], 0) {
                for i1 in idx(a[1], 1)..=idx(b[1], 1) {
                    for i2 in idx(a[2], 2)..=idx(b[2], 2) {
                        buckets[(i2 * n[1] + i1) * n[0] + i0].push(c);
                    }
                }
            }
        }
        Locator { lo, size, n, buckets }
    }

    /// The cell containing x, and its reference coordinates.
    fn find(&self, m: &FieldMesh, x: [f64; 3]) -> Option<(usize, [f64; 3])> {
        let idx = |i: usize| {
            (((x[i] - self.lo[i]) / self.size[i]).floor().max(0.0) as usize).min(self.n[i] - 1)
        };
        let b = (idx(2) * self.n[1] + idx(1)) * self.n[0] + idx(0);
        for &c in &self.buckets[b] {
            let (kind, nodes) = &m.cells[c];
            let xy: Vec<[f64; 3]> = nodes.iter().map(|&v| m.coords[v]).collect();
            if let Some(xi) = inverse_map(*kind, &xy, x, m.dim) {
                if inside(*kind, xi) {
                    return Some((c, xi));
                }
            }
        }
        None
    }
}

/// Relative L2 and H1-seminorm differences `(||u - u_ref|| / ||u_ref||, |u - u_ref| / |u_ref|)`.
pub fn relative_errors(run: &FieldMesh, reference: &FieldMesh) -> Result<(f64, f64)> {
    if run.dim != reference.dim {
        return Err(Error::Io("the run and the reference differ in dimension".into()));
    }
    let dim = run.dim;
    let locator = Locator::new(run);
    let (mut l2, mut h1, mut r2, mut rh1) = (0.0, 0.0, 0.0, 0.0);
    let mut dn = [[0.0; 3]; 8];
    let mut nn = [0.0; 8];
    for (kind, nodes) in &reference.cells {
        let xy: Vec<[f64; 3]> = nodes.iter().map(|&v| reference.coords[v]).collect();
        let mut centroid = [0.0; 3];
        for p in &xy {
            for i in 0..3 {
                centroid[i] += p[i] / xy.len() as f64;
            }
        }
        let (cell, _) = locator.find(run, centroid).ok_or_else(|| {
            Error::Io(format!(
                "the reference cell at ({:.4}, {:.4}, {:.4}) lies in no cell of the run (meshes not nested?)",
                centroid[0], centroid[1], centroid[2]
            ))
        })?;
        let (ck, cnodes) = &run.cells[cell];
        let cxy: Vec<[f64; 3]> = cnodes.iter().map(|&v| run.coords[v]).collect();
        let cu: Vec<f64> = cnodes
            .iter()
            .flat_map(|&v| (0..dim).map(move |c| (v, c)))
            .map(|(v, c)| run.u[v * dim + c])
            .collect();
        let failed = std::cell::Cell::new(false);
        // The run's solution at a point of this reference cell: value and gradient.
        let coarse = |x: [f64; 3]| -> ([f64; 3], [[f64; 3]; 3]) {
            let mut val = [0.0; 3];
            let mut grad = [[0.0; 3]; 3];
            let Some(xi) = inverse_map(*ck, &cxy, x, dim) else {
                failed.set(true);
                return (val, grad);
            };
            let n = ck.n_nodes();
            let mut nn = [0.0; 8];
            let mut dn = [[0.0; 3]; 8];
            shape::shape(*ck, xi, &mut nn[..n]);
            shape::physical_gradients(*ck, &cxy, xi, &mut dn[..n]);
            for a in 0..n {
                for i in 0..dim {
                    val[i] += nn[a] * cu[a * dim + i];
                    for j in 0..dim {
                        grad[i][j] += dn[a][j] * cu[a * dim + i];
                    }
                }
            }
            (val, grad)
        };
        let ru: Vec<f64> = nodes
            .iter()
            .flat_map(|&v| (0..dim).map(move |c| (v, c)))
            .map(|(v, c)| reference.u[v * dim + c])
            .collect();
        let (a, b) = kernels::error_sq(*kind, &xy, &ru, &coarse, 4);
        if failed.get() {
            return Err(Error::Io(
                "cannot evaluate the run's solution inside a reference cell".into(),
            ));
        }
        l2 += a;
        h1 += b;
        let zero = |_: [f64; 3]| ([0.0; 3], [[0.0; 3]; 3]);
        let (c, d) = kernels::error_sq(*kind, &xy, &ru, &zero, 4);
        r2 += c;
        rh1 += d;
        let _ = (&mut dn, &mut nn);
    }
    if r2 <= 0.0 || rh1 <= 0.0 {
        return Err(Error::Io(
            "the reference displacement is zero: relative errors undefined".into(),
        ));
    }
    Ok(((l2 / r2).sqrt(), (h1 / rh1).sqrt()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(nx: usize, f: impl Fn(f64, f64) -> [f64; 2]) -> FieldMesh {
        let mut coords = Vec::new();
        let mut u = Vec::new();
        for j in 0..=nx {
            for i in 0..=nx {
                let (x, y) = (i as f64 / nx as f64, j as f64 / nx as f64);
                coords.push([x, y, 0.0]);
                u.extend(f(x, y));
            }
        }
        let id = |i: usize, j: usize| j * (nx + 1) + i;
        let mut cells = Vec::new();
        for j in 0..nx {
            for i in 0..nx {
                cells.push((
                    ElementKind::Quad4,
                    vec![id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)],
                ));
            }
        }
        FieldMesh { coords, cells, u, dim: 2 }
    }

    #[test]
    fn identical_fields_have_zero_error_and_bilinear_fields_transfer_exactly() {
        let f = |x: f64, y: f64| [1.0 + x * y, 2.0 * x - y];
        let (a, b) = relative_errors(&grid(4, f), &grid(4, f)).unwrap();
        assert!(a < 1e-14 && b < 1e-14);
        // A bilinear field is exact on the coarse mesh: no error against the fine one.
        let (a, b) = relative_errors(&grid(4, f), &grid(8, f)).unwrap();
        assert!(a < 1e-12 && b < 1e-12, "{a} {b}");
    }

    #[test]
    fn interpolation_error_converges_at_rates_2_and_1() {
        let f = |x: f64, y: f64| [(3.0 * x).sin() * y, (2.0 * y).cos() * x];
        let fine = grid(64, f);
        let e: Vec<(f64, f64)> =
            [4, 8, 16].iter().map(|&n| relative_errors(&grid(n, f), &fine).unwrap()).collect();
        for w in e.windows(2) {
            let (rl, rh) = ((w[0].0 / w[1].0).log2(), (w[0].1 / w[1].1).log2());
            assert!((rl - 2.0).abs() < 0.2 && (rh - 1.0).abs() < 0.2, "rates {rl} {rh}");
        }
    }
}
