//! The stress-type output fields through the program: exact uniform stress for exact linear
//! displacements on every element kind (cells and nodal projection, two materials), the
//! convergence of the beam's stress (paper 7.1) against its exact stress, the same files on
//! 1 and 2 ranks, and the stress timing (zero when no stress field is asked for).
#![allow(clippy::needless_range_loop)] // small dense tensors

mod common;
use common::*;
use massfree::fem::ElementKind;
use std::path::Path;

/// Every stress-type field, cell values and nodal projections.
const ALL_STRESS: &str = "fields = [\"displacement\", \"stress\", \"strain\", \"von_mises\", \
     \"effective_stress\", \"pressure\", \"stress_nodal\", \"strain_nodal\", \"von_mises_nodal\", \
     \"effective_stress_nodal\", \"pressure_nodal\"]";

/// A field of a run's file: (rows, components, values of each written step).
fn field(h5: &Path, name: &str) -> (usize, usize, Vec<Vec<f64>>) {
    let f = reader(h5);
    let d = f.file.dataset(&layout::field(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
    let shape = d.shape();
    let all = d.read_raw::<f64>().unwrap();
    let per = shape[1] * shape[2];
    (shape[1], shape[2], all.chunks(per).map(<[f64]>::to_vec).collect())
}

/// Lame parameters (docs/method.md, the problem): lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu)).
fn lame(e: f64, nu: f64) -> (f64, f64) {
    (e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu)))
}

type T3 = [[f64; 3]; 3];

/// The six stored components, in the documented order xx, xy, xz, yy, yz, zz.
fn six(t: &T3) -> [f64; 6] {
    [t[0][0], t[0][1], t[0][2], t[1][1], t[1][2], t[2][2]]
}

fn hooke(eps: &T3, lambda: f64, mu: f64) -> T3 {
    let tr = eps[0][0] + eps[1][1] + eps[2][2];
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = 2.0 * mu * eps[i][j] + if i == j { lambda * tr } else { 0.0 };
        }
    }
    s
}

/// von Mises, effective stress (in-plane in 2D) and pressure of a stress, written out.
fn invariants(s: &T3, d: usize) -> [f64; 3] {
    let vm =
        (((s[0][0] - s[1][1]).powi(2) + (s[1][1] - s[2][2]).powi(2) + (s[2][2] - s[0][0]).powi(2))
            / 2.0
            + 3.0 * (s[0][1].powi(2) + s[1][2].powi(2) + s[0][2].powi(2)))
        .sqrt();
    let m = (0..d).map(|i| s[i][i]).sum::<f64>() / d as f64;
    let mut eff = 0.0;
    for i in 0..d {
        for j in 0..d {
            eff += (s[i][j] - if i == j { m } else { 0.0 }).powi(2);
        }
    }
    [vm, eff, -(s[0][0] + s[1][1] + s[2][2]) / 3.0]
}

/// The displacement gradient of the patch tests (d x d part used).
const G: T3 = [[0.011, -0.023, 0.017], [0.031, 0.005, -0.013], [-0.007, 0.019, 0.029]];
const C: [f64; 3] = [0.1, -0.2, 0.3];

/// `u = G x + c` as the scene's expressions.
fn linear_field(d: usize) -> String {
    let axes = ["x", "y", "z"];
    let comps: Vec<String> = (0..d)
        .map(|i| {
            let terms: Vec<String> = (0..d).map(|j| format!("{}*{}", G[i][j], axes[j])).collect();
            format!("\"{} + {}\"", C[i], terms.join(" + "))
        })
        .collect();
    format!("[{}]", comps.join(", "))
}

/// A body whose whole boundary (`groups`) holds `u = G x + c` (`field`: the scene's
/// expressions, [`linear_field`] by default), starting there at rest: the exact solution is
/// that static field, so every written step must hold its strain and stress (per body
/// material) in every cell and at every node.
fn patch_scene(
    dir: &Path,
    name: &str,
    mesh: &str,
    d: usize,
    groups: &[&str],
    bodies: &str,
) -> std::path::PathBuf {
    patch_scene_with(dir, name, mesh, groups, bodies, &linear_field(d))
}

fn patch_scene_with(
    dir: &Path,
    name: &str,
    mesh: &str,
    groups: &[&str],
    bodies: &str,
    u: &str,
) -> std::path::PathBuf {
    let dirichlet: String =
        groups.iter().map(|g| format!("[[dirichlet]]\ngroup = \"{g}\"\nvalue = {u}\n")).collect();
    let text = format!(
        "name = \"{name}\"\n[mesh]\n{mesh}\n[material]\nE = 100.0\nnu = 0.3\nrho = 1.0\n{bodies}\n{dirichlet}\
         [initial]\ndisplacement = {u}\n[time]\ntau = 1e-2\nsteps = 3\n[output]\nevery = 1\n{ALL_STRESS}\n"
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

/// Check every stress field of `h5` at its first `steps` written steps against the state of
/// the displacement gradient `grad(cell centroid)` (G for the linear field) with the material
/// `material(cell centroid)` (E, nu): cells exactly, nodes for a single material (a node on two
/// materials averages two stresses).
fn check_patch(
    h5: &Path,
    d: usize,
    steps: usize,
    material: &dyn Fn([f64; 3]) -> (f64, f64),
    grad: &dyn Fn([f64; 3]) -> T3,
) -> usize {
    let f = reader(h5);
    let coords = f.coordinates().unwrap();
    let cells = f.cells().unwrap();
    let state = |x: [f64; 3]| {
        let g = grad(x);
        let mut eps = [[0.0; 3]; 3];
        for i in 0..d {
            for j in 0..d {
                eps[i][j] = 0.5 * (g[i][j] + g[j][i]);
            }
        }
        let (e, nu) = material(x);
        let (l, m) = lame(e, nu);
        let s = hooke(&eps, l, m);
        let mut v: Vec<Vec<f64>> = vec![six(&s).to_vec(), six(&eps).to_vec()];
        v.extend(invariants(&s, d).iter().map(|&x| vec![x]));
        v
    };
    let names = ["stress", "strain", "von_mises", "effective_stress", "pressure"];
    let one_material = {
        let m0 = material(coords[0]);
        cells.iter().all(|(_, c)| material(centroid(&coords, c)) == m0)
    };
    let mut checked = 0;
    let n_steps = steps;
    for (k, name) in names.iter().enumerate() {
        let (rows, comps, steps) = field(h5, name);
        assert_eq!(rows, cells.len(), "{name}: one row per cell");
        assert_eq!(comps, if k < 2 { 6 } else { 1 }, "{name}");
        assert_eq!(steps.len(), 4, "{name}: steps 0..3");
        let scale = steps[0].iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        assert!(scale > 0.0);
        for (step, vals) in steps[..n_steps].iter().enumerate() {
            for (i, (_, c)) in cells.iter().enumerate() {
                let want = &state(centroid(&coords, c))[k];
                for j in 0..comps {
                    let got = vals[i * comps + j];
                    assert!(
                        (got - want[j]).abs() <= 1e-9 * scale,
                        "{name}[cell {i}][{j}] = {got} at written step {step}, exact {}",
                        want[j]
                    );
                    checked += 1;
                }
            }
        }
        let (rows, comps, steps) = field(h5, &format!("{name}_nodal"));
        assert_eq!(rows, coords.len(), "{name}_nodal: one row per node");
        if one_material {
            let want = &state(coords[0])[k];
            for vals in &steps[..n_steps] {
                for i in 0..rows {
                    for j in 0..comps {
                        let got = vals[i * comps + j];
                        assert!(
                            (got - want[j]).abs() <= 1e-9 * scale,
                            "{name}_nodal[node {i}][{j}] = {got}, exact {}",
                            want[j]
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    checked
}

fn centroid(coords: &[[f64; 3]], cell: &[usize]) -> [f64; 3] {
    let mut c = [0.0; 3];
    for &v in cell {
        for i in 0..3 {
            c[i] += coords[v][i] / cell.len() as f64;
        }
    }
    c
}

#[test]
fn patch_test_every_kind_exact_stress_in_every_cell_and_node() {
    let dir = scratch("stress-patch");
    let steel = |_: [f64; 3]| (100.0, 0.3);
    let cases = [
        (
            "quads",
            "geo = \"../meshes/disc_quad.geo\"\nparams = { h = 2.0, hc = 0.5 }",
            2,
            vec!["contact", "free", "top"],
        ),
        (
            "triangles",
            "geo = \"../meshes/disc_tri.geo\"\nparams = { h = 2.0, hc = 0.5 }",
            2,
            vec!["contact", "free", "top"],
        ),
        (
            "tets",
            "geo = \"../meshes/sphere_tet.geo\"\nparams = { h = 0.4, hc = 0.2 }",
            3,
            vec!["contact", "free"],
        ),
        (
            "hexes",
            "geo = \"../meshes/sphere_hex.geo\"\nparams = { h = 0.8, hc = 0.4 }",
            3,
            vec!["contact", "free"],
        ),
    ];
    for (name, mesh, d, groups) in cases {
        let scene = patch_scene(&dir, name, mesh, d, &groups, "");
        // 2 ranks: the nodal projection sums over cells of both ranks.
        run_scene(2, &scene, &[]);
        let h5 = dir.join(format!("{name}-2.h5"));
        let kinds: Vec<ElementKind> = reader(&h5).cells().unwrap().iter().map(|c| c.0).collect();
        let n = check_patch(&h5, d, 4, &steel, &|_| G);
        eprintln!("{name}: {} cells ({:?}), {n} values exact", kinds.len(), kinds[0]);
    }
}

/// The patch test of two materials side by side (E = 100, nu = 0.3 left of x = 1/2, E = 300,
/// nu = 0.2 right of it, plane strain): `u = c + G x` on the left, `c + G x + a (x - 1/2)` on
/// the right. Continuous (only d/dx jumps, by `a`) and, with `a` chosen so that the traction
/// `sigma e_x` is the same on both sides of the interface, a static equilibrium without body
/// force: each side's stress is uniform, and across the interface the tractions cancel. The
/// mesh has the interface as a line, so the discrete solution is that field exactly (every
/// interior node's residual is a sum of cancelling tractions): starting there at rest with the
/// field on the whole boundary, the body stays, and every solved step holds it.
///
/// `a`: `sigma_xy` continuous: `2 mu_R (eps_xy + a_y / 2) = sigma_xy`, so
/// `a_y = sigma_xy / mu_R - 2 eps_xy`; `sigma_xx` continuous:
/// `(lambda_R + 2 mu_R)(eps_xx + a_x) + lambda_R eps_yy = sigma_xx`, with eps and sigma the
/// left side's.
fn two_material_jump() -> [f64; 2] {
    let eps = |i: usize, j: usize| 0.5 * (G[i][j] + G[j][i]);
    let (l, m) = lame(100.0, 0.3);
    let (lr, mr) = lame(300.0, 0.2);
    let (sxx, sxy) = ((l + 2.0 * m) * eps(0, 0) + l * eps(1, 1), 2.0 * m * eps(0, 1));
    [(sxx - lr * eps(1, 1)) / (lr + 2.0 * mr) - eps(0, 0), sxy / mr - 2.0 * eps(0, 1)]
}

/// Two materials side by side on an unstructured mesh of quadrangles (left, first in the
/// mesh) and triangles (right; first in the file, which stores kinds in gmsh type order), in
/// the equilibrium of `two_material_jump`: every cell holds its own material's stress of its
/// side's strain at the start and at every solved step.
#[test]
fn patch_test_two_materials_and_mixed_cells() {
    let dir = scratch("stress-patch-bodies");
    let geo = dir.join("halves.geo");
    std::fs::write(
        &geo,
        "h = 0.2;\n\
         Point(1) = {0, 0, 0, h}; Point(2) = {0.5, 0, 0, h}; Point(3) = {1, 0, 0, h};\n\
         Point(4) = {1, 1, 0, h}; Point(5) = {0.5, 1, 0, h}; Point(6) = {0, 1, 0, h};\n\
         Line(1) = {1, 2}; Line(2) = {2, 3}; Line(3) = {3, 4}; Line(4) = {4, 5};\n\
         Line(5) = {5, 6}; Line(6) = {6, 1}; Line(7) = {2, 5};\n\
         Curve Loop(1) = {1, 7, 5, 6}; Plane Surface(1) = {1};\n\
         Curve Loop(2) = {2, 3, 4, -7}; Plane Surface(2) = {2};\n\
         Recombine Surface{1};\n\
         Physical Surface(\"soft\") = {1}; Physical Surface(\"stiff\") = {2};\n\
         Physical Curve(\"boundary\") = {1, 2, 3, 4, 5, 6};\n",
    )
    .unwrap();
    let a = two_material_jump();
    let u: Vec<String> = (0..2)
        .map(|i| {
            format!(
                "\"{} + {}*x + {}*y + {}*(x - 0.5 + abs(x - 0.5))/2\"",
                C[i], G[i][0], G[i][1], a[i]
            )
        })
        .collect();
    let scene = patch_scene_with(
        &dir,
        "halves",
        "geo = \"halves.geo\"",
        &["boundary"],
        "[[body]]\ngroup = \"stiff\"\nE = 300.0\nnu = 0.2",
        &format!("[{}]", u.join(", ")),
    );
    run_scene(2, &scene, &["--", "-ksp_rtol", "1e-12"]);
    let h5 = dir.join("halves-2.h5");
    let kinds: Vec<ElementKind> = reader(&h5).cells().unwrap().iter().map(|c| c.0).collect();
    assert!(
        kinds.contains(&ElementKind::Tri3) && kinds.contains(&ElementKind::Quad4),
        "mixed mesh"
    );
    let right = |x: [f64; 3]| x[0] > 0.5;
    let grad = |x: [f64; 3]| {
        let mut g = G;
        if right(x) {
            g[0][0] += a[0];
            g[1][0] += a[1];
        }
        g
    };
    // Step 0 (the prescribed field) and the three solved steps.
    check_patch(&h5, 2, 4, &|x| if right(x) { (300.0, 0.2) } else { (100.0, 0.3) }, &grad);
}

// ---------------------------------------------------------------------------------------------
// The beam of section 7.1.

/// Gauss-Legendre on [-1, 1], 4 points (exact to degree 7).
const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
];

/// Points (shape values of the cell's nodes, physical point, weight) of a rule on a cell:
/// 4 x 4 Gauss on the bilinear quad, collapsed (Duffy) 4 x 4 Gauss on the triangle.
fn rule(kind: ElementKind, x: &[[f64; 3]]) -> Vec<(Vec<f64>, [f64; 2], f64)> {
    let mut pts = Vec::new();
    for &(a, wa) in &GL4 {
        for &(b, wb) in &GL4 {
            let (n, dn, w): (Vec<f64>, Vec<[f64; 2]>, f64) = match kind {
                ElementKind::Quad4 => {
                    let s = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
                    let n = s.iter().map(|p| (1.0 + p[0] * a) * (1.0 + p[1] * b) / 4.0).collect();
                    let dn = s
                        .iter()
                        .map(|p| [p[0] * (1.0 + p[1] * b) / 4.0, p[1] * (1.0 + p[0] * a) / 4.0])
                        .collect();
                    (n, dn, wa * wb)
                }
                ElementKind::Tri3 => {
                    // (s, t) in [0, 1]^2 -> xi = s, eta = t (1 - s), Jacobian 1 - s.
                    let (s, t) = ((a + 1.0) / 2.0, (b + 1.0) / 2.0);
                    let (xi, eta) = (s, t * (1.0 - s));
                    let n = vec![1.0 - xi - eta, xi, eta];
                    (n, vec![[-1.0, -1.0], [1.0, 0.0], [0.0, 1.0]], wa * wb / 4.0 * (1.0 - s))
                }
                _ => unreachable!(),
            };
            let mut j = [[0.0; 2]; 2];
            let mut p = [0.0; 2];
            for k in 0..n.len() {
                for r in 0..2 {
                    p[r] += n[k] * x[k][r];
                    for c in 0..2 {
                        j[r][c] += x[k][r] * dn[k][c];
                    }
                }
            }
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            assert!(det > 0.0);
            pts.push((n, p, w * det));
        }
    }
    pts
}

/// The exact stress of the beam, `u = (0, 0.02 x (10 - x) y^2 sin(2 pi t))`, E = 200, nu = 0.3,
/// plane strain.
fn beam_stress(p: [f64; 2], t: f64) -> [f64; 6] {
    let (l, m) = (1500.0 / 13.0, 1000.0 / 13.0);
    let s = (2.0 * std::f64::consts::PI * t).sin();
    let (x, y) = (p[0], p[1]);
    let wx = 0.02 * (10.0 - 2.0 * x) * y * y * s;
    let wy = 0.04 * x * (10.0 - x) * y * s;
    // eps_yy = wy, eps_xy = wx / 2.
    [l * wy, m * wx, 0.0, (l + 2.0 * m) * wy, 0.0, l * wy]
}

/// |a|^2 of a symmetric tensor stored as six components (off-diagonal entries twice).
fn norm2(a: &[f64]) -> f64 {
    let w = [1.0, 2.0, 2.0, 1.0, 2.0, 1.0];
    (0..6).map(|k| w[k] * a[k] * a[k]).sum()
}

/// L2 errors of the cell stress and of the nodal stress against the exact stress at the last
/// written step.
fn beam_errors(h5: &Path, t: f64) -> (f64, f64) {
    let f = reader(h5);
    let coords = f.coordinates().unwrap();
    let cells = f.cells().unwrap();
    let (_, _, cell) = field(h5, "stress");
    let (_, _, nodal) = field(h5, "stress_nodal");
    let (cell, nodal) = (cell.last().unwrap(), nodal.last().unwrap());
    let times = f.series(&layout::field_time("stress")).unwrap();
    assert!((times.last().unwrap() - t).abs() < 1e-12);
    let (mut ec, mut en) = (0.0, 0.0);
    for (i, (kind, nodes)) in cells.iter().enumerate() {
        let x: Vec<[f64; 3]> = nodes.iter().map(|&v| coords[v]).collect();
        for (n, p, w) in rule(*kind, &x) {
            let exact = beam_stress(p, t);
            let dc: Vec<f64> = (0..6).map(|k| exact[k] - cell[i * 6 + k]).collect();
            let dn: Vec<f64> = (0..6)
                .map(|k| {
                    exact[k] - (0..n.len()).map(|a| n[a] * nodal[nodes[a] * 6 + k]).sum::<f64>()
                })
                .collect();
            ec += w * norm2(&dc);
            en += w * norm2(&dn);
        }
    }
    (ec.sqrt(), en.sqrt())
}

#[test]
fn beam_stress_converges_at_rate_one() {
    let dir = scratch("stress-beam");
    let t = 30.0 * 1e-5;
    for (scene_name, mesh) in [("beam.toml", "quads"), ("beam_tri.toml", "triangles")] {
        let mut errs = Vec::new();
        for h in [0.5, 0.25, 0.125] {
            let sub = dir.join(format!("{mesh}-{h}"));
            std::fs::create_dir_all(&sub).unwrap();
            let scene = scene_variant(
                scene_name,
                &sub,
                &[
                    ("steps = 250", "steps = 30"),
                    ("error_steps = [30, 250]", "error_steps = [30]"),
                    ("every = 10", "every = 30\nfields = [\"stress\", \"stress_nodal\"]"),
                ],
            );
            run_scene(1, &scene, &["--param", &format!("h={h}")]);
            let stem = scene.file_stem().unwrap().to_string_lossy().to_string();
            errs.push(beam_errors(&sub.join(format!("{stem}-1.h5")), t));
        }
        let rate = |a: f64, b: f64| (a / b).log2();
        for k in 1..errs.len() {
            let (rc, rn) = (rate(errs[k - 1].0, errs[k].0), rate(errs[k - 1].1, errs[k].1));
            eprintln!(
                "beam {mesh}: h = 1/{}: cell L2 {:.4e} (rate {rc:.3}), nodal L2 {:.4e} (rate {rn:.3})",
                1 << (k + 1),
                errs[k].0,
                errs[k].1
            );
            // Theory: the cell values are piecewise constant, first order in L2; the lumped
            // projection is second order at interior nodes (the averaged gradient is
            // superconvergent there) and first order only at the boundary nodes, a strip of
            // width h: h * h^(1/2) in L2, rate 3/2. So it converges faster, at every level.
            // (Which of the two errors is smaller on a given mesh depends on constants theory
            // does not give: not asserted.)
            assert!(rn > rc, "{mesh}: nodal rate {rn} not above the cell rate {rc}: {errs:?}");
            assert!(rc > 0.85, "{mesh}: cell stress rate {rc} at level {k}: {errs:?}");
            assert!(rn >= 0.85, "{mesh}: nodal stress rate {rn} at level {k}: {errs:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Rank independence and timing.

/// Largest difference between the stress fields of two runs, relative to each field's largest
/// value; also checks the fields' step axes agree.
fn max_rel_diff(a: &Path, b: &Path, names: &[&str]) -> f64 {
    let mut worst: f64 = 0.0;
    for name in names {
        let (ra, ca, va) = field(a, name);
        let (rb, cb, vb) = field(b, name);
        assert_eq!((ra, ca, va.len()), (rb, cb, vb.len()), "{name}");
        let sa = values(a, &layout::field_step(name));
        assert_eq!(sa, values(b, &layout::field_step(name)), "{name} steps");
        let scale = va.iter().flatten().fold(0.0f64, |m, &x| m.max(x.abs()));
        assert!(scale > 0.0, "{name} is zero");
        for (x, y) in va.iter().flatten().zip(vb.iter().flatten()) {
            worst = worst.max((x - y).abs() / scale);
        }
    }
    worst
}

const NAMES: [&str; 10] = [
    "stress",
    "strain",
    "von_mises",
    "effective_stress",
    "pressure",
    "stress_nodal",
    "strain_nodal",
    "von_mises_nodal",
    "effective_stress_nodal",
    "pressure_nodal",
];

#[test]
fn one_and_two_ranks_write_the_same_stress() {
    let dir = scratch("stress-ranks");
    // The disc through its impact (contact from step 63), and the ball on the plane (contact
    // from step 1), with per-field periods.
    let periods = "field_every = { von_mises = 20, stress_nodal = 40, pressure = 30 }";
    let disc = scene_variant(
        "disc.toml",
        &dir,
        &[
            ("steps = 1000", "steps = 120"),
            ("every = 10", &format!("every = 10\n{periods}\n{ALL_STRESS}")),
        ],
    );
    let ball = scene_variant(
        "sphere.toml",
        &dir,
        &[("steps = 220", "steps = 30"), ("every = 10", &format!("every = 10\n{ALL_STRESS}"))],
    );
    // The ball's contact steps use block Jacobi/ILU(0) with a block per rank: 1 and 2 ranks
    // differ by the solver's error, so its solves go to 1e-13 (the disc's Jacobi is the same on
    // any rank count).
    for (scene, rtol) in [(disc, None), (ball, Some("1e-13"))] {
        let stem = scene.file_stem().unwrap().to_string_lossy().to_string();
        let args: Vec<&str> = rtol.map_or(vec![], |r| vec!["--", "-ksp_rtol", r]);
        run_scene(1, &scene, &args);
        run_scene(2, &scene, &args);
        let (a, b) = (dir.join(format!("{stem}-1.h5")), dir.join(format!("{stem}-2.h5")));
        let d = max_rel_diff(&a, &b, &NAMES);
        eprintln!(
            "{stem}: 1 vs 2 ranks: largest stress difference {d:.2e} of the field's largest value"
        );
        assert!(d < 1e-10, "{stem}: {d}");
        if stem == "disc" {
            assert_eq!(
                values(&a, &layout::field_step("von_mises")),
                vec![0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0]
            );
            assert_eq!(
                values(&a, &layout::field_step("stress_nodal")),
                vec![0.0, 40.0, 80.0, 120.0]
            );
            assert_eq!(
                values(&a, &layout::field_step("pressure")),
                vec![0.0, 30.0, 60.0, 90.0, 120.0]
            );
        }
    }
}

#[test]
fn stress_time_is_reported_and_zero_without_stress_fields() {
    let dir = scratch("stress-timing");
    let short = [("steps = 250", "steps = 20"), ("error_steps = [30, 250]", "error_steps = [20]")];
    let plain = scene_variant("beam.toml", &dir, &short);
    let s = run_scene(2, &plain, &["--param", "h=0.25"]);
    // Exactly zero, no clock involved: the stress timer runs only around stress work, so this
    // fails exactly when a run without stress fields does some.
    assert_eq!(s.timings.stress, 0.0, "no stress field, no stress work");
    let h5 = dir.join("beam-2.h5");
    assert!(
        reader(&h5).text("timings").contains("stress = 0e0"),
        "{}",
        reader(&h5).text("timings")
    );
    let sub = dir.join("with");
    std::fs::create_dir_all(&sub).unwrap();
    let with = scene_variant(
        "beam.toml",
        &sub,
        &[
            short[0],
            short[1],
            (
                "every = 10",
                "every = 10\nfields = [\"displacement\", \"von_mises\", \"von_mises_nodal\"]",
            ),
        ],
    );
    let s = run_scene(2, &with, &["--param", "h=0.25"]);
    // Reported: the stress work of the three written steps is timed (it stays 0 if untimed).
    assert!(s.timings.stress > 0.0, "{:?}", s.timings);
    let h5 = sub.join("beam-2.h5");
    let line = reader(&h5).text("timings");
    assert!(line.lines().any(|l| l.starts_with("stress = ") && l != "stress = 0e0"), "{line}");
    // Written at steps 0, 10, 20 only.
    assert_eq!(values(&h5, &layout::field_step("von_mises_nodal")), vec![0.0, 10.0, 20.0]);
    // `post --node` follows the nodal fields (a cell field has no node values).
    let h5s = h5.display().to_string();
    let o = massfree(0, &["post", &h5s, "--node", "5,1"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = std::fs::read_dir(&sub)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.to_string_lossy().ends_with("-von_mises_nodal.csv"))
        .expect("node CSV of von_mises_nodal");
    let text = std::fs::read_to_string(csv).unwrap();
    assert!(text.starts_with("time,von_mises_nodal\n"), "{text}");
    assert_eq!(text.lines().count(), 4);
    let o = massfree(0, &["post", &h5s, "--node", "5,1", "--field", "von_mises"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("a cell field") && err.contains("von_mises_nodal"),
        "{err}"
    );
}
