//! Rigid obstacles (issue 11): a wall that moves into a block gives the static reaction, two
//! obstacles at once act as mirror images, a cylinder in 3D touches along its top line; the
//! energy balance and impulse = momentum change close in every run.

mod common;
use common::*;
use massfree::contact::history::ContactSummary;
use ndarray::Array2;
use std::path::{Path, PathBuf};

fn contact(s: &RunSummary) -> &ContactSummary {
    s.contact.as_ref().expect("a [contact] summary")
}

/// `contact/<name>` as rows (steps + 1) x contact nodes.
fn contact_table(h5: &Path, name: &str) -> Array2<f64> {
    reader(h5).table(&layout::contact(name)).unwrap_or_else(|e| panic!("{e}"))
}

/// The contact nodes' reference coordinates.
fn contact_coords(h5: &Path) -> Vec<[f64; 3]> {
    let run = reader(h5);
    let coords = run.coordinates().unwrap();
    run.series(layout::CONTACT_NODES).unwrap().iter().map(|&v| coords[v as usize]).collect()
}

/// The rest of the scene "wall": the square (0,1)^2 of `small_scene` (plane strain, h = 1/8)
/// on rollers (the bottom slides along x, the left side along y) and a frictionless wall on
/// its top that moves down at V = 1e-3 from t = 0, for 10 time units.
const WALL: &str = r#"
[[dirichlet]]
group = "bottom"
components = ["y"]
[[dirichlet]]
group = "left"
components = ["x"]
[time]
tau = 1e-2
steps = 1000
[mass]
kind = "modified1"
[contact]
boundary = "top"
obstacle = { type = "plane", point = [0.0, 1.0], normal = [0.0, -1.0], motion = ["0", "-1e-3*t"] }
[output]
every = 100
"#;

#[test]
fn a_wall_pushed_slowly_into_a_block_gives_the_static_reaction() {
    // The static state. Rollers and a frictionless wall leave the block free to expand along
    // x, so for a compression d of the height H the state is homogeneous: u_y = -d y / H,
    // eps_yy = -d/H, sigma_xx = 0 (free right side), eps_zz = 0 (plane strain). Hooke with
    // Lame's lambda, mu: sigma_xx = lambda (eps_xx + eps_yy) + 2 mu eps_xx = 0 gives
    // eps_xx = -lambda eps_yy / (lambda + 2 mu), then
    // sigma_yy = (lambda + 2 mu) eps_yy + lambda eps_xx = 4 mu (lambda + mu) / (lambda + 2 mu) eps_yy
    //          = E / (1 - nu^2) eps_yy,
    // and the wall takes F = E / (1 - nu^2) W d / H (per unit thickness). Bilinear elements
    // hold this linear field exactly, so only the dynamics differs from it.
    //
    // The dynamics: the wall sets the top moving at V at once; the stress wave it starts has
    // the amplitude rho c V (c = sqrt(E/(1 - nu^2)/rho) ~ 10.5, the midpoint rule does not damp
    // it), so the force oscillates about the static one by rho c V W, relative to it
    // (V / c) / (d / H) = (V / c) (H / (V t)) = H / (c t): 1.2% after t = 8 (about 85 transit
    // times). A speed V << c keeps the compression small (d/H = 1%) for that long.
    let (e, nu, v, tau) = (100.0f64, 0.3f64, 1e-3f64, 1e-2f64);
    let (w, h) = (1.0, 1.0);
    let dir = scratch("wall");
    let scene = small_scene(&dir, "wall", "square_quad.geo", 0.125, WALL);
    for mass in ["modified1", "consistent"] {
        let s = run_scene(2, &scene, &["--mass", mass, "--", "-ksp_rtol", "1e-12"]);
        // The wall's work is the contact work on the body: all the energy there is.
        let c = contact(&s);
        assert!(s.energy_balance < 1e-8, "{mass}: energy balance {}", s.energy_balance);
        assert!(c.contact_work > 0.0, "{mass}: contact work {}", c.contact_work);
        assert!(rel_diff(s.energy_final - s.energy_initial, c.contact_work) < 1e-8, "{mass}");
        let h5 = dir.join("wall-2.h5");
        let force = contact_table(&h5, "force");
        let steps = force.nrows() - 1;
        let mut worst: f64 = 0.0;
        for n in steps * 4 / 5 + 1..=steps {
            // The force acts at the midpoint of step n - 1 -> n, where the wall has moved
            // d = V (n - 1/2) tau.
            let total = force.row(n).sum();
            let d = v * (n as f64 - 0.5) * tau;
            let f_static = e / (1.0 - nu * nu) * w * d / h;
            worst = worst.max(rel_diff(total, f_static));
        }
        eprintln!("{mass}: total force vs static over t in (8, 10]: at most {worst:.2e} off");
        assert!(worst < 0.03, "{mass}: the total force is {worst} off the static reaction");
        // The top follows the wall placed at the end of each step: u_y = -V t there.
        let top = contact_coords(&h5);
        let run = reader(&h5);
        let coords = run.coordinates().unwrap();
        for t in [2.0, 6.0, 10.0] {
            let (u, dim) = run.field_at("displacement", t).unwrap();
            for x in &top {
                let node = coords.iter().position(|c| c == x).unwrap();
                let uy = u[node * dim + 1];
                assert!((uy + v * t).abs() < 1e-9 * v * t, "{mass}: u_y = {uy} at t = {t}");
            }
        }
    }
}

/// Runs the scene `name` on 2 ranks (CG rtol 1e-12): the body of mesh `geo` (size `h`, `dim`
/// dimensions) falls at speed 1 (along -y in 2D, -z in 3D) for `steps` steps of 1e-3 with
/// `M_H^1`, its "bottom" onto `obstacles` (the `[contact]` line); `output` is `[output]`'s
/// body. The summary and the file.
fn fall(
    name: &str,
    (geo, h, dim): (&str, f64, usize),
    steps: usize,
    obstacles: &str,
    output: &str,
) -> (RunSummary, PathBuf) {
    let velocity = if dim == 2 { r#"["0", "-1"]"# } else { r#"["0", "0", "-1"]"# };
    let rest = format!(
        "[initial]\nvelocity = {velocity}\n[time]\ntau = 1e-3\nsteps = {steps}\n[mass]\nkind = \"modified1\"\n[contact]\nboundary = \"bottom\"\n{obstacles}\n[output]\n{output}\n"
    );
    let dir = scratch(name);
    let scene = small_scene(&dir, name, geo, h, &rest);
    let s = run_scene(2, &scene, &["--", "-ksp_rtol", "1e-12"]);
    (s, dir.join(format!("{name}-2.h5")))
}

/// The square (0,1)^2 (h = 1/8) falls onto two discs of radius 0.2 under x = 1/4 and
/// x = 3/4 (gap 0.01): a scene that is its own mirror image about x = 1/2.
const TWO_DISCS: &str = r#"obstacles = [
  { type = "sphere", center = [0.25, -0.21], radius = 0.2 },
  { type = "sphere", center = [0.75, -0.21], radius = 0.2 },
]"#;

#[test]
fn two_discs_at_once_act_as_mirror_images() {
    // The displacement at every step: the normals of the resultants below.
    let output = "every = 1\nfields = [\"displacement\"]";
    let (s, h5) = fall("twodiscs", ("square_quad.geo", 0.125, 2), 300, TWO_DISCS, output);
    let force = contact_table(&h5, "force");
    let nodes = contact_coords(&h5);
    let run = reader(&h5);
    let coords = run.coordinates().unwrap();
    let rows: Vec<usize> =
        nodes.iter().map(|x| coords.iter().position(|c| c == x).unwrap()).collect();
    // [outputs, nodes, 2], flattened; written at every step.
    let u = run.series(&layout::field("displacement")).unwrap();
    let per_step = coords.len() * 2;
    let centers = [[0.25, -0.21], [0.75, -0.21]];
    // Per step and disc, the resultant sum_q lambda_q n_q of the nodes on the disc's side,
    // with the normals the solver used: from the disc's center to the node at u^{n-1}.
    let tau = 1e-3;
    let (mut impulse, mut fmax, mut mirror): ([f64; 2], f64, f64) = ([0.0; 2], 0.0, 0.0);
    let mut touched = [false; 2];
    for n in 1..force.nrows() {
        let mut r = [[0.0f64; 2]; 2];
        for (q, x) in nodes.iter().enumerate() {
            let lam = force[[n, q]];
            if lam == 0.0 {
                continue;
            }
            assert!(x[0] != 0.5, "the node on the symmetry line touched");
            let k = if x[0] < 0.5 { 0 } else { 1 };
            let d = (n - 1) * per_step + rows[q] * 2;
            let y = [x[0] + u[d], x[1] + u[d + 1]];
            let off = [y[0] - centers[k][0], y[1] - centers[k][1]];
            let len = off[0].hypot(off[1]);
            for c in 0..2 {
                r[k][c] -= lam * off[c] / len;
            }
            touched[k] = true;
        }
        for c in 0..2 {
            impulse[c] -= tau * (r[0][c] + r[1][c]);
        }
        fmax = fmax.max(r[0][0].hypot(r[0][1]));
        // Mirrored: (Fx, Fy) on the left is (-Fx, Fy) on the right.
        mirror = mirror.max((r[0][0] + r[1][0]).abs()).max((r[0][1] - r[1][1]).abs());
    }
    eprintln!("peak resultant per disc {fmax:.4e}, largest mirror defect {mirror:.2e}");
    assert!(touched[0] && touched[1], "both discs must be touched: {touched:?}");
    assert!(mirror <= 1e-8 * fmax, "resultants differ by {mirror} (peak {fmax})");
    // The impulse from these normals is the run's, and equals the momentum change.
    let c = contact(&s);
    let (p0, p1) = (&s.momentum_initial, &s.momentum_final);
    for i in 0..2 {
        let scale = c.impulse[1].abs();
        assert!((impulse[i] - c.impulse[i]).abs() <= 1e-8 * scale, "impulse[{i}]");
        assert!((c.impulse[i] - (p1[i] - p0[i])).abs() <= 1e-6 * scale, "momentum[{i}]");
    }
    assert!(c.impulse[0].abs() <= 1e-8 * c.impulse[1].abs(), "a sideways impulse");
    assert!(p0[1] < 0.0 && p1[1] > 0.0, "no bounce (momentum {} -> {})", p0[1], p1[1]);
    assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
}

/// A unit cube of hexahedra (h = 1/4) falls onto a horizontal cylinder of radius 0.5 whose
/// axis runs along the diagonal x = y of the cube's bottom, 0.01 below it. The line contact
/// is soft (the cube rebounds on it like a mass on a spring): it lasts until step 329.
const ON_CYLINDER: &str = r#"obstacle = { type = "cylinder", point = [0.5, 0.5, -0.51], axis = [1.0, 1.0, 0.0], radius = 0.5 }"#;

#[test]
fn a_block_dropped_on_a_cylinder_touches_along_its_top_line() {
    let (s, h5) = fall("oncylinder", ("cube_hex.geo", 0.25, 3), 400, ON_CYLINDER, "every = 50");
    let active = contact_table(&h5, "active");
    let gap = contact_table(&h5, "gap");
    let nodes = contact_coords(&h5);
    // Horizontal distance of a bottom node from the cylinder's top line x = y.
    let off = |x: &[f64; 3]| (x[0] - x[1]).abs() / 2f64.sqrt();
    let on_line: Vec<bool> = nodes.iter().map(|x| off(x) < 1e-12).collect();
    assert_eq!(on_line.iter().filter(|&&l| l).count(), 5);
    let first = (1..active.nrows())
        .find(|&n| active.row(n).iter().any(|&a| a == 1.0))
        .expect("no contact happened");
    // The whole line touches at once (a sphere would touch one point first) ...
    for (q, &l) in on_line.iter().enumerate() {
        assert_eq!(active[[first, q]] == 1.0, l, "node {:?} at the first contact", nodes[q]);
    }
    // ... and contact never leaves the line's neighbourhood (one mesh size, h = 0.25).
    for n in 1..active.nrows() {
        for (q, x) in nodes.iter().enumerate() {
            if active[[n, q]] == 1.0 {
                assert!(off(x) <= 0.25 / 2f64.sqrt() + 1e-12, "node {x:?} active at step {n}");
            }
            assert!(gap[[n, q]] >= -1e-9, "penetration {} at step {n}", gap[[n, q]]);
        }
    }
    let last = active.row(active.nrows() - 1);
    assert!(last.iter().all(|&a| a == 0.0), "still in contact at the end");
    // Impulse = momentum change; by the symmetries of the scene it is vertical.
    let c = contact(&s);
    let (p0, p1) = (&s.momentum_initial, &s.momentum_final);
    let scale = c.impulse[2].abs();
    for i in 0..3 {
        assert!((c.impulse[i] - (p1[i] - p0[i])).abs() <= 1e-6 * scale, "momentum[{i}]");
    }
    assert!(c.impulse[0].abs().max(c.impulse[1].abs()) <= 1e-8 * scale, "a sideways impulse");
    assert!(p0[2] < 0.0 && p1[2] > 0.0, "no bounce (momentum {} -> {})", p0[2], p1[2]);
    assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
}
