//! The joint P-D servo of the RKGNN paper (Section 1: "the servo controller can be represented by
//! a Proportional Derivative (P-D) controller"): per joint
//!   tau_i = Kp_i (q_d,i - q_i) + Kd_i (qd_d,i - qd_i),
//! with no model and no gravity compensation, clipped to the joint's torque limit. It is the
//! "actual controller" whose gains a later identification does not know. With `gravity_model`
//! (a robot file: the CAD model a user has) it adds that model's G(q) at the measured positions,
//! the P-D servo with gravity compensation of Takegaki and Arimoto (1981), the usual industrial
//! baseline: tau_i = Kp_i e_i + Kd_i e_dot_i + G_i,model(q).
//! Parameters: [Kp_1..Kp_n, Kd_1..Kd_n]. Positions are the measured outputs y (with the plant's
//! sensor noise); velocities by default the measured positions differenced and low-passed as a
//! drive makes them (`velocity = "filtered"`, `estimator::VelocityFilter`), or the simulator's
//! true joint velocities `qd_true` (`velocity = "true"`, the paper's simulation). The
//! programmatic constructor starts on the true velocities (`with_velocity` sets another).

use super::estimator::{Velocities, VelocitySource};
use super::{
    driven_arm, joint_gains, model_file, velocity_source, Controller, ControllerConfig,
    ControllerContext, VelocityKey,
};
use crate::dynamics::{Data, Model};
use crate::check::{Check, ConfigError, Tunable};
use crate::msg::{ParamKind, PlantState};
use crate::reference::Setpoint;
use serde::{Deserialize, Serialize};

/// The joint P-D servo of the module docs, with gravity compensation when built `with_gravity`: the
/// gains [Kp; Kd], each joint's torque limit and the velocity source.
pub struct PdServo {
    gains: Vec<f64>,
    limits: Vec<f64>,
    velocity: Velocities,
    gravity: Option<Gravity>,
}

/// A model's gravity torque with its buffers (computed in place every cycle).
struct Gravity {
    model: Model,
    data: Data,
    g: Vec<f64>,
}

impl PdServo {
    /// `gains` = [Kp; Kd] (2n values), `limits` the torque limit per joint (may be infinite).
    pub fn new(gains: &[f64], limits: &[f64]) -> Self {
        assert_eq!(
            gains.len(),
            2 * limits.len(),
            "P-D servo gains are [Kp; Kd]"
        );
        Self {
            gains: gains.to_vec(),
            limits: limits.to_vec(),
            velocity: Velocities::True,
            gravity: None,
        }
    }

    /// Add `model`'s gravity torque G(q) at the measured positions.
    pub fn with_gravity(mut self, model: Model) -> Self {
        self.gravity = Some(Gravity {
            data: model.data(),
            g: vec![0.0; model.dof()],
            model,
        });
        self
    }

    /// Read velocities from `source` (the true ones until this is called), every `period` s.
    pub fn with_velocity(mut self, source: VelocitySource, period: f64) -> Self {
        self.velocity = Velocities::new(source, self.limits.len(), period, None);
        self
    }
}

impl Controller for PdServo {
    fn kind(&self) -> ParamKind {
        ParamKind::PdServo
    }
    fn n_params(&self) -> usize {
        self.gains.len()
    }
    fn params(&self) -> &[f64] {
        &self.gains
    }
    fn n_outputs(&self) -> usize {
        self.limits.len()
    }

    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let n = self.limits.len();
        let (kp, kd) = self.gains.split_at(n);
        let qd = self.velocity.read(state, n, None);
        if let Some(c) = &mut self.gravity {
            c.model.gravity_torque(&mut c.data, &state.y[..n], &mut c.g);
        }
        for i in 0..n {
            let g = self.gravity.as_ref().map_or(0.0, |c| c.g[i]);
            let tau = kp[i] * (sp.q[i] - state.y[i]) + kd[i] * (sp.qd[i] - qd[i]) + g;
            u[i] = tau.clamp(-self.limits[i], self.limits[i]);
        }
    }

    fn swap_params(&mut self, new: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.gains.copy_from_slice(new);
    }
}

// ---------------------------------------------------------------- configuration

/// The `[controller.pd_servo]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    kp: Vec<f64>,
    kd: Vec<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
    velocity: Option<VelocityKey>,
    velocity_cutoff_hz: Option<f64>,
    /// A robot file whose G(q) the servo adds (relative to the scenario): gravity compensation.
    gravity_model: Option<std::path::PathBuf>,
}

/// Validated P-D gains [Kp; Kd] with their bounds, and the arm's torque limits.
#[derive(Debug, Clone, Serialize)]
pub struct PdServoSpec {
    /// The gains [Kp_1..Kp_n, Kd_1..Kd_n] (each >= 0) and their bounds.
    #[serde(flatten)]
    pub tunable: Tunable,
    /// Torque limit per joint (from the robot description; infinite where none).
    pub torque_limits: Vec<f64>,
    /// Where the servo's joint velocities come from (`velocity`; differenced and low-passed by
    /// default).
    pub velocity: VelocitySource,
    /// The model whose gravity torque is added, if any (`gravity_model`).
    pub gravity_model: Option<Model>,
}

/// Validate `[controller.pd_servo]` for the arm the plant drives: `kp` and `kd` (one per joint,
/// at least 0, within their bounds), the velocity source and the gravity model (a robot file with as
/// many joints). Fails when the plant is no arm or the table is missing.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &ControllerContext,
) -> Result<PdServoSpec, ConfigError> {
    let model = driven_arm(check, cx, "pd_servo")?;
    let Some(t) = t else {
        return check.fail(
            "controller.pd_servo",
            "missing table [controller.pd_servo] with `kp` and `kd`",
        );
    };
    let tunable = joint_gains(
        check,
        "pd_servo",
        model.dof(),
        ["kp", "kd"],
        [t.kp, t.kd],
        t.lower,
        t.upper,
    )?;
    let gravity_model = match &t.gravity_model {
        Some(rel) => Some(model_file(
            check,
            "controller.pd_servo.gravity_model",
            rel,
            model.dof(),
        )?),
        None => None,
    };
    Ok(PdServoSpec {
        tunable,
        gravity_model,
        torque_limits: model.bodies.iter().map(|b| b.limits.effort).collect(),
        velocity: velocity_source(
            check,
            "pd_servo",
            t.velocity,
            t.velocity_cutoff_hz,
            cx,
            false,
        )?,
    })
}

impl ControllerConfig for PdServoSpec {
    fn build(&self, period: f64, _u_limit: Option<f64>) -> Box<dyn Controller> {
        let servo = PdServo::new(&self.tunable.gains, &self.torque_limits)
            .with_velocity(self.velocity, period);
        Box::new(match &self.gravity_model {
            Some(m) => servo.with_gravity(m.clone()),
            None => servo,
        })
    }
    fn reads_truth(&self) -> bool {
        self.velocity.reads_truth()
    }
    fn tunable(&self) -> &Tunable {
        &self.tunable
    }
    fn param_kind(&self) -> ParamKind {
        ParamKind::PdServo
    }
}
