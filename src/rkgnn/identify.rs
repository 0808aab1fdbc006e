//! Identification of an RKGNN from reference and output data (RKGNN paper, Section 5.1).
//!
//! The RKGNN is the Runge-Kutta-Gill step (`plant::gill`) wrapped around the function network
//! N_f; driven by the servo's reference it predicts the arm's output from one measured state.
//! The objective is eq. 13 with its constraints eqs. 14-16:
//!   J = (1/t_N) sum_i (|theta^(i) - theta(i)| + |theta^'(i) - theta'(i)|)
//!       + s_t/2 sum_j lambda_j [g_j^+]^2,   s_t = 10 + ln(k + 1) at generation k,
//! with lambda = (1000, 1, 1), g_1 = -Gamma (the smallest leading principal minor of M-hat),
//! g_2 = m_1 - lambda_min(M-hat), g_3 = lambda_max(M-hat) - m_2, each at its worst over probe
//! states drawn from the training data.
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
//! The bounds m_1, m_2 of Property 1 (eq. 2) are constants the method assumes known. We derive
//! them from the arm's true M(q) over the training data's joint positions: m_1 is the smallest
//! eigenvalue and m_2 the largest seen (the paper's 1.23 and 1.45 belong to its own arm). Besides
//! shaping M-hat, they fix the model's scale, which data without torques cannot: multiplying
//! M-hat, V-hat, G-hat and the torque network by one constant predicts the same motion.

use super::data::Trajectory;
use super::ea::{ChaoticEa, ChaoticEaConfig};
use super::network::{self, Layout, Mat, Network, Part, RbfCounts};
use crate::optim::{evaluate, Objective, Optimiser};
use crate::plant::gill::RungeKuttaGill;
use crate::MAX_JOINTS;
use serde::{Deserialize, Serialize};

/// Error charged per sample left when a prediction diverges.
pub const DIVERGED: f64 = 10.0;
/// Magnitude of a predicted state beyond which the prediction counts as diverged.
const STATE_LIMIT: f64 = 1e3;

/// Identification settings.
#[derive(Debug, Clone, Serialize)]
pub struct Settings {
    pub counts: RbfCounts,
    /// Use every `stride`-th sample (the RKGNN's step h = stride x the data's period).
    pub stride: usize,
    /// Fraction of the data (at the end) held out for `holdout_rms`.
    pub holdout: f64,
    /// Objective evaluations.
    pub evaluations: usize,
    pub ea: ChaoticEaConfig,
    /// Eq. 13's lambda_1..3.
    pub lambda: [f64; 3],
    /// Probe states for the constraints.
    pub probes: usize,
    pub threads: usize,
}

impl Settings {
    pub fn paper(n: usize, seed: u64, evaluations: usize) -> Self {
        Self {
            counts: RbfCounts::paper(n),
            stride: 10,
            holdout: 0.2,
            evaluations,
            ea: ChaoticEaConfig {
                seed,
                ..Default::default()
            },
            lambda: [1000.0, 1.0, 1.0],
            probes: 40,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

/// What an identification reports (`evoloop identify rkgnn --json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// Free-run prediction error over the training window, RMS per joint, rad.
    pub train_rms: Vec<f64>,
    /// The same over the held-out end of the data, predicted from its first measured state.
    pub holdout_rms: Vec<f64>,
    /// Smallest eigenvalue of M-hat over every training sample.
    pub min_eig_m_hat: f64,
    pub evaluations: usize,
    pub seconds: f64,
    pub generations: usize,
    /// Eq. 13 at the end (with the last generation's s_t).
    pub objective: f64,
    /// The RKGNN's step, s.
    pub h: f64,
    pub m1: f64,
    pub m2: f64,
    pub seed: u64,
    /// Best objective after each generation.
    pub history: Vec<f64>,
}

/// Eq. 2's bounds from a rigid-body model's M(q) over joint positions `qs`.
pub fn inertia_bounds<'a>(
    model: &crate::dynamics::Model,
    qs: impl Iterator<Item = &'a [f64]>,
) -> (f64, f64) {
    let n = model.dof();
    let mut data = model.data();
    let mut flat: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for q in qs {
        let m = model.mass_matrix(&mut data, q);
        for a in 0..n {
            for b in 0..n {
                flat[a * n + b] = m[(a, b)];
            }
        }
        let (l, h) = network::sym_eig_range(n, &flat);
        lo = lo.min(l);
        hi = hi.max(h);
    }
    (lo, hi)
}

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
pub fn constraints(layout: &Layout, p: &[f64], probes: &[Vec<f64>], m1: f64, m2: f64) -> [f64; 3] {
    let n = layout.n;
    let mut g = [f64::NEG_INFINITY; 3];
    let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
    for q in probes {
        network::inertia(layout, p, q, &mut m);
        let gamma = network::min_leading_minor(n, &m);
        let (lo, hi) = network::sym_eig_range(n, &m);
        g[0] = g[0].max(-gamma);
        g[1] = g[1].max(m1 - lo);
        g[2] = g[2].max(hi - m2);
    }
    g
}

/// Eq. 13 for one generation.
struct Fit<'a> {
    layout: &'a Layout,
    train: &'a Trajectory,
    probes: &'a [Vec<f64>],
    m1: f64,
    m2: f64,
    lambda: [f64; 3],
    s_t: f64,
}

impl Objective for Fit<'_> {
    fn value(&self, p: &[f64]) -> f64 {
        let g = constraints(self.layout, p, self.probes, self.m1, self.m2);
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
/// at 0. The torque scale m2 (rms theta_d'' + 9.81) only
/// sets how far the search steps at first, divided like every scale by sqrt(parameters).
pub fn initial(layout: &Layout, train: &Trajectory, m1: f64, m2: f64) -> (Vec<f64>, Vec<f64>) {
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
    let m_mid = 0.5 * (m1 + m2);
    // The starting servo: critically damped at 20 rad/s on the middle inertia (a stiff
    // industrial axis). Only a start: the search moves every weight.
    let (k_p, k_d) = (m_mid * 400.0, m_mid * 40.0);
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
                    let k = if p { k_p } else { k_d };
                    let c = a * (l as f64 - (net.rbfs as f64 - 1.0) / 2.0);
                    x0[b] = c;
                    s0[b] = 0.5 * a;
                    x0[b + 1] = a;
                    s0[b + 1] = 0.5 * a;
                    x0[b + 2] = k * c / (4.0 / std::f64::consts::E);
                    s0[b + 2] = torque_scale;
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
                        Part::Inertia(a, c) => {
                            w.fill(0.1 * m_mid);
                            if a == c {
                                // Broad bumps are near 1 over the data: split m_mid among them.
                                x0[b + n + 1] = m_mid / net.rbfs as f64;
                            }
                        }
                        Part::Velocity(_) => w.fill(m2),
                        _ => w.fill(torque_scale),
                    }
                }
            }
        }
    }
    // Every variable moves at once: steps of sigma per coordinate move the whole vector by
    // about sigma sqrt(n), so the per-coordinate scales are the part scales over sqrt(n).
    let shrink = 1.0 / (layout.len as f64).sqrt();
    s0.iter_mut().for_each(|v| *v *= shrink);
    (x0, s0)
}

/// Identify an RKGNN on `data` (the first 1 - holdout of it) with eq. 2's bounds `m1`, `m2`.
/// `progress(evaluations, best)` is called after each generation. Returns the network (with the
/// settings' RBF counts) and the report.
pub fn identify(
    data: &Trajectory,
    m1: f64,
    m2: f64,
    s: &Settings,
    mut progress: impl FnMut(usize, f64),
) -> Result<(Network, Report), String> {
    let t0 = std::time::Instant::now();
    let d = data.every(s.stride.max(1));
    let n_hold = ((d.len() as f64) * s.holdout).round() as usize;
    if d.len() < 20 || d.len() - n_hold < 10 {
        return Err(format!(
            "too few samples: {} at stride {} (need at least 20)",
            d.len(),
            s.stride
        ));
    }
    let split = d.len() - n_hold;
    let train = d.window(0, split);
    let hold = d.window(split - 1, d.len());
    let layout = Layout::new(d.n, s.counts);
    let probes: Vec<Vec<f64>> = (0..s.probes)
        .map(|k| train.x_at(k * train.len() / s.probes)[..d.n].to_vec())
        .collect();
    let (x0, s0) = initial(&layout, &train, m1, m2);
    let mut ea = ChaoticEa::new(s.ea, &x0, &s0);
    let mut history = Vec::new();
    while ea.evaluations() < s.evaluations {
        let s_t = 10.0 + (ea.generation() as f64 + 1.0).ln();
        let fit = Fit {
            layout: &layout,
            train: &train,
            probes: &probes,
            m1,
            m2,
            lambda: s.lambda,
            s_t,
        };
        ea.ask();
        let values = evaluate(ea.candidates(), None, &fit, s.threads);
        ea.tell(&values);
        history.push(ea.best().1);
        progress(ea.evaluations(), ea.best().1);
    }
    let (best, objective) = ea.best();
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
        m1,
        m2,
        seed: s.ea.seed,
        history,
    };
    Ok((net, report))
}
