//! The real-coded genetic algorithm of the fuzzy-network paper (Section 4), steady state:
//! - fitness-proportional selection of two parents (minimisation: windowed fitness
//!   f_i = G_worst - G_i + 0.1 (G_worst - G_best), so the worst member keeps a small chance);
//! - one-point weighted-average crossover (eqs. 17-18) with probability P_C: y ~ U[0, L),
//!   k = floor(y), W = y - k; genes before k stay, genes after k are exchanged, gene k becomes
//!   W A(k) + (1 - W) B(k) and W B(k) + (1 - W) A(k);
//! - non-uniform mutation (eq. 19, Michalewicz) of each gene with probability P_M = 1/L:
//!   X ~ U[-1, 1], s' = s + (s_max - s)(1 - X^e) for X >= 0, s - (s - s_min)(1 - (-X)^e)
//!   otherwise, e = (1 - t / N_max)^2, so steps shrink from global to local over the run;
//! - the two children replace the two worst members of the old population.
//!
//! A child whose value is not finite (e.g. a controller that destabilises the loop) is replaced
//! by a copy of the current best, as the paper does for the maglev experiments. While no member
//! has a finite value (every random set lost the ball), parents are chosen uniformly and failed
//! children are kept, so the search explores instead of panicking or collapsing to one point.
//! Each iteration asks for two evaluations; the first `ask` returns the initial population.

use super::Optimiser;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Settings of `Ga`; the defaults are population 10, P_C 0.9, P_M = 1/L, N_max 150 and
/// seed 1.
#[derive(Debug, Clone)]
pub struct GaConfig {
    /// Population size (at least 2).
    pub population: usize,
    /// Crossover probability P_C of a pair of parents.
    pub p_crossover: f64,
    /// Per-gene mutation probability; None = 1 / (number of genes).
    pub p_mutation: Option<f64>,
    /// N_max of eq. 19: the iteration at which mutation steps have shrunk to zero.
    pub max_iterations: usize,
    /// Seed of the initial population, the selections, crossovers and mutations.
    pub seed: u64,
}

impl Default for GaConfig {
    fn default() -> Self {
        Self {
            population: 10,
            p_crossover: 0.9,
            p_mutation: None,
            max_iterations: 150,
            seed: 1,
        }
    }
}

/// The fuzzy-network paper's steady-state real-coded GA (see the module): two children per
/// iteration. It has no stopping rule of its own: `converged` is always false.
pub struct Ga {
    cfg: GaConfig,
    lower: Vec<f64>,
    upper: Vec<f64>,
    rng: ChaCha8Rng,
    pop: Vec<Vec<f64>>,
    values: Vec<f64>,
    asked: Vec<Vec<f64>>,
    initialised: bool,
    iteration: usize,
    evaluations: usize,
    best: (Vec<f64>, f64),
    /// Population slots the last two children went to.
    slots: Vec<usize>,
    uniform_selections: usize,
    /// Selection's fitness values (scratch: an iteration allocates nothing).
    fit: Vec<f64>,
}

impl Ga {
    /// A GA over the box [lower, upper]; `seeds` (user-specified sets, clamped into the box) fill
    /// the first places of the initial population, the rest is uniform random.
    pub fn new(cfg: GaConfig, lower: &[f64], upper: &[f64], seeds: &[Vec<f64>]) -> Self {
        assert_eq!(lower.len(), upper.len());
        assert!(cfg.population >= 2, "a population of at least two");
        let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
        let mut pop: Vec<Vec<f64>> = seeds
            .iter()
            .take(cfg.population)
            .map(|s| {
                s.iter()
                    .zip(lower.iter().zip(upper))
                    .map(|(v, (l, u))| v.clamp(*l, *u))
                    .collect()
            })
            .collect();
        while pop.len() < cfg.population {
            pop.push(
                lower
                    .iter()
                    .zip(upper)
                    .map(|(l, u)| if u > l { rng.gen_range(*l..*u) } else { *l })
                    .collect(),
            );
        }
        Self {
            asked: pop.clone(),
            pop,
            values: Vec::new(),
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            rng,
            initialised: false,
            iteration: 0,
            evaluations: 0,
            best: (Vec::new(), f64::INFINITY),
            slots: Vec::with_capacity(2),
            uniform_selections: 0,
            fit: Vec::with_capacity(cfg.population),
            cfg,
        }
    }

    /// The population and its values (after the first `tell`).
    pub fn population(&self) -> (&[Vec<f64>], &[f64]) {
        (&self.pop, &self.values)
    }

    /// The population slots the children of the last iteration now occupy.
    pub fn last_slots(&self) -> &[usize] {
        &self.slots
    }

    /// Replace member `i` (e.g. after a local search improved it) and its value.
    pub fn replace(&mut self, i: usize, x: Vec<f64>, value: f64) {
        if value < self.best.1 {
            self.best = (x.clone(), value);
        }
        self.pop[i] = x;
        self.values[i] = value;
    }

    /// Fitness-proportional choice of one member. Members with an infinite cost (a lost ball)
    /// get no share; when no member has a finite cost there is nothing to be proportional to, so
    /// the choice is uniform (counted in `uniform_selections`).
    fn select(&mut self) -> usize {
        let finite = || self.values.iter().cloned().filter(|v| v.is_finite());
        let worst = finite().fold(f64::NEG_INFINITY, f64::max);
        let best = finite().fold(f64::INFINITY, f64::min);
        if !best.is_finite() {
            self.uniform_selections += 1;
            return self.rng.gen_range(0..self.values.len());
        }
        let mut fit = std::mem::take(&mut self.fit);
        fit.clear();
        if best > 0.0 {
            // Costs are positive (performance indices): fitness 1/G, invariant to G's scale.
            fit.extend(self.values.iter().map(|v| 1.0 / v));
        } else {
            let window = 0.1 * (worst - best) + 1e-12 * worst.abs().max(1e-300);
            fit.extend(self.values.iter().map(|v| {
                if v.is_finite() {
                    worst - v + window
                } else {
                    0.0
                }
            }));
        }
        let total: f64 = fit.iter().sum();
        let mut r = self.rng.gen_range(0.0..total);
        let mut chosen = fit.len() - 1;
        for (i, f) in fit.iter().enumerate() {
            if r < *f {
                chosen = i;
                break;
            }
            r -= f;
        }
        self.fit = fit;
        chosen
    }

    /// Parent choices made uniformly because no member had a finite cost.
    pub fn uniform_selections(&self) -> usize {
        self.uniform_selections
    }

    fn mutate(&mut self, x: &mut [f64]) {
        let l = x.len();
        let pm = self.cfg.p_mutation.unwrap_or(1.0 / l as f64);
        let progress = (self.iteration as f64 / self.cfg.max_iterations.max(1) as f64).min(1.0);
        let e = (1.0 - progress).powi(2);
        for (i, xi) in x.iter_mut().enumerate() {
            if self.rng.gen::<f64>() >= pm {
                continue;
            }
            let r: f64 = self.rng.gen_range(-1.0..=1.0);
            let (lo, hi) = (self.lower[i], self.upper[i]);
            *xi = if r >= 0.0 {
                *xi + (hi - *xi) * (1.0 - r.powf(e))
            } else {
                *xi - (*xi - lo) * (1.0 - (-r).powf(e))
            }
            .clamp(lo, hi);
        }
    }
}

/// One-point weighted-average crossover (eqs. 17-18) at the real-valued point y in [0, L).
pub fn crossover(a: &[f64], b: &[f64], y: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut c, mut d) = (Vec::new(), Vec::new());
    crossover_into(a, b, y, &mut c, &mut d);
    (c, d)
}

/// `crossover` into the children's existing buffers.
fn crossover_into(a: &[f64], b: &[f64], y: f64, c: &mut Vec<f64>, d: &mut Vec<f64>) {
    let k = (y.floor() as usize).min(a.len() - 1);
    let w = y - k as f64;
    c.clear();
    c.extend_from_slice(&a[..=k]);
    c.extend_from_slice(&b[k + 1..]);
    d.clear();
    d.extend_from_slice(&b[..=k]);
    d.extend_from_slice(&a[k + 1..]);
    c[k] = w * a[k] + (1.0 - w) * b[k];
    d[k] = w * b[k] + (1.0 - w) * a[k];
}

/// `to` = `from`, reusing `to`'s buffer.
fn copy_into(to: &mut Vec<f64>, from: &[f64]) {
    to.clear();
    to.extend_from_slice(from);
}

impl Optimiser for Ga {
    /// Two children per iteration, written into the buffers of the last two (nothing allocated
    /// once the first iteration has run).
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.initialised {
            let i = self.select();
            let j = self.select();
            let mut asked = std::mem::take(&mut self.asked);
            asked.resize_with(2, Vec::new);
            let [c, d] = &mut asked[..] else {
                unreachable!("two children")
            };
            if self.rng.gen::<f64>() < self.cfg.p_crossover {
                let y = self.rng.gen_range(0.0..self.pop[i].len() as f64);
                crossover_into(&self.pop[i], &self.pop[j], y, c, d);
            } else {
                copy_into(c, &self.pop[i]);
                copy_into(d, &self.pop[j]);
            }
            self.mutate(c);
            self.mutate(d);
            self.asked = asked;
        }
        &self.asked
    }

    fn candidates(&self) -> &[Vec<f64>] {
        &self.asked
    }

    fn tell(&mut self, values: &[f64]) {
        self.evaluations += values.len();
        if !self.initialised {
            self.values = values
                .iter()
                .map(|v| if v.is_finite() { *v } else { f64::INFINITY })
                .collect();
            self.initialised = true;
            for (x, v) in self.pop.iter().zip(&self.values) {
                if *v < self.best.1 || self.best.0.is_empty() {
                    self.best = (x.clone(), *v);
                }
            }
            return;
        }
        // The two worst of the old population make way: the first index of the largest value,
        // then the first of the largest among the rest (what a stable descending sort puts
        // first), chosen before any child is placed.
        let worst = |skip: Option<usize>| {
            let mut w: Option<usize> = None;
            for (i, v) in self.values.iter().enumerate() {
                if Some(i) != skip && w.is_none_or(|k| v.total_cmp(&self.values[k]).is_gt()) {
                    w = Some(i);
                }
            }
            w
        };
        let first = worst(None);
        let second = worst(first);
        self.slots.clear();
        self.slots.extend(first.into_iter().chain(second));
        for (k, v) in values.iter().enumerate().take(self.slots.len()) {
            let slot = self.slots[k];
            let x = &self.asked[k];
            if v.is_finite() {
                if *v < self.best.1 {
                    copy_into(&mut self.best.0, x);
                    self.best.1 = *v;
                }
                copy_into(&mut self.pop[slot], x);
                self.values[slot] = *v;
            } else if self.best.1.is_finite() {
                copy_into(&mut self.pop[slot], &self.best.0);
                self.values[slot] = self.best.1;
            } else {
                // No finite member yet: a copy of an equally failed "best" would only clone the
                // population into one point; keep the child so the search goes on exploring.
                copy_into(&mut self.pop[slot], x);
                self.values[slot] = f64::INFINITY;
            }
        }
        self.iteration += 1;
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.best.0, self.best.1)
    }
    fn generation(&self) -> usize {
        self.iteration
    }
    fn evaluations(&self) -> usize {
        self.evaluations
    }
    fn converged(&self) -> bool {
        false
    }
}
