use super::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh folder with `meshes/beam.geo` and `meshes/beam.msh`, and scenes in `scenes/`.
fn workspace() -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "scenedev-test-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::SeqCst)
    ));
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::create_dir_all(dir.join("scenes")).unwrap();
    std::fs::write(
        dir.join("meshes/beam.geo"),
        "// geo\nDefineConstant[ h = {0.25, Name \"h\"}, n = {4, Name \"n\"} ];\n",
    )
    .unwrap();
    std::fs::write(dir.join("meshes/beam.msh"), "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n").unwrap();
    dir
}

const FULL: &str = r#"
name = "beam"

[mesh]
geo = "../meshes/beam.geo"
params = { h = 0.25, n = 4 }
binary = true

[material]
E = 200.0
nu = 0.3
rho = 1.0

[[dirichlet]]
group = "left"
value = ["0", "0"]
components = ["y", "x"]

[[dirichlet]]
group = "clamp"
value = [0, "1e-3*t"]

[[neumann]]
group = "top"
traction = ["0", "-1e-3*sin(2*pi*t)"]

[body_force]
value = ["0", "0.02*x*(10-x)*y^2*sin(2*pi*t)"]

[initial]
displacement = ["0", "0"]
velocity = ["0", "x*(10-x)"]

[time]
tau = 1e-5
end = 2.5e-3

[mass]
kind = "modified1"
contact_boundary = "bottom"

[solver]
ksp_type = "cg"
pc_type = "jacobi"
rtol = 1e-10
options = "-ksp_norm_type  unpreconditioned -ksp_monitor"

[output]
file = "results/beam.h5"
every = 5
fields = ["velocity"]
progress = true

[exact]
displacement = ["0", "x*t"]
velocity = ["0", "x"]
gradient = [["0", "0"], ["t", "0"]]
error_steps = [30, 10, 30]

[contact]
boundary = "contact"
obstacle = { type = "plane", point = [0.0, -1.0], normal = [0.0, 2.0] }
"#;

const MINIMAL: &str = r#"
[mesh]
msh = "../meshes/beam.msh"
[material]
E = 1
nu = 0.25
rho = 2
[time]
tau = 0.1
steps = 10
"#;

fn parse_in(dir: &Path, text: &str) -> Result<Scene> {
    parse(text, "beam.toml", &dir.join("scenes"))
}

fn err_of(text: &str) -> String {
    let dir = workspace();
    match parse_in(&dir, text) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => {
            let m = e.to_string();
            assert!(!m.contains('\n'), "multi-line message: {m:?}");
            assert!(m.starts_with("scene error: beam.toml: "), "{m}");
            m
        }
    }
}

fn assert_err(text: &str, needles: &[&str]) {
    let m = err_of(text);
    for n in needles {
        assert!(m.contains(n), "message {m:?} lacks {n:?}");
    }
}

/// MINIMAL with `from` replaced by `to` (which must occur).
fn minimal_with(from: &str, to: &str) -> String {
    assert!(MINIMAL.contains(from), "{from}");
    MINIMAL.replacen(from, to, 1)
}

/// MINIMAL with a `[contact]` table on the boundary "c" and `obstacle` (the obstacle line(s)).
fn with_contact(obstacle: &str) -> String {
    format!("{MINIMAL}\n[contact]\nboundary = \"c\"\n{obstacle}\n")
}

fn full_with(from: &str, to: &str) -> String {
    assert!(FULL.contains(from), "{from}");
    FULL.replacen(from, to, 1)
}

#[test]
fn full_scene_round_trips() {
    let dir = workspace();
    let s = parse_in(&dir, FULL).unwrap();
    assert_eq!(s.name, "beam");
    assert_eq!(s.text, FULL);
    assert_eq!(s.source, dir.join("scenes").join("beam.toml"));
    match &s.mesh {
        MeshSource::Geo { path, params, binary } => {
            assert_eq!(path, &dir.join("scenes").join("../meshes/beam.geo"));
            assert!(path.is_file());
            assert_eq!(params, &vec![("h".to_string(), 0.25), ("n".to_string(), 4.0)]);
            assert!(*binary);
        }
        m => panic!("{m:?}"),
    }
    assert_eq!(
        s.material,
        MaterialSpec {
            e: 200.0,
            nu: 0.3,
            rho: 1.0,
            model: Model::Linear,
            formulation: Formulation::Displacement
        }
    );
    assert_eq!(s.dirichlet.len(), 2);
    assert_eq!(s.dirichlet[0].group, "left");
    assert_eq!(s.dirichlet[0].components, vec![0, 1]);
    assert!(s.dirichlet[0].components_given);
    assert!(s.dirichlet[0].value.is_zero());
    assert_eq!(s.dirichlet[1].components, vec![0, 1, 2]);
    assert!(!s.dirichlet[1].components_given);
    assert_eq!(s.dirichlet[1].constrained(2), vec![0, 1]);
    assert_eq!(s.dirichlet[1].value.eval([0.0; 3], 2.0), [0.0, 2e-3, 0.0]);
    assert_eq!(s.neumann.len(), 1);
    assert_eq!(s.neumann[0].group, "top");
    let tr = s.neumann[0].traction.eval([0.0; 3], 0.25);
    assert!((tr[1] + 1e-3).abs() < 1e-15);
    let b = s.body_force.as_ref().unwrap();
    let (x, y, t) = (3.0, 0.5, 0.1);
    let want = 0.02 * x * (10.0 - x) * y * y * (2.0 * std::f64::consts::PI * t).sin();
    assert!((b.eval([x, y, 0.0], t)[1] - want).abs() < 1e-15);
    assert!(s.initial_displacement.as_ref().unwrap().is_zero());
    assert_eq!(s.initial_velocity.as_ref().unwrap().eval([2.0, 0.0, 0.0], 0.0), [0.0, 16.0, 0.0]);
    assert_eq!(s.tau, 1e-5);
    assert_eq!(s.steps, 250);
    assert!((s.end_time() - 2.5e-3).abs() < 1e-15);
    assert_eq!(s.mass.kind, MassKind::Modified1);
    assert_eq!(s.mass.kind.name(), "modified1");
    assert_eq!(s.mass.contact_boundary.as_deref(), Some("bottom"));
    assert_eq!(
        s.solver,
        SolverSpec {
            ksp_type: Some("cg".into()),
            pc_type: Some("jacobi".into()),
            rtol: Some(1e-10),
            options: vec![
                "-ksp_norm_type".into(),
                "unpreconditioned".into(),
                "-ksp_monitor".into()
            ],
        }
    );
    assert_eq!(
        s.output,
        OutputSpec {
            file: PathBuf::from("results/beam.h5"),
            compression: None,
            every: 5,
            field_every: vec![],
            times: vec![],
            time_steps: vec![],
            fields: vec![Field::Velocity],
            progress: true,
        }
    );
    let ex = s.exact.as_ref().unwrap();
    assert_eq!(ex.displacement.eval([2.0, 0.0, 0.0], 3.0), [0.0, 6.0, 0.0]);
    assert!(ex.velocity.is_some());
    let g = ex.gradient.as_ref().unwrap();
    assert_eq!(g.len(), 2);
    assert_eq!(g[1].eval([0.0; 3], 7.0), [7.0, 0.0, 0.0]);
    assert_eq!(ex.error_steps, vec![10, 30]);
    let c = s.contact.as_ref().unwrap();
    assert_eq!(c.boundary.as_deref(), Some("contact"));
    assert!(c.pairs.is_empty());
    let plane = Shape::Plane { point: vec![0.0, -1.0], normal: vec![0.0, 1.0] };
    assert_eq!(c.obstacles, vec![Obstacle { shape: plane, motion: None, friction: None }]);
    assert!(!c.listed);
    s.check_dim(2).unwrap();
}

#[test]
fn stress_fields_and_their_periods() {
    let dir = workspace();
    let text = full_with(
        "fields = [\"velocity\"]",
        "fields = [\"von_mises\", \"stress_nodal\", \"displacement\", \"von_mises\", \"pressure_nodal\"]\n\
         field_every = { von_mises = 10, stress_nodal = 20, effective_stress = 3 }",
    );
    let s = parse_in(&dir, &text).unwrap();
    // In the order given, without duplicates.
    assert_eq!(
        s.output.fields,
        vec![Field::VonMises, Field::StressNodal, Field::Displacement, Field::PressureNodal]
    );
    assert_eq!(s.every_of(Field::VonMises), 10);
    assert_eq!(s.every_of(Field::StressNodal), 20);
    assert_eq!(s.every_of(Field::Displacement), 5);
    assert_eq!(s.every_of(Field::PressureNodal), 5);
    // Specs: cell values and nodal projections, 6 components for tensors (also in 2D).
    use crate::rows::{FieldSpec, Location};
    assert_eq!(Field::VonMises.spec(2), FieldSpec::cell("von_mises", 1));
    assert_eq!(Field::Stress.spec(2), FieldSpec::cell("stress", 6));
    assert_eq!(Field::StrainNodal.spec(3), FieldSpec::nodal("strain_nodal", 6));
    assert_eq!(Field::PressureNodal.spec(3), FieldSpec::nodal("pressure_nodal", 1));
    assert_eq!(Field::Displacement.spec(3), FieldSpec::nodal("displacement", 3));
    for f in Field::ALL {
        // Every name parses back to its field and every stress field names its quantity.
        let one = full_with("fields = [\"velocity\"]", &format!("fields = [\"{}\"]", f.name()));
        assert_eq!(parse_in(&dir, &one).unwrap().output.fields, vec![f]);
        if let Some((q, loc)) = f.derived() {
            let base = f.name().trim_end_matches("_nodal");
            assert_eq!(q.name(), base);
            assert_eq!(loc == Location::Nodal, f.name().ends_with("_nodal"));
        }
    }
    assert_err(
        &full_with("fields = [\"velocity\"]", "field_every = { von_mises = 0 }"),
        &["output.field_every.von_mises = 0 is impossible"],
    );
    assert_err(
        &full_with("fields = [\"velocity\"]", "field_every = { mises = 2 }"),
        &["unknown key \"output.field_every.mises\"", "von_mises_nodal"],
    );
}

#[test]
fn minimal_scene_defaults() {
    let dir = workspace();
    let s = parse_in(&dir, MINIMAL).unwrap();
    assert_eq!(s.name, "beam"); // file stem
    assert_eq!(s.mesh, MeshSource::Msh { path: dir.join("scenes").join("../meshes/beam.msh") });
    assert!(s.dirichlet.is_empty() && s.neumann.is_empty());
    assert!(s.body_force.is_none());
    assert!(s.initial_displacement.is_none() && s.initial_velocity.is_none());
    assert_eq!(s.steps, 10);
    assert_eq!(s.mass.kind, MassKind::Consistent);
    assert_eq!(s.mass.contact_boundary, None);
    assert_eq!(s.solver, SolverSpec::default());
    assert_eq!(s.output.file, PathBuf::from("out/beam.h5"));
    assert_eq!(s.output.every, 1);
    assert_eq!(s.output.fields, vec![Field::Displacement, Field::Velocity]);
    assert!(s.output.progress, "progress is on by default (only rank 0 on a terminal shows a bar)");
    assert!(s.exact.is_none() && s.contact.is_none());
    assert_eq!(
        s.effects().summary(),
        "effects: elasticity, consistent mass; not built: mass-free layer, initial displacement, initial velocity, body force, tractions, Dirichlet, Dirichlet lifting, contact, friction, exact errors, stress output"
    );
    s.check_dim(2).unwrap();
    s.check_dim(3).unwrap();
}

#[test]
fn load_from_file() {
    let dir = workspace();
    let path = dir.join("scenes").join("cantilever.toml");
    std::fs::write(&path, MINIMAL).unwrap();
    let s = load(&path).unwrap();
    assert_eq!(s.name, "cantilever");
    assert_eq!(s.source, path);
    assert_eq!(s.text, MINIMAL);
    assert_eq!(s.output.file, PathBuf::from("out/cantilever.h5"));
    let missing = load(&dir.join("scenes/nope.toml")).unwrap_err().to_string();
    assert!(missing.contains("nope.toml: cannot read the scene file"), "{missing}");
    std::fs::write(&path, "[material]\nE = 1\nnu = 0.7\nrho = 1\n").unwrap();
    let m = load(&path).unwrap_err().to_string();
    assert!(m.contains("cantilever.toml: missing key \"mesh\""), "{m}");
}

#[test]
fn defaults_for_exact_and_mass() {
    let dir = workspace();
    let text =
        format!("{MINIMAL}\n[exact]\ndisplacement = [\"x\", 0]\n[mass]\nkind = \"lumped\"\n");
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.exact.as_ref().unwrap().error_steps, vec![10]);
    assert!(s.exact.as_ref().unwrap().gradient.is_none());
    assert_eq!(s.mass.kind, MassKind::Lumped);
    let s = parse_in(&dir, &format!("{MINIMAL}\n[mass]\n")).unwrap();
    assert_eq!(s.mass.kind, MassKind::Consistent);
}

#[test]
fn sphere_obstacle() {
    let dir = workspace();
    let text = with_contact("obstacle = { type = \"sphere\", center = [0, 2, 0], radius = 1.5 }");
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(
        s.contact.as_ref().unwrap().obstacles[0].shape,
        Shape::Sphere { center: vec![0.0, 2.0, 0.0], radius: 1.5 }
    );
    assert_eq!(
        s.effects().contact,
        vec![ObstacleEffect { kind: ObstacleKind::Sphere, moving: false }]
    );
    s.check_dim(3).unwrap();
    let m = s.check_dim(2).unwrap_err().to_string();
    assert!(m.contains("contact.obstacle.center has 3 components but the mesh is 2D"), "{m}");
    // As a sub-table instead of an inline table.
    let text = with_contact("[contact.obstacle]\ntype = \"sphere\"\ncenter = [0, 2]\nradius = 1");
    parse_in(&dir, &text).unwrap();
}

#[test]
fn moving_cylinder_among_several_obstacles() {
    let dir = workspace();
    let text = with_contact(
        "obstacles = [\n  { type = \"plane\", point = [0, 0, 0], normal = [0, 0, 2], motion = [0, \"0*t\", \"t^2\"] },\n  { type = \"cylinder\", point = [0, 0, 3], axis = [0, 3, 4], radius = 0.5 },\n  { type = \"sphere\", center = [0, 0, 9], radius = 1, motion = [1, 2, 3] },\n]",
    );
    let s = parse_in(&dir, &text).unwrap();
    let c = s.contact.as_ref().unwrap();
    assert!(c.listed && c.obstacles.len() == 3);
    assert_eq!(c.obstacle_key(2), "contact.obstacles[2]");
    assert_eq!(
        c.obstacles[1].shape,
        Shape::Cylinder { point: vec![0.0, 0.0, 3.0], axis: vec![0.0, 0.6, 0.8], radius: 0.5 }
    );
    let d = c.obstacles[0].motion.as_ref().unwrap();
    assert_eq!(d.eval([0.0; 3], 3.0), [0.0, 0.0, 9.0]);
    // A constant motion only shifts the sphere: it is not "moving".
    let moving: Vec<bool> = c.obstacles.iter().map(Obstacle::is_moving).collect();
    assert_eq!(moving, [true, false, false]);
    let line = s.effects().summary();
    assert!(
        line.contains(", contact (3 obstacles: moving plane, cylinder, sphere); not built:"),
        "{line}"
    );
    s.check_dim(3).unwrap();
    let m = s.check_dim(2).unwrap_err().to_string();
    assert!(m.contains("contact.obstacles[1] is a cylinder but the mesh is 2D"), "{m}");
    // One moving obstacle.
    let text = with_contact(
        "obstacle = { type = \"plane\", point = [0, 1], normal = [0, -1], motion = [\"0\", \"-1e-3*t\"] }",
    );
    let line = parse_in(&dir, &text).unwrap().effects().summary();
    assert!(line.contains(", contact (moving plane obstacle); not built:"), "{line}");
    // As an array of tables.
    let text = with_contact(
        "[[contact.obstacles]]\ntype = \"sphere\"\ncenter = [0, 2]\nradius = 1\n[[contact.obstacles]]\ntype = \"plane\"\npoint = [0, 0]\nnormal = [0, 1]\nmotion = [\"t\", 0]",
    );
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.contact.as_ref().unwrap().obstacles.len(), 2);
    s.check_dim(2).unwrap();
}

#[test]
fn obstacle_errors_name_the_key() {
    let plane = "{ type = \"plane\", point = [0, 0], normal = [0, 1] }";
    let cases: &[(&str, &[&str])] = &[
        (
            "obstacles = [{ type = \"cylinder\", point = [0, 0, 0], axis = [0, 0, 0], radius = 1 }]",
            &["contact.obstacles[0].axis = [0.0, 0.0, 0.0] is impossible: the axis must be nonzero"],
        ),
        (
            "obstacle = { type = \"cylinder\", point = [0, 0, 0], axis = [0, 1, 0], radius = -2 }",
            &["contact.obstacle.radius = -2 is impossible: the radius must be > 0"],
        ),
        (
            "obstacle = { type = \"cylinder\", point = [0, 0], axis = [0, 1], radius = 1 }",
            &["contact.obstacle.point has 2 components: a cylinder exists in 3D only"],
        ),
        (
            "obstacle = { type = \"plane\", point = [0, 0], normal = [0, 1], motion = [\"0\", \"-y*t\"] }",
            &["contact.obstacle.motion[1] = \"-y*t\" is impossible: a motion is a function of t only"],
        ),
        (
            "obstacle = { type = \"plane\", point = [0, 0], normal = [0, 1], motion = [] }",
            &["contact.obstacle.motion is empty"],
        ),
        (
            "obstacles = []",
            &["contact.obstacles is empty: give at least one obstacle"],
        ),
        (
            "boundary2 = 1",
            &["unknown key \"contact.boundary2\"", "allowed: boundary, slave, master, pairs, obstacle, obstacles"],
        ),
        (
            "obstacles = [{ type = \"cone\", point = [0, 0] }]",
            &["\"cone\" is not allowed", "allowed: plane, sphere, cylinder"],
        ),
    ];
    for (o, needles) in cases {
        assert_err(&with_contact(o), needles);
    }
    assert_err(
        &with_contact(&format!("obstacle = {plane}\nobstacles = [{plane}]")),
        &["contact: give exactly one of contact.obstacle and contact.obstacles, not both"],
    );
    assert_err(
        &with_contact(""),
        &[
            "contact: give the obstacle (contact.obstacle = ",
            "or a list of them (contact.obstacles",
        ],
    );
    // Found against the mesh's dimension.
    let dir = workspace();
    let dim_error = |o: &str, dim: usize| {
        let s = parse_in(&dir, &with_contact(o)).unwrap();
        let m = s.check_dim(dim).unwrap_err().to_string();
        assert!(!m.contains('\n'), "{m}");
        m
    };
    let m = dim_error(
        "obstacle = { type = \"cylinder\", point = [0, 0, 0], axis = [0, 1, 0], radius = 1 }",
        2,
    );
    assert!(m.contains("contact.obstacle is a cylinder but the mesh is 2D"), "{m}");
    let m = dim_error(
        &format!("obstacles = [{plane}, {{ type = \"sphere\", center = [0, 0], radius = 1, motion = [0, 0, \"t\"] }}]"),
        2,
    );
    assert!(m.contains("contact.obstacles[1].motion has 3 components but the mesh is 2D"), "{m}");
}

#[test]
fn unknown_keys() {
    assert_err(
        &format!("materail = 3\n{MINIMAL}"),
        &["unknown key \"materail\"", "allowed: name, mesh, material, body, dirichlet"],
    );
    let m = err_of(&minimal_with("[material]", "[materail]\nE=1\n[material]"));
    assert!(m.contains("unknown key \"materail\""), "{m}");
    assert_err(
        &minimal_with("rho = 2", "rho = 2\nrho2 = 3"),
        &["unknown key \"material.rho2\" (allowed: E, nu, rho, model, formulation)", "(line 8)"],
    );
    assert_err(
        &minimal_with("E = 1", "e = 1"),
        &["unknown key \"material.e\" (allowed: E, nu, rho, model, formulation)"],
    );
    assert_err(
        &full_with("group = \"clamp\"", "group = \"clamp\"\nvalues = [1]"),
        &["unknown key \"dirichlet[1].values\"", "allowed: group, value, components"],
    );
    assert_err(
        &full_with("normal = [0.0, 2.0]", "normal = [0.0, 2.0], foo = 1"),
        &["unknown key \"contact.obstacle.foo\"", "allowed: point, normal"],
    );
    assert_err(
        &full_with("params = { h = 0.25, n = 4 }", "param = { h = 0.25 }"),
        &["unknown key \"mesh.param\"", "allowed: geo, msh, params, binary"],
    );
    assert_err(
        &full_with("progress = true", "progres = true"),
        &["unknown key \"output.progres\""],
    );
}

#[test]
fn wrong_types_and_values() {
    assert_err(
        &minimal_with("E = 1", "E = \"big\""),
        &["material.E has the wrong type", "expected a number", "(line 5)"],
    );
    assert_err(
        &minimal_with("steps = 10", "steps = 2.5"),
        &["time.steps has the wrong type", "expected an integer"],
    );
    assert_err(
        &full_with("value = [0, \"1e-3*t\"]", "value = [0, true]"),
        &["dirichlet[1].value has the wrong type", "expression string or a number"],
    );
    assert_err(
        &full_with("kind = \"modified1\"", "kind = \"heavy\""),
        &[
            "mass.kind = \"heavy\" is not allowed",
            "allowed: consistent, lumped, modified0, modified1",
        ],
    );
    assert_err(
        &full_with("fields = [\"velocity\"]", "fields = [\"velocity\", \"tension\"]"),
        &[
            "output.fields = \"tension\" is not allowed",
            "allowed: displacement, velocity, stress, strain, von_mises, effective_stress, \
             pressure, stress_nodal, strain_nodal, von_mises_nodal, effective_stress_nodal, \
             pressure_nodal",
        ],
    );
    // A near miss of a stress field is named as given.
    assert_err(
        &full_with("fields = [\"velocity\"]", "fields = [\"vonmises\"]"),
        &["output.fields = \"vonmises\" is not allowed", "von_mises_nodal"],
    );
    assert_err(
        &full_with("components = [\"y\", \"x\"]", "components = [\"w\"]"),
        &["dirichlet[0].components = \"w\" is not allowed", "allowed: x, y, z"],
    );
    assert_err(
        &full_with("type = \"plane\"", "type = \"cone\""),
        &["contact.obstacle", "\"cone\" is not allowed", "allowed: plane, sphere, cylinder"],
    );
    assert_err(&minimal_with("rho = 2\n", ""), &["missing key \"material.rho\""]);
    assert_err(
        &full_with("traction = [\"0\", \"-1e-3*sin(2*pi*t)\"]", ""),
        &["missing key \"neumann[0].traction\""],
    );
    assert_err(
        &full_with(", normal = [0.0, 2.0]", ""),
        &["missing key \"contact.obstacle.normal\""],
    );
    assert_err(&MINIMAL.replace("[time]\ntau = 0.1\nsteps = 10\n", ""), &["missing key \"time\""]);
    assert_err("[mesh\n", &["invalid TOML", "line 1"]);
    // A misplaced key lands in the table above it, and the message says so.
    assert_err(
        &minimal_with("[material]", "materail = 3\n[material]"),
        &["unknown key \"mesh.materail\" (allowed: geo, msh, params, binary)"],
    );
    assert_err(
        &minimal_with("rho = 2", "rho = 2\nrho = 3"),
        &["invalid TOML", "duplicate key", "line 8"],
    );
}

#[test]
fn impossible_values() {
    let cases: &[(&str, &str, &[&str])] = &[
        ("E = 1", "E = 0", &["material.E = 0 is impossible", "> 0"]),
        ("E = 1", "E = -3", &["material.E = -3 is impossible"]),
        (
            "nu = 0.25",
            "nu = 0.5",
            &["material.nu = 0.5 is impossible: Poisson's ratio must be in (-1, 0.5)"],
        ),
        ("nu = 0.25", "nu = -1", &["material.nu = -1 is impossible"]),
        ("nu = 0.25", "nu = nan", &["material.nu = NaN is impossible"]),
        ("rho = 2", "rho = 0", &["material.rho = 0 is impossible"]),
        ("tau = 0.1", "tau = 0", &["time.tau = 0 is impossible: the time step must be > 0"]),
        ("steps = 10", "steps = 0", &["time.steps = 0 is impossible", ">= 1"]),
        ("steps = 10", "steps = -4", &["time.steps = -4 is impossible"]),
        ("steps = 10", "steps = 10\nend = 1.0", &["time: give exactly one of steps and end"]),
        ("steps = 10", "", &["time: give the number of steps", "time.end"]),
        ("steps = 10", "end = 1.05", &["time.end = 1.05 is impossible", "whole number of steps"]),
        ("steps = 10", "end = 0", &["time.end = 0 is impossible"]),
        ("steps = 10", "end = 0.01", &["time.end = 0.01 is impossible", "shorter than one step"]),
        (
            "msh = \"../meshes/beam.msh\"",
            "msh = \"../meshes/beam.msh\"\ngeo = \"../meshes/beam.geo\"",
            &["mesh: give exactly one of geo and msh"],
        ),
        (
            "msh = \"../meshes/beam.msh\"",
            "binary = true",
            &["mesh: give exactly one of geo", "msh"],
        ),
        (
            "msh = \"../meshes/beam.msh\"",
            "msh = \"../meshes/nope.msh\"",
            &["mesh.msh = \"../meshes/nope.msh\": file not found: ", "meshes/nope.msh"],
        ),
        (
            "msh = \"../meshes/beam.msh\"",
            "geo = \"nope.geo\"",
            &["mesh.geo = \"nope.geo\": file not found", "scenes/nope.geo"],
        ),
        (
            "msh = \"../meshes/beam.msh\"",
            "msh = \"../meshes/beam.msh\"\nparams = { h = 1 }",
            &["mesh.params only applies to mesh.geo"],
        ),
        (
            "msh = \"../meshes/beam.msh\"",
            "msh = \"../meshes/beam.msh\"\nbinary = false",
            &["mesh.binary only applies to mesh.geo"],
        ),
    ];
    for (from, to, needles) in cases {
        assert_err(&minimal_with(from, to), needles);
    }
    let more = [
        "[mass]\nkind = \"modified0\"\n",
        "[output]\nevery = 0\n",
        "[solver]\nrtol = 1.5\n",
        "[exact]\ndisplacement = [\"0\", \"0\"]\nerror_steps = [11]\n",
        "[exact]\ndisplacement = [\"0\", \"0\"]\nerror_steps = [-1]\n",
        "[contact]\nboundary = \"c\"\nobstacle = { type = \"plane\", point = [0, 0], normal = [0, 0] }\n",
        "[contact]\nboundary = \"c\"\nobstacle = { type = \"sphere\", center = [0, 0], radius = 0 }\n",
        "[contact]\nboundary = \"c\"\nobstacle = { type = \"sphere\", center = [0], radius = 1 }\n",
        "[[dirichlet]]\ngroup = \"\"\n",
        "[[dirichlet]]\ngroup = \"a\"\ncomponents = [\"x\", \"x\"]\n",
        "[body_force]\nvalue = []\n",
        "[body_force]\nvalue = [1, 2, 3, 4]\n",
    ];
    let needles: [&[&str]; 12] = [
        &["mass.kind = modified0 needs mass.contact_boundary (or a [contact] section): the mass-free layer is built along the potential contact boundary"],
        &["output.every = 0 is impossible"],
        &["solver.rtol = 1.5 is impossible", "(0, 1)"],
        &["exact.error_steps contains 11", "time.steps = 10"],
        &["exact.error_steps contains -1"],
        &["contact.obstacle.normal = [0.0, 0.0] is impossible: the normal must be nonzero"],
        &["contact.obstacle.radius = 0 is impossible: the radius must be > 0"],
        &["contact.obstacle.center has 1 components"],
        &["dirichlet[0].group is empty"],
        &["dirichlet[0].components lists a component twice"],
        &["body_force.value is empty"],
        &["body_force.value has 4 components"],
    ];
    for (extra, needles) in more.iter().zip(needles.iter()) {
        assert_err(&format!("{MINIMAL}\n{extra}"), needles);
    }
}

#[test]
fn bad_expressions_name_key_and_index() {
    assert_err(
        &full_with(
            "traction = [\"0\", \"-1e-3*sin(2*pi*t)\"]",
            "traction = [\"0\", \"3*sinn(t)\"]",
        ),
        &["neumann[0].traction[1]: unknown function 'sinn' at column 3"],
    );
    assert_err(
        &full_with("value = [\"0\", \"0.02*x", "value = [\"q\", \"0.02*x"),
        &["body_force.value[0]: unknown variable 'q' at column 1"],
    );
    assert_err(
        &full_with("velocity = [\"0\", \"x*(10-x)\"]", "velocity = [\"0\", \"x*(10-x))\"]"),
        &["initial.velocity[1]: unmatched ')' at column 9"],
    );
    assert_err(
        &full_with(
            "gradient = [[\"0\", \"0\"], [\"t\", \"0\"]]",
            "gradient = [[\"0\", \"0\"], [\"t\", \"1+\"]]",
        ),
        &["exact.gradient[1][1]: unexpected end of expression"],
    );
    assert_err(
        &full_with("value = [0, \"1e-3*t\"]", "value = [0, \"\"]"),
        &["dirichlet[1].value[1]: empty expression"],
    );
}

#[test]
fn check_dim_names_the_key() {
    let dir = workspace();
    let s = parse_in(&dir, FULL).unwrap();
    let m = s.check_dim(3).unwrap_err().to_string();
    assert!(m.starts_with("scene error: beam.toml: "), "{m}");
    assert!(m.contains("has 2 components but the mesh is 3D"), "{m}");
    assert!(s.check_dim(1).is_err());

    let text = format!("{MINIMAL}\n[initial]\nvelocity = [\"0\", \"0\", \"1\"]\n");
    let s = parse_in(&dir, &text).unwrap();
    s.check_dim(3).unwrap();
    let m = s.check_dim(2).unwrap_err().to_string();
    assert!(m.contains("initial.velocity has 3 components but the mesh is 2D"), "{m}");

    let text = format!("{MINIMAL}\n[[dirichlet]]\ngroup = \"a\"\ncomponents = [\"z\"]\n");
    let s = parse_in(&dir, &text).unwrap();
    s.check_dim(3).unwrap();
    let m = s.check_dim(2).unwrap_err().to_string();
    assert!(m.contains("dirichlet[0].components includes \"z\" but the mesh is 2D"), "{m}");

    let text =
        format!("{MINIMAL}\n[exact]\ndisplacement = [0, 0]\ngradient = [[0, 0], [0, 0], [0, 0]]\n");
    let m = parse_in(&dir, &text).unwrap().check_dim(2).unwrap_err().to_string();
    assert!(m.contains("exact.gradient has 3 rows but the mesh is 2D"), "{m}");
    let text = format!("{MINIMAL}\n[exact]\ndisplacement = [0, 0]\ngradient = [[0, 0], [0]]\n");
    let m = parse_in(&dir, &text).unwrap().check_dim(2).unwrap_err().to_string();
    assert!(m.contains("exact.gradient[1] has 1 components"), "{m}");
}

#[test]
fn effects_follow_the_scene() {
    let dir = workspace();
    let s = parse_in(&dir, FULL).unwrap();
    let varying = Some(Variation::TimeDependent);
    assert_eq!(
        s.effects(),
        Effects {
            mass: MassKind::Modified1,
            standard_masses: vec![],
            layer: Some((MassKind::Modified1, "\"bottom\"".into())),
            bodies: vec![],
            finite_strain: None,
            mixed: false,
            initial_displacement: false,
            initial_velocity: true,
            body_force: varying,
            tractions: varying,
            dirichlet: true,
            dirichlet_lifting: varying,
            contact: vec![ObstacleEffect { kind: ObstacleKind::Plane, moving: false }],
            exact_errors: true,
            contact_pairs: Vec::new(),
            contact_obstacle_boundary: None,
            friction: Vec::new(),
            stress_fields: Vec::new(),
        }
    );
    let text = format!(
        "{MINIMAL}\n[body_force]\nvalue = [0, \"0.0\"]\n[[neumann]]\ngroup = \"top\"\ntraction = [\"0\", \"-2*x\"]\n[[neumann]]\ngroup = \"side\"\ntraction = [0, 0]\n[[dirichlet]]\ngroup = \"left\"\n[[dirichlet]]\ngroup = \"right\"\nvalue = [\"0\", \"0.1\"]\n[mass]\nkind = \"lumped\"\ncontact_boundary = \"bottom\"\n"
    );
    let s = parse_in(&dir, &text).unwrap();
    assert!(s.body_force.as_ref().unwrap().is_zero());
    assert_eq!(
        s.effects(),
        Effects {
            mass: MassKind::Lumped,
            standard_masses: vec![MassKind::Lumped],
            layer: None, // no layer for a lumped mass, though a boundary is named
            bodies: vec![],
            finite_strain: None,
            mixed: false,
            initial_displacement: false,
            initial_velocity: false,
            body_force: None,
            tractions: Some(Variation::Steady),
            dirichlet: true,
            dirichlet_lifting: Some(Variation::Steady),
            contact: vec![],
            exact_errors: false,
            contact_pairs: Vec::new(),
            contact_obstacle_boundary: None,
            friction: Vec::new(),
            stress_fields: Vec::new(),
        }
    );
    assert_eq!(
        s.effects().summary(),
        "effects: elasticity, lumped mass, tractions (steady), Dirichlet (non-zero values), Dirichlet lifting (steady); not built: mass-free layer, initial displacement, initial velocity, body force, contact, friction, exact errors, stress output"
    );
}

#[test]
fn effects_summary_lines() {
    let dir = workspace();
    let s = parse_in(&dir, FULL).unwrap();
    assert_eq!(
        s.effects().summary(),
        "effects: elasticity, mass-free layer (modified1 along \"bottom\"), initial velocity, body force (time-dependent), tractions (time-dependent), Dirichlet (non-zero values), Dirichlet lifting (time-dependent), contact (plane obstacle), exact errors; not built: initial displacement, friction, stress output"
    );
    let all = full_with("displacement = [\"0\", \"0\"]", "displacement = [\"0\", \"1e-3*x\"]");
    let line = parse_in(&dir, &all).unwrap().effects().summary();
    assert!(line.starts_with("effects: elasticity, mass-free layer"), "{line}");
    assert!(line.contains(", initial displacement, initial velocity, "), "{line}");
    assert!(line.ends_with("exact errors; not built: friction, stress output"), "{line}");
    // Stress-type fields asked for: item 12, with their names in the scene's order.
    let stressed = all.replace(
        "fields = [\"velocity\"]",
        "fields = [\"von_mises\", \"displacement\", \"stress_nodal\"]",
    );
    let line = parse_in(&dir, &stressed).unwrap().effects().summary();
    assert!(
        line.ends_with(
            "exact errors, stress output (von_mises, stress_nodal); not built: friction"
        ),
        "{line}"
    );
    // The layer along the contact boundary (the default), zero Dirichlet values: no lifting.
    let text = format!(
        "{MINIMAL}\n[[dirichlet]]\ngroup = \"left\"\nvalue = [\"0\", \"2-2\"]\n[mass]\nkind = \"modified1\"\n[contact]\nboundary = \"contact\"\nobstacle = {{ type = \"plane\", point = [0, 0], normal = [0, 1] }}\n[initial]\nvelocity = [0, 0]\n"
    );
    let line = parse_in(&dir, &text).unwrap().effects().summary();
    assert_eq!(
        line,
        "effects: elasticity, mass-free layer (modified1 along \"contact\"), Dirichlet (zero values), contact (plane obstacle); not built: initial displacement, initial velocity, body force, tractions, Dirichlet lifting, friction, exact errors, stress output"
    );
    assert!(!line.contains('\n'));
}

#[test]
fn error_paths_in_multiline_arrays() {
    let text =
        format!("{MINIMAL}\n[[neumann]]\ngroup = \"top\"\ntraction = [\n  \"0\",\n  false,\n]\n");
    assert_err(&text, &["neumann[0].traction has the wrong type", "(line 16)"]);
}

#[test]
fn overrides_of_time_and_error_steps_follow_the_scene_rules() {
    let dir = workspace();
    let mut s = parse_in(&dir, FULL).unwrap();
    assert_eq!((s.steps, s.exact.as_ref().unwrap().error_steps.clone()), (250, vec![10, 30]));
    // set_tau: steps = end / tau by the rule of time.end, listed error steps kept in the run.
    s.set_tau(2e-5, 1e-3).unwrap();
    assert_eq!((s.tau, s.steps), (2e-5, 50));
    assert_eq!(steps_to_end(1e-3, 2e-5), Ok(50));
    for (tau, end) in [(0.3, 1.0), (0.1, 0.01)] {
        let m = s.clone().set_tau(tau, end).unwrap_err().to_string();
        let from_text =
            err_of(&minimal_with("tau = 0.1\nsteps = 10", &format!("tau = {tau}\nend = {end}")));
        assert_eq!(m, from_text, "the same rule and message as time.end");
    }
    s.set_steps(20).unwrap();
    assert_eq!(s.exact.as_ref().unwrap().error_steps, vec![10]);
    s.add_error_step(20).unwrap();
    assert_eq!(s.exact.as_ref().unwrap().error_steps, vec![10, 20]);
    assert!(s
        .add_error_step(21)
        .unwrap_err()
        .to_string()
        .contains("exact.error_steps contains 21"));
    assert!(s.set_steps(0).unwrap_err().to_string().contains("time.steps = 0 is impossible"));
    // Without listed error steps the default (the last step) follows; an added step replaces it.
    let text = format!("{MINIMAL}\n[exact]\ndisplacement = [\"x\", 0]\n[output]\ntimes = [0.5]\n");
    let mut s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.output.time_steps, vec![5]);
    s.set_tau(0.05, 1.0).unwrap();
    assert_eq!((s.steps, s.exact.as_ref().unwrap().error_steps.clone()), (20, vec![20]));
    assert_eq!(s.output.time_steps, vec![10]);
    s.add_error_step(5).unwrap();
    assert_eq!(s.exact.as_ref().unwrap().error_steps, vec![5]);
    let m = s.set_steps(2).unwrap_err().to_string();
    assert!(m.contains("output.times[0] = 0.5 is impossible"), "{m}");
}

#[test]
fn variant_text_parses_back_to_the_overridden_scene() {
    let dir = workspace();
    let elsewhere = dir.join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    let mut s = parse_in(&dir, FULL).unwrap();
    s.set_mesh_param("h=0.125").unwrap();
    s.set_mass_kind("modified0").unwrap();
    s.set_tau(2e-5, 1e-3).unwrap();
    s.add_error_step(50).unwrap();
    s.output.every = 7;
    s.output.fields = vec![Field::Displacement];
    let v = parse(&s.variant_text().unwrap(), "copy.toml", &elsewhere).unwrap();
    assert_eq!(v.name, "beam");
    let MeshSource::Geo { path, params, binary } = &v.mesh else { panic!("{:?}", v.mesh) };
    assert_eq!(*path, dir.join("meshes/beam.geo").canonicalize().unwrap());
    assert_eq!((params.clone(), *binary), (vec![("h".into(), 0.125), ("n".into(), 4.0)], true));
    assert_eq!((v.tau, v.steps), (2e-5, 50));
    assert_eq!(v.mass, s.mass);
    assert_eq!(v.exact.as_ref().unwrap().error_steps, vec![10, 30, 50]);
    assert_eq!(v.output, s.output);
    assert_eq!((v.material, v.solver, v.contact), (s.material, s.solver, s.contact));
    // A .msh scene without [output] or [mass].
    let s = parse_in(&dir, MINIMAL).unwrap();
    let v = parse(&s.variant_text().unwrap(), "copy.toml", &elsewhere).unwrap();
    let msh = dir.join("meshes/beam.msh").canonicalize().unwrap();
    assert_eq!(v.mesh, MeshSource::Msh { path: msh });
    assert_eq!((v.name, v.steps, v.output, v.mass), (s.name, s.steps, s.output, s.mass));
}

#[test]
fn contact_pairs_of_two_bodies() {
    let dir = workspace();
    let pair = |rest: &str| format!("{MINIMAL}\n[contact]\n{rest}\n");
    let s = parse_in(
        &dir,
        &format!("{}[mass]\nkind = \"modified1\"\n", pair("slave = \"a\"\nmaster = \"b\"")),
    )
    .unwrap();
    let c = s.contact.as_ref().unwrap();
    assert_eq!(
        c.pairs,
        vec![ContactPair { slave: "a".into(), master: "b".into(), friction: None }]
    );
    assert_eq!(c.boundary, None);
    assert!(c.obstacles.is_empty());
    // The layer runs along both sides unless the scene names its group.
    assert_eq!(s.mass.layer_groups(), vec!["a", "b"]);
    assert!(s.effects().summary().contains(
        "mass-free layer (modified1 along \"a\" and \"b\"), contact (two bodies, slave \"a\" on master \"b\", dual mortar)"
    ));
    let named = format!(
        "{}[mass]\nkind = \"modified1\"\ncontact_boundary = \"a\"\n",
        pair("slave = \"a\"\nmaster = \"b\"")
    );
    assert_eq!(parse_in(&dir, &named).unwrap().mass.layer_groups(), vec!["a"]);
    // Rigid obstacles beside the pair, met by the nodes of contact.boundary.
    let mixed = format!(
        "{}[mass]\nkind = \"modified1\"\n",
        pair("slave = \"a\"\nmaster = \"b\"\nboundary = \"c\"\nobstacle = { type = \"plane\", point = [0, 0], normal = [0, -1] }")
    );
    let s = parse_in(&dir, &mixed).unwrap();
    let c = s.contact.as_ref().unwrap();
    assert_eq!((c.pairs[0].slave.as_str(), c.obstacle_boundary()), ("a", Some("c")));
    assert_eq!(c.obstacles.len(), 1);
    assert_eq!(s.mass.layer_groups(), vec!["a", "b", "c"]);
    assert!(s.effects().summary().contains(
        "contact (two bodies, slave \"a\" on master \"b\", dual mortar; \"c\" on plane obstacle)"
    ), "{}", s.effects().summary());
    let plane = "{ type = \"plane\", point = [0, 0], normal = [0, 1] }";
    let cases: Vec<(String, &str)> = vec![
        (pair("slave = \"a\""), "contact.slave needs contact.master"),
        (pair("master = \"b\""), "contact.master needs contact.slave"),
        (
            pair("slave = \"a\"\nmaster = \"a\""),
            "contact.slave and contact.master are the same group \"a\"",
        ),
        (
            pair(&format!("slave = \"a\"\nmaster = \"b\"\nobstacle = {plane}")),
            "obstacles beside a slave/master pair need contact.boundary",
        ),
        (
            pair("boundary = \"c\"\nslave = \"a\"\nmaster = \"b\""),
            "contact.boundary = \"c\" beside a slave/master pair needs the obstacles it meets",
        ),
        (
            pair(&format!("boundary = \"a\"\nslave = \"a\"\nmaster = \"b\"\nobstacle = {plane}")),
            "contact.boundary = \"a\" is also contact.slave",
        ),
        (
            pair(&format!("boundary = \"b\"\nslave = \"a\"\nmaster = \"b\"\nobstacle = {plane}")),
            "contact.boundary = \"b\" is also contact.master",
        ),
        (
            pair(&format!(
                "boundary = \"c\"\nslave = \"a\"\nmaster = \"b\"\nobstacle = {plane}\nobstacles = [{plane}]"
            )),
            "give exactly one of contact.obstacle and contact.obstacles",
        ),
        (pair("boundary = \"c\"\nslave = \"a\""), "contact.slave needs contact.master"),
        (pair(""), "give contact.boundary (with an obstacle) or contact.slave and contact.master"),
    ];
    for (text, needle) in &cases {
        assert_err(text, &[needle]);
    }
}

#[test]
fn several_contact_pairs() {
    let dir = workspace();
    let pairs = |list: &str| format!("{MINIMAL}\n[contact]\npairs = [{list}]\n");
    let two = pairs("{ slave = \"a\", master = \"m\" }, { slave = \"b\", master = \"m2\" }");
    let s = parse_in(&dir, &format!("{two}[mass]\nkind = \"modified1\"\n")).unwrap();
    let c = s.contact.as_ref().unwrap();
    let p = |a: &str, b: &str| ContactPair { slave: a.into(), master: b.into(), friction: None };
    assert_eq!(c.pairs, vec![p("a", "m"), p("b", "m2")]);
    assert_eq!((c.slave_groups(), c.master_groups()), (vec!["a", "b"], vec!["m", "m2"]));
    // The layer runs along every contact group.
    assert_eq!(s.mass.layer_groups(), vec!["a", "b", "m", "m2"]);
    assert!(s.effects().summary().contains(
        "contact (2 pairs: slave \"a\" on master \"m\", slave \"b\" on master \"m2\", dual mortar)"
    ), "{}", s.effects().summary());
    // One master for two slaves, one slave on two masters.
    let shared = pairs("{ slave = \"a\", master = \"m\" }, { slave = \"b\", master = \"m\" }, { slave = \"a\", master = \"m2\" }");
    let c = parse_in(&dir, &shared).unwrap().contact.unwrap();
    assert_eq!((c.slave_groups(), c.master_groups()), (vec!["a", "b"], vec!["m", "m2"]));
    let plane = "{ type = \"plane\", point = [0, 0], normal = [0, 1] }";
    let cases: Vec<(String, &str)> = vec![
        (pairs(""), "contact.pairs is empty"),
        (pairs("{ slave = \"a\" }"), "contact.pairs[0] needs master"),
        (pairs("{ master = \"a\" }"), "contact.pairs[0] needs slave"),
        (pairs("{ slave = \"a\", master = \"a\" }"), "contact.pairs[0]: slave and master are the same group \"a\""),
        (pairs("{ slave = \"a\", master = \"\" }"), "contact.pairs[0].master is empty"),
        (pairs("{ slave = \"a\", master = \"b\", other = \"c\" }"), "unknown key"),
        (
            pairs("{ slave = \"a\", master = \"b\" }, { slave = \"a\", master = \"b\" }"),
            "contact.pairs[1] repeats contact.pairs[0]",
        ),
        (
            pairs("{ slave = \"a\", master = \"b\" }, { slave = \"b\", master = \"c\" }"),
            "contact.pairs[1].slave = \"b\" is also contact.pairs[0].master",
        ),
        (
            format!("{MINIMAL}\n[contact]\nslave = \"a\"\nmaster = \"b\"\npairs = [{{ slave = \"c\", master = \"d\" }}]\n"),
            "give either contact.slave and contact.master (one pair) or contact.pairs",
        ),
        (
            format!("{}boundary = \"b\"\nobstacle = {plane}\n", pairs("{ slave = \"a\", master = \"b\" }")),
            "contact.boundary = \"b\" is also a contact.pairs[].master",
        ),
    ];
    for (text, needle) in &cases {
        assert_err(text, &[needle]);
    }
}

/// MINIMAL with `[[body]]` tables (and whatever else `rest` holds) appended.
fn with_bodies(rest: &str) -> String {
    format!("{MINIMAL}\n{rest}\n")
}

#[test]
fn bodies_take_their_own_values_over_the_material() {
    let dir = workspace();
    let text = with_bodies(
        "[[body]]\ngroup = \"lower\"\nE = 400\nmass = \"consistent\"\n[[body]]\ngroup = \"upper\"\nrho = 3e-8\nnu = 0.1\n[[body]]\ngroup = \"plain\"\n[mass]\nkind = \"modified1\"\ncontact_boundary = \"c\"\n",
    );
    let mut s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.bodies.len(), 3);
    let (lower, upper) = (&s.bodies[0], &s.bodies[1]);
    assert_eq!(lower.group, "lower");
    assert_eq!(
        lower.material,
        MaterialSpec {
            e: 400.0,
            nu: 0.25,
            rho: 2.0,
            model: Model::Linear,
            formulation: Formulation::Displacement
        }
    );
    assert_eq!(lower.sets, [true, false, false, false]);
    assert_eq!(
        upper.material,
        MaterialSpec {
            e: 1.0,
            nu: 0.1,
            rho: 3e-8,
            model: Model::Linear,
            formulation: Formulation::Displacement
        }
    );
    assert_eq!(upper.sets, [false, true, true, false]);
    assert_eq!(s.bodies[2].material, s.material);
    // The body's own mass, else mass.kind, which --mass replaces.
    assert_eq!(s.body_mass(0), MassKind::Consistent);
    assert_eq!(s.body_mass(1), MassKind::Modified1);
    s.set_mass_kind("lumped").unwrap();
    assert_eq!((s.body_mass(0), s.body_mass(1)), (MassKind::Consistent, MassKind::Lumped));
    // A scene without bodies has none.
    assert!(parse_in(&dir, MINIMAL).unwrap().bodies.is_empty());
}

#[test]
fn body_errors_name_the_key() {
    let body = |rest: &str| with_bodies(&format!("[[body]]\ngroup = \"a\"\n[[body]]\n{rest}"));
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            body("group = \"b\"\nE = -1"),
            vec!["body[1].E = -1 is impossible: Young's modulus must be > 0"],
        ),
        (body("group = \"b\"\nnu = 0.5"), vec!["body[1].nu = 0.5 is impossible"]),
        (
            body("group = \"b\"\nrho = 0"),
            vec!["body[1].rho = 0 is impossible: the density must be > 0"],
        ),
        (body("group = \"\""), vec!["body[1].group is empty"]),
        (body("group = \"a\""), vec!["body[1].group = \"a\" is also body[0].group"]),
        (body("E = 3"), vec!["missing key \"body[1].group\""]),
        (
            body("group = \"b\"\ndensity = 3"),
            vec![
                "unknown key \"body[1].density\"",
                "allowed: group, E, nu, rho, mass, model, formulation",
            ],
        ),
        (
            body("group = \"b\"\nmass = \"heavy\""),
            vec!["body[1].mass = \"heavy\" is not allowed", "consistent"],
        ),
        (body("group = \"b\"\nE = \"big\""), vec!["body[1].E has the wrong type"]),
        // A modified mass needs a group to build the layer along.
        (
            body("group = \"b\"\nmass = \"modified1\""),
            vec!["body[1].mass = modified1 needs mass.contact_boundary (or a [contact] section)"],
        ),
    ];
    for (text, needles) in &cases {
        assert_err(text, needles);
    }
    // With a contact boundary, a modified body is fine; [material] is still checked alone.
    let dir = workspace();
    let ok = format!(
        "{}\n[mass]\ncontact_boundary = \"c\"\n",
        body("group = \"b\"\nmass = \"modified0\"")
    );
    assert_eq!(parse_in(&dir, &ok).unwrap().body_mass(1), MassKind::Modified0);
    assert_err(
        &minimal_with("E = 1", "E = 0").replace("[time]", "[[body]]\ngroup = \"a\"\nE = 5\n[time]"),
        &["material.E = 0 is impossible"],
    );
}

#[test]
fn effects_name_the_bodies() {
    let dir = workspace();
    let pair = "[contact]\nslave = \"a\"\nmaster = \"b\"\n";
    // Same mass everywhere: the layer is known without the mesh.
    let text = with_bodies(&format!(
        "[[body]]\ngroup = \"lower\"\nE = 400\n[[body]]\ngroup = \"upper\"\nrho = 2e-8\n[mass]\nkind = \"modified1\"\n{pair}"
    ));
    let line = parse_in(&dir, &text).unwrap().effects().summary();
    assert!(
        line.starts_with("effects: elasticity, bodies (\"lower\": E = 400; \"upper\": rho = 2e-8), mass-free layer (modified1 along \"a\" and \"b\"), contact"),
        "{line}"
    );
    assert!(!line.contains("not built: bodies") && !line.contains(", bodies,"), "{line}");
    // Mixed kinds: which group is on which body needs the mesh; resolved, the line states it.
    let text = with_bodies(&format!(
        "[[body]]\ngroup = \"lower\"\nmass = \"consistent\"\n[mass]\nkind = \"modified1\"\n{pair}"
    ));
    let e = parse_in(&dir, &text).unwrap().effects();
    assert_eq!(e.bodies, vec!["\"lower\": mass consistent".to_string()]);
    assert!(
        e.summary().contains(
            "consistent mass, mass-free layer (modified1 along \"a\" and \"b\", on the bodies with that mass)"
        ),
        "{}",
        e.summary()
    );
    let b = ["b".to_string()];
    let resolved = e.resolve(vec![MassKind::Consistent], Some((MassKind::Modified1, &b[..])));
    assert!(
        resolved.summary().starts_with(
            "effects: elasticity, bodies (\"lower\": mass consistent), consistent mass, mass-free layer (modified1 along \"b\"), contact"
        ),
        "{}",
        resolved.summary()
    );
    // A lumped body beside consistent cells: both standard masses, no layer.
    let text = with_bodies("[[body]]\ngroup = \"x\"\nmass = \"lumped\"\n");
    let line = parse_in(&dir, &text).unwrap().effects().summary();
    assert!(line.contains("consistent mass, lumped mass; not built: mass-free layer"), "{line}");
}

#[test]
fn friction_keys_give_each_obstacle_and_pair_its_law() {
    let dir = workspace();
    let base = format!("{MINIMAL}\n[contact]\nboundary = \"contact\"\n");
    let plane = "{ type = \"plane\", point = [0, 0], normal = [0, 1]";
    // The contact's law for every obstacle without its own; an obstacle's own wins, and its
    // friction = 0 makes it frictionless.
    let text = format!(
        "{base}friction = 0.3\nobstacles = [{plane} }}, {plane}, friction = 0.5 }}, {plane}, friction = 0 }}, {plane}, tresca = 2 }}]\n"
    );
    let s = parse_in(&dir, &text).unwrap();
    let laws: Vec<_> = s.contact.as_ref().unwrap().obstacles.iter().map(|o| o.friction).collect();
    assert_eq!(
        laws,
        vec![
            Some(FrictionSpec::Coulomb(0.3)),
            Some(FrictionSpec::Coulomb(0.5)),
            None,
            Some(FrictionSpec::Tresca(2.0))
        ]
    );
    let line = s.effects().summary();
    assert!(
        line.contains(
            ", friction (Coulomb, mu = 0.3; Coulomb, mu = 0.5; Tresca, bound = 2); not built: "
        ),
        "{line}"
    );
    // friction = 0 everywhere: frictionless, listed among what is not built.
    let text = format!("{base}friction = 0\nobstacle = {plane} }}\n");
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.contact.as_ref().unwrap().obstacles[0].friction, None);
    assert!(
        s.effects().summary().contains("; not built: ")
            && s.effects().summary().contains("friction, exact errors")
    );
    // Pairs: their own, else the contact's.
    let text = format!(
        "{MINIMAL}\n[contact]\nfriction = 0.2\npairs = [{{ slave = \"a\", master = \"b\" }}, {{ slave = \"c\", master = \"d\", friction = 0.4 }}]\n"
    );
    let s = parse_in(&dir, &text).unwrap();
    let laws: Vec<_> = s.contact.as_ref().unwrap().pairs.iter().map(|p| p.friction).collect();
    assert_eq!(laws, vec![Some(FrictionSpec::Coulomb(0.2)), Some(FrictionSpec::Coulomb(0.4))]);
}

#[test]
fn impossible_friction_values_name_their_key() {
    let base = format!("{MINIMAL}\n[contact]\nboundary = \"contact\"\n");
    let plane = "{ type = \"plane\", point = [0, 0], normal = [0, 1]";
    assert_err(
        &format!("{base}friction = -0.1\nobstacle = {plane} }}\n"),
        &["contact.friction = -0.1 is impossible", "must be >= 0"],
    );
    assert_err(
        &format!("{base}friction = nan\nobstacle = {plane} }}\n"),
        &["contact.friction = NaN is impossible"],
    );
    assert_err(
        &format!("{base}obstacles = [{plane}, tresca = -1 }}]\n"),
        &["contact.obstacles[0].tresca = -1 is impossible"],
    );
    assert_err(
        &format!("{base}obstacle = {plane}, friction = inf }}\n"),
        &["contact.obstacle.friction = inf is impossible"],
    );
    assert_err(
        &format!("{base}friction = 0.3\ntresca = 1\nobstacle = {plane} }}\n"),
        &["contact: give at most one of contact.friction (Coulomb) and contact.tresca"],
    );
    assert_err(
        &format!(
            "{MINIMAL}\n[contact]\npairs = [{{ slave = \"a\", master = \"b\", friction = -2 }}]\n"
        ),
        &["contact.pairs[0].friction = -2 is impossible"],
    );
}

#[test]
fn the_model_is_linear_unless_the_scene_names_another() {
    let dir = workspace();
    let s = parse_in(&dir, MINIMAL).unwrap();
    assert_eq!(s.material.model, Model::Linear);
    // A linear scene's effects line is what it was before finite strain existed.
    assert!(s.effects().summary().starts_with("effects: elasticity, "));
    let text = minimal_with("rho = 2\n", "rho = 2\nmodel = \"neo_hookean\"\n");
    let text = format!(
        "{text}\n[[body]]\ngroup = \"hard\"\nmodel = \"saint_venant_kirchhoff\"\n[[body]]\ngroup = \"soft\"\nE = 0.5\n"
    );
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.material.model, Model::NeoHookean);
    assert_eq!(s.bodies[0].material.model, Model::SaintVenantKirchhoff);
    assert_eq!(s.bodies[0].sets, [false, false, false, true]);
    // A body that does not name one takes [material]'s.
    assert_eq!(s.bodies[1].material.model, Model::NeoHookean);
    let line = s.effects().summary();
    assert!(line.contains("elasticity (finite strain, neo_hookean)"), "{line}");
    assert!(line.contains("\"hard\": model saint_venant_kirchhoff"), "{line}");
}

#[test]
fn model_errors_name_the_key() {
    assert_err(
        &minimal_with("rho = 2\n", "rho = 2\nmodel = \"mooney\"\n"),
        &["material.model = \"mooney\" is unknown", "neo_hookean"],
    );
    assert_err(
        &with_bodies("[[body]]\ngroup = \"a\"\nmodel = \"Neo-Hooke\"\n"),
        &["body[0].model = \"Neo-Hooke\" is unknown"],
    );
    assert_err(
        &minimal_with("nu = 0.25\n", "nu = 0.5\nmodel = \"neo_hookean\"\n"),
        &["material.nu = 0.5 is impossible", "neo-Hooke's lambda is infinite"],
    );
}

#[test]
fn the_formulation_is_the_displacement_one_unless_the_scene_names_mixed() {
    let dir = workspace();
    let s = parse_in(&dir, MINIMAL).unwrap();
    assert_eq!(s.material.formulation, Formulation::Displacement);
    let text = minimal_with("rho = 2\n", "rho = 2\nformulation = \"mixed\"\n");
    let text = format!(
        "{text}\n[[body]]\ngroup = \"hard\"\nformulation = \"displacement\"\n[[body]]\ngroup = \"soft\"\n"
    );
    let s = parse_in(&dir, &text).unwrap();
    assert_eq!(s.material.formulation, Formulation::Mixed);
    assert_eq!(s.bodies[0].material.formulation, Formulation::Displacement);
    // A body that does not name one takes [material]'s.
    assert_eq!(s.bodies[1].material.formulation, Formulation::Mixed);
    let line = s.effects().summary();
    assert!(
        line.starts_with(
            "effects: elasticity (mixed: mean dilatation, nodal pressure on simplices)"
        ),
        "{line}"
    );
    assert!(line.contains("\"soft\": formulation mixed"), "{line}");
}

#[test]
fn formulation_errors_name_the_key() {
    assert_err(
        &minimal_with("rho = 2\n", "rho = 2\nformulation = \"hybrid\"\n"),
        &["material.formulation = \"hybrid\" is unknown", "\"mixed\""],
    );
    assert_err(
        &with_bodies(
            "[[body]]\ngroup = \"a\"\nmodel = \"saint_venant_kirchhoff\"\nformulation = \"mixed\"\n",
        ),
        &["body[0].formulation = \"mixed\" takes model = \"linear\" or \"neo_hookean\""],
    );
}

/// Every shipped scene (scenes/ and the suite's scenes/suite/) is a valid scene: its keys,
/// values, expressions and mesh files (a misspelt key or a `mesh.params` name its `.geo` does
/// not declare would stop a user at once).
#[test]
fn every_shipped_scene_loads() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut n = 0;
    for dir in [root.clone(), root.join("suite")] {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.extension().is_some_and(|x| x == "toml") {
                super::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
                n += 1;
            }
        }
    }
    assert!(n >= 30, "only {n} shipped scenes found");
}
