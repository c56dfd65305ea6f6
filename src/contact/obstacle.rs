//! Rigid obstacles: their shapes (plane, sphere, cylinder), a prescribed rigid translation
//! `d(t)` of each, and the set of obstacles a contact node sees.
//!
//! Every function gives the gap `g` and the unit normal `n` at a point `y`: `g > 0` outside
//! the obstacle, and `n` points from the body towards the obstacle (docs/method.md, contact), so
//! that the gap of a node moved by `du` is `g - n . du` to first order (exactly for a plane).
//! An obstacle with a motion is placed at `t` by translating its reference shape by `d(t)`;
//! among several obstacles a node takes the one with the smallest gap (node-local: right for
//! obstacles that are apart).

use super::friction::FrictionLaw;
use crate::scene;
use crate::scene::expr::VecExpr;

/// A rigid shape in its reference position.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// The half-space `(y - point) . normal >= 0` is free; `normal` (unit) points into it
    /// (towards the body).
    Plane { point: [f64; 3], normal: [f64; 3] },
    /// A rigid ball (disc in 2D); the body stays outside it.
    Sphere { center: [f64; 3], radius: f64 },
    /// An infinite circular cylinder around the line through `point` along `axis` (unit; 3D
    /// only); the body stays outside it.
    Cylinder { point: [f64; 3], axis: [f64; 3], radius: f64 },
}

fn pad(v: &[f64]) -> [f64; 3] {
    let mut a = [0.0; 3];
    a[..v.len().min(3)].copy_from_slice(&v[..v.len().min(3)]);
    a
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// Gap and normal outside a round obstacle whose surface is at distance `radius` from the
/// point `y - r` (the nearest point of its center or axis): `g = |r| - radius`,
/// `n = -r / |r|`; at `r = 0` (the center itself) the normal is `fallback`.
fn round(r: [f64; 3], radius: f64, fallback: [f64; 3]) -> (f64, [f64; 3]) {
    let len = dot(r, r).sqrt();
    if len == 0.0 {
        return (-radius, fallback);
    }
    (len - radius, [-r[0] / len, -r[1] / len, -r[2] / len])
}

/// A unit vector perpendicular to the unit vector `a`: `e x a / |e x a|` with `e` the
/// coordinate axis least aligned with `a`.
fn perpendicular(a: [f64; 3]) -> [f64; 3] {
    let i = (0..3).min_by(|&i, &j| a[i].abs().total_cmp(&a[j].abs())).unwrap_or(0);
    let mut e = [0.0; 3];
    e[i] = 1.0;
    let c = [e[1] * a[2] - e[2] * a[1], e[2] * a[0] - e[0] * a[2], e[0] * a[1] - e[1] * a[0]];
    let len = dot(c, c).sqrt();
    [c[0] / len, c[1] / len, c[2] / len]
}

impl Shape {
    pub fn from_scene(s: &scene::Shape) -> Shape {
        match s {
            scene::Shape::Plane { point, normal } => {
                Shape::Plane { point: pad(point), normal: pad(normal) }
            }
            scene::Shape::Sphere { center, radius } => {
                Shape::Sphere { center: pad(center), radius: *radius }
            }
            scene::Shape::Cylinder { point, axis, radius } => {
                Shape::Cylinder { point: pad(point), axis: pad(axis), radius: *radius }
            }
        }
    }

    /// The shape translated by `d` (a rigid motion keeps normals and radii).
    pub fn translated(&self, d: [f64; 3]) -> Shape {
        match self {
            Shape::Plane { point, normal } => {
                Shape::Plane { point: add(*point, d), normal: *normal }
            }
            Shape::Sphere { center, radius } => {
                Shape::Sphere { center: add(*center, d), radius: *radius }
            }
            Shape::Cylinder { point, axis, radius } => {
                Shape::Cylinder { point: add(*point, d), axis: *axis, radius: *radius }
            }
        }
    }

    /// Gap and unit normal (pointing from the body towards the obstacle) at position `y`:
    /// - plane: `g = (y - p) . m`, `n = -m` (`m` the plane's normal);
    /// - sphere: `r = y - c`, `g = |r| - R`, `n = -r / |r|`;
    /// - cylinder: `r = (y - p) - ((y - p) . a) a` (the part normal to the axis `a`),
    ///   `g = |r| - R`, `n = -r / |r|`.
    pub fn gap_normal(&self, y: [f64; 3]) -> (f64, [f64; 3]) {
        match self {
            Shape::Plane { point, normal } => {
                (dot(sub(y, *point), *normal), [-normal[0], -normal[1], -normal[2]])
            }
            Shape::Sphere { center, radius } => round(sub(y, *center), *radius, [0.0, -1.0, 0.0]),
            Shape::Cylinder { point, axis, radius } => {
                let d = sub(y, *point);
                let along = dot(d, *axis);
                let r = [d[0] - along * axis[0], d[1] - along * axis[1], d[2] - along * axis[2]];
                round(r, *radius, perpendicular(*axis))
            }
        }
    }
}

/// A rigid obstacle: a shape and its prescribed translation `d(t)` (none: at rest).
#[derive(Debug, Clone)]
pub struct Obstacle {
    pub shape: Shape,
    /// `d(t)`, expressions in `t` only (the scene checks it).
    pub motion: Option<VecExpr>,
    /// The friction between the bodies and this obstacle (`None`: frictionless).
    pub friction: Option<FrictionLaw>,
}

impl Obstacle {
    pub fn from_scene(o: &scene::Obstacle) -> Obstacle {
        Obstacle {
            shape: Shape::from_scene(&o.shape),
            motion: o.motion.clone(),
            friction: o.friction.map(FrictionLaw::from_scene),
        }
    }

    /// The obstacle at time `t`: the reference shape translated by `d(t)`.
    pub fn at(&self, t: f64) -> Shape {
        match &self.motion {
            None => self.shape.clone(),
            Some(d) => self.shape.translated(d.eval([0.0; 3], t)),
        }
    }
}

/// The obstacles of a scene (at least one).
#[derive(Debug, Clone)]
pub struct Obstacles(pub Vec<Obstacle>);

impl Obstacles {
    pub fn from_scene(list: &[scene::Obstacle]) -> Obstacles {
        Obstacles(list.iter().map(Obstacle::from_scene).collect())
    }

    /// Every obstacle placed at time `t`.
    pub fn at(&self, t: f64) -> Vec<Shape> {
        self.0.iter().map(|o| o.at(t)).collect()
    }
}

/// The obstacle with the smallest gap at `y` among `placed` (the first on a tie): its index,
/// gap and normal, `argmin_k g_k(y)`.
pub fn closest(placed: &[Shape], y: [f64; 3]) -> (usize, f64, [f64; 3]) {
    let mut best = (0, f64::INFINITY, [0.0, -1.0, 0.0]);
    for (k, s) in placed.iter().enumerate() {
        let (g, n) = s.gap_normal(y);
        if g < best.1 {
            best = (k, g, n);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::expr::Expr;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|i| (a[i] - b[i]).abs() < 1e-14)
    }

    #[test]
    fn plane_and_sphere_gaps() {
        let plane = Shape::Plane { point: [0.0, 1.0, 0.0], normal: [0.0, 1.0, 0.0] };
        let (g, n) = plane.gap_normal([3.0, 1.5, 0.0]);
        assert!((g - 0.5).abs() < 1e-15 && n == [0.0, -1.0, 0.0]);
        let ball = Shape::Sphere { center: [0.0, 0.0, 0.0], radius: 1.0 };
        let (g, n) = ball.gap_normal([0.0, 3.0, 0.0]);
        assert!((g - 2.0).abs() < 1e-15 && (n[1] + 1.0).abs() < 1e-15);
    }

    #[test]
    fn cylinder_gap_ignores_the_axial_position() {
        // Axis along y through (0, 0, -2), radius 1: a point above the axis at height z has
        // the gap z + 2 - 1 wherever it is along y, and the normal points down.
        let cyl = Shape::Cylinder { point: [0.0, 0.0, -2.0], axis: [0.0, 1.0, 0.0], radius: 1.0 };
        for y in [-5.0, 0.0, 7.5] {
            let (g, n) = cyl.gap_normal([0.0, y, 0.5]);
            assert!((g - 1.5).abs() < 1e-14 && close(n, [0.0, 0.0, -1.0]), "{g} {n:?}");
        }
        // Off to the side at 45 degrees: g = sqrt(2) * 2 - 1, n = -(1, 0, 1)/sqrt(2).
        let (g, n) = cyl.gap_normal([2.0, 3.0, 0.0]);
        let s = 0.5f64.sqrt();
        assert!((g - (8.0f64.sqrt() - 1.0)).abs() < 1e-14 && close(n, [-s, 0.0, -s]));
        // On the axis: the deepest point, a normal perpendicular to the axis.
        let (g, n) = cyl.gap_normal([0.0, 4.0, -2.0]);
        assert!(g == -1.0 && n[1] == 0.0 && (dot(n, n) - 1.0).abs() < 1e-14, "{n:?}");
    }

    #[test]
    fn perpendicular_is_a_unit_normal_to_the_axis() {
        let s = 3.0f64.sqrt();
        for a in [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0 / s, 1.0 / s, 1.0 / s]] {
            let p = perpendicular(a);
            assert!(dot(p, a).abs() < 1e-15 && (dot(p, p) - 1.0).abs() < 1e-15, "{p:?}");
        }
    }

    #[test]
    fn a_moving_obstacle_is_translated_by_its_motion() {
        // A floor at y = 0 that moves up as d(t) = (0, 2 t): at t = 0.25 a point at y = 1 is
        // 0.5 above it.
        let motion = VecExpr(vec![Expr::zero(), Expr::parse("2*t").unwrap()]);
        let floor = Obstacle {
            shape: Shape::Plane { point: [0.0; 3], normal: [0.0, 1.0, 0.0] },
            motion: Some(motion),
            friction: None,
        };
        let (g, n) = floor.at(0.25).gap_normal([4.0, 1.0, 0.0]);
        assert!((g - 0.5).abs() < 1e-15 && n == [0.0, -1.0, 0.0]);
        assert_eq!(floor.at(0.0), floor.shape);
    }

    #[test]
    fn the_closest_obstacle_wins() {
        // Two discs of radius 1 at x = -2 and x = 2: a point at x = 0.5 belongs to the right.
        let placed = [
            Shape::Sphere { center: [-2.0, 0.0, 0.0], radius: 1.0 },
            Shape::Sphere { center: [2.0, 0.0, 0.0], radius: 1.0 },
        ];
        let (k, g, n) = closest(&placed, [0.5, 0.0, 0.0]);
        assert_eq!(k, 1);
        assert!((g - 0.5).abs() < 1e-15 && close(n, [1.0, 0.0, 0.0]));
        let (k, g, _) = closest(&placed, [-0.5, 0.0, 0.0]);
        assert!(k == 0 && (g - 0.5).abs() < 1e-15);
    }
}
