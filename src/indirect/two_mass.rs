//! The indirect scheme on the two-mass-spring benchmark: the spring constant k is estimated
//! online by recursive least squares on v2' = k (x1 - x2) / m2 from the published state, and
//! DE/rand/1/bin tunes the state-feedback gains on the model with the estimated k for the cost
//! of one repetition of the scenario's reference, sum |r - y| + w sum |u| per sample.

use super::{Candidate, Estimate, Scheme};
use crate::config::Scenario;
use crate::control::StateFeedback;
use crate::ipc::messages::PlantState;
use crate::optim::{evaluate, DeConfig, DifferentialEvolution, Optimiser};
use crate::plant::two_mass::{Sensor, TwoMass};
use crate::reference::Reference;

pub struct TwoMassScheme {
    m1: f64,
    m2: f64,
    k_nominal: f64,
    sensor: Sensor,
    period: f64,
    step: f64,
    reference: Reference,
    duration: f64,
    lower: Vec<f64>,
    upper: Vec<f64>,
    u_limit: Option<f64>,
    w: f64,
    seed: u64,
    threads: usize,
    epoch_evaluations: usize,
    margin: f64,
    epoch_no: u64,
    // Estimator: ring of (deflection x1 - x2, v2) for central differences over `stride` samples.
    stride: usize,
    ring: Vec<(f64, f64)>,
    filled: usize,
    rls: super::rls::Rls,
}

impl TwoMassScheme {
    pub fn new(scn: &Scenario) -> Self {
        let stride = 5;
        let repetition = match &scn.reference {
            Reference::Square { period, start, .. } => start + period,
            _ => scn.timing.duration.min(20.0),
        };
        Self {
            m1: scn.plant.m1,
            m2: scn.plant.m2,
            k_nominal: scn.plant.spring,
            sensor: scn.plant.sensor,
            period: scn.timing.period,
            step: scn.plant.step,
            reference: scn.reference.clone(),
            duration: repetition,
            lower: scn.controller.lower.clone(),
            upper: scn.controller.upper.clone(),
            u_limit: scn.controller.u_limit,
            w: scn.optimiser.cost_u_weight,
            seed: scn.seed,
            threads: scn.optimiser.threads,
            epoch_evaluations: scn.optimiser.epoch_evaluations,
            margin: scn.optimiser.margin,
            epoch_no: 0,
            stride,
            ring: vec![(0.0, 0.0); 2 * stride + 1],
            filled: 0,
            rls: super::rls::Rls::new(scn.plant.spring / scn.plant.m2, 0.99),
        }
    }

    /// Cost of `gains` over one repetition on the model with spring constant k (infinite when
    /// the loop diverges).
    pub fn cost(&self, k: f64, gains: &[f64]) -> f64 {
        let plant = TwoMass::new(self.m1, self.m2, k, self.sensor);
        let ctrl = StateFeedback::new(gains, self.period, self.u_limit);
        let (_, y, u) = crate::sim::response(
            Box::new(plant),
            Box::new(ctrl),
            &self.reference,
            self.period,
            self.step,
            self.duration,
            1e3,
        );
        let n = (self.duration / self.period).round() as usize;
        if y.len() < n {
            return f64::INFINITY;
        }
        let mut sp = crate::reference::Setpoint::default();
        let mut c = 0.0;
        for (k, (yk, uk)) in y.iter().zip(&u).enumerate() {
            self.reference.sample(k as f64 * self.period, &mut sp);
            c += (sp.q[0] - yk).abs() + self.w * uk.abs();
        }
        c
    }
}

impl Scheme for TwoMassScheme {
    fn observe(&mut self, prev: Option<&PlantState>, s: &PlantState) {
        if prev.is_none() {
            self.filled = 0;
        }
        let n = self.ring.len();
        // State order [x2, x1, v2, v1].
        self.ring[s.seq as usize % n] = (s.x[1] - s.x[0], s.x[2]);
        self.filled += 1;
        if self.filled >= n && s.seq % self.stride as u64 == 0 {
            let st = self.stride as u64;
            let (_, v_a) = self.ring[(s.seq - 2 * st) as usize % n];
            let (d, _) = self.ring[(s.seq - st) as usize % n];
            let (_, v_b) = self.ring[s.seq as usize % n];
            let acc = (v_b - v_a) / (2.0 * st as f64 * self.period);
            // acc = (k / m2) d: RLS on theta = k / m2.
            self.rls.update(acc, d);
        }
    }

    fn estimate(&self, t: f64) -> Estimate {
        Estimate {
            t,
            value: self.rls.theta * self.m2,
            std: self.m2 * self.rls.std(),
        }
    }

    fn ready(&self) -> bool {
        self.rls.updates > 50
    }

    fn nominal(&self) -> f64 {
        self.k_nominal
    }

    fn epoch(&mut self, k: f64, in_service: &[f64]) -> Candidate {
        let k = k.max(1e-3);
        let np = 15;
        let mut de = DifferentialEvolution::new(DeConfig {
            np,
            f: 0.5,
            cr: 0.9,
            lower: self.lower.clone(),
            upper: self.upper.clone(),
            seed: self
                .seed
                .wrapping_add(self.epoch_no.wrapping_mul(0x9E37_79B9)),
            diversity_stop: false,
            eta: 100,
            epsilon: 0.01,
        })
        .expect("valid DE settings");
        self.epoch_no += 1;
        de.seed_population(&[in_service.to_vec()]);
        let f = |g: &[f64]| self.cost(k, g);
        while de.evaluations() + np <= self.epoch_evaluations {
            let v = evaluate(de.ask(), None, &f, self.threads);
            de.tell(&v);
        }
        let (best, value) = de.best();
        Candidate {
            params: best.to_vec(),
            expected_cost: value,
            in_service_cost: self.cost(k, in_service),
            model_value: k,
        }
    }

    fn margin(&self) -> f64 {
        self.margin
    }

    fn epoch_evaluations(&self) -> usize {
        self.epoch_evaluations
    }
}
