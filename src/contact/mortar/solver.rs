//! Two-body contact with dual mortar multipliers, solved by the sparse primal-dual active set
//! ([`crate::contact::pdas::ActiveSet`]) in the mortar basis.
//!
//! Because `D` is diagonal, the change of basis `du = T u~`, `T = I + E`,
//! `E_(q,c),(l,c) = M_ql / D_qq` (slave rows, master columns, each component) makes the
//! linearized weighted gap node-local:
//!
//! ```text
//! g_q - n_q . (D_qq du_q - sum_l M_ql du_l) = D_qq (g_q / D_qq - n_q . u~_q),
//! u~_q = du_q - sum_l (M_ql / D_qq) du_l      (E^2 = 0, so T^{-1} = I - E).
//! ```
//!
//! In that basis the step is `T^T K T u~ = T^T rhs - factor sum_q D_qq lambda_q n_q e_q`:
//! each slave node meets one plane, which the active set solves unchanged; then `du = T u~`.
//! The slave nodes get the force `D lambda` (the inner solver's nodal force), the master
//! nodes `-M^T lambda`, and the contact work `-lambda^T (D n.du_s - M n.du_m)` equals
//! `-sum_q (D lambda)_q n_q . u~_q`, the inner solver's. Small sliding
//! ([`InterfaceMode::Frozen`]): `D`, `M`, normals and gaps are evaluated on the reference
//! configuration and re-evaluated on the current one while the bodies approach (no node in
//! contact), then kept through the contact (docs/method.md, two bodies). Finite sliding
//! ([`InterfaceMode::Follow`]): inside every contact step, `D`, `M` and the normals at the
//! step's midpoint and the planes shifted onto the weighted gaps at its end, in rounds until
//! neither moves (docs/method.md, frozen and following interfaces).
//!
//! Memory: `T` (O(slave nodes) entries beyond the identity) and `T^T K T`, a second operator
//! with `K`'s pattern widened at the slave nodes towards their master neighbours.

use std::collections::HashMap;

use super::interface::{oriented_facets, MortarInterface, SearchState, SurfaceFacet};
use super::normals::NormalKind;
pub use crate::contact::cost::MortarCost;
use crate::contact::interface::ContactSolver;
use crate::contact::nodes::ContactNodes;
use crate::contact::pdas::ActiveSet;
use crate::contact::step::{NodePlane, StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::partition::Partition;
use crate::petsc::{Ksp, Matrix, Vector};

mod basis;
mod follow;
mod rows;

use basis::{basis_change, pattern_of, transfer};

pub struct MortarActiveSet<'w> {
    inner: ActiveSet<'w>,
    pair: Pair,
    /// `E` (without the identity) and `T = I + E`.
    e: Matrix,
    t: Matrix,
    /// `T^T K T`, its solver, and work vectors (built from the step operator by `prepare`).
    hat: Option<Hat>,
    /// Re-evaluate the interface (while no node is in contact) when an interface node moved
    /// farther than this since the last evaluation (`-mortar_update_distance`, default a
    /// tenth of the smallest slave facet; `inf`: the reference configuration only).
    update_distance: f64,
    /// Re-evaluate in contact too (`-mortar_update_in_contact`; finite sliding).
    update_in_contact: bool,
    /// `sum_l M_ql / D_qq` per contact node (1 where the master covers a slave node's support,
    /// 0 at the nodes meeting obstacles beside the pair): the master body's share of the
    /// node's force.
    coverage: Vec<f64>,
    /// The master nodes (mesh indices, ascending) and `(contact node, master index, M_ql /
    /// D_qq)` per entry of `M`: where each slave node's force goes on the master side.
    master: Vec<usize>,
    couplings: Vec<(usize, usize, f64)>,
    /// The last round's normal part of the master nodes' forces (`master_nodal` without
    /// friction's): the main terms the consistent force's rest is taken against.
    master_normal: Vec<[f64; 3]>,
    /// The interface nodes' displacements at the last evaluation (of `T`, the planes and the
    /// rows), and where the Jacobians of the consistent force were computed (following: the
    /// midpoint of the round, while `T` may lag behind by `operator_lag`).
    evaluated_at: Vec<f64>,
    jacobians_at: Vec<f64>,
    cost: MortarCost,
    /// Whether the interface follows the bodies inside the step (`-mortar_interface`).
    mode: InterfaceMode,
    /// Following: the step is done when the midpoint configuration has moved less than this
    /// since the interface was evaluated on it, and every active slave node's gap at the end
    /// of the step is this close to the planes' prediction (`-mortar_geometry_tol`).
    geometry_tol: f64,
    /// Following: how far the midpoint may move before `D`, `M` and the normals are evaluated
    /// again inside a step (1e-4 of the smallest slave facet, or 1e5 `-mortar_geometry_tol`).
    move_tol: f64,
    /// Following, in contact: how far the midpoint may move before `T`, the planes and `T^T K
    /// T` are built again (10 `move_tol`: 1e-3 of a facet; with 100 the two bars' total force
    /// ended 2e-6 of its peak away from the wall's, with 1000 the rounds were 40% more). Their
    /// lag changes only how fast the rounds converge: the rest of the consistent force is taken
    /// against the main terms `T` applied, and the planes' shifts against fresh end-of-step
    /// gaps.
    operator_lag: f64,
    /// The slave nodes' planes as evaluated (linearized from the evaluation point), and the
    /// shift per contact node that moves them onto the end-of-step weighted gap.
    base_planes: Vec<Option<NodePlane>>,
    shift: Vec<f64>,
    /// The step the shifts belong to: a step solved again (the energy correction) starts
    /// from them.
    shift_step: usize,
    /// The last step counted as a following contact step (its solves are counted each).
    counted_step: usize,
    /// Following: the active slave nodes' gap linearization beyond the main terms, in the
    /// basis change (`rows.rs`).
    gap_rows: Vec<rows::GapRow>,
    /// This step goes on without the rows (they cycled).
    rows_off: bool,
    /// The contact node of every slave node (the slave nodes never change).
    slots: Vec<usize>,
    /// Solves beyond one per round of the active set, and rounds beyond one per step.
    extra_rounds: usize,
    /// Following: the rest of the consistent contact force, `sum_q lambda_q grad g~_q` minus
    /// the main terms the basis change applies (per pair node and component, like the pair's
    /// trace), and what it needs: the slave side's adjacency, `D` per contact node where the
    /// interface was evaluated, the factor of the force in the step equation.
    rest: Vec<f64>,
    adjacency: super::gradient::SlaveAdjacency,
    /// This rank's slave facets' Jacobians at the midpoint where the interface was evaluated
    /// (computed when first needed, dropped at each evaluation).
    jacobians: HashMap<usize, super::gradient::FacetJacobian>,
    /// `-mortar_jacobian closed_form`: fully covered facets' Jacobians from linearize.rs.
    closed_form: bool,
    /// `-mortar_gap_rows`: the active nodes' whole gap linearization in the basis change.
    rows_enabled: bool,
    d_evaluated: Vec<f64>,
    factor: f64,
    /// The step operator is a finite-strain tangent (replaced every Newton iteration,
    /// unsymmetric): `T^T K T` is not marked symmetric.
    tangent: bool,
    /// The step operator and the `T` that `T^T K T` was last computed from (`T` replaced:
    /// `None`; a `T` of the same pattern is copied into the old one): with both unchanged a
    /// Newton iteration's tangent refills the product in place (`MatPtAP`'s numeric part on
    /// its symbolic one).
    product_of: Option<crate::petsc::ffi::Mat>,
    /// A fingerprint of this rank's rows of `T`'s nonzero pattern.
    t_pattern: u64,
    /// Finite strain: the step whose solve built the hat solver's preconditioner, and that
    /// solve's KSP iterations (`None`: built at the next solve).
    pc_built: Option<(usize, usize)>,
}

/// How the pair's interface moves with the bodies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InterfaceMode {
    /// Evaluated inside every contact step on the configuration the step reaches (finite
    /// sliding): `D`, `M` and the normals at the midpoint `u^n + du/2` (the force of the
    /// midpoint rule), the weighted gaps at the end `u^{n+1}` (non-penetration at `t_{n+1}`).
    Follow,
    /// Evaluated while no node is in contact and kept from the touch-down (small sliding).
    Frozen,
}

/// What the interface is evaluated from: the pair's facets and nodes, the mesh and partition.
struct Pair {
    mesh: std::rc::Rc<crate::mesh::Mesh>,
    part: std::rc::Rc<Partition>,
    slave: Vec<SurfaceFacet>,
    master: Vec<SurfaceFacet>,
    reach: f64,
    /// The normal field of the gaps (`-mortar_normal`).
    normal: NormalKind,
    /// Slave and master nodes (mesh indices, ascending) and their DOFs (global, owned here).
    nodes: Vec<usize>,
    dofs: Vec<(i32, bool)>,
    slot_of: HashMap<usize, usize>,
    /// The last bucket search's pairs, and the pair's displacement there: searched again once
    /// a node has moved farther than the search's margin (the smallest slave facet) since.
    search: SearchState,
    searched_at: Vec<f64>,
}

impl Pair {
    /// The pair's nodes' displacements, on every rank.
    fn trace(&self, world: &mpi::topology::SimpleCommunicator, u: &Vector) -> Result<Vec<f64>> {
        crate::contact::nodes::trace(world, &self.dofs, self.part.first_dof(), u)
    }

    /// Each pair node's index in `nodes` (its slot in a trace).
    fn slots(&self) -> &HashMap<usize, usize> {
        &self.slot_of
    }

    /// The interface at displacement `trace` (of `self.nodes`), its cost counted in `cost`.
    fn evaluate(
        &mut self,
        world: &mpi::topology::SimpleCommunicator,
        trace: &[f64],
        cost: &mut MortarCost,
        only: Option<&[bool]>,
    ) -> Result<MortarInterface> {
        let t0 = std::time::Instant::now();
        let dim = self.part.dim;
        let at = &self.slot_of;
        let x = |v: usize| {
            let mut p = self.mesh.coords[v];
            if let Some(&k) = at.get(&v) {
                for c in 0..dim {
                    p[c] += trace[k * dim + c];
                }
            }
            p
        };
        self.search.reuse = self.searched_at.len() == trace.len()
            && largest_difference(trace, &self.searched_at) <= self.search.margin;
        let searches = self.search.searches;
        let (iface, search) = MortarInterface::build_timed(
            world,
            &self.mesh,
            &self.part,
            &self.slave,
            &self.master,
            &x,
            self.reach,
            self.normal,
            &mut self.search,
            only,
        )?;
        if self.search.searches > searches {
            self.searched_at = trace.to_vec();
            cost.searches += 1;
        }
        cost.evaluations += 1;
        cost.search_seconds += search;
        cost.evaluation_seconds += t0.elapsed().as_secs_f64();
        Ok(iface)
    }
}

struct Hat {
    k: Matrix,
    ksp: Option<Ksp>,
    rhs: Vector,
    u: Vector,
    du: Vector,
    tmp: Vector,
    /// A configuration the interface is asked at (midpoint, end of the step).
    mid: Vector,
    /// The rest of the consistent force as a vector, and the right-hand side with it.
    rest: Vector,
    rhs_plus: Vector,
}

impl<'w> MortarActiveSet<'w> {
    /// `nodes`: the slave boundary's contact nodes (their boundary weights are `D`), and those
    /// of the group meeting obstacles beside the pair, if any (no plane, `u~ = u` there).
    fn new(
        mut nodes: ContactNodes<'w>,
        mut pair: Pair,
        update_distance: f64,
        options: Settings,
        factor: f64,
    ) -> Result<MortarActiveSet<'w>> {
        let zero = vec![0.0; pair.dofs.len()];
        let mut cost = MortarCost::default();
        let iface = pair.evaluate(nodes.world, &zero, &mut cost, None)?;
        let slots = slave_slots(&nodes, &iface)?;
        nodes.node_planes = Some(planes(
            &iface,
            &pair,
            &vec![0.0; iface.slave.len() * pair.part.dim],
            &slots,
            nodes.len(),
        ));
        let e = transfer(&pair.part, &iface, false)?;
        let t = transfer(&pair.part, &iface, true)?;
        let nodes_len = nodes.len();
        let base_planes = nodes.node_planes.clone().expect("set above");
        Ok(MortarActiveSet {
            mode: options.mode,
            geometry_tol: options.geometry_tol,
            move_tol: options.move_tol,
            operator_lag: 10.0 * options.move_tol,
            base_planes,
            shift: vec![0.0; nodes_len],
            shift_step: usize::MAX,
            counted_step: usize::MAX,
            gap_rows: Vec::new(),
            rows_off: false,
            slots: slots.clone(),
            extra_rounds: 0,
            rest: vec![0.0; pair.dofs.len()],
            adjacency: super::gradient::SlaveAdjacency::new(&pair.slave),
            jacobians: HashMap::new(),
            closed_form: options.closed_form,
            rows_enabled: options.gap_rows,
            d_evaluated: d_at_contact_nodes(&iface, &slots, nodes_len),
            tangent: false,
            product_of: None,
            t_pattern: 0,
            pc_built: None,
            factor,
            inner: ActiveSet::new(nodes, factor),
            pair,
            e,
            t,
            hat: None,
            coverage: coverage(&iface, &slots, nodes_len),
            couplings: couplings(&iface, &slots),
            master_normal: Vec::new(),
            master: iface.master,
            update_distance,
            update_in_contact: options.update_in_contact,
            jacobians_at: zero.clone(),
            evaluated_at: zero,
            cost,
        })
    }
}

/// Node q keeps `n_q . (x_q + u~_q) <= c_q`, `c_q = n_q . (x_q + u~^e_q) + g_q / D_qq` with
/// `u~^e` the slave nodes' mortar-basis displacement where the interface was evaluated, so that
/// the gap there is the weighted gap. A slave node with no master facet in reach cannot touch.
/// Per contact node (`n_nodes` of them; slave node q at `slots[q]`): the slave nodes' planes,
/// `None` at the nodes that meet obstacles beside the pair.
fn planes(
    iface: &MortarInterface,
    pair: &Pair,
    ut_slave: &[f64],
    slots: &[usize],
    n_nodes: usize,
) -> Vec<Option<crate::contact::step::NodePlane>> {
    let dim = pair.part.dim;
    let covered = iface.m_row_sums();
    let mut out = vec![None; n_nodes];
    for q in 0..iface.slave.len() {
        let n = iface.normals[q];
        out[slots[q]] = Some(if !(covered[q] > 0.0 && iface.d[q] > 0.0) {
            (f64::MAX, n)
        } else {
            let x = pair.mesh.coords[iface.slave[q]];
            let c = (0..dim).map(|i| n[i] * (x[i] + ut_slave[q * dim + i])).sum::<f64>()
                + iface.gap[q] / iface.d[q];
            (c, n)
        });
    }
    out
}

/// `D_qq` per contact node (0 off the slave nodes).
fn d_at_contact_nodes(iface: &MortarInterface, slots: &[usize], n_nodes: usize) -> Vec<f64> {
    let mut out = vec![0.0; n_nodes];
    for (q, &d) in iface.d.iter().enumerate() {
        out[slots[q]] = d;
    }
    out
}

/// The master body's share per contact node (0 off the slave nodes).
fn coverage(iface: &MortarInterface, slots: &[usize], n_nodes: usize) -> Vec<f64> {
    let mut out = vec![0.0; n_nodes];
    for (q, (s, d)) in iface.m_row_sums().iter().zip(&iface.d).enumerate() {
        out[slots[q]] = if *d > 0.0 { s / d } else { 0.0 };
    }
    out
}

/// `(contact node, master index, M_ql / D_qq)` per entry of `M`.
fn couplings(iface: &MortarInterface, slots: &[usize]) -> Vec<(usize, usize, f64)> {
    (iface.m.iter())
        .map(|&(q, l, m)| (slots[q as usize], l as usize, m / iface.d[q as usize]))
        .collect()
}

/// The index among the contact nodes of every slave node of the interface; an error unless
/// the contact nodes are the slave nodes and, beside the pair, nodes of no slave facet.
fn slave_slots(nodes: &ContactNodes<'_>, iface: &MortarInterface) -> Result<Vec<usize>> {
    let all = &nodes.boundary.nodes;
    let slots: Vec<usize> = iface.slave.iter().filter_map(|v| all.binary_search(v).ok()).collect();
    let beside =
        nodes.node_planes.as_ref().map_or(all.len().saturating_sub(iface.slave.len()), |p| {
            p.iter().filter(|x| x.is_none()).count()
        });
    if slots.len() != iface.slave.len() || all.len() != iface.slave.len() + beside {
        return Err(Error::Solver("mortar: the contact nodes are not the slave nodes".into()));
    }
    Ok(slots)
}

/// A solver for `k` configured like `like` (type, preconditioner, tolerance), then the
/// command line's `-step_` options, as the step operator's own.
fn ksp_like(k: &Matrix, like: &Ksp) -> Result<Ksp> {
    let mut ksp = Ksp::new("")?;
    ksp.set_operators(k, k)?;
    ksp.set_type(&like.ksp_type()?)?;
    ksp.set_pc_type(&like.pc_type()?)?;
    ksp.set_tolerances(Some(like.rtol()?), Some(1e-50), None, Some(10_000))?;
    ksp.set_from_options()?;
    ksp.set_options_prefix("step_")?;
    ksp.set_from_options()?;
    let iterative = ksp.ksp_type()? != "preonly";
    ksp.set_initial_guess_nonzero(iterative)?;
    ksp.set_up()?;
    Ok(ksp)
}

impl MortarActiveSet<'_> {
    /// Re-evaluates the interface at the pair's displacement `trace`: `T`, the planes, and
    /// `T^T K T` with the constraints and the solver's operators (collective).
    fn update(&mut self, k: &Matrix, trace: Vec<f64>) -> Result<()> {
        let world = self.inner.nodes().world;
        let iface = self.pair.evaluate(world, &trace, &mut self.cost, None)?;
        let t0 = std::time::Instant::now();
        let dim = self.pair.part.dim;
        let slots = slave_slots(self.inner.nodes(), &iface)?;
        self.jacobians_at = trace.clone();
        self.evaluated_at = trace;
        self.jacobians.clear();
        // Following: the active nodes' whole gap linearization joins the basis change (its
        // differences counted with the consistent force's, not with the rebuild).
        let mut rows_seconds = 0.0;
        self.gap_rows = match self.mode {
            InterfaceMode::Follow if self.rows_enabled && !self.rows_off => {
                let t1 = std::time::Instant::now();
                let rows = self.gap_rows(&iface, &slots)?;
                rows_seconds = t1.elapsed().as_secs_f64();
                self.cost.gradient_seconds += rows_seconds;
                rows
            }
            _ => Vec::new(),
        };
        let trace = &self.evaluated_at;
        let at = self.pair.slots();
        // u~ of the slave nodes at the evaluation: u_q - sum_l (M_ql / D_qq) u_l, and along
        // the normal the rows' `- sum_k w_qk . u_k`.
        let mut ut = vec![0.0; iface.slave.len() * dim];
        for (q, &v) in iface.slave.iter().enumerate() {
            for c in 0..dim {
                ut[q * dim + c] = trace[at[&v] * dim + c];
            }
        }
        for &(q, l, m) in &iface.m {
            let (q, l) = (q as usize, at[&iface.master[l as usize]]);
            for c in 0..dim {
                ut[q * dim + c] -= m / iface.d[q] * trace[l * dim + c];
            }
        }
        for r in &self.gap_rows {
            let wu: f64 = (0..dim).map(|c| r.w[c] * trace[r.k * dim + c]).sum();
            for c in 0..dim {
                ut[r.q * dim + c] -= wu * iface.normals[r.q][c];
            }
        }
        let n_nodes = self.inner.nodes().len();
        self.base_planes = planes(&iface, &self.pair, &ut, &slots, n_nodes);
        self.inner.nodes_mut().node_planes = Some(self.shifted_planes());
        // Without rows (frozen, or no active node) the main terms in every component, as the
        // frozen interface has them.
        let (e, t) = match !self.rows_enabled || self.mode == InterfaceMode::Frozen {
            false => (
                rows::transfer_following(&self.pair.part, &iface, &self.gap_rows, false)?,
                rows::transfer_following(&self.pair.part, &iface, &self.gap_rows, true)?,
            ),
            true => (
                transfer(&self.pair.part, &iface, false)?,
                transfer(&self.pair.part, &iface, true)?,
            ),
        };
        self.coverage = coverage(&iface, &slots, n_nodes);
        self.d_evaluated = d_at_contact_nodes(&iface, &slots, n_nodes);
        self.couplings = couplings(&iface, &slots);
        self.master = iface.master;
        // A basis change of the last one's pattern (the same slave-master couplings: the
        // interface moved within its facets) goes into the last one's matrix: the product
        // `T^T K T` keeps its symbolic part (PETSc reuses a product for its own `P` only).
        let pattern = pattern_of(&t)?;
        let same = i32::from(pattern == self.t_pattern);
        let mut all = 0i32;
        mpi::traits::CommunicatorCollectives::all_reduce_into(
            self.inner.nodes().world,
            &same,
            &mut all,
            mpi::collective::SystemOperation::min(),
        );
        if all == 1 {
            self.t.copy_values_from(&t)?;
        } else {
            self.t = t;
            self.product_of = None;
        }
        self.e = e;
        self.t_pattern = pattern;
        self.rebuild(k)?;
        self.cost.operator_seconds += t0.elapsed().as_secs_f64() - rows_seconds;
        Ok(())
    }

    /// `T^T K T`, the constraints on it, and the solver's operators.
    fn rebuild(&mut self, k: &Matrix) -> Result<()> {
        // The same step operator (a finite-strain tangent refilled in place, or the linear
        // one) and a basis change of the last one's pattern: the product's pattern is the
        // last one's (the constraints only write values within it).
        if let Some(h) = self.hat.as_mut().filter(|_| self.product_of == Some(k.raw())) {
            k.ptap_into(&self.t, &mut h.k)?;
            h.k.set_option_symmetric(!self.tangent)?;
            self.inner.operator_replaced(&h.k)?;
            if let Some(ksp) = h.ksp.as_mut() {
                ksp.set_operators(&h.k, &h.k)?;
            }
            return Ok(());
        }
        self.product_of = Some(k.raw());
        let mut k_hat = k.ptap(&self.t)?;
        k_hat.set_option_symmetric(!self.tangent)?;
        self.inner.prepare(&k_hat)?;
        match self.hat.as_mut() {
            Some(h) => {
                if let Some(ksp) = h.ksp.as_mut() {
                    ksp.set_operators(&k_hat, &k_hat)?;
                }
                h.k = k_hat;
            }
            None => {
                let (rhs, u) = k_hat.create_vecs()?;
                let (du, tmp) = k_hat.create_vecs()?;
                let mid = tmp.duplicate()?;
                let (rest, rhs_plus) = (tmp.duplicate()?, tmp.duplicate()?);
                self.hat = Some(Hat { k: k_hat, ksp: None, rhs, u, du, tmp, mid, rest, rhs_plus });
            }
        }
        Ok(())
    }
}

impl MortarActiveSet<'_> {
    /// Small sliding: re-evaluated only while no slave node is active; in contact the interface
    /// stays as it was at the touch-down. With `-mortar_update_in_contact` re-evaluated in
    /// contact too, explicitly (the interface of `t_n` holds at `t_{n+1}`; README "Two bodies").
    fn solve_frozen(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let in_contact = self.inner.nodes().active.iter().any(|&a| a);
        let t0 = std::time::Instant::now();
        if self.update_distance.is_finite() && (!in_contact || self.update_in_contact) {
            let trace = self.pair.trace(self.inner.nodes().world, sys.u)?;
            let moved = largest_difference(&trace, &self.evaluated_at);
            self.cost.step_seconds += t0.elapsed().as_secs_f64();
            if moved > self.update_distance {
                self.update(sys.k, trace)?;
            }
        }
        self.round(sys)
    }

    /// One solve of the active set on the interface as it stands: the basis changes around
    /// the inner solver, and the master side's forces.
    fn round(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { ksp, rhs, u, du, step, time, tau, linearization, .. } = sys;
        // A node with no master under it any more cannot stay in contact.
        let nodes = self.inner.nodes_mut();
        if let Some(planes) = nodes.node_planes.as_ref() {
            for (a, p) in nodes.active.iter_mut().zip(planes) {
                if p.is_some_and(|(c, _)| c >= f64::MAX) {
                    *a = false;
                }
            }
        }
        let t1 = std::time::Instant::now();
        let h = self.hat.as_mut().expect("built in solve");
        if h.ksp.is_none() {
            h.ksp = Some(ksp_like(&h.k, ksp)?);
        }
        // rhs~ = T^T rhs, u~ = T^{-1} u, du~ = T^{-1} du (the first guess); following, the
        // rest of the consistent force joins the right-hand side as a load.
        if self.rest.iter().any(|&x| x != 0.0) {
            h.rhs_plus.waxpy(self.factor, &h.rest, rhs)?;
            self.t.mult_transpose(&h.rhs_plus, &mut h.rhs)?;
        } else {
            self.t.mult_transpose(rhs, &mut h.rhs)?;
        }
        self.e.mult(u, &mut h.tmp)?;
        h.u.waxpy(-1.0, &h.tmp, u)?;
        self.e.mult(du, &mut h.tmp)?;
        h.du.waxpy(-1.0, &h.tmp, du)?;
        let mut step_seconds = t1.elapsed().as_secs_f64();
        // Finite strain: the preconditioner is built at a step's first solve and kept through
        // its rounds and Newton iterations (the tangent and the interface move little within a
        // step: on the oblique balls 309 factorizations became 101, the GMRES iterations the
        // same to 0.1%). A kept one that lets a round take more than twice the iterations of
        // the solve that built it (and 10 more) is built again at the next round; a round that
        // fails on it is solved again, from the round's start, on a fresh one. Only the active
        // set needs restoring: friction's slip states are written once a solve has succeeded.
        let mut keep = self.tangent && self.pc_built.is_some_and(|(s, _)| s == step);
        let (mut out, its) = loop {
            let ksp = h.ksp.as_mut().expect("built above");
            if self.tangent {
                ksp.set_reuse_preconditioner(keep)?;
            }
            let before = keep.then(|| self.inner.nodes().active.clone());
            let inner = StepSystem {
                k: &mut h.k,
                ksp,
                rhs: &h.rhs,
                u: &h.u,
                du: &mut h.du,
                step,
                time,
                tau,
                linearization,
            };
            match self.inner.solve(inner) {
                Err(Error::Solver(_)) if keep => {
                    self.inner.nodes_mut().active = before.expect("kept");
                    self.e.mult(du, &mut h.tmp)?;
                    h.du.waxpy(-1.0, &h.tmp, du)?;
                    keep = false;
                }
                r => break r?,
            }
        };
        if self.tangent {
            self.pc_built = match self.pc_built {
                Some((_, first)) if keep && its > 2 * first + 10 => None,
                Some(built) if keep => Some(built),
                _ => Some((step, its)),
            };
        }
        let t2 = std::time::Instant::now();
        self.t.mult(&h.du, du)?;
        step_seconds += t2.elapsed().as_secs_f64();
        self.cost.step_seconds += step_seconds;
        // The master nodes get -M^T lambda in the equation of motion: a force
        // sum_q coverage_q lambda_q n_q on the master body (with friction, the multiplier is
        // lambda_q n_q + t_q: the slip is weighted by the same mortar basis).
        let tangential = |q: usize| out.row.tangential.get(q).copied().unwrap_or([0.0; 3]);
        for (q, &f) in out.row.force.iter().enumerate() {
            let t = tangential(q);
            for c in 0..3 {
                out.master_force[c] += self.coverage[q] * (f * out.normals[q][c] + t[c]);
            }
        }
        out.master_nodal = vec![[0.0; 3]; self.master.len()];
        self.master_normal = vec![[0.0; 3]; self.master.len()];
        if !out.row.tangential.is_empty() {
            out.master_friction = vec![[0.0; 3]; self.master.len()];
        }
        for &(p, l, w) in &self.couplings {
            let t = tangential(p);
            for c in 0..3 {
                let normal = w * out.row.force[p] * out.normals[p][c];
                self.master_normal[l][c] += normal;
                out.master_nodal[l][c] += normal + w * t[c];
            }
            if let Some(f) = out.master_friction.get_mut(l) {
                for c in 0..3 {
                    f[c] += w * t[c];
                }
            }
        }
        Ok((out, its))
    }
}

/// The largest difference between two equally long lists.
fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
}

impl ContactSolver for MortarActiveSet<'_> {
    fn prepare(&mut self, k: &Matrix) -> Result<()> {
        let t0 = std::time::Instant::now();
        self.rebuild(k)?;
        self.cost.operator_seconds += t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// A finite-strain Newton iteration's tangent: `T^T K T` and its constraints again, with
    /// the basis change of the interface as it stands (the rounds of a following interface
    /// evaluate it again on the iterate's configuration).
    fn operator_replaced(&mut self, k: &Matrix) -> Result<()> {
        self.tangent = true;
        self.prepare(k)
    }

    fn follows_operator_changes(&self) -> bool {
        true
    }

    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        if self.hat.is_none() {
            self.rebuild(sys.k)?;
        }
        match self.mode {
            InterfaceMode::Frozen => self.solve_frozen(sys),
            InterfaceMode::Follow => self.solve_following(sys),
        }
    }

    fn nodes(&self) -> &ContactNodes<'_> {
        self.inner.nodes()
    }
    fn active_mut(&mut self) -> &mut Vec<bool> {
        self.inner.active_mut()
    }
    fn extra_solves(&self) -> usize {
        self.inner.extra_solves() + self.extra_rounds
    }
    fn held_slipping(&self) -> usize {
        self.inner.held_slipping()
    }
    fn is_pair(&self) -> bool {
        true
    }
    fn master_nodes(&self) -> &[usize] {
        &self.master
    }
    fn loaded_dofs(&self) -> Vec<i32> {
        let nodes = self.inner.nodes();
        let dim = nodes.dim;
        let active = self.inner.active();
        let mut dofs = Vec::new();
        for (k, &a) in active.iter().enumerate() {
            if a {
                dofs.extend((0..dim).map(|c| nodes.dofs[k * dim + c].0));
            }
        }
        // The master nodes an active slave node presses on carry its force too.
        for &(p, l, w) in &self.couplings {
            if active.get(p).copied().unwrap_or(false) && w != 0.0 {
                if let Some(&slot) = self.pair.slot_of.get(&self.master[l]) {
                    dofs.extend((0..dim).map(|c| self.pair.dofs[slot * dim + c].0));
                }
            }
        }
        dofs.sort_unstable();
        dofs.dedup();
        dofs
    }
    fn mortar_cost(&self) -> Option<MortarCost> {
        Some(self.cost)
    }
    fn geometry_follows(&self) -> bool {
        self.mode == InterfaceMode::Follow
    }
    fn penetrating(&self, u: &Vector, time: f64) -> Result<Vec<(usize, usize)>> {
        // The planes hold for u~ = T^{-1} u.
        let h = self.hat.as_ref();
        match h {
            Some(h) => {
                let mut eu = h.tmp.duplicate()?;
                self.e.mult(u, &mut eu)?;
                let mut ut = h.tmp.duplicate()?;
                ut.waxpy(-1.0, &eu, u)?;
                self.inner.nodes().penetrating(&ut, time)
            }
            None => Err(Error::Solver("mortar: penetration asked before prepare".into())),
        }
    }
}

/// The mortar pair's options, as the run read them at set-up
/// (`run::options::AppOptions::read`).
#[derive(Debug, Clone)]
pub struct MortarOptions {
    /// `-mortar_update_distance D` (default: a tenth of the smallest slave facet): while no node
    /// is in contact, the interface is evaluated again once an interface node has moved
    /// farther than `D` since the last evaluation; `inf`: the reference configuration only.
    pub update_distance: Option<f64>,
    /// `-mortar_update_in_contact` (default off: small sliding, the interface is kept through
    /// the contact): evaluate it again in contact too (finite sliding).
    pub update_in_contact: bool,
    /// `-mortar_normal slave|average` (default `slave`): the normal field of the gaps and
    /// projections, the slave side's averaged nodal normals or, in 2D, halfway between them
    /// and the master's across.
    pub normal: NormalKind,
    /// `-mortar_interface follow|frozen` (default `follow`): the interface follows the bodies
    /// inside every contact step (finite sliding), or is kept from the touch-down (small
    /// sliding: valid while the bodies slide less than a contact cell, and faster).
    pub mode: InterfaceMode,
    /// `-mortar_geometry_tol L` (default 1e-9 of the slave surface's extent): following, the
    /// gap the planes may still miss when a step is done; the interface may still move 1e5 L
    /// (default 1e-4 of the smallest slave facet).
    pub geometry_tol: Option<f64>,
    /// `-mortar_jacobian differences|closed_form` (default `differences`): the derivatives of
    /// the weighted gaps in the consistent force, by central differences of each facet's
    /// integrals, or in closed form (`linearize.rs`, `linearize3d.rs`; partly covered facets by
    /// differences either way). The two agree (tested); differences are faster here.
    pub closed_form: bool,
    /// `-mortar_gap_rows` (default off): following, the active slave nodes' whole gap
    /// linearization in the basis change, a Newton step of the geometry per round
    /// (`solver/rows.rs`): fewer rounds where the surfaces are curved; a step whose Newton step
    /// overshoots into a configuration the interface cannot be evaluated on starts again
    /// without them (README "Finite sliding").
    pub gap_rows: bool,
}

impl Default for MortarOptions {
    fn default() -> Self {
        MortarOptions {
            update_distance: None,
            update_in_contact: false,
            normal: NormalKind::Slave,
            mode: InterfaceMode::Follow,
            geometry_tol: None,
            closed_form: false,
            gap_rows: false,
        }
    }
}

/// The options of one pair solver with their defaults resolved.
struct Settings {
    closed_form: bool,
    gap_rows: bool,
    mode: InterfaceMode,
    geometry_tol: f64,
    move_tol: f64,
    update_in_contact: bool,
}

/// The contact solver of slave/master pairs of deformable bodies: the interface evaluated
/// on the reference configuration and again, while no node is in contact, whenever an
/// interface node has moved farther than the update distance since the last evaluation; the
/// active set on the slave nodes. Several pairs make one interface: each slave facet is
/// integrated against the master facets of its own pairs, and a slave node on the facets of
/// two pairs couples to both masters. The search reaches as far as the largest slave facet.
/// `beside`: a group of another part of the boundary and the rigid obstacles its nodes meet
/// (in the same active set: `u~ = u` there). A node of a master group may meet obstacles too
/// (`T` leaves master DOFs alone); a slave node may not, nor be a master node (`E^2 = 0`).
pub fn pair_solver<'w>(
    world: &'w mpi::topology::SimpleCommunicator,
    mesh: std::rc::Rc<crate::mesh::Mesh>,
    part: std::rc::Rc<Partition>,
    pairs: &[crate::scene::ContactPair],
    beside: Option<(&str, crate::contact::obstacle::Obstacles)>,
    factor: f64,
    options: &MortarOptions,
) -> Result<Box<dyn ContactSolver + 'w>> {
    if pairs.len() > 64 {
        return Err(Error::Scene(format!("contact.pairs has {} pairs: at most 64", pairs.len())));
    }
    let sides = |side: fn(&crate::scene::ContactPair) -> &str| -> Result<Vec<SurfaceFacet>> {
        let mut out: Vec<SurfaceFacet> = Vec::new();
        let mut seen: HashMap<Vec<usize>, usize> = HashMap::new();
        for (i, p) in pairs.iter().enumerate() {
            for mut f in oriented_facets(&mesh, side(p))? {
                let mut key = f.nodes.clone();
                key.sort_unstable();
                match seen.get(&key) {
                    Some(&k) => out[k].pairs |= 1 << i,
                    None => {
                        f.pairs = 1 << i;
                        seen.insert(key, out.len());
                        out.push(f);
                    }
                }
            }
        }
        Ok(out)
    };
    let mut sf = sides(|p| &p.slave)?;
    let mf = sides(|p| &p.master)?;
    super::interface::spread_facets(world, &mesh, &mut sf);
    let size = |f: &SurfaceFacet| {
        let x0 = mesh.coords[f.nodes[0]];
        f.nodes
            .iter()
            .map(|&v| (0..3).map(|c| (mesh.coords[v][c] - x0[c]).powi(2)).sum::<f64>().sqrt())
            .fold(0.0, f64::max)
    };
    let reach = sf.iter().map(size).fold(0.0, f64::max);
    let smallest = sf.iter().map(size).fold(f64::MAX, f64::min);
    // The slave surface's extent: the largest side of its bounding box.
    let extent = {
        let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
        for &v in sf.iter().flat_map(|f| f.nodes.iter()) {
            for c in 0..3 {
                lo[c] = lo[c].min(mesh.coords[v][c]);
                hi[c] = hi[c].max(mesh.coords[v][c]);
            }
        }
        (0..3).map(|c| hi[c] - lo[c]).fold(smallest, f64::max)
    };
    let update_distance = options.update_distance.unwrap_or(0.1 * smallest);
    let settings = Settings {
        closed_form: options.closed_form,
        gap_rows: options.gap_rows,
        mode: options.mode,
        // The gaps to 1e-9 of the slave surface's extent (penetration far below 1e-8 of the
        // body); D, M and the normals to 1e-4 of a facet (their lag tilts the forces by that
        // fraction, the planes' shift keeps the gaps exact).
        geometry_tol: options.geometry_tol.unwrap_or(1e-9 * extent),
        move_tol: options.geometry_tol.map_or(1e-4 * smallest, |t| 1e5 * t),
        update_in_contact: options.update_in_contact,
    };
    let normal = options.normal;
    if normal == NormalKind::Average && part.dim != 2 {
        return Err(Error::Scene("-mortar_normal average is built for 2D meshes only".into()));
    }
    let node_set = |fs: &[SurfaceFacet]| {
        let mut v: Vec<usize> = fs.iter().flat_map(|f| f.nodes.iter().copied()).collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let (slave_nodes, master_nodes) = (node_set(&sf), node_set(&mf));
    if let Some(&v) = slave_nodes.iter().find(|v| master_nodes.binary_search(v).is_ok()) {
        let on = |side: fn(&crate::scene::ContactPair) -> &str| -> Vec<String> {
            let mut g: Vec<String> = (pairs.iter().map(side))
                .filter(|g| mesh.group_nodes(g).is_ok_and(|n| n.binary_search(&v).is_ok()))
                .map(|g| format!("\"{g}\""))
                .collect();
            g.dedup();
            g
        };
        return Err(Error::Scene(format!(
            "contact: gmsh node {} is on the slave group {} and the master group {}: the two sides of a pair must not share nodes",
            mesh.node_tags[v],
            on(|p| &p.slave).join(", "),
            on(|p| &p.master).join(", ")
        )));
    }
    let mut nodes: Vec<usize> = slave_nodes.iter().chain(&master_nodes).copied().collect();
    nodes.sort_unstable();
    let dofs = nodes
        .iter()
        .flat_map(|&v| (0..part.dim).map(move |c| (v, c)))
        .map(|(v, c)| (part.dof(v, c) as i32, part.owns(v)))
        .collect();
    let slave_groups = crate::scene::slave_groups(pairs);
    let mut boundary = crate::contact::nodes::ContactBoundary::build_groups(&mesh, &slave_groups)?;
    let obstacles = match beside {
        Some((group, obstacles)) => {
            let other = crate::contact::nodes::ContactBoundary::build(&mesh, group)?;
            boundary = boundary.union(other, &mesh)?;
            obstacles
        }
        None => crate::contact::obstacle::Obstacles(Vec::new()),
    };
    // The slave nodes meet their planes as one more "obstacle" after the rigid ones: one law
    // for all pairs.
    let law = pairs[0].friction;
    if let Some(p) = pairs.iter().find(|p| p.friction != law) {
        return Err(Error::Scene(format!(
            "contact: pairs with different friction (slave \"{}\", master \"{}\" against the first pair's) are not built; give them one law",
            p.slave, p.master
        )));
    }
    let mut contact_nodes = ContactNodes::new(world, &mesh, &part, boundary, obstacles);
    contact_nodes.friction.push(law.map(crate::contact::friction::FrictionLaw::from_scene));
    let search = SearchState { margin: smallest, ..SearchState::default() };
    let pair = Pair {
        mesh,
        part,
        slave: sf,
        master: mf,
        reach,
        normal,
        slot_of: nodes.iter().enumerate().map(|(k, &v)| (v, k)).collect(),
        nodes,
        dofs,
        search,
        searched_at: Vec::new(),
    };
    Ok(Box::new(MortarActiveSet::new(contact_nodes, pair, update_distance, settings, factor)?))
}
