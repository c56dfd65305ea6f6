//! Mesh topology: which cells share a facet or a node, and the boundary groups a contact
//! zone is given by. Pure functions of the mesh, so every rank holding the same mesh gets the
//! same answer; the partition, the mass-free layer and the contact boundary all build on them.

use std::collections::HashMap;

use super::{Element, Mesh};
use crate::error::{Error, Result};

/// Sorted facet node list padded with `usize::MAX` (facets have at most 4 nodes): equal for
/// the same facet seen from either of its cells, whatever their local numbering.
pub type FacetKey = [usize; 4];

/// The key of the facet of a cell with nodes `cell_nodes` made of its local nodes `local`.
pub fn facet_key(cell_nodes: &[usize], local: &[usize]) -> FacetKey {
    let mut k = [usize::MAX; 4];
    for (i, &a) in local.iter().enumerate() {
        k[i] = cell_nodes[a];
    }
    k[..local.len()].sort_unstable();
    k
}

/// Cells on each side of a facet: `(first, second, count)`, with `second == usize::MAX` while
/// only one cell has the facet and `count` the number of cells that have it.
pub type FacetCells = HashMap<FacetKey, (usize, usize, usize)>;

/// The facets of the given cells, each with the cells (among those given) that have it, in
/// the order given. Built only over the cells given (e.g. a contact layer and its neighbours,
/// see [`cells_near`]), so its cost follows their number, not the mesh's.
pub fn facet_map(mesh: &Mesh, cells: &[usize]) -> FacetCells {
    let mut map: FacetCells = HashMap::new();
    for &c in cells {
        let e = &mesh.cells[c];
        for f in e.kind.facets() {
            let entry = map.entry(facet_key(&e.nodes(), f)).or_insert((c, usize::MAX, 0));
            if entry.2 == 1 {
                entry.1 = c;
            }
            entry.2 += 1;
        }
    }
    map
}

/// The elements of a contact boundary group, checked: a group of dimension dim - 1, not
/// empty, and on the boundary of the body (each element a facet of exactly one cell).
/// Errors name the group and an offending gmsh element.
pub fn boundary_group<'m>(mesh: &'m Mesh, name: &str) -> Result<Vec<&'m Element>> {
    let group = mesh.group(name).map_err(|e| match e {
        Error::Mesh(m) => Error::Scene(format!("contact group: {m}")),
        other => other,
    })?;
    if group.dim + 1 != mesh.dim {
        return Err(Error::Scene(format!(
            "contact group \"{name}\" has dimension {}, but the contact boundary of a {}D \
             body must be a physical group of dimension {}",
            group.dim,
            mesh.dim,
            mesh.dim - 1
        )));
    }
    let elems = mesh.group_elements(name)?;
    if elems.is_empty() {
        return Err(Error::Scene(format!("contact group \"{name}\" has no elements")));
    }

    // The contact group must lie on the boundary: each of its elements is a facet of
    // exactly one cell.
    let facets = facet_map(mesh, &cells_near(mesh, &elems));
    for e in &elems {
        let all: Vec<usize> = (0..e.kind.n_nodes()).collect();
        let key = facet_key(&e.nodes(), &all);
        match facets.get(&key) {
            Some(&(_, _, 1)) => {}
            Some(&(c0, c1, n)) => {
                let other = if c1 == usize::MAX {
                    String::new()
                } else {
                    format!(" (between elements {} and {})", mesh.cells[c0].tag, mesh.cells[c1].tag)
                };
                return Err(Error::Scene(format!(
                    "contact group \"{name}\" is not on the boundary of the body: its \
                     element {} is a facet of {n} elements{other}",
                    e.tag
                )));
            }
            None => {
                return Err(Error::Mesh(format!(
                    "contact group \"{name}\": its element {} is not a facet of any {}D \
                     element (non-conforming mesh?)",
                    e.tag, mesh.dim
                )));
            }
        }
    }

    Ok(elems)
}

/// The indices (ascending) of the cells that share a node with a cell touching the given
/// boundary elements: every facet a boundary element or a cell touching one can share lies
/// among their facets.
pub fn cells_near(mesh: &Mesh, elems: &[&Element]) -> Vec<usize> {
    let mut near_contact = vec![false; mesh.n_nodes()];
    for e in elems {
        for n in e.nodes() {
            near_contact[n] = true;
        }
    }
    let mut near_layer = vec![false; mesh.n_nodes()];
    for cell in &mesh.cells {
        if cell.nodes().iter().any(|&n| near_contact[n]) {
            for n in cell.nodes() {
                near_layer[n] = true;
            }
        }
    }
    (0..mesh.cells.len())
        .filter(|&c| mesh.cells[c].nodes().iter().any(|&n| near_layer[n]))
        .collect()
}

/// The node -> cells map in CSR form: `(start, list)` with `start` of length
/// `n_nodes + 1`; the cells of node `v` are `list[start[v]..start[v + 1]]`, ascending.
pub fn node_cells(mesh: &Mesh) -> (Vec<usize>, Vec<usize>) {
    let n = mesh.n_nodes();
    let mut start = vec![0usize; n + 1];
    for e in &mesh.cells {
        for v in e.nodes() {
            start[v + 1] += 1;
        }
    }
    for i in 0..n {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut list = vec![0usize; start[n]];
    for (c, e) in mesh.cells.iter().enumerate() {
        for v in e.nodes() {
            list[fill[v]] = c;
            fill[v] += 1;
        }
    }
    (start, list)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{ElementKind, PhysicalGroup};

    /// Two unit quads side by side (nodes 0-1-2 bottom, 3-4-5 top), with the bottom edges as
    /// group "bottom" and the shared edge as group "mid".
    fn two_quads() -> Mesh {
        let coords = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [0.0, 1.0], [1.0, 1.0], [2.0, 1.0]];
        let line = |n: &[usize], tag, entity| Element::new(ElementKind::Line2, n, tag, entity);
        let group = |name: &str, dim, tag| PhysicalGroup {
            name: name.into(),
            dim,
            tag,
            entities: vec![tag],
        };
        Mesh {
            dim: 2,
            coords: coords.iter().map(|c| [c[0], c[1], 0.0]).collect(),
            node_tags: (1..=6).collect(),
            cells: vec![
                Element::new(ElementKind::Quad4, &[0, 1, 4, 3], 1, 1),
                Element::new(ElementKind::Quad4, &[1, 2, 5, 4], 2, 1),
            ],
            boundary: vec![line(&[0, 1], 11, 2), line(&[1, 2], 12, 2), line(&[1, 4], 13, 3)],
            groups: vec![group("body", 2, 1), group("bottom", 1, 2), group("mid", 1, 3)],
        }
    }

    #[test]
    fn facet_map_counts_the_cells_of_each_facet() {
        let m = two_quads();
        let facets = facet_map(&m, &[0, 1]);
        assert_eq!(facets.len(), 7);
        assert_eq!(facets[&facet_key(&[4, 1], &[0, 1])], (0, 1, 2));
        assert_eq!(facets[&facet_key(&[0, 1], &[1, 0])], (0, usize::MAX, 1));
        // Only the cells given count.
        assert_eq!(facet_map(&m, &[1])[&facet_key(&[1, 4], &[0, 1])], (1, usize::MAX, 1));
    }

    #[test]
    fn node_cells_is_csr_with_ascending_cells() {
        let (start, list) = node_cells(&two_quads());
        assert_eq!(start, vec![0, 1, 3, 4, 5, 7, 8]);
        assert_eq!(list, vec![0, 0, 1, 1, 0, 0, 1, 1]);
    }

    #[test]
    fn boundary_group_is_checked() {
        let m = two_quads();
        let tags: Vec<u64> = boundary_group(&m, "bottom").unwrap().iter().map(|e| e.tag).collect();
        assert_eq!(tags, vec![11, 12]);
        assert_eq!(cells_near(&m, &boundary_group(&m, "bottom").unwrap()), vec![0, 1]);
        let err = boundary_group(&m, "mid").unwrap_err().to_string();
        assert!(err.contains("element 13 is a facet of 2 elements (between elements 1 and 2)"));
        let err = boundary_group(&m, "body").unwrap_err().to_string();
        assert!(err.contains("\"body\" has dimension 2"), "{err}");
    }
}
