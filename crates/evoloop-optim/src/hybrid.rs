//! The three-phase hybrid of the fuzzy-network paper (Section 4): (1) the GA alone explores;
//! (2) the GA continues and Hooke-Jeeves optimises the scaling factors of each new candidate;
//! (3) Hooke-Jeeves fine-tunes all parameters of the best set.
//!
//! Budgets. The paper counts 95 / 200 / 30 iterations and 660 evaluations for its synthetic
//! experiment: 10 initial sets plus two evaluations per iteration in every phase
//! (10 + 2 (95 + 200 + 30) = 660). Each phase therefore gets two evaluations per iteration;
//! phase 2 spends its budget on GA iterations (two children each) and on a Hooke-Jeeves search
//! of each child's scaling genes (at most one exploratory sweep, 2 per scaling gene), until the
//! budget is used; phase 3 runs Hooke-Jeeves on all genes within its budget. The evaluation
//! count is exact.

use super::{evaluate, Ga, GaConfig, HookeJeeves, Objective, Optimiser};
use serde::Serialize;
use std::time::Instant;

/// Settings of the three-phase `hybrid`.
#[derive(Debug, Clone)]
pub struct HybridConfig {
    /// The GA's settings (phases 1 and 2).
    pub ga: GaConfig,
    /// Iterations of the three phases (0 skips a phase).
    pub phases: [usize; 3],
    /// Gene indices Hooke-Jeeves optimises in phase 2 (the scaling factors).
    pub scaling: Vec<usize>,
    /// Threads for evaluating the GA's candidates.
    pub threads: usize,
    /// Hooke-Jeeves initial step, as a fraction of each gene's range.
    pub hj_step: f64,
    /// Phase 2: evaluations Hooke-Jeeves may spend on one candidate's scaling genes
    /// (0 = one exploratory sweep, 2 per scaling gene).
    pub hj_per_candidate: usize,
}

/// What `hybrid` found and what it spent, evaluation by evaluation.
#[derive(Debug, Clone, Serialize)]
pub struct HybridResult {
    /// Best set found.
    pub best: Vec<f64>,
    /// Its objective value.
    pub value: f64,
    /// Best value among the initial population.
    pub initial_best: f64,
    /// Objective evaluations made in all (the sum of `phase_evaluations`).
    pub evaluations: usize,
    /// Evaluations spent in each phase (phase 1 includes the initial population).
    pub phase_evaluations: [usize; 3],
    /// GA iterations run (phases 1 and 2).
    pub ga_iterations: usize,
    /// Every evaluation's value, in evaluation order.
    pub values: Vec<f64>,
    /// Best value so far after each evaluation.
    pub best_so_far: Vec<f64>,
    /// Wall-clock time of the run, s.
    pub seconds: f64,
}

/// Run the hybrid on `f` over the box [lower, upper], starting from `seeds` plus random sets;
/// `progress(evaluations, best)` after every GA iteration and local search.
pub fn hybrid<F: Objective + ?Sized>(
    cfg: &HybridConfig,
    f: &F,
    lower: &[f64],
    upper: &[f64],
    seeds: &[Vec<f64>],
    mut progress: impl FnMut(usize, f64),
) -> HybridResult {
    let t0 = Instant::now();
    let mut ga = Ga::new(cfg.ga.clone(), lower, upper, seeds);
    let mut values: Vec<f64> = Vec::new();
    let mut phase = [0usize; 3];
    let clean = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    // Phase 1: initial population and the GA alone.
    let init = evaluate(ga.ask(), None, f, cfg.threads);
    values.extend(init.iter().map(|v| clean(*v)));
    ga.tell(&init);
    let initial_best = ga.best().1;
    phase[0] += init.len();
    for _ in 0..cfg.phases[0] {
        let v = evaluate(ga.ask(), None, f, cfg.threads);
        values.extend(v.iter().map(|x| clean(*x)));
        ga.tell(&v);
        phase[0] += v.len();
        progress(values.len(), ga.best().1);
    }
    // Phase 2: GA iterations, Hooke-Jeeves on each child's scaling genes.
    let budget2 = 2 * cfg.phases[1];
    let hj_per_child = if cfg.hj_per_candidate > 0 {
        cfg.hj_per_candidate
    } else {
        2 * cfg.scaling.len()
    };
    while phase[1] + 2 <= budget2 {
        let v = evaluate(ga.ask(), None, f, cfg.threads);
        values.extend(v.iter().map(|x| clean(*x)));
        ga.tell(&v);
        phase[1] += v.len();
        if !cfg.scaling.is_empty() {
            let slots = ga.last_slots().to_vec();
            for slot in slots {
                let left = budget2 - phase[1];
                if left == 0 {
                    break;
                }
                let (pop, vals) = ga.population();
                let (x0, f0) = (pop[slot].clone(), vals[slot]);
                if !f0.is_finite() {
                    continue;
                }
                let sub_lo: Vec<f64> = cfg.scaling.iter().map(|i| lower[*i]).collect();
                let sub_hi: Vec<f64> = cfg.scaling.iter().map(|i| upper[*i]).collect();
                let s0: Vec<f64> = cfg.scaling.iter().map(|i| x0[*i]).collect();
                let seen = std::cell::RefCell::new(Vec::new());
                let sub_f = |s: &[f64]| {
                    let mut x = x0.clone();
                    for (k, i) in cfg.scaling.iter().enumerate() {
                        x[*i] = s[k];
                    }
                    let v = clean(f.value(&x));
                    seen.borrow_mut().push(v);
                    v
                };
                let hj = HookeJeeves {
                    initial_step: cfg.hj_step,
                    min_step: 1e-9,
                    max_evaluations: hj_per_child.min(left),
                };
                let r = hj.minimise_from(sub_f, &s0, Some(f0), &sub_lo, &sub_hi);
                values.extend(seen.into_inner());
                phase[1] += r.evaluations;
                if r.value < f0 {
                    let mut x = x0;
                    for (k, i) in cfg.scaling.iter().enumerate() {
                        x[*i] = r.x[k];
                    }
                    ga.replace(slot, x, r.value);
                }
            }
        }
        progress(values.len(), ga.best().1);
    }
    // Phase 3: Hooke-Jeeves on all genes of the best set.
    let (mut best, mut value) = (ga.best().0.to_vec(), ga.best().1);
    if cfg.phases[2] > 0 && value.is_finite() {
        let seen = std::cell::RefCell::new(Vec::new());
        let hj = HookeJeeves {
            initial_step: cfg.hj_step,
            min_step: 1e-9,
            max_evaluations: 2 * cfg.phases[2],
        };
        let r = hj.minimise_from(
            |x: &[f64]| {
                let v = clean(f.value(x));
                seen.borrow_mut().push(v);
                v
            },
            &best,
            Some(value),
            lower,
            upper,
        );
        values.extend(seen.into_inner());
        phase[2] = r.evaluations;
        if r.value < value {
            best = r.x;
            value = r.value;
        }
        progress(values.len(), value);
    }
    let mut run = f64::INFINITY;
    let best_so_far = values
        .iter()
        .map(|v| {
            run = run.min(*v);
            run
        })
        .collect();
    HybridResult {
        best,
        value,
        initial_best,
        evaluations: values.len(),
        phase_evaluations: phase,
        ga_iterations: ga.generation(),
        values,
        best_so_far,
        seconds: t0.elapsed().as_secs_f64(),
    }
}
