//! What a run measures besides the state: the mass matrix's moments (checked against the
//! paper's Lemma 3.3), momenta and contact impulses per body, errors against an exact
//! solution, the shortest edges (the CFL number), the cost of one product with the step
//! operator and the peak memory. Free functions of the run's [`Domain`]; collective where
//! they reduce over the ranks.

use mpi::collective::SystemOperation;
use mpi::traits::*;

use super::domain::Domain;
use super::views::Views;
use crate::assembly;
use crate::comm::{max_over_ranks, sum_over_ranks};
use crate::contact::history::History as ContactHistory;
use crate::contact::ContactSolver;
use crate::error::Result;
use crate::fem::kernels;
use crate::mass::{MassFreeLayer, MassMatrix};
use crate::petsc::Vector;
use crate::report::MassCheck;

/// Mass-matrix diagnostics, computed once: total mass, first and second moments per component
/// (`1^T M 1`, `x^T M 1`, `x^T M x` with x the nodal coordinates in one component), and the
/// largest entry of `M 1` on contact DOFs (zero for M_H).
pub fn check_mass(
    d: &Domain,
    views: &mut Views,
    m: &MassMatrix,
    layer: Option<&MassFreeLayer>,
) -> Result<MassCheck> {
    let part = &d.part;
    let dim = part.dim;
    let mut check = MassCheck::default();
    let mut one = assembly::new_vector(part)?;
    let mut x = one.duplicate()?;
    let mut y = one.duplicate()?;
    for c in 0..dim {
        let owned = &part.owned_nodes;
        one.zero()?;
        one.with_local_slice_mut(|s| {
            for i in 0..owned.len() {
                s[i * dim + c] = 1.0;
            }
        })?;
        x.zero()?;
        x.with_local_slice_mut(|s| {
            for (i, &v) in owned.iter().enumerate() {
                s[i * dim + c] = d.mesh.coords[v][c];
            }
        })?;
        m.mult(&one, &mut y)?;
        check.total_mass.push(one.dot(&y)?);
        let per_body = body_sums(d, &y, c)?;
        check.body_mass.resize(per_body.len(), Vec::new());
        for (b, m) in per_body.into_iter().enumerate() {
            check.body_mass[b].push(m);
        }
        check.first_moment.push(x.dot(&y)?);
        let contact_max = match layer.map(|l| &l.contact_nodes) {
            Some(nodes) => {
                let lo = part.first_dof();
                let mut mx: f64 = 0.0;
                y.with_local_slice(|s| {
                    for &v in nodes {
                        if part.owns(v) {
                            mx = mx.max(s[part.dof(v, c) - lo].abs());
                        }
                    }
                })?;
                max_over_ranks(d.world, mx)
            }
            None => 0.0,
        };
        check.contact_row_max = check.contact_row_max.max(contact_max);
        m.mult(&x, &mut y)?;
        check.second_moment.push(x.dot(&y)?);
    }
    // The probe: M applied to r_i = sin(i + 1), i the natural (gmsh-order) DOF index.
    let owned = &part.owned_nodes;
    x.with_local_slice_mut(|s| {
        for (i, &v) in owned.iter().enumerate() {
            for c in 0..dim {
                s[i * dim + c] = ((part.node_original[v] * dim + c + 1) as f64).sin();
            }
        }
    })?;
    m.mult(&x, &mut y)?;
    check.probe = views.to_natural(&y)?;
    Ok(check)
}

/// The shortest cell edge (any two nodes of a cell: for simplices the edges, for quads and
/// hexes their diagonals too, which are longer) of each region (`Bodies`), over the cells of
/// all ranks (`f64::MAX` for a region without cells).
pub fn min_edges(d: &Domain) -> Vec<f64> {
    let mut h = vec![f64::MAX; d.bodies.regions.len()];
    for &c in &d.part.local_cells {
        let r = d.bodies.region_of(c);
        let nodes = d.mesh.cells[c].nodes();
        for (i, &a) in nodes.iter().enumerate() {
            for &b in &nodes[i + 1..] {
                let (x, y) = (d.mesh.coords[a], d.mesh.coords[b]);
                let d2: f64 = (0..3).map(|k| (x[k] - y[k]).powi(2)).sum();
                h[r] = h[r].min(d2.sqrt());
            }
        }
    }
    let mut global = vec![0.0; h.len()];
    d.world.all_reduce_into(&h[..], &mut global[..], SystemOperation::min());
    global
}

/// Per body, the sum of component `c` of `x` over the body's nodes (all ranks).
fn body_sums(d: &Domain, x: &Vector, c: usize) -> Result<Vec<f64>> {
    let n = d.bodies.n_bodies();
    if n == 0 {
        return Ok(Vec::new());
    }
    let part = &d.part;
    let lo = part.first_dof();
    let mut sums = vec![0.0; n];
    x.with_local_slice(|s| {
        for (b, sum) in sums.iter_mut().enumerate() {
            for &v in d.bodies.body_nodes(b) {
                if part.owns(v) {
                    *sum += s[part.dof(v, c) - lo];
                }
            }
        }
    })?;
    let mut out = vec![0.0; n];
    d.world.all_reduce_into(&sums[..], &mut out[..], SystemOperation::sum());
    Ok(out)
}

/// The body of each owned node, in DOF order: the index of the first `[[body]]` holding it,
/// or the number of bodies for the nodes of no body.
pub fn node_bodies(d: &Domain) -> Vec<u32> {
    let n = d.bodies.n_bodies();
    let part = &d.part;
    let lo = part.first_dof();
    let dim = part.dim;
    let mut out = vec![n as u32; part.owned_nodes.len()];
    for b in (0..n).rev() {
        for &v in d.bodies.body_nodes(b) {
            if part.owns(v) {
                out[(part.dof(v, 0) - lo) / dim] = b as u32;
            }
        }
    }
    out
}

/// The momentum `1_B^T M v` of each body, per component, from `M v`.
pub fn body_momenta(d: &Domain, mv: &Vector) -> Result<Vec<Vec<f64>>> {
    let mut p = vec![Vec::new(); d.bodies.n_bodies()];
    for c in 0..d.part.dim {
        for (b, x) in body_sums(d, mv, c)?.into_iter().enumerate() {
            p[b].push(x);
        }
    }
    Ok(p)
}

/// The contact nodes and the cells of the layer on each `[[body]]` (over all ranks:
/// collective).
pub fn body_layers(d: &Domain, layer: Option<&MassFreeLayer>) -> Vec<(usize, usize)> {
    let n = d.bodies.n_bodies();
    let Some(layer) = layer else { return vec![(0, 0); n] };
    let part = &d.part;
    let mut counts = vec![0u64; 2 * n];
    for i in 0..n {
        let nodes = d.bodies.body_nodes(i);
        counts[2 * i] = (layer.contact_nodes.iter())
            .filter(|&&v| part.owns(v) && nodes.binary_search(&v).is_ok())
            .count() as u64;
        counts[2 * i + 1] = (layer.layer_cells.iter())
            .filter(|&&c| part.cell_rank[c] as usize == part.rank && d.bodies.region_of(c) == i + 1)
            .count() as u64;
    }
    let mut total = vec![0u64; 2 * n];
    d.world.all_reduce_into(&counts[..], &mut total[..], SystemOperation::sum());
    (0..n).map(|i| (total[2 * i] as usize, total[2 * i + 1] as usize)).collect()
}

/// Total momentum `1^T M v` per component (from the product `M v` the step keeps).
pub fn momentum(d: &Domain, mv: &Vector) -> Result<[f64; 3]> {
    let dim = d.part.dim;
    let mut p = [0.0; 3];
    mv.with_local_slice(|s| {
        for (i, x) in s.iter().enumerate() {
            p[i % dim] += x;
        }
    })?;
    let mut out = [0.0; 3];
    d.world.all_reduce_into(&p[..], &mut out[..], SystemOperation::sum());
    Ok(out)
}

/// The reference coordinate of each owned DOF, in DOF order (the node's coordinate in the
/// DOF's component).
pub fn reference_positions(d: &Domain) -> Vec<f64> {
    let dim = d.part.dim;
    let first = d.part.first_dof();
    let mut x = vec![0.0; d.part.owned_nodes.len() * dim];
    for &v in &d.part.owned_nodes {
        for c in 0..dim {
            x[d.part.dof(v, c) - first] = d.mesh.coords[v][c];
        }
    }
    x
}

/// The angular momentum about the centre of mass, `sum_v (x_v - x_c) x (M v)_v` with the
/// current positions `x_v = X_v + u_v` and `x_c = sum_v (M 1)_v x_v / sum_v (M 1)_v` (three
/// components; in 2D only the third is not zero). Collective.
pub fn angular_momentum(d: &Domain, m: &MassMatrix, u: &Vector, mv: &Vector) -> Result<[f64; 3]> {
    let dim = d.part.dim;
    let first = d.part.first_dof();
    let disp = u.with_local_slice(|s| s.to_vec())?;
    let position = |v: usize| {
        let mut x = d.mesh.coords[v];
        for c in 0..dim {
            x[c] += disp[d.part.dof(v, c) - first];
        }
        x
    };
    // The centre of mass from the lumped masses M 1 (component by component).
    let mut ones = u.duplicate()?;
    ones.set(1.0)?;
    let mut m1 = u.duplicate()?;
    m.mult(&ones, &mut m1)?;
    let mut moments = [0.0; 6];
    m1.with_local_slice(|s| {
        for &v in &d.part.owned_nodes {
            let x = position(v);
            for c in 0..dim {
                let w = s[d.part.dof(v, c) - first];
                moments[c] += w * x[c];
                moments[3 + c] += w;
            }
        }
    })?;
    let mut sums = [0.0; 6];
    d.world.all_reduce_into(&moments[..], &mut sums[..], SystemOperation::sum());
    let centre: [f64; 3] =
        [0, 1, 2].map(|c| if sums[3 + c] > 0.0 { sums[c] / sums[3 + c] } else { 0.0 });
    let mut l = [0.0; 3];
    mv.with_local_slice(|s| {
        for &v in &d.part.owned_nodes {
            let p = position(v);
            let x = [0, 1, 2].map(|c| p[c] - centre[c]);
            let f: Vec<f64> = (0..dim).map(|c| s[d.part.dof(v, c) - first]).collect();
            let f3 = [f[0], f[1], if dim == 3 { f[2] } else { 0.0 }];
            l[0] += x[1] * f3[2] - x[2] * f3[1];
            l[1] += x[2] * f3[0] - x[0] * f3[2];
            l[2] += x[0] * f3[1] - x[1] * f3[0];
        }
    })?;
    let mut out = [0.0; 3];
    d.world.all_reduce_into(&l[..], &mut out[..], SystemOperation::sum());
    Ok(out)
}

/// The impulse the contact gave each `[[body]]`: the sum over its contact nodes (slave nodes
/// and nodes meeting obstacles) and its master nodes of what they received. A node on two
/// bodies counts for the first.
pub fn contact_impulses(
    d: &Domain,
    contact: Option<&dyn ContactSolver>,
    history: &ContactHistory,
) -> Vec<Vec<f64>> {
    per_body(d, contact, |c, holds| {
        history.impulse_on(&c.boundary().nodes, c.master_nodes(), holds)
    })
}

/// Per body, the friction's part of [`contact_impulses`].
pub fn friction_impulses(
    d: &Domain,
    contact: Option<&dyn ContactSolver>,
    history: &ContactHistory,
) -> Vec<Vec<f64>> {
    per_body(d, contact, |c, holds| {
        history.friction_impulse_on(&c.boundary().nodes, c.master_nodes(), holds)
    })
}

/// `sum(c, holds)` for each body, `holds` accepting the nodes of that body (a node on two
/// bodies counts for the first); zeros without contact.
fn per_body(
    d: &Domain,
    contact: Option<&dyn ContactSolver>,
    sum: impl Fn(&dyn ContactSolver, &dyn Fn(usize) -> bool) -> [f64; 3],
) -> Vec<Vec<f64>> {
    let dim = d.part.dim;
    let n = d.bodies.n_bodies();
    let Some(c) = contact else { return vec![vec![0.0; dim]; n] };
    // The solvers number their nodes on the contact surface.
    let first_body =
        |v: usize| (0..n).find(|&b| d.bodies.surface_body_nodes(b).binary_search(&v).is_ok());
    (0..n).map(|b| sum(c, &|v| first_body(v) == Some(b))[..dim].to_vec()).collect()
}

/// L2 and H1-seminorm errors of `u` against the scene's exact displacement at time t (`None`
/// for a scene without one).
pub fn exact_errors(
    d: &Domain,
    views: &mut Views,
    u: &Vector,
    t: f64,
) -> Result<Option<(f64, f64)>> {
    let Some(exact) = &d.scene.exact else { return Ok(None) };
    let (vals, view) = views.local_values(u)?;
    let slot = &view.slot;
    let dim = d.part.dim;
    let disp = &exact.displacement;
    let grad = exact.gradient.as_ref();
    let f = |x: [f64; 3]| -> ([f64; 3], [[f64; 3]; 3]) {
        let val = disp.eval(x, t);
        let mut g = [[0.0; 3]; 3];
        match grad {
            Some(rows) => {
                for i in 0..dim {
                    let r = rows[i].eval(x, t);
                    g[i][..dim].copy_from_slice(&r[..dim]);
                }
            }
            None => {
                // Central differences: O(h^2) = 1e-12 relative, far below discretization error.
                for j in 0..dim {
                    let hstep = 1e-6 * (1.0 + x[j].abs());
                    let (mut xp, mut xm) = (x, x);
                    xp[j] += hstep;
                    xm[j] -= hstep;
                    let (fp, fm) = (disp.eval(xp, t), disp.eval(xm, t));
                    for i in 0..dim {
                        g[i][j] = (fp[i] - fm[i]) / (2.0 * hstep);
                    }
                }
            }
        }
        (val, g)
    };
    let (mut l2, mut h1) = (0.0, 0.0);
    let mut xy = [[0.0; 3]; 8];
    let mut ue = [0.0; assembly::MAX_EDOFS];
    for &c in &d.part.local_cells {
        let cell = &d.mesh.cells[c];
        let n = assembly::cell_coords(&d.mesh, cell, &mut xy);
        for (i, &v) in cell.nodes().iter().enumerate() {
            for k in 0..dim {
                ue[i * dim + k] = vals[slot[v] * dim + k];
            }
        }
        let (a, b) = kernels::error_sq(cell.kind, &xy[..n], &ue[..n * dim], &f, 6);
        l2 += a;
        h1 += b;
    }
    let l2 = sum_over_ranks(d.world, l2).sqrt();
    let h1 = sum_over_ranks(d.world, h1).sqrt();
    Ok(Some((l2, h1)))
}

/// `|v - v_exact(t)|_L2` over the mesh (the velocity interpolated by the shape functions, the
/// exact one at the quadrature points). Collective.
pub fn velocity_error(
    d: &Domain,
    views: &mut Views,
    v: &Vector,
    exact: &crate::scene::expr::VecExpr,
    t: f64,
) -> Result<f64> {
    let (vals, view) = views.local_values(v)?;
    let slot = &view.slot;
    let dim = d.part.dim;
    // Only the L2 part of `error_sq` is used: the gradient it is given is zero.
    let f = |x: [f64; 3]| -> ([f64; 3], [[f64; 3]; 3]) { (exact.eval(x, t), [[0.0; 3]; 3]) };
    let mut l2 = 0.0;
    let mut xy = [[0.0; 3]; 8];
    let mut ve = [0.0; assembly::MAX_EDOFS];
    for &c in &d.part.local_cells {
        let cell = &d.mesh.cells[c];
        let n = assembly::cell_coords(&d.mesh, cell, &mut xy);
        for (i, &p) in cell.nodes().iter().enumerate() {
            for k in 0..dim {
                ve[i * dim + k] = vals[slot[p] * dim + k];
            }
        }
        l2 += kernels::error_sq(cell.kind, &xy[..n], &ve[..n * dim], &f, 6).0;
    }
    Ok(sum_over_ranks(d.world, l2).sqrt())
}

/// Peak resident set size of this process (VmHWM), in MiB; 0 where /proc is unavailable.
pub fn peak_rss_mib() -> f64 {
    crate::phase::status_mib("VmHWM:")
}
