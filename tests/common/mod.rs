//! Shared helpers of the integration tests: scene variants, runs of the real binary under
//! mpirun, and reading back summaries and HDF5 output.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

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

/// `mpirun -n ranks massfree args...` (ranks = 0: the binary alone, as a singleton).
pub fn massfree(ranks: usize, args: &[&str]) -> Output {
    let mut cmd = if ranks == 0 {
        Command::new(bin())
    } else {
        let mut c = Command::new("mpirun");
        c.args(["--oversubscribe", "-n", &ranks.to_string()]).arg(bin());
        c
    };
    cmd.args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .env("OMPI_MCA_rmaps_base_oversubscribe", "1")
        .env("RUST_BACKTRACE", "0");
    cmd.output().expect("failed to start massfree")
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
