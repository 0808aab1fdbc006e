//! The objectives an evaluation worker (`evoloop worker`) can rebuild from their description
//! (`optim::Job`): the indirect scheme's model costs, which are what an optimiser evaluates by the
//! population. An objective over data too large to ship (the RKGNN fit over a recorded window)
//! describes itself as None and stays in its process.
//!
//! | kind | objective | what it carries |
//! |---|---|---|
//! | `maglev` | `sim::maglev::Objective` | the experiment (plant with the estimated mass, trajectory, noise), anti-windup scheme, noise seed |
//! | `two_mass` | `indirect::two_mass::SpringCost` | the model with the estimated spring constant, one repetition of the reference, the cost weight |

use crate::optim::{Job, JobDecodeError, Objective};

/// Every kind `rebuild` knows.
pub const KINDS: [&str; 2] = [
    crate::sim::maglev::Objective::KIND,
    crate::indirect::two_mass::SpringCost::KIND,
];

/// Why a job's objective cannot be rebuilt here.
#[derive(Debug)]
pub enum RebuildError {
    /// No objective of this kind in this build (a worker of another version): the kind.
    UnknownKind(String),
    /// The bytes do not decode as the objective the kind names.
    Decode(JobDecodeError),
}

impl std::fmt::Display for RebuildError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RebuildError::UnknownKind(k) => write!(
                f,
                "unknown job kind `{k}` (this build knows {})",
                KINDS.join(", ")
            ),
            RebuildError::Decode(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for RebuildError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RebuildError::Decode(e) => Some(e),
            RebuildError::UnknownKind(_) => None,
        }
    }
}

/// The objective `job` describes, ready to evaluate.
pub fn rebuild(job: &Job) -> Result<Box<dyn Objective + Send>, RebuildError> {
    match job.kind.as_str() {
        crate::sim::maglev::Objective::KIND => Ok(Box::new(
            job.decode::<crate::sim::maglev::Objective>()
                .map_err(RebuildError::Decode)?,
        )),
        crate::indirect::two_mass::SpringCost::KIND => Ok(Box::new(
            job.decode::<crate::indirect::two_mass::SpringCost>()
                .map_err(RebuildError::Decode)?,
        )),
        k => Err(RebuildError::UnknownKind(k.to_string())),
    }
}
