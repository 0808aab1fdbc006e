//! Differential evolution DE/rand/1/bin (Storn & Price; two-mass paper Section 3.1) with the
//! diversity stopping rule of the paper's Table 3.
//!
//! Each generation, for every target x_i: mutant v = x_r1 + F (x_r2 - x_r3) with r1, r2, r3
//! distinct and != i drawn at random; binomial crossover with rate CR (one component always from
//! the mutant); a component outside its bounds is redrawn uniformly inside them; the trial
//! replaces the target when its objective is not worse. Constraint handling is the objective's
//! business (DOCHM: the objective returns F(X) > 0 for infeasible candidates, -r_c for feasible
//! ones, so feasible always wins).
//!
//! Stopping rule (Table 3): over the last `eta` generations, the standard deviation of each
//! component of the best individual is below `epsilon` times that component's search range. (The
//! table writes the range as max - min of x_best,d; read over the same window that condition can
//! never hold, so the search range is used.)

use super::Optimiser;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::VecDeque;

#[derive(Debug, Clone, Serialize)]
pub struct DeConfig {
    pub np: usize,
    pub f: f64,
    pub cr: f64,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub seed: u64,
    /// Apply the diversity stopping rule (off: run to the iteration limit or a target).
    pub diversity_stop: bool,
    /// Stopping-rule window (generations).
    pub eta: usize,
    /// Stopping-rule threshold, as a fraction of each component's search range.
    pub epsilon: f64,
}

impl DeConfig {
    /// The paper's settings (Table 4) for given F and CR.
    pub fn paper(f: f64, cr: f64, lower: Vec<f64>, upper: Vec<f64>, seed: u64) -> Self {
        Self {
            np: 100,
            f,
            cr,
            lower,
            upper,
            seed,
            diversity_stop: true,
            eta: 100,
            epsilon: 0.01,
        }
    }

    pub fn validate(&self) -> Result<(), String> {
        if self.eta == 0 || self.eta > 100_000 {
            return Err(format!("eta must be in 1..=100000 (got {})", self.eta));
        }
        if self.np < 4 {
            return Err(format!("population size must be >= 4 (got {})", self.np));
        }
        if !(self.f > 0.0 && self.f <= 2.0) {
            return Err(format!("F must be in (0, 2] (got {})", self.f));
        }
        if !(0.0..=1.0).contains(&self.cr) {
            return Err(format!("CR must be in [0, 1] (got {})", self.cr));
        }
        if self.lower.len() != self.upper.len() || self.lower.is_empty() {
            return Err("bounds must have the same, non-zero length".into());
        }
        if self
            .lower
            .iter()
            .zip(&self.upper)
            .any(|(l, u)| l.partial_cmp(u) != Some(std::cmp::Ordering::Less))
        {
            return Err("every lower bound must be below its upper bound".into());
        }
        Ok(())
    }
}

pub struct DifferentialEvolution {
    cfg: DeConfig,
    rng: ChaCha8Rng,
    pop: Vec<Vec<f64>>,
    values: Vec<f64>,
    trials: Vec<Vec<f64>>,
    initialised: bool,
    generation: usize,
    evaluations: usize,
    best: usize,
    window: VecDeque<Vec<f64>>,
}

impl DifferentialEvolution {
    pub fn new(cfg: DeConfig) -> Result<Self, String> {
        cfg.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let d = cfg.lower.len();
        let pop: Vec<Vec<f64>> = (0..cfg.np)
            .map(|_| {
                (0..d)
                    .map(|j| rng.gen_range(cfg.lower[j]..cfg.upper[j]))
                    .collect()
            })
            .collect();
        Ok(Self {
            trials: pop.clone(),
            values: vec![f64::INFINITY; cfg.np],
            pop,
            rng,
            initialised: false,
            generation: 0,
            evaluations: 0,
            best: 0,
            window: VecDeque::with_capacity(cfg.eta + 1),
            cfg,
        })
    }

    pub fn population(&self) -> &[Vec<f64>] {
        &self.pop
    }

    /// Put known sets (clamped into the box) in the first places of the initial population,
    /// e.g. the set in service. Only before the first `tell`.
    pub fn seed_population(&mut self, seeds: &[Vec<f64>]) {
        if self.initialised {
            return;
        }
        for (member, s) in self.pop.iter_mut().zip(seeds) {
            for (j, v) in member.iter_mut().enumerate() {
                *v = s[j].clamp(self.cfg.lower[j], self.cfg.upper[j]);
            }
        }
        self.trials = self.pop.clone();
    }

    fn breed(&mut self) {
        let (np, d) = (self.cfg.np, self.cfg.lower.len());
        for i in 0..np {
            let pick = |exclude: &[usize], rng: &mut ChaCha8Rng| loop {
                let r = rng.gen_range(0..np);
                if !exclude.contains(&r) {
                    return r;
                }
            };
            let r1 = pick(&[i], &mut self.rng);
            let r2 = pick(&[i, r1], &mut self.rng);
            let r3 = pick(&[i, r1, r2], &mut self.rng);
            let jrand = self.rng.gen_range(0..d);
            for j in 0..d {
                let v = if j == jrand || self.rng.gen::<f64>() < self.cfg.cr {
                    let m = self.pop[r1][j] + self.cfg.f * (self.pop[r2][j] - self.pop[r3][j]);
                    if m < self.cfg.lower[j] || m > self.cfg.upper[j] {
                        self.rng.gen_range(self.cfg.lower[j]..self.cfg.upper[j])
                    } else {
                        m
                    }
                } else {
                    self.pop[i][j]
                };
                self.trials[i][j] = v;
            }
        }
    }
}

impl Optimiser for DifferentialEvolution {
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.initialised {
            self.breed();
            &self.trials
        } else {
            &self.pop
        }
    }

    fn candidates(&self) -> &[Vec<f64>] {
        if self.initialised {
            &self.trials
        } else {
            &self.pop
        }
    }

    fn thresholds(&self) -> Option<&[f64]> {
        // Trial i only matters if it is not worse than target i.
        self.initialised.then_some(&self.values[..])
    }

    fn tell(&mut self, values: &[f64]) {
        assert_eq!(values.len(), self.cfg.np, "one value per candidate");
        self.evaluations += values.len();
        if !self.initialised {
            // NaN objectives rank last.
            self.values = values
                .iter()
                .map(|v| if v.is_nan() { f64::INFINITY } else { *v })
                .collect();
            self.initialised = true;
        } else {
            for (i, v) in values.iter().enumerate() {
                if !v.is_nan() && *v <= self.values[i] {
                    self.values[i] = *v;
                    self.pop[i].copy_from_slice(&self.trials[i]);
                }
            }
            self.generation += 1;
        }
        self.best = (0..self.cfg.np)
            .min_by(|&a, &b| self.values[a].total_cmp(&self.values[b]))
            .unwrap_or(0);
        if self.cfg.diversity_stop {
            if self.window.len() == self.cfg.eta {
                self.window.pop_front();
            }
            self.window.push_back(self.pop[self.best].clone());
        }
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.pop[self.best], self.values[self.best])
    }

    fn generation(&self) -> usize {
        self.generation
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }

    fn converged(&self) -> bool {
        let n = self.window.len();
        if !self.cfg.diversity_stop || n < self.cfg.eta {
            return false;
        }
        (0..self.cfg.lower.len()).all(|d| {
            let mean = self.window.iter().map(|x| x[d]).sum::<f64>() / n as f64;
            let var = self
                .window
                .iter()
                .map(|x| (x[d] - mean).powi(2))
                .sum::<f64>()
                / n as f64;
            var.sqrt() < self.cfg.epsilon * (self.cfg.upper[d] - self.cfg.lower[d])
        })
    }
}
