//! The indirect scheme for any linear single-input plant (an `lti` plant or a process of the
//! user's own): no plant-specific code, only the prior of `[optimiser.model]` (the transfer
//! function's structure and nominal coefficients).
//!
//! Estimator. The plant is a(s) y = b(s) u with a monic of degree n (<= 4) and b of degree
//! m < n. The relation holds for the signals through the state-variable filter
//! F = p^4 / (s + p)^4 (`evoloop_control::filter::svf`), whose states are the filtered derivatives:
//!
//!   s^n F y = -a_0 F y - ... - a_{n-1} s^{n-1} F y + b_0 F u + ... + b_m s^m F u,
//!
//! linear in theta = [a_0 .. a_{n-1}, b_0 .. b_m] (continuous-time least squares with a
//! state-variable filter: Young 1981, Garnier et al. 2003). The information matrix
//! R = sum lambda^k phi phi^T and f = sum lambda^k phi target forget with time constant
//! `memory`; theta = R^-1 f is re-solved every 0.1 s of plant time, and adopted only when the
//! data determine it:
//! - **excitation monitor**: the smallest eigenvalue of R's correlation matrix (R scaled to a
//!   unit diagonal) must exceed `EXCITATION_MIN` and the input gain's relative standard
//!   deviation `GAIN_REL_STD_MAX`; otherwise the last adopted model is held (a loop at rest
//!   teaches nothing, and a fit on it would follow the noise);
//! - **drift monitor**: the prediction error of the adopted model, averaged over `DRIFT_WINDOW_S`,
//!   against the fit's own residual; past `DRIFT_RATIO` times it the plant has changed, and the
//!   old data are discounted by `DRIFT_DISCOUNT` so that the new ones decide at once.
//!
//! Tuner. Differential evolution on the controller's parameters, each scored on one repetition
//! of the scenario's reference on the estimated model (an `lti` plant built from the estimated
//! transfer function, the same plant code the plant process runs), after one repetition from
//! rest; a set that the PID stability check (`LinearModel::stabilised_by_pid`) does not pass on
//! the model with its input gain at each of `GAIN_CHECKED` times the estimate costs infinity.

use super::{Candidate, Estimate, Estimator, Tuner};
use super::{Svf, SvfDesign};
use crate::config::{ModelPrior, Scenario};
use crate::law::{Controller, ControllerSpec};
use crate::msg::PlantState;
use crate::plant::lti::LtiSpec;
use crate::reference::Reference;
use crate::sim::cost::TrackingCost;
use nalgebra::{DMatrix, DVector};

/// Smallest eigenvalue of the information matrix's correlation matrix for a fit to count.
pub const EXCITATION_MIN: f64 = 1e-6;
/// Largest relative standard deviation of the input gain for a fit to be adopted.
pub const GAIN_REL_STD_MAX: f64 = 0.05;
/// The prediction error's averaging window (s) and the ratio to the fit's residual that means
/// the plant has changed.
pub const DRIFT_WINDOW_S: f64 = 0.2;
/// Ratio of the averaged squared prediction error to the fit's residual variance past which
/// the plant has changed.
pub const DRIFT_RATIO: f64 = 10.0;
/// What is kept of the old information when a drift is detected.
pub const DRIFT_DISCOUNT: f64 = 0.01;
/// Multiples of the estimated input gain at which a candidate must keep the loop stable (a
/// 25 % change either way before the next epoch).
pub const GAIN_CHECKED: [f64; 3] = [0.8, 1.0, 1.25];
/// The smallest residual standard deviation assumed, relative to the target's rms.
const RESIDUAL_FLOOR_REL: f64 = 1e-4;
/// Seconds between fits (the estimates are recorded at this rate too).
const SOLVE_EVERY_S: f64 = 0.1;
/// The filter's start transient dies out within this many time constants 1/p.
const SETTLE_TIME_CONSTANTS: f64 = 20.0;

/// The general scheme for the scenario (validated by `config::model_prior`).
pub fn scheme(
    scn: &Scenario,
    prior: &ModelPrior,
) -> Result<(LinearEstimator, LinearTuner), crate::SchemeError> {
    let range = scn
        .plant
        .model
        .config()
        .scalar_input()
        .ok_or(crate::SchemeError::NotSiso(
            "the indirect scheme takes a plant with one input and one output",
        ))?
        .range;
    // The filters start exactly at rest on an lti plant that starts at rest; anything else
    // (an initial state, a plant of the user's own) waits for their start transient.
    let at_rest = matches!(&scn.plant.model, crate::plant::PlantModel::Lti(l) if l.x0.iter().all(|x| *x == 0.0));
    Ok((
        LinearEstimator::new(prior, scn.timing.period, at_rest),
        LinearTuner::new(scn, prior, range),
    ))
}

/// What the excitation and drift monitors saw, for the report.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Monitor {
    /// Fits adopted, and fits held back because the data did not determine them.
    pub fits_adopted: u64,
    /// Fits held back because the data did not determine them (the last adopted model kept).
    pub fits_held: u64,
    /// The last fit's excitation (smallest eigenvalue of the correlation matrix).
    pub excitation: f64,
    /// Plant times at which the drift monitor discounted the old data.
    pub drift_alarms: Vec<f64>,
    /// The model in use, [a_0 .. a_{n-1}, b_0 .. b_m]: the last fit adopted, or the prior
    /// (filled in when the monitor is read).
    pub theta: Vec<f64>,
}

/// The general scheme's estimator: continuous-time least squares through the state-variable
/// filter, with forgetting and the excitation and drift monitors (see the module).
pub struct LinearEstimator {
    n: usize,
    m: usize,
    period: f64,
    svf: SvfDesign,
    y_f: Svf,
    u_f: Svf,
    settling: usize,
    /// The plant starts at rest, so the filters' start at seq 0 is exact.
    starts_at_rest: bool,
    /// Forgetting per sample.
    lambda: f64,
    r: DMatrix<f64>,
    f: DVector<f64>,
    /// Discounted sum of target^2 and of the weights (the effective sample count).
    tt: f64,
    weight: f64,
    phi: DVector<f64>,
    /// The adopted model, its input gain's standard deviation and the fit's residual variance.
    theta: DVector<f64>,
    gain_std: f64,
    residual_var: f64,
    nominal: DVector<f64>,
    /// Prediction error of the adopted model, averaged over `DRIFT_WINDOW_S`.
    error_var: f64,
    /// The memory in samples (the effective count of a fully remembered window).
    memory_samples: f64,
    samples: u64,
    /// What the excitation and drift monitors saw (its `theta` filled in when read through
    /// `Estimator::monitor`).
    pub monitor: Monitor,
}

impl LinearEstimator {
    /// An estimator with `prior`'s structure, filter pole and memory, starting from its nominal
    /// coefficients; `period` is the control period (s), `starts_at_rest` whether the plant
    /// starts at rest (the filters' start at sample 0 is then exact).
    pub fn new(prior: &ModelPrior, period: f64, starts_at_rest: bool) -> Self {
        let (n, m) = (prior.poles(), prior.zeros);
        let d = n + m + 1;
        // theta from the prior: a_i is den's coefficient of s^i, b_j num's.
        let nominal = DVector::from_fn(d, |k, _| {
            if k < n {
                prior.den[n - k]
            } else {
                prior.num[n - (k - n)]
            }
        });
        Self {
            n,
            m,
            period,
            svf: SvfDesign::new(prior.filter_pole, period),
            y_f: Svf::default(),
            u_f: Svf::default(),
            settling: 0,
            starts_at_rest,
            lambda: (-period / prior.memory).exp(),
            r: DMatrix::zeros(d, d),
            f: DVector::zeros(d),
            tt: 0.0,
            weight: 0.0,
            phi: DVector::zeros(d),
            theta: nominal.clone(),
            gain_std: f64::INFINITY,
            residual_var: 0.0,
            nominal,
            error_var: 0.0,
            memory_samples: prior.memory / period,
            samples: 0,
            monitor: Monitor::default(),
        }
    }

    /// Feed sample `s`; `follows` when it directly follows the previous one (otherwise the
    /// filters restart on it and wait for their start transient to die out).
    pub fn push(&mut self, follows: bool, s: &PlantState) {
        if !follows {
            self.y_f = Svf::at_rest(s.y[0]);
            self.u_f = Svf::at_rest(s.u_applied[0]);
            let settle = SETTLE_TIME_CONSTANTS / self.svf.pole();
            self.settling = if s.seq == 0 && self.starts_at_rest {
                0
            } else {
                (settle / self.period).ceil() as usize
            };
            return;
        }
        let d = &self.svf;
        self.u_f.held(d, s.u_applied[0]);
        self.y_f.sampled(d, s.y[0]);
        if self.settling > 0 {
            self.settling -= 1;
            return;
        }
        let n = self.n;
        for i in 0..n {
            self.phi[i] = -self.y_f.derivative(d, i);
        }
        for j in 0..=self.m {
            self.phi[n + j] = self.u_f.derivative(d, j);
        }
        let target = self.y_f.derivative(d, n);
        self.watch_drift(s.t, target);
        let l = self.lambda;
        self.r *= l;
        self.r.ger(1.0, &self.phi, &self.phi, 1.0);
        self.f *= l;
        self.f.axpy(target, &self.phi, 1.0);
        self.tt = l * self.tt + target * target;
        self.weight = l * self.weight + 1.0;
        self.samples += 1;
        if self
            .samples
            .is_multiple_of((SOLVE_EVERY_S / self.period).round().max(1.0) as u64)
        {
            self.solve();
        }
    }

    /// The drift monitor: the adopted model's prediction error against the fit's residual.
    fn watch_drift(&mut self, t: f64, target: f64) {
        let e = target - self.theta.dot(&self.phi);
        let w = (self.period / DRIFT_WINDOW_S).min(1.0);
        self.error_var += w * (e * e - self.error_var);
        // Armed once the fit rests on half a memory of data (at the start, and again after an
        // alarm discounted the old data): a fit on a fraction of a transient underestimates its
        // own residual.
        let armed = self.monitor.fits_adopted > 0 && self.weight >= 0.5 * self.memory_samples;
        if armed && self.error_var > DRIFT_RATIO * self.residual_var {
            self.r *= DRIFT_DISCOUNT;
            self.f *= DRIFT_DISCOUNT;
            self.tt *= DRIFT_DISCOUNT;
            self.weight *= DRIFT_DISCOUNT;
            self.monitor.drift_alarms.push(t);
        }
    }

    /// Re-solve theta = R^-1 f and adopt it when the excitation monitor passes it.
    fn solve(&mut self) {
        let d = self.r.nrows();
        let diag: Vec<f64> = (0..d)
            .map(|i| self.r[(i, i)].max(f64::MIN_POSITIVE).sqrt())
            .collect();
        let corr = DMatrix::from_fn(d, d, |i, j| self.r[(i, j)] / (diag[i] * diag[j]));
        let excitation = corr.symmetric_eigenvalues().min();
        self.monitor.excitation = excitation;
        let Some(inv) = (excitation > EXCITATION_MIN)
            .then(|| self.r.clone().cholesky())
            .flatten()
            .map(|c| c.inverse())
        else {
            self.monitor.fits_held += 1;
            return;
        };
        let theta = &inv * &self.f;
        // The residual's variance: (sum target^2 - theta . f) over the effective count.
        let dof = (self.weight - d as f64).max(1.0);
        // Floored at 1e-4 of the target's rms: an ideal sensor's residual is the filter's
        // discretisation error, and a drift test against it would fire on rounding.
        let floor = RESIDUAL_FLOOR_REL * RESIDUAL_FLOOR_REL * self.tt / self.weight.max(1.0);
        let var = ((self.tt - theta.dot(&self.f)) / dof).max(floor);
        let g = self.n + self.m;
        let gain_std = (var * inv[(g, g)]).max(0.0).sqrt();
        if !(theta.iter().all(|v| v.is_finite()) && gain_std <= GAIN_REL_STD_MAX * theta[g].abs()) {
            self.monitor.fits_held += 1;
            return;
        }
        self.theta = theta;
        self.gain_std = gain_std;
        self.residual_var = var;
        self.monitor.fits_adopted += 1;
    }

    /// A fit has been adopted.
    pub fn ready(&self) -> bool {
        self.monitor.fits_adopted > 0
    }

    /// The input gain b_m (the transfer function's leading numerator coefficient, den monic)
    /// and its standard deviation.
    pub fn estimate(&self, t: f64) -> Estimate {
        Estimate {
            t,
            value: self.theta[self.n + self.m],
            std: self.gain_std,
        }
    }
}

impl Estimator for LinearEstimator {
    fn observe(&mut self, prev: Option<&PlantState>, s: &PlantState) {
        self.push(prev.is_some(), s);
    }
    fn estimate(&self, t: f64) -> Estimate {
        LinearEstimator::estimate(self, t)
    }
    fn ready(&self) -> bool {
        LinearEstimator::ready(self)
    }
    fn nominal(&self) -> f64 {
        self.nominal[self.n + self.m]
    }
    fn coefficients(&self) -> Vec<f64> {
        self.theta.iter().copied().collect()
    }
    fn nominal_coefficients(&self) -> Vec<f64> {
        self.nominal.iter().copied().collect()
    }
    fn monitor(&self) -> Option<Monitor> {
        Some(Monitor {
            theta: self.coefficients(),
            ..self.monitor.clone()
        })
    }
    fn transfer_function(&self) -> Option<(Vec<f64>, Vec<f64>)> {
        let theta: Vec<f64> = self.theta.iter().copied().collect();
        self.ready()
            .then(|| transfer_function(self.n, self.m, &theta))
    }
}

/// (num, den), descending powers, den monic, from theta = [a_0 .. a_{n-1}, b_0 .. b_m].
pub fn transfer_function(n: usize, m: usize, theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut den = vec![1.0; n + 1];
    for i in 0..n {
        den[n - i] = theta[i];
    }
    let mut num = vec![0.0; n + 1];
    for j in 0..=m {
        num[n - j] = theta[n + j];
    }
    (num, den)
}

/// The closed loop a candidate is scored on, all but the model's coefficients.
#[derive(Debug, Clone)]
pub struct LoopModel {
    n: usize,
    m: usize,
    period: f64,
    step: f64,
    /// The plant's declared sensor delay, samples: the model's runs measure as the plant does.
    sensor_delay: usize,
    u_range: (f64, f64),
    controller: ControllerSpec,
    reference: Reference,
    duration: f64,
    score_from: f64,
    w: f64,
}

impl LoopModel {
    /// The estimated transfer function (num, den), descending powers, from theta.
    pub fn transfer_function(&self, theta: &[f64]) -> (Vec<f64>, Vec<f64>) {
        transfer_function(self.n, self.m, theta)
    }

    fn plant(&self, theta: &[f64]) -> Option<LtiSpec> {
        let (num, den) = self.transfer_function(theta);
        LtiSpec::from_transfer_function(&num, &den, self.period, self.u_range).ok()
    }

    /// Whether the set keeps the sampled loop stable on the model, its input gain at each of
    /// `GAIN_CHECKED` times the estimate's: the controller's own check (`Controller::stabilises`
    /// on `LinearModel::sampled_transfer_function`), which it applies to the estimates it adopts.
    pub fn stable(&self, theta: &[f64], params: &[f64]) -> bool {
        self.stable_under(self.controller.build(self.period).as_ref(), theta, params)
    }

    fn stable_under(&self, law: &dyn Controller, theta: &[f64], params: &[f64]) -> bool {
        let (num, den) = self.transfer_function(theta);
        GAIN_CHECKED.iter().all(|g| {
            let scaled: Vec<f64> = num.iter().map(|b| b * g).collect();
            crate::law::LinearModel::sampled_transfer_function(&scaled, &den, self.period)
                .is_some_and(|lm| law.stabilises(&lm, params))
        })
    }

    /// Cost of `params` on the model with coefficients `theta`: sum |r - y| + w |u| per sample
    /// over the second repetition; infinite when the loop is not stable or is lost.
    pub fn cost(&self, theta: &[f64], params: &[f64]) -> f64 {
        let mut ctrl = self.controller.build(self.period);
        if !self.stable_under(ctrl.as_ref(), theta, params) {
            return f64::INFINITY;
        }
        let Some(plant) = self.plant(theta) else {
            return f64::INFINITY;
        };
        ctrl.swap_params(
            params,
            &PlantState::default(),
            &crate::reference::Setpoint::default(),
        );
        let run = crate::sim::Run {
            reference: &self.reference,
            period: self.period,
            step: self.step,
            duration: self.duration,
            diverged: 1e6,
            noise_std: 0.0,
            seed: 0,
            sensor_delay: self.sensor_delay,
            u0: 0.0,
        }
        .response(Box::new(plant), ctrl);
        let n = (self.duration / self.period).round() as usize;
        if run.y.len() < n {
            return f64::INFINITY;
        }
        let mut cost = TrackingCost::new(self.w);
        for k in 0..n {
            if run.t[k] + 1e-9 >= self.score_from {
                cost.add(&run.r[k..=k], &run.y[k..=k], &run.u[k..=k]);
            }
        }
        cost.total
    }
}

/// The DE's objective: the set's cost on the model with coefficients `theta`.
pub struct LinearCost<'a> {
    /// The closed loop the set runs in, all but the coefficients.
    pub model: &'a LoopModel,
    /// The model's coefficients, [a_0 .. a_{n-1}, b_0 .. b_m].
    pub theta: Vec<f64>,
}

impl crate::optim::Objective for LinearCost<'_> {
    fn value(&self, params: &[f64]) -> f64 {
        self.model.cost(&self.theta, params)
    }
}

/// The general scheme's tuner: epochs of DE on the controller's parameters, on the model with
/// the estimated transfer function.
pub struct LinearTuner {
    /// The closed loop candidates are scored on, all but the model's coefficients.
    pub model: LoopModel,
    de: super::DeEpochs,
    margin: f64,
    previous_best: Option<Vec<f64>>,
}

impl LinearTuner {
    /// The tuner for the scenario: DE within the controller's bounds, each candidate scored on
    /// the model over the second repetition of a square-wave reference (else over the run's
    /// first 10 s at most); `u_range` is the plant's input range.
    pub fn new(scn: &Scenario, prior: &ModelPrior, u_range: (f64, f64)) -> Self {
        // Scored on the second repetition of a periodic reference, which starts where the first
        // left the loop, as every repetition after the first does on the plant.
        let (duration, score_from) = match &scn.reference {
            Reference::Square { period, start, .. } => (start + 2.0 * period, start + period),
            _ => (scn.timing.duration.min(10.0), 0.0),
        };
        Self {
            model: LoopModel {
                n: prior.poles(),
                m: prior.zeros,
                period: scn.timing.period,
                step: scn.plant.step,
                sensor_delay: scn.plant.sensor_delay as usize,
                u_range,
                controller: scn.controller.clone(),
                reference: scn.reference.clone(),
                duration,
                score_from,
                w: scn.optimiser.cost_u_weight,
            },
            de: super::DeEpochs::new(scn, &scn.controller.tunable().bounds),
            margin: scn.optimiser.margin,
            previous_best: None,
        }
    }
}

impl Tuner for LinearTuner {
    fn epoch(&mut self, p: f64, theta: &[f64], in_service: &[f64]) -> Candidate {
        let mut seeds = vec![in_service.to_vec()];
        seeds.extend(self.previous_best.clone());
        let f = LinearCost {
            model: &self.model,
            theta: theta.to_vec(),
        };
        let (best, value) = self.de.run(&seeds, &f);
        self.previous_best = Some(best.clone());
        Candidate {
            params: best,
            expected_cost: value,
            in_service_cost: self.model.cost(theta, in_service),
            model_value: p,
        }
    }
    fn margin(&self) -> f64 {
        self.margin
    }
    fn epoch_evaluations(&self) -> usize {
        self.de.evaluations
    }
    fn checked_model(&self, _: f64, theta: &[f64]) -> Option<crate::law::LinearModel> {
        let (num, den) = self.model.transfer_function(theta);
        crate::law::LinearModel::sampled_transfer_function(&num, &den, self.model.period)
    }
}
