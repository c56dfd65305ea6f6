//! What a run simulates: the effects a scene asks for, and the one-line report of them.
//!
//! Elasticity and a mass matrix are always built; everything else only when the scene asks
//! for it: a value that is identically zero (`"0"`, `"2-2"`) asks for nothing.
//! [`Effects::summary`] is the line a run prints and stores, e.g.
//!
//! ```text
//! effects: elasticity, mass-free layer (modified1 along "contact"), Dirichlet (zero values), contact (plane obstacle); not built: initial displacement, initial velocity, body force, tractions, Dirichlet lifting, exact errors
//! ```

use super::{MassKind, Obstacle, Scene, Shape};
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
    /// The mass treatment (always built).
    pub mass: MassKind,
    /// The group the mass-free layer is built along: `Some` exactly for the modified kinds.
    pub layer_boundary: Option<String>,
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
    pub contact_pair: Option<(String, String)>,
}

impl Scene {
    /// What must be built: only what the scene asks for.
    pub fn effects(&self) -> Effects {
        let groups: Vec<String> =
            self.mass.layer_groups().iter().map(|g| format!("\"{g}\"")).collect();
        let layer_boundary = Some(groups.join(" and "))
            .filter(|_| self.mass.kind.is_modified() && !groups.is_empty());
        let nonzero = |f: &Option<VecExpr>| f.as_ref().is_some_and(|f| !f.is_zero());
        Effects {
            mass: self.mass.kind,
            layer_boundary,
            initial_displacement: nonzero(&self.initial_displacement),
            initial_velocity: nonzero(&self.initial_velocity),
            body_force: Variation::of(&self.body_force),
            tractions: Variation::of(self.neumann.iter().map(|n| &n.traction)),
            dirichlet: !self.dirichlet.is_empty(),
            dirichlet_lifting: Variation::of(self.dirichlet.iter().map(|d| &d.value)),
            contact: self
                .contact
                .iter()
                .flat_map(|c| &c.obstacles)
                .map(ObstacleEffect::of)
                .collect(),
            contact_pair: self
                .contact
                .as_ref()
                .and_then(|c| c.master.as_ref().map(|m| (c.boundary.clone(), m.clone()))),
            exact_errors: self.exact.is_some(),
        }
    }
}

impl Effects {
    /// One line: `effects: A, B, C; not built: X, Y` (`not built: none` when nothing is left).
    ///
    /// The items, always in this order:
    /// 1. `elasticity` (always built);
    /// 2. the mass (always built): `consistent mass`, `lumped mass`, or
    ///    `mass-free layer (KIND along "GROUP")`;
    /// 3. `initial displacement`, 4. `initial velocity`;
    /// 5. `body force (steady | time-dependent)`, 6. `tractions (steady | time-dependent)`;
    /// 7. `Dirichlet (zero values | non-zero values)`,
    ///    8. `Dirichlet lifting (steady | time-dependent)`;
    /// 9. `contact (OBSTACLE obstacle)` with one obstacle, `contact (N obstacles: OBSTACLE,
    ///    OBSTACLE, ...)` with several, each `[moving ](plane | sphere | cylinder)`;
    /// 10. `exact errors`.
    ///
    /// `not built:` lists, in the same order and by the names before the parentheses, the
    /// optional items 3 to 10 the scene does not ask for, preceded by `mass-free layer` when
    /// the mass is consistent or lumped.
    pub fn summary(&self) -> String {
        let with = |name: &str, what: Option<&str>| what.map(|w| format!("{name} ({w})"));
        let flag = |name: &str, on: bool| on.then(|| name.to_string());
        let dirichlet_values =
            if self.dirichlet_lifting.is_some() { "non-zero values" } else { "zero values" };
        let names: Vec<String> = self.contact.iter().map(|o| o.name()).collect();
        let obstacle = match names.len() {
            0 => self
                .contact_pair
                .as_ref()
                .map(|(s, m)| format!("two bodies, slave {s:?} on master {m:?}, dual mortar")),
            1 => Some(format!("{} obstacle", names[0])),
            n => Some(format!("{n} obstacles: {}", names.join(", "))),
        };
        let layer = self.layer_boundary.as_ref().map(|g| format!("{} along {g}", self.mass.name()));
        let optional: [(&str, Option<String>); 9] = [
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
            ("exact errors", flag("exact errors", self.exact_errors)),
        ];
        let mut built = vec!["elasticity".to_string()];
        if self.layer_boundary.is_none() {
            built.push(format!("{} mass", self.mass.name()));
        }
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
