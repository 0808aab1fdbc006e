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

use super::rng::Xoshiro256pp;
use super::Optimiser;
use crate::SettingsError;
use rand::{Rng, RngCore, SeedableRng};
use serde::Serialize;
use std::collections::VecDeque;

/// Settings of `DifferentialEvolution`: population, F, CR, the search box, the seed and the
/// diversity stopping rule.
#[derive(Debug, Clone, Serialize)]
pub struct DeConfig {
    /// Population size NP (at least 4: a mutant needs three members besides its target).
    pub np: usize,
    /// Mutation scale factor F, in (0, 2].
    pub f: f64,
    /// Binomial crossover rate CR, in [0, 1].
    pub cr: f64,
    /// Lower bounds of the search box, one per object variable.
    pub lower: Vec<f64>,
    /// Upper bounds of the search box, each above its lower bound.
    pub upper: Vec<f64>,
    /// Seed of the initial population, the mutants' members, the crossover and the redraws.
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

    /// Check the settings: `eta` in 1..=100000, NP >= 4, F in (0, 2], CR in [0, 1] and the
    /// bounds a box.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.eta == 0 || self.eta > 100_000 {
            return Err(SettingsError::out_of_range(
                "eta",
                "in 1..=100000",
                self.eta,
            ));
        }
        if self.np < 4 {
            return Err(SettingsError::out_of_range(
                "population size",
                ">= 4",
                self.np,
            ));
        }
        if !(self.f > 0.0 && self.f <= 2.0) {
            return Err(SettingsError::out_of_range("F", "in (0, 2]", self.f));
        }
        if !(0.0..=1.0).contains(&self.cr) {
            return Err(SettingsError::out_of_range("CR", "in [0, 1]", self.cr));
        }
        crate::settings::check_box(&self.lower, &self.upper)
    }
}

/// What DE and JADE (`super::jade`) keep alike: the targets and their values, the trials of
/// the generation under way and the counters. The first `ask` hands out the random initial
/// population, each later one the trials the method bred; a trial replaces its target when the
/// method's rule says so.
pub(super) struct Generations {
    pub pop: Vec<Vec<f64>>,
    pub values: Vec<f64>,
    pub trials: Vec<Vec<f64>>,
    pub initialised: bool,
    pub generation: usize,
    pub evaluations: usize,
    pub best: usize,
}

impl Generations {
    /// `np` members drawn uniformly in the box.
    pub fn random(np: usize, lower: &[f64], upper: &[f64], rng: &mut Xoshiro256pp) -> Self {
        let pop: Vec<Vec<f64>> = (0..np)
            .map(|_| {
                lower
                    .iter()
                    .zip(upper)
                    .map(|(l, u)| rng.gen_range(*l..*u))
                    .collect()
            })
            .collect();
        Self {
            trials: pop.clone(),
            values: vec![f64::INFINITY; np],
            pop,
            initialised: false,
            generation: 0,
            evaluations: 0,
            best: 0,
        }
    }

    pub fn candidates(&self) -> &[Vec<f64>] {
        if self.initialised {
            &self.trials
        } else {
            &self.pop
        }
    }

    /// Trial i only matters if it can replace target i.
    pub fn thresholds(&self) -> Option<&[f64]> {
        self.initialised.then_some(&self.values[..])
    }

    /// The values of the candidates handed out. The initial population takes them (NaN ranks
    /// last); afterwards `replaces(i, trial's value, target's value, target)` decides whether
    /// trial i takes target i's place (the target is passed before it is overwritten).
    pub fn tell(
        &mut self,
        values: &[f64],
        mut replaces: impl FnMut(usize, f64, f64, &[f64]) -> bool,
    ) {
        assert_eq!(values.len(), self.pop.len(), "one value per candidate");
        self.evaluations += values.len();
        if !self.initialised {
            for (slot, v) in self.values.iter_mut().zip(values) {
                *slot = if v.is_nan() { f64::INFINITY } else { *v };
            }
            self.initialised = true;
        } else {
            for (i, &v) in values.iter().enumerate() {
                if replaces(i, v, self.values[i], &self.pop[i]) {
                    self.values[i] = v;
                    self.pop[i].copy_from_slice(&self.trials[i]);
                }
            }
            self.generation += 1;
        }
        self.best = (0..self.pop.len())
            .min_by(|&a, &b| self.values[a].total_cmp(&self.values[b]))
            .unwrap_or(0);
    }

    pub fn best(&self) -> (&[f64], f64) {
        (&self.pop[self.best], self.values[self.best])
    }
}

/// DE/rand/1/bin with the two-mass paper's diversity stopping rule (see the module).
pub struct DifferentialEvolution {
    cfg: DeConfig,
    rng: Xoshiro256pp,
    /// One trial's random draws, one per component (scratch of `breed`).
    draws: Vec<u64>,
    g: Generations,
    window: VecDeque<Vec<f64>>,
}

impl DifferentialEvolution {
    /// A DE with `cfg` and its random initial population. Fails as `DeConfig::validate` does.
    pub fn new(cfg: DeConfig) -> Result<Self, SettingsError> {
        cfg.validate()?;
        let mut rng = Xoshiro256pp::seed_from_u64(cfg.seed);
        let g = Generations::random(cfg.np, &cfg.lower, &cfg.upper, &mut rng);
        Ok(Self {
            g,
            rng,
            draws: vec![0; cfg.lower.len()],
            window: VecDeque::with_capacity(cfg.eta + 1),
            cfg,
        })
    }

    /// The current targets, the population member i in place i.
    pub fn population(&self) -> &[Vec<f64>] {
        &self.g.pop
    }

    /// Put known sets (clamped into the box) in the first places of the initial population,
    /// e.g. the set in service. Only before the first `tell`.
    pub fn seed_population(&mut self, seeds: &[Vec<f64>]) {
        if self.g.initialised {
            return;
        }
        for (member, s) in self.g.pop.iter_mut().zip(seeds) {
            for (j, v) in member.iter_mut().enumerate() {
                *v = s[j].clamp(self.cfg.lower[j], self.cfg.upper[j]);
            }
        }
        self.g.trials = self.g.pop.clone();
    }

    /// One trial per target. Each component takes one 64-bit draw: its high half decides the
    /// crossover, its low half is the uniform redraw should the mutant leave the box (drawn
    /// whether needed or not, so that the update is a branch-free pass the compiler can
    /// vectorise; the optimiser's own cost per evaluation is what `optim bench` measures).
    fn breed(&mut self) {
        let Self {
            cfg, rng, g, draws, ..
        } = self;
        let (pop, trials) = (&g.pop, &mut g.trials);
        let (np, d, f, cr) = (cfg.np, cfg.lower.len(), cfg.f, cfg.cr);
        let (lower, upper, draws) = (&cfg.lower[..d], &cfg.upper[..d], &mut draws[..d]);
        for (i, trial) in trials.iter_mut().enumerate() {
            let r1 = pick(rng, np, &[i]);
            let r2 = pick(rng, np, &[i, r1]);
            let r3 = pick(rng, np, &[i, r1, r2]);
            let jrand = rng.gen_range(0..d);
            for r in draws.iter_mut() {
                *r = rng.next_u64();
            }
            let rule = Crossover {
                f,
                cr,
                jrand,
                lower,
                upper,
            };
            rule.trial(trial, [&pop[r1], &pop[r2], &pop[r3]], &pop[i], draws);
        }
    }
}

/// DE/rand/1/bin for one target: mutation, box repair and binomial crossover.
struct Crossover<'a> {
    f: f64,
    cr: f64,
    jrand: usize,
    lower: &'a [f64],
    upper: &'a [f64],
}

impl Crossover<'_> {
    super::wide_method! {
        /// `out` = the trial of `target` from the parents r1, r2, r3, one draw per component;
        /// four lanes wide where the CPU has AVX2 (`super::wide_method`), with the same
        /// results on every x86-64.
        fn trial, trial_avx2 => trial_body(
            out: &mut [f64], parents: [&[f64]; 3], target: &[f64], draws: &[u64]
        )
    }

    #[inline(always)]
    fn trial_body(&self, out: &mut [f64], parents: [&[f64]; 3], target: &[f64], draws: &[u64]) {
        let d = out.len();
        let [a, b, c] = parents.map(|p| &p[..d]);
        let (target, draws, lower, upper) = (
            &target[..d],
            &draws[..d],
            &self.lower[..d],
            &self.upper[..d],
        );
        let (f, cr, jrand) = (self.f, self.cr, self.jrand);
        for j in 0..d {
            let (u, redraw) = Xoshiro256pp::halves(draws[j]);
            let m = a[j] + f * (b[j] - c[j]);
            let inside = lower[j] + redraw * (upper[j] - lower[j]);
            let m = select((m < lower[j]) | (m > upper[j]), inside, m);
            out[j] = select((u < cr) | (j == jrand), m, target[j]);
        }
    }
}

/// A member index uniform in 0..n other than those in `exclude` (drawn again until it is).
pub(super) fn pick(rng: &mut Xoshiro256pp, n: usize, exclude: &[usize]) -> usize {
    loop {
        let r = rng.gen_range(0..n);
        if !exclude.contains(&r) {
            return r;
        }
    }
}

/// `if take { a } else { b }` by bit masks: the compiler turns a plain `if` with loads on
/// both sides into a branch, mispredicted whenever crossover or the box decides at random.
#[inline(always)]
pub(super) fn select(take: bool, a: f64, b: f64) -> f64 {
    let mask = (take as u64).wrapping_neg();
    f64::from_bits((a.to_bits() & mask) | (b.to_bits() & !mask))
}

impl Optimiser for DifferentialEvolution {
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.g.initialised {
            self.breed();
        }
        self.g.candidates()
    }

    fn candidates(&self) -> &[Vec<f64>] {
        self.g.candidates()
    }

    fn thresholds(&self) -> Option<&[f64]> {
        self.g.thresholds()
    }

    fn tell(&mut self, values: &[f64]) {
        // The trial replaces its target when it is not worse.
        self.g
            .tell(values, |_, v, target, _| !v.is_nan() && v <= target);
        if self.cfg.diversity_stop {
            let best = &self.g.pop[self.g.best];
            // The oldest row is reused once the window is full: no allocation per generation.
            let mut row = if self.window.len() == self.cfg.eta {
                self.window.pop_front().unwrap_or_default()
            } else {
                Vec::with_capacity(best.len())
            };
            row.clear();
            row.extend_from_slice(best);
            self.window.push_back(row);
        }
    }

    fn best(&self) -> (&[f64], f64) {
        self.g.best()
    }

    fn generation(&self) -> usize {
        self.g.generation
    }

    fn evaluations(&self) -> usize {
        self.g.evaluations
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

#[cfg(test)]
mod tests {
    use super::*;

    fn draws(n: usize, seed: u64) -> Vec<u64> {
        let mut r = Xoshiro256pp::seed_from_u64(seed);
        (0..n).map(|_| r.next_u64()).collect()
    }

    /// With CR = 0 only component jrand comes from the mutant; a mutant component outside the
    /// box is replaced by a uniform draw inside it.
    #[test]
    fn cr_zero_takes_only_jrand_and_a_mutant_outside_the_box_is_redrawn_inside() {
        let d = 9;
        let (lower, upper) = (vec![-1.0; d], vec![1.0; d]);
        let (a, b, c) = (vec![0.9; d], vec![1.0; d], vec![-1.0; d]); // mutant 0.9 + F * 2 > 1
        let target = vec![0.25; d];
        let mut out = vec![0.0; d];
        let rule = Crossover {
            f: 0.5,
            cr: 0.0,
            jrand: 4,
            lower: &lower,
            upper: &upper,
        };
        rule.trial(&mut out, [&a, &b, &c], &target, &draws(d, 1));
        for (j, v) in out.iter().enumerate() {
            if j == 4 {
                assert!(*v != 0.25 && (-1.0..=1.0).contains(v), "{v}");
            } else {
                assert_eq!(*v, 0.25);
            }
        }
    }

    /// The share of mutant components follows CR, and the AVX2 build (where the CPU has it)
    /// gives the same bits as the baseline build.
    #[test]
    fn crossover_follows_cr_and_the_wide_build_agrees_bit_for_bit() {
        let d = 1001;
        let (lower, upper) = (vec![-10.0; d], vec![10.0; d]);
        let (a, b, c) = (vec![1.0; d], vec![2.0; d], vec![0.0; d]); // mutant 2.0, inside
        let target = vec![-3.0; d];
        let rule = Crossover {
            f: 0.5,
            cr: 0.3,
            jrand: 0,
            lower: &lower,
            upper: &upper,
        };
        let r = draws(d, 2);
        let (mut wide, mut base) = (vec![0.0; d], vec![0.0; d]);
        rule.trial(&mut wide, [&a, &b, &c], &target, &r);
        rule.trial_body(&mut base, [&a, &b, &c], &target, &r);
        assert_eq!(wide, base);
        let share = wide.iter().filter(|v| **v == 2.0).count() as f64 / d as f64;
        // Binomial(1001, 0.3): standard deviation 0.0145; 4 of them.
        assert!((share - 0.3).abs() < 0.058, "{share}");
    }

    /// Seeded runs repeat exactly, and DE reaches the minimum of a 10-D sphere.
    #[test]
    fn seeded_runs_repeat_and_reach_the_sphere_minimum() {
        let run = || {
            let mut de = DifferentialEvolution::new(DeConfig {
                np: 30,
                f: 0.5,
                cr: 0.9,
                lower: vec![-5.0; 10],
                upper: vec![5.0; 10],
                seed: 7,
                diversity_stop: true,
                eta: 50,
                epsilon: 1e-9,
            })
            .unwrap();
            crate::drive(&mut de, 60_000, |x| x.iter().map(|v| v * v).sum(), |_| {});
            (de.best().0.to_vec(), de.best().1)
        };
        let (a, b) = (run(), run());
        assert_eq!(a, b);
        assert!(a.1 < 1e-12, "{}", a.1);
    }
}
