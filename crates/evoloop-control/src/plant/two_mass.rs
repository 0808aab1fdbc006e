//! The two-mass-spring benchmark of the two-mass paper (papers/two-mass-robust-de-stability-radius.md):
//! two bodies on a frictionless line joined by a spring k, a force u on body 1 (the actuated
//! body), and the position of body 2 measured (the non-collocated benchmark).
//!
//! State order follows the reading under which the paper's Table 9 gains are consistent:
//! the measured body first, x = [x_far, x_act, v_far, v_act] with x_far = body 2 and
//! x_act = body 1, so that
//!   `A = [[0,0,1,0],[0,0,0,1],[-k/m2,k/m2,0,0],[k/m1,-k/m1,0,0]]`, `B = [0,0,0,1/m1]^T`.
//! The measurement is `C = [1,0,0,0]` (`Sensor::Far`, the paper's plant) or `C = [0,1,0,0]`
//! (`Sensor::Actuated`, the collocated variant that reproduces the LQR rows of Table 9).
//! Joint order in messages is physical: q = [x1, x2] (body 1, body 2).

use super::{LinearModel, Plant, PlantConfig, PlantContext, ScalarInput};
use crate::check::{Check, ConfigError};
use serde::{Deserialize, Serialize};

/// Which body's position the plant measures (`plant.two_mass.sensor`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Sensor {
    /// Position of body 2, across the spring from the force (the paper's benchmark).
    #[default]
    Far,
    /// Position of body 1, where the force acts (collocated variant).
    Actuated,
}

/// The two-mass-spring plant as simulated (see the module docs): its masses, spring, sensor, start,
/// spring schedule and encoder.
#[derive(Debug, Clone, Copy)]
pub struct TwoMass {
    /// Mass of body 1, the actuated one.
    pub m1: f64,
    /// Mass of body 2, across the spring.
    pub m2: f64,
    /// The spring constant, in force while `k_schedule` is empty.
    pub k: f64,
    /// Which body's position is measured.
    pub sensor: Sensor,
    /// Initial positions of body 1 and body 2.
    pub x0: [f64; 2],
    /// Optional spring-constant schedule: (time, k) points, linearly interpolated, held before
    /// the first and after the last; `k` applies when it is empty. Fixed size so the plant stays
    /// `Copy` and its derivative allocation-free.
    pub k_schedule: [(f64, f64); MAX_SCHEDULE],
    /// How many entries of `k_schedule` are in use (0: constant `k`).
    pub k_points: usize,
    /// Position encoder resolution (length per count); the measurement is rounded to it after
    /// the sensor noise. 0: an ideal sensor.
    pub resolution: f64,
}

pub use super::MAX_SCHEDULE;

impl TwoMass {
    /// The plant with masses `m1`, `m2`, spring `k` and `sensor`: at rest at the origin, no spring
    /// schedule, an ideal encoder.
    pub fn new(m1: f64, m2: f64, k: f64, sensor: Sensor) -> Self {
        Self {
            m1,
            m2,
            k,
            sensor,
            x0: [0.0; 2],
            k_schedule: [(0.0, 0.0); MAX_SCHEDULE],
            k_points: 0,
            resolution: 0.0,
        }
    }

    /// Make the spring constant follow `points` (time, k) over the run (at most MAX_SCHEDULE,
    /// times increasing).
    pub fn with_spring_schedule(mut self, points: &[(f64, f64)]) -> Self {
        let n = points.len().min(MAX_SCHEDULE);
        self.k_schedule[..n].copy_from_slice(&points[..n]);
        self.k_points = n;
        self
    }

    /// The spring constant at time t.
    pub fn spring_at(&self, t: f64) -> f64 {
        let pts = &self.k_schedule[..self.k_points];
        match pts {
            [] => self.k,
            [first, ..] if t <= first.0 => first.1,
            [.., last] if t >= last.0 => last.1,
            _ => {
                let i = pts.iter().position(|p| p.0 > t).unwrap_or(pts.len() - 1);
                let (a, b) = (pts[i - 1], pts[i]);
                a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
            }
        }
    }

    /// The continuous-time (A, B, C) in the documented state order.
    pub fn matrices(&self) -> ([[f64; 4]; 4], [f64; 4], [f64; 4]) {
        let (k, m1, m2) = (self.k, self.m1, self.m2);
        let a = [
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
            [-k / m2, k / m2, 0.0, 0.0],
            [k / m1, -k / m1, 0.0, 0.0],
        ];
        let b = [0.0, 0.0, 0.0, 1.0 / m1];
        let c = match self.sensor {
            Sensor::Far => [1.0, 0.0, 0.0, 0.0],
            Sensor::Actuated => [0.0, 1.0, 0.0, 0.0],
        };
        (a, b, c)
    }

    /// The (A, B, C) model a state-feedback controller checks its gains against.
    pub fn linear_model(&self) -> LinearModel {
        let (a, b, c) = self.matrices();
        LinearModel::continuous(a.as_flattened(), &b, &c)
    }

    /// Total mechanical energy (kinetic + spring); conserved when u = 0.
    pub fn energy(&self, x: &[f64]) -> f64 {
        let d = x[0] - x[1];
        0.5 * self.m2 * x[2] * x[2] + 0.5 * self.m1 * x[3] * x[3] + 0.5 * self.k * d * d
    }
}

impl Plant for TwoMass {
    fn n_states(&self) -> usize {
        4
    }
    fn n_inputs(&self) -> usize {
        1
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn n_joints(&self) -> usize {
        2
    }
    fn derivative(&self, t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let spring = self.spring_at(t) * (x[0] - x[1]); // force pulling body 2 back towards body 1
        dx[0] = x[2];
        dx[1] = x[3];
        dx[2] = -spring / self.m2;
        dx[3] = (spring + u[0]) / self.m1;
    }
    fn output(&self, x: &[f64], y: &mut [f64]) {
        y[0] = match self.sensor {
            Sensor::Far => x[0],
            Sensor::Actuated => x[1],
        };
    }
    fn measure(&self, y: &mut [f64]) {
        if self.resolution > 0.0 {
            y[0] = (y[0] / self.resolution).round() * self.resolution;
        }
    }
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        q[0] = x[1];
        q[1] = x[0];
        qd[0] = x[3];
        qd[1] = x[2];
    }
    fn initial_state(&self, x: &mut [f64]) {
        x.copy_from_slice(&[self.x0[1], self.x0[0], 0.0, 0.0]);
    }
}

// ---------------------------------------------------------------- configuration

/// The `[plant.two_mass]` keys.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    m1: Option<f64>,
    m2: Option<f64>,
    spring: Option<f64>,
    sensor: Option<Sensor>,
    initial_positions: Option<[f64; 2]>,
    spring_times: Option<Vec<f64>>,
    spring_values: Option<Vec<f64>>,
    resolution: Option<f64>,
}

/// A validated two-mass plant.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TwoMassSpec {
    /// Mass of body 1, the actuated one (default 1).
    pub m1: f64,
    /// Mass of body 2, across the spring (default 1).
    pub m2: f64,
    /// The nominal spring constant (the one gains are checked against).
    pub spring: f64,
    /// Which body's position is measured (default `Far`, the paper's benchmark).
    pub sensor: Sensor,
    /// Initial positions of body 1 and body 2 (default 0).
    pub initial_positions: [f64; 2],
    /// Spring-constant schedule (time, k), linearly interpolated; empty = constant `spring`.
    pub spring_schedule: Vec<(f64, f64)>,
    /// Position encoder resolution (0: ideal).
    pub resolution: f64,
}

/// Validate `[plant.two_mass]` (every key has a default, the table may be absent) for a scalar
/// reference: masses and spring within [1e-6, 1e6], the spring schedule, finite initial positions,
/// a resolution within [0, 1].
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &PlantContext,
) -> Result<TwoMassSpec, ConfigError> {
    if cx.reference.joints() != 1 {
        return check.fail(
            "reference",
            "the two-mass plant follows a scalar reference (step, square or steps)",
        );
    }
    let t = t.unwrap_or_default();
    let spring_schedule = check.schedule(
        "plant.two_mass.spring_times",
        "plant.two_mass.spring_values",
        t.spring_times,
        t.spring_values,
        MAX_SCHEDULE,
    )?;
    let x0 = t.initial_positions.unwrap_or([0.0; 2]);
    for (i, v) in x0.iter().enumerate() {
        check.finite(&format!("plant.two_mass.initial_positions[{i}]"), *v)?;
    }
    Ok(TwoMassSpec {
        m1: check.range("plant.two_mass.m1", t.m1.unwrap_or(1.0), 1e-6, 1e6)?,
        m2: check.range("plant.two_mass.m2", t.m2.unwrap_or(1.0), 1e-6, 1e6)?,
        spring: check.range("plant.two_mass.spring", t.spring.unwrap_or(1.0), 1e-6, 1e6)?,
        sensor: t.sensor.unwrap_or_default(),
        resolution: check.range(
            "plant.two_mass.resolution",
            t.resolution.unwrap_or(0.0),
            0.0,
            1.0,
        )?,
        initial_positions: x0,
        spring_schedule,
    })
}

impl TwoMassSpec {
    /// The plant at its nominal spring constant, without schedule, start or encoder.
    pub fn nominal(&self) -> TwoMass {
        TwoMass::new(self.m1, self.m2, self.spring, self.sensor)
    }

    /// The plant as configured.
    pub fn plant(&self) -> TwoMass {
        let mut p = self.nominal();
        p.x0 = self.initial_positions;
        p.resolution = self.resolution;
        p.with_spring_schedule(&self.spring_schedule)
    }
}

impl PlantConfig for TwoMassSpec {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(self.plant())
    }
    fn linear_model(&self) -> Option<LinearModel> {
        Some(self.nominal().linear_model())
    }
    /// At spring constant `p`.
    fn linear_model_at(&self, p: f64) -> Option<LinearModel> {
        Some(TwoMass::new(self.m1, self.m2, p, self.sensor).linear_model())
    }
    fn scalar_input(&self) -> Option<ScalarInput> {
        Some(ScalarInput {
            range: (f64::NEG_INFINITY, f64::INFINITY),
            hold: 0.0,
        })
    }
    /// The spring constant.
    fn varying_parameter(&self, t: f64) -> Option<f64> {
        Some(self.nominal().with_spring_schedule(&self.spring_schedule).spring_at(t))
    }
    fn first_change(&self) -> Option<f64> {
        self.spring_schedule.first().map(|s| s.0)
    }
    fn quantisation(&self) -> f64 {
        self.resolution
    }
}
