//! Properties of the mass-free layer mass matrix M_H = sum_K E_K^T M_K E_K on gmsh meshes,
//! checked against the standard consistent mass M (docs/method.md, the mass-free layer). Dense assembly, so
//! the meshes are kept below ~1500 dofs. Run with `--nocapture` to see the deviations.

#![allow(clippy::needless_range_loop, clippy::type_complexity)]

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use massfree::error::Error;
use massfree::fem::kernels::mass;
use massfree::mass::layer::{MassFreeLayer, Variant};
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::read_msh;
use massfree::mesh::Mesh;

const RHO: f64 = 2.5;

fn cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache")
}

fn load_geo(geo: &Path, params: &[(&str, f64)], dim: usize) -> Mesh {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let path = mesh_geo(geo, &params, dim, false, &cache()).unwrap();
    read_msh(&path).unwrap()
}

fn load(name: &str, params: &[(&str, f64)], dim: usize) -> Mesh {
    let geo = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes").join(format!("{name}.geo"));
    load_geo(&geo, params, dim)
}

/// Dense (n_nodes*dim)^2 mass matrix: standard (layer = None) or modified.
fn assemble(mesh: &Mesh, layer: Option<&MassFreeLayer>) -> Vec<f64> {
    let d = mesh.dim;
    let n = mesh.n_nodes() * d;
    let mut a = vec![0.0; n * n];
    let (mut nodes, mut out) = (Vec::new(), Vec::new());
    for (c, e) in mesh.cells.iter().enumerate() {
        let modified = layer.and_then(|l| l.element_matrix(mesh, c, RHO, &mut nodes, &mut out));
        if modified.is_none() {
            nodes.clear();
            nodes.extend_from_slice(&e.nodes());
            let nd = nodes.len() * d;
            out.clear();
            out.resize(nd * nd, 0.0);
            mass(e.kind, &mesh.element_coords(e), RHO, &mut out);
        }
        let nd = nodes.len() * d;
        assert_eq!(out.len(), nd * nd);
        for (i, &gi) in nodes.iter().enumerate() {
            for (j, &gj) in nodes.iter().enumerate() {
                for ci in 0..d {
                    for cj in 0..d {
                        a[(gi * d + ci) * n + gj * d + cj] += out[(i * d + ci) * nd + j * d + cj];
                    }
                }
            }
        }
    }
    a
}

fn quad_form(a: &[f64], x: &[f64], y: &[f64]) -> f64 {
    let n = x.len();
    let mut s = 0.0;
    for i in 0..n {
        if x[i] == 0.0 {
            continue;
        }
        let row = &a[i * n..(i + 1) * n];
        s += x[i] * row.iter().zip(y).map(|(r, v)| r * v).sum::<f64>();
    }
    s
}

/// PSD test by symmetric pivoted Cholesky: returns (min pivot / max diagonal, number of
/// pivots below `tol * max diagonal`), or Err if a pivot is negative beyond the tolerance or
/// the numerically-zero trailing block is not zero.
fn psd(mut a: Vec<f64>, n: usize, tol: f64) -> Result<(f64, usize), String> {
    let scale = (0..n).map(|i| a[i * n + i]).fold(0.0, f64::max);
    let mut perm: Vec<usize> = (0..n).collect();
    let mut min_pivot = f64::INFINITY;
    for k in 0..n {
        // pivot: largest remaining diagonal
        let (p, &dmax) = perm[k..]
            .iter()
            .map(|&i| &a[i * n + i])
            .enumerate()
            .max_by(|x, y| x.1.total_cmp(y.1))
            .unwrap();
        let p = p + k;
        if dmax < -tol * scale {
            return Err(format!("negative pivot {dmax:e} (scale {scale:e})"));
        }
        if dmax <= tol * scale {
            // The remaining Schur complement must vanish.
            for &i in &perm[k..] {
                for &j in &perm[k..] {
                    if a[i * n + j].abs() > tol * scale {
                        return Err(format!(
                            "zero pivot with nonzero off-diagonal {:e}",
                            a[i * n + j]
                        ));
                    }
                }
            }
            return Ok((min_pivot.min(dmax) / scale, n - k));
        }
        min_pivot = min_pivot.min(dmax);
        perm.swap(k, p);
        let pk = perm[k];
        let piv = a[pk * n + pk];
        let col: Vec<f64> = perm[k + 1..].iter().map(|&i| a[i * n + pk]).collect();
        for (ii, &i) in perm[k + 1..].iter().enumerate() {
            let li = col[ii] / piv;
            if li == 0.0 {
                continue;
            }
            for (jj, &j) in perm[k + 1..].iter().enumerate() {
                a[i * n + j] -= li * col[jj];
            }
        }
    }
    Ok((min_pivot / scale, 0))
}

#[derive(Default, Debug)]
struct Report {
    dofs: usize,
    layer_cells: usize,
    contact_nodes: usize,
    max_contact_entry: f64,
    asym: f64,
    min_pivot: f64,
    zero_pivots: usize,
    total_mass: f64,
    first_moment: f64,
    second_moment: f64,
    fallback_partners: usize,
    vertex_only_partners: usize,
    max_abs_weight: f64,
}

/// Node pairs coupled by the standard mass matrix (sharing a cell).
fn node_pairs(mesh: &Mesh) -> HashSet<(usize, usize)> {
    let mut s = HashSet::new();
    for e in &mesh.cells {
        for a in e.nodes() {
            for b in e.nodes() {
                s.insert((a, b));
            }
        }
    }
    s
}

fn check(mesh: &Mesh, group: &str, variant: Variant, label: &str) -> Report {
    let layer = MassFreeLayer::build(mesh, group, variant).unwrap();
    let d = mesh.dim;
    let n = mesh.n_nodes() * d;
    assert!(n < 1600, "{label}: {n} dofs is too many for the dense checks");
    let m = assemble(mesh, None);
    let mh = assemble(mesh, Some(&layer));
    let mut r = Report {
        dofs: n,
        layer_cells: layer.n_layer_cells(),
        contact_nodes: layer.n_contact_nodes(),
        ..Default::default()
    };
    assert_eq!(layer.contact_nodes, mesh.group_nodes(group).unwrap());
    assert!(r.layer_cells > 0 && r.contact_nodes > 0);
    // layer cells = cells with a contact node
    let expect: Vec<usize> = (0..mesh.cells.len())
        .filter(|&c| mesh.cells[c].nodes().iter().any(|&g| layer.is_contact[g]))
        .collect();
    assert_eq!(layer.layer_cells, expect);
    let scale = mh.iter().fold(0.0f64, |s, v| s.max(v.abs()));

    // 1. contact rows and columns exactly zero.
    for &g in &layer.contact_nodes {
        for c in 0..d {
            let i = g * d + c;
            for j in 0..n {
                r.max_contact_entry = r.max_contact_entry.max(mh[i * n + j].abs());
                r.max_contact_entry = r.max_contact_entry.max(mh[j * n + i].abs());
            }
        }
    }
    assert_eq!(r.max_contact_entry, 0.0, "{label}: contact rows/columns not zero");

    // 2. symmetry
    for i in 0..n {
        for j in 0..i {
            r.asym = r.asym.max((mh[i * n + j] - mh[j * n + i]).abs() / scale);
        }
    }
    assert!(r.asym <= 1e-14, "{label}: asymmetry {:e}", r.asym);

    // 3. PSD on the non-contact dofs
    let free: Vec<usize> = (0..n).filter(|&i| !layer.is_contact[i / d]).collect();
    let nf = free.len();
    let mut red = vec![0.0; nf * nf];
    for (a, &i) in free.iter().enumerate() {
        for (b, &j) in free.iter().enumerate() {
            red[a * nf + b] = mh[i * n + j];
        }
    }
    let (mp, zp) = psd(red, nf, 1e-12).unwrap_or_else(|e| panic!("{label}: not PSD: {e}"));
    r.min_pivot = mp;
    r.zero_pivots = zp;
    assert_eq!(zp, layer.massless_nodes(mesh).len() * d, "{label}: unexpected zero pivots");

    // 4./5. moments, per component; relative to sqrt(u^T M u * v^T M v) (Cauchy-Schwarz).
    for c in 0..d {
        let mut vecs = vec![vec![0.0; n]];
        for node in 0..mesh.n_nodes() {
            vecs[0][node * d + c] = 1.0;
        }
        for a in 0..d {
            let mut x = vec![0.0; n];
            for node in 0..mesh.n_nodes() {
                x[node * d + c] = mesh.coords[node][a];
            }
            vecs.push(x);
        }
        let norms: Vec<f64> = vecs.iter().map(|v| quad_form(&m, v, v)).collect();
        for i in 0..vecs.len() {
            for j in 0..=i {
                let dev = (quad_form(&mh, &vecs[i], &vecs[j]) - quad_form(&m, &vecs[i], &vecs[j]))
                    .abs()
                    / (norms[i] * norms[j]).sqrt();
                let slot = match (i, j) {
                    (0, 0) => &mut r.total_mass,
                    (_, 0) => &mut r.first_moment,
                    _ => &mut r.second_moment,
                };
                *slot = slot.max(dev);
            }
        }
    }
    assert!(r.total_mass <= 1e-12, "{label}: total mass deviation {:e}", r.total_mass);
    if variant == Variant::One {
        assert!(r.first_moment <= 1e-12, "{label}: first moment deviation {:e}", r.first_moment);
        assert!(r.second_moment <= 1e-12, "{label}: second moment deviation {:e}", r.second_moment);
    }

    // 11. sparsity: sources of each map pairwise coupled by M; pattern(M_H) within pattern(M).
    let pairs = node_pairs(mesh);
    for map in &layer.maps {
        for &a in &map.sources {
            for &b in &map.sources {
                assert!(pairs.contains(&(a, b)), "{label}: sources {a},{b} widen the pattern");
            }
        }
        r.max_abs_weight = map.weights.iter().fold(r.max_abs_weight, |s, w| s.max(w.abs()));
        // rows sum to one
        let ns = map.sources.len();
        for row in map.weights.chunks(ns) {
            assert!((row.iter().sum::<f64>() - 1.0).abs() < 1e-12, "{label}: row sum");
        }
    }
    for i in 0..mesh.n_nodes() {
        for j in 0..mesh.n_nodes() {
            if mh[(i * d) * n + j * d] != 0.0 {
                assert!(pairs.contains(&(i, j)), "{label}: M_H couples {i},{j}");
            }
        }
    }

    // Partner statistics (variant 1): partners outside the layer; facet vs vertex neighbours.
    for (l, &k1) in layer.partners.iter().enumerate() {
        let k = layer.layer_cells[l];
        assert!(layer.map(k1).is_none(), "{label}: partner in the layer");
        let kn: HashSet<usize> = mesh.cells[k].nodes().iter().copied().collect();
        let shared = mesh.cells[k1].nodes().iter().filter(|g| kn.contains(g)).count();
        let facet_size = mesh.cells[k].kind.facets()[0].len();
        assert!(shared >= 1);
        if shared < facet_size {
            r.fallback_partners += 1;
            if shared == 1 {
                r.vertex_only_partners += 1;
            }
        }
    }
    eprintln!("{label}: {r:?}");
    r
}

struct Case {
    geo: &'static str,
    params: &'static [(&'static str, f64)],
    dim: usize,
    group: &'static str,
}

const CASES: &[Case] = &[
    Case { geo: "beam_quad", params: &[("h", 0.25)], dim: 2, group: "bottom" },
    Case { geo: "beam_tri", params: &[("h", 0.25)], dim: 2, group: "bottom" },
    Case { geo: "block_hex", params: &[("h", 0.5)], dim: 3, group: "bottom" },
    Case { geo: "block_tet", params: &[("h", 0.5)], dim: 3, group: "bottom" },
    Case { geo: "disc_tri", params: &[("h", 2.0), ("hc", 0.4)], dim: 2, group: "contact" },
    Case { geo: "disc_quad", params: &[("h", 2.0), ("hc", 0.4)], dim: 2, group: "contact" },
    Case { geo: "square_tri", params: &[("h", 0.5)], dim: 2, group: "bottom" },
    Case { geo: "square_tri", params: &[("h", 0.25)], dim: 2, group: "bottom" },
    Case { geo: "square_quad", params: &[("h", 0.5)], dim: 2, group: "bottom" },
    Case { geo: "square_quad", params: &[("h", 0.25)], dim: 2, group: "bottom" },
];

fn run_case(case: &Case) {
    let mesh = load(case.geo, case.params, case.dim);
    for variant in [Variant::Zero, Variant::One] {
        let label = format!("{} {:?} {:?}", case.geo, case.params, variant);
        check(&mesh, case.group, variant, &label);
    }
}

#[test]
fn beam_quad() {
    run_case(&CASES[0]);
}
#[test]
fn beam_tri() {
    run_case(&CASES[1]);
}
#[test]
fn block_hex() {
    run_case(&CASES[2]);
}
#[test]
fn block_tet() {
    run_case(&CASES[3]);
}
#[test]
fn disc_tri() {
    run_case(&CASES[4]);
}
#[test]
fn disc_quad() {
    run_case(&CASES[5]);
}
#[test]
fn squares() {
    for c in &CASES[6..] {
        run_case(c);
    }
}

/// The moment check can fail: variant 0 (exact for constants only) does not conserve the
/// second moment; and the PSD checker rejects an indefinite matrix.
#[test]
fn checks_are_discriminating() {
    let mesh = load("beam_quad", &[("h", 0.25)], 2);
    let r = check(&mesh, "bottom", Variant::Zero, "beam_quad variant 0 (control)");
    assert!(r.second_moment > 1e-6, "variant 0 unexpectedly conserves the second moment");
    assert_eq!(r.dofs, 2 * mesh.n_nodes());
    assert!(psd(vec![1.0, 2.0, 2.0, 1.0], 2, 1e-12).is_err());
    assert!(psd(vec![1.0, 1.0, 1.0, 1.0], 2, 1e-12).is_ok());
}

/// Properties 8 and 9 on the structured beam/block: K1 is the element directly above K, and
/// w_q = 2 w_p1 - w_p2 along the mesh line normal to Gamma_C.
fn structured_variant1(mesh: &Mesh, h: f64) {
    let d = mesh.dim;
    let up = d - 1; // y in 2D, z in 3D
    let layer = MassFreeLayer::build(mesh, "bottom", Variant::One).unwrap();
    let centroid = |c: usize| {
        let e = &mesh.cells[c];
        let mut x = [0.0; 3];
        for g in e.nodes() {
            for i in 0..3 {
                x[i] += mesh.coords[g][i] / e.nodes().len() as f64;
            }
        }
        x
    };
    let find = |x: [f64; 3]| {
        (0..mesh.n_nodes())
            .find(|&g| (0..3).all(|i| (mesh.coords[g][i] - x[i]).abs() < 1e-6 * h))
            .unwrap()
    };
    let mut checked = 0;
    let mut max_dev: f64 = 0.0;
    for (l, &k) in layer.layer_cells.iter().enumerate() {
        let k1 = layer.partners[l];
        let (ck, c1) = (centroid(k), centroid(k1));
        for i in 0..3 {
            let e = if i == up { h } else { 0.0 };
            // gmsh's transfinite coordinates carry ~1e-12 noise.
            assert!((c1[i] - ck[i] - e).abs() < 1e-9 * h, "partner of cell {k} is not above it");
        }
        let map = &layer.maps[l];
        for (a, &q) in mesh.cells[k].nodes().iter().enumerate() {
            let x = mesh.coords[q];
            let expected: Vec<(usize, f64)> = if x[up].abs() < 1e-9 * h {
                let mut p1 = x;
                p1[up] += h;
                let mut p2 = x;
                p2[up] += 2.0 * h;
                vec![(find(p1), 2.0), (find(p2), -1.0)]
            } else {
                vec![(q, 1.0)]
            };
            for &s in &map.sources {
                let e = expected.iter().find(|(g, _)| *g == s).map_or(0.0, |p| p.1);
                let dev = (map.weight(a, s) - e).abs();
                max_dev = max_dev.max(dev);
                assert!(dev < 1e-9, "cell {k} node {q} source {s}: weight {}", map.weight(a, s));
            }
            for (g, _) in &expected {
                assert!(map.sources.contains(g));
            }
            checked += 1;
        }
    }
    assert!(checked > 0);
    eprintln!("structured variant 1 ({d}D, h = {h}): max weight deviation {max_dev:e}");
}

#[test]
fn structured_partner_and_extrapolation_weights() {
    structured_variant1(&load("beam_quad", &[("h", 0.25)], 2), 0.25);
    structured_variant1(&load("square_quad", &[("h", 0.25)], 2), 0.25);
    structured_variant1(&load("block_hex", &[("h", 0.5)], 3), 0.5);
}

/// Property 6 on a gmsh mesh: every beam_quad layer cell (rectangles) gets
/// E^T M_K E = 2-point Gauss on the opposite edge, weights |K|/2: for h x h squares the
/// matrix on the two opposite-edge nodes is rho h^2/2 [[n0^2 + n1^2, 2 n0 n1], [2 n0 n1,
/// n0^2 + n1^2]] per component, with n0, n1 = (1 -+ 1/sqrt 3)/2 the edge shape functions at
/// the Gauss points.
#[test]
fn beam_quad_variant0_element_matrices() {
    let h = 0.25;
    let mesh = load("beam_quad", &[("h", h)], 2);
    let layer = MassFreeLayer::build(&mesh, "bottom", Variant::Zero).unwrap();
    let g = 1.0 / 3f64.sqrt();
    let (n0, n1) = ((1.0 - g) / 2.0, (1.0 + g) / 2.0);
    let diag = RHO * h * h / 2.0 * (n0 * n0 + n1 * n1);
    let off = RHO * h * h / 2.0 * (2.0 * n0 * n1);
    let (mut nodes, mut out) = (Vec::new(), Vec::new());
    let mut max_dev: f64 = 0.0;
    for &k in &layer.layer_cells {
        layer.element_matrix(&mesh, k, RHO, &mut nodes, &mut out).unwrap();
        assert_eq!(nodes.len(), 2);
        for &s in &nodes {
            assert!((mesh.coords[s][1] - h).abs() < 1e-9 * h);
        }
        for i in 0..2 {
            for j in 0..2 {
                for c in 0..2 {
                    for c2 in 0..2 {
                        let v = out[(i * 2 + c) * 4 + j * 2 + c2];
                        let e = if c != c2 {
                            0.0
                        } else if i == j {
                            diag
                        } else {
                            off
                        };
                        // relative 1e-10: gmsh's coordinates carry ~1e-12 noise
                        let dev = (v - e).abs() / (RHO * h * h);
                        max_dev = max_dev.max(dev);
                        assert!(dev < 1e-10, "cell {k}: {v} vs {e}");
                    }
                }
            }
        }
    }
    eprintln!("beam_quad variant 0 vs opposite-edge Gauss rule: max rel. deviation {max_dev:e}");
}

/// Errors on real gmsh meshes: an interior curve as contact group; a mesh without partner.
#[test]
fn gmsh_errors() {
    let dir = cache();
    std::fs::create_dir_all(&dir).unwrap();
    let geo = dir.join("square_interior_curve.geo");
    std::fs::write(
        &geo,
        "h = 0.25;\n\
         Point(1) = {0, 0, 0, h}; Point(2) = {1, 0, 0, h}; Point(3) = {1, 1, 0, h}; \
         Point(4) = {0, 1, 0, h};\n\
         Point(5) = {0.25, 0.5, 0, h}; Point(6) = {0.75, 0.5, 0, h};\n\
         Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 1};\n\
         Line(5) = {5, 6};\n\
         Curve Loop(1) = {1, 2, 3, 4}; Plane Surface(1) = {1};\n\
         Line{5} In Surface{1};\n\
         Physical Curve(\"bottom\") = {1};\n\
         Physical Curve(\"mid\") = {5};\n\
         Physical Surface(\"body\") = {1};\n",
    )
    .unwrap();
    let mesh = load_geo(&geo, &[], 2);
    let mid_tags: Vec<u64> = mesh.group_elements("mid").unwrap().iter().map(|e| e.tag).collect();
    assert!(!mid_tags.is_empty());
    for v in [Variant::Zero, Variant::One] {
        let err = MassFreeLayer::build(&mesh, "mid", v).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, Error::Scene(_)), "{msg}");
        assert!(msg.contains("\"mid\"") && msg.contains("not on the boundary"), "{msg}");
        assert!(mid_tags.iter().any(|t| msg.contains(&format!("element {t} "))), "{msg}");
        MassFreeLayer::build(&mesh, "bottom", v).unwrap();
    }
    let err = MassFreeLayer::build(&mesh, "body", Variant::One).unwrap_err();
    assert!(matches!(&err, Error::Scene(s) if s.contains("dimension 2")), "{err}");

    // square_tri with h = 1: two triangles, both touch the bottom: no partner for variant 1.
    let mesh = load("square_tri", &[("h", 1.0)], 2);
    assert_eq!(mesh.cells.len(), 2);
    let err = MassFreeLayer::build(&mesh, "bottom", Variant::One).unwrap_err();
    assert!(matches!(&err, Error::Mesh(s) if s.contains("variant 0")), "{err}");
    MassFreeLayer::build(&mesh, "bottom", Variant::Zero).unwrap();
}

/// Building twice gives identical layers (determinism, as every MPI rank builds its own).
#[test]
fn deterministic() {
    let mesh = load("disc_quad", &[("h", 2.0), ("hc", 0.4)], 2);
    for v in [Variant::Zero, Variant::One] {
        let a = MassFreeLayer::build(&mesh, "contact", v).unwrap();
        let b = MassFreeLayer::build(&mesh, "contact", v).unwrap();
        assert_eq!(a, b);
    }
}

/// Larger meshes (too big for the dense checks): total mass and (variant 1) moments computed
/// element by element, u^T M_H v = sum_K (E u_K)^T M_K (E v_K); no contact node is a source;
/// partner statistics.
#[test]
fn larger_meshes_elementwise() {
    let cases: &[(&str, &[(&str, f64)], usize, &str)] = &[
        ("disc_quad", &[], 2, "contact"),
        ("disc_tri", &[], 2, "contact"),
        ("beam_tri", &[("h", 0.125)], 2, "bottom"),
        ("block_tet", &[("h", 0.25)], 3, "bottom"),
    ];
    for &(geo, params, dim, group) in cases {
        let mesh = load(geo, params, dim);
        let d = mesh.dim;
        for variant in [Variant::Zero, Variant::One] {
            let layer = MassFreeLayer::build(&mesh, group, variant).unwrap();
            // f_a(node) = 1 (a = 0) or coordinate a-1.
            let f = |a: usize, g: usize| if a == 0 { 1.0 } else { mesh.coords[g][a - 1] };
            let nf = d + 1;
            let mut qm = vec![0.0; nf * nf];
            let mut qh = vec![0.0; nf * nf];
            let (mut nodes, mut out) = (Vec::new(), Vec::new());
            let mut mk = Vec::new();
            for (c, e) in mesh.cells.iter().enumerate() {
                let nd = e.nodes().len() * d;
                mk.clear();
                mk.resize(nd * nd, 0.0);
                mass(e.kind, &mesh.element_coords(e), RHO, &mut mk);
                let form = |nodes: &[usize], m: &[f64], a: usize, b: usize| {
                    let k = nodes.len() * d;
                    let mut s = 0.0;
                    for (i, &gi) in nodes.iter().enumerate() {
                        for (j, &gj) in nodes.iter().enumerate() {
                            s += f(a, gi) * m[(i * d) * k + j * d] * f(b, gj);
                        }
                    }
                    s
                };
                let layered = layer.element_matrix(&mesh, c, RHO, &mut nodes, &mut out).is_some();
                for a in 0..nf {
                    for b in 0..nf {
                        let std = form(&e.nodes(), &mk, a, b);
                        qm[a * nf + b] += std;
                        qh[a * nf + b] += if layered { form(&nodes, &out, a, b) } else { std };
                    }
                }
                if layered {
                    assert!(nodes.iter().all(|&g| !layer.is_contact[g]));
                }
            }
            let mut dev = [0.0f64; 3];
            for a in 0..nf {
                for b in 0..nf {
                    let rel = (qh[a * nf + b] - qm[a * nf + b]).abs()
                        / (qm[a * nf + a] * qm[b * nf + b]).sqrt();
                    let slot = if a == 0 && b == 0 {
                        0
                    } else if a == 0 || b == 0 {
                        1
                    } else {
                        2
                    };
                    dev[slot] = dev[slot].max(rel);
                }
            }
            assert!(dev[0] < 1e-12, "{geo} {variant:?}: total mass {:e}", dev[0]);
            if variant == Variant::One {
                assert!(dev[1] < 1e-12 && dev[2] < 1e-12, "{geo}: moments {dev:?}");
            }
            let (mut fallback, mut vertex_only) = (0, 0);
            for (l, &k1) in layer.partners.iter().enumerate() {
                let k = &mesh.cells[layer.layer_cells[l]];
                let shared =
                    mesh.cells[k1].nodes().iter().filter(|g| k.nodes().contains(g)).count();
                if shared < k.kind.facets()[0].len() {
                    fallback += 1;
                }
                if shared == 1 {
                    vertex_only += 1;
                }
            }
            let wmax = layer
                .maps
                .iter()
                .flat_map(|m| m.weights.iter())
                .fold(0.0f64, |s, w| s.max(w.abs()));
            eprintln!(
                "{geo} {params:?} {variant:?}: nodes {} cells {} layer {} contact nodes {} | \
                 total mass {:.1e} 1st {:.1e} 2nd {:.1e} | fallback partners {fallback} \
                 (vertex-only {vertex_only}) max|w| {wmax:.3}",
                mesh.n_nodes(),
                mesh.cells.len(),
                layer.n_layer_cells(),
                layer.n_contact_nodes(),
                dev[0],
                dev[1],
                dev[2]
            );
        }
    }
}
