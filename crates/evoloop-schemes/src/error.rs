//! Why a tuning scheme cannot be set up for a scenario, or run on it in this process.

use crate::check::ConfigError;
use crate::optim::by_name::BuildError;
use crate::optim::settings::SettingsError;

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
            SchemeError::NotSiso(sentence) => f.write_str(sentence),
            SchemeError::NoIndirectModel => f.write_str(
                "the indirect optimiser drives the maglev under a PID, the two-mass plant under \
                 state feedback, or an lti or external plant under a PID",
            ),
            SchemeError::NoNominalModel => f.write_str(
                "safe_bayes_model needs the plant's nominal model: [optimiser.nominal_plant] or \
                 [optimiser.model] num, den",
            ),
            SchemeError::NominalModel(reason) => f.write_str(reason),
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
