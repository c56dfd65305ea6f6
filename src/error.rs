//! One error type for the whole application. Its `Display` is a single line that names the
//! culprit (a scene key, a mesh element, a PETSc call); `main` prints it and exits non-zero.

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// Command line: wrong subcommand, missing file, bad flag.
    Usage(String),
    /// Scene file: unknown key, impossible value (names the key and what is allowed).
    Scene(String),
    /// Mesh file or mesh geometry: malformed MSH, degenerate element, missing group.
    Mesh(String),
    /// Partitioning (METIS) failures.
    Partition(String),
    /// A PETSc call returned a non-zero error code; `message` is PETSc's own explanation.
    Petsc { call: String, code: i32, location: String, message: String },
    /// A solver did not converge or a numerical invariant broke.
    Solver(String),
    /// Reading or writing files (HDF5, PNG, CSV, ...).
    Io(String),
    /// An MPI-level failure.
    Mpi(String),
    /// The run was stopped by SIGINT or SIGTERM (after finishing its step and its output).
    Interrupted(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Usage(m) => write!(f, "usage error: {m}"),
            Error::Scene(m) => write!(f, "scene error: {m}"),
            Error::Mesh(m) => write!(f, "mesh error: {m}"),
            Error::Partition(m) => write!(f, "partition error: {m}"),
            Error::Petsc { call, code, location, message } => {
                write!(f, "PETSc error {code} in {call} at {location}")?;
                if !message.is_empty() {
                    write!(f, ": {message}")?;
                }
                Ok(())
            }
            Error::Solver(m) => write!(f, "solver error: {m}"),
            Error::Io(m) => write!(f, "I/O error: {m}"),
            Error::Mpi(m) => write!(f, "MPI error: {m}"),
            Error::Interrupted(m) => write!(f, "interrupted: {m}"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;
