//! The mass-free surface layer (Hager & Wohlmuth 2009; docs/method.md, the mass-free layer): the modified
//! mass matrix `M_H = sum_K E_K^T M_K E_K`, where `E_K` is the identity on elements away from
//! the contact boundary and, on the elements of the contact layer `Omega_C1` (cells with at
//! least one contact node), replaces nodal values by combinations of values at non-contact
//! nodes. Contact DOFs then get exactly zero rows and columns; `M_H` stays symmetric PSD and
//! conserves the total mass (variant 1 also the first and second moments).
//!
//! - [`Variant::Zero`] (Q^0): each contact node `q` of `K` takes the mean of the non-contact
//!   vertices of `K` joined to `q` by an edge of `K` (all non-contact vertices of `K` if there
//!   is none); non-contact nodes keep their value. Sources: the non-contact nodes of `K`.
//! - [`Variant::One`] (Q^1): `K` gets a partner `K1` outside the layer and every node of `K`
//!   that is not a vertex of `K1` gets the affine extrapolation from `K1`: barycentric
//!   coordinates w.r.t. `K1` if it is a simplex, else w.r.t. the simplex of the `d + 1`
//!   vertices of `K1` nearest to the node (skipping vertices that would make it flat). Sources:
//!   the nodes of `K1` (which already include `K`'s vertices shared with `K1`).
//!
//! Partner rule (variant 1), deterministic:
//! 1. among the facet neighbours of `K` that are not in the layer, the one whose shared facet
//!    is farthest from `K`'s contact nodes (distance from the centroid of `K`'s contact nodes
//!    to the centroid of the shared facet; near-ties, within `1e-10` of `K`'s diameter, go to
//!    the lowest cell index). On a structured layer of quads/hexes this is the element across
//!    the facet opposite `Gamma_C` (the only facet neighbour outside the layer);
//! 2. else the non-layer cell sharing at least one vertex with `K` whose centroid is nearest to
//!    `K`'s centroid (near-ties to the lowest cell index);
//! 3. else an error suggesting variant 0.
//!
//! Every source node set is the node set of one cell (`K` for variant 0, `K1` for variant 1),
//! so `E_K^T M_K E_K` only couples node pairs that `M` already couples: the sparsity pattern of
//! `M` is not widened (also when the partner shares only a vertex with `K`).
//!
//! Everything is computed from the global mesh in a fixed order with index tie-breaks, so every
//! MPI rank that holds the same mesh builds the same layer.

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use crate::error::{Error, Result};
use crate::fem::element::ElementKind;
use crate::fem::kernels::{mass, MAX_DOFS, MAX_NODES};
use crate::fem::shape::det3;
use crate::mesh::topology::{boundary_group, facet_key, facet_map, node_cells, FacetCells};
use crate::mesh::Mesh;

/// Which interpolation operator defines the layer (docs/method.md, the mass-free layer).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variant {
    /// Q^0: donors inside the element (exact for constants).
    Zero,
    /// Q^1: affine extension from a partner element outside the layer (exact for affine
    /// functions: conserves total mass, first and second moments).
    One,
}

/// `E_K` as a sparse map from the element's nodes to "source" nodes: the modified element
/// contributes `E^T M_K E`, where `E` is `(n_local x n_src)` per component (the same for every
/// displacement component, i.e. `E ⊗ I_dim`).
#[derive(Debug, Clone, PartialEq)]
pub struct ElementMap {
    /// Global node indices the element's values come from (its non-contact nodes for variant
    /// 0; the nodes of the partner K1, which include K's vertices shared with K1, for variant
    /// 1) - sorted and unique.
    pub sources: Vec<usize>,
    /// Dense row-major `(n_local x sources.len())` weights; row i = local node i of the cell.
    /// Every row sums to one (up to rounding).
    pub weights: Vec<f64>,
}

impl ElementMap {
    /// Weight of global source node `src` in the value of local node `local` (0 if `src` is
    /// not a source).
    pub fn weight(&self, local: usize, src: usize) -> f64 {
        match self.sources.binary_search(&src) {
            Ok(j) => self.weights[local * self.sources.len() + j],
            Err(_) => 0.0,
        }
    }
}

/// The contact layer and the per-element interpolation operators `E_K`.
#[derive(Debug, Clone, PartialEq)]
pub struct MassFreeLayer {
    pub variant: Variant,
    /// Sorted node indices on the closure of the contact boundary (C_h).
    pub contact_nodes: Vec<usize>,
    /// `is_contact[node]`
    pub is_contact: Vec<bool>,
    /// Indices of cells with at least one contact node (Omega_C1), sorted.
    pub layer_cells: Vec<usize>,
    /// Variant 1: partner cell K1 of each layer cell (same order as `layer_cells`).
    /// Empty for variant 0.
    pub partners: Vec<usize>,
    /// E_K for each layer cell (same order as `layer_cells`).
    pub maps: Vec<ElementMap>,
    /// `cell -> index into layer_cells`, `u32::MAX` for cells outside the layer.
    cell_layer: Vec<u32>,
    /// The whole layer's numbers of contact nodes and cells (over all ranks' parts).
    totals: (usize, usize),
}

/// Relative tolerance for near-ties in the partner choice (times the element's diameter).
const TIE_TOL: f64 = 1e-10;
/// A vertex is accepted into the extrapolation simplex of a quad/hex partner if the simplex
/// so far keeps a relative volume (Gram determinant normalized by the edge lengths, in [0, 1]:
/// the sine of the angle in 2D) of at least this much.
const FLAT_TOL: f64 = 0.1;
/// Below this relative volume even the best simplex counts as degenerate.
const DEGENERATE_TOL: f64 = 1e-12;

fn dist2(a: &[f64; 3], b: &[f64; 3], d: usize) -> f64 {
    (0..d).map(|i| (a[i] - b[i]) * (a[i] - b[i])).sum()
}

fn centroid(mesh: &Mesh, nodes: &[usize]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for &n in nodes {
        for i in 0..3 {
            c[i] += mesh.coords[n][i];
        }
    }
    let s = 1.0 / nodes.len() as f64;
    c.map(|v| v * s)
}

fn diameter(mesh: &Mesh, nodes: &[usize], d: usize) -> f64 {
    let mut m: f64 = 0.0;
    for &a in nodes {
        for &b in nodes {
            m = m.max(dist2(&mesh.coords[a], &mesh.coords[b], d));
        }
    }
    m.sqrt()
}

/// Determinant of the k x k Gram matrix of the vectors `v[..k]` (first `d` components).
fn gram_det(v: &[[f64; 3]], k: usize, d: usize) -> f64 {
    let mut g = [[0.0; 3]; 3];
    for i in 0..k {
        for j in 0..k {
            g[i][j] = (0..d).map(|c| v[i][c] * v[j][c]).sum();
        }
    }
    match k {
        1 => g[0][0],
        2 => g[0][0] * g[1][1] - g[0][1] * g[1][0],
        _ => det3(&g),
    }
}

/// Relative volume of the simplex `pts` (in [0, 1]): sqrt(Gram det) / product of edge lengths
/// from `pts[0]`.
fn relative_volume(pts: &[[f64; 3]], d: usize) -> f64 {
    let k = pts.len() - 1;
    let mut v = [[0.0; 3]; 3];
    let mut norms = 1.0;
    for i in 0..k {
        for c in 0..d {
            v[i][c] = pts[i + 1][c] - pts[0][c];
        }
        norms *= (0..d).map(|c| v[i][c] * v[i][c]).sum::<f64>().sqrt();
    }
    if norms == 0.0 {
        return 0.0;
    }
    gram_det(&v, k, d).max(0.0).sqrt() / norms
}

/// Barycentric coordinates of `x` w.r.t. the simplex `p[0..=d]` (extrapolated outside).
fn barycentric(p: &[[f64; 3]], x: &[f64; 3], d: usize) -> [f64; 4] {
    let mut a = [[0.0; 3]; 3];
    let mut r = [0.0; 3];
    for i in 0..d {
        for k in 0..d {
            a[i][k] = p[k + 1][i] - p[0][i];
        }
        r[i] = x[i] - p[0][i];
    }
    let mut lam = [0.0; 3];
    if d == 2 {
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        lam[0] = (r[0] * a[1][1] - a[0][1] * r[1]) / det;
        lam[1] = (a[0][0] * r[1] - r[0] * a[1][0]) / det;
    } else {
        let det = det3(&a);
        for k in 0..3 {
            let mut ak = a;
            for i in 0..3 {
                ak[i][k] = r[i];
            }
            lam[k] = det3(&ak) / det;
        }
    }
    let mut c = [0.0; 4];
    c[0] = 1.0 - lam[..d].iter().sum::<f64>();
    c[1..=d].copy_from_slice(&lam[..d]);
    c
}

impl MassFreeLayer {
    /// Builds the layer for the boundary group `contact_group` (dimension `mesh.dim - 1`).
    ///
    /// Errors: the group is missing, has the wrong dimension, is empty, or is not on the
    /// boundary of the body (`Error::Scene`, or `Error::Mesh` for a group element that is no
    /// facet of any cell); variant 0: a layer cell has no non-contact vertex; variant 1: a
    /// layer cell has no partner outside the layer, or a degenerate partner (`Error::Mesh`).
    pub fn build(mesh: &Mesh, contact_group: &str, variant: Variant) -> Result<MassFreeLayer> {
        MassFreeLayer::build_along(mesh, &[contact_group], variant)
    }

    /// The layer along several contact boundary groups (both sides of a two-body contact).
    pub fn build_along(
        mesh: &Mesh,
        contact_groups: &[&str],
        variant: Variant,
    ) -> Result<MassFreeLayer> {
        let joined = contact_groups.join("\" and \"");
        let mut elems = Vec::new();
        for g in contact_groups {
            elems.extend(boundary_group(mesh, g)?);
        }
        let mut is_contact = vec![false; mesh.n_nodes()];
        for e in &elems {
            for n in e.nodes() {
                is_contact[n] = true;
            }
        }
        MassFreeLayer::from_contact_nodes(mesh, is_contact, |_| true, variant, &joined)
    }

    /// The layer of a rank's part of the mesh (own cells and the ghost layer), its contact
    /// nodes flagged (`is_contact`, from the gathered contact surface): layer cells are the
    /// cells with a contact node, and `E_K` is built for the cells `mapped(c)` says (the own
    /// ones: every cell sharing a node with an own cell is local, so their partners are found
    /// as on the whole mesh). Other layer cells get an empty map. `name` is for messages.
    pub fn from_contact_nodes(
        mesh: &Mesh,
        is_contact: Vec<bool>,
        mapped: impl Fn(usize) -> bool,
        variant: Variant,
        name: &str,
    ) -> Result<MassFreeLayer> {
        let contact_nodes: Vec<usize> = (0..mesh.n_nodes()).filter(|&v| is_contact[v]).collect();
        let layer_cells: Vec<usize> = (0..mesh.cells.len())
            .filter(|&c| mesh.cells[c].nodes().iter().any(|&n| is_contact[n]))
            .collect();
        let mut cell_layer = vec![u32::MAX; mesh.cells.len()];
        let mut near = vec![false; mesh.n_nodes()];
        for (l, &c) in layer_cells.iter().enumerate() {
            cell_layer[c] = l as u32;
            for n in mesh.cells[c].nodes() {
                near[n] = true;
            }
        }
        // The cells a layer cell's facets can be shared with (`cells_near` of the facets).
        let near_cells: Vec<usize> = (0..mesh.cells.len())
            .filter(|&c| mesh.cells[c].nodes().iter().any(|&n| near[n]))
            .collect();
        let facets = facet_map(mesh, &near_cells);

        let mut maps = Vec::with_capacity(layer_cells.len());
        let mut partners = Vec::new();
        let unmapped = || ElementMap { sources: Vec::new(), weights: Vec::new() };
        match variant {
            Variant::Zero => {
                for &c in &layer_cells {
                    maps.push(if mapped(c) {
                        map_variant0(mesh, c, &is_contact, name)?
                    } else {
                        unmapped()
                    });
                }
            }
            Variant::One => {
                let node_cells = node_cells(mesh);
                partners.reserve(layer_cells.len());
                for &c in &layer_cells {
                    if !mapped(c) {
                        partners.push(usize::MAX);
                        maps.push(unmapped());
                        continue;
                    }
                    let k1 =
                        partner(mesh, c, &is_contact, &cell_layer, &facets, &node_cells, name)?;
                    partners.push(k1);
                    maps.push(map_variant1(mesh, c, k1)?);
                }
            }
        }

        Ok(MassFreeLayer {
            variant,
            totals: (contact_nodes.len(), layer_cells.len()),
            contact_nodes,
            is_contact,
            layer_cells,
            partners,
            maps,
            cell_layer,
        })
    }

    /// Index of `cell` in `layer_cells` (and `maps`, `partners`), or None outside the layer.
    #[inline]
    pub fn layer_index(&self, cell: usize) -> Option<usize> {
        match self.cell_layer.get(cell) {
            Some(&l) if l != u32::MAX => Some(l as usize),
            _ => None,
        }
    }

    /// `E_K` of `cell`, or None if the cell is not in the layer.
    pub fn map(&self, cell: usize) -> Option<&ElementMap> {
        self.layer_index(cell).map(|l| &self.maps[l])
    }

    /// Variant 1: the partner `K1` of `cell`; None outside the layer or for variant 0.
    pub fn partner(&self, cell: usize) -> Option<usize> {
        self.layer_index(cell).and_then(|l| self.partners.get(l).copied())
    }

    /// The modified element mass for a cell: if the cell is not in the layer, returns None
    /// (use the standard `M_K`, `nodes` and `out` untouched); else fills `nodes` with the
    /// global source nodes and `out` with `E^T M_K E` expanded to `(sources.len()*dim)^2`
    /// row-major, interlaced dofs (`node*dim + comp`). The result is exactly symmetric.
    pub fn element_matrix(
        &self,
        mesh: &Mesh,
        cell: usize,
        rho: f64,
        nodes: &mut Vec<usize>,
        out: &mut Vec<f64>,
    ) -> Option<()> {
        let map = self.map(cell)?;
        let e = &mesh.cells[cell];
        let kind = e.kind;
        let n = kind.n_nodes();
        let d = kind.dim();
        let nd = n * d;
        let mut coords = [[0.0; 3]; MAX_NODES];
        for (a, &g) in e.nodes().iter().enumerate() {
            coords[a] = mesh.coords[g];
        }
        let mut mk = [0.0; MAX_DOFS * MAX_DOFS];
        mass(kind, &coords[..n], rho, &mut mk[..nd * nd]);
        // The element mass is (scalar mass) ⊗ I_d.
        let ns = map.sources.len();
        let w = &map.weights;
        // t = Ms E  (n x ns)
        let mut t = [0.0; MAX_NODES * MAX_NODES];
        for a in 0..n {
            for s in 0..ns {
                let mut v = 0.0;
                for b in 0..n {
                    v += mk[(a * d) * nd + b * d] * w[b * ns + s];
                }
                t[a * ns + s] = v;
            }
        }
        nodes.clear();
        nodes.extend_from_slice(&map.sources);
        let nsd = ns * d;
        out.clear();
        out.resize(nsd * nsd, 0.0);
        for s in 0..ns {
            for r in s..ns {
                let mut v = 0.0;
                for a in 0..n {
                    v += w[a * ns + s] * t[a * ns + r];
                }
                for i in 0..d {
                    out[(s * d + i) * nsd + r * d + i] = v;
                    out[(r * d + i) * nsd + s * d + i] = v;
                }
            }
        }
        Some(())
    }

    /// Variant 1 only (empty for variant 0): the non-contact nodes all of whose cells are in
    /// the layer. Their values are extrapolated over on every cell and they are nobody's
    /// source (partners are outside the layer), so their rows and columns of `M_H` are zero
    /// like the contact nodes': `M_H` is then singular on non-contact DOFs (fine for the
    /// implicit midpoint rule if the stiffness is definite there, but worth a warning).
    /// Empty on all test meshes; possible on meshes only one or two elements thick at
    /// `Gamma_C`.
    pub fn massless_nodes(&self, mesh: &Mesh) -> Vec<usize> {
        if self.variant == Variant::Zero {
            return Vec::new();
        }
        let mut outside = vec![false; mesh.n_nodes()];
        for (c, e) in mesh.cells.iter().enumerate() {
            if self.cell_layer[c] == u32::MAX {
                for g in e.nodes() {
                    outside[g] = true;
                }
            }
        }
        (0..mesh.n_nodes()).filter(|&g| !self.is_contact[g] && !outside[g]).collect()
    }

    pub fn n_layer_cells(&self) -> usize {
        self.totals.1
    }

    pub fn n_contact_nodes(&self) -> usize {
        self.totals.0
    }

    /// Set the whole layer's numbers of contact nodes and cells (a rank's part of the layer
    /// counts its own ghosts and misses other ranks' cells).
    pub fn set_totals(&mut self, contact_nodes: usize, layer_cells: usize) {
        self.totals = (contact_nodes, layer_cells);
    }
}

/// Variant 0: donors inside K.
fn map_variant0(mesh: &Mesh, c: usize, is_contact: &[bool], name: &str) -> Result<ElementMap> {
    let e = &mesh.cells[c];
    let nodes = e.nodes();
    let n = nodes.len();
    let free: Vec<usize> = (0..n).filter(|&a| !is_contact[nodes[a]]).collect();
    if free.is_empty() {
        return Err(Error::Mesh(format!(
            "element {} ({}) has all its vertices on the contact boundary \"{name}\": the mesh \
             is too coarse at the contact boundary for the mass-free layer (refine it there)",
            e.tag,
            e.kind.name()
        )));
    }
    let mut sources: Vec<usize> = free.iter().map(|&a| nodes[a]).collect();
    sources.sort_unstable();
    let ns = sources.len();
    let col = |g: usize| sources.binary_search(&g).expect("source node");
    let mut weights = vec![0.0; n * ns];
    for a in 0..n {
        if !is_contact[nodes[a]] {
            weights[a * ns + col(nodes[a])] = 1.0;
            continue;
        }
        let mut donors: Vec<usize> = e
            .kind
            .edges()
            .iter()
            .filter_map(|&[i, j]| {
                if i == a {
                    Some(j)
                } else if j == a {
                    Some(i)
                } else {
                    None
                }
            })
            .filter(|&b| !is_contact[nodes[b]])
            .collect();
        if donors.is_empty() {
            donors = free.clone();
        }
        let wt = 1.0 / donors.len() as f64;
        for b in donors {
            weights[a * ns + col(nodes[b])] += wt;
        }
    }
    Ok(ElementMap { sources, weights })
}

/// Variant 1 partner of layer cell `c` (see the module docs for the rule).
fn partner(
    mesh: &Mesh,
    c: usize,
    is_contact: &[bool],
    cell_layer: &[u32],
    facets: &FacetCells,
    node_cells: &(Vec<usize>, Vec<usize>),
    name: &str,
) -> Result<usize> {
    let e = &mesh.cells[c];
    let nodes = e.nodes();
    let d = mesh.dim;
    let tol = TIE_TOL * diameter(mesh, &nodes, d);
    let contact: Vec<usize> = nodes.iter().copied().filter(|&g| is_contact[g]).collect();
    let cc = centroid(mesh, &contact);

    // 1. Facet neighbours outside the layer, in ascending cell order.
    let mut cands: Vec<(usize, f64)> = Vec::new();
    for f in e.kind.facets() {
        let Some(&(c0, c1, _)) = facets.get(&facet_key(&nodes, f)) else { continue };
        let other = if c0 == c { c1 } else { c0 };
        if other == usize::MAX || cell_layer[other] != u32::MAX {
            continue;
        }
        let fnodes: Vec<usize> = f.iter().map(|&a| nodes[a]).collect();
        let score = dist2(&cc, &centroid(mesh, &fnodes), d).sqrt();
        cands.push((other, score));
    }
    cands.sort_by_key(|&(o, _)| o);
    cands.dedup_by_key(|&mut (o, _)| o);
    let mut best: Option<(usize, f64)> = None;
    for &(o, s) in &cands {
        if best.is_none_or(|(_, bs)| s > bs + tol) {
            best = Some((o, s));
        }
    }
    if let Some((o, _)) = best {
        return Ok(o);
    }

    // 2. Non-layer cells sharing a vertex, nearest centroid.
    let (start, list) = node_cells;
    let mut cands: Vec<usize> = nodes
        .iter()
        .flat_map(|&g| list[start[g]..start[g + 1]].iter().copied())
        .filter(|&o| cell_layer[o] == u32::MAX)
        .collect();
    cands.sort_unstable();
    cands.dedup();
    let ck = centroid(mesh, &nodes);
    let mut best: Option<(usize, f64)> = None;
    for &o in &cands {
        let s = dist2(&ck, &centroid(mesh, &mesh.cells[o].nodes()), d).sqrt();
        if best.is_none_or(|(_, bs)| s < bs - tol) {
            best = Some((o, s));
        }
    }
    if let Some((o, _)) = best {
        return Ok(o);
    }
    Err(Error::Mesh(format!(
        "element {} ({}) of the contact layer of \"{name}\" has no partner element for the \
         variant-1 mass-free layer: every element touching it also touches the contact \
         boundary; refine the mesh near the contact boundary or use variant 0",
        e.tag,
        e.kind.name()
    )))
}

/// Variant 1: affine extension of the values on the partner `k1` to the nodes of `c`.
fn map_variant1(mesh: &Mesh, c: usize, k1: usize) -> Result<ElementMap> {
    let e = &mesh.cells[c];
    let p = &mesh.cells[k1];
    let d = mesh.dim;
    let pn = p.nodes();
    let mut sources: Vec<usize> = pn.to_vec();
    sources.sort_unstable();
    let ns = sources.len();
    let col = |g: usize| sources.binary_search(&g).expect("source node");
    let n = e.kind.n_nodes();
    let mut weights = vec![0.0; n * ns];
    let simplex = matches!(p.kind, ElementKind::Tri3 | ElementKind::Tet4);
    for (a, &g) in e.nodes().iter().enumerate() {
        if sources.binary_search(&g).is_ok() {
            weights[a * ns + col(g)] = 1.0;
            continue;
        }
        let x = mesh.coords[g];
        let chosen: Vec<usize> = if simplex {
            (0..pn.len()).collect()
        } else {
            extrapolation_simplex(mesh, &p.nodes(), &x, d).ok_or_else(|| {
                Error::Mesh(format!(
                    "element {} ({}), partner of element {} in the mass-free layer, is \
                     degenerate: no {} of its vertices span a {}D simplex",
                    p.tag,
                    p.kind.name(),
                    e.tag,
                    d + 1,
                    d
                ))
            })?
        };
        let pts: Vec<[f64; 3]> = chosen.iter().map(|&k| mesh.coords[pn[k]]).collect();
        let bc = barycentric(&pts, &x, d);
        if bc.iter().any(|v| !v.is_finite()) {
            return Err(Error::Mesh(format!(
                "element {} ({}), partner of element {} in the mass-free layer, is degenerate",
                p.tag,
                p.kind.name(),
                e.tag
            )));
        }
        for (k, &lk) in chosen.iter().enumerate() {
            weights[a * ns + col(pn[lk])] += bc[k];
        }
    }
    Ok(ElementMap { sources, weights })
}

/// Local indices of `d + 1` vertices of a quad/hex forming a non-flat simplex near `x`: the
/// vertices in order of distance to `x` (ties by local index), each accepted if the simplex so
/// far keeps a relative volume >= FLAT_TOL; if no remaining vertex does, the one giving the
/// largest relative volume. None if even that is degenerate.
fn extrapolation_simplex(mesh: &Mesh, pn: &[usize], x: &[f64; 3], d: usize) -> Option<Vec<usize>> {
    let mut order: Vec<(f64, usize)> =
        pn.iter().enumerate().map(|(k, &g)| (dist2(&mesh.coords[g], x, d), k)).collect();
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut chosen = vec![order[0].1];
    let mut rest: Vec<usize> = order[1..].iter().map(|&(_, k)| k).collect();
    while chosen.len() < d + 1 {
        let mut pick: Option<(usize, f64)> = None; // (position in rest, relative volume)
        for (i, &k) in rest.iter().enumerate() {
            let pts: Vec<[f64; 3]> =
                chosen.iter().chain(std::iter::once(&k)).map(|&j| mesh.coords[pn[j]]).collect();
            let rv = relative_volume(&pts, d);
            if rv >= FLAT_TOL {
                pick = Some((i, rv));
                break;
            }
            if pick.is_none_or(|(_, best)| rv > best) {
                pick = Some((i, rv));
            }
        }
        let (i, rv) = pick?;
        if rv < DEGENERATE_TOL {
            return None;
        }
        chosen.push(rest.remove(i));
    }
    Some(chosen)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::shape::reference_node;
    use crate::mesh::{Element, PhysicalGroup};

    /// A 2D mesh from coordinates, cells and one boundary group of Line2 elements.
    fn mesh2d(
        coords: &[[f64; 2]],
        cells: &[(ElementKind, Vec<usize>)],
        groups: &[(&str, Vec<[usize; 2]>)],
    ) -> Mesh {
        let mut boundary = Vec::new();
        let mut pgs = Vec::new();
        let mut tag = 1000;
        for (gi, (gname, lines)) in groups.iter().enumerate() {
            for l in lines {
                tag += 1;
                boundary.push(Element::new(ElementKind::Line2, l, tag, gi as i32 + 1));
            }
            pgs.push(PhysicalGroup {
                name: gname.to_string(),
                dim: 1,
                tag: gi as i32 + 1,
                entities: vec![gi as i32 + 1],
            });
        }
        pgs.push(PhysicalGroup { name: "body".into(), dim: 2, tag: 100, entities: vec![1] });
        Mesh {
            dim: 2,
            coords: coords.iter().map(|c| [c[0], c[1], 0.0]).collect(),
            node_tags: (1..=coords.len() as u64).collect(),
            cells: cells
                .iter()
                .enumerate()
                .map(|(i, (k, n))| Element::new(*k, n, i as u64 + 1, 1))
                .collect(),
            boundary,
            groups: pgs,
        }
    }

    fn quad_det_j(x: &[[f64; 3]], xi: f64, eta: f64) -> f64 {
        // Reference [-1,1]^2, gmsh order.
        let r: Vec<[f64; 3]> = (0..4).map(|a| reference_node(ElementKind::Quad4, a)).collect();
        let mut j = [[0.0; 2]; 2];
        for a in 0..4 {
            let dxi = 0.25 * r[a][0] * (1.0 + r[a][1] * eta);
            let deta = 0.25 * r[a][1] * (1.0 + r[a][0] * xi);
            for i in 0..2 {
                j[i][0] += x[a][i] * dxi;
                j[i][1] += x[a][i] * deta;
            }
        }
        j[0][0] * j[1][1] - j[0][1] * j[1][0]
    }

    /// Property 6: a quad with one edge on Gamma_C, variant 0, is the 2-point Gauss rule on the
    /// opposite edge with weights 1/2 det J(xi_g, 1/2) (reference [0,1]^2), i.e. |K|/2 on a
    /// parallelogram. Checked for each rotation of the local numbering (contact edge = local
    /// edge r).
    #[test]
    fn quad_variant0_is_gauss_on_opposite_edge() {
        let shapes: [[[f64; 2]; 4]; 3] = [
            [[0.0, 0.0], [2.0, 0.0], [2.5, 1.5], [0.5, 1.5]], // parallelogram
            [[0.0, 0.0], [3.0, 0.0], [2.0, 1.0], [0.5, 1.2]], // general quad
            [[0.0, 0.0], [4.0, 0.0], [3.0, 2.0], [1.0, 2.0]], // trapezoid
        ];
        let rho = 2.7;
        for (si, s) in shapes.iter().enumerate() {
            for rot in 0..4 {
                // local node a of the cell = global node (a + rot) % 4; contact edge = global 0-1.
                let cell: Vec<usize> = (0..4).map(|a| (a + rot) % 4).collect();
                let m = mesh2d(s, &[(ElementKind::Quad4, cell.clone())], &[("c", vec![[0, 1]])]);
                let layer = MassFreeLayer::build(&m, "c", Variant::Zero).unwrap();
                let (mut nodes, mut out) = (Vec::new(), Vec::new());
                layer.element_matrix(&m, 0, rho, &mut nodes, &mut out).unwrap();
                assert_eq!(nodes, vec![2, 3]);
                // Expected with global numbering 0,1 on Gamma_C (eta = -1), 3,2 opposite.
                let x: Vec<[f64; 3]> = s.iter().map(|c| [c[0], c[1], 0.0]).collect();
                let g = 1.0 / 3f64.sqrt();
                let mut expect = [[0.0; 2]; 2]; // rows/cols: global nodes 2, 3
                for xg in [-g, g] {
                    // weight: reference [-1,1]^2, integral over eta gives 2 det J(xi, 0).
                    let wq = 2.0 * quad_det_j(&x, xg, 0.0);
                    let nval = [0.5 * (1.0 + xg), 0.5 * (1.0 - xg)]; // N_2, N_3 on eta = 1
                    for i in 0..2 {
                        for j in 0..2 {
                            expect[i][j] += rho * wq * nval[i] * nval[j];
                        }
                    }
                }
                if si == 0 {
                    let area = 3.0;
                    assert!((quad_det_j(&x, g, 0.0) * 4.0 - area).abs() < 1e-14);
                }
                for i in 0..2 {
                    for j in 0..2 {
                        for c in 0..2 {
                            for c2 in 0..2 {
                                let v = out[(i * 2 + c) * 4 + j * 2 + c2];
                                let e = if c == c2 { expect[i][j] } else { 0.0 };
                                assert!(
                                    (v - e).abs() < 1e-13 * rho,
                                    "shape {si} rot {rot}: {v} vs {e}"
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// Property 7: triangle with an edge on Gamma_C: all mass on the third vertex.
    #[test]
    fn triangle_variant0_mass_on_third_vertex() {
        let s = [[0.0, 0.0], [2.0, 0.3], [0.7, 1.9]];
        let area = 0.5 * ((2.0 * 1.9) - (0.3 * 0.7));
        for rot in 0..3 {
            let cell: Vec<usize> = (0..3).map(|a| (a + rot) % 3).collect();
            let m = mesh2d(&s, &[(ElementKind::Tri3, cell)], &[("c", vec![[1, 0]])]);
            let layer = MassFreeLayer::build(&m, "c", Variant::Zero).unwrap();
            let (mut nodes, mut out) = (Vec::new(), Vec::new());
            layer.element_matrix(&m, 0, 1.5, &mut nodes, &mut out).unwrap();
            assert_eq!(nodes, vec![2]);
            assert_eq!(out.len(), 4);
            assert!((out[0] - 1.5 * area).abs() < 1e-14 * area);
            assert!((out[3] - 1.5 * area).abs() < 1e-14 * area);
            assert_eq!(out[1], 0.0);
            assert_eq!(out[2], 0.0);
        }
    }

    /// 3 x 3 structured quads on [0,3]x[0,3] (node (i,j) = 4 j + i), contact = bottom.
    fn structured_quads() -> Mesh {
        let mut coords = Vec::new();
        for j in 0..4 {
            for i in 0..4 {
                coords.push([i as f64, j as f64]);
            }
        }
        let mut cells = Vec::new();
        for j in 0..3 {
            for i in 0..3 {
                let n0 = 4 * j + i;
                cells.push((ElementKind::Quad4, vec![n0, n0 + 1, n0 + 5, n0 + 4]));
            }
        }
        let mid = vec![[4, 5], [5, 6], [6, 7]]; // interior line y = 1
        mesh2d(&coords, &cells, &[("bottom", vec![[0, 1], [1, 2], [2, 3]]), ("mid", mid)])
    }

    /// Properties 8 and 9 on a hand-built structured layer.
    #[test]
    fn structured_quads_variant1() {
        let m = structured_quads();
        let layer = MassFreeLayer::build(&m, "bottom", Variant::One).unwrap();
        assert_eq!(layer.layer_cells, vec![0, 1, 2]);
        assert_eq!(layer.partners, vec![3, 4, 5]);
        for (l, &c) in layer.layer_cells.iter().enumerate() {
            let map = &layer.maps[l];
            let nodes = m.cells[c].nodes();
            for (a, &q) in nodes.iter().enumerate() {
                for &s in &map.sources {
                    let expect = if q < 4 {
                        // w_q = 2 w_{q+4} - w_{q+8}
                        if s == q + 4 {
                            2.0
                        } else if s == q + 8 {
                            -1.0
                        } else {
                            0.0
                        }
                    } else if s == q {
                        1.0
                    } else {
                        0.0
                    };
                    assert!((map.weight(a, s) - expect).abs() < 1e-14, "cell {c} node {q} src {s}");
                }
            }
        }
    }

    #[test]
    fn error_wrong_dimension_and_interior_group() {
        let m = structured_quads();
        let err = MassFreeLayer::build(&m, "body", Variant::Zero).unwrap_err();
        assert!(
            matches!(&err, Error::Scene(s) if s.contains("\"body\"") && s.contains("dimension 2")),
            "{err}"
        );
        let err = MassFreeLayer::build(&m, "mid", Variant::One).unwrap_err();
        // The first "mid" element is tag 1004 (after the three "bottom" ones).
        assert!(
            matches!(&err, Error::Scene(s) if s.contains("\"mid\"") && s.contains("element 1004") && s.contains("not on the boundary")),
            "{err}"
        );
        let err = MassFreeLayer::build(&m, "nope", Variant::One).unwrap_err();
        assert!(err.to_string().contains("\"nope\""), "{err}");
    }

    #[test]
    fn error_all_vertices_on_contact() {
        // Two triangles; triangle 2 (tag 2) has two edges on the contact group.
        let m = mesh2d(
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            &[(ElementKind::Tri3, vec![0, 2, 3]), (ElementKind::Tri3, vec![0, 1, 2])],
            &[("c", vec![[0, 1], [1, 2]])],
        );
        let err = MassFreeLayer::build(&m, "c", Variant::Zero).unwrap_err();
        assert!(
            matches!(&err, Error::Mesh(s) if s.contains("element 2 ") && s.contains("too coarse")),
            "{err}"
        );
    }

    #[test]
    fn error_no_partner() {
        let m = mesh2d(
            &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            &[(ElementKind::Quad4, vec![0, 1, 2, 3])],
            &[("c", vec![[0, 1]])],
        );
        let err = MassFreeLayer::build(&m, "c", Variant::One).unwrap_err();
        assert!(
            matches!(&err, Error::Mesh(s) if s.contains("element 1 ") && s.contains("variant 0")),
            "{err}"
        );
        // Variant 0 works on the same mesh.
        MassFreeLayer::build(&m, "c", Variant::Zero).unwrap();
    }

    /// The extrapolation simplex of a hex partner skips the coplanar fourth face vertex.
    #[test]
    fn hex_partner_skips_coplanar_vertex() {
        let r = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mut coords = Vec::new();
        for z in 0..3 {
            for c in r {
                coords.push([c[0], c[1], z as f64]);
            }
        }
        let cells = vec![
            Element::new(ElementKind::Hex8, &[0, 1, 2, 3, 4, 5, 6, 7], 1, 1),
            Element::new(ElementKind::Hex8, &[4, 5, 6, 7, 8, 9, 10, 11], 2, 1),
        ];
        let m = Mesh {
            dim: 3,
            coords,
            node_tags: (1..=12).collect(),
            cells,
            boundary: vec![Element::new(ElementKind::Quad4, &[0, 3, 2, 1], 10, 7)],
            groups: vec![PhysicalGroup {
                name: "bottom".into(),
                dim: 2,
                tag: 1,
                entities: vec![7],
            }],
        };
        let layer = MassFreeLayer::build(&m, "bottom", Variant::One).unwrap();
        assert_eq!(layer.partners, vec![1]);
        let map = &layer.maps[0];
        for q in 0..4 {
            for &s in &map.sources {
                let e = if s == q + 4 {
                    2.0
                } else if s == q + 8 {
                    -1.0
                } else {
                    0.0
                };
                assert!((map.weight(q, s) - e).abs() < 1e-14);
            }
        }
    }
}
