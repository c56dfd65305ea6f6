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
