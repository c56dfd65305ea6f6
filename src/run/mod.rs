//! One run of a scene, top to bottom in [`Simulation::run`] (like MFEM's ex10p): the output
//! file, mesh and partition ([`Simulation::setup`]) -> the physics ([`physics`]: `A`, `M` or
//! `M_H`, loads, Dirichlet data, the contact solver) -> the start ([`start`]: the step
//! operator and its solver set up once, the initial state) -> the time loop (the integrator
//! `time::Midpoint` steps, [`record`] keeps the balance, [`output`] writes) -> the summary.
//!
//! The rooms, each with explicit inputs (the run's [`Domain`] and what the phase needs):
//! - [`options`]: the command line's additions to the scene;
//! - [`physics`]: the operators and loads, assembled once;
//! - [`start`]: step solver defaults, initial state, massless initialization, restart;
//! - [`output`]: the HDF5 file's life (create, open, steps, checkpoints, finish, failure);
//! - [`views`]: natural-order and local views of distributed vectors;
//! - [`record`]: the per-step record and the summary;
//! - [`diagnostics`]: mass check, momenta, impulses, exact errors, costs;
//! - [`stress`]: the stress-type output fields.

pub mod blocks;
pub mod diagnostics;
pub mod domain;
pub mod options;
pub mod output;
pub mod physics;
pub mod record;
pub mod rotation;
pub mod start;
pub mod stress;
pub mod views;

use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::bodies::Bodies;
use crate::comm::max_over_ranks;
use crate::console::{Console, Progress};
use crate::contact::{ContactSolver, StepContact};
use crate::error::{Error, Result};
use crate::mesh::share::ASCII_WHOLE_LIMIT;
use crate::mesh::Mesh;
use crate::partition::distribute::read_local_timed;
use crate::phase::{self, HangTimeout, Phase, Watchdog};
use crate::post::{picture_paths, write_pictures};
use crate::report::{MassCheck, RunSummary, Timings};
use crate::rows::Energy;
use crate::scene::{MeshSource, Scene};
use crate::time::Midpoint;
pub use domain::Domain;
pub use options::{AppOptions, RunOptions};
use output::{ContactStep, RunOutput};
use physics::{LoadsAt, Physics};
use record::{Record, SetupFacts};
use stress::StressFields;
use views::Views;

/// One run: the domain, the options, the output file and the run's views of its vectors.
pub struct Simulation<'a> {
    /// A duplicate of the world used only to find out whether an error happened on every rank.
    agree: &'a SimpleCommunicator,
    console: &'a Console,
    pub domain: Domain<'a>,
    opts: RunOptions,
    /// The application's options (`-contact_*`, `-mortar_*`, `-massless_*`), read at set-up.
    app: AppOptions,
    timings: Timings,
    output: RunOutput,
    views: Views<'a>,
    stress: StressFields<'a>,
    /// Contact nodes and cells of the mass-free layer (once assembled).
    layer: Option<(usize, usize)>,
}

/// A run from its start to its end: the integrator, the contact solver, the loads, the
/// record, and what the set-up learned for the summary.
struct Stepping<'a> {
    midpoint: Midpoint,
    contact: Option<Box<dyn ContactSolver + 'a>>,
    loads: LoadsAt,
    record: Record,
    facts: SetupFacts,
    /// The first step of the loop (0, or a restart's checkpoint step).
    first: usize,
    /// How far each body has turned (and the warning for small-strain bodies that turn).
    rotations: rotation::BodyRotations,
}

/// The time loop's clock: its start and the output, error and stress work inside it, which the
/// stepping time excludes.
struct LoopClock {
    start: Instant,
    output: f64,
    /// The errors against the scene's exact solution (diagnostics, like the output).
    errors: f64,
    stress_before: f64,
}

impl LoopClock {
    fn start(stress: &StressFields) -> LoopClock {
        LoopClock {
            start: Instant::now(),
            output: 0.0,
            errors: 0.0,
            stress_before: stress.seconds(),
        }
    }
}

impl<'a> Simulation<'a> {
    /// Output file, scene, mesh and partition. The output file is created first, so that a
    /// run that fails or is stopped in any later phase says so in its file.
    pub fn setup(
        world: &'a SimpleCommunicator,
        agree: &'a SimpleCommunicator,
        console: &'a Console,
        scene: Scene,
        opts: RunOptions,
    ) -> Result<Simulation<'a>> {
        phase::enter(Phase::Start);
        let rank = world.rank() as usize;
        let size = world.size() as usize;
        let output = RunOutput::create(world, &scene, &opts)?;
        let parts = guard(|| {
            // The options, read once: the scene's PETSc options entered where the command line
            // did not set them, the program's solver defaults, then every application option.
            options::apply_scene_options(&scene.solver.options)?;
            options::enter_solver_defaults()?;
            let app = AppOptions::read()?;
            phase::enter(Phase::Meshing);
            let path = mesh_file(world, &scene)?;
            phase::enter(Phase::Partitioning);
            // This rank's part of the mesh: own cells and a ghost layer. Read by blocks (no
            // rank holds the whole mesh), or, with --replicated-mesh, cut out of the whole
            // mesh every rank reads.
            // On one rank the part is the whole mesh: read it whole (the directory exchanges
            // of the distributed path would only cost time there; measured in README).
            let (mesh, part, front) = if opts.replicated_mesh || size == 1 {
                crate::partition::verify::replicated(world, &path, opts.partition)?
            } else {
                read_local_timed(world, &path, opts.partition, ASCII_WHOLE_LIMIT)?
            };
            scene.check_dim(mesh.dim)?;
            crate::mesh::share::agree(world, crate::mesh::check::check_geometry(&mesh))?;
            let t2 = Instant::now();
            let surface =
                crate::partition::surface::gather(world, &mesh, &part, &scene.surface_groups())?;
            let bodies = Bodies::resolve_local(world, &scene, &mesh, &part, &surface)?;
            let t_migration = front.distribute + t2.elapsed().as_secs_f64();
            phase::check_signal(world)?;
            let timings = Timings {
                mesh: max_over_ranks(world, front.read),
                partition: max_over_ranks(world, front.partition),
                migration: max_over_ranks(world, t_migration),
                ..Default::default()
            };
            Ok((mesh, part, surface, timings, bodies, app))
        });
        let (mesh, part, surface, timings, bodies, app) = match parts {
            Ok((mesh, part, surface, timings, bodies, app)) => {
                (Rc::new(mesh), Rc::new(part), Rc::new(surface), timings, bodies, app)
            }
            Err(e) => {
                output.fail(world, agree, &e);
                return Err(e);
            }
        };
        let n_steps = opts.steps.unwrap_or(scene.steps);
        let views = Views::new(world, Rc::clone(&mesh), Rc::clone(&part));
        let stress = StressFields::new(world, Rc::clone(&mesh), Rc::clone(&part));
        let body_size = domain::body_size(world, &mesh);
        let domain =
            Domain { world, scene, bodies, mesh, part, surface, rank, size, n_steps, body_size };
        Ok(Simulation {
            agree,
            console,
            domain,
            opts,
            app,
            timings,
            output,
            views,
            stress,
            layer: None,
        })
    }

    /// The run after `setup`, top to bottom. On an error (or a signal) in any step the output
    /// file is marked, and the error comes back.
    pub fn run(&mut self) -> Result<RunSummary> {
        let result = guard(|| {
            // 1. The physics: A, M (or M_H), loads, Dirichlet data, contact.
            let physics = self.assemble()?;
            // 2. The start: K = 4/tau^2 M + A and its solver (set up once), the initial state,
            //    the output file opened for the time series.
            let mut run = self.start(physics)?;
            // 3. The time loop: step, record, output, progress.
            let n_steps = self.domain.n_steps;
            let hang = self.opts.hang_timeout.unwrap_or(HangTimeout::Auto);
            let mut watchdog = Watchdog::start(hang, self.domain.rank);
            watchdog.arm();
            phase::enter(Phase::Stepping);
            phase::step_done(run.first);
            let mut progress =
                Progress::new(self.console, n_steps, self.domain.scene.output.progress);
            let mut clock = LoopClock::start(&self.stress);
            for n in run.first..n_steps {
                let t_step = Instant::now();
                let report = run.midpoint.step(n, &run.loads, run.contact.as_deref_mut())?;
                let seconds = t_step.elapsed().as_secs_f64();
                run.record.step(&report, run.midpoint.energy(), seconds, run.midpoint.tau());
                run.rotations.step(&self.domain, self.console, run.midpoint.u(), report.time)?;
                self.say_energies(n + 1, report.time, run.midpoint.energy());
                let stop =
                    self.output_step(n + 1, &mut run, report.contact.as_ref(), &mut clock)?;
                phase::step_done(n + 1);
                watchdog.step_time(t_step.elapsed().as_secs_f64());
                // A signal after the last step is the final phase's business: the run still
                // writes its summary, then says it was interrupted.
                if stop && n + 1 < n_steps {
                    progress.finish();
                    return Err(Error::Interrupted(format!(
                        "a signal stopped the run after step {} (t = {}); continue it with --restart",
                        n + 1,
                        crate::console::time(report.time)
                    )));
                }
                let t_errors = Instant::now();
                run.record.errors_at(&self.domain, &mut self.views, n + 1, &mut run.midpoint)?;
                clock.errors += t_errors.elapsed().as_secs_f64();
                let newton = run
                    .midpoint
                    .newton_stats()
                    .map(|s| s.iterations as f64 / s.steps.max(1) as f64);
                progress.update(n + 1, report.time, run.record.balance, newton);
            }
            progress.finish();
            // 4. The summary, the pictures and the file's final metadata.
            let summary = self.finish(run, clock)?;
            watchdog.disarm();
            Ok(summary)
        });
        if let Err(e) = &result {
            let output = std::mem::replace(&mut self.output, RunOutput::None);
            output.fail(self.domain.world, self.agree, e);
        }
        result
    }

    /// Step 1: the physics, and the mass check on it.
    fn assemble(&mut self) -> Result<(Physics<'a>, MassCheck)> {
        let d = &self.domain;
        self.console.say(format!(
            "{}: {} nodes, {} cells ({}D), {} DOFs on {} rank(s); assembling",
            d.scene.name,
            d.part.n_global_nodes(),
            d.part.n_global_cells,
            d.mesh.dim,
            d.part.n_global_dofs(),
            d.size
        ));
        self.console.say(d.effects());
        phase::enter(Phase::Assembling);
        let t0 = Instant::now();
        let physics = Physics::assemble(d, &self.app, self.console)?;
        self.timings.assembly = max_over_ranks(d.world, t0.elapsed().as_secs_f64());
        self.timings.layer = max_over_ranks(d.world, physics.layer_seconds);
        self.timings.stiffness = max_over_ranks(d.world, physics.stiffness_seconds);
        let layer = physics.layer.as_ref();
        let mass_check = diagnostics::check_mass(d, &mut self.views, &physics.m, layer)?;
        phase::check_signal(d.world)?;
        Ok((physics, mass_check))
    }

    /// Step 2: the step operator and its solver (set up once), the initial state (or the
    /// checkpoint's), the output file opened for the time series, and the record of the run
    /// with its first entry written.
    fn start(&mut self, (physics, mass_check): (Physics<'a>, MassCheck)) -> Result<Stepping<'a>> {
        let d = &self.domain;
        let console = self.console;
        phase::enter(Phase::SolverSetup);
        let t1 = Instant::now();
        let Physics { a, m, dirichlet, layer, mut contact, loads, .. } = physics;
        let with_contact = contact.is_some();
        let (op, cfl) =
            start::step_operator(d, &self.app, console, &m, &a, &dirichlet, with_contact)?;
        crate::phase::trace_memory("step operator");
        if let Some(c) = contact.as_mut() {
            c.prepare(&op.k)?;
        }
        self.timings.setup = max_over_ranks(d.world, t1.elapsed().as_secs_f64());
        let (u0, v0) = start::initial_state(d)?;
        let mut midpoint = Midpoint::new(op, m, a, dirichlet, d.scene.tau, u0, v0, 0.0, &loads)?;
        if d.bodies.finite_strain() {
            // Every contact solver but the stored columns follows Newton's tangent.
            if contact.as_deref().is_some_and(|c| !c.follows_operator_changes()) {
                return Err(Error::Usage(
                    "finite strain: -contact_solver columns cannot follow the tangent that changes every Newton iteration (it works with model = \"linear\" only; use pdas)".into(),
                ));
            }
            let newton =
                start::newton(d, &self.app, midpoint.u(), &midpoint.operator().k, midpoint.mass())?;
            midpoint.set_finite_strain(newton)?;
        }
        crate::phase::trace_memory("integrator");
        let massless_initialized = match self.opts.restart {
            // A restart's state already is consistent.
            Some(_) => None,
            None => start::make_massless_consistent(d, &mut midpoint, contact.as_deref(), &loads)?,
        };
        // The energy correction of contact steps with massless DOFs (on unless
        // `-massless_energy_correction false`).
        let correct = self.app.massless_energy_correction;
        midpoint.configure_massless(
            correct,
            self.app.massless_drift_rtol,
            d.part.dim,
            diagnostics::node_bodies(d),
        )?;
        if d.bodies.finite_strain() {
            midpoint.set_reference_positions(diagnostics::reference_positions(d));
        }
        midpoint.set_correction_blend(self.app.massless_correction_blend);
        midpoint.set_correction_kick(self.app.massless_correction_kick);
        // With massless DOFs contact steps start from the last increment: the residual test
        // hardly sees the massless rows, and an extrapolated guess let their velocity drift
        // (1.5e-6 of a rigid translation in 60 steps of the disc, tests/snapshot.rs).
        midpoint.set_contact_predictor(match midpoint.has_massless() {
            true => crate::time::Predictor::Last,
            false => self.app.step_predictor,
        });
        let restart = match &self.opts.restart {
            Some(path) => Some(start::restore(
                d,
                &mut self.views,
                console,
                path,
                &mut midpoint,
                contact.as_deref_mut(),
                &loads,
            )?),
            None => None,
        };
        let first = restart.as_ref().map_or(0, |cp| cp.step);
        if first > d.n_steps {
            return Err(Error::Usage(format!(
                "--restart: the checkpoint is at step {first}, beyond the {} steps of the scene",
                d.n_steps
            )));
        }
        if let (Some(c), None) = (contact.as_deref(), &restart) {
            start::check_no_penetration(d, c, midpoint.u())?;
        }
        let (op, solver) = (midpoint.operator(), contact.as_deref());
        self.timings.output +=
            self.output.open(d, &self.opts, op, solver, layer.as_ref(), &mass_check)?;
        phase::check_signal(d.world)?;
        let record = Record::new(d, &midpoint, contact.as_deref(), restart.as_ref(), first)?;
        self.layer = layer.as_ref().map(|l| (l.n_contact_nodes(), l.n_layer_cells()));
        let facts = SetupFacts {
            timings: Timings::default(),
            mass_check,
            layer: self.layer,
            body_layers: diagnostics::body_layers(d, layer.as_ref()),
            massless_initialized,
            cfl,
        };
        let mut rotations = rotation::BodyRotations::new(d)?;
        rotations.step(d, console, midpoint.u(), midpoint.time_at(first))?;
        if restart.is_none() {
            // The layer's velocity at the start: the derivative of its static response to the
            // initial velocity (held: the nodes in contact at t = 0).
            if let Some(c) = contact.as_deref() {
                midpoint.set_loaded_dofs(c.loaded_dofs());
            }
            midpoint.settle_layer_velocity()?;
        }
        let run = Stepping { midpoint, contact, loads, record, facts, first, rotations };
        let at_start = run.contact.as_deref().map(|solver| ContactStep {
            solver,
            row: run.record.history.last_row().expect("the history's first row"),
            normals: run.record.history.last_normals(),
        });
        let views = &mut self.views;
        self.output.write_step(d, views, &mut self.stress, first, &run.midpoint, at_start)?;
        if self.opts.verbose {
            let e = run.midpoint.energy();
            console.say(format!(
                "step {first}  t = {}  kinetic {:.10e}  potential {:.10e}  total {:.10e}",
                crate::console::time(run.midpoint.time_at(first)),
                e.kinetic,
                e.potential,
                run.record.e0
            ));
        }
        let mut run = run;
        run.record.errors_at(d, &mut self.views, first, &mut run.midpoint)?;
        Ok(run)
    }

    /// The energies of a step on the console (with --verbose).
    fn say_energies(&self, n: usize, t: f64, e: &Energy) {
        if self.opts.verbose {
            self.console.say(format!(
                "step {n}  t = {t:.6e}  kinetic {:.10e}  potential {:.10e}  total {:.10e}  external work {:.10e}  contact work {:.10e}  friction dissipation {:.10e}",
                e.kinetic,
                e.potential,
                e.total(),
                e.external_work,
                e.contact_work,
                e.friction_dissipation
            ));
        }
    }

    /// Write step n (energies, fields when due, contact row) and the checkpoint when due; find
    /// out whether a signal asks the run to stop (every rank learns it here). Returns that.
    fn output_step(
        &mut self,
        n: usize,
        run: &mut Stepping,
        contact: Option<&StepContact>,
        clock: &mut LoopClock,
    ) -> Result<bool> {
        let d = &self.domain;
        let t0 = Instant::now();
        let stress0 = self.stress.seconds();
        // Checkpoints: every 10 field outputs (they hold three fields), at the end, and
        // when a signal stops the run. They and the velocity field hold the layer's settled
        // velocity.
        let due = n.is_multiple_of(10 * d.scene.output.every) || n == d.n_steps;
        if due || self.output.velocity_due(d, n) {
            run.midpoint.settle_layer_velocity()?;
        }
        let now = run.contact.as_deref().zip(contact).map(|(solver, c)| ContactStep {
            solver,
            row: &c.row,
            normals: &c.normals,
        });
        self.output.write_step(d, &mut self.views, &mut self.stress, n, &run.midpoint, now)?;
        // A signal on any rank stops all ranks after this step, with a checkpoint.
        let stop = phase::stop_requested(d.world);
        if due || stop {
            run.midpoint.settle_layer_velocity()?;
            let cp = run.record.checkpoint(n, &run.midpoint, run.contact.as_deref());
            self.output.write_checkpoint(&mut self.views, &cp, &run.midpoint)?;
        }
        // The stress-type fields' computation is timed on its own (`Timings::stress`).
        clock.output += t0.elapsed().as_secs_f64() - (self.stress.seconds() - stress0);
        Ok(stop)
    }

    /// Step 4: the timings, the pictures, the summary and the file's final metadata.
    fn finish(&mut self, mut run: Stepping, clock: LoopClock) -> Result<RunSummary> {
        phase::enter(Phase::Final);
        let world = self.domain.world;
        // Stepping is the loop without its output and stress work (each timed on its own).
        let stepping = clock.start.elapsed().as_secs_f64()
            - clock.output
            - clock.errors
            - (self.stress.seconds() - clock.stress_before);
        self.timings.errors = max_over_ranks(world, clock.errors);
        self.timings.stepping = max_over_ranks(world, stepping);
        self.timings.output = max_over_ranks(world, self.timings.output + clock.output);
        self.timings.stress = max_over_ranks(world, self.stress.seconds());
        let contact = run.contact.as_deref();
        if let Some(c) = contact {
            run.record.curves.lowest_pressure = run.record.history.pressure(c.lowest());
        }
        let pictures = self.pictures(std::mem::take(&mut run.record.curves), contact.is_some());
        run.facts.timings = self.timings.clone();
        let path = self.output.open_file().map(|o| o.path().to_path_buf());
        let d = &self.domain;
        let mut summary =
            record::summarize(d, &run.facts, run.record, &run.midpoint, contact, path, pictures)?;
        summary.rotations = run.rotations.summary(d);
        self.output.finish(world, &summary, d.n_steps)?;
        Ok(summary)
    }

    /// The run's pictures beside the output file, drawn by rank 0 from the histories in
    /// memory. A picture that cannot be drawn (e.g. no font) is a warning, not a failed run;
    /// every rank learns the outcome, since the summary must be the same on all.
    fn pictures(&self, curves: crate::post::RunCurves, with_contact: bool) -> Vec<PathBuf> {
        let Some(out) = self.output.open_file() else { return Vec::new() };
        let world = self.domain.world;
        let prefix = out.path().with_extension("");
        let mut pictures = Vec::new();
        let mut ok = 1i32;
        if self.domain.rank == 0 {
            match write_pictures(&prefix, &[curves]) {
                Ok(p) => pictures = p,
                Err(e) => {
                    ok = 0;
                    eprintln!("massfree: warning: pictures not written: {e}");
                }
            }
        }
        world.process_at_rank(0).broadcast_into(&mut ok);
        if ok == 1 && self.domain.rank != 0 {
            pictures = picture_paths(&prefix, with_contact);
        } else if ok == 0 {
            pictures.clear();
        }
        pictures
    }

    /// Human summary lines of the finished run.
    pub fn summary_lines(&self, s: &RunSummary) -> Vec<String> {
        record::summary_lines(&self.domain, self.layer, s)
    }
}

/// The scene's mesh file: its `msh`, or its `geo` meshed by gmsh on rank 0 (the others wait,
/// then find it in the cache).
pub fn mesh_file(world: &SimpleCommunicator, scene: &Scene) -> Result<PathBuf> {
    let rank = world.rank();
    let path = match &scene.mesh {
        MeshSource::Msh { path } => path.clone(),
        MeshSource::Geo { path, params, binary } => {
            let cache = path.parent().unwrap_or(Path::new(".")).join(".cache");
            let dim_guess = 3; // gmsh -3 meshes the highest dimension present in the .geo
            let mut result = Ok(PathBuf::new());
            if rank == 0 {
                result = crate::mesh::gmsh::mesh_geo(path, params, dim_guess, *binary, &cache);
            }
            // 1: meshed, 0: failed, 2: stopped by a signal.
            let mut code = match &result {
                Ok(_) => 1i32,
                Err(Error::Interrupted(_)) => 2,
                Err(_) => 0,
            };
            world.process_at_rank(0).broadcast_into(&mut code);
            if code != 1 {
                return Err(match result {
                    Err(e) => e,
                    Ok(_) if code == 2 => phase::interrupted(),
                    Ok(_) => Error::Mesh(format!("meshing {} failed on rank 0", path.display())),
                });
            }
            // The others find rank 0's mesh in the cache (same key, no second gmsh run).
            match result {
                Ok(p) if rank == 0 => p,
                _ => crate::mesh::gmsh::mesh_geo(path, params, dim_guess, *binary, &cache)?,
            }
        }
    };
    Ok(path)
}

/// Mesh the scene's geometry and read the whole mesh (every rank that calls it holds it).
pub fn load_mesh(world: &SimpleCommunicator, scene: &Scene) -> Result<Mesh> {
    let mesh = crate::mesh::msh::read_msh(&mesh_file(world, scene)?)?;
    crate::mesh::check::check_geometry(&mesh)?;
    Ok(mesh)
}

/// Run `f`, turning a panic into an error (its message was kept by the panic hook), so that a
/// panic ends the run like any other error: the file says `failed: ...`.
pub fn guard<T>(f: impl FnOnce() -> Result<T>) -> Result<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => Err(Error::Internal(crate::error::panic_message(payload.as_ref()))),
    }
}
