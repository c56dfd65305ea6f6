//! `massfree study STUDY.toml`: sweeps of real runs mapping error against wall time.
//!
//! A study (schema in [`spec`]) sweeps the product of mesh sizes, mass kinds, time steps and
//! solver option lists over one scene. Every point is a real `mpirun -n RANKS massfree run`
//! process (the same code path as `./run`), repeated `repeat` times (the median time is
//! kept). Errors come from the run's summary (exact solution, computed by the solver) or from
//! the HDF5 files against a reference run (the finest run of each group, or a given file).
//! The output folder gets `results.csv`, `results.md`, `error_h.png` (error against h with
//! reference slopes), `error_tau.png` (error against tau) and `error_time.png` (error against
//! run time with the Pareto front), plus `runs/` (scene copies, summaries, HDF5 files).
//! Each point runs a variant of the scene: the study's overrides (mesh parameter, mass kind,
//! time step and steps, error step, output) are applied to the loaded [`Scene`] by its typed
//! methods and written by [`Scene::variant_text`].
//! A failed point is a row marked failed with its one-line error; the sweep goes on.

pub mod fieldnorm;
pub mod reference;
pub mod spec;
pub mod table;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::post::plot::{loglog_plot, Plot, Series};
use crate::scene::{Field, Scene};
use crate::simulation::RunSummary;
use spec::{Reference, Study};
use table::{Columns, ContactColumns, Measured, Row};

/// Run the study described by the file.
pub fn run(path: &Path) -> Result<()> {
    let study = spec::load(path)?;
    let binary = std::env::current_exe()
        .map_err(|e| Error::Io(format!("study: cannot locate the massfree binary: {e}")))?;
    let rows = execute(&study, &binary)?;
    let n_ok = rows.iter().filter(|r| r.ok()).count();
    if n_ok == 0 {
        return Err(Error::Solver(format!(
            "study {}: all {} runs failed (first: {})",
            path.display(),
            rows.len(),
            rows.first().and_then(|r| r.failure.clone()).unwrap_or_default()
        )));
    }
    Ok(())
}

/// One point of the grid.
#[derive(Debug, Clone)]
struct Point {
    h: Option<f64>,
    mass: Option<String>,
    tau: f64,
    steps: usize,
    /// The step whose errors are reported.
    error_step: usize,
    solver: Option<usize>,
    group: usize,
    label: String,
    id: String,
}

/// Whether the runs need HDF5 output (errors against a reference run).
fn needs_h5(study: &Study) -> bool {
    study.reference != Reference::Exact
}

/// Runs the whole sweep and writes the results; returns the rows.
fn execute(study: &Study, binary: &Path) -> Result<Vec<Row>> {
    let out = &study.output;
    let runs = out.join("runs");
    std::fs::create_dir_all(&runs)
        .map_err(|e| Error::Io(format!("cannot create {}: {e}", runs.display())))?;
    let _ = std::fs::copy(&study.file, out.join("study.toml"));
    let points = grid(study)?;
    // The scene file of each point, or why the point cannot run (its one-line error).
    let mut scenes = Vec::new();
    for p in &points {
        scenes.push(match variant(study, p).and_then(|s| s.variant_text()) {
            Ok(text) => Ok(write_scene(&runs.join(format!("{}.scene.toml", p.id)), &text)?),
            Err(e) => Err(e.to_string()),
        });
    }
    let total = points.len() * study.repeat;
    eprintln!(
        "study {}: {} points x {} repeat(s) = {} runs of {} on {} rank(s); output {}",
        study.title,
        points.len(),
        study.repeat,
        total,
        study.scene_path.display(),
        study.ranks,
        out.display()
    );
    let started = Instant::now();
    let mut done = 0usize;
    let mut rows: Vec<Row> = points
        .iter()
        .map(|p| Row {
            label: p.label.clone(),
            h: p.h.or(if study.h.is_empty() { study.h_default } else { None }),
            tau: p.tau,
            steps: p.steps,
            mass: p.mass.clone().unwrap_or_default(),
            solver: p
                .solver
                .map(|s| study.solver[s].label.clone())
                .unwrap_or_else(|| "scene".into()),
            ranks: study.ranks,
            group: p.group,
            ..Default::default()
        })
        .collect();
    // Repeats go round the whole grid (not one point after the other), so that a passing
    // load on the machine spreads over the points instead of spoiling one point's median.
    let mut samples: Vec<Vec<Measured>> = vec![Vec::new(); points.len()];
    for k in 0..study.repeat {
        for (i, p) in points.iter().enumerate() {
            if rows[i].failure.is_some() {
                continue;
            }
            let res = run_point(study, binary, p, &scenes[i], &runs);
            done += 1;
            let elapsed = started.elapsed().as_secs_f64();
            let eta = elapsed / done as f64 * (total - done) as f64;
            let what = if study.repeat > 1 {
                format!("{} (repeat {}/{})", p.label, k + 1, study.repeat)
            } else {
                p.label.clone()
            };
            match res {
                Ok(m) => {
                    eprintln!(
                        "study: [{done}/{total}] {what}: ok, {:.2} s ({} DOFs) | elapsed {}, ETA {}",
                        m.process_s,
                        m.dofs,
                        clock(elapsed),
                        clock(eta)
                    );
                    samples[i].push(m);
                }
                Err(e) => {
                    eprintln!(
                        "study: [{done}/{total}] {what}: FAILED: {e} | elapsed {}, ETA {}",
                        clock(elapsed),
                        clock(eta)
                    );
                    rows[i].failure = Some(e);
                    // The remaining repeats of a failed point are skipped.
                    done += study.repeat - 1 - k;
                }
            }
        }
    }
    for (row, s) in rows.iter_mut().zip(samples) {
        if row.failure.is_none() && !s.is_empty() {
            row.measured = Some(median(s));
        }
    }

    compute_errors(study, &points, &mut rows, &runs);
    let columns = Columns {
        h_name: &study.mesh_param,
        rate_h: study.h.len() >= 2,
        rate_tau: study.tau.len() >= 2,
        h1: study.reference == Reference::Exact,
        contact: study.has_contact(),
    };
    table::fill_rates(&mut rows, columns.rate_h, columns.rate_tau);
    table::fill_pareto(&mut rows);

    let csv = out.join("results.csv");
    write(&csv, &table::csv(&rows, &columns))?;
    let md = out.join("results.md");
    let table_md = table::markdown(&rows, &columns);
    write(&md, &format!("{}\n\n{}", describe(study), table_md))?;
    let mut files = vec![csv, md];
    match plots(study, &rows, &columns) {
        Ok(p) => files.extend(p),
        Err(e) => eprintln!("study: warning: {e}"),
    }

    let n_ok = rows.iter().filter(|r| r.ok()).count();
    println!("{}", describe(study));
    println!();
    print!("{table_md}");
    println!();
    println!(
        "{n_ok} of {} points ok, {} failed; {} runs in {}",
        rows.len(),
        rows.len() - n_ok,
        total,
        clock(started.elapsed().as_secs_f64())
    );
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(rows)
}

pub(crate) fn clock(s: f64) -> String {
    if s < 60.0 {
        format!("{s:.0} s")
    } else {
        format!("{}:{:02} min", (s / 60.0).floor() as u64, (s % 60.0).round() as u64 % 60)
    }
}

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text)
        .map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

/// One line on what was swept and what the errors are measured against.
fn describe(study: &Study) -> String {
    let reference = match &study.reference {
        Reference::Exact => "errors against the exact solution (L2 and H1 seminorm, computed by the run)".to_string(),
        Reference::Finest if study.has_contact() => "error = relative L2 difference over time of the lowest contact node's pressure to the finest run of the same mass kind and solver (reference row)".to_string(),
        Reference::Finest => "error = relative nodal L2 difference of the displacement at the error time to the finest run of the same mass kind and solver (reference row)".to_string(),
        Reference::File(f) if study.has_contact() => format!("error = relative L2 difference over time of the lowest contact node's pressure to {}", f.display()),
        Reference::File(f) => format!("error = relative nodal L2 difference of the displacement at the error time to {}", f.display()),
    };
    let at = match study.end_time {
        _ if study.has_contact() && study.reference != Reference::Exact => {
            format!("over all {} steps", study.steps.unwrap_or(study.scene.steps))
        }
        Some(t) => format!("at the end time t = {t}"),
        None => {
            let steps = study.steps.unwrap_or(study.scene.steps);
            let s = study.error_step.unwrap_or(steps);
            format!("at step {s} of {steps}")
        }
    };
    format!(
        "# Study {}: scene {} on {} rank(s), median of {} repeat(s)\n\n{reference}, {at}; run_s = \
         wall time inside the program (mesh + partition + assembly + setup + stepping + output), \
         process_s = the whole mpirun process; pareto * = not dominated in (run_s, err_l2), errors within 0.1 % counting as equal.",
        study.title, study.scene.name, study.ranks, study.repeat
    )
}

/// The grid (solver, mass, tau, h from the outside in).
fn grid(study: &Study) -> Result<Vec<Point>> {
    let opt = |v: &[f64]| -> Vec<Option<f64>> {
        if v.is_empty() {
            vec![None]
        } else {
            v.iter().copied().map(Some).collect()
        }
    };
    let masses: Vec<Option<String>> = if study.mass.is_empty() {
        vec![None]
    } else {
        study.mass.iter().cloned().map(Some).collect()
    };
    let solvers: Vec<Option<usize>> = if study.solver.is_empty() {
        vec![None]
    } else {
        (0..study.solver.len()).map(Some).collect()
    };
    // (tau, steps, error step) of each time step.
    let mut times = Vec::new();
    for tau in opt(&study.tau) {
        times.push(match (tau, study.end_time) {
            (Some(t), Some(end)) => {
                let n = spec::steps_for(end, t).map_err(Error::Usage)?;
                (t, n, n)
            }
            _ => {
                let n = study.steps.unwrap_or(study.scene.steps);
                (study.scene.tau, n, study.error_step.unwrap_or(n))
            }
        });
    }
    let mut points = Vec::new();
    for (si, s) in solvers.iter().enumerate() {
        for (mi, m) in masses.iter().enumerate() {
            let group = si * masses.len() + mi;
            for (ti, (tau, steps, error_step)) in times.iter().enumerate() {
                for (hi, h) in opt(&study.h).into_iter().enumerate() {
                    let mut label = Vec::new();
                    if let Some(h) = h {
                        label.push(format!("{}={}", study.mesh_param, table::show_h(h)));
                    }
                    if let Some(m) = m {
                        label.push(format!("mass={m}"));
                    }
                    if !study.tau.is_empty() {
                        label.push(format!("tau={}", table::show_tau(*tau)));
                    }
                    if let Some(s) = s {
                        label.push(format!("solver={}", study.solver[*s].label));
                    }
                    if label.is_empty() {
                        label.push("scene".into());
                    }
                    points.push(Point {
                        h,
                        mass: m.clone(),
                        tau: *tau,
                        steps: *steps,
                        error_step: *error_step,
                        solver: *s,
                        group,
                        label: label.join(" "),
                        id: format!("s{si}-m{mi}-t{ti}-h{hi}"),
                    });
                }
            }
        }
    }
    Ok(points)
}

/// The point's scene: the study's scene with the point's mesh parameter, fixed parameters,
/// mass kind, time step (steps to the end time) or steps, its error step among the exact
/// errors, and, for errors against a reference run, the displacement written at the error step.
fn variant(study: &Study, p: &Point) -> Result<Scene> {
    let mut s = study.scene.clone();
    if let Some(h) = p.h {
        s.set_mesh_param(&format!("{}={h}", study.mesh_param))?;
    }
    for (k, v) in &study.params {
        s.set_mesh_param(&format!("{k}={v}"))?;
    }
    if let Some(m) = &p.mass {
        s.set_mass_kind(m)?;
    }
    match (study.end_time, study.steps) {
        (Some(end), _) => s.set_tau(p.tau, end)?,
        (None, Some(n)) => s.set_steps(n)?,
        (None, None) => {}
    }
    s.add_error_step(p.error_step)?;
    if needs_h5(study) && !study.has_contact() {
        s.output.every = p.error_step.max(1);
        s.output.fields = vec![Field::Displacement];
    }
    Ok(s)
}

/// Writes a point's scene file; returns its absolute path.
fn write_scene(path: &Path, text: &str) -> Result<PathBuf> {
    write(path, text)?;
    path.canonicalize().map_err(|e| Error::Io(format!("cannot resolve {}: {e}", path.display())))
}

/// The launcher: `MASSFREE_MPIRUN` (e.g. "srun") or `mpirun --oversubscribe`, then `-n RANKS`.
pub(crate) fn launcher(ranks: usize) -> Command {
    let custom = std::env::var("MASSFREE_MPIRUN").ok().filter(|s| !s.trim().is_empty());
    let words: Vec<String> = match custom {
        Some(s) => s.split_whitespace().map(str::to_string).collect(),
        None => vec!["mpirun".into(), "--oversubscribe".into()],
    };
    let mut cmd = Command::new(&words[0]);
    cmd.args(&words[1..]).arg("-n").arg(ranks.to_string());
    // What ./run sets for Open MPI (root in containers, no CMA), unless already set.
    for (k, v) in [
        ("OMPI_ALLOW_RUN_AS_ROOT", "1"),
        ("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"),
        ("OMPI_MCA_btl_vader_single_copy_mechanism", "none"),
    ] {
        if std::env::var_os(k).is_none() {
            cmd.env(k, v);
        }
    }
    // The study process itself may be an MPI singleton: its MPI environment must not leak
    // into the launcher of the runs.
    for (k, _) in std::env::vars_os() {
        let k = k.to_string_lossy();
        if k.starts_with("PMIX_")
            || k.starts_with("OMPI_COMM_WORLD")
            || k.starts_with("OMPI_MCA_orte_")
            || k.starts_with("OMPI_MCA_ess")
            || k.starts_with("OMPI_MCA_pmix")
            || k.starts_with("OMPI_FILE_LOCATION")
            || k.starts_with("OMPI_UNIVERSE_SIZE")
        {
            cmd.env_remove(k.as_ref());
        }
    }
    cmd
}

/// One run of a point; the error is the run's one-line message.
fn run_point(
    study: &Study,
    binary: &Path,
    p: &Point,
    scene: &std::result::Result<PathBuf, String>,
    runs: &Path,
) -> std::result::Result<Measured, String> {
    let scene = scene.as_ref().map_err(String::clone)?;
    let summary = runs.join(format!("{}.summary.toml", p.id));
    let _ = std::fs::remove_file(&summary);
    let mut cmd = launcher(study.ranks);
    cmd.arg(binary).arg("run").arg(scene).arg("-q");
    cmd.arg("--summary").arg(&summary);
    if needs_h5(study) {
        cmd.arg("-o").arg(runs.join(format!("{}.h5", p.id))).arg("--overwrite");
    } else {
        cmd.arg("--no-output");
    }
    if let Some(s) = p.solver {
        cmd.arg("--").args(&study.solver[s].options);
    }
    cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let t0 = Instant::now();
    let output = cmd.output().map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    let process_s = t0.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&output.stderr);
    let _ = std::fs::write(
        runs.join(format!("{}.log", p.id)),
        [&output.stdout[..], &output.stderr[..]].concat(),
    );
    if !output.status.success() {
        return Err(last_error_line(&stderr, output.status.code()));
    }
    let text = std::fs::read_to_string(&summary)
        .map_err(|e| format!("the run wrote no summary {}: {e}", summary.display()))?;
    let s = parse_summary(&text).map_err(|e| format!("summary {}: {e}", summary.display()))?;
    let mut m = measured(&s, p.error_step);
    m.process_s = process_s;
    Ok(m)
}

/// The run's own error line (`massfree: ...`), else the last line that is not mpirun's frame.
pub(crate) fn last_error_line(stderr: &str, code: Option<i32>) -> String {
    let lines: Vec<&str> = stderr.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    if let Some(l) = lines.iter().rev().find(|l| l.starts_with("massfree:")) {
        return l.trim_start_matches("massfree:").trim().to_string();
    }
    if let Some(l) = lines.iter().rev().find(|l| !l.chars().all(|c| c == '-')) {
        return l.to_string();
    }
    match code {
        Some(c) => format!("the run exited with code {c}"),
        None => "the run was killed by a signal".into(),
    }
}

/// A run's summary as `massfree run --summary` writes it.
pub(crate) fn parse_summary(text: &str) -> std::result::Result<RunSummary, String> {
    toml::from_str(text).map_err(|e: toml::de::Error| e.message().to_string())
}

/// The table's columns of a run; its errors against the exact solution at `error_step`.
fn measured(s: &RunSummary, error_step: usize) -> Measured {
    let t = &s.timings;
    Measured {
        dofs: s.n_dofs,
        ksp_iterations: s.ksp_iterations,
        ksp_type: s.ksp_type.clone(),
        pc_type: s.pc_type.clone(),
        mass_kind: s.mass_kind.clone(),
        mesh_s: t.mesh,
        partition_s: t.partition,
        assembly_s: t.assembly,
        setup_s: t.setup,
        stepping_s: t.stepping,
        output_s: t.output,
        run_s: t.mesh + t.partition + t.assembly + t.setup + t.stepping + t.output,
        peak_mib: s.peak_memory_mib,
        energy_drift: s.energy_drift,
        contact: s.contact.as_ref().map(|c| ContactColumns {
            lowest_osc2: c.lowest_osc2,
            total_force_tv_index: c.total_force_tv_index,
            max_pressure: c.max_pressure,
            episodes_max: c.episodes_max,
        }),
        exact: s.errors.iter().rev().find(|e| e.step == error_step).map(|e| (e.l2, e.h1_semi)),
        ..Default::default()
    }
}

/// The repeat with the median run time (its phases stay consistent), with the median
/// process time.
fn median(mut samples: Vec<Measured>) -> Measured {
    let mid = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let mut process: Vec<f64> = samples.iter().map(|m| m.process_s).collect();
    let process = mid(&mut process);
    samples.sort_by(|a, b| a.run_s.total_cmp(&b.run_s));
    let k = samples.len() / 2;
    let mut m = samples.swap_remove(k);
    m.process_s = process;
    m
}

/// Fills err_l2 / err_h1 (and the reference flags) of the rows.
fn compute_errors(study: &Study, points: &[Point], rows: &mut [Row], runs: &Path) {
    let h5 = |p: &Point| runs.join(format!("{}.h5", p.id));
    // Contact scenes: the lowest node's pressure history; others: relative L2 and H1-seminorm
    // differences of the displacement, integrated with quadrature over the reference's cells.
    let compare = |p: &Point, r: &Path| -> Result<(f64, Option<f64>)> {
        if study.has_contact() {
            reference::pressure_error(&h5(p), r).map(|e| (e, None))
        } else {
            let t = p.error_step as f64 * p.tau;
            let (run, refr) = (fieldnorm::read(&h5(p), t)?, fieldnorm::read(r, t)?);
            fieldnorm::relative_errors(&run, &refr).map(|(l2, h1)| (l2, Some(h1)))
        }
    };
    match &study.reference {
        Reference::Exact => {
            for (r, p) in rows.iter_mut().zip(points) {
                if let Some(m) = &r.measured {
                    match m.exact {
                        Some((l2, h1)) => {
                            r.err_l2 = Some(l2);
                            r.err_h1 = Some(h1);
                        }
                        None => {
                            r.failure =
                                Some(format!("the run reported no error at step {}", p.error_step))
                        }
                    }
                }
            }
        }
        Reference::File(file) => {
            for (r, p) in rows.iter_mut().zip(points) {
                if r.ok() {
                    match compare(p, file) {
                        Ok((l2, h1)) => {
                            r.err_l2 = Some(l2);
                            r.err_h1 = h1;
                        }
                        Err(e) => r.failure = Some(format!("error against the reference: {e}")),
                    }
                }
            }
        }
        Reference::Finest => {
            let groups: Vec<usize> = {
                let mut g: Vec<usize> = points.iter().map(|p| p.group).collect();
                g.dedup();
                g
            };
            for g in groups {
                let members: Vec<usize> =
                    (0..points.len()).filter(|&i| points[i].group == g).collect();
                // The finest point: smallest tau, then smallest h.
                let finest = members.iter().copied().min_by(|&a, &b| {
                    let (pa, pb) = (&points[a], &points[b]);
                    pa.tau
                        .total_cmp(&pb.tau)
                        .then(pa.h.unwrap_or(0.0).total_cmp(&pb.h.unwrap_or(0.0)))
                });
                let Some(f) = finest else { continue };
                if !rows[f].ok() {
                    for &i in &members {
                        if rows[i].ok() {
                            rows[i].failure = Some(format!(
                                "no reference: the finest run ({}) failed",
                                points[f].label
                            ));
                        }
                    }
                    continue;
                }
                rows[f].is_reference = true;
                rows[f].err_l2 = Some(0.0);
                let rpath = h5(&points[f]);
                for &i in members.iter().filter(|&&i| i != f) {
                    if rows[i].ok() {
                        match compare(&points[i], &rpath) {
                            Ok((l2, h1)) => {
                                rows[i].err_l2 = Some(l2);
                                rows[i].err_h1 = h1;
                            }
                            Err(e) => {
                                rows[i].failure = Some(format!("error against the reference: {e}"))
                            }
                        }
                    }
                }
            }
        }
    }
}

/// A legend name for a group of rows (what differs between groups).
fn group_name(study: &Study, r: &Row) -> String {
    let mut parts = Vec::new();
    if study.mass.len() > 1 || study.solver.len() <= 1 {
        parts.push(if r.mass.is_empty() {
            r.measured.as_ref().map(|m| m.mass_kind.clone()).unwrap_or_default()
        } else {
            r.mass.clone()
        });
    }
    if study.solver.len() > 1 {
        parts.push(r.solver.clone());
    }
    parts.retain(|p| !p.is_empty());
    if parts.is_empty() {
        study.scene.name.clone()
    } else {
        parts.join(", ")
    }
}

/// Series of (x, error) per group (and per tau or h when both are swept).
fn series(
    study: &Study,
    rows: &[Row],
    x: &dyn Fn(&Row) -> f64,
    err: &dyn Fn(&Row) -> Option<f64>,
    split: &dyn Fn(&Row) -> String,
    prefix: &str,
    sort: bool,
) -> Vec<Series> {
    let mut out: Vec<Series> = Vec::new();
    for r in rows.iter().filter(|r| r.ok() && !r.is_reference) {
        let Some(e) = err(r) else { continue };
        let s = split(r);
        let name = format!(
            "{prefix}{}{}",
            group_name(study, r),
            if s.is_empty() { s } else { format!(", {s}") }
        );
        let pt = (x(r), e);
        match out.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push(pt),
            None => out.push(Series { name, points: vec![pt] }),
        }
    }
    if sort {
        for s in &mut out {
            s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
    }
    out
}

fn plots(study: &Study, rows: &[Row], c: &Columns) -> Result<Vec<PathBuf>> {
    let out = &study.output;
    let mut files = Vec::new();
    let err_name = match study.reference {
        Reference::Exact => "error",
        _ if study.has_contact() => "pressure error (relative)",
        _ => "error (relative, vs reference)",
    };
    let l2 = |r: &Row| r.err_l2;
    let h1 = |r: &Row| r.err_h1;
    let hx = |r: &Row| r.h.unwrap_or(f64::NAN);
    let tx = |r: &Row| r.tau;
    let by_tau = |r: &Row| {
        if study.tau.len() > 1 {
            format!("tau={}", table::show_tau(r.tau))
        } else {
            String::new()
        }
    };
    let by_h = |r: &Row| match r.h {
        Some(h) if study.h.len() > 1 => format!("{}={}", study.mesh_param, table::show_h(h)),
        _ => String::new(),
    };
    let (l2p, h1p) = if c.h1 { ("L2 ", "H1 ") } else { ("", "") };
    if study.h.len() >= 2 {
        let mut s = series(study, rows, &hx, &l2, &by_tau, l2p, true);
        if c.h1 {
            s.extend(series(study, rows, &hx, &h1, &by_tau, h1p, true));
        }
        let path = out.join("error_h.png");
        let xl = study.mesh_param.clone();
        let title = format!("{}: {err_name} against {}", study.title, study.mesh_param);
        let plot = Plot {
            title: &title,
            x_label: &xl,
            y_label: err_name,
            series: &s,
            width: 900,
            height: 650,
        };
        loglog_plot(&path, &plot, &[1.0, 2.0])?;
        files.push(path);
    }
    if study.tau.len() >= 2 {
        let mut s = series(study, rows, &tx, &l2, &by_h, l2p, true);
        if c.h1 {
            s.extend(series(study, rows, &tx, &h1, &by_h, h1p, true));
        }
        let path = out.join("error_tau.png");
        let title = format!("{}: {err_name} against tau", study.title);
        let plot = Plot {
            title: &title,
            x_label: "tau",
            y_label: err_name,
            series: &s,
            width: 900,
            height: 650,
        };
        loglog_plot(&path, &plot, &[2.0])?;
        files.push(path);
    }
    // Error against run time, with the Pareto front.
    let time = |r: &Row| r.measured.as_ref().map(|m| m.run_s).unwrap_or(f64::NAN);
    // One curve per group along its refinements (per tau when both h and tau are swept).
    let by_tau_if_grid = |r: &Row| if study.h.len() > 1 { by_tau(r) } else { String::new() };
    let mut s = series(study, rows, &time, &l2, &by_tau_if_grid, "", false);
    let mut front: Vec<(f64, f64)> =
        rows.iter().filter(|r| r.pareto).filter_map(|r| Some((time(r), r.err_l2?))).collect();
    front.sort_by(|a, b| a.0.total_cmp(&b.0));
    if !front.is_empty() {
        s.push(Series { name: "Pareto front".into(), points: front });
    }
    let path = out.join("error_time.png");
    let title =
        format!("{}: {} against run time", study.title, if c.h1 { "L2 error" } else { err_name });
    let yl = if c.h1 { "L2 error" } else { err_name };
    let plot = Plot {
        title: &title,
        x_label: "run time inside the program (s, median)",
        y_label: yl,
        series: &s,
        width: 900,
        height: 650,
    };
    loglog_plot(&path, &plot, &[])?;
    files.push(path);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_line_of_a_failed_run() {
        let stderr = "massfree: PETSc error 86 in KSPSetFromOptions: Unable to find requested KSP type nonsense\n\
            --------------------------------------------------------------------------\n\
            Primary job  terminated normally, but 1 process returned\n\
            --------------------------------------------------------------------------\n";
        assert_eq!(
            last_error_line(stderr, Some(1)),
            "PETSc error 86 in KSPSetFromOptions: Unable to find requested KSP type nonsense"
        );
        assert_eq!(last_error_line("\n-----\n", Some(3)), "the run exited with code 3");
        assert_eq!(last_error_line("oops\n----\n", Some(3)), "oops");
    }

    #[test]
    fn summary_columns() {
        use crate::contact::history::ContactSummary;
        use crate::simulation::{ErrorSample, MassCheck, Timings};
        let run = RunSummary {
            n_nodes: 729,
            n_dofs: 1458,
            steps: 30,
            timings: Timings {
                mesh: 0.1,
                partition: 0.01,
                assembly: 0.02,
                setup: 0.03,
                stepping: 0.5,
                output: 0.0,
                stress: 0.0,
            },
            ksp_iterations: 124,
            energy_initial: 1.0,
            energy_final: 1.0,
            external_work: 0.0,
            energy_balance: 1e-12,
            energy_drift: 1e-4,
            errors: vec![ErrorSample { step: 30, time: 3e-4, l2: 6.1e-6, h1_semi: 1.5e-4 }],
            output: None,
            matmult_seconds: 1e-4,
            peak_memory_mib: 85.5,
            ranks: 2,
            ksp_type: "cg".into(),
            pc_type: "jacobi".into(),
            mass_kind: "consistent".into(),
            layer_contact_nodes: 0,
            layer_cells: 0,
            mass: MassCheck::default(),
            momentum_initial: vec![0.0, 0.0],
            momentum_final: vec![0.0, 0.0],
            contact: Some(ContactSummary {
                max_pressure: 2.5,
                episodes_max: 1,
                ..Default::default()
            }),
            pictures: vec![],
            effects: String::new(),
            bodies: Vec::new(),
            energy_max: 0.0,
            massless_initialization: None,
            release_projections: 0,
            release_energy: 0.0,
            energy_corrections: Default::default(),
            ksp_iterations_step_max: 7,
            cfl: 0.5,
            stability: None,
        };
        // The text `massfree run --summary` writes, read back.
        let s = parse_summary(&toml::to_string(&run).unwrap()).unwrap();
        let m = measured(&s, 30);
        assert_eq!(m.dofs, 1458);
        assert_eq!((m.ksp_type.as_str(), m.mass_kind.as_str()), ("cg", "consistent"));
        assert_eq!((m.peak_mib, m.energy_drift), (85.5, 1e-4));
        assert!((m.run_s - 0.66).abs() < 1e-12);
        assert_eq!(m.exact, Some((6.1e-6, 1.5e-4)));
        let c = m.contact.unwrap();
        assert_eq!((c.max_pressure, c.episodes_max), (2.5, 1));
        assert!(measured(&s, 31).exact.is_none());
        assert!(parse_summary("n_dofs = 1").is_err());
    }
}
