//! Mass matrices: consistent `M`, row-sum lumped, and (METHOD.md section 3) the modified
//! mass-free-layer matrices `M_H^0`, `M_H^1` = `sum_K E_K^T M_K E_K`. All go through the one
//! assembler (`assembly::assemble_blocks`) with the same preallocation.

pub mod layer;

use crate::assembly::assemble_blocks;
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::Matrix;
use crate::scene::MassKind;

pub use layer::{MassFreeLayer, Variant};

/// The layer a mass kind needs (None for consistent and lumped).
pub fn build_layer(
    mesh: &Mesh,
    kind: MassKind,
    contact_boundaries: &[&str],
) -> Result<Option<MassFreeLayer>> {
    let variant = match kind {
        MassKind::Modified0 => Variant::Zero,
        MassKind::Modified1 => Variant::One,
        _ => return Ok(None),
    };
    if contact_boundaries.is_empty() {
        return Err(Error::Scene(format!(
            "mass.kind = {} needs mass.contact_boundary: the mass-free layer is built along the potential contact boundary",
            kind.name()
        )));
    }
    MassFreeLayer::build_along(mesh, contact_boundaries, variant).map(Some)
}

/// Assemble the mass matrix of the requested kind; `layer` must be `build_layer`'s result.
pub fn mass_matrix(
    mesh: &Mesh,
    part: &Partition,
    rho: f64,
    kind: MassKind,
    layer: Option<&MassFreeLayer>,
) -> Result<Matrix> {
    let dim = part.dim;
    match (kind, layer) {
        (MassKind::Consistent, _) => assemble_blocks(mesh, part, |c, xy, _, out| {
            out.resize((xy.len() * dim).pow(2), 0.0);
            kernels::mass(mesh.cells[c].kind, xy, rho, out);
            Ok(())
        }),
        (MassKind::Lumped, _) => assemble_blocks(mesh, part, |c, xy, _, out| {
            out.resize((xy.len() * dim).pow(2), 0.0);
            kernels::mass_lumped(mesh.cells[c].kind, xy, rho, out);
            Ok(())
        }),
        (_, Some(layer)) => assemble_blocks(mesh, part, |c, xy, nodes, out| {
            // Layer cells: E_K^T M_K E_K on the source nodes; others: the standard M_K.
            if layer.element_matrix(mesh, c, rho, nodes, out).is_none() {
                out.resize((xy.len() * dim).pow(2), 0.0);
                kernels::mass(mesh.cells[c].kind, xy, rho, out);
            }
            Ok(())
        }),
        (_, None) => Err(Error::Solver(format!(
            "mass.kind = {}: the mass-free layer was not built",
            kind.name()
        ))),
    }
}
