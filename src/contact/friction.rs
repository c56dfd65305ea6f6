//! Coulomb and Tresca friction at one contact node: the law and the slip bound of the
//! primal-dual active set with three sets per node (Hueber, Stadler and Wohlmuth, SIAM J. Sci. Comput. 30,
//! 2008; docs/method.md, friction). [`super::pdas`] decides the sets inside its active-set loop (with a
//! band around the bound against flip-flops), [`super::constraint::Condition`] holds the rows
//! they lead to.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_slip_bound_follows_the_law() {
        let (coulomb, c) = (FrictionLaw::Coulomb { mu: 0.3 }, 1.0);
        // Coulomb: mu times the pressing force, lambda_n - c_n g (an entering node's
        // penetration counts); nothing where the node is not pressed.
        assert_eq!(slip_bound(coulomb, 2.0, 0.0, c), 0.3 * 2.0);
        assert_eq!(slip_bound(coulomb, 2.0, -0.5, c), 0.3 * 2.5);
        assert_eq!(slip_bound(coulomb, 0.0, 0.1, c), 0.0);
        // Tresca: the given bound wherever the node is pressed, none where it is not.
        let tresca = FrictionLaw::Tresca { bound: 0.25 };
        assert_eq!(slip_bound(tresca, 2.0, 0.0, c), 0.25);
        assert_eq!(slip_bound(tresca, 0.0, 0.1, c), 0.0);
    }
}
