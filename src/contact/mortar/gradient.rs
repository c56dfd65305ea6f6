//! The consistent contact force of an interface that follows the bodies: the gradient of
//! `Phi(x) = sum_q lambda_q g~_q(x)` with respect to every interface node's position, from the
//! Jacobian of each loaded slave facet's weighted gaps ([`facet_jacobians`]), by central
//! differences or, for fully covered facets, in closed form (`linearize.rs`,
//! `linearize3d.rs`). The solver keeps the Jacobians until the interface is evaluated again
//! and combines them with each round's multipliers.
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
//! Cost, by differences: per slave facet with a nonzero multiplier, `2 dim` evaluations of its
//! integrals per node that moves them (its nodes, their neighbours through the normals, the
//! master facets under it), of only the pairs a master node moves, and in 3D none for a
//! neighbour (the normals enter the gaps linearly there): surface-sized and only where the
//! contact is.

use std::collections::HashMap;

use super::dual::{dual_basis_2d, dual_basis_3d};
use super::facet::{Facet2, Facet3};
use super::geom::*;
use super::interface::{covered_part, facet_integrals, facet_normal, facet_pairs, SurfaceFacet};
use super::linearize::{mortar_pair_lin_2d, nodal_normals_lin_2d, Lin, PairIds2};
use super::linearize3d::{mortar_pair_lin_3d, nodal_normals_lin_3d, PairIds3};
use super::search::{candidate_pairs, facet_aabb_2d, facet_aabb_3d, Aabb};
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
/// A fully covered facet (`finite_differences` false) gets its Jacobian in closed form, a
/// partly covered one (dual basis on the covered part) by central differences, of the moving
/// nodes `column` takes only (the others' columns stay zero: ranks share a facet's columns).
#[allow(clippy::too_many_arguments)]
pub fn facet_jacobians(
    dim: usize,
    slave: &[SurfaceFacet],
    which: &[usize],
    master: &[SurfaceFacet],
    adjacency: &SlaveAdjacency,
    x: &dyn Fn(usize) -> [f64; 3],
    reach: f64,
    finite_differences: bool,
    column: &dyn Fn(&SurfaceFacet, usize) -> bool,
) -> Result<Vec<FacetJacobian>> {
    const FULL: f64 = 1.0 - 1e-9;
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
        if covered >= FULL && !finite_differences {
            // Fully covered: the facet's own dual basis, whose derivatives are built in closed
            // form (linearize.rs, linearize3d.rs).
            let mut jac = closed_form(dim, f, slave, adjacency, &overlapping, x).map_err(err)?;
            for (kk, &v) in jac.moving.iter().enumerate() {
                if !column(f, v) {
                    jac.d.iter_mut().for_each(|row| row[kk] = [0.0; 3]);
                }
            }
            out.push(jac);
            continue;
        }
        let p0 = pos_at(f, x);
        let size = p0.iter().fold(0.0f64, |a, p| a.max(norm3(sub3(*p, p0[0]))));
        // The step: 1e-6 of the covered part (the dual functions of a partly covered facet
        // vary on its scale), at least 1e-9 of the facet.
        let h = 1e-6 * size * covered.clamp(1e-3, 1.0);
        let normals_at = |xp: &dyn Fn(usize) -> [f64; 3]| -> Result<Vec<Vec3>> {
            f.nodes
                .iter()
                .map(|v| {
                    let mut s = [0.0; 3];
                    for &g in &adjacency.around[v] {
                        let n = facet_normal(dim, &pos_at(&slave[g], xp))?;
                        s = add3(s, scale3(1.0 / norm3(n), n));
                    }
                    Ok(scale3(1.0 / norm3(s), s))
                })
                .collect::<std::result::Result<_, GeomError>>()
                .map_err(err)
        };
        let sum_gaps =
            |found: Option<([f64; 4], Vec<(&SurfaceFacet, super::segment::PairIntegrals)>)>| {
                let mut g = [0.0; 4];
                if let Some((_, pairs)) = found {
                    for (_, pi) in &pairs {
                        for j in 0..nj {
                            g[j] += pi.weighted_gap[j];
                        }
                    }
                }
                g
            };
        // The facet's raw pairs at the base configuration: a master node moved changes only
        // the pairs of its facets.
        let (dual0, raw0) =
            facet_pairs(dim, &p0, &nrm0, &overlapping, &|m| pos_at(m, x)).map_err(err)?;
        // In 3D the nodal normals enter only the gaps, linearly: g_j = G_j . n_j with
        // G_j = int psi_j (x_m - x_s); a neighbour that moves only the normals needs no new
        // integrals.
        let g_vec: Option<Vec<[f64; 3]>> = if dim == 3 {
            let mut gv = vec![[0.0; 3]; nj];
            for c in 0..3 {
                let mut axis = [0.0; 3];
                axis[c] = 1.0;
                let axes = vec![axis; nj];
                let found = facet_integrals(dim, &p0, &axes, &overlapping, &|m| pos_at(m, x))
                    .map_err(err)?;
                let g = sum_gaps(found);
                for j in 0..nj {
                    gv[j][c] = g[j];
                }
            }
            Some(gv)
        } else {
            None
        };
        let own: std::collections::HashSet<usize> = f.nodes.iter().copied().collect();
        let mut slave_moving: std::collections::HashSet<usize> = std::collections::HashSet::new();
        for &v in &f.nodes {
            for &g in &adjacency.around[&v] {
                slave_moving.extend(&slave[g].nodes);
            }
        }
        let gaps = |moved: usize, c: usize, by: f64| -> Result<[f64; 4]> {
            let xp = |v: usize| {
                let mut p = x(v);
                if v == moved {
                    p[c] += by;
                }
                p
            };
            if !slave_moving.contains(&moved) {
                // A master node: only its facets' pairs change.
                let raw: Vec<_> = raw0
                    .iter()
                    .map(|(m, pi)| {
                        if m.nodes.contains(&moved) {
                            let (_, again) =
                                facet_pairs(dim, &p0, &nrm0, &[*m], &|m| pos_at(m, &xp))?;
                            Ok(again.into_iter().next())
                        } else {
                            Ok(Some((*m, *pi)))
                        }
                    })
                    .collect::<std::result::Result<Vec<_>, GeomError>>()
                    .map_err(err)?
                    .into_iter()
                    .flatten()
                    .collect();
                return Ok(sum_gaps(covered_part(&dual0, raw)));
            }
            let nrm = normals_at(&xp)?;
            if let (Some(gv), false) = (&g_vec, own.contains(&moved)) {
                let mut g = [0.0; 4];
                for j in 0..nj {
                    g[j] = dot3(gv[j], nrm[j]);
                }
                return Ok(g);
            }
            let pos = |m: &SurfaceFacet| pos_at(m, &xp);
            Ok(sum_gaps(
                facet_integrals(dim, &pos_at(f, &xp), &nrm, &overlapping, &pos).map_err(err)?,
            ))
        };
        let mut d = vec![vec![[0.0; 3]; moving.len()]; nj];
        for (kk, &v) in moving.iter().enumerate() {
            if !column(f, v) {
                continue; // another rank's column (zero here: the ranks' parts are summed)
            }
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

/// The Jacobian of a fully covered slave facet `f` in closed form: the involved nodes are the
/// facet's, its nodes' neighbours (through the averaged normals) and the overlapping masters';
/// `delta g_(f,j) = sum_m delta g_j(f, m)` from [`mortar_pair_lin_2d`] / [`mortar_pair_lin_3d`]
/// with the normals' derivatives from [`nodal_normals_lin_2d`] / [`nodal_normals_lin_3d`].
fn closed_form(
    dim: usize,
    f: &SurfaceFacet,
    slave: &[SurfaceFacet],
    adjacency: &SlaveAdjacency,
    masters: &[&SurfaceFacet],
    x: &dyn Fn(usize) -> [f64; 3],
) -> std::result::Result<FacetJacobian, GeomError> {
    let mut moving: Vec<usize> = f.nodes.clone();
    let mut around: Vec<usize> = Vec::new();
    for &v in &f.nodes {
        for &g in &adjacency.around[&v] {
            around.push(g);
            moving.extend(&slave[g].nodes);
        }
    }
    around.sort_unstable();
    around.dedup();
    for m in masters {
        moving.extend(&m.nodes);
    }
    // The facet's own nodes first (ids 0..n), then the others once each.
    let mut seen = std::collections::HashSet::new();
    moving.retain(|v| seen.insert(*v));
    let id: HashMap<usize, usize> = moving.iter().enumerate().map(|(k, &v)| (v, k)).collect();
    let coords: Vec<[f64; 3]> = moving.iter().map(|&v| x(v)).collect();
    let nj = f.nodes.len();
    let mut d = vec![vec![[0.0; 3]; moving.len()]; nj];
    let mut add = |j: usize, lin: &Lin| {
        for &((a, c), v) in lin.entries() {
            d[j][a][c] += v;
        }
    };
    if dim == 2 {
        let c2: Vec<Vec2> = coords.iter().map(|p| [p[0], p[1]]).collect();
        let facets: Vec<[usize; 2]> =
            around.iter().map(|&g| [id[&slave[g].nodes[0]], id[&slave[g].nodes[1]]]).collect();
        let normals = nodal_normals_lin_2d(&c2, &facets, false)?;
        let fs = Facet2::from_nodes(&c2, [0, 1])?;
        let dual = dual_basis_2d(&fs)?;
        let nrm = [normals[0].value, normals[1].value];
        let nlin = [normals[0].lin.clone(), normals[1].lin.clone()];
        for m in masters {
            let ids = PairIds2 { slave: [0, 1], master: [id[&m.nodes[0]], id[&m.nodes[1]]] };
            let fm = Facet2::from_nodes(&c2, ids.master)?;
            if let Some(p) = mortar_pair_lin_2d(&fs, &nrm, &dual, &fm, ids, &nlin)? {
                for j in 0..2 {
                    add(j, &p.weighted_gap[j]);
                }
            }
        }
    } else {
        let facets: Vec<Vec<usize>> =
            around.iter().map(|&g| slave[g].nodes.iter().map(|v| id[v]).collect()).collect();
        let normals = nodal_normals_lin_3d(&coords, &facets, false)?;
        let own: Vec<usize> = (0..nj).collect();
        let fs = Facet3::from_nodes(&coords, &own)?;
        let dual = dual_basis_3d(&fs)?;
        let nrm: Vec<Vec3> = (0..nj).map(|j| normals[j].value).collect();
        let nlin: Vec<_> = (0..nj).map(|j| normals[j].lin.clone()).collect();
        for m in masters {
            let mut ids = PairIds3 { slave: [0; 4], master: [0; 4] };
            for (k, slot) in ids.slave.iter_mut().enumerate().take(nj) {
                *slot = k;
            }
            let mids: Vec<usize> = m.nodes.iter().map(|v| id[v]).collect();
            ids.master[..mids.len()].copy_from_slice(&mids);
            let fm = Facet3::from_nodes(&coords, &mids)?;
            if let Some(p) = mortar_pair_lin_3d(&fs, &nrm, &dual, &fm, ids, &nlin)? {
                for j in 0..nj {
                    add(j, &p.weighted_gap[j]);
                }
            }
        }
    }
    Ok(FacetJacobian { moving, d })
}
