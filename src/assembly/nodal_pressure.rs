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

    /// The nodes' pressures at finite strain, `L_a / V_a ln(theta_a) / theta_a` with
    /// `theta_a = v_a / V_a` (zero at nodes of no such cell), from the current nodal volumes
    /// `v_a` (a node vector). Collective.
    pub fn finite_pressure(&self, current: &Vector) -> Result<Vector> {
        let mut p = self.volume.duplicate()?;
        let vol = self.volume.with_local_slice(|s| s.to_vec())?;
        let lv = self.lambda_volume.with_local_slice(|s| s.to_vec())?;
        current.with_local_slice(|v| {
            p.with_local_slice_mut(|ps| {
                for i in 0..vol.len() {
                    let th = if vol[i] > 0.0 { v[i] / vol[i] } else { 1.0 };
                    ps[i] = if vol[i] > 0.0 { lv[i] / vol[i] * th.ln() / th } else { 0.0 };
                }
            })
        })??;
        Ok(p)
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

/// The averaged nodal pressure of neo-Hookean simplices at finite strain
/// (`fem::hyperelastic::NodalPressure`): the stored energy's volumetric part
/// `sum_a L_a/2 (ln theta_a)^2`, `theta_a = v_a / V_a`, with the current nodal volumes
/// `v_a = sum_{K ∋ a} |K_0| J_K / (d + 1)` summed by the owners from every rank's cells,
/// the nodes' algorithmic pressures handed back to the cells, and the tangent's coupling
/// through them, `sum_a dp_a/dv_1,a R_a (x) B_a` with `R_a = sum_{K ∋ a} d f_K/d p_K / (d + 1)`
/// and `B_a = d v_1,a / d u_1`: PETSc's distributed `R^T diag(dp/dv) B`, in the pattern of
/// the small-strain `G^T D G` (nodes two cells apart), which the step operator already has.
pub struct NodalVolumes {
    /// `V_a`, `L_a` and the pattern of `G`.
    reference: NodalDilatation,
    /// The current volumes of both states, the pressures and their derivatives (node
    /// vectors, made once).
    v0: Vector,
    v1: Vector,
    p: Vector,
    dp: Vector,
    /// Node values at the internal force's local slots, and the scatter between the two.
    gather: crate::petsc::Scatter,
    local: Vector,
    /// The tangent's factors `R` and `B` (node rows, DOF columns) and `R^T diag(dp) B`.
    r: Matrix,
    b: Matrix,
    product: Option<Matrix>,
    dim: usize,
}

/// What [`NodalVolumes::pressures`] found: the nodes' pressures at the local slots and this
/// rank's share of the volumetric energies of both states.
pub struct NodalState {
    pub pressure: Vec<f64>,
    pub w0: f64,
    pub w1: f64,
}

impl NodalVolumes {
    /// For the nodes `slots` (the internal force's local slots, mesh node numbers in slot
    /// order); `None` on every rank when no cell's volumetric part is nodal. Collective.
    pub fn new(
        mesh: &Mesh,
        part: &Partition,
        material: &dyn Fn(usize) -> Material,
        slots: &[usize],
    ) -> Result<Option<NodalVolumes>> {
        let Some(reference) = NodalDilatation::build(mesh, part, material)? else {
            return Ok(None);
        };
        let dim = part.dim;
        let world = mpi::topology::SimpleCommunicator::world();
        let k = slots.len();
        let mut offset = 0usize;
        world.scan_into(&k, &mut offset, mpi::collective::SystemOperation::sum());
        let total = crate::comm::sum_over_ranks(&world, k as f64) as usize;
        let local = Vector::new_mpi(k, total, 1)?;
        let from: Vec<i32> = slots.iter().map(|&v| (part.dof(v, 0) / dim) as i32).collect();
        let to: Vec<i32> = (offset - k..offset).map(|i| i as i32).collect();
        let gather = crate::petsc::Scatter::new(&reference.volume, &from, &local, &to)?;
        let (r, b) = (reference.g.duplicate(false)?, reference.g.duplicate(false)?);
        let dup = || reference.volume.duplicate();
        Ok(Some(NodalVolumes {
            v0: dup()?,
            v1: dup()?,
            p: dup()?,
            dp: dup()?,
            gather,
            local,
            r,
            b,
            product: None,
            dim,
            reference,
        }))
    }

    /// From the local slots' volume sums of both states (`sum_{K ∋ a} |K_0| J_K / (d + 1)`
    /// over this rank's cells): the nodes' algorithmic pressures
    /// (`fem::hyperelastic::volumetric_pressure` of `L_a / V_a` in `v_a / V_a`, per unit
    /// current volume) at the local slots, and the energies. With `tangent`, the factors
    /// `R` and `B` are zeroed for [`NodalVolumes::add_rows`]. Collective.
    pub fn pressures(&mut self, a0: &[f64], a1: &[f64], tangent: bool) -> Result<NodalState> {
        for (sums, v) in [(a0, &mut self.v0), (a1, &mut self.v1)] {
            self.local.with_local_slice_mut(|s| s.copy_from_slice(sums))?;
            v.zero()?;
            self.gather.reverse_add(&self.local, v)?;
        }
        let (mut w0, mut w1) = (0.0, 0.0);
        {
            let vol = self.reference.volume.with_local_slice(|s| s.to_vec())?;
            let lv = self.reference.lambda_volume.with_local_slice(|s| s.to_vec())?;
            let v0 = self.v0.with_local_slice(|s| s.to_vec())?;
            let v1 = self.v1.with_local_slice(|s| s.to_vec())?;
            let mut dp = vec![0.0; vol.len()];
            let pv = self.p.with_local_slice_mut(|ps| {
                for i in 0..vol.len() {
                    if vol[i] <= 0.0 {
                        ps[i] = 0.0;
                        continue;
                    }
                    let (th0, th1) = (v0[i] / vol[i], v1[i] / vol[i]);
                    let (l0, l1) = (th0.ln(), th1.ln());
                    w0 += 0.5 * lv[i] * l0 * l0;
                    w1 += 0.5 * lv[i] * l1 * l1;
                    let (pa, dpa) =
                        crate::fem::hyperelastic::volumetric_pressure(lv[i] / vol[i], th0, th1);
                    ps[i] = pa;
                    dp[i] = dpa / vol[i];
                }
            });
            pv?;
            self.dp.with_local_slice_mut(|s| s.copy_from_slice(&dp))?;
        }
        self.gather.forward(&self.p, &mut self.local)?;
        let pressure = self.local.with_local_slice(|s| s.to_vec())?;
        if tangent {
            self.r.zero_entries()?;
            self.b.zero_entries()?;
        }
        Ok(NodalState { pressure, w0, w1 })
    }

    /// A cell's rows of `R` and `B`: `dforce / (d + 1)` and `dvolume / (d + 1)` at each of
    /// its nodes' rows (`dofs` its DOFs in the layout).
    pub fn add_rows(
        &mut self,
        part: &Partition,
        nodes: &[usize],
        dofs: &[i32],
        dforce: &[f64],
        dvolume: &[f64],
    ) -> Result<()> {
        let share = 1.0 / nodes.len() as f64;
        let rv: Vec<f64> = dforce.iter().map(|x| share * x).collect();
        let bv: Vec<f64> = dvolume.iter().map(|x| share * x).collect();
        for &a in nodes {
            let row = [(part.dof(a, 0) / self.dim) as i32];
            self.r.set_values(&row, dofs, &rv, true)?;
            self.b.set_values(&row, dofs, &bv, true)?;
        }
        Ok(())
    }

    /// `tangent += R^T diag(dp/dv_1) B` (within `tangent`'s pattern). Collective.
    pub fn add_tangent(&mut self, tangent: &mut Matrix) -> Result<()> {
        self.r.assemble()?;
        self.b.assemble()?;
        self.r.scale_rows(&self.dp)?;
        match self.product.as_mut() {
            Some(c) => c.product_again()?,
            None => self.product = Some(self.r.transpose_times(&self.b, self.dim)?),
        }
        tangent.axpy(1.0, self.product.as_ref().expect("product"), crate::petsc::Pattern::Subset)
    }
}
