//! Prescribed displacements `u = g(x, t)` on Dirichlet groups: the constrained DOFs this rank
//! owns and their values at any time.

use crate::error::Result;
use crate::mesh::Mesh;
use crate::partition::Partition;
use crate::scene::expr::VecExpr;
use crate::scene::DirichletSpec;

/// The Dirichlet DOFs owned by this rank, with the point, component and value of each.
pub struct Dirichlet {
    /// Global DOF numbers, sorted.
    dofs: Vec<i32>,
    /// (point, component, index into `values`) per DOF.
    entries: Vec<([f64; 3], usize, usize)>,
    values: Vec<VecExpr>,
    /// The scene has Dirichlet groups (decided on the scene, the same on every rank: a rank
    /// may own no constrained DOF, but the collective operations of the lifting must run).
    pub present: bool,
    /// Some prescribed value is non-zero: then `K[:, D] du_D` moves to the right-hand side
    /// every step (the lifting), which needs the unconstrained operator.
    pub nonzero: bool,
}

impl Dirichlet {
    /// The constrained DOFs of `specs` owned by this rank; later specs override earlier ones on
    /// shared nodes.
    pub fn new(mesh: &Mesh, part: &Partition, specs: &[DirichletSpec]) -> Result<Dirichlet> {
        let mut by_dof: std::collections::BTreeMap<i32, ([f64; 3], usize, usize)> =
            Default::default();
        for (si, d) in specs.iter().enumerate() {
            let comps = d.constrained(mesh.dim);
            for v in mesh.group_nodes(&d.group)? {
                if part.owns(v) {
                    for &c in &comps {
                        by_dof.insert(part.dof(v, c) as i32, (mesh.coords[v], c, si));
                    }
                }
            }
        }
        Ok(Dirichlet {
            dofs: by_dof.keys().copied().collect(),
            entries: by_dof.into_values().collect(),
            values: specs.iter().map(|d| d.value.clone()).collect(),
            present: !specs.is_empty(),
            nonzero: specs.iter().any(|d| !d.value.is_zero()),
        })
    }

    /// No Dirichlet boundary.
    pub fn none() -> Dirichlet {
        Dirichlet { dofs: vec![], entries: vec![], values: vec![], present: false, nonzero: false }
    }

    /// The constrained global DOFs owned by this rank.
    pub fn dofs(&self) -> &[i32] {
        &self.dofs
    }

    /// `g` at the i-th constrained DOF and time t.
    pub fn value(&self, i: usize, t: f64) -> f64 {
        let (x, c, s) = self.entries[i];
        self.values[s].eval(x, t)[c]
    }
}
