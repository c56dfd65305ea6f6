//! Tests of the element kernels; expected values come from theory (closed forms, invariants).

use super::*;
use crate::fem::shape::tests::mapped_coords as cell_coords;
use crate::fem::shape::{physical_gradients, reference_node};
use std::collections::HashMap;

const CELLS: [ElementKind; 4] =
    [ElementKind::Tri3, ElementKind::Quad4, ElementKind::Tet4, ElementKind::Hex8];

fn mat() -> Material {
    Material::from_young_poisson(210.0, 0.3, 7.8)
}

/// Independent volume: high-order quadrature of det J.
fn volume_high_order(kind: ElementKind, coords: &[[f64; 3]]) -> f64 {
    let mut g = [[0.0; 3]; 8];
    gauss(kind, 9).into_iter().map(|(xi, w)| w * physical_gradients(kind, coords, xi, &mut g)).sum()
}

fn norm_inf(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

fn matvec(k: &[f64], n: usize, x: &[f64]) -> Vec<f64> {
    (0..n).map(|r| (0..n).map(|c| k[r * n + c] * x[c]).sum()).collect()
}

/// Rigid-body modes of the nodes: d translations, then d(d-1)/2 infinitesimal rotations.
fn rigid_modes(d: usize, coords: &[[f64; 3]]) -> Vec<Vec<f64>> {
    let n = coords.len();
    let mut modes = Vec::new();
    for i in 0..d {
        let mut v = vec![0.0; n * d];
        for a in 0..n {
            v[a * d + i] = 1.0;
        }
        modes.push(v);
    }
    for i in 0..d {
        for j in (i + 1)..d {
            let mut v = vec![0.0; n * d];
            for a in 0..n {
                v[a * d + i] = -coords[a][j];
                v[a * d + j] = coords[a][i];
            }
            modes.push(v);
        }
    }
    modes
}

/// Eigenvalues of a symmetric matrix by cyclic Jacobi rotations (test helper).
fn sym_eigenvalues(a: &[f64], n: usize) -> Vec<f64> {
    let mut a = a.to_vec();
    for _sweep in 0..100 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * n + j].powi(2))
            .sum();
        if off < 1e-30 * (0..n).map(|i| a[i * n + i].powi(2)).sum::<f64>() {
            break;
        }
        for p in 0..n {
            for q in (p + 1)..n {
                let apq = a[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let akp = a[k * n + p];
                    let akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let apk = a[p * n + k];
                    let aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
            }
        }
    }
    let mut e: Vec<f64> = (0..n).map(|i| a[i * n + i]).collect();
    e.sort_by(|x, y| x.partial_cmp(y).unwrap());
    e
}

// ---------------------------------------------------------------------------------------------

#[test]
fn lame_parameters() {
    let m = Material::from_young_poisson(1.0, 0.25, 2.0);
    assert!((m.lambda - 0.4).abs() < 1e-15);
    assert!((m.mu - 0.4).abs() < 1e-15);
    let (cp, cs) = m.wave_speeds();
    assert!((cp - (1.2f64 / 2.0).sqrt()).abs() < 1e-15 && (cs - 0.2f64.sqrt()).abs() < 1e-15);
}

#[test]
fn stiffness_reference_triangle_hand_computed() {
    let (l, m) = (1.5, 0.7);
    let mat = Material { lambda: l, mu: m, rho: 1.0, mean_dilatation: false };
    let c = l + 2.0 * m;
    // K = |T| B^T D B with |T| = 1/2, B from grad N = (-1,-1), (1,0), (0,1).
    #[rustfmt::skip]
    let expect = [
        c + m, l + m, -c, -m, -m, -l,
        l + m, c + m, -l, -m, -m, -c,
        -c,    -l,    c,  0.0, 0.0, l,
        -m,    -m,    0.0, m,  m,  0.0,
        -m,    -m,    0.0, m,  m,  0.0,
        -l,    -c,    l,  0.0, 0.0, c,
    ];
    let coords = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut k = [0.0; 36];
    stiffness(ElementKind::Tri3, &coords, &mat, &mut k).unwrap();
    for i in 0..36 {
        assert!(
            (k[i] - 0.5 * expect[i]).abs() < 1e-15,
            "entry {i}: {} vs {}",
            k[i],
            0.5 * expect[i]
        );
    }
}

#[test]
fn stiffness_symmetric_rigid_modes_psd_rank() {
    for kind in CELLS {
        for distort in [false, true] {
            let coords = cell_coords(kind, distort);
            let d = kind.dim();
            let nd = kind.n_nodes() * d;
            let mut k = vec![f64::NAN; nd * nd];
            stiffness(kind, &coords, &mat(), &mut k).unwrap();
            let kmax = norm_inf(&k);
            for r in 0..nd {
                for c in 0..nd {
                    assert!(
                        (k[r * nd + c] - k[c * nd + r]).abs() <= 1e-14 * kmax,
                        "{kind:?} not symmetric"
                    );
                }
            }
            let modes = rigid_modes(d, &coords);
            assert_eq!(modes.len(), d * (d + 1) / 2);
            for (m, v) in modes.iter().enumerate() {
                let kv = matvec(&k, nd, v);
                assert!(
                    norm_inf(&kv) <= 1e-12 * kmax * norm_inf(v),
                    "{kind:?} distort={distort}: rigid mode {m} not in kernel: {}",
                    norm_inf(&kv)
                );
            }
            let ev = sym_eigenvalues(&k, nd);
            let nzero = d * (d + 1) / 2;
            let emax = ev[nd - 1];
            for (i, e) in ev.iter().enumerate() {
                if i < nzero {
                    assert!(e.abs() < 1e-12 * emax, "{kind:?}: eigenvalue {i} = {e} should be 0");
                } else {
                    assert!(
                        *e > 1e-6 * emax,
                        "{kind:?}: eigenvalue {i} = {e} should be > 0 (spurious mode)"
                    );
                }
            }
        }
    }
}

#[test]
fn stiffness_scales_with_size_as_h_pow_d_minus_2() {
    // K(s x) = s^(d-2) K(x): a check that the J^{-T} and det J factors are consistent.
    for kind in CELLS {
        let c1 = cell_coords(kind, true);
        let c2: Vec<[f64; 3]> = c1.iter().map(|x| [3.0 * x[0], 3.0 * x[1], 3.0 * x[2]]).collect();
        let nd = kind.n_nodes() * kind.dim();
        let (mut k1, mut k2) = (vec![0.0; nd * nd], vec![0.0; nd * nd]);
        stiffness(kind, &c1, &mat(), &mut k1).unwrap();
        stiffness(kind, &c2, &mat(), &mut k2).unwrap();
        let s = 3f64.powi(kind.dim() as i32 - 2);
        for i in 0..nd * nd {
            assert!((k2[i] - s * k1[i]).abs() < 1e-12 * norm_inf(&k2));
        }
    }
}

#[test]
fn inverted_elements_are_errors_naming_the_kind() {
    for kind in CELLS {
        let mut coords = cell_coords(kind, false);
        // Mirror the element (x -> -x) to invert it.
        for x in coords.iter_mut() {
            x[0] = -x[0];
        }
        let nd = kind.n_nodes() * kind.dim();
        let mut k = vec![0.0; nd * nd];
        let err = stiffness(kind, &coords, &mat(), &mut k).unwrap_err();
        let msg = err.to_string();
        assert!(matches!(err, Error::Mesh(_)), "{msg}");
        assert!(msg.contains(kind.name()) && msg.contains(&format!("{kind:?}")), "{msg}");
        assert!(msg.contains("inverted or degenerate"), "{msg}");
        assert!(min_det_jacobian(kind, &coords) < 0.0);
        // Degenerate: all nodes collapsed onto a line.
        let flat: Vec<[f64; 3]> =
            (0..kind.n_nodes()).map(|a| [a as f64, 2.0 * a as f64, 0.0]).collect();
        assert!(stiffness(kind, &flat, &mat(), &mut k).is_err());
    }
}

#[test]
fn min_det_jacobian_detects_nonconvex_quad() {
    // Arrow-shaped quad: node 2 pushed inside; det J at that corner is negative while the
    // 2x2 Gauss points may still be fine.
    let c = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.4, 0.4, 0.0], [0.0, 2.0, 0.0]];
    assert!(min_det_jacobian(ElementKind::Quad4, &c) < 0.0);
    let ok = cell_coords(ElementKind::Quad4, true);
    assert!(min_det_jacobian(ElementKind::Quad4, &ok) > 0.0);
    // Tri3: det J = 2 area.
    let t = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
    assert!((min_det_jacobian(ElementKind::Tri3, &t) - 6.0).abs() < 1e-15);
}

// ---------------------------------------------------------------------------------------------
// Patch tests.

struct Patch {
    kind: ElementKind,
    d: usize,
    nodes: Vec<[f64; 3]>,
    cells: Vec<Vec<usize>>,
}

/// Structured (n x n [x n]) grid on [0,2]^d with all nodes perturbed, boundary nodes
/// included (boundary edges stay straight; 3D boundary faces become warped bilinear faces,
/// for which the 2x2 face rule still integrates N_a sigma n ds exactly).
fn grid_nodes(d: usize, n: usize) -> (Vec<[f64; 3]>, impl Fn(usize, usize, usize) -> usize) {
    let m = n + 1;
    let id = move |i: usize, j: usize, k: usize| i + m * (j + m * k);
    let mut nodes = Vec::new();
    let h = 2.0 / n as f64;
    for k in 0..(if d == 3 { m } else { 1 }) {
        for j in 0..m {
            for i in 0..m {
                let s = (i * 7 + j * 13 + k * 5) as f64;
                let p = [
                    i as f64 * h + 0.18 * h * (s * 1.3).sin(),
                    j as f64 * h + 0.15 * h * (s * 0.7).cos(),
                    if d == 3 { k as f64 * h + 0.12 * h * (s * 2.1).sin() } else { 0.0 },
                ];
                nodes.push(p);
            }
        }
    }
    (nodes, id)
}

fn quad_patch() -> Patch {
    let (nodes, id) = grid_nodes(2, 2);
    let mut cells = Vec::new();
    for j in 0..2 {
        for i in 0..2 {
            cells.push(vec![id(i, j, 0), id(i + 1, j, 0), id(i + 1, j + 1, 0), id(i, j + 1, 0)]);
        }
    }
    Patch { kind: ElementKind::Quad4, d: 2, nodes, cells }
}

fn tri_patch() -> Patch {
    let (nodes, id) = grid_nodes(2, 3);
    let mut cells = Vec::new();
    for j in 0..3 {
        for i in 0..3 {
            let (a, b, c, e) = (id(i, j, 0), id(i + 1, j, 0), id(i + 1, j + 1, 0), id(i, j + 1, 0));
            if (i + j) % 2 == 0 {
                cells.push(vec![a, b, c]);
                cells.push(vec![a, c, e]);
            } else {
                cells.push(vec![a, b, e]);
                cells.push(vec![b, c, e]);
            }
        }
    }
    Patch { kind: ElementKind::Tri3, d: 2, nodes, cells }
}

fn hex_patch() -> Patch {
    let (nodes, id) = grid_nodes(3, 2);
    let mut cells = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                cells.push(vec![
                    id(i, j, k),
                    id(i + 1, j, k),
                    id(i + 1, j + 1, k),
                    id(i, j + 1, k),
                    id(i, j, k + 1),
                    id(i + 1, j, k + 1),
                    id(i + 1, j + 1, k + 1),
                    id(i, j + 1, k + 1),
                ]);
            }
        }
    }
    Patch { kind: ElementKind::Hex8, d: 3, nodes, cells }
}

/// Freudenthal (Kuhn) split of every cube of a 2x2x2 grid into 6 tets (conforming);
/// orientation fixed by swapping two nodes when needed.
fn tet_patch() -> Patch {
    let (nodes, id) = grid_nodes(3, 2);
    let mut cells = Vec::new();
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..2 {
                for p in perms {
                    let mut v = [i, j, k];
                    let mut tet = vec![id(v[0], v[1], v[2])];
                    for axis in p {
                        v[axis] += 1;
                        tet.push(id(v[0], v[1], v[2]));
                    }
                    let c: Vec<[f64; 3]> = tet.iter().map(|&a| nodes[a]).collect();
                    if measure(ElementKind::Tet4, &c) < 0.0 {
                        tet.swap(2, 3);
                    }
                    cells.push(tet);
                }
            }
        }
    }
    Patch { kind: ElementKind::Tet4, d: 3, nodes, cells }
}

/// Boundary facets (outward-ordered via `facets()`): facets appearing in exactly one cell.
fn boundary_facets(p: &Patch) -> Vec<Vec<usize>> {
    let mut count: HashMap<Vec<usize>, (usize, Vec<usize>)> = HashMap::new();
    for c in &p.cells {
        for f in p.kind.facets() {
            let v: Vec<usize> = f.iter().map(|&a| c[a]).collect();
            let mut key = v.clone();
            key.sort();
            count.entry(key).or_insert((0, v)).0 += 1;
        }
    }
    count.into_values().filter(|(c, _)| *c == 1).map(|(_, v)| v).collect()
}

fn run_patch_test(p: &Patch) {
    let d = p.d;
    let nn = p.nodes.len();
    let ndof = nn * d;
    let mat = mat();
    let mut kg = vec![0.0; ndof * ndof];
    let ne = p.kind.n_nodes() * d;
    let mut ke = vec![0.0; ne * ne];
    for c in &p.cells {
        let coords: Vec<[f64; 3]> = c.iter().map(|&a| p.nodes[a]).collect();
        stiffness(p.kind, &coords, &mat, &mut ke).unwrap();
        for (la, &ga) in c.iter().enumerate() {
            for (lb, &gb) in c.iter().enumerate() {
                for i in 0..d {
                    for j in 0..d {
                        kg[(ga * d + i) * ndof + gb * d + j] += ke[(la * d + i) * ne + lb * d + j];
                    }
                }
            }
        }
    }
    // Linear field u = a + B x and its constant stress.
    let a = [0.3, -0.2, 0.5];
    let bm = [[0.01, 0.03, -0.02], [-0.04, 0.02, 0.05], [0.015, -0.01, 0.03]];
    let mut u = vec![0.0; ndof];
    for (n, x) in p.nodes.iter().enumerate() {
        for i in 0..d {
            u[n * d + i] = a[i] + (0..d).map(|j| bm[i][j] * x[j]).sum::<f64>();
        }
    }
    let tr: f64 = (0..d).map(|i| bm[i][i]).sum();
    let mut sigma = [[0.0; 3]; 3];
    for i in 0..d {
        for j in 0..d {
            sigma[i][j] =
                mat.mu * (bm[i][j] + bm[j][i]) + if i == j { mat.lambda * tr } else { 0.0 };
        }
    }
    let r = matvec(&kg, ndof, &u);
    // Consistent boundary forces of the constant stress: int_F N_a sigma n ds.
    let mut f = vec![0.0; ndof];
    let facets = boundary_facets(p);
    assert!(!facets.is_empty());
    let mut on_boundary = vec![false; nn];
    for fv in &facets {
        let fk = match fv.len() {
            2 => ElementKind::Line2,
            3 => ElementKind::Tri3,
            _ => ElementKind::Quad4,
        };
        let coords: Vec<[f64; 3]> = fv.iter().map(|&a| p.nodes[a]).collect();
        let g = |_x: [f64; 3], n: [f64; 3]| {
            let mut t = [0.0; 3];
            for i in 0..3 {
                t[i] = (0..3).map(|j| sigma[i][j] * n[j]).sum();
            }
            t
        };
        let mut fe = vec![0.0; fv.len() * d];
        traction(fk, &coords, &g, d, 2, &mut fe);
        for (la, &ga) in fv.iter().enumerate() {
            on_boundary[ga] = true;
            for i in 0..d {
                f[ga * d + i] += fe[la * d + i];
            }
        }
    }
    let scale = norm_inf(&f);
    assert!(scale > 0.0);
    let interior = on_boundary.iter().filter(|b| !**b).count();
    assert!(interior >= 1, "{:?} patch has no interior node", p.kind);
    for n in 0..nn {
        for i in 0..d {
            let k = n * d + i;
            if !on_boundary[n] {
                assert!(r[k].abs() < 1e-12 * scale, "{:?}: interior residual {}", p.kind, r[k]);
            }
            assert!(
                (r[k] - f[k]).abs() < 1e-12 * scale,
                "{:?}: node {n} comp {i}: K u = {} vs traction {}",
                p.kind,
                r[k],
                f[k]
            );
        }
    }
    // Sanity: the assembled boundary forces balance (sum = 0) and the check is not vacuous.
    for i in 0..d {
        let s: f64 = (0..nn).map(|n| f[n * d + i]).sum();
        assert!(s.abs() < 1e-12 * scale);
    }
}

#[test]
fn patch_test_quads() {
    run_patch_test(&quad_patch());
}

#[test]
fn patch_test_triangles() {
    run_patch_test(&tri_patch());
}

#[test]
fn patch_test_hexes() {
    run_patch_test(&hex_patch());
}

#[test]
fn patch_test_tets() {
    run_patch_test(&tet_patch());
}

#[test]
fn patch_test_can_fail() {
    // A wrong material on one element must break the interior equilibrium: guards against a
    // vacuous patch test.
    let p = quad_patch();
    let d = 2;
    let nn = p.nodes.len();
    let mut r = vec![0.0; nn * d];
    let mut ke = vec![0.0; 64];
    for (e, c) in p.cells.iter().enumerate() {
        let coords: Vec<[f64; 3]> = c.iter().map(|&a| p.nodes[a]).collect();
        let mut m = mat();
        if e == 0 {
            m.mu *= 2.0;
        }
        stiffness(p.kind, &coords, &m, &mut ke).unwrap();
        let ue: Vec<f64> = c.iter().flat_map(|&a| [0.01 * p.nodes[a][0], 0.0]).collect();
        let fe = matvec(&ke, 8, &ue);
        for (la, &ga) in c.iter().enumerate() {
            for i in 0..d {
                r[ga * d + i] += fe[la * d + i];
            }
        }
    }
    let center = 4; // node (1,1) of the 3x3 node grid
    assert!(r[center * d].abs() + r[center * d + 1].abs() > 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Mass.

#[test]
fn mass_p1_triangle_and_tet_closed_form() {
    let rho = 2.5;
    let t = [[0.2, 0.1, 0.0], [2.0, 0.4, 0.0], [0.5, 1.7, 0.0]];
    let area = 0.5
        * ((t[1][0] - t[0][0]) * (t[2][1] - t[0][1]) - (t[2][0] - t[0][0]) * (t[1][1] - t[0][1]));
    let mut m = [0.0; 36];
    mass(ElementKind::Tri3, &t, rho, &mut m);
    for a in 0..3 {
        for b in 0..3 {
            for i in 0..2 {
                for j in 0..2 {
                    let e = if i == j {
                        rho * area / 12.0 * if a == b { 2.0 } else { 1.0 }
                    } else {
                        0.0
                    };
                    assert!(
                        (m[(a * 2 + i) * 6 + b * 2 + j] - e).abs() < 1e-14,
                        "tri M[{a}{i},{b}{j}]"
                    );
                }
            }
        }
    }
    let c = cell_coords(ElementKind::Tet4, false);
    let vol = measure(ElementKind::Tet4, &c);
    let mut m = [0.0; 144];
    mass(ElementKind::Tet4, &c, rho, &mut m);
    for a in 0..4 {
        for b in 0..4 {
            let e = rho * vol / 20.0 * if a == b { 2.0 } else { 1.0 };
            assert!((m[(a * 3 + 1) * 12 + b * 3 + 1] - e).abs() < 1e-14);
            assert!(m[(a * 3) * 12 + b * 3 + 2] == 0.0);
        }
    }
}

#[test]
fn mass_q1_rectangle_and_box_tensor_formula() {
    let (a, b, rho) = (3.0, 0.5, 1.3);
    let c = [[1.0, 1.0, 0.0], [1.0 + a, 1.0, 0.0], [1.0 + a, 1.0 + b, 0.0], [1.0, 1.0 + b, 0.0]];
    let tab =
        [[4.0, 2.0, 1.0, 2.0], [2.0, 4.0, 2.0, 1.0], [1.0, 2.0, 4.0, 2.0], [2.0, 1.0, 2.0, 4.0]];
    let mut m = [0.0; 64];
    mass(ElementKind::Quad4, &c, rho, &mut m);
    for p in 0..4 {
        for q in 0..4 {
            let e = rho * a * b / 36.0 * tab[p][q];
            for i in 0..2 {
                assert!((m[(p * 2 + i) * 8 + q * 2 + i] - e).abs() < 1e-14);
                assert!(m[(p * 2 + i) * 8 + q * 2 + 1 - i] == 0.0);
            }
        }
    }
    // Box lx x ly x lz: m_ab = rho prod_k l_k/6 (2 if same coordinate along k else 1).
    let l = [2.0, 1.5, 0.7];
    let r: Vec<[f64; 3]> = (0..8).map(|n| reference_node(ElementKind::Hex8, n)).collect();
    let c: Vec<[f64; 3]> = r
        .iter()
        .map(|x| [l[0] * (x[0] + 1.0) / 2.0, l[1] * (x[1] + 1.0) / 2.0, l[2] * (x[2] + 1.0) / 2.0])
        .collect();
    let mut m = [0.0; 576];
    mass(ElementKind::Hex8, &c, rho, &mut m);
    for p in 0..8 {
        for q in 0..8 {
            let mut e = rho;
            for k in 0..3 {
                e *= l[k] / 6.0 * if r[p][k] == r[q][k] { 2.0 } else { 1.0 };
            }
            assert!((m[(p * 3 + 2) * 24 + q * 3 + 2] - e).abs() < 1e-14, "hex M[{p},{q}]");
        }
    }
}

#[test]
fn mass_sums_to_element_mass_and_lumped_is_row_sum() {
    let rho = 3.1;
    for kind in CELLS {
        for distort in [false, true] {
            let c = cell_coords(kind, distort);
            let d = kind.dim();
            let nd = kind.n_nodes() * d;
            let vol = volume_high_order(kind, &c);
            assert!((measure(kind, &c) - vol).abs() < 1e-13 * vol, "{kind:?} measure");
            let mut m = vec![f64::NAN; nd * nd];
            mass(kind, &c, rho, &mut m);
            for i in 0..d {
                let s: f64 = (0..nd)
                    .filter(|r| r % d == i)
                    .flat_map(|r| (0..nd).map(move |c| (r, c)))
                    .map(|(r, c)| m[r * nd + c])
                    .sum();
                assert!(
                    (s - rho * vol).abs() < 1e-13 * rho * vol,
                    "{kind:?} distort={distort}: {s} vs {}",
                    rho * vol
                );
            }
            let mut diag = vec![f64::NAN; nd];
            mass_lumped_diag(kind, &c, rho, &mut diag);
            let mut ml = vec![f64::NAN; nd * nd];
            mass_lumped(kind, &c, rho, &mut ml);
            for r in 0..nd {
                let rs: f64 = (0..nd).map(|c| m[r * nd + c]).sum();
                assert!((diag[r] - rs).abs() < 1e-14 * rho * vol);
                assert!(diag[r] > 0.0);
                for col in 0..nd {
                    let e = if r == col { diag[r] } else { 0.0 };
                    assert!(ml[r * nd + col] == e);
                }
            }
            // Consistent mass is symmetric positive definite.
            let ev = sym_eigenvalues(&m, nd);
            assert!(ev[0] > 0.0, "{kind:?} mass not SPD");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Loads.

#[test]
fn body_force_constant_sums_to_measure_times_f() {
    let f = |_x: [f64; 3]| [1.5, -2.0, 0.75];
    for kind in CELLS {
        let c = cell_coords(kind, true);
        let d = kind.dim();
        let nd = kind.n_nodes() * d;
        let vol = volume_high_order(kind, &c);
        let mut fe = vec![f64::NAN; nd];
        body_force(kind, &c, &f, 2, &mut fe);
        let fv = f([0.0; 3]);
        for i in 0..d {
            let s: f64 = (0..kind.n_nodes()).map(|a| fe[a * d + i]).sum();
            assert!((s - vol * fv[i]).abs() < 1e-13 * vol, "{kind:?} comp {i}");
        }
    }
    // P1: each node gets |K|/(d+1) f.
    let c = cell_coords(ElementKind::Tri3, false);
    let mut fe = [0.0; 6];
    body_force(ElementKind::Tri3, &c, &f, 1, &mut fe);
    let area = measure(ElementKind::Tri3, &c);
    for a in 0..3 {
        assert!((fe[a * 2] - area / 3.0 * 1.5).abs() < 1e-14);
    }
}

#[test]
fn body_force_linear_field_exact() {
    // f = (x, 0): int_T N_a x dx on the reference triangle = (1/24, 1/12, 1/24) for
    // nodes (0,0),(1,0),(0,1) (int N_a N_b = |T|(1 + delta)/12 applied to x = N_1).
    let c = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let mut fe = [0.0; 6];
    body_force(ElementKind::Tri3, &c, &|x| [x[0], 0.0, 0.0], 2, &mut fe);
    let e = [1.0 / 24.0, 1.0 / 12.0, 1.0 / 24.0];
    for a in 0..3 {
        assert!((fe[2 * a] - e[a]).abs() < 1e-15 && fe[2 * a + 1] == 0.0);
    }
}

#[test]
fn traction_constant_on_line_and_faces() {
    let g = |_x: [f64; 3], _n: [f64; 3]| [2.0, -1.0, 0.5];
    // Line2 of length 5.
    let c = [[1.0, 1.0, 0.0], [4.0, 5.0, 0.0]];
    let mut fe = [0.0; 4];
    traction(ElementKind::Line2, &c, &g, 2, 1, &mut fe);
    for a in 0..2 {
        assert!((fe[a * 2] - 2.5 * 2.0).abs() < 1e-14 && (fe[a * 2 + 1] + 2.5).abs() < 1e-14);
    }
    let mut w = [0.0; 2];
    boundary_weights(ElementKind::Line2, &c, &mut w);
    assert!((w[0] - 2.5).abs() < 1e-14 && (w[1] - 2.5).abs() < 1e-14);
    // Tri3 face, area = 0.5 |(1,2,0) x (0,1,3)| = 0.5 |(6,-3,1)| = sqrt(46)/2.
    let c = [[0.0, 0.0, 1.0], [1.0, 2.0, 1.0], [0.0, 1.0, 4.0]];
    let area = 46f64.sqrt() / 2.0;
    let mut fe = [0.0; 9];
    traction(ElementKind::Tri3, &c, &g, 3, 1, &mut fe);
    let gv = g([0.0; 3], [0.0; 3]);
    for a in 0..3 {
        for i in 0..3 {
            assert!((fe[a * 3 + i] - area / 3.0 * gv[i]).abs() < 1e-14);
        }
    }
    let mut w = [0.0; 3];
    boundary_weights(ElementKind::Tri3, &c, &mut w);
    assert!(w.iter().all(|v| (v - area / 3.0).abs() < 1e-14));
    // Quad4 rectangle face 2 x 3: each node area/4 = 1.5.
    let c = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 3.0, 0.0], [0.0, 3.0, 0.0]];
    let mut fe = [0.0; 12];
    traction(ElementKind::Quad4, &c, &g, 3, 1, &mut fe);
    for a in 0..4 {
        for i in 0..3 {
            assert!((fe[a * 3 + i] - 1.5 * gv[i]).abs() < 1e-14);
        }
    }
    let mut w = [0.0; 4];
    boundary_weights(ElementKind::Quad4, &c, &mut w);
    assert!(w.iter().all(|v| (v - 1.5).abs() < 1e-14));
}

#[test]
fn traction_pressure_uses_outward_normals() {
    // Pressure p: g = -p n. On the CCW unit square, the total force on each edge is -p n L
    // with n outward: (0,+p) on the bottom edge, (-p,0) on the right, ...
    let p = 2.0;
    let g = |_x: [f64; 3], n: [f64; 3]| [-p * n[0], -p * n[1], 0.0];
    let sq = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let outward = [[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]];
    for e in 0..4 {
        let c = [sq[e], sq[(e + 1) % 4]];
        let mut fe = [0.0; 4];
        traction(ElementKind::Line2, &c, &g, 2, 1, &mut fe);
        for i in 0..2 {
            assert!((fe[i] + fe[2 + i] + p * outward[e][i]).abs() < 1e-15, "edge {e}");
        }
    }
    // Reference hex faces from facets(): pressure on face f gives total force -p n_f * 4.
    let nodes: Vec<[f64; 3]> = (0..8).map(|a| reference_node(ElementKind::Hex8, a)).collect();
    let expect = [
        [0.0, 0.0, -1.0],
        [0.0, -1.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let gp = |_x: [f64; 3], n: [f64; 3]| [-p * n[0], -p * n[1], -p * n[2]];
    for (f, facet) in ElementKind::Hex8.facets().iter().enumerate() {
        let c: Vec<[f64; 3]> = facet.iter().map(|&a| nodes[a]).collect();
        let mut fe = [0.0; 12];
        traction(ElementKind::Quad4, &c, &gp, 3, 2, &mut fe);
        for i in 0..3 {
            let s: f64 = (0..4).map(|a| fe[a * 3 + i]).sum();
            assert!(
                (s + 4.0 * p * expect[f][i]).abs() < 1e-14,
                "hex facet {f} {facet:?} comp {i}: {s}"
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors and convergence.

fn interpolate(d: usize, coords: &[[f64; 3]], u: &dyn Fn([f64; 3]) -> [f64; 3]) -> Vec<f64> {
    coords.iter().flat_map(|x| u(*x)[..d].to_vec()).collect()
}

#[test]
fn error_sq_zero_for_affine_fields() {
    let exact = |x: [f64; 3]| {
        let gr = [[0.1, -0.3, 0.2], [0.4, 0.05, -0.1], [-0.2, 0.3, 0.15]];
        let mut u = [1.0, -2.0, 0.5];
        for i in 0..3 {
            for j in 0..3 {
                u[i] += gr[i][j] * x[j];
            }
        }
        (u, gr)
    };
    for kind in CELLS {
        let c = cell_coords(kind, true);
        let uh = interpolate(kind.dim(), &c, &|x| exact(x).0);
        let (e0, e1) = error_sq(kind, &c, &uh, &exact, 4);
        assert!(e0 < 1e-28 && e1 < 1e-28, "{kind:?}: {e0} {e1}");
        // and it is not blind: perturb one nodal value by 1e-3
        let mut up = uh.clone();
        up[1] += 1e-3;
        let (p0, p1) = error_sq(kind, &c, &up, &exact, 4);
        assert!(p0 > 1e-9 && p1 > 1e-9);
    }
}

fn quadratic_exact(x: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let (a, b, c) = (x[0], x[1], x[2]);
    let u = [a * a + 0.5 * a * b, b * b - a * c + 0.3 * c * c, a * b + b * c];
    let g = [[2.0 * a + 0.5 * b, 0.5 * a, 0.0], [-c, 2.0 * b, -a + 0.6 * c], [b, a + c, b]];
    (u, g)
}

/// Sum of error_sq over a uniform grid of the unit square/cube with n cells per side.
fn grid_errors(kind: ElementKind, n: usize) -> (f64, f64) {
    let d = kind.dim();
    let h = 1.0 / n as f64;
    let mut tot = (0.0, 0.0);
    let nz = if d == 3 { n } else { 1 };
    for k in 0..nz {
        for j in 0..n {
            for i in 0..n {
                let pt = |c: [usize; 3]| {
                    [
                        (i + c[0]) as f64 * h,
                        (j + c[1]) as f64 * h,
                        if d == 3 { (k + c[2]) as f64 * h } else { 0.0 },
                    ]
                };
                let cells: Vec<(ElementKind, Vec<[f64; 3]>)> = match kind {
                    ElementKind::Quad4 => vec![(
                        kind,
                        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
                            .iter()
                            .map(|c| pt(*c))
                            .collect(),
                    )],
                    ElementKind::Tri3 => vec![
                        (kind, [[0, 0, 0], [1, 0, 0], [1, 1, 0]].iter().map(|c| pt(*c)).collect()),
                        (kind, [[0, 0, 0], [1, 1, 0], [0, 1, 0]].iter().map(|c| pt(*c)).collect()),
                    ],
                    ElementKind::Hex8 => vec![(
                        kind,
                        (0..8)
                            .map(|a| {
                                let r = reference_node(kind, a);
                                pt([
                                    (r[0] > 0.0) as usize,
                                    (r[1] > 0.0) as usize,
                                    (r[2] > 0.0) as usize,
                                ])
                            })
                            .collect(),
                    )],
                    ElementKind::Tet4 => {
                        [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]]
                            .iter()
                            .map(|p| {
                                let mut v = [0usize; 3];
                                let mut t = vec![pt(v)];
                                for &ax in p {
                                    v[ax] += 1;
                                    t.push(pt(v));
                                }
                                if measure(kind, &t) < 0.0 {
                                    t.swap(2, 3);
                                }
                                (kind, t)
                            })
                            .collect()
                    }
                    _ => unreachable!(),
                };
                for (kd, c) in cells {
                    let uh = interpolate(d, &c, &|x| quadratic_exact(x).0);
                    let (e0, e1) = error_sq(kd, &c, &uh, &quadratic_exact, 4);
                    tot.0 += e0;
                    tot.1 += e1;
                }
            }
        }
    }
    tot
}

#[test]
fn interpolation_error_rates_2d() {
    for kind in [ElementKind::Tri3, ElementKind::Quad4] {
        let errs: Vec<(f64, f64)> = [4, 8, 16, 32].iter().map(|&n| grid_errors(kind, n)).collect();
        for w in errs.windows(2) {
            let r0 = (w[0].0 / w[1].0).sqrt().log2();
            let r1 = (w[0].1 / w[1].1).sqrt().log2();
            assert!((r0 - 2.0).abs() < 0.05, "{kind:?}: L2 rate {r0}");
            assert!((r1 - 1.0).abs() < 0.05, "{kind:?}: H1 rate {r1}");
        }
    }
}

#[test]
fn interpolation_error_rates_3d() {
    for kind in [ElementKind::Tet4, ElementKind::Hex8] {
        let errs: Vec<(f64, f64)> = [2, 4, 8].iter().map(|&n| grid_errors(kind, n)).collect();
        for w in errs.windows(2) {
            let r0 = (w[0].0 / w[1].0).sqrt().log2();
            let r1 = (w[0].1 / w[1].1).sqrt().log2();
            assert!((r0 - 2.0).abs() < 0.1, "{kind:?}: L2 rate {r0}");
            assert!((r1 - 1.0).abs() < 0.1, "{kind:?}: H1 rate {r1}");
        }
    }
}

#[test]
fn measure_of_known_shapes() {
    let q = [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 1.0, 0.0], [0.0, 1.0, 0.0]]; // trapezoid
    assert!((measure(ElementKind::Quad4, &q) - 2.5).abs() < 1e-15);
    let t = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]];
    assert!((measure(ElementKind::Tet4, &t) - 1.0).abs() < 1e-15);
    let c = cell_coords(ElementKind::Hex8, false);
    // affine image of [-1,1]^3 under A: volume 8 det A
    let det_a = 2.0 * (1.5 * 0.9 + 0.2 * 0.2) - 0.5 * (0.5 * 0.9 - 0.2 * 0.1)
        + 0.1 * (-0.5 * 0.2 - 1.5 * 0.1);
    assert!((measure(ElementKind::Hex8, &c) - 8.0 * det_a).abs() < 1e-13);
}

#[test]
fn high_orders_use_cached_and_uncached_tables() {
    // order 20 > MAX_CACHED_ORDER: same answer as order 12 for a polynomial of degree 6.
    let c = cell_coords(ElementKind::Tri3, true);
    let f = |x: [f64; 3]| [x[0].powi(5), x[1].powi(5), 0.0];
    let (mut f1, mut f2) = ([0.0; 6], [0.0; 6]);
    body_force(ElementKind::Tri3, &c, &f, 6, &mut f1);
    body_force(ElementKind::Tri3, &c, &f, 20, &mut f2);
    body_force(ElementKind::Tri3, &c, &f, 20, &mut f2);
    for i in 0..6 {
        assert!((f1[i] - f2[i]).abs() < 1e-12 * norm_inf(&f1));
    }
}

#[test]
fn node_mass_blocks_are_the_mass_per_component() {
    // mass = mass_nodes ⊗ I_d and mass_lumped = mass_lumped_nodes ⊗ I_d, exactly: the run
    // stores only the node blocks (mass::MassMatrix).
    for kind in [ElementKind::Tri3, ElementKind::Quad4, ElementKind::Tet4, ElementKind::Hex8] {
        let coords = cell_coords(kind, true);
        let (n, d) = (kind.n_nodes(), kind.dim());
        let nd = n * d;
        type Kernel = fn(ElementKind, &[[f64; 3]], f64, &mut [f64]);
        let pairs: [(Kernel, Kernel); 2] = [(mass, mass_nodes), (mass_lumped, mass_lumped_nodes)];
        for (full_kernel, node_kernel) in pairs {
            let mut full = vec![0.0; nd * nd];
            let mut node = vec![0.0; n * n];
            full_kernel(kind, &coords, 2.5, &mut full);
            node_kernel(kind, &coords, 2.5, &mut node);
            for r in 0..nd {
                for c in 0..nd {
                    let want = if r % d == c % d { node[(r / d) * n + c / d] } else { 0.0 };
                    assert_eq!(full[r * nd + c], want, "{kind:?} ({r}, {c})");
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Mean dilatation (formulation = "mixed").

fn mixed(m: Material) -> Material {
    Material { mean_dilatation: true, ..m }
}

/// The patch test: an affine displacement has a constant dilatation, so its cell mean is
/// itself and the mean-dilatation element gives the plain element's (exact) nodal forces.
#[test]
fn mean_dilatation_passes_the_patch_test() {
    for kind in [ElementKind::Quad4, ElementKind::Hex8] {
        let d = kind.dim();
        let x = cell_coords(kind, true);
        let nd = x.len() * d;
        let (mut k, mut kb) = (vec![0.0; nd * nd], vec![0.0; nd * nd]);
        stiffness(kind, &x, &mat(), &mut k).unwrap();
        stiffness(kind, &x, &mixed(mat()), &mut kb).unwrap();
        let g = [[0.3, -0.7, 0.2], [0.5, 0.9, -0.4], [-0.1, 0.6, 1.1]];
        let u: Vec<f64> = (0..nd)
            .map(|r| {
                let (a, i) = (r / d, r % d);
                0.25 + (0..d).map(|j| g[i][j] * x[a][j]).sum::<f64>()
            })
            .collect();
        let (f, fb) = (matvec(&k, nd, &u), matvec(&kb, nd, &u));
        let scale = norm_inf(&f);
        for r in 0..nd {
            assert!(
                (f[r] - fb[r]).abs() <= 1e-12 * scale,
                "{}: {} vs {}",
                kind.name(),
                f[r],
                fb[r]
            );
        }
    }
}

/// The volumetric part is the rank-one `lambda/|K| b b^T`, `b_a = int grad N_a` with
/// `sum_a b_a (x) x_a = |K| I` (the integral of grad x); what is left is the mu part; the
/// element keeps exactly the rigid motions as zero-energy modes (no spurious modes).
#[test]
fn mean_dilatation_is_rank_one_in_lambda_and_has_no_spurious_modes() {
    for kind in [ElementKind::Quad4, ElementKind::Hex8] {
        let d = kind.dim();
        let x = cell_coords(kind, true);
        let n = x.len();
        let nd = n * d;
        let lam = Material { lambda: 1.0, mu: 0.0, rho: 1.0, mean_dilatation: true };
        let mut kl = vec![0.0; nd * nd];
        stiffness(kind, &x, &lam, &mut kl).unwrap();
        let vol = volume_high_order(kind, &x);
        // b from the diagonal blocks' row a: K_(a,i),(a,i) = b_a,i^2/|K|; recover b by
        // b b^T = |K| K and check sum_a b_a (x) x_a = |K| I.
        let mut id = [[0.0; 3]; 3];
        let r0 = (0..nd).max_by(|&p, &q| kl[p * nd + p].total_cmp(&kl[q * nd + q])).unwrap();
        let b0 = (vol * kl[r0 * nd + r0]).sqrt();
        let b: Vec<f64> = (0..nd).map(|c| vol * kl[r0 * nd + c] / b0).collect();
        for p in 0..nd {
            for q in 0..nd {
                assert!((kl[p * nd + q] - b[p] * b[q] / vol).abs() < 1e-12, "rank one");
            }
        }
        for a in 0..n {
            for i in 0..d {
                for j in 0..d {
                    id[i][j] += b[a * d + i] * x[a][j];
                }
            }
        }
        // (b is known up to its sign.)
        let sign = id[0][0].signum();
        for i in 0..d {
            for j in 0..d {
                id[i][j] *= sign;
                let want = if i == j { vol } else { 0.0 };
                assert!((id[i][j] - want).abs() < 1e-12 * vol, "{}: sum b x = |K| I", kind.name());
            }
        }
        // Nearly incompressible: the zero eigenvalues are the rigid motions only.
        let m = mixed(Material::from_young_poisson(1.0, 0.4999, 1.0));
        let mut kb = vec![0.0; nd * nd];
        stiffness(kind, &x, &m, &mut kb).unwrap();
        for r in rigid_modes(d, &x) {
            assert!(norm_inf(&matvec(&kb, nd, &r)) < 1e-9 * m.lambda, "rigid mode");
        }
        let e = sym_eigenvalues(&kb, nd);
        let rigid = d * (d + 1) / 2;
        assert!(e[..rigid].iter().all(|v| v.abs() < 1e-9 * m.lambda), "{e:?}");
        assert!(e[rigid] > 1e-3 * m.mu, "{}: a spurious zero-energy mode: {e:?}", kind.name());
    }
}

/// Simplices have a constant strain already: the flag changes nothing there.
#[test]
fn mean_dilatation_leaves_simplices_as_they_are() {
    for kind in [ElementKind::Tri3, ElementKind::Tet4] {
        let d = kind.dim();
        let x = cell_coords(kind, false);
        let nd = x.len() * d;
        let (mut k, mut kb) = (vec![0.0; nd * nd], vec![0.0; nd * nd]);
        stiffness(kind, &x, &mat(), &mut k).unwrap();
        stiffness(kind, &x, &mixed(mat()), &mut kb).unwrap();
        assert_eq!(k, kb);
    }
}
