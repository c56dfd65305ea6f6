//! The options of a run, read once at set-up (like PETSc tutorials' `ProcessOptions`): what
//! the command line's flags add to a scene ([`RunOptions`]), and the application's own
//! options after `--` (`massfree run SCENE -- -name value`, [`AppOptions`]), which live in
//! PETSc's options database beside PETSc's. [`AppOptions::read`] is the one place that reads
//! them; the run passes the parts down (the contact solver, the mortar pair, the step solver,
//! the integrator), so that nothing below the run looks an option up.

use std::path::PathBuf;

use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::console::Console;
use crate::contact::mortar::{InterfaceMode, MortarOptions, NormalKind};
use crate::contact::{ContactOptions, ContactSolverKind};
use crate::error::{Error, Result};
use crate::petsc::{OptionsBlock, Petsc};
use crate::phase::HangTimeout;

/// What the command line adds to a scene.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    pub output: Option<PathBuf>,
    pub overwrite: bool,
    /// Override the scene's number of steps.
    pub steps: Option<usize>,
    pub quiet: bool,
    /// Print the energies of every step.
    pub verbose: bool,
    /// Do not write the HDF5 file.
    pub no_output: bool,
    pub partition: crate::partition::Strategy,
    /// Every rank reads the whole mesh and cuts its part out of it (`--replicated-mesh`; by
    /// default each rank reads only blocks of the mesh file): a check of the default.
    pub replicated_mesh: bool,
    /// Continue from the checkpoint of this run's HDF5 file.
    pub restart: Option<PathBuf>,
    /// The PETSc options of the command line (recorded in the output).
    pub petsc_args: Vec<String>,
    /// When the watchdog ends a rank that waits for the others (a collective that hangs).
    pub hang_timeout: Option<HangTimeout>,
}

/// The scene's extra PETSc options (`solver.options`), entered only where the command line did
/// not set the same option: the command line wins.
pub fn apply_scene_options(tokens: &[String]) -> Result<()> {
    let mut i = 0;
    while i < tokens.len() {
        let name = &tokens[i];
        if !name.starts_with('-') || name.parse::<f64>().is_ok() {
            return Err(Error::Scene(format!(
                "solver.options: expected an option name starting with '-', found \"{name}\""
            )));
        }
        let value = tokens
            .get(i + 1)
            .filter(|v| !v.starts_with('-') || v.parse::<f64>().is_ok())
            .map(|v| v.as_str());
        i += if value.is_some() { 2 } else { 1 };
        if !Petsc::options_given(name)? {
            Petsc::options_set_given(name, value)?;
        }
    }
    Ok(())
}

/// Defaults the program enters in PETSc's options database for the step solver, where neither
/// the command line nor the scene set them (so that they also hold for a solver chosen there,
/// and can still be turned off): `-step_pc_gamg_reuse_interpolation true`. A contact solver
/// rewrites the operator near the contact when the active set changes; GAMG then keeps its
/// hierarchy's interpolation and recomputes only the coarse operators.
pub fn enter_solver_defaults() -> Result<()> {
    let reuse = "pc_gamg_reuse_interpolation";
    if !Petsc::options_given(&format!("-{reuse}"))?
        && !Petsc::options_given(&format!("-step_{reuse}"))?
    {
        Petsc::options_set(&format!("-step_{reuse}"), Some("true"))?;
    }
    Ok(())
}

/// Warns about the options given (on the command line after `--`, or in the scene's `[solver]
/// options`) that nothing read on any rank: one line each on stderr from rank 0, e.g.
/// `massfree: warning: option -step_reus was given but never used`. PETSc's `-options_left`,
/// on unless `-options_left false`; PETSc's own listing at `PetscFinalize` is turned off, so
/// nothing is reported twice. Options the program entered itself ([`Petsc::options_set`]) are
/// never reported. Called at the end of a run that completed (collective).
pub fn warn_unused(world: &SimpleCommunicator, console: &Console) -> Result<()> {
    let on = Petsc::options_get_bool("-options_left")?.unwrap_or(true);
    Petsc::options_set("-options_left", Some("false"))?;
    if !on {
        return Ok(());
    }
    let mine = Petsc::options_unused()?;
    // An option counts as used if any rank read it (a rank's solvers may differ: a rank
    // without contact nodes, without layer rows). Each rank's list, NUL-terminated.
    let mut bytes = mine.join("\n").into_bytes();
    bytes.push(0);
    let all = crate::comm::gather_all(world, &bytes);
    let lists: Vec<Vec<&str>> = all
        .split(|&b| b == 0)
        .take(world.size() as usize)
        .map(|l| std::str::from_utf8(l).unwrap_or("").lines().collect())
        .collect();
    for name in &mine {
        if lists.iter().all(|l| l.contains(&name.as_str())) {
            console.warn(format!("option {name} was given but never used"));
        }
    }
    Ok(())
}

/// Every application option of a run, with the defaults of options not given. The table of
/// [`AppOptions::read`] is the list `massfree run SCENE -- -help` prints.
#[derive(Debug, Clone)]
pub struct AppOptions {
    /// The contact solver against rigid obstacles: `-contact_solver`, `-contact_loose_rtol`,
    /// `-contact_reference_solve`.
    pub contact: ContactOptions,
    /// The two-body (mortar) pairs: `-mortar_interface`, `-mortar_update_distance`,
    /// `-mortar_update_in_contact`, `-mortar_normal`, `-mortar_jacobian`, `-mortar_gap_rows`,
    /// `-mortar_geometry_tol`.
    pub mortar: MortarOptions,
    /// `-massless_energy_correction` (default true): with massless DOFs, a contact step whose
    /// active set changed gets the force that takes out the work the contact did
    /// (`time::Midpoint::correct_energy`).
    pub massless_energy_correction: bool,
    /// `-massless_correction_blend` (default true): a corrected step whose two solves share
    /// an active set takes the interpolated increment and contact data at the model's root
    /// without a confirming solve (`false`: always the confirming solve).
    pub massless_correction_blend: bool,
    /// `-massless_correction_kick` (default true): a corrected step against rigid obstacles
    /// without friction is settled without any solve, its increment moved along the massive
    /// motion relative to the mean with the layer's static response (`time::Midpoint::kick`);
    /// `false`: the correction's solves.
    pub massless_correction_kick: bool,
    /// `-massless_drift_rtol X` (default `time::Midpoint::DRIFT_RTOL`, 1e-7): following the
    /// bodies, the work of steady contact steps is collected up to this fraction of the
    /// energy before the correction puts it back.
    pub massless_drift_rtol: Option<f64>,
    /// `-ksp_reuse_preconditioner` or `-step_ksp_reuse_preconditioner` given (PETSc's own
    /// options; default not given): PETSc's value holds. Without them a multigrid step
    /// preconditioner is built once and kept when the contact rewrites the operator.
    pub user_reuse_preconditioner: bool,
    /// The step's own CG and its kept products (`time::cg`): `-step_reuse` (default true;
    /// used by CG steps without contact), `-step_reuse_refresh N` (default 16),
    /// `-step_predictor`, `-step_energy_rtol X` (default 1e-13), `-step_layer` (default true:
    /// the mass-free layer's rows factored, `time::layer`), `-step_layer_local` (default: true
    /// in 3D, false in 2D; each rank sweeps its own part of the layer). `None`: off.
    pub step_reuse: Option<crate::time::Reuse>,
    /// `-step_layer_around` (default false): the mass-free layer's rows swept around PETSc's
    /// preconditioner too (Jacobi or block Jacobi/ILU: contact steps, and every step of runs
    /// with contact; `time::layer::LayerShell`). Off by default: on the disc and the ball it
    /// saved 2-6% of the contact steps' iterations and cost more time than that.
    pub step_layer_around: bool,
    /// `-step_predictor zero|last|extrapolate` (default extrapolate), for contact steps too
    /// (their first solve's guess).
    pub step_predictor: crate::time::Predictor,
    /// `-ksp_type`, `-pc_type`, `-step_ksp_type` or `-step_pc_type` given (PETSc's own
    /// options, on the command line or in the scene's `[solver] options`): the step solver is
    /// named, so it is not chosen knowing the run (`time::choice`).
    pub step_solver_named: bool,
    /// `-step_choice run|regime` (default run): the step solver chosen knowing the run
    /// (`time::choice`: a factorization for long runs, block ILU for 3D contact) or by the
    /// CFL number alone (runs that must repeat to the bit on 2 ranks: parallel MUMPS does
    /// not).
    pub choice_by_run: bool,
    /// The Newton loop of finite-strain bodies (`time::newton`): `-newton_rtol X` (default
    /// 1e-10), `-newton_energy_rtol X` (1e-14), `-newton_max_it N` (25), `-newton_monitor`
    /// (each iteration's residual on stdout), `-newton_tangent_reuse X` (0).
    pub newton: crate::time::newton::NewtonOptions,
}

/// The choices of `-contact_solver`, `-mortar_interface`, ... in the order of their kinds.
const CONTACT_SOLVERS: [&str; 2] = ["pdas", "columns"];
const INTERFACES: [&str; 2] = ["follow", "frozen"];
const NORMALS: [&str; 2] = ["slave", "average"];
const JACOBIANS: [&str; 2] = ["differences", "closed_form"];
const PREDICTORS: [&str; 3] = ["zero", "last", "extrapolate"];
const CHOICES: [&str; 2] = ["run", "regime"];

impl AppOptions {
    /// The options as the database holds them: the command line's, then the scene's
    /// `[solver] options` where the command line did not set the same name
    /// ([`apply_scene_options`], called first). Each option is registered with PETSc with its
    /// description and default (`-help` lists them, like PETSc's own objects' options) and
    /// marked used. A bad value is an error naming the option.
    pub fn read() -> Result<AppOptions> {
        let contact = OptionsBlock::read("massfree: contact with rigid obstacles", |b| {
            Ok(ContactOptions {
                solver: match b.choice(
                    "-contact_solver",
                    "Active-set solver against rigid obstacles: pdas (one projected solve per iteration) or columns (Schur complement from stored columns; no friction)",
                    &CONTACT_SOLVERS,
                    0,
                )? {
                    0 => ContactSolverKind::Pdas,
                    _ => ContactSolverKind::Columns,
                },
                loose_rtol: b.real_or(
                    "-contact_loose_rtol",
                    "pdas: relative tolerance of the solves until the active set repeats (then one solve to full accuracy)",
                    "sqrt(step solver rtol)",
                )?,
                reference_solve: b.bool(
                    "-contact_reference_solve",
                    "pdas: also solve each contact step without contact, for the cost ratio in the summary",
                    false,
                )?,
            })
        })?;
        let mortar = OptionsBlock::read("massfree: contact between bodies (mortar)", |b| {
            // `-mortar_update_in_contact` updates the frozen interface explicitly: alone it
            // asks for that interface; with `-mortar_interface follow` it makes no sense.
            let update_in_contact = b.bool(
                "-mortar_update_in_contact",
                "Evaluate the frozen interface again at every contact step too (explicit update; alone it selects -mortar_interface frozen)",
                false,
            )?;
            let mode = match b.choice(
                "-mortar_interface",
                "The interface follows the bodies in every contact step (finite sliding) or is kept from the touch-down (frozen: small sliding, faster)",
                &INTERFACES,
                usize::from(update_in_contact),
            )? {
                0 => InterfaceMode::Follow,
                _ => InterfaceMode::Frozen,
            };
            if mode == InterfaceMode::Follow && update_in_contact {
                return Err(Error::Usage(
                    "-mortar_update_in_contact is an update of the frozen interface: -mortar_interface follow evaluates it in contact already".into(),
                ));
            }
            Ok(MortarOptions {
                update_distance: b.real_or(
                    "-mortar_update_distance",
                    "Out of contact, evaluate the interface again once a node has moved this far (inf: the reference configuration only)",
                    "0.1 x smallest slave facet",
                )?,
                update_in_contact,
                normal: match b.choice(
                    "-mortar_normal",
                    "Normal of the gaps and projections: the slave side's averaged nodal normals, or (2D) halfway to the master's",
                    &NORMALS,
                    0,
                )? {
                    0 => NormalKind::Slave,
                    _ => NormalKind::Average,
                },
                mode,
                closed_form: b.choice(
                    "-mortar_jacobian",
                    "follow: derivatives of the weighted gaps by central differences or in closed form",
                    &JACOBIANS,
                    0,
                )? == 1,
                gap_rows: b.bool(
                    "-mortar_gap_rows",
                    "follow: the active nodes' whole gap linearization in the basis change (a Newton step of the geometry per round)",
                    false,
                )?,
                geometry_tol: positive(
                    "-mortar_geometry_tol",
                    b.real_or(
                        "-mortar_geometry_tol",
                        "follow: the gap the planes may still miss when a step is done (the midpoint may move 1e5 times this)",
                        "1e-9 x slave surface extent",
                    )?,
                )?,
            })
        })?;
        let (energy_correction, blend, kick, drift) = OptionsBlock::read(
            "massfree: mass-free layer (massless DOFs) at contact",
            |b| {
                Ok((
                    b.bool(
                        "-massless_energy_correction",
                        "A contact step whose active set changed gets the force that puts back the work the contact took",
                        true,
                    )?,
                    b.bool(
                        "-massless_correction_blend",
                        "A corrected step whose two solves share an active set takes the interpolated increment without a confirming solve",
                        true,
                    )?,
                    b.bool(
                        "-massless_correction_kick",
                        "Rigid obstacles without friction: settle a corrected step without solving it again (the layer's static response)",
                        true,
                    )?,
                    b.real(
                        "-massless_drift_rtol",
                        "Following the bodies: the work of steady contact steps collected up to this fraction of the energy, then put back",
                        crate::time::Midpoint::DRIFT_RTOL,
                    )?,
                ))
            },
        )?;
        let step = OptionsBlock::read("massfree: step solver", |b| {
            let reuse = b.bool(
                "-step_reuse",
                "Steps without contact solved by the program's own CG, which keeps K du, A u and M v from step to step (false: PETSc's KSP)",
                true,
            )?;
            let refresh = b.int(
                "-step_reuse_refresh",
                "The kept products are computed afresh every this many steps",
                crate::time::Reuse::default().refresh as i32,
            )?;
            let predictor = b.choice(
                "-step_predictor",
                "First guess of a step's solve: zero, the last increment, or 2 du^n - du^(n-1)",
                &PREDICTORS,
                2,
            )?;
            let energy_rtol = b.real(
                "-step_energy_rtol",
                "The energy error a solve of the own CG may leave, relative to the energy (with prescribed displacements)",
                crate::time::Reuse::default().energy_rtol,
            )?;
            let layer = b.bool(
                "-step_layer",
                "Steps solved by the own CG + Jacobi sweep the mass-free layer's massless rows exactly (factored block)",
                true,
            )?;
            let layer_local = b.bool_or(
                "-step_layer_local",
                "Each rank factors and sweeps its own part of the layer (false: the whole layer gathered on every rank)",
                "true in 3D, false in 2D",
            )?;
            let around = b.bool(
                "-step_layer_around",
                "Also sweep the layer's rows around PETSc's preconditioner (Jacobi, block Jacobi/ILU: contact steps)",
                false,
            )?;
            let by_run = b.choice(
                "-step_choice",
                "Step solver chosen knowing the run (factorization for long runs, block ILU for 3D contact) or by the CFL number alone (regime)",
                &CHOICES,
                0,
            )? == 0;
            Ok((reuse, refresh, predictor, energy_rtol, layer, layer_local, around, by_run))
        })?;
        let (reuse, refresh, predictor, energy_rtol, layer, layer_local, around, by_run) = step;
        let predictor = match predictor {
            0 => crate::time::Predictor::Zero,
            1 => crate::time::Predictor::Last,
            _ => crate::time::Predictor::Extrapolate,
        };
        let newton = OptionsBlock::read("massfree: Newton loop of finite-strain bodies", |b| {
            let d = crate::time::newton::NewtonOptions::default();
            newton_options(
                b.real(
                    "-newton_rtol",
                    "Residual 2-norm relative to the sum of the norms of its terms",
                    d.rtol,
                )?,
                b.real(
                    "-newton_energy_rtol",
                    "The step's energy error |du.r|/2 relative to the energy",
                    d.energy_rtol,
                )?,
                b.int(
                    "-newton_max_it",
                    "Newton iterations (linear solves) per step at most",
                    d.max_it as i32,
                )?,
                b.bool(
                    "-newton_monitor",
                    "Print each Newton iteration's residual and energy error",
                    d.monitor,
                )?,
                b.real(
                    "-newton_tangent_reuse",
                    "Steps without contact keep the tangent while an iteration shrinks the residual by this factor (0: a new tangent every iteration)",
                    d.tangent_reuse,
                )?,
            )
        })?;
        Ok(AppOptions {
            contact,
            mortar,
            massless_energy_correction: energy_correction,
            massless_correction_blend: blend,
            massless_correction_kick: kick,
            massless_drift_rtol: positive("-massless_drift_rtol", Some(drift))?,
            user_reuse_preconditioner: Petsc::options_has("-ksp_reuse_preconditioner")?
                || Petsc::options_has("-step_ksp_reuse_preconditioner")?,
            step_reuse: step_reuse(reuse, refresh, predictor, energy_rtol, layer, layer_local)?,
            step_layer_around: layer && around,
            step_predictor: predictor,
            step_solver_named: any_given(&[
                "-ksp_type",
                "-pc_type",
                "-step_ksp_type",
                "-step_pc_type",
            ])?,
            choice_by_run: by_run,
            newton,
        })
    }
}

/// Whether any of the options `names` is given.
fn any_given(names: &[&str]) -> Result<bool> {
    for name in names {
        if Petsc::options_has(name)? {
            return Ok(true);
        }
    }
    Ok(false)
}

/// The Newton loop's options, checked.
fn newton_options(
    rtol: f64,
    energy_rtol: f64,
    max_it: i32,
    monitor: bool,
    tangent_reuse: f64,
) -> Result<crate::time::newton::NewtonOptions> {
    if !(0.0..1.0).contains(&tangent_reuse) {
        return Err(Error::Usage(format!(
            "-newton_tangent_reuse {tangent_reuse}: give a contraction factor in [0, 1) (0: a new tangent every iteration)"
        )));
    }
    if max_it < 1 {
        return Err(Error::Usage(format!(
            "-newton_max_it {max_it}: give a whole number of iterations, at least 1"
        )));
    }
    Ok(crate::time::newton::NewtonOptions {
        rtol: positive("-newton_rtol", Some(rtol))?.unwrap_or(rtol),
        energy_rtol: positive("-newton_energy_rtol", Some(energy_rtol))?.unwrap_or(energy_rtol),
        max_it: max_it as usize,
        monitor,
        tangent_reuse,
    })
}

/// An option that must be positive and finite.
fn positive(name: &str, value: Option<f64>) -> Result<Option<f64>> {
    match value {
        Some(x) if !(x > 0.0 && x.is_finite()) => {
            Err(Error::Usage(format!("{name} {x}: give a positive number")))
        }
        v => Ok(v),
    }
}

/// The step's own CG, or `None` with `-step_reuse false`.
fn step_reuse(
    on: bool,
    refresh: i32,
    predictor: crate::time::Predictor,
    energy_rtol: f64,
    layer: bool,
    layer_local: Option<bool>,
) -> Result<Option<crate::time::Reuse>> {
    if refresh < 1 {
        return Err(Error::Usage(format!(
            "-step_reuse_refresh {refresh}: give a whole number of steps, at least 1"
        )));
    }
    if energy_rtol.is_nan() || energy_rtol <= 0.0 {
        return Err(Error::Usage(format!(
            "-step_energy_rtol {energy_rtol}: give a positive number"
        )));
    }
    let r = crate::time::Reuse {
        refresh: refresh as usize,
        predictor,
        energy_rtol,
        layer,
        layer_local,
    };
    Ok(on.then_some(r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_checked_with_their_defaults() {
        let p = crate::time::Predictor::Extrapolate;
        let r = step_reuse(true, 16, p, 1e-13, true, None).unwrap().expect("on");
        assert_eq!((r.refresh, r.predictor, r.layer_local), (16, p, None));
        assert!(step_reuse(false, 16, p, 1e-13, true, None).unwrap().is_none());
        let d = crate::time::newton::NewtonOptions::default();
        let n = newton_options(d.rtol, d.energy_rtol, d.max_it as i32, false, 0.0).unwrap();
        assert_eq!((n.rtol, n.energy_rtol, n.max_it), (1e-10, 1e-14, 25));
        assert_eq!(positive("-x", Some(2.0)), Ok(Some(2.0)));
        assert!(positive("-x", Some(f64::INFINITY)).is_err());
    }

    #[test]
    fn bad_values_name_the_option() {
        let p = crate::time::Predictor::Extrapolate;
        let e = step_reuse(true, 0, p, 1e-13, true, None).unwrap_err().to_string();
        assert_eq!(
            e,
            "usage error: -step_reuse_refresh 0: give a whole number of steps, at least 1"
        );
        let e = step_reuse(true, 16, p, 0.0, true, None).unwrap_err().to_string();
        assert_eq!(e, "usage error: -step_energy_rtol 0: give a positive number");
        let e = newton_options(1e-10, 1e-14, 0, false, 0.0).unwrap_err().to_string();
        assert_eq!(
            e,
            "usage error: -newton_max_it 0: give a whole number of iterations, at least 1"
        );
        let e = newton_options(1e-10, 1e-14, 25, false, 1.0).unwrap_err().to_string();
        assert!(e.starts_with("usage error: -newton_tangent_reuse 1: give a contraction"), "{e}");
        let e = newton_options(-1.0, 1e-14, 25, false, 0.0).unwrap_err().to_string();
        assert_eq!(e, "usage error: -newton_rtol -1: give a positive number");
        let e = positive("-mortar_geometry_tol", Some(0.0)).unwrap_err().to_string();
        assert_eq!(e, "usage error: -mortar_geometry_tol 0: give a positive number");
    }
}
