//! The benchmark study of the eMuPSO paper (Section 4.2, Tables 4-9): every algorithm on every
//! function of the suite, `runs` seeded runs each at the same evaluation budget, and the
//! statistics the paper reports (min, mean, std of the error f - f_min; Wilcoxon signed-rank of
//! eMuPSO against each peer; win/tie/loss per group).
//!
//! Shifted copies: GWO and WOA move towards the origin by construction (their updates scale
//! positions towards the leaders and shrink them), so on functions whose minimiser is the
//! origin they are flattered. Every origin-centred function therefore also runs as
//! `<key>_shifted`: g(x) = f(R (x - o)), o uniform in the middle 80 % of the box and R a random
//! rotation, both drawn from a fixed seed per function (the same copy for every algorithm and
//! run). g has f's minimum f_min at x = o.
//!
//! Runs are the parallel unit: each run evaluates its populations in its own thread (a
//! benchmark function costs tens of nanoseconds, far below what a hand-off to another thread
//! costs, see `super::PARALLEL_MIN_SAVING_NS`), and the runs share the cores.

use super::emupso::{EmuPso, EmuPsoSettings};
use super::jade::{Jade, JadeConfig};
use super::pso::Pso;
use super::suite::{self, Function};
use super::swarm::SwarmConfig;
use super::wolves::{Goa, Gwo, Woa};
use super::{DeConfig, DifferentialEvolution, Ga, GaConfig, Optimiser};
use crate::report::stats::{wilcoxon, Wilcoxon};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use std::cell::RefCell;

/// The study's algorithms: the paper's six, then the real-coded GA of the fuzzy-network paper
/// and JADE, the adaptive DE the Python libraries offer (`super::jade`). (Hooke-Jeeves is a
/// local search from one point, not a population method; it is left out.)
pub const ALGORITHMS: [&str; 8] = ["emupso", "pso", "woa", "gwo", "goa", "de", "ga", "jade"];

/// The algorithm every peer is compared with.
pub const SUBJECT: &str = "emupso";

/// Points of each run's convergence curve (best error so far), evenly spaced in evaluations.
pub const CHECKPOINTS: usize = 60;

/// An optimiser of the study over a box, for a population and an evaluation budget.
/// DE is DE/rand/1/bin with F = 0.5, CR = 0.9 (Storn and Price's standard; the paper gives no
/// settings) and no stopping rule; the GA's mutation steps shrink to zero at the end of the
/// budget (N_max of its eq. 19 = its iterations: two evaluations each after the first
/// population).
pub fn build(
    name: &str,
    lower: &[f64],
    upper: &[f64],
    population: usize,
    evaluations: usize,
    seed: u64,
) -> Result<Box<dyn Optimiser + Send>, String> {
    build_seeded(name, lower, upper, population, evaluations, seed, &[])
}

/// `build`, with user-specified sets placed in the GA's initial population (the fuzzy-network
/// paper's GA starts from prespecified sets; the swarms and DE start at random and ignore them).
pub fn build_seeded(
    name: &str,
    lower: &[f64],
    upper: &[f64],
    population: usize,
    evaluations: usize,
    seed: u64,
    seeds: &[Vec<f64>],
) -> Result<Box<dyn Optimiser + Send>, String> {
    let swarm = || {
        SwarmConfig::for_budget(
            lower.to_vec(),
            upper.to_vec(),
            population,
            evaluations,
            seed,
        )
    };
    Ok(match name {
        "emupso" => Box::new(EmuPso::new(swarm(), EmuPsoSettings::default())?),
        "pso" => Box::new(Pso::new(swarm())?),
        "gwo" => Box::new(Gwo::new(swarm())?),
        "woa" => Box::new(Woa::new(swarm())?),
        "goa" => Box::new(Goa::new(swarm())?),
        "de" => Box::new(DifferentialEvolution::new(DeConfig {
            np: population,
            f: 0.5,
            cr: 0.9,
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            seed,
            diversity_stop: false,
            eta: 1,
            epsilon: 0.0,
        })?),
        "jade" => Box::new(Jade::new(JadeConfig::new(
            population,
            lower.to_vec(),
            upper.to_vec(),
            seed,
        ))?),
        "ga" => Box::new(Ga::new(
            GaConfig {
                population,
                p_crossover: 0.9,
                p_mutation: None,
                max_iterations: (evaluations.saturating_sub(population) / 2).max(1),
                seed,
            },
            lower,
            upper,
            seeds,
        )),
        other => {
            return Err(format!(
                "unknown algorithm {other:?} (known: {})",
                ALGORITHMS.join(", ")
            ))
        }
    })
}

/// A shift and rotation: g(x) = f(R (x - o)).
#[derive(Debug, Clone, Serialize)]
pub struct Shift {
    pub offset: Vec<f64>,
    /// R, row-major, D x D.
    pub rotation: Vec<f64>,
}

/// A function of the suite as the study runs it, plain or shifted.
#[derive(Debug, Clone)]
pub struct Problem {
    pub key: String,
    pub function: &'static Function,
    pub shift: Option<Shift>,
}

thread_local! {
    /// R (x - o) of a shifted problem: one buffer per thread, so evaluating allocates nothing.
    static ROTATED: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// The seed of a function's shifted copy: fixed per key (FNV-1a of it).
fn shift_seed(key: &str) -> u64 {
    key.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A random rotation (Haar-distributed): Gram-Schmidt on a Gaussian matrix, rows orthonormal.
fn rotation(d: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut r: Vec<f64> = (0..d * d).map(|_| StandardNormal.sample(rng)).collect();
    for i in 0..d {
        for k in 0..i {
            let dot: f64 = (0..d).map(|j| r[i * d + j] * r[k * d + j]).sum();
            for j in 0..d {
                r[i * d + j] -= dot * r[k * d + j];
            }
        }
        let norm = (0..d).map(|j| r[i * d + j].powi(2)).sum::<f64>().sqrt();
        for j in 0..d {
            r[i * d + j] /= norm;
        }
    }
    r
}

impl Problem {
    pub fn plain(function: &'static Function) -> Self {
        Self {
            key: function.key.into(),
            function,
            shift: None,
        }
    }

    /// The shifted and rotated copy (module docs).
    pub fn shifted(function: &'static Function) -> Self {
        let key = format!("{}_shifted", function.key);
        let mut rng = ChaCha8Rng::seed_from_u64(shift_seed(&key));
        let (lower, upper) = function.bounds();
        let offset = lower
            .iter()
            .zip(&upper)
            .map(|(l, u)| {
                let m = 0.1 * (u - l);
                rng.gen_range(l + m..u - m)
            })
            .collect();
        let rotation = rotation(function.dim, &mut rng);
        Self {
            key,
            function,
            shift: Some(Shift { offset, rotation }),
        }
    }

    /// Whether the function's minimiser is the origin (it gets a shifted copy).
    pub fn origin_centred(function: &Function) -> bool {
        (function.argmin)(function.dim).iter().all(|v| *v == 0.0)
    }

    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        self.function.bounds()
    }

    pub fn f_min(&self) -> f64 {
        self.function.f_min
    }

    pub fn group(&self) -> &'static str {
        self.function.group
    }

    /// A minimiser.
    pub fn argmin(&self) -> Vec<f64> {
        match &self.shift {
            Some(s) => s.offset.clone(),
            None => (self.function.argmin)(self.function.dim),
        }
    }

    pub fn value(&self, x: &[f64]) -> f64 {
        let Some(s) = &self.shift else {
            return (self.function.f)(x);
        };
        ROTATED.with(|buf| {
            let mut y = buf.borrow_mut();
            let d = x.len();
            y.resize(d, 0.0);
            for (i, yi) in y.iter_mut().enumerate() {
                let row = &s.rotation[i * d..(i + 1) * d];
                *yi = row
                    .iter()
                    .zip(x.iter().zip(&s.offset))
                    .map(|(r, (xj, oj))| r * (xj - oj))
                    .sum();
            }
            (self.function.f)(&y)
        })
    }
}

/// The problems of a study: the named functions (all when `keys` is None, `<key>_shifted`
/// allowed), each origin-centred one followed by its shifted copy when `shifted` is set and no
/// keys are named.
pub fn problems(keys: Option<&[String]>, shifted: bool) -> Result<Vec<Problem>, String> {
    let Some(keys) = keys else {
        let mut out = Vec::new();
        for f in suite::all() {
            out.push(Problem::plain(f));
            if shifted && Problem::origin_centred(f) {
                out.push(Problem::shifted(f));
            }
        }
        return Ok(out);
    };
    keys.iter()
        .map(|k| {
            let (base, is_shifted) = match k.strip_suffix("_shifted") {
                Some(b) => (b, true),
                None => (k.as_str(), false),
            };
            let f =
                suite::get(base).ok_or_else(|| {
                    format!(
                    "unknown function {k:?} (known: {}, and <key>_shifted for origin-centred ones)",
                    suite::all().iter().map(|f| f.key).collect::<Vec<_>>().join(", ")
                )
                })?;
            if !is_shifted {
                Ok(Problem::plain(f))
            } else if Problem::origin_centred(f) {
                Ok(Problem::shifted(f))
            } else {
                Err(format!(
                    "{k:?}: {base} is not origin-centred, it has no shifted copy"
                ))
            }
        })
        .collect()
}

/// One run's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct RunResult {
    pub seed: u64,
    pub best_value: f64,
    pub error: f64,
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
) -> Result<RunResult, String> {
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
    pub mean_value: f64,
    pub mean_error: f64,
    /// Sample standard deviation (n - 1), as the paper's MATLAB `std`.
    pub std_error: f64,
    pub min_error: f64,
    pub median_error: f64,
    pub max_error: f64,
}

impl Cell {
    pub fn of(runs: &[RunResult]) -> Self {
        let n = runs.len() as f64;
        let mut e: Vec<f64> = runs.iter().map(|r| r.error).collect();
        e.sort_by(f64::total_cmp);
        let mean = e.iter().sum::<f64>() / n;
        let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        let m = e.len();
        let median = crate::report::stats::median(&e);
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
    Win,
    Tie,
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

    #[test]
    fn a_shifted_copy_has_its_minimum_at_the_offset_and_is_a_rotation() {
        for f in suite::all().iter().filter(|f| Problem::origin_centred(f)) {
            let p = Problem::shifted(f);
            let o = p.argmin();
            let (lo, hi) = p.bounds();
            assert!(o
                .iter()
                .zip(lo.iter().zip(&hi))
                .all(|(v, (l, h))| l < v && v < h));
            assert!(
                (p.value(&o) - f.f_min).abs() < 1e-12,
                "{}: {}",
                p.key,
                p.value(&o)
            );
            // R is orthonormal: R R^T = I.
            let s = p.shift.as_ref().unwrap();
            let d = f.dim;
            for i in 0..d {
                for k in 0..d {
                    let dot: f64 = (0..d)
                        .map(|j| s.rotation[i * d + j] * s.rotation[k * d + j])
                        .sum();
                    assert!((dot - if i == k { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
            // The sphere's copy is |x - o|^2 (rotation-invariant): checks R (x - o) itself.
            if f.key == "sphere" {
                let x: Vec<f64> = (0..d).map(|j| j as f64 - 10.0).collect();
                let direct: f64 = x.iter().zip(&o).map(|(a, b)| (a - b).powi(2)).sum();
                assert!((p.value(&x) - direct).abs() < 1e-9 * direct);
            }
        }
        // Same key, same copy.
        let a = Problem::shifted(suite::get("rastrigin").unwrap());
        let b = Problem::shifted(suite::get("rastrigin").unwrap());
        assert_eq!(a.argmin(), b.argmin());
    }

    #[test]
    fn the_origin_centred_functions_are_the_expected_ones() {
        let keys: Vec<&str> = suite::all()
            .iter()
            .filter(|f| Problem::origin_centred(f))
            .map(|f| f.key)
            .collect();
        for k in ["sphere", "griewank", "rastrigin", "ackley", "schwefel_1_2"] {
            assert!(keys.contains(&k), "{k} in {keys:?}");
        }
        for k in ["rosenbrock", "beale", "shekel5", "easom"] {
            assert!(!keys.contains(&k), "{k}");
        }
    }

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

    #[test]
    fn unknown_or_unshiftable_functions_are_refused_by_name() {
        let e = problems(Some(&["nope".into()]), true).unwrap_err();
        assert!(e.contains("\"nope\"") && e.contains("sphere"), "{e}");
        let e = problems(Some(&["rosenbrock_shifted".into()]), true).unwrap_err();
        assert!(e.contains("not origin-centred"), "{e}");
        let all = problems(None, true).unwrap();
        assert!(all.iter().any(|p| p.key == "rastrigin_shifted"));
        assert_eq!(problems(None, false).unwrap().len(), 37);
    }
}
