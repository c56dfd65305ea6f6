//! Dynamic elasticity end to end (issue: backbone): the beam of paper section 7.1 converges at
//! the rates of the theory, energy is conserved by the midpoint rule, and results do not
//! depend on the number of ranks.

mod common;
use common::*;

/// Observed rates log2(e_h / e_{h/2}) of consecutive refinements.
fn rates(e: &[f64]) -> Vec<f64> {
    e.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// Errors at t_30 for the given scene on meshes h = 1/4, 1/8, ... (two ranks): displacement
/// in L2 and H1, and the velocity's L2 error (`exact.velocity`), whose rate is checked here.
fn convergence(scene: &str, hs: &[&str], name: &str) -> (Vec<f64>, Vec<f64>) {
    let dir = scratch(name);
    let (mut l2, mut h1, mut v2) = (vec![], vec![], vec![]);
    for h in hs {
        let path = scene_variant(
            scene,
            &dir,
            &[("steps = 250", "steps = 30"), ("error_steps = [30, 250]", "error_steps = [30]")],
        );
        let s =
            run_scene(2, &path, &["--param", &format!("h={h}"), "--", "-step_ksp_rtol", "1e-13"]);
        let e = &s.errors;
        assert_eq!(e.len(), 1);
        assert_eq!(e[0].step, 30);
        l2.push(e[0].l2);
        h1.push(e[0].h1_semi);
        v2.push(e[0].velocity_l2.expect("the scene gives exact.velocity"));
    }
    // The exact velocity u_t solves the same problem with the data differentiated in time
    // (smooth here), so the L2 estimate O(h^2) holds for it as for u; tau = 1e-5 leaves the
    // midpoint rule's O(tau^2) far below.
    let rv = rates(&v2);
    eprintln!("{name}: velocity L2 {v2:?} rates {rv:?}");
    for r in &rv {
        assert!((r - 2.0).abs() < 0.15, "{name}: velocity L2 rate {r} is not 2 (rates {rv:?})");
    }
    (l2, h1)
}

fn assert_rates(l2: &[f64], h1: &[f64], what: &str) {
    let (rl, rh) = (rates(l2), rates(h1));
    eprintln!("{what}: L2 {l2:?} rates {rl:?}; H1 {h1:?} rates {rh:?}");
    // Theory (paper Theorems 6.1/6.2): O(h^2) in L2, O(h) in H1 for P1/Q1 elements.
    for r in &rl {
        assert!((r - 2.0).abs() < 0.15, "{what}: L2 rate {r} is not 2 (rates {rl:?})");
    }
    for r in &rh {
        assert!((r - 1.0).abs() < 0.15, "{what}: H1 rate {r} is not 1 (rates {rh:?})");
    }
}

#[test]
fn beam_quads_converge_at_theoretical_rates() {
    let (l2, h1) = convergence("beam.toml", &["0.25", "0.125", "0.0625", "0.03125"], "beam-quad");
    assert_rates(&l2, &h1, "beam Q1");
}

#[test]
fn beam_triangles_converge_at_theoretical_rates() {
    let (l2, h1) = convergence("beam_tri.toml", &["0.25", "0.125", "0.0625"], "beam-tri");
    assert_rates(&l2, &h1, "beam P1");
}

#[test]
fn block_hexahedra_converge_at_theoretical_rates() {
    let (l2, h1) = convergence("block_hex.toml", &["0.5", "0.25", "0.125"], "block-hex");
    assert_rates(&l2, &h1, "block Q1");
}

#[test]
fn block_tetrahedra_converge_at_theoretical_rates() {
    let (l2, h1) = convergence("block_tet.toml", &["0.5", "0.25", "0.125"], "block-tet");
    assert_rates(&l2, &h1, "block P1");
}

const FREE_BODY_3D: &str = r#"
name = "free_body"
[mesh]
geo = "../meshes/block_hex.geo"
params = { h = 0.5 }
[material]
E = 200.0
nu = 0.3
rho = 1.0
[initial]
velocity = ["1 + 0.2*z", "0.5*x*z", "-0.3 + 0.1*x*y"]
[time]
tau = 2e-3
steps = 1000
[mass]
kind = "consistent"
[output]
every = 250
"#;

const DIRECT: [&str; 7] = [
    "--",
    "-step_ksp_type",
    "preonly",
    "-step_pc_type",
    "cholesky",
    "-step_pc_factor_mat_solver_type",
    "mumps",
];

#[test]
fn midpoint_rule_conserves_energy_clamped_2d() {
    let dir = scratch("energy-2d");
    let scene = scene_text(&dir, "free_vibration.toml", FREE_VIBRATION);
    for ranks in [1, 2] {
        let s = run_scene(ranks, &scene, &DIRECT);
        let drift = s.energy_drift;
        assert!(s.energy_initial > 0.0);
        assert_eq!(s.external_work, 0.0);
        assert!(drift < 1e-9, "{ranks} rank(s): |E^n - E^0|/E^0 = {drift} over 1000 steps");
    }
}

#[test]
fn midpoint_rule_conserves_energy_free_body_3d() {
    let dir = scratch("energy-3d");
    let scene = scene_text(&dir, "free_body.toml", FREE_BODY_3D);
    let s = run_scene(2, &scene, &DIRECT);
    let drift = s.energy_drift;
    assert!(drift < 1e-9, "|E^n - E^0|/E^0 = {drift} over 1000 steps");
}

#[test]
fn forced_run_closes_the_energy_balance() {
    // With loads, E^{n+1} - E^n = f^{n+1/2} . du exactly: the balance is solver tolerance.
    let dir = scratch("balance");
    let scene = scene_variant("beam.toml", &dir, &[]);
    let s = run_scene(2, &scene, &["--param", "h=0.25", "--", "-step_ksp_rtol", "1e-14"]);
    assert!(s.external_work.abs() > 0.0);
    let b = s.energy_balance;
    assert!(b < 1e-8, "energy balance residual {b}");
}

fn final_displacement(h5: &std::path::Path) -> Vec<f64> {
    let run = reader(h5);
    let name = layout::field("displacement");
    let per_step = run.file.dataset(&name).unwrap().shape()[1..].iter().product::<usize>();
    let all = run.series(&name).unwrap();
    all[all.len() - per_step..].to_vec()
}

#[test]
fn results_do_not_depend_on_the_number_of_ranks() {
    let dir = scratch("ranks");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[("steps = 250", "steps = 100"), ("error_steps = [30, 250]", "error_steps = [30, 100]")],
    );
    let mut runs = vec![];
    for ranks in [1, 2, 3] {
        let s = run_scene(ranks, &scene, &["--", "-step_ksp_rtol", "1e-13"]);
        let u = final_displacement(&dir.join(format!("beam-{ranks}.h5")));
        runs.push((ranks, s, u));
    }
    let (_, s1, u1) = &runs[0];
    let norm = u1.iter().map(|x| x * x).sum::<f64>().sqrt();
    assert!(norm > 0.0);
    for (ranks, s, u) in &runs[1..] {
        for (key, a, b) in [
            ("energy_final", s1.energy_final, s.energy_final),
            ("external_work", s1.external_work, s.external_work),
        ] {
            let d = rel_diff(a, b);
            assert!(d < 1e-8, "{key}: 1 vs {ranks} ranks differ by {d}");
        }
        let diff = u1.iter().zip(u).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt() / norm;
        assert!(diff < 1e-8, "final displacement: 1 vs {ranks} ranks differ by {diff}");
        assert_eq!(s1.errors.len(), s.errors.len());
        for (a, b) in s1.errors.iter().zip(&s.errors) {
            assert!(
                rel_diff(a.l2, b.l2) < 1e-6 && rel_diff(a.h1_semi, b.h1_semi) < 1e-6,
                "errors {a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn extruded_hex_block_reproduces_the_plane_strain_beam() {
    // The block's exact solution does not depend on y and its tractions on y = 0, 1 are the
    // plane-strain stresses: the discrete 3D Q1 solution on the extruded mesh is the 2D
    // plane-strain Q1 solution, so the two codes' errors must agree (an independent check of
    // the 3D kernels, loads and assembly against the 2D ones).
    let dir = scratch("extruded");
    let fix = [("steps = 250", "steps = 30"), ("error_steps = [30, 250]", "error_steps = [30]")];
    let beam = scene_variant("beam.toml", &dir, &fix);
    let block = scene_variant("block_hex.toml", &dir, &fix);
    let rtol = ["--param", "h=0.25", "--", "-step_ksp_rtol", "1e-13"];
    let e2 = run_scene(2, &beam, &rtol).errors[0];
    let e3 = run_scene(2, &block, &rtol).errors[0];
    assert!(rel_diff(e2.l2, e3.l2) < 1e-6, "L2: 2D {} vs 3D {}", e2.l2, e3.l2);
    assert!(rel_diff(e2.h1_semi, e3.h1_semi) < 1e-6, "H1: 2D {} vs 3D {}", e2.h1_semi, e3.h1_semi);
}
