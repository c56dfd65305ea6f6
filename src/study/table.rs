//! The study's table: one row per point, observed rates, the Pareto front, CSV and Markdown.

use std::fmt::Write as _;

/// What one finished run measured (medians over the repeats where noted).
#[derive(Debug, Clone, Default)]
pub struct Measured {
    pub dofs: usize,
    pub ksp_type: String,
    pub pc_type: String,
    pub mass_kind: String,
    pub ksp_iterations: usize,
    pub mesh_s: f64,
    pub partition_s: f64,
    pub assembly_s: f64,
    pub setup_s: f64,
    pub stepping_s: f64,
    pub output_s: f64,
    /// Sum of the phases measured inside the program (the repeat with the median total).
    pub run_s: f64,
    /// Median wall time of the whole `mpirun` process, as seen by the study.
    pub process_s: f64,
    pub peak_mib: f64,
    pub energy_drift: f64,
    /// `(E_0 - E_end) / E_0`: the share of the initial energy lost by the end of the run.
    pub energy_loss: f64,
    pub contact: Option<ContactColumns>,
    /// The run's own errors against the exact solution at the error step: (L2, H1 seminorm).
    pub exact: Option<(f64, f64)>,
}

#[derive(Debug, Clone, Copy, Default)]
pub struct ContactColumns {
    pub lowest_osc2: f64,
    pub lowest_tv_index: f64,
    pub total_force_tv_index: f64,
    pub max_pressure: f64,
    pub episodes_max: usize,
}

#[derive(Debug, Clone, Default)]
pub struct Row {
    pub label: String,
    pub h: Option<f64>,
    pub tau: f64,
    pub steps: usize,
    pub mass: String,
    pub solver: String,
    pub ranks: usize,
    /// Index of the (mass, solver) combination: rows of a group differ only in h and tau
    /// (unique across the parts of a study).
    pub group: usize,
    /// The study part (scene) of the row and its name (empty without parts).
    pub part: usize,
    pub part_name: String,
    /// The material model (`sweep.model`; empty: the scene's) and the amplitude
    /// (`sweep.amplitude`) of the row.
    pub model: String,
    pub amplitude: Option<f64>,
    pub measured: Option<Measured>,
    /// The one-line error of a failed point.
    pub failure: Option<String>,
    pub err_l2: Option<f64>,
    pub err_h1: Option<f64>,
    /// Contact scenes against a reference run: the total contact force's relative L2
    /// difference in time (err_l2 is the lowest node's pressure's).
    pub err_force: Option<f64>,
    /// Against another model's run (`reference = { model }`): the relative nodal L2 difference
    /// of the final displacement.
    pub err_u: Option<f64>,
    /// Against another model's run: this row's run_s over the reference run's.
    pub time_ratio: Option<f64>,
    /// This row is the reference of its group (its error is zero by definition).
    pub is_reference: bool,
    pub rate_l2_h: Option<f64>,
    pub rate_h1_h: Option<f64>,
    pub rate_l2_tau: Option<f64>,
    pub rate_h1_tau: Option<f64>,
    /// On the Pareto front of (run time, err_l2) among the rows of its part.
    pub pareto: bool,
    /// On the Pareto front of (run time, err_force) among the rows of its part.
    pub pareto_force: bool,
}

impl Row {
    pub fn ok(&self) -> bool {
        self.measured.is_some() && self.failure.is_none()
    }
}

/// Observed order between two refinements: `ln(e0/e1) / ln(x0/x1)`.
pub fn rate(e0: f64, e1: f64, x0: f64, x1: f64) -> Option<f64> {
    let r = (e0 / e1).ln() / (x0 / x1).ln();
    (e0 > 0.0 && e1 > 0.0 && x0 != x1 && r.is_finite()).then_some(r)
}

/// Fills the rate columns: along h between rows of the same group and tau, along tau between
/// rows of the same group and h, each time between consecutive refinements (sorted from
/// coarse to fine). Failed rows and reference rows break no chain: they are skipped.
pub fn fill_rates(rows: &mut [Row], along_h: bool, along_tau: bool) {
    let usable: Vec<usize> =
        (0..rows.len()).filter(|&i| rows[i].ok() && !rows[i].is_reference).collect();
    let chains = |rows: &[Row], key: &dyn Fn(&Row) -> (usize, u64), x: &dyn Fn(&Row) -> f64| {
        let mut keys: Vec<(usize, u64)> = usable.iter().map(|&i| key(&rows[i])).collect();
        keys.sort();
        keys.dedup();
        keys.into_iter()
            .map(|k| {
                let mut idx: Vec<usize> =
                    usable.iter().copied().filter(|&i| key(&rows[i]) == k).collect();
                idx.sort_by(|&a, &b| x(&rows[b]).total_cmp(&x(&rows[a])));
                idx
            })
            .collect::<Vec<_>>()
    };
    let hx = |r: &Row| r.h.unwrap_or(f64::NAN);
    if along_h {
        for chain in chains(rows, &|r: &Row| (r.group, r.tau.to_bits()), &hx) {
            for w in chain.windows(2) {
                let (a, b) = (&rows[w[0]], &rows[w[1]]);
                let l2 = opt_rate(a.err_l2, b.err_l2, hx(a), hx(b));
                let h1 = opt_rate(a.err_h1, b.err_h1, hx(a), hx(b));
                rows[w[1]].rate_l2_h = l2;
                rows[w[1]].rate_h1_h = h1;
            }
        }
    }
    if along_tau {
        let tx = |r: &Row| r.tau;
        for chain in chains(rows, &|r: &Row| (r.group, r.h.unwrap_or(0.0).to_bits()), &tx) {
            for w in chain.windows(2) {
                let (a, b) = (&rows[w[0]], &rows[w[1]]);
                let l2 = opt_rate(a.err_l2, b.err_l2, a.tau, b.tau);
                let h1 = opt_rate(a.err_h1, b.err_h1, a.tau, b.tau);
                rows[w[1]].rate_l2_tau = l2;
                rows[w[1]].rate_h1_tau = h1;
            }
        }
    }
}

fn opt_rate(e0: Option<f64>, e1: Option<f64>, x0: f64, x1: f64) -> Option<f64> {
    rate(e0?, e1?, x0, x1)
}

/// Which of the points `(cost, error)` are on the Pareto front: no other point is at least as
/// cheap and at least as accurate and strictly better in one of the two. Errors that differ
/// by less than the relative tolerance `tol` count as equal (`tol = 0`: the plain definition).
/// Points with a non-finite coordinate are never on the front (and dominate nothing).
pub fn pareto_front(points: &[(f64, f64)], tol: f64) -> Vec<bool> {
    let finite = |p: &(f64, f64)| p.0.is_finite() && p.1.is_finite();
    let dominates = |q: &(f64, f64), p: &(f64, f64)| {
        q.0 <= p.0 && q.1 <= p.1 * (1.0 + tol) && (q.0 < p.0 || q.1 < p.1 * (1.0 - tol))
    };
    points
        .iter()
        .map(|p| finite(p) && !points.iter().any(|q| finite(q) && dominates(q, p)))
        .collect()
}

/// Errors closer than this (relative) count as equal on the Pareto front: the table shows
/// four digits, and a difference in the fifth is no gain in accuracy worth paying for.
pub const PARETO_TOLERANCE: f64 = 1e-3;

/// Marks the rows on the Pareto fronts of (run time, err_l2) and (run time, err_force),
/// each part (scene) on its own: the runs of different scenes solve different problems.
pub fn fill_pareto(rows: &mut [Row]) {
    let parts: Vec<usize> = {
        let mut p: Vec<usize> = rows.iter().map(|r| r.part).collect();
        p.sort_unstable();
        p.dedup();
        p
    };
    let point = |r: &Row, e: Option<f64>| match (&r.measured, e) {
        (Some(m), Some(e)) if r.ok() && !r.is_reference && e > 0.0 => (m.run_s, e),
        _ => (f64::NAN, f64::NAN),
    };
    for k in parts {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| rows[i].part == k).collect();
        let pts: Vec<(f64, f64)> = idx.iter().map(|&i| point(&rows[i], rows[i].err_l2)).collect();
        for (&i, p) in idx.iter().zip(pareto_front(&pts, PARETO_TOLERANCE)) {
            rows[i].pareto = p;
        }
        let pts: Vec<(f64, f64)> =
            idx.iter().map(|&i| point(&rows[i], rows[i].err_force)).collect();
        for (&i, p) in idx.iter().zip(pareto_front(&pts, PARETO_TOLERANCE)) {
            rows[i].pareto_force = p;
        }
    }
}

/// Which optional columns the table shows.
#[derive(Debug, Clone, Copy)]
pub struct Columns<'a> {
    /// Name of the mesh parameter column (e.g. "h", "hc").
    pub h_name: &'a str,
    pub rate_h: bool,
    pub rate_tau: bool,
    pub h1: bool,
    pub contact: bool,
    /// The total force's error (and its front) beside err_l2 (contact against a reference).
    pub force: bool,
    /// A first column naming the part (files with parts).
    pub part: bool,
    /// The `model` and `amplitude` columns (`sweep.model`, `sweep.amplitude`).
    pub model: bool,
    pub amplitude: bool,
    /// Rows against another model's run: `err_u` and `time_ratio`.
    pub against_model: bool,
}

fn sci(x: Option<f64>) -> String {
    x.map(|v| format!("{v:.4e}")).unwrap_or_default()
}
fn fix(x: Option<f64>, d: usize) -> String {
    x.map(|v| format!("{v:.d$}")).unwrap_or_default()
}

/// `h` as a fraction 1/N when 1/h is (nearly) a whole number >= 2.
pub fn show_h(h: f64) -> String {
    let n = (1.0 / h).round();
    if n >= 2.0 && ((1.0 / h) - n).abs() < 1e-9 * n {
        format!("1/{n}")
    } else {
        format!("{h}")
    }
}

/// A time step in the shortest form: `1e-5`, `2.5e-3`, `0.05`.
pub fn show_tau(tau: f64) -> String {
    if tau < 1e-2 {
        format!("{tau:e}")
    } else {
        format!("{tau}")
    }
}

fn header(c: &Columns) -> Vec<String> {
    let mut h: Vec<String> = Vec::new();
    if c.part {
        h.push("scene".into());
    }
    h.extend([
        c.h_name.to_string(),
        "dofs".into(),
        "tau".into(),
        "steps".into(),
        "mass".into(),
        "solver".into(),
        "ranks".into(),
    ]);
    if c.model {
        h.push("model".into());
    }
    if c.amplitude {
        h.push("amplitude".into());
    }
    h.push("err_l2".into());
    if c.force {
        h.push("err_force".into());
    }
    if c.against_model {
        h.push("err_u".into());
    }
    if c.rate_h {
        h.push(format!("rate_l2_{}", c.h_name));
    }
    if c.rate_tau {
        h.push("rate_l2_tau".into());
    }
    if c.h1 {
        h.push("err_h1".into());
        if c.rate_h {
            h.push(format!("rate_h1_{}", c.h_name));
        }
        if c.rate_tau {
            h.push("rate_h1_tau".into());
        }
    }
    h.push("run_s".into());
    if c.against_model {
        h.push("time_ratio".into());
    }
    for s in [
        "mesh_partition_s",
        "assembly_s",
        "setup_s",
        "stepping_s",
        "output_s",
        "process_s",
        "ksp_its_per_step",
        "peak_mib",
    ] {
        h.push(s.into());
    }
    if c.contact {
        for s in [
            "energy_drift",
            "energy_loss",
            "lowest_osc2",
            "lowest_tv_index",
            "total_force_tv_index",
            "max_pressure",
            "episodes_max",
        ] {
            h.push(s.into());
        }
    }
    h.push("pareto".into());
    if c.force {
        h.push("pareto_force".into());
    }
    h.push("status".into());
    h
}

fn cells(r: &Row, c: &Columns, md: bool) -> Vec<String> {
    let m = r.measured.as_ref();
    let h = r.h.map(|h| if md { show_h(h) } else { format!("{h}") }).unwrap_or_default();
    let err = |e: Option<f64>| {
        if r.is_reference && r.ok() {
            if md {
                "(reference)".to_string()
            } else {
                "0".to_string()
            }
        } else {
            sci(e)
        }
    };
    let mut v = Vec::new();
    if c.part {
        v.push(r.part_name.clone());
    }
    v.extend([
        h,
        m.map(|m| m.dofs.to_string()).unwrap_or_default(),
        show_tau(r.tau),
        r.steps.to_string(),
        m.map(|m| m.mass_kind.clone()).filter(|s| !s.is_empty()).unwrap_or_else(|| r.mass.clone()),
        r.solver.clone(),
        r.ranks.to_string(),
    ]);
    if c.model {
        v.push(r.model.clone());
    }
    if c.amplitude {
        v.push(r.amplitude.map(|a| format!("{a}")).unwrap_or_default());
    }
    v.push(err(r.err_l2));
    if c.force {
        v.push(err(r.err_force));
    }
    if c.against_model {
        v.push(err(r.err_u));
    }
    if c.rate_h {
        v.push(fix(r.rate_l2_h, 3));
    }
    if c.rate_tau {
        v.push(fix(r.rate_l2_tau, 3));
    }
    if c.h1 {
        v.push(err(r.err_h1));
        if c.rate_h {
            v.push(fix(r.rate_h1_h, 3));
        }
        if c.rate_tau {
            v.push(fix(r.rate_h1_tau, 3));
        }
    }
    let f = |g: &dyn Fn(&Measured) -> f64, d: usize| fix(m.map(g), d);
    v.push(f(&|m| m.run_s, 3));
    if c.against_model {
        v.push(fix(r.time_ratio, 3));
    }
    v.push(f(&|m| m.mesh_s + m.partition_s, 3));
    v.push(f(&|m| m.assembly_s, 3));
    v.push(f(&|m| m.setup_s, 3));
    v.push(f(&|m| m.stepping_s, 3));
    v.push(f(&|m| m.output_s, 3));
    v.push(f(&|m| m.process_s, 2));
    v.push(f(&|m| m.ksp_iterations as f64 / r.steps.max(1) as f64, 2));
    v.push(f(&|m| m.peak_mib, 0));
    if c.contact {
        let k = m.and_then(|m| m.contact);
        v.push(sci(m.map(|m| m.energy_drift)));
        v.push(sci(m.map(|m| m.energy_loss)));
        v.push(sci(k.map(|k| k.lowest_osc2)));
        v.push(fix(k.map(|k| k.lowest_tv_index), 3));
        v.push(fix(k.map(|k| k.total_force_tv_index), 3));
        v.push(sci(k.map(|k| k.max_pressure)));
        v.push(k.map(|k| k.episodes_max.to_string()).unwrap_or_default());
    }
    let mark = |on: bool| -> String {
        match (on, md) {
            (true, true) => "*".into(),
            (true, false) => "1".into(),
            (false, true) => String::new(),
            (false, false) => "0".into(),
        }
    };
    v.push(mark(r.pareto));
    if c.force {
        v.push(mark(r.pareto_force));
    }
    v.push(match &r.failure {
        Some(e) => format!("failed: {e}"),
        None => "ok".into(),
    });
    v
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn csv(rows: &[Row], c: &Columns) -> String {
    let mut out = String::new();
    let line = |v: Vec<String>| v.iter().map(|s| csv_field(s)).collect::<Vec<_>>().join(",");
    out.push_str(&line(header(c)));
    out.push('\n');
    for r in rows {
        out.push_str(&line(cells(r, c, false)));
        out.push('\n');
    }
    out
}

pub fn markdown(rows: &[Row], c: &Columns) -> String {
    let mut out = String::new();
    let head = header(c);
    let _ = writeln!(out, "| {} |", head.join(" | "));
    let _ = writeln!(out, "|{}", "---|".repeat(head.len()));
    for r in rows {
        let v: Vec<String> = cells(r, c, true).iter().map(|s| s.replace('|', "\\|")).collect();
        let _ = writeln!(out, "| {} |", v.join(" | "));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pareto_front_of_a_hand_made_table() {
        // (cost, error)
        let pts = [
            (1.0, 10.0),     // front: cheapest
            (2.0, 5.0),      // front
            (3.0, 6.0),      // dominated by (2, 5)
            (4.0, 1.0),      // front: most accurate
            (5.0, 1.0),      // dominated by (4, 1) (same error, dearer)
            (2.0, 5.0),      // a duplicate of a front point: neither dominates the other
            (f64::NAN, 0.1), // failed: never on the front, dominates nothing
            (0.5, f64::INFINITY),
            (3.5, 2.0), // front
        ];
        let f = pareto_front(&pts, 0.0);
        assert_eq!(f, vec![true, true, false, true, false, true, false, false, true]);
        assert_eq!(pareto_front(&[], 0.0), Vec::<bool>::new());
        assert_eq!(pareto_front(&[(1.0, 1.0)], 0.0), vec![true]);
        // A dearer point whose error is smaller only in the fifth digit gains nothing.
        let near = [(1.0, 3.18960e-6), (2.0, 3.18957e-6)];
        assert_eq!(pareto_front(&near, 0.0), vec![true, true]);
        assert_eq!(pareto_front(&near, PARETO_TOLERANCE), vec![true, false]);
        // Same cost, errors within the tolerance: neither dominates.
        assert_eq!(pareto_front(&[(1.0, 1.0), (1.0, 1.0005)], PARETO_TOLERANCE), vec![true, true]);
    }

    #[test]
    fn pareto_marks_rows_and_skips_failed_and_reference() {
        let row = |t: f64, e: f64| Row {
            measured: Some(Measured { run_s: t, ..Default::default() }),
            err_l2: Some(e),
            ..Default::default()
        };
        let mut rows = vec![row(1.0, 4.0), row(2.0, 1.0), row(3.0, 2.0), row(0.1, 0.0)];
        rows[3].is_reference = true;
        let mut failed = row(0.01, 0.01);
        failed.failure = Some("boom".into());
        rows.push(failed);
        fill_pareto(&mut rows);
        let marks: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(marks, vec![true, true, false, false, false]);
    }

    #[test]
    fn each_part_has_its_own_fronts() {
        let row = |part: usize, t: f64, e: f64, f: f64| Row {
            part,
            measured: Some(Measured { run_s: t, ..Default::default() }),
            err_l2: Some(e),
            err_force: Some(f),
            ..Default::default()
        };
        // Part 1's rows are all dominated by part 0's first row, which must not matter;
        // within part 1 the pressure front and the force front differ.
        let mut rows = vec![
            row(0, 1.0, 1e-3, 1e-3),
            row(0, 2.0, 2e-3, 5e-4),
            row(1, 3.0, 0.5, 0.1),
            row(1, 4.0, 0.2, 0.2),
            row(1, 5.0, 0.3, 0.05),
        ];
        fill_pareto(&mut rows);
        let p: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        let f: Vec<bool> = rows.iter().map(|r| r.pareto_force).collect();
        assert_eq!(p, vec![true, false, true, true, false]);
        assert_eq!(f, vec![true, true, true, false, true]);
    }

    #[test]
    fn rates_between_consecutive_refinements() {
        let row = |h: f64, e: f64, group: usize| Row {
            h: Some(h),
            tau: 1e-5,
            group,
            measured: Some(Measured::default()),
            err_l2: Some(e),
            err_h1: Some(e.sqrt()),
            ..Default::default()
        };
        // Out of order on purpose, two groups.
        let mut rows = vec![
            row(0.125, 1.0 / 16.0, 0),
            row(0.5, 1.0, 0),
            row(0.25, 0.25, 0),
            row(0.5, 2.0, 1),
            row(0.25, 1.0, 1),
        ];
        fill_rates(&mut rows, true, false);
        assert!(rows[1].rate_l2_h.is_none());
        assert!((rows[2].rate_l2_h.unwrap() - 2.0).abs() < 1e-12);
        assert!((rows[0].rate_l2_h.unwrap() - 2.0).abs() < 1e-12);
        assert!((rows[0].rate_h1_h.unwrap() - 1.0).abs() < 1e-12);
        assert!((rows[4].rate_l2_h.unwrap() - 1.0).abs() < 1e-12);
        assert!(rows[4].rate_l2_tau.is_none());
        assert_eq!(rate(1.0, 0.0, 2.0, 1.0), None);
    }

    #[test]
    fn csv_quotes_and_h_fractions() {
        assert_eq!(csv_field("a,b"), "\"a,b\"");
        assert_eq!(csv_field("say \"x\""), "\"say \"\"x\"\"\"");
        assert_eq!(show_h(0.03125), "1/32");
        assert_eq!(show_h(0.4), "0.4");
        assert_eq!(show_h(0.05), "1/20");
    }
}
