//! The magnetic-levitation closed loop of the fuzzy-network paper, Section 5.2: the PID (any
//! anti-windup scheme) on the maglev plant over a set-point trajectory with sensor noise, scored
//! by the index of eq. 31. One loop for everyone who needs it: the GA experiments (`evoloop tune`),
//! the indirect scheme's model, the tests and the benchmarks.

use crate::law::pid::{AntiWindup, Pid};
use crate::plant::maglev::{Maglev, MaglevParams};
use crate::reference::Reference;
use serde::{Deserialize, Serialize};

/// The experiment: plant, sampling, trajectory and noise.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Spec {
    /// The maglev plant's parameters (the paper's 160 g ball by default).
    pub plant: MaglevParams,
    /// Control (sampling) period, s (default 1 ms).
    pub period: f64,
    /// Integration step, s (default 0.25 ms).
    pub step: f64,
    /// Standard deviation of the sensor noise, mm (default 0.002).
    pub noise_mm: f64,
    /// Run length, s (default 2.5).
    pub duration: f64,
    /// The set-point trajectory, mm above the operating point (default `default_reference`).
    pub reference: Reference,
    /// G counts the samples from this time on (s): 0 scores the whole run from rest; the
    /// indirect scheme scores a repetition that starts where the previous one left the plant.
    pub score_from: f64,
}

impl Default for Spec {
    fn default() -> Self {
        Self {
            plant: MaglevParams::default(),
            period: 0.001,
            step: 0.00025,
            noise_mm: 0.002,
            duration: 2.5,
            reference: default_reference(),
            score_from: 0.0,
        }
    }
}

/// One repetition of the set-point trajectory (mm): up 2 mm, down 2 mm, back to the operating
/// point; each step's derivative kick saturates the amplifier at 0 or i_max.
pub fn default_reference() -> Reference {
    Reference::Steps {
        times: vec![0.2, 1.0, 1.8],
        values: vec![2.0, -2.0, 0.0],
    }
}

/// The index of eq. 31 and its parts: G = g_error + g_current, and g_current = g_holding (the
/// constant holding current over the run, the same for every controller) + g_control (the
/// current spent beyond it, which can be negative).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Cost {
    /// The index G of eq. 31: `g_error + g_current`.
    pub g: f64,
    /// Sum of |r - y| over the scored samples, mm.
    pub g_error: f64,
    /// Sum of |u| / 1000 over the scored samples (u in mA: 1/1000 per mA).
    pub g_current: f64,
    /// The constant holding current's share of `g_current`, the same for every controller.
    pub g_holding: f64,
    /// The current spent beyond the holding current: `g_current - g_holding` (can be negative).
    pub g_control: f64,
}

/// A closed-loop response: time, reference, output (mm), command (mA).
pub use super::Response as Trace;

/// Run the PID with `aw` and `params` on the experiment; None when the ball is lost (|y| > 4.5
/// mm, near the sensor's end). `seed` drives the sensor noise.
pub fn simulate(
    spec: &Spec,
    aw: AntiWindup,
    params: &[f64],
    seed: u64,
    trace: Option<&mut Trace>,
) -> Option<Cost> {
    let hold = spec.plant.hold_current_ma(spec.plant.mass_at(0.0));
    let pid = Pid::new(
        aw,
        params,
        spec.period,
        (0.0, 1000.0 * spec.plant.i_max),
        hold,
    );
    let lost = 0.9 * spec.plant.sensor_range_mm;
    let run = super::Run {
        reference: &spec.reference,
        period: spec.period,
        step: spec.step,
        duration: spec.duration,
        diverged: lost,
        noise_std: spec.noise_mm,
        seed,
        sensor_delay: 0,
        u0: hold,
    };
    let r = run.response(Box::new(Maglev::new(spec.plant.clone())), Box::new(pid));
    let n = (spec.duration / spec.period).round() as usize;
    if r.y.len() < n || r.y.iter().any(|y| !y.is_finite() || y.abs() > lost) {
        if let Some(tr) = trace {
            *tr = r;
        }
        return None;
    }
    // Eq. 31: 1/1000 per mA of coil current.
    let mut cost = super::cost::TrackingCost::new(1e-3);
    let from = ((spec.score_from / spec.period).round() as usize).min(n);
    for k in from..n {
        cost.add(&r.r[k..k + 1], &r.y[k..k + 1], &r.u[k..k + 1]);
    }
    let g_holding = (n - from) as f64 * hold / 1000.0;
    if let Some(tr) = trace {
        *tr = r;
    }
    // G as eq. 31 writes it: the error sum plus the current sum.
    Some(Cost {
        g: cost.error + cost.control,
        g_error: cost.error,
        g_current: cost.control,
        g_holding,
        g_control: cost.control - g_holding,
    })
}

/// The paper's tuned fuzzy anti-windup set.
pub const PAPER_FUZZY: [f64; 7] = [
    983.108, 0.0447895, 0.638417, 0.57288, 1.16908, 106.064, 1.05207,
];

/// The value the GA minimises: G, or infinity for a lost ball. It owns its experiment, so an
/// evaluation worker can rebuild it from its description (`optim::Job`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Objective {
    /// The experiment each candidate is run on.
    pub spec: Spec,
    /// The PID's anti-windup scheme.
    pub aw: AntiWindup,
    /// Seed of the sensor noise.
    pub seed: u64,
}

impl Objective {
    /// The `optim::Job` kind of this objective.
    pub const KIND: &'static str = "maglev";

    /// The paper's experiment (`Spec::default`) over its first `duration` s, with the fuzzy
    /// anti-windup PID and noise seed `seed`.
    pub fn fuzzy(duration: f64, seed: u64) -> Self {
        Self {
            spec: Spec {
                duration,
                ..Spec::default()
            },
            aw: AntiWindup::Fuzzy,
            seed,
        }
    }
}

impl crate::optim::Objective for Objective {
    fn value(&self, x: &[f64]) -> f64 {
        simulate(&self.spec, self.aw, x, self.seed, None).map_or(f64::INFINITY, |c| c.g)
    }
    fn describe(&self) -> Option<crate::optim::Job> {
        crate::optim::Job::of(Self::KIND, self)
    }
}
