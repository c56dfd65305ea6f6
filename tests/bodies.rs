//! Bodies with their own material and mass treatment (`[[body]]`, issue 12): each body's mass
//! and momentum from theory, a stiffer body's faster vibration and the step solver's regime,
//! the mass-free layer only on the body with a modified mass, rank independence.

mod common;
use common::*;

/// Two strips (L = 1, H = 0.1, 20 x 2 quads, `meshes/two_bars.geo`) with E = 1, nu = `nu`,
/// rho = 1 in `[material]`, then `rest`.
fn two_bars(
    dir: &std::path::Path,
    name: &str,
    params: &str,
    nu: f64,
    rest: &str,
) -> std::path::PathBuf {
    let text = format!(
        "name = \"{name}\"\n[mesh]\ngeo = \"../meshes/two_bars.geo\"\nparams = {{ {params} }}\n[material]\nE = 1.0\nnu = {nu}\nrho = 1.0\n{rest}"
    );
    scene_text(dir, &format!("{name}.toml"), &text)
}

fn body<'a>(s: &'a RunSummary, group: &str) -> &'a massfree::report::BodySummary {
    s.bodies.iter().find(|b| b.group == group).unwrap_or_else(|| panic!("no body {group}"))
}

/// Two free strips of densities 1 and 3 with the velocity v = (1 - x, 0.5), no contact: each
/// body's mass is rho_b L H, its momentum rho_b int (1 - x, 0.5) (v is linear, so its nodal
/// interpolant is exact and so is `1^T M v`), and with no force between them each body keeps
/// its momentum (the stiffness has no row coupling them, and `1_B` is a rigid mode of B).
#[test]
fn each_body_has_its_own_mass_and_keeps_its_momentum() {
    let dir = scratch("bodies-mass");
    let scene = two_bars(
        &dir,
        "densities",
        "n = 20, ny = 2",
        0.3,
        "[[body]]\ngroup = \"left\"\n[[body]]\ngroup = \"right\"\nrho = 3.0\nE = 2.0\n[initial]\nvelocity = [\"1 - x\", \"0.5\"]\n[time]\ntau = 0.01\nsteps = 50\n[output]\nevery = 50\n",
    );
    let s = run_scene(2, &scene, &["--", "-ksp_rtol", "1e-13"]);
    let (left, right) = (body(&s, "left"), body(&s, "right"));
    assert_eq!((left.rho, right.rho, right.e), (1.0, 3.0, 2.0));
    assert_eq!((left.cells, right.cells), (40, 40));
    let (l, h) = (1.0, 0.1);
    for c in 0..2 {
        assert!(rel_diff(left.total_mass[c], l * h) < 1e-12, "left mass {:?}", left.total_mass);
        assert!(rel_diff(right.total_mass[c], 3.0 * l * h) < 1e-12, "{:?}", right.total_mass);
        assert!(rel_diff(s.mass.total_mass[c], 4.0 * l * h) < 1e-12);
    }
    // int_0^1 (1 - x) dx = 1/2 and int_1.01^2.01 (1 - x) dx = -0.51, times H.
    let expect = [[0.5 * h, 0.5 * h], [3.0 * -0.51 * h, 3.0 * 0.5 * h]];
    for (b, p) in [left, right].iter().zip(expect) {
        for c in 0..2 {
            assert!(
                (b.momentum_initial[c] - p[c]).abs() < 1e-12,
                "{}: momentum {:?}, expected {p:?}",
                b.group,
                b.momentum_initial
            );
            let d = (b.momentum_final[c] - b.momentum_initial[c]).abs();
            assert!(d < 1e-9 * p[c].abs(), "{}: momentum {c} changed by {d}", b.group);
        }
    }
    assert!(s.energy_balance < 1e-9, "energy balance {}", s.energy_balance);
}

/// nu = 0: the strips' lowest longitudinal mode is the rod's, u = (a cos(pi x / L), 0) with
/// omega = pi sqrt(E / rho) / L (no Poisson coupling, plane strain is exact). The gap is 1, so
/// the same field is the mode of both strips (right: x in [2, 3]). With E = 4 on the right its
/// potential energy starts 4 times the left's, and at t = 1/2 (a quarter period of the left,
/// half of the right) the left's is back to zero and the right's at its start: potential /
/// total = 4/5 (1 with E = 4 everywhere, 0 with E = 1).
#[test]
fn a_stiffer_body_vibrates_faster_and_sets_the_regime() {
    let dir = scratch("bodies-waves");
    let rest = |tau: &str, steps: usize| {
        format!(
            "[[body]]\ngroup = \"right\"\nE = 4.0\n[initial]\ndisplacement = [\"0.01*cos(pi*x)\", \"0\"]\n[time]\ntau = {tau}\nsteps = {steps}\n[output]\nevery = 100\n"
        )
    };
    let scene = two_bars(&dir, "stiff", "n = 20, ny = 2, gap = 1.0", 0.0, &rest("0.005", 100));
    let s = run_scene(2, &scene, &["--", "-ksp_rtol", "1e-12"]);
    // Continuum: 1/2 E int (u')^2 = 1/2 E (0.01 pi)^2 H / 2 per strip (Q1 error O(h^2) ~ 0.4%).
    let p_left = 0.5 * (0.01 * std::f64::consts::PI).powi(2) * 0.1 / 2.0;
    assert!(rel_diff(s.energy_initial, 5.0 * p_left) < 0.01, "initial energy {}", s.energy_initial);
    let h5 = dir.join("stiff-2.h5");
    let (potential, total) =
        (values(&h5, &layout::energy("potential")), values(&h5, &layout::energy("total")));
    let t = values(&h5, &layout::energy("time"));
    assert!((t[100] - 0.5).abs() < 1e-12);
    let ratio = potential[100] / total[100];
    assert!((ratio - 0.8).abs() < 0.005, "potential/total at t = 1/2: {ratio}, expected 0.8");
    assert_eq!(s.pc_type, "jacobi");
    // The regime: h_min = 0.05, c = 1 on the left, 2 on the right. tau = 0.3 puts the left at
    // CFL 6 and the right at 12, above the crossover (10): multigrid only if the right counts.
    let scene = two_bars(&dir, "regime", "n = 20, ny = 2, gap = 1.0", 0.0, &rest("0.3", 1));
    let s = run_scene(1, &scene, &["--no-output"]);
    assert!((s.cfl - 12.0).abs() < 1e-9, "the regime's CFL is the fast body's: {}", s.cfl);
    // A stiff-regime solver: multigrid, or a factorization where the run is long enough for
    // it to pay back (`time::choice`: this small problem factors in milliseconds).
    assert!(
        s.pc_type == "gamg" || s.pc_type == "cholesky",
        "the fast body's CFL 12 > 10 must select a stiff-regime solver, not {}",
        s.pc_type
    );
}

/// The two discs with the lower one's mass consistent and the upper one's modified: the layer
/// runs along the upper contact arc only. The mesh is mirrored, so that is half the contact
/// nodes and cells the layer has along both arcs; its contact rows are zero.
#[test]
fn the_layer_is_built_only_on_the_body_with_a_modified_mass() {
    let dir = scratch("bodies-layer");
    let both = scene_variant("two_discs.toml", &scratch("bodies-layer-both"), &[]);
    let one = scene_variant(
        "two_discs.toml",
        &dir,
        &[("group = \"lower\"\n", "group = \"lower\"\nmass = \"consistent\"\n")],
    );
    let args = ["--steps", "5", "--no-output"];
    let b = run_scene(1, &both, &args);
    let s = run_scene(2, &one, &args);
    assert!(b.layer_contact_nodes > 0 && b.layer_contact_nodes.is_multiple_of(2));
    assert_eq!(s.layer_contact_nodes * 2, b.layer_contact_nodes);
    assert_eq!(s.layer_cells * 2, b.layer_cells);
    let (lower, upper) = (body(&s, "lower"), body(&s, "upper"));
    assert_eq!((lower.mass_kind.as_str(), upper.mass_kind.as_str()), ("consistent", "modified1"));
    assert_eq!((lower.layer_contact_nodes, lower.layer_cells), (0, 0));
    assert_eq!(
        (upper.layer_contact_nodes, upper.layer_cells),
        (s.layer_contact_nodes, s.layer_cells)
    );
    assert_eq!(s.mass.contact_row_max, 0.0);
    // Both mass matrices keep each disc's mass (the layer conserves it).
    assert!(rel_diff(lower.total_mass[0], upper.total_mass[0]) < 1e-12);
    assert!(
        s.effects.contains("consistent mass, mass-free layer (modified1 along \"upper_contact\")"),
        "{}",
        s.effects
    );
}

/// A two-material run through the contact: 1 and 2 ranks agree to 1e-10. The x-slabs cut both
/// discs at x = 0 (METIS would give each disc a rank of its own), so each body's cells are
/// assembled on both ranks.
#[test]
fn two_materials_do_not_depend_on_the_number_of_ranks() {
    let dir = scratch("bodies-ranks");
    let scene = scene_variant(
        "two_discs.toml",
        &dir,
        &[
            ("steps = 1000", "steps = 120"),
            ("every = 10", "every = 40"),
            ("group = \"upper\"\n", "group = \"upper\"\nrho = 4e-8\n"),
            ("group = \"lower\"\n", "group = \"lower\"\nE = 200.0\nmass = \"consistent\"\n"),
        ],
    );
    let args = ["--partition", "x-slabs", "--", "-ksp_rtol", "1e-13"];
    let s1 = run_scene(1, &scene, &args);
    let s2 = run_scene(2, &scene, &args);
    assert!(s1.contact.as_ref().is_some_and(|c| c.max_active_nodes > 0), "no contact");
    let close = |a: &[f64], b: &[f64], what: &str| {
        assert_eq!(a.len(), b.len(), "{what}");
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
        let d = a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(d <= 1e-10 * scale, "{what}: 1 and 2 ranks differ by {d} (scale {scale})");
    };
    let (r1, r2) = (dir.join("two_discs-1.h5"), dir.join("two_discs-2.h5"));
    for name in [layout::field("displacement"), layout::energy("total"), layout::contact("force")] {
        close(&values(&r1, &name), &values(&r2, &name), &name);
    }
    for (a, b) in s1.bodies.iter().zip(&s2.bodies) {
        close(&a.total_mass, &b.total_mass, "body mass");
        close(&a.momentum_final, &b.momentum_final, "body momentum");
    }
    // The heavier upper disc: twice the lower one's mass.
    assert!(
        rel_diff(body(&s1, "upper").total_mass[0], 2.0 * body(&s1, "lower").total_mass[0]) < 1e-12
    );
}
