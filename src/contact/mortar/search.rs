//! Bounding boxes of facets and the bucket search for candidate slave/master pairs.

use super::facet::{Facet2, Facet3};
use super::geom::*;

// ------------------------------------------------------------------------------------------
// Bounding boxes and bucket search
// ------------------------------------------------------------------------------------------

/// Axis-aligned box `[min, max]` (closed). 2D boxes use `z in [-inflate, inflate]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// Closed boxes intersect iff `a.min_k <= b.max_k` and `b.min_k <= a.max_k` on every axis
    /// (touching counts).
    pub fn intersects(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.min[k] <= o.max[k] && o.min[k] <= self.max[k])
    }

    pub(crate) fn is_valid(&self) -> bool {
        all_finite(&self.min) && all_finite(&self.max) && (0..3).all(|k| self.min[k] <= self.max[k])
    }

    pub(crate) fn of_points(points: impl Iterator<Item = Vec3>, inflate: f64) -> Aabb {
        let mut b = Aabb { min: [f64::INFINITY; 3], max: [f64::NEG_INFINITY; 3] };
        for p in points {
            for (k, v) in p.iter().enumerate() {
                b.min[k] = b.min[k].min(*v);
                b.max[k] = b.max[k].max(*v);
            }
        }
        for k in 0..3 {
            b.min[k] -= inflate;
            b.max[k] += inflate;
        }
        b
    }
}

/// Box of a line facet's nodes inflated by `inflate` on every side (z range `[-inflate, inflate]`).
/// For a straight line the node box contains the facet.
pub fn facet_aabb_2d(facet: &Facet2, inflate: f64) -> Aabb {
    Aabb::of_points(facet.x.iter().map(|p| [p[0], p[1], 0.0]), inflate)
}

/// Box of a 3D facet's nodes inflated by `inflate` (a bilinear quad lies in the convex hull of
/// its nodes, so the node box contains the facet).
pub fn facet_aabb_3d(facet: &Facet3, inflate: f64) -> Aabb {
    Aabb::of_points(facet.nodes().iter().copied(), inflate)
}

/// All `(slave, master)` index pairs whose boxes intersect, sorted, via a uniform bucket grid.
///
/// Bucket size rule: the cell edge is the mean over the master boxes of their largest side, so
/// a typical master box touches at most 2 cells per axis; it is doubled until the grid over
/// the master boxes' union has at most `4 n_m + 64` cells (bounded memory with outliers);
/// an axis along which the union is flat gets one cell. Masters are entered into every cell
/// they touch; each slave box visits its cells, and candidates are tested exactly (deduped
/// with a per-slave stamp). Cost ~ O(n_s + n_m + pairs) for boxes of similar size.
/// Boxes with non-finite or inverted bounds are skipped (they intersect nothing).
pub fn candidate_pairs(slave_boxes: &[Aabb], master_boxes: &[Aabb]) -> Vec<(usize, usize)> {
    let masters: Vec<usize> =
        (0..master_boxes.len()).filter(|&i| master_boxes[i].is_valid()).collect();
    if masters.is_empty() || slave_boxes.is_empty() {
        return Vec::new();
    }
    let mut dom = Aabb { min: [f64::INFINITY; 3], max: [f64::NEG_INFINITY; 3] };
    let mut h = 0.0;
    for &i in &masters {
        let b = &master_boxes[i];
        let mut side: f64 = 0.0;
        for k in 0..3 {
            dom.min[k] = dom.min[k].min(b.min[k]);
            dom.max[k] = dom.max[k].max(b.max[k]);
            side = side.max(b.max[k] - b.min[k]);
        }
        h += side;
    }
    h /= masters.len() as f64;
    let ext: Vec3 = [dom.max[0] - dom.min[0], dom.max[1] - dom.min[1], dom.max[2] - dom.min[2]];
    if !(h > 0.0) {
        // All master boxes are points: fall back to the domain spread over the box count.
        h = ext.iter().fold(0.0f64, |a, &b| a.max(b)) / (masters.len() as f64).cbrt();
        if !(h > 0.0) {
            h = 1.0;
        }
    }
    let cap = 4.0 * masters.len() as f64 + 64.0;
    let mut dims = [1.0f64; 3];
    loop {
        for k in 0..3 {
            dims[k] = (ext[k] / h).ceil().max(1.0);
        }
        if dims[0] * dims[1] * dims[2] <= cap {
            break;
        }
        h *= 2.0;
    }
    let dims = [dims[0] as usize, dims[1] as usize, dims[2] as usize];
    let cell = |v: f64, k: usize| -> usize {
        (((v - dom.min[k]) / h).floor().max(0.0) as usize).min(dims[k] - 1)
    };
    let range = |b: &Aabb| -> ([usize; 3], [usize; 3]) {
        (
            [cell(b.min[0], 0), cell(b.min[1], 1), cell(b.min[2], 2)],
            [cell(b.max[0], 0), cell(b.max[1], 1), cell(b.max[2], 2)],
        )
    };
    let index = |i: usize, j: usize, k: usize| (k * dims[1] + j) * dims[0] + i;
    let mut cells: Vec<Vec<usize>> = vec![Vec::new(); dims[0] * dims[1] * dims[2]];
    for &m in &masters {
        let (lo, hi) = range(&master_boxes[m]);
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    cells[index(i, j, k)].push(m);
                }
            }
        }
    }
    let mut stamp = vec![usize::MAX; master_boxes.len()];
    let mut pairs = Vec::new();
    let mut found = Vec::new();
    for (s, sb) in slave_boxes.iter().enumerate() {
        if !sb.is_valid() || !sb.intersects(&dom) {
            continue;
        }
        let (lo, hi) = range(sb);
        found.clear();
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    for &m in &cells[index(i, j, k)] {
                        if stamp[m] != s {
                            stamp[m] = s;
                            if sb.intersects(&master_boxes[m]) {
                                found.push(m);
                            }
                        }
                    }
                }
            }
        }
        found.sort_unstable();
        pairs.extend(found.iter().map(|&m| (s, m)));
    }
    pairs
}
