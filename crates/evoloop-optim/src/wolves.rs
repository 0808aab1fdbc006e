//! The eMuPSO paper's swarm peers, each as its reference publication defines it (and as
//! Mirjalili's reference MATLAB code implements it, where the papers leave a detail open):
//!
//! - `Gwo`, Grey Wolf Optimizer (Mirjalili, Mirjalili and Lewis 2014): a falls linearly from 2
//!   to 0; each wolf moves to the mean of X_alpha - A1 |C1 X_alpha - X|, the same for beta
//!   and delta (the three best so far), A = 2 a r1 - a and C = 2 r2 per dimension.
//! - `Woa`, Whale Optimization Algorithm (Mirjalili and Lewis 2016): a falls from 2 to 0, a2
//!   from -1 to -2; per whale one A, C, p and l = (a2 - 1) r + 1; with p < 0.5 it encircles
//!   the best (|A| < 1) or a random whale (|A| >= 1), else it spirals to the best,
//!   D e^(b l) cos(2 pi l) + X* with b = 1.
//! - `Goa`, Grasshopper Optimisation Algorithm (Saremi, Mirjalili and Lewis 2017): c falls
//!   linearly from 1 to 4e-5; X_i = c sum_(j != i) c (ub - lb)/2 s(d_ij) (x_j - x_i)/d_ij + T
//!   per dimension with s(r) = f e^(-r/l) - e^(-r), f = 0.5, l = 1.5, the distance mapped into
//!   [2, 4) as the reference code does (2 + d mod 2), T the best so far.
//!
//! All positions are clamped to the box. GWO and WOA move towards the best positions by
//! multiplying differences, so they favour the origin's neighbourhood when the best is near it;
//! the study's shifted copies are there so that an optimum at the origin does not flatter them.

use super::swarm::{Rule, Swarm, SwarmConfig, SwarmOptimiser};
use crate::SettingsError;
use rand::Rng;

/// GWO's three leaders (positions and values).
pub struct GwoRule {
    leaders: [(Vec<f64>, f64); 3],
}

/// The Grey Wolf Optimizer as an `Optimiser`.
pub type Gwo = SwarmOptimiser<GwoRule>;

impl Gwo {
    /// A GWO on the swarm `cfg`. Fails as `SwarmConfig::validate` does.
    pub fn new(cfg: SwarmConfig) -> Result<Self, SettingsError> {
        let swarm = Swarm::new(cfg)?;
        let d = swarm.cfg.dim();
        let leader = || (vec![0.0; d], f64::INFINITY);
        Ok(SwarmOptimiser::from_parts(
            swarm,
            GwoRule {
                leaders: [leader(), leader(), leader()],
            },
        ))
    }
}

impl Rule for GwoRule {
    const NAME: &'static str = "gwo";
    fn advance(&mut self, s: &mut Swarm) {
        // Alpha, beta, delta: the three best positions seen.
        for i in 0..s.x.len() {
            let f = s.f[i];
            if let Some(k) = self.leaders.iter().position(|l| f < l.1) {
                // Shift the worse leaders down one place; the old delta's buffer takes x.
                self.leaders[k..].rotate_right(1);
                self.leaders[k].0.copy_from_slice(&s.x[i]);
                self.leaders[k].1 = f;
            }
        }
        let a = 2.0 * (1.0 - s.progress());
        for i in 0..s.x.len() {
            for j in 0..s.cfg.dim() {
                let mut sum = 0.0;
                for l in &self.leaders {
                    let (r1, r2): (f64, f64) = (s.rng.gen(), s.rng.gen());
                    let (aa, c) = (2.0 * a * r1 - a, 2.0 * r2);
                    sum += l.0[j] - aa * (c * l.0[j] - s.x[i][j]).abs();
                }
                s.x[i][j] = s.clamp(j, sum / 3.0);
            }
        }
    }
}

/// WOA's `Rule`: it keeps no state beyond the swarm's (the best so far is `Swarm::best_x`).
pub struct WoaRule;

/// The Whale Optimization Algorithm as an `Optimiser`.
pub type Woa = SwarmOptimiser<WoaRule>;

impl Woa {
    /// A WOA on the swarm `cfg`. Fails as `SwarmConfig::validate` does.
    pub fn new(cfg: SwarmConfig) -> Result<Self, SettingsError> {
        Ok(SwarmOptimiser::from_parts(Swarm::new(cfg)?, WoaRule))
    }
}

impl Rule for WoaRule {
    const NAME: &'static str = "woa";
    fn advance(&mut self, s: &mut Swarm) {
        let t = s.progress();
        let (a, a2) = (2.0 * (1.0 - t), -1.0 - t);
        let n = s.x.len();
        for i in 0..n {
            let (r1, r2): (f64, f64) = (s.rng.gen(), s.rng.gen());
            let (aa, c) = (2.0 * a * r1 - a, 2.0 * r2);
            let l = (a2 - 1.0) * s.rng.gen::<f64>() + 1.0;
            let p: f64 = s.rng.gen();
            // The random whale is drawn per whale (the reference code draws it per dimension;
            // one whale per move is the paper's eq. 2.8).
            let rand = s.rng.gen_range(0..n);
            for j in 0..s.cfg.dim() {
                let x = s.x[i][j];
                let best = s.best_x[j];
                let nx = if p < 0.5 {
                    let lead = if aa.abs() < 1.0 { best } else { s.x[rand][j] };
                    lead - aa * (c * lead - x).abs()
                } else {
                    (best - x).abs() * l.exp() * (2.0 * std::f64::consts::PI * l).cos() + best
                };
                s.x[i][j] = s.clamp(j, nx);
            }
        }
    }
}

/// GOA keeps the previous positions (every grasshopper moves from the same swarm state) and
/// one grasshopper's social sum per dimension.
pub struct GoaRule {
    prev: Vec<Vec<f64>>,
    sum: Vec<f64>,
}

/// The Grasshopper Optimisation Algorithm as an `Optimiser`.
pub type Goa = SwarmOptimiser<GoaRule>;

impl Goa {
    /// A GOA on the swarm `cfg`. Fails as `SwarmConfig::validate` does.
    pub fn new(cfg: SwarmConfig) -> Result<Self, SettingsError> {
        let swarm = Swarm::new(cfg)?;
        let prev = swarm.x.clone();
        let sum = vec![0.0; swarm.cfg.dim()];
        Ok(SwarmOptimiser::from_parts(swarm, GoaRule { prev, sum }))
    }
}

/// s(r) of the social forces.
fn social(r: f64) -> f64 {
    const F: f64 = 0.5;
    const L: f64 = 1.5;
    F * (-r / L).exp() - (-r).exp()
}

impl Rule for GoaRule {
    const NAME: &'static str = "goa";
    fn advance(&mut self, s: &mut Swarm) {
        const C_MAX: f64 = 1.0;
        const C_MIN: f64 = 0.00004;
        let c = C_MAX - s.progress() * (C_MAX - C_MIN);
        let n = s.x.len();
        for (p, x) in self.prev.iter_mut().zip(&s.x) {
            p.copy_from_slice(x);
        }
        for i in 0..n {
            self.sum.fill(0.0);
            for k in (0..n).filter(|&k| k != i) {
                // One distance per pair (not per dimension), mapped into [2, 4).
                let (xi, xk) = (&self.prev[i], &self.prev[k]);
                let dist = xi
                    .iter()
                    .zip(xk)
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    .sqrt();
                let force = c * social(2.0 + dist % 2.0) / (dist + f64::EPSILON);
                for (j, sj) in self.sum.iter_mut().enumerate() {
                    *sj += 0.5 * s.cfg.range(j) * force * (xk[j] - xi[j]);
                }
            }
            for j in 0..s.cfg.dim() {
                s.x[i][j] = s.clamp(j, c * self.sum[j] + s.best_x[j]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Optimiser;

    fn run<O: Optimiser>(o: &mut O, iterations: usize, f: impl Fn(&[f64]) -> f64) -> f64 {
        let budget = o.candidates().len() * (iterations + 1);
        crate::drive(o, budget, f, |_| {});
        o.best().1
    }

    /// Each peer makes real progress on a shifted sphere (optimum away from the origin), and a
    /// seeded run repeats bit for bit.
    #[test]
    fn the_peers_converge_on_a_shifted_sphere_and_repeat_with_their_seed() {
        let f = |x: &[f64]| x.iter().map(|v| (v - 1.234).powi(2)).sum::<f64>();
        let cfg = SwarmConfig::for_budget(vec![-10.0; 5], vec![10.0; 5], 20, 4000, 5);
        let t = cfg.iterations;
        let start = 5.0 * 10.0f64.powi(2) / 3.0; // about the mean of f over the box
        for (name, a, b) in [
            (
                "gwo",
                run(&mut Gwo::new(cfg.clone()).unwrap(), t, f),
                run(&mut Gwo::new(cfg.clone()).unwrap(), t, f),
            ),
            (
                "woa",
                run(&mut Woa::new(cfg.clone()).unwrap(), t, f),
                run(&mut Woa::new(cfg.clone()).unwrap(), t, f),
            ),
            (
                "goa",
                run(&mut Goa::new(cfg.clone()).unwrap(), t, f),
                run(&mut Goa::new(cfg.clone()).unwrap(), t, f),
            ),
        ] {
            assert_eq!(a.to_bits(), b.to_bits(), "{name} not reproducible");
            assert!(a < 1e-3 * start, "{name}: {a}");
        }
    }

    #[test]
    fn the_social_force_attracts_far_and_repels_near() {
        assert!(social(1.0) < 0.0 && social(3.0) > 0.0);
        // Comfort zone near r = 2.079 for f = 0.5, l = 1.5.
        assert!(social(2.0) < 0.0 && social(2.2) > 0.0);
    }
}
