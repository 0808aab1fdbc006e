//! Levenberg-Marquardt on a least-squares residual, with a forward-difference Jacobian whose
//! columns are computed in parallel: the local refinement after a global start (the RKGNN
//! identification's output-error fit, `rkgnn::refine`). Unlike the ask/tell optimisers it uses
//! the residual vector, not just its sum of squares, and a step is taken only if it lowers the
//! sum and a caller's condition holds for the new parameters (e.g. a model stays physical).
//!
//! ```
//! use evoloop_optim::levenberg_marquardt::{minimise, Settings};
//!
//! // y = a e^(b t) through three exact points of a = 2, b = -1, from a = 1, b = 0.
//! let t = [0.0, 1.0, 2.0];
//! let y: Vec<f64> = t.iter().map(|t: &f64| 2.0 * (-t).exp()).collect();
//! let residual = |p: &[f64], r: &mut Vec<f64>| {
//!     r.clear();
//!     r.extend(t.iter().zip(&y).map(|(t, y)| p[0] * (p[1] * t).exp() - y));
//! };
//! let mut p = [1.0, 0.0];
//! let s = Settings { iterations: 100, threads: 1 };
//! let out = minimise(&mut p, &[0, 1], residual, |_| true, s);
//! assert!(out.after < 1e-16 && out.after < out.before, "{out:?}");
//! assert!((p[0] - 2.0).abs() < 1e-6 && (p[1] + 1.0).abs() < 1e-6, "{p:?}");
//! ```

use nalgebra::{DMatrix, DVector};

/// Forward-difference step, relative to the parameter (with a floor for parameters near 0).
const FD_STEP: f64 = 1e-6;
/// Damping: start, growth on a rejected step, shrink on an accepted one.
const MU: (f64, f64, f64) = (1e-3, 10.0, 0.3);
/// The damping past which no step can be taken: the search stops.
const MU_MAX: f64 = 1e8;
/// A search stops when an accepted step improves the sum of squares by less than this fraction.
const TOLERANCE: f64 = 1e-5;

/// How long a search runs and on how many threads its Jacobian is computed.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Steps tried at most, accepted or rejected.
    pub iterations: usize,
    /// Threads sharing the Jacobian's columns.
    pub threads: usize,
}

/// What a search did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outcome {
    /// Steps tried, accepted or rejected.
    pub iterations: usize,
    /// The sum of squared residuals at the start.
    pub before: f64,
    /// The sum of squared residuals at the end.
    pub after: f64,
}

/// Minimise the sum of squares of `residual(p)` over `p`'s entries `free` (indices into `p`),
/// in place. `residual` writes the residual vector into its buffer (the same length on every
/// call); a step is taken only if it lowers the sum, the sum is finite and `keep` holds for the
/// new parameters. Stops after `settings.iterations` steps, when an accepted step gains less than
/// a relative 1e-5, or when the damping passes 1e8.
pub fn minimise<R, K>(
    p: &mut [f64],
    free: &[usize],
    residual: R,
    keep: K,
    settings: Settings,
) -> Outcome
where
    R: Fn(&[f64], &mut Vec<f64>) + Sync,
    K: Fn(&[f64]) -> bool,
{
    let mut r = Vec::new();
    residual(p, &mut r);
    let cost = |r: &[f64]| r.iter().map(|v| v * v).sum::<f64>();
    let before = cost(&r);
    let mut now = before;
    let mut mu = MU.0;
    let mut done = 0;
    let mut jac = jacobian(p, free, &residual, &r, settings.threads);
    while done < settings.iterations {
        done += 1;
        let jt = jac.transpose();
        let mut a = &jt * &jac;
        let g = &jt * DVector::from_column_slice(&r);
        for k in 0..free.len() {
            a[(k, k)] += mu * a[(k, k)].max(1e-12);
        }
        let Some(chol) = a.cholesky() else {
            mu *= MU.1;
            continue;
        };
        let step = chol.solve(&(-g));
        let mut trial = p.to_vec();
        for (k, &i) in free.iter().enumerate() {
            trial[i] += step[k];
        }
        let mut rt = Vec::new();
        residual(&trial, &mut rt);
        let c = cost(&rt);
        if c < now && c.is_finite() && keep(&trial) {
            let gain = (now - c) / now;
            p.copy_from_slice(&trial);
            r = rt;
            now = c;
            mu *= MU.2;
            if gain < TOLERANCE {
                break;
            }
            jac = jacobian(p, free, &residual, &r, settings.threads);
        } else {
            mu *= MU.1;
            if mu > MU_MAX {
                break;
            }
        }
    }
    Outcome {
        iterations: done,
        before,
        after: now,
    }
}

/// d residual / d p[free[k]] by forward differences, columns shared among `threads` threads.
fn jacobian<R>(p: &[f64], free: &[usize], residual: &R, r0: &[f64], threads: usize) -> DMatrix<f64>
where
    R: Fn(&[f64], &mut Vec<f64>) + Sync,
{
    let mut jac = DMatrix::<f64>::zeros(r0.len(), free.len());
    let threads = threads.max(1).min(free.len().max(1));
    let chunk = free.len().div_ceil(threads);
    let columns: Vec<Vec<(usize, Vec<f64>)>> = std::thread::scope(|s| {
        let handles: Vec<_> = free
            .chunks(chunk.max(1))
            .enumerate()
            .map(|(t, ks)| {
                s.spawn(move || {
                    let mut q = p.to_vec();
                    let mut r = Vec::new();
                    ks.iter()
                        .enumerate()
                        .map(|(c, &i)| {
                            let h = FD_STEP * p[i].abs().max(1e-3);
                            q[i] = p[i] + h;
                            residual(&q, &mut r);
                            q[i] = p[i];
                            let col = r.iter().zip(r0).map(|(a, b)| (a - b) / h).collect();
                            (t * chunk + c, col)
                        })
                        .collect()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (c, col) in columns.into_iter().flatten() {
        jac.set_column(c, &DVector::from_vec(col));
    }
    jac
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock's valley as residuals (10 (y - x^2), 1 - x), from (-1.2, 1).
    fn rosenbrock(p: &[f64], r: &mut Vec<f64>) {
        r.clear();
        r.extend([10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]]);
    }

    #[test]
    fn the_valley_is_followed_to_its_minimum_the_same_on_any_number_of_threads() {
        let run = |threads| {
            let mut p = [-1.2, 1.0];
            let s = Settings {
                iterations: 200,
                threads,
            };
            let out = minimise(&mut p, &[0, 1], rosenbrock, |_| true, s);
            (p, out)
        };
        let (p, out) = run(1);
        assert!(
            (p[0] - 1.0).abs() < 1e-3 && (p[1] - 1.0).abs() < 1e-3,
            "{p:?}"
        );
        assert!(out.after < 1e-6 * out.before, "{out:?}");
        assert_eq!(
            run(2),
            (p, out),
            "the Jacobian's columns do not depend on the threads"
        );
    }

    #[test]
    fn a_step_the_caller_refuses_is_not_taken_and_a_fixed_entry_stays() {
        // Only x is free: y stays at 1 whatever the residual would gain from moving it.
        let mut p = [-1.2, 1.0];
        let s = Settings {
            iterations: 50,
            threads: 1,
        };
        let out = minimise(&mut p, &[0], rosenbrock, |_| true, s);
        assert_eq!(p[1], 1.0);
        assert!(out.after < out.before, "{out:?}");
        // Every step refused: the parameters and the sum stay where they started.
        let mut q = [-1.2, 1.0];
        let out = minimise(&mut q, &[0, 1], rosenbrock, |_| false, s);
        assert_eq!(q, [-1.2, 1.0]);
        assert_eq!(out.after, out.before);
    }
}
