//! The scalar model of the energy correction ([`super::Midpoint`]'s `correct_energy`): the
//! step's energy error as a function of the correction's size `xi`, from two solves.

/// Solves of a corrected step beyond its first, at most.
pub const MAX_SOLVES: usize = 8;

/// The root of the step's energy error `F(xi) = W(xi) - xi q(xi) + debt` nearest the last
/// sample, where the contact work `W` and `q = m.du` are the lines through two solves' samples
/// `a = (xi_a, W_a, q_a)` and `b = (xi_b, W_b, q_b)`:
///
/// ```text
/// F(xi) = -q' xi^2 + (W' - q_a + xi_a q') xi + (W_a - xi_a W' + debt),
/// W' = (W_b - W_a) / (xi_b - xi_a),   q' = (q_b - q_a) / (xi_b - xi_a)
/// ```
///
/// exact when the solve is affine in `xi` between the samples (a fixed active set). Of the
/// two roots the one nearer `xi_b` (the quadratic term is the correction's `O(xi tau^2)`
/// effect on its own work, small); without a real root, the model's Newton step from `xi_b`.
/// `None` when the samples cannot define a model (equal `xi`, or a flat model).
pub fn model_root(a: (f64, f64, f64), b: (f64, f64, f64), debt: f64) -> Option<f64> {
    let d = b.0 - a.0;
    if d == 0.0 || !d.is_finite() {
        return None;
    }
    let (w1, q1) = ((b.1 - a.1) / d, (b.2 - a.2) / d);
    let (qa, qb, qc) = (-q1, w1 - a.2 + a.0 * q1, a.1 - a.0 * w1 + debt);
    let disc = qb * qb - 4.0 * qa * qc;
    let root = if qa != 0.0 && disc >= 0.0 {
        // Both roots without cancellation: the small one 2c / (-b - sgn(b) sqrt(disc)), the
        // other (-b - sgn(b) sqrt(disc)) / 2a.
        let s = -qb - qb.signum() * disc.sqrt();
        let r1 = if s != 0.0 { 2.0 * qc / s } else { f64::NAN };
        let r2 = s / (2.0 * qa);
        if !r1.is_finite() || (r2.is_finite() && (r2 - b.0).abs() < (r1 - b.0).abs()) {
            r2
        } else {
            r1
        }
    } else {
        // Newton on the model from xi_b.
        let f = (qa * b.0 + qb) * b.0 + qc;
        let df = 2.0 * qa * b.0 + qb;
        b.0 - f / df
    };
    root.is_finite().then_some(root)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A solve affine in xi: W(xi) = w0 + w1 xi, m.du(xi) = q0 + q1 xi.
    fn sample(xi: f64, (w0, w1, q0, q1): (f64, f64, f64, f64)) -> (f64, f64, f64) {
        (xi, w0 + w1 * xi, q0 + q1 * xi)
    }

    fn residual(xi: f64, (w0, w1, q0, q1): (f64, f64, f64, f64), debt: f64) -> f64 {
        w0 + w1 * xi - xi * (q0 + q1 * xi) + debt
    }

    #[test]
    fn the_root_of_an_affine_response_is_exact() {
        // A loss W0 < 0, a response that lowers m.du (the correction force slows the motion)
        // and changes the contact work a little.
        for &(p, debt) in &[
            ((-1e-6, 2e-4, 0.5, -0.05), 0.0),
            ((-3e-9, -1e-3, 2.0, 0.3), -1e-9),
            ((-1e-6, 0.0, 0.5, 0.0), 2e-7),
        ] {
            let a = sample(0.0, p);
            let xi1 = (p.0 + debt) / p.2;
            let b = sample(xi1, p);
            let xi = model_root(a, b, debt).expect("a root");
            let scale = p.0.abs() + debt.abs();
            assert!(
                residual(xi, p, debt).abs() <= 1e-12 * scale,
                "{p:?}: F = {}",
                residual(xi, p, debt)
            );
            // The root near the first guess, not the far one of the quadratic.
            assert!((xi - xi1).abs() <= 0.2 * xi1.abs(), "{xi} against {xi1}");
        }
    }

    #[test]
    fn samples_that_cannot_define_a_model_give_none() {
        let a = (1.0, -1e-6, 0.5);
        assert_eq!(model_root(a, a, 0.0), None);
        // A flat model (F constant and nonzero) has no root.
        assert_eq!(model_root((0.0, -1e-6, 0.0), (1.0, -1e-6, 0.0), 0.0), None);
    }

    #[test]
    fn without_a_real_root_the_newton_step_lowers_the_model() {
        // F(xi) = -1 + 2 xi - 2 xi^2 (q' = 2): no real root; the vertex lies at xi = 0.5.
        let p = (-1.0, 0.0, -2.0, 2.0);
        let (a, b) = (sample(0.0, p), sample(1.0, p));
        let xi = model_root(a, b, 0.0).expect("a step");
        assert!(residual(xi, p, 0.0).abs() < residual(1.0, p, 0.0).abs());
    }
}
