//! Shared helpers of the integration tests: scene variants, runs of the real binary under
//! mpirun, and reading back summaries and HDF5 output.
#![allow(dead_code)]

use std::collections::HashMap;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, ExitStatus, Output};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

#[allow(unused_imports)] // not every test file reads dataset names
pub use massfree::io::layout::{self, RunReader};
pub use massfree::report::RunSummary;

/// A run's file through the reader post and study use (panics with the path if it fails).
pub fn reader(h5: &Path) -> RunReader {
    RunReader::open(h5).unwrap_or_else(|e| panic!("{e}"))
}

/// Dataset `name` of a run's file as numbers, flattened (panics with the name if absent).
pub fn values(h5: &Path, name: &str) -> Vec<f64> {
    reader(h5).series(name).unwrap_or_else(|e| panic!("{e}"))
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_massfree"))
}

/// A fresh folder for one test's files under target/test-runs.
pub fn scratch(name: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let k = N.fetch_add(1, Ordering::SeqCst);
    let dir = repo().join("target/test-runs").join(format!("{name}-{}-{k}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Write a variant of a shipped scene: mesh paths made absolute, text replacements applied.
pub fn scene_variant(base: &str, dir: &Path, replace: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(repo().join("scenes").join(base)).unwrap();
    text = text.replace("\"../meshes/", &format!("\"{}/meshes/", repo().display()));
    for (a, b) in replace {
        assert!(text.contains(a), "scene {base} has no {a:?}");
        text = text.replace(a, b);
    }
    let path = dir.join(base);
    std::fs::write(&path, text).unwrap();
    path
}

/// Write a scene from text (mesh paths relative to the repo's meshes/ made absolute).
pub fn scene_text(dir: &Path, name: &str, text: &str) -> PathBuf {
    let text = text.replace("\"../meshes/", &format!("\"{}/meshes/", repo().display()));
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Write the small test scene `NAME.toml`: the mesh `meshes/GEO` at size `h`, the material
/// E = 100, nu = 0.3, rho = 1 (elastic waves at about 10), then `rest` (the other tables).
pub fn small_scene(dir: &Path, name: &str, geo: &str, h: f64, rest: &str) -> PathBuf {
    let text = format!(
        "name = \"{name}\"\n[mesh]\ngeo = \"../meshes/{geo}\"\nparams = {{ h = {h} }}\n[material]\nE = 100.0\nnu = 0.3\nrho = 1.0\n{rest}"
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

/// `mpirun -n ranks massfree args...` (ranks = 0: the binary alone, as a singleton), within
/// [`LAUNCH_LIMIT_S`].
pub fn massfree(ranks: usize, args: &[&str]) -> Output {
    let mut cmd = if ranks == 0 {
        Command::new(bin())
    } else {
        let mut c = Command::new("mpirun");
        c.args(["--oversubscribe", "-n", &ranks.to_string()]).arg(bin());
        c
    };
    cmd.args(args);
    mpi_env(&mut cmd);
    output(&mut cmd)
}

/// The longest any one launch of a test may take (the longest, a 3-rank run of the suite's
/// scenes, takes about a minute on 2 cores): a launch that passes it is a hang.
pub const LAUNCH_LIMIT_S: f64 = 600.0;

/// `cmd`'s output like [`Command::output`], but within [`LAUNCH_LIMIT_S`]: a launch that
/// passes it is killed with everything it started, and the test fails saying HANG, with its
/// own name and the command.
pub fn output(cmd: &mut Command) -> Output {
    output_within(cmd, LAUNCH_LIMIT_S)
}

/// [`output`] with a limit of `seconds`.
pub fn output_within(cmd: &mut Command, seconds: f64) -> Output {
    let test = std::thread::current().name().unwrap_or("a test").to_string();
    let what = format!("{test}: {:?}", cmd);
    cmd.stdout(std::process::Stdio::piped()).stderr(std::process::Stdio::piped());
    let mut job = Job::start(cmd, &what);
    let stdout = job.take_stdout();
    let reader = std::thread::spawn(move || {
        let mut s = Vec::new();
        let mut stdout = stdout;
        let _ = std::io::Read::read_to_end(&mut stdout, &mut s);
        s
    });
    let status = job.wait(&Limit::fixed(seconds, "the limit of one launch of a test"));
    let stdout = reader.join().unwrap_or_default();
    let stderr = job.stderr_text().into_bytes();
    Output { status, stdout, stderr }
}

/// The environment of every launch: mpirun as root, no shared-memory single copy (containers),
/// oversubscription allowed, no backtraces in the program's messages, and HDF5's file locks
/// off. A run file this test process reads (`RunReader`) is opened by the HDF5 library
/// without close-on-exec, so a launch that another test thread starts meanwhile inherits the
/// descriptor and, with it, the read lock, for as long as that launch runs; a later run
/// writing the same file then fails with "unable to lock file, errno = 11" (seen once in
/// `tests/mass_free.rs`, whose two tests launch runs in parallel threads). The runs of one
/// test never write a file another process is writing, so the locks protect nothing here.
///
/// Each launch also gets a session directory base of its own: Open MPI 4.1 creates
/// `<base>/ompi.<host>.<uid>` with a plain mkdir and aborts on "File exists" when another
/// job created it a moment before (or removes it at its end while this one starts), a race
/// that parallel test threads lose now and then (CI, `tests/two_body.rs`, orte_init failed).
pub fn mpi_env(cmd: &mut Command) -> &mut Command {
    cmd.env("OMPI_MCA_orte_tmpdir_base", session_base())
        .env("HDF5_USE_FILE_LOCKING", "FALSE")
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RUST_BACKTRACE", "0")
}

/// A fresh, short directory (Unix socket paths under it must stay below 108 bytes) for one
/// launch's Open MPI session files.
pub fn session_base() -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join("mf-ompi").join(format!(
        "{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).expect("cannot create an Open MPI session directory base");
    dir
}

/// Run a scene and return its summary; panics with the program's output on failure.
pub fn run_scene(ranks: usize, scene: &Path, extra: &[&str]) -> RunSummary {
    let dir = scene.parent().unwrap();
    let stem = scene.file_stem().unwrap().to_string_lossy().to_string();
    let summary = dir.join(format!("{stem}-{ranks}.summary.toml"));
    let out = dir.join(format!("{stem}-{ranks}.h5"));
    let mut args = vec![
        "run".to_string(),
        scene.display().to_string(),
        "--quiet".into(),
        "--overwrite".into(),
        "--output".into(),
        out.display().to_string(),
        "--summary".into(),
        summary.display().to_string(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let argv: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    let o = massfree(ranks, &argv);
    assert!(
        o.status.success(),
        "massfree failed on {ranks} rank(s):\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(&summary).unwrap();
    toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", summary.display()))
}

pub fn rel_diff(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
}

/// A clamped beam in free vibration (no loads): the midpoint rule must conserve its energy.
/// Its bottom is the contact boundary of the mass-free layer (`--mass modified0|1`).
pub const FREE_VIBRATION: &str = r#"
name = "free_vibration"
[mesh]
geo = "../meshes/beam_quad.geo"
params = { h = 0.25 }
[material]
E = 200.0
nu = 0.3
rho = 1.0
[[dirichlet]]
group = "left"
[[dirichlet]]
group = "right"
[initial]
velocity = ["0.1*sin(pi*x/10)", "x*(10 - x)*y"]
displacement = ["0", "0.01*sin(pi*x/10)"]
[time]
tau = 1e-3
steps = 1000
[mass]
kind = "consistent"
contact_boundary = "bottom"
[output]
every = 100
"#;

/// Per step (row 0 = the start): the total contact force (the sum of the nodal forces; for a
/// two-body pair the slave side's `D lambda`) and whether any contact node is active.
pub fn force_history(h5: &Path) -> (Vec<f64>, Vec<bool>) {
    let run = reader(h5);
    let nc = run.file.dataset(&layout::contact("force")).unwrap().shape()[1];
    let force = run.series(&layout::contact("force")).unwrap();
    let active = run.series(&layout::contact("active")).unwrap();
    let total = force.chunks(nc).map(|r| r.iter().sum()).collect();
    let any = active.chunks(nc).map(|r| r.iter().any(|&a| a != 0.0)).collect();
    (total, any)
}

/// A run for a rank-count comparison: `massfree run` with `args` (output, scene and the
/// solver options among them) on `ranks`, asserted to succeed. Returns the contact forces and
/// active flags per step, and, with `estimate`, PETSc's largest condition number estimate of
/// the step solves (`-step_ksp_view_singularvalues` is added; 0 without it).
pub fn contact_history(
    ranks: usize,
    args: &[&str],
    out: &Path,
    estimate: bool,
) -> (ndarray::Array2<f64>, Vec<f64>, f64) {
    let mut args = args.to_vec();
    if estimate {
        args.push("-step_ksp_view_singularvalues");
    }
    let o = massfree(ranks, &args);
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{ranks} rank(s): {}", String::from_utf8_lossy(&o.stderr));
    // "Iteratively computed extreme singular values: max A min B max/min C", per solve.
    let kappa = stdout
        .lines()
        .filter(|l| l.contains("extreme singular values"))
        .map(|l| l.rsplit(' ').next().unwrap().parse::<f64>().unwrap())
        .fold(0.0f64, f64::max);
    assert!(!estimate || kappa > 1.0, "no condition number estimate in the output");
    let r = reader(out);
    let f = r.table(&layout::contact("force")).unwrap();
    let a = r.series(&layout::contact("active")).unwrap();
    (f, a, kappa)
}

/// Per stored step, the largest difference of two force tables over the contact nodes.
pub fn step_differences(f: &ndarray::Array2<f64>, g: &ndarray::Array2<f64>) -> Vec<f64> {
    (f.rows().into_iter().zip(g.rows()))
        .map(|(x, y)| x.iter().zip(y).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Launches that cannot outlive their test, and limits no healthy run can reach.
//
// A `Job` is a launch (mpirun or the binary alone) in a process group of its own. Open MPI gives
// each rank a process group of its own too (its ODLS calls setpgid), so killing mpirun's group
// alone would leave the ranks running: on a timeout or when the test ends before it, the job
// stops mpirun (SIGSTOP: it can neither start nor reap anything now), then kills with SIGKILL
// every process that descends from it (found in /proc by their parent ids; a rank's group, which
// holds what it started, e.g. gmsh, only when the rank leads it), then mpirun's group. Nothing
// else: no process that this launch did not start is ever signalled.
//
// A `Pace` is the duration of a short reference run of the same kind, measured by the test
// itself on this machine under its present load; `Pace::limit` scales it by the work ratio and
// a wide factor (`PACE_FACTOR`, at least `PACE_FLOOR_S`). A healthy run cannot reach that limit
// unless the machine became PACE_FACTOR times slower between the two runs; a run that hangs
// reaches it. A failure message says which of the two it was: "HANG" (the limit was reached and
// the job killed) or "FAILED" (the job ended by itself with that status, within its limit).

/// The factor between a reference run's time (scaled by the work ratio) and a limit.
pub const PACE_FACTOR: f64 = 20.0;
/// No limit is shorter than this (a reference run can be lucky with the load).
pub const PACE_FLOOR_S: f64 = 60.0;
/// The cap of a reference run itself (a run of a few seconds).
pub const REFERENCE_CAP_S: f64 = 600.0;

/// How long a job may take, and why.
#[derive(Debug, Clone)]
pub struct Limit {
    pub seconds: f64,
    pub reason: String,
}

impl Limit {
    /// A fixed limit (only for reference runs and for waits no test result depends on).
    pub fn fixed(seconds: f64, reason: &str) -> Limit {
        Limit { seconds, reason: reason.to_string() }
    }
}

/// The pace of this machine now: the duration of a short reference run.
#[derive(Debug, Clone)]
pub struct Pace {
    pub seconds: f64,
    pub what: String,
}

impl Pace {
    /// Time the reference run `cmd` (a short run of the kind the limits are for), which must
    /// succeed; its output goes nowhere.
    pub fn measure(cmd: &mut Command, what: &str) -> Pace {
        cmd.stdout(std::process::Stdio::null()).stderr(std::process::Stdio::piped());
        let mut job = Job::start(cmd, &format!("the reference run ({what})"));
        let cap = Limit::fixed(REFERENCE_CAP_S, "the cap of a reference run of seconds");
        let st = job.wait(&cap);
        let seconds = job.elapsed().as_secs_f64();
        let err = job.stderr_text();
        assert!(st.success(), "FAILED: the reference run ({what}): exit {st}\n{err}");
        eprintln!("pace: {what} took {seconds:.2} s");
        Pace { seconds, what: what.to_string() }
    }

    /// The limit of a run doing `work` times the reference's work (at least once).
    pub fn limit(&self, work: f64) -> Limit {
        let w = work.max(1.0);
        let seconds = (PACE_FACTOR * self.seconds * w).max(PACE_FLOOR_S);
        Limit {
            seconds,
            reason: format!(
                "{PACE_FACTOR} x the reference run ({}: {:.2} s) x {w:.1} its work, at least {PACE_FLOOR_S} s",
                self.what, self.seconds
            ),
        }
    }
}

/// A launch in a process group of its own, killed with everything it started (and nothing
/// else) when a limit is reached or when it is dropped still running.
pub struct Job {
    child: Child,
    what: String,
    started: Instant,
    status: Option<ExitStatus>,
    /// A piped stderr, drained by a thread (a full pipe would block the program).
    stderr: Option<std::thread::JoinHandle<String>>,
}

impl Job {
    /// Start `cmd` (see [`massfree_command`]) in a new process group.
    pub fn start(cmd: &mut Command, what: &str) -> Job {
        cmd.process_group(0);
        let mut child = cmd.spawn().unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
        let stderr = child.stderr.take().map(|mut e| {
            std::thread::spawn(move || {
                let mut s = String::new();
                let _ = std::io::Read::read_to_string(&mut e, &mut s);
                s
            })
        });
        Job { child, what: what.to_string(), started: Instant::now(), status: None, stderr }
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    pub fn what(&self) -> &str {
        &self.what
    }

    /// Since the start.
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    pub fn take_stdout(&mut self) -> ChildStdout {
        self.child.stdout.take().expect("stdout piped")
    }

    /// What the job wrote on stderr, if it was piped (empty otherwise); call it once the job
    /// has ended.
    pub fn stderr_text(&mut self) -> String {
        self.stderr.take().map(|t| t.join().unwrap_or_default()).unwrap_or_default()
    }

    /// The exit status, if the job has ended.
    pub fn poll(&mut self) -> Option<ExitStatus> {
        if self.status.is_none() {
            self.status = self.child.try_wait().expect("try_wait");
        }
        self.status
    }

    /// Send `sig` to the launched process alone (mpirun forwards SIGTERM and SIGINT to the
    /// ranks).
    pub fn signal(&self, sig: Signal) {
        let _ = kill(Pid::from_raw(self.pid() as i32), sig);
    }

    /// The launched process's children: the ranks under mpirun.
    pub fn children(&self) -> Vec<u32> {
        let table = process_table();
        table.iter().filter(|p| p.ppid == self.pid()).map(|p| p.pid).collect()
    }

    /// Wait for the end, at most `limit` from now: the exit status, or a panic saying HANG
    /// after killing the job's processes.
    pub fn wait(&mut self, limit: &Limit) -> ExitStatus {
        self.wait_until(limit, "its end", |_| false);
        self.status.unwrap()
    }

    /// Wait, at most `limit` from now, until `ready(elapsed)` holds or the job ends: `true` when
    /// ready, `false` when the job ended first. Reaching the limit kills the job's processes
    /// and panics with HANG.
    pub fn wait_until(
        &mut self,
        limit: &Limit,
        what: &str,
        mut ready: impl FnMut(Duration) -> bool,
    ) -> bool {
        let t0 = Instant::now();
        loop {
            if self.poll().is_some() {
                return false;
            }
            if ready(self.elapsed()) {
                return true;
            }
            if t0.elapsed().as_secs_f64() > limit.seconds {
                self.kill_all();
                panic!(
                    "{}: HANG: waited {:.1} s for {what}, beyond the limit of {:.1} s ({}); the job's processes were killed",
                    self.what,
                    t0.elapsed().as_secs_f64(),
                    limit.seconds,
                    limit.reason
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Like [`Job::wait_until`], but the job ending first is a failure (FAILED, with its exit
    /// status and stderr if piped).
    pub fn wait_for(&mut self, limit: &Limit, what: &str, ready: impl FnMut(Duration) -> bool) {
        if !self.wait_until(limit, what, ready) {
            let st = self.status.unwrap();
            let err = self.stderr_text();
            panic!(
                "{}: FAILED: it ended ({st}) after {:.1} s, before {what}\n{err}",
                self.what,
                self.elapsed().as_secs_f64()
            );
        }
    }

    /// SIGKILL to every process of the job, and reap it.
    pub fn kill_all(&mut self) {
        if self.poll().is_some() {
            return;
        }
        let root = self.pid();
        // Frozen, mpirun can neither start ranks nor reap them: their pids stay theirs.
        let _ = kill(Pid::from_raw(root as i32), Signal::SIGSTOP);
        for _ in 0..3 {
            let table = process_table();
            let ours = descendants_in(&table, root);
            for p in table.iter().filter(|p| ours.contains(&p.pid)) {
                if p.pgrp == p.pid {
                    // A group led by a process of ours (a rank): it and what it started.
                    let _ = kill(Pid::from_raw(-(p.pid as i32)), Signal::SIGKILL);
                }
                let _ = kill(Pid::from_raw(p.pid as i32), Signal::SIGKILL);
            }
        }
        // The launch's own group, which it leads (`process_group(0)`).
        let _ = kill(Pid::from_raw(-(root as i32)), Signal::SIGKILL);
        self.status = self.child.wait().ok();
    }
}

impl Drop for Job {
    fn drop(&mut self) {
        self.kill_all();
    }
}

/// One line of /proc/PID/stat: the ids a job needs.
#[derive(Debug, Clone, Copy)]
struct Proc {
    pid: u32,
    ppid: u32,
    pgrp: u32,
}

fn process_table() -> Vec<Proc> {
    let mut out = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc") else { return out };
    for e in dir.flatten() {
        let Some(pid) = e.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else { continue };
        // "pid (comm) state ppid pgrp ...": comm may hold spaces and parentheses.
        let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else { continue };
        let f: Vec<&str> = rest.split_whitespace().collect();
        if let (Some(ppid), Some(pgrp)) =
            (f.get(1).and_then(|x| x.parse().ok()), f.get(2).and_then(|x| x.parse().ok()))
        {
            out.push(Proc { pid, ppid, pgrp });
        }
    }
    out
}

/// Every process descending from `root` (children, their children, ...).
fn descendants_in(table: &[Proc], root: u32) -> Vec<u32> {
    let mut out = vec![];
    let mut frontier = vec![root];
    while let Some(p) = frontier.pop() {
        for c in table.iter().filter(|c| c.ppid == p) {
            if !out.contains(&c.pid) {
                out.push(c.pid);
                frontier.push(c.pid);
            }
        }
    }
    out
}

/// `mpirun -q -n ranks massfree args` (ranks = 1: the binary alone, as users also run it), with
/// the MPI environment; start it with [`Job::start`].
pub fn massfree_command(ranks: usize, args: &[String]) -> Command {
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

/// The length of `/energy/step` in a file a run is still writing (h5dump without file
/// locking; `None` while the file or the dataset is not readable yet).
pub fn steps_in_growing_file(h5: &Path) -> Option<usize> {
    if !h5.exists() {
        return None;
    }
    let o = output_within(
        Command::new("h5dump")
            .args(["-H", "-d", "/energy/step"])
            .arg(h5)
            .env("HDF5_USE_FILE_LOCKING", "FALSE"),
        60.0,
    );
    let text = String::from_utf8_lossy(&o.stdout).to_string();
    let line = text.lines().find(|l| l.contains("DATASPACE"))?;
    line.split_once("( ")?.1.split_once(' ')?.0.parse().ok()
}

/// The pseudo-random choices of a test (delays, mesh sizes): xorshift64* from a seed that is
/// printed, `MASSFREE_TEST_SEED` when set (to repeat a run's choices), else a fixed default.
pub struct Rng(u64);

impl Rng {
    pub const DEFAULT_SEED: u64 = 20_260_423;

    pub fn from_env(test: &str) -> Rng {
        let seed = match std::env::var("MASSFREE_TEST_SEED") {
            Ok(s) => s.trim().parse().unwrap_or_else(|_| panic!("MASSFREE_TEST_SEED={s:?}")),
            Err(_) => Rng::DEFAULT_SEED,
        };
        eprintln!("{test}: seed {seed} (MASSFREE_TEST_SEED={seed} repeats its choices)");
        // splitmix64 of the seed: never the all-zero state xorshift cannot leave.
        let mut z = seed.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        Rng((z ^ (z >> 31)) | 1)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        (x.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A study's `results.csv` as one map column -> value per row.
pub fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
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

/// A number of a study's CSV row.
pub fn num(row: &HashMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap_or_else(|_| panic!("{key} = {:?} in {row:?}", row[key]))
}
