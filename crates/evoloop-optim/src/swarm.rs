//! What the population methods of the eMuPSO paper's study share (PSO, eMuPSO, GWO, WOA, GOA):
//! a box, a population of positions asked for evaluation, their values, the best position found
//! and the counters, behind the `Optimiser` ask/tell interface. Each algorithm is a `Rule` that
//! moves the population after each `tell`; everything is allocated once, at construction.

use super::rng::Xoshiro256pp;
use super::Optimiser;
use rand::{Rng, SeedableRng};

pub use crate::settings::check_box;
use crate::SettingsError;

/// The settings every swarm method takes.
#[derive(Debug, Clone, PartialEq)]
pub struct SwarmConfig {
    /// Lower bounds of the search box, one per object variable.
    pub lower: Vec<f64>,
    /// Upper bounds of the search box, each above its lower bound.
    pub upper: Vec<f64>,
    /// Population size.
    pub population: usize,
    /// The iteration budget (generations after the initial one): the schedules (inertia weight,
    /// GWO's and WOA's a, GOA's c) run from their start to their end value over it.
    pub iterations: usize,
    /// Seed of the initial population and of the method's random draws.
    pub seed: u64,
}

impl SwarmConfig {
    /// The box, a population and the iterations an evaluation budget allows: the initial
    /// population counts as one iteration, so `evaluations / population - 1` follow it.
    pub fn for_budget(
        lower: Vec<f64>,
        upper: Vec<f64>,
        population: usize,
        evaluations: usize,
        seed: u64,
    ) -> Self {
        Self {
            lower,
            upper,
            population,
            iterations: (evaluations / population.max(1)).saturating_sub(1).max(1),
            seed,
        }
    }

    /// Check the settings: the bounds a box, a population of at least 4, at least one
    /// iteration.
    pub fn validate(&self) -> Result<(), SettingsError> {
        check_box(&self.lower, &self.upper)?;
        if self.population < 4 {
            return Err(SettingsError::out_of_range(
                "population",
                ">= 4",
                self.population,
            ));
        }
        if self.iterations == 0 {
            return Err(SettingsError::out_of_range("iterations", ">= 1", 0));
        }
        Ok(())
    }

    /// Number of object variables (the box's dimension).
    pub fn dim(&self) -> usize {
        self.lower.len()
    }

    /// Upper minus lower bound of dimension j.
    pub fn range(&self, j: usize) -> f64 {
        self.upper[j] - self.lower[j]
    }
}

/// The population and its bookkeeping.
pub struct Swarm {
    /// The settings the swarm was built with.
    pub cfg: SwarmConfig,
    /// The random stream of the initial population and of the rule's draws.
    pub rng: Xoshiro256pp,
    /// The positions asked for (and, after `tell`, evaluated).
    pub x: Vec<Vec<f64>>,
    /// Their values (NaN counted as +inf).
    pub f: Vec<f64>,
    /// Best position found so far (the lower bounds before any value).
    pub best_x: Vec<f64>,
    /// Its value (+infinity before any).
    pub best_f: f64,
    /// Iterations completed (one per `tell`).
    pub generation: usize,
    /// Objective evaluations recorded.
    pub evaluations: usize,
}

impl Swarm {
    /// A uniformly random population in the box.
    pub fn new(cfg: SwarmConfig) -> Result<Self, SettingsError> {
        cfg.validate()?;
        let mut rng = Xoshiro256pp::seed_from_u64(cfg.seed);
        let x = (0..cfg.population)
            .map(|_| {
                (0..cfg.dim())
                    .map(|j| rng.gen_range(cfg.lower[j]..cfg.upper[j]))
                    .collect()
            })
            .collect();
        Ok(Self {
            rng,
            x,
            f: vec![f64::INFINITY; cfg.population],
            best_x: cfg.lower.clone(),
            best_f: f64::INFINITY,
            generation: 0,
            evaluations: 0,
            cfg,
        })
    }

    /// Start from `positions` instead of the random population (before the first `tell`): a
    /// swarm seeded from earlier elites. Missing members stay random; extra ones are ignored.
    pub fn start_from(&mut self, positions: &[Vec<f64>]) {
        assert_eq!(
            self.generation, 0,
            "only the initial population can be seeded"
        );
        for (x, p) in self.x.iter_mut().zip(positions) {
            for (j, (xj, pj)) in x.iter_mut().zip(p).enumerate() {
                *xj = pj.clamp(self.cfg.lower[j], self.cfg.upper[j]);
            }
        }
    }

    /// Record the values of the positions asked for; update the best.
    pub fn record(&mut self, values: &[f64]) {
        assert_eq!(values.len(), self.x.len(), "one value per candidate");
        for (i, v) in values.iter().enumerate() {
            let v = if v.is_nan() { f64::INFINITY } else { *v };
            self.f[i] = v;
            if v < self.best_f {
                self.best_f = v;
                self.best_x.copy_from_slice(&self.x[i]);
            }
        }
        self.evaluations += values.len();
    }

    /// Fraction of the iteration budget used, in [0, 1].
    pub fn progress(&self) -> f64 {
        (self.generation as f64 / self.cfg.iterations as f64).min(1.0)
    }

    /// `v` put back into dimension j's bounds.
    pub fn clamp(&self, j: usize, v: f64) -> f64 {
        v.clamp(self.cfg.lower[j], self.cfg.upper[j])
    }

    /// Indices of the `k` smallest of `values` into `out` (ascending), without allocating
    /// beyond `out`'s capacity.
    pub fn smallest(values: &[f64], k: usize, out: &mut Vec<usize>) {
        out.clear();
        for (i, v) in values.iter().enumerate() {
            let pos = out.partition_point(|&o| values[o] <= *v);
            if pos < k {
                if out.len() == k {
                    out.pop();
                }
                out.insert(pos, i);
            }
        }
    }
}

/// How one swarm method moves its population once the values of the last positions are known.
pub trait Rule {
    /// The algorithm's name in tables and JSON.
    const NAME: &'static str;
    /// Move `s.x` to the next positions to evaluate (`s.f` holds the values of the current ones,
    /// `s.generation` the iterations completed before this one).
    fn advance(&mut self, s: &mut Swarm);
    /// The method's own stopping rule.
    fn converged(&self, _s: &Swarm) -> bool {
        false
    }
}

/// A swarm method as an `Optimiser`.
pub struct SwarmOptimiser<R: Rule> {
    /// The population and its bookkeeping.
    pub swarm: Swarm,
    /// The method that moves it.
    pub rule: R,
}

impl<R: Rule> SwarmOptimiser<R> {
    /// The optimiser of `swarm` moved by `rule`.
    pub fn from_parts(swarm: Swarm, rule: R) -> Self {
        Self { swarm, rule }
    }
}

impl<R: Rule> Optimiser for SwarmOptimiser<R> {
    fn ask(&mut self) -> &[Vec<f64>] {
        &self.swarm.x
    }
    fn candidates(&self) -> &[Vec<f64>] {
        &self.swarm.x
    }
    fn tell(&mut self, values: &[f64]) {
        self.swarm.record(values);
        self.rule.advance(&mut self.swarm);
        self.swarm.generation += 1;
    }
    fn best(&self) -> (&[f64], f64) {
        (&self.swarm.best_x, self.swarm.best_f)
    }
    fn generation(&self) -> usize {
        self.swarm.generation
    }
    fn evaluations(&self) -> usize {
        self.swarm.evaluations
    }
    fn converged(&self) -> bool {
        self.rule.converged(&self.swarm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn smallest_keeps_the_k_best_in_order() {
        let v = [5.0, 1.0, 4.0, 0.5, 3.0, 1.0];
        let mut out = Vec::with_capacity(3);
        Swarm::smallest(&v, 3, &mut out);
        assert_eq!(out, vec![3, 1, 5]);
    }

    #[test]
    fn a_budget_gives_iterations_after_the_initial_population() {
        let c = SwarmConfig::for_budget(vec![0.0], vec![1.0], 30, 30_000, 0);
        assert_eq!(c.iterations, 999);
        assert!(SwarmConfig {
            population: 2,
            ..c.clone()
        }
        .validate()
        .is_err());
        assert!(SwarmConfig {
            upper: vec![0.0],
            ..c
        }
        .validate()
        .unwrap_err()
        .to_string()
        .contains("dimension 0"));
    }
}
