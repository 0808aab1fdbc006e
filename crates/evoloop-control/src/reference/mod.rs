//! Reference signals: scalar set-points r(t) (a step, a square wave, a sequence of steps) and
//! joint-space trajectories with position, velocity and acceleration (rest-to-rest quintic
//! segments through waypoints; sums of sinusoids; the finite Fourier series of excitation
//! trajectories, `series`), all sampled into a `Setpoint`.

pub mod series;

use crate::MAX_JOINTS;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Largest |value| of a scalar reference (amplitude, offset, step value): far beyond any plant's
/// range, small enough that squared errors and their integrals stay finite.
pub const MAX_VALUE: f64 = 1e6;

/// What the controller tracks at one instant: per joint (or output) a desired position,
/// velocity and acceleration. Scalar references fill joint 0 with zero derivatives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Setpoint {
    /// The joints (outputs) the reference drives: the valid prefix of `q`, `qd` and `qdd`.
    pub n: usize,
    /// Desired position per joint (output), in the output's unit (rad, m, mm, °C ...).
    pub q: [f64; MAX_JOINTS],
    /// Desired velocity per joint, the output's unit per s (0 for a scalar reference).
    pub qd: [f64; MAX_JOINTS],
    /// Desired acceleration per joint, the output's unit per s^2 (0 for a scalar reference).
    pub qdd: [f64; MAX_JOINTS],
}

impl Default for Setpoint {
    fn default() -> Self {
        Self {
            n: 1,
            q: [0.0; MAX_JOINTS],
            qd: [0.0; MAX_JOINTS],
            qdd: [0.0; MAX_JOINTS],
        }
    }
}

impl Setpoint {
    /// A scalar set-point `r` on joint 0, with zero velocity and acceleration.
    pub fn scalar(r: f64) -> Self {
        let mut s = Self::default();
        s.q[0] = r;
        s
    }
}

/// Rest-to-rest quintic blend s(x) = 10x^3 - 15x^4 + 6x^5 on x in [0, 1] and its first two
/// derivatives in x (zero velocity and acceleration at both ends).
fn quintic(x: f64) -> (f64, f64, f64) {
    let x2 = x * x;
    let x3 = x2 * x;
    (
        x3 * (10.0 - 15.0 * x + 6.0 * x2),
        30.0 * x2 * (1.0 - 2.0 * x + x2),
        60.0 * x * (1.0 - 3.0 * x + 2.0 * x2),
    )
}

/// A reference signal (see the module docs), as validated from a scenario's `[reference]`;
/// values are in the plant output's unit, times in s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Reference {
    /// 0 before `start`, `amplitude` from `start` on.
    Step {
        /// The value from `start` on.
        amplitude: f64,
        /// When the step happens, s.
        start: f64,
    },
    /// From `start` on, `offset + amplitude` for the first half of each period and
    /// `offset - amplitude` for the second half; `offset` before `start`.
    Square {
        /// Half the peak-to-peak swing about `offset`.
        amplitude: f64,
        /// The wave's period, s.
        period: f64,
        /// The value the wave swings about, and holds before `start`.
        offset: f64,
        /// When the wave starts, s.
        start: f64,
    },
    /// Piecewise constant: `values[i]` from `times[i]` on (0 before `times[0]`); times increasing.
    Steps {
        /// When each value takes over, s, increasing.
        times: Vec<f64>,
        /// The values, one per time.
        values: Vec<f64>,
    },
    /// A sampled sequence repeated for ever: `values[k mod N]` at t = k `period` (the value of the
    /// nearest sample instant, so accumulated float time lands on its sample).
    Samples {
        /// The sequence, one value per sample.
        values: Vec<f64>,
        /// The time between samples, s.
        period: f64,
    },
    /// Joint space, rest-to-rest quintic segments: `waypoints[k]` (one value per joint) at
    /// `times[k]`, held before the first and after the last; zero velocity and acceleration at
    /// every waypoint.
    Quintic {
        /// The waypoints' times, s, increasing.
        times: Vec<f64>,
        /// The waypoints, one value per joint each.
        waypoints: Vec<Vec<f64>>,
    },
    /// Joint space, sums of sinusoids:
    /// `q_j(t) = offsets[j] + sum_h amplitudes[j][h] sin(2 pi frequencies[h] t + phases[j][h])`.
    Sines {
        /// The mean position per joint.
        offsets: Vec<f64>,
        /// Per joint, the amplitude of each frequency.
        amplitudes: Vec<Vec<f64>>,
        /// The frequencies every joint shares, Hz.
        frequencies: Vec<f64>,
        /// Per joint, the phase of each frequency, rad.
        phases: Vec<Vec<f64>>,
    },
}

impl Reference {
    /// Number of joints (outputs) the reference drives.
    pub fn joints(&self) -> usize {
        match self {
            Reference::Quintic { waypoints, .. } => waypoints.first().map_or(1, |w| w.len()),
            Reference::Sines { offsets, .. } => offsets.len(),
            _ => 1,
        }
    }

    /// Sample the reference at time t. Allocation-free.
    pub fn sample(&self, t: f64, sp: &mut Setpoint) {
        sp.n = self.joints();
        sp.qd = [0.0; MAX_JOINTS];
        sp.qdd = [0.0; MAX_JOINTS];
        match self {
            Reference::Quintic { times, waypoints } => {
                let last = times.len() - 1;
                let k = times.iter().rposition(|tk| t >= *tk);
                match k {
                    None => sp.q[..sp.n].copy_from_slice(&waypoints[0]),
                    Some(k) if k == last => sp.q[..sp.n].copy_from_slice(&waypoints[last]),
                    Some(k) => {
                        let dt = times[k + 1] - times[k];
                        let (s, ds, dds) = quintic((t - times[k]) / dt);
                        let (from, to) = (&waypoints[k], &waypoints[k + 1]);
                        for j in 0..sp.n {
                            let (a, b) = (from[j], to[j]);
                            sp.q[j] = a + (b - a) * s;
                            sp.qd[j] = (b - a) * ds / dt;
                            sp.qdd[j] = (b - a) * dds / (dt * dt);
                        }
                    }
                }
            }
            Reference::Sines {
                offsets,
                amplitudes,
                frequencies,
                phases,
            } => {
                for j in 0..sp.n {
                    let (mut q, mut qd, mut qdd) = (offsets[j], 0.0, 0.0);
                    for (h, f) in frequencies.iter().enumerate() {
                        let w = TAU * f;
                        let (sn, cs) = (w * t + phases[j][h]).sin_cos();
                        let a = amplitudes[j][h];
                        q += a * sn;
                        qd += a * w * cs;
                        qdd -= a * w * w * sn;
                    }
                    sp.q[j] = q;
                    sp.qd[j] = qd;
                    sp.qdd[j] = qdd;
                }
            }
            _ => sp.q[0] = self.value(t),
        }
    }

    /// One line for a person: the kind and its key figures, not every value.
    pub fn describe(&self) -> String {
        match self {
            Reference::Step { amplitude, start } => format!("step to {amplitude} at {start} s"),
            Reference::Square {
                amplitude,
                period,
                offset,
                start,
            } => format!("square {offset} +- {amplitude}, period {period} s from {start} s"),
            Reference::Steps { times, .. } => format!("{} steps", times.len()),
            Reference::Samples { values, period } => {
                format!("{} samples every {period} s, repeating", values.len())
            }
            Reference::Quintic { times, .. } => {
                format!(
                    "quintic through {} waypoints, {} joints",
                    times.len(),
                    self.joints()
                )
            }
            Reference::Sines { frequencies, .. } => format!(
                "sums of {} sinusoids, {} joints",
                frequencies.len(),
                self.joints()
            ),
        }
    }

    /// Scalar value r(t) (joint 0 of a joint-space trajectory).
    pub fn value(&self, t: f64) -> f64 {
        match self {
            Reference::Step { amplitude, start } => {
                if t >= *start {
                    *amplitude
                } else {
                    0.0
                }
            }
            Reference::Square {
                amplitude,
                period,
                offset,
                start,
            } => {
                if t < *start {
                    return *offset;
                }
                let phase = ((t - start) / period).fract();
                if phase < 0.5 {
                    offset + amplitude
                } else {
                    offset - amplitude
                }
            }
            Reference::Steps { times, values } => {
                // Few entries: a linear scan is cheaper than a search and allocation-free.
                let mut r = 0.0;
                for (ti, vi) in times.iter().zip(values) {
                    if t >= *ti {
                        r = *vi;
                    } else {
                        break;
                    }
                }
                r
            }
            Reference::Samples { values, period } => {
                let k = (t / period).round().max(0.0) as usize;
                values[k % values.len()]
            }
            Reference::Quintic { .. } | Reference::Sines { .. } => {
                let mut sp = Setpoint::default();
                self.sample(t, &mut sp);
                sp.q[0]
            }
        }
    }

    /// Time of the last change of the reference (for settling-time measurement).
    pub fn last_change(&self, horizon: f64) -> f64 {
        match self {
            Reference::Step { start, .. } => *start,
            Reference::Square { period, start, .. } => {
                if horizon <= *start {
                    return *start;
                }
                let half = period / 2.0;
                start + ((horizon - start) / half).floor() * half
            }
            Reference::Steps { times, .. } => times
                .iter()
                .copied()
                .filter(|t| *t <= horizon)
                .fold(0.0, f64::max),
            Reference::Quintic { times, .. } => times
                .iter()
                .copied()
                .filter(|t| *t <= horizon)
                .fold(0.0, f64::max),
            // A trajectory that never rests: there is no settling to measure.
            Reference::Sines { .. } | Reference::Samples { .. } => horizon,
        }
    }
}
