//! The two-mass loop as a machine with one position sensor runs it: the state feedback acting on
//! a Kalman filter's estimate (`[controller.state_feedback] state = "kalman"`) instead of the
//! full state the paper assumes. Analysed two ways, each the other's check:
//!
//! - **Continuous time, for the paper's r_c.** The filter enters as its continuous-time
//!   equivalent x̂' = A x̂ + B u + L_c (y - C x̂) with L_c = L / T, L = Φ M the sampled filter's
//!   predictor gain: an approximation (it drops the current form's direct use of y, and the
//!   gain depends on T), which the sampled loop below checks (their spring ranges agree to three
//!   digits on the default filter). The loop's state is
//!   [x; ξ; x̂]; the perturbation E Δ H acts on the plant's rows and columns only, because the
//!   filter keeps its nominal model while the plant's spring moves.
//! - **Sampled, as the controller runs it:** the plant held over each period (ZOH), the
//!   current-form filter with its own M, the integrator's Euler step, no saturation. Its range of
//!   stable springs must contain what r_c guarantees: a spring change δ is the perturbation
//!   δ [[-1, 1], [1, -1]] of norm 2|δ|, so |δ| < r_c / 2 keeps the loop stable.

use crate::law::estimator::{KalmanDesign, KalmanError, KalmanGains};
use crate::linalg::eig;
use crate::plant::linear::LinearModel;
use nalgebra::DMatrix;

/// A steady-state Kalman filter in the loop, designed for the nominal model at `period`.
#[derive(Debug, Clone)]
pub struct Observer {
    /// The noise levels the filter is designed for.
    pub design: KalmanDesign,
    /// The period (s) the filter runs at, the controller's.
    pub period: f64,
    /// The sampled filter the controller runs.
    pub filter: KalmanGains,
    /// Its continuous-time equivalent gain L_c = L / T (n x 1).
    pub l_c: DMatrix<f64>,
    /// The perturbation's E and H padded for the loop's filter states (`pad_perturbation`).
    pub e_loop: DMatrix<f64>,
    /// H of the perturbation padded with zero columns for the filter's states.
    pub h_loop: DMatrix<f64>,
}

/// Why `Observer::new` gives no filter to compute r_c with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObserverError {
    /// The Kalman design gives no filter for the model at the period.
    Kalman(KalmanError),
    /// The sampled filter's continuous equivalent L/T has this error pole in the right
    /// half-plane at this period (s): r_c of the loop with it is not defined.
    ContinuousUnstable {
        /// The sampling period, s.
        period: f64,
        /// The error pole, Re >= 0.
        pole: nalgebra::Complex<f64>,
    },
}

impl std::fmt::Display for ObserverError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ObserverError::Kalman(e) => write!(f, "no Kalman filter for this plant: {e}"),
            ObserverError::ContinuousUnstable { period, pole } => write!(
                f,
                "the filter's continuous equivalent L/T at period {period} s has an error pole \
                 at {:.4} {:+.4}j, not in the left half-plane: r_c of the loop with it is not \
                 defined (a shorter period or a slower filter)",
                pole.re, pole.im
            ),
        }
    }
}

impl std::error::Error for ObserverError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ObserverError::Kalman(e) => Some(e),
            ObserverError::ContinuousUnstable { .. } => None,
        }
    }
}

impl Observer {
    /// The filter `design` gives for the continuous `model` sampled every `period` s, in the
    /// loop of the augmented open loop perturbed by E Δ H.
    pub fn new(
        model: &LinearModel,
        (e, h): (&DMatrix<f64>, &DMatrix<f64>),
        design: KalmanDesign,
        period: f64,
    ) -> Result<Self, ObserverError> {
        let filter = design.gains(model, period).map_err(ObserverError::Kalman)?;
        let n = model.n();
        let l_c = DMatrix::from_fn(n, 1, |i, _| filter.l[i] / period);
        let (e_loop, h_loop) = pad_perturbation(e, h, n);
        let observer = Self {
            design,
            period,
            filter,
            l_c,
            e_loop,
            h_loop,
        };
        // The sampled filter is stable by its design; its continuous equivalent, on which r_c
        // is computed, need not be at a long period. Refused then, not scored.
        if let Some(p) = observer.error_poles(model).iter().find(|p| p.re >= 0.0) {
            return Err(ObserverError::ContinuousUnstable { period, pole: *p });
        }
        Ok(observer)
    }

    /// The continuous equivalent's error dynamics A - L_c C: its eigenvalues are the loop's
    /// poles besides the state feedback's (separation), on the nominal plant.
    pub fn error_poles(&self, model: &LinearModel) -> Vec<nalgebra::Complex<f64>> {
        let n = model.n();
        eig(&DMatrix::from_fn(n, n, |i, j| {
            model.a(i, j) - self.l_c[(i, 0)] * model.c(j)
        }))
    }
}

/// The continuous loop [x; ξ; x̂]' = A_loop [x; ξ; x̂] of the augmented open loop (Â, B̂) of a
/// plant with n states (Â = [[A, 0], [-C, 0]], B̂ = [B; 0]) under u = -K_x x̂ - k_ξ ξ, with the
/// filter x̂' = A x̂ + B u + L_c (C x - C x̂) on the nominal model (A, B, C) = (Â, B̂)'s blocks.
/// `plant` is the (possibly perturbed) Â the plant rows use.
pub fn continuous_loop(
    plant: &DMatrix<f64>,
    nominal: &DMatrix<f64>,
    b_hat: &DMatrix<f64>,
    l_c: &DMatrix<f64>,
    gains: &[f64],
) -> DMatrix<f64> {
    let n = gains.len() - 1;
    let (kx, ki) = (&gains[..n], gains[n]);
    // C from the integrator's row of Â: ξ' = -C x.
    let c = |j: usize| -nominal[(n, j)];
    let mut m = DMatrix::zeros(2 * n + 1, 2 * n + 1);
    for i in 0..=n {
        for j in 0..=n {
            m[(i, j)] = plant[(i, j)];
        }
        m[(i, n)] -= b_hat[(i, 0)] * ki;
        for j in 0..n {
            m[(i, n + 1 + j)] = -b_hat[(i, 0)] * kx[j];
        }
    }
    for i in 0..n {
        let r = n + 1 + i;
        let l = l_c[(i, 0)];
        for j in 0..n {
            m[(r, j)] = l * c(j);
            m[(r, n + 1 + j)] = nominal[(i, j)] - b_hat[(i, 0)] * kx[j] - l * c(j);
        }
        m[(r, n)] = -b_hat[(i, 0)] * ki;
    }
    m
}

/// E and H of the augmented open loop, padded with zeros for the filter's n states: the
/// perturbation reaches the plant, not the filter.
fn pad_perturbation(e: &DMatrix<f64>, h: &DMatrix<f64>, n: usize) -> (DMatrix<f64>, DMatrix<f64>) {
    let size = e.nrows() + n;
    (
        e.clone().resize_vertically(size, 0.0),
        h.clone().resize_horizontally(size, 0.0),
    )
}

/// The sampled loop as the controller runs it, state [x; x̄; I] at a sample (x̄ the filter's
/// prediction before the measurement, I the integrator's contribution to u):
///   x̂ = x̄ + M (C x - C x̄),  u = I - K_x x̂,
///   x+ = Φ_p x + Γ_p u,  x̄+ = Φ x̂ + Γ u,  I+ = I + k_ξ T C x.
/// `plant` is the continuous plant (possibly another spring than the filter's model); None when
/// it cannot be sampled at the filter's period.
pub fn sampled_loop(
    plant: &LinearModel,
    filter: &KalmanGains,
    period: f64,
    gains: &[f64],
) -> Option<DMatrix<f64>> {
    let p = plant.at_period(period)?;
    let f = &filter.model;
    let n = p.n();
    let ki = gains[n];
    let (_, u_x, u_bar) = command_row(&p, filter, gains);
    // x̂ = (I - M C) x̄ + M C x: the (i, j) entries of its two blocks.
    let hat_x = |i: usize, j: usize| filter.m[i] * p.c(j);
    let hat_bar = |i: usize, j: usize| f64::from(u8::from(i == j)) - filter.m[i] * f.c(j);
    let size = 2 * n + 1;
    let mut m = DMatrix::zeros(size, size);
    for i in 0..n {
        for j in 0..n {
            m[(i, j)] = p.a(i, j) + p.b(i) * u_x[j];
            m[(i, n + j)] = p.b(i) * u_bar[j];
            let phi_hat_x: f64 = (0..n).map(|l| f.a(i, l) * hat_x(l, j)).sum();
            let phi_hat_bar: f64 = (0..n).map(|l| f.a(i, l) * hat_bar(l, j)).sum();
            m[(n + i, j)] = phi_hat_x + f.b(i) * u_x[j];
            m[(n + i, n + j)] = phi_hat_bar + f.b(i) * u_bar[j];
        }
        m[(i, 2 * n)] = p.b(i);
        m[(n + i, 2 * n)] = f.b(i);
    }
    for j in 0..n {
        m[(2 * n, j)] = ki * period * p.c(j);
    }
    m[(2 * n, 2 * n)] = 1.0;
    Some(m)
}

/// The command's row of the sampled loop, u = u_x·x + u_bar·x̄ + I, with u = I - K_x x̂ and
/// x̂ = x̄ + M (C x - C x̄); and K_x M, the command's direct response to a measurement.
fn command_row(p: &LinearModel, filter: &KalmanGains, gains: &[f64]) -> (f64, Vec<f64>, Vec<f64>) {
    let n = p.n();
    let kx = &gains[..n];
    let km: f64 = (0..n).map(|j| kx[j] * filter.m[j]).sum();
    let u_x = (0..n).map(|j| -km * p.c(j)).collect();
    let u_bar = (0..n).map(|j| -kx[j] + km * filter.model.c(j)).collect();
    (km, u_x, u_bar)
}

/// The largest eigenvalue modulus (< 1: the sampled loop is stable).
pub fn spectral_radius(m: &DMatrix<f64>) -> f64 {
    eig(m).iter().map(|z| z.norm()).fold(0.0, f64::max)
}

/// The springs around `k` for which `stable` holds without a break: (lowest, highest), each
/// found by stepping 2 % at a time and bisecting the first failure to 1e-6 relative; None on a
/// side where the loop is still stable at k/1000 (below) or 1000 k (above). A loop unstable at
/// `k` itself is stable for no spring around it: the empty range (k, k).
pub fn spring_range(k: f64, stable: impl Fn(f64) -> bool) -> (Option<f64>, Option<f64>) {
    if !stable(k) {
        return (Some(k), Some(k));
    }
    let edge = |factor: f64, limit: f64| -> Option<f64> {
        let mut inside = k;
        loop {
            let next = inside * factor;
            if (factor > 1.0 && next > limit) || (factor < 1.0 && next < limit) {
                return None;
            }
            if !stable(next) {
                let mut out = next;
                while (out - inside).abs() > 1e-6 * k {
                    let mid = 0.5 * (inside + out);
                    if stable(mid) {
                        inside = mid;
                    } else {
                        out = mid;
                    }
                }
                return Some(0.5 * (inside + out));
            }
            inside = next;
        }
    };
    (edge(1.0 / 1.02, k / 1000.0), edge(1.02, 1000.0 * k))
}

/// The standard deviation of u in steady state when the measurement carries white noise of
/// standard deviation `sigma` (the loop otherwise at rest): what a faster filter costs. The
/// noise v enters y_k = C x_k + v_k, so the filter's correction, the integrator and u itself;
/// the stationary covariance of the sampled loop's state solves P = M P M' + N N' sigma², by
/// doubling (the slowest poles are within 1e-3 of the unit circle at 1 kHz). None when the
/// loop is not stable or cannot be sampled.
pub fn command_noise(
    plant: &LinearModel,
    filter: &KalmanGains,
    period: f64,
    gains: &[f64],
    sigma: f64,
) -> Option<f64> {
    let m = sampled_loop(plant, filter, period, gains)?;
    if spectral_radius(&m) >= 1.0 {
        return None;
    }
    let p = plant.at_period(period)?;
    let f = &filter.model;
    let n = p.n();
    let ki = gains[n];
    let (km, u_x, u_bar) = command_row(&p, filter, gains);
    // u = U z + d v, z+ = M z + N v.
    let u_row = DMatrix::from_fn(1, 2 * n + 1, |_, j| match j {
        j if j < n => u_x[j],
        j if j < 2 * n => u_bar[j - n],
        _ => 1.0,
    });
    let mut noise = DMatrix::zeros(2 * n + 1, 1);
    for i in 0..n {
        noise[(i, 0)] = -km * p.b(i);
        noise[(n + i, 0)] = (0..n).map(|l| f.a(i, l) * filter.m[l]).sum::<f64>() - km * f.b(i);
    }
    noise[(2 * n, 0)] = ki * period;
    let mut cov = &noise * noise.transpose() * (sigma * sigma);
    let mut a = m;
    for _ in 0..64 {
        let next = &cov + &a * &cov * a.transpose();
        let change = (&next - &cov).norm();
        cov = next;
        a = &a * &a;
        if change <= 1e-14 * cov.norm() {
            break;
        }
    }
    let var = (&u_row * &cov * u_row.transpose())[(0, 0)] + km * km * sigma * sigma;
    (var.is_finite() && var >= 0.0).then(|| var.sqrt())
}
