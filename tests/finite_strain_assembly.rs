//! The assembled tangent of finite-strain bodies against central differences of the assembled
//! internal force, at random states of every element kind with both models, and with the
//! mixed neo-Hookean forms (the cell's mean dilatation on quadrilaterals and hexahedra, the
//! averaged nodal pressure on triangles and tetrahedra, whose tangent couples nodes two cells
//! apart); one rank, PETSc initialized once in the single test.

use std::path::Path;

use massfree::assembly::finite_strain::{Evaluation, InternalForce};
use massfree::assembly::nodal_pressure::volumetric_stiffness;
use massfree::assembly::{assemble_matrix, new_matrix, new_vector};
use massfree::bodies::Bodies;
use massfree::mesh::gmsh::mesh_geo;
use massfree::mesh::msh::read_msh;
use massfree::partition::Partition;
use massfree::petsc::{Pattern, Petsc, Vector};

/// A small deterministic generator: uniform in [-1, 1).
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

fn random_vector(layout: &Vector, size: f64, rng: &mut Rng) -> Vector {
    let mut v = layout.duplicate().unwrap();
    v.with_local_slice_mut(|x| x.iter_mut().for_each(|x| *x = size * rng.next())).unwrap();
    v
}

fn force(f: &mut InternalForce, u1: &Vector, out: &mut Vector) {
    match f.evaluate(u1, out, None).unwrap() {
        Evaluation::Energies { .. } => {}
        Evaluation::Inverted(m) => panic!("{m}"),
    }
}

#[test]
fn the_assembled_tangent_is_the_derivative_of_the_assembled_force() {
    let _universe = mpi::initialize().expect("MPI initialized twice");
    let _petsc = Petsc::init(&["finite-strain-assembly".to_string()], "test").unwrap();
    let world = mpi::topology::SimpleCommunicator::world();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let cache = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mesh-cache");
    let mut rng = Rng(17);
    for (geo, h, dim) in [
        ("square_tri.geo", 0.25, 2),
        ("square_quad.geo", 0.25, 2),
        ("cube_hex.geo", 0.5, 3),
        ("block_tet.geo", 0.5, 3),
    ] {
        let msh = mesh_geo(&root.join("meshes").join(geo), &[("h".into(), h)], dim, false, &cache)
            .unwrap();
        let mesh = read_msh(&msh).unwrap();
        let part = std::rc::Rc::new(Partition::new(&mesh, 0, 1).unwrap());
        let mesh = std::rc::Rc::new(mesh);
        for (model, formulation, nu) in [
            ("neo_hookean", "displacement", 0.3),
            ("saint_venant_kirchhoff", "displacement", 0.3),
            ("neo_hookean", "mixed", 0.45),
        ] {
            let text = format!(
                "[mesh]\nmsh = \"{}\"\n[material]\nE = 100\nnu = {nu}\nrho = 1\nmodel = \"{model}\"\nformulation = \"{formulation}\"\n[time]\ntau = 0.1\nsteps = 1\n",
                msh.display()
            );
            let model = format!("{model} {formulation}");
            let scene = massfree::scene::parse(&text, "t.toml", root).unwrap();
            let bodies = Bodies::resolve(&scene, &mesh).unwrap();
            let layout = new_vector(&part).unwrap();
            let mut f =
                InternalForce::new(&world, mesh.clone(), part.clone(), &bodies, &layout).unwrap();
            // Random states with strains of about 0.1 (displacements of 0.02 per node on
            // cells of size 0.25-0.5), and a random direction.
            let u0 = random_vector(&layout, 0.02, &mut rng);
            let u1 = random_vector(&layout, 0.02, &mut rng);
            let dir = random_vector(&layout, 1.0, &mut rng);
            f.set_start(&u0).unwrap();
            // The step operator's pattern: the cells', and the nodal pressure's if any.
            let pattern = || {
                let material = |c: usize| *bodies.material(c);
                let cells = assemble_matrix(&mesh, &part, |c, xy, out| {
                    massfree::fem::kernels::stiffness(mesh.cells[c].kind, xy, &material(c), out)
                        .map_err(|e| massfree::error::Error::Mesh(e.to_string()))
                })
                .unwrap();
                match volumetric_stiffness(&mesh, &part, &material).unwrap() {
                    Some(mut k) => {
                        k.axpy(1.0, &cells, Pattern::Different).unwrap();
                        k.keep_pattern().unwrap();
                        k.zero_entries().unwrap();
                        k
                    }
                    None => new_matrix(&mesh, &part).unwrap(),
                }
            };
            let mut k = pattern();
            let mut f1 = layout.duplicate().unwrap();
            // The tangent at another state first: the one checked is a refill of the kept
            // storage (the recorded slots replayed, the values written into the matrix's
            // arrays), which must equal a first assembly to the last bit.
            let other = random_vector(&layout, 0.02, &mut rng);
            for u in [&other, &u1] {
                match f.evaluate(u, &mut f1, Some(&mut k)).unwrap() {
                    Evaluation::Energies { .. } => {}
                    Evaluation::Inverted(m) => panic!("{geo} {model}: {m}"),
                }
            }
            let mut first =
                InternalForce::new(&world, mesh.clone(), part.clone(), &bodies, &layout).unwrap();
            first.set_start(&u0).unwrap();
            let mut k_first = pattern();
            let mut f_first = layout.duplicate().unwrap();
            first.evaluate(&u1, &mut f_first, Some(&mut k_first)).unwrap();
            k_first.axpy(-1.0, &k, Pattern::Same).unwrap();
            let refill = k_first.norm_frobenius().unwrap();
            assert_eq!(refill, 0.0, "{geo} {model}: the refilled tangent differs by {refill:e}");
            let mut kd = layout.duplicate().unwrap();
            k.mult(&dir, &mut kd).unwrap();
            // Central differences of the assembled force along the direction.
            let step = 1e-6;
            let (mut plus, mut minus) = (layout.duplicate().unwrap(), layout.duplicate().unwrap());
            plus.waxpy(step, &dir, &u1).unwrap();
            minus.waxpy(-step, &dir, &u1).unwrap();
            let (mut fp, mut fm) = (layout.duplicate().unwrap(), layout.duplicate().unwrap());
            force(&mut f, &plus, &mut fp);
            force(&mut f, &minus, &mut fm);
            fp.axpy(-1.0, &fm).unwrap();
            fp.scale(0.5 / step).unwrap();
            let scale = kd.norm_inf().unwrap();
            fp.axpy(-1.0, &kd).unwrap();
            let err = fp.norm_inf().unwrap();
            assert!(err < 1e-6 * scale, "{geo} {model}: |K d - FD| = {err:e} of {scale:e}");
        }
    }
}
