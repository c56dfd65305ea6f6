//! The study's plots: errors against h, tau and run time per part (`error_h.png`,
//! `error_tau.png`, `error_time.png`) and, for files with parts, one plot of all parts'
//! errors against run time with their Pareto fronts.

use std::path::PathBuf;

use super::spec::{Reference, Study, StudySet};
use super::table::{self, Columns, Row};
use crate::error::Result;
use crate::post::plot::{loglog_plot, loglog_plot_styled, Marker, Plot, Series, SeriesStyle};

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

/// One part's plots: `PREFIXerror_h.png`, `PREFIXerror_tau.png` and, with `with_time`,
/// `error_time.png` (files with parts draw one error-against-time plot of all parts,
/// [`set_plots`]).
pub(super) fn part_plots(
    study: &Study,
    rows: &[Row],
    c: &Columns,
    prefix: &str,
    with_time: bool,
) -> Result<Vec<PathBuf>> {
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
        let path = out.join(format!("{prefix}error_h.png"));
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
        let path = out.join(format!("{prefix}error_tau.png"));
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
    if !with_time {
        return Ok(files);
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

/// The palette colour and marker of a mass kind (the same in every plot of parts).
fn mass_style(kind: &str) -> (usize, Marker) {
    match kind {
        "consistent" => (0, Marker::Circle),
        "lumped" => (1, Marker::Square),
        "modified0" => (2, Marker::Triangle),
        "modified1" => (3, Marker::Diamond),
        _ => (7, Marker::Circle),
    }
}

/// A plot of [`set_plots`]: file name, y label, the row's error, whether the row is on
/// that error's front.
type Measure =
    (&'static str, &'static str, Box<dyn Fn(&Row) -> Option<f64>>, Box<dyn Fn(&Row) -> bool>);

/// The plots of a file with parts: `error_time.png` (err_l2 against run time) and, for
/// contact parts, `error_force_time.png` (err_force against run time). One colour and
/// marker per mass kind; part 1 filled markers and solid lines, part 2 hollow markers, part
/// 3 filled and thin lines...; one curve per (part, mass kind, tau) along the mesh
/// refinements; each part's Pareto front as a thick grey line through its front points,
/// which are ringed.
pub(super) fn set_plots(set: &StudySet, rows: &[Row], c: &Columns) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    let time = |r: &Row| r.measured.as_ref().map(|m| m.run_s).unwrap_or(f64::NAN);
    let mut measures: Vec<Measure> = vec![(
        "error_time.png",
        if c.force { "pressure error of the lowest node (relative L2 in time)" } else { "error" },
        Box::new(|r: &Row| r.err_l2),
        Box::new(|r: &Row| r.pareto),
    )];
    if c.force {
        measures.push((
            "error_force_time.png",
            "total contact force error (relative L2 in time)",
            Box::new(|r: &Row| r.err_force),
            Box::new(|r: &Row| r.pareto_force),
        ));
    }
    for (file, y_label, err, on_front) in &measures {
        let mut series: Vec<Series> = Vec::new();
        let mut styles: Vec<SeriesStyle> = Vec::new();
        for (k, study) in set.parts.iter().enumerate() {
            let part_rows: Vec<&Row> =
                rows.iter().filter(|r| r.part == k && r.ok() && !r.is_reference).collect();
            // Curves: per mass kind (and solver) and tau, along h, sorted by time.
            let mut keys: Vec<(usize, u64)> =
                part_rows.iter().map(|r| (r.group, r.tau.to_bits())).collect();
            keys.sort();
            keys.dedup();
            let mut named: Vec<usize> = Vec::new();
            for (g, t) in keys {
                let mut pts: Vec<(f64, f64)> = part_rows
                    .iter()
                    .filter(|r| r.group == g && r.tau.to_bits() == t)
                    .filter_map(|r| Some((time(r), err(r)?)))
                    .collect();
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                let Some(r0) = part_rows.iter().find(|r| r.group == g) else { continue };
                let kind = if r0.mass.is_empty() {
                    r0.measured.as_ref().map(|m| m.mass_kind.clone()).unwrap_or_default()
                } else {
                    r0.mass.clone()
                };
                let (ci, marker) = mass_style(&kind);
                // The legend names each (part, kind) once.
                let name = if named.contains(&g) {
                    String::new()
                } else {
                    named.push(g);
                    format!("{}: {}", study.title, group_name(study, r0))
                };
                series.push(Series { name, points: pts });
                styles.push(SeriesStyle {
                    color: SeriesStyle::palette(ci),
                    marker: Some(marker),
                    filled: k % 2 == 0,
                    size: 5,
                    line: true,
                    line_width: if k < 2 { 2 } else { 1 },
                });
            }
            let mut front: Vec<(f64, f64)> = part_rows
                .iter()
                .filter(|r| on_front(r))
                .filter_map(|r| Some((time(r), err(r)?)))
                .collect();
            front.sort_by(|a, b| a.0.total_cmp(&b.0));
            if !front.is_empty() {
                series
                    .push(Series { name: format!("{}: Pareto front", study.title), points: front });
                styles.push(SeriesStyle {
                    color: (90, 90, 90),
                    marker: Some(Marker::Circle),
                    filled: false,
                    size: 9,
                    line: true,
                    line_width: 1,
                });
            }
        }
        // The fronts go first so that the points are drawn over them.
        let order: Vec<usize> = (0..series.len())
            .filter(|&i| styles[i].size == 9)
            .chain((0..series.len()).filter(|&i| styles[i].size != 9))
            .collect();
        let series: Vec<Series> = order.iter().map(|&i| series[i].clone()).collect();
        let styles: Vec<SeriesStyle> = order.iter().map(|&i| styles[i]).collect();
        let path = set.output.join(file);
        let title = format!(
            "{}: {} against run time",
            set.title,
            if c.force && *file != "error_time.png" { "force error" } else { "error" }
        );
        let plot = Plot {
            title: &title,
            x_label: "run time inside the program (s, median)",
            y_label,
            series: &series,
            width: 1000,
            height: 720,
        };
        loglog_plot_styled(&path, &plot, &[], &styles)?;
        files.push(path);
    }
    Ok(files)
}
