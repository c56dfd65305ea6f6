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
    /// XDMF's attribute type for this number of components.
    pub fn xdmf_type(&self, dim: usize) -> &'static str {
        match self.components {
            1 => "Scalar",
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
