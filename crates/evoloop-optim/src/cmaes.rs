//! CMA-ES, the covariance matrix adaptation evolution strategy (Hansen, "The CMA Evolution
//! Strategy: A Tutorial", arXiv:1604.00772, 2016): (mu/mu_w, lambda) with weighted
//! recombination, cumulative step-size adaptation and the rank-one plus rank-mu covariance
//! update, with the tutorial's default constants (its Table 1).
//!
//! Where the tutorial leaves a choice:
//! - **Coordinates.** The search runs in the box normalised to [0, 1]^d, so that one step size
//!   suits gains of different magnitudes (a PID's k_p in the thousands beside a k_d of 0.01).
//! - **Start.** The mean starts at the first seed set when one is given (the set in service:
//!   a tuner on a running plant starts where the plant is), else at the box's centre; sigma_0 =
//!   `CmaesConfig::sigma` of the box (0.2 by default: a step the plant is likely to survive).
//! - **Box.** A sample outside the box is projected onto it and the projected point is both
//!   evaluated and used in the update (the tutorial's "repair", Lamarckian), its step bounded in
//!   C's norm as Hansen (2011) does for injected solutions: the strategy adapts to the steps it
//!   really took without a projected step inflating its paths.
//! - **A value of +infinity** (an aborted trial) ranks last and is not recombined; a generation
//!   with none finite halves the step and leaves the mean.
//!
//! The eigendecomposition of C runs once a generation (d <= 25 in evoloop's tuning problems,
//! microseconds); vectors are allocated per sample, negligible beside an experiment on a plant.

use super::rng::Xoshiro256pp;
use super::Optimiser;
use crate::settings::{from_unit, to_unit};
use crate::SettingsError;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

/// Settings of `Cmaes`: the search box, lambda, sigma_0, the start and the seed.
#[derive(Debug, Clone, PartialEq)]
pub struct CmaesConfig {
    /// Lower bounds of the search box, one per object variable.
    pub lower: Vec<f64>,
    /// Upper bounds of the search box, each above its lower bound.
    pub upper: Vec<f64>,
    /// lambda, candidates per generation (the tutorial's default: 4 + floor(3 ln d)).
    pub population: usize,
    /// sigma_0 as a fraction of the box.
    pub sigma: f64,
    /// Where the mean starts (None: the box's centre).
    pub start: Option<Vec<f64>>,
    /// Seed of the Gaussian samples.
    pub seed: u64,
}

impl CmaesConfig {
    /// The tutorial's population for `d` dimensions.
    pub fn default_population(d: usize) -> usize {
        4 + (3.0 * (d as f64).ln()).floor() as usize
    }
}

/// CMA-ES in the box's unit coordinates (see the module). Converged once the step size
/// sigma falls below 1e-12.
pub struct Cmaes {
    cfg: CmaesConfig,
    d: usize,
    /// Recombination weights of the best mu (their mu_eff set the constants below).
    weights: Vec<f64>,
    c_sigma: f64,
    d_sigma: f64,
    c_c: f64,
    c_1: f64,
    c_mu: f64,
    chi_n: f64,
    /// Mean, step size, paths and covariance, in normalised coordinates.
    mean: DVector<f64>,
    sigma: f64,
    p_sigma: DVector<f64>,
    p_c: DVector<f64>,
    c: DMatrix<f64>,
    /// B D (C = B D^2 B^T) and C^{-1/2} from the last decomposition.
    bd: DMatrix<f64>,
    c_inv_sqrt: DMatrix<f64>,
    /// This generation's normalised points (after projection), whether each was projected,
    /// and their real-valued copies.
    points: Vec<DVector<f64>>,
    projected: Vec<bool>,
    candidates: Vec<Vec<f64>>,
    rng: Xoshiro256pp,
    best: (Vec<f64>, f64),
    generation: usize,
    evaluations: usize,
}

impl Cmaes {
    /// A CMA-ES with `cfg`. Fails if the bounds are not a box, the population is below 2,
    /// `sigma` is not in (0, 1] or `start` has the wrong length.
    pub fn new(cfg: CmaesConfig) -> Result<Self, SettingsError> {
        crate::settings::check_box(&cfg.lower, &cfg.upper)?;
        let d = cfg.lower.len();
        if cfg.population < 2 {
            return Err(SettingsError::out_of_range(
                "population",
                ">= 2",
                cfg.population,
            ));
        }
        if !(cfg.sigma > 0.0 && cfg.sigma <= 1.0) {
            return Err(SettingsError::out_of_range("sigma", "in (0, 1]", cfg.sigma));
        }
        if let Some(s) = &cfg.start {
            if s.len() != d {
                return Err(SettingsError::BoxShape {
                    lower: d,
                    upper: s.len(),
                });
            }
        }
        let (lambda, df) = (cfg.population, d as f64);
        let mu = lambda / 2;
        let raw: Vec<f64> = (0..mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - ((i + 1) as f64).ln())
            .collect();
        let sum: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / sum).collect();
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let c_sigma = (mu_eff + 2.0) / (df + mu_eff + 5.0);
        let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (df + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
        let c_c = (4.0 + mu_eff / df) / (df + 4.0 + 2.0 * mu_eff / df);
        let c_1 = 2.0 / ((df + 1.3).powi(2) + mu_eff);
        let c_mu =
            (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((df + 2.0).powi(2) + mu_eff));
        let chi_n = df.sqrt() * (1.0 - 1.0 / (4.0 * df) + 1.0 / (21.0 * df * df));
        let mean = match &cfg.start {
            Some(s) => to_unit(&cfg.lower, &cfg.upper, s),
            None => DVector::from_element(d, 0.5),
        };
        Ok(Self {
            d,
            weights,
            c_sigma,
            d_sigma,
            c_c,
            c_1,
            c_mu,
            chi_n,
            mean,
            sigma: cfg.sigma,
            p_sigma: DVector::zeros(d),
            p_c: DVector::zeros(d),
            c: DMatrix::identity(d, d),
            bd: DMatrix::identity(d, d),
            c_inv_sqrt: DMatrix::identity(d, d),
            points: Vec::with_capacity(lambda),
            projected: Vec::with_capacity(lambda),
            candidates: Vec::with_capacity(lambda),
            rng: Xoshiro256pp::seed_from_u64(cfg.seed),
            best: (Vec::new(), f64::INFINITY),
            generation: 0,
            evaluations: 0,
            cfg,
        })
    }

    /// The step size, in units of the box (for tests and reports).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// C = B D^2 B^T: B D and C^{-1/2} for the next generation.
    fn decompose(&mut self) {
        // Enforce symmetry against round-off before the decomposition.
        let c = (&self.c + self.c.transpose()) * 0.5;
        let eig = c.clone().symmetric_eigen();
        let dvals = eig.eigenvalues.map(|v| v.max(1e-20).sqrt());
        let b = eig.eigenvectors;
        self.bd = &b * DMatrix::from_diagonal(&dvals);
        self.c_inv_sqrt = &b * DMatrix::from_diagonal(&dvals.map(|v| 1.0 / v)) * b.transpose();
        self.c = c;
    }
}

impl Optimiser for Cmaes {
    fn ask(&mut self) -> &[Vec<f64>] {
        self.points.clear();
        self.projected.clear();
        self.candidates.clear();
        for _ in 0..self.cfg.population {
            let z = DVector::from_iterator(
                self.d,
                (0..self.d).map(|_| StandardNormal.sample(&mut self.rng)),
            );
            let drawn = &self.mean + (&self.bd * z) * self.sigma;
            let x = drawn.map(|v| v.clamp(0.0, 1.0));
            self.projected.push(x != drawn);
            self.candidates
                .push(from_unit(&self.cfg.lower, &self.cfg.upper, &x));
            self.points.push(x);
        }
        &self.candidates
    }

    fn candidates(&self) -> &[Vec<f64>] {
        &self.candidates
    }

    fn tell(&mut self, values: &[f64]) {
        assert_eq!(values.len(), self.points.len(), "one value per candidate");
        self.evaluations += values.len();
        let mut order: Vec<usize> = (0..values.len()).collect();
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        if values[order[0]] < self.best.1 {
            self.best = (self.candidates[order[0]].clone(), values[order[0]]);
        }
        // Recombine the best mu with finite values only: aborted candidates carry no ranking
        // among themselves. None finite: nothing learnt, and the region about the mean aborts
        // its samples, so the step halves.
        let ranked: Vec<usize> = order
            .iter()
            .copied()
            .filter(|&i| values[i].is_finite())
            .take(self.weights.len())
            .collect();
        if ranked.is_empty() {
            self.sigma *= 0.5;
            self.generation += 1;
            return;
        }
        let sum: f64 = self.weights[..ranked.len()].iter().sum();
        let weights: Vec<f64> = self.weights[..ranked.len()]
            .iter()
            .map(|w| w / sum)
            .collect();
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        // Each step as taken; a projected sample's step (not one C would draw) no longer in
        // Mahalanobis norm than sqrt(d) + 2d / (d + 2), so that it does not inflate the paths
        // (Hansen 2011, "Injecting external solutions"). Drawn steps are used as drawn.
        let old = self.mean.clone();
        let df = self.d as f64;
        let bound = df.sqrt() + 2.0 * df / (df + 2.0);
        let ys: Vec<DVector<f64>> = ranked
            .iter()
            .map(|&i| {
                let y = (&self.points[i] - &old) / self.sigma;
                let m = (&self.c_inv_sqrt * &y).norm();
                if self.projected[i] && m > bound {
                    y * (bound / m)
                } else {
                    y
                }
            })
            .collect();
        let mut step = DVector::zeros(self.d);
        for (w, y) in weights.iter().zip(&ys) {
            step += y * *w;
        }
        self.mean = (&old + &step * self.sigma).map(|v| v.clamp(0.0, 1.0));
        let cs = self.c_sigma;
        self.p_sigma = &self.p_sigma * (1.0 - cs)
            + (&self.c_inv_sqrt * &step) * (cs * (2.0 - cs) * mu_eff).sqrt();
        let g = (self.generation + 1) as f64;
        let ps_norm = self.p_sigma.norm();
        // h_sigma: stall the rank-one update while the step-size path is long (tutorial eq. 45).
        let h_sigma = ps_norm / (1.0 - (1.0 - cs).powf(2.0 * g)).sqrt() / self.chi_n
            < 1.4 + 2.0 / (self.d as f64 + 1.0);
        let cc = self.c_c;
        self.p_c = &self.p_c * (1.0 - cc);
        if h_sigma {
            self.p_c += &step * (cc * (2.0 - cc) * mu_eff).sqrt();
        }
        let delta_h = if h_sigma { 0.0 } else { cc * (2.0 - cc) };
        let mut rank_mu = DMatrix::zeros(self.d, self.d);
        for (w, y) in weights.iter().zip(&ys) {
            rank_mu += y * y.transpose() * *w;
        }
        self.c = &self.c * (1.0 + self.c_1 * delta_h - self.c_1 - self.c_mu)
            + &self.p_c * self.p_c.transpose() * self.c_1
            + rank_mu * self.c_mu;
        self.sigma *= ((cs / self.d_sigma) * (ps_norm / self.chi_n - 1.0)).exp();
        self.sigma = self.sigma.min(1.0);
        self.decompose();
        self.generation += 1;
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.best.0, self.best.1)
    }

    fn generation(&self) -> usize {
        self.generation
    }

    fn evaluations(&self) -> usize {
        self.evaluations
    }

    /// Converged when the step is below 1e-12 of the box (nothing left to learn).
    fn converged(&self) -> bool {
        self.sigma < 1e-12
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(f: impl Fn(&[f64]) -> f64, d: usize, budget: usize, seed: u64) -> f64 {
        let mut o = Cmaes::new(CmaesConfig {
            lower: vec![-5.0; d],
            upper: vec![5.0; d],
            population: CmaesConfig::default_population(d),
            sigma: 0.3,
            start: Some(vec![3.0; d]),
            seed,
        })
        .unwrap();
        while o.evaluations() < budget {
            let v: Vec<f64> = o.ask().iter().map(|x| f(x)).collect();
            o.tell(&v);
        }
        o.best().1
    }

    /// A rotated, ill-conditioned ellipsoid (condition 1e4): what CMA-ES is for, and where a
    /// method without covariance learning stalls.
    fn rotated_ellipsoid(x: &[f64]) -> f64 {
        let d = x.len();
        let mut s = 0.0;
        for i in 0..d {
            // y = R x with R a fixed rotation (pairs of coordinates mixed by 30 degrees).
            let j = (i + 1) % d;
            let (c, sn) = (0.866_025_403_784_438_6, 0.5);
            let y = c * (x[i] - 1.0) + sn * (x[j] - 1.0);
            s += 10f64.powf(4.0 * i as f64 / (d - 1) as f64) * y * y;
        }
        s
    }

    #[test]
    fn solves_a_rotated_ill_conditioned_ellipsoid() {
        for seed in 1..=5 {
            let best = run(rotated_ellipsoid, 6, 5000, seed);
            assert!(best < 1e-8, "seed {seed}: {best}");
        }
    }

    #[test]
    fn rosenbrock_in_few_evaluations() {
        let rosen = |x: &[f64]| {
            (0..x.len() - 1)
                .map(|i| 100.0 * (x[i + 1] - x[i] * x[i]).powi(2) + (1.0 - x[i]).powi(2))
                .sum::<f64>()
        };
        let best = run(rosen, 4, 4000, 1);
        assert!(best < 1e-6, "{best}");
    }

    #[test]
    fn candidates_stay_in_the_box_and_infinity_ranks_last() {
        let mut o = Cmaes::new(CmaesConfig {
            lower: vec![0.0, 10.0],
            upper: vec![1.0, 20.0],
            population: 8,
            sigma: 1.0,
            start: None,
            seed: 3,
        })
        .unwrap();
        for _ in 0..20 {
            let xs = o.ask().to_vec();
            for x in &xs {
                assert!((0.0..=1.0).contains(&x[0]) && (10.0..=20.0).contains(&x[1]));
            }
            // Everything with x0 > 0.5 "aborts".
            let v: Vec<f64> = xs
                .iter()
                .map(|x| {
                    if x[0] > 0.5 {
                        f64::INFINITY
                    } else {
                        (x[1] - 12.0).powi(2)
                    }
                })
                .collect();
            o.tell(&v);
        }
        let (x, v) = o.best();
        assert!(v < 1e-3 && x[0] <= 0.5, "{x:?} {v}");
    }

    #[test]
    fn refuses_bad_settings() {
        let cfg = CmaesConfig {
            lower: vec![0.0],
            upper: vec![1.0],
            population: 1,
            sigma: 0.2,
            start: None,
            seed: 1,
        };
        assert!(Cmaes::new(cfg.clone()).is_err());
        assert!(Cmaes::new(CmaesConfig {
            sigma: 0.0,
            population: 4,
            ..cfg.clone()
        })
        .is_err());
        assert!(Cmaes::new(CmaesConfig {
            start: Some(vec![0.5, 0.5]),
            population: 4,
            ..cfg
        })
        .is_err());
    }
}
