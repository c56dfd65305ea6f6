//! Checks of the 2D linearizations against central finite differences of the functions the
//! solver uses (`nodal_normals_2d`, `project_onto_*_2d`, `dual_basis_2d`, `mortar_pair_2d`).
//!
//! A configuration is a list of involved nodes (the slave chain around the pair's slave facet,
//! then the pair's master facet). A perturbation direction `V` gives every node coordinate a
//! velocity; the finite difference `(q(X + h V) - q(X - h V)) / 2h` must approach the analytic
//! `delta q [V]` like `h^2` until round-off. Errors are measured per group of quantities (e.g.
//! the four `M_jl`) and relative to the group's largest analytic derivative over the
//! directions: `err(h) = max_V |fd_V - an_V|_2 / max_V |an_V|_2`.
//! Run with `--nocapture` to see the tables.

use super::*;
use crate::contact::mortar::dual::{dual_basis_2d, nodal_normals_2d};
use crate::contact::mortar::segment::mortar_pair_2d;

// ---------------- configurations ----------------

/// Involved nodes: the slave chain `0..ns` (facets `[i, i + 1]`, body on their left), then
/// the master facet's two nodes `ns, ns + 1`; the pair is slave facet `k` against it.
#[derive(Clone)]
struct Case {
    name: &'static str,
    x: Vec<Vec2>,
    slave_facets: Vec<[usize; 2]>,
    ids: PairIds2,
}

fn rigid(p: Vec2) -> Vec2 {
    let (s, c) = 0.4f64.sin_cos();
    [c * p[0] - s * p[1] + 0.3, s * p[0] + c * p[1] - 0.7]
}

/// `slave`: the chain (right to left for a body below, normal up); `master`: its facet
/// (left to right: body above, normal down); pair slave facet `k`. Everything moved rigidly
/// off the axes.
fn case(name: &'static str, slave: &[Vec2], master: [Vec2; 2], k: usize) -> Case {
    let ns = slave.len();
    let mut x: Vec<Vec2> = slave.to_vec();
    x.extend_from_slice(&master);
    let x = x.into_iter().map(rigid).collect();
    Case {
        name,
        x,
        slave_facets: (0..ns - 1).map(|i| [i, i + 1]).collect(),
        ids: PairIds2 { slave: [k, k + 1], master: [ns, ns + 1] },
    }
}

/// A slave chain near y = 0 (nodes at the given abscissae, right to left, small heights).
fn chain(xs: &[f64], ys: &[f64]) -> Vec<Vec2> {
    xs.iter().zip(ys).map(|(&a, &b)| [a, b]).collect()
}

/// Slave arc of radius `r` centred at (0, -r), angles in degrees (increasing: right to left).
fn arc(r: f64, deg: &[f64]) -> Vec<Vec2> {
    deg.iter().map(|a| [r * a.to_radians().cos(), -r + r * a.to_radians().sin()]).collect()
}

/// The pair configurations; the segment ends each should have.
fn cases() -> Vec<(Case, Option<[SegmentEnd; 2]>)> {
    use SegmentEnd::{Master, Slave};
    let flat = chain(&[1.9, 1.0, 0.0, -0.8], &[0.05, 0.0, 0.0, -0.03]);
    vec![
        // Master longer than the slave facet and not parallel: both ends slave nodes.
        (
            case("full overlap (non-matching)", &flat, [[-0.35, 0.03], [1.3, 0.08]], 1),
            Some([Slave(0), Slave(1)]),
        ),
        // Master shifted right, shorter: the left end is the projection of master node 0.
        (
            case("partial: slave + master end", &flat, [[0.35, 0.04], [1.6, 0.02]], 1),
            Some([Slave(0), Master(0)]),
        ),
        // Master inside the slave facet: both ends master projections.
        (
            case("master inside the slave", &flat, [[0.2, 0.05], [0.7, 0.02]], 1),
            Some([Master(1), Master(0)]),
        ),
        // Curved slave (averaged normals differ from the facet normal), tilted master that
        // covers part of the facet.
        (
            case(
                "curved slave, tilted master",
                &arc(2.0, &[70.0, 80.5, 92.0, 101.0]),
                [[-0.25, 0.07], [0.25, 0.0]],
                1,
            ),
            Some([Master(1), Slave(1)]),
        ),
        // Slave node 1 (left end, x = 0) projects just off the master's left end.
        (
            case("slave node just off the master", &flat, [[0.03, 0.03], [1.4, 0.05]], 1),
            Some([Slave(0), Master(0)]),
        ),
        // The same node just on it.
        (
            case("slave node just on the master", &flat, [[-0.03, 0.03], [1.4, 0.05]], 1),
            Some([Slave(0), Slave(1)]),
        ),
        // Master beside the slave facet: no overlap.
        (case("no overlap", &flat, [[1.2, 0.03], [1.8, 0.05]], 1), None),
    ]
}

// ---------------- the quantities, twice ----------------

/// What a configuration is measured by: groups of scalars.
const GROUPS: [&str; 12] = [
    "n_q (nodal normals)",
    "e (facet unit normal)",
    "eta_k (slave node -> master)",
    "xi_l (master node -> slave)",
    "J (slave Jacobian)",
    "d_j (D of the facet)",
    "A (dual coefficients)",
    "segment ends",
    "M_jl",
    "N_j",
    "g_j (weighted gaps)",
    "overlap length",
];

fn facets(c: &Case, x: &[Vec2]) -> (Facet2, Facet2) {
    (Facet2::from_nodes(x, c.ids.slave).unwrap(), Facet2::from_nodes(x, c.ids.master).unwrap())
}

/// The segment by the rule of `mortar_pair_2d` (step 2), from the solver's projections.
fn segment_by_rule(s: &Facet2, n: &[Vec2; 2], m: &Facet2) -> Option<[f64; 2]> {
    let tol = 1e-12;
    let inside = |p: f64| p.abs() <= 1.0 + tol;
    let mut c = Vec::new();
    for (k, end) in [(0, -1.0), (1, 1.0)] {
        if project_onto_master_2d(m, s.x[k], n[k]).is_some_and(inside) {
            c.push(end);
        }
    }
    for y in m.x {
        if let Some(xi) = project_onto_slave_2d(s, n, y).filter(|&xi| inside(xi)) {
            c.push(xi.clamp(-1.0, 1.0));
        }
    }
    let lo = c.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (hi - lo > 2.0 * tol).then_some([lo, hi])
}

/// The solver's values, in the order of `analytic`, grouped.
fn solver_values(c: &Case, x: &[Vec2], with_segment: bool) -> Vec<(&'static str, f64)> {
    let mut out = Vec::new();
    let normals = nodal_normals_2d(x, &c.slave_facets, false).unwrap();
    let nrm = [normals[c.ids.slave[0]], normals[c.ids.slave[1]]];
    for n in nrm {
        out.extend([(GROUPS[0], n[0]), (GROUPS[0], n[1])]);
    }
    let (s, m) = facets(c, x);
    let e = s.normal();
    out.extend([(GROUPS[1], e[0] / norm2(e)), (GROUPS[1], e[1] / norm2(e))]);
    for (xk, nk) in s.x.into_iter().zip(nrm) {
        out.push((GROUPS[2], project_onto_master_2d(&m, xk, nk).unwrap()));
    }
    for y in m.x {
        out.push((GROUPS[3], project_onto_slave_2d(&s, &nrm, y).unwrap()));
    }
    out.push((GROUPS[4], s.jacobian()));
    let dual = dual_basis_2d(&s).unwrap();
    out.extend([(GROUPS[5], dual.d[0]), (GROUPS[5], dual.d[1])]);
    for i in 0..2 {
        for k in 0..2 {
            out.push((GROUPS[6], dual.a[i][k]));
        }
    }
    if with_segment {
        let seg = segment_by_rule(&s, &nrm, &m).expect("segment");
        out.extend([(GROUPS[7], seg[0]), (GROUPS[7], seg[1])]);
    }
    let p = mortar_pair_2d(&s, &nrm, &dual, &m).unwrap().unwrap_or(PairIntegrals::zero(2, 2));
    for j in 0..2 {
        for l in 0..2 {
            out.push((GROUPS[8], p.m[j][l]));
        }
    }
    out.extend([(GROUPS[9], p.psi_integral[0]), (GROUPS[9], p.psi_integral[1])]);
    out.extend([(GROUPS[10], p.weighted_gap[0]), (GROUPS[10], p.weighted_gap[1])]);
    out.push((GROUPS[11], p.overlap_measure));
    out
}

/// The linearized functions' values and derivatives, in the order of `solver_values`.
fn analytic(c: &Case, x: &[Vec2]) -> (Vec<(&'static str, f64, Lin)>, Option<PairIntegralsLin>) {
    let mut out = Vec::new();
    let normals = nodal_normals_lin_2d(x, &c.slave_facets, false).unwrap();
    let nrm = [normals[c.ids.slave[0]].clone(), normals[c.ids.slave[1]].clone()];
    for n in &nrm {
        for k in 0..2 {
            out.push((GROUPS[0], n.value[k], n.lin[k].clone()));
        }
    }
    let (s, m) = facets(c, x);
    let e = facet_normal_lin_2d(&s, c.ids.slave, false).unwrap();
    for k in 0..2 {
        out.push((GROUPS[1], e.value[k], e.lin[k].clone()));
    }
    for (k, nk) in nrm.iter().enumerate() {
        let xk = Vec2Lin::node(c.ids.slave[k], s.x[k]);
        let (eta, d) = project_onto_master_lin_2d(&m, c.ids.master, &xk, nk).unwrap();
        out.push((GROUPS[2], eta, d));
    }
    for l in 0..2 {
        let (xi, d) =
            project_onto_slave_lin_2d(&s, c.ids.slave, &nrm, m.x[l], c.ids.master[l]).unwrap();
        out.push((GROUPS[3], xi, d));
    }
    let (j, dj) = jacobian_lin_2d(&s, c.ids.slave);
    out.push((GROUPS[4], j, dj));
    let (dual, dd) = dual_basis_lin_2d(&s, c.ids.slave).unwrap();
    out.extend([(GROUPS[5], dual.d[0], dd[0].clone()), (GROUPS[5], dual.d[1], dd[1].clone())]);
    for i in 0..2 {
        for k in 0..2 {
            out.push((GROUPS[6], dual.a[i][k], Lin::zero()));
        }
    }
    let nv = [nrm[0].value, nrm[1].value];
    let nl = [nrm[0].lin.clone(), nrm[1].lin.clone()];
    let p = mortar_pair_lin_2d(&s, &nv, &dual, &m, c.ids, &nl).unwrap();
    if let Some(p) = &p {
        for k in 0..2 {
            out.push((GROUPS[7], p.segment[k], p.segment_lin[k].clone()));
        }
    }
    let zero = PairIntegrals::zero(2, 2);
    let v = p.as_ref().map_or(&zero, |p| &p.value);
    let d = |f: &dyn Fn(&PairIntegralsLin) -> Lin| p.as_ref().map_or(Lin::zero(), f);
    for jj in 0..2 {
        for l in 0..2 {
            out.push((GROUPS[8], v.m[jj][l], d(&|p| p.m[jj][l].clone())));
        }
    }
    for jj in 0..2 {
        out.push((GROUPS[9], v.psi_integral[jj], d(&|p| p.psi_integral[jj].clone())));
    }
    for jj in 0..2 {
        out.push((GROUPS[10], v.weighted_gap[jj], d(&|p| p.weighted_gap[jj].clone())));
    }
    out.push((GROUPS[11], v.overlap_measure, d(&|p| p.overlap_measure.clone())));
    (out, p)
}

// ---------------- the finite-difference harness ----------------

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// Perturbation directions: every coordinate alone, and four random mixes of all.
fn directions(n: usize) -> Vec<Vec<Vec2>> {
    let mut out = Vec::new();
    for a in 0..n {
        for c in 0..2 {
            let mut v = vec![[0.0; 2]; n];
            v[a][c] = 1.0;
            out.push(v);
        }
    }
    let mut rng = Lcg(7);
    for _ in 0..4 {
        out.push((0..n).map(|_| [rng.next(), rng.next()]).collect());
    }
    out
}

/// The grouped solver values at a configuration.
type Values<'a> = dyn Fn(&[Vec2]) -> Vec<(&'static str, f64)> + 'a;

const STEPS: [f64; 5] = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7];

/// Per group: the relative error at each step (`None` for a group whose derivative is zero in
/// every direction: then the largest |fd| instead, absolute).
struct Table {
    groups: Vec<(&'static str, f64, Vec<f64>)>,
}

/// `q(x)`: the grouped solver values at a configuration; `an`: the grouped analytic
/// derivatives at `x0`.
fn fd_table(x0: &[Vec2], q: &Values, an: &[(&'static str, f64, Lin)]) -> Table {
    fd_table_with(x0, q, an, false)
}

/// `fd_table`; with `richardson`, the central difference's first-order error term (a kink in
/// the second derivative) eliminated: `2 fd(h/2) - fd(h)`.
fn fd_table_with(
    x0: &[Vec2],
    q: &Values,
    an: &[(&'static str, f64, Lin)],
    richardson: bool,
) -> Table {
    let dirs = directions(x0.len());
    let mut names: Vec<&'static str> = Vec::new();
    for (g, _, _) in an {
        if !names.contains(g) {
            names.push(g);
        }
    }
    let moved = |v: &[Vec2], h: f64| -> Vec<Vec2> {
        x0.iter().zip(v).map(|(p, d)| [p[0] + h * d[0], p[1] + h * d[1]]).collect()
    };
    // [direction][step][entry]
    let fd: Vec<Vec<Vec<f64>>> = dirs
        .iter()
        .map(|v| {
            STEPS
                .iter()
                .map(|&h| {
                    let central = |h: f64| -> Vec<f64> {
                        let (p, m) = (q(&moved(v, h)), q(&moved(v, -h)));
                        assert_eq!(p.len(), an.len(), "quantity list changed under perturbation");
                        p.iter().zip(&m).map(|(a, b)| (a.1 - b.1) / (2.0 * h)).collect()
                    };
                    if richardson {
                        let (a, b) = (central(0.5 * h), central(h));
                        a.iter().zip(&b).map(|(a, b)| 2.0 * a - b).collect()
                    } else {
                        central(h)
                    }
                })
                .collect()
        })
        .collect();
    let mut groups = Vec::new();
    for g in names {
        let idx: Vec<usize> = (0..an.len()).filter(|&i| an[i].0 == g).collect();
        let norm = |f: &dyn Fn(usize) -> f64| idx.iter().map(|&i| f(i).powi(2)).sum::<f64>().sqrt();
        let scale = dirs.iter().map(|v| norm(&|i| an[i].2.apply(v))).fold(0.0, f64::max);
        let errs: Vec<f64> = (0..STEPS.len())
            .map(|s| {
                dirs.iter()
                    .enumerate()
                    .map(|(d, v)| norm(&|i| fd[d][s][i] - an[i].2.apply(v)))
                    .fold(0.0, f64::max)
                    / if scale > 0.0 { scale } else { 1.0 }
            })
            .collect();
        groups.push((g, scale, errs));
    }
    Table { groups }
}

impl Table {
    fn print(&self, title: &str) {
        println!("\n{title}");
        print!("  {:<30} {:>9}", "quantity", "|delta|");
        for h in STEPS {
            print!(" {:>9}", format!("h={h:.0e}"));
        }
        println!();
        for (g, scale, errs) in &self.groups {
            print!("  {:<30} {:>9.2e}", g, scale);
            for e in errs {
                print!(" {:>9.1e}", e);
            }
            println!();
        }
    }

    /// Every group: below `tol` at some step, and falling like h^2 (a factor >= 50 per
    /// decade) between steps where the error is above the round-off level `floor`. A group
    /// with zero derivative: |fd| below round-off, 1e-14/h.
    fn assert_second_order(&self, title: &str, tol: f64, floor: f64) {
        for (g, scale, errs) in &self.groups {
            if *scale == 0.0 {
                // Round-off of the values (~1e-15) over the step.
                let ok = errs.iter().zip(STEPS).all(|(&e, h)| e <= 1e-14 / h);
                assert!(ok, "{title}: {g}: zero derivative, fd {errs:?}");
                continue;
            }
            let best = errs.iter().copied().fold(f64::INFINITY, f64::min);
            assert!(best < tol, "{title}: {g}: best relative error {best:e}");
            for w in errs.windows(2) {
                if w[1] > floor {
                    assert!(w[0] / w[1] > 50.0, "{title}: {g}: not second order: {errs:?}");
                }
            }
        }
    }
}

// ---------------- tests ----------------

#[test]
fn lin_algebra() {
    let a = Lin::from_entries([((2, 1), 1.0), ((0, 0), 2.0), ((2, 1), 0.5)]);
    assert_eq!(a.entries(), &[((0, 0), 2.0), ((2, 1), 1.5)]);
    let b = Lin::unit(1, 0);
    let c = Lin::combine(2.0, &a, -1.0, &b);
    assert_eq!(c.entries(), &[((0, 0), 4.0), ((1, 0), -1.0), ((2, 1), 3.0)]);
    assert_eq!(c.get(1, 0), -1.0);
    assert_eq!(c.get(1, 1), 0.0);
    assert_eq!(Lin::sum(&[(2.0, &a), (-1.0, &b)]), c);
    let mut d = a.clone();
    d.add_scaled(-1.0, &a);
    assert!(d.is_zero() && !a.is_zero());
    assert_eq!(a.add(&b).scale(2.0), Lin::combine(2.0, &a, 2.0, &b));
    let dir = [[1.0, 10.0], [100.0, 1000.0], [0.5, 0.25]];
    assert_eq!(c.apply(&dir), 4.0 - 100.0 + 0.75);
    let v = lin2_node(2);
    assert_eq!(lin2_cross([1.0, 2.0], &v).apply(&dir), 1.0 * 0.25 - 2.0 * 0.5);
    assert_eq!(lin2_dot([1.0, 2.0], &v).apply(&dir), 0.5 + 0.5);
}

/// The linearized pair returns `mortar_pair_2d`'s integrals (bit for bit; asserted to 1e-14),
/// the same `None`s, and the segment ends the case is meant to have.
#[test]
fn linearized_pair_returns_the_solver_integrals() {
    for (c, ends) in cases() {
        let x = &c.x;
        let normals = nodal_normals_2d(x, &c.slave_facets, false).unwrap();
        let nl = nodal_normals_lin_2d(x, &c.slave_facets, false).unwrap();
        for (n, l) in normals.iter().zip(&nl) {
            assert_eq!(*n, l.value, "{}: nodal normal", c.name);
        }
        let nrm = [normals[c.ids.slave[0]], normals[c.ids.slave[1]]];
        let lins = [nl[c.ids.slave[0]].lin.clone(), nl[c.ids.slave[1]].lin.clone()];
        let (s, m) = facets(&c, x);
        let dual = dual_basis_2d(&s).unwrap();
        let p = mortar_pair_2d(&s, &nrm, &dual, &m).unwrap();
        let q = mortar_pair_lin_2d(&s, &nrm, &dual, &m, c.ids, &lins).unwrap();
        match (p, q) {
            (None, None) => assert!(ends.is_none(), "{}: no overlap", c.name),
            (Some(p), Some(q)) => {
                let diff = (0..2)
                    .flat_map(|j| {
                        [
                            p.m[j][0] - q.value.m[j][0],
                            p.m[j][1] - q.value.m[j][1],
                            p.psi_integral[j] - q.value.psi_integral[j],
                            p.weighted_gap[j] - q.value.weighted_gap[j],
                        ]
                    })
                    .chain([p.overlap_measure - q.value.overlap_measure])
                    .fold(0.0f64, |a, d| a.max(d.abs()));
                assert!(diff <= 1e-14, "{}: integrals differ by {diff:e}", c.name);
                assert_eq!(p, q.value, "{}: not bit for bit", c.name);
                assert_eq!(Some(q.ends), ends, "{}: segment ends", c.name);
            }
            (p, q) => {
                panic!("{}: mortar_pair_2d {:?}, linearized {:?}", c.name, p, q.map(|q| q.value))
            }
        }
    }
}

/// On a line2 facet `A_e = [[2, -1], [-1, 2]]` whatever its nodes: the differences of the
/// solver's coefficients vanish to round-off, and `D`'s follow `delta J`.
#[test]
fn dual_coefficients_do_not_move() {
    let f = Facet2 { x: [[0.3, -0.2], [-0.9, 0.45]] };
    let dual = dual_basis_2d(&f).unwrap();
    for i in 0..2 {
        for k in 0..2 {
            let expect = if i == k { 2.0 } else { -1.0 };
            assert!((dual.a[i][k] - expect).abs() < 1e-14, "A = {:?}", dual.a);
        }
    }
    let mut rng = Lcg(3);
    for _ in 0..5 {
        let v: Vec<Vec2> = (0..2).map(|_| [rng.next(), rng.next()]).collect();
        let h = 1e-4;
        let g = |s: f64| Facet2 {
            x: [
                [f.x[0][0] + s * v[0][0], f.x[0][1] + s * v[0][1]],
                [f.x[1][0] + s * v[1][0], f.x[1][1] + s * v[1][1]],
            ],
        };
        let (p, m) = (dual_basis_2d(&g(h)).unwrap(), dual_basis_2d(&g(-h)).unwrap());
        for i in 0..2 {
            for k in 0..2 {
                let fd = (p.a[i][k] - m.a[i][k]) / (2.0 * h);
                assert!(fd.abs() < 1e-10, "dA/dx = {fd:e}");
            }
        }
    }
}

/// Every derivative of every pair configuration against central differences.
#[test]
fn pair_derivatives_match_central_differences() {
    for (c, ends) in cases() {
        let (an, p) = analytic(&c, &c.x);
        let with_segment = p.is_some();
        let sv = solver_values(&c, &c.x, with_segment);
        assert_eq!(sv.len(), an.len());
        for (s, a) in sv.iter().zip(&an) {
            assert!((s.1 - a.1).abs() <= 1e-14, "{}: {} value {} vs {}", c.name, s.0, s.1, a.1);
        }
        let q = |x: &[Vec2]| solver_values(&c, x, with_segment);
        let t = fd_table(&c.x, &q, &an);
        t.print(&format!("{} (ends {:?}); relative error of central differences", c.name, ends));
        t.assert_second_order(c.name, 1e-6, 1e-8);
        if ends.is_none() {
            // No overlap: the integrals and their derivatives are zero.
            for g in &GROUPS[8..] {
                assert!(t.groups.iter().any(|(n, s, _)| n == g && *s == 0.0), "{g} not zero");
            }
        }
    }
}

// ---------------- assembled patches ----------------

/// A slave chain (right to left, nodes `0..ns`) and a master chain (left to right, nodes
/// `ns..`), every slave facet tried against every master facet, as the interface sums them.
struct Patch {
    x: Vec<Vec2>,
    ns: usize,
    slave_facets: Vec<[usize; 2]>,
    master_facets: Vec<[usize; 2]>,
}

fn patch(slave: &[Vec2], master: &[Vec2]) -> Patch {
    let ns = slave.len();
    let x: Vec<Vec2> = slave.iter().chain(master).map(|&p| rigid(p)).collect();
    Patch {
        ns,
        slave_facets: (0..ns - 1).map(|i| [i, i + 1]).collect(),
        master_facets: (0..master.len() - 1).map(|i| [ns + i, ns + i + 1]).collect(),
        x,
    }
}

const PATCH_GROUPS: [&str; 4] = ["D_q", "N_q", "M_ql", "g_q"];

/// `D_q`, `N_q`, `M_ql` (all slave q, all master l), `g_q`, summed over the pairs; with
/// derivatives when `lin` (else zero derivatives).
fn assembled(p: &Patch, x: &[Vec2], lin: bool) -> Vec<(&'static str, f64, Lin)> {
    let ns = p.ns;
    let nm = x.len() - ns;
    let mut d = vec![(0.0, Lin::zero()); ns];
    let mut n = vec![(0.0, Lin::zero()); ns];
    let mut g = vec![(0.0, Lin::zero()); ns];
    let mut m = vec![vec![(0.0, Lin::zero()); nm]; ns];
    let add = |a: &mut (f64, Lin), v: f64, dv: Option<&Lin>| {
        a.0 += v;
        if let Some(dv) = dv {
            a.1.add_scaled(1.0, dv);
        }
    };
    let normals = nodal_normals_2d(x, &p.slave_facets, false).unwrap();
    let nl = nodal_normals_lin_2d(x, &p.slave_facets, false).unwrap();
    for sf in &p.slave_facets {
        let s = Facet2::from_nodes(x, *sf).unwrap();
        let (dual, dd) = dual_basis_lin_2d(&s, *sf).unwrap();
        for k in 0..2 {
            add(&mut d[sf[k]], dual.d[k], lin.then_some(&dd[k]));
        }
        let nrm = [normals[sf[0]], normals[sf[1]]];
        let lins = [nl[sf[0]].lin.clone(), nl[sf[1]].lin.clone()];
        for mf in &p.master_facets {
            let mfac = Facet2::from_nodes(x, *mf).unwrap();
            let ids = PairIds2 { slave: *sf, master: *mf };
            if lin {
                let Some(q) = mortar_pair_lin_2d(&s, &nrm, &dual, &mfac, ids, &lins).unwrap()
                else {
                    continue;
                };
                for j in 0..2 {
                    add(&mut n[sf[j]], q.value.psi_integral[j], Some(&q.psi_integral[j]));
                    add(&mut g[sf[j]], q.value.weighted_gap[j], Some(&q.weighted_gap[j]));
                    for l in 0..2 {
                        add(&mut m[sf[j]][mf[l] - ns], q.value.m[j][l], Some(&q.m[j][l]));
                    }
                }
            } else {
                let Some(q) = mortar_pair_2d(&s, &nrm, &dual, &mfac).unwrap() else { continue };
                for j in 0..2 {
                    add(&mut n[sf[j]], q.psi_integral[j], None);
                    add(&mut g[sf[j]], q.weighted_gap[j], None);
                    for l in 0..2 {
                        add(&mut m[sf[j]][mf[l] - ns], q.m[j][l], None);
                    }
                }
            }
        }
    }
    let mut out = Vec::new();
    out.extend(d.into_iter().map(|(v, l)| (PATCH_GROUPS[0], v, l)));
    out.extend(n.into_iter().map(|(v, l)| (PATCH_GROUPS[1], v, l)));
    out.extend(m.into_iter().flatten().map(|(v, l)| (PATCH_GROUPS[2], v, l)));
    out.extend(g.into_iter().map(|(v, l)| (PATCH_GROUPS[3], v, l)));
    out
}

fn patch_table(p: &Patch) -> (Table, Vec<(&'static str, f64, Lin)>) {
    let an = assembled(p, &p.x, true);
    let sv = assembled(p, &p.x, false);
    for (a, s) in an.iter().zip(&sv) {
        assert!((a.1 - s.1).abs() <= 1e-14, "{}: {} vs {}", a.0, a.1, s.1);
    }
    let q = |x: &[Vec2]| assembled(p, x, false).into_iter().map(|(g, v, _)| (g, v)).collect();
    (fd_table(&p.x, &q, &an), an)
}

/// Matching meshes: every interior master node sits on a slave node's normal, a switching
/// point of every pair around it. A pair's own integrals have a kink there (its segment end
/// jumps from the slave node to the master node's projection), but summed over the master
/// facets around the node the first derivative is the same from both sides (the integrand
/// is continuous across the master node) and the rule's choice (the slave end) gives it. The
/// second derivatives differ from side to side, so central differences of `M` converge only
/// like h (first order) here, with a clean `c h` error term: eliminating it by Richardson
/// extrapolation restores h^2, i.e. the derivative is exact. (`N`, `D`, and `g` on this
/// straight master are smooth to second order: `sum_l phi_l = 1` and the master line has no
/// kink.)
#[test]
fn matching_meshes_assembled() {
    let d = 0.02;
    let xs = [1.0, 0.62, 0.3, 0.0];
    let slave: Vec<Vec2> = xs.iter().map(|&a| [a, 0.0]).collect();
    let master: Vec<Vec2> = [-0.4, 0.0, 0.3, 0.62, 1.0, 1.4].iter().map(|&a| [a, d]).collect();
    let p = patch(&slave, &master);
    let (t, an) = patch_table(&p);
    t.print("matching meshes, assembled over all pairs; relative error of central differences");
    let q = |x: &[Vec2]| assembled(&p, x, false).into_iter().map(|(g, v, _)| (g, v)).collect();
    let r = fd_table_with(&p.x, &q, &an, true);
    r.print("the same, Richardson-extrapolated differences 2 fd(h/2) - fd(h)");
    r.assert_second_order("matching, extrapolated", 1e-6, 1e-8);
    for (g, scale, errs) in &t.groups {
        let best = errs.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(*scale > 0.0 && best < 1e-6, "matching: {g}: {errs:?}");
        // At least first order: a factor >= 5 per decade while above round-off.
        for w in errs.windows(2) {
            if w[1] > 1e-8 {
                assert!(w[0] / w[1] > 5.0, "matching: {g}: {errs:?}");
            }
        }
    }
    // Full overlap: sum_l M_ql = D_qq, with the same derivative.
    let ns = p.ns;
    let nm = p.x.len() - ns;
    for q in 0..ns {
        let row = Lin::sum(&(0..nm).map(|l| (1.0, &an[2 * ns + q * nm + l].2)).collect::<Vec<_>>());
        let diff = Lin::combine(1.0, &row, -1.0, &an[q].2);
        assert!(diff.max_abs() < 1e-13, "delta sum_l M_ql != delta D_qq: {diff:?}");
    }
}

/// Non-matching meshes with a slave node off the master: the last slave node's support lies
/// beside the master, so its row of M, its N and its gap are zero, and so are their
/// derivatives (no entries at all); the rest converges like h^2.
#[test]
fn slave_node_off_the_master_assembled() {
    let xs = [1.0, 0.6, 0.3, 0.0];
    let slave: Vec<Vec2> = xs.iter().zip([0.0, 0.01, -0.005, 0.0]).map(|(&a, b)| [a, b]).collect();
    let master: Vec<Vec2> = [[0.45, 0.03], [0.8, 0.02], [1.4, 0.04]].to_vec();
    let p = patch(&slave, &master);
    let (t, an) = patch_table(&p);
    t.print("non-matching, last slave node off the master, assembled; relative errors");
    t.assert_second_order("off the master", 1e-6, 1e-8);
    let (ns, nm) = (p.ns, p.x.len() - p.ns);
    let q = ns - 1;
    let zero: Vec<&(&str, f64, Lin)> = [ns + q, 2 * ns + ns * nm + q]
        .into_iter()
        .chain((0..nm).map(|l| 2 * ns + q * nm + l))
        .map(|i| &an[i])
        .collect();
    for (g, v, l) in zero {
        assert!(*v == 0.0 && l.entries().is_empty(), "node {q}: {g} = {v}, delta {l:?}");
    }
}

// ---------------- at a switching point ----------------

/// The pair's integrals (`M`, `N`, `g`, overlap): the solver's values, and the analytic
/// values with derivatives.
fn integrals(c: &Case, x: &[Vec2]) -> Vec<f64> {
    let keep = &GROUPS[8..];
    solver_values(c, x, false).into_iter().filter(|e| keep.contains(&e.0)).map(|e| e.1).collect()
}

fn integrals_lin(c: &Case, x: &[Vec2]) -> (Vec<f64>, Vec<Lin>, Option<[SegmentEnd; 2]>) {
    let keep = &GROUPS[8..];
    let (an, p) = analytic(c, x);
    let (v, l) = an.into_iter().filter(|e| keep.contains(&e.0)).map(|e| (e.1, e.2)).unzip();
    (v, l, p.map(|p| p.ends))
}

/// At a switching point the derivative is one-sided. Two switching points of one pair, with
/// master node 0 placed exactly on a slave node's normal ray:
///
/// * "end switch": the ray of the segment's slave end. The rule keeps the slave end
///   (`delta xi = 0`): the derivative of the side where the master covers the slave node.
///   Forward differences towards that side converge to it (first order, as forward
///   differences do); towards the other side they converge to the derivative there (the
///   analytic one at a point 1e-9 away), which differs: the segment end then follows the
///   master node's projection.
/// * "touching": the master facet ends where the slave facet ends. The pair has no overlap
///   (`None`, zero derivative): the derivative of the side where they are apart. Moving the
///   master node towards the slave opens an overlap whose integrals grow linearly: the
///   one-sided derivative there is the integrand at the end times the opening rate.
#[test]
fn switching_points_have_one_sided_derivatives() {
    let flat = chain(&[1.9, 1.0, 0.0, -0.8], &[0.05, 0.0, 0.0, -0.03]);
    for (name, node, far) in
        [("end switch", 2usize, [1.4, 0.05]), ("touching", 1usize, [1.6, 0.04])]
    {
        let mut c = case(name, &flat, [[0.0, 0.03], far], 1);
        let n = nodal_normals_2d(&c.x, &c.slave_facets, false).unwrap();
        c.x[4] = add2(c.x[node], scale2(0.03, n[node]));
        let (v0, l0, ends) = integrals_lin(&c, &c.x);
        let tm = sub2(c.x[5], c.x[4]);
        let tm = scale2(1.0 / norm2(tm), tm);
        let dir = |s: f64| -> Vec<Vec2> {
            let mut v = vec![[0.0; 2]; c.x.len()];
            v[4] = scale2(s, tm);
            v
        };
        // Master node 0 moved along the master line: away from master node 1 (over the slave
        // node in "end switch", onto the slave facet in "touching"), or towards it.
        let sides = [("-t_m (node 0 outwards)", dir(-1.0)), ("+t_m (node 0 inwards)", dir(1.0))];
        println!("\n{name}: ends at the switch {ends:?}; forward differences, |fd - Lin|/|Lin|");
        for (label, v) in sides {
            let moved = |h: f64| -> Vec<Vec2> {
                c.x.iter().zip(&v).map(|(p, d)| [p[0] + h * d[0], p[1] + h * d[1]]).collect()
            };
            let at = |l: &[Lin]| -> Vec<f64> { l.iter().map(|l| l.apply(&v)).collect() };
            let an_switch = at(&l0);
            let (_, l_near, ends_near) = integrals_lin(&c, &moved(1e-9));
            let an_side = at(&l_near);
            let norm = |a: &[f64]| a.iter().map(|x| x * x).sum::<f64>().sqrt();
            let diff = |a: &[f64], b: &[f64]| -> Vec<f64> {
                a.iter().zip(b).map(|(x, y)| x - y).collect()
            };
            // Relative to the derivatives' size (absolute where both are zero: no overlap).
            let scale = norm(&an_side).max(norm(&an_switch)).max(1e-300);
            let jump = norm(&diff(&an_switch, &an_side)) / scale;
            print!("  {label:<24} ends there {ends_near:?}, |Lin| {:.2e} at the switch, {:.2e} there, jump {jump:.1e}:", norm(&an_switch), norm(&an_side));
            let mut errs = Vec::new();
            for h in STEPS {
                let fd: Vec<f64> =
                    integrals(&c, &moved(h)).iter().zip(&v0).map(|(a, b)| (a - b) / h).collect();
                let e = norm(&diff(&fd, &an_side)) / scale;
                print!(" h={h:.0e}: {e:.1e}");
                errs.push(e);
            }
            println!();
            // Converges to the derivative of the side it moves to (first order).
            let zero = norm(&an_side) == 0.0;
            assert!(
                (zero && errs.iter().all(|&e| e == 0.0))
                    || (errs[4] < 1e-5 && errs[0] / errs[3] > 300.0),
                "{name}, {label}: {errs:?}"
            );
            let rule_side = jump < 1e-6;
            match (name, label.contains("outwards")) {
                ("end switch", true) | ("touching", false) => {
                    assert!(rule_side, "{name}, {label}: the rule's side, jump {jump:e}")
                }
                _ => assert!(jump > 1e-2, "{name}, {label}: a real switch, jump {jump:e}"),
            }
        }
        match name {
            "end switch" => assert_eq!(ends, Some([SegmentEnd::Slave(0), SegmentEnd::Slave(1)])),
            _ => assert_eq!(ends, None),
        }
    }
}
