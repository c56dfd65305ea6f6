//! Finite-strain bodies through the program as users run it (mpirun, 1-3 ranks): rigid
//! rotations carry no energy, a spinning body keeps its energy and angular momentum and its
//! size, results do not depend on the number of ranks, and bad input ends the run with one
//! line.

mod common;

use common::*;
use std::path::Path;

/// The unit square of `h`-sized quads spinning about its centre at `omega` (rad/s), no loads;
/// `rest`: more tables.
fn spinning_square(
    dir: &Path,
    name: &str,
    model: &str,
    omega: f64,
    tau: f64,
    steps: usize,
    rest: &str,
) -> std::path::PathBuf {
    small_scene(
        dir,
        name,
        "square_quad.geo",
        0.25,
        &format!(
            "model = \"{model}\"\n[initial]\nvelocity = [\"-{omega}*(y-0.5)\", \"{omega}*(x-0.5)\"]\n[time]\ntau = {tau}\nsteps = {steps}\n[output]\nevery = {}\n{rest}",
            (steps / 100).max(1)
        ),
    )
}

/// The four side lengths of the unit square (corners found in the reference coordinates) at
/// each written step.
fn side_lengths(h5: &Path) -> Vec<[f64; 4]> {
    let run = reader(h5);
    let x = run.series("mesh/coordinates").unwrap();
    let u = run.series("fields/displacement").unwrap();
    let n = x.len() / 3;
    let corner = |p: [f64; 2]| {
        (0..n)
            .min_by(|&a, &b| {
                let da = (x[3 * a] - p[0]).powi(2) + (x[3 * a + 1] - p[1]).powi(2);
                let db = (x[3 * b] - p[0]).powi(2) + (x[3 * b + 1] - p[1]).powi(2);
                da.total_cmp(&db)
            })
            .unwrap()
    };
    let c = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]].map(corner);
    u.chunks(2 * n)
        .map(|uk| {
            let pos = |v: usize| [x[3 * v] + uk[2 * v], x[3 * v + 1] + uk[2 * v + 1]];
            [0, 1, 2, 3].map(|i| {
                let (a, b) = (pos(c[i]), pos(c[(i + 1) % 4]));
                ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
            })
        })
        .collect()
}

/// The static hoop strain at the rim of a plane-strain disc of radius `b` spinning at
/// `omega` (free edge, small strain): `rho omega^2 b^2 (1 - 2 nu)(1 + nu) / (4 E)`.
fn rim_strain(omega: f64, b: f64) -> f64 {
    let (e, nu, rho) = (100.0, 0.3, 1.0);
    rho * omega * omega * b * b * (1.0 - 2.0 * nu) * (1.0 + nu) / (4.0 * e)
}

#[test]
fn a_spinning_square_keeps_its_energy_angular_momentum_and_size_with_every_mass() {
    let dir = scratch("spin");
    let omega = 2.0 * std::f64::consts::PI;
    let layer = "[mass]\nkind = \"consistent\"\ncontact_boundary = \"bottom\"\n";
    let scene = spinning_square(&dir, "spin", "neo_hookean", omega, 0.01, 10_000, layer);
    let scene = {
        let text = std::fs::read_to_string(&scene).unwrap().replace("h = 0.25", "h = 0.125");
        std::fs::write(&scene, text).unwrap();
        scene
    };
    // Between the rim strains of the inscribed and the circumscribed disc: the square's mean
    // side stretch, about which it breathes (it starts unstressed: up to twice as far).
    let (inner, outer) = (rim_strain(omega, 0.5), rim_strain(omega, 0.5f64.sqrt()));
    // The consistent mass on 2 ranks, the layer's on 1: 10^4 steps of a small body are
    // latency-bound on 2 ranks beside another test (the physics is the test here; rank-count
    // independence is tested elsewhere).
    for (mass, ranks) in [("consistent", 2), ("modified0", 1), ("modified1", 1)] {
        let s = run_scene(ranks, &scene, &["--mass", mass]);
        assert!(s.energy_drift < 1e-10, "{mass}: energy drift {:e}", s.energy_drift);
        let (l0, l1) = (s.angular_momentum_initial[2], s.angular_momentum_final[2]);
        assert!(rel_diff(l0, l1) < 1e-10, "{mass}: angular momentum {l0} -> {l1}");
        // A hundred turns: the rotation passed 179 degrees (a finite-strain body: no warning).
        assert!(s.rotations[0].degrees > 179.0, "{mass}: {:?}", s.rotations);
        let newton = s.newton.expect("Newton statistics");
        assert_eq!(newton.steps, 10_000);
        let sides = side_lengths(&dir.join(format!("spin-{ranks}.h5")));
        assert_eq!(sides.len(), 101);
        for k in 0..4 {
            let stretch: Vec<f64> = sides.iter().map(|s| s[k] - 1.0).collect();
            let mean = stretch.iter().sum::<f64>() / stretch.len() as f64;
            let (lo, hi) = stretch
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            assert!(
                mean > inner && mean < outer,
                "{mass}: side {k}'s mean stretch {mean:e} outside [{inner:e}, {outer:e}]"
            );
            // Started unstressed, an undamped breathing swings to at most twice the static
            // stretch. With M_H the layer's massless nodes (along the bottom) carry no
            // centrifugal load, and the sides next to them swing further: only a guard
            // against growth there.
            let bound = if mass == "consistent" { 2.0 * outer } else { 3.0 * outer };
            assert!(
                lo > -outer && hi < bound,
                "{mass}: side {k} stretched in [{lo:e}, {hi:e}], outside [-{outer:e}, {bound:e}]"
            );
        }
    }
    // The small-strain model sees no strain in the rotation's tangent motion: every point
    // flies off along it, the sides grow to sqrt(1 + (omega t)^2) after t (6.4 after a turn).
    let linear = spinning_square(&dir, "linear", "linear", omega, 0.01, 100, "");
    let s = run_scene(2, &linear, &[]);
    assert!(s.newton.is_none());
    // Its mean deformation gradient I + t W (W = omega's skew tensor) has the polar rotation
    // atan(omega t): the summary's largest rotation after one turn.
    let want = omega.atan().to_degrees();
    assert!(
        (s.rotations[0].degrees - want).abs() < 1e-6,
        "rotation {:?}, theory {want}",
        s.rotations
    );
    // The run warns once, when the body passes 5 degrees (omega t = 5 degrees after 0.0139,
    // the second step).
    let o =
        massfree(2, &["run", linear.to_str().unwrap(), "--quiet", "--overwrite", "--no-output"]);
    let err = String::from_utf8_lossy(&o.stderr);
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(warnings.len(), 1, "{err}");
    assert!(
        warnings[0].contains("the body has turned")
            && warnings[0].contains("t = 2e-2")
            && warnings[0].contains("neo_hookean"),
        "{}",
        warnings[0]
    );
    let sides = side_lengths(&dir.join("linear-2.h5"));
    let want = (1.0 + omega * omega).sqrt();
    for side in sides.last().unwrap() {
        assert!(rel_diff(*side, want) < 1e-9, "linear: side {side} after a turn, theory {want}");
    }
}

#[test]
fn finite_strain_does_not_depend_on_the_number_of_ranks() {
    let dir = scratch("spin_ranks");
    let layer = "[mass]\nkind = \"modified1\"\ncontact_boundary = \"bottom\"\n[[dirichlet]]\ngroup = \"left\"\nvalue = [\"0.1*t\", \"0\"]\ncomponents = [\"x\"]\n[body_force]\nacceleration = [\"0\", \"-9.81\"]\n";
    let scene = spinning_square(&dir, "spin", "saint_venant_kirchhoff", 3.0, 0.01, 50, layer);
    let runs: Vec<(usize, RunSummary)> = [1, 2, 3].map(|r| (r, run_scene(r, &scene, &[]))).into();
    let u1 = values(&dir.join("spin-1.h5"), "fields/displacement");
    let scale = u1.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (r, s) in &runs {
        // The energy identity holds with the loads and the moving boundary's reaction work.
        assert!(s.energy_balance < 1e-10, "{r} ranks: energy balance {:e}", s.energy_balance);
        let u = values(&dir.join(format!("spin-{r}.h5")), "fields/displacement");
        let diff = u.iter().zip(&u1).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff < 1e-8 * scale, "{r} ranks: displacements differ by {diff:e} of {scale:e}");
        let n = values(&dir.join(format!("spin-{r}.h5")), "newton/iterations");
        assert_eq!(n.len(), 51, "{r} ranks: a Newton count per step");
        assert!(n[1..].iter().all(|&k| k >= 1.0));
    }
}

#[test]
fn a_rigid_rotation_of_ninety_degrees_is_stress_free_at_finite_strain_only() {
    let dir = scratch("rotation");
    // u = (R - I)(X - c) for R the rotation by 90 degrees about z through c.
    let rotation2 = "[initial]\ndisplacement = [\"-(y-0.5)-(x-0.5)\", \"(x-0.5)-(y-0.5)\"]\n[time]\ntau = 0.01\nsteps = 10\n";
    let rotation3 = "[initial]\ndisplacement = [\"-(y-0.5)-(x-0.5)\", \"(x-0.5)-(y-0.5)\", \"0\"]\n[time]\ntau = 0.01\nsteps = 10\n";
    let (lambda, mu) = (100.0 * 0.3 / (1.3 * 0.4), 100.0 / 2.6);
    for (geo, rest) in [
        ("square_quad.geo", rotation2),
        ("square_tri.geo", rotation2),
        ("cube_hex.geo", rotation3),
        ("block_tet.geo", rotation3),
    ] {
        for model in ["neo_hookean", "saint_venant_kirchhoff", "linear"] {
            let name = format!("{}_{model}", geo.trim_end_matches(".geo"));
            let scene = small_scene(&dir, &name, geo, 0.5, &format!("model = \"{model}\"\n{rest}"));
            let s = run_scene(1, &scene, &[]);
            if model == "linear" {
                // The small strain of the rotation is -I in its plane: 2 (lambda + mu) per
                // unit volume (the block is 10 x 1 x 1, the others unit squares and cubes).
                let volume = if geo == "block_tet.geo" { 10.0 } else { 1.0 };
                let want = 2.0 * (lambda + mu) * volume;
                assert!(
                    rel_diff(s.energy_initial, want) < 1e-10,
                    "{name}: {} against {want}",
                    s.energy_initial
                );
            } else {
                assert!(
                    s.energy_initial.abs() < 1e-12 * mu,
                    "{name}: energy {:e}",
                    s.energy_initial
                );
                assert!(
                    s.energy_final.abs() < 1e-12 * mu,
                    "{name}: energy {:e} after 10 steps",
                    s.energy_final
                );
                let u = values(&dir.join(format!("{name}-1.h5")), "fields/displacement");
                let n = u.len() / 11;
                let moved =
                    u[10 * n..].iter().zip(&u[..n]).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
                assert!(moved < 1e-12, "{name}: the rotated body at rest moved by {moved:e}");
            }
        }
    }
}

#[test]
fn an_element_that_inverts_ends_the_run_with_one_line() {
    let dir = scratch("invert");
    // Saint Venant-Kirchhoff's energy stays finite as J -> 0: a fast enough implosion passes
    // through it (the energy at F = 0 is lambda/2 + mu/2 per unit area, 48; the kinetic energy
    // 5000 (x^2 + y^2)/2 integrated, 833).
    let scene = small_scene(
        &dir,
        "implode",
        "square_quad.geo",
        0.25,
        "model = \"saint_venant_kirchhoff\"\n[initial]\nvelocity = [\"-100*(x-0.5)\", \"-100*(y-0.5)\"]\n[time]\ntau = 0.001\nsteps = 100\n[output]\nevery = 1\n",
    );
    let out = dir.join("implode.h5");
    let o = massfree(
        2,
        &[
            "run",
            scene.to_str().unwrap(),
            "--quiet",
            "--overwrite",
            "--output",
            out.to_str().unwrap(),
        ],
    );
    assert!(!o.status.success(), "the implosion ran through");
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err.lines().filter(|l| l.contains("massfree")).collect();
    assert_eq!(lines.len(), 1, "one line, got:\n{err}");
    assert!(
        lines[0].contains("step ") && lines[0].contains("inverts") && lines[0].contains("the body"),
        "{}",
        lines[0]
    );
    assert!(!err.contains("panicked") && !err.contains("backtrace"), "{err}");
    // The file keeps the steps before, says it failed, and holds no NaN.
    let run = reader(&out);
    let status = run.text("status");
    assert!(status.contains("failed"), "status {status}");
    let u = values(&out, "fields/displacement");
    assert!(u.len() >= 5 * 25 * 2, "the steps before the failure are kept ({} values)", u.len());
    assert!(u.iter().all(|x| x.is_finite()));
    assert!(values(&out, "energy/total").iter().all(|x| x.is_finite()));
}

/// Per step and contact node of a run: the pressure.
fn pressures(h5: &Path) -> Vec<f64> {
    values(h5, "contact/pressure")
}

#[test]
fn the_disc_at_finite_strain_hits_the_plane_as_the_linear_one_and_keeps_its_energy() {
    let dir = scratch("disc_finite");
    let scene = scene_variant(
        "disc.toml",
        &dir,
        &[("rho = 2e-8\n", "rho = 2e-8\nmodel = \"neo_hookean\"\n")],
    );
    let lin_dir = dir.join("linear");
    std::fs::create_dir_all(&lin_dir).unwrap();
    let linear = scene_variant("disc.toml", &lin_dir, &[]);
    let runs: Vec<(usize, RunSummary)> = [1, 2, 3].map(|r| (r, run_scene(r, &scene, &[]))).into();
    let lin = run_scene(2, &linear, &[]);
    let p2 = pressures(&dir.join("disc-2.h5"));
    let p_max = p2.iter().fold(0.0f64, |m, &p| m.max(p));
    for (r, s) in &runs {
        // The energy correction puts back the contact work of the impact's activations and
        // releases: the energy is kept across the impact.
        let drift = rel_diff(s.energy_final, s.energy_initial);
        assert!(
            drift < 1e-8,
            "{r} ranks: energy {} -> {} ({drift:e})",
            s.energy_initial,
            s.energy_final
        );
        assert!(s.energy_balance < 1e-8, "{r} ranks: energy balance {:e}", s.energy_balance);
        assert!(s.energy_corrections.steps > 0, "{r} ranks: no corrected step");
        // 1, 2 and 3 ranks: the same contact history to the solver's tolerance.
        let p = pressures(&dir.join(format!("disc-{r}.h5")));
        let diff = p.iter().zip(&p2).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff < 1e-8 * p_max, "{r} ranks: pressures differ by {diff:e} of {p_max:e}");
    }
    // Before the touch both bodies fly rigidly: the contact starts on the same step. The two
    // models differ by the order of the strain, which is the pressure over E (7.8%) here.
    let (c, cl) = (runs[1].1.contact.as_ref().unwrap(), lin.contact.as_ref().unwrap());
    assert_eq!(c.first_contact_step, cl.first_contact_step);
    let strain = cl.max_pressure / 100.0;
    let duration = |c: &massfree::contact::history::ContactSummary| {
        (c.last_contact_step - c.first_contact_step) as f64
    };
    assert!(rel_diff(duration(c), duration(cl)) < strain, "contact steps {c:?} against {cl:?}");
    assert!(
        rel_diff(c.max_pressure, cl.max_pressure) < strain,
        "max pressure {} against {}",
        c.max_pressure,
        cl.max_pressure
    );
}

#[test]
fn the_stress_output_of_finite_strain_bodies_is_the_cauchy_stress_of_the_deformed_body() {
    let dir = scratch("cauchy");
    let (lambda, mu) = (100.0 * 0.3 / (1.3 * 0.4), 100.0 / 2.6);
    let fields = "[output]\nfields = [\"displacement\", \"stress\", \"von_mises\"]\n";
    // A uniform stretch F = diag(1.2, 1) (plane strain), J = 1.2: neo-Hooke's Cauchy stress
    // sigma = (mu (F F^T - I) + lambda ln J I) / J.
    let stretch = format!("model = \"neo_hookean\"\n[initial]\ndisplacement = [\"0.2*x\", \"0\"]\n[time]\ntau = 0.01\nsteps = 1\n{fields}");
    let scene = small_scene(&dir, "stretch", "square_tri.geo", 0.5, &stretch);
    run_scene(1, &scene, &[]);
    let s = values(&dir.join("stretch-1.h5"), "fields/stress");
    let j: f64 = 1.2;
    let want = [
        (mu * (1.44 - 1.0) + lambda * j.ln()) / j,
        0.0,
        0.0,
        lambda * j.ln() / j,
        0.0,
        lambda * j.ln() / j,
    ];
    for cell in s[..s.len() / 2].chunks(6) {
        for k in 0..6 {
            assert!((cell[k] - want[k]).abs() < 1e-10 * mu, "stress {cell:?} against {want:?}");
        }
    }
    // A rigid rotation of 90 degrees: no stress at finite strain; the linear model's is
    // lambda tr(eps) I + 2 mu eps with eps = -I in the plane.
    for (model, sxx, szz) in
        [("neo_hookean", 0.0, 0.0), ("linear", -2.0 * (lambda + mu), -2.0 * lambda)]
    {
        let text = format!("model = \"{model}\"\n[initial]\ndisplacement = [\"-(y-0.5)-(x-0.5)\", \"(x-0.5)-(y-0.5)\"]\n[time]\ntau = 0.01\nsteps = 1\n{fields}");
        let scene = small_scene(&dir, &format!("turned_{model}"), "square_quad.geo", 0.5, &text);
        run_scene(1, &scene, &[]);
        let s = values(&dir.join(format!("turned_{model}-1.h5")), "fields/stress");
        for cell in s[..s.len() / 2].chunks(6) {
            let want = [sxx, 0.0, 0.0, sxx, 0.0, szz];
            for k in 0..6 {
                assert!(
                    (cell[k] - want[k]).abs() < 1e-10 * mu,
                    "{model}: stress {cell:?} against {want:?}"
                );
            }
        }
    }
}

#[test]
fn newton_converges_quadratically_on_a_beam_bent_at_finite_strain() {
    let dir = scratch("newton_rate");
    // A cantilever (10 x 1) under a tip-heavy traction, three long steps: large rotations.
    let scene = scene_text(
        &dir,
        "bend.toml",
        "name = \"bend\"\n[mesh]\ngeo = \"../meshes/beam_quad.geo\"\nparams = { h = 0.25 }\n[material]\nE = 200.0\nnu = 0.3\nrho = 1.0\nmodel = \"neo_hookean\"\n[[dirichlet]]\ngroup = \"left\"\n[[neumann]]\ngroup = \"top\"\ntraction = [\"0\", \"-3\"]\n[time]\ntau = 0.2\nsteps = 3\n",
    );
    for ranks in [1, 2] {
        let o = massfree(
            ranks,
            &[
                "run",
                scene.to_str().unwrap(),
                "--quiet",
                "--overwrite",
                "--no-output",
                "--",
                "-newton_monitor",
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let out = String::from_utf8_lossy(&o.stdout);
        // "step N Newton K: residual R (relative X), ..." per iteration.
        let mut rel: Vec<(usize, f64)> = Vec::new();
        for l in out.lines().filter(|l| l.contains(" Newton ")) {
            let step: usize = l.split_whitespace().nth(1).unwrap().parse().unwrap();
            let x: f64 =
                l.split("(relative ").nth(1).unwrap().split(')').next().unwrap().parse().unwrap();
            rel.push((step, x));
        }
        let mut pairs = 0;
        for w in rel.windows(2) {
            let ((s0, a), (s1, b)) = (w[0], w[1]);
            // Quadratic: the exponent log b / log a near 2 while neither is round-off.
            if s0 == s1 && a < 0.1 && a > 1e-7 && b > 1e-13 {
                let order = b.ln() / a.ln();
                assert!(
                    order > 1.8,
                    "{ranks} ranks: step {s0}: {a:e} -> {b:e} (order {order:.2})\n{out}"
                );
                pairs += 1;
            }
        }
        assert!(pairs >= 3, "{ranks} ranks: too few iterations to see the rate\n{out}");
    }
}

#[test]
fn the_free_flying_l_block_keeps_its_energy_and_momenta_after_the_load() {
    let dir = scratch("l_block");
    let scene = scene_variant("l_block.toml", &dir, &[]);
    // The loads end at t = 5 (step 50): from there the block flies free.
    let early = run_scene(2, &scene, &["--steps", "51"]);
    let late = run_scene(1, &scene, &["--steps", "200"]);
    // Equal and opposite loads: no resultant, so no momentum, against the load's impulse
    // |(256, 512, 768)| times the hat's integral 2.5.
    let impulse = (256.0f64.powi(2) + 512.0f64.powi(2) + 768.0f64.powi(2)).sqrt() * 2.5;
    for s in [&early, &late] {
        let p = s.momentum_final.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(p < 1e-10 * impulse, "momentum {:?}", s.momentum_final);
        assert!(s.energy_balance < 1e-10, "energy balance {:e}", s.energy_balance);
    }
    // The load's moment set it spinning; after the load the angular momentum stays.
    let (l5, l20) = (&early.angular_momentum_final, &late.angular_momentum_final);
    let size = l5.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(size > 1e3, "angular momentum {l5:?}");
    for k in 0..3 {
        assert!(
            (l5[k] - l20[k]).abs() < 1e-10 * size,
            "angular momentum {l5:?} at t = 5.1, {l20:?} at t = 20"
        );
    }
    assert!(late.rotations[0].degrees > 90.0, "it turned {:?}", late.rotations);
    // The energy from t = 5 on (1 rank's run).
    let t = values(&dir.join("l_block-1.h5"), "energy/time");
    let e = values(&dir.join("l_block-1.h5"), "energy/total");
    let free: Vec<f64> =
        t.iter().zip(&e).filter(|(t, _)| **t > 5.0 + 1e-9).map(|(_, e)| *e).collect();
    let (lo, hi) = free.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert!(free.len() == 150 && (hi - lo) < 1e-10 * hi, "free flight energy in [{lo}, {hi}]");
}

/// The L2 and H1 errors of the summary's last error sample.
fn last_errors(s: &RunSummary) -> (f64, f64) {
    let e = s.errors.last().expect("an error sample");
    (e.l2, e.h1_semi)
}

#[test]
fn a_manufactured_motion_at_finite_strain_converges_at_second_order_in_h_and_tau() {
    let dir = scratch("manufactured");
    // In space: the body force of tools/manufactured_finite_strain.py makes a motion with
    // strains up to 0.3 exact; tau small enough that the time error is below the space error.
    let tables =
        std::fs::read_to_string(repo().join("tests/data/manufactured_neo_hooke.toml")).unwrap();
    let walls = "[[dirichlet]]\ngroup = \"left\"\n[[dirichlet]]\ngroup = \"right\"\n[[dirichlet]]\ngroup = \"top\"\n[[dirichlet]]\ngroup = \"bottom\"\n";
    let mut space = Vec::new();
    for h in [0.25, 0.125, 0.0625] {
        let name = format!("space_{}", (1.0 / h) as usize);
        let rest = format!("model = \"neo_hookean\"\n{walls}[initial]\nvelocity = [\"pi*sin(pi*x)*sin(pi*y)/5\", \"0\"]\n[time]\ntau = 0.001\nsteps = 100\n{tables}error_steps = [100]\n");
        space.push(last_errors(&run_scene(
            2,
            &small_scene(&dir, &name, "square_quad.geo", h, &rest),
            &[],
        )));
    }
    for w in space.windows(2) {
        let (l2, h1) = ((w[0].0 / w[1].0).log2(), (w[0].1 / w[1].1).log2());
        assert!((1.9..2.2).contains(&l2), "L2 rate {l2:.3} ({space:?})");
        assert!((0.9..1.2).contains(&h1), "H1 rate {h1:.3} ({space:?})");
    }
    // In time: a homogeneous motion u = A(t) X, which the elements hold exactly (its body
    // force rho A'' X; F uniform, so Div P = 0), leaves the midpoint rule's error alone.
    let motion = "[\"0.3*sin(2*pi*t)*x\", \"0.3*(1 - cos(2*pi*t))*y\"]";
    let mut time = Vec::new();
    for n in [20, 40, 80] {
        let boundary: String = ["left", "right", "top", "bottom"]
            .map(|g| format!("[[dirichlet]]\ngroup = \"{g}\"\nvalue = {motion}\n"))
            .concat();
        let rest = format!(
            "model = \"neo_hookean\"\n{boundary}[initial]\nvelocity = [\"0.6*pi*x\", \"0\"]\n[body_force]\nvalue = [\"-1.2*pi^2*sin(2*pi*t)*x\", \"1.2*pi^2*cos(2*pi*t)*y\"]\n[time]\ntau = {}\nsteps = {n}\n[exact]\ndisplacement = {motion}\nvelocity = [\"0.6*pi*cos(2*pi*t)*x\", \"0.6*pi*sin(2*pi*t)*y\"]\ngradient = [[\"0.3*sin(2*pi*t)\", \"0\"], [\"0\", \"0.3*(1 - cos(2*pi*t))\"]]\n",
            0.4 / n as f64
        );
        time.push(last_errors(&run_scene(
            2,
            &small_scene(&dir, &format!("time_{n}"), "square_tri.geo", 0.25, &rest),
            &[],
        )));
    }
    // The first halving is not yet asymptotic (rate 2.3): the second is.
    let rate = (time[1].0 / time[2].0).log2();
    assert!((1.9..2.2).contains(&rate), "tau rate {rate:.3} ({time:?})");
    assert!((time[0].0 / time[1].0).log2() > 1.9, "{time:?}");
}

#[test]
fn at_small_amplitude_the_finite_strain_beam_is_the_linear_one_to_second_order() {
    let dir = scratch("small_amplitude");
    // The paper's beam (section 7.1) with its loads and initial velocity scaled by s: the
    // linear solution scales by s, the neo-Hooke one differs from it by O(s^2).
    let scaled = |s: f64, model: &str| {
        let name = format!("beam_{model}_{}", (1.0 / s).round() as usize);
        let text = format!(
            "name = \"{name}\"\n[mesh]\ngeo = \"../meshes/beam_quad.geo\"\nparams = {{ h = 0.25 }}\n[material]\nE = 200.0\nnu = 0.3\nrho = 1.0\nmodel = \"{model}\"\n[[dirichlet]]\ngroup = \"left\"\n[[dirichlet]]\ngroup = \"right\"\n[[neumann]]\ngroup = \"top\"\ntraction = [\"{s}*40/13*(5 - x)*sin(2*pi*t)\", \"{s}*140/13*x*(10 - x)*sin(2*pi*t)\"]\n[body_force]\nvalue = [\"{s}*200/13*y*(x - 5)*sin(2*pi*t)\", \"{s}*(0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2)*sin(2*pi*t)\"]\n[initial]\nvelocity = [\"0\", \"{s}*0.04*pi*x*(10 - x)*y^2\"]\n[time]\ntau = 2e-3\nsteps = 100\n[output]\nevery = 100\n"
        );
        let scene = scene_text(&dir, &format!("{name}.toml"), &text);
        run_scene(2, &scene, &[]);
        values(&dir.join(format!("{name}-2.h5")), "fields/displacement")
    };
    let mut gaps = Vec::new();
    for s in [0.02, 0.01] {
        let (nh, lin) = (scaled(s, "neo_hookean"), scaled(s, "linear"));
        let n = nh.len() / 2;
        let size = lin[n..].iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let gap = nh[n..].iter().zip(&lin[n..]).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        gaps.push((s, size, gap));
    }
    // Halving the amplitude halves the linear solution and quarters the difference.
    let order = (gaps[0].2 / gaps[1].2).log2();
    assert!(rel_diff(gaps[0].1, 2.0 * gaps[1].1) < 1e-9, "{gaps:?}");
    assert!((1.9..2.1).contains(&order), "the difference falls at order {order:.3}: {gaps:?}");
    assert!(gaps[1].2 < 0.05 * gaps[1].1, "{gaps:?}");
}

#[test]
fn a_block_at_finite_strain_slides_down_a_slope_at_g_sin_minus_mu_cos() {
    let dir = scratch("slope_finite");
    // The unit square (E = 1e4: nearly rigid) on the plane y = 0 with gravity turned by
    // theta = 30 degrees, Coulomb mu = 0.3, the mass-free layer along its bottom.
    let (g, theta, mu, steps) = (10.0, std::f64::consts::PI / 6.0, 0.3, 100);
    let scene = scene_text(
        &dir,
        "slope.toml",
        &format!(
            "name = \"slope\"\n[mesh]\ngeo = \"../meshes/square_quad.geo\"\nparams = {{ h = 0.25 }}\n[material]\nE = 1e4\nnu = 0.3\nrho = 1.0\nmodel = \"neo_hookean\"\n[body_force]\nacceleration = [\"{g}*sin(pi/6)\", \"-{g}*cos(pi/6)\"]\n[time]\ntau = 1e-2\nsteps = {steps}\n[mass]\nkind = \"modified1\"\n[contact]\nboundary = \"bottom\"\nobstacle = {{ type = \"plane\", point = [0.0, 0.0], normal = [0.0, 1.0] }}\nfriction = {mu}\n[output]\nevery = 10\n"
        ),
    );
    let a = g * (theta.sin() - mu * theta.cos());
    let t = steps as f64 * 1e-2;
    let mut runs = Vec::new();
    for ranks in [1, 2] {
        let s = run_scene(ranks, &scene, &[]);
        // Impulse = momentum change: the mean acceleration P(T) / (m T), m = 1; the normal
        // force's start-up oscillation leaves it within 1%.
        let a_run = s.momentum_final[0] / t;
        assert!(rel_diff(a_run, a) < 0.01, "{ranks} ranks: acceleration {a_run} against {a}");
        // The dissipation is mu m g cos theta per unit of sliding.
        let u = values(&dir.join(format!("slope-{ranks}.h5")), "fields/displacement");
        let last = &u[u.len() - 50..];
        let x = (0..25).map(|k| last[2 * k]).sum::<f64>() / 25.0;
        assert!(rel_diff(x, a * t * t / 2.0) < 0.01, "distance {x} against {}", a * t * t / 2.0);
        let d = s.contact.as_ref().unwrap().friction_dissipation;
        assert!(rel_diff(d, mu * g * theta.cos() * x) < 0.01, "dissipation {d}");
        assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
        runs.push(s);
    }
    assert!(rel_diff(runs[0].momentum_final[0], runs[1].momentum_final[0]) < 1e-8);
    let (d1, d2) = (runs[0].contact.as_ref().unwrap(), runs[1].contact.as_ref().unwrap());
    assert!(rel_diff(d1.friction_dissipation, d2.friction_dissipation) < 1e-8);
}

/// The total contact force per step and whether any node is active.
fn contact_force(h5: &Path) -> (Vec<f64>, Vec<bool>) {
    force_history(h5)
}

#[test]
fn a_soft_ball_follows_hertz_slowly_and_keeps_its_energy_flattened_by_a_fifth() {
    let dir = scratch("soft_ball");
    let model = ("rho = 1.0\n", "rho = 1.0\nmodel = \"neo_hookean\"\n");
    // Slowly (v = 0.0167, indentation 1% of R): Hertz's impact, as for the linear ball.
    // E* = E / (1 - nu^2), delta = (15 m v^2 / (16 E* sqrt R))^(2/5), F = 4/3 E* sqrt(R)
    // delta^(3/2), t_c = 2.87 (m^2 / (R E*^2 v))^(1/5).
    let slow = scene_variant("sphere.toml", &dir, &[model]);
    let s = run_scene(2, &slow, &[]);
    let (m, es, v) = (s.mass.total_mass[2], 100.0 / (1.0 - 0.09), 0.0167);
    let delta = (15.0 * m * v * v / (16.0 * es)).powf(0.4);
    let (f_max, t_c) = (4.0 / 3.0 * es * delta.powf(1.5), 2.87 * (m * m / (es * es * v)).powf(0.2));
    let (force, any) = contact_force(&dir.join("sphere-2.h5"));
    let duration = any.iter().filter(|&&a| a).count() as f64 * 0.01;
    let peak = force.iter().cloned().fold(0.0, f64::max);
    assert!((duration / t_c - 1.0).abs() < 0.10, "contact time {duration} vs Hertz {t_c}");
    assert!((peak / f_max - 1.0).abs() < 0.10, "peak force {peak} vs Hertz {f_max}");
    assert_eq!(s.contact.as_ref().unwrap().episodes_max, 1);
    // Fast (v = 1.7): the ball is flattened by more than a fifth of its height; the mass-free
    // layer and the energy correction keep the energy across the impact, each node touches
    // once, and 1, 2 and 3 ranks give the same impact.
    let dir = dir.join("fast");
    std::fs::create_dir_all(&dir).unwrap();
    let fast = scene_variant(
        "sphere.toml",
        &dir,
        &[
            model,
            ("\"-0.0167\"", "\"-1.7\""),
            ("steps = 220", "steps = 100"),
            ("every = 10", "every = 1"),
        ],
    );
    let runs: Vec<(usize, RunSummary)> = [1, 2, 3].map(|r| (r, run_scene(r, &fast, &[]))).into();
    let (f2, _) = contact_force(&dir.join("sphere-2.h5"));
    let f_peak = f2.iter().cloned().fold(0.0, f64::max);
    for (r, s) in &runs {
        let c = s.contact.as_ref().unwrap();
        let drift = rel_diff(s.energy_final, s.energy_initial);
        assert!(
            drift < 1e-8,
            "{r} ranks: energy {} -> {} ({drift:e})",
            s.energy_initial,
            s.energy_final
        );
        assert_eq!(c.episodes_max, 1, "{r} ranks: a node touched twice");
        assert!(c.last_contact_step < s.steps, "{r} ranks: the ball must leave the plane");
        let dp = s.momentum_final[2] - s.momentum_initial[2];
        assert!(
            rel_diff(c.impulse[2], dp) < 1e-8,
            "{r} ranks: impulse {} vs momentum change {dp}",
            c.impulse[2]
        );
        let (f, _) = contact_force(&dir.join(format!("sphere-{r}.h5")));
        let diff = f.iter().zip(&f2).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        assert!(diff < 1e-8 * f_peak, "{r} ranks: contact forces differ by {diff:e} of {f_peak:e}");
    }
    // The flattening: the ball's height at its most compressed over its diameter.
    let run = reader(&dir.join("sphere-2.h5"));
    let x = run.series("mesh/coordinates").unwrap();
    let u = run.series("fields/displacement").unwrap();
    let n = x.len() / 3;
    let height = |k: usize| {
        let z = (0..n).map(|v| x[3 * v + 2] + u[k * 3 * n + 3 * v + 2]);
        let (lo, hi) = z.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), z| (a.min(z), b.max(z)));
        hi - lo
    };
    let least = (0..u.len() / (3 * n)).map(height).fold(f64::INFINITY, f64::min);
    assert!(1.0 - least / height(0) > 0.2, "flattened by {:.3} only", 1.0 - least / height(0));
}

#[test]
fn a_kept_tangent_reaches_the_newton_solution() {
    let dir = scratch("tangent_reuse");
    let scene = scene_variant("l_block.toml", &dir, &[]);
    let newton = run_scene(2, &scene, &["--steps", "60"]);
    let u_newton = values(&dir.join("l_block-2.h5"), "fields/displacement");
    let kept = run_scene(2, &scene, &["--steps", "60", "--", "-newton_tangent_reuse", "0.1"]);
    let u_kept = values(&dir.join("l_block-2.h5"), "fields/displacement");
    let stats = kept.newton.unwrap();
    assert!(stats.kept_tangent > 0 && newton.newton.unwrap().kept_tangent == 0);
    // Both converge the same equations to the same tolerances: the same motion, and the
    // energy identity holds as tightly.
    let scale = u_newton.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = u_newton.iter().zip(&u_kept).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(diff < 1e-8 * scale, "the kept tangent's motion differs by {diff:e} of {scale:e}");
    assert!(kept.energy_balance < 1e-10, "energy balance {:e}", kept.energy_balance);
}

/// The suite's disc (neo-Hooke, E = 100, nu = 0.3) on a contact mesh twice as fine (hc =
/// 0.025, 1798 DOFs) squeezed to a fifth of its height (v/c = 0.2) with the mass-free layer
/// `M_H^1`: at the rebound layer nodes inside the contact zone are released, and Newton from the
/// extrapolated guess (the last motion run on) finds no step near it; from the step's start it
/// does. The run goes through, its energy kept to the Newton tolerance.
#[test]
fn a_squeezed_disc_on_a_fine_contact_mesh_rebounds_with_the_mass_free_layer() {
    let dir = scratch("fine-squeeze");
    let base = std::fs::read_to_string(repo().join("scenes/suite/disc_impact.toml")).unwrap();
    let text = base
        .replace("\"../../meshes/", "\"../meshes/")
        .replace("h = 0.25, hc = 0.05, rc = 0.15", "h = 0.1, hc = 0.025, rc = 0.3")
        .replace("\nnu = 0.3\n", "\nnu = 0.3\nmodel = \"neo_hookean\"\n")
        .replace("-0.116024", "-2.32048")
        .replace("steps = 250", "steps = 60")
        .replace("every = 250", "every = 60");
    assert!(
        text.contains("hc = 0.025") && text.contains("neo_hookean") && text.contains("2.32048")
    );
    let scene = scene_text(&dir, "fine_squeeze.toml", &text);
    let s = run_scene(2, &scene, &["--mass", "modified1"]);
    let c = s.contact.as_ref().expect("contact");
    eprintln!(
        "balance {}, contact {:?}, restarts {}",
        s.energy_balance,
        c.max_active_nodes,
        s.newton.as_ref().unwrap().restarts
    );
    assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
    assert!(c.max_active_nodes > 20, "squeezed flat: {} active nodes", c.max_active_nodes);
}
