//! Runs that never hang and never lie: long runs on 2 and 3 ranks finish, metadata written
//! from values that differ between ranks cannot hang, a signal at any moment ends the run
//! within seconds with a readable file that says `interrupted: ...`, a killed run is
//! recognised by `post`, a hung collective is ended by the watchdog, results do not depend on
//! the number of ranks (1-4), and `./run` works from any directory with one-line errors.

mod common;
use common::*;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

fn mpi_env(cmd: &mut Command) -> &mut Command {
    cmd.env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RUST_BACKTRACE", "0")
}

/// `mpirun -q -n ranks massfree args` (ranks = 1: the binary alone, as users also run it).
fn launch(ranks: usize, args: &[String]) -> Command {
    let mut cmd = if ranks == 1 {
        Command::new(bin())
    } else {
        let mut c = Command::new("mpirun");
        c.args(["-q", "--oversubscribe", "-n", &ranks.to_string()]).arg(bin());
        c
    };
    cmd.args(args);
    mpi_env(&mut cmd);
    cmd
}

/// Wait for a child at most `limit`; a child still running then is killed and reported.
fn wait_for(child: &mut Child, limit: Duration, what: &str) -> ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = Command::new("pkill").args(["-9", "-f", bin().to_str().unwrap()]).status();
            let _ = child.wait();
            panic!("{what}: still running after {:.0} s (hung?)", limit.as_secs_f64());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The status attribute as h5dump (an independent reader) prints it.
fn status_by_h5dump(h5: &Path) -> String {
    let o = Command::new("h5dump").args(["-a", "status"]).arg(h5).output().unwrap();
    assert!(
        o.status.success(),
        "h5dump cannot read {}: {}",
        h5.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let line = text.lines().find(|l| l.trim_start().starts_with("(0):")).unwrap_or("");
    line.split_once('"')
        .map(|(_, r)| r.trim_end().trim_end_matches('"').to_string())
        .unwrap_or_default()
}

/// The length of `/energy/step` in a file a run is still writing (h5dump without file
/// locking; `None` while the file or the dataset is not readable yet).
fn steps_in_growing_file(h5: &Path) -> Option<usize> {
    if !h5.exists() {
        return None;
    }
    let o = Command::new("h5dump")
        .args(["-H", "-d", "/energy/step"])
        .arg(h5)
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let line = text.lines().find(|l| l.contains("DATASPACE"))?;
    line.split_once("( ")?.1.split_once(' ')?.0.parse().ok()
}

fn raw(h5: &Path, name: &str) -> Vec<f64> {
    values(h5, name)
}

fn max_rel_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// `run SCENE -q --overwrite -o OUT EXTRA...`
fn run_args(scene: &str, out: &str, extra: &[&str]) -> Vec<String> {
    let mut v = strings(&["run", scene, "-q", "--overwrite", "-o", out]);
    v.extend(strings(extra));
    v
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// The disc of the default scene on a coarse mesh (179 nodes), so that long runs stay short.
fn coarse_disc(dir: &Path) -> PathBuf {
    scene_variant("disc.toml", dir, &[("h = 1.0, hc = 0.1", "h = 2.0, hc = 0.4")])
}

#[test]
fn long_runs_finish_on_two_and_three_ranks() {
    // Before the fix a 2-rank disc run hung after its last step at 10000 steps (and failed in
    // MPI_Bcast at 10000 steps with --every 1000); the HDF5 metadata path then depended on
    // the file's history. Each run here must end, and say `finished`.
    let dir = scratch("long-runs");
    let scene = coarse_disc(&dir);
    for ranks in [2, 3] {
        for (steps, every) in [(10000, "10"), (12000, "1000"), (20000, "1000")] {
            let out = dir.join(format!("long-{ranks}-{steps}.h5"));
            let args = run_args(
                scene.to_str().unwrap(),
                out.to_str().unwrap(),
                &["--steps", &steps.to_string(), "--every", every],
            );
            let mut child = launch(ranks, &args).stdout(Stdio::null()).spawn().unwrap();
            let what = format!("{steps} steps on {ranks} ranks");
            let st = wait_for(&mut child, Duration::from_secs(240), &what);
            assert!(st.success(), "{what}: exit {st}");
            assert_eq!(status_by_h5dump(&out), "finished", "{what}");
            assert_eq!(raw(&out, "energy/step").len(), steps + 1, "{what}: every step written");
        }
    }
}

/// The child half of the metadata test: runs under mpirun (see below).
fn metadata_child(dir: &Path) {
    use massfree::io::{FieldSpec, Meta, Output, OutputPlan, PlannedField, RunFile};
    use massfree::time::Energy;
    use mpi::traits::*;
    let universe = mpi::initialize().unwrap();
    let world = universe.world();
    let rank = world.rank() as usize;
    let geo = repo().join("meshes/square_quad.geo");
    let msh = massfree::mesh::gmsh::mesh_geo(&geo, &[], 3, false, &dir.join("cache")).unwrap();
    let mesh = massfree::mesh::msh::read_msh(&msh).unwrap();
    let path = dir.join("meta.h5");
    // Text of a different length on every rank, as timings, paths or warnings would be.
    let own = |base: &str, k: usize| format!("{base} {}", "r".repeat(1 + 997 * rank + k % 7));
    let file = RunFile::create(
        &world,
        &path,
        true,
        &[Meta::text("status", "running"), Meta::text("note", own("created on rank", 0))],
    )
    .unwrap();
    for k in 0..200 {
        file.write_meta(&world, &[Meta::text("note", own("rewritten", k))]).unwrap();
    }
    let plan = OutputPlan {
        fields: vec![PlannedField { spec: FieldSpec::nodal("displacement", mesh.dim), every: 50 }],
        time_steps: vec![],
        compression: None,
    };
    let cell_rank = vec![0; mesh.cells.len()];
    let mut out = Output::open(file, &world, &mesh, &cell_rank, plan).unwrap();
    let (lo, hi) = out.natural_range();
    let block = vec![rank as f64; (hi - lo) * mesh.dim];
    for step in 0..12000 {
        let e = Energy { kinetic: step as f64, ..Default::default() };
        out.write_energy(step, step as f64, &e).unwrap();
        if step % 50 == 0 {
            out.write_fields(step, step as f64, &[Some(block.clone())]).unwrap();
        }
    }
    let summary = own("summary of rank", rank * 1000);
    out.finish(&world, &[Meta::text("status", "finished"), Meta::text("summary", summary)])
        .unwrap();
}

#[test]
fn metadata_from_values_that_differ_between_ranks_cannot_hang() {
    if let Ok(dir) = std::env::var("MASSFREE_META_CHILD") {
        metadata_child(Path::new(&dir));
        return;
    }
    let dir = scratch("metadata");
    let exe = std::env::current_exe().unwrap();
    let mut cmd = Command::new("mpirun");
    cmd.args(["-q", "--oversubscribe", "-n", "3"])
        .arg(&exe)
        .args([
            "--exact",
            "metadata_from_values_that_differ_between_ranks_cannot_hang",
            "--test-threads",
            "1",
        ])
        .env("MASSFREE_META_CHILD", &dir)
        .stdout(Stdio::null());
    mpi_env(&mut cmd);
    let mut child = cmd.spawn().unwrap();
    let st = wait_for(&mut child, Duration::from_secs(180), "the metadata writers");
    assert!(st.success(), "the 3-rank metadata writers failed: {st}");
    let h5 = dir.join("meta.h5");
    let run = reader(&h5);
    let text = |name: &str| run.text(name);
    assert_eq!(status_by_h5dump(&h5), "finished");
    // Only rank 0's values reach the file: rank 0's summary has 1 + 0 + 0 characters of r.
    assert_eq!(text("summary"), "summary of rank r");
    assert_eq!(text("note"), format!("rewritten {}", "r".repeat(1 + 199 % 7)));
    assert_eq!(raw(&h5, "energy/kinetic").len(), 12000);
    let u = raw(&h5, "fields/displacement");
    let n = u.len() / 240 / 2;
    // Each rank wrote its own block of nodes: the values are the writers' ranks, in order.
    let first_row = &u[..n * 2];
    assert_eq!(first_row[0], 0.0);
    assert_eq!(*first_row.last().unwrap(), 2.0);
    assert!(first_row.windows(2).all(|w| w[0] <= w[1]));
}

/// When to send the signal.
#[derive(Debug, Clone, Copy)]
enum Moment {
    /// This long after the output file appeared (the run is meshing a new mesh, partitioning
    /// or assembling).
    Setup(f64),
    /// This long after the output file appeared (the run is stepping).
    Stepping(f64),
    /// As soon as the last step's line is printed (the run is in its final phase).
    Final,
}

struct Stopped {
    status: String,
    exit: ExitStatus,
    /// From the signal to the end of the process.
    after_signal: Duration,
}

impl Stopped {
    /// One line of the test's report.
    fn line(&self, what: &str) -> String {
        format!("{what}: {} after {:.2} s", self.status, self.after_signal.as_secs_f64())
    }
}

/// Start a run, signal it (SIGTERM; to mpirun, which forwards it, for several ranks) at the
/// given moment, and report how it ended.
fn stop_run(ranks: usize, args: &[String], out: &Path, moment: Moment) -> Stopped {
    let _ = std::fs::remove_file(out);
    let mut child =
        launch(ranks, args).stdout(Stdio::piped()).stderr(Stdio::null()).spawn().unwrap();
    let stdout = child.stdout.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel::<String>();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(|l| l.ok()) {
            let _ = tx.send(line);
        }
    });
    let steps: usize =
        args.iter().position(|a| a == "--steps").map(|i| args[i + 1].parse().unwrap()).unwrap();
    let t0 = Instant::now();
    match moment {
        Moment::Setup(d) | Moment::Stepping(d) => {
            while !out.exists() {
                assert!(t0.elapsed() < Duration::from_secs(60), "no output file after 60 s");
                assert!(child.try_wait().unwrap().is_none(), "the run ended before the signal");
                std::thread::sleep(Duration::from_millis(5));
            }
            std::thread::sleep(Duration::from_secs_f64(d));
        }
        Moment::Final => {
            let last = format!("step {steps} ");
            loop {
                let line = rx.recv_timeout(Duration::from_secs(60)).expect("no last step line");
                if line.starts_with(&last) {
                    break;
                }
            }
        }
    }
    let _ = Command::new("kill").args(["-TERM", &child.id().to_string()]).status();
    let t_signal = Instant::now();
    let exit = wait_for(&mut child, Duration::from_secs(30), "a signalled run");
    let after_signal = t_signal.elapsed();
    Stopped { status: status_by_h5dump(out), exit, after_signal }
}

#[test]
fn a_signal_at_any_moment_ends_the_run_with_a_truthful_file() {
    let dir = scratch("kill-anywhere");
    let disc = coarse_disc(&dir);
    let mut final_phase_hits = 0;
    let mut report = Vec::new();
    for ranks in [1, 2] {
        // The second delay is random: it lands in meshing, partitioning, assembly or the first
        // steps, whichever the machine is at.
        let late = 0.9 + 0.8 * (rand_seed() % 1000) as f64 / 1000.0;
        for (trial, delay) in [0.05, late].into_iter().enumerate() {
            // Meshing: a mesh size no run used before, so that gmsh (about a second) runs.
            let h =
                format!("h={}", 0.05 + 1e-5 * (rand_seed() % 1000) as f64 + 1e-3 * trial as f64);
            let tet = scene_variant("block_tet.toml", &dir, &[]);
            let out = dir.join(format!("mesh-{ranks}-{trial}.h5"));
            let args = run_args(
                tet.to_str().unwrap(),
                out.to_str().unwrap(),
                &["--param", &h, "--steps", "100000"],
            );
            let s = stop_run(ranks, &args, &out, Moment::Setup(delay));
            let line = s.line(&format!("set-up, {ranks} rank(s), +{delay:.2} s"));
            assert!(s.status.starts_with("interrupted: a signal stopped the run"), "{line}");
            check_exit(&s, ranks);
            report.push(line);

            // Stepping: then continue the run from its checkpoint and compare with a run that
            // was never interrupted.
            let out = dir.join(format!("step-{ranks}-{trial}.h5"));
            let mut args = run_args(
                disc.to_str().unwrap(),
                out.to_str().unwrap(),
                &["--steps", "1000000", "--every", "20"],
            );
            args.extend(strings(&["--", "-ksp_rtol", "1e-12"]));
            let s = stop_run(ranks, &args, &out, Moment::Stepping(1.0 + delay));
            let line = s.line(&format!("stepping, {ranks} rank(s), +{:.2} s", 1.0 + delay));
            assert!(
                s.status.starts_with("interrupted: a signal stopped the run after step"),
                "{line}"
            );
            check_exit(&s, ranks);
            report.push(line);
            let k = raw(&out, "checkpoint/scalars")[0] as usize;
            assert_eq!(
                k as f64,
                *raw(&out, "energy/step").last().unwrap(),
                "checkpoint = last step"
            );
            let total = (k + 150).to_string();
            let run_to_end = |o: &Path, restart: Option<&Path>| {
                let mut a = run_args(
                    disc.to_str().unwrap(),
                    o.to_str().unwrap(),
                    &["--steps", &total, "--every", "20"],
                );
                if let Some(r) = restart {
                    a.extend(strings(&["--restart", r.to_str().unwrap()]));
                }
                a.extend(strings(&["--", "-ksp_rtol", "1e-12"]));
                let st = launch(ranks, &a).stdout(Stdio::null()).status().unwrap();
                assert!(st.success());
            };
            let (cont, full) = (dir.join("continued.h5"), dir.join("uninterrupted.h5"));
            run_to_end(&cont, Some(&out));
            run_to_end(&full, None);
            let d = max_rel_diff(&raw(&full, "checkpoint/u"), &raw(&cont, "checkpoint/u"));
            assert!(d < 1e-9, "restart after step {k} differs from the uninterrupted run by {d:e}");
            let (ea, eb) = (raw(&full, "energy/total"), raw(&cont, "energy/total"));
            assert!(rel_diff(*ea.last().unwrap(), *eb.last().unwrap()) < 1e-10);

            // The final phase: summary, pictures, final metadata.
            let out = dir.join(format!("final-{ranks}-{trial}.h5"));
            let args = strings(&[
                "run",
                disc.to_str().unwrap(),
                "-v",
                "--overwrite",
                "-o",
                out.to_str().unwrap(),
                "--steps",
                "3000",
            ]);
            let s = stop_run(ranks, &args, &out, Moment::Final);
            let line = s.line(&format!("final phase, {ranks} rank(s)"));
            // A signal that comes after the file was marked finished finds a finished run.
            if s.status.starts_with("interrupted") {
                assert!(s.status.contains("after the last step (3000 of 3000)"), "{line}");
                check_exit(&s, ranks);
                final_phase_hits += 1;
            } else {
                assert_eq!(s.status, "finished", "{line}");
            }
            report.push(line);
        }
    }
    eprintln!("{}", report.join("\n"));
    assert!(
        final_phase_hits > 0,
        "no signal reached a run in its final phase:\n{}",
        report.join("\n")
    );
}

fn rand_seed() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().subsec_nanos()
        as u64
}

/// A stopped run exits within seconds (mpirun itself waits about 2 s before it ends), with
/// exit code 130 when the binary runs alone and non-zero under mpirun.
fn check_exit(s: &Stopped, ranks: usize) {
    assert!(s.after_signal < Duration::from_secs(6), "took {:?} to stop", s.after_signal);
    if ranks == 1 {
        assert_eq!(s.exit.code(), Some(130));
    } else {
        assert!(!s.exit.success());
    }
}

#[test]
fn a_killed_run_leaves_a_readable_file_that_post_reports_as_unfinished() {
    let dir = scratch("sigkill");
    let disc = coarse_disc(&dir);
    for trial in 0..3 {
        let out = dir.join(format!("killed-{trial}.h5"));
        let args = run_args(disc.to_str().unwrap(), out.to_str().unwrap(), &["--steps", "1000000"]);
        let mut child =
            launch(2, &args).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
        // Kill it once more than 100 (and, trial by trial, a few more) steps are in the file,
        // however loaded the machine is: wait for the file, not for a time.
        let start = std::time::Instant::now();
        while steps_in_growing_file(&out).is_none_or(|n| n < 120 + 37 * trial) {
            assert!(start.elapsed() < Duration::from_secs(120), "the run wrote too few steps");
            std::thread::sleep(Duration::from_millis(20));
        }
        // SIGKILL to the ranks (as the kernel's OOM killer would); mpirun then ends the job.
        let _ = Command::new("pkill").args(["-9", "-P", &child.id().to_string()]).status();
        let st = wait_for(&mut child, Duration::from_secs(30), "a killed run");
        assert!(!st.success());
        assert_eq!(status_by_h5dump(&out), "running");
        let o =
            massfree(0, &["post", out.to_str().unwrap(), "-o", dir.join("p").to_str().unwrap()]);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "post failed: {}", String::from_utf8_lossy(&o.stderr));
        let steps = raw(&out, "energy/step");
        let last = format!("the run did not finish (status still \"running\": killed, or still running): last written step {}", steps.last().unwrap());
        assert!(text.contains(&last), "post says:\n{text}");
        assert!(steps.len() > 100, "only {} steps written", steps.len());
    }
}

#[test]
fn the_watchdog_ends_a_run_whose_rank_stopped_responding() {
    let dir = scratch("watchdog");
    let disc = coarse_disc(&dir);
    let out = dir.join("hung.h5");
    let args = run_args(
        disc.to_str().unwrap(),
        out.to_str().unwrap(),
        &["--steps", "1000000", "--hang-timeout", "2"],
    );
    let mut child = launch(2, &args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
    while !out.exists() {
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(1500));
    // Stop one rank: the other then waits in a collective that never completes.
    let ranks = Command::new("pgrep").args(["-P", &child.id().to_string()]).output().unwrap();
    let pids: Vec<String> =
        String::from_utf8_lossy(&ranks.stdout).split_whitespace().map(String::from).collect();
    assert_eq!(pids.len(), 2, "rank processes: {pids:?}");
    let _ = Command::new("kill").args(["-STOP", &pids[1]]).status();
    let t0 = Instant::now();
    let st = wait_for(&mut child, Duration::from_secs(30), "a run with a stopped rank");
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    assert!(!st.success());
    assert!(t0.elapsed() < Duration::from_secs(15), "the watchdog took {:?}", t0.elapsed());
    assert!(
        err.contains("made no progress for") && err.contains("in stepping after step"),
        "stderr:\n{err}"
    );
}

#[test]
fn results_do_not_depend_on_the_number_of_ranks_from_one_to_four() {
    let dir = scratch("rank-sweep");
    // The default scene (the two-disc impact with contact) and the beam (loads, Dirichlet).
    let disc = scene_variant("disc.toml", &dir, &[("steps = 1000", "steps = 300")]);
    let beam = scene_variant(
        "beam.toml",
        &dir,
        &[("steps = 250", "steps = 60"), ("error_steps = [30, 250]", "error_steps = [60]")],
    );
    for (scene, datasets) in [
        (
            &disc,
            vec![
                "energy/total",
                "energy/contact_work",
                "fields/displacement",
                "fields/velocity",
                "contact/pressure",
                "contact/active",
            ],
        ),
        (
            &beam,
            vec!["energy/total", "energy/external_work", "fields/displacement", "fields/velocity"],
        ),
    ] {
        let mut files = Vec::new();
        for ranks in 1..=4 {
            let out =
                dir.join(format!("{}-{ranks}.h5", scene.file_stem().unwrap().to_string_lossy()));
            let args = run_args(
                scene.to_str().unwrap(),
                out.to_str().unwrap(),
                &["--", "-ksp_rtol", "1e-13"],
            );
            let mut child = launch(ranks, &args).stdout(Stdio::null()).spawn().unwrap();
            let st = wait_for(&mut child, Duration::from_secs(120), "rank sweep");
            assert!(st.success(), "{} on {ranks} ranks: {st}", scene.display());
            assert_eq!(status_by_h5dump(&out), "finished");
            files.push(out);
        }
        for name in &datasets {
            // (u8 active flags are read as numbers too: HDF5 converts them.)
            let one = raw(&files[0], name);
            for (k, other) in files.iter().enumerate().skip(1) {
                let b = raw(other, name);
                let d = max_rel_diff(&one, &b);
                assert!(
                    d <= 1e-8,
                    "{}: {name} on {} ranks differs from 1 rank by {d:e}",
                    scene.display(),
                    k + 1
                );
            }
        }
    }
}

#[test]
fn the_run_script_works_from_any_directory_and_prints_one_error_line() {
    let dir = scratch("run-script");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[("steps = 250", "steps = 20"), ("error_steps = [30, 250]", "error_steps = [20]")],
    );
    let good = std::fs::read_to_string(&scene).unwrap();
    assert!(good.contains("E = 200.0"));
    std::fs::write(dir.join("bad.toml"), good.replace("E = 200.0", "E = -1.0")).unwrap();
    let script = repo().join("run");
    let run = |args: &[&str]| {
        let mut cmd = Command::new(&script);
        cmd.args(args).current_dir(&dir).env("MASSFREE_PREBUILT", "1");
        mpi_env(&mut cmd);
        cmd.output().unwrap()
    };
    // Relative scene and output paths are the caller's.
    let name = scene.file_name().unwrap().to_str().unwrap();
    let o = run(&[name, "-q", "-o", "results/beam.h5"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(status_by_h5dump(&dir.join("results/beam.h5")), "finished");
    // A bad scene: exactly one line on stderr, naming the key, and a non-zero exit code.
    let o = run(&["bad.toml"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "stderr:\n{err}");
    assert!(
        err.starts_with("massfree: scene error: bad.toml:") && err.contains("material.E"),
        "{err}"
    );
    // The same output again: refused (the file exists), once, on one line.
    let o = run(&[name, "-q", "-o", "results/beam.h5"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(err.lines().count(), 1, "stderr:\n{err}");
    assert!(err.contains("results/beam.h5 exists; pass --overwrite"), "{err}");
}
