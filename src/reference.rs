//! Reference signals r(t): a step, a square wave and a sequence of steps.

use serde::Serialize;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Reference {
    /// 0 before `start`, `amplitude` from `start` on.
    Step { amplitude: f64, start: f64 },
    /// From `start` on, `offset + amplitude` for the first half of each period and
    /// `offset - amplitude` for the second half; `offset` before `start`.
    Square {
        amplitude: f64,
        period: f64,
        offset: f64,
        start: f64,
    },
    /// Piecewise constant: `values[i]` from `times[i]` on (0 before `times[0]`); times increasing.
    Steps { times: Vec<f64>, values: Vec<f64> },
}

impl Reference {
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
        }
    }
}
