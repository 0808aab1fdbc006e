//! Per-cycle timing of the control loop, recorded into memory allocated before the loop starts,
//! and the percentile summary computed after it.

use hdrhistogram::Histogram;
use serde::{Deserialize, Serialize};

/// One cycle's timing.
#[derive(Debug, Clone, Copy, Default)]
pub struct CycleTiming {
    /// Controller cycle index.
    pub cycle: u64,
    /// Wake-up lateness against the cycle's absolute deadline, ns (0 in lockstep; negative: early).
    pub lateness_ns: i64,
    /// Time from wake-up through the control law and the command's publication, ns.
    pub compute_ns: u64,
    /// Age of the state sample at wake-up (wake-up time minus its stamp), ns.
    pub state_age_ns: u64,
    /// The cycle's telemetry flags (`evoloop_msg::TELEMETRY_FLAG_*` bits).
    pub flags: u32,
}

/// The loop's timing, accumulated cycle by cycle in fixed memory (three histograms), so a run
/// of any length summarises exactly what it ran. `record` never allocates.
#[derive(Default)]
pub struct TimingStats {
    /// Wake-up lateness of every cycle, ns.
    pub lateness: Accumulator,
    /// Compute time of every cycle, ns.
    pub compute: Accumulator,
    /// Age of the state every cycle used, ns.
    pub state_age: Accumulator,
}

impl TimingStats {
    /// Cycles recorded (each records one value of every quantity).
    pub fn cycles(&self) -> u64 {
        self.lateness.n
    }

    /// Add one cycle's lateness, compute time and state age. No allocation.
    #[inline]
    pub fn record(&mut self, c: &CycleTiming) {
        self.lateness.record(c.lateness_ns);
        self.compute.record(c.compute_ns as i64);
        self.state_age.record(c.state_age_ns as i64);
    }
}

/// Percentiles of a stream of nanosecond values, in fixed memory: a histogram of 3 significant
/// digits from 1 ns to 60 s, with exact min, max and mean beside it.
pub struct Accumulator {
    h: Histogram<u64>,
    min: i64,
    max: i64,
    sum: f64,
    n: u64,
}

impl Default for Accumulator {
    fn default() -> Self {
        Self::new()
    }
}

impl Accumulator {
    /// An empty accumulator; its histogram (fixed size) is allocated here, once.
    pub fn new() -> Self {
        Self {
            h: Histogram::<u64>::new_with_bounds(1, 60_000_000_000, 3)
                .expect("constant histogram bounds are valid"),
            min: i64::MAX,
            max: i64::MIN,
            sum: 0.0,
            n: 0,
        }
    }

    /// Negative values (early wake-ups) are clamped at 1 ns in the histogram but kept in the
    /// minimum and the mean. No allocation: the histogram's size is fixed.
    #[inline]
    pub fn record(&mut self, s: i64) {
        self.min = self.min.min(s);
        self.max = self.max.max(s);
        self.sum += s as f64;
        self.n += 1;
        self.h.saturating_record(s.max(1) as u64);
    }

    /// The summary of the values recorded so far (all zeros when none was); the percentiles are
    /// the histogram's, kept within the exact minimum and maximum.
    pub fn percentiles(&self) -> Percentiles {
        if self.n == 0 {
            return Percentiles::default();
        }
        let (min, max) = (self.min, self.max);
        let q = |p: f64| self.h.value_at_quantile(p) as i64;
        Percentiles {
            count: self.n,
            min_ns: min,
            p50_ns: q(0.5).clamp(min, max),
            p90_ns: q(0.9).clamp(min, max),
            p99_ns: q(0.99).clamp(min, max),
            p99_9_ns: q(0.999).clamp(min, max),
            max_ns: max,
            mean_ns: self.sum / self.n as f64,
        }
    }
}

/// Percentiles of one timing quantity, ns.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Percentiles {
    /// Number of values.
    pub count: u64,
    /// Smallest value, exact (a negative lateness is an early wake-up), ns.
    pub min_ns: i64,
    /// Median, ns.
    pub p50_ns: i64,
    /// 90th percentile, ns.
    pub p90_ns: i64,
    /// 99th percentile, ns.
    pub p99_ns: i64,
    /// 99.9th percentile, ns.
    pub p99_9_ns: i64,
    /// Largest value, exact, ns.
    pub max_ns: i64,
    /// Mean, exact, ns.
    pub mean_ns: f64,
}

impl Percentiles {
    /// From raw samples (negative lateness, i.e. early wake-ups, is clamped at 1 ns in the
    /// histogram but kept in `min_ns`).
    pub fn from_samples(samples: impl IntoIterator<Item = i64>) -> Self {
        let mut a = Accumulator::new();
        for s in samples {
            a.record(s);
        }
        a.percentiles()
    }
}

/// The loop's timing over a run.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct TimingSummary {
    /// Cycles the loop ran.
    pub cycles: u64,
    /// Wake-up lateness against each cycle's absolute deadline (0 in lockstep).
    pub lateness: Percentiles,
    /// Time from wake-up through the control law and the command's publication.
    pub compute: Percentiles,
    /// Age of the state sample each cycle used, at wake-up.
    pub state_age: Percentiles,
    /// Cycles whose lateness plus compute time exceeded the period.
    pub overruns: u64,
    /// Control periods that passed without a cycle (whole periods skipped, those before the
    /// first state included).
    pub missed_deadlines: u64,
    /// Cycles that used a state older than the stale limit.
    pub stale_states: u64,
}
