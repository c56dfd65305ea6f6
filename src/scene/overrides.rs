//! Typed overrides of a loaded scene beyond the command line's (`set_mesh_param`,
//! `set_mass_kind`): the number of steps, the time step for a fixed end time, an error step;
//! and [`Scene::variant_text`], the scene file of the overridden scene (e.g. for the runs of a
//! study, which have no `--tau` flag).

use super::model::{steps_to_end, MeshSource, Scene};
use super::validate::{check_tau, error_step, steps_of_times};
use crate::error::{Error, Result};
use std::path::Path;
use toml::{Table, Value};

impl Scene {
    /// Override the number of steps (as `time.steps` would): listed error steps beyond the run
    /// are dropped, the default one (the last step) follows, and `output.times` must still lie
    /// within the run.
    pub fn set_steps(&mut self, steps: usize) -> Result<()> {
        if steps < 1 {
            return Err(self.error(format!(
                "time.steps = {steps} is impossible: the number of steps must be >= 1"
            )));
        }
        self.set_time(self.tau, steps)
    }

    /// Override the time step for a run that ends at `end`: the steps are `end / tau` by the
    /// rule of `time.end` ([`steps_to_end`]), then as [`Scene::set_steps`].
    pub fn set_tau(&mut self, tau: f64, end: f64) -> Result<()> {
        let steps = check_tau(tau)
            .and_then(|()| steps_to_end(end, tau).map_err(|e| e.message(end, tau)))
            .map_err(|m| self.error(m))?;
        self.set_time(tau, steps)
    }

    fn set_time(&mut self, tau: f64, steps: usize) -> Result<()> {
        self.output.time_steps =
            steps_of_times(&self.output.times, tau, steps).map_err(|m| self.error(m))?;
        self.tau = tau;
        self.steps = steps;
        if let Some(ex) = &mut self.exact {
            if ex.error_steps_listed {
                ex.error_steps.retain(|&s| s <= steps);
            } else {
                ex.error_steps = vec![steps];
            }
        }
        Ok(())
    }

    /// Also report the errors against the exact solution at `step` (only there when the scene
    /// lists no `exact.error_steps`). Without `[exact]` nothing changes.
    pub fn add_error_step(&mut self, step: usize) -> Result<()> {
        let step = error_step(step as i64, self.steps).map_err(|m| self.error(m))?;
        if let Some(ex) = &mut self.exact {
            if !ex.error_steps_listed {
                ex.error_steps.clear();
                ex.error_steps_listed = true;
            }
            ex.error_steps.push(step);
            ex.error_steps.sort_unstable();
            ex.error_steps.dedup();
        }
        Ok(())
    }

    /// The scene's text with its typed values written back key by key: `name`, the mesh file
    /// (an absolute path) and `mesh.params`, `time.tau` and `time.steps` (no `time.end`),
    /// `mass.kind`, `exact.error_steps`, `output.every` and `output.fields`; every other key
    /// as written (comments are lost). Parsed from any folder, it gives this scene.
    pub fn variant_text(&self) -> Result<String> {
        let mut t: Table = self.text.parse().map_err(|e: toml::de::Error| {
            self.error(format!("invalid TOML: {}", e.message().trim()))
        })?;
        t.insert("name".into(), Value::String(self.name.clone()));
        let mesh = section(&mut t, "mesh");
        match &self.mesh {
            MeshSource::Geo { path, params, .. } => {
                mesh.insert("geo".into(), absolute(path)?);
                let p: Table = params.iter().map(|(k, v)| (k.clone(), Value::Float(*v))).collect();
                if p.is_empty() {
                    mesh.remove("params");
                } else {
                    mesh.insert("params".into(), Value::Table(p));
                }
            }
            MeshSource::Msh { path } => {
                mesh.insert("msh".into(), absolute(path)?);
            }
        }
        let time = section(&mut t, "time");
        time.remove("end");
        time.insert("tau".into(), Value::Float(self.tau));
        time.insert("steps".into(), Value::Integer(self.steps as i64));
        section(&mut t, "mass").insert("kind".into(), Value::String(self.mass.kind.name().into()));
        if let Some(ex) = &self.exact {
            let steps = ex.error_steps.iter().map(|&s| Value::Integer(s as i64)).collect();
            section(&mut t, "exact").insert("error_steps".into(), Value::Array(steps));
        }
        let output = section(&mut t, "output");
        output.insert("every".into(), Value::Integer(self.output.every as i64));
        let fields = self.output.fields.iter().map(|f| Value::String(f.name().into())).collect();
        output.insert("fields".into(), Value::Array(fields));
        toml::to_string(&t).map_err(|e| self.error(format!("cannot write a copy: {e}")))
    }

    /// A scene error naming the scene file.
    pub(super) fn error(&self, m: String) -> Error {
        Error::Scene(format!("{}: {m}", self.display_name()))
    }
}

/// The table `key` of the scene (created when absent).
fn section<'a>(t: &'a mut Table, key: &str) -> &'a mut Table {
    let v = t.entry(key).or_insert_with(|| Value::Table(Table::new()));
    if !v.is_table() {
        *v = Value::Table(Table::new());
    }
    match v {
        Value::Table(s) => s,
        _ => unreachable!("{key} was made a table"),
    }
}

fn absolute(path: &Path) -> Result<Value> {
    let p = path
        .canonicalize()
        .map_err(|e| Error::Io(format!("cannot resolve {}: {e}", path.display())))?;
    Ok(Value::String(p.to_string_lossy().into_owned()))
}
