//! HDF5 output: the mesh, nodal time series in the original gmsh node numbering, the energies
//! of every step, the scene text and the run's settings.
//!
//! Layout (all names documented in README.md):
//! - `/mesh/coordinates` [n_nodes, 3], `/mesh/node_tags` [n_nodes],
//!   `/mesh/cells/<kind>` [n, nodes per cell] (0-based indices into coordinates),
//!   `/mesh/cell_rank` [n_cells] (the partition, RCB by default, in the order of the cells of
//!   `/mesh/cells`),
//! - `/time` [n_out], `/step` [n_out] of the written field steps,
//! - `/fields/displacement`, `/fields/velocity` [n_out, n_nodes, dim], the stress-type cell
//!   fields `/fields/{stress,strain}` [n_out, n_cells, 6] and `/fields/{von_mises,
//!   effective_stress,pressure}` [n_out, n_cells, 1] (cells in the order of `/mesh/cells`,
//!   [`natural_cell_index`]) and their nodal projections `/fields/<name>_nodal`, each with its
//!   own `/fields/<name>_step`, `/fields/<name>_time` (fields may have their own periods),
//! - `/energy/{step,time,kinetic,potential,total,external_work}` [n_steps + 1], one entry per
//!   step (external work `W^n = sum_k f^{k+1/2} . du^k`, so `total - total[0] - external_work`
//!   is the integrator's energy balance, zero up to solver tolerance),
//! - `/mesh/groups/<name>/nodes` (attribute `dim`), `/contact/...` (for a slave/master pair
//!   also `/contact/master_nodes` and the attributes `slave_group`, `master_group`; with
//!   obstacles beside the pair `obstacle_group`, whose nodes are among `/contact/nodes`),
//!   `/checkpoint/...`,
//! - attributes on `/`: `scene`, `settings` (key = value lines), `solver_options`, `ranks`,
//!   `version`, `status` (`running`, `finished`, `failed: ...`, `interrupted: ...`),
//!   `summary`, `timings`. The file is created (status `running`) before the mesh is read, so
//!   a run that fails or is stopped in any phase says so in its file.
//!
//! The file is opened with the MPI-IO driver: each rank writes its own contiguous block of
//! every field (in natural, i.e. original, node order), so no rank gathers a whole field.
//! Dataset creation and resizing are collective; every written field step is flushed so a run
//! that dies keeps what it wrote.
//!
//! **Why runs never hang in HDF5.** Parallel HDF5 keeps a metadata cache on every rank and
//! relies on all ranks performing the same metadata operations in the same order: its
//! collective points (cache sync points, reads that rank 0 does and broadcasts) are reached by
//! counting what each rank did. Anything one rank does and another does not makes the caches
//! diverge, and some later collective then hangs or fails (`MPI_ERR_TRUNCATE` in an
//! `MPI_Bcast`), after however many steps it takes for the difference to matter. Seen: a
//! 2-rank disc run hung after 10000 steps in a variable-length attribute write (global heap,
//! `H5HG_insert -> H5C_protect -> MPI_Bcast` on rank 1 while rank 0 was in `H5Fflush`), and,
//! with the attributes fixed, the same run with `--every 1000` failed when it created
//! `/checkpoint` at its end: rank 0 alone had written the energy series, and its writes into
//! chunked datasets had looked up chunk addresses that the other ranks never loaded. Two rules
//! make this impossible, and this module is built on them:
//! 1. Attributes (all text, and the few numbers) are written only by rank 0 through a serial
//!    handle while no parallel handle is open ([`meta`]); [`Output`] has no attribute method.
//! 2. While the parallel handle is open, every rank makes the same HDF5 calls: datasets are
//!    created with shapes all ranks agree on (checked by an allreduce before creation), series
//!    that every rank holds (energies, axes, contact rows) are written by every rank alike, and
//!    nodal fields use one chunk per written step, so each rank's block lands in the same
//!    chunk. Only contiguous datasets (mesh, checkpoint scalars), whose writes touch no
//!    metadata, are written by rank 0 alone.

pub mod fields;
pub mod layout;
pub mod meta;
pub mod xdmf;

pub use crate::rows::{FieldSpec, Location};
pub use fields::PlannedField;
pub use meta::{Meta, MetaValue, RunFile};

use std::path::{Path, PathBuf};

use hdf5::file::FileCloseDegree;
use hdf5::{Dataset, File};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::{Error, Result};

use crate::rows::{ContactRow, Energy};

fn h5err(path: &Path, what: &str, e: hdf5::Error) -> Error {
    Error::Io(format!("{}: {what}: {e}", path.display()))
}

/// Append `val` at row `k` of an extendable 1-D series. Every rank calls this with the same
/// value: chunked datasets must see the same calls on every rank (see the module doc).
fn append_replicated(ds: &Dataset, k: usize, val: f64, path: &Path, name: &str) -> Result<()> {
    ds.resize((k + 1,)).map_err(|e| h5err(path, &format!("resize {name}"), e))?;
    ds.write_slice(&[val], k..k + 1).map_err(|e| h5err(path, &format!("write {name}"), e))
}

/// Open a group, or create it (collectively) if the metadata phase did not.
fn group(parent: &hdf5::Group, name: &str, path: &Path) -> Result<hdf5::Group> {
    match parent.group(name) {
        Ok(g) => Ok(g),
        Err(_) => parent.create_group(name).map_err(|e| h5err(path, &format!("create {name}"), e)),
    }
}

/// The name of a physical group's HDF5 group (`/` is not allowed in a name).
pub fn group_key(name: &str) -> String {
    name.replace('/', "_")
}

/// All ranks must create the same datasets: compare the numbers that decide the layout.
fn agreed_layout(
    world: &mpi::topology::SimpleCommunicator,
    key: &[usize],
    path: &Path,
) -> Result<()> {
    let mine: Vec<u64> = key.iter().map(|&k| k as u64).collect();
    let mut lo = vec![0u64; mine.len()];
    let mut hi = vec![0u64; mine.len()];
    world.all_reduce_into(&mine[..], &mut lo[..], SystemOperation::min());
    world.all_reduce_into(&mine[..], &mut hi[..], SystemOperation::max());
    if lo != hi {
        return Err(Error::Io(format!(
            "{}: the ranks disagree on the file's layout ({lo:?} vs {hi:?}); this is a bug, please report it",
            path.display()
        )));
    }
    Ok(())
}

pub mod blocks;

pub use crate::mesh::{file_cell_kinds, natural_cell_index, natural_range};
pub use blocks::MeshBlocks;

/// `/mesh`: coordinates, node tags, cells by kind, cell ranks and the groups' nodes, each
/// rank writing its blocks (datasets created collectively; every write is collective).
fn write_mesh(
    file: &File,
    mesh: &MeshBlocks,
    (lo, hi): (usize, usize),
    (clo, chi): (usize, usize),
    path: &Path,
) -> Result<()> {
    let n = mesh.n_nodes;
    let g = group(file, "mesh", path)?;
    let coords = g
        .new_dataset::<f64>()
        .shape((n, 3))
        .create("coordinates")
        .map_err(|e| h5err(path, "create /mesh/coordinates", e))?;
    let flat = mesh.coords.as_flattened();
    let arr = ndarray::ArrayView2::from_shape((hi - lo, 3), flat).expect("shape");
    coords
        .write_slice(arr, ndarray::s![lo..hi, ..])
        .map_err(|e| h5err(path, "write /mesh/coordinates", e))?;
    let tags = g
        .new_dataset::<u64>()
        .shape((n,))
        .create("node_tags")
        .map_err(|e| h5err(path, "create /mesh/node_tags", e))?;
    tags.write_slice(&mesh.tags, ndarray::s![lo..hi])
        .map_err(|e| h5err(path, "write /mesh/node_tags", e))?;
    let cr = g
        .new_dataset::<i32>()
        .shape((mesh.n_cells(),))
        .create("cell_rank")
        .map_err(|e| h5err(path, "create /mesh/cell_rank", e))?;
    cr.write_slice(&mesh.cell_rank, ndarray::s![clo..chi])
        .map_err(|e| h5err(path, "write /mesh/cell_rank", e))?;
    // One dataset per kind: this rank's rows are its block's cells of that kind.
    let cg = group(&g, "cells", path)?;
    let mut first = 0;
    // Where this rank's cells of the current kind start in `mesh.cells`.
    let mut at = 0;
    for &(k, count) in &mesh.kinds {
        let nn = k.n_nodes();
        let ds = cg
            .new_dataset::<u64>()
            .shape((count, nn))
            .create(k.name())
            .map_err(|e| h5err(path, "create /mesh/cells", e))?;
        // This rank's block's rows of this kind (none when the block lies elsewhere).
        let (a, b) = (clo.max(first), chi.min(first + count));
        if a >= b {
            first += count;
            continue;
        }
        let conn = mesh.cells.get(at..at + (b - a) * nn).ok_or_else(|| {
            Error::Internal(format!(
                "/mesh/cells: {} node entries, short of {}",
                mesh.cells.len(),
                at + (b - a) * nn
            ))
        })?;
        at += (b - a) * nn;
        let arr = ndarray::ArrayView2::from_shape((b - a, nn), conn).expect("shape");
        ds.write_slice(arr, ndarray::s![a - first..b - first, ..])
            .map_err(|e| h5err(path, "write /mesh/cells", e))?;
        first += count;
    }
    // Physical groups: /mesh/groups/<name>/nodes with the group's dimension as attribute.
    let gg = group(&g, "groups", path)?;
    for (name, offset, nodes, total) in &mesh.groups {
        let sub = group(&gg, &group_key(name), path)?;
        let ds = sub
            .new_dataset::<u64>()
            .shape((*total,))
            .create("nodes")
            .map_err(|e| h5err(path, "create group nodes", e))?;
        ds.write_slice(nodes, ndarray::s![*offset..*offset + nodes.len()])
            .map_err(|e| h5err(path, "write group nodes", e))?;
    }
    Ok(())
}

struct ContactDatasets {
    pressure: Dataset,
    force: Dataset,
    gap: Dataset,
    active: Dataset,
    active_set_size: Dataset,
    iterations: Dataset,
    /// `[steps + 1, contact nodes, dim]`: `-p_q n_q`, and `[steps + 1]`: the active weights.
    traction: Dataset,
    area: Dataset,
    /// With friction: `tangential_traction` and `slip` `[steps + 1, contact nodes, dim]`,
    /// `state` `[steps + 1, contact nodes]`.
    friction: Option<[Dataset; 3]>,
    dim: usize,
    /// Boundary weights `D_qq`: the pressure written is `force / weight`.
    weights: Vec<f64>,
    n_written: usize,
}

/// Which fields are written, and how often.
#[derive(Debug, Clone)]
pub struct OutputPlan {
    pub fields: Vec<PlannedField>,
    /// Extra steps to write every field at (from the scene's output.times).
    pub time_steps: Vec<usize>,
    /// Deflate level for the fields (one rank only).
    pub compression: Option<u8>,
}

impl OutputPlan {
    /// Which fields (in plan order) are written at `step`.
    pub fn due_fields(&self, step: usize) -> Vec<bool> {
        let extra = self.time_steps.binary_search(&step).is_ok();
        self.fields.iter().map(|f| step % f.every == 0 || extra).collect()
    }
}

/// One field's datasets: values [T, nodes or cells, components] and its own step and time axes.
struct FieldSet {
    spec: FieldSpec,
    values: Dataset,
    step: Dataset,
    time: Dataset,
    written: usize,
}

pub struct Output {
    path: PathBuf,
    run_file: RunFile,
    file: File,
    dim: usize,
    range: (usize, usize),
    rank: usize,
    plan: OutputPlan,
    time: Dataset,
    step: Dataset,
    fields: Vec<FieldSet>,
    /// The series of `layout::ENERGY_SERIES`, in that order.
    energy: Vec<Dataset>,
    contact: Option<ContactDatasets>,
    /// `newton/iterations`, per step beside `/energy` (finite strain; created on first use).
    newton: Option<Dataset>,
    n_fields_written: usize,
    n_energies_written: usize,
    n_nodes: usize,
    checkpoint: Option<([Dataset; 3], Dataset, Dataset)>,
    /// For the XDMF index: cell kinds and counts, times of written fields.
    cell_kinds: Vec<(crate::mesh::ElementKind, usize)>,
    /// (time, row of each field written then) of each written step.
    field_times: Vec<(f64, Vec<Option<usize>>)>,
    /// This rank's block of natural cells (for cell fields).
    cell_range: (usize, usize),
    /// The reference coordinates of this rank's natural nodes, kept when the plan writes
    /// [`layout::POSITION`].
    reference: Vec<[f64; 3]>,
}

const CHECKPOINT_SCALARS: usize = 12;

/// The scalars of a checkpoint: the step reached and the running totals of the energy balance.
#[derive(Debug, Clone, Default)]
pub struct Checkpoint {
    pub step: usize,
    pub time: f64,
    pub energy_initial: f64,
    pub external_work: f64,
    pub contact_work: f64,
    pub dirichlet_work: f64,
    pub momentum_initial: [f64; 3],
    pub ksp_iterations: usize,
    /// The contact work the massless DOFs' energy correction still has to put back
    /// (`time::Corrections::pending`; 0 in a checkpoint written before it was kept).
    pub pending_correction: f64,
    /// The frictional dissipation so far (0 in a checkpoint written before it was kept).
    pub friction_dissipation: f64,
    /// The active set after the step (contact scenes).
    pub active: Vec<bool>,
}

impl Checkpoint {
    fn scalars(&self) -> Vec<f64> {
        vec![
            self.step as f64,
            self.time,
            self.energy_initial,
            self.external_work,
            self.contact_work,
            self.dirichlet_work,
            self.momentum_initial[0],
            self.momentum_initial[1],
            self.momentum_initial[2],
            self.ksp_iterations as f64,
            self.pending_correction,
            self.friction_dissipation,
        ]
    }
}

/// Read the checkpoint of a run: the scalars, the active set, and this rank's natural block
/// of u, v and du. Collective open (MPI-IO), independent reads.
pub fn read_checkpoint(
    path: &Path,
    world: &mpi::topology::SimpleCommunicator,
    range: (usize, usize),
    n_nodes: usize,
    dim: usize,
) -> Result<(Checkpoint, [Vec<f64>; 3])> {
    let comm = world.as_raw();
    let file = File::with_options()
        .with_fapl(|p| p.mpio(comm, None))
        .open(path)
        .map_err(|e| h5err(path, "open for restart", e))?;
    let g = file.group(layout::CHECKPOINT).map_err(|_| {
        Error::Io(format!(
            "{}: no checkpoint to restart from (was output written?)",
            path.display()
        ))
    })?;
    let sc = g
        .dataset("scalars")
        .and_then(|d| d.read_raw::<f64>())
        .map_err(|e| h5err(path, "read /checkpoint/scalars", e))?;
    let active: Vec<bool> = g
        .dataset("active")
        .and_then(|d| d.read_raw::<u8>())
        .map_err(|e| h5err(path, "read /checkpoint/active", e))?
        .into_iter()
        .map(|a| a == 1)
        .collect();
    let (lo, hi) = range;
    let mut fields = [Vec::new(), Vec::new(), Vec::new()];
    for (i, name) in layout::CHECKPOINT_STATE.iter().enumerate() {
        let ds =
            g.dataset(name).map_err(|e| h5err(path, &format!("open /checkpoint/{name}"), e))?;
        if ds.shape() != [n_nodes, dim] {
            return Err(Error::Io(format!(
                "{}: /checkpoint/{name} has shape {:?}, but this scene's mesh has {n_nodes} nodes in {dim}D: restart with the same scene and mesh",
                path.display(),
                ds.shape()
            )));
        }
        let a: ndarray::Array2<f64> = ds
            .read_slice(ndarray::s![lo..hi, ..])
            .map_err(|e| h5err(path, &format!("read /checkpoint/{name}"), e))?;
        fields[i] = a.into_raw_vec_and_offset().0;
    }
    let cp = Checkpoint {
        step: sc[0] as usize,
        time: sc[1],
        energy_initial: sc[2],
        external_work: sc[3],
        contact_work: sc[4],
        dirichlet_work: sc[5],
        momentum_initial: [sc[6], sc[7], sc[8]],
        ksp_iterations: sc[9] as usize,
        // Files written before the pending correction was kept have 10 scalars.
        pending_correction: sc.get(10).copied().unwrap_or(0.0),
        friction_dissipation: sc.get(11).copied().unwrap_or(0.0),
        active,
    };
    Ok((cp, fields))
}

impl Output {
    /// Open the run file in parallel on all ranks of `world` (MPI-IO; a serial handle for a
    /// compressed one-rank run) and write the mesh; create the time series. Collective. The
    /// groups that carry metadata (`/mesh/groups/<name>`, `/contact`) were made by
    /// `RunFile::write_meta` before; this handle writes datasets only.
    pub fn open(
        run_file: RunFile,
        world: &mpi::topology::SimpleCommunicator,
        mesh: &MeshBlocks,
        plan: OutputPlan,
    ) -> Result<Output> {
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let path = run_file.path();
        // Deflate needs collective parallel I/O, which the HDF5 binding does not expose: it is
        // offered on one rank, where the file is written without MPI-IO.
        if plan.compression.is_some() && size > 1 {
            return Err(Error::Scene(format!(
                "output.compression works on one rank only (parallel HDF5 filters need collective writes); this run has {size} ranks"
            )));
        }
        // Every dataset below is created collectively: all ranks must see the same layout. A
        // disagreement is a bug; it is reported here instead of hanging in HDF5.
        let kinds_count: Vec<usize> = mesh.kinds.iter().fold(vec![0; 8], |mut v, &(k, n)| {
            v[k.gmsh_type() as usize % 8] += n;
            v
        });
        let n_cells = mesh.n_cells();
        agreed_layout(
            world,
            &[
                [mesh.n_nodes, mesh.dim, n_cells, mesh.groups.len()].as_slice(),
                &kinds_count,
                &mesh.groups.iter().map(|g| g.3).collect::<Vec<_>>(),
                &plan.fields.iter().map(|f| f.every * 4 + f.spec.components).collect::<Vec<_>>(),
            ]
            .concat(),
            path,
        )?;
        let comm = world.as_raw();
        let file = if plan.compression.is_some() {
            File::open_rw(path).map_err(|e| h5err(path, "open", e))?
        } else {
            File::with_options()
                .with_fapl(|p| p.mpio(comm, None).fclose_degree(FileCloseDegree::Strong))
                .open_rw(path)
                .map_err(|e| h5err(path, "open in parallel", e))?
        };
        let path_buf = path.to_path_buf();
        let path = path_buf.as_path();
        let dim = mesh.dim;
        let n = mesh.n_nodes;
        let range = natural_range(n, rank, size);
        let cell_range = natural_range(n_cells, rank, size);
        write_mesh(&file, mesh, range, cell_range, path)?;

        let resizable_1d = |name: &str| -> Result<Dataset> {
            file.new_dataset::<f64>()
                .chunk((1024,))
                .shape((0..,))
                .create(name)
                .map_err(|e| h5err(path, &format!("create {name}"), e))
        };
        let time = resizable_1d(layout::TIME)?;
        let step = resizable_1d(layout::STEP)?;
        let fg = group(&file, layout::FIELDS, path)?;
        let field = |spec: &FieldSpec| -> Result<FieldSet> {
            let (name, c) = (spec.name.as_str(), spec.components);
            let rows = match spec.location {
                Location::Nodal => n,
                Location::Cell => n_cells,
            };
            let mut b = fg.new_dataset::<f64>();
            // One chunk per written step: every rank writes its block into the same chunk, so
            // all ranks make the same chunk-index lookups (see the module doc).
            b = b.chunk((1, rows.max(1), c));
            if let Some(level) = plan.compression {
                b = b.deflate(level);
            }
            let values = b
                .shape((0.., rows, c))
                .create(name)
                .map_err(|e| h5err(path, &format!("create /fields/{name}"), e))?;
            Ok(FieldSet {
                spec: spec.clone(),
                values,
                step: resizable_1d(&layout::field_step(name))?,
                time: resizable_1d(&layout::field_time(name))?,
                written: 0,
            })
        };
        let fields = plan.fields.iter().map(|f| field(&f.spec)).collect::<Result<Vec<_>>>()?;
        let plan_has_position = plan.fields.iter().any(|f| f.spec.name == layout::POSITION);
        group(&file, "energy", path)?;
        let energy = layout::ENERGY_SERIES
            .map(|name| resizable_1d(&layout::energy(name)))
            .into_iter()
            .collect::<Result<Vec<_>>>()?;

        file.flush().map_err(|e| h5err(path, "flush", e))?;

        Ok(Output {
            path: path.to_path_buf(),
            run_file,
            file,
            dim,
            range,
            rank,
            plan,
            time,
            step,
            fields,
            energy,
            contact: None,
            newton: None,
            n_fields_written: 0,
            n_energies_written: 0,
            n_nodes: n,
            checkpoint: None,
            cell_kinds: mesh.kinds.clone(),
            field_times: Vec::new(),
            cell_range,
            reference: if plan_has_position { mesh.coords.clone() } else { Vec::new() },
        })
    }

    /// This rank's block of [`layout::POSITION`], `X + u`, from its block of the displacement
    /// (`dim` components a node).
    pub fn position_block(&self, u: &[f64]) -> Vec<f64> {
        let dim = self.dim;
        let mut x = Vec::with_capacity(self.reference.len() * 3);
        for (p, ui) in self.reference.iter().zip(u.chunks(dim)) {
            x.extend((0..3).map(|i| p[i] + ui.get(i).copied().unwrap_or(0.0)));
        }
        x
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
    /// This rank's block of natural nodes.
    pub fn natural_range(&self) -> (usize, usize) {
        self.range
    }
    /// The fields of the plan, in order.
    pub fn field_specs(&self) -> impl Iterator<Item = &FieldSpec> {
        self.fields.iter().map(|f| &f.spec)
    }

    /// Which fields (in plan order) are written at `step`.
    pub fn due_fields(&self, step: usize) -> Vec<bool> {
        self.plan.due_fields(step)
    }

    /// This rank's block of the natural nodes or cells a field of `location` is written in.
    pub fn block(&self, location: Location) -> (usize, usize) {
        match location {
            Location::Nodal => self.range,
            Location::Cell => self.cell_range,
        }
    }

    /// Write the fields of one step: `blocks[i]` is this rank's block (see [`Output::block`],
    /// components interlaced) of the i-th field of the plan, `None` when it is not written now.
    /// Collective.
    pub fn write_fields(&mut self, step: usize, t: f64, blocks: &[Option<Vec<f64>>]) -> Result<()> {
        let k = self.n_fields_written;
        let path = self.path.clone();
        let mut rows = vec![None; self.fields.len()];
        for (i, data) in blocks.iter().enumerate() {
            let Some(data) = data else { continue };
            let (lo, hi) = self.block(self.fields[i].spec.location);
            let set = &mut self.fields[i];
            let (name, c) = (set.spec.name.as_str(), set.spec.components);
            let r = set.written;
            let n = set.values.shape()[1];
            set.values
                .resize((r + 1, n, c))
                .map_err(|e| h5err(&path, &format!("resize /fields/{name}"), e))?;
            let arr = ndarray::Array3::from_shape_vec((1, hi - lo, c), data.to_vec())
                .map_err(|_| Error::Io(format!("{name}: block size mismatch")))?;
            set.values
                .write_slice(&arr, ndarray::s![r..r + 1, lo..hi, ..])
                .map_err(|e| h5err(&path, &format!("write /fields/{name}"), e))?;
            for (ds, val) in [(&set.step, step as f64), (&set.time, t)] {
                append_replicated(ds, r, val, &path, "a field axis")?;
            }
            set.written += 1;
            rows[i] = Some(r);
        }
        // /time and /step: every step at which some field was written.
        for (ds, val, name) in [(&self.time, t, "time"), (&self.step, step as f64, "step")] {
            append_replicated(ds, k, val, &path, name)?;
        }
        self.n_fields_written += 1;
        self.field_times.push((t, rows));
        self.file.flush().map_err(|e| h5err(&path, "flush", e))
    }

    /// Append one step's energies. Collective (resizing is), rank 0 writes.
    pub fn write_energy(&mut self, step: usize, t: f64, e: &Energy) -> Result<()> {
        let k = self.n_energies_written;
        let vals = [
            step as f64,
            t,
            e.kinetic,
            e.potential,
            e.kinetic + e.potential,
            e.external_work,
            e.contact_work,
            e.dirichlet_work,
            e.friction_dissipation,
        ];
        for (ds, val) in self.energy.iter().zip(vals) {
            append_replicated(ds, k, val, &self.path, "/energy")?;
        }
        self.n_energies_written += 1;
        Ok(())
    }

    /// The Newton iterations of the step whose energies were written last, in
    /// `newton/iterations` (the same rows as `/energy`). Collective: every rank calls it for
    /// the same steps (finite-strain runs, every step).
    pub fn write_newton(&mut self, iterations: usize) -> Result<()> {
        let path = self.path.clone();
        if self.newton.is_none() {
            let g = group(&self.file, layout::NEWTON, &path)?;
            let ds = g
                .new_dataset::<f64>()
                .chunk((1024,))
                .shape((0..,))
                .create("iterations")
                .map_err(|e| h5err(&path, "create /newton/iterations", e))?;
            self.newton = Some(ds);
        }
        let ds = self.newton.as_ref().expect("created above");
        let k = self.n_energies_written.saturating_sub(1);
        append_replicated(ds, k, iterations as f64, &path, "/newton/iterations")
    }

    /// The mass matrix's diagnostics: `/mass/{total_mass,first_moment,second_moment}` [dim] and
    /// `/mass/probe` [nodes, dim] (`M r`, r_i = sin(i+1) in natural DOF order). Collective.
    pub fn write_mass_check(
        &mut self,
        total: &[f64],
        first: &[f64],
        second: &[f64],
        probe: &[f64],
    ) -> Result<()> {
        let path = self.path.clone();
        let g =
            self.file.create_group(layout::MASS).map_err(|e| h5err(&path, "create /mass", e))?;
        for (name, vals) in
            [("total_mass", total), ("first_moment", first), ("second_moment", second)]
        {
            let ds = g
                .new_dataset::<f64>()
                .shape((vals.len(),))
                .create(name)
                .map_err(|e| h5err(&path, &format!("create /mass/{name}"), e))?;
            if self.rank == 0 {
                ds.write(vals).map_err(|e| h5err(&path, &format!("write /mass/{name}"), e))?;
            }
        }
        let nodes = self.n_nodes;
        let ds = g
            .new_dataset::<f64>()
            .shape((nodes, self.dim))
            .create("probe")
            .map_err(|e| h5err(&path, "create /mass/probe", e))?;
        let (lo, hi) = self.range;
        let arr = ndarray::Array2::from_shape_vec((hi - lo, self.dim), probe.to_vec())
            .map_err(|_| Error::Io("probe: block size mismatch".into()))?;
        ds.write_slice(&arr, ndarray::s![lo..hi, ..])
            .map_err(|e| h5err(&path, "write /mass/probe", e))?;
        Ok(())
    }

    /// Create `/contact`: `nodes` (0-based rows of /mesh/coordinates), `weights` (boundary
    /// weights D_qq), and per step `pressure`, `force`, `gap`, `active` [steps + 1, contact
    /// nodes], `active_set_size`, `iterations` [steps + 1]; with `friction` also
    /// `tangential_traction`, `slip` [steps + 1, contact nodes, dim] and `state` [steps + 1,
    /// contact nodes] (0 inactive, 1 stick, 2 slip). Collective.
    pub fn create_contact(
        &mut self,
        nodes: &[usize],
        weights: &[f64],
        dim: usize,
        friction: bool,
    ) -> Result<()> {
        let path = self.path.clone();
        let g = group(&self.file, layout::CONTACT, &path)?;
        let nc = nodes.len();
        let nodes_ds = g
            .new_dataset::<u64>()
            .shape((nc,))
            .create("nodes")
            .map_err(|e| h5err(&path, "create /contact/nodes", e))?;
        let w_ds = g
            .new_dataset::<f64>()
            .shape((nc,))
            .create("weights")
            .map_err(|e| h5err(&path, "create /contact/weights", e))?;
        if self.rank == 0 {
            let n64: Vec<u64> = nodes.iter().map(|&v| v as u64).collect();
            nodes_ds.write(&n64).map_err(|e| h5err(&path, "write /contact/nodes", e))?;
            w_ds.write(weights).map_err(|e| h5err(&path, "write /contact/weights", e))?;
        }
        let per_node = |name: &str| -> Result<Dataset> {
            g.new_dataset::<f64>()
                .chunk((64, nc.max(1)))
                .shape((0.., nc))
                .create(name)
                .map_err(|e| h5err(&path, &format!("create /contact/{name}"), e))
        };
        let per_step = |name: &str| -> Result<Dataset> {
            g.new_dataset::<f64>()
                .chunk((1024,))
                .shape((0..,))
                .create(name)
                .map_err(|e| h5err(&path, &format!("create /contact/{name}"), e))
        };
        let vector = |name: &str| -> Result<Dataset> {
            g.new_dataset::<f64>()
                .chunk((64, nc.max(1), dim))
                .shape((0.., nc, dim))
                .create(name)
                .map_err(|e| h5err(&path, &format!("create /contact/{name}"), e))
        };
        let friction = if friction {
            let state = g
                .new_dataset::<u8>()
                .chunk((64, nc.max(1)))
                .shape((0.., nc))
                .create(layout::CONTACT_STATE)
                .map_err(|e| h5err(&path, "create /contact/state", e))?;
            Some([vector(layout::CONTACT_TANGENTIAL)?, vector(layout::CONTACT_SLIP)?, state])
        } else {
            None
        };
        self.contact = Some(ContactDatasets {
            friction,
            pressure: per_node("pressure")?,
            force: per_node("force")?,
            gap: per_node("gap")?,
            active: g
                .new_dataset::<u8>()
                .chunk((64, nc.max(1)))
                .shape((0.., nc))
                .create("active")
                .map_err(|e| h5err(&path, "create /contact/active", e))?,
            active_set_size: per_step("active_set_size")?,
            iterations: per_step("iterations")?,
            traction: g
                .new_dataset::<f64>()
                .chunk((64, nc.max(1), dim))
                .shape((0.., nc, dim))
                .create("traction")
                .map_err(|e| h5err(&path, "create /contact/traction", e))?,
            area: per_step("area")?,
            dim,
            weights: weights.to_vec(),
            n_written: 0,
        });
        Ok(())
    }

    /// `/contact/master_nodes` of a slave/master pair: the master group's nodes (0-based rows
    /// of /mesh/coordinates; `/contact/nodes` holds the slave nodes). Collective: every rank
    /// creates the dataset with the same shape (checked), rank 0 writes its values into the
    /// contiguous dataset (no metadata touched). Every rank holds the whole mesh and scene, so
    /// the group's nodes are the same list on every rank; only rank 0's reach the file anyway.
    pub fn create_contact_pair(
        &mut self,
        world: &mpi::topology::SimpleCommunicator,
        master_nodes: &[usize],
    ) -> Result<()> {
        let path = self.path.clone();
        agreed_layout(world, &[master_nodes.len()], &path)?;
        group(&self.file, layout::CONTACT, &path)?;
        let ds = (self.file.new_dataset::<u64>())
            .shape((master_nodes.len(),))
            .create(layout::CONTACT_MASTER_NODES)
            .map_err(|e| h5err(&path, &format!("create /{}", layout::CONTACT_MASTER_NODES), e))?;
        if self.rank == 0 {
            let n64: Vec<u64> = master_nodes.iter().map(|&v| v as u64).collect();
            ds.write(&n64).map_err(|e| {
                h5err(&path, &format!("write /{}", layout::CONTACT_MASTER_NODES), e)
            })?;
        }
        Ok(())
    }

    /// Append one step's contact data (`normals`: the contact nodes' normals of the step, from
    /// the body towards the obstacle or master side). Collective (resizing), rank 0 writes.
    pub fn write_contact(&mut self, row: &ContactRow, normals: &[[f64; 3]]) -> Result<()> {
        let path = self.path.clone();
        let Some(c) = self.contact.as_mut() else { return Ok(()) };
        let k = c.n_written;
        let nc = row.force.len();
        let pressure = row.pressure(&c.weights);
        for (ds, vals, name) in [
            (&c.pressure, &pressure[..], "pressure"),
            (&c.force, &row.force[..], "force"),
            (&c.gap, &row.gap[..], "gap"),
        ] {
            ds.resize((k + 1, nc))
                .map_err(|e| h5err(&path, &format!("resize /contact/{name}"), e))?;
            let arr = ndarray::Array2::from_shape_vec((1, nc), vals.to_vec()).expect("shape");
            ds.write_slice(&arr, ndarray::s![k..k + 1, ..])
                .map_err(|e| h5err(&path, &format!("write /contact/{name}"), e))?;
        }
        c.active.resize((k + 1, nc)).map_err(|e| h5err(&path, "resize /contact/active", e))?;
        let act: Vec<u8> = row.active.iter().map(|&a| u8::from(a)).collect();
        let arr = ndarray::Array2::from_shape_vec((1, nc), act).expect("shape");
        c.active
            .write_slice(&arr, ndarray::s![k..k + 1, ..])
            .map_err(|e| h5err(&path, "write /contact/active", e))?;
        // The traction on the body, -p_q n_q (a node's normal is zero before its first step).
        let dim = c.dim;
        let traction = row.traction(&c.weights, normals, dim);
        c.traction
            .resize((k + 1, nc, dim))
            .map_err(|e| h5err(&path, "resize /contact/traction", e))?;
        let arr = ndarray::Array3::from_shape_vec((1, nc, dim), traction).expect("shape");
        c.traction
            .write_slice(&arr, ndarray::s![k..k + 1, .., ..])
            .map_err(|e| h5err(&path, "write /contact/traction", e))?;
        if let Some([tangential, slip, state]) = &c.friction {
            // The first row (the start) has no friction data: zeros.
            let or_zero = |v: Vec<f64>| if v.is_empty() { vec![0.0; nc * dim] } else { v };
            let t = or_zero(row.tangential_traction(&c.weights, dim));
            let s = or_zero(row.slip.iter().flat_map(|s| s[..dim].to_vec()).collect());
            for (ds, vals, name) in [(tangential, t, "tangential_traction"), (slip, s, "slip")] {
                ds.resize((k + 1, nc, dim))
                    .map_err(|e| h5err(&path, &format!("resize /contact/{name}"), e))?;
                let arr = ndarray::Array3::from_shape_vec((1, nc, dim), vals).expect("shape");
                ds.write_slice(&arr, ndarray::s![k..k + 1, .., ..])
                    .map_err(|e| h5err(&path, &format!("write /contact/{name}"), e))?;
            }
            let st = if row.state.is_empty() { vec![0u8; nc] } else { row.state.clone() };
            state.resize((k + 1, nc)).map_err(|e| h5err(&path, "resize /contact/state", e))?;
            let arr = ndarray::Array2::from_shape_vec((1, nc), st).expect("shape");
            state
                .write_slice(&arr, ndarray::s![k..k + 1, ..])
                .map_err(|e| h5err(&path, "write /contact/state", e))?;
        }
        let size = row.active.iter().filter(|&&a| a).count() as f64;
        let area: f64 =
            (row.active.iter().zip(&c.weights)).filter(|(a, _)| **a).map(|(_, w)| w).sum();
        for (ds, val, name) in [
            (&c.active_set_size, size, "active_set_size"),
            (&c.iterations, row.iterations as f64, "iterations"),
            (&c.area, area, "area"),
        ] {
            append_replicated(ds, k, val, &path, name)?;
        }
        c.n_written += 1;
        Ok(())
    }

    /// The checkpoint: `/checkpoint/{u,v,du}` [nodes, dim] (natural order, overwritten in
    /// place) and its scalars as attributes. Everything a restart needs to continue the run
    /// exactly. Collective.
    pub fn write_checkpoint(
        &mut self,
        cp: &Checkpoint,
        u: &[f64],
        v: &[f64],
        du: &[f64],
    ) -> Result<()> {
        let path = self.path.clone();
        if self.checkpoint.is_none() {
            let g = self
                .file
                .create_group(layout::CHECKPOINT)
                .map_err(|e| h5err(&path, "create /checkpoint", e))?;
            let mk = |name: &str| -> Result<Dataset> {
                g.new_dataset::<f64>()
                    .shape((self.n_nodes, self.dim))
                    .create(name)
                    .map_err(|e| h5err(&path, &format!("create /checkpoint/{name}"), e))
            };
            let [u, v, du] = layout::CHECKPOINT_STATE;
            let ds = [mk(u)?, mk(v)?, mk(du)?];
            let scalars = g
                .new_dataset::<f64>()
                .shape((CHECKPOINT_SCALARS,))
                .create("scalars")
                .map_err(|e| h5err(&path, "create /checkpoint/scalars", e))?;
            let active = g
                .new_dataset::<u8>()
                .shape((cp.active.len(),))
                .create("active")
                .map_err(|e| h5err(&path, "create /checkpoint/active", e))?;
            self.checkpoint = Some((ds, scalars, active));
        }
        let (ds, scalars, active) = self.checkpoint.as_ref().expect("checkpoint datasets");
        let (lo, hi) = self.range;
        for (d, data) in ds.iter().zip([u, v, du]) {
            let arr = ndarray::Array2::from_shape_vec((hi - lo, self.dim), data.to_vec())
                .map_err(|_| Error::Io("checkpoint: block size mismatch".into()))?;
            d.write_slice(&arr, ndarray::s![lo..hi, ..])
                .map_err(|e| h5err(&path, "write /checkpoint", e))?;
        }
        if self.rank == 0 {
            scalars
                .write(&cp.scalars())
                .map_err(|e| h5err(&path, "write /checkpoint/scalars", e))?;
            let act: Vec<u8> = cp.active.iter().map(|&a| u8::from(a)).collect();
            active.write(&act).map_err(|e| h5err(&path, "write /checkpoint/active", e))?;
        }
        self.file.flush().map_err(|e| h5err(&path, "flush", e))
    }

    /// End the run's file: flush and close the parallel handle, then write the final metadata
    /// (`status`: "finished", "failed: message", "interrupted: ..."; summary, timings) through
    /// the serial handle of rank 0, and the XDMF index beside the file. Collective.
    pub fn finish(self, world: &mpi::topology::SimpleCommunicator, items: &[Meta]) -> Result<()> {
        let name =
            self.path.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        let fields: Vec<(FieldSpec, usize)> =
            self.fields.iter().map(|f| (f.spec.clone(), f.written)).collect();
        let (rank, n_nodes, dim) = (self.rank, self.n_nodes, self.dim);
        let (cells, steps) = (self.cell_kinds.clone(), self.field_times.clone());
        let (h5_path, xdmf_path) = (self.path.clone(), self.xdmf_path());
        let run_file = self.close()?;
        run_file.write_meta(world, items)?;
        let mut outcome = Ok(());
        if rank == 0 {
            // Serial, with no parallel handle open (like the metadata): the index's views.
            outcome = xdmf::write_xdmf(
                &h5_path,
                &xdmf_path,
                &xdmf::XdmfLayout {
                    h5_name: &name,
                    n_nodes,
                    dim,
                    cells: &cells,
                    steps: &steps,
                    fields: &fields,
                },
            );
        }
        meta::agree(world, outcome)
    }

    /// Flush and close the parallel handle (collective); the file can then take metadata.
    pub fn close(self) -> Result<RunFile> {
        let Output { file, run_file, path, .. } = self;
        // The datasets were dropped with the rest of `self`; the file goes last.
        file.flush().map_err(|e| h5err(&path, "flush", e))?;
        file.close().map_err(|e| h5err(&path, "close", e))?;
        Ok(run_file)
    }

    /// The XDMF file written beside the HDF5 file.
    pub fn xdmf_path(&self) -> PathBuf {
        self.path.with_extension("xdmf")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{Element, ElementKind, Mesh};

    #[test]
    fn natural_cells_follow_the_files_kind_order() {
        // Mesh order: quad, tri, quad, tri, tri; the file stores triangles (gmsh 2) first.
        let q = |t| Element::new(ElementKind::Quad4, &[0, 1, 2, 3], t, 1);
        let t = |t| Element::new(ElementKind::Tri3, &[0, 1, 2], t, 1);
        let mesh = Mesh {
            dim: 2,
            coords: vec![[0.0; 3]; 4],
            node_tags: vec![1, 2, 3, 4],
            cells: vec![q(1), t(2), q(3), t(4), t(5)],
            boundary: vec![],
            groups: vec![],
        };
        assert_eq!(file_cell_kinds(&mesh), vec![ElementKind::Tri3, ElementKind::Quad4]);
        assert_eq!(natural_cell_index(&mesh), vec![3, 0, 4, 1, 2]);
    }
}
