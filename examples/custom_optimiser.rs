//! An optimiser of your own behind evoloop's ask/tell interface (`Optimiser`), beside one of
//! evoloop's (differential evolution) used as a plain library, on the same function and budget.
//!
//! The optimiser is a (1+1) evolution strategy with the 1/5th success rule (Rechenberg): one
//! candidate per ask, the step size grown after a success and shrunk after a failure. Anything
//! that implements `Optimiser` can drive the same loops evoloop's own do.
//!
//!     cargo run --release --example custom_optimiser

use evoloop::optim::{DeConfig, DifferentialEvolution, Optimiser};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

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

    /// A standard normal draw (Box-Muller).
    fn normal(&mut self) -> f64 {
        let (u1, u2): (f64, f64) = (self.rng.gen_range(f64::EPSILON..1.0), self.rng.gen());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

impl Optimiser for OnePlusOne {
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.evaluations > 0 {
            let steps: Vec<f64> = (0..self.parent.len()).map(|_| self.normal()).collect();
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

/// Ask, evaluate, tell until `budget` evaluations or the optimiser's own stop: the loop every
/// evoloop optimiser runs in (there in parallel, over evaluation workers, or over a plant).
pub fn minimise(opt: &mut dyn Optimiser, f: &dyn Fn(&[f64]) -> f64, budget: usize) -> f64 {
    while opt.evaluations() < budget && !opt.converged() {
        let values: Vec<f64> = opt.ask().iter().map(|x| f(x)).collect();
        opt.tell(&values);
    }
    opt.best().1
}

/// A 10-D sphere centred off the middle of [-5, 5]^10 (at 1.234 on every axis), 20 000
/// evaluations each: (ES best, DE best).
pub fn run() -> (f64, f64) {
    let sphere = |x: &[f64]| x.iter().map(|v| (v - 1.234).powi(2)).sum::<f64>();
    let (lower, upper) = (vec![-5.0; 10], vec![5.0; 10]);
    let mut es = OnePlusOne::new(lower.clone(), upper.clone(), 1);
    let es_best = minimise(&mut es, &sphere, 20_000);
    let mut cfg = DeConfig::paper(0.5, 0.9, lower, upper, 1);
    cfg.np = 40;
    cfg.diversity_stop = false;
    let mut de = DifferentialEvolution::new(cfg).expect("valid DE settings");
    let de_best = minimise(&mut de, &sphere, 20_000);
    (es_best, de_best)
}

#[allow(dead_code)]
fn main() {
    let (es, de) = run();
    println!("10-D shifted sphere, 20 000 evaluations: (1+1)-ES {es:.3e}, evoloop's DE {de:.3e}");
}
