//! The unstable discrete-time plant of the fuzzy-network paper's synthetic experiment
//! (Section 5.1, eq. 23):
//!   x_{k+1} = -a x_k + arsinh(u_k),   a = 1.1,
//! one map per control period (`Plant::map`: nothing is integrated). The output is the state.
//! `evoloop tune config/experiments/arsinh_tune.toml` evaluates controllers on the same map from x_0 = 0
//! (`fuzzy::arsinh::plant`); this kind puts it behind the processes, for the direct scheme.
//! A physical plant cannot grow without bound: |x| is held within `limit` (default 100, where
//! the tune experiment charges a diverged run), so a lost loop stays finite.

use super::{Plant, PlantConfig, PlantContext};
use crate::check::{Check, ConfigError};
use serde::{Deserialize, Serialize};

/// The arsinh plant as validated, which is also the plant simulated (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ArsinhSpec {
    /// The pole's magnitude (1.1 in the paper: unstable).
    pub a: f64,
    /// The bound on |x|: each step's state is held within [-limit, limit] (default 100).
    pub limit: f64,
    /// The initial state x_0, within the limit (default 0).
    pub initial: f64,
}

impl Plant for ArsinhSpec {
    fn n_states(&self) -> usize {
        1
    }
    fn n_inputs(&self) -> usize {
        1
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn n_joints(&self) -> usize {
        1
    }
    /// Never integrated (`map` advances it); zero so that nothing moves if it were.
    fn derivative(&self, _t: f64, _x: &[f64], _u: &[f64], dx: &mut [f64]) {
        dx[0] = 0.0;
    }
    fn output(&self, x: &[f64], y: &mut [f64]) {
        y[0] = x[0];
    }
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        q[0] = x[0];
        qd[0] = 0.0;
    }
    fn initial_state(&self, x: &mut [f64]) {
        x[0] = self.initial;
    }
    fn map(&self, _t: f64, x: &mut [f64], u: &[f64], _dt: f64) -> bool {
        let next = -self.a * x[0] + u[0].asinh();
        // NaN (a NaN command) is held at the limit too: the state stays a number.
        x[0] = if next.is_nan() {
            self.limit
        } else {
            next.clamp(-self.limit, self.limit)
        };
        true
    }
}

/// The `[plant.arsinh]` keys; every one has a default.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    a: Option<f64>,
    limit: Option<f64>,
    initial: Option<f64>,
}

/// Validate `[plant.arsinh]` (every key has a default, the table may be absent) for a scalar
/// reference.
pub fn validate(t: Option<Table>, check: &Check, cx: &PlantContext) -> Result<ArsinhSpec, ConfigError> {
    if cx.reference.joints() != 1 {
        return check.fail("reference", "the arsinh plant follows a scalar reference");
    }
    let t = t.unwrap_or_default();
    let limit = check.range("plant.arsinh.limit", t.limit.unwrap_or(100.0), 1e-6, 1e12)?;
    Ok(ArsinhSpec {
        a: check.range("plant.arsinh.a", t.a.unwrap_or(1.1), -1e3, 1e3)?,
        initial: check.range("plant.arsinh.initial", t.initial.unwrap_or(0.0), -limit, limit)?,
        limit,
    })
}

impl PlantConfig for ArsinhSpec {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
    /// Its map is one control period: realtime's split periods would apply it several times.
    fn realtime_refusal(&self) -> Option<String> {
        Some(
            "the arsinh plant is a discrete map, one step a control period, and realtime splits \
             a period where a command arrives: run it in lockstep"
                .into(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::PlantSim;

    #[test]
    fn the_simulated_plant_is_the_tune_experiments_map() {
        let p = ArsinhSpec {
            a: 1.1,
            limit: 100.0,
            initial: 0.0,
        };
        // One period is one map, whatever the integration step.
        let mut sim = PlantSim::new(Box::new(p), 0.001, 0.0, 1);
        let mut x = 0.0;
        for u in [0.3, -2.0, 4.0, 0.0, -0.7] {
            sim.advance(&[u], 0.01);
            x = crate::fuzzy::arsinh::plant(x, u);
            assert_eq!(sim.x[0], x);
        }
        // Exact tracking with eq. 24, u = sinh(w + 1.1 x).
        let w = 0.8;
        sim.advance(&[(w + 1.1 * sim.x[0]).sinh()], 0.01);
        assert!((sim.x[0] - w).abs() < 1e-12);
    }

    #[test]
    fn a_lost_loop_is_held_at_the_limit() {
        let p = ArsinhSpec {
            a: 1.1,
            limit: 100.0,
            initial: 90.0,
        };
        let mut sim = PlantSim::new(Box::new(p), 0.01, 0.0, 1);
        for _ in 0..10 {
            sim.advance(&[0.0], 0.01);
        }
        assert!(sim.x[0].abs() <= 100.0 && sim.x[0].is_finite());
        sim.advance(&[f64::NAN], 0.01);
        assert_eq!(sim.x[0], 100.0);
    }
}
