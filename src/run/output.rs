//! The output file through a run: created first, with the scene and `status = running`, so
//! that a run failing in any later phase says so in its file; opened in parallel for the time
//! series once the solver is set up (the run's settings, the groups, the mass check, the
//! contact datasets); one step's energies, due fields and contact row per step, a checkpoint
//! every ten field outputs; closed with the summary and `finished`, or marked `failed: ...` /
//! `interrupted: ...` after an error.

use std::path::Path;
use std::time::Instant;

use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::domain::Domain;
use super::options::RunOptions;
use super::stress::StressFields;
use super::views::Views;
use crate::contact::ContactSolver;
use crate::error::{Error, Result};
use crate::fem::stress::Quantity;
use crate::io::{group_key, layout, Checkpoint, Meta, Output, OutputPlan, PlannedField, RunFile};
use crate::mass::MassFreeLayer;
use crate::phase::{self, Phase};
use crate::report::{MassCheck, RunSummary, Timings};
use crate::rows::{ContactRow, Location};
use crate::scene::{Field, Scene};
use crate::time::{Midpoint, StepOperator};

/// What a step writes of the contact: the solver (its nodes and weights), the step's row and
/// the contact nodes' normals.
pub struct ContactStep<'r> {
    pub solver: &'r dyn ContactSolver,
    pub row: &'r ContactRow,
    pub normals: &'r [[f64; 3]],
}

/// The output file in its three states.
pub enum RunOutput {
    /// `--no-output`, or after the end.
    None,
    /// Created: metadata only, written by rank 0's serial handle.
    Closed(RunFile),
    /// Open in parallel for the time series.
    Open(Box<Output>),
}

impl RunOutput {
    /// Create the file (rank 0 writes, all wait) with the scene, the version, `status =
    /// running` and the effects the scene asks for.
    pub fn create(
        world: &SimpleCommunicator,
        scene: &Scene,
        opts: &RunOptions,
    ) -> Result<RunOutput> {
        if opts.no_output {
            return Ok(RunOutput::None);
        }
        let path = opts.output.clone().unwrap_or_else(|| scene.output.file.clone());
        if let Some(src) = &opts.restart {
            let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
                (Ok(x), Ok(y)) => x == y,
                _ => a == b,
            };
            if same(src, &path) {
                return Err(Error::Usage(format!(
                    "--restart {}: the continued run must be written to another file (-o NEW.h5)",
                    src.display()
                )));
            }
        }
        let items = [
            Meta::text("scene", scene.text.clone()),
            Meta::text("version", env!("CARGO_PKG_VERSION")),
            Meta::text("status", "running"),
            Meta::text("effects", scene.effects().summary()),
            Meta::int_on("/", "ranks", world.size() as i64),
        ];
        Ok(RunOutput::Closed(RunFile::create(world, &path, opts.overwrite, &items)?))
    }

    /// The file open for the time series, if any.
    pub fn open_file(&self) -> Option<&Output> {
        match self {
            RunOutput::Open(o) => Some(o),
            _ => None,
        }
    }

    /// Write the run's settings and the groups' metadata, then open the file in parallel for
    /// the time series. Returns the seconds it took.
    pub fn open(
        &mut self,
        d: &Domain,
        opts: &RunOptions,
        op: &StepOperator,
        contact: Option<&dyn ContactSolver>,
        layer: Option<&MassFreeLayer>,
        mass_check: &MassCheck,
    ) -> Result<f64> {
        let RunOutput::Closed(file) = std::mem::replace(self, RunOutput::None) else {
            return Ok(0.0);
        };
        phase::enter(Phase::OpeningOutput);
        let t0 = Instant::now();
        let (scene, mesh) = (&d.scene, &d.mesh);
        let dim = mesh.dim;
        let mut fields: Vec<PlannedField> = (scene.output.fields.iter())
            .map(|&f| PlannedField { spec: f.spec(dim), every: scene.every_of(f) })
            .collect();
        // Finite strain: the current positions with the displacement, for the XDMF index to
        // draw the deformed bodies (a small-strain file stays as it was).
        if d.bodies.finite_strain() && scene.output.fields.contains(&Field::Displacement) {
            fields.push(PlannedField {
                spec: crate::rows::FieldSpec::nodal(layout::POSITION, 3),
                every: scene.every_of(Field::Displacement),
            });
        }
        let plan = OutputPlan {
            fields,
            time_steps: scene.output.time_steps.clone(),
            compression: scene.output.compression,
        };
        let settings = settings(d, opts, op, layer);
        let settings_text: String = settings.iter().map(|(k, v)| format!("{k} = {v}\n")).collect();
        let solver_options =
            settings.iter().find(|(k, _)| k == "petsc_options").map_or("", |(_, v)| v.as_str());
        let mut meta = vec![
            // The effects as the mesh resolved them (the file was created with the scene's).
            Meta::text("effects", d.effects()),
            Meta::text("settings", settings_text),
            Meta::text("solver_options", solver_options),
        ];
        for g in &mesh.groups {
            let object = format!("mesh/groups/{}", group_key(&g.name));
            meta.push(Meta::int_on(&object, "dim", g.dim as i64));
        }
        // A slave/master pair: its groups as attributes of /contact (written by rank 0's serial
        // handle, `io::meta`), its master nodes below (created collectively). Every rank holds
        // the whole mesh and the scene, so names and nodes are the same on every rank.
        // Several pairs: the groups joined by ", " in pair order.
        let spec = scene.contact.as_ref().filter(|s| !s.pairs.is_empty());
        if let Some(c) = contact {
            let group = c.boundary().group.clone();
            meta.push(Meta::text_on(layout::CONTACT, layout::CONTACT_GROUP_ATTR, group));
            if let Some(spec) = spec {
                let (slaves, masters) =
                    (spec.slave_groups().join(", "), spec.master_groups().join(", "));
                meta.push(Meta::text_on(layout::CONTACT, layout::CONTACT_SLAVE_GROUP_ATTR, slaves));
                meta.push(Meta::text_on(
                    layout::CONTACT,
                    layout::CONTACT_MASTER_GROUP_ATTR,
                    masters,
                ));
                if let Some(g) = spec.obstacle_boundary() {
                    meta.push(Meta::text_on(
                        layout::CONTACT,
                        layout::CONTACT_OBSTACLE_GROUP_ATTR,
                        g,
                    ));
                }
            }
        }
        file.write_meta(d.world, &meta)?;
        let blocks = super::blocks::mesh_blocks(d)?;
        let mut out = Output::open(file, d.world, &blocks, plan)?;
        let mc = mass_check;
        out.write_mass_check(&mc.total_mass, &mc.first_moment, &mc.second_moment, &mc.probe)?;
        if let Some(c) = contact {
            let friction = d.scene.contact.as_ref().is_some_and(|s| s.has_friction());
            // The solvers' nodes are the contact surface's; the file has original numbers.
            let original = |s: &usize| d.surface.part.node_original[*s];
            let nodes: Vec<usize> = c.boundary().nodes.iter().map(original).collect();
            out.create_contact(&nodes, &c.boundary().weights, mesh.dim, friction)?;
            if let Some(spec) = spec {
                let groups: Vec<&str> = spec.master_groups();
                out.create_contact_pair(d.world, &d.surface.original_nodes(&groups)?)?;
            }
        }
        *self = RunOutput::Open(Box::new(out));
        Ok(t0.elapsed().as_secs_f64())
    }

    /// Write what is due at step n: energies always, fields when due, the contact row.
    /// Whether step `n` writes the velocity field (the mass-free layer's velocity must then
    /// be settled first).
    pub fn velocity_due(&self, d: &Domain, n: usize) -> bool {
        let Some(out) = self.open_file() else { return false };
        let due = out.due_fields(n);
        d.scene.output.fields.iter().zip(&due).any(|(f, &due)| due && *f == Field::Velocity)
    }

    pub fn write_step(
        &mut self,
        d: &Domain,
        views: &mut Views,
        stress: &mut StressFields,
        n: usize,
        midpoint: &Midpoint,
        contact: Option<ContactStep>,
    ) -> Result<()> {
        let Some(out) = self.open_file() else { return Ok(()) };
        let t = midpoint.time_at(n);
        let due = out.due_fields(n);
        let fields = &d.scene.output.fields;
        // The stress-type fields due now, computed together in one pass over the cells.
        let wanted: Vec<(Quantity, Location)> = fields
            .iter()
            .zip(&due)
            .filter(|(_, &due)| due)
            .filter_map(|(f, _)| f.derived())
            .collect();
        let mut derived = if wanted.is_empty() {
            Vec::new()
        } else {
            stress.blocks(views, &d.bodies, midpoint.u(), &wanted)?
        }
        .into_iter();
        let mut blocks = Vec::with_capacity(due.len());
        let mut displacement = None;
        let with_position = due.len() > fields.len();
        for (&field, &due) in fields.iter().zip(&due) {
            blocks.push(match (due, field.derived()) {
                (false, _) => None,
                (true, Some(_)) => derived.next(),
                (true, None) => Some(match field {
                    Field::Displacement => {
                        let u = views.to_natural(midpoint.u())?;
                        if with_position {
                            displacement = Some(u.clone());
                        }
                        u
                    }
                    Field::Velocity => views.to_natural(midpoint.v())?,
                    Field::ContactTraction => traction_block(d, contact.as_ref()),
                    other => {
                        return Err(Error::Internal(format!(
                            "{} is not a state field",
                            other.name()
                        )))
                    }
                }),
            });
        }
        // The planned fields after the scene's: the positions (finite strain), due with the
        // displacement.
        if with_position {
            blocks.push(displacement.map(|u| out.position_block(&u)));
        }
        let RunOutput::Open(out) = self else { unreachable!("checked above") };
        out.write_energy(n, t, midpoint.energy())?;
        if let Some(stats) = midpoint.newton_stats() {
            out.write_newton(stats.last)?;
        }
        if blocks.iter().any(Option::is_some) {
            out.write_fields(n, t, &blocks)?;
        }
        if let Some(c) = contact {
            out.write_contact(c.row, c.normals)?;
        }
        Ok(())
    }

    /// Write the checkpoint of step n (u, v, the last increment, the running works, the
    /// active set), when the file is open.
    pub fn write_checkpoint(
        &mut self,
        views: &mut Views,
        cp: &Checkpoint,
        midpoint: &Midpoint,
    ) -> Result<()> {
        let RunOutput::Open(out) = self else { return Ok(()) };
        let (u, v, du) = (
            views.to_natural(midpoint.u())?,
            views.to_natural(midpoint.v())?,
            views.to_natural(midpoint.du())?,
        );
        out.write_checkpoint(cp, &u, &v, &du)
    }

    /// The file's final metadata: status, summary and timings. A signal that arrived in the
    /// final phase is reported as such, with everything already written.
    pub fn finish(
        &mut self,
        world: &SimpleCommunicator,
        summary: &RunSummary,
        n_steps: usize,
    ) -> Result<()> {
        let interrupted = phase::stop_requested(world);
        let status = if interrupted {
            format!(
                "interrupted: a signal arrived after the last step ({n_steps} of {n_steps}); all steps and the summary are written"
            )
        } else {
            "finished".to_string()
        };
        if let RunOutput::Open(out) = std::mem::replace(self, RunOutput::None) {
            let text = toml::to_string(summary).unwrap_or_default();
            out.finish(
                world,
                &[
                    Meta::text("status", status.clone()),
                    Meta::text("summary", text),
                    Meta::text("timings", timings_text(&summary.timings)),
                ],
            )?;
        }
        phase::enter(Phase::Finished);
        if interrupted {
            return Err(Error::Interrupted(status["interrupted: ".len()..].to_string()));
        }
        Ok(())
    }

    /// Mark the file after an error: `interrupted: ...` for a signal, `failed: ...` otherwise.
    /// Closing a parallel file is collective, so this first makes sure that every rank has the
    /// error; if only this rank has it, it prints the error and aborts the job (the file then
    /// keeps `running`, which `massfree post` reports as a run that did not finish).
    pub fn fail(self, world: &SimpleCommunicator, agree: &SimpleCommunicator, e: &Error) {
        if !phase::all_reached(agree, std::time::Duration::from_secs(10)) {
            eprintln!("massfree: rank {}: {e}", world.rank());
            world.abort(1);
        }
        let status = match e {
            Error::Interrupted(m) => format!("interrupted: {m}"),
            other => format!("failed: {other}"),
        };
        let status = [Meta::text("status", status)];
        let marked = match self {
            RunOutput::None => Ok(()),
            RunOutput::Closed(f) => f.write_meta(world, &status),
            RunOutput::Open(out) => (*out).finish(world, &status),
        };
        if let (Err(m), 0) = (marked, world.rank()) {
            eprintln!("massfree: warning: the output file could not be marked: {m}");
        }
    }
}

/// The `timings` attribute: one `phase = seconds` line per phase.
fn timings_text(t: &Timings) -> String {
    format!(
        "mesh = {:e}\npartition = {:e}\nmigration = {:e}\nassembly = {:e}\nlayer = {:e}\nstiffness = {:e}\nsetup = {:e}\nstepping = {:e}\noutput = {:e}\nstress = {:e}\n",
        t.mesh, t.partition, t.migration, t.assembly, t.layer, t.stiffness, t.setup, t.stepping, t.output, t.stress
    )
}

/// This rank's block of `contact_traction`: `-p_q n_q` at the contact nodes (every rank holds
/// the contact nodes' rows), zero at every other node.
fn traction_block(d: &Domain, contact: Option<&ContactStep>) -> Vec<f64> {
    let dim = d.part.dim;
    let (lo, hi) = d.part.natural_block();
    let mut block = vec![0.0; (hi - lo) * dim];
    let Some(c) = contact else { return block };
    let boundary = c.solver.boundary();
    let traction = c.row.traction(&boundary.weights, c.normals, dim);
    for (q, &s) in boundary.nodes.iter().enumerate() {
        let v = d.surface.part.node_original[s];
        if (lo..hi).contains(&v) {
            block[(v - lo) * dim..(v - lo + 1) * dim]
                .copy_from_slice(&traction[q * dim..(q + 1) * dim]);
        }
    }
    block
}

/// The run's settings (`settings` attribute, one `key = value` line each).
fn settings(
    d: &Domain,
    opts: &RunOptions,
    op: &StepOperator,
    layer: Option<&MassFreeLayer>,
) -> Vec<(String, String)> {
    let scene = &d.scene;
    let bodies = scene.effects().bodies;
    let mut settings = vec![
        ("ranks".into(), d.size.to_string()),
        ("dim".into(), d.mesh.dim.to_string()),
        ("nodes".into(), d.part.n_global_nodes().to_string()),
        ("dofs".into(), d.part.n_global_dofs().to_string()),
        ("mass".into(), scene.mass.kind.name().to_string()),
        (
            "contact_boundary".into(),
            scene.mass.contact_boundary.clone().unwrap_or_else(|| "none".into()),
        ),
        (
            "mass_free_layer".into(),
            match layer {
                Some(l) => {
                    format!(
                        "{} contact nodes, {} layer cells",
                        l.n_contact_nodes(),
                        l.n_layer_cells()
                    )
                }
                None => "none".into(),
            },
        ),
        ("tau".into(), format!("{:e}", scene.tau)),
        ("steps".into(), d.n_steps.to_string()),
        ("ksp_type".into(), op.ksp.ksp_type().unwrap_or_default()),
        (
            "petsc_options".into(),
            (scene.solver.options.iter())
                .chain(opts.petsc_args.iter())
                .cloned()
                .collect::<Vec<_>>()
                .join(" "),
        ),
        ("pc_type".into(), op.ksp.pc_type().unwrap_or_default()),
        ("partition".into(), format!("{:?}", opts.partition)),
        ("metis_seed".into(), crate::partition::METIS_SEED.to_string()),
    ];
    if !bodies.is_empty() {
        settings.insert(5, ("bodies".into(), bodies.join("; ")));
    }
    settings
}
