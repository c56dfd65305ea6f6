//! One-rank checks of the PETSc layer. MPI and PETSc can be initialized only once per
//! process and `cargo test` runs tests on threads, so every PETSc check lives in the single
//! `#[test]` below, which runs them in order and reports all failures together.

use massfree::error::{Error, Result};
use massfree::petsc::{
    memory_current, memory_maximum, wtime, IndexSet, Ksp, LogStage, Matrix, NullSpace, Petsc,
    Vector,
};

const N: usize = 100;

fn fail(msg: String) -> Error {
    Error::Solver(format!("check failed: {msg}"))
}

fn ensure(cond: bool, msg: impl FnOnce() -> String) -> Result<()> {
    if cond {
        Ok(())
    } else {
        Err(fail(msg()))
    }
}

/// Exact solution of tridiag(-1, 2, -1) x = 1 (zero Dirichlet values outside).
fn exact(i: usize) -> f64 {
    ((i + 1) * (N - i)) as f64 / 2.0
}

/// The 1D Laplacian, assembled row by row with exact preallocation.
fn laplacian() -> Result<Matrix> {
    let d_nnz: Vec<i32> = (0..N).map(|i| if i == 0 || i == N - 1 { 2 } else { 3 }).collect();
    let mut a = Matrix::new_aij(N, N, 1, &d_nnz, &vec![0; N])?;
    for i in 0..N as i32 {
        let cols: Vec<i32> =
            [i - 1, i, i + 1].into_iter().filter(|&c| c >= 0 && c < N as i32).collect();
        let vals: Vec<f64> = cols.iter().map(|&c| if c == i { 2.0 } else { -1.0 }).collect();
        a.set_values(&[i], &cols, &vals, false)?;
    }
    a.assemble()?;
    Ok(a)
}

fn max_error(x: &Vector) -> Result<f64> {
    let all = x.gather_all()?;
    ensure(all.len() == N, || format!("gather_all gave {} entries", all.len()))?;
    Ok(all.iter().enumerate().map(|(i, v)| (v - exact(i)).abs()).fold(0.0, f64::max))
}

fn check_before_init() -> Result<()> {
    match Vector::new_mpi(3, 3, 1) {
        Err(Error::Petsc { call, .. }) if call.starts_with("PetscInitialized") => Ok(()),
        Err(e) => Err(fail(format!("before init: unexpected error {e}"))),
        Ok(_) => Err(fail("Vector::new_mpi succeeded before Petsc::init".into())),
    }
}

fn check_vector_ops() -> Result<()> {
    let mut x = Vector::new_mpi(N, N, 1)?;
    ensure(x.local_size() == N && x.global_size() == N, || "sizes".into())?;
    ensure(x.ownership_range() == (0, N), || "ownership range".into())?;
    x.with_local_slice_mut(|s| {
        for (i, v) in s.iter_mut().enumerate() {
            *v = i as f64;
        }
    })?;
    let mut y = x.duplicate()?;
    y.set(2.0)?;
    ensure(y.sum()? == 2.0 * N as f64, || "set/sum".into())?;
    let expect_dot: f64 = (0..N).map(|i| 2.0 * i as f64).sum();
    ensure(x.dot(&y)? == expect_dot, || "dot".into())?;
    ensure(x.norm_inf()? == (N - 1) as f64, || "norm_inf".into())?;
    let n2: f64 = (0..N).map(|i| (i * i) as f64).sum::<f64>().sqrt();
    ensure((x.norm2()? - n2).abs() < 1e-12 * n2, || "norm2".into())?;

    let mut z = x.duplicate()?;
    z.copy_from(&x)?;
    z.axpy(-1.0, &x)?; // 0
    ensure(z.norm2()? == 0.0, || "copy_from/axpy".into())?;
    z.waxpy(3.0, &x, &y)?; // 3x + 2
    z.aypx(-1.0, &y)?; // 2 - (3x + 2) = -3x
    z.scale(-1.0 / 3.0)?; // x
    z.axpy(-1.0, &x)?;
    ensure(z.norm_inf()? < 1e-12, || "waxpy/aypx/scale".into())?;
    z.pointwise_mult(&x, &y)?; // 2x
    ensure(z.sum()? == expect_dot, || "pointwise_mult".into())?;

    z.zero()?;
    z.set_values(&[1, 5, 5], &[1.0, 2.0, 3.0], true)?;
    z.assemble()?;
    ensure(z.get_values(&[0, 1, 5])? == vec![0.0, 1.0, 5.0], || {
        "set_values(add)/get_values".into()
    })?;
    z.set_values(&[5], &[7.0], false)?;
    z.assemble()?;
    let first = z.with_local_slice(|s| (s[1], s[5]))?;
    ensure(first == (1.0, 7.0), || format!("insert/with_local_slice: {first:?}"))?;
    ensure(z.gather_all()?[5] == 7.0, || "gather_all".into())?;

    let is = IndexSet::from_global(&[3, 1, 2])?;
    ensure(is.local_len()? == 3 && is.indices()? == vec![3, 1, 2], || "IndexSet".into())?;

    match z.set_values(&[1, 2], &[1.0], false) {
        Err(Error::Solver(m)) if m.contains("set_values") => {}
        other => return Err(fail(format!("length mismatch not reported: {other:?}"))),
    }
    Ok(())
}

fn check_matrix_ops() -> Result<()> {
    let a = laplacian()?;
    ensure(a.size() == (N, N) && a.ownership_range() == (0, N), || "layout".into())?;
    let info = a.nonzero_info()?;
    let nnz = (3 * N - 2) as f64;
    ensure(info.allocated == nnz && info.used == nnz && info.mallocs == 0.0, || {
        format!("exact preallocation: {info:?}")
    })?;
    ensure(a.info_nonzeros_used()? == nnz, || "info_nonzeros_used".into())?;
    ensure(a.info_nonzeros_allocated()? == nnz, || "info_nonzeros_allocated".into())?;
    ensure(a.get_row(0)? == (vec![0, 1], vec![2.0, -1.0]), || "get_row(0)".into())?;
    ensure(a.get_row(50)? == (vec![49, 50, 51], vec![-1.0, 2.0, -1.0]), || "get_row(50)".into())?;
    ensure(a.get_row(N).is_err(), || "get_row out of range accepted".into())?;
    ensure(a.is_symmetric(0.0)?, || "is_symmetric".into())?;
    let fro = (4.0 * N as f64 + 2.0 * (N - 1) as f64).sqrt();
    ensure((a.norm_frobenius()? - fro).abs() < 1e-12, || "norm_frobenius".into())?;

    let (mut x, mut b) = a.create_vecs()?;
    ensure(x.global_size() == N && b.global_size() == N, || "create_vecs".into())?;
    a.get_diagonal(&mut x)?;
    ensure(x.sum()? == 2.0 * N as f64, || "get_diagonal".into())?;
    x.set(1.0)?;
    a.mult(&x, &mut b)?; // row sums: 1 at both ends, 0 inside
    ensure(b.sum()? == 2.0 && b.norm_inf()? == 1.0, || "mult".into())?;
    let mut c = b.duplicate()?;
    a.mult_add(&x, &b, &mut c)?;
    ensure(c.sum()? == 4.0, || "mult_add".into())?;

    let mut m = a.duplicate(true)?;
    m.scale(2.0)?;
    m.axpy(-2.0, &a, massfree::petsc::Pattern::Same)?;
    ensure(m.norm_frobenius()? == 0.0, || "duplicate/scale/axpy".into())?;
    let z = a.duplicate(false)?;
    ensure(z.norm_frobenius()? == 0.0, || "duplicate(false) copied values".into())?;

    // Dirichlet row/column 0 pinned to x0 = 5: b0 = 5 and b1 gets +5 from the column.
    let mut k = a.duplicate(true)?;
    let mut xb = x.duplicate()?;
    xb.set(5.0)?;
    let mut rhs = x.duplicate()?;
    rhs.zero()?;
    k.zero_rows_columns(&[0], 1.0, Some(&xb), Some(&mut rhs))?;
    ensure(k.get_row(0)? == (vec![0, 1], vec![1.0, 0.0]), || "zero_rows_columns row".into())?;
    ensure(k.get_row(1)?.1 == vec![0.0, 2.0, -1.0], || "zero_rows_columns col".into())?;
    ensure(rhs.get_values(&[0, 1, 2])? == vec![5.0, 5.0, 0.0], || {
        format!("zero_rows_columns rhs {:?}", rhs.get_values(&[0, 1, 2]))
    })?;
    ensure(k.is_symmetric(0.0)?, || "zero_rows_columns kept symmetry".into())?;
    k.zero_rows(&[N as i32 - 1], 3.0, None, None)?;
    ensure(k.get_row(N - 1)?.1 == vec![0.0, 3.0], || "zero_rows".into())?;
    Ok(())
}

fn rhs_ones(a: &Matrix) -> Result<(Vector, Vector)> {
    let (x, mut b) = a.create_vecs()?;
    b.set(1.0)?;
    Ok((x, b))
}

fn check_cg_jacobi() -> Result<()> {
    let mut a = laplacian()?;
    a.set_option_symmetric(true)?;
    let (mut x, b) = rhs_ones(&a)?;
    let mut ksp = Ksp::new("cgj_")?;
    ksp.set_operators(&a, &a)?;
    ksp.set_type("cg")?;
    ksp.set_pc_type("jacobi")?;
    ksp.set_tolerances(Some(1e-12), Some(1e-50), None, Some(1000))?;
    ksp.set_from_options()?;
    let info = ksp.solve(&b, &mut x)?;
    ensure(ksp.ksp_type()? == "cg" && ksp.pc_type()? == "jacobi", || "types".into())?;
    ensure(info.reason > 0 && info.iterations <= N, || format!("{info:?}"))?;
    let err = max_error(&x)?;
    ensure(err < 1e-7, || format!("CG error {err}"))?;
    // True residual |b - A x|.
    let mut r = b.duplicate()?;
    a.mult(&x, &mut r)?;
    r.aypx(-1.0, &b)?;
    ensure(r.norm2()? < 1e-8, || "CG residual".into())?;
    println!("cg+jacobi: {info:?}, max error {err:e}");
    Ok(())
}

fn check_mumps_cholesky() -> Result<()> {
    let mut a = laplacian()?;
    a.set_option_spd(true)?;
    let (mut x, b) = rhs_ones(&a)?;
    let mut ksp = Ksp::new("direct_")?;
    ksp.set_operators(&a, &a)?;
    ksp.set_type("preonly")?;
    ksp.set_pc_factor_solver_type("mumps")?; // before set_pc_type on purpose: must stick
    ksp.set_pc_type("cholesky")?;
    ksp.set_from_options()?;
    ksp.set_up()?;
    let info = ksp.solve(&b, &mut x)?;
    let err = max_error(&x)?;
    ensure(err < 1e-9, || format!("MUMPS error {err}"))?;
    ensure(ksp.pc_type()? == "cholesky", || "pc type".into())?;
    let pkg = ksp.pc_factor_solver_type()?;
    ensure(pkg == "mumps", || format!("factor package {pkg:?}"))?;
    println!("mumps cholesky: {info:?}, max error {err:e}");
    // Second solve reuses the factorization.
    x.zero()?;
    ksp.solve(&b, &mut x)?;
    ensure(max_error(&x)? < 1e-9, || "MUMPS re-solve".into())?;
    Ok(())
}

fn check_error_paths(petsc: &Petsc) -> Result<()> {
    // Incompatible sizes: PETSc error naming the call, not a panic.
    let a = laplacian()?;
    let x = Vector::new_mpi(N / 2, N / 2, 1)?;
    let mut y = Vector::new_mpi(N, N, 1)?;
    match petsc.with_quiet_errors(|| a.mult(&x, &mut y)) {
        Err(Error::Petsc { call, code, location, message }) => {
            ensure(call == "MatMult" && code != 0, || format!("{call} {code}"))?;
            ensure(location.starts_with("src/petsc/mat.rs:"), || location.clone())?;
            println!("expected error: {}", Error::Petsc { call, code, location, message });
        }
        other => return Err(fail(format!("MatMult size mismatch gave {other:?}"))),
    }

    // Preallocation violation: only the diagonal was preallocated.
    let mut d = Matrix::new_aij(4, 4, 1, &[1; 4], &[0; 4])?;
    d.set_values(&[0], &[0], &[1.0], false)?;
    match petsc.with_quiet_errors(|| d.set_values(&[0], &[1], &[1.0], false)) {
        Err(Error::Petsc { call, .. }) if call == "MatSetValues" => {}
        other => return Err(fail(format!("preallocation violation gave {other:?}"))),
    }

    // Divergence via the reason check.
    let (mut x, b) = rhs_ones(&a)?;
    let mut ksp = Ksp::new("fail_")?;
    ksp.set_operators(&a, &a)?;
    ksp.set_type("cg")?;
    ksp.set_pc_type("none")?;
    ksp.set_tolerances(Some(1e-14), None, None, Some(1))?;
    ksp.set_from_options()?;
    match ksp.solve(&b, &mut x) {
        Err(Error::Solver(m)) if m.contains("DIVERGED_ITS") && m.contains("fail_") => {
            println!("expected error: {}", Error::Solver(m));
        }
        other => return Err(fail(format!("forced divergence gave {other:?}"))),
    }

    // Divergence via -ksp_error_if_not_converged: KSPSolve itself fails.
    Petsc::options_set("-strict_ksp_error_if_not_converged", None)?;
    let mut ksp = Ksp::new("strict_")?;
    ksp.set_operators(&a, &a)?;
    ksp.set_type("cg")?;
    ksp.set_pc_type("none")?;
    ksp.set_tolerances(Some(1e-14), None, None, Some(1))?;
    ksp.set_from_options()?;
    match petsc.with_quiet_errors(|| ksp.solve(&b, &mut x)) {
        Err(Error::Petsc { call, .. }) if call == "KSPSolve" => {}
        other => return Err(fail(format!("error_if_not_converged gave {other:?}"))),
    }

    // Unknown type name.
    let mut ksp = Ksp::new("bad_")?;
    match petsc.with_quiet_errors(|| ksp.set_type("no_such_ksp")) {
        Err(Error::Petsc { call, .. }) if call == "KSPSetType" => {}
        other => return Err(fail(format!("bad KSP type gave {other:?}"))),
    }
    Ok(())
}

fn check_null_space() -> Result<()> {
    // 4 nodes of a unit square, 2 dofs each.
    let mut coords = Vector::new_mpi(8, 8, 2)?;
    coords.with_local_slice_mut(|s| s.copy_from_slice(&[0., 0., 1., 0., 1., 1., 0., 1.]))?;
    let ns = NullSpace::rigid_body_modes(&coords)?;
    ensure(ns.num_vectors()? == 3, || "2D rigid body modes".into())?;
    // A matrix with the same layout accepts it; a zero matrix has it as null space.
    let mut m = Matrix::new_aij(8, 8, 2, &[1; 8], &[0; 8])?;
    m.assemble()?;
    m.set_near_null_space(&ns)?;
    ensure(ns.is_null_space_of(&m)?, || "null space of zero matrix".into())?;
    let mut coords3 = Vector::new_mpi(6, 6, 3)?;
    coords3.with_local_slice_mut(|s| s.copy_from_slice(&[0., 0., 0., 1., 2., 3.]))?;
    ensure(NullSpace::rigid_body_modes(&coords3)?.num_vectors()? == 6, || "3D modes".into())
}

fn check_options_and_log() -> Result<()> {
    Petsc::options_set("-my_int", Some("42"))?;
    Petsc::options_set("-my_real", Some("2.5"))?;
    Petsc::options_set("-my_str", Some("hello"))?;
    ensure(Petsc::options_has("-my_int")?, || "options_has".into())?;
    ensure(!Petsc::options_has("-not_there")?, || "options_has absent".into())?;
    ensure(Petsc::options_get_int("-my_int")? == Some(42), || "get_int".into())?;
    ensure(Petsc::options_get_real("-my_real")? == Some(2.5), || "get_real".into())?;
    ensure(Petsc::options_get_string("-my_str")? == Some("hello".into()), || "get_string".into())?;
    ensure(Petsc::options_get_int("-nope")?.is_none(), || "get_int absent".into())?;
    Petsc::options_clear("-my_str")?;
    ensure(!Petsc::options_has("-my_str")?, || "options_clear".into())?;
    for k in ["-my_int", "-my_real"] {
        Petsc::options_clear(k)?;
    }
    let stage = LogStage::register("test stage")?;
    stage.push()?;
    let t0 = wtime();
    let mem = memory_current()?;
    stage.pop()?;
    ensure(wtime() >= t0 && mem > 0.0, || format!("wtime/memory {mem}"))?;
    let _ = memory_maximum()?;
    Ok(())
}

#[test]
fn petsc_layer_on_one_rank() {
    let universe = mpi::initialize().expect("MPI initialized twice");
    let mut failures = Vec::new();
    if let Err(e) = check_before_init() {
        failures.push(format!("before_init: {e}"));
    }
    let args: Vec<String> = ["serial-test", "-malloc_debug", "-malloc_dump", "-options_left"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let petsc = Petsc::init(&args, "petscdev serial test").expect("PetscInitialize");
    assert_eq!((petsc.rank(), petsc.size()), (0, 1));
    assert!(Petsc::init(&args, "").is_err(), "second init must fail");

    type Check = fn(&Petsc) -> Result<()>;
    let checks: [(&str, Check); 7] = [
        ("vector_ops", |_| check_vector_ops()),
        ("matrix_ops", |_| check_matrix_ops()),
        ("cg_jacobi", |_| check_cg_jacobi()),
        ("mumps_cholesky", |_| check_mumps_cholesky()),
        ("error_paths", check_error_paths),
        ("null_space", |_| check_null_space()),
        ("options_and_log", |_| check_options_and_log()),
    ];
    for (name, check) in checks {
        match check(&petsc) {
            Ok(()) => println!("{name}: ok"),
            Err(e) => failures.push(format!("{name}: {e}")),
        }
    }
    drop(petsc);
    // After finalize, constructors refuse instead of crashing.
    if Vector::new_mpi(1, 1, 1).is_ok() {
        failures.push("Vector::new_mpi succeeded after PetscFinalize".into());
    }
    drop(universe);
    assert!(failures.is_empty(), "failed checks:\n{}", failures.join("\n"));
}
