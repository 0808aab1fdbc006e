//! eMuPSO: mutating PSO with Gaussian mutation and archived elite learning (the eMuPSO paper,
//! Section 3).
//!
//! - **Schedules (eqs. 3-4).** w_t = w_0 n^t falls from 2.1 to 0.6 and c2_t = c2_0 / m^t rises
//!   from 1.8 to 3.9 over the iteration budget T. "n and m can be determined by setting iter to
//!   the maximum value": n = (0.6 / 2.1)^(1/T), m = (1.8 / 3.9)^(1/T), so both reach their end
//!   values exactly at t = T.
//! - **Swarm radius and stagnation (eqs. 5-6).** rad_t = (best cost of the current swarm) -
//!   mean(personal best costs); the counter g grows by one when the change of rad is
//!   "negligible", |rad_t - rad_(t-1)| <= 1e-2 |rad_t| (the text: "no change ... or negligible"),
//!   and is reset otherwise.
//! - **Mutation (eqs. 7-8).** When g reaches G the swarm is rebuilt around k elites: the swarm
//!   is split into k + 1 parts; part i (< k) is elite i itself followed by its offspring, the
//!   last part uniformly random. An offspring is its elite with one dimension j, drawn per
//!   offspring, moved by N(0, sigma * range_j) and clamped to the box (module notes below).
//!   Velocities restart at zero and personal bests at the new positions, so the new swarm is
//!   not pulled straight back to the old best (the paper's reason for the archive).
//! - **Elite archive (Section 3.3).** Global elites are the elites of earlier segments (between
//!   mutations); local elites are the k best personal bests of the current one. At a mutation
//!   the k best distinct positions of both are the elites, and they become the global elites.
//! - **Stopping (eq. 7's "end if 1e-8").** Optional `target`: converged once the best value is
//!   at or below it. The study runs the whole budget (no target) so that every algorithm spends
//!   the same evaluations.
//!
//! Where the text is silent, our choices (tested in this module):
//! - c1 is not given a schedule; it stays at 1.8, the start of the range the text quotes.
//!   (The text calls the rising coefficient "cognitive" but eq. 4 updates c2, the social one;
//!   we follow the equation.)
//! - **The velocity clamp is the step size.** With w >= 0.6 and c1 + c2 up to 5.7 the update
//!   lies outside PSO's second-order stability region (c1 + c2 < 24 (1 - w^2) / (7 - 5 w) =
//!   3.84 at w = 0.6, Poli 2009) for the whole budget: read literally, the swarm is a random
//!   walk as wide as its clamp and never converges (measured: 30-D sphere 2.9e3 after 30 000
//!   evaluations, where the paper reports 9.5e-8). The text does not say how its runs converged;
//!   we take the known remedy for an expanding swarm, dynamic delimitation of the maximum
//!   velocity (Schutte and Groenwold 2005): the clamp starts at 20 % of each range and halves
//!   whenever the run's best has not improved for 3 iterations. The schedules of eqs. 3-4 are
//!   kept as written; they set how the swarm moves within the clamp.
//! - **An offspring mutates one dimension.** Eq. 8 is written per dimension ("if x^dim is the
//!   dim-th dimension of the swarm, then all the elements in the dim-th dimension shall
//!   mutate"); we read it as: an offspring takes its elite and mutates one dimension, drawn
//!   for each offspring. Its other coordinates keep the elite's refined values, so its value
//!   says at once whether that one move found a better basin. Mutating every dimension (our
//!   first reading) scatters all the refined coordinates at once: on the 30-D Rastrigin the
//!   mean error was 65-68 with sigma halving per mutation, against 16.2 for this reading and
//!   the paper's 17.4 (30 runs; module test). Alternatives measured on the whole study (51
//!   functions, 30 paired seeds, the book): one dimension shared by all offspring of a mutation
//!   (Rastrigin 32.6), each dimension with probability 1/D (22.2).
//! - **The elites stay in the swarm.** "Elite solutions are recalled from the archive and
//!   merged with the best solutions of the current run": each elite is the first member of its
//!   part, unchanged. The swarm keeps refining the best point while its offspring explore; with
//!   every member mutated, 2-D functions solved to 1e-8 before (Easom, modified Ackley) lost
//!   that precision.
//! - **sigma is a constant fraction of each range**, 0.1 by default: "a variable between
//!   [0-1] multiplied by size of the search space". The rebuilt swarm's clamp restarts at
//!   sigma, so it searches at the scale it was seeded with, and shrinks again as it stagnates.
//!   On Rastrigin sigma = 0.05 gives 37, 0.2 gives 11 (30 runs); the default is not tuned to it.
//! - k = 5 elites (the paper's robot experiments stop at five elite particles), G = 10 (its
//!   value for the excitation-trajectory search).

use super::pso::Particles;
use super::swarm::{Rule, Swarm, SwarmConfig, SwarmOptimiser};
use crate::SettingsError;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};

/// eMuPSO's settings beyond the swarm's.
#[derive(Debug, Clone, PartialEq)]
pub struct EmuPsoSettings {
    /// Inertia weight w at the start and at the end of the budget (eq. 3; 2.1 and 0.6).
    pub w: [f64; 2],
    /// Social coefficient c2 at the start and at the end of the budget (eq. 4; 1.8 and 3.9).
    pub c2: [f64; 2],
    /// Cognitive coefficient c1 (towards the personal best), constant (1.8).
    pub c1: f64,
    /// Stagnant iterations before a mutation (G).
    pub stagnation: usize,
    /// Elites (k).
    pub elites: usize,
    /// The mutation's sigma as a fraction of each range (eq. 8).
    pub sigma: f64,
    /// The velocity clamp at the start, as a fraction of each dimension's range (0.2); a
    /// rebuilt swarm's clamp restarts at `sigma`.
    pub vmax_fraction: f64,
    /// The clamp's factor after `vmax_patience` iterations without a better best.
    pub vmax_shrink: f64,
    /// Iterations without a better best before the clamp shrinks by `vmax_shrink` (3).
    pub vmax_patience: usize,
    /// A change of the swarm radius at most this fraction of it counts as none (eq. 6).
    pub stagnation_tolerance: f64,
    /// Stop once the best value is at or below this.
    pub target: Option<f64>,
}

impl Default for EmuPsoSettings {
    fn default() -> Self {
        Self {
            w: [2.1, 0.6],
            c2: [1.8, 3.9],
            c1: 1.8,
            stagnation: 10,
            elites: 5,
            sigma: 0.1,
            vmax_fraction: 0.2,
            vmax_shrink: 0.5,
            vmax_patience: 3,
            stagnation_tolerance: 1e-2,
            target: None,
        }
    }
}

/// eMuPSO's `Rule`: the schedules, the stagnation counter, the mutation and the elite
/// archive (see the module).
pub struct EmuPsoRule {
    set: EmuPsoSettings,
    p: Particles,
    /// n and m of eqs. 3-4.
    n: f64,
    m: f64,
    rad: f64,
    /// The stagnation counter g.
    g: usize,
    /// Global elites (positions, values): k slots, the first `n_global` in use.
    global: Vec<(Vec<f64>, f64)>,
    n_global: usize,
    /// Scratch for the merge at a mutation (2k slots), its order, the k best personal bests
    /// and the merged slots kept: all allocated here, so a mutation allocates nothing.
    merged: Vec<(Vec<f64>, f64)>,
    order: Vec<usize>,
    best: Vec<usize>,
    keep: Vec<usize>,
    /// Mutations (swarm rebuilds around the elites) so far.
    pub mutations: usize,
    /// The run's best when it last improved, and the iterations since.
    last_best: f64,
    idle: usize,
}

/// eMuPSO as an `Optimiser`.
pub type EmuPso = SwarmOptimiser<EmuPsoRule>;

impl EmuPso {
    /// An eMuPSO on the swarm `cfg` with `set`. Fails if `elites` is not in 1..population,
    /// `sigma`, `vmax_fraction` or `vmax_shrink` is not in (0, 1], `vmax_patience` is 0,
    /// `stagnation_tolerance` is negative or NaN, or `SwarmConfig::validate` refuses `cfg`.
    pub fn new(cfg: SwarmConfig, set: EmuPsoSettings) -> Result<Self, SettingsError> {
        if set.elites == 0 || set.elites >= cfg.population {
            return Err(SettingsError::out_of_range(
                "elites",
                "in 1..population",
                set.elites,
            ));
        }
        let fraction = |v: f64| v > 0.0 && v <= 1.0;
        for (name, v) in [
            ("sigma", set.sigma),
            ("vmax_fraction", set.vmax_fraction),
            ("vmax_shrink", set.vmax_shrink),
        ] {
            if !fraction(v) {
                return Err(SettingsError::out_of_range(name, "in (0, 1]", v));
            }
        }
        if set.vmax_patience == 0 {
            return Err(SettingsError::out_of_range("vmax_patience", ">= 1", 0));
        }
        if set.stagnation_tolerance.is_nan() || set.stagnation_tolerance < 0.0 {
            return Err(SettingsError::out_of_range(
                "stagnation_tolerance",
                ">= 0",
                set.stagnation_tolerance,
            ));
        }
        let swarm = Swarm::new(cfg)?;
        let t = swarm.cfg.iterations as f64;
        let k = set.elites;
        let d = swarm.cfg.dim();
        let rule = EmuPsoRule {
            n: (set.w[1] / set.w[0]).powf(1.0 / t),
            m: (set.c2[0] / set.c2[1]).powf(1.0 / t),
            p: Particles::new(&swarm, set.vmax_fraction),
            rad: f64::NAN,
            g: 0,
            global: (0..k).map(|_| (vec![0.0; d], f64::INFINITY)).collect(),
            n_global: 0,
            merged: (0..2 * k).map(|_| (vec![0.0; d], f64::INFINITY)).collect(),
            order: Vec::with_capacity(2 * k),
            best: Vec::with_capacity(k),
            keep: Vec::with_capacity(k),
            mutations: 0,
            last_best: f64::INFINITY,
            idle: 0,
            set,
        };
        Ok(SwarmOptimiser::from_parts(swarm, rule))
    }
}

impl EmuPsoRule {
    /// w and c2 at iteration t (eqs. 3-4).
    pub fn schedules(&self, t: usize) -> (f64, f64) {
        (
            self.set.w[0] * self.n.powi(t as i32),
            self.set.c2[0] / self.m.powi(t as i32),
        )
    }

    /// The global elites (positions, values), best first.
    pub fn elites(&self) -> &[(Vec<f64>, f64)] {
        &self.global[..self.n_global]
    }

    /// The k best distinct positions of the global elites and the current personal bests
    /// become the global elites.
    fn update_archive(&mut self) {
        let k = self.set.elites;
        Swarm::smallest(&self.p.pbest_f, k, &mut self.best);
        let sources = self.global[..self.n_global]
            .iter()
            .map(|(x, f)| (x.as_slice(), *f))
            .chain(
                self.best
                    .iter()
                    .map(|&i| (self.p.pbest_x[i].as_slice(), self.p.pbest_f[i])),
            );
        let mut used = 0;
        for ((slot, value), (x, f)) in self.merged.iter_mut().zip(sources) {
            slot.copy_from_slice(x);
            *value = f;
            used += 1;
        }
        self.order.clear();
        self.order.extend(0..used);
        let merged = &self.merged;
        // Unstable: no buffer; equal values are equally good elites.
        self.order
            .sort_unstable_by(|&a, &b| merged[a].1.total_cmp(&merged[b].1));
        self.keep.clear();
        for &i in &self.order {
            if self.keep.len() == k {
                break;
            }
            if self.keep.iter().all(|&j| merged[j].0 != merged[i].0) {
                self.keep.push(i);
            }
        }
        for (g, &i) in self.global.iter_mut().zip(&self.keep) {
            g.0.copy_from_slice(&merged[i].0);
            g.1 = merged[i].1;
        }
        self.n_global = self.keep.len();
    }

    /// Eq. 8: the swarm rebuilt around the elites, the last part random.
    fn mutate(&mut self, s: &mut Swarm) {
        self.update_archive();
        let n = s.x.len();
        let parts = self.n_global + 1;
        let cfg = &s.cfg;
        let sigma = self.set.sigma;
        let rng = &mut s.rng;
        for (i, (x, v)) in s.x.iter_mut().zip(&mut self.p.v).enumerate() {
            // Particle i belongs to part i * parts / n: parts of (nearly) equal size.
            let part = i * parts / n;
            match self.global[..self.n_global].get(part) {
                Some((e, _)) => {
                    x.copy_from_slice(e);
                    // The part's first member is its elite; the others are its offspring.
                    if i > 0 && (i - 1) * parts / n == part {
                        let j = rng.gen_range(0..x.len());
                        let z: f64 = StandardNormal.sample(rng);
                        x[j] = (e[j] + z * sigma * cfg.range(j)).clamp(cfg.lower[j], cfg.upper[j]);
                    }
                }
                None => {
                    for (j, xj) in x.iter_mut().enumerate() {
                        *xj = rng.gen_range(cfg.lower[j]..cfg.upper[j]);
                    }
                }
            }
            v.fill(0.0);
            self.p.pbest_f[i] = f64::INFINITY;
        }
        self.p.reset_swarm_best();
        self.p.vmax_fraction = sigma;
        self.idle = 0;
        self.g = 0;
        self.rad = f64::NAN;
        self.mutations += 1;
    }
}

impl Rule for EmuPsoRule {
    const NAME: &'static str = "emupso";

    fn advance(&mut self, s: &mut Swarm) {
        self.p.update_bests(s);
        // Eq. 5 on the current segment's swarm; eq. 6's counter.
        let mean = self.p.pbest_f.iter().sum::<f64>() / self.p.pbest_f.len() as f64;
        let rad = self.p.swarm_best_f() - mean;
        let same = (rad - self.rad).abs() <= self.set.stagnation_tolerance * rad.abs()
            || (rad.is_nan() && self.rad.is_nan());
        self.g = if same { self.g + 1 } else { 0 };
        self.rad = rad;
        if self.g >= self.set.stagnation {
            self.mutate(s);
            return;
        }
        // Dynamic delimitation of the clamp (module docs).
        if s.best_f < self.last_best {
            self.last_best = s.best_f;
            self.idle = 0;
        } else {
            self.idle += 1;
            if self.idle >= self.set.vmax_patience {
                self.p.vmax_fraction = (self.p.vmax_fraction * self.set.vmax_shrink).max(1e-15);
                self.idle = 0;
            }
        }
        let (w, c2) = self.schedules(s.generation + 1);
        self.p.fly(s, w, self.set.c1, c2);
    }

    fn converged(&self, s: &Swarm) -> bool {
        self.set.target.is_some_and(|t| s.best_f <= t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Optimiser;

    fn sphere(x: &[f64]) -> f64 {
        x.iter().map(|v| v * v).sum()
    }

    /// The whole budget (initial population and every iteration), or up to the target.
    fn run(opt: &mut EmuPso, f: impl Fn(&[f64]) -> f64) {
        let budget = opt.swarm.cfg.population * (opt.swarm.cfg.iterations + 1);
        crate::drive(opt, budget, f, |_| {});
    }

    #[test]
    fn the_schedules_run_from_their_start_to_their_end_value_over_the_budget() {
        let cfg = SwarmConfig::for_budget(vec![-1.0; 3], vec![1.0; 3], 30, 30_000, 0);
        let o = EmuPso::new(cfg, EmuPsoSettings::default()).unwrap();
        let (w0, c0) = o.rule.schedules(0);
        let (w1, c1) = o.rule.schedules(999);
        assert!((w0 - 2.1).abs() < 1e-12 && (c0 - 1.8).abs() < 1e-12);
        assert!(
            (w1 - 0.6).abs() < 1e-9 && (c1 - 3.9).abs() < 1e-9,
            "{w1} {c1}"
        );
        // Non-linear: geometric, so the midpoint is the geometric mean.
        let (wm, _) = o.rule.schedules(500);
        assert!((wm - (2.1f64 * 0.6).sqrt()).abs() < 2e-3, "{wm}");
    }

    /// A flat objective never improves a personal best: the counter reaches G after G
    /// iterations and the swarm is rebuilt around the elites (k parts near them, one random).
    #[test]
    fn a_stagnant_swarm_mutates_after_g_iterations_around_its_elites() {
        let cfg = SwarmConfig::for_budget(vec![-10.0; 2], vec![10.0; 2], 12, 12_000, 7);
        let set = EmuPsoSettings {
            elites: 2,
            ..Default::default()
        };
        let mut o = EmuPso::new(cfg, set).unwrap();
        // Two distinct values then flat: the first tell sets the bests, then nothing improves.
        let mut calls = 0;
        while o.rule.mutations == 0 {
            let v: Vec<f64> = o
                .ask()
                .iter()
                .map(|x| if calls == 0 { x[0].abs() } else { 1e9 })
                .collect();
            o.tell(&v);
            calls += 1;
            assert!(calls < 100, "never mutated");
        }
        // First tell sets the radius, then G = 10 unchanged ones.
        assert_eq!(calls, 11);
        assert_eq!(o.rule.elites().len(), 2);
        let elites: Vec<Vec<f64>> = o.rule.elites().iter().map(|e| e.0.clone()).collect();
        // Parts: particles 0-3 of elite 0, 4-7 of elite 1, 8-11 random. The first of a part is
        // its elite; the others differ from it in exactly one dimension.
        for (i, x) in o.swarm.x.iter().enumerate() {
            let e = match i {
                0..=3 => &elites[0],
                4..=7 => &elites[1],
                _ => continue,
            };
            let moved = x.iter().zip(e).filter(|(a, b)| a != b).count();
            let expected = if i % 4 == 0 { 0 } else { 1 };
            assert_eq!(moved, expected, "particle {i}: {x:?} against {e:?}");
        }
        assert!(o.rule.p.v.iter().all(|v| v.iter().all(|c| *c == 0.0)));
        assert_eq!(o.rule.p.vmax_fraction, 0.1, "the clamp restarts at sigma");
    }

    /// An offspring's one moved coordinate is N(elite, sigma * range): over many mutations its
    /// offsets have mean ~0 and standard deviation ~sigma * range (here 0.1 * 2000 = 200, far
    /// from the box's edges), and each dimension is drawn about equally often.
    #[test]
    fn an_offspring_moves_one_dimension_by_sigma_times_the_range() {
        let cfg = SwarmConfig::for_budget(vec![-1000.0; 3], vec![1000.0; 3], 40, 40_000, 5);
        let set = EmuPsoSettings {
            elites: 1,
            ..Default::default()
        };
        let mut o = EmuPso::new(cfg, set).unwrap();
        let mut offsets = Vec::new();
        let mut per_dim = [0usize; 3];
        for _ in 0..200 {
            o.rule.global[0] = (vec![0.0; 3], 0.0);
            o.rule.n_global = 1;
            o.rule.p.pbest_f.fill(f64::INFINITY);
            o.rule.mutate(&mut o.swarm);
            // One elite: part 0 is particles 0-19 (the elite, then 19 offspring).
            for x in &o.swarm.x[1..20] {
                for (j, v) in x.iter().enumerate() {
                    if *v != 0.0 {
                        offsets.push(*v);
                        per_dim[j] += 1;
                    }
                }
            }
        }
        let n = offsets.len() as f64;
        let mean = offsets.iter().sum::<f64>() / n;
        let sd = (offsets.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt();
        assert_eq!(offsets.len(), 200 * 19, "one coordinate per offspring");
        assert!(
            mean.abs() < 10.0 && (sd - 200.0).abs() < 10.0,
            "{mean} {sd}"
        );
        assert!(
            per_dim.iter().all(|&c| (1150..1380).contains(&c)),
            "{per_dim:?}"
        );
    }

    #[test]
    fn the_archive_keeps_the_k_best_distinct_positions() {
        let cfg = SwarmConfig::for_budget(vec![-1.0; 1], vec![1.0; 1], 6, 600, 1);
        let set = EmuPsoSettings {
            elites: 2,
            ..Default::default()
        };
        let mut o = EmuPso::new(cfg, set).unwrap();
        o.rule.global = vec![(vec![0.5], 0.25), (vec![0.1], 0.01)];
        o.rule.n_global = 2;
        o.rule.p.pbest_x = vec![
            vec![0.1],
            vec![0.2],
            vec![0.3],
            vec![0.4],
            vec![0.6],
            vec![0.7],
        ];
        o.rule.p.pbest_f = vec![0.01, 0.04, 0.09, 0.16, 0.36, 0.49];
        o.rule.update_archive();
        let kept: Vec<f64> = o.rule.elites().iter().map(|e| e.0[0]).collect();
        assert_eq!(kept, vec![0.1, 0.2], "0.1 once (in both), then 0.2");
    }

    #[test]
    fn seeded_runs_are_reproducible() {
        let cfg = SwarmConfig::for_budget(vec![-100.0; 30], vec![100.0; 30], 30, 30_000, 3);
        let mut a = EmuPso::new(cfg.clone(), EmuPsoSettings::default()).unwrap();
        let mut b = EmuPso::new(cfg, EmuPsoSettings::default()).unwrap();
        run(&mut a, sphere);
        run(&mut b, sphere);
        assert_eq!(a.best().1.to_bits(), b.best().1.to_bits());
        assert_eq!(a.evaluations(), 30_000);
    }

    /// The paper's Table 4-5 means for eMuPSO (30-D, 30 000 evaluations, population 30):
    /// sphere 9.46e-8, Griewank 0.0343, Rastrigin 17.38. The mean over the study's 30 seeds must
    /// be at least as good.
    #[test]
    fn reaches_the_published_sphere_griewank_and_rastrigin_values_at_30000_evaluations() {
        for (key, published) in [
            ("sphere", 9.46e-8),
            ("griewank", 0.0343134),
            ("rastrigin", 17.378784),
        ] {
            let f = crate::suite::get(key).unwrap();
            let errors: Vec<f64> = (0..30)
                .map(|seed| {
                    let (lower, upper) = f.bounds();
                    let cfg = SwarmConfig::for_budget(lower, upper, 30, 30_000, seed);
                    let mut o = EmuPso::new(cfg, EmuPsoSettings::default()).unwrap();
                    run(&mut o, f.f);
                    o.best().1 - f.f_min
                })
                .collect();
            let mean = errors.iter().sum::<f64>() / errors.len() as f64;
            assert!(
                mean <= published,
                "{key}: mean error {mean:e} > {published:e}: {errors:?}"
            );
        }
    }

    /// Without the clamp's delimitation the paper's coefficients do not converge (module docs):
    /// the mechanism, not luck, brings the sphere down.
    #[test]
    fn without_the_shrinking_clamp_the_literal_swarm_does_not_converge() {
        let cfg = SwarmConfig::for_budget(vec![-100.0; 30], vec![100.0; 30], 30, 30_000, 3);
        let literal = EmuPsoSettings {
            vmax_shrink: 1.0,
            ..Default::default()
        };
        let mut a = EmuPso::new(cfg.clone(), literal).unwrap();
        let mut b = EmuPso::new(cfg, EmuPsoSettings::default()).unwrap();
        run(&mut a, sphere);
        run(&mut b, sphere);
        assert!(
            a.best().1 > 1.0 && b.best().1 < 1e-20,
            "{} {}",
            a.best().1,
            b.best().1
        );
    }

    #[test]
    fn a_target_stops_the_run() {
        let cfg = SwarmConfig::for_budget(vec![-5.0; 2], vec![5.0; 2], 20, 20_000, 2);
        let set = EmuPsoSettings {
            target: Some(1e-8),
            ..Default::default()
        };
        let mut o = EmuPso::new(cfg, set).unwrap();
        run(&mut o, sphere);
        assert!(o.best().1 <= 1e-8 && o.evaluations() < 20_000);
    }
}
