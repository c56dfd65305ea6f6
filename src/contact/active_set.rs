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
    /// Whether a cycle ends the loop at the current set instead of being an error
    /// ([`ActiveSetLoop::tolerate_cycles`]), and whether one did.
    tolerant: bool,
    pub cycled: bool,
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
        ActiveSetLoop {
            history: vec![first.to_vec()],
            iterations: 0,
            max_iterations,
            step,
            time,
            tolerant: false,
            cycled: false,
        }
    }

    /// A cycle ends the loop at the set just solved (`advance` gives `Ok(None)` and sets
    /// `cycled`): in a Newton iteration's linearization the next iteration moves the
    /// linearization point, and the sets of a cycle there need not recur.
    pub fn tolerate_cycles(&mut self) {
        self.tolerant = true;
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
            if self.tolerant {
                self.cycled = true;
                return Ok(None);
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Sets a, b, a: a cycle. A step's own loop says so in one line naming the nodes that
    /// flip; a Newton linearization's takes the set it solved last and marks it cycled.
    #[test]
    fn a_cycle_is_an_error_unless_the_loop_tolerates_it() {
        let (a, b) = (vec![true, false, true], vec![true, true, false]);
        let tags = [7, 8, 9];
        let mut lp = ActiveSetLoop::new(&a, 10, 2, 0.04);
        assert_eq!(lp.advance(&a, b.clone(), &tags).unwrap(), Some(b.clone()));
        let e = lp.advance(&b, a.clone(), &tags).unwrap_err().to_string();
        assert!(e.contains("the active set cycles; gmsh nodes 8, 9 flip"), "{e}");
        let mut lp = ActiveSetLoop::new(&a, 10, 2, 0.04);
        lp.tolerate_cycles();
        assert_eq!(lp.advance(&a, b.clone(), &tags).unwrap(), Some(b.clone()));
        assert!(!lp.cycled);
        assert_eq!(lp.advance(&b, a.clone(), &tags).unwrap(), None);
        assert!(lp.cycled);
        // The cap still holds.
        let mut lp = ActiveSetLoop::new(&a, 1, 2, 0.04);
        lp.tolerate_cycles();
        assert!(lp.advance(&a, b, &tags).is_err());
    }
}
