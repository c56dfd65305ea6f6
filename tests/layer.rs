//! The mass-free layer's rows in the step's preconditioner (issue 28, `time::layer`): the
//! massless DOFs' block of `K` solved in a symmetric block sweep, and their own guess.
//!
//! - Same increments: every shipped scene without contact (the beam and the block, quads,
//!   triangles, hexahedra, tetrahedra) with either layer (`modified0`, `modified1`) gives the
//!   plain Jacobi solver's results to solver tolerance, on 1 and 2 ranks; 1 rank against 2 as
//!   well; on 2 ranks both scopes of the block (the whole layer gathered, the 2D default;
//!   each rank's own, the 3D default: `-step_layer_local`).
//! - The iterations of `M`: with the sweep `B K` has the eigenvalue 1 on the layer and
//!   Jacobi's spectrum on the Schur complement of the massive rows (`4/tau^2 M_II` plus a
//!   stiffness below `A_II`), and the layer's guess is exact for the `(-1)^n` mode the
//!   midpoint rule leaves on massless DOFs: so `M_H` takes `M`'s iterations (within 10%),
//!   also with the partition cutting the layer (plain Jacobi's count is printed: about 1.8
//!   times `M`'s).

mod common;
use common::*;

const STEPS: usize = 120;
/// The step solver's relative tolerance (`StepSolverDefaults::rtol`).
const RTOL: f64 = 1e-10;

struct Run {
    summary: RunSummary,
    displacement: Vec<f64>,
    /// Active contact nodes per step (empty without contact).
    active: Vec<f64>,
    /// The contact force per step and contact node (empty without contact).
    force: Vec<f64>,
}

fn run(scene: &str, mass: &str, ranks: usize, layer: bool, extra: &[&str]) -> Run {
    run_with(scene, &shortened(), mass, ranks, layer, extra, &[])
}

/// The shipped scenes without contact cut to `STEPS` steps.
fn shortened() -> [(&'static str, String); 2] {
    [
        ("steps = 250", format!("steps = {STEPS}")),
        ("error_steps = [30, 250]", "error_steps = [30, 120]".into()),
    ]
}

fn run_with(
    scene: &str,
    replace: &[(&str, String)],
    mass: &str,
    ranks: usize,
    layer: bool,
    extra: &[&str],
    petsc: &[&str],
) -> Run {
    let tag = petsc.join("").replace('-', "");
    let dir =
        scratch(&format!("layer-{}-{mass}-{ranks}-{layer}{tag}", scene.trim_end_matches(".toml")));
    let replace: Vec<(&str, &str)> = replace.iter().map(|(a, b)| (*a, b.as_str())).collect();
    let path = scene_variant(scene, &dir, &replace);
    let mut args = vec!["--mass", mass];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--", "-step_layer", if layer { "true" } else { "false" }]);
    if layer {
        args.extend_from_slice(&["-step_layer_around", "true"]);
    }
    args.extend_from_slice(petsc);
    let summary = run_scene(ranks, &path, &args);
    let stem = path.file_stem().unwrap().to_string_lossy().to_string();
    let h5 = dir.join(format!("{stem}-{ranks}.h5"));
    let file = reader(&h5);
    let active = file.series("contact/active_set_size").unwrap_or_default();
    let force = file.series("contact/force").unwrap_or_default();
    Run { summary, displacement: values(&h5, "fields/displacement"), active, force }
}

/// The option for the layer block's scope that is not the default of `scene` (each rank's
/// own block in 3D, the whole layer gathered in 2D).
fn other_scope(scene: &str) -> [&'static str; 2] {
    let three_d = scene.starts_with("block") || scene.starts_with("sphere");
    ["-step_layer_local", if three_d { "false" } else { "true" }]
}

/// `max |a - b| / max |b|` over the whole series.
fn field_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

#[test]
fn the_layer_sweep_gives_the_plain_solvers_results_on_every_scene_without_contact() {
    for (scene, mass) in [
        ("beam.toml", "modified0"),
        ("beam.toml", "modified1"),
        ("beam_tri.toml", "modified1"),
        ("block_hex.toml", "modified1"),
        ("block_tet.toml", "modified0"),
    ] {
        let one = run(scene, mass, 1, true, &[]);
        for ranks in [1, 2] {
            let swept = if ranks == 1 { None } else { Some(run(scene, mass, ranks, true, &[])) };
            let swept = swept.as_ref().unwrap_or(&one);
            let plain = run(scene, mass, ranks, false, &[]);
            let (s, p) = (&swept.summary, &plain.summary);
            assert!(s.step_reuse.layer_rows > 0, "{scene} {mass}: no layer block");
            assert_eq!(p.step_reuse.layer_rows, 0, "{scene} {mass}: -step_layer false");
            // Each solve may leave an error of rtol in the energy norm; the midpoint rule is
            // stable, so after n steps the runs differ by about n rtol of the solution (a
            // factor 10 for the max-norm against the energy norm on the massless rows).
            let bound = 10.0 * STEPS as f64 * RTOL;
            let d = field_diff(&swept.displacement, &plain.displacement);
            eprintln!("{scene} {mass} {ranks} rank(s): displacements differ by {d:.2e} (bound {bound:.1e}); iterations {} against {}", s.ksp_iterations, p.ksp_iterations);
            assert!(d < bound, "{scene} {mass} on {ranks} rank(s): displacement differs by {d:e}");
            // The sweep keeps the energy identity like plain CG (the solution scaled onto its
            // own direction).
            assert!(s.energy_balance < 1e-10, "{scene} {mass}: balance {:e}", s.energy_balance);
            if ranks == 2 {
                let d = field_diff(&swept.displacement, &one.displacement);
                assert!(d < bound, "{scene} {mass}: 1 rank against 2 differ by {d:e}");
                // The other scope of the layer's block (`-step_layer_local`; by default each
                // rank's own block in 3D, the whole layer in 2D): another preconditioner,
                // the same solution.
                let local = other_scope(scene);
                let l = run_with(scene, &shortened(), mass, 2, true, &[], &local);
                assert!(
                    l.summary.step_reuse.layer_rows > 0,
                    "{scene} {mass}: no layer block (other scope)"
                );
                let d = field_diff(&l.displacement, &plain.displacement);
                eprintln!(
                    "{scene} {mass} other scope {local:?}: differ by {d:.2e}; iterations {}",
                    l.summary.ksp_iterations
                );
                assert!(d < bound, "{scene} {mass} other scope: displacement differs by {d:e}");
                assert!(l.summary.energy_balance < 1e-10, "{scene} {mass} local: balance");
            }
        }
    }
}

#[test]
fn the_modified_mass_takes_the_iterations_of_the_standard_one() {
    // The beam at h = 1/32 (CFL 0.02) on 2 ranks cut across the layer (x-slabs: the cut runs
    // through the bottom edge, where the layer is).
    let extra = ["--param", "h=0.03125", "--partition", "x-slabs"];
    let m = run("beam.toml", "consistent", 2, true, &extra).summary;
    assert_eq!(m.step_reuse.layer_rows, 0, "M has no massless rows");
    for mass in ["modified0", "modified1"] {
        let swept = run("beam.toml", mass, 2, true, &extra).summary;
        let plain = run("beam.toml", mass, 2, false, &extra).summary;
        let per_step = |s: &RunSummary| s.ksp_iterations as f64 / s.steps as f64;
        let (im, is, ip) = (per_step(&m), per_step(&swept), per_step(&plain));
        eprintln!("{mass}: {is:.2} iterations a step with the sweep, {ip:.2} without, M {im:.2}");
        assert!(is <= 1.1 * im, "{mass}: {is:.2} iterations a step against M's {im:.2}");
    }
}

#[test]
fn the_layer_sweep_around_petscs_preconditioner_gives_the_plain_solvers_contact_steps() {
    // Contact steps are solved by PETSc's KSP on the operator the contact solver rewrote in
    // the layer's rows; with `-step_layer_around` the sweep wraps its preconditioner
    // (Jacobi for the disc, block Jacobi/ILU(0) for the ball) and is set up again at every
    // active-set change. The disc
    // hits at step 63 and the ball at step 6: both runs see the contact zone grow.
    for (scene, mass, shipped, steps) in [
        ("disc.toml", "modified1", "steps = 1000", 160),
        ("disc.toml", "modified0", "steps = 1000", 160),
        ("sphere_hex.toml", "modified0", "steps = 220", 40),
        ("sphere_hex.toml", "modified1", "steps = 220", 40),
    ] {
        let replace = [(shipped, format!("steps = {steps}"))];
        let one = run_with(scene, &replace, mass, 1, true, &[], &[]);
        for ranks in [1, 2] {
            let swept = if ranks == 1 {
                None
            } else {
                Some(run_with(scene, &replace, mass, ranks, true, &[], &[]))
            };
            let swept = swept.as_ref().unwrap_or(&one);
            let plain = run_with(scene, &replace, mass, ranks, false, &[], &[]);
            let (s, p) = (&swept.summary, &plain.summary);
            assert!(s.step_reuse.layer_rows > 0, "{scene} {mass}: no layer sweep");
            assert_eq!(p.step_reuse.layer_rows, 0, "{scene} {mass}: -step_layer false");
            // The same contact: the same active sets, step by step.
            assert!(swept.active.iter().any(|&a| a > 0.0), "{scene}: no contact");
            assert_eq!(
                swept.active, plain.active,
                "{scene} {mass} on {ranks} rank(s): active sets"
            );
            // As without contact: each solve leaves at most rtol in the energy norm.
            let bound = 10.0 * steps as f64 * RTOL;
            let d = field_diff(&swept.displacement, &plain.displacement);
            eprintln!("{scene} {mass} {ranks} rank(s): displacements differ by {d:.2e} (bound {bound:.1e}); iterations {} against {}", s.ksp_iterations, p.ksp_iterations);
            assert!(d < bound, "{scene} {mass} on {ranks} rank(s): displacement differs by {d:e}");
            // The same contact forces, to the same bound relative to the peak: the contact
            // nodes are the layer's, massless, so their force is the layer's static response
            // to the state (the step's residual on those rows, the stiffness alone), and its
            // error is the state's in proportion. The iterations are printed above, not
            // compared: the sweep's savings belong in benchmarks.
            let f = field_diff(&swept.force, &plain.force);
            eprintln!(
                "{scene} {mass} {ranks} rank(s): contact forces differ by {f:.2e} of the peak"
            );
            assert!(f < bound, "{scene} {mass} on {ranks} rank(s): contact forces differ by {f:e}");
            if ranks == 2 {
                let d = field_diff(&swept.displacement, &one.displacement);
                assert!(d < bound, "{scene} {mass}: 1 rank against 2 differ by {d:e}");
                assert_eq!(swept.active, one.active, "{scene} {mass}: 1 rank against 2");
                let f = field_diff(&swept.force, &one.force);
                assert!(f < bound, "{scene} {mass}: 1 rank against 2: forces differ by {f:e}");
                let local = other_scope(scene);
                let l = run_with(scene, &replace, mass, 2, true, &[], &local);
                assert_eq!(l.active, plain.active, "{scene} {mass} other scope: active sets");
                let d = field_diff(&l.displacement, &plain.displacement);
                eprintln!(
                    "{scene} {mass} other scope {local:?}: differ by {d:.2e}; iterations {}",
                    l.summary.ksp_iterations
                );
                assert!(d < bound, "{scene} {mass} other scope: displacement differs by {d:e}");
                let f = field_diff(&l.force, &plain.force);
                assert!(f < bound, "{scene} {mass} other scope: forces differ by {f:e}");
            }
        }
    }
}
