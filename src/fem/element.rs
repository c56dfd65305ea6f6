//! Element kinds as gmsh numbers and orders them (MSH 4.1 element types and node ordering).

/// Lowest-order Lagrange elements, with gmsh's node ordering:
/// - `Line2` (gmsh 1): 0--1
/// - `Tri3` (gmsh 2): counter-clockwise (0,0),(1,0),(0,1)
/// - `Quad4` (gmsh 3): counter-clockwise (-1,-1),(1,-1),(1,1),(-1,1)
/// - `Tet4` (gmsh 4): (0,0,0),(1,0,0),(0,1,0),(0,0,1)
/// - `Hex8` (gmsh 5): bottom face 0-3 counter-clockwise seen from +z, then top face 4-7 above them
/// - `Point1` (gmsh 15)
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ElementKind {
    Point1,
    Line2,
    Tri3,
    Quad4,
    Tet4,
    Hex8,
}

impl ElementKind {
    /// Every kind, in gmsh type order (the order the run file stores cell kinds in).
    pub const ALL: [ElementKind; 6] = [
        ElementKind::Line2,
        ElementKind::Tri3,
        ElementKind::Quad4,
        ElementKind::Tet4,
        ElementKind::Hex8,
        ElementKind::Point1,
    ];

    pub fn from_gmsh(t: i32) -> Option<ElementKind> {
        Some(match t {
            15 => ElementKind::Point1,
            1 => ElementKind::Line2,
            2 => ElementKind::Tri3,
            3 => ElementKind::Quad4,
            4 => ElementKind::Tet4,
            5 => ElementKind::Hex8,
            _ => return None,
        })
    }
    pub fn gmsh_type(self) -> i32 {
        match self {
            ElementKind::Point1 => 15,
            ElementKind::Line2 => 1,
            ElementKind::Tri3 => 2,
            ElementKind::Quad4 => 3,
            ElementKind::Tet4 => 4,
            ElementKind::Hex8 => 5,
        }
    }
    pub fn n_nodes(self) -> usize {
        match self {
            ElementKind::Point1 => 1,
            ElementKind::Line2 => 2,
            ElementKind::Tri3 => 3,
            ElementKind::Quad4 => 4,
            ElementKind::Tet4 => 4,
            ElementKind::Hex8 => 8,
        }
    }
    /// Triangles and tetrahedra (constant strain in the linear elements).
    pub fn is_simplex(self) -> bool {
        matches!(self, ElementKind::Tri3 | ElementKind::Tet4)
    }

    /// Topological dimension.
    pub fn dim(self) -> usize {
        match self {
            ElementKind::Point1 => 0,
            ElementKind::Line2 => 1,
            ElementKind::Tri3 | ElementKind::Quad4 => 2,
            ElementKind::Tet4 | ElementKind::Hex8 => 3,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Point1 => "point",
            ElementKind::Line2 => "line",
            ElementKind::Tri3 => "triangle",
            ElementKind::Quad4 => "quadrilateral",
            ElementKind::Tet4 => "tetrahedron",
            ElementKind::Hex8 => "hexahedron",
        }
    }
    /// Local vertex pairs forming the edges of the element.
    #[rustfmt::skip]
    pub fn edges(self) -> &'static [[usize; 2]] {
        match self {
            ElementKind::Point1 => &[],
            ElementKind::Line2 => &[[0, 1]],
            ElementKind::Tri3 => &[[0, 1], [1, 2], [2, 0]],
            ElementKind::Quad4 => &[[0, 1], [1, 2], [2, 3], [3, 0]],
            ElementKind::Tet4 => &[[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]],
            ElementKind::Hex8 => &[
                [0, 1], [1, 2], [2, 3], [3, 0],
                [4, 5], [5, 6], [6, 7], [7, 4],
                [0, 4], [1, 5], [2, 6], [3, 7],
            ],
        }
    }
    /// Local vertex lists of the facets (dimension dim-1), outward-oriented for 2D/3D cells.
    #[rustfmt::skip]
    pub fn facets(self) -> &'static [&'static [usize]] {
        match self {
            ElementKind::Point1 => &[],
            ElementKind::Line2 => &[&[0], &[1]],
            ElementKind::Tri3 => &[&[0, 1], &[1, 2], &[2, 0]],
            ElementKind::Quad4 => &[&[0, 1], &[1, 2], &[2, 3], &[3, 0]],
            ElementKind::Tet4 => &[&[0, 2, 1], &[0, 1, 3], &[0, 3, 2], &[1, 2, 3]],
            ElementKind::Hex8 => &[
                &[0, 3, 2, 1],
                &[0, 1, 5, 4],
                &[1, 2, 6, 5],
                &[2, 3, 7, 6],
                &[3, 0, 4, 7],
                &[4, 5, 6, 7],
            ],
        }
    }
}
