//! `massfree suite [SPEC] [--reduced] [--ranks N] [--dir DIR]`: the hard-case stability suite.
//!
//! Every point of the suite file ([`spec`]: cases, each a shipped scene with a sweep of
//! overrides and mass kinds) is a real `mpirun -n RANKS massfree run` process, as in a study
//! (`study::launcher`). Its metrics ([`crate::stability`]) are computed from the run's HDF5
//! file (energies every step in `/energy`, contact per node and step in `/contact`, the
//! summary for the KSP iterations and the lowest node). Cases marked `rank_sweep` run again on
//! the suite's other rank counts and are compared entry by entry with the main run (energies
//! relative to the energy scale, contact forces relative to the largest force, active flags). The output folder gets
//! `suite.md` (per case, then every run), `suite.csv` (every run), `suite.png` (energy change
//! and osc2 of every run, coloured by pass/fail) and `runs/` (scenes, files, summaries, logs).
//!
//! A run fails the checks on a non-finite value, an energy above `E^0 +` work by more than
//! `rise_tol E_ref`, a penetration beyond `penetration_tol` of the body size, or a rank count
//! that differs by more than `rank_tol` (or fails); the rest is reported. The command fails
//! (non-zero exit) only when a run fails outright or hits NaN/inf.

pub mod spec;
pub mod table;

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::layout::RunReader;
use crate::post::plot::{status_panels, StatusPanel, StatusPoint};
use crate::report::{stability_from_file, RunSummary};
use crate::study::{clock, last_error_line, launcher};
use spec::Spec;
use table::{Done, Row, Tolerances};

/// What the command line asks for.
#[derive(Debug, Clone, Default)]
pub struct Options {
    pub spec: PathBuf,
    pub reduced: bool,
    pub ranks: Option<usize>,
    pub output: Option<PathBuf>,
    /// Write the runs' scenes and stop.
    pub scenes_only: bool,
}

/// Runs the suite; returns its rows (an error when a run failed or hit NaN/inf, after the
/// tables are written).
pub fn run(opts: &Options) -> Result<Vec<Row>> {
    let mut spec = spec::load(&opts.spec, opts.reduced)?;
    if let Some(r) = opts.ranks {
        if r == 0 {
            return Err(Error::Usage("--ranks 0: at least one rank".into()));
        }
        spec.ranks = r;
    }
    if let Some(o) = &opts.output {
        spec.output.clone_from(o);
    }
    if opts.scenes_only {
        return write_scenes(&spec).map(|_| Vec::new());
    }
    let binary = std::env::current_exe()
        .map_err(|e| Error::Io(format!("suite: cannot locate the massfree binary: {e}")))?;
    let rows = execute(&spec, &binary)?;
    let broken: Vec<&Row> = rows
        .iter()
        .filter(|r| {
            r.result.as_ref().map_or(true, |d| d.stability.non_finite > 0)
                || r.result.as_ref().is_ok_and(|d| d.ranks.iter().any(|(_, x)| x.is_err()))
        })
        .collect();
    if let Some(first) = broken.first() {
        return Err(Error::Solver(format!(
            "suite: {} run(s) failed or hit NaN/inf (first: {} {} {})",
            broken.len(),
            first.case,
            first.variant,
            first.mass_kind()
        )));
    }
    Ok(rows)
}

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text)
        .map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

/// Every run's scene, as `execute` writes it, without running (`--scenes-only`).
fn write_scenes(spec: &Spec) -> Result<()> {
    let runs = spec.output.join("runs");
    std::fs::create_dir_all(&runs)
        .map_err(|e| Error::Io(format!("cannot create {}: {e}", runs.display())))?;
    let points = spec::points(spec);
    for p in &points {
        write_scene(&runs, &spec.cases[p.case], p)?;
    }
    eprintln!("suite {}: {} scenes written to {}", spec.title, points.len(), runs.display());
    Ok(())
}

/// A point's scene written to `runs/<id>.scene.toml`: its path, steps and time step.
fn write_scene(runs: &Path, case: &spec::Case, p: &spec::Point) -> Result<(PathBuf, usize, f64)> {
    let (text, steps, tau) = spec::scene_text(case, p)?;
    let path = runs.join(format!("{}.scene.toml", p.id));
    write(&path, &text)?;
    Ok((path, steps, tau))
}

fn execute(spec: &Spec, binary: &Path) -> Result<Vec<Row>> {
    let out = &spec.output;
    let runs = out.join("runs");
    std::fs::create_dir_all(&runs)
        .map_err(|e| Error::Io(format!("cannot create {}: {e}", runs.display())))?;
    let _ = std::fs::copy(&spec.file, out.join("suite.toml"));
    let points = spec::points(spec);
    let extra: usize = points
        .iter()
        .filter(|p| spec.cases[p.case].rank_sweep)
        .map(|_| spec.rank_sweep.iter().filter(|&&r| r != spec.ranks).count())
        .sum();
    let total = points.len() + extra;
    eprintln!(
        "suite {}{}: {} cases, {} runs on {} rank(s) + {} for the rank sweep {:?}; output {}",
        spec.title,
        if spec.reduced { " (reduced)" } else { "" },
        spec.cases.len(),
        points.len(),
        spec.ranks,
        extra,
        spec.rank_sweep,
        out.display()
    );
    let tol = Tolerances::of(spec);
    let started = Instant::now();
    let mut done = 0usize;
    let mut rows = Vec::new();
    for p in &points {
        let case = &spec.cases[p.case];
        let h5 = runs.join(format!("{}.h5", p.id));
        let scene = write_scene(&runs, case, p);
        let mut row = Row {
            case: case.name.clone(),
            group: case.group.clone(),
            variant: p.variant.clone(),
            mass: p.mass.clone().unwrap_or_default(),
            ranks: spec.ranks,
            tau: scene.as_ref().map_or(0.0, |s| s.2),
            single_episode: case.single_episode,
            rank_tol: case.rank_tol,
            file: format!("runs/{}.h5", p.id),
            result: Err(String::new()),
        };
        row.result = match &scene {
            Err(e) => Err(e.to_string()),
            Ok((path, _, _)) => run_point(case, binary, path, &h5, spec.ranks),
        };
        done += 1;
        report(&row, tol, done, total, started);
        // The rank sweep: the same scene on other rank counts, compared with this run.
        if case.rank_sweep {
            if let (Ok((path, _, _)), Ok(_)) = (&scene, &row.result) {
                for &r in spec.rank_sweep.iter().filter(|&&r| r != spec.ranks) {
                    let other = runs.join(format!("{}-n{r}.h5", p.id));
                    let diff = run_point(case, binary, path, &other, r).and_then(|_| {
                        compare(&h5, &other, case.rank_steps).map_err(|e| e.to_string())
                    });
                    done += 1;
                    let elapsed = started.elapsed().as_secs_f64();
                    eprintln!(
                        "suite: [{done}/{total}] {} {} {} on {r} rank(s): {} | elapsed {}",
                        row.case,
                        row.variant,
                        row.mass_kind(),
                        match &diff {
                            Ok(d) => format!("largest relative difference {d:.1e}"),
                            Err(e) => format!("FAILED: {e}"),
                        },
                        clock(elapsed)
                    );
                    if let Ok(d) = &mut row.result {
                        d.ranks.push((r, diff));
                    }
                }
            } else if let Ok(d) = &mut row.result {
                d.ranks.clear();
            }
        }
        rows.push(row);
    }

    let csv = out.join("suite.csv");
    write(&csv, &table::csv(&rows, tol))?;
    let n_fail = rows.iter().filter(|r| !r.failures(tol).is_empty()).count();
    let head = describe(spec, &rows, n_fail, started.elapsed().as_secs_f64());
    let per_case = table::case_summary(&rows, tol);
    let all = table::markdown(&rows, tol);
    let md = out.join("suite.md");
    write(&md, &format!("{head}\n\n## Per case\n\n{per_case}\n## Every run\n\n{all}"))?;
    let mut files = vec![md, csv];
    let png = out.join("suite.png");
    match picture(&png, spec, &rows, tol) {
        Ok(()) => files.push(png),
        Err(e) => eprintln!("suite: warning: {e}"),
    }
    println!("{head}\n");
    print!("{per_case}");
    println!();
    for f in files {
        println!("wrote {}", f.display());
    }
    Ok(rows)
}

fn report(row: &Row, tol: Tolerances, done: usize, total: usize, started: Instant) {
    let elapsed = started.elapsed().as_secs_f64();
    let eta = elapsed / done as f64 * (total - done) as f64;
    let what = match &row.result {
        Ok(d) => {
            let fails = row.failures(tol);
            format!(
                "{}, {:.1} s, rise {:.1e}, loss {:.1e}, {} impact(s), penetration {:.1e}",
                if fails.is_empty() {
                    "pass".to_string()
                } else {
                    format!("FAIL ({})", fails.join(", "))
                },
                d.process_s,
                d.stability.energy_rise,
                d.stability.energy_loss,
                d.stability.impacts,
                d.stability.penetration
            )
        }
        Err(e) => format!("FAILED: {e}"),
    };
    eprintln!(
        "suite: [{done}/{total}] {} {} {}: {what} | elapsed {}, ETA {}",
        row.case,
        row.variant,
        row.mass_kind(),
        clock(elapsed),
        clock(eta)
    );
}

/// One run of a point on `ranks` ranks into `h5`; its summary and metrics.
fn run_point(
    case: &spec::Case,
    binary: &Path,
    scene: &Path,
    h5: &Path,
    ranks: usize,
) -> std::result::Result<Done, String> {
    let stem = h5.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = h5.parent().unwrap_or(Path::new("."));
    let summary = dir.join(format!("{stem}.summary.toml"));
    let _ = std::fs::remove_file(&summary);
    let mut cmd = launcher(ranks);
    cmd.arg(binary).arg("run").arg(scene).arg("-q");
    cmd.arg("--summary").arg(&summary).arg("-o").arg(h5).arg("--overwrite");
    if !case.petsc.is_empty() {
        cmd.arg("--").args(&case.petsc);
    }
    cmd.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(Stdio::piped());
    let t0 = Instant::now();
    let output = cmd.output().map_err(|e| format!("cannot start {:?}: {e}", cmd.get_program()))?;
    let process_s = t0.elapsed().as_secs_f64();
    let _ = std::fs::write(
        dir.join(format!("{stem}.log")),
        [&output.stdout[..], &output.stderr[..]].concat(),
    );
    if !output.status.success() {
        return Err(last_error_line(
            &String::from_utf8_lossy(&output.stderr),
            output.status.code(),
        ));
    }
    let text = std::fs::read_to_string(&summary)
        .map_err(|e| format!("the run wrote no summary {}: {e}", summary.display()))?;
    let summary = RunSummary::parse(&text).map_err(|e| format!("summary: {e}"))?;
    let stability = stability_from_file(h5).map_err(|e| e.to_string())?;
    Ok(Done { summary, stability, process_s, ranks: Vec::new() })
}

/// The energy series a rank sweep compares (each relative to the run's energy scale, the
/// largest absolute value over all of them: a work that stays at rounding level is compared
/// against the energy, not against itself).
const ENERGIES: [&str; 6] = [
    "/energy/total",
    "/energy/kinetic",
    "/energy/potential",
    "/energy/external_work",
    "/energy/contact_work",
    "/energy/dirichlet_work",
];

/// The largest relative difference between two runs of the same scene: the energy series
/// relative to the energy scale, the contact forces relative to the largest force, the active
/// flags (any mismatch counts as 1); over the first `steps` steps when given (the series have
/// one row per step from step 0).
pub fn compare(a: &Path, b: &Path, steps: Option<usize>) -> Result<f64> {
    let (ra, rb) = (RunReader::open(a)?, RunReader::open(b)?);
    let read = |name: &str| -> Result<Option<(Vec<f64>, Vec<f64>)>> {
        let has = |r: &RunReader| r.file.dataset(name).is_ok();
        match (has(&ra), has(&rb)) {
            (false, false) => Ok(None),
            (true, true) => {
                let (mut x, mut y) = (ra.series(name)?, rb.series(name)?);
                if let Some(k) = steps {
                    // Rows of this series: as many as the energy series has values.
                    let rows = ra.series("/energy/total")?.len().max(1);
                    let keep = (k + 1).min(rows) * (x.len() / rows);
                    x.truncate(keep);
                    y.truncate(keep.min(y.len()));
                }
                if x.len() != y.len() {
                    return Err(Error::Io(format!(
                        "{name}: {} against {} values",
                        x.len(),
                        y.len()
                    )));
                }
                Ok(Some((x, y)))
            }
            _ => Err(Error::Io(format!("{name} is in one run's file only"))),
        }
    };
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = |x: &[f64], y: &[f64]| {
        x.iter().zip(y).fold(0.0f64, |m, (p, q)| {
            if p.is_nan() && q.is_nan() {
                m
            } else {
                m.max((p - q).abs())
            }
        })
    };
    let relative = |d: f64, scale: f64| {
        let r = if scale > 0.0 { d / scale } else { d };
        if r.is_nan() {
            f64::INFINITY
        } else {
            r
        }
    };
    let mut energies = Vec::new();
    for name in ENERGIES {
        if let Some(p) = read(name)? {
            energies.push(p);
        }
    }
    let scale = energies.iter().map(|(x, _)| largest(x)).fold(0.0, f64::max);
    let mut worst = energies.iter().map(|(x, y)| relative(diff(x, y), scale)).fold(0.0, f64::max);
    if let Some((x, y)) = read("/contact/force")? {
        worst = worst.max(relative(diff(&x, &y), largest(&x)));
    }
    if let Some((x, y)) = read("/contact/active")? {
        worst = worst.max(diff(&x, &y));
    }
    Ok(worst)
}

fn describe(spec: &Spec, rows: &[Row], n_fail: usize, seconds: f64) -> String {
    let flicker = rows.iter().filter(|r| r.flags().contains(&"flicker")).count();
    format!(
        "# Stability suite {}{}\n\n{} runs of {} cases on {} rank(s) (rank sweep {:?} for the cases so marked), \
         {} in all; {} pass, {} fail the checks, {} flagged (flicker with M_H).\n\n\
         Checks (fail): NaN/inf anywhere; energy rise max_n (E^n - E^0 - W^n)/E_ref > {:e} (W: loads and \
         Dirichlet reactions, not contact; E_ref = max_n max(|E^n|, |E^0 + W^n|)); penetration -min gap > {:e} \
         of the body size; another rank count differing by more than {:e} (the energy series relative to \
         the largest energy, the contact forces relative to the largest force, the active flags). Reported: loss = (E^0 + W^N - E^N)/E_ref \
         at the end, impacts = contact episodes of the body, osc2 and TV index of the lowest node's pressure \
         (p, largest over its episodes) and of the total contact force (F, largest over the impacts), \
         contact episodes per node within an impact, active-set (PDAS) iterations per contact step, KSP \
         iterations per step, wall time of the whole mpirun process.",
        spec.title,
        if spec.reduced { " (reduced)" } else { "" },
        rows.len(),
        spec.cases.len(),
        spec.ranks,
        spec.rank_sweep,
        clock(seconds),
        rows.len() - n_fail,
        n_fail,
        flicker,
        spec.rise_tol,
        spec.penetration_tol,
        spec.rank_tol,
    )
}

/// Energy change and osc2 of every run, on log scales, coloured by pass / flagged / fail.
fn picture(path: &Path, spec: &Spec, rows: &[Row], tol: Tolerances) -> Result<()> {
    let class = |r: &Row| {
        if !r.failures(tol).is_empty() {
            2
        } else if !r.flags().is_empty() {
            1
        } else {
            0
        }
    };
    let floor = 1e-16;
    let pts = |f: &dyn Fn(&Done) -> f64| -> Vec<StatusPoint> {
        rows.iter()
            .enumerate()
            .filter_map(|(i, r)| {
                r.result.as_ref().ok().map(|d| StatusPoint {
                    x: i as f64,
                    y: f(d).max(floor),
                    class: class(r),
                })
            })
            .collect()
    };
    let rise = pts(&|d| d.stability.energy_rise);
    let loss = pts(&|d| d.stability.energy_loss.abs());
    let osc = pts(&|d| d.stability.force_osc2);
    let mut bands: Vec<(f64, f64, String)> = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        match bands.last_mut() {
            Some(b) if b.2 == r.case => b.1 = i as f64,
            _ => bands.push((i as f64, i as f64, r.case.clone())),
        }
    }
    let title = format!("{}: {} runs", spec.title, rows.len());
    status_panels(
        path,
        &title,
        &[
            StatusPanel {
                caption: "energy rise above E0 + work (relative; floor 1e-16)",
                points: &rise,
                threshold: Some(tol.rise),
            },
            StatusPanel {
                caption: "|energy loss| at the end (relative)",
                points: &loss,
                threshold: None,
            },
            StatusPanel {
                caption: "osc2 of the total contact force",
                points: &osc,
                threshold: None,
            },
        ],
        &bands,
        &["pass", "flagged (flicker)", "fail"],
    )
}
