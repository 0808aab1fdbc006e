//! Step-response and tracking metrics computed from a run's samples.

use serde::{Deserialize, Serialize};

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
    let band = 0.02;
    let mut m = ResponseMetrics {
        settling_band: band,
        ..Default::default()
    };
    for i in 0..n {
        let e = r[i] - y[i];
        m.iae += e.abs() * dt;
        m.ise += e * e * dt;
    }
    m.final_error = r[n - 1] - y[n - 1];
    let tail = n - (n / 10).max(1);
    m.max_error_tail = (tail..n).map(|i| (r[i] - y[i]).abs()).fold(0.0, f64::max);

    let i0 = t.iter().position(|&ti| ti >= t_change - 1e-12).unwrap_or(0);
    let r_final = r[n - 1];
    let r_before = if i0 > 0 { r[i0 - 1] } else { 0.0 };
    let step = (r_final - r_before).abs();
    let scale = if step > 0.0 {
        step
    } else {
        r_final.abs().max(1e-12)
    };
    let tol = band * scale;
    // Last sample outside the band: settled from the next one on.
    let last_out = (i0..n).rev().find(|&i| (r[i] - y[i]).abs() > tol);
    m.settling_time_s = match last_out {
        None => Some(0.0),
        Some(i) if i + 1 < n => Some(t[i + 1] - t_change),
        Some(_) => None,
    };
    let dir = (r_final - r_before).signum();
    if dir != 0.0 {
        let over = (i0..n).map(|i| (y[i] - r_final) * dir).fold(0.0, f64::max);
        m.overshoot_pct = 100.0 * over / step;
    }
    m
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
    let (from, len) = (range.start, range.end.saturating_sub(range.start));
    let mut out = Tracking::default();
    let (mut sum_all, mut n_all) = (0.0, 0usize);
    for (r, y) in refs.iter().zip(ys) {
        let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
        for (ri, yi) in r.iter().zip(y.iter()).skip(from).take(len) {
            let e = ri - yi;
            sum += e * e;
            max = max.max(e.abs());
            n += 1;
        }
        out.rms
            .push(if n > 0 { (sum / n as f64).sqrt() } else { 0.0 });
        out.max_abs.push(max);
        sum_all += sum;
        n_all += n;
    }
    out.rms_all = if n_all > 0 {
        (sum_all / n_all as f64).sqrt()
    } else {
        0.0
    };
    out
}
