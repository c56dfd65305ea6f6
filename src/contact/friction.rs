//! Coulomb and Tresca friction at one contact node: the pointwise kernels of the primal-dual
//! active set with three sets per node (Hueber, Stadler and Wohlmuth, SIAM J. Sci. Comput. 30,
//! 2008; METHOD.md 5c). Pure functions of one node's data; [`super::pdas`] uses them inside its
//! active-set loop, [`super::constraint::Condition`] holds the rows they lead to.
//!
//! Per node: the normal multiplier `lambda_n` and weighted gap `g` of the normal condition, the
//! tangential multiplier `lambda_t` and the weighted slip increment `u_t` (both in the node's
//! tangent plane; the third component is zero in 2D), the complementarity parameters
//! `c_n, c_t > 0`. With the slip bound
//!
//! ```text
//! b = mu max(0, lambda_n - c_n g)      (Coulomb)      b = s      (Tresca, on an active node)
//! z = lambda_t + c_t u_t
//! ```
//!
//! the node is *inactive* where `lambda_n - c_n g <= 0` (`lambda = 0`), *sticks* where
//! `|z| < b` (`u_t = 0`) and *slips* otherwise (`lambda_t = b z / |z|`): the zeros of
//!
//! ```text
//! C_t = max(b, |z|) lambda_t - b z.
//! ```
//!
//! With this sign the tangential multiplier points along the slip, and a step dissipates
//! `lambda_t . u_t = b |u_t| >= 0` at a slipping node, nothing at a sticking one.

/// The friction law of a contact (or of one obstacle or pair).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionLaw {
    /// Coulomb: the tangential traction is bounded by `mu` times the normal one.
    Coulomb { mu: f64 },
    /// Tresca: bounded by a given `bound` wherever the node is in contact (verification).
    Tresca { bound: f64 },
}

impl FrictionLaw {
    pub fn from_scene(f: crate::scene::FrictionSpec) -> FrictionLaw {
        match f {
            crate::scene::FrictionSpec::Coulomb(mu) => FrictionLaw::Coulomb { mu },
            crate::scene::FrictionSpec::Tresca(bound) => FrictionLaw::Tresca { bound },
        }
    }
}

/// A node's set in an active-set iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeState {
    Inactive,
    Stick,
    Slip,
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn norm(a: &[f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// `z = lambda_t + c_t u_t`.
fn trial(lambda_t: &[f64; 3], slip: &[f64; 3], c_t: f64) -> [f64; 3] {
    [0, 1, 2].map(|i| lambda_t[i] + c_t * slip[i])
}

/// The slip bound `b`: `mu max(0, lambda_n - c_n g)` (Coulomb), or Tresca's bound where the
/// node is in contact (`lambda_n - c_n g > 0`) and 0 elsewhere.
pub fn slip_bound(law: FrictionLaw, lambda_n: f64, gap: f64, c_n: f64) -> f64 {
    let pressed = lambda_n - c_n * gap;
    match law {
        FrictionLaw::Coulomb { mu } => mu * pressed.max(0.0),
        FrictionLaw::Tresca { bound } if pressed > 0.0 => bound,
        FrictionLaw::Tresca { .. } => 0.0,
    }
}

/// The node's set from the current iterate: inactive where `lambda_n - c_n g <= 0`, stick
/// where `|lambda_t + c_t u_t| < b`, slip otherwise (frictionless contact, `b = 0`, slips).
#[allow(clippy::too_many_arguments)]
pub fn classify(
    law: FrictionLaw,
    lambda_n: f64,
    gap: f64,
    lambda_t: &[f64; 3],
    slip: &[f64; 3],
    c_n: f64,
    c_t: f64,
) -> NodeState {
    if lambda_n - c_n * gap <= 0.0 {
        return NodeState::Inactive;
    }
    let b = slip_bound(law, lambda_n, gap, c_n);
    if norm(&trial(lambda_t, slip, c_t)) < b {
        NodeState::Stick
    } else {
        NodeState::Slip
    }
}

/// The tangential complementarity function `C_t = max(b, |z|) lambda_t - b z`: zero exactly
/// where the node sticks (`u_t = 0`, `|lambda_t| <= b`) or slips (`lambda_t = b z / |z|`).
pub fn complementarity(b: f64, lambda_t: &[f64; 3], slip: &[f64; 3], c_t: f64) -> [f64; 3] {
    let z = trial(lambda_t, slip, c_t);
    let m = b.max(norm(&z));
    [0, 1, 2].map(|i| m * lambda_t[i] - b * z[i])
}

/// A slipping node's tangential multiplier `lambda_t = b z / |z|` and its derivative by `z`,
/// `b (I - z^ z^T) / |z|` (`z^ = z / |z|`; the semi-smooth Newton step's linearized slip
/// direction). Zero where `b = 0` or `z = 0` (no direction to slip in).
pub fn slip_traction(b: f64, lambda_t: &[f64; 3], slip: &[f64; 3], c_t: f64) -> SlipTraction {
    let z = trial(lambda_t, slip, c_t);
    let len = norm(&z);
    if b == 0.0 || len == 0.0 {
        return SlipTraction { traction: [0.0; 3], d_dz: [[0.0; 3]; 3] };
    }
    let zh = z.map(|x| x / len);
    let mut d_dz = [[0.0; 3]; 3];
    for (i, row) in d_dz.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            let id = if i == j { 1.0 } else { 0.0 };
            *x = b * (id - zh[i] * zh[j]) / len;
        }
    }
    SlipTraction { traction: zh.map(|x| b * x), d_dz }
}

/// [`slip_traction`]'s result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SlipTraction {
    /// `lambda_t = b z / |z|`.
    pub traction: [f64; 3],
    /// `d lambda_t / d z` (row `i`, column `j`: `d lambda_t[i] / d z[j]`).
    pub d_dz: [[f64; 3]; 3],
}

/// A node's frictional dissipation over the step, `lambda_t . u_t` (non-negative at every
/// solution of the friction law).
pub fn dissipation(lambda_t: &[f64; 3], slip: &[f64; 3]) -> f64 {
    dot(lambda_t, slip)
}

#[cfg(test)]
mod tests {
    use super::*;

    const C: f64 = 1.0;
    const COULOMB: FrictionLaw = FrictionLaw::Coulomb { mu: 0.3 };

    #[test]
    fn the_sets_follow_the_bound() {
        // Open gap and no pressure: inactive, whatever the tangential data.
        assert_eq!(
            classify(COULOMB, 0.0, 0.1, &[5.0, 0.0, 0.0], &[0.0; 3], C, C),
            NodeState::Inactive
        );
        // Pressed with lambda_n = 2: b = 0.6; |z| = 0.5 sticks, 0.7 slips, 0.6 slips.
        let s = |zx: f64| classify(COULOMB, 2.0, 0.0, &[zx, 0.0, 0.0], &[0.0; 3], C, C);
        assert_eq!(s(0.5), NodeState::Stick);
        assert_eq!(s(0.7), NodeState::Slip);
        assert_eq!(s(0.6), NodeState::Slip);
        // The slip increment counts with c_t: lambda_t = 0.5 sticks until c_t u_t pushes |z|
        // past the bound.
        let with_slip =
            |u: f64| classify(COULOMB, 2.0, 0.0, &[0.5, 0.0, 0.0], &[u, 0.0, 0.0], C, C);
        assert_eq!(with_slip(0.05), NodeState::Stick);
        assert_eq!(with_slip(0.2), NodeState::Slip);
        // Frictionless contact slips with no traction.
        let free = FrictionLaw::Coulomb { mu: 0.0 };
        assert_eq!(classify(free, 2.0, 0.0, &[0.0; 3], &[0.0; 3], C, C), NodeState::Slip);
        assert_eq!(slip_traction(0.0, &[0.0; 3], &[1.0, 0.0, 0.0], C).traction, [0.0; 3]);
        // Tresca: the given bound wherever the node is pressed, none where it is not.
        let tresca = FrictionLaw::Tresca { bound: 0.25 };
        assert_eq!(slip_bound(tresca, 2.0, 0.0, C), 0.25);
        assert_eq!(slip_bound(tresca, 0.0, 0.1, C), 0.0);
        assert_eq!(slip_bound(COULOMB, 2.0, -0.5, C), 0.3 * 2.5);
    }

    #[test]
    fn the_complementarity_function_vanishes_exactly_at_stick_and_slip() {
        let b = 0.6;
        // Stick: no slip, |lambda_t| below the bound (in 3D, any direction in the plane).
        let lt = [0.3, -0.2, 0.1];
        assert_eq!(complementarity(b, &lt, &[0.0; 3], C), [0.0; 3]);
        // ... but not with a slip increment.
        assert!(norm(&complementarity(b, &lt, &[0.01, 0.0, 0.0], C)) > 0.0);
        // Slip: lambda_t = b u^ along the slip (then z is along it too).
        let u = [0.2, 0.1, -0.2];
        let uh = u.map(|x| x / norm(&u));
        let lt = uh.map(|x| b * x);
        let c = complementarity(b, &lt, &u, C);
        assert!(norm(&c) < 1e-15, "{c:?}");
        // The traction of slip_traction satisfies it, and dissipates b |u_t|.
        let t = slip_traction(b, &lt, &u, C).traction;
        assert!(norm(&complementarity(b, &t, &u, C)) < 1e-15);
        assert!((dissipation(&t, &u) - b * norm(&u)).abs() < 1e-15);
        // Against the slip it is no solution.
        let against = uh.map(|x| -b * x);
        assert!(norm(&complementarity(b, &against, &u, C)) > 0.1);
    }

    /// `d(b z/|z|)/dz = b (I - z^ z^T)/|z|` against central differences: the error falls as
    /// h^2 (below 1e-9 relative at h = 1e-5), in 3D at a general z and in 2D (one tangent:
    /// the direction is constant, the derivative zero along it).
    #[test]
    fn the_slip_direction_derivative_matches_differences() {
        let b = 0.7;
        let z0 = [0.3, -0.4, 0.25];
        let d = slip_traction(b, &z0, &[0.0; 3], C).d_dz;
        let h = 1e-5;
        let mut worst = 0.0f64;
        for j in 0..3 {
            let (mut p, mut m) = (z0, z0);
            p[j] += h;
            m[j] -= h;
            let (tp, tm) = (
                slip_traction(b, &p, &[0.0; 3], C).traction,
                slip_traction(b, &m, &[0.0; 3], C).traction,
            );
            for i in 0..3 {
                let fd = (tp[i] - tm[i]) / (2.0 * h);
                worst = worst.max((fd - d[i][j]).abs());
            }
        }
        let scale = b / norm(&z0);
        assert!(worst < 1e-9 * scale, "derivative off by {worst:e} (scale {scale:e})");
        // The derivative is tangential to the circle: d (z/|z|) . z^ = 0.
        for row in &d {
            assert!(dot(row, &z0).abs() < 1e-15);
        }
        // 2D: z along the one tangent, the direction cannot turn.
        let d2 = slip_traction(b, &[0.5, 0.0, 0.0], &[0.0; 3], C).d_dz;
        assert_eq!(d2[0][0], 0.0);
    }
}
