//! Identification of an RKGNN from reference and output data (RKGNN paper, Section 5.1).
//!
//! The RKGNN is the Runge-Kutta-Gill step (`plant::gill`) wrapped around the function network
//! N_f; driven by the servo's reference it predicts the arm's output from one measured state.
//! The objective is eq. 13 with its constraints eqs. 14-16:
//!   J = (1/t_N) sum_i (|theta^(i) - theta(i)| + |theta^'(i) - theta'(i)|)
//!       + s_t/2 sum_j lambda_j [g_j^+]^2,   s_t = 10 + ln(k + 1) at generation k,
//! with lambda = (1000, 1, 1), g_1 = -Gamma (the smallest leading principal minor of M-hat),
//! g_2 = m_1 - lambda_min(M-hat), g_3 = lambda_max(M-hat) - m_2, each at its worst over probe
//! positions of the operating region (`region_probes`: the training positions and points of the
//! box around them, widened, since the controller runs near the data, not on it).
//!
//! Our reading of eq. 13. As printed it compares the reference theta_d with the output theta,
//! which does not depend on the network at all. The identification error is between the
//! RKGNN's predicted output theta^ and the measured output theta: the prediction runs free
//! (long horizon) from the first measured state over the whole training window, driven only by
//! the reference, so a model is judged on what the controller will need, its behaviour over a
//! trajectory, not on one-step fits. A prediction that diverges (non-finite, beyond 1e3, or a
//! singular M-hat) is scored as if every remaining sample had error `DIVERGED`, so a model that
//! survives longer ranks better. The log in s_t is natural; the survivors' values were computed
//! with the s_t of their generation.
//!
//! What the identification knows of the arm is the data (reference and output) and the two
//! constants m_1, m_2 of Property 1 (eq. 2), which the paper assumes known (`Prior`; a user
//! takes them from a datasheet, a CAD model or a bound); it never reads a robot file. Besides
//! shaping M-hat, they fix the model's one free scale, which data without torques cannot:
//! multiplying M-hat, V-hat, G-hat and the torque network by one constant predicts the same
//! motion.
//!
//! Beyond the paper (each opt-in on the command line, see the book, "RKGNN"):
//! - `--servo linear`: the servo network as k_p e + k_d e' per joint (`RbfCounts::linear_servo`
//!   says why it makes gravity identifiable).
//! - `--velocity christoffel`: no velocity network, V-hat from M-hat's Christoffel symbols
//!   (`network::christoffel`; eq. 3 by construction).
//! - `--start least-squares`: the EA starts from `least_squares_start`, the inverse-dynamics
//!   equation solved for the output weights in units of joint 1's k_p, then given the one scale
//!   that centres M-hat's eigenvalues in eq. 2's [m_1, m_2]; `--evaluations 0` keeps the start
//!   as the model.
//! - `--servo known`: the training run's servo is the user's own P-D law with known gains (the
//!   paper allows it: "if detailed information of the controller is known, the structure of the
//!   network can be altered accordingly"); its torque is then known at every sample, the fit is
//!   M-hat q'' + V-hat + G-hat = tau, and the scale comes with it (`ServoPrior::Known`).
//! - `--refine N`: Levenberg-Marquardt on the free-run output error after the least-squares
//!   start (`refine`).
//! - The default step is h = 5 ms (stride 5 at 1 kHz): the Gill step, like RK4, is stable for
//!   h |lambda| < 2.78 on the real axis, and arm3's forearm under its servo has a mode at
//!   k_d / M_33,eff = 8 / 0.029 = 277 /s, so h = 10 ms sits at 2.77: a model as stiff as the
//!   true arm barely survives a free-run prediction there, and the search prefers softer,
//!   wrong ones (M-hat_33 three times the truth, G-hat_2 at 40 % of it, seen at stride 10).

use super::data::Trajectory;
use crate::linalg::{min_leading_minor, sym_eig_range, Mat};
use crate::msg::MAX_JOINTS;
use crate::optim::chaotic::{ChaoticEa, ChaoticEaConfig};
use crate::optim::{evaluate, Objective, Optimiser};
use crate::plant::gill::RungeKuttaGill;
use evoloop_rkgnn::model::{Report, ServoPrior, Start, Weighing};
use evoloop_rkgnn::network::{self, Layout, Network, Part, RbfCounts};
use serde::{Deserialize, Serialize};

/// Error charged per sample left when a prediction diverges.
pub const DIVERGED: f64 = 10.0;
/// Magnitude of a predicted state beyond which the prediction counts as diverged.
const STATE_LIMIT: f64 = 1e3;

/// Identification settings.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    /// RBFs per sub-network of N_f (0 torque RBFs: a linear servo).
    pub counts: RbfCounts,
    /// Use every `stride`-th sample (the RKGNN's step h = stride x the data's period).
    pub stride: usize,
    /// Fraction of the data (at the end) held out for `holdout_rms`.
    pub holdout: f64,
    /// Objective evaluations.
    pub evaluations: usize,
    /// The chaotic EA's settings (population, crossover, memory, strategic moves, seed).
    pub ea: ChaoticEaConfig,
    /// Eq. 13's lambda_1..3.
    pub lambda: [f64; 3],
    /// Probe positions for the constraints (`region_probes`).
    pub probes: usize,
    /// Threads evaluating the EA's candidates and the refinement's Jacobian.
    pub threads: usize,
    /// Where the EA starts.
    pub start: Start,
    /// Levenberg-Marquardt steps on the output error after the least-squares start
    /// (`refine::refine`; 0 = none).
    pub refine: usize,
    /// What the identification knows of the servo the data were taken under.
    pub servo: ServoPrior,
    /// Known torques: when to weigh each joint's equations by 1 / that joint's torque rms, so
    /// that a wrist carrying 100x less torque than the shoulder is fitted as closely, relatively
    /// (`--weigh-joints`; `Weighing` says why it is not always done).
    pub weighing: Weighing,
}

/// The EA's mutation scales after a least-squares start, as a fraction of `initial`'s: the
/// start is near a fit already, and `initial`'s steps, sized for a search from nothing, scatter
/// the population far from it.
const LS_SIGMA: f64 = 0.1;

impl Settings {
    /// Section 5.1's settings for an `n`-joint arm: the paper's RBF counts, lambda =
    /// (1000, 1, 1), a random start and an unknown servo; stride 5 (h = 5 ms at 1 kHz),
    /// 20 % held out, 40 probes, `evaluations` of the EA seeded with `seed`.
    pub fn paper(n: usize, seed: u64, evaluations: usize) -> Self {
        Self {
            counts: RbfCounts::paper(n),
            stride: 5,
            holdout: 0.2,
            evaluations,
            ea: ChaoticEaConfig {
                seed,
                ..Default::default()
            },
            lambda: [1000.0, 1.0, 1.0],
            probes: 40,
            threads: crate::optim::all_cores(),
            start: Start::Random,
            refine: 0,
            servo: ServoPrior::Unknown,
            weighing: Weighing::AsNeeded,
        }
    }

    /// V-hat from M-hat's Christoffel symbols (`--velocity christoffel`): no velocity network.
    pub fn christoffel_velocity(&mut self) {
        self.counts.velocity = 0;
    }

    /// The recipe of the shipped models (the book, "RKGNN"): a linear P-D servo network, the
    /// least-squares start; `evaluations` = 0 keeps the
    /// start, more continue with the EA.
    pub fn least_squares(n: usize, seed: u64, evaluations: usize) -> Self {
        let mut s = Self::paper(n, seed, evaluations);
        s.counts = RbfCounts::linear_servo(n);
        s.start = Start::LeastSquares;
        s
    }
}

/// What the identification assumes known of the arm (Property 1, eq. 2): m_1 ||y||^2 <= y^T
/// M(q) y <= m_2 ||y||^2. Nothing else of the robot reaches the fit.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct Prior {
    /// Lower bound m_1 on M(q)'s eigenvalues (kg m^2 for revolute joints).
    pub m1: f64,
    /// Upper bound m_2 on M(q)'s eigenvalues.
    pub m2: f64,
}

impl Prior {
    /// Checked: 0 < m1 <= m2, both finite.
    pub fn new(m1: f64, m2: f64) -> Result<Self, super::RkgnnError> {
        if !(m1 > 0.0 && m1.is_finite() && m2.is_finite() && m1 <= m2) {
            return Err(super::RkgnnError::Prior { m1, m2 });
        }
        Ok(Self { m1, m2 })
    }

    /// The middle of [m1, m2]: where a joint's inertia starts when nothing else is known.
    pub fn mid(&self) -> f64 {
        0.5 * (self.m1 + self.m2)
    }

    /// The bounds a rigid-body model gives over joint positions `qs`: the smallest and largest
    /// eigenvalue of its M(q) there (what a user reads off a CAD model over the workspace). For
    /// the study and for users with a model; the identifier itself never calls it.
    pub fn of_model<'a>(
        model: &crate::dynamics::Model,
        qs: impl Iterator<Item = &'a [f64]>,
    ) -> Self {
        let n = model.dof();
        let mut data = model.data();
        let mut flat: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
        let (mut m1, mut m2) = (f64::INFINITY, 0.0f64);
        for q in qs {
            let m = model.mass_matrix(&mut data, q);
            for a in 0..n {
                for c in 0..n {
                    flat[a * n + c] = m[(a, c)];
                }
            }
            let (l, h) = sym_eig_range(n, &flat);
            m1 = m1.min(l);
            m2 = m2.max(h);
        }
        Self { m1, m2 }
    }
}

/// `count` joint positions drawn uniformly (fixed seed) within `model`'s joint limits
/// (`Limits::position_span`): the workspace over which a CAD model gives eq. 2's bounds
/// (`evoloop rkgnn prior` without --data, and the study's user).
pub fn limit_positions(model: &crate::dynamics::Model, count: usize) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(1);
    (0..count)
        .map(|_| {
            model
                .bodies
                .iter()
                .map(|b| {
                    let (lo, hi) = b.limits.position_span();
                    rng.gen_range(lo..=hi)
                })
                .collect()
        })
        .collect()
}

/// How many positions `limit_positions` draws by default.
pub const LIMIT_SAMPLES: usize = 2000;

/// Where M-hat must be positive definite and within eq. 2's bounds: `count` positions, half of
/// them training positions spread over the run, half drawn (fixed seed) from the box around
/// them widened by `REGION_MARGIN` of each joint's span (at least `REGION_MIN` rad) on each
/// side. The controller runs near the data, not on it: a model checked on its own samples only
/// was indefinite a little way off them (issue 41).
pub fn region_probes(train: &Trajectory, count: usize) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let n = train.n;
    let len = train.len();
    let on_data = count.div_ceil(2);
    let mut probes: Vec<Vec<f64>> = (0..on_data)
        .map(|k| train.x_at(k * len / on_data)[..n].to_vec())
        .collect();
    let range: Vec<(f64, f64)> = (0..n)
        .map(|j| {
            let (lo, hi) = (0..len).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
                let v = train.x_at(i)[j];
                (a.min(v), b.max(v))
            });
            let m = (REGION_MARGIN * (hi - lo)).max(REGION_MIN);
            (lo - m, hi + m)
        })
        .collect();
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x005e_ed41);
    probes.extend((on_data..count).map(|_| {
        range
            .iter()
            .map(|&(lo, hi)| rng.gen_range(lo..=hi))
            .collect()
    }));
    probes
}

/// How far `region_probes` reaches beyond the data, as a fraction of each joint's span.
pub const REGION_MARGIN: f64 = 0.5;
/// ... and at least this far, rad.
const REGION_MIN: f64 = 0.1;

/// Free-run prediction of `traj` from its first state: the predicted states (sample-major, 2n
/// each) into `out` if given, and eq. 13's error term. Allocates only the integrator's two
/// state-sized buffers (and `out`).
pub fn predict(
    layout: &Layout,
    p: &[f64],
    traj: &Trajectory,
    mut out: Option<&mut Vec<f64>>,
) -> f64 {
    let n = traj.n;
    let w = 2 * n;
    let steps = traj.len();
    let mut x = [0.0; 2 * MAX_JOINTS];
    x[..w].copy_from_slice(traj.x_at(0));
    let mut rkg = RungeKuttaGill::new(w);
    let zero = network::servo_zero(layout, p);
    let mut sum = 0.0;
    if let Some(o) = out.as_deref_mut() {
        o.clear();
        o.extend_from_slice(&x[..w]);
    }
    for i in 1..steps {
        let (r0, r1) = (traj.r_at(i - 1), traj.r_at(i));
        let mut mid = [0.0; 2 * MAX_JOINTS];
        for k in 0..w {
            mid[k] = 0.5 * (r0[k] + r1[k]);
        }
        // The four stages sit at t, t + h/2, t + h/2, t + h: the reference is linear between
        // samples.
        let mut stage = 0;
        let mut ok = true;
        rkg.step(&mut x[..w], traj.h, |xs, dx| {
            let r = match stage {
                0 => r0,
                3 => r1,
                _ => &mid[..w],
            };
            stage += 1;
            ok &= network::rate(layout, p, &zero, xs, r, dx);
        });
        let bad = !ok || x[..w].iter().any(|v| v.is_nan() || v.abs() > STATE_LIMIT);
        if bad {
            return sum / steps as f64 + DIVERGED * (steps - i) as f64 / steps as f64;
        }
        let m = traj.x_at(i);
        let (mut ep, mut ev) = (0.0, 0.0);
        for j in 0..n {
            ep += (x[j] - m[j]).powi(2);
            ev += (x[n + j] - m[n + j]).powi(2);
        }
        sum += ep.sqrt() + ev.sqrt();
        if let Some(o) = out.as_deref_mut() {
            o.extend_from_slice(&x[..w]);
        }
    }
    sum / steps as f64
}

/// Eqs. 14-16 at their worst over the probe positions: [g_1, g_2, g_3].
pub fn constraints(layout: &Layout, p: &[f64], probes: &[Vec<f64>], b: &Prior) -> [f64; 3] {
    let n = layout.n;
    let mut g = [f64::NEG_INFINITY; 3];
    let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    for q in probes {
        network::inertia(layout, p, q, &mut m);
        let gamma = min_leading_minor(n, &m);
        let (lo, hi) = sym_eig_range(n, &m);
        g[0] = g[0].max(-gamma);
        g[1] = g[1].max(b.m1 - lo);
        g[2] = g[2].max(hi - b.m2);
    }
    g
}

/// Eq. 13 for one generation.
struct Fit<'a> {
    layout: &'a Layout,
    train: &'a Trajectory,
    probes: &'a [Vec<f64>],
    prior: &'a Prior,
    lambda: [f64; 3],
    s_t: f64,
}

impl Objective for Fit<'_> {
    fn value(&self, p: &[f64]) -> f64 {
        let g = constraints(self.layout, p, self.probes, self.prior);
        let pen: f64 = g
            .iter()
            .zip(self.lambda)
            .map(|(g, l)| l * g.max(0.0).powi(2))
            .sum();
        let e = predict(self.layout, p, self.train, None);
        let v = e + 0.5 * self.s_t * pen;
        if v.is_finite() {
            v
        } else {
            f64::MAX
        }
    }
}

/// Per-joint RMS of the predicted minus measured positions.
pub fn rms_per_joint(layout: &Layout, p: &[f64], traj: &Trajectory) -> Vec<f64> {
    let mut pred = Vec::with_capacity(traj.x.len());
    predict(layout, p, traj, Some(&mut pred));
    let n = traj.n;
    let k = pred.len() / (2 * n);
    (0..n)
        .map(|j| {
            let s: f64 = (0..traj.len())
                .map(|i| {
                    if i < k {
                        (pred[2 * n * i + j] - traj.x_at(i)[j]).powi(2)
                    } else {
                        DIVERGED * DIVERGED
                    }
                })
                .sum();
            (s / traj.len() as f64).sqrt()
        })
        .collect()
}

/// Initial network and per-parameter mutation scales from the data (the EA's x0 and sigma0).
/// Centres sit on data samples, widths span the data, the inertia diagonal starts at the middle
/// of [m1, m2], the servo network as a critically damped P-D servo, every other output weight
/// at 0. The last RBF of each inertia sub-network is the entry's constant part (`is_constant`):
/// centred on the data's mean position, `CONSTANT_WIDTH` wide, so that M-hat tends to a
/// constant matrix away from the data instead of decaying to 0. The torque scale m2 (rms
/// theta_d'' + 9.81) only sets how far the search steps at first, divided like every scale by
/// sqrt(parameters).
pub fn initial(layout: &Layout, train: &Trajectory, prior: &Prior) -> (Vec<f64>, Vec<f64>) {
    let m2 = prior.m2;
    let n = train.n;
    let len = train.len();
    let mut x0 = vec![0.0; layout.len];
    let mut s0 = vec![0.0; layout.len];
    let rms = |f: &dyn Fn(usize) -> f64| -> f64 {
        ((0..len).map(|i| f(i).powi(2)).sum::<f64>() / len as f64)
            .sqrt()
            .max(1e-3)
    };
    let e_rms: Vec<f64> = (0..n)
        .map(|j| rms(&|i| train.r_at(i)[j] - train.x_at(i)[j]))
        .collect();
    let ed_rms: Vec<f64> = (0..n)
        .map(|j| rms(&|i| train.r_at(i)[n + j] - train.x_at(i)[n + j]))
        .collect();
    let acc_rms = rms(&|i| {
        let k = i.min(len - 2);
        (0..n)
            .map(|j| (train.r_at(k + 1)[n + j] - train.r_at(k)[n + j]) / train.h)
            .map(|a| a * a)
            .sum::<f64>()
            .sqrt()
            / (n as f64).sqrt()
    });
    let torque_scale = m2 * (acc_rms + 9.81);
    // Joint-position spread for the theta-driven sub-networks.
    let span = (0..n)
        .map(|j| {
            let (lo, hi) = (0..len).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), i| {
                let v = train.x_at(i)[j];
                (a.min(v), b.max(v))
            });
            (hi - lo).max(0.1)
        })
        .fold(0.0f64, |a, b| a.max(b));
    let m_mid = |_: usize| prior.mid();
    let mean: Vec<f64> = (0..n)
        .map(|j| (0..len).map(|i| train.x_at(i)[j]).sum::<f64>() / len as f64)
        .collect();
    // The starting servo: critically damped at 20 rad/s on the middle inertia (a stiff
    // industrial axis). Only a start: the search moves every weight.
    let (k_p, k_d) = (400.0, 40.0);
    for (part, net) in layout.subnets() {
        let per = net.per_rbf();
        for l in 0..net.rbfs {
            let b = net.offset + l * per;
            match part {
                Part::Proportional(j) | Part::Derivative(j) => {
                    // An odd, restoring characteristic: bumps at -a, 0, +a of width a with
                    // weights k c / 1.47 have slope k at 0 (for a pair at +-a of width a the
                    // slope is 4/(e a) of the weight). Without it a random servo network pushes
                    // one way, loses the arm beyond its bumps and every prediction diverges.
                    let p = matches!(part, Part::Proportional(_));
                    let a = 4.0 * if p { e_rms[j] } else { ed_rms[j] };
                    let k = m_mid(j) * if p { k_p } else { k_d };
                    let c = a * (l as f64 - (net.rbfs as f64 - 1.0) / 2.0);
                    x0[b] = c;
                    s0[b] = 0.5 * a;
                    x0[b + 1] = a;
                    s0[b + 1] = 0.5 * a;
                    x0[b + 2] = k * c / (4.0 / std::f64::consts::E);
                    s0[b + 2] = torque_scale;
                }
                Part::Inertia(a, c) if is_constant(net, l) => {
                    x0[b..b + n].copy_from_slice(&mean);
                    x0[b + n] = CONSTANT_WIDTH;
                    s0[b + n + 1] = 0.1 * m_mid(a);
                    if a == c {
                        x0[b + n + 1] = m_mid(a);
                    }
                }
                _ => {
                    // Centres on training positions spread over the run.
                    let i = (l * len) / net.rbfs + len / (2 * net.rbfs);
                    let q = &train.x_at(i.min(len - 1))[..n];
                    x0[b..b + n].copy_from_slice(q);
                    s0[b..b + n].fill(0.2 * span);
                    x0[b + n] = 2.0 * span;
                    s0[b + n] = 0.5 * span;
                    let w = &mut s0[b + n + 1..b + per];
                    match part {
                        Part::Inertia(a, _) => w.fill(0.1 * m_mid(a)),
                        Part::Velocity(_) => w.fill(m2),
                        _ => w.fill(torque_scale),
                    }
                }
            }
        }
    }
    if let Some(g) = layout.gains {
        for j in 0..n {
            x0[g + 2 * j] = m_mid(j) * k_p;
            x0[g + 2 * j + 1] = m_mid(j) * k_d;
            s0[g + 2 * j] = 0.5 * m_mid(j) * k_p;
            s0[g + 2 * j + 1] = 0.5 * m_mid(j) * k_d;
        }
    }
    // Every variable moves at once: steps of sigma per coordinate move the whole vector by
    // about sigma sqrt(n), so the per-coordinate scales are the part scales over sqrt(n).
    let shrink = 1.0 / (layout.len as f64).sqrt();
    s0.iter_mut().for_each(|v| *v *= shrink);
    (x0, s0)
}

/// Width of an inertia entry's constant RBF, rad: exp(-d^2 / 1e6) stays within 1e-5 of 1 over
/// any joint range.
const CONSTANT_WIDTH: f64 = 1e3;

/// Whether RBF `l` of an inertia sub-network is its constant part (the last one; a sub-network
/// of one RBF has none, so that it can still vary).
fn is_constant(net: &network::SubNet, l: usize) -> bool {
    net.rbfs > 1 && l == net.rbfs - 1
}

/// Identify a model from `data` knowing only eq. 2's `prior` of the arm, an RKGNN on the data's
/// reference at the settings' step; `source` names the data in the model file.
pub fn identify_model(
    data: &Trajectory,
    prior: &Prior,
    s: &Settings,
    source: String,
    progress: impl FnMut(usize, f64),
) -> Result<evoloop_rkgnn::RkgnnModel, super::RkgnnError> {
    let (net, report) = identify(data, prior, s, progress)?;
    let d = data.every(s.stride.max(1));
    Ok(evoloop_rkgnn::RkgnnModel::new(
        net, d.h, d.r, source, report,
    ))
}

/// Identify an RKGNN on `data` (the first 1 - holdout of it) with eq. 2's bounds `prior`.
/// `progress(evaluations, best)` is called after each generation. Returns the network (with the
/// settings' RBF counts) and the report.
pub fn identify(
    data: &Trajectory,
    prior: &Prior,
    s: &Settings,
    mut progress: impl FnMut(usize, f64),
) -> Result<(Network, Report), super::RkgnnError> {
    let t0 = std::time::Instant::now();
    let d = data.every(s.stride.max(1));
    let n_hold = ((d.len() as f64) * s.holdout).round() as usize;
    if d.len() < 20 || d.len() - n_hold < 10 {
        return Err(super::RkgnnError::TooFewSamples(format!(
            "too few samples: {} at stride {} (need at least 20)",
            d.len(),
            s.stride
        )));
    }
    let split = d.len() - n_hold;
    let train = d.window(0, split);
    let hold = d.window(split - 1, d.len());
    let layout = Layout::new(d.n, s.counts);
    let probes = region_probes(&train, s.probes);
    let (x0, s0) = initial(&layout, &train, prior);
    // Whether the least squares weighed the joints' equations (`Settings::weighing`).
    let (mut x0, mut s0, weighed) = match s.start {
        Start::Random => (x0, s0, false),
        Start::LeastSquares => {
            let full = data.window(0, ((split - 1) * s.stride.max(1) + 1).min(data.len()));
            if full.len() < 2 * full.trim() + MIN_ROWS * s.stride.max(1) {
                return Err(super::RkgnnError::TooFewSamples(format!(
                    "too few samples for the least-squares start: {:.2} s, the low-pass \
                     (--smoothing {} s) drops {:.2} s at each end and {MIN_ROWS} rows must remain",
                    full.len() as f64 * full.h,
                    full.smoothing,
                    full.trim() as f64 * full.h
                )));
            }
            let (x, w) = least_squares_start(&layout, &x0, &full, &probes, prior, s)
                .ok_or(super::RkgnnError::NoStart)?;
            let x = refine_start(&layout, x, &train, &probes, prior, s);
            (x, s0.iter().map(|v| v * LS_SIGMA).collect(), w)
        }
    };
    // A known servo is not searched, whatever the start: its gains are the given ones.
    if let (Some(g), ServoPrior::Known { kp, kd, .. }) = (layout.gains, &s.servo) {
        for j in 0..d.n {
            (x0[g + 2 * j], x0[g + 2 * j + 1]) = (kp[j], kd[j]);
        }
        s0[g..g + 2 * d.n].fill(0.0);
    }
    let mut ea = ChaoticEa::new(s.ea, &x0, &s0);
    let mut history = Vec::new();
    // Eq. 13 at generation k: s_t = 10 + ln(k + 1).
    let fit_at = |k: usize| Fit {
        layout: &layout,
        train: &train,
        probes: &probes,
        prior,
        lambda: s.lambda,
        s_t: 10.0 + (k as f64 + 1.0).ln(),
    };
    while ea.evaluations() < s.evaluations {
        let fit = fit_at(ea.generation());
        ea.ask();
        let values = evaluate(ea.candidates(), None, &fit, s.threads);
        ea.tell(&values);
        history.push(ea.best().1);
        progress(ea.evaluations(), ea.best().1);
    }
    let (best, objective) = if ea.evaluations() == 0 {
        // No search (--evaluations 0): the start is the model; eq. 13 at generation 0.
        (x0.as_slice(), fit_at(0).value(&x0))
    } else {
        ea.best()
    };
    let net = Network::new(layout, best.to_vec());
    let report = Report {
        train_rms: rms_per_joint(&net.layout, net.params(), &train),
        holdout_rms: rms_per_joint(&net.layout, net.params(), &hold),
        min_eig_m_hat: net.min_eig(train.x.chunks(2 * d.n).map(|x| &x[..d.n])),
        evaluations: ea.evaluations(),
        seconds: t0.elapsed().as_secs_f64(),
        generations: ea.generation(),
        objective,
        h: d.h,
        m1: prior.m1,
        m2: prior.m2,
        start: s.start,
        servo: s.servo.clone(),
        weigh_joints: weighed,
        weighing: Some(s.weighing),
        velocity_smoothing: Some(d.smoothing),
        seed: s.ea.seed,
        history,
    };
    Ok((net, report))
}

/// The least-squares start refined by `s.refine` Levenberg-Marquardt steps on the output error:
/// with an unknown servo k_p,1 holds the scale and eq. 2 gives it again after; a known servo's
/// gains stay as they are.
fn refine_start(
    layout: &Layout,
    mut x: Vec<f64>,
    train: &Trajectory,
    probes: &[Vec<f64>],
    prior: &Prior,
    s: &Settings,
) -> Vec<f64> {
    let Some(g) = layout.gains else { return x };
    if s.refine == 0 {
        return x;
    }
    let known = matches!(s.servo, ServoPrior::Known { .. });
    let free: Vec<usize> = weight_indices(layout)
        .into_iter()
        .filter(|&k| {
            if known {
                !(g..g + 2 * layout.n).contains(&k)
            } else {
                k != g
            }
        })
        .collect();
    let keep =
        |p: &[f64]| network::min_eig(layout, p, probes.iter().map(Vec::as_slice)) >= 0.5 * prior.m1;
    super::refine::refine(layout, &mut x, &free, train, keep, s.refine, s.threads);
    if known {
        return x;
    }
    scale_to_prior(layout, x.clone(), probes, prior).unwrap_or(x)
}

/// Indices of every output weight in the flat parameter vector (centres and widths excluded).
fn weight_indices(layout: &Layout) -> Vec<usize> {
    let mut w: Vec<usize> = layout
        .subnets()
        .flat_map(|(_, net)| net.all_weights())
        .collect();
    if let Some(g) = layout.gains {
        w.extend(g..g + 2 * layout.n);
    }
    w
}

/// `p` with every output weight and servo gain at zero (the residual's zero).
fn without_weights(layout: &Layout, p: &[f64]) -> Vec<f64> {
    let mut p = p.to_vec();
    weight_indices(layout).iter().for_each(|&k| p[k] = 0.0);
    p
}

/// The inverse-dynamics residual M-hat(q) q'' + V-hat(q, q') + G-hat(q) - tau-hat(e, e') into
/// `out`. For fixed centres and widths it is linear in the output weights (zero when they all
/// are), which is what the least squares (`design`) use.
fn residual(layout: &Layout, p: &[f64], x: &[f64], xdd: &[f64], r: &[f64], out: &mut [f64]) {
    let n = layout.n;
    let zero = network::servo_zero(layout, p);
    let mut f = [0.0; MAX_JOINTS];
    let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    network::net_force(layout, p, &zero, x, r, &mut m, &mut f);
    for a in 0..n {
        let mq: f64 = (0..n).map(|b| m[a * n + b] * xdd[b]).sum();
        out[a] = mq - f[a];
    }
}

/// The EA's starting point with a linear servo, beyond the paper. With the RBF centres and
/// widths of `initial` fixed, the inverse-dynamics equation
///   M-hat(q) q'' + V-hat(q, q') + G-hat(q) = k_p e + k_d e',  e = theta_d - q,
/// which holds at every sample (q'' from central differences of the measured q'), is linear in
/// every other parameter, the per-joint gains included. It is homogeneous (scale all and the
/// motion is the same), so it is solved in units of joint 1's k_p (k_p,1 = 1 moves to the
/// right-hand side; every other k_p,j and every k_d,j stays unknown: one scale for the whole
/// model, since M-hat is one symmetric matrix shared by all joints' equations), a linear
/// least-squares problem solved by SVD on unit-norm columns. The model is then given the one
/// scale c that centres its eigenvalue range over the operating region in eq. 2's [m_1, m_2]
/// (geometrically: c^2 lo hi = m_1 m_2). Fixing the scale on M-hat instead, inside the least
/// squares, does not work: the data's accelerations are small, so "no servo, no gravity,
/// M-hat q'' ~ 0" fits the equation better than the truth with its unmodelled friction. The EA
/// then refines everything on the free-run prediction error it is judged by.
///
/// Returns the parameters and whether the joints' equations were weighed (`Settings::weighing`:
/// with `AsNeeded`, a known servo's fit is tried in N m first and weighed only if that finds no
/// positive definite M-hat).
pub fn least_squares_start(
    layout: &Layout,
    p0: &[f64],
    data: &Trajectory,
    probes: &[Vec<f64>],
    prior: &Prior,
    s: &Settings,
) -> Option<(Vec<f64>, bool)> {
    let (stride, servo) = (s.stride, &s.servo);
    let n = layout.n;
    let g = layout.gains?;
    let floor = at_least(layout, probes, 0.5 * prior.m1);
    // Reference and measurement low-passed alike (`Trajectory::filtered`). The servo's torque
    // k_p e is read off the position error, and with torque-free data the scale of joints that
    // couple only weakly to joint 1 hangs on small terms: encoder-class noise of 1e-4 rad on e,
    // unfiltered, halved the shoulder and forearm gains of arm3's fit (1.29 and 0.77 of k_p,1 on
    // clean data, 0.64 and 0.28 with noise; truth 1.33 and 0.67).
    let data = &data.filtered();
    if let ServoPrior::Known { kp, kd, .. } = servo {
        let tau = servo_torques(servo, data);
        let mut p = p0.to_vec();
        for j in 0..n {
            p[g + 2 * j] = kp[j];
            p[g + 2 * j + 1] = kd[j];
        }
        let fit = |weigh: bool| {
            let target = Target::Torques { tau: &tau, weigh };
            least_squares(layout, &p, data, target, stride, INERTIA_RIDGES, &floor)
                .map(|p| (p, weigh))
        };
        return match s.weighing {
            Weighing::Never => fit(false),
            Weighing::AsNeeded => fit(false).or_else(|| fit(true)),
            Weighing::Always => fit(true),
        };
    }
    // Stage 1, the servo: every weight free (no ridge on the inertia, which would shrink the
    // joints that are tied to joint 1's scale only weakly), for the gains alone.
    let positive = |p: Vec<f64>| {
        (0..n)
            .all(|j| p[g + 2 * j] > 0.0 && p[g + 2 * j + 1] >= 0.0)
            .then_some(p)
    };
    let servo = least_squares(layout, p0, data, Target::ServoUnits, stride, &[0.0], |p| {
        positive(p)
    })?;
    // Stage 2, the arm: with the gains fixed the servo's torque is known at every sample, and
    // M-hat, V-hat, G-hat are fitted to it with the smallest inertia ridge that leaves M-hat
    // positive definite over the region once scaled to eq. 2 (at least m_1 / 2 there).
    let mut tau = vec![0.0; data.len() * n];
    for i in 0..data.len() {
        let (r, x) = (data.r_at(i), data.x_at(i));
        for j in 0..n {
            tau[i * n + j] =
                servo[g + 2 * j] * (r[j] - x[j]) + servo[g + 2 * j + 1] * (r[n + j] - x[n + j]);
        }
    }
    let scaled = |p: Vec<f64>| scale_to_prior(layout, p, probes, prior).and_then(&floor);
    let target = Target::Torques {
        tau: &tau,
        weigh: false,
    };
    least_squares(layout, &servo, data, target, stride, INERTIA_RIDGES, scaled).map(|p| (p, false))
}

/// The live identification's fit (`rkgnn::live`): the model in service, `p0`, updated to a window
/// of data whose joint torques are known (`torques`, n per sample of `data`: under computed torque
/// the command is the controller's own, known without measuring a torque). The equations are
/// `--servo known`'s, M-hat q'' + V-hat + G-hat = tau (no scale to fix; the servo network keeps
/// p0's values, it plays no part in computed torque), but the fit is centred on the model in
/// service: each output weight is p0's plus a correction, and a ridge on the corrections, each in
/// units of its output's size in p0 (`prior_scales`), says how far a few seconds of one trajectory
/// may move a model identified on more. Fitted from zero instead (as before 2026-11-29), the
/// window's data leave most of a 7-DOF arm's inertia network to a ridge and M-hat was positive
/// definite in none of arm7's attempts. The friction columns of `design` stay free (projected out)
/// and are dropped. Of `UPDATE_RIDGES` (relative to the largest singular value) the smallest whose
/// M-hat reaches `min_eig` over `probes` is taken; the largest leaves p0 nearly as it is. One SVD
/// serves every ridge, of the design's R (`linalg::Ridges`): arm7's window is 5 376 rows by 917
/// columns, and its attempts took 20 s through the whole matrix's SVD, 12.5 s through R
/// (2026-12-03).
pub fn update_with_torques(
    layout: &Layout,
    p0: &[f64],
    data: &Trajectory,
    torques: &[f64],
    stride: usize,
    probes: &[Vec<f64>],
    min_eig: f64,
) -> Option<Vec<f64>> {
    let n = layout.n;
    let g = layout.gains?;
    // The torques through the same low-pass as the signals (`Trajectory::filtered`), where
    // the fit reads them.
    let tau = data.filter_alike_for(torques, stride);
    let data = &data.filtered_for(stride);
    let cols: Vec<usize> = weight_indices(layout)
        .into_iter()
        .filter(|k| !(g..g + 2 * n).contains(k))
        .collect();
    let samples: Vec<usize> = data.interior(stride).collect();
    if samples.len() < MIN_ROWS {
        return None;
    }
    let (a, _) = design(layout, p0, data, &cols, &samples);
    let w = cols.len();
    // What the model in service leaves of the torques is the correction's right-hand side.
    let w0 = nalgebra::DVector::from_iterator(w, cols.iter().map(|&k| p0[k]));
    let mut rhs = at_samples(&tau, &samples, n) - a.columns(0, w) * &w0;
    // The friction columns (`design`) are free, unlike the weights: projected out of the
    // weights' columns and the right-hand side, so that the ridge never leaves the arm's
    // friction for V-hat and G-hat to take.
    let friction = column_space(a.columns(w, 2 * n).clone_owned());
    let mut a = a.columns(0, w).clone_owned();
    a -= &friction * friction.tr_mul(&a);
    rhs -= &friction * friction.tr_mul(&rhs);
    let scale = prior_scales(layout, p0);
    for (c, &k) in cols.iter().enumerate() {
        a.column_mut(c).scale_mut(scale[k]);
    }
    let ridges = crate::linalg::Ridges::new(a, rhs)?;
    let s_max = ridges.largest_singular_value();
    // An empty window, or a model and data all at zero: nothing to update.
    if s_max.is_nan() || s_max <= 0.0 {
        return None;
    }
    let accept = at_least(layout, probes, min_eig);
    UPDATE_RIDGES.iter().find_map(|&rho| {
        let du = ridges.solution(rho);
        let mut p = p0.to_vec();
        for (c, &k) in cols.iter().enumerate() {
            p[k] += du[c] * scale[k];
        }
        accept(p)
    })
}

/// An orthonormal basis of the span of `m`'s columns (a joint at rest leaves its friction
/// columns at zero, which span nothing).
fn column_space(m: nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    let svd = m.svd(true, false);
    let Some(u) = svd.u else {
        return nalgebra::DMatrix::zeros(svd.singular_values.len(), 0);
    };
    let tol = 1e-12 * svd.singular_values.max();
    let keep: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&i| svd.singular_values[i] > tol)
        .collect();
    u.select_columns(&keep)
}

/// Per parameter, the size of its output in `p`: the rms of that output's weights over its
/// sub-network's RBFs (one inertia entry, one joint's gravity, one velocity product). An output
/// near zero (an off-diagonal inertia entry, a product the arm hardly has) gets at least 1 % of
/// the rms of its kind's weights (inertia, velocity, gravity), so that it may still move; a
/// kind all at zero, 1.
fn prior_scales(layout: &Layout, p: &[f64]) -> Vec<f64> {
    let rms = |ks: &mut dyn Iterator<Item = usize>| {
        let (sum, count) = ks.fold((0.0, 0usize), |(s, c), k| (s + p[k] * p[k], c + 1));
        (sum / count.max(1) as f64).sqrt()
    };
    let kind = |part: Part| std::mem::discriminant(&part);
    let floor = |part: Part| {
        let same = layout
            .subnets()
            .filter(move |(q, _)| kind(*q) == kind(part));
        0.01 * rms(&mut same.flat_map(|(_, net)| net.all_weights()))
    };
    let mut sizes = vec![1.0; p.len()];
    for (part, net) in layout.subnets() {
        let floor = floor(part);
        for o in 0..net.outputs {
            let of = |l: usize| net.weights(l).start + o;
            let size = rms(&mut (0..net.rbfs).map(of)).max(floor);
            (0..net.rbfs).for_each(|l| sizes[of(l)] = if size > 0.0 { size } else { 1.0 });
        }
    }
    sizes
}

/// A least-squares acceptance: the parameters if they are finite and M-hat's smallest eigenvalue
/// over `probes` reaches `floor`.
fn at_least<'a>(
    layout: &'a Layout,
    probes: &'a [Vec<f64>],
    floor: f64,
) -> impl Fn(Vec<f64>) -> Option<Vec<f64>> + 'a {
    move |p| {
        let finite = p.iter().all(|v| v.is_finite());
        (finite && network::min_eig(layout, &p, probes.iter().map(Vec::as_slice)) >= floor)
            .then_some(p)
    }
}

/// What the least squares fit the dynamics to.
#[derive(Clone, Copy)]
enum Target<'a> {
    /// The servo's torque in units of joint 1's k_p (torque-free data is homogeneous): k_p,1 =
    /// 1 moves to the right-hand side.
    ServoUnits,
    /// Known joint torques, n per sample of the data; the servo stays out of the fit. With
    /// `weigh` each joint's rows are weighed by 1 / that joint's torque rms.
    Torques { tau: &'a [f64], weigh: bool },
}

/// The least-squares fits' common part: the solution with the smallest of `ridges` (on the
/// inertia network's bumps) that `accept` takes, as `accept` returns it.
#[allow(clippy::too_many_arguments)]
fn least_squares(
    layout: &Layout,
    p0: &[f64],
    data: &Trajectory,
    target: Target,
    stride: usize,
    ridges: &[f64],
    accept: impl Fn(Vec<f64>) -> Option<Vec<f64>>,
) -> Option<Vec<f64>> {
    let n = layout.n;
    let g = layout.gains?;
    let kp = |j: usize| g + 2 * j;
    let torques = match target {
        Target::Torques { tau, .. } => Some(tau),
        Target::ServoUnits => None,
    };
    // In k_p,1 units joint 1's k_p column is the right-hand side; with torques every servo
    // weight stays out of the fit.
    let servo = |k: usize| k == kp(0) || (torques.is_some() && (g..g + 2 * n).contains(&k));
    let cols: Vec<usize> = weight_indices(layout)
        .into_iter()
        .filter(|k| !servo(*k))
        .collect();
    let samples: Vec<usize> = data.interior(stride).collect();
    let (mut a, xdd) = design(layout, p0, data, &cols, &samples);
    let rows = a.nrows();
    let mut rhs = match torques {
        Some(tau) => at_samples(tau, &samples, n),
        None => nalgebra::DVector::<f64>::zeros(rows),
    };
    let mut p = without_weights(layout, p0);
    if torques.is_none() {
        // k_p,1 = 1 moves to the right-hand side.
        let mut column = nalgebra::DVector::<f64>::zeros(rows);
        fill_column(layout, &mut p, kp(0), data, &samples, &xdd, &mut column);
        rhs -= &column;
    }
    if let Target::Torques { weigh: true, .. } = target {
        // Each joint's equations in units of its own torque: unweighted, the shoulder's
        // residuals (tens of N m) decide the fit and the wrist's inertia, whose 0.0035 kg m^2 is
        // arm7's smallest eigenvalue, is left to round-off (M-hat indefinite).
        weigh_rows(&mut a, &mut rhs, n);
    }
    let norms: Vec<f64> = (0..a.ncols())
        .map(|c| a.column(c).norm().max(1e-300))
        .collect();
    for (c, nrm) in norms.iter().enumerate() {
        a.column_mut(c).scale_mut(1.0 / nrm);
    }
    // Ridges (unit-norm column space). The velocity network's products of joint velocities
    // are small and nearly collinear with the other columns along one trajectory:
    // unregularised, its weights grow large and cancelling, harmless in the fit, wild at the
    // velocities a controller meets off it (V-hat 5 N m where the arm's V is 0.07), so its
    // columns always carry VELOCITY_RIDGE. The inertia network's bumps (not its constant
    // parts) get the smallest ridge of INERTIA_RIDGES that leaves M-hat positive definite over
    // the operating region's probes (at least `floor`): the larger the ridge, the nearer M-hat
    // is to its constant part.
    let sub_cols = |ks: Vec<usize>| -> Vec<usize> {
        ks.into_iter()
            .filter_map(|k| cols.iter().position(|&c| c == k))
            .collect()
    };
    let vel = sub_cols(
        layout
            .velocity
            .iter()
            .flat_map(|net| net.all_weights())
            .collect(),
    );
    let iner = sub_cols(
        layout
            .inertia
            .iter()
            .flat_map(|(_, net)| {
                (0..net.rbfs)
                    .filter(|&l| !is_constant(net, l))
                    .flat_map(|l| net.weights(l))
            })
            .collect(),
    );
    // Each ridge's problem is the design stacked on its ridge rows. The design's part is
    // reduced once to R and Q^T b (`householder_reduce`), which have its least-squares
    // solutions and singular values, so the SVD per ridge is of R's rows and the ridge rows
    // rather than of one row per equation (arm7's refused fit in tests/rkgnn.rs: 38 s -> 7 s).
    let (a, rhs) = crate::linalg::householder_reduce(a, rhs);
    let base = a.nrows();
    for &r_m in ridges {
        let extra = vel.len() + if r_m > 0.0 { iner.len() } else { 0 };
        let mut ar = a.clone().resize_vertically(base + extra, 0.0);
        let br = rhs.clone().resize_vertically(base + extra, 0.0);
        for (r, &c) in vel.iter().enumerate() {
            ar[(base + r, c)] = VELOCITY_RIDGE;
        }
        if r_m > 0.0 {
            for (r, &c) in iner.iter().enumerate() {
                ar[(base + vel.len() + r, c)] = r_m;
            }
        }
        let svd = ar.svd(true, true);
        let Ok(w) = svd.solve(&br, LS_TOLERANCE * svd.singular_values.max()) else {
            continue;
        };
        let mut p = p.clone();
        for (c, &k) in cols.iter().enumerate() {
            p[k] = w[c] / norms[c];
        }
        match target {
            Target::ServoUnits => p[kp(0)] = 1.0,
            Target::Torques { .. } => p[g..g + 2 * n].copy_from_slice(&p0[g..g + 2 * n]),
        }
        if let Some(p) = accept(p) {
            return Some(p);
        }
    }
    None
}

/// The inverse-dynamics equations at `samples` as a linear system in the output weights `cols`
/// (every other parameter as in `p0`, every output weight and servo gain at zero), with viscous
/// and Coulomb friction columns per joint after them; and q'' at the samples (central
/// differences of the measured q'). Joint friction is not in N_f but is in every real arm's
/// data (and our plant's): the friction columns absorb it, so that it does not bend the inertia
/// and gravity estimates, and the fits drop them.
fn design(
    layout: &Layout,
    p0: &[f64],
    data: &Trajectory,
    cols: &[usize],
    samples: &[usize],
) -> (nalgebra::DMatrix<f64>, Vec<[f64; MAX_JOINTS]>) {
    let n = layout.n;
    let rows = samples.len() * n;
    let mut a = nalgebra::DMatrix::<f64>::zeros(rows, cols.len() + 2 * n);
    for (s, &i) in samples.iter().enumerate() {
        for j in 0..n {
            let v = data.x_at(i)[n + j];
            a[(s * n + j, cols.len() + 2 * j)] = v;
            a[(s * n + j, cols.len() + 2 * j + 1)] = (v / 1e-2).tanh();
        }
    }
    let xdd: Vec<[f64; MAX_JOINTS]> = samples.iter().map(|&i| data.acceleration_at(i)).collect();
    let mut p = without_weights(layout, p0);
    let mut column = nalgebra::DVector::<f64>::zeros(rows);
    for (c, &k) in cols.iter().enumerate() {
        fill_column(layout, &mut p, k, data, samples, &xdd, &mut column);
        a.set_column(c, &column);
    }
    (a, xdd)
}

/// The n values per sample of `v` at `samples`, one after the other.
fn at_samples(v: &[f64], samples: &[usize], n: usize) -> nalgebra::DVector<f64> {
    nalgebra::DVector::from_iterator(
        samples.len() * n,
        samples
            .iter()
            .flat_map(|&i| v[i * n..(i + 1) * n].iter().copied()),
    )
}

/// The column of parameter k: the residual at `samples` with k at 1 and every weight at 0 (as
/// `p` has them, and leaves them).
fn fill_column(
    layout: &Layout,
    p: &mut [f64],
    k: usize,
    data: &Trajectory,
    samples: &[usize],
    xdd: &[[f64; MAX_JOINTS]],
    col: &mut nalgebra::DVector<f64>,
) {
    let n = layout.n;
    p[k] = 1.0;
    let mut out = [0.0; MAX_JOINTS];
    for (s, &i) in samples.iter().enumerate() {
        residual(layout, p, data.x_at(i), &xdd[s], data.r_at(i), &mut out);
        col.rows_mut(s * n, n).copy_from_slice(&out[..n]);
    }
    p[k] = 0.0;
}

/// Scale the rows of joint j (row s n + j of sample s) of `a` and `rhs` by 1 / the rms of
/// joint j's right-hand side.
fn weigh_rows(a: &mut nalgebra::DMatrix<f64>, rhs: &mut nalgebra::DVector<f64>, n: usize) {
    let samples = rhs.len() / n;
    for j in 0..n {
        let ms = (0..samples).map(|s| rhs[s * n + j].powi(2)).sum::<f64>() / samples.max(1) as f64;
        let w = 1.0 / ms.sqrt().max(1e-9);
        for s in 0..samples {
            a.row_mut(s * n + j).scale_mut(w);
            rhs[s * n + j] *= w;
        }
    }
}

/// Fewest equation rows (samples at the identification's step) the least squares takes.
const MIN_ROWS: usize = 20;

/// Relative SVD cut-off of the least-squares start.
const LS_TOLERANCE: f64 = 1e-6;
/// A known servo's torque at every sample of the filtered trajectory `data`. Filtering every
/// signal alike commutes with the servo's linear law while its torque is inside its limits (as
/// in arm3's training runs; a clamped torque would not): its torque from the filtered signals
/// is its filtered torque. Behind a drive's velocity filter (`velocity_cutoff_hz`) the velocity
/// the law saw was the positions' backward difference, low-passed: on filtered signals, the
/// filtered velocity half a sample late (the mean of two), through the same low-pass, which
/// starts settled on the first one.
fn servo_torques(servo: &ServoPrior, data: &Trajectory) -> Vec<f64> {
    let n = data.n;
    let drive = match servo {
        ServoPrior::Known {
            velocity_cutoff_hz: Some(fc),
            ..
        } => Some(crate::law::estimator::low_pass_share(*fc, data.h)),
        _ => None,
    };
    let velocity = |i: usize| &data.x_at(i)[n..];
    let mut seen = velocity(0).to_vec();
    let (mut x, mut tau) = (vec![0.0; 2 * n], vec![0.0; data.len() * n]);
    for i in 0..data.len() {
        x.copy_from_slice(data.x_at(i));
        if let Some(share) = drive {
            let late = velocity(i).iter().zip(velocity(i.saturating_sub(1)));
            for (v, (now, before)) in seen.iter_mut().zip(late) {
                *v += share * (0.5 * (now + before) - *v);
            }
            x[n..].copy_from_slice(&seen);
        }
        servo.torque(data.r_at(i), &x, &mut tau[i * n..(i + 1) * n]);
    }
    tau
}

/// Ridge on the velocity network's columns in the least-squares start.
const VELOCITY_RIDGE: f64 = 0.1;
/// Ridges on the live update's corrections (`update_with_torques`), relative to the largest
/// singular value of its columns (each in units of its output's size), smallest first.
const UPDATE_RIDGES: &[f64] = &[1e-5, 1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 0.3, 1.0];
/// Ridges tried on the inertia network's bumps, smallest first.
const INERTIA_RIDGES: &[f64] = &[0.0, 0.003, 0.01, 0.03, 0.1, 0.3, 1.0];

/// Give a model in k_p,1 units the one scale c that centres its eigenvalue range [lo, hi] over
/// the probes in eq. 2's [m_1, m_2] geometrically (c^2 lo hi = m_1 m_2): every output weight
/// and gain times c. None if M-hat is not positive definite there.
fn scale_to_prior(
    layout: &Layout,
    mut p: Vec<f64>,
    probes: &[Vec<f64>],
    prior: &Prior,
) -> Option<Vec<f64>> {
    let n = layout.n;
    let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for q in probes {
        network::inertia(layout, &p, q, &mut m);
        let (l, h) = sym_eig_range(n, &m);
        lo = lo.min(l);
        hi = hi.max(h);
    }
    if !(lo > 0.0 && hi.is_finite()) {
        return None;
    }
    let c = (prior.m1 * prior.m2 / (lo * hi)).sqrt();
    for k in weight_indices(layout) {
        p[k] *= c;
    }
    p.iter().all(|v| v.is_finite()).then_some(p)
}
