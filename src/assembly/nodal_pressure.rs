//! The averaged nodal pressure: `formulation = "mixed"` on triangles and tetrahedra
//! (docs/method.md, nearly incompressible bodies).
//!
//! A linear simplex has one constant dilatation, so one volumetric constraint per cell:
//! about as many constraints as DOFs in 2D and more than half of them in 3D, and the mesh
//! locks as `lambda/mu` grows. Here the dilatation is averaged over each node's patch of
//! cells instead (Bonet and Burton 1998):
//!
//! `theta_a = (G u)_a / V_a`, `(G u)_a = sum_{K ∋ a} int_K div u dx / (d + 1)`,
//! `V_a = sum_{K ∋ a} |K| / (d + 1)`,
//!
//! one constraint per node (half the DOFs in 2D, a third in 3D), and the stored energy is
//!
//! `W = sum_K int_K mu eps:eps dx + sum_a L_a / 2 theta_a^2`, `L_a = sum_{K ∋ a} lambda_K |K| / (d + 1)`,
//!
//! whose volumetric stiffness is `G^T diag(L_a / V_a^2) G`. It is still a quadratic energy
//! with a symmetric matrix: the midpoint step's energy identity, the mass-free layer and
//! contact use it as they use any stiffness. No pressure unknowns are added (the global system
//! keeps its size and stays positive definite, so the step solvers stay as they are); the
//! price is a wider pattern, the nodes two cells apart. An affine displacement gives every
//! node its exact dilatation (`G u = V_a div u`), so a constant pressure is reproduced
//! exactly (the patch test).
//!
//! Distributed like the other matrices: each rank adds its own cells' rows of `G` (node rows,
//! DOF columns) and its nodal sums, PETSc sends the rows of other ranks' nodes, and
//! `G^T D G` is PETSc's distributed triple product: no rank sees more than its cells.

use mpi::traits::*;

use crate::error::{Error, Result};
use crate::fem::kernels::{self, Material};
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::petsc::{Matrix, Vector};

/// Whether a cell's volumetric part is the nodal one: a mixed body's triangles and tetrahedra.
pub fn is_nodal(kind: crate::fem::element::ElementKind, mat: &Material) -> bool {
    mat.mean_dilatation && kind.is_simplex()
}

/// The material a cell's own stiffness kernel integrates: without `lambda` where the
/// volumetric part is nodal ([`volumetric_stiffness`] adds it), the cell's otherwise.
pub fn element_material(kind: crate::fem::element::ElementKind, mat: &Material) -> Material {
    if is_nodal(kind, mat) {
        Material { lambda: 0.0, ..*mat }
    } else {
        *mat
    }
}

/// The averaged nodal dilatation's operator of a mesh: `G` (owned node rows, DOF columns)
/// and the nodal sums `V_a` and `L_a` (node vectors).
pub struct NodalDilatation {
    pub g: Matrix,
    pub volume: Vector,
    pub lambda_volume: Vector,
}

impl NodalDilatation {
    /// `G`, `V_a` and `L_a` from this rank's cells whose volumetric part is nodal; `None`
    /// on every rank when no rank has such a cell. Collective.
    pub fn build(
        mesh: &Mesh,
        part: &Partition,
        material: &dyn Fn(usize) -> Material,
    ) -> Result<Option<NodalDilatation>> {
        let nodal = |c: usize| is_nodal(mesh.cells[c].kind, &material(c));
        let any = part.local_cells.iter().any(|&c| nodal(c));
        let world = mpi::topology::SimpleCommunicator::world();
        let mut any_anywhere = false;
        world.all_reduce_into(
            &any,
            &mut any_anywhere,
            mpi::collective::SystemOperation::logical_or(),
        );
        if !any_anywhere {
            return Ok(None);
        }
        let dim = part.dim;
        let (n_nodes, n_global) = (part.n_owned_nodes(), part.n_global_nodes());
        // Row a couples the DOFs of the nodes sharing a cell with a: the node graph's rows.
        let (d_nnz, o_nnz) = part.graph(mesh).preallocation_for(part, 1);
        let scale = |v: Vec<i32>| v.into_iter().map(|x| x * dim as i32).collect::<Vec<_>>();
        let mut g = Matrix::new_aij_rect(
            (n_nodes, n_global),
            (part.n_owned_dofs(), part.n_global_dofs(), dim),
            &scale(d_nnz),
            &scale(o_nnz),
        )?;
        let mut volume = Vector::new_mpi(n_nodes, n_global, 1)?;
        let mut lambda_volume = Vector::new_mpi(n_nodes, n_global, 1)?;
        let mut xy = [[0.0; 3]; 8];
        let mut b = [[0.0; 3]; 8];
        let (mut cols, mut vals) = (Vec::with_capacity(12), Vec::with_capacity(12));
        let mut failed = None;
        for &c in &part.local_cells {
            if !nodal(c) {
                continue;
            }
            let cell = &mesh.cells[c];
            let n = super::cell_coords(mesh, cell, &mut xy);
            let vol = match kernels::divergence_row(cell.kind, &xy[..n], &mut b[..n]) {
                Ok(v) => v,
                Err(e) => {
                    failed = Some(Error::Mesh(format!("{e} (gmsh element tag {})", cell.tag)));
                    break;
                }
            };
            let share = 1.0 / n as f64;
            super::node_dofs(part, &cell.nodes(), &mut cols);
            vals.clear();
            for bb in &b[..n] {
                vals.extend(bb[..dim].iter().map(|x| share * x));
            }
            let lambda = material(c).lambda;
            for a in cell.nodes() {
                let row = [(part.dof(a, 0) / dim) as i32];
                g.set_values(&row, &cols, &vals, true)?;
                volume.set_values(&row, &[share * vol], true)?;
                lambda_volume.set_values(&row, &[share * vol * lambda], true)?;
            }
        }
        // A bad cell on one rank must not leave the others in the assembly: agree first.
        let first = crate::comm::first_failure(&world, failed.as_ref().map(|e| e.to_string()));
        match (failed, first) {
            (Some(e), _) => return Err(e),
            (None, Some(m)) => return Err(Error::Mesh(m)),
            (None, None) => {}
        }
        g.assemble()?;
        volume.assemble()?;
        lambda_volume.assemble()?;
        Ok(Some(NodalDilatation { g, volume, lambda_volume }))
    }

    /// The volumetric stiffness `G^T diag(L_a / V_a^2) G` (DOF blocks of `dim`). Collective.
    pub fn stiffness(&self) -> Result<Matrix> {
        let (lo, hi) = self.volume.ownership_range();
        let n = hi - lo;
        let mut d = Matrix::new_aij(n, self.volume.global_size(), 1, &vec![1; n], &vec![0; n])?;
        let diag = self.volume.with_local_slice(|v| {
            self.lambda_volume.with_local_slice(|l| {
                v.iter()
                    .zip(l)
                    .map(|(&v, &l)| if v > 0.0 { l / (v * v) } else { 0.0 })
                    .collect::<Vec<_>>()
            })
        })??;
        for (i, x) in diag.iter().enumerate() {
            let r = [(lo + i) as i32];
            d.set_values(&r, &r, &[*x], false)?;
        }
        d.assemble()?;
        d.ptap(&self.g)
    }

    /// The nodal dilatations `theta_a = (G u)_a / V_a` (zero at nodes of no such cell), a
    /// node vector. Collective.
    pub fn dilatation(&self, u: &Vector) -> Result<Vector> {
        let mut theta = self.volume.duplicate()?;
        self.g.mult(u, &mut theta)?;
        self.volume.with_local_slice(|v| {
            theta.with_local_slice_mut(|t| {
                for (t, &v) in t.iter_mut().zip(v) {
                    *t = if v > 0.0 { *t / v } else { 0.0 };
                }
            })
        })??;
        Ok(theta)
    }
}

/// The stiffness of a mesh whose mixed bodies have simplices: each cell's own part
/// (`element` assembles it, with [`element_material`]) plus the nodal volumetric part; `None`
/// when no cell's volumetric part is nodal. Collective.
pub fn volumetric_stiffness(
    mesh: &Mesh,
    part: &Partition,
    material: &dyn Fn(usize) -> Material,
) -> Result<Option<Matrix>> {
    match NodalDilatation::build(mesh, part, material)? {
        Some(n) => Ok(Some(n.stiffness()?)),
        None => Ok(None),
    }
}
