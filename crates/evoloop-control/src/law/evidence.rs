//! Each identified model's evidence from the running loop (beyond the RKGNN paper): how well it
//! explains, joint by joint, the motion the torque the loop applies produces, from measured
//! data only.
//!
//! The paper's memberships (eqs. 19-20) say which model was identified nearest the reference;
//! they cannot say whether that model is a good one. The loop knows more: the torque it applied
//! (its own command, no torque sensor needed) and the encoders' positions. Model i's residual
//!   r_i = M-hat_i(q) q'' + V-hat_i(q, q') + G-hat_i(q) - tau
//! is zero for a perfect model (but for the arm's unmodelled friction, common to all), and
//! a_i = M-hat_i^-1 r_i is the acceleration by which the model misses the motion: under
//! computed torque on model i, e'' + K_v e' + K_p e = -a_i, so a_i is what the tracking error
//! answers to. (In torque units r_i would count against a model with a larger M-hat the larger
//! residual that comes with the higher effective gain that also makes it track better.)
//!
//! q' and q'' are not measured: the positions and the applied torque pass through the same
//! critically damped state-variable filter F = lambda^2 / (s + lambda)^2, whose states give
//! F y, (F y)' and (F y)'' without differencing noise, and the residual is taken on the
//! filtered signals (exact for the linear terms, a good approximation for the others while
//! lambda is well above the motion's bandwidth). Each a_ij^2 is averaged with a memory of
//! `memory` s per model and joint: E_ij.
//!
//! The law then weights the models per joint by prior x evidence, at full evidence
//! w_ij ∝ s_i / E_ij (inverse variance weighting, the combination of unbiased estimates with
//! the least variance; `weights` eases into it from the prior), with
//! s_i the prior: uniform (the default) or the memberships' blend (`evidence_prior`). On joint
//! j a model that misses the motion counts for little, whatever its membership. Until every
//! model has been evaluated after the filter's warm-up, the weights are the prior's.
//!
//! Cost: the filter is 4 multiply-adds per joint and signal per cycle; one model is evaluated
//! (M-hat, V-hat, G-hat and an n x n solve) every cycle at most, each model once every `stride`
//! cycles (1 ms, or the number of models if more periods: 3 ms for three models at 1 kHz). No
//! allocation after construction. A model that replaces another in its slot (identify mode)
//! inherits the slot's evidence, which its own residuals replace over the memory: the weights
//! do not jump when it arrives.

use crate::filter::{Svf, SvfDesign};
use crate::MAX_JOINTS;
use evoloop_rkgnn::RkgnnModel;

use super::fuzzy_computed_torque::MAX_MODELS;

/// Default filter bandwidth lambda, rad/s: ten times a 0.8 Hz motion's angular frequency.
pub const BANDWIDTH: f64 = 50.0;
/// Default memory of the averaged squared residual, s.
pub const MEMORY: f64 = 0.5;
/// Each model's residual is evaluated about this often, s (at least one period per model).
const EVALUATION_PERIOD: f64 = 0.001;
/// The filter's start-up is this many time constants 1/lambda: no evidence before.
const WARMUP_TIME_CONSTANTS: f64 = 10.0;

/// The residuals' filter: the state-variable filter lambda^2 / (s + lambda)^2 (critically
/// damped), its input held over each period; its states are [F v, (F v)'].
///
/// (F v)'' is taken as the change of (F v)' over the period divided by it: the mean over the
/// period (`mean_acceleration`). The filter equation's value at the sample, lambda^2 (v - F v) -
/// 2 lambda (F v)', would carry the staircase's ripple, lambda^2 times half a step of v: at 1 kHz
/// and lambda = 50 rad/s, about 1 rad/s^2 for a joint moving at 1 rad/s, more than a poor model's
/// error.
type Filter = SvfDesign<2>;

/// The mean of (F v)'' over the period from state `before` to `now`.
fn mean_acceleration(filter: &Filter, before: &Svf<2>, now: &Svf<2>) -> f64 {
    (now.derivative(filter, 1) - before.derivative(filter, 1)) / filter.period()
}

/// The evidence of up to `MAX_MODELS` models on `n` joints.
pub struct Evidence {
    filter: Filter,
    n: usize,
    /// Filtered positions and torques, [F v, (F v)'] per joint, now and one period before.
    y: [Svf<2>; MAX_JOINTS],
    tau: [Svf<2>; MAX_JOINTS],
    y_before: [Svf<2>; MAX_JOINTS],
    tau_before: [Svf<2>; MAX_JOINTS],
    /// The positions of the last sample, and its sequence number.
    y_last: [f64; MAX_JOINTS],
    seq_last: Option<u64>,
    /// E_ij: the averaged squared acceleration residual, per model and joint, over `count[i]`
    /// evaluations.
    e: [[f64; MAX_JOINTS]; MAX_MODELS],
    count: [u64; MAX_MODELS],
    /// Averaging weight per evaluation once the memory is full.
    alpha: f64,
    stride: u64,
    warmup: u64,
    /// Cycles since the filter (re)started at rest.
    k: u64,
}

impl Evidence {
    /// For `models` models on `n` joints at `period` s, filter bandwidth `lambda` rad/s and
    /// memory `memory` s.
    ///
    /// # Panics
    ///
    /// If `models` is not 1..=`MAX_MODELS`, `n` above `MAX_JOINTS`, or `lambda` or `period` not
    /// positive (the rule's table is checked before: `evidence_bandwidth` must be positive).
    pub fn new(models: usize, n: usize, period: f64, lambda: f64, memory: f64) -> Self {
        assert!((1..=MAX_MODELS).contains(&models) && n <= MAX_JOINTS);
        let stride = ((EVALUATION_PERIOD / period).round() as u64).max(models as u64);
        Self {
            filter: Filter::new(lambda, period),
            n,
            y: [Svf::default(); MAX_JOINTS],
            tau: [Svf::default(); MAX_JOINTS],
            y_before: [Svf::default(); MAX_JOINTS],
            tau_before: [Svf::default(); MAX_JOINTS],
            y_last: [0.0; MAX_JOINTS],
            seq_last: None,
            e: [[0.0; MAX_JOINTS]; MAX_MODELS],
            count: [0; MAX_MODELS],
            alpha: (stride as f64 * period / memory).min(1.0),
            stride,
            warmup: (WARMUP_TIME_CONSTANTS / (lambda * period)).ceil() as u64,
            k: 0,
        }
    }

    /// One cycle on sample `seq`: filter the measured positions `y` and the torque applied
    /// over the last period `tau`, and, on a model's turn, update its evidence.
    ///
    /// The torque was held over the period that ended at this sample, so the motion it explains
    /// is that period's middle: the positions enter the filter as the mean of this sample and
    /// the last (one period of misalignment is, at 1 kHz, a torque error of G-hat's rate of
    /// change times 1 ms: on a light joint, an acceleration error as large as a poor model's),
    /// and the residual is taken on the filters' states halfway through the period, where
    /// their mean second derivative belongs.
    ///
    /// A sample seen before (the cycle may step a law twice on one sample) changes nothing; a
    /// sample after a gap, or a value that is not finite, restarts the filters at rest and
    /// their warm-up, keeping the evidence gathered.
    pub fn update(&mut self, models: &[RkgnnModel], seq: u64, y: &[f64], tau: &[f64]) {
        let n = self.n;
        if self.seq_last == Some(seq) {
            return;
        }
        let finite = y[..n].iter().chain(&tau[..n]).all(|v| v.is_finite());
        if !finite || self.seq_last.is_some_and(|s| seq != s.wrapping_add(1)) {
            self.k = 0;
        }
        self.seq_last = Some(seq);
        if !finite {
            return;
        }
        if self.k == 0 {
            // At rest on this sample: no step into the filter.
            for j in 0..n {
                self.y[j] = Svf::at_rest(y[j]);
                self.tau[j] = Svf::at_rest(tau[j]);
                self.y_last[j] = y[j];
            }
        }
        self.y_before = self.y;
        self.tau_before = self.tau;
        for j in 0..n {
            let mid = 0.5 * (y[j] + self.y_last[j]);
            self.y_last[j] = y[j];
            self.y[j].held(&self.filter, mid);
            self.tau[j].held(&self.filter, tau[j]);
        }
        let turn = (self.k % self.stride) as usize;
        self.k += 1;
        if self.k <= self.warmup || turn >= models.len() {
            return;
        }
        self.evaluate(turn, &models[turn]);
    }

    /// Model `i`'s acceleration residual on the filtered signals at the last period's middle,
    /// into its average (a running mean until the memory is full, so that no single sample
    /// sets it).
    fn evaluate(&mut self, i: usize, model: &RkgnnModel) {
        let n = self.n;
        let mut x = [0.0; 2 * MAX_JOINTS];
        let mut acc = [0.0; MAX_JOINTS];
        for j in 0..n {
            let f = &self.filter;
            let mid = |now: &Svf<2>, before: &Svf<2>, d: usize| {
                0.5 * (now.derivative(f, d) + before.derivative(f, d))
            };
            x[j] = mid(&self.y[j], &self.y_before[j], 0);
            x[n + j] = mid(&self.y[j], &self.y_before[j], 1);
            acc[j] = mid(&self.tau[j], &self.tau_before[j], 0);
        }
        // acc <- M-hat^-1 (tau - V-hat - G-hat): the model's acceleration for the torque.
        let net = &model.net;
        if !evoloop_rkgnn::network::acceleration(
            &net.layout,
            net.params(),
            &x[..2 * n],
            &mut acc[..n],
        ) {
            return;
        }
        let a2 = |j: usize| {
            let qdd = mean_acceleration(&self.filter, &self.y_before[j], &self.y[j]);
            (acc[j] - qdd).powi(2)
        };
        if (0..n).any(|j| !a2(j).is_finite()) {
            return;
        }
        self.count[i] += 1;
        let rate = self.alpha.max(1.0 / self.count[i] as f64);
        for j in 0..n {
            self.e[i][j] += rate * (a2(j) - self.e[i][j]);
        }
    }

    /// Per joint, the weights of the models (`w[i * MAX_JOINTS + j]`, summing to 1 over i for
    /// each joint) from the normalised `prior` and the evidence:
    ///   w_ij ∝ prior_i (E_min,j / E_ij)^rho,
    /// with rho rising from 0 to 1 over the first memory's evaluations, so that the evidence
    /// takes the law over smoothly from the prior. A model not yet evaluated counts as the
    /// worst evaluated one; the prior alone before any evaluation.
    pub fn weights(&self, prior: &[f64], w: &mut [f64]) {
        let (n, models) = (self.n, prior.len());
        let most = self.count[..models].iter().copied().max().unwrap_or(0);
        let rho = (most as f64 * self.alpha).min(1.0);
        let prior_sum: f64 = prior.iter().sum();
        for j in 0..n {
            let (best, worst) = (0..models)
                .filter(|&i| self.count[i] > 0)
                .map(|i| self.e[i][j])
                .fold((f64::INFINITY, 0.0f64), |(b, w), e| (b.min(e), w.max(e)));
            let mut sum = 0.0;
            for (i, p) in prior.iter().enumerate() {
                let e = if self.count[i] > 0 {
                    self.e[i][j]
                } else {
                    worst
                };
                let factor = if rho > 0.0 && e > 0.0 {
                    (best / e).powf(rho)
                } else {
                    1.0
                };
                w[i * MAX_JOINTS + j] = p * factor;
                sum += p * factor;
            }
            for (i, p) in prior.iter().enumerate() {
                let x = &mut w[i * MAX_JOINTS + j];
                *x = if sum > 0.0 && sum.is_finite() {
                    *x / sum
                } else {
                    p / prior_sum
                };
            }
        }
    }

    /// Evaluations of model `i` so far.
    pub fn evaluations(&self, i: usize) -> u64 {
        self.count[i]
    }

    /// E_ij (0: not evaluated yet).
    pub fn squared_residual(&self, model: usize, joint: usize) -> f64 {
        self.e[model][joint]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const H: f64 = 1e-3;

    fn shipped(k: usize) -> RkgnnModel {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../config/models/arm3_train{k}.json"));
        RkgnnModel::load(&p).unwrap()
    }

    /// The test arm's motion: q, q', q'' at t (sines about arm3's training region).
    fn motion(t: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
        let (off, a, f) = ([0.2, 0.7, -1.3], 0.3, [0.5, 0.3, 0.4]);
        let (mut q, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        for j in 0..3 {
            let w = 2.0 * std::f64::consts::PI * f[j];
            q[j] = off[j] + a * (w * t).sin();
            qd[j] = a * w * (w * t).cos();
            qdd[j] = -a * w * w * (w * t).sin();
        }
        (q, qd, qdd)
    }

    /// The torque of an "arm" that is `truth` (M q'' + V + G) at t.
    fn torque(truth: &RkgnnModel, t: f64) -> [f64; 3] {
        let (q, qd, qdd) = motion(t);
        let (mut m, mut v, mut g) = ([0.0; MAX_JOINTS * MAX_JOINTS], [0.0; 3], [0.0; 3]);
        truth.net.inertia_and_velocity(&q, &qd, &mut m, &mut v);
        truth.net.gravity(&q, &mut g);
        std::array::from_fn(|j| (0..3).map(|c| m[j * 3 + c] * qdd[c]).sum::<f64>() + v[j] + g[j])
    }

    /// Feed `ev` the samples `seqs` of the arm `truth` at 1 kHz as a loop would: positions read
    /// by an encoder with 1e-4 rad of noise, and the torque held over the period that ended at
    /// each sample (the arm's at that period's middle).
    fn feed(
        ev: &mut Evidence,
        models: &[RkgnnModel],
        truth: &RkgnnModel,
        seqs: std::ops::Range<u64>,
    ) {
        for k in seqs {
            let t = k as f64 * H;
            let mut y = motion(t).0;
            let mut seed = k.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xD1B5_4A32_D192_ED03;
            for yj in &mut y {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                *yj += 2e-4 * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            }
            let tau = if k == 0 {
                [0.0; 3]
            } else {
                torque(truth, t - H / 2.0)
            };
            ev.update(models, k, &y, &tau);
        }
    }

    fn evidence_of(models: &[RkgnnModel], truth: &RkgnnModel) -> Evidence {
        let mut ev = Evidence::new(models.len(), 3, H, BANDWIDTH, MEMORY);
        feed(&mut ev, models, truth, 0..4000);
        ev
    }

    #[test]
    fn the_model_that_moves_like_the_arm_gets_the_weight_on_every_joint() {
        // Either order: the evidence knows no favourite slot.
        let (one, two) = (shipped(1), shipped(2));
        for (models, right) in [([one.clone(), two.clone()], 0), ([two, one.clone()], 1)] {
            let ev = evidence_of(&models, &one);
            let mut w = [0.0; MAX_MODELS * MAX_JOINTS];
            ev.weights(&[0.5, 0.5], &mut w);
            for j in 0..3 {
                let (good, bad) = (
                    ev.squared_residual(right, j),
                    ev.squared_residual(1 - right, j),
                );
                eprintln!(
                    "joint {j}: E {good:.3e} vs {bad:.3e}, weight {}",
                    w[right * MAX_JOINTS + j]
                );
                // The arm's own model misses only by the encoder noise through the filter
                // (about 0.1 rad/s^2).
                assert!(good > 0.0 && good < 0.05, "joint {j}: {good}");
                assert!(good < 0.05 * bad, "joint {j}: {good} vs {bad}");
                assert!(w[right * MAX_JOINTS + j] > 0.95, "joint {j}");
                let sum = w[j] + w[MAX_JOINTS + j];
                assert!((sum - 1.0).abs() < 1e-12);
            }
            // A prior of 0 keeps a model out whatever its evidence.
            ev.weights(&[0.0, 1.0], &mut w);
            assert!((0..3).all(|j| w[j] == 0.0 && w[MAX_JOINTS + j] == 1.0));
        }
    }

    #[test]
    fn the_prior_rules_until_the_filter_settles_then_every_model_is_evaluated() {
        let (one, two) = (shipped(1), shipped(2));
        let models = [one.clone(), two];
        let mut ev = Evidence::new(2, 3, H, BANDWIDTH, MEMORY);
        // 10 / lambda = 0.2 s at 1 kHz: 200 cycles of warm-up.
        feed(&mut ev, &models, &one, 0..200);
        let mut w = [0.0; MAX_MODELS * MAX_JOINTS];
        ev.weights(&[0.25, 0.75], &mut w);
        assert_eq!((w[0], w[MAX_JOINTS]), (0.25, 0.75));
        assert_eq!((ev.evaluations(0), ev.evaluations(1)), (0, 0));
        // One round later (stride 2 at 1 kHz) each model has been evaluated once, and the
        // evidence has barely begun to move the weights away from the prior.
        feed(&mut ev, &models, &one, 200..202);
        assert_eq!((ev.evaluations(0), ev.evaluations(1)), (1, 1));
        ev.weights(&[0.25, 0.75], &mut w);
        assert!((w[0] - 0.25).abs() < 0.02 && w[0] >= 0.25, "{}", w[0]);
    }

    #[test]
    fn a_repeated_sample_changes_nothing_and_a_gap_or_a_nan_restarts_the_filters() {
        let (one, two) = (shipped(1), shipped(2));
        let models = [one.clone(), two];
        let mut once = Evidence::new(2, 3, H, BANDWIDTH, MEMORY);
        feed(&mut once, &models, &one, 0..1000);
        // Every sample twice (a law stepped again on the same sample): the same evidence.
        let mut twice = Evidence::new(2, 3, H, BANDWIDTH, MEMORY);
        for k in 0..1000 {
            feed(&mut twice, &models, &one, k..k + 1);
            feed(&mut twice, &models, &one, k..k + 1);
        }
        for i in 0..2 {
            assert_eq!(once.evaluations(i), twice.evaluations(i));
            for j in 0..3 {
                assert_eq!(once.squared_residual(i, j), twice.squared_residual(i, j));
            }
        }
        // 50 samples lost: no evaluation for the next warm-up, the evidence kept, then on.
        let before = once.evaluations(0);
        feed(&mut once, &models, &one, 1050..1250);
        assert_eq!(once.evaluations(0), before);
        feed(&mut once, &models, &one, 1250..3000);
        assert!(once.evaluations(0) > before);
        // A torque that is not finite: the filters restart; nothing turns to NaN.
        once.update(&models, 3000, &[0.2, 0.7, -1.3], &[f64::NAN, 0.0, 0.0]);
        feed(&mut once, &models, &one, 3001..5000);
        let mut w = [0.0; MAX_MODELS * MAX_JOINTS];
        once.weights(&[0.5, 0.5], &mut w);
        for (j, wj) in w[..3].iter().enumerate() {
            assert!(once.squared_residual(0, j).is_finite());
            assert!(*wj > 0.95, "joint {j}: {wj}");
        }
    }

    #[test]
    fn the_filter_has_unit_gain_and_its_states_are_the_derivatives_of_its_output() {
        // A ramp v = c t after the transient: F v = c (t - 2 / lambda), (F v)' = c, (F v)'' = 0.
        let (lambda, h, c) = (50.0, 1e-4, 0.7);
        let f = Filter::new(lambda, h);
        let mut x = Svf::<2>::at_rest(0.0);
        let steps = 20_000;
        let mut acc = 0.0f64;
        for k in 1..=steps {
            let before = x;
            x.held(&f, c * k as f64 * h);
            acc = mean_acceleration(&f, &before, &x);
        }
        assert!(acc.abs() < 1e-6, "{acc}");
        let t = steps as f64 * h;
        // (Each sample is held over the period it ends: within a period of the ramp.)
        let want = c * (t - 2.0 / lambda);
        let (value, rate) = (x.derivative(&f, 0), x.derivative(&f, 1));
        assert!((value - want).abs() < c * h, "{value} vs {want}");
        // (Within a period the staircase's slope ripples by about c (lambda h)^2.)
        assert!((rate - c).abs() < 1e-5 * c, "{rate}");
        // A sine well inside the band: (F v)'' follows -w^2 sin within the filter's phase, at
        // the middle of the period (from rest: the start is forgotten long before t = 1 s).
        let w = 2.0;
        let mut x = Svf::<2>::at_rest(0.0);
        let mut worst: f64 = 0.0;
        for k in 1..=steps {
            let t = k as f64 * h;
            let before = x;
            x.held(&f, (w * t).sin());
            let acc = mean_acceleration(&f, &before, &x);
            if t > 1.0 {
                // F at w: magnitude 1 / (1 + (w/lambda)^2), phase -2 atan(w/lambda).
                let phase = 2.0 * (w / lambda).atan();
                let mid = t - h / 2.0;
                let want = -w * w * (w * mid - phase).sin() / (1.0 + (w / lambda).powi(2));
                worst = worst.max((acc - want).abs());
            }
        }
        assert!(worst < 0.01 * w * w, "worst {worst}");
    }
}
