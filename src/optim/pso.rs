//! Particle swarm optimisation, eqs. 1-2 of the eMuPSO paper, in two flavours sharing one
//! velocity update:
//!
//! - `Pso`, canonical PSO with inertia weight (Shi and Eberhart 1998): w falls linearly from
//!   0.9 to 0.4 over the iteration budget, c1 = c2 = 2, velocities clamped to 20 % of each
//!   dimension's range, positions to the box (the velocity component that left it is zeroed).
//! - eMuPSO's particles (`super::emupso`) use the same update with their own schedules.

use super::swarm::{Rule, Swarm, SwarmConfig, SwarmOptimiser};

/// Velocities and personal bests: the particle part of a swarm.
pub struct Particles {
    pub v: Vec<Vec<f64>>,
    pub pbest_x: Vec<Vec<f64>>,
    pub pbest_f: Vec<f64>,
    /// The best personal best since the swarm was (re)built: the social attractor. For
    /// canonical PSO it is the run's best; eMuPSO restarts it at every mutation.
    gbest_x: Vec<f64>,
    gbest_f: f64,
    /// Largest |v_j| as a fraction of dimension j's range.
    pub vmax_fraction: f64,
    /// The clamp per dimension (scratch of `fly`).
    vmax: Vec<f64>,
}

impl Particles {
    pub fn new(s: &Swarm, vmax_fraction: f64) -> Self {
        let (n, d) = (s.cfg.population, s.cfg.dim());
        Self {
            v: vec![vec![0.0; d]; n],
            pbest_x: s.x.clone(),
            pbest_f: vec![f64::INFINITY; n],
            gbest_x: s.x[0].clone(),
            gbest_f: f64::INFINITY,
            vmax_fraction,
            vmax: vec![0.0; d],
        }
    }

    /// The swarm's best value since it was (re)built.
    pub fn swarm_best_f(&self) -> f64 {
        self.gbest_f
    }

    /// Forget the swarm's best (a rebuilt swarm starts its own).
    pub fn reset_swarm_best(&mut self) {
        self.gbest_f = f64::INFINITY;
    }

    /// Take the values just recorded into the personal bests.
    pub fn update_bests(&mut self, s: &Swarm) {
        for i in 0..s.x.len() {
            if s.f[i] < self.pbest_f[i] {
                self.pbest_f[i] = s.f[i];
                self.pbest_x[i].copy_from_slice(&s.x[i]);
            }
            if s.f[i] < self.gbest_f {
                self.gbest_f = s.f[i];
                self.gbest_x.copy_from_slice(&s.x[i]);
            }
        }
    }

    /// Eqs. 1-2 with inertia w and coefficients c1 (towards the personal best) and c2 (towards
    /// the swarm's best), r1, r2 uniform per dimension (one 64-bit draw gives both, 32 bits
    /// each: the optimiser's own cost per evaluation is mostly drawing numbers).
    pub fn fly(&mut self, s: &mut Swarm, w: f64, c1: f64, c2: f64) {
        let (lower, upper) = (&s.cfg.lower, &s.cfg.upper);
        for (m, (l, u)) in self.vmax.iter_mut().zip(lower.iter().zip(upper)) {
            *m = self.vmax_fraction * (u - l);
        }
        let rng = &mut s.rng;
        for ((x, v), p) in s.x.iter_mut().zip(&mut self.v).zip(&self.pbest_x) {
            let dims = x
                .iter_mut()
                .zip(v.iter_mut())
                .zip(p.iter().zip(&self.gbest_x));
            for (((xj, vj), (pj, gj)), (vmax, (l, u))) in
                dims.zip(self.vmax.iter().zip(lower.iter().zip(upper)))
            {
                let (r1, r2) = rng.pair();
                let nv =
                    (w * *vj + c1 * r1 * (pj - *xj) + c2 * r2 * (gj - *xj)).clamp(-vmax, *vmax);
                let nx = *xj + nv;
                let cx = nx.clamp(*l, *u);
                *vj = if cx == nx { nv } else { 0.0 };
                *xj = cx;
            }
        }
    }
}

/// Canonical PSO's rule.
pub struct PsoRule {
    p: Particles,
}

pub type Pso = SwarmOptimiser<PsoRule>;

/// Inertia weight at the start and at the end of the budget, and c1 = c2.
const W_START: f64 = 0.9;
const W_END: f64 = 0.4;
const C: f64 = 2.0;
/// Velocity clamp, fraction of the range.
const VMAX: f64 = 0.2;

impl Pso {
    pub fn new(cfg: SwarmConfig) -> Result<Self, String> {
        let swarm = Swarm::new(cfg)?;
        let p = Particles::new(&swarm, VMAX);
        Ok(SwarmOptimiser::from_parts(swarm, PsoRule { p }))
    }
}

impl Rule for PsoRule {
    const NAME: &'static str = "pso";
    fn advance(&mut self, s: &mut Swarm) {
        self.p.update_bests(s);
        let w = W_START + (W_END - W_START) * s.progress();
        self.p.fly(s, w, C, C);
    }
}
