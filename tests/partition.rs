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
            counts[r as usize] += 1;
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
        let min =
            list[off[v]..off[v + 1]].iter().map(|&c| parts[0].cell_rank[c] as usize).min().unwrap();
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

/// The local view of each rank (own cells plus the vertex-neighbour ghost layer) against the
/// whole mesh: owned nodes cover every node once with the replicated numbering, every owned
/// node's cell star is complete, and the local maps lead back to the original entities.
#[test]
fn local_views_cover_the_mesh_with_complete_stars() {
    let mesh = quad_mesh(15, 9);
    let (off, _) = node_cells(&mesh);
    for size in [1, 2, 3, 4] {
        let cell_rank = massfree::partition::partition_cells(&mesh, size).unwrap();
        let mut seen = vec![0usize; mesh.n_nodes()];
        let mut own_cells = 0;
        for rank in 0..size {
            let whole = Partition::from_cell_ranks(&mesh, rank, size, cell_rank.clone());
            let (local, p) = massfree::partition::local::localize(&mesh, &cell_rank, rank, size);
            assert_eq!(p.node_offsets, whole.node_offsets);
            assert_eq!(local.n_nodes(), p.node_original.len());
            let (loff, llist) = node_cells(&local);
            for (l, &v) in p.node_original.iter().enumerate() {
                assert_eq!(local.coords[l], mesh.coords[v]);
                assert_eq!(p.node_global[l], whole.node_global[v]);
                assert_eq!(p.node_owner[l], whole.node_owner[v]);
            }
            for &l in &p.owned_nodes {
                let v = p.node_original[l];
                seen[v] += 1;
                assert_eq!(loff[l + 1] - loff[l], off[v + 1] - off[v], "star of node {v}");
            }
            for (lc, c) in p.cell_original.iter().map(|&c| c as usize).enumerate() {
                let back: Vec<usize> =
                    local.cells[lc].nodes().iter().map(|&l| p.node_original[l]).collect();
                assert_eq!(back, *mesh.cells[c].nodes());
                assert_eq!(p.cell_rank[lc] as usize, cell_rank[c]);
                // A ghost cell shares a node with an own cell.
                if cell_rank[c] != rank {
                    assert!(local.cells[lc].nodes().iter().any(|&l| {
                        llist[loff[l]..loff[l + 1]].iter().any(|&k| p.cell_rank[k] as usize == rank)
                    }));
                }
            }
            own_cells += p.local_cells.len();
            let owned_global: Vec<usize> =
                p.owned_nodes.iter().map(|&l| p.node_global[l]).collect();
            let lo = p.node_offsets[rank];
            assert_eq!(owned_global, (lo..lo + owned_global.len()).collect::<Vec<_>>());
            if size > 1 {
                assert!(local.cells.len() > p.local_cells.len(), "a ghost layer");
                assert!(local.cells.len() < mesh.cells.len(), "not the whole mesh");
            }
        }
        assert!(seen.iter().all(|&s| s == 1), "each node owned once");
        assert_eq!(own_cells, mesh.cells.len());
    }
}
