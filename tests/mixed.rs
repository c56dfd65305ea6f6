//! Nearly incompressible bodies: the mixed (mean-dilatation, Q1/P0) formulation against the
//! displacement one.
//!
//! Cook's membrane is a static problem: it is assembled here from the element kernels the runs
//! use (`fem::stiffness`) and solved exactly (banded Cholesky), so the test measures the
//! discretization alone.

use massfree::fem::{divergence_row, gauss, physical_gradients, stiffness, ElementKind, Material};
use massfree::report::RunSummary;

/// Cook's membrane: the trapezoid (0, 0), (48, 44), (48, 60), (0, 44), clamped at x = 0, a
/// uniform vertical traction of total force `force` on the edge x = 48; plane strain, `n x n`
/// bilinear quadrilaterals of the bilinear map of the unit square. Returns the vertical
/// displacement of the upper right corner (48, 60).
fn cook_tip(n: usize, e: f64, nu: f64, mixed: bool, force: f64) -> f64 {
    cook(n, e, nu, mixed, force).0
}

/// Node (i along x, j across) of Cook's `n x n` grid, numbered j fastest (the band is about
/// 2 (n + 2) DOFs), and its position.
fn cook_node(n: usize, i: usize, j: usize) -> (usize, [f64; 3]) {
    let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
    let (lo, hi) = (44.0 * s, 44.0 + 16.0 * s);
    (i * (n + 1) + j, [48.0 * s, lo + t * (hi - lo), 0.0])
}

/// The corners of grid cell (i, j), counterclockwise from (i, j).
fn cook_corners(i: usize, j: usize) -> [(usize, usize); 4] {
    [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
}

/// Cook's membrane solved on the grid's quadrilaterals (`ElementKind::Quad4`) or on its
/// triangles (`Tri3`, each cell cut along the diagonal from (i, j)); with `mixed` the
/// quadrilaterals take the mean dilatation and the triangles the averaged nodal pressure (its
/// own implementation here: `G^T diag(lambda / V_a) G` with `(G u)_a = sum_K |K|/3 div u_K`,
/// `V_a = sum_K |K|/3`). Returns the displacements (node * 2 + component).
/// The membrane's load vector (`stride` unknowns per node, the first two the displacement):
/// the traction `force / 16` per unit length on the right edge, lumped to its nodes (exact for
/// a constant traction on straight segments); the left edge clamped (identity rows and
/// columns in `k`).
fn cook_load_and_clamp(k: &mut Banded, n: usize, force: f64, stride: usize) -> Vec<f64> {
    let mut f = vec![0.0; stride * (n + 1) * (n + 1)];
    let h = 16.0 / n as f64;
    for j in 0..n {
        f[stride * cook_node(n, n, j).0 + 1] += 0.5 * force / 16.0 * h;
        f[stride * cook_node(n, n, j + 1).0 + 1] += 0.5 * force / 16.0 * h;
    }
    for j in 0..=n {
        for p in 0..2 {
            k.fix(stride * cook_node(n, 0, j).0 + p);
        }
    }
    f
}

fn cook_solve(n: usize, kind: ElementKind, m: &Material, force: f64) -> Vec<f64> {
    let np = n + 1;
    let dofs = 2 * np * np;
    let nodal = kind == ElementKind::Tri3 && m.mean_dilatation;
    // The nodal pressure couples nodes two cells apart.
    let band = if nodal { 2 * (2 * np + 3) } else { 2 * (np + 2) };
    let mut k = Banded::new(dofs, band);
    let cells: Vec<Vec<(usize, usize)>> = (0..n * n)
        .flat_map(|c| {
            let q = cook_corners(c / n, c % n);
            match kind {
                ElementKind::Quad4 => vec![q.to_vec()],
                _ => vec![vec![q[0], q[1], q[2]], vec![q[0], q[2], q[3]]],
            }
        })
        .collect();
    let cell_material = if nodal { Material { lambda: 0.0, ..*m } } else { *m };
    // Per node: its patch's volume and divergence row (DOF, value).
    let mut volume = vec![0.0; np * np];
    let mut rows: Vec<std::collections::BTreeMap<usize, f64>> = vec![Default::default(); np * np];
    let mut ke = [0.0; 64];
    for cell in &cells {
        let (nodes, coords): (Vec<usize>, Vec<[f64; 3]>) =
            cell.iter().map(|&(i, j)| cook_node(n, i, j)).unzip();
        let nd = 2 * nodes.len();
        stiffness(kind, &coords, &cell_material, &mut ke[..nd * nd]).expect("a valid cell");
        for a in 0..nodes.len() {
            for b in 0..nodes.len() {
                for (p, q) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    k.add(2 * nodes[a] + p, 2 * nodes[b] + q, ke[(2 * a + p) * nd + 2 * b + q]);
                }
            }
        }
        if nodal {
            let mut b = [[0.0; 3]; 3];
            let vol = divergence_row(kind, &coords, &mut b).expect("a valid cell");
            for &a in &nodes {
                volume[a] += vol / 3.0;
                for (c, bc) in nodes.iter().zip(&b) {
                    for (p, x) in bc[..2].iter().enumerate() {
                        *rows[a].entry(2 * c + p).or_default() += x / 3.0;
                    }
                }
            }
        }
    }
    for (row, v) in rows.iter().zip(&volume) {
        for (&i, &gi) in row {
            for (&j, &gj) in row {
                k.add(i, j, m.lambda / v * gi * gj);
            }
        }
    }
    let f = cook_load_and_clamp(&mut k, n, force, 2);
    k.solve(f)
}

/// [`cook_tip`] and each cell's mean pressure `-(lambda + 2 mu/3) theta_bar` (cell `i * n + j`,
/// `i` along x): the mixed element's constant pressure, the displacement element's cell mean.
fn cook(n: usize, e: f64, nu: f64, mixed: bool, force: f64) -> (f64, Vec<f64>) {
    let m = Material { mean_dilatation: mixed, ..Material::from_young_poisson(e, nu, 1.0) };
    let u = cook_solve(n, ElementKind::Quad4, &m, force);
    let mut pressure = Vec::with_capacity(n * n);
    for c in 0..n * n {
        let (nodes, coords): (Vec<usize>, Vec<[f64; 3]>) =
            cook_corners(c / n, c % n).iter().map(|&(i, j)| cook_node(n, i, j)).unzip();
        let (mut theta, mut volume) = (0.0, 0.0);
        for (xi, w) in gauss(ElementKind::Quad4, 2) {
            let mut g = [[0.0; 3]; 4];
            let det = physical_gradients(ElementKind::Quad4, &coords, xi, &mut g);
            volume += w * det;
            for a in 0..4 {
                theta += w * det * (g[a][0] * u[2 * nodes[a]] + g[a][1] * u[2 * nodes[a] + 1]);
            }
        }
        pressure.push(-(m.lambda + 2.0 * m.mu / 3.0) * theta / volume);
    }
    (u[2 * cook_node(n, n, n).0 + 1], pressure)
}

/// A symmetric banded matrix (lower band stored) and its Cholesky solve.
struct Banded {
    n: usize,
    b: usize,
    /// `l[i * (b + 1) + (i - j)]` holds entry (i, j), `i - b <= j <= i`.
    l: Vec<f64>,
}

impl Banded {
    fn new(n: usize, b: usize) -> Banded {
        Banded { n, b, l: vec![0.0; n * (b + 1)] }
    }

    fn add(&mut self, i: usize, j: usize, v: f64) {
        if j <= i {
            assert!(i - j <= self.b, "outside the band");
            self.l[i * (self.b + 1) + (i - j)] += v;
        }
    }

    fn fix(&mut self, i: usize) {
        let w = self.b + 1;
        for d in 0..=self.b.min(i) {
            self.l[i * w + d] = 0.0;
        }
        for r in i + 1..(i + self.b + 1).min(self.n) {
            self.l[r * w + (r - i)] = 0.0;
        }
        self.l[i * w] = 1.0;
    }

    #[allow(clippy::needless_range_loop)] // index-heavy banded algebra
    fn solve(mut self, mut x: Vec<f64>) -> Vec<f64> {
        let (n, b, w) = (self.n, self.b, self.b + 1);
        for i in 0..n {
            for j in i.saturating_sub(b)..=i {
                let mut s = self.l[i * w + (i - j)];
                for k in i.saturating_sub(b).max(j.saturating_sub(b))..j {
                    s -= self.l[i * w + (i - k)] * self.l[j * w + (j - k)];
                }
                if i == j {
                    assert!(s > 0.0, "not positive definite at row {i}");
                    self.l[i * w] = s.sqrt();
                } else {
                    self.l[i * w + (i - j)] = s / self.l[j * w];
                }
            }
        }
        for i in 0..n {
            let mut s = x[i];
            for k in i.saturating_sub(b)..i {
                s -= self.l[i * w + (i - k)] * x[k];
            }
            x[i] = s / self.l[i * w];
        }
        for i in (0..n).rev() {
            let mut s = x[i];
            for r in i + 1..(i + b + 1).min(n) {
                s -= self.l[r * w + (r - i)] * x[r];
            }
            x[i] = s / self.l[i * w];
        }
        x
    }
}

impl Banded {
    /// `L D L^T` without pivoting: for quasi-definite matrices (`[A B^T; B -C]`, `A` and `C`
    /// positive definite), whose factorization exists in every symmetric ordering (Vanderbei
    /// 1995), e.g. a stabilized saddle point with its unknowns interleaved node by node.
    #[allow(clippy::needless_range_loop)] // index-heavy banded algebra
    fn solve_quasi_definite(mut self, mut x: Vec<f64>) -> Vec<f64> {
        let (n, b, w) = (self.n, self.b, self.b + 1);
        let mut lik = vec![0.0; w];
        for i in 0..n {
            let lo = i.saturating_sub(b);
            // lik[k - lo] = l_ik d_k for the finished columns k < i.
            for j in lo..=i {
                let mut s = self.l[i * w + (i - j)];
                for k in lo.max(j.saturating_sub(b))..j {
                    s -= lik[k - lo] * self.l[j * w + (j - k)];
                }
                if i == j {
                    assert!(s != 0.0 && s.is_finite(), "zero pivot at row {i}");
                    self.l[i * w] = s;
                } else {
                    lik[j - lo] = s;
                    self.l[i * w + (i - j)] = s / self.l[j * w];
                }
            }
        }
        for i in 0..n {
            for k in i.saturating_sub(b)..i {
                x[i] -= self.l[i * w + (i - k)] * x[k];
            }
        }
        for i in 0..n {
            x[i] /= self.l[i * w];
        }
        for i in (0..n).rev() {
            for r in i + 1..(i + b + 1).min(n) {
                x[i] -= self.l[r * w + (r - i)] * x[r];
            }
        }
        x
    }
}

/// Cook's membrane of triangles (cut as in [`cook_solve`]) with the stabilized equal-order
/// P1/P1 mixed form, the alternative to the averaged nodal pressure: a continuous linear
/// pressure `p` beside `u`,
///
/// ```text
/// 2 mu (eps(u), eps(v)) + (p, div v) = f(v)
/// (div u, q) - (p, q) / lambda - S(p, q) = 0,   S(p, q) = (p - P0 p, q - P0 q) / mu
/// ```
///
/// with `P0` the projection onto constants per cell (Dohrmann and Bochev 2004: the
/// polynomial pressure projection, free of parameters beyond the scaling by `1/mu`). The system
/// is quasi-definite (`A` positive definite once clamped, `(p, q)/lambda + S` positive
/// definite), solved by a banded `L D L^T` with the unknowns (u_x, u_y, p) node by node.
/// Returns the tip displacement and the nodal pressures.
fn cook_p1p1(n: usize, m: &Material, force: f64) -> (f64, Vec<f64>) {
    let np = n + 1;
    let dofs = 3 * np * np;
    let mut k = Banded::new(dofs, 3 * (np + 2));
    let shear = Material { lambda: 0.0, ..*m };
    let mut ke = [0.0; 36];
    for c in 0..n * n {
        let q = cook_corners(c / n, c % n);
        for cell in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            let (nodes, coords): (Vec<usize>, Vec<[f64; 3]>) =
                cell.iter().map(|&(i, j)| cook_node(n, i, j)).unzip();
            stiffness(ElementKind::Tri3, &coords, &shear, &mut ke).expect("a valid cell");
            let mut b = [[0.0; 3]; 3];
            let area = divergence_row(ElementKind::Tri3, &coords, &mut b).expect("a valid cell");
            for a in 0..3 {
                for c2 in 0..3 {
                    for (pi, qi) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        let v = ke[(2 * a + pi) * 6 + 2 * c2 + qi];
                        k.add(3 * nodes[a] + pi, 3 * nodes[c2] + qi, v);
                    }
                    // (p, div v): int_K phi_a div u = |K|/3 div u_K = sum_b b_b . u_b / 3.
                    for pi in 0..2 {
                        let v = b[c2][pi] / 3.0;
                        k.add(3 * nodes[a] + 2, 3 * nodes[c2] + pi, v);
                        k.add(3 * nodes[c2] + pi, 3 * nodes[a] + 2, v);
                    }
                    // -(p, q)/lambda - S: the P1 mass |K|/12 (1 + delta), its mean part |K|/9.
                    let mass = area / 12.0 * if a == c2 { 2.0 } else { 1.0 };
                    let v = -mass / m.lambda - (mass - area / 9.0) / m.mu;
                    k.add(3 * nodes[a] + 2, 3 * nodes[c2] + 2, v);
                }
            }
        }
    }
    let f = cook_load_and_clamp(&mut k, n, force, 3);
    let x = k.solve_quasi_definite(f);
    let pressure = (0..np * np).map(|a| x[3 * a + 2]).collect();
    (x[3 * cook_node(n, n, n).0 + 1], pressure)
}

/// The tip displacement on the meshes 4 x 4 ... 64 x 64.
fn tips(e: f64, nu: f64, mixed: bool, force: f64) -> Vec<f64> {
    [4usize, 8, 16, 32, 64].iter().map(|&n| cook_tip(n, e, nu, mixed, force)).collect()
}

/// The compressible membrane as the code comparison of CoFEA sets it (plane strain, E = 70,
/// nu = 1/3, traction 6.25 on the edge of height 16): quadratic elements on very fine meshes
/// give 32.20 (Code_Aster), 32.27 (CalculiX), 32.28 (Elmer). Both formulations converge there.
#[test]
fn cook_membrane_compressible_matches_the_published_values() {
    for mixed in [false, true] {
        let t = tips(70.0, 1.0 / 3.0, mixed, 100.0);
        println!("mixed {mixed}: {t:?}");
        let last = t[t.len() - 1];
        assert!((last - 32.24).abs() < 0.01 * 32.24, "mixed {mixed}: {last} against 32.20-32.28");
        // From below, monotonically (the displacement element is too stiff, the mixed one too).
        assert!(t.windows(2).all(|w| w[1] > w[0]), "{t:?}");
    }
}

/// Nearly incompressible (E = 250, nu = 0.4999, force 100): the mixed element converges (each
/// refinement at least halves the change, the 64 x 64 mesh within 1% of the sequence's
/// Richardson limit) and does so uniformly in lambda (nu = 0.49999, ten times lambda, changes
/// the tip by less than 1e-3 on every mesh: the limit problem's solution is continuous as
/// lambda grows); the displacement element locks (below 55% of the mixed tip on every mesh,
/// and further below as lambda grows).
#[test]
fn cook_membrane_nearly_incompressible_converges_without_locking() {
    let mixed = tips(250.0, 0.4999, true, 100.0);
    let stiffer = tips(250.0, 0.49999, true, 100.0);
    let plain = tips(250.0, 0.4999, false, 100.0);
    let plain_stiffer = tips(250.0, 0.49999, false, 100.0);
    println!("mixed {mixed:?}\nnu 0.49999 {stiffer:?}\ndisplacement {plain:?}\nnu 0.49999 {plain_stiffer:?}");
    let d: Vec<f64> = mixed.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(d.iter().all(|&x| x > 0.0), "from below: {mixed:?}");
    assert!(d.windows(2).all(|w| w[1] < 0.5 * w[0]), "converging: changes {d:?}");
    // Richardson: the last change times r/(1 - r), r the ratio of the last two changes.
    let r = d[d.len() - 1] / d[d.len() - 2];
    let limit = mixed[mixed.len() - 1] + d[d.len() - 1] * r / (1.0 - r);
    let last = mixed[mixed.len() - 1];
    println!("Richardson limit {limit}");
    assert!((limit - last).abs() < 0.01 * limit, "{last} against the limit {limit}");
    for k in 0..mixed.len() {
        assert!((mixed[k] - stiffer[k]).abs() < 1e-3 * mixed[k], "uniform in lambda");
        assert!(plain[k] < 0.55 * mixed[k], "the displacement element locks: {plain:?}");
        assert!(plain_stiffer[k] < plain[k], "and locks more as lambda grows");
    }
}

/// Triangles (each cell cut along one diagonal, as gmsh's structured meshes; the pattern that
/// locks most), E = 250, nu = 0.4999, force 100, meshes 4 x 4 to 128 x 128. The displacement
/// triangles lock: on 128 x 128 cells the tip is under half the limit's, 57 times as far
/// from it as the averaged nodal pressure's. That one converges to the quadrilaterals' limit
/// (the mean dilatation's Richardson limit, an independent element), its distance falling by
/// a third or more with each refinement (measured 0.59, 0.42, 0.38, 0.40, 0.41), within 1% on
/// the finest mesh (measured 0.91%); its own Richardson limit is the quadrilaterals' within 1%
/// (measured 0.1%). It is not fully uniform in lambda on coarse meshes (nu = 0.49999 moves the
/// tip by 1.3% on 8 x 8, 0.07% on 128 x 128): asserted within 2% and falling over the finer
/// meshes.
#[test]
fn cook_membrane_triangles_with_the_nodal_pressure_converge_without_locking() {
    let tips = |nu: f64, mixed: bool| -> Vec<f64> {
        let m = Material { mean_dilatation: mixed, ..Material::from_young_poisson(250.0, nu, 1.0) };
        [4usize, 8, 16, 32, 64, 128]
            .iter()
            .map(|&n| cook_solve(n, ElementKind::Tri3, &m, 100.0)[2 * cook_node(n, n, n).0 + 1])
            .collect()
    };
    let richardson = |t: &[f64]| {
        let (a, b, c) = (t[t.len() - 3], t[t.len() - 2], t[t.len() - 1]);
        let r = (c - b) / (b - a);
        c + (c - b) * r / (1.0 - r)
    };
    let quads: Vec<f64> =
        [16usize, 32, 64].iter().map(|&n| cook_tip(n, 250.0, 0.4999, true, 100.0)).collect();
    let limit = richardson(&quads);
    let (nodal, stiffer, plain) = (tips(0.4999, true), tips(0.49999, true), tips(0.4999, false));
    println!("nodal {nodal:?}\nnu 0.49999 {stiffer:?}\ndisplacement {plain:?}\nlimit {limit}");
    let dist: Vec<f64> = nodal.iter().map(|t| (t - limit).abs()).collect();
    assert!(dist.windows(2).all(|w| w[1] < 0.67 * w[0]), "not converging: {nodal:?}");
    let last = nodal.len() - 1;
    assert!(dist[last] < 0.01 * limit, "{nodal:?} against {limit}");
    assert!((richardson(&nodal) - limit).abs() < 0.01 * limit, "{nodal:?} against {limit}");
    let lambda: Vec<f64> = nodal.iter().zip(&stiffer).map(|(a, b)| rel_diff(*a, *b)).collect();
    assert!(lambda.iter().all(|&d| d < 0.02), "lambda moves the tip: {lambda:?}");
    assert!(lambda[2..].windows(2).all(|w| w[1] < w[0]), "{lambda:?}");
    for k in 0..nodal.len() {
        assert!(plain[k] < 0.7 * nodal[k], "the displacement triangles lock: {plain:?}");
    }
    assert!((plain[last] - limit).abs() > 10.0 * dist[last], "{plain:?}");
}

/// The other locking-free choice for simplices, measured against the averaged nodal pressure
/// on the same triangles (E = 250, nu = 0.4999): the stabilized P1/P1 form ([`cook_p1p1`]).
/// Checked first that its solve is right: at nu = 0.3 its tip agrees with the displacement
/// triangles' as the mesh is refined (both converge to the same solution). Then at 0.4999 it
/// converges to the quadrilaterals' limit, uniformly in lambda (ten times lambda moves it by
/// under 1e-3 on every mesh), and its pressure has no checkerboard: the alternating share of
/// the nodal pressures falls with every refinement from 8 x 8 on (a spurious mode would not).
///
/// Measured: 46%, 24%, 9.5%, 3.6%, 1.4% from the limit on 4 x 4 ... 64 x 64, where the nodal
/// pressure is 59%, 35%, 15%, 5.6%, 2.2%; ten times lambda moves it by 1e-4; alternating
/// shares 1.8%, 2.2%, 1.1%, 0.41%, 0.15%. The runs keep the nodal pressure all the same: its
/// operator is the displacement form's, symmetric positive definite with no pressure unknowns,
/// so the step solvers, the contact solvers and the energy identity take it unchanged; P1/P1
/// adds a continuous pressure field that cannot be condensed per cell and an indefinite step
/// system (docs/method.md).
#[test]
fn cook_membrane_stabilized_p1p1_against_the_nodal_pressure() {
    let meshes = [4usize, 8, 16, 32, 64];
    let material = |nu: f64, mixed: bool| Material {
        mean_dilatation: mixed,
        ..Material::from_young_poisson(250.0, nu, 1.0)
    };
    let tip = |u: Vec<f64>, n: usize| u[2 * cook_node(n, n, n).0 + 1];
    let p1p1 = |nu: f64| -> Vec<(f64, Vec<f64>)> {
        meshes.iter().map(|&n| cook_p1p1(n, &material(nu, true), 100.0)).collect()
    };
    let compressible = p1p1(0.3);
    let plain: Vec<f64> = (meshes.iter())
        .map(|&n| tip(cook_solve(n, ElementKind::Tri3, &material(0.3, false), 100.0), n))
        .collect();
    println!(
        "nu 0.3: p1p1 {:?}\ndisplacement {plain:?}",
        compressible.iter().map(|x| x.0).collect::<Vec<_>>()
    );
    let gap: Vec<f64> = compressible.iter().zip(&plain).map(|(a, b)| rel_diff(a.0, *b)).collect();
    assert!(gap.windows(2).all(|w| w[1] < w[0]), "the forms do not meet at nu = 0.3: {gap:?}");
    let (stabilized, stiffer) = (p1p1(0.4999), p1p1(0.49999));
    let nodal: Vec<f64> = (meshes.iter())
        .map(|&n| tip(cook_solve(n, ElementKind::Tri3, &material(0.4999, true), 100.0), n))
        .collect();
    let quads: Vec<f64> =
        [16usize, 32, 64].iter().map(|&n| cook_tip(n, 250.0, 0.4999, true, 100.0)).collect();
    let r = (quads[2] - quads[1]) / (quads[1] - quads[0]);
    let limit = quads[2] + (quads[2] - quads[1]) * r / (1.0 - r);
    // The alternating share of the nodal pressures, `|sum (-1)^(i+j) p_ij| / sum |p_ij|`.
    let checkerboard = |n: usize, p: &[f64]| {
        let (mut alt, mut total) = (0.0, 0.0);
        for i in 0..=n {
            for j in 0..=n {
                let x = p[cook_node(n, i, j).0];
                alt += if (i + j) % 2 == 0 { x } else { -x };
                total += x.abs();
            }
        }
        alt.abs() / total
    };
    let tips: Vec<f64> = stabilized.iter().map(|x| x.0).collect();
    let boards: Vec<f64> =
        meshes.iter().zip(&stabilized).map(|(&n, x)| checkerboard(n, &x.1)).collect();
    println!(
        "limit {limit}\np1p1 {tips:?}\nnu 0.49999 {:?}\nnodal {nodal:?}\ncheckerboard {boards:?}",
        stiffer.iter().map(|x| x.0).collect::<Vec<_>>()
    );
    let dist: Vec<f64> = tips.iter().map(|t| (t - limit).abs() / limit).collect();
    let nodal_dist: Vec<f64> = nodal.iter().map(|t| (t - limit).abs() / limit).collect();
    println!("distance to the limit: p1p1 {dist:?}\nnodal {nodal_dist:?}");
    assert!(dist.windows(2).all(|w| w[1] < w[0]), "not converging: {tips:?} against {limit}");
    for (a, b) in stabilized.iter().zip(&stiffer) {
        assert!(rel_diff(a.0, b.0) < 1e-3, "lambda moves the tip: {} and {}", a.0, b.0);
    }
    assert!(boards[1..].windows(2).all(|w| w[1] < w[0]), "a checkerboard: {boards:?}");
}

mod common;
use common::*;

/// A manufactured divergence-free motion of the beam (0, 10) x (0, 1) (clamped at both ends,
/// traction-free bottom): `u = curl psi`, `psi = x^2 (10 - x)^2 y^3 sin(2 pi t) / 10^4`, so
/// `div u = 0` and the solution, its body force `rho u_tt - mu Lap u` and the top traction
/// `(sigma_xy, sigma_yy)` do not depend on lambda: a locking-free element converges at rates
/// and errors independent of lambda. `mu = 1000/13` (the beam's), `E = 2 mu (1 + nu)`, `rho = 1`,
/// plane strain.
fn incompressible_beam(
    dir: &std::path::Path,
    geo: &str,
    nu: f64,
    formulation: &str,
) -> std::path::PathBuf {
    let mu = 1000.0 / 13.0;
    let e = 2.0 * mu * (1.0 + nu);
    let text = format!(
        r#"name = "incompressible_beam"
[mesh]
geo = "../meshes/{geo}"
params = {{ h = 0.25 }}
[material]
E = {e}
nu = {nu}
rho = 1.0
formulation = "{formulation}"
[[dirichlet]]
group = "left"
[[dirichlet]]
group = "right"
[[neumann]]
group = "top"
traction = ["{mu}*(3*x^4 - 60*x^3 + 294*x^2 + 60*x - 100)*sin(2*pi*t)/5000", "-3*{mu}*x*(x - 10)*(x - 5)*sin(2*pi*t)/1250"]
[body_force]
value = [
  "-3*({mu}*x^4 - 20*{mu}*x^3 + 6*{mu}*x^2*y^2 + 100*{mu}*x^2 - 60*{mu}*x*y^2 + 100*{mu}*y^2 + 2*pi^2*x^4*y^2 - 40*pi^2*x^3*y^2 + 200*pi^2*x^2*y^2)*sin(2*pi*t)/5000",
  "y*(x - 5)*(3*{mu}*x^2 - 30*{mu}*x + 3*{mu}*y^2 + 2*pi^2*x^2*y^2 - 20*pi^2*x*y^2)*sin(2*pi*t)/1250",
]
[initial]
velocity = ["3*pi*x^2*y^2*(x - 10)^2/5000", "-pi*x*y^3*(x - 10)*(x - 5)/1250"]
[time]
tau = 1e-3
steps = 250
[mass]
kind = "consistent"
[output]
every = 250
[exact]
displacement = ["3*x^2*y^2*(x - 10)^2*sin(2*pi*t)/10000", "-x*y^3*(x - 10)*(x - 5)*sin(2*pi*t)/2500"]
velocity = ["3*pi*x^2*y^2*(x - 10)^2*cos(2*pi*t)/5000", "-pi*x*y^3*(x - 10)*(x - 5)*cos(2*pi*t)/1250"]
gradient = [
  ["3*x*y^2*(x - 10)*(x - 5)*sin(2*pi*t)/2500", "3*x^2*y*(x - 10)^2*sin(2*pi*t)/5000"],
  ["-y^3*(3*x^2 - 30*x + 50)*sin(2*pi*t)/2500", "-3*x*y^2*(x - 10)*(x - 5)*sin(2*pi*t)/2500"],
]
error_steps = [250]
"#
    );
    scene_text(dir, &format!("beam-{geo}-{nu}-{formulation}.toml"), &text)
}

/// Observed rates log2(e_h / e_{h/2}).
fn rates(e: &[f64]) -> Vec<f64> {
    e.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

/// The manufactured beam (`geo`) on h = 1/4, 1/8, 1/16 (2 ranks), errors at t = 0.25 (250
/// steps of 1e-3: the midpoint rule's O(tau^2) far below the space error): L2 and H1 errors.
fn beam_errors(
    dir: &std::path::Path,
    geo: &str,
    nu: f64,
    formulation: &str,
) -> (Vec<f64>, Vec<f64>) {
    let scene = incompressible_beam(dir, geo, nu, formulation);
    let (mut l2, mut h1) = (vec![], vec![]);
    for h in ["0.25", "0.125", "0.0625"] {
        let s =
            run_scene(2, &scene, &["--param", &format!("h={h}"), "--", "-step_ksp_rtol", "1e-12"]);
        l2.push(s.errors[0].l2);
        h1.push(s.errors[0].h1_semi);
    }
    eprintln!(
        "{geo} nu {nu} {formulation}: L2 {l2:?} rates {:?}; H1 {h1:?} rates {:?}",
        rates(&l2),
        rates(&h1)
    );
    (l2, h1)
}

/// Theory: O(h^2) in L2 and O(h) in H1 for a locking-free element, with constants bounded
/// independently of lambda (the data are the same for both `nu`, lambda grows 4300 times).
/// Asserted: both converge at the optimal rates or faster (the last rates within 0.2 of them);
/// the errors at the two `nu` agree within `coarse` on every mesh, their difference falls
/// with every refinement, and within 10% on the finest; the displacement element's errors
/// are more than tenfold (locking).
fn assert_rates_do_not_depend_on_lambda(geo: &str, coarse: f64) {
    let dir = scratch("incompressible-beam");
    let (l2_c, h1_c) = beam_errors(&dir, geo, 0.3, "mixed");
    let (l2_i, h1_i) = beam_errors(&dir, geo, 0.4999, "mixed");
    let (l2_d, _) = beam_errors(&dir, geo, 0.4999, "displacement");
    for (l2, h1) in [(&l2_c, &h1_c), (&l2_i, &h1_i)] {
        for (r, p) in [(rates(l2), 2.0), (rates(h1), 1.0)] {
            assert!(r.iter().all(|r| *r > p - 0.15), "rates {r:?} below {p}");
            assert!((r[r.len() - 1] - p).abs() < 0.2, "rates {r:?} against {p}");
        }
    }
    for (c, i) in [(&l2_c, &l2_i), (&h1_c, &h1_i)] {
        let d: Vec<f64> = c.iter().zip(i).map(|(c, i)| rel_diff(*c, *i)).collect();
        assert!(d.iter().all(|&x| x < coarse), "errors depend on lambda: {c:?} {i:?}");
        assert!(d.windows(2).all(|w| w[1] <= w[0] || w[1] < 0.01), "{d:?} does not fall");
        assert!(d[d.len() - 1] < 0.1, "errors depend on lambda: {c:?} {i:?}");
    }
    for k in 0..l2_c.len() {
        assert!(l2_d[k] > 10.0 * l2_i[k], "the displacement element does not lock? {l2_d:?}");
    }
}

/// Quadrilaterals: the mean dilatation (Q1/P0).
#[test]
fn manufactured_rates_do_not_depend_on_lambda() {
    assert_rates_do_not_depend_on_lambda("beam_quad.geo", 0.1);
}

/// Triangles (structured, two per square): the averaged nodal pressure. Its errors at
/// nu = 0.4999 start 40% above the compressible ones on the coarsest mesh (four cells through
/// the beam's thickness; 14% on the next, 0.5% on the finest) and converge faster to the same
/// values (L2 rates 2.27, 2.18): the pressure's averaging patch is two cells wide.
#[test]
fn manufactured_rates_on_triangles_do_not_depend_on_lambda() {
    assert_rates_do_not_depend_on_lambda("beam_tri.geo", 0.5);
}

/// The contact patch of a body at nu = 0.3 (displacement element, `reference`), at nu = 0.4999
/// with the mixed element and with the displacement element (`locked`): the mixed peak
/// pressure is `hertz` times the reference's within 10%, over at least 70% of its contact
/// nodes; the locked one's is more than three times the mixed one's, over fewer nodes; the
/// energy is kept to 1e-8 in all three.
fn assert_contact_patch(
    reference: &RunSummary,
    mixed: &RunSummary,
    locked: &RunSummary,
    hertz: f64,
) {
    let [r, m, l] = [reference, mixed, locked].map(|s| s.contact.clone().expect("contact"));
    eprintln!(
        "peak pressure {} / {} / {}; active nodes {} / {} / {}",
        r.max_pressure,
        m.max_pressure,
        l.max_pressure,
        r.max_active_nodes,
        m.max_active_nodes,
        l.max_active_nodes
    );
    assert!(rel_diff(m.max_pressure / r.max_pressure, hertz) < 0.1, "mixed: {}", m.max_pressure);
    assert!(m.max_active_nodes as f64 >= 0.7 * r.max_active_nodes as f64);
    assert!(l.max_pressure > 3.0 * m.max_pressure, "the displacement element does not lock?");
    assert!(l.max_active_nodes < m.max_active_nodes);
    for s in [reference, mixed, locked] {
        assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
    }
}

/// The suite's disc (Q1, E = 100, rho = 1, hitting a rigid plane at 0.116 with the mass-free
/// layer M_H^1) at `nu` with `formulation` on `ranks`: its summary.
fn disc(dir: &std::path::Path, nu: f64, formulation: &str, ranks: usize) -> RunSummary {
    disc_with(dir, nu, formulation, ranks, &[], &[])
}

/// [`disc`] with more replacements in the scene text and more arguments of the run.
fn disc_with(
    dir: &std::path::Path,
    nu: f64,
    formulation: &str,
    ranks: usize,
    replace: &[(&str, &str)],
    args: &[&str],
) -> RunSummary {
    disc_scene_with(dir, "disc_impact.toml", nu, formulation, ranks, replace, args)
}

/// [`disc_with`] of a disc scene of the suite (`disc_impact.toml` quadrilaterals,
/// `disc_impact_tri.toml` triangles); the triangles' files are named `tri-disc-...`.
fn disc_scene_with(
    dir: &std::path::Path,
    scene: &str,
    nu: f64,
    formulation: &str,
    ranks: usize,
    replace: &[(&str, &str)],
    args: &[&str],
) -> RunSummary {
    let base = std::fs::read_to_string(repo().join("scenes/suite").join(scene)).unwrap();
    let mut text = base
        .replace("\"../../meshes/", "\"../meshes/")
        .replace("\nnu = 0.3\n", &format!("\nnu = {nu}\nformulation = \"{formulation}\"\n"));
    assert!(text.contains("formulation"), "the suite's disc no longer sets nu = 0.3");
    for (a, b) in replace {
        assert!(text.contains(a), "the suite's disc has no {a:?}");
        text = text.replace(a, b);
    }
    let tag: String = args.concat().chars().filter(|c| c.is_alphanumeric()).collect();
    let prefix = if scene.contains("tri") { "tri-" } else { "" };
    let name = format!("{prefix}disc-{nu}-{formulation}-{ranks}{tag}.toml");
    let named = scene_text(dir, &name, &text);
    run_scene(ranks, &named, args)
}

/// Hertz's line contact: the peak pressure grows as (E / (1 - nu^2))^(3/4) at a given impact
/// energy, 1.15 times from nu = 0.3 to 0.4999 (E fixed); the contact lasts about as long and
/// spreads over as many nodes. The mixed disc keeps that contact patch; the locked displacement
/// disc behaves as a far stiffer body (one node, several times the pressure). Energy is kept
/// (the step's identity) with either.
#[test]
fn nearly_incompressible_disc_keeps_its_contact_patch() {
    let dir = scratch("incompressible-disc");
    let reference = disc(&dir, 0.3, "displacement", 2);
    let mixed = disc(&dir, 0.4999, "mixed", 2);
    let locked = disc(&dir, 0.4999, "displacement", 2);
    let hertz = (0.91f64 / (1.0 - 0.4999f64.powi(2))).powf(0.75);
    assert_contact_patch(&reference, &mixed, &locked, hertz);
    let m = mixed.contact.clone().expect("contact");
    // One rank: the same run to the solver's tolerance.
    let one = disc(&dir, 0.4999, "mixed", 1);
    let o = one.contact.clone().expect("contact");
    assert!(
        rel_diff(o.max_pressure, m.max_pressure) < 1e-8,
        "{} against {}",
        o.max_pressure,
        m.max_pressure
    );
    assert!(rel_diff(one.energy_final, mixed.energy_final) < 1e-8);
}

/// A shipped scene (`scenes/<base>`) at `nu` with `formulation` on `ranks` (`args` added to
/// the run): its summary.
fn variant(
    dir: &std::path::Path,
    base: &str,
    nu: f64,
    formulation: &str,
    ranks: usize,
    args: &[&str],
) -> RunSummary {
    let text = std::fs::read_to_string(repo().join("scenes").join(base))
        .unwrap()
        .replace("\"../../meshes/", "\"../meshes/")
        .replace("\nnu = 0.3\n", &format!("\nnu = {nu}\nformulation = \"{formulation}\"\n"));
    assert!(text.contains("formulation"), "{base} no longer sets nu = 0.3");
    let stem = base.replace(['/', '.'], "-");
    let scene = scene_text(dir, &format!("{stem}-{nu}-{formulation}.toml"), &text);
    run_scene(ranks, &scene, args)
}

/// Triangles and tetrahedra take the averaged nodal pressure. The suite's disc of triangles
/// (`M_H^0`, dropped at 0.116) and the ball of tetrahedra (`M_H^0`, h = 0.3, hc = 0.06)
/// at nu = 0.4999 against the same element at nu = 0.3 (the linear tetrahedron's displacement
/// form is itself stiff in bending at 0.3): Hertz's growth of the peak pressure within 10%
/// (line contact 1.15, point contact 1.167), the same contact patch, energy kept; the
/// displacement simplices lock (one node, 5 and 30 times the pressure). 1, 2 and 3 ranks give
/// the same disc, 1 and 2 the same ball.
#[test]
fn nearly_incompressible_simplices_keep_their_contact_patch() {
    let dir = scratch("incompressible-simplices");
    let disc = "suite/disc_impact_tri.toml";
    let reference = variant(&dir, disc, 0.3, "mixed", 2, &[]);
    let mixed = variant(&dir, disc, 0.4999, "mixed", 2, &[]);
    let locked = variant(&dir, disc, 0.4999, "displacement", 2, &[]);
    let line = (0.91f64 / (1.0 - 0.4999f64.powi(2))).powf(0.75);
    assert_contact_patch(&reference, &mixed, &locked, line);
    for ranks in [1, 3] {
        let other = variant(&dir, disc, 0.4999, "mixed", ranks, &[]);
        let (o, m) = (other.contact.expect("contact"), mixed.contact.clone().expect("contact"));
        assert!(rel_diff(o.max_pressure, m.max_pressure) < 1e-8, "{ranks} ranks");
        assert!(rel_diff(other.energy_final, mixed.energy_final) < 1e-8, "{ranks} ranks");
    }
    let coarse = ["--param", "h=0.3", "--param", "hc=0.06"];
    let reference = variant(&dir, "sphere.toml", 0.3, "mixed", 2, &coarse);
    let mixed = variant(&dir, "sphere.toml", 0.4999, "mixed", 2, &coarse);
    let locked = variant(&dir, "sphere.toml", 0.4999, "displacement", 2, &coarse);
    let point = (0.91f64 / (1.0 - 0.4999f64.powi(2))).powf(0.8);
    assert_contact_patch(&reference, &mixed, &locked, point);
    let one = variant(&dir, "sphere.toml", 0.4999, "mixed", 1, &coarse);
    let (o, m) = (one.contact.expect("contact"), mixed.contact.expect("contact"));
    assert!(rel_diff(o.max_pressure, m.max_pressure) < 1e-8, "1 against 2 ranks");
}

/// The neo-Hookean disc dropped at 0.58, squeezed by 6% of its height, as `nu` -> 1/2 (E
/// fixed; `tau` = 0.0025, 260 steps: the contact ends by step 230, then free flight), `M_H`.
/// The nearly incompressible solution converges to the incompressible limit at the rate
/// `mu / lambda`: the changes of the largest compression and of the rebound velocity over
/// `nus` (lambda ten times each) fall by at least three. The displacement element locks at
/// 0.4999: its compression is short of the limit's by more than `locked_short`. Energy kept
/// (LU, chosen from `lambda/mu` 1000, balances to 1e-12); 1 and 2 ranks alike at `nus[1]`.
fn rubber_disc_limit(scene: &str, nus: [f64; 3], locked_short: f64) {
    let dir = scratch(&format!("rubber-disc-limit-{}", scene.trim_end_matches(".toml")));
    let fast: &[(&str, &str)] = &[
        ("\n[material]\n", "\n[material]\nmodel = \"neo_hookean\"\n"),
        ("-0.116024", "-0.58"),
        ("tau = 0.01", "tau = 0.0025"),
        ("steps = 250", "steps = 260"),
        ("every = 250", "every = 2"),
    ];
    let prefix = if scene.contains("tri") { "tri-" } else { "" };
    // The run's summary, its largest compression (1 - least height / 2) and rebound velocity.
    let run = |nu: f64, formulation: &str, ranks: usize| {
        let s = disc_scene_with(&dir, scene, nu, formulation, ranks, fast, &[]);
        let h5 = dir.join(format!("{prefix}disc-{nu}-{formulation}-{ranks}-{ranks}.h5"));
        let r = reader(&h5);
        let (x, u) =
            (r.series("mesh/coordinates").unwrap(), r.series("fields/displacement").unwrap());
        // Coordinates have three components, the 2D displacement two.
        let n = x.len() / 3;
        let height = |k: usize| {
            let y = (0..n).map(|v| x[3 * v + 1] + u[k * 2 * n + 2 * v + 1]);
            let (lo, hi) =
                y.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| (a.min(y), b.max(y)));
            hi - lo
        };
        let least = (0..u.len() / (2 * n)).map(height).fold(f64::INFINITY, f64::min);
        let rebound = s.momentum_final[1] / s.mass.total_mass[1];
        eprintln!(
            "{scene} nu {nu} {formulation} {ranks}: compression {} rebound {rebound}",
            1.0 - least / 2.0
        );
        (s, 1.0 - least / 2.0, rebound)
    };
    let mixed: Vec<_> = nus.iter().map(|&nu| run(nu, "mixed", 1)).collect();
    for (s, _, _) in &mixed {
        assert!(s.energy_balance < 1e-8, "{scene}: energy balance {}", s.energy_balance);
        assert!(s.contact.as_ref().unwrap().last_contact_step < s.steps, "the disc rebounds");
    }
    let change = |f: &dyn Fn(&(RunSummary, f64, f64)) -> f64| {
        [(f(&mixed[1]) - f(&mixed[0])).abs(), (f(&mixed[2]) - f(&mixed[1])).abs()]
    };
    for (what, [a, b]) in
        [("compression", change(&|r| r.1)), ("rebound velocity", change(&|r| r.2))]
    {
        assert!(b < a / 3.0, "{scene} {what}: changes {a:e} then {b:e}: not as mu/lambda");
    }
    let locked = run(0.4999, "displacement", 1);
    let limit = mixed[2].1;
    assert!(
        locked.1 < (1.0 - locked_short) * limit,
        "{scene}: the displacement disc does not lock? {} against {limit}",
        locked.1
    );
    let two = run(nus[1], "mixed", 2);
    let one = &mixed[1];
    assert!(rel_diff(two.2, one.2) < 1e-6, "{scene}: 1 against 2 ranks: {} {}", two.2, one.2);
    assert!(two.0.energy_balance < 1e-8);
}

/// The quadrilaterals' mean dilatation from `nu` = 0.49 (measured: the changes fall by 55 and
/// 11; the displacement disc 21% short of the compression, its contact 40% fewer steps).
#[test]
fn a_finite_strain_rubber_disc_converges_as_nu_approaches_one_half() {
    rubber_disc_limit("disc_impact.toml", [0.49, 0.499, 0.4999], 0.1);
}

/// The triangles' averaged nodal pressure at finite strain, from `nu` = 0.499: at 0.49 it is
/// not yet in the `mu / lambda` regime (measured: the compression's changes 5.3e-4 from 0.49
/// to 0.499, then 1.9e-4, then 1.0e-5 to 0.49999). Measured: compression 6.334%, 6.315%,
/// 6.314% (the quadrilaterals' limit, on another mesh: 6.268%); the displacement triangles
/// 10.4% short, with five times the peak pressure.
#[test]
fn a_finite_strain_rubber_disc_of_triangles_converges_as_nu_approaches_one_half() {
    rubber_disc_limit("disc_impact_tri.toml", [0.499, 0.4999, 0.49999], 0.05);
}

/// A linear body's averaged nodal pressure is the small-strain operator: in a finite-strain
/// run (a neo-Hookean body beside it) it is a one-line error naming both bodies and the
/// remedies, on 2 ranks, before any step.
#[test]
fn linear_mixed_simplices_in_a_finite_strain_run_are_an_error() {
    let dir = scratch("mixed-simplices-error");
    let text = std::fs::read_to_string(repo().join("scenes/two_discs_tri.toml"))
        .unwrap()
        .replace("\nnu = 0.3\n", "\nnu = 0.49\nformulation = \"mixed\"\n")
        .replace("group = \"lower\"\n", "group = \"lower\"\nmodel = \"neo_hookean\"\n");
    assert!(text.contains("neo_hookean") && text.contains("mixed"), "the scene changed");
    let scene = scene_text(&dir, "linear-beside-neo-hooke.toml", &text);
    let out = massfree(2, &["run", &scene.display().to_string(), "--quiet", "--overwrite"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    let line = err.lines().find(|l| l.contains("formulation")).unwrap_or_default();
    assert!(
        line.contains("upper")
            && line.contains("lower")
            && line.contains("neo_hookean")
            && line.contains("quadrilaterals or hexahedra"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

/// The neo-Hookean disc with the mean dilatation at nu = 0.49 (lambda/mu = 49), dropped at
/// 0.58 (five times the suite's speed), tau = 0.0025 (300 steps, through the rebound): the
/// step's energy identity holds with
/// the cell's volumetric discrete gradient (balance at the Newton tolerance) on 1 and 2 ranks
/// alike; the mass-free layer keeps the contact pressure free of the consistent mass's
/// period-2 chatter (its osc2 a third or less of M's); and at a hundredth of the speed the
/// finite-strain disc is the small-strain one (peak pressures within 1%: strains of 1e-3).
#[test]
fn finite_strain_mixed_disc_keeps_energy_and_recovers_small_strain() {
    let dir = scratch("finite-strain-mixed-disc");
    let fast: &[(&str, &str)] = &[
        ("\n[material]\n", "\n[material]\nmodel = \"neo_hookean\"\n"),
        ("-0.116024", "-0.58"),
        ("tau = 0.01", "tau = 0.0025"),
        ("steps = 250", "steps = 300"),
        ("every = 250", "every = 300"),
    ];
    let layer = disc_with(&dir, 0.49, "mixed", 2, fast, &[]);
    let one = disc_with(&dir, 0.49, "mixed", 1, fast, &[]);
    let consistent = disc_with(&dir, 0.49, "mixed", 2, fast, &["--mass", "consistent"]);
    for s in [&layer, &one] {
        assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
    }
    let [l, o, c] = [&layer, &one, &consistent].map(|s| s.contact.clone().expect("contact"));
    eprintln!(
        "osc2 M_H^1 {} M {}; peak {} / {}",
        l.lowest_osc2, c.lowest_osc2, l.max_pressure, o.max_pressure
    );
    assert!(rel_diff(l.max_pressure, o.max_pressure) < 1e-6, "1 against 2 ranks");
    assert!(
        l.lowest_osc2 < c.lowest_osc2 / 3.0,
        "M_H^1 {} against M {}",
        l.lowest_osc2,
        c.lowest_osc2
    );
    let slow: &[(&str, &str)] = &[("\n[material]\n", "\n[material]\nmodel = \"neo_hookean\"\n")];
    let finite = disc_with(&dir, 0.49, "mixed", 2, slow, &[]).contact.expect("contact");
    let small = disc(&dir, 0.49, "mixed", 2).contact.expect("contact");
    eprintln!("slow: peak {} finite, {} small strain", finite.max_pressure, small.max_pressure);
    assert!(rel_diff(finite.max_pressure, small.max_pressure) < 0.01);
}

/// The paper's two discs (a dual mortar pair, `M_H^1` on both arcs) as nearly incompressible
/// bodies (`nu` = 0.49, the mean dilatation), frictionless and with Coulomb friction 0.3
/// (`--friction`): the step's energy identity holds (the balance books the friction's
/// dissipation), each disc's momentum change is the impulse the contact gave it and the two
/// impulses cancel (action and reaction through the mortar coupling), and 1 and 2 ranks give
/// the same run.
#[test]
fn mixed_bodies_in_a_mortar_pair_with_friction() {
    let dir = scratch("mixed-pair");
    let base = std::fs::read_to_string(repo().join("scenes/two_discs.toml")).unwrap();
    let text = base.replace("\nnu = 0.3\n", "\nnu = 0.49\nformulation = \"mixed\"\n");
    assert!(text.contains("formulation"), "two_discs.toml no longer sets nu = 0.3");
    let text = text.replace("steps = 1000", "steps = 300");
    let scene = scene_text(&dir, "two_discs_mixed.toml", &text);
    let runs = [
        run_scene(2, &scene, &[]),
        run_scene(1, &scene, &[]),
        run_scene(2, &scene, &["--friction", "0.3"]),
    ];
    for (k, s) in runs.iter().enumerate() {
        assert!(s.energy_balance < 1e-8, "run {k}: energy balance {}", s.energy_balance);
        assert_eq!(s.bodies.len(), 2);
        let p0 = s.bodies[0].momentum_initial.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        for c in 0..2 {
            let j: f64 = s.bodies.iter().map(|b| b.contact_impulse[c]).sum();
            assert!(j.abs() < 1e-8 * p0, "run {k}: impulses do not cancel ({j})");
            for b in &s.bodies {
                let dp = b.momentum_final[c] - b.momentum_initial[c];
                assert!((dp - b.contact_impulse[c]).abs() < 1e-6 * p0, "run {k}: {}", b.group);
            }
        }
        let impulse = s.bodies[0].contact_impulse.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!(impulse > 0.1 * p0, "run {k}: no contact ({impulse})");
    }
    assert!(rel_diff(runs[0].energy_final, runs[1].energy_final) < 1e-8, "1 against 2 ranks");
}

/// The checkerboard share of a structured mesh's cell pressures, `|sum_ij (-1)^(i+j) p_ij| /
/// sum_ij |p_ij|`: a smooth field cancels in the alternating sum (O(1/n)), the spurious
/// pressure mode of an unstable pair does not.
fn checkerboard(n: usize, p: &[f64]) -> f64 {
    let alternating: f64 =
        (0..n * n).map(|k| if (k / n + k % n).is_multiple_of(2) { p[k] } else { -p[k] }).sum();
    alternating.abs() / p.iter().map(|x| x.abs()).sum::<f64>()
}

/// The cells' pressures averaged at the nodes (each cell's four corners, equal weights: the
/// lumped projection of a uniform mesh), `(n + 1)^2` values.
fn nodal(n: usize, p: &[f64]) -> Vec<f64> {
    let np = n + 1;
    let (mut sum, mut count) = (vec![0.0; np * np], vec![0.0; np * np]);
    for i in 0..n {
        for j in 0..n {
            for (a, b) in [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)] {
                sum[a * np + b] += p[i * n + j];
                count[a * np + b] += 1.0;
            }
        }
    }
    sum.iter().zip(&count).map(|(s, c)| s / c).collect()
}

/// The pressure of Cook's membrane (E = 250, force 100). Q1/P0 is not inf-sup stable: at
/// nu = 0.4999 its cell pressures carry a checkerboard share of 19% on 8 x 8, falling only as
/// h^0.7 (4% on 64 x 64; at nu = 0.3 3% to 0.08%, as h^1.7): asserted that it falls with every
/// refinement (with a traction edge the mode is not in the kernel). Averaged at the nodes (as
/// the run's `pressure_nodal` output does) the alternating cells cancel: the nodal pressure's
/// share stays within twice the compressible one's and falls with h, while the locked
/// displacement element's stays several times higher.
#[test]
fn cook_membrane_nodal_pressure_has_no_checkerboard() {
    let shares = |nu: f64, mixed: bool| {
        let (mut cells, mut nodes) = (vec![], vec![]);
        for n in [8usize, 16, 32, 64] {
            let p = cook(n, 250.0, nu, mixed, 100.0).1;
            cells.push(checkerboard(n, &p));
            nodes.push(checkerboard(n + 1, &nodal(n, &p)));
        }
        eprintln!("nu {nu} mixed {mixed}: checkerboard share cells {cells:?} nodes {nodes:?}");
        (cells, nodes)
    };
    let (_, smooth) = shares(0.3, true);
    let (cells, nodes) = shares(0.4999, true);
    let (_, locked) = shares(0.4999, false);
    assert!(cells.windows(2).all(|w| w[1] < w[0]), "cell checkerboard does not fall: {cells:?}");
    for k in 0..nodes.len() {
        assert!(nodes[k] < 2.0 * smooth[k], "nodal checkerboard {nodes:?} against {smooth:?}");
        assert!(locked[k] > nodes[k], "the displacement element: {locked:?}");
    }
    assert!(nodes.windows(2).all(|w| w[1] < w[0]), "nodal checkerboard does not fall: {nodes:?}");
}

/// The mass-free layer's advantage with the mixed element at nu = 0.4999 (the suite's disc,
/// tau = 0.002, CFL 33 in the pressure wave): the standard mass `M` chatters (the paper's
/// Figure 7.5 effect), `M_H^0` keeps the lowest node's pressure smooth (osc2 a third of M's or
/// less, measured 8 times smaller) and the energy (M loses 1e-3 per impact, M_H 1e-19).
#[test]
fn mass_free_layer_keeps_its_advantage_when_nearly_incompressible() {
    let dir = scratch("incompressible-layer");
    let fine: &[(&str, &str)] = &[
        ("tau = 0.01", "tau = 0.002"),
        ("steps = 250", "steps = 1250"),
        ("every = 250", "every = 1250"),
    ];
    let layer = disc_with(&dir, 0.4999, "mixed", 2, fine, &["--mass", "modified0"]);
    let standard = disc_with(&dir, 0.4999, "mixed", 2, fine, &["--mass", "consistent"]);
    let [l, m] = [&layer, &standard].map(|s| s.contact.clone().expect("contact"));
    eprintln!("osc2 M_H^0 {} M {}", l.lowest_osc2, m.lowest_osc2);
    assert!(
        l.lowest_osc2 < m.lowest_osc2 / 3.0,
        "M_H^0 {} against M {}",
        l.lowest_osc2,
        m.lowest_osc2
    );
    assert!(layer.energy_balance < 1e-8, "energy balance {}", layer.energy_balance);
}

/// The Q1 ball of `scenes/sphere_hex.toml` (hexahedra, `M_H^1`, radius 1, E = 100, dropped at
/// 0.0167; coarse: h = 0.5, hc = 0.15) at `nu` with `formulation` on `ranks`.
fn ball(dir: &std::path::Path, nu: f64, formulation: &str, ranks: usize) -> RunSummary {
    let base = std::fs::read_to_string(repo().join("scenes/sphere_hex.toml")).unwrap();
    let text =
        base.replace("\nnu = 0.3\n", &format!("\nnu = {nu}\nformulation = \"{formulation}\"\n"));
    assert!(text.contains("formulation"), "sphere_hex.toml no longer sets nu = 0.3");
    let scene = scene_text(dir, &format!("ball-{nu}-{formulation}.toml"), &text);
    run_scene(ranks, &scene, &["--param", "h=0.5", "--param", "hc=0.15"])
}

/// Hertz's point contact in 3D: at a given impact energy the peak pressure grows as
/// (E / (1 - nu^2))^(4/5), 1.167 times from nu = 0.3 to 0.4999. The mixed hexahedra keep the
/// ball's contact patch (as many nodes as at 0.3), the displacement hexahedra lock (half the
/// nodes, four times the pressure); energy kept; 1 and 2 ranks alike.
#[test]
fn nearly_incompressible_ball_of_hexahedra_keeps_its_contact_patch() {
    let dir = scratch("incompressible-ball");
    let reference = ball(&dir, 0.3, "displacement", 2);
    let mixed = ball(&dir, 0.4999, "mixed", 2);
    let locked = ball(&dir, 0.4999, "displacement", 2);
    let one = ball(&dir, 0.4999, "mixed", 1);
    let hertz = (0.91f64 / (1.0 - 0.4999f64.powi(2))).powf(0.8);
    assert_contact_patch(&reference, &mixed, &locked, hertz);
    let [m, o] = [&mixed, &one].map(|s| s.contact.clone().expect("contact"));
    assert!(
        rel_diff(o.max_pressure, m.max_pressure) < 1e-8,
        "{} against {}",
        o.max_pressure,
        m.max_pressure
    );
}

/// The neo-Hookean disc with the mean dilatation at nu = 0.499 dropped at 0.58 with tau = 0.01:
/// from the extrapolated guess Newton diverges in the first contact steps (the guess runs the
/// motion on into the plane, far into the volume constraint); those steps are solved again
/// from their start (and the next ones start there) and the run goes through the impact
/// (steps 1-58), keeping its energy, on 1 and 2 ranks alike.
#[test]
fn nearly_incompressible_finite_strain_steps_restart_from_their_start() {
    let dir = scratch("finite-strain-restart");
    let fast: &[(&str, &str)] = &[
        ("\n[material]\n", "\n[material]\nmodel = \"neo_hookean\"\n"),
        ("-0.116024", "-0.58"),
        ("steps = 250", "steps = 70"),
        ("every = 250", "every = 70"),
    ];
    let two = disc_with(&dir, 0.499, "mixed", 2, fast, &[]);
    let one = disc_with(&dir, 0.499, "mixed", 1, fast, &[]);
    let restarts = two.newton.as_ref().expect("finite strain").restarts;
    eprintln!("restarts {restarts}, balance {}", two.energy_balance);
    assert!(restarts > 0, "no step needed its restart: the case no longer tests it");
    for s in [&two, &one] {
        assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
    }
    let [a, b] = [&two, &one].map(|s| s.contact.clone().expect("contact").max_pressure);
    assert!(rel_diff(a, b) < 1e-6, "1 against 2 ranks: {a} {b}");
}

/// The finite-strain patch test of the averaged nodal pressure: under an affine deformation
/// `F = [[0.95, 0.02], [0, 0.92]]` (J = 0.874: every node's volume ratio is J) the nearly
/// incompressible neo-Hookean disc of triangles writes, in every cell, the exact Cauchy
/// stress `mu/J (F F^T - I) + lambda ln(J)/J I`, as does its nodal pressure projection (2
/// ranks, the initial state written by a run of no steps; the volumetric part is 770 times
/// the deviatoric one, so a wrong nodal average shows at once).
#[test]
fn an_affine_deformation_gives_the_exact_stress_with_the_nodal_pressure_at_finite_strain() {
    let dir = scratch("nodal-pressure-affine");
    let text = std::fs::read_to_string(repo().join("scenes/suite/disc_impact_tri.toml"))
        .unwrap()
        .replace("\"../../meshes/", "\"../meshes/")
        .replace(
            "\nnu = 0.3\n",
            "\nnu = 0.4999\nformulation = \"mixed\"\nmodel = \"neo_hookean\"\n",
        )
        .replace(
            "velocity = [\"0\", \"-0.116024\"]",
            "velocity = [\"0\", \"0\"]\ndisplacement = [\"-0.05 * x + 0.02 * y\", \"-0.08 * y\"]",
        )
        .replace("kind = \"modified0\"", "kind = \"consistent\"")
        .replace("every = 250", "every = 1\nfields = [\"stress\", \"pressure_nodal\"]");
    let (a, b) = (text.find("[contact]").unwrap(), text.find("[output]").unwrap());
    let text = format!("{}{}", &text[..a], &text[b..]);
    assert!(text.contains("displacement = ") && text.contains("stress"), "the scene changed");
    let scene = scene_text(&dir, "affine.toml", &text);
    run_scene(2, &scene, &["--steps", "0"]);
    let r = reader(&dir.join("affine-2.h5"));
    let (e, nu) = (100.0f64, 0.4999f64);
    let (lambda, mu) = (e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), e / (2.0 * (1.0 + nu)));
    let f = [[0.95, 0.02], [0.0, 0.92]];
    let j: f64 = f[0][0] * f[1][1] - f[0][1] * f[1][0];
    let b = |i: usize, k: usize| f[i][0] * f[k][0] + f[i][1] * f[k][1];
    let p = lambda * j.ln() / j;
    // xx, xy, xz, yy, yz, zz.
    let exact =
        [mu / j * (b(0, 0) - 1.0) + p, mu / j * b(0, 1), 0.0, mu / j * (b(1, 1) - 1.0) + p, 0.0, p];
    let stress = r.series("fields/stress").unwrap();
    let cells = stress.len() / 6; // step 0's frame, six components
    let worst = (0..cells * 6).fold(0.0f64, |m, i| m.max((stress[i] - exact[i % 6]).abs()));
    assert!(worst < 1e-10 * p.abs(), "stress off by {worst:e} of {p:e}");
    // The nodal projection of the pressure -tr(sigma)/3.
    let pressure = -(exact[0] + exact[3] + exact[5]) / 3.0;
    let nodal = r.series("fields/pressure_nodal").unwrap();
    let worst = nodal.iter().fold(0.0f64, |m, x| m.max((x - pressure).abs()));
    assert!(worst < 1e-10 * p.abs(), "nodal pressure off by {worst:e} of {pressure:e}");
}

/// Coulomb friction on a nearly incompressible body: the mixed disc (`nu` = 0.4999, the mean
/// dilatation) hits the plane sliding (velocity 0.05 along it, 0.116 into it; `--friction
/// 0.3`). Under the normal load its contact zone spreads sideways, so a node slipping one way
/// slips back whichever way it is pushed; such a node sticks (the active-set loop's rule)
/// instead of turning its slip direction for ever (before: "the slip directions did not
/// settle" at step 1). Asserted: the run ends; the energy balance books the dissipation to
/// the solver tolerance (1e-8, solves to 1e-12); the dissipation is positive; the friction
/// impulse lies in Coulomb's cone, `|J_t| <= mu J_n`; 1 and 2 ranks agree to 1e-8.
#[test]
fn nearly_incompressible_bodies_take_coulomb_friction() {
    let dir = scratch("incompressible-friction");
    let sliding: &[(&str, &str)] =
        &[("velocity = [\"0\", \"-0.116024\"]", "velocity = [\"0.05\", \"-0.116024\"]")];
    let args = ["--friction", "0.3", "--", "-step_ksp_rtol", "1e-12"];
    let runs: Vec<RunSummary> =
        [1, 2].iter().map(|&n| disc_with(&dir, 0.4999, "mixed", n, sliding, &args)).collect();
    for s in &runs {
        let c = s.contact.as_ref().expect("contact");
        assert!(s.energy_balance < 1e-8, "energy balance {}", s.energy_balance);
        assert!(c.friction_dissipation > 0.0, "dissipation {}", c.friction_dissipation);
        let (jt, jn) = (c.friction_impulse[0].abs(), c.impulse[1]);
        assert!(
            jt > 0.0 && jt <= 0.3 * jn * (1.0 + 1e-9),
            "|J_t| {jt} against mu J_n {}",
            0.3 * jn
        );
    }
    let (a, b) = (runs[0].contact.as_ref().unwrap(), runs[1].contact.as_ref().unwrap());
    assert!(rel_diff(a.friction_impulse[0], b.friction_impulse[0]) < 1e-8, "1 against 2 ranks");
    assert!(rel_diff(a.friction_dissipation, b.friction_dissipation) < 1e-8, "1 against 2 ranks");
}
