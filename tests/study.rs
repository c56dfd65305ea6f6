//! `massfree study`: real sweeps through the binary (which launches `mpirun` itself):
//! convergence rates read back from the CSV, the plots, failed points, bad study files.

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
    Command::new(env!("CARGO_BIN_EXE_massfree"))
        .arg("study")
        .arg(file)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .output()
        .expect("cannot start massfree")
}

fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// The CSV as one map column -> value per row.
fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
    let t = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = t.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(str::to_string).collect();
    lines
        .map(|l| {
            // Only the last column (status) may hold commas, quoted.
            let mut cells: Vec<String> = Vec::new();
            let mut rest = l;
            while cells.len() + 1 < head.len() {
                let (a, b) = rest.split_once(',').unwrap_or((rest, ""));
                cells.push(a.to_string());
                rest = b;
            }
            cells.push(rest.trim_matches('"').replace("\"\"", "\""));
            head.iter().cloned().zip(cells).collect()
        })
        .collect()
}

fn num(row: &HashMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap_or_else(|_| panic!("{key} = {:?} in {row:?}", row[key]))
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
    let mut rates = 0;
    for r in &rows {
        assert_eq!(r["status"], "ok", "{r:?}");
        assert!(num(r, "err_l2") > 0.0 && num(r, "err_h1") > 0.0);
        assert!(num(r, "run_s") > 0.0 && num(r, "stepping_s") > 0.0 && num(r, "dofs") > 0.0);
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
    assert!(rows.iter().any(|r| r["pareto"] == "1"));
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
        // One reference per scene: the consistent run at the smaller hc; its errors are
        // zero by definition, every other run's are positive (a different mesh or mass).
        let refs: Vec<_> = part.iter().filter(|r| num(r, "err_l2") == 0.0).collect();
        assert_eq!(refs.len(), 1, "{part:?}");
        assert_eq!((refs[0]["hc"].as_str(), refs[0]["mass"].as_str()), ("0.1", "consistent"));
        assert_eq!(num(refs[0], "err_force"), 0.0);
        for r in part.iter().filter(|r| num(r, "err_l2") != 0.0) {
            assert!(num(r, "err_l2") > 0.0 && num(r, "err_force") > 0.0, "{r:?}");
            assert!(num(r, "energy_loss").is_finite() && num(r, "lowest_osc2") >= 0.0);
        }
        // Each scene has its own front.
        assert!(
            part.iter().any(|r| r["pareto"] == "1")
                && part.iter().any(|r| r["pareto_force"] == "1")
        );
    }
    for png in
        ["error_time.png", "error_force_time.png", "quads-error_h.png", "triangles-error_h.png"]
    {
        let bytes = std::fs::read(out.join(png)).unwrap_or_default();
        assert!(bytes.len() > 1000 && &bytes[1..4] == b"PNG", "{png} missing or not a PNG");
    }
}
