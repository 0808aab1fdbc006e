//! A heated block: a heating element of capacity C_e (J/K) driven by a power P (W, the input,
//! clipped to [0, p_max]) conducts through R_eb (K/W) into a block of capacity C_b, which loses
//! heat to the ambient T_a through R_ba; a sensor reads the block's temperature (°C):
//!   C_e T_e' = P - (T_e - T_b) / R_eb,   C_b T_b' = (T_e - T_b) / R_eb - (T_b - T_a) / R_ba.
//! The heater only heats, so a PID driving it up a large step winds up: a small plant to try
//! anti-windup schemes on. It is also the book's worked example of adding a plant kind: this
//! file plus the line `heater => Heater(HeaterSpec),` in `plant/mod.rs`.

use super::{Plant, PlantConfig, PlantContext, ScalarInput};
use crate::check::{Check, ConfigError};
use serde::{Deserialize, Serialize};

/// The validated `[plant.heater]`, also the simulated model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeaterSpec {
    /// The element's heat capacity C_e, J/K (default 5).
    pub c_element: f64,
    /// The block's heat capacity C_b, J/K (default 50).
    pub c_block: f64,
    /// The thermal resistance R_eb from element to block, K/W (default 0.5).
    pub r_element_block: f64,
    /// The thermal resistance R_ba from block to ambient, K/W (default 2).
    pub r_block_ambient: f64,
    /// The ambient temperature T_a, °C (default 20).
    pub ambient: f64,
    /// The most power the element takes, W (default 100): the input is clipped to [0, p_max].
    pub p_max: f64,
    /// Both bodies start here, °C.
    pub initial: f64,
}

impl HeaterSpec {
    /// Steady-state block temperature under a constant power p (within [0, p_max]).
    pub fn steady_state(&self, p: f64) -> f64 {
        self.ambient + p.clamp(0.0, self.p_max) * self.r_block_ambient
    }
}

/// State x = [T_e, T_b]; the block is the one "joint" (q = T_b, qd = T_b').
impl Plant for HeaterSpec {
    fn n_states(&self) -> usize {
        2
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
    fn derivative(&self, _t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let into_block = (x[0] - x[1]) / self.r_element_block;
        let power = u[0].clamp(0.0, self.p_max);
        dx[0] = (power - into_block) / self.c_element;
        dx[1] = (into_block - (x[1] - self.ambient) / self.r_block_ambient) / self.c_block;
    }
    fn output(&self, x: &[f64], y: &mut [f64]) {
        y[0] = x[1];
    }
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        let mut dx = [0.0; 2];
        // The block's rate does not depend on the input.
        self.derivative(0.0, x, &[0.0], &mut dx);
        q[0] = x[1];
        qd[0] = dx[1];
    }
    fn initial_state(&self, x: &mut [f64]) {
        x.fill(self.initial);
    }
}

// ---------------------------------------------------------------- configuration

/// The `[plant.heater]` keys; every one has a default.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    c_element: Option<f64>,
    c_block: Option<f64>,
    r_element_block: Option<f64>,
    r_block_ambient: Option<f64>,
    ambient: Option<f64>,
    p_max: Option<f64>,
    initial: Option<f64>,
}

/// Validate `[plant.heater]` (every key has a default, the table may be absent) for a scalar
/// temperature reference: capacities, resistances and `p_max` > 0, the temperatures in range.
pub fn validate(t: Option<Table>, check: &Check, cx: &PlantContext) -> Result<HeaterSpec, ConfigError> {
    if cx.reference.joints() != 1 {
        return check.fail("reference", "the heater follows a scalar temperature reference (°C)");
    }
    let t = t.unwrap_or_default();
    let positive = |key: &str, v: Option<f64>, default: f64| {
        check.positive(&format!("plant.heater.{key}"), v.unwrap_or(default))
    };
    let ambient = check.range("plant.heater.ambient", t.ambient.unwrap_or(20.0), -50.0, 100.0)?;
    Ok(HeaterSpec {
        c_element: positive("c_element", t.c_element, 5.0)?,
        c_block: positive("c_block", t.c_block, 50.0)?,
        r_element_block: positive("r_element_block", t.r_element_block, 0.5)?,
        r_block_ambient: positive("r_block_ambient", t.r_block_ambient, 2.0)?,
        p_max: positive("p_max", t.p_max, 100.0)?,
        initial: check.range("plant.heater.initial", t.initial.unwrap_or(ambient), -50.0, 500.0)?,
        ambient,
    })
}

impl PlantConfig for HeaterSpec {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
    /// 0..p_max W; the power that holds the block at its initial temperature.
    fn scalar_input(&self) -> Option<ScalarInput> {
        Some(ScalarInput {
            range: (0.0, self.p_max),
            hold: ((self.initial - self.ambient) / self.r_block_ambient).clamp(0.0, self.p_max),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::PlantState;
    use crate::plant::PlantSim;

    fn spec() -> HeaterSpec {
        let cx = PlantContext {
            step: 0.01,
            period: 0.01,
            reference: &crate::reference::Reference::Step {
                amplitude: 60.0,
                start: 0.0,
            },
            duration: 10.0,
        };
        validate(None, &Check::new("heater.toml".as_ref()), &cx).unwrap()
    }

    #[test]
    fn a_constant_power_settles_at_the_analytic_steady_state() {
        let h = spec();
        let mut sim = PlantSim::new(Box::new(h.clone()), 0.01, 0.0, 1);
        // Slowest time constant ~ (C_e + C_b) R_ba = 110 s: 20 of them.
        sim.advance(&[30.0], 2200.0);
        assert!((sim.x[1] - h.steady_state(30.0)).abs() < 1e-6, "{:?}", sim.x);
        // The element runs hotter by P R_eb.
        assert!((sim.x[0] - sim.x[1] - 30.0 * h.r_element_block).abs() < 1e-6);
    }

    /// `plant.sensor_delay`: each sample's measurement is, bit for bit, the undelayed sensor's
    /// of `delay` samples before (the noise drawn as it was), the first reading before that;
    /// the state and the truth fields are the present's.
    #[test]
    fn a_delayed_sensor_gives_the_reading_of_delay_samples_before() {
        let delay = 4;
        let sims = |d: usize| PlantSim::new(Box::new(spec()), 0.01, 0.2, 9).delaying(d);
        let (mut plain, mut late) = (sims(0), sims(delay));
        let (mut a, mut b) = (PlantState::default(), PlantState::default());
        let mut readings = Vec::new();
        for k in 0..50u64 {
            let u = [10.0 + 5.0 * (k as f64 * 0.3).sin()];
            plain.sample(k, 0, &u, &mut a);
            late.sample(k, 0, &u, &mut b);
            readings.push(a.y[0]);
            let want = readings[(k as usize).saturating_sub(delay)];
            assert_eq!(b.y[0].to_bits(), want.to_bits(), "sample {k}");
            assert_eq!(a.x_true, b.x_true);
            plain.advance(&u, 0.01);
            late.advance(&u, 0.01);
        }
        assert_ne!(readings[10], readings[10 - delay]);
    }

    #[test]
    fn the_input_saturates_at_zero_and_p_max() {
        let h = spec();
        let mut dx = [0.0; 2];
        let (mut lo, mut hi) = ([0.0; 2], [0.0; 2]);
        h.derivative(0.0, &[40.0, 30.0], &[-50.0], &mut dx);
        h.derivative(0.0, &[40.0, 30.0], &[0.0], &mut lo);
        assert_eq!(dx, lo);
        h.derivative(0.0, &[40.0, 30.0], &[1e6], &mut dx);
        h.derivative(0.0, &[40.0, 30.0], &[h.p_max], &mut hi);
        assert_eq!(dx, hi);
    }
}
