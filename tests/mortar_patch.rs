//! The mortar patch test through the solver (issue 12): two blocks with non-matching interface
//! meshes (2D quads, triangles, mixed; 3D hexahedra, tetrahedra, mixed), pressed together by a
//! uniform traction `p` on the upper block's top, the lower block's bottom on rollers and every
//! side on rollers (confined compression).
//!
//! Exact solution: `u = 0` across the sides, `u_d = -p (x_d + 1) / (lambda + 2 mu)` along the
//! normal `d` (both blocks, continuous across the interface, zero at the bottom `x_d = -1`),
//! uniform stress, and a uniform contact pressure `p`. The dual mortar discretization
//! reproduces it exactly: `D^{-1} M` transfers linear fields exactly (`tests/mortar.rs`) and
//! `sum_q M_ql = int phi_l` on a flat, fully overlapped interface, so the master nodes receive
//! exactly the consistent load of the uniform pressure. The run starts from the exact field at
//! rest; any error in `D`, `M`, the change of basis, the Dirichlet rows in the mortar basis or
//! the forces moves it. Asserted to solver tolerance: every slave node's pressure equals `p`
//! at every step, and the displacement stays the exact one.

mod common;
use common::*;

const E: f64 = 100.0;
const NU: f64 = 0.3;
const P: f64 = 1.0;

/// `lambda + 2 mu` (the confined modulus).
fn confined() -> f64 {
    E * (1.0 - NU) / ((1.0 + NU) * (1.0 - 2.0 * NU))
}

struct Case {
    dim: usize,
    kind: u32,
    /// Cells per direction of the lower and upper blocks.
    n: (u32, u32),
    slave: &'static str,
    master: &'static str,
    mass: &'static str,
}

impl Case {
    /// The upper block's bottom as the slave side on the lower block's top.
    fn upper_on_lower(dim: usize, kind: u32, n: (u32, u32), mass: &'static str) -> Case {
        Case { dim, kind, n, slave: "upper_contact", master: "lower_contact", mass }
    }
}

fn scene(dir: &std::path::Path, c: &Case) -> std::path::PathBuf {
    let (geo, sides) = if c.dim == 2 {
        ("two_blocks_2d.geo", "[\"x\"]")
    } else {
        ("two_blocks_3d.geo", "[\"x\", \"y\"]")
    };
    let normal = if c.dim == 2 { "y" } else { "z" };
    let zeros = |k: usize| vec!["\"0\""; k].join(", ");
    let exact = format!("\"-{P} * ({normal} + 1) / {}\"", confined());
    let disp = format!("{}, {exact}", zeros(c.dim - 1));
    let traction = format!("{}, \"-{P}\"", zeros(c.dim - 1));
    let name = format!("patch{}d-k{}-{}", c.dim, c.kind, c.slave);
    let text = format!(
        r#"name = "{name}"
[mesh]
geo = "../meshes/{geo}"
params = {{ kind = {kind}, n_lower = {nl}, n_upper = {nu} }}
[material]
E = {E}
nu = {NU}
rho = 1.0
[[dirichlet]]
group = "lower_bottom"
components = ["{normal}"]
[[dirichlet]]
group = "lower_sides"
components = {sides}
[[dirichlet]]
group = "upper_sides"
components = {sides}
[[neumann]]
group = "upper_top"
traction = [{traction}]
[initial]
displacement = [{disp}]
[time]
tau = 1e-3
steps = 3
[mass]
kind = "{mass}"
[contact]
slave = "{slave}"
master = "{master}"
[output]
every = 1
"#,
        kind = c.kind,
        nl = c.n.0,
        nu = c.n.1,
        mass = c.mass,
        slave = c.slave,
        master = c.master,
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

/// Runs a case on `ranks` ranks and checks pressure and displacement against the exact
/// solution; returns the pressures of the last step.
fn check(c: &Case, ranks: usize) -> Vec<f64> {
    let dir = scratch("mortar-patch");
    let path = scene(&dir, c);
    let s = run_scene(ranks, &path, &["--", "-ksp_rtol", "1e-13"]);
    let label = format!("{}D kind {} slave {} on {ranks} rank(s)", c.dim, c.kind, c.slave);
    let h5 = dir.join(format!("{}-{ranks}.h5", path.file_stem().unwrap().to_string_lossy()));
    let run = reader(&h5);
    let force = run.table(&layout::contact("force")).unwrap();
    let active = run.table(&layout::contact("active")).unwrap();
    let weights = values(&h5, layout::CONTACT_WEIGHTS);
    assert_eq!(force.nrows(), 4, "{label}: rows of the contact history");
    let mut last = vec![];
    for n in 1..force.nrows() {
        assert!(active.row(n).iter().all(|&a| a == 1.0), "{label}: step {n}: a slave node is off");
        last = force.row(n).iter().zip(&weights).map(|(f, w)| f / w).collect();
        for (q, p) in last.iter().enumerate() {
            assert!((p - P).abs() < 1e-9 * P, "{label}: step {n}, slave node {q}: pressure {p}");
        }
    }
    let x = run.coordinates().unwrap();
    let t_end = 3.0 * 1e-3;
    let (u, comps) = run.field_at("displacement", t_end).unwrap();
    let d = c.dim - 1;
    let scale = P * 2.0 / confined();
    for (k, xk) in x.iter().enumerate() {
        for i in 0..c.dim {
            let want = if i == d { -P * (xk[d] + 1.0) / confined() } else { 0.0 };
            let got = u[k * comps + i];
            assert!(
                (got - want).abs() < 1e-9 * scale,
                "{label}: node {k} at {xk:?}, component {i}: {got} vs {want}"
            );
        }
    }
    assert!(s.energy_balance < 1e-8, "{label}: energy balance {}", s.energy_balance);
    last
}

#[test]
fn mortar_patch_test_2d_quads_triangles_and_mixed() {
    for kind in [0, 1, 2] {
        let c = Case::upper_on_lower(2, kind, (4, 5), "modified1");
        check(&c, 2);
    }
    // The coarser side as the slave, and the standard mass.
    let c = Case {
        dim: 2,
        kind: 0,
        n: (4, 7),
        slave: "lower_contact",
        master: "upper_contact",
        mass: "consistent",
    };
    check(&c, 2);
}

#[test]
fn mortar_patch_test_3d_hexahedra_tetrahedra_and_mixed() {
    for kind in [0, 1, 2] {
        let c = Case::upper_on_lower(3, kind, (3, 4), "consistent");
        check(&c, 2);
    }
}

/// The same patch on 1 and 3 ranks (the interface cut by the partition) gives the same
/// pressures to solver tolerance.
#[test]
fn mortar_patch_test_does_not_depend_on_the_number_of_ranks() {
    let c = Case::upper_on_lower(3, 2, (3, 4), "modified1");
    let one = check(&c, 1);
    let three = check(&c, 3);
    for (a, b) in one.iter().zip(&three) {
        assert!((a - b).abs() < 1e-9, "pressures {a} vs {b}");
    }
}
