//! Two-body contact with dual mortar multipliers, solved by the sparse primal-dual active set
//! ([`crate::contact::pdas::ActiveSet`]) in the mortar basis.
//!
//! Because `D` is diagonal, the change of basis `du = T u~`, `T = I + E`,
//! `E_(q,c),(l,c) = M_ql / D_qq` (slave rows, master columns, each component) makes the
//! linearized weighted gap node-local:
//!
//! ```text
//! g_q - n_q . (D_qq du_q - sum_l M_ql du_l) = D_qq (g_q / D_qq - n_q . u~_q),
//! u~_q = du_q - sum_l (M_ql / D_qq) du_l      (E^2 = 0, so T^{-1} = I - E).
//! ```
//!
//! In that basis the step is `T^T K T u~ = T^T rhs - factor sum_q D_qq lambda_q n_q e_q`:
//! each slave node meets one plane, which the active set solves unchanged; then `du = T u~`.
//! The slave nodes get the force `D lambda` (the inner solver's nodal force), the master
//! nodes `-M^T lambda`, and the contact work `-lambda^T (D n.du_s - M n.du_m)` equals
//! `-sum_q (D lambda)_q n_q . u~_q`, the inner solver's. Small sliding: `D`, `M`, normals and
//! gaps come from the reference configuration, once per run (METHOD.md 5b).
//!
//! Memory: `T` (O(slave nodes) entries beyond the identity) and `T^T K T`, a second operator
//! with `K`'s pattern widened at the slave nodes towards their master neighbours.

use super::MortarInterface;
use crate::contact::pdas::ActiveSet;
use crate::contact::{ContactNodes, ContactSolver, StepContact, StepSystem};
use crate::error::{Error, Result};
use crate::partition::Partition;
use crate::petsc::{Ksp, Matrix, Vector};

pub struct MortarActiveSet<'w> {
    inner: ActiveSet<'w>,
    /// `E` (without the identity) and `T = I + E`.
    e: Matrix,
    t: Matrix,
    /// `T^T K T`, its solver, and work vectors (built from the step operator by `prepare`).
    hat: Option<Hat>,
}

struct Hat {
    k: Matrix,
    ksp: Option<Ksp>,
    rhs: Vector,
    u: Vector,
    du: Vector,
    tmp: Vector,
}

impl<'w> MortarActiveSet<'w> {
    /// `nodes`: the slave boundary's contact nodes (their boundary weights are `D`); the
    /// interface evaluated on the reference configuration.
    pub fn new(
        mut nodes: ContactNodes<'w>,
        iface: &MortarInterface,
        part: &Partition,
        coords: &[[f64; 3]],
        factor: f64,
    ) -> Result<MortarActiveSet<'w>> {
        if nodes.boundary.nodes != iface.slave {
            return Err(Error::Solver("mortar: the contact nodes are not the slave nodes".into()));
        }
        // Node q keeps n_q . (x_q + u~_q) <= n_q . x_q + g_q / D_qq.
        // A slave node with no master facet in reach cannot touch (small sliding).
        let dim = part.dim;
        let covered = iface.m_row_sums();
        let planes = (0..iface.slave.len())
            .map(|q| {
                if covered[q] <= 0.0 {
                    return (f64::MAX, iface.normals[q]);
                }
                let n = iface.normals[q];
                let x = coords[iface.slave[q]];
                let c = (0..dim).map(|i| n[i] * x[i]).sum::<f64>() + iface.gap[q] / iface.d[q];
                (c, n)
            })
            .collect();
        nodes.node_planes = Some(planes);
        let e = transfer(part, iface, false)?;
        let t = transfer(part, iface, true)?;
        Ok(MortarActiveSet { inner: ActiveSet::new(nodes, factor), e, t, hat: None })
    }
}

/// `E` (or `T = I + E` with `identity`), rows owned as the partition says.
fn transfer(part: &Partition, iface: &MortarInterface, identity: bool) -> Result<Matrix> {
    let dim = part.dim;
    let n_local = part.n_owned_dofs();
    let lo = part.first_dof();
    let mut rows: Vec<Vec<(i32, f64)>> = vec![Vec::new(); iface.slave.len()];
    for &(q, l, v) in &iface.m {
        rows[q as usize].push((iface.master[l as usize] as i32, v / iface.d[q as usize]));
    }
    let local = |dof: usize| (lo..lo + n_local).contains(&dof);
    let (mut d_nnz, mut o_nnz) = (vec![i32::from(identity); n_local], vec![0i32; n_local]);
    for (q, row) in rows.iter().enumerate() {
        let v = iface.slave[q];
        if !part.owns(v) {
            continue;
        }
        for c in 0..dim {
            let i = part.dof(v, c) - lo;
            for &(l, _) in row {
                if local(part.dof(l as usize, c)) {
                    d_nnz[i] += 1;
                } else {
                    o_nnz[i] += 1;
                }
            }
        }
    }
    let n = part.n_global_dofs();
    let mut m = Matrix::new_aij(n_local, n, dim, &d_nnz, &o_nnz)?;
    if identity {
        for i in lo..lo + n_local {
            m.set_values(&[i as i32], &[i as i32], &[1.0], false)?;
        }
    }
    for (q, row) in rows.iter().enumerate() {
        let v = iface.slave[q];
        if !part.owns(v) || row.is_empty() {
            continue;
        }
        for c in 0..dim {
            let cols: Vec<i32> = row.iter().map(|&(l, _)| part.dof(l as usize, c) as i32).collect();
            let vals: Vec<f64> = row.iter().map(|&(_, x)| x).collect();
            m.set_values(&[part.dof(v, c) as i32], &cols, &vals, false)?;
        }
    }
    m.assemble()?;
    Ok(m)
}

/// A solver for `k` configured like `like` (type, preconditioner, tolerance), then the
/// command line's `-step_` options, as the step operator's own.
fn ksp_like(k: &Matrix, like: &Ksp) -> Result<Ksp> {
    let mut ksp = Ksp::new("")?;
    ksp.set_operators(k, k)?;
    ksp.set_type(&like.ksp_type()?)?;
    ksp.set_pc_type(&like.pc_type()?)?;
    ksp.set_tolerances(Some(like.rtol()?), Some(1e-50), None, Some(10_000))?;
    ksp.set_from_options()?;
    ksp.set_options_prefix("step_")?;
    ksp.set_from_options()?;
    let iterative = ksp.ksp_type()? != "preonly";
    ksp.set_initial_guess_nonzero(iterative)?;
    ksp.set_up()?;
    Ok(ksp)
}

impl ContactSolver for MortarActiveSet<'_> {
    fn prepare(&mut self, k: &Matrix) -> Result<()> {
        let mut k_hat = k.ptap(&self.t)?;
        k_hat.set_option_symmetric(true)?;
        self.inner.prepare(&k_hat)?;
        let (rhs, u) = k_hat.create_vecs()?;
        let (du, tmp) = k_hat.create_vecs()?;
        self.hat = Some(Hat { k: k_hat, ksp: None, rhs, u, du, tmp });
        Ok(())
    }

    fn solve(&mut self, sys: StepSystem<'_>) -> Result<(StepContact, usize)> {
        let StepSystem { k, ksp, rhs, u, du, step, time } = sys;
        if self.hat.is_none() {
            self.prepare(k)?;
        }
        let h = self.hat.as_mut().expect("prepared above");
        if h.ksp.is_none() {
            h.ksp = Some(ksp_like(&h.k, ksp)?);
        }
        // rhs~ = T^T rhs, u~ = T^{-1} u, du~ = T^{-1} du (the first guess).
        self.t.mult_transpose(rhs, &mut h.rhs)?;
        self.e.mult(u, &mut h.tmp)?;
        h.u.waxpy(-1.0, &h.tmp, u)?;
        self.e.mult(du, &mut h.tmp)?;
        h.du.waxpy(-1.0, &h.tmp, du)?;
        let inner = StepSystem {
            k: &mut h.k,
            ksp: h.ksp.as_mut().expect("built above"),
            rhs: &h.rhs,
            u: &h.u,
            du: &mut h.du,
            step,
            time,
        };
        let out = self.inner.solve(inner)?;
        self.t.mult(&h.du, du)?;
        Ok(out)
    }

    fn nodes(&self) -> &ContactNodes<'_> {
        self.inner.nodes()
    }
    fn active_mut(&mut self) -> &mut Vec<bool> {
        self.inner.active_mut()
    }
    fn extra_solves(&self) -> usize {
        self.inner.extra_solves()
    }
    fn penetrating(&self, u: &Vector, time: f64) -> Result<Vec<(usize, usize)>> {
        // The planes hold for u~ = T^{-1} u.
        let h = self.hat.as_ref();
        match h {
            Some(h) => {
                let mut eu = h.tmp.duplicate()?;
                self.e.mult(u, &mut eu)?;
                let mut ut = h.tmp.duplicate()?;
                ut.waxpy(-1.0, &eu, u)?;
                self.inner.nodes().penetrating(&ut, time)
            }
            None => Err(Error::Solver("mortar: penetration asked before prepare".into())),
        }
    }
}

/// The contact solver of a slave/master pair of deformable bodies: the interface evaluated on
/// the reference configuration (small sliding), the active set on the slave nodes. The search
/// reaches as far as the largest slave facet.
pub fn pair_solver<'w>(
    world: &'w mpi::topology::SimpleCommunicator,
    mesh: &crate::mesh::Mesh,
    part: &Partition,
    slave: &str,
    master: &str,
    factor: f64,
) -> Result<Box<dyn ContactSolver + 'w>> {
    use super::oriented_facets;
    let sf = oriented_facets(mesh, slave)?;
    let mf = oriented_facets(mesh, master)?;
    let reach = sf
        .iter()
        .map(|f| {
            let x0 = mesh.coords[f.nodes[0]];
            f.nodes
                .iter()
                .map(|&v| (0..3).map(|c| (mesh.coords[v][c] - x0[c]).powi(2)).sum::<f64>().sqrt())
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let iface = MortarInterface::build(world, mesh, part, &sf, &mf, &mesh.coords, reach)?;
    let boundary = crate::contact::ContactBoundary::build(mesh, slave)?;
    let nodes =
        ContactNodes::new(world, mesh, part, boundary, crate::contact::Obstacles(Vec::new()));
    Ok(Box::new(MortarActiveSet::new(nodes, &iface, part, &mesh.coords, factor)?))
}
