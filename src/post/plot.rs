//! PNG line plots (time series, energy panels, convergence plots) drawn with `plotters`.
//!
//! Everything is rendered in pure Rust: the bitmap is drawn by `plotters`' bitmap backend,
//! encoded as PNG by the pure-Rust `image`/`png` crates, and text is rasterised by `ab_glyph`
//! from DejaVu Sans, which is read at run time from [`FONT_PATH`] (Debian package
//! `fonts-dejavu-core`). No system development library (fontconfig, freetype) is needed.
//!
//! All functions are pure apart from writing the one PNG file they are given: they never
//! print, and every failure comes back as [`Error::Io`] naming the file.
//!
//! Data handling common to all plots:
//! * points with a NaN or infinite coordinate are skipped (the line joins their neighbours);
//!   in log-log plots, points with `x <= 0` or `y <= 0` are skipped as well;
//! * an empty series list, or series that hold no drawable point, is an error ("nothing to
//!   plot");
//! * the x axis spans the data exactly, the y axis gets a 5 % margin on both sides; a constant
//!   coordinate (min == max) gets a small padded range around its value;
//! * tick labels switch to scientific notation (`2.5e-4`) when the axis values are small
//!   (< 1e-2) or large (>= 1e4);
//! * series get distinct colours from a 10-colour palette (cycled beyond 10 series) and a
//!   legend entry with their name (series with an empty name get no legend entry).

use crate::error::{Error, Result};
use plotters::chart::SeriesAnno;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint, Ranged};
use plotters::coord::Shift;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use std::path::Path;
use std::sync::Mutex;

/// The TrueType font used for all text.
pub const FONT_PATH: &str = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";

/// One curve: its legend name and its `(x, y)` points, drawn in the given order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// One chart: title, axis labels, the curves and the image size in pixels.
///
/// In [`stacked_plots`] each entry is one panel: `title` is the panel caption, `height` is
/// the panel's height, and the widest `width` is the image width.
#[derive(Debug, Clone, Copy)]
pub struct Plot<'a> {
    pub title: &'a str,
    pub x_label: &'a str,
    pub y_label: &'a str,
    pub series: &'a [Series],
    pub width: u32,
    pub height: u32,
}

/// Smallest accepted plot (or panel) size; below it the labels do not fit.
const MIN_WIDTH: u32 = 200;
const MIN_HEIGHT: u32 = 150;
/// Largest accepted image side.
pub(crate) const MAX_SIDE: u32 = 16_384;

/// Family name under which the font is registered with `plotters`.
pub(crate) const FAMILY: &str = "sans-serif";
pub(crate) const TITLE_SIZE: u32 = 22;
pub(crate) const CAPTION_SIZE: u32 = 18;
pub(crate) const DESC_SIZE: u32 = 16;
pub(crate) const TICK_SIZE: u32 = 14;
const LEGEND_SIZE: u32 = 14;
/// Height of the band that holds the overall title of [`stacked_plots`].
const STACK_TITLE_BAND: u32 = 40;
/// Fraction of the y span added above and below the data.
const Y_MARGIN: f64 = 0.05;

/// Colour-blind friendly "tab10" palette.
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Colour of series number `i`.
fn color(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Line plot of all series (distinct colors, legend with the names, axes with tick labels in
/// scientific notation where the values are small or large, e.g. times like 2.5e-4), written
/// as a `plot.width` x `plot.height` PNG at `path`.
///
/// Errors ([`Error::Io`], naming `path`): nothing to plot, size out of range, missing font,
/// the file cannot be written (e.g. its directory does not exist).
pub fn line_plot(path: &Path, plot: &Plot) -> Result<()> {
    check_size(path, plot.width, plot.height)?;
    let b = data_bounds(plot.series, false).ok_or_else(|| nothing(path))?;
    let xr = pad_linear(b.xlo, b.xhi, 0.0);
    let yr = pad_linear(b.ylo, b.yhi, Y_MARGIN);
    ensure_font()?;
    render(path, plot.width, plot.height, |root| {
        draw_linear_panel(root, plot, xr, yr, true, TITLE_SIZE)
    })
}

/// Same as [`line_plot`], but one panel per entry of `panels`, stacked vertically under the
/// overall `title`, all sharing one x range (the union of the panels' data) and the x axis
/// label of the last panel (shown under the bottom panel only). For e.g. kinetic / potential /
/// total energy panels.
///
/// The image is as wide as the widest panel and as tall as the panels' heights added up
/// (plus a band for the title). A panel without drawable points is drawn as empty axes; it
/// is an error only when no panel has any.
pub fn stacked_plots(path: &Path, title: &str, panels: &[Plot]) -> Result<()> {
    if panels.is_empty() {
        return Err(nothing(path));
    }
    for p in panels {
        check_size(path, p.width, p.height)?;
    }
    let width = panels.iter().map(|p| p.width).max().unwrap_or(MIN_WIDTH);
    let height = panels
        .iter()
        .map(|p| u64::from(p.height))
        .sum::<u64>()
        .saturating_add(u64::from(STACK_TITLE_BAND));
    if height > u64::from(MAX_SIDE) {
        return Err(io(path, format!("image height {height} exceeds {MAX_SIDE} pixels")));
    }
    let height = height as u32;

    let bounds: Vec<Option<Bounds>> = panels.iter().map(|p| data_bounds(p.series, false)).collect();
    let all =
        bounds.iter().flatten().copied().reduce(Bounds::union).ok_or_else(|| nothing(path))?;
    let xr = pad_linear(all.xlo, all.xhi, 0.0);
    let shared_x_label = panels.last().map_or("", |p| p.x_label);
    ensure_font()?;

    render(path, width, height, |root| {
        let body = root.titled(title, (FAMILY, TITLE_SIZE)).map_err(|e| e.to_string())?;
        // Split the remaining height in proportion to the panels' heights.
        let total: u64 = panels.iter().map(|p| u64::from(p.height)).sum();
        let body_h = u64::from(body.dim_in_pixel().1);
        let mut acc = 0u64;
        let breaks: Vec<i32> = panels[..panels.len() - 1]
            .iter()
            .map(|p| {
                acc += u64::from(p.height);
                (acc * body_h / total.max(1)) as i32
            })
            .collect();
        let areas = body.split_by_breakpoints::<i32, i32, _, _>([], breaks);
        let last = panels.len() - 1;
        for (i, (area, panel)) in areas.iter().zip(panels).enumerate() {
            let yr = match bounds[i] {
                Some(b) => pad_linear(b.ylo, b.yhi, Y_MARGIN),
                None => (0.0, 1.0),
            };
            let shown = Plot { x_label: if i == last { shared_x_label } else { "" }, ..*panel };
            draw_linear_panel(area, &shown, xr, yr, i == last, CAPTION_SIZE)?;
        }
        Ok(())
    })
}

/// Log-log plot of all series with a circle marker on every point, plus one dashed reference
/// line per entry of `reference_slopes` (e.g. `[1.0, 2.0]` for error versus mesh size `h`).
///
/// The reference lines `y = c x^p` pass a factor 2 below the right-most point of the first
/// series that has drawable points (so that they run beside, not on top of, a curve of the
/// same slope), span the data's x range (cut where they leave the y range), and have
/// legend entries "slope p". Non-finite slopes are ignored. Points with a non-positive
/// coordinate cannot be shown on log axes and are skipped.
pub fn loglog_plot(path: &Path, plot: &Plot, reference_slopes: &[f64]) -> Result<()> {
    let styles: Vec<SeriesStyle> = (0..plot.series.len()).map(SeriesStyle::default_for).collect();
    loglog_plot_styled(path, plot, reference_slopes, &styles)
}

/// Marker shapes of [`SeriesStyle`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
}

/// How [`loglog_plot_styled`] draws one series: colour, marker (filled or hollow, radius in
/// pixels) and whether its points are joined by a line (`line_width` pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeriesStyle {
    pub color: (u8, u8, u8),
    pub marker: Option<Marker>,
    pub filled: bool,
    pub size: u32,
    pub line: bool,
    pub line_width: u32,
}

impl SeriesStyle {
    /// Series `i` of a plain plot: palette colour `i`, filled circles, a 2-pixel line.
    pub fn default_for(i: usize) -> SeriesStyle {
        let c = color(i);
        SeriesStyle {
            color: (c.0, c.1, c.2),
            marker: Some(Marker::Circle),
            filled: true,
            size: 3,
            line: true,
            line_width: 2,
        }
    }

    /// Palette colour number `i` (the "tab10" colours).
    pub fn palette(i: usize) -> (u8, u8, u8) {
        let c = color(i);
        (c.0, c.1, c.2)
    }
}

/// The outline of a marker around (0, 0) in pixels (y down), closed.
fn marker_outline(m: Marker, r: u32) -> Vec<(i32, i32)> {
    let r = r as f64;
    let pts: Vec<(f64, f64)> = match m {
        Marker::Circle => (0..16)
            .map(|k| {
                let a = std::f64::consts::PI * f64::from(k) / 8.0;
                (r * a.cos(), r * a.sin())
            })
            .collect(),
        Marker::Square => {
            let q = r * 0.85;
            vec![(-q, -q), (q, -q), (q, q), (-q, q)]
        }
        Marker::Triangle => {
            let q = r * 1.2;
            vec![(0.0, -q), (q * 0.866, q * 0.5), (-q * 0.866, q * 0.5)]
        }
        Marker::Diamond => {
            let q = r * 1.2;
            vec![(0.0, -q), (q, 0.0), (0.0, q), (-q, 0.0)]
        }
    };
    let mut out: Vec<(i32, i32)> =
        pts.iter().map(|&(x, y)| (x.round() as i32, y.round() as i32)).collect();
    out.push(out[0]);
    out
}

/// [`loglog_plot`] with a style per series (`styles[i]` for `plot.series[i]`; missing
/// entries get [`SeriesStyle::default_for`]). Series with an empty name get no legend entry,
/// and an entry is not repeated for a later series of the same name and style.
pub fn loglog_plot_styled(
    path: &Path,
    plot: &Plot,
    reference_slopes: &[f64],
    styles: &[SeriesStyle],
) -> Result<()> {
    check_size(path, plot.width, plot.height)?;
    let b = data_bounds(plot.series, true).ok_or_else(|| {
        io(
            path,
            "nothing to plot (no point with finite, positive x and y for log axes)".to_string(),
        )
    })?;
    let xr = pad_log(b.xlo, b.xhi, 0.0);
    let yr = pad_log(b.ylo, b.yhi, Y_MARGIN);

    // Anchor of the reference lines: a factor REFERENCE_OFFSET below the right-most point
    // of the first non-empty series.
    let anchor = plot.series.iter().find_map(|s| {
        drawable(s, true)
            .fold(None, |best: Option<(f64, f64)>, p| match best {
                Some(q) if q.0 >= p.0 => Some(q),
                _ => Some(p),
            })
            .map(|(x, y)| (x, y * REFERENCE_OFFSET))
    });
    let refs: Vec<(f64, Vec<(f64, f64)>)> = match anchor {
        Some(a) => reference_slopes
            .iter()
            .filter(|p| p.is_finite())
            .filter_map(|&p| reference_line(a, p, (b.xlo, b.xhi), yr).map(|l| (p, l)))
            .collect(),
        None => Vec::new(),
    };

    ensure_font()?;
    render(path, plot.width, plot.height, |root| {
        let xfmt = log_formatter(xr.0, xr.1);
        let yfmt = log_formatter(yr.0, yr.1);
        let y_area = y_label_area(root, plot.y_label, &log_sample_ticks(yr), &yfmt);
        let mut chart = ChartBuilder::on(root)
            .caption(plot.title, (FAMILY, TITLE_SIZE))
            .margin(10)
            .margin_right(25)
            .x_label_area_size(x_label_area(plot.x_label))
            .y_label_area_size(y_area)
            .build_cartesian_2d(LogAxis::new(xr), LogAxis::new(yr))
            .map_err(|e| e.to_string())?;
        let mut mesh = chart.configure_mesh();
        mesh.x_label_formatter(&xfmt)
            .y_label_formatter(&yfmt)
            .x_labels(10)
            .y_labels(10)
            .label_style((FAMILY, TICK_SIZE))
            .axis_desc_style((FAMILY, DESC_SIZE))
            .light_line_style(RGBColor(235, 235, 235))
            .bold_line_style(RGBColor(205, 205, 205));
        if !plot.x_label.is_empty() {
            mesh.x_desc(plot.x_label);
        }
        if !plot.y_label.is_empty() {
            mesh.y_desc(plot.y_label);
        }
        mesh.draw().map_err(|e| e.to_string())?;

        let to_fraction = |(x, y): (f64, f64)| {
            ((x / xr.0).log10() / (xr.1 / xr.0).log10(), (y / yr.0).log10() / (yr.1 / yr.0).log10())
        };
        let mut legend = Legend::default();
        let mut named: Vec<(String, SeriesStyle)> = Vec::new();
        for (i, s) in plot.series.iter().enumerate() {
            let pts: Vec<(f64, f64)> = drawable(s, true).collect();
            if pts.is_empty() {
                continue;
            }
            let st = styles.get(i).copied().unwrap_or_else(|| SeriesStyle::default_for(i));
            let c = RGBColor(st.color.0, st.color.1, st.color.2);
            legend.add_path(&pts, to_fraction);
            if st.line && pts.len() > 1 {
                if st.line_width >= 2 {
                    draw_thick_width(&mut chart, &pts, c, st.line_width)?;
                } else {
                    chart
                        .draw_series(std::iter::once(PathElement::new(
                            pts.clone(),
                            c.stroke_width(1),
                        )))
                        .map_err(|e| e.to_string())?;
                }
            }
            let (marker, size, filled) = match st.marker {
                Some(m) => (m, st.size, st.filled),
                // A series without markers still needs an anchor for its legend entry.
                None => (Marker::Circle, 0, true),
            };
            let outline = marker_outline(marker, size);
            let fill = if filled { c } else { WHITE };
            let anno = chart
                .draw_series(pts.iter().map(|&p| {
                    EmptyElement::at(p)
                        + Polygon::new(outline.clone(), fill.filled())
                        + PathElement::new(
                            outline.clone(),
                            c.stroke_width(if size > 0 { 2 } else { 0 }),
                        )
                }))
                .map_err(|e| e.to_string())?;
            if !s.name.is_empty() && !named.iter().any(|(n, t)| *n == s.name && *t == st) {
                named.push((s.name.clone(), st));
                legend.labels.push(s.name.clone());
                let line = st.line;
                let lw = st.line_width.max(1);
                let outline = outline.clone();
                anno.label(s.name.as_str()).legend(move |(x, y)| {
                    let seg = if line { vec![(0, 0), (20, 0)] } else { vec![(10, 0), (10, 0)] };
                    let moved: Vec<(i32, i32)> =
                        outline.iter().map(|&(a, b)| (a + 10, b)).collect();
                    EmptyElement::at((x, y))
                        + PathElement::new(seg, c.stroke_width(if line { lw } else { 0 }))
                        + Polygon::new(moved.clone(), fill.filled())
                        + PathElement::new(moved, c.stroke_width(if size > 0 { 2 } else { 0 }))
                });
            }
        }
        for (k, (slope, pts)) in refs.iter().enumerate() {
            let (dash, gap) = DASHES[k % DASHES.len()];
            let style = RGBColor(60, 60, 60).stroke_width(1);
            let line = chart
                .draw_series(std::iter::once(DashedPathElement::new(pts.clone(), dash, gap, style)))
                .map_err(|e| e.to_string())?;
            legend.add_path(pts, to_fraction);
            let label = format!("slope {slope}");
            legend.labels.push(label.clone());
            line.label(label).legend(move |(x, y)| {
                DashedPathElement::new(vec![(x, y), (x + 20, y)], dash, gap, style)
            });
        }
        legend.draw(&mut chart)
    })
}

/// `plotters`' logarithmic axis with duplicate tick values removed (it can return the upper
/// end twice, which draws that tick label twice and makes it look bold).
struct LogAxis(LogCoord<f64>);

impl LogAxis {
    fn new((lo, hi): (f64, f64)) -> Self {
        LogAxis((lo..hi).log_scale().into())
    }
}

impl Ranged for LogAxis {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.0.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        let r = self.0.range();
        let (lo, hi) = (r.start.min(r.end), r.start.max(r.end));
        if !(lo > 0.0 && hi > lo && hi.is_finite()) {
            return Vec::new();
        }
        if hint.weight().allow_light_points() {
            log_grid_ticks(lo, hi)
        } else {
            log_label_ticks(lo, hi, hint.max_num_points().max(2))
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.0.range()
    }
}

/// The values `m 10^k` (`m` in `mantissas`) inside `[lo, hi]`, ascending.
fn log_ticks_with(lo: f64, hi: f64, mantissas: &[f64]) -> Vec<f64> {
    let tol = 1e-9;
    let mut out = Vec::new();
    let mut k = lo.log10().floor() as i32 - 1;
    while 10f64.powi(k) <= hi * (1.0 + tol) {
        for m in mantissas {
            let v = m * 10f64.powi(k);
            if v >= lo * (1.0 - tol) && v <= hi * (1.0 + tol) {
                out.push(v);
            }
        }
        k += 1;
    }
    out
}

/// Grid lines of a log axis over `[lo, hi]`: every `m 10^k` (m = 1..9) up to 6 decades,
/// only the powers of ten beyond.
fn log_grid_ticks(lo: f64, hi: f64) -> Vec<f64> {
    if (hi / lo).log10() <= 6.0 {
        log_ticks_with(lo, hi, &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0])
    } else {
        log_ticks_with(lo, hi, &[1.0])
    }
}

/// Labelled ticks of a log axis over `[lo, hi]`, at most `max` of them: the powers of ten
/// (every k-th one when there are too many) over 3 decades and more; 1, 2 and 5 times them
/// over 1 to 3 decades; every `m 10^k` (m = 1..9) within a decade. When a set holds fewer
/// than two ticks the next finer one is used (1-9, then 1, 1.5, 2, ... 9.5, then five
/// log-spaced values), so that every axis has at least two labels. [`log_formatter`] labels
/// the same set.
fn log_label_ticks(lo: f64, hi: f64, max: usize) -> Vec<f64> {
    let decades = (hi / lo).log10();
    let sets: [&[f64]; 4] = [
        &[1.0],
        &[1.0, 2.0, 5.0],
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0],
        &[1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0, 5.5, 6.0, 6.5, 7.0, 7.5, 8.0, 8.5, 9.0, 9.5],
    ];
    let first = if decades >= 3.0 {
        0
    } else if decades >= 1.0 {
        1
    } else {
        2
    };
    for (i, m) in sets.iter().enumerate().skip(first) {
        let mut t = log_ticks_with(lo, hi, m);
        if i == 0 && t.len() > max {
            let every = t.len().div_ceil(max);
            t = t.into_iter().step_by(every).collect();
        }
        if t.len() >= 2 {
            if t.len() > max && i > first {
                // A finer set only to reach two labels: keep it short.
                let every = t.len().div_ceil(max);
                t = t.into_iter().step_by(every).collect();
            }
            return t;
        }
    }
    let (a, b) = (lo.ln(), hi.ln());
    (0..5).map(|i| (a + (b - a) * f64::from(i) / 4.0).exp()).collect()
}

/// Reference lines start this factor below their anchor point.
const REFERENCE_OFFSET: f64 = 0.5;

/// Dash and gap lengths (pixels) of successive reference lines.
const DASHES: [(u32, u32); 4] = [(8, 4), (3, 3), (12, 4), (6, 2)];

// ---------------------------------------------------------------------------------------------
// Drawing helpers

pub(crate) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Creates the bitmap, lets `draw` paint it, and writes the PNG; every failure becomes
/// `Error::Io` naming `path`.
pub(crate) fn render<F>(path: &Path, width: u32, height: u32, draw: F) -> Result<()>
where
    F: FnOnce(&Area) -> std::result::Result<(), String>,
{
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() && !dir.is_dir() {
            return Err(io(path, format!("directory {} does not exist", dir.display())));
        }
    }
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| io(path, e.to_string()))?;
    draw(&root).map_err(|e| io(path, e))?;
    root.present().map_err(|e| io(path, format!("cannot write PNG: {e}")))
}

/// One linear chart (a whole plot or one stacked panel) on `area`.
fn draw_linear_panel(
    area: &Area,
    plot: &Plot,
    xr: (f64, f64),
    yr: (f64, f64),
    x_ticks_and_desc: bool,
    caption_size: u32,
) -> std::result::Result<(), String> {
    let xfmt = linear_formatter(xr.0, xr.1);
    let yfmt = linear_formatter(yr.0, yr.1);
    let y_area = y_label_area(area, plot.y_label, &sample_ticks(yr), &yfmt);
    let mut builder = ChartBuilder::on(area);
    if !plot.title.is_empty() {
        builder.caption(plot.title, (FAMILY, caption_size));
    }
    let mut chart = builder
        .margin(10)
        .margin_right(25)
        .x_label_area_size(if x_ticks_and_desc {
            x_label_area(plot.x_label)
        } else {
            TICK_SIZE + 12
        })
        .y_label_area_size(y_area)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)
        .map_err(|e| e.to_string())?;

    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&xfmt)
        .y_label_formatter(&yfmt)
        .x_labels(8)
        .y_labels(if caption_size == TITLE_SIZE { 8 } else { 5 })
        .max_light_lines(4)
        .label_style((FAMILY, TICK_SIZE))
        .axis_desc_style((FAMILY, DESC_SIZE))
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(210, 210, 210));
    if x_ticks_and_desc && !plot.x_label.is_empty() {
        mesh.x_desc(plot.x_label);
    }
    if !plot.y_label.is_empty() {
        mesh.y_desc(plot.y_label);
    }
    mesh.draw().map_err(|e| e.to_string())?;

    let mut legend = Legend::default();
    for (i, s) in plot.series.iter().enumerate() {
        let pts: Vec<(f64, f64)> = drawable(s, false).collect();
        if pts.is_empty() {
            continue;
        }
        let c = color(i);
        let pts = thin_path(pts, xr, area.dim_in_pixel().0);
        legend.add_path(&pts, |(x, y)| ((x - xr.0) / (xr.1 - xr.0), (y - yr.0) / (yr.1 - yr.0)));
        let line = draw_thick(&mut chart, &pts, c)?;
        if !s.name.is_empty() {
            legend.labels.push(s.name.clone());
            line.label(s.name.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2))
            });
        }
    }
    legend.draw(&mut chart)
}

/// Draws the curve through `pts` 2 pixels wide and returns its series annotation (for the
/// legend). A single point is drawn as a dot.
///
/// `plotters` fills a thick multi-point path as one polygon with unlimited miter joins, which
/// draws long spikes at sharp turns (noisy data) and ragged edges. Instead the curve is drawn
/// as a 1-pixel polyline plus copies shifted one pixel right, down and diagonally (a 2x2 pixel
/// brush); 1-pixel lines have no joins and are fast.
fn draw_thick<'a, 'c, X, Y>(
    chart: &'c mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
    pts: &[(f64, f64)],
    color: RGBColor,
) -> std::result::Result<&'c mut SeriesAnno<'a, BitMapBackend<'a>>, String>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    draw_thick_width(chart, pts, color, 2)
}

/// [`draw_thick`] with a `width` x `width` pixel brush.
fn draw_thick_width<'a, 'c, X, Y>(
    chart: &'c mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
    pts: &[(f64, f64)],
    color: RGBColor,
    width: u32,
) -> std::result::Result<&'c mut SeriesAnno<'a, BitMapBackend<'a>>, String>
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let area = chart.plotting_area();
    let (bx, by) = area.get_base_pixel();
    let pixels: Vec<(i32, i32)> = pts
        .iter()
        .map(|p| {
            let (x, y) = chart.backend_coord(p);
            (x - bx, y - by)
        })
        .collect();
    let flat = area.strip_coord_spec();
    let w = width.max(1) as i32;
    let offsets = (0..w).flat_map(|dx| (0..w).map(move |dy| (dx - (w - 1) / 2, dy - (w - 1) / 2)));
    for (dx, dy) in offsets.filter(|&(dx, dy)| (dx, dy) != (0, 0) || w == 1) {
        let shifted: Vec<(i32, i32)> = pixels.iter().map(|&(x, y)| (x + dx, y + dy)).collect();
        flat.draw(&PathElement::new(shifted, color.stroke_width(1))).map_err(|e| e.to_string())?;
    }
    if let [p] = pts {
        // A lone point has no line: mark it with a dot.
        return chart
            .draw_series(std::iter::once(Circle::new(*p, 3, color.filled())))
            .map_err(|e| e.to_string());
    }
    chart
        .draw_series(std::iter::once(PathElement::new(pts.to_vec(), color.stroke_width(1))))
        .map_err(|e| e.to_string())
}

/// Legend entries of one chart and the drawn paths in plot-fraction coordinates (0..1 from
/// the lower-left corner of the plotting area), used to put the legend where it hides least.
#[derive(Default)]
struct Legend {
    labels: Vec<String>,
    /// The drawn paths (series and reference lines) in plot-fraction coordinates.
    paths: Vec<Vec<(f64, f64)>>,
}

impl Legend {
    fn add_path(&mut self, pts: &[(f64, f64)], to_fraction: impl Fn((f64, f64)) -> (f64, f64)) {
        self.paths.push(pts.iter().map(|&p| to_fraction(p)).collect());
    }

    /// Draws the legend (if any entry has a name) in the corner of the plotting area that
    /// covers the fewest path samples, preferring upper right, upper left, lower right, lower
    /// left in that order on ties.
    fn draw<'a, X, Y>(
        &self,
        chart: &mut ChartContext<'a, BitMapBackend<'a>, Cartesian2d<X, Y>>,
    ) -> std::result::Result<(), String>
    where
        X: Ranged,
        Y: Ranged,
    {
        if self.labels.is_empty() {
            return Ok(());
        }
        let area = chart.plotting_area();
        let (pw, ph) = area.dim_in_pixel();
        let style: TextStyle = (FAMILY, LEGEND_SIZE).into();
        let text_w = self
            .labels
            .iter()
            .map(|l| area.estimate_text_size(l, &style).map_or(0, |(w, _)| w))
            .max()
            .unwrap_or(0);
        // Same layout as plotters' legend: text + symbol area + 2 margins, plus the offset
        // from the plotting area's edge.
        let box_w = f64::from(text_w + LEGEND_SYMBOL + 2 * LEGEND_MARGIN + 8);
        let box_h = self.labels.len() as f64 * f64::from(LEGEND_SIZE) * 1.25
            + f64::from(2 * LEGEND_MARGIN + 8);
        let (bw, bh) = (box_w / f64::from(pw.max(1)), box_h / f64::from(ph.max(1)));
        // Corner boxes in plot fractions: upper right, upper left, lower right, lower left.
        let boxes = [
            (1.0 - bw, 1.0, 1.0 - bh, 1.0),
            (0.0, bw, 1.0 - bh, 1.0),
            (1.0 - bw, 1.0, 0.0, bh),
            (0.0, bw, 0.0, bh),
        ];
        let mut hits = [0usize; 4];
        for path in &self.paths {
            let segs = path.windows(2).map(|w| (w[0], w[1]));
            let single = (path.len() == 1).then(|| (path[0], path[0]));
            for (p, q) in segs.chain(single) {
                for (h, b) in hits.iter_mut().zip(&boxes) {
                    if segment_meets_box(p, q, *b) {
                        *h += 1;
                    }
                }
            }
        }
        let best = (0..4).min_by_key(|&c| (hits[c], c)).unwrap_or(0);
        let position = [
            SeriesLabelPosition::UpperRight,
            SeriesLabelPosition::UpperLeft,
            SeriesLabelPosition::LowerRight,
            SeriesLabelPosition::LowerLeft,
        ][best]
            .clone();
        chart
            .configure_series_labels()
            .position(position)
            .margin(LEGEND_MARGIN)
            .legend_area_size(LEGEND_SYMBOL)
            .label_font((FAMILY, LEGEND_SIZE))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .draw()
            .map_err(|e| e.to_string())
    }
}

/// Whether the segment `p`-`q` meets the box `(x0, x1, y0, y1)` (Liang-Barsky clipping).
fn segment_meets_box(p: (f64, f64), q: (f64, f64), (x0, x1, y0, y1): (f64, f64, f64, f64)) -> bool {
    let (dx, dy) = (q.0 - p.0, q.1 - p.1);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (dir, dist) in [(-dx, p.0 - x0), (dx, x1 - p.0), (-dy, p.1 - y0), (dy, y1 - p.1)] {
        if dir == 0.0 {
            if dist < 0.0 {
                return false;
            }
        } else {
            let r = dist / dir;
            if dir < 0.0 {
                if r > t1 {
                    return false;
                }
                t0 = t0.max(r);
            } else {
                if r < t0 {
                    return false;
                }
                t1 = t1.min(r);
            }
        }
    }
    true
}

const LEGEND_MARGIN: u32 = 8;
const LEGEND_SYMBOL: u32 = 25;

/// Height of the x label area: tick labels, plus the axis description when there is one.
fn x_label_area(desc: &str) -> u32 {
    if desc.is_empty() {
        TICK_SIZE + 14
    } else {
        TICK_SIZE + DESC_SIZE + 24
    }
}

/// Width of the y label area: the widest tick label (estimated from `samples`), plus the
/// rotated axis description when there is one.
fn y_label_area(area: &Area, desc: &str, samples: &[f64], fmt: &dyn Fn(&f64) -> String) -> u32 {
    let style: TextStyle = (FAMILY, TICK_SIZE).into();
    let widest = samples
        .iter()
        .map(|v| {
            let label = fmt(v);
            // Fallback: DejaVu Sans digits are about 0.64 em wide.
            area.estimate_text_size(&label, &style)
                .map_or(label.len() as u32 * TICK_SIZE * 2 / 3, |(w, _)| w)
        })
        .max()
        .unwrap_or(0);
    let desc_w = if desc.is_empty() { 0 } else { DESC_SIZE + 10 };
    widest + desc_w + 14
}

/// Values whose labels are about as wide as the tick labels `plotters` will pick.
fn sample_ticks((lo, hi): (f64, f64)) -> Vec<f64> {
    (0..=20).map(|k| lo + (hi - lo) * f64::from(k) / 20.0).collect()
}

/// The values 1, 2 and 5 times a power of ten inside `[lo, hi]` (candidate log ticks).
fn log_sample_ticks((lo, hi): (f64, f64)) -> Vec<f64> {
    let (a, b) = (lo.log10().floor() as i32, hi.log10().ceil() as i32);
    (a..=b)
        .flat_map(|k| [1.0, 2.0, 5.0].map(|m| m * 10f64.powi(k)))
        .filter(|v| (lo..=hi).contains(v))
        .collect()
}

/// Reduces a long path to at most ~4 points per pixel column (first, min, max, last of each
/// run of consecutive points falling into one column), which draws the same picture. Paths
/// that are not sorted by x only lose points that fall into the same column consecutively.
fn thin_path(pts: Vec<(f64, f64)>, xr: (f64, f64), w: u32) -> Vec<(f64, f64)> {
    let cols = f64::from(w.max(1));
    if pts.len() <= 4 * w as usize {
        return pts;
    }
    let scale = cols / (xr.1 - xr.0);
    let col = |x: f64| ((x - xr.0) * scale).floor() as i64;
    let mut out = Vec::with_capacity(4 * w as usize + 8);
    let mut i = 0;
    while i < pts.len() {
        let c = col(pts[i].0);
        let mut j = i;
        let (mut imin, mut imax) = (i, i);
        while j + 1 < pts.len() && col(pts[j + 1].0) == c {
            j += 1;
            if pts[j].1 < pts[imin].1 {
                imin = j;
            }
            if pts[j].1 > pts[imax].1 {
                imax = j;
            }
        }
        let mut idx = [i, imin, imax, j];
        idx.sort_unstable();
        let mut prev = usize::MAX;
        for k in idx {
            if k != prev {
                out.push(pts[k]);
                prev = k;
            }
        }
        i = j + 1;
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Data ranges

#[derive(Debug, Clone, Copy)]
struct Bounds {
    xlo: f64,
    xhi: f64,
    ylo: f64,
    yhi: f64,
}

impl Bounds {
    fn union(a: Bounds, b: Bounds) -> Bounds {
        Bounds {
            xlo: a.xlo.min(b.xlo),
            xhi: a.xhi.max(b.xhi),
            ylo: a.ylo.min(b.ylo),
            yhi: a.yhi.max(b.yhi),
        }
    }
}

/// The points of `s` that can be drawn: finite, and positive when `log`.
fn drawable(s: &Series, log: bool) -> impl Iterator<Item = (f64, f64)> + '_ {
    s.points
        .iter()
        .copied()
        .filter(move |&(x, y)| x.is_finite() && y.is_finite() && (!log || (x > 0.0 && y > 0.0)))
}

/// Bounding box of all drawable points, `None` when there is none.
fn data_bounds(series: &[Series], log: bool) -> Option<Bounds> {
    series
        .iter()
        .flat_map(|s| drawable(s, log))
        .map(|(x, y)| Bounds { xlo: x, xhi: x, ylo: y, yhi: y })
        .reduce(Bounds::union)
}

/// Linear axis range: `[lo, hi]` widened by `frac` of its span on both sides; a (nearly)
/// constant range becomes `value ± 10 %` (or `± 1` around zero).
fn pad_linear(lo: f64, hi: f64, frac: f64) -> (f64, f64) {
    let mag = lo.abs().max(hi.abs());
    if hi - lo <= 1e-12 * mag || !(hi - lo).is_finite() {
        let c = lo * 0.5 + hi * 0.5;
        let d = if c != 0.0 { 0.1 * c.abs() } else { 1.0 };
        return (c - d, c + d);
    }
    let m = frac * hi - frac * lo;
    (lo - m, hi + m)
}

/// Logarithmic axis range (`lo > 0`): widened by `frac` of its span in log space; a constant
/// range becomes `[value / 2, value * 2]`.
fn pad_log(lo: f64, hi: f64, frac: f64) -> (f64, f64) {
    let (a, b) = (lo.log10(), hi.log10());
    if b - a <= 1e-9 {
        return (lo / 2.0, hi * 2.0);
    }
    let m = frac * (b - a);
    (10f64.powf(a - m), 10f64.powf(b + m))
}

/// Points of the reference line `y = anchor.y (x / anchor.x)^slope` over `xs`, cut to `yr`.
fn reference_line(
    anchor: (f64, f64),
    slope: f64,
    xs: (f64, f64),
    yr: (f64, f64),
) -> Option<Vec<(f64, f64)>> {
    let (xa, ya) = anchor;
    let y = |x: f64| ya * (x / xa).powf(slope);
    let (mut x0, mut x1) = xs;
    if slope != 0.0 {
        // x where the line crosses the bottom and top of the y range.
        let at = |yy: f64| xa * (yy / ya).powf(1.0 / slope);
        let (a, b) = (at(yr.0), at(yr.1));
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        x0 = x0.max(lo);
        x1 = x1.min(hi);
    } else if ya < yr.0 || ya > yr.1 {
        return None;
    }
    if x0.partial_cmp(&x1) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    // Straight in log-log, so two end points suffice.
    Some(vec![(x0, y(x0)), (x1, y(x1))])
}

// ---------------------------------------------------------------------------------------------
// Tick labels

/// Formatter for a linear axis over `[lo, hi]`: scientific notation when the values are small
/// (< 1e-2) or large (>= 1e4), with only the digits the tick spacing needs.
pub(crate) fn linear_formatter(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let mag = lo.abs().max(hi.abs());
    let sci = !(1e-2..1e4).contains(&mag);
    // Slightly below the spacing of ~10 ticks, so that no needed digit is cut.
    let step = ((hi - lo) / 12.0).abs();
    move |v: &f64| format_tick(*v, step, sci)
}

fn format_tick(v: f64, step: f64, sci: bool) -> String {
    if !v.is_finite() {
        return format!("{v}");
    }
    if step > 0.0 && v.abs() < step * 1e-6 {
        return "0".to_string();
    }
    let step_exp = if step > 0.0 { step.log10().floor() } else { 0.0 };
    if sci {
        let exp = v.abs().log10().floor();
        let digits = (exp - step_exp + 1.0).clamp(1.0, 8.0) as usize;
        trim_sci(&format!("{:.*e}", digits - 1, v))
    } else {
        let decimals = (-step_exp).clamp(0.0, 12.0) as usize;
        trim_fixed(&format!("{v:.decimals$}"))
    }
}

/// Formatter for a log axis over `[lo, hi]`: labels the ticks of [`log_label_ticks`] (the
/// powers of ten over 3 decades and more, 1, 2 and 5 times them over 1 to 3 decades, every
/// tick within a decade) and leaves any other value blank, so that labels never run into
/// each other.
fn log_formatter(lo: f64, hi: f64) -> impl Fn(&f64) -> String {
    let decades = (hi / lo).log10();
    move |v: &f64| {
        let v = *v;
        if v > 0.0 && v.is_finite() && decades >= 1.0 {
            let m = v / 10f64.powf(v.log10().floor());
            let near = |k: f64| (m - k).abs() < 1e-6 * k || (m - 10.0 * k).abs() < 1e-5 * k;
            let shown =
                if decades >= 3.0 { near(1.0) } else { near(1.0) || near(2.0) || near(5.0) };
            if !shown {
                return String::new();
            }
        }
        log_tick(v)
    }
}

/// Tick label on a log axis: plain for 1e-2 <= |v| < 1e4, otherwise scientific.
fn log_tick(v: f64) -> String {
    if !v.is_finite() || v == 0.0 {
        return format!("{v}");
    }
    if (1e-2..1e4).contains(&v.abs()) {
        trim_fixed(&format!("{v:.4}"))
    } else {
        trim_sci(&format!("{v:.3e}"))
    }
}

/// "1.2500" -> "1.25", "3.000" -> "3", "-0" -> "0".
fn trim_fixed(s: &str) -> String {
    let t = if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s };
    if t == "-0" {
        "0".to_string()
    } else {
        t.to_string()
    }
}

/// "2.500e-4" -> "2.5e-4", "1.0e3" -> "1e3".
pub(crate) fn trim_sci(s: &str) -> String {
    match s.split_once('e') {
        Some((m, e)) => format!("{}e{e}", trim_fixed(m)),
        None => s.to_string(),
    }
}

// ---------------------------------------------------------------------------------------------
// Errors, checks, font

fn io(path: &Path, msg: String) -> Error {
    Error::Io(format!("plot {}: {msg}", path.display()))
}

fn nothing(path: &Path) -> Error {
    io(path, "nothing to plot (no series with a finite point)".to_string())
}

fn check_size(path: &Path, width: u32, height: u32) -> Result<()> {
    if !(MIN_WIDTH..=MAX_SIDE).contains(&width) || !(MIN_HEIGHT..=MAX_SIDE).contains(&height) {
        return Err(io(
            path,
            format!(
                "size {width}x{height} pixels out of range ({MIN_WIDTH}x{MIN_HEIGHT} to \
                 {MAX_SIDE}x{MAX_SIDE})"
            ),
        ));
    }
    Ok(())
}

/// Whether DejaVu Sans is registered with `plotters` (done once per process; a failure is not
/// remembered, so installing the font later works without a restart).
static FONT_REGISTERED: Mutex<bool> = Mutex::new(false);

/// Registers [`FONT_PATH`] with `plotters` under the family "sans-serif" the first time it is
/// called; the font bytes are leaked once to obtain the `'static` slice `plotters` requires.
pub(crate) fn ensure_font() -> Result<()> {
    let mut done = FONT_REGISTERED.lock().unwrap_or_else(|e| e.into_inner());
    if *done {
        return Ok(());
    }
    let bytes = std::fs::read(FONT_PATH).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::Io(format!(
                "plot: font {FONT_PATH} not found: install the Debian package fonts-dejavu-core"
            ))
        } else {
            Error::Io(format!("plot: cannot read font {FONT_PATH}: {e}"))
        }
    })?;
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    plotters::style::register_font(FAMILY, FontStyle::Normal, bytes)
        .map_err(|_| Error::Io(format!("plot: font {FONT_PATH} is not a valid TrueType font")))?;
    *done = true;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels() {
        let f = linear_formatter(0.0, 5e-4);
        assert_eq!(f(&2.5e-4), "2.5e-4");
        assert_eq!(f(&0.0), "0");
        assert_eq!(f(&1e-4), "1e-4");
        let f = linear_formatter(-1.1, 1.1);
        assert_eq!(f(&0.5), "0.5");
        assert_eq!(f(&-1.0), "-1");
        assert_eq!(f(&(0.1 + 0.2)), "0.3");
        let f = linear_formatter(0.0, 2e5);
        assert_eq!(f(&150000.0), "1.5e5");
        let f = linear_formatter(0.0, 100.0);
        assert_eq!(f(&40.0), "40");
        assert_eq!(log_tick(1e-3), "1e-3");
        assert_eq!(log_tick(0.05), "0.05");
        assert_eq!(log_tick(100.0), "100");
        assert_eq!(log_tick(1e5), "1e5");
        let f = log_formatter(0.03, 1.0);
        assert_eq!(f(&0.05), "0.05");
        assert_eq!(f(&0.2), "0.2");
        assert_eq!(f(&0.3), "");
        assert_eq!(f(&1.0), "1");
        let f = log_formatter(1e-6, 1.0);
        assert_eq!(f(&1e-5), "1e-5");
        assert_eq!(f(&2e-5), "");
        let f = log_formatter(0.2, 0.8);
        assert_eq!(f(&0.3), "0.3");
    }

    #[test]
    fn log_axis_labels() {
        let close = |a: &[f64], b: &[f64]| {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-9 * y.abs())
        };
        // Within a decade: every m 10^k; 1 to 3 decades: 1, 2, 5; more: powers of ten.
        let t = log_label_ticks(0.25, 0.8, 10);
        assert!(close(&t, &[0.3, 0.4, 0.5, 0.6, 0.7, 0.8]), "{t:?}");
        let t = log_label_ticks(3.2e-6, 2.2e-4, 10);
        assert!(close(&t, &[5e-6, 1e-5, 2e-5, 5e-5, 1e-4, 2e-4]), "{t:?}");
        let t = log_label_ticks(1e-6, 1.0, 10);
        assert!(close(&t, &[1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 0.1, 1.0]), "{t:?}");
        // Too many decades for the labels: every other one.
        let t = log_label_ticks(1e-9, 1e3, 10);
        assert!(close(&t, &[1e-9, 1e-7, 1e-5, 1e-3, 0.1, 10.0, 1e3]), "{t:?}");
        // No two ticks of 1..9: half steps, then log-spaced values.
        let t = log_label_ticks(1.2, 1.8, 10);
        assert!(t.len() >= 2 && t.iter().all(|&v| (1.2..=1.8).contains(&v)), "{t:?}");
        assert!(close(&log_label_ticks(1.4, 2.6, 10), &[1.5, 2.0, 2.5]));
        // The formatter labels exactly the ticks chosen.
        for (lo, hi) in [(0.25, 0.8), (3.2e-6, 2.2e-4), (1e-6, 1.0)] {
            let f = log_formatter(lo, hi);
            assert!(log_label_ticks(lo, hi, 10).iter().all(|v| !f(v).is_empty()));
        }
        // Grid lines: every m 10^k.
        let g = log_grid_ticks(0.25, 0.8);
        assert!(close(&g, &[0.3, 0.4, 0.5, 0.6, 0.7, 0.8]), "{g:?}");
        assert_eq!(log_grid_ticks(1e-9, 1.0).len(), 10);
    }

    #[test]
    fn segment_box() {
        let b = (0.8, 1.0, 0.8, 1.0);
        assert!(segment_meets_box((0.0, 0.0), (1.0, 1.0), b));
        assert!(segment_meets_box((0.9, 0.9), (0.9, 0.9), b));
        assert!(!segment_meets_box((0.0, 0.0), (0.5, 0.5), b));
        assert!(!segment_meets_box((0.0, 0.9), (0.7, 0.9), b));
        assert!(segment_meets_box((0.0, 0.9), (0.85, 0.9), b));
        assert!(!segment_meets_box((0.0, 1.0), (1.0, 0.5), b)); // passes below the corner
    }

    #[test]
    fn ranges() {
        assert_eq!(pad_linear(2.0, 2.0, 0.05), (1.8, 2.2));
        assert_eq!(pad_linear(0.0, 0.0, 0.05), (-1.0, 1.0));
        let (lo, hi) = pad_linear(0.0, 10.0, 0.05);
        assert!((lo + 0.5).abs() < 1e-12 && (hi - 10.5).abs() < 1e-12);
        assert_eq!(pad_log(1e-3, 1e-3, 0.05), (5e-4, 2e-3));
    }

    #[test]
    fn reference_line_is_cut_to_y_range() {
        let l = reference_line((1.0, 1.0), 2.0, (0.01, 1.0), (1e-2, 2.0)).unwrap();
        assert!((l[0].0 - 0.1).abs() < 1e-12, "{l:?}");
        assert!((l[1].1 - 1.0).abs() < 1e-12);
        assert!(reference_line((1.0, 1.0), 0.0, (0.1, 1.0), (2.0, 3.0)).is_none());
    }

    #[test]
    fn thinning_keeps_extremes() {
        let pts: Vec<(f64, f64)> =
            (0..100_000).map(|i| (i as f64, if i == 500 { 9.0 } else { 0.0 })).collect();
        let t = thin_path(pts, (0.0, 100_000.0), 100);
        assert!(t.len() <= 400);
        assert!(t.contains(&(500.0, 9.0)));
        assert_eq!(t.first(), Some(&(0.0, 0.0)));
        assert_eq!(t.last(), Some(&(99_999.0, 0.0)));
    }
}

/// One point of a [`status_panels`] chart: `class` picks its colour (0 green, 1 orange, 2 red).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StatusPoint {
    pub x: f64,
    pub y: f64,
    pub class: usize,
}

/// One panel of [`status_panels`]: a caption, the points (log y) and an optional dashed
/// threshold line.
#[derive(Debug, Clone, Copy)]
pub struct StatusPanel<'a> {
    pub caption: &'a str,
    pub points: &'a [StatusPoint],
    pub threshold: Option<f64>,
}

const STATUS_COLORS: [RGBColor; 3] =
    [RGBColor(44, 160, 44), RGBColor(255, 127, 14), RGBColor(214, 39, 40)];

/// Panels of points on a log y axis over a shared x axis (e.g. one point per run), coloured
/// by class (`classes` names them in the legend), with vertical bands `(x_first, x_last,
/// name)` that group the points (e.g. the runs of one case; their names label the bottom
/// axis). Points with `y <= 0` or non-finite coordinates are skipped.
pub fn status_panels(
    path: &Path,
    title: &str,
    panels: &[StatusPanel],
    bands: &[(f64, f64, String)],
    classes: &[&str],
) -> Result<()> {
    let panel_h = 300u32;
    let label_band = 170u32;
    let width =
        (bands.iter().map(|b| b.1 - b.0 + 1.0).sum::<f64>() * 9.0).clamp(900.0, 4000.0) as u32;
    let height = panel_h * panels.len() as u32 + STACK_TITLE_BAND + label_band;
    check_size(path, width, height)?;
    let xs: Vec<f64> = panels.iter().flat_map(|p| p.points.iter().map(|q| q.x)).collect();
    if xs.is_empty() {
        return Err(nothing(path));
    }
    let (xlo, xhi) =
        xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
    let xlo = bands.first().map_or(xlo, |b| b.0.min(xlo)) - 0.5;
    let xhi = bands.last().map_or(xhi, |b| b.1.max(xhi)) + 0.5;
    ensure_font()?;
    render(path, width, height, |root| {
        let body = root.titled(title, (FAMILY, TITLE_SIZE)).map_err(|e| e.to_string())?;
        let n = panels.len() as i32;
        let breaks: Vec<i32> = (1..=n).map(|k| k * panel_h as i32).collect();
        let areas = body.split_by_breakpoints::<i32, i32, _, _>([], breaks);
        // Pixel x of each band's middle (from the last panel's coordinates) and the top of
        // the label band.
        let mut label_x: Vec<i32> = Vec::new();
        let mut label_top = 0i32;
        for (i, panel) in panels.iter().enumerate() {
            let area = &areas[i];
            let ys: Vec<f64> = panel
                .points
                .iter()
                .map(|p| p.y)
                .chain(panel.threshold)
                .filter(|y| *y > 0.0 && y.is_finite())
                .collect();
            let (lo, hi) = ys
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &y| (a.min(y), b.max(y)));
            let yr = if lo.is_finite() { pad_log(lo, hi, Y_MARGIN) } else { (1e-16, 1.0) };
            let yfmt = log_formatter(yr.0, yr.1);
            let y_area = y_label_area(area, "", &log_sample_ticks(yr), &yfmt);
            let mut chart = ChartBuilder::on(area)
                .caption(panel.caption, (FAMILY, CAPTION_SIZE))
                .margin(8)
                .margin_right(25)
                .x_label_area_size(10)
                .y_label_area_size(y_area)
                .build_cartesian_2d(xlo..xhi, LogAxis::new(yr))
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .disable_x_axis()
                .y_label_formatter(&yfmt)
                .y_labels(8)
                .label_style((FAMILY, TICK_SIZE))
                .light_line_style(RGBColor(235, 235, 235))
                .bold_line_style(RGBColor(205, 205, 205))
                .draw()
                .map_err(|e| e.to_string())?;
            for (k, b) in bands.iter().enumerate() {
                if k % 2 == 1 {
                    chart
                        .draw_series(std::iter::once(Rectangle::new(
                            [(b.0 - 0.5, yr.0), (b.1 + 0.5, yr.1)],
                            RGBColor(240, 240, 248).filled(),
                        )))
                        .map_err(|e| e.to_string())?;
                }
            }
            if let Some(t) = panel.threshold {
                chart
                    .draw_series(std::iter::once(DashedPathElement::new(
                        vec![(xlo, t), (xhi, t)],
                        8,
                        4,
                        RGBColor(214, 39, 40).stroke_width(1),
                    )))
                    .map_err(|e| e.to_string())?;
            }
            for (c, name) in classes.iter().enumerate() {
                let col = STATUS_COLORS[c.min(2)];
                let pts: Vec<(f64, f64)> = panel
                    .points
                    .iter()
                    .filter(|p| p.class == c && p.y > 0.0 && p.y.is_finite() && p.x.is_finite())
                    .map(|p| (p.x, p.y))
                    .collect();
                let s = chart
                    .draw_series(pts.into_iter().map(|p| Circle::new(p, 4, col.filled())))
                    .map_err(|e| e.to_string())?;
                if i == 0 {
                    s.label(*name).legend(move |(x, y)| Circle::new((x + 10, y), 4, col.filled()));
                }
            }
            if i + 1 == panels.len() {
                label_x = bands
                    .iter()
                    .map(|b| chart.backend_coord(&((b.0 + b.1) / 2.0, yr.0)).0)
                    .collect();
                label_top = chart.backend_coord(&(xlo, yr.0)).1 + 6;
            }
            if i == 0 {
                chart
                    .configure_series_labels()
                    .position(SeriesLabelPosition::UpperRight)
                    .background_style(WHITE.mix(0.85))
                    .border_style(RGBColor(120, 120, 120))
                    .label_font((FAMILY, LEGEND_SIZE))
                    .draw()
                    .map_err(|e| e.to_string())?;
            }
        }
        // The bands' names, rotated, under the last panel.
        let style = TextStyle::from((FAMILY, 12).into_font()).transform(FontTransform::Rotate90);
        for (b, x) in bands.iter().zip(label_x) {
            root.draw_text(&b.2, &style, (x + 6, label_top)).map_err(|e| e.to_string())?;
        }
        Ok(())
    })
}
