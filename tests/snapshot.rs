//! `post --snapshot` and `compare --snapshot`: pictures of a field on the deformed mesh. Most
//! tests write small synthetic run files (the layout `RunReader` reads: mesh coordinates and
//! cells, `/fields/<name>` with its own time and step axes) whose pictures are known, run the
//! real binary and read the PNG back pixel by pixel; one draws a real run.

mod common;

use common::*;
use massfree::post::snapshot::{viridis, COLOUR_BAR_WIDTH};
use std::path::{Path, PathBuf};
use std::process::Output;

/// A field of a synthetic run: `outputs` = (time, step, values of all entries x components).
struct Field {
    name: &'static str,
    comps: usize,
    outputs: Vec<(f64, u64, Vec<f64>)>,
}

/// A mesh: node coordinates and cells of one kind (dataset name, nodes per cell, connectivity).
struct Mesh {
    coords: Vec<[f64; 3]>,
    kind: &'static str,
    per_cell: usize,
    cells: Vec<Vec<u64>>,
}

impl Mesh {
    fn n_cells(&self) -> usize {
        self.cells.len()
    }
    fn centroid(&self, c: usize) -> [f64; 3] {
        let n = self.cells[c].len() as f64;
        std::array::from_fn(|k| {
            self.cells[c].iter().map(|&v| self.coords[v as usize][k]).sum::<f64>() / n
        })
    }
}

/// [0, lx] x [0, ly] in nx x ny quadrilaterals (gmsh order: counterclockwise).
fn rectangle(lx: f64, ly: f64, nx: usize, ny: usize) -> Mesh {
    let mut coords = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            coords.push([lx * i as f64 / nx as f64, ly * j as f64 / ny as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u64;
    let mut cells = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            cells.push(vec![id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    Mesh { coords, kind: "quadrilateral", per_cell: 4, cells }
}

/// The unit cube in n^3 hexahedra (gmsh order: bottom face counterclockwise seen from +z, then
/// the top face above it).
fn cube(n: usize) -> Mesh {
    let mut coords = Vec::new();
    for k in 0..=n {
        for j in 0..=n {
            for i in 0..=n {
                coords.push([i as f64 / n as f64, j as f64 / n as f64, k as f64 / n as f64]);
            }
        }
    }
    let id = |i: usize, j: usize, k: usize| ((k * (n + 1) + j) * (n + 1) + i) as u64;
    let mut cells = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let b = [id(i, j, k), id(i + 1, j, k), id(i + 1, j + 1, k), id(i, j + 1, k)];
                let t = [
                    id(i, j, k + 1),
                    id(i + 1, j, k + 1),
                    id(i + 1, j + 1, k + 1),
                    id(i, j + 1, k + 1),
                ];
                cells.push([b, t].concat());
            }
        }
    }
    Mesh { coords, kind: "hexahedron", per_cell: 8, cells }
}

/// Write a run file with `mesh` and `fields` in the layout of the program's writer.
fn write_run(path: &Path, mesh: &Mesh, fields: &[Field]) {
    let f = hdf5::File::create(path).unwrap();
    let m = f.create_group("mesh").unwrap();
    let n = mesh.coords.len();
    let flat: Vec<f64> = mesh.coords.iter().flatten().copied().collect();
    m.new_dataset_builder()
        .with_data(&ndarray::Array2::from_shape_vec((n, 3), flat).unwrap())
        .create("coordinates")
        .unwrap();
    let cg = m.create_group("cells").unwrap();
    let conn: Vec<u64> = mesh.cells.iter().flatten().copied().collect();
    cg.new_dataset_builder()
        .with_data(&ndarray::Array2::from_shape_vec((mesh.n_cells(), mesh.per_cell), conn).unwrap())
        .create(mesh.kind)
        .unwrap();
    let fg = f.create_group("fields").unwrap();
    for fd in fields {
        let k = fd.outputs.len();
        let rows = fd.outputs.first().map_or(0, |o| o.2.len() / fd.comps);
        let all: Vec<f64> = fd.outputs.iter().flat_map(|o| o.2.iter().copied()).collect();
        fg.new_dataset_builder()
            .with_data(&ndarray::Array3::from_shape_vec((k, rows, fd.comps), all).unwrap())
            .create(fd.name)
            .unwrap();
        let times: Vec<f64> = fd.outputs.iter().map(|o| o.0).collect();
        let steps: Vec<f64> = fd.outputs.iter().map(|o| o.1 as f64).collect();
        fg.new_dataset_builder()
            .with_data(times.as_slice())
            .create(format!("{}_time", fd.name).as_str())
            .unwrap();
        fg.new_dataset_builder()
            .with_data(steps.as_slice())
            .create(format!("{}_step", fd.name).as_str())
            .unwrap();
    }
}

/// A cell field of one component: `value(centroid)` per cell, written at the given outputs.
fn cell_field(
    name: &'static str,
    mesh: &Mesh,
    outputs: &[(f64, u64)],
    value: impl Fn([f64; 3]) -> f64,
) -> Field {
    let v: Vec<f64> = (0..mesh.n_cells()).map(|c| value(mesh.centroid(c))).collect();
    Field { name, comps: 1, outputs: outputs.iter().map(|&(t, s)| (t, s, v.clone())).collect() }
}

/// A nodal field: `value(x)` (comps values) per node.
fn nodal_field(
    name: &'static str,
    mesh: &Mesh,
    comps: usize,
    outputs: &[(f64, u64)],
    value: impl Fn([f64; 3], f64) -> Vec<f64>,
) -> Field {
    Field {
        name,
        comps,
        outputs: outputs
            .iter()
            .map(|&(t, s)| (t, s, mesh.coords.iter().flat_map(|&x| value(x, t)).collect()))
            .collect(),
    }
}

/// The binary alone (post and compare are serial). HDF5's file locks are off: a run file
/// written by this process can be inherited, still locked, by a child that another test
/// thread started meanwhile (the descriptors are not closed on exec).
fn snapshot_cmd(args: &[&str]) -> Output {
    output(
        std::process::Command::new(bin())
            .args(args)
            .env("HDF5_USE_FILE_LOCKING", "FALSE")
            .env("RUST_BACKTRACE", "0"),
    )
}

fn run_ok(args: &[&str]) -> String {
    let o = snapshot_cmd(args);
    assert!(
        o.status.success(),
        "massfree {args:?} failed:\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).to_string()
}

/// Decodes the PNG at `path`: (width, height, RGB pixels row by row).
fn decode(path: &Path) -> (usize, usize, Vec<[u8; 3]>) {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    let ch = info.color_type.samples();
    let px = buf[..info.buffer_size()].chunks(ch).map(|c| [c[0], c[1], c[2]]).collect();
    (info.width as usize, info.height as usize, px)
}

/// The colour map's parameter t of a pixel, when the pixel has a colour of the map.
fn map_t(p: [u8; 3]) -> Option<f64> {
    let (mut best, mut at) = (i32::MAX, 0.0);
    for k in 0..=512 {
        let t = k as f64 / 512.0;
        let c = viridis(t);
        let d = (0..3).map(|i| (p[i] as i32 - c[i] as i32).abs()).max().unwrap();
        if d < best {
            best = d;
            at = t;
        }
    }
    (best <= 3).then_some(at)
}

/// A picture read back: the pixels of the mesh (map colours left of the colour bar).
struct Picture {
    w: usize,
    h: usize,
    /// (x, y, t) of every pixel drawn in a colour of the map, left of the colour bar.
    mesh: Vec<(usize, usize, f64)>,
    px: Vec<[u8; 3]>,
}

impl Picture {
    fn read(path: &Path) -> Picture {
        let (w, h, px) = decode(path);
        let right = w - COLOUR_BAR_WIDTH as usize;
        let mut mesh = Vec::new();
        let mut seen = std::collections::HashMap::new();
        for y in 0..h {
            for x in 0..right {
                let p = px[y * w + x];
                if let Some(t) = *seen.entry(p).or_insert_with(|| map_t(p)) {
                    mesh.push((x, y, t));
                }
            }
        }
        Picture { w, h, mesh, px }
    }
    /// (x0, x1, y0, y1) of the mesh pixels with t in `ts`.
    fn bbox(&self, ts: std::ops::RangeInclusive<f64>) -> (usize, usize, usize, usize) {
        let sel: Vec<_> = self.mesh.iter().filter(|p| ts.contains(&p.2)).collect();
        assert!(!sel.is_empty(), "no mesh pixel with t in {ts:?}");
        (
            sel.iter().map(|p| p.0).min().unwrap(),
            sel.iter().map(|p| p.0).max().unwrap(),
            sel.iter().map(|p| p.1).min().unwrap(),
            sel.iter().map(|p| p.1).max().unwrap(),
        )
    }
    fn count(&self, ts: std::ops::RangeInclusive<f64>) -> usize {
        self.mesh.iter().filter(|p| ts.contains(&p.2)).count()
    }
}

const LOW: std::ops::RangeInclusive<f64> = 0.0..=0.03;
const HIGH: std::ops::RangeInclusive<f64> = 0.97..=1.0;
const MID: std::ops::RangeInclusive<f64> = 0.47..=0.53;

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A 2 x 1 rectangle with the cell field `mark` (0 on the left half, 1 on the right) and a
/// uniform displacement (0.5, 0.25) at t = 1 (step 10), none at t = 0.
fn marked_rectangle(dir: &Path, name: &str, high: f64) -> PathBuf {
    let mesh = rectangle(2.0, 1.0, 8, 4);
    let outs = [(0.0, 0), (1.0, 10)];
    let mark = cell_field("mark", &mesh, &outs, |c| if c[0] < 1.0 { 0.0 } else { high });
    let disp = nodal_field("displacement", &mesh, 2, &outs, |_, t| vec![0.5 * t, 0.25 * t]);
    let path = dir.join(format!("{name}.h5"));
    write_run(&path, &mesh, &[mark, disp]);
    path
}

#[test]
fn a_cell_field_is_drawn_cell_by_cell_at_equal_scale() {
    let dir = scratch("snapshot-cells");
    let h5 = marked_rectangle(&dir, "rect", 1.0);
    let out = run_ok(&["post", path_str(&h5), "--snapshot", "mark", "--time", "0"]);
    let png = dir.join("rect-post-snapshot-mark.png");
    assert!(out.contains(&format!("wrote {}", png.display())), "{out}");
    assert!(out.contains("mark in [0, 1]"), "{out}");
    let pic = Picture::read(&png);
    // The 2 x 1 mesh with a margin of 3% of its width (2.12 x 1.12) fitted into the 720 x 560
    // drawing area: 720 x 380 pixels, plus axes, title and colour bar.
    assert_eq!((pic.w, pic.h), (10 + 80 + 720 + 16 + 130, 40 + 30 + 8 + 380 + 54 + 6));
    // Only the map's two ends: the left half low, the right half high.
    let (low, high) = (pic.count(LOW), pic.count(HIGH));
    assert!(low > 10_000 && high > 10_000, "low {low}, high {high} pixels");
    assert!(pic.mesh.len() - low - high < (low + high) / 50, "other colours on a 0/1 field");
    let (l, h) = (pic.bbox(LOW), pic.bbox(HIGH));
    assert!(l.1 <= h.0 + 1, "low pixels reach x = {} right of the high ones from x = {}", l.1, h.0);
    assert!((low as f64 / high as f64 - 1.0).abs() < 0.05, "halves of {low} and {high} pixels");
    // x and y at the same scale: the 2 x 1 mesh is drawn twice as wide as high.
    let all = pic.bbox(0.0..=1.0);
    let ratio = (all.1 - all.0 + 1) as f64 / (all.3 - all.2 + 1) as f64;
    assert!((ratio - 2.0).abs() < 0.03, "aspect {ratio}");
    // --size bounds the drawing area: 360 x 190 for the 2.12 x 1.12 box in 360 x 280.
    run_ok(&["post", path_str(&h5), "--snapshot", "mark", "--size", "360x280"]);
    let small = Picture::read(&png);
    assert_eq!((small.w, small.h), (10 + 80 + 360 + 16 + 130, 40 + 30 + 8 + 190 + 54 + 6));
    // A long thin bar gets a taller drawing area than its shape (160 pixels at least), but is
    // still drawn at its own aspect ratio, 20 : 1.
    let bar = rectangle(10.0, 0.5, 40, 2);
    let f = cell_field("mark", &bar, &[(0.0, 0)], |c| c[0]);
    let thin = dir.join("bar.h5");
    write_run(&thin, &bar, &[f]);
    run_ok(&["post", path_str(&thin), "--snapshot", "mark"]);
    let b = Picture::read(&dir.join("bar-post-snapshot-mark.png")).bbox(0.0..=1.0);
    let ratio = (b.1 - b.0 + 1) as f64 / (b.3 - b.2 + 1) as f64;
    assert!((ratio / 20.0 - 1.0).abs() < 0.06, "bar drawn at aspect {ratio}");
    // Text was drawn (title, ticks): dark pixels outside the mesh.
    let dark = pic.px.iter().filter(|p| p.iter().all(|&c| c < 80)).count();
    assert!(dark > 300, "{dark} dark pixels");
}

#[test]
fn a_nodal_field_is_interpolated_over_each_cell() {
    let dir = scratch("snapshot-nodal");
    let mesh = rectangle(2.0, 1.0, 4, 2);
    let f = nodal_field("x", &mesh, 1, &[(0.0, 0)], |x, _| vec![x[0]]);
    let h5 = dir.join("lin.h5");
    write_run(&h5, &mesh, &[f]);
    run_ok(&["post", path_str(&h5), "--snapshot", "x", "--prefix", path_str(&dir.join("p"))]);
    let pic = Picture::read(&dir.join("p-snapshot-x.png"));
    // Along the middle row, t grows with x from 0 to 1 (a linear field is drawn exactly).
    let (x0, x1, y0, y1) = pic.bbox(0.0..=1.0);
    let y = (y0 + y1) / 2;
    let row: Vec<(usize, f64)> = pic.mesh.iter().filter(|p| p.1 == y).map(|p| (p.0, p.2)).collect();
    assert!(row.len() > (x1 - x0) * 9 / 10, "row {y} has {} mesh pixels", row.len());
    for (x, t) in &row {
        let expected = (*x as f64 + 0.5 - x0 as f64) / (x1 - x0 + 1) as f64;
        assert!((t - expected).abs() < 0.02, "x = {x}: t = {t}, expected {expected}");
    }
}

#[test]
fn the_drawing_moves_with_the_displacement() {
    let dir = scratch("snapshot-moves");
    let h5 = marked_rectangle(&dir, "rect", 1.0);
    let bbox = |extra: &[&str]| {
        let prefix = dir.join("p");
        let mut args =
            vec!["post", path_str(&h5), "--snapshot", "mark", "--prefix", path_str(&prefix)];
        args.extend_from_slice(&["--window", "-1,4,-1,3"]);
        args.extend_from_slice(extra);
        let out = run_ok(&args);
        (Picture::read(&dir.join("p-snapshot-mark.png")).bbox(0.0..=1.0), out)
    };
    let (b0, out0) = bbox(&["--time", "0"]);
    assert!(out0.contains("t = 0 (step 0), mesh deformed by the displacement"), "{out0}");
    // The window 5 x 4 in 720 x 560 pixels: 560 / 4 = 140 pixels per unit.
    let s = (b0.1 - b0.0 + 1) as f64 / 2.0;
    assert!((s - 140.0).abs() < 1.5, "{s} pixels per unit");
    let shift = |b: (usize, usize, usize, usize)| {
        (
            b.0 as f64 - b0.0 as f64,
            b.1 as f64 - b0.1 as f64,
            b0.2 as f64 - b.2 as f64,
            b0.3 as f64 - b.3 as f64,
        )
    };
    for (extra, k) in
        [(&["--time", "1"][..], 1.0), (&["--step", "10"][..], 1.0), (&["--magnify", "2"][..], 2.0)]
    {
        let (b, _) = bbox(extra);
        let d = shift(b);
        for (got, want) in
            [(d.0, 0.5 * k * s), (d.1, 0.5 * k * s), (d.2, 0.25 * k * s), (d.3, 0.25 * k * s)]
        {
            assert!(
                (got - want).abs() <= 1.5,
                "{extra:?}: moved {d:?} pixels, expected ({}, {}) in x, y",
                0.5 * k * s,
                0.25 * k * s
            );
        }
    }
}

#[test]
fn without_a_displacement_the_mesh_is_drawn_undeformed() {
    let dir = scratch("snapshot-undeformed");
    let mesh = rectangle(2.0, 1.0, 4, 2);
    let f = cell_field("mark", &mesh, &[(0.5, 5)], |c| c[0]);
    let h5 = dir.join("plain.h5");
    write_run(&h5, &mesh, &[f]);
    let out = run_ok(&["post", path_str(&h5), "--snapshot", "mark", "--edges"]);
    assert!(
        out.contains("t = 0.5 (step 5), undeformed: no displacement written at t = 0.5"),
        "{out}"
    );
    let pic = Picture::read(&dir.join("plain-post-snapshot-mark.png"));
    assert!(pic.mesh.len() > 50_000);
    // --edges: dark lines inside the mesh's box.
    let (x0, x1, y0, y1) = pic.bbox(0.0..=1.0);
    let lines = (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .filter(|&(x, y)| map_t(pic.px[y * pic.w + x]).is_none())
        .count();
    assert!(lines > 2 * (x1 - x0), "{lines} edge pixels");
}

#[test]
fn a_tensor_is_drawn_by_a_chosen_component() {
    let dir = scratch("snapshot-tensor");
    let mesh = rectangle(2.0, 1.0, 4, 2);
    // xx = 1 on the left, yy = 1 on the right, xy = 0.5 everywhere.
    let v: Vec<f64> = (0..mesh.n_cells())
        .flat_map(|c| {
            let right = mesh.centroid(c)[0] > 1.0;
            let (xx, yy) = if right { (0.0, 1.0) } else { (1.0, 0.0) };
            [xx, 0.5, 0.0, yy, 0.0, 0.0]
        })
        .collect();
    let f = Field { name: "stress", comps: 6, outputs: vec![(0.0, 0, v)] };
    let h5 = dir.join("t.h5");
    write_run(&h5, &mesh, &[f]);
    let prefix = dir.join("p");
    let png = dir.join("p-snapshot-stress.png");
    for (c, left_high) in [("yy", false), ("xx", true)] {
        let out = run_ok(&[
            "post",
            path_str(&h5),
            "--snapshot",
            "stress",
            "--component",
            c,
            "--prefix",
            path_str(&prefix),
        ]);
        assert!(out.contains(&format!("stress {c} in [0, 1]")), "{out}");
        let pic = Picture::read(&png);
        let (l, h) = (pic.bbox(LOW), pic.bbox(HIGH));
        assert_eq!(h.0 < l.0, left_high, "--component {c}: high at x {h:?}, low at {l:?}");
    }
    // The default is the Frobenius norm: equal on both halves (sqrt(1 + 2 * 0.25)).
    let out =
        run_ok(&["post", path_str(&h5), "--snapshot", "stress", "--prefix", path_str(&prefix)]);
    assert!(out.contains("stress Frobenius norm in [1.22474, 1.22474]; colours over"), "{out}");
    let pic = Picture::read(&png);
    assert!(pic.count(MID) > pic.mesh.len() * 95 / 100, "a constant field takes the middle colour");
}

#[test]
fn two_runs_side_by_side_share_one_colour_range() {
    let dir = scratch("snapshot-two");
    let a = marked_rectangle(&dir, "a", 1.0);
    let b = marked_rectangle(&dir, "b", 2.0);
    let prefix = dir.join("ab");
    let out = run_ok(&[
        "compare",
        path_str(&a),
        path_str(&b),
        "--snapshot",
        "mark",
        "--label",
        "A",
        "--label",
        "B",
        "--prefix",
        path_str(&prefix),
    ]);
    assert!(out.contains("mark in [0, 2]"), "{out}");
    let pic = Picture::read(&dir.join("ab-snapshot-mark.png"));
    // Two panels of 480 x 240 drawing areas and one colour bar.
    assert_eq!(pic.w, 2 * (10 + 80 + 480 + 16) + 130);
    let half = (pic.w - COLOUR_BAR_WIDTH as usize) / 2;
    let left = |p: &&(usize, usize, f64)| p.0 < half;
    let count = |side: bool, ts: std::ops::RangeInclusive<f64>| {
        pic.mesh.iter().filter(|p| left(p) == side && ts.contains(&p.2)).count()
    };
    // Run a (0 and 1) on the left: low and middle colours; run b (0 and 2): low and high.
    assert!(count(true, LOW) > 5000 && count(true, MID) > 5000, "left panel");
    assert_eq!(count(true, HIGH), 0, "the left panel has its own colour range");
    assert!(count(false, LOW) > 5000 && count(false, HIGH) > 5000, "right panel");
    assert_eq!(count(false, MID), 0);
}

#[test]
fn a_3d_run_is_drawn_by_its_boundary_faces_along_the_view() {
    let dir = scratch("snapshot-3d");
    let mesh = cube(3);
    let z = nodal_field("z", &mesh, 1, &[(0.0, 0)], |x, _| vec![x[2]]);
    let layer = cell_field("layer", &mesh, &[(0.0, 0)], |c| c[2]);
    let h5 = dir.join("cube.h5");
    write_run(&h5, &mesh, &[z, layer]);
    let prefix = dir.join("p");
    for field in ["z", "layer"] {
        let png = dir.join(format!("p-snapshot-{field}.png"));
        let draw = |view: &str| {
            run_ok(&[
                "post",
                path_str(&h5),
                "--snapshot",
                field,
                "--view",
                view,
                "--prefix",
                path_str(&prefix),
            ]);
            Picture::read(&png)
        };
        // From above (looking along -z) only the top face shows: all high; from below all low.
        let top = draw("-z");
        assert!(top.count(HIGH) > 50_000, "{field}: top face");
        assert!(
            top.count(HIGH) > top.mesh.len() * 99 / 100,
            "{field}: from above, not only the top face"
        );
        let bottom = draw("+z");
        assert!(bottom.count(LOW) > bottom.mesh.len() * 99 / 100, "{field}: from below");
        // From the front (looking along +y, z up): low at the bottom, high at the top.
        let front = draw("+y");
        let (l, h) = (front.bbox(LOW), front.bbox(HIGH));
        assert!(h.3 < l.2, "{field}: high at rows {h:?}, low at {l:?}");
    }
}

/// Two cubes one behind the other along y: the nearer one hides the farther one.
#[test]
fn a_nearer_body_hides_a_farther_one() {
    let dir = scratch("snapshot-hidden");
    let mut mesh = cube(2);
    let n = mesh.coords.len() as u64;
    let far: Vec<[f64; 3]> = mesh.coords.iter().map(|x| [x[0], x[1] + 2.0, x[2]]).collect();
    mesh.coords.extend(far);
    let cells: Vec<Vec<u64>> =
        mesh.cells.iter().map(|c| c.iter().map(|v| v + n).collect()).collect();
    mesh.cells.extend(cells);
    // Value 0 in the cube at y in [0, 1], 1 in the one at y in [2, 3].
    let f = cell_field("body", &mesh, &[(0.0, 0)], |c| if c[1] < 1.5 { 0.0 } else { 1.0 });
    let h5 = dir.join("two.h5");
    write_run(&h5, &mesh, &[f]);
    let png = dir.join("two-post-snapshot-body.png");
    for (view, seen) in [("+y", LOW), ("-y", HIGH)] {
        run_ok(&["post", path_str(&h5), "--snapshot", "body", "--view", view]);
        let pic = Picture::read(&png);
        assert!(pic.count(seen.clone()) > 100_000, "--view {view}");
        assert!(pic.count(seen) > pic.mesh.len() * 99 / 100, "--view {view}: the far cube shows");
    }
}

fn fails(args: &[&str]) -> String {
    let o = snapshot_cmd(args);
    let err = String::from_utf8_lossy(&o.stderr).trim().to_string();
    assert!(
        !o.status.success(),
        "{args:?} should fail; stdout: {}",
        String::from_utf8_lossy(&o.stdout)
    );
    assert_eq!(err.lines().count(), 1, "{args:?}: not one line:\n{err}");
    assert!(!err.contains("panic") && !err.contains("internal error"), "{err}");
    err
}

#[test]
fn mistakes_are_one_line_naming_the_culprit() {
    let dir = scratch("snapshot-errors");
    let h5 = marked_rectangle(&dir, "rect", 1.0);
    let r = path_str(&h5);
    let e = fails(&["post", r, "--snapshot", "stress"]);
    assert!(e.contains("--snapshot stress") && e.contains("written: displacement, mark"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--time", "0.6"]);
    assert!(e.contains("--time 0.6") && e.contains("nearest written: 0, 1"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--step", "7"]);
    assert!(e.contains("--step 7") && e.contains("nearest written: 0, 10"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--time", "1", "--step", "10"]);
    assert!(e.contains("--time and --step"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--component", "x"]);
    assert!(e.contains("--component x") && e.contains("scalar"), "{e}");
    let e = fails(&["post", r, "--snapshot", "displacement", "--component", "z"]);
    assert!(e.contains("--component z") && e.contains("x, y or magnitude"), "{e}");
    for w in ["1,0,0,1", "0,1,0", "a,b,c,d"] {
        let e = fails(&["post", r, "--snapshot", "mark", "--window", w]);
        assert!(e.contains(&format!("--window {w}")), "{e}");
    }
    let e = fails(&["post", r, "--snapshot", "mark", "--window", "10,11,-5,-4"]);
    assert!(e.contains("shows no part of the mesh") && e.contains("in x"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--magnify", "big"]);
    assert!(e.contains("--magnify big"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--range", "1,0"]);
    assert!(e.contains("--range 1,0"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--view", "+x"]);
    assert!(e.contains("--view +x") && e.contains("2D"), "{e}");
    for size in ["100x400", "400", "axb"] {
        let e = fails(&["post", r, "--snapshot", "mark", "--size", size]);
        assert!(e.contains(&format!("--size {size}: expected WxH")), "{e}");
    }
    let e = fails(&["post", r, "--snapshot", "mark", "--view", "up"]);
    assert!(e.contains("--view up"), "{e}");
    let e = fails(&["post", r, "--time", "1"]);
    assert!(e.contains("--time needs --snapshot"), "{e}");
    let e = fails(&["compare", r, r, "--window", "0,1,0,1"]);
    assert!(e.contains("--window needs --snapshot"), "{e}");
    let e = fails(&["post", r, "--snapshot", "mark", "--node", "0,0"]);
    assert!(e.contains("--snapshot draws only the picture"), "{e}");
    let missing = dir.join("missing.h5");
    let e = fails(&["post", path_str(&missing), "--snapshot", "mark"]);
    assert!(e.contains("missing.h5"), "{e}");
    let e = fails(&["compare", r, path_str(&missing), "--snapshot", "mark"]);
    assert!(e.contains("missing.h5"), "{e}");
}

/// A real run (the default scene, 60 steps on 2 ranks): its velocity on the deformed disc.
#[test]
fn a_real_run_draws_its_velocity() {
    let dir = scratch("snapshot-run");
    let scene = scene_variant("disc.toml", &dir, &[("steps = 1000", "steps = 60")]);
    run_scene(2, &scene, &[]);
    let h5 = dir.join("disc-2.h5");
    let prefix = dir.join("v");
    let out = run_ok(&[
        "post",
        path_str(&h5),
        "--snapshot",
        "velocity",
        "--edges",
        "--prefix",
        path_str(&prefix),
    ]);
    assert!(out.contains("t = 6e-5 (step 60), mesh deformed by the displacement"), "{out}");
    let pic = Picture::read(&dir.join("v-snapshot-velocity.png"));
    // The disc (radius 8) fills a 560 x 560 drawing area: its area is about pi/4 of it.
    let (x0, x1, y0, y1) = pic.bbox(0.0..=1.0);
    let (dx, dy) = ((x1 - x0) as f64, (y1 - y0) as f64);
    assert!((dx / dy - 1.0).abs() < 0.02, "disc drawn {dx} x {dy}");
    assert!(pic.mesh.len() as f64 > 0.6 * dx * dy, "{} mesh pixels", pic.mesh.len());
    // At step 60 the disc has not touched yet (its first contact is at step 63): it moves as a
    // rigid body at 800, which the midpoint rule keeps exactly, so |v| = 800 at every node to
    // round-off (the printed range)...
    let range = out
        .split("velocity magnitude in [")
        .nth(1)
        .and_then(|r| r.split(']').next())
        .unwrap_or_else(|| panic!("no range printed: {out}"));
    let (lo, hi) = range.split_once(',').map(|(a, b)| (a.trim(), b.trim())).unwrap();
    for x in [lo, hi] {
        let v: f64 = x.parse().unwrap_or_else(|_| panic!("range [{range}]"));
        assert!((v - 800.0).abs() <= 1e-6 * 800.0, "|v| in [{range}], not 800");
    }
    // ... and drawn with the colours of [0, 1000], every pixel of the disc has the colour of
    // 0.8 (within the map's 8-bit steps, 1/256).
    run_ok(&[
        "post",
        path_str(&h5),
        "--snapshot",
        "velocity",
        "--range",
        "0,1000",
        "--prefix",
        path_str(&prefix),
    ]);
    let pic = Picture::read(&dir.join("v-snapshot-velocity.png"));
    let off: Vec<_> = pic.mesh.iter().filter(|p| (p.2 - 0.8).abs() > 1.0 / 256.0).collect();
    eprintln!("|v| in [{range}]; {} of {} disc pixels off 0.8", off.len(), pic.mesh.len());
    assert!(
        off.len() * 1000 < pic.mesh.len(),
        "{} of {} pixels of the disc not at 0.8 of the map, e.g. {:?}",
        off.len(),
        pic.mesh.len(),
        &off[..off.len().min(5)]
    );
}
