//! The model a controller checks new gain sets on (indirect scheme, Section 3.1.2 of the
//! fuzzy-network paper): the plant's linear model at its configured parameters until the
//! optimiser's estimate of the parameter that changes in operation arrives, then at the latest
//! estimate. A set the optimiser tuned on a drifted plant is judged on that plant, not on one the
//! plant no longer is; and a set that is stable only on the nominal model is refused.
//!
//! Estimates are adopted at the sample they name (`ModelEstimate::apply_at_seq`), so every
//! lockstep run of a seed checks each set on the same estimate. An estimate that is not finite
//! or not positive is refused and the last good model stays.

use super::LinearModel;
use crate::msg::{LinearEstimate, ModelEstimate};
use crate::plant::PlantModel;

/// Estimates waiting for their sample: at 10 Hz and applied within a synchronisation interval,
/// a few at most.
const PENDING: usize = 8;

/// What became of the estimates, for the run's report.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ModelCheckReport {
    /// The last estimate adopted; None: sets were checked on the configured model only.
    pub last_adopted: Option<f64>,
    /// Estimates adopted: sets were checked on their models from their sample on.
    pub adopted: u64,
    /// Not finite or not positive: the model in use was kept.
    pub refused: u64,
    /// More estimates waiting than the queue holds (the oldest go).
    pub dropped: u64,
    /// A law on a model-based filter (state feedback's Kalman filter): the filter designed
    /// again on an adopted estimate, and the estimates that gave no stable filter (the last
    /// filter kept).
    #[serde(default)]
    pub filters_designed: u64,
    /// Adopted estimates on which no stable filter could be designed (the last filter kept).
    #[serde(default)]
    pub filters_refused: u64,
}

/// Estimates waiting for their sample and what became of them: the queue both checks share.
/// Capacity `PENDING`, never grown; the oldest goes when it is full.
struct Adoption<T> {
    pending: Vec<T>,
    report: ModelCheckReport,
}

impl<T: Copy> Adoption<T> {
    fn new() -> Self {
        Self {
            pending: Vec::with_capacity(PENDING),
            report: ModelCheckReport::default(),
        }
    }

    fn offer(&mut self, e: &T) {
        if self.pending.len() == PENDING {
            self.pending.remove(0);
            self.report.dropped += 1;
        }
        self.pending.push(*e);
    }

    /// Adopt every estimate due at sample `seq` (`at` gives its sample), in order, through
    /// `model_of` (the model and the value reported, None to refuse it); the model of the last
    /// good one when any was adopted. Allocation-free.
    fn due(
        &mut self,
        seq: u64,
        at: impl Fn(&T) -> u64,
        model_of: impl Fn(&T) -> Option<(LinearModel, Option<f64>)>,
    ) -> Option<LinearModel> {
        let mut model = None;
        while let Some(i) = self.pending.iter().position(|e| at(e) <= seq) {
            let e = self.pending.remove(i);
            match model_of(&e) {
                Some((m, value)) => {
                    model = Some(m);
                    self.report.adopted += 1;
                    self.report.last_adopted = value;
                }
                None => self.report.refused += 1,
            }
        }
        model
    }
}

/// The model a controller checks new gain sets on for a plant with a varying parameter: the plant's
/// linear model at the configured value, then at the latest estimate adopted (see the module docs).
pub struct ModelCheck {
    plant: PlantModel,
    adoption: Adoption<ModelEstimate>,
}

impl ModelCheck {
    /// For a plant with a varying parameter and a linear model at any value of it; None
    /// otherwise (nothing to re-check on).
    pub fn new(plant: &PlantModel) -> Option<Self> {
        let cfg = plant.config();
        cfg.linear_model_at(cfg.varying_parameter(0.0)?)?;
        Some(Self {
            plant: plant.clone(),
            adoption: Adoption::new(),
        })
    }

    /// Queue a received estimate. Never allocates.
    pub fn offer(&mut self, e: &ModelEstimate) {
        self.adoption.offer(e);
    }

    /// Adopt every estimate due at sample `seq`, in order; the model at the last good one when
    /// any was adopted. Allocation-free.
    pub fn due(&mut self, seq: u64) -> Option<LinearModel> {
        let plant = &self.plant;
        self.adoption.due(
            seq,
            |e| e.apply_at_seq,
            |e| {
                (e.value.is_finite() && e.value > 0.0)
                    .then(|| plant.config().linear_model_at(e.value))
                    .flatten()
                    .map(|m| (m, Some(e.value)))
            },
        )
    }

    /// What became of the estimates so far.
    pub fn report(&self) -> &ModelCheckReport {
        &self.adoption.report
    }
}

/// The general indirect scheme's counterpart of `ModelCheck` (an `lti` plant or a plant of the
/// user's own): the controller checks new sets on the estimated transfer function the
/// optimiser publishes (`LinearEstimate`), adopted at the sample it names. An estimate that is
/// malformed (not finite, not monic, not strictly proper, more poles than the message holds)
/// or whose sampled model is not finite is refused and the last good model stays.
pub struct LinearCheck {
    period: f64,
    adoption: Adoption<LinearEstimate>,
}

impl LinearCheck {
    /// A check with no estimate yet, sampling each estimated transfer function at the control
    /// period `period`, s.
    pub fn new(period: f64) -> Self {
        Self {
            period,
            adoption: Adoption::new(),
        }
    }

    /// Queue a received estimate. Never allocates.
    pub fn offer(&mut self, e: &LinearEstimate) {
        self.adoption.offer(e);
    }

    /// Adopt every estimate due at sample `seq`, in order; the sampled model of the last good
    /// one when any was adopted. Allocation-free.
    pub fn due(&mut self, seq: u64) -> Option<LinearModel> {
        let period = self.period;
        self.adoption.due(
            seq,
            |e| e.apply_at_seq,
            |e| {
                let n = e.poles as usize;
                if n >= e.num.len() {
                    return None;
                }
                let (num, den) = (&e.num[..=n], &e.den[..=n]);
                if !num.iter().chain(den).all(|v| v.is_finite()) {
                    return None;
                }
                // Reported: the input gain, the leading numerator coefficient not zero.
                LinearModel::sampled_transfer_function(num, den, period)
                    .map(|m| (m, num.iter().copied().find(|b| *b != 0.0)))
            },
        )
    }

    /// What became of the estimates so far.
    pub fn report(&self) -> &ModelCheckReport {
        &self.adoption.report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn estimate(at: u64, num: [f64; 3], den: [f64; 3]) -> LinearEstimate {
        let mut e = LinearEstimate {
            apply_at_seq: at,
            poles: 2,
            ..Default::default()
        };
        e.num[..3].copy_from_slice(&num);
        e.den[..3].copy_from_slice(&den);
        e
    }

    /// Estimates are adopted at their sample, and a malformed one is refused and the last good
    /// model stays. (That adopting allocates nothing is checked on the real loop:
    /// `cycle_allocations` of `tests/indirect.rs`'s general-scheme runs.)
    #[test]
    fn estimates_are_adopted_at_their_sample_and_bad_ones_refused() {
        let mut c = LinearCheck::new(1e-3);
        c.offer(&estimate(10, [0.0, 0.0, 40.0], [1.0, 20.0, 0.0]));
        c.offer(&estimate(20, [0.0, 0.0, f64::NAN], [1.0, 20.0, 0.0]));
        c.offer(&estimate(20, [1.0, 0.0, 40.0], [1.0, 20.0, 0.0]));
        assert!(c.due(9).is_none());
        let m = c.due(10).expect("the good estimate");
        assert!(m.stabilised_by_pid(20.0, 20.0 * 0.02 / 1e-3, 0.02));
        assert!(c.due(20).is_none());
        assert_eq!((c.report().adopted, c.report().refused), (1, 2));
        assert_eq!(c.report().last_adopted, Some(40.0));
    }
}
