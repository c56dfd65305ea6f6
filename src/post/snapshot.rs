//! Snapshots: one field of a run drawn on its deformed mesh as a PNG picture
//! (`massfree post RUN.h5 --snapshot FIELD`), or of several runs side by side with one colour
//! range (`massfree compare A.h5 B.h5 --snapshot FIELD`).
//!
//! What is drawn:
//! * any dataset of `/fields`: nodal data (second dimension = number of nodes) or cell data
//!   (second dimension = number of cells, cells in the order [`RunReader::cells`] returns
//!   them; when both counts are equal the field is taken as nodal);
//! * a scalar as it is, a vector (2 or 3 components) by its magnitude or one component, a
//!   symmetric tensor (6 components xx, xy, xz, yy, yz, zz) by its Frobenius norm (default), one
//!   component or its von Mises value; any other count by its Euclidean norm or one component;
//! * 2D runs: every cell filled. A triangle is filled by linear interpolation of its nodal
//!   values (Gouraud shading, per pixel); a quadrilateral is split into four triangles around
//!   its centroid, whose value is the average of the four nodes. Cell data fill their cell with
//!   one colour;
//! * 3D runs: the boundary faces (faces of one cell only) projected along a view direction,
//!   hidden parts removed by a depth buffer (per pixel; faces turned away from the viewer are
//!   dropped first). Nodal data are interpolated over each face as above, cell data give each
//!   face its cell's value;
//! * the mesh deformed by `displacement` written at the same time, times `magnify`; without one
//!   the mesh is drawn undeformed and the caption says so;
//! * x and y to the same scale; colours from viridis (a 33-entry table, linear in between) over
//!   the field's range at that time (all its nodes or cells, also hidden ones or ones outside
//!   the window; of all panels together; a constant value gets the middle colour) or over
//!   `--range`, with a colour bar.
//!
//! Every error is one line that names the culprit (flag, field, file).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::plot::{self, Area, CAPTION_SIZE, DESC_SIZE, FAMILY, TICK_SIZE, TITLE_SIZE};
use crate::error::{Error, Result};
use crate::fem::element::ElementKind;
use crate::io::layout::{self, RunReader};

/// The snapshot flags of `post` and `compare`, as typed: they are parsed by [`draw`], so that
/// every mistake is reported as one line naming its flag.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct SnapshotArgs {
    /// Draw FIELD (any dataset of /fields, nodal or cell data) on the deformed mesh as a PNG
    /// picture PREFIX-snapshot-FIELD.png (only that picture is written).
    #[arg(long, value_name = "FIELD")]
    pub snapshot: Option<String>,
    /// The written time to draw (default: the last time the field was written).
    #[arg(long, value_name = "T", allow_hyphen_values = true)]
    pub time: Option<String>,
    /// The written step to draw, instead of --time.
    #[arg(long, value_name = "N", allow_hyphen_values = true)]
    pub step: Option<String>,
    /// Vector: x, y, z or magnitude (default); tensor (xx, xy, xz, yy, yz, zz): a component,
    /// magnitude (the Frobenius norm, default) or mises; other fields: 0, 1, ... or magnitude.
    #[arg(long, value_name = "C")]
    pub component: Option<String>,
    /// Scale the displacement the mesh is deformed by (default 1; 0 draws it undeformed).
    #[arg(long, value_name = "K", allow_hyphen_values = true)]
    pub magnify: Option<String>,
    /// Show only the window x0..x1, y0..y1 (of the picture's axes).
    #[arg(long, value_name = "X0,X1,Y0,Y1", allow_hyphen_values = true)]
    pub window: Option<String>,
    /// Fix the colour range (default: the field's range at that time, all nodes or cells).
    #[arg(long, value_name = "LO,HI", allow_hyphen_values = true)]
    pub range: Option<String>,
    /// 3D runs: the direction the camera looks in, +x, -x, +y (default: x right, z up), -y,
    /// +z or -z (from above: x right, y up).
    #[arg(long, value_name = "D", allow_hyphen_values = true)]
    pub view: Option<String>,
    /// Draw the cell edges (3D: the edges of the visible boundary faces) as thin lines.
    #[arg(long)]
    pub edges: bool,
    /// The largest drawing area of a panel in pixels (default 720x560, side by side 480x480);
    /// the mesh is fitted into it at its own aspect ratio.
    #[arg(long, value_name = "WxH")]
    pub size: Option<String>,
}

impl SnapshotArgs {
    /// Whether any snapshot flag other than `--snapshot` was given.
    pub fn any_detail(&self) -> Option<&'static str> {
        [
            (self.time.is_some(), "--time"),
            (self.step.is_some(), "--step"),
            (self.component.is_some(), "--component"),
            (self.magnify.is_some(), "--magnify"),
            (self.window.is_some(), "--window"),
            (self.range.is_some(), "--range"),
            (self.view.is_some(), "--view"),
            (self.edges, "--edges"),
            (self.size.is_some(), "--size"),
        ]
        .into_iter()
        .find_map(|(given, name)| given.then_some(name))
    }
}

/// Width of the colour bar strip at the right of the picture (pixels).
pub const COLOUR_BAR_WIDTH: u32 = 130;
/// Largest drawing area of one panel (pixels): the mesh's bounding box (or the window) is
/// fitted into it at its own aspect ratio.
pub const MAX_PLOT: (u32, u32) = (720, 560);
/// Largest drawing area of one panel when there are several.
pub const MAX_PLOT_SIDE_BY_SIDE: (u32, u32) = (480, 480);
/// Smallest side of a panel's drawing area (a long thin mesh gets empty space around it).
pub const MIN_PLOT_SIDE: u32 = 160;
/// Largest side `--size` accepts.
pub const MAX_PLOT_SIDE: u32 = 4000;
/// Height of the band holding the picture's title.
const TITLE_BAND: u32 = 40;
/// A panel around its drawing area: caption band, margins, tick label areas.
const CAPTION_BAND: u32 = 30;
const MARGIN_TOP: u32 = 8;
const MARGIN_BOTTOM: u32 = 6;
const MARGIN_LEFT: u32 = 10;
const MARGIN_RIGHT: u32 = 16;
const X_LABELS: u32 = TICK_SIZE + DESC_SIZE + 24;
const Y_LABELS: u32 = 80;

/// Viridis (matplotlib's perceptual colour map, CC0) at 33 equally spaced points: entry k is
/// the colour of 0 <= t = k / 32 <= 1. Linear interpolation in between stays within 2/255 of
/// the full 256-entry map.
pub const VIRIDIS: [[u8; 3]; 33] = [
    [68, 1, 84],
    [71, 13, 96],
    [72, 24, 106],
    [72, 35, 116],
    [71, 45, 123],
    [69, 55, 129],
    [66, 64, 134],
    [62, 73, 137],
    [59, 82, 139],
    [55, 91, 141],
    [51, 99, 141],
    [47, 107, 142],
    [44, 114, 142],
    [41, 122, 142],
    [38, 130, 142],
    [35, 137, 142],
    [33, 145, 140],
    [31, 151, 139],
    [31, 159, 136],
    [33, 166, 133],
    [39, 173, 129],
    [49, 181, 123],
    [61, 188, 116],
    [76, 194, 108],
    [92, 200, 99],
    [110, 206, 88],
    [129, 211, 77],
    [149, 216, 64],
    [170, 220, 50],
    [192, 223, 37],
    [213, 226, 26],
    [234, 229, 26],
    [253, 231, 37],
];

/// Colour of values that are not finite.
const NAN_COLOUR: [u8; 3] = [170, 170, 170];

/// The colour map at `t` (clamped to [0, 1]; NaN gives grey).
pub fn viridis(t: f64) -> [u8; 3] {
    if !t.is_finite() {
        return NAN_COLOUR;
    }
    let x = t.clamp(0.0, 1.0) * (VIRIDIS.len() - 1) as f64;
    let k = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    std::array::from_fn(|c| {
        (f64::from(a[c]) + (f64::from(b[c]) - f64::from(a[c])) * f).round() as u8
    })
}

/// A short number: 6 significant digits at most, no trailing zeros (1e-3, 0.25, 1.5e4).
fn short(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let r: f64 = format!("{v:.5e}").parse().unwrap_or(v);
    if (1e-3..1e5).contains(&r.abs()) {
        format!("{r}")
    } else {
        plot::trim_sci(&format!("{r:.5e}"))
    }
}

fn usage(m: String) -> Error {
    Error::Usage(m)
}

/// Numbers separated by commas, exactly `n` of them.
fn numbers(flag: &str, text: &str, n: usize, shape: &str) -> Result<Vec<f64>> {
    let v: Vec<f64> = text
        .split(',')
        .map(|c| c.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| usage(format!("{flag} {text}: expected {shape} (numbers)")))?;
    if v.len() != n {
        return Err(usage(format!("{flag} {text}: expected {shape} ({n} numbers)")));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(usage(format!("{flag} {text}: the numbers must be finite")));
    }
    Ok(v)
}

/// Which written output to draw.
#[derive(Debug, Clone, Copy)]
enum When {
    Last,
    Time(f64),
    Step(f64),
}

/// A view direction for 3D runs: screen right, screen up, and the direction to the viewer.
#[derive(Debug, Clone, Copy)]
struct View {
    name: &'static str,
    right: [f64; 3],
    up: [f64; 3],
    toward: [f64; 3],
}

impl View {
    /// `d` is the direction the camera looks in (ParaView's "view direction"); up is z for
    /// the x and y directions and y for the z directions; right = up x (-d).
    fn parse(s: &str) -> Option<View> {
        let (name, d): (&'static str, [f64; 3]) = match s {
            "x" | "+x" => ("+x", [1.0, 0.0, 0.0]),
            "-x" => ("-x", [-1.0, 0.0, 0.0]),
            "y" | "+y" => ("+y", [0.0, 1.0, 0.0]),
            "-y" => ("-y", [0.0, -1.0, 0.0]),
            "z" | "+z" => ("+z", [0.0, 0.0, 1.0]),
            "-z" => ("-z", [0.0, 0.0, -1.0]),
            _ => return None,
        };
        let up = if d[2] != 0.0 { [0.0, 1.0, 0.0] } else { [0.0, 0.0, 1.0] };
        let toward = d.map(|c| -c);
        let right = [
            up[1] * toward[2] - up[2] * toward[1],
            up[2] * toward[0] - up[0] * toward[2],
            up[0] * toward[1] - up[1] * toward[0],
        ];
        Some(View { name, right, up, toward })
    }

    /// The name of a screen axis: the coordinate it runs along, with its sign.
    fn axis_name(a: [f64; 3]) -> String {
        let k = (0..3).find(|&k| a[k] != 0.0).unwrap_or(0);
        format!("{}{}", if a[k] < 0.0 { "-" } else { "" }, ["x", "y", "z"][k])
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// How the components of an entry become the drawn number.
#[derive(Debug, Clone, Copy)]
enum Reduce {
    Index(usize),
    Norm,
    /// Frobenius norm of a symmetric tensor stored as xx, xy, xz, yy, yz, zz.
    Frobenius,
    Mises,
}

const VECTOR: [&str; 3] = ["x", "y", "z"];
const TENSOR: [&str; 6] = ["xx", "xy", "xz", "yy", "yz", "zz"];

/// The reduction for `--component` of a field with `comps` components, and the words that
/// name the drawn quantity ("" for a scalar).
fn reduction(field: &str, comps: usize, want: Option<&str>) -> Result<(Reduce, String)> {
    let bad = |allowed: String, what: &str| {
        usage(format!("--component {}: {field} is {what}; use {allowed}", want.unwrap_or_default()))
    };
    match comps {
        1 => match want {
            None => Ok((Reduce::Index(0), String::new())),
            Some(_) => Err(bad("no --component".into(), "a scalar (1 component)")),
        },
        2 | 3 => match want {
            None | Some("magnitude") => Ok((Reduce::Norm, "magnitude".into())),
            Some(c) => match VECTOR[..comps].iter().position(|n| *n == c) {
                Some(k) => Ok((Reduce::Index(k), c.to_string())),
                None => Err(bad(
                    format!("{} or magnitude", VECTOR[..comps].join(", ")),
                    &format!("a vector ({comps} components)"),
                )),
            },
        },
        6 => match want {
            None | Some("magnitude") | Some("frobenius") => {
                Ok((Reduce::Frobenius, "Frobenius norm".into()))
            }
            Some("mises") => Ok((Reduce::Mises, "von Mises".into())),
            Some(c) => match TENSOR.iter().position(|n| *n == c) {
                Some(k) => Ok((Reduce::Index(k), c.to_string())),
                None => Err(bad(
                    format!("{}, magnitude (Frobenius norm) or mises", TENSOR.join(", ")),
                    "a symmetric tensor (6 components xx, xy, xz, yy, yz, zz)",
                )),
            },
        },
        _ => match want {
            None | Some("magnitude") => Ok((Reduce::Norm, "magnitude".into())),
            Some(c) => match c.parse::<usize>() {
                Ok(k) if k < comps => Ok((Reduce::Index(k), format!("component {k}"))),
                _ => Err(bad(
                    format!("0 to {} or magnitude", comps - 1),
                    &format!("a field of {comps} components"),
                )),
            },
        },
    }
}

fn reduce(r: Reduce, v: &[f64]) -> f64 {
    match r {
        Reduce::Index(k) => v[k],
        Reduce::Norm => v.iter().map(|x| x * x).sum::<f64>().sqrt(),
        Reduce::Frobenius => {
            let [xx, xy, xz, yy, yz, zz] = [v[0], v[1], v[2], v[3], v[4], v[5]];
            (xx * xx + yy * yy + zz * zz + 2.0 * (xy * xy + xz * xz + yz * yz)).sqrt()
        }
        Reduce::Mises => {
            let [xx, xy, xz, yy, yz, zz] = [v[0], v[1], v[2], v[3], v[4], v[5]];
            (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2))
                + 3.0 * (xy * xy + yz * yz + xz * xz))
                .sqrt()
        }
    }
}

/// The parsed flags.
#[derive(Debug, Clone)]
struct Request {
    field: String,
    when: When,
    component: Option<String>,
    magnify: f64,
    window: Option<[f64; 4]>,
    range: Option<(f64, f64)>,
    view: Option<View>,
    edges: bool,
    size: Option<(u32, u32)>,
}

impl Request {
    fn parse(a: &SnapshotArgs) -> Result<Request> {
        let field = a.snapshot.clone().unwrap_or_default();
        if field.is_empty() {
            return Err(usage("--snapshot: name a field".into()));
        }
        let when = match (&a.time, &a.step) {
            (Some(_), Some(_)) => {
                return Err(usage("--time and --step: give one of them".into()));
            }
            (Some(t), None) => When::Time(
                t.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|t| t.is_finite())
                    .ok_or_else(|| usage(format!("--time {t}: not a number")))?,
            ),
            (None, Some(s)) => When::Step(
                s.trim()
                    .parse::<u64>()
                    .map_err(|_| usage(format!("--step {s}: not a step number (0, 1, 2, ...)")))?
                    as f64,
            ),
            (None, None) => When::Last,
        };
        let magnify = match &a.magnify {
            None => 1.0,
            Some(k) => k
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|k| k.is_finite())
                .ok_or_else(|| usage(format!("--magnify {k}: not a finite number")))?,
        };
        let window = match &a.window {
            None => None,
            Some(w) => {
                let v = numbers("--window", w, 4, "x0,x1,y0,y1")?;
                if !(v[0] < v[1] && v[2] < v[3]) {
                    return Err(usage(format!("--window {w}: needs x0 < x1 and y0 < y1")));
                }
                Some([v[0], v[1], v[2], v[3]])
            }
        };
        let range = match &a.range {
            None => None,
            Some(r) => {
                let v = numbers("--range", r, 2, "lo,hi")?;
                if v[0] >= v[1] {
                    return Err(usage(format!("--range {r}: needs lo < hi")));
                }
                Some((v[0], v[1]))
            }
        };
        let view =
            match &a.view {
                None => None,
                Some(v) => Some(View::parse(v.trim()).ok_or_else(|| {
                    usage(format!("--view {v}: use one of +x, -x, +y, -y, +z, -z"))
                })?),
            };
        let size = match &a.size {
            None => None,
            Some(t) => {
                let bad = || {
                    usage(format!(
                        "--size {t}: expected WxH in pixels, each {MIN_PLOT_SIDE} to {MAX_PLOT_SIDE}"
                    ))
                };
                let (w, h) = t.trim().split_once('x').ok_or_else(bad)?;
                let side = |v: &str| {
                    v.trim()
                        .parse::<u32>()
                        .ok()
                        .filter(|v| (MIN_PLOT_SIDE..=MAX_PLOT_SIDE).contains(v))
                        .ok_or_else(bad)
                };
                Some((side(w)?, side(h)?))
            }
        };
        Ok(Request {
            field,
            when,
            component: a.component.clone(),
            magnify,
            window,
            range,
            view,
            edges: a.edges,
            size,
        })
    }
}

/// One run's picture, in screen coordinates (x right, y up, depth toward the viewer).
struct Panel {
    /// The run's label (`--label`, default its file name).
    label: String,
    /// How the mesh is drawn: deformed, undeformed and why.
    note: String,
    /// Triangles: (x, y, depth, value) per corner.
    tris: Vec<[[f64; 4]; 3]>,
    /// Cell or face edges: (x, y, depth) per end.
    edges: Vec<[[f64; 3]; 2]>,
    time: f64,
    step: f64,
    /// The smallest and largest finite value of the field (all nodes or cells, drawn or not).
    range: Option<(f64, f64)>,
}

impl Panel {
    fn bounds(&self) -> Option<[f64; 4]> {
        let mut b = [f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY];
        for p in self.tris.iter().flatten() {
            b = [b[0].min(p[0]), b[1].max(p[0]), b[2].min(p[1]), b[3].max(p[1])];
        }
        (b[0] <= b[1]).then_some(b)
    }
}

/// What the panels have in common.
struct Quantity {
    /// "velocity magnitude", "stress yy", "partition".
    name: String,
    /// Screen axis names.
    axes: (String, String),
}

/// The written outputs of field `name`: (steps, times).
fn field_axis(run: &RunReader, name: &str, rows: usize) -> Result<(Vec<f64>, Vec<f64>)> {
    let times = run.series(&layout::field_time(name)).or_else(|_| run.series(layout::TIME))?;
    let steps = run.series(&layout::field_step(name)).or_else(|_| run.series(layout::STEP))?;
    let n = rows.min(times.len()).min(steps.len());
    Ok((steps[..n].to_vec(), times[..n].to_vec()))
}

/// Up to three written values nearest to `x`, in increasing order.
fn nearest_listed(written: &[f64], x: f64) -> String {
    let mut v: Vec<f64> = written.to_vec();
    v.sort_by(|a, b| (a - x).abs().total_cmp(&(b - x).abs()));
    v.truncate(3);
    v.sort_by(f64::total_cmp);
    v.iter().map(|t| short(*t)).collect::<Vec<_>>().join(", ")
}

/// Index of the written time `t` in `times` (relative tolerance 1e-9 of the time scale).
fn time_index(times: &[f64], t: f64) -> Option<usize> {
    let scale = times.iter().fold(t.abs(), |a, b| a.max(b.abs()));
    let tol = (1e-9 * scale).max(1e-300);
    times
        .iter()
        .enumerate()
        .filter(|(_, x)| (*x - t).abs() <= tol)
        .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
        .map(|(k, _)| k)
}

/// Row `k` of `/fields/<name>` (entries x components, flattened).
fn field_row(run: &RunReader, path: &Path, name: &str, k: usize) -> Result<Vec<f64>> {
    let ds = run
        .file
        .dataset(&layout::field(name))
        .map_err(|e| Error::Io(format!("{}: fields/{name}: {e}", path.display())))?;
    let a = ds
        .read_slice_2d::<f64, _>(ndarray::s![k, .., ..])
        .map_err(|e| Error::Io(format!("{}: read fields/{name}: {e}", path.display())))?;
    Ok(a.iter().copied().collect())
}

/// Read one run and turn it into a panel.
fn prepare(path: &Path, req: &Request, label: &str) -> Result<(Panel, Quantity)> {
    let run = RunReader::open(path)?;
    let shown = path.display();
    let fields = run.fields();
    let name = &req.field;
    if !fields.contains(name) {
        let has = if fields.is_empty() { "none".to_string() } else { fields.join(", ") };
        return Err(usage(format!("--snapshot {name}: no such field in {shown} (written: {has})")));
    }
    let ds = run
        .file
        .dataset(&layout::field(name))
        .map_err(|e| Error::Io(format!("{shown}: fields/{name}: {e}")))?;
    let shape = ds.shape();
    if shape.len() != 3 {
        return Err(Error::Io(format!(
            "{shown}: fields/{name} has shape {shape:?}, expected [outputs, entries, components]"
        )));
    }
    let (rows, entries, comps) = (shape[0], shape[1], shape[2]);
    let (steps, times) = field_axis(&run, name, rows)?;
    if steps.is_empty() || comps == 0 {
        return Err(usage(format!("--snapshot {name}: {shown} holds no written output of it yet")));
    }
    let k = match req.when {
        When::Last => steps.len() - 1,
        When::Time(t) => time_index(&times, t).ok_or_else(|| {
            usage(format!(
                "--time {}: {name} was not written at that time in {shown} (nearest written: {})",
                short(t),
                nearest_listed(&times, t)
            ))
        })?,
        When::Step(s) => steps.iter().position(|&x| x == s).ok_or_else(|| {
            usage(format!(
                "--step {s}: {name} was not written at that step in {shown} (nearest written: {})",
                nearest_listed(&steps, s)
            ))
        })?,
    };
    let (time, step) = (times[k], steps[k]);
    let (how, words) = reduction(name, comps, req.component.as_deref())?;
    let quantity = if words.is_empty() { name.clone() } else { format!("{name} {words}") };

    let coords = run.coordinates()?;
    let cells = run.cells()?;
    let n_nodes = coords.len();
    let nodal = if entries == n_nodes {
        true
    } else if entries == cells.len() {
        false
    } else {
        return Err(Error::Io(format!(
            "{shown}: fields/{name} has {entries} entries per output: neither the {n_nodes} nodes nor the {} cells",
            cells.len()
        )));
    };
    let raw = field_row(&run, path, name, k)?;
    let values: Vec<f64> = raw.chunks(comps).map(|v| reduce(how, v)).collect();

    // The deformed mesh: the displacement written at the same time.
    let mut x = coords.clone();
    let mut deformed = None;
    if fields.iter().any(|f| f == "displacement") && req.magnify != 0.0 {
        let dshape = run.file.dataset(&layout::field("displacement")).map(|d| d.shape());
        if let Ok([drows, dn, dc]) = dshape.as_deref() {
            let (_, dtimes) = field_axis(&run, "displacement", *drows)?;
            if let (Some(kd), true) = (time_index(&dtimes, time), *dn == n_nodes) {
                let u = field_row(&run, path, "displacement", kd)?;
                for (p, ui) in x.iter_mut().zip(u.chunks(*dc)) {
                    for (c, d) in ui.iter().take(3).enumerate() {
                        p[c] += req.magnify * d;
                    }
                }
                deformed = Some(req.magnify);
            }
        }
    }
    let note = match deformed {
        Some(1.0) => "mesh deformed by the displacement".to_string(),
        Some(m) => format!("mesh deformed by {} x the displacement", short(m)),
        None if req.magnify == 0.0 => "undeformed (--magnify 0)".to_string(),
        None => format!("undeformed: no displacement written at t = {}", short(time)),
    };

    let three_d = cells.iter().any(|(kind, _)| kind.dim() == 3);
    let label = label.to_string();
    let range = values.iter().filter(|v| v.is_finite()).fold(None, |r: Option<(f64, f64)>, &v| {
        Some(r.map_or((v, v), |r| (r.0.min(v), r.1.max(v))))
    });
    let mut panel = Panel { label, note, tris: Vec::new(), edges: Vec::new(), time, step, range };
    let value_of = |cell: usize, node: usize| if nodal { values[node] } else { values[cell] };
    let axes;
    if three_d {
        let view = req.view.unwrap_or_else(|| View::parse("+y").expect("view"));
        axes = (View::axis_name(view.right), View::axis_name(view.up));
        let screen = |p: [f64; 3]| [dot(p, view.right), dot(p, view.up), dot(p, view.toward)];
        // Boundary faces: the faces of exactly one cell.
        let mut faces: HashMap<Vec<usize>, (usize, usize, &[usize])> = HashMap::new();
        for (ci, (kind, nodes)) in cells.iter().enumerate() {
            if kind.dim() != 3 {
                continue;
            }
            for f in kind.facets() {
                let mut key: Vec<usize> = f.iter().map(|&l| nodes[l]).collect();
                key.sort_unstable();
                faces.entry(key).and_modify(|e| e.1 += 1).or_insert((ci, 1, f));
            }
        }
        let mut boundary: Vec<(usize, Vec<usize>)> = faces
            .into_values()
            .filter(|e| e.1 == 1)
            .map(|(ci, _, f)| (ci, f.iter().map(|&l| cells[ci].1[l]).collect()))
            .collect();
        boundary.sort();
        for (ci, nodes) in boundary {
            let pts: Vec<[f64; 3]> = nodes.iter().map(|&n| screen(x[n])).collect();
            // Outward faces run counterclockwise seen from outside: drop the ones turned away.
            let area2: f64 = (0..pts.len())
                .map(|i| {
                    let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
                    a[0] * b[1] - b[0] * a[1]
                })
                .sum();
            if area2 <= 0.0 {
                continue;
            }
            let vals: Vec<f64> = nodes.iter().map(|&n| value_of(ci, n)).collect();
            polygon(&mut panel, &pts, &vals);
        }
    } else {
        if let Some(v) = req.view.filter(|v| v.name != "-z") {
            return Err(usage(format!(
                "--view {}: {shown} is a 2D run, drawn in its x-y plane (--view is for 3D runs)",
                v.name
            )));
        }
        axes = ("x".to_string(), "y".to_string());
        for (ci, (kind, nodes)) in cells.iter().enumerate() {
            if !matches!(kind, ElementKind::Tri3 | ElementKind::Quad4) {
                continue;
            }
            let pts: Vec<[f64; 3]> = nodes.iter().map(|&n| [x[n][0], x[n][1], 0.0]).collect();
            let vals: Vec<f64> = nodes.iter().map(|&n| value_of(ci, n)).collect();
            polygon(&mut panel, &pts, &vals);
        }
    }
    if panel.tris.is_empty() {
        return Err(Error::Io(format!("{shown}: no cells to draw")));
    }
    Ok((panel, Quantity { name: quantity, axes }))
}

/// Add a triangle or quadrilateral (screen points, values at its corners): its fill (a quad as
/// four triangles around its centroid) and its edges.
fn polygon(panel: &mut Panel, pts: &[[f64; 3]], vals: &[f64]) {
    let corner = |p: [f64; 3], v: f64| [p[0], p[1], p[2], v];
    match pts.len() {
        3 => panel.tris.push([
            corner(pts[0], vals[0]),
            corner(pts[1], vals[1]),
            corner(pts[2], vals[2]),
        ]),
        n => {
            let inv = 1.0 / n as f64;
            let c: [f64; 3] = std::array::from_fn(|k| pts.iter().map(|p| p[k]).sum::<f64>() * inv);
            let cv = vals.iter().sum::<f64>() * inv;
            for i in 0..n {
                let j = (i + 1) % n;
                panel.tris.push([corner(pts[i], vals[i]), corner(pts[j], vals[j]), corner(c, cv)]);
            }
        }
    }
    for i in 0..pts.len() {
        panel.edges.push([pts[i], pts[(i + 1) % pts.len()]]);
    }
}

/// The file a snapshot of `field` is written to: `PREFIX-snapshot-FIELD.png`.
pub fn snapshot_path(prefix: &Path, field: &str) -> PathBuf {
    let mut p = prefix.as_os_str().to_owned();
    p.push(format!("-snapshot-{field}.png"));
    PathBuf::from(p)
}

/// Draw the snapshot of `args.snapshot` for each run (one panel per run, side by side, one
/// colour range; `labels[i]` captions run i's panel when there are several runs, default its
/// file name) into `PREFIX-snapshot-FIELD.png`. Returns the lines to print.
pub fn draw(
    runs: &[PathBuf],
    labels: &[String],
    args: &SnapshotArgs,
    prefix: &Path,
) -> Result<Vec<String>> {
    let req = Request::parse(args)?;
    if runs.is_empty() {
        return Err(usage("--snapshot: no run given".into()));
    }
    let several = runs.len() > 1;
    let mut panels = Vec::new();
    let mut quantity = None;
    for (i, r) in runs.iter().enumerate() {
        let stem = r.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        let label = labels.get(i).cloned().unwrap_or(stem);
        let (p, q) = prepare(r, &req, &label)?;
        panels.push(p);
        quantity = Some(q);
    }
    let q = quantity.expect("one run");
    let mut bounds = panels
        .iter()
        .filter_map(Panel::bounds)
        .reduce(|a, b| [a[0].min(b[0]), a[1].max(b[1]), a[2].min(b[2]), a[3].max(b[3])])
        .expect("cells");
    if let Some(w) = req.window {
        if w[1] < bounds[0] || w[0] > bounds[1] || w[3] < bounds[2] || w[2] > bounds[3] {
            return Err(usage(format!(
                "--window {},{},{},{}: shows no part of the mesh, which spans {} .. {} in {} and {} .. {} in {}",
                short(w[0]), short(w[1]), short(w[2]), short(w[3]),
                short(bounds[0]), short(bounds[1]), q.axes.0,
                short(bounds[2]), short(bounds[3]), q.axes.1
            )));
        }
        bounds = w;
    } else {
        // A small margin around the mesh.
        let m = 0.03 * (bounds[1] - bounds[0]).max(bounds[3] - bounds[2]);
        let m = if m > 0.0 { m } else { 1.0 };
        bounds = [bounds[0] - m, bounds[1] + m, bounds[2] - m, bounds[3] + m];
    }
    // The values' range over all runs, and the colours' range.
    let data = panels.iter().filter_map(|p| p.range).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)));
    let (lo, hi) = match (req.range, data) {
        (Some(r), _) => r,
        (None, Some(r)) if r.1 > r.0 => r,
        // A constant field: a range around its value, which gets the middle colour.
        (None, Some((v, _))) => {
            let d = if v != 0.0 { 0.1 * v.abs() } else { 1.0 };
            (v - d, v + d)
        }
        (None, None) => (0.0, 1.0),
    };
    let field = &req.field;
    // What all panels share goes into the title, the rest into each panel's caption.
    let p0 = &panels[0];
    let same_time = panels.iter().all(|p| p.time == p0.time && p.step == p0.step);
    let same_note = panels.iter().all(|p| p.note == p0.note);
    let when = |p: &Panel| format!("t = {} (step {})", short(p.time), p.step);
    let mut title = if several { q.name.clone() } else { format!("{}: {}", p0.label, q.name) };
    if same_time {
        title = format!("{title}, {}", when(p0));
    }
    if several && same_note {
        title = format!("{title}, {}", p0.note);
    }
    let captions: Vec<String> = panels
        .iter()
        .map(|p| {
            let mut c = if several { vec![p.label.clone()] } else { vec![] };
            if !same_time {
                c.push(when(p));
            }
            if !(several && same_note) {
                c.push(p.note.clone());
            }
            c.join(", ")
        })
        .collect();
    let out = snapshot_path(prefix, field);
    let fit = req.size.unwrap_or(if several { MAX_PLOT_SIDE_BY_SIDE } else { MAX_PLOT });
    let (dx, dy) = (bounds[1] - bounds[0], bounds[3] - bounds[2]);
    let s = (f64::from(fit.0) / dx).min(f64::from(fit.1) / dy);
    let pw = ((dx * s).round() as u32).max(MIN_PLOT_SIDE);
    let ph = ((dy * s).round() as u32).max(MIN_PLOT_SIDE);
    let panel_w = MARGIN_LEFT + Y_LABELS + pw + MARGIN_RIGHT;
    let panel_h = CAPTION_BAND + MARGIN_TOP + ph + X_LABELS + MARGIN_BOTTOM;
    let width = panel_w * panels.len() as u32 + COLOUR_BAR_WIDTH;
    let height = TITLE_BAND + panel_h;
    if width > plot::MAX_SIDE {
        return Err(usage(format!("--snapshot: {} panels make a picture too wide", panels.len())));
    }
    plot::ensure_font()?;
    let style = Style { bounds, range: (lo, hi), edges: req.edges, axes: &q.axes };
    plot::render(&out, width, height, |root| {
        let body = titled(root, &title, TITLE_SIZE, TITLE_BAND)?;
        let (row, bar) = body.split_horizontally(panel_w * panels.len() as u32);
        let areas = row.split_evenly((1, panels.len()));
        for ((area, p), caption) in areas.iter().zip(&panels).zip(&captions) {
            draw_panel(area, p, caption, &style)?;
        }
        colour_bar(&bar, &req.field, &q.name, (lo, hi))
    })?;
    let mut lines: Vec<String> = runs
        .iter()
        .zip(&panels)
        .map(|(r, p)| format!("{}: {}, {}", r.display(), when(p), p.note))
        .collect();
    let mut range_line = match data {
        Some((a, b)) => format!("{} in [{}, {}]", q.name, short(a), short(b)),
        None => format!("{}: no finite value", q.name),
    };
    if data != Some((lo, hi)) {
        let why = if req.range.is_some() { "--range" } else { "constant field" };
        range_line.push_str(&format!("; colours over [{}, {}] ({why})", short(lo), short(hi)));
    }
    lines.push(range_line);
    lines.push(format!("wrote {}", out.display()));
    Ok(lines)
}

struct Style<'a> {
    bounds: [f64; 4],
    range: (f64, f64),
    edges: bool,
    axes: &'a (String, String),
}

/// Draw `text` centred in a band of `band` pixels at the top of `area`; return the rest.
fn titled<'a>(
    area: &Area<'a>,
    text: &str,
    size: u32,
    band: u32,
) -> std::result::Result<Area<'a>, String> {
    let (w, _) = area.dim_in_pixel();
    let style = TextStyle::from((FAMILY, size)).pos(plotters::style::text_anchor::Pos::new(
        plotters::style::text_anchor::HPos::Center,
        plotters::style::text_anchor::VPos::Center,
    ));
    area.draw_text(text, &style, ((w / 2) as i32, (band / 2) as i32)).map_err(|e| e.to_string())?;
    Ok(area.split_vertically(band).1)
}

fn draw_panel(
    area: &Area,
    p: &Panel,
    caption: &str,
    st: &Style,
) -> std::result::Result<(), String> {
    let body = titled(area, caption, CAPTION_SIZE - 2, CAPTION_BAND)?;
    let build = |xr: (f64, f64), yr: (f64, f64)| {
        ChartBuilder::on(&body)
            .margin_top(MARGIN_TOP)
            .margin_bottom(MARGIN_BOTTOM)
            .margin_left(MARGIN_LEFT)
            .margin_right(MARGIN_RIGHT)
            .x_label_area_size(X_LABELS)
            .y_label_area_size(Y_LABELS)
            .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
            .map_err(|e| e.to_string())
    };
    // The drawing area's size in pixels (building a chart draws nothing yet).
    let (pw, ph) = build((0.0, 1.0), (0.0, 1.0))?.plotting_area().dim_in_pixel();
    let (pw, ph) = (f64::from(pw.max(1)), f64::from(ph.max(1)));
    // One scale for x and y: the bounds fitted into the drawing area, centred.
    let b = st.bounds;
    let s = (pw / (b[1] - b[0])).min(ph / (b[3] - b[2]));
    let (cx, cy) = (0.5 * (b[0] + b[1]), 0.5 * (b[2] + b[3]));
    let (hx, hy) = (0.5 * pw / s, 0.5 * ph / s);
    let xr = (cx - hx, cx + hx);
    let yr = (cy - hy, cy + hy);
    let mut chart = build(xr, yr)?;
    let xfmt = plot::linear_formatter(xr.0, xr.1);
    let yfmt = plot::linear_formatter(yr.0, yr.1);
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(6)
        .y_labels(6)
        .x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .label_style((FAMILY, TICK_SIZE))
        .set_all_tick_mark_size(5)
        .axis_desc_style((FAMILY, DESC_SIZE))
        .x_desc(st.axes.0.as_str())
        .y_desc(st.axes.1.as_str())
        .draw()
        .map_err(|e| e.to_string())?;
    let plotting = chart.plotting_area().strip_coord_spec();
    let (aw, ah) = plotting.dim_in_pixel();
    let image = rasterize(p, st, (aw as usize, ah as usize), xr, yr);
    for (i, c) in image.iter().enumerate() {
        if let Some(c) = c {
            let (px, py) = ((i % aw as usize) as i32, (i / aw as usize) as i32);
            plotting
                .draw_pixel((px, py), &RGBColor(c[0], c[1], c[2]))
                .map_err(|e| e.to_string())?;
        }
    }
    // A frame around the drawing area.
    plotting
        .draw(&Rectangle::new(
            [(0, 0), (aw as i32 - 1, ah as i32 - 1)],
            RGBColor(120, 120, 120).stroke_width(1),
        ))
        .map_err(|e| e.to_string())
}

/// The panel's pixels (row by row from the top; `None` = background) for a drawing area of
/// `size` pixels spanning the screen coordinates `xr` x `yr`.
fn rasterize(
    p: &Panel,
    st: &Style,
    size: (usize, usize),
    xr: (f64, f64),
    yr: (f64, f64),
) -> Vec<Option<[u8; 3]>> {
    let (w, h) = size;
    let mut colour: Vec<Option<[u8; 3]>> = vec![None; w * h];
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let (lo, hi) = st.range;
    // The axes' ranges span the drawing area (equal per unit in x and y: see draw_panel).
    let (sx, sy) = (w as f64 / (xr.1 - xr.0), h as f64 / (yr.1 - yr.0));
    let to_px = |q: &[f64]| ((q[0] - xr.0) * sx, (yr.1 - q[1]) * sy);
    for t in &p.tris {
        let v: Vec<(f64, f64)> = t.iter().map(|q| to_px(q)).collect();
        let area = (v[1].0 - v[0].0) * (v[2].1 - v[0].1) - (v[2].0 - v[0].0) * (v[1].1 - v[0].1);
        if area.abs() < 1e-12 {
            continue;
        }
        let xmin = v.iter().map(|q| q.0).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
        let xmax =
            v.iter().map(|q| q.0).fold(f64::NEG_INFINITY, f64::max).ceil().min(w as f64) as usize;
        let ymin = v.iter().map(|q| q.1).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
        let ymax =
            v.iter().map(|q| q.1).fold(f64::NEG_INFINITY, f64::max).ceil().min(h as f64) as usize;
        // Pixel centres on a shared edge belong to both triangles (no cracks).
        let eps = -1e-9 * area.abs();
        for py in ymin..ymax {
            for px in xmin..xmax {
                let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
                let bary: [f64; 3] = std::array::from_fn(|k| {
                    let (a, b) = (v[(k + 1) % 3], v[(k + 2) % 3]);
                    ((b.0 - a.0) * (cy - a.1) - (cx - a.0) * (b.1 - a.1)) / area
                });
                if bary.iter().any(|&l| l * area.abs() < eps) {
                    continue;
                }
                let d: f64 = (0..3).map(|k| bary[k] * t[k][2]).sum();
                let i = py * w + px;
                if d < depth[i] {
                    continue;
                }
                let val: f64 = (0..3).map(|k| bary[k] * t[k][3]).sum();
                depth[i] = d;
                colour[i] = Some(viridis((val - lo) / (hi - lo)));
            }
        }
    }
    if st.edges {
        let span = p
            .tris
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |r, q| (r.0.min(q[2]), r.1.max(q[2])));
        // Edges lie on their faces: a tolerance for the depth sampled half a pixel away.
        let tol = 0.02 * (span.1 - span.0).max(0.0) + 1e-12;
        for e in &p.edges {
            let (a, b) = (to_px(&e[0]), to_px(&e[1]));
            let n = (b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil().max(1.0) as usize;
            for k in 0..=n {
                let f = k as f64 / n as f64;
                let (x, y) = (a.0 + (b.0 - a.0) * f, a.1 + (b.1 - a.1) * f);
                if x < 0.0 || y < 0.0 || x >= w as f64 || y >= h as f64 {
                    continue;
                }
                let i = y as usize * w + x as usize;
                let d = e[0][2] + (e[1][2] - e[0][2]) * f;
                if d + tol < depth[i] {
                    continue; // hidden behind a nearer face
                }
                let under = colour[i].unwrap_or([255, 255, 255]);
                colour[i] = Some(under.map(|c| (f64::from(c) * 0.55) as u8));
            }
        }
    }
    colour
}

/// The colour bar: the field name and component above a vertical strip with tick labels.
fn colour_bar(
    area: &Area,
    field: &str,
    quantity: &str,
    (lo, hi): (f64, f64),
) -> std::result::Result<(), String> {
    let words = quantity.strip_prefix(field).unwrap_or("").trim();
    let body = titled(area, field, DESC_SIZE, CAPTION_BAND)?;
    let body = if words.is_empty() { body } else { titled(&body, words, TICK_SIZE, 20)? };
    let mut chart = ChartBuilder::on(&body)
        .margin_top(MARGIN_TOP)
        .margin_bottom(MARGIN_BOTTOM + X_LABELS)
        .margin_left(14)
        .right_y_label_area_size(COLOUR_BAR_WIDTH - 14 - 26 - 4)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(|e| e.to_string())?;
    let fmt = plot::linear_formatter(lo, hi);
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(8)
        .y_label_formatter(&fmt)
        .label_style((FAMILY, TICK_SIZE))
        .set_all_tick_mark_size(5)
        .draw()
        .map_err(|e| e.to_string())?;
    let bands = 256;
    chart
        .draw_series((0..bands).map(|k| {
            let (a, b) = (k as f64 / bands as f64, (k + 1) as f64 / bands as f64);
            let c = viridis(0.5 * (a + b));
            Rectangle::new(
                [(0.0, lo + (hi - lo) * a), (1.0, lo + (hi - lo) * b)],
                RGBColor(c[0], c[1], c[2]).filled(),
            )
        }))
        .map_err(|e| e.to_string())?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(0.0, lo), (1.0, hi)],
            RGBColor(120, 120, 120).stroke_width(1),
        )))
        .map_err(|e| e.to_string())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colour_map_ends_and_middle() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(0.5), [33, 145, 140]);
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(f64::NAN), NAN_COLOUR);
    }

    #[test]
    fn components() {
        let v = [3.0, 4.0];
        assert_eq!(reduce(reduction("v", 2, None).unwrap().0, &v), 5.0);
        assert_eq!(reduce(reduction("v", 2, Some("y")).unwrap().0, &v), 4.0);
        assert!(reduction("v", 2, Some("z")).is_err());
        assert!(reduction("p", 1, Some("x")).is_err());
        let t = [1.0, 2.0, 0.0, 3.0, 0.0, 0.0];
        assert_eq!(reduce(reduction("s", 6, Some("yy")).unwrap().0, &t), 3.0);
        let f = reduce(reduction("s", 6, None).unwrap().0, &t);
        assert!((f - (1.0f64 + 9.0 + 8.0).sqrt()).abs() < 1e-12);
        // Uniaxial stress: von Mises = |sigma|.
        let u = [0.0, 0.0, 0.0, -2.0, 0.0, 0.0];
        assert!((reduce(Reduce::Mises, &u) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn views_are_right_handed() {
        let v = View::parse("+y").unwrap();
        assert_eq!((View::axis_name(v.right), View::axis_name(v.up)), ("x".into(), "z".into()));
        let v = View::parse("-z").unwrap();
        assert_eq!((View::axis_name(v.right), View::axis_name(v.up)), ("x".into(), "y".into()));
        assert_eq!(v.toward, [0.0, 0.0, 1.0]);
        let v = View::parse("+x").unwrap();
        assert_eq!(View::axis_name(v.right), "-y");
    }

    #[test]
    fn short_numbers() {
        assert_eq!(short(1e-3), "0.001");
        assert_eq!(short(0.0010000000000000002), "0.001");
        assert_eq!(short(2.5e-4), "2.5e-4");
        assert_eq!(short(0.25), "0.25");
        assert_eq!(short(0.0), "0");
        assert_eq!(short(123456789.0), "1.23457e8");
    }
}
