//! The `massfree` command. A run reads top to bottom: init MPI and PETSc, read the scene,
//! mesh, partition, assemble, set up solvers, initial energy, time loop, output, summary.

use std::path::PathBuf;

use clap::{Parser, Subcommand};
use mpi::traits::*;

use massfree::console::Console;
use massfree::error::{Error, Result};
use massfree::petsc::Petsc;
use massfree::phase::{self, HangTimeout};
use massfree::post::snapshot::{self, SnapshotArgs};
use massfree::run::{RunOptions, Simulation};

/// Examples of the top-level help.
const EXAMPLES: &str = "\
Examples:
  mpirun -n 2 massfree run scenes/disc.toml --overwrite
      a scene on 2 ranks, written to its output file (out/disc.h5)
  massfree post out/disc.h5
      the run's summary, energy plots and CSV files (out/disc-post-*)
  massfree compare out/disc.h5 out/disc-lumped.h5 --prefix out/disc-masses
      two runs overlaid (out/disc-masses-energy.png, out/disc-masses-pressure.png)
  massfree suite --reduced
      the reduced stability suite (out/suite-reduced/suite.md, .csv, .png)

Every subcommand has its own help (massfree run --help, ...); the solver options of a run,
PETSc's and the program's own, with their defaults: massfree run SCENE --steps 1 --no-output -- -help";

const RUN_EXAMPLES: &str = "\
Examples:
  mpirun -n 2 massfree run scenes/disc.toml --overwrite
      the disc impact on 2 ranks, written to the scene's output file (out/disc.h5)
  mpirun -n 2 massfree run scenes/beam.toml --steps 50 --mass lumped -o out/beam-lumped.h5
      50 steps with the lumped mass matrix, written to another file
  massfree run scenes/two_discs.toml --no-output -q -- -mortar_interface frozen -step_ksp_rtol 1e-12
      one rank, no file, only the summary; options after --: the program's own and PETSc's
  massfree run scenes/disc.toml --steps 1 --no-output -- -help
      every option after -- (PETSc's and the program's) with its default and description";

const POST_EXAMPLES: &str = "\
Examples:
  massfree post out/disc.h5
      summary, energy and contact pictures and CSV files: out/disc-post-energy.png, ...
  massfree post out/disc.h5 --node 0,8 --contact-node 0,0 --prefix out/disc-top
      also the histories of the node nearest (0, 8) and of the contact node nearest (0, 0):
      out/disc-top-node-N.png, out/disc-top-contact-N.csv, ... (N: the node's number)
  massfree post out/disc.h5 --snapshot velocity --time 6e-5 --edges
      the velocity on the deformed mesh at t = 6e-5: out/disc-post-snapshot-velocity.png";

const COMPARE_EXAMPLES: &str = "\
Examples:
  massfree compare out/disc.h5 out/disc-lumped.h5 --prefix out/disc-masses
      energies and pressures of both runs: out/disc-masses-energy.png, -pressure.png
  massfree compare out/disc.h5 out/disc-lumped.h5 --label M_H --label lumped
      the same with these curve labels, in out/compare-energy.png, out/compare-pressure.png
  massfree compare out/disc.h5 out/disc-lumped.h5 --snapshot displacement --component y
      the runs' vertical displacement side by side: out/compare-snapshot-displacement.png";

const STUDY_EXAMPLES: &str = "\
Examples:
  massfree study studies/beam_time.toml
      time convergence on the beam for each mass treatment: out/study-beam-time/
  massfree study studies/disc_contact.toml
      the disc impact over a refinement of the contact zone: out/study-disc-contact/";

const SUITE_EXAMPLES: &str = "\
Examples:
  massfree suite --reduced
      the reduced suite of studies/suite.toml: out/suite-reduced/suite.md, .csv, .png
  massfree suite studies/suite.toml --ranks 3 --dir out/suite-3
      the whole suite with its runs on 3 ranks (and the rank sweep's), in out/suite-3
  massfree suite --reduced --scenes-only --dir out/suite-scenes
      only the scene of every run (out/suite-scenes/runs/*.scene.toml), to run them by hand";

#[derive(Parser, Debug)]
#[command(
    name = "massfree",
    version,
    about = "Dynamic elasticity with contact and mass-free surface layers, on PETSc and MPI",
    after_help = EXAMPLES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// A point `x,y[,z]`.
fn parse_point(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|c| c.trim().parse::<f64>().map_err(|_| format!("not a number: {c}")))
        .collect::<std::result::Result<_, _>>()?;
    if !(2..=3).contains(&v.len()) {
        return Err("expected x,y or x,y,z".into());
    }
    Ok([v[0], v[1], *v.get(2).unwrap_or(&0.0)])
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Summarize a run's HDF5 file; write PNG plots and CSV of its energies and of chosen
    /// node and contact-node histories; or, with --snapshot, draw a field on the deformed mesh.
    #[command(after_help = POST_EXAMPLES)]
    Post {
        /// The run's .h5 file.
        run: PathBuf,
        /// Node history at the mesh node nearest to x,y[,z] (repeatable).
        #[arg(long = "node", value_parser = parse_point, allow_hyphen_values = true)]
        nodes: Vec<[f64; 3]>,
        /// Contact history at the contact node nearest to x,y[,z] (repeatable).
        #[arg(long = "contact-node", value_parser = parse_point, allow_hyphen_values = true)]
        contact_nodes: Vec<[f64; 3]>,
        /// Fields of the node histories: displacement, velocity (default: all written).
        #[arg(long = "field")]
        fields: Vec<String>,
        /// Prefix of the written files, PREFIX-*.png and PREFIX-*.csv (default: the run's file
        /// without .h5, followed by -post).
        #[arg(long, value_name = "PREFIX")]
        prefix: Option<PathBuf>,
        #[command(flatten)]
        snapshot: SnapshotArgs,
    },
    /// Sweep a grid of settings over a scene (each point a real run on 2 ranks) and map error
    /// against wall time: CSV, Markdown table and PNG plots in the study's output folder.
    #[command(after_help = STUDY_EXAMPLES)]
    Study {
        /// The study file (TOML).
        study: PathBuf,
    },
    /// Run the hard-case stability suite (each case a real run on 2 ranks; selected cases also
    /// on other rank counts) and write DIR/suite.md, suite.csv and suite.png.
    #[command(after_help = SUITE_EXAMPLES)]
    Suite {
        /// The suite file (default: studies/suite.toml, here or in the repository).
        spec: Option<PathBuf>,
        /// The reduced suite (coarser meshes, fewer steps): the suite file's [reduced] variant.
        #[arg(long)]
        reduced: bool,
        /// Ranks of every run (default: the suite file's, 2).
        #[arg(long)]
        ranks: Option<usize>,
        /// Output folder (default: the suite file's output, out/suite or out/suite-reduced).
        #[arg(long, value_name = "DIR")]
        dir: Option<PathBuf>,
        /// Only write every run's scene (DIR/runs/*.scene.toml), to run them by hand.
        #[arg(long)]
        scenes_only: bool,
    },
    /// Overlay the energies and the lowest contact node's pressure of several runs (HDF5
    /// files) in PNG pictures PREFIX-energy.png and PREFIX-pressure.png; with --snapshot, draw
    /// a field of the runs side by side (one colour range) in PREFIX-snapshot-FIELD.png.
    #[command(after_help = COMPARE_EXAMPLES)]
    Compare {
        /// The runs' .h5 files.
        #[arg(required = true)]
        runs: Vec<PathBuf>,
        /// Prefix of the pictures, PREFIX-*.png.
        #[arg(long, value_name = "PREFIX", default_value = "out/compare")]
        prefix: PathBuf,
        /// Curve labels, one per run (default: the mass kind and mesh; for --snapshot panels
        /// the file name).
        #[arg(long = "label")]
        labels: Vec<String>,
        #[command(flatten)]
        snapshot: SnapshotArgs,
    },
    /// Check the distributed mesh front end against the replicated path on this rank count
    /// (every field of each rank's part of the mesh, bit for bit), or time one path alone.
    #[command(hide = true)]
    MeshCheck {
        /// The mesh file (MSH 4.1).
        mesh: PathBuf,
        /// Partition: metis, x-slabs, y-slabs or rcb.
        #[arg(long, default_value = "rcb")]
        partition: String,
        /// ASCII files above this size (bytes) are converted to binary with gmsh.
        #[arg(long)]
        ascii_limit: Option<u64>,
        /// Run only one path and print its times and peak memory: distributed or replicated.
        #[arg(long, value_parser = ["distributed", "replicated"])]
        only: Option<String>,
    },
    /// Run a scene (launch with mpirun for several ranks). PETSc options and the program's
    /// own solver options go after `--`.
    #[command(after_help = RUN_EXAMPLES)]
    Run {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Output file (default: the scene's output.file).
        #[arg(long, short)]
        output: Option<PathBuf>,
        /// Replace an existing output file.
        #[arg(long)]
        overwrite: bool,
        /// Do not write an HDF5 file.
        #[arg(long)]
        no_output: bool,
        /// Override the scene's number of steps.
        #[arg(long)]
        steps: Option<usize>,
        /// Override the scene's output.every (write the fields every K steps).
        #[arg(long, value_name = "K")]
        every: Option<usize>,
        /// Print only the summary.
        #[arg(long, short)]
        quiet: bool,
        /// Print the energies of every step.
        #[arg(long, short)]
        verbose: bool,
        /// Override a mesh parameter of the scene's .geo, e.g. --param h=0.0625 (repeatable).
        #[arg(long = "param", value_name = "NAME=VALUE")]
        params: Vec<String>,
        /// Override the scene's mass treatment: consistent, lumped, modified0, modified1.
        #[arg(long, value_name = "KIND")]
        mass: Option<String>,
        /// Override the constitutive model of [material] and of every body that does not name
        /// its own: linear (small strain), neo_hookean or saint_venant_kirchhoff (finite
        /// strain).
        #[arg(long, value_name = "MODEL")]
        model: Option<String>,
        /// Override the friction of every obstacle and pair: Coulomb's coefficient (0:
        /// frictionless).
        #[arg(long, value_name = "MU")]
        friction: Option<f64>,
        /// How cells are split over ranks: rcb (recursive coordinate bisection of the cell
        /// centroids, computed without any rank holding the mesh), metis (METIS on rank 0 over
        /// the gathered connectivity), x-slabs or y-slabs (equal-count slabs along x or y, a
        /// predictable cut through the median).
        #[arg(long, default_value = "rcb", value_parser = ["rcb", "metis", "x-slabs", "y-slabs"])]
        partition: String,
        /// Every rank reads the whole mesh file and cuts its part out of it (by default each rank
        /// reads only blocks of it); a check of the default, at the cost of memory.
        #[arg(long)]
        replicated_mesh: bool,
        /// Continue a finished or interrupted run from the checkpoint in its HDF5 file.
        #[arg(long, value_name = "RUN.h5")]
        restart: Option<PathBuf>,
        /// Write the run's summary (sizes, timings, energies, errors) to this TOML file.
        #[arg(long, value_name = "FILE")]
        summary: Option<PathBuf>,
        /// End the run when a rank waits this long for the others (a hung collective): auto
        /// (max(60 s, 1000 x the median step)), off, or seconds.
        #[arg(long, value_name = "auto|off|SECONDS", default_value = "auto", value_parser = HangTimeout::parse)]
        hang_timeout: HangTimeout,
        /// PETSc options, e.g. -ksp_type cg -pc_type gamg -log_view (prefix step_ for the step
        /// solver), and the program's own options, e.g. -contact_solver pdas; -help lists them
        /// all with their defaults, and an option that nothing used is a warning at the end.
        #[arg(last = true, allow_hyphen_values = true)]
        petsc: Vec<String>,
    },
}

/// A snapshot flag without `--snapshot` is a mistake, not something to ignore.
fn no_snapshot_details(args: &SnapshotArgs) -> Result<()> {
    match args.any_detail() {
        Some(flag) => Err(Error::Usage(format!("{flag} needs --snapshot FIELD"))),
        None => Ok(()),
    }
}

fn run(
    cli: Cli,
    universe: &mpi::environment::Universe,
    agree: &mpi::topology::SimpleCommunicator,
) -> Result<()> {
    if let Command::Post { run, nodes, contact_nodes, fields, prefix, snapshot } = &cli.command {
        if universe.world().rank() == 0 {
            if snapshot.snapshot.is_some() {
                if !nodes.is_empty() || !contact_nodes.is_empty() || !fields.is_empty() {
                    return Err(Error::Usage(
                        "--snapshot draws only the picture: leave out --node, --contact-node and --field (run post twice)".into(),
                    ));
                }
                let prefix = prefix.clone().unwrap_or_else(|| massfree::post::default_prefix(run));
                for line in snapshot::draw(std::slice::from_ref(run), &[], snapshot, &prefix)? {
                    println!("{line}");
                }
                return Ok(());
            }
            no_snapshot_details(snapshot)?;
            let opts = massfree::post::PostOptions {
                nodes: nodes.clone(),
                contact_nodes: contact_nodes.clone(),
                fields: fields.clone(),
                prefix: prefix.clone(),
            };
            for line in massfree::post::post(run, &opts)? {
                println!("{line}");
            }
        }
        return Ok(());
    }
    if let Command::Study { study } = &cli.command {
        // The study orchestrates separate mpirun runs; only rank 0 drives it.
        if universe.world().rank() == 0 {
            massfree::study::run(study)?;
        }
        return Ok(());
    }
    if let Command::Suite { spec, reduced, ranks, dir, scenes_only } = &cli.command {
        // Like a study: separate mpirun runs, driven by rank 0.
        if universe.world().rank() == 0 {
            let spec = spec.clone().unwrap_or_else(default_suite);
            let opts = massfree::suite::Options {
                spec,
                reduced: *reduced,
                ranks: *ranks,
                output: dir.clone(),
                scenes_only: *scenes_only,
            };
            massfree::suite::run(&opts)?;
        }
        return Ok(());
    }
    if let Command::Compare { runs, prefix, labels, snapshot } = &cli.command {
        // Post-processing: serial, rank 0 only.
        if universe.world().rank() == 0 {
            if snapshot.snapshot.is_some() {
                for line in snapshot::draw(runs, labels, snapshot, prefix)? {
                    println!("{line}");
                }
                return Ok(());
            }
            no_snapshot_details(snapshot)?;
            let mut curves = Vec::new();
            for (i, r) in runs.iter().enumerate() {
                let mut c = massfree::post::read_curves(r)?;
                if let Some(l) = labels.get(i) {
                    c.label = l.clone();
                }
                curves.push(c);
            }
            for p in massfree::post::write_pictures(prefix, &curves)? {
                println!("{}", p.display());
            }
        }
        return Ok(());
    }
    if let Command::MeshCheck { mesh, partition, ascii_limit, only } = &cli.command {
        use massfree::partition::verify::{mesh_check, Paths};
        let strategy = massfree::partition::Strategy::from_name(partition)
            .ok_or_else(|| Error::Usage(format!("--partition {partition}: unknown")))?;
        let paths = match only.as_deref() {
            Some("distributed") => Paths::Distributed,
            Some("replicated") => Paths::Replicated,
            _ => Paths::Compare,
        };
        let limit = ascii_limit.unwrap_or(massfree::mesh::share::ASCII_WHOLE_LIMIT);
        return mesh_check(&universe.world(), mesh, strategy, limit, paths);
    }
    let world = universe.world();
    let rank = world.rank() as usize;
    match cli.command {
        Command::Run {
            scene,
            output,
            overwrite,
            no_output,
            steps,
            every,
            quiet,
            verbose,
            params,
            mass,
            model,
            friction,
            partition,
            replicated_mesh,
            restart,
            summary: summary_file,
            hang_timeout,
            petsc,
        } => {
            let program = std::env::args().next().unwrap_or_else(|| "massfree".into());
            let mut args = vec![program];
            args.extend(petsc.iter().cloned());
            // The guard is declared first so it is dropped last, after every PETSc object.
            let _petsc =
                Petsc::init(&args, "massfree: dynamic elasticity with mass-free surface layers\n")?;
            let console = Console::new(rank, quiet);
            let mut scene = massfree::scene::load(&scene)?;
            for p in &params {
                scene.set_mesh_param(p)?;
            }
            if let Some(kind) = &mass {
                scene.set_mass_kind(kind)?;
            }
            if let Some(m) = &model {
                scene.set_model(m)?;
            }
            if let Some(mu) = friction {
                scene.set_friction(mu)?;
            }
            if let Some(k) = every {
                if k == 0 {
                    return Err(Error::Usage("--every 0: the output period must be >= 1".into()));
                }
                scene.output.every = k;
            }
            let partition = massfree::partition::Strategy::from_name(&partition)
                .ok_or_else(|| Error::Usage(format!("--partition {partition}: unknown")))?;
            let opts = RunOptions {
                output,
                overwrite,
                steps,
                quiet,
                verbose,
                no_output,
                partition,
                replicated_mesh,
                restart,
                petsc_args: petsc,
                hang_timeout: Some(hang_timeout),
            };
            let mut sim = Simulation::setup(&world, agree, &console, scene, opts)?;
            let summary = sim.run()?;
            for line in sim.summary_lines(&summary) {
                console.result(line);
            }
            massfree::run::options::warn_unused(&world, &console)?;
            if let (Some(path), 0) = (summary_file, rank) {
                let text =
                    toml::to_string(&summary).map_err(|e| Error::Io(format!("summary: {e}")))?;
                std::fs::write(&path, text)
                    .map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))?;
            }
            Ok(())
        }
        Command::Compare { .. }
        | Command::Study { .. }
        | Command::Post { .. }
        | Command::Suite { .. }
        | Command::MeshCheck { .. } => Ok(()),
    }
}

/// `studies/suite.toml` in the current folder, else the one of the repository the binary was
/// built from.
fn default_suite() -> PathBuf {
    let here = PathBuf::from("studies/suite.toml");
    if here.is_file() {
        return here;
    }
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("studies/suite.toml")
}

fn main() {
    let cli = Cli::parse();
    // SIGINT/SIGTERM stop a run at its next phase boundary or step; it marks its file and exits
    // with code 130. Installed first, so that a signal at any moment is seen. (post, study and
    // compare keep the default: a signal ends them at once.)
    if matches!(cli.command, Command::Run { .. }) {
        if let Err(e) = phase::install_signal_handlers() {
            eprintln!("massfree: {e}");
            std::process::exit(1);
        }
    }
    massfree::error::install_panic_hook();
    let code = {
        // MPI is called from the main thread only, except MPI_Abort by the watchdog thread
        // when the main thread is stuck in MPI (Open MPI handles that; THREAD_MULTIPLE would
        // make it strictly legal but costs ~50% per step on small problems: 0.17-0.20 against
        // 0.28-0.30 ms per step, coarse disc, 2 ranks).
        let Some((universe, _)) = mpi::initialize_with_threading(mpi::Threading::Funneled) else {
            eprintln!("massfree: MPI error: MPI was already initialized");
            std::process::exit(1);
        };
        let world = universe.world();
        // Used only to find out whether an error happened on every rank (see phase::all_reached).
        let agree = world.duplicate();
        let result = massfree::run::guard(|| run(cli, &universe, &agree));
        match result {
            Ok(()) => 0,
            Err(e) => report(&world, &agree, &e),
        }
        // universe dropped here: MPI_Finalize after PETSc's guard was dropped inside run().
    };
    std::process::exit(code);
}

/// Print an error once and return the exit code (130 for a signal, 1 otherwise). An error that
/// every rank has is printed by rank 0; one that only this rank has is printed here, and the
/// job is aborted, since the other ranks wait for this one in some collective operation.
fn report(
    world: &mpi::topology::SimpleCommunicator,
    agree: &mpi::topology::SimpleCommunicator,
    e: &Error,
) -> i32 {
    if !phase::all_reached(agree, std::time::Duration::from_secs(10)) {
        eprintln!("massfree: rank {}: {e}", world.rank());
        world.abort(1);
    }
    if world.rank() == 0 {
        eprintln!("massfree: {e}");
    }
    if matches!(e, Error::Interrupted(_)) {
        130
    } else {
        1
    }
}
