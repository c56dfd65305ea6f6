//! The reduced hard-case suite (`massfree suite studies/suite.toml --reduced`, issue 14)
//! through the binary, each case a real run on 2 ranks (the marked ones also on 1), and what
//! theory guarantees for the current algorithm, checked on every run's HDF5 file with this
//! file's own code (not the suite's), then against the suite's table:
//!
//! - no NaN/inf in the energies, the contact series and the written fields;
//! - the energy never rises above the initial energy plus the work of the loads and of the
//!   Dirichlet reactions, `E^n - E^0 - W^n <= 1e-6 E_ref` at every step (the contact work of
//!   fixed obstacles is `-lambda g^n <= 0` per step, and the energy correction of the
//!   massless DOFs puts back at most what was lost: loss is allowed, rise is not);
//! - no penetration beyond 1e-8 of the body size at any step (`-min gap`);
//! - 1 and 2 ranks agree to 1e-8 (energies relative to the energy scale, contact forces to
//!   the largest force, active sets exactly); a run whose step solver is GAMG (CFL above 30
//!   with contact) is rank-dependent at the solver's tolerance, so it is compared again with
//!   `-step_ksp_rtol 1e-12`;
//! - with M_H^1, the impact cases from rest-length starts (`single_episode` in the suite
//!   file) have one contact episode per node and impact;
//! - the metrics the run stored in its summary (in-memory series) equal the suite's (from the
//!   file).
//!
//! Reported by the suite and not asserted here: the energy loss of the masses with inertia at
//! the contact nodes (M, lumped) in repeated impacts, and the flicker of rattling contacts.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use common::{massfree, reader, repo, scratch, RunSummary};

/// One CSV line into fields (fields with a comma or quote are quoted, quotes doubled).
fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cur.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut cur)),
            _ => cur.push(c),
        }
    }
    out.push(cur);
    out
}

fn read_csv(path: &Path) -> Vec<HashMap<String, String>> {
    let t = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = t.lines();
    let head = split_csv(lines.next().unwrap());
    lines
        .map(|l| {
            let f = split_csv(l);
            assert_eq!(f.len(), head.len(), "{l}");
            head.iter().cloned().zip(f).collect()
        })
        .collect()
}

fn num(row: &HashMap<String, String>, key: &str) -> f64 {
    row[key].parse().unwrap_or_else(|_| panic!("{key} = {:?} in {row:?}", row[key]))
}

/// Per step: the energy and the work of the loads and the Dirichlet reactions.
fn energy_and_work(h5: &Path) -> (Vec<f64>, Vec<f64>) {
    let r = reader(h5);
    let s = |n: &str| r.series(&format!("/energy/{n}")).unwrap();
    let (e, ext, dir) = (s("total"), s("external_work"), s("dirichlet_work"));
    let w = ext.iter().zip(&dir).map(|(a, b)| a + b).collect();
    (e, w)
}

/// `max_n (E^n - E^0 - (W^n - W^0)) / E_ref`, `E_ref = max_n max(|E^n|, |E^0 + W^n - W^0|)`.
fn energy_rise(e: &[f64], w: &[f64]) -> f64 {
    let e_ref =
        (0..e.len()).map(|n| e[n].abs().max((e[0] + w[n] - w[0]).abs())).fold(0.0, f64::max);
    (0..e.len()).map(|n| (e[n] - e[0] - (w[n] - w[0])) / e_ref).fold(f64::NEG_INFINITY, f64::max)
}

/// (nodes, rows of [steps + 1][nodes]: force, gap, active) of a contact run.
struct Contact {
    nodes: usize,
    force: Vec<f64>,
    gap: Vec<f64>,
    active: Vec<bool>,
}

/// The contact series of a run whose scene has contact (a missing dataset is a failure).
fn contact(h5: &Path) -> Contact {
    let r = reader(h5);
    let series = |name: &str| {
        r.series(name)
            .unwrap_or_else(|e| panic!("{}: a contact run lacks {name}: {e}", h5.display()))
    };
    let nodes = series("/contact/nodes").len();
    Contact {
        nodes,
        force: series("/contact/force"),
        gap: series("/contact/gap"),
        active: series("/contact/active").iter().map(|&a| a != 0.0).collect(),
    }
}

/// The scene a run of the suite ran (`runs/ID.scene.toml` beside `runs/ID.h5`).
fn scene_of(h5: &Path) -> toml::Table {
    let path = h5.with_extension("scene.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    toml::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// What the suite file marks for each case under `--reduced`: the number of runs (masses x
/// sweep points), the rank sweep, the single-episode theory, the compared steps.
#[derive(Debug)]
struct Marks {
    runs: usize,
    rank_sweep: bool,
    single_episode: bool,
    rank_steps: Option<usize>,
    /// The case's own rank tolerance, if it sets one (the suite file says why).
    rank_tol: Option<f64>,
}

/// The marks of every case of the suite file that the reduced suite runs (schema:
/// src/suite/spec.rs; `[case.reduced]` replaces mass and sweep, `skip` leaves a case out).
fn reduced_marks(spec: &toml::Value) -> HashMap<String, Marks> {
    let mut out = HashMap::new();
    for c in spec["case"].as_array().expect("[[case]]") {
        let red = c.get("reduced");
        if red.and_then(|r| r.get("skip")).and_then(|v| v.as_bool()) == Some(true) {
            continue;
        }
        let pick = |key: &str| red.and_then(|r| r.get(key)).or_else(|| c.get(key));
        let masses = pick("mass").map_or(1, |m| m.as_array().unwrap().len());
        let points = pick("sweep").map_or(1, |t| {
            t.as_table().unwrap().values().next().map_or(1, |v| v.as_array().unwrap().len())
        });
        let flag = |key: &str| c.get(key).and_then(|v| v.as_bool()).unwrap_or(false);
        out.insert(
            c["name"].as_str().unwrap().to_string(),
            Marks {
                runs: masses * points,
                rank_sweep: flag("rank_sweep"),
                single_episode: flag("single_episode"),
                rank_steps: c.get("rank_steps").and_then(|v| v.as_integer()).map(|k| k as usize),
                rank_tol: c.get("rank_tol").and_then(|v| v.as_float()),
            },
        );
    }
    out
}

fn body_size(h5: &Path) -> f64 {
    let x = reader(h5).coordinates().unwrap();
    (0..3)
        .map(|i| {
            let lo = x.iter().map(|p| p[i]).fold(f64::INFINITY, f64::min);
            let hi = x.iter().map(|p| p[i]).fold(f64::NEG_INFINITY, f64::max);
            hi - lo
        })
        .fold(0.0, f64::max)
}

/// Non-finite values in every energy series, the final checkpoint, the displacement and
/// velocity fields unless the scene's `output.fields` leaves them out, and with contact the forces, pressures and the
/// gaps after the start (row 0 is NaN by design). Every one of these datasets the run must have
/// written is required: a missing one is a failure, not a dataset without NaN.
fn non_finite(h5: &Path, scene: &toml::Table) -> usize {
    let r = reader(h5);
    let mut n = 0;
    let mut count = |name: &str, skip: usize| {
        let v = r.series(name).unwrap_or_else(|e| panic!("{}: no {name}: {e}", h5.display()));
        n += v.iter().skip(skip).filter(|x| !x.is_finite()).count();
    };
    for s in ["total", "kinetic", "potential", "external_work", "contact_work", "dirichlet_work"] {
        count(&format!("/energy/{s}"), 0);
    }
    count("/checkpoint/u", 0);
    count("/checkpoint/v", 0);
    // Without `output.fields` a run writes displacement and velocity.
    let fields = scene.get("output").and_then(|o| o.get("fields")).and_then(|f| f.as_array());
    for f in ["displacement", "velocity"] {
        if fields.is_none_or(|fs| fs.iter().any(|x| x.as_str() == Some(f))) {
            count(&format!("/fields/{f}"), 0);
        }
    }
    if scene.contains_key("contact") {
        count("/contact/force", 0);
        count("/contact/pressure", 0);
        let nc = r.series("/contact/nodes").unwrap_or_else(|e| panic!("{e}")).len();
        count("/contact/gap", nc);
    }
    n
}

/// Runs of consecutive steps with an active node (the body's impacts), inclusive.
fn impacts(c: &Contact) -> Vec<(usize, usize)> {
    let rows = c.active.len() / c.nodes;
    let any: Vec<bool> =
        (0..rows).map(|n| c.active[n * c.nodes..(n + 1) * c.nodes].iter().any(|&a| a)).collect();
    let mut out = Vec::new();
    let mut start = None;
    for (n, &a) in any.iter().chain(std::iter::once(&false)).enumerate() {
        match (a, start) {
            (true, None) => start = Some(n),
            (false, Some(s)) => {
                out.push((s, n - 1));
                start = None;
            }
            _ => {}
        }
    }
    out
}

/// The largest number of times one node enters contact within one impact.
fn episodes_per_impact(c: &Contact) -> usize {
    let mut worst = 0;
    for (a, b) in impacts(c) {
        for k in 0..c.nodes {
            let mut e = 0;
            let mut prev = false;
            for n in a..=b {
                let on = c.active[n * c.nodes + k];
                if on && !prev {
                    e += 1;
                }
                prev = on;
            }
            worst = worst.max(e);
        }
    }
    worst
}

/// The largest difference of two runs of one scene: energies relative to the energy scale,
/// contact forces relative to the largest force, active flags (a mismatch counts 1); over the
/// first `steps` steps when given (a case's `rank_steps`).
fn rank_difference(a: &Path, b: &Path, steps: Option<usize>) -> f64 {
    let (ra, rb) = (reader(a), reader(b));
    let rows = ra.series("/energy/total").unwrap().len();
    let largest = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let diff = |x: &[f64], y: &[f64]| {
        assert_eq!(x.len(), y.len(), "{} against {}", a.display(), b.display());
        let keep = steps.map_or(x.len(), |k| (k + 1).min(rows) * (x.len() / rows));
        x[..keep].iter().zip(&y[..keep]).fold(0.0f64, |m, (p, q)| m.max((p - q).abs()))
    };
    let mut scale = 0.0f64;
    let mut d_energy = 0.0f64;
    for s in ["total", "kinetic", "potential", "external_work", "contact_work", "dirichlet_work"] {
        let name = format!("/energy/{s}");
        let (x, y) = (ra.series(&name).unwrap(), rb.series(&name).unwrap());
        scale = scale.max(largest(&x));
        d_energy = d_energy.max(diff(&x, &y));
    }
    let mut worst = d_energy / scale;
    if ra.file.dataset("/contact/force").is_ok() {
        let (x, y) = (ra.series("/contact/force").unwrap(), rb.series("/contact/force").unwrap());
        worst = worst.max(diff(&x, &y) / largest(&x).max(f64::MIN_POSITIVE));
        let (x, y) = (ra.series("/contact/active").unwrap(), rb.series("/contact/active").unwrap());
        worst = worst.max(diff(&x, &y));
    }
    worst
}

fn summary_of(h5: &Path) -> RunSummary {
    let path = h5.with_extension("summary.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    toml::from_str(&text).unwrap()
}

/// Runs the scene of `h5`'s run again on `ranks` ranks with `-step_ksp_rtol 1e-12`.
fn rerun_tight(scene: &Path, ranks: usize, out: &Path) {
    let o = massfree(
        ranks,
        &[
            "run",
            scene.to_str().unwrap(),
            "-q",
            "--overwrite",
            "-o",
            out.to_str().unwrap(),
            "--",
            "-step_ksp_rtol",
            "1e-12",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn reduced_suite_is_stable_by_theory() {
    let dir = scratch("suite");
    let out = dir.join("out");
    let spec = repo().join("studies/suite.toml");
    let o = massfree(
        0,
        &["suite", spec.to_str().unwrap(), "--reduced", "--dir", out.to_str().unwrap()],
    );
    let log = format!(
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "the suite failed (a run failed or hit NaN/inf):\n{log}");
    for f in ["suite.md", "suite.csv", "suite.png"] {
        let p = out.join(f);
        assert!(p.is_file() && std::fs::metadata(&p).unwrap().len() > 500, "{}", p.display());
    }
    let rows = read_csv(&out.join("suite.csv"));
    let md = std::fs::read_to_string(out.join("suite.md")).unwrap();
    let mut cases: Vec<&str> = rows.iter().map(|r| r["case"].as_str()).collect();
    cases.dedup();
    for c in &cases {
        assert!(md.contains(&format!("| {c} |")), "suite.md lacks case {c}");
    }
    // What the suite file marks: every row of a marked case is checked, and every run the
    // reduced suite must make is in the table (a missing row or file is a failure).
    let spec_text: toml::Value =
        toml::from_str(&std::fs::read_to_string(&spec).unwrap()).expect("the suite file");
    let marks = reduced_marks(&spec_text);
    let mut per_case: HashMap<&str, usize> = HashMap::new();
    for r in &rows {
        *per_case.entry(r["case"].as_str()).or_default() += 1;
    }
    for (name, m) in &marks {
        assert_eq!(per_case.get(name.as_str()).copied().unwrap_or(0), m.runs, "rows of {name}");
    }
    assert_eq!(per_case.len(), marks.len(), "cases in the table: {per_case:?}");
    let (mut single, mut swept) = (0, 0);
    let mut report = Vec::new();
    for r in &rows {
        let what = format!("{} {} {}", r["case"], r["variant"], r["mass"]);
        let m = &marks[r["case"].as_str()];
        assert_ne!(r["status"], "error", "{what}: {}", r["failed_checks"]);
        assert_eq!(r["single_episode"], m.single_episode.to_string(), "{what}: single_episode");
        let h5: PathBuf = out.join(&r["file"]);
        let scene = scene_of(&h5);
        // No NaN/inf anywhere.
        assert_eq!(non_finite(&h5, &scene), 0, "{what}: non-finite values in {}", h5.display());
        assert_eq!(num(r, "non_finite"), 0.0, "{what}");
        // The energy never rises above the initial energy plus the work done.
        let (e, w) = energy_and_work(&h5);
        let rise = energy_rise(&e, &w);
        assert!(rise <= 1e-6, "{what}: the energy rises {rise:e} of E_ref above E^0 + W");
        assert!(
            (rise.max(0.0) - num(r, "energy_rise")).abs() <= 1e-12,
            "{what}: rise {rise:e}, the suite says {}",
            r["energy_rise"]
        );
        // No penetration beyond tolerance at any step, and no pulling contact force, in every
        // run whose scene has contact.
        let size = body_size(&h5);
        let c = scene.contains_key("contact").then(|| contact(&h5));
        if let Some(c) = &c {
            let min_gap = c.gap[c.nodes..]
                .iter()
                .filter(|g| **g < 1e300)
                .fold(f64::INFINITY, |m, &g| m.min(g));
            let pen = (-min_gap).max(0.0);
            assert!(pen <= 1e-8 * size, "{what}: penetration {pen:e} (body size {size})");
            assert!(
                (pen - num(r, "penetration")).abs() <= 1e-15 * size,
                "{what}: penetration {pen:e}, the suite says {}",
                r["penetration"]
            );
            assert!(
                c.force
                    .iter()
                    .all(|&f| f >= -1e-12 * c.force.iter().fold(0.0f64, |m, x| m.max(x.abs()))),
                "{what}: a contact force pulls"
            );
        }
        // The metrics the run stored in its summary (HDF5 attribute and --summary file)
        // equal those the suite computed from the file.
        let sum = summary_of(&h5);
        let stored = sum.stability.as_ref().expect("the run stores its stability metrics");
        let in_file = massfree::report::RunSummary::read(&reader(&h5)).unwrap().stability.unwrap();
        assert_eq!(stored, &in_file, "{what}: the summary file and the HDF5 summary differ");
        for (key, x) in [
            ("energy_rise", stored.energy_rise),
            ("energy_loss", stored.energy_loss),
            ("penetration", stored.penetration),
            ("force_osc2", stored.force_osc2),
            ("episodes_per_impact_max", stored.episodes_per_impact_max as f64),
            ("impacts", stored.impacts as f64),
            ("ksp_max", stored.ksp_iterations_max as f64),
        ] {
            let y = num(r, key);
            assert!(
                (x - y).abs() <= 1e-9 * x.abs().max(y.abs()) + 1e-15,
                "{what}: {key} in the run's summary {x:e}, from the file {y:e}"
            );
        }
        // M_H^1 impacts from rest-length starts: one contact episode per node and impact.
        if m.single_episode && r["mass"] == "modified1" {
            let c = c.as_ref().unwrap_or_else(|| panic!("{what}: an impact case without contact"));
            assert!(!impacts(c).is_empty(), "{what}: no contact");
            assert_eq!(episodes_per_impact(c), 1, "{what}: a node flickers");
            assert_eq!(num(r, "episodes_per_impact_max"), 1.0, "{what}");
            single += 1;
        }
        // Rank independence: the 1-rank run of every run of a case so marked (and of no other).
        let one = h5.with_file_name(format!("{}-n1.h5", h5.file_stem().unwrap().to_string_lossy()));
        if !m.rank_sweep {
            assert!(!one.exists() && r["rank_diff"].is_empty(), "{what}: swept, not marked");
            continue;
        }
        assert!(
            one.is_file(),
            "{what}: marked for the rank sweep, but {} is missing",
            one.display()
        );
        swept += 1;
        let d = rank_difference(&h5, &one, m.rank_steps);
        assert!(
            (d - num(r, "rank_diff")).abs() <= 1e-9 * d.max(1e-300) || d == num(r, "rank_diff"),
            "{what}: rank difference {d:e}, the suite says {}",
            r["rank_diff"]
        );
        if sum.pc_type == "gamg" {
            // GAMG's aggregates follow the partition: rank counts agree to the solver's
            // tolerance only. Solved to 1e-12 they must agree to 1e-8.
            let scene = h5.with_extension("scene.toml");
            let (t1, t2) = (
                dir.join(format!("{}-tight1.h5", r["case"].replace('/', "_"))),
                dir.join(format!("{}-tight2.h5", r["case"].replace('/', "_"))),
            );
            rerun_tight(&scene, 1, &t1);
            rerun_tight(&scene, 2, &t2);
            let tight = rank_difference(&t2, &t1, None);
            report.push(format!(
                "{what}: GAMG, 1 vs 2 ranks {d:.1e} at the default rtol, {tight:.1e} at 1e-12"
            ));
            assert!(tight <= 1e-8, "{what}: 1 and 2 ranks differ by {tight:e} at rtol 1e-12");
        } else {
            let tol = m.rank_tol.unwrap_or(1e-8);
            assert!(d <= tol, "{what}: 1 and 2 ranks differ by {d:e} (tolerance {tol:e})");
        }
    }
    // Every marked run was checked (the counts the suite file gives).
    let marked = |f: &dyn Fn(&Marks) -> bool| {
        rows.iter().filter(|r| f(&marks[r["case"].as_str()])).collect::<Vec<_>>()
    };
    let want_single =
        marked(&|m| m.single_episode).iter().filter(|r| r["mass"] == "modified1").count();
    assert_eq!(single, want_single, "single-episode runs checked");
    assert_eq!(swept, marked(&|m| m.rank_sweep).len(), "runs compared across rank counts");
    eprintln!("{single} single-episode runs and {swept} rank sweeps checked");
    eprintln!("{}", report.join("\n"));
}

#[test]
fn bad_suite_files_are_one_line_errors() {
    let dir = scratch("suite-bad");
    let cases = [
        ("bogus = 1\n", "bogus"),
        ("[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"nope.toml\"\n", "case[0] (a): scene"),
        (
            "[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"SCENE\"\nsweep = { x = [1, 2], y = [1] }\n",
            "zipped",
        ),
        (
            "[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"SCENE\"\nmass = [\"heavy\"]\n",
            "mass: \"heavy\" is unknown",
        ),
    ];
    let scene = repo().join("scenes/suite/block_impact.toml");
    for (i, (text, want)) in cases.iter().enumerate() {
        let file = dir.join(format!("bad{i}.toml"));
        std::fs::write(&file, text.replace("SCENE", scene.to_str().unwrap())).unwrap();
        let o = massfree(0, &["suite", file.to_str().unwrap(), "--dir", dir.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
        assert_eq!(lines.len(), 1, "{err}");
        assert!(lines[0].contains(want), "{err}");
    }
}
