//! Hand-written MSH 4.1 files: the reader's and checker's error paths.

use massfree::error::Error;
use massfree::mesh::check::check_geometry;
use massfree::mesh::msh::parse_msh;
use massfree::mesh::{ElementKind, Mesh};

/// Unit square, two triangles, physical curve "left" (x = 0) and surface "body".
const SQUARE: &str = "$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
1 1 \"left\"
2 2 \"body\"
$EndPhysicalNames
$Entities
0 1 1 0
4 0 0 0 0 1 0 1 1 0
1 0 0 0 1 1 0 1 2 0
$EndEntities
$Nodes
1 4 1 4
2 1 0 4
1
2
3
4
0 0 0
1 0 0
1 1 0
0 1 0
$EndNodes
$Elements
2 3 1 3
1 4 1 1
3 4 1
2 1 2 2
1 1 2 3
2 1 3 4
$EndElements
";

fn parse(text: &str) -> Result<Mesh, Error> {
    parse_msh(text.as_bytes(), "test.msh")
}

fn err_of(text: &str) -> String {
    match parse(text) {
        Ok(_) => panic!("expected an error, parsed fine:\n{text}"),
        Err(Error::Mesh(m)) => m,
        Err(e) => panic!("expected Error::Mesh, got {e:?}"),
    }
}

fn assert_has(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "error message {msg:?} lacks {p:?}");
    }
    assert!(!msg.contains('\n'), "error message is not one line: {msg:?}");
}

#[test]
fn parses_small_square() {
    let m = parse(SQUARE).unwrap();
    assert_eq!(m.dim, 2);
    assert_eq!(m.n_nodes(), 4);
    assert_eq!(m.node_tags, vec![1, 2, 3, 4]);
    assert_eq!(m.cells.len(), 2);
    assert!(m.cells.iter().all(|e| e.kind == ElementKind::Tri3));
    assert_eq!(*m.cells[1].nodes(), [0, 2, 3]);
    assert_eq!(m.cells[1].tag, 2);
    assert_eq!(m.boundary.len(), 1);
    assert_eq!(m.boundary[0].kind, ElementKind::Line2);
    let left = m.group("left").unwrap();
    assert_eq!((left.dim, left.tag, left.entities.clone()), (1, 1, vec![4]));
    assert_eq!(m.group("body").unwrap().dim, 2);
    assert_eq!(m.group_nodes("left").unwrap(), vec![0, 3]);
    check_geometry(&m).unwrap();
}

#[test]
fn rejects_msh_2_2() {
    let text = SQUARE.replacen("4.1 0 8", "2.2 0 8", 1);
    assert_has(&err_of(&text), &["test.msh", "MSH 4.1 required, found 2.2", "-format msh41"]);
}

#[test]
fn rejects_non_msh() {
    assert_has(&err_of("hello\n"), &["test.msh", "not a gmsh MSH file"]);
    assert_has(&err_of(""), &["test.msh"]);
}

#[test]
fn rejects_second_order_triangle() {
    let text = SQUARE
        .replacen("2 1 2 2\n1 1 2 3\n2 1 3 4\n", "2 1 9 1\n7 1 2 3 4 1 2\n", 1)
        .replacen("2 3 1 3", "2 2 1 7", 1);
    assert_has(
        &err_of(&text),
        &["test.msh", "element type 9", "element tag 7", "Mesh.ElementOrder = 1"],
    );
}

#[test]
fn rejects_prism() {
    let text = SQUARE.replacen("2 1 2 2\n1 1 2 3\n", "3 1 6 2\n5 1 2 3 4 1 2\n", 1);
    assert_has(&err_of(&text), &["element type 6", "prism", "element tag 5"]);
}

#[test]
fn rejects_missing_node() {
    let text = SQUARE.replacen("2 1 3 4\n", "2 1 3 99\n", 1);
    assert_has(&err_of(&text), &["test.msh", "element tag 2", "node tag 99"]);
}

#[test]
fn rejects_bad_number_with_line() {
    let text = SQUARE.replacen("1 0 0\n1 1 0\n", "1 0 0\n1 x 0\n", 1);
    // "1 1 0" is the coordinate line of node 3, line 23 of the file.
    assert_has(&err_of(&text), &["test.msh", "bad node coordinate \"x\"", "line 23", "$Nodes"]);
}

#[test]
fn rejects_every_truncation() {
    let full = SQUARE.trim_end();
    for n in 0..full.len() {
        let r = parse(&full[..n]);
        assert!(r.is_err(), "prefix of {n} bytes parsed fine:\n{}", &full[..n]);
    }
    parse(full).unwrap();
    let msg = err_of(&SQUARE[..SQUARE.find("1 1 2 3").unwrap()]);
    assert_has(&msg, &["test.msh", "truncated", "$Elements"]);
}

#[test]
fn rejects_wrong_counts() {
    let text = SQUARE.replacen("2 3 1 3", "2 4 1 3", 1);
    assert_has(&err_of(&text), &["announces 4 elements"]);
}

#[test]
fn rejects_partitioned() {
    let text = SQUARE.replacen(
        "$Nodes\n",
        "$PartitionedEntities\n2\n0\n0 0 0 0\n$EndPartitionedEntities\n$Nodes\n",
        1,
    );
    assert_has(&err_of(&text), &["test.msh", "partitioned"]);
}

#[test]
fn skips_unknown_sections() {
    let text = SQUARE.replacen(
        "$Nodes\n",
        "$Periodic\n0\n$EndPeriodic\n$Comments\nanything $Nodes-like\n$EndComments\n$Nodes\n",
        1,
    ) + "$NodeData\n1\n\"u\"\n$EndNodeData\n";
    assert_eq!(parse(&text).unwrap(), parse(SQUARE).unwrap());
}

#[test]
fn unnamed_group_and_several_physical_tags() {
    // The curve also belongs to group 7, which has no name.
    let text = SQUARE.replacen("4 0 0 0 0 1 0 1 1 0", "4 0 0 0 0 1 0 2 1 7 0", 1);
    let m = parse(&text).unwrap();
    let g = m.group("7").unwrap();
    assert_eq!((g.dim, g.entities.clone()), (1, vec![4]));
    assert_eq!(m.group_nodes("left").unwrap(), m.group_nodes("7").unwrap());
}

#[test]
fn drops_unphysical_boundary_and_unused_nodes() {
    // Curve 4 without physical tag: its line is dropped. Node 5 used by nothing: dropped.
    let text = SQUARE
        .replacen("4 0 0 0 0 1 0 1 1 0", "4 0 0 0 0 1 0 0 0", 1)
        .replacen("1 4 1 4\n2 1 0 4\n", "1 5 1 5\n2 1 0 5\n", 1)
        .replacen("4\n0 0 0\n", "4\n5\n0 0 0\n", 1)
        .replacen("0 1 0\n$EndNodes", "0 1 0\n5 5 0\n$EndNodes", 1);
    let m = parse(&text).unwrap();
    assert_eq!(m.n_nodes(), 4);
    assert!(m.boundary.is_empty());
    assert!(m.group_nodes("left").unwrap().is_empty());
    assert!(m.group_nodes("body").is_ok());
}

#[test]
fn rejects_boundary_node_outside_cells() {
    // A physical point on node 5, which no triangle uses.
    let text = SQUARE
        .replacen("0 1 1 0\n", "1 1 1 0\n9 5 5 0 1 3\n", 1)
        .replacen("1 4 1 4\n2 1 0 4\n", "1 5 1 5\n2 1 0 5\n", 1)
        .replacen("4\n0 0 0\n", "4\n5\n0 0 0\n", 1)
        .replacen("0 1 0\n$EndNodes", "0 1 0\n5 5 0\n$EndNodes", 1)
        .replacen("2 3 1 3\n", "3 4 1 8\n0 9 15 1\n8 5\n", 1);
    assert_has(&err_of(&text), &["test.msh", "point", "element tag 8", "node tag 5", "no 2D cell"]);
}

#[test]
fn rejects_mesh_without_cells() {
    let text =
        SQUARE.replacen("2 3 1 3", "1 1 1 1", 1).replacen("2 1 2 2\n1 1 2 3\n2 1 3 4\n", "", 1);
    assert_has(&err_of(&text), &["test.msh", "no surface or volume elements"]);
}

#[test]
fn parametric_nodes_are_skipped() {
    // Same nodes, split into a parametric curve block (u) and a parametric surface block (u v).
    let text = SQUARE.replacen(
        "1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n",
        "2 4 1 4\n1 4 1 2\n1\n4\n0 0 0 1.0\n0 1 0 0.0\n2 1 1 2\n2\n3\n1 0 0 0.5 0.5\n1 1 0 0.25 0.25\n",
        1,
    );
    assert_eq!(parse(&text).unwrap(), parse(SQUARE).unwrap());
}

#[test]
fn inverted_triangle_is_named() {
    let text = SQUARE.replacen("2 1 3 4\n", "2 1 4 3\n", 1);
    let m = parse(&text).unwrap();
    match check_geometry(&m) {
        Err(Error::Mesh(msg)) => {
            assert_has(&msg, &["inverted triangle (gmsh element tag 2)", "Reverse Surface"])
        }
        other => panic!("expected inverted-triangle error, got {other:?}"),
    }
}

/// One quadrangle; `x` are the 4 node coordinates.
fn quad(x: [[f64; 2]; 4]) -> String {
    let mut s = String::from(
        "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n",
    );
    for p in x {
        s += &format!("{} {} 0\n", p[0], p[1]);
    }
    s + "$EndNodes\n$Elements\n1 1 11 11\n2 1 3 1\n11 1 2 3 4\n$EndElements\n"
}

fn geometry_error(text: &str) -> String {
    match check_geometry(&parse(text).unwrap()) {
        Err(Error::Mesh(m)) => m,
        other => panic!("expected a geometry error, got {other:?}"),
    }
}

#[test]
fn quad_checks() {
    check_geometry(&parse(&quad([[0., 0.], [1., 0.], [1., 1.], [0., 1.]])).unwrap()).unwrap();
    // Three collinear corners: zero Jacobian at corner 1.
    let msg = geometry_error(&quad([[0., 0.], [1., 0.], [2., 0.], [0., 1.]]));
    assert_has(&msg, &["degenerate quadrilateral (gmsh element tag 11)", "corner 1"]);
    // Two coincident nodes.
    let msg = geometry_error(&quad([[0., 0.], [1., 0.], [1., 0.], [0., 1.]]));
    assert_has(&msg, &["degenerate quadrilateral (gmsh element tag 11)"]);
    // Clockwise.
    let msg = geometry_error(&quad([[0., 0.], [0., 1.], [1., 1.], [1., 0.]]));
    assert_has(&msg, &["inverted quadrilateral (gmsh element tag 11)", "clockwise"]);
    // Non-convex (dart) quad.
    let msg = geometry_error(&quad([[0., 0.], [2., 0.], [0.5, 0.5], [0., 2.]]));
    assert_has(&msg, &["inverted quadrilateral (gmsh element tag 11)", "non-convex"]);
}

#[test]
fn tet_checks() {
    let tet = |z: f64| {
        format!(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n\
             0 0 0\n1 0 0\n0 1 0\n0 0 {z}\n$EndNodes\n$Elements\n1 1 5 5\n3 1 4 1\n5 1 2 3 4\n\
             $EndElements\n"
        )
    };
    let m = parse(&tet(1.0)).unwrap();
    assert_eq!(m.dim, 3);
    check_geometry(&m).unwrap();
    assert_has(&geometry_error(&tet(-1.0)), &["inverted tetrahedron (gmsh element tag 5)"]);
    assert_has(&geometry_error(&tet(0.0)), &["degenerate tetrahedron (gmsh element tag 5)"]);
}

#[test]
fn hex_checks() {
    let unit = [
        [0., 0., 0.],
        [1., 0., 0.],
        [1., 1., 0.],
        [0., 1., 0.],
        [0., 0., 1.],
        [1., 0., 1.],
        [1., 1., 1.],
        [0., 1., 1.],
    ];
    let hex = |x: [[f64; 3]; 8]| {
        let mut s = String::from(
            "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 8 1 8\n3 1 0 8\n1\n2\n3\n4\n5\n6\n7\n8\n",
        );
        for p in x {
            s += &format!("{} {} {}\n", p[0], p[1], p[2]);
        }
        s + "$EndNodes\n$Elements\n1 1 4 4\n3 1 5 1\n4 1 2 3 4 5 6 7 8\n$EndElements\n"
    };
    check_geometry(&parse(&hex(unit)).unwrap()).unwrap();
    let mut flipped = unit;
    for p in flipped.iter_mut() {
        p[2] = -p[2];
    }
    assert_has(&geometry_error(&hex(flipped)), &["inverted hexahedron (gmsh element tag 4)"]);
    let mut flat = unit;
    for p in flat.iter_mut().skip(4) {
        p[2] = 0.0;
    }
    assert_has(&geometry_error(&hex(flat)), &["degenerate hexahedron (gmsh element tag 4)"]);
}

#[test]
fn tilted_2d_mesh_is_rejected() {
    let text = SQUARE.replacen("1 0 0\n1 1 0\n", "1 0 0\n1 1 0.5\n", 1);
    assert_has(&geometry_error(&text), &["xy-plane", "node tag 3"]);
}
