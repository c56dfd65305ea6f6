//! The run file's layout in one place: the dataset names the writer creates and the readers
//! (post, study, restart, tests) open, and [`RunReader`], the serial reader of a run's file.
//! README.md ("Output") documents the same layout for users.

use std::path::{Path, PathBuf};

use hdf5::types::VarLenUnicode;

use crate::error::{Error, Result};
use crate::fem::element::ElementKind;

pub const COORDINATES: &str = "mesh/coordinates";
pub const NODE_TAGS: &str = "mesh/node_tags";
pub const CELL_RANK: &str = "mesh/cell_rank";
pub const CELLS: &str = "mesh/cells";
pub const GROUPS: &str = "mesh/groups";
/// Steps and times at which some field was written.
pub const TIME: &str = "time";
pub const STEP: &str = "step";
pub const FIELDS: &str = "fields";
/// The views the XDMF index reads (`io::xdmf`): `xdmf/<field>/<row>`, a virtual dataset of row
/// `row` of `fields/<field>`, and for meshes with several cell kinds `xdmf/topology`.
pub const XDMF: &str = "xdmf";
pub const XDMF_TOPOLOGY: &str = "xdmf/topology";
/// Finite strain: the nodes' current positions `X + u` (3 components), written with
/// `displacement`; the XDMF index draws each step's mesh at them.
pub const POSITION: &str = "position";
/// The per-step energy series, `energy/<name>`, in the order the writer appends them.
pub const ENERGY_SERIES: [&str; 9] = [
    "step",
    "time",
    "kinetic",
    "potential",
    "total",
    "external_work",
    "contact_work",
    "dirichlet_work",
    "friction_dissipation",
];
/// Finite strain: `newton/iterations` per step, rows as `/energy`'s.
pub const NEWTON: &str = "newton";
pub const NEWTON_ITERATIONS: &str = "newton/iterations";
pub const CONTACT: &str = "contact";
pub const CONTACT_NODES: &str = "contact/nodes";
pub const CONTACT_WEIGHTS: &str = "contact/weights";
/// Attribute of `/contact`: the contact boundary group (the slave group of a pair).
pub const CONTACT_GROUP_ATTR: &str = "group";
/// Attributes of `/contact` for a slave/master pair of bodies (absent with obstacles).
pub const CONTACT_SLAVE_GROUP_ATTR: &str = "slave_group";
pub const CONTACT_MASTER_GROUP_ATTR: &str = "master_group";
/// Attribute of `/contact` for obstacles beside a pair: the group meeting them (its nodes are
/// among `contact/nodes` then, after or between the slave nodes, in mesh order).
pub const CONTACT_OBSTACLE_GROUP_ATTR: &str = "obstacle_group";
/// The master side's nodes of a pair (rows of coordinates, like `contact/nodes`, whose rows
/// are the slave nodes then).
pub const CONTACT_MASTER_NODES: &str = "contact/master_nodes";
/// Per contact node and step.
pub const CONTACT_PER_NODE: [&str; 4] = ["pressure", "force", "gap", "active"];
/// Per step.
pub const CONTACT_PER_STEP: [&str; 3] = ["active_set_size", "iterations", "area"];
/// Per contact node and step, `dim` components: the traction `-p_q n_q` on the body.
pub const CONTACT_TRACTION: &str = "contact/traction";
/// With friction, per contact node and step: the tangential traction on the body `-t_q / D_qq`
/// and the slip increment (`dim` components), and the set (0 inactive, 1 stick, 2 slip).
pub const CONTACT_TANGENTIAL: &str = "tangential_traction";
pub const CONTACT_SLIP: &str = "slip";
pub const CONTACT_STATE: &str = "state";
pub const CHECKPOINT: &str = "checkpoint";
pub const CHECKPOINT_STATE: [&str; 3] = ["u", "v", "du"];
pub const CHECKPOINT_SCALARS: &str = "checkpoint/scalars";
pub const CHECKPOINT_ACTIVE: &str = "checkpoint/active";
pub const MASS: &str = "mass";
/// `M * probe` for the probe vectors of the mass check.
pub const MASS_PROBE: &str = "mass/probe";

/// `energy/<series>`
pub fn energy(series: &str) -> String {
    format!("energy/{series}")
}
/// `fields/<name>`, and its own step and time axes.
pub fn field(name: &str) -> String {
    format!("{FIELDS}/{name}")
}
pub fn field_time(name: &str) -> String {
    format!("{FIELDS}/{name}_time")
}
pub fn field_step(name: &str) -> String {
    format!("{FIELDS}/{name}_step")
}
/// `contact/<name>`
pub fn contact(name: &str) -> String {
    format!("{CONTACT}/{name}")
}

/// A run's file opened for reading (one process, no MPI).
pub struct RunReader {
    pub file: hdf5::File,
    path: PathBuf,
}

impl RunReader {
    pub fn open(path: &Path) -> Result<RunReader> {
        let file = hdf5::File::open(path)
            .map_err(|e| Error::Io(format!("{}: open: {e}", path.display())))?;
        Ok(RunReader { file, path: path.to_path_buf() })
    }

    fn err(&self, what: &str, e: hdf5::Error) -> Error {
        Error::Io(format!("{}: {what}: {e}", self.path.display()))
    }

    /// A text attribute of the root (empty when absent).
    pub fn text(&self, name: &str) -> String {
        self.file
            .attr(name)
            .and_then(|a| a.read_scalar::<VarLenUnicode>())
            .map(|s| s.to_string())
            .unwrap_or_default()
    }

    /// A text attribute of a group (empty when absent).
    pub fn group_text(&self, group: &str, name: &str) -> String {
        self.file
            .group(group)
            .and_then(|g| g.attr(name))
            .and_then(|a| a.read_scalar::<VarLenUnicode>())
            .map(|s| s.to_string())
            .unwrap_or_default()
    }

    /// The slave and master groups of a two-body run (`None` with obstacles or no contact).
    pub fn contact_pair(&self) -> Option<(String, String)> {
        let slave = self.group_text(CONTACT, CONTACT_SLAVE_GROUP_ATTR);
        let master = self.group_text(CONTACT, CONTACT_MASTER_GROUP_ATTR);
        (!slave.is_empty() && !master.is_empty()).then_some((slave, master))
    }

    /// A dataset's values as numbers, flattened.
    pub fn series(&self, name: &str) -> Result<Vec<f64>> {
        self.file
            .dataset(name)
            .and_then(|d| d.read_raw::<f64>())
            .map_err(|e| self.err(&format!("read {name}"), e))
    }

    /// A 2-D dataset (steps x entries).
    pub fn table(&self, name: &str) -> Result<ndarray::Array2<f64>> {
        self.file
            .dataset(name)
            .and_then(|d| d.read_2d::<f64>())
            .map_err(|e| self.err(&format!("read {name}"), e))
    }

    /// The node coordinates (always three per node).
    pub fn coordinates(&self) -> Result<Vec<[f64; 3]>> {
        Ok(self.series(COORDINATES)?.chunks(3).map(|x| [x[0], x[1], x[2]]).collect())
    }

    /// The cells, kind by kind in the writer's order, as 0-based node indices.
    pub fn cells(&self) -> Result<Vec<(ElementKind, Vec<usize>)>> {
        let g = self.file.group(CELLS).map_err(|e| self.err(CELLS, e))?;
        let mut cells = Vec::new();
        for kind in ElementKind::ALL {
            if let Ok(ds) = g.dataset(kind.name()) {
                let conn = ds.read_raw::<u64>().map_err(|e| self.err(kind.name(), e))?;
                for c in conn.chunks(kind.n_nodes()) {
                    cells.push((kind, c.iter().map(|&v| v as usize).collect()));
                }
            }
        }
        Ok(cells)
    }

    /// The values of field `name` written at time `time` (within 1e-9 relative), flattened
    /// (entries x components), and the number of components.
    pub fn field_at(&self, name: &str, time: f64) -> Result<(Vec<f64>, usize)> {
        let times = self.series(&field_time(name)).or_else(|_| self.series(TIME))?;
        let tol = (1e-9 * time.abs()).max(1e-12);
        let k = times.iter().position(|t| (t - time).abs() <= tol).ok_or_else(|| {
            Error::Io(format!("{}: no {name} written at t = {time:e}", self.path.display()))
        })?;
        let path = field(name);
        let d = self.file.dataset(&path).map_err(|e| self.err(&path, e))?;
        let shape = d.shape();
        let (n, comps) = (shape[1], shape[2]);
        let all = d.read_raw::<f64>().map_err(|e| self.err(&format!("read {path}"), e))?;
        Ok((all[k * n * comps..(k + 1) * n * comps].to_vec(), comps))
    }

    /// The names of the fields written (`/fields/<name>`, without their axes).
    pub fn fields(&self) -> Vec<String> {
        let Ok(g) = self.file.group(FIELDS) else { return vec![] };
        let mut names: Vec<String> = g
            .member_names()
            .unwrap_or_default()
            .into_iter()
            .filter(|n| !n.ends_with("_time") && !n.ends_with("_step"))
            .collect();
        names.sort();
        names
    }

    /// The run's summary as TOML text (empty for a run that did not finish; parsed by
    /// `report::RunSummary::read`).
    pub fn summary_text(&self) -> String {
        self.text("summary")
    }

    /// The value of one `settings` line (`key = value`).
    pub fn setting(&self, key: &str) -> String {
        self.text("settings")
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{key} = ")).map(str::to_string))
            .unwrap_or_default()
    }
}
