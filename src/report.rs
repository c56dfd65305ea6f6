//! What a finished run reports: [`RunSummary`] and its parts. Written to the HDF5 file's
//! `summary` attribute and by `--summary FILE` as TOML; read back from a run file by `post`,
//! `study` and `suite` through [`RunSummary::read`].

use std::path::PathBuf;

use crate::contact::history::ContactSummary;
use crate::io::layout::RunReader;
use crate::stability::{body_size, ContactColumns, RunSeries, Stability};
use crate::time::{Corrections, ReuseReport};

/// Wall time of the phases of a run, in seconds (max over ranks).
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct Timings {
    /// Meshing (gmsh, when the cache misses) and reading this rank's share of the mesh file.
    pub mesh: f64,
    /// Deciding the rank of every cell.
    pub partition: f64,
    /// Moving cells to their ranks: ownership, numbering, the ghost layer, the contact surface.
    #[serde(default)]
    pub migration: f64,
    /// Matrices and loads (the layer's part of it in `layer`).
    pub assembly: f64,
    /// Building the mass-free layer (its part of `assembly`).
    #[serde(default)]
    pub layer: f64,
    /// The stiffness `A` alone (its part of `assembly`; the node graph, built once for every
    /// matrix, included).
    #[serde(default)]
    pub stiffness: f64,
    pub setup: f64,
    pub stepping: f64,
    /// Writing the output (the stress-type fields' computation excluded).
    pub output: f64,
    /// Computing the stress-type output fields (`stress`, `von_mises_nodal`, ...): zero in a
    /// run that writes none.
    #[serde(default)]
    pub stress: f64,
    /// Errors against the scene's exact solution at its error steps (not part of `stepping`).
    #[serde(default)]
    pub errors: f64,
}

/// Errors of the displacement against the scene's exact solution at one step.
#[derive(Debug, Clone, Copy, serde::Serialize, serde::Deserialize)]
pub struct ErrorSample {
    pub step: usize,
    pub time: f64,
    pub l2: f64,
    pub h1_semi: f64,
    /// The velocity's L2 error, where the scene gives `exact.velocity`.
    #[serde(default)]
    pub velocity_l2: Option<f64>,
}

/// What a finished run reports (written by `--summary FILE` as TOML).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RunSummary {
    pub n_nodes: usize,
    /// Cells of the whole mesh.
    #[serde(default)]
    pub n_cells: usize,
    pub n_dofs: usize,
    pub steps: usize,
    pub timings: Timings,
    pub ksp_iterations: usize,
    pub energy_initial: f64,
    pub energy_final: f64,
    pub external_work: f64,
    /// max_n |E^n - E^0 - W^n| / max_n E^n: the integrator's energy balance.
    pub energy_balance: f64,
    /// max_n |E^n - E^0| / E^0 (0 when E^0 = 0).
    pub energy_drift: f64,
    /// max_n |E^n|: the scale of the run's energy (a body released at rest under gravity
    /// starts at E^0 = 0).
    #[serde(default)]
    pub energy_max: f64,
    pub errors: Vec<ErrorSample>,
    pub output: Option<PathBuf>,
    /// Wall time of one MatMult with the step operator (the floor of a step's cost).
    pub matmult_seconds: f64,
    /// Peak resident memory summed over the ranks, in MiB.
    pub peak_memory_mib: f64,
    /// The largest peak resident memory of one rank, in MiB.
    #[serde(default)]
    pub peak_memory_rank_mib: f64,
    /// What each rank holds of the mesh, in rank order (what its memory scales with).
    #[serde(default)]
    pub held: Vec<RankHeld>,
    pub ranks: usize,
    /// The step solver as PETSc finally configured it (defaults < scene < command line).
    pub ksp_type: String,
    pub pc_type: String,
    pub mass_kind: String,
    /// Contact nodes and layer cells of the mass-free layer (0 without one).
    pub layer_contact_nodes: usize,
    pub layer_cells: usize,
    pub mass: MassCheck,
    /// Total momentum `1^T M v` at the start and the end, per component.
    pub momentum_initial: Vec<f64>,
    pub momentum_final: Vec<f64>,
    /// The angular momentum about the centre of mass, `sum_v (x_v - x_c) x (M v)_v` (current
    /// positions `x = X + u`, three components), at the start (a restart: at the restart) and
    /// the end.
    #[serde(default)]
    pub angular_momentum_initial: Vec<f64>,
    #[serde(default)]
    pub angular_momentum_final: Vec<f64>,
    pub contact: Option<ContactSummary>,
    /// PNG pictures written (rank 0's list).
    pub pictures: Vec<PathBuf>,
    /// What the run simulated and what it did not build (`Effects::summary`).
    pub effects: String,
    /// Each `[[body]]` (empty without).
    #[serde(default)]
    pub bodies: Vec<BodySummary>,
    /// The largest change the consistent initialization made to the massless DOFs' initial
    /// displacement (`None` without massless DOFs, or on a restart).
    #[serde(default)]
    pub massless_initialization: Option<f64>,
    /// Steps after which released massless contact nodes were put back in static equilibrium
    /// (`Midpoint::step`), and the energy that took (<= 0, part of the contact work).
    #[serde(default)]
    pub release_projections: usize,
    #[serde(default)]
    pub release_energy: f64,
    /// What the level scheme's energy correction did.
    #[serde(default)]
    pub energy_corrections: Corrections,
    /// What the step's own CG and its kept products did (`time::cg`; zero steps when PETSc's
    /// KSP solved every step).
    #[serde(default)]
    pub step_reuse: ReuseReport,
    /// The largest number of KSP iterations of one step (`ksp_iterations` is the sum).
    #[serde(default)]
    pub ksp_iterations_step_max: usize,
    /// The CFL number `c_p tau / h_min` of the step solver's regime (largest over the bodies).
    #[serde(default)]
    pub cfl: f64,
    /// Stability metrics (energy rise and loss against the work, penetration, chatter,
    /// episodes per impact, iterations; `stability::Stability`).
    #[serde(default)]
    pub stability: Option<Stability>,
    /// Finite strain: what the Newton loops did (`time::newton`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub newton: Option<crate::time::newton::NewtonStats>,
    /// Each body's largest rotation (of its mean deformation gradient).
    #[serde(default)]
    pub rotations: Vec<BodyRotation>,
}

/// The part of the mesh one rank holds: its own cells and the ghost layer (the cells sharing a
/// node with its own), and their nodes.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct RankHeld {
    /// Cells held: own and ghost.
    pub cells: usize,
    /// Cells the rank assembles (its part of the partition).
    pub cells_owned: usize,
    /// Nodes held: the nodes of the cells held.
    pub nodes: usize,
    /// Nodes the rank owns (its rows).
    pub nodes_owned: usize,
}

/// One body's largest rotation over a run (`run::rotation`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BodyRotation {
    pub body: String,
    /// The largest rotation angle of the body's mean deformation gradient, in degrees.
    pub degrees: f64,
    /// When it was reached.
    pub time: f64,
}

/// One `[[body]]` of a finished run.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct BodySummary {
    pub group: String,
    #[serde(rename = "E")]
    pub e: f64,
    pub nu: f64,
    pub rho: f64,
    /// The mass treatment its cells got: consistent, lumped, modified0, modified1 (a modified
    /// kind without a contact group on the body gives the consistent mass: `consistent`).
    pub mass_kind: String,
    pub cells: usize,
    /// `1_B^T M 1` per component, `1_B` one on the body's nodes: the body's mass when it shares
    /// no node with another body.
    pub total_mass: Vec<f64>,
    /// `1_B^T M v` per component at the start and the end: the body's momentum (a restarted
    /// run starts at its checkpoint).
    pub momentum_initial: Vec<f64>,
    pub momentum_final: Vec<f64>,
    /// The mass-free layer's contact nodes and cells on the body.
    pub layer_contact_nodes: usize,
    pub layer_cells: usize,
    /// The impulse the contact gave the body, `tau sum_n` of the contact forces on its nodes
    /// (a pair's slave: `D lambda`; its master: `-M^T lambda`; zero off the contact): with no
    /// other load it equals the momentum change.
    #[serde(default)]
    pub contact_impulse: Vec<f64>,
    /// Friction's part of `contact_impulse` (zero without friction).
    #[serde(default)]
    pub friction_impulse: Vec<f64>,
}

/// Mass-matrix diagnostics (see `check_mass`), per displacement component.
#[derive(Debug, Clone, Default, serde::Serialize, serde::Deserialize)]
pub struct MassCheck {
    pub total_mass: Vec<f64>,
    pub first_moment: Vec<f64>,
    pub second_moment: Vec<f64>,
    /// max |(M 1)_q| over contact DOFs q (exactly zero for the mass-free layer).
    pub contact_row_max: f64,
    /// M r for r_i = sin(i + 1) (natural DOF order), this rank's natural block.
    #[serde(skip)]
    pub probe: Vec<f64>,
    /// Per body, `1_B^T M 1` per component (reported in `RunSummary::bodies`).
    #[serde(skip)]
    pub body_mass: Vec<Vec<f64>>,
}

impl RunSummary {
    /// A run's summary as `massfree run --summary` and the HDF5 file's `summary` attribute
    /// hold it (TOML).
    pub fn parse(text: &str) -> std::result::Result<RunSummary, String> {
        toml::from_str(text).map_err(|e: toml::de::Error| e.message().to_string())
    }

    /// The summary of the run file `run` (absent for a run that did not finish).
    pub fn read(run: &RunReader) -> Option<RunSummary> {
        RunSummary::parse(&run.summary_text()).ok()
    }

    /// A made-up summary of a small contact run for unit tests (30 steps, 1458 DOFs, M).
    #[cfg(test)]
    pub fn example() -> RunSummary {
        use crate::contact::history::ContactSummary;
        RunSummary {
            n_nodes: 729,
            n_cells: 640,
            n_dofs: 1458,
            steps: 30,
            timings: Timings {
                mesh: 0.1,
                partition: 0.01,
                assembly: 0.02,
                setup: 0.03,
                stepping: 0.5,
                output: 0.0,
                stress: 0.0,
                ..Default::default()
            },
            ksp_iterations: 124,
            energy_initial: 1.0,
            energy_final: 1.0,
            external_work: 0.0,
            energy_balance: 1e-12,
            energy_drift: 1e-4,
            errors: vec![ErrorSample {
                step: 30,
                time: 3e-4,
                l2: 6.1e-6,
                h1_semi: 1.5e-4,
                velocity_l2: Some(2.4e-5),
            }],
            output: None,
            matmult_seconds: 1e-4,
            peak_memory_mib: 85.5,
            peak_memory_rank_mib: 85.5,
            held: vec![RankHeld { cells: 640, cells_owned: 640, nodes: 729, nodes_owned: 729 }],
            ranks: 2,
            ksp_type: "cg".into(),
            pc_type: "jacobi".into(),
            mass_kind: "consistent".into(),
            layer_contact_nodes: 0,
            layer_cells: 0,
            mass: MassCheck::default(),
            momentum_initial: vec![0.0, 0.0],
            momentum_final: vec![0.0, 0.0],
            angular_momentum_initial: vec![0.0; 3],
            angular_momentum_final: vec![0.0; 3],
            contact: Some(ContactSummary {
                max_pressure: 2.5,
                episodes_max: 1,
                ..Default::default()
            }),
            pictures: vec![],
            effects: String::new(),
            bodies: Vec::new(),
            energy_max: 0.0,
            massless_initialization: None,
            release_projections: 0,
            release_energy: 0.0,
            energy_corrections: Default::default(),
            step_reuse: Default::default(),
            ksp_iterations_step_max: 7,
            newton: None,
            rotations: Vec::new(),
            cfl: 0.5,
            stability: None,
        }
    }
}

/// The metrics of a finished run read back from its HDF5 file: the series of `/energy` and
/// `/contact`, the coordinates, and from the file's summary the lowest contact node and the
/// KSP iterations (not in the datasets); the written fields (and the final checkpoint) are
/// scanned for non-finite values too.
pub fn stability_from_file(path: &std::path::Path) -> crate::Result<Stability> {
    use crate::io::layout;
    let run = RunReader::open(path)?;
    let summary = RunSummary::read(&run).ok_or_else(|| {
        crate::Error::Io(format!("{}: no run summary (the run did not finish)", path.display()))
    })?;
    let series = |name: &str| run.series(&layout::energy(name));
    let contact = if run.file.dataset(&layout::contact("force")).is_ok() {
        let nodes = run.series(&layout::contact("nodes"))?;
        let lowest = (summary.contact.as_ref())
            .and_then(|c| nodes.iter().position(|&v| v as usize == c.lowest_node))
            .unwrap_or(0);
        let active = run.series(&layout::contact("active"))?.iter().map(|&a| a != 0.0).collect();
        Some(ContactColumns {
            nodes: nodes.len(),
            force: run.series(&layout::contact("force"))?,
            gap: run.series(&layout::contact("gap"))?,
            active,
            weights: run.series(&layout::contact("weights"))?,
            iterations: run.series(&layout::contact("iterations"))?,
            lowest,
        })
    } else {
        None
    };
    let mut s = RunSeries {
        total: series("total")?,
        external_work: series("external_work")?,
        dirichlet_work: series("dirichlet_work")?,
        // The work of all contact forces: friction's dissipation taken off (a file from before
        // friction has no dissipation series).
        contact_work: match series("friction_dissipation") {
            Ok(fd) => series("contact_work")?.iter().zip(&fd).map(|(w, d)| w - d).collect(),
            Err(_) => series("contact_work")?,
        },
        contact,
        body_size: body_size(&run.coordinates()?),
        ksp_iterations: summary.ksp_iterations,
        ksp_iterations_step_max: summary.ksp_iterations_step_max,
    }
    .measure();
    for name in ["fields/displacement", "fields/velocity", "checkpoint/u", "checkpoint/v"] {
        if run.file.dataset(name).is_ok() {
            s.non_finite += run.series(name)?.iter().filter(|x| !x.is_finite()).count();
        }
    }
    Ok(s)
}
