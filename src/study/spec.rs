//! The study file: schema, validation (one-line errors naming the key, unknown keys denied)
//! and what the study needs to know about its scene.
//!
//! ```toml
//! scene = "../scenes/beam.toml"      # required, relative to the study file
//! output = "out/study-beam"          # folder, relative to the current directory
//!                                    # (default out/study-<study file stem>)
//! title = "beam, space"              # optional, default the study file stem
//! ranks = 2                          # MPI ranks per run (default 2)
//! repeat = 3                         # runs per point; the median time is reported (default 1)
//! mesh_param = "h"                   # the .geo parameter that sweep.h sets (default "h")
//! params = { gap = 0.05 }            # fixed --param values for every run
//! steps = 250                        # override the scene's steps (not with sweep.tau)
//! error_step = 250                   # step of the errors (default: the last); not with sweep.tau
//! end_time = 0.8                     # with sweep.tau: steps = end_time / tau, errors at the end
//! reference = "exact"                # "exact" (default with [exact]), "finest" (default
//!                                    # otherwise), { file = "run.h5" } or { mass = "consistent" }
//! scaled = { h = 5.0 }               # params that follow the mesh parameter: h = 5 x hc
//! [sweep]                            # every key optional; the grid is the product
//! h = [0.25, 0.125, 0.0625]          # values of the mesh parameter
//! mass = ["consistent", "modified1"] # consistent | lumped | modified0 | modified1
//! tau = [4e-3, 2e-3, 1e-3]           # time steps (needs end_time)
//! solver = [                         # PETSc option lists, optionally labelled
//!   ["-ksp_type", "cg", "-pc_type", "jacobi"],
//!   { label = "gamg", options = ["-ksp_type", "cg", "-pc_type", "gamg"] },
//! ]
//! skip = [{ h = 0.04, tau = 0.005 }] # points of the product not run (all given keys match)
//! model = ["linear", "neo_hookean"]  # material models (linear | neo_hookean |
//!                                    # saint_venant_kirchhoff), as `run --model`
//! amplitude = [0.01, 0.1]            # values put for {amplitude} into amplitude_set
//! ```
//!
//! With `sweep.amplitude` the study (or part) sets scene keys from templates, as the suite's
//! `set` does: `amplitude_set = { "initial.velocity" = ["0", "-11.6024 * {amplitude}"] }`;
//! `reference = { model = "neo_hookean" }` compares every row with the run of that model at
//! the same point otherwise (`models`).
//!
//! Several scenes in one study: a list of parts, each a study of its own (the keys above but
//! `output` and `title`; `name` names the part), sharing `ranks`, `repeat` and `reference`
//! given at the top (a part may override them). The parts' rows go into one table and their
//! error-against-time curves into one plot:
//!
//! ```toml
//! title = "contact"
//! output = "out/study-contact"
//! reference = { mass = "consistent" }
//! [[part]]
//! name = "disc (2D)"
//! scene = "../scenes/disc.toml"
//! ...
//! [[part]]
//! name = "ball (3D)"
//! ...
//! ```

use std::path::{Path, PathBuf};

use toml::{Table, Value};

use crate::error::{Error, Result};
use crate::scene::{self, MassKind, MeshSource, Model, Scene};

/// What the errors of a run are measured against.
#[derive(Debug, Clone, PartialEq)]
pub enum Reference {
    /// The scene's exact solution (errors computed by the run itself).
    Exact,
    /// The finest run of each group (same mass kind and solver): smallest h, smallest tau.
    Finest,
    /// A given HDF5 file of an earlier run.
    File(PathBuf),
    /// One reference for every row of the study (of the part): the finest run of this mass
    /// kind (smallest h, then smallest tau), so that all kinds are measured against the same
    /// approximation of the solution.
    Mass(String),
    /// Every row against the run of this material model at the same point otherwise (same
    /// amplitude, h, tau, mass kind and solver): what the other models change (`models`).
    Model(String),
}

/// One PETSc option list of `sweep.solver`.
#[derive(Debug, Clone, PartialEq)]
pub struct Solver {
    pub label: String,
    pub options: Vec<String>,
}

/// A study file: one study, or several parts (one scene each) reported together.
#[derive(Debug, Clone)]
pub struct StudySet {
    pub file: PathBuf,
    pub title: String,
    pub output: PathBuf,
    /// One study per part; a file without `[[part]]` is one part.
    pub parts: Vec<Study>,
    /// Whether the file lists parts (`[[part]]`).
    pub multi: bool,
}

/// A point of the product grid that is not run (`sweep.skip`): every given value matches.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Skip {
    pub h: Option<f64>,
    pub tau: Option<f64>,
    pub mass: Option<String>,
}

impl Skip {
    /// Whether the point (h, tau, mass) is skipped (values equal within 1e-9 relative).
    pub fn matches(&self, h: Option<f64>, tau: f64, mass: Option<&str>) -> bool {
        let near = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs());
        self.h.is_none_or(|x| h.is_some_and(|y| near(x, y)))
            && self.tau.is_none_or(|x| near(x, tau))
            && self.mass.as_deref().is_none_or(|m| mass == Some(m))
    }
}

#[derive(Debug, Clone)]
pub struct Study {
    pub file: PathBuf,
    pub title: String,
    pub scene_path: PathBuf,
    /// The scene as loaded; every point runs a variant of it (typed overrides).
    pub scene: Scene,
    /// The mesh parameter's value in the scene (when it sets it).
    pub h_default: Option<f64>,
    pub output: PathBuf,
    pub ranks: usize,
    pub repeat: usize,
    pub mesh_param: String,
    pub params: Vec<(String, f64)>,
    /// Parameters set to a factor times the swept mesh parameter (`scaled`).
    pub scaled: Vec<(String, f64)>,
    pub steps: Option<usize>,
    pub error_step: Option<usize>,
    pub end_time: Option<f64>,
    pub reference: Reference,
    pub h: Vec<f64>,
    pub mass: Vec<String>,
    pub tau: Vec<f64>,
    pub solver: Vec<Solver>,
    pub skip: Vec<Skip>,
    /// Material models of `sweep.model` (names as `run --model` takes them).
    pub model: Vec<String>,
    /// Values of `sweep.amplitude`, put for `{amplitude}` into `amplitude_set`.
    pub amplitude: Vec<f64>,
    /// Scene keys (dotted paths) and their templates in `{amplitude}` (`amplitude_set`).
    pub amplitude_set: Vec<(String, Value)>,
}

impl Study {
    pub fn has_contact(&self) -> bool {
        self.scene.contact.is_some()
    }
}

const TOP_KEYS: [&str; 16] = [
    "scene",
    "output",
    "title",
    "ranks",
    "repeat",
    "mesh_param",
    "params",
    "steps",
    "error_step",
    "end_time",
    "reference",
    "sweep",
    "description",
    "scaled",
    "amplitude_set",
    "part",
];
const SWEEP_KEYS: [&str; 7] = ["h", "mass", "tau", "solver", "skip", "model", "amplitude"];
/// The top of a file with parts: what the parts share.
const SET_KEYS: [&str; 7] =
    ["title", "output", "description", "ranks", "repeat", "reference", "part"];
/// Shared keys a part inherits unless it sets them.
const INHERITED: [&str; 3] = ["ranks", "repeat", "reference"];

/// Reads and validates a study file (one study or parts).
pub fn load(path: &Path) -> Result<StudySet> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::Usage(format!("study {}: cannot read: {e}", path.display())))?;
    parse_set(path, &text)
}

/// Validates the text of a study file with or without `[[part]]`.
pub fn parse_set(path: &Path, text: &str) -> Result<StudySet> {
    let shown = path.display().to_string();
    let bad = |m: String| Error::Usage(format!("study {shown}: {m}"));
    let table: Table = text.parse().map_err(|e: toml::de::Error| {
        bad(format!("not valid TOML: {}", e.message().lines().next().unwrap_or("")))
    })?;
    let Some(parts) = table.get("part") else {
        let study = parse_table(path, &table, None)?;
        return Ok(StudySet {
            file: path.to_path_buf(),
            title: study.title.clone(),
            output: study.output.clone(),
            parts: vec![study],
            multi: false,
        });
    };
    check_keys(&table, "", &SET_KEYS).map_err(&bad)?;
    let Value::Array(list) = parts else {
        return Err(bad(format!(
            "part = {parts} is impossible: a list of tables [[part]] is expected"
        )));
    };
    if list.is_empty() {
        return Err(bad("part is empty".into()));
    }
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let output = get_str(&table, "output")
        .map_err(&bad)?
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(format!("out/study-{stem}")));
    let title = get_str(&table, "title").map_err(&bad)?.unwrap_or_else(|| stem.clone());
    get_str(&table, "description").map_err(&bad)?;
    let mut studies: Vec<Study> = Vec::new();
    for (i, p) in list.iter().enumerate() {
        let Value::Table(pt) = p else {
            return Err(bad(format!("part[{i}] = {p} is impossible: a table is expected")));
        };
        let name = match pt.get("name") {
            Some(Value::String(s)) if !s.trim().is_empty() => s.clone(),
            Some(v) => {
                return Err(bad(format!("part[{i}].name = {v} is impossible: a name is expected")))
            }
            None => return Err(bad(format!("part[{i}].name: missing (the part's name)"))),
        };
        if studies.iter().any(|s| s.title == name) {
            return Err(bad(format!("part[{i}].name = {name:?}: two parts have this name")));
        }
        let mut merged = Table::new();
        for k in INHERITED {
            if let Some(v) = table.get(k) {
                merged.insert(k.to_string(), v.clone());
            }
        }
        for (k, v) in pt {
            match k.as_str() {
                "name" => {}
                "output" | "title" | "part" => {
                    return Err(bad(format!(
                        "unknown key part[{i}].{k} (a part has no {k}: the file's top sets it)"
                    )))
                }
                _ => {
                    merged.insert(k.clone(), v.clone());
                }
            }
        }
        let mut study = parse_table(path, &merged, Some(&format!("part[{i}] ({name})")))?;
        study.title = name;
        study.output = output.clone();
        studies.push(study);
    }
    Ok(StudySet { file: path.to_path_buf(), title, output, parts: studies, multi: true })
}

/// Validates the text of a single-scene study file (`path` names it in errors and anchors
/// `scene`).
pub fn parse(path: &Path, text: &str) -> Result<Study> {
    let set = parse_set(path, text)?;
    if set.multi {
        return Err(Error::Usage(format!(
            "study {}: a file with parts where one study was expected",
            path.display()
        )));
    }
    Ok(set.parts.into_iter().next().expect("one part"))
}

/// Validates one study's table; `part` names the part in errors (files with parts).
fn parse_table(path: &Path, table: &Table, part: Option<&str>) -> Result<Study> {
    let shown = match part {
        Some(p) => format!("{}: {p}", path.display()),
        None => path.display().to_string(),
    };
    let bad = |m: String| Error::Usage(format!("study {shown}: {m}"));
    check_keys(table, "", &TOP_KEYS[..TOP_KEYS.len() - 1]).map_err(&bad)?;

    let table = table.clone();
    let scene_rel = get_str(&table, "scene")
        .map_err(&bad)?
        .ok_or_else(|| bad("scene: missing (the scene file, relative to the study file)".into()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let scene_path = base.join(&scene_rel);
    let scene = scene::load(&scene_path).map_err(|e| {
        let m = match e {
            Error::Scene(m) => m,
            e => e.to_string(),
        };
        let shown = format!("{}: ", scene_path.display());
        bad(format!("scene = {scene_rel:?}: {}", m.strip_prefix(&shown).unwrap_or(&m)))
    })?;

    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let output = get_str(&table, "output")
        .map_err(&bad)?
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(format!("out/study-{stem}")));
    let title = get_str(&table, "title").map_err(&bad)?.unwrap_or_else(|| stem.clone());
    get_str(&table, "description").map_err(&bad)?;
    let ranks = get_count(&table, "ranks", 1, 1024).map_err(&bad)?.unwrap_or(2);
    let repeat = get_count(&table, "repeat", 1, 100).map_err(&bad)?.unwrap_or(1);
    let mesh_param = get_str(&table, "mesh_param").map_err(&bad)?.unwrap_or_else(|| "h".into());
    let h_default = match &scene.mesh {
        MeshSource::Geo { params, .. } => {
            params.iter().find(|(n, _)| *n == mesh_param).map(|&(_, x)| x)
        }
        MeshSource::Msh { .. } => None,
    };
    if mesh_param.is_empty() || mesh_param.contains(['=', ' ']) {
        return Err(bad(format!("mesh_param = {mesh_param:?} is not a parameter name")));
    }
    let mut params = Vec::new();
    match table.get("params") {
        None => {}
        Some(Value::Table(t)) => {
            for (k, v) in t {
                let x = number(v).ok_or_else(|| {
                    bad(format!("params.{k} = {v} is impossible: a number is expected"))
                })?;
                if *k == mesh_param {
                    return Err(bad(format!(
                        "params.{k}: the swept mesh parameter is set by sweep.h, not params"
                    )));
                }
                params.push((k.clone(), x));
            }
        }
        Some(v) => {
            return Err(bad(format!(
                "params = {v} is impossible: a table NAME = VALUE is expected"
            )))
        }
    }
    let mut scaled = Vec::new();
    match table.get("scaled") {
        None => {}
        Some(Value::Table(t)) => {
            for (k, v) in t {
                let x = number(v).filter(|x| *x > 0.0 && x.is_finite()).ok_or_else(|| {
                    bad(format!("scaled.{k} = {v} is impossible: a factor > 0 is expected"))
                })?;
                if *k == mesh_param || params.iter().any(|(n, _)| n == k) {
                    return Err(bad(format!(
                        "scaled.{k}: {k} is already set (by sweep.h or params)"
                    )));
                }
                scaled.push((k.clone(), x));
            }
        }
        Some(v) => {
            return Err(bad(format!(
                "scaled = {v} is impossible: a table NAME = FACTOR is expected"
            )))
        }
    }
    let steps = get_count(&table, "steps", 1, 100_000_000).map_err(&bad)?;
    let error_step = get_count(&table, "error_step", 0, 100_000_000).map_err(&bad)?;
    let end_time = match table.get("end_time") {
        None => None,
        Some(v) => match number(v) {
            Some(x) if x > 0.0 && x.is_finite() => Some(x),
            _ => return Err(bad(format!("end_time = {v} is impossible: a time > 0 is expected"))),
        },
    };

    // The sweep.
    let empty = Table::new();
    let sweep = match table.get("sweep") {
        None => &empty,
        Some(Value::Table(t)) => t,
        Some(v) => return Err(bad(format!("sweep = {v} is impossible: a table is expected"))),
    };
    check_keys(sweep, "sweep.", &SWEEP_KEYS).map_err(&bad)?;
    let h = positive_list(sweep, "h").map_err(&bad)?;
    let tau = positive_list(sweep, "tau").map_err(&bad)?;
    let mut mass = Vec::new();
    if let Some(v) = sweep.get("mass") {
        let Value::Array(a) = v else {
            return Err(bad(format!(
                "sweep.mass = {v} is impossible: a list of mass kinds is expected"
            )));
        };
        for x in a {
            match x.as_str().and_then(MassKind::from_name) {
                Some(k) => mass.push(k.name().to_string()),
                None => {
                    let names: Vec<&str> = MassKind::ALL.iter().map(|k| k.name()).collect();
                    return Err(bad(format!(
                        "sweep.mass contains {x}, which is unknown (allowed: {})",
                        names.join(", ")
                    )));
                }
            }
        }
        if mass.is_empty() {
            return Err(bad("sweep.mass is empty".into()));
        }
        no_duplicates(&mass, "sweep.mass").map_err(&bad)?;
    }
    let solver = solvers(sweep).map_err(&bad)?;
    let skip = skips(sweep).map_err(&bad)?;
    let model = models(sweep).map_err(&bad)?;
    let amplitude = positive_list(sweep, "amplitude").map_err(&bad)?;
    let amplitude_set = amplitude_set(&table, !amplitude.is_empty()).map_err(&bad)?;

    // Time: a tau sweep runs to a fixed end time.
    if !tau.is_empty() {
        let Some(end) = end_time else {
            return Err(bad(
                "sweep.tau needs end_time (each run takes end_time / tau steps)".into()
            ));
        };
        if steps.is_some() {
            return Err(bad(
                "steps: not with sweep.tau (the steps follow from end_time / tau)".into()
            ));
        }
        if error_step.is_some() {
            return Err(bad(
                "error_step: not with sweep.tau (the errors are taken at end_time)".into()
            ));
        }
        for &t in &tau {
            steps_for(end, t).map_err(&bad)?;
        }
    } else if end_time.is_some() {
        return Err(bad("end_time: only with sweep.tau (otherwise use steps)".into()));
    }
    if let (Some(e), None) = (error_step, steps) {
        if e > scene.steps {
            return Err(bad(format!(
                "error_step = {e} is impossible: the scene runs {} steps",
                scene.steps
            )));
        }
    }
    if let (Some(e), Some(s)) = (error_step, steps) {
        if e > s {
            return Err(bad(format!("error_step = {e} is impossible: the runs take steps = {s}")));
        }
    }

    let has_exact = scene.exact.is_some();
    let reference = match table.get("reference") {
        None if has_exact => Reference::Exact,
        None => Reference::Finest,
        Some(Value::String(s)) if s == "exact" => {
            if !has_exact {
                return Err(bad(
                    "reference = \"exact\" is impossible: the scene has no [exact] solution".into(),
                ));
            }
            Reference::Exact
        }
        Some(Value::String(s)) if s == "finest" => Reference::Finest,
        Some(Value::Table(t)) if t.contains_key("mass") => {
            check_keys(t, "reference.", &["mass"]).map_err(&bad)?;
            let m = get_str(t, "mass").map_err(|m| bad(format!("reference.{m}")))?.unwrap_or_default();
            if !mass.contains(&m) {
                return Err(bad(format!(
                    "reference.mass = {m:?} is impossible: sweep.mass must list it (the reference is the finest run of that kind)"
                )));
            }
            Reference::Mass(m)
        }
        Some(Value::Table(t)) if t.contains_key("model") => {
            check_keys(t, "reference.", &["model"]).map_err(&bad)?;
            let m = get_str(t, "model").map_err(|m| bad(format!("reference.{m}")))?.unwrap_or_default();
            if !model.contains(&m) {
                return Err(bad(format!(
                    "reference.model = {m:?} is impossible: sweep.model must list it (every row is compared with the run of that model)"
                )));
            }
            Reference::Model(m)
        }
        Some(Value::Table(t)) => {
            check_keys(t, "reference.", &["file", "mass", "model"]).map_err(&bad)?;
            let f = get_str(t, "file")
                .map_err(|m| bad(format!("reference.{m}")))?
                .ok_or_else(|| bad("reference: a table needs file = \"run.h5\"".into()))?;
            let p = base.join(&f);
            if !p.is_file() {
                return Err(bad(format!("reference.file = {f:?}: no such file ({})", p.display())));
            }
            Reference::File(p)
        }
        Some(v) => {
            return Err(bad(format!(
                "reference = {v} is impossible (allowed: \"exact\", \"finest\", {{ file = \"run.h5\" }}, {{ mass = KIND }}, {{ model = MODEL }})"
            )))
        }
    };
    if matches!(reference, Reference::Finest | Reference::Mass(_)) && h.len() < 2 && tau.len() < 2 {
        return Err(bad(
            "reference = \"finest\" needs at least two values of sweep.h or sweep.tau".into(),
        ));
    }
    if !scaled.is_empty() && h.is_empty() {
        return Err(bad("scaled: only with sweep.h (the factors multiply its values)".into()));
    }
    if !h.is_empty() && !matches!(scene.mesh, MeshSource::Geo { .. }) {
        return Err(bad(format!(
            "sweep.h: the scene reads a .msh file; {mesh_param} is a parameter of mesh.geo"
        )));
    }

    Ok(Study {
        file: path.to_path_buf(),
        title,
        scene_path,
        scene,
        h_default,
        output,
        ranks,
        repeat,
        mesh_param,
        params,
        scaled,
        steps,
        error_step,
        end_time,
        reference,
        h,
        mass,
        tau,
        solver,
        skip,
        model,
        amplitude,
        amplitude_set,
    })
}

/// `end / tau` as a whole number of steps, by the scene's rule for `time.end`.
pub fn steps_for(end: f64, tau: f64) -> std::result::Result<usize, String> {
    scene::steps_to_end(end, tau).map_err(|e| match e {
        scene::EndSteps::TooMany { n } => format!(
            "sweep.tau contains {tau}, which is impossible: end_time = {end} takes too many such steps ({n})"
        ),
        _ => format!(
            "sweep.tau contains {tau}, which is impossible: end_time = {end} is not a whole number of such steps"
        ),
    })
}

fn check_keys(t: &Table, prefix: &str, allowed: &[&str]) -> std::result::Result<(), String> {
    for k in t.keys() {
        if !allowed.contains(&k.as_str()) {
            return Err(format!("unknown key {prefix}{k} (allowed: {})", allowed.join(", ")));
        }
    }
    Ok(())
}

/// A TOML number (float or integer) as f64; also read by `suite::spec`.
pub(crate) fn number(v: &Value) -> Option<f64> {
    match v {
        Value::Float(x) => Some(*x),
        Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

fn get_str(t: &Table, key: &str) -> std::result::Result<Option<String>, String> {
    match t.get(key) {
        None => Ok(None),
        Some(Value::String(s)) => Ok(Some(s.clone())),
        Some(v) => Err(format!("{key} = {v} is impossible: a string is expected")),
    }
}

fn get_count(
    t: &Table,
    key: &str,
    min: i64,
    max: i64,
) -> std::result::Result<Option<usize>, String> {
    match t.get(key) {
        None => Ok(None),
        Some(Value::Integer(i)) if (min..=max).contains(i) => Ok(Some(*i as usize)),
        Some(v) => {
            Err(format!("{key} = {v} is impossible: a whole number in {min}..={max} is expected"))
        }
    }
}

fn positive_list(t: &Table, key: &str) -> std::result::Result<Vec<f64>, String> {
    let Some(v) = t.get(key) else { return Ok(Vec::new()) };
    let Value::Array(a) = v else {
        return Err(format!("sweep.{key} = {v} is impossible: a list of numbers is expected"));
    };
    let mut out = Vec::new();
    for x in a {
        match number(x) {
            Some(y) if y > 0.0 && y.is_finite() => out.push(y),
            _ => {
                return Err(format!(
                    "sweep.{key} contains {x}, which is impossible: values must be numbers > 0"
                ))
            }
        }
    }
    if out.is_empty() {
        return Err(format!("sweep.{key} is empty"));
    }
    let labels: Vec<String> = out.iter().map(|x| format!("{x}")).collect();
    no_duplicates(&labels, &format!("sweep.{key}"))?;
    Ok(out)
}

fn no_duplicates(list: &[String], key: &str) -> std::result::Result<(), String> {
    for (i, a) in list.iter().enumerate() {
        if list[..i].contains(a) {
            return Err(format!("{key} lists {a} twice"));
        }
    }
    Ok(())
}

fn skips(sweep: &Table) -> std::result::Result<Vec<Skip>, String> {
    let Some(v) = sweep.get("skip") else { return Ok(Vec::new()) };
    let Value::Array(a) = v else {
        return Err(format!(
            "sweep.skip = {v} is impossible: a list of tables {{ h, tau, mass }} is expected"
        ));
    };
    let mut out = Vec::new();
    for (i, e) in a.iter().enumerate() {
        let what = format!("sweep.skip[{i}]");
        let Value::Table(t) = e else {
            return Err(format!(
                "{what} = {e} is impossible: a table {{ h, tau, mass }} is expected"
            ));
        };
        check_keys(t, &format!("{what}."), &["h", "tau", "mass"])?;
        if t.is_empty() {
            return Err(format!("{what} is empty (it would skip every point)"));
        }
        let num = |k: &str| -> std::result::Result<Option<f64>, String> {
            match t.get(k) {
                None => Ok(None),
                Some(v) => number(v).filter(|x| *x > 0.0).map(Some).ok_or_else(|| {
                    format!("{what}.{k} = {v} is impossible: a number > 0 is expected")
                }),
            }
        };
        let mass = get_str(t, "mass").map_err(|m| format!("{what}.{m}"))?;
        out.push(Skip { h: num("h")?, tau: num("tau")?, mass });
    }
    Ok(out)
}

/// `sweep.model`: names `run --model` takes, each once.
fn models(sweep: &Table) -> std::result::Result<Vec<String>, String> {
    let Some(v) = sweep.get("model") else { return Ok(Vec::new()) };
    let Value::Array(a) = v else {
        return Err(format!(
            "sweep.model = {v} is impossible: a list of material models is expected"
        ));
    };
    let mut out = Vec::new();
    for x in a {
        match x.as_str().and_then(Model::from_name) {
            Some(m) => out.push(m.name().to_string()),
            None => {
                return Err(format!(
                    "sweep.model contains {x}, which is unknown (allowed: {})",
                    MODELS.join(", ")
                ))
            }
        }
    }
    if out.is_empty() {
        return Err("sweep.model is empty".into());
    }
    no_duplicates(&out, "sweep.model")?;
    Ok(out)
}

/// The material models `sweep.model` takes (those of `run --model`).
pub const MODELS: [&str; 3] = ["linear", "neo_hookean", "saint_venant_kirchhoff"];

/// `amplitude_set`: scene keys and their templates, checked with the suite's substitution
/// (a placeholder other than `{amplitude}` is an error); only together with
/// `sweep.amplitude` (`swept`).
fn amplitude_set(table: &Table, swept: bool) -> std::result::Result<Vec<(String, Value)>, String> {
    let t = match table.get("amplitude_set") {
        None if swept => {
            return Err("sweep.amplitude needs amplitude_set (the scene keys it sets, e.g. \
                amplitude_set = { \"initial.velocity\" = [\"0\", \"-{amplitude}\"] })"
                .into())
        }
        None => return Ok(Vec::new()),
        Some(Value::Table(t)) => t,
        Some(v) => {
            return Err(format!(
                "amplitude_set = {v} is impossible: a table \"scene.key\" = TEMPLATE is expected"
            ))
        }
    };
    let mut out = Vec::new();
    for (k, v) in t {
        if k.is_empty() || k.split('.').any(str::is_empty) {
            return Err(format!("amplitude_set.{k:?}: not a dotted scene key"));
        }
        // The templates with a trial value: what each point will do.
        crate::suite::spec::value(k, v, &[("amplitude".to_string(), 1.0)])
            .map_err(|m| format!("amplitude_set.{k}: {m}"))?;
        out.push((k.clone(), v.clone()));
    }
    if out.is_empty() {
        return Err("amplitude_set is empty".into());
    }
    if !swept {
        return Err(format!(
            "amplitude_set.{} is set but there is no sweep.amplitude (its values fill {{amplitude}})",
            out[0].0
        ));
    }
    Ok(out)
}

fn solvers(sweep: &Table) -> std::result::Result<Vec<Solver>, String> {
    let Some(v) = sweep.get("solver") else { return Ok(Vec::new()) };
    let Value::Array(a) = v else {
        return Err(format!(
            "sweep.solver = {v} is impossible: a list of PETSc option lists is expected"
        ));
    };
    let strings = |v: &Value, what: &str| -> std::result::Result<Vec<String>, String> {
        let Value::Array(a) = v else {
            return Err(format!("{what} = {v} is impossible: a list of strings is expected"));
        };
        a.iter()
            .map(|x| {
                x.as_str()
                    .map(str::to_string)
                    .ok_or_else(|| format!("{what} contains {x}, which is not a string"))
            })
            .collect()
    };
    let mut out = Vec::new();
    for (i, entry) in a.iter().enumerate() {
        let what = format!("sweep.solver[{i}]");
        let s = match entry {
            Value::Array(_) => {
                let options = strings(entry, &what)?;
                Solver { label: default_label(&options), options }
            }
            Value::Table(t) => {
                check_keys(t, &format!("{what}."), &["label", "options"])?;
                let options = strings(
                    t.get("options").ok_or_else(|| format!("{what}.options: missing"))?,
                    &format!("{what}.options"),
                )?;
                let label = get_str(t, "label")
                    .map_err(|m| format!("{what}.{m}"))?
                    .unwrap_or_else(|| default_label(&options));
                Solver { label, options }
            }
            v => {
                return Err(format!(
                    "{what} = {v} is impossible: an option list or {{ label, options }} is expected"
                ))
            }
        };
        out.push(s);
    }
    if out.is_empty() {
        return Err("sweep.solver is empty".into());
    }
    let labels: Vec<String> = out.iter().map(|s| s.label.clone()).collect();
    no_duplicates(&labels, "sweep.solver (labels)")?;
    Ok(out)
}

/// "cg+jacobi" from ["-ksp_type", "cg", "-pc_type", "jacobi"]; the joined options otherwise.
fn default_label(options: &[String]) -> String {
    let value =
        |key: &str| options.iter().position(|o| o == key).and_then(|i| options.get(i + 1)).cloned();
    match (value("-ksp_type"), value("-pc_type")) {
        (Some(k), Some(p)) if options.len() == 4 => format!("{k}+{p}"),
        _ if options.is_empty() => "default".to_string(),
        _ => options.join(" "),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("studies/test.toml")
    }

    fn set(text: &str) -> std::result::Result<StudySet, String> {
        parse_set(&file(), text).map_err(|e| e.to_string())
    }

    const TWO: &str = r#"
title = "two"
reference = { mass = "consistent" }
repeat = 2
[[part]]
name = "disc"
scene = "../scenes/disc.toml"
mesh_param = "hc"
scaled = { h = 10.0 }
[part.sweep]
h = [0.1, 0.05]
mass = ["consistent", "modified1"]
[[part]]
name = "beam"
scene = "../scenes/beam.toml"
repeat = 1
end_time = 1e-4
[part.sweep]
h = [0.25, 0.125]
tau = [1e-5, 5e-6]
mass = ["consistent"]
skip = [{ h = 0.125, tau = 1e-5 }]
"#;

    #[test]
    fn parts_share_the_top_and_override_it() {
        let s = set(TWO).unwrap();
        assert!(s.multi);
        assert_eq!((s.title.as_str(), s.parts.len()), ("two", 2));
        let (a, b) = (&s.parts[0], &s.parts[1]);
        assert_eq!((a.title.as_str(), b.title.as_str()), ("disc", "beam"));
        assert_eq!((a.repeat, b.repeat), (2, 1));
        assert_eq!(a.reference, Reference::Mass("consistent".into()));
        assert_eq!(a.scaled, vec![("h".to_string(), 10.0)]);
        assert_eq!(a.output, s.output);
        assert_eq!(b.skip, vec![Skip { h: Some(0.125), tau: Some(1e-5), mass: None }]);
        // A file without parts is one part.
        let one = set("scene = \"../scenes/beam.toml\"\n[sweep]\nh = [0.25, 0.125]\n").unwrap();
        assert!(!one.multi && one.parts.len() == 1);
    }

    #[test]
    fn bad_parts_are_one_line_errors_naming_the_key() {
        let cases = [
            (TWO.replace("repeat = 1", "repeats = 1"), "part[1] (beam): unknown key repeats"),
            (TWO.replace("name = \"beam\"", "name = \"disc\""), "part[1].name"),
            (TWO.replace("name = \"beam\"\n", ""), "part[1].name: missing"),
            (TWO.replace("name = \"beam\"", "name = \"beam\"\noutput = \"x\""), "part[1].output"),
            (TWO.replace("title = \"two\"", "title = \"two\"\nscene = \"x\""), "unknown key scene"),
            (TWO.replace("skip = [{ h", "skip = [{ mesh"), "sweep.skip[0].mesh"),
            (TWO.replace("skip = [{ h = 0.125, tau = 1e-5 }]", "skip = [{}]"), "sweep.skip[0]"),
            (TWO.replace("scaled = { h = 10.0 }", "scaled = { h = -1 }"), "scaled.h"),
            (TWO.replace("scaled = { h = 10.0 }", "scaled = { hc = 2 }"), "scaled.hc"),
            (TWO.replace("[\"consistent\", \"modified1\"]", "[\"modified1\"]"), "reference.mass"),
        ];
        for (text, key) in cases {
            let e = set(&text).unwrap_err();
            assert_eq!(e.lines().count(), 1, "{e}");
            assert!(e.contains(key), "{e} does not name {key}");
        }
        let e = set("scene = \"../scenes/beam.toml\"\nscaled = { x = 2 }\n").unwrap_err();
        assert!(e.contains("scaled: only with sweep.h"), "{e}");
        let e = parse(&file(), TWO).unwrap_err().to_string();
        assert!(e.contains("parts"), "{e}");
    }

    #[test]
    fn skips_match_every_given_value() {
        let k = Skip { h: Some(0.04), tau: None, mass: Some("lumped".into()) };
        assert!(k.matches(Some(0.04), 1.0, Some("lumped")));
        assert!(k.matches(Some(0.04 * (1.0 + 1e-12)), 2.0, Some("lumped")));
        assert!(!k.matches(Some(0.04), 1.0, Some("consistent")));
        assert!(!k.matches(Some(0.05), 1.0, Some("lumped")));
        assert!(!k.matches(None, 1.0, Some("lumped")));
        let t = Skip { tau: Some(0.005), ..Default::default() };
        assert!(t.matches(None, 0.005, None) && !t.matches(None, 0.01, None));
    }
}
