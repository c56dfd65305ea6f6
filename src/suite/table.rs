//! The suite's rows: the checks of each run, the Markdown and CSV tables, the per-case summary.

use crate::report::RunSummary;
use crate::stability::Stability;

use super::spec::Spec;

/// A finished run of a point.
#[derive(Debug, Clone)]
pub struct Done {
    pub summary: RunSummary,
    /// From the HDF5 file (`report::stability_from_file`).
    pub stability: Stability,
    /// The whole mpirun process, seconds.
    pub process_s: f64,
    /// The rank sweep: (ranks, largest relative difference to this run, or the failure).
    pub ranks: Vec<(usize, std::result::Result<f64, String>)>,
}

/// One row: a point and what became of it.
#[derive(Debug, Clone)]
pub struct Row {
    pub case: String,
    pub group: String,
    pub variant: String,
    pub mass: String,
    pub ranks: usize,
    /// The time step of the point's scene.
    pub tau: f64,
    pub single_episode: bool,
    /// The case's own rank tolerance (`None`: the suite's).
    pub rank_tol: Option<f64>,
    pub file: String,
    pub result: std::result::Result<Done, String>,
}

/// The tolerances of the checks.
#[derive(Debug, Clone, Copy)]
pub struct Tolerances {
    pub rise: f64,
    pub penetration: f64,
    pub ranks: f64,
}

impl Tolerances {
    pub fn of(spec: &Spec) -> Tolerances {
        Tolerances { rise: spec.rise_tol, penetration: spec.penetration_tol, ranks: spec.rank_tol }
    }
}

fn modified(mass: &str) -> bool {
    mass.starts_with("modified")
}

impl Row {
    /// The checks this run fails: `error` (the run failed), `nan` (a non-finite value),
    /// `energy rise` (above E^0 + work by more than the tolerance), `penetration` (beyond the
    /// tolerance of the body size), `ranks` (another rank count differs or failed).
    pub fn failures(&self, tol: Tolerances) -> Vec<&'static str> {
        let d = match &self.result {
            Err(_) => return vec!["error"],
            Ok(d) => d,
        };
        let s = &d.stability;
        let mut out = Vec::new();
        if s.non_finite > 0 {
            out.push("nan");
        }
        // NaN fails too (a NaN rise or penetration is not within the tolerance).
        let within = |x: f64, tol: f64| x <= tol;
        if !within(s.energy_rise, tol.rise) {
            out.push("energy rise");
        }
        if !within(s.penetration, tol.penetration * s.body_size) {
            out.push("penetration");
        }
        let ranks = self.rank_tol.unwrap_or(tol.ranks);
        if d.ranks.iter().any(|(_, r)| !matches!(r, Ok(x) if *x <= ranks)) {
            out.push("ranks");
        }
        out
    }

    /// What is reported but not judged: `flicker` (more than one episode per node in an
    /// impact with the mass-free layer).
    pub fn flags(&self) -> Vec<&'static str> {
        let mut out = Vec::new();
        if let Ok(d) = &self.result {
            let kind = if self.mass.is_empty() { d.summary.mass_kind.as_str() } else { &self.mass };
            if modified(kind) && d.stability.episodes_per_impact_max > 1 {
                out.push("flicker");
            }
        }
        out
    }

    /// The constitutive model of the run: the finite-strain model of `[material]` as the
    /// run's effects line names it, `per body` when only `[[body]]` tables choose finite
    /// strain, else `linear` (empty for a failed run).
    pub fn model(&self) -> String {
        match &self.result {
            Ok(d) => model_of(&d.summary),
            Err(_) => String::new(),
        }
    }

    pub fn mass_kind(&self) -> String {
        match &self.result {
            Ok(d) if self.mass.is_empty() => d.summary.mass_kind.clone(),
            _ => self.mass.clone(),
        }
    }

    /// The stepping phase's wall time per step, ms (the program's own timing).
    pub fn stepping_ms(&self) -> Option<f64> {
        let m = &self.result.as_ref().ok()?.summary;
        (m.steps > 0).then(|| 1e3 * m.timings.stepping / m.steps as f64)
    }

    /// The cost of this run against the standard mass `M` (`consistent`) at the same case and
    /// variant: (KSP iterations per step, stepping time per step), each as a ratio to `M`'s
    /// run. `None` for `M` itself, when that run is missing or failed, or took no iterations.
    pub fn cost_to_m(&self, rows: &[Row]) -> Option<(f64, f64)> {
        let d = self.result.as_ref().ok()?;
        if self.mass_kind() == "consistent" {
            return None;
        }
        let m = rows.iter().find(|r| {
            r.case == self.case
                && r.variant == self.variant
                && r.ranks == self.ranks
                && r.mass_kind() == "consistent"
        })?;
        let dm = m.result.as_ref().ok()?;
        let its = dm.stability.ksp_iterations_mean;
        let time = m.stepping_ms()?;
        (its > 0.0 && time > 0.0).then(|| {
            (d.stability.ksp_iterations_mean / its, self.stepping_ms().unwrap_or(0.0) / time)
        })
    }

    /// The largest relative difference over the rank sweep (None: not swept).
    pub fn rank_diff(&self) -> Option<f64> {
        let d = self.result.as_ref().ok()?;
        if d.ranks.is_empty() {
            return None;
        }
        Some(d.ranks.iter().map(|(_, r)| *r.as_ref().unwrap_or(&f64::INFINITY)).fold(0.0, f64::max))
    }
}

/// The model a run's summary names ([`Row::model`]).
fn model_of(s: &RunSummary) -> String {
    let named = s.effects.split("elasticity (finite strain, ").nth(1);
    match named.and_then(|rest| rest.split(')').next()) {
        Some(m) => m.to_string(),
        None if s.newton.is_some() => "per body".into(),
        None => "linear".into(),
    }
}

fn e(x: f64) -> String {
    if x == 0.0 {
        "0".into()
    } else if x.is_nan() {
        "NaN".into()
    } else {
        format!("{x:.1e}")
    }
}

fn f2(x: f64) -> String {
    format!("{x:.2}")
}

/// The CSV columns (one line per run; the tests read them by name).
pub const CSV_COLUMNS: [&str; 42] = [
    "case",
    "group",
    "variant",
    "model",
    "mass",
    "ranks",
    "dofs",
    "steps",
    "tau",
    "cfl",
    "status",
    "failed_checks",
    "flags",
    "single_episode",
    "energy_initial",
    "energy_ref",
    "energy_rise",
    "energy_loss",
    "energy_drift",
    "impacts",
    "loss_per_impact",
    "contact_steps",
    "penetration",
    "penetration_rel",
    "force_max",
    "pressure_osc2",
    "pressure_tv_index",
    "force_osc2",
    "force_tv_index",
    "episodes_per_impact_max",
    "episodes_per_impact_mean",
    "pdas_mean",
    "pdas_max",
    "ksp_mean",
    "ksp_max",
    "non_finite",
    "rank_diff",
    "wall_s",
    "stepping_ms_per_step",
    "ksp_ratio_to_m",
    "time_ratio_to_m",
    "file",
];

fn quote(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn csv(rows: &[Row], tol: Tolerances) -> String {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for r in rows {
        let fails = r.failures(tol);
        let status = if fails.is_empty() { "pass" } else { "fail" };
        let mut f: Vec<String> = vec![
            r.case.clone(),
            r.group.clone(),
            r.variant.clone(),
            r.model(),
            r.mass_kind(),
            r.ranks.to_string(),
        ];
        match &r.result {
            Ok(d) => {
                let s = &d.stability;
                let m = &d.summary;
                f.extend([
                    m.n_dofs.to_string(),
                    m.steps.to_string(),
                    format!("{:e}", r.tau),
                    format!("{:e}", m.cfl),
                    status.into(),
                    fails.join(" "),
                    r.flags().join(" "),
                    r.single_episode.to_string(),
                    format!("{:e}", s.energy_initial),
                    format!("{:e}", s.energy_ref),
                    format!("{:e}", s.energy_rise),
                    format!("{:e}", s.energy_loss),
                    format!("{:e}", s.energy_drift),
                    s.impacts.to_string(),
                    format!("{:e}", s.loss_per_impact),
                    s.contact_steps.to_string(),
                    format!("{:e}", s.penetration),
                    format!("{:e}", s.penetration / s.body_size.max(f64::MIN_POSITIVE)),
                    format!("{:e}", s.force_max),
                    format!("{:e}", s.pressure_osc2),
                    format!("{:e}", s.pressure_tv_index),
                    format!("{:e}", s.force_osc2),
                    format!("{:e}", s.force_tv_index),
                    s.episodes_per_impact_max.to_string(),
                    format!("{:e}", s.episodes_per_impact_mean),
                    format!("{:e}", s.pdas_iterations_mean),
                    s.pdas_iterations_max.to_string(),
                    format!("{:e}", s.ksp_iterations_mean),
                    s.ksp_iterations_max.to_string(),
                    s.non_finite.to_string(),
                    r.rank_diff().map(|x| format!("{x:e}")).unwrap_or_default(),
                    format!("{:.3}", d.process_s),
                    r.stepping_ms().map(|x| format!("{x:e}")).unwrap_or_default(),
                ]);
                let cost = r.cost_to_m(rows);
                f.push(cost.map(|c| format!("{:e}", c.0)).unwrap_or_default());
                f.push(cost.map(|c| format!("{:e}", c.1)).unwrap_or_default());
            }
            Err(msg) => {
                f.extend(["".into(), "".into(), "".into(), "".into(), "error".into()]);
                f.push(format!("error: {msg}"));
                f.extend(std::iter::repeat_n(String::new(), CSV_COLUMNS.len() - 13));
            }
        }
        f.push(r.file.clone());
        debug_assert_eq!(f.len(), CSV_COLUMNS.len());
        out.push_str(&f.iter().map(|x| quote(x)).collect::<Vec<_>>().join(","));
        out.push('\n');
    }
    out
}

/// One Markdown table of all runs, grouped by case.
pub fn markdown(rows: &[Row], tol: Tolerances) -> String {
    let mut out = String::new();
    out.push_str(
        "| case | variant | model | mass | DOFs | steps | CFL | status | energy rise | loss | impacts | loss / impact | penetration / size | osc2 p | TV p | osc2 F | TV F | episodes / impact max (mean) | PDAS mean / max | KSP mean / max | rank diff | wall s | stepping ms/step | KSP its, time vs M |\n",
    );
    out.push_str(&"|---".repeat(24));
    out.push_str("|\n");
    for r in rows {
        let fails = r.failures(tol);
        let flags = r.flags();
        let mut status = if fails.is_empty() {
            "pass".to_string()
        } else {
            format!("**FAIL** ({})", fails.join(", "))
        };
        if !flags.is_empty() {
            status.push_str(&format!(" [{}]", flags.join(", ")));
        }
        let head = format!("| {} | {} | {} | {} ", r.case, r.variant, r.model(), r.mass_kind());
        match &r.result {
            Ok(d) => {
                let s = &d.stability;
                let m = &d.summary;
                out.push_str(&format!(
                    "{head}| {} | {} | {} | {status} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} ({}) | {} / {} | {} / {} | {} | {:.1} | {} | {} |\n",
                    m.n_dofs,
                    m.steps,
                    cfl(m.cfl),
                    e(s.energy_rise),
                    e(s.energy_loss),
                    s.impacts,
                    e(s.loss_per_impact),
                    e(s.penetration / s.body_size.max(f64::MIN_POSITIVE)),
                    e(s.pressure_osc2),
                    f2(s.pressure_tv_index),
                    e(s.force_osc2),
                    f2(s.force_tv_index),
                    s.episodes_per_impact_max,
                    f2(s.episodes_per_impact_mean),
                    f2(s.pdas_iterations_mean),
                    s.pdas_iterations_max,
                    f2(s.ksp_iterations_mean),
                    s.ksp_iterations_max,
                    r.rank_diff().map(e).unwrap_or_else(|| "-".into()),
                    d.process_s,
                    r.stepping_ms().map(|x| format!("{x:.2}")).unwrap_or_else(|| "-".into()),
                    r.cost_to_m(rows)
                        .map(|(i, t)| format!("{i:.2}, {t:.2}"))
                        .unwrap_or_else(|| "-".into()),
                ));
            }
            Err(msg) => {
                out.push_str(&format!(
                    "{head}| | | | **FAIL** (error: {}) |{}\n",
                    msg.replace('|', "/"),
                    " |".repeat(16)
                ));
            }
        }
    }
    out
}

fn cfl(x: f64) -> String {
    if x >= 10.0 {
        format!("{x:.0}")
    } else if x >= 1.0 {
        format!("{x:.1}")
    } else {
        format!("{x:.2}")
    }
}

/// One line per case: its runs, failures and the extremes of the metrics over its runs.
pub fn case_summary(rows: &[Row], tol: Tolerances) -> String {
    let mut out = String::from(
        "| group | case | model | runs | failed | largest energy rise | largest loss / impact (mass) | largest penetration / size | osc2 F: M, lumped / M_H (largest) | episodes / impact max: M, lumped / M_H | flicker (M_H runs) | rank diff | wall s | cost M_H / M: KSP its (time), largest |\n",
    );
    out.push_str(&"|---".repeat(14));
    out.push_str("|\n");
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.case.as_str()) {
            names.push(&r.case);
        }
    }
    for name in names {
        let rs: Vec<&Row> = rows.iter().filter(|r| r.case == name).collect();
        let done: Vec<(&Row, &Done)> =
            rs.iter().filter_map(|r| r.result.as_ref().ok().map(|d| (*r, d))).collect();
        let failed = rs.iter().filter(|r| !r.failures(tol).is_empty()).count();
        let max = |f: &dyn Fn(&Done) -> f64| done.iter().map(|(_, d)| f(d)).fold(0.0, f64::max);
        let loss = done
            .iter()
            .max_by(|a, b| a.1.stability.loss_per_impact.total_cmp(&b.1.stability.loss_per_impact))
            .map(|(r, d)| format!("{} ({})", e(d.stability.loss_per_impact), r.mass_kind()))
            .unwrap_or_default();
        let split = |f: &dyn Fn(&Done) -> f64, m: bool| -> Option<f64> {
            let v: Vec<f64> = done
                .iter()
                .filter(|(r, _)| modified(&r.mass_kind()) == m)
                .map(|(_, d)| f(d))
                .collect();
            (!v.is_empty()).then(|| v.iter().copied().fold(0.0, f64::max))
        };
        let pair = |f: &dyn Fn(&Done) -> f64, fmt: &dyn Fn(f64) -> String| {
            let a = split(f, false).map(fmt).unwrap_or_else(|| "-".into());
            let b = split(f, true).map(fmt).unwrap_or_else(|| "-".into());
            format!("{a} / {b}")
        };
        let flicker = rs.iter().filter(|r| r.flags().contains(&"flicker")).count();
        let n_mh = rs.iter().filter(|r| modified(&r.mass_kind())).count();
        let ranks = rs
            .iter()
            .filter_map(|r| r.rank_diff())
            .fold(None, |a: Option<f64>, b| Some(a.map_or(b, |a| a.max(b))));
        let wall: f64 = done.iter().map(|(_, d)| d.process_s).sum();
        let mut models: Vec<String> = Vec::new();
        for (r, _) in &done {
            if !models.contains(&r.model()) {
                models.push(r.model());
            }
        }
        let costs: Vec<(f64, f64)> = rs.iter().filter_map(|r| r.cost_to_m(rows)).collect();
        let cost = if costs.is_empty() {
            "-".to_string()
        } else {
            let its = costs.iter().map(|c| c.0).fold(0.0, f64::max);
            let time = costs.iter().map(|c| c.1).fold(0.0, f64::max);
            format!("{its:.2} ({time:.2})")
        };
        out.push_str(&format!(
            "| {} | {name} | {} | {} | {} | {} | {loss} | {} | {} | {} | {} | {} | {:.0} | {cost} |\n",
            rs[0].group,
            if models.is_empty() { "-".to_string() } else { models.join(", ") },
            rs.len(),
            if failed == 0 { "0".to_string() } else { format!("**{failed}**") },
            e(max(&|d| d.stability.energy_rise)),
            e(max(&|d| d.stability.penetration / d.stability.body_size.max(f64::MIN_POSITIVE))),
            pair(&|d| d.stability.force_osc2, &e),
            pair(&|d| d.stability.episodes_per_impact_max as f64, &|x| format!("{x:.0}")),
            if n_mh == 0 { "-".to_string() } else { format!("{flicker} of {n_mh}") },
            ranks.map(e).unwrap_or_else(|| "-".into()),
            wall,
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(case: &str, variant: &str, mass: &str, ksp_mean: f64, stepping: f64) -> Row {
        let mut summary = RunSummary::example();
        summary.timings.stepping = stepping;
        let stability = Stability { ksp_iterations_mean: ksp_mean, ..Default::default() };
        Row {
            case: case.into(),
            group: "g".into(),
            variant: variant.into(),
            mass: mass.into(),
            ranks: 2,
            tau: 1e-3,
            single_episode: true,
            rank_tol: None,
            file: String::new(),
            result: Ok(Done { summary, stability, process_s: 1.0, ranks: Vec::new() }),
        }
    }

    /// Each `M_H` run is compared with `M`'s run of its own case and variant, never another's.
    #[test]
    fn the_cost_of_m_h_is_a_ratio_to_m_at_the_same_point() {
        let rows = vec![
            run("a", "v=1", "consistent", 10.0, 0.3),
            run("a", "v=1", "modified0", 12.0, 0.45),
            run("a", "v=2", "consistent", 20.0, 0.6),
            run("a", "v=2", "modified1", 21.0, 0.6),
            run("b", "v=1", "modified0", 5.0, 0.1),
        ];
        let close =
            |a: (f64, f64), b: (f64, f64)| (a.0 - b.0).abs() < 1e-15 && (a.1 - b.1).abs() < 1e-15;
        assert!(close(rows[1].cost_to_m(&rows).unwrap(), (1.2, 1.5)));
        assert!(close(rows[3].cost_to_m(&rows).unwrap(), (1.05, 1.0)));
        assert_eq!(rows[0].cost_to_m(&rows), None, "M against itself");
        assert_eq!(rows[4].cost_to_m(&rows), None, "no M at that point");
        // The stepping time per step: 0.3 s over the example's 30 steps.
        assert!((rows[0].stepping_ms().unwrap() - 10.0).abs() < 1e-12);
        let tol = Tolerances { rise: 1e-6, penetration: 1e-8, ranks: 1e-8 };
        let table = case_summary(&rows, tol);
        let line = table.lines().find(|l| l.contains("| a |")).unwrap();
        assert!(line.ends_with("| 1.20 (1.50) |"), "{line}");
        assert!(table.lines().find(|l| l.contains("| b |")).unwrap().ends_with("| - |"));
        let csv = csv(&rows, tol);
        let second = csv.lines().nth(2).unwrap();
        assert!(second.contains(",1.2e0,1.5e0,"), "{second}");
    }
}
