//! What a run simulates: the effects a scene asks for, and the one-line report of them.
//!
//! Elasticity and a mass matrix are always built; everything else only when the scene asks
//! for it: a value that is identically zero (`"0"`, `"2-2"`) asks for nothing.
//! [`Effects::summary`] is the line a run prints and stores, e.g.
//!
//! ```text
//! effects: elasticity, mass-free layer (modified1 along "contact"), Dirichlet (zero values), contact (plane obstacle); not built: initial displacement, initial velocity, body force, tractions, Dirichlet lifting, exact errors, stress output
//! ```

use super::model::{BodySpec, Formulation, MassKind, Model, Obstacle, Scene, Shape};
use crate::scene::expr::VecExpr;

/// How a load or prescribed value varies in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variation {
    /// Constant in time: assembled once.
    Steady,
    /// Depends on `t` (as written; `0*t` counts).
    TimeDependent,
}

impl Variation {
    /// Of the non-zero fields among `fields`; None if all are zero (or there are none).
    fn of<'a>(fields: impl IntoIterator<Item = &'a VecExpr>) -> Option<Variation> {
        let mut nonzero = fields.into_iter().filter(|f| !f.is_zero()).peekable();
        nonzero.peek()?;
        Some(if nonzero.any(|f| f.depends_on_t()) {
            Variation::TimeDependent
        } else {
            Variation::Steady
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            Variation::Steady => "steady",
            Variation::TimeDependent => "time-dependent",
        }
    }
}

/// The shape of a contact obstacle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObstacleKind {
    Plane,
    Sphere,
    Cylinder,
}

impl ObstacleKind {
    pub fn name(self) -> &'static str {
        match self {
            ObstacleKind::Plane => "plane",
            ObstacleKind::Sphere => "sphere",
            ObstacleKind::Cylinder => "cylinder",
        }
    }
}

/// One contact obstacle as a run reports it: its shape, and whether it moves (a motion that
/// depends on `t`; a constant one only shifts it).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ObstacleEffect {
    pub kind: ObstacleKind,
    pub moving: bool,
}

impl ObstacleEffect {
    pub fn of(o: &Obstacle) -> ObstacleEffect {
        let kind = match o.shape {
            Shape::Plane { .. } => ObstacleKind::Plane,
            Shape::Sphere { .. } => ObstacleKind::Sphere,
            Shape::Cylinder { .. } => ObstacleKind::Cylinder,
        };
        ObstacleEffect { kind, moving: o.is_moving() }
    }

    /// `plane`, `moving plane`, ...
    pub fn name(self) -> String {
        let moving = if self.moving { "moving " } else { "" };
        format!("{moving}{}", self.kind.name())
    }
}

/// What the scene asks the program to build and compute (everything else is skipped).
/// Elasticity (the stiffness operator) is always built and has no field.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Effects {
    /// `mass.kind`: the mass treatment of the cells outside every `[[body]]` with its own.
    pub mass: MassKind,
    /// The standard mass matrices built (consistent, lumped), in that order: without
    /// `[[body]]` the one of `mass.kind`, or none for a modified kind.
    pub standard_masses: Vec<MassKind>,
    /// The mass-free layer: its kind and the groups it is built along (`"a" and "b"`);
    /// `Some` exactly when a layer is built.
    pub layer: Option<(MassKind, String)>,
    /// `[[body]]`, each briefly: `"lower": E = 400, mass consistent` (the values it sets).
    pub bodies: Vec<String>,
    /// `[material]`'s constitutive model when it is a finite-strain one (bodies that set
    /// their own say so in `bodies`).
    pub finite_strain: Option<Model>,
    /// `[material]`'s formulation is the mixed (mean-dilatation) one.
    pub mixed: bool,
    /// A non-zero initial displacement / velocity is interpolated (else the body starts at rest
    /// in its reference configuration).
    pub initial_displacement: bool,
    pub initial_velocity: bool,
    /// A body force that is not identically zero.
    pub body_force: Option<Variation>,
    /// Some Neumann boundary with a traction that is not identically zero.
    pub tractions: Option<Variation>,
    /// Some Dirichlet condition constrains displacement components.
    pub dirichlet: bool,
    /// Some Dirichlet value is not identically zero: the step needs the Dirichlet lifting, i.e.
    /// the extra unconstrained operator that moves the prescribed values to the right-hand side.
    pub dirichlet_lifting: Option<Variation>,
    /// Contact with these obstacles (the active-set solver); empty: no contact.
    pub contact: Vec<ObstacleEffect>,
    /// Errors against the exact solution are computed (at `exact.error_steps`).
    pub exact_errors: bool,
    /// Two-body contact: (slave group, master group), dual mortar.
    pub contact_pairs: Vec<(String, String)>,
    /// Beside a pair: the group that meets the obstacles of `contact`.
    pub contact_obstacle_boundary: Option<String>,
    /// The friction laws of the obstacles and pairs that have one (`Coulomb, mu = 0.3`), each
    /// once in the order of the scene; empty: frictionless (or no contact).
    pub friction: Vec<String>,
    /// The stress-type output fields asked for (their names, in the scene's order).
    pub stress_fields: Vec<&'static str>,
}

impl Scene {
    /// What must be built: only what the scene asks for.
    ///
    /// With `[[body]]` of different mass kinds, which contact group lies on which body is known
    /// only with the mesh: the layer then reads `KIND along "a" and "b", on the bodies with that
    /// mass` until [`Effects::resolve`] states it.
    pub fn effects(&self) -> Effects {
        let groups = self.mass.layer_groups();
        // The kinds of the cells outside every body and of the bodies (all in use, as far as
        // the scene tells).
        let mut kinds = vec![self.mass.kind];
        kinds.extend((0..self.bodies.len()).map(|i| self.body_mass(i)));
        let standard_masses =
            MassKind::ALL.into_iter().filter(|k| !k.is_modified() && kinds.contains(k)).collect();
        let modified: Vec<MassKind> =
            MassKind::ALL.into_iter().filter(|k| k.is_modified() && kinds.contains(k)).collect();
        let layer = match modified.as_slice() {
            [] => None,
            _ if groups.is_empty() => None,
            [k] if kinds.iter().all(|c| c == k) => Some((*k, quoted(&groups))),
            [k, ..] => Some((*k, format!("{}, on the bodies with that mass", quoted(&groups)))),
        };
        let nonzero = |f: &Option<VecExpr>| f.as_ref().is_some_and(|f| !f.is_zero());
        Effects {
            mass: self.mass.kind,
            standard_masses,
            layer,
            bodies: self.bodies.iter().map(body_brief).collect(),
            finite_strain: Some(self.material.model).filter(|m| m.is_finite_strain()),
            mixed: self.material.formulation == Formulation::Mixed,
            initial_displacement: nonzero(&self.initial_displacement),
            initial_velocity: nonzero(&self.initial_velocity),
            body_force: Variation::of(self.body_force.iter().chain(&self.body_acceleration)),
            tractions: Variation::of(self.neumann.iter().map(|n| &n.traction)),
            dirichlet: !self.dirichlet.is_empty(),
            dirichlet_lifting: Variation::of(self.dirichlet.iter().map(|d| &d.value)),
            contact: self
                .contact
                .iter()
                .flat_map(|c| &c.obstacles)
                .map(ObstacleEffect::of)
                .collect(),
            contact_pairs: (self.contact.iter())
                .flat_map(|c| &c.pairs)
                .map(|p| (p.slave.clone(), p.master.clone()))
                .collect(),
            contact_obstacle_boundary: (self.contact.as_ref())
                .and_then(|c| c.obstacle_boundary().map(String::from)),
            friction: {
                let mut laws: Vec<String> = Vec::new();
                let c = self.contact.as_ref();
                let all = c.iter().flat_map(|c| {
                    (c.obstacles.iter().map(|o| o.friction))
                        .chain(c.pairs.iter().map(|p| p.friction))
                });
                for f in all.flatten().map(|f| f.describe()) {
                    if !laws.contains(&f) {
                        laws.push(f);
                    }
                }
                laws
            },
            exact_errors: self.exact.is_some(),
            stress_fields: (self.output.fields.iter())
                .filter(|f| f.derived().is_some())
                .map(|f| f.name())
                .collect(),
        }
    }
}

/// `"a" and "b"`.
pub fn quoted<S: AsRef<str>>(groups: &[S]) -> String {
    groups.iter().map(|g| format!("\"{}\"", g.as_ref())).collect::<Vec<_>>().join(" and ")
}

/// `"lower": E = 400, rho = 2e-8, mass consistent`: a body's group and what it sets.
fn body_brief(b: &BodySpec) -> String {
    let names = ["E", "nu", "rho"];
    let values = [b.material.e, b.material.nu, b.material.rho];
    let mut items: Vec<String> = (0..3)
        .filter(|&k| b.sets[k])
        .map(|k| format!("{} = {}", names[k], short_number(values[k])))
        .collect();
    if b.sets[3] {
        items.push(format!("model {}", b.material.model.name()));
    }
    if b.material.formulation != Formulation::Displacement {
        items.push(format!("formulation {}", b.material.formulation.name()));
    }
    if let Some(m) = b.mass {
        items.push(format!("mass {}", m.name()));
    }
    if items.is_empty() {
        format!("\"{}\"", b.group)
    } else {
        format!("\"{}\": {}", b.group, items.join(", "))
    }
}

/// `200`, `0.3`, `2e-8`: the shorter of the plain and the exponent form.
pub fn short_number(x: f64) -> String {
    let (plain, exp) = (format!("{x}"), format!("{x:e}"));
    if plain.len() <= exp.len() {
        plain
    } else {
        exp
    }
}

impl Effects {
    /// The mass treatment as the mesh resolved it (`crate::bodies::Bodies`): the standard
    /// mass kinds with cells, and the layer's kind and groups.
    pub fn resolve(
        mut self,
        standard: Vec<MassKind>,
        layer: Option<(MassKind, &[String])>,
    ) -> Self {
        self.standard_masses = standard;
        self.layer = layer.map(|(k, groups)| (k, quoted(groups)));
        self
    }

    /// One line: `effects: A, B, C; not built: X, Y` (`not built: none` when nothing is left).
    ///
    /// The items, always in this order:
    /// 1. `elasticity` (always built; `elasticity (finite strain, MODEL)` when `[material]`
    ///    has a finite-strain model), then with `[[body]]` `bodies (BODY; BODY; ...)`, each
    ///    `"GROUP": E = .., nu = .., rho = .., model MODEL, mass KIND` with what it sets;
    /// 2. the mass (always built): `consistent mass`, `lumped mass` and/or
    ///    `mass-free layer (KIND along "GROUP" and "GROUP")`;
    /// 3. `initial displacement`, 4. `initial velocity`;
    /// 5. `body force (steady | time-dependent)`, 6. `tractions (steady | time-dependent)`;
    /// 7. `Dirichlet (zero values | non-zero values)`,
    ///    8. `Dirichlet lifting (steady | time-dependent)`;
    /// 9. `contact (OBSTACLE obstacle)` with one obstacle, `contact (N obstacles: OBSTACLE,
    ///    OBSTACLE, ...)` with several, each `[moving ](plane | sphere | cylinder)`; a pair:
    ///    `contact (two bodies, slave "S" on master "M", dual mortar)`, with obstacles beside
    ///    it followed by `; "GROUP" on OBSTACLES` (as above);
    /// 10. `friction (Coulomb, mu = MU)` or `friction (Tresca, bound = S)`, several laws
    ///     joined by `; `;
    /// 11. `exact errors`, 12. `stress output (FIELD, FIELD, ...)`.
    ///
    /// `not built:` lists, in the same order and by the names before the parentheses, the
    /// optional items 3 to 11 the scene does not ask for, preceded by `mass-free layer` when
    /// there is none (`bodies` is never listed there).
    pub fn summary(&self) -> String {
        let with = |name: &str, what: Option<&str>| what.map(|w| format!("{name} ({w})"));
        let flag = |name: &str, on: bool| on.then(|| name.to_string());
        let dirichlet_values =
            if self.dirichlet_lifting.is_some() { "non-zero values" } else { "zero values" };
        let names: Vec<String> = self.contact.iter().map(|o| o.name()).collect();
        let obstacles = match names.len() {
            0 => None,
            1 => Some(format!("{} obstacle", names[0])),
            n => Some(format!("{n} obstacles: {}", names.join(", "))),
        };
        let sides: Vec<String> = self
            .contact_pairs
            .iter()
            .map(|(s, m)| format!("slave {s:?} on master {m:?}"))
            .collect();
        let pair = match sides.len() {
            0 => None,
            1 => Some(format!("two bodies, {}, dual mortar", sides[0])),
            n => Some(format!("{n} pairs: {}, dual mortar", sides.join(", "))),
        };
        let obstacle = match (pair, obstacles) {
            (Some(p), Some(o)) => {
                let g = self.contact_obstacle_boundary.as_deref().unwrap_or_default();
                Some(format!("{p}; {g:?} on {o}"))
            }
            (p, o) => p.or(o),
        };
        let layer = self.layer.as_ref().map(|(k, g)| format!("{} along {g}", k.name()));
        let stress = (!self.stress_fields.is_empty()).then(|| self.stress_fields.join(", "));
        let friction = (!self.friction.is_empty()).then(|| self.friction.join("; "));
        let optional: [(&str, Option<String>); 11] = [
            ("mass-free layer", with("mass-free layer", layer.as_deref())),
            ("initial displacement", flag("initial displacement", self.initial_displacement)),
            ("initial velocity", flag("initial velocity", self.initial_velocity)),
            ("body force", with("body force", self.body_force.map(Variation::name))),
            ("tractions", with("tractions", self.tractions.map(Variation::name))),
            ("Dirichlet", with("Dirichlet", Some(dirichlet_values).filter(|_| self.dirichlet))),
            (
                "Dirichlet lifting",
                with("Dirichlet lifting", self.dirichlet_lifting.map(Variation::name)),
            ),
            ("contact", with("contact", obstacle.as_deref())),
            ("friction", with("friction", friction.as_deref())),
            ("exact errors", flag("exact errors", self.exact_errors)),
            ("stress output", with("stress output", stress.as_deref())),
        ];
        let mut built = vec![match (self.finite_strain, self.mixed) {
            (Some(m), true) => {
                let mixed = "mixed: mean dilatation, nodal pressure on simplices";
                format!("elasticity (finite strain, {}, {mixed})", m.name())
            }
            (Some(m), false) => format!("elasticity (finite strain, {})", m.name()),
            (None, true) => {
                "elasticity (mixed: mean dilatation, nodal pressure on simplices)".to_string()
            }
            (None, false) => "elasticity".to_string(),
        }];
        if !self.bodies.is_empty() {
            built.push(format!("bodies ({})", self.bodies.join("; ")));
        }
        built.extend(self.standard_masses.iter().map(|k| format!("{} mass", k.name())));
        let mut skipped = Vec::new();
        for (name, item) in optional {
            match item {
                Some(text) => built.push(text),
                None => skipped.push(name),
            }
        }
        let skipped = if skipped.is_empty() { "none".to_string() } else { skipped.join(", ") };
        format!("effects: {}; not built: {skipped}", built.join(", "))
    }
}
