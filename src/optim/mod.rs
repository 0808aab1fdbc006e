//! Optimisers. Every optimiser is an ask/tell object over the `Optimiser` trait: it proposes a
//! generation of candidates, the caller evaluates them (in parallel, on whatever model), and
//! tells it the objective values (minimised). Seeded for reproducibility.

pub mod de;
pub mod hooke_jeeves;

pub use de::{DeConfig, DifferentialEvolution};
pub use hooke_jeeves::{HookeJeeves, LocalResult};

use std::time::Instant;

pub trait Optimiser {
    /// Candidates to evaluate now.
    fn ask(&mut self) -> &[Vec<f64>];
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
}

/// Evaluate `candidates` with `f` on `threads` threads (1 = in this thread). The result does not
/// depend on the thread count: each value is computed independently.
pub fn evaluate<F: Fn(&[f64]) -> f64 + Sync>(
    candidates: &[Vec<f64>],
    f: &F,
    threads: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; candidates.len()];
    let threads = threads.max(1).min(candidates.len().max(1));
    if threads == 1 {
        for (o, c) in out.iter_mut().zip(candidates) {
            *o = f(c);
        }
        return out;
    }
    let chunk = candidates.len().div_ceil(threads);
    std::thread::scope(|s| {
        for (outs, cands) in out.chunks_mut(chunk).zip(candidates.chunks(chunk)) {
            s.spawn(move || {
                for (o, c) in outs.iter_mut().zip(cands) {
                    *o = f(c);
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
pub fn run<O: Optimiser, F: Fn(&[f64]) -> f64 + Sync>(
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
        let values = evaluate(opt.ask(), f, threads);
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
