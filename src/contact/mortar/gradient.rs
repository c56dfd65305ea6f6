//! The consistent contact force of an interface that follows the bodies: the gradient of
//! `Phi(x) = sum_q lambda_q g~_q(x)` with respect to every interface node's position, by
//! central differences of each slave facet's weighted gaps.
//!
//! The weighted gap `g~_q = int psi_q n_q . (x_m(projection) - x_s)` depends on the positions
//! through `D`, `M`, the dual functions (on the covered part of a facet), the projections, the
//! segment ends and the averaged normals. The force the mortar solver applies, `n_q (D lambda)_q`
//! on the slave node and `-n_q M_ql lambda_q` on the master nodes, is only the part of
//! `lambda_q grad g~_q` with all of those held fixed (the "main terms"); the rest carries the
//! pointwise gap and the misalignment of the two surfaces, and without it the contact does
//! work while the bodies slide (measured on `scenes/slide_off.toml`: 2.95e-3, 1.2% of the
//! energy, the same at tau/2 and tau/4, i.e. a force error, not a time error). With the whole
//! gradient at the step's midpoint, the work of a step in closed contact is
//! `lambda (g~(u^{n+1}) - g~(u^n)) + O(du^3) = O(du^3)`.
//!
//! Cost: per slave facet with a nonzero multiplier, `2 dim` evaluations of its integrals per
//! node that moves them (its nodes, their neighbours through the normals, the master facets
//! under it): surface-sized and only where the contact is.

use std::collections::HashMap;

use super::geom::*;
use super::interface::{facet_integrals, facet_normal, SurfaceFacet};
use super::search::{candidate_pairs, facet_aabb_2d, facet_aabb_3d, Aabb};
use super::facet::{Facet2, Facet3};
use crate::error::{Error, Result};

/// The slave side's facets around each slave node (for the nodal normals).
pub struct SlaveAdjacency {
    around: HashMap<usize, Vec<usize>>,
}

impl SlaveAdjacency {
    pub fn new(slave: &[SurfaceFacet]) -> SlaveAdjacency {
        let mut around: HashMap<usize, Vec<usize>> = HashMap::new();
        for (i, f) in slave.iter().enumerate() {
            for &v in &f.nodes {
                around.entry(v).or_default().push(i);
            }
        }
        SlaveAdjacency { around }
    }
}

/// The derivatives of one slave facet's contributions to its nodes' weighted gaps: for each
/// node `v` that moves them, `d g_(f,j) / d x_v` per facet node `j` (3 components; z = 0 in 2D).
#[derive(Debug, Clone, Default)]
pub struct FacetJacobian {
    pub moving: Vec<usize>,
    /// `[j][k]`: facet node `j`, moving node `k`.
    pub d: Vec<Vec<[f64; 3]>>,
}

/// The Jacobians of the slave facets `which` (indices into `slave`) at the positions `x`, by
/// central differences (step 1e-6 of the facet's size). `reach`: the search reach.
pub fn facet_jacobians(
    dim: usize,
    slave: &[SurfaceFacet],
    which: &[usize],
    master: &[SurfaceFacet],
    adjacency: &SlaveAdjacency,
    x: &dyn Fn(usize) -> [f64; 3],
    reach: f64,
) -> Result<Vec<FacetJacobian>> {
    let err = |e: GeomError| Error::Solver(format!("mortar (consistent force): {e}"));
    if which.is_empty() {
        return Ok(Vec::new());
    }
    let pos_at = |f: &SurfaceFacet, x: &dyn Fn(usize) -> [f64; 3]| -> Vec<[f64; 3]> {
        f.nodes.iter().map(|&v| x(v)).collect()
    };
    let aabb = |p: &[[f64; 3]], inflate: f64| -> Result<Aabb> {
        Ok(if dim == 2 {
            let q: Vec<Vec2> = p.iter().map(|a| [a[0], a[1]]).collect();
            facet_aabb_2d(&Facet2::from_nodes(&q, [0, 1]).map_err(err)?, inflate)
        } else {
            let idx: Vec<usize> = (0..p.len()).collect();
            facet_aabb_3d(&Facet3::from_nodes(p, &idx).map_err(err)?, inflate)
        })
    };
    let sboxes: Vec<Aabb> =
        which.iter().map(|&i| aabb(&pos_at(&slave[i], x), reach)).collect::<Result<_>>()?;
    let mboxes: Vec<Aabb> =
        master.iter().map(|f| aabb(&pos_at(f, x), reach)).collect::<Result<_>>()?;
    let mut candidates: Vec<Vec<&SurfaceFacet>> = vec![Vec::new(); which.len()];
    for (s, m) in candidate_pairs(&sboxes, &mboxes) {
        if slave[which[s]].pairs & master[m].pairs != 0 {
            candidates[s].push(&master[m]);
        }
    }
    let mut out = Vec::with_capacity(which.len());
    for (k, &fi) in which.iter().enumerate() {
        let f = &slave[fi];
        let nj = f.nodes.len();
        // The nodes that move the facet's gaps: its own, its nodes' neighbours (normals), the
        // masters under it.
        let mut moving: Vec<usize> = Vec::new();
        for &v in &f.nodes {
            for &g in &adjacency.around[&v] {
                moving.extend(&slave[g].nodes);
            }
        }
        // Only the masters it overlaps now (a step of 1e-6 of a facet makes no new overlap
        // but at a touching point, where the derivative is one-sided anyway).
        let nrm0: Vec<Vec3> = f
            .nodes
            .iter()
            .map(|v| {
                let mut s = [0.0; 3];
                for &g in &adjacency.around[v] {
                    let n = facet_normal(dim, &pos_at(&slave[g], x))?;
                    s = add3(s, scale3(1.0 / norm3(n), n));
                }
                Ok(scale3(1.0 / norm3(s), s))
            })
            .collect::<std::result::Result<_, GeomError>>()
            .map_err(err)?;
        let base = facet_integrals(dim, &pos_at(f, x), &nrm0, &candidates[k], &|m| pos_at(m, x))
            .map_err(err)?;
        let covered = base.as_ref().map_or(1.0, |(_, pairs)| {
            pairs.iter().map(|(_, p)| p.overlap_measure / p.slave_measure).sum::<f64>()
        });
        let overlapping: Vec<&SurfaceFacet> =
            base.map_or(Vec::new(), |(_, pairs)| pairs.iter().map(|(m, _)| *m).collect());
        for m in &overlapping {
            moving.extend(&m.nodes);
        }
        moving.sort_unstable();
        moving.dedup();
        let p0 = pos_at(f, x);
        let size = p0.iter().fold(0.0f64, |a, p| a.max(norm3(sub3(*p, p0[0]))));
        // The step: 1e-6 of the covered part (the dual functions of a partly covered facet
        // vary on its scale), at least 1e-9 of the facet.
        let h = 1e-6 * size * covered.clamp(1e-3, 1.0);
        let gaps = |moved: usize, c: usize, by: f64| -> Result<[f64; 4]> {
            let xp = |v: usize| {
                let mut p = x(v);
                if v == moved {
                    p[c] += by;
                }
                p
            };
            let nrm: Vec<Vec3> = f
                .nodes
                .iter()
                .map(|v| {
                    let mut s = [0.0; 3];
                    for &g in &adjacency.around[v] {
                        let n = facet_normal(dim, &pos_at(&slave[g], &xp))?;
                        s = add3(s, scale3(1.0 / norm3(n), n));
                    }
                    Ok(scale3(1.0 / norm3(s), s))
                })
                .collect::<std::result::Result<_, GeomError>>()
                .map_err(err)?;
            let pos = |m: &SurfaceFacet| pos_at(m, &xp);
            let found =
                facet_integrals(dim, &pos_at(f, &xp), &nrm, &overlapping, &pos).map_err(err)?;
            let mut g = [0.0; 4];
            if let Some((_, pairs)) = found {
                for (_, pi) in &pairs {
                    for j in 0..nj {
                        g[j] += pi.weighted_gap[j];
                    }
                }
            }
            Ok(g)
        };
        let mut d = vec![vec![[0.0; 3]; moving.len()]; nj];
        for (kk, &v) in moving.iter().enumerate() {
            for c in 0..dim {
                let (plus, minus) = (gaps(v, c, h)?, gaps(v, c, -h)?);
                for j in 0..nj {
                    d[j][kk][c] = (plus[j] - minus[j]) / (2.0 * h);
                }
            }
        }
        out.push(FacetJacobian { moving, d });
    }
    Ok(out)
}
