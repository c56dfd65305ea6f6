//! What a run keeps while stepping (the energy balance, the contact history, the errors
//! against an exact solution, the series for the stability metrics) and what it makes of it
//! at the end: the [`RunSummary`] and its lines on the console.

use std::path::PathBuf;

use super::diagnostics;
use super::domain::Domain;
use super::views::Views;
use crate::bodies::Bodies;
use crate::comm::{max_over_ranks, sum_over_ranks};
use crate::contact::history::{ContactSummary, History as ContactHistory};
use crate::contact::ContactSolver;
use crate::error::Result;
use crate::io::Checkpoint;
use crate::post::RunCurves;
use crate::report::{BodySummary, ErrorSample, MassCheck, RankHeld, RunSummary, Timings};
use crate::rows::Energy;
use crate::scene::effects::short_number;
use crate::stability::{ContactColumns, RunSeries, Stability};
use crate::time::{Midpoint, StepReport};

/// What the run keeps while stepping, for the energy balance, the summary and the pictures.
pub struct Record {
    /// Reference of the energy balance (the initial energy, or the restarted run's).
    pub e0: f64,
    p0: [f64; 3],
    /// The angular momentum at the start of this run (a restart: at the restart).
    l0: [f64; 3],
    e_max: f64,
    /// max_n |E^n - E^0 - W^n| / max_n E^n
    pub balance: f64,
    /// max_n |E^n - E^0| / E^0
    drift: f64,
    pub curves: RunCurves,
    pub history: ContactHistory,
    errors: Vec<ErrorSample>,
    error_steps: Vec<usize>,
    /// Wall time and KSP iterations of the steps with an active contact node.
    contact_seconds: f64,
    contact_ksp_iterations: usize,
    /// Momentum of each body at the start, per component.
    body_p0: Vec<Vec<f64>>,
    /// Per step from the start: total energy, work of the loads, of the Dirichlet reactions
    /// and of the contact (the series of `/energy`, for the stability metrics).
    energies: Vec<[f64; 4]>,
    /// The largest number of KSP iterations of one step.
    ksp_step_max: usize,
}

impl Record {
    /// The record from the state at step `start` (the initial energy is the reference of the
    /// energy balance; a restart takes its checkpoint's).
    pub fn new(
        d: &Domain,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
        restart: Option<&Checkpoint>,
        start: usize,
    ) -> Result<Record> {
        let e = *midpoint.energy();
        let e0 = restart.map_or(e.total(), |cp| cp.energy_initial);
        let p0 = match restart {
            Some(cp) => cp.momentum_initial,
            None => diagnostics::momentum(d, midpoint.mv())?,
        };
        let mut record = Record {
            e0,
            p0,
            l0: diagnostics::angular_momentum(d, midpoint.mass(), midpoint.u(), midpoint.mv())?,
            e_max: e0.abs(),
            balance: 0.0,
            drift: 0.0,
            curves: RunCurves {
                label: d.scene.mass.kind.name().to_string(),
                time: vec![midpoint.time_at(start)],
                kinetic: vec![e.kinetic],
                potential: vec![e.potential],
                lowest_pressure: vec![],
            },
            history: ContactHistory::default(),
            errors: Vec::new(),
            error_steps: match &d.scene.exact {
                Some(ex) if !ex.error_steps.is_empty() => ex.error_steps.clone(),
                Some(_) => vec![d.n_steps],
                None => vec![],
            },
            contact_seconds: 0.0,
            contact_ksp_iterations: 0,
            body_p0: diagnostics::body_momenta(d, midpoint.mv())?,
            energies: vec![[
                e.total(),
                e.external_work,
                e.dirichlet_work,
                e.contact_work_with_friction(),
            ]],
            ksp_step_max: 0,
        };
        if let Some(c) = contact {
            record.history.start(c);
        }
        Ok(record)
    }

    /// Account for one finished step, `report` of the integrator, `seconds` its wall time.
    pub fn step(&mut self, report: &StepReport, e: &Energy, seconds: f64, tau: f64) {
        self.ksp_step_max = self.ksp_step_max.max(report.ksp_iterations);
        if let Some(c) = &report.contact {
            if c.row.active.iter().any(|&a| a) {
                self.contact_seconds += seconds;
                self.contact_ksp_iterations += report.ksp_iterations;
            }
            self.history.push(c, tau);
        }
        let total = e.total();
        self.curves.time.push(report.time);
        self.curves.kinetic.push(e.kinetic);
        self.curves.potential.push(e.potential);
        self.e_max = self.e_max.max(total.abs());
        let residual =
            total - self.e0 - e.external_work - e.contact_work_with_friction() - e.dirichlet_work;
        self.balance = self.balance.max(residual.abs() / self.e_max.max(f64::MIN_POSITIVE));
        if self.e0 != 0.0 {
            self.drift = self.drift.max(((total - self.e0) / self.e0).abs());
        }
        self.energies.push([
            total,
            e.external_work,
            e.dirichlet_work,
            e.contact_work_with_friction(),
        ]);
    }

    /// Errors against the exact solution at the scene's error steps.
    pub fn errors_at(
        &mut self,
        d: &Domain,
        views: &mut Views,
        n: usize,
        midpoint: &mut Midpoint,
    ) -> Result<()> {
        if self.error_steps.contains(&n) {
            let t = midpoint.time_at(n);
            if let Some((l2, h1)) = diagnostics::exact_errors(d, views, midpoint.u(), t)? {
                let velocity_l2 = match d.scene.exact.as_ref().and_then(|e| e.velocity.as_ref()) {
                    Some(exact) => {
                        // The massless DOFs' velocity as written (their static response's).
                        midpoint.settle_layer_velocity()?;
                        Some(diagnostics::velocity_error(d, views, midpoint.v(), exact, t)?)
                    }
                    None => None,
                };
                self.errors.push(ErrorSample { step: n, time: t, l2, h1_semi: h1, velocity_l2 });
            }
        }
        Ok(())
    }

    /// The checkpoint of step n: what a continued run needs besides the fields.
    pub fn checkpoint(
        &self,
        n: usize,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
    ) -> Checkpoint {
        let e = midpoint.energy();
        Checkpoint {
            step: n,
            time: midpoint.time_at(n),
            energy_initial: self.e0,
            external_work: e.external_work,
            contact_work: e.contact_work,
            dirichlet_work: e.dirichlet_work,
            momentum_initial: self.p0,
            ksp_iterations: midpoint.ksp_iterations(),
            pending_correction: midpoint.corrections().pending,
            friction_dissipation: e.friction_dissipation,
            active: contact.map(|c| c.active().to_vec()).unwrap_or_default(),
        }
    }

    /// The stability metrics of the run from its in-memory series (the same function that
    /// `massfree suite` applies to the HDF5 file, `report::stability_from_file`).
    fn stability(
        &self,
        d: &Domain,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
    ) -> Stability {
        let col = |i: usize| self.energies.iter().map(|r| r[i]).collect::<Vec<f64>>();
        let contact = contact.map(|c| {
            let rows = self.history.rows();
            ContactColumns {
                nodes: c.n_nodes(),
                force: rows.iter().flat_map(|r| r.force.iter().copied()).collect(),
                gap: rows.iter().flat_map(|r| r.gap.iter().copied()).collect(),
                active: rows.iter().flat_map(|r| r.active.iter().copied()).collect(),
                weights: self.history.nodes().1.to_vec(),
                iterations: rows.iter().map(|r| r.iterations as f64).collect(),
                lowest: c.lowest(),
            }
        });
        let series = RunSeries {
            total: col(0),
            external_work: col(1),
            dirichlet_work: col(2),
            contact_work: col(3),
            contact,
            body_size: d.body_size,
            ksp_iterations: midpoint.ksp_iterations(),
            ksp_iterations_step_max: self.ksp_step_max,
        };
        series.measure()
    }
}

/// What the run learned at set-up that its summary reports.
pub struct SetupFacts {
    pub timings: Timings,
    pub mass_check: MassCheck,
    /// Contact nodes and cells of the mass-free layer (`None` without one), in all and per
    /// body.
    pub layer: Option<(usize, usize)>,
    pub body_layers: Vec<(usize, usize)>,
    /// The largest change the consistent initialization made to the massless DOFs (`None`
    /// without massless DOFs or on a restart).
    pub massless_initialized: Option<f64>,
    /// The regime's CFL number `c_p tau / h_min` (largest over the bodies).
    pub cfl: f64,
}

/// The run's summary (collective: every rank makes the same one).
pub fn summarize(
    d: &Domain,
    facts: &SetupFacts,
    record: Record,
    midpoint: &Midpoint,
    contact: Option<&dyn ContactSolver>,
    output: Option<PathBuf>,
    pictures: Vec<PathBuf>,
) -> Result<RunSummary> {
    let mut scratch = midpoint.u().duplicate()?;
    let matmult_seconds = crate::time::operator::time_product(
        &midpoint.operator().k,
        midpoint.v(),
        &mut scratch,
        20,
    )?;
    let peak_memory_mib = sum_over_ranks(d.world, diagnostics::peak_rss_mib());
    let peak_memory_rank_mib = max_over_ranks(d.world, diagnostics::peak_rss_mib());
    let mine =
        [d.mesh.cells.len(), d.part.local_cells.len(), d.mesh.n_nodes(), d.part.n_owned_nodes()];
    let held = crate::comm::gather_all(d.world, &mine.map(|x| x as u64))
        .chunks(4)
        .map(|c| RankHeld {
            cells: c[0] as usize,
            cells_owned: c[1] as usize,
            nodes: c[2] as usize,
            nodes_owned: c[3] as usize,
        })
        .collect();
    let p1 = diagnostics::momentum(d, midpoint.mv())?;
    let body_p1 = diagnostics::body_momenta(d, midpoint.mv())?;
    let e = midpoint.energy();
    let contact_summary = contact.map(|c| {
        let mut s = record.history.summary(
            c,
            &d.surface,
            e.contact_work,
            e.friction_dissipation,
            max_over_ranks(d.world, record.contact_seconds),
        );
        s.ksp_iterations_contact_steps = record.contact_ksp_iterations;
        s
    });
    // Collective: every rank has the same contact solver.
    let mortar = contact.and_then(|c| c.mortar_cost()).map(|m| m.max_over_ranks(d.world));
    let contact_summary = contact_summary.map(|s| ContactSummary { mortar, ..s });
    let stability = record.stability(d, midpoint, contact);
    let impulses = diagnostics::contact_impulses(d, contact, &record.history);
    let friction_impulses = diagnostics::friction_impulses(d, contact, &record.history);
    let ksp = &midpoint.operator().ksp;
    let (layer_contact_nodes, layer_cells) = facts.layer.unwrap_or((0, 0));
    let bodies = (0..d.bodies.n_bodies())
        .map(|i| {
            let reg = &d.bodies.regions[i + 1];
            BodySummary {
                group: reg.group.clone().unwrap_or_default(),
                e: reg.spec.e,
                nu: reg.spec.nu,
                rho: reg.spec.rho,
                mass_kind: d.bodies.mass_of(i + 1).name().to_string(),
                cells: reg.n_cells,
                total_mass: facts.mass_check.body_mass[i].clone(),
                momentum_initial: record.body_p0[i].clone(),
                momentum_final: body_p1[i].clone(),
                layer_contact_nodes: facts.body_layers[i].0,
                layer_cells: facts.body_layers[i].1,
                contact_impulse: impulses[i].clone(),
                friction_impulse: friction_impulses[i].clone(),
            }
        })
        .collect();
    Ok(RunSummary {
        n_nodes: d.part.n_global_nodes(),
        n_cells: d.part.n_global_cells,
        n_dofs: d.part.n_global_dofs(),
        steps: d.n_steps,
        timings: facts.timings.clone(),
        ksp_iterations: midpoint.ksp_iterations(),
        energy_initial: record.e0,
        energy_final: e.total(),
        external_work: e.external_work,
        energy_balance: record.balance,
        energy_drift: record.drift,
        energy_max: record.e_max,
        errors: record.errors,
        output,
        matmult_seconds,
        peak_memory_mib,
        peak_memory_rank_mib,
        held,
        ranks: d.size,
        ksp_type: ksp.ksp_type()?,
        pc_type: ksp.pc_type()?,
        mass_kind: d.scene.mass.kind.name().to_string(),
        layer_contact_nodes,
        layer_cells,
        mass: facts.mass_check.clone(),
        momentum_initial: record.p0[..d.part.dim].to_vec(),
        momentum_final: p1[..d.part.dim].to_vec(),
        angular_momentum_initial: record.l0.to_vec(),
        angular_momentum_final: diagnostics::angular_momentum(
            d,
            midpoint.mass(),
            midpoint.u(),
            midpoint.mv(),
        )?
        .to_vec(),
        contact: contact_summary,
        pictures,
        effects: d.effects(),
        bodies,
        massless_initialization: facts.massless_initialized,
        release_projections: midpoint.release_projections().0,
        release_energy: midpoint.release_projections().1,
        energy_corrections: midpoint.corrections(),
        step_reuse: midpoint.reuse(),
        ksp_iterations_step_max: record.ksp_step_max,
        cfl: facts.cfl,
        stability: Some(stability),
        newton: midpoint.newton_stats().map(|mut s| {
            s.force_seconds = max_over_ranks(d.world, s.force_seconds);
            s.tangent_seconds = max_over_ranks(d.world, s.tangent_seconds);
            s.contact_seconds = max_over_ranks(d.world, s.contact_seconds);
            s.plain_seconds = max_over_ranks(d.world, s.plain_seconds);
            s
        }),
        rotations: Vec::new(),
    })
}

/// Human summary lines of a run (printed by rank 0 through the console); `layer` as in
/// [`SetupFacts::layer`].
pub fn summary_lines(d: &Domain, layer: Option<(usize, usize)>, s: &RunSummary) -> Vec<String> {
    let t = &s.timings;
    let mut lines = vec![
        format!(
            "{}: {}D, {} nodes, {} DOFs, {} cells on {} rank(s); mass {}{}",
            d.scene.name,
            d.mesh.dim,
            s.n_nodes,
            s.n_dofs,
            d.part.n_global_cells,
            d.size,
            mass_kinds(&d.bodies),
            match (layer, &d.bodies.layer) {
                (Some((nodes, cells)), Some((_, groups))) => format!(
                    " (mass-free layer along {}: {nodes} contact nodes, {cells} layer cells)",
                    crate::scene::effects::quoted(groups),
                ),
                _ => String::new(),
            }
        ),
        format!(
            "{} steps of tau = {} to t = {}: {:.3} s stepping ({:.3} ms/step), {:.2} KSP iterations/step",
            s.steps,
            crate::console::time(d.scene.tau),
            crate::console::time(s.steps as f64 * d.scene.tau),
            t.stepping,
            1e3 * t.stepping / s.steps.max(1) as f64,
            s.ksp_iterations as f64 / s.steps.max(1) as f64
        ),
        format!(
            "time: mesh {:.3} s, partition {:.3} s, assembly {:.3} s, solver setup {:.3} s, output {:.3} s, stress {:.3} s, errors {:.3} s",
            t.mesh, t.partition, t.assembly, t.setup, t.output, t.stress, t.errors
        ),
        format!(
            "energy: initial {:.10e}, final {:.10e}, external work {:.6e}; balance |E^n - E^0 - W^n|/max E = {:.2e} (W: loads, contact less friction's dissipation, boundary reactions)",
            s.energy_initial, s.energy_final, s.external_work, s.energy_balance
        ),
    ];
    for r in s.rotations.iter().filter(|r| r.degrees >= 0.1) {
        lines.push(format!(
            "rotation: {} turned {:.1} degrees at most (t = {})",
            r.body,
            r.degrees,
            crate::console::time(r.time)
        ));
    }
    if let Some(nw) = &s.newton {
        lines.push(format!(
            "Newton: {:.2} iterations/step (at most {}; {} on the step's tangent for the energy alone), {} halved corrections{}; the largest energy error a step left {:.2e} of the energy; internal force {:.3} ms, with its tangent {:.3} ms ({:.3e} cells/s/rank)",
            nw.iterations as f64 / nw.steps.max(1) as f64,
            nw.max_iterations,
            nw.energy_chords,
            nw.halvings,
            if nw.restarts > 0 {
                format!(", {} steps solved again from another first guess", nw.restarts)
            } else {
                String::new()
            },
            nw.max_energy_error,
            1e3 * nw.force_seconds / nw.force_evaluations.max(1) as f64,
            1e3 * nw.tangent_seconds / nw.tangent_evaluations.max(1) as f64,
            s.n_cells as f64 * nw.tangent_evaluations as f64
                / (d.size as f64 * nw.tangent_seconds.max(1e-12))
        ));
        if nw.contact_steps > 0 {
            let per = |x: f64, n: usize| x / n.max(1) as f64;
            let (c, p) =
                (per(nw.contact_seconds, nw.contact_steps), per(nw.plain_seconds, nw.plain_steps));
            lines.push(format!(
                "Newton in contact: {} contact steps, {:.2} iterations each (plain steps: {}, {:.2} each); a contact step took {:.3} ms{}{}",
                nw.contact_steps,
                per(nw.contact_iterations as f64, nw.contact_steps),
                nw.plain_steps,
                per(nw.plain_iterations as f64, nw.plain_steps),
                1e3 * c,
                if nw.plain_steps > 0 && p > 0.0 {
                    format!(", {:.2} plain steps ({:.3} ms)", c / p, 1e3 * p)
                } else {
                    String::new()
                },
                if nw.cycled > 0 {
                    format!("; {} iterations took a cycling active set as it was", nw.cycled)
                } else {
                    String::new()
                }
            ));
        }
    }
    if let Some(d) = s.massless_initialization.filter(|&d| d > 0.0) {
        lines.push(format!(
            "massless DOFs: the initial displacement made statically consistent there (largest change {d:.3e})"
        ));
    }
    if s.energy_corrections.enabled {
        let c = &s.energy_corrections;
        lines.push(format!(
            "massless DOFs: contact work put back on {} steps ({} kicked, {} extra solves, {} KSP iterations, {} steps settled without a confirming solve; {} steps handed it on, {} unsettled): {:.3e}, pending at the end {:.3e}",
            c.steps, c.kicked, c.extra_solves, c.iterations, c.closed_form, c.skipped, c.unconverged, c.energy, c.pending
        ));
        if c.kicked > 0 {
            lines.push(format!(
                "massless DOFs: the kicks' force on the layer's rows at most {:.1e} of the massive rows' (static response)",
                c.kick_residual
            ));
        }
    }
    if s.release_projections > 0 {
        lines.push(format!(
            "massless DOFs: released contact nodes put back in static equilibrium after {} steps (energy {:.3e}, in the contact work)",
            s.release_projections, s.release_energy
        ));
    }
    for b in &s.bodies {
        let vec = |v: &[f64]| {
            let x: Vec<String> = v.iter().map(|x| format!("{x:.6e}")).collect();
            format!("({})", x.join(", "))
        };
        let layer = if b.layer_cells > 0 {
            format!(" (layer: {} contact nodes, {} cells)", b.layer_contact_nodes, b.layer_cells)
        } else {
            String::new()
        };
        lines.push(format!(
            "body \"{}\": E = {}, nu = {}, rho = {}, {} mass{layer}; {} cells, total mass {:.10e}, momentum {} -> {}{}",
            b.group,
            short_number(b.e),
            short_number(b.nu),
            short_number(b.rho),
            b.mass_kind,
            b.cells,
            b.total_mass.first().copied().unwrap_or(0.0),
            vec(&b.momentum_initial),
            vec(&b.momentum_final),
            if b.contact_impulse.iter().any(|&x| x != 0.0) {
                format!(", contact impulse {}", vec(&b.contact_impulse))
            } else {
                String::new()
            } + &if b.friction_impulse.iter().any(|&x| x != 0.0) {
                format!(" (friction's part {})", vec(&b.friction_impulse))
            } else {
                String::new()
            }
        ));
    }
    for e in &s.errors {
        lines.push(format!(
            "error at step {} (t = {:.6e}): L2 {:.6e}, H1-seminorm {:.6e}{}",
            e.step,
            e.time,
            e.l2,
            e.h1_semi,
            e.velocity_l2.map_or(String::new(), |v| format!(", velocity L2 {v:.6e}"))
        ));
    }
    if let Some(c) = &s.contact {
        lines.push(format!(
            "contact: steps {}..{}, up to {} active nodes, max pressure {:.4e}, {:.2} active-set iterations/step (max {}), energy loss {:.2e} (contact work {:.4e})",
            c.first_contact_step,
            c.last_contact_step,
            c.max_active_nodes,
            c.max_pressure,
            c.active_set_iterations_mean,
            c.active_set_iterations_max,
            // The energy the contact took, relative to the largest energy of the run: a body
            // released at rest under gravity, or pushed by a moving obstacle, starts at E = 0,
            // and loads or moving boundaries change E besides the contact.
            -c.contact_work / s.energy_max.max(f64::MIN_POSITIVE),
            c.contact_work
        ));
        if !c.friction_impulse.is_empty() {
            lines.push(format!(
                "friction: dissipated {:.6e}; node-steps in stick {}, in slip {} ({} held slipping to end a cycle; last step: {} stick, {} slip); friction impulse ({}); tangential chatter: lowest node osc2 {:.2e}, total TV index {:.3}",
                c.friction_dissipation,
                c.stick_node_steps,
                c.slip_node_steps,
                c.held_slipping_node_steps,
                c.stick_nodes_last,
                c.slip_nodes_last,
                c.friction_impulse.iter().map(|x| format!("{x:.6e}")).collect::<Vec<_>>().join(", "),
                c.lowest_tangential_osc2,
                c.total_tangential_tv_index
            ));
        }
        lines.push(format!(
            "chatter: lowest node osc2 {:.2e}, total-force TV index {:.3}, episodes per node max {} (mean {:.2})",
            c.lowest_osc2, c.total_force_tv_index, c.episodes_max, c.episodes_mean
        ));
        if let Some(m) = &c.mortar {
            let rounds = if m.following_steps > 0 {
                format!(
                    "; interface following the bodies: {:.2} rounds per contact step ({:.2} solves; {} steps without the gap rows, {} facets left out of the derivatives), consistent force {:.3} s",
                    m.rounds as f64 / m.following_steps as f64,
                    m.following_solves as f64 / m.following_steps as f64,
                    m.rows_dropped,
                    m.jacobians_skipped,
                    m.gradient_seconds
                )
            } else {
                String::new()
            };
            lines.push(format!(
                "mortar: {} interface evaluations {:.3} s ({} {} {:.3} s), T^T K T rebuilds {:.3} s, per-step basis changes {:.3} s; {:.1}% of the stepping{rounds}",
                m.evaluations,
                m.evaluation_seconds,
                m.searches,
                if m.searches == 1 { "search" } else { "searches" },
                m.search_seconds,
                m.operator_seconds,
                m.step_seconds,
                100.0 * m.total_seconds
                    / s.timings.stepping.max(1e-300)
            ));
        }
    }
    if let Some(p) = &s.output {
        lines.push(format!("output: {}", p.display()));
    }
    if !s.pictures.is_empty() {
        let list: Vec<String> = s.pictures.iter().map(|p| p.display().to_string()).collect();
        lines.push(format!("pictures: {}", list.join(", ")));
    }
    lines
}

/// The mass kinds the run's cells got: `modified1`, or with bodies of several kinds
/// `consistent + modified1`.
fn mass_kinds(bodies: &Bodies) -> String {
    let mut kinds: Vec<&str> = Vec::new();
    for (r, _) in bodies.in_use() {
        let k = bodies.mass_of(r).name();
        if !kinds.contains(&k) {
            kinds.push(k);
        }
    }
    kinds.join(" + ")
}
