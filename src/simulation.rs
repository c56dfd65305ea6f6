//! One run of a scene, in the steps of [`Simulation::run`] (like MFEM's ex10p): the output
//! file, mesh and partition (`setup`) -> the physics operators `A`, `M` or `M_H`, loads,
//! Dirichlet data and the contact solver (`assemble`) -> the integrator, the midpoint rule with
//! its step operator set up once (`integrator`) -> the time loop (step, output, progress) ->
//! the summary. The physics (here) is separate from the time integrator (`time::Midpoint`)
//! and from the contact solver (`contact::ContactSolver`).

use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::time::Instant;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::assembly::{self, Loads};
use crate::bodies::Bodies;
use crate::console::{Console, Progress};
use crate::contact::history::{ContactSummary, History as ContactHistory};
use crate::contact::{self, ContactBoundary, ContactSolver, Obstacles};
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::fem::stress::Quantity;
use crate::io::{
    group_key, natural_range, read_checkpoint, Checkpoint, Location, Meta, Output, OutputPlan,
    PlannedField, RunFile,
};
use crate::mass::{build_layer, mass_matrix, MassFreeLayer};
use crate::mesh::Mesh;
use crate::options::AppOptions;
use crate::partition::Partition;
use crate::petsc::{Matrix, NullSpace, Scatter, Vector};
use crate::phase::{self, HangTimeout, Phase, Watchdog};
use crate::post::{picture_paths, write_pictures, RunCurves};
use crate::report::{BodySummary, ErrorSample, MassCheck, RunSummary, Timings};
use crate::scene::effects::short_number;
use crate::scene::{Field, MeshSource, Scene};
use crate::stability::{self, ContactSeries, EnergySeries, Stability};
use crate::stress_output::StressOutput;
use crate::time::{Dirichlet, Energy, Forces, Midpoint, StepOperator, StepSolverDefaults};

/// What the command line adds to a scene.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    pub output: Option<PathBuf>,
    pub overwrite: bool,
    /// Override the scene's number of steps.
    pub steps: Option<usize>,
    pub quiet: bool,
    /// Print the energies of every step.
    pub verbose: bool,
    /// Do not write the HDF5 file.
    pub no_output: bool,
    pub partition: crate::partition::Strategy,
    /// Continue from the checkpoint of this run's HDF5 file.
    pub restart: Option<PathBuf>,
    /// The PETSc options of the command line (recorded in the output).
    pub petsc_args: Vec<String>,
    /// When the watchdog ends a rank that waits for the others (a collective that hangs).
    pub hang_timeout: Option<HangTimeout>,
}

/// Mesh the scene's geometry (gmsh on rank 0, others wait) and read it on every rank.
pub fn load_mesh(world: &SimpleCommunicator, scene: &Scene) -> Result<Mesh> {
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
    let mesh = crate::mesh::msh::read_msh(&path)?;
    crate::mesh::check::check_geometry(&mesh)?;
    Ok(mesh)
}

/// The output file through a run: created at the start (metadata only), opened in parallel
/// for the time loop, closed with its status at the end.
enum RunOutput {
    None,
    Closed(RunFile),
    Open(Output),
}

impl RunOutput {
    fn open(&self) -> Option<&Output> {
        match self {
            RunOutput::Open(o) => Some(o),
            _ => None,
        }
    }
    fn open_mut(&mut self) -> Option<&mut Output> {
        match self {
            RunOutput::Open(o) => Some(o),
            _ => None,
        }
    }
}

pub struct Simulation<'a> {
    world: &'a SimpleCommunicator,
    /// A duplicate of `world` used only to find out whether an error happened on every rank.
    agree: &'a SimpleCommunicator,
    console: &'a Console,
    pub scene: Scene,
    /// The cells of each `[[body]]`: material and mass treatment per cell, the layer's groups.
    pub bodies: Bodies,
    opts: RunOptions,
    /// Shared with the loads the integrator assembles (`LoadsAt`).
    pub mesh: Rc<Mesh>,
    pub part: Rc<Partition>,
    rank: usize,
    size: usize,
    pub timings: Timings,
    /// Contact nodes and cells of the mass-free layer (once assembled).
    layer_summary: Option<(usize, usize)>,
    /// The largest change the consistent initialization made to the massless DOFs
    /// (`Midpoint::make_massless_consistent`; `None` without massless DOFs or on a restart).
    massless_initialized: Option<f64>,
    /// The regime's CFL number `c_p tau / h_min` (largest over the bodies).
    cfl: f64,
    /// Per body: contact nodes and cells of the mass-free layer on it.
    body_layers: Vec<(usize, usize)>,
    mass_check: MassCheck,
    /// Scatter to this rank's block of natural (gmsh) node order, built on first use.
    natural: Option<(Scatter, Vector)>,
    /// Values at the nodes of this rank's cells, built on first use (exact errors, stress).
    local_view: Option<LocalView>,
    /// The stress-type output fields, built at the first step one is due.
    stress: Option<StressOutput>,
    output: RunOutput,
}

/// The values of a distributed vector at the nodes of this rank's cells, ghosts included: a
/// scatter built once into a vector holding them on this rank.
struct LocalView {
    scatter: Scatter,
    values: Vector,
    /// The nodes of this rank's cells, sorted: node `nodes[i]` at slot i.
    nodes: Vec<usize>,
    /// The slot of each node in the values (`usize::MAX` for nodes of no cell of this rank).
    slot: Vec<usize>,
}

/// The physics of a scene, assembled once: stiffness `A`, mass `M` (or `M_H`), loads,
/// Dirichlet data, the mass-free layer and the contact solver.
pub struct Physics<'a> {
    a: Matrix,
    m: Matrix,
    dirichlet: Dirichlet,
    layer: Option<MassFreeLayer>,
    mass_check: MassCheck,
    contact: Option<Box<dyn ContactSolver + 'a>>,
}

/// The loads of a scene as the integrator sees them: `f(t)` assembled on demand.
struct LoadsAt {
    loads: Loads,
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    inertial: Option<InertialLoad>,
}

/// A body force per unit mass `a` (`body_force.acceleration`, gravity), integrated like the
/// inertia: `f = M a_h`. With the mass-free layer the massless DOFs then carry no weight, as
/// they carry no inertia: a body in free fall moves rigidly (`u = a t^2/2` solves
/// `M u'' + A u = M a`, as `A` vanishes on translations), and a body at rest has consistent
/// data. `M_H` keeps the total mass and, for `M_H^1`, its first moments (Lemma 3.3), so the
/// resultant and the moment of a uniform `a` are exact.
enum InertialLoad {
    /// `M a_h`, assembled once.
    Steady(Vector),
    /// `a` depends on `t`: `M a_h(t)` at every evaluation.
    Varying(crate::scene::expr::VecExpr, crate::petsc::Matrix),
}

impl LoadsAt {
    fn new(
        loads: Loads,
        mesh: Rc<Mesh>,
        part: Rc<Partition>,
        acceleration: Option<&crate::scene::expr::VecExpr>,
        m: &crate::petsc::Matrix,
    ) -> Result<LoadsAt> {
        let inertial = match acceleration.filter(|a| !a.is_zero()) {
            None => None,
            Some(a) if a.depends_on_t() => {
                Some(InertialLoad::Varying(a.clone(), m.duplicate(true)?))
            }
            Some(a) => {
                let ah = assembly::interpolate(&mesh, &part, a, 0.0)?;
                let mut f = ah.duplicate()?;
                m.mult(&ah, &mut f)?;
                Some(InertialLoad::Steady(f))
            }
        };
        Ok(LoadsAt { loads, mesh, part, inertial })
    }
}

impl Forces for LoadsAt {
    fn present(&self) -> bool {
        self.loads.present || self.inertial.is_some()
    }
    fn time_dependent(&self) -> bool {
        self.loads.time_dependent || matches!(self.inertial, Some(InertialLoad::Varying(..)))
    }
    fn assemble(&self, t: f64, out: &mut Vector) -> Result<()> {
        if self.loads.present {
            self.loads.assemble(&self.mesh, &self.part, t, out)?;
        } else {
            out.zero()?;
        }
        match &self.inertial {
            None => Ok(()),
            Some(InertialLoad::Steady(f)) => out.axpy(1.0, f),
            Some(InertialLoad::Varying(a, m)) => {
                let ah = assembly::interpolate(&self.mesh, &self.part, a, t)?;
                let mut f = ah.duplicate()?;
                m.mult(&ah, &mut f)?;
                out.axpy(1.0, &f)
            }
        }
    }
}

/// What the run keeps while stepping, for the energy balance, the summary and the pictures.
struct Record {
    /// Reference of the energy balance (the initial energy, or the restarted run's).
    e0: f64,
    p0: [f64; 3],
    e_max: f64,
    /// max_n |E^n - E^0 - W^n| / max_n E^n
    balance: f64,
    /// max_n |E^n - E^0| / E^0
    drift: f64,
    curves: RunCurves,
    history: ContactHistory,
    errors: Vec<ErrorSample>,
    error_steps: Vec<usize>,
    /// Wall time and KSP iterations of the steps with an active contact node.
    contact_seconds: f64,
    contact_ksp_iterations: usize,
    /// Wall time spent writing output inside the loop.
    output_seconds: f64,
    /// Momentum of each body at the start, per component.
    body_p0: Vec<Vec<f64>>,
    /// Per step from the start: total energy, work of the loads, of the Dirichlet reactions
    /// and of the contact (the series of `/energy`, for the stability metrics).
    energies: Vec<[f64; 4]>,
    /// The largest number of KSP iterations of one step.
    ksp_step_max: usize,
}

impl Record {
    /// Account for one finished step (energies after it at time t).
    fn step(&mut self, t: f64, e: &Energy) {
        let total = e.total();
        self.curves.time.push(t);
        self.curves.kinetic.push(e.kinetic);
        self.curves.potential.push(e.potential);
        self.e_max = self.e_max.max(total.abs());
        let residual = total - self.e0 - e.external_work - e.contact_work - e.dirichlet_work;
        self.balance = self.balance.max(residual.abs() / self.e_max.max(f64::MIN_POSITIVE));
        if self.e0 != 0.0 {
            self.drift = self.drift.max(((total - self.e0) / self.e0).abs());
        }
        self.energies.push([total, e.external_work, e.dirichlet_work, e.contact_work]);
    }
}

fn max_over_ranks(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut y = 0.0;
    world.all_reduce_into(&x, &mut y, SystemOperation::max());
    y
}

fn sum_over_ranks(world: &SimpleCommunicator, x: f64) -> f64 {
    let mut y = 0.0;
    world.all_reduce_into(&x, &mut y, SystemOperation::sum());
    y
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
        let output = if opts.no_output {
            RunOutput::None
        } else {
            let path = opts.output.clone().unwrap_or_else(|| scene.output.file.clone());
            if let Some(src) = &opts.restart {
                let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
                    (Ok(x), Ok(y)) => x == y,
                    _ => a == b,
                };
                if same(src, &path) {
                    return Err(Error::Usage(format!(
                        "--restart {}: the continued run must be written to another file (-o NEW.h5)",
                        src.display()
                    )));
                }
            }
            let items = [
                Meta::text("scene", scene.text.clone()),
                Meta::text("version", env!("CARGO_PKG_VERSION")),
                Meta::text("status", "running"),
                Meta::text("effects", scene.effects().summary()),
                Meta::int_on("/", "ranks", size as i64),
            ];
            RunOutput::Closed(RunFile::create(world, &path, opts.overwrite, &items)?)
        };
        let parts = guard(|| {
            phase::enter(Phase::Meshing);
            let t0 = Instant::now();
            let mesh = load_mesh(world, &scene)?;
            scene.check_dim(mesh.dim)?;
            let bodies = Bodies::resolve(&scene, &mesh)?;
            let t_mesh = t0.elapsed().as_secs_f64();
            phase::check_signal(world)?;
            phase::enter(Phase::Partitioning);
            let t1 = Instant::now();
            let part = Partition::with_strategy(&mesh, rank, size, opts.partition)?;
            let t_part = t1.elapsed().as_secs_f64();
            phase::check_signal(world)?;
            let timings = Timings {
                mesh: max_over_ranks(world, t_mesh),
                partition: max_over_ranks(world, t_part),
                ..Default::default()
            };
            Ok((mesh, part, timings, bodies))
        });
        let (mesh, part, timings, bodies) = match parts {
            Ok((mesh, part, timings, bodies)) => (Rc::new(mesh), Rc::new(part), timings, bodies),
            Err(e) => {
                end_with_error(world, agree, output, &e);
                return Err(e);
            }
        };
        Ok(Simulation {
            world,
            agree,
            console,
            scene,
            bodies,
            opts,
            mesh,
            part,
            rank,
            size,
            timings,
            layer_summary: None,
            massless_initialized: None,
            cfl: 0.0,
            body_layers: Vec::new(),
            mass_check: MassCheck::default(),
            natural: None,
            local_view: None,
            stress: None,
            output,
        })
    }

    /// End the output file after an error in any phase (`failed: ...` or `interrupted: ...`).
    fn fail(&mut self, e: &Error) {
        let output = std::mem::replace(&mut self.output, RunOutput::None);
        end_with_error(self.world, self.agree, output, e);
    }

    pub fn n_steps(&self) -> usize {
        self.opts.steps.unwrap_or(self.scene.steps)
    }

    /// The run after `setup`, top to bottom. On an error (or a signal) in any step the output
    /// file is marked, and the error comes back.
    pub fn run(&mut self) -> Result<RunSummary> {
        let result = guard(|| {
            // 1. The physics: A, M (or M_H), loads, Dirichlet data, contact.
            let (physics, loads) = self.assemble()?;
            let forces = LoadsAt::new(
                loads,
                Rc::clone(&self.mesh),
                Rc::clone(&self.part),
                self.scene.body_acceleration.as_ref(),
                &physics.m,
            )?;
            // 2. The integrator: K = 4/tau^2 M + A and its solver, set up once; the state.
            let (mut midpoint, mut contact, start, mut record) =
                self.integrator(physics, &forces)?;
            // 3. Time loop: step, record, output, progress.
            let n_steps = self.n_steps();
            let mut watchdog =
                Watchdog::start(self.opts.hang_timeout.unwrap_or(HangTimeout::Auto), self.rank);
            watchdog.arm();
            phase::enter(Phase::Stepping);
            phase::step_done(start);
            let mut progress = Progress::new(self.console, n_steps, self.scene.output.progress);
            let t_loop = Instant::now();
            let stress_before_loop = self.stress_seconds();
            for n in start..n_steps {
                let t_step = Instant::now();
                let report = midpoint.step(n, &forces, contact.as_deref_mut())?;
                record.ksp_step_max = record.ksp_step_max.max(report.ksp_iterations);
                let t_next = (n + 1) as f64 * midpoint.tau();
                if let Some(c) = &report.contact {
                    if c.row.active.iter().any(|&a| a) {
                        record.contact_seconds += t_step.elapsed().as_secs_f64();
                        record.contact_ksp_iterations += report.ksp_iterations;
                    }
                    record.history.push(c, midpoint.tau());
                }
                record.step(t_next, midpoint.energy());
                self.report_step(n + 1, t_next, midpoint.energy());
                let stop = self.output_step(n + 1, &midpoint, contact.as_deref(), &mut record)?;
                phase::step_done(n + 1);
                watchdog.step_time(t_step.elapsed().as_secs_f64());
                // A signal after the last step is the final phase's business: the run still
                // writes its summary, then says it was interrupted.
                if stop && n + 1 < n_steps {
                    progress.finish();
                    return Err(Error::Interrupted(format!(
                        "a signal stopped the run after step {} (t = {t_next:e}); continue it with --restart",
                        n + 1
                    )));
                }
                self.record_errors(n + 1, midpoint.u(), &mut record)?;
                progress.update(n + 1, t_next, record.balance);
            }
            progress.finish();
            // 4. The summary, the pictures and the file's final metadata.
            phase::enter(Phase::Final);
            // Stepping is the loop without its output and stress work (each timed on its own).
            let stepping = t_loop.elapsed().as_secs_f64()
                - record.output_seconds
                - (self.stress_seconds() - stress_before_loop);
            self.timings.stepping = max_over_ranks(self.world, stepping);
            self.timings.output =
                max_over_ranks(self.world, self.timings.output + record.output_seconds);
            self.timings.stress = max_over_ranks(self.world, self.stress_seconds());
            let summary = self.summarize(&midpoint, contact.as_deref(), record)?;
            self.finish(&summary)?;
            watchdog.disarm();
            Ok(summary)
        });
        if let Err(e) = &result {
            self.fail(e);
        }
        result
    }

    /// Step 1: stiffness, mass, loads, Dirichlet data, the mass-free layer and the contact
    /// solver.
    pub fn assemble(&mut self) -> Result<(Physics<'a>, Loads)> {
        self.console.say(format!(
            "{}: {} nodes, {} cells ({}D), {} DOFs on {} rank(s); assembling",
            self.scene.name,
            self.mesh.n_nodes(),
            self.mesh.cells.len(),
            self.mesh.dim,
            self.part.n_global_dofs(),
            self.size
        ));
        self.console.say(self.effects());
        phase::enter(Phase::Assembling);
        let t0 = Instant::now();
        let mesh = &self.mesh;
        let part = &self.part;
        let bodies = &self.bodies;
        let a = assembly::assemble_matrix(mesh, part, |c, xy, out| {
            kernels::stiffness(mesh.cells[c].kind, xy, bodies.material(c), out)
                .map_err(|e| Error::Mesh(format!("{e} (gmsh element tag {})", mesh.cells[c].tag)))
        })?;
        let layer = match &bodies.layer {
            Some((kind, groups)) => {
                let groups: Vec<&str> = groups.iter().map(String::as_str).collect();
                build_layer(mesh, *kind, &groups)?
            }
            None => None,
        };
        let m = mass_matrix(mesh, part, |c| bodies.cell_mass(c), layer.as_ref())?;
        let neumann: Vec<(String, crate::scene::expr::VecExpr)> =
            self.scene.neumann.iter().map(|n| (n.group.clone(), n.traction.clone())).collect();
        let loads = Loads::new(mesh, part, self.scene.body_force.as_ref(), &neumann)?;
        let dirichlet = Dirichlet::new(mesh, part, &self.scene.dirichlet)?;
        // As the command line gives them: the scene's [solver] options enter the database
        // later, for the step solver (`integrator` reads the options again then).
        let app = AppOptions::read()?;
        let contact: Option<Box<dyn ContactSolver + 'a>> = match &self.scene.contact {
            Some(spec) if !spec.pairs.is_empty() => Some(contact::mortar::pair_solver(
                self.world,
                Rc::clone(&self.mesh),
                Rc::clone(&self.part),
                &spec.pairs,
                spec.obstacle_boundary().map(|g| (g, Obstacles::from_scene(&spec.obstacles))),
                Midpoint::CONTACT_FORCE_FACTOR,
                &app.mortar,
            )?),
            Some(spec) => Some(contact::solver(
                self.world,
                &self.mesh,
                &self.part,
                ContactBoundary::build(&self.mesh, spec.boundary.as_deref().unwrap_or_default())?,
                Obstacles::from_scene(&spec.obstacles),
                Midpoint::CONTACT_FORCE_FACTOR,
                &app.contact,
            )?),
            None => None,
        };
        self.warn_finite_sliding_without_mass(app.mortar.update_in_contact);
        self.timings.assembly = max_over_ranks(self.world, t0.elapsed().as_secs_f64());
        let mass_check = self.check_mass(&m, layer.as_ref())?;
        phase::check_signal(self.world)?;
        Ok((Physics { a, m, dirichlet, layer, mass_check, contact }, loads))
    }

    /// Finite sliding (`-mortar_update_in_contact`) with the mass-free layer on a pair: the
    /// forces of an interface re-evaluated in contact are not the gradient of the gap (no
    /// consistent linearization of `D`, `M` and the normals), so they can do positive work;
    /// with massless interface nodes nothing holds that back when the updates come often
    /// (measured on the two discs: stable with updates 0.003 or more apart, the energy grows
    /// at 0.002). Said once, on rank 0, as a warning: the run goes on.
    fn warn_finite_sliding_without_mass(&self, update_in_contact: bool) {
        let Some(spec) = &self.scene.contact else { return };
        let Some((_, groups)) = &self.bodies.layer else { return };
        let massless =
            spec.pairs.iter().any(|p| groups.iter().any(|g| *g == p.slave || *g == p.master));
        if massless && update_in_contact {
            self.console.warn(
                "-mortar_update_in_contact with the mass-free layer on a pair: frequent in-contact updates can make the energy grow (no consistent linearization); keep -mortar_update_distance at its default or larger and watch the energy balance",
            );
        }
    }

    /// Step 2: the step operator and its solver (set up once), the initial state (or the
    /// checkpoint's), the output file opened for the time series, and the record of the run.
    #[allow(clippy::type_complexity)]
    fn integrator(
        &mut self,
        physics: Physics<'a>,
        forces: &dyn Forces,
    ) -> Result<(Midpoint, Option<Box<dyn ContactSolver + 'a>>, usize, Record)> {
        phase::enter(Phase::SolverSetup);
        let t1 = Instant::now();
        let Physics { a, m, dirichlet, layer, mass_check, mut contact } = physics;
        let null_space = self.near_null_space()?;
        // The step solver's defaults follow the regime (scene and command line still win).
        let regime = self.bodies.regime(self.scene.tau, &self.min_edges());
        self.cfl = regime.cfl;
        let (mut defaults, why) = StepSolverDefaults::for_regime(&regime, contact.is_some());
        if let Some(k) = &self.scene.solver.ksp_type {
            defaults.ksp_type = k.clone();
        }
        if let Some(p) = &self.scene.solver.pc_type {
            defaults.pc_type = p.clone();
        }
        if let Some(r) = self.scene.solver.rtol {
            defaults.rtol = r;
        }
        apply_scene_options(&self.scene.solver.options)?;
        // Again, with the scene's options in the database: they count for the step solver
        // (the contact solver's options were read before they were entered).
        let app = AppOptions::read()?;
        defaults.user_reuse_preconditioner = app.user_reuse_preconditioner;
        let op = StepOperator::new(
            &m,
            &a,
            self.scene.tau,
            dirichlet.dofs().to_vec(),
            dirichlet.nonzero,
            Some(&null_space),
            &defaults,
        )?;
        let (ksp_type, pc_type) = (op.ksp.ksp_type()?, op.ksp.pc_type()?);
        let chosen = if pc_type == defaults.pc_type && self.scene.solver.pc_type.is_none() {
            why
        } else {
            "set by the scene or the command line".to_string()
        };
        self.console.say(format!("step solver: {ksp_type} + {pc_type} ({chosen})"));
        if let Some(c) = contact.as_mut() {
            c.prepare(&op.k)?;
        }
        self.timings.setup = max_over_ranks(self.world, t1.elapsed().as_secs_f64());
        // The initial state: nodal interpolants of the scene's initial fields.
        let u0 = match &self.scene.initial_displacement {
            Some(e) => assembly::interpolate(&self.mesh, &self.part, e, 0.0)?,
            None => assembly::new_vector(&self.part)?,
        };
        let v0 = match &self.scene.initial_velocity {
            Some(e) => assembly::interpolate(&self.mesh, &self.part, e, 0.0)?,
            None => assembly::new_vector(&self.part)?,
        };
        let mut midpoint = Midpoint::new(op, m, a, dirichlet, self.scene.tau, u0, v0, 0.0, forces)?;
        if self.opts.restart.is_none() {
            // The massless DOFs start in static equilibrium (a restart's state already is).
            // Contact nodes the projection would push through an obstacle or the master side
            // need their contact force for it (bodies touching at t = 0): they are held as
            // given, and the projection is made again without them.
            let mut hold: Vec<i32> = Vec::new();
            loop {
                let change = midpoint.make_massless_consistent(forces, 0.0, &hold)?;
                let through = match contact.as_ref() {
                    Some(c) => c.penetrating(midpoint.u(), 0.0)?,
                    None => Vec::new(),
                };
                let dofs: Vec<i32> = (through.iter())
                    .flat_map(|&(v, _)| (0..self.part.dim).map(move |c| (v, c)))
                    .map(|(v, c)| self.part.dof(v, c) as i32)
                    .filter(|d| !hold.contains(d))
                    .collect();
                if through.is_empty() {
                    self.massless_initialized = change;
                    break;
                }
                midpoint.undo_massless(forces, 0.0)?;
                if dofs.is_empty() {
                    // Penetrating as given: the scene check below says so.
                    break;
                }
                hold.extend(dofs);
            }
        }
        // The energy correction of contact steps with massless DOFs (on unless
        // `-massless_energy_correction false`).
        let correct = app.massless_energy_correction.clone()?;
        midpoint.configure_massless(correct, self.part.dim, self.node_bodies())?;
        let restart = match self.opts.restart.clone() {
            Some(path) => {
                Some(self.restore(&path, &mut midpoint, contact.as_deref_mut(), forces)?)
            }
            None => None,
        };
        let start = restart.as_ref().map_or(0, |cp| cp.step);
        if start > self.n_steps() {
            return Err(Error::Usage(format!(
                "--restart: the checkpoint is at step {start}, beyond the {} steps of the scene",
                self.n_steps()
            )));
        }
        if let (Some(c), Some(spec), None) =
            (contact.as_ref(), self.scene.contact.as_ref(), restart.as_ref())
        {
            let hits = c.penetrating(midpoint.u(), 0.0)?;
            // The first obstacle that intersects the body, and its nodes.
            if let Some(first) = hits.iter().map(|&(_, o)| o).min() {
                let bad: Vec<usize> =
                    hits.iter().filter(|&&(_, o)| o == first).map(|&(v, _)| v).collect();
                let tags: Vec<String> =
                    bad.iter().take(10).map(|&v| self.mesh.node_tags[v].to_string()).collect();
                // Past the obstacles: a slave node's plane (the master body).
                let what = if first < spec.obstacles.len() {
                    spec.obstacle_key(first)
                } else {
                    "a master body (contact.master or contact.pairs)".to_string()
                };
                return Err(Error::Scene(format!(
                    "{what} already intersects the body at t = 0: {} contact node(s) penetrate it (gmsh nodes {}{})",
                    bad.len(),
                    tags.join(", "),
                    if bad.len() > 10 { ", ..." } else { "" }
                )));
            }
        }
        self.open_output(midpoint.operator(), contact.as_deref(), &layer, &mass_check)?;
        phase::check_signal(self.world)?;

        // The record, from the initial energy (the reference of the energy balance).
        let e = *midpoint.energy();
        let e0 = restart.as_ref().map_or(e.total(), |cp| cp.energy_initial);
        let p0 = match restart.as_ref() {
            Some(cp) => cp.momentum_initial,
            None => self.momentum(midpoint.mv())?,
        };
        let t_start = start as f64 * self.scene.tau;
        let n_steps = self.n_steps();
        let mut record = Record {
            e0,
            p0,
            e_max: e0.abs(),
            balance: 0.0,
            drift: 0.0,
            curves: RunCurves {
                label: self.scene.mass.kind.name().to_string(),
                time: vec![t_start],
                kinetic: vec![e.kinetic],
                potential: vec![e.potential],
                lowest_pressure: vec![],
            },
            history: ContactHistory::default(),
            errors: Vec::new(),
            error_steps: match &self.scene.exact {
                Some(ex) if !ex.error_steps.is_empty() => ex.error_steps.clone(),
                Some(_) => vec![n_steps],
                None => vec![],
            },
            contact_seconds: 0.0,
            contact_ksp_iterations: 0,
            output_seconds: 0.0,
            body_p0: self.body_momenta(midpoint.mv())?,
            energies: vec![[e.total(), e.external_work, e.dirichlet_work, e.contact_work]],
            ksp_step_max: 0,
        };
        if let Some(c) = contact.as_deref() {
            record.history.start(c);
        }
        self.layer_summary = layer.as_ref().map(|l| (l.n_contact_nodes(), l.n_layer_cells()));
        self.body_layers = (0..self.bodies.n_bodies())
            .map(|i| match layer.as_ref() {
                Some(l) => self.body_layer(l, i),
                None => (0, 0),
            })
            .collect();
        self.mass_check = mass_check;
        self.write_step(start, &midpoint, &record)?;
        if self.opts.verbose {
            self.console.say(format!(
                "step {start}  t = {t_start:e}  kinetic {:.10e}  potential {:.10e}  total {e0:.10e}",
                e.kinetic, e.potential
            ));
        }
        self.record_errors(start, midpoint.u(), &mut record)?;
        Ok((midpoint, contact, start, record))
    }

    /// The energies of a step on the console (with --verbose).
    fn report_step(&self, n: usize, t: f64, e: &Energy) {
        if self.opts.verbose {
            self.console.say(format!(
                "step {n}  t = {t:.6e}  kinetic {:.10e}  potential {:.10e}  total {:.10e}  external work {:.10e}  contact work {:.10e}",
                e.kinetic,
                e.potential,
                e.total(),
                e.external_work,
                e.contact_work
            ));
        }
    }

    /// Errors against the exact solution at the scene's error steps.
    fn record_errors(&mut self, n: usize, u: &Vector, record: &mut Record) -> Result<()> {
        if record.error_steps.contains(&n) {
            let t = n as f64 * self.scene.tau;
            if let Some((l2, h1)) = self.exact_errors(u, t)? {
                record.errors.push(ErrorSample { step: n, time: t, l2, h1_semi: h1 });
            }
        }
        Ok(())
    }

    /// Write step n (energies, fields when due, contact row) and the checkpoint when due; find
    /// out whether a signal asks the run to stop (every rank learns it here). Returns that.
    fn output_step(
        &mut self,
        n: usize,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
        record: &mut Record,
    ) -> Result<bool> {
        let t0 = Instant::now();
        let stress0 = self.stress_seconds();
        self.write_step(n, midpoint, record)?;
        // A signal on any rank stops all ranks after this step, with a checkpoint.
        let stop = phase::stop_requested(self.world);
        // Checkpoints: every 10 field outputs (they hold three fields), at the end, and
        // when a signal stops the run.
        let due = n % (10 * self.scene.output.every) == 0;
        if self.output.open().is_some() && (due || stop || n == self.n_steps()) {
            let e = midpoint.energy();
            let cp = Checkpoint {
                step: n,
                time: n as f64 * midpoint.tau(),
                energy_initial: record.e0,
                external_work: e.external_work,
                contact_work: e.contact_work,
                dirichlet_work: e.dirichlet_work,
                momentum_initial: record.p0,
                ksp_iterations: midpoint.ksp_iterations(),
                active: contact.map(|c| c.active().to_vec()).unwrap_or_default(),
            };
            let (u, v, du) = (
                self.to_natural(midpoint.u())?,
                self.to_natural(midpoint.v())?,
                self.to_natural(midpoint.du())?,
            );
            self.output.open_mut().expect("output").write_checkpoint(&cp, &u, &v, &du)?;
        }
        // The stress-type fields' computation is timed on its own (`Timings::stress`).
        record.output_seconds += t0.elapsed().as_secs_f64() - (self.stress_seconds() - stress0);
        Ok(stop)
    }

    /// Write what is due at step n: energies always, fields when due, the contact row.
    fn write_step(&mut self, n: usize, midpoint: &Midpoint, record: &Record) -> Result<()> {
        let Some(out) = self.output.open() else { return Ok(()) };
        let t = n as f64 * midpoint.tau();
        let due = out.due_fields(n);
        let fields = self.scene.output.fields.clone();
        // The stress-type fields due now, computed together in one pass over the cells.
        let wanted: Vec<(Quantity, Location)> =
            fields.iter().zip(&due).filter(|(_, &d)| d).filter_map(|(f, _)| f.derived()).collect();
        let mut derived =
            if wanted.is_empty() { Vec::new() } else { self.stress_blocks(midpoint.u(), &wanted)? }
                .into_iter();
        let mut blocks = Vec::with_capacity(due.len());
        for (&field, due) in fields.iter().zip(due) {
            blocks.push(match (due, field.derived()) {
                (false, _) => None,
                (true, Some(_)) => derived.next(),
                (true, None) => Some(self.field_block(field, midpoint, record)?),
            });
        }
        let out = self.output.open_mut().expect("output");
        out.write_energy(n, t, midpoint.energy())?;
        if blocks.iter().any(Option::is_some) {
            out.write_fields(n, t, &blocks)?;
        }
        if let Some(row) = record.history.last_row() {
            out.write_contact(row, record.history.last_normals())?;
        }
        Ok(())
    }

    /// This rank's block of a state field (natural order, components interlaced); the
    /// stress-type fields come from `stress_blocks`.
    fn field_block(
        &mut self,
        field: Field,
        midpoint: &Midpoint,
        record: &Record,
    ) -> Result<Vec<f64>> {
        match field {
            Field::Displacement => self.to_natural(midpoint.u()),
            Field::Velocity => self.to_natural(midpoint.v()),
            Field::ContactTraction => Ok(self.traction_block(record)),
            other => Err(Error::Internal(format!("{} is not a state field", other.name()))),
        }
    }

    /// This rank's block of `contact_traction`: `-p_q n_q` at the contact nodes of the last
    /// step (every rank holds the contact nodes' rows), zero at every other node.
    fn traction_block(&self, record: &Record) -> Vec<f64> {
        let dim = self.part.dim;
        let (lo, hi) = natural_range(self.mesh.n_nodes(), self.rank, self.size);
        let mut block = vec![0.0; (hi - lo) * dim];
        let Some(row) = record.history.last_row() else { return block };
        let (nodes, weights) = record.history.nodes();
        let normals = record.history.last_normals();
        let pressure = row.pressure(weights);
        for (q, &v) in nodes.iter().enumerate() {
            if (lo..hi).contains(&v) {
                for i in 0..dim {
                    block[(v - lo) * dim + i] = -pressure[q] * normals[q][i];
                }
            }
        }
        block
    }

    /// Continue from a checkpoint: u, v, the last increment (the solver's initial guess), the
    /// loads at the checkpoint's time, the running work totals and the active set.
    fn restore(
        &mut self,
        path: &Path,
        midpoint: &mut Midpoint,
        contact: Option<&mut (dyn ContactSolver + 'a)>,
        forces: &dyn Forces,
    ) -> Result<Checkpoint> {
        let range = natural_range(self.mesh.n_nodes(), self.rank, self.size);
        let (cp, [u, v, du]) =
            read_checkpoint(path, self.world, range, self.mesh.n_nodes(), self.part.dim)?;
        let works = Energy {
            external_work: cp.external_work,
            contact_work: cp.contact_work,
            dirichlet_work: cp.dirichlet_work,
            ..Default::default()
        };
        midpoint.restore(
            |uu, vv, dd| {
                self.from_natural(&u, uu)?;
                self.from_natural(&v, vv)?;
                self.from_natural(&du, dd)
            },
            works,
            cp.ksp_iterations,
        )?;
        midpoint.refresh(forces, cp.time)?;
        if let Some(c) = contact {
            if cp.active.len() != c.n_nodes() {
                return Err(Error::Io(format!(
                    "{}: the checkpoint's contact set has {} nodes, this scene's {}",
                    path.display(),
                    cp.active.len(),
                    c.n_nodes()
                )));
            }
            c.set_active(cp.active.clone());
        }
        self.console.say(format!(
            "restarting from step {} (t = {:e}) of {}",
            cp.step,
            cp.time,
            path.display()
        ));
        Ok(cp)
    }

    /// The run's summary; rank 0 draws the pictures beside the output file.
    fn summarize(
        &mut self,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
        mut record: Record,
    ) -> Result<RunSummary> {
        let mut scratch = midpoint.u().duplicate()?;
        let matmult_seconds =
            self.time_matmult(&midpoint.operator().k, midpoint.v(), &mut scratch)?;
        let peak_memory_mib = sum_over_ranks(self.world, peak_rss_mib());
        let p1 = self.momentum(midpoint.mv())?;
        let body_p1 = self.body_momenta(midpoint.mv())?;
        let e = midpoint.energy();
        let contact_summary = contact.map(|c| {
            let mut s = record.history.summary(
                c,
                &self.mesh,
                e.contact_work,
                max_over_ranks(self.world, record.contact_seconds),
            );
            s.ksp_iterations_contact_steps = record.contact_ksp_iterations;
            s
        });
        // Collective: every rank has the same contact solver.
        let mortar = contact.and_then(|c| c.mortar_cost()).map(|m| m.max_over_ranks(self.world));
        let contact_summary = contact_summary.map(|s| ContactSummary { mortar, ..s });
        let stability = self.stability(midpoint, contact, &record);
        // Pictures next to the HDF5 file, drawn by rank 0 from the histories in memory. A
        // picture that cannot be drawn (e.g. no font) is a warning, not a failed run; every
        // rank learns the outcome, since the summary written below must be the same on all.
        let mut pictures = Vec::new();
        if let Some(out) = self.output.open() {
            let prefix = out.path().with_extension("");
            let mut ok = 1i32;
            if self.rank == 0 {
                if let Some(c) = contact {
                    record.curves.lowest_pressure = record.history.pressure(c.lowest());
                }
                match write_pictures(&prefix, &[record.curves]) {
                    Ok(p) => pictures = p,
                    Err(e) => {
                        ok = 0;
                        eprintln!("massfree: warning: pictures not written: {e}");
                    }
                }
            }
            self.world.process_at_rank(0).broadcast_into(&mut ok);
            if ok == 1 && self.rank != 0 {
                pictures = picture_paths(&prefix, contact.is_some());
            } else if ok == 0 {
                pictures.clear();
            }
        }
        let impulses = self.contact_impulses(contact, &record.history);
        let ksp = &midpoint.operator().ksp;
        let (layer_contact_nodes, layer_cells) = self.layer_summary.unwrap_or((0, 0));
        let bodies = (0..self.bodies.n_bodies())
            .map(|i| {
                let reg = &self.bodies.regions[i + 1];
                BodySummary {
                    group: reg.group.clone().unwrap_or_default(),
                    e: reg.spec.e,
                    nu: reg.spec.nu,
                    rho: reg.spec.rho,
                    mass_kind: self.bodies.mass_of(i + 1).name().to_string(),
                    cells: reg.n_cells,
                    total_mass: self.mass_check.body_mass[i].clone(),
                    momentum_initial: record.body_p0[i].clone(),
                    momentum_final: body_p1[i].clone(),
                    layer_contact_nodes: self.body_layers[i].0,
                    layer_cells: self.body_layers[i].1,
                    contact_impulse: impulses[i].clone(),
                }
            })
            .collect();
        Ok(RunSummary {
            n_nodes: self.mesh.n_nodes(),
            n_dofs: self.part.n_global_dofs(),
            steps: self.n_steps(),
            timings: self.timings.clone(),
            ksp_iterations: midpoint.ksp_iterations(),
            energy_initial: record.e0,
            energy_final: e.total(),
            external_work: e.external_work,
            energy_balance: record.balance,
            energy_drift: record.drift,
            energy_max: record.e_max,
            errors: record.errors,
            output: self.output.open().map(|o| o.path().to_path_buf()),
            matmult_seconds,
            peak_memory_mib,
            ranks: self.size,
            ksp_type: ksp.ksp_type()?,
            pc_type: ksp.pc_type()?,
            mass_kind: self.scene.mass.kind.name().to_string(),
            layer_contact_nodes,
            layer_cells,
            mass: self.mass_check.clone(),
            momentum_initial: record.p0[..self.part.dim].to_vec(),
            momentum_final: p1[..self.part.dim].to_vec(),
            contact: contact_summary,
            pictures,
            effects: self.effects(),
            bodies,
            massless_initialization: self.massless_initialized,
            release_projections: midpoint.release_projections().0,
            release_energy: midpoint.release_projections().1,
            energy_corrections: midpoint.corrections(),
            ksp_iterations_step_max: record.ksp_step_max,
            cfl: self.cfl,
            stability: Some(stability),
        })
    }

    /// The stability metrics of the run from its in-memory series (the same function that
    /// `massfree suite` applies to the HDF5 file).
    fn stability(
        &self,
        midpoint: &Midpoint,
        contact: Option<&dyn ContactSolver>,
        record: &Record,
    ) -> Stability {
        let col = |i: usize| record.energies.iter().map(|r| r[i]).collect::<Vec<f64>>();
        let (total, ext, dir, con) = (col(0), col(1), col(2), col(3));
        let energy = EnergySeries {
            total: &total,
            external_work: &ext,
            dirichlet_work: &dir,
            contact_work: &con,
        };
        let size = stability::body_size(&self.mesh.coords);
        let ksp = (midpoint.ksp_iterations(), record.ksp_step_max, total.len().saturating_sub(1));
        match contact {
            Some(c) => {
                let rows = record.history.rows();
                let force: Vec<f64> = rows.iter().flat_map(|r| r.force.iter().copied()).collect();
                let gap: Vec<f64> = rows.iter().flat_map(|r| r.gap.iter().copied()).collect();
                let active: Vec<bool> =
                    rows.iter().flat_map(|r| r.active.iter().copied()).collect();
                let iterations: Vec<f64> = rows.iter().map(|r| r.iterations as f64).collect();
                let series = ContactSeries {
                    nodes: c.n_nodes(),
                    force: &force,
                    gap: &gap,
                    active: &active,
                    weights: record.history.nodes().1,
                    iterations: &iterations,
                    lowest: c.lowest(),
                };
                stability::measure(&energy, Some(&series), size, ksp)
            }
            None => stability::measure(&energy, None, size, ksp),
        }
    }

    /// The file's final metadata. A signal that arrived in the final phase is reported as
    /// such, with everything already written.
    fn finish(&mut self, summary: &RunSummary) -> Result<()> {
        let n_steps = self.n_steps();
        let interrupted = phase::stop_requested(self.world);
        let status = if interrupted {
            format!(
                "interrupted: a signal arrived after the last step ({n_steps} of {n_steps}); all steps and the summary are written"
            )
        } else {
            "finished".to_string()
        };
        if let RunOutput::Open(out) = std::mem::replace(&mut self.output, RunOutput::None) {
            let text = toml::to_string(summary).unwrap_or_default();
            let t = &self.timings;
            let timing = format!(
                "mesh = {:e}\npartition = {:e}\nassembly = {:e}\nsetup = {:e}\nstepping = {:e}\noutput = {:e}\nstress = {:e}\n",
                t.mesh, t.partition, t.assembly, t.setup, t.stepping, t.output, t.stress
            );
            out.finish(
                self.world,
                &[
                    Meta::text("status", status.clone()),
                    Meta::text("summary", text),
                    Meta::text("timings", timing),
                ],
            )?;
        }
        phase::enter(Phase::Finished);
        if interrupted {
            return Err(Error::Interrupted(status["interrupted: ".len()..].to_string()));
        }
        Ok(())
    }

    /// Mass-matrix diagnostics, computed once: total mass, first and second moments per
    /// component (`1^T M 1`, `x^T M 1`, `x^T M x` with x the nodal coordinates in one
    /// component), and the largest entry of `M 1` on contact DOFs (zero for M_H).
    fn check_mass(&mut self, m: &Matrix, layer: Option<&MassFreeLayer>) -> Result<MassCheck> {
        let dim = self.part.dim;
        let mut check = MassCheck::default();
        let mut one = assembly::new_vector(&self.part)?;
        let mut x = one.duplicate()?;
        let mut y = one.duplicate()?;
        for c in 0..dim {
            let owned = &self.part.owned_nodes;
            one.zero()?;
            one.with_local_slice_mut(|s| {
                for i in 0..owned.len() {
                    s[i * dim + c] = 1.0;
                }
            })?;
            x.zero()?;
            x.with_local_slice_mut(|s| {
                for (i, &v) in owned.iter().enumerate() {
                    s[i * dim + c] = self.mesh.coords[v][c];
                }
            })?;
            m.mult(&one, &mut y)?;
            check.total_mass.push(one.dot(&y)?);
            let per_body = self.body_sums(&y, c)?;
            check.body_mass.resize(per_body.len(), Vec::new());
            for (b, m) in per_body.into_iter().enumerate() {
                check.body_mass[b].push(m);
            }
            check.first_moment.push(x.dot(&y)?);
            let contact_max = match layer.map(|l| &l.contact_nodes) {
                Some(nodes) => {
                    let lo = self.part.first_dof();
                    let mut mx: f64 = 0.0;
                    y.with_local_slice(|s| {
                        for &v in nodes {
                            if self.part.owns(v) {
                                mx = mx.max(s[self.part.dof(v, c) - lo].abs());
                            }
                        }
                    })?;
                    max_over_ranks(self.world, mx)
                }
                None => 0.0,
            };
            check.contact_row_max = check.contact_row_max.max(contact_max);
            m.mult(&x, &mut y)?;
            check.second_moment.push(x.dot(&y)?);
        }
        // The probe: M applied to r_i = sin(i + 1), i the natural (gmsh-order) DOF index.
        let owned = self.part.owned_nodes.clone();
        x.with_local_slice_mut(|s| {
            for (i, &v) in owned.iter().enumerate() {
                for c in 0..dim {
                    s[i * dim + c] = ((v * dim + c + 1) as f64).sin();
                }
            }
        })?;
        m.mult(&x, &mut y)?;
        check.probe = self.to_natural(&y)?;
        Ok(check)
    }

    /// The shortest cell edge (any two nodes of a cell: for simplices the edges, for quads and
    /// hexes their diagonals too, which are longer) of each region (`Bodies`), over the cells
    /// of all ranks (`f64::MAX` for a region without cells).
    fn min_edges(&self) -> Vec<f64> {
        let mut h = vec![f64::MAX; self.bodies.regions.len()];
        for &c in &self.part.local_cells {
            let r = self.bodies.region_of(c);
            let nodes = self.mesh.cells[c].nodes();
            for (i, &a) in nodes.iter().enumerate() {
                for &b in &nodes[i + 1..] {
                    let (x, y) = (self.mesh.coords[a], self.mesh.coords[b]);
                    let d2: f64 = (0..3).map(|k| (x[k] - y[k]).powi(2)).sum();
                    h[r] = h[r].min(d2.sqrt());
                }
            }
        }
        let mut global = vec![0.0; h.len()];
        self.world.all_reduce_into(&h[..], &mut global[..], SystemOperation::min());
        global
    }

    /// Per body, the sum of component `c` of `x` over the body's nodes (all ranks).
    fn body_sums(&self, x: &Vector, c: usize) -> Result<Vec<f64>> {
        let n = self.bodies.n_bodies();
        if n == 0 {
            return Ok(Vec::new());
        }
        let lo = self.part.first_dof();
        let mut sums = vec![0.0; n];
        x.with_local_slice(|s| {
            for (b, sum) in sums.iter_mut().enumerate() {
                for &v in self.bodies.body_nodes(b) {
                    if self.part.owns(v) {
                        *sum += s[self.part.dof(v, c) - lo];
                    }
                }
            }
        })?;
        let mut out = vec![0.0; n];
        self.world.all_reduce_into(&sums[..], &mut out[..], SystemOperation::sum());
        Ok(out)
    }

    /// The body of each owned node, in DOF order: the index of the first `[[body]]` holding
    /// it, or the number of bodies for the nodes of no body.
    fn node_bodies(&self) -> Vec<u32> {
        let n = self.bodies.n_bodies();
        let lo = self.part.first_dof();
        let dim = self.part.dim;
        let mut out = vec![n as u32; self.part.owned_nodes.len()];
        for b in (0..n).rev() {
            for &v in self.bodies.body_nodes(b) {
                if self.part.owns(v) {
                    out[(self.part.dof(v, 0) - lo) / dim] = b as u32;
                }
            }
        }
        out
    }

    /// The momentum `1_B^T M v` of each body, per component, from `M v`.
    fn body_momenta(&self, mv: &Vector) -> Result<Vec<Vec<f64>>> {
        let mut p = vec![Vec::new(); self.bodies.n_bodies()];
        for c in 0..self.part.dim {
            for (b, x) in self.body_sums(mv, c)?.into_iter().enumerate() {
                p[b].push(x);
            }
        }
        Ok(p)
    }

    /// The contact nodes and the cells of the layer on `body[i]`.
    fn body_layer(&self, layer: &MassFreeLayer, i: usize) -> (usize, usize) {
        let nodes = self.bodies.body_nodes(i);
        let contact = layer.contact_nodes.iter().filter(|v| nodes.binary_search(v).is_ok()).count();
        let cells =
            layer.layer_cells.iter().filter(|&&c| self.bodies.region_of(c) == i + 1).count();
        (contact, cells)
    }

    /// The effects line, with the mass treatment as the mesh resolved it.
    pub fn effects(&self) -> String {
        let layer = self.bodies.layer.as_ref().map(|(k, g)| (*k, g.as_slice()));
        self.scene.effects().resolve(self.bodies.standard_masses(), layer).summary()
    }

    /// Rigid-body modes from the owned nodes' coordinates (for algebraic multigrid).
    fn near_null_space(&self) -> Result<NullSpace> {
        let mut coords = assembly::new_vector(&self.part)?;
        let dim = self.part.dim;
        coords.with_local_slice_mut(|x| {
            for (i, &v) in self.part.owned_nodes.iter().enumerate() {
                for c in 0..dim {
                    x[i * dim + c] = self.mesh.coords[v][c];
                }
            }
        })?;
        NullSpace::rigid_body_modes(&coords)
    }

    /// Scatter from the solver's layout to this rank's block of natural (gmsh) node order.
    fn natural_scatter(&self, x: &Vector) -> Result<(Scatter, Vector)> {
        let dim = self.part.dim;
        let (lo, hi) = natural_range(self.mesh.n_nodes(), self.rank, self.size);
        let y = Vector::new_mpi((hi - lo) * dim, self.part.n_global_dofs(), dim)?;
        let mut from = Vec::with_capacity((hi - lo) * dim);
        let mut to = Vec::with_capacity((hi - lo) * dim);
        for node in lo..hi {
            for c in 0..dim {
                from.push(self.part.dof(node, c) as i32);
                to.push((node * dim + c) as i32);
            }
        }
        let sc = Scatter::new(x, &from, &y, &to)?;
        Ok((sc, y))
    }

    /// This rank's natural block of `x` (interlaced components).
    pub fn to_natural(&mut self, x: &Vector) -> Result<Vec<f64>> {
        if self.natural.is_none() {
            self.natural = Some(self.natural_scatter(x)?);
        }
        let (sc, y) = self.natural.as_mut().expect("natural scatter");
        sc.forward(x, y)?;
        let mut out = Vec::new();
        y.with_local_slice(|s| out.extend_from_slice(s))?;
        Ok(out)
    }

    /// Fill `x` (solver layout) from this rank's natural block (the inverse of `to_natural`).
    pub fn from_natural(&mut self, block: &[f64], x: &mut Vector) -> Result<()> {
        if self.natural.is_none() {
            self.natural = Some(self.natural_scatter(x)?);
        }
        let (sc, y) = self.natural.as_mut().expect("natural scatter");
        y.with_local_slice_mut(|s| s.copy_from_slice(block))?;
        sc.reverse(y, x)
    }

    /// Values of `x` at the nodes of this rank's cells (ghosts included), for element loops.
    /// The values come back; the slot of each node in them stays in `self.local_view`.
    fn local_values(&mut self, x: &Vector) -> Result<Vec<f64>> {
        if self.local_view.is_none() {
            let dim = self.part.dim;
            let mut nodes: Vec<usize> = self
                .part
                .local_cells
                .iter()
                .flat_map(|&c| self.mesh.cells[c].nodes().iter().copied())
                .collect();
            nodes.sort_unstable();
            nodes.dedup();
            let mut slot = vec![usize::MAX; self.mesh.n_nodes()];
            let mut from = Vec::with_capacity(nodes.len() * dim);
            for (i, &v) in nodes.iter().enumerate() {
                slot[v] = i;
                for c in 0..dim {
                    from.push(self.part.dof(v, c) as i32);
                }
            }
            // A distributed vector holding, on each rank, the values its cells touch.
            let k = from.len();
            let mut offset = 0usize;
            self.world.scan_into(&k, &mut offset, SystemOperation::sum());
            let total = sum_over_ranks(self.world, k as f64) as usize;
            let values = Vector::new_mpi(k, total, 1)?;
            let first = offset - k;
            let to: Vec<i32> = (first..first + k).map(|i| i as i32).collect();
            let scatter = Scatter::new(x, &from, &values, &to)?;
            self.local_view = Some(LocalView { scatter, values, nodes, slot });
        }
        let view = self.local_view.as_mut().expect("local view");
        view.scatter.forward(x, &mut view.values)?;
        let mut vals = Vec::new();
        view.values.with_local_slice(|s| vals.extend_from_slice(s))?;
        Ok(vals)
    }

    /// This rank's natural blocks of the stress-type fields `wanted` (in that order), from the
    /// displacement `u`; the stress output is built at the first call. Timed as `stress`.
    fn stress_blocks(
        &mut self,
        u: &Vector,
        wanted: &[(Quantity, Location)],
    ) -> Result<Vec<Vec<f64>>> {
        let t0 = Instant::now();
        let vals = self.local_values(u)?;
        let view = self.local_view.as_ref().expect("local view");
        let fetch = t0.elapsed().as_secs_f64();
        if self.stress.is_none() {
            let (mesh, part) = (Rc::clone(&self.mesh), Rc::clone(&self.part));
            self.stress = Some(StressOutput::new(self.world, mesh, part, &view.nodes, &view.slot)?);
        }
        let stress = self.stress.as_mut().expect("stress output");
        stress.seconds += fetch;
        stress.compute(self.world, &self.bodies, &vals, &view.slot, wanted)
    }

    /// Wall time of the stress work so far on this rank (zero before the first stress field).
    fn stress_seconds(&self) -> f64 {
        self.stress.as_ref().map_or(0.0, |s| s.seconds)
    }

    /// L2 and H1-seminorm errors of `u` against the scene's exact displacement at time t.
    pub fn exact_errors(&mut self, u: &Vector, t: f64) -> Result<Option<(f64, f64)>> {
        let Some(exact) = self.scene.exact.clone() else { return Ok(None) };
        let vals = self.local_values(u)?;
        let slot = &self.local_view.as_ref().expect("local view").slot;
        let dim = self.part.dim;
        let disp = &exact.displacement;
        let grad = exact.gradient.as_ref();
        let f = |x: [f64; 3]| -> ([f64; 3], [[f64; 3]; 3]) {
            let val = disp.eval(x, t);
            let mut g = [[0.0; 3]; 3];
            match grad {
                Some(rows) => {
                    for i in 0..dim {
                        let r = rows[i].eval(x, t);
                        g[i][..dim].copy_from_slice(&r[..dim]);
                    }
                }
                None => {
                    // Central differences: O(h^2) = 1e-12 relative, far below discretization error.
                    for j in 0..dim {
                        let hstep = 1e-6 * (1.0 + x[j].abs());
                        let (mut xp, mut xm) = (x, x);
                        xp[j] += hstep;
                        xm[j] -= hstep;
                        let (fp, fm) = (disp.eval(xp, t), disp.eval(xm, t));
                        for i in 0..dim {
                            g[i][j] = (fp[i] - fm[i]) / (2.0 * hstep);
                        }
                    }
                }
            }
            (val, g)
        };
        let (mut l2, mut h1) = (0.0, 0.0);
        let mut xy = [[0.0; 3]; 8];
        let mut ue = [0.0; assembly::MAX_EDOFS];
        for &c in &self.part.local_cells {
            let cell = &self.mesh.cells[c];
            let n = assembly::cell_coords(&self.mesh, cell, &mut xy);
            for (i, &v) in cell.nodes().iter().enumerate() {
                for k in 0..dim {
                    ue[i * dim + k] = vals[slot[v] * dim + k];
                }
            }
            let (a, b) = kernels::error_sq(cell.kind, &xy[..n], &ue[..n * dim], &f, 6);
            l2 += a;
            h1 += b;
        }
        let l2 = sum_over_ranks(self.world, l2).sqrt();
        let h1 = sum_over_ranks(self.world, h1).sqrt();
        Ok(Some((l2, h1)))
    }

    fn settings(&self, op: &StepOperator, layer: &Option<MassFreeLayer>) -> Vec<(String, String)> {
        let bodies = self.scene.effects().bodies;
        let mut settings = vec![
            ("ranks".into(), self.size.to_string()),
            ("dim".into(), self.mesh.dim.to_string()),
            ("nodes".into(), self.mesh.n_nodes().to_string()),
            ("dofs".into(), self.part.n_global_dofs().to_string()),
            ("mass".into(), self.scene.mass.kind.name().to_string()),
            (
                "contact_boundary".into(),
                self.scene.mass.contact_boundary.clone().unwrap_or_else(|| "none".into()),
            ),
            (
                "mass_free_layer".into(),
                match layer {
                    Some(l) => format!(
                        "{} contact nodes, {} layer cells",
                        l.n_contact_nodes(),
                        l.n_layer_cells()
                    ),
                    None => "none".into(),
                },
            ),
            ("tau".into(), format!("{:e}", self.scene.tau)),
            ("steps".into(), self.n_steps().to_string()),
            ("ksp_type".into(), op.ksp.ksp_type().unwrap_or_default()),
            (
                "petsc_options".into(),
                self.scene
                    .solver
                    .options
                    .iter()
                    .chain(self.opts.petsc_args.iter())
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(" "),
            ),
            ("pc_type".into(), op.ksp.pc_type().unwrap_or_default()),
            ("partition".into(), format!("{:?}", self.opts.partition)),
            ("metis_seed".into(), crate::partition::METIS_SEED.to_string()),
        ];
        if !bodies.is_empty() {
            settings.insert(5, ("bodies".into(), bodies.join("; ")));
        }
        settings
    }

    /// The impulse the contact gave each `[[body]]`: the sum over its contact nodes (slave
    /// nodes and nodes meeting obstacles) and its master nodes of what they received. A node
    /// on two bodies counts for the first.
    fn contact_impulses(
        &self,
        contact: Option<&dyn ContactSolver>,
        history: &ContactHistory,
    ) -> Vec<Vec<f64>> {
        let dim = self.part.dim;
        let n = self.bodies.n_bodies();
        let Some(c) = contact else { return vec![vec![0.0; dim]; n] };
        let first_body =
            |v: usize| (0..n).find(|&b| self.bodies.body_nodes(b).binary_search(&v).is_ok());
        (0..n)
            .map(|b| {
                let imp = history.impulse_on(&c.boundary().nodes, c.master_nodes(), |v| {
                    first_body(v) == Some(b)
                });
                imp[..dim].to_vec()
            })
            .collect()
    }

    /// Total momentum `1^T M v` per component (from the product `M v` the step keeps).
    fn momentum(&self, mv: &Vector) -> Result<[f64; 3]> {
        let dim = self.part.dim;
        let mut p = [0.0; 3];
        mv.with_local_slice(|s| {
            for (i, x) in s.iter().enumerate() {
                p[i % dim] += x;
            }
        })?;
        let mut out = [0.0; 3];
        self.world.all_reduce_into(&p[..], &mut out[..], SystemOperation::sum());
        Ok(out)
    }

    /// Write the run's settings and the groups' metadata, then open the file in parallel for
    /// the time series.
    fn open_output(
        &mut self,
        op: &StepOperator,
        contact: Option<&dyn ContactSolver>,
        layer: &Option<MassFreeLayer>,
        mass_check: &MassCheck,
    ) -> Result<()> {
        let RunOutput::Closed(file) = std::mem::replace(&mut self.output, RunOutput::None) else {
            return Ok(());
        };
        phase::enter(Phase::OpeningOutput);
        let t0 = Instant::now();
        let dim = self.mesh.dim;
        let plan = OutputPlan {
            fields: (self.scene.output.fields.iter())
                .map(|&f| PlannedField { spec: f.spec(dim), every: self.scene.every_of(f) })
                .collect(),
            time_steps: self.scene.output.time_steps.clone(),
            compression: self.scene.output.compression,
        };
        let settings = self.settings(op, layer);
        let settings_text: String = settings.iter().map(|(k, v)| format!("{k} = {v}\n")).collect();
        let solver_options =
            settings.iter().find(|(k, _)| k == "petsc_options").map_or("", |(_, v)| v.as_str());
        let mut meta = vec![
            // The effects as the mesh resolved them (the file was created with the scene's).
            Meta::text("effects", self.effects()),
            Meta::text("settings", settings_text),
            Meta::text("solver_options", solver_options),
        ];
        for g in &self.mesh.groups {
            let object = format!("mesh/groups/{}", group_key(&g.name));
            meta.push(Meta::int_on(&object, "dim", g.dim as i64));
        }
        use crate::io::layout;
        // A slave/master pair: its groups as attributes of /contact (written by rank 0's serial
        // handle, `io::meta`), its master nodes below (created collectively). Every rank holds
        // the whole mesh and the scene, so names and nodes are the same on every rank.
        // Several pairs: the groups joined by ", " in pair order.
        let spec = self.scene.contact.as_ref().filter(|s| !s.pairs.is_empty());
        if let Some(c) = contact {
            let group = c.boundary().group.clone();
            meta.push(Meta::text_on(layout::CONTACT, layout::CONTACT_GROUP_ATTR, group));
            if let Some(spec) = spec {
                let (slaves, masters) =
                    (spec.slave_groups().join(", "), spec.master_groups().join(", "));
                meta.push(Meta::text_on(layout::CONTACT, layout::CONTACT_SLAVE_GROUP_ATTR, slaves));
                meta.push(Meta::text_on(
                    layout::CONTACT,
                    layout::CONTACT_MASTER_GROUP_ATTR,
                    masters,
                ));
                if let Some(g) = spec.obstacle_boundary() {
                    meta.push(Meta::text_on(
                        layout::CONTACT,
                        layout::CONTACT_OBSTACLE_GROUP_ATTR,
                        g,
                    ));
                }
            }
        }
        file.write_meta(self.world, &meta)?;
        let mut out = Output::open(file, self.world, &self.mesh, &self.part.cell_rank, plan)?;
        let mc = mass_check;
        out.write_mass_check(&mc.total_mass, &mc.first_moment, &mc.second_moment, &mc.probe)?;
        if let Some(c) = contact {
            out.create_contact(&c.boundary().nodes, &c.boundary().weights, self.mesh.dim)?;
            if let Some(spec) = spec {
                let mut nodes = Vec::new();
                for g in spec.master_groups() {
                    nodes.extend(self.mesh.group_nodes(g)?);
                }
                nodes.sort_unstable();
                nodes.dedup();
                out.create_contact_pair(self.world, &nodes)?;
            }
        }
        self.output = RunOutput::Open(out);
        self.timings.output += t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// Mean wall time of one `y = K x` (max over ranks), timed after the run: the unit in which
    /// the benchmark expresses the cost of a step.
    fn time_matmult(&self, k: &Matrix, x: &Vector, y: &mut Vector) -> Result<f64> {
        let reps = 20;
        k.mult(x, y)?;
        self.world.barrier();
        let t0 = Instant::now();
        for _ in 0..reps {
            k.mult(x, y)?;
        }
        let dt = t0.elapsed().as_secs_f64() / reps as f64;
        Ok(max_over_ranks(self.world, dt))
    }
}

/// Run `f`, turning a panic into an error (its message was kept by the panic hook), so that a
/// panic ends the run like any other error: the file says `failed: ...`.
pub fn guard<T>(f: impl FnOnce() -> Result<T>) -> Result<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(payload) => Err(Error::Internal(crate::error::panic_message(payload.as_ref()))),
    }
}

/// Mark the output file after an error: `interrupted: ...` for a signal, `failed: ...`
/// otherwise. Closing a parallel file is collective, so this first makes sure that every rank
/// has the error; if only this rank has it, it prints the error and aborts the job (the file
/// then keeps `running`, which `massfree post` reports as a run that did not finish).
fn end_with_error(
    world: &SimpleCommunicator,
    agree: &SimpleCommunicator,
    output: RunOutput,
    e: &Error,
) {
    if !phase::all_reached(agree, std::time::Duration::from_secs(10)) {
        eprintln!("massfree: rank {}: {e}", world.rank());
        world.abort(1);
    }
    let status = match e {
        Error::Interrupted(m) => format!("interrupted: {m}"),
        other => format!("failed: {other}"),
    };
    let status = [Meta::text("status", status)];
    let marked = match output {
        RunOutput::None => Ok(()),
        RunOutput::Closed(f) => f.write_meta(world, &status),
        RunOutput::Open(out) => out.finish(world, &status),
    };
    if let (Err(m), 0) = (marked, world.rank()) {
        eprintln!("massfree: warning: the output file could not be marked: {m}");
    }
}

/// The scene's extra PETSc options (`solver.options`), entered only where the command line
/// did not set the same option: the command line wins.
fn apply_scene_options(tokens: &[String]) -> Result<()> {
    let mut i = 0;
    while i < tokens.len() {
        let name = &tokens[i];
        if !name.starts_with('-') || name.parse::<f64>().is_ok() {
            return Err(Error::Scene(format!(
                "solver.options: expected an option name starting with '-', found \"{name}\""
            )));
        }
        let value = tokens
            .get(i + 1)
            .filter(|v| !v.starts_with('-') || v.parse::<f64>().is_ok())
            .map(|v| v.as_str());
        i += if value.is_some() { 2 } else { 1 };
        if !crate::petsc::Petsc::options_has(name)? {
            crate::petsc::Petsc::options_set(name, value)?;
        }
    }
    Ok(())
}

/// Peak resident set size of this process (VmHWM), in MiB; 0 where /proc is unavailable.
pub fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1).and_then(|k| k.parse::<f64>().ok()))
        })
        .map(|kib| kib / 1024.0)
        .unwrap_or(0.0)
}

/// Human summary lines of a run (printed by rank 0 through the console).
pub fn summary_lines(sim: &Simulation, s: &RunSummary) -> Vec<String> {
    let t = &s.timings;
    let mut lines = vec![
        format!(
            "{}: {}D, {} nodes, {} DOFs, {} cells on {} rank(s); mass {}{}",
            sim.scene.name,
            sim.mesh.dim,
            s.n_nodes,
            s.n_dofs,
            sim.mesh.cells.len(),
            sim.size,
            mass_kinds(&sim.bodies),
            match (sim.layer_summary, &sim.bodies.layer) {
                (Some((nodes, cells)), Some((_, groups))) => format!(
                    " (mass-free layer along {}: {nodes} contact nodes, {cells} layer cells)",
                    crate::scene::effects::quoted(groups),
                ),
                _ => String::new(),
            }
        ),
        format!(
            "{} steps of tau = {:e} to t = {:e}: {:.3} s stepping ({:.3} ms/step), {:.2} KSP iterations/step",
            s.steps,
            sim.scene.tau,
            s.steps as f64 * sim.scene.tau,
            t.stepping,
            1e3 * t.stepping / s.steps.max(1) as f64,
            s.ksp_iterations as f64 / s.steps.max(1) as f64
        ),
        format!(
            "time: mesh {:.3} s, partition {:.3} s, assembly {:.3} s, solver setup {:.3} s, output {:.3} s, stress {:.3} s",
            t.mesh, t.partition, t.assembly, t.setup, t.output, t.stress
        ),
        format!(
            "energy: initial {:.10e}, final {:.10e}, external work {:.6e}; balance |E^n - E^0 - W^n|/max E = {:.2e} (W: loads, contact, boundary reactions)",
            s.energy_initial, s.energy_final, s.external_work, s.energy_balance
        ),
    ];
    if let Some(d) = s.massless_initialization.filter(|&d| d > 0.0) {
        lines.push(format!(
            "massless DOFs: the initial displacement made statically consistent there (largest change {d:.3e})"
        ));
    }
    if s.energy_corrections.enabled {
        let c = &s.energy_corrections;
        lines.push(format!(
            "massless DOFs: contact work put back on {} steps ({} extra solves, {} steps handed it on, {} unsettled): {:.3e}, pending at the end {:.3e}",
            c.steps, c.extra_solves, c.skipped, c.unconverged, c.energy, c.pending
        ));
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
            }
        ));
    }
    for e in &s.errors {
        lines.push(format!(
            "error at step {} (t = {:.6e}): L2 {:.6e}, H1-seminorm {:.6e}",
            e.step, e.time, e.l2, e.h1_semi
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
        lines.push(format!(
            "chatter: lowest node osc2 {:.2e}, total-force TV index {:.3}, episodes per node max {} (mean {:.2})",
            c.lowest_osc2, c.total_force_tv_index, c.episodes_max, c.episodes_mean
        ));
        if let Some(m) = &c.mortar {
            lines.push(format!(
                "mortar: {} interface evaluations {:.3} s (search {:.3} s), T^T K T rebuilds {:.3} s, per-step basis changes {:.3} s; {:.1}% of the stepping",
                m.evaluations,
                m.evaluation_seconds,
                m.search_seconds,
                m.operator_seconds,
                m.step_seconds,
                100.0 * (m.evaluation_seconds + m.operator_seconds + m.step_seconds)
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
