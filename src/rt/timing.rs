//! Per-cycle timing of the control loop, recorded into memory allocated before the loop starts,
//! and the percentile summary computed after it.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// One cycle's timing.
#[derive(Debug, Clone, Copy, Default)]
pub struct CycleTiming {
    pub cycle: u64,
    pub lateness_ns: i64,
    pub compute_ns: u64,
    pub state_age_ns: u64,
    pub flags: u32,
}

/// A fixed-capacity record: `push` never allocates; cycles beyond the capacity are counted, not
/// stored.
pub struct TimingLog {
    rows: Vec<CycleTiming>,
    pub dropped: u64,
}

impl TimingLog {
    pub fn with_capacity(n: usize) -> Self {
        Self {
            rows: Vec::with_capacity(n),
            dropped: 0,
        }
    }
    #[inline]
    pub fn push(&mut self, row: CycleTiming) {
        if self.rows.len() < self.rows.capacity() {
            self.rows.push(row);
        } else {
            self.dropped += 1;
        }
    }
    pub fn rows(&self) -> &[CycleTiming] {
        &self.rows
    }
}

/// Percentiles of one timing quantity, ns.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Percentiles {
    pub count: u64,
    pub min_ns: i64,
    pub p50_ns: i64,
    pub p90_ns: i64,
    pub p99_ns: i64,
    pub p99_9_ns: i64,
    pub max_ns: i64,
    pub mean_ns: f64,
}

impl Percentiles {
    /// From raw samples (negative lateness, i.e. early wake-ups, is clamped at 0 in the
    /// histogram but kept in `min_ns`).
    pub fn from_samples(samples: impl IntoIterator<Item = i64>) -> Self {
        let mut h = Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3)
            .expect("constant histogram bounds are valid");
        let mut min = i64::MAX;
        let mut max = i64::MIN;
        let mut sum = 0.0;
        let mut n = 0u64;
        for s in samples {
            min = min.min(s);
            max = max.max(s);
            sum += s as f64;
            n += 1;
            h.saturating_record(s.max(1) as u64);
        }
        if n == 0 {
            return Self::default();
        }
        let q = |p: f64| h.value_at_quantile(p) as i64;
        Self {
            count: n,
            min_ns: min,
            p50_ns: q(0.5).clamp(min, max),
            p90_ns: q(0.9).clamp(min, max),
            p99_ns: q(0.99).clamp(min, max),
            p99_9_ns: q(0.999).clamp(min, max),
            max_ns: max,
            mean_ns: sum / n as f64,
        }
    }
}

/// The loop's timing over a run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct TimingSummary {
    pub cycles: u64,
    pub lateness: Percentiles,
    pub compute: Percentiles,
    pub state_age: Percentiles,
    /// Cycles whose compute time exceeded the period.
    pub overruns: u64,
    /// Cycles that started a full period or more late (a deadline passed without a cycle).
    pub missed_deadlines: u64,
    /// Cycles that used a state older than the stale limit.
    pub stale_states: u64,
}
