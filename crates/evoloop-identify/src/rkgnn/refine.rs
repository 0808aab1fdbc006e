//! Levenberg-Marquardt refinement of an identified model on the free-run output error.
//!
//! The least-squares start fits the inverse-dynamics equation with q'' from differences of
//! noisy measurements: an equation-error fit, biased toward zero on every coefficient whose
//! regressor carries noise (errors in variables), and it weighs the equation where the data
//! are, not the motion the controller will need. The output error of eq. 13 (the RKGNN's
//! free-run prediction against the measured output) has neither flaw: measurement noise enters
//! it additively, once. Its parameters are those the least squares solved for (every output
//! weight and servo gain but k_p,1, which holds the scale: torque-free data cannot tell it);
//! the RBF centres and widths stay put. The search is `optim::levenberg_marquardt` (a
//! forward-difference Jacobian, its columns computed in parallel); a step is taken only if it
//! lowers the error and leaves M-hat positive definite over the operating region's probes.

use super::data::Trajectory;
use super::identify::DIVERGED;
use evoloop_optim::levenberg_marquardt::{self as lm, Outcome};
use evoloop_rkgnn::network::Layout;

/// Velocity residuals are weighed by this (s): rad/s against rad, the arm's motion is a few
/// tenths of a hertz to a hertz, so a velocity error means about as much as a position error
/// a tenth of it.
const VELOCITY_WEIGHT: f64 = 0.1;

/// Samples per free-run segment (multiple shooting): each segment's prediction starts from its
/// first measured state. One free run over the whole record is what eq. 13 scores, but from a
/// start that loses the arm a few seconds in, its residual after that is flat (every entry
/// `DIVERGED`) and no derivative points back; segments of about a second keep every part of the
/// record informative while still spanning the servo's slowest mode.
pub const SEGMENT: usize = 100;

/// `train` cut into segments of `SEGMENT` samples (each shares its first sample with the last
/// of the one before).
pub fn segments(train: &Trajectory) -> Vec<Trajectory> {
    let mut out = Vec::new();
    let mut from = 0;
    while from + 1 < train.len() {
        let to = (from + SEGMENT).min(train.len());
        out.push(train.window(from, to));
        from = to - 1;
    }
    out
}

/// The free-run residual of `p` over `segments`: predicted minus measured positions, and
/// velocities times `VELOCITY_WEIGHT`, every sample after each segment's first. A prediction
/// that diverges leaves `DIVERGED` in every remaining entry of its segment.
pub fn residual(layout: &Layout, p: &[f64], segments: &[Trajectory], out: &mut Vec<f64>) {
    out.clear();
    for seg in segments {
        segment_residual(layout, p, seg, out);
    }
}

fn segment_residual(layout: &Layout, p: &[f64], train: &Trajectory, out: &mut Vec<f64>) {
    let n = train.n;
    let mut pred = Vec::with_capacity(train.x.len());
    super::identify::predict(layout, p, train, Some(&mut pred));
    for i in 1..train.len() {
        let m = train.x_at(i);
        let have = pred.len() >= 2 * n * (i + 1);
        for j in 0..2 * n {
            let w = if j < n { 1.0 } else { VELOCITY_WEIGHT };
            out.push(if have {
                w * (pred[2 * n * i + j] - m[j])
            } else {
                DIVERGED
            });
        }
    }
}

/// Refine `p`'s parameters `free` (indices into it) by Levenberg-Marquardt on the free-run
/// residual over `train`, for at most `iterations` accepted or rejected steps, on `threads`
/// threads. A step is taken only if `keep` holds for the new parameters (e.g. M-hat positive
/// definite over the operating region).
pub fn refine(
    layout: &Layout,
    p: &mut [f64],
    free: &[usize],
    train: &Trajectory,
    keep: impl Fn(&[f64]) -> bool,
    iterations: usize,
    threads: usize,
) -> Outcome {
    // Segments the start loses the arm on carry no gradient: they are left out (and a step
    // that loses it on a kept one raises the error, so it is refused).
    let mut o = Vec::new();
    let train: &Vec<Trajectory> = &segments(train)
        .into_iter()
        .filter(|seg| {
            o.clear();
            segment_residual(layout, p, seg, &mut o);
            !o.contains(&DIVERGED)
        })
        .collect();
    let settings = lm::Settings {
        iterations,
        threads,
    };
    let free_run = |p: &[f64], out: &mut Vec<f64>| residual(layout, p, train, out);
    lm::minimise(p, free, free_run, keep, settings)
}
