//! One generic distributed assembler: each rank loops over its own cells, computes element
//! contributions with the pure kernels of `fem`, maps nodes to global DOFs and adds them with
//! `MatSetValues`/`VecSetValues` (PETSc moves off-rank entries). Every matrix and load vector
//! of the solver goes through here, with exact preallocation from the partition.

pub mod finite_strain;
pub mod nodal_pressure;
pub mod rows;

use mpi::topology::SimpleCommunicator;

use crate::error::{Error, Result};
use crate::mesh::{Element, Mesh};
use crate::partition::Partition;
use crate::petsc::{Matrix, Vector};
use crate::scene::expr::{Expr, VecExpr};

/// Largest element: 8 nodes x 3 components.
pub const MAX_EDOFS: usize = 24;

/// Element node coordinates on the stack.
#[inline]
pub fn cell_coords(mesh: &Mesh, e: &Element, out: &mut [[f64; 3]; 8]) -> usize {
    let nodes = e.nodes();
    for (i, &v) in nodes.iter().enumerate() {
        out[i] = mesh.coords[v];
    }
    nodes.len()
}

/// Interlaced global DOFs of a node list.
#[inline]
pub fn node_dofs(part: &Partition, nodes: &[usize], out: &mut Vec<i32>) {
    out.clear();
    for &v in nodes {
        for c in 0..part.dim {
            out.push(part.dof(v, c) as i32);
        }
    }
}

/// An empty distributed matrix with the pattern of "nodes sharing a cell", block size dim.
pub fn new_matrix(mesh: &Mesh, part: &Partition) -> Result<Matrix> {
    let (d, o) = part.preallocation(mesh);
    Matrix::new_aij(part.n_owned_dofs(), part.n_global_dofs(), part.dim, &d, &o)
}

/// A distributed vector with this partition's layout.
pub fn new_vector(part: &Partition) -> Result<Vector> {
    Vector::new_mpi(part.n_owned_dofs(), part.n_global_dofs(), part.dim)
}

/// Assemble `sum_K P_K^T kernel(K) P_K` over this rank's cells. The kernel receives the cell
/// index and its node coordinates and writes the (n dim)^2 row-major element matrix, DOFs
/// interlaced (node * dim + component), in the cell's own node order.
pub fn assemble_matrix<F>(mesh: &Mesh, part: &Partition, mut kernel: F) -> Result<Matrix>
where
    F: FnMut(usize, &[[f64; 3]], &mut [f64]) -> Result<()>,
{
    assemble_blocks(mesh, part, |c, xy, _nodes, vals| {
        let nd = xy.len() * part.dim;
        vals.resize(nd * nd, 0.0);
        kernel(c, xy, vals)
    })
}

/// The general form: for each of this rank's cells the kernel may replace the node list
/// (pre-filled with the cell's nodes) by the nodes its block couples, e.g. the source nodes of
/// the mass-free layer's `E_K^T M_K E_K`, and writes the matching dense block into `vals`
/// ((nodes.len() dim)^2, row-major, interlaced). The matrix pattern is that of nodes sharing a
/// cell: a block coupling other node pairs is a PETSc error (new nonzero), which asserts it.
pub fn assemble_blocks<F>(mesh: &Mesh, part: &Partition, kernel: F) -> Result<Matrix>
where
    F: FnMut(usize, &[[f64; 3]], &mut Vec<usize>, &mut Vec<f64>) -> Result<()>,
{
    assemble_components(mesh, part, part.dim, false, kernel)
}

/// [`assemble_matrix`] stored as block AIJ (`dim x dim` blocks, `Matrix::new_baij`): for an
/// operator used in products, such as the stiffness `A` (about 30% less memory in 3D).
pub fn assemble_matrix_blocked<F>(mesh: &Mesh, part: &Partition, mut kernel: F) -> Result<Matrix>
where
    F: FnMut(usize, &[[f64; 3]], &mut [f64]) -> Result<()>,
{
    assemble_components(mesh, part, part.dim, true, |c, xy, _nodes, vals| {
        let nd = xy.len() * part.dim;
        vals.resize(nd * nd, 0.0);
        kernel(c, xy, vals)
    })
}

/// [`assemble_blocks`] for a node matrix (one component per node): the kernel writes
/// `nodes.len()^2` values. Its rows are the owned nodes, numbered as the DOFs' nodes.
pub fn assemble_node_blocks<F>(mesh: &Mesh, part: &Partition, kernel: F) -> Result<Matrix>
where
    F: FnMut(usize, &[[f64; 3]], &mut Vec<usize>, &mut Vec<f64>) -> Result<()>,
{
    assemble_components(mesh, part, 1, false, kernel)
}

fn assemble_components<F>(
    mesh: &Mesh,
    part: &Partition,
    dim: usize,
    blocked: bool,
    mut kernel: F,
) -> Result<Matrix>
where
    F: FnMut(usize, &[[f64; 3]], &mut Vec<usize>, &mut Vec<f64>) -> Result<()>,
{
    let owned = part.n_owned_nodes() * dim;
    let global = part.n_global_nodes() * dim;
    let mat = if blocked {
        let (d_nnz, o_nnz) = part.graph(mesh).preallocation_for(part, 1);
        Matrix::new_baij(owned, global, dim, &d_nnz, &o_nnz)?
    } else {
        let (d_nnz, o_nnz) = part.graph(mesh).preallocation_for(part, dim);
        Matrix::new_aij(owned, global, dim, &d_nnz, &o_nnz)?
    };
    let mut sums = rows::RowSums::with_components(part.graph(mesh), mesh, part, dim);
    let mut xy = [[0.0; 3]; 8];
    let mut nodes = Vec::with_capacity(8);
    let mut vals = Vec::with_capacity(MAX_EDOFS * MAX_EDOFS);
    // A kernel error on one rank must not leave the others in the exchange: agree first.
    let mut failed = None;
    for &c in &part.local_cells {
        let cell = &mesh.cells[c];
        let n = cell_coords(mesh, cell, &mut xy);
        nodes.clear();
        nodes.extend_from_slice(&cell.nodes());
        if let Err(e) = kernel(c, &xy[..n], &mut nodes, &mut vals) {
            failed = Some(e);
            break;
        }
        debug_assert_eq!(vals.len(), (nodes.len() * dim).pow(2));
        sums.add(part, part.cell_original[c] as usize, &nodes, &vals)?;
    }
    let world = SimpleCommunicator::world();
    let first = crate::comm::first_failure(&world, failed.as_ref().map(|e| e.to_string()));
    match (failed, first) {
        (Some(e), _) => return Err(e),
        (None, Some(m)) => return Err(Error::Mesh(m)),
        (None, None) => {}
    }
    sums.into_matrix(&world, mat)
}

/// The rank that integrates a boundary element: the owner of its smallest node (deterministic).
pub fn boundary_rank(part: &Partition, e: &Element) -> usize {
    part.boundary_rank(e)
}

/// Nodal interpolant of a vector expression at time `t` into a distributed vector.
pub fn interpolate(mesh: &Mesh, part: &Partition, f: &VecExpr, t: f64) -> Result<Vector> {
    let mut x = new_vector(part)?;
    let dim = part.dim;
    let mut idx = Vec::with_capacity(part.n_owned_dofs());
    let mut vals = Vec::with_capacity(part.n_owned_dofs());
    for &v in &part.owned_nodes {
        let val = f.eval(mesh.coords[v], t);
        for (c, &vc) in val.iter().enumerate().take(dim) {
            idx.push(part.dof(v, c) as i32);
            vals.push(vc);
        }
    }
    x.set_values(&idx, &vals, false)?;
    x.assemble()?;
    Ok(x)
}

/// External loads of the scene: body force over the cells, tractions over boundary elements.
/// `assemble(t)` gives the load vector `f(t) = int N f dx + int_{Gamma_N} N g ds`.
///
/// When every load expression separates as `sum_k s_k(t) g_k(x)` (the usual case: steady,
/// ramped or harmonic loads), each `int N g_k` is assembled once and a step only combines
/// the vectors; otherwise the expressions are integrated at every step.
pub struct Loads {
    general: LoadIntegrals,
    /// (time factor, assembled space part) when the loads separate.
    separated: Option<Vec<(Expr, Vector)>>,
    /// Whether `f` changes in time (else it is assembled once).
    pub time_dependent: bool,
    pub present: bool,
}

/// Load expressions and the boundary elements this rank integrates them over.
struct LoadIntegrals {
    body_force: Option<VecExpr>,
    /// (boundary element index, traction index) pairs this rank integrates.
    tractions: Vec<(usize, usize)>,
    traction_exprs: Vec<VecExpr>,
}

/// Quadrature order for loads given as general expressions.
const LOAD_QUADRATURE_ORDER: usize = 4;

impl LoadIntegrals {
    /// Assemble f(t) into `out` (overwritten). Contributions to other ranks' rows are sent
    /// in one all-to-all and added in rank order, not in the order messages arrive (PETSc's
    /// `VecAssembly`): with three or more ranks a row can get them from two ranks, and runs
    /// then did not repeat to the last bit.
    fn assemble(&self, mesh: &Mesh, part: &Partition, t: f64, out: &mut Vector) -> Result<()> {
        let dim = part.dim;
        let first = part.first_dof();
        let mut own = vec![0.0; part.n_owned_dofs()];
        let mut away: Vec<u64> = Vec::new();
        let mut away_rank: Vec<usize> = Vec::new();
        let mut add = |nodes: &[usize], fe: &[f64]| {
            for (a, &v) in nodes.iter().enumerate() {
                for c in 0..dim {
                    let dof = part.dof(v, c);
                    if part.owns(v) {
                        own[dof - first] += fe[a * dim + c];
                    } else {
                        away.extend([dof as u64, fe[a * dim + c].to_bits()]);
                        away_rank.push(part.node_owner[v]);
                    }
                }
            }
        };
        let mut xy = [[0.0; 3]; 8];
        let mut fe = [0.0; MAX_EDOFS];
        if let Some(f) = &self.body_force {
            let func = |x: [f64; 3]| f.eval(x, t);
            for &c in &part.local_cells {
                let cell = &mesh.cells[c];
                let n = cell_coords(mesh, cell, &mut xy);
                crate::fem::kernels::body_force(
                    cell.kind,
                    &xy[..n],
                    &func,
                    LOAD_QUADRATURE_ORDER,
                    &mut fe[..n * dim],
                );
                add(&cell.nodes(), &fe[..n * dim]);
            }
        }
        for &(bi, k) in &self.tractions {
            let g = &self.traction_exprs[k];
            let func = |x: [f64; 3], _n: [f64; 3]| g.eval(x, t);
            let e = &mesh.boundary[bi];
            let n = cell_coords(mesh, e, &mut xy);
            crate::fem::kernels::traction(
                e.kind,
                &xy[..n],
                &func,
                dim,
                LOAD_QUADRATURE_ORDER,
                &mut fe[..n * dim],
            );
            add(&e.nodes(), &fe[..n * dim]);
        }
        let world = SimpleCommunicator::world();
        let came = crate::comm::all_to_all_rows(&world, 2, &away, |k| away_rank[k]);
        for r in came.chunks_exact(2) {
            let i =
                (r[0] as usize).checked_sub(first).filter(|&i| i < own.len()).ok_or_else(|| {
                    Error::Internal(format!(
                        "loads: DOF {} sent to a rank that does not own it",
                        r[0]
                    ))
                })?;
            own[i] += f64::from_bits(r[1]);
        }
        out.with_local_slice_mut(|x| x.copy_from_slice(&own))
    }
}

/// Split every component of the load expressions by time factor: for each distinct `s_k(t)`,
/// the space parts (body force, then one per traction) as expressions; None if some
/// expression does not separate.
#[allow(clippy::type_complexity)]
fn separate_loads(
    dim: usize,
    body: Option<&VecExpr>,
    tractions: &[VecExpr],
) -> Option<Vec<(String, Vec<Vec<String>>)>> {
    use std::collections::BTreeMap;
    let sources: Vec<&VecExpr> = body.into_iter().chain(tractions.iter()).collect();
    // time factor -> per source, per component, list of signed space terms
    let mut groups: BTreeMap<String, Vec<Vec<Vec<String>>>> = BTreeMap::new();
    for (si, src) in sources.iter().enumerate() {
        for c in 0..dim.min(src.0.len()) {
            for term in crate::scene::separate::separate(src.0[c].source())? {
                let entry = groups
                    .entry(term.time.clone())
                    .or_insert_with(|| vec![vec![Vec::new(); dim]; sources.len()]);
                let sign = if term.sign < 0.0 { "-" } else { "+" };
                entry[si][c].push(format!("{sign}{}", term.space));
            }
        }
    }
    Some(
        groups
            .into_iter()
            .map(|(time, per_source)| {
                let exprs = per_source
                    .into_iter()
                    .map(|comps| {
                        comps
                            .into_iter()
                            .map(|t| if t.is_empty() { "0".to_string() } else { t.join(" ") })
                            .collect()
                    })
                    .collect();
                (time, exprs)
            })
            .collect(),
    )
}

impl Loads {
    pub fn new(
        mesh: &Mesh,
        part: &Partition,
        body_force: Option<&VecExpr>,
        neumann: &[(String, VecExpr)],
    ) -> Result<Loads> {
        let body_force = body_force.filter(|f| !f.is_zero()).cloned();
        let mut tractions = Vec::new();
        let mut traction_exprs = Vec::new();
        let mut time_dependent = body_force.as_ref().is_some_and(|f| f.depends_on_t());
        for (group, g) in neumann {
            let pg = mesh.group(group)?;
            if pg.dim + 1 != mesh.dim {
                return Err(crate::error::Error::Scene(format!(
                    "neumann group \"{group}\" has dimension {}, but tractions act on boundary groups of dimension {}",
                    pg.dim,
                    mesh.dim - 1
                )));
            }
            if g.is_zero() {
                continue;
            }
            time_dependent |= g.depends_on_t();
            let k = traction_exprs.len();
            traction_exprs.push(g.clone());
            for (bi, e) in mesh.boundary.iter().enumerate() {
                if e.kind.dim() == pg.dim
                    && pg.entities.contains(&e.entity)
                    && boundary_rank(part, e) == part.rank
                {
                    tractions.push((bi, k));
                }
            }
        }
        let present = body_force.is_some() || !traction_exprs.is_empty();
        let general = LoadIntegrals { body_force, tractions, traction_exprs };
        let mut separated = None;
        if present && time_dependent {
            let groups =
                separate_loads(mesh.dim, general.body_force.as_ref(), &general.traction_exprs);
            if let Some(groups) = groups {
                let mut parts = Vec::new();
                for (time, exprs) in groups {
                    let parse = |v: &Vec<String>| -> Result<VecExpr> {
                        v.iter()
                            .map(|s| Expr::parse(s))
                            .collect::<std::result::Result<Vec<_>, _>>()
                            .map(VecExpr)
                            .map_err(|e| crate::error::Error::Scene(format!("separated load: {e}")))
                    };
                    let mut it = exprs.iter();
                    let body = match general.body_force {
                        Some(_) => Some(parse(it.next().expect("body part"))?),
                        None => None,
                    };
                    let traction_exprs = it.map(parse).collect::<Result<Vec<_>>>()?;
                    let space = LoadIntegrals {
                        body_force: body,
                        tractions: general.tractions.clone(),
                        traction_exprs,
                    };
                    let mut f = new_vector(part)?;
                    space.assemble(mesh, part, 0.0, &mut f)?;
                    let s = Expr::parse(&time)
                        .map_err(|e| crate::error::Error::Scene(format!("separated load: {e}")))?;
                    parts.push((s, f));
                }
                separated = Some(parts);
            }
        }
        Ok(Loads { general, separated, time_dependent, present })
    }

    /// f(t) integrated from the expressions themselves (what the separated form must equal).
    pub fn assemble_integrated(
        &self,
        mesh: &Mesh,
        part: &Partition,
        t: f64,
        out: &mut Vector,
    ) -> Result<()> {
        self.general.assemble(mesh, part, t, out)
    }

    /// Whether the loads are combined from pre-assembled space parts each step.
    pub fn is_separated(&self) -> bool {
        self.separated.is_some()
    }

    /// Assemble f(t) into `out` (overwritten).
    pub fn assemble(&self, mesh: &Mesh, part: &Partition, t: f64, out: &mut Vector) -> Result<()> {
        match &self.separated {
            Some(parts) => {
                // The first part is written, the others added: one pass for the usual single
                // time factor.
                for (k, (s, f)) in parts.iter().enumerate() {
                    let sk = s.eval([0.0; 3], t);
                    if k == 0 {
                        Vector::with_slices([f], [&mut *out], |[f], [o]| {
                            for (o, f) in o.iter_mut().zip(f) {
                                *o = sk * f;
                            }
                        })?;
                    } else {
                        out.axpy(sk, f)?;
                    }
                }
                if parts.is_empty() {
                    out.zero()?;
                }
                Ok(())
            }
            None => self.general.assemble(mesh, part, t, out),
        }
    }
}
