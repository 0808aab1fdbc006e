//! Optimisers. Every optimiser is an ask/tell object over the `Optimiser` trait: it proposes a
//! generation of candidates, the caller evaluates them (in parallel, on whatever model), and
//! tells it the objective values (minimised). Seeded for reproducibility.

pub mod de;
pub mod ga;
pub mod hooke_jeeves;
pub mod hybrid;

pub use de::{DeConfig, DifferentialEvolution};
pub use ga::{Ga, GaConfig};
pub use hooke_jeeves::{HookeJeeves, LocalResult};

use std::time::Instant;

pub trait Optimiser {
    /// Candidates to evaluate now.
    fn ask(&mut self) -> &[Vec<f64>];
    /// The candidates the last `ask` returned.
    fn candidates(&self) -> &[Vec<f64>];
    /// Their objective values (minimised), in the order `ask` gave them.
    fn tell(&mut self, values: &[f64]);
    /// Best candidate so far and its value.
    fn best(&self) -> (&[f64], f64);
    /// Completed generations (iterations).
    fn generation(&self) -> usize;
    /// Objective evaluations so far.
    fn evaluations(&self) -> usize;
    /// The optimiser's own stopping rule says stop.
    fn converged(&self) -> bool;
    /// For each candidate of the last `ask`, the value it must reach (<=) to be of any use, when
    /// the optimiser knows one (DE: its target's value). Lets an objective stop early.
    fn thresholds(&self) -> Option<&[f64]> {
        None
    }
}

/// A function to minimise. `value_below` may stop early once it has proven the value is above
/// `threshold`, returning any number above it; the optimiser then makes the same decision as
/// with the exact value.
pub trait Objective: Sync {
    fn value(&self, x: &[f64]) -> f64;
    fn value_below(&self, x: &[f64], threshold: f64) -> f64 {
        let _ = threshold;
        self.value(x)
    }
}

impl<F: Fn(&[f64]) -> f64 + Sync> Objective for F {
    fn value(&self, x: &[f64]) -> f64 {
        self(x)
    }
}

/// Evaluate `candidates` with `f` on `threads` threads (1 = in this thread), each against its
/// threshold when given. The result does not depend on the thread count: each value is computed
/// independently.
pub fn evaluate<F: Objective + ?Sized>(
    candidates: &[Vec<f64>],
    thresholds: Option<&[f64]>,
    f: &F,
    threads: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; candidates.len()];
    let limits: Vec<f64> = match thresholds {
        Some(t) => t.to_vec(),
        None => vec![f64::INFINITY; candidates.len()],
    };
    let one = |c: &Vec<f64>, t: f64| {
        if t.is_finite() {
            f.value_below(c, t)
        } else {
            f.value(c)
        }
    };
    let threads = threads.max(1).min(candidates.len().max(1));
    if threads == 1 {
        for ((o, c), t) in out.iter_mut().zip(candidates).zip(&limits) {
            *o = one(c, *t);
        }
        return out;
    }
    let chunk = candidates.len().div_ceil(threads);
    std::thread::scope(|s| {
        for ((outs, cands), lims) in out
            .chunks_mut(chunk)
            .zip(candidates.chunks(chunk))
            .zip(limits.chunks(chunk))
        {
            let one = &one;
            s.spawn(move || {
                for ((o, c), t) in outs.iter_mut().zip(cands).zip(lims) {
                    *o = one(c, *t);
                }
            });
        }
    });
    out
}

/// Result of running an optimiser to its end.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunResult {
    pub best: Vec<f64>,
    pub value: f64,
    pub generations: usize,
    pub evaluations: usize,
    pub seconds: f64,
    /// Why it stopped: "converged" (the optimiser's rule), "max_generations" or "target".
    pub stopped_by: String,
    /// Best value after each generation.
    pub history: Vec<f64>,
}

/// Run `opt` on `f` until its stopping rule, `max_generations`, or (when given) `target` is
/// reached; `progress` is called after each generation.
pub fn run<O: Optimiser, F: Objective + ?Sized>(
    opt: &mut O,
    f: &F,
    threads: usize,
    max_generations: usize,
    target: Option<f64>,
    mut progress: impl FnMut(&O),
) -> RunResult {
    let t0 = Instant::now();
    let mut history = Vec::new();
    let stopped_by = loop {
        opt.ask();
        let values = evaluate(opt.candidates(), opt.thresholds(), f, threads);
        opt.tell(&values);
        history.push(opt.best().1);
        progress(opt);
        if target.is_some_and(|t| opt.best().1 <= t) {
            break "target";
        }
        if opt.converged() {
            break "converged";
        }
        if opt.generation() >= max_generations {
            break "max_generations";
        }
    };
    let (best, value) = opt.best();
    RunResult {
        best: best.to_vec(),
        value,
        generations: opt.generation(),
        evaluations: opt.evaluations(),
        seconds: t0.elapsed().as_secs_f64(),
        stopped_by: stopped_by.into(),
        history,
    }
}
