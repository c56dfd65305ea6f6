//! The active-set loop's bookkeeping shared by the contact solvers ([`super::pdas`],
//! [`super::columns`], the mortar pair's): the next set from the complementarity function,
//! convergence, cycle detection and the iteration cap.

use crate::error::{Error, Result};

/// The active-set loop's bookkeeping, shared by the solvers: the next set from the
/// complementarity function, convergence, cycle detection and the iteration cap.
///
/// A set is one state per node: `bool` (in contact or not), or with friction the node's
/// [`super::friction::NodeState`].
pub struct ActiveSetLoop<S = bool> {
    history: Vec<Vec<S>>,
    pub iterations: usize,
    max_iterations: usize,
    step: usize,
    time: f64,
}

impl ActiveSetLoop<bool> {
    pub fn new(first: &[bool], max_iterations: usize, step: usize, time: f64) -> ActiveSetLoop {
        ActiveSetLoop::with_states(first, max_iterations, step, time)
    }

    /// The next active set: an active node stays while its force is not negative (relative
    /// to the largest force), an inactive node enters when its gap is negative beyond `gap_tol`.
    pub fn next_set(active: &[bool], force: &[f64], gap: &[f64], gap_tol: f64) -> Vec<bool> {
        let scale = force.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
        (0..active.len())
            .map(|p| if active[p] { force[p] > -1e-12 * scale } else { gap[p] < -gap_tol })
            .collect()
    }
}

impl<S: Clone + PartialEq> ActiveSetLoop<S> {
    pub fn with_states(first: &[S], max_iterations: usize, step: usize, time: f64) -> Self {
        ActiveSetLoop { history: vec![first.to_vec()], iterations: 0, max_iterations, step, time }
    }

    /// Counts an iteration that kept the set but must be repeated (slip directions that
    /// have not settled): an error at the cap.
    pub fn again(&mut self) -> Result<()> {
        self.iterations += 1;
        if self.iterations >= self.max_iterations {
            let (step, time) = (self.step, self.time);
            return Err(Error::Solver(format!(
                "contact at step {step} (t = {}): the slip directions did not settle in {} iterations",
                crate::console::time(time),
                self.max_iterations
            )));
        }
        Ok(())
    }

    /// Whether the loop has already been at `set`.
    pub fn seen(&self, set: &[S]) -> bool {
        self.history.iter().any(|h| h == set)
    }

    /// Starts the cycle history anew from `set` (the iterations before were inexact: a
    /// repeat among them says nothing about the exact ones).
    pub fn restart(&mut self, set: &[S]) {
        self.history = vec![set.to_vec()];
    }

    /// Counts an iteration that gave `next` from `active`: `Ok(None)` when the set settled,
    /// `Ok(Some(next))` to iterate again, an error when it cycles or hits the cap.
    pub fn advance(&mut self, active: &[S], next: Vec<S>, tags: &[u64]) -> Result<Option<Vec<S>>> {
        self.iterations += 1;
        if next == active {
            return Ok(None);
        }
        let (step, time) = (self.step, self.time);
        if self.history.contains(&next) {
            let flips: Vec<String> = (0..next.len())
                .filter(|&k| next[k] != active[k])
                .map(|k| tags[k].to_string())
                .collect();
            return Err(Error::Solver(format!(
                "contact at step {step} (t = {}): the active set cycles; gmsh nodes {} flip",
                crate::console::time(time),
                flips.join(", ")
            )));
        }
        if self.iterations >= self.max_iterations {
            return Err(Error::Solver(format!(
                "contact at step {step} (t = {}): the active set did not settle in {} iterations",
                crate::console::time(time),
                self.max_iterations
            )));
        }
        self.history.push(next.clone());
        Ok(Some(next))
    }
}
