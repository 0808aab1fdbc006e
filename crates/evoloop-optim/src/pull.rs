//! A push-style optimiser (one that calls its objective, such as the GA/Hooke-Jeeves hybrid) as
//! an ask/tell `Optimiser`: it runs in a thread of its own whose objective hands each candidate
//! over and waits for its value. One candidate at a time, in the order the optimiser evaluates
//! them, so the sequence is the same as calling it directly with the same values: the direct
//! scheme, whose "evaluation" is a repetition on the plant, can drive it.

use super::hybrid::{hybrid, HybridConfig};
use super::{Objective, Optimiser};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Mutex;

enum FromOpt {
    Candidate(Vec<f64>),
    Done,
}

/// The objective the pushed optimiser calls: send the candidate, wait for its value. When the
/// driver has gone (budget spent), every value is +infinity and the optimiser runs out at once.
struct Relay {
    out: Mutex<Sender<FromOpt>>,
    back: Mutex<Receiver<f64>>,
}

impl Objective for Relay {
    fn value(&self, x: &[f64]) -> f64 {
        let sent = self
            .out
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .send(FromOpt::Candidate(x.to_vec()));
        if sent.is_err() {
            return f64::INFINITY;
        }
        self.back
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .recv()
            .unwrap_or(f64::INFINITY)
    }
}

/// A push-style optimiser, running in its own thread, driven through `Optimiser`: each
/// `ask` returns its next candidate (or none once it has finished), each `tell` hands the
/// value back.
pub struct Pulled {
    from_opt: Receiver<FromOpt>,
    to_opt: Sender<f64>,
    asked: Vec<Vec<f64>>,
    best: (Vec<f64>, f64),
    evaluations: usize,
    done: bool,
}

impl Pulled {
    /// The GA/Hooke-Jeeves hybrid of `cfg` over [lower, upper] from `seeds`, evaluated serially
    /// (one candidate at a time, whatever `cfg.threads` says).
    pub fn hybrid(mut cfg: HybridConfig, lower: &[f64], upper: &[f64], seeds: &[Vec<f64>]) -> Self {
        cfg.threads = 1;
        let (out, from_opt) = channel();
        let (to_opt, back) = channel();
        let (lower, upper, seeds) = (lower.to_vec(), upper.to_vec(), seeds.to_vec());
        std::thread::Builder::new()
            .name("evoloop-hybrid".into())
            .spawn(move || {
                let relay = Relay {
                    out: Mutex::new(out),
                    back: Mutex::new(back),
                };
                hybrid(&cfg, &relay, &lower, &upper, &seeds, |_, _| {});
                let _ = relay
                    .out
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .send(FromOpt::Done);
            })
            .expect("a thread for the hybrid");
        Self {
            from_opt,
            to_opt,
            asked: Vec::new(),
            best: (Vec::new(), f64::INFINITY),
            evaluations: 0,
            done: false,
        }
    }
}

impl Optimiser for Pulled {
    /// The next candidate, or none once the optimiser has finished.
    fn ask(&mut self) -> &[Vec<f64>] {
        self.asked.clear();
        if !self.done {
            match self.from_opt.recv() {
                Ok(FromOpt::Candidate(x)) => self.asked.push(x),
                Ok(FromOpt::Done) | Err(_) => self.done = true,
            }
        }
        &self.asked
    }
    fn candidates(&self) -> &[Vec<f64>] {
        &self.asked
    }
    fn tell(&mut self, values: &[f64]) {
        for (x, v) in self.asked.iter().zip(values) {
            self.evaluations += 1;
            if *v < self.best.1 {
                self.best = (x.clone(), *v);
            }
            let _ = self.to_opt.send(*v);
        }
    }
    fn best(&self) -> (&[f64], f64) {
        (&self.best.0, self.best.1)
    }
    fn generation(&self) -> usize {
        self.evaluations
    }
    fn evaluations(&self) -> usize {
        self.evaluations
    }
    fn converged(&self) -> bool {
        self.done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::GaConfig;

    fn cfg() -> HybridConfig {
        HybridConfig {
            ga: GaConfig {
                population: 6,
                max_iterations: 10,
                seed: 3,
                ..GaConfig::default()
            },
            phases: [5, 5, 4],
            scaling: vec![1],
            threads: 1,
            hj_step: 0.05,
            hj_per_candidate: 0,
        }
    }

    #[test]
    fn pulled_one_at_a_time_it_evaluates_what_the_pushed_hybrid_evaluates() {
        let f = |x: &[f64]| x.iter().map(|v| (v - 0.3) * (v - 0.3)).sum::<f64>();
        let (lo, hi) = (vec![-1.0; 3], vec![1.0; 3]);
        let pushed = hybrid(&cfg(), &f, &lo, &hi, &[], |_, _| {});
        let mut pulled = Pulled::hybrid(cfg(), &lo, &hi, &[]);
        let mut values = Vec::new();
        while let Some(x) = pulled.ask().first().cloned() {
            let v = f(&x);
            values.push(v);
            pulled.tell(&[v]);
        }
        assert_eq!(values, pushed.values);
        assert_eq!(pulled.best().1, pushed.value);
        assert!(pulled.converged());
    }
}
