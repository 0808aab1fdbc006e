//! State estimators for the laws that need states no sensor gives. A law knows the plant
//! through its sensor readings (`PlantState::y`, the applied command `u_applied`, the sample's
//! `seq`) and its own model; the truth fields (`x_true`, `q_true`, `qd_true`) are the
//! simulator's, there to judge a run, and no estimator reads them.
//!
//! - [`Kalman`]: the steady-state discrete Kalman filter of a single-input single-output linear
//!   model at the control period, designed once off the cycle ([`KalmanDesign::gains`]: the
//!   gains python-control's `dlqe` gives, checked in tests/estimator.rs), run in its current
//!   form, so a sample's estimate already uses that sample's measurement.
//! - [`VelocityFilter`]: joint velocities from measured positions as a servo drive makes them,
//!   differenced positions through a first-order low-pass.
//! - [`VelocityObserver`]: joint positions and velocities predicted by the law's own rigid-body
//!   model from the applied torques and corrected by the measured positions (a model-based
//!   observer; without the model's acceleration it is the alpha-beta tracker of a drive).
//!
//! All step without allocating and advance by the samples' `seq`: a sample seen again (the
//! cycle's bumpless swap and its step read the same one) is not counted twice, and samples the
//! loop never saw (realtime skips a late one, a refused one is not read) are predicted across.

use crate::dynamics::{Data, Model};
use crate::msg::{PlantState, MAX_JOINTS};
use crate::plant::{DelayLine, LinearModel, MAX_LINEAR_STATES};
use nalgebra::allocator::Allocator;
use nalgebra::{DMatrix, DVector, DefaultAllocator, Dim, OMatrix, SMatrix, U1};

const N: usize = MAX_LINEAR_STATES;

/// The most samples predicted across in one step: a longer gap is a plant that stopped, after
/// which the filter goes on from where it was rather than spinning through the gap.
const MAX_GAP: u64 = 1000;

/// Samples since the last one seen (`None` before the first); 0 for the same sample again.
fn samples_since(last: Option<u64>, seq: u64) -> Option<u64> {
    last.map(|l| seq.saturating_sub(l).min(MAX_GAP))
}

/// What a Kalman filter is designed for, as standard deviations: a disturbance entering where
/// the input does and held over a period as the input is (input units), the measurement's error
/// (output units: the sensor's noise and its quantisation), and a disturbance on every sampled
/// state each period (the states' units, one number for every state, per sample: a value is
/// tied to the model's state coordinates and to the period; 0: none).
///
/// Why the third: with the input's disturbance alone the filter trusts the model wherever the
/// input cannot move the output. A collocated sensor (the two-mass's encoder on the driven mass)
/// does not see the far mass swing at the antiresonance sqrt(k/m2), a zero of the input-to-output
/// path, and the filter's error poles settle on that zero, all but undamped (k = 0.5: -0.00009 ±
/// 0.707j): the loop is then stable for springs at most 2 % above the one designed for. A disturbance
/// on the states reaches the output through the spring, which moves those poles off the axis.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KalmanDesign {
    /// Standard deviation of the disturbance entering where the input does, held over a period as
    /// the input is (input units; > 0).
    pub process_noise: f64,
    /// Standard deviation of the measurement's error, the sensor's noise and its quantisation
    /// together (output units; > 0).
    pub measurement_noise: f64,
    /// Standard deviation of the disturbance on every sampled state, per sample (the states' units;
    /// 0, the default: none).
    #[serde(default)]
    pub state_noise: f64,
}

/// A designed steady-state filter.
#[derive(Debug, Clone)]
pub struct KalmanGains {
    /// The sampled model the filter predicts with (a continuous one discretised with the input
    /// held over the period).
    pub model: LinearModel,
    /// The measurement update's gain M = P C' (C P C' + R)^-1 (the current form's).
    pub m: Vec<f64>,
    /// The one-step predictor's gain L = A M: python-control's `dlqe` L.
    pub l: Vec<f64>,
    /// The a-priori error covariance P, the filtering Riccati equation's solution (`dlqe`'s P).
    pub p: DMatrix<f64>,
    /// The estimation error's eigenvalues, those of A - L C (inside the unit circle).
    pub poles: Vec<nalgebra::Complex<f64>>,
    /// What it was designed for: the design a filter in the cycle repeats on an estimated
    /// model (`Kalman::redesign`).
    pub design: KalmanDesign,
}

/// Why `KalmanDesign::gains` gives no filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum KalmanError {
    /// A process or measurement noise not finite and above 0, or a state noise not finite and at
    /// least 0 (process, measurement, state).
    Noise(f64, f64, f64),
    /// The model cannot be sampled at the control period.
    NotSampled,
    /// No steady state of the Riccati equation: the measured output does not see every
    /// unstable mode.
    NotDetectable,
    /// The filter's error dynamics are not stable.
    Unstable,
    /// The eigenvalues of A - L C did not converge.
    NoEigenvalues,
}

impl std::fmt::Display for KalmanError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            KalmanError::Noise(q, r, w) => write!(
                f,
                "process and measurement noise must be finite and > 0, state noise finite and \
                 >= 0 (got {q}, {r}, {w})"
            ),
            KalmanError::NotSampled => {
                f.write_str("the model cannot be sampled at the control period")
            }
            KalmanError::NotDetectable => f.write_str(
                "no steady-state filter: the measured output does not see every unstable mode \
                 (the model is not detectable from y)",
            ),
            KalmanError::Unstable => f.write_str("the filter's error dynamics are not stable"),
            KalmanError::NoEigenvalues => f.write_str("no eigenvalues of A - L C"),
        }
    }
}

impl std::error::Error for KalmanError {}

impl KalmanDesign {
    /// The filter for `model` run at `period` (s): the steady state of the filtering Riccati
    /// equation P = A P A' - A P C' (C P C' + R)^-1 C P A' + Q, with Q = G G' process_noise² +
    /// I state_noise², R = measurement_noise² and G the column through which the input reaches
    /// the plant. Off the cycle (allocates). An error says why no filter exists.
    pub fn gains(&self, model: &LinearModel, period: f64) -> Result<KalmanGains, KalmanError> {
        let (q, r, w) = (self.process_noise, self.measurement_noise, self.state_noise);
        if !(q.is_finite() && q > 0.0 && r.is_finite() && r > 0.0 && w.is_finite() && w >= 0.0) {
            return Err(KalmanError::Noise(q, r, w));
        }
        let model = model.at_period(period).ok_or(KalmanError::NotSampled)?;
        let n = model.n();
        let a = DMatrix::from_fn(n, n, |i, j| model.a(i, j));
        let c = DMatrix::from_fn(1, n, |_, j| model.c(j));
        let g = DVector::from_fn(n, |i, _| model.input_column(i));
        let gq = self.process_covariance(&g, n);
        let p = filter_riccati(&a, &c, &gq, r * r).ok_or(KalmanError::NotDetectable)?;
        let m: Vec<f64> = measurement_gain(&p, &c, r * r).iter().copied().collect();
        if !error_is_stable(&model, &m) {
            return Err(KalmanError::Unstable);
        }
        let l: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| a[(i, j)] * m[j]).sum())
            .collect();
        let error = DMatrix::from_fn(n, n, |i, j| a[(i, j)] - l[i] * c[(0, j)]);
        let poles = crate::linalg::eigen::eigenvalues(&error).ok_or(KalmanError::NoEigenvalues)?;
        Ok(KalmanGains {
            model,
            m,
            l,
            p,
            poles,
            design: *self,
        })
    }

    /// Q = G G' process_noise² + state_noise² on the first `n` states' diagonal (a padded
    /// model's other states stay without noise, so they stay zero in P). Generic as
    /// `filter_riccati`: the design off the cycle and `Kalman::redesign` in it.
    fn process_covariance<D: Dim>(&self, g: &OMatrix<f64, D, U1>, n: usize) -> OMatrix<f64, D, D>
    where
        DefaultAllocator: Allocator<D, D> + Allocator<D, U1> + Allocator<U1, D>,
    {
        let q = self.process_noise;
        let mut gq = g * g.transpose() * (q * q);
        for i in 0..n {
            gq[(i, i)] += self.state_noise * self.state_noise;
        }
        gq
    }
}

/// The measurement update's gain M = P C' (C P C' + r)^-1 of the filter whose Riccati solution
/// is `p` (generic as `filter_riccati`, for the design off the cycle and in it).
fn measurement_gain<R: Dim, D: Dim>(
    p: &OMatrix<f64, D, D>,
    c: &OMatrix<f64, R, D>,
    r: f64,
) -> OMatrix<f64, D, R>
where
    DefaultAllocator: Allocator<D, D> + Allocator<R, D> + Allocator<D, R> + Allocator<R, R>,
{
    let s = (c * p * c.transpose())[(0, 0)] + r;
    (p * c.transpose()) / s
}

/// Whether the filter's error dynamics A - L C, L = A M, of the sampled `model` with gain `m`
/// are stable (every eigenvalue inside the unit circle). Stack-only: the design checks its
/// filter with it off the cycle and `Kalman::redesign` in it.
fn error_is_stable(model: &LinearModel, m: &[f64]) -> bool {
    let n = model.n();
    let error = |i: usize, j: usize| {
        model.a(i, j) - (0..n).map(|l| model.a(i, l) * m[l]).sum::<f64>() * model.c(j)
    };
    crate::plant::linear::all_eigenvalues(n, error, |z| z.norm() < 1.0)
}

/// The stabilising solution of P = A P A' - A P C' (C P C' + r)^-1 C P A' + Q by the
/// structure-preserving doubling algorithm (quadratic convergence, where the Riccati
/// recursion would take as many steps as the slowest mode has samples), checked by its
/// residual. None when it does not converge to a finite, accurate solution.
/// Generic over the size, so that the design off the cycle (dynamic matrices, `C` 1 x n) and
/// the one in it (`Kalman::redesign`: fixed-size, zero-padded, allocation-free) are one
/// algorithm.
fn filter_riccati<R: Dim, D: Dim>(
    a: &OMatrix<f64, D, D>,
    c: &OMatrix<f64, R, D>,
    gq: &OMatrix<f64, D, D>,
    r: f64,
) -> Option<OMatrix<f64, D, D>>
where
    DefaultAllocator: Allocator<D, D> + Allocator<R, D> + Allocator<D, R> + Allocator<R, R>,
{
    let (rows, cols) = a.shape_generic();
    let id = OMatrix::<f64, D, D>::identity_generic(rows, cols);
    // The filtering equation is the control one of (A', C'): A_0 = A', G_0 = C' C / r, H_0 = Q.
    let mut ak = a.transpose();
    let mut gk = c.transpose() * c / r;
    let mut hk = gq.clone();
    for _ in 0..100 {
        let w = (&id + &gk * &hk).try_inverse()?;
        let next_h = &hk + ak.transpose() * &hk * &w * &ak;
        let next_g = &gk + &ak * &w * &gk * ak.transpose();
        let next_a = &ak * &w * &ak;
        let change = (&next_h - &hk).norm();
        (ak, gk, hk) = (next_a, next_g, next_h);
        if !hk.iter().all(|v| v.is_finite()) {
            return None;
        }
        if change <= 1e-15 * hk.norm() {
            break;
        }
    }
    let p = (&hk + hk.transpose()) * 0.5;
    let pct = &p * c.transpose();
    let s = (c * &pct)[(0, 0)] + r;
    let apct = a * &pct;
    let residual = a * &p * a.transpose() - &apct * apct.transpose() / s + gq - &p;
    (residual.norm() <= 1e-9 * p.norm().max(gq.norm())).then_some(p)
}

/// A Kalman filter in the control cycle: fixed-size, allocation-free.
#[derive(Debug, Clone)]
pub struct Kalman {
    n: usize,
    a: [[f64; N]; N],
    b: [f64; N],
    c: [f64; N],
    /// Sampled models only: y_k = C z_k + d v_{k-1}, v_k = f z_k + g u_k.
    d: f64,
    f: [f64; N],
    g: f64,
    m: [f64; N],
    /// The estimate, after the last sample's measurement, of the state that measurement is of
    /// (`delay` samples before the sample).
    x: [f64; N],
    /// The input that reached the plant over the period before the last sample, as estimated.
    v_prev: f64,
    last_seq: Option<u64>,
    /// The inputs (`u_applied`) of the last d samples, d the samples the measurement lags the
    /// state (the plant's declared `sensor_delay`): the filter runs that far behind, on the
    /// samples its measurements are of, and `ahead` predicts the present from `x` over these
    /// inputs, the d-step predictor of the delayed measurement's Kalman filter. The gains are
    /// the undelayed filter's; with the model right, the loop's poles are the state feedback's
    /// and the filter's, whatever the delay.
    inputs: DelayLine<f64>,
    /// The estimate of the state at the last sample: `x` predicted over `inputs`.
    ahead: [f64; N],
    /// What the filter is designed for and its period, for `redesign`.
    design: KalmanDesign,
    period: f64,
}

impl Kalman {
    /// The filter with `gains`, starting from the state 0 (a rest the first measurements
    /// correct), for measurements `delay` samples old.
    pub fn new(gains: &KalmanGains, delay: usize) -> Self {
        let model = &gains.model;
        let period = match model.time() {
            crate::plant::linear::Time::Sampled { period } => period,
            crate::plant::linear::Time::Continuous => unreachable!("a filter's model is sampled"),
        };
        let mut k = Self {
            n: model.n(),
            a: [[0.0; N]; N],
            b: [0.0; N],
            c: [0.0; N],
            d: 0.0,
            f: [0.0; N],
            g: 1.0,
            m: [0.0; N],
            x: [0.0; N],
            v_prev: 0.0,
            last_seq: None,
            inputs: DelayLine::new(delay, 0.0),
            ahead: [0.0; N],
            design: gains.design,
            period,
        };
        k.load(model, &gains.m);
        k
    }

    /// Predict with the sampled `model` and correct with gain `m` from now on; the estimate
    /// goes on from where it is (the states keep their meaning).
    fn load(&mut self, model: &LinearModel, m: &[f64]) {
        let n = model.n();
        let (d, f, g) = model.feedthrough();
        for i in 0..n {
            for j in 0..n {
                self.a[i][j] = model.a(i, j);
            }
            self.b[i] = model.b(i);
            self.c[i] = model.c(i);
            self.f[i] = f[i];
            self.m[i] = m[i];
        }
        (self.d, self.g) = (d, g);
    }

    /// Design the filter again for `model`, an estimate of the plant with the filter's states
    /// (the indirect scheme's), with the same noise design and period, and run on it from now
    /// on. Allocation-free, for the control cycle: the model sampled and the Riccati equation
    /// solved on fixed-size matrices (`LinearModel::at_period_fixed`, `filter_riccati`), tens
    /// of microseconds for the two-mass. False, the filter unchanged, when the model cannot be
    /// sampled or gives no stable filter.
    pub fn redesign(&mut self, model: &LinearModel) -> bool {
        let n = self.n;
        let Some(s) = model.at_period_fixed(self.period).filter(|s| s.n() == n) else {
            return false;
        };
        // Zero-padded to the largest model: the padding is decoupled and stays zero in P.
        let a = SMatrix::<f64, N, N>::from_fn(|i, j| if i < n && j < n { s.a(i, j) } else { 0.0 });
        let c = SMatrix::<f64, 1, N>::from_fn(|_, j| if j < n { s.c(j) } else { 0.0 });
        let g = SMatrix::<f64, N, 1>::from_fn(|i, _| if i < n { s.input_column(i) } else { 0.0 });
        let r = self.design.measurement_noise;
        let gq = self.design.process_covariance(&g, n);
        let Some(p) = filter_riccati(&a, &c, &gq, r * r) else {
            return false;
        };
        let m = measurement_gain(&p, &c, r * r);
        if !error_is_stable(&s, &m.as_slice()[..n]) {
            return false;
        }
        self.load(&s, m.as_slice());
        true
    }

    /// The estimate of the state at `state`'s sample, from its measurement `y[0]` and the
    /// command applied since the last sample `u_applied[0]` (held over any samples between).
    pub fn update(&mut self, state: &PlantState) -> &[f64] {
        let n = self.n;
        match samples_since(self.last_seq, state.seq) {
            Some(0) => return &self.ahead[..n],
            Some(k) => {
                for _ in 0..k {
                    // The input of the sample the delayed measurement is of (0, a rest, before
                    // the run's first inputs are that old).
                    let u = self.inputs.push(state.u_applied[0]);
                    self.predict(u);
                }
            }
            None => {}
        }
        self.last_seq = Some(state.seq);
        let predicted: f64 =
            (0..n).map(|j| self.c[j] * self.x[j]).sum::<f64>() + self.d * self.v_prev;
        let innovation = state.y[0] - predicted;
        for (x, m) in self.x[..n].iter_mut().zip(&self.m[..n]) {
            *x += m * innovation;
        }
        self.predict_ahead();
        &self.ahead[..n]
    }

    /// The last estimate (zeros before the first sample).
    pub fn estimate(&self) -> &[f64] {
        &self.ahead[..self.n]
    }

    /// `ahead`: `x` through the model over the inputs of the last d samples, oldest first.
    fn predict_ahead(&mut self) {
        self.ahead = self.x;
        for i in 0..self.inputs.len() {
            self.ahead = self.step(&self.ahead, self.inputs.get(i));
        }
    }

    /// A x + B u.
    fn step(&self, x: &[f64; N], u: f64) -> [f64; N] {
        let n = self.n;
        let mut next = [0.0; N];
        for (i, z) in next.iter_mut().enumerate().take(n) {
            *z = (0..n).map(|j| self.a[i][j] * x[j]).sum::<f64>() + self.b[i] * u;
        }
        next
    }

    fn predict(&mut self, u: f64) {
        let n = self.n;
        let next = self.step(&self.x, u);
        self.v_prev = (0..n).map(|j| self.f[j] * self.x[j]).sum::<f64>() + self.g * u;
        self.x = next;
    }
}

/// Joint velocities as a servo drive estimates them from its encoders: the position difference
/// over the time between samples, through a first-order low-pass of cutoff `cutoff_hz`
/// (discretised exactly: each sample moves the estimate a fraction 1 - e^(-2 pi fc T) of the way
/// to the new difference). Its lag is about 1 / (2 pi fc) plus half a period.
#[derive(Debug, Clone)]
pub struct VelocityFilter {
    n: usize,
    period: f64,
    /// The share of a new difference per sample, 1 - e^(-2 pi fc T).
    alpha: f64,
    q_prev: [f64; MAX_JOINTS],
    qd: [f64; MAX_JOINTS],
    last_seq: Option<u64>,
}

/// The share of a new input per sample of a first-order low-pass at `cutoff_hz` sampled every
/// `period` s: 1 - e^(-2 pi fc T) (`VelocityFilter`'s; the identification reproduces a drive's).
pub fn low_pass_share(cutoff_hz: f64, period: f64) -> f64 {
    1.0 - (-2.0 * std::f64::consts::PI * cutoff_hz * period).exp()
}

impl VelocityFilter {
    /// For `n` joints sampled every `period` s, with the low-pass's cutoff `cutoff_hz` (> 0).
    pub fn new(n: usize, period: f64, cutoff_hz: f64) -> Self {
        Self {
            n: n.min(MAX_JOINTS),
            period,
            alpha: low_pass_share(cutoff_hz, period),
            q_prev: [0.0; MAX_JOINTS],
            qd: [0.0; MAX_JOINTS],
            last_seq: None,
        }
    }

    /// The joint velocities at `state`'s sample from its measured positions `y[..n]`. The first
    /// sample gives zero (a start at rest).
    pub fn update(&mut self, state: &PlantState) -> &[f64] {
        let n = self.n;
        if let Some(k) = samples_since(self.last_seq, state.seq) {
            if k == 0 {
                return &self.qd[..n];
            }
            let dt = k as f64 * self.period;
            // A gap of k samples is one difference over k periods, filtered as k samples are.
            let share = 1.0 - (1.0 - self.alpha).powi(k as i32);
            let moved = state.y[..n].iter().zip(&self.q_prev[..n]);
            for (qd, (y, prev)) in self.qd[..n].iter_mut().zip(moved) {
                *qd += share * ((y - prev) / dt - *qd);
            }
        }
        self.q_prev[..n].copy_from_slice(&state.y[..n]);
        self.last_seq = Some(state.seq);
        &self.qd[..n]
    }

    /// The last estimate.
    pub fn estimate(&self) -> &[f64] {
        &self.qd[..self.n]
    }
}

/// A joint vector's first values in a fixed array (the rest 0), as the delay lines hold them.
fn joint_values(v: &[f64]) -> [f64; MAX_JOINTS] {
    let mut out = [0.0; MAX_JOINTS];
    out[..v.len()].copy_from_slice(v);
    out
}

/// The most samples a `VelocityObserver` predicts across in one cycle (one forward-dynamics pass
/// each, about a microsecond for seven joints).
const MAX_OBSERVER_GAP: u64 = 20;

/// Joint positions and velocities from the measured positions, the applied torques and a
/// rigid-body model, one sample at a time. Over each period the model predicts
///   qdd = M(q̂)^-1 (tau - V(q̂, q̂d) - G(q̂) - F(q̂d)),  q̂ += T q̂d + T²/2 qdd,  q̂d += T qdd,
/// with tau the torque that reached the plant (`u_applied`), and the measured position corrects
/// the prediction, q̂ += m1 (y - q̂), q̂d += m2 (y - q̂). Where the model is right the error of
/// each joint obeys the double integrator's e+ = (I - M C) A e, whose two eigenvalues the gains
/// m1 = 1 - p² (dimensionless) and m2 = (1 - p)² / T (1/s) place together at
/// p = e^(-2 pi fc T): the error decays as a critically damped pair of bandwidth `bandwidth_hz`.
/// A model error or an unmodelled load enters as an acceleration the correction must carry, so
/// the observer lags less than the low-pass the better the model is. A gap of more than
/// `MAX_OBSERVER_GAP` samples (a stalled plant, which meanwhile applied its safe command, not
/// the held one) restarts the estimate from the measured position and the difference quotient
/// over the gap, rather than spending the late cycle on predictions.
#[derive(Debug, Clone)]
pub struct VelocityObserver {
    n: usize,
    period: f64,
    m1: f64,
    m2: f64,
    q: [f64; MAX_JOINTS],
    qd: [f64; MAX_JOINTS],
    qdd: [f64; MAX_JOINTS],
    data: Data,
    last_seq: Option<u64>,
    /// The torques of the last d samples, d the samples the measured positions lag (the
    /// plant's `sensor_delay`): the estimate above is of the sample the last measurement is of,
    /// `ahead` the present's, predicted by the model over these torques (d forward-dynamics
    /// passes a cycle).
    torques: DelayLine<[f64; MAX_JOINTS]>,
    ahead_q: [f64; MAX_JOINTS],
    ahead_qd: [f64; MAX_JOINTS],
}

impl VelocityObserver {
    /// For `model`'s joints sampled every `period` s, the error's double pole at `bandwidth_hz`.
    pub fn new(model: &Model, period: f64, bandwidth_hz: f64) -> Self {
        let (m1, m2) = Self::gains(period, bandwidth_hz);
        Self {
            n: model.dof().min(MAX_JOINTS),
            period,
            m1,
            m2,
            q: [0.0; MAX_JOINTS],
            qd: [0.0; MAX_JOINTS],
            qdd: [0.0; MAX_JOINTS],
            data: model.data(),
            last_seq: None,
            torques: DelayLine::new(0, [0.0; MAX_JOINTS]),
            ahead_q: [0.0; MAX_JOINTS],
            ahead_qd: [0.0; MAX_JOINTS],
        }
    }

    /// For positions measured `delay` samples late: the observer
    /// runs that far behind and predicts the present across the torques since.
    pub fn delayed_by(mut self, delay: usize) -> Self {
        self.torques = DelayLine::new(delay, [0.0; MAX_JOINTS]);
        self
    }

    /// The correction's gains (m1 on the position, m2 on the velocity, 1/s) that put both
    /// eigenvalues of a joint's error map at p = e^(-2 pi fc T).
    pub fn gains(period: f64, bandwidth_hz: f64) -> (f64, f64) {
        let p = (-2.0 * std::f64::consts::PI * bandwidth_hz * period).exp();
        (1.0 - p * p, (1.0 - p) * (1.0 - p) / period)
    }

    /// The joint velocities at `state`'s sample, from its measured positions `y[..n]` and the
    /// torques applied since the last sample `u_applied[..n]` (held over any samples between),
    /// predicted by `model` (the law's model in service, whose joints this observer was built
    /// for). The first sample starts the estimate at its positions, at rest.
    pub fn update(&mut self, model: &Model, state: &PlantState) -> &[f64] {
        let n = self.n;
        match samples_since(self.last_seq, state.seq) {
            Some(0) => return self.estimate(),
            Some(k) if k > MAX_OBSERVER_GAP => {
                let dt = k as f64 * self.period;
                for i in 0..n {
                    self.qd[i] = (state.y[i] - self.q[i]) / dt;
                    self.q[i] = state.y[i];
                }
                // Over the gap the plant held one command: the torques since are that one.
                self.torques.fill(joint_values(&state.u_applied[..n]));
            }
            Some(k) => {
                for _ in 0..k {
                    // The torques of the sample the late measurement is of (zero, a rest,
                    // before the run's are that old).
                    let tau = self.torques.push(joint_values(&state.u_applied[..n]));
                    self.predict(model, &tau[..n]);
                }
                for i in 0..n {
                    let e = state.y[i] - self.q[i];
                    self.q[i] += self.m1 * e;
                    self.qd[i] += self.m2 * e;
                }
            }
            None => {
                self.q[..n].copy_from_slice(&state.y[..n]);
                self.qd[..n].fill(0.0);
            }
        }
        self.last_seq = Some(state.seq);
        self.predict_ahead(model);
        self.estimate()
    }

    /// The present's estimate: the delayed one stepped by the model over the torques of the
    /// last `delay` samples, oldest first (nothing to do on time).
    fn predict_ahead(&mut self, model: &Model) {
        if self.torques.is_empty() {
            return;
        }
        let n = self.n;
        let (q, qd) = (self.q, self.qd);
        for i in 0..self.torques.len() {
            let tau = self.torques.get(i);
            self.predict(model, &tau[..n]);
        }
        self.ahead_q = self.q;
        self.ahead_qd = self.qd;
        (self.q, self.qd) = (q, qd);
    }

    /// One period of the model's motion under the held torques. A model whose mass matrix is
    /// not positive definite at q̂ (none the laws accept, which check theirs) predicts no
    /// acceleration: the correction alone then tracks, as a drive's alpha-beta tracker does.
    fn predict(&mut self, model: &Model, tau: &[f64]) {
        let (n, t) = (self.n, self.period);
        let (q, qd) = (&self.q[..n], &self.qd[..n]);
        if model
            .forward_dynamics_aba(&mut self.data, q, qd, tau, &mut self.qdd[..n])
            .is_err()
            || !self.qdd[..n].iter().all(|a| a.is_finite())
        {
            self.qdd[..n].fill(0.0);
        }
        for i in 0..n {
            self.q[i] += t * self.qd[i] + 0.5 * t * t * self.qdd[i];
            self.qd[i] += t * self.qdd[i];
        }
    }

    /// The last velocity estimate (of the present, across a sensor delay).
    pub fn estimate(&self) -> &[f64] {
        if !self.torques.is_empty() {
            &self.ahead_qd[..self.n]
        } else {
            &self.qd[..self.n]
        }
    }

    /// The last position estimate (of the present, across a sensor delay).
    pub fn positions(&self) -> &[f64] {
        if !self.torques.is_empty() {
            &self.ahead_q[..self.n]
        } else {
            &self.q[..self.n]
        }
    }
}

/// Where a joint-space law's velocities come from (`controller.<law>.velocity`).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocitySource {
    /// The simulator's true joint velocities `qd_true`, which no encoder gives: the RKGNN
    /// paper's simulation, an ideal sensor (`velocity = "true"`).
    True,
    /// Measured positions differenced and low-passed (`VelocityFilter`) at this cutoff, Hz.
    Filtered {
        /// The low-pass's cutoff, Hz.
        cutoff_hz: f64,
    },
    /// The law's own model predicting from the applied torques, corrected by the measured
    /// positions (`VelocityObserver`), the error's double pole at this bandwidth, Hz, the
    /// positions `delay` samples late (the plant's `sensor_delay`).
    Observer {
        /// Where the estimation error's double pole lies, Hz.
        bandwidth_hz: f64,
        /// Samples the measured positions lag the state (the plant's `sensor_delay`).
        delay: usize,
    },
}

impl VelocitySource {
    /// Whether the law reads the simulator's `qd_true` (`True`), which no sensor gives.
    pub fn reads_truth(self) -> bool {
        self == VelocitySource::True
    }
}

/// A law's velocity reading in the cycle.
#[derive(Debug, Clone)]
pub enum Velocities {
    /// The simulator's true joint velocities `qd_true`.
    True,
    /// Measured positions differenced and low-passed.
    Filtered(VelocityFilter),
    /// Boxed: its state and the model's workspace, built once off the cycle.
    Observer(Box<VelocityObserver>),
}

impl Velocities {
    /// For a law of `n` joints run every `period` s; `model` is the law's own, which an
    /// observer needs (a law without one is refused `velocity = "observer"` by its config).
    pub fn new(source: VelocitySource, n: usize, period: f64, model: Option<&Model>) -> Self {
        match (source, model) {
            (VelocitySource::True, _) => Velocities::True,
            (VelocitySource::Filtered { cutoff_hz }, _) => {
                Velocities::Filtered(VelocityFilter::new(n, period, cutoff_hz))
            }
            (
                VelocitySource::Observer {
                    bandwidth_hz,
                    delay,
                },
                Some(m),
            ) => Velocities::Observer(Box::new(
                VelocityObserver::new(m, period, bandwidth_hz).delayed_by(delay),
            )),
            (VelocitySource::Observer { .. }, None) => {
                panic!("a velocity observer needs the law's model (its config refuses it without)")
            }
        }
    }

    /// The first `n` joint velocities at `state`'s sample; an observer predicts with `model`,
    /// the law's model in service. Allocation-free.
    pub fn read<'a>(
        &'a mut self,
        state: &'a PlantState,
        n: usize,
        model: Option<&Model>,
    ) -> &'a [f64] {
        match (self, model) {
            (Velocities::True, _) => &state.qd_true[..n],
            (Velocities::Filtered(f), _) => f.update(state),
            (Velocities::Observer(o), Some(m)) => o.update(m, state),
            (Velocities::Observer(o), None) => o.estimate(),
        }
    }

    /// The joint positions a law acts on where they are not the measured ones: an observer's
    /// prediction across a late sensor (after `read` on the same sample). None: the
    /// measurement `y` (on time, or no model to predict with).
    pub fn predicted_positions(&self) -> Option<&[f64]> {
        match self {
            Velocities::Observer(o) if !o.torques.is_empty() => Some(o.positions()),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(seq: u64, y: &[f64], u: f64) -> PlantState {
        let mut s = PlantState {
            seq,
            ..Default::default()
        };
        s.y[..y.len()].copy_from_slice(y);
        s.u_applied[0] = u;
        s
    }

    /// With a state noise (the collocated encoder's design), the redesign in the cycle is the
    /// off-cycle design too: the noise on the states is in both.
    #[test]
    fn a_filter_with_a_state_noise_designed_again_is_the_one_designed_for_it() {
        use crate::plant::two_mass::Sensor;
        use crate::plant::TwoMass;
        let design = KalmanDesign {
            process_noise: 1.0,
            measurement_noise: 5e-4,
            state_noise: 1e-3,
        };
        let at = |k| TwoMass::new(1.0, 1.0, k, Sensor::Actuated).linear_model();
        let mut kf = Kalman::new(&design.gains(&at(1.0), 1e-3).unwrap(), 0);
        assert!(kf.redesign(&at(0.5)));
        let direct = design.gains(&at(0.5), 1e-3).unwrap();
        let without = KalmanDesign {
            state_noise: 0.0,
            ..design
        };
        let plain = without.gains(&at(0.5), 1e-3).unwrap();
        for i in 0..4 {
            let m = direct.m[i];
            assert!(
                (kf.m[i] - m).abs() <= 1e-9 * m.abs(),
                "M {i}: {} vs {m}",
                kf.m[i]
            );
            assert!((plain.m[i] - m).abs() > 1e-3 * m.abs(), "M {i} without it");
        }
        // The padded states of the cycle's fixed-size design get no noise (they stay zero in P).
        let g = SMatrix::<f64, N, 1>::from_fn(|i, _| if i < 4 { 1.0 } else { 0.0 });
        let q = design.process_covariance(&g, 4);
        assert!(q
            .iter()
            .enumerate()
            .all(|(k, v)| (k % N < 4 && k / N < 4) || *v == 0.0));
        assert!((q[(3, 3)] - (1.0 + 1e-6)).abs() < 1e-15 && q[(2, 3)] == 1.0);
        // The error poles: on the antiresonance without it (|z| within 1e-6 of 1), off it with.
        let slowest = |g: &KalmanGains| g.poles.iter().map(|z| z.norm()).fold(0.0, f64::max);
        assert!(slowest(&plain) > 1.0 - 1e-6, "{:?}", plain.poles);
        assert!(slowest(&direct) < 1.0 - 1e-4, "{:?}", direct.poles);
    }

    /// Designed again in the cycle on an estimated model (the indirect scheme's spring), the
    /// filter predicts with that model sampled and corrects with the gain the off-cycle design
    /// gives it; a model it cannot filter (an unstable mode the sensor does not see) or of
    /// another size leaves it as it was.
    #[test]
    fn a_filter_designed_again_on_an_estimate_is_the_one_designed_for_it() {
        use crate::plant::two_mass::Sensor;
        use crate::plant::TwoMass;
        let design = KalmanDesign {
            process_noise: 1.0,
            measurement_noise: 5e-4,
            state_noise: 0.0,
        };
        let at = |k| TwoMass::new(1.0, 1.0, k, Sensor::Far).linear_model();
        let mut kf = Kalman::new(&design.gains(&at(1.0), 1e-3).unwrap(), 0);
        let nominal_m = kf.m;
        assert!(kf.redesign(&at(0.5)));
        let direct = design.gains(&at(0.5), 1e-3).unwrap();
        for (i, nominal) in nominal_m.iter().enumerate().take(4) {
            let m = direct.m[i];
            assert!(
                (kf.m[i] - m).abs() <= 1e-9 * m.abs(),
                "M {i}: {} vs {m}",
                kf.m[i]
            );
            assert!(
                (kf.m[i] - nominal).abs() > 1e-6 * m.abs(),
                "M {i} did not move"
            );
            assert!((kf.b[i] - direct.model.b(i)).abs() <= 1e-15);
            for j in 0..4 {
                assert!(
                    (kf.a[i][j] - direct.model.a(i, j)).abs() <= 1e-14,
                    "A {i} {j}"
                );
            }
        }
        let designed = kf.clone();
        let hidden = LinearModel::continuous(
            &[
                1.0, 0.0, 0.0, 0.0, //
                0.0, -1.0, 0.0, 0.0, //
                0.0, 0.0, -1.0, 0.0, //
                0.0, 0.0, 0.0, -1.0,
            ],
            &[1.0, 1.0, 1.0, 1.0],
            &[0.0, 1.0, 0.0, 0.0],
        );
        let smaller = LinearModel::continuous(&[-1.0], &[1.0], &[1.0]);
        for refused in [hidden, smaller] {
            assert!(!kf.redesign(&refused));
            assert_eq!((kf.a, kf.m), (designed.a, designed.m));
        }
    }

    /// A scalar random walk x+ = x + w, y = x + v: the Riccati equation has the closed form
    /// P = (Q + sqrt(Q² + 4 Q R)) / 2 and M = P / (P + R).
    #[test]
    fn a_random_walk_has_the_closed_form_gain() {
        let model = LinearModel::sampled(0.1, &[1.0], &[1.0], &[1.0], 0.0, &[0.0], 1.0);
        let (q, r) = (0.3f64, 0.5f64);
        let k = KalmanDesign {
            process_noise: q,
            measurement_noise: r,
            state_noise: 0.0,
        }
        .gains(&model, 0.1)
        .unwrap();
        let (q2, r2) = (q * q, r * r);
        let p = (q2 + (q2 * q2 + 4.0 * q2 * r2).sqrt()) / 2.0;
        assert!(
            (k.p[(0, 0)] - p).abs() < 1e-12 * p,
            "{} vs {p}",
            k.p[(0, 0)]
        );
        assert!((k.m[0] - p / (p + r2)).abs() < 1e-12);
        assert!((k.l[0] - k.m[0]).abs() < 1e-15);
    }

    /// The filter of a double integrator measured in position, sampled every `t` s.
    fn double_integrator_filter(t: f64) -> KalmanGains {
        let model = LinearModel::continuous(&[0.0, 1.0, 0.0, 0.0], &[0.0, 1.0], &[1.0, 0.0]);
        KalmanDesign {
            process_noise: 1.0,
            measurement_noise: 1e-3,
            state_noise: 0.0,
        }
        .gains(&model, t)
        .unwrap()
    }

    /// On a noise-free double integrator the filter converges to the true position and
    /// velocity from a wrong start, one sample at a time, without being told the truth.
    #[test]
    fn the_filter_finds_a_double_integrators_velocity_from_its_position() {
        let t = 0.01;
        let gains = double_integrator_filter(t);
        // Zero-order hold of the double integrator: A = [[1, T], [0, 1]], B = [T²/2, T].
        assert!((gains.model.a(0, 1) - t).abs() < 1e-15);
        assert!((gains.model.b(0) - t * t / 2.0).abs() < 1e-15);
        let mut kf = Kalman::new(&gains, 0);
        let (mut pos, mut vel) = (0.5, -2.0);
        let u = 3.0;
        for seq in 0..400 {
            let x = kf.update(&sample(seq, &[pos], u));
            if seq > 300 {
                assert!(
                    (x[0] - pos).abs() < 1e-9 && (x[1] - vel).abs() < 1e-6,
                    "{x:?}"
                );
            }
            pos += vel * t + u * t * t / 2.0;
            vel += u * t;
        }
        // The same sample again changes nothing.
        let before = kf.estimate().to_vec();
        kf.update(&sample(399, &[123.0], u));
        assert_eq!(kf.estimate(), &before[..]);
    }

    /// With the position measured `delay` samples late, the filter runs that far behind and
    /// predicts the present over the inputs applied since: on a noise-free double integrator
    /// driven by a varying input it finds the present state to round-off, where the same filter
    /// told of no delay is off by the motion over the delay. An input taken one sample early
    /// or late would leave an error of the order of T² u per step, far above round-off.
    #[test]
    fn a_delayed_measurement_is_predicted_across_to_the_present() {
        let t = 0.01;
        let delay = 7;
        let gains = double_integrator_filter(t);
        let (mut told, mut blind) = (Kalman::new(&gains, delay), Kalman::new(&gains, 0));
        // At rest at 0.5 before the start, as the sensor's first readings say.
        let (mut pos, mut vel) = (0.5, 0.0);
        let mut readings = vec![pos; delay];
        let mut u_applied = 0.0;
        let (mut worst_told, mut worst_blind) = (0.0f64, 0.0f64);
        for seq in 0..600u64 {
            readings.push(pos);
            let y = readings[readings.len() - 1 - delay];
            let state = sample(seq, &[y], u_applied);
            let (x, xb) = (told.update(&state).to_vec(), blind.update(&state).to_vec());
            if seq > 400 {
                worst_told = worst_told.max((x[0] - pos).abs() + (x[1] - vel).abs() * t);
                worst_blind = worst_blind.max((xb[0] - pos).abs());
            }
            let u = 3.0 * (0.05 * seq as f64).sin() + 1.0;
            pos += vel * t + u * t * t / 2.0;
            vel += u * t;
            u_applied = u;
        }
        assert!(worst_told < 1e-9, "told of the delay: {worst_told}");
        assert!(worst_blind > 1e-3, "not told: {worst_blind}");
        assert_eq!(told.estimate().len(), 2);
    }

    /// One joint turning about a vertical axis, no gravity, no friction: its acceleration is
    /// tau / izz whatever the state, so the model's prediction is exact.
    fn free_joint() -> Model {
        let text = "name = \"free\"\nconvention = \"standard\"\ngravity = [0.0, 0.0, 0.0]\n\
                    [[joint]]\nname = \"j\"\na = 0.0\nalpha = 0.0\nd = 0.0\nmass = 1.0\n\
                    com = [0.0, 0.0, 0.0]\ninertia = [0.3, 0.3, 0.5, 0.0, 0.0, 0.0]\n";
        crate::dynamics::dh::parse(text, std::path::Path::new("free.toml")).unwrap()
    }

    /// The gains put both eigenvalues of the error map (I - M C) A at p = e^(-2 pi fc T):
    /// trace 2p, determinant p².
    #[test]
    fn the_observer_gains_place_a_double_pole_at_the_bandwidth() {
        for (t, fc) in [(0.001, 50.0), (0.0001, 200.0), (0.002, 5.0)] {
            let (m1, m2) = VelocityObserver::gains(t, fc);
            let p = (-2.0 * std::f64::consts::PI * fc * t).exp();
            // (I - M C) A = [[1 - m1, (1 - m1) T], [-m2, 1 - m2 T]].
            let (trace, det) = (
                2.0 - m1 - m2 * t,
                (1.0 - m1) * (1.0 - m2 * t) + (1.0 - m1) * m2 * t,
            );
            assert!((trace - 2.0 * p).abs() < 1e-12, "{trace} vs {}", 2.0 * p);
            assert!((det - p * p).abs() < 1e-12, "{det} vs {}", p * p);
        }
    }

    /// Where the model is exact (a free joint under a constant torque) the observer's error
    /// after k samples is the analytic Phi^k e_0, Phi = (I - M C) A, from a start at rest while
    /// the joint already turns.
    #[test]
    fn on_an_exact_model_the_observer_error_follows_its_error_map() {
        let (model, t, fc) = (free_joint(), 0.001, 20.0);
        let mut obs = VelocityObserver::new(&model, t, fc);
        let (m1, m2) = VelocityObserver::gains(t, fc);
        let phi = [[1.0 - m1, (1.0 - m1) * t], [-m2, 1.0 - m2 * t]];
        let (tau, izz) = (0.2, 0.5);
        let acc = tau / izz;
        let (mut q, mut v) = (0.3, 1.5);
        let mut e = [0.0, v]; // the observer starts at the measured position, at rest
        for seq in 0..300 {
            obs.update(&model, &sample(seq, &[q], tau));
            let got = [q - obs.positions()[0], v - obs.estimate()[0]];
            assert!(
                (got[0] - e[0]).abs() < 1e-12 && (got[1] - e[1]).abs() < 1e-9,
                "sample {seq}: error {got:?}, analytic {e:?}"
            );
            e = [
                phi[0][0] * e[0] + phi[0][1] * e[1],
                phi[1][0] * e[0] + phi[1][1] * e[1],
            ];
            q += v * t + 0.5 * acc * t * t;
            v += acc * t;
        }
        // After 300 samples (p^300 ~ 1e-16) the velocity error is gone.
        assert!(e[1].abs() < 1e-12, "{e:?}");
    }

    /// Positions measured `delay` samples late: the observer told of it runs behind and steps
    /// its (here exact) model over the torques since, so on a free joint under a varying torque
    /// it finds the present position and velocity to round-off; one not told is a motion over
    /// the delay behind. An off-by-one in the torques would show as an error of T² tau / izz.
    #[test]
    fn the_observer_predicts_across_a_late_sensor() {
        let (model, t, fc, delay) = (free_joint(), 0.001, 20.0, 12);
        let mut told = VelocityObserver::new(&model, t, fc).delayed_by(delay);
        let mut blind = VelocityObserver::new(&model, t, fc);
        let izz = 0.5;
        let (mut q, mut v) = (0.3, 0.0);
        let mut readings = vec![q; delay];
        let mut tau_applied = 0.0;
        let (mut worst_told, mut worst_blind) = (0.0f64, 0.0f64);
        for seq in 0..800u64 {
            readings.push(q);
            let state = sample(seq, &[readings[readings.len() - 1 - delay]], tau_applied);
            let qd = told.update(&model, &state)[0];
            blind.update(&model, &state);
            if seq > 600 {
                worst_told = worst_told.max((told.positions()[0] - q).abs() + (qd - v).abs() * t);
                worst_blind = worst_blind.max((blind.positions()[0] - q).abs());
            }
            let tau = 0.2 * (0.01 * seq as f64).sin() + 0.05;
            let acc = tau / izz;
            q += v * t + 0.5 * acc * t * t;
            v += acc * t;
            tau_applied = tau;
        }
        assert!(worst_told < 1e-9, "told of the delay: {worst_told}");
        assert!(worst_blind > 1e-4, "not told: {worst_blind}");
    }

    /// A gap of samples is predicted across with the held torque: the estimate after the gap
    /// equals the one of an observer that saw every sample but was corrected only at the end.
    #[test]
    fn the_observer_predicts_across_a_gap_and_ignores_a_repeated_sample() {
        let model = free_joint();
        let mut obs = VelocityObserver::new(&model, 0.001, 20.0);
        obs.update(&model, &sample(0, &[0.0], 0.5));
        let once = obs.update(&model, &sample(5, &[0.0], 0.5)).to_vec();
        // Five periods at 1 rad/s² from rest: q̂ = 12.5e-6, q̂d = 5e-3 before the correction.
        let (m1, m2) = VelocityObserver::gains(0.001, 20.0);
        let (qp, vp) = (0.5 * 1.0 * 0.005f64.powi(2), 0.005);
        assert!((obs.positions()[0] - (qp + m1 * (0.0 - qp))).abs() < 1e-15);
        assert!((once[0] - (vp + m2 * (0.0 - qp))).abs() < 1e-12);
        let again = obs.update(&model, &sample(5, &[9.0], 0.5)).to_vec();
        assert_eq!(once, again);
    }

    #[test]
    fn an_undetectable_unstable_mode_has_no_filter() {
        // Two states, the unstable second never reaching y.
        let model = LinearModel::sampled(
            0.1,
            &[0.5, 0.0, 0.0, 1.2],
            &[1.0, 1.0],
            &[1.0, 0.0],
            0.0,
            &[0.0, 0.0],
            1.0,
        );
        let e = KalmanDesign {
            process_noise: 1.0,
            measurement_noise: 0.1,
            state_noise: 0.0,
        }
        .gains(&model, 0.1)
        .unwrap_err();
        assert!(
            matches!(e, KalmanError::NotDetectable | KalmanError::Unstable),
            "{e}"
        );
    }

    #[test]
    fn the_velocity_filter_follows_a_ramp_with_its_lag_and_skips_gaps() {
        let t = 0.001;
        let mut f = VelocityFilter::new(2, t, 50.0);
        for seq in 0..200u64 {
            let tk = seq as f64 * t;
            f.update(&sample(seq, &[2.0 * tk, -tk], 0.0));
        }
        let v = f.estimate();
        assert!(
            (v[0] - 2.0).abs() < 1e-9 && (v[1] + 1.0).abs() < 1e-9,
            "{v:?}"
        );
        // Three samples missed: one difference over four periods, still the slope.
        let tk = 203.0 * t;
        let v = f.update(&sample(203, &[2.0 * tk, -tk], 0.0));
        assert!((v[0] - 2.0).abs() < 1e-9, "{v:?}");
        // A step of 1 mrad moves the estimate by the filter's share of 1 mrad / T, not all of it.
        let mut f = VelocityFilter::new(1, t, 50.0);
        f.update(&sample(0, &[0.0], 0.0));
        let v = f.update(&sample(1, &[1e-3], 0.0))[0];
        let share = 1.0 - (-2.0 * std::f64::consts::PI * 50.0 * t).exp();
        assert!((v - share).abs() < 1e-12, "{v}");
    }
}
