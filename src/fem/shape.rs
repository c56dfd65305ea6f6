//! P1/Q1 shape functions on the reference elements and the isoparametric geometry map.
//!
//! Reference elements (gmsh node ordering, see [`ElementKind`]):
//! - `Point1`: N = 1.
//! - `Line2`: xi in [-1, 1], nodes -1, 1: N0 = (1 - xi)/2, N1 = (1 + xi)/2.
//! - `Tri3`: nodes (0,0),(1,0),(0,1): N = (1 - xi - eta, xi, eta).
//! - `Quad4`: nodes (-1,-1),(1,-1),(1,1),(-1,1): N_a = (1 + xi_a xi)(1 + eta_a eta)/4.
//! - `Tet4`: nodes (0,0,0),(1,0,0),(0,1,0),(0,0,1): N = (1 - xi - eta - zeta, xi, eta, zeta).
//! - `Hex8`: nodes (-1,-1,-1),(1,-1,-1),(1,1,-1),(-1,1,-1), then the same with zeta = +1:
//!   N_a = (1 + xi_a xi)(1 + eta_a eta)(1 + zeta_a zeta)/8.
//!
//! The geometry is isoparametric: x(xi) = sum_a N_a(xi) x_a. Coordinates are `[f64; 3]`; only
//! the first `kind.dim()` components are used by [`physical_gradients`] (z ignored in 2D,
//! y and z ignored for a `Line2` cell).

#![allow(clippy::needless_range_loop)] // index-heavy small dense linear algebra

use super::element::ElementKind;

/// Reference coordinates of the nodes of the Quad4 / Hex8 reference elements.
const QUAD_NODES: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
const HEX_NODES: [[f64; 3]; 8] = [
    [-1.0, -1.0, -1.0],
    [1.0, -1.0, -1.0],
    [1.0, 1.0, -1.0],
    [-1.0, 1.0, -1.0],
    [-1.0, -1.0, 1.0],
    [1.0, -1.0, 1.0],
    [1.0, 1.0, 1.0],
    [-1.0, 1.0, 1.0],
];

/// Reference coordinates of node `a` of `kind` (padded with zeros).
pub fn reference_node(kind: ElementKind, a: usize) -> [f64; 3] {
    match kind {
        ElementKind::Point1 => [0.0; 3],
        ElementKind::Line2 => [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]][a],
        ElementKind::Tri3 => [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]][a],
        ElementKind::Quad4 => [QUAD_NODES[a][0], QUAD_NODES[a][1], 0.0],
        ElementKind::Tet4 => {
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]][a]
        }
        ElementKind::Hex8 => HEX_NODES[a],
    }
}

/// Shape function values N_a(xi), a = 0..kind.n_nodes(), written to `n[..n_nodes]`.
#[inline]
pub fn shape(kind: ElementKind, xi: [f64; 3], n: &mut [f64]) {
    let [x, y, z] = xi;
    match kind {
        ElementKind::Point1 => n[0] = 1.0,
        ElementKind::Line2 => {
            n[0] = 0.5 * (1.0 - x);
            n[1] = 0.5 * (1.0 + x);
        }
        ElementKind::Tri3 => {
            n[0] = 1.0 - x - y;
            n[1] = x;
            n[2] = y;
        }
        ElementKind::Quad4 => {
            for (a, p) in QUAD_NODES.iter().enumerate() {
                n[a] = 0.25 * (1.0 + p[0] * x) * (1.0 + p[1] * y);
            }
        }
        ElementKind::Tet4 => {
            n[0] = 1.0 - x - y - z;
            n[1] = x;
            n[2] = y;
            n[3] = z;
        }
        ElementKind::Hex8 => {
            for (a, p) in HEX_NODES.iter().enumerate() {
                n[a] = 0.125 * (1.0 + p[0] * x) * (1.0 + p[1] * y) * (1.0 + p[2] * z);
            }
        }
    }
}

/// Reference gradients dN_a/dxi_j written to `dn[a][j]` (j = 0..3, unused directions 0).
#[inline]
pub fn shape_grad_ref(kind: ElementKind, xi: [f64; 3], dn: &mut [[f64; 3]]) {
    let [x, y, z] = xi;
    match kind {
        ElementKind::Point1 => dn[0] = [0.0; 3],
        ElementKind::Line2 => {
            dn[0] = [-0.5, 0.0, 0.0];
            dn[1] = [0.5, 0.0, 0.0];
        }
        ElementKind::Tri3 => {
            dn[0] = [-1.0, -1.0, 0.0];
            dn[1] = [1.0, 0.0, 0.0];
            dn[2] = [0.0, 1.0, 0.0];
        }
        ElementKind::Quad4 => {
            for (a, p) in QUAD_NODES.iter().enumerate() {
                dn[a] = [0.25 * p[0] * (1.0 + p[1] * y), 0.25 * p[1] * (1.0 + p[0] * x), 0.0];
            }
        }
        ElementKind::Tet4 => {
            dn[0] = [-1.0, -1.0, -1.0];
            dn[1] = [1.0, 0.0, 0.0];
            dn[2] = [0.0, 1.0, 0.0];
            dn[3] = [0.0, 0.0, 1.0];
        }
        ElementKind::Hex8 => {
            for (a, p) in HEX_NODES.iter().enumerate() {
                let (fx, fy, fz) = (1.0 + p[0] * x, 1.0 + p[1] * y, 1.0 + p[2] * z);
                dn[a] = [0.125 * p[0] * fy * fz, 0.125 * p[1] * fx * fz, 0.125 * p[2] * fx * fy];
            }
        }
    }
}

/// Given reference gradients `dn_ref` (n nodes), computes the Jacobian
/// J_ij = sum_a x_a[i] dN_a/dxi_j (i, j < d = kind.dim()), returns det J and overwrites
/// `dn` with the physical gradients dN_a/dx = J^{-T} dN_a/dxi. If det J == 0 (or is not
/// finite) the gradients are set to zero; callers must check the sign of the returned
/// determinant. Works in place: `dn` holds reference gradients on entry.
#[inline(always)]
pub(crate) fn map_gradients(d: usize, n: usize, coords: &[[f64; 3]], dn: &mut [[f64; 3]]) -> f64 {
    let j = jacobian(d, n, coords, dn);
    match d {
        3 => {
            let c00 = j[1][1] * j[2][2] - j[1][2] * j[2][1];
            let c01 = j[1][2] * j[2][0] - j[1][0] * j[2][2];
            let c02 = j[1][0] * j[2][1] - j[1][1] * j[2][0];
            let det = j[0][0] * c00 + j[0][1] * c01 + j[0][2] * c02;
            if det == 0.0 || !det.is_finite() {
                dn[..n].iter_mut().for_each(|g| *g = [0.0; 3]);
                return det;
            }
            let id = 1.0 / det;
            // inv = adj(J)/det; we need (J^{-T} g)_r = sum_c inv[c][r] g_c.
            // inv^T = cofactor matrix / det.
            let cof = [
                [c00, c01, c02],
                [
                    j[0][2] * j[2][1] - j[0][1] * j[2][2],
                    j[0][0] * j[2][2] - j[0][2] * j[2][0],
                    j[0][1] * j[2][0] - j[0][0] * j[2][1],
                ],
                [
                    j[0][1] * j[1][2] - j[0][2] * j[1][1],
                    j[0][2] * j[1][0] - j[0][0] * j[1][2],
                    j[0][0] * j[1][1] - j[0][1] * j[1][0],
                ],
            ];
            for g in dn[..n].iter_mut() {
                let r = *g;
                for i in 0..3 {
                    g[i] = id * (cof[i][0] * r[0] + cof[i][1] * r[1] + cof[i][2] * r[2]);
                }
            }
            det
        }
        2 => {
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det == 0.0 || !det.is_finite() {
                dn[..n].iter_mut().for_each(|g| *g = [0.0; 3]);
                return det;
            }
            let id = 1.0 / det;
            // J^{-T} = [[j11, -j10], [-j01, j00]] / det
            for g in dn[..n].iter_mut() {
                let r = *g;
                g[0] = id * (j[1][1] * r[0] - j[1][0] * r[1]);
                g[1] = id * (-j[0][1] * r[0] + j[0][0] * r[1]);
                g[2] = 0.0;
            }
            det
        }
        1 => {
            let det = j[0][0];
            if det == 0.0 || !det.is_finite() {
                dn[..n].iter_mut().for_each(|g| *g = [0.0; 3]);
                return det;
            }
            for g in dn[..n].iter_mut() {
                *g = [g[0] / det, 0.0, 0.0];
            }
            det
        }
        _ => 1.0,
    }
}

/// The Jacobian J_ij = dx_i/dxi_j = sum_a x_a[i] dN_a/dxi_j (i, j < d; other entries 0) of
/// the nodes `coords[..n]` from their reference gradients `dn[..n]`.
#[inline(always)]
pub(crate) fn jacobian(d: usize, n: usize, coords: &[[f64; 3]], dn: &[[f64; 3]]) -> [[f64; 3]; 3] {
    let mut j = [[0.0f64; 3]; 3];
    for a in 0..n {
        let x = coords[a];
        let g = dn[a];
        for r in 0..d {
            for c in 0..d {
                j[r][c] += x[r] * g[c];
            }
        }
    }
    j
}

/// det J only (J_ij = sum_a x_a[i] dN_a/dxi_j, i, j < d), from reference gradients.
#[inline(always)]
pub(crate) fn jacobian_det(d: usize, n: usize, coords: &[[f64; 3]], dn: &[[f64; 3]]) -> f64 {
    let j = jacobian(d, n, coords, dn);
    match d {
        // `det3` with the middle cofactor negated: the same value up to the sign of an exact
        // zero, kept so that the kernels' results stay bit-for-bit what they were.
        3 => {
            j[0][0] * (j[1][1] * j[2][2] - j[1][2] * j[2][1])
                + j[0][1] * (j[1][2] * j[2][0] - j[1][0] * j[2][2])
                + j[0][2] * (j[1][0] * j[2][1] - j[1][1] * j[2][0])
        }
        2 => j[0][0] * j[1][1] - j[0][1] * j[1][0],
        1 => j[0][0],
        _ => 1.0,
    }
}

/// Determinant of a 3 x 3 matrix (cofactor expansion along the first row): one copy for the
/// mesh checks' Jacobians and volumes and the mass-free layer's Gram determinants and
/// barycentric coordinates.
#[inline]
pub fn det3(a: &[[f64; 3]; 3]) -> f64 {
    a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
        - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
}

/// Physical shape-function gradients of a cell at reference point `xi`.
///
/// With J_ij = dx_i/dxi_j = sum_a x_a[i] dN_a/dxi_j (i, j < d = `kind.dim()`), fills
/// `dn_phys[a] = J^{-T} grad_xi N_a` (unused components 0) and returns det J. The determinant
/// is the ratio of physical to reference measure (reference triangle area 1/2, tet volume 1/6,
/// quad area 4, hex volume 8). If det J == 0 the gradients are set to zero; a negative det J
/// means an inverted element (gradients are still correct for that map).
#[inline]
pub fn physical_gradients(
    kind: ElementKind,
    coords: &[[f64; 3]],
    xi: [f64; 3],
    dn_phys: &mut [[f64; 3]],
) -> f64 {
    shape_grad_ref(kind, xi, dn_phys);
    map_gradients(kind.dim(), kind.n_nodes(), coords, dn_phys)
}

/// Surface element and unit normal of a boundary facet at reference point `xi`.
///
/// Returns `(ds, n)` with `ds` the ratio of physical to reference measure and `n` the unit
/// normal. Orientation rule (right-hand rule on the node ordering):
/// - `Line2` (boundary of a 2D domain; z ignored): t = dx/dxi (from node 0 towards node 1),
///   ds = |t| (= L/2 since the reference line is [-1, 1]), n = (t_y, -t_x)/|t|, i.e. the
///   normal points to the RIGHT of the direction of travel; outward for a counter-clockwise
///   boundary.
/// - `Tri3` / `Quad4` (faces in 3D): a1 = dx/dxi, a2 = dx/deta, n = a1 x a2 / |a1 x a2|,
///   ds = |a1 x a2|: the normal points towards the side from which the nodes appear
///   counter-clockwise. The facets listed by `ElementKind::facets()` for Tet4/Hex8 yield the
///   outward normal with this rule (checked in the tests).
/// - `Point1`: ds = 1, n = 0.
///
/// For a degenerate facet ds = 0 and n = 0. Panics for cell kinds Tet4/Hex8.
#[inline]
pub fn surface_measure(kind: ElementKind, coords: &[[f64; 3]], xi: [f64; 3]) -> (f64, [f64; 3]) {
    let mut dn = [[0.0; 3]; 4];
    let n = kind.n_nodes();
    match kind {
        ElementKind::Point1 => (1.0, [0.0; 3]),
        ElementKind::Line2 => {
            shape_grad_ref(kind, xi, &mut dn);
            let mut t = [0.0; 2];
            for a in 0..n {
                t[0] += coords[a][0] * dn[a][0];
                t[1] += coords[a][1] * dn[a][0];
            }
            let l = (t[0] * t[0] + t[1] * t[1]).sqrt();
            if l == 0.0 {
                return (0.0, [0.0; 3]);
            }
            (l, [t[1] / l, -t[0] / l, 0.0])
        }
        ElementKind::Tri3 | ElementKind::Quad4 => {
            shape_grad_ref(kind, xi, &mut dn);
            let mut a1 = [0.0; 3];
            let mut a2 = [0.0; 3];
            for a in 0..n {
                for i in 0..3 {
                    a1[i] += coords[a][i] * dn[a][0];
                    a2[i] += coords[a][i] * dn[a][1];
                }
            }
            let c = [
                a1[1] * a2[2] - a1[2] * a2[1],
                a1[2] * a2[0] - a1[0] * a2[2],
                a1[0] * a2[1] - a1[1] * a2[0],
            ];
            let s = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if s == 0.0 {
                return (0.0, [0.0; 3]);
            }
            (s, [c[0] / s, c[1] / s, c[2] / s])
        }
        ElementKind::Tet4 | ElementKind::Hex8 => {
            panic!("surface_measure: {} is not a boundary facet kind", kind.name())
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    const KINDS: [ElementKind; 6] = [
        ElementKind::Point1,
        ElementKind::Line2,
        ElementKind::Tri3,
        ElementKind::Quad4,
        ElementKind::Tet4,
        ElementKind::Hex8,
    ];

    fn sample_points(kind: ElementKind) -> Vec<[f64; 3]> {
        match kind {
            ElementKind::Tri3 => vec![[0.2, 0.3, 0.0], [0.1, 0.7, 0.0], [0.6, 0.05, 0.0]],
            ElementKind::Tet4 => vec![[0.2, 0.3, 0.1], [0.1, 0.1, 0.7], [0.05, 0.6, 0.2]],
            _ => vec![[0.3, -0.7, 0.45], [-0.9, 0.2, -0.35], [0.0, 0.0, 0.0]],
        }
    }

    #[test]
    fn partition_of_unity_and_gradients_sum_to_zero() {
        for kind in KINDS {
            for xi in sample_points(kind) {
                let mut n = [0.0; 8];
                let mut dn = [[0.0; 3]; 8];
                shape(kind, xi, &mut n);
                shape_grad_ref(kind, xi, &mut dn);
                let nn = kind.n_nodes();
                let s: f64 = n[..nn].iter().sum();
                assert!((s - 1.0).abs() < 1e-15, "{kind:?}: sum N = {s}");
                for j in 0..3 {
                    let g: f64 = dn[..nn].iter().map(|d| d[j]).sum();
                    assert!(g.abs() < 1e-15, "{kind:?}: sum dN/dxi_{j} = {g}");
                }
            }
        }
    }

    #[test]
    fn kronecker_delta_at_nodes() {
        for kind in KINDS {
            let nn = kind.n_nodes();
            for b in 0..nn {
                let mut n = [0.0; 8];
                shape(kind, reference_node(kind, b), &mut n);
                for a in 0..nn {
                    let e = if a == b { 1.0 } else { 0.0 };
                    assert!((n[a] - e).abs() < 1e-15, "{kind:?}: N_{a}(node {b}) = {}", n[a]);
                }
            }
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let h = 1e-6;
        for kind in KINDS {
            let nn = kind.n_nodes();
            for xi in sample_points(kind) {
                let mut dn = [[0.0; 3]; 8];
                shape_grad_ref(kind, xi, &mut dn);
                for j in 0..kind.dim() {
                    let (mut p, mut m) = (xi, xi);
                    p[j] += h;
                    m[j] -= h;
                    let (mut np, mut nm) = ([0.0; 8], [0.0; 8]);
                    shape(kind, p, &mut np);
                    shape(kind, m, &mut nm);
                    for a in 0..nn {
                        let fd = (np[a] - nm[a]) / (2.0 * h);
                        assert!((fd - dn[a][j]).abs() < 1e-9, "{kind:?} a={a} j={j}");
                    }
                }
            }
        }
    }

    /// A fixed affine map x = A xi + b with det A = 2 (3D) or 2.5 (2D), applied to a cell's
    /// reference nodes, followed by a non-affine perturbation (all still valid elements).
    /// Also the kernel tests' cells.
    pub(crate) fn mapped_coords(kind: ElementKind, distort: bool) -> Vec<[f64; 3]> {
        (0..kind.n_nodes())
            .map(|a| {
                let r = reference_node(kind, a);
                let mut x = [
                    1.0 + 2.0 * r[0] + 0.5 * r[1] + 0.1 * r[2],
                    -1.0 + 0.5 * r[0] + 1.5 * r[1] + 0.2 * r[2],
                    0.3 + 0.1 * r[0] - 0.2 * r[1] + 0.9 * r[2],
                ];
                if distort {
                    x[0] += 0.15 * (a as f64 * 1.7).sin();
                    x[1] += 0.12 * (a as f64 * 2.3).cos();
                    x[2] += 0.1 * (a as f64 * 0.9).sin();
                }
                if kind.dim() < 3 {
                    x[2] = 0.0;
                }
                x
            })
            .collect()
    }

    #[test]
    fn physical_gradients_match_finite_differences_in_x() {
        // Check grad_x N via the chain rule: for a small reference step d xi,
        // N(xi + d xi) - N(xi) ~ grad_x N . (x(xi + d xi) - x(xi)).
        let h = 1e-6;
        for kind in [ElementKind::Tri3, ElementKind::Quad4, ElementKind::Tet4, ElementKind::Hex8] {
            let nn = kind.n_nodes();
            let d = kind.dim();
            let coords = mapped_coords(kind, true);
            for xi in sample_points(kind) {
                let mut g = [[0.0; 3]; 8];
                let det = physical_gradients(kind, &coords, xi, &mut g);
                assert!(det > 0.0);
                for j in 0..d {
                    let (mut p, mut m) = (xi, xi);
                    p[j] += h;
                    m[j] -= h;
                    let (mut np, mut nm) = ([0.0; 8], [0.0; 8]);
                    shape(kind, p, &mut np);
                    shape(kind, m, &mut nm);
                    let mut dx = [0.0; 3];
                    for a in 0..nn {
                        for i in 0..d {
                            dx[i] += (np[a] - nm[a]) * coords[a][i];
                        }
                    }
                    for a in 0..nn {
                        let dn = np[a] - nm[a];
                        let pred: f64 = (0..d).map(|i| g[a][i] * dx[i]).sum();
                        assert!((dn - pred).abs() < 1e-9, "{kind:?} a={a} j={j}: {dn} vs {pred}");
                    }
                }
            }
        }
    }

    #[test]
    fn physical_gradients_reproduce_linear_fields() {
        // sum_a x_a[i] grad N_a = e_i for any (also distorted) element.
        for kind in [ElementKind::Tri3, ElementKind::Quad4, ElementKind::Tet4, ElementKind::Hex8] {
            let d = kind.dim();
            let coords = mapped_coords(kind, true);
            for xi in sample_points(kind) {
                let mut g = [[0.0; 3]; 8];
                physical_gradients(kind, &coords, xi, &mut g);
                for i in 0..d {
                    for j in 0..d {
                        let s: f64 = (0..kind.n_nodes()).map(|a| coords[a][i] * g[a][j]).sum();
                        let e = if i == j { 1.0 } else { 0.0 };
                        assert!((s - e).abs() < 1e-13, "{kind:?} ({i},{j}) = {s}");
                    }
                }
            }
        }
    }

    #[test]
    fn det_j_of_affine_map() {
        for (kind, det_a) in [
            (ElementKind::Tri3, 2.0 * 1.5 - 0.5 * 0.5),
            (ElementKind::Quad4, 2.0 * 1.5 - 0.5 * 0.5),
            (ElementKind::Tet4, 0.0),
            (ElementKind::Hex8, 0.0),
        ] {
            let a = [[2.0, 0.5, 0.1], [0.5, 1.5, 0.2], [0.1, -0.2, 0.9]];
            let det3 = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1])
                - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
                + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
            let expect = if kind.dim() == 3 { det3 } else { det_a };
            let coords = mapped_coords(kind, false);
            let mut g = [[0.0; 3]; 8];
            let det = physical_gradients(kind, &coords, sample_points(kind)[0], &mut g);
            assert!((det - expect).abs() < 1e-14, "{kind:?}: {det} vs {expect}");
        }
    }

    #[test]
    fn line_normal_points_right_of_travel() {
        // Counter-clockwise unit square: outward normals -y, +x, +y, -x.
        let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        let expect = [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]];
        for e in 0..4 {
            let c = [p[e], p[(e + 1) % 4]];
            let (ds, n) = surface_measure(ElementKind::Line2, &c, [0.3, 0.0, 0.0]);
            assert!((ds - 0.5).abs() < 1e-15);
            assert!((n[0] - expect[e][0]).abs() < 1e-15 && (n[1] - expect[e][1]).abs() < 1e-15);
        }
        // Slanted segment of length 5 from (0,0) to (3,4): n = (4,-3)/5, ds = 5/2.
        let (ds, n) =
            surface_measure(ElementKind::Line2, &[[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]], [0.0; 3]);
        assert!((ds - 2.5).abs() < 1e-15);
        assert!((n[0] - 0.8).abs() < 1e-15 && (n[1] + 0.6).abs() < 1e-15);
    }

    /// Outward normals of the facets listed in `ElementKind::facets()` for the 3D reference
    /// cells: the facet normal from `surface_measure` must point away from the cell centroid.
    #[test]
    fn cell_facets_give_outward_normals() {
        for kind in [ElementKind::Tet4, ElementKind::Hex8] {
            let nn = kind.n_nodes();
            let nodes: Vec<[f64; 3]> = (0..nn).map(|a| reference_node(kind, a)).collect();
            let mut cen = [0.0; 3];
            for x in &nodes {
                for i in 0..3 {
                    cen[i] += x[i] / nn as f64;
                }
            }
            for (f, facet) in kind.facets().iter().enumerate() {
                let fk = if facet.len() == 3 { ElementKind::Tri3 } else { ElementKind::Quad4 };
                let c: Vec<[f64; 3]> = facet.iter().map(|&a| nodes[a]).collect();
                let xi =
                    if fk == ElementKind::Tri3 { [1.0 / 3.0, 1.0 / 3.0, 0.0] } else { [0.0; 3] };
                let (ds, n) = surface_measure(fk, &c, xi);
                assert!(ds > 0.0);
                let mut fc = [0.0; 3];
                for x in &c {
                    for i in 0..3 {
                        fc[i] += x[i] / c.len() as f64;
                    }
                }
                let out: f64 = (0..3).map(|i| n[i] * (fc[i] - cen[i])).sum();
                assert!(out > 0.0, "{kind:?} facet {f} {facet:?}: inward normal {n:?}");
                // Unit axis-aligned normals for the reference hex.
                if kind == ElementKind::Hex8 {
                    let nrm: f64 = n.iter().map(|v| v.abs()).sum();
                    assert!((nrm - 1.0).abs() < 1e-15);
                }
            }
        }
        // 2D cells: facets (edges) must have normals pointing away from the centroid.
        for kind in [ElementKind::Tri3, ElementKind::Quad4] {
            let nn = kind.n_nodes();
            let nodes: Vec<[f64; 3]> = (0..nn).map(|a| reference_node(kind, a)).collect();
            let cen = nodes.iter().fold([0.0; 3], |acc, x| {
                [acc[0] + x[0] / nn as f64, acc[1] + x[1] / nn as f64, 0.0]
            });
            for facet in kind.facets() {
                let c = [nodes[facet[0]], nodes[facet[1]]];
                let (_, n) = surface_measure(ElementKind::Line2, &c, [0.0; 3]);
                let mid = [(c[0][0] + c[1][0]) / 2.0, (c[0][1] + c[1][1]) / 2.0];
                assert!(
                    n[0] * (mid[0] - cen[0]) + n[1] * (mid[1] - cen[1]) > 0.0,
                    "{kind:?} {facet:?}"
                );
            }
        }
    }

    #[test]
    fn surface_area_of_faces() {
        // Tri3 face with legs 2 and 3 in the plane z = 1: area 3, ds = 2 * area = 6.
        let c = [[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 3.0, 1.0]];
        let (ds, n) = surface_measure(ElementKind::Tri3, &c, [0.2, 0.2, 0.0]);
        assert!((ds - 6.0).abs() < 1e-14 && (n[2] - 1.0).abs() < 1e-15);
        // Quad4 face 2 x 3 in the plane x = 0, ordered so the normal is -x: ds = area/4.
        let c = [[0.0, 0.0, 0.0], [0.0, 0.0, 3.0], [0.0, 2.0, 3.0], [0.0, 2.0, 0.0]];
        let (ds, n) = surface_measure(ElementKind::Quad4, &c, [0.1, -0.4, 0.0]);
        assert!((ds - 1.5).abs() < 1e-14 && (n[0] + 1.0).abs() < 1e-15, "{ds} {n:?}");
    }
}
