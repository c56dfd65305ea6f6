//! Issue 27, a step near the hardware's floor (`./run bench --only step [--baseline BIN]`):
//!
//! - the beam at 10^6 DOFs (mass-dominated, CFL 0.002) on 1 and 2 ranks, 100 steps;
//! - the 3D block at 266k DOFs in free vibration at CFL 33, on 1 and 2 ranks, a short run
//!   (20 steps: multigrid) and a long one (200 steps: the choice factors);
//! - a table over CFL 0.3-100 of the three step solvers on the beam (2D) and the block (3D),
//!   with the solver `time::choice` picks for a run of 1000 steps;
//! - the ball dropped on the plane (contact) at 162k and 950k DOFs: a run to the contact
//!   writes a checkpoint, and every build continues it for a few contact steps.
//!
//! `--baseline BIN` runs the same cases with another build (the commit before the issue) for
//! the ratios. Products with `K` per step come from `-log_view`'s `MatMult` count (all levels
//! of multigrid, and the products with `M`), differenced between a run of n and 2n steps so
//! that set-up and diagnostics drop out. Bytes moved are estimated from the stored matrices
//! and the vectors a step streams (see README).

use std::path::{Path, PathBuf};
use std::process::Command;

use massfree::report::RunSummary;

/// One run: its summary and the `MatMult` count of `-log_view` (None without `-log_view`).
fn run(
    bin: &Path,
    ranks: usize,
    scene: &Path,
    args: &[String],
    log: bool,
    dir: &Path,
) -> Option<(RunSummary, Option<f64>)> {
    let summary = dir.join("step-floor.toml");
    let _ = std::fs::remove_file(&summary);
    let mut cmd = Command::new("mpirun");
    cmd.args(["--oversubscribe", "-n", &ranks.to_string()])
        .arg(bin)
        .arg("run")
        .arg(scene)
        .args(["--quiet", "--overwrite", "--summary"])
        .arg(&summary)
        .args(if args.iter().any(|a| a == "--output") { None } else { Some("--no-output") })
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none");
    if log {
        if !args.iter().any(|a| a == "--") {
            cmd.arg("--");
        }
        cmd.arg("-log_view");
    }
    let o = cmd.output().ok()?;
    if !o.status.success() {
        eprintln!("bench: step floor run failed: {}", String::from_utf8_lossy(&o.stderr));
        return None;
    }
    let text = std::fs::read_to_string(&summary).ok()?;
    let s: RunSummary = toml::from_str(&text).ok()?;
    let count = log.then(|| matmult_count(&String::from_utf8_lossy(&o.stdout))).flatten();
    Some((s, count))
}

/// The `MatMult` event's count in `-log_view`'s table.
fn matmult_count(log: &str) -> Option<f64> {
    log.lines()
        .find(|l| l.split_whitespace().next() == Some("MatMult"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
}

/// Products with `K` (and `M`, all multigrid levels) per step: the count of a run of `2 n`
/// steps less that of `n`, over `n`.
fn products_per_step(
    bin: &Path,
    ranks: usize,
    scene: &Path,
    args: &[String],
    n: usize,
    dir: &Path,
) -> Option<f64> {
    let with = |steps: usize| {
        let mut a = vec!["--steps".to_string(), steps.to_string()];
        a.extend_from_slice(args);
        run(bin, ranks, scene, &a, true, dir).and_then(|r| r.1)
    };
    Some((with(2 * n)? - with(n)?) / n as f64)
}

/// A variant of a shipped scene: loads, exact solution and output dropped (free vibration),
/// the step `tau`.
fn free_vibration(repo: &Path, scene: &str, tau: f64, dir: &Path) -> PathBuf {
    variant(repo, scene, Some(tau), &["[[neumann]]", "[body_force]", "[exact]", "[output]"], dir)
}

/// A variant of a shipped scene without the sections `drop`, with the step `tau` if given.
fn variant(repo: &Path, scene: &str, tau: Option<f64>, drop: &[&str], dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo.join("scenes").join(scene)).expect("scene");
    let mut out = String::new();
    let mut skip = false;
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            skip = drop.contains(&t);
        }
        if skip {
            continue;
        }
        if let (true, Some(tau)) = (t.starts_with("tau ="), tau) {
            out += &format!("tau = {tau:e}\n");
        } else if t.starts_with("geo =") {
            out += &line.replace("../meshes/", &format!("{}/meshes/", repo.display()));
            out += "\n";
        } else {
            out += line;
            out += "\n";
        }
    }
    let tag = tau.map_or("same".to_string(), |t| format!("{t:e}"));
    let path = dir.join(format!("{}-{}-{tag}.toml", scene.trim_end_matches(".toml"), drop.len()));
    std::fs::write(&path, out).expect("write scene");
    path
}

fn per_step(s: &RunSummary) -> f64 {
    s.timings.stepping / s.steps.max(1) as f64
}

const JACOBI: &[&str] = &["-step_ksp_type", "cg", "-step_pc_type", "jacobi"];
const GAMG: &[&str] = &["-step_ksp_type", "cg", "-step_pc_type", "gamg"];
const CHOLESKY: &[&str] = &[
    "-step_ksp_type",
    "preonly",
    "-step_pc_type",
    "cholesky",
    "-step_pc_factor_mat_solver_type",
    "mumps",
];

fn strings(a: &[&str]) -> Vec<String> {
    a.iter().map(|s| s.to_string()).collect()
}

pub fn section(
    repo: &Path,
    dir: &Path,
    quick: bool,
    baseline: Option<&Path>,
    parts: &[usize],
) -> String {
    let current = repo.join("target/release/massfree");
    let mut builds: Vec<(&str, PathBuf)> = vec![];
    if let Some(b) = baseline {
        builds.push(("baseline", b.to_path_buf()));
    }
    builds.push(("this build", current.clone()));
    let mut md = String::from("\n## Step floor\n");

    // 1. The beam, mass-dominated.
    if parts.contains(&1) {
        let h = if quick { "0.015625" } else { "0.004464285714285714" };
        // The loads kept, the errors against the exact solution dropped (the build before the
        // issue timed them as part of the stepping).
        let beam = variant(repo, "beam.toml", None, &["[exact]", "[output]"], dir);
        md += &format!(
        "\nThe beam (Q1, h = {h}, the loads of section 7.1), 100 steps, no output; products per step from `-log_view` (MatMult calls with `K` and `M`, a run of 200 steps less one of 100):\n\n| build | ranks | DOFs | ms/step | KSP its/step | MatMult calls/step | step / MatMult | ms/step ratio to before |\n|---|---|---|---|---|---|---|---|\n"
    );
        for ranks in [1, 2] {
            let mut before = None;
            for (name, bin) in &builds {
                eprintln!("bench: step floor, beam, {name}, {ranks} rank(s)");
                let args = strings(&["--param", &format!("h={h}"), "--steps", "100"]);
                let Some((s, _)) = run(bin, ranks, &beam, &args, false, dir) else {
                    md += &format!("| {name} | {ranks} | failed |\n");
                    continue;
                };
                let calls = products_per_step(
                    bin,
                    ranks,
                    &beam,
                    &strings(&["--param", &format!("h={h}")]),
                    100,
                    dir,
                );
                let t = per_step(&s);
                let ratio = before.map_or("-".to_string(), |b: f64| format!("{:.2}", t / b));
                if before.is_none() {
                    before = Some(t);
                }
                md += &format!(
                    "| {name} | {ranks} | {} | {:.2} | {:.2} | {} | {:.2} | {ratio} |\n",
                    s.n_dofs,
                    1e3 * t,
                    s.ksp_iterations as f64 / s.steps as f64,
                    calls.map_or("-".into(), |c| format!("{c:.2}")),
                    t / s.matmult_seconds
                );
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    // 2. The 3D block at CFL 33: a short and a long run.
    if parts.contains(&2) {
        let block_h = if quick { "0.1" } else { "0.05" };
        let block = free_vibration(repo, "block_tet.toml", 0.1, dir);
        md += &format!(
        "\nThe 3D block (P1 tets, h = {block_h}), free vibration, tau = 0.1 (CFL 33), no output; the default solver of each build for a run of 20 and of 200 steps (`time::choice` factors the long run):\n\n| build | ranks | steps | DOFs | solver | set-up s | ms/step | KSP its/step | (set-up + stepping) / steps, ms | peak MiB/rank | ms/step ratio to before | whole-run ratio to before |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    );
        for ranks in [1, 2] {
            for steps in [20usize, 200] {
                let mut before: Option<(f64, f64)> = None;
                for (name, bin) in &builds {
                    // The build before the issue runs 20 steps: its per-step cost does not depend
                    // on the run's length.
                    let n = if before.is_none() && baseline.is_some() { 20 } else { steps };
                    eprintln!("bench: step floor, block, {name}, {ranks} rank(s), {n} steps");
                    let args =
                        strings(&["--param", &format!("h={block_h}"), "--steps", &n.to_string()]);
                    let Some((s, _)) = run(bin, ranks, &block, &args, false, dir) else {
                        md += &format!("| {name} | {ranks} | {steps} | failed |\n");
                        continue;
                    };
                    let t = per_step(&s);
                    let whole = (s.timings.setup + s.timings.stepping) / s.steps as f64;
                    let (r1, r2) = match before {
                        Some((b, bsetup)) => (
                            format!("{:.2}", t / b),
                            format!("{:.2}", whole / ((bsetup + b * steps as f64) / steps as f64)),
                        ),
                        None => ("-".into(), "-".into()),
                    };
                    if before.is_none() {
                        before = Some((t, s.timings.setup));
                    }
                    md += &format!(
                    "| {name} | {ranks} | {steps} | {} | {} + {} | {:.1} | {:.0} | {:.1} | {:.0} | {:.0} | {r1} | {r2} |\n",
                    s.n_dofs,
                    s.ksp_type,
                    s.pc_type,
                    s.timings.setup,
                    1e3 * t,
                    s.ksp_iterations as f64 / s.steps as f64,
                    1e3 * whole,
                    s.peak_memory_rank_mib
                );
                    print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
                }
            }
        }
    }
    // 3. The solvers over CFL 0.3-100, 2D and 3D (1 rank, 10 steps), and the choice for a
    // run of 1000 steps.
    if parts.contains(&3) {
        let cases: [(&str, &str, &str); 2] = if quick {
            [("beam 2D Q1", "beam.toml", "0.0625"), ("block 3D P1", "block_tet.toml", "0.2")]
        } else {
            [("beam 2D Q1", "beam.toml", "0.015625"), ("block 3D P1", "block_tet.toml", "0.1")]
        };
        md += "\nStep solvers over the CFL number `c_p tau / h_min` (1 rank, 10 steps, free vibration; ms per step, set-up s and peak MiB in brackets; `choice` is what `time::choice` picks for a run of 1000 steps from the measured product):\n\n| case | DOFs | CFL | CG + Jacobi | CG + GAMG | Cholesky (MUMPS) | choice, 1000 steps |\n|---|---|---|---|---|---|---|\n";
        for (label, scene, h) in cases {
            // The CFL number of a probe step fixes tau for the others.
            let probe = free_vibration(repo, scene, 1e-3, dir);
            let hp = strings(&["--param", &format!("h={h}"), "--steps", "1"]);
            let Some((p, _)) = run(&current, 1, &probe, &hp, false, dir) else {
                md += &format!("| {label} | failed |\n");
                continue;
            };
            for cfl in [0.3, 1.0, 3.0, 10.0, 30.0, 100.0] {
                let scene_at = free_vibration(repo, scene, 1e-3 * cfl / p.cfl, dir);
                let mut cells = vec![];
                let mut matmult = None;
                for solver in [JACOBI, GAMG, CHOLESKY] {
                    let mut args = strings(&["--param", &format!("h={h}"), "--steps", "10", "--"]);
                    args.extend(strings(solver));
                    eprintln!("bench: step floor, {label}, CFL {cfl}, {}", solver[3]);
                    match run(&current, 1, &scene_at, &args, false, dir) {
                        Some((s, _)) => {
                            matmult = Some((s.matmult_seconds, s.n_dofs));
                            cells.push(format!(
                                "{:.1} ({:.1}; {:.0})",
                                1e3 * per_step(&s),
                                s.timings.setup,
                                s.peak_memory_rank_mib
                            ));
                        }
                        None => cells.push("failed".into()),
                    }
                }
                let pick = matmult.map_or("-".to_string(), |(mm, dofs)| {
                    let f = massfree::time::choice::RunFacts {
                        dofs,
                        dim: if scene.starts_with("beam") { 2 } else { 3 },
                        ranks: 1,
                        steps: 1000,
                        cfl,
                        contact: false,
                        memory_per_rank: 12e9,
                        // The shipped beam and cube: nu = 0.3, displacement form.
                        lambda_over_mu: 1.5,
                        nodal_pressure: false,
                    };
                    format!("{:?}", massfree::time::choice::choose(&f, mm).0)
                });
                md += &format!(
                    "| {label} | {} | {cfl} | {} | {} | {} | {pick} |\n",
                    matmult.map_or(0, |m| m.1),
                    cells[0],
                    cells[1],
                    cells[2]
                );
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    // 4. The ball on the plane: contact steps. One run of the current build to the contact
    // (its checkpoint), then each build continues from it for a window of contact steps: at
    // 162k DOFs the peak of the impact (steps 91-100: 383 active nodes), at 950k the first
    // contact steps (9-11: the zone growing, 2 ranks only).
    if parts.contains(&4) {
        let levels: &[(&str, &str, usize, usize, &[usize])] = if quick {
            &[("0.2", "0.04", 60, 10, &[1, 2])]
        } else {
            &[("0.05", "0.01", 90, 10, &[1, 2]), ("0.027", "0.0055", 8, 3, &[2])]
        };
        md += "\nThe ball dropped on the plane (P1 tets, M_H^0, tau = 0.01), contact steps continued from a checkpoint of the current build; the default solver of each build:\n\n| build | ranks | DOFs | CFL | steps | solver | ms per contact step | KSP its per contact step | peak MiB/rank | ratio to before |\n|---|---|---|---|---|---|---|---|---|---|\n";
        for &(h, hc, lead, window, ranks_list) in levels {
            let ball = variant(repo, "sphere.toml", None, &["[output]"], dir);
            let mesh = strings(&["--param", &format!("h={h}"), "--param", &format!("hc={hc}")]);
            let checkpoint = dir.join(format!("ball-{h}.h5"));
            let mut args = mesh.clone();
            args.extend(strings(&["--steps", &lead.to_string(), "--every", "1000000", "--output"]));
            args.push(checkpoint.display().to_string());
            eprintln!("bench: step floor, ball h = {h}, to step {lead}");
            let Some((first, _)) = run(&current, 2, &ball, &args, false, dir) else {
                md += &format!("| ball h = {h} | failed |\n");
                continue;
            };
            for &ranks in ranks_list {
                let mut before = None;
                for (name, bin) in &builds {
                    eprintln!("bench: step floor, ball h = {h}, {name}, {ranks} rank(s)");
                    let mut args = mesh.clone();
                    args.extend(strings(&["--steps", &(lead + window).to_string(), "--restart"]));
                    args.push(checkpoint.display().to_string());
                    let Some((s, _)) = run(bin, ranks, &ball, &args, false, dir) else {
                        md += &format!("| {name} | {ranks} | failed |\n");
                        continue;
                    };
                    // (A restart counts the checkpoint's own step among the contact steps.)
                    let Some(c) = s.contact.as_ref().filter(|c| c.contact_steps >= window) else {
                        md += &format!("| {name} | {ranks} | not every step in contact |\n");
                        continue;
                    };
                    let n = window as f64;
                    let t = c.contact_steps_seconds / n;
                    let ratio = before.map_or("-".to_string(), |b: f64| format!("{:.2}", t / b));
                    if before.is_none() {
                        before = Some(t);
                    }
                    md += &format!(
                    "| {name} | {ranks} | {} | {:.0} | {}-{} | {} + {} | {:.0} | {:.0} | {:.0} | {ratio} |\n",
                    s.n_dofs,
                    s.cfl,
                    lead + 1,
                    lead + window,
                    s.ksp_type,
                    s.pc_type,
                    1e3 * t,
                    s.ksp_iterations.saturating_sub(first.ksp_iterations) as f64 / n,
                    s.peak_memory_rank_mib
                );
                    print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
                }
            }
        }
    }
    md
}
