//! Post-processing: plots of a run's energies and contact histories.

pub mod plot;
pub mod snapshot;

use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::layout::{self, RunReader};
use crate::report::RunSummary;
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

/// `prefix` with `suffix` appended to its file name (`out/disc` + `-energy.png`).
fn suffixed(prefix: &Path, suffix: &str) -> PathBuf {
    let mut p = prefix.as_os_str().to_owned();
    p.push(suffix);
    PathBuf::from(p)
}

/// The files `write_pictures` writes for one run (with or without contact).
pub fn picture_paths(prefix: &Path, contact: bool) -> Vec<PathBuf> {
    let with_suffix = |s: &str| suffixed(prefix, s);
    let mut v = vec![with_suffix("-energy.png")];
    if contact {
        v.push(with_suffix("-pressure.png"));
    }
    v
}

/// `<out>-energy.png` (kinetic, potential, total; one curve per run) and, when the runs have
/// contact, `<out>-pressure.png` (the lowest contact node's pressure). Returns the files written.
pub fn write_pictures(prefix: &Path, runs: &[RunCurves]) -> Result<Vec<PathBuf>> {
    let with_suffix = |s: &str| suffixed(prefix, s);
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
    let run = RunReader::open(path)?;
    let time = run.series(&layout::energy("time"))?;
    let kinetic = run.series(&layout::energy("kinetic"))?;
    let potential = run.series(&layout::energy("potential"))?;
    let mut label = run.setting("mass");
    let mesh = run.setting("cells");
    if !mesh.is_empty() {
        label = format!("{label} ({mesh})");
    }
    let mut lowest_pressure = Vec::new();
    if run.file.dataset(&layout::contact("pressure")).is_ok() {
        let p = run.table(&layout::contact("pressure"))?;
        // The lowest node (closest to the obstacle at t = 0) is recorded in the summary.
        let lowest = RunSummary::read(&run).and_then(|s| s.contact).map(|c| c.lowest_node as f64);
        let nodes = run.series(layout::CONTACT_NODES)?;
        if let Some(k) = lowest.and_then(|l| nodes.iter().position(|&n| n == l)) {
            lowest_pressure = p.column(k).to_vec();
        }
    }
    Ok(RunCurves { label, time, kinetic, potential, lowest_pressure })
}

/// What `massfree post` extracts.
#[derive(Debug, Clone, Default)]
pub struct PostOptions {
    /// Points whose nearest mesh node's field histories are written.
    pub nodes: Vec<[f64; 3]>,
    /// Points whose nearest contact node's pressure/force/gap histories are written.
    pub contact_nodes: Vec<[f64; 3]>,
    /// Nodal fields for the node histories (default: all in the file).
    pub fields: Vec<String>,
    /// Prefix of the files written (default: RUN without .h5, plus "-post").
    pub prefix: Option<PathBuf>,
}

fn nearest(coords: &[f64], candidates: &[usize], p: [f64; 3]) -> usize {
    *candidates
        .iter()
        .min_by(|&&a, &&b| {
            let d = |i: usize| (0..3).map(|c| (coords[3 * i + c] - p[c]).powi(2)).sum::<f64>();
            d(a).total_cmp(&d(b)).then(a.cmp(&b))
        })
        .expect("candidates")
}

fn write_csv(path: &Path, header: &[String], columns: &[Vec<f64>]) -> Result<()> {
    let mut text = header.join(",");
    text.push('\n');
    let rows = columns.iter().map(|c| c.len()).min().unwrap_or(0);
    for r in 0..rows {
        let line: Vec<String> = columns.iter().map(|c| format!("{:e}", c[r])).collect();
        text.push_str(&line.join(","));
        text.push('\n');
    }
    std::fs::write(path, text)
        .map_err(|e| Error::Io(format!("cannot write {}: {e}", path.display())))
}

/// The prefix of `post`'s files for the run `path` when `-o` is not given: RUN without .h5,
/// plus "-post".
pub fn default_prefix(path: &Path) -> PathBuf {
    let mut p = path.with_extension("").into_os_string();
    p.push("-post");
    PathBuf::from(p)
}

/// Summarize a run's HDF5 file and write PNG plots and CSV files of its energies and of the
/// chosen node and contact-node histories. Returns the lines to print.
pub fn post(path: &Path, opts: &PostOptions) -> Result<Vec<String>> {
    let run = RunReader::open(path)?;
    let file = &run.file;
    let read = |name: &str| run.series(name);
    let attr = |name: &str| run.text(name);
    let prefix = opts.prefix.clone().unwrap_or_else(|| default_prefix(path));
    let with_suffix = |s: &str| suffixed(&prefix, s);
    let status = attr("status");
    let Ok(time) = read(&layout::energy("time")) else {
        return Err(Error::Io(format!("{}: no steps written (status: {status})", path.display())));
    };
    let step = read(&layout::energy("step"))?;
    let kinetic = read(&layout::energy("kinetic"))?;
    let potential = read(&layout::energy("potential"))?;
    let total = read(&layout::energy("total"))?;
    let ext = read(&layout::energy("external_work"))?;
    let cw = read(&layout::energy("contact_work")).unwrap_or_else(|_| vec![0.0; total.len()]);
    let dw = read(&layout::energy("dirichlet_work")).unwrap_or_else(|_| vec![0.0; total.len()]);
    // Files written before friction have no dissipation series: nothing dissipated.
    let fd =
        read(&layout::energy("friction_dissipation")).unwrap_or_else(|_| vec![0.0; total.len()]);
    let mut lines = Vec::new();
    let n = total.len();
    if n == 0 {
        return Err(Error::Io(format!("{}: no steps written (status: {status})", path.display())));
    }
    let e0 = total[0];
    let emax = total.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
    let drift = total.iter().map(|e| ((e - e0) / e0).abs()).fold(0.0, f64::max);
    let balance =
        (0..n).map(|i| (total[i] - e0 - ext[i] - cw[i] - dw[i] + fd[i]).abs()).fold(0.0, f64::max)
            / emax;
    if status == "running" {
        // Only a run that was killed (SIGKILL, power loss, a watchdog abort) or is still
        // running leaves this status: every other end is written into the file.
        lines.push(format!(
            "{}: the run did not finish (status still \"running\": killed, or still running): last written step {}",
            path.display(),
            step[n - 1]
        ));
    } else {
        lines.push(format!("{}: status {status}", path.display()));
    }
    lines.push(format!(
        "steps {}..{} (t = {} .. {}), {} written",
        step[0],
        step[n - 1],
        crate::console::time(time[0]),
        crate::console::time(time[n - 1]),
        n
    ));
    lines.push(format!(
        "energy: initial {e0:.10e}, final {:.10e}, drift max |E - E0|/E0 = {drift:.2e}, balance max |E - E0 - W|/max E = {balance:.2e}",
        total[n - 1]
    ));
    let mut written = Vec::new();
    let energy_csv = with_suffix("-energy.csv");
    write_csv(
        &energy_csv,
        // The file's energy series, in its order (the columns below follow it).
        &layout::ENERGY_SERIES.map(String::from),
        &[
            step.clone(),
            time.clone(),
            kinetic.clone(),
            potential.clone(),
            total.clone(),
            ext,
            cw,
            dw,
            fd,
        ],
    )?;
    written.push(energy_csv);
    let coords = read(layout::COORDINATES)?;
    let tags = file
        .dataset(layout::NODE_TAGS)
        .and_then(|d| d.read_raw::<u64>())
        .map_err(|e| h5(path, "read mesh/node_tags", e))?;
    let mut curves = read_curves(path)?;

    // Contact: period, peak pressure, chosen contact nodes.
    if let Ok(ds) = file.dataset(&layout::contact("pressure")) {
        let p = ds.read_2d::<f64>().map_err(|e| h5(path, "read contact/pressure", e))?;
        let f = file
            .dataset(&layout::contact("force"))
            .and_then(|d| d.read_2d::<f64>())
            .map_err(|e| h5(path, "read contact/force", e))?;
        let g = file
            .dataset(&layout::contact("gap"))
            .and_then(|d| d.read_2d::<f64>())
            .map_err(|e| h5(path, "read contact/gap", e))?;
        let a = file
            .dataset(&layout::contact("active"))
            .and_then(|d| d.read_2d::<u8>())
            .map_err(|e| h5(path, "read contact/active", e))?;
        let cn = file
            .dataset(layout::CONTACT_NODES)
            .and_then(|d| d.read_raw::<u64>())
            .map_err(|e| h5(path, "read contact/nodes", e))?;
        let rows = p.nrows().min(n);
        if let Some((slave, master)) = run.contact_pair() {
            let n_master = file.dataset(layout::CONTACT_MASTER_NODES).map_or(0, |d| d.size());
            // Obstacles beside the pair: their group's nodes are among the contact nodes.
            let beside = run.group_text(layout::CONTACT, layout::CONTACT_OBSTACLE_GROUP_ATTR);
            // Several pairs: the groups joined by ", " in pair order.
            let several = slave.contains(", ") || master.contains(", ");
            let (pair, s, m) =
                if several { ("contact pairs", "s", "s") } else { ("contact pair", "", "") };
            let pair = format!("{pair}: slave{s} \"{slave}\"");
            let mut line = if beside.is_empty() {
                format!("{pair} ({} nodes), master{m} \"{master}\" ({n_master} nodes)", cn.len())
            } else {
                format!(
                    "{pair}, master{m} \"{master}\" ({n_master} nodes), obstacles met by \"{beside}\" ({} contact nodes with the slave's)",
                    cn.len()
                )
            };
            // The node whose pressure `compare` draws: the slave node closest to the master.
            if let Some(c) = RunSummary::read(&run).and_then(|s| s.contact) {
                let x = &coords[3 * c.lowest_node..3 * c.lowest_node + 3];
                let at = if x[2] == 0.0 {
                    format!("({}, {})", x[0], x[1])
                } else {
                    format!("({}, {}, {})", x[0], x[1], x[2])
                };
                line.push_str(&format!(
                    "; lowest slave node (closest to the master at t = 0): gmsh node {} at {at}",
                    c.lowest_node_tag
                ));
            }
            lines.push(line);
        }
        let any: Vec<bool> = (0..rows).map(|r| a.row(r).iter().any(|&x| x == 1)).collect();
        match crate::contact::metrics::contact_period(&any) {
            Some((f0, f1)) => {
                let (mut pmax, mut at) = (0.0f64, 0usize);
                for ((r, k), &v) in p.indexed_iter() {
                    if v > pmax {
                        pmax = v;
                        at = k;
                        let _ = r;
                    }
                }
                lines.push(format!(
                    "contact: steps {}..{} (t = {} .. {}), max pressure {pmax:.6e} at gmsh node {}",
                    step[f0],
                    step[f1],
                    crate::console::time(time[f0]),
                    crate::console::time(time[f1]),
                    tags[cn[at] as usize]
                ));
            }
            None => lines.push("contact: none".to_string()),
        }
        let cand: Vec<usize> = cn.iter().map(|&v| v as usize).collect();
        for q in &opts.contact_nodes {
            let node = nearest(&coords, &cand, *q);
            let k = cn.iter().position(|&v| v as usize == node).expect("contact node");
            let tag = tags[node];
            let csv = with_suffix(&format!("-contact-{tag}.csv"));
            let col = |m: &ndarray::Array2<f64>| {
                m.column(k).iter().take(rows).copied().collect::<Vec<f64>>()
            };
            let act: Vec<f64> = a.column(k).iter().take(rows).map(|&x| x as f64).collect();
            write_csv(
                &csv,
                &["step", "time", "pressure", "force", "gap", "active"].map(String::from),
                &[step[..rows].to_vec(), time[..rows].to_vec(), col(&p), col(&f), col(&g), act],
            )?;
            written.push(csv);
            let png = with_suffix(&format!("-contact-{tag}.png"));
            let series = vec![Series {
                name: format!("gmsh node {tag}"),
                points: time.iter().copied().zip(col(&p)).collect(),
            }];
            line_plot(
                &png,
                &Plot {
                    title: "Contact pressure",
                    x_label: "time",
                    y_label: "pressure",
                    series: &series,
                    width: 1000,
                    height: 450,
                },
            )?;
            written.push(png);
        }
    } else if !opts.contact_nodes.is_empty() {
        return Err(Error::Usage(format!(
            "{}: --contact-node given, but the run has no contact",
            path.display()
        )));
    }

    // Node histories of the nodal fields (cell fields, e.g. `stress`, have no node values).
    if !opts.nodes.is_empty() {
        let rows_of = |f: &str| file.dataset(&layout::field(f)).map(|d| d.shape()[1]).ok();
        let available: Vec<String> =
            run.fields().into_iter().filter(|f| rows_of(f) == Some(tags.len())).collect();
        let fields: Vec<String> =
            if opts.fields.is_empty() { available.clone() } else { opts.fields.clone() };
        for f in &fields {
            if !available.contains(f) {
                let what = if rows_of(f).is_some() {
                    format!("a cell field of {}, not a nodal one (try {f}_nodal)", path.display())
                } else {
                    format!("not in {}", path.display())
                };
                return Err(Error::Usage(format!(
                    "--field {f}: {what} (its nodal fields: {})",
                    available.join(", ")
                )));
            }
        }
        let all: Vec<usize> = (0..tags.len()).collect();
        for p in &opts.nodes {
            let node = nearest(&coords, &all, *p);
            let tag = tags[node];
            let mut panels_series = Vec::new();
            for f in &fields {
                // Each field has its own time axis (fields may be written at different periods).
                let ftime = read(&layout::field_time(f)).or_else(|_| read(layout::TIME))?;
                let ds = file.dataset(&layout::field(f)).map_err(|e| h5(path, "open field", e))?;
                let dim = ds.shape()[2];
                // Component names: x, y, z; a symmetric tensor's six (fem::stress::TENSOR6);
                // none for a scalar.
                let comps: Vec<String> = match dim {
                    1 => vec![String::new()],
                    6 => crate::fem::stress::tensor6_names().to_vec(),
                    _ => ["x", "y", "z"][..dim].iter().map(|c| c.to_string()).collect(),
                };
                let a: ndarray::Array3<f64> =
                    ds.read().map_err(|e| h5(path, &format!("read fields/{f}"), e))?;
                let mut header = vec!["time".to_string()];
                let mut cols = vec![ftime.clone()];
                let mut series = Vec::new();
                for c in 0..dim {
                    let v: Vec<f64> = (0..a.shape()[0]).map(|k| a[[k, node, c]]).collect();
                    let comp = &comps[c];
                    let sep = if comp.is_empty() { "" } else { "_" };
                    header.push(format!("{f}{sep}{comp}"));
                    series.push(Series {
                        name: format!("{f} {comp}").trim_end().to_string(),
                        points: ftime.iter().copied().zip(v.iter().copied()).collect(),
                    });
                    cols.push(v);
                }
                let csv = with_suffix(&format!("-node-{tag}-{f}.csv"));
                write_csv(&csv, &header, &cols)?;
                written.push(csv);
                panels_series.push((f.clone(), series));
            }
            let png = with_suffix(&format!("-node-{tag}.png"));
            let panels: Vec<Plot> = panels_series
                .iter()
                .map(|(f, s)| Plot {
                    title: f,
                    x_label: "time",
                    y_label: f,
                    series: s,
                    width: 1000,
                    height: 320,
                })
                .collect();
            stacked_plots(&png, &format!("gmsh node {tag}"), &panels)?;
            written.push(png);
        }
    }
    curves.label = "run".into();
    written.extend(write_pictures(&prefix, &[curves])?);
    for w in &written {
        lines.push(format!("wrote {}", w.display()));
    }
    Ok(lines)
}
