//! Issue 28, the mass-free layer at the price of the standard mass (`./run bench --only
//! layer`): `M_H^0` and `M_H^1` against `M`, milliseconds and KSP iterations per step, with
//! the layer's sweep (`time::layer`, the default; in 3D also with the whole layer gathered,
//! `-step_layer_local false`, against the default own blocks) and without it
//! (`-step_layer false`):
//!
//! - the beam of section 7.1 (its loads, tau = 1e-5) at 83k and 330k DOFs, 1000 steps, on 1
//!   and 2 ranks;
//! - the 3D block (Q1 hexahedra, h = 0.0625, 140k DOFs, its loads) at CFL 1 and 30, 30 steps,
//!   2 ranks (the default solver of each: CG + Jacobi at CFL 1, the factorization at 30);
//! - the disc and the ball with contact (the contact-cost study's settings at one point each),
//!   whose contact steps PETSc's KSP solves: there the sweep is `-step_layer_around` (around
//!   Jacobi for the disc, block Jacobi/ILU for the ball), off by default.
//!
//! The runs of one case are interleaved over the mass kinds and repeated; each keeps its
//! fastest round (this machine's timings vary by 20% and more between runs).

use std::path::{Path, PathBuf};
use std::process::Command;

use massfree::report::RunSummary;

/// `mpirun -n ranks massfree run scene --quiet --no-output args`: its summary, or None (the
/// failure's stderr printed).
pub fn run(
    repo: &Path,
    ranks: usize,
    scene: &Path,
    args: &[String],
    dir: &Path,
) -> Option<RunSummary> {
    let summary = dir.join("layer.toml");
    let _ = std::fs::remove_file(&summary);
    let o = Command::new("mpirun")
        .args(["--oversubscribe", "-n", &ranks.to_string()])
        .arg(repo.join("target/release/massfree"))
        .arg("run")
        .arg(scene)
        .args(["--quiet", "--no-output", "--summary"])
        .arg(&summary)
        .args(args)
        .env("OMPI_ALLOW_RUN_AS_ROOT", "1")
        .env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1")
        .env("OMPI_MCA_btl_vader_single_copy_mechanism", "none")
        .output()
        .ok()?;
    if !o.status.success() {
        eprintln!("bench: run failed: {}", String::from_utf8_lossy(&o.stderr));
        return None;
    }
    toml::from_str(&std::fs::read_to_string(&summary).ok()?).ok()
}

/// A shipped scene with its mesh path made absolute and the step `tau` if given.
pub fn scene(repo: &Path, name: &str, tau: Option<f64>, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(repo.join("scenes").join(name)).expect("scene");
    let mut out = String::new();
    for line in text.lines() {
        match tau {
            Some(t) if line.trim_start().starts_with("tau =") => out += &format!("tau = {t:e}\n"),
            _ => {
                out += &line.replace("\"../meshes/", &format!("\"{}/meshes/", repo.display()));
                out += "\n";
            }
        }
    }
    let tag = tau.map_or("same".to_string(), |t| format!("{t:e}"));
    let path = dir.join(format!("layer-{}-{tag}.toml", name.trim_end_matches(".toml")));
    std::fs::write(&path, out).expect("write scene");
    path
}

struct Case {
    label: String,
    scene: PathBuf,
    ranks: usize,
    args: Vec<String>,
    rounds: usize,
    /// Contact: the variants are [`CONTACT_VARIANTS`] (PETSc's KSP solves the contact steps;
    /// the sweep there is `-step_layer_around`).
    around: bool,
}

/// The variants of a contact case: `M`, and each `M_H` with the energy correction's kick
/// (the default), with its solves (`-massless_correction_kick false`, the solver before the
/// kick), and with the kick and the sweep around PETSc's preconditioner: (mass, what the row
/// shows in the sweep column, options).
const CONTACT_VARIANTS: [(&str, &str, &[&str]); 7] = [
    ("consistent", "-", &[]),
    ("modified0", "no; correction kicked", &[]),
    ("modified0", "no; correction solved", &["-massless_correction_kick", "false"]),
    ("modified0", "around the PC; kicked", &["-step_layer_around", "true"]),
    ("modified1", "no; correction kicked", &[]),
    ("modified1", "no; correction solved", &["-massless_correction_kick", "false"]),
    ("modified1", "around the PC; kicked", &["-step_layer_around", "true"]),
];

/// How a variant sweeps the layer: the default, the whole layer gathered on every rank
/// (`-step_layer_local false`: only in 3D, where each rank's own block is the default), or
/// not at all (`-step_layer false`).
#[derive(Clone, Copy, PartialEq)]
enum Sweep {
    Default,
    Gathered,
    Off,
}

/// The variants of a case: `M`, and each `M_H` with the sweep (both scopes in 3D) and
/// without.
const VARIANTS: [(&str, Sweep); 7] = [
    ("consistent", Sweep::Default),
    ("modified0", Sweep::Default),
    ("modified0", Sweep::Gathered),
    ("modified0", Sweep::Off),
    ("modified1", Sweep::Default),
    ("modified1", Sweep::Gathered),
    ("modified1", Sweep::Off),
];

fn per_step(x: &RunSummary) -> f64 {
    x.timings.stepping / x.steps.max(1) as f64
}

fn its(x: &RunSummary) -> f64 {
    x.ksp_iterations as f64 / x.steps.max(1) as f64
}

/// One row of the table (printed as it comes): `base` is `M`'s (ms/step, its/step).
fn row(
    md: &mut String,
    case: &Case,
    r: &RunSummary,
    mass: &str,
    sweep: &str,
    base: Option<(f64, f64)>,
) {
    let (rt, ri) = base.map_or((f64::NAN, f64::NAN), |(t0, i0)| {
        (per_step(r) / t0, if i0 > 0.0 { its(r) / i0 } else { f64::NAN })
    });
    *md += &format!(
        "| {} | {} | {} | {:.3} | {mass} | {sweep} | {} + {} | {:.2} | {:.2} | {rt:.2} | {ri:.2} |\n",
        case.label,
        case.ranks,
        r.n_dofs,
        r.cfl,
        r.ksp_type,
        r.pc_type,
        1e3 * per_step(r),
        its(r),
    );
    print!("{}", md.lines().last().map(|l| format!("{l}\n")).unwrap_or_default());
}

fn sweep_name(sweep: Sweep) -> &'static str {
    match sweep {
        Sweep::Default => "default",
        Sweep::Gathered => "whole layer",
        Sweep::Off => "off",
    }
}

/// Variant `k` of `case` is left out: the whole layer's scope outside 3D (the default there);
/// a variant of a mass kind whose default run had no sweep in use (a factorization): the
/// same run again.
fn skip(case: &Case, best: &[Option<RunSummary>], k: usize) -> bool {
    let (mass, sweep) = VARIANTS[k];
    if sweep == Sweep::Gathered && !case.label.contains("3D") {
        return true;
    }
    let default = VARIANTS.iter().position(|v| v.0 == mass && v.1 == Sweep::Default);
    sweep != Sweep::Default
        && default.is_some_and(|d| best[d].as_ref().is_some_and(|r| r.step_reuse.layer_rows == 0))
}

/// `part`: `Some("beam" | "block" | "contact")` runs only the cases whose label starts so
/// (`./run bench --only layer:block`), `None` all of them.
pub fn section(repo: &Path, dir: &Path, quick: bool, part: Option<&str>) -> String {
    let mut md = String::from(
        "\nThe mass-free layer against the standard mass (`./run bench --only layer`; fastest of the rounds, runs interleaved; ratio = ms/step over `M`'s in the same case):\n\n| case | ranks | DOFs | CFL | mass | layer sweep | solver | ms/step | KSP its/step | time ratio to M | its ratio to M |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let mut cases = vec![];
    let beam = scene(repo, "beam.toml", None, dir);
    let (beam_steps, beam_sizes): (&str, &[&str]) =
        if quick { ("50", &["0.0625"]) } else { ("1000", &["0.015625", "0.0078125"]) };
    for &h in beam_sizes {
        for ranks in [1, 2] {
            cases.push(Case {
                label: "beam 2D Q1".into(),
                scene: beam.clone(),
                ranks,
                args: s(&["--param", &format!("h={h}"), "--steps", beam_steps]),
                rounds: if quick {
                    1
                } else if h == "0.015625" {
                    3
                } else {
                    2
                },
                around: false,
            });
        }
    }
    // c_p = 16.41 for E = 200, nu = 0.3, rho = 1: CFL 1 and 30 at h = 0.0625.
    let block_h = if quick { "0.25" } else { "0.0625" };
    for (tau, rounds) in [(3.8e-3, 3), (0.114, 2)] {
        let tau = if quick { tau * 4.0 } else { tau };
        cases.push(Case {
            label: "block 3D Q1".into(),
            scene: scene(repo, "block_hex.toml", Some(tau), dir),
            ranks: 2,
            args: s(&[
                "--param",
                &format!("h={block_h}"),
                "--steps",
                if quick { "5" } else { "30" },
            ]),
            rounds: if quick { 1 } else { rounds },
            around: false,
        });
    }
    // Contact: the study's disc (hc = 0.05, tau = 1e-6, to t = 9e-4) and ball (hc = 0.08,
    // tau = 0.01, to t = 1.8).
    cases.push(Case {
        label: "disc 2D contact".into(),
        scene: scene(repo, "disc.toml", None, dir),
        ranks: 2,
        args: s(&[
            "--param",
            "hc=0.05",
            "--param",
            "rc=2.0",
            "--param",
            "h=0.5",
            "--steps",
            if quick { "100" } else { "900" },
        ]),
        rounds: if quick { 1 } else { 2 },
        around: true,
    });
    cases.push(Case {
        label: "ball 3D contact".into(),
        scene: scene(repo, "sphere_hex.toml", None, dir),
        ranks: 2,
        args: s(&[
            "--param",
            "hc=0.08",
            "--param",
            "h=0.4",
            "--steps",
            if quick { "20" } else { "180" },
        ]),
        rounds: if quick { 1 } else { 2 },
        around: true,
    });
    let chosen =
        |c: &Case| part.is_none_or(|p| c.label.starts_with(p) || (p == "contact" && c.around));
    cases.retain(chosen);
    for case in cases.iter().filter(|c| c.around) {
        let mut best: Vec<Option<RunSummary>> = vec![None; CONTACT_VARIANTS.len()];
        for round in 0..case.rounds {
            for (k, &(mass, what, extra)) in CONTACT_VARIANTS.iter().enumerate() {
                eprintln!("bench: layer {} {mass} {what} round {round}", case.label);
                let mut args = case.args.clone();
                args.extend(s(&["--mass", mass, "--"]));
                args.extend(s(extra));
                if let Some(r) = run(repo, case.ranks, &case.scene, &args, dir) {
                    if best[k].as_ref().is_none_or(|b| per_step(&r) < per_step(b)) {
                        best[k] = Some(r);
                    }
                }
            }
        }
        let base = best[0].as_ref().map(|b| (per_step(b), its(b)));
        for (k, &(mass, what, _)) in CONTACT_VARIANTS.iter().enumerate() {
            let Some(r) = &best[k] else {
                md += &format!(
                    "| {} | {} | | | {mass} | {what} | failed |\n",
                    case.label, case.ranks
                );
                continue;
            };
            row(&mut md, case, r, mass, what, base);
        }
    }
    for case in cases.iter().filter(|c| !c.around) {
        let mut best: Vec<Option<RunSummary>> = vec![None; VARIANTS.len()];
        for round in 0..case.rounds {
            for (k, &(mass, sweep)) in VARIANTS.iter().enumerate() {
                if skip(case, &best, k) {
                    continue;
                }
                eprintln!(
                    "bench: layer {} {} ranks {mass} sweep {} round {round}",
                    case.label,
                    case.ranks,
                    sweep_name(sweep)
                );
                let mut args = case.args.clone();
                args.extend(s(&["--mass", mass, "--"]));
                match sweep {
                    Sweep::Default => {}
                    Sweep::Gathered => args.extend(s(&["-step_layer_local", "false"])),
                    Sweep::Off => args.extend(s(&["-step_layer", "false"])),
                }
                if let Some(r) = run(repo, case.ranks, &case.scene, &args, dir) {
                    if best[k].as_ref().is_none_or(|b| per_step(&r) < per_step(b)) {
                        best[k] = Some(r);
                    }
                }
            }
        }
        let base = best[0].as_ref().map(|b| (per_step(b), its(b)));
        for (k, &(mass, sweep)) in VARIANTS.iter().enumerate() {
            if skip(case, &best, k) {
                continue;
            }
            let Some(r) = &best[k] else {
                md += &format!(
                    "| {} | {} | | | {mass} | {} | failed |\n",
                    case.label,
                    case.ranks,
                    sweep_name(sweep)
                );
                continue;
            };
            let scope = match (sweep, case.label.contains("3D")) {
                (Sweep::Gathered, _) | (_, false) => "whole layer",
                _ => "own blocks",
            };
            let sweep = if r.step_reuse.layer_rows > 0 {
                format!("yes ({} rows, {scope})", r.step_reuse.layer_rows)
            } else if mass == "consistent" {
                "-".into()
            } else {
                "no".into()
            };
            row(&mut md, case, r, mass, &sweep, base);
        }
    }
    md
}
