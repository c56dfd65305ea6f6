//! The command line explains itself: every subcommand's help has examples; `run SCENE -- -help`
//! lists the program's own options with their defaults beside PETSc's; an option nothing used
//! is one warning line; booleans read as PETSc reads them; post and compare write under
//! `--prefix`, the suite under `--dir`.

mod common;
use common::*;

use std::path::Path;
use std::process::Output;

/// The limit of one launch here: the runs are a few steps of small scenes (seconds).
const LIMIT_S: f64 = 120.0;

/// `massfree args` (ranks 0 or 1: the binary alone) or `mpirun -q -n ranks massfree args`.
fn launch(ranks: usize, args: &[&str]) -> Output {
    let args: Vec<String> = args.iter().map(|a| a.to_string()).collect();
    output_within(&mut massfree_command(ranks.max(1), &args), LIMIT_S)
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// The lines of stderr that are not empty.
fn lines(o: &Output) -> Vec<String> {
    text(&o.stderr).lines().filter(|l| !l.trim().is_empty()).map(str::to_string).collect()
}

fn warnings(o: &Output) -> Vec<String> {
    lines(o).into_iter().filter(|l| l.contains("warning")).collect()
}

fn scene(name: &str) -> String {
    repo().join("scenes").join(name).display().to_string()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn every_subcommand_help_has_examples() {
    for sub in [None, Some("run"), Some("post"), Some("compare"), Some("study"), Some("suite")] {
        let mut args: Vec<&str> = sub.into_iter().collect();
        args.push("--help");
        let o = launch(0, &args);
        let out = text(&o.stdout);
        assert!(o.status.success(), "{args:?}: {}", text(&o.stderr));
        let examples = out.split_once("Examples:").map(|(_, e)| e).unwrap_or_else(|| {
            panic!("massfree {args:?} has no examples:\n{out}");
        });
        // Real command lines of this subcommand (the top level: of several).
        let commands: Vec<&str> = examples
            .lines()
            .map(str::trim)
            .filter(|l| l.starts_with("massfree ") || l.starts_with("mpirun "))
            .collect();
        assert!((2..=4).contains(&commands.len()), "{args:?}: {commands:?}");
        if let Some(sub) = sub {
            let call = format!("massfree {sub} ");
            assert!(commands.iter().all(|c| c.contains(&call)), "{args:?}: {commands:?}");
        }
    }
}

/// The program's own options after `--`, each with the default `-help` shows (as PETSc prints
/// it) and the code's value it stands for.
const APP_OPTIONS: [(&str, &str); 27] = [
    ("-contact_solver", "pdas"),
    ("-contact_loose_rtol", "sqrt(step solver rtol)"),
    ("-contact_reference_solve", "false"),
    ("-mortar_update_in_contact", "false"),
    ("-mortar_interface", "follow"),
    ("-mortar_update_distance", "0.1 x smallest slave facet"),
    ("-mortar_normal", "slave"),
    ("-mortar_jacobian", "differences"),
    ("-mortar_gap_rows", "false"),
    ("-mortar_geometry_tol", "1e-9 x slave surface extent"),
    ("-massless_energy_correction", "true"),
    ("-massless_correction_blend", "true"),
    ("-massless_correction_kick", "true"),
    ("-massless_drift_rtol", "1e-07"),
    ("-step_reuse", "true"),
    ("-step_reuse_refresh", "16"),
    ("-step_predictor", "extrapolate"),
    ("-step_energy_rtol", "1e-13"),
    ("-step_layer", "true"),
    ("-step_layer_local", "true in 3D, false in 2D"),
    ("-step_layer_around", "false"),
    ("-step_choice", "run"),
    ("-newton_rtol", "1e-10"),
    ("-newton_energy_rtol", "1e-14"),
    ("-newton_max_it", "25"),
    ("-newton_monitor", "false"),
    ("-newton_tangent_reuse", "0."),
];

#[test]
fn help_lists_every_application_option_with_its_default() {
    // The defaults shown are the code's.
    let newton = massfree::time::newton::NewtonOptions::default();
    assert_eq!(
        (newton.rtol, newton.energy_rtol, newton.max_it, newton.monitor, newton.tangent_reuse),
        (1e-10, 1e-14, 25, false, 0.0)
    );
    let reuse = massfree::time::Reuse::default();
    assert_eq!((reuse.refresh, reuse.energy_rtol, reuse.layer), (16, 1e-13, true));
    assert_eq!(reuse.predictor, massfree::time::Predictor::Extrapolate);
    assert_eq!(massfree::time::Midpoint::DRIFT_RTOL, 1e-7);
    let o = launch(0, &["run", &scene("disc.toml"), "--steps", "1", "--no-output", "--", "-help"]);
    let out = text(&o.stdout);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(out.contains("-ksp_type"), "PETSc's own options are listed too:\n{out}");
    for (name, default) in APP_OPTIONS {
        let line = out
            .lines()
            .find(|l| {
                let l = l.trim_start();
                l.strip_prefix(name).is_some_and(|r| r.starts_with(' ') || r.starts_with(':'))
            })
            .unwrap_or_else(|| panic!("{name} is not listed by -help"));
        // PETSc prints `-name <now D : formerly D>`, `-name: <D : D>` or `-name <D : D>`.
        let (shown, default) = (line.to_lowercase(), default.to_lowercase());
        assert!(
            shown.contains(&format!("<{default} :"))
                || shown.contains(&format!("<now {default} :")),
            "{name}: default {default} not shown in {line:?}"
        );
        // A description, not only the name and the value.
        let description = line.rsplit_once('>').map(|(_, d)| d.trim()).unwrap_or("");
        assert!(description.len() > 20, "{name}: no description in {line:?}");
    }
    // Nothing listed that the summary would call unused.
    assert!(warnings(&o).is_empty(), "{:?}", warnings(&o));
    // The user guide's table has a row for each, and no row for an option -help does not list.
    let guide = std::fs::read_to_string(repo().join("docs/user-guide.md")).unwrap();
    let section = guide.split("### Application options").nth(1).expect("user guide: no options");
    let rows: Vec<&str> = section
        .lines()
        .take_while(|l| !l.starts_with('#'))
        .filter_map(|l| l.strip_prefix("| `-"))
        .filter_map(|l| l.split([' ', '`']).next())
        .collect();
    for (name, _) in APP_OPTIONS {
        assert!(rows.contains(&&name[1..]), "docs/user-guide.md has no row for {name}");
    }
    for row in rows {
        assert!(
            APP_OPTIONS.iter().any(|(n, _)| n[1..] == *row),
            "docs/user-guide.md documents -{row}, which -help does not list"
        );
    }
}

#[test]
fn an_option_nothing_used_is_one_warning_and_the_run_succeeds() {
    let disc = scene("disc.toml");
    let run = |extra: &[&str]| {
        let mut args = vec!["run", &disc, "--steps", "2", "--no-output", "-q", "--"];
        args.extend_from_slice(extra);
        let o = launch(2, &args);
        assert!(o.status.success(), "{extra:?}: {}", text(&o.stderr));
        o
    };
    let o = run(&["-step_reus", "true"]);
    assert_eq!(
        warnings(&o),
        ["massfree: warning: option -step_reus was given but never used"],
        "{}",
        text(&o.stderr)
    );
    // PETSc's own listing (-options_left) is not printed besides.
    assert!(!text(&o.stdout).contains("unused"), "{}", text(&o.stdout));
    // Spelt right, the program's and PETSc's options are used: no warning; PETSc's options
    // read at the end (-options_view, -memory_view) neither.
    let o = run(&[
        "-step_reuse",
        "true",
        "-newton_rtol",
        "1e-9",
        "-mortar_gap_rows",
        "-ksp_rtol",
        "1e-10",
        "-memory_view",
        "-options_view",
    ]);
    assert!(lines(&o).is_empty(), "{}", text(&o.stderr));
    // -options_left false: no warning.
    let o = run(&["-step_reus", "true", "-options_left", "false"]);
    assert!(lines(&o).is_empty(), "{}", text(&o.stderr));
}

#[test]
fn a_scenes_solver_options_are_used_and_a_misspelt_one_is_named() {
    let dir = scratch("cli-scene-options");
    let with = |name: &str, options: &str| {
        let path = scene_variant(
            "disc.toml",
            &dir,
            &[("[output]", &format!("[solver]\noptions = \"{options}\"\n\n[output]"))],
        );
        let named = dir.join(name);
        std::fs::rename(&path, &named).unwrap();
        named
    };
    let good =
        with("good.toml", "-step_predictor last -step_reuse false -ksp_norm_type unpreconditioned");
    let o = launch(2, &["run", path(&good), "--steps", "2", "--no-output", "-q"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(lines(&o).is_empty(), "{}", text(&o.stderr));
    let bad = with("bad.toml", "-step_predictor last -step_reus false");
    let o = launch(2, &["run", path(&bad), "--steps", "2", "--no-output", "-q"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_eq!(warnings(&o), ["massfree: warning: option -step_reus was given but never used"]);
    // The same misspelt name on the command line too: still unused.
    let o = launch(
        2,
        &["run", path(&bad), "--steps", "2", "--no-output", "-q", "--", "-step_reus", "1"],
    );
    assert_eq!(warnings(&o).len(), 1, "{}", text(&o.stderr));
}

#[test]
fn booleans_read_as_petsc_reads_them() {
    // The finite-strain L-block: its Newton loop prints each iteration with -newton_monitor.
    let l_block = scene("l_block.toml");
    let monitored = |extra: &[&str]| {
        let mut args = vec!["run", &l_block, "--steps", "1", "--no-output", "-q", "--"];
        args.extend_from_slice(extra);
        let o = launch(0, &args);
        assert!(o.status.success(), "{extra:?}: {}", text(&o.stderr));
        assert!(warnings(&o).is_empty(), "{extra:?}: {}", text(&o.stderr));
        text(&o.stdout).contains("Newton 0: residual")
    };
    assert!(!monitored(&[]), "not monitored by default");
    assert!(monitored(&["-newton_monitor"]), "a bare flag is true");
    assert!(monitored(&["-newton_monitor", "-ksp_rtol", "1e-10"]), "a bare flag before another");
    for v in ["true", "1", "yes", "on", "TRUE"] {
        assert!(monitored(&["-newton_monitor", v]), "-newton_monitor {v}");
    }
    for v in ["false", "0", "no", "off"] {
        assert!(!monitored(&["-newton_monitor", v]), "-newton_monitor {v}");
    }
}

#[test]
fn a_bad_option_value_is_a_one_line_error_naming_the_option() {
    let disc = scene("disc.toml");
    for (option, value) in [
        ("-newton_monitor", "maybe"),
        ("-step_layer_local", "2"),
        ("-mortar_gap_rows", "sure"),
        ("-step_reuse", "nope"),
        ("-newton_rtol", "small"),
        ("-newton_max_it", "2.5"),
        ("-step_predictor", "quadratic"),
    ] {
        let o = launch(0, &["run", &disc, "--steps", "1", "--no-output", "--", option, value]);
        assert!(!o.status.success(), "{option} {value} was accepted");
        let l = lines(&o);
        assert_eq!(l.len(), 1, "{option} {value}: {}", text(&o.stderr));
        assert!(l[0].contains(&format!("{option} {value}:")), "{option} {value}: {l:?}");
        assert!(!l[0].contains("panicked"), "{l:?}");
    }
    // A number option without its number.
    let o = launch(0, &["run", &disc, "--steps", "1", "--no-output", "--", "-newton_rtol"]);
    assert!(!o.status.success(), "-newton_rtol without a value was accepted");
    assert_eq!(lines(&o), ["massfree: usage error: -newton_rtol needs a value: give a number"]);
}

#[test]
fn post_and_compare_write_under_their_prefix() {
    let dir = scratch("cli-prefix");
    let h5 = dir.join("disc.h5");
    let o = launch(0, &["run", &scene("disc.toml"), "--steps", "3", "-q", "-o", path(&h5)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let p = dir.join("p");
    let o = launch(0, &["post", path(&h5), "--prefix", path(&p)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    for f in ["p-energy.png", "p-energy.csv"] {
        assert!(dir.join(f).is_file(), "post --prefix wrote no {f}: {}", text(&o.stdout));
    }
    let c = dir.join("c");
    let o = launch(0, &["compare", path(&h5), path(&h5), "--prefix", path(&c)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(dir.join("c-energy.png").is_file(), "compare --prefix: {}", text(&o.stdout));
    // -o is the run's output file only.
    for sub in ["post", "compare"] {
        let o = launch(0, &[sub, path(&h5), "-o", path(&c)]);
        assert!(!o.status.success(), "{sub} -o was accepted");
        assert!(text(&o.stderr).contains("'-o'"), "{sub}: {}", text(&o.stderr));
    }
}

#[test]
fn the_suite_writes_under_its_dir() {
    let dir = scratch("cli-suite");
    let file = dir.join("tiny.toml");
    let scene = repo().join("scenes/suite/block_impact.toml");
    std::fs::write(
        &file,
        format!("[[case]]\nname = \"a\"\ngroup = \"g\"\nscene = \"{}\"\n", scene.display()),
    )
    .unwrap();
    let out = dir.join("out");
    let o = launch(0, &["suite", path(&file), "--scenes-only", "--dir", path(&out)]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let runs: Vec<_> = std::fs::read_dir(out.join("runs")).unwrap().flatten().collect();
    assert_eq!(runs.len(), 1, "{}", text(&o.stdout));
    let o = launch(0, &["suite", path(&file), "--scenes-only", "-o", path(&out)]);
    assert!(!o.status.success(), "suite -o was accepted");
}
