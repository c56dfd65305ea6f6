//! What finite strain costs (`./run bench --only finite_strain`): the same runs with
//! `--model linear` and `--model neo_hookean`, side by side in one launch of the benchmark:
//! Newton iterations per step, the time of a step against the linear one, the internal force
//! and its tangent per evaluation and as a rate (cells per second and rank), on
//! - the beam of section 7.1 (2D Q1) at about 2 10^4 and 10^6 DOFs, its tau scaled to CFL 1,
//!   and at 2 10^4 DOFs at CFL 30;
//! - the block (3D Q1 hexahedra) at CFL 1;
//! - the ball dropped on a plane (3D P1, the mass-free layer, contact) at about 10^5 DOFs;
//!
//! and what a contact step costs at finite strain ([`contact_section`], its own section
//! `finite_contact`).

use std::path::{Path, PathBuf};

use massfree::report::RunSummary;

use super::layer::{run, scene};

pub fn section(repo: &Path, dir: &Path, quick: bool) -> String {
    let mut md = String::from(
        "\nFinite strain against the linear step (the same run with `--model linear` and `--model neo_hookean`, interleaved; stepping time per step; f: the internal force alone, f + K: with its tangent, per evaluation; rate: cells x tangent evaluations / (ranks x their seconds)):\n\n| case | ranks | DOFs | steps | linear ms/step | finite ms/step | ratio | Newton its/step | KSP its/step (linear, finite) | f ms | f + K ms | f + K cells/s/rank |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    // c_p = 16.41 for E = 200, nu = 0.3, rho = 1: tau = h / c_p is CFL 1.
    let beams: &[(&str, usize)] =
        if quick { &[("0.125", 10)] } else { &[("0.03125", 20), ("0.004464285714285714", 5)] };
    let mut cases: Vec<(String, PathBuf, Vec<String>, Vec<usize>)> = Vec::new();
    for &(h, steps) in beams {
        let tau = h.parse::<f64>().unwrap() / 16.41;
        cases.push((
            format!("beam 2D Q1, h = {}", if h.len() > 8 { "1/224" } else { h }),
            scene(repo, "beam.toml", Some(tau), dir),
            s(&["--param", &format!("h={h}"), "--steps", &steps.to_string()]),
            vec![1, 2],
        ));
    }
    // Implicit dynamics at large steps: the small beam at CFL 30 (multigrid).
    let (h30, steps30) = if quick { ("0.125", 5) } else { ("0.03125", 10) };
    cases.push((
        format!("beam 2D Q1, h = {h30}, CFL 30"),
        scene(repo, "beam.toml", Some(30.0 * h30.parse::<f64>().unwrap() / 16.41), dir),
        s(&["--param", &format!("h={h30}"), "--steps", &steps30.to_string()]),
        vec![1, 2],
    ));
    let block_h = if quick { "0.25" } else { "0.0625" };
    let tau = block_h.parse::<f64>().unwrap() / 16.41;
    cases.push((
        format!("block 3D Q1, h = {block_h}"),
        scene(repo, "block_hex.toml", Some(tau), dir),
        s(&["--param", &format!("h={block_h}"), "--steps", if quick { "5" } else { "10" }]),
        vec![1, 2],
    ));
    let (bh, bhc, bsteps) = if quick { ("0.2", "0.04", "60") } else { ("0.045", "0.03", "60") };
    cases.push((
        format!("ball on a plane, M_H^0, h = {bh}, hc = {bhc} (steps 1-60: the impact)"),
        scene(repo, "sphere.toml", None, dir),
        s(&["--param", &format!("h={bh}"), "--param", &format!("hc={bhc}"), "--steps", bsteps]),
        vec![2],
    ));
    for (label, path, args, ranks) in cases {
        for r in ranks {
            eprintln!("bench: finite strain, {label}, {r} rank(s)");
            let with = |model: &str| {
                let mut a = args.clone();
                a.extend(["--model".to_string(), model.to_string()]);
                run(repo, r, &path, &a, dir)
            };
            // Interleaved: linear, finite, linear; the linear time is the faster of its two.
            let (l1, f, l2) = (with("linear"), with("neo_hookean"), with("linear"));
            let (Some(l1), Some(f), Some(l2)) = (l1, f, l2) else {
                md += &format!("| {label} | {r} | failed |\n");
                continue;
            };
            let per = |t: &RunSummary| 1e3 * t.timings.stepping / t.steps.max(1) as f64;
            let lin = per(&l1).min(per(&l2));
            let fin = per(&f);
            let nw = f.newton.expect("Newton statistics");
            md += &format!(
                "| {label} | {r} | {} | {} | {lin:.2} | {fin:.2} | {:.2} | {:.2} | {:.1}, {:.1} | {:.3} | {:.3} | {:.2e} |\n",
                f.n_dofs,
                f.steps,
                fin / lin,
                nw.iterations as f64 / nw.steps.max(1) as f64,
                l1.ksp_iterations as f64 / l1.steps.max(1) as f64,
                f.ksp_iterations as f64 / f.steps.max(1) as f64,
                1e3 * nw.force_seconds / nw.force_evaluations.max(1) as f64,
                1e3 * nw.tangent_seconds / nw.tangent_evaluations.max(1) as f64,
                f.n_cells as f64 * nw.tangent_evaluations as f64
                    / (r as f64 * nw.tangent_seconds.max(1e-12)),
            );
        }
    }
    md
}

/// Contact steps at finite strain (`./run bench --only finite_contact`): per
/// time step with a node in contact at its end, the Newton iterations (every solve of the step,
/// the energy correction's too), the active-set iterations per contact solve, the interface's
/// rounds and solves (pairs following the bodies), and the wall time against a plain Newton
/// step of the same run (the steps without contact). Aims: a contact step at most 2 plain
/// steps, at most 5 Newton iterations per contact step on average.
pub fn contact_section(repo: &Path, dir: &Path, quick: bool) -> String {
    let mut md = String::from(
        "\nContact steps at finite strain (neo-Hooke, M_H; one run each; a contact step: a time step ending with a node in contact; Newton its: every solve of the step, the energy correction's included; plain: the same run's steps without contact):\n\n| case | ranks | DOFs | steps | contact steps | Newton its / contact step | Newton its / plain step | active-set its (a contact step's last solve) | interface rounds (solves) / contact step | contact step ms | plain step ms | contact / plain | cycles taken |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let mut cases: Vec<(String, PathBuf, Vec<String>, usize)> = vec![
        (
            "ball on a plane, M_H^0, h = 0.2, hc = 0.04".into(),
            scene(repo, "sphere.toml", None, dir),
            s(&["--model", "neo_hookean", "--param", "h=0.2", "--param", "hc=0.04"]),
            2,
        ),
        (
            "ironing at depth, M_H^1, mu = 0.3, h = 1/32".into(),
            scene(repo, "ironing_deep.toml", None, dir),
            s(&["--param", "h=0.03125"]),
            2,
        ),
        (
            "block sliding off a block (2D pair), M_H^1".into(),
            scene(repo, "slide_off_neo_hooke.toml", None, dir),
            s(&[]),
            2,
        ),
        (
            "two balls oblique (3D pair), M_H^0, h = 0.4, hc = 0.1".into(),
            scene(repo, "two_spheres_oblique_neo_hooke.toml", None, dir),
            s(&["--param", "h=0.4", "--param", "hc=0.1"]),
            2,
        ),
    ];
    if !quick {
        cases.push((
            "block sliding off a block (3D pair), M_H^1".into(),
            scene(repo, "slide_off_3d_neo_hooke.toml", None, dir),
            s(&[]),
            2,
        ));
        cases.push((
            "two balls oblique (3D pair), M_H^0, h = 0.2, hc = 0.04".into(),
            scene(repo, "two_spheres_oblique_neo_hooke.toml", None, dir),
            s(&[]),
            2,
        ));
    }
    for (label, path, mut args, r) in cases {
        eprintln!("bench: finite strain contact, {label}, {r} rank(s)");
        if quick {
            args.extend(s(&["--steps", "40"]));
        }
        let Some(f) = run(repo, r, &path, &args, dir) else {
            md += &format!("| {label} | {r} | failed |\n");
            continue;
        };
        let nw = f.newton.expect("Newton statistics");
        let per = |x: f64, n: usize| if n > 0 { x / n as f64 } else { f64::NAN };
        let (cms, pms) = (
            1e3 * per(nw.contact_seconds, nw.contact_steps),
            1e3 * per(nw.plain_seconds, nw.plain_steps),
        );
        let contact = f.contact.as_ref();
        let active_set = contact.map_or(f64::NAN, |c| c.active_set_iterations_mean);
        let interface = contact.and_then(|c| c.mortar).filter(|m| m.following_steps > 0).map_or(
            "-".to_string(),
            |m| {
                format!(
                    "{:.2} ({:.2})",
                    per(m.rounds as f64, m.following_steps),
                    per(m.following_solves as f64, m.following_steps)
                )
            },
        );
        // "-" where a run has no steps of a kind (the ironing is in contact throughout).
        let f2 = |x: f64| if x.is_finite() { format!("{x:.2}") } else { "-".to_string() };
        md += &format!(
            "| {label} | {r} | {} | {} | {} | {} | {} | {} | {interface} | {} | {} | {} | {} |\n",
            f.n_dofs,
            f.steps,
            nw.contact_steps,
            f2(per(nw.contact_iterations as f64, nw.contact_steps)),
            f2(per(nw.plain_iterations as f64, nw.plain_steps)),
            f2(active_set),
            f2(cms),
            f2(pms),
            f2(cms / pms),
            nw.cycled,
        );
    }
    md
}
