//! The change of basis `T = I + E` (module doc of [`super`]) as a distributed matrix.

use super::super::interface::MortarInterface;
use crate::error::Result;
use crate::partition::Partition;
use crate::petsc::Matrix;

/// `E` (or `T = I + E` with `identity`), rows owned as the partition says.
///
/// Dirichlet DOFs need nothing here: `T` is invertible, so `T^T K T u~ = T^T rhs` is
/// `K du = rhs` itself, the step operator's Dirichlet rows included (the mortar patch test
/// has Dirichlet DOFs on both sides of the interface).
pub(super) fn transfer(
    part: &Partition,
    iface: &MortarInterface,
    identity: bool,
) -> Result<Matrix> {
    let mut per: Vec<Vec<(usize, f64)>> = vec![Vec::new(); iface.slave.len()];
    for &(q, l, v) in &iface.m {
        per[q as usize].push((iface.master[l as usize], v / iface.d[q as usize]));
    }
    let mut rows: Vec<(usize, Vec<(usize, f64)>)> = Vec::new();
    for (q, row) in per.iter().enumerate() {
        let v = iface.slave[q];
        if !part.owns(v) || row.is_empty() {
            continue;
        }
        for c in 0..part.dim {
            rows.push((part.dof(v, c), row.iter().map(|&(l, x)| (part.dof(l, c), x)).collect()));
        }
    }
    basis_change(part, &rows, identity)
}

/// `E` (or `T = I + E` with `identity`) from its owned rows: per owned slave DOF, its columns
/// (global DOFs, each once) and values.
pub(super) fn basis_change(
    part: &Partition,
    rows: &[(usize, Vec<(usize, f64)>)],
    identity: bool,
) -> Result<Matrix> {
    let n_local = part.n_owned_dofs();
    let lo = part.first_dof();
    let local = |dof: usize| (lo..lo + n_local).contains(&dof);
    let (mut d_nnz, mut o_nnz) = (vec![i32::from(identity); n_local], vec![0i32; n_local]);
    for (row, cols) in rows {
        for &(col, _) in cols {
            if identity && col == *row {
                continue; // the identity's diagonal, counted already
            }
            match local(col) {
                true => d_nnz[row - lo] += 1,
                false => o_nnz[row - lo] += 1,
            }
        }
    }
    let mut m = Matrix::new_aij(n_local, part.n_global_dofs(), part.dim, &d_nnz, &o_nnz)?;
    if identity {
        for i in lo..lo + n_local {
            m.set_values(&[i as i32], &[i as i32], &[1.0], true)?;
        }
    }
    for (row, cols) in rows {
        let idx: Vec<i32> = cols.iter().map(|&(col, _)| col as i32).collect();
        let vals: Vec<f64> = cols.iter().map(|&(_, x)| x).collect();
        // Added: the identity's diagonal may be among the columns.
        m.set_values(&[*row as i32], &idx, &vals, true)?;
    }
    m.assemble()?;
    Ok(m)
}

/// A fingerprint of the nonzero pattern of this rank's rows of `m` (equal patterns, equal
/// fingerprints; different ones collide with probability 2^-64).
pub(super) fn pattern_of(m: &Matrix) -> Result<u64> {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    let (lo, hi) = m.ownership_range();
    for r in lo..hi {
        m.with_row(r, |cols, _| cols.hash(&mut h))?;
    }
    (lo, hi).hash(&mut h);
    Ok(h.finish())
}
