//! Checks of the 3D linearizations against central finite differences of the functions the
//! solver uses (`nodal_normals_3d`, `dual_basis_3d`, `AuxPlane`, `invert_on_plane`,
//! `clip_polygon`, `mortar_pair_3d`).
//!
//! A configuration is a list of involved nodes: the slave patch (the pair's slave facet first,
//! then neighbours that enter the averaged nodal normals), then the master facet. A direction
//! `V` gives every coordinate a velocity; `(q(X + h V) - q(X - h V)) / 2h` must approach the
//! analytic `delta q [V]` like `h^2` until round-off. Errors per group of quantities, relative
//! to the group's largest analytic derivative over the directions:
//! `err(h) = max_V |fd_V - an_V|_2 / max_V |an_V|_2`. Run with `--nocapture` for the tables.

use super::*;
use crate::contact::mortar::dual::{dual_basis_3d, nodal_normals_3d};
use crate::contact::mortar::segment::{
    clip_polygon, dedupe_polygon, invert_on_plane, mortar_pair_3d, polygon_area, AuxPlane,
    PairIntegrals,
};

// ---------------- configurations ----------------

#[derive(Clone)]
struct Case {
    name: &'static str,
    x: Vec<Vec3>,
    /// Slave patch facets (indices into `x`); the first is the pair's slave facet.
    patch: Vec<Vec<usize>>,
    /// Number of patch nodes (they come first in `x`).
    np: usize,
    master: Vec<usize>,
    /// Master node `l` moves with patch node `twin[l]` (matching meshes moved together).
    twin: Option<Vec<usize>>,
}

/// A rigid motion off the axes.
fn rigid(p: Vec3) -> Vec3 {
    let (s, c) = 0.5f64.sin_cos();
    let (s2, c2) = 0.3f64.sin_cos();
    // rotation about z by 0.5, then about x by 0.3, then a shift.
    let a = [c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]];
    [a[0] + 0.2, c2 * a[1] - s2 * a[2] - 0.4, s2 * a[1] + c2 * a[2] + 0.7]
}

fn case(name: &'static str, patch_x: &[Vec3], patch: &[&[usize]], master_x: &[Vec3]) -> Case {
    let np = patch_x.len();
    let mut x = patch_x.to_vec();
    x.extend_from_slice(master_x);
    Case {
        name,
        x: x.into_iter().map(rigid).collect(),
        patch: patch.iter().map(|f| f.to_vec()).collect(),
        np,
        master: (np..np + master_x.len()).collect(),
        twin: None,
    }
}

/// A warped, non-parallelogram slave quad (normal +z) with a neighbour on its right.
fn quad_patch() -> (Vec<Vec3>, Vec<&'static [usize]>) {
    (
        vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.03],
            [1.1, 1.0, -0.02],
            [0.0, 0.9, 0.01],
            [2.0, 0.0, 0.1],
            [2.1, 1.0, 0.12],
        ],
        vec![&[0, 1, 2, 3], &[1, 4, 5, 2]],
    )
}

/// A tilted slave triangle (normal ~ +z) with a neighbour.
fn tri_patch() -> (Vec<Vec3>, Vec<&'static [usize]>) {
    (
        vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.02], [0.1, 1.0, -0.03], [1.1, 1.05, 0.1]],
        vec![&[0, 1, 2], &[1, 3, 2]],
    )
}

/// Master quad facing down (clockwise seen from above), left edge at `x ~ s`.
fn master_quad(s: f64) -> Vec<Vec3> {
    vec![[s, 0.3, 0.05], [s + 0.01, 1.35, 0.07], [1.4, 1.3, 0.04], [1.45, 0.25, 0.06]]
}

fn cases() -> Vec<(Case, Option<Vec<PolyVertex>>)> {
    use PolyVertex::*;
    let (qx, qf) = quad_patch();
    let (tx, tf) = tri_patch();
    let mut out = vec![
        // Partial overlap of non-matching quads: all three vertex kinds.
        (case("quad/quad partial (warped)", &qx, &qf, &master_quad(0.4)), None),
        // Triangles, partial: master nodes and crossings.
        (
            case(
                "tri/tri partial",
                &tx,
                &tf,
                &[[0.3, 0.2, 0.04], [0.15, 0.75, 0.06], [1.0, 0.6, 0.03]],
            ),
            None,
        ),
        // A tilted master quad covering the slave triangle: the polygon is the slave's.
        (
            case(
                "tri in tilted quad",
                &tx,
                &tf,
                &[[-0.5, -0.5, 0.1], [-0.5, 1.6, 0.2], [1.6, 1.6, 0.15], [1.6, -0.5, 0.05]],
            ),
            Some(vec![Slave(0), Slave(1), Slave(2)]),
        ),
        // A master triangle inside the warped slave quad: the polygon is the master's.
        (
            case(
                "tri inside warped quad",
                &qx,
                &qf,
                &[[0.2, 0.2, 0.05], [0.4, 0.7, 0.08], [0.8, 0.3, 0.02]],
            ),
            None,
        ),
        // Both sides of a switch: slave node 3 (0, 0.9) just inside / just outside the master.
        (case("slave node just inside the master", &qx, &qf, &master_quad(-0.02)), None),
        (case("slave node just outside the master", &qx, &qf, &master_quad(0.02)), None),
    ];
    // Matching, touching quads moved together (the master is the slave facet reversed).
    let mut m = case("matching quads moved together", &qx, &qf, &[qx[3], qx[2], qx[1], qx[0]]);
    m.twin = Some(vec![3, 2, 1, 0]);
    out.push((m, None));
    out
}

// ---------------- the quantities, twice ----------------

const GROUPS: [&str; 15] = [
    "n_q (nodal normals)",
    "e (facet unit normal at a point)",
    "J (slave Jacobian at a point)",
    "d_j (D of the facet)",
    "A (dual coefficients)",
    "aux plane (x0, n0, e1, e2)",
    "projected nodes (slave, master)",
    "xi_s, xi_m (inverse maps)",
    "polygon vertices",
    "polygon centre",
    "sub-triangle areas",
    "M_jl",
    "N_j",
    "g_j (weighted gaps)",
    "overlap area",
];

fn point(f: &Facet3) -> Vec2 {
    match f {
        Facet3::Tri3(_) => [0.2, 0.3],
        Facet3::Quad4(_) => [0.3, -0.4],
    }
}

fn facets(c: &Case, x: &[Vec3]) -> (Facet3, Facet3) {
    (Facet3::from_nodes(x, &c.patch[0]).unwrap(), Facet3::from_nodes(x, &c.master).unwrap())
}

/// The plane point where both inverse maps are checked: halfway between the facet centres.
fn probe(plane: &AuxPlane, m: &Facet3) -> Vec2 {
    scale2(0.5, plane.coords(m.position(m.centre_param())))
}

fn solver_values(c: &Case, x: &[Vec3]) -> Vec<(&'static str, f64)> {
    let mut out = Vec::new();
    let normals = nodal_normals_3d(&x[..c.np], &c.patch, false).unwrap();
    let nrm: Vec<Vec3> = c.patch[0].iter().map(|&k| normals[k]).collect();
    for n in &nrm {
        out.extend(n.iter().map(|&v| (GROUPS[0], v)));
    }
    let (s, m) = facets(c, x);
    let e = s.normal(point(&s));
    out.extend(e.iter().map(|&v| (GROUPS[1], v / norm3(e))));
    out.push((GROUPS[2], s.jacobian(point(&s))));
    let dual = dual_basis_3d(&s).unwrap();
    out.extend(dual.d[..dual.n].iter().map(|&v| (GROUPS[3], v)));
    for i in 0..dual.n {
        out.extend(dual.a[i][..dual.n].iter().map(|&v| (GROUPS[4], v)));
    }
    let plane = AuxPlane::of_slave(&s).unwrap();
    for v in [plane.centre, plane.normal, plane.e1, plane.e2] {
        out.extend(v.iter().map(|&v| (GROUPS[5], v)));
    }
    for &y in s.nodes().iter().chain(m.nodes()) {
        out.extend(plane.coords(y).iter().map(|&v| (GROUPS[6], v)));
    }
    let q = probe(&plane, &m);
    for f in [&s, &m] {
        out.extend(invert_on_plane(f, &plane, q).unwrap().iter().map(|&v| (GROUPS[7], v)));
    }
    // The polygon as mortar_pair_3d builds it.
    let sp: Vec<Vec2> = s.nodes().iter().map(|&y| plane.coords(y)).collect();
    let mut mp: Vec<Vec2> = m.nodes().iter().map(|&y| plane.coords(y)).collect();
    mp.reverse();
    let h2 = s.size().powi(2);
    let h = polygon_area(&sp).sqrt();
    let poly = dedupe_polygon(clip_polygon(&mp, &sp, 1e-13 * h2), 1e-12 * h);
    for p in &poly {
        out.extend(p.iter().map(|&v| (GROUPS[8], v)));
    }
    if !poly.is_empty() {
        let inv_n = 1.0 / poly.len() as f64;
        let c = poly.iter().fold([0.0; 2], |acc, &p| add2(acc, scale2(inv_n, p)));
        out.extend(c.iter().map(|&v| (GROUPS[9], v)));
        for i in 0..poly.len() {
            let (p1, p2) = (poly[i], poly[(i + 1) % poly.len()]);
            out.push((GROUPS[10], 0.5 * cross2(sub2(p1, c), sub2(p2, c))));
        }
    }
    let p = mortar_pair_3d(&s, &nrm, &dual, &m)
        .unwrap()
        .unwrap_or(PairIntegrals::zero(s.n_nodes(), m.n_nodes()));
    for j in 0..p.n_slave {
        out.extend(p.m[j][..p.n_master].iter().map(|&v| (GROUPS[11], v)));
    }
    out.extend(p.psi_integral[..p.n_slave].iter().map(|&v| (GROUPS[12], v)));
    out.extend(p.weighted_gap[..p.n_slave].iter().map(|&v| (GROUPS[13], v)));
    out.push((GROUPS[14], p.overlap_measure));
    out
}

fn ids4(v: &[usize]) -> [usize; 4] {
    let mut a = [0; 4];
    a[..v.len()].copy_from_slice(v);
    a
}

fn analytic(c: &Case, x: &[Vec3]) -> (Vec<(&'static str, f64, Lin)>, Option<PairIntegralsLin3>) {
    let mut out = Vec::new();
    let normals = nodal_normals_lin_3d(&x[..c.np], &c.patch, false).unwrap();
    let nrm: Vec<Vec3Lin> = c.patch[0].iter().map(|&k| normals[k].clone()).collect();
    for n in &nrm {
        for k in 0..3 {
            out.push((GROUPS[0], n.value[k], n.lin[k].clone()));
        }
    }
    let (s, m) = facets(c, x);
    let sid = &c.patch[0][..];
    let e = facet_normal_lin_3d(&s, sid, point(&s)).unwrap();
    for k in 0..3 {
        out.push((GROUPS[1], e.value[k], e.lin[k].clone()));
    }
    let (j, dj) = jacobian_lin_3d(&s, sid, point(&s));
    out.push((GROUPS[2], j, dj));
    let dual = dual_basis_lin_3d(&s, sid).unwrap();
    let n = dual.value.n;
    for jj in 0..n {
        out.push((GROUPS[3], dual.value.d[jj], dual.d[jj].clone()));
    }
    for i in 0..n {
        for k in 0..n {
            out.push((GROUPS[4], dual.value.a[i][k], dual.a[i][k].clone()));
        }
    }
    let plane = aux_plane_lin(&s, sid).unwrap();
    let pv = plane.value;
    for (v, d) in [
        (pv.centre, &plane.centre),
        (pv.normal, &plane.normal),
        (pv.e1, &plane.e1),
        (pv.e2, &plane.e2),
    ] {
        for k in 0..3 {
            out.push((GROUPS[5], v[k], d[k].clone()));
        }
    }
    for (&y, &id) in s.nodes().iter().chain(m.nodes()).zip(sid.iter().chain(&c.master)) {
        let q = plane.coords_lin(&Vec3Lin::node(id, y));
        for k in 0..2 {
            out.push((GROUPS[6], q.value[k], q.lin[k].clone()));
        }
    }
    // probe = (1/2) P(x_m(centre)), x_m(centre) = sum_l phi_l(centre) y_l.
    let phic = m.shape(m.centre_param());
    let yc = Vec3Lin {
        value: m.position(m.centre_param()),
        lin: {
            let nodes: Vec<Lin3> = c.master.iter().map(|&k| lin3_node(k)).collect();
            lin3_sum(&(0..c.master.len()).map(|l| (phic[l], &nodes[l])).collect::<Vec<_>>())
        },
    };
    let qc = plane.coords_lin(&yc);
    let q =
        Vec2Lin { value: scale2(0.5, qc.value), lin: [qc.lin[0].scale(0.5), qc.lin[1].scale(0.5)] };
    for (f, ids) in [(&s, sid), (&m, &c.master[..])] {
        let (xi, dxi) = invert_on_plane_lin(f, ids, &plane, &q).unwrap();
        for k in 0..2 {
            out.push((GROUPS[7], xi[k], dxi[k].clone()));
        }
    }
    let nv: Vec<Vec3> = nrm.iter().map(|n| n.value).collect();
    let nl: Vec<Lin3> = nrm.iter().map(|n| n.lin.clone()).collect();
    let ids = PairIds3 { slave: ids4(sid), master: ids4(&c.master) };
    let p = mortar_pair_lin_3d(&s, &nv, &dual.value, &m, ids, &nl).unwrap();
    if let Some(p) = &p {
        for (v, d) in p.polygon.iter().zip(&p.polygon_lin) {
            for k in 0..2 {
                out.push((GROUPS[8], v[k], d[k].clone()));
            }
        }
        for k in 0..2 {
            out.push((GROUPS[9], p.centre[k], p.centre_lin[k].clone()));
        }
        for (a, d) in p.sub_areas.iter().zip(&p.sub_areas_lin) {
            out.push((GROUPS[10], *a, d.clone()));
        }
    }
    let (ns, nm) = (s.n_nodes(), m.n_nodes());
    let zero = PairIntegrals::zero(ns, nm);
    let v = p.as_ref().map_or(&zero, |p| &p.value);
    let d = |f: &dyn Fn(&PairIntegralsLin3) -> Lin| p.as_ref().map_or(Lin::zero(), f);
    for jj in 0..ns {
        for l in 0..nm {
            out.push((GROUPS[11], v.m[jj][l], d(&|p| p.m[jj][l].clone())));
        }
    }
    for jj in 0..ns {
        out.push((GROUPS[12], v.psi_integral[jj], d(&|p| p.psi_integral[jj].clone())));
    }
    for jj in 0..ns {
        out.push((GROUPS[13], v.weighted_gap[jj], d(&|p| p.weighted_gap[jj].clone())));
    }
    out.push((GROUPS[14], v.overlap_measure, d(&|p| p.overlap_measure.clone())));
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

/// Perturbation directions: every coordinate alone, and four random mixes of all. With
/// `twin`, master node `l` moves as patch node `twin[l]` (and has no directions of its own).
fn directions(c: &Case) -> Vec<Vec<Vec3>> {
    let n = c.x.len();
    let free = if c.twin.is_some() { c.np } else { n };
    let tie = |mut v: Vec<Vec3>| {
        if let Some(t) = &c.twin {
            for (l, &k) in t.iter().enumerate() {
                v[c.np + l] = v[k];
            }
        }
        v
    };
    let mut out = Vec::new();
    for a in 0..free {
        for k in 0..3 {
            let mut v = vec![[0.0; 3]; n];
            v[a][k] = 1.0;
            out.push(tie(v));
        }
    }
    let mut rng = Lcg(11);
    for _ in 0..4 {
        out.push(tie((0..n).map(|_| [rng.next(), rng.next(), rng.next()]).collect()));
    }
    out
}

/// Below this, an analytic derivative is round-off of an exact zero; the table then shows
/// absolute errors.
const ZERO: f64 = 1e-10;

const STEPS: [f64; 5] = [1e-3, 1e-4, 1e-5, 1e-6, 1e-7];

/// Per group: (name, largest analytic derivative, relative error at each step).
fn fd_table(c: &Case) -> Vec<(&'static str, f64, Vec<f64>)> {
    let (an, _) = analytic(c, &c.x);
    let dirs = directions(c);
    let mut names: Vec<&'static str> = Vec::new();
    for (g, _, _) in &an {
        if !names.contains(g) {
            names.push(g);
        }
    }
    let moved = |v: &[Vec3], h: f64| -> Vec<Vec3> {
        c.x.iter().zip(v).map(|(p, d)| add3(*p, scale3(h, *d))).collect()
    };
    let mut out = Vec::new();
    for g in names {
        let idx: Vec<usize> = (0..an.len()).filter(|&i| an[i].0 == g).collect();
        let mut amax: f64 = 0.0;
        let mut emax = vec![0.0f64; STEPS.len()];
        for v in &dirs {
            let a: Vec<f64> = idx.iter().map(|&i| lin_apply3(&an[i].2, v)).collect();
            amax = amax.max(a.iter().map(|x| x * x).sum::<f64>().sqrt());
            for (sidx, &h) in STEPS.iter().enumerate() {
                let (p, m) = (solver_values(c, &moved(v, h)), solver_values(c, &moved(v, -h)));
                assert_eq!(p.len(), an.len(), "{}: quantity list changed (h = {h})", c.name);
                assert_eq!(m.len(), an.len(), "{}: quantity list changed (h = {h})", c.name);
                let e: f64 = idx
                    .iter()
                    .zip(&a)
                    .map(|(&i, ai)| ((p[i].1 - m[i].1) / (2.0 * h) - ai).powi(2))
                    .sum::<f64>()
                    .sqrt();
                emax[sidx] = emax[sidx].max(e);
            }
        }
        let rel = if amax > ZERO { emax.iter().map(|e| e / amax).collect() } else { emax };
        out.push((g, amax, rel));
    }
    out
}

fn print_table(name: &str, t: &[(&'static str, f64, Vec<f64>)]) {
    println!("\n{name}");
    print!("  {:<34} {:>9}", "group", "max|an|");
    for h in STEPS {
        print!(" {:>9}", format!("h={h:.0e}"));
    }
    println!();
    for (g, a, e) in t {
        print!("  {:<34} {:>9.2e}", g, a);
        for x in e {
            print!(" {:>9.2e}", x);
        }
        println!();
    }
}

/// The group's derivative is right: below 1e-6 at some step, and second order while the
/// truncation error dominates (a factor >= 30 from h = 1e-3 to 1e-4 when err(1e-3) > 1e-9).
/// A group whose analytic derivative is round-off (max |an| <= ZERO, e.g. a triangle's dual
/// coefficients) is checked absolutely: |fd - an| below 1e-8 at some step.
fn check_table(name: &str, t: &[(&'static str, f64, Vec<f64>)]) {
    for (g, a, e) in t {
        let best = e.iter().copied().fold(f64::INFINITY, f64::min);
        if *a <= ZERO {
            assert!(best < 1e-8, "{name}: {g}: zero derivative but |fd| = {best:e}");
            continue;
        }
        assert!(best < 1e-6, "{name}: {g}: best relative error {best:e}");
        if e[0] > 1e-9 {
            assert!(e[0] / e[1] > 30.0, "{name}: {g}: not second order: {e:?}");
        }
    }
}

// ---------------- tests ----------------

fn values_match(c: &Case) {
    let sv = solver_values(c, &c.x);
    let (an, _) = analytic(c, &c.x);
    assert_eq!(sv.len(), an.len(), "{}", c.name);
    for ((g, v), (g2, w, _)) in sv.iter().zip(&an) {
        assert_eq!(g, g2, "{}", c.name);
        assert!((v - w).abs() <= 1e-14 * v.abs().max(1.0), "{}: {g}: {v} vs {w}", c.name);
    }
}

#[test]
fn values_are_the_solvers() {
    for (c, _) in cases() {
        values_match(&c);
        // And bit for bit where the same expressions run.
        let (s, m) = facets(&c, &c.x);
        let normals = nodal_normals_3d(&c.x[..c.np], &c.patch, false).unwrap();
        let nl = nodal_normals_lin_3d(&c.x[..c.np], &c.patch, false).unwrap();
        assert!(normals.iter().zip(&nl).all(|(a, b)| *a == b.value));
        let nrm: Vec<Vec3> = c.patch[0].iter().map(|&k| normals[k]).collect();
        let nlin: Vec<Lin3> = c.patch[0].iter().map(|&k| nl[k].lin.clone()).collect();
        let dual = dual_basis_3d(&s).unwrap();
        assert_eq!(dual_basis_lin_3d(&s, &c.patch[0]).unwrap().value, dual);
        assert_eq!(aux_plane_lin(&s, &c.patch[0]).unwrap().value, AuxPlane::of_slave(&s).unwrap());
        let ids = PairIds3 { slave: ids4(&c.patch[0]), master: ids4(&c.master) };
        let p = mortar_pair_3d(&s, &nrm, &dual, &m).unwrap();
        let pl = mortar_pair_lin_3d(&s, &nrm, &dual, &m, ids, &nlin).unwrap();
        assert_eq!(p, pl.map(|p| p.value), "{}", c.name);
    }
}

#[test]
fn polygon_vertex_kinds() {
    use PolyVertex::*;
    let mut seen_slave = false;
    let mut seen_master = false;
    let mut seen_crossing = false;
    for (c, expect) in cases() {
        let (_, p) = analytic(&c, &c.x);
        let p = p.expect("overlap");
        println!("{}: {:?}", c.name, p.kinds);
        if let Some(e) = expect {
            let mut k = p.kinds.clone();
            let mut e = e.clone();
            k.sort_by_key(|v| format!("{v:?}"));
            e.sort_by_key(|v| format!("{v:?}"));
            assert_eq!(k, e, "{}", c.name);
        }
        if c.name.starts_with("quad/quad partial") {
            for k in &p.kinds {
                match k {
                    Slave(_) => seen_slave = true,
                    Master(_) => seen_master = true,
                    Crossing { .. } => seen_crossing = true,
                    Other => panic!("degenerate vertex"),
                }
            }
        }
        if c.name.contains("just inside") {
            assert!(p.kinds.contains(&Slave(3)), "{:?}", p.kinds);
        }
        if c.name.contains("just outside") {
            assert!(!p.kinds.contains(&Slave(3)), "{:?}", p.kinds);
        }
    }
    assert!(seen_slave && seen_master && seen_crossing);
}

#[test]
fn derivatives_match_central_differences() {
    for (c, _) in cases() {
        let t = fd_table(&c);
        print_table(c.name, &t);
        check_table(c.name, &t);
    }
}

/// On an affine triangle the dual coefficients are `[[3,-1,-1],[-1,3,-1],[-1,-1,3]]` whatever
/// the nodes; on a general quad they move.
#[test]
fn dual_coefficients_of_triangles_do_not_move() {
    let (tx, _) = tri_patch();
    let x: Vec<Vec3> = tx.into_iter().map(rigid).collect();
    let f = Facet3::from_nodes(&x, &[0, 1, 2]).unwrap();
    let d = dual_basis_lin_3d(&f, &[0, 1, 2]).unwrap();
    for i in 0..3 {
        for k in 0..3 {
            let want = if i == k { 3.0 } else { -1.0 };
            assert!((d.value.a[i][k] - want).abs() < 1e-12);
            assert!(d.a[i][k].max_abs() < 1e-12, "{:?}", d.a[i][k]);
        }
    }
    let (qx, _) = quad_patch();
    let x: Vec<Vec3> = qx.into_iter().map(rigid).collect();
    let f = Facet3::from_nodes(&x, &[0, 1, 2, 3]).unwrap();
    let d = dual_basis_lin_3d(&f, &[0, 1, 2, 3]).unwrap();
    assert!(d.a[0][0].max_abs() > 1e-2, "a general quad's A moves: {:?}", d.a[0][0]);
}

/// Matching quads with a gap between them, the twins moved together: moving the slave turns
/// the projection direction `n0`, so the master nodes' projections leave the slave nodes by
/// O(h) and every vertex crosses its switch. The pair's `M` and `g` have a kink there; their
/// central differences stay O(0.1) away from the derivative returned (the side where the
/// master nodes are kept; see the module docs), at every step.
#[test]
fn matching_with_a_gap_is_a_switch() {
    let (qx, qf) = quad_patch();
    let f = Facet3::from_nodes(&qx, &[0, 1, 2, 3]).unwrap();
    let n0 = AuxPlane::of_slave(&f).unwrap().normal;
    let up = |p: Vec3| add3(p, scale3(0.05, n0));
    let mut m =
        case("matching with a gap", &qx, &qf, &[up(qx[3]), up(qx[2]), up(qx[1]), up(qx[0])]);
    m.twin = Some(vec![3, 2, 1, 0]);
    let (_, p) = analytic(&m, &m.x);
    let kinds = p.unwrap().kinds;
    assert!(kinds.iter().all(|k| matches!(k, PolyVertex::Master(_))), "{kinds:?}");
    let t = fd_table(&m);
    print_table(m.name, &t);
    let mjl = t.iter().find(|g| g.0 == GROUPS[11]).unwrap();
    assert!(mjl.2.iter().all(|&e| e > 1e-2), "M_jl converged at a switch? {:?}", mjl.2);
}
