//! The step solver's settings: built-in defaults, then the scene's [solver] keys and options,
//! then the command line, each overriding the one before; plain -ksp_* options and the
//! step_ prefix both reach the step solver.

mod common;
use common::*;

fn solver_of(s: &RunSummary) -> (String, String) {
    (s.ksp_type.clone(), s.pc_type.clone())
}

#[test]
fn defaults_scene_and_command_line_in_order() {
    let dir = scratch("solver-options");
    let plain = scene_variant(
        "beam.toml",
        &dir,
        &[("steps = 250", "steps = 2"), ("error_steps = [30, 250]", "error_steps = [2]")],
    );
    let s = run_scene(1, &plain, &["--param", "h=0.5"]);
    assert_eq!(solver_of(&s), ("cg".into(), "jacobi".into()));

    let keyed = scene_text(
        &dir,
        "keyed.toml",
        &std::fs::read_to_string(&plain).unwrap().replace(
            "[output]",
            "[solver]\nksp_type = \"minres\"\noptions = \"-pc_type bjacobi -step_ksp_norm_type preconditioned\"\n\n[output]",
        ),
    );
    let s = run_scene(1, &keyed, &["--param", "h=0.5"]);
    assert_eq!(solver_of(&s), ("minres".into(), "bjacobi".into()));
    // The command line wins over the scene, the step_ prefix over plain options.
    let s = run_scene(
        1,
        &keyed,
        &[
            "--param",
            "h=0.5",
            "--",
            "-pc_type",
            "none",
            "-ksp_type",
            "gmres",
            "-step_ksp_type",
            "bcgs",
        ],
    );
    assert_eq!(solver_of(&s), ("bcgs".into(), "none".into()));
}

/// CFL number `c_p tau / h_min` of [`a_factorization_chosen_by_run_length_gives_cgs_results`]:
/// above the 3.1 where CG + Jacobi's `5 + 13 CFL` products a step (`time::choice`) cost more
/// than a factorization's solve (45), below the multigrid regime (10).
const STIFF_CFL: f64 = 8.0;

/// A long stiff run without contact: the choice by run length factors `K` (MUMPS Cholesky),
/// and its energies must be CG's to the solver's tolerance. The clamped beam in free
/// vibration (`FREE_VIBRATION`: E = 200, nu = 0.3, rho = 1, squares h = 0.25, 410 DOFs) at
/// CFL 8, 1000 steps, on 2 ranks: once with the chosen solver, once forced to CG + Jacobi
/// with rtol 1e-12.
///
/// The tolerance, from the rtol. The midpoint rule maps a difference of the state
/// (u, v) isometrically in the norm `|(u, v)|^2 = u.Au + v.Mv = 2 E` (it keeps the energy of
/// the linear, unloaded difference exactly), and a solve's error `e` in the increment is the
/// state difference `(e, 2 e / tau)`, of norm `|e|_K` (`K = 4/tau^2 M + A`). So after n steps
/// the runs differ by at most `D_n = sum_k |e_k|_K` in that norm, and the kinetic and the
/// potential energy by at most `D_n sqrt(2 E)`. Each increment has `|du|_K^2 = |v^n +
/// v^{n+1}|_M^2 + |du|_A^2 <= 16 E`. CG stops at `r.D^{-1}r <= rtol^2 x.Kx` (D = diag K),
/// and `|e|_K^2 = r.K^{-1}r <= r.D^{-1}r / lambda_min(D^{-1}K)`; with Q1 squares
/// `lambda_min(D^{-1}K) >= 1/4 / (1 + 1.5 CFL^2)`: the consistent mass is at least a quarter
/// of its diagonal (the element's `diag^{-1} M` has eigenvalues 1/4 to 9/4), and a diagonal
/// entry of A is at most `6 c_p^2 / h^2` times M's (per element `(lambda + 3 mu)/3` over
/// `rho h^2/9`). Cholesky's error is round-off, `kappa(K) eps` (backward stable, to first
/// order) with `kappa(K) <= 36 (1 + 24 CFL^2)`: M's eigenvalues lie between 1/4 of its smallest
/// diagonal entry and 9/4 of its largest (4 times the smallest: an inner node's 4 elements
/// against a corner's 1), and `lambda_max(M^{-1}A)` is at most the Q1 element's, `24 * 2
/// (lambda + mu) / (rho h^2)` (the Laplacian's `24/h^2`; the elastic energy density at most
/// `2 (lambda + mu) |grad u|^2` in 2D). Hence, with `E` the largest energy,
/// `|dE| <= 4 sqrt(2) n (rtol sqrt(4 (1 + 1.5 CFL^2)) + kappa eps) E`.
#[test]
fn a_factorization_chosen_by_run_length_gives_cgs_results() {
    let dir = scratch("solver-choice");
    let (h, steps, rtol) = (0.25, 1000usize, 1e-12);
    // c_p = sqrt((lambda + 2 mu) / rho) = sqrt(E (1 - nu) / (rho (1 + nu) (1 - 2 nu))).
    let c_p = (200.0f64 * 0.7 / (1.3 * 0.4)).sqrt();
    let tau = STIFF_CFL * h / c_p;
    let text = FREE_VIBRATION
        .replace("tau = 1e-3", &format!("tau = {tau:e}"))
        .replace("steps = 1000", &format!("steps = {steps}"));
    assert!(text.contains(&format!("tau = {tau:e}")) && text.contains("params = { h = 0.25 }"));
    let chosen = run_scene(2, &scene_text(&dir, "chosen.toml", &text), &[]);
    let forced = run_scene(
        2,
        &scene_text(&dir, "forced.toml", &text),
        &["--", "-step_ksp_type", "cg", "-step_pc_type", "jacobi", "-step_ksp_rtol", "1e-12"],
    );
    assert!((chosen.cfl - STIFF_CFL).abs() < 1e-9 * STIFF_CFL, "CFL {}", chosen.cfl);
    // A factorization of 410 DOFs costs about 1e-3 s (`time::choice`'s model) and saves
    // 109 - 45 products with K a step: chosen unless a product took below 2e-8 s.
    assert_eq!(solver_of(&chosen), ("preonly".into(), "cholesky".into()), "the choice");
    assert_eq!(solver_of(&forced), ("cg".into(), "jacobi".into()));
    let energy =
        |name: &str, run: &str| values(&dir.join(format!("{run}-2.h5")), &layout::energy(name));
    let e_max = energy("total", "chosen")
        .iter()
        .chain(&energy("total", "forced"))
        .fold(0.0f64, |m, &e| m.max(e));
    let cg_error = rtol * (4.0 * (1.0 + 1.5 * STIFF_CFL * STIFF_CFL)).sqrt();
    let kappa = 36.0 * (1.0 + 24.0 * STIFF_CFL * STIFF_CFL);
    let per_step = cg_error + kappa * f64::EPSILON;
    let mut report = Vec::new();
    for name in ["kinetic", "potential", "total"] {
        let (a, b) = (energy(name, "chosen"), energy(name, "forced"));
        assert_eq!((a.len(), b.len()), (steps + 1, steps + 1), "{name}: every step");
        let (mut worst, mut at) = (0.0f64, 0);
        for n in 0..=steps {
            let d = (a[n] - b[n]).abs();
            let bound = 4.0 * 2f64.sqrt() * n as f64 * per_step * e_max;
            assert!(
                d <= bound,
                "{name} energy at step {n}: Cholesky {:.12e}, CG {:.12e}: differ by {d:e} > {bound:e}",
                a[n],
                b[n]
            );
            if d / e_max > worst {
                (worst, at) = (d / e_max, n);
            }
        }
        report.push(format!("{name}: {worst:.2e} of E at step {at}"));
    }
    eprintln!(
        "Cholesky against CG (rtol {rtol:e}, {} iterations a step): {}; bound at step {steps}: {:.2e} of E",
        forced.ksp_iterations as f64 / steps as f64,
        report.join(", "),
        4.0 * 2f64.sqrt() * steps as f64 * per_step
    );
}
