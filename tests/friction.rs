//! Coulomb friction against rigid obstacles (issue 25): a block on a slope slides with
//! `a = g (sin theta - mu cos theta)` and dissipates `mu m g cos theta` per unit of sliding, or
//! sticks when `mu > tan theta`; in 3D it slides straight downhill; a disc hitting a plane
//! obliquely with little friction slips at every node (`t = mu lambda`), with much friction
//! sticks and spins off; Tresca's bound gives a constant friction force and dissipates `S L`
//! per unit of sliding; `friction = 0` is frictionless, and a vanishing `mu` approaches the
//! frictionless solution by the Coulomb impulse `mu J_n`; Cattaneo and Mindlin's partial slip;
//! every result the same on 1, 2 and 3 ranks.

mod common;
use common::*;
use std::path::Path;

/// Gravity `g` on a slope of angle `theta`: the plane stays y = 0 (z = 0 in 3D) and gravity
/// turns, `a = g (sin theta, -cos theta)` (3D: downhill along the angle `phi` in the plane).
const G: f64 = 10.0;
const THETA: f64 = std::f64::consts::PI / 6.0;

/// The unit square (E = 1e4, so the block is nearly rigid: its first frequencies lie far
/// above 1/T, and the normal force's start-up oscillation averages out over the run) on the
/// plane y = 0, with the mass-free layer along its bottom; `rest` adds [contact] keys and
/// tables.
fn slope_2d(
    dir: &Path,
    name: &str,
    gravity: &str,
    steps: usize,
    friction: &str,
) -> std::path::PathBuf {
    let text = format!(
        r#"name = "{name}"
[mesh]
geo = "../meshes/square_quad.geo"
params = {{ h = 0.25 }}
[material]
E = 1e4
nu = 0.3
rho = 1.0
[body_force]
acceleration = [{gravity}]
[time]
tau = 1e-2
steps = {steps}
[mass]
kind = "modified1"
[contact]
boundary = "bottom"
obstacle = {{ type = "plane", point = [0.0, 0.0], normal = [0.0, 1.0] }}
{friction}
[output]
every = 10
"#
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

fn gravity_2d(ramp: Option<f64>) -> String {
    let r = ramp.map_or(String::new(), |t| format!("*min(t/{t}, 1)"));
    format!("\"{G}*sin(pi/6){r}\", \"-{G}*cos(pi/6){r}\"")
}

fn contact(s: &RunSummary) -> &massfree::contact::history::ContactSummary {
    s.contact.as_ref().expect("a [contact] summary")
}

/// Node values of the last written displacement, `dim` per node.
fn last_displacement(h5: &Path) -> (Vec<f64>, usize) {
    let run = reader(h5);
    let ds = run.file.dataset(&layout::field("displacement")).unwrap();
    let shape = ds.shape();
    let all = run.series(&layout::field("displacement")).unwrap();
    let per = shape[1] * shape[2];
    (all[all.len() - per..].to_vec(), shape[2])
}

fn mean_component(u: &[f64], dim: usize, c: usize) -> f64 {
    let n = u.len() / dim;
    (0..n).map(|k| u[k * dim + c]).sum::<f64>() / n as f64
}

#[test]
fn a_block_slides_down_a_slope_at_g_sin_minus_mu_cos_and_dissipates_mu_n_per_length() {
    let dir = scratch("friction_slide");
    let mu = 0.3;
    let steps = 100;
    let t = steps as f64 * 1e-2;
    let scene = slope_2d(&dir, "slide", &gravity_2d(None), steps, &format!("friction = {mu}"));
    let a = G * (THETA.sin() - mu * THETA.cos());
    let mut runs = Vec::new();
    for ranks in [1, 2] {
        let s = run_scene(ranks, &scene, &[]);
        let m = s.bodies.first().map_or(s.mass.total_mass[0], |b| b.total_mass[0]);
        assert!((m - 1.0).abs() < 1e-12, "the unit square's mass: {m}");
        // Momentum: the midpoint rule keeps impulse = momentum change exactly, so the mean
        // acceleration is P(T) / (m T); the normal force's oscillation leaves it within 1%.
        let a_run = s.momentum_final[0] / (m * t);
        eprintln!(
            "{ranks} rank(s): a = {a_run:.6} (theory {a:.6}), y momentum {:.2e}",
            s.momentum_final[1]
        );
        assert!(rel_diff(a_run, a) < 0.01, "acceleration {a_run} against {a}");
        // Displacement along the slope against a t^2 / 2.
        let h5 = dir.join(format!("slide-{ranks}.h5"));
        let (u, dim) = last_displacement(&h5);
        let x = mean_component(&u, dim, 0);
        assert!(rel_diff(x, a * t * t / 2.0) < 0.01, "distance {x} against {}", a * t * t / 2.0);
        // Dissipation: mu m g cos theta per unit of sliding.
        let c = contact(&s);
        let d = c.friction_dissipation;
        let expected = mu * m * G * THETA.cos() * x;
        eprintln!("dissipation {d:.6} against mu N x = {expected:.6}");
        assert!(rel_diff(d, expected) < 0.01, "dissipation {d} against {expected}");
        // The energy identity with the dissipation: E - E0 = W_loads + W_contact - D.
        assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
        let energy = reader(&h5).series(&layout::energy("friction_dissipation")).unwrap();
        assert!((energy.last().unwrap() - d).abs() <= 1e-12 * d, "the series ends at the total");
        assert!(energy.windows(2).all(|w| w[1] >= w[0] - 1e-14 * d), "D only grows");
        // Most nodes slip (the corners may lift off while the block rocks).
        assert!(
            c.slip_node_steps > 4 * c.stick_node_steps,
            "{} slip, {} stick",
            c.slip_node_steps,
            c.stick_node_steps
        );
        runs.push((s, h5));
    }
    // 1 and 2 ranks: the same run.
    let (s1, h1) = &runs[0];
    let (s2, h2) = &runs[1];
    assert!(rel_diff(s1.momentum_final[0], s2.momentum_final[0]) < 1e-8);
    assert!(rel_diff(contact(s1).friction_dissipation, contact(s2).friction_dissipation) < 1e-8);
    let name = layout::contact(layout::CONTACT_TANGENTIAL);
    let (t1, t2) = (reader(h1).series(&name).unwrap(), reader(h2).series(&name).unwrap());
    let scale = t1.iter().fold(0.0f64, |a, &x| a.max(x.abs()));
    let diff = t1.iter().zip(&t2).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
    assert!(diff <= 1e-8 * scale, "tangential tractions differ by {diff:e} of {scale:e}");
}

#[test]
fn a_block_whose_friction_exceeds_tan_theta_sticks() {
    // mu = 0.7 > tan 30 deg = 0.577. Gravity ramps up over 0.3 s, so that the block does
    // not start rocking; it then shears elastically but does not move along the plane.
    let dir = scratch("friction_stick");
    let scene = slope_2d(&dir, "stick", &gravity_2d(Some(0.3)), 200, "friction = 0.7");
    let s = run_scene(2, &scene, &[]);
    let h5 = dir.join("stick-2.h5");
    let run = reader(&h5);
    let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
    let slip = run.series(&layout::contact(layout::CONTACT_SLIP)).unwrap();
    let nc = run.series(layout::CONTACT_NODES).unwrap().len();
    // A node that sticks does not move along the plane, to solver tolerance.
    for (k, st) in state.iter().enumerate() {
        if *st == 1.0 {
            let s = (slip[2 * k].powi(2) + slip[2 * k + 1].powi(2)).sqrt();
            assert!(s < 1e-10, "step {}, node {}: slip {s:e} while sticking", k / nc, k % nc);
        }
    }
    // At the end every node in contact sticks.
    let last = &state[state.len() - nc..];
    assert!(last.iter().all(|&x| x != 2.0), "the last step's states: {last:?}");
    assert!(last.iter().filter(|&&x| x == 1.0).count() >= 3, "{last:?}");
    // The block moves only by its elastic shear: the mean shear stress at its base is
    // rho g sin theta L, and the shear strain tau / G over the height L gives a top
    // displacement rho g sin theta L^2 / G (the mean over the block is below it); twice that
    // leaves room for the vibration, a slipping block would be far beyond.
    let shear_modulus = 1e4 / (2.0 * 1.3);
    let elastic = G * THETA.sin() / shear_modulus;
    let (u, dim) = last_displacement(&h5);
    let x = mean_component(&u, dim, 0);
    eprintln!("mean displacement {x:e}, elastic bound {elastic:e}");
    assert!(x.abs() < 2.0 * elastic, "the block crept: {x} against {elastic}");
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
}

#[test]
fn in_3d_the_block_slides_straight_downhill() {
    // Downhill points at phi = 30 deg in the plane: the slip directions are no axis, and the
    // two tangents of every node carry it.
    let dir = scratch("friction_3d");
    let mu = 0.3;
    let phi = std::f64::consts::PI / 6.0;
    let text = format!(
        r#"name = "slide3d"
[mesh]
geo = "../meshes/cube_hex.geo"
params = {{ h = 0.25 }}
[material]
E = 1e4
nu = 0.3
rho = 1.0
[body_force]
acceleration = ["{G}*sin(pi/6)*cos(pi/6)", "{G}*sin(pi/6)*sin(pi/6)", "-{G}*cos(pi/6)"]
[time]
tau = 1e-2
steps = 100
[mass]
kind = "modified1"
[contact]
boundary = "bottom"
obstacle = {{ type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }}
friction = {mu}
[output]
every = 50
"#
    );
    let scene = scene_text(&dir, "slide3d.toml", &text);
    let s = run_scene(2, &scene, &[]);
    let a = G * (THETA.sin() - mu * THETA.cos());
    let p = &s.momentum_final;
    let along = (p[0] * phi.cos() + p[1] * phi.sin()) / 1.0;
    let across = -p[0] * phi.sin() + p[1] * phi.cos();
    eprintln!("downhill {along:.6} (theory {a:.6}), across {across:e}, normal {:e}", p[2]);
    assert!(rel_diff(along, a) < 0.01, "downhill momentum {along} against {a}");
    assert!(across.abs() < 1e-3 * a, "the block turned away from downhill: {across}");
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    // The friction impulse points uphill, mu times the normal impulse where every node slips.
    let c = contact(&s);
    let f = &c.friction_impulse;
    let len = (f[0] * f[0] + f[1] * f[1]).sqrt();
    let uphill = [-phi.cos(), -phi.sin()];
    assert!(
        (f[0] / len - uphill[0]).abs() < 1e-3 && (f[1] / len - uphill[1]).abs() < 1e-3,
        "friction impulse {f:?}"
    );
    // The dissipation from the block's motion, not from the solver's tractions and slips: a
    // sliding block's friction is mu N, N = m g cos theta on average, so sliding a distance x
    // (the mean displacement downhill, from the displacement field) costs mu m g cos theta x.
    // The normal force oscillates about that (gravity switched on at t = 0; the midpoint rule
    // does not damp it), with a relative amplitude A at an angular frequency omega; weighted
    // by the speed a t, an oscillation's share of D over the run T is at most
    // A (2 / (omega T) + 4 / (omega T)^2) of it. A and omega from the normal force's series
    // (its largest excursion; pi times its crossings of the mean per unit time).
    let m = s.mass.total_mass[0];
    assert!((m - 1.0).abs() < 1e-12, "the unit cube's mass: {m}");
    let h5 = dir.join("slide3d-2.h5");
    let run = reader(&h5);
    let nc = run.series(layout::CONTACT_NODES).unwrap().len();
    let lambda = run.series(&layout::contact("force")).unwrap();
    let n0 = m * G * THETA.cos();
    let normal: Vec<f64> = lambda.chunks(nc).skip(1).map(|r| r.iter().sum::<f64>() / n0).collect();
    let amplitude = normal.iter().fold(0.0f64, |a, &x| a.max((x - 1.0).abs()));
    let crossings = normal.windows(2).filter(|w| (w[0] - 1.0) * (w[1] - 1.0) < 0.0).count();
    let t = 1.0;
    let omega = std::f64::consts::PI * crossings as f64 / t;
    let tol = amplitude * (2.0 / (omega * t) + 4.0 / (omega * t).powi(2));
    let (u, dim) = last_displacement(&h5);
    let x = mean_component(&u, dim, 0) * phi.cos() + mean_component(&u, dim, 1) * phi.sin();
    let d = c.friction_dissipation;
    let expected = mu * m * G * THETA.cos() * x;
    eprintln!(
        "slid {x:.6} (a T^2 / 2 = {:.6}); dissipation {d:.6} against mu m g cos theta x = \
         {expected:.6} ({:+.2e}); the normal force's oscillation: A = {amplitude:.3}, \
         omega = {omega:.1}: bound {tol:.2e}",
        a * t * t / 2.0,
        d / expected - 1.0
    );
    assert!(rel_diff(d, expected) < tol, "dissipation {d} against {expected}");
    // The series is the summary's total, step by step, and only grows.
    let series = run.series(&layout::energy("friction_dissipation")).unwrap();
    assert!((series.last().unwrap() - d).abs() <= 1e-12 * d, "the series ends at the total");
    assert!(series.windows(2).all(|w| w[1] >= w[0] - 1e-14 * d), "D only grows");
}

/// The oblique disc's tangential and normal speeds: disc.toml's 800, turned so that the disc
/// slides twice as fast as it comes down.
const V_T: f64 = 800.0;
const V_N: f64 = 400.0;
/// The disc's radius (disc.toml, disc_oblique.toml).
const R_DISC: f64 = 8.0;

/// The disc of `scenes/disc.toml` (R = 8, E = 100, the mass-free layer) hitting the plane
/// obliquely at (V_T, -V_N), 400 steps (in contact from step 125 on, still pressed at the end).
fn oblique_disc(dir: &Path, friction: &str) -> std::path::PathBuf {
    scene_variant(
        "disc.toml",
        dir,
        &[
            ("velocity = [\"0\", \"-800\"]", &format!("velocity = [\"{V_T}\", \"-{V_N}\"]")),
            ("[output]", &format!("{friction}\n[output]")),
            ("steps = 1000", "steps = 400"),
            ("every = 10", "every = 100"),
        ],
    )
}

/// A disc's mass and moment of inertia about its centre of mass, from the mass matrix's
/// moments: `I = sum_c X_c^T M X_c - |X^T M 1|^2 / m`, the `I` of `L = I omega` for a rigid
/// rotation of the discrete disc (the summary's `L` is taken about the centre of mass).
fn disc_inertia(s: &RunSummary) -> (f64, f64) {
    let m = s.mass.total_mass[0];
    let (f, q) = (&s.mass.first_moment, &s.mass.second_moment);
    (m, q[0] + q[1] - (f[0] * f[0] + f[1] * f[1]) / m)
}

/// The oblique disc slides at every node, in theory. A rigid disc's contact point (tangential
/// velocity `v_c = v_x + omega R`) slows by `(1/m + R^2/I) J_t` under the friction impulse
/// `J_t <= mu J_n` (`J_n` the normal impulse: the y momentum's change; `1 + m R^2 / I = 3` for
/// a uniform disc), so it keeps sliding forward while `V_T - (1/m + R^2/I) mu J_n > 0`. The
/// nodes' own tangential velocities differ from the rigid contact point's by the disc's
/// elastic motion, which the impact at `V_N` drives and keeps below `V_N` (a wave from an
/// impact at `V_N` moves the material at `V_N` at most; the nodes' slip rates scatter by
/// about 0.3 `V_N` around the contact point's here). So where the contact point keeps more
/// than `V_N`, no node can come to rest on the plane: none sticks, and every step's friction
/// is `mu` times its normal force. Asserts that, and returns the contact point's least speed.
fn assert_no_node_can_stick(s: &RunSummary, mu: f64) -> f64 {
    let (m, inertia) = disc_inertia(s);
    let p0 = &s.momentum_initial;
    assert!(rel_diff(p0[0], m * V_T) < 1e-12 && rel_diff(p0[1], -m * V_N) < 1e-12, "{p0:?}");
    let j_n = s.momentum_final[1] - p0[1];
    let v_c = V_T - (1.0 / m + R_DISC * R_DISC / inertia) * mu * j_n;
    eprintln!(
        "mu = {mu}: J_n / m = {:.2}, 1 + m R^2 / I = {:.4}: the contact point keeps {v_c:.2} > V_N = {V_N}",
        j_n / m,
        1.0 + m * R_DISC * R_DISC / inertia
    );
    assert!(v_c > V_N, "precondition of gross slip: the contact point keeps {v_c}, not > {V_N}");
    v_c
}

#[test]
fn an_oblique_impact_with_little_friction_slips_at_every_node_on_any_rank_count() {
    let dir = scratch("friction_oblique");
    let mu = 0.1;
    let scene = oblique_disc(&dir, &format!("friction = {mu}"));
    let mut histories = Vec::new();
    for ranks in [1, 2, 3] {
        let s = run_scene(ranks, &scene, &[]);
        let h5 = dir.join(format!("disc-{ranks}.h5"));
        let run = reader(&h5);
        let lambda = run.series(&layout::contact("force")).unwrap();
        let weights = run.series(layout::CONTACT_WEIGHTS).unwrap();
        let nc = weights.len();
        let tt = run.series(&layout::contact(layout::CONTACT_TANGENTIAL)).unwrap();
        // The force on the obstacle side, t_q = -(traction on the body) D_qq.
        let t: Vec<f64> = (0..lambda.len()).map(|k| -tt[2 * k] * weights[k % nc]).collect();
        let scale = lambda.iter().fold(0.0f64, |a, &x| a.max(x));
        // Never beyond the cone, at any node and step (to solver tolerance).
        for k in 0..lambda.len() {
            assert!(
                t[k].abs() <= mu * lambda[k] + 1e-7 * mu * scale,
                "step {}, node {}: |t| = {:e} > mu lambda = {:e}",
                k / nc,
                k % nc,
                t[k].abs(),
                mu * lambda[k]
            );
        }
        // Gross slip, from the precondition: no node sticks, tangential impulse = mu x normal
        // impulse.
        let c = contact(&s);
        assert_no_node_can_stick(&s, mu);
        let slip = run.series(&layout::contact(layout::CONTACT_SLIP)).unwrap();
        let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
        let rates = (0..lambda.len()).filter(|&k| state[k] != 0.0).map(|k| slip[2 * k] / 1e-6);
        let (lo, hi) = rates.fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v), b.max(v)));
        eprintln!("{ranks} rank(s): the nodes' slip rates lie in [{lo:.1}, {hi:.1}]");
        assert_eq!(c.stick_node_steps, 0, "the disc slides along: no node sticks");
        let (sum_t, sum_l): (f64, f64) = (t.iter().sum(), lambda.iter().sum());
        eprintln!("{ranks} rank(s): sum t = {sum_t:.12e}, mu sum lambda = {:.12e}", mu * sum_l);
        assert!(rel_diff(sum_t, mu * sum_l) < 1e-8, "{sum_t} against {}", mu * sum_l);
        // It pushes the obstacle forward (+x), so the disc's friction impulse points back.
        assert!(c.friction_impulse[0] < 0.0 && sum_t > 0.0);
        // The energy identity, the dissipation >= 0 and the energy lost to it.
        assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
        let lost = s.energy_initial - s.energy_final;
        assert!(c.friction_dissipation > 0.0);
        assert!(
            rel_diff(lost, c.friction_dissipation) < 1e-6,
            "lost {lost} against D = {}",
            c.friction_dissipation
        );
        histories.push((t, lambda, s.momentum_final.clone()));
    }
    let (t1, l1, p1) = &histories[0];
    for (t, l, p) in &histories[1..] {
        let scale = l1.iter().fold(0.0f64, |a, &x| a.max(x));
        let dt = t1.iter().zip(t).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        let dl = l1.iter().zip(l).fold(0.0f64, |a, (x, y)| a.max((x - y).abs()));
        assert!(
            dt <= 1e-8 * scale && dl <= 1e-8 * scale,
            "histories differ: {dt:e}, {dl:e} of {scale:e}"
        );
        assert!(rel_diff(p1[0], p[0]) < 1e-8 && rel_diff(p1[1], p[1]) < 1e-8);
    }
}

#[test]
fn an_oblique_impact_with_much_friction_sticks_and_leaves_the_disc_spinning() {
    // disc_oblique.toml (the disc hitting the plane at (v_t, -v_n) = (400, -800), mu = 0.3)
    // with E = 1e5: in contact for some 30 steps.
    //
    // A rigid disc: the friction impulse J_t slows the centre to v_x = v_t - J_t / m and spins
    // the disc to omega = -R J_t / I, so the contact point v_c = v_x + omega R slows by
    // (1/m + R^2/I) J_t = 3 J_t / m. Sliding stops at J_t = m v_t / 3, the rolling limit
    // (v_x = 2 v_t / 3, omega R = -v_x); Coulomb allows up to mu J_n (J_n about 2 m v_n), far
    // more: the contact must stick (asserted below from the run's J_n).
    //
    // An elastic disc does not leave rolling, however stiff: its stuck contact zone is a
    // tangential spring whose compliance is of the order of the normal one (both scale as
    // 1/E), and it gives its energy back as the load falls, so the contact point leaves with
    // a tangential velocity of either sign (tangential restitution e_t = -v_c / v_t; Maw,
    // Barber and Fawcett 1976; measured here 0.37, at E = 1e4 0.42, at E = 1e3 0.46, and
    // -0.17 with mu = 1). What theory does give, each failing on a wrong friction:
    // - it sticks: node-steps in stick (a friction too weak to stop the sliding would slip
    //   throughout), and J_t < mu J_n (equality is gross slip);
    // - the friction slows the disc and spins it along its travel: J_t > 0, L < 0;
    // - the energy bounds the contact point's reversal: the rigid-body part of the final
    //   motion, |p|^2 / 2m + L^2 / 2I, is at most the initial energy (the friction only
    //   dissipates; the rest of the kinetic energy is at least L^2 / 2I by Cauchy-Schwarz). A
    //   friction that kept pushing at mu J_n once the slip reversed would leave the contact
    //   point at v_t - 3 mu J_n / m = -1000, far beyond what the bound allows.
    let dir = scratch("friction_spin");
    let scene = scene_variant(
        "disc_oblique.toml",
        &dir,
        &[("E = 100.0", "E = 1e5"), ("steps = 1000", "steps = 200"), ("every = 10", "every = 100")],
    );
    let mu = 0.3;
    let s = run_scene(1, &scene, &[]);
    let c = contact(&s);
    assert!(c.last_contact_step < 200, "the disc left the plane");
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    let (m, inertia) = disc_inertia(&s);
    let (p0, p1) = (&s.momentum_initial, &s.momentum_final);
    let v_t = p0[0] / m;
    assert!(rel_diff(v_t, 400.0) < 1e-12 && s.angular_momentum_initial[2].abs() < 1e-12 * m);
    let (j_t, j_n) = (p0[0] - p1[0], p1[1] - p0[1]);
    let k = 1.0 / m + R_DISC * R_DISC / inertia;
    // Precondition: Coulomb's friction can stop the contact point.
    assert!(k * mu * j_n > v_t, "mu J_n = {} cannot stop v_t = {v_t}", mu * j_n);
    assert!(
        c.stick_node_steps > 0 && c.slip_node_steps > 0,
        "{} stick, {} slip",
        c.stick_node_steps,
        c.slip_node_steps
    );
    assert!(j_t < mu * j_n, "J_t = {j_t} against mu J_n = {}", mu * j_n);
    // Slowed down and spinning clockwise with its travel (+x).
    let l = s.angular_momentum_final[2];
    assert!(j_t > 0.0 && l < 0.0, "J_t = {j_t}, L = {l}");
    let (v_x, omega_r) = (p1[0] / m, l / inertia * R_DISC);
    let v_c = v_x + omega_r;
    eprintln!(
        "v_x = {v_x:.2}, omega R = {omega_r:.2} (rolling: {:.2}, {:.2}); the contact point \
         leaves at {v_c:.2}: e_t = {:.3}; J_t / (mu J_n) = {:.3}",
        2.0 * v_t / 3.0,
        -2.0 * v_t / 3.0,
        -v_c / v_t,
        j_t / (mu * j_n)
    );
    let rigid = (p1[0] * p1[0] + p1[1] * p1[1]) / (2.0 * m) + l * l / (2.0 * inertia);
    eprintln!("rigid-body energy at the end {rigid:.6} of {:.6}", s.energy_initial);
    assert!(rigid <= s.energy_initial, "{rigid} > E0 = {}", s.energy_initial);
}

#[test]
fn friction_zero_is_frictionless_and_a_vanishing_mu_approaches_it() {
    // `friction = 0` is frictionless by definition (README, the scene format): the parser
    // makes it no law at all, so a run with it is the frictionless run itself.
    let dir = scratch("friction_zero");
    let zero = oblique_disc(&dir, "friction = 0");
    let spec = massfree::scene::load(&zero).unwrap_or_else(|e| panic!("{e}"));
    let spec = spec.contact.expect("a [contact]");
    assert!(!spec.has_friction() && spec.obstacles[0].friction.is_none(), "friction = 0");
    // Coulomb's friction with mu -> 0 against the frictionless solver, 2 ranks each.
    let mu = 1e-3;
    let run = |name: &str, law: &str| {
        let sub = dir.join(name);
        std::fs::create_dir_all(&sub).unwrap();
        (run_scene(2, &oblique_disc(&sub, law), &[]), sub.join("disc-2.h5"))
    };
    let (plain, h_plain) = run("plain", "");
    let (small, _) = run("small", &format!("friction = {mu}"));
    // No friction data without friction.
    assert!(reader(&h_plain).file.dataset(&layout::contact(layout::CONTACT_STATE)).is_err());
    assert_eq!(contact(&plain).friction_dissipation, 0.0);
    // Momenta to the step solver's tolerance (1e-8 of the momentum, as on 1, 2 and 3 ranks).
    let p0 = &plain.momentum_initial;
    let tol = 1e-8 * (p0[0] * p0[0] + p0[1] * p0[1]).sqrt();
    // The frictionless plane exerts no tangential force: the x momentum stays.
    let drift = plain.momentum_final[0] - p0[0];
    assert!(drift.abs() <= tol, "frictionless x momentum drifts by {drift:e}");
    // With mu = 1e-3 the disc slides at every node (precondition), so the friction impulse is
    // exactly mu J_n against the travel, and it is all that changes the x momentum.
    assert_no_node_can_stick(&small, mu);
    assert_eq!(contact(&small).stick_node_steps, 0);
    let j_n = small.momentum_final[1] - small.momentum_initial[1];
    let j_n0 = plain.momentum_final[1] - p0[1];
    let dp_x = plain.momentum_final[0] - small.momentum_final[0];
    eprintln!(
        "x momentum lost {dp_x:.9e} against mu J_n = {:.9e}; J_n {j_n:.9e} against {j_n0:.9e} \
         without friction",
        mu * j_n
    );
    assert!((dp_x - mu * j_n).abs() <= tol, "{dp_x:e} against mu J_n = {:e}", mu * j_n);
    // The normal impulse changes only through the elastic coupling of the tangential and
    // normal responses, which Dundurs' beta = (1 - 2 nu) / (2 (1 - nu)) bounds for an elastic
    // body on a rigid one: at most beta mu J_n.
    let beta = (1.0 - 2.0 * 0.3) / (2.0 * (1.0 - 0.3));
    let dj = (j_n - j_n0).abs();
    eprintln!("|J_n - J_n0| = {:.3e} mu J_n (beta = {beta:.3})", dj / (mu * j_n));
    assert!(dj <= beta * mu * j_n, "the normal impulse moved by {dj:e}");
    // The dissipation: every node slides at V_T plus its elastic lateral velocity, which is odd
    // in x in the frictionless impact (the vertical impact carried along at V_T), so D ->
    // mu J_n V_T. Off by the slowing down, (1/m + R^2/I) mu J_n / V_T (below 1e-3), and what
    // the mesh's asymmetry (unstructured quads) leaves of the lateral velocities' lambda-
    // weighted mean: 1% for both.
    let d = contact(&small).friction_dissipation;
    let (m, inertia) = disc_inertia(&small);
    eprintln!(
        "D = {d:.9e} against mu J_n V_T = {:.9e} ({:+.2e}); slowing down {:.1e} of V_T",
        mu * j_n * V_T,
        d / (mu * j_n * V_T) - 1.0,
        (1.0 / m + R_DISC * R_DISC / inertia) * mu * j_n / V_T
    );
    assert!(rel_diff(d, mu * j_n * V_T) < 0.01, "D = {d} against mu J_n V_T");
}

#[test]
fn tresca_bound_gives_a_constant_friction_force() {
    // Tresca's bound S (a traction) on the unit square's base. The block starts compressed
    // between the plane and rollers on its top (u = (0, -e y), the top held at y = 1 - e;
    // nu = 0, so this is a static state: no Poisson stress along x), so every base node stays
    // pressed; gravity along the plane, g sin theta, drives it. Where all nodes slip, the
    // friction force is S L (L = 1) exactly.
    let dir = scratch("friction_tresca");
    let bound = 2.0;
    let text = format!(
        r#"name = "tresca"
[mesh]
geo = "../meshes/square_quad.geo"
params = {{ h = 0.25 }}
[material]
E = 1e4
nu = 0.0
rho = 1.0
[body_force]
acceleration = ["{G}*sin(pi/6)", "0"]
[initial]
displacement = ["0", "-1e-3*y"]
[[dirichlet]]
group = "top"
components = ["y"]
value = ["0", "-1e-3"]
[time]
tau = 1e-2
steps = 100
[mass]
kind = "modified1"
[contact]
boundary = "bottom"
obstacle = {{ type = "plane", point = [0.0, 0.0], normal = [0.0, 1.0] }}
tresca = {bound}
[output]
every = 50
"#
    );
    let scene = scene_text(&dir, "tresca.toml", &text);
    let s = run_scene(1, &scene, &[]);
    let h5 = dir.join("tresca-1.h5");
    let run = reader(&h5);
    let tt = run.series(&layout::contact(layout::CONTACT_TANGENTIAL)).unwrap();
    let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
    let nc = run.series(layout::CONTACT_NODES).unwrap().len();
    // Where a node slips it carries the traction S (against the slip: -x); after the start
    // (the first step sticks: the block's elastic shear takes up gravity's first push) every
    // node slips.
    let mut slipping_steps = 0;
    for (k, st) in state.iter().enumerate().skip(nc) {
        if *st == 2.0 {
            assert!(
                (tt[2 * k] + bound).abs() < 1e-8 * bound,
                "step {}, node {}: {}",
                k / nc,
                k % nc,
                tt[2 * k]
            );
        }
        if k % nc == 0 && state[k..k + nc].iter().all(|&x| x == 2.0) {
            slipping_steps += 1;
        }
        if k / nc >= 10 {
            assert_eq!(*st, 2.0, "step {}, node {} does not slip", k / nc, k % nc);
        }
    }
    let (tau, t) = (1e-2, 1.0);
    let c = contact(&s);
    let f = -c.friction_impulse[0];
    eprintln!("friction impulse {f} (S L T = {}), {slipping_steps} steps in full slip", bound * t);
    // At most S L T; exactly S L tau per step in full slip, less in the steps before.
    assert!(
        f <= bound * t * (1.0 + 1e-9) && f >= bound * tau * slipping_steps as f64 * (1.0 - 1e-9),
        "{f}"
    );
    assert!(slipping_steps >= 95, "{slipping_steps}");
    // Momentum along x: gravity's impulse m g sin theta T less the friction's.
    let p = s.momentum_final[0];
    assert!(
        rel_diff(p, G * THETA.sin() * t - f) < 1e-8,
        "momentum {p} against {}",
        G * THETA.sin() * t - f
    );
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    // The dissipation, from the block's motion rather than the solver's tractions and slips:
    // Tresca's friction is S per unit length against the slip, so sliding the base (length
    // L = 1: the weights D_qq sum to it) costs S L x. A sticking node does not move (the
    // obstacle rests) and a slipping one only slides forward, so the run's D is exactly
    // S sum_q D_qq u_x,q(T), the base nodes' displacement from the field (to the 1e-8 of the
    // tractions above).
    let nodes = run.series(layout::CONTACT_NODES).unwrap();
    let w = run.series(layout::CONTACT_WEIGHTS).unwrap();
    assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12, "the base's length");
    let (u, dim) = last_displacement(&h5);
    let x: f64 = (0..nc).map(|q| w[q] * u[nodes[q] as usize * dim]).sum();
    let d = c.friction_dissipation;
    eprintln!("dissipation {d:.12} against S L x = {:.12}", bound * x);
    assert!(rel_diff(d, bound * x) < 1e-8, "dissipation {d} against S L x = {}", bound * x);
    // And x from kinematics: from the steps in full slip on, the block accelerates at
    // a = g sin theta - S L / m; in the steps before, the friction was between 0 and S L, which
    // adds between 0 and S L tau T / m each to the distance a T^2 / 2. The base moves with
    // the block up to its shear: the shear stress is at most S, the strain S / G_s over the
    // height L, twice that with the start-up's shear oscillation.
    let a = G * THETA.sin() - bound;
    let before = (t / tau).round() - slipping_steps as f64;
    let shear = 2.0 * bound / (1e4 / 2.0);
    let (lo, hi) = (a * t * t / 2.0 - shear, a * t * t / 2.0 + before * bound * tau * t + shear);
    eprintln!("the base slid {x:.6}, kinematics [{lo:.6}, {hi:.6}]");
    assert!(lo <= x && x <= hi, "the base slid {x}, not within [{lo}, {hi}]");
}

#[test]
fn friction_where_it_is_not_built_is_a_one_line_error() {
    let dir = scratch("friction_errors");
    let scene = slope_2d(&dir, "cols", &gravity_2d(None), 5, "friction = 0.3");
    let o = massfree(
        1,
        &[
            "run",
            scene.to_str().unwrap(),
            "--quiet",
            "--overwrite",
            "--",
            "-contact_solver",
            "columns",
        ],
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("-contact_solver columns has no friction"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // Pairs with different laws: one law for all pairs is built.
    let pairs = scene_variant(
        "three_bars.toml",
        &dir,
        &[(
            "{ slave = \"left_contact\", master = \"middle_left\" },",
            "{ slave = \"left_contact\", master = \"middle_left\", friction = 0.4 },",
        )],
    );
    let o =
        massfree(1, &["run", pairs.to_str().unwrap(), "--quiet", "--overwrite", "--steps", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("pairs with different friction"), "{err}");
    assert_eq!(err.trim().lines().filter(|l| l.contains("massfree")).count(), 1, "{err}");
}

/// Per step of a run with friction: the reaction on the obstacle (or master side) `F = sum_q (lambda_q n_q + t_q)`
/// (from the traction on the body), `sum_q |t_q|`, `sum_q lambda_q`, and whether every node in
/// contact slips.
fn friction_history(h5: &Path, dim: usize) -> Vec<([f64; 3], f64, f64, bool)> {
    let run = reader(h5);
    let w = run.series(layout::CONTACT_WEIGHTS).unwrap();
    let nc = w.len();
    let traction = run.series(&layout::contact("traction")).unwrap();
    let tangential = run.series(&layout::contact(layout::CONTACT_TANGENTIAL)).unwrap();
    let lambda = run.series(&layout::contact("force")).unwrap();
    let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
    (0..lambda.len() / nc)
        .map(|n| {
            let mut f = [0.0; 3];
            let (mut t, mut l) = (0.0, 0.0);
            let mut all_slip = false;
            for q in 0..nc {
                let k = n * nc + q;
                let mut tq = 0.0;
                for c in 0..dim {
                    f[c] -= traction[k * dim + c] * w[q];
                    tq += (tangential[k * dim + c] * w[q]).powi(2);
                }
                t += tq.sqrt();
                l += lambda[k];
                if state[k] == 2.0 {
                    all_slip = true;
                }
            }
            let slipping = all_slip && (0..nc).all(|q| state[n * nc + q] != 1.0);
            (f, t, l, slipping)
        })
        .collect()
}

/// Where every node in contact slips, `sum_q |t_q| = mu sum_q lambda_q`, to the solver's
/// tolerance on the run's largest force (the tolerance is relative to the right-hand side,
/// which the inertia terms dominate: the first contact forces of an impact are far below it).
fn assert_slip_at_the_bound(h: &[([f64; 3], f64, f64, bool)], mu: f64) {
    let scale = h.iter().fold(0.0f64, |a, r| a.max(r.2));
    for (n, r) in h.iter().enumerate().filter(|(_, r)| r.3) {
        assert!(
            (r.1 - mu * r.2).abs() <= 1e-8 * mu * scale,
            "step {n}: sum |t| = {} against mu sum lambda = {}",
            r.1,
            mu * r.2
        );
    }
}

#[test]
fn ironing_drags_with_mu_times_the_normal_force_on_any_rank_count() {
    // scenes/ironing.toml: a rigid disc pressed into the block and dragged along its top (a
    // moving obstacle: the stick rows follow its translation). Where every node in contact
    // slips, sum |t_q| = mu sum lambda_q; on 3 ranks cut into slabs along x the contact zone
    // crosses the cuts as it moves, and the histories stay those of 1 rank.
    let dir = scratch("friction_ironing");
    let scene = scene_variant(
        "ironing.toml",
        &dir,
        &[("h = 0.015625", "h = 0.03125"), ("every = 10", "every = 50")],
    );
    let mu = 0.3;
    let mut runs = Vec::new();
    for (ranks, extra) in [(1, &[][..]), (2, &[][..]), (3, &["--partition", "x-slabs"][..])] {
        let s = run_scene(ranks, &scene, extra);
        assert!(s.energy_balance < 1e-8, "{ranks} rank(s): balance {:e}", s.energy_balance);
        let h = friction_history(&dir.join(format!("ironing-{ranks}.h5")), 2);
        let slipping: Vec<_> = h.iter().filter(|r| r.3).collect();
        assert!(slipping.len() > 150, "{} steps in full slip", slipping.len());
        assert_slip_at_the_bound(&h, mu);
        // The drag resists the motion (+x): the obstacle is pushed back and up.
        let last = h.last().unwrap().0;
        assert!(last[0] < 0.0 && last[1] > 0.0, "{last:?}");
        runs.push(h);
    }
    let scale = runs[0].iter().fold(0.0f64, |a, r| a.max(r.0[1].abs()));
    for (k, h) in runs.iter().enumerate().skip(1) {
        for (n, (a, b)) in runs[0].iter().zip(h).enumerate() {
            for c in 0..2 {
                assert!(
                    (a.0[c] - b.0[c]).abs() <= 1e-8 * scale,
                    "run {k}, step {n}: {:?} against {:?}",
                    a.0,
                    b.0
                );
            }
        }
    }
}

#[test]
fn ironing_in_3d_drags_with_mu_times_the_normal_force() {
    // scenes/ironing_3d.toml on a coarser cube: a rigid cylinder along y dragged along x.
    let dir = scratch("friction_ironing_3d");
    let scene = scene_variant(
        "ironing_3d.toml",
        &dir,
        &[("h = 0.0625", "h = 0.125"), ("every = 10", "every = 50")],
    );
    let s = run_scene(2, &scene, &[]);
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    let h = friction_history(&dir.join("ironing_3d-2.h5"), 3);
    let mu = 0.3;
    let slipping = h.iter().filter(|r| r.3).count();
    assert!(slipping > 100, "{slipping} steps in full slip");
    assert_slip_at_the_bound(&h, mu);
    // Nothing pushes along the cylinder's axis.
    for (n, r) in h.iter().enumerate().filter(|(_, r)| r.3) {
        assert!(r.0[1].abs() < 1e-8 * r.0[2].abs(), "step {n}: {:?}", r.0);
    }
    let last = h.last().unwrap().0;
    assert!(last[0] < 0.0 && last[2] > 0.0, "{last:?}");
}

/// Ironing at depth, `scenes/ironing_deep.toml` (h = 1/32): a rigid disc pressed into the
/// neo-Hookean block to 20% of its height and dragged along it with mu = 0.3. Where every node
/// in contact slips, `sum |t_q| = mu sum lambda_q` (the global friction law at finite strain);
/// the block pushes the disc back and up; 1 and 2 ranks give the same reactions. Smooth with
/// `M_H^1`: while the disc is dragged, the normal reaction's step-to-step alternation,
/// `max |F_n - (F_{n-1} + F_{n+1}) / 2|`, is below that of the standard mass `M` (whose
/// contact nodes arrive with their inertia) and below half of one contact node's share of the
/// force (node passage alone changes the force by about one share per passed node, over
/// several steps).
#[test]
fn ironing_at_depth_drags_with_mu_times_the_normal_force_and_smooth_reactions() {
    let mu = 0.3;
    let mut alternation = Vec::new();
    let mut reactions = Vec::new();
    for (mass, ranks) in [("modified1", 2), ("consistent", 2), ("modified1", 1)] {
        let dir = scratch(&format!("friction_ironing_deep_{mass}"));
        let scene = scene_variant(
            "ironing_deep.toml",
            &dir,
            &[("h = 0.0625", "h = 0.03125"), ("every = 10", "every = 100")],
        );
        let s = run_scene(ranks, &scene, &["--mass", mass]);
        assert!(s.energy_balance < 1e-8, "{mass}: balance {:e}", s.energy_balance);
        let h = friction_history(&dir.join(format!("ironing_deep-{ranks}.h5")), 2);
        let slipping = h.iter().filter(|r| r.3).count();
        assert!(slipping > 150, "{mass}: {slipping} steps in full slip");
        assert_slip_at_the_bound(&h, mu);
        let last = h.last().unwrap().0;
        assert!(last[0] < 0.0 && last[1] > 0.0, "{mass}: {last:?}");
        // The drag from t = 1.4 (after the start's transient) to the end, tau = 0.01.
        let fy: Vec<f64> = h.iter().map(|r| r.0[1]).collect();
        let drag = 140..fy.len() - 1;
        let alt = drag.clone().map(|n| (fy[n] - 0.5 * (fy[n - 1] + fy[n + 1])).abs());
        let alt = alt.fold(0.0f64, f64::max);
        let contact = s.contact.as_ref().expect("contact");
        let share =
            fy[drag].iter().fold(0.0f64, |a, &b| a.max(b)) / contact.max_active_nodes as f64;
        eprintln!("{mass}, {ranks} rank(s): alternation {alt:.3e}, one node's share {share:.3e}");
        if mass == "modified1" {
            assert!(alt < 0.5 * share, "{mass}: alternation {alt:e} against a share {share:e}");
        }
        alternation.push(alt);
        reactions.push(h);
    }
    assert!(alternation[0] < alternation[1], "M_H {:e}, M {:e}", alternation[0], alternation[1]);
    let scale = reactions[0].iter().fold(0.0f64, |a, r| a.max(r.0[1].abs()));
    for (n, (a, b)) in reactions[0].iter().zip(&reactions[2]).enumerate() {
        for c in 0..2 {
            assert!(
                (a.0[c] - b.0[c]).abs() <= 1e-8 * scale,
                "step {n}: {:?} against {:?}",
                a.0,
                b.0
            );
        }
    }
}

#[test]
fn a_block_sliding_on_another_feels_mu_times_the_normal_force_and_the_other_the_opposite() {
    // scenes/slide_off.toml (the upper block lands on the long lower one and slides at 1)
    // with mu = 0.2, before it reaches the edge: dual mortar multipliers carry the friction,
    // the slip weighted by the same basis (the interface follows the bodies).
    let dir = scratch("friction_pair");
    let scene = scene_variant(
        "slide_off.toml",
        &dir,
        &[("steps = 500", "steps = 250"), ("[output]", "friction = 0.2\n[output]")],
    );
    let mu = 0.2;
    let mut impulses = Vec::new();
    // 3 ranks in slabs along x: the cuts cross the contact zone.
    for (ranks, extra) in [(1, &[][..]), (2, &[][..]), (3, &["--partition", "x-slabs"][..])] {
        // The node law holds to the solver's tolerance, relative to the right-hand side, which
        // the inertia terms dominate: the landing's first contact forces are small against it.
        let mut args = extra.to_vec();
        args.extend(["--", "-ksp_rtol", "1e-12"]);
        let s = run_scene(ranks, &scene, &args);
        assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
        let h = friction_history(&dir.join(format!("slide_off-{ranks}.h5")), 2);
        let slipping = h.iter().filter(|r| r.3).count();
        assert_slip_at_the_bound(&h, mu);
        assert!(slipping > 200, "{slipping} steps in full slip");
        // Action = reaction: the two bodies' contact impulses cancel, friction's included.
        let body =
            |g: &str| s.bodies.iter().find(|b| b.group == g).unwrap().contact_impulse.clone();
        let (up, low) = (body("upper"), body("lower"));
        let scale = up[1].abs();
        for c in 0..2 {
            assert!((up[c] + low[c]).abs() <= 1e-8 * scale, "impulses {up:?} and {low:?}");
        }
        // The friction slows the upper block: its x impulse is friction's, about mu times its
        // normal impulse (the mortar normals are nearly vertical).
        let friction = &s.bodies.iter().find(|b| b.group == "upper").unwrap().friction_impulse;
        // Friction's parts cancel as well (the master's through -M^T t).
        let lower = &s.bodies.iter().find(|b| b.group == "lower").unwrap().friction_impulse;
        for c in 0..2 {
            assert!((friction[c] + lower[c]).abs() <= 1e-8 * scale, "{friction:?} and {lower:?}");
        }
        assert!(rel_diff(friction[0], up[0]) < 1e-3, "{friction:?} against {up:?}");
        assert!(
            rel_diff(-up[0], mu * up[1]) < 1e-2,
            "x impulse {} against mu y impulse {}",
            -up[0],
            mu * up[1]
        );
        impulses.push(up);
    }
    for imp in &impulses[1..] {
        assert!(rel_diff(impulses[0][0], imp[0]) < 1e-8 && rel_diff(impulses[0][1], imp[1]) < 1e-8);
    }
}

#[test]
fn a_block_pushed_along_another_sticks_until_the_push_reaches_mu_times_its_weight() {
    // The upper block of slide_off.toml at rest, pressed down by gravity (ramped up to 1 over
    // 0.5, so that it settles without rocking) and from t = 1 pushed along x by an
    // acceleration rising as 0.2 (t - 1): with mu = 0.2 the push reaches mu m g at t = 2.
    // Quasi-statically, gross slip (every node in contact slipping) cannot come before: the
    // friction would then be mu N, more than the push (5% margin for what is left of the
    // normal force's oscillation); well after it every node slips.
    let dir = scratch("friction_pair_stick");
    let scene = scene_variant(
        "slide_off.toml",
        &dir,
        &[
            ("velocity = [\"max(0, min(1, 1e6 * y))\", \"0\"]", "velocity = [\"0\", \"0\"]"),
            (
                "acceleration = [\"0\", \"-1\"]",
                "acceleration = [\"0.2*max(0, t - 1)*max(0, min(1, 1e6 * y))\", \"-min(t/0.5, 1)\"]",
            ),
            ("steps = 500", "steps = 260"),
            ("[output]", "friction = 0.2\n[output]"),
        ],
    );
    let s = run_scene(2, &scene, &[]);
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    let h5 = dir.join("slide_off-2.h5");
    let run = reader(&h5);
    let nc = run.series(layout::CONTACT_NODES).unwrap().len();
    let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
    let tau = 0.01;
    let gross = |n: usize| {
        let row = &state[n * nc..(n + 1) * nc];
        row.iter().any(|&x| x != 0.0) && row.iter().all(|&x| x != 1.0)
    };
    let first = (1..state.len() / nc).find(|&n| gross(n)).expect("the block slips in the end");
    eprintln!("gross slip from step {first} (t = {})", first as f64 * tau);
    assert!(first as f64 * tau >= 0.95 * 2.0, "gross slip at t = {}", first as f64 * tau);
    // From t = 2.3 on the block slides: nearly every node slips (an edge node may stick for a
    // step as the block vibrates).
    let late: Vec<f64> = state[230 * nc..].to_vec();
    let slip = late.iter().filter(|&&x| x == 2.0).count() as f64;
    let touching = late.iter().filter(|&&x| x != 0.0).count() as f64;
    assert!(slip >= 0.9 * touching, "{slip} of {touching} node-steps slip after t = 2.3");
    let upper = s.bodies.iter().find(|b| b.group == "upper").unwrap();
    assert!(upper.momentum_final[0] > 0.0, "the block moves along the push");
    assert!(contact(&s).stick_node_steps > 0);
}

#[test]
fn cattaneo_mindlin_partial_slip_shrinks_the_stick_zone_as_theory_says() {
    // scenes/cattaneo.toml at tau = 0.02: a half-cylinder (R = 4) pressed on a block of the
    // same material (no normal-tangential coupling), then moved sideways. Cattaneo and
    // Mindlin (2D): the contact half-width is Hertz's, a = sqrt(4 P R / (pi E*)) with
    // 1/E* = 2 (1 - nu^2) / E; under a growing tangential force Q < mu P the middle sticks
    // over |x| < c = a sqrt(1 - Q / (mu P)) and the edges slip, with the traction
    // q = mu p0 (sqrt(1 - x^2/a^2) - (c/a) sqrt(1 - x^2/c^2)) in the stick zone and mu p in the
    // slip zones (p0 = 2 P / (pi a)). The zone edges are measured halfway between the last
    // node inside and the first outside, and must lie within one contact cell of theory.
    //
    // The traction profile: the theory's is even in x. The bodies here are no half-planes:
    // "same material, no coupling" holds for two half-planes only, and pressing the
    // half-cylinder on the block already leaves an odd tangential traction (the two surfaces
    // would slide apart differently; the stick zone holds them), before any tangential load.
    // The mesh is mirror-symmetric about x = 0 (asserted), so the traction splits into its
    // even part, which the theory predicts, and its odd part, outside the theory (printed).
    // The even part's error comes from the discretization: at the four zone edges (+-a, +-c)
    // both terms of the profile are square roots, at most mu p0 sqrt(2 d / a) at a distance d
    // from their edge (c <= a), so an edge within one cell h of theory (asserted) changes the
    // traction at the node beside it by up to mu p0 sqrt(2 h / a), and by less further in.
    // Four such nodes among the 2 a / h contact nodes make an RMS error of
    // sqrt(4 (2 h / a) h / (2 a)) = 2 h / a, in units of mu p0.
    let dir = scratch("friction_cattaneo");
    let scene = scene_variant(
        "cattaneo.toml",
        &dir,
        &[
            ("tau = 0.01", "tau = 0.02"),
            ("steps = 200", "steps = 100"),
            ("every = 10", "every = 100"),
        ],
    );
    let s = run_scene(2, &scene, &[]);
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    let run = reader(&dir.join("cattaneo-2.h5"));
    let (mu, e, nu, radius) = (0.3, 100.0, 0.3, 4.0);
    let e_star = e / (2.0 * (1.0 - nu * nu));
    let coords = run.coordinates().unwrap();
    let nodes = run.series(layout::CONTACT_NODES).unwrap();
    let w = run.series(layout::CONTACT_WEIGHTS).unwrap();
    let nc = w.len();
    let x: Vec<f64> = nodes.iter().map(|&v| coords[v as usize][0]).collect();
    let mut order: Vec<usize> = (0..nc).collect();
    order.sort_by(|&i, &j| x[i].total_cmp(&x[j]));
    // Each contact node's mirror image about x = 0 is a contact node (to gmsh's placement of
    // the nodes, some 1e-9: far below a cell).
    let mirror: Vec<usize> = (0..nc)
        .map(|i| {
            let j = (0..nc).min_by(|&j, &k| (x[j] + x[i]).abs().total_cmp(&(x[k] + x[i]).abs()));
            let j = j.unwrap();
            assert!((x[j] + x[i]).abs() < 1e-6, "no contact node at -{}", x[i]);
            j
        })
        .collect();
    let lambda = run.series(&layout::contact("force")).unwrap();
    let tt = run.series(&layout::contact(layout::CONTACT_TANGENTIAL)).unwrap();
    let state = run.series(&layout::contact(layout::CONTACT_STATE)).unwrap();
    // The edges of the nodes (in x order) in a set: halfway to the neighbours outside.
    let half_width = |n: usize, inside: &dyn Fn(f64) -> bool| -> (f64, f64) {
        let k: Vec<usize> = (0..nc).filter(|&i| inside(state[n * nc + order[i]])).collect();
        let (lo, hi) = (k[0], *k.last().unwrap());
        assert!(k.len() == hi - lo + 1, "step {n}: the set is not one interval");
        let left = 0.5 * (x[order[lo]] + x[order[lo - 1]]);
        let right = 0.5 * (x[order[hi]] + x[order[hi + 1]]);
        (0.5 * (right - left), x[order[hi + 1]] - x[order[hi]])
    };
    let mut p_start = 0.0;
    let mut checked = 0;
    for n in 51..=96 {
        let p: f64 = lambda[n * nc..(n + 1) * nc].iter().sum();
        let q: f64 = (0..nc).map(|k| -tt[2 * (n * nc + k)] * w[k]).sum();
        if n == 51 {
            p_start = p;
        }
        // The normal force does not feel the tangential one.
        assert!(rel_diff(p, p_start) < 1e-2, "step {n}: P = {p} against {p_start}");
        let a = (4.0 * p * radius / (std::f64::consts::PI * e_star)).sqrt();
        let (a_m, h) = half_width(n, &|s| s != 0.0);
        assert!((a_m - a).abs() <= h, "step {n}: contact half-width {a_m} against Hertz's {a}");
        if n == 51 {
            // Before the tangential load: the odd traction the pressing left.
            let p0 = 2.0 * p / (std::f64::consts::PI * a);
            let odd: Vec<f64> = (0..nc)
                .filter(|&k| state[n * nc + k] != 0.0)
                .map(|k| 0.5 * (tt[2 * (n * nc + mirror[k])] - tt[2 * (n * nc + k)]))
                .collect();
            let rms = (odd.iter().map(|e| e * e).sum::<f64>() / odd.len() as f64).sqrt();
            eprintln!(
                "step 51: Q/(mu P) = {:.4}, the traction's odd part {:.4} mu p0 (RMS)",
                q / (mu * p),
                rms / (mu * p0)
            );
        }
        if q / (mu * p) < 0.1 {
            continue;
        }
        let c = a * (1.0 - q / (mu * p)).sqrt();
        let (c_m, cell) = half_width(n, &|s| s == 1.0);
        assert!(
            (c_m - c).abs() <= cell,
            "step {n}: Q/(mu P) = {:.3}, stick half-width {c_m} against {c}",
            q / (mu * p)
        );
        // The traction profile's even part, RMS over the contact nodes, within 2 h / a of
        // mu p0 (the header); the odd part printed.
        let p0 = 2.0 * p / (std::f64::consts::PI * a);
        let theory = |xx: f64| {
            let outer = (1.0 - xx * xx / (a * a)).max(0.0).sqrt();
            let inner = if xx.abs() < c { (c / a) * (1.0 - xx * xx / (c * c)).sqrt() } else { 0.0 };
            mu * p0 * (outer - inner)
        };
        let q_at = |k: usize| -tt[2 * (n * nc + k)];
        let touching = |k: usize| state[n * nc + k] != 0.0 || state[n * nc + mirror[k]] != 0.0;
        let rms = |f: &dyn Fn(usize) -> f64| {
            let v: Vec<f64> = (0..nc).filter(|&k| touching(k)).map(f).collect();
            (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt() / (mu * p0)
        };
        let even = rms(&|k| 0.5 * (q_at(k) + q_at(mirror[k])) - theory(x[k]));
        let odd = rms(&|k| 0.5 * (q_at(k) - q_at(mirror[k])));
        let whole = rms(&|k| q_at(k) - theory(x[k]));
        let bound = 2.0 * h / a;
        if n % 5 == 1 {
            eprintln!(
                "step {n}: Q/(mu P) = {:.3}, traction RMS errors / (mu p0): even {even:.4} \
                 (bound 2 h / a = {bound:.4}), odd {odd:.4}, together {whole:.4}",
                q / (mu * p)
            );
        }
        assert!(
            even < bound,
            "step {n}: the traction's even part off by {even} (RMS, / mu p0), beyond 2 h / a = {bound}"
        );
        checked += 1;
    }
    assert!(checked > 30, "{checked} steps of partial slip checked");
}

#[test]
fn an_oblique_ball_with_little_friction_slips_within_the_cone_in_3d() {
    // scenes/sphere_oblique.toml with mu = 0.05: the friction impulse mu J_n (J_n about
    // 2 m v_n for the elastic bounce) is below the (2/7) m v_t a solid ball needs to roll, so
    // the ball slides through the whole impact. Every node stays in the cone, and while every
    // node in contact slips, sum |t_q| = mu sum lambda_q; the energy lost is the dissipation.
    let dir = scratch("friction_ball");
    let scene = scene_variant("sphere_oblique.toml", &dir, &[("every = 10", "every = 110")]);
    let mu = 0.05;
    let s = run_scene(2, &scene, &["--friction", "0.05"]);
    assert!(s.energy_balance < 1e-8, "balance {:e}", s.energy_balance);
    let h5 = dir.join("sphere_oblique-2.h5");
    let h = friction_history(&h5, 3);
    assert_slip_at_the_bound(&h, mu);
    let slipping = h.iter().filter(|r| r.3).count();
    let touching = h.iter().filter(|r| r.2 > 0.0).count();
    assert!(
        slipping as f64 >= 0.9 * touching as f64,
        "{slipping} of {touching} contact steps in full slip"
    );
    let run = reader(&h5);
    let w = run.series(layout::CONTACT_WEIGHTS).unwrap();
    let nc = w.len();
    let lambda = run.series(&layout::contact("force")).unwrap();
    let tt = run.series(&layout::contact(layout::CONTACT_TANGENTIAL)).unwrap();
    let scale = lambda.iter().fold(0.0f64, |a, &x| a.max(x));
    for k in 0..lambda.len() {
        let t = (0..3).map(|c| (tt[3 * k + c] * w[k % nc]).powi(2)).sum::<f64>().sqrt();
        assert!(
            t <= mu * lambda[k] + 1e-7 * mu * scale,
            "step {}, node {}: |t| = {t:e} > mu lambda",
            k / nc,
            k % nc
        );
    }
    let c = contact(&s);
    let lost = s.energy_initial - s.energy_final;
    assert!(c.friction_dissipation > 0.0);
    assert!(
        rel_diff(lost, c.friction_dissipation) < 1e-6,
        "lost {lost} against D = {}",
        c.friction_dissipation
    );
}
