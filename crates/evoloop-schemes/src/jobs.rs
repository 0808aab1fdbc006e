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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{Overrides, Scenario};

    /// Values of the rebuilt objective equal the original's bit for bit, for candidates that
    /// keep the ball, lose it (infinite) and carry awkward bits (subnormal, -0.0, 1 ulp apart).
    fn same_values(f: &dyn Objective, candidates: &[Vec<f64>]) {
        let job = f.describe().expect("describes itself");
        let g = rebuild(&job).expect("rebuilds");
        assert_eq!(g.describe(), Some(job), "the description survives the trip");
        for c in candidates {
            assert_eq!(
                f.value(c).to_bits(),
                g.value(c).to_bits(),
                "candidate {c:?}"
            );
        }
    }

    #[test]
    fn maglev_objective_rebuilds_to_the_same_bits() {
        let mut f = crate::sim::maglev::Objective::fuzzy(0.5, 7);
        // A mass that is not a short decimal: the description must carry all its bits.
        f.spec.plant.mass_steps = vec![(0.0, 0.160 * (1.0 + 1.0 / 3.0) + f64::EPSILON)];
        let p = crate::sim::maglev::PAPER_FUZZY.to_vec();
        let mut next = p.clone();
        next[0] = f64::from_bits(p[0].to_bits() + 1);
        let mut lost = p.clone();
        lost[0] = -1e6;
        same_values(&f, &[p, next, lost]);
    }

    #[test]
    fn two_mass_objective_rebuilds_to_the_same_bits() {
        let scn = Scenario::load(
            std::path::Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../config/two_mass/two_mass_indirect.toml"
            )),
            &Overrides::default(),
        )
        .expect("the shipped scenario");
        let crate::plant::PlantModel::TwoMass(plant) = &scn.plant.model else {
            panic!("a two-mass scenario")
        };
        let (_, tuner) = crate::indirect::two_mass::scheme(&scn, plant, scn.controller.tunable());
        let f = tuner.objective(0.5 + 1e-9);
        let g0 = scn.controller.tunable().gains.clone();
        let mut odd = g0.clone();
        odd[0] = -0.0;
        same_values(&f, &[g0, odd, vec![f64::MIN_POSITIVE / 4.0; 4]]);
    }

    #[test]
    fn an_unknown_or_damaged_job_is_refused_with_its_kind() {
        let e = rebuild(&Job {
            kind: "rkgnn".into(),
            bytes: vec![],
        })
        .err()
        .expect("refused");
        assert!(
            matches!(&e, RebuildError::UnknownKind(k) if k == "rkgnn"),
            "{e}"
        );
        let e = e.to_string();
        assert!(e.contains("rkgnn") && e.contains("maglev"), "{e}");
        let e = rebuild(&Job {
            kind: "maglev".into(),
            bytes: vec![1, 2, 3],
        })
        .err()
        .expect("refused");
        assert!(matches!(&e, RebuildError::Decode(_)), "{e}");
        assert!(
            std::error::Error::source(&e).is_some(),
            "the decoder's error is kept"
        );
        let e = e.to_string();
        assert!(e.contains("maglev") && e.contains("decode"), "{e}");
    }
}
