//! The primal-dual active set whose every iteration is one solve of the step operator (the
//! default contact solver).
//!
//! Per iteration with the active set `A`: the operator is constrained on `A`
//! ([`NormalConstraints`]: the active nodes' normal displacement increments prescribed from
//! their gaps), one KSP solve gives `du`, the residual rows give the forces `lambda_q` on `A`,
//! and the gaps `g_q - n_q . du_q` off `A`. The next set keeps the nodes with `lambda_q >= 0`
//! and adds those with a negative gap; the loop ends when the set repeats (it is the step's
//! first guess next time, so a step with an unchanged contact zone costs one solve). The
//! operator is rewritten, and the preconditioner rebuilt by PETSc, only when the set or an
//! active node's normal changes.
//!
//! With friction (Hueber, Stadler and Wohlmuth 2008) a node in contact is in one of two more
//! sets, stick or slip ([`Condition`]), chosen from `|t + c_t s|` against the slip bound `b`
//! (`t` the tangential force read from the residual, `s` the slip increment relative to what
//! the node meets); a slipping node's direction is Newton-iterated until it settles. The loop
//! ends when the sets repeat and the directions have settled; the step reports the tangential
//! forces, the slips, the states and the dissipation `sum t . s`.

use super::active_set::ActiveSetLoop;
use super::constraint::{Condition, NormalConstraints};
pub use super::cost::ReferenceCost;
use super::friction::{self, FrictionLaw, NodeState};
use super::interface::ContactSolver;
use super::nodes::ContactNodes;
use super::nodes::StepFriction;
use super::step::{StepContact, StepSystem};
use crate::rows::{STATE_INACTIVE, STATE_SLIP, STATE_STICK};
use std::time::Instant;

use crate::error::Result;
use crate::petsc::{Matrix, Vector};

pub struct ActiveSet<'w> {
    nodes: ContactNodes<'w>,
    /// Built from the step operator by `prepare`.
    constraints: Option<NormalConstraints>,
    /// The constrained right-hand side.
    b: Option<Vector>,
    /// Factor of the force in the step equation (2 for the midpoint rule's du form).
    factor: f64,
    max_iterations: usize,
    /// Relative tolerance of the solves until the active set repeats (`-contact_loose_rtol`,
    /// default the square root of the step solver's); at or below the step solver's own,
    /// every solve is exact.
    loose_rtol: Option<f64>,
    /// Solves beyond the first of each step.
    extra_solves: usize,
    /// With `-contact_reference_solve` (benchmark): each step's plain solve, for the cost ratio.
    reference: Option<ReferenceCost>,
    /// With friction, per contact node after the last step: its state, slip direction and
    /// `b / |z|` (the next step's first guess).
    slip_states: Vec<(NodeState, [f64; 3], f64)>,
    /// Node-steps held slipping to end a stick/slip cycle.
    held_slipping: usize,
}

/// The complementarity parameter `c_t` of the tangential sets, relative to a node's stiffness
/// over the force factor. With `c_t` that large a slipping node whose slip comes out reversed
/// (`|c_t s| > 2 b`) jumps to slipping the other way and back (the active set cycled on a block
/// rocking on a slope, `c_t` = 1); below 0.3 it sticks first, and the solution does not depend
/// on it (0.3, 0.1, 0.01 and 0.001 gave the same runs).
const C_T: f64 = 0.01;

/// Relative width of the band around the slip bound in which a node keeps its state.
const SET_RTOL: f64 = 1e-9;
/// A slipping node's direction has settled when it turns by less than this (radians). The
/// size of its friction force is exact whatever the direction (the row along it), and the
/// step's dissipation is booked with the final force and slip; only the direction of the
/// force across the slip carries this error. 1e-6 took 4.56 active-set iterations per
/// contact step on the oblique ball (consistent mass, 23058 DOFs), 1e-4 3.87, 1e-3 3.43.
const DIR_TOL: f64 = 1e-4;

/// Per contact node of an iterate: the tangential force `t_q` and the slip `s_q`.
struct Tangent {
    traction: Vec<[f64; 3]>,
    slip: Vec<[f64; 3]>,
}

impl Tangent {
    fn new(nc: usize) -> Tangent {
        Tangent { traction: vec![[0.0; 3]; nc], slip: vec![[0.0; 3]; nc] }
    }
    fn set(&mut self, p: usize, t: [f64; 3], s: [f64; 3]) {
        self.traction[p] = t;
        self.slip[p] = s;
    }
}

/// `(I - n n^T) x` on the first `dim` components.
fn tangential(x: &[f64; 3], n: &[f64; 3], dim: usize) -> [f64; 3] {
    let s: f64 = (0..dim).map(|i| x[i] * n[i]).sum();
    [0, 1, 2].map(|i| if i < dim { x[i] - s * n[i] } else { 0.0 })
}

fn norm(x: &[f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    norm(&[a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// A unit vector in the tangent plane of `n` (a slip direction before there is one).
fn any_tangent(n: &[f64; 3], dim: usize) -> [f64; 3] {
    if dim == 2 {
        return [-n[1], n[0], 0.0];
    }
    // The axis least along n, made orthogonal to it.
    let k = (0..3).min_by(|&a, &b| n[a].abs().total_cmp(&n[b].abs())).unwrap_or(0);
    let mut e = [0.0; 3];
    e[k] = 1.0;
    let t = tangential(&e, n, 3);
    let l = norm(&t);
    t.map(|x| x / l)
}

impl<'w> ActiveSet<'w> {
    /// Measure each step against a plain solve (benchmark only: it costs that solve and two
    /// operator rewrites per step).
    pub fn with_reference_solve(mut self) -> ActiveSet<'w> {
        self.reference = Some(ReferenceCost::default());
        self
    }

    pub fn new(nodes: ContactNodes<'w>, factor: f64) -> ActiveSet<'w> {
        ActiveSet {
            nodes,
            constraints: None,
            b: None,
            factor,
            max_iterations: 50,
            loose_rtol: None,
            extra_solves: 0,
            reference: None,
            slip_states: Vec::new(),
            held_slipping: 0,
        }
    }

    /// Solve with relative tolerance `rtol` until the active set repeats, then to full
    /// accuracy.
    pub fn with_loose_rtol(mut self, rtol: Option<f64>) -> ActiveSet<'w> {
        self.loose_rtol = rtol;
        self
    }

    /// The contact nodes (e.g. to move the planes of a two-body contact).
    pub fn nodes_mut(&mut self) -> &mut ContactNodes<'w> {
        &mut self.nodes
    }
}

impl ContactSolver for ActiveSet<'_> {
    fn prepare(&mut self, k: &Matrix) -> Result<()> {
        self.constraints = Some(NormalConstraints::new(k, &self.nodes)?);
        self.b = Some(k.create_vecs()?.0);
        Ok(())
    }

    fn operator_replaced(&mut self, k: &Matrix) -> Result<()> {
        match self.constraints.as_mut() {
            Some(c) => c.refresh(k),
            None => self.prepare(k),
        }
    }

    fn follows_operator_changes(&self) -> bool {
        true
    }

    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { k, ksp, rhs, u, du, step, time, tau, linearization } = sys;
        if self.constraints.is_none() {
            self.prepare(k)?;
        }
        let nc = self.nodes.len();
        let dim = self.nodes.dim;
        let closest = self.nodes.closest(&self.nodes.trace(u)?, time);
        let frames: Vec<(f64, [f64; 3])> = closest.iter().map(|&(_, g, n)| (g, n)).collect();
        let normals: Vec<[f64; 3]> = frames.iter().map(|f| f.1).collect();
        let friction = self.nodes.node_friction(&closest, time, tau);
        let with_friction = friction.iter().any(Option::is_some);
        let (Some(cons), Some(b)) = (self.constraints.as_mut(), self.b.as_mut()) else {
            unreachable!("prepared above")
        };
        // The friction parameter c_t = C_T d_q / factor (d_q = n^T K_qq n): slip and traction
        // on one scale.
        let c_t: Vec<f64> = if with_friction {
            let d = cons.normal_stiffness(&self.nodes, &normals);
            d.iter().map(|d| C_T * d / self.factor).collect()
        } else {
            Vec::new()
        };
        // The obstacle side's tangential displacement over the step.
        let motion_t: Vec<[f64; 3]> = (0..nc)
            .map(|p| friction[p].map_or([0.0; 3], |f| tangential(&f.motion, &normals[p], dim)))
            .collect();
        // First guess: the last step's set, plus the nodes the last increment would push
        // through the obstacle (a growing contact zone then needs no extra iteration); a node
        // with friction keeps its last state and slip direction, a new one starts sticking.
        let ndu_last = self.nodes.normal_parts(&frames, &self.nodes.trace(du)?);
        let mut states: Vec<NodeState> = (0..nc)
            .map(|p| {
                let entering = frames[p].0 - ndu_last[p] < -self.nodes.gap_tol;
                match (self.nodes.active[p] || entering, friction[p].is_some()) {
                    (false, _) => NodeState::Inactive,
                    (true, false) => NodeState::Slip,
                    (true, true) => match self.slip_states.get(p) {
                        Some(&(NodeState::Slip, _, _)) => NodeState::Slip,
                        _ => NodeState::Stick,
                    },
                }
            })
            .collect();
        let mut dirs: Vec<([f64; 3], f64)> = (0..nc)
            .map(|p| match self.slip_states.get(p) {
                Some(&(NodeState::Slip, dir, ratio)) => (dir, ratio),
                _ => (any_tangent(&normals[p], dim), 0.0),
            })
            .collect();
        let conditions = |states: &[NodeState], dirs: &[([f64; 3], f64)]| -> Vec<Condition> {
            (0..nc)
                .map(|p| {
                    let (g, n) = frames[p];
                    match (states[p], friction[p]) {
                        (NodeState::Inactive, _) => Condition::Free,
                        (_, None) => Condition::Normal { n, g },
                        (NodeState::Stick, Some(_)) => Condition::Stick { n, g, w_t: motion_t[p] },
                        (NodeState::Slip, Some(f)) => {
                            let (dir, ratio) = dirs[p];
                            let (mu, h) = match f.law {
                                FrictionLaw::Coulomb { mu } => (mu, [0.0; 3]),
                                FrictionLaw::Tresca { bound } => {
                                    (0.0, dir.map(|x| -self.factor * bound * x))
                                }
                            };
                            let c_f = c_t[p] * self.factor;
                            Condition::Slip { n, g, w_t: motion_t[p], dir, mu, h, ratio, c_f }
                        }
                    }
                })
                .collect()
        };
        let plain = match self.reference {
            Some(_) => {
                cons.impose(k, &vec![Condition::Free; nc])?;
                let mut x = du.duplicate()?;
                x.copy_from(du)?;
                let t0 = Instant::now();
                let info = ksp.solve(rhs, &mut x)?;
                Some((info.iterations, t0.elapsed().as_secs_f64()))
            }
            None => None,
        };
        let t0 = Instant::now();
        let mut lp = ActiveSetLoop::with_states(&states, self.max_iterations, step, time);
        if linearization {
            lp.tolerate_cycles();
        }
        let mut its = 0;
        let tight = ksp.rtol()?;
        let rhs_norm = rhs.norm2()?;
        let loose = self.loose_rtol.unwrap_or(tight.sqrt());
        // Inexact solves only pay when the set may change: not while every node stays away
        // from the obstacle by more than the largest normal motion of the last step.
        let reach = ndu_last.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
        let quiet =
            (0..nc).all(|p| states[p] == NodeState::Inactive && frames[p].0 - ndu_last[p] > reach);
        let mut exact = quiet || loose <= tight;
        let mut confirmations = 0;
        // Nodes held slipping to end a stick/slip cycle (see below).
        let mut fixed = vec![false; nc];
        let (lambda, trace, tangent) = loop {
            let conds = conditions(&states, &dirs);
            cons.impose(k, &conds)?;
            cons.rhs(rhs, &conds, b)?;
            if b.norm2()? <= tight * rhs_norm {
                // The constrained right-hand side is below the accuracy the step asks for
                // (e.g. bodies at rest in equilibrium): du = 0 solves it to that accuracy, and a
                // relative tolerance on round-off could never be met.
                du.zero()?;
            } else {
                if !exact {
                    ksp.set_tolerances(Some(loose), None, None, None)?;
                }
                let info = ksp.solve(b, du);
                if !exact {
                    ksp.set_tolerances(Some(tight), None, None, None)?;
                }
                its += info?.iterations;
            }
            let trace = self.nodes.trace(du)?;
            let residuals = cons.residuals(&self.nodes, rhs, du, &conds)?;
            let lambda = NormalConstraints::normal_forces(&residuals, &conds, dim, self.factor);
            let ndu = self.nodes.normal_parts(&frames, &trace);
            let gap: Vec<f64> = (0..nc).map(|p| frames[p].0 - ndu[p]).collect();
            let active: Vec<bool> = states.iter().map(|&s| s != NodeState::Inactive).collect();
            let next_active = ActiveSetLoop::next_set(&active, &lambda, &gap, self.nodes.gap_tol);
            // With friction: each node's tangential force and slip, and its next state.
            let mut tangent = Tangent::new(nc);
            let mut next = Vec::with_capacity(nc);
            let mut next_dirs = dirs.clone();
            let mut settled = true;
            for p in 0..nc {
                let state = match (next_active[p], friction[p]) {
                    (false, _) => NodeState::Inactive,
                    (true, None) => NodeState::Slip,
                    (true, Some(f)) => {
                        let n = normals[p];
                        let t = if active[p] {
                            tangential(&residuals[p].map(|x| x / self.factor), &n, dim)
                        } else {
                            [0.0; 3]
                        };
                        let du_q: [f64; 3] =
                            [0, 1, 2].map(|i| if i < dim { trace[p * dim + i] } else { 0.0 });
                        let du_t = tangential(&du_q, &n, dim);
                        let s = [0, 1, 2].map(|i| du_t[i] - motion_t[p][i]);
                        // An entering node's bound comes from its penetration (lambda = 0).
                        let (lam, g) = if active[p] { (lambda[p], 0.0) } else { (0.0, gap[p]) };
                        let bound = friction::slip_bound(f.law, lam, g, c_t[p]);
                        let z = [0, 1, 2].map(|i| t[i] + c_t[p] * s[i]);
                        let len = norm(&z);
                        // A little hysteresis, so that a node at the bound does not flip.
                        let keep = match states[p] {
                            NodeState::Stick => len <= bound * (1.0 + SET_RTOL),
                            NodeState::Slip => len < bound * (1.0 - SET_RTOL),
                            NodeState::Inactive => false,
                        };
                        tangent.set(p, t, s);
                        if fixed[p] {
                            // Held slipping to end a cycle (below).
                            NodeState::Slip
                        } else if keep {
                            NodeState::Stick
                        } else {
                            let dir = if len > 0.0 { z.map(|x| x / len) } else { dirs[p].0 };
                            let ratio = if len > 0.0 { (bound / len).min(1.0) } else { 0.0 };
                            let was = dirs[p].0;
                            let slipping = states[p] == NodeState::Slip;
                            let dot = (0..3).map(|i| dir[i] * was[i]).sum::<f64>();
                            if slipping && dot < 0.0 {
                                // Its slip came out against the direction it slipped along: it
                                // slips back whichever way it is pushed, and the two directions
                                // alternate (nearly incompressible bodies, whose contact zone
                                // spreads sideways under the normal load). Its slip passes
                                // through zero: it sticks (the stick test then decides).
                                settled = false;
                                NodeState::Stick
                            } else {
                                if slipping && distance(&dir, &was) > DIR_TOL {
                                    settled = false;
                                }
                                next_dirs[p] = (dir, ratio);
                                NodeState::Slip
                            }
                        }
                    }
                };
                next.push(state);
            }
            dirs = next_dirs;
            if !exact && (next == states || lp.seen(&next)) {
                // The inexact solves found their set (or cycle among nearby sets): from here
                // on solve to full accuracy, starting from where they ended. That solve
                // confirms the set; it is counted as a solve, not as an active-set iteration.
                exact = true;
                confirmations += 1;
                lp.restart(&next);
                states = next;
                continue;
            }
            if next == states && !settled {
                // The set stays, the slip directions still turn (3D): another Newton step.
                lp.again()?;
                continue;
            }
            if exact && with_friction && next != states && lp.seen(&next) {
                // A cycle of nodes between stick and slip: a node at the bound with a force
                // next to nothing (at the edge of a contact zone) can stick with more than its
                // bound and slip against its own slip, by turns. Such nodes are held slipping
                // along their last direction for the rest of the step (their friction force is
                // the bound's, their slip as it comes), once; a cycle after that is an error.
                let flips: Vec<usize> = (0..nc).filter(|&p| next[p] != states[p]).collect();
                let frictional = flips.iter().all(|&p| {
                    matches!(
                        (states[p], next[p]),
                        (NodeState::Stick, NodeState::Slip) | (NodeState::Slip, NodeState::Stick)
                    )
                });
                if frictional && !flips.iter().any(|&p| fixed[p]) {
                    for &p in &flips {
                        fixed[p] = true;
                        if next[p] == NodeState::Stick {
                            // It slipped last along dirs[p]; keep that direction.
                            next[p] = NodeState::Slip;
                        }
                    }
                    self.held_slipping += flips.len();
                    lp.restart(&next);
                    lp.again()?;
                    states = next;
                    continue;
                }
            }
            match lp.advance(&states, next, &self.nodes.tags)? {
                None => break (lambda, trace, tangent),
                Some(next) => states = next,
            }
        };
        self.extra_solves += lp.iterations - 1 + confirmations;
        let active: Vec<bool> = states.iter().map(|&s| s != NodeState::Inactive).collect();
        if let (Some(r), Some((plain_its, plain_s))) = (self.reference.as_mut(), plain) {
            r.plain_seconds_all_steps += plain_s;
            if active.iter().any(|&a| a) {
                r.steps += 1;
                r.plain_ksp_iterations += plain_its;
                r.plain_seconds += plain_s;
                r.contact_ksp_iterations += its;
                r.contact_seconds += t0.elapsed().as_secs_f64();
            }
        }
        let step_friction = with_friction.then(|| {
            let state = (0..nc)
                .map(|p| match states[p] {
                    NodeState::Inactive => STATE_INACTIVE,
                    NodeState::Stick => STATE_STICK,
                    NodeState::Slip => STATE_SLIP,
                })
                .collect();
            let keep = |v: &[[f64; 3]]| -> Vec<[f64; 3]> {
                (0..nc).map(|p| if active[p] { v[p] } else { [0.0; 3] }).collect()
            };
            StepFriction {
                tangential: keep(&tangent.traction),
                state,
                slip: keep(&tangent.slip),
                motion_t: keep(&motion_t),
            }
        });
        self.slip_states = (0..nc).map(|p| (states[p], dirs[p].0, dirs[p].1)).collect();
        let mut out = self.nodes.step_contact(
            &frames,
            active.clone(),
            &lambda,
            &trace,
            lp.iterations,
            step_friction,
        );
        out.cycled = lp.cycled;
        self.nodes.active = active;
        Ok((out, its))
    }

    fn nodes(&self) -> &ContactNodes<'_> {
        &self.nodes
    }
    fn active_mut(&mut self) -> &mut Vec<bool> {
        &mut self.nodes.active
    }
    fn extra_solves(&self) -> usize {
        self.extra_solves
    }
    fn held_slipping(&self) -> usize {
        self.held_slipping
    }
    fn reference_cost(&self) -> Option<ReferenceCost> {
        self.reference
    }
    fn constrained_operator(&self) -> bool {
        true
    }
}
