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
