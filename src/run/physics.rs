//! The physics of a scene, assembled once (docs/method.md): stiffness `A`, mass `M`
//! (consistent, lumped or the mass-free `M_H`), the loads `f(t)`, Dirichlet data and the
//! contact solver the scene and the options ask for. Nothing here knows the time integrator:
//! it gets these as data.

use std::rc::Rc;

use super::domain::Domain;
use super::options::AppOptions;
use crate::assembly::{self, nodal_pressure, Loads};
use crate::console::Console;
use crate::contact::mortar::InterfaceMode;
use crate::contact::{self, ContactBoundary, ContactSolver, Obstacles};
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mass::{build_local_layer, mass_matrix, MassFreeLayer, MassMatrix};
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Matrix, NullSpace, Pattern, Vector};
use crate::scene::expr::VecExpr;
use crate::time::{Dirichlet, Forces, Midpoint};

/// The physics of a scene, assembled once.
pub struct Physics<'a> {
    pub a: Matrix,
    pub m: MassMatrix,
    pub dirichlet: Dirichlet,
    pub layer: Option<MassFreeLayer>,
    pub contact: Option<Box<dyn ContactSolver + 'a>>,
    pub loads: LoadsAt,
    /// Building the mass-free layer (part of the assembly).
    pub layer_seconds: f64,
    /// Assembling the stiffness (part of the assembly).
    pub stiffness_seconds: f64,
}

impl<'a> Physics<'a> {
    /// Stiffness, mass, the mass-free layer, loads, Dirichlet data and the contact solver.
    /// Collective.
    pub fn assemble(d: &Domain<'a>, app: &AppOptions, console: &Console) -> Result<Physics<'a>> {
        let (mesh, part, bodies) = (&d.mesh, &d.part, &d.bodies);
        // A mixed body's simplices: each cell's mu part here, lambda's on the nodes.
        let stiffness = |c: usize, xy: &[[f64; 3]], out: &mut [f64]| {
            let kind = mesh.cells[c].kind;
            let mat = nodal_pressure::element_material(kind, bodies.material(c));
            kernels::stiffness(kind, xy, &mat, out)
                .map_err(|e| Error::Mesh(format!("{e} (gmsh element tag {})", mesh.cells[c].tag)))
        };
        let t_a = std::time::Instant::now();
        let a = match nodal_pressure::volumetric_stiffness(mesh, part, &|c| *bodies.material(c))? {
            // A is used in products only: block AIJ, 30% less memory in 3D (K is AIJ).
            None => assembly::assemble_matrix_blocked(mesh, part, stiffness)?,
            // The nodal part couples nodes two cells apart: AIJ with that wider pattern.
            Some(mut volumetric) => {
                let cells = assembly::assemble_matrix(mesh, part, stiffness)?;
                volumetric.axpy(1.0, &cells, Pattern::Different)?;
                volumetric.keep_pattern()?;
                volumetric
            }
        };
        let stiffness_seconds = t_a.elapsed().as_secs_f64();
        // The summed rows (as large as A) are freed: give them back before M and K.
        crate::phase::release_free_memory();
        crate::phase::trace_memory("stiffness assembled");
        let t_layer = std::time::Instant::now();
        let layer = match &bodies.layer {
            Some((kind, groups)) => {
                let groups: Vec<&str> = groups.iter().map(String::as_str).collect();
                let nodes = d.surface.original_nodes(&groups)?;
                build_local_layer(d.world, mesh, part, *kind, &groups, &nodes)?
            }
            None => None,
        };
        let layer_seconds = t_layer.elapsed().as_secs_f64();
        let m = mass_matrix(mesh, part, |c| bodies.cell_mass(c), layer.as_ref())?;
        crate::phase::trace_memory("mass assembled");
        let neumann: Vec<(String, VecExpr)> =
            d.scene.neumann.iter().map(|n| (n.group.clone(), n.traction.clone())).collect();
        let loads = Loads::new(mesh, part, d.scene.body_force.as_ref(), &neumann)?;
        let dirichlet = Dirichlet::new(mesh, part, &d.scene.dirichlet)?;
        let contact = contact_solver(d, app)?;
        warn_finite_sliding_without_mass(d, app.mortar.update_in_contact, console);
        if contact.as_ref().is_some_and(|c| c.is_pair()) {
            console.say(match app.mortar.mode {
                InterfaceMode::Follow => "mortar interface: follows the bodies inside every contact step (finite sliding; -mortar_interface follow)",
                InterfaceMode::Frozen => "mortar interface: kept from the touch-down (small sliding only; -mortar_interface frozen)",
            }.to_string());
        }
        let loads = LoadsAt::new(
            loads,
            Rc::clone(&d.mesh),
            Rc::clone(&d.part),
            d.scene.body_acceleration.as_ref(),
            &m,
        )?;
        Ok(Physics { a, m, dirichlet, layer, contact, loads, layer_seconds, stiffness_seconds })
    }
}

/// The contact solver of the scene: dual mortar for slave/master pairs (with the obstacles
/// beside them), the active set against rigid obstacles, none without `[contact]`.
fn contact_solver<'a>(
    d: &Domain<'a>,
    app: &AppOptions,
) -> Result<Option<Box<dyn ContactSolver + 'a>>> {
    Ok(match &d.scene.contact {
        Some(spec) if !spec.pairs.is_empty() => Some(contact::mortar::pair_solver(
            d.world,
            Rc::new(d.surface.mesh.clone()),
            Rc::new(d.surface.part.clone()),
            &spec.pairs,
            spec.obstacle_boundary().map(|g| (g, Obstacles::from_scene(&spec.obstacles))),
            Midpoint::CONTACT_FORCE_FACTOR,
            &app.mortar,
        )?),
        Some(spec) => Some(contact::solver(
            d.world,
            &d.surface.mesh,
            &d.surface.part,
            ContactBoundary::build(&d.surface.mesh, spec.boundary.as_deref().unwrap_or_default())?,
            Obstacles::from_scene(&spec.obstacles),
            Midpoint::CONTACT_FORCE_FACTOR,
            &app.contact,
        )?),
        None => None,
    })
}

/// Finite sliding (`-mortar_update_in_contact`) with the mass-free layer on a pair: the forces
/// of an interface re-evaluated in contact are not the gradient of the gap (no consistent
/// linearization of `D`, `M` and the normals), so they can do positive work; with massless
/// interface nodes nothing holds that back when the updates come often (measured on the two
/// discs: stable with updates 0.003 or more apart, the energy grows at 0.002). Said once, on
/// rank 0, as a warning: the run goes on.
fn warn_finite_sliding_without_mass(d: &Domain, update_in_contact: bool, console: &Console) {
    let Some(spec) = &d.scene.contact else { return };
    let Some((_, groups)) = &d.bodies.layer else { return };
    let massless =
        spec.pairs.iter().any(|p| groups.iter().any(|g| *g == p.slave || *g == p.master));
    if massless && update_in_contact {
        console.warn(
            "-mortar_update_in_contact with the mass-free layer on a pair: frequent in-contact updates can make the energy grow (no consistent linearization); keep -mortar_update_distance at its default or larger and watch the energy balance",
        );
    }
}

/// Rigid-body modes from the owned nodes' coordinates (the near null space of `A`, for
/// algebraic multigrid).
pub fn near_null_space(d: &Domain) -> Result<NullSpace> {
    let mut coords = assembly::new_vector(&d.part)?;
    let dim = d.part.dim;
    coords.with_local_slice_mut(|x| {
        for (i, &v) in d.part.owned_nodes.iter().enumerate() {
            for c in 0..dim {
                x[i * dim + c] = d.mesh.coords[v][c];
            }
        }
    })?;
    NullSpace::rigid_body_modes(&coords)
}

/// The loads of a scene as the integrator sees them: `f(t)` assembled on demand.
pub struct LoadsAt {
    loads: Loads,
    mesh: Rc<Mesh>,
    part: Rc<Partition>,
    inertial: Option<InertialLoad>,
}

/// A body force per unit mass `a` (`body_force.acceleration`, gravity), integrated like the
/// inertia: `f = M a_h`. With the mass-free layer the massless DOFs then carry no weight, as
/// they carry no inertia: a body in free fall moves rigidly (`u = a t^2/2` solves
/// `M u'' + A u = M a`, as `A` vanishes on translations), and a body at rest has consistent
/// data. `M_H` keeps the total mass and, for `M_H^1`, its first moments (Lemma 3.3), so the
/// resultant and the moment of a uniform `a` are exact.
enum InertialLoad {
    /// `M a_h`, assembled once.
    Steady(Vector),
    /// `a` depends on `t`: `M a_h(t)` at every evaluation.
    Varying(VecExpr, MassMatrix),
}

impl LoadsAt {
    fn new(
        loads: Loads,
        mesh: Rc<Mesh>,
        part: Rc<Partition>,
        acceleration: Option<&VecExpr>,
        m: &MassMatrix,
    ) -> Result<LoadsAt> {
        let inertial = match acceleration.filter(|a| !a.is_zero()) {
            None => None,
            Some(a) if a.depends_on_t() => Some(InertialLoad::Varying(a.clone(), m.duplicate()?)),
            Some(a) => {
                let ah = assembly::interpolate(&mesh, &part, a, 0.0)?;
                let mut f = ah.duplicate()?;
                m.mult(&ah, &mut f)?;
                Some(InertialLoad::Steady(f))
            }
        };
        Ok(LoadsAt { loads, mesh, part, inertial })
    }
}

impl Forces for LoadsAt {
    fn present(&self) -> bool {
        self.loads.present || self.inertial.is_some()
    }
    fn time_dependent(&self) -> bool {
        self.loads.time_dependent || matches!(self.inertial, Some(InertialLoad::Varying(..)))
    }
    fn assemble(&self, t: f64, out: &mut Vector) -> Result<()> {
        if self.loads.present {
            self.loads.assemble(&self.mesh, &self.part, t, out)?;
        } else {
            out.zero()?;
        }
        match &self.inertial {
            None => Ok(()),
            Some(InertialLoad::Steady(f)) => out.axpy(1.0, f),
            Some(InertialLoad::Varying(a, m)) => {
                let ah = assembly::interpolate(&self.mesh, &self.part, a, t)?;
                let mut f = ah.duplicate()?;
                m.mult(&ah, &mut f)?;
                out.axpy(1.0, &f)
            }
        }
    }
}
