//! The magnetic-levitation closed loop of the fuzzy-network paper, Section 5.2: the PID (any
//! anti-windup scheme) on the maglev plant over a set-point trajectory with sensor noise, scored
//! by the index of eq. 31. One loop for everyone who needs it: the GA experiments (`evoloop tune`),
//! the indirect scheme's model, the tests and the benchmarks.

use crate::control::pid::{AntiWindup, Pid};
use crate::control::Controller;
use crate::msg::PlantState;
use crate::plant::maglev::{Maglev, MaglevParams};
use crate::plant::PlantSim;
use crate::reference::{Reference, Setpoint};
use serde::Serialize;

/// The experiment: plant, sampling, trajectory and noise.
#[derive(Debug, Clone, Serialize)]
pub struct Spec {
    pub plant: MaglevParams,
    pub period: f64,
    pub step: f64,
    pub noise_mm: f64,
    pub duration: f64,
    pub reference: Reference,
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
    pub g: f64,
    pub g_error: f64,
    pub g_current: f64,
    pub g_holding: f64,
    pub g_control: f64,
}

/// A closed-loop response: time, reference, output (mm), command (mA).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Trace {
    pub t: Vec<f64>,
    pub r: Vec<f64>,
    pub y: Vec<f64>,
    pub u: Vec<f64>,
}

/// Run the PID with `aw` and `params` on the experiment; None when the ball is lost (|y| > 4.5
/// mm, near the sensor's end). `seed` drives the sensor noise.
pub fn simulate(
    spec: &Spec,
    aw: AntiWindup,
    params: &[f64],
    seed: u64,
    mut trace: Option<&mut Trace>,
) -> Option<Cost> {
    let plant = Maglev::new(spec.plant.clone());
    let hold = spec.plant.hold_current_ma(spec.plant.mass_at(0.0));
    let mut sim = PlantSim::new(Box::new(plant), spec.step, spec.noise_mm, seed);
    let mut pid = Pid::new(
        aw,
        params,
        spec.period,
        (0.0, 1000.0 * spec.plant.i_max),
        hold,
    );
    let n = (spec.duration / spec.period).round() as usize;
    let mut state = PlantState::default();
    let mut sp = Setpoint::default();
    let mut u = [hold];
    // Eq. 31: 1/1000 per mA of coil current.
    let mut cost = super::cost::TrackingCost::new(1e-3);
    let lost = 0.9 * spec.plant.sensor_range_mm;
    for k in 0..n {
        sim.sample(k as u64, 0, &u, &mut state);
        if !state.y[0].is_finite() || state.y[0].abs() > lost {
            return None;
        }
        spec.reference.sample(state.t, &mut sp);
        pid.step(&state, &sp, &mut u);
        cost.add(&sp.q[..1], &state.y[..1], &u);
        if let Some(tr) = trace.as_deref_mut() {
            tr.t.push(state.t);
            tr.r.push(sp.q[0]);
            tr.y.push(state.y[0]);
            tr.u.push(u[0]);
        }
        sim.advance(&u, spec.period);
    }
    let g_holding = n as f64 * hold / 1000.0;
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

/// The value the GA minimises: G, or infinity for a lost ball.
pub struct Objective<'a> {
    pub spec: &'a Spec,
    pub aw: AntiWindup,
    pub seed: u64,
}

impl crate::optim::Objective for Objective<'_> {
    fn value(&self, x: &[f64]) -> f64 {
        simulate(self.spec, self.aw, x, self.seed, None).map_or(f64::INFINITY, |c| c.g)
    }
}
