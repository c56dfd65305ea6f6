//! The dual-mortar interface on gmsh meshes of two blocks with non-matching interface meshes
//! (issue 12): properties that hold exactly for flat interfaces, whatever the meshes:
//! `sum_q D_qq` = interface area, `sum_l M_ql = D_qq` (partition of unity, full overlap),
//! `D^{-1} M` reproduces linear fields at the slave nodes (the property behind the mortar
//! patch test), weighted gap `g_q = d D_qq` for a flat gap `d`, normals towards the master.

use std::path::{Path, PathBuf};

use massfree::contact::mortar::{
    oriented_facets, MortarInterface, NormalKind, SearchState, SurfaceFacet,
};
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::read_msh;
use massfree::mesh::Mesh;
use massfree::partition::Partition;

fn load(name: &str, params: &[(&str, f64)], dim: usize) -> Mesh {
    let geo = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes").join(format!("{name}.geo"));
    let cache: PathBuf = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache");
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    read_msh(&mesh_geo(&geo, &params, dim, false, &cache).unwrap()).unwrap()
}

/// The interface with the slave side's normals (the default), without the search's time.
fn build(
    world: &mpi::topology::SimpleCommunicator,
    mesh: &Mesh,
    part: &Partition,
    slave: &[SurfaceFacet],
    master: &[SurfaceFacet],
    x: &dyn Fn(usize) -> [f64; 3],
    reach: f64,
) -> massfree::Result<MortarInterface> {
    let mut search = SearchState::default();
    MortarInterface::build_timed(
        world,
        mesh,
        part,
        slave,
        master,
        x,
        reach,
        NormalKind::Slave,
        &mut search,
        None,
    )
    .map(|r| r.0)
}

fn check(world: &mpi::topology::SimpleCommunicator, name: &str, dim: usize, kind: f64, gap: f64) {
    let label = format!("{name} kind {kind} gap {gap}");
    let mesh = load(name, &[("kind", kind), ("gap", gap)], dim);
    let part = Partition::new(&mesh, 0, 1).unwrap();
    let slave = oriented_facets(&mesh, "upper_contact").unwrap();
    let master = oriented_facets(&mesh, "lower_contact").unwrap();
    let i = build(world, &mesh, &part, &slave, &master, &|v| mesh.coords[v], 0.1).unwrap();
    assert!(!i.slave.is_empty() && !i.master.is_empty(), "{label}: empty interface");
    assert!(i.slave.iter().all(|v| !i.master.contains(v)), "{label}: bodies share nodes");
    // The interface is the unit segment / unit square.
    let area: f64 = i.d.iter().sum();
    assert!((area - 1.0).abs() < 1e-12, "{label}: sum of D = {area}");
    for (q, s) in i.m_row_sums().iter().enumerate() {
        assert!(
            (s - i.d[q]).abs() < 1e-12 * i.d[q].max(1e-3),
            "{label}: row {q}: {s} vs {}",
            i.d[q]
        );
    }
    let down = if dim == 2 { [0.0, -1.0, 0.0] } else { [0.0, 0.0, -1.0] };
    for n in &i.normals {
        let e: f64 = (0..3).map(|c| (n[c] - down[c]).abs()).sum();
        assert!(e < 1e-12, "{label}: slave normal {n:?}");
    }
    for (q, g) in i.gap.iter().enumerate() {
        assert!((g - gap * i.d[q]).abs() < 1e-12, "{label}: weighted gap {g} vs {}", gap * i.d[q]);
    }
    // A linear field on the master nodes, transferred by D^{-1} M, is exact at the slave
    // nodes (their in-plane coordinates; the gap is along the normal).
    let f = |x: [f64; 3]| 1.0 + 2.0 * x[0] + 3.0 * x[1] * (dim == 3) as i32 as f64;
    let mut t = vec![0.0; i.slave.len()];
    for &(q, l, v) in &i.m {
        t[q as usize] += v * f(mesh.coords[i.master[l as usize]]);
    }
    for (q, &v) in i.slave.iter().enumerate() {
        let want = f(mesh.coords[v]);
        let got = t[q] / i.d[q];
        assert!((got - want).abs() < 1e-11, "{label}: node {v}: {got} vs {want}");
    }
}

/// One test function: MPI is initialized once per process.
#[test]
fn mortar_interfaces() {
    let universe = mpi::initialize().expect("MPI initialized twice");
    let world = universe.world();
    two_discs(&world);
    kept_search_pairs_give_the_fresh_search_interface(&world);
    for kind in [0.0, 1.0, 2.0] {
        for gap in [0.0, 0.01] {
            check(&world, "two_blocks_2d", 2, kind, gap);
            check(&world, "two_blocks_3d", 3, kind, gap);
        }
    }
}

/// Curved, mirrored interfaces: the two-disc mesh. gmsh orders boundary lines as it likes;
/// the facets must come out facing the other body (slave normals down, the master's up), and
/// the lowest slave node sees the lowest distance, 0.1, straight below it.
fn two_discs(world: &mpi::topology::SimpleCommunicator) {
    let mesh = load("two_discs_quad", &[], 2);
    let part = Partition::new(&mesh, 0, 1).unwrap();
    let slave = oriented_facets(&mesh, "upper_contact").unwrap();
    let master = oriented_facets(&mesh, "lower_contact").unwrap();
    // The search must reach every master facet a slave normal can hit: 0.3 > gap + tilt.
    let i = build(world, &mesh, &part, &slave, &master, &|v| mesh.coords[v], 0.3).unwrap();
    assert!(i.normals.iter().all(|n| n[1] < -0.5), "slave normals must point down");
    let low = (0..i.slave.len())
        .min_by(|&a, &b| mesh.coords[i.slave[a]][1].total_cmp(&mesh.coords[i.slave[b]][1]))
        .unwrap();
    // Averaged over the node's support (size h = 0.1) on arcs of radius R = 8 that curve
    // away: within h^2/R of the distance at the node.
    let g = i.gap[low] / i.d[low];
    assert!(g <= 0.1 + 1e-12 && g > 0.1 - 0.1 * 0.1 / 8.0, "gap {g}");
    let rs = i.m_row_sums();
    assert!((rs[low] - i.d[low]).abs() < 1e-12 * i.d[low], "row sum {} vs {}", rs[low], i.d[low]);
    // Near the first contact point (|x| < 0.5, gaps below 0.14) every node's support is
    // covered by the master: partition of unity.
    for (q, s) in rs.iter().enumerate() {
        if mesh.coords[i.slave[q]][0].abs() < 0.5 {
            assert!((s - i.d[q]).abs() < 1e-12 * i.d[q], "node {q}: {s} vs {}", i.d[q]);
        }
    }
}

/// The search's pairs kept between searches (issue 24: searched again only once a node moved
/// farther than the margin): the upper block of `two_blocks_3d` (tetrahedra, non-matching,
/// gap 0.01) slid sideways in steps of 0.02 up to 0.3, with a margin of 0.1. At every position
/// the interface from the kept pairs is bit for bit the one a fresh search gives (the kept
/// pairs filtered by the reach are exactly the pairs within reach), and fewer searches are made
/// than positions.
fn kept_search_pairs_give_the_fresh_search_interface(world: &mpi::topology::SimpleCommunicator) {
    let mesh = load("two_blocks_3d", &[("kind", 1.0), ("gap", 0.01)], 3);
    let part = Partition::new(&mesh, 0, 1).unwrap();
    let slave = oriented_facets(&mesh, "upper_contact").unwrap();
    let master = oriented_facets(&mesh, "lower_contact").unwrap();
    let upper: std::collections::HashSet<usize> =
        mesh.group_nodes("upper").unwrap().into_iter().collect();
    let mut kept = SearchState { margin: 0.1, ..SearchState::default() };
    let mut searched_at = f64::NEG_INFINITY;
    let mut positions = 0;
    for k in 0..=15 {
        let shift = 0.02 * k as f64;
        let x = |v: usize| {
            let mut p = mesh.coords[v];
            if upper.contains(&v) {
                p[0] += shift;
                p[1] += 0.5 * shift;
            }
            p
        };
        kept.reuse = shift - searched_at <= kept.margin;
        let before = kept.searches;
        let (a, _) = MortarInterface::build_timed(
            world,
            &mesh,
            &part,
            &slave,
            &master,
            &x,
            0.3,
            NormalKind::Slave,
            &mut kept,
            None,
        )
        .unwrap();
        if kept.searches > before {
            searched_at = shift;
        }
        let b = build(world, &mesh, &part, &slave, &master, &x, 0.3).unwrap();
        assert_eq!((&a.d, &a.m, &a.gap), (&b.d, &b.m, &b.gap), "shift {shift}: interfaces differ");
        positions += 1;
    }
    assert!(kept.searches < positions, "{} searches for {positions} positions", kept.searches);
}
