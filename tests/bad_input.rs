//! Bad input gets a one-line error naming the culprit and a non-zero exit code, never a panic.

mod common;
use common::*;

fn expect_error(args: &[&str], culprit: &str) {
    let o = massfree(0, args);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "expected failure for {args:?}");
    assert!(!stderr.contains("panicked"), "panic for {args:?}: {stderr}");
    let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "not one line for {args:?}: {stderr}");
    assert!(lines[0].contains(culprit), "{:?} does not name {culprit:?}", lines[0]);
}

fn beam_with(dir: &std::path::Path, from: &str, to: &str) -> String {
    scene_variant("beam.toml", dir, &[(from, to)]).display().to_string()
}

#[test]
fn scene_errors_name_the_key() {
    let dir = scratch("bad-scene");
    expect_error(&["run", &beam_with(&dir, "E = 200.0", "E = -200.0")], "E");
    expect_error(&["run", &beam_with(&dir, "nu = 0.3", "nu = 0.5")], "nu");
    expect_error(&["run", &beam_with(&dir, "tau = 1e-5", "tau = 0.0")], "tau");
    expect_error(&["run", &beam_with(&dir, "tau = 1e-5", "tau = -1e-5")], "tau");
    expect_error(&["run", &beam_with(&dir, "[material]", "[materail]")], "materail");
    // This one is found after the output file was created: the file says so, and a second
    // run may replace it (it holds no step).
    let out = dir.join("roof.h5");
    let roof = beam_with(&dir, "group = \"top\"", "group = \"roof\"");
    for _ in 0..2 {
        expect_error(&["run", &roof, "-o", out.to_str().unwrap()], "roof");
        let status = reader(&out).text("status");
        assert!(status.starts_with("failed: ") && status.contains("roof"), "{status}");
    }
}

#[test]
fn unknown_output_field_names_the_key_and_the_valid_names() {
    let dir = scratch("bad-field");
    let scene =
        beam_with(&dir, "every = 10", "every = 10\nfields = [\"displacement\", \"vonmises\"]");
    expect_error(&["run", &scene], "output.fields = \"vonmises\" is not allowed");
    expect_error(
        &["run", &scene],
        "allowed: displacement, velocity, stress, strain, von_mises, effective_stress, pressure, \
         stress_nodal, strain_nodal, von_mises_nodal, effective_stress_nodal, pressure_nodal, \
         contact_traction",
    );
    let scene = beam_with(&dir, "every = 10", "every = 10\nfield_every = { vonmises = 5 }");
    expect_error(&["run", &scene], "unknown key \"output.field_every.vonmises\"");
    // The beam has no contact: no contact traction to write.
    let scene = beam_with(&dir, "every = 10", "every = 10\nfields = [\"contact_traction\"]");
    expect_error(&["run", &scene], "output.fields: contact_traction needs a [contact] table");
}

/// gmsh ignores a `-setnumber` its `.geo` does not declare: a misspelt `--param` would mesh the
/// default size without a word. It is a one-line error naming the parameter and the declared
/// ones.
#[test]
fn a_param_the_geo_does_not_declare_is_an_error() {
    let dir = scratch("bad-param");
    let scene = scene_variant("beam.toml", &dir, &[]);
    let scene = scene.to_str().unwrap();
    expect_error(&["run", scene, "--no-output", "--param", "hh=0.1"], "\"hh\" (it has: h)");
}

/// The same in the scene: `mesh.params` names are the `.geo`'s, or the scene is refused.
#[test]
fn a_scene_param_the_geo_does_not_declare_is_an_error() {
    let dir = scratch("bad-scene-param");
    let scene =
        scene_variant("beam.toml", &dir, &[("params = { h = 0.125 }", "params = { hh = 0.125 }")]);
    let scene = scene.to_str().unwrap();
    expect_error(
        &["run", scene, "--no-output"],
        "beam_quad.geo declares no parameter \"hh\" (it has: h)",
    );
}

#[test]
fn missing_scene_file_is_an_error() {
    expect_error(&["run", "/nonexistent/scene.toml"], "/nonexistent/scene.toml");
}

#[test]
fn malformed_msh_is_an_error() {
    let dir = scratch("bad-msh");
    let msh = dir.join("broken.msh");
    std::fs::write(&msh, "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 1 2\n2 1 0 2\n1\n")
        .unwrap();
    let text = std::fs::read_to_string(repo().join("scenes/beam.toml")).unwrap();
    let text = text.replace(
        "geo = \"../meshes/beam_quad.geo\"\nparams = { h = 0.125 }",
        &format!("msh = \"{}\"", msh.display()),
    );
    let scene = dir.join("beam.toml");
    std::fs::write(&scene, text).unwrap();
    expect_error(&["run", &scene.display().to_string()], "broken.msh");
}

#[test]
fn bad_petsc_option_value_is_an_error_not_a_panic() {
    let dir = scratch("bad-petsc");
    let scene = scene_variant(
        "beam.toml",
        &dir,
        &[("steps = 250", "steps = 2"), ("error_steps = [30, 250]", "error_steps = [2]")],
    );
    let o = massfree(
        0,
        &["run", &scene.display().to_string(), "--no-output", "--", "-step_ksp_type", "nonsense"],
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(stderr.contains("massfree: PETSc error"), "{stderr}");
}

/// The unit square (one step) with `obstacle` as `[contact]`'s obstacle line(s).
fn square_with_obstacle(dir: &std::path::Path, obstacle: &str) -> String {
    let rest =
        format!("[time]\ntau = 1e-3\nsteps = 1\n[contact]\nboundary = \"bottom\"\n{obstacle}\n");
    small_scene(dir, "square", "square_quad.geo", 0.25, &rest).display().to_string()
}

#[test]
fn obstacle_errors_name_the_key() {
    let dir = scratch("bad-obstacle");
    let floor = "{ type = \"plane\", point = [0, -0.01], normal = [0, 1] }";
    let cases = [
        (
            "obstacle = { type = \"plane\", point = [0, -0.01], normal = [0, 0] }".to_string(),
            "contact.obstacle.normal",
        ),
        (
            format!("obstacles = [{floor}, {{ type = \"cylinder\", point = [0, 0, -1], axis = [0, 0, 0], radius = 1 }}]"),
            "contact.obstacles[1].axis",
        ),
        (
            "obstacle = { type = \"sphere\", center = [0.5, -1.01], radius = 0 }".to_string(),
            "contact.obstacle.radius",
        ),
        (
            "obstacle = { type = \"plane\", point = [0, -0.01], normal = [0, 1], motion = [\"0\", \"0\", \"t\"] }"
                .to_string(),
            "contact.obstacle.motion has 3 components but the mesh is 2D",
        ),
        (
            "obstacle = { type = \"plane\", point = [0, -0.01], normal = [0, 1], motion = [\"x*t\", \"0\"] }"
                .to_string(),
            "contact.obstacle.motion[0]",
        ),
        (
            format!("obstacle = {floor}\nobstacles = [{floor}]"),
            "contact.obstacle and contact.obstacles",
        ),
        (String::new(), "contact.obstacle"),
        (
            "obstacle = { type = \"cylinder\", point = [0, 0, -1], axis = [1, 0, 0], radius = 0.99 }"
                .to_string(),
            "contact.obstacle is a cylinder but the mesh is 2D",
        ),
        // At t = 0 the second obstacle, moved by d(0) = (0, 0.5), cuts into the body.
        (
            format!("obstacles = [{floor}, {{ type = \"plane\", point = [0, -0.01], normal = [0, 1], motion = [\"0\", \"0.5 - t\"] }}]"),
            "contact.obstacles[1] already intersects the body at t = 0",
        ),
    ];
    for (obstacle, culprit) in &cases {
        let scene = square_with_obstacle(&dir, obstacle);
        expect_error(&["run", &scene, "--no-output"], culprit);
    }
}

/// `[[body]]` errors found against the mesh, through the binary: one line naming
/// the key, no panic, and the output file says the run failed.
#[test]
fn body_errors_name_the_key() {
    let dir = scratch("bad-body");
    let base = "[mesh]\ngeo = \"../meshes/two_bars.geo\"\nparams = { n = 4, ny = 1 }\n[material]\nE = 1.0\nnu = 0.3\nrho = 1.0\n[time]\ntau = 0.01\nsteps = 1\n";
    let cases = [
        ("[[body]]\ngroup = \"left\"\n[[body]]\ngroup = \"middle\"\n", "body[1].group = \"middle\": no such physical group of dimension 2"),
        ("[[body]]\ngroup = \"left_contact\"\nE = 2\n", "body[0].group = \"left_contact\": no such physical group of dimension 2 (\"left_contact\" has dimension 1"),
        (
            "[[body]]\ngroup = \"right\"\nmass = \"modified1\"\n[mass]\ncontact_boundary = \"left_contact\"\n",
            "body[0].mass = modified1 needs a contact group on the body \"right\"",
        ),
        (
            "[[body]]\ngroup = \"right\"\nmass = \"modified0\"\n[mass]\nkind = \"modified1\"\n[contact]\nslave = \"left_contact\"\nmaster = \"right_contact\"\n",
            "one run builds one variant",
        ),
    ];
    for (i, (rest, culprit)) in cases.iter().enumerate() {
        let scene = scene_text(&dir, &format!("bars{i}.toml"), &format!("{base}{rest}"));
        let out = dir.join(format!("bars{i}.h5"));
        let o = massfree(0, &["run", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && !stderr.contains("panicked"), "{stderr}");
        let lines: Vec<&str> = stderr.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "not one line: {stderr}");
        assert!(lines[0].contains(culprit), "{:?} does not name {culprit:?}", lines[0]);
        let status = reader(&out).text("status");
        assert!(status.starts_with("failed: ") && status.contains(culprit), "{status}");
    }
}

/// Obstacles beside a slave/master pair: the group meeting them is required and must share no
/// node with the slave group (found against the mesh); one line naming the keys, no panic.
#[test]
fn obstacles_beside_a_pair_name_the_key() {
    let dir = scratch("bad-pair-obstacles");
    let base = "[mesh]\ngeo = \"../meshes/two_bars.geo\"\nparams = { n = 4, ny = 1 }\n[material]\nE = 1.0\nnu = 0.3\nrho = 1.0\n[time]\ntau = 0.01\nsteps = 1\n[contact]\nslave = \"left_contact\"\nmaster = \"right_contact\"\nobstacle = { type = \"plane\", point = [3.0, 0.0], normal = [-1.0, 0.0] }\n";
    let cases = [
        ("", "obstacles beside a slave/master pair need contact.boundary"),
        (
            "boundary = \"right_contact\"\n",
            "contact.boundary = \"right_contact\" is also contact.master",
        ),
        (
            "boundary = \"left_free\"\n",
            "contact.boundary = \"left_free\" and contact.slave = \"left_contact\" share gmsh node",
        ),
    ];
    for (i, (rest, culprit)) in cases.iter().enumerate() {
        let scene = scene_text(&dir, &format!("pair{i}.toml"), &format!("{base}{rest}"));
        expect_error(&["run", scene.to_str().unwrap(), "--no-output"], culprit);
    }
}

/// Several pairs: the sides of a pair share no node (found against the mesh: "left_free" holds
/// the corner nodes of "left_contact"); a group that does not exist is named.
#[test]
fn contact_pairs_name_the_groups() {
    let dir = scratch("bad-pairs");
    let base = "[mesh]\ngeo = \"../meshes/three_bars.geo\"\nparams = { n = 4, ny = 1 }\n[material]\nE = 1.0\nnu = 0.3\nrho = 1.0\n[time]\ntau = 0.01\nsteps = 1\n[contact]\n";
    let cases = [
        (
            "pairs = [{ slave = \"left_contact\", master = \"middle_left\" }, { slave = \"right_contact\", master = \"free\" }]\n",
            "gmsh node",
        ),
        (
            "pairs = [{ slave = \"left_contact\", master = \"middle_left\" }, { slave = \"right_contact\", master = \"middle_rihgt\" }]\n",
            "middle_rihgt",
        ),
    ];
    for (i, (rest, culprit)) in cases.iter().enumerate() {
        let scene = scene_text(&dir, &format!("pairs{i}.toml"), &format!("{base}{rest}"));
        expect_error(&["run", scene.to_str().unwrap(), "--no-output"], culprit);
    }
}

/// The stored-columns contact solver cannot follow a tangent that changes every Newton
/// iteration: at finite strain it is a one-line error naming it (every other solver follows).
#[test]
fn finite_strain_with_the_columns_contact_solver_is_an_error() {
    let dir = scratch("fs-columns");
    let scene = scene_variant("disc.toml", &dir, &[]);
    let scene = scene.to_str().unwrap();
    let args = ["run", scene, "--no-output", "--steps", "1", "--model", "neo_hookean"];
    expect_error(
        &[&args[..], &["--", "-contact_solver", "columns"]].concat(),
        "-contact_solver columns cannot follow",
    );
}
