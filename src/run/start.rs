//! How a run starts: the step solver (its defaults chosen by the regime, then the scene's and
//! the command line's options), the initial state (the scene's initial fields, the massless
//! DOFs made statically consistent, or a checkpoint's state), and the check that no contact
//! node starts inside an obstacle.

use std::path::Path;

use super::domain::Domain;
use super::options::AppOptions;
use super::views::Views;
use super::{diagnostics, physics};
use crate::assembly;
use crate::assembly::finite_strain::InternalForce;
use crate::console::Console;
use crate::contact::ContactSolver;
use crate::error::{Error, Result};
use crate::io::{read_checkpoint, Checkpoint};
use crate::petsc::Matrix;
use crate::time::choice::RunFacts;
use crate::time::newton::Newton;
use crate::time::{Dirichlet, Energy, Forces, Midpoint, StepOperator, StepSolverDefaults};

/// The step operator `K = 4/tau^2 M + A` and its solver, set up once. The solver's defaults
/// follow the regime (the CFL number `c_p tau / h_min`, returned); the scene and the command
/// line still win.
pub fn step_operator(
    d: &Domain,
    app: &AppOptions,
    console: &Console,
    m: &crate::mass::MassMatrix,
    a: &Matrix,
    dirichlet: &Dirichlet,
    with_contact: bool,
) -> Result<(StepOperator, f64)> {
    let null_space = || physics::near_null_space(d);
    let regime = d.bodies.regime(d.scene.tau, &diagnostics::min_edges(d));
    let solver = &d.scene.solver;
    let (mut defaults, mut why) = StepSolverDefaults::for_regime(&regime, with_contact);
    if d.scene.contact.as_ref().is_some_and(|c| c.has_friction()) {
        // A slipping node's rows couple its normal residual into the tangential one
        // (contact::constraint): the constrained operator is not symmetric.
        defaults.ksp_type = "gmres".into();
        defaults.symmetric = false;
        why.push_str("; friction makes the contact rows unsymmetric: GMRES");
    }
    let finite_strain = d.bodies.finite_strain();
    // What the choices by run length and by `lambda/mu` weigh (collective: the free memory).
    let facts = RunFacts {
        dofs: d.part.n_global_dofs(),
        dim: d.part.dim,
        ranks: d.size,
        steps: d.n_steps,
        cfl: regime.cfl,
        contact: with_contact,
        memory_per_rank: memory_per_rank(d),
        lambda_over_mu: d.bodies.lambda_over_mu(),
        nodal_pressure: d.bodies.nodal_pressure,
    };
    if finite_strain {
        // Newton's tangent (`time::newton`) is unsymmetric and changes every iteration: GMRES
        // through PETSc's KSP on K in AIJ, without the linear step's own CG or the choice by
        // run length (which may factor K once for the run).
        defaults.ksp_type = "gmres".into();
        defaults.symmetric = false;
        why.push_str("; finite strain: Newton's tangent is unsymmetric: GMRES");
        // SOR (each rank's rows, symmetric sweeps) instead of Jacobi or block Jacobi/ILU(0):
        // no factorization per Newton iteration, and about the iterations of ILU(0). Step
        // times against block Jacobi/ILU(0), 2026-12-05: the beam at 3.3e5 DOFs, CFL 1, one
        // rank 520 -> 413 ms; on 2 ranks the L-block (h = 0.5) 16.8 -> 11.4 ms, loaded twice
        // as hard 1.80 -> 1.57, the ball (h = 0.1) 85 -> 72, the disc 1.27 -> 1.20.
        // Two-body pairs take additive Schwarz, ILU(0) on each rank's rows with one layer of
        // overlap: their operator in the mortar basis, `T^T K T`, stalled GMRES on the 3D
        // slide-off at step 182 (the block leaving the edge) with SOR and, after the energy
        // correction's force lost its moment, with block Jacobi/ILU(0) too (10000
        // iterations); ASM ran it in 33.1 s on 2 ranks (MUMPS LU 53.1 s), and costs 7-11% more
        // than block Jacobi on the 2D slide-off and the oblique balls. On one rank it is
        // ILU(0).
        let pairs = d.scene.contact.as_ref().is_some_and(|c| !c.pairs.is_empty());
        if pairs && matches!(defaults.pc_type.as_str(), "jacobi" | "sor" | "bjacobi") {
            defaults.pc_type = "asm".into();
        }
        if pairs && defaults.pc_type == "asm" {
            why.push_str(" with additive Schwarz/ILU(0), overlap 1 (two-body pairs)");
        } else if defaults.pc_type == "jacobi" || defaults.pc_type == "bjacobi" {
            defaults.pc_type = "sor".into();
            why.push_str(" with SOR");
        }
        // Nearly incompressible: each tangent factored (`time::choice`).
        if crate::time::choice::finite_strain_factors(&facts) {
            defaults.ksp_type = "preonly".into();
            defaults.pc_type = "lu".into();
            defaults.factor_solver = Some("mumps".into());
            why = format!(
                "CFL {:.3}, lambda/mu {:.0}: finite strain, nearly incompressible: each Newton tangent factored (LU, MUMPS)",
                regime.cfl, facts.lambda_over_mu
            );
        }
    }
    if let Some(k) = &solver.ksp_type {
        defaults.ksp_type = k.clone();
    }
    if let Some(p) = &solver.pc_type {
        defaults.pc_type = p.clone();
    }
    if let Some(r) = solver.rtol {
        defaults.rtol = r;
    }
    defaults.user_reuse_preconditioner = app.user_reuse_preconditioner;
    // Knowing the run's length, a factorization may pay back (`time::choice`), unless the
    // scene or the command line names the solver (friction's GMRES stays).
    let named = solver.ksp_type.is_some() || solver.pc_type.is_some() || app.step_solver_named;
    if !named && defaults.symmetric && app.choice_by_run && !finite_strain {
        defaults.run = Some(facts);
    }
    // The step's own CG serves steps without contact (a contact solver rewrites K's rows).
    defaults.reuse = if with_contact || finite_strain { None } else { app.step_reuse };
    defaults.layer = app.step_layer_around && !finite_strain;
    defaults.blocked =
        d.scene.contact.as_ref().is_none_or(|c| c.pairs.is_empty()) && !finite_strain;
    let op = StepOperator::new(
        m,
        a,
        d.scene.tau,
        dirichlet.dofs().to_vec(),
        // The Newton step keeps its Dirichlet increments in its iterate: no lifting.
        dirichlet.nonzero && !finite_strain,
        Some(&null_space),
        &defaults,
    )?;
    let (ksp_type, pc_type) = (op.ksp.ksp_type()?, op.ksp.pc_type()?);
    let chosen = match &op.choice {
        Some((_, _, reason, _)) if !named => reason.clone(),
        _ if pc_type == defaults.pc_type && solver.pc_type.is_none() => why,
        _ => "set by the scene or the command line".to_string(),
    };
    let around = op.layer.as_ref().and_then(|i| i.borrow().clone());
    let own = op.cg.as_ref().and_then(|cg| cg.layer_solver());
    let layer = match own.or(around) {
        Some((rows, solver)) => format!(
            "; the mass-free layer's {rows} massless rows swept with {solver} (-step_layer false: not swept)"
        ),
        None => String::new(),
    };
    console.say(format!("step solver: {ksp_type} + {pc_type} ({chosen}){layer}"));
    Ok((op, regime.cfl))
}

/// The Newton loop of finite-strain bodies: the internal force over this rank's cells and the
/// loop's options. Collective.
pub fn newton(
    d: &Domain,
    app: &AppOptions,
    layout: &crate::petsc::Vector,
    k: &Matrix,
    m: &crate::mass::MassMatrix,
) -> Result<Newton> {
    use std::rc::Rc;
    let force =
        InternalForce::new(d.world, Rc::clone(&d.mesh), Rc::clone(&d.part), &d.bodies, layout)?;
    // Names by `diagnostics::node_bodies`' numbers: body i, then the cells outside every body.
    let n = d.bodies.n_bodies();
    let mut names: Vec<String> = (0..n).map(|i| d.bodies.regions[i + 1].name.clone()).collect();
    names.push(if n == 0 { "the body".to_string() } else { d.bodies.regions[0].name.clone() });
    let bodies = diagnostics::node_bodies(d);
    Newton::new(force, layout, k, m, d.scene.tau, app.newton, bodies, names, d.part.dim)
}

/// The memory a rank may still use: the node's available memory (`MemAvailable`) shared by
/// the ranks on the node, the least over the nodes. Collective.
fn memory_per_rank(d: &Domain) -> f64 {
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("MemAvailable:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::INFINITY, |kib| kib * 1024.0);
    use mpi::traits::*;
    let node = d.world.split_shared(0);
    // The smallest over the ranks: every rank must make the same choice.
    let mine = available / node.size().max(1) as f64;
    let mut least = mine;
    d.world.all_reduce_into(&mine, &mut least, mpi::collective::SystemOperation::min());
    least
}

/// The initial state: the nodal interpolants of the scene's initial displacement and
/// velocity (zero where the scene gives none).
pub fn initial_state(d: &Domain) -> Result<(crate::petsc::Vector, crate::petsc::Vector)> {
    let u0 = match &d.scene.initial_displacement {
        Some(e) => assembly::interpolate(&d.mesh, &d.part, e, 0.0)?,
        None => assembly::new_vector(&d.part)?,
    };
    let v0 = match &d.scene.initial_velocity {
        Some(e) => assembly::interpolate(&d.mesh, &d.part, e, 0.0)?,
        None => assembly::new_vector(&d.part)?,
    };
    Ok((u0, v0))
}

/// The massless DOFs start in static equilibrium (docs/method.md, massless DOFs: their rows carry no inertia).
/// Contact nodes the projection would push through an obstacle or the master side need their
/// contact force for it (bodies touching at t = 0): they are held as given, and the projection
/// is made again without them. Returns the largest change (`None` without massless DOFs).
pub fn make_massless_consistent(
    d: &Domain,
    midpoint: &mut Midpoint,
    contact: Option<&dyn ContactSolver>,
    forces: &dyn Forces,
) -> Result<Option<f64>> {
    let mut hold: Vec<i32> = Vec::new();
    loop {
        let change = midpoint.make_massless_consistent(forces, 0.0, &hold)?;
        let through = match contact {
            Some(c) => c.penetrating(midpoint.u(), 0.0)?,
            None => Vec::new(),
        };
        let dofs: Vec<i32> = (through.iter())
            .flat_map(|&(v, _)| (0..d.part.dim).map(move |c| (v, c)))
            .map(|(v, c)| d.surface.part.dof(v, c) as i32)
            .filter(|dof| !hold.contains(dof))
            .collect();
        if through.is_empty() {
            return Ok(change);
        }
        midpoint.undo_massless(forces, 0.0)?;
        if dofs.is_empty() {
            // Penetrating as given: `check_no_penetration` says so.
            return Ok(None);
        }
        hold.extend(dofs);
    }
}

/// Continue from a checkpoint: u, v, the last increment (the solver's initial guess), the
/// loads at the checkpoint's time, the running work totals and the active set.
pub fn restore(
    d: &Domain,
    views: &mut Views,
    console: &Console,
    path: &Path,
    midpoint: &mut Midpoint,
    contact: Option<&mut (dyn ContactSolver + '_)>,
    forces: &dyn Forces,
) -> Result<Checkpoint> {
    let range = d.part.natural_block();
    let n = d.part.n_global_nodes();
    let (cp, [u, v, du]) = read_checkpoint(path, d.world, range, n, d.part.dim)?;
    let works = Energy {
        external_work: cp.external_work,
        contact_work: cp.contact_work,
        dirichlet_work: cp.dirichlet_work,
        friction_dissipation: cp.friction_dissipation,
        ..Default::default()
    };
    midpoint.restore(
        |uu, vv, dd| {
            views.from_natural(&u, uu)?;
            views.from_natural(&v, vv)?;
            views.from_natural(&du, dd)
        },
        works,
        cp.ksp_iterations,
        cp.pending_correction,
    )?;
    midpoint.refresh(forces, cp.time)?;
    if let Some(c) = contact {
        if cp.active.len() != c.n_nodes() {
            return Err(Error::Io(format!(
                "{}: the checkpoint's contact set has {} nodes, this scene's {}",
                path.display(),
                cp.active.len(),
                c.n_nodes()
            )));
        }
        c.set_active(cp.active.clone());
    }
    console.say(format!(
        "restarting from step {} (t = {}) of {}",
        cp.step,
        crate::console::time(cp.time),
        path.display()
    ));
    Ok(cp)
}

/// A scene whose body starts inside an obstacle (or a slave node behind its master side) is
/// an error naming the obstacle and its first nodes.
pub fn check_no_penetration(
    d: &Domain,
    contact: &dyn ContactSolver,
    u: &crate::petsc::Vector,
) -> Result<()> {
    let Some(spec) = d.scene.contact.as_ref() else { return Ok(()) };
    let hits = contact.penetrating(u, 0.0)?;
    // The first obstacle that intersects the body, and its nodes.
    let Some(first) = hits.iter().map(|&(_, o)| o).min() else { return Ok(()) };
    let bad: Vec<usize> = hits.iter().filter(|&&(_, o)| o == first).map(|&(v, _)| v).collect();
    let tags: Vec<String> =
        bad.iter().take(10).map(|&v| d.surface.mesh.node_tags[v].to_string()).collect();
    // Past the obstacles: a slave node's plane (the master body).
    let what = if first < spec.obstacles.len() {
        spec.obstacle_key(first)
    } else {
        "a master body (contact.master or contact.pairs)".to_string()
    };
    Err(Error::Scene(format!(
        "{what} already intersects the body at t = 0: {} contact node(s) penetrate it (gmsh nodes {}{})",
        bad.len(),
        tags.join(", "),
        if bad.len() > 10 { ", ..." } else { "" }
    )))
}
