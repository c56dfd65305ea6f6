//! Checks of the finite-strain kernels from theory: rigid motions carry no energy or stress,
//! the algorithmic force is the exact discrete gradient of the energy and keeps momentum and
//! angular momentum, and the tangent equals central differences of the force.

use super::*;
use crate::fem::kernels::{stiffness, Material};
use crate::fem::shape::reference_node;

const CELLS: [ElementKind; 4] =
    [ElementKind::Tri3, ElementKind::Quad4, ElementKind::Tet4, ElementKind::Hex8];
const MODELS: [Model; 2] = [Model::NeoHookean, Model::SaintVenantKirchhoff];

fn law(model: Model) -> Law {
    Law::new(model, &Material::from_young_poisson(200.0, 0.3, 1.0))
}

/// The laws of the element checks: each model, and neo-Hooke with the mean dilatation (the
/// point-wise law on simplices, the cell's volumetric term on Q1 cells) nearly incompressible.
fn laws() -> Vec<(String, Law)> {
    let mut v: Vec<(String, Law)> = MODELS.iter().map(|&m| (format!("{m:?}"), law(m))).collect();
    let m = Material { mean_dilatation: true, ..Material::from_young_poisson(200.0, 0.49, 1.0) };
    v.push(("NeoHookean mixed".into(), Law::new(Model::NeoHookean, &m)));
    v
}

/// A small deterministic generator (no dependency): uniform in [-1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// A distorted cell: the reference nodes, scaled, sheared and moved a little.
fn cell(kind: ElementKind, rng: &mut Rng) -> Vec<[f64; 3]> {
    let d = kind.dim();
    (0..kind.n_nodes())
        .map(|a| {
            let r = reference_node(kind, a);
            let mut x = [0.0; 3];
            for i in 0..d {
                x[i] = 0.7 * r[i] + 0.2 * r[(i + 1) % d] + 0.03 * rng.next() + 1.0;
            }
            x
        })
        .collect()
}

/// Rotation by `theta` about the axis `(1, 2, 3)/|..|` in 3D, about z in 2D.
fn rotation_matrix(d: usize, theta: f64) -> Tensor {
    let (c, s) = (theta.cos(), theta.sin());
    if d == 2 {
        return [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
    }
    let n = 14f64.sqrt();
    let k = [1.0 / n, 2.0 / n, 3.0 / n];
    let mut r = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let kx = match (i, j) {
                (0, 1) => -k[2],
                (1, 0) => k[2],
                (0, 2) => k[1],
                (2, 0) => -k[1],
                (1, 2) => -k[0],
                (2, 1) => k[0],
                _ => 0.0,
            };
            r[i][j] = c * if i == j { 1.0 } else { 0.0 } + s * kx + (1.0 - c) * k[i] * k[j];
        }
    }
    r
}

/// Nodal displacements `u_a = (F - I) X_a + eps noise_a`.
fn displacement(x: &[[f64; 3]], d: usize, f: &Tensor, eps: f64, rng: &mut Rng) -> Vec<f64> {
    let mut u = vec![0.0; x.len() * d];
    for (a, xa) in x.iter().enumerate() {
        for i in 0..d {
            let mut v = -xa[i];
            for j in 0..d {
                v += f[i][j] * xa[j];
            }
            u[a * d + i] = v + eps * rng.next();
        }
    }
    u
}

/// A random deformation gradient near a rotation: `R (I + 0.25 sym(random))`.
fn random_f(d: usize, rng: &mut Rng) -> Tensor {
    let r = rotation_matrix(d, 1.3 * rng.next());
    let mut s = identity();
    for i in 0..d {
        for j in i..d {
            let v = 0.25 * rng.next();
            s[i][j] += v;
            if i != j {
                s[j][i] += v;
            }
        }
    }
    let mut f = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            for k in 0..3 {
                f[i][j] += r[i][k] * s[k][j];
            }
        }
    }
    f
}

fn force(kind: ElementKind, x: &[[f64; 3]], law: &Law, u0: &[f64], u1: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; u0.len()];
    midpoint_force(kind, x, law, u0, u1, &mut f, None).expect("not inverted");
    f
}

#[test]
fn a_rigid_rotation_of_ninety_degrees_has_no_energy_and_no_stress() {
    let mut rng = Rng(7);
    for kind in CELLS {
        let d = kind.dim();
        let x = cell(kind, &mut rng);
        let r = rotation_matrix(d, std::f64::consts::FRAC_PI_2);
        let u = displacement(&x, d, &r, 0.0, &mut rng);
        for (model, law) in laws() {
            let e = strain_energy(kind, &x, &law, &u).expect("not inverted");
            // Round-off of a unit strain's stress, lambda + 2 mu = 269 at nu = 0.3 (the
            // energy scale of a unit strain on this cell: mu |K| ~ 77 * 0.5).
            let tol = 4e-15 * (law.lambda + 2.0 * law.mu);
            assert!(e.abs() < tol, "{kind:?} {model:?}: energy {e:e} of a rigid rotation");
            let f = force(kind, &x, &law, &u, &u);
            let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(fmax < tol, "{kind:?} {model:?}: force {fmax:e} of a rigid rotation");
            let fx = deformation_gradient_at(kind, &x, &u, [0.2, 0.1, 0.1]);
            let sigma = cauchy_stress(&law, &fx);
            let smax = sigma.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(smax < tol, "{kind:?} {model:?}: Cauchy stress {smax:e}");
        }
        // The small-strain energy of the same motion is 1/2 u.K u = |K| 2 (1 - cos)^2
        // (lambda + mu) for a rotation about z (strain (cos - 1) I in the plane of rotation):
        // at 90 degrees 2 (lambda + mu) per unit volume, the growth the linear model sees.
        let rz = {
            let (c, s) = (0.0f64, 1.0f64);
            [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
        };
        let uz = displacement(&x, d, &rz, 0.0, &mut rng);
        let m = Material::from_young_poisson(200.0, 0.3, 1.0);
        let nd = x.len() * d;
        let mut k = vec![0.0; nd * nd];
        stiffness(kind, &x, &m, &mut k).expect("valid cell");
        let mut e = 0.0;
        for i in 0..nd {
            for j in 0..nd {
                e += 0.5 * uz[i] * k[i * nd + j] * uz[j];
            }
        }
        let volume = crate::fem::measure(kind, &x);
        let want = volume * 2.0 * (m.lambda + m.mu);
        assert!((e - want).abs() < 1e-10 * want, "{kind:?}: linear energy {e} against {want}");
    }
}

#[test]
fn the_midpoint_force_is_the_exact_discrete_gradient_of_the_energy() {
    let mut rng = Rng(11);
    for kind in CELLS {
        let d = kind.dim();
        for (model, law) in laws() {
            for _ in 0..5 {
                let x = cell(kind, &mut rng);
                let u0 = displacement(&x, d, &random_f(d, &mut rng), 0.02, &mut rng);
                let u1 = displacement(&x, d, &random_f(d, &mut rng), 0.02, &mut rng);
                let mut f = vec![0.0; u0.len()];
                let step = midpoint_force(kind, &x, &law, &u0, &u1, &mut f, None).unwrap();
                let work: f64 =
                    f.iter().zip(u1.iter().zip(&u0)).map(|(f, (a, b))| f * (a - b)).sum();
                let dw = step.w1 - step.w0;
                let scale = step.w1.abs() + step.w0.abs();
                assert!(
                    (work - dw).abs() < 1e-13 * scale,
                    "{kind:?} {model:?}: f.du {work} against dW {dw}"
                );
                // Momentum: the forces sum to zero; angular momentum: sum x_m x f = 0.
                let mut sum = [0.0f64; 3];
                let mut moment = [0.0f64; 3];
                for a in 0..x.len() {
                    let mut xm = [0.0; 3];
                    let mut fa = [0.0; 3];
                    for i in 0..d {
                        xm[i] = x[a][i] + 0.5 * (u0[a * d + i] + u1[a * d + i]);
                        fa[i] = f[a * d + i];
                        sum[i] += fa[i];
                    }
                    moment[0] += xm[1] * fa[2] - xm[2] * fa[1];
                    moment[1] += xm[2] * fa[0] - xm[0] * fa[2];
                    moment[2] += xm[0] * fa[1] - xm[1] * fa[0];
                }
                let fmax = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for i in 0..3 {
                    assert!(sum[i].abs() < 1e-12 * fmax, "{kind:?} {model:?}: sum f {sum:?}");
                    assert!(
                        moment[i].abs() < 1e-12 * fmax * 3.0,
                        "{kind:?} {model:?}: moment {moment:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn the_tangent_equals_central_differences_of_the_force() {
    let mut rng = Rng(3);
    for kind in CELLS {
        let d = kind.dim();
        for (model, law) in laws() {
            let x = cell(kind, &mut rng);
            let u0 = displacement(&x, d, &random_f(d, &mut rng), 0.02, &mut rng);
            let u1 = displacement(&x, d, &random_f(d, &mut rng), 0.02, &mut rng);
            let nd = u0.len();
            let mut f = vec![0.0; nd];
            let mut k = vec![0.0; nd * nd];
            midpoint_force(kind, &x, &law, &u0, &u1, &mut f, Some(&mut k)).unwrap();
            let h = 1e-6;
            let kmax = k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            for j in 0..nd {
                let mut up = u1.clone();
                let mut um = u1.clone();
                up[j] += h;
                um[j] -= h;
                let fp = force(kind, &x, &law, &u0, &up);
                let fm = force(kind, &x, &law, &u0, &um);
                for i in 0..nd {
                    let fd = (fp[i] - fm[i]) / (2.0 * h);
                    let an = k[i * nd + j];
                    assert!(
                        (fd - an).abs() < 1e-6 * kmax,
                        "{kind:?} {model:?}: K[{i}][{j}] = {an} against {fd}"
                    );
                }
            }
        }
    }
}

#[test]
fn at_one_state_the_algorithmic_stress_is_two_dw_dc() {
    let mut rng = Rng(5);
    for model in MODELS {
        let law = law(model);
        let f = random_f(3, &mut rng);
        let c = right_cauchy_green(&f);
        let s = law.stress(&c);
        let sa = law.midpoint_stress(&c, &c);
        let h = 1e-6;
        for i in 0..3 {
            for j in 0..3 {
                assert!(
                    (s[i][j] - sa[i][j]).abs() < 1e-12 * law.mu,
                    "{model:?}: S_alg(C, C) != S(C)"
                );
                // S_ij = 2 dW/dC_ij, C perturbed symmetrically.
                let (mut cp, mut cm) = (c, c);
                let step = if i == j { h } else { 0.5 * h };
                cp[i][j] += step;
                cm[i][j] -= step;
                if i != j {
                    cp[j][i] += step;
                    cm[j][i] -= step;
                }
                // Off the diagonal both C_ij and C_ji move by h/2: the quotient is dW/dC_ij.
                let dw = (law.energy(&cp).unwrap() - law.energy(&cm).unwrap()) / (2.0 * h);
                let want = 2.0 * dw;
                assert!(
                    (s[i][j] - want).abs() < 1e-6 * law.mu,
                    "{model:?}: S[{i}][{j}] {} against {want}",
                    s[i][j]
                );
            }
        }
    }
}

#[test]
fn the_neo_hooke_quotient_has_no_cancellation_when_the_step_is_tiny() {
    let law = law(Model::NeoHookean);
    let mut rng = Rng(9);
    let f = random_f(3, &mut rng);
    let c0 = right_cauchy_green(&f);
    for eps in [1e-4, 1e-8, 1e-12, 1e-15, 0.0] {
        let mut c1 = c0;
        c1[0][0] += eps;
        let ca = lin(0.5, &c0, 0.5, &c1);
        let sa = law.midpoint_stress(&c0, &c1);
        let s = law.stress(&ca);
        for i in 0..3 {
            for j in 0..3 {
                // The discrete gradient differs from S(C_a) by O(|dC|^2).
                assert!(
                    (sa[i][j] - s[i][j]).abs() < 1e-12 * law.lambda + law.lambda * eps * eps,
                    "dC = {eps:e}: S_alg {} against S(C_a) {}",
                    sa[i][j],
                    s[i][j]
                );
            }
        }
    }
}

#[test]
fn the_polar_rotation_recovers_the_rotation_of_a_stretch() {
    for d in [2, 3] {
        let r = rotation_matrix(d, 0.7);
        let u = [[1.2, 0.1, 0.0], [0.1, 0.9, 0.05], [0.0, 0.05, 1.1]];
        let u = if d == 2 { [[1.2, 0.1, 0.0], [0.1, 0.9, 0.0], [0.0, 0.0, 1.0]] } else { u };
        let mut f = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    f[i][j] += r[i][k] * u[k][j];
                }
            }
        }
        let got = rotation(&f);
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[i][j] - r[i][j]).abs() < 1e-12, "d = {d}: R {got:?} against {r:?}");
            }
        }
        assert!((rotation_angle_degrees(&got) - 0.7f64.to_degrees()).abs() < 1e-9);
    }
}

#[test]
fn an_inverted_state_is_an_error_not_a_nan() {
    let mut rng = Rng(1);
    for kind in CELLS {
        let d = kind.dim();
        let x = cell(kind, &mut rng);
        // A reflection: det F = -1.
        let mut f = identity();
        f[0][0] = -1.0;
        let u = displacement(&x, d, &f, 0.0, &mut rng);
        let zero = vec![0.0; u.len()];
        let mut out = vec![0.0; u.len()];
        for model in MODELS {
            let e = midpoint_force(kind, &x, &law(model), &zero, &u, &mut out, None);
            assert!(matches!(e, Err(Inverted { state: 1, .. })), "{kind:?} {model:?}");
        }
    }
}

/// At the reference state the static tangent (twice the midpoint one with both states equal)
/// is the small-strain stiffness, the mean-dilatation one for the mixed law: the finite-strain
/// mixed element linearizes to the B-bar element.
#[test]
fn the_mixed_law_linearizes_to_the_mean_dilatation_stiffness() {
    let mut rng = Rng(13);
    for kind in [ElementKind::Quad4, ElementKind::Hex8] {
        let x = cell(kind, &mut rng);
        let nd = x.len() * kind.dim();
        let m =
            Material { mean_dilatation: true, ..Material::from_young_poisson(200.0, 0.49, 1.0) };
        let zero = vec![0.0; nd];
        let (mut f, mut k) = (vec![0.0; nd], vec![0.0; nd * nd]);
        midpoint_force(
            kind,
            &x,
            &Law::new(Model::NeoHookean, &m),
            &zero,
            &zero,
            &mut f,
            Some(&mut k),
        )
        .unwrap();
        let mut kb = vec![0.0; nd * nd];
        stiffness(kind, &x, &m, &mut kb).unwrap();
        let kmax = kb.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        for i in 0..nd * nd {
            assert!((2.0 * k[i] - kb[i]).abs() < 1e-12 * kmax, "{kind:?} entry {i}");
        }
    }
}
