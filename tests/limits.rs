//! The suite cannot hang: a launch that passes its limit is killed and fails its test, saying
//! HANG with the test's name (nextest's own limit, `.config/nextest.toml`, is the outer one).

mod common;
use common::*;

#[test]
fn a_launch_past_its_limit_is_killed_and_names_its_test() {
    let t0 = std::time::Instant::now();
    let caught = std::panic::catch_unwind(|| {
        output_within(std::process::Command::new("sleep").arg("60"), 1.0);
    });
    let message = match caught {
        Ok(()) => panic!("a 60 s sleep passed a 1 s limit"),
        Err(e) => e
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default(),
    };
    eprintln!("{message}");
    assert!(message.contains("HANG"), "no HANG in {message:?}");
    assert!(
        message.contains("a_launch_past_its_limit_is_killed_and_names_its_test"),
        "the test is not named in {message:?}"
    );
    assert!(t0.elapsed().as_secs_f64() < 30.0, "the sleep was not killed at its limit");
}
