//! `massfree study` with the model and amplitude axes: a tiny sweep of the disc impact,
//! linear against neo-Hookean at two impact speeds, read back from the CSV and checked
//! against what the theory says of the difference between the two models.

mod common;
use common::{num, read_csv};

use std::process::Command;

/// The disc (hc = 0.1, h = 0.4: 234 DOFs) dropped on the plane at v/c = 0.01 and 0.1, linear
/// and neo-Hookean, 60 steps of tau = 0.01 (the contact's first 0.6 time units, its whole
/// rise and most of its fall). The strain of the impact scales with v, the nonlinear part of
/// the Green-Lagrange strain with its square: relative to the response, the difference
/// between the two models grows about in proportion to v, so the tenfold speed must show the
/// larger difference (at least twice the slower one's, with room below the proportional
/// tenfold for the coarse mesh's active-set events). The reference model's rows are the
/// reference: difference 0 and time ratio 1.
#[test]
fn linear_and_neo_hookean_differ_more_at_the_higher_impact_speed() {
    let dir = common::scratch("study-models");
    let out = dir.join("out");
    let file = dir.join("study.toml");
    let scene = common::repo().join("scenes/suite/disc_impact.toml");
    let text = format!(
        r#"scene = {:?}
output = {:?}
mesh_param = "hc"
params = {{ h = 0.4 }}
steps = 60
reference = {{ model = "neo_hookean" }}
amplitude_set = {{ "initial.velocity" = ["0", "-11.6024 * {{amplitude}}"] }}
[sweep]
h = [0.1]
model = ["linear", "neo_hookean"]
amplitude = [0.01, 0.1]
"#,
        scene.display().to_string(),
        out.display().to_string()
    );
    std::fs::write(&file, text).unwrap();
    let mut cmd = Command::new(common::bin());
    cmd.arg("study").arg(&file);
    common::mpi_env(&mut cmd);
    let o = common::output(&mut cmd);
    let shown = format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(o.status.success(), "{shown}");
    let rows = read_csv(&out.join("results.csv"));
    assert_eq!(rows.len(), 4, "{shown}");
    let row = |model: &str, a: f64| {
        rows.iter()
            .find(|r| r["model"] == model && num(r, "amplitude") == a)
            .unwrap_or_else(|| panic!("no row {model} at {a}:\n{shown}"))
    };
    for r in &rows {
        assert_eq!(r["status"], "ok", "{shown}");
        assert!(num(r, "run_s") > 0.0, "{r:?}");
    }
    for a in [0.01, 0.1] {
        let r = row("neo_hookean", a);
        for k in ["err_l2", "err_force", "err_u"] {
            assert_eq!(num(r, k), 0.0, "{k} of the reference row: {r:?}");
        }
        assert_eq!(num(r, "time_ratio"), 1.0, "{r:?}");
        let l = row("linear", a);
        assert!(num(l, "time_ratio") > 0.0, "{l:?}");
    }
    let (slow, fast) = (row("linear", 0.01), row("linear", 0.1));
    for k in ["err_force", "err_l2"] {
        let (s, f) = (num(slow, k), num(fast, k));
        assert!(s > 0.0, "{k} at v/c = 0.01 is {s}: the models must differ\n{shown}");
        assert!(f > 2.0 * s, "{k}: {f} at v/c = 0.1 is not well above {s} at 0.01\n{shown}");
    }
    for png in ["difference_amplitude.png", "cost_amplitude.png"] {
        let p = out.join(png);
        assert!(p.is_file() && std::fs::metadata(&p).unwrap().len() > 1000, "{}", p.display());
    }
}
