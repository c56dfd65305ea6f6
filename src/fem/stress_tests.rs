//! Tests of the stress kernels: exact values for linear displacement fields on affine and
//! distorted cells of every kind, invariants of known tensors, plane strain, the Q1 average.

use super::*;
use crate::fem::quadrature::gauss;
use crate::fem::shape::{shape, shape_grad_ref};

const G: [[f64; 3]; 3] = [[0.011, -0.023, 0.017], [0.031, 0.005, -0.013], [-0.007, 0.019, 0.029]];
const C: [f64; 3] = [0.1, -0.2, 0.3];

fn steel() -> Material {
    Material::from_young_poisson(200.0, 0.3, 1.0)
}

/// Nodal values of u = G x + c (first d rows and columns of G).
fn linear_u(coords: &[[f64; 3]], d: usize) -> Vec<f64> {
    let mut u = Vec::new();
    for x in coords {
        for i in 0..d {
            u.push(C[i] + (0..d).map(|j| G[i][j] * x[j]).sum::<f64>());
        }
    }
    u
}

/// sym(G) restricted to d dimensions (plane strain: zero z row and column in 2D).
fn sym_g(d: usize) -> Tensor {
    let mut e = [[0.0; 3]; 3];
    for i in 0..d {
        for j in 0..d {
            e[i][j] = 0.5 * (G[i][j] + G[j][i]);
        }
    }
    e
}

/// sigma from the Lame parameters of docs/method.md (the problem), written out component by component.
fn sigma_expected(eps: &Tensor, mat: &Material) -> Tensor {
    let tr = eps[0][0] + eps[1][1] + eps[2][2];
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = 2.0 * mat.mu * eps[i][j] + if i == j { mat.lambda * tr } else { 0.0 };
        }
    }
    s
}

fn affine3(a: [[f64; 3]; 3], b: [f64; 3], xi: [f64; 3]) -> [f64; 3] {
    let mut x = b;
    for i in 0..3 {
        for j in 0..3 {
            x[i] += a[i][j] * xi[j];
        }
    }
    x
}

const A3: [[f64; 3]; 3] = [[1.0, 0.3, 0.1], [0.2, 1.4, -0.2], [0.1, 0.25, 0.9]];

/// Cells of every kind: (name, kind, coords), affine and distorted.
fn cells() -> Vec<(&'static str, ElementKind, Vec<[f64; 3]>)> {
    let unit_hex = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0],
        [1.0, 1.0, 1.0],
        [0.0, 1.0, 1.0],
    ];
    let perturb = [
        [0.05, -0.1, 0.02],
        [0.12, 0.03, -0.08],
        [-0.1, 0.15, 0.06],
        [0.02, -0.06, -0.1],
        [-0.07, 0.04, 0.13],
        [0.09, -0.12, 0.0],
        [0.14, 0.1, -0.05],
        [-0.04, 0.08, 0.11],
    ];
    let pp: Vec<[f64; 3]> = unit_hex.iter().map(|&x| affine3(A3, [0.3, -0.2, 0.5], x)).collect();
    let distorted_hex: Vec<[f64; 3]> = unit_hex
        .iter()
        .zip(perturb)
        .map(|(x, p)| [x[0] + p[0], x[1] + p[1], x[2] + p[2]])
        .collect();
    vec![
        (
            "skewed triangle",
            ElementKind::Tri3,
            vec![[0.1, 0.2, 0.0], [2.3, 0.5, 0.0], [0.7, 1.9, 0.0]],
        ),
        (
            "needle triangle",
            ElementKind::Tri3,
            vec![[0.0, 0.0, 0.0], [5.0, 0.1, 0.0], [2.6, 0.25, 0.0]],
        ),
        (
            "parallelogram",
            ElementKind::Quad4,
            vec![[0.0, 0.0, 0.0], [2.0, 0.5, 0.0], [2.7, 1.8, 0.0], [0.7, 1.3, 0.0]],
        ),
        (
            "distorted quad",
            ElementKind::Quad4,
            vec![[0.0, 0.0, 0.0], [2.2, 0.3, 0.0], [1.9, 1.7, 0.0], [-0.3, 1.1, 0.0]],
        ),
        (
            "skewed tet",
            ElementKind::Tet4,
            vec![[0.0, 0.0, 0.0], [1.2, 0.1, 0.2], [0.3, 1.1, -0.1], [0.2, 0.3, 0.9]],
        ),
        (
            "flat tet",
            ElementKind::Tet4,
            vec![[0.0, 0.0, 0.0], [3.0, 0.2, 0.1], [0.4, 2.5, -0.1], [1.1, 1.0, 0.15]],
        ),
        ("parallelepiped", ElementKind::Hex8, pp),
        ("distorted hex", ElementKind::Hex8, distorted_hex),
    ]
}

fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-12 * scale
}

#[test]
fn tensor6_order_is_xx_xy_xz_yy_yz_zz() {
    assert_eq!(tensor6_names(), ["xx", "xy", "xz", "yy", "yz", "zz"].map(String::from));
    let t = [[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [3.0, 5.0, 6.0]];
    assert_eq!(tensor6(&t), [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    assert_eq!(from_tensor6(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), t);
}

#[test]
fn linear_field_gives_exact_strain_and_stress_on_every_kind() {
    // The mean-dilatation element too: an affine field's dilatation is its own mean.
    for mat in [steel(), Material { mean_dilatation: true, ..steel() }] {
        linear_field_exact(mat);
    }
}

fn linear_field_exact(mat: Material) {
    for (name, kind, coords) in cells() {
        let (n, d) = (kind.n_nodes(), kind.dim());
        let u = linear_u(&coords, d);
        let eps = sym_g(d);
        let sigma = sigma_expected(&eps, &mat);
        let scale_e = 0.05;
        let scale_s = 0.05 * (mat.lambda + 2.0 * mat.mu);
        // At every point of the stress rule.
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        for p in &s[..k] {
            for i in 0..3 {
                for j in 0..3 {
                    assert!(
                        close(p.eps[i][j], eps[i][j], scale_e),
                        "{name}: eps[{i}][{j}] at a point"
                    );
                }
            }
        }
        // At arbitrary points of the cell.
        for xi in [[0.2, 0.3, 0.1], [0.05, 0.6, 0.2], [0.0, 0.0, 0.0]] {
            let e = strain_at(kind, &coords, &u, xi).unwrap();
            for i in 0..3 {
                for j in 0..3 {
                    assert!(close(e[i][j], eps[i][j], scale_e), "{name}: strain_at {xi:?}");
                }
            }
        }
        // Cell values and the nodal projection of every quantity.
        let mut lumped = [0.0; MAX_NODES];
        lumped_weights(&s[..k], n, &mut lumped);
        for q in Quantity::ALL {
            let c = q.components();
            let expected: Vec<f64> = match q {
                Quantity::Stress => tensor6(&sigma).to_vec(),
                Quantity::Strain => tensor6(&eps).to_vec(),
                Quantity::VonMises => vec![von_mises(&sigma)],
                Quantity::EffectiveStress => vec![effective_stress(&sigma, d)],
                Quantity::Pressure => vec![-(sigma[0][0] + sigma[1][1] + sigma[2][2]) / 3.0],
            };
            let scale = match q {
                Quantity::Strain => scale_e,
                Quantity::EffectiveStress => scale_s * scale_s,
                _ => scale_s,
            };
            let mut cell = [0.0; 6];
            let mut nodal = [0.0; MAX_NODES * 6];
            let measure = integrate(&s[..k], n, d, &mat, q, &mut cell, &mut nodal);
            assert!(close(measure, lumped[..n].iter().sum(), measure), "{name}: measure");
            let mut cv = [0.0; 6];
            cell_value(kind, &coords, &u, &mat, q, &mut cv).unwrap();
            for kk in 0..c {
                assert!(close(cell[kk], expected[kk], scale), "{name} {}: cell[{kk}]", q.name());
                assert!(close(cv[kk], expected[kk], scale), "{name} {}: cell_value", q.name());
                for a in 0..n {
                    let v = nodal[a * c + kk] / lumped[a];
                    assert!(close(v, expected[kk], scale), "{name} {}: node {a}", q.name());
                }
            }
        }
        // Plane strain: no out-of-plane strain, sigma_zz = nu (sigma_xx + sigma_yy).
        if d == 2 {
            let mut st = [0.0; 6];
            cell_value(kind, &coords, &u, &mat, Quantity::Strain, &mut st).unwrap();
            assert_eq!([st[2], st[4], st[5]], [0.0; 3], "{name}");
            cell_value(kind, &coords, &u, &mat, Quantity::Stress, &mut st).unwrap();
            assert!(close(st[5], 0.3 * (st[0] + st[3]), scale_s), "{name}: sigma_zz");
            assert_eq!([st[2], st[4]], [0.0; 2], "{name}");
        }
    }
}

#[test]
fn invariants_of_known_tensors() {
    let s0 = -7.5;
    let uni = [[s0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
    assert!((von_mises(&uni) - s0.abs()).abs() < 1e-14);
    assert!((pressure(&uni) - (-s0 / 3.0)).abs() < 1e-14);
    assert!((effective_stress(&uni, 3) - 2.0 / 3.0 * s0 * s0).abs() < 1e-12);
    assert!((effective_stress(&uni, 2) - s0 * s0 / 2.0).abs() < 1e-12);
    // Uniaxial along y, and along z: the same von Mises (isotropic); in 2D sigma_zz is not
    // part of the effective stress.
    let uni_y = [[0.0, 0.0, 0.0], [0.0, s0, 0.0], [0.0, 0.0, 0.0]];
    let uni_z = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, s0]];
    assert!((von_mises(&uni_y) - s0.abs()).abs() < 1e-14);
    assert!((von_mises(&uni_z) - s0.abs()).abs() < 1e-14);
    assert_eq!(effective_stress(&uni_z, 2), 0.0);
    let tau = 2.5;
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let mut shear = [[0.0; 3]; 3];
        shear[i][j] = tau;
        shear[j][i] = tau;
        assert!((von_mises(&shear) - 3f64.sqrt() * tau).abs() < 1e-14);
        assert_eq!(pressure(&shear), 0.0);
        assert!((effective_stress(&shear, 3) - 2.0 * tau * tau).abs() < 1e-13);
    }
    let p = 4.0;
    let hydro = [[-p, 0.0, 0.0], [0.0, -p, 0.0], [0.0, 0.0, -p]];
    assert!(von_mises(&hydro).abs() < 1e-14);
    assert!((pressure(&hydro) - p).abs() < 1e-14);
    assert!(effective_stress(&hydro, 3).abs() < 1e-14);
    assert!(effective_stress(&hydro, 2).abs() < 1e-14);
    // A general tensor: von Mises from the principal-free formula
    // sqrt(((sxx-syy)^2 + (syy-szz)^2 + (szz-sxx)^2)/2 + 3 (sxy^2 + syz^2 + sxz^2)).
    let t = [[3.0, 1.5, -0.5], [1.5, -2.0, 0.7], [-0.5, 0.7, 1.0]];
    let vm: f64 = (((3.0f64 + 2.0).powi(2) + (-2.0f64 - 1.0).powi(2) + (1.0f64 - 3.0).powi(2))
        / 2.0
        + 3.0 * (1.5f64.powi(2) + 0.7f64.powi(2) + 0.5f64.powi(2)))
    .sqrt();
    assert!((von_mises(&t) - vm).abs() < 1e-13);
    // 2D effective stress of the in-plane part: (sxx - m)^2 + (syy - m)^2 + 2 sxy^2, m = (sxx+syy)/2.
    let eff2 = 2.0 * (2.5f64).powi(2) + 2.0 * 1.5f64.powi(2);
    assert!((effective_stress(&t, 2) - eff2).abs() < 1e-13);
}

#[test]
fn hooke_matches_young_and_poisson() {
    let (e, nu) = (200.0, 0.3);
    let mat = Material::from_young_poisson(e, nu, 1.0);
    // A uniaxial stress state sigma = s0 e_x e_x has the strain s0/E (1, -nu, -nu).
    let s0 = 1.7;
    let eps = [[s0 / e, 0.0, 0.0], [0.0, -nu * s0 / e, 0.0], [0.0, 0.0, -nu * s0 / e]];
    let s = hooke(&eps, &mat);
    let want = [[s0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]];
    for i in 0..3 {
        for j in 0..3 {
            assert!((s[i][j] - want[i][j]).abs() < 1e-13, "{s:?}");
        }
    }
    // Shear: sigma_xy = E / (1 + nu) eps_xy = 2 mu eps_xy.
    let g = 1e-3;
    let eps = [[0.0, g, 0.0], [g, 0.0, 0.0], [0.0, 0.0, 0.0]];
    assert!((hooke(&eps, &mat)[0][1] - e / (1.0 + nu) * g).abs() < 1e-14);
    // Plane strain: sigma_zz = nu (sigma_xx + sigma_yy) for any in-plane strain.
    for eps in [
        [[1e-3, 2e-4, 0.0], [2e-4, -3e-4, 0.0], [0.0; 3]],
        [[-2e-3, 0.0, 0.0], [0.0, 5e-4, 0.0], [0.0; 3]],
    ] {
        let s = hooke(&eps, &mat);
        assert!((s[2][2] - nu * (s[0][0] + s[1][1])).abs() < 1e-13, "{s:?}");
        assert_eq!((s[0][2], s[1][2]), (0.0, 0.0));
    }
}

/// The exact average over a cell of the strain of a nodal field, by a high-order rule.
fn exact_average_strain(kind: ElementKind, coords: &[[f64; 3]], u: &[f64]) -> Tensor {
    let (n, d) = (kind.n_nodes(), kind.dim());
    let mut sum = [[0.0; 3]; 3];
    let mut vol = 0.0;
    for (xi, w) in gauss(kind, 12) {
        let mut g = [[0.0; 3]; 8];
        shape_grad_ref(kind, xi, &mut g);
        let det = crate::fem::shape::map_gradients(d, n, coords, &mut g);
        let e = strain(d, n, &g, u);
        for i in 0..3 {
            for j in 0..3 {
                sum[i][j] += w * det * e[i][j];
            }
        }
        vol += w * det;
    }
    sum.map(|r| r.map(|x| x / vol))
}

#[test]
fn q1_cell_value_is_the_cell_average_on_parallelograms() {
    // A non-linear nodal field: the strain varies over the cell, the 2 x 2 (x 2) Gauss rule
    // still integrates it exactly on parallelograms and parallelepipeds.
    let mat = steel();
    for (name, kind, coords) in
        cells().into_iter().filter(|c| c.0 == "parallelogram" || c.0 == "parallelepiped")
    {
        let d = kind.dim();
        let u: Vec<f64> =
            (0..kind.n_nodes() * d).map(|k| ((k * 7 + 3) as f64).sin() * 1e-3).collect();
        let avg = exact_average_strain(kind, &coords, &u);
        let mut cv = [0.0; 6];
        cell_value(kind, &coords, &u, &mat, Quantity::Strain, &mut cv).unwrap();
        for (k, &(i, j)) in TENSOR6.iter().enumerate() {
            assert!((cv[k] - avg[i][j]).abs() < 1e-15, "{name}: {k}: {} vs {}", cv[k], avg[i][j]);
        }
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        assert!(s[..k].windows(2).any(|w| w[0].eps != w[1].eps), "{name}: the field should vary");
    }
}

#[test]
fn lumped_weights_are_the_integrals_of_the_shape_functions() {
    for (name, kind, coords) in cells() {
        let (n, d) = (kind.n_nodes(), kind.dim());
        let u = vec![0.0; n * d];
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        let mut m = [0.0; MAX_NODES];
        lumped_weights(&s[..k], n, &mut m);
        // int_K N_a by a high-order rule.
        let mut exact = [0.0; MAX_NODES];
        for (xi, w) in gauss(kind, 12) {
            let mut nn = [0.0; 8];
            shape(kind, xi, &mut nn);
            let mut g = [[0.0; 3]; 8];
            shape_grad_ref(kind, xi, &mut g);
            let det = crate::fem::shape::map_gradients(d, n, &coords, &mut g);
            for a in 0..n {
                exact[a] += w * det * nn[a];
            }
        }
        let vol: f64 = exact[..n].iter().sum();
        for a in 0..n {
            // Exact on every cell: det J N_a has degree <= 2 (2D) or 3 (3D) per direction.
            assert!(
                (m[a] - exact[a]).abs() <= 1e-13 * vol,
                "{name}: node {a}: {} vs {}",
                m[a],
                exact[a]
            );
        }
        if matches!(kind, ElementKind::Tri3 | ElementKind::Tet4) {
            for a in 0..n {
                assert!((m[a] - vol / (d + 1) as f64).abs() < 1e-14 * vol, "{name}");
            }
        }
    }
}

#[test]
fn inverted_cells_are_errors() {
    let coords = [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]];
    let mut s = [Sample::default(); MAX_SAMPLES];
    let e = samples(ElementKind::Tri3, &coords, &[0.0; 6], &mut s).unwrap_err();
    assert!(e.to_string().contains("inverted"), "{e}");
}

#[test]
fn q1_cell_value_is_the_jacobian_weighted_mean_on_distorted_cells() {
    // On distorted Q1 cells the 2 x 2 (x 2) Gauss values of a non-linear field are averaged
    // with the weights w_q det J_q (not a plain mean of the points); the nodal numerators carry
    // the same weights times N_a.
    let mat = steel();
    for (name, kind, coords) in cells().into_iter().filter(|c| c.0.starts_with("distorted")) {
        let (n, d) = (kind.n_nodes(), kind.dim());
        let u: Vec<f64> = (0..n * d).map(|k| ((k * 5 + 1) as f64).cos() * 1e-3).collect();
        let (mut sum, mut vol) = ([0.0; 6], 0.0);
        let mut num = vec![[0.0; 6]; n];
        let mut dets = Vec::new();
        for (xi, w) in gauss(kind, 2) {
            let mut g = [[0.0; 3]; 8];
            let det = crate::fem::shape::physical_gradients(kind, &coords, xi, &mut g);
            let mut nn = [0.0; 8];
            shape(kind, xi, &mut nn);
            let s = tensor6(&hooke(&strain(d, n, &g, &u), &mat));
            for k in 0..6 {
                sum[k] += w * det * s[k];
                for a in 0..n {
                    num[a][k] += w * det * nn[a] * s[k];
                }
            }
            vol += w * det;
            dets.push(det);
        }
        assert!(dets.windows(2).any(|p| (p[0] - p[1]).abs() > 1e-3 * p[0]), "{name}: det J varies");
        let mut cell = [0.0; 6];
        let mut nodal = [0.0; MAX_NODES * 6];
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        let m = integrate(&s[..k], n, d, &mat, Quantity::Stress, &mut cell, &mut nodal);
        assert!((m - vol).abs() < 1e-14 * vol, "{name}");
        let scale = cell.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        for kk in 0..6 {
            assert!((cell[kk] - sum[kk] / vol).abs() < 1e-13 * scale, "{name}: {kk}");
            for a in 0..n {
                assert!(
                    (nodal[a * 6 + kk] - num[a][kk]).abs() < 1e-13 * scale * vol,
                    "{name}: node {a}"
                );
            }
        }
    }
}

/// The finite-strain stress output with the mean dilatation (neo-Hooke, `formulation =
/// "mixed"`): a homogeneous deformation has its own Jacobian as the cell's mean, so the stress
/// is the point-wise law's; under a non-homogeneous one the mixed pressure differs from the
/// point-wise law without lambda by one constant over the cell (the cell's pressure
/// `lambda ln(theta)/theta`), at every point and node.
#[test]
fn finite_strain_mixed_stress_has_the_cell_pressure() {
    use crate::fem::hyperelastic::{Law, Model};
    let m = Material::from_young_poisson(200.0, 0.45, 1.0);
    let plain = Law::new(Model::NeoHookean, &m);
    let mixed = Law::new(Model::NeoHookean, &Material { mean_dilatation: true, ..m });
    let no_lambda = Law { lambda: 0.0, ..plain };
    for (name, kind, coords) in cells().into_iter().filter(|c| !c.1.is_simplex()) {
        let (n, d) = (kind.n_nodes(), kind.dim());
        // Homogeneous: u = (F - I) X with a finite stretch and shear.
        let f = [[1.2, 0.3, 0.1], [-0.1, 0.9, 0.2], [0.05, 0.1, 1.1]];
        let u: Vec<f64> = coords
            .iter()
            .flat_map(|x| (0..d).map(move |i| (0..d).map(|j| f[i][j] * x[j]).sum::<f64>() - x[i]))
            .collect();
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        let (mut a, mut b) = ([0.0; 6], [0.0; 6]);
        let mut nodal = [0.0; MAX_NODES * 6];
        integrate_finite(&s[..k], n, d, &plain, Quantity::Stress, &mut a, &mut nodal);
        integrate_finite(&s[..k], n, d, &mixed, Quantity::Stress, &mut b, &mut nodal);
        for c in 0..6 {
            assert!(
                close(a[c], b[c], m.lambda),
                "{name}: homogeneous stress[{c}] {} vs {}",
                a[c],
                b[c]
            );
        }
        // Non-homogeneous: a bilinear (trilinear) field on top.
        let u: Vec<f64> =
            u.iter().enumerate().map(|(r, v)| v + 0.05 * ((r * 7 % 5) as f64 - 2.0)).collect();
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        let mut shift = Vec::new();
        for law in [&mixed, &no_lambda] {
            let (mut cell, mut nodal) = ([0.0; 6], [0.0; MAX_NODES * 6]);
            integrate_finite(&s[..k], n, d, law, Quantity::Pressure, &mut cell, &mut nodal);
            let mut lumped = [0.0; MAX_NODES];
            lumped_weights(&s[..k], n, &mut lumped);
            shift.push((0..n).map(|a| nodal[a] / lumped[a]).collect::<Vec<f64>>());
        }
        let diff: Vec<f64> = (0..n).map(|a| shift[0][a] - shift[1][a]).collect();
        for a in 1..n {
            assert!(
                close(diff[a], diff[0], m.lambda),
                "{name}: the cell pressure varies: {diff:?}"
            );
        }
        assert!(diff[0].abs() > 1e-3 * m.lambda, "{name}: no cell pressure: {diff:?}");
        // The plain law's pressure is not one constant away from the point-wise mu part.
        let (mut cell, mut nodal) = ([0.0; 6], [0.0; MAX_NODES * 6]);
        integrate_finite(&s[..k], n, d, &plain, Quantity::Pressure, &mut cell, &mut nodal);
        let mut lumped = [0.0; MAX_NODES];
        lumped_weights(&s[..k], n, &mut lumped);
        let plain_diff: Vec<f64> = (0..n).map(|a| nodal[a] / lumped[a] - shift[1][a]).collect();
        let spread = plain_diff.iter().fold(0.0f64, |x, v| x.max((v - plain_diff[0]).abs()));
        assert!(spread > 1e-6 * m.lambda, "{name}: the field is too tame to tell: {plain_diff:?}");
    }
}

/// The mixed formulations' pressure part: with the field's own dilatation the stress is
/// Hooke's; with another dilatation `theta` only the pressure moves, by `-lambda (theta -
/// tr eps)` (the deviatoric stress is the field's).
#[test]
fn a_given_dilatation_moves_only_the_pressure() {
    let mat = Material { mean_dilatation: true, ..Material::from_young_poisson(2.0, 0.4999, 1.0) };
    for (name, kind, coords) in cells() {
        let d = kind.dim();
        let u = linear_u(&coords, d);
        let tr: f64 = (0..3).map(|i| sym_g(d)[i][i]).sum();
        let mut s = [Sample::default(); MAX_SAMPLES];
        let k = samples(kind, &coords, &u, &mut s).unwrap();
        let n = kind.n_nodes();
        let (mut c0, mut c1, mut nv) = ([0.0; 6], [0.0; 6], [0.0; MAX_NODES * 6]);
        let plain = Material { mean_dilatation: false, ..mat };
        integrate(&s[..k], n, d, &plain, Quantity::Stress, &mut c0, &mut nv);
        integrate_dilatation(&s[..k], n, d, &mat, tr, Quantity::Stress, &mut c1, &mut nv);
        let scale = mat.lambda * 0.05;
        assert!((0..6).all(|i| close(c0[i], c1[i], scale)), "{name}: {c0:?} {c1:?}");
        for theta in [0.0, 0.01] {
            let (mut p, mut dev) = ([0.0; 1], [0.0; 1]);
            integrate_dilatation(&s[..k], n, d, &mat, theta, Quantity::Pressure, &mut p, &mut nv);
            let shift = -mat.lambda * (theta - tr);
            let (mut p0, mut dev0) = ([0.0; 1], [0.0; 1]);
            integrate(&s[..k], n, d, &plain, Quantity::Pressure, &mut p0, &mut nv);
            assert!(close(p[0], p0[0] + shift, scale), "{name}: pressure {} {}", p[0], p0[0]);
            integrate_dilatation(&s[..k], n, d, &mat, theta, Quantity::VonMises, &mut dev, &mut nv);
            integrate(&s[..k], n, d, &plain, Quantity::VonMises, &mut dev0, &mut nv);
            assert!(close(dev[0], dev0[0], scale), "{name}: von Mises {} {}", dev[0], dev0[0]);
        }
    }
}
