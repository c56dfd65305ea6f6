//! Checks from theory: biorthogonality, partition of unity, exact transfer of linear fields,
//! weighted gaps, additivity, clipping and the bucket search against brute force.

use super::*;
use crate::fem::quadrature::gauss_legendre;

fn assert_close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol, "{}: {} vs {} (diff {:e}, tol {:e})", what, a, b, a - b, tol);
}

/// Rodrigues rotation about the unit `axis` by `angle`:
/// `R v = v cos + (k x v) sin + k (k . v)(1 - cos)`.
fn rotate(axis: Vec3, angle: f64, v: Vec3) -> Vec3 {
    let k = scale3(1.0 / norm3(axis), axis);
    let (s, c) = angle.sin_cos();
    add3(add3(scale3(c, v), scale3(s, cross3(k, v))), scale3(dot3(k, v) * (1.0 - c), k))
}

/// A rigid motion used to put test configurations in a general position.
fn tilt(v: Vec3) -> Vec3 {
    add3(rotate([1.0, 2.0, 3.0], 0.7, v), [0.3, -0.2, 0.5])
}

fn tilt2(v: Vec2) -> Vec2 {
    let (s, c) = 0.4f64.sin_cos();
    [c * v[0] - s * v[1] + 0.3, s * v[0] + c * v[1] - 0.7]
}

// ---------------- quadrature ----------------

#[test]
fn gauss_legendre_is_exact_to_degree_2n_minus_1() {
    let g = gauss_legendre(5);
    for k in 0..=9 {
        let q: f64 = g.iter().map(|&(x, w)| w * x.powi(k)).sum();
        let exact = if k % 2 == 1 { 0.0 } else { 2.0 / (k as f64 + 1.0) };
        assert_close(q, exact, 1e-15, &format!("int x^{}", k));
    }
}

#[test]
fn triangle_rule_is_exact_to_degree_5() {
    // int_T xi^a eta^b = a! b! / (a + b + 2)! on the unit reference triangle.
    let fact = |n: u32| (1..=n).map(|k| k as f64).product::<f64>();
    for a in 0..=5u32 {
        for b in 0..=(5 - a) {
            let q: f64 = triangle_rule_deg5()
                .iter()
                .map(|(l, w)| 0.5 * w * l[1].powi(a as i32) * l[2].powi(b as i32))
                .sum();
            assert_close(
                q,
                fact(a) * fact(b) / fact(a + b + 2),
                1e-16,
                &format!("xi^{} eta^{}", a, b),
            );
        }
    }
}

#[test]
fn three_point_rule_is_exact_to_degree_2_only() {
    let fact = |n: u32| (1..=n).map(|k| k as f64).product::<f64>();
    let q = |a: i32, b: i32| -> f64 {
        triangle_rule_deg2().iter().map(|(l, w)| 0.5 * w * l[1].powi(a) * l[2].powi(b)).sum()
    };
    for a in 0..=2u32 {
        for b in 0..=(2 - a) {
            let exact = fact(a) * fact(b) / fact(a + b + 2);
            assert_close(q(a as i32, b as i32), exact, 1e-16, &format!("xi^{a} eta^{b}"));
        }
    }
    // Not degree 3: int xi^3 = 1/20.
    assert!((q(3, 0) - 1.0 / 20.0).abs() > 1e-4);
}

/// Two triangles: every map of the pair is affine, so the three-point rule on each clip
/// triangle integrates `M`, `N`, the gaps and the primal integrals exactly. Against the
/// seven-point rule on the slave facet itself (the master covers it, tilted, with nodal normals
/// that differ from node to node).
#[test]
fn a_pair_of_triangles_is_integrated_exactly_with_three_points() {
    let slave = Facet3::Tri3([tilt([0.0, 0.0, 0.0]), tilt([1.0, 0.1, 0.0]), tilt([0.3, 0.9, 0.0])]);
    let m = [[-0.6, -0.5, 0.05], [0.4, 1.9, 0.25], [1.8, -0.4, -0.1]];
    let master = Facet3::Tri3([tilt(m[0]), tilt(m[1]), tilt(m[2])]);
    let n0 = scale3(1.0 / slave.jacobian([0.0; 2]), slave.normal([0.0; 2]));
    let nrm: Vec<Vec3> = [[0.1, 0.0, 0.0], [0.0, -0.15, 0.05], [-0.05, 0.1, 0.0]]
        .iter()
        .map(|&d| {
            let n = add3(n0, sub3(tilt(d), tilt([0.0; 3])));
            scale3(1.0 / norm3(n), n)
        })
        .collect();
    let ds = dual_basis_3d(&slave).unwrap();
    let p = mortar_pair_3d(&slave, &nrm, &ds, &master).unwrap().expect("overlap");
    let plane = AuxPlane::of_slave(&slave).unwrap();
    let area = polygon_area(&slave.nodes().iter().map(|&x| plane.coords(x)).collect::<Vec<_>>());
    let mut want = PairIntegrals::zero(3, 3);
    for (l, w) in triangle_rule_deg5().iter() {
        let xs = [l[1], l[2]];
        let q = plane.coords(slave.position(xs));
        let xm = invert_on_plane(&master, &plane, q).unwrap();
        let gap = sub3(master.position(xm), slave.position(xs));
        let mut gn = [0.0; 4];
        for (g, n) in gn.iter_mut().zip(&nrm) {
            *g = dot3(*n, gap);
        }
        let phi = slave.shape(xs);
        want.add_point(w * area, &ds.psi(&phi), &master.shape(xm), &gn);
        want.add_primal(w * area, &phi, &master.shape(xm), &gn);
    }
    let close = |a: &[f64], b: &[f64], what: &str| {
        for (x, y) in a.iter().zip(b) {
            assert_close(*x, *y, 1e-14, what);
        }
    };
    for j in 0..3 {
        close(&p.m[j], &want.m[j], "M");
        close(&p.phi_m[j], &want.phi_m[j], "primal M");
        close(&p.phi_gap[j], &want.phi_gap[j], "primal gap");
        close(&p.phi_phi[j], &want.phi_phi[j], "primal D");
    }
    close(&p.psi_integral, &want.psi_integral, "N");
    close(&p.weighted_gap, &want.weighted_gap, "gaps");
    close(&p.phi_integral, &want.phi_integral, "primal N");
    assert_close(p.overlap_measure, area, 1e-14, "overlap");
    assert!(p.weighted_gap.iter().take(3).any(|g| g.abs() > 1e-2), "a gap that varies");
}

// ---------------- shape functions and facets ----------------

#[test]
fn shape_functions_partition_unity_and_derivatives_match_differences() {
    let pts = [[0.2, 0.3], [-0.7, 0.4], [0.0, 0.0]];
    let e = 1e-6;
    for &xi in &pts {
        assert_close(shape_quad4(xi).iter().sum(), 1.0, 1e-15, "quad4 sum");
        assert_close(shape_tri3(xi).iter().sum(), 1.0, 1e-15, "tri3 sum");
        let d = dshape_quad4(xi);
        for k in 0..4 {
            let fd0 = (shape_quad4([xi[0] + e, xi[1]])[k] - shape_quad4([xi[0] - e, xi[1]])[k])
                / (2.0 * e);
            let fd1 = (shape_quad4([xi[0], xi[1] + e])[k] - shape_quad4([xi[0], xi[1] - e])[k])
                / (2.0 * e);
            assert_close(d[k][0], fd0, 1e-9, "quad4 d/dxi");
            assert_close(d[k][1], fd1, 1e-9, "quad4 d/deta");
        }
    }
    for (k, c) in QUAD4_CORNERS.iter().enumerate() {
        assert_close(shape_quad4(*c)[k], 1.0, 0.0, "quad4 nodal");
    }
    assert_close(shape_line2(-1.0)[0], 1.0, 0.0, "line2 nodal");
    // Normal convention: a line from a to b has the body on its left, normal (t_y, -t_x).
    let f = Facet2 { x: [[0.0, 0.0], [2.0, 0.0]] };
    assert_eq!(f.normal(), [0.0, -1.0]);
    assert_close(f.jacobian(), 1.0, 0.0, "line J = L/2");
    let t = Facet3::Tri3([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    assert_eq!(t.normal([0.3, 0.3]), [0.0, 0.0, 2.0]);
    assert_close(t.jacobian([0.1, 0.1]), 2.0, 0.0, "tri J = 2 area");
}

// ---------------- dual basis ----------------

/// Derivation of the closed forms (affine facets, J constant):
/// line2: `M = (L/6)[[2,1],[1,2]]`, `D = (L/2) I`, `M^{-1} = (2/L)[[2,-1],[-1,2]]`, so
/// `A = [[2,-1],[-1,2]]`: `psi_1 = 2 phi_1 - phi_2`.
/// tri3: `M = (|T|/12)[[2,1,1],[1,2,1],[1,1,2]]`, `D = (|T|/3) I`,
/// `[[2,1,1],[1,2,1],[1,1,2]]^{-1} = (1/4)[[3,-1,-1],[-1,3,-1],[-1,-1,3]]`, so
/// `A = [[3,-1,-1],[-1,3,-1],[-1,-1,3]]`: `psi_i = 3 phi_i - phi_j - phi_k = 4 phi_i - 1`
/// (using `phi_j + phi_k = 1 - phi_i`). Check: `int psi_1 phi_1 = 4|T|/6 - |T|/3 = |T|/3`,
/// `int psi_1 phi_2 = 4|T|/12 - |T|/3 = 0`. ("3 phi_i - 1" would give `int psi_1 phi_2 =
/// |T|/4 - |T|/3 != 0`.)
/// parallelogram quad4: `M` and `D` are tensor products of the line2 ones, so `A` is the
/// Kronecker product of `[[2,-1],[-1,2]]`: 4 on the diagonal, -2 for edge neighbours, 1 for
/// the opposite node.
#[test]
fn dual_closed_forms_on_affine_facets() {
    let line = Facet2 { x: [[0.3, -0.1], [1.4, 0.8]] };
    let d = dual_basis_2d(&line).unwrap();
    let l = 2.0 * line.jacobian();
    for i in 0..2 {
        assert_close(d.d[i], 0.5 * l, 1e-15, "line d");
        for k in 0..2 {
            assert_close(d.a[i][k], if i == k { 2.0 } else { -1.0 }, 1e-13, "line A");
        }
    }
    let tri = Facet3::Tri3([[0.1, 0.2, 0.3], [1.2, 0.1, -0.2], [0.4, 0.9, 0.5]]);
    let d = dual_basis_3d(&tri).unwrap();
    let area = 0.5 * tri.jacobian([0.0, 0.0]);
    for i in 0..3 {
        assert_close(d.d[i], area / 3.0, 1e-15, "tri d");
        for k in 0..3 {
            assert_close(d.a[i][k], if i == k { 3.0 } else { -1.0 }, 1e-13, "tri A");
        }
    }
    for xi in [[0.2, 0.1], [0.6, 0.3], [0.0, 1.0]] {
        let phi = tri.shape(xi);
        let psi = d.psi(&phi);
        for i in 0..3 {
            assert_close(psi[i], 4.0 * phi[i] - 1.0, 1e-13, "tri psi = 4 phi - 1");
        }
    }
    // A parallelogram: x = x0 + a (1+xi)/2 + b (1+eta)/2.
    let (x0, a, b) = ([0.2, -0.1, 0.4], [1.0, 0.3, 0.2], [0.4, 0.8, -0.3]);
    let corner = |s: f64, t: f64| add3(x0, add3(scale3(s, a), scale3(t, b)));
    let quad =
        Facet3::Quad4([corner(0.0, 0.0), corner(1.0, 0.0), corner(1.0, 1.0), corner(0.0, 1.0)]);
    let d = dual_basis_3d(&quad).unwrap();
    for i in 0..4 {
        for k in 0..4 {
            let expected = match (i + 4 - k) % 4 {
                0 => 4.0,
                2 => 1.0,
                _ => -2.0,
            };
            assert_close(d.a[i][k], expected, 1e-12, "parallelogram A");
        }
    }
}

/// Independent fine rules: 8x8 Gauss on quads, collapsed (Duffy) 8x8 Gauss on triangles
/// (`xi = u`, `eta = v (1 - u)`, `dxi deta = (1 - u) du dv`).
fn fine_rule(f: &Facet3) -> Vec<(Vec2, f64)> {
    let g = gauss_legendre(8);
    let mut out = Vec::new();
    for &(a, wa) in &g {
        for &(b, wb) in &g {
            match f {
                Facet3::Quad4(_) => out.push(([a, b], wa * wb)),
                Facet3::Tri3(_) => {
                    let (u, v) = (0.5 * (a + 1.0), 0.5 * (b + 1.0));
                    out.push(([u, v * (1.0 - u)], 0.25 * wa * wb * (1.0 - u)));
                }
            }
        }
    }
    out
}

/// `(int psi_i phi_j J, int phi_j J)` with the rule given.
fn biorthogonality_integrals(
    f: &Facet3,
    dual: &DualBasis,
    rule: &[(Vec2, f64)],
) -> ([[f64; 4]; 4], [f64; 4]) {
    let mut ip = [[0.0; 4]; 4];
    let mut ph = [0.0; 4];
    for &(xi, w) in rule {
        let wj = w * f.jacobian(xi);
        let phi = f.shape(xi);
        let psi = dual.psi(&phi);
        for i in 0..4 {
            ph[i] += wj * phi[i];
            for k in 0..4 {
                ip[i][k] += wj * psi[i] * phi[k];
            }
        }
    }
    (ip, ph)
}

fn assert_biorthogonal(ip: &[[f64; 4]; 4], ph: &[f64; 4], n: usize, tol: f64, what: &str) {
    for i in 0..n {
        for k in 0..n {
            let expected = if i == k { ph[k] } else { 0.0 };
            assert_close(ip[i][k], expected, tol, &format!("{} int psi_{} phi_{}", what, i, k));
        }
    }
}

#[test]
fn biorthogonality_line_tri_affine_and_distorted_quad() {
    // line2: independent 8-point Gauss.
    let line = Facet2 { x: [[0.3, -0.1], [1.4, 0.8]] };
    let d = dual_basis_2d(&line).unwrap();
    let mut ip = [[0.0; 4]; 4];
    let mut ph = [0.0; 4];
    for (x, w) in gauss_legendre(8) {
        let p = shape_line2(x);
        let phi = [p[0], p[1], 0.0, 0.0];
        let psi = d.psi(&phi);
        for i in 0..2 {
            ph[i] += w * line.jacobian() * phi[i];
            for k in 0..2 {
                ip[i][k] += w * line.jacobian() * psi[i] * phi[k];
            }
        }
    }
    assert_biorthogonal(&ip, &ph, 2, 1e-13, "line2");
    // tri3, an affine (parallelogram) quad4 and a distorted planar quad4 in a tilted plane:
    // on planar facets J is affine in (xi, eta), so the fine rules are exact.
    let tri = Facet3::Tri3([tilt([0.0, 0.0, 0.0]), tilt([1.3, 0.2, 0.0]), tilt([0.4, 0.9, 0.0])]);
    let para = Facet3::Quad4([
        tilt([0.0, 0.0, 0.0]),
        tilt([1.0, 0.2, 0.0]),
        tilt([1.5, 1.1, 0.0]),
        tilt([0.5, 0.9, 0.0]),
    ]);
    let dist = Facet3::Quad4([
        tilt([0.0, 0.0, 0.0]),
        tilt([1.2, -0.1, 0.0]),
        tilt([0.9, 0.8, 0.0]),
        tilt([-0.2, 1.3, 0.0]),
    ]);
    for (f, name) in [(tri, "tri3"), (para, "parallelogram"), (dist, "distorted quad")] {
        let d = dual_basis_3d(&f).unwrap();
        let (ip, ph) = biorthogonality_integrals(&f, &d, &fine_rule(&f));
        assert_biorthogonal(&ip, &ph, f.n_nodes(), 1e-13, name);
        for k in 0..f.n_nodes() {
            assert_close(d.d[k], ph[k], 1e-14, "D_e = int phi");
        }
    }
}

#[test]
fn biorthogonality_warped_quad_discrete_and_close_to_exact() {
    // Non-planar quad: J is not polynomial, so biorthogonality is exact for the rule that
    // built A_e (3x3 Gauss) and approximate against a finer one.
    let warped =
        Facet3::Quad4([[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [1.1, 0.9, -0.05], [-0.1, 1.0, 0.15]]);
    let d = dual_basis_3d(&warped).unwrap();
    let (ip, ph) = biorthogonality_integrals(&warped, &d, &warped.quadrature());
    assert_biorthogonal(&ip, &ph, 4, 1e-14, "warped (same rule)");
    let (ip, ph) = biorthogonality_integrals(&warped, &d, &fine_rule(&warped));
    assert_biorthogonal(&ip, &ph, 4, 2e-6, "warped (fine rule)");
}

#[test]
fn degenerate_input_gives_errors_not_panics() {
    assert!(dual_basis_2d(&Facet2 { x: [[1.0, 1.0], [1.0, 1.0]] }).is_err());
    assert!(dual_basis_3d(&Facet3::Tri3([[0.0; 3], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]])).is_err());
    assert!(dual_basis_3d(&Facet3::Quad4([[0.0; 3]; 4])).is_err());
    assert!(
        dual_basis_3d(&Facet3::Tri3([[f64::NAN; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])).is_err()
    );
    assert!(Facet3::from_nodes(&[[0.0; 3]; 3], &[0, 1, 5]).is_err());
    assert!(Facet3::from_nodes(&[[0.0; 3]; 5], &[0, 1, 2, 3, 4]).is_err());
    assert!(nodal_normals_2d(&[[0.0, 0.0], [1.0, 0.0]], &[[0, 2]], false).is_err());
    assert!(nodal_normals_2d(&[[0.0, 0.0], [0.0, 0.0]], &[[0, 1]], false).is_err());
    // Knife edge: the two facets' normals cancel at node 1.
    assert!(nodal_normals_2d(&[[0.0, 0.0], [1.0, 0.0]], &[[0, 1], [1, 0]], false).is_err());
    let s = Facet2 { x: [[1.0, 0.0], [0.0, 0.0]] };
    let ds = dual_basis_2d(&s).unwrap();
    let nrm = [[0.0, 1.0]; 2];
    assert!(mortar_pair_2d(&s, &nrm, &ds, &Facet2 { x: [[0.5, 0.1], [0.5, 0.1]] }).is_err());
    let t = Facet3::Tri3([[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let dt = dual_basis_3d(&t).unwrap();
    assert!(mortar_pair_3d(&t, &[[0.0, 0.0, 1.0]; 2], &dt, &t).is_err(), "wrong normal count");
    assert!(mortar_pair_3d(&t, &[[0.0, 0.0, 1.0]; 3], &ds, &t).is_err(), "wrong dual basis");
    // A bow-tie (self-intersecting) slave quad is not convex on its plane.
    let bow = Facet3::Quad4([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]);
    if let Ok(db) = dual_basis_3d(&bow) {
        assert!(mortar_pair_3d(&bow, &[[0.0, 0.0, 1.0]; 4], &db, &t).is_err());
    }
}

// ---------------- nodal normals ----------------

#[test]
fn averaged_normals_2d_square_and_reverse() {
    // Counter-clockwise unit square: body on the left of each edge, normals outward.
    let x = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let f = [[0, 1], [1, 2], [2, 3], [3, 0]];
    let n = nodal_normals_2d(&x, &f, false).unwrap();
    let r = 0.5f64.sqrt();
    let expected = [[-r, -r], [r, -r], [r, r], [-r, r]];
    for k in 0..4 {
        for c in 0..2 {
            assert_close(n[k][c], expected[k][c], 1e-15, "square corner normal");
        }
    }
    let nr = nodal_normals_2d(&x, &f, true).unwrap();
    assert_close(nr[2][0], -r, 1e-15, "reversed");
    // A node on no facet gets zero.
    let n = nodal_normals_2d(&[[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]], &[[0, 1]], false).unwrap();
    assert_eq!(n[2], [0.0, 0.0]);
    assert_eq!(n[0], [0.0, -1.0]);
}

#[test]
fn averaged_normals_3d_cube_corner_and_planar_patch() {
    // Three faces of the unit cube at the origin, ordered so x_xi x x_eta points outward.
    let x = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 1.0],
        [1.0, 0.0, 1.0],
    ];
    let faces = vec![vec![0, 2, 4, 1], vec![0, 3, 5, 2], vec![0, 1, 6, 3]];
    let n = nodal_normals_3d(&x, &faces, false).unwrap();
    let r = 1.0 / 3f64.sqrt();
    for c in 0..3 {
        assert_close(n[0][c], -r, 1e-15, "cube corner normal");
    }
    assert_close(n[4][2], -1.0, 1e-15, "bottom face only");
    // A tilted, distorted planar patch of triangles: every nodal normal is the plane normal.
    let m = map_mesh(grid(0.0, 1.5, 0.0, 1.0, 3, 2, 0.0, true, true), |p| tilt(perturb(p)));
    let n = nodal_normals_3d(&m.x, &m.f, false).unwrap();
    let nz = sub3(tilt([0.0, 0.0, 1.0]), tilt([0.0; 3]));
    for v in &n {
        for c in 0..3 {
            assert_close(v[c], nz[c], 1e-14, "planar patch normal");
        }
    }
}

// ---------------- meshes for the assembly tests ----------------

struct Mesh3 {
    x: Vec<Vec3>,
    f: Vec<Vec<usize>>,
}

/// `nx x ny` grid on `[x0,x1] x [y0,y1]` at height z; quads, or 2 triangles per quad;
/// counter-clockwise seen from +z when `up` (outward normal +z), clockwise otherwise.
#[allow(clippy::too_many_arguments)]
fn grid(
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    nx: usize,
    ny: usize,
    z: f64,
    tri: bool,
    up: bool,
) -> Mesh3 {
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut x = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            x.push([
                x0 + (x1 - x0) * i as f64 / nx as f64,
                y0 + (y1 - y0) * j as f64 / ny as f64,
                z,
            ]);
        }
    }
    let mut f = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            let mut cells =
                if tri { vec![vec![a, b, c], vec![a, c, d]] } else { vec![vec![a, b, c, d]] };
            if !up {
                cells.iter_mut().for_each(|c| c.reverse());
            }
            f.extend(cells);
        }
    }
    Mesh3 { x, f }
}

fn map_mesh(m: Mesh3, g: impl Fn(Vec3) -> Vec3) -> Mesh3 {
    Mesh3 { x: m.x.into_iter().map(g).collect(), f: m.f }
}

/// In-plane perturbation vanishing on x = 0, 1.5 and y = 0, 1 (keeps a patch planar and its
/// outline, makes its interior elements non-affine).
fn perturb(p: Vec3) -> Vec3 {
    let bump = (p[0] * std::f64::consts::PI / 1.5).sin() * (p[1] * std::f64::consts::PI).sin();
    [p[0] + 0.12 * bump, p[1] - 0.08 * bump, p[2]]
}

fn rotate_about_z(c: Vec2, angle: f64) -> impl Fn(Vec3) -> Vec3 {
    move |p| {
        let (s, co) = angle.sin_cos();
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        [c[0] + co * dx - s * dy, c[1] + s * dx + co * dy, p[2]]
    }
}

struct Assembled {
    d: Vec<f64>,
    m: Vec<Vec<f64>>,
    n: Vec<f64>,
    g: Vec<f64>,
}

/// Loops over the candidate pairs of the bucket search and sums the pair integrals into
/// global slave x master arrays; D is summed per slave facet.
fn assemble_3d(slave: &Mesh3, master: &Mesh3, inflate: f64) -> Assembled {
    let normals = nodal_normals_3d(&slave.x, &slave.f, false).unwrap();
    let sf: Vec<Facet3> =
        slave.f.iter().map(|f| Facet3::from_nodes(&slave.x, f).unwrap()).collect();
    let mf: Vec<Facet3> =
        master.f.iter().map(|f| Facet3::from_nodes(&master.x, f).unwrap()).collect();
    let sb: Vec<Aabb> = sf.iter().map(|f| facet_aabb_3d(f, inflate)).collect();
    let mb: Vec<Aabb> = mf.iter().map(|f| facet_aabb_3d(f, inflate)).collect();
    let duals: Vec<DualBasis> = sf.iter().map(|f| dual_basis_3d(f).unwrap()).collect();
    let (ns, nm) = (slave.x.len(), master.x.len());
    let mut out = Assembled {
        d: vec![0.0; ns],
        m: vec![vec![0.0; nm]; ns],
        n: vec![0.0; ns],
        g: vec![0.0; ns],
    };
    for (e, f) in slave.f.iter().enumerate() {
        for (a, &k) in f.iter().enumerate() {
            out.d[k] += duals[e].d[a];
        }
    }
    for (s, m) in candidate_pairs(&sb, &mb) {
        let nrm: Vec<Vec3> = slave.f[s].iter().map(|&k| normals[k]).collect();
        if let Some(p) = mortar_pair_3d(&sf[s], &nrm, &duals[s], &mf[m]).unwrap() {
            for (j, &gj) in slave.f[s].iter().enumerate() {
                out.n[gj] += p.psi_integral[j];
                out.g[gj] += p.weighted_gap[j];
                for (l, &gl) in master.f[m].iter().enumerate() {
                    out.m[gj][gl] += p.m[j][l];
                }
            }
        }
    }
    out
}

struct Mesh2 {
    x: Vec<Vec2>,
    f: Vec<[usize; 2]>,
}

/// Line through the given abscissae at height y; `body_below`: facets run right to left
/// (body on the left = below, outward normal +y), else left to right (normal -y).
fn line_mesh(xs: &[f64], y: f64, body_below: bool) -> Mesh2 {
    let x = xs.iter().map(|&a| [a, y]).collect();
    let f = (0..xs.len() - 1).map(|i| if body_below { [i + 1, i] } else { [i, i + 1] }).collect();
    Mesh2 { x, f }
}

fn assemble_2d(slave: &Mesh2, master: &Mesh2, inflate: f64) -> Assembled {
    let normals = nodal_normals_2d(&slave.x, &slave.f, false).unwrap();
    let sf: Vec<Facet2> =
        slave.f.iter().map(|f| Facet2::from_nodes(&slave.x, *f).unwrap()).collect();
    let mf: Vec<Facet2> =
        master.f.iter().map(|f| Facet2::from_nodes(&master.x, *f).unwrap()).collect();
    let sb: Vec<Aabb> = sf.iter().map(|f| facet_aabb_2d(f, inflate)).collect();
    let mb: Vec<Aabb> = mf.iter().map(|f| facet_aabb_2d(f, inflate)).collect();
    let (ns, nm) = (slave.x.len(), master.x.len());
    let mut out = Assembled {
        d: vec![0.0; ns],
        m: vec![vec![0.0; nm]; ns],
        n: vec![0.0; ns],
        g: vec![0.0; ns],
    };
    let duals: Vec<DualBasis> = sf.iter().map(|f| dual_basis_2d(f).unwrap()).collect();
    for (e, f) in slave.f.iter().enumerate() {
        for (a, &k) in f.iter().enumerate() {
            out.d[k] += duals[e].d[a];
        }
    }
    for (s, m) in candidate_pairs(&sb, &mb) {
        let nrm = [normals[slave.f[s][0]], normals[slave.f[s][1]]];
        if let Some(p) = mortar_pair_2d(&sf[s], &nrm, &duals[s], &mf[m]).unwrap() {
            for (j, &gj) in slave.f[s].iter().enumerate() {
                out.n[gj] += p.psi_integral[j];
                out.g[gj] += p.weighted_gap[j];
                for (l, &gl) in master.f[m].iter().enumerate() {
                    out.m[gj][gl] += p.m[j][l];
                }
            }
        }
    }
    out
}

// ---------------- sum of D ----------------

#[test]
fn sum_of_d_is_length_or_area() {
    // A straight line of length 2 in direction (0.6, 0.8), split unevenly.
    let xs = [0.0, 0.3, 0.55, 1.0];
    let m = Mesh2 {
        x: xs.iter().map(|s| [1.2 * s - 0.4, 1.6 * s + 0.1]).collect(),
        f: vec![[0, 1], [1, 2], [2, 3]],
    };
    let total: f64 =
        m.f.iter()
            .map(|f| dual_basis_2d(&Facet2::from_nodes(&m.x, *f).unwrap()).unwrap().d)
            .map(|d| d[0] + d[1])
            .sum();
    assert_close(total, 2.0, 1e-14, "sum D over a line");
    // Planar tilted patches of distorted quads and of triangles, area 1.5.
    for tri in [false, true] {
        let m = map_mesh(grid(0.0, 1.5, 0.0, 1.0, 3, 2, 0.0, tri, true), |p| tilt(perturb(p)));
        let total: f64 = m
            .f
            .iter()
            .map(|f| {
                dual_basis_3d(&Facet3::from_nodes(&m.x, f).unwrap()).unwrap().d.iter().sum::<f64>()
            })
            .sum();
        assert_close(total, 1.5, 1e-14, if tri { "sum D triangles" } else { "sum D quads" });
    }
}

// ---------------- 2D assembled checks ----------------

/// Full overlap checks shared by the 2D and 3D configurations:
/// partition of unity `sum_l M_jl = N_j = D_jj`; weighted gap `g_j = d D_jj` (flat bodies at
/// distance d); mortar projection of a linear field `sum_l M_jl f_l = D_jj f(x_j)`.
fn check_full_overlap(a: &Assembled, d: f64, f_slave: &[f64], f_master: &[f64], what: &str) {
    for j in 0..a.d.len() {
        let row: f64 = a.m[j].iter().sum();
        assert_close(row, a.d[j], 1e-13, &format!("{}: sum_l M_{}l = D_jj", what, j));
        assert_close(a.n[j], a.d[j], 1e-13, &format!("{}: N_{} = D_jj", what, j));
        assert_close(a.g[j], d * a.d[j], 1e-14, &format!("{}: g_{} = d D_jj", what, j));
        let mf: f64 = a.m[j].iter().zip(f_master).map(|(m, f)| m * f).sum();
        assert_close(
            mf / a.d[j],
            f_slave[j],
            1e-12,
            &format!("{}: (D^-1 M f)_{} = f(x_j)", what, j),
        );
    }
}

#[test]
fn mortar_2d_non_matching_straight_lines_full_overlap() {
    let d = 0.01;
    let lin = |p: Vec2| 1.0 + 2.5 * p[0] - 0.7 * p[1] * 0.0; // depends on the abscissa only
    for tilted in [false, true] {
        let mut slave = line_mesh(&[0.0, 0.3, 0.55, 1.0], 0.0, true);
        let mut master = line_mesh(&[0.0, 0.2, 0.7, 1.0], d, false);
        let fs: Vec<f64> = slave.x.iter().map(|&p| lin(p)).collect();
        let fm: Vec<f64> = master.x.iter().map(|&p| lin(p)).collect();
        if tilted {
            slave.x.iter_mut().for_each(|p| *p = tilt2(*p));
            master.x.iter_mut().for_each(|p| *p = tilt2(*p));
        }
        let a = assemble_2d(&slave, &master, 0.05);
        assert_close(a.d.iter().sum(), 1.0, 1e-14, "sum D = length");
        check_full_overlap(&a, d, &fs, &fm, if tilted { "2D tilted" } else { "2D" });
    }
}

#[test]
fn mortar_2d_curved_slave_partition_of_unity() {
    // Slave: arc of radius 2 (centre (0,-2)), angles 60..120 deg, nodes counter-clockwise
    // (body inside, on the left), uneven spacing. Master: the line y = 0.05 over [-3, 3]
    // facing down. The normal field varies along each slave facet, so the projection is
    // non-linear; still sum_l M_jl = int psi_j = D_jj because the master phi_l sum to one.
    let angles = [60.0f64, 71.0, 79.0, 90.0, 97.0, 108.0, 120.0];
    let slave = Mesh2 {
        x: angles
            .iter()
            .map(|a| [2.0 * a.to_radians().cos(), -2.0 + 2.0 * a.to_radians().sin()])
            .collect(),
        f: (0..angles.len() - 1).map(|i| [i, i + 1]).collect(),
    };
    let master = line_mesh(&[-3.0, -1.1, -0.35, 0.05, 0.6, 1.3, 3.0], 0.05, false);
    let a = assemble_2d(&slave, &master, 0.3);
    for j in 0..slave.x.len() {
        assert_close(a.m[j].iter().sum(), a.d[j], 1e-13, "curved: sum_l M_jl = D_jj");
        assert!(a.g[j] > 0.0, "curved: bodies apart, positive weighted gap");
    }
    // Top node (90 deg): normal (0,1), gap 0.05 there; g/D is a psi-weighted average of a gap
    // that grows away from the top, so it is at least near 0.05.
    assert!(a.g[3] / a.d[3] > 0.049 && a.g[3] / a.d[3] < 0.06, "top gap {}", a.g[3] / a.d[3]);
}

#[test]
fn projections_2d_solve_their_defining_equations() {
    let s = Facet2 { x: [[1.0, 0.0], [0.0, 0.0]] };
    let nrm = [[0.0, 1.0], [0.0, 1.0]];
    // x(xi) = 0.5 - 0.5 xi = 0.3 -> xi = 0.4.
    assert_close(
        project_onto_slave_2d(&s, &nrm, [0.3, 0.5]).unwrap(),
        0.4,
        1e-15,
        "parallel normals",
    );
    // Varying normals: x(xi) + alpha n(xi) = y must hold at the returned xi.
    let nrm = [[0.3f64, 1.0], [-0.2, 1.0]];
    let y = [0.35, 0.4];
    let xi = project_onto_slave_2d(&s, &nrm, y).unwrap();
    let p = shape_line2(xi);
    let n = add2(scale2(p[0], nrm[0]), scale2(p[1], nrm[1]));
    assert_close(cross2(sub2(s.position(xi), y), n), 0.0, 1e-15, "residual");
    assert!(xi.abs() <= 1.0);
    let m = Facet2 { x: [[-1.0, 0.2], [2.0, 0.5]] };
    let eta = project_onto_master_2d(&m, [0.4, 0.0], [0.1, 1.0]).unwrap();
    assert_close(
        cross2(sub2(m.position(eta), [0.4, 0.0]), [0.1, 1.0]),
        0.0,
        1e-15,
        "master residual",
    );
    assert!(project_onto_master_2d(&m, [0.4, 0.0], [3.0, 0.3]).is_none(), "parallel ray");
}

#[test]
fn mortar_2d_partial_overlap_matches_direct_quadrature_and_no_overlap_is_none() {
    let d = 0.02;
    // Slave from (1,0) to (0,0) (normal +y): x = 0.5 - 0.5 xi. Master (0.4,d) -> (1.6,d).
    let s = Facet2 { x: [[1.0, 0.0], [0.0, 0.0]] };
    let nrm = [[0.0, 1.0]; 2];
    let ds = dual_basis_2d(&s).unwrap();
    let m = Facet2 { x: [[0.4, d], [1.6, d]] };
    let p = mortar_pair_2d(&s, &nrm, &ds, &m).unwrap().expect("overlap [0.4, 1]");
    // Independent: Gauss on x in [0.4, 1] with the closed-form duals psi_1 = 2 phi_1 - phi_2,
    // slave phi from xi = 1 - 2x, master phi from eta = (x - 1)/0.6, ds = dx.
    let mut mm = [[0.0; 2]; 2];
    for (t, w) in gauss_legendre(4) {
        let x = 0.7 + 0.3 * t;
        let wx = 0.3 * w;
        let ps = shape_line2(1.0 - 2.0 * x);
        let psi = [2.0 * ps[0] - ps[1], 2.0 * ps[1] - ps[0]];
        let pm = shape_line2((x - 1.0) / 0.6);
        for j in 0..2 {
            for l in 0..2 {
                mm[j][l] += wx * psi[j] * pm[l];
            }
        }
    }
    for j in 0..2 {
        for l in 0..2 {
            assert_close(p.m[j][l], mm[j][l], 1e-15, "2D partial M_jl");
        }
        assert_close(p.psi_integral[j], mm[j][0] + mm[j][1], 1e-15, "2D partial N_j");
        assert_close(p.weighted_gap[j], d * p.psi_integral[j], 1e-16, "2D partial gap");
    }
    assert_close(p.overlap_measure, 0.6, 1e-15, "overlap length");
    // No overlap: master beside the slave.
    assert!(mortar_pair_2d(&s, &nrm, &ds, &Facet2 { x: [[1.5, d], [2.5, d]] }).unwrap().is_none());
    // Back-facing master (normal +y, same as the slave): no contribution.
    assert!(mortar_pair_2d(&s, &nrm, &ds, &Facet2 { x: [[1.6, d], [0.4, d]] }).unwrap().is_none());
}

// ---------------- 3D assembled checks ----------------

#[test]
fn mortar_3d_non_matching_full_overlap() {
    let d = 0.01;
    let lin = |p: Vec3| 1.0 + 2.0 * p[0] - 3.0 * p[1]; // in-plane linear field
    type Case = (&'static str, Mesh3, Mesh3);
    let cases: Vec<Case> = vec![
        (
            "quad2x2 vs quad3x3",
            grid(0.0, 1.0, 0.0, 1.0, 2, 2, 0.0, false, true),
            grid(0.0, 1.0, 0.0, 1.0, 3, 3, d, false, false),
        ),
        (
            "quad2x2 vs tri3x3",
            grid(0.0, 1.0, 0.0, 1.0, 2, 2, 0.0, false, true),
            grid(0.0, 1.0, 0.0, 1.0, 3, 3, d, true, false),
        ),
        (
            "tri3x3 vs tri2x2",
            grid(0.0, 1.0, 0.0, 1.0, 3, 3, 0.0, true, true),
            grid(0.0, 1.0, 0.0, 1.0, 2, 2, d, true, false),
        ),
        (
            "tri3x3 vs tri4x4 rotated",
            grid(0.0, 1.0, 0.0, 1.0, 3, 3, 0.0, true, true),
            map_mesh(
                grid(-0.5, 1.5, -0.5, 1.5, 4, 4, d, true, false),
                rotate_about_z([0.5, 0.5], 0.35),
            ),
        ),
        (
            "quad2x2 vs quad5x5 rotated",
            grid(0.0, 1.0, 0.0, 1.0, 2, 2, 0.0, false, true),
            map_mesh(
                grid(-0.5, 1.5, -0.5, 1.5, 5, 5, d, false, false),
                rotate_about_z([0.5, 0.5], 0.6),
            ),
        ),
        (
            "tri2x2 vs quad3x3 rotated",
            grid(0.0, 1.0, 0.0, 1.0, 2, 2, 0.0, true, true),
            map_mesh(
                grid(-0.5, 1.5, -0.5, 1.5, 3, 3, d, false, false),
                rotate_about_z([0.4, 0.5], -0.25),
            ),
        ),
    ];
    for (name, slave, master) in cases {
        let fs: Vec<f64> = slave.x.iter().map(|&p| lin(p)).collect();
        let fm: Vec<f64> = master.x.iter().map(|&p| lin(p)).collect();
        let a = assemble_3d(&slave, &master, 0.05);
        assert_close(a.d.iter().sum(), 1.0, 1e-14, &format!("{}: sum D = area", name));
        check_full_overlap(&a, d, &fs, &fm, name);
        // The same in a general position (rigid motion of both meshes).
        let (slave, master) = (map_mesh(slave, tilt), map_mesh(master, tilt));
        let a = assemble_3d(&slave, &master, 0.05);
        assert_close(a.d.iter().sum(), 1.0, 1e-14, &format!("{} tilted: sum D = area", name));
        check_full_overlap(&a, d, &fs, &fm, &format!("{} tilted", name));
    }
}

#[test]
fn mortar_3d_partial_overlap_matches_direct_quadrature() {
    let d = 0.03;
    // Slave: unit square quad, normal +z. Master: [0.3,1.7] x [-0.2,0.6] at z = d, facing
    // down (clockwise from above). Overlap: [0.3,1] x [0,0.6].
    let slave = Facet3::Quad4([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
    let mx = [[0.3, -0.2, d], [0.3, 0.6, d], [1.7, 0.6, d], [1.7, -0.2, d]];
    let master = Facet3::Quad4(mx);
    let ds = dual_basis_3d(&slave).unwrap();
    let p = mortar_pair_3d(&slave, &[[0.0, 0.0, 1.0]; 4], &ds, &master).unwrap().expect("overlap");
    // Independent: 4x4 Gauss on the overlap rectangle with 1D hat functions. Slave dual:
    // psi = (2 h_x - h_x')(2 h_y - h_y') (tensor product of the line2 duals); master phi_l
    // = bilinear hats of its rectangle, built from its node coordinates.
    let hat = |v: f64, node: f64, lo: f64, hi: f64| {
        let other = if node == lo { hi } else { lo };
        (v - other) / (node - other)
    };
    let snodes = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let g = gauss_legendre(4);
    let mut mm = [[0.0; 4]; 4];
    for &(a, wa) in &g {
        for &(b, wb) in &g {
            let (x, y) = (0.65 + 0.35 * a, 0.3 + 0.3 * b);
            let w = wa * wb * 0.35 * 0.3;
            for j in 0..4 {
                let (hx, hy) = (hat(x, snodes[j][0], 0.0, 1.0), hat(y, snodes[j][1], 0.0, 1.0));
                let psi = (2.0 * hx - (1.0 - hx)) * (2.0 * hy - (1.0 - hy));
                for l in 0..4 {
                    let phi = hat(x, mx[l][0], 0.3, 1.7) * hat(y, mx[l][1], -0.2, 0.6);
                    mm[j][l] += w * psi * phi;
                }
            }
        }
    }
    for j in 0..4 {
        for l in 0..4 {
            assert_close(p.m[j][l], mm[j][l], 1e-15, &format!("3D partial M_{}{}", j, l));
        }
        assert_close(p.psi_integral[j], mm[j].iter().sum(), 1e-15, "3D partial N_j");
        assert_close(p.weighted_gap[j], d * p.psi_integral[j], 1e-16, "3D partial gap");
    }
    assert_close(p.overlap_measure, 0.7 * 0.6, 1e-15, "overlap area");
}

#[test]
fn mortar_3d_overlap_is_additive_over_a_split_master() {
    // Tilted triangle slave against a rotated rectangular master that partly overlaps it, and
    // against the master's two halves: N_j, g_j and the overlap area add up (the master
    // geometry is the same affine map, only its interpolation differs).
    let slave = Facet3::Tri3([tilt([0.0, 0.0, 0.0]), tilt([1.0, 0.1, 0.0]), tilt([0.3, 0.9, 0.0])]);
    let r = rotate_about_z([0.5, 0.4], 0.5);
    let c: Vec<Vec3> = [[0.35, -0.3, 0.02], [0.35, 0.7, 0.02], [1.4, 0.7, 0.02], [1.4, -0.3, 0.02]]
        .iter()
        .map(|&p| tilt(r(p)))
        .collect();
    let whole = Facet3::Quad4([c[0], c[1], c[2], c[3]]);
    let halves = [Facet3::Tri3([c[0], c[1], c[2]]), Facet3::Tri3([c[0], c[2], c[3]])];
    let n0 = scale3(1.0 / slave.jacobian([0.0; 2]), slave.normal([0.0; 2]));
    let nrm = [n0; 3];
    let ds = dual_basis_3d(&slave).unwrap();
    let pw = mortar_pair_3d(&slave, &nrm, &ds, &whole).unwrap().unwrap();
    let ph: Vec<PairIntegrals> =
        halves.iter().map(|h| mortar_pair_3d(&slave, &nrm, &ds, h).unwrap().unwrap()).collect();
    assert!(
        pw.overlap_measure > 0.05 && pw.overlap_measure < 0.4,
        "genuinely partial: {}",
        pw.overlap_measure
    );
    assert_close(
        pw.overlap_measure,
        ph[0].overlap_measure + ph[1].overlap_measure,
        1e-15,
        "area additive",
    );
    for j in 0..3 {
        assert_close(
            pw.psi_integral[j],
            ph[0].psi_integral[j] + ph[1].psi_integral[j],
            1e-14,
            "N_j additive",
        );
        assert_close(
            pw.weighted_gap[j],
            ph[0].weighted_gap[j] + ph[1].weighted_gap[j],
            1e-15,
            "g_j additive",
        );
        assert_close(pw.weighted_gap[j], 0.02 * pw.psi_integral[j], 1e-15, "g_j = d N_j");
        assert_close(pw.m[j].iter().sum(), pw.psi_integral[j], 1e-14, "sum_l M_jl = N_j");
    }
}

#[test]
fn mortar_3d_no_overlap_and_back_facing_give_none() {
    let slave = Facet3::Quad4([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]]);
    let ds = dual_basis_3d(&slave).unwrap();
    let nrm = [[0.0, 0.0, 1.0]; 4];
    let beside =
        Facet3::Quad4([[2.0, 0.0, 0.01], [2.0, 1.0, 0.01], [3.0, 1.0, 0.01], [3.0, 0.0, 0.01]]);
    assert!(mortar_pair_3d(&slave, &nrm, &ds, &beside).unwrap().is_none());
    // Sharing only an edge: zero-area overlap.
    let edge =
        Facet3::Quad4([[1.0, 0.0, 0.01], [1.0, 1.0, 0.01], [2.0, 1.0, 0.01], [2.0, 0.0, 0.01]]);
    assert!(mortar_pair_3d(&slave, &nrm, &ds, &edge).unwrap().is_none());
    // Overlapping but facing away (normal +z like the slave).
    let back =
        Facet3::Quad4([[0.2, 0.2, 0.01], [0.8, 0.2, 0.01], [0.8, 0.8, 0.01], [0.2, 0.8, 0.01]]);
    assert!(mortar_pair_3d(&slave, &nrm, &ds, &back).unwrap().is_none());
    // Edge-on master (perpendicular to the plane).
    let edge_on = Facet3::Tri3([[0.5, 0.0, 0.01], [0.5, 1.0, 0.01], [0.5, 0.5, 0.5]]);
    assert!(mortar_pair_3d(&slave, &nrm, &ds, &edge_on).unwrap().is_none());
}

#[test]
fn mortar_3d_warped_slave_quad_integrates_over_its_projection() {
    // Warped slave quad fully covered by a big flat master facing it: the integrals are
    // over the slave's projection on the aux plane, whose area is 1/2 |(x3 - x1) x (x4 - x2)|
    // (the aux normal at the centre, (x3-x1) x (x4-x2)/8, is parallel to the vector area).
    let x = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.1], [1.1, 0.9, -0.05], [-0.1, 1.0, 0.15]];
    let slave = Facet3::Quad4(x);
    let ds = dual_basis_3d(&slave).unwrap();
    let nrm = [[0.0, 0.0, 1.0]; 4];
    let master =
        Facet3::Quad4([[-2.0, -2.0, 0.5], [-2.0, 3.0, 0.5], [3.0, 3.0, 0.5], [3.0, -2.0, 0.5]]);
    let p = mortar_pair_3d(&slave, &nrm, &ds, &master).unwrap().unwrap();
    let proj_area = 0.5 * norm3(cross3(sub3(x[2], x[0]), sub3(x[3], x[1])));
    let sum_n: f64 = p.psi_integral.iter().sum();
    assert_close(sum_n, proj_area, 1e-13, "sum_j N_j = projected area (sum_j psi_j = 1)");
    assert_close(p.overlap_measure, proj_area, 1e-13, "overlap = projected slave");
    // The surface area (sum of D) is larger, by O(warp^2) only.
    let surf: f64 = ds.d.iter().sum();
    assert!(
        surf > proj_area && (surf - proj_area) / surf < 0.02,
        "surface {} vs projection {}",
        surf,
        proj_area
    );
    // Round trip of the Newton inversion on the warped quad.
    let plane = AuxPlane::of_slave(&slave).unwrap();
    for xi in [[0.3, -0.2], [-0.95, 0.9], [1.0, 1.0], [0.0, 0.0]] {
        let back = invert_on_plane(&slave, &plane, plane.coords(slave.position(xi))).unwrap();
        assert_close(back[0], xi[0], 1e-12, "xi round trip");
        assert_close(back[1], xi[1], 1e-12, "eta round trip");
    }
    // A point far outside the facet is reported, not silently extrapolated.
    assert!(invert_on_plane(&slave, &plane, [10.0, 10.0]).is_err());
}

#[test]
fn clipping_of_coincident_and_nested_polygons() {
    let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let same = dedupe_polygon(clip_polygon(&sq, &sq, 1e-13), 1e-12);
    assert_close(polygon_area(&same), 1.0, 1e-15, "coincident squares");
    let inner = [[0.2, 0.2], [0.7, 0.2], [0.7, 0.6]];
    assert_close(polygon_area(&clip_polygon(&inner, &sq, 1e-13)), 0.1, 1e-15, "nested triangle");
    let diamond = [[0.5, -0.5], [1.5, 0.5], [0.5, 1.5], [-0.5, 0.5]];
    // The diamond |x - 0.5| + |y - 0.5| <= 1 contains the unit square.
    assert_close(
        polygon_area(&clip_polygon(&diamond, &sq, 1e-13)),
        1.0,
        1e-15,
        "square inside diamond",
    );
    let small = [[0.5, 0.0], [1.0, 0.5], [0.5, 1.0], [0.0, 0.5]];
    assert_close(
        polygon_area(&clip_polygon(&sq, &small, 1e-13)),
        0.5,
        1e-15,
        "diamond inside square",
    );
}

// ---------------- bucket search ----------------

/// Minimal linear congruential generator (Knuth's MMIX constants), uniform in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn random_boxes(rng: &mut Lcg, n: usize, flat: bool) -> Vec<Aabb> {
    (0..n)
        .map(|i| {
            let c =
                [10.0 * rng.next(), 10.0 * rng.next(), if flat { 0.0 } else { 10.0 * rng.next() }];
            // Mostly small boxes, some point-like, every 37th an outlier of size up to 6.
            let big = if i % 37 == 0 { 6.0 } else { 0.9 };
            let h =
                [big * rng.next(), big * rng.next(), if flat { 0.05 } else { big * rng.next() }];
            let h = if i % 23 == 0 { [0.0; 3] } else { h };
            Aabb { min: sub3(c, h), max: add3(c, h) }
        })
        .collect()
}

fn brute_force(s: &[Aabb], m: &[Aabb]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for (i, a) in s.iter().enumerate() {
        for (j, b) in m.iter().enumerate() {
            if a.intersects(b) {
                out.push((i, j));
            }
        }
    }
    out
}

#[test]
fn bucket_search_equals_brute_force() {
    let mut rng = Lcg(20240611);
    for (ns, nm, flat) in [(300, 400, false), (250, 180, true), (1, 50, false), (60, 1, false)] {
        let s = random_boxes(&mut rng, ns, flat);
        let m = random_boxes(&mut rng, nm, flat);
        let fast = candidate_pairs(&s, &m);
        let slow = brute_force(&s, &m);
        if ns > 100 {
            assert!(slow.len() > ns, "test set has many intersections");
        }
        assert_eq!(fast, slow, "bucket search vs brute force ({} x {}, flat {})", ns, nm, flat);
    }
    // Degenerate inputs: empty sets, all master boxes one point, invalid boxes skipped.
    assert!(candidate_pairs(&[], &random_boxes(&mut rng, 5, false)).is_empty());
    let pt = Aabb { min: [1.0; 3], max: [1.0; 3] };
    let around = Aabb { min: [0.5; 3], max: [1.5; 3] };
    assert_eq!(candidate_pairs(&[around, pt], &[pt, pt]), vec![(0, 0), (0, 1), (1, 0), (1, 1)]);
    let nan = Aabb { min: [f64::NAN; 3], max: [1.0; 3] };
    assert_eq!(candidate_pairs(&[nan, around], &[nan, pt]), vec![(1, 1)]);
    // Facet boxes contain the facet and are inflated.
    let b = facet_aabb_2d(&Facet2 { x: [[0.0, 1.0], [2.0, -1.0]] }, 0.1);
    assert_eq!((b.min, b.max), ([-0.1, -1.1, -0.1], [2.1, 1.1, 0.1]));
}

/// A slave facet partly over the master (finite sliding): the dual basis biorthogonal on the covered
/// part keeps what the mortar method needs there. Slave (1,0) -> (0,0), master lines covering
/// x in [c, 1] at height d, split in two at x = s (two pairs of one facet). Asserted from
/// theory: `D_jj = int_cov phi_j` (closed form: with `xi = 1 - 2x`, `phi_1 = x`,
/// `phi_2 = 1 - x` over [c, 1]); `sum_l M_jl = D_jj` (partition of unity, so a rigid
/// translation of both bodies leaves the gaps alone); exact transfer of a master field linear
/// in x, `sum_l M_jl f(x_l) = D_jj f(x_j)` (biorthogonality on the covered part), even for the
/// node beyond the master's end; `g_j = d D_jj`. Fully covered (c = 0) it is the facet's own
/// dual basis; below the smallest covered fraction the facet is left out.
#[test]
fn a_partly_covered_slave_facet_keeps_partition_of_unity_and_linear_transfer() {
    let d = 0.02;
    let s = Facet2 { x: [[1.0, 0.0], [0.0, 0.0]] };
    let nrm = [[0.0, 1.0]; 2];
    let ds = dual_basis_2d(&s).unwrap();
    let facet = SurfaceFacet { nodes: vec![], cell: 0, pairs: 1, worker: usize::MAX, key: 0 };
    let f = |x: f64| 3.0 - 2.0 * x;
    for c in [0.0, 0.3, 0.9, 0.999] {
        let split = 0.5 * (c + 1.0);
        let masters = [Facet2 { x: [[c, d], [split, d]] }, Facet2 { x: [[split, d], [1.2, d]] }];
        let found: Vec<_> = masters
            .iter()
            .map(|m| (&facet, mortar_pair_2d(&s, &nrm, &ds, m).unwrap().expect("overlap")))
            .collect();
        let (d_e, pairs) = covered_part(&ds, found).expect("covered");
        // Node 0 at x = 1 (phi = x), node 1 at x = 0 (phi = 1 - x), over [c, 1].
        let exact = [(1.0 - c * c) / 2.0, (1.0 - c) - (1.0 - c * c) / 2.0];
        let xs = [1.0, 0.0];
        for j in 0..2 {
            assert_close(d_e[j], exact[j], 1e-14, &format!("c = {c}: D_jj"));
            let (mut sum, mut transfer, mut gap) = (0.0, 0.0, 0.0);
            for ((_, p), m) in pairs.iter().zip(&masters) {
                for l in 0..2 {
                    sum += p.m[j][l];
                    transfer += p.m[j][l] * f(m.x[l][0]);
                }
                gap += p.weighted_gap[j];
            }
            assert_close(sum / d_e[j], 1.0, 1e-9, &format!("c = {c}: sum_l M_jl / D_jj"));
            assert_close(transfer / d_e[j], f(xs[j]), 1e-9, &format!("c = {c}: linear transfer"));
            assert_close(gap / d_e[j], d, 1e-9, &format!("c = {c}: weighted gap"));
        }
        if c == 0.0 {
            assert_eq!(d_e, ds.d, "fully covered: the facet's own D_e");
        }
    }
    let tiny = Facet2 { x: [[1.0 - 1e-7, d], [1.2, d]] };
    let p = mortar_pair_2d(&s, &nrm, &ds, &tiny).unwrap().expect("a sliver of overlap");
    assert!(covered_part(&ds, vec![(&facet, p)]).is_none(), "a sliver below MIN_COVERED");
}
