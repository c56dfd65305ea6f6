//! The application's own command-line options (`massfree run SCENE -- -name value`): they
//! live in PETSc's options database beside PETSc's, and [`AppOptions::read`] is the one place
//! that reads them; the run passes the parts down (the contact solver, the mortar pair, the
//! step solver, the integrator), so that nothing below the run looks options up.
//!
//! A value that can be wrong is kept as a `Result` and its error raised where the value is
//! used: a bad `-contact_solver` fails only the runs with obstacle contact, at contact set-up,
//! after the errors that come before it there (the order in which a bad run reports them).

use crate::contact::mortar::{MortarOptions, NormalKind};
use crate::contact::{ContactOptions, ContactSolverKind};
use crate::error::{Error, Result};
use crate::petsc::Petsc;

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
    pub massless_energy_correction: Result<bool>,
    /// `-ksp_reuse_preconditioner` or `-step_ksp_reuse_preconditioner` given (PETSc's own
    /// options; default not given): PETSc's value holds. Without them a multigrid step
    /// preconditioner is built once and kept when the contact rewrites the operator.
    pub user_reuse_preconditioner: bool,
}

impl AppOptions {
    /// The options as the database holds them now (the command line, and the scene's
    /// `[solver]` options once the run has entered them). Fails only if PETSc does.
    pub fn read() -> Result<AppOptions> {
        Ok(AppOptions {
            contact: ContactOptions {
                solver: Petsc::options_get_string("-contact_solver")
                    .and_then(|v| contact_solver(v.as_deref())),
                loose_rtol: Petsc::options_get_real("-contact_loose_rtol"),
                reference_solve: Petsc::options_has("-contact_reference_solve")?,
            },
            mortar: MortarOptions {
                update_distance: Petsc::options_get_real("-mortar_update_distance"),
                update_in_contact: Petsc::options_has("-mortar_update_in_contact")?,
                normal: Petsc::options_get_string("-mortar_normal").and_then(mortar_normal),
            },
            massless_energy_correction: Petsc::options_get_string("-massless_energy_correction")
                .and_then(|v| massless_energy_correction(v.as_deref())),
            user_reuse_preconditioner: Petsc::options_has("-ksp_reuse_preconditioner")?
                || Petsc::options_has("-step_ksp_reuse_preconditioner")?,
        })
    }
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

fn mortar_normal(value: Option<String>) -> Result<NormalKind> {
    match value {
        None => Ok(NormalKind::Slave),
        Some(s) => NormalKind::parse(&s).ok_or_else(|| {
            Error::Scene(format!("-mortar_normal {s}: give slave (the default) or average"))
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
    }

    #[test]
    fn bad_values_name_the_option() {
        let e = contact_solver(Some("x")).unwrap_err().to_string();
        assert_eq!(e, "usage error: -contact_solver x: unknown contact solver (pdas or columns)");
        let e = mortar_normal(Some("x".into())).unwrap_err().to_string();
        assert_eq!(e, "scene error: -mortar_normal x: give slave (the default) or average");
        let e = massless_energy_correction(Some("")).unwrap_err().to_string();
        assert_eq!(e, "usage error: -massless_energy_correction : give true or false");
    }
}
