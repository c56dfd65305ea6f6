//! The options of a run, read once at set-up: what the command line adds to a scene
//! ([`RunOptions`]).

use std::path::PathBuf;

use crate::phase::HangTimeout;

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
