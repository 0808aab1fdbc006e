//! Why a tuning scheme cannot be set up for a scenario, or run on it in this process.

use crate::check::ConfigError;
use crate::optim::by_name::BuildError;
use crate::optim::settings::SettingsError;

/// Why `DirectTuner::new`, `direct::run_in_process` or `Indirect::new` refuses a scenario.
#[derive(Debug, Clone, PartialEq)]
pub enum SchemeError {
    /// The scenario cannot be simulated in this process: a plant of the user's own, or a run
    /// until stopped (`Scenario::require_in_process`'s file, key and reason).
    NotInProcess(ConfigError),
    /// This scheme needs a plant with one input and one output; the plant has more.
    NotSiso(&'static str),
    /// The indirect optimiser has no model of this plant under this controller.
    NoIndirectModel,
    /// `safe_bayes_model` without the plant's nominal model.
    NoNominalModel,
    /// The nominal transfer function (`[optimiser.model]`) makes no plant model: the reason.
    NominalModel(String),
    /// The optimiser named in the scenario cannot be built with its settings.
    Optimiser(BuildError),
    /// The Bayesian optimiser's settings are refused.
    Settings(SettingsError),
}

impl std::fmt::Display for SchemeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SchemeError::NotInProcess(e) => e.fmt(f),
            SchemeError::NotSiso(what) => {
                write!(f, "{what} takes a plant with one input and one output")
            }
            SchemeError::NoIndirectModel => f.write_str(
                "the indirect optimiser drives the maglev under a PID, the two-mass plant under \
                 state feedback, or an lti or external plant under a PID",
            ),
            SchemeError::NoNominalModel => f.write_str(
                "safe_bayes_model needs the plant's nominal model: [optimiser.nominal_plant] or \
                 [optimiser.model] num, den",
            ),
            SchemeError::NominalModel(reason) => write!(f, "the nominal model: {reason}"),
            SchemeError::Optimiser(e) => e.fmt(f),
            SchemeError::Settings(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for SchemeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SchemeError::NotInProcess(e) => Some(e),
            SchemeError::Optimiser(e) => Some(e),
            SchemeError::Settings(e) => Some(e),
            _ => None,
        }
    }
}
