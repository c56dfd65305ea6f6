//! The step's own CG keeps its products (issue 27, `time::cg`): `A u` and `M v` are updated
//! from `K du` and `M du` instead of recomputed, and every `-step_reuse_refresh` steps computed
//! afresh, where the run compares them. Over 10^4 steps of the beam (loads, clamped ends) the
//! kept products equal the recomputed ones to round-off, and the run equals the one that
//! recomputes every step (PETSc's KSP) to solver tolerance, on 1 and 2 ranks.

mod common;
use common::*;

const STEPS: usize = 10_000;
const REFRESH: usize = 16;

fn beam(ranks: usize, extra: &[&str]) -> massfree::report::RunSummary {
    let dir = scratch("step-reuse");
    let path = scene_variant(
        "beam.toml",
        &dir,
        &[
            ("steps = 250", &format!("steps = {STEPS}")),
            ("error_steps = [30, 250]", "error_steps = [250, 10000]"),
        ],
    );
    let mut args = vec!["--param", "h=0.0625", "--"];
    args.extend_from_slice(extra);
    run_scene(ranks, &path, &args)
}

#[test]
fn kept_products_equal_recomputed_ones_over_ten_thousand_steps() {
    let refresh = REFRESH.to_string();
    let kept = beam(2, &["-step_reuse_refresh", &refresh]);
    let r = kept.step_reuse;
    assert_eq!(r.steps, STEPS, "every step solved by the step's own CG");
    assert_eq!(r.refreshes, STEPS / REFRESH, "a refresh every {REFRESH} steps");
    // Round-off: each step's update rounds a few times at the unit round-off eps; between two
    // refreshes at most REFRESH steps of it add up, with a factor 64 for the rounding of the
    // products themselves (rows of up to 18 terms) and the extrapolated guess (its products
    // summed twice).
    let bound = REFRESH as f64 * 64.0 * f64::EPSILON;
    eprintln!("kept products: {r:?} (round-off bound {bound:e})");
    assert!(r.drift_mv < bound, "M v drifted by {:e} of its largest entry", r.drift_mv);
    assert!(r.drift_au < bound, "A u drifted by {:e} of the right-hand side", r.drift_au);
    // The energies: each update rounds `A u` by at most gamma_m ((|K| + 4/tau^2 |M|) |du|)
    // (m = 18 terms a row, gamma_m = m u, u = eps/2), about 2 gamma_m 4/tau^2 M |du| (K is
    // its mass term here: CFL 0.003), so the potential energy u^T A u / 2 by at most
    // gamma_m 4/tau^2 |u|^T M |du| = gamma_m 4/tau |u|^T M |v_mid|
    // <= gamma_m 4/tau ||u||_M ||v||_M (the state has one sign, the shape x (10 - x) y^2)
    // <= 4 gamma_m E / (omega_min tau), as ||u||_M <= sqrt(2 E_pot) / omega_min and
    // ||v||_M = sqrt(2 E_kin); the kinetic energy by 2 gamma_m E a step, 10^-5 of that. Over
    // REFRESH steps, plus the recomputed products' own rounding (below one update's here):
    // (REFRESH + 1) 4 gamma_m / (omega_min tau) of the energy. omega_min, the beam's lowest
    // frequency, is at least half the Euler-Bernoulli value of a clamped-clamped beam,
    // 4.730^2 sqrt(E' I / (rho A)) / L^2 = 0.958 (E' = E / (1 - nu^2), plane strain; I / A =
    // 1/12, L = 10): shear and rotary inertia lower it by a few percent at L / H = 10, the
    // finite elements raise it.
    let e_plane = 200.0 / (1.0 - 0.3f64.powi(2));
    let omega_min = 0.5 * 4.730f64.powi(2) * (e_plane / 12.0).sqrt() / 100.0;
    let gamma = 18.0 * f64::EPSILON / 2.0;
    let tau = 1e-5;
    let energy_bound = (REFRESH + 1) as f64 * 4.0 * gamma / (omega_min * tau);
    eprintln!("energy drift {:e} (round-off bound {energy_bound:e})", r.drift_energy);
    assert!(
        r.drift_energy < energy_bound,
        "the energies drifted by {:e} of the energy (bound {energy_bound:e})",
        r.drift_energy
    );
    // The same run with every product recomputed (PETSc's CG): equal to solver tolerance.
    // Each solve may leave an error of rtol = 1e-10 of the increment; the midpoint rule is
    // stable, so over n steps the states differ by at most about n rtol of the solution's
    // size (the exact solution's amplitude, 0.02 x (10 - x) y^2 <= 0.5), and so do the errors.
    let fresh = beam(2, &["-step_reuse", "false"]);
    assert_eq!(fresh.step_reuse.steps, 0);
    assert_eq!(kept.errors.len(), 2);
    for (a, b) in kept.errors.iter().zip(&fresh.errors) {
        assert_eq!(a.step, b.step);
        let limit = a.step as f64 * 1e-10 * 0.5;
        assert!(
            (a.l2 - b.l2).abs() < limit,
            "L2 error at step {}: {} vs {} (limit {limit:e})",
            a.step,
            a.l2,
            b.l2
        );
    }
    // The energy is quadratic in the state: twice the states' relative difference.
    assert!(
        rel_diff(kept.energy_final, fresh.energy_final) < 2.0 * STEPS as f64 * 1e-10,
        "final energy {} vs {}",
        kept.energy_final,
        fresh.energy_final
    );
    assert!(kept.energy_balance < 1e-9, "energy balance {:e}", kept.energy_balance);
    // 1 rank against 2: the same solver, so far closer than the bound above.
    let one = beam(1, &["-step_reuse_refresh", &refresh]);
    assert!(
        rel_diff(one.energy_final, kept.energy_final) < 1e-9,
        "1 rank {} vs 2 ranks {}",
        one.energy_final,
        kept.energy_final
    );
    assert_eq!(one.step_reuse.refreshes, r.refreshes);
}
