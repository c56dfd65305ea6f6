//! The scene file as serde reads it: one `Raw*` type per table, every key optional where the
//! scene allows leaving it out, unknown keys rejected. [`super::validate`] turns it into a
//! [`super::Scene`]; nothing here checks a value.

use super::model::{Field, MassKind};
use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;

/// An expression as written: a string, or a plain number.
#[derive(Debug, Clone)]
pub(super) enum ExprSrc {
    Text(String),
    Num(f64),
}

impl<'de> Deserialize<'de> for ExprSrc {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = ExprSrc;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("an expression string or a number")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> std::result::Result<ExprSrc, E> {
                Ok(ExprSrc::Text(v.to_string()))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<ExprSrc, E> {
                Ok(ExprSrc::Num(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> std::result::Result<ExprSrc, E> {
                Ok(ExprSrc::Num(v as f64))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<ExprSrc, E> {
                Ok(ExprSrc::Num(v))
            }
        }
        d.deserialize_any(V)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    pub(super) name: Option<String>,
    pub(super) mesh: RawMesh,
    pub(super) material: RawMaterial,
    #[serde(default)]
    pub(super) body: Vec<RawBody>,
    #[serde(default)]
    pub(super) dirichlet: Vec<RawDirichlet>,
    #[serde(default)]
    pub(super) neumann: Vec<RawNeumann>,
    pub(super) body_force: Option<RawBodyForce>,
    pub(super) initial: Option<RawInitial>,
    pub(super) time: RawTime,
    pub(super) mass: Option<RawMass>,
    pub(super) solver: Option<RawSolver>,
    pub(super) output: Option<RawOutput>,
    pub(super) exact: Option<RawExact>,
    pub(super) contact: Option<RawContact>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMesh {
    pub(super) geo: Option<String>,
    pub(super) msh: Option<String>,
    pub(super) params: Option<BTreeMap<String, f64>>,
    pub(super) binary: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMaterial {
    #[serde(rename = "E")]
    pub(super) e: f64,
    pub(super) nu: f64,
    pub(super) rho: f64,
    pub(super) model: Option<String>,
    pub(super) formulation: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBody {
    pub(super) group: String,
    #[serde(rename = "E")]
    pub(super) e: Option<f64>,
    pub(super) nu: Option<f64>,
    pub(super) rho: Option<f64>,
    pub(super) mass: Option<MassKind>,
    pub(super) model: Option<String>,
    pub(super) formulation: Option<String>,
}

#[derive(Deserialize, Clone, Copy, PartialEq)]
#[serde(rename_all = "lowercase")]
pub(super) enum Component {
    X,
    Y,
    Z,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawDirichlet {
    pub(super) group: String,
    pub(super) value: Option<Vec<ExprSrc>>,
    pub(super) components: Option<Vec<Component>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawNeumann {
    pub(super) group: String,
    pub(super) traction: Vec<ExprSrc>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBodyForce {
    pub(super) value: Option<Vec<ExprSrc>>,
    pub(super) acceleration: Option<Vec<ExprSrc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInitial {
    pub(super) displacement: Option<Vec<ExprSrc>>,
    pub(super) velocity: Option<Vec<ExprSrc>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawTime {
    pub(super) tau: f64,
    pub(super) steps: Option<i64>,
    pub(super) end: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMass {
    pub(super) kind: Option<MassKind>,
    pub(super) contact_boundary: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSolver {
    pub(super) ksp_type: Option<String>,
    pub(super) pc_type: Option<String>,
    pub(super) rtol: Option<f64>,
    pub(super) options: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawOutput {
    pub(super) file: Option<String>,
    pub(super) compression: Option<i64>,
    pub(super) every: Option<i64>,
    pub(super) field_every: Option<RawFieldEvery>,
    pub(super) times: Option<Vec<f64>>,
    pub(super) fields: Option<Vec<Field>>,
    pub(super) progress: Option<bool>,
}

/// Per-field output periods, overriding `output.every` (one key per [`Field`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFieldEvery {
    displacement: Option<i64>,
    velocity: Option<i64>,
    stress: Option<i64>,
    strain: Option<i64>,
    von_mises: Option<i64>,
    effective_stress: Option<i64>,
    pressure: Option<i64>,
    stress_nodal: Option<i64>,
    strain_nodal: Option<i64>,
    von_mises_nodal: Option<i64>,
    effective_stress_nodal: Option<i64>,
    pressure_nodal: Option<i64>,
    contact_traction: Option<i64>,
}

impl RawFieldEvery {
    /// The period given for `f`, if any.
    pub(super) fn of(&self, f: Field) -> Option<i64> {
        match f {
            Field::Displacement => self.displacement,
            Field::Velocity => self.velocity,
            Field::Stress => self.stress,
            Field::Strain => self.strain,
            Field::VonMises => self.von_mises,
            Field::EffectiveStress => self.effective_stress,
            Field::Pressure => self.pressure,
            Field::StressNodal => self.stress_nodal,
            Field::StrainNodal => self.strain_nodal,
            Field::VonMisesNodal => self.von_mises_nodal,
            Field::EffectiveStressNodal => self.effective_stress_nodal,
            Field::PressureNodal => self.pressure_nodal,
            Field::ContactTraction => self.contact_traction,
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawExact {
    pub(super) displacement: Vec<ExprSrc>,
    pub(super) velocity: Option<Vec<ExprSrc>>,
    pub(super) gradient: Option<Vec<Vec<ExprSrc>>>,
    pub(super) error_steps: Option<Vec<i64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawContact {
    pub(super) boundary: Option<String>,
    pub(super) slave: Option<String>,
    pub(super) master: Option<String>,
    pub(super) pairs: Option<Vec<RawPair>>,
    pub(super) obstacle: Option<RawObstacle>,
    pub(super) obstacles: Option<Vec<RawObstacle>>,
    pub(super) friction: Option<f64>,
    pub(super) tresca: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawPair {
    pub(super) slave: Option<String>,
    pub(super) master: Option<String>,
    pub(super) friction: Option<f64>,
    pub(super) tresca: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields, tag = "type", rename_all = "lowercase")]
pub(super) enum RawObstacle {
    Plane {
        point: Vec<f64>,
        normal: Vec<f64>,
        motion: Option<Vec<ExprSrc>>,
        friction: Option<f64>,
        tresca: Option<f64>,
    },
    Sphere {
        center: Vec<f64>,
        radius: f64,
        motion: Option<Vec<ExprSrc>>,
        friction: Option<f64>,
        tresca: Option<f64>,
    },
    Cylinder {
        point: Vec<f64>,
        axis: Vec<f64>,
        radius: f64,
        motion: Option<Vec<ExprSrc>>,
        friction: Option<f64>,
        tresca: Option<f64>,
    },
}
