use evoloop_schemes::error::*;
use std::error::Error;

/// Where the robust study cannot make its directory, it says so with the path and keeps the
/// system's error, before any run.
#[test]
fn a_study_that_cannot_write_keeps_the_path_and_the_cause() {
    let tmp = tempfile::tempdir().unwrap();
    let blocked = tmp.path().join("a_file");
    std::fs::write(&blocked, "").unwrap();
    let dir = blocked.join("study");
    let e = evoloop_schemes::robust::study::study(&dir, 1, 1, &mut |_, _, _| {})
        .expect_err("a directory inside a file cannot be made");
    let evoloop_schemes::robust::study::StudyError::Write(WriteError::File { path, source }) = &e
    else {
        panic!("{e:?}");
    };
    assert_eq!(path, &dir);
    assert!(e.to_string().contains(&dir.display().to_string()), "{e}");
    assert!(
        e.source().is_some_and(|s| s.is::<std::io::Error>()),
        "{source}"
    );
}

/// A nominal transfer function the plant loader refuses names the part refused, and the
/// scheme's message is the reason alone.
#[test]
fn a_refused_nominal_model_keeps_its_key() {
    let e = evoloop_control::plant::lti::LtiSpec::from_transfer_function(
        &[1.0],
        &[0.0, 1.0],
        1e-3,
        (-1.0, 1.0),
    )
    .expect_err("a leading zero in the denominator");
    assert_eq!(e.file, std::path::Path::new("model"));
    assert!(!e.key.is_empty(), "{e}");
    let s = SchemeError::NominalModel(e.clone());
    assert_eq!(s.to_string(), e.reason);
    assert!(s.source().is_some());
    let fast = evoloop_control::plant::lti::LtiSpec::from_transfer_function(
        &[1.0],
        &[1.0, 1e12],
        1.0,
        (-1.0, 1.0),
    )
    .expect_err("a pole at -1e12 rad/s cannot be held for a second");
    assert_eq!(fast.key, "period", "{fast}");
}
