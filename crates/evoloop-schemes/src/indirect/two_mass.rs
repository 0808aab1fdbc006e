//! The indirect scheme on the two-mass-spring benchmark: the spring constant k is estimated
//! online from what a sensor gives — the measured position (noisy, quantised) and the command
//! applied — and DE/rand/1/bin tunes the state-feedback gains on the model with the estimated k
//! for the cost of one repetition of the scenario's reference, sum |r - y| + w sum |u| per
//! sample.
//!
//! Estimator. From m1 x1'' = u - k (x1 - x2) and m2 x2'' = k (x1 - x2):
//! - far sensor (y = x2): m1 m2 y'''' = k (u - (m1 + m2) y''),
//! - collocated sensor (y = x1): m1 m2 y'''' - m2 u'' = k (u - (m1 + m2) y''),
//!
//! linear in k. The derivatives are those of the signals through the state-variable filter
//! a^4 / (s + a)^4 (`evoloop_control::filter::svf`), which leaves the relation intact; recursive least squares with
//! forgetting tracks k. Noise enters the target through s^4 F with gain ~a^4 but is white there,
//! so the least-squares average removes it; the regressor sees it only through s^2 F, which falls
//! off as 1/s^2, so the equation-error bias stays far below the tolerance of the tests.

use super::rls::InformationRls;
use super::{Candidate, Estimate, Estimator, Tuner};
use super::{Svf, SvfDesign};
use crate::check::Tunable;
use crate::config::Scenario;
use crate::law::estimator::{KalmanDesign, KalmanGains};
use crate::law::{ControllerModel, StateFeedback};
use crate::msg::PlantState;
use crate::plant::two_mass::{Sensor, TwoMass, TwoMassSpec};
use crate::reference::Reference;
use crate::robust::observer::{sampled_loop, spectral_radius};
use crate::sim::cost::TrackingCost;

/// The two-mass indirect scheme: the spring's estimator and the tuner of the gains.
pub fn scheme(
    scn: &Scenario,
    plant: &TwoMassSpec,
    tunable: &Tunable,
) -> (SpringEstimator, TwoMassTuner) {
    (
        SpringEstimator::new(scn, plant),
        TwoMassTuner::new(scn, plant, tunable),
    )
}

/// DE on the state-feedback gains, over one repetition on the model with the estimated spring.
pub struct TwoMassTuner {
    model: SpringModel,
    de: super::DeEpochs,
    margin: f64,
}

/// The model a candidate is scored on, all but its spring constant: one repetition of the
/// scenario's reference from rest, sum |r - y| + w sum |u| per sample.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct SpringModel {
    m1: f64,
    m2: f64,
    sensor: Sensor,
    period: f64,
    step: f64,
    reference: Reference,
    duration: f64,
    u_limit: Option<f64>,
    w: f64,
    /// The plant's declared sensor delay, samples: the model measures as the plant does and
    /// the filter predicts across it.
    #[serde(default)]
    sensor_delay: usize,
    /// The running law's filter design (`controller.state_feedback.state = "kalman"`). The
    /// controller designs its filter again on each estimate it adopts (`Kalman::redesign`), the
    /// one an epoch tunes on: each candidate is judged in the loop it will run in, with the
    /// filter designed at the spring scored. None: the true state.
    kalman: Option<KalmanDesign>,
}

/// The DE's objective: the gains' cost on the model with spring constant `k`. It owns the model,
/// so an evaluation worker can rebuild it from its description (`optim::Job`).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct SpringCost {
    /// The model the gains are scored on, all but its spring.
    pub model: SpringModel,
    /// The spring constant of the model the gains are scored on.
    pub k: f64,
    /// The filter on the model at `k`, designed once on first use (not per candidate; rebuilt
    /// by each evaluation worker, since it does not travel). None with a `kalman` design: no
    /// filter exists, and every candidate costs infinity.
    #[serde(skip)]
    filter: std::sync::OnceLock<Option<KalmanGains>>,
}

impl SpringCost {
    /// The `optim::Job` kind of this objective.
    pub const KIND: &'static str = "two_mass";
}

impl crate::optim::Objective for SpringCost {
    fn value(&self, gains: &[f64]) -> f64 {
        let filter = self.filter.get_or_init(|| {
            let design = self.model.kalman?;
            let model = self.model.plant(self.k).linear_model();
            design.gains(&model, self.model.period).ok()
        });
        match (self.model.kalman, filter) {
            // The scenario's check designed the filter at the nominal spring; none exists here.
            (Some(_), None) => f64::INFINITY,
            _ => self.model.cost(self.k, filter.as_ref(), gains),
        }
    }
    fn describe(&self) -> Option<crate::optim::Job> {
        crate::optim::Job::of(Self::KIND, self)
    }
}

/// Online estimate of the spring constant from the measured position and the applied command
/// (see the module's documentation).
pub struct SpringEstimator {
    /// The configured spring constant, the model's until the estimate is ready.
    k_nominal: f64,
    m1: f64,
    m2: f64,
    sensor: Sensor,
    period: f64,
    /// The measured output and the applied command through the same filter.
    svf: SvfDesign,
    y_f: Svf,
    u_f: Svf,
    /// Samples still to filter before the filtered signals are used (the filter's transient
    /// after a start on a plant that was not at rest).
    settling: usize,
    /// The plant starts at rest (equal initial positions, no velocity).
    starts_at_rest: bool,
    rls: InformationRls,
    /// The measurement noise's variance, from the second differences of the output (white
    /// noise of variance s2 gives E[(y[k+1] - 2 y[k] + y[k-1])^2] = 6 s2; the motion's own
    /// second difference, y'' dt^2, is far below the encoder's count here).
    y_last: [f64; 2],
    noise_var: f64,
    /// RMS gain from output noise to the target m1 m2 s^4 F y.
    target_noise_gain: f64,
}

/// Filter pole (rad/s): a few times the benchmark's modes (sqrt(k (m1 + m2) / (m1 m2)) = 1 to 2
/// rad/s for k = 0.5 to 2), so the filtered signals keep the dynamics that carry k.
pub const SVF_POLE: f64 = 2.0;
/// After joining a moving plant, the filter's start error decays as (a t)^3 e^(-a t) / 6:
/// below 3e-6 after 20 time constants 1/a (10 s at a = 2).
const SVF_SETTLE_S: f64 = 20.0 / SVF_POLE;
/// The estimator keeps the data for this relative standard deviation of k at the measured noise
/// level, and forgets older data as fast as new excitation replaces them (`InformationRls`).
pub const K_REL_STD: f64 = 0.01;
/// Multiples of the estimated k at which a candidate must make the loop stable (a 25 % drift
/// either way before the next epoch).
const DRIFT_CHECKED: [f64; 5] = [0.8, 0.9, 1.0, 1.125, 1.25];

/// The smallest output noise assumed (std): with an ideal sensor the discretisation error of the
/// filtered relation (first-order hold, ~1e-8 of the travel here) takes the noise's place, and a
/// zero variance would let a single sample at rest, where the regressor vanishes, set k.
const NOISE_FLOOR: f64 = 1e-6;
/// Time constant (s) with which the estimator's information fades regardless of excitation:
/// one half-period of the shipped square wave, so a barely excited loop still follows the drift.
pub const FADE_S: f64 = 5.0;
/// Seconds over which the measurement noise's variance is averaged.
const NOISE_MEMORY_S: f64 = 1.0;

impl TwoMassTuner {
    /// The tuner for the scenario: DE within the gains' `tunable` bounds, each candidate scored
    /// over one repetition of the reference on a model with the plant's masses and sensor and
    /// the running law's filter design.
    pub fn new(scn: &Scenario, plant: &TwoMassSpec, tunable: &Tunable) -> Self {
        let repetition = match &scn.reference {
            Reference::Square { period, start, .. } => start + period,
            _ => scn.timing.duration.min(20.0),
        };
        Self {
            model: SpringModel {
                m1: plant.m1,
                m2: plant.m2,
                sensor: plant.sensor,
                period: scn.timing.period,
                step: scn.plant.step,
                reference: scn.reference.clone(),
                duration: repetition,
                u_limit: scn.controller.u_limit,
                w: scn.optimiser.cost_u_weight,
                sensor_delay: scn.plant.sensor_delay as usize,
                kalman: match &scn.controller.model {
                    ControllerModel::StateFeedback(sf) => sf.kalman,
                    _ => None,
                },
            },
            de: super::DeEpochs::new(scn, &tunable.bounds),
            margin: scn.optimiser.margin,
        }
    }

    /// Cost of `gains` over one repetition on the model with spring constant k (infinite when
    /// the loop diverges).
    pub fn cost(&self, k: f64, gains: &[f64]) -> f64 {
        crate::optim::Objective::value(&self.objective(k), gains)
    }

    /// The DE's objective on the model with spring constant k.
    pub fn objective(&self, k: f64) -> SpringCost {
        SpringCost {
            model: self.model.clone(),
            k,
            filter: std::sync::OnceLock::new(),
        }
    }
}

impl SpringModel {
    fn plant(&self, k: f64) -> TwoMass {
        TwoMass::new(self.m1, self.m2, k, self.sensor)
    }

    /// Cost of `gains` over one repetition on the model with spring constant k, the law on
    /// `filter` (designed at k) or on the true state (infinite when the loop diverges or is not
    /// stable over the drift checked).
    fn cost(&self, k: f64, filter: Option<&KalmanGains>, gains: &[f64]) -> f64 {
        // A candidate of another length (a damaged job) is no loop at all.
        if gains.len() != self.plant(k).linear_model().n() + 1 {
            return f64::INFINITY;
        }
        // A finite horizon cannot see a slowly growing oscillation (a set with closed-loop poles
        // at +0.08 +- 4.7j costs little over one 10 s repetition from rest, then diverges on the
        // plant), and k keeps drifting after the epoch: a set must make the loop asymptotically
        // stable on the model over the drift it may meet before the next epoch. With a filter,
        // the loop while the filter lags the drift: the filter where it was designed, the plant
        // drifted (the sampled loop of plant, filter and feedback). Requiring the full-state
        // loop at the drifted spring as well (the filter caught up, by separation) was tried:
        // on seed 1 the sets it let through left the loop too slow to excite the estimator,
        // whose estimate stalled at 1.39 for the true 2 (the book's Sensors chapter).
        let stable = DRIFT_CHECKED.iter().all(|f| {
            let drifted = self.plant(k * f).linear_model();
            match filter {
                Some(g) => sampled_loop(&drifted, g, self.period, gains)
                    .is_some_and(|m| spectral_radius(&m) < 1.0),
                None => drifted.stabilised_by(gains),
            }
        });
        if !stable {
            return f64::INFINITY;
        }
        let plant = self.plant(k);
        let mut ctrl = StateFeedback::new(gains, self.period, self.u_limit);
        if let Some(g) = filter {
            ctrl = ctrl.with_kalman(g, self.sensor_delay);
        }
        let crate::sim::Response { y, u, .. } = crate::sim::Run {
            reference: &self.reference,
            period: self.period,
            step: self.step,
            duration: self.duration,
            diverged: 1e3,
            noise_std: 0.0,
            seed: 0,
            sensor_delay: self.sensor_delay,
            u0: 0.0,
        }
        .response(Box::new(plant), Box::new(ctrl));
        let n = (self.duration / self.period).round() as usize;
        if y.len() < n {
            return f64::INFINITY;
        }
        let mut sp = crate::reference::Setpoint::default();
        let mut cost = TrackingCost::new(self.w);
        for (k, (yk, uk)) in y.iter().zip(&u).enumerate() {
            self.reference.sample(k as f64 * self.period, &mut sp);
            cost.add(
                &sp.q[..1],
                std::slice::from_ref(yk),
                std::slice::from_ref(uk),
            );
        }
        cost.total
    }
}

impl SpringEstimator {
    /// The estimator for the scenario's two-mass plant: its masses and sensor, its configured
    /// spring as the start, the filter pole `SVF_POLE` at the control period.
    pub fn new(scn: &Scenario, plant: &TwoMassSpec) -> Self {
        let svf = SvfDesign::new(SVF_POLE, scn.timing.period);
        Self {
            k_nominal: plant.spring,
            m1: plant.m1,
            m2: plant.m2,
            sensor: plant.sensor,
            period: scn.timing.period,
            target_noise_gain: plant.m1 * plant.m2 * svf.noise_gain(4),
            svf,
            y_f: Svf::default(),
            u_f: Svf::default(),
            settling: 0,
            starts_at_rest: plant.initial_positions[0] == plant.initial_positions[1],
            rls: InformationRls::new(plant.spring, K_REL_STD, FADE_S / scn.timing.period),
            y_last: [0.0; 2],
            noise_var: 0.0,
        }
    }

    /// Feed sample `s`; `follows` when it directly follows the previous one (otherwise the
    /// filters restart on it).
    pub fn push(&mut self, follows: bool, s: &PlantState) {
        // The command in `s` is the one held over the period that ended at `s`.
        if !follows {
            // First sample, or a gap in the stream: restart the filters at rest on it. That is
            // exact at the run's first sample when the plant starts at rest; otherwise the
            // filter's start transient must die out first.
            self.y_f = Svf::at_rest(s.y[0]);
            self.u_f = Svf::at_rest(s.u_applied[0]);
            self.y_last = [s.y[0]; 2];
            self.settling = if s.seq == 0 && self.starts_at_rest {
                0
            } else {
                (SVF_SETTLE_S / self.period).ceil() as usize
            };
            return;
        }
        let d = &self.svf;
        self.u_f.held(d, s.u_applied[0]);
        self.y_f.sampled(d, s.y[0]);
        let dd = s.y[0] - 2.0 * self.y_last[1] + self.y_last[0];
        self.y_last = [self.y_last[1], s.y[0]];
        let w = self.period / NOISE_MEMORY_S;
        self.noise_var += w * (dd * dd / 6.0 - self.noise_var);
        if self.settling > 0 {
            self.settling -= 1;
            return;
        }
        let (m1, m2) = (self.m1, self.m2);
        let y2 = self.y_f.derivative(d, 2);
        let y4 = self.y_f.derivative(d, 4);
        let collocated = match self.sensor {
            Sensor::Far => 0.0,
            Sensor::Actuated => m2 * self.u_f.derivative(d, 2),
        };
        let target = m1 * m2 * y4 - collocated;
        let regressor = self.u_f.derivative(d, 0) - (m1 + m2) * y2;
        let noise_var = self.noise_var.max(NOISE_FLOOR * NOISE_FLOOR);
        let target_var = (self.target_noise_gain * self.target_noise_gain) * noise_var;
        self.rls.update(target, regressor, target_var);
    }

    /// The estimate of k and its standard deviation at plant time `t`.
    pub fn estimate(&self, t: f64) -> Estimate {
        Estimate {
            t,
            value: self.rls.theta,
            std: self.rls.std(),
        }
    }

    /// Enough data for the estimate to replace the nominal value.
    pub fn ready(&self) -> bool {
        // Two seconds of data.
        self.rls.updates as f64 * self.period > 2.0
    }
}

impl Estimator for SpringEstimator {
    fn observe(&mut self, prev: Option<&PlantState>, s: &PlantState) {
        self.push(prev.is_some(), s);
    }

    fn estimate(&self, t: f64) -> Estimate {
        SpringEstimator::estimate(self, t)
    }

    fn ready(&self) -> bool {
        SpringEstimator::ready(self)
    }

    fn nominal(&self) -> f64 {
        self.k_nominal
    }
}

impl Tuner for TwoMassTuner {
    fn epoch(&mut self, k: f64, _: &[f64], in_service: &[f64]) -> Candidate {
        let k = k.max(1e-3);
        // One objective, so its filter is designed once for the epoch and the set in service.
        let objective = self.objective(k);
        let (best, value) = self.de.run(&[in_service.to_vec()], &objective);
        Candidate {
            params: best,
            expected_cost: value,
            in_service_cost: crate::optim::Objective::value(&objective, in_service),
            model_value: k,
        }
    }

    fn margin(&self) -> f64 {
        self.margin
    }

    fn epoch_evaluations(&self) -> usize {
        self.de.evaluations
    }
}
