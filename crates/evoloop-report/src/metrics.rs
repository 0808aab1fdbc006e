//! Step-response and tracking metrics computed from a run's samples.

use serde::{Deserialize, Serialize};

/// Step-response and tracking figures of one output against its reference over a run: settling
/// time, overshoot, IAE, ISE and the final and tail errors (`response_metrics`, `ResponseAcc`).
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ResponseMetrics {
    /// Time from the last reference change until |y - r| stays within `band` x step size for
    /// the rest of the run; null if it never settles.
    pub settling_time_s: Option<f64>,
    /// The band used, as a fraction of the step size (0.02 = 2 %).
    pub settling_band: f64,
    /// Largest excursion past the final reference, in % of the step size (0 if none).
    pub overshoot_pct: f64,
    /// Integral of |e| and of e^2 over the whole run (rectangle rule at the sample period).
    pub iae: f64,
    /// Integral of e^2 over the whole run (rectangle rule at the sample period).
    pub ise: f64,
    /// e = r - y at the last sample.
    pub final_error: f64,
    /// Largest |e| over the last 10 % of the run.
    pub max_error_tail: f64,
}

/// Metrics of output `y` tracking `r`, sampled at times `t` with period `dt`; `t_change` is the
/// time of the last reference change.
pub fn response_metrics(
    t: &[f64],
    r: &[f64],
    y: &[f64],
    dt: f64,
    t_change: f64,
) -> ResponseMetrics {
    let n = t.len().min(r.len()).min(y.len());
    if n == 0 {
        return ResponseMetrics::default();
    }
    let mut acc = ResponseAcc::new(n, t[n - 1], r[n - 1], dt, t_change);
    for i in 0..n {
        acc.add(t[i], r[i], y[i]);
    }
    acc.finish()
}

/// `response_metrics` one sample at a time, for a run read row by row: what it needs of the
/// whole run up front is its extent (samples, last time, last reference value).
pub struct ResponseAcc {
    m: ResponseMetrics,
    dt: f64,
    t_change: f64,
    n: usize,
    /// The first sample of the last 10 %.
    tail: usize,
    /// No sample at or after the change: the response is measured from the first.
    from_start: bool,
    r_final: f64,
    i: usize,
    /// Whether the response to the last change has begun (its step, band and sign are set).
    changed: bool,
    r_prev: f64,
    tol: f64,
    dir: f64,
    step: f64,
    over: f64,
    /// Whether a sample since the change left the band, and the time of the first sample after
    /// the last one that did.
    out: bool,
    t_after_out: Option<f64>,
}

impl ResponseAcc {
    /// An accumulator for a run of `n` samples whose last sample is at `t_last` (s) with reference
    /// `r_final`, sampled every `dt` (s), the last reference change at `t_change` (s).
    pub fn new(n: usize, t_last: f64, r_final: f64, dt: f64, t_change: f64) -> Self {
        Self {
            m: ResponseMetrics {
                settling_band: 0.02,
                ..Default::default()
            },
            dt,
            t_change,
            n,
            // An empty run (stopped before its first sample) has no tail.
            tail: n.saturating_sub((n / 10).max(1)),
            from_start: t_last < t_change - 1e-12,
            r_final,
            i: 0,
            changed: false,
            r_prev: 0.0,
            tol: 0.0,
            dir: 0.0,
            step: 0.0,
            over: 0.0,
            out: false,
            t_after_out: None,
        }
    }

    /// A sample that is not finite (a state the controller refused: its NaN is in run.csv as
    /// it came) is left out of the integrals and the settling, which would all be NaN; the
    /// refusals are counted in the summary.
    pub fn add(&mut self, t: f64, r: f64, y: f64) {
        let e = r - y;
        if !e.is_finite() {
            self.r_prev = if r.is_finite() { r } else { self.r_prev };
            self.i += 1;
            return;
        }
        let m = &mut self.m;
        m.iae += e.abs() * self.dt;
        m.ise += e * e * self.dt;
        m.final_error = e;
        if self.i >= self.tail {
            m.max_error_tail = m.max_error_tail.max(e.abs());
        }
        if !self.changed && (self.from_start || t >= self.t_change - 1e-12) {
            self.changed = true;
            let r_before = if self.i > 0 { self.r_prev } else { 0.0 };
            self.step = (self.r_final - r_before).abs();
            let scale = if self.step > 0.0 {
                self.step
            } else {
                self.r_final.abs().max(1e-12)
            };
            self.tol = m.settling_band * scale;
            // signum(0.0) is 1: no step has no direction (and no overshoot; it was 0/0).
            let d = self.r_final - r_before;
            self.dir = if d == 0.0 { 0.0 } else { d.signum() };
        }
        if self.changed {
            if e.abs() > self.tol {
                self.out = true;
                self.t_after_out = None;
            } else if self.out && self.t_after_out.is_none() {
                self.t_after_out = Some(t);
            }
            self.over = self.over.max((y - self.r_final) * self.dir);
        }
        self.r_prev = r;
        self.i += 1;
    }

    /// The metrics of the samples added: settling time 0 when no sample left the band, `None` when
    /// the last one was outside it. The default (no figures) for a run of no samples.
    pub fn finish(self) -> ResponseMetrics {
        let mut m = self.m;
        if self.n == 0 {
            return ResponseMetrics::default();
        }
        // Settled from the first sample after the last one outside the band.
        m.settling_time_s = match (self.out, self.t_after_out) {
            (false, _) => Some(0.0),
            (true, Some(t)) => Some(t - self.t_change),
            (true, None) => None,
        };
        if self.dir != 0.0 {
            m.overshoot_pct = 100.0 * self.over / self.step;
        }
        m
    }
}

/// Tracking error per joint over a run: e_i = r_i - y_i.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Tracking {
    /// Root-mean-square error per joint.
    pub rms: Vec<f64>,
    /// Largest |e| per joint.
    pub max_abs: Vec<f64>,
    /// RMS over all joints and samples.
    pub rms_all: f64,
}

/// Tracking metrics from reference and output columns (one per joint), skipping the samples
/// before `from` (e.g. a start-up transient).
pub fn tracking(refs: &[&[f64]], ys: &[&[f64]], from: usize) -> Tracking {
    tracking_in(refs, ys, from..usize::MAX)
}

/// Tracking metrics over the samples in `range` (clipped to the columns).
pub fn tracking_in(refs: &[&[f64]], ys: &[&[f64]], range: std::ops::Range<usize>) -> Tracking {
    let joints = refs.len().min(ys.len());
    let len = (0..joints)
        .map(|j| refs[j].len().min(ys[j].len()))
        .min()
        .unwrap_or(0);
    let mut acc = TrackingAcc::new(joints);
    let mut e = vec![0.0; joints];
    for k in range.start.min(len)..range.end.min(len) {
        for j in 0..joints {
            e[j] = refs[j][k] - ys[j][k];
        }
        acc.add(&e);
    }
    acc.finish()
}

/// `tracking_in` one sample at a time (the errors e_i = r_i - y_i of all joints).
#[derive(Debug, Clone)]
pub struct TrackingAcc {
    sum: Vec<f64>,
    max: Vec<f64>,
    n: usize,
}

impl TrackingAcc {
    /// An accumulator for `joints` joints with no samples yet.
    pub fn new(joints: usize) -> Self {
        Self {
            sum: vec![0.0; joints],
            max: vec![0.0; joints],
            n: 0,
        }
    }

    /// A sample with an error that is not finite (a refused state) is left out, as by
    /// `ResponseAcc::add`.
    pub fn add(&mut self, e: &[f64]) {
        if e.iter().any(|e| !e.is_finite()) {
            return;
        }
        for ((s, m), e) in self.sum.iter_mut().zip(&mut self.max).zip(e) {
            *s += e * e;
            *m = m.max(e.abs());
        }
        self.n += 1;
    }

    /// Samples counted so far (those with a non-finite error are not).
    pub fn samples(&self) -> usize {
        self.n
    }

    /// Start again with no samples.
    pub fn clear(&mut self) {
        self.sum.fill(0.0);
        self.max.fill(0.0);
        self.n = 0;
    }

    /// The tracking metrics of the samples counted so far (zeros with none); the accumulator stays
    /// usable.
    pub fn finish(&self) -> Tracking {
        let n = self.n;
        let rms = |s: f64| if n > 0 { (s / n as f64).sqrt() } else { 0.0 };
        let n_all = n * self.sum.len();
        Tracking {
            rms: self.sum.iter().map(|s| rms(*s)).collect(),
            max_abs: self.max.clone(),
            rms_all: if n_all > 0 {
                (self.sum.iter().sum::<f64>() / n_all as f64).sqrt()
            } else {
                0.0
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_that_ends_before_its_step_has_no_overshoot_not_nan() {
        // Stopped 3 ms into a run whose step comes at 0.5 s: no step, so no overshoot (it was
        // printed as "overshoot NaN %").
        let (t, r, y) = ([0.0, 0.001, 0.002], [0.0; 3], [0.0, 1e-4, -1e-4]);
        let m = response_metrics(&t, &r, &y, 0.001, 0.5);
        assert_eq!(m.overshoot_pct, 0.0);
        // A real step still has its overshoot.
        let (t, r, y) = ([0.0, 0.001, 0.002], [1.0; 3], [0.5, 1.1, 1.0]);
        let m = response_metrics(&t, &r, &y, 0.001, 0.0);
        assert!((m.overshoot_pct - 10.0).abs() < 1e-9, "{}", m.overshoot_pct);
    }

    /// A refused state's NaN in run.csv made the summary print "IAE NaN" (issue 63, item 8):
    /// the sample is left out, and the figures are the other samples'.
    #[test]
    fn a_sample_that_is_not_finite_is_left_out_not_nan() {
        let (t, r) = ([0.0, 0.001, 0.002, 0.003], [1.0; 4]);
        let with_nan = response_metrics(&t, &r, &[0.5, f64::NAN, 1.0, 1.0], 0.001, 0.0);
        let without = response_metrics(&t[..3], &r[..3], &[0.5, 1.0, 1.0], 0.001, 0.0);
        assert_eq!(with_nan.iae, without.iae);
        assert_eq!(with_nan.ise, without.ise);
        assert!(with_nan.settling_time_s.is_some_and(f64::is_finite));
        let mut acc = TrackingAcc::new(2);
        acc.add(&[0.1, 0.2]);
        acc.add(&[f64::NAN, 0.2]);
        assert_eq!(acc.samples(), 1);
        assert!(acc.finish().rms_all.is_finite());
    }
}
