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
    /// A contact interface cannot be evaluated at a configuration (a slave facet that does not
    /// project onto the master any more); the same on every rank, so a solver may go back.
    Geometry(String),
    /// Reading or writing files (HDF5, PNG, CSV, ...).
    Io(String),
    /// An MPI-level failure.
    Mpi(String),
    /// The run was stopped by SIGINT or SIGTERM (after finishing its step and its output).
    Interrupted(String),
    /// A bug: a panic, caught and reported as one line.
    Internal(String),
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
            Error::Geometry(m) => write!(f, "solver error: {m}"),
            Error::Io(m) => write!(f, "I/O error: {m}"),
            Error::Mpi(m) => write!(f, "MPI error: {m}"),
            Error::Interrupted(m) => write!(f, "interrupted: {m}"),
            Error::Internal(m) => write!(f, "internal error (a bug, please report it): {m}"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

/// Where and why the last panic happened, kept by the hook of [`install_panic_hook`].
static LAST_PANIC: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// Replace Rust's multi-line panic report by a record of its message and place: the run turns
/// the panic into an [`Error::Internal`], marks its output file and prints one line.
pub fn install_panic_hook() {
    std::panic::set_hook(Box::new(|info| {
        let place = info.location().map(|l| format!(" at {}:{}", l.file(), l.line()));
        let text = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "panic".into());
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = format!("{}{}", text.replace('\n', "; "), place.unwrap_or_default());
        }
    }));
}

/// The message of a caught panic (with its place when the hook recorded it).
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    let recorded = LAST_PANIC.lock().map(|m| m.clone()).unwrap_or_default();
    if !recorded.is_empty() {
        return recorded;
    }
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "panic".into())
}
