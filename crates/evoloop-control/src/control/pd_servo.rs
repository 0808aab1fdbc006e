//! The joint P-D servo of the RKGNN paper (Section 1: "the servo controller can be represented by
//! a Proportional Derivative (P-D) controller"): per joint
//!   tau_i = Kp_i (q_d,i - q_i) + Kd_i (qd_d,i - qd_i),
//! with no model and no gravity compensation, clipped to the joint's torque limit. It is the
//! "actual controller" whose gains a later identification does not know.
//! Parameters: [Kp_1..Kp_n, Kd_1..Kd_n]. Positions are the measured outputs y (with the plant's
//! sensor noise); velocities by default the measured positions differenced and low-passed as a
//! drive makes them (`velocity = "filtered"`, `estimator::VelocityFilter`), or the simulator's
//! true joint velocities `qd_true` (`velocity = "true"`, the paper's simulation). The
//! programmatic constructor starts on the true velocities (`with_velocity` sets another).

use super::estimator::{Velocities, VelocitySource};
use super::{
    driven_arm, joint_gains, velocity_source, Controller, ControllerConfig, ControllerContext,
    VelocityKey,
};
use crate::check::{Check, ConfigError, Tunable};
use crate::msg::{ParamKind, PlantState};
use crate::reference::Setpoint;
use serde::{Deserialize, Serialize};

pub struct PdServo {
    gains: Vec<f64>,
    limits: Vec<f64>,
    velocity: Velocities,
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
        }
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
        for i in 0..n {
            let tau = kp[i] * (sp.q[i] - state.y[i]) + kd[i] * (sp.qd[i] - qd[i]);
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
}

/// Validated P-D gains [Kp; Kd] with their bounds, and the arm's torque limits.
#[derive(Debug, Clone, Serialize)]
pub struct PdServoSpec {
    #[serde(flatten)]
    pub tunable: Tunable,
    /// Torque limit per joint (from the robot description; infinite where none).
    pub torque_limits: Vec<f64>,
    pub velocity: VelocitySource,
}

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
    Ok(PdServoSpec {
        tunable,
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
        Box::new(
            PdServo::new(&self.tunable.gains, &self.torque_limits)
                .with_velocity(self.velocity, period),
        )
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
