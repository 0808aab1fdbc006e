//! A serial (or branched) arm as a plant: x = [q; qd], u = joint torques (forces for prismatic
//! joints), y = q. The forward dynamics come from `dynamics::Model`; torques are clipped to each
//! joint's effort limit, and joint position limits act as inelastic stops (after each integration
//! step a joint past its limit is put back on it and its velocity into the limit removed).
//!
//! A payload schedule (`payload_times`, `payload_values`) puts a point mass on the last body
//! from each time on, the load an arm picks up in operation: the plant switches between models
//! built once at validation, so the derivative stays allocation-free, while controllers keep
//! the file's model (what an indirect scheme has to catch up with).

use super::{Plant, PlantConfig, PlantContext};
use crate::check::{Check, ConfigError};
use crate::dynamics::spatial::Inertia;
use crate::dynamics::{Data, Model};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use std::cell::RefCell;

/// An arm as a plant (see the module docs): its model, the models carrying each
/// payload, the algorithms' buffers and the initial state.
pub struct Arm {
    /// The arm's model without payload, simulated until the first payload time.
    pub model: Model,
    /// The model from each payload time on (strictly increasing times), after `model`.
    loaded: Vec<(f64, Model)>,
    /// `derivative` takes &self (the integrator's contract), the algorithms need buffers: the
    /// plant is owned by one simulator thread, so a RefCell is enough and never contended.
    data: RefCell<Data>,
    tau: RefCell<Vec<f64>>,
    /// The initial state [q0; 0]: at rest at the initial joint positions.
    pub x0: Vec<f64>,
}

impl Arm {
    /// The arm at rest at joint positions `q0`.
    pub fn new(model: Model, q0: &[f64]) -> Self {
        Self::with_payloads(model, Vec::new(), q0)
    }

    /// The arm at rest at `q0`, becoming `loaded[i].1` from time `loaded[i].0` on.
    pub fn with_payloads(model: Model, loaded: Vec<(f64, Model)>, q0: &[f64]) -> Self {
        let n = model.dof();
        assert_eq!(q0.len(), n, "one initial position per joint");
        let mut x0 = vec![0.0; 2 * n];
        x0[..n].copy_from_slice(q0);
        Self {
            data: RefCell::new(model.data()),
            tau: RefCell::new(vec![0.0; n]),
            model,
            loaded,
            x0,
        }
    }
}

impl Plant for Arm {
    fn n_states(&self) -> usize {
        2 * self.model.dof()
    }
    fn n_inputs(&self) -> usize {
        self.model.dof()
    }
    fn n_outputs(&self) -> usize {
        self.model.dof()
    }
    fn n_joints(&self) -> usize {
        self.model.dof()
    }

    fn derivative(&self, t: f64, x: &[f64], u: &[f64], dx: &mut [f64]) {
        let n = self.model.dof();
        let (q, qd) = x.split_at(n);
        let model = super::step_at(&self.loaded, t).unwrap_or(&self.model);
        let mut tau = self.tau.borrow_mut();
        for (i, b) in model.bodies.iter().enumerate() {
            tau[i] = u[i].clamp(-b.limits.effort, b.limits.effort);
        }
        dx[..n].copy_from_slice(qd);
        let mut d = self.data.borrow_mut();
        // M(q) was checked positive definite when the robot loaded; should a configuration make
        // it singular the joints are frozen for this stage rather than poisoned with NaN.
        if model
            .forward_dynamics(&mut d, q, qd, &tau, &mut dx[n..])
            .is_err()
        {
            dx[n..].fill(0.0);
        }
    }

    fn output(&self, x: &[f64], y: &mut [f64]) {
        let n = self.model.dof();
        y[..n].copy_from_slice(&x[..n]);
    }

    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]) {
        let n = self.model.dof();
        q[..n].copy_from_slice(&x[..n]);
        qd[..n].copy_from_slice(&x[n..2 * n]);
    }

    fn initial_state(&self, x: &mut [f64]) {
        x.copy_from_slice(&self.x0);
    }

    fn constrain(&self, x: &mut [f64]) {
        let n = self.model.dof();
        for (i, b) in self.model.bodies.iter().enumerate() {
            if x[i] < b.limits.q_min {
                x[i] = b.limits.q_min;
                x[n + i] = x[n + i].max(0.0);
            } else if x[i] > b.limits.q_max {
                x[i] = b.limits.q_max;
                x[n + i] = x[n + i].min(0.0);
            }
        }
    }
}

// ---------------------------------------------------------------- configuration

/// The `[plant.arm]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    /// D-H TOML or URDF, relative to the scenario file.
    robot: PathBuf,
    initial_q: Option<Vec<f64>>,
    /// Payload schedule: from payload_times[i] (s) on, a point mass of payload_values[i] (kg)
    /// on the last body (replacing the previous payload, not adding to it).
    payload_times: Option<Vec<f64>>,
    payload_values: Option<Vec<f64>>,
    /// Where the payload sits in the last body's frame, m (default: that body's centre of mass).
    payload_com: Option<[f64; 3]>,
}

/// A validated arm.
#[derive(Debug, Clone, Serialize)]
pub struct ArmSpec {
    /// The robot file as resolved (relative to the scenario file).
    pub robot: PathBuf,
    /// The robot file's model, without payload (what the controllers are given).
    pub model: Model,
    /// The joint positions the arm starts at rest at, within the joint limits (rad; m for a
    /// prismatic joint); by default the reference's at t = 0.
    pub initial_q: Vec<f64>,
    /// (time s, payload kg) steps; no payload before the first.
    pub payload: Vec<(f64, f64)>,
    /// The payload's position in the last body's frame, m.
    pub payload_com: [f64; 3],
}

impl ArmSpec {
    /// The file's model with `mass` kg at `payload_com` on its last body.
    pub fn loaded_model(&self, mass: f64) -> Model {
        let mut m = self.model.clone();
        if let Some(b) = m.bodies.last_mut() {
            let c = glam::DVec3::from_array(self.payload_com);
            b.inertia = b.inertia + Inertia::from_com(mass, c, glam::DMat3::ZERO);
        }
        m
    }
}

/// Validate `[plant.arm]`: the robot file, a reference with one value per joint that keeps within
/// the joint limits, the initial positions and the payload schedule. Fails when the table is
/// missing or the robot file does not load.
pub fn validate(t: Option<Table>, check: &Check, cx: &PlantContext) -> Result<ArmSpec, ConfigError> {
    let Some(t) = t else {
        return check.fail("plant.arm", "missing table [plant.arm] with `robot`");
    };
    let (robot, model) = check.robot("plant.arm.robot", &t.robot)?;
    let n = model.dof();
    let reference = cx.reference;
    if reference.joints() != n {
        return check.fail(
            "reference",
            format!(
                "drives {} joint(s) but the robot `{}` has {n}; use a joint-space reference (quintic or sines) with {n} values per point",
                reference.joints(),
                model.name
            ),
        );
    }
    within_limits(check, &robot, &model, reference, cx.duration)?;
    let initial_q = match t.initial_q {
        Some(q) => {
            if q.len() != n {
                return check.fail(
                    "plant.arm.initial_q",
                    format!("needs {n} values (one per joint), got {}", q.len()),
                );
            }
            for (i, v) in q.iter().enumerate() {
                let b = &model.bodies[i].limits;
                check.range(&format!("plant.arm.initial_q[{i}]"), *v, b.q_min, b.q_max)?;
            }
            q
        }
        // Start where the trajectory starts.
        None => {
            let mut sp = crate::reference::Setpoint::default();
            reference.sample(0.0, &mut sp);
            sp.q[..n].to_vec()
        }
    };
    let payload = check.schedule(
        "plant.arm.payload_times",
        "plant.arm.payload_values",
        t.payload_times,
        t.payload_values,
        super::MAX_SCHEDULE,
    )?;
    let last = model.bodies.last().map(|b| b.inertia.com()).unwrap_or_default();
    let payload_com = match t.payload_com {
        Some(c) => {
            for (i, v) in c.iter().enumerate() {
                check.range(&format!("plant.arm.payload_com[{i}]"), *v, -10.0, 10.0)?;
            }
            c
        }
        None => last.to_array(),
    };
    check.unused(
        "plant.arm.payload_com",
        t.payload_com.is_some() && payload.is_empty(),
        "when there is no payload (payload_times/payload_values)",
    )?;
    Ok(ArmSpec {
        robot,
        model,
        initial_q,
        payload,
        payload_com,
    })
}

/// The reference must keep every joint within its limits (a waypoint beyond a joint stop
/// passed before, and the arm ran into the stop): sampled every millisecond over the run (its
/// first 600 s when longer or until stopped), the first excursion named with its time.
fn within_limits(
    check: &Check,
    robot: &std::path::Path,
    model: &crate::dynamics::Model,
    reference: &crate::reference::Reference,
    duration: f64,
) -> Result<(), ConfigError> {
    let n = model.dof();
    let end = duration.min(600.0);
    let samples = (end / 1e-3).ceil() as usize;
    let mut sp = crate::reference::Setpoint::default();
    for k in 0..=samples {
        let t = (k as f64 * 1e-3).min(end);
        reference.sample(t, &mut sp);
        for (j, b) in model.bodies.iter().enumerate().take(n) {
            let q = sp.q[j];
            let l = &b.limits;
            if q < l.q_min - 1e-9 || q > l.q_max + 1e-9 {
                return check.fail(
                    "reference",
                    format!(
                        "takes joint {} ({} of {}) to {q:.4} at t = {t:.3} s, outside its limits [{}, {}]",
                        j + 1,
                        b.joint,
                        robot.display(),
                        l.q_min,
                        l.q_max
                    ),
                );
            }
        }
    }
    Ok(())
}

impl PlantConfig for ArmSpec {
    fn build(&self) -> Box<dyn Plant> {
        let loaded = self
            .payload
            .iter()
            .map(|&(t, m)| (t, self.loaded_model(m)))
            .collect();
        Box::new(Arm::with_payloads(
            self.model.clone(),
            loaded,
            &self.initial_q,
        ))
    }
    /// The payload's mass.
    fn varying_parameter(&self, t: f64) -> Option<f64> {
        (!self.payload.is_empty()).then(|| super::step_at(&self.payload, t).map_or(0.0, |m| *m))
    }
    fn first_change(&self) -> Option<f64> {
        self.payload.first().map(|s| s.0)
    }
    fn rigid_body(&self) -> Option<&Model> {
        Some(&self.model)
    }
}
