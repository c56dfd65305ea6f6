//! The options of a run, read once at set-up (like PETSc tutorials' `ProcessOptions`): what
//! the command line's flags add to a scene ([`RunOptions`]), and the application's own
//! options after `--` (`massfree run SCENE -- -name value`, [`AppOptions`]), which live in
//! PETSc's options database beside PETSc's. [`AppOptions::read`] is the one place that reads
//! them; the run passes the parts down (the contact solver, the mortar pair, the step solver,
//! the integrator), so that nothing below the run looks an option up.

use std::path::PathBuf;

use crate::contact::mortar::{InterfaceMode, MortarOptions, NormalKind};
use crate::contact::{ContactOptions, ContactSolverKind};
use crate::error::{Error, Result};
use crate::petsc::Petsc;
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
    /// Every rank reads the whole mesh and cuts its part out of it (`--replicated-mesh`: how
    /// runs were set up before the mesh was read by blocks; repeats them, checks the other).
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
        if !Petsc::options_has(name)? {
            Petsc::options_set(name, value)?;
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
    if !Petsc::options_has(&format!("-{reuse}"))? && !Petsc::options_has(&format!("-step_{reuse}"))?
    {
        Petsc::options_set(&format!("-step_{reuse}"), Some("true"))?;
    }
    Ok(())
}

/// Every application option of a run, with the defaults of options not given.
#[derive(Debug, Clone)]
pub struct AppOptions {
    /// The contact solver against rigid obstacles: `-contact_solver`, `-contact_loose_rtol`,
    /// `-contact_reference_solve`.
    pub contact: ContactOptions,
    /// The two-body (mortar) pairs: `-mortar_update_distance`, `-mortar_update_in_contact`,
    /// `-mortar_normal`.
    pub mortar: MortarOptions,
    /// `-massless_energy_correction true|false` (also `1|0`, `yes|no`; default true): with
    /// massless DOFs, a contact step whose active set changed gets the force that takes out
    /// the work the contact did (`time::Midpoint::correct_energy`).
    pub massless_energy_correction: bool,
    /// `-massless_correction_blend true|false` (default true): a corrected step whose two
    /// solves share an active set takes the interpolated increment and contact data at the
    /// model's root without a confirming solve (`false`: always the confirming solve).
    pub massless_correction_blend: bool,
    /// `-massless_correction_kick true|false` (default true): a corrected step against rigid
    /// obstacles without friction is settled without any solve, its increment moved along
    /// the massive motion relative to the mean with the layer's static response
    /// (`time::Midpoint::kick`); `false`: the correction's solves.
    pub massless_correction_kick: bool,
    /// `-massless_drift_rtol X` (default `time::Midpoint::DRIFT_RTOL`, 1e-7): following the
    /// bodies, the work of steady contact steps is collected up to this fraction of the
    /// energy before the correction puts it back.
    pub massless_drift_rtol: Option<f64>,
    /// `-ksp_reuse_preconditioner` or `-step_ksp_reuse_preconditioner` given (PETSc's own
    /// options; default not given): PETSc's value holds. Without them a multigrid step
    /// preconditioner is built once and kept when the contact rewrites the operator.
    pub user_reuse_preconditioner: bool,
    /// The step's own CG and its kept products (`time::cg`): `-step_reuse true|false`
    /// (default true; used by CG steps without contact), `-step_reuse_refresh N` (default 16),
    /// `-step_predictor zero|last|extrapolate`, `-step_energy_rtol X`, `-step_layer
    /// true|false` (default true: the mass-free layer's rows factored, `time::layer`),
    /// `-step_layer_local true|false` (default: true in 3D, false in 2D; each rank sweeps its
    /// own part of the layer). `None`: off.
    pub step_reuse: Option<crate::time::Reuse>,
    /// `-step_layer_around true|false` (default false): the mass-free layer's rows swept
    /// around PETSc's preconditioner too (Jacobi or block Jacobi/ILU: contact steps, and
    /// every step of runs with contact; `time::layer::LayerShell`). Off by default: on the
    /// disc and the ball it saved 2-6% of the contact steps' iterations and cost more time
    /// than that (README "The layer's rows in the step solver").
    pub step_layer_around: bool,
    /// `-step_predictor`, for contact steps too (their first solve's guess).
    pub step_predictor: crate::time::Predictor,
    /// `-ksp_type`, `-pc_type`, `-step_ksp_type` or `-step_pc_type` given (PETSc's own
    /// options, on the command line or in the scene's `[solver] options`): the step solver is
    /// named, so it is not chosen knowing the run (`time::choice`).
    pub step_solver_named: bool,
    /// `-step_choice run|regime` (default run): the step solver chosen knowing the run
    /// (`time::choice`: a factorization for long runs, block ILU for 3D contact) or by the
    /// regime alone, as before issue 27 (runs that must repeat to the bit on 2 ranks:
    /// parallel MUMPS does not).
    pub choice_by_run: bool,
    /// The Newton loop of finite-strain bodies (`time::newton`): `-newton_rtol X` (default
    /// 1e-10), `-newton_energy_rtol X` (1e-14), `-newton_max_it N` (25), `-newton_monitor`
    /// (each iteration's residual on stdout).
    pub newton: crate::time::newton::NewtonOptions,
}

impl AppOptions {
    /// The options as the database holds them: the command line's, then the scene's
    /// `[solver] options` where the command line did not set the same name
    /// ([`apply_scene_options`], called first). A bad value is an error naming the option.
    pub fn read() -> Result<AppOptions> {
        // `-mortar_update_in_contact` updates the frozen interface explicitly: alone it asks
        // for that interface; with `-mortar_interface follow` it makes no sense.
        let asked = Petsc::options_get_string("-mortar_interface")?;
        let update_in_contact = Petsc::options_has("-mortar_update_in_contact")?;
        let follow = match (asked.is_none(), update_in_contact) {
            (true, true) => InterfaceMode::Frozen,
            _ => mortar_interface(asked)?,
        };
        if follow == InterfaceMode::Follow && update_in_contact {
            return Err(Error::Scene(
                "-mortar_update_in_contact is an update of the frozen interface: -mortar_interface follow evaluates it in contact already".into(),
            ));
        }
        Ok(AppOptions {
            contact: ContactOptions {
                solver: contact_solver(Petsc::options_get_string("-contact_solver")?.as_deref())?,
                loose_rtol: Petsc::options_get_real("-contact_loose_rtol")?,
                reference_solve: Petsc::options_has("-contact_reference_solve")?,
            },
            mortar: MortarOptions {
                update_distance: Petsc::options_get_real("-mortar_update_distance")?,
                update_in_contact,
                normal: mortar_normal(Petsc::options_get_string("-mortar_normal")?)?,
                mode: follow,
                closed_form: mortar_jacobian(Petsc::options_get_string("-mortar_jacobian")?)?,
                gap_rows: Petsc::options_has("-mortar_gap_rows")?,
                geometry_tol: positive(
                    "-mortar_geometry_tol",
                    Petsc::options_get_real("-mortar_geometry_tol")?,
                )?,
            },
            massless_energy_correction: massless_energy_correction(
                Petsc::options_get_string("-massless_energy_correction")?.as_deref(),
            )?,
            massless_correction_blend: on_by_default(
                "-massless_correction_blend",
                Petsc::options_get_string("-massless_correction_blend")?.as_deref(),
            )?,
            massless_correction_kick: on_by_default(
                "-massless_correction_kick",
                Petsc::options_get_string("-massless_correction_kick")?.as_deref(),
            )?,
            massless_drift_rtol: positive(
                "-massless_drift_rtol",
                Petsc::options_get_real("-massless_drift_rtol")?,
            )?,
            user_reuse_preconditioner: Petsc::options_has("-ksp_reuse_preconditioner")?
                || Petsc::options_has("-step_ksp_reuse_preconditioner")?,
            step_reuse: step_reuse(
                Petsc::options_get_string("-step_reuse")?.as_deref(),
                Petsc::options_get_real("-step_reuse_refresh")?,
                Petsc::options_get_string("-step_predictor")?.as_deref(),
                Petsc::options_get_real("-step_energy_rtol")?,
                Petsc::options_get_string("-step_layer")?.as_deref(),
                if Petsc::options_has("-step_layer_local")? {
                    Some(Petsc::options_get_string("-step_layer_local")?.unwrap_or_default())
                } else {
                    None
                }
                .as_deref(),
            )?,
            step_layer_around: step_layer(Petsc::options_get_string("-step_layer")?.as_deref())?
                && flag("-step_layer_around", Petsc::options_get_string("-step_layer_around")?)?,
            step_predictor: step_predictor(
                Petsc::options_get_string("-step_predictor")?.as_deref(),
            )?,
            step_solver_named: any_given(&[
                "-ksp_type",
                "-pc_type",
                "-step_ksp_type",
                "-step_pc_type",
            ])?,
            choice_by_run: match Petsc::options_get_string("-step_choice")?.as_deref() {
                None | Some("run") => true,
                Some("regime") => false,
                Some(other) => {
                    return Err(Error::Usage(format!("-step_choice {other}: give run or regime")))
                }
            },
            newton: newton_options(
                Petsc::options_get_real("-newton_rtol")?,
                Petsc::options_get_real("-newton_energy_rtol")?,
                Petsc::options_get_real("-newton_max_it")?,
                Petsc::options_has("-newton_monitor")?,
                Petsc::options_get_real("-newton_tangent_reuse")?,
            )?,
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

/// The Newton loop's tolerances over their defaults.
fn newton_options(
    rtol: Option<f64>,
    energy_rtol: Option<f64>,
    max_it: Option<f64>,
    monitor: bool,
    tangent_reuse: Option<f64>,
) -> Result<crate::time::newton::NewtonOptions> {
    let mut o = crate::time::newton::NewtonOptions { monitor, ..Default::default() };
    if let Some(x) = tangent_reuse {
        if !(0.0..1.0).contains(&x) {
            return Err(Error::Usage(format!(
                "-newton_tangent_reuse {x}: give a contraction factor in [0, 1) (0: a new tangent every iteration)"
            )));
        }
        o.tangent_reuse = x;
    }
    if let Some(x) = positive("-newton_rtol", rtol)? {
        o.rtol = x;
    }
    if let Some(x) = positive("-newton_energy_rtol", energy_rtol)? {
        o.energy_rtol = x;
    }
    if let Some(n) = max_it {
        if !(n >= 1.0 && n.fract() == 0.0 && n < 1e6) {
            return Err(Error::Usage(format!(
                "-newton_max_it {n}: give a whole number of iterations, at least 1"
            )));
        }
        o.max_it = n as usize;
    }
    Ok(o)
}

fn contact_solver(value: Option<&str>) -> Result<ContactSolverKind> {
    match value {
        None | Some("pdas") => Ok(ContactSolverKind::Pdas),
        Some("columns") => Ok(ContactSolverKind::Columns),
        Some(other) => Err(Error::Usage(format!(
            "-contact_solver {other}: unknown contact solver (pdas or columns)"
        ))),
    }
}

fn mortar_interface(value: Option<String>) -> Result<InterfaceMode> {
    match value.as_deref() {
        None | Some("follow") => Ok(InterfaceMode::Follow),
        Some("frozen") => Ok(InterfaceMode::Frozen),
        Some(s) => Err(Error::Scene(format!(
            "-mortar_interface {s}: give follow (the default: finite sliding) or frozen (small sliding, faster)"
        ))),
    }
}

fn mortar_jacobian(value: Option<String>) -> Result<bool> {
    match value.as_deref() {
        None | Some("differences") => Ok(false),
        Some("closed_form") => Ok(true),
        Some(s) => Err(Error::Scene(format!(
            "-mortar_jacobian {s}: give differences (the default) or closed_form"
        ))),
    }
}

/// A length option that must be positive and finite.
fn positive(name: &str, value: Option<f64>) -> Result<Option<f64>> {
    match value {
        Some(x) if !(x > 0.0 && x.is_finite()) => {
            Err(Error::Scene(format!("{name} {x}: give a positive number")))
        }
        v => Ok(v),
    }
}

fn mortar_normal(value: Option<String>) -> Result<NormalKind> {
    match value {
        None => Ok(NormalKind::Slave),
        Some(s) => NormalKind::parse(&s).ok_or_else(|| {
            Error::Scene(format!("-mortar_normal {s}: give slave (the default) or average"))
        }),
    }
}

fn step_reuse(
    on: Option<&str>,
    refresh: Option<f64>,
    predictor: Option<&str>,
    energy_rtol: Option<f64>,
    layer: Option<&str>,
    layer_local: Option<&str>,
) -> Result<Option<crate::time::Reuse>> {
    let on = match on {
        None | Some("1" | "true" | "yes") => true,
        Some("0" | "false" | "no") => false,
        Some(other) => {
            return Err(Error::Usage(format!("-step_reuse {other}: give true or false")));
        }
    };
    let mut r = crate::time::Reuse::default();
    if let Some(n) = refresh {
        if !(n >= 1.0 && n.fract() == 0.0 && n < 1e9) {
            return Err(Error::Usage(format!(
                "-step_reuse_refresh {n}: give a whole number of steps, at least 1"
            )));
        }
        r.refresh = n as usize;
    }
    r.predictor = step_predictor(predictor)?;
    if let Some(e) = energy_rtol {
        if !(e > 0.0) {
            return Err(Error::Usage(format!("-step_energy_rtol {e}: give a positive number")));
        }
        r.energy_rtol = e;
    }
    r.layer = step_layer(layer)?;
    r.layer_local = layer_local.map(|v| flag_value("-step_layer_local", Some(v))).transpose()?;
    Ok(on.then_some(r))
}

/// `-step_layer true|false` (default true).
fn step_layer(value: Option<&str>) -> Result<bool> {
    on_by_default("-step_layer", value)
}

/// A boolean option on by default.
fn on_by_default(name: &str, value: Option<&str>) -> Result<bool> {
    match value {
        None | Some("1" | "true" | "yes") => Ok(true),
        Some("0" | "false" | "no") => Ok(false),
        Some(other) => Err(Error::Usage(format!("{name} {other}: give true or false"))),
    }
}

/// A boolean option off by default (`-name` alone turns it on, as PETSc's flags do).
fn flag(name: &str, value: Option<String>) -> Result<bool> {
    if !Petsc::options_has(name)? {
        return Ok(false);
    }
    flag_value(name, value.as_deref())
}

/// The value of a flag that was given (alone: on).
fn flag_value(name: &str, value: Option<&str>) -> Result<bool> {
    match value {
        None | Some("" | "1" | "true" | "yes") => Ok(true),
        Some("0" | "false" | "no") => Ok(false),
        Some(other) => Err(Error::Usage(format!("{name} {other}: give true or false"))),
    }
}

/// `-step_predictor zero|last|extrapolate` (default extrapolate): the first guess of a step's
/// solve, with or without contact.
fn step_predictor(value: Option<&str>) -> Result<crate::time::Predictor> {
    match value {
        None => Ok(crate::time::Predictor::Extrapolate),
        Some(p) => crate::time::Predictor::parse(p).ok_or_else(|| {
            Error::Usage(format!("-step_predictor {p}: give zero, last or extrapolate"))
        }),
    }
}

fn massless_energy_correction(value: Option<&str>) -> Result<bool> {
    match value {
        None | Some("1" | "true" | "yes") => Ok(true),
        Some("0" | "false" | "no") => Ok(false),
        Some(other) => {
            Err(Error::Usage(format!("-massless_energy_correction {other}: give true or false")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_parse_with_their_defaults() {
        assert_eq!(contact_solver(None), Ok(ContactSolverKind::Pdas));
        assert_eq!(contact_solver(Some("columns")), Ok(ContactSolverKind::Columns));
        assert_eq!(mortar_normal(None), Ok(NormalKind::Slave));
        assert_eq!(mortar_normal(Some("average".into())), Ok(NormalKind::Average));
        assert_eq!(massless_energy_correction(None), Ok(true));
        assert_eq!(massless_energy_correction(Some("no")), Ok(false));
        let r = step_reuse(None, None, None, None, None, None).unwrap().expect("on by default");
        assert_eq!(r.refresh, 16);
        assert_eq!(r.predictor, crate::time::Predictor::Extrapolate);
        assert!(step_reuse(Some("false"), None, None, None, None, None).unwrap().is_none());
        let r =
            step_reuse(None, Some(100.0), Some("last"), Some(1e-12), None, None).unwrap().unwrap();
        assert_eq!(
            (r.refresh, r.predictor, r.energy_rtol),
            (100, crate::time::Predictor::Last, 1e-12)
        );
    }

    #[test]
    fn bad_values_name_the_option() {
        let e = contact_solver(Some("x")).unwrap_err().to_string();
        assert_eq!(e, "usage error: -contact_solver x: unknown contact solver (pdas or columns)");
        let e = mortar_normal(Some("x".into())).unwrap_err().to_string();
        assert_eq!(e, "scene error: -mortar_normal x: give slave (the default) or average");
        let e = massless_energy_correction(Some("")).unwrap_err().to_string();
        assert_eq!(e, "usage error: -massless_energy_correction : give true or false");
        let e = step_reuse(None, Some(0.5), None, None, None, None).unwrap_err().to_string();
        assert_eq!(
            e,
            "usage error: -step_reuse_refresh 0.5: give a whole number of steps, at least 1"
        );
        let e = step_reuse(None, None, None, None, None, Some("maybe")).unwrap_err().to_string();
        assert_eq!(e, "usage error: -step_layer_local maybe: give true or false");
        let local = |v| step_reuse(None, None, None, None, None, v).unwrap().unwrap().layer_local;
        assert_eq!(
            (local(None), local(Some("")), local(Some("no"))),
            (None, Some(true), Some(false))
        );
        let e =
            step_reuse(None, None, Some("quadratic"), None, None, None).unwrap_err().to_string();
        assert_eq!(e, "usage error: -step_predictor quadratic: give zero, last or extrapolate");
        let e = step_reuse(Some("maybe"), None, None, None, None, None).unwrap_err().to_string();
        assert_eq!(e, "usage error: -step_reuse maybe: give true or false");
    }
}
