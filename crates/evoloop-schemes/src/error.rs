//! Why a tuning scheme cannot be set up for a scenario, or run on it in this process.

use crate::check::ConfigError;
use crate::optim::by_name::BuildError;
use crate::optim::settings::SettingsError;
use crate::report::plot::PlotError;

/// Why a scheme refuses a scenario: `DirectTuner::new`, `direct::run_in_process` and
/// `run_tuner_in_process`, `direct::model::ModelTrials::new`, `Indirect::new` and the general
/// indirect scheme (`indirect::linear::scheme`).
#[derive(Debug, Clone, PartialEq)]
pub enum SchemeError {
    /// The scenario cannot be simulated in this process: a plant of the user's own, or a run
    /// until stopped (`Scenario::require_in_process`'s file, key and reason).
    NotInProcess(ConfigError),
    /// The plant has more than one input or output, and this part needs one of each: the
    /// sentence that says which.
    NotSiso(&'static str),
    /// The indirect optimiser has no model of this plant under this controller.
    NoIndirectModel,
    /// `safe_bayes_model` without the plant's nominal model.
    NoNominalModel,
    /// The nominal transfer function (`[optimiser.model]`) makes no plant model: why (its
    /// `reason` is the message; the key names the part refused).
    NominalModel(ConfigError),
    /// The optimiser named in the scenario cannot be built with its settings.
    Optimiser(BuildError),
    /// The Bayesian optimiser's settings are refused.
    Settings(SettingsError),
}

impl std::fmt::Display for SchemeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SchemeError::NotInProcess(e) => e.fmt(f),
            SchemeError::NotSiso(sentence) => f.write_str(sentence),
            SchemeError::NoIndirectModel => f.write_str(
                "the indirect optimiser drives the maglev under a PID, the two-mass plant under \
                 state feedback, or an lti or external plant under a PID",
            ),
            SchemeError::NoNominalModel => f.write_str(
                "safe_bayes_model needs the plant's nominal model: [optimiser.nominal_plant] or \
                 [optimiser.model] num, den",
            ),
            SchemeError::NominalModel(e) => f.write_str(&e.reason),
            SchemeError::Optimiser(e) => e.fmt(f),
            SchemeError::Settings(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for SchemeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SchemeError::NotInProcess(e) | SchemeError::NominalModel(e) => Some(e),
            SchemeError::Optimiser(e) => Some(e),
            SchemeError::Settings(e) => Some(e),
            _ => None,
        }
    }
}

/// A result file a scheme or study could not write (`direct::write_files`, the robust study).
#[derive(Debug)]
pub enum WriteError {
    /// A file or directory could not be made or written: its path and the system's error.
    File {
        /// The file or directory.
        path: std::path::PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A figure could not be drawn or written (the error names its file).
    Figure(PlotError),
}

impl WriteError {
    /// `source` on writing `path`, for `map_err`.
    pub fn file(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| WriteError::File {
            path: path.to_path_buf(),
            source,
        }
    }
}

impl std::fmt::Display for WriteError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // evoloop_files' errors name the path already; a bare io::Error does not.
            WriteError::File { path, source } => crate::report::with_path(f, path, source),
            WriteError::Figure(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for WriteError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            WriteError::File { source, .. } => Some(source),
            WriteError::Figure(e) => e.source(),
        }
    }
}
