//! The contact history of a run, kept in memory (a few numbers per contact node and step),
//! and its summary: contact period, active-set iterations, peak pressure, chatter metrics,
//! energy and momentum balance across the impact.

use super::interface::ContactSolver;
use super::metrics::{contact_period, episodes, osc2, tv_index};
use super::step::StepContact;
use crate::partition::surface::Surface;
use crate::rows::ContactRow;

#[derive(Debug, Default)]
pub struct History {
    /// One row per step (index 0 = the start).
    rows: Vec<ContactRow>,
    /// The obstacle's impulse `tau sum_n sum_q lambda_q n_q` per component.
    impulse: [f64; 3],
    /// The master body's impulse `tau sum_n master_force` (two-body pairs).
    master_impulse: [f64; 3],
    /// The obstacles' impulse beside a pair, `tau sum_n obstacle_force`.
    obstacle_impulse: [f64; 3],
    /// Per contact node, the impulse its body got there: `-tau sum_n lambda_q n_q`.
    node_impulse: Vec<[f64; 3]>,
    /// Per contact node, the friction's share of `node_impulse`: `-tau sum_n t_q`.
    node_friction_impulse: Vec<[f64; 3]>,
    /// Per master node, the friction's share of `master_node_impulse`.
    master_friction_impulse: Vec<[f64; 3]>,
    /// Node-steps in stick and in slip (friction), and the nodes of the last step in each.
    stick_slip: [usize; 4],
    /// Per master node, `tau sum_n (M^T lambda)_l n` (pairs).
    master_node_impulse: Vec<[f64; 3]>,
    weights: Vec<f64>,
    /// The contact nodes' normals of the last step (zero before the first).
    last_normals: Vec<[f64; 3]>,
    /// The contact nodes (mesh indices), as the solver's boundary lists them.
    nodes: Vec<usize>,
}

/// What a contact run reports (written by `--summary` under `[contact]`).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct ContactSummary {
    pub nodes: usize,
    /// First and last step with an active node (0 if none).
    pub first_contact_step: usize,
    pub last_contact_step: usize,
    pub contact_steps: usize,
    pub active_set_iterations_mean: f64,
    pub active_set_iterations_max: usize,
    pub max_pressure: f64,
    pub max_active_nodes: usize,
    /// The contact node closest to the obstacle at t = 0 (0-based mesh node) and its gmsh tag.
    pub lowest_node: usize,
    pub lowest_node_tag: u64,
    /// Chatter of the lowest node's pressure: period-2 amplitude and total-variation index.
    pub lowest_osc2: f64,
    pub lowest_tv_index: f64,
    /// Total contact force: total-variation index and period-2 amplitude.
    pub total_force_tv_index: f64,
    pub total_force_osc2: f64,
    /// Contact episodes per node that touched: maximum and mean.
    pub episodes_max: usize,
    pub episodes_mean: f64,
    pub contact_work: f64,
    /// With friction: what it dissipated, `sum_n sum_q t_q . s_q >= 0`.
    #[serde(default)]
    pub friction_dissipation: f64,
    /// With friction: node-steps in stick and in slip over the run, and nodes in stick and in
    /// slip at the last step.
    #[serde(default)]
    pub stick_node_steps: usize,
    #[serde(default)]
    pub slip_node_steps: usize,
    #[serde(default)]
    pub stick_nodes_last: usize,
    /// With friction: node-steps held slipping to end a cycle between stick and slip (nodes
    /// at the bound with next to no force, at the edge of a contact zone).
    #[serde(default)]
    pub held_slipping_node_steps: usize,
    #[serde(default)]
    pub slip_nodes_last: usize,
    /// With friction: the friction's part of `impulse`, `-tau sum_n sum_q t_q` (empty
    /// without friction).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub friction_impulse: Vec<f64>,
    /// With friction: the chatter of the tangential traction, as of the pressure: the lowest
    /// node's `|t_q| / D_qq` (period-2 amplitude, total-variation index) and the total
    /// tangential force `|sum_q t_q|` (total-variation index, period-2 amplitude).
    #[serde(default)]
    pub lowest_tangential_osc2: f64,
    #[serde(default)]
    pub lowest_tangential_tv_index: f64,
    #[serde(default)]
    pub total_tangential_tv_index: f64,
    #[serde(default)]
    pub total_tangential_osc2: f64,
    /// Impulse the contact gave the body (the slave body of a pair),
    /// `-tau sum_n sum_q lambda_q n_q`, per component.
    pub impulse: Vec<f64>,
    /// Impulse the contact gave the master body of a pair (empty against obstacles).
    #[serde(default)]
    pub master_impulse: Vec<f64>,
    /// Impulse the obstacles beside a pair gave the body of the group meeting them,
    /// `-tau sum_n sum_q lambda_q n_q` over its nodes (empty without a pair, or a pair alone;
    /// `impulse` is then the slave nodes' part only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub obstacle_impulse: Vec<f64>,
    /// Solves with the step operator beyond one per step: active-set iterations after the
    /// first (pdas), or the Schur complement's column solves (columns).
    pub extra_solves: usize,
    /// Wall time of the steps with an active contact node (max over ranks), seconds.
    pub contact_steps_seconds: f64,
    /// KSP iterations of the steps with an active contact node (step solves only; the
    /// Schur-complement column solves are not counted).
    pub ksp_iterations_contact_steps: usize,
    /// The contact steps against one plain solve each (`-contact_reference_solve` only).
    pub reference: Option<super::cost::ReferenceCost>,
    /// The mortar interface's cost (two-body pairs; wall times the largest over the ranks).
    #[serde(default)]
    pub mortar: Option<super::cost::MortarCost>,
}

/// `dst[k] += tau src[k]` (`src` may be shorter: an empty list adds nothing).
fn add_scaled(dst: &mut [[f64; 3]], src: &[[f64; 3]], tau: f64) {
    for (d, f) in dst.iter_mut().zip(src) {
        for i in 0..3 {
            d[i] += tau * f[i];
        }
    }
}

/// The sum of the per-node values (`nodes` with `at_nodes`, `master` with `at_master`) of the
/// nodes `holds` accepts.
fn sum_held(
    nodes: &[usize],
    at_nodes: &[[f64; 3]],
    master: &[usize],
    at_master: &[[f64; 3]],
    holds: impl Fn(usize) -> bool,
) -> [f64; 3] {
    let mut out = [0.0; 3];
    let all = nodes.iter().zip(at_nodes).chain(master.iter().zip(at_master));
    for (&v, x) in all {
        if holds(v) {
            for i in 0..3 {
                out[i] += x[i];
            }
        }
    }
    out
}

impl History {
    pub fn start(&mut self, c: &dyn ContactSolver) {
        let nc = c.n_nodes();
        self.weights = c.boundary().weights.clone();
        self.last_normals = vec![[0.0; 3]; nc];
        self.nodes.clone_from(&c.boundary().nodes);
        // The first row: the set the run starts from (empty, or a restart's checkpoint).
        self.rows.push(ContactRow {
            force: vec![0.0; nc],
            gap: vec![f64::NAN; nc],
            active: c.active().to_vec(),
            iterations: 0,
            ..ContactRow::default()
        });
    }

    pub fn push(&mut self, c: &StepContact, tau: f64) {
        self.rows.push(c.row.clone());
        self.last_normals.clone_from(&c.normals);
        let n = c.row.force.len();
        self.node_impulse.resize(n, [0.0; 3]);
        for (p, imp) in self.node_impulse.iter_mut().enumerate() {
            for (i, x) in imp.iter_mut().enumerate() {
                *x -= tau * c.row.force[p] * c.normals[p][i];
            }
        }
        add_scaled(&mut self.node_impulse, &c.contact_nodal, tau);
        if !c.row.tangential.is_empty() {
            self.node_friction_impulse.resize(n, [0.0; 3]);
            add_scaled(&mut self.node_friction_impulse, &c.friction_nodal, tau);
            let count = |s: u8| c.row.state.iter().filter(|&&x| x == s).count();
            let (stick, slip) = (count(crate::rows::STATE_STICK), count(crate::rows::STATE_SLIP));
            self.stick_slip = [self.stick_slip[0] + stick, self.stick_slip[1] + slip, stick, slip];
        }
        self.master_friction_impulse.resize(c.master_friction.len(), [0.0; 3]);
        add_scaled(&mut self.master_friction_impulse, &c.master_friction, tau);
        self.master_node_impulse.resize(c.master_nodal.len(), [0.0; 3]);
        add_scaled(&mut self.master_node_impulse, &c.master_nodal, tau);
        for i in 0..3 {
            self.impulse[i] += tau * c.resultant[i];
            self.master_impulse[i] += tau * c.master_force[i];
            self.obstacle_impulse[i] += tau * c.obstacle_force[i];
        }
    }

    /// The impulse the contact gave the nodes `holds` accepts: at the contact nodes (`nodes`,
    /// the solver's boundary nodes) and the master nodes (`master`, the solver's).
    pub fn impulse_on(
        &self,
        nodes: &[usize],
        master: &[usize],
        holds: impl Fn(usize) -> bool,
    ) -> [f64; 3] {
        sum_held(nodes, &self.node_impulse, master, &self.master_node_impulse, holds)
    }

    /// The friction's impulse on the contact nodes (`nodes`) and master nodes (`master`)
    /// `holds` accepts (zero without friction).
    pub fn friction_impulse_on(
        &self,
        nodes: &[usize],
        master: &[usize],
        holds: impl Fn(usize) -> bool,
    ) -> [f64; 3] {
        sum_held(nodes, &self.node_friction_impulse, master, &self.master_friction_impulse, holds)
    }

    /// Every step's row (index 0 = the start).
    pub fn rows(&self) -> &[ContactRow] {
        &self.rows
    }

    /// The last step's row.
    pub fn last_row(&self) -> Option<&ContactRow> {
        self.rows.last()
    }

    /// The contact nodes (mesh indices) and their boundary weights `D_qq`.
    pub fn nodes(&self) -> (&[usize], &[f64]) {
        (&self.nodes, &self.weights)
    }

    /// The contact nodes' normals of the last step (zero before the first step).
    pub fn last_normals(&self) -> &[[f64; 3]] {
        &self.last_normals
    }

    /// Pressure history of contact node `k` (index among the contact nodes).
    pub fn pressure(&self, k: usize) -> Vec<f64> {
        self.rows.iter().map(|r| r.force[k] / self.weights[k]).collect()
    }

    pub fn summary(
        &self,
        c: &dyn ContactSolver,
        surface: &Surface,
        contact_work: f64,
        friction_dissipation: f64,
        contact_steps_seconds: f64,
    ) -> ContactSummary {
        let nc = c.n_nodes();
        let dim = surface.mesh.dim;
        let steps = self.rows.len();
        let any: Vec<bool> = self.rows.iter().map(|r| r.active.iter().any(|&x| x)).collect();
        let period = contact_period(&any);
        let (first, last) = period.unwrap_or((0, 0));
        let its: Vec<usize> =
            (1..steps).filter(|&n| any[n]).map(|n| self.rows[n].iterations).collect();
        let lowest = c.lowest();
        let pressure_of = |k: usize| self.pressure(k);
        let active_of = |k: usize| -> Vec<bool> { self.rows.iter().map(|r| r.active[k]).collect() };
        let p_low = pressure_of(lowest);
        let (lowest_osc2, lowest_tv) = match contact_period(&active_of(lowest)) {
            Some(per) => (osc2(&p_low, per), tv_index(&p_low, per)),
            None => (0.0, 0.0),
        };
        let total: Vec<f64> = self.rows.iter().map(|r| r.force.iter().sum()).collect();
        let (tf_tv, tf_osc2) = match period {
            Some(per) => (tv_index(&total, per), osc2(&total, per)),
            None => (0.0, 0.0),
        };
        let eps: Vec<usize> = (0..nc).map(|k| episodes(&active_of(k))).filter(|&e| e > 0).collect();
        let max_pressure = (0..nc).flat_map(pressure_of).fold(0.0f64, |a, b| a.max(b));
        // The tangential traction's chatter (rows without friction data count as zero).
        let norm = |t: &[f64; 3]| (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        let t_low: Vec<f64> = (self.rows.iter())
            .map(|r| r.tangential.get(lowest).map_or(0.0, |t| norm(t) / self.weights[lowest]))
            .collect();
        let (lowest_tangential_osc2, lowest_tangential_tv_index) =
            match contact_period(&active_of(lowest)) {
                Some(per) if t_low.iter().any(|&x| x > 0.0) => {
                    (osc2(&t_low, per), tv_index(&t_low, per))
                }
                _ => (0.0, 0.0),
            };
        let t_total: Vec<f64> = (self.rows.iter())
            .map(|r| {
                let mut s = [0.0; 3];
                for t in &r.tangential {
                    for i in 0..3 {
                        s[i] += t[i];
                    }
                }
                norm(&s)
            })
            .collect();
        let (total_tangential_tv_index, total_tangential_osc2) = match period {
            Some(per) if t_total.iter().any(|&x| x > 0.0) => {
                (tv_index(&t_total, per), osc2(&t_total, per))
            }
            _ => (0.0, 0.0),
        };
        ContactSummary {
            nodes: nc,
            first_contact_step: first,
            last_contact_step: last,
            contact_steps: any.iter().filter(|&&a| a).count(),
            active_set_iterations_mean: if its.is_empty() {
                0.0
            } else {
                its.iter().sum::<usize>() as f64 / its.len() as f64
            },
            active_set_iterations_max: its.iter().copied().max().unwrap_or(0),
            max_pressure,
            max_active_nodes: self
                .rows
                .iter()
                .map(|r| r.active.iter().filter(|&&x| x).count())
                .max()
                .unwrap_or(0),
            lowest_node: surface.part.node_original[c.boundary().nodes[lowest]],
            lowest_node_tag: surface.mesh.node_tags[c.boundary().nodes[lowest]],
            lowest_osc2,
            lowest_tv_index: lowest_tv,
            total_force_tv_index: tf_tv,
            total_force_osc2: tf_osc2,
            episodes_max: eps.iter().copied().max().unwrap_or(0),
            episodes_mean: if eps.is_empty() {
                0.0
            } else {
                eps.iter().sum::<usize>() as f64 / eps.len() as f64
            },
            contact_work,
            friction_dissipation,
            stick_node_steps: self.stick_slip[0],
            slip_node_steps: self.stick_slip[1],
            stick_nodes_last: self.stick_slip[2],
            held_slipping_node_steps: c.held_slipping(),
            slip_nodes_last: self.stick_slip[3],
            friction_impulse: if self.node_friction_impulse.is_empty() {
                vec![]
            } else {
                let all = self.friction_impulse_on(&self.nodes, &[], |_| true);
                all[..dim].to_vec()
            },
            lowest_tangential_osc2,
            lowest_tangential_tv_index,
            total_tangential_tv_index,
            total_tangential_osc2,
            impulse: (0..dim).map(|i| -self.impulse[i]).collect(),
            master_impulse: if c.is_pair() {
                (0..dim).map(|i| self.master_impulse[i]).collect()
            } else {
                vec![]
            },
            obstacle_impulse: if c.is_pair() && !c.nodes().obstacles.0.is_empty() {
                (0..dim).map(|i| -self.obstacle_impulse[i]).collect()
            } else {
                vec![]
            },
            extra_solves: c.extra_solves(),
            contact_steps_seconds,
            ksp_iterations_contact_steps: 0,
            reference: c.reference_cost(),
            mortar: None,
        }
    }
}
