//! Magnetic levitation (fuzzy-network paper, Section 5.2): an iron ball of 160 g held below an
//! electromagnet. Physics (SI inside, mm and mA at the interface):
//!   z'' = g - F(i, z) / m,   F(i, z) = k_F i^2 / (z + d)^2,   i' = (i_cmd - i) / tau,
//! z the air gap (m, growing downwards), d the magnet's effective pole offset, i the coil current
//! from a current amplifier with lag tau whose command i_cmd is the controller's output u in mA,
//! quantised by a 12-bit DAC over [0, i_max] and clipped to it. The measured output is the ball's
//! height above the operating point, y = (z_op - z) in mm, from an optical sensor with seeded
//! noise, quantised by a 12-bit ADC over +-`sensor_range_mm`. The ball stops at the magnet
//! (z = 0) and on a catcher `catcher_mm` below the operating point.
//!
//! Open loop the equilibrium is unstable: dF/dz = -2F/(z + d), so a ball displaced upwards is
//! pulled harder (pole at +sqrt(2 g / (z_op + d)) = 49.5 rad/s with the defaults).
//!
//! Numbers. The paper gives the mass (160 g), the 1 ms sampling and the 12-bit converters; the
//! rest are representative laboratory values (chosen, not measured): operating gap 6 mm, pole
//! offset 2 mm, holding current 1 A at the operating point (which fixes k_F = m g (z_op + d)^2),
//! a 0..2 A amplifier with a 0.5 ms current lag, a +-5 mm sensor with 2 um noise. The mass may
//! follow a schedule (a load added in operation).

use super::{Plant, PlantConfig, PlantContext, ScalarInput};
use crate::check::{Check, ConfigError};
use serde::{Deserialize, Serialize};

/// Standard gravity, m/s^2.
pub const G: f64 = 9.80665;

/// The maglev's parameters (see the module docs), validated from `[plant.maglev]`; the defaults are
/// the documented laboratory values.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaglevParams {
    /// Ball mass, kg.
    pub mass: f64,
    /// Operating air gap, m.
    pub gap_op: f64,
    /// Effective pole offset d, m.
    pub pole_offset: f64,
    /// Coil current holding the nominal mass at the operating gap, A (fixes k_F).
    pub hold_current: f64,
    /// Amplifier limit, A (commands are clipped to [0, i_max]).
    pub i_max: f64,
    /// Current-loop lag, s.
    pub tau: f64,
    /// Sensor range, +- mm around the operating point.
    pub sensor_range_mm: f64,
    /// Converter resolution, bits (ADC and DAC).
    pub bits: u32,
    /// The catcher below the operating point, mm.
    pub catcher_mm: f64,
    /// Mass schedule: (time s, mass kg) steps; the mass is `mass` before the first.
    pub mass_steps: Vec<(f64, f64)>,
}

impl Default for MaglevParams {
    fn default() -> Self {
        Self {
            mass: 0.160,
            gap_op: 0.006,
            pole_offset: 0.002,
            hold_current: 1.0,
            i_max: 2.0,
            tau: 0.0005,
            sensor_range_mm: 5.0,
            bits: 12,
            catcher_mm: 5.0,
            mass_steps: Vec::new(),
        }
    }
}

impl MaglevParams {
    /// Force constant k_F (N m^2 / A^2) from the holding condition of the nominal mass.
    pub fn k_force(&self) -> f64 {
        self.mass * G * (self.gap_op + self.pole_offset).powi(2) / self.hold_current.powi(2)
    }

    /// The mass at time t.
    pub fn mass_at(&self, t: f64) -> f64 {
        super::step_at(&self.mass_steps, t).map_or(self.mass, |m| *m)
    }

    /// Holding current for mass m at the operating gap, mA.
    pub fn hold_current_ma(&self, m: f64) -> f64 {
        1000.0 * self.hold_current * (m / self.mass).sqrt()
    }

    /// The magnet's pull k_F i^2 / (z + d)^2 (N) at gap z (m) and coil current i (A); with
    /// k_f = 1 it is the regressor an estimator of m / k_F uses. One law for plant and estimator.
    pub fn force(&self, k_f: f64, z: f64, i: f64) -> f64 {
        k_f * i * i / (z + self.pole_offset).powi(2)
    }

    /// The fraction of a step in the current command the amplifier has followed after dt under
    /// its first-order lag i' = (i_cmd - i) / tau (the exact solution for a held command).
    pub fn lag_fraction(&self, dt: f64) -> f64 {
        1.0 - (-dt / self.tau).exp()
    }

    /// The open-loop unstable pole at the operating point, rad/s.
    pub fn unstable_pole(&self) -> f64 {
        (2.0 * G / (self.gap_op + self.pole_offset)).sqrt()
    }
}

/// The maglev as simulated: its parameters and the force constant and converter steps derived from
/// them once.
pub struct Maglev {
    /// The parameters it was built from.
    pub p: MaglevParams,
    k_force: f64,
    dac_step_ma: f64,
    adc_step_mm: f64,
}

impl Maglev {
    /// The plant with parameters `p`, the ball starting at rest at the operating gap with the
    /// holding current flowing.
    pub fn new(p: MaglevParams) -> Self {
        let levels = ((1u64 << p.bits) - 1) as f64;
        Self {
            k_force: p.k_force(),
            dac_step_ma: 1000.0 * p.i_max / levels,
            adc_step_mm: 2.0 * p.sensor_range_mm / levels,
            p,
        }
    }

    /// The current command the amplifier applies for controller output `u_ma`, A.
    pub fn applied_current(&self, u_ma: f64) -> f64 {
        let u = u_ma.clamp(0.0, 1000.0 * self.p.i_max);
        (u / self.dac_step_ma).round() * self.dac_step_ma / 1000.0
    }
}

impl Plant for Maglev {
    fn n_states(&self) -> usize {
        3
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

    /// x = [gap z (m), gap rate (m/s), coil current (A)].
    fn derivative(&self, t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let m = self.p.mass_at(t);
        let force = self.p.force(self.k_force, x[0], x[2]);
        dx[0] = x[1];
        dx[1] = G - force / m;
        dx[2] = (self.applied_current(u[0]) - x[2]) / self.p.tau;
    }

    fn output(&self, x: &[f64], y: &mut [f64]) {
        y[0] = (self.p.gap_op - x[0]) * 1000.0;
    }

    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        q[0] = (self.p.gap_op - x[0]) * 1000.0;
        qd[0] = -x[1] * 1000.0;
    }

    fn initial_state(&self, x: &mut [f64]) {
        x[0] = self.p.gap_op;
        x[1] = 0.0;
        x[2] = self.p.hold_current_ma(self.p.mass_at(0.0)) / 1000.0;
    }

    fn constrain(&self, x: &mut [f64]) {
        let floor = self.p.gap_op + self.p.catcher_mm / 1000.0;
        if x[0] <= 0.0 {
            x[0] = 0.0;
            x[1] = x[1].max(0.0);
        } else if x[0] >= floor {
            x[0] = floor;
            x[1] = x[1].min(0.0);
        }
    }

    fn measure(&self, y: &mut [f64]) {
        let r = self.p.sensor_range_mm;
        y[0] = ((y[0].clamp(-r, r) + r) / self.adc_step_mm).round() * self.adc_step_mm - r;
    }
}

// ---------------------------------------------------------------- configuration

/// The `[plant.maglev]` keys (the rest of `MaglevParams` keeps its documented defaults).
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    mass: Option<f64>,
    hold_current: Option<f64>,
    i_max: Option<f64>,
    tau: Option<f64>,
    sensor_range_mm: Option<f64>,
    mass_times: Option<Vec<f64>>,
    mass_values: Option<Vec<f64>>,
}

/// Validate `[plant.maglev]` (every key has a default, the table may be absent) for a scalar height
/// reference: the values in their ranges, the mass schedule, and an integration step no longer than
/// the coil lag tau.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &PlantContext,
) -> Result<MaglevParams, ConfigError> {
    if cx.reference.joints() != 1 {
        return check.fail(
            "reference",
            "the maglev follows a scalar height reference (mm)",
        );
    }
    let t = t.unwrap_or_default();
    let d = MaglevParams::default();
    let mg = MaglevParams {
        mass: check.range("plant.maglev.mass", t.mass.unwrap_or(d.mass), 0.01, 2.0)?,
        hold_current: check.range(
            "plant.maglev.hold_current",
            t.hold_current.unwrap_or(d.hold_current),
            0.01,
            100.0,
        )?,
        i_max: check.range("plant.maglev.i_max", t.i_max.unwrap_or(d.i_max), 0.01, 100.0)?,
        tau: check.range("plant.maglev.tau", t.tau.unwrap_or(d.tau), 1e-6, 1.0)?,
        sensor_range_mm: check.range(
            "plant.maglev.sensor_range_mm",
            t.sensor_range_mm.unwrap_or(d.sensor_range_mm),
            0.1,
            50.0,
        )?,
        mass_steps: check.schedule(
            "plant.maglev.mass_times",
            "plant.maglev.mass_values",
            t.mass_times,
            t.mass_values,
            super::MAX_SCHEDULE,
        )?,
        ..d
    };
    if cx.step > mg.tau {
        return check.fail(
            "plant.step",
            format!(
                "{} s is longer than the coil lag tau = {} s; the RK4 step must resolve it",
                cx.step, mg.tau
            ),
        );
    }
    Ok(mg)
}

impl PlantConfig for MaglevParams {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(Maglev::new(self.clone()))
    }
    /// The amplifier's 0..i_max (in mA) and the current holding the ball at t = 0.
    fn scalar_input(&self) -> Option<ScalarInput> {
        Some(ScalarInput {
            range: (0.0, 1000.0 * self.i_max),
            hold: self.hold_current_ma(self.mass_at(0.0)),
        })
    }
    /// The ball's mass.
    fn varying_parameter(&self, t: f64) -> Option<f64> {
        Some(self.mass_at(t))
    }
    fn first_change(&self) -> Option<f64> {
        self.mass_steps.first().map(|s| s.0)
    }
}
