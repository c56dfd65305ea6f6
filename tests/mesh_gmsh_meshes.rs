//! The shipped .geo files meshed by the real gmsh, read back in ASCII and binary.

mod common;

use massfree::error::Error;
use massfree::mesh::check::{cell_measure, check_geometry};
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::{parse_msh, read_msh};
use massfree::mesh::{ElementKind, Mesh};
use std::path::{Path, PathBuf};

fn geo(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes").join(format!("{name}.geo"))
}

fn cache() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache")
}

fn params(p: &[(&str, f64)]) -> Vec<(String, f64)> {
    p.iter().map(|(n, v)| (n.to_string(), *v)).collect()
}

/// Meshes in ASCII and binary, checks both read to the same mesh, and returns it.
fn load(name: &str, p: &[(&str, f64)], dim: usize) -> Mesh {
    let p = params(p);
    let ascii = read_msh(&mesh_geo(&geo(name), &p, dim, false, &cache()).unwrap()).unwrap();
    let binary = read_msh(&mesh_geo(&geo(name), &p, dim, true, &cache()).unwrap()).unwrap();
    assert_same(&ascii, &binary, name);
    check_geometry(&ascii).unwrap();
    ascii
}

/// Identical except coordinates, which the ASCII file rounds to 16 significant digits.
fn assert_same(a: &Mesh, b: &Mesh, name: &str) {
    assert_eq!(a.dim, b.dim, "{name}");
    assert_eq!(a.node_tags, b.node_tags, "{name}");
    assert_eq!(a.cells, b.cells, "{name}");
    assert_eq!(a.boundary, b.boundary, "{name}");
    assert_eq!(a.groups, b.groups, "{name}");
    assert_eq!(a.coords.len(), b.coords.len(), "{name}");
    for (x, y) in a.coords.iter().zip(&b.coords) {
        for k in 0..3 {
            assert!((x[k] - y[k]).abs() <= 1e-14 * (1.0 + x[k].abs()), "{name}: {x:?} vs {y:?}");
        }
    }
}

fn total_measure(m: &Mesh) -> f64 {
    m.cells.iter().map(|e| cell_measure(m, e)).sum()
}

/// Checks group `name` has dimension `dim` and all its nodes satisfy coordinate k == v.
fn assert_plane(m: &Mesh, name: &str, dim: usize, k: usize, v: f64) {
    let g = m.group(name).unwrap();
    assert_eq!(g.dim, dim, "group {name}");
    let nodes = m.group_nodes(name).unwrap();
    assert!(!nodes.is_empty(), "group {name} has no nodes");
    for n in nodes {
        assert!((m.coords[n][k] - v).abs() < 1e-12, "group {name}: node {:?}", m.coords[n]);
    }
}

fn count(m: &Mesh, kind: ElementKind) -> usize {
    m.cells.iter().filter(|e| e.kind == kind).count()
}

fn check_beam(m: &Mesh, kind: ElementKind, per_square: usize, h: f64) {
    let (nx, ny) = ((10.0 / h).round() as usize, (1.0 / h).round() as usize);
    assert_eq!(m.dim, 2);
    assert_eq!(m.n_nodes(), (nx + 1) * (ny + 1));
    assert_eq!(m.cells.len(), per_square * nx * ny);
    assert_eq!(count(m, kind), m.cells.len());
    assert_eq!(m.boundary.len(), 2 * (nx + ny));
    assert!((total_measure(m) - 10.0).abs() < 1e-10);
    assert_plane(m, "left", 1, 0, 0.0);
    assert_plane(m, "right", 1, 0, 10.0);
    assert_plane(m, "bottom", 1, 1, 0.0);
    assert_plane(m, "top", 1, 1, 1.0);
    assert_eq!(m.group("body").unwrap().dim, 2);
    assert_eq!(m.group_elements("body").unwrap().len(), m.cells.len());
    assert_eq!(m.group_nodes("left").unwrap().len(), ny + 1);
}

#[test]
fn beam_quad() {
    check_beam(&load("beam_quad", &[], 2), ElementKind::Quad4, 1, 0.25);
}

#[test]
fn beam_tri() {
    check_beam(&load("beam_tri", &[], 2), ElementKind::Tri3, 2, 0.25);
}

#[test]
fn setnumber_changes_the_mesh() {
    let m = load("beam_quad", &[("h", 0.5)], 2);
    assert_eq!(m.n_nodes(), 21 * 3);
    check_beam(&m, ElementKind::Quad4, 1, 0.5);
    check_beam(&load("beam_tri", &[("h", 0.125)], 2), ElementKind::Tri3, 2, 0.125);
}

fn check_square(m: &Mesh, kind: ElementKind, per_square: usize) {
    assert_eq!(m.dim, 2);
    assert_eq!(m.n_nodes(), 25);
    assert_eq!(m.cells.len(), 16 * per_square);
    assert_eq!(count(m, kind), m.cells.len());
    assert!((total_measure(m) - 1.0).abs() < 1e-12);
    assert_plane(m, "left", 1, 0, 0.0);
    assert_plane(m, "right", 1, 0, 1.0);
    assert_plane(m, "bottom", 1, 1, 0.0);
    assert_plane(m, "top", 1, 1, 1.0);
    assert_eq!(m.group("body").unwrap().dim, 2);
}

#[test]
fn square_quad() {
    check_square(&load("square_quad", &[], 2), ElementKind::Quad4, 1);
}

#[test]
fn square_tri() {
    check_square(&load("square_tri", &[], 2), ElementKind::Tri3, 2);
}

fn check_block(m: &Mesh, kind: ElementKind, per_cube: usize, facets_per_square: usize) {
    assert_eq!(m.dim, 3);
    assert_eq!(m.n_nodes(), 41 * 5 * 5);
    assert_eq!(m.cells.len(), 40 * 4 * 4 * per_cube);
    assert_eq!(count(m, kind), m.cells.len());
    assert_eq!(m.boundary.len(), (2 * 40 * 4 * 2 + 2 * 4 * 4) * facets_per_square);
    assert!((total_measure(m) - 10.0).abs() < 1e-10);
    assert_plane(m, "left", 2, 0, 0.0);
    assert_plane(m, "right", 2, 0, 10.0);
    assert_plane(m, "front", 2, 1, 0.0);
    assert_plane(m, "back", 2, 1, 1.0);
    assert_plane(m, "bottom", 2, 2, 0.0);
    assert_plane(m, "top", 2, 2, 1.0);
    assert_eq!(m.group("body").unwrap().dim, 3);
    assert_eq!(m.group_nodes("left").unwrap().len(), 25);
    assert_eq!(m.group_nodes("top").unwrap().len(), 41 * 5);
}

#[test]
fn block_hex() {
    check_block(&load("block_hex", &[], 3), ElementKind::Hex8, 1, 1);
}

#[test]
fn block_tet() {
    check_block(&load("block_tet", &[], 3), ElementKind::Tet4, 6, 2);
}

#[test]
fn cube_hex() {
    let m = load("cube_hex", &[], 3);
    assert_eq!((m.dim, m.n_nodes(), count(&m, ElementKind::Hex8)), (3, 125, 64));
    assert_eq!(m.cells.len(), 64);
    assert_eq!(m.boundary.len(), 6 * 16);
    assert!((total_measure(&m) - 1.0).abs() < 1e-12);
    let sides = [
        ("left", 0, 0.0),
        ("right", 0, 1.0),
        ("front", 1, 0.0),
        ("back", 1, 1.0),
        ("bottom", 2, 0.0),
        ("top", 2, 1.0),
    ];
    for (name, k, v) in sides {
        assert_plane(&m, name, 2, k, v);
        assert_eq!(m.group_nodes(name).unwrap().len(), 25, "{name}");
    }
    assert_eq!(m.group("body").unwrap().dim, 3);
}

fn check_disc(m: &Mesh, kind: ElementKind, r: f64, gap: f64) {
    assert_eq!(m.dim, 2);
    assert_eq!(count(m, kind), m.cells.len(), "all cells are {}", kind.name());
    let area = std::f64::consts::PI * r * r;
    let got = total_measure(m);
    assert!(got < area && (area - got) / area < 1e-2, "disc area {got} vs {area}");
    let yc = r + gap;
    let lowest = m.coords.iter().map(|x| x[1]).fold(f64::INFINITY, f64::min);
    assert!((lowest - gap).abs() < 1e-12, "lowest point at y = {lowest}");
    assert_eq!(m.group("disc").unwrap().dim, 2);
    let s = std::f64::consts::FRAC_1_SQRT_2;
    for (name, lower) in [("contact", true), ("free", false)] {
        assert_eq!(m.group(name).unwrap().dim, 1);
        for n in m.group_nodes(name).unwrap() {
            let [x, y, _] = m.coords[n];
            let d = (x * x + (y - yc) * (y - yc)).sqrt();
            assert!((d - r).abs() < 1e-9 * r, "{name} node {x} {y} off the circle");
            // Contact: angles 225..315 deg, i.e. y <= yc - R sin 45.
            let below = y <= yc - r * s + 1e-9;
            let strictly_below = y < yc - r * s - 1e-9;
            assert!(if lower { below } else { !strictly_below }, "{name} node {x} {y}");
        }
    }
    // Refined near the contact point: the smallest cells are there.
    let size = |e: &massfree::mesh::Element| cell_measure(m, e).sqrt();
    let smallest = m.cells.iter().min_by(|a, b| size(a).total_cmp(&size(b))).unwrap();
    let c = m.element_coords(smallest)[0];
    assert!(c[0].abs() < 1.0 && c[1] < gap + 1.0, "smallest cell at {c:?}");
}

#[test]
fn disc_tri() {
    let m = load("disc_tri", &[], 2);
    check_disc(&m, ElementKind::Tri3, 8.0, 0.05);
    let finer = load("disc_tri", &[("hc", 0.05)], 2);
    assert!(finer.n_nodes() > m.n_nodes());
}

#[test]
fn disc_quad() {
    check_disc(&load("disc_quad", &[], 2), ElementKind::Quad4, 8.0, 0.05);
    let m = load("disc_quad", &[("R", 4.0), ("gap", 0.5), ("h", 0.5)], 2);
    check_disc(&m, ElementKind::Quad4, 4.0, 0.5);
}

#[test]
fn cache_is_reused() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache-reuse");
    let _ = std::fs::remove_dir_all(&dir);
    let p = params(&[("h", 0.5)]);
    let first = mesh_geo(&geo("square_quad"), &p, 2, false, &dir).unwrap();
    assert!(first.starts_with(&dir));
    assert!(first.file_name().unwrap().to_str().unwrap().starts_with("square_quad-"));
    // If gmsh ran again it would overwrite this marker.
    std::fs::write(&first, "marker").unwrap();
    let again = mesh_geo(&geo("square_quad"), &p, 2, false, &dir).unwrap();
    assert_eq!(first, again);
    assert_eq!(std::fs::read_to_string(&again).unwrap(), "marker");
    // Any change of the key gives another file.
    let other = [
        mesh_geo(&geo("square_quad"), &params(&[("h", 0.25)]), 2, false, &dir).unwrap(),
        mesh_geo(&geo("square_quad"), &p, 2, true, &dir).unwrap(),
        mesh_geo(&geo("square_quad"), &[], 2, false, &dir).unwrap(),
    ];
    for o in &other {
        assert_ne!(o, &first);
    }
    // No temporary files left behind.
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 4, "{names:?}");
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}

#[test]
fn gmsh_errors_are_reported() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache-errors");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.geo");
    std::fs::write(&bad, "Point(1) = {0, 0, 0;\n").unwrap();
    match mesh_geo(&bad, &[], 2, false, &dir.join("cache")) {
        Err(Error::Mesh(m)) => {
            assert!(m.contains("bad.geo") && m.contains("syntax error"), "{m}");
            assert!(!m.contains('\n'), "{m}");
        }
        other => panic!("expected a gmsh error, got {other:?}"),
    }
    let left = std::fs::read_dir(dir.join("cache")).map(|d| d.count()).unwrap_or(0);
    assert_eq!(left, 0, "temporary output left behind");
    match mesh_geo(&dir.join("missing.geo"), &[], 2, false, &dir) {
        Err(Error::Mesh(m)) => assert!(m.contains("missing.geo"), "{m}"),
        other => panic!("expected an error, got {other:?}"),
    }
    assert!(mesh_geo(&geo("square_quad"), &params(&[("h; x", 1.0)]), 2, false, &dir).is_err());
}

/// Truncating a real binary file anywhere gives an error, never a panic or a wrong mesh.
#[test]
fn truncated_binary_is_rejected() {
    let path = mesh_geo(&geo("square_tri"), &params(&[("h", 0.5)]), 2, true, &cache()).unwrap();
    let bytes = std::fs::read(path).unwrap();
    let full = parse_msh(&bytes, "square.msh").unwrap();
    let end = bytes.len() - "$EndElements\n".len();
    for n in (0..end).step_by(3).chain([end - 1]) {
        match parse_msh(&bytes[..n], "square.msh") {
            Err(Error::Mesh(m)) => assert!(m.starts_with("square.msh: "), "{m}"),
            other => panic!("prefix of {n} bytes: {other:?}"),
        }
    }
    assert_eq!(parse_msh(&bytes[..end + 12], "square.msh").unwrap(), full);
}

/// Files saved with parametric coordinates (`gmsh -parametric`) read to the same mesh.
#[test]
fn parametric_files() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-parametric");
    std::fs::create_dir_all(&dir).unwrap();
    for (name, d) in [("disc_quad", 2), ("block_hex", 3)] {
        for bin in [false, true] {
            let out = dir.join(format!("{name}-{bin}.msh"));
            let mut cmd = std::process::Command::new("gmsh");
            cmd.arg(geo(name)).arg(format!("-{d}")).args(["-format", "msh41", "-parametric"]);
            if bin {
                cmd.arg("-bin");
            }
            let o = common::output(cmd.arg("-o").arg(&out).args(["-v", "1"]));
            assert!(o.status.success());
            let text = std::fs::read(&out).unwrap();
            let plain = load(name, &[], d);
            let m = parse_msh(&text, "p.msh").unwrap();
            assert_same(&m, &plain, name);
        }
    }
}
