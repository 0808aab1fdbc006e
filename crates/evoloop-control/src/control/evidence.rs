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
//! The law then weights the models per joint by prior x evidence, w_ij ∝ s_i / E_ij (inverse
//! variance weighting, the combination of unbiased estimates with the least variance), with
//! s_i the prior: uniform (the default) or the memberships' blend (`evidence_prior`). On joint
//! j a model that misses the motion counts for little, whatever its membership. Until every
//! model has been evaluated after the filter's warm-up, the weights are the prior's.
//!
//! Cost: the filter is 4 multiply-adds per joint and signal per cycle; one model is evaluated
//! (M-hat, V-hat, G-hat and an n x n solve) every cycle at most, each model once every `stride`
//! cycles (about 1 ms). No allocation after construction.

use crate::linalg::Mat;
use crate::MAX_JOINTS;
use evoloop_rkgnn::RkgnnModel;

use super::fuzzy_computed_torque::MAX_MODELS;

/// Default filter bandwidth lambda, rad/s: ten times a 0.8 Hz motion's angular frequency.
pub const BANDWIDTH: f64 = 50.0;
/// Default memory of the averaged squared residual, s.
pub const MEMORY: f64 = 0.5;
/// Each model's residual is evaluated about this often, s.
const EVALUATION_PERIOD: f64 = 0.001;
/// The filter's start-up is this many time constants 1/lambda: no evidence before.
const WARMUP_TIME_CONSTANTS: f64 = 10.0;

/// A critically damped second-order state-variable filter discretised exactly for an input
/// held over each period: x = [F v, (F v)'].
///
/// (F v)'' is taken as the change of (F v)' over the period divided by it: the mean over the
/// period. The filter equation's value at the sample, lambda^2 (v - F v) - 2 lambda (F v)',
/// would carry the staircase's ripple, lambda^2 times half a step of v: at 1 kHz and lambda =
/// 50 rad/s, about 1 rad/s^2 for a joint moving at 1 rad/s, more than a poor model's error.
#[derive(Debug, Clone, Copy)]
struct Filter {
    period: f64,
    phi: [[f64; 2]; 2],
    gamma: [f64; 2],
}

impl Filter {
    fn new(lambda: f64, period: f64) -> Self {
        let lh = lambda * period;
        let e = (-lh).exp();
        // exp(A h) for A = [[0, 1], [-lambda^2, -2 lambda]].
        let phi = [
            [e * (1.0 + lh), e * period],
            [-e * lambda * lh, e * (1.0 - lh)],
        ];
        // A held input u settles at x = [u, 0]: gamma = (I - phi) [1, 0]^T (unit DC gain).
        let gamma = [1.0 - phi[0][0], -phi[1][0]];
        Self { period, phi, gamma }
    }

    /// Advance one period with `v` held over it; the mean of (F v)'' over the period.
    fn step(&self, x: &mut [f64; 2], v: f64) -> f64 {
        let [a, b] = *x;
        x[0] = self.phi[0][0] * a + self.phi[0][1] * b + self.gamma[0] * v;
        x[1] = self.phi[1][0] * a + self.phi[1][1] * b + self.gamma[1] * v;
        (x[1] - b) / self.period
    }
}

/// The evidence of up to `MAX_MODELS` models on `n` joints.
pub struct Evidence {
    filter: Filter,
    n: usize,
    /// Filtered positions and torques, [F v, (F v)'] per joint.
    y: [[f64; 2]; MAX_JOINTS],
    tau: [[f64; 2]; MAX_JOINTS],
    /// (F y)'' over the last period.
    y_acc: [f64; MAX_JOINTS],
    /// The positions of the last sample.
    y_last: [f64; MAX_JOINTS],
    /// E_ij: the averaged squared residual, per model and joint; 0 until first evaluated.
    e: [[f64; MAX_JOINTS]; MAX_MODELS],
    /// Averaging weight per evaluation.
    alpha: f64,
    stride: u64,
    warmup: u64,
    k: u64,
}

impl Evidence {
    /// For `models` models on `n` joints at `period` s, filter bandwidth `lambda` rad/s and
    /// memory `memory` s.
    pub fn new(models: usize, n: usize, period: f64, lambda: f64, memory: f64) -> Self {
        assert!((1..=MAX_MODELS).contains(&models) && n <= MAX_JOINTS);
        let stride = ((EVALUATION_PERIOD / period).round() as u64).max(models as u64);
        Self {
            filter: Filter::new(lambda, period),
            n,
            y: [[0.0; 2]; MAX_JOINTS],
            tau: [[0.0; 2]; MAX_JOINTS],
            y_acc: [0.0; MAX_JOINTS],
            y_last: [0.0; MAX_JOINTS],
            e: [[0.0; MAX_JOINTS]; MAX_MODELS],
            alpha: (stride as f64 * period / memory).min(1.0),
            stride,
            warmup: (WARMUP_TIME_CONSTANTS / (lambda * period)).ceil() as u64,
            k: 0,
        }
    }

    /// One cycle: filter the measured positions `y` and the torque applied over the last
    /// period `tau`, and, on this model's turn, update one model's evidence. `m`, `v`, `g` are
    /// the caller's scratch.
    ///
    /// The torque was held over the period that ended at this sample, so the motion it explains
    /// is that period's middle: the positions enter the filter as the mean of this sample and
    /// the last (one period of misalignment is, at 1 kHz, a torque error of G-hat's rate of
    /// change times 1 ms: on a light joint, an acceleration error as large as a poor model's).
    pub fn update(
        &mut self,
        models: &[RkgnnModel],
        y: &[f64],
        tau: &[f64],
        m: &mut Mat,
        v: &mut [f64; MAX_JOINTS],
        g: &mut [f64; MAX_JOINTS],
    ) {
        let n = self.n;
        if self.k == 0 {
            // At rest on the first sample: no step into the filter.
            for j in 0..n {
                self.y[j] = [y[j], 0.0];
                self.tau[j] = [tau[j], 0.0];
                self.y_last[j] = y[j];
            }
        }
        for j in 0..n {
            let mid = 0.5 * (y[j] + self.y_last[j]);
            self.y_last[j] = y[j];
            self.y_acc[j] = self.filter.step(&mut self.y[j], mid);
            self.filter.step(&mut self.tau[j], tau[j]);
        }
        let turn = (self.k % self.stride) as usize;
        self.k += 1;
        if self.k <= self.warmup || turn >= models.len() {
            return;
        }
        let (mut q, mut qd, mut qdd) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
        for j in 0..n {
            q[j] = self.y[j][0];
            qd[j] = self.y[j][1];
            qdd[j] = self.y_acc[j];
        }
        let net = &models[turn].net;
        net.inertia_and_velocity(&q[..n], &qd[..n], m, &mut v[..n]);
        net.gravity(&q[..n], &mut g[..n]);
        // The torque residual r, then the acceleration it is under the model: M-hat^-1 r.
        let mut r = [0.0; MAX_JOINTS];
        for j in 0..n {
            let ma: f64 = (0..n).map(|c| m[j * n + c] * qdd[c]).sum();
            r[j] = ma + v[j] + g[j] - self.tau[j][0];
        }
        if !crate::linalg::small::solve(n, m, &mut r[..n]) {
            return;
        }
        for (e, a) in self.e[turn].iter_mut().zip(&r[..n]) {
            let a2 = a * a;
            *e = if *e == 0.0 {
                a2
            } else {
                *e + self.alpha * (a2 - *e)
            };
        }
    }

    /// Per joint, the weights of the models (`w[i * MAX_JOINTS + j]`, summing to 1 over i for
    /// each joint) from the memberships' blend `prior` and the evidence; the prior alone until
    /// every model has evidence.
    pub fn weights(&self, prior: &[f64], w: &mut [f64]) {
        let (n, models) = (self.n, prior.len());
        for j in 0..n {
            let ready = (0..models).all(|i| self.e[i][j] > 0.0);
            let mut sum = 0.0;
            for (i, p) in prior.iter().enumerate() {
                let x = if ready { p / self.e[i][j] } else { *p };
                w[i * MAX_JOINTS + j] = x;
                sum += x;
            }
            for i in 0..models {
                w[i * MAX_JOINTS + j] = if sum > 0.0 && sum.is_finite() {
                    w[i * MAX_JOINTS + j] / sum
                } else {
                    1.0 / models as f64
                };
            }
        }
    }

    /// E_ij of the last evaluations (0: none yet).
    pub fn squared_residual(&self, model: usize, joint: usize) -> f64 {
        self.e[model][joint]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOISE: f64 = 2e-4;
    fn shipped(k: usize) -> RkgnnModel {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../config/models/arm3_train{k}.json"));
        RkgnnModel::load(&p).unwrap()
    }

    /// Feed `models`' evidence with an "arm" that is `truth` (its torque M q'' + V + G along
    /// sines, at 1 kHz, each held over the next period as a loop's command is), its positions
    /// read by an encoder with 1e-4 rad of noise. The evidence, 4 s on.
    fn evidence_of(models: &[RkgnnModel], truth: &RkgnnModel) -> Evidence {
        let (n, h) = (3, 1e-3);
        let mut ev = Evidence::new(models.len(), n, h, BANDWIDTH, MEMORY);
        let (mut m, mut v, mut g): (Mat, _, _) = (
            [0.0; MAX_JOINTS * MAX_JOINTS],
            [0.0; MAX_JOINTS],
            [0.0; MAX_JOINTS],
        );
        let (off, a, f) = ([0.2, 0.7, -1.3], 0.3, [0.5, 0.3, 0.4]);
        let mut tau = [0.0; 3];
        let mut seed = 12345u64;
        for k in 0..4000 {
            let t = k as f64 * h;
            let (mut q, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3]);
            let mut y = [0.0; 3];
            for j in 0..n {
                let w = 2.0 * std::f64::consts::PI * f[j];
                q[j] = off[j] + a * (w * t).sin();
                qd[j] = a * w * (w * t).cos();
                qdd[j] = -a * w * w * (w * t).sin();
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                y[j] = q[j] + NOISE * ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
            }
            ev.update(models, &y, &tau, &mut m, &mut v, &mut g);
            // The next period's torque: the arm's at its middle.
            let t = t + h / 2.0;
            for j in 0..n {
                let w = 2.0 * std::f64::consts::PI * f[j];
                q[j] = off[j] + a * (w * t).sin();
                qd[j] = a * w * (w * t).cos();
                qdd[j] = -a * w * w * (w * t).sin();
            }
            truth.net.inertia_and_velocity(&q, &qd, &mut m, &mut v[..n]);
            truth.net.gravity(&q, &mut g[..n]);
            for j in 0..n {
                tau[j] = (0..n).map(|c| m[j * n + c] * qdd[c]).sum::<f64>() + v[j] + g[j];
            }
        }
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
                assert!(
                    good > 0.0 && good < 0.05 * bad,
                    "joint {j}: {good} vs {bad}"
                );
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
    fn before_the_filter_settles_the_weights_are_the_prior() {
        let models = [shipped(1), shipped(2)];
        let mut ev = Evidence::new(2, 3, 1e-3, BANDWIDTH, MEMORY);
        let (mut m, mut v, mut g): (Mat, _, _) = (
            [0.0; MAX_JOINTS * MAX_JOINTS],
            [0.0; MAX_JOINTS],
            [0.0; MAX_JOINTS],
        );
        // 10 / lambda = 0.2 s at 1 kHz: 200 cycles of warm-up.
        for _ in 0..200 {
            ev.update(
                &models,
                &[0.2, 0.7, -1.3],
                &[1.0, 2.0, 3.0],
                &mut m,
                &mut v,
                &mut g,
            );
        }
        let mut w = [0.0; MAX_MODELS * MAX_JOINTS];
        ev.weights(&[0.25, 0.75], &mut w);
        assert_eq!((w[0], w[MAX_JOINTS]), (0.25, 0.75));
        assert_eq!(ev.squared_residual(0, 0), 0.0);
    }

    #[test]
    fn the_filter_has_unit_gain_and_its_states_are_the_derivatives_of_its_output() {
        // A ramp v = c t after the transient: F v = c (t - 2 / lambda), (F v)' = c, (F v)'' = 0.
        let (lambda, h, c) = (50.0, 1e-4, 0.7);
        let f = Filter::new(lambda, h);
        let mut x = [0.0, 0.0];
        let steps = 20_000;
        let mut acc = 0.0;
        for k in 1..=steps {
            acc = f.step(&mut x, c * k as f64 * h);
        }
        assert!(acc.abs() < 1e-6, "{acc}");
        let t = steps as f64 * h;
        // (Each sample is held over the period it ends: within a period of the ramp.)
        let want = c * (t - 2.0 / lambda);
        assert!((x[0] - want).abs() < c * h, "{} vs {want}", x[0]);
        // (Within a period the staircase's slope ripples by about c (lambda h)^2.)
        assert!((x[1] - c).abs() < 1e-5 * c, "{}", x[1]);
        // A sine well inside the band: (F v)'' follows -w^2 sin within the filter's phase, at
        // the middle of the period.
        let w = 2.0;
        let mut x = [0.0, 1.0 * w];
        let mut worst: f64 = 0.0;
        for k in 1..=steps {
            let t = k as f64 * h;
            let acc = f.step(&mut x, (w * t).sin());
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
