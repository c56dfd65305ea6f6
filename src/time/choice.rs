//! The step solver chosen knowing the run: for an operator used unchanged for many
//! steps, a sparse Cholesky factorization (MUMPS) pays back its set-up after some number of
//! steps. [`choose`] compares the run's estimated cost both ways, from the operator's size, the
//! run's length and regime and the time of one product with `K` (timed at set-up), and takes
//! the factorization when it is cheaper over the run and fits in memory.
//!
//! The model, fitted to MUMPS 5.5 through PETSc 3.18 on this machine (AMD EPYC, 1 rank;
//! README "Step solver by run length"), nested-dissection orderings:
//!
//! ```text
//!   factor flops   3D: 4.2 n^2        2D: 26.5 n^1.5           (n = DOFs)
//!   factor entries 3D: 12.2e6 (n/36663)^1.43   2D: 25.7e6 (n/330498)^1.16
//!   factor seconds flops / (6e9 p^0.5) + 4e-6 n / p          (p = ranks)
//!   factor memory  12 bytes an entry (MUMPS's INFOG(16): 10.5-13.2), 1.25 / p per rank on p > 1
//!   a solve        45 products with K (measured 35 at 0.27-1M DOFs, 45-49 at 37-83k)
//! ```
//! The averaged nodal pressure of triangles and tetrahedra couples nodes two cells apart: its
//! graph is about the square of the mesh's, whose separators are two node layers thick, so
//! the fronts double: flops 8 and entries 4 times the plain pattern's (MUMPS' analysis of the
//! suite's disc of triangles at 828-11994 DOFs: 6.2-7.2 and 2.7-3.1 times; the ball of
//! tetrahedra at 1317-13545 DOFs: 6.4-7.6 and 2.8-3.3 times, rising with the size).
//!
//! and the iterative solvers in products with `K` per step (fitted over CFL 0.3-100, 1 rank,
//! free vibration): CG + Jacobi `5 + 13 CFL` in 2D and `5 + 20 CFL` in 3D, CG + GAMG
//! `100 + 70 log10 CFL` in 2D and `120 + 120 log10 CFL` in 3D plus a set-up of 400 products.

use super::operator::{GAMG_ABOVE_CFL, GAMG_ABOVE_CFL_CONTACT};

/// What the choice knows of the run.
#[derive(Debug, Clone, Copy)]
pub struct RunFacts {
    /// Unknowns of the step operator.
    pub dofs: usize,
    pub dim: usize,
    pub ranks: usize,
    /// Steps the run will take.
    pub steps: usize,
    pub cfl: f64,
    /// A contact solver rewrites rows of `K` when the active set changes: a factorization
    /// would be redone (not chosen for such runs yet).
    pub contact: bool,
    /// Memory a rank may still use, in bytes.
    pub memory_per_rank: f64,
    /// The largest `lambda / mu` of the bodies (48 at nu = 0.49, 5000 at nu = 0.4999).
    pub lambda_over_mu: f64,
    /// Some body's simplices take the averaged nodal pressure: `K` couples nodes two cells
    /// apart.
    pub nodal_pressure: bool,
}

/// The nodal pressure's factor against the plain pattern's (module doc): flops, entries.
pub const NODAL_PRESSURE_FILL: (f64, f64) = (8.0, 4.0);

/// From this `lambda / mu` on (nu = 0.49) the iterative solvers' counts leave the fitted model
/// (fitted at nu = 0.3): on the disc with contact (406 DOFs, 2 ranks) CG + GAMG took 188
/// iterations and 3.95 ms a step at nu = 0.4999 with the mean dilatation, MUMPS' Cholesky
/// 0.32 ms (refactored at every active-set change); on the Q1 ball (11271 DOFs) 406 iterations
/// and 1800 ms against 52.5 ms; at nu = 0.49 on the disc CG + Jacobi 0.51 ms, Cholesky 0.29 ms.
pub const NEARLY_INCOMPRESSIBLE: f64 = 48.0;

/// A nearly incompressible run factors when the factorization costs at most this many of the
/// iterative solver's estimated steps (with contact it is redone at active-set changes).
pub const INCOMPRESSIBLE_FACTOR_STEPS: f64 = 10.0;

/// From this `lambda / mu` on (nu = 0.4995) a finite-strain run factors each Newton tangent
/// (MUMPS' LU) instead of GMRES + SOR. Measured with the mean dilatation, the neo-Hookean disc
/// dropped at 0.58 with `tau` = 0.0025 (406 DOFs, 1 rank): at nu = 0.4999 GMRES took 790
/// iterations and 44.5 ms a step, LU 11.4 ms; at 0.499 GMRES was still the faster (3.42
/// against 4.73 ms). On the Q1 ball at 0.4999 (5205 DOFs) GMRES with GAMG stopped at 10000
/// iterations in the first contact steps and SOR took 2600 iterations a step; LU ran through.
pub const FINITE_STRAIN_FACTOR_RATIO: f64 = 1000.0;

/// Whether a finite-strain run factors its Newton tangents: nearly incompressible beyond
/// [`FINITE_STRAIN_FACTOR_RATIO`], and the LU factor (twice the Cholesky estimate) fits in
/// [`MEMORY_SHARE`] of the memory a rank may still use.
pub fn finite_strain_factors(f: &RunFacts) -> bool {
    let bytes = 2.0 * estimate(f, 0.0).factor_bytes_per_rank;
    f.lambda_over_mu >= FINITE_STRAIN_FACTOR_RATIO && bytes <= MEMORY_SHARE * f.memory_per_rank
}

/// The step solver chosen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Solver {
    /// CG + Jacobi.
    Jacobi,
    /// CG + GAMG.
    Multigrid,
    /// A sparse Cholesky factorization (MUMPS), one solve a step.
    Cholesky,
}

/// The estimates behind a choice (seconds, bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub factor_seconds: f64,
    pub factor_bytes_per_rank: f64,
    /// The whole run's step solves with the factorization (its set-up included) and with the
    /// iterative solver.
    pub cholesky_seconds: f64,
    pub iterative_seconds: f64,
    /// Steps after which the factorization has paid for itself (infinite: never).
    pub payback_steps: f64,
}

/// Products with `K` a factorization's solve costs (measured 35 at 0.27-1 million DOFs, 45-49
/// at 37-83 thousand).
pub const CHOLESKY_SOLVE_PRODUCTS: f64 = 45.0;
/// A factorization may take this share of the memory a rank may still use.
pub const MEMORY_SHARE: f64 = 0.5;

/// The factorization's entries (nested dissection fill, fitted).
pub fn factor_entries(dofs: usize, dim: usize) -> f64 {
    let n = dofs as f64;
    if dim >= 3 {
        12.2e6 * (n / 36663.0).powf(1.43)
    } else {
        25.7e6 * (n / 330498.0).powf(1.16)
    }
}

/// The factorization's floating-point operations (fitted).
pub fn factor_flops(dofs: usize, dim: usize) -> f64 {
    let n = dofs as f64;
    if dim >= 3 {
        4.2 * n * n
    } else {
        26.5 * n.powf(1.5)
    }
}

/// Products with `K` a step of the iterative solver costs, and its set-up in products
/// (fitted to the table over CFL 0.3-100 of README "Benchmark: the step floor": 2D Q1 and 3D
/// P1, free vibration, 1 rank).
pub fn iterative_products(solver: Solver, cfl: f64, dim: usize) -> (f64, f64) {
    let three = dim >= 3;
    match solver {
        Solver::Multigrid => {
            let decades = cfl.max(1.0).log10();
            let per_step = if three { 120.0 + 120.0 * decades } else { 100.0 + 70.0 * decades };
            (per_step, 400.0)
        }
        _ => (5.0 + if three { 20.0 } else { 13.0 } * cfl, 0.0),
    }
}

/// The iterative solver the regime picks (README "Step solver by regime": measured crossovers).
pub fn iterative(cfl: f64, contact: bool) -> Solver {
    let limit = if contact { GAMG_ABOVE_CFL_CONTACT } else { GAMG_ABOVE_CFL };
    if cfl > limit {
        Solver::Multigrid
    } else {
        Solver::Jacobi
    }
}

/// The estimates for a run, `matmult` the seconds of one product with `K`.
pub fn estimate(f: &RunFacts, matmult: f64) -> Estimate {
    let p = f.ranks.max(1) as f64;
    let n = f.dofs as f64;
    let (flops, entries) = if f.nodal_pressure { NODAL_PRESSURE_FILL } else { (1.0, 1.0) };
    let factor_seconds = flops * factor_flops(f.dofs, f.dim) / (6e9 * p.sqrt()) + 4e-6 * n / p;
    let spread = if f.ranks > 1 { 1.25 } else { 1.0 };
    let factor_bytes_per_rank = 12.0 * entries * factor_entries(f.dofs, f.dim) * spread / p;
    let (per_step, setup) = iterative_products(iterative(f.cfl, f.contact), f.cfl, f.dim);
    let steps = f.steps as f64;
    let iterative_seconds = (setup + steps * per_step) * matmult;
    let cholesky_seconds = factor_seconds + steps * CHOLESKY_SOLVE_PRODUCTS * matmult;
    let saved = (per_step - CHOLESKY_SOLVE_PRODUCTS) * matmult;
    let payback_steps =
        if saved > 0.0 { (factor_seconds - setup * matmult) / saved } else { f64::INFINITY };
    Estimate {
        factor_seconds,
        factor_bytes_per_rank,
        cholesky_seconds,
        iterative_seconds,
        payback_steps,
    }
}

/// The step solver for the run, its estimates and the reason (for the run's report).
pub fn choose(f: &RunFacts, matmult: f64) -> (Solver, Estimate, String) {
    let it = iterative(f.cfl, f.contact);
    let e = estimate(f, matmult);
    let name = match it {
        Solver::Multigrid => "multigrid",
        _ => "Jacobi",
    };
    let mib = e.factor_bytes_per_rank / 1048576.0;
    if f.lambda_over_mu >= NEARLY_INCOMPRESSIBLE {
        // The model's iterative step (fitted at nu = 0.3) is a lower bound here.
        let step = iterative_products(it, f.cfl, f.dim).0 * matmult;
        let fits = e.factor_bytes_per_rank <= MEMORY_SHARE * f.memory_per_rank;
        if fits && e.factor_seconds <= INCOMPRESSIBLE_FACTOR_STEPS * step {
            return (
                Solver::Cholesky,
                e,
                format!(
                    "CFL {:.3}, lambda/mu {:.0}: Cholesky (MUMPS), est. {:.2} s and {mib:.0} MiB per rank to factor{}{} (nearly incompressible: {name} needs several times its usual iterations)",
                    f.cfl,
                    f.lambda_over_mu,
                    e.factor_seconds,
                    if f.nodal_pressure { " the nodal pressure's wider pattern" } else { "" },
                    if f.contact { ", again at active-set changes" } else { "" }
                ),
            );
        }
    }
    if f.contact {
        return (it, e, format!("CFL {:.3}, contact: {name}", f.cfl));
    }
    if e.payback_steps.is_infinite() {
        return (
            it,
            e,
            format!("CFL {:.3}: {name} (a factorization's solve costs more than a step)", f.cfl),
        );
    }
    if e.cholesky_seconds >= e.iterative_seconds {
        return (
            it,
            e,
            format!(
                "CFL {:.3}: {name}; a Cholesky factorization (est. {:.1} s) would pay back after {:.0} steps, the run has {}",
                f.cfl, e.factor_seconds, e.payback_steps, f.steps
            ),
        );
    }
    if e.factor_bytes_per_rank > MEMORY_SHARE * f.memory_per_rank {
        return (
            it,
            e,
            format!(
                "CFL {:.3}: {name}; a Cholesky factorization would pay back after {:.0} of {} steps but needs est. {mib:.0} MiB per rank, more than half of the {:.0} MiB free",
                f.cfl,
                e.payback_steps,
                f.steps,
                f.memory_per_rank / 1048576.0
            ),
        );
    }
    (
        Solver::Cholesky,
        e,
        format!(
            "CFL {:.3}, {} steps: Cholesky (MUMPS), est. {:.1} s and {mib:.0} MiB per rank to factor, paid back after {:.0} steps ({name}: est. {:.0} s of solves, Cholesky {:.0} s)",
            f.cfl, f.steps, e.factor_seconds, e.payback_steps, e.iterative_seconds, e.cholesky_seconds
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finite_strain_factors_only_nearly_incompressible_runs_that_fit() {
        let disc = |lambda_over_mu: f64, memory_per_rank: f64| RunFacts {
            dofs: 406,
            dim: 2,
            ranks: 1,
            steps: 1000,
            cfl: 100.0,
            contact: true,
            memory_per_rank,
            lambda_over_mu,
            nodal_pressure: false,
        };
        assert!(finite_strain_factors(&disc(4999.0, 1e9)));
        assert!(!finite_strain_factors(&disc(499.0, 1e9)), "GMRES + SOR is faster at 0.499");
        assert!(!finite_strain_factors(&disc(4999.0, 1e3)), "the factor must fit");
    }

    /// The 3D block of the benchmark: 265923 DOFs, CFL 32.8, one product 6.5 ms (1 rank).
    fn block(steps: usize) -> RunFacts {
        RunFacts {
            dofs: 265923,
            dim: 3,
            ranks: 1,
            steps,
            cfl: 32.8,
            contact: false,
            memory_per_rank: 20e9,
            lambda_over_mu: 1.5,
            nodal_pressure: false,
        }
    }

    /// Nearly incompressible: the ball of 11271 DOFs with contact (one product 0.2 ms) factors;
    /// the block of 265923 DOFs does not (est. 50 s to factor against 2 s a multigrid step);
    /// at nu = 0.3 the ball keeps the iterative solver.
    #[test]
    fn nearly_incompressible_runs_factor_when_it_costs_a_few_steps() {
        let ball = |lambda_over_mu| RunFacts {
            dofs: 11271,
            cfl: 435.0,
            contact: true,
            lambda_over_mu,
            ranks: 2,
            ..block(220)
        };
        assert_eq!(choose(&ball(5000.0), 2e-4).0, Solver::Cholesky);
        assert!(choose(&ball(5000.0), 2e-4).2.contains("lambda/mu 5000"));
        assert_eq!(choose(&ball(1.5), 2e-4).0, Solver::Multigrid);
        let big = RunFacts { contact: true, lambda_over_mu: 5000.0, ..block(1000) };
        assert_eq!(choose(&big, 6.5e-3).0, Solver::Multigrid);
        // Without room for the factor it stays iterative.
        let small_memory = RunFacts { memory_per_rank: 1e3, ..ball(5000.0) };
        assert_eq!(choose(&small_memory, 2e-4).0, Solver::Multigrid);
    }

    /// The nodal pressure's wider pattern (8 times the flops, 4 times the entries) decides:
    /// a nearly incompressible ball of 40000 DOFs (one product 0.71 ms) factors with the plain
    /// pattern (est. 0.87 s, ten multigrid steps 3.1 s) and not with the nodal one (6.4 s);
    /// the ball of 11271 DOFs with 25 MB for the factor fits its plain estimate (17 MB) and
    /// not the nodal one (68 MB), in the small-strain choice and the finite-strain LU alike.
    #[test]
    fn the_nodal_pressure_pattern_costs_its_factorization_more() {
        let ball = |dofs, nodal_pressure| RunFacts {
            dofs,
            cfl: 435.0,
            contact: true,
            lambda_over_mu: 5000.0,
            ranks: 2,
            nodal_pressure,
            ..block(220)
        };
        assert_eq!(choose(&ball(40000, false), 7.1e-4).0, Solver::Cholesky);
        assert_eq!(choose(&ball(40000, true), 7.1e-4).0, Solver::Multigrid);
        let (plain, nodal) =
            (estimate(&ball(40000, false), 0.0), estimate(&ball(40000, true), 0.0));
        let per_dof = 4e-6 * 40000.0 / 2.0; // the factorization's term linear in n
        let flops = (nodal.factor_seconds - per_dof) / (plain.factor_seconds - per_dof);
        assert!((flops - 8.0).abs() < 1e-9, "{flops}");
        assert_eq!(nodal.factor_bytes_per_rank, 4.0 * plain.factor_bytes_per_rank);
        let tight = |nodal| RunFacts { memory_per_rank: 50e6, ..ball(11271, nodal) };
        assert_eq!(choose(&tight(false), 2e-4).0, Solver::Cholesky);
        assert_eq!(choose(&tight(true), 2e-4).0, Solver::Multigrid);
        let roomy = |nodal| RunFacts { memory_per_rank: 100e6, ..ball(11271, nodal) };
        assert!(finite_strain_factors(&roomy(false)), "LU: twice 17 MB fits in 50");
        assert!(!finite_strain_factors(&roomy(true)), "twice 68 MB does not");
    }

    #[test]
    fn the_model_reproduces_the_measurements_it_was_fitted_to() {
        // Measured (1 rank): factor + analysis 50.5 s, 210.4e6 entries, 2204 MB (MUMPS's
        // INFOG(16)) for the 3D block; 8.9 s, 93.4e6 entries, 1231 MB for the 2D beam at
        // 1008450 DOFs.
        let e = estimate(&block(1), 6.5e-3);
        assert!((e.factor_seconds / 50.5 - 1.0).abs() < 0.1, "{}", e.factor_seconds);
        assert!((factor_entries(265923, 3) / 210.4e6 - 1.0).abs() < 0.1);
        assert!((e.factor_bytes_per_rank / 2204e6 - 1.0).abs() < 0.2);
        let beam = RunFacts { dofs: 1008450, dim: 2, cfl: 0.05, ..block(1) };
        let e = estimate(&beam, 8.6e-3);
        assert!((e.factor_seconds / 8.9 - 1.0).abs() < 0.1, "{}", e.factor_seconds);
        assert!((factor_entries(1008450, 2) / 93.4e6 - 1.0).abs() < 0.1);
    }

    #[test]
    fn a_long_stiff_run_factors_and_a_short_one_does_not() {
        let e = estimate(&block(1), 6.5e-3);
        let crossover = e.payback_steps;
        // (50.5 - 2.6) s / ((302 - 45) * 6.5 ms): about 29 steps (measured: 41).
        assert!(crossover > 20.0 && crossover < 80.0, "payback after {crossover} steps");
        let below = (crossover * 0.9) as usize;
        let above = (crossover * 1.1) as usize + 1;
        assert_eq!(choose(&block(below), 6.5e-3).0, Solver::Multigrid);
        assert_eq!(choose(&block(above), 6.5e-3).0, Solver::Cholesky);
    }

    #[test]
    fn the_factorization_must_fit() {
        let mut f = block(10_000);
        assert_eq!(choose(&f, 6.5e-3).0, Solver::Cholesky);
        let need = estimate(&f, 6.5e-3).factor_bytes_per_rank;
        f.memory_per_rank = need / MEMORY_SHARE * 0.99;
        assert_eq!(choose(&f, 6.5e-3).0, Solver::Multigrid);
        f.memory_per_rank = need / MEMORY_SHARE * 1.01;
        assert_eq!(choose(&f, 6.5e-3).0, Solver::Cholesky);
    }

    #[test]
    fn mass_dominated_steps_never_factor() {
        // The beam at CFL 0.05: a step costs a few products, a solve 45.
        let beam = RunFacts { dofs: 1008450, dim: 2, cfl: 0.05, ..block(1_000_000) };
        let (s, e, _) = choose(&beam, 8.6e-3);
        assert_eq!(s, Solver::Jacobi);
        assert!(e.payback_steps.is_infinite());
        // At the Jacobi-to-multigrid crossover a long run factors.
        let stiff = RunFacts { cfl: GAMG_ABOVE_CFL, ..beam };
        assert_eq!(choose(&stiff, 8.6e-3).0, Solver::Cholesky);
        // Just where Jacobi's steps cost as much as a solve, never.
        let even = RunFacts { cfl: (CHOLESKY_SOLVE_PRODUCTS - 5.0) / 13.0, ..beam };
        assert!(estimate(&even, 8.6e-3).payback_steps.is_infinite());
    }

    #[test]
    fn the_crossovers_of_the_measured_table() {
        // README's table (1 rank, 1000 steps): the beam (83330 DOFs, a product 0.45 ms)
        // keeps Jacobi at CFL 3 (19.4 ms a step against 22.1 for a solve) and factors at 10;
        // the block (36663 DOFs, 0.39 ms) factors from CFL 3 (26.8 against 16.8 ms).
        let beam = |cfl| RunFacts { dofs: 83330, dim: 2, cfl, ..block(1000) };
        assert_eq!(choose(&beam(1.0), 0.45e-3).0, Solver::Jacobi);
        assert_eq!(choose(&beam(3.0), 0.45e-3).0, Solver::Jacobi);
        assert_eq!(choose(&beam(10.0), 0.45e-3).0, Solver::Cholesky);
        let cube = |cfl| RunFacts { dofs: 36663, cfl, ..block(1000) };
        assert_eq!(choose(&cube(1.0), 0.39e-3).0, Solver::Jacobi);
        assert_eq!(choose(&cube(3.0), 0.39e-3).0, Solver::Cholesky);
    }

    #[test]
    fn contact_runs_keep_the_iterative_solver() {
        let f = RunFacts { contact: true, ..block(1_000_000) };
        assert_eq!(choose(&f, 6.5e-3).0, Solver::Multigrid);
        let f = RunFacts { contact: true, cfl: 20.0, ..block(1_000_000) };
        assert_eq!(choose(&f, 6.5e-3).0, Solver::Jacobi);
    }
}
