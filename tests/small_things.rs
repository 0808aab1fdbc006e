//! Small things users hit (issue 18, item 8): a closed pipe, an endless input file, inputs
//! that overflow, out-of-range reference values, each with a clear outcome instead of a panic,
//! a hang or NaN with exit 0.

mod common;
use common::{assert_refused, cli, evoloop, scenario, write};
use std::process::{Command, Stdio};

#[test]
fn a_closed_stdout_is_not_a_panic() {
    // `evoloop dynamics regressor ... | head -1`: the reader is gone before the output is written.
    let mut child = Command::new(evoloop())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "dynamics",
            "regressor",
            "--robot",
            "config/robots/industrial6.toml",
            "--q",
            "0.1,0.2,0.3,0.4,0.5,0.6",
            "--json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    // Like any Unix filter: it ends quietly, by SIGPIPE (or exit 0 had it written everything
    // before the pipe closed), never with a panic (exit 101).
    use std::os::unix::process::ExitStatusExt;
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.signal() == Some(libc::SIGPIPE) || o.status.code() == Some(0),
        "{:?}: {e}",
        o.status
    );
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn an_endless_file_is_refused_after_a_bounded_read() {
    let o = cli(&["check", "/dev/zero"]);
    assert_refused(&o, "larger than 16 MiB");
}

#[test]
fn inputs_that_overflow_are_an_error_not_nan() {
    let o = cli(&[
        "dynamics",
        "--robot",
        "config/robots/arm3.toml",
        "--qd",
        "1e300,1e300,1e300",
        "--json",
    ]);
    assert_refused(&o, "not finite");
}

#[test]
fn a_reference_value_beyond_any_plant_is_refused_with_its_key() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(
        tmp.path(),
        "big.toml",
        &scenario("kind = \"step\"\namplitude = 1e308", ""),
    );
    let o = cli(&["check", cfg.to_str().unwrap()]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("reference.amplitude") && e.contains("1000000"),
        "{e}"
    );
}
