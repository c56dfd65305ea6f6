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

/// Assemble the mass matrix, cell by cell: `cell_mass(c)` gives the density and the mass
/// treatment of cell `c` (`crate::bodies::Bodies::cell_mass`; one kind for the whole mesh
/// without `[[body]]`). Consistent cells get `M_K`, lumped cells its row-sum diagonal, modified
/// cells `E_K^T M_K E_K` where they are in `layer` (`build_layer`'s result) and `M_K` elsewhere.
pub fn mass_matrix<F>(
    mesh: &Mesh,
    part: &Partition,
    cell_mass: F,
    layer: Option<&MassFreeLayer>,
) -> Result<Matrix>
where
    F: Fn(usize) -> (f64, MassKind),
{
    let dim = part.dim;
    assemble_blocks(mesh, part, |c, xy, nodes, out| {
        let (rho, kind) = cell_mass(c);
        let kernel = match kind {
            MassKind::Lumped => kernels::mass_lumped,
            MassKind::Consistent => kernels::mass,
            MassKind::Modified0 | MassKind::Modified1 => {
                // Layer cells: E_K^T M_K E_K on the source nodes; others: the standard M_K.
                if layer.and_then(|l| l.element_matrix(mesh, c, rho, nodes, out)).is_some() {
                    return Ok(());
                }
                kernels::mass
            }
        };
        out.resize((xy.len() * dim).pow(2), 0.0);
        kernel(mesh.cells[c].kind, xy, rho, out);
        Ok(())
    })
}
