//! The model and amplitude axes of a study: when is small strain good enough, and what does
//! finite strain cost.
//!
//! `sweep.model` runs every point with each material model (`run --model`), `sweep.amplitude`
//! with each amplitude put into the scene keys of `amplitude_set` (the suite's `set`
//! substitution, [`crate::suite::spec::value`]). With `reference = { model = M }` every row is
//! compared with the run of model `M` at the same point otherwise (amplitude, h, tau, mass
//! kind, solver): the contact histories as against any reference run ([`super::reference`]),
//! the final displacement field ([`super::fieldnorm`]) and the stepping time (`time_ratio`). The
//! plots `difference_amplitude.png` and `cost_amplitude.png` show both against the amplitude.

use std::path::{Path, PathBuf};

use toml::{Table, Value};

use super::spec::Study;
use super::table::Row;
use super::{fieldnorm, reference, Point};
use crate::error::{Error, Result};
use crate::post::plot::{loglog_plot, Plot, Series};
use crate::scene;

/// The scene text of a point with its amplitude put into `amplitude_set`'s keys (`text`
/// unchanged without an amplitude). The result is parsed once, so that a template giving an
/// impossible scene is the point's one-line error rather than a failed run.
pub(super) fn with_amplitude(
    study: &Study,
    amplitude: Option<f64>,
    text: String,
) -> Result<String> {
    let Some(a) = amplitude else { return Ok(text) };
    let shown = study.scene_path.display();
    let err = |m: String| Error::Scene(format!("{shown}: amplitude = {a}: {m}"));
    let mut t: Table = text
        .parse()
        .map_err(|e: toml::de::Error| err(format!("invalid TOML: {}", e.message().trim())))?;
    let vars = [("amplitude".to_string(), a)];
    for (k, v) in &study.amplitude_set {
        let v = crate::suite::spec::value(k, v, &vars)
            .map_err(|m| err(format!("amplitude_set.{k}: {m}")))?;
        set_key(&mut t, k, v).map_err(&err)?;
    }
    let text = toml::to_string(&t).map_err(|e| err(format!("cannot write the scene: {e}")))?;
    let dir = study.scene_path.parent().unwrap_or(Path::new("."));
    scene::parse(&text, &study.scene.name, dir)?;
    Ok(text)
}

/// Puts `v` at the dotted path `key` of the scene table, creating tables on the way.
fn set_key(t: &mut Table, key: &str, v: Value) -> std::result::Result<(), String> {
    let path: Vec<&str> = key.split('.').collect();
    let Some((last, tables)) = path.split_last() else { return Ok(()) };
    let mut at = t;
    for part in tables {
        let entry = at.entry(part.to_string()).or_insert_with(|| Value::Table(Table::new()));
        at = entry
            .as_table_mut()
            .ok_or_else(|| format!("amplitude_set.{key}: {part} is no table of the scene"))?;
    }
    at.insert(last.to_string(), v);
    Ok(())
}

/// The paragraph's sentence on the errors against the model `m`.
pub(super) fn describe(study: &Study, m: &str, contact_errors: &str) -> String {
    let what = if study.has_contact() {
        format!("{contact_errors} against the {m} run")
    } else {
        format!(
            "error = relative L2 difference of the displacement at the error time to the {m} run"
        )
    };
    format!(
        "{what} of the same amplitude, mesh, time step, mass kind and solver (reference row); \
         err_u = relative L2 difference of the final displacement to it, time_ratio = the \
         stepping time over its stepping time (what the model costs, without mesh and set-up)"
    )
}

/// Whether two points differ only in the material model.
fn same_but_model(a: &Point, b: &Point) -> bool {
    a.h.map(f64::to_bits) == b.h.map(f64::to_bits)
        && a.tau.to_bits() == b.tau.to_bits()
        && a.steps == b.steps
        && a.mass == b.mass
        && a.solver == b.solver
        && a.amplitude.map(f64::to_bits) == b.amplitude.map(f64::to_bits)
}

/// Fills err_l2, err_force (contact scenes), err_u and time_ratio of one part's rows against
/// the run of `model` at the same point otherwise (`rows[i]` belongs to `points[i]`).
pub(super) fn compute_errors(
    study: &Study,
    model: &str,
    points: &[Point],
    rows: &mut [Row],
    runs: &Path,
) {
    let h5 = |p: &Point| runs.join(format!("{}.h5", p.id));
    for i in 0..points.len() {
        let Some(f) = (0..points.len()).find(|&j| {
            points[j].model.as_deref() == Some(model) && same_but_model(&points[i], &points[j])
        }) else {
            continue;
        };
        if !rows[i].ok() {
            continue;
        }
        if !rows[f].ok() {
            rows[i].failure =
                Some(format!("no reference: the {model} run ({}) failed", points[f].label));
            continue;
        }
        // The stepping time: where the models differ (meshing and set-up are the same).
        let time = |r: &Row| r.measured.as_ref().map_or(f64::NAN, |m| m.stepping_s);
        rows[i].time_ratio = Some(time(&rows[i]) / time(&rows[f]));
        if i == f {
            let r = &mut rows[i];
            r.is_reference = true;
            r.err_l2 = Some(0.0);
            r.err_u = Some(0.0);
            if study.has_contact() {
                r.err_force = Some(0.0);
            }
            continue;
        }
        let (p, rp) = (&points[i], &points[f]);
        let compare = || -> Result<(f64, Option<f64>, f64)> {
            let t = p.steps as f64 * p.tau;
            let (u, _) = fieldnorm::relative_errors(
                &fieldnorm::read(&h5(p), t)?,
                &fieldnorm::read(&h5(rp), t)?,
            )?;
            if study.has_contact() {
                let run = reference::read_contact(&h5(p))?;
                let refr = reference::read_contact(&h5(rp))?;
                let (pressure, force) = reference::contact_errors(&run, &refr)?;
                Ok((pressure, Some(force), u))
            } else {
                let t = p.error_step as f64 * p.tau;
                let (l2, _) = fieldnorm::relative_errors(
                    &fieldnorm::read(&h5(p), t)?,
                    &fieldnorm::read(&h5(rp), t)?,
                )?;
                Ok((l2, None, u))
            }
        };
        match compare() {
            Ok((l2, force, u)) => {
                let r = &mut rows[i];
                r.err_l2 = Some(l2);
                r.err_force = force;
                r.err_u = Some(u);
            }
            Err(e) => rows[i].failure = Some(format!("error against the {model} run: {e}")),
        }
    }
}

/// What a row is besides its model and amplitude, when the part sweeps more than those
/// (one curve each): "mass=modified1, h=0.1".
fn setting(study: &Study, r: &Row) -> String {
    let mut parts = Vec::new();
    if study.mass.len() > 1 {
        parts.push(format!("mass={}", r.mass));
    }
    if study.solver.len() > 1 {
        parts.push(format!("solver={}", r.solver));
    }
    if study.h.len() > 1 {
        parts.push(format!(
            "{}={}",
            study.mesh_param,
            r.h.map(super::table::show_h).unwrap_or_default()
        ));
    }
    if study.tau.len() > 1 {
        parts.push(format!("tau={}", super::table::show_tau(r.tau)));
    }
    parts.join(", ")
}

/// A curve name's tail and the row's value it draws.
type Measure = (&'static str, fn(&Row) -> Option<f64>);

/// Adds the point `(amplitude, y)` to the series `name` (created on first use).
fn push(series: &mut Vec<Series>, name: String, pt: (f64, f64)) {
    match series.iter_mut().find(|s| s.name == name) {
        Some(s) => s.points.push(pt),
        None => series.push(Series { name, points: vec![pt] }),
    }
}

/// `PREFIXdifference_amplitude.png` (the differences to the reference model against the
/// amplitude, one curve per other model and measure, slope 1 for reference) and
/// `PREFIXcost_amplitude.png` (run time against amplitude, one curve per model), for a part
/// that sweeps two or more amplitudes and models.
pub(super) fn plots(study: &Study, rows: &[Row], prefix: &str) -> Result<Vec<PathBuf>> {
    if study.amplitude.len() < 2 || study.model.is_empty() {
        return Ok(Vec::new());
    }
    let mut files = Vec::new();
    let named = |r: &Row, what: &str| {
        let s = setting(study, r);
        let s = if s.is_empty() { s } else { format!(" ({s})") };
        format!("{}{s}{what}", r.model)
    };
    let ok: Vec<&Row> = rows.iter().filter(|r| r.ok() && r.amplitude.is_some()).collect();
    if let super::spec::Reference::Model(m) = &study.reference {
        let mut series = Vec::new();
        let measures: [Measure; 3] = [
            (": total contact force", |r| r.err_force),
            (": lowest node's pressure", |r| if r.err_force.is_some() { r.err_l2 } else { None }),
            (": final displacement", |r| r.err_u),
        ];
        for (what, get) in measures {
            for r in ok.iter().filter(|r| !r.is_reference) {
                if let (Some(a), Some(e)) = (r.amplitude, get(r)) {
                    if e > 0.0 && e.is_finite() {
                        push(&mut series, named(r, what), (a, e));
                    }
                }
            }
        }
        let path = study.output.join(format!("{prefix}difference_amplitude.png"));
        let title = format!("{}: difference to {m} against amplitude", study.title);
        amplitude_plot(&path, &title, "relative L2 difference", series, &[1.0])?;
        files.push(path);
    }
    let mut series = Vec::new();
    for r in &ok {
        if let (Some(a), Some(m)) = (r.amplitude, &r.measured) {
            push(&mut series, named(r, ""), (a, m.stepping_s));
        }
    }
    let path = study.output.join(format!("{prefix}cost_amplitude.png"));
    let title = format!("{}: stepping time against amplitude", study.title);
    amplitude_plot(&path, &title, "stepping time (s, median)", series, &[])?;
    files.push(path);
    Ok(files)
}

/// One log-log picture against the amplitude (`slopes`: reference slopes drawn dashed).
fn amplitude_plot(
    path: &Path,
    title: &str,
    y_label: &str,
    series: Vec<Series>,
    slopes: &[f64],
) -> Result<()> {
    let plot = Plot {
        title,
        x_label: "amplitude",
        y_label,
        series: &sorted(series),
        width: 900,
        height: 650,
    };
    loglog_plot(path, &plot, slopes)
}

fn sorted(mut series: Vec<Series>) -> Vec<Series> {
    for s in &mut series {
        s.points.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
    series
}

#[cfg(test)]
mod tests {
    use super::super::spec::{self, Reference};
    use super::*;

    fn file() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("studies/test.toml")
    }

    const DISC: &str = r#"
scene = "../scenes/suite/disc_impact.toml"
mesh_param = "hc"
params = { h = 0.4 }
steps = 20
reference = { model = "neo_hookean" }
amplitude_set = { "initial.velocity" = ["0", "-11.6024 * {amplitude}"] }
[sweep]
h = [0.1]
model = ["linear", "neo_hookean"]
amplitude = [0.01, 0.1]
"#;

    fn parse(text: &str) -> std::result::Result<Study, String> {
        spec::parse(&file(), text).map_err(|e| e.to_string())
    }

    #[test]
    fn the_model_and_amplitude_keys_parse() {
        let s = parse(DISC).unwrap();
        assert_eq!(s.model, vec!["linear", "neo_hookean"]);
        assert_eq!(s.amplitude, vec![0.01, 0.1]);
        assert_eq!(s.reference, Reference::Model("neo_hookean".into()));
        assert_eq!(s.amplitude_set.len(), 1);
        assert_eq!(s.amplitude_set[0].0, "initial.velocity");
        // Every model once, every amplitude once, grouped so that a group holds one of each.
        let points = super::super::grid(&s).unwrap();
        let labels: Vec<&str> = points.iter().map(|p| p.label.as_str()).collect();
        assert_eq!(
            labels,
            vec![
                "hc=1/10 model=linear amplitude=0.01",
                "hc=1/10 model=linear amplitude=0.1",
                "hc=1/10 model=neo_hookean amplitude=0.01",
                "hc=1/10 model=neo_hookean amplitude=0.1",
            ]
        );
        let mut groups: Vec<usize> = points.iter().map(|p| p.group).collect();
        groups.dedup();
        assert_eq!(groups.len(), 4);
        assert!(same_but_model(&points[0], &points[2]) && !same_but_model(&points[0], &points[1]));
        // The amplitude reaches the scene: -11.6024 * (0.1).
        let text = with_amplitude(&s, Some(0.1), s.scene.variant_text().unwrap()).unwrap();
        let t: Table = text.parse().unwrap();
        assert_eq!(
            t["initial"]["velocity"],
            Value::Array(vec![Value::String("0".into()), Value::String("-11.6024 * (0.1)".into())])
        );
        let parsed = scene::parse(&text, "x", Path::new(".")).unwrap();
        assert_eq!(parsed.steps, s.scene.steps);
        // Without amplitudes the text stays.
        assert_eq!(with_amplitude(&s, None, "x".into()).unwrap(), "x");
    }

    #[test]
    fn bad_model_and_amplitude_keys_are_one_line_errors_naming_the_key() {
        let cases = [
            (
                DISC.replace("model = \"neo_hookean\" }", "model = \"saint_venant_kirchhoff\" }"),
                "reference.model",
            ),
            (DISC.replace("amplitude_set = {", "# {"), "sweep.amplitude needs amplitude_set"),
            (
                DISC.replace("amplitude = [0.01, 0.1]", ""),
                "amplitude_set.initial.velocity is set but there is no sweep.amplitude",
            ),
            (DISC.replace("{amplitude}\"]", "{v/c}\"]"), "amplitude_set.initial.velocity"),
            (DISC.replace("\"linear\", ", "\"hooke\", "), "sweep.model"),
            (
                DISC.replace("\"linear\", ", "\"neo_hookean\", "),
                "sweep.model lists neo_hookean twice",
            ),
            (
                DISC.replace("amplitude = [0.01, 0.1]", "amplitude = [0.01, -0.1]"),
                "sweep.amplitude",
            ),
            (DISC.replace("reference = { model", "reference = { modle"), "reference.modle"),
        ];
        for (text, key) in cases {
            let e = parse(&text).unwrap_err();
            assert_eq!(e.lines().count(), 1, "{e}");
            assert!(e.contains(key), "{e} does not name {key}");
        }
        // The placeholder error names the culprit.
        let e = parse(&DISC.replace("{amplitude}\"]", "{v/c}\"]")).unwrap_err();
        assert!(e.contains("{v/c}"), "{e}");
    }
}
