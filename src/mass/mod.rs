//! Mass matrices: consistent `M`, row-sum lumped, and (METHOD.md section 3) the modified
//! mass-free-layer matrices `M_H^0`, `M_H^1`. All go through the one assembler.

use crate::assembly::assemble_matrix;
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::Matrix;
use crate::scene::MassKind;

/// Assemble the mass matrix of the requested kind.
pub fn mass_matrix(mesh: &Mesh, part: &Partition, rho: f64, kind: MassKind) -> Result<Matrix> {
    match kind {
        MassKind::Consistent => assemble_matrix(mesh, part, |c, xy, out| {
            kernels::mass(mesh.cells[c].kind, xy, rho, out);
            Ok(())
        }),
        MassKind::Lumped => assemble_matrix(mesh, part, |c, xy, out| {
            kernels::mass_lumped(mesh.cells[c].kind, xy, rho, out);
            Ok(())
        }),
        other => Err(Error::Scene(format!(
            "mass.kind = {} is not available in this build (allowed: consistent, lumped)",
            other.name()
        ))),
    }
}
