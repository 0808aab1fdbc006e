//! Why an RKGNN identification could not run.

use crate::config::ConfigError;
use std::path::PathBuf;

/// Why `Prior::new`, `Trajectory::from_run`, `identify`, `identify_model`, `LiveIdentify::new`
/// or `live::simulate` stopped.
#[derive(Debug)]
pub enum RkgnnError {
    /// Eq. 2's bounds refused: they need 0 < m1 <= m2, both finite.
    Prior {
        /// The lower bound given.
        m1: f64,
        /// The upper bound given.
        m2: f64,
    },
    /// A run's `run.csv` is missing, unreadable or lacks what identification needs.
    RunFile {
        /// The file.
        file: PathBuf,
        /// What is wrong with it (empty: the system's error says it).
        reason: String,
        /// The system's error, where there is one.
        source: Option<std::io::Error>,
    },
    /// Too few samples for the fit or its least-squares start (how many, and what is needed).
    TooFewSamples(String),
    /// The least-squares start found no model with a positive definite M-hat.
    NoStart,
    /// Identification alongside operation needs a `fuzzy_computed_torque` controller.
    NotFuzzy,
    /// The scenario cannot run in this process.
    Scenario(ConfigError),
}

impl RkgnnError {
    pub(crate) fn run_file(file: &std::path::Path, reason: impl Into<String>) -> Self {
        RkgnnError::RunFile {
            file: file.to_path_buf(),
            reason: reason.into(),
            source: None,
        }
    }
}

impl std::fmt::Display for RkgnnError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RkgnnError::Prior { m1, m2 } => write!(
                f,
                "eq. 2's bounds need 0 < m1 <= m2 (finite), got m1 = {m1}, m2 = {m2}"
            ),
            RkgnnError::RunFile {
                file,
                reason,
                source,
            } => {
                write!(f, "{}: ", file.display())?;
                match source {
                    Some(e) => e.fmt(f),
                    None => f.write_str(reason),
                }
            }
            RkgnnError::TooFewSamples(why) => f.write_str(why),
            RkgnnError::NoStart => f.write_str(
                "the least-squares start found no model with a positive definite M-hat (give \
                 --start random)",
            ),
            RkgnnError::NotFuzzy => f.write_str(
                "optimiser.mode = \"identify\" needs a fuzzy_computed_torque controller",
            ),
            RkgnnError::Scenario(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for RkgnnError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RkgnnError::RunFile {
                source: Some(e), ..
            } => Some(e),
            _ => None,
        }
    }
}

impl From<ConfigError> for RkgnnError {
    fn from(e: ConfigError) -> Self {
        RkgnnError::Scenario(e)
    }
}

/// Why `evoloop rkgnn study` or `evoloop rkgnn selection` stopped (`study::run`,
/// `selection::run`).
#[derive(Debug)]
pub enum StudyError {
    /// The study's built-in scenario lacks what the study edits: evoloop's fault, not the input's.
    BuiltIn(String),
    /// A setting refused (`--seeds` below 1, a model directory without the model asked for).
    Setting(String),
    /// A case's scenario is refused (its reference leaves the arm's joint limits, say).
    Scenario(ConfigError),
    /// The robot file does not load.
    Robot(crate::dynamics::RobotError),
    /// The robot is not one the study takes: which, and why.
    Arm(String),
    /// A case's run in this process failed.
    Run {
        /// The case.
        case: String,
        /// Why.
        source: RkgnnError,
    },
    /// An identification the study needs failed.
    Identify(RkgnnError),
    /// A model file could not be saved or loaded.
    Model(evoloop_rkgnn::model::ModelError),
    /// A result or scenario file, or its directory, could not be written.
    Write(evoloop_schemes::WriteError),
    /// A run logged less than the study reads.
    Data(&'static str),
}

impl std::fmt::Display for StudyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StudyError::BuiltIn(why) => write!(f, "built-in scenario: {why}"),
            StudyError::Setting(why) | StudyError::Arm(why) => f.write_str(why),
            StudyError::Scenario(e) => e.fmt(f),
            StudyError::Robot(e) => e.fmt(f),
            StudyError::Run { case, source } => write!(f, "{case}: {source}"),
            StudyError::Identify(e) => e.fmt(f),
            StudyError::Model(e) => e.fmt(f),
            StudyError::Write(e) => e.fmt(f),
            StudyError::Data(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for StudyError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            StudyError::Run { source, .. } => Some(source),
            // A wrapping variant reads as the error it wraps: its source is that error's.
            StudyError::Scenario(e) => e.source(),
            StudyError::Robot(e) => e.source(),
            StudyError::Identify(e) => e.source(),
            StudyError::Model(e) => e.source(),
            StudyError::Write(e) => e.source(),
            _ => None,
        }
    }
}

impl From<ConfigError> for StudyError {
    fn from(e: ConfigError) -> Self {
        StudyError::Scenario(e)
    }
}

impl From<crate::dynamics::RobotError> for StudyError {
    fn from(e: crate::dynamics::RobotError) -> Self {
        StudyError::Robot(e)
    }
}

impl From<RkgnnError> for StudyError {
    fn from(e: RkgnnError) -> Self {
        StudyError::Identify(e)
    }
}

impl From<evoloop_rkgnn::model::ModelError> for StudyError {
    fn from(e: evoloop_rkgnn::model::ModelError) -> Self {
        StudyError::Model(e)
    }
}

impl From<evoloop_schemes::WriteError> for StudyError {
    fn from(e: evoloop_schemes::WriteError) -> Self {
        StudyError::Write(e)
    }
}

impl From<crate::report::plot::PlotError> for StudyError {
    fn from(e: crate::report::plot::PlotError) -> Self {
        StudyError::Write(evoloop_schemes::WriteError::Figure(e))
    }
}
