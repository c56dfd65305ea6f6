//! What crosses the interface of a contact solver in one step: the step's linear system
//! ([`StepSystem`]) and what the solver found ([`StepContact`]); a slave node's plane
//! ([`NodePlane`]).

use crate::petsc::{Ksp, Matrix, Vector};
use crate::rows::ContactRow;

/// One step's linear system as the integrator hands it to the contact solver.
pub struct StepSystem<'a> {
    /// The operator `ksp` solves with: the solver may change it near the contact nodes (and
    /// restores it when the contact ends).
    pub k: &'a mut Matrix,
    pub ksp: &'a mut Ksp,
    /// The right-hand side of `K du = rhs - factor B^T lambda`.
    pub rhs: &'a Vector,
    /// `u^n`.
    pub u: &'a Vector,
    /// Holds the previous increment (the first guess) and gets the result.
    pub du: &'a mut Vector,
    /// The step being solved (`n + 1`), its end time `t_{n+1}` and length `tau`.
    pub step: usize,
    pub time: f64,
    pub tau: f64,
    /// One Newton iteration's linearization (finite strain): an active set that cycles is
    /// taken as it is and said so ([`StepContact::cycled`]); the next iteration linearizes
    /// anew from there. A step's own system (linear bodies): a cycle is an error.
    pub linearization: bool,
}

/// What the contact solver found in one step (all per contact node, same on every rank).
#[derive(Debug, Clone, Default)]
pub struct StepContact {
    pub row: ContactRow,
    pub normals: Vec<[f64; 3]>,
    /// Work of the contact forces in this step, `-sum_q lambda_q n_q . du_q` (<= 0).
    pub work: f64,
    /// With friction: the frictional dissipation of the step, `sum_q t_q . s_q >= 0` (the
    /// tangential force's work against the slip; the body loses it).
    pub dissipation: f64,
    /// With friction against a moving obstacle: the work its tangential force does by
    /// carrying the body along, `-sum_q t_q . w_q` (the body's tangential work is this minus
    /// the dissipation).
    pub tangential_work: f64,
    /// `sum_q lambda_q n_q + t_q` (the force the obstacle takes; the body gets its negative);
    /// of a pair with obstacles beside it, over the slave nodes only.
    pub resultant: [f64; 3],
    /// Of a pair with obstacles beside it: `sum_q lambda_q n_q` over the nodes that meet the
    /// obstacles (the obstacles' force; that body gets its negative). Zero otherwise.
    pub obstacle_force: [f64; 3],
    /// The force on the master body of a two-body pair, `sum_l (M^T lambda)_l n`, i.e.
    /// `sum_q (sum_l M_ql / D_qq) lambda_q n_q` (zero against rigid obstacles).
    pub master_force: [f64; 3],
    /// Per master node `l` (of [`ContactSolver::master_nodes`]): its share
    /// `sum_q (M_ql / D_qq) lambda_q n_q` of `master_force` (empty against rigid obstacles).
    pub master_nodal: Vec<[f64; 3]>,
    /// With friction: per contact node, the tangential force its body got, `-t_q` as the
    /// solve applied it (a pair's `t_q` may be restated at the midpoint in `row.tangential`).
    pub friction_nodal: Vec<[f64; 3]>,
    /// With friction between two bodies: per master node, friction's part of `master_nodal`,
    /// `sum_q (M_ql / D_qq) t_q` (empty otherwise).
    pub master_friction: Vec<[f64; 3]>,
    /// Per contact node: a force beside `-force n` (the rest of the consistent force of an
    /// interface that follows the bodies; empty otherwise).
    pub contact_nodal: Vec<[f64; 3]>,
    /// The active set cycled and was taken as it was (a Newton iteration's linearization,
    /// [`StepSystem::linearization`]): not a settled set.
    pub cycled: bool,
}

/// A slave node's plane in the mortar basis, `(c_q, n_q)`: `n_q . y_q <= c_q`.
pub type NodePlane = (f64, [f64; 3]);

impl StepContact {
    /// The contact data of the solve at `xi_a + t (xi_b - xi_a)` between two solves `a`, `b`
    /// of one step whose right-hand sides differ along one direction (the energy
    /// correction's), when both found the same active set on the same normals without
    /// friction or a geometry that follows the bodies: the constrained operator is then the
    /// same, so the solution, the forces, the gaps and the works are affine in `t` (to the
    /// solves' tolerance). `None` when they cannot be blended, or when the blend leaves an
    /// active node pulling (`lambda < 0`) or an inactive one penetrating (gap < 0): then the
    /// step must be solved at that point.
    pub fn blend(a: &StepContact, b: &StepContact, t: f64) -> Option<StepContact> {
        let plain = |c: &StepContact| {
            c.row.tangential.is_empty()
                && c.contact_nodal.is_empty()
                && c.friction_nodal.is_empty()
                && c.master_friction.is_empty()
        };
        if !(plain(a) && plain(b))
            || a.row.active != b.row.active
            || a.normals != b.normals
            || a.row.force.len() != b.row.force.len()
            || a.row.gap.len() != b.row.gap.len()
            || a.master_nodal.len() != b.master_nodal.len()
        {
            return None;
        }
        let mix = |x: f64, y: f64| x + t * (y - x);
        let mix3 = |x: &[f64; 3], y: &[f64; 3]| [0, 1, 2].map(|i| mix(x[i], y[i]));
        let force: Vec<f64> =
            a.row.force.iter().zip(&b.row.force).map(|(&x, &y)| mix(x, y)).collect();
        let gap: Vec<f64> = a.row.gap.iter().zip(&b.row.gap).map(|(&x, &y)| mix(x, y)).collect();
        let feasible = b.row.active.iter().enumerate().all(|(q, &on)| {
            if on {
                force.get(q).is_none_or(|&f| f >= 0.0)
            } else {
                gap.get(q).is_none_or(|&g| !(g < 0.0))
            }
        });
        if !feasible {
            return None;
        }
        let mut c = b.clone();
        c.row.force = force;
        c.row.gap = gap;
        c.work = mix(a.work, b.work);
        c.resultant = mix3(&a.resultant, &b.resultant);
        c.obstacle_force = mix3(&a.obstacle_force, &b.obstacle_force);
        c.master_force = mix3(&a.master_force, &b.master_force);
        c.master_nodal =
            a.master_nodal.iter().zip(&b.master_nodal).map(|(x, y)| mix3(x, y)).collect();
        Some(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(scale: f64, active: Vec<bool>) -> StepContact {
        let mut c = StepContact::default();
        c.row.force = vec![1.0 * scale, 0.0];
        c.row.gap = vec![0.0, 0.5 * scale];
        c.row.active = active;
        c.normals = vec![[0.0, 1.0, 0.0]; 2];
        c.work = -2.0 * scale;
        c.resultant = [0.0, scale, 0.0];
        c
    }

    #[test]
    fn a_blend_is_affine_between_solves_of_one_active_set() {
        let (a, b) = (sample(1.0, vec![true, false]), sample(3.0, vec![true, false]));
        let c = StepContact::blend(&a, &b, 0.25).expect("blendable");
        assert_eq!(c.row.force, vec![1.5, 0.0]);
        assert_eq!(c.row.gap, vec![0.0, 0.75]);
        assert_eq!(c.work, -3.0);
        assert_eq!(c.resultant, [0.0, 1.5, 0.0]);
        // Beyond b, still feasible.
        assert!(StepContact::blend(&a, &b, 1.2).is_some());
    }

    #[test]
    fn no_blend_across_active_sets_friction_or_infeasible_points() {
        let a = sample(1.0, vec![true, false]);
        assert!(StepContact::blend(&a, &sample(3.0, vec![true, true]), 0.5).is_none());
        let mut f = sample(3.0, vec![true, false]);
        f.row.tangential = vec![[0.0; 3]; 2];
        assert!(StepContact::blend(&a, &f, 0.5).is_none());
        // Extrapolated so far that the active node pulls: lambda = 1 + t (-1 - 1) < 0.
        let pull = sample(-1.0, vec![true, false]);
        assert!(StepContact::blend(&a, &pull, 0.75).is_none());
        assert!(StepContact::blend(&a, &pull, 0.25).is_some());
    }
}
