//! Plain rows of data that the solver produces and `io` writes and reads back: the energy
//! row of a step, the contact row of a step, and what an output field is. They sit below
//! both, so that `io` needs none of the solver's modules (and `scene` none of `io`).

/// The energies of the current state and the works done since the start: the midpoint rule
/// keeps `kinetic + potential - E^0 = external_work + contact_work + dirichlet_work -
/// friction_dissipation` to solver tolerance.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Energy {
    /// `1/2 v.Mv`
    pub kinetic: f64,
    /// `1/2 u.Au`
    pub potential: f64,
    /// `sum_k f^{k+1/2}.du^k`
    pub external_work: f64,
    /// `-sum_k lambda^{k+1/2}.B du^k` (<= 0)
    pub contact_work: f64,
    /// Work of the reactions at non-zero Dirichlet boundaries.
    pub dirichlet_work: f64,
    /// `sum_k sum_q t_q^{k+1/2} . s_q^k >= 0`: what friction dissipated (the tangential
    /// forces' work against the slip); a moving obstacle's tangential work is in
    /// `contact_work`.
    pub friction_dissipation: f64,
}

impl Energy {
    pub fn total(&self) -> f64 {
        self.kinetic + self.potential
    }

    /// The work of all contact forces, friction's included: `contact_work -
    /// friction_dissipation`.
    pub fn contact_work_with_friction(&self) -> f64 {
        self.contact_work - self.friction_dissipation
    }
}

/// One step on the contact boundary, per contact node in the order of the boundary's nodes:
/// the one row type that the solver returns, the history keeps, the file stores (with the
/// pressure `force / weight` beside it) and `post` reads back.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ContactRow {
    /// Midpoint contact force `lambda_q` (of the unscaled equation).
    pub force: Vec<f64>,
    /// Gap at `t_{n+1}` (NaN before the first step).
    pub gap: Vec<f64>,
    pub active: Vec<bool>,
    /// Active-set iterations of the step.
    pub iterations: usize,
    /// With friction (empty without): per contact node the tangential force `t_q` of the
    /// midpoint equation, on the obstacle or master side (the body gets `-t_q`), in the
    /// tangent plane; it points along the slip.
    pub tangential: Vec<[f64; 3]>,
    /// With friction: per contact node its set, [`STATE_INACTIVE`], [`STATE_STICK`] or
    /// [`STATE_SLIP`].
    pub state: Vec<u8>,
    /// With friction: per contact node the slip increment of the step, the tangential
    /// displacement relative to the obstacle (zero off contact and where it sticks).
    pub slip: Vec<[f64; 3]>,
}

/// A contact node's set in [`ContactRow::state`].
pub const STATE_INACTIVE: u8 = 0;
pub const STATE_STICK: u8 = 1;
pub const STATE_SLIP: u8 = 2;

impl ContactRow {
    /// Pressure `lambda_q / D_qq` with the boundary weights `D_qq`.
    pub fn pressure(&self, weights: &[f64]) -> Vec<f64> {
        self.force.iter().zip(weights).map(|(f, w)| f / w).collect()
    }

    /// The traction on the body at each contact node, `-p_q n_q - t_q / D_qq`, `dim`
    /// components per node (zero for a node without a normal yet: before its first step).
    pub fn traction(&self, weights: &[f64], normals: &[[f64; 3]], dim: usize) -> Vec<f64> {
        let pressure = self.pressure(weights);
        let nc = self.force.len();
        let mut traction = vec![0.0; nc * dim];
        for q in 0..nc.min(normals.len()) {
            for i in 0..dim {
                traction[q * dim + i] = -pressure[q] * normals[q][i];
            }
        }
        for (q, t) in self.tangential.iter().enumerate().take(nc) {
            for i in 0..dim {
                traction[q * dim + i] -= t[i] / weights[q];
            }
        }
        traction
    }

    /// The tangential traction on the body, `-t_q / D_qq`, `dim` components per node (empty
    /// without friction).
    pub fn tangential_traction(&self, weights: &[f64], dim: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.tangential.len() * dim);
        for (t, w) in self.tangential.iter().zip(weights) {
            out.extend((0..dim).map(|i| -t[i] / w));
        }
        out
    }
}

/// Where a field lives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Location {
    /// One value per mesh node, in the natural (gmsh) node order.
    Nodal,
    /// One value per cell, in the order of `/mesh/cells/<kind>` (kinds in gmsh type order).
    Cell,
}

/// One output field: `/fields/<name>` of shape `[written steps, nodes or cells, components]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FieldSpec {
    pub name: String,
    pub components: usize,
    pub location: Location,
}

impl FieldSpec {
    pub fn nodal(name: &str, components: usize) -> FieldSpec {
        FieldSpec { name: name.to_string(), components, location: Location::Nodal }
    }
    pub fn cell(name: &str, components: usize) -> FieldSpec {
        FieldSpec { name: name.to_string(), components, location: Location::Cell }
    }
    /// XDMF's attribute type for this number of components: 6 is a symmetric tensor
    /// (`Tensor6`) and 9 a full tensor (`Tensor`) on any mesh, `dim` or 3 a vector.
    ///
    /// Symmetric tensors are stored with 6 components in XDMF's `Tensor6` order
    /// **xx, xy, xz, yy, yz, zz** (the upper triangle row by row), in 2D too. Measured with
    /// ParaView 5.11 (tests/paraview.rs, tools/check-xdmf.py): the legacy `XDMFReader` expands
    /// `Tensor6` to the full 9-component tensor row by row (xx xy xz / xy yy yz / xz yz zz),
    /// which is this order; the Xdmf3 readers (`Xdmf3ReaderS`/`T`) pass the 6 components on
    /// as stored, and ParaView then labels them with VTK's symmetric order XX YY ZZ XY YZ XZ:
    /// there the component labelled "YY" is xy, "ZZ" xz, "XY" yy, "YZ" yz, "XZ" zz
    /// (`XDMFReader`'s 9 components are unambiguous). meshio returns the 6 as stored.
    pub fn xdmf_type(&self, dim: usize) -> &'static str {
        match self.components {
            1 => "Scalar",
            6 => "Tensor6",
            9 => "Tensor",
            c if c == dim || c == 3 => "Vector",
            _ => "Matrix",
        }
    }
    /// XDMF's centering.
    pub fn xdmf_center(&self) -> &'static str {
        match self.location {
            Location::Nodal => "Node",
            Location::Cell => "Cell",
        }
    }
}
