//! Dual mortar pairs of finite-strain bodies.
//!
//! The patch test at finite strain: two blocks with non-matching interface meshes, pressed
//! together by a nominal (dead) traction `p` on the upper block's top, every side on rollers
//! and the lower block's bottom fixed along the normal: uniaxial strain. The exact solution
//! is the stretch `s` along the normal `d` with `P_dd(s) = -p` (`P` the first Piola-Kirchhoff
//! stress), the same in both blocks:
//!
//! - Saint Venant-Kirchhoff: `P_dd = s (lambda + 2 mu) (s^2 - 1) / 2`;
//! - neo-Hooke (`W = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2`):
//!   `P_dd = mu (s - 1/s) + lambda ln(s) / s`;
//!
//! and `u_d = (s - 1)(x_d + 1)`. The lateral stretch is 1, so the interface keeps its
//! reference area and the mortar matrices their reference values: every slave node carries
//! the pressure `p` exactly, and the dual mortar discretization reproduces the linear field
//! exactly. At `p` 0.15 of the confined modulus the compression is 21% (Saint Venant-Kirchhoff)
//! or 13% (neo-Hooke) where small strain gives 15%: the run must be at finite strain to pass. It starts from the exact field at rest
//! and must stay there; any error in the tangent handed to the mortar solver, its basis
//! change or the contact force inside the Newton loop moves it.

mod common;
use common::*;

const E: f64 = 100.0;
const NU: f64 = 0.3;

fn lame() -> (f64, f64) {
    (E * NU / ((1.0 + NU) * (1.0 - 2.0 * NU)), E / (2.0 * (1.0 + NU)))
}

/// `P_dd(s)` of uniaxial strain.
fn nominal_stress(model: &str, s: f64) -> f64 {
    let (l, m) = lame();
    match model {
        "saint_venant_kirchhoff" => s * (l + 2.0 * m) * (s * s - 1.0) / 2.0,
        "neo_hookean" => m * (s - 1.0 / s) + l * s.ln() / s,
        _ => unreachable!("{model}"),
    }
}

/// The stretch with `P_dd(s) = -p`, by bisection on (0.6, 1) (both laws rise there).
fn stretch(model: &str, p: f64) -> f64 {
    let (mut lo, mut hi) = (0.6, 1.0);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if nominal_stress(model, mid) + p > 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

struct Case {
    dim: usize,
    kind: u32,
    model: &'static str,
    mass: &'static str,
    interface: &'static str,
    /// Both blocks moving sideways at this speed (their sides moved with them): the exact
    /// solution translated, `u_x += v t`.
    slide: f64,
}

/// Steps of a case: 10 while sliding (the interface moves by 2.5 cells of the finer side at
/// v = 50), else 3.
fn steps(c: &Case) -> usize {
    if c.slide != 0.0 {
        10
    } else {
        3
    }
}

fn scene(dir: &std::path::Path, c: &Case, p: f64, s: f64) -> std::path::PathBuf {
    let (geo, sides, n) = if c.dim == 2 {
        ("two_blocks_2d.geo", "[\"x\"]", (4, 5))
    } else {
        ("two_blocks_3d.geo", "[\"x\", \"y\"]", (2, 3))
    };
    let normal = if c.dim == 2 { "y" } else { "z" };
    let zeros = |k: usize| vec!["\"0\""; k].join(", ");
    let disp = format!("{}, \"{} * ({normal} + 1)\"", zeros(c.dim - 1), s - 1.0);
    let (v, steps) = (c.slide, steps(c));
    let vel = format!("\"{v}\", {}", zeros(c.dim - 1));
    // Rollers on every side: moved along x with the blocks, held along y in 3D.
    let side = format!("[\"{v} * t\", {}]", zeros(c.dim - 1));
    let traction = format!("{}, \"-{p}\"", zeros(c.dim - 1));
    let name = format!(
        "fs-patch{}d-k{}-{}-{}-{}-v{}",
        c.dim, c.kind, c.model, c.mass, c.interface, c.slide
    );
    let text = format!(
        r#"name = "{name}"
[mesh]
geo = "../meshes/{geo}"
params = {{ kind = {kind}, n_lower = {nl}, n_upper = {nu} }}
[material]
E = {E}
nu = {NU}
rho = 1.0
model = "{model}"
[[dirichlet]]
group = "lower_bottom"
components = ["{normal}"]
[[dirichlet]]
group = "lower_sides"
components = {sides}
value = {side}
[[dirichlet]]
group = "upper_sides"
components = {sides}
value = {side}
[[neumann]]
group = "upper_top"
traction = [{traction}]
[initial]
displacement = [{disp}]
velocity = [{vel}]
[time]
tau = 1e-3
steps = {steps}
[mass]
kind = "{mass}"
[contact]
slave = "upper_contact"
master = "lower_contact"
[output]
every = 1
"#,
        kind = c.kind,
        nl = n.0,
        nu = n.1,
        model = c.model,
        mass = c.mass,
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

/// Runs a case on `ranks` ranks and checks pressures and displacement against the exact
/// solution; returns the pressures of the last step.
fn check(c: &Case, ranks: usize) -> Vec<f64> {
    let (l, m) = lame();
    let p = 0.15 * (l + 2.0 * m);
    let s = stretch(c.model, p);
    // Small strain would compress by 15%: the exact stretch is another one.
    let small = 1.0 - p / (l + 2.0 * m);
    assert!((nominal_stress(c.model, s) + p).abs() < 1e-12 * p, "stretch {s}");
    assert!((s - small).abs() > 0.01, "stretch {s} against small strain's {small}");
    let dir = scratch("fs-patch");
    let path = scene(&dir, c, p, s);
    // The slave nodes end each step within `-mortar_geometry_tol` of the planes: a pressure
    // error of about E L / h (2e-8 of p at the default L, 2e-9 of the slave side's extent).
    let args = [
        "--",
        "-ksp_rtol",
        "1e-13",
        "-newton_rtol",
        "1e-12",
        "-mortar_interface",
        c.interface,
        "-mortar_geometry_tol",
        "1e-12",
    ];
    let sum = run_scene(ranks, &path, &args);
    let label = format!(
        "{}D kind {} {} {} {} on {ranks} rank(s)",
        c.dim, c.kind, c.model, c.mass, c.interface
    );
    let h5 = dir.join(format!("{}-{ranks}.h5", path.file_stem().unwrap().to_string_lossy()));
    let run = reader(&h5);
    let force = run.table(&layout::contact("force")).unwrap();
    let active = run.table(&layout::contact("active")).unwrap();
    let weights = values(&h5, layout::CONTACT_WEIGHTS);
    assert_eq!(force.nrows(), steps(c) + 1, "{label}: rows of the contact history");
    let mut last = vec![];
    for n in 1..force.nrows() {
        assert!(active.row(n).iter().all(|&a| a == 1.0), "{label}: step {n}: a slave node is off");
        last = force.row(n).iter().zip(&weights).map(|(f, w)| f / w).collect();
        for (q, pq) in last.iter().enumerate() {
            assert!(
                (pq - p).abs() < 1e-8 * p,
                "{label}: step {n}, slave node {q}: pressure {pq}, exact {p}"
            );
        }
    }
    let x = run.coordinates().unwrap();
    let t_end = steps(c) as f64 * 1e-3;
    let (u, comps) = run.field_at("displacement", t_end).unwrap();
    let d = c.dim - 1;
    for (k, xk) in x.iter().enumerate() {
        for i in 0..c.dim {
            let want = match i {
                0 => c.slide * t_end,
                _ if i == d => (s - 1.0) * (xk[d] + 1.0),
                _ => 0.0,
            };
            let got = u[k * comps + i];
            assert!(
                (got - want).abs() < 1e-8,
                "{label}: node {k} at {xk:?}, component {i}: {got} vs {want}"
            );
        }
    }
    assert!(sum.energy_balance < 1e-8, "{label}: energy balance {}", sum.energy_balance);
    last
}

#[test]
fn the_mortar_patch_test_holds_at_finite_strain_in_2d() {
    for model in ["neo_hookean", "saint_venant_kirchhoff"] {
        for interface in ["frozen", "follow"] {
            check(&Case { dim: 2, kind: 0, model, mass: "consistent", interface, slide: 0.0 }, 2);
        }
    }
    // Triangles against quadrilaterals, with the mass-free layer on both sides.
    check(
        &Case {
            dim: 2,
            kind: 2,
            model: "neo_hookean",
            mass: "modified1",
            interface: "follow",
            slide: 0.0,
        },
        2,
    );
}

/// The sliding patch test at finite strain: the compressed blocks of the patch test moving
/// sideways at v = 50 with their sides, the interface following them over 2.5 cells. The
/// exact solution is the static one translated, `u = (v t, (s - 1)(y + 1))`: a translation
/// adds no stress at finite strain either, the midpoint rule reproduces a motion linear in
/// time exactly, and the interface evaluated on the moved configuration is the static one
/// translated. So every slave node carries `p` at every step, the interface stays closed, and
/// the displacement is the exact one (1e-8), in 2D and 3D. With the standard mass `M`: with
/// `M_H^1` the pressures' spread across the slave nodes grows from round-off by about 2.5
/// times a step while the interface slides (1.8e-8 of `p` at step 10; the small-strain blocks
/// grow it by 1.7 times a step, to 2e-5 at step 30), a mode of the massless contact nodes
/// that this test leaves to its own.
#[test]
fn the_mortar_patch_test_holds_at_finite_strain_while_the_blocks_slide() {
    for dim in [2, 3] {
        let kind = if dim == 2 { 0 } else { 2 };
        let model = "saint_venant_kirchhoff";
        check(&Case { dim, kind, model, mass: "consistent", interface: "follow", slide: 50.0 }, 2);
    }
}

#[test]
fn the_mortar_patch_test_holds_at_finite_strain_in_3d_on_1_and_3_ranks() {
    let c = Case {
        dim: 3,
        kind: 2,
        model: "neo_hookean",
        mass: "modified1",
        interface: "follow",
        slide: 0.0,
    };
    let one = check(&c, 1);
    let three = check(&c, 3);
    for (a, b) in one.iter().zip(&three) {
        assert!((a - b).abs() < 1e-8 * a.abs(), "pressures {a} vs {b}");
    }
}

/// When the rigid block of `scenes/slide_off.toml` (1 x 0.5, mass 0.5, sliding at 1 under
/// g = 1, frictionless) stops touching the lower block: from the moment its centre passes
/// the edge (4, 0) at t = 3.3 it tips about that edge, the edge sliding along its bottom face
/// (the contact force normal to that face), until its rear bottom corner passes the edge or
/// the force would pull. The equations of the rigid body with that one constraint, integrated
/// with a step of 1e-5 (the constraint held by its second derivative and a stiff
/// stabilization). Returns the time and the angle turned (radians).
fn rigid_tipping_release() -> (f64, f64) {
    let (a, b, m, g) = (1.0f64, 0.5f64, 0.5f64, 1.0f64);
    let inertia = m * (a * a + b * b) / 12.0;
    let edge = [4.0, 0.0];
    // The constraint's gradient, value (the edge's distance out of the bottom face) and the
    // edge's position along the face, at centre (x, y) and angle th.
    let geometry = |x: f64, y: f64, th: f64| {
        let n = [th.sin(), -th.cos()];
        let bc = [x + 0.5 * b * th.sin(), y - 0.5 * b * th.cos()];
        let r = [edge[0] - bc[0], edge[1] - bc[1]];
        let dn = [th.cos(), th.sin()];
        let dbc = [0.5 * b * th.cos(), 0.5 * b * th.sin()];
        let grad = [-n[0], -n[1], dn[0] * r[0] + dn[1] * r[1] - (n[0] * dbc[0] + n[1] * dbc[1])];
        (grad, n[0] * r[0] + n[1] * r[1], dn[0] * r[0] + dn[1] * r[1])
    };
    let (mut q, mut v, mut t, dt) = ([4.0, 0.5 * b, 0.0], [1.0, 0.0, 0.0], 3.3, 1e-5);
    let inv = [1.0 / m, 1.0 / m, 1.0 / inertia];
    let gravity = [0.0, -m * g, 0.0];
    loop {
        let (grad, gap, along) = geometry(q[0], q[1], q[2]);
        let eps = 1e-7;
        let (ahead, _, _) = geometry(q[0] + v[0] * eps, q[1] + v[1] * eps, q[2] + v[2] * eps);
        let curvature: f64 = (0..3).map(|i| (ahead[i] - grad[i]) / eps * v[i]).sum();
        let rate: f64 = (0..3).map(|i| grad[i] * v[i]).sum();
        let stiffness: f64 = (0..3).map(|i| grad[i] * inv[i] * grad[i]).sum();
        let free: f64 = (0..3).map(|i| grad[i] * inv[i] * gravity[i]).sum();
        let lambda = (-curvature - free - 1e4 * gap - 2e2 * rate) / stiffness;
        if lambda < 0.0 || along < -0.5 * a {
            return (t, q[2].abs());
        }
        for i in 0..3 {
            v[i] += inv[i] * (gravity[i] + lambda * grad[i]) * dt;
            q[i] += v[i] * dt;
        }
        t += dt;
        assert!(t < 6.0, "the rigid block never lets go");
    }
}

/// The upper block's four side lengths at every written step, relative to their rest lengths
/// (1, 0.5, 1, 0.5): the largest departure.
fn largest_side_change(h5: &std::path::Path) -> f64 {
    let run = reader(h5);
    let x = run.coordinates().unwrap();
    let nearest = |p: [f64; 2]| {
        (0..x.len())
            .min_by(|&i, &j| {
                let d = |k: usize| (x[k][0] - p[0]).powi(2) + (x[k][1] - p[1]).powi(2);
                d(i).total_cmp(&d(j))
            })
            .unwrap()
    };
    let corners = [[0.2, 0.001], [1.2, 0.001], [1.2, 0.501], [0.2, 0.501]].map(nearest);
    let mut worst = 0.0f64;
    for t in values(h5, "time") {
        let (u, comps) = run.field_at("displacement", t).unwrap();
        let at = |k: usize| [x[k][0] + u[k * comps], x[k][1] + u[k * comps + 1]];
        for s in 0..4 {
            let (p, q) = (at(corners[s]), at(corners[(s + 1) % 4]));
            let rest = if s % 2 == 0 { 1.0 } else { 0.5 };
            let len = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt();
            worst = worst.max((len / rest - 1.0).abs());
        }
    }
    worst
}

/// The block of `scenes/slide_off.toml` slides off the end of the lower block and tips over
/// its edge, both bodies neo-Hookean. Asserted:
/// - contact ends within 0.03 (three steps) of when the rigid block lets go
///   ([`rigid_tipping_release`], t = 3.82 after turning 5.6 degrees): two steps for the step
///   a release shows in and the slave nodes' spacing, one for the elastic compliance (the
///   block's weight over its stiffness, 0.5 / 100, deflects its corner by about 1e-3 of its
///   size, which moves the release by about that much of the slide);
/// - no contact force after that: the block falls freely, its momentum change the contact
///   impulse plus gravity's (`-m g T`, m = 0.5, T = 5) to 1e-8 of its initial momentum, and
///   the two bodies' contact impulses cancel to 1e-8 of their size;
/// - its four sides keep their rest lengths to 1% at every written step, while it turns by
///   tens of degrees (the small-strain block, run beside it, grows by more than that: a check
///   that can tell them apart);
/// - the energy balance holds at the Newton tolerance (1e-8 of the energy), with `M` and
///   with `M_H^1`.
#[test]
fn a_neo_hookean_block_tips_over_the_edge_keeping_its_size() {
    let (release, angle) = rigid_tipping_release();
    assert!((3.3..3.9).contains(&release) && angle > 0.05, "rigid release {release}, {angle}");
    for mass in ["modified1", "consistent"] {
        let name = format!("fs-slide-off-{mass}");
        let dir = scratch(&name);
        let scene = scene_variant("slide_off.toml", &dir, &[]);
        let args = [
            "--model",
            "neo_hookean",
            "--mass",
            mass,
            "--",
            "-ksp_rtol",
            "1e-12",
            "-newton_rtol",
            "1e-11",
        ];
        let s = run_scene(2, &scene, &args);
        let h5 = dir.join("slide_off-2.h5");
        let (force, active) = force_history(&h5);
        let last = (0..active.len()).filter(|&i| active[i]).last().expect("contact");
        let t_last = last as f64 * 0.01;
        assert!(
            (t_last - release).abs() <= 0.03,
            "{name}: contact ends at t = {t_last}, rigid {release}"
        );
        let after = force[last + 1..].iter().fold(0.0f64, |a, f| a.max(f.abs()));
        assert_eq!(after, 0.0, "{name}: contact force after the release");
        let upper = s.bodies.iter().find(|b| b.group == "upper").expect("body upper");
        let lower = s.bodies.iter().find(|b| b.group == "lower").expect("body lower");
        let p0 = upper.momentum_initial[0];
        let gravity = [0.0, -0.5 * 1.0 * 5.0];
        let size = upper.contact_impulse.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        for c in 0..2 {
            let dp = upper.momentum_final[c] - upper.momentum_initial[c];
            let miss = (dp - upper.contact_impulse[c] - gravity[c]).abs();
            assert!(
                miss < 1e-8 * p0,
                "{name}: momentum balance of the block, component {c}: {miss:e}"
            );
            let sum = (upper.contact_impulse[c] + lower.contact_impulse[c]).abs();
            assert!(
                sum < 1e-8 * size,
                "{name}: the impulses do not cancel, component {c}: {sum:e}"
            );
        }
        assert!(s.energy_balance < 1e-8, "{name}: energy balance {}", s.energy_balance);
        let turned = s.rotations.iter().map(|r| r.degrees).fold(0.0, f64::max);
        let grown = largest_side_change(&h5);
        eprintln!("{name}: contact ends at t = {t_last} (rigid {release:.4}), turned {turned:.1} degrees, sides within {grown:.2e}");
        assert!(turned > 20.0, "{name}: the block turned only {turned} degrees");
        assert!(grown < 0.01, "{name}: a side changed by {grown:.3} of its length");
    }
    let dir = scratch("fs-slide-off-linear");
    let scene = scene_variant("slide_off.toml", &dir, &[]);
    run_scene(2, &scene, &["--model", "linear"]);
    let grown = largest_side_change(&dir.join("slide_off-2.h5"));
    assert!(grown > 0.05, "the small-strain block grew by only {grown:.3}");
}

/// 1, 2 and 3 ranks (x-slabs: the partition cuts the sliding zone) give the same contact
/// histories of the neo-Hookean slide-off: the same active sets at every step, and while the
/// block slides on the flat (up to step 280) forces that differ by no more than the solves
/// allow. Each Newton iteration's GMRES stops at the relative residual `rtol`, each Newton
/// loop at the relative residual `newton_rtol`, an error of at most `kappa` times these of the
/// step's solution (`kappa` PETSc's estimate of the condition number of the preconditioned
/// tangent over every solve on one rank, doubled); two runs differ by twice that a step, and
/// by `2 n kappa (rtol + newton_rtol)` of the state after n steps; the slave nodes end every
/// step within `L` of the planes (`-mortar_geometry_tol`), a force error of `E L` a node. The
/// preconditioner is point Jacobi, the same on every rank count, and the energy correction
/// is off (its decisions to put steady steps' work back can flip on round-off).
#[test]
fn the_neo_hookean_slide_off_does_not_depend_on_the_number_of_ranks() {
    let dir = scratch("fs-slide-off-ranks");
    let scene = scene_variant("slide_off.toml", &dir, &[("steps = 500", "steps = 400")]);
    const FLAT: usize = 280;
    let run = ["--model", "neo_hookean", "--partition", "x-slabs"];
    assert_ranks_agree(&dir, &scene, "slide_off", &run, FLAT, Some(FLAT));
}

/// The finite-strain pair's contact histories (`--output` in `dir` under `tag`, the run's own
/// arguments `run`) on 2 and 3 ranks against 1 rank's: the same active sets at every step,
/// and forces over the steps up to `compared` (all: `None`) within the bound of n = `steps`
/// steps, `2 n kappa (rtol + newton_rtol)` of the peak force plus `2 E L` (E = 100, `L` the
/// geometry tolerance). Point Jacobi, the energy correction off. Returns the 1-rank run's
/// active set sizes.
fn assert_ranks_agree(
    dir: &std::path::Path,
    scene: &std::path::Path,
    tag: &str,
    run: &[&str],
    steps: usize,
    compared: Option<usize>,
) -> Vec<f64> {
    const RTOL: f64 = 1e-14;
    const NEWTON_RTOL: f64 = 1e-12;
    const GEOMETRY_TOL: f64 = 1e-12;
    let (rtol, newton, geometry) =
        (RTOL.to_string(), NEWTON_RTOL.to_string(), GEOMETRY_TOL.to_string());
    let series = |ranks: usize, estimate: bool| {
        let out = dir.join(format!("{tag}-{ranks}.h5"));
        let mut args = vec!["run", scene.to_str().unwrap(), "--quiet", "--overwrite"];
        args.extend(run);
        args.extend(["--output", out.to_str().unwrap()]);
        args.extend(["--", "-step_pc_type", "jacobi", "-step_ksp_rtol", &rtol]);
        args.extend(["-newton_rtol", &newton, "-mortar_geometry_tol", &geometry]);
        args.extend(["-massless_energy_correction", "false"]);
        contact_history(ranks, &args, &out, estimate)
    };
    let (f1, a1, estimate) = series(1, true);
    let fmax = f1.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let kappa = 2.0 * estimate;
    let bound =
        2.0 * steps as f64 * kappa * (RTOL + NEWTON_RTOL) * fmax + 2.0 * 100.0 * GEOMETRY_TOL;
    eprintln!("one rank: peak force {fmax:.4}, condition number estimate {estimate:.0}; bound {:.1e} of the peak", bound / fmax);
    for ranks in [2, 3] {
        let (f, a, _) = series(ranks, false);
        assert_eq!(a1, a, "{ranks} ranks: active sets differ");
        let d = step_differences(&f1, &f);
        let d = match compared {
            Some(last) => &d[..=last],
            None => &d[..],
        };
        let most = d.iter().fold(0.0f64, |m, &x| m.max(x));
        eprintln!("{ranks} ranks: forces differ by {:.2e} of the peak", most / fmax);
        assert!(most <= bound, "{ranks} ranks: forces differ by {most:e}, beyond {bound:e}");
    }
    a1
}

/// 1, 2 and 3 ranks give the same contact histories of the coarse neo-Hookean oblique balls
/// (`scenes/two_spheres_oblique_neo_hooke.toml`, h = 0.4, hc = 0.1, the first 40 steps: the
/// touch-down and the caps sliding on each other): the same active sets at every step, and
/// forces that differ by no more than the solves allow, the bound of the 2D slide-off's test
/// above. In 3D the ranks share the slave facets' integrals and each loaded facet's derivative
/// columns by hashes of node tags, whichever rank owns the facets' cells (on 2 ranks the
/// partition puts each ball on its own rank).
#[test]
fn the_oblique_neo_hookean_balls_do_not_depend_on_the_number_of_ranks() {
    let dir = scratch("fs-balls-ranks");
    let scene = scene_variant("two_spheres_oblique_neo_hooke.toml", &dir, &[]);
    const STEPS: usize = 40;
    let steps = STEPS.to_string();
    let run = ["--param", "h=0.4", "--param", "hc=0.1", "--steps", &steps];
    let a1 = assert_ranks_agree(&dir, &scene, "balls", &run, STEPS, None);
    assert!(a1.iter().any(|&x| x > 0.0), "the balls never touched in {STEPS} steps");
}

/// The neo-Hookean balls of `scenes/two_spheres_oblique_neo_hooke.toml` on a coarse mesh (h =
/// 0.4, hc = 0.1), frictionless and with Coulomb friction (mu = 0.3) between the caps: no
/// force acts on the pair but the contact, so the two bodies' contact impulses cancel (to
/// 1e-8 of their size), and the pair's momentum is kept to the same fraction of a ball's;
/// frictionless, the energy is kept (the contact takes work only at activation and the
/// correction puts it back, steady steps' work collected below 1e-7 of the energy: the end
/// within 1e-6 of the start); with friction, the energy lost is what friction dissipated,
/// `sum t.s`, to 1e-6 of the energy, and it is lost (friction acted). The energy balance
/// holds at the Newton tolerance in both.
///
/// Angular momentum: the hyperelastic force has no moment at the midpoint positions, nor has
/// the energy correction's force (rigid motions projected out per body), nor the mortar's
/// normal force once the weighted gaps close (to the geometry tolerance, 1e-12 here): the
/// pair's angular momentum about its centre of mass (0.134, spinning the balls apart) is kept
/// to 1e-7 frictionless (a correction force without the rotations projected out moved it by
/// 5e-4). With friction the tangential traction acts across the pointwise gap between the
/// surfaces (zero only weighted over each node's support): a moment of the discretization,
/// 1.1e-7 of it on this mesh, asserted below 1e-6.
#[test]
fn oblique_neo_hookean_balls_keep_momentum_and_lose_only_what_friction_dissipates() {
    for (mu, angular) in [("0", 1e-7), ("0.3", 1e-6)] {
        let name = format!("fs-balls-mu{mu}");
        let dir = scratch(&name);
        let scene = scene_variant("two_spheres_oblique_neo_hooke.toml", &dir, &[]);
        let args = [
            "--friction",
            mu,
            "--param",
            "h=0.4",
            "--param",
            "hc=0.1",
            "--",
            "-mortar_geometry_tol",
            "1e-12",
        ];
        let s = run_scene(2, &scene, &args);
        let (l0, l1) = (&s.angular_momentum_initial, &s.angular_momentum_final);
        let size = l0.iter().map(|x| x * x).sum::<f64>().sqrt();
        let moved = l0.iter().zip(l1).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
        assert!(size > 0.1, "{name}: the pair hardly spins ({size:e})");
        assert!(
            moved < angular * size,
            "{name}: angular momentum moved by {:.2e} of its size",
            moved / size
        );
        let (a, b) = (&s.bodies[0], &s.bodies[1]);
        let size = a.contact_impulse.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        let ball = a.momentum_initial.iter().fold(0.0f64, |m, c| m.max(c.abs()));
        assert!(size > 0.1 * ball, "{name}: the balls hardly touched ({size:e})");
        for c in 0..3 {
            let sum = (a.contact_impulse[c] + b.contact_impulse[c]).abs();
            assert!(sum < 1e-8 * size, "{name}: impulses do not cancel in {c}: {sum:e}");
            let dp = (s.momentum_final[c] - s.momentum_initial[c]).abs();
            assert!(dp < 1e-8 * ball, "{name}: the pair's momentum moved by {dp:e} in {c}");
        }
        assert!(s.energy_balance < 1e-8, "{name}: energy balance {}", s.energy_balance);
        let contact = s.contact.as_ref().expect("contact");
        let lost = s.energy_initial - s.energy_final;
        let miss = (lost - contact.friction_dissipation).abs() / s.energy_initial;
        eprintln!(
            "{name}: energy lost {:.3e} of the initial, friction dissipated {:.3e}; angular momentum {:?} -> {:?}",
            lost / s.energy_initial,
            contact.friction_dissipation / s.energy_initial,
            s.angular_momentum_initial,
            s.angular_momentum_final
        );
        assert!(
            miss < 1e-6,
            "{name}: energy lost {lost:e}, dissipated {:e}",
            contact.friction_dissipation
        );
        if mu != "0" {
            assert!(contact.friction_dissipation > 1e-3 * s.energy_initial, "{name}: no slip");
        }
    }
}
