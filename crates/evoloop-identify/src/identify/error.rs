//! Why an excitation could not be designed or a study of it could not run.

use super::lls::LlsError;
use crate::optim::SettingsError;

/// Why `Stage::new`, `WristCentre::of`, `MfsDesign::new`, `ExcitationProblem::new`, `search`
/// or the excitation study stopped.
#[derive(Debug)]
pub enum ExcitationError {
    /// A design setting refused: which (`harmonics`, `period`, `samples`), and why.
    Setting {
        /// The setting.
        key: &'static str,
        /// Why it is refused (with its value).
        reason: String,
    },
    /// The robot cannot take this stage or trajectory: too few joints, no spherical wrist, a
    /// modified Fourier series on the wrist stage. The reason names the robot and the way out.
    Robot(String),
    /// The swarm's settings were refused.
    Optimiser(SettingsError),
    /// The search found no trajectory it could use (which, and what to change).
    NotFound(String),
    /// A study's experiment: the scenario refused the trajectory.
    Scenario(crate::config::ConfigError),
    /// A study's experiment: the estimate failed on a trajectory.
    Estimate(LlsError),
}

impl ExcitationError {
    pub(crate) fn setting(key: &'static str, reason: impl Into<String>) -> Self {
        ExcitationError::Setting {
            key,
            reason: reason.into(),
        }
    }
}

impl std::fmt::Display for ExcitationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExcitationError::Setting { reason, .. } => f.write_str(reason),
            ExcitationError::Robot(r) | ExcitationError::NotFound(r) => f.write_str(r),
            ExcitationError::Scenario(e) => e.fmt(f),
            ExcitationError::Optimiser(e) => e.fmt(f),
            ExcitationError::Estimate(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for ExcitationError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ExcitationError::Optimiser(e) => e.source(),
            ExcitationError::Estimate(e) => e.source(),
            _ => None,
        }
    }
}

impl From<SettingsError> for ExcitationError {
    fn from(e: SettingsError) -> Self {
        ExcitationError::Optimiser(e)
    }
}

impl From<crate::config::ConfigError> for ExcitationError {
    fn from(e: crate::config::ConfigError) -> Self {
        ExcitationError::Scenario(e)
    }
}

impl From<LlsError> for ExcitationError {
    fn from(e: LlsError) -> Self {
        ExcitationError::Estimate(e)
    }
}
