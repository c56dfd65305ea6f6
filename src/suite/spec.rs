//! The suite file (`studies/suite.toml`): its schema, and the scene of each point.
//!
//! ```toml
//! title = "hard cases"               # optional
//! output = "out/suite"               # folder, relative to the current directory
//! ranks = 2                          # ranks of every run (--ranks overrides)
//! rank_sweep = [1, 3, 4]             # cases with rank_sweep = true also run on these
//! rank_tol = 1e-8                    # their energies and contact forces against the main run
//! rise_tol = 1e-6                    # energy rise above E^0 + work, relative to E_ref
//! penetration_tol = 1e-8             # penetration, relative to the body size
//! [reduced]                          # with --reduced
//! output = "out/suite-reduced"
//! rank_sweep = [1]
//!
//! [[case]]
//! name = "speed/block"               # unique
//! group = "impact speed"             # what the case shows (the group's heading)
//! scene = "../scenes/suite/block_impact.toml"   # relative to the suite file
//! mass = ["consistent", "modified1"] # optional: one run per kind (default: the scene's)
//! sweep = { "v/c" = [0.01, 0.1] }    # optional: variables, zipped (one point per index)
//! params = { h = 0.1 }               # mesh parameters: numbers or expressions in {var}
//! set = { "initial.velocity" = ["0", "-11.6024 * {v/c}"], "time.tau" = "= 0.004 * {cfl}" }
//!                                    # scene keys (dotted paths): strings get {var} replaced;
//!                                    # a string "= expr" becomes the number it evaluates to
//! petsc = ["-ksp_rtol", "1e-12"]     # optional PETSc options of the runs
//! rank_sweep = true                  # also run on the suite's rank_sweep counts
//! rank_steps = 500                   # optional: compare the rank sweep's first 500 steps only
//!                                    # (chaotic histories: round-off differences grow)
//! rank_tol = 1e-6                    # optional: this case's rank tolerance (a solver whose own
//!                                    # stopping test is looser than the suite's rank_tol)
//! single_episode = true              # theory: one contact episode per node and impact with M_H
//! [case.reduced]                     # with --reduced: replaces mass / sweep / petsc, merges
//! skip = false                       # params and set; skip = true leaves the case out
//! ```

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::{Table, Value};

use crate::error::{Error, Result};
use crate::scene::{self, expr::Expr, MassKind, Scene};
use crate::study::spec::number;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    title: Option<String>,
    #[allow(dead_code)]
    description: Option<String>,
    output: Option<String>,
    ranks: Option<usize>,
    #[serde(default)]
    rank_sweep: Vec<usize>,
    rank_tol: Option<f64>,
    rise_tol: Option<f64>,
    penetration_tol: Option<f64>,
    reduced: Option<RawReducedTop>,
    #[serde(default)]
    case: Vec<RawCase>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReducedTop {
    output: Option<String>,
    rank_sweep: Option<Vec<usize>>,
}

#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct RawCase {
    name: String,
    group: String,
    scene: String,
    #[allow(dead_code)]
    description: Option<String>,
    mass: Option<Vec<String>>,
    sweep: Option<Table>,
    params: Option<Table>,
    set: Option<Table>,
    petsc: Option<Vec<String>>,
    #[serde(default)]
    rank_sweep: bool,
    rank_steps: Option<usize>,
    rank_tol: Option<f64>,
    #[serde(default)]
    single_episode: bool,
    reduced: Option<RawCaseReduced>,
}

#[derive(Debug, Deserialize, Clone)]
#[serde(deny_unknown_fields)]
struct RawCaseReduced {
    #[serde(default)]
    skip: bool,
    mass: Option<Vec<String>>,
    sweep: Option<Table>,
    params: Option<Table>,
    set: Option<Table>,
    petsc: Option<Vec<String>>,
}

/// The suite as it runs (the reduced variant already applied).
#[derive(Debug, Clone)]
pub struct Spec {
    pub file: PathBuf,
    pub title: String,
    pub output: PathBuf,
    pub ranks: usize,
    pub rank_sweep: Vec<usize>,
    pub rank_tol: f64,
    pub rise_tol: f64,
    pub penetration_tol: f64,
    pub reduced: bool,
    pub cases: Vec<Case>,
}

#[derive(Debug, Clone)]
pub struct Case {
    pub name: String,
    pub group: String,
    pub scene_path: PathBuf,
    pub masses: Vec<Option<String>>,
    /// Variables and their values (all of the same length).
    pub sweep: Vec<(String, Vec<f64>)>,
    pub params: Table,
    pub set: Table,
    pub petsc: Vec<String>,
    pub rank_sweep: bool,
    /// The rank sweep compares the first so many steps (all without).
    pub rank_steps: Option<usize>,
    /// This case's rank tolerance (`None`: the suite's `rank_tol`).
    pub rank_tol: Option<f64>,
    pub single_episode: bool,
}

/// One run of the suite: a case at one index of its sweep with one mass kind.
#[derive(Debug, Clone)]
pub struct Point {
    pub case: usize,
    /// `v/c=0.01 cfl=10` (empty without a sweep).
    pub variant: String,
    pub vars: Vec<(String, f64)>,
    pub mass: Option<String>,
    /// File stem under runs/.
    pub id: String,
}

/// Reads a suite file; `reduced` applies its reduced variant.
pub fn load(path: &Path, reduced: bool) -> Result<Spec> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| Error::Usage(format!("suite {}: cannot read: {e}", path.display())))?;
    parse(path, &text, reduced)
}

pub fn parse(path: &Path, text: &str, reduced: bool) -> Result<Spec> {
    let shown = path.display().to_string();
    let bad = |m: String| Error::Usage(format!("suite {shown}: {m}"));
    let raw: RawSpec = toml::from_str(text)
        .map_err(|e: toml::de::Error| bad(e.message().lines().next().unwrap_or("").to_string()))?;
    let base = path.parent().unwrap_or(Path::new("."));
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let red = raw.reduced.as_ref();
    let output = match (reduced, red.and_then(|r| r.output.clone()), raw.output.clone()) {
        (true, Some(o), _) => PathBuf::from(o),
        (true, None, Some(o)) => PathBuf::from(format!("{o}-reduced")),
        (true, None, None) => PathBuf::from(format!("out/{stem}-reduced")),
        (false, _, Some(o)) => PathBuf::from(o),
        (false, _, None) => PathBuf::from(format!("out/{stem}")),
    };
    let rank_sweep = match (reduced, red.and_then(|r| r.rank_sweep.clone())) {
        (true, Some(r)) => r,
        _ => raw.rank_sweep.clone(),
    };
    let ranks = raw.ranks.unwrap_or(2);
    if ranks == 0 || rank_sweep.contains(&0) {
        return Err(bad("ranks and rank_sweep must be >= 1".into()));
    }
    let tol = |v: Option<f64>, key: &str, default: f64| -> Result<f64> {
        match v {
            None => Ok(default),
            Some(x) if x > 0.0 && x.is_finite() => Ok(x),
            Some(x) => Err(bad(format!("{key} = {x} is impossible: a number > 0 is expected"))),
        }
    };
    let rank_tol = tol(raw.rank_tol, "rank_tol", 1e-8)?;
    let rise_tol = tol(raw.rise_tol, "rise_tol", 1e-6)?;
    let penetration_tol = tol(raw.penetration_tol, "penetration_tol", 1e-8)?;
    if raw.case.is_empty() {
        return Err(bad("no [[case]]".into()));
    }
    let mut cases = Vec::new();
    for (i, c) in raw.case.iter().enumerate() {
        let key = format!("case[{i}] ({})", c.name);
        if raw.case[..i].iter().any(|d| d.name == c.name) {
            return Err(bad(format!("{key}: the name is used twice")));
        }
        let mut c = c.clone();
        if reduced {
            if let Some(r) = c.reduced.clone() {
                if r.skip {
                    continue;
                }
                if r.mass.is_some() {
                    c.mass = r.mass;
                }
                if r.sweep.is_some() {
                    c.sweep = r.sweep;
                }
                if r.petsc.is_some() {
                    c.petsc = r.petsc;
                }
                for (mine, theirs) in [(&mut c.params, r.params), (&mut c.set, r.set)] {
                    if let Some(t) = theirs {
                        mine.get_or_insert_with(Table::new).extend(t);
                    }
                }
            }
        }
        cases.push(case(base, &c).map_err(|m| bad(format!("{key}: {m}")))?);
    }
    Ok(Spec {
        file: path.to_path_buf(),
        title: raw.title.unwrap_or(stem),
        output,
        ranks,
        rank_sweep,
        rank_tol,
        rise_tol,
        penetration_tol,
        reduced,
        cases,
    })
}

fn case(base: &Path, c: &RawCase) -> std::result::Result<Case, String> {
    let scene_path = base.join(&c.scene);
    if !scene_path.is_file() {
        return Err(format!("scene = {:?}: no such file ({})", c.scene, scene_path.display()));
    }
    let masses = match &c.mass {
        None => vec![None],
        Some(list) if list.is_empty() => return Err("mass is empty".into()),
        Some(list) => {
            let mut out = Vec::new();
            for m in list {
                let k = MassKind::from_name(m).ok_or_else(|| {
                    let names: Vec<&str> = MassKind::ALL.iter().map(|k| k.name()).collect();
                    format!("mass: {m:?} is unknown (allowed: {})", names.join(", "))
                })?;
                out.push(Some(k.name().to_string()));
            }
            out
        }
    };
    let mut sweep = Vec::new();
    for (k, v) in c.sweep.iter().flatten() {
        let Value::Array(a) = v else {
            return Err(format!("sweep.{k} = {v} is impossible: a list of numbers is expected"));
        };
        let xs: Vec<f64> = a
            .iter()
            .map(|x| number(x).ok_or_else(|| format!("sweep.{k} contains {x}: not a number")))
            .collect::<std::result::Result<_, _>>()?;
        if xs.is_empty() {
            return Err(format!("sweep.{k} is empty"));
        }
        if let Some((k0, x0)) = sweep.first().map(|(k, x): &(String, Vec<f64>)| (k, x.len())) {
            if xs.len() != x0 {
                return Err(format!(
                    "sweep.{k} has {} values but sweep.{k0} has {x0}: the variables are zipped",
                    xs.len()
                ));
            }
        }
        sweep.push((k.clone(), xs));
    }
    Ok(Case {
        name: c.name.clone(),
        group: c.group.clone(),
        scene_path,
        masses,
        sweep,
        params: c.params.clone().unwrap_or_default(),
        set: c.set.clone().unwrap_or_default(),
        petsc: c.petsc.clone().unwrap_or_default(),
        rank_sweep: c.rank_sweep,
        rank_steps: c.rank_steps,
        rank_tol: match c.rank_tol {
            Some(x) if !(x > 0.0 && x.is_finite()) => {
                return Err(format!("rank_tol = {x} is impossible: a number > 0 is expected"))
            }
            t => t,
        },
        single_episode: c.single_episode,
    })
}

/// Every point of the suite, case by case (sweep index, then mass kind).
pub fn points(spec: &Spec) -> Vec<Point> {
    let mut out = Vec::new();
    for (ci, c) in spec.cases.iter().enumerate() {
        let n = c.sweep.first().map_or(1, |(_, v)| v.len());
        for i in 0..n {
            let vars: Vec<(String, f64)> = c.sweep.iter().map(|(k, v)| (k.clone(), v[i])).collect();
            let variant =
                vars.iter().map(|(k, x)| format!("{k}={}", show(*x))).collect::<Vec<_>>().join(" ");
            for m in &c.masses {
                let slug: String = c
                    .name
                    .chars()
                    .map(|ch| if ch.is_ascii_alphanumeric() { ch } else { '_' })
                    .collect();
                let id = format!(
                    "{slug}-{i}{}",
                    m.as_ref().map(|m| format!("-{m}")).unwrap_or_default()
                );
                out.push(Point {
                    case: ci,
                    variant: variant.clone(),
                    vars: vars.clone(),
                    mass: m.clone(),
                    id,
                });
            }
        }
    }
    out
}

/// A number as the labels show it (shortest form).
pub fn show(x: f64) -> String {
    format!("{x}")
}

/// `{var}` replaced by the variables' values in `s`.
fn substitute(s: &str, vars: &[(String, f64)]) -> std::result::Result<String, String> {
    let mut out = s.to_string();
    for (k, x) in vars {
        out = out.replace(&format!("{{{k}}}"), &format!("({})", show(*x)));
    }
    if let Some(i) = out.find('{') {
        let rest = &out[i..];
        let end = rest.find('}').map_or(rest.len(), |j| j + 1);
        return Err(format!("{:?}: {} is no variable of the sweep", s, &rest[..end]));
    }
    Ok(out)
}

/// A constant expression (no x, y, z, t) after substitution.
fn constant(s: &str, vars: &[(String, f64)]) -> std::result::Result<f64, String> {
    let text = substitute(s, vars)?;
    let e = Expr::parse(&text).map_err(|m| format!("{s:?}: {m}"))?;
    if e.depends_on_t() || e.depends_on_x() {
        return Err(format!("{s:?}: a constant is expected (no x, y, z, t)"));
    }
    let x = e.eval([0.0; 3], 0.0);
    if !x.is_finite() {
        return Err(format!("{s:?} = {x}: not a finite number"));
    }
    Ok(x)
}

/// A value of `set` with the variables put in: strings get `{var}` replaced, a string
/// `"= expr"` becomes its number (rounded to a whole number >= 1 for the keys that count:
/// `...steps`, `...every`).
pub(crate) fn value(
    key: &str,
    v: &Value,
    vars: &[(String, f64)],
) -> std::result::Result<Value, String> {
    Ok(match v {
        Value::String(s) => match s.trim_start().strip_prefix('=') {
            Some(e) => {
                let x = constant(e, vars)?;
                if key.ends_with("steps") || key.ends_with("every") {
                    let n = x.round();
                    if n < 1.0 {
                        return Err(format!("{key} = {s:?} = {x}: a number >= 1 is expected"));
                    }
                    Value::Integer(n as i64)
                } else {
                    Value::Float(x)
                }
            }
            None => Value::String(substitute(s, vars)?),
        },
        Value::Array(a) => Value::Array(
            a.iter().map(|x| value(key, x, vars)).collect::<std::result::Result<_, _>>()?,
        ),
        Value::Table(t) => {
            let mut out = Table::new();
            for (k, x) in t {
                out.insert(k.clone(), value(key, x, vars)?);
            }
            Value::Table(out)
        }
        other => other.clone(),
    })
}

/// The scene text of a point, its number of steps and its time step: the case's scene with the point's
/// mesh parameters and mass kind (typed overrides), then the `set` keys; the fields are
/// written at the start and the end only (the energies and contact series every step).
pub fn scene_text(case: &Case, p: &Point) -> Result<(String, usize, f64)> {
    let err = |m: String| Error::Scene(format!("{}: {m}", case.scene_path.display()));
    let mut s: Scene = scene::load(&case.scene_path)?;
    for (k, v) in &case.params {
        let x = match v {
            Value::String(e) => {
                constant(e, &p.vars).map_err(|m| err(format!("params.{k}: {m}")))?
            }
            v => number(v).ok_or_else(|| err(format!("params.{k} = {v}: not a number")))?,
        };
        s.set_mesh_param(&format!("{k}={x}"))?;
    }
    if let Some(m) = &p.mass {
        s.set_mass_kind(m)?;
    }
    let mut t: Table = s
        .variant_text()?
        .parse()
        .map_err(|e: toml::de::Error| err(format!("invalid TOML: {}", e.message())))?;
    let mut keys: BTreeMap<&str, &Value> = BTreeMap::new();
    for (k, v) in &case.set {
        keys.insert(k, v);
    }
    for (k, v) in keys {
        let v = value(k, v, &p.vars).map_err(&err)?;
        let path: Vec<&str> = k.split('.').collect();
        let (last, tables) = path.split_last().expect("split gives one part");
        let mut at = &mut t;
        for part in tables {
            let entry = at.entry(part.to_string()).or_insert_with(|| Value::Table(Table::new()));
            at = entry.as_table_mut().ok_or_else(|| err(format!("set.{k}: {part} is no table")))?;
        }
        match k {
            "time.steps" => {
                at.remove("end");
            }
            "time.end" => {
                at.remove("steps");
            }
            _ => {}
        }
        at.insert(last.to_string(), v);
    }
    // Parse once to learn the steps (time.end or time.steps), then write the fields at the
    // start and at the last step only.
    let text = toml::to_string(&t).map_err(|e| err(format!("cannot write: {e}")))?;
    let dir = case.scene_path.parent().unwrap_or(Path::new("."));
    let parsed = scene::parse(&text, &format!("{}.toml", p.id), dir)?;
    let (steps, tau) = (parsed.steps, parsed.tau);
    let out = t.entry("output").or_insert_with(|| Value::Table(Table::new()));
    if let Some(o) = out.as_table_mut() {
        o.insert("every".into(), Value::Integer(steps as i64));
        o.insert("progress".into(), Value::Boolean(false));
        o.remove("times");
        o.remove("field_every");
    }
    let text = toml::to_string(&t).map_err(|e| err(format!("cannot write: {e}")))?;
    scene::parse(&text, &format!("{}.toml", p.id), dir)?;
    Ok((text, steps, tau))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_with_variables() {
        let vars = vec![("v/c".to_string(), 0.5), ("cfl".to_string(), 10.0)];
        assert_eq!(substitute("-11.6 * {v/c}", &vars).unwrap(), "-11.6 * (0.5)");
        assert!(substitute("{nope}", &vars).unwrap_err().contains("{nope}"));
        assert_eq!(
            value("time.tau", &Value::String("= 0.004 * {cfl}".into()), &vars).unwrap(),
            Value::Float(0.04)
        );
        assert_eq!(
            value("time.steps", &Value::String("= 2000 / {cfl}".into()), &vars).unwrap(),
            Value::Integer(200)
        );
        assert_eq!(
            value("time.steps", &Value::String("= 33 / {cfl}".into()), &vars).unwrap(),
            Value::Integer(3)
        );
        assert!(value("time.steps", &Value::String("= 3 / {cfl}".into()), &vars).is_err());
        let a = Value::Array(vec![Value::String("0".into()), Value::String("-{v/c}".into())]);
        assert_eq!(
            value("initial.velocity", &a, &vars).unwrap(),
            Value::Array(vec![Value::String("0".into()), Value::String("-(0.5)".into())])
        );
        assert!(constant("x + 1", &vars).is_err());
    }

    #[test]
    fn spec_errors_name_the_key() {
        let p = Path::new("/nonexistent/suite.toml");
        let e = parse(p, "[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"x.toml\"\n", false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("case[0] (a): scene"), "{e}");
        let e = parse(p, "bogus = 1\n", false).unwrap_err().to_string();
        assert!(e.contains("bogus"), "{e}");
    }
}
