//! Post-processing: plots of a run's energies and contact histories.

pub mod plot;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use plot::{line_plot, stacked_plots, Plot, Series};

/// The histories a run's pictures are drawn from.
#[derive(Debug, Clone, Default)]
pub struct RunCurves {
    pub label: String,
    pub time: Vec<f64>,
    pub kinetic: Vec<f64>,
    pub potential: Vec<f64>,
    /// Contact pressure of the lowest contact node (empty without contact).
    pub lowest_pressure: Vec<f64>,
}

impl RunCurves {
    fn series(&self, ys: &[f64], name: &str) -> Series {
        Series {
            name: name.to_string(),
            points: self.time.iter().copied().zip(ys.iter().copied()).collect(),
        }
    }
    fn total(&self) -> Vec<f64> {
        self.kinetic.iter().zip(&self.potential).map(|(k, p)| k + p).collect()
    }
}

/// The files `write_pictures` writes for one run (with or without contact).
pub fn picture_paths(prefix: &Path, contact: bool) -> Vec<PathBuf> {
    let with_suffix = |s: &str| {
        let mut p = prefix.as_os_str().to_owned();
        p.push(s);
        PathBuf::from(p)
    };
    let mut v = vec![with_suffix("-energy.png")];
    if contact {
        v.push(with_suffix("-pressure.png"));
    }
    v
}

/// `<out>-energy.png` (kinetic, potential, total; one curve per run) and, when the runs have
/// contact, `<out>-pressure.png` (the lowest contact node's pressure). Returns the files written.
pub fn write_pictures(prefix: &Path, runs: &[RunCurves]) -> Result<Vec<PathBuf>> {
    let with_suffix = |s: &str| {
        let mut p = prefix.as_os_str().to_owned();
        p.push(s);
        PathBuf::from(p)
    };
    let mut written = Vec::new();
    let kin: Vec<Series> = runs.iter().map(|r| r.series(&r.kinetic, &r.label)).collect();
    let pot: Vec<Series> = runs.iter().map(|r| r.series(&r.potential, &r.label)).collect();
    let tot: Vec<Series> = runs.iter().map(|r| r.series(&r.total(), &r.label)).collect();
    let panel = |title, y_label, series| Plot {
        title,
        x_label: "time",
        y_label,
        series,
        width: 1000,
        height: 320,
    };
    let energy = with_suffix("-energy.png");
    stacked_plots(
        &energy,
        "Energies",
        &[
            panel("kinetic energy", "kinetic", &kin),
            panel("potential energy", "potential", &pot),
            panel("total energy", "total", &tot),
        ],
    )?;
    written.push(energy);
    if runs.iter().any(|r| !r.lowest_pressure.is_empty()) {
        let ps: Vec<Series> = runs
            .iter()
            .filter(|r| !r.lowest_pressure.is_empty())
            .map(|r| r.series(&r.lowest_pressure, &r.label))
            .collect();
        let path = with_suffix("-pressure.png");
        if ps.len() == 1 {
            line_plot(
                &path,
                &Plot {
                    title: "Contact pressure at the lowest contact node",
                    x_label: "time",
                    y_label: "pressure",
                    series: &ps,
                    width: 1000,
                    height: 500,
                },
            )?;
        } else {
            // One panel per run on a shared time axis: a chattering curve would hide the others.
            let panels: Vec<Plot> = ps
                .iter()
                .map(|s| Plot {
                    title: &s.name,
                    x_label: "time",
                    y_label: "pressure",
                    series: std::slice::from_ref(s),
                    width: 1000,
                    height: 260,
                })
                .collect();
            stacked_plots(&path, "Contact pressure at the lowest contact node", &panels)?;
        }
        written.push(path);
    }
    Ok(written)
}

fn h5(path: &Path, what: &str, e: hdf5::Error) -> Error {
    Error::Io(format!("{}: {what}: {e}", path.display()))
}

/// Read the curves of a finished (or interrupted) run from its HDF5 file.
pub fn read_curves(path: &Path) -> Result<RunCurves> {
    let file = hdf5::File::open(path).map_err(|e| h5(path, "open", e))?;
    let read = |name: &str| -> Result<Vec<f64>> {
        file.dataset(name)
            .and_then(|d| d.read_raw::<f64>())
            .map_err(|e| h5(path, &format!("read {name}"), e))
    };
    let time = read("energy/time")?;
    let kinetic = read("energy/kinetic")?;
    let potential = read("energy/potential")?;
    let settings: String = file
        .attr("settings")
        .and_then(|a| a.read_scalar::<hdf5::types::VarLenUnicode>())
        .map(|s| s.to_string())
        .unwrap_or_default();
    let setting = |key: &str| {
        settings
            .lines()
            .find_map(|l| l.strip_prefix(&format!("{key} = ")).map(str::to_string))
            .unwrap_or_default()
    };
    let mut label = setting("mass");
    let mesh = setting("cells");
    if !mesh.is_empty() {
        label = format!("{label} ({mesh})");
    }
    let mut lowest_pressure = Vec::new();
    if let Ok(ds) = file.dataset("contact/pressure") {
        let p = ds.read_2d::<f64>().map_err(|e| h5(path, "read contact/pressure", e))?;
        // The lowest node: the contact node with the smallest gap... recorded in the summary.
        let summary: String = file
            .attr("summary")
            .and_then(|a| a.read_scalar::<hdf5::types::VarLenUnicode>())
            .map(|s| s.to_string())
            .unwrap_or_default();
        let lowest = summary
            .parse::<toml::Table>()
            .ok()
            .and_then(|t| t.get("contact")?.get("lowest_node")?.as_integer())
            .map(|v| v as u64);
        let nodes = file
            .dataset("contact/nodes")
            .and_then(|d| d.read_raw::<u64>())
            .map_err(|e| h5(path, "read contact/nodes", e))?;
        if let Some(k) = lowest.and_then(|l| nodes.iter().position(|&n| n == l)) {
            lowest_pressure = p.column(k).to_vec();
        }
    }
    Ok(RunCurves { label, time, kinetic, potential, lowest_pressure })
}
