//! The scene file: a TOML description of one simulation (mesh, material, loads, time stepping,
//! mass matrix, solver defaults, output, exact solution, contact).
//!
//! [`load`] / [`parse`] read it with serde (unknown keys are rejected at every level), validate
//! every value, compile every expression ([`expr::Expr`]) and resolve mesh paths against the scene
//! file's folder. Every error is one line that names the key, e.g.
//! `scene error: beam.toml: material.nu = 0.5 is impossible: Poisson's ratio must be in (-1, 0.5)`.
//!
//! Vector-valued keys must have exactly `dim` components, but `dim` is only known after meshing:
//! call [`Scene::check_dim`] then. [`Scene::effects`] tells what the scene asks to be built
//! ([`Effects::summary`]: the one-line report a run prints).
//!
//! Every key, its type, default and checks: `docs/scene-reference.md` (a test,
//! `tests/docs_reference.rs`, holds it to the keys [`parse`] accepts, found by probing).
//!
//! Bodies (`[[body]]`): each cell takes the material and mass treatment of the body whose group
//! holds it, else `[material]` and `mass.kind`; body groups must not overlap. The mass-free
//! layer (modified0/modified1) runs along those of the layer groups (`mass.contact_boundary`,
//! or the contact boundary / both sides of a pair and the group meeting obstacles beside it)
//! that lie on cells with a modified mass;
//! a consistent or lumped body gets none. A contact group must touch cells of one mass kind
//! only, one run builds one layer variant, and a body whose own `mass` is modified must have
//! a contact group on it (a body that only inherits a modified `mass.kind` and has no contact
//! group gets the consistent mass: `M_H` with an empty layer is `M`). These checks need the
//! mesh: `crate::bodies::Bodies::resolve` makes them, with errors naming the key as here.
//!
//! This file owns the validated model ([`Scene`] and its parts) and the entry points; `raw`
//! holds the serde form of the file, `validate` turns it into a [`Scene`] section by section,
//! and `toml_error` reduces the TOML parser's errors to the same one-line form.

pub mod effects;
pub mod expr;
mod model;
mod overrides;
mod raw;
pub mod separate;
mod toml_error;
mod validate;

pub use effects::{Effects, ObstacleEffect, ObstacleKind, Variation};

pub use model::{
    master_groups, slave_groups, steps_to_end, BodySpec, ContactPair, ContactSpec, DirichletSpec,
    EndSteps, ExactSpec, Field, Formulation, FrictionSpec, MassKind, MassSpec, MaterialSpec,
    MeshSource, Model, NeumannSpec, Obstacle, OutputSpec, Scene, Shape, SolverSpec,
};

use crate::error::{Error, Result};
use raw::RawScene;
use std::path::{Path, PathBuf};
use toml_error::toml_error;
use validate::build;

// =============================================================================================
// Loading

/// Reads, parses and validates the scene file at `path`; relative mesh paths are resolved
/// against the file's folder. Error messages start with `path` as given.
pub fn load(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| {
        Error::Scene(format!("{}: cannot read the scene file: {e}", path.display()))
    })?;
    let base = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let display = path.display().to_string();
    let mut scene = parse_impl(&text, &display, &base)?;
    scene.source = path.to_path_buf();
    Ok(scene)
}

/// Parses and validates scene `text`. `name` is the file name used in messages and for the
/// default scene name (its stem); relative mesh paths are resolved against `base_dir`.
pub fn parse(text: &str, name: &str, base_dir: &Path) -> Result<Scene> {
    parse_impl(text, name, base_dir)
}

fn parse_impl(text: &str, name: &str, base_dir: &Path) -> Result<Scene> {
    let raw: RawScene = toml::from_str(text)
        .map_err(|e| Error::Scene(format!("{name}: {}", toml_error(text, &e))))?;
    let stem = Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| name.to_string());
    let mut scene =
        build(raw, &stem, base_dir).map_err(|m| Error::Scene(format!("{name}: {m}")))?;
    scene.text = text.to_string();
    scene.source = base_dir.join(name);
    Ok(scene)
}

#[cfg(test)]
mod tests;
