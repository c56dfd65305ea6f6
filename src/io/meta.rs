//! The run file's metadata: every attribute of the file (text and numbers) goes through
//! [`RunFile::write_meta`], and nowhere else.
//!
//! Why: a variable-length string lives in HDF5's global heap, and whether writing one needs a
//! new heap collection (a collective file-space allocation) depends on each rank's metadata
//! cache. Written collectively through the parallel (MPI-IO) handle, attributes let the ranks
//! take different metadata paths: rank 0 in `H5Fflush`, rank 1 in `H5HG_insert -> MPI_Bcast`,
//! and the run hung after its last step (10000 steps of the disc on 2 ranks). The same holds
//! for any attribute whose text differs between ranks (timings, paths, warnings).
//!
//! The cure chosen (by measurement: a serial open, write and close costs about a millisecond,
//! and happens three times per run): attributes are written by rank 0 alone, through a serial
//! handle, only while no parallel handle of the file is open: when the file is created, once
//! before the time series are opened in parallel (settings, groups), and after the parallel
//! handle is closed at the end (status, summary, timings). The other ranks make no HDF5 call
//! for them at all, so no metadata path can differ; they only learn the outcome (a broadcast of
//! rank 0's result), so an I/O error is reported alike on every rank. Only rank 0's values are
//! written: values that differ between ranks cannot reach the file. The types make the order
//! impossible to get wrong: [`RunFile`] (closed, can write metadata) is consumed by
//! `Output::open` (parallel, cannot write metadata) and given back by `Output::close`.
//! Fixed-length strings sized by an allreduce would also avoid the global heap, but the HDF5
//! binding has fixed-length strings only with compile-time sizes.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;
use hdf5::File;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::error::{Error, Result};

fn h5err(path: &Path, what: &str, e: hdf5::Error) -> Error {
    Error::Io(format!("{}: {what}: {e}", path.display()))
}

/// One attribute value.
#[derive(Debug, Clone, PartialEq)]
pub enum MetaValue {
    Text(String),
    Int(i64),
}

/// One attribute: on `object` (`"/"` or a group path such as `"contact"` or
/// `"mesh/groups/left"`; missing groups are created), its name and value.
#[derive(Debug, Clone, PartialEq)]
pub struct Meta {
    pub object: String,
    pub name: String,
    pub value: MetaValue,
}

impl Meta {
    /// A text attribute on the root.
    pub fn text(name: &str, value: impl Into<String>) -> Meta {
        Meta { object: "/".into(), name: name.into(), value: MetaValue::Text(value.into()) }
    }
    /// A text attribute on a group.
    pub fn text_on(object: &str, name: &str, value: impl Into<String>) -> Meta {
        Meta { object: object.into(), name: name.into(), value: MetaValue::Text(value.into()) }
    }
    /// An integer attribute on a group (or the root, `"/"`).
    pub fn int_on(object: &str, name: &str, value: i64) -> Meta {
        Meta { object: object.into(), name: name.into(), value: MetaValue::Int(value) }
    }
}

/// The run file while no parallel handle is open: the only state in which metadata is written.
#[derive(Debug)]
pub struct RunFile {
    path: PathBuf,
    rank: usize,
}

impl RunFile {
    /// Create the file with its first metadata (rank 0, serial handle). Refuses an existing
    /// file unless `overwrite`. Collective: every rank gets rank 0's outcome.
    pub fn create(
        world: &SimpleCommunicator,
        path: &Path,
        overwrite: bool,
        items: &[Meta],
    ) -> Result<RunFile> {
        let rank = world.rank() as usize;
        let mut outcome = Ok(());
        if rank == 0 {
            outcome = create_serial(path, overwrite, items);
        }
        agree(world, outcome)?;
        Ok(RunFile { path: path.to_path_buf(), rank })
    }

    /// Write metadata (rank 0, serial handle). Collective: every rank gets rank 0's outcome.
    pub fn write_meta(&self, world: &SimpleCommunicator, items: &[Meta]) -> Result<()> {
        let mut outcome = Ok(());
        if self.rank == 0 {
            outcome = File::open_rw(&self.path)
                .map_err(|e| h5err(&self.path, "open to write metadata", e))
                .and_then(|f| {
                    write_items(&f, items, &self.path)?;
                    f.close().map_err(|e| h5err(&self.path, "close", e))
                });
        }
        agree(world, outcome)
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Whether an existing file is the record of a run that ended before its first step (failed
/// or stopped during set-up): it holds nothing worth keeping, so a new run may replace it
/// without `--overwrite` (the user fixed the scene and runs again).
fn holds_no_step(path: &Path) -> bool {
    let Ok(f) = File::open(path) else { return false };
    let status = f
        .attr("status")
        .and_then(|a| a.read_scalar::<VarLenUnicode>())
        .map(|s| s.to_string())
        .unwrap_or_default();
    let ended = status.starts_with("failed") || status.starts_with("interrupted");
    let steps = f.dataset("energy/step").map(|d| d.size()).unwrap_or(0);
    ended && steps == 0
}

fn create_serial(path: &Path, overwrite: bool, items: &[Meta]) -> Result<()> {
    if path.exists() && !overwrite && !holds_no_step(path) {
        return Err(Error::Io(format!(
            "{} exists; pass --overwrite to replace it or choose another output.file",
            path.display()
        )));
    }
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir)
                .map_err(|e| Error::Io(format!("cannot create {}: {e}", dir.display())))?;
        }
    }
    let f = File::create(path).map_err(|e| h5err(path, "create", e))?;
    write_items(&f, items, path)?;
    f.close().map_err(|e| h5err(path, "close", e))
}

fn write_items(f: &File, items: &[Meta], path: &Path) -> Result<()> {
    for m in items {
        let mut g = f.group("/").map_err(|e| h5err(path, "open /", e))?;
        for part in m.object.split('/').filter(|p| !p.is_empty()) {
            g = match g.group(part) {
                Ok(sub) => sub,
                Err(_) => g
                    .create_group(part)
                    .map_err(|e| h5err(path, &format!("create group {}", m.object), e))?,
            };
        }
        let loc: &hdf5::Location = &g;
        let what = format!("attribute {} of {}", m.name, m.object);
        // A new value of another type or length replaces the attribute.
        if loc.attr(&m.name).is_ok() {
            loc.delete_attr(&m.name).map_err(|e| h5err(path, &format!("replace {what}"), e))?;
        }
        match &m.value {
            MetaValue::Text(s) => {
                let v: VarLenUnicode = s.parse().map_err(|_| {
                    Error::Io(format!("{}: {what} is not valid text", path.display()))
                })?;
                loc.new_attr::<VarLenUnicode>()
                    .create(m.name.as_str())
                    .and_then(|a| a.write_scalar(&v))
                    .map_err(|e| h5err(path, &format!("write {what}"), e))?;
            }
            MetaValue::Int(i) => {
                loc.new_attr::<i64>()
                    .create(m.name.as_str())
                    .and_then(|a| a.write_scalar(i))
                    .map_err(|e| h5err(path, &format!("write {what}"), e))?;
            }
        }
    }
    Ok(())
}

/// Every rank gets rank 0's outcome: `Ok`, or rank 0's error (its kind and message).
pub fn agree(world: &SimpleCommunicator, outcome: Result<()>) -> Result<()> {
    if world.size() == 1 {
        return outcome;
    }
    let root = world.process_at_rank(0);
    let (mut code, mut text) = match &outcome {
        Ok(()) => (0i32, Vec::new()),
        Err(Error::Io(m)) => (1, m.as_bytes().to_vec()),
        Err(e) => (2, e.to_string().into_bytes()),
    };
    root.broadcast_into(&mut code);
    if code == 0 {
        return Ok(());
    }
    let mut len = text.len() as u64;
    root.broadcast_into(&mut len);
    text.resize(len as usize, 0);
    root.broadcast_into(&mut text[..]);
    if world.rank() == 0 {
        return outcome;
    }
    let msg = String::from_utf8_lossy(&text).into_owned();
    Err(if code == 1 { Error::Io(msg) } else { Error::Io(format!("on rank 0: {msg}")) })
}
