//! Validation: the serde form ([`super::raw`]) -> [`Scene`]. Every value is checked, every
//! expression compiled and the mesh paths resolved; an error is one line naming the key
//! (without the file name, which [`super::parse`] puts in front).

use super::expr::{Expr, VecExpr};
use super::model::{
    obstacle_key, steps_to_end, BodySpec, ContactPair, ContactSpec, DirichletSpec, ExactSpec,
    Field, Formulation, FrictionSpec, MassKind, MassSpec, MaterialSpec, MeshSource, Model,
    NeumannSpec, Obstacle, OutputSpec, Scene, Shape, SolverSpec,
};
use super::raw::{
    ExprSrc, RawBody, RawBodyForce, RawContact, RawDirichlet, RawExact, RawInitial, RawMass,
    RawMaterial, RawMesh, RawNeumann, RawObstacle, RawOutput, RawPair, RawScene, RawSolver,
    RawTime,
};
use std::path::{Path, PathBuf};

type VResult<T> = std::result::Result<T, String>;

/// The scene, section by section in the order of the checks: the first error found is the
/// one reported, so this order is part of the messages a bad scene gets.
pub(super) fn build(raw: RawScene, stem: &str, base_dir: &Path) -> VResult<Scene> {
    let name = name(raw.name, stem)?;
    let mesh = mesh(raw.mesh, base_dir)?;
    let (material, bodies) = materials(raw.material, raw.body)?;
    let dirichlet = dirichlet(raw.dirichlet)?;
    let neumann = neumann(raw.neumann)?;
    let (body_force, body_acceleration) = body_force(raw.body_force)?;
    let (initial_displacement, initial_velocity) = initial(raw.initial)?;
    let (tau, steps) = time(raw.time)?;
    let solver = solver(raw.solver)?;
    let output = output(raw.output, &name, tau, steps)?;
    let exact = exact(raw.exact, steps)?;
    let contact = contact(raw.contact)?;
    // The mass comes after the contact: the layer runs along the contact groups by default.
    let mass = mass(raw.mass, &bodies, contact.as_ref())?;
    check_contact_output(&output, contact.as_ref())?;

    Ok(Scene {
        name,
        text: String::new(),
        source: PathBuf::new(),
        mesh,
        material,
        bodies,
        dirichlet,
        neumann,
        body_force,
        body_acceleration,
        initial_displacement,
        initial_velocity,
        tau,
        steps,
        mass,
        solver,
        output,
        exact,
        contact,
    })
}

// =============================================================================================
// The sections, in the order `build` checks them

/// `name`, default: the scene file's stem.
fn name(name: Option<String>, stem: &str) -> VResult<String> {
    let name = name.unwrap_or_else(|| stem.to_string());
    if name.trim().is_empty() || name.contains('/') || name.contains('\\') {
        return Err(format!(
            "name = {name:?} is impossible: it must be non-empty and contain no path separator"
        ));
    }
    Ok(name)
}

/// `[mesh]`: exactly one of `geo` (with `params`, `binary`) and `msh`, found relative to
/// `base_dir`.
fn mesh(m: RawMesh, base_dir: &Path) -> VResult<MeshSource> {
    let resolve = |p: &str, key: &str| -> VResult<PathBuf> {
        if p.trim().is_empty() {
            return Err(format!("{key} is empty: give a file name"));
        }
        let full = base_dir.join(p);
        if !full.is_file() {
            return Err(format!("{key} = \"{p}\": file not found: {}", full.display()));
        }
        Ok(full)
    };
    Ok(match (m.geo, m.msh) {
        (Some(_), Some(_)) => {
            return Err("mesh: give exactly one of geo and msh, not both".into());
        }
        (None, None) => {
            return Err(
                "mesh: give exactly one of geo (a gmsh .geo source) and msh (an MSH 4.1 file)"
                    .into(),
            );
        }
        (Some(geo), None) => {
            let path = resolve(&geo, "mesh.geo")?;
            // gmsh ignores a -setnumber the .geo does not declare: a misspelt name would
            // silently mesh the default.
            let declared = std::fs::read_to_string(&path)
                .map(|text| crate::mesh::gmsh::declared_parameters(&text))
                .unwrap_or_default();
            let mut params = Vec::new();
            for (k, v) in m.params.unwrap_or_default() {
                if !declared.contains(&k) {
                    return Err(format!(
                        "mesh.params.{k}: {geo} declares no parameter \"{k}\" (it has: {})",
                        if declared.is_empty() { "none".to_string() } else { declared.join(", ") }
                    ));
                }
                if k.is_empty() || !k.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    return Err(format!(
                        "mesh.params: \"{k}\" is not a valid gmsh parameter name (letters, digits, _)"
                    ));
                }
                if !v.is_finite() {
                    return Err(format!(
                        "mesh.params.{k} = {v} is impossible: values must be finite"
                    ));
                }
                params.push((k, v));
            }
            MeshSource::Geo { path, params, binary: m.binary.unwrap_or(false) }
        }
        (None, Some(msh)) => {
            if m.params.is_some() {
                return Err(
                    "mesh.params only applies to mesh.geo (gmsh -setnumber), not to mesh.msh"
                        .into(),
                );
            }
            if m.binary.is_some() {
                return Err(
                    "mesh.binary only applies to mesh.geo (the format gmsh writes), not to mesh.msh"
                        .into(),
                );
            }
            MeshSource::Msh { path: resolve(&msh, "mesh.msh")? }
        }
    })
}

/// `[material]`, then each `[[body]]`'s own values over it.
fn materials(mat: RawMaterial, raw_bodies: Vec<RawBody>) -> VResult<(MaterialSpec, Vec<BodySpec>)> {
    let model = match &mat.model {
        Some(name) => model_of("material", name)?,
        None => Model::Linear,
    };
    let formulation = match &mat.formulation {
        Some(name) => formulation_of("material", name)?,
        None => Formulation::Displacement,
    };
    let material = material_spec("material", mat.e, mat.nu, mat.rho, model, formulation)?;
    let mut bodies: Vec<BodySpec> = Vec::new();
    for (i, b) in raw_bodies.into_iter().enumerate() {
        let key = format!("body[{i}]");
        let group = group_name(b.group, &format!("{key}.group"))?;
        if let Some(j) = bodies.iter().position(|o| o.group == group) {
            return Err(format!(
                "{key}.group = \"{group}\" is also body[{j}].group: give each body once"
            ));
        }
        let m = material_spec(
            &key,
            b.e.unwrap_or(material.e),
            b.nu.unwrap_or(material.nu),
            b.rho.unwrap_or(material.rho),
            match &b.model {
                Some(name) => model_of(&key, name)?,
                None => material.model,
            },
            match &b.formulation {
                Some(name) => formulation_of(&key, name)?,
                None => material.formulation,
            },
        )?;
        let sets = [b.e.is_some(), b.nu.is_some(), b.rho.is_some(), b.model.is_some()];
        bodies.push(BodySpec { group, material: m, sets, mass: b.mass });
    }
    Ok((material, bodies))
}

/// `[[dirichlet]]`.
fn dirichlet(raw: Vec<RawDirichlet>) -> VResult<Vec<DirichletSpec>> {
    let mut dirichlet = Vec::new();
    for (i, d) in raw.into_iter().enumerate() {
        let key = format!("dirichlet[{i}]");
        let group = group_name(d.group, &format!("{key}.group"))?;
        let value = match d.value {
            Some(v) => compile_vec(&v, &format!("{key}.value"))?,
            None => VecExpr::default(),
        };
        let components_given = d.components.is_some();
        let components = match d.components {
            None => vec![0, 1, 2],
            Some(cs) => {
                if cs.is_empty() {
                    return Err(format!(
                        "{key}.components is empty: list some of \"x\", \"y\", \"z\" or leave it out (all)"
                    ));
                }
                let mut idx: Vec<usize> = cs.iter().map(|&c| c as usize).collect();
                idx.sort_unstable();
                if idx.windows(2).any(|w| w[0] == w[1]) {
                    return Err(format!("{key}.components lists a component twice"));
                }
                idx
            }
        };
        dirichlet.push(DirichletSpec { group, value, components, components_given });
    }
    Ok(dirichlet)
}

/// `[[neumann]]`.
fn neumann(raw: Vec<RawNeumann>) -> VResult<Vec<NeumannSpec>> {
    let mut neumann = Vec::new();
    for (i, n) in raw.into_iter().enumerate() {
        let key = format!("neumann[{i}]");
        neumann.push(NeumannSpec {
            group: group_name(n.group, &format!("{key}.group"))?,
            traction: compile_vec(&n.traction, &format!("{key}.traction"))?,
        });
    }
    Ok(neumann)
}

/// `[body_force]`: the force per volume (`value`) and per mass (`acceleration`).
fn body_force(raw: Option<RawBodyForce>) -> VResult<(Option<VecExpr>, Option<VecExpr>)> {
    let (mut body_force, mut body_acceleration) = (None, None);
    if let Some(b) = raw {
        if b.value.is_none() && b.acceleration.is_none() {
            return Err(
                "body_force: give value (force per volume) or acceleration (per mass, e.g. gravity)"
                    .into(),
            );
        }
        if let Some(v) = b.value {
            body_force = Some(compile_vec(&v, "body_force.value")?);
        }
        if let Some(a) = b.acceleration {
            body_acceleration = Some(compile_vec(&a, "body_force.acceleration")?);
        }
    }
    Ok((body_force, body_acceleration))
}

/// `[initial]`: the initial displacement and velocity.
fn initial(raw: Option<RawInitial>) -> VResult<(Option<VecExpr>, Option<VecExpr>)> {
    let (mut initial_displacement, mut initial_velocity) = (None, None);
    if let Some(init) = raw {
        if let Some(d) = init.displacement {
            initial_displacement = Some(compile_vec(&d, "initial.displacement")?);
        }
        if let Some(v) = init.velocity {
            initial_velocity = Some(compile_vec(&v, "initial.velocity")?);
        }
    }
    Ok((initial_displacement, initial_velocity))
}

/// `[time]`: the time step and the number of steps (given, or from `end`).
fn time(t: RawTime) -> VResult<(f64, usize)> {
    check_tau(t.tau)?;
    let steps = match (t.steps, t.end) {
        (Some(_), Some(_)) => {
            return Err("time: give exactly one of steps and end, not both".into());
        }
        (None, None) => {
            return Err(
                "time: give the number of steps (time.steps) or the end time (time.end)".into()
            );
        }
        (Some(s), None) => {
            if s < 1 {
                return Err(format!(
                    "time.steps = {s} is impossible: the number of steps must be >= 1"
                ));
            }
            s as usize
        }
        (None, Some(end)) => steps_to_end(end, t.tau).map_err(|e| e.message(end, t.tau))?,
    };
    Ok((t.tau, steps))
}

/// `[solver]`.
fn solver(raw: Option<RawSolver>) -> VResult<SolverSpec> {
    let Some(s) = raw else {
        return Ok(SolverSpec::default());
    };
    if let Some(r) = s.rtol {
        if !(r > 0.0 && r < 1.0) {
            return Err(format!(
                "solver.rtol = {r} is impossible: the relative tolerance must be in (0, 1)"
            ));
        }
    }
    for (k, v) in [("ksp_type", &s.ksp_type), ("pc_type", &s.pc_type)] {
        if let Some(v) = v {
            if v.trim().is_empty() || v.contains(char::is_whitespace) {
                return Err(format!("solver.{k} = {v:?} is impossible: give one PETSc type name"));
            }
        }
    }
    Ok(SolverSpec {
        ksp_type: s.ksp_type,
        pc_type: s.pc_type,
        rtol: s.rtol,
        options: s
            .options
            .map(|o| o.split_whitespace().map(str::to_string).collect())
            .unwrap_or_default(),
    })
}

/// `[output]`; the default file is named after the scene, `output.times` need the run's
/// `tau` and `steps`.
fn output(raw: Option<RawOutput>, name: &str, tau: f64, steps: usize) -> VResult<OutputSpec> {
    let o = raw.unwrap_or(RawOutput {
        file: None,
        compression: None,
        every: None,
        field_every: None,
        times: None,
        fields: None,
        progress: None,
    });
    let every = o.every.unwrap_or(1);
    if every < 1 {
        return Err(format!(
            "output.every = {every} is impossible: write every k-th step with k >= 1"
        ));
    }
    let file = match o.file {
        Some(f) if f.trim().is_empty() => {
            return Err("output.file is empty: give a file name".into());
        }
        Some(f) => PathBuf::from(f),
        None => PathBuf::from("out").join(format!("{name}.h5")),
    };
    let mut fields = Vec::new();
    for f in o.fields.unwrap_or_else(|| vec![Field::Displacement, Field::Velocity]) {
        if !fields.contains(&f) {
            fields.push(f);
        }
    }
    let times = o.times.unwrap_or_default();
    let time_steps = steps_of_times(&times, tau, steps)?;
    let mut field_every = Vec::new();
    if let Some(fe) = &o.field_every {
        for f in Field::ALL {
            if let Some(k) = fe.of(f) {
                if k < 1 {
                    return Err(format!(
                        "output.field_every.{} = {k} is impossible: write every k-th step with k >= 1",
                        f.name()
                    ));
                }
                field_every.push((f, k as usize));
            }
        }
    }
    let compression = match o.compression {
        None | Some(0) => None,
        Some(l) if (1..=9).contains(&l) => Some(l as u8),
        Some(l) => {
            return Err(format!(
                "output.compression = {l} is impossible: a deflate level 0 (off) to 9"
            ))
        }
    };
    Ok(OutputSpec {
        file,
        compression,
        every: every as usize,
        field_every,
        times,
        time_steps,
        fields,
        progress: o.progress.unwrap_or(true),
    })
}

/// `[exact]`: the exact solution; the error steps lie in the run's `0..=steps`.
fn exact(raw: Option<RawExact>, steps: usize) -> VResult<Option<ExactSpec>> {
    let Some(ex) = raw else {
        return Ok(None);
    };
    let displacement = compile_vec(&ex.displacement, "exact.displacement")?;
    let velocity = match ex.velocity {
        Some(v) => Some(compile_vec(&v, "exact.velocity")?),
        None => None,
    };
    let gradient = match ex.gradient {
        None => None,
        Some(rows) => {
            if rows.is_empty() {
                return Err("exact.gradient is empty: give one row per displacement component, or leave it out".into());
            }
            let mut g = Vec::new();
            for (i, r) in rows.iter().enumerate() {
                g.push(compile_vec(r, &format!("exact.gradient[{i}]"))?);
            }
            Some(g)
        }
    };
    let error_steps_listed = ex.error_steps.is_some();
    let mut error_steps = Vec::new();
    for s in ex.error_steps.unwrap_or_else(|| vec![steps as i64]) {
        error_steps.push(error_step(s, steps)?);
    }
    error_steps.sort_unstable();
    error_steps.dedup();
    Ok(Some(ExactSpec { displacement, velocity, gradient, error_steps, error_steps_listed }))
}

/// `[contact]`: the slave/master pairs, then `boundary` and the obstacles it meets.
fn contact(raw: Option<RawContact>) -> VResult<Option<ContactSpec>> {
    let Some(c) = raw else {
        return Ok(None);
    };
    let has_obstacles = c.obstacle.is_some() || c.obstacles.is_some();
    let pairs_listed = c.pairs.is_some();
    let friction = friction_law(c.friction, c.tresca, "contact")?;
    let pairs = contact_pairs(c.slave, c.master, c.pairs, friction)?;
    let boundary = c.boundary.map(|b| group_name(b, "contact.boundary")).transpose()?;
    match (&boundary, pairs.is_empty(), has_obstacles) {
        (None, true, _) => return Err("contact: give contact.boundary (with an obstacle) or contact.slave and contact.master (two bodies)".into()),
        (None, false, true) => return Err("contact: obstacles beside a slave/master pair need contact.boundary, the group that meets them (another part of the boundary than contact.slave and contact.master)".into()),
        (Some(b), false, false) => return Err(format!("contact.boundary = \"{b}\" beside a slave/master pair needs the obstacles it meets (contact.obstacle or contact.obstacles)")),
        (Some(b), false, true) => {
            let key = |side: &str| if pairs_listed { format!("a contact.pairs[].{side}") } else { format!("contact.{side}") };
            if pairs.iter().any(|p| &p.slave == b) {
                return Err(format!("contact.boundary = \"{b}\" is also {}: the obstacles need another part of the boundary than the pair's", key("slave")));
            }
            if pairs.iter().any(|p| &p.master == b) {
                return Err(format!("contact.boundary = \"{b}\" is also {}: the obstacles need another part of the boundary than the pair's", key("master")));
            }
        }
        _ => {}
    }
    if boundary.is_none() {
        return Ok(Some(ContactSpec { pairs, boundary, obstacles: Vec::new(), listed: false }));
    }
    let (obstacles, listed) = obstacles(c.obstacle, c.obstacles, friction)?;
    Ok(Some(ContactSpec { pairs, boundary, obstacles, listed }))
}

/// `KEY.friction = MU` (Coulomb) or `KEY.tresca = S` (a given slip bound), at most one;
/// `default` where neither is given. `friction = 0` is frictionless.
fn friction_law(
    mu: Option<f64>,
    tresca: Option<f64>,
    key: &str,
) -> VResult<Option<Option<FrictionSpec>>> {
    match (mu, tresca) {
        (Some(_), Some(_)) => Err(format!(
            "{key}: give at most one of {key}.friction (Coulomb) and {key}.tresca (a given slip bound)"
        )),
        (Some(mu), None) if !(mu >= 0.0 && mu.is_finite()) => Err(format!(
            "{key}.friction = {mu} is impossible: the friction coefficient must be >= 0 and finite"
        )),
        (None, Some(s)) if !(s >= 0.0 && s.is_finite()) => Err(format!(
            "{key}.tresca = {s} is impossible: the slip bound must be >= 0 and finite"
        )),
        (Some(mu), None) => Ok(Some((mu > 0.0).then_some(FrictionSpec::Coulomb(mu)))),
        (None, Some(s)) => Ok(Some(Some(FrictionSpec::Tresca(s)))),
        (None, None) => Ok(None),
    }
}

/// `contact.obstacle` or the list `contact.obstacles` (exactly one), and whether it is the
/// list.
fn obstacles(
    one: Option<RawObstacle>,
    list: Option<Vec<RawObstacle>>,
    friction: Option<Option<FrictionSpec>>,
) -> VResult<(Vec<Obstacle>, bool)> {
    let (raws, listed) = match (one, list) {
        (Some(_), Some(_)) => {
            return Err(
                "contact: give exactly one of contact.obstacle and contact.obstacles, not both"
                    .into(),
            );
        }
        (None, None) => {
            return Err("contact: give the obstacle (contact.obstacle = { type = ... }) or a list of them (contact.obstacles = [{ ... }, ...])".into());
        }
        (Some(o), None) => (vec![o], false),
        (None, Some(list)) if list.is_empty() => {
            return Err("contact.obstacles is empty: give at least one obstacle".into());
        }
        (None, Some(list)) => (list, true),
    };
    let obstacles = raws
        .into_iter()
        .enumerate()
        .map(|(i, o)| obstacle(o, &obstacle_key(listed, i), friction.flatten()))
        .collect::<VResult<Vec<_>>>()?;
    Ok((obstacles, listed))
}

/// `[mass]`: the kind, and the groups the mass-free layer runs along (`contact_boundary`, by
/// default the contact groups); a modified mass, of the scene or of a body, needs one.
fn mass(
    raw: Option<RawMass>,
    bodies: &[BodySpec],
    contact: Option<&ContactSpec>,
) -> VResult<MassSpec> {
    let (kind, contact_boundary) = match raw {
        Some(m) => (m.kind.unwrap_or(MassKind::Consistent), m.contact_boundary),
        None => (MassKind::Consistent, None),
    };
    // The mass-free layer sits on the contact boundary unless the scene names another group.
    let (contact_boundary, also_along) = match contact_boundary {
        Some(g) => (Some(group_name(g, "mass.contact_boundary")?), Vec::new()),
        // The layer runs along every contact group: the first names it, the others follow.
        None => {
            let groups: Vec<String> =
                contact.into_iter().flat_map(ContactSpec::groups).map(String::from).collect();
            (groups.first().cloned(), groups.iter().skip(1).cloned().collect())
        }
    };
    if kind.is_modified() && contact_boundary.is_none() {
        return Err(format!(
            "mass.kind = {} needs mass.contact_boundary (or a [contact] section): the mass-free layer is built along the potential contact boundary",
            kind.name()
        ));
    }
    for (i, b) in bodies.iter().enumerate() {
        match b.mass {
            Some(k) if k.is_modified() && contact_boundary.is_none() => {
                return Err(format!(
                    "body[{i}].mass = {} needs mass.contact_boundary (or a [contact] section): the mass-free layer is built along the potential contact boundary",
                    k.name()
                ));
            }
            _ => {}
        }
    }
    Ok(MassSpec { kind, contact_boundary, also_along })
}

/// The contact traction is written at contact nodes: `output.fields` may list it only with a
/// `[contact]` table.
fn check_contact_output(output: &OutputSpec, contact: Option<&ContactSpec>) -> VResult<()> {
    if output.fields.contains(&Field::ContactTraction) && contact.is_none() {
        return Err(
            "output.fields: contact_traction needs a [contact] table (no contact nodes)".into()
        );
    }
    Ok(())
}

// =============================================================================================
// Helpers: expressions, values, group names, obstacles, steps

fn compile(src: &ExprSrc, key: &str) -> VResult<Expr> {
    match src {
        ExprSrc::Num(v) if v.is_finite() => Ok(Expr::constant(*v)),
        ExprSrc::Num(v) => Err(format!("{key} = {v} is impossible: values must be finite")),
        ExprSrc::Text(s) => Expr::parse(s).map_err(|m| format!("{key}: {m} (in \"{s}\")")),
    }
}

fn compile_vec(v: &[ExprSrc], key: &str) -> VResult<VecExpr> {
    if v.is_empty() {
        return Err(format!("{key} is empty: give one expression per component"));
    }
    if v.len() > 3 {
        return Err(format!("{key} has {} components: at most 3 are possible", v.len()));
    }
    let exprs = v
        .iter()
        .enumerate()
        .map(|(i, s)| compile(s, &format!("{key}[{i}]")))
        .collect::<VResult<Vec<_>>>()?;
    Ok(VecExpr(exprs))
}

/// The constitutive model of `KEY.model`.
fn model_of(key: &str, name: &str) -> VResult<Model> {
    Model::from_name(name).ok_or_else(|| {
        format!(
            "{key}.model = \"{name}\" is unknown: use \"linear\", \"neo_hookean\" or \"saint_venant_kirchhoff\""
        )
    })
}

/// The volumetric discretization of `KEY.formulation`.
fn formulation_of(key: &str, name: &str) -> VResult<Formulation> {
    Formulation::from_name(name).ok_or_else(|| {
        format!("{key}.formulation = \"{name}\" is unknown: use \"displacement\" or \"mixed\"")
    })
}

/// A material checked value by value (`key` is `material` or `body[i]`).
fn material_spec(
    key: &str,
    e: f64,
    nu: f64,
    rho: f64,
    model: Model,
    formulation: Formulation,
) -> VResult<MaterialSpec> {
    if !(e > 0.0 && e.is_finite()) {
        return Err(format!("{key}.E = {e} is impossible: Young's modulus must be > 0"));
    }
    if !(nu > -1.0 && nu < 0.5) {
        let why = match model {
            Model::NeoHookean => " (neo-Hooke's lambda is infinite at 0.5)",
            _ => "",
        };
        return Err(format!(
            "{key}.nu = {nu} is impossible: Poisson's ratio must be in (-1, 0.5){why}"
        ));
    }
    if !(rho > 0.0 && rho.is_finite()) {
        return Err(format!("{key}.rho = {rho} is impossible: the density must be > 0"));
    }
    if formulation == Formulation::Mixed && model == Model::SaintVenantKirchhoff {
        return Err(format!(
            "{key}.formulation = \"mixed\" takes model = \"linear\" or \"neo_hookean\" (Saint Venant-Kirchhoff has no mixed form here)"
        ));
    }
    Ok(MaterialSpec { e, nu, rho, model, formulation })
}

/// The slave/master pairs: `contact.slave` with `contact.master` (one pair) or the list
/// `contact.pairs`. A slave group must not be a master group (the dual mortar basis change
/// keeps slave and master nodes apart).
fn contact_pairs(
    slave: Option<String>,
    master: Option<String>,
    listed: Option<Vec<RawPair>>,
    friction: Option<Option<FrictionSpec>>,
) -> VResult<Vec<ContactPair>> {
    let list = match (slave, master, listed) {
        (None, None, None) => return Ok(Vec::new()),
        (Some(s), Some(m), None) => {
            let (slave, master) = (group_name(s, "contact.slave")?, group_name(m, "contact.master")?);
            if slave == master {
                return Err(format!("contact.slave and contact.master are the same group \"{slave}\""));
            }
            return Ok(vec![ContactPair { slave, master, friction: friction.flatten() }]);
        }
        (Some(_), None, None) => return Err("contact.slave needs contact.master (the other body's contact boundary)".into()),
        (None, Some(_), None) => return Err("contact.master needs contact.slave (this body's contact boundary)".into()),
        (None, None, Some(list)) => list,
        (_, _, Some(_)) => return Err("contact: give either contact.slave and contact.master (one pair) or contact.pairs (a list of them), not both".into()),
    };
    if list.is_empty() {
        return Err(
            "contact.pairs is empty: give at least one { slave = \"...\", master = \"...\" }"
                .into(),
        );
    }
    let mut pairs: Vec<ContactPair> = Vec::with_capacity(list.len());
    for (i, p) in list.into_iter().enumerate() {
        let key = format!("contact.pairs[{i}]");
        let slave = group_name(
            p.slave.ok_or(format!("{key} needs slave (this body's contact boundary)"))?,
            &format!("{key}.slave"),
        )?;
        let master = group_name(
            p.master.ok_or(format!("{key} needs master (the other body's contact boundary)"))?,
            &format!("{key}.master"),
        )?;
        if slave == master {
            return Err(format!("{key}: slave and master are the same group \"{slave}\""));
        }
        if let Some(j) = pairs.iter().position(|q| q.slave == slave && q.master == master) {
            return Err(format!(
                "{key} repeats contact.pairs[{j}] (slave \"{slave}\", master \"{master}\")"
            ));
        }
        let own = friction_law(p.friction, p.tresca, &key)?;
        pairs.push(ContactPair { slave, master, friction: own.or(friction).flatten() });
    }
    for (i, p) in pairs.iter().enumerate() {
        if let Some(j) = pairs.iter().position(|q| q.master == p.slave) {
            return Err(format!("contact.pairs[{i}].slave = \"{}\" is also contact.pairs[{j}].master: a slave group must not be a master group (swap the sides of one pair)", p.slave));
        }
    }
    Ok(pairs)
}

fn group_name(g: String, key: &str) -> VResult<String> {
    if g.trim().is_empty() {
        return Err(format!("{key} is empty: give a physical group name"));
    }
    Ok(g)
}

fn point(v: Vec<f64>, key: &str) -> VResult<Vec<f64>> {
    if !(2..=3).contains(&v.len()) {
        return Err(format!("{key} has {} components: give 2 (2D) or 3 (3D)", v.len()));
    }
    if v.iter().any(|c| !c.is_finite()) {
        return Err(format!("{key} = {v:?} is impossible: values must be finite"));
    }
    Ok(v)
}

/// A direction: `v / |v|` for `v` != 0 (`what` names it in the message).
fn direction(v: Vec<f64>, key: &str, what: &str) -> VResult<Vec<f64>> {
    let v = point(v, key)?;
    let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
    if norm <= 0.0 {
        return Err(format!("{key} = {v:?} is impossible: the {what} must be nonzero"));
    }
    Ok(v.iter().map(|c| c / norm).collect())
}

fn radius(r: f64, key: &str) -> VResult<f64> {
    if !(r > 0.0 && r.is_finite()) {
        return Err(format!("{key} = {r} is impossible: the radius must be > 0"));
    }
    Ok(r)
}

/// One obstacle (`key` names it: `contact.obstacle` or `contact.obstacles[i]`).
fn obstacle(raw: RawObstacle, key: &str, default: Option<FrictionSpec>) -> VResult<Obstacle> {
    let at = |name: &str| format!("{key}.{name}");
    let (mu, tresca) = match &raw {
        RawObstacle::Plane { friction, tresca, .. }
        | RawObstacle::Sphere { friction, tresca, .. }
        | RawObstacle::Cylinder { friction, tresca, .. } => (*friction, *tresca),
    };
    let friction = friction_law(mu, tresca, key)?.unwrap_or(default);
    let (shape, motion) = match raw {
        RawObstacle::Plane { point: p, normal, motion, .. } => {
            let point = point(p, &at("point"))?;
            (Shape::Plane { point, normal: direction(normal, &at("normal"), "normal")? }, motion)
        }
        RawObstacle::Sphere { center, radius: r, motion, .. } => (
            Shape::Sphere {
                center: point(center, &at("center"))?,
                radius: radius(r, &at("radius"))?,
            },
            motion,
        ),
        RawObstacle::Cylinder { point: p, axis, radius: r, motion, .. } => {
            for (name, v) in [("point", &p), ("axis", &axis)] {
                if v.len() != 3 {
                    return Err(format!(
                        "{} has {} components: a cylinder exists in 3D only (give 3)",
                        at(name),
                        v.len()
                    ));
                }
            }
            let point = point(p, &at("point"))?;
            let axis = direction(axis, &at("axis"), "axis")?;
            (Shape::Cylinder { point, axis, radius: radius(r, &at("radius"))? }, motion)
        }
    };
    let motion = match motion {
        None => None,
        Some(m) => {
            let d = compile_vec(&m, &at("motion"))?;
            if let Some((i, e)) = d.0.iter().enumerate().find(|(_, e)| e.depends_on_x()) {
                return Err(format!(
                    "{}[{i}] = \"{e}\" is impossible: a motion is a function of t only (no x, y, z)",
                    at("motion")
                ));
            }
            Some(d)
        }
    };
    Ok(Obstacle { shape, motion, friction })
}

pub(super) fn check_tau(tau: f64) -> VResult<()> {
    if !(tau > 0.0 && tau.is_finite()) {
        return Err(format!("time.tau = {tau} is impossible: the time step must be > 0"));
    }
    Ok(())
}

/// One entry of `exact.error_steps`: a step of the run.
pub(super) fn error_step(s: i64, steps: usize) -> VResult<usize> {
    if s < 0 || s as u64 > steps as u64 {
        return Err(format!(
            "exact.error_steps contains {s}, which is impossible: steps run from 0 to time.steps = {steps}"
        ));
    }
    Ok(s as usize)
}

/// The steps nearest to the extra output times (`output.times`), sorted, each within the run.
pub(super) fn steps_of_times(times: &[f64], tau: f64, steps: usize) -> VResult<Vec<usize>> {
    let mut time_steps = Vec::new();
    for (i, &time) in times.iter().enumerate() {
        let n = (time / tau).round();
        if time.is_nan() || time < 0.0 || n > steps as f64 {
            return Err(format!(
                "output.times[{i}] = {time} is impossible: times must lie in [0, {}] (steps * tau)",
                steps as f64 * tau
            ));
        }
        time_steps.push(n as usize);
    }
    time_steps.sort_unstable();
    time_steps.dedup();
    Ok(time_steps)
}
