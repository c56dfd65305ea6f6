//! The energy correction's force without rigid motions at finite strain: no resultant and no
//! moment on any body, so the correction keeps every body's momentum and angular momentum.

use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;

use super::Midpoint;
use crate::error::Result;
use crate::petsc::Vector;

/// The rigid motions of a body in `dim` dimensions: `dim` translations and one rotation (2D)
/// or three (3D).
fn n_modes(dim: usize) -> usize {
    if dim == 3 {
        6
    } else {
        dim + 1
    }
}

/// Component `c` of rigid mode `j` at a point `d` from the body's centre: the translation
/// `e_j` for `j < dim`, else the rotation `e_a x d` about axis `a` (2D: `a = z`,
/// `(-d_y, d_x)`).
fn mode(dim: usize, j: usize, c: usize, d: [f64; 3]) -> f64 {
    if j < dim {
        return f64::from(u8::from(c == j));
    }
    let a = if dim == 3 { j - dim } else { 2 };
    // (e_a x d)_c = eps_{c a k} d_k
    match (a, c) {
        (0, 1) => -d[2],
        (0, 2) => d[1],
        (1, 0) => d[2],
        (1, 2) => -d[0],
        (2, 0) => -d[1],
        (2, 1) => d[0],
        _ => 0.0,
    }
}

/// `G a = h` by Gaussian elimination with partial pivoting (`k <= 6`); `None` when `G` is
/// singular (a body without mass, or held by Dirichlet rows).
fn solve_small(mut g: Vec<f64>, mut h: Vec<f64>) -> Option<Vec<f64>> {
    let k = h.len();
    let scale = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return None;
    }
    for col in 0..k {
        let p = (col..k).max_by(|&a, &b| g[a * k + col].abs().total_cmp(&g[b * k + col].abs()))?;
        if g[p * k + col].abs() <= 1e-13 * scale {
            return None;
        }
        if p != col {
            for c in 0..k {
                g.swap(p * k + c, col * k + c);
            }
            h.swap(p, col);
        }
        for r in col + 1..k {
            let f = g[r * k + col] / g[col * k + col];
            for c in col..k {
                g[r * k + c] -= f * g[col * k + c];
            }
            h[r] -= f * h[col];
        }
    }
    let mut a = vec![0.0; k];
    for r in (0..k).rev() {
        let s: f64 = (r + 1..k).map(|c| g[r * k + c] * a[c]).sum();
        a[r] = (h[r] - s) / g[r * k + r];
    }
    a.iter().all(|x| x.is_finite()).then_some(a)
}

impl Midpoint {
    /// The reference position of each owned DOF (its node's coordinate in the DOF's
    /// component): with them the energy correction's force at finite strain has neither
    /// resultant nor moment on any body ([`Midpoint::without_rigid_motions`]).
    pub fn set_reference_positions(&mut self, x: Vec<f64>) {
        self.reference = Some(x);
    }

    /// `f -= sum_j (M r_j) a_j` on each body, `G a = h`, `G_jl = r_j.M r_l`, `h_j = r_j.f`,
    /// with `r_j` the body's rigid motions at the step's midpoint positions `x = X + u + du /
    /// 2` (translations, and rotations about the body's centre of mass), the Dirichlet rows
    /// zero: afterwards `r_j.f = 0`, the force has no resultant and no moment about any point
    /// on any body. The midpoint rule changes a body's angular momentum by `tau sum_a x_a x
    /// f_a` (midpoint positions; the internal force of a hyperelastic body has no moment
    /// there), so the correction force `-xi f` leaves it as the other forces do. Without
    /// reference positions (the linear step, whose internal force has a moment anyway), the
    /// translations only ([`Midpoint::without_translations`]). Collective.
    pub(super) fn without_rigid_motions(&mut self, f: &mut Vector) -> Result<()> {
        let Some(reference) = self.reference.as_ref() else {
            return self.without_translations(f);
        };
        let dim = self.dim.max(1);
        let k = n_modes(dim);
        let ng = self.n_groups.max(1);
        let lo = self.first_dof;
        let group = |i: usize| self.groups.get(i / dim).map_or(0, |&g| g as usize);
        let fixed: Vec<usize> = self.dirichlet.dofs().iter().map(|&d| d as usize - lo).collect();
        // Midpoint positions, and each body's centre of mass (lumped: the row sums of M).
        let mut x = reference.clone();
        Vector::with_slices([&self.u, &self.du], [], |[u, du], []| {
            for i in 0..x.len() {
                x[i] += u[i] + 0.5 * du[i];
            }
        })?;
        let mut ones = self.u.duplicate()?;
        ones.set(1.0)?;
        let mut m1 = self.u.duplicate()?;
        self.m.mult(&ones, &mut m1)?;
        let mut sums = vec![0.0f64; 2 * ng * dim];
        m1.with_local_slice(|m| {
            for i in 0..m.len() {
                let b = group(i) * dim + i % dim;
                sums[b] += m[i] * x[i];
                sums[ng * dim + b] += m[i];
            }
        })?;
        let mut all = vec![0.0f64; sums.len()];
        let world = SimpleCommunicator::world();
        world.all_reduce_into(&sums[..], &mut all[..], SystemOperation::sum());
        let centre = |b: usize, c: usize| {
            let w = all[ng * dim + b * dim + c];
            if w > 0.0 {
                all[b * dim + c] / w
            } else {
                0.0
            }
        };
        // The modes r_j (Dirichlet rows zero) and M r_j.
        let nodes = x.len() / dim;
        let offset = |v: usize| {
            let b = group(v * dim);
            let mut d = [0.0; 3];
            for c in 0..dim {
                d[c] = x[v * dim + c] - centre(b, c);
            }
            d
        };
        let mut r = Vec::with_capacity(k);
        let mut mr = Vec::with_capacity(k);
        for j in 0..k {
            let mut rj = self.u.duplicate()?;
            rj.with_local_slice_mut(|s| {
                for v in 0..nodes {
                    let d = offset(v);
                    for c in 0..dim {
                        s[v * dim + c] = mode(dim, j, c, d);
                    }
                }
                for &i in &fixed {
                    s[i] = 0.0;
                }
            })?;
            let mut mj = self.u.duplicate()?;
            self.m.mult(&rj, &mut mj)?;
            mj.with_local_slice_mut(|s| {
                for &i in &fixed {
                    s[i] = 0.0;
                }
            })?;
            r.push(rj.with_local_slice(|s| s.to_vec())?);
            mr.push(mj.with_local_slice(|s| s.to_vec())?);
        }
        f.with_local_slice_mut(|s| {
            for &i in &fixed {
                s[i] = 0.0;
            }
        })?;
        // G and h per body.
        let per = k * k + k;
        let mut local = vec![0.0f64; ng * per];
        f.with_local_slice(|s| {
            for i in 0..s.len() {
                let b = group(i) * per;
                for j in 0..k {
                    for l in 0..k {
                        local[b + j * k + l] += r[j][i] * mr[l][i];
                    }
                    local[b + k * k + j] += r[j][i] * s[i];
                }
            }
        })?;
        let mut total = vec![0.0f64; local.len()];
        world.all_reduce_into(&local[..], &mut total[..], SystemOperation::sum());
        let coefficients: Vec<Option<Vec<f64>>> = (0..ng)
            .map(|b| {
                let t = &total[b * per..(b + 1) * per];
                solve_small(t[..k * k].to_vec(), t[k * k..].to_vec())
            })
            .collect();
        f.with_local_slice_mut(|s| {
            for i in 0..s.len() {
                if let Some(a) = &coefficients[group(i)] {
                    for j in 0..k {
                        s[i] -= a[j] * mr[j][i];
                    }
                }
            }
        })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rotation_modes_are_cross_products() {
        let d = [0.3, -1.2, 2.0];
        for a in 0..3 {
            let r: Vec<f64> = (0..3).map(|c| mode(3, 3 + a, c, d)).collect();
            // e_a x d is orthogonal to e_a and to d.
            assert_eq!(r[a], 0.0);
            assert!((0..3).map(|c| r[c] * d[c]).sum::<f64>().abs() < 1e-15);
        }
        // 2D: (-d_y, d_x).
        assert_eq!((mode(2, 2, 0, d), mode(2, 2, 1, d)), (1.2, 0.3));
        assert_eq!((mode(2, 0, 0, d), mode(2, 0, 1, d)), (1.0, 0.0));
    }

    #[test]
    fn small_systems_are_solved_and_singular_ones_refused() {
        let g = vec![4.0, 1.0, 0.0, 1.0, 3.0, 1.0, 0.0, 1.0, 2.0];
        let a = [1.0, -2.0, 0.5];
        let h: Vec<f64> = (0..3).map(|r| (0..3).map(|c| g[r * 3 + c] * a[c]).sum()).collect();
        let x = solve_small(g, h).expect("regular");
        for c in 0..3 {
            assert!((x[c] - a[c]).abs() < 1e-14);
        }
        assert!(solve_small(vec![1.0, 2.0, 2.0, 4.0], vec![1.0, 1.0]).is_none());
        assert!(solve_small(vec![0.0; 4], vec![1.0, 1.0]).is_none());
    }
}
