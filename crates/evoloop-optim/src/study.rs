//! The benchmark study of the eMuPSO paper (Section 4.2, Tables 4-9): every algorithm on every
//! function of the suite (`optim::problem`, plain and shifted), `runs` seeded runs each at the
//! same evaluation budget, and the statistics the paper reports (min, mean, std of the error
//! f - f_min; Wilcoxon signed-rank of eMuPSO against each peer; win/tie/loss per group).
//!
//! Runs are the parallel unit: each run evaluates its populations in its own thread (a
//! benchmark function costs tens of nanoseconds, far below what a hand-off to another thread
//! costs, see `optim::PARALLEL_MIN_SAVING_NS`), and the runs share the cores.

use super::by_name::build;
use super::problem::Problem;
use evoloop_stats::{wilcoxon, Wilcoxon};
use serde::Serialize;

/// The algorithm every peer is compared with.
pub const SUBJECT: &str = "emupso";

/// Points of each run's convergence curve (best error so far), evenly spaced in evaluations.
pub const CHECKPOINTS: usize = 60;

/// One run's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    /// The run's seed.
    pub seed: u64,
    /// Best objective value found.
    pub best_value: f64,
    /// Its error, best value minus the function's f_min.
    pub error: f64,
    /// Objective evaluations made (at most the budget).
    pub evaluations: usize,
    /// Best error so far at evaluations budget * (k + 1) / CHECKPOINTS.
    pub curve: Vec<f64>,
}

/// One seeded run of `algorithm` on `problem`, never more than `evaluations` evaluations.
pub fn run_one(
    problem: &Problem,
    algorithm: &str,
    population: usize,
    evaluations: usize,
    seed: u64,
) -> Result<RunResult, super::by_name::BuildError> {
    let (lower, upper) = problem.bounds();
    let mut opt = build(algorithm, &lower, &upper, population, evaluations, seed)?;
    let mut curve = Vec::with_capacity(CHECKPOINTS);
    let f_min = problem.f_min();
    super::drive(
        opt.as_mut(),
        evaluations,
        |x| problem.value(x),
        |opt| {
            let best = opt.best().1 - f_min;
            while curve.len() < CHECKPOINTS
                && opt.evaluations() * CHECKPOINTS >= evaluations * (curve.len() + 1)
            {
                curve.push(best);
            }
        },
    );
    let best_value = opt.best().1;
    curve.resize(CHECKPOINTS, best_value - f_min);
    Ok(RunResult {
        seed,
        best_value,
        error: best_value - f_min,
        evaluations: opt.evaluations(),
        curve,
    })
}

/// The statistics of one algorithm on one function (Tables 4-6, results.json).
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// Mean best value over the runs.
    pub mean_value: f64,
    /// Mean final error f - f_min over the runs.
    pub mean_error: f64,
    /// Sample standard deviation (n - 1), as the paper's MATLAB `std`.
    pub std_error: f64,
    /// Smallest final error of the runs.
    pub min_error: f64,
    /// Median final error of the runs.
    pub median_error: f64,
    /// Largest final error of the runs.
    pub max_error: f64,
}

impl Cell {
    /// The statistics of `runs`, at least one (none panics).
    pub fn of(runs: &[RunResult]) -> Self {
        let n = runs.len() as f64;
        let mut e: Vec<f64> = runs.iter().map(|r| r.error).collect();
        e.sort_by(f64::total_cmp);
        let mean = e.iter().sum::<f64>() / n;
        let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let m = e.len();
        let median = evoloop_stats::median(&e);
        Self {
            mean_value: runs.iter().map(|r| r.best_value).sum::<f64>() / n,
            mean_error: mean,
            std_error: var.sqrt(),
            min_error: e[0],
            median_error: median,
            max_error: e[m - 1],
        }
    }
}

/// The outcome of eMuPSO against one peer on one function (Tables 8-9).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Outcome {
    /// eMuPSO's errors are lower (significant at 5 %, lower on more pairs).
    Win,
    /// No difference shown at 5 %, or as many pairs lower as higher.
    Tie,
    /// eMuPSO's errors are higher (significant at 5 %, higher on more pairs).
    Loss,
}

/// eMuPSO wins when the two-sided Wilcoxon test on the paired final errors (same seeds) rejects
/// equality at 5 % and eMuPSO is lower on more pairs; loses in the mirror case; ties otherwise.
pub fn outcome(test: &Wilcoxon) -> Outcome {
    if test.p_two_sided >= 0.05 || test.a_lower == test.a_higher {
        Outcome::Tie
    } else if test.a_lower > test.a_higher {
        Outcome::Win
    } else {
        Outcome::Loss
    }
}

/// The paired comparison of the subject with `peer` on one function.
pub fn compare(subject: &[RunResult], peer: &[RunResult]) -> (Wilcoxon, Outcome) {
    let a: Vec<f64> = subject.iter().map(|r| r.error).collect();
    let b: Vec<f64> = peer.iter().map(|r| r.error).collect();
    let w = wilcoxon(&a, &b);
    let o = outcome(&w);
    (w, o)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::by_name::ALGORITHMS;
    use crate::suite;

    #[test]
    fn every_algorithm_spends_exactly_the_budget_and_is_reproducible() {
        let p = Problem::plain(suite::get("sphere").unwrap());
        for a in ALGORITHMS {
            let r1 = run_one(&p, a, 30, 3000, 5).unwrap();
            let r2 = run_one(&p, a, 30, 3000, 5).unwrap();
            assert_eq!(r1.evaluations, 3000, "{a}");
            assert_eq!(r1.best_value.to_bits(), r2.best_value.to_bits(), "{a}");
            assert_eq!(r1.curve.len(), CHECKPOINTS);
            assert!(
                r1.curve.windows(2).all(|w| w[1] <= w[0]),
                "{a}: curve rises"
            );
            assert_eq!(*r1.curve.last().unwrap(), r1.error);
        }
        assert!(build("nope", &[0.0], &[1.0], 10, 100, 0).is_err());
    }

    #[test]
    fn statistics_and_outcomes_follow_their_definitions() {
        let runs = |e: &[f64]| -> Vec<RunResult> {
            e.iter()
                .map(|&v| RunResult {
                    seed: 0,
                    best_value: v + 1.0,
                    error: v,
                    evaluations: 0,
                    curve: vec![],
                })
                .collect()
        };
        let c = Cell::of(&runs(&[3.0, 1.0, 2.0, 4.0]));
        assert_eq!(
            (c.mean_error, c.min_error, c.median_error, c.max_error),
            (2.5, 1.0, 2.5, 4.0)
        );
        assert!((c.std_error - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert_eq!(c.mean_value, 3.5);
        let low: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let high: Vec<f64> = (0..10).map(|i| i as f64 + 1.0 + 0.01 * i as f64).collect();
        assert_eq!(compare(&runs(&low), &runs(&high)).1, Outcome::Win);
        assert_eq!(compare(&runs(&high), &runs(&low)).1, Outcome::Loss);
        assert_eq!(compare(&runs(&low), &runs(&low)).1, Outcome::Tie);
    }
}
