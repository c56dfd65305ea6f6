//! The midpoint integrator on its own, in this process (one rank, no mpirun): a 1-DOF and a
//! 2-DOF oscillator against the exact solution of the midpoint rule's recurrence, and the
//! exact energy identity with a time-dependent force; with the step's products recomputed
//! every step and kept (updated from the solve, `time::cg`). MPI and PETSc start once per process,
//! so both checks live in the single test below.

use massfree::error::Result;
use massfree::mass::MassMatrix;
use massfree::petsc::{Matrix, Petsc, Vector};
use massfree::time::midpoint::NoForces;
use massfree::time::{Dirichlet, Forces, Midpoint, StepOperator, StepSolverDefaults};

/// A dense symmetric n x n matrix as a PETSc matrix.
fn matrix(n: usize, a: &[f64]) -> Result<Matrix> {
    let mut m = Matrix::new_aij(n, n, 1, &vec![n as i32; n], &vec![0; n])?;
    for i in 0..n {
        let cols: Vec<i32> = (0..n as i32).collect();
        m.set_values(&[i as i32], &cols, &a[i * n..(i + 1) * n], false)?;
    }
    m.assemble()?;
    Ok(m)
}

fn vector(x: &[f64]) -> Result<Vector> {
    let mut v = Vector::new_mpi(x.len(), x.len(), 1)?;
    v.with_local_slice_mut(|s| s.copy_from_slice(x))?;
    Ok(v)
}

fn values(x: &Vector) -> Vec<f64> {
    x.with_local_slice(|s| s.to_vec()).unwrap()
}

/// Tight tolerance: the checks compare with exact recurrences to ~1e-12.
fn integrator(
    n: usize,
    m: &[f64],
    a: &[f64],
    tau: f64,
    u0: &[f64],
    v0: &[f64],
    forces: &dyn Forces,
    reuse: bool,
) -> Result<Midpoint> {
    let (mm, aa) = (MassMatrix::dofs(matrix(n, m)?), matrix(n, a)?);
    let mut defaults = StepSolverDefaults { rtol: 1e-14, ..Default::default() };
    if !reuse {
        defaults.reuse = None;
    }
    let op = StepOperator::new(&mm, &aa, tau, vec![], false, None, &defaults)?;
    Midpoint::new(op, mm, aa, Dirichlet::none(), tau, vector(u0)?, vector(v0)?, 0.0, forces)
}

/// f(t) = (sin 3t, cos t).
struct Harmonic;
impl Forces for Harmonic {
    fn present(&self) -> bool {
        true
    }
    fn time_dependent(&self) -> bool {
        true
    }
    fn assemble(&self, t: f64, out: &mut Vector) -> Result<()> {
        out.with_local_slice_mut(|s| {
            s[0] = (3.0 * t).sin();
            s[1] = t.cos();
        })
    }
}

/// The midpoint rule maps (u, v/omega) by a rotation of angle theta = 2 atan(omega tau / 2)
/// per step (it is the Cayley transform of the oscillator's generator), for each mode.
fn mode(u0: f64, v0: f64, omega: f64, tau: f64, n: usize) -> (f64, f64) {
    let th = n as f64 * 2.0 * (omega * tau / 2.0).atan();
    (u0 * th.cos() + v0 / omega * th.sin(), -u0 * omega * th.sin() + v0 * th.cos())
}

/// The energy's tolerance: round-off with the products recomputed every step; with them kept
/// (updated from the solve, `time::cg`), what the refreshes let them drift.
fn energy_tol(reuse: bool) -> f64 {
    if reuse {
        Midpoint::DRIFT_TARGET
    } else {
        1e-13
    }
}

fn one_dof(reuse: bool) -> Result<()> {
    let (m, k, tau) = (2.0, 50.0, 0.3); // omega tau = 1.5: far from the exact solution, on purpose
    let (u0, v0) = (0.7, -1.3);
    let mut mp = integrator(1, &[m], &[k], tau, &[u0], &[v0], &NoForces, reuse)?;
    let e0 = mp.energy().total();
    assert!((e0 - (0.5 * m * v0 * v0 + 0.5 * k * u0 * u0)).abs() < 1e-14 * e0);
    let omega = (k / m).sqrt();
    for n in 0..200 {
        mp.step(n, &NoForces, None)?;
        let (u, v) = mode(u0, v0, omega, tau, n + 1);
        let (uh, vh) = (values(mp.u())[0], values(mp.v())[0]);
        assert!((uh - u).abs() < 1e-11, "1 DOF, step {}: u {uh} vs {u}", n + 1);
        assert!((vh - v).abs() < 1e-10 * omega, "1 DOF, step {}: v {vh} vs {v}", n + 1);
        let de = (mp.energy().total() - e0).abs() / e0;
        assert!(de < energy_tol(reuse), "energy at step {}: {de:e}", n + 1);
    }
    Ok(())
}

fn two_dof(reuse: bool) -> Result<()> {
    // A x = lambda M x has the modes (1, 1) with lambda = 2/3 and (1, -1) with lambda = 4.
    let (m, a, tau) = ([2.0, 1.0, 1.0, 2.0], [3.0, -1.0, -1.0, 3.0], 0.05);
    let (u0, v0) = ([0.3, -0.1], [0.2, 0.5]);
    let mut mp = integrator(2, &m, &a, tau, &u0, &v0, &NoForces, reuse)?;
    let half = |x: [f64; 2]| ((x[0] + x[1]) / 2.0, (x[0] - x[1]) / 2.0);
    let ((p0, q0), (pv, qv)) = (half(u0), half(v0));
    let (w1, w2) = ((2.0f64 / 3.0).sqrt(), 2.0);
    for n in 0..400 {
        mp.step(n, &NoForces, None)?;
        let (p, _) = mode(p0, pv, w1, tau, n + 1);
        let (q, _) = mode(q0, qv, w2, tau, n + 1);
        let u = values(mp.u());
        assert!(
            (u[0] - (p + q)).abs() < 1e-11 && (u[1] - (p - q)).abs() < 1e-11,
            "2 DOF, step {}: {u:?}",
            n + 1
        );
    }
    // With a force: E^{n+1} - E^n = f^{n+1/2} . du exactly, accumulated as the external work.
    let mut mp = integrator(2, &m, &a, tau, &u0, &v0, &Harmonic, reuse)?;
    let e0 = mp.energy().total();
    let mut work = 0.0;
    for n in 0..400 {
        let u_before = values(mp.u());
        mp.step(n, &Harmonic, None)?;
        let du: Vec<f64> = values(mp.u()).iter().zip(&u_before).map(|(a, b)| a - b).collect();
        let (t0, t1) = (n as f64 * tau, (n + 1) as f64 * tau);
        let f = [((3.0 * t0).sin() + (3.0 * t1).sin()) / 2.0, (t0.cos() + t1.cos()) / 2.0];
        work += f[0] * du[0] + f[1] * du[1];
        let e = mp.energy();
        assert!((e.external_work - work).abs() < 1e-13, "external work at step {}", n + 1);
        assert!(
            (e.total() - e0 - work).abs() < energy_tol(reuse).max(1e-12) * e0.max(1.0),
            "energy identity at step {}",
            n + 1
        );
    }
    Ok(())
}

#[test]
fn midpoint_rule_on_small_systems() {
    let _universe = mpi::initialize().expect("MPI initialized twice");
    let args = vec!["integrator-test".to_string()];
    let _petsc = Petsc::init(&args, "integrator test").expect("PetscInitialize");
    for reuse in [false, true] {
        one_dof(reuse).unwrap();
        two_dof(reuse).unwrap();
    }
}
