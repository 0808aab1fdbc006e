//! An optimiser of your own behind evoloop's ask/tell interface (`Optimiser`), beside one of
//! evoloop's (differential evolution) used as a plain library, on the same function and budget.
//!
//! The optimiser is a (1+1) evolution strategy with the 1/5th success rule (Rechenberg): one
//! candidate per ask, the step size grown after a success and shrunk after a failure. Anything
//! that implements `Optimiser` runs in the same loop as evoloop's own (`optim::run`).
//!
//!     cargo run --release --example custom_optimiser

use evoloop::optim::{run as optimise, DeConfig, DifferentialEvolution, Optimiser};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// The (1+1) evolution strategy: a parent, its value, and the step size the 1/5th rule adapts,
/// inside a box.
pub struct OnePlusOne {
    parent: Vec<f64>,
    parent_value: f64,
    sigma: f64,
    candidate: Vec<Vec<f64>>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    rng: ChaCha8Rng,
    evaluations: usize,
}

impl OnePlusOne {
    /// Start at a random point of the box (seeded) with a step of a fifth of its width.
    pub fn new(lower: Vec<f64>, upper: Vec<f64>, seed: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let parent: Vec<f64> = lower
            .iter()
            .zip(&upper)
            .map(|(l, u)| rng.gen_range(*l..*u))
            .collect();
        let width = upper
            .iter()
            .zip(&lower)
            .map(|(u, l)| u - l)
            .fold(0.0, f64::max);
        Self {
            candidate: vec![parent.clone()],
            parent,
            parent_value: f64::INFINITY,
            sigma: 0.2 * width,
            lower,
            upper,
            rng,
            evaluations: 0,
        }
    }
}

impl Optimiser for OnePlusOne {
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.evaluations > 0 {
            let steps: Vec<f64> = (0..self.parent.len())
                .map(|_| self.rng.sample(StandardNormal))
                .collect();
            self.candidate[0] = (self.parent.iter().zip(&steps))
                .zip(self.lower.iter().zip(&self.upper))
                .map(|((p, s), (l, u))| (p + self.sigma * s).clamp(*l, *u))
                .collect();
        }
        &self.candidate
    }
    fn candidates(&self) -> &[Vec<f64>] {
        &self.candidate
    }
    fn tell(&mut self, values: &[f64]) {
        self.evaluations += 1;
        // The 1/5th rule: a success grows the step by e^(4/5)-ish, a failure shrinks it so that
        // a success rate of 1/5 keeps it steady.
        if values[0] <= self.parent_value {
            self.parent = self.candidate[0].clone();
            self.parent_value = values[0];
            self.sigma *= 1.5;
        } else {
            self.sigma *= 1.5f64.powf(-0.25);
        }
    }
    fn best(&self) -> (&[f64], f64) {
        (&self.parent, self.parent_value)
    }
    fn generation(&self) -> usize {
        self.evaluations
    }
    fn evaluations(&self) -> usize {
        self.evaluations
    }
    fn converged(&self) -> bool {
        self.sigma < 1e-12
    }
}

/// A 10-D sphere centred off the middle of [-5, 5]^10 (at 1.234 on every axis), 20 000
/// evaluations each: (ES best, DE best).
pub fn run() -> (f64, f64) {
    let sphere = |x: &[f64]| x.iter().map(|v| (v - 1.234).powi(2)).sum::<f64>();
    let (lower, upper) = (vec![-5.0; 10], vec![5.0; 10]);
    // evoloop's own loop (`optim::run`: ask, evaluate on every core, tell) drives either; the
    // budget is 20 000 evaluations: 20 000 generations of one, 500 of 40.
    let threads = evoloop::optim::all_cores();
    let mut es = OnePlusOne::new(lower.clone(), upper.clone(), 1);
    let es_best = optimise(&mut es, &sphere, threads, 20_000, None, |_| {}).value;
    let mut cfg = DeConfig::paper(0.5, 0.9, lower, upper, 1);
    cfg.np = 40;
    cfg.diversity_stop = false;
    let mut de = DifferentialEvolution::new(cfg).expect("valid DE settings");
    let de_best = optimise(&mut de, &sphere, threads, 500, None, |_| {}).value;
    (es_best, de_best)
}

#[allow(dead_code)]
fn main() {
    let (es, de) = run();
    println!("10-D shifted sphere, 20 000 evaluations: (1+1)-ES {es:.3e}, evoloop's DE {de:.3e}");
}
