//! Why an experiment of `evoloop tune` stopped.

use evoloop_control::check::ConfigError;
use evoloop_schemes::{SchemeError, WriteError};

/// Why `tune`, `validate_file` or an experiment stopped. A variant that wraps an error reads as
/// it, and its `source()` is that error's own cause (a chain printed whole says each thing once).
#[derive(Debug)]
pub enum TuneError {
    /// The experiment file or the scenario is refused: file, key, reason.
    Config(ConfigError),
    /// A command-line option this experiment or scenario does not take: the option and why.
    Option {
        /// The option, as typed (`--seeds`, `--compare`).
        option: &'static str,
        /// Why it is refused here.
        reason: String,
    },
    /// The direct scheme refused the scenario or failed on it.
    Scheme(SchemeError),
    /// A result file could not be written.
    Write(WriteError),
}

impl TuneError {
    /// `option` refused for `reason`.
    pub(crate) fn option(option: &'static str, reason: impl Into<String>) -> Self {
        TuneError::Option {
            option,
            reason: reason.into(),
        }
    }
}

impl std::fmt::Display for TuneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TuneError::Config(e) => e.fmt(f),
            TuneError::Option { option, reason } => write!(f, "{option}: {reason}"),
            TuneError::Scheme(e) => e.fmt(f),
            TuneError::Write(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for TuneError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TuneError::Config(e) => e.source(),
            TuneError::Option { .. } => None,
            TuneError::Scheme(e) => e.source(),
            TuneError::Write(e) => e.source(),
        }
    }
}

impl From<ConfigError> for TuneError {
    fn from(e: ConfigError) -> Self {
        TuneError::Config(e)
    }
}

impl From<SchemeError> for TuneError {
    fn from(e: SchemeError) -> Self {
        TuneError::Scheme(e)
    }
}

impl From<WriteError> for TuneError {
    fn from(e: WriteError) -> Self {
        TuneError::Write(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{tune, validate_file, TuneRequest};
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
}
