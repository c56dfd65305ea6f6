//! HDF5 output (issue: time series that outlive crashes): the documented layout, files equal
//! across rank counts, crash safety (SIGTERM, a diverging solver), restart = uninterrupted,
//! the XDMF index, and `massfree post`.

mod common;
use common::*;
use std::path::Path;

// This file reads the run file with the plain HDF5 API and literal names on purpose: it checks
// the layout README.md documents for users, independently of `io::layout`'s constants.
fn open(p: &Path) -> hdf5::File {
    hdf5::File::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn attr(f: &hdf5::File, name: &str) -> String {
    f.attr(name).unwrap().read_scalar::<hdf5::types::VarLenUnicode>().unwrap().to_string()
}

fn raw(f: &hdf5::File, name: &str) -> Vec<f64> {
    f.dataset(name).unwrap_or_else(|e| panic!("{name}: {e}")).read_raw::<f64>().unwrap()
}

fn beam(dir: &Path) -> std::path::PathBuf {
    scene_variant(
        "beam.toml",
        dir,
        &[
            ("steps = 250", "steps = 20"),
            ("error_steps = [30, 250]", "error_steps = [20]"),
            ("every = 10", "every = 5"),
        ],
    )
}

#[test]
fn layout_is_documented_and_rank_independent() {
    let dir = scratch("io-layout");
    let scene = beam(&dir);
    let args = ["--param", "h=0.25", "--", "-ksp_rtol", "1e-13"];
    let s2 = run_scene(2, &scene, &args);
    let s1 = run_scene(1, &scene, &args);
    let (f2, f1) = (open(&dir.join("beam-2.h5")), open(&dir.join("beam-1.h5")));
    let n = f2.dataset("mesh/coordinates").unwrap().shape()[0];
    assert_eq!(f2.dataset("mesh/coordinates").unwrap().shape(), vec![n, 3]);
    assert_eq!(f2.dataset("mesh/node_tags").unwrap().shape(), vec![n]);
    let cells = f2.dataset("mesh/cells/quadrilateral").unwrap().shape();
    assert_eq!(cells, vec![160, 4]);
    let ranks = f2.dataset("mesh/cell_rank").unwrap().read_raw::<i32>().unwrap();
    assert_eq!(ranks.len(), 160);
    assert!(ranks.iter().all(|&r| r == 0 || r == 1) && ranks.contains(&1));
    let left = f2.dataset("mesh/groups/left/nodes").unwrap().read_raw::<u64>().unwrap();
    let xy = raw(&f2, "mesh/coordinates");
    assert!(!left.is_empty() && left.iter().all(|&v| xy[3 * v as usize].abs() < 1e-12));
    assert_eq!(raw(&f2, "time").len(), 5);
    assert_eq!(raw(&f2, "step"), vec![0.0, 5.0, 10.0, 15.0, 20.0]);
    for field in ["displacement", "velocity"] {
        assert_eq!(f2.dataset(&format!("fields/{field}")).unwrap().shape(), vec![5, n, 2]);
    }
    for e in [
        "step",
        "time",
        "kinetic",
        "potential",
        "total",
        "external_work",
        "contact_work",
        "dirichlet_work",
    ] {
        assert_eq!(raw(&f2, &format!("energy/{e}")).len(), 21, "energy/{e}");
    }
    let total = raw(&f2, "energy/total");
    assert!(rel_diff(total[0], s2.energy_initial) < 1e-14);
    assert!(rel_diff(total[20], s2.energy_final) < 1e-14);
    let kin = raw(&f2, "energy/kinetic");
    let pot = raw(&f2, "energy/potential");
    assert!((0..21).all(|i| (kin[i] + pot[i] - total[i]).abs() <= 1e-14 * total[i].abs()));
    assert_eq!(attr(&f2, "scene"), std::fs::read_to_string(&scene).unwrap());
    assert!(attr(&f2, "settings").contains("ranks = 2"));
    assert_eq!(attr(&f2, "solver_options"), "-ksp_rtol 1e-13");
    assert_eq!(attr(&f2, "status"), "finished");
    assert_eq!(attr(&f2, "version"), env!("CARGO_PKG_VERSION"));
    assert_eq!(f2.attr("ranks").unwrap().read_scalar::<i32>().unwrap(), 2);
    // The last written displacement is the state the solver continued from (the checkpoint).
    assert_eq!(raw(&f2, "checkpoint/u"), raw(&f2, "fields/displacement")[4 * n * 2..].to_vec());
    // 1 and 2 ranks: the same datasets, entry by entry, to solver tolerance.
    for name in
        ["mesh/coordinates", "fields/displacement", "fields/velocity", "energy/total", "mass/probe"]
    {
        let (a, b) = (raw(&f1, name), raw(&f2, name));
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let d = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(d <= 1e-9 * scale, "{name}: 1 vs 2 ranks differ by {d}");
    }
    let _ = s1;
    // h5dump reads it.
    let o = output(std::process::Command::new("h5dump").arg("-H").arg(dir.join("beam-2.h5")));
    assert!(o.status.success());
}

#[test]
fn sigterm_leaves_a_readable_file_with_a_checkpoint() {
    let dir = scratch("io-sigterm");
    let scene = scene_variant("disc.toml", &dir, &[]);
    let out = dir.join("killed.h5");
    let args = |out: &Path, steps: &str| -> Vec<String> {
        ["run", scene.to_str().unwrap(), "-q", "-o", out.to_str().unwrap(), "--steps", steps]
            .iter()
            .map(|s| s.to_string())
            .collect()
    };
    // The pace: the same run for 1000 steps; then the run of 10^6 steps, signalled once more
    // than two steps are in its file (waiting for the file, not for a time).
    let reference = args(&dir.join("reference.h5"), "1000");
    let pace = Pace::measure(&mut massfree_command(2, &reference), "the disc, 1000 steps, 2 ranks");
    let long = args(&out, "1000000");
    let mut job = Job::start(
        massfree_command(2, &long).stderr(std::process::Stdio::piped()),
        "the disc signalled",
    );
    job.wait_for(&pace.limit(1.0), "3 steps in the file", |_| {
        std::thread::sleep(std::time::Duration::from_millis(20));
        steps_in_growing_file(&out).is_some_and(|n| n > 2)
    });
    // SIGTERM to mpirun, which forwards it to the ranks.
    job.signal(nix::sys::signal::Signal::SIGTERM);
    let status = job.wait(&pace.limit(1.0));
    assert!(!status.success());
    let f = open(&out);
    let st = attr(&f, "status");
    assert!(st.starts_with("interrupted"), "status {st}");
    let steps = raw(&f, "energy/step");
    assert!(steps.len() > 2, "steps written: {}", steps.len());
    let cp = raw(&f, "checkpoint/scalars");
    assert_eq!(cp[0], *steps.last().unwrap(), "the checkpoint is the last step written");
    assert!(dir.join("killed.xdmf").exists());
}

#[test]
fn a_diverging_solver_marks_the_file_failed() {
    let dir = scratch("io-failed");
    let scene = beam(&dir);
    let out = dir.join("failed.h5");
    let o = massfree(
        2,
        &[
            "run",
            &scene.display().to_string(),
            "-q",
            "-o",
            &out.display().to_string(),
            "--",
            "-ksp_max_it",
            "1",
            "-ksp_rtol",
            "1e-14",
        ],
    );
    assert!(!o.status.success());
    let f = open(&out);
    let st = attr(&f, "status");
    assert!(st.starts_with("failed") && st.contains("DIVERGED"), "status {st}");
    assert!(!raw(&f, "energy/total").is_empty(), "the steps before the failure are kept");
}

/// Run N steps in one go, and k steps then a restart to N: same final state and energies.
fn restart_equals_uninterrupted(scene_name: &str, replace: &[(&str, &str)], k: usize, name: &str) {
    let dir = scratch(name);
    let scene = scene_variant(scene_name, &dir, replace);
    let p = |x: &str| dir.join(x).display().to_string();
    let opts = ["--", "-ksp_rtol", "1e-12"];
    let run = |args: &[&str]| {
        let mut all = vec!["run", scene.to_str().unwrap(), "-q", "--overwrite"];
        all.extend_from_slice(args);
        all.extend_from_slice(&opts);
        let o = massfree(2, &all);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    run(&["-o", &p("full.h5")]);
    run(&["-o", &p("first.h5"), "--steps", &k.to_string()]);
    run(&["-o", &p("second.h5"), "--restart", &p("first.h5")]);
    let (a, b) = (open(&dir.join("full.h5")), open(&dir.join("second.h5")));
    let (ua, ub) = (raw(&a, "checkpoint/u"), raw(&b, "checkpoint/u"));
    let norm = ua.iter().map(|x| x * x).sum::<f64>().sqrt();
    let diff = ua.iter().zip(&ub).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
    assert!(diff <= 1e-10 * norm, "{name}: final displacement differs by {diff} (norm {norm})");
    let (ea, eb) = (raw(&a, "energy/total"), raw(&b, "energy/total"));
    assert!(rel_diff(*ea.last().unwrap(), *eb.last().unwrap()) < 1e-10);
    assert_eq!(raw(&b, "energy/step")[0], k as f64, "the restart starts at the checkpoint");
    if a.dataset("contact/active").is_ok() {
        let aa = a.dataset("contact/active").unwrap().read_raw::<u8>().unwrap();
        let ab = b.dataset("contact/active").unwrap().read_raw::<u8>().unwrap();
        let nc = a.dataset("contact/active").unwrap().shape()[1];
        assert_eq!(
            &aa[aa.len() - (ab.len())..],
            &ab[..],
            "{name}: active sets differ after the restart"
        );
        assert!(ab.chunks(nc).any(|r| r.contains(&1)), "{name}: the restart must cover contact");
    }
}

#[test]
fn restart_equals_the_uninterrupted_run() {
    restart_equals_uninterrupted(
        "beam.toml",
        &[("steps = 250", "steps = 60"), ("error_steps = [30, 250]", "error_steps = [60]")],
        30,
        "restart-beam",
    );
    restart_equals_uninterrupted(
        "disc.toml",
        &[("steps = 1000", "steps = 300")],
        150,
        "restart-disc",
    );
}

/// A checkpoint taken at a step whose massless-DOF energy correction is still pending (it
/// hands contact work on to later steps right after an activation or a release, METHOD.md 7)
/// must restart exactly too: the checkpoint keeps the pending work. Without it the continued
/// run differed from the uninterrupted one (coarse disc, 1 rank: by 1.3e-4 of the displacement
/// after a restart at step 64, 8e-7 at step 760; exact at 60, 400, 740, 1000).
#[test]
fn restart_with_a_pending_energy_correction() {
    let coarse = [("steps = 1000", "steps = 1200"), ("h = 1.0, hc = 0.1", "h = 2.0, hc = 0.4")];
    for k in [64, 760] {
        restart_equals_uninterrupted("disc.toml", &coarse, k, &format!("restart-pending-{k}"));
    }
}

#[test]
fn xdmf_refers_to_existing_datasets_with_the_right_shapes() {
    let dir = scratch("io-xdmf");
    let scene = beam(&dir);
    run_scene(2, &scene, &["--param", "h=0.25"]);
    let text = std::fs::read_to_string(dir.join("beam-2.xdmf")).unwrap();
    let doc = roxmltree::Document::parse(&text).expect("valid XML");
    let f = open(&dir.join("beam-2.h5"));
    let mut refs = 0;
    for node in doc
        .descendants()
        .filter(|n| n.has_tag_name("DataItem") && n.attribute("Format") == Some("HDF"))
    {
        let t = node.text().unwrap().trim();
        let (file, ds) = t.split_once(':').unwrap();
        assert_eq!(file, "beam-2.h5");
        let shape = f.dataset(ds).unwrap_or_else(|_| panic!("{ds} does not exist")).shape();
        let dims: Vec<usize> = node
            .attribute("Dimensions")
            .unwrap()
            .split_whitespace()
            .map(|d| d.parse().unwrap())
            .collect();
        assert_eq!(dims, shape, "{ds}");
        refs += 1;
    }
    let grids = doc.descendants().filter(|n| n.has_tag_name("Time")).count();
    assert_eq!(grids, 5, "one grid per written step");
    // Per step: topology, geometry, displacement, velocity, partition.
    assert_eq!(refs, 5 * 5);
    // A field row the index shows is a view of that row of /fields (tests/paraview.rs reads
    // them with ParaView and meshio).
    for field in ["displacement", "velocity"] {
        let all = raw(&f, &format!("fields/{field}"));
        let row = all.len() / 5;
        for k in 0..5 {
            let view = raw(&f, &format!("xdmf/{field}/{k}"));
            assert_eq!(view, all[k * row..(k + 1) * row].to_vec(), "xdmf/{field}/{k}");
        }
    }
}

#[test]
fn post_writes_pictures_and_csv_equal_to_the_file() {
    let dir = scratch("io-post");
    let scene = scene_variant(
        "disc.toml",
        &dir,
        &[("steps = 1000", "steps = 200"), ("every = 10", "every = 20")],
    );
    run_scene(2, &scene, &[]);
    let h5 = dir.join("disc-2.h5");
    let o = massfree(0, &["post", h5.to_str().unwrap(), "--node", "0,16", "--contact-node", "0,0"]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("contact: steps"), "{out}");
    let f = open(&h5);
    // One body against an obstacle: no pair in the file, none in the summary.
    assert!(f.dataset("contact/master_nodes").is_err());
    assert!(text_attr(&f, "contact", "master_group").is_none());
    assert_eq!(text_attr(&f, "contact", "group").as_deref(), Some("contact"));
    assert!(!out.contains("contact pair"), "{out}");
    let written: Vec<String> =
        out.lines().filter_map(|l| l.strip_prefix("wrote ")).map(String::from).collect();
    assert!(written.iter().filter(|w| w.ends_with(".png")).count() >= 3);
    for w in &written {
        let min = if w.ends_with(".png") { 1000 } else { 50 };
        assert!(std::fs::metadata(w).unwrap().len() > min, "{w} is empty");
    }
    // energy CSV = /energy
    let energy_csv = written.iter().find(|w| w.ends_with("-energy.csv")).unwrap();
    let text = std::fs::read_to_string(energy_csv).unwrap();
    let total: Vec<f64> =
        text.lines().skip(1).map(|l| l.split(',').nth(4).unwrap().parse().unwrap()).collect();
    assert_eq!(total, raw(&f, "energy/total"));
    // node CSV = /fields at that node
    let node_csv = written.iter().find(|w| w.ends_with("-displacement.csv")).unwrap();
    let tag: u64 = node_csv
        .rsplit("-node-")
        .next()
        .unwrap()
        .trim_end_matches("-displacement.csv")
        .parse()
        .unwrap();
    let tags = f.dataset("mesh/node_tags").unwrap().read_raw::<u64>().unwrap();
    let node = tags.iter().position(|&t| t == tag).unwrap();
    let u = raw(&f, "fields/displacement");
    let n = tags.len();
    let text = std::fs::read_to_string(node_csv).unwrap();
    for (k, line) in text.lines().skip(1).enumerate() {
        let uy: f64 = line.split(',').nth(2).unwrap().parse().unwrap();
        assert_eq!(uy, u[(k * n + node) * 2 + 1]);
    }
}

#[test]
fn fields_can_have_their_own_periods() {
    let dir = scratch("io-field-every");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[
            ("steps = 250", "steps = 20"),
            ("error_steps = [30, 250]", "error_steps = [20]"),
            ("every = 10", "every = 5\nfield_every = { velocity = 10 }"),
        ],
    );
    run_scene(2, &scene, &["--param", "h=0.5"]);
    let f = open(&dir.join("beam-2.h5"));
    assert_eq!(raw(&f, "fields/displacement_step"), vec![0.0, 5.0, 10.0, 15.0, 20.0]);
    assert_eq!(raw(&f, "fields/velocity_step"), vec![0.0, 10.0, 20.0]);
    assert_eq!(f.dataset("fields/velocity").unwrap().shape()[0], 3);
    assert_eq!(raw(&f, "step"), vec![0.0, 5.0, 10.0, 15.0, 20.0]);
    // The XDMF gives velocity only at the steps it was written.
    let text = std::fs::read_to_string(dir.join("beam-2.xdmf")).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let v = doc.descendants().filter(|n| n.attribute("Name") == Some("velocity")).count();
    assert_eq!(v, 3);
}

#[test]
fn fields_are_written_every_k_steps_and_at_given_times() {
    let dir = scratch("io-times");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[
            ("steps = 250", "steps = 20"),
            ("error_steps = [30, 250]", "error_steps = [20]"),
            ("every = 10", "every = 10\ntimes = [3e-5, 1.2e-4, 1e-4]"),
        ],
    );
    run_scene(2, &scene, &["--param", "h=0.5"]);
    let f = open(&dir.join("beam-2.h5"));
    // every 10 steps (0, 10, 20) and at t = 3e-5, 1e-4, 1.2e-4 (steps 3, 10, 12).
    assert_eq!(raw(&f, "step"), vec![0.0, 3.0, 10.0, 12.0, 20.0]);
    assert_eq!(f.dataset("fields/velocity").unwrap().shape()[0], 5);
    // A bad time is a one-line error naming the key.
    let bad = scene_variant("beam.toml", &dir, &[("every = 10", "every = 10\ntimes = [1.0]")]);
    let o = massfree(0, &["run", bad.to_str().unwrap(), "--no-output"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("output.times[0]") && err.lines().count() == 1,
        "{err}"
    );
}

#[test]
fn compression_on_one_rank_keeps_the_data_and_is_refused_on_two() {
    let dir = scratch("io-deflate");
    let plain = beam(&dir);
    let packed = scene_text(
        &dir,
        "packed.toml",
        &std::fs::read_to_string(&plain)
            .unwrap()
            .replace("every = 5", "every = 5\ncompression = 4"),
    );
    run_scene(1, &plain, &["--param", "h=0.25"]);
    run_scene(1, &packed, &["--param", "h=0.25"]);
    let (a, b) = (open(&dir.join("beam-1.h5")), open(&dir.join("packed-1.h5")));
    assert_eq!(raw(&a, "fields/displacement"), raw(&b, "fields/displacement"));
    assert!(b.dataset("fields/displacement").unwrap().is_chunked());
    let o = massfree(2, &["run", packed.to_str().unwrap(), "--no-output"]);
    assert!(o.status.success(), "no output, no compression: fine on 2 ranks");
    let o = massfree(
        2,
        &["run", packed.to_str().unwrap(), "--overwrite", "-o", dir.join("x.h5").to_str().unwrap()],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("output.compression works on one rank only"),
        "{err}"
    );
}

fn text_attr(f: &hdf5::File, group: &str, name: &str) -> Option<String> {
    let a = f.group(group).ok()?.attr(name).ok()?;
    Some(a.read_scalar::<hdf5::types::VarLenUnicode>().ok()?.to_string())
}

fn nodes_of(f: &hdf5::File, name: &str) -> Vec<u64> {
    f.dataset(name).unwrap_or_else(|e| panic!("{name}: {e}")).read_raw::<u64>().unwrap()
}

/// A two-body run's file names its pair: the slave and master groups (attributes of
/// /contact), the slave nodes (`contact/nodes`) and the master nodes (`contact/master_nodes`),
/// consistent with the mesh's groups; per slave node the pressure is force / weight and the gap
/// is the weighted gap over `D_qq` (a distance). On 2 ranks, so the metadata (attributes) and
/// the new dataset go through the collective path; the XDMF index covers both bodies.
#[test]
fn a_two_body_run_file_names_its_pair() {
    let dir = scratch("io-pair");
    let scene = scene_variant("two_discs.toml", &dir, &[("steps = 1000", "steps = 80")]);
    let s = run_scene(2, &scene, &[]);
    let h5 = dir.join("two_discs-2.h5");
    let f = open(&h5);
    assert_eq!(text_attr(&f, "contact", "slave_group").as_deref(), Some("upper_contact"));
    assert_eq!(text_attr(&f, "contact", "master_group").as_deref(), Some("lower_contact"));
    assert_eq!(text_attr(&f, "contact", "group").as_deref(), Some("upper_contact"));
    let slave = nodes_of(&f, "contact/nodes");
    let master = nodes_of(&f, "contact/master_nodes");
    assert_eq!(slave, nodes_of(&f, "mesh/groups/upper_contact/nodes"));
    assert_eq!(master, nodes_of(&f, "mesh/groups/lower_contact/nodes"));
    assert!(!master.is_empty() && master.iter().all(|v| !slave.contains(v)));
    let upper = nodes_of(&f, "mesh/groups/upper/nodes");
    let lower = nodes_of(&f, "mesh/groups/lower/nodes");
    assert!(slave.iter().all(|v| upper.contains(v)) && master.iter().all(|v| lower.contains(v)));
    let xy = raw(&f, "mesh/coordinates");
    assert!(slave.iter().all(|&v| xy[3 * v as usize + 1] > 0.0));
    assert!(master.iter().all(|&v| xy[3 * v as usize + 1] < 0.0));
    // Per slave node and step: pressure = force / weight, weights sum to the slave arc's
    // length (a quarter of the circle of radius 8, as an inscribed polygon: measured 3e-4
    // shorter), forces only where active.
    let nc = slave.len();
    let w = raw(&f, "contact/weights");
    assert_eq!(w.len(), nc);
    let arc = w.iter().sum::<f64>();
    let quarter = 4.0 * std::f64::consts::PI;
    assert!(arc < quarter && rel_diff(arc, quarter) < 1e-3, "slave arc length {arc}");
    let (p, force) = (raw(&f, "contact/pressure"), raw(&f, "contact/force"));
    let active = f.dataset("contact/active").unwrap().read_raw::<u8>().unwrap();
    assert_eq!(f.dataset("contact/pressure").unwrap().shape(), vec![81, nc]);
    for (i, (&pi, &fi)) in p.iter().zip(&force).enumerate() {
        assert!((pi - fi / w[i % nc]).abs() <= 1e-12 * pi.abs(), "pressure at entry {i}");
        assert!(fi >= 0.0 && (active[i] == 1 || fi == 0.0), "force at entry {i}");
    }
    assert!(active.contains(&1), "80 steps reach the contact (it starts at step 63)");
    // The gap of the slave node closest to the master (0, 0.05) after one step: the discs
    // start 0.1 apart and close at 2 * 800 * tau.
    let low = s.contact.as_ref().unwrap().lowest_node as u64;
    assert_eq!(&xy[3 * low as usize..3 * low as usize + 2], &[0.0, 0.05]);
    let k = slave.iter().position(|&v| v == low).unwrap();
    let gap1 = raw(&f, "contact/gap")[nc + k];
    assert!((gap1 - (0.1 - 1600e-6)).abs() < 1e-5, "gap of the lowest slave node {gap1}");
    // compare draws that node's pressure.
    let curves = massfree::post::read_curves(&h5).unwrap();
    let column: Vec<f64> = p.chunks(nc).map(|r| r[k]).collect();
    assert_eq!(curves.lowest_pressure, column, "compare draws another node");
    assert!(column.iter().any(|&x| x > 0.0));
    // The XDMF index shows the whole mesh: both bodies' cells and nodes.
    let text = std::fs::read_to_string(dir.join("two_discs-2.xdmf")).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let cells = f.dataset("mesh/cells/quadrilateral").unwrap().shape()[0];
    for t in doc.descendants().filter(|n| n.has_tag_name("Topology")) {
        assert_eq!(t.attribute("NumberOfElements"), Some(cells.to_string().as_str()));
    }
    let conn = nodes_of(&f, "mesh/cells/quadrilateral");
    assert!(upper.iter().chain(&lower).all(|v| conn.contains(v)), "a body is missing");
    // post names the pair and the slave node whose pressure compare draws.
    let o =
        massfree(0, &["post", h5.to_str().unwrap(), "--prefix", dir.join("p").to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let tag = nodes_of(&f, "mesh/node_tags")[low as usize];
    let line = format!(
        "contact pair: slave \"upper_contact\" ({nc} nodes), master \"lower_contact\" ({} nodes); lowest slave node (closest to the master at t = 0): gmsh node {tag} at (0, 0.05)",
        master.len()
    );
    assert!(out.contains(&line), "{out}");
    let o = output(std::process::Command::new("h5dump").arg("-H").arg(&h5));
    assert!(o.status.success());
}
