//! The mortar interface of one contact pair: dual-mortar matrices `D` (diagonal) and `M`, the
//! averaged slave normals and the weighted gaps, on a given configuration (docs/method.md, two bodies).
//!
//! `D_qq = int_{Gamma_s} phi_q`, `M_ql = int_{Gamma_s} psi_q (phi_l o projection)`, both over
//! the part of the slave surface the master covers (a partly covered facet with the dual basis
//! biorthogonal there: [`covered_part`]),
//! `g_q = int psi_q n_q . (x_m(projection) - x_s)` (positive while the bodies are apart), so
//! that the weighted gap after an increment `du` is, to first order,
//! `g_q - n_q . (D_qq du_q - sum_l M_ql du_l)`.
//!
//! Distributed by the slave side: each rank integrates its share of the slave facets
//! ([`spread_facets`]: by a hash of their node tags, where every rank holds the pair's facets;
//! else the facets whose cell it owns) against the master facets its bucket search finds, and
//! the ranks sum their parts (O(slave nodes) replicated data, the contact nodes' share, like the
//! obstacle contact's). Every rank holds the pair's facets and nodes today, so the master facets
//! are at hand; with a pair side spread over more than the surface a rank fetches the master
//! facets within its slave facets' boxes.

use std::collections::HashMap;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::dual::{dual_basis_2d, dual_basis_3d, invert_small, DualBasis};
use super::facet::{Facet2, Facet3};
use super::geom::*;
use super::normals::{averaged_normals_2d, NormalKind};
use super::search::{candidate_pairs, facet_aabb_2d, facet_aabb_3d, Aabb};
use super::segment::{mortar_pair_2d, mortar_pair_3d, PairIntegrals};
use crate::error::{Error, Result};
use crate::mesh::topology::{boundary_group, cells_near, facet_key, facet_map};
use crate::mesh::Mesh;
use crate::partition::Partition;

/// One boundary facet of a contact group: its mesh nodes, ordered so that its normal points
/// out of its body, the cell it bounds, and the pairs it belongs to (bit `i` for pair `i`; a
/// slave facet is integrated only against master facets of a pair it shares).
#[derive(Debug, Clone)]
pub struct SurfaceFacet {
    pub nodes: Vec<usize>,
    pub cell: usize,
    pub pairs: u64,
    /// The rank that integrates the facet ([`SurfaceFacet::is_mine`]; `usize::MAX`: its
    /// cell's owner), and the hash of its node tags that chose it ([`spread_facets`]).
    pub worker: usize,
    pub key: u64,
}

impl SurfaceFacet {
    /// Whether this rank integrates the facet (and differentiates its integrals): the rank
    /// its `worker` names, else the owner of its cell.
    pub fn is_mine(&self, part: &Partition) -> bool {
        match self.worker {
            usize::MAX => part.cell_rank[self.cell] as usize == part.rank,
            w => w == part.rank,
        }
    }
}

/// Spreads the slave facets' integration over the ranks: each facet to the rank its nodes'
/// gmsh tags hash to, the same on every rank (a contact zone lies on one rank's side of the
/// partition, whose rank would otherwise do all of its mortar work while the others wait: on
/// the oblique balls one rank owned every slave facet). Only where every rank holds the same
/// slave facets (checked: their number and tags agree), else left with their cells' owners.
/// Collective.
pub fn spread_facets(world: &SimpleCommunicator, mesh: &Mesh, facets: &mut [SurfaceFacet]) {
    let key = |f: &SurfaceFacet| -> u64 {
        let mut tags: Vec<u64> = f.nodes.iter().map(|&v| mesh.node_tags[v]).collect();
        tags.sort_unstable();
        // FNV-1a over the sorted tags: the same facet, the same key, on every rank.
        tags.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &t| (h ^ t).wrapping_mul(0x100_0000_01b3))
    };
    let keys: Vec<u64> = facets.iter().map(key).collect();
    let sum = keys.iter().fold(0u64, |a, &k| a.wrapping_add(k >> 11));
    let mine = [facets.len() as f64, sum as f64];
    let (mut lo, mut hi) = ([0.0; 2], [0.0; 2]);
    world.all_reduce_into(&mine[..], &mut lo[..], SystemOperation::min());
    world.all_reduce_into(&mine[..], &mut hi[..], SystemOperation::max());
    if lo != hi {
        return;
    }
    let size = world.size() as u64;
    for (f, k) in facets.iter_mut().zip(keys) {
        f.worker = (k % size) as usize;
        f.key = k;
    }
}

/// Whether this rank takes the derivative columns of facet `f` by its node `v` (gmsh tag
/// `tag`): where the facets are spread, the columns are too (a contact zone has a few loaded
/// facets, each with some twenty moving nodes); else its worker takes them all.
pub fn column_is_mine(f: &SurfaceFacet, tag: u64, part: &Partition) -> bool {
    if f.worker == usize::MAX {
        return f.is_mine(part);
    }
    let h = (f.key ^ tag).wrapping_mul(0x9e37_79b9_7f4a_7c15);
    ((h >> 32) % part.size as u64) as usize == part.rank
}

/// The facets of a contact boundary group, oriented outwards (gmsh does not promise an
/// orientation for boundary elements): the facet normal must point away from its cell's
/// centroid. Errors name the group.
pub fn oriented_facets(mesh: &Mesh, group: &str) -> Result<Vec<SurfaceFacet>> {
    let elems = boundary_group(mesh, group)?;
    let facets = facet_map(mesh, &cells_near(mesh, &elems));
    let mut out = Vec::with_capacity(elems.len());
    for e in &elems {
        let all: Vec<usize> = (0..e.kind.n_nodes()).collect();
        let cell = facets[&facet_key(&e.nodes(), &all)].0;
        let mut nodes = e.nodes().to_vec();
        let x: Vec<[f64; 3]> = nodes.iter().map(|&v| mesh.coords[v]).collect();
        let n = facet_normal(mesh.dim, &x)
            .map_err(|err| Error::Mesh(format!("contact group \"{group}\": {err}")))?;
        let centre = centroid(&x);
        let inside = centroid(&mesh.element_coords(&mesh.cells[cell]));
        if dot3(n, sub3(centre, inside)) < 0.0 {
            // Keep the first node (a quad stays a quad), reverse the cycle; a line swaps.
            if nodes.len() == 2 {
                nodes.reverse();
            } else {
                nodes[1..].reverse();
            }
        }
        out.push(SurfaceFacet { nodes, cell, pairs: 1, worker: usize::MAX, key: 0 });
    }
    Ok(out)
}

fn centroid(x: &[[f64; 3]]) -> [f64; 3] {
    let s = x.iter().fold([0.0; 3], |a, p| add3(a, *p));
    scale3(1.0 / x.len() as f64, s)
}

/// The (unnormalized) normal of a facet at its centre, in 3D components (z = 0 in 2D).
pub(crate) fn facet_normal(dim: usize, x: &[[f64; 3]]) -> std::result::Result<Vec3, GeomError> {
    let idx: Vec<usize> = (0..x.len()).collect();
    if dim == 2 {
        let p: Vec<Vec2> = x.iter().map(|p| [p[0], p[1]]).collect();
        let n = Facet2::from_nodes(&p, [0, 1])?.normal();
        Ok([n[0], n[1], 0.0])
    } else {
        let f = Facet3::from_nodes(x, &idx)?;
        Ok(f.normal(f.centre_param()))
    }
}

/// The candidate facet pairs of the last bucket search, kept while the interface moves less
/// than `margin` (the caller decides: `reuse`), and how many searches were made.
#[derive(Debug, Clone, Default)]
pub struct SearchState {
    /// How far beyond the reach the last search looked.
    pub margin: f64,
    /// Take the kept pairs (filtered by the reach) instead of searching.
    pub reuse: bool,
    /// `(owned slave facet, master facet)` within reach + margin at the last search.
    pub pairs: Option<Vec<(usize, usize)>>,
    pub searches: usize,
}

/// The mortar data of one slave/master pair, identical on every rank.
#[derive(Debug, Clone, Default)]
pub struct MortarInterface {
    /// Slave nodes (mesh indices, ascending).
    pub slave: Vec<usize>,
    /// Master nodes (mesh indices, ascending).
    pub master: Vec<usize>,
    /// `D_qq` per slave node.
    pub d: Vec<f64>,
    /// `(q, l, M_ql)`: slave index, master index (into `slave`, `master`), sorted.
    pub m: Vec<(u32, u32, f64)>,
    /// Averaged unit slave normals (towards the master).
    pub normals: Vec<[f64; 3]>,
    /// Weighted gaps `g_q`.
    pub gap: Vec<f64>,
}

impl MortarInterface {
    /// Evaluates the pair on the configuration `x` (the position of a mesh node, e.g.
    /// reference + `u`; asked only for the pair's nodes) with the normal field `normal`.
    /// `reach`: master facets farther than this from a slave facet are not considered (the
    /// search inflates the facets' boxes by it). Collective. Also returns this rank's wall
    /// time of the bucket search (seconds).
    #[allow(clippy::too_many_arguments)]
    pub fn build_timed(
        world: &SimpleCommunicator,
        mesh: &Mesh,
        part: &Partition,
        slave_facets: &[SurfaceFacet],
        master_facets: &[SurfaceFacet],
        x: &dyn Fn(usize) -> [f64; 3],
        reach: f64,
        normal: NormalKind,
        search: &mut SearchState,
        only: Option<&[bool]>,
    ) -> Result<(MortarInterface, f64)> {
        let err = |e: GeomError| Error::Solver(format!("mortar: {e}"));
        let dim = mesh.dim;
        let slave = sorted_nodes(slave_facets);
        let master = sorted_nodes(master_facets);
        let s_of: HashMap<usize, u32> =
            slave.iter().enumerate().map(|(k, &v)| (v, k as u32)).collect();
        let m_of: HashMap<usize, u32> =
            master.iter().enumerate().map(|(k, &v)| (v, k as u32)).collect();
        let mine: Vec<&SurfaceFacet> = slave_facets.iter().filter(|f| f.is_mine(part)).collect();
        let pos = |f: &SurfaceFacet| -> Vec<[f64; 3]> { f.nodes.iter().map(|&v| x(v)).collect() };
        let ns = slave.len();

        // A facet that cannot be evaluated on one rank fails the evaluation on every rank
        // (a flag in the next reduction, then the message): the caller may go back.
        let mut failed: Option<String> = None;
        let fail = |failed: Option<String>| -> Error {
            Error::Geometry(crate::comm::first_failure(world, failed).unwrap_or_default())
        };

        // Averaged nodal normals: sum of the adjacent facets' unit normals.
        let mut nsum = vec![0.0; 3 * ns + 1];
        for f in &mine {
            let n = match facet_normal(dim, &pos(f)) {
                Ok(n) => scale3(1.0 / norm3(n), n),
                Err(e) => {
                    failed = Some(format!("mortar: {e}"));
                    nsum[3 * ns] = 1.0;
                    break;
                }
            };
            for &v in &f.nodes {
                let q = s_of[&v] as usize;
                for c in 0..3 {
                    nsum[3 * q + c] += n[c];
                }
            }
        }
        let mut total = vec![0.0; 3 * ns + 1];
        world.all_reduce_into(&nsum[..], &mut total[..], SystemOperation::sum());
        if total[3 * ns] > 0.0 {
            return Err(fail(failed));
        }
        let normals: Vec<[f64; 3]> = (0..ns)
            .map(|q| {
                let n = [total[3 * q], total[3 * q + 1], total[3 * q + 2]];
                scale3(1.0 / norm3(n), n)
            })
            .collect();
        let mut search_seconds = 0.0;
        let normals = match normal {
            NormalKind::Slave => normals,
            NormalKind::Average if dim == 2 => {
                let t0 = std::time::Instant::now();
                let n = averaged(&slave, &normals, slave_facets, master_facets, &m_of, x, reach)
                    .map_err(err)?;
                search_seconds += t0.elapsed().as_secs_f64();
                n
            }
            NormalKind::Average => {
                return Err(Error::Solver(
                    "-mortar_normal average is built for 2D meshes only".into(),
                ))
            }
        };

        // Candidate pairs by bucket search over the boxes of the facets.
        let boxes = |fs: &[&SurfaceFacet], reach: f64| -> Result<Vec<Aabb>> {
            fs.iter()
                .map(|f| {
                    let p = pos(f);
                    Ok(if dim == 2 {
                        let q: Vec<Vec2> = p.iter().map(|a| [a[0], a[1]]).collect();
                        facet_aabb_2d(&Facet2::from_nodes(&q, [0, 1]).map_err(err)?, reach)
                    } else {
                        let idx: Vec<usize> = (0..p.len()).collect();
                        facet_aabb_3d(&Facet3::from_nodes(&p, &idx).map_err(err)?, reach)
                    })
                })
                .collect()
        };
        let t_search = std::time::Instant::now();
        let masters: Vec<&SurfaceFacet> = master_facets.iter().collect();
        // (The master side's boxes are the same on every rank, and so is their error.)
        let mboxes = boxes(&masters, reach)?;
        let pairs = match boxes(&mine, reach) {
            Ok(sboxes) => {
                if !search.reuse || search.pairs.is_none() {
                    // Search with the boxes inflated by the margin too: the pairs found hold
                    // every pair within reach until a node has moved farther than the margin.
                    let wide = reach + search.margin;
                    let mine_wide = boxes(&mine, wide)?;
                    let mut found = candidate_pairs(&mine_wide, &boxes(&masters, wide)?);
                    found.retain(|&(s, m)| mine[s].pairs & masters[m].pairs != 0);
                    search.pairs = Some(found);
                    search.searches += 1;
                }
                // Those within reach now: the pairs a fresh search would find.
                let mut pairs = search.pairs.clone().expect("searched above");
                pairs.retain(|&(s, m)| sboxes[s].intersects(&mboxes[m]));
                pairs
            }
            Err(e) => {
                failed = Some(match e {
                    Error::Solver(m) => m,
                    other => other.to_string(),
                });
                Vec::new()
            }
        };
        search_seconds += t_search.elapsed().as_secs_f64();

        // D per owned slave facet, M and the weighted gaps per overlapping pair (`only`: of
        // the slave facets it marks; the others' nodes then have partial sums).
        let index_of: HashMap<*const SurfaceFacet, usize> =
            slave_facets.iter().enumerate().map(|(i, f)| (f as *const _, i)).collect();
        let mut d = vec![0.0; ns];
        let mut gap = vec![0.0; ns];
        let mut m: HashMap<(u32, u32), f64> = HashMap::new();
        let mut k = 0;
        for (si, f) in mine.iter().enumerate() {
            if failed.is_some() {
                break;
            }
            let qs: Vec<usize> = f.nodes.iter().map(|v| s_of[v] as usize).collect();
            let mut candidates = Vec::new();
            while k < pairs.len() && pairs[k].0 == si {
                candidates.push(masters[pairs[k].1]);
                k += 1;
            }
            if only.is_some_and(|o| !o[index_of[&(*f as *const _)]]) {
                continue;
            }
            let nrm: Vec<Vec3> = qs.iter().map(|&q| normals[q]).collect();
            let (d_e, found) = match facet_integrals(dim, &pos(f), &nrm, &candidates, &pos) {
                Ok(Some(x)) => x,
                Ok(None) => continue,
                Err(e) => {
                    failed = Some(format!("mortar: {e}"));
                    break;
                }
            };
            for (j, &q) in qs.iter().enumerate() {
                d[q] += d_e[j];
            }
            for (mf, pi) in found {
                for (j, &q) in qs.iter().enumerate() {
                    gap[q] += pi.weighted_gap[j];
                    for (l, &v) in mf.nodes.iter().enumerate() {
                        *m.entry((q as u32, m_of[&v])).or_insert(0.0) += pi.m[j][l];
                    }
                }
            }
        }

        // Sum the ranks' parts: D and the gaps by reduction, M's entries gathered and merged.
        let mut dg = d;
        dg.extend_from_slice(&gap);
        dg.push(if failed.is_some() { 1.0 } else { 0.0 });
        let mut dg_all = vec![0.0; dg.len()];
        world.all_reduce_into(&dg[..], &mut dg_all[..], SystemOperation::sum());
        if dg_all[2 * ns] > 0.0 {
            return Err(fail(failed));
        }
        let (d, gap) = (dg_all[..ns].to_vec(), dg_all[ns..2 * ns].to_vec());
        let mut local: Vec<(u32, u32, f64)> = m.into_iter().map(|((q, l), v)| (q, l, v)).collect();
        local.sort_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)));
        let m = merge(&gather(world, &local));
        Ok((MortarInterface { slave, master, d, m, normals, gap }, search_seconds))
    }

    /// `sum_l M_ql` per slave node (equals `D_qq` where the master covers the node's support).
    pub fn m_row_sums(&self) -> Vec<f64> {
        let mut s = vec![0.0; self.slave.len()];
        for &(q, _, v) in &self.m {
            s[q as usize] += v;
        }
        s
    }
}

/// One slave facet (nodes at `p`, nodal normals `nrm`) against its candidate master facets
/// (positions by `pos`): its `D_e` and the integrals of the master facets it overlaps, on its
/// covered part ([`covered_part`]); `None` when too little of it is covered.
#[allow(clippy::type_complexity)]
pub(crate) fn facet_integrals<'a>(
    dim: usize,
    p: &[[f64; 3]],
    nrm: &[Vec3],
    candidates: &[&'a SurfaceFacet],
    pos: &dyn Fn(&SurfaceFacet) -> Vec<[f64; 3]>,
) -> std::result::Result<Option<([f64; 4], Vec<(&'a SurfaceFacet, PairIntegrals)>)>, GeomError> {
    let (dual, found) = facet_pairs(dim, p, nrm, candidates, pos)?;
    Ok(covered_part(&dual, found))
}

/// The facet's own dual basis and its integrals against each candidate it overlaps, before the
/// covered part is taken ([`facet_integrals`] = this, then [`covered_part`]).
#[allow(clippy::type_complexity)]
pub(crate) fn facet_pairs<'a>(
    dim: usize,
    p: &[[f64; 3]],
    nrm: &[Vec3],
    candidates: &[&'a SurfaceFacet],
    pos: &dyn Fn(&SurfaceFacet) -> Vec<[f64; 3]>,
) -> std::result::Result<(DualBasis, Vec<(&'a SurfaceFacet, PairIntegrals)>), GeomError> {
    let mut found = Vec::new();
    if dim == 2 {
        let q: Vec<Vec2> = p.iter().map(|a| [a[0], a[1]]).collect();
        let fs = Facet2::from_nodes(&q, [0, 1])?;
        let dual = dual_basis_2d(&fs)?;
        let n2 = [[nrm[0][0], nrm[0][1]], [nrm[1][0], nrm[1][1]]];
        for &mf in candidates {
            let q: Vec<Vec2> = pos(mf).iter().map(|a| [a[0], a[1]]).collect();
            let fm = Facet2::from_nodes(&q, [0, 1])?;
            if let Some(pi) = mortar_pair_2d(&fs, &n2, &dual, &fm)? {
                found.push((mf, pi));
            }
        }
        Ok((dual, found))
    } else {
        let idx: Vec<usize> = (0..p.len()).collect();
        let fs = Facet3::from_nodes(p, &idx)?;
        let dual = dual_basis_3d(&fs)?;
        for &mf in candidates {
            let pm = pos(mf);
            let idx: Vec<usize> = (0..pm.len()).collect();
            let fm = Facet3::from_nodes(&pm, &idx)?;
            if let Some(pi) = mortar_pair_3d(&fs, nrm, &dual, &fm)? {
                found.push((mf, pi));
            }
        }
        Ok((dual, found))
    }
}

/// Below this covered fraction a slave facet is left out (its Gram matrix on the covered part
/// is too ill-conditioned to invert): the force it would carry is at most this fraction of
/// its share.
const MIN_COVERED: f64 = 1e-5;
/// From this covered fraction on a facet counts as fully covered (the sum of its overlaps
/// equals its measure to round-off).
const FULL_COVERED: f64 = 1.0 - 1e-9;

/// A slave facet's `D_e` and its pairs' integrals, on the part of the facet that the master
/// covers (Popp et al. 2013's consistent dual basis): fully covered, the facet's own dual
/// basis and `d_j = int_e phi_j`; partly covered, the dual basis biorthogonal on the covered
/// part, `A = diag(p) G^{-1}` with `G = int_cov phi phi^T`, `p = int_cov phi`, and `d_j = p_j`,
/// so that `sum_l M_jl = D_jj` still holds at every node (a rigid translation of both bodies
/// leaves every weighted gap unchanged) and a node's share falls continuously to zero as the
/// master slides off its support. `None`: too little covered (`MIN_COVERED`), the facet
/// carries nothing.
pub(crate) fn covered_part<'a>(
    dual: &DualBasis,
    found: Vec<(&'a SurfaceFacet, PairIntegrals)>,
) -> Option<([f64; 4], Vec<(&'a SurfaceFacet, PairIntegrals)>)> {
    let whole = found.first()?.1.slave_measure;
    let covered: f64 = found.iter().map(|(_, p)| p.overlap_measure).sum();
    let fraction = covered / whole;
    if !(fraction >= MIN_COVERED) {
        return None;
    }
    if fraction >= FULL_COVERED {
        return Some((dual.d, found));
    }
    let n = dual.n;
    let (mut g, mut p) = ([[0.0; 4]; 4], [0.0; 4]);
    for (_, pi) in &found {
        for k in 0..n {
            p[k] += pi.phi_integral[k];
            for i in 0..n {
                g[k][i] += pi.phi_phi[k][i];
            }
        }
    }
    let ginv = invert_small(&g, n).ok()?;
    let mut a = [[0.0; 4]; 4];
    for i in 0..n {
        for k in 0..n {
            a[i][k] = p[i] * ginv[i][k];
        }
    }
    Some((p, found.into_iter().map(|(f, pi)| (f, pi.with_dual(&a))).collect()))
}

/// The averaged normals (2D) of the slave nodes `slave` with slave normals `ns`: each node's
/// ray is tried against the master lines of its own pairs within `reach` (every rank does every
/// slave node: the result is the same everywhere, O(slave nodes) work).
fn averaged(
    slave: &[usize],
    ns: &[[f64; 3]],
    slave_facets: &[SurfaceFacet],
    master_facets: &[SurfaceFacet],
    m_of: &HashMap<usize, u32>,
    x: &dyn Fn(usize) -> [f64; 3],
    reach: f64,
) -> std::result::Result<Vec<[f64; 3]>, GeomError> {
    let p2 = |v: usize| -> Vec2 { [x(v)[0], x(v)[1]] };
    let mut nm = vec![[0.0; 2]; m_of.len()];
    let mut lines = Vec::with_capacity(master_facets.len());
    for f in master_facets {
        let line = Facet2::from_nodes(&[p2(f.nodes[0]), p2(f.nodes[1])], [0, 1])?;
        let n = line.normal();
        let n = scale2(1.0 / norm2(n), n);
        for v in &f.nodes {
            let m = &mut nm[m_of[v] as usize];
            *m = add2(*m, n);
        }
        lines.push(line);
    }
    let unit = |n: Vec2| scale2(1.0 / norm2(n), n);
    let lines: Vec<(Facet2, [Vec2; 2])> = (lines.into_iter().zip(master_facets))
        .map(|(l, f)| {
            (l, [unit(nm[m_of[&f.nodes[0]] as usize]), unit(nm[m_of[&f.nodes[1]] as usize])])
        })
        .collect();
    // Each slave node's pairs: those of its facets.
    let s_of: HashMap<usize, usize> = slave.iter().enumerate().map(|(k, &v)| (v, k)).collect();
    let mut mask = vec![0u64; slave.len()];
    for f in slave_facets {
        for v in &f.nodes {
            mask[s_of[v]] |= f.pairs;
        }
    }
    let points: Vec<Aabb> =
        slave.iter().map(|&v| Aabb::of_points(std::iter::once(x(v)), reach)).collect();
    let boxes: Vec<Aabb> = lines.iter().map(|(l, _)| facet_aabb_2d(l, 0.0)).collect();
    let mut candidates = vec![Vec::new(); slave.len()];
    for (q, k) in candidate_pairs(&points, &boxes) {
        if mask[q] & master_facets[k].pairs != 0 {
            candidates[q].push(k);
        }
    }
    let xs: Vec<Vec2> = slave.iter().map(|&v| p2(v)).collect();
    let n2: Vec<Vec2> = ns.iter().map(|n| [n[0], n[1]]).collect();
    Ok(averaged_normals_2d(&xs, &n2, &lines, &candidates)
        .into_iter()
        .map(|n| [n[0], n[1], 0.0])
        .collect())
}

fn sorted_nodes(facets: &[SurfaceFacet]) -> Vec<usize> {
    let mut v: Vec<usize> = facets.iter().flat_map(|f| f.nodes.iter().copied()).collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// Every rank's `(q, l, value)` entries, in rank order.
pub(crate) fn gather(
    world: &SimpleCommunicator,
    local: &[(u32, u32, f64)],
) -> Vec<(u32, u32, f64)> {
    let keys: Vec<u64> = local.iter().map(|e| (u64::from(e.0) << 32) | u64::from(e.1)).collect();
    let vals: Vec<f64> = local.iter().map(|e| e.2).collect();
    let all_keys = crate::comm::gather_all(world, &keys);
    let all_vals = crate::comm::gather_all(world, &vals);
    all_keys.iter().zip(&all_vals).map(|(&k, &v)| ((k >> 32) as u32, k as u32, v)).collect()
}

/// Entries sorted by (q, l), duplicates (the same pair from two ranks) summed.
pub(crate) fn merge(entries: &[(u32, u32, f64)]) -> Vec<(u32, u32, f64)> {
    let mut e = entries.to_vec();
    e.sort_by(|a, b| (a.0, a.1).cmp(&(b.0, b.1)));
    let mut out: Vec<(u32, u32, f64)> = Vec::with_capacity(e.len());
    for (q, l, v) in e {
        match out.last_mut() {
            Some(last) if last.0 == q && last.1 == l => last.2 += v,
            _ => out.push((q, l, v)),
        }
    }
    out
}
