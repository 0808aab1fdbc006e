//! The evolutionary algorithm of the RKGNN paper (Section 4) behind the project's ask/tell
//! `Optimiser` interface.
//!
//! - Individuals a = (x, sigma) (eq. 11): object variables and one strategy parameter each.
//! - Recombination: arithmetical crossover with probability `crossover` (0.2, Section 4.2): the
//!   child of parents a and b is (w x_a + (1-w) x_b, w sigma_a + (1-w) sigma_b), w ~ U(0, 1).
//! - Chaotic mutation (Section 4.3, after the authors' ref. \[5\]): every object variable of every
//!   individual owns a logistic map z <- 4 z (1 - z), fully chaotic on (0, 1), seeded at random.
//!   Each mutation iterates it twice: the first value drives the strategy parameter,
//!   sigma' = sigma exp(tau (2 z - 1)) with tau = 1/sqrt(2 sqrt(n_x)) (the self-adaptation rate of
//!   evolution strategies, with the chaotic value in place of a Gaussian draw); the second moves
//!   the variable, x' = x + sigma' (2 z - 1). The logistic map's invariant density is the arcsine
//!   law on (0, 1), so steps concentrate near +-sigma' (more long steps than a Gaussian) and the
//!   sequence of one variable is deterministic chaos rather than independent noise. A parent's
//!   maps advance with its child's, the child's one step further, so no two draws repeat. A map that
//!   falls onto a fixed point or 0 in floating point is reseeded from the generator.
//!   sigma stays within [1e-6, 10] times its initial value. A parent whose child does no better
//!   than itself multiplies its own sigma by 0.97 (a success rule): elitist parents that are never
//!   beaten would otherwise keep their step for ever (measured: the 10-D sphere stalled at 0.18
//!   after 400 generations without it, 5e-8 with it).
//! - Selection: (mu + mu): every parent makes one child; the mu best of parents and children
//!   survive.
//! - Strategic moves (Section 4.4, eq. 12): a memory of the n_p previous generations' bests; each
//!   generation mu_p extra candidates
//!   x^s_ij = U_ij(B_L, B_U) x*_j(k) - sum_{r=1..n_p} x*_j(k - r),   B_U = B_L + 1,
//!   replace the mu_p worst survivors. We take B_L = n_p + 1/2: then U = n_p + 1 gives the
//!   extrapolation x* + sum_r (x* - x*(k-r)) along the recent improvements, and the range
//!   [n_p + 1/2, n_p + 3/2] scatters each variable around it by +-x*/2 (the paper fixes only
//!   B_U = B_L + 1). Until the memory holds n_p bests, the available ones are used (with B_L =
//!   their count + 1/2); before any, no strategic move is made.
//!
//! The first generation is the initial point and mu - 1 individuals scattered uniformly within
//! +-sigma0 around it. Seeded; the generation's buffers are reused (no allocation per generation).

use crate::Optimiser;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::collections::VecDeque;

/// Settings of `ChaoticEa`; the defaults are the RKGNN paper's (mu 30, crossover 0.2) with
/// n_p 2, mu_p 3 and seed 1.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ChaoticEaConfig {
    /// Population size mu.
    pub population: usize,
    /// Probability of arithmetical crossover (0.2 in the paper).
    pub crossover: f64,
    /// Memory of previous bests n_p.
    pub memory: usize,
    /// Strategic moves per generation mu_p ("a lower percentage of the population").
    pub strategic: usize,
    /// Seed of the random numbers (initial scatter, crossover, logistic-map seeds, strategic
    /// moves).
    pub seed: u64,
}

impl Default for ChaoticEaConfig {
    fn default() -> Self {
        Self {
            population: 30,
            crossover: 0.2,
            memory: 2,
            strategic: 3,
            seed: 1,
        }
    }
}

/// The RKGNN paper's evolutionary algorithm with chaotic mutation and strategic moves (see
/// the module). It has no stopping rule of its own: `converged` is always false.
pub struct ChaoticEa {
    cfg: ChaoticEaConfig,
    rng: StdRng,
    n: usize,
    tau: f64,
    sigma0: Vec<f64>,
    /// Slots 0..mu: the survivors, best first. Slots mu..2mu: this generation's children (the
    /// first generation: the initial population); 2mu..2mu+mu_p: the strategic moves. Per slot:
    /// object variables, strategy parameters, logistic-map states and value.
    xs: Vec<Vec<f64>>,
    ss: Vec<Vec<f64>>,
    zs: Vec<Vec<f64>>,
    f: Vec<f64>,
    n_strategic: usize,
    /// Bests of previous generations, newest first.
    memory: VecDeque<Vec<f64>>,
    best_x: Vec<f64>,
    best_f: f64,
    generation: usize,
    evaluations: usize,
    /// Scratch for reordering slots (capacity fixed at construction).
    order: Vec<usize>,
    scratch: Vec<Vec<f64>>,
    scratch_f: Vec<f64>,
}

impl ChaoticEa {
    /// Start around `x0` with initial strategy parameters `sigma0` (one per variable, > 0).
    pub fn new(cfg: ChaoticEaConfig, x0: &[f64], sigma0: &[f64]) -> Self {
        let n = x0.len();
        assert_eq!(sigma0.len(), n);
        assert!(cfg.population >= 2, "a population of at least 2");
        let mut rng = StdRng::seed_from_u64(cfg.seed);
        let mu = cfg.population;
        let slots = 2 * mu + cfg.strategic;
        let mut xs = vec![vec![0.0; n]; slots];
        let mut zs = vec![vec![0.0; n]; slots];
        for i in 0..mu {
            for j in 0..n {
                xs[mu + i][j] = if i == 0 {
                    x0[j]
                } else {
                    x0[j] + sigma0[j] * rng.gen_range(-1.0..1.0)
                };
                zs[mu + i][j] = fresh_z(&mut rng);
            }
        }
        Self {
            tau: 1.0 / (2.0 * (n as f64).sqrt()).sqrt(),
            sigma0: sigma0.to_vec(),
            xs,
            ss: vec![sigma0.to_vec(); slots],
            zs,
            f: vec![f64::INFINITY; slots],
            n_strategic: 0,
            memory: VecDeque::with_capacity(cfg.memory + 1),
            best_x: x0.to_vec(),
            best_f: f64::INFINITY,
            generation: 0,
            evaluations: 0,
            order: Vec::with_capacity(slots),
            scratch: Vec::with_capacity(slots),
            scratch_f: Vec::with_capacity(slots),
            rng,
            n,
            cfg,
        }
    }

    /// The survivors' values, best first after a `tell`.
    pub fn values(&self) -> &[f64] {
        &self.f[..self.cfg.population]
    }

    /// The survivors, best first after a `tell`.
    pub fn population(&self) -> &[Vec<f64>] {
        &self.xs[..self.cfg.population]
    }

    fn chaos(z: &mut f64, rng: &mut StdRng) -> f64 {
        *z = 4.0 * *z * (1.0 - *z);
        if !(1e-9..1.0 - 1e-9).contains(z) || (*z - 0.75).abs() < 1e-12 {
            *z = fresh_z(rng);
        }
        2.0 * *z - 1.0
    }

    /// Children of the survivors and the strategic moves into their slots.
    fn breed(&mut self) {
        let (mu, n) = (self.cfg.population, self.n);
        let (parents, rest) = self.xs.split_at_mut(mu);
        let (sp, srest) = self.ss.split_at_mut(mu);
        let (zp, zrest) = self.zs.split_at_mut(mu);
        for i in 0..mu {
            let (c, cs, cz) = (&mut rest[i], &mut srest[i], &mut zrest[i]);
            c.copy_from_slice(&parents[i]);
            cs.copy_from_slice(&sp[i]);
            cz.copy_from_slice(&zp[i]);
            if self.rng.gen::<f64>() < self.cfg.crossover {
                let mut k = self.rng.gen_range(0..mu - 1);
                if k >= i {
                    k += 1;
                }
                let w: f64 = self.rng.gen();
                for j in 0..n {
                    c[j] = w * c[j] + (1.0 - w) * parents[k][j];
                    cs[j] = w * cs[j] + (1.0 - w) * sp[k][j];
                }
            }
            for j in 0..n {
                let a = Self::chaos(&mut cz[j], &mut self.rng);
                cs[j] = (cs[j] * (self.tau * a).exp())
                    .clamp(1e-6 * self.sigma0[j], 10.0 * self.sigma0[j]);
                let b = Self::chaos(&mut cz[j], &mut self.rng);
                c[j] += cs[j] * b;
            }
            // The parent's maps advance with the ones used, and the child's run one step ahead:
            // a parent that survives must not hand the same steps to its next child.
            zp[i].copy_from_slice(cz);
            for z in cz.iter_mut() {
                Self::chaos(z, &mut self.rng);
            }
        }
        // Eq. 12 over the memory available.
        self.n_strategic = if self.memory.is_empty() {
            0
        } else {
            self.cfg.strategic
        };
        let np = self.memory.len() as f64;
        for s in 0..self.n_strategic {
            let c = &mut rest[mu + s];
            for j in 0..n {
                let u = self.rng.gen_range(np + 0.5..np + 1.5);
                let past: f64 = self.memory.iter().map(|m| m[j]).sum();
                c[j] = u * self.best_x[j] - past;
            }
            srest[mu + s].copy_from_slice(&sp[0]);
            zrest[mu + s].copy_from_slice(&zp[0]);
        }
    }

    /// Reorder slots 0..k by value (stable), moving vectors, not copying them.
    fn sort_slots(&mut self, k: usize) {
        self.order.clear();
        self.order.extend(0..k);
        let f = &self.f;
        self.order
            .sort_by(|a, b| f[*a].total_cmp(&f[*b]).then(a.cmp(b)));
        for v in [&mut self.xs, &mut self.ss, &mut self.zs] {
            self.scratch.clear();
            self.scratch
                .extend(self.order.iter().map(|&i| std::mem::take(&mut v[i])));
            for (slot, x) in v.iter_mut().zip(self.scratch.drain(..)) {
                *slot = x;
            }
        }
        self.scratch_f.clear();
        self.scratch_f.extend(self.order.iter().map(|&i| self.f[i]));
        self.f[..k].copy_from_slice(&self.scratch_f);
    }
}

/// Factor on a parent's strategy parameters when its child did not improve on it.
const FAILURE_SHRINK: f64 = 0.97;

fn fresh_z(rng: &mut StdRng) -> f64 {
    rng.gen_range(0.01..0.99)
}

/// NaN ranks last.
fn key(v: f64) -> f64 {
    if v.is_nan() {
        f64::INFINITY
    } else {
        v
    }
}

impl Optimiser for ChaoticEa {
    fn ask(&mut self) -> &[Vec<f64>] {
        if self.generation > 0 {
            self.breed();
        }
        self.candidates()
    }

    fn candidates(&self) -> &[Vec<f64>] {
        let mu = self.cfg.population;
        &self.xs[mu..2 * mu + self.n_strategic]
    }

    fn tell(&mut self, values: &[f64]) {
        let mu = self.cfg.population;
        self.evaluations += values.len();
        // The previous generation's best joins the memory x*(k-1), ..., x*(k-n_p).
        if self.generation > 0 && self.cfg.memory > 0 {
            let mut slot = if self.memory.len() == self.cfg.memory {
                self.memory.pop_back().unwrap_or_default()
            } else {
                Vec::with_capacity(self.n)
            };
            slot.clear();
            slot.extend_from_slice(&self.xs[0]);
            self.memory.push_front(slot);
        }
        for (i, v) in values.iter().enumerate() {
            self.f[mu + i] = key(*v);
        }
        // A parent whose child did no better steps shorter next time (Rechenberg's success
        // rule, beside the chaotic self-adaptation): an elitist parent that is never beaten
        // would otherwise keep its step for ever.
        if self.generation > 0 {
            for i in 0..mu {
                if self.f[mu + i] >= self.f[i] {
                    for (s, s0) in self.ss[i].iter_mut().zip(&self.sigma0) {
                        *s = (*s * FAILURE_SHRINK).max(1e-6 * s0);
                    }
                }
            }
        }
        // (mu + mu) selection over parents and children.
        self.sort_slots(2 * mu);
        // Strategic moves replace the worst survivors.
        for s in 0..self.n_strategic {
            let slot = mu - 1 - s;
            self.xs.swap(slot, 2 * mu + s);
            self.ss.swap(slot, 2 * mu + s);
            self.zs.swap(slot, 2 * mu + s);
            self.f.swap(slot, 2 * mu + s);
        }
        if self.n_strategic > 0 {
            self.sort_slots(mu);
        }
        if self.f[0] < self.best_f {
            self.best_f = self.f[0];
            self.best_x.copy_from_slice(&self.xs[0]);
        }
        self.generation += 1;
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.best_x, self.best_f)
    }

    fn generation(&self) -> usize {
        self.generation
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }

    fn converged(&self) -> bool {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{run, Objective};

    fn sphere(x: &[f64]) -> f64 {
        x.iter().map(|v| (v - 1.0) * (v - 1.0)).sum()
    }

    #[test]
    fn it_minimises_a_sphere_and_is_seeded() {
        let go = |seed| {
            let mut ea = ChaoticEa::new(
                ChaoticEaConfig {
                    seed,
                    ..Default::default()
                },
                &[5.0; 10],
                &[2.0; 10],
            );
            run(&mut ea, &sphere, 1, 400, None, |_| {})
        };
        let a = go(3);
        assert!(a.value < 1e-3, "sphere after 400 generations: {}", a.value);
        assert_eq!(a.best, go(3).best, "same seed, same result");
        assert_ne!(a.best, go(4).best);
        // Elitist: the best never gets worse.
        assert!(a.history.windows(2).all(|w| w[1] <= w[0]));
    }

    #[test]
    fn rosenbrock_improves_far_from_the_start() {
        struct Rosen;
        impl Objective for Rosen {
            fn value(&self, x: &[f64]) -> f64 {
                x.windows(2)
                    .map(|w| 100.0 * (w[1] - w[0] * w[0]).powi(2) + (1.0 - w[0]).powi(2))
                    .sum()
            }
        }
        let mut ea = ChaoticEa::new(
            ChaoticEaConfig::default(),
            &[-1.2, 1.0, -1.2, 1.0],
            &[0.5; 4],
        );
        let start = Rosen.value(&[-1.2, 1.0, -1.2, 1.0]);
        let r = run(&mut ea, &Rosen, 1, 1000, None, |_| {});
        assert!(r.value < start / 100.0, "{} from {start}", r.value);
    }

    #[test]
    fn strategic_moves_follow_eq_12() {
        // With a memory of one best x*(k-1) and the current best x*(k), every strategic
        // candidate lies in [1.5 x* - x*(k-1), 2.5 x* - x*(k-1)] elementwise (x* > 0 here).
        let cfg = ChaoticEaConfig {
            memory: 1,
            strategic: 5,
            ..Default::default()
        };
        let mut ea = ChaoticEa::new(cfg, &[3.0; 4], &[0.5; 4]);
        // Bests after each tell: at the next ask, x*(k) is the last, x*(k-1) the one before.
        let mut bests: Vec<Vec<f64>> = Vec::new();
        for _ in 0..20 {
            let cands = ea.ask().to_vec();
            if bests.len() >= 2 {
                let (best, prev) = (&bests[bests.len() - 1], &bests[bests.len() - 2]);
                assert_eq!(ea.best().0, &best[..]);
                assert_eq!(cands.len(), cfg.population + 5);
                for c in &cands[cfg.population..] {
                    for j in 0..4 {
                        let lo = 1.5 * best[j] - prev[j];
                        let hi = 2.5 * best[j] - prev[j];
                        assert!(c[j] >= lo.min(hi) - 1e-12 && c[j] <= lo.max(hi) + 1e-12);
                    }
                }
            }
            let values: Vec<f64> = cands.iter().map(|c| sphere(c)).collect();
            ea.tell(&values);
            bests.push(ea.population()[0].clone());
        }
    }
}
