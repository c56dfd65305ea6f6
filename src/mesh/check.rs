//! Geometric sanity of the cells before any assembly: an inverted or flat element would
//! give a negative or singular Jacobian deep inside the solver, far from its cause.

use super::{Element, ElementKind, Mesh};
use crate::error::{Error, Result};
use crate::fem::shape::{det3, jacobian, reference_node, shape_grad_ref};

/// Relative tolerance below which a cell counts as degenerate: |measure| <= TOL * h^dim.
const TOL: f64 = 1e-12;

/// Checks that every cell is positively oriented and not degenerate.
///
/// Triangles and tetrahedra use their signed area/volume; quadrangles and hexahedra the
/// Jacobian determinant of the (bi/tri)linear map at every corner, which catches inverted,
/// non-convex and bow-tie shapes. 2D meshes must lie in the xy-plane (z = 0).
pub fn check_geometry(mesh: &Mesh) -> Result<()> {
    if mesh.dim == 2 {
        check_planar(mesh)?;
    }
    for e in &mesh.cells {
        check_cell(mesh, e)?;
    }
    Ok(())
}

fn check_planar(mesh: &Mesh) -> Result<()> {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for x in &mesh.coords {
        for k in 0..3 {
            lo[k] = lo[k].min(x[k]);
            hi[k] = hi[k].max(x[k]);
        }
    }
    let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
    for (i, x) in mesh.coords.iter().enumerate() {
        if x[2].abs() > 1e-9 * size.max(f64::MIN_POSITIVE) {
            return Err(Error::Mesh(format!(
                "2D mesh is not in the xy-plane: node tag {} has z = {}",
                mesh.node_tags[i], x[2]
            )));
        }
    }
    Ok(())
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Longest edge: the length scale for the degeneracy tolerance.
fn size(x: &[[f64; 3]], kind: ElementKind) -> f64 {
    kind.edges()
        .iter()
        .map(|&[a, b]| {
            let d = sub(x[a], x[b]);
            (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
        })
        .fold(0.0, f64::max)
}

/// det J of the bilinear (quad) or trilinear (hex) map of the cell with nodes `x` at the
/// reference point `xi`.
fn jacobian_det_at(x: &[[f64; 3]], kind: ElementKind, xi: [f64; 3]) -> f64 {
    let mut dn = [[0.0; 3]; 8];
    shape_grad_ref(kind, xi, &mut dn);
    let j = jacobian(kind.dim(), kind.n_nodes(), x, &dn);
    match kind {
        ElementKind::Quad4 => j[0][0] * j[1][1] - j[0][1] * j[1][0],
        // Expanded along the first column (det3 of J^T), as these checks always have.
        ElementKind::Hex8 => det3(&[
            [j[0][0], j[1][0], j[2][0]],
            [j[0][1], j[1][1], j[2][1]],
            [j[0][2], j[1][2], j[2][2]],
        ]),
        _ => unreachable!("jacobian_det_at is for quads and hexes"),
    }
}

/// Jacobian determinants at the corners, scaled to the corner's parallelogram area
/// (x4 for quads) or parallelepiped volume (x8 for hexes) so they compare with h^dim.
fn corner_measures(x: &[[f64; 3]], kind: ElementKind) -> Vec<f64> {
    let scale = if kind == ElementKind::Quad4 { 4.0 } else { 8.0 };
    (0..kind.n_nodes()).map(|a| scale * jacobian_det_at(x, kind, reference_node(kind, a))).collect()
}

fn check_cell(mesh: &Mesh, e: &Element) -> Result<()> {
    let x = mesh.element_coords(e);
    let kind = e.kind;
    let h = size(&x, kind);
    let tol = TOL * h.powi(kind.dim() as i32);
    let tags: Vec<String> = e.nodes().iter().map(|&n| mesh.node_tags[n].to_string()).collect();
    let tags = tags.join(", ");
    let name = kind.name();
    let t = e.tag;
    let mesh_err = |s: String| Err(Error::Mesh(s));
    if kind.dim() != mesh.dim {
        return mesh_err(format!(
            "{name} (gmsh element tag {t}) is a cell of a {}D mesh",
            mesh.dim
        ));
    }
    match kind {
        ElementKind::Tri3 | ElementKind::Tet4 => {
            let (m, what) = if kind == ElementKind::Tri3 {
                let (a, b) = (sub(x[1], x[0]), sub(x[2], x[0]));
                (0.5 * (a[0] * b[1] - a[1] * b[0]), "signed area")
            } else {
                (det3(&[sub(x[1], x[0]), sub(x[2], x[0]), sub(x[3], x[0])]) / 6.0, "signed volume")
            };
            if m.abs() <= tol {
                return mesh_err(format!(
                    "degenerate {name} (gmsh element tag {t}): {what} {m:e} for size {h:e} \
                     (node tags {tags})"
                ));
            }
            if m < 0.0 {
                let hint = if kind == ElementKind::Tri3 {
                    "; the nodes are clockwise: if the surface normal points to -z, add \
                     `Reverse Surface{...};` for that surface in the .geo"
                } else {
                    "; the node ordering is left-handed"
                };
                return mesh_err(format!(
                    "inverted {name} (gmsh element tag {t}): {what} {m:e} < 0 (node tags \
                     {tags}){hint}"
                ));
            }
        }
        ElementKind::Quad4 | ElementKind::Hex8 => {
            let m = corner_measures(&x, kind);
            if let Some(k) = m.iter().position(|v| v.abs() <= tol) {
                return mesh_err(format!(
                    "degenerate {name} (gmsh element tag {t}): Jacobian determinant ~0 \
                     ({:e}) at corner {k} (node tag {}), size {h:e} (node tags {tags})",
                    m[k],
                    mesh.node_tags[e.nodes()[k]]
                ));
            }
            if let Some(k) = m.iter().position(|&v| v < 0.0) {
                let hint = if kind == ElementKind::Quad4 {
                    if m.iter().all(|&v| v < 0.0) {
                        "; the nodes are clockwise: if the surface normal points to -z, add \
                         `Reverse Surface{...};` for that surface in the .geo"
                    } else {
                        "; the quadrangle is non-convex or self-intersecting"
                    }
                } else {
                    "; the hexahedron is inverted, non-convex or twisted"
                };
                return mesh_err(format!(
                    "inverted {name} (gmsh element tag {t}): Jacobian determinant {:e} < 0 at \
                     corner {k} (node tag {}) (node tags {tags}){hint}",
                    m[k],
                    mesh.node_tags[e.nodes()[k]]
                ));
            }
        }
        ElementKind::Point1 | ElementKind::Line2 => {
            return mesh_err(format!(
                "{name} (gmsh element tag {t}) cannot be a cell of a {}D mesh",
                mesh.dim
            ));
        }
    }
    Ok(())
}

/// Signed measure of a cell (area in 2D, volume in 3D); used by tests and diagnostics.
///
/// Quadrangles and hexahedra are integrated exactly with 2x2(x2) Gauss points (the
/// Jacobian of a bilinear/trilinear map is polynomial of low degree).
pub fn cell_measure(mesh: &Mesh, e: &Element) -> f64 {
    let x = mesh.element_coords(e);
    match e.kind {
        ElementKind::Tri3 => {
            let (a, b) = (sub(x[1], x[0]), sub(x[2], x[0]));
            0.5 * (a[0] * b[1] - a[1] * b[0])
        }
        ElementKind::Tet4 => det3(&[sub(x[1], x[0]), sub(x[2], x[0]), sub(x[3], x[0])]) / 6.0,
        ElementKind::Quad4 | ElementKind::Hex8 => {
            // The 2x2(x2) Gauss points are the corners scaled by 1/sqrt(3), weights 1.
            let g = 1.0 / 3f64.sqrt();
            let mut s = 0.0;
            for a in 0..e.kind.n_nodes() {
                let xi = reference_node(e.kind, a).map(|v| v * g);
                s += jacobian_det_at(&x, e.kind, xi);
            }
            s
        }
        ElementKind::Point1 | ElementKind::Line2 => 0.0,
    }
}
