//! Small things users hit (issue 18, item 8): a closed pipe, an endless input file, inputs
//! that overflow, out-of-range reference values, each with a clear outcome instead of a panic,
//! a hang or NaN with exit 0.

use crate::common;
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
    // A device has no end: refused before a byte is read.
    let o = cli(&["check", "/dev/zero"]);
    assert_refused(&o, "not a regular file");
    // A regular file that is too long: refused after the bound (a sparse file, no disk used).
    let tmp = tempfile::tempdir().unwrap();
    let big = tmp.path().join("big.toml");
    std::fs::File::create(&big)
        .unwrap()
        .set_len(17 << 20)
        .unwrap();
    let o = cli(&["check", big.to_str().unwrap()]);
    assert_refused(&o, "larger than 16 MiB");
}

/// A FIFO where a linear plant's model file should be (issue 63, item 8): `evoloop check`
/// refuses it at once with the reason, where it waited for a writer forever.
#[test]
fn a_fifo_as_a_model_file_is_refused_not_waited_on() {
    let tmp = tempfile::tempdir().unwrap();
    let fifo = tmp.path().join("pendulum.json");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    // SAFETY: a valid C string.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let text = std::fs::read_to_string(common::config("linear/lti_pendulum.toml")).unwrap();
    let cfg = write(tmp.path(), "s.toml", &text);
    let with_fifo = |line: &str| {
        if line.trim_start().starts_with("file =") {
            format!("file = {:?}", fifo.to_str().unwrap())
        } else {
            line.to_string()
        }
    };
    let text: Vec<String> = text.lines().map(with_fifo).collect();
    assert!(
        text.iter().any(|l| l.contains("pendulum.json")),
        "no plant.lti.file"
    );
    std::fs::write(&cfg, text.join("\n")).unwrap();
    let mut child = Command::new(evoloop())
        .args(["check", cfg.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t0.elapsed() > std::time::Duration::from_secs(20) {
            let _ = child.kill();
            panic!("evoloop check waits on the FIFO");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    assert_refused(&o, "not a regular file");
}

/// `--seeds A..B` is counted before it is built (issue 63, item 7): the whole u64 range, ten
/// billion seeds and an empty range are refused at once with the reason; a seed given twice too.
#[test]
fn a_seed_range_is_counted_before_it_is_built() {
    for (seeds, why) in [
        ("0..18446744073709551615", "got 2^64"),
        ("1..10000000000", "got 10000000000"),
        ("1..300000000", "got 300000000"),
        ("5..1", "is empty"),
        ("3,4,3", "seed 3 is given twice"),
    ] {
        let t0 = std::time::Instant::now();
        let o = cli(&["run", "config/two_mass/two_mass.toml", "--seeds", seeds]);
        assert_refused(&o, why);
        assert!(t0.elapsed() < std::time::Duration::from_secs(10), "{seeds}");
    }
}

/// `--compare ga,ga` compared the GA with itself (issue 63, item 8): refused with the reason.
#[test]
fn an_optimiser_named_twice_in_a_comparison_is_refused() {
    let o = cli(&[
        "tune",
        "config/maglev/maglev_direct.toml",
        "--compare",
        "ga,ga",
        "--seeds",
        "1..2",
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("`ga` is named twice"), "{e}");
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
