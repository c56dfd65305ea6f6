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
//! The model and amplitude axes (`sweep.model`, `sweep.amplitude`, `reference = { model }`)
//! are in [`models`], the plots in `plots`.
//! A failed point is a row marked failed with its one-line error; the sweep goes on.

pub mod fieldnorm;
pub mod models;
mod plots;
pub mod reference;
pub mod spec;
pub mod table;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use crate::error::{Error, Result};
use crate::report::RunSummary;
use crate::scene::{Field, Scene};
use plots::{part_plots, set_plots};
use spec::{Reference, Study, StudySet};
use table::{Columns, ContactColumns, Measured, Row};

/// Run the study described by the file.
pub fn run(path: &Path) -> Result<()> {
    let set = spec::load(path)?;
    let binary = std::env::current_exe()
        .map_err(|e| Error::Io(format!("study: cannot locate the massfree binary: {e}")))?;
    let rows = execute(&set, &binary)?;
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
    /// Material model (`sweep.model`) and amplitude (`sweep.amplitude`) of the point.
    model: Option<String>,
    amplitude: Option<f64>,
    group: usize,
    /// Index of the study's part (0 without parts).
    part: usize,
    label: String,
    id: String,
}

/// Whether the runs need HDF5 output (errors against a reference run).
fn needs_h5(study: &Study) -> bool {
    study.reference != Reference::Exact
}

/// Runs the whole sweep (every part) and writes the results; returns the rows.
fn execute(set: &StudySet, binary: &Path) -> Result<Vec<Row>> {
    let out = &set.output;
    let runs = out.join("runs");
    std::fs::create_dir_all(&runs)
        .map_err(|e| Error::Io(format!("cannot create {}: {e}", runs.display())))?;
    let _ = std::fs::copy(&set.file, out.join("study.toml"));
    // Every part's points, ids prefixed by the part in files with parts.
    let mut parts: Vec<(&Study, Vec<Point>)> = Vec::new();
    for (k, study) in set.parts.iter().enumerate() {
        let mut points = grid(study)?;
        for p in &mut points {
            p.part = k;
            p.group += k * GROUPS_PER_PART;
            if set.multi {
                p.id = format!("p{k}-{}", p.id);
            }
        }
        parts.push((study, points));
    }
    // The scene file of each point, or why the point cannot run (its one-line error).
    let mut scenes = Vec::new();
    for (study, points) in &parts {
        for p in points {
            let text = variant(study, p)
                .and_then(|s| s.variant_text())
                .and_then(|t| models::with_amplitude(study, p.amplitude, t));
            scenes.push(match text {
                Ok(text) => Ok(write_scene(&runs.join(format!("{}.scene.toml", p.id)), &text)?),
                Err(e) => Err(e.to_string()),
            });
        }
    }
    let all: Vec<(&Study, &Point)> =
        parts.iter().flat_map(|(s, ps)| ps.iter().map(move |p| (*s, p))).collect();
    let repeat = set.parts.iter().map(|s| s.repeat).max().unwrap_or(1);
    let total: usize = all.iter().map(|(s, _)| s.repeat).sum();
    for (study, points) in &parts {
        eprintln!(
            "study {}: {} points x {} repeat(s) of {} on {} rank(s); output {}",
            study.title,
            points.len(),
            study.repeat,
            study.scene_path.display(),
            study.ranks,
            out.display()
        );
    }
    let started = Instant::now();
    let mut done = 0usize;
    let mut rows: Vec<Row> = all
        .iter()
        .map(|(study, p)| Row {
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
            part: p.part,
            part_name: if set.multi { study.title.clone() } else { String::new() },
            model: p.model.clone().unwrap_or_default(),
            amplitude: p.amplitude,
            ..Default::default()
        })
        .collect();
    // Repeats go round the whole grid (not one point after the other), so that a passing
    // load on the machine spreads over the points instead of spoiling one point's median.
    let mut samples: Vec<Vec<Measured>> = vec![Vec::new(); all.len()];
    for k in 0..repeat {
        for (i, (study, p)) in all.iter().enumerate() {
            if rows[i].failure.is_some() || k >= study.repeat {
                continue;
            }
            let res = run_point(study, binary, p, &scenes[i], &runs);
            done += 1;
            let elapsed = started.elapsed().as_secs_f64();
            let eta = elapsed / done as f64 * (total - done) as f64;
            let name =
                if set.multi { format!("{}: {}", study.title, p.label) } else { p.label.clone() };
            let what = if study.repeat > 1 {
                format!("{name} (repeat {}/{})", k + 1, study.repeat)
            } else {
                name
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

    let mut offset = 0;
    for (study, points) in &parts {
        let n = points.len();
        compute_errors(study, points, &mut rows[offset..offset + n], &runs);
        offset += n;
    }
    let first = &set.parts[0];
    let mesh_param = if set.parts.iter().all(|s| s.mesh_param == first.mesh_param) {
        first.mesh_param.as_str()
    } else {
        "h"
    };
    let contact_ref = |s: &Study| s.has_contact() && s.reference != Reference::Exact;
    let columns = Columns {
        h_name: mesh_param,
        rate_h: set.parts.iter().any(|s| s.h.len() >= 2),
        rate_tau: set.parts.iter().any(|s| s.tau.len() >= 2),
        h1: set.parts.iter().all(|s| s.reference == Reference::Exact),
        contact: set.parts.iter().any(Study::has_contact),
        force: set.parts.iter().any(contact_ref),
        part: set.multi,
        model: set.parts.iter().any(|s| !s.model.is_empty()),
        amplitude: set.parts.iter().any(|s| !s.amplitude.is_empty()),
        against_model: set.parts.iter().any(|s| matches!(s.reference, Reference::Model(_))),
    };
    table::fill_rates(&mut rows, columns.rate_h, columns.rate_tau);
    table::fill_pareto(&mut rows);

    let csv = out.join("results.csv");
    write(&csv, &table::csv(&rows, &columns))?;
    let md = out.join("results.md");
    let table_md = table::markdown(&rows, &columns);
    let described = describe_set(set);
    write(&md, &format!("{described}\n\n{table_md}"))?;
    let mut files = vec![csv, md];
    let mut offset = 0;
    for (study, points) in &parts {
        let n = points.len();
        let prefix = if set.multi { format!("{}-", slug(&study.title)) } else { String::new() };
        match part_plots(study, &rows[offset..offset + n], &columns, &prefix, !set.multi) {
            Ok(p) => files.extend(p),
            Err(e) => eprintln!("study: warning: {e}"),
        }
        match models::plots(study, &rows[offset..offset + n], &prefix) {
            Ok(p) => files.extend(p),
            Err(e) => eprintln!("study: warning: {e}"),
        }
        offset += n;
    }
    if set.multi {
        match set_plots(set, &rows, &columns) {
            Ok(p) => files.extend(p),
            Err(e) => eprintln!("study: warning: {e}"),
        }
    }

    let n_ok = rows.iter().filter(|r| r.ok()).count();
    println!("{described}");
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

/// Group indices of part k start at k times this (a part has far fewer groups).
const GROUPS_PER_PART: usize = 1_000_000;

/// A file-name form of a part's name: "disc (2D)" -> "disc-2d".
pub(crate) fn slug(name: &str) -> String {
    let mut out = String::new();
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('-') && !out.is_empty() {
            out.push('-');
        }
    }
    out.trim_end_matches('-').to_string()
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

/// The heading and one paragraph per part on what was swept and what the errors are
/// measured against.
fn describe_set(set: &StudySet) -> String {
    if !set.multi {
        return describe(&set.parts[0]);
    }
    let mut out = format!("# Study {}: {} parts\n", set.title, set.parts.len());
    for s in &set.parts {
        out.push_str(&format!("\n{}", describe(s).replacen("# Study", "## Part", 1)));
        out.push('\n');
    }
    out.trim_end().to_string()
}

/// One line on what was swept and what the errors are measured against.
fn describe(study: &Study) -> String {
    let contact_errors = "error (err_l2) = relative L2 difference in time of the lowest contact node's \
        pressure history, err_force = the same of the total contact force, both piecewise linear in \
        time and integrated exactly on the union of the two runs' time grids,";
    let reference = match &study.reference {
        Reference::Exact => "errors against the exact solution (L2 and H1 seminorm, computed by the run)".to_string(),
        Reference::Finest if study.has_contact() => format!("{contact_errors} against the finest run of the same mass kind and solver (reference row)"),
        Reference::Finest => "error = relative nodal L2 difference of the displacement at the error time to the finest run of the same mass kind and solver (reference row)".to_string(),
        Reference::Mass(m) if study.has_contact() => format!("{contact_errors} against one reference for every row: the finest {m} run (smallest {}, then smallest tau; reference row)", study.mesh_param),
        Reference::Mass(m) => format!("error = relative nodal L2 difference of the displacement at the error time to the finest {m} run (smallest {}, then smallest tau; reference row)", study.mesh_param),
        Reference::File(f) if study.has_contact() => format!("{contact_errors} against {}", f.display()),
        Reference::File(f) => format!("error = relative nodal L2 difference of the displacement at the error time to {}", f.display()),
        Reference::Model(m) => models::describe(study, m, contact_errors),
    };
    let at = match study.end_time {
        Some(t) if study.has_contact() && study.reference != Reference::Exact => {
            format!("over (0, {t})")
        }
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
    let mut fixed: Vec<String> = study.params.iter().map(|(k, v)| format!("{k} = {v}")).collect();
    fixed.extend(study.scaled.iter().map(|(k, f)| format!("{k} = {f} {}", study.mesh_param)));
    let fixed = if fixed.is_empty() { String::new() } else { format!(" ({})", fixed.join(", ")) };
    format!(
        "# Study {}: scene {}{fixed} on {} rank(s), median of {} repeat(s)\n\n{reference}, {at}; run_s = \
         wall time inside the program (mesh + partition + assembly + setup + stepping + output), \
         process_s = the whole mpirun process; pareto * = not dominated in (run_s, err_l2) among the \
         rows of the same scene, errors within 0.1 % counting as equal.",
        study.title, study.scene.name, study.ranks, study.repeat
    )
}

/// The grid (solver, mass, model, amplitude, tau, h from the outside in).
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
    let models: Vec<Option<String>> = if study.model.is_empty() {
        vec![None]
    } else {
        study.model.iter().cloned().map(Some).collect()
    };
    let amplitudes = opt(&study.amplitude);
    // (model, amplitude) pairs: a group holds one of each (rows of a group differ only in h
    // and tau).
    let variants: Vec<(usize, usize)> =
        (0..models.len()).flat_map(|a| (0..amplitudes.len()).map(move |b| (a, b))).collect();
    let mut points = Vec::new();
    for (si, s) in solvers.iter().enumerate() {
        for (mi, m) in masses.iter().enumerate() {
            for (vi, &(oi, ai)) in variants.iter().enumerate() {
                let (model, amplitude) = (&models[oi], amplitudes[ai]);
                let group = (si * masses.len() + mi) * variants.len() + vi;
                for (ti, (tau, steps, error_step)) in times.iter().enumerate() {
                    for (hi, h) in opt(&study.h).into_iter().enumerate() {
                        if study.skip.iter().any(|k| k.matches(h, *tau, m.as_deref())) {
                            continue;
                        }
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
                        if let Some(o) = model {
                            label.push(format!("model={o}"));
                        }
                        if let Some(a) = amplitude {
                            label.push(format!("amplitude={a}"));
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
                            model: model.clone(),
                            amplitude,
                            group,
                            part: 0,
                            label: label.join(" "),
                            id: format!(
                                "s{si}-m{mi}-t{ti}-h{hi}{}{}",
                                if model.is_some() { format!("-M{oi}") } else { String::new() },
                                if amplitude.is_some() { format!("-a{ai}") } else { String::new() }
                            ),
                        });
                    }
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
        for (k, f) in &study.scaled {
            s.set_mesh_param(&format!("{k}={}", f * h))?;
        }
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
    if needs_h5(study) && study.has_contact() {
        // The errors need the contact tables (written every step) only: the fields once.
        s.output.every = p.steps.max(1);
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
    if let Some(m) = &p.model {
        cmd.arg("--model").arg(m);
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
    let s = RunSummary::parse(&text).map_err(|e| format!("summary {}: {e}", summary.display()))?;
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
        energy_loss: if s.energy_initial != 0.0 {
            (s.energy_initial - s.energy_final) / s.energy_initial
        } else {
            0.0
        },
        contact: s.contact.as_ref().map(|c| ContactColumns {
            lowest_osc2: c.lowest_osc2,
            lowest_tv_index: c.lowest_tv_index,
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

/// A run's errors against a reference run.
#[derive(Debug, Clone, Copy, Default)]
struct Errors {
    l2: f64,
    h1: Option<f64>,
    force: Option<f64>,
}

/// Fills err_l2 / err_h1 / err_force (and the reference flags) of one part's rows (`rows[i]`
/// belongs to `points[i]`).
fn compute_errors(study: &Study, points: &[Point], rows: &mut [Row], runs: &Path) {
    let h5 = |p: &Point| runs.join(format!("{}.h5", p.id));
    // Contact scenes: the lowest node's pressure and the total force over time; others:
    // relative L2 and H1-seminorm differences of the displacement, integrated with quadrature
    // over the reference's cells.
    let compare = |p: &Point, r: &Path| -> Result<Errors> {
        if study.has_contact() {
            let (run, refr) = (reference::read_contact(&h5(p))?, reference::read_contact(r)?);
            let (l2, force) = reference::contact_errors(&run, &refr)?;
            Ok(Errors { l2, h1: None, force: Some(force) })
        } else {
            let t = p.error_step as f64 * p.tau;
            let (run, refr) = (fieldnorm::read(&h5(p), t)?, fieldnorm::read(r, t)?);
            let (l2, h1) = fieldnorm::relative_errors(&run, &refr)?;
            Ok(Errors { l2, h1: Some(h1), force: None })
        }
    };
    let fill = |row: &mut Row, e: Result<Errors>| match e {
        Ok(e) => {
            row.err_l2 = Some(e.l2);
            row.err_h1 = e.h1;
            row.err_force = e.force;
        }
        Err(e) => row.failure = Some(format!("error against the reference: {e}")),
    };
    // The finest of the given points: smallest tau, then smallest h (`space_first`: smallest
    // h, then smallest tau).
    let finest = |members: &[usize], space_first: bool| -> Option<usize> {
        members.iter().copied().min_by(|&a, &b| {
            let (pa, pb) = (&points[a], &points[b]);
            let h = pa.h.unwrap_or(0.0).total_cmp(&pb.h.unwrap_or(0.0));
            let t = pa.tau.total_cmp(&pb.tau);
            if space_first {
                h.then(t)
            } else {
                t.then(h)
            }
        })
    };
    // Marks `f` as the reference of `members` and fills their errors against it.
    let against = |rows: &mut [Row], f: usize, members: &[usize]| {
        if !rows[f].ok() {
            for &i in members {
                if rows[i].ok() {
                    rows[i].failure =
                        Some(format!("no reference: the finest run ({}) failed", points[f].label));
                }
            }
            return;
        }
        rows[f].is_reference = true;
        rows[f].err_l2 = Some(0.0);
        if study.has_contact() {
            rows[f].err_force = Some(0.0);
        }
        let rpath = h5(&points[f]);
        for &i in members.iter().filter(|&&i| i != f) {
            if rows[i].ok() {
                fill(&mut rows[i], compare(&points[i], &rpath));
            }
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
                    fill(r, compare(p, file));
                }
            }
        }
        Reference::Mass(kind) => {
            let of_kind: Vec<usize> =
                (0..points.len()).filter(|&i| points[i].mass.as_deref() == Some(kind)).collect();
            let all: Vec<usize> = (0..points.len()).collect();
            if let Some(f) = finest(&of_kind, true) {
                against(rows, f, &all);
            }
        }
        Reference::Model(m) => models::compute_errors(study, m, points, rows, runs),
        Reference::Finest => {
            let groups: Vec<usize> = {
                let mut g: Vec<usize> = points.iter().map(|p| p.group).collect();
                g.dedup();
                g
            };
            for g in groups {
                let members: Vec<usize> =
                    (0..points.len()).filter(|&i| points[i].group == g).collect();
                if let Some(f) = finest(&members, false) {
                    against(rows, f, &members);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_leaves_out_skipped_points() {
        let file = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("studies/test.toml");
        let text = "scene = \"../scenes/beam.toml\"\nend_time = 1e-4\n[sweep]\n\
            h = [0.25, 0.125]\ntau = [1e-5, 5e-6]\nmass = [\"consistent\", \"lumped\"]\n\
            skip = [{ h = 0.125, tau = 1e-5 }, { mass = \"lumped\", tau = 5e-6 }]\n";
        let study = spec::parse(&file, text).unwrap();
        let labels: Vec<String> = grid(&study).unwrap().into_iter().map(|p| p.label).collect();
        // 2 x 2 x 2 points, less (1/8, 1e-5) of both kinds and lumped at 5e-6 (one of
        // them already gone).
        assert_eq!(
            labels,
            vec![
                "h=1/4 mass=consistent tau=1e-5",
                "h=1/4 mass=consistent tau=5e-6",
                "h=1/8 mass=consistent tau=5e-6",
                "h=1/4 mass=lumped tau=1e-5",
            ]
        );
        assert_eq!(slug("disc (2D)"), "disc-2d");
        assert_eq!(slug("Ball, 3D: hexes"), "ball-3d-hexes");
    }

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
        let run = RunSummary::example();
        // The text `massfree run --summary` writes, read back.
        let s = RunSummary::parse(&toml::to_string(&run).unwrap()).unwrap();
        let m = measured(&s, 30);
        assert_eq!(m.dofs, 1458);
        assert_eq!((m.ksp_type.as_str(), m.mass_kind.as_str()), ("cg", "consistent"));
        assert_eq!((m.peak_mib, m.energy_drift), (85.5, 1e-4));
        assert!((m.run_s - 0.66).abs() < 1e-12);
        assert_eq!(m.exact, Some((6.1e-6, 1.5e-4)));
        let c = m.contact.unwrap();
        assert_eq!((c.max_pressure, c.episodes_max), (2.5, 1));
        assert!(measured(&s, 31).exact.is_none());
        assert!(RunSummary::parse("n_dofs = 1").is_err());
    }
}
