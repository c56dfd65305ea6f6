//! Integration tests: the plots are written as real PNG files and decoded again.

use massfree::error::Error;
use massfree::post::plot::{line_plot, loglog_plot, stacked_plots, Plot, Series};
use std::path::{Path, PathBuf};
use std::time::Instant;

fn out(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("plots");
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    let _ = std::fs::remove_file(&p);
    p
}

/// Decodes the PNG at `path` and returns (width, height, RGB pixels).
fn decode(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let bytes = std::fs::read(path).expect("PNG written");
    assert!(!bytes.is_empty(), "{} is empty", path.display());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "PNG signature");
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().expect("PNG header");
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).expect("PNG data");
    let ch = info.color_type.samples();
    assert!(ch >= 3, "colour PNG expected, got {:?}", info.color_type);
    let px = buf[..info.buffer_size()].chunks(ch).map(|c| [c[0], c[1], c[2]]).collect();
    (info.width, info.height, px)
}

/// Whether a pixel is within a small distance of `rgb`.
fn near(p: &[u8; 3], rgb: [u8; 3]) -> bool {
    (0..3).all(|i| (p[i] as i32 - rgb[i] as i32).abs() <= 8)
}

/// Number of pixels within a small distance of `rgb`.
fn count_near(px: &[[u8; 3]], rgb: [u8; 3]) -> usize {
    px.iter().filter(|p| near(p, rgb)).count()
}

const BLUE: [u8; 3] = [31, 119, 180];
const ORANGE: [u8; 3] = [255, 127, 14];
const GREEN: [u8; 3] = [44, 160, 44];

fn sin_cos(n: usize, t_end: f64) -> Vec<Series> {
    let t = |i: usize| t_end * i as f64 / (n - 1) as f64;
    let w = 2.0 * std::f64::consts::PI / t_end * 2.0;
    vec![
        Series { name: "sin".into(), points: (0..n).map(|i| (t(i), (w * t(i)).sin())).collect() },
        Series { name: "cos".into(), points: (0..n).map(|i| (t(i), (w * t(i)).cos())).collect() },
    ]
}

#[test]
fn sin_cos_line_plot() {
    let path = out("sin_cos.png");
    let series = sin_cos(400, 5e-4);
    let plot = Plot {
        title: "Displacement at probe",
        x_label: "time [s]",
        y_label: "u [m]",
        series: &series,
        width: 800,
        height: 500,
    };
    line_plot(&path, &plot).unwrap();
    let (w, h, px) = decode(&path);
    assert_eq!((w, h), (800, 500));
    let first = px[0];
    assert!(px.iter().any(|p| *p != first), "flat image");
    assert!(count_near(&px, BLUE) > 500, "sin curve (blue) missing");
    assert!(count_near(&px, ORANGE) > 500, "cos curve (orange) missing");
    // Text was rendered: dark pixels exist outside the plotting area (left strip).
    let dark_left = (0..h as usize)
        .flat_map(|y| (0..60).map(move |x| (x, y)))
        .filter(|&(x, y)| px[y * w as usize + x].iter().all(|&c| c < 100))
        .count();
    assert!(dark_left > 50, "no y-axis text");
}

#[test]
fn nan_inf_skipped_and_constant_data() {
    let path = out("constant.png");
    let series = vec![
        Series {
            name: "constant".into(),
            points: vec![(0.0, 2.0), (1.0, f64::NAN), (2.0, 2.0), (f64::INFINITY, 1.0)],
        },
        Series { name: "empty".into(), points: vec![] },
    ];
    let plot = Plot {
        title: "Constant",
        x_label: "t",
        y_label: "E",
        series: &series,
        width: 400,
        height: 300,
    };
    line_plot(&path, &plot).unwrap();
    let (w, h, px) = decode(&path);
    assert_eq!((w, h), (400, 300));
    assert!(count_near(&px, BLUE) > 100);
}

#[test]
fn stacked_three_panels() {
    let path = out("energy.png");
    let n = 300;
    let t: Vec<f64> = (0..n).map(|i| i as f64 * 1e-5).collect();
    let ek = [Series {
        name: "kinetic".into(),
        points: t.iter().map(|&t| (t, 1e3 * (1e4 * t).sin().powi(2))).collect(),
    }];
    let ep = [Series {
        name: "potential".into(),
        points: t.iter().map(|&t| (t, 1e3 * (1e4 * t).cos().powi(2))).collect(),
    }];
    let et =
        [Series { name: "total".into(), points: t.iter().map(|&t| (t, 1e3 + 1e-9 * t)).collect() }];
    let panel = |title, y_label, series| Plot {
        title,
        x_label: "time [s]",
        y_label,
        series,
        width: 800,
        height: 250,
    };
    let panels = [
        panel("kinetic", "E_k [J]", &ek[..]),
        panel("potential", "E_p [J]", &ep[..]),
        panel("total", "E [J]", &et[..]),
    ];
    stacked_plots(&path, "Energy balance", &panels).unwrap();
    let (w, h, px) = decode(&path);
    assert_eq!(w, 800);
    assert_eq!(h, 3 * 250 + 40);
    // Every panel draws its single series in the first palette colour: blue in each third.
    let third = h as usize / 3;
    for k in 0..3 {
        let rows = &px[k * third * w as usize..(k + 1) * third * w as usize];
        assert!(count_near(rows, BLUE) > 100, "panel {k} has no curve");
    }
}

#[test]
fn stacked_with_empty_panel_and_single_points() {
    let path = out("stacked_sparse.png");
    let one = [Series { name: "single".into(), points: vec![(1.0, 5.0)] }];
    let none = [Series { name: "none".into(), points: vec![(f64::NAN, 1.0)] }];
    let panel = |series| Plot {
        title: "",
        x_label: "step",
        y_label: "value",
        series,
        width: 500,
        height: 200,
    };
    stacked_plots(&path, "sparse", &[panel(&one[..]), panel(&none[..])]).unwrap();
    let (w, h, px) = decode(&path);
    assert_eq!((w, h), (500, 440));
    // The dot at (1, 5) is in the middle of the top panel, below the legend.
    let middle = &px[90 * w as usize..150 * w as usize];
    assert!(count_near(middle, BLUE) >= 9, "single point not drawn");
}

#[test]
fn loglog_with_reference_slopes() {
    let path = out("convergence.png");
    let hs: Vec<f64> = (0..6).map(|k| 0.5f64.powi(k)).collect();
    let series = vec![
        Series { name: "L2 error".into(), points: hs.iter().map(|&h| (h, 0.3 * h * h)).collect() },
        Series {
            name: "H1 error".into(),
            points: hs.iter().map(|&h| (h, 0.8 * h)).chain([(0.0, 1.0), (1.0, -1.0)]).collect(),
        },
    ];
    let plot = Plot {
        title: "Convergence",
        x_label: "h",
        y_label: "error",
        series: &series,
        width: 700,
        height: 500,
    };
    loglog_plot(&path, &plot, &[1.0, 2.0]).unwrap();
    let (w, h, px) = decode(&path);
    assert_eq!((w, h), (700, 500));
    assert!(count_near(&px, BLUE) > 200);
    assert!(count_near(&px, ORANGE) > 200);
    assert!(count_near(&px, [60, 60, 60]) > 100, "reference lines missing");
    // Only non-positive points: error.
    let bad = vec![Series { name: "x".into(), points: vec![(0.0, 1.0), (1.0, 0.0)] }];
    let err = loglog_plot(&out("bad_loglog.png"), &Plot { series: &bad, ..plot }, &[1.0]);
    assert!(matches!(err, Err(Error::Io(ref m)) if m.contains("nothing to plot")), "{err:?}");
}

#[test]
fn empty_input_is_an_error() {
    let path = out("empty.png");
    let plot =
        Plot { title: "t", x_label: "x", y_label: "y", series: &[], width: 400, height: 300 };
    for res in [line_plot(&path, &plot), loglog_plot(&path, &plot, &[1.0])] {
        match res {
            Err(Error::Io(m)) => {
                assert!(m.contains("nothing to plot"), "{m}");
                assert!(m.contains("empty.png"), "{m}");
            }
            other => panic!("expected Io error, got {other:?}"),
        }
    }
    let nan_only = vec![
        Series { name: "a".into(), points: vec![(f64::NAN, 1.0), (1.0, f64::INFINITY)] },
        Series { name: "b".into(), points: vec![] },
    ];
    let err = line_plot(&path, &Plot { series: &nan_only, ..plot }).unwrap_err();
    assert!(matches!(err, Error::Io(ref m) if m.contains("nothing to plot")));
    let err = stacked_plots(&path, "none", &[]).unwrap_err();
    assert!(matches!(err, Error::Io(ref m) if m.contains("nothing to plot")));
    let err = stacked_plots(&path, "none", &[Plot { series: &nan_only, ..plot }]).unwrap_err();
    assert!(matches!(err, Error::Io(ref m) if m.contains("nothing to plot")));
    assert!(!path.exists());
}

#[test]
fn missing_directory_is_an_error() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("no/such/dir/plot.png");
    let series = sin_cos(10, 1.0);
    let plot =
        Plot { title: "t", x_label: "x", y_label: "y", series: &series, width: 400, height: 300 };
    match line_plot(&path, &plot) {
        Err(Error::Io(m)) => assert!(m.contains("no/such/dir/plot.png"), "{m}"),
        other => panic!("expected Io error, got {other:?}"),
    }
    // A path that exists as a directory cannot be written either.
    let dir = out("a_directory.png");
    std::fs::create_dir_all(&dir).unwrap();
    match line_plot(&dir, &plot) {
        Err(Error::Io(m)) => assert!(m.contains("a_directory.png"), "{m}"),
        other => panic!("expected Io error, got {other:?}"),
    }
}

#[test]
fn bad_size_is_an_error() {
    let series = sin_cos(10, 1.0);
    let plot =
        Plot { title: "t", x_label: "x", y_label: "y", series: &series, width: 0, height: 300 };
    assert!(matches!(line_plot(&out("size.png"), &plot), Err(Error::Io(_))));
}

/// The noise series of [`many_points_keep_their_envelope`]: `((i * 7919) mod 1000) / 1000 -
/// 0.5`. 7919 = -81 (mod 1000) and is prime to 1000: the values take every step of 0.001 in
/// [-0.5, 0.499], and they wrap around once every 12 or 13 points, so any 13 consecutive points
/// reach below -0.5 + 0.081 and above 0.499 - 0.081.
fn noise(i: usize) -> f64 {
    ((i * 7919) % 1000) as f64 / 1000.0 - 0.5
}

/// Rows of the pixels of colour `rgb` in each column: (top, bottom) or `None`.
fn column_extents(w: u32, h: u32, px: &[[u8; 3]], rgb: [u8; 3]) -> Vec<Option<(usize, usize)>> {
    let (w, h) = (w as usize, h as usize);
    (0..w)
        .map(|x| {
            let rows = (0..h).filter(|&y| near(&px[y * w + x], rgb));
            rows.fold(None, |e, y| match e {
                None => Some((y, y)),
                Some((a, b)) => Some((a.min(y), b.max(y))),
            })
        })
        .collect()
}

#[test]
fn many_points_keep_their_envelope() {
    let path = out("many.png");
    let n = 100_000;
    let mut series = sin_cos(n, 1.0);
    // The noise is drawn last (on top), in the third palette colour. No names: no legend box
    // over the curves.
    series.push(Series {
        name: String::new(),
        points: (0..n).map(|i| (i as f64 / (n - 1) as f64, noise(i))).collect(),
    });
    for s in &mut series {
        s.name.clear();
    }
    let plot = Plot {
        title: "10^5 points per series",
        x_label: "t",
        y_label: "u",
        series: &series,
        width: 1200,
        height: 700,
    };
    // The time is printed, not checked (timings are for benchmarks).
    let start = Instant::now();
    line_plot(&path, &plot).unwrap();
    eprintln!("3 x 10^5-point line plot: {:.3} s", start.elapsed().as_secs_f64());
    let (w, h, px) = decode(&path);
    assert_eq!((w, h), (1200, 700));
    // Thinned or not, the picture must show the noise's envelope everywhere. Its columns at
    // most one pixel wide (1200 pixels, 10^5 points: about 90 points each), each lies within
    // two adjacent pixel columns, so any three adjacent pixel columns hold one whole data
    // column, whose points (more than 13) reach -0.419 and +0.418 (`noise`). The curve is a
    // 1-pixel path through the kept points plus copies one pixel right and down: its top
    // pixel is the global maximum 0.499, its bottom pixel one below the minimum -0.5, which
    // calibrates the rows; a point is within half a pixel of its row.
    let ext = column_extents(w, h, &px, GREEN);
    let cols: Vec<usize> = (0..w as usize).filter(|&x| ext[x].is_some()).collect();
    let (first, last) = (cols[0], *cols.last().unwrap());
    let top = ext.iter().flatten().map(|e| e.0).min().unwrap() as f64;
    let bottom = ext.iter().flatten().map(|e| e.1).max().unwrap() as f64 - 1.0;
    assert!(bottom - top > 100.0, "the noise band is {} pixels high", bottom - top);
    let row = |v: f64| top + (0.499 - v) / 0.999 * (bottom - top);
    let (high, low) = (row(0.499 - 0.081), row(-0.5 + 0.081));
    let mut thinnest = f64::INFINITY;
    for c in first..=last - 2 {
        let window = ext[c..c + 3].iter().flatten();
        let (t, b) = window.fold((usize::MAX, 0), |(t, b), e| (t.min(e.0), b.max(e.1)));
        assert!(
            t as f64 <= high + 1.0 && b as f64 >= low - 1.0,
            "pixel columns {c}-{}: the noise drawn between rows {t} and {b}, its envelope spans rows {high:.1} to {low:.1} (the band {top}-{bottom})",
            c + 2
        );
        thinnest = thinnest.min((b - t) as f64 / (bottom - top));
    }
    eprintln!(
        "noise band rows {top}-{bottom}, columns {first}-{last}; every 3 columns span at least {thinnest:.3} of it (at least (0.999 - 2 x 0.081) / 0.999 = 0.838)"
    );
}
