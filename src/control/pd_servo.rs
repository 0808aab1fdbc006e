//! The joint P-D servo of the RKGNN paper (Section 1: "the servo controller can be represented by
//! a Proportional Derivative (P-D) controller"): per joint
//!   tau_i = Kp_i (q_d,i - q_i) + Kd_i (qd_d,i - qd_i),
//! with no model and no gravity compensation, clipped to the joint's torque limit. It is the
//! "actual controller" whose gains a later identification does not know.
//! Parameters: [Kp_1..Kp_n, Kd_1..Kd_n]. Positions are the measured outputs y (with the plant's
//! sensor noise), velocities the joint velocities of the state message.

use super::Controller;
use crate::msg::{PlantState, KIND_PD_SERVO};
use crate::reference::Setpoint;

pub struct PdServo {
    gains: Vec<f64>,
    limits: Vec<f64>,
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
        }
    }
}

impl Controller for PdServo {
    fn kind(&self) -> u32 {
        KIND_PD_SERVO
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
        for i in 0..n {
            let tau = kp[i] * (sp.q[i] - state.y[i]) + kd[i] * (sp.qd[i] - state.qd[i]);
            u[i] = tau.clamp(-self.limits[i], self.limits[i]);
        }
    }

    fn swap_params(&mut self, new: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.gains.copy_from_slice(new);
    }
}
