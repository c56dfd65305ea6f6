//! The distributed mesh front end (`partition::distribute::read_local`) against the replicated
//! path (`read_msh`, the partition of the whole mesh, `localize`): every field of every rank's
//! part, bit for bit, on 1-4 ranks, 2D and 3D, binary and ASCII, for metis, x-slabs and rcb
//! (`massfree mesh-check`); rcb's balance and cut; bad files failing alike on both paths; and
//! hand-made binary files with what gmsh does not write (mixed kinds in interleaved blocks,
//! unsorted sparse node tags, cells outside physical groups, unused nodes).

mod common;
use common::{massfree, scratch};
use massfree::mesh::gmsh::mesh_geo;
use std::path::{Path, PathBuf};

fn geo(name: &str) -> PathBuf {
    common::repo().join("meshes").join(format!("{name}.geo"))
}

/// The shipped `.geo` meshed at size `h` (cached), in binary or ASCII.
fn mesh(name: &str, dim: usize, h: f64, binary: bool) -> PathBuf {
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache");
    mesh_geo(&geo(name), &[("h".to_string(), h)], dim, binary, &cache).unwrap()
}

/// `mesh-check` on `ranks` ranks; asserts it succeeds with one "same" line per rank and returns
/// its output.
fn check(ranks: usize, file: &Path, args: &[&str]) -> String {
    let mut all = vec!["mesh-check", file.to_str().unwrap()];
    all.extend_from_slice(args);
    let o = massfree(ranks, &all);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    let what = format!("{} on {ranks} rank(s) {args:?}", file.display());
    assert!(o.status.success(), "{what}: failed\nstdout:\n{out}\nstderr:\n{err}");
    let same = out.lines().filter(|l| l.contains(": same (")).count();
    assert_eq!(same, ranks, "{what}: not every rank the same\n{out}");
    out
}

/// Every rank count and partition on one file.
fn check_all(file: &Path, extra: &[&str]) {
    for ranks in 1..=4 {
        for partition in ["metis", "x-slabs", "rcb"] {
            let mut args = vec!["--partition", partition];
            args.extend_from_slice(extra);
            check(ranks, file, &args);
        }
    }
}

#[test]
fn square_2d_binary_and_ascii() {
    check_all(&mesh("square_tri", 2, 0.1, true), &[]);
    check_all(&mesh("square_tri", 2, 0.1, false), &[]);
}

#[test]
fn block_3d_binary_and_ascii() {
    check_all(&mesh("block_tet", 3, 0.25, true), &[]);
    check_all(&mesh("block_tet", 3, 0.25, false), &[]);
}

#[test]
fn quads_hexahedra_and_y_slabs() {
    for (name, dim, h) in [("disc_quad", 2, 0.25), ("cube_hex", 3, 0.25)] {
        let file = mesh(name, dim, h, true);
        for ranks in [2, 3] {
            for partition in ["y-slabs", "rcb"] {
                check(ranks, &file, &["--partition", partition]);
            }
        }
    }
}

/// A large ASCII file is made binary by gmsh (here: any ASCII file, limit 0) and read by
/// byte ranges; the view is the one the ASCII file gives.
#[test]
fn ascii_converted_to_binary() {
    for (name, dim) in [("square_tri", 2), ("block_tet", 3)] {
        let file = mesh(name, dim, 0.25, false);
        for ranks in [1, 3] {
            check(ranks, &file, &["--partition", "rcb", "--ascii-limit", "0"]);
        }
    }
}

/// The partition line of `mesh-check`: "partition S: cells per rank MIN..MAX (ideal X), shared
/// nodes N, cut facets C".
struct Quality {
    min: f64,
    max: f64,
    ideal: f64,
    shared: f64,
    cut: f64,
}

fn quality(out: &str) -> Quality {
    let line = out.lines().find(|l| l.starts_with("partition ")).expect("partition line");
    let after = |label: &str| -> f64 {
        let rest = &line
            [line.find(label).unwrap_or_else(|| panic!("{label} in {line:?}")) + label.len()..];
        let rest = rest.split("..").next().unwrap_or("");
        let num: String = rest.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
        num.parse().unwrap_or_else(|_| panic!("{label} in {line:?}"))
    };
    Quality {
        min: after("cells per rank "),
        max: after(".."),
        ideal: after("(ideal "),
        shared: after("shared nodes "),
        cut: after("cut facets "),
    }
}

/// The largest number of closed intervals `[lo, hi]` that contain one point.
fn most_overlapping(intervals: &[(f64, f64)]) -> usize {
    // Openings before closings at the same place: closed intervals.
    let mut events: Vec<(f64, i32)> =
        intervals.iter().flat_map(|&(lo, hi)| [(lo, -1), (hi, 1)]).collect();
    events.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let (mut open, mut most) = (0i64, 0i64);
    for (_, e) in events {
        open -= e as i64;
        most = most.max(open);
    }
    most as usize
}

/// An upper bound, from the mesh alone, of the facets one plane `x_a = c` cuts when it splits
/// the cells by their centroids (the rcb bisection), over every position `c` and every axis
/// `a` of `axes`: the plane separates two cells sharing a facet exactly when it lies between
/// their centroids (ties of equal coordinates can go either way: the intervals are closed),
/// so the most such intervals through one point bound the cut. Simplices only (every set of
/// all nodes but one is a facet).
fn plane_cut_bound(mesh: &massfree::mesh::Mesh, axes: &[usize]) -> usize {
    let cells: Vec<Vec<usize>> = mesh.cells.iter().map(|c| c.nodes().to_vec()).collect();
    let centroid = |c: &[usize], a: usize| -> f64 {
        c.iter().map(|&v| mesh.coords[v][a]).sum::<f64>() / c.len() as f64
    };
    let mut facets: std::collections::HashMap<Vec<usize>, Vec<usize>> = Default::default();
    for (k, c) in cells.iter().enumerate() {
        assert_eq!(c.len(), mesh.dim + 1, "simplices only");
        for skip in 0..c.len() {
            let mut f: Vec<usize> = (0..c.len()).filter(|&i| i != skip).map(|i| c[i]).collect();
            f.sort_unstable();
            facets.entry(f).or_default().push(k);
        }
    }
    let mut cut = 0;
    for &a in axes {
        let x: Vec<f64> = cells.iter().map(|c| centroid(c, a)).collect();
        let pairs: Vec<(f64, f64)> = facets
            .values()
            .filter(|k| k.len() == 2)
            .map(|k| (x[k[0]].min(x[k[1]]), x[k[0]].max(x[k[1]])))
            .collect();
        cut = cut.max(most_overlapping(&pairs));
    }
    cut
}

/// rcb: parts within 10% of the ideal count (the smoothing keeps them within 3%), and compact:
/// cut facets within what its planes can cut, from the mesh's geometry. rcb cuts
/// p parts with p - 1 planes, each across the longest side of a part's box (for the block's
/// parts x, at least about 10/4 long against 1; for the disc and the ball any axis, and the
/// bound takes the largest), and each plane's cut is at most the most facets of the
/// whole mesh one plane across that axis can cut ([`plane_cut_bound`]: a part's cells are
/// some of the mesh's). The smoothing that follows moves a cell only when that lowers the cut
/// facets or keeps them (`partition::refine`), so the cut stays within `(p - 1)` times that
/// bound. The shared nodes are the nodes of cut facets (the cells around a node are connected
/// through facets that hold it): at most d a cut facet. METIS's cut is printed for
/// comparison (measured: rcb's 0.9-1.8 times METIS's on these meshes).
#[test]
fn rcb_is_balanced_and_compact() {
    for (name, dim, h, axes) in [
        ("disc_tri", 2, 0.1, &[0, 1][..]),
        ("sphere_tet", 3, 0.25, &[0, 1, 2][..]),
        ("block_tet", 3, 0.125, &[0][..]),
    ] {
        let file = mesh(name, dim, h, true);
        let whole = massfree::mesh::msh::read_msh(&file).unwrap();
        let plane_cut = plane_cut_bound(&whole, axes);
        for ranks in [2, 3, 4] {
            let r = quality(&check(ranks, &file, &["--partition", "rcb"]));
            let m = quality(&check(ranks, &file, &["--partition", "metis"]));
            let what = format!("{name} h = {h} on {ranks} ranks");
            let cut_bound = (ranks - 1) as f64 * plane_cut as f64;
            eprintln!(
                "{what}: rcb parts {}..{} (ideal {}), cut {} (bound {cut_bound}; metis {}), shared nodes {} (bound {}; metis {})",
                r.min, r.max, r.ideal, r.cut, m.cut, r.shared, dim as f64 * r.cut, m.shared
            );
            assert!(r.min >= 0.9 * r.ideal && r.max <= 1.1 * r.ideal, "{what}: rcb unbalanced");
            assert!(
                r.cut > 0.0 && r.cut <= cut_bound,
                "{what}: rcb cut {} beyond its planes' {cut_bound}",
                r.cut
            );
            assert!(
                r.shared > 0.0 && r.shared <= dim as f64 * r.cut,
                "{what}: rcb shared nodes {} for {} cut facets",
                r.shared,
                r.cut
            );
        }
    }
}

/// A truncated binary file: one line naming the file and the place, no panic, the same message
/// as the replicated reader's.
#[test]
fn truncated_binary_file_fails_alike() {
    let dir = scratch("distributed-mesh-truncated");
    let bytes = std::fs::read(mesh("block_tet", 3, 0.25, true)).unwrap();
    for frac in [0.001, 0.3, 0.97] {
        let cut = dir.join(format!("cut-{frac}.msh"));
        std::fs::write(&cut, &bytes[..(bytes.len() as f64 * frac) as usize]).unwrap();
        expect_failure(3, &cut, "truncated");
    }
}

/// `mesh-check` fails on both paths with the same message containing `culprit`.
fn expect_failure(ranks: usize, file: &Path, culprit: &str) {
    let o = massfree(ranks, &["mesh-check", file.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    let what = format!("{} on {ranks} rank(s)", file.display());
    assert!(!o.status.success(), "{what}: should fail\n{out}");
    assert!(out.contains("both paths fail alike"), "{what}: paths differ\n{out}\n{err}");
    let lines: Vec<&str> = err.lines().filter(|l| l.starts_with("massfree")).collect();
    assert_eq!(lines.len(), 1, "{what}: one error line expected:\n{err}");
    assert!(lines[0].contains("mesh error") && lines[0].contains(culprit), "{what}: {}", lines[0]);
    assert!(lines[0].contains(file.to_str().unwrap()), "{what}: the file is not named");
    assert!(!err.contains("panicked") && !err.contains("internal error"), "{what}: {err}");
}

// ---------------------------------------------------------------------------------------------
// Hand-made binary MSH 4.1 files.

/// An element block: entity dimension, entity tag, gmsh type, rows (tag, node tags...).
struct Block(i32, i32, i32, Vec<Vec<u64>>);

/// A binary MSH 4.1 file: physical names, entities (dim, tag, physical tags), one node block
/// per entry of `nodes` (tags, coordinates), element blocks.
fn write_binary(
    path: &Path,
    names: &[(i32, i32, &str)],
    entities: &[(usize, i32, Vec<i32>)],
    nodes: &[(Vec<u64>, Vec<[f64; 3]>)],
    blocks: &[Block],
) {
    let mut b: Vec<u8> = b"$MeshFormat\n4.1 1 8\n".to_vec();
    b.extend(1i32.to_le_bytes());
    b.extend(b"\n$EndMeshFormat\n$PhysicalNames\n");
    b.extend(format!("{}\n", names.len()).bytes());
    for (d, t, n) in names {
        b.extend(format!("{d} {t} \"{n}\"\n").bytes());
    }
    b.extend(b"$EndPhysicalNames\n$Entities\n");
    let size = |b: &mut Vec<u8>, v: u64| b.extend(v.to_le_bytes());
    let int = |b: &mut Vec<u8>, v: i32| b.extend(v.to_le_bytes());
    for d in 0..4 {
        size(&mut b, entities.iter().filter(|e| e.0 == d).count() as u64);
    }
    for d in 0..4 {
        for (_, tag, phys) in entities.iter().filter(|e| e.0 == d) {
            int(&mut b, *tag);
            for _ in 0..if d == 0 { 3 } else { 6 } {
                b.extend(0f64.to_le_bytes());
            }
            size(&mut b, phys.len() as u64);
            phys.iter().for_each(|&p| int(&mut b, p));
            if d > 0 {
                size(&mut b, 0);
            }
        }
    }
    b.extend(b"\n$EndEntities\n$Nodes\n");
    let all: Vec<u64> = nodes.iter().flat_map(|n| n.0.iter().copied()).collect();
    for v in [nodes.len() as u64, all.len() as u64, 1, *all.iter().max().unwrap()] {
        size(&mut b, v);
    }
    for (tags, xs) in nodes {
        [2, 1, 0].iter().for_each(|&v| int(&mut b, v));
        size(&mut b, tags.len() as u64);
        tags.iter().for_each(|&t| size(&mut b, t));
        xs.iter().flatten().for_each(|x| b.extend(x.to_le_bytes()));
    }
    b.extend(b"\n$EndNodes\n$Elements\n");
    let n: usize = blocks.iter().map(|k| k.3.len()).sum();
    for v in [blocks.len() as u64, n as u64, 1, n as u64] {
        size(&mut b, v);
    }
    for Block(d, e, t, rows) in blocks {
        [*d, *e, *t].iter().for_each(|&v| int(&mut b, v));
        size(&mut b, rows.len() as u64);
        rows.iter().flatten().for_each(|&v| size(&mut b, v));
    }
    b.extend(b"\n$EndElements\n");
    std::fs::write(path, b).unwrap();
}

/// A 4 x 2 grid of unit squares: node (i, j) has gmsh tag `tag(i, j)` (sparse, and written
/// out of order in two blocks), plus tag 7777 used by no cell. Cells: triangles and quads in
/// interleaved blocks, in surfaces 1 (physical "body") and 2 (no group); lines on curve 3
/// ("left") and curve 4 (no group); a point on point 5 ("corner"). `edit` changes the blocks.
fn grid_file(path: &Path, edit: impl Fn(&mut Vec<Block>)) {
    let tag = |i: u64, j: u64| 1000 - 37 * (5 * j + i);
    let x = |i: u64, j: u64| [i as f64, j as f64, 0.0];
    let mut first = (vec![], vec![]);
    let mut second = (vec![7777], vec![[9.0, 9.0, 0.0]]);
    for j in 0..3 {
        for i in 0..5 {
            let half = if (i + j) % 2 == 0 { &mut first } else { &mut second };
            half.0.push(tag(i, j));
            half.1.push(x(i, j));
        }
    }
    let tri = |t: u64, a: (u64, u64), b: (u64, u64), c: (u64, u64)| {
        vec![t, tag(a.0, a.1), tag(b.0, b.1), tag(c.0, c.1)]
    };
    let quad = |t: u64, i: u64, j: u64| {
        vec![t, tag(i, j), tag(i + 1, j), tag(i + 1, j + 1), tag(i, j + 1)]
    };
    let mut blocks = vec![
        Block(0, 5, 15, vec![vec![90, tag(0, 0)]]),
        Block(1, 3, 1, vec![vec![80, tag(0, 0), tag(0, 1)], vec![81, tag(0, 1), tag(0, 2)]]),
        Block(1, 4, 1, vec![vec![82, tag(4, 0), tag(4, 1)]]),
        Block(2, 1, 2, vec![tri(5, (0, 0), (1, 0), (1, 1)), tri(3, (0, 0), (1, 1), (0, 1))]),
        Block(2, 2, 3, vec![quad(40, 1, 0), quad(41, 2, 0), quad(42, 3, 1)]),
        Block(2, 1, 2, vec![tri(7, (3, 0), (4, 0), (4, 1)), tri(8, (3, 0), (4, 1), (3, 1))]),
        Block(2, 1, 3, vec![quad(43, 0, 1), quad(44, 1, 1), quad(45, 2, 1)]),
    ];
    edit(&mut blocks);
    write_binary(
        path,
        &[(2, 1, "body"), (1, 3, "left"), (0, 5, "corner")],
        &[(0, 5, vec![5]), (1, 3, vec![3]), (1, 4, vec![]), (2, 1, vec![1]), (2, 2, vec![])],
        &[first, second],
        &blocks,
    );
}

#[test]
fn hand_made_binary_file_with_mixed_kinds() {
    let dir = scratch("distributed-mesh-grid");
    let file = dir.join("grid.msh");
    grid_file(&file, |_| {});
    for ranks in 1..=4 {
        for partition in ["metis", "y-slabs", "rcb"] {
            check(ranks, &file, &["--partition", partition]);
        }
    }
    // An element outside the physical groups is not read further: a bad node tag there is
    // no error.
    let file = dir.join("ignored.msh");
    grid_file(&file, |b| b[2].3[0][1] = 4243);
    check(3, &file, &["--partition", "rcb"]);
}

#[test]
fn hand_made_binary_files_with_errors() {
    let dir = scratch("distributed-mesh-bad");
    let cases: [(&str, &str, fn(&mut Vec<Block>)); 5] = [
        ("missing", "references node tag 4242", |b| b[5].3[1][2] = 4242),
        ("unused", "belongs to no 2D cell", |b| b[1].3[1][2] = 7777),
        ("boundary-missing", "references node tag 4243", |b| b[1].3[0][1] = 4243),
        ("second-order", "unsupported gmsh element type 9", |b| b[4].2 = 9),
        ("dimension", "declares entity dimension 1", |b| b[4].0 = 1),
    ];
    for (name, culprit, edit) in cases {
        let file = dir.join(format!("{name}.msh"));
        grid_file(&file, edit);
        expect_failure(3, &file, culprit);
    }
    // A node tag twice: the second block repeats one of the first.
    let file = dir.join("duplicate.msh");
    grid_file(&file, |_| {});
    let mut bytes = std::fs::read(&file).unwrap();
    let (a, b) = (1000u64.to_le_bytes(), 7777u64.to_le_bytes());
    let nodes = bytes.windows(7).position(|w| w == b"$Nodes\n").unwrap() + 7 + 32;
    let at = nodes + bytes[nodes..].windows(8).position(|w| w == b).unwrap();
    bytes[at..at + 8].copy_from_slice(&a);
    std::fs::write(&file, bytes).unwrap();
    expect_failure(2, &file, "node tag 1000 appears twice");
}
