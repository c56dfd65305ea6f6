//! The output fields as data: each field is a spec (name, components, nodal or cell data),
//! and the scene's field list, the HDF5 writer, the XDMF index and `post` all iterate specs.
//! A new field is one entry here (or in the scene's field list) plus the kernel that computes
//! it.

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

/// A field of the output plan: its spec and its period in steps.
#[derive(Debug, Clone)]
pub struct PlannedField {
    pub spec: FieldSpec,
    pub every: usize,
}
