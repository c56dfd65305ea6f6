//! `massfree study`: real sweeps through the binary (which launches `mpirun` itself):
//! convergence rates read back from the CSV, the plots, failed points, bad study files.

mod common;
use common::{num, read_csv};

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn scratch(name: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let k = N.fetch_add(1, Ordering::SeqCst);
    let dir =
        repo().join("target/test-runs").join(format!("study-{name}-{}-{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `text` as a study file in `dir` (the scene and output are filled in) and runs it.
fn study(dir: &Path, scene: &str, text: &str) -> (Output, PathBuf) {
    let out = dir.join("out");
    let file = dir.join("study.toml");
    let scene = repo().join("scenes").join(scene);
    let full = format!(
        "scene = {:?}\noutput = {:?}\n{text}",
        scene.display().to_string(),
        out.display().to_string()
    );
    std::fs::write(&file, full).unwrap();
    (run_study(&file), out)
}

/// `massfree study FILE`.
fn run_study(file: &Path) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_massfree"));
    cmd.arg("study")
        .arg(file)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        // A session directory base per study, as `tests/common/mod.rs` gives every launch
        // (Open MPI's mkdir race between parallel jobs).
        .env("OMPI_MCA_orte_tmpdir_base", session_base())
        // The study's runs inherit it: HDF5's file locks off, as for every launch of the tests
        // (`tests/common/mod.rs`, `mpi_env`: a descriptor inherited by a launch of another
        // test thread keeps this process's read lock).
        .env("HDF5_USE_FILE_LOCKING", "FALSE");
    common::output(&mut cmd)
}

/// A fresh Open MPI session directory base (short: Unix socket paths live under it).
fn session_base() -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join("mf-ompi").join(format!(
        "s{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The summaries of a study's runs (`runs/ID.summary.toml`), with the ID; `prefix` selects a
/// part's runs (`p0-`, ...).
fn summaries(out: &Path, prefix: &str) -> Vec<(String, massfree::report::RunSummary)> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(out.join("runs")).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if let Some(id) = name.strip_suffix(".summary.toml").filter(|id| id.starts_with(prefix)) {
            let text = std::fs::read_to_string(e.path()).unwrap();
            v.push((id.to_string(), toml::from_str(&text).unwrap()));
        }
    }
    v
}

/// The run of a row: the one summary of the part with the row's mass kind and DOFs.
fn run_of<'a>(
    runs: &'a [(String, massfree::report::RunSummary)],
    r: &HashMap<String, String>,
) -> &'a (String, massfree::report::RunSummary) {
    let dofs = num(r, "dofs") as usize;
    let mine: Vec<_> =
        runs.iter().filter(|(_, s)| s.mass_kind == r["mass"] && s.n_dofs == dofs).collect();
    assert_eq!(mine.len(), 1, "the run of {r:?}");
    mine[0]
}

/// The Pareto column `mark` of the rows against their (run_s, `error`) as the CSV prints them
/// (run_s to 1 ms, errors to 5 digits): a row on the front is dominated by no other for
/// certain (cheaper by more than the rounding, at least as accurate up to the table's 0.1 %
/// tolerance, and strictly better in one); a row off the front is, within the rounding,
/// dominated by some other. Reference and failed rows (error 0 or empty) are never on it.
fn check_pareto(rows: &[&HashMap<String, String>], error: &str, mark: &str) {
    const TOL: f64 = 1e-3; // relative: errors closer than this count as equal
    const DC: f64 = 0.0005; // half a unit of the printed run_s
    const DE: f64 = 5e-5; // half a unit of the fifth digit, relative
    let eligible = |r: &HashMap<String, String>| {
        r["status"] == "ok" && r[error].parse::<f64>().is_ok_and(|e| e > 0.0)
    };
    let pt = |r: &HashMap<String, String>| (num(r, "run_s"), num(r, error));
    let certainly_dominates = |q: (f64, f64), p: (f64, f64)| {
        let (qc, qe, pc, pe) = (q.0 + DC, q.1 * (1.0 + DE), p.0 - DC, p.1 * (1.0 - DE));
        qc <= pc && qe <= pe * (1.0 + TOL) && (qc < pc || qe < pe * (1.0 - TOL))
    };
    let may_dominate = |q: (f64, f64), p: (f64, f64)| {
        q.0 - DC <= p.0 + DC && q.1 * (1.0 - DE) <= p.1 * (1.0 + DE) * (1.0 + TOL)
    };
    for (i, r) in rows.iter().enumerate() {
        let others = || rows.iter().enumerate().filter(move |(j, q)| *j != i && eligible(q));
        match r[mark].as_str() {
            "1" => {
                assert!(eligible(r), "{mark}: a reference or failed row on the front: {r:?}");
                for (_, q) in others() {
                    assert!(
                        !certainly_dominates(pt(q), pt(r)),
                        "{mark}: {r:?} is dominated by {q:?}"
                    );
                }
            }
            "0" if eligible(r) => assert!(
                others().any(|(_, q)| may_dominate(pt(q), pt(r))),
                "{mark}: {r:?} is off the front, but nothing dominates it"
            ),
            "0" => {}
            m => panic!("{mark} = {m:?} in {r:?}"),
        }
    }
}

#[test]
fn space_study_shows_rates_2_and_1_and_writes_plots() {
    let dir = scratch("space");
    let (o, out) = study(
        &dir,
        "beam.toml",
        "repeat = 1\nsteps = 30\n[sweep]\nh = [0.25, 0.125, 0.0625]\nmass = [\"consistent\", \"modified1\"]\n",
    );
    assert!(o.status.success(), "{}", text(&o));
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 6, "{}", text(&o));
    let runs = summaries(&out, "");
    assert_eq!(runs.len(), 6, "one run per row");
    let mut rates = 0;
    for r in &rows {
        assert_eq!(r["status"], "ok", "{r:?}");
        assert!(num(r, "err_l2") > 0.0 && num(r, "err_h1") > 0.0);
        // The size: the beam (0, 10) x (0, 1) in uniform quadrilaterals of size h has
        // (10/h + 1)(1/h + 1) nodes of two DOFs, and the row is its run's.
        let n = |l: f64| (l / num(r, "h")).round() as usize + 1;
        assert_eq!(num(r, "dofs") as usize, 2 * n(10.0) * n(1.0), "{r:?}");
        run_of(&runs, r);
        // The times nest (to the printed digits): stepping is a part of the program's run
        // time, which is a part of the whole process.
        let (stepping, run, process) = (num(r, "stepping_s"), num(r, "run_s"), num(r, "process_s"));
        assert!(stepping <= run + 0.001, "stepping_s {stepping} > run_s {run}: {r:?}");
        assert!(run <= process + 0.0055, "run_s {run} > process_s {process}: {r:?}");
        if r["h"] == "0.25" {
            assert_eq!(r["rate_l2_h"], "", "no rate on the coarsest mesh");
            continue;
        }
        let (l2, h1) = (num(r, "rate_l2_h"), num(r, "rate_h1_h"));
        assert!((l2 - 2.0).abs() < 0.2, "L2 rate {l2} in {r:?}");
        assert!((h1 - 1.0).abs() < 0.2, "H1 rate {h1} in {r:?}");
        rates += 1;
    }
    assert_eq!(rates, 4);
    assert_eq!(rows.iter().filter(|r| r["mass"] == "modified1").count(), 3);
    check_pareto(&rows.iter().collect::<Vec<_>>(), "err_l2", "pareto");
    for png in ["error_h.png", "error_time.png"] {
        let p = out.join(png);
        let len = std::fs::metadata(&p).map(|m| m.len()).unwrap_or(0);
        assert!(len > 1000, "{} missing or empty", p.display());
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{} is not a PNG", p.display());
    }
    let md = std::fs::read_to_string(out.join("results.md")).unwrap();
    assert!(md.contains("| 1/16 |"), "{md}");
}

#[test]
fn time_study_against_the_finest_run_shows_rate_2() {
    let dir = scratch("time");
    let (o, out) = study(
        &dir,
        "beam.toml",
        "reference = \"finest\"\nend_time = 0.8\n[sweep]\nh = [0.125]\ntau = [0.1, 0.05, 0.025, 0.003125]\n",
    );
    assert!(o.status.success(), "{}", text(&o));
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 4);
    let steps: Vec<f64> = rows.iter().map(|r| num(r, "steps")).collect();
    assert_eq!(steps, [8.0, 16.0, 32.0, 256.0]);
    assert_eq!(num(&rows[3], "err_l2"), 0.0, "the finest run is the reference");
    for r in &rows[1..3] {
        let rate = num(r, "rate_l2_tau");
        assert!((rate - 2.0).abs() < 0.2, "time rate {rate} in {r:?}");
    }
    assert!(std::fs::metadata(out.join("error_tau.png")).unwrap().len() > 1000);
}

#[test]
fn failed_points_are_recorded_and_the_sweep_goes_on() {
    let dir = scratch("failed");
    let (o, out) = study(
        &dir,
        "beam.toml",
        "steps = 5\n[sweep]\nh = [0.25]\nsolver = [[\"-ksp_type\", \"nonsense\"], [\"-ksp_type\", \"cg\", \"-pc_type\", \"jacobi\"]]\n",
    );
    assert!(o.status.success(), "one point ran: {}", text(&o));
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 2);
    assert!(rows[0]["status"].starts_with("failed: "), "{:?}", rows[0]);
    assert!(rows[0]["status"].contains("nonsense"), "the run's own error line: {:?}", rows[0]);
    assert!(!rows[0]["status"].contains('\n'));
    assert_eq!(rows[1]["status"], "ok", "{:?}", rows[1]);
    assert!(num(&rows[1], "err_l2") > 0.0);
    let md = std::fs::read_to_string(out.join("results.md")).unwrap();
    assert!(md.contains("failed: "), "{md}");
}

#[test]
fn a_study_where_everything_fails_exits_non_zero() {
    let dir = scratch("allfail");
    let (o, out) = study(
        &dir,
        "beam.toml",
        "steps = 5\n[sweep]\nh = [0.25]\nsolver = [[\"-pc_type\", \"bogus\"]]\n",
    );
    assert!(!o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("all 1 runs failed"), "{err}");
    let rows = read_csv(&out.join("results.csv"));
    assert!(rows[0]["status"].starts_with("failed: "));
}

#[test]
fn bad_study_files_are_one_line_errors_naming_the_key() {
    let cases = [
        ("[sweep]\nh = [0.25]\nmesh = [1]\n", "sweep.mesh"),
        ("repeats = 3\n", "repeats"),
        ("[sweep]\nmass = [\"heavy\"]\n", "sweep.mass"),
        ("[sweep]\nh = [0.25, -1]\n", "sweep.h"),
        ("[sweep]\ntau = [0.1, 0.05]\n", "end_time"),
        ("end_time = 1.0\n[sweep]\ntau = [0.3]\n", "sweep.tau"),
        ("ranks = 0\n", "ranks"),
        ("error_step = 1000\n", "error_step"),
        ("reference = \"best\"\n", "reference"),
        ("reference = { mass = \"lumped\" }\n[sweep]\nh = [0.25, 0.125]\n", "reference.mass"),
        ("[sweep]\nh = [0.25]\nskip = [{ size = 1 }]\n", "sweep.skip[0].size"),
    ];
    for (i, (body, key)) in cases.iter().enumerate() {
        let dir = scratch(&format!("bad{i}"));
        let (o, _) = study(&dir, "beam.toml", body);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{body}: {}", text(&o));
        assert_eq!(err.trim().lines().count(), 1, "{body}: {err}");
        assert!(err.contains(key), "{body}: {err} does not name {key}");
    }
    // A scene without an exact solution cannot be the reference.
    let dir = scratch("bad-exact");
    let (o, _) = study(&dir, "disc.toml", "reference = \"exact\"\n[sweep]\nh = [0.2]\n");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("[exact]"));
    // An unknown key in a part of a file with parts.
    let dir = scratch("bad-part");
    let scene = repo().join("scenes/beam.toml").display().to_string();
    let (o, _) =
        study_file(&dir, &format!("[[part]]\nname = \"a\"\nscene = {scene:?}\nmesh = 1\n"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("part[0] (a): unknown key mesh"), "{err}");
}

/// Runs the study file `text` (a file with parts: it names its scenes itself) from `dir`.
fn study_file(dir: &Path, text: &str) -> (Output, PathBuf) {
    let out = dir.join("out");
    let file = dir.join("study.toml");
    std::fs::write(&file, format!("output = {:?}\n{text}", out.display().to_string())).unwrap();
    (run_study(&file), out)
}

#[test]
fn contact_study_with_two_scenes_against_one_consistent_reference() {
    let dir = scratch("parts");
    let scenes = repo().join("scenes");
    let part = |name: &str, scene: &str, kinds: &str| {
        format!(
            "[[part]]\nname = \"{name}\"\nscene = {:?}\nmesh_param = \"hc\"\nsteps = 100\n\
             params = {{ h = 2.0 }}\n[part.sweep]\nh = [0.2, 0.1]\nmass = [{kinds}]\n",
            scenes.join(scene).display().to_string()
        )
    };
    let file = format!(
        "title = \"parts\"\nreference = {{ mass = \"consistent\" }}\n{}{}",
        part("quads", "disc.toml", "\"consistent\", \"modified1\""),
        part("triangles", "disc_tri.toml", "\"consistent\", \"modified0\"")
    );
    let (o, out) = study_file(&dir, &file);
    assert!(o.status.success(), "{}", text(&o));
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 8, "{}", text(&o));
    for (k, name) in ["quads", "triangles"].iter().enumerate() {
        let part: Vec<_> = rows[4 * k..4 * k + 4].iter().collect();
        assert!(part.iter().all(|r| r["scene"] == *name && r["status"] == "ok"), "{part:?}");
        let runs = summaries(&out, &format!("p{k}-"));
        assert_eq!(runs.len(), 4, "{name}: one run per row");
        // One reference per scene: the consistent run at the smaller hc; its errors are
        // zero by definition, every other run's are positive (a different mesh or mass).
        let refs: Vec<_> = part.iter().filter(|r| num(r, "err_l2") == 0.0).collect();
        assert_eq!(refs.len(), 1, "{part:?}");
        assert_eq!((refs[0]["hc"].as_str(), refs[0]["mass"].as_str()), ("0.1", "consistent"));
        assert_eq!(num(refs[0], "err_force"), 0.0);
        for r in part.iter().filter(|r| num(r, "err_l2") != 0.0) {
            assert!(num(r, "err_l2") > 0.0 && num(r, "err_force") > 0.0, "{r:?}");
        }
        // The contact columns are the runs' own (to the 5 digits printed).
        for r in &part {
            let (id, s) = run_of(&runs, r);
            let c = s.contact.as_ref().expect("a contact summary");
            for (key, x) in [("lowest_osc2", c.lowest_osc2), ("max_pressure", c.max_pressure)] {
                let y = num(r, key);
                assert!(
                    (x - y).abs() <= 5e-5 * x.abs(),
                    "{name} {id}: {key} {y} in the table, {x} in the run"
                );
            }
            assert_eq!(num(r, "episodes_max") as usize, c.episodes_max, "{name} {id}");
        }
        // The mass-free layer removes the period-2 chatter of the contact nodes (docs/method.md, chatter and impacts):
        // at each contact mesh size its lowest node's osc2 is below the consistent mass's.
        for hc in ["0.2", "0.1"] {
            let osc2 = |layer: bool| {
                let at = part.iter().filter(|r| r["hc"] == hc);
                let mut v = at.filter(|r| (r["mass"] != "consistent") == layer);
                num(v.next().unwrap(), "lowest_osc2")
            };
            assert!(
                osc2(true) < osc2(false),
                "{name}, hc {hc}: osc2 {} with the layer, {} without",
                osc2(true),
                osc2(false)
            );
        }
        // Each scene has its own fronts, marked right.
        check_pareto(&part, "err_l2", "pareto");
        check_pareto(&part, "err_force", "pareto_force");
    }
    for png in
        ["error_time.png", "error_force_time.png", "quads-error_h.png", "triangles-error_h.png"]
    {
        let bytes = std::fs::read(out.join(png)).unwrap_or_default();
        assert!(bytes.len() > 1000 && &bytes[1..4] == b"PNG", "{png} missing or not a PNG");
    }
}
