//! Partition: METIS determinism, ownership rule, contiguous numbering, exact preallocation.

use massfree::mesh::topology::node_cells;
use massfree::mesh::{Element, ElementKind, Mesh, PhysicalGroup};
use massfree::partition::Partition;

/// A structured nx x ny quad mesh of the unit square (built by hand: no gmsh needed here).
fn quad_mesh(nx: usize, ny: usize) -> Mesh {
    let mut coords = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            coords.push([i as f64 / nx as f64, j as f64 / ny as f64, 0.0]);
        }
    }
    let id = |i: usize, j: usize| j * (nx + 1) + i;
    let mut cells = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let n = [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)];
            cells.push(Element::new(ElementKind::Quad4, &n, cells.len() as u64 + 1, 1));
        }
    }
    let n = coords.len();
    Mesh {
        dim: 2,
        coords,
        node_tags: (1..=n as u64).collect(),
        cells,
        boundary: vec![],
        groups: vec![PhysicalGroup { name: "body".into(), dim: 2, tag: 1, entities: vec![1] }],
    }
}

#[test]
fn partition_is_deterministic_and_balanced() {
    let mesh = quad_mesh(20, 10);
    for size in [2, 3, 4] {
        let p = Partition::new(&mesh, 0, size).unwrap();
        let q = Partition::new(&mesh, size - 1, size).unwrap();
        assert_eq!(p.cell_rank, q.cell_rank, "every rank must compute the same partition");
        let mut counts = vec![0usize; size];
        for &r in &p.cell_rank {
            counts[r] += 1;
        }
        let ideal = mesh.cells.len() as f64 / size as f64;
        for c in counts {
            assert!(
                (c as f64) < 1.2 * ideal && (c as f64) > 0.8 * ideal,
                "imbalanced: {c} vs {ideal}"
            );
        }
    }
}

#[test]
fn ownership_numbering_is_contiguous_and_a_permutation() {
    let mesh = quad_mesh(12, 7);
    let size = 3;
    let parts: Vec<Partition> =
        (0..size).map(|r| Partition::new(&mesh, r, size).unwrap()).collect();
    let n = mesh.n_nodes();
    // node_global is a permutation of 0..n.
    let mut seen = vec![false; n];
    for &g in &parts[0].node_global {
        assert!(!seen[g]);
        seen[g] = true;
    }
    assert!(seen.iter().all(|&s| s));
    // Owner = smallest rank among the cells containing the node; owned block contiguous.
    let (off, list) = node_cells(&mesh);
    for v in 0..n {
        let min = list[off[v]..off[v + 1]].iter().map(|&c| parts[0].cell_rank[c]).min().unwrap();
        assert_eq!(parts[0].node_owner[v], min);
        let r = min;
        let g = parts[0].node_global[v];
        assert!(g >= parts[0].node_offsets[r] && g < parts[0].node_offsets[r + 1]);
    }
    let total: usize = parts.iter().map(|p| p.n_owned_nodes()).sum();
    assert_eq!(total, n);
    // Within a rank, the original order is kept.
    for p in &parts {
        let g: Vec<usize> = p.owned_nodes.iter().map(|&v| p.node_global[v]).collect();
        assert!(g.windows(2).all(|w| w[1] == w[0] + 1));
    }
}

#[test]
fn preallocation_counts_match_the_node_graph() {
    let mesh = quad_mesh(6, 5);
    let size = 2;
    for rank in 0..size {
        let p = Partition::new(&mesh, rank, size).unwrap();
        let (d, o) = p.preallocation(&mesh);
        assert_eq!(d.len(), p.n_owned_dofs());
        // Brute force: nodes sharing a cell with v.
        for (i, &v) in p.owned_nodes.iter().enumerate() {
            let mut nb: Vec<usize> = mesh
                .cells
                .iter()
                .filter(|c| c.nodes().contains(&v))
                .flat_map(|c| c.nodes().to_vec())
                .collect();
            nb.sort_unstable();
            nb.dedup();
            let dd = nb.iter().filter(|&&w| p.node_owner[w] == rank).count() as i32 * 2;
            let oo = nb.iter().filter(|&&w| p.node_owner[w] != rank).count() as i32 * 2;
            assert_eq!((d[2 * i], o[2 * i]), (dd, oo), "node {v}");
            assert_eq!((d[2 * i + 1], o[2 * i + 1]), (dd, oo));
        }
    }
}

#[test]
fn one_rank_owns_everything_in_original_order() {
    let mesh = quad_mesh(4, 4);
    let p = Partition::new(&mesh, 0, 1).unwrap();
    assert_eq!(p.node_global, (0..mesh.n_nodes()).collect::<Vec<_>>());
    assert_eq!(p.local_cells.len(), mesh.cells.len());
}

#[test]
fn more_ranks_than_cells_is_an_error() {
    let mesh = quad_mesh(1, 1);
    let e = Partition::new(&mesh, 0, 2).unwrap_err();
    assert!(e.to_string().contains("fewer than the 2 ranks"), "{e}");
}

#[test]
fn metis_repeats_itself() {
    let mesh = quad_mesh(20, 10);
    let a = massfree::partition::partition_cells(&mesh, 3).unwrap();
    let b = massfree::partition::partition_cells(&mesh, 3).unwrap();
    let c = massfree::partition::partition_cells(&mesh, 2).unwrap();
    let d = massfree::partition::partition_cells(&mesh, 3).unwrap();
    assert_eq!(a, b);
    assert_eq!(a, d, "{c:?}");
}
