//! Mass matrices: consistent `M`, row-sum lumped, and (docs/method.md, the mass-free layer) the modified
//! mass-free-layer matrices `M_H^0`, `M_H^1` = `sum_K E_K^T M_K E_K`. All go through the one
//! assembler (`assembly::assemble_node_blocks`), stored as node matrices ([`MassMatrix`]).

pub mod layer;

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use crate::assembly::assemble_node_blocks;
use crate::error::{Error, Result};
use crate::fem::kernels;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Matrix, Pattern, Vector};
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
    let is_contact: Vec<bool> =
        (part.node_original.iter()).map(|v| contact_nodes.binary_search(v).is_ok()).collect();
    let own = |c: usize| part.cell_rank[c] as usize == part.rank;
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

/// A mass matrix. Every mass here (consistent, lumped, `M_H^0`, `M_H^1`) acts on each
/// displacement component alike, `M = M_s ⊗ I_dim` (docs/method.md, the mass-free layer: `E_K` maps nodes, not
/// components), so the run stores only the node matrix `M_s`, a ninth of the DOF matrix in
/// 3D (at 3.9M DOFs on 2 ranks about 0.95 GB per rank less), and applies it through PETSc's
/// MAIJ. The products equal the DOF matrix's to round-off (PETSc's AIJ kernels may group a
/// row's terms differently; measured: 3e-15 relative in the state after a step). A DOF matrix
/// ([`MassMatrix::dofs`]) serves tests and general operators.
pub struct MassMatrix {
    storage: Storage,
}

enum Storage {
    /// `M_s` (owned nodes' rows) and `M_s ⊗ I_dim` as MAIJ for the products.
    Nodes { nodes: Matrix, product: Matrix, dim: usize },
    /// Any DOF matrix.
    Dofs(Matrix),
}

impl MassMatrix {
    /// `M_s ⊗ I_dim` from the node matrix `M_s`.
    pub fn kron(nodes: Matrix, dim: usize) -> Result<MassMatrix> {
        let product = nodes.maij(dim)?;
        Ok(MassMatrix { storage: Storage::Nodes { nodes, product, dim } })
    }

    /// A mass stored as a DOF matrix.
    pub fn dofs(m: Matrix) -> MassMatrix {
        MassMatrix { storage: Storage::Dofs(m) }
    }

    fn product(&self) -> &Matrix {
        match &self.storage {
            Storage::Nodes { product, .. } => product,
            Storage::Dofs(m) => m,
        }
    }

    /// `y = M x`.
    pub fn mult(&self, x: &Vector, y: &mut Vector) -> Result<()> {
        self.product().mult(x, y)
    }

    /// The diagonal of `M` (DOF vector).
    pub fn get_diagonal(&self, d: &mut Vector) -> Result<()> {
        match &self.storage {
            Storage::Dofs(m) => m.get_diagonal(d),
            Storage::Nodes { nodes, dim, .. } => {
                let mut ds = nodes.create_vecs()?.0;
                nodes.get_diagonal(&mut ds)?;
                let dim = *dim;
                ds.with_local_slice(|s| {
                    d.with_local_slice_mut(|x| {
                        for (i, xi) in x.iter_mut().enumerate() {
                            *xi = s[i / dim];
                        }
                    })
                })?
            }
        }
    }

    /// `k += alpha M`; `k` has the pattern of nodes sharing a cell, which holds every mass
    /// matrix's (the mass-free layer does not widen it, docs/method.md, the mass-free layer). Collective.
    pub fn add_to(&self, k: &mut Matrix, alpha: f64) -> Result<()> {
        match &self.storage {
            Storage::Dofs(m) => k.axpy(alpha, m, Pattern::Subset),
            Storage::Nodes { nodes, dim, .. } => {
                let dim = *dim;
                let (lo, hi) = nodes.ownership_range();
                let mut cols = Vec::new();
                let mut vals = Vec::new();
                for i in lo..hi {
                    nodes.with_row(i, |c, v| {
                        cols.clear();
                        cols.extend_from_slice(c);
                        vals.clear();
                        vals.extend(v.iter().map(|&m| alpha * m));
                    })?;
                    for comp in 0..dim {
                        let row = [(i * dim + comp) as i32];
                        let dof_cols: Vec<i32> =
                            cols.iter().map(|&j| j * dim as i32 + comp as i32).collect();
                        k.set_values(&row, &dof_cols, &vals, true)?;
                    }
                }
                k.assemble()
            }
        }
    }

    /// A copy (for loads that multiply by `M` at every evaluation).
    pub fn duplicate(&self) -> Result<MassMatrix> {
        Ok(match &self.storage {
            Storage::Dofs(m) => MassMatrix::dofs(m.duplicate(true)?),
            Storage::Nodes { nodes, dim, .. } => MassMatrix::kron(nodes.duplicate(true)?, *dim)?,
        })
    }
}

/// Assemble the mass matrix, cell by cell: `cell_mass(c)` gives the density and the mass
/// treatment of cell `c` (`crate::bodies::Bodies::cell_mass`; one kind for the whole mesh
/// without `[[body]]`). Consistent cells get `M_K`, lumped cells its row-sum diagonal, modified
/// cells `E_K^T M_K E_K` where they are in `layer` (`build_layer`'s result) and `M_K` elsewhere.
/// Stored as the node matrix ([`MassMatrix`]): the kernels' node blocks (`kernels::mass_nodes`,
/// `mass_lumped_nodes`; the layer's blocks checked to be `node block ⊗ I_dim`).
pub fn mass_matrix<F>(
    mesh: &Mesh,
    part: &Partition,
    cell_mass: F,
    layer: Option<&MassFreeLayer>,
) -> Result<MassMatrix>
where
    F: Fn(usize) -> (f64, MassKind),
{
    let dim = part.dim;
    let mut full = Vec::with_capacity(crate::assembly::MAX_EDOFS.pow(2));
    let nodes = assemble_node_blocks(mesh, part, |c, xy, nodes, out| {
        let (rho, kind) = cell_mass(c);
        let kernel = match kind {
            MassKind::Lumped => kernels::mass_lumped_nodes,
            MassKind::Consistent => kernels::mass_nodes,
            MassKind::Modified0 | MassKind::Modified1 => {
                // Layer cells: E_K^T M_K E_K on the source nodes; others: the standard M_K.
                if layer.and_then(|l| l.element_matrix(mesh, c, rho, nodes, &mut full)).is_some() {
                    return to_node_block(&full, nodes.len(), dim, out);
                }
                kernels::mass_nodes
            }
        };
        out.resize(xy.len().pow(2), 0.0);
        kernel(mesh.cells[c].kind, xy, rho, out);
        Ok(())
    })?;
    MassMatrix::kron(nodes, dim)
}

/// The node block of a DOF block `M_s ⊗ I_dim` (`n dim` square, interlaced): its first
/// component's entries, after checking that the block is that Kronecker product (a kernel
/// that coupled components would make the node storage wrong; the check is cheap next to
/// the kernel).
fn to_node_block(full: &[f64], n: usize, dim: usize, out: &mut Vec<f64>) -> Result<()> {
    let nd = n * dim;
    out.clear();
    for a in 0..n {
        for b in 0..n {
            out.push(full[(a * dim) * nd + b * dim]);
        }
    }
    let kron = (0..nd).all(|r| {
        (0..nd).all(|c| {
            let v = full[r * nd + c];
            if r % dim == c % dim {
                v == out[(r / dim) * n + c / dim]
            } else {
                v == 0.0
            }
        })
    });
    if kron {
        Ok(())
    } else {
        Err(Error::Internal("a mass element block is not (node block) x I_dim".into()))
    }
}
