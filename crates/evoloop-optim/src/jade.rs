//! JADE: adaptive differential evolution with an optional external archive (Zhang and
//! Sanderson, "JADE: Adaptive Differential Evolution With Optional External Archive", IEEE
//! Trans. Evol. Comput. 13(5), 2009). The DE of the study (`super::de`) is DE/rand/1/bin with
//! F and CR fixed; on rotated problems that is a decade behind what users of mealpy or pymoo
//! get, so the study carries JADE as its adaptive DE.
//!
//! Each generation, for every target x_i (the paper's Section III, eqs. 5-10):
//! - **Parameters.** CR_i ~ N(mu_CR, 0.1) clipped to [0, 1]; F_i ~ Cauchy(mu_F, 0.1), drawn
//!   again while <= 0 and truncated to 1 above it.
//! - **Mutation, DE/current-to-pbest/1 with archive.** v = x_i + F_i (x_pbest - x_i) +
//!   F_i (x_r1 - x~_r2): x_pbest uniform among the best ceil(p NP) members, x_r1 from the
//!   population (r1 != i), x~_r2 from the population and the archive together (!= i, r1).
//! - **Box.** A mutant component below its lower bound becomes (lower + x_i,j) / 2, above its
//!   upper bound (upper + x_i,j) / 2 (the paper's repair: half-way back from the parent).
//! - **Crossover.** Binomial with rate CR_i, component j_rand always from the mutant.
//! - **Selection.** The trial replaces its target when it is strictly better (the paper's
//!   "if f(x_i) <= f(u_i) keep x_i"); the replaced parent goes to the archive, and F_i, CR_i to
//!   the successful sets S_F, S_CR. The archive holds at most NP members; past that, randomly
//!   chosen ones are overwritten.
//! - **Adaptation (eqs. 11-13).** mu_CR = (1 - c) mu_CR + c mean(S_CR); mu_F = (1 - c) mu_F +
//!   c mean_L(S_F), the Lehmer mean sum F^2 / sum F (it favours larger F, against the
//!   arithmetic mean's drift towards small steps). Nothing changes after a generation without a
//!   success.
//!
//! Settings: mu_CR = mu_F = 0.5 at the start and c = 0.1, the paper's. p: the paper recommends
//! 5-20 % and runs 5 % at NP = 100 (five members); the study's NP = 30 would leave 1-2 at 5 %,
//! i.e. nearly current-to-best, which the paper warns is greedy, so we take p = 0.1 (three).
//!
//! Everything is allocated at construction: a generation allocates nothing.

use super::de::{pick, select, Generations};
use super::rng::Xoshiro256pp;
use super::Optimiser;
use crate::SettingsError;
use rand::{Rng, RngCore, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// Settings of `Jade`: population, search box, seed, p, c and the archive.
#[derive(Debug, Clone, PartialEq)]
pub struct JadeConfig {
    /// Population size NP (at least 4).
    pub np: usize,
    /// Lower bounds of the search box, one per object variable.
    pub lower: Vec<f64>,
    /// Upper bounds of the search box, each above its lower bound.
    pub upper: Vec<f64>,
    /// Seed of the initial population and of every draw (F_i, CR_i, members, crossover).
    pub seed: u64,
    /// Share of the population the p-best is drawn from.
    pub p: f64,
    /// Adaptation rate of mu_F and mu_CR.
    pub c: f64,
    /// Keep the external archive (JADE with archive; off: JADE without archive).
    pub archive: bool,
}

impl JadeConfig {
    /// The settings of the module docs.
    pub fn new(np: usize, lower: Vec<f64>, upper: Vec<f64>, seed: u64) -> Self {
        Self {
            np,
            lower,
            upper,
            seed,
            p: 0.1,
            c: 0.1,
            archive: true,
        }
    }

    /// Check the settings: NP >= 4, `p` and `c` in (0, 1], the bounds a box.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.np < 4 {
            return Err(SettingsError::out_of_range(
                "population size",
                ">= 4",
                self.np,
            ));
        }
        let fraction = |v: f64| v > 0.0 && v <= 1.0;
        if !fraction(self.p) {
            return Err(SettingsError::out_of_range("p", "in (0, 1]", self.p));
        }
        if !fraction(self.c) {
            return Err(SettingsError::out_of_range("c", "in (0, 1]", self.c));
        }
        crate::settings::check_box(&self.lower, &self.upper)
    }

    /// How many of the best members the p-best is drawn from.
    fn top(&self) -> usize {
        ((self.p * self.np as f64).ceil() as usize).clamp(1, self.np)
    }
}

/// JADE, adaptive DE/current-to-pbest/1 with an optional archive (see the module). It has
/// no stopping rule of its own: `converged` is always false.
pub struct Jade {
    cfg: JadeConfig,
    rng: Xoshiro256pp,
    g: Generations,
    /// Each trial's F and CR, for the success sets.
    f_i: Vec<f64>,
    cr_i: Vec<f64>,
    /// Replaced parents: `archive_len` of the NP slots in use.
    archive: Vec<Vec<f64>>,
    archive_len: usize,
    /// One trial's random draws, one per component (scratch of `breed`).
    draws: Vec<u64>,
    /// Members by value, best first (scratch: sorted in place every generation).
    order: Vec<usize>,
    /// Location mu_F of the Cauchy distribution F_i is drawn from (0.5 at the start).
    pub mu_f: f64,
    /// Mean mu_CR of the normal distribution CR_i is drawn from (0.5 at the start).
    pub mu_cr: f64,
}

impl Jade {
    /// A JADE with `cfg` and its random initial population. Fails as `JadeConfig::validate`
    /// does.
    pub fn new(cfg: JadeConfig) -> Result<Self, SettingsError> {
        cfg.validate()?;
        let mut rng = Xoshiro256pp::seed_from_u64(cfg.seed);
        let (np, d) = (cfg.np, cfg.lower.len());
        Ok(Self {
            g: Generations::random(np, &cfg.lower, &cfg.upper, &mut rng),
            f_i: vec![0.5; np],
            cr_i: vec![0.5; np],
            archive: vec![vec![0.0; d]; np],
            archive_len: 0,
            draws: vec![0; d],
            order: (0..np).collect(),
            mu_f: 0.5,
            mu_cr: 0.5,
            rng,
            cfg,
        })
    }

    /// Members in the archive.
    pub fn archived(&self) -> usize {
        self.archive_len
    }

    /// F_i ~ Cauchy(mu_F, 0.1): drawn again while <= 0, truncated to 1.
    fn draw_f(&mut self) -> f64 {
        loop {
            let u: f64 = self.rng.gen();
            let f = self.mu_f + 0.1 * (std::f64::consts::PI * (u - 0.5)).tan();
            if f > 0.0 {
                return f.min(1.0);
            }
        }
    }

    /// CR_i ~ N(mu_CR, 0.1), clipped to [0, 1].
    fn draw_cr(&mut self) -> f64 {
        let z: f64 = StandardNormal.sample(&mut self.rng);
        (self.mu_cr + 0.1 * z).clamp(0.0, 1.0)
    }

    fn breed(&mut self) {
        let (np, d) = (self.cfg.np, self.cfg.lower.len());
        let values = &self.g.values;
        self.order
            .sort_unstable_by(|&a, &b| values[a].total_cmp(&values[b]));
        let top = self.cfg.top();
        for i in 0..np {
            let f = self.draw_f();
            let cr = self.draw_cr();
            self.f_i[i] = f;
            self.cr_i[i] = cr;
            let pbest = self.order[self.rng.gen_range(0..top)];
            let r1 = pick(&mut self.rng, np, &[i]);
            // r2 indexes the population (< np) or the archive (np..np + archive_len).
            let r2 = pick(&mut self.rng, np + self.archive_len, &[i, r1]);
            let jrand = self.rng.gen_range(0..d);
            for r in self.draws.iter_mut() {
                *r = self.rng.next_u64();
            }
            let (pop, archive) = (&self.g.pop, &self.archive);
            let x2 = if r2 < np { &pop[r2] } else { &archive[r2 - np] };
            let rule = Trial {
                f,
                cr,
                jrand,
                lower: &self.cfg.lower,
                upper: &self.cfg.upper,
            };
            rule.trial(
                &mut self.g.trials[i],
                [&pop[i], &pop[pbest], &pop[r1], x2],
                &self.draws,
            );
        }
    }
}

/// DE/current-to-pbest/1/bin for one target: mutation, the paper's box repair, crossover.
struct Trial<'a> {
    f: f64,
    cr: f64,
    jrand: usize,
    lower: &'a [f64],
    upper: &'a [f64],
}

impl Trial<'_> {
    super::wide_method! {
        /// `out` = the trial from the target x, the p-best, x_r1 and x~_r2, one draw per
        /// component (its high half decides the crossover); a branch-free pass, four lanes wide
        /// where the CPU has AVX2 (`super::wide_method`), with the same results on every x86-64.
        fn trial, trial_avx2 => trial_body(out: &mut [f64], parents: [&[f64]; 4], draws: &[u64])
    }

    #[inline(always)]
    fn trial_body(&self, out: &mut [f64], parents: [&[f64]; 4], draws: &[u64]) {
        let d = out.len();
        let [x, xp, x1, x2] = parents.map(|p| &p[..d]);
        let (draws, lower, upper) = (&draws[..d], &self.lower[..d], &self.upper[..d]);
        let (f, cr, jrand) = (self.f, self.cr, self.jrand);
        for j in 0..d {
            let (u, _) = Xoshiro256pp::halves(draws[j]);
            let v = x[j] + f * (xp[j] - x[j]) + f * (x1[j] - x2[j]);
            let v = select(v < lower[j], (lower[j] + x[j]) / 2.0, v);
            let v = select(v > upper[j], (upper[j] + x[j]) / 2.0, v);
            out[j] = select((u < cr) | (j == jrand), v, x[j]);
        }
    }
}

impl Optimiser for Jade {
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
        let (mut n, mut sum_cr, mut sum_f, mut sum_f2) = (0usize, 0.0, 0.0, 0.0);
        let Self {
            cfg,
            rng,
            g,
            f_i,
            cr_i,
            archive,
            archive_len,
            ..
        } = self;
        // A trial replaces its target when strictly better; the target goes to the archive (a
        // random slot once it is full) and the trial's F and CR to the successful sets.
        g.tell(values, |i, v, target, parent| {
            if v.is_nan() || v >= target {
                return false;
            }
            if cfg.archive {
                let slot = if *archive_len < cfg.np {
                    *archive_len += 1;
                    *archive_len - 1
                } else {
                    rng.gen_range(0..cfg.np)
                };
                archive[slot].copy_from_slice(parent);
            }
            n += 1;
            sum_cr += cr_i[i];
            sum_f += f_i[i];
            sum_f2 += f_i[i] * f_i[i];
            true
        });
        if n > 0 {
            let c = self.cfg.c;
            self.mu_cr = (1.0 - c) * self.mu_cr + c * sum_cr / n as f64;
            self.mu_f = (1.0 - c) * self.mu_f + c * sum_f2 / sum_f;
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
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere(x: &[f64]) -> f64 {
        x.iter().map(|v| v * v).sum()
    }

    fn run(cfg: JadeConfig, evaluations: usize, f: impl Fn(&[f64]) -> f64) -> Jade {
        let mut o = Jade::new(cfg).unwrap();
        crate::drive(&mut o, evaluations, f, |_| {});
        o
    }

    #[test]
    fn seeded_runs_repeat_and_spend_the_budget() {
        let cfg = JadeConfig::new(30, vec![-100.0; 30], vec![100.0; 30], 4);
        let (a, b) = (run(cfg.clone(), 30_000, sphere), run(cfg, 30_000, sphere));
        assert_eq!(a.best().1.to_bits(), b.best().1.to_bits());
        assert_eq!(a.best().0, b.best().0);
        assert_eq!(a.evaluations(), 30_000);
    }

    /// The draws follow the paper's distributions: CR_i within [0, 1] about mu_CR with standard
    /// deviation 0.1; F_i in (0, 1] from Cauchy(mu_F, 0.1) conditioned on F > 0 (drawn again
    /// otherwise), whose median and share within mu_F -+ 0.1 follow from the Cauchy CDF
    /// P(F <= x) = 1/2 + atan((x - mu_F) / 0.1) / pi: with F0 = P(F <= 0), the median is where
    /// P = 1/2 + F0 / 2 and the share is (1/2) / (1 - F0).
    #[test]
    fn f_and_cr_follow_their_distributions() {
        let mut o = Jade::new(JadeConfig::new(10, vec![0.0; 2], vec![1.0; 2], 9)).unwrap();
        let (mu_f, s) = (0.6, 0.1);
        o.mu_f = mu_f;
        o.mu_cr = 0.3;
        let n = 200_000;
        let mut fs: Vec<f64> = (0..n).map(|_| o.draw_f()).collect();
        let crs: Vec<f64> = (0..n).map(|_| o.draw_cr()).collect();
        assert!(fs.iter().all(|f| *f > 0.0 && *f <= 1.0));
        assert!(crs.iter().all(|c| (0.0..=1.0).contains(c)));
        let pi = std::f64::consts::PI;
        let f0 = 0.5 + ((0.0 - mu_f) / s).atan() / pi;
        let median = mu_f + s * (pi * (f0 / 2.0)).tan();
        fs.sort_by(f64::total_cmp);
        assert!(
            (fs[n / 2] - median).abs() < 0.002,
            "median {} vs {median}",
            fs[n / 2]
        );
        let inner = fs.iter().filter(|f| (0.5..=0.7).contains(*f)).count() as f64 / n as f64;
        let share = 0.5 / (1.0 - f0);
        assert!((inner - share).abs() < 0.006, "{inner} vs {share}");
        let mean = crs.iter().sum::<f64>() / n as f64;
        let sd = (crs.iter().map(|c| (c - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(
            (mean - 0.3).abs() < 0.002 && (sd - 0.1).abs() < 0.002,
            "{mean} {sd}"
        );
    }

    /// Eqs. 11-13 on a generation whose successes are known: every trial succeeds, so mu_CR
    /// moves a tenth of the way to the mean of the CR_i and mu_F to their Lehmer mean; the
    /// replaced parents fill the archive. A generation without a success changes nothing.
    #[test]
    fn the_means_adapt_to_the_successful_parameters_and_parents_are_archived() {
        let mut o = Jade::new(JadeConfig::new(6, vec![-1.0; 3], vec![1.0; 3], 2)).unwrap();
        o.ask();
        o.tell(&[10.0; 6]);
        o.ask();
        let parents = o.g.pop.clone();
        let (f, cr) = (o.f_i.clone(), o.cr_i.clone());
        o.tell(&[1.0; 6]);
        let lehmer = f.iter().map(|v| v * v).sum::<f64>() / f.iter().sum::<f64>();
        let mean_cr = cr.iter().sum::<f64>() / 6.0;
        assert!((o.mu_f - (0.9 * 0.5 + 0.1 * lehmer)).abs() < 1e-15);
        assert!((o.mu_cr - (0.9 * 0.5 + 0.1 * mean_cr)).abs() < 1e-15);
        assert_eq!(o.archived(), 6);
        assert_eq!(&o.archive[..6], &parents[..]);
        let (mu_f, mu_cr) = (o.mu_f, o.mu_cr);
        o.ask();
        o.tell(&[5.0; 6]);
        assert_eq!((o.mu_f, o.mu_cr), (mu_f, mu_cr));
        assert_eq!(o.archived(), 6, "the archive never exceeds NP");
    }

    /// The AVX2 build of a trial (where the CPU has it) and the baseline build give the same
    /// bits; a mutant component outside the box comes back half-way between the bound and the
    /// target's component; CR = 0 takes only j_rand from the mutant.
    #[test]
    fn the_trial_repairs_the_box_and_the_wide_build_agrees_bit_for_bit() {
        let d = 37; // not a multiple of the lane count: the remainder loop is checked too
        let (lower, upper) = (vec![-1.0; d], vec![1.0; d]);
        let x = vec![0.5; d];
        // v = 0.5 + 0.5 (1 - 0.5) + 0.5 (1 - (-1)) = 1.75 > 1: repaired to (1 + 0.5) / 2.
        let (xp, x1, x2) = (vec![1.0; d], vec![1.0; d], vec![-1.0; d]);
        let mut r = Xoshiro256pp::seed_from_u64(5);
        let draws: Vec<u64> = (0..d).map(|_| r.next_u64()).collect();
        let mut rule = Trial {
            f: 0.5,
            cr: 0.6,
            jrand: 3,
            lower: &lower,
            upper: &upper,
        };
        let (mut wide, mut base) = (vec![0.0; d], vec![0.0; d]);
        rule.trial(&mut wide, [&x, &xp, &x1, &x2], &draws);
        rule.trial_body(&mut base, [&x, &xp, &x1, &x2], &draws);
        assert_eq!(wide, base);
        assert_eq!(wide[3], 0.75);
        assert!(wide.iter().all(|v| *v == 0.75 || *v == 0.5));
        assert!(wide.iter().filter(|v| **v == 0.75).count() > 5);
        rule.cr = 0.0;
        rule.trial(&mut wide, [&x, &xp, &x1, &x2], &draws);
        for (j, v) in wide.iter().enumerate() {
            assert_eq!(*v, if j == 3 { 0.75 } else { 0.5 }, "component {j}");
        }
    }

    /// A mutant component outside the box comes back half-way between the bound and its parent,
    /// so every trial stays inside the box.
    #[test]
    fn trials_stay_inside_the_box() {
        let mut o = Jade::new(JadeConfig::new(8, vec![0.0; 5], vec![1.0; 5], 3)).unwrap();
        for g in 0..200 {
            let values: Vec<f64> = o.ask().iter().map(|x| -x.iter().sum::<f64>()).collect();
            assert!(o
                .candidates()
                .iter()
                .all(|x| x.iter().all(|v| (0.0..=1.0).contains(v))));
            o.tell(&values);
            if g == 199 {
                // Maximising the sum drives every component to the upper bound.
                assert!(o.best().1 < -4.999, "{}", o.best().1);
            }
        }
    }

    /// On the study's shifted and rotated Ackley and Schwefel 2.21 (30-D, 30 000 evaluations,
    /// population 30) JADE ends lower than DE/rand/1/bin with F = 0.5, CR = 0.9 on each of 5
    /// paired seeds: the reason the study carries it.
    #[test]
    fn beats_classic_de_on_rotated_problems() {
        use crate::by_name::build;
        use crate::problem::Problem;
        for key in ["ackley", "schwefel_2_21"] {
            let problem = Problem::shifted(crate::suite::get(key).unwrap());
            let (lower, upper) = problem.bounds();
            let f = |x: &[f64]| problem.value(x) - problem.f_min();
            for seed in 0..5 {
                let end = |name: &str| {
                    let mut o = build(name, &lower, &upper, 30, 30_000, seed).unwrap();
                    crate::drive(o.as_mut(), 30_000, f, |_| {});
                    o.best().1
                };
                let (jade, de) = (end("jade"), end("de"));
                assert!(jade < de, "{key}, seed {seed}: JADE {jade:e}, DE {de:e}");
            }
        }
    }
}
