//! The plain mesh every rank holds: node coordinates, elements by dimension, and gmsh
//! physical groups by name. Reading (MSH 4.1, ASCII and binary) lives in `msh`, meshing
//! `.geo` sources with the gmsh command in `gmsh`, geometric checks in `check`, which cells
//! share facets and nodes (and the checked contact boundary groups) in `topology`.

pub mod blocks;
pub mod check;
pub mod convert;
pub mod exchange;
pub mod gmsh;
pub mod msh;
pub mod share;
pub mod topology;

use crate::error::{Error, Result};
pub use crate::fem::element::ElementKind;

/// One mesh element: its kind, its nodes (indices into `Mesh::coords`, gmsh ordering), and
/// the gmsh entity it belongs to (physical groups are sets of entities). Node indices are
/// stored in 32 bits (indices into a rank's part of the mesh): 48 bytes a cell instead of 80,
/// 0.12 GB per rank at 3.9M DOFs on 2 ranks.
#[derive(Debug, Clone, PartialEq)]
pub struct Element {
    pub kind: ElementKind,
    nodes: [u32; 8],
    /// gmsh element tag (for error messages).
    pub tag: u64,
    /// gmsh entity tag (the entity's dimension is `kind.dim()`).
    pub entity: i32,
}

impl Element {
    /// Panics on a node index beyond 32 bits (a part of a mesh with 4 x 10^9 nodes).
    pub fn new(kind: ElementKind, nodes: &[usize], tag: u64, entity: i32) -> Element {
        assert_eq!(nodes.len(), kind.n_nodes());
        let mut n = [0u32; 8];
        for (to, &v) in n.iter_mut().zip(nodes) {
            *to = u32::try_from(v).expect("node index beyond 32 bits");
        }
        Element { kind, nodes: n, tag, entity }
    }
    /// The node indices (a small copy; use it as a slice).
    #[inline]
    pub fn nodes(&self) -> NodeList {
        let mut ids = [0usize; 8];
        for (to, &v) in ids.iter_mut().zip(&self.nodes) {
            *to = v as usize;
        }
        NodeList { ids, n: self.kind.n_nodes() as u8 }
    }
}

/// An element's node indices, by value (see [`Element::nodes`]); a slice by `Deref`.
#[derive(Debug, Clone, Copy)]
pub struct NodeList {
    ids: [usize; 8],
    n: u8,
}

impl std::ops::Deref for NodeList {
    type Target = [usize];
    #[inline]
    fn deref(&self) -> &[usize] {
        &self.ids[..self.n as usize]
    }
}

impl IntoIterator for NodeList {
    type Item = usize;
    type IntoIter = std::iter::Take<std::array::IntoIter<usize, 8>>;
    fn into_iter(self) -> Self::IntoIter {
        self.ids.into_iter().take(self.n as usize)
    }
}

/// A gmsh physical group: a name, a dimension, and the entities it contains.
#[derive(Debug, Clone, PartialEq)]
pub struct PhysicalGroup {
    pub name: String,
    pub dim: usize,
    pub tag: i32,
    pub entities: Vec<i32>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Spatial dimension of the problem: 2 or 3 (the highest element dimension present).
    pub dim: usize,
    /// Node coordinates (z = 0 in 2D). Only nodes used by `cells` are kept, sorted by gmsh tag.
    pub coords: Vec<[f64; 3]>,
    /// gmsh tag of node i (the "original numbering" users see is the index i in this order).
    pub node_tags: Vec<u64>,
    /// Elements of dimension `dim`: the bodies.
    pub cells: Vec<Element>,
    /// Elements of lower dimension (facets, edges, points) that carry physical groups.
    pub boundary: Vec<Element>,
    pub groups: Vec<PhysicalGroup>,
}

impl Mesh {
    pub fn n_nodes(&self) -> usize {
        self.coords.len()
    }

    /// The physical group called `name`, or an error naming it and listing the groups there are.
    pub fn group(&self, name: &str) -> Result<&PhysicalGroup> {
        self.groups.iter().find(|g| g.name == name).ok_or_else(|| {
            let have: Vec<String> =
                self.groups.iter().map(|g| format!("\"{}\" (dim {})", g.name, g.dim)).collect();
            Error::Mesh(format!(
                "physical group \"{name}\" not found in the mesh; it has {}",
                if have.is_empty() { "no physical groups".to_string() } else { have.join(", ") }
            ))
        })
    }

    /// Elements (cells or boundary elements) that belong to the group.
    pub fn group_elements(&self, name: &str) -> Result<Vec<&Element>> {
        let g = self.group(name)?;
        let pool = if g.dim == self.dim { &self.cells } else { &self.boundary };
        Ok(pool
            .iter()
            .filter(|e| e.kind.dim() == g.dim && g.entities.contains(&e.entity))
            .collect())
    }

    /// Sorted, de-duplicated node indices of the group's elements.
    pub fn group_nodes(&self, name: &str) -> Result<Vec<usize>> {
        let mut nodes: Vec<usize> =
            self.group_elements(name)?.iter().flat_map(|e| e.nodes().into_iter()).collect();
        nodes.sort_unstable();
        nodes.dedup();
        Ok(nodes)
    }

    /// Coordinates of the nodes of an element.
    pub fn element_coords(&self, e: &Element) -> Vec<[f64; 3]> {
        e.nodes().iter().map(|&n| self.coords[n]).collect()
    }
}

/// The block of natural (original-order) nodes a rank writes: an even split.
pub fn natural_range(n_nodes: usize, rank: usize, size: usize) -> (usize, usize) {
    crate::comm::block_range(n_nodes, rank, size)
}

/// The cell kinds of the mesh in the order the file stores them (`/mesh/cells/<kind>`): gmsh
/// type order.
pub fn file_cell_kinds(mesh: &Mesh) -> Vec<ElementKind> {
    let mut kinds: Vec<ElementKind> = mesh.cells.iter().map(|c| c.kind).collect();
    kinds.sort_by_key(|k| k.gmsh_type());
    kinds.dedup();
    kinds
}

/// The natural (file) index of each mesh cell: its row in the file's cell order, the kinds of
/// [`file_cell_kinds`] one after the other, mesh order within a kind. Cell fields are written
/// in this order (for a mesh of one kind it is the mesh order).
pub fn natural_cell_index(mesh: &Mesh) -> Vec<usize> {
    let kinds = file_cell_kinds(mesh);
    let mut next = vec![0usize; kinds.len()];
    for c in &mesh.cells {
        let k = kinds.iter().position(|&k| k == c.kind).expect("kind");
        for n in &mut next[k + 1..] {
            *n += 1;
        }
    }
    mesh.cells
        .iter()
        .map(|c| {
            let k = kinds.iter().position(|&k| k == c.kind).expect("kind");
            next[k] += 1;
            next[k] - 1
        })
        .collect()
}
