//! The backbone benchmark: for the beam (2D, Q1) and the block (3D, Q1) at several sizes up to
//! about 10^6 DOFs, on 1 and 2 ranks: DOFs, assembly time, operator setup time, time per step,
//! KSP iterations per step, peak memory, and each step's cost in MatMults with the step
//! operator (timed in the same run: the floor of a step's cost). Also compares step solvers.
//!
//! Run with `./run bench` (it builds the release binary first). `--quick` runs the small sizes
//! only. The Markdown tables go to stdout and to target/bench/scaling.md.

use std::path::{Path, PathBuf};
use std::process::Command;

use massfree::report::RunSummary;

#[path = "scaling/finite_strain.rs"]
mod finite_strain;
#[path = "scaling/layer.rs"]
mod layer;
#[path = "scaling/step_floor.rs"]
mod step_floor;

struct Case {
    scene: &'static str,
    h: &'static str,
    steps: usize,
    ranks: usize,
    solver: &'static [&'static str],
    label: &'static str,
    mass: &'static str,
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Where the benchmark's summaries, scratch files and tables go (created by `main`).
fn bench_dir() -> PathBuf {
    repo().join("target/bench")
}

fn run(case: &Case) -> Result<RunSummary, String> {
    let out = bench_dir();
    let summary =
        out.join(format!("summary-{}-{}-{}-{}.toml", case.label, case.h, case.ranks, case.mass));
    let _ = std::fs::remove_file(&summary);
    let mut cmd = Command::new("mpirun");
    cmd.args(["--oversubscribe", "-n", &case.ranks.to_string()])
        .arg(repo().join("target/release/massfree"))
        .arg("run")
        .arg(repo().join("scenes").join(case.scene))
        .args(["--quiet", "--no-output", "--param", &format!("h={}", case.h)])
        .args(["--steps", &case.steps.to_string(), "--mass", case.mass, "--summary"])
        .arg(&summary)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none");
    if !case.solver.is_empty() {
        cmd.arg("--").args(case.solver);
    }
    let o = cmd.output().map_err(|e| e.to_string())?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr)
            .lines()
            .last()
            .unwrap_or("failed")
            .to_string());
    }
    read_summary(&summary)
}

/// The summary a run wrote (`--summary FILE`).
fn read_summary(path: &Path) -> Result<RunSummary, String> {
    let text = std::fs::read_to_string(path).map_err(|e| e.to_string())?;
    toml::from_str(&text).map_err(|e: toml::de::Error| e.to_string())
}

/// `mpirun -n ranks massfree run scene --quiet --no-output args... --summary summary`; the
/// summary, or None if the run failed (its stderr printed).
/// `mpirun -n ranks massfree run SCENE` with the environment Open MPI needs here.
fn massfree_run(ranks: usize, scene: &Path) -> Command {
    let mut cmd = Command::new("mpirun");
    cmd.args(["--oversubscribe", "-n", &ranks.to_string()])
        .arg(repo().join("target/release/massfree"))
        .arg("run")
        .arg(scene)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none");
    cmd
}

fn run_scene(ranks: usize, scene: &str, args: &[String], summary: &Path) -> Option<RunSummary> {
    let _ = std::fs::remove_file(summary);
    let o = massfree_run(ranks, &repo().join("scenes").join(scene))
        .args(["--quiet", "--no-output", "--summary"])
        .arg(summary)
        .args(args)
        .output()
        .ok()?;
    if !o.status.success() {
        eprintln!("bench: {scene} failed: {}", String::from_utf8_lossy(&o.stderr));
        return None;
    }
    read_summary(summary).ok()
}

struct Row {
    label: String,
    ranks: usize,
    dofs: f64,
    assembly: f64,
    setup: f64,
    per_step: f64,
    its: f64,
    mem: f64,
    matmults: f64,
}

fn row(case: &Case, t: &RunSummary) -> Row {
    let steps = t.steps as f64;
    let per_step = t.timings.stepping / steps;
    Row {
        label: case.label.to_string(),
        ranks: case.ranks,
        dofs: t.n_dofs as f64,
        assembly: t.timings.assembly,
        setup: t.timings.setup,
        per_step,
        its: t.ksp_iterations as f64 / steps,
        mem: t.peak_memory_mib,
        matmults: per_step / t.matmult_seconds,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Err(e) = std::fs::create_dir_all(bench_dir()) {
        eprintln!("bench: cannot create {}: {e}", bench_dir().display());
        std::process::exit(1);
    }
    let quick = args.iter().any(|a| a == "--quick");
    // --only scaling|solvers|mass|disc|contact3d|two_body|friction|output|stress|suite|setup|step|layer|long|finite_strain|finite_contact runs one
    // section (step:N,M some parts of it).
    let only = args.iter().position(|a| a == "--only").and_then(|i| args.get(i + 1)).cloned();
    const SECTIONS: [&str; 16] = [
        "scaling",
        "solvers",
        "mass",
        "disc",
        "contact3d",
        "two_body",
        "friction",
        "output",
        "stress",
        "suite",
        "setup",
        "step",
        "layer",
        "long",
        "finite_strain",
        "finite_contact",
    ];
    if let Some(o) = only.as_deref() {
        let section = o.split_once(':').map_or(o, |(s, _)| s);
        let parts_allowed = section == "step" || section == "layer" || !o.contains(':');
        if !SECTIONS.contains(&section) || !parts_allowed {
            eprintln!("bench: --only {o}: unknown section (the sections: {})", SECTIONS.join(", "));
            std::process::exit(2);
        }
    }
    let want = |section: &str| only.as_deref().is_none_or(|o| o == section);
    let cg_jacobi: &[&str] = &[];
    let cases_2d: &[&str] = if quick {
        &["0.0625", "0.03125"]
    } else {
        &["0.03125", "0.015625", "0.0078125", "0.004464285714285714"]
    };
    let cases_3d: &[&str] =
        if quick { &["0.25", "0.125"] } else { &["0.125", "0.0625", "0.03125"] };
    let mut cases = vec![];
    for &h in cases_2d {
        for ranks in [1, 2] {
            cases.push(Case {
                scene: "beam.toml",
                h,
                steps: 20,
                ranks,
                solver: cg_jacobi,
                label: "beam 2D Q1",
                mass: "consistent",
            });
        }
    }
    for &h in cases_3d {
        for ranks in [1, 2] {
            cases.push(Case {
                scene: "block_hex.toml",
                h,
                steps: 10,
                ranks,
                solver: cg_jacobi,
                label: "block 3D Q1",
                mass: "consistent",
            });
        }
    }
    let solver_h = if quick { "0.03125" } else { "0.0078125" };
    let solvers: [(&str, &[&str]); 4] = [
        ("cg + jacobi (default)", &[]),
        ("cg + gamg", &["-ksp_type", "cg", "-pc_type", "gamg"]),
        ("cg + bjacobi/icc", &["-ksp_type", "cg", "-pc_type", "bjacobi", "-sub_pc_type", "icc"]),
        (
            "cholesky (mumps)",
            &[
                "-ksp_type",
                "preonly",
                "-pc_type",
                "cholesky",
                "-pc_factor_mat_solver_type",
                "mumps",
            ],
        ),
    ];
    let mut md = String::new();
    let machine = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_default();
    md += &format!(
        "Machine: {machine}, {} cores\n\n",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0)
    );
    // Each table's heading only where its section runs (`--only` names one).
    if want("scaling") {
        md += "| case | ranks | DOFs | assembly s | setup s | ms/step | KSP its/step | step / MatMult | peak MiB (sum) | efficiency 2 ranks |\n";
        md += "|---|---|---|---|---|---|---|---|---|---|\n";
    }
    let mut last_one_rank: Option<f64> = None;
    for case in cases.iter().filter(|_| want("scaling")) {
        eprintln!("bench: {} h = {} on {} rank(s)", case.label, case.h, case.ranks);
        match run(case) {
            Ok(t) => {
                let r = row(case, &t);
                let eff = if r.ranks == 1 {
                    last_one_rank = Some(r.per_step);
                    String::from("-")
                } else {
                    last_one_rank
                        .map(|t1| format!("{:.0}%", 100.0 * t1 / (2.0 * r.per_step)))
                        .unwrap_or_default()
                };
                md += &format!(
                    "| {} | {} | {:.0} | {:.3} | {:.3} | {:.2} | {:.1} | {:.1} | {:.0} | {} |\n",
                    r.label,
                    r.ranks,
                    r.dofs,
                    r.assembly,
                    r.setup,
                    1e3 * r.per_step,
                    r.its,
                    r.matmults,
                    r.mem,
                    eff
                );
            }
            Err(e) => {
                md += &format!("| {} h={} | {} | failed: {e} |\n", case.label, case.h, case.ranks)
            }
        }
        print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
    }
    if want("solvers") {
        md += "\nStep solvers on the beam, h = ";
        md += solver_h;
        md += ", 2 ranks, 20 steps:\n\n| solver | DOFs | setup s | ms/step | KSP its/step | step / MatMult |\n|---|---|---|---|---|---|\n";
    }
    for (name, opts) in solvers.into_iter().filter(|_| want("solvers")) {
        let case = Case {
            scene: "beam.toml",
            h: solver_h,
            steps: 20,
            ranks: 2,
            solver: opts,
            label: "solver",
            mass: "consistent",
        };
        eprintln!("bench: solver {name}");
        match run(&case) {
            Ok(t) => {
                let r = row(&case, &t);
                md += &format!(
                    "| {name} | {:.0} | {:.3} | {:.2} | {:.1} | {:.1} |\n",
                    r.dofs,
                    r.setup,
                    1e3 * r.per_step,
                    r.its,
                    r.matmults
                );
            }
            Err(e) => md += &format!("| {name} | failed: {e} |\n"),
        }
    }
    // Mass kinds side by side (issue: modified mass costs nothing extra): the same mesh, the
    // same solver; the minimum of 5 repetitions of each phase (the least disturbed by other work
    // on a shared machine).
    let mass_sizes: &[&str] =
        if quick { &["0.03125"] } else { &["0.015625", "0.004464285714285714"] };
    if want("mass") {
        md += "\nMass kinds on the beam (Q1, 2 ranks, 20 steps, minimum of 5 runs; ratios to consistent):\n\n| DOFs | mass | assembly s | setup s | ms/step | KSP its/step | assembly ratio | step ratio |\n|---|---|---|---|---|---|---|---|\n";
    }
    for &h in mass_sizes.iter().filter(|_| want("mass")) {
        let mut base: Option<(f64, f64)> = None;
        for mass in ["consistent", "lumped", "modified0", "modified1"] {
            let case = Case {
                scene: "beam.toml",
                h,
                steps: 20,
                ranks: 2,
                solver: cg_jacobi,
                label: "mass",
                mass,
            };
            eprintln!("bench: mass {mass} h = {h}");
            let mut rows = vec![];
            for _ in 0..5 {
                match run(&case) {
                    Ok(t) => rows.push(row(&case, &t)),
                    Err(e) => eprintln!("bench: {mass} failed: {e}"),
                }
            }
            if rows.is_empty() {
                md += &format!("| h={h} | {mass} | failed |\n");
                continue;
            }
            let med = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).fold(f64::INFINITY, f64::min);
            let (asm, setup, step, its) =
                (med(&|r| r.assembly), med(&|r| r.setup), med(&|r| r.per_step), med(&|r| r.its));
            let (ra, rs) = match base {
                None => {
                    base = Some((asm, step));
                    (1.0, 1.0)
                }
                Some((a0, s0)) => (asm / a0, step / s0),
            };
            md += &format!("| {:.0} | {mass} | {asm:.3} | {setup:.3} | {:.2} | {its:.1} | {ra:.2} | {rs:.2} |\n", rows[0].dofs, 1e3 * step);
            print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
        }
    }
    // The two-disc benchmark (paper 7.2, tau = 1e-6) for each mass kind on a finer contact
    // mesh than the tests' (hc = 0.025, h = 0.5): cost of contact steps against free-flight steps.
    if want("disc") {
        md += "\nTwo-disc impact (2 ranks, 1000 steps, tau = 1e-6, gap 0.05):\n\n| mesh | mass | DOFs | stepping s | ms/step | KSP its/step | active-set its mean / max | contact step / free step | share of time in contact steps | column solves |\n|---|---|---|---|---|---|---|---|---|---|\n";
        let (hc, h) = if quick { ("0.1", "1.0") } else { ("0.025", "0.5") };
        for (scene, mesh) in [("disc.toml", "quads"), ("disc_tri.toml", "triangles")] {
            for mass in ["consistent", "lumped", "modified0", "modified1"] {
                let out = bench_dir();
                let summary = out.join(format!("disc-{mesh}-{mass}.toml"));
                let o = Command::new("mpirun")
                    .args(["--oversubscribe", "-n", "2"])
                    .arg(repo().join("target/release/massfree"))
                    .arg("run")
                    .arg(repo().join("scenes").join(scene))
                    .args([
                        "--quiet",
                        "--no-output",
                        "--mass",
                        mass,
                        "--param",
                        &format!("hc={hc}"),
                    ])
                    .args(["--param", &format!("h={h}"), "--summary"])
                    .arg(&summary)
                    .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
                    .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
                    .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
                    .output();
                let t = match o {
                    Ok(o) if o.status.success() => read_summary(&summary).ok(),
                    _ => None,
                };
                let Some(t) = t else {
                    md += &format!("| {mesh} | {mass} | failed |\n");
                    continue;
                };
                let c = t.contact.as_ref().unwrap();
                let steps = t.steps as f64;
                let stepping = t.timings.stepping;
                let csteps = c.contact_steps as f64;
                let csec = c.contact_steps_seconds;
                let ratio = (csec / csteps) / ((stepping - csec) / (steps - csteps));
                md += &format!(
                    "| {mesh} | {mass} | {:.0} | {:.2} | {:.2} | {:.1} | {:.2} / {} | {:.2} | {:.0}% | {} |\n",
                    t.n_dofs as f64,
                    stepping,
                    1e3 * stepping / steps,
                    t.ksp_iterations as f64 / steps,
                    c.active_set_iterations_mean,
                    c.active_set_iterations_max,
                    ratio,
                    100.0 * csec / stepping,
                    c.extra_solves,
                );
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    // The 3D impact (issue 11): the ball of scenes/sphere.toml at three mesh levels on 1 and 2
    // ranks, each with contact and in free flight (the same ball 0.5 above the plane). Every
    // contact step is also measured against one plain solve of the same step
    // (-contact_reference_solve); its time is taken out of the contact run's figures.
    if want("contact3d") {
        md += "\n3D impact: ball on a plane (P1 tets, M_H^0, tau = 0.01; steps to t = 2.2, or 20 at the finest level):\n\n| DOFs | ranks | steps | step solver | max active | free ms/step | contact ms/step (contact steps) | contact / free step | contact run / free run | PDAS its mean / max | solves per contact step | KSP its per contact step | contact step / plain solve (KSP its, time) | peak MiB free / contact |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        let levels: &[(&str, &str, usize)] = if quick {
            &[("0.2", "0.04", 220)]
        } else {
            &[("0.1", "0.02", 220), ("0.05", "0.01", 220), ("0.027", "0.0055", 20)]
        };
        for &(h, hc, steps) in levels {
            for ranks in [1, 2] {
                let base = vec![
                    "--param".to_string(),
                    format!("h={h}"),
                    "--param".into(),
                    format!("hc={hc}"),
                    "--steps".into(),
                    steps.to_string(),
                ];
                let mut free_args = base.clone();
                free_args.extend(["--param".into(), "gap=0.5".into()]);
                let mut contact_args = base.clone();
                contact_args.extend(["--".into(), "-contact_reference_solve".into()]);
                let out = bench_dir();
                eprintln!("bench: sphere h = {h}, hc = {hc} on {ranks} rank(s)");
                let free =
                    run_scene(ranks, "sphere.toml", &free_args, &out.join("sphere-free.toml"));
                let hit = run_scene(
                    ranks,
                    "sphere.toml",
                    &contact_args,
                    &out.join("sphere-contact.toml"),
                );
                let (Some(f), Some(t)) = (free, hit) else {
                    md += &format!("| h = {h} | {ranks} | failed |\n");
                    continue;
                };
                let c = t.contact.as_ref().unwrap();
                let r = c.reference.unwrap_or_default();
                let n = t.steps as f64;
                let free_ms = 1e3 * f.timings.stepping / f.steps as f64;
                let contact_ms = 1e3 * (c.contact_steps_seconds - r.plain_seconds)
                    / c.contact_steps.max(1) as f64;
                let run_ms = 1e3 * (t.timings.stepping - r.plain_seconds_all_steps) / n;
                md += &format!(
                    "| {} | {ranks} | {} | {} + {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} / {} | {:.2} | {:.1} | {:.2}, {:.2} | {:.0} / {:.0} |\n",
                    t.n_dofs,
                    t.steps,
                    t.ksp_type,
                    t.pc_type,
                    c.max_active_nodes,
                    free_ms,
                    contact_ms,
                    contact_ms / free_ms,
                    run_ms / free_ms,
                    c.active_set_iterations_mean,
                    c.active_set_iterations_max,
                    1.0 + c.extra_solves as f64 / c.contact_steps.max(1) as f64,
                    c.ksp_iterations_contact_steps as f64 / c.contact_steps.max(1) as f64,
                    r.contact_ksp_iterations as f64 / r.plain_ksp_iterations.max(1) as f64,
                    r.contact_seconds / r.plain_seconds.max(1e-300),
                    f.peak_memory_mib,
                    t.peak_memory_mib,
                );
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    // Two-body contact (issue 12): the two discs of the paper as two bodies (dual mortar) at
    // the scene's resolution and on a finer contact mesh, and two balls in 3D at about 10^5
    // DOFs; per run the cost of a contact step against a free step, the PDAS iterations, and
    // the mortar interface's share (evaluations with the search, T^T K T rebuilds, the
    // per-step basis changes) of the stepping and of the contact steps.
    if want("two_body") {
        md += "\nTwo-body contact, dual mortar (2 ranks):\n\n| run | interface | DOFs | slave nodes | steps | ms/step | contact / free step | rounds per contact step | KSP its per contact step | evaluations | evaluation + search ms (search) | T^T K T rebuilds ms | consistent force ms | mortar share of stepping | mortar share of a contact step |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        let mut runs: Vec<(String, &str, Vec<String>)> = vec![];
        let discs: &[(&str, &str)] =
            if quick { &[("1.0", "0.1")] } else { &[("1.0", "0.1"), ("0.5", "0.025")] };
        for &(h, hc) in discs {
            for mass in ["consistent", "modified1"] {
                runs.push((
                    format!("two discs h = {h}, hc = {hc}, {mass}"),
                    "two_discs.toml",
                    ["--param", &format!("h={h}"), "--param", &format!("hc={hc}"), "--mass", mass]
                        .map(String::from)
                        .to_vec(),
                ));
            }
        }
        // The balls head-on and obliquely (sliding past each other by more than a contact
        // cell), at about 10^4 and 10^5 DOFs; the larger oblique run following the bodies is
        // cut after 20 steps (17 contact steps: its per-step figures, at about 25 s a step).
        let balls: &[(&str, &str)] =
            if quick { &[("0.2", "0.04")] } else { &[("0.2", "0.04"), ("0.07", "0.014")] };
        for &(h, hc) in balls {
            for scene in ["two_spheres.toml", "two_spheres_oblique.toml"] {
                let name =
                    if scene.contains("oblique") { "two balls oblique" } else { "two balls" };
                runs.push((
                    format!("{name} h = {h}, hc = {hc}, modified0"),
                    scene,
                    ["--param", &format!("h={h}"), "--param", &format!("hc={hc}")]
                        .map(String::from)
                        .to_vec(),
                ));
            }
        }
        for (label, scene, args) in runs {
            // The oblique balls also with the gap rows (`-mortar_gap_rows`, opt-in).
            let oblique = label.contains("oblique");
            let modes: &[&str] = if oblique {
                &["frozen", "follow", "follow + gap rows"]
            } else {
                &["frozen", "follow"]
            };
            for &mode in modes {
                let large = label.contains("h = 0.07");
                if large && mode != "frozen" && !oblique {
                    continue; // head-on at 10^5 DOFs: the frozen interface is valid there
                }
                let mut args = args.clone();
                if large && mode != "frozen" {
                    args.extend(["--steps", "20"].map(String::from));
                }
                let interface = if mode == "frozen" { "frozen" } else { "follow" };
                args.extend(["--", "-mortar_interface", interface].map(String::from));
                if mode.contains("rows") {
                    args.push("-mortar_gap_rows".into());
                }
                eprintln!("bench: {label}, {mode}");
                let summary = bench_dir().join("two-body.toml");
                let Some(t) = run_scene(2, scene, &args, &summary) else {
                    md += &format!("| {label} | {mode} | failed |\n");
                    continue;
                };
                let c = t.contact.as_ref().unwrap();
                let m = c.mortar.unwrap_or_default();
                let steps = t.steps as f64;
                let csteps = c.contact_steps.max(1) as f64;
                let csec = c.contact_steps_seconds;
                let free = (t.timings.stepping - csec) / (steps - csteps).max(1.0);
                let mortar =
                    m.evaluation_seconds + m.operator_seconds + m.step_seconds + m.gradient_seconds;
                // Frozen, a contact step pays the basis changes only; following, nearly all
                // of the mortar work is done in contact steps (the evaluations during the
                // approach are counted with them: an upper bound).
                let in_contact = match mode {
                    "frozen" => (m.step_seconds / steps) / (csec / csteps),
                    _ => mortar / csec,
                };
                let rounds = if m.following_steps > 0 {
                    format!(
                        "{:.2} ({:.2} solves)",
                        m.rounds as f64 / m.following_steps as f64,
                        m.following_solves as f64 / m.following_steps as f64
                    )
                } else {
                    format!("{:.2} (active set)", c.active_set_iterations_mean)
                };
                md += &format!(
                    "| {label} | {mode} | {} | {} | {} | {:.2} | {:.2} | {rounds} | {:.1} | {} | {:.1} ({:.1}) | {:.1} | {:.1} | {:.1}% | {:.1}% |\n",
                    t.n_dofs,
                    c.nodes,
                    t.steps,
                    1e3 * t.timings.stepping / steps,
                    (csec / csteps) / free,
                    c.ksp_iterations_contact_steps as f64 / csteps,
                    m.evaluations,
                    1e3 * m.evaluation_seconds,
                    1e3 * m.search_seconds,
                    1e3 * m.operator_seconds,
                    1e3 * m.gradient_seconds,
                    100.0 * mortar / t.timings.stepping,
                    100.0 * in_contact.min(1.0),
                );
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    // Friction (issue 25; README "Friction"): the disc and the ball hitting the plane
    // obliquely, with and without Coulomb friction, at about 10^4 DOFs in 2D and 2-6 x 10^4 in
    // 3D: per contact step the active-set iterations and the cost against a plain solve of the
    // step (`-contact_reference_solve`), and the chatter of the pressure and of the tangential
    // traction with each mass kind.
    if want("friction") {
        md += "\nFriction (2 ranks; per contact step: active-set iterations, KSP iterations and time against a plain solve of the same step):\n\n| run | mass | mu | DOFs | contact steps | active-set its | solves | KSP its / plain | time / plain | stick node-steps | slip node-steps | pressure osc2 (lowest) | total force TV | tangential osc2 (lowest) | tangential TV (total) | dissipation / E0 |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
        let mut runs: Vec<(String, &str, Vec<String>)> = vec![];
        let disc = if quick { ("0.5", "0.05") } else { ("0.25", "0.025") };
        for mass in ["consistent", "lumped", "modified0", "modified1"] {
            for mu in ["0", "0.3"] {
                runs.push((
                    format!("disc h = {}, hc = {}", disc.0, disc.1),
                    "disc_oblique.toml",
                    ["--param", &format!("h={}", disc.0), "--param", &format!("hc={}", disc.1)]
                        .map(String::from)
                        .to_vec(),
                ));
                let last = runs.last_mut().unwrap();
                last.2.extend(["--mass", mass, "--friction", mu].map(String::from));
            }
        }
        let balls: &[(&str, &str)] =
            if quick { &[("0.2", "0.04")] } else { &[("0.1", "0.02"), ("0.07", "0.014")] };
        for &(h, hc) in balls {
            for mass in ["consistent", "modified0"] {
                for mu in ["0", "0.3"] {
                    let mut args: Vec<String> =
                        ["--param", &format!("h={h}"), "--param", &format!("hc={hc}")]
                            .map(String::from)
                            .to_vec();
                    args.extend(["--mass", mass, "--friction", mu].map(String::from));
                    runs.push((format!("ball h = {h}, hc = {hc}"), "sphere_oblique.toml", args));
                }
            }
        }
        for (label, scene, mut args) in runs {
            let mass = args[args.iter().position(|a| a == "--mass").unwrap() + 1].clone();
            let mu = args[args.iter().position(|a| a == "--friction").unwrap() + 1].clone();
            args.extend(["--", "-contact_reference_solve"].map(String::from));
            eprintln!("bench: friction, {label}, {mass}, mu = {mu}");
            let summary = bench_dir().join("friction.toml");
            let Some(t) = run_scene(2, scene, &args, &summary) else {
                md += &format!("| {label} | {mass} | {mu} | failed |\n");
                continue;
            };
            let c = t.contact.as_ref().unwrap();
            let (its, secs) = match c.reference {
                Some(r) if r.steps > 0 && r.plain_ksp_iterations > 0 => (
                    r.contact_ksp_iterations as f64 / r.plain_ksp_iterations as f64,
                    r.contact_seconds / r.plain_seconds,
                ),
                _ => (f64::NAN, f64::NAN),
            };
            let csteps = c.contact_steps.max(1) as f64;
            md += &format!(
                "| {label} | {mass} | {mu} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {} | {} | {:.2e} | {:.2} | {:.2e} | {:.2} | {:.2e} |\n",
                t.n_dofs,
                c.contact_steps,
                c.active_set_iterations_mean,
                1.0 + c.extra_solves as f64 / csteps,
                its,
                secs,
                c.stick_node_steps,
                c.slip_node_steps,
                c.lowest_osc2,
                c.total_force_tv_index,
                c.lowest_tangential_osc2,
                c.total_tangential_tv_index,
                c.friction_dissipation / t.energy_initial.abs().max(f64::MIN_POSITIVE),
            );
            print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
        }
    }
    // Output cost: the beam at ~10^6 DOFs writing displacement and velocity every step
    // (parallel HDF5, each rank its block), against the same run without output.
    if want("output") {
        let h = if quick { "0.03125" } else { "0.004464285714285714" };
        md += "\nOutput cost (beam, displacement + velocity every step, 10 steps):\n\n| ranks | DOFs | ms/step without output | ms/step with output | output ms per written step | MB per step | MB/s | output / step |\n|---|---|---|---|---|---|---|---|\n";
        for ranks in [1, 2] {
            let out = bench_dir();
            let mut t = Vec::new();
            for write in [false, true] {
                let summary = out.join(format!("output-{ranks}-{write}.toml"));
                let h5 = out.join(format!("output-{ranks}.h5"));
                let mut cmd = massfree_run(ranks, &repo().join("scenes/beam.toml"));
                cmd.args([
                    "--quiet",
                    "--param",
                    &format!("h={h}"),
                    "--steps",
                    "10",
                    "--every",
                    "1",
                    "--summary",
                ])
                .arg(&summary);
                if write {
                    cmd.args(["--overwrite", "-o"]).arg(&h5);
                } else {
                    cmd.arg("--no-output");
                }
                let ok = cmd.output().map(|o| o.status.success()).unwrap_or(false);
                t.push(if ok { read_summary(&summary).ok() } else { None });
                let _ = std::fs::remove_file(&h5);
            }
            match (&t[0], &t[1]) {
                (Some(a), Some(b)) => {
                    let steps = b.steps as f64;
                    let dofs = b.n_dofs as f64;
                    let step_ms = 1e3 * a.timings.stepping / steps;
                    let step_w = 1e3 * b.timings.stepping / steps;
                    let out_ms = 1e3 * b.timings.output / (steps + 1.0);
                    let mb = 2.0 * dofs * 8.0 / 1e6;
                    md += &format!(
                        "| {ranks} | {dofs:.0} | {step_ms:.1} | {step_w:.1} | {out_ms:.1} | {mb:.1} | {:.0} | {:.0}% |\n",
                        mb / (out_ms / 1e3),
                        100.0 * out_ms / step_ms
                    );
                }
                _ => md += &format!("| {ranks} | failed |\n"),
            }
            print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
        }
    }
    if want("stress") {
        // The cost of the stress-type fields: the same 10 steps written every step with the
        // state only, with the five cell fields, and with the five nodal projections too.
        md += "\nStress output (2 ranks, 10 steps written every step; ms per written step):\n\n| case | DOFs | fields | ms/step (solve) | stress ms | output ms | stress + output / step |\n|---|---|---|---|---|---|---|\n";
        let cells = ["stress", "strain", "von_mises", "effective_stress", "pressure"];
        let nodal: Vec<String> = cells.iter().map(|c| format!("{c}_nodal")).collect();
        let cases = [
            ("beam (quads)", "beam.toml", if quick { "0.0625" } else { "0.01" }),
            ("block (hexahedra)", "block_hex.toml", if quick { "0.125" } else { "0.05" }),
        ];
        for (label, scene, h) in cases {
            let text = std::fs::read_to_string(repo().join("scenes").join(scene)).unwrap();
            let mut state = vec!["displacement".to_string(), "velocity".to_string()];
            let with_cells: Vec<String> =
                state.iter().cloned().chain(cells.iter().map(|c| c.to_string())).collect();
            let with_all: Vec<String> = with_cells.iter().cloned().chain(nodal.clone()).collect();
            for (what, fields) in [
                ("state", std::mem::take(&mut state)),
                ("+ 5 cell fields", with_cells),
                ("+ 5 nodal projections", with_all),
            ] {
                let list = fields.iter().map(|f| format!("\"{f}\"")).collect::<Vec<_>>();
                let variant = text.replacen(
                    "\nevery = 10",
                    &format!("\nevery = 1\nfields = [{}]", list.join(", ")),
                    1,
                );
                let dir = bench_dir();
                let path = dir.join(format!("stress-{scene}"));
                std::fs::write(
                    &path,
                    variant.replace("../meshes/", &format!("{}/meshes/", repo().display())),
                )
                .unwrap();
                let summary = dir.join("stress-summary.toml");
                let h5 = dir.join("stress.h5");
                let ok = massfree_run(2, &path)
                    .args([
                        "--quiet",
                        "--param",
                        &format!("h={h}"),
                        "--steps",
                        "10",
                        "--overwrite",
                        "-o",
                    ])
                    .arg(&h5)
                    .arg("--summary")
                    .arg(&summary)
                    .output()
                    .map(|o| o.status.success())
                    .unwrap_or(false);
                let _ = std::fs::remove_file(&h5);
                match ok.then(|| read_summary(&summary).ok()).flatten() {
                    Some(t) => {
                        let steps = t.steps as f64;
                        let step_ms = 1e3 * t.timings.stepping / steps;
                        let stress_ms = 1e3 * t.timings.stress / (steps + 1.0);
                        let out_ms = 1e3 * t.timings.output / (steps + 1.0);
                        md += &format!(
                            "| {label} | {} | {what} | {step_ms:.1} | {stress_ms:.1} | {out_ms:.1} | {:.0}% |\n",
                            t.n_dofs,
                            100.0 * (stress_ms + out_ms) / step_ms
                        );
                    }
                    None => md += &format!("| {label} | failed | {what} |\n"),
                }
                print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
            }
        }
    }
    if want("suite") {
        // The hard-case stability suite (issue 14; README "Hard cases: the stability suite"):
        // every case on 2 ranks, the marked ones also on 1, 3 and 4 (--quick: the reduced
        // suite). Its own tables go to target/bench/suite/; here its per-case table and time.
        let out = bench_dir().join("suite");
        let mut cmd = Command::new(repo().join("target/release/massfree"));
        cmd.arg("suite").arg(repo().join("studies/suite.toml")).arg("--dir").arg(&out);
        if quick {
            cmd.arg("--reduced");
        }
        let t0 = std::time::Instant::now();
        let ok = cmd
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
            .status()
            .map(|s| s.success())
            .unwrap_or(false);
        let seconds = t0.elapsed().as_secs_f64();
        md += &format!(
            "\n## Stability suite{}\n\n{} in {:.1} min (aim: under 30 min on 2 cores); tables in {}\n\n",
            if quick { " (reduced)" } else { "" },
            if ok { "finished" } else { "FAILED (a run failed or hit NaN/inf)" },
            seconds / 60.0,
            out.display()
        );
        if let Ok(text) = std::fs::read_to_string(out.join("suite.md")) {
            if let Some(table) = text.split("## Per case").nth(1) {
                md += table.split("## Every run").next().unwrap_or("").trim();
                md += "\n";
            }
        }
    }
    if want("setup") {
        md += &setup_section(quick);
    }
    // `--only step:3,4` runs parts of the step floor (1 beam, 2 block, 3 CFL table, 4 ball).
    let step_parts = only
        .as_deref()
        .and_then(|o| o.strip_prefix("step:"))
        .map(|p| p.split(',').filter_map(|x| x.trim().parse::<usize>().ok()).collect::<Vec<_>>());
    if want("step") || step_parts.is_some() {
        // --baseline BIN: the same cases with the build before issue 27, for the ratios.
        let baseline = args.iter().position(|a| a == "--baseline").and_then(|i| args.get(i + 1));
        let parts = step_parts.unwrap_or_else(|| vec![1, 2, 3, 4]);
        md += &step_floor::section(&repo(), &bench_dir(), quick, baseline.map(Path::new), &parts);
    }
    // `--only layer:contact` runs the layer's contact cases only (the disc and the ball),
    // `layer:beam` and `layer:block` the others.
    let layer_part = only.as_deref().and_then(|o| o.strip_prefix("layer:"));
    if want("layer") || layer_part.is_some() {
        md += &layer::section(&repo(), &bench_dir(), quick, layer_part);
    }
    if want("long") {
        md += &long_runs_section(quick);
    }
    if want("finite_strain") {
        md += &finite_strain::section(&repo(), &bench_dir(), quick);
    }
    if want("finite_contact") {
        md += &finite_strain::contact_section(&repo(), &bench_dir(), quick);
    }
    let path = bench_dir().join("scaling.md");
    std::fs::write(&path, &md).unwrap();
    println!("\n{md}\nwritten to {}", path.display());
}

/// Issue 26: the set-up phases (read, partition, migration, assembly, layer, solver set-up)
/// and the peak memory of the largest rank, for the mesh read by blocks (the default) and for
/// the replicated path (`--replicated-mesh --partition metis`: every rank reads the whole
/// mesh, as before), on the 3D block and on two contact scenes. One step each.
fn setup_section(quick: bool) -> String {
    let mut md = String::from(
        "\nSet-up phases (1 step, no output; seconds are the slowest rank's; assembly is A, M and the loads together, the stiffness A alone is its part (node graph included); rates are cells / (ranks x seconds); peak MiB of the largest rank):\n\n| case | path | ranks | DOFs | cells | read s | partition s | migration s | assembly s | stiffness s | stiffness cells/s/rank | layer s | solver set-up s | peak MiB/rank |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let blocks: &[(&str, &[usize])] =
        if quick { &[("0.1", &[1, 2, 4])] } else { &[("0.03", &[1, 2, 4]), ("0.02", &[2, 4])] };
    let mut runs: Vec<(String, &str, Vec<String>, usize)> = vec![];
    for &(h, ranks) in blocks {
        for &r in ranks {
            runs.push((
                format!("block P1 h = {h}"),
                "block_tet.toml",
                vec!["--param".into(), format!("h={h}")],
                r,
            ));
        }
    }
    for (label, scene) in [
        ("ball on plane (contact, M_H)", "sphere.toml"),
        ("two spheres (mortar)", "two_spheres.toml"),
    ] {
        for r in [1, 2, 4] {
            runs.push((label.to_string(), scene, vec![], r));
        }
    }
    for (label, scene, args, ranks) in runs {
        for (path, extra) in
            [("blocks", vec![]), ("replicated", vec!["--replicated-mesh", "--partition", "metis"])]
        {
            let mut a = args.clone();
            a.extend(["--steps", "1"].map(String::from));
            a.extend(extra.iter().map(|s| s.to_string()));
            eprintln!("bench: setup, {label}, {path}, {ranks} rank(s)");
            let summary = bench_dir().join("setup.toml");
            let Some(t) = run_scene(ranks, scene, &a, &summary) else {
                md += &format!("| {label} | {path} | {ranks} | failed |\n");
                continue;
            };
            let tm = &t.timings;
            let cells = t.n_cells.max(1) as f64;
            md += &format!(
                "| {label} | {path} | {ranks} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2e} | {:.3} | {:.2} | {:.0} |\n",
                t.n_dofs,
                t.n_cells,
                tm.mesh,
                tm.partition,
                tm.migration,
                tm.assembly,
                tm.stiffness,
                cells / (ranks as f64 * tm.stiffness.max(1e-9)),
                tm.layer,
                tm.setup,
                t.peak_memory_rank_mib
            );
        }
    }
    md
}

/// The long runs that left the test suite (tests/robustness.rs keeps 10000 and 12000 steps):
/// the coarse disc of the robustness tests (179 nodes) for 20000 steps with output every 1000,
/// on 2 and 3 ranks. Each must exit 0 with every step's energy row and `status = finished`;
/// the table gives the wall time and the pace, so a slowdown of the late steps (a file whose
/// metadata grows) shows as a higher ms/step than the short runs of the same scene.
fn long_runs_section(quick: bool) -> String {
    use massfree::io::layout::RunReader;
    let steps: usize = if quick { 2000 } else { 20000 };
    let mut md = format!(
        "\nLong runs (the coarse disc, h = 2.0, hc = 0.4, {steps} steps, output every 1000; wall time of the whole launch):\n\n| ranks | wall s | ms/step | energy rows | status |\n|---|---|---|---|---|\n"
    );
    for ranks in [2usize, 3] {
        let out = bench_dir().join(format!("long-{ranks}.h5"));
        let start = std::time::Instant::now();
        let o = Command::new("mpirun")
            .args(["-q", "--oversubscribe", "-n", &ranks.to_string()])
            .arg(repo().join("target/release/massfree"))
            .arg("run")
            .arg(repo().join("scenes/disc.toml"))
            .args(["--param", "h=2.0", "--param", "hc=0.4", "--quiet", "--overwrite"])
            .args(["--steps", &steps.to_string(), "--every", "1000", "-o"])
            .arg(&out)
            .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
            .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
            .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
            .output();
        let wall = start.elapsed().as_secs_f64();
        let (rows, status) = match (&o, RunReader::open(&out)) {
            (Ok(o), Ok(r)) if o.status.success() => {
                (r.series("energy/step").map(|v| v.len()).unwrap_or(0), r.text("status"))
            }
            (Ok(o), _) => (0, format!("FAILED: {}", String::from_utf8_lossy(&o.stderr).trim())),
            (Err(e), _) => (0, format!("FAILED: {e}")),
        };
        let ok = if rows == steps + 1 && status == "finished" { "" } else { " (NOT ALL)" };
        md += &format!(
            "| {ranks} | {wall:.1} | {:.2} | {rows}{ok} | {status} |\n",
            1e3 * wall / steps as f64
        );
        eprintln!("long run on {ranks} ranks: {wall:.1} s, {rows} rows, {status}");
    }
    md
}
