//! The XDMF index with the real readers (issue 13): ParaView 5.11's `XDMFReader`,
//! `Xdmf3ReaderS` and `Xdmf3ReaderT` and meshio's time-series reader must show every field at
//! the first and the last time with the values of the HDF5 file (tools/check-xdmf.py does the
//! reading and comparing), for a 2D and a 3D run on 2 ranks and for a synthetic run file with a
//! mixed triangle + quadrilateral mesh, a cell scalar and a symmetric tensor (6 components).
//! A negative control shows the check fails on the HyperSlab items the index used before.
//!
//! Needs paraview, python3-paraview, python3-meshio, python3-h5py, xvfb and xauth (`./run test`
//! installs them): Debian's ParaView renders through X only, so the checks run under
//! `xvfb-run -a`.

mod common;
use common::*;
use massfree::io::xdmf::{write_xdmf, XdmfLayout};
use massfree::io::FieldSpec;
use massfree::mesh::ElementKind;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

/// One check at a time: `xvfb-run -a` picks a free display number racily, and pvbatch
/// renders on the two shared cores.
static PVBATCH: Mutex<()> = Mutex::new(());

/// Run tools/check-xdmf.py on `xdmf` (with a rendering into `png`); its output, and whether
/// every check passed.
fn check_xdmf(xdmf: &Path, png: Option<&Path>) -> (String, bool) {
    for tool in ["pvbatch", "xvfb-run", "/usr/bin/python3"] {
        let found = Command::new("sh")
            .args(["-c", &format!("command -v {tool}")])
            .status()
            .is_ok_and(|s| s.success());
        assert!(
            found,
            "{tool} is missing: `./run test` installs paraview python3-paraview python3-meshio \
             python3-h5py xvfb xauth"
        );
    }
    let _one = PVBATCH.lock().unwrap_or_else(|e| e.into_inner());
    let run = || {
        let mut cmd = Command::new("xvfb-run");
        cmd.args(["-a", "-s", "-screen 0 1280x1024x24"])
            .arg(repo().join("tools/check-xdmf.py"))
            .arg(xdmf);
        if let Some(png) = png {
            cmd.arg("--png").arg(png);
        }
        output(&mut cmd)
    };
    // Another process's xvfb-run may take the same display number at the same moment (the
    // choice is racy across processes): pvbatch then finds no X server. Only that is retried.
    let mut o = run();
    for _ in 0..2 {
        if !String::from_utf8_lossy(&o.stdout).contains("bad X server connection") {
            break;
        }
        std::thread::sleep(std::time::Duration::from_secs(2));
        o = run();
    }
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(out.contains("check-xdmf: "), "tools/check-xdmf.py did not finish:\n{out}\n{err}");
    (out, o.status.success())
}

/// The check passes, with the checks `expect` among its lines.
fn assert_readers_agree(xdmf: &Path, png: Option<&Path>, expect: &[String]) -> String {
    let (out, ok) = check_xdmf(xdmf, png);
    let failed: Vec<&str> = out.lines().filter(|l| l.starts_with("FAIL")).collect();
    assert!(ok && failed.is_empty(), "{}:\n{}\n\n{out}", xdmf.display(), failed.join("\n"));
    for e in expect {
        assert!(
            out.lines().any(|l| l.starts_with("ok") && l.contains(e.as_str())),
            "no {e:?} in\n{out}"
        );
    }
    out
}

/// A rendering that shows something: 800 x 600, a fiftieth of it not background (the bodies
/// are slender), in many colours.
fn assert_picture(png: &Path) {
    let bytes = std::fs::read(png).unwrap_or_else(|e| panic!("{}: {e}", png.display()));
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    let mut reader = png::Decoder::new(std::io::Cursor::new(bytes)).read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (800, 600));
    let ch = info.color_type.samples();
    assert!(ch >= 3, "colour PNG expected, got {:?}", info.color_type);
    let px: Vec<[u8; 3]> =
        buf[..info.buffer_size()].chunks(ch).map(|c| [c[0], c[1], c[2]]).collect();
    let background = px[0];
    let shown: Vec<&[u8; 3]> = px.iter().filter(|p| **p != background).collect();
    let mut colours: Vec<[u8; 3]> = shown.iter().map(|p| **p).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(shown.len() * 50 > px.len(), "{}: only {} pixels drawn", png.display(), shown.len());
    assert!(colours.len() > 50, "{}: only {} colours", png.display(), colours.len());
}

/// The ok-lines every reader must print for `field` (`where` = point or cell) at time `t`.
fn every_reader(at: &str, where_: &str, field: &str, row: usize) -> Vec<String> {
    ["XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT"]
        .iter()
        .map(|r| format!("{r} t={at}: {where_} field {field} = row {row} "))
        .collect()
}

fn run_and_check(scene: &Path, png_name: &str, expect: &[String]) {
    run_scene(2, scene, &[]);
    let dir = scene.parent().unwrap();
    let stem = scene.file_stem().unwrap().to_string_lossy();
    let xdmf = dir.join(format!("{stem}-2.xdmf"));
    let png = dir.join(png_name);
    let out = assert_readers_agree(&xdmf, Some(&png), expect);
    assert!(out.contains("OpenDataFile picks Xdmf3ReaderS"), "{out}");
    assert_picture(&png);
}

/// The 2D beam on 2 ranks, displacement every 5 steps and velocity every 10 (fields with
/// their own periods: velocity is absent from some steps).
#[test]
fn a_2d_run_reads_alike_in_every_reader() {
    let dir = scratch("paraview-2d");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[
            ("steps = 250", "steps = 20"),
            ("error_steps = [30, 250]", "error_steps = [20]"),
            (
                "every = 10",
                "every = 5\nfields = [\"displacement\", \"velocity\", \"stress\", \"von_mises_nodal\"]\nfield_every = { velocity = 10, stress = 10 }",
            ),
            ("h = 0.125", "h = 0.5"),
        ],
    );
    let mut expect = every_reader("0", "point", "displacement", 0);
    expect.extend(every_reader("0.0002", "point", "displacement", 4));
    expect.extend(every_reader("0.0002", "point", "velocity", 2));
    expect.extend(every_reader("0.0002", "cell", "stress", 2));
    expect.extend(every_reader("0.0002", "point", "von_mises_nodal", 4));
    expect.extend(["meshio step 4: velocity = row 2".into(), "meshio step 3: displacement".into()]);
    expect.push("XDMFReader t=0.0002: point field displacement = row 4 (padded to 3".into());
    run_and_check(&scene, "beam.png", &expect);
}

/// The 3D block of tetrahedra on 2 ranks.
#[test]
fn a_3d_run_reads_alike_in_every_reader() {
    let dir = scratch("paraview-3d");
    let scene = scene_variant(
        "block_tet.toml",
        &dir,
        &[
            ("steps = 250", "steps = 20"),
            ("error_steps = [30, 250]", "error_steps = [20]"),
            ("h = 0.25", "h = 0.5"),
            (
                "every = 10",
                "every = 10\nfields = [\"displacement\", \"velocity\", \"strain\", \"stress_nodal\", \"effective_stress\"]",
            ),
        ],
    );
    let mut expect = every_reader("0", "point", "displacement", 0);
    expect.extend(every_reader("0.0002", "point", "velocity", 2));
    expect.extend(every_reader("0.0002", "cell", "strain", 2));
    expect.extend(every_reader("0.0002", "point", "stress_nodal", 2));
    expect.extend(every_reader("0.0002", "cell", "effective_stress", 2));
    expect.push("cells = /mesh/cells (tetrahedron)".into());
    run_and_check(&scene, "block.png", &expect);
}

/// The free-flying L-shaped block (finite strain, hexahedra) on 2 ranks: every reader draws
/// each written step's mesh at the positions written then, which are `X + u`; the block has
/// turned by then, so the reference coordinates would fail the check.
#[test]
fn a_finite_strain_run_shows_the_deformed_bodies_in_every_reader() {
    let dir = scratch("paraview-finite-strain");
    let scene = scene_variant(
        "l_block.toml",
        &dir,
        &[
            ("end = 30.0", "end = 8.0"),
            ("every = 5", "every = 40\nfields = [\"displacement\", \"velocity\", \"von_mises\"]"),
        ],
    );
    let mut expect = Vec::new();
    for r in ["XDMFReader", "Xdmf3ReaderS", "Xdmf3ReaderT"] {
        expect.push(format!("{r} t=8: points = position"));
    }
    expect.extend(every_reader("8", "point", "displacement", 2));
    expect.extend(every_reader("8", "cell", "von_mises", 2));
    expect.push("position row 2 = /mesh/coordinates + displacement".into());
    expect.push("position: written with the displacement (3 rows)".into());
    run_and_check(&scene, "l_block.png", &expect);
    // The block has moved and turned: the drawn points are not the reference ones.
    let f = hdf5::File::open(dir.join("l_block-2.h5")).unwrap();
    let x: Vec<f64> = f.dataset("fields/position").unwrap().read_raw().unwrap();
    let x0: Vec<f64> = f.dataset("mesh/coordinates").unwrap().read_raw().unwrap();
    let n = x0.len();
    let moved = (0..n).map(|i| (x[2 * n + i] - x0[i]).abs()).fold(0.0, f64::max);
    assert!(moved > 1.0, "the block moved only {moved} by t = 8");
}

/// A run file written here: 4 triangles and 2 quadrilaterals (file order: triangles first)
/// on a 2 x 4 strip, three written steps; `displacement` (nodal, 2 components) every step,
/// `pressure` (cell, 1) at steps 0 and 2, `stress` (cell, 6 components; component k of cell i
/// at row r is 100 r + 10 i + k + 1, so any reordering shows) every step. Its XDMF index comes
/// from the library (views and text, as a run writes them).
fn synthetic_run(dir: &Path) -> PathBuf {
    let h5 = dir.join("mixed.h5");
    let f = hdf5::File::create(&h5).unwrap();
    // Nodes (x, y): 0..4 on y = 0, 5..9 on y = 1 (x = 0..4).
    let mut coords = Vec::new();
    for y in 0..2 {
        for x in 0..5 {
            coords.extend([x as f64 + 0.25 * y as f64, y as f64, 0.0]);
        }
    }
    let n = coords.len() / 3;
    let tris: Vec<u64> = vec![0, 1, 6, 0, 6, 5, 1, 2, 7, 1, 7, 6];
    let quads: Vec<u64> = vec![2, 3, 8, 7, 3, 4, 9, 8];
    let (nt, nq) = (tris.len() / 3, quads.len() / 4);
    let nc = nt + nq;
    let ds = |name: &str, shape: &[usize], data: &[f64]| {
        let arr = ndarray::ArrayD::from_shape_vec(shape.to_vec(), data.to_vec()).unwrap();
        f.new_dataset_builder().with_data(&arr).create(name).unwrap();
    };
    ds("mesh/coordinates", &[n, 3], &coords);
    for (name, conn, nn) in [("triangle", &tris, 3), ("quadrilateral", &quads, 4)] {
        let arr = ndarray::Array2::from_shape_vec((conn.len() / nn, nn), conn.clone()).unwrap();
        f.new_dataset_builder()
            .with_data(&arr)
            .create(format!("mesh/cells/{name}").as_str())
            .unwrap();
    }
    let rank: Vec<i32> = (0..nc as i32).map(|i| i % 2).collect();
    f.new_dataset_builder().with_data(&rank).create("mesh/cell_rank").unwrap();
    let times = [0.0, 1.5e-3, 3.0e-3];
    ds("time", &[3], &times);
    ds("step", &[3], &[0.0, 15.0, 30.0]);
    let u: Vec<f64> =
        (0..3 * n * 2).map(|k| (k as f64 * 0.37).sin() * 10f64.powi(k as i32 % 3)).collect();
    ds("fields/displacement", &[3, n, 2], &u);
    let p: Vec<f64> = (0..2 * nc).map(|k| 1000.0 + k as f64 / 7.0).collect();
    ds("fields/pressure", &[2, nc, 1], &p);
    let mut s = Vec::new();
    for r in 0..3 {
        for i in 0..nc {
            s.extend((0..6).map(|k| (100 * r + 10 * i + k + 1) as f64));
        }
    }
    ds("fields/stress", &[3, nc, 6], &s);
    for (name, idx) in
        [("displacement", &[0, 1, 2][..]), ("pressure", &[0, 2]), ("stress", &[0, 1, 2])]
    {
        let t: Vec<f64> = idx.iter().map(|&i| times[i]).collect();
        let st: Vec<f64> = idx.iter().map(|&i| 15.0 * i as f64).collect();
        ds(&format!("fields/{name}_time"), &[t.len()], &t);
        ds(&format!("fields/{name}_step"), &[st.len()], &st);
    }
    f.close().unwrap();

    let cells = [(ElementKind::Tri3, nt), (ElementKind::Quad4, nq)];
    let steps = [
        (times[0], vec![Some(0), Some(0), Some(0)]),
        (times[1], vec![Some(1), None, Some(1)]),
        (times[2], vec![Some(2), Some(1), Some(2)]),
    ];
    let fields = [
        (FieldSpec::nodal("displacement", 2), 3),
        (FieldSpec::cell("pressure", 1), 2),
        (FieldSpec::cell("stress", 6), 3),
    ];
    let layout = XdmfLayout {
        h5_name: "mixed.h5",
        n_nodes: n,
        dim: 2,
        cells: &cells,
        steps: &steps,
        fields: &fields,
    };
    let xdmf = dir.join("mixed.xdmf");
    write_xdmf(&h5, &xdmf, &layout).unwrap();
    xdmf
}

/// A mixed mesh with a cell scalar and a symmetric tensor: one Mixed topology; every reader
/// shows both cell fields (the tensor as a Tensor6: XDMFReader's 9 components read the 6 as
/// xx xy xz yy yz zz, the Xdmf3 readers and meshio keep the 6 as stored).
#[test]
fn a_mixed_mesh_with_cell_fields_and_a_tensor_reads_alike_in_every_reader() {
    for dim in [2, 3] {
        assert_eq!(FieldSpec::cell("stress", 6).xdmf_type(dim), "Tensor6");
        assert_eq!(FieldSpec::nodal("gradient", 9).xdmf_type(dim), "Tensor");
        assert_eq!(FieldSpec::nodal("u", dim).xdmf_type(dim), "Vector");
    }
    let dir = scratch("paraview-mixed");
    let xdmf = synthetic_run(&dir);
    let text = std::fs::read_to_string(&xdmf).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let attr = |name: &str| {
        doc.descendants()
            .find(|n| n.has_tag_name("Attribute") && n.attribute("Name") == Some(name))
            .unwrap_or_else(|| panic!("no attribute {name}"))
    };
    assert_eq!(attr("stress").attribute("AttributeType"), Some("Tensor6"));
    assert_eq!(attr("stress").attribute("Center"), Some("Cell"));
    assert_eq!(attr("pressure").attribute("AttributeType"), Some("Scalar"));
    assert_eq!(attr("displacement").attribute("AttributeType"), Some("Vector"));
    let topo = doc.descendants().find(|n| n.has_tag_name("Topology")).unwrap();
    assert_eq!(topo.attribute("TopologyType"), Some("Mixed"));
    assert_eq!(topo.attribute("NumberOfElements"), Some("6"));

    let mut expect = Vec::new();
    for (at, row_p, row_s) in [("0", 0, 0), ("0.003", 1, 2)] {
        expect.extend(every_reader(at, "cell", "pressure", row_p));
        expect.extend(every_reader(at, "cell", "stress", row_s));
        expect.extend(every_reader(at, "point", "displacement", row_s));
        expect.push(format!("XDMFReader t={at}: cell field stress = row {row_s} (9: full tensor of xx xy xz yy yz zz"));
        for r in ["Xdmf3ReaderS", "Xdmf3ReaderT"] {
            expect.push(format!("{r} t={at}: cell field stress = row {row_s} (as stored; ParaView labels XX YY ZZ XY YZ XZ)"));
        }
    }
    expect.push("cells = /mesh/cells (triangle, quadrilateral)".into());
    expect.push("meshio step 2: stress = row 2".into());
    expect.push("meshio step 2: pressure = row 1".into());
    assert_readers_agree(&xdmf, None, &expect);
}

/// The negative control: the same index with each view replaced by the HyperSlab item of the
/// row (the form the index had before) fails the check: the Xdmf3 readers skip the fields
/// ("Skipping unrecognized array type [None]") and meshio cannot read the item.
#[test]
fn the_check_fails_on_hyperslab_items() {
    let dir = scratch("paraview-hyperslab");
    let xdmf = synthetic_run(&dir);
    let f = hdf5::File::open(dir.join("mixed.h5")).unwrap();
    let text = std::fs::read_to_string(&xdmf).unwrap();
    let mut old = String::new();
    for line in text.lines() {
        let Some((head, path)) = line.split_once(">mixed.h5:/xdmf/") else {
            old.push_str(line);
            old.push('\n');
            continue;
        };
        let path = path.trim_end_matches("</DataItem>");
        let Some((name, row)) = path.split_once('/') else {
            // The Mixed topology stays.
            old.push_str(line);
            old.push('\n');
            continue;
        };
        let shape = f.dataset(&format!("fields/{name}")).unwrap().shape();
        let (rows, entries, c) = (shape[0], shape[1], shape[2]);
        assert!(head.contains(&format!("Dimensions=\"{entries} {c}\"")), "{line}");
        old.push_str(&format!(
            "     <DataItem ItemType=\"HyperSlab\" Dimensions=\"{entries} {c}\" Type=\"HyperSlab\">\n      <DataItem Dimensions=\"3 3\" Format=\"XML\">{row} 0 0 1 1 1 1 {entries} {c}</DataItem>\n      <DataItem Dimensions=\"{rows} {entries} {c}\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">mixed.h5:/fields/{name}</DataItem>\n     </DataItem>\n"
        ));
    }
    let hyperslab = dir.join("hyperslab.xdmf");
    std::fs::write(&hyperslab, old).unwrap();
    let (out, ok) = check_xdmf(&hyperslab, None);
    assert!(!ok, "the check passed on HyperSlab items:\n{out}");
    for e in [
        "FAIL Xdmf3ReaderS t=0: displacement missing",
        "FAIL Xdmf3ReaderT t=0.003: stress missing",
        "FAIL meshio: KeyError",
        "pvbatch: Skipping unrecognized array type [None]",
    ] {
        assert!(out.contains(e), "no {e:?} in\n{out}");
    }
    // The legacy reader reads those items.
    assert!(out.contains("ok   XDMFReader t=0.003: cell field stress = row 2"), "{out}");
}
