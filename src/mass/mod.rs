//! Mass matrices: consistent `M`, row-sum lumped, and (METHOD.md section 3) the modified
//! mass-free-layer matrices `M_H^0`, `M_H^1` = `sum_K E_K^T M_K E_K`. All go through the one
//! assembler (`assembly::assemble_blocks`) with the same preallocation.

pub mod layer;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

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

/// The layer of a rank's part of the mesh along the gathered contact surface (`contact_nodes`:
/// original node indices, sorted), `E_K` built on own cells; the totals are the whole layer's.
/// Collective: a failure on one rank (no partner, say) fails every rank with its message.
pub fn build_local_layer(
    world: &SimpleCommunicator,
    mesh: &Mesh,
    part: &Partition,
    kind: MassKind,
    contact_groups: &[&str],
    contact_nodes: &[usize],
) -> Result<Option<MassFreeLayer>> {
    let variant = match kind {
        MassKind::Modified0 => Variant::Zero,
        MassKind::Modified1 => Variant::One,
        _ => return Ok(None),
    };
    let is_contact: Vec<bool> = (part.node_original.iter())
        .map(|v| contact_nodes.binary_search(v).is_ok())
        .collect();
    let own = |c: usize| part.cell_rank[c] == part.rank;
    let name = contact_groups.join("\" and \"");
    let built = MassFreeLayer::from_contact_nodes(mesh, is_contact, own, variant, &name);
    let failure = crate::comm::first_failure(world, built.as_ref().err().map(|e| e.to_string()));
    let mut layer = match (built, failure) {
        (Ok(l), None) => l,
        (Err(e), _) => return Err(e),
        (Ok(_), Some(m)) => return Err(Error::Mesh(m)),
    };
    let own_cells = layer.layer_cells.iter().filter(|&&c| own(c)).count();
    let mut n = [own_cells as u64, 0];
    let mine = n;
    world.all_reduce_into(&mine[..], &mut n[..], SystemOperation::sum());
    layer.set_totals(contact_nodes.len(), n[0] as usize);
    Ok(Some(layer))
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
