use evoloop_schemes::WriteError;
use evoloop_tune::{tune, validate_file, TuneError, TuneRequest};
use std::error::Error;
use std::path::{Path, PathBuf};

fn request(file: &Path, out: PathBuf) -> TuneRequest {
    TuneRequest {
        file: file.to_path_buf(),
        seed: None,
        seeds: None,
        json: false,
        out: Some(out),
        quiet: true,
        compare: None,
        settle: None,
    }
}

/// Each refusal says what is refused, in the form the command line printed before, with
/// the cause kept where there is one.
#[test]
fn an_experiment_is_refused_with_its_cause() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("maglev.toml");
    std::fs::write(&file, "experiment = \"maglev\"\n[maglev]\nmass = 7.0\n").unwrap();
    let e = validate_file(&file).unwrap_err();
    let TuneError::Config(c) = &e else {
        panic!("{e:?}")
    };
    assert_eq!(c.key, "maglev.mass");
    assert_eq!(
        e.to_string(),
        format!(
            "{}: key `maglev.mass`: must be within [0.01, 2] (got 7)",
            file.display()
        )
    );

    let arsinh = tmp.path().join("arsinh.toml");
    std::fs::write(&arsinh, "experiment = \"arsinh\"\n").unwrap();
    let mut r = request(&arsinh, tmp.path().join("out"));
    r.seeds = Some(vec![1, 2]);
    let e = tune(&r).unwrap_err();
    assert!(
        matches!(
            e,
            TuneError::Option {
                option: "--seeds",
                ..
            }
        ),
        "{e:?}"
    );
    assert_eq!(
        e.to_string(),
        "--seeds: the multi-seed study is for the maglev experiment"
    );

    // An output directory inside a file cannot be made: its path, and the system's error.
    let blocked = tmp.path().join("a_file");
    std::fs::write(&blocked, "").unwrap();
    let e = tune(&request(&arsinh, blocked.join("out"))).unwrap_err();
    assert!(
        matches!(&e, TuneError::Write(WriteError::File { .. })),
        "{e:?}"
    );
    assert!(
        e.to_string().contains(&blocked.display().to_string()),
        "{e}"
    );
    assert!(e.source().is_some());
}
