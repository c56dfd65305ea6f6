//! Which normal field the weighted gaps and the 2D projections use.
//!
//! The default is the slave side's averaged nodal normals (Popp, Gee, Wall 2009). On curved
//! interfaces these tilt away from the direction in which the two surfaces face each other:
//! two mirrored discs then measure their gap along the slave arc's normal to the mirrored arc,
//! not across the symmetry plane, and differ from the disc on the plane by O((a/R)^2).
//! The averaged normal halves the two sides' views: at slave node `q`,
//!
//! ```text
//! n_q = (n_s,q - n_m(P_q)) / |n_s,q - n_m(P_q)|,   P_q = x_q + t n_q on the master surface,
//! ```
//!
//! with `n_m` the master's averaged nodal normals interpolated linearly along the master line
//! (pointing out of the master body, so `-n_m` points towards it). `P_q` depends on `n_q`: a
//! fixed point, found by iteration from `n_s,q` (a contraction with factor about the gap
//! times the curvature; at most 20 iterations, to 1e-14). For mirror-symmetric sides the fixed
//! point is normal to the mirror plane, projections map mirrored points onto each other, `M`
//! is `D` on mirrored facets (biorthogonality) and `g_q / D_qq` is twice the node's distance to
//! the mirror: the pair is then the same discrete problem as one side on a rigid plane.
//! 2D only: in 3D the projection runs along the auxiliary plane's normal (the slave facet's),
//! whose measure a tilted normal would change.

use super::facet::Facet2;
use super::geom::*;
use super::segment::project_onto_master_2d;

/// `-mortar_normal slave|average`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum NormalKind {
    /// The slave side's averaged nodal normals (the default).
    #[default]
    Slave,
    /// Halfway between the slave normal and the master normal across from it (2D).
    Average,
}

impl NormalKind {
    pub fn parse(s: &str) -> Option<NormalKind> {
        match s {
            "slave" => Some(NormalKind::Slave),
            "average" => Some(NormalKind::Average),
            _ => None,
        }
    }
}

/// The averaged normals of slave nodes `xs` (2D points) from their slave normals `ns`, against
/// master lines `lines` (node positions, oriented with the master body on their left, as
/// `Facet2`) with the master nodal normals `nm` at their ends. `candidates[q]`: the lines
/// worth trying for node q. A node whose ray meets no line keeps its slave normal.
pub fn averaged_normals_2d(
    xs: &[Vec2],
    ns: &[Vec2],
    lines: &[(Facet2, [Vec2; 2])],
    candidates: &[Vec<usize>],
) -> Vec<Vec2> {
    let mut out = Vec::with_capacity(xs.len());
    for q in 0..xs.len() {
        let mut n = ns[q];
        for _ in 0..20 {
            // The nearest crossing of the line through x_q along n with a candidate master line.
            let mut best: Option<(f64, Vec2)> = None;
            for &k in &candidates[q] {
                let (line, normals) = &lines[k];
                let Some(eta) = project_onto_master_2d(line, xs[q], n) else { continue };
                if !(-1.0 - 1e-12..=1.0 + 1e-12).contains(&eta) {
                    continue;
                }
                let t = dot2(sub2(line.position(eta), xs[q]), n).abs();
                let (a, b) = (0.5 * (1.0 - eta), 0.5 * (1.0 + eta));
                let nm = add2(scale2(a, normals[0]), scale2(b, normals[1]));
                if best.is_none_or(|(tb, _)| t < tb) {
                    best = Some((t, nm));
                }
            }
            let Some((_, nm)) = best else { break };
            let len = norm2(nm);
            let mid = sub2(ns[q], scale2(1.0 / len, nm));
            let lm = norm2(mid);
            if !(len > 0.0 && lm > 1e-12) {
                break;
            }
            let next = scale2(1.0 / lm, mid);
            let change = norm2(sub2(next, n));
            n = next;
            if !(change > 1e-14) {
                break;
            }
        }
        out.push(n);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(a: Vec2, b: Vec2) -> Facet2 {
        Facet2::from_nodes(&[a, b], [0, 1]).unwrap()
    }

    /// Mirrored arcs: the slave node on the upper arc y = 0.05 + x^2/16 (normal tilted), the
    /// master arc its mirror; the averaged normal is vertical to 1e-14, the slave's is not.
    #[test]
    fn mirrored_arcs_give_the_normal_of_the_mirror_plane() {
        let y = |x: f64| 0.05 + x * x / 16.0;
        // Upper arc (slave), normal pointing down and outwards from its curvature centre.
        let xq = [0.3, y(0.3)];
        let slope = 0.3 / 8.0;
        let ns = {
            let n = [slope, -1.0];
            scale2(1.0 / norm2(n), n)
        };
        // The mirrored master: lines through (x, -y(x)), body below, nodal normals mirrored.
        let pts: Vec<Vec2> = (0..7).map(|i| -0.3 + 0.15 * i as f64).map(|x| [x, -y(x)]).collect();
        // The master's outward normal at x: (x/8, 1)/|.|, the mirror of the slave's (x/8, -1).
        let nrm = |x: f64| {
            let n = [x / 8.0, 1.0];
            scale2(1.0 / norm2(n), n)
        };
        // Body below a line from a to b: b to the left of a (n = (t_y, -t_x) points up).
        let lines: Vec<(Facet2, [Vec2; 2])> =
            pts.windows(2).map(|w| (line(w[1], w[0]), [nrm(w[1][0]), nrm(w[0][0])])).collect();
        let all: Vec<usize> = (0..lines.len()).collect();
        let n = averaged_normals_2d(&[xq], &[ns], &lines, &[all]);
        // n_s - n_m at the mirror point is (0, -2)/|.|: straight down.
        assert!(n[0][0].abs() < 1e-14, "averaged normal {:?}", n[0]);
        assert!((n[0][1] + 1.0).abs() < 1e-14, "averaged normal {:?}", n[0]);
        assert!(ns[0].abs() > 0.03, "the slave normal is tilted: {ns:?}");
    }
}
