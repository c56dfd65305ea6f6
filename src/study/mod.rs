//! `massfree study STUDY.toml`: sweeps of real runs mapping error against wall time.

use std::path::Path;

use crate::error::{Error, Result};

/// Run the study described by the file (placeholder until the study module lands).
pub fn run(path: &Path) -> Result<()> {
    Err(Error::Usage(format!("study {}: the study command is being built", path.display())))
}
