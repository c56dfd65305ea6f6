//! What contact costs, as the run's summary reports it: the active set's steps against plain
//! solves ([`ReferenceCost`]) and the mortar interface's evaluations ([`MortarCost`]).

/// The cost of the contact steps against one plain solve of the same step (the unconstrained
/// operator, the same right-hand side and first guess), summed over the steps that end with
/// an active node. Measured only with `-contact_reference_solve`; the plain solve's result is
/// discarded.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct ReferenceCost {
    pub steps: usize,
    pub plain_ksp_iterations: usize,
    pub plain_seconds: f64,
    /// Every solve of the active-set loop, and the operator rewrites between them.
    pub contact_ksp_iterations: usize,
    pub contact_seconds: f64,
    /// The plain solves of every step (to take them out of the run's time).
    pub plain_seconds_all_steps: f64,
}

/// What the mortar interface cost this rank (the run reports the largest over the ranks).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MortarCost {
    /// Evaluations of the interface (the reference configuration's included).
    pub evaluations: usize,
    /// Wall time of the evaluations: `D`, `M`, normals, weighted gaps, with the search.
    pub evaluation_seconds: f64,
    /// Of that, the bucket search for candidate facet pairs (and, between searches, keeping
    /// the pairs within reach).
    pub search_seconds: f64,
    /// Bucket searches: the first, and one each time an interface node has moved farther than
    /// the search's margin since the last.
    #[serde(default)]
    pub searches: usize,
    /// Wall time of rebuilding `T` and `T^T K T` with its constraint rows after an evaluation.
    pub operator_seconds: f64,
    /// Wall time of the per-step check whether the interface moved (one reduction of the
    /// interface nodes' displacements), and of the basis changes `T^T rhs`, `T u~`.
    pub step_seconds: f64,
    /// With the interface following the bodies: the steps that ended in contact, their solves
    /// (a step the energy correction solves again counts each), and the rounds (solves of the
    /// active set with one geometry) those took in all.
    #[serde(default)]
    pub following_steps: usize,
    #[serde(default)]
    pub following_solves: usize,
    #[serde(default)]
    pub rounds: usize,
    /// Steps whose rounds with the whole gap linearization in the basis change did not settle
    /// and went on without it.
    #[serde(default)]
    pub rows_dropped: usize,
    /// Slave facets left out of the consistent force's derivatives at an evaluation (their
    /// perturbed geometry could not be integrated).
    #[serde(default)]
    pub jacobians_skipped: usize,
    /// Wall time of the consistent force's rest (finite differences of the weighted gaps).
    #[serde(default)]
    pub gradient_seconds: f64,
    /// The sum of the wall times above on one rank, the largest over the ranks (the parts
    /// are each the largest over the ranks, which may be different ranks).
    #[serde(default)]
    pub total_seconds: f64,
}

impl MortarCost {
    /// The largest of every entry over the ranks (collective).
    pub fn max_over_ranks(&self, world: &mpi::topology::SimpleCommunicator) -> MortarCost {
        use mpi::traits::*;
        // The counters too: most are the same on every rank (collective decisions), but a
        // facet left out of the derivatives is a rank's own, and the summary written to the
        // run file must be the same on every rank.
        let local = [
            self.evaluation_seconds,
            self.search_seconds,
            self.operator_seconds,
            self.step_seconds,
            self.gradient_seconds,
            self.evaluation_seconds
                + self.operator_seconds
                + self.step_seconds
                + self.gradient_seconds,
            self.evaluations as f64,
            self.searches as f64,
            self.following_steps as f64,
            self.following_solves as f64,
            self.rounds as f64,
            self.rows_dropped as f64,
            self.jacobians_skipped as f64,
        ];
        let mut all = [0.0; 13];
        world.all_reduce_into(&local[..], &mut all[..], mpi::collective::SystemOperation::max());
        MortarCost {
            evaluation_seconds: all[0],
            search_seconds: all[1],
            operator_seconds: all[2],
            step_seconds: all[3],
            gradient_seconds: all[4],
            total_seconds: all[5],
            evaluations: all[6] as usize,
            searches: all[7] as usize,
            following_steps: all[8] as usize,
            following_solves: all[9] as usize,
            rounds: all[10] as usize,
            rows_dropped: all[11] as usize,
            jacobians_skipped: all[12] as usize,
        }
    }
}
