//! The mortar geometry's basics: points and vectors ([`Vec2`], [`Vec3`]) and their small
//! algebra, and the error of a degenerate input ([`GeomError`]).

// Deliberate: `!(a > b)` treats NaN as failing the test, which `a <= b` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::fmt;

/// A point or vector in the plane.
pub type Vec2 = [f64; 2];
/// A point or vector in space.
pub type Vec3 = [f64; 3];

// ------------------------------------------------------------------------------------------
// Errors
// ------------------------------------------------------------------------------------------

/// A degenerate or inconsistent input, with a one-line message naming the culprit.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GeomError(pub String);

impl fmt::Display for GeomError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "mortar geometry: {}", self.0)
    }
}

impl std::error::Error for GeomError {}

pub(crate) fn fail<T>(msg: impl Into<String>) -> Result<T, GeomError> {
    Err(GeomError(msg.into()))
}

// ------------------------------------------------------------------------------------------
// Small vector algebra (kept private; arrays keep the hot loops allocation free)
// ------------------------------------------------------------------------------------------

pub(crate) fn add2(a: Vec2, b: Vec2) -> Vec2 {
    [a[0] + b[0], a[1] + b[1]]
}
pub(crate) fn sub2(a: Vec2, b: Vec2) -> Vec2 {
    [a[0] - b[0], a[1] - b[1]]
}
pub(crate) fn scale2(s: f64, a: Vec2) -> Vec2 {
    [s * a[0], s * a[1]]
}
pub(crate) fn dot2(a: Vec2, b: Vec2) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
/// z-component of the 2D cross product.
pub(crate) fn cross2(a: Vec2, b: Vec2) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}
pub(crate) fn norm2(a: Vec2) -> f64 {
    dot2(a, a).sqrt()
}
pub(crate) fn add3(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub(crate) fn sub3(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn scale3(s: f64, a: Vec3) -> Vec3 {
    [s * a[0], s * a[1], s * a[2]]
}
pub(crate) fn dot3(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross3(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
pub(crate) fn norm3(a: Vec3) -> f64 {
    dot3(a, a).sqrt()
}
pub(crate) fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}
