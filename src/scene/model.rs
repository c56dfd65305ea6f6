//! The validated scene ([`Scene`] and its parts) and the rule of `time.end`: what the rest of
//! the program reads. `validate` builds it from the file's serde form.

use super::expr::VecExpr;
use crate::error::{Error, Result};
pub use crate::fem::hyperelastic::Model;
use serde::Deserialize;
use std::path::PathBuf;

// =============================================================================================
// The validated scene

/// A validated scene. Expressions are compiled; absent optional parts are `None`.
#[derive(Debug, Clone)]
pub struct Scene {
    /// `name` key, default: the scene file's stem.
    pub name: String,
    /// The scene file's text, verbatim (e.g. to store alongside the results).
    pub text: String,
    /// The scene file (for [`parse`]: `base_dir/name`).
    pub source: PathBuf,
    pub mesh: MeshSource,
    /// `[material]`: the material of every cell outside the `[[body]]` groups.
    pub material: MaterialSpec,
    /// `[[body]]`, in the order given: groups of cells with their own material or mass.
    pub bodies: Vec<BodySpec>,
    pub dirichlet: Vec<DirichletSpec>,
    pub neumann: Vec<NeumannSpec>,
    /// `None` when absent; present but all-zero is kept (see [`Effects::body_force`]).
    pub body_force: Option<VecExpr>,
    /// `body_force.acceleration`: a body force per unit mass (gravity), `rho a`, integrated
    /// like the inertia: `f = M a_h` with the run's mass matrix (`M_H` with the mass-free
    /// layer) and the nodal interpolant `a_h`.
    pub body_acceleration: Option<VecExpr>,
    pub initial_displacement: Option<VecExpr>,
    pub initial_velocity: Option<VecExpr>,
    /// Time step, > 0.
    pub tau: f64,
    /// Number of time steps, >= 1 (given, or `end / tau`).
    pub steps: usize,
    pub mass: MassSpec,
    pub solver: SolverSpec,
    pub output: OutputSpec,
    pub exact: Option<ExactSpec>,
    pub contact: Option<ContactSpec>,
}

/// Where the mesh comes from. Paths are resolved against the scene file's folder and exist.
#[derive(Debug, Clone, PartialEq)]
pub enum MeshSource {
    /// A gmsh `.geo` source to mesh, with `-setnumber` parameters (sorted by name).
    Geo { path: PathBuf, params: Vec<(String, f64)>, binary: bool },
    /// An existing MSH 4.1 file.
    Msh { path: PathBuf },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MaterialSpec {
    /// Young's modulus, > 0.
    pub e: f64,
    /// Poisson's ratio, in (-1, 0.5).
    pub nu: f64,
    /// Density, > 0.
    pub rho: f64,
    /// The constitutive model (`model`, default `linear`: small strain).
    pub model: Model,
    /// How the volumetric strain is discretized (`formulation`, default `displacement`).
    pub formulation: Formulation,
}

/// `formulation`: the plain displacement element, or the mixed (mean-dilatation, Q1/P0) one
/// whose pressure is constant per cell and condensed, free of volumetric locking as `nu`
/// approaches 0.5.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Formulation {
    #[default]
    Displacement,
    Mixed,
}

impl Formulation {
    pub fn from_name(name: &str) -> Option<Formulation> {
        match name {
            "displacement" => Some(Formulation::Displacement),
            "mixed" => Some(Formulation::Mixed),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Formulation::Displacement => "displacement",
            Formulation::Mixed => "mixed",
        }
    }
}

/// One `[[body]]`: a physical group of cells (of the mesh's dimension) with its own material
/// and/or mass treatment. Which cells it holds is known once the mesh is read
/// (`crate::bodies::Bodies`).
#[derive(Debug, Clone, PartialEq)]
pub struct BodySpec {
    /// Physical group name (the mesh's dimension; checked against the mesh).
    pub group: String,
    /// `[material]` with the body's own `E`, `nu`, `rho` where given.
    pub material: MaterialSpec,
    /// Which of `E`, `nu`, `rho`, `model` the body sets (in that order).
    pub sets: [bool; 4],
    /// `body[i].mass`; None: `[mass].kind` (see [`Scene::body_mass`]).
    pub mass: Option<MassKind>,
}

#[derive(Debug, Clone)]
pub struct DirichletSpec {
    /// Physical group name (any dimension).
    pub group: String,
    /// Prescribed displacement per component (indexed by displacement component, `dim` long);
    /// empty = zero.
    pub value: VecExpr,
    /// Constrained components (0 = x, 1 = y, 2 = z), sorted, no duplicates. When not given in
    /// the scene this is `[0, 1, 2]`: use [`DirichletSpec::constrained`] to clip it to `dim`.
    pub components: Vec<usize>,
    /// Whether `components` was given in the scene (then [`Scene::check_dim`] checks it).
    pub components_given: bool,
}

impl DirichletSpec {
    /// The constrained components for a `dim`-dimensional mesh.
    pub fn constrained(&self, dim: usize) -> Vec<usize> {
        self.components.iter().copied().filter(|&c| c < dim).collect()
    }
}

#[derive(Debug, Clone)]
pub struct NeumannSpec {
    pub group: String,
    /// Traction (force per unit boundary measure) per component.
    pub traction: VecExpr,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MassKind {
    Consistent,
    Lumped,
    Modified0,
    Modified1,
}

impl MassKind {
    pub fn name(self) -> &'static str {
        match self {
            MassKind::Consistent => "consistent",
            MassKind::Lumped => "lumped",
            MassKind::Modified0 => "modified0",
            MassKind::Modified1 => "modified1",
        }
    }

    /// The mass-free (modified) kinds, which need a contact boundary.
    pub fn is_modified(self) -> bool {
        matches!(self, MassKind::Modified0 | MassKind::Modified1)
    }

    pub const ALL: [MassKind; 4] =
        [MassKind::Consistent, MassKind::Lumped, MassKind::Modified0, MassKind::Modified1];

    /// The kind called `name` (as in scenes: consistent, lumped, modified0, modified1).
    pub fn from_name(name: &str) -> Option<MassKind> {
        MassKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct MassSpec {
    pub kind: MassKind,
    /// Potential contact boundary (physical group); always `Some` for the modified kinds.
    pub contact_boundary: Option<String>,
    /// Further groups the layer runs along: the master side of a contact pair and the group
    /// meeting obstacles beside it, unless the scene names `mass.contact_boundary` itself.
    pub also_along: Vec<String>,
}

impl MassSpec {
    /// Every group the mass-free layer runs along.
    pub fn layer_groups(&self) -> Vec<&str> {
        self.contact_boundary.iter().chain(&self.also_along).map(String::as_str).collect()
    }
}

/// Defaults for the step operator's KSP; command-line PETSc options still win.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SolverSpec {
    pub ksp_type: Option<String>,
    pub pc_type: Option<String>,
    /// In (0, 1).
    pub rtol: Option<f64>,
    /// Extra PETSc options, split on whitespace.
    pub options: Vec<String>,
}

/// A field that can be written to the output file: the state (nodal), and the stress-type
/// fields derived from the displacement (`fem::stress`), each as cell values (`stress`, ...)
/// and as their lumped L2 projection to the nodes (`stress_nodal`, ...).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Field {
    Displacement,
    Velocity,
    Stress,
    Strain,
    VonMises,
    EffectiveStress,
    Pressure,
    StressNodal,
    StrainNodal,
    VonMisesNodal,
    EffectiveStressNodal,
    PressureNodal,
    ContactTraction,
}

impl Field {
    /// Every field, in the order of the scene schema.
    pub const ALL: [Field; 13] = [
        Field::Displacement,
        Field::Velocity,
        Field::Stress,
        Field::Strain,
        Field::VonMises,
        Field::EffectiveStress,
        Field::Pressure,
        Field::StressNodal,
        Field::StrainNodal,
        Field::VonMisesNodal,
        Field::EffectiveStressNodal,
        Field::PressureNodal,
        Field::ContactTraction,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Field::Displacement => "displacement",
            Field::Velocity => "velocity",
            Field::Stress => "stress",
            Field::Strain => "strain",
            Field::VonMises => "von_mises",
            Field::EffectiveStress => "effective_stress",
            Field::Pressure => "pressure",
            Field::StressNodal => "stress_nodal",
            Field::StrainNodal => "strain_nodal",
            Field::VonMisesNodal => "von_mises_nodal",
            Field::EffectiveStressNodal => "effective_stress_nodal",
            Field::PressureNodal => "pressure_nodal",
            Field::ContactTraction => "contact_traction",
        }
    }

    /// For a stress-type field: the quantity and where it lives (cell values or their nodal
    /// projection); `None` for the state (displacement, velocity) and the contact traction.
    pub fn derived(self) -> Option<(crate::fem::stress::Quantity, crate::rows::Location)> {
        use crate::fem::stress::Quantity as Q;
        use crate::rows::Location::{Cell, Nodal};
        Some(match self {
            Field::Displacement | Field::Velocity | Field::ContactTraction => return None,
            Field::Stress => (Q::Stress, Cell),
            Field::Strain => (Q::Strain, Cell),
            Field::VonMises => (Q::VonMises, Cell),
            Field::EffectiveStress => (Q::EffectiveStress, Cell),
            Field::Pressure => (Q::Pressure, Cell),
            Field::StressNodal => (Q::Stress, Nodal),
            Field::StrainNodal => (Q::Strain, Nodal),
            Field::VonMisesNodal => (Q::VonMises, Nodal),
            Field::EffectiveStressNodal => (Q::EffectiveStress, Nodal),
            Field::PressureNodal => (Q::Pressure, Nodal),
        })
    }

    /// What the output writes for this field on a `dim`-dimensional mesh.
    pub fn spec(self, dim: usize) -> crate::rows::FieldSpec {
        use crate::rows::{FieldSpec, Location};
        match self.derived() {
            None => FieldSpec::nodal(self.name(), dim),
            Some((q, Location::Cell)) => FieldSpec::cell(self.name(), q.components()),
            Some((q, Location::Nodal)) => FieldSpec::nodal(self.name(), q.components()),
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct OutputSpec {
    /// As given, or `out/<name>.h5`; relative paths are relative to the working directory.
    pub file: PathBuf,
    /// Deflate level of the nodal fields (1-9; one-rank runs), None = off (the default).
    pub compression: Option<u8>,
    /// Write every k-th step, >= 1.
    pub every: usize,
    /// Per-field periods overriding `every` (`output.field_every`).
    pub field_every: Vec<(Field, usize)>,
    /// `output.times` as given.
    pub times: Vec<f64>,
    /// Also write at these steps (from `output.times`, the nearest steps), sorted.
    pub time_steps: Vec<usize>,
    /// Fields to write, in the order given, without duplicates.
    pub fields: Vec<Field>,
    /// Default false.
    pub progress: bool,
}

#[derive(Debug, Clone)]
pub struct ExactSpec {
    pub displacement: VecExpr,
    pub velocity: Option<VecExpr>,
    /// `gradient[i]` = row i: `d u_i / d x_j` for j = 0..dim. `None`: differentiate numerically.
    pub gradient: Option<Vec<VecExpr>>,
    /// Steps at which to report errors, sorted, no duplicates, each in 0..=steps
    /// (default: `[steps]`).
    pub error_steps: Vec<usize>,
    /// Whether the scene lists `exact.error_steps` (else the default follows the last step).
    pub error_steps_listed: bool,
}

/// The shape of a rigid obstacle in its reference position.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Half-space bounded by the plane (line in 2D) through `point`; `normal` is unit length.
    Plane { point: Vec<f64>, normal: Vec<f64> },
    /// Ball (disk in 2D) with `radius` > 0.
    Sphere { center: Vec<f64>, radius: f64 },
    /// Infinite cylinder (3D only: `point` and `axis` have 3 components) around the line
    /// through `point` along `axis` (unit length), `radius` > 0.
    Cylinder { point: Vec<f64>, axis: Vec<f64>, radius: f64 },
}

/// A rigid obstacle: its shape, and its rigid translation `d(t)` (the obstacle is at
/// reference + `d(t)`; expressions in `t` only) when it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    pub shape: Shape,
    pub motion: Option<VecExpr>,
    /// Its friction (its own `friction`/`tresca`, else `contact.friction`/`contact.tresca`);
    /// `None`: frictionless.
    pub friction: Option<FrictionSpec>,
}

/// A friction law as the scene gives it (`friction = MU` or `tresca = S`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionSpec {
    /// Coulomb's law with coefficient `mu > 0`.
    Coulomb(f64),
    /// Tresca's law: the slip bound `s >= 0` (a traction, like the pressure) wherever the node
    /// is in contact (verification).
    Tresca(f64),
}

impl FrictionSpec {
    /// `Coulomb, mu = 0.3` / `Tresca, bound = 2`.
    pub fn describe(&self) -> String {
        match self {
            FrictionSpec::Coulomb(mu) => {
                format!("Coulomb, mu = {}", super::effects::short_number(*mu))
            }
            FrictionSpec::Tresca(s) => {
                format!("Tresca, bound = {}", super::effects::short_number(*s))
            }
        }
    }
}

impl Obstacle {
    /// A translation that depends on `t` is given (as written: `0*t` counts).
    pub fn is_moving(&self) -> bool {
        self.motion.as_ref().is_some_and(VecExpr::depends_on_t)
    }
}

/// A slave/master pair of deformable bodies: the slave group's nodes carry the dual mortar
/// multipliers, the master group's facets are integrated against them.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactPair {
    pub slave: String,
    pub master: String,
    /// Its friction (its own, else the contact's); `None`: frictionless.
    pub friction: Option<FrictionSpec>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct ContactSpec {
    /// Slave/master pairs (`contact.slave` and `contact.master`, or `contact.pairs`); empty
    /// for contact with rigid obstacles alone. No slave group is a master group.
    pub pairs: Vec<ContactPair>,
    /// `contact.boundary`: the group whose nodes meet the rigid obstacles, alone or beside the
    /// pairs (then no slave or master group).
    pub boundary: Option<String>,
    /// At least one unless there are pairs and no `boundary`; each contact node that is not a
    /// slave node meets the one with the smallest gap.
    pub obstacles: Vec<Obstacle>,
    /// Given as the list `contact.obstacles` (else as `contact.obstacle`).
    pub listed: bool,
}

impl ContactSpec {
    /// The scene key of obstacle `i`: `contact.obstacle` or `contact.obstacles[i]`.
    pub fn obstacle_key(&self, i: usize) -> String {
        obstacle_key(self.listed, i)
    }

    /// Whether some obstacle or pair has friction.
    pub fn has_friction(&self) -> bool {
        self.obstacles.iter().any(|o| o.friction.is_some())
            || self.pairs.iter().any(|p| p.friction.is_some())
    }

    /// The groups meeting obstacles beside pairs: `boundary` when there are pairs.
    pub fn obstacle_boundary(&self) -> Option<&str> {
        if self.pairs.is_empty() {
            None
        } else {
            self.boundary.as_deref()
        }
    }

    /// Every contact group once: the slave groups, the master groups, then `boundary`.
    pub fn groups(&self) -> Vec<&str> {
        once_each(
            (self.pairs.iter().map(|p| p.slave.as_str()))
                .chain(self.pairs.iter().map(|p| p.master.as_str()))
                .chain(self.boundary.as_deref()),
        )
    }

    /// The slave groups once each, in pair order.
    pub fn slave_groups(&self) -> Vec<&str> {
        slave_groups(&self.pairs)
    }

    /// The master groups once each, in pair order.
    pub fn master_groups(&self) -> Vec<&str> {
        master_groups(&self.pairs)
    }
}

/// The slave groups of `pairs` once each, in pair order (pairs may share a slave group).
pub fn slave_groups(pairs: &[ContactPair]) -> Vec<&str> {
    once_each(pairs.iter().map(|p| p.slave.as_str()))
}

/// The master groups of `pairs` once each, in pair order (pairs may share a master group).
pub fn master_groups(pairs: &[ContactPair]) -> Vec<&str> {
    once_each(pairs.iter().map(|p| p.master.as_str()))
}

/// Each group once, where it first appears: the one de-duplication of contact group names.
fn once_each<'a>(groups: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for g in groups {
        if !out.contains(&g) {
            out.push(g);
        }
    }
    out
}

pub(super) fn obstacle_key(listed: bool, i: usize) -> String {
    if listed {
        format!("contact.obstacles[{i}]")
    } else {
        "contact.obstacle".to_string()
    }
}

impl Scene {
    /// The output period of a field: `output.field_every.<field>`, else `output.every`.
    pub fn every_of(&self, f: Field) -> usize {
        self.output.field_every.iter().find(|(g, _)| *g == f).map_or(self.output.every, |&(_, k)| k)
    }

    /// Override one `.geo` parameter from the command line: `NAME=VALUE`, e.g. `h=0.0625`.
    pub fn set_mesh_param(&mut self, assignment: &str) -> Result<()> {
        let bad = |m: &str| Err(Error::Usage(format!("--param {assignment}: {m}")));
        let Some((name, value)) = assignment.split_once('=') else {
            return bad("expected NAME=VALUE, e.g. h=0.0625");
        };
        let Ok(value) = value.trim().parse::<f64>() else {
            return bad("the value is not a number");
        };
        match &mut self.mesh {
            MeshSource::Geo { params, path, .. } => {
                let name = name.trim().to_string();
                // gmsh ignores a -setnumber the .geo does not declare: a misspelt name would
                // silently mesh the default.
                if let Ok(text) = std::fs::read_to_string(&*path) {
                    let declared = crate::mesh::gmsh::declared_parameters(&text);
                    if !declared.contains(&name) {
                        return bad(&format!(
                            "{} declares no parameter \"{name}\" (it has: {})",
                            path.display(),
                            if declared.is_empty() {
                                "none".to_string()
                            } else {
                                declared.join(", ")
                            }
                        ));
                    }
                }
                params.retain(|(n, _)| *n != name);
                params.push((name, value));
                params.sort_by(|a, b| a.0.cmp(&b.0));
                Ok(())
            }
            MeshSource::Msh { .. } => {
                bad("the scene reads a .msh file; parameters apply to mesh.geo")
            }
        }
    }

    /// Override the mass treatment from the command line (`--mass modified1`); the same rule
    /// as in the scene: a modified mass needs `mass.contact_boundary`. It replaces `mass.kind`,
    /// the default: a `[[body]]` with its own `mass` keeps it.
    pub fn set_mass_kind(&mut self, name: &str) -> Result<()> {
        let kind = MassKind::from_name(name).ok_or_else(|| {
            Error::Usage(format!(
                "--mass {name}: unknown mass kind (allowed: consistent, lumped, modified0, modified1)"
            ))
        })?;
        if kind.is_modified() && self.mass.contact_boundary.is_none() {
            return Err(Error::Usage(format!(
                "--mass {name} needs mass.contact_boundary in the scene {}: the mass-free layer is built along the potential contact boundary",
                self.display_name()
            )));
        }
        self.mass.kind = kind;
        Ok(())
    }

    /// The constitutive model of `[material]` and of every body that does not name its own
    /// (`--model`).
    pub fn set_model(&mut self, name: &str) -> Result<()> {
        let model = Model::from_name(name).ok_or_else(|| {
            Error::Usage(format!(
                "--model {name}: unknown model (allowed: linear, neo_hookean, saint_venant_kirchhoff)"
            ))
        })?;
        self.material.model = model;
        for b in self.bodies.iter_mut().filter(|b| !b.sets[3]) {
            b.material.model = model;
        }
        Ok(())
    }

    /// Give every obstacle and pair Coulomb's friction `mu` (`--friction`; 0: frictionless).
    pub fn set_friction(&mut self, mu: f64) -> Result<()> {
        if !(mu >= 0.0 && mu.is_finite()) {
            return Err(Error::Usage(format!(
                "--friction {mu}: the friction coefficient must be >= 0 and finite"
            )));
        }
        let Some(c) = self.contact.as_mut() else {
            return Err(Error::Usage(format!(
                "--friction {mu}: the scene {} has no [contact]",
                self.display_name()
            )));
        };
        let law = (mu > 0.0).then_some(FrictionSpec::Coulomb(mu));
        c.obstacles.iter_mut().for_each(|o| o.friction = law);
        c.pairs.iter_mut().for_each(|p| p.friction = law);
        Ok(())
    }

    /// The mass treatment of `body[i]`: its own `mass`, else `mass.kind`.
    pub fn body_mass(&self, i: usize) -> MassKind {
        self.bodies[i].mass.unwrap_or(self.mass.kind)
    }

    /// The end time `steps * tau`.
    pub fn end_time(&self) -> f64 {
        self.steps as f64 * self.tau
    }

    /// Every group contact or the mass-free layer looks at, once: the contact groups, then the
    /// layer's. The ranks gather these surfaces whole (`partition::surface`).
    /// The layer's only when some mass is modified (a consistent run with
    /// `mass.contact_boundary` set builds no layer and gathers nothing for it).
    pub fn surface_groups(&self) -> Vec<&str> {
        let contact = self.contact.as_ref().map(|c| c.groups()).unwrap_or_default();
        let modified = self.mass.kind.is_modified()
            || (0..self.bodies.len()).any(|i| self.body_mass(i).is_modified());
        let layer = if modified { self.mass.layer_groups() } else { Vec::new() };
        once_each(contact.into_iter().chain(layer))
    }

    /// Checks that every vector-valued key has exactly `dim` components (and that explicitly
    /// listed Dirichlet components exist in `dim` dimensions).
    pub fn check_dim(&self, dim: usize) -> Result<()> {
        let fail = |m: String| Err(Error::Scene(format!("{}: {m}", self.display_name())));
        if !(2..=3).contains(&dim) {
            return fail(format!("the mesh is {dim}D: only 2D and 3D meshes are supported"));
        }
        let mut keys: Vec<(String, usize)> = Vec::new();
        for (i, d) in self.dirichlet.iter().enumerate() {
            if !d.value.is_empty() {
                keys.push((format!("dirichlet[{i}].value"), d.value.len()));
            }
            if d.components_given {
                if let Some(&c) = d.components.iter().find(|&&c| c >= dim) {
                    return fail(format!(
                        "dirichlet[{i}].components includes \"{}\" but the mesh is {dim}D",
                        ["x", "y", "z"][c.min(2)]
                    ));
                }
            }
        }
        for (i, n) in self.neumann.iter().enumerate() {
            keys.push((format!("neumann[{i}].traction"), n.traction.len()));
        }
        let mut opt = |k: &str, v: Option<&VecExpr>| {
            if let Some(v) = v {
                keys.push((k.to_string(), v.len()));
            }
        };
        opt("body_force.value", self.body_force.as_ref());
        opt("body_force.acceleration", self.body_acceleration.as_ref());
        opt("initial.displacement", self.initial_displacement.as_ref());
        opt("initial.velocity", self.initial_velocity.as_ref());
        if let Some(ex) = &self.exact {
            opt("exact.displacement", Some(&ex.displacement));
            opt("exact.velocity", ex.velocity.as_ref());
            if let Some(g) = &ex.gradient {
                keys.push(("exact.gradient".to_string(), g.len()));
                for (i, row) in g.iter().enumerate() {
                    keys.push((format!("exact.gradient[{i}]"), row.len()));
                }
            }
        }
        if let Some(c) = &self.contact {
            for (i, o) in c.obstacles.iter().enumerate() {
                let key = c.obstacle_key(i);
                let mut vector =
                    |name: &str, v: &[f64]| keys.push((format!("{key}.{name}"), v.len()));
                match &o.shape {
                    Shape::Plane { point, normal } => {
                        vector("point", point);
                        vector("normal", normal);
                    }
                    Shape::Sphere { center, .. } => vector("center", center),
                    Shape::Cylinder { .. } if dim == 2 => {
                        return fail(format!(
                            "{key} is a cylinder but the mesh is 2D: cylinders exist in 3D only"
                        ));
                    }
                    Shape::Cylinder { point, axis, .. } => {
                        vector("point", point);
                        vector("axis", axis);
                    }
                }
                if let Some(m) = &o.motion {
                    keys.push((format!("{key}.motion"), m.len()));
                }
            }
        }
        for (k, n) in keys {
            if n != dim {
                let what = if k == "exact.gradient" { "rows" } else { "components" };
                return fail(format!("{k} has {n} {what} but the mesh is {dim}D"));
            }
        }
        Ok(())
    }

    /// The scene file's name, as error messages start.
    pub(crate) fn display_name(&self) -> String {
        self.source
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_else(|| self.source.display().to_string())
    }
}

// =============================================================================================
// The rule of `time.end`

/// Why an end time is not a whole number of time steps (the rule of `time.end`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EndSteps {
    /// The end time is not a finite number > 0.
    NotPositive,
    /// `end / tau` rounds to 0.
    ShorterThanOneStep,
    /// `end / tau` is more than 1e-9 (relative) away from a whole number.
    NotWhole { ratio: f64 },
    /// More than 1e15 steps.
    TooMany { n: f64 },
}

impl EndSteps {
    /// The scene's message for `time.end = end` with `time.tau = tau`.
    pub fn message(self, end: f64, tau: f64) -> String {
        match self {
            EndSteps::NotPositive => {
                format!("time.end = {end} is impossible: the end time must be > 0")
            }
            EndSteps::ShorterThanOneStep => format!(
                "time.end = {end} is impossible: it is shorter than one step (time.tau = {tau})"
            ),
            EndSteps::NotWhole { ratio } => format!(
                "time.end = {end} is impossible: it is not a whole number of steps of time.tau = {tau} (end/tau = {ratio})"
            ),
            EndSteps::TooMany { n } => format!("time.end = {end}: too many steps ({n})"),
        }
    }
}

/// The number of steps of `tau` (> 0) that end at `end`, the rule of `time.end`: `end / tau`
/// rounded, when that is a whole number to 1e-9 (relative), at least 1 and at most 1e15.
pub fn steps_to_end(end: f64, tau: f64) -> std::result::Result<usize, EndSteps> {
    if !(end > 0.0 && end.is_finite()) {
        return Err(EndSteps::NotPositive);
    }
    let ratio = end / tau;
    let n = ratio.round();
    if n < 1.0 {
        return Err(EndSteps::ShorterThanOneStep);
    }
    if (ratio - n).abs() > 1e-9 * ratio {
        return Err(EndSteps::NotWhole { ratio });
    }
    if n > 1e15 {
        return Err(EndSteps::TooMany { n });
    }
    Ok(n as usize)
}
