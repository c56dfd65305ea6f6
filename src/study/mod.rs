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
//! A failed point is a row marked failed with its one-line error; the sweep goes on.

pub mod fieldnorm;
pub mod reference;
pub mod spec;
pub mod table;

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use toml::{Table, Value};

use crate::error::{Error, Result};
use crate::post::plot::{loglog_plot, Plot, Series};
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
    scene: PathBuf,
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
    let points = grid(study, &runs)?;
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
            h: p.h.or(if study.h.is_empty() { study.scene.h_default } else { None }),
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
            let res = run_point(study, binary, p, &runs);
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
        contact: study.scene.has_contact,
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

fn clock(s: f64) -> String {
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
        Reference::Finest if study.scene.has_contact => "error = relative L2 difference over time of the lowest contact node's pressure to the finest run of the same mass kind and solver (reference row)".to_string(),
        Reference::Finest => "error = relative nodal L2 difference of the displacement at the error time to the finest run of the same mass kind and solver (reference row)".to_string(),
        Reference::File(f) if study.scene.has_contact => format!("error = relative L2 difference over time of the lowest contact node's pressure to {}", f.display()),
        Reference::File(f) => format!("error = relative nodal L2 difference of the displacement at the error time to {}", f.display()),
    };
    let at = match study.end_time {
        _ if study.scene.has_contact && study.reference != Reference::Exact => {
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

/// The grid (solver, mass, tau, h from the outside in) and the scene copies it runs on.
fn grid(study: &Study, runs: &Path) -> Result<Vec<Point>> {
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
    // One scene copy per time step.
    let mut scenes = Vec::new();
    for (i, tau) in opt(&study.tau).into_iter().enumerate() {
        let (tau, steps, error_step) = match (tau, study.end_time) {
            (Some(t), Some(end)) => {
                let n = spec::steps_for(end, t).map_err(Error::Usage)?;
                (t, n, n)
            }
            _ => {
                let n = study.steps.unwrap_or(study.scene.steps);
                (study.scene.tau, n, study.error_step.unwrap_or(n))
            }
        };
        let name =
            if study.tau.is_empty() { "scene.toml".into() } else { format!("scene-tau{i}.toml") };
        let path = runs.join(name);
        let text = scene_copy(study, tau, steps, error_step)?;
        write(&path, &text)?;
        let path = path
            .canonicalize()
            .map_err(|e| Error::Io(format!("cannot resolve {}: {e}", path.display())))?;
        scenes.push((tau, steps, error_step, path));
    }
    let mut points = Vec::new();
    for (si, s) in solvers.iter().enumerate() {
        for (mi, m) in masses.iter().enumerate() {
            let group = si * masses.len() + mi;
            for (ti, (tau, steps, error_step, scene)) in scenes.iter().enumerate() {
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
                        scene: scene.clone(),
                        label: label.join(" "),
                        id: format!("s{si}-m{mi}-t{ti}-h{hi}"),
                    });
                }
            }
        }
    }
    Ok(points)
}

/// The scene with absolute mesh paths, the time step and number of steps of the point, the
/// error step among the exact errors, and fields written at the error step.
fn scene_copy(study: &Study, tau: f64, steps: usize, error_step: usize) -> Result<String> {
    let mut t = study.scene.table.clone();
    let bad = |m: &str| Error::Scene(format!("{}: {m}", study.scene_path.display()));
    if let Some(Value::Table(mesh)) = t.get_mut("mesh") {
        for key in ["geo", "msh"] {
            if let Some(Value::String(p)) = mesh.get_mut(key) {
                let abs = study.scene.dir.join(&*p);
                *p = abs.to_string_lossy().into_owned();
            }
        }
    }
    let time = t.get_mut("time").and_then(Value::as_table_mut).ok_or_else(|| bad("no [time]"))?;
    time.remove("end");
    time.insert("tau".into(), Value::Float(tau));
    time.insert("steps".into(), Value::Integer(steps as i64));
    if let Some(Value::Table(exact)) = t.get_mut("exact") {
        let mut s: Vec<i64> = exact
            .get("error_steps")
            .and_then(Value::as_array)
            .map(|a| {
                a.iter().filter_map(Value::as_integer).filter(|&x| x as usize <= steps).collect()
            })
            .unwrap_or_default();
        s.push(error_step as i64);
        s.sort_unstable();
        s.dedup();
        exact.insert(
            "error_steps".into(),
            Value::Array(s.into_iter().map(Value::Integer).collect()),
        );
    }
    if needs_h5(study) && !study.scene.has_contact {
        let output = t.entry("output").or_insert_with(|| Value::Table(Table::new()));
        if let Value::Table(o) = output {
            o.insert("every".into(), Value::Integer(error_step.max(1) as i64));
            o.insert("fields".into(), Value::Array(vec![Value::String("displacement".into())]));
        }
    }
    toml::to_string(&t).map_err(|e| bad(&format!("cannot write a copy: {e}")))
}

/// The launcher: `MASSFREE_MPIRUN` (e.g. "srun") or `mpirun --oversubscribe`, then `-n RANKS`.
fn launcher(ranks: usize) -> Command {
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
    runs: &Path,
) -> std::result::Result<Measured, String> {
    let summary = runs.join(format!("{}.summary.toml", p.id));
    let _ = std::fs::remove_file(&summary);
    let mut cmd = launcher(study.ranks);
    cmd.arg(binary).arg("run").arg(&p.scene).arg("-q");
    if let Some(h) = p.h {
        cmd.arg("--param").arg(format!("{}={h}", study.mesh_param));
    }
    for (k, v) in &study.params {
        cmd.arg("--param").arg(format!("{k}={v}"));
    }
    if let Some(m) = &p.mass {
        cmd.arg("--mass").arg(m);
    }
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
    let mut m = parse_summary(&text, p.error_step)
        .map_err(|e| format!("summary {}: {e}", summary.display()))?;
    m.process_s = process_s;
    Ok(m)
}

/// The run's own error line (`massfree: ...`), else the last line that is not mpirun's frame.
fn last_error_line(stderr: &str, code: Option<i32>) -> String {
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

fn parse_summary(text: &str, error_step: usize) -> std::result::Result<Measured, String> {
    let t: Table = text.parse().map_err(|e: toml::de::Error| e.message().to_string())?;
    let f = |t: &Table, k: &str| -> std::result::Result<f64, String> {
        match t.get(k) {
            Some(Value::Float(x)) => Ok(*x),
            Some(Value::Integer(i)) => Ok(*i as f64),
            _ => Err(format!("no number {k}")),
        }
    };
    let s = |k: &str| t.get(k).and_then(Value::as_str).unwrap_or_default().to_string();
    let timings = t.get("timings").and_then(Value::as_table).ok_or("no [timings]")?;
    let mut m = Measured {
        dofs: f(&t, "n_dofs")? as usize,
        ksp_iterations: f(&t, "ksp_iterations")? as usize,
        ksp_type: s("ksp_type"),
        pc_type: s("pc_type"),
        mass_kind: s("mass_kind"),
        mesh_s: f(timings, "mesh")?,
        partition_s: f(timings, "partition")?,
        assembly_s: f(timings, "assembly")?,
        setup_s: f(timings, "setup")?,
        stepping_s: f(timings, "stepping")?,
        output_s: f(timings, "output")?,
        peak_mib: f(&t, "peak_memory_mib").unwrap_or(f64::NAN),
        energy_drift: f(&t, "energy_drift").unwrap_or(f64::NAN),
        ..Default::default()
    };
    m.run_s = m.mesh_s + m.partition_s + m.assembly_s + m.setup_s + m.stepping_s + m.output_s;
    if let Some(c) = t.get("contact").and_then(Value::as_table) {
        m.contact = Some(ContactColumns {
            lowest_osc2: f(c, "lowest_osc2").unwrap_or(f64::NAN),
            total_force_tv_index: f(c, "total_force_tv_index").unwrap_or(f64::NAN),
            max_pressure: f(c, "max_pressure").unwrap_or(f64::NAN),
            episodes_max: f(c, "episodes_max").unwrap_or(0.0) as usize,
        });
    }
    if let Some(errors) = t.get("errors").and_then(Value::as_array) {
        for e in errors.iter().filter_map(Value::as_table) {
            if f(e, "step").ok() == Some(error_step as f64) {
                m.exact = Some((f(e, "l2")?, f(e, "h1_semi")?));
            }
        }
    }
    Ok(m)
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
        if study.scene.has_contact {
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
        _ if study.scene.has_contact => "pressure error (relative)",
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
        let text = r#"
n_dofs = 1458
ksp_iterations = 124
ksp_type = "cg"
pc_type = "jacobi"
mass_kind = "consistent"
peak_memory_mib = 85.5
energy_drift = 1e-4
[timings]
mesh = 0.1
partition = 0.01
assembly = 0.02
setup = 0.03
stepping = 0.5
output = 0.0
[[errors]]
step = 30
time = 3e-4
l2 = 6.1e-6
h1_semi = 1.5e-4
"#;
        let m = parse_summary(text, 30).unwrap();
        assert_eq!(m.dofs, 1458);
        assert!((m.run_s - 0.66).abs() < 1e-12);
        assert_eq!(m.exact, Some((6.1e-6, 1.5e-4)));
        assert!(parse_summary(text, 31).unwrap().exact.is_none());
        assert!(parse_summary("n_dofs = 1", 0).is_err());
    }
}
