//! Assembly on one rank (PETSc initialized once in the single test): separated loads equal
//! integrated loads; assembled matrices have the exact preallocation; the stiffness kills
//! rigid motions and the mass matrix carries the body's mass.

use massfree::assembly::{assemble_matrix, interpolate, new_vector, Loads};
use massfree::fem::{kernels, Material};
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::read_msh;
use massfree::partition::Partition;
use massfree::petsc::Petsc;
use massfree::scene::expr::{Expr, VecExpr};
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
    // Mass: 1^T M e_x = rho |Omega| = 2 * 10.
    let m = assemble_matrix(&mesh, &part, |c, xy, out| {
        kernels::mass(mesh.cells[c].kind, xy, mat.rho, out);
        Ok(())
    })
    .unwrap();
    let ex = interpolate(&mesh, &part, &vexpr(&["1", "0"]), 0.0).unwrap();
    m.mult(&ex, &mut y).unwrap();
    assert!((y.sum().unwrap() - 20.0).abs() < 1e-12);
}
