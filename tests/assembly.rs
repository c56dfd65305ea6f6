//! Assembly on one rank (PETSc initialized once in the single test): separated loads equal
//! integrated loads; assembled matrices have the exact preallocation; the stiffness kills
//! rigid motions and the mass matrix carries the body's mass.

use massfree::assembly::nodal_pressure::{self, NodalDilatation};
use massfree::assembly::{
    assemble_matrix, assemble_matrix_blocked, interpolate, new_vector, Loads,
};
use massfree::fem::{kernels, Material};
use massfree::mass::mass_matrix;
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::read_msh;
use massfree::partition::Partition;
use massfree::petsc::{Pattern, Petsc};
use massfree::scene::expr::{Expr, VecExpr};
use massfree::scene::MassKind;
use std::path::Path;

fn vexpr(v: &[&str]) -> VecExpr {
    VecExpr(v.iter().map(|s| Expr::parse(s).unwrap()).collect())
}

#[test]
fn assembly_on_one_rank() {
    let _universe = mpi::initialize().expect("MPI initialized twice");
    let _petsc = Petsc::init(&["assembly-test".to_string()], "assembly test").unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache");
    let msh = mesh_geo(&root.join("meshes/beam_quad.geo"), &[("h".into(), 0.25)], 2, false, &cache)
        .unwrap();
    let mesh = read_msh(&msh).unwrap();
    let part = Partition::new(&mesh, 0, 1).unwrap();

    // Separated loads (the beam's, plus a steady and a two-term traction) equal integration.
    let body = vexpr(&[
        "200/13*y*(x - 5)*sin(2*pi*t)",
        "(0.08*pi^2*x*y^2*(x - 10) + 140/13*x*(x - 10) + 40/13*y^2)*sin(2*pi*t) + 0.5*x",
    ]);
    let neumann = vec![
        ("top".to_string(), vexpr(&["40/13*(5 - x)*sin(2*pi*t)", "x*exp(-t) - 2e-1*t^2"])),
        ("bottom".to_string(), vexpr(&["0", "0"])),
    ];
    let loads = Loads::new(&mesh, &part, Some(&body), &neumann).unwrap();
    assert!(loads.is_separated() && loads.time_dependent);
    let mut a = new_vector(&part).unwrap();
    let mut b = new_vector(&part).unwrap();
    for t in [0.0, 0.013, 0.25, 0.71] {
        loads.assemble(&mesh, &part, t, &mut a).unwrap();
        loads.assemble_integrated(&mesh, &part, t, &mut b).unwrap();
        let scale = b.norm2().unwrap();
        b.axpy(-1.0, &a).unwrap();
        assert!(b.norm2().unwrap() <= 1e-13 * scale.max(1.0), "t = {t}: {}", b.norm2().unwrap());
    }
    // A load that does not separate is integrated every step.
    let mixed = vexpr(&["sin(x*t)", "0"]);
    assert!(!Loads::new(&mesh, &part, Some(&mixed), &[]).unwrap().is_separated());

    // Stiffness: rigid motions are in its kernel; exact preallocation (no mallocs).
    let mat = Material::from_young_poisson(200.0, 0.3, 2.0);
    let k = assemble_matrix(&mesh, &part, |c, xy, out| {
        kernels::stiffness(mesh.cells[c].kind, xy, &mat, out)
    })
    .unwrap();
    let info = k.nonzero_info().unwrap();
    assert_eq!(info.mallocs, 0.0);
    assert_eq!(info.allocated, info.used, "preallocation must be exact");
    assert!(k.is_symmetric(1e-12).unwrap());
    let mut y = new_vector(&part).unwrap();
    for rigid in [["1", "0"], ["0", "1"], ["-y", "x"]] {
        let r = interpolate(&mesh, &part, &vexpr(&rigid), 0.0).unwrap();
        k.mult(&r, &mut y).unwrap();
        assert!(y.norm2().unwrap() < 1e-10 * r.norm2().unwrap(), "rigid mode {rigid:?}");
    }
    // The run stores A as block AIJ: its products equal AIJ's to round-off, and converted
    // back to AIJ (K's storage) it has the same pattern and values.
    let kb = assemble_matrix_blocked(&mesh, &part, |c, xy, out| {
        kernels::stiffness(mesh.cells[c].kind, xy, &mat, out)
    })
    .unwrap();
    assert!(kb.is_baij().unwrap() && !k.is_baij().unwrap());
    let back = kb.to_aij().unwrap();
    assert_eq!(back.nonzero_info().unwrap().used, info.used);
    let lo = back.ownership_range().0;
    for row in lo..lo + 40 {
        let a = k.get_row(row).unwrap();
        assert_eq!(back.get_row(row).unwrap(), a, "row {row}");
    }
    let r = interpolate(&mesh, &part, &vexpr(&["x*y + sin(y)", "x - 2*y*y"]), 0.0).unwrap();
    let mut yb = new_vector(&part).unwrap();
    k.mult(&r, &mut y).unwrap();
    kb.mult(&r, &mut yb).unwrap();
    let scale = y.norm_inf().unwrap();
    yb.axpy(-1.0, &y).unwrap();
    assert!(yb.norm_inf().unwrap() <= 1e-14 * scale, "BAIJ product {:e}", yb.norm_inf().unwrap());

    // Mass: 1^T M e_x = rho |Omega| = 2 * 10.
    let m = assemble_matrix(&mesh, &part, |c, xy, out| {
        kernels::mass(mesh.cells[c].kind, xy, mat.rho, out);
        Ok(())
    })
    .unwrap();
    let ex = interpolate(&mesh, &part, &vexpr(&["1", "0"]), 0.0).unwrap();
    m.mult(&ex, &mut y).unwrap();
    assert!((y.sum().unwrap() - 20.0).abs() < 1e-12);

    // The run's mass is stored as the node matrix M_s with M = M_s x I_dim (MAIJ): its
    // diagonal equals the DOF matrix's, its products and K = A + c M equal the DOF matrix's to
    // round-off (the same terms; PETSc's kernels may group a row's terms differently).
    let x = interpolate(&mesh, &part, &vexpr(&["sin(3*x) + y", "cos(x*y) - 0.3*x"]), 0.0).unwrap();
    for (kind, kernel) in [
        (MassKind::Consistent, kernels::mass as fn(_, &_, f64, &mut [f64])),
        (MassKind::Lumped, kernels::mass_lumped),
    ] {
        let full = assemble_matrix(&mesh, &part, |c, xy, out| {
            kernel(mesh.cells[c].kind, xy, mat.rho, out);
            Ok(())
        })
        .unwrap();
        let nodes = mass_matrix(&mesh, &part, |_| (mat.rho, kind), None).unwrap();
        let bits = |v: &massfree::petsc::Vector| -> Vec<u64> {
            v.with_local_slice(|s| s.iter().map(|x| x.to_bits()).collect()).unwrap()
        };
        let close = |a: &massfree::petsc::Vector, b: &massfree::petsc::Vector, what: &str| {
            let (a, b) = (
                a.with_local_slice(|s| s.to_vec()).unwrap(),
                b.with_local_slice(|s| s.to_vec()).unwrap(),
            );
            let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let diff = a.iter().zip(&b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
            assert!(diff <= 4.0 * f64::EPSILON * scale, "{kind:?}: {what}: {diff:e} of {scale:e}");
        };
        let mut y1 = new_vector(&part).unwrap();
        let mut y2 = new_vector(&part).unwrap();
        full.mult(&x, &mut y1).unwrap();
        nodes.mult(&x, &mut y2).unwrap();
        close(&y1, &y2, "M x");
        full.get_diagonal(&mut y1).unwrap();
        nodes.get_diagonal(&mut y2).unwrap();
        assert_eq!(bits(&y1), bits(&y2), "{kind:?}: diagonal");
        let c = 4.0 / 0.01f64.powi(2);
        let mut k1 = k.duplicate(true).unwrap();
        k1.axpy(c, &full, Pattern::Subset).unwrap();
        let mut k2 = k.duplicate(true).unwrap();
        nodes.add_to(&mut k2, c).unwrap();
        k1.mult(&x, &mut y1).unwrap();
        k2.mult(&x, &mut y2).unwrap();
        close(&y1, &y2, "(A + c M) x");
        let info = k2.nonzero_info().unwrap();
        assert_eq!((info.mallocs, info.allocated), (0.0, info.used), "{kind:?}: K's pattern kept");
    }

    // The averaged nodal pressure on the beam of triangles (mixed, nu = 0.4999): the nodal
    // dilatation of an affine field is its divergence at every node (the patch test), its
    // stiffness with the cells' mu part has no force on the interior nodes of an affine field
    // (constant stress), kills rigid motions, is symmetric and positive definite there, and
    // its volumetric energy is lambda/2 |Omega| (div u)^2 (each node's share V_a).
    let tri = mesh_geo(&root.join("meshes/beam_tri.geo"), &[("h".into(), 0.5)], 2, false, &cache)
        .unwrap();
    let tri = read_msh(&tri).unwrap();
    let tpart = Partition::new(&tri, 0, 1).unwrap();
    let rubber =
        Material { mean_dilatation: true, ..Material::from_young_poisson(2.0, 0.4999, 1.0) };
    let nodal = NodalDilatation::build(&tri, &tpart, &|_| rubber).unwrap().expect("nodal cells");
    let affine = ["0.3*x - 0.2*y + 1", "0.1*x + 0.5*y - 2"];
    let u = interpolate(&tri, &tpart, &vexpr(&affine), 0.0).unwrap();
    let theta = nodal.dilatation(&u).unwrap();
    theta
        .with_local_slice(|t| assert!(t.iter().all(|t| (t - 0.8).abs() < 1e-13), "{t:?}"))
        .unwrap();
    let cells = assemble_matrix(&tri, &tpart, |c, xy, out| {
        let kind = tri.cells[c].kind;
        kernels::stiffness(kind, xy, &nodal_pressure::element_material(kind, &rubber), out)
    })
    .unwrap();
    let mut a = nodal.stiffness().unwrap();
    let volumetric = a.duplicate(true).unwrap();
    a.axpy(1.0, &cells, Pattern::Different).unwrap();
    assert!(a.is_symmetric(1e-12).unwrap());
    assert_eq!(a.column_block_size().unwrap(), 2, "the DOF blocks are kept for GAMG");
    let mut f = new_vector(&tpart).unwrap();
    a.mult(&u, &mut f).unwrap();
    let interior: Vec<bool> = (0..tri.coords.len())
        .map(|v| {
            let [x, y, _] = tri.coords[v];
            x > 1e-9 && x < 10.0 - 1e-9 && y > 1e-9 && y < 1.0 - 1e-9
        })
        .collect();
    let scale = rubber.lambda * 0.8 * 0.5;
    f.with_local_slice(|f| {
        for (v, inner) in interior.iter().enumerate() {
            for c in 0..2 {
                let x = f[tpart.dof(v, c)];
                assert!(!inner || x.abs() < 1e-9 * scale, "node {v}: force {x}");
            }
        }
    })
    .unwrap();
    let mut vu = new_vector(&tpart).unwrap();
    volumetric.mult(&u, &mut vu).unwrap();
    let energy = 0.5 * vu.dot(&u).unwrap();
    let exact = 0.5 * rubber.lambda * 10.0 * 0.8f64.powi(2);
    assert!((energy - exact).abs() < 1e-10 * exact, "{energy} against {exact}");
    for rigid in [["1", "0"], ["0", "1"], ["-y", "x"]] {
        let r = interpolate(&tri, &tpart, &vexpr(&rigid), 0.0).unwrap();
        a.mult(&r, &mut f).unwrap();
        assert!(f.norm2().unwrap() < 1e-10 * rubber.lambda * r.norm2().unwrap(), "{rigid:?}");
    }
}
