//! State feedback with integral action (two-mass paper, eq. 2 and Fig. 1):
//!   u = -K x̂,  x̂ = [x; ξ],  ξ' = r - y,
//! with K = [k1, ..., kn, k_{n+1}] in the column order of the paper's Table 9 (so the paper's
//! integral gain k_i equals -k_{n+1}). x is the plant's full state in its documented order, read
//! from the simulator's true state `x_true` as the paper's full-state feedback assumes (on
//! hardware an observer would supply it); the integrator acts on the measured output y.
//!
//! The integrator is stored as its contribution to u, I = -k_{n+1} ξ (as ros2_control stores
//! Ki·∫e), which makes the bumpless swap a one-line re-initialisation of I.
//! Optional output limit with conditional integration (the integrator holds while the output is
//! saturated and the error would drive it further into saturation).

use super::{Controller, ControllerConfig, ControllerContext};
use crate::check::{Check, ConfigError, Tunable};
use serde::{Deserialize, Serialize};
use crate::msg::{PlantState, ParamKind};
use crate::reference::Setpoint;

pub struct StateFeedback {
    gains: Vec<f64>,
    n_x: usize,
    /// Control period (s): the integrator's step.
    period: f64,
    /// Integral contribution to u.
    integral: f64,
    u_limit: Option<f64>,
}

impl StateFeedback {
    /// `gains` has n_x + 1 entries.
    pub fn new(gains: &[f64], period: f64, u_limit: Option<f64>) -> Self {
        assert!(gains.len() >= 2, "state feedback needs n_x + 1 >= 2 gains");
        Self {
            n_x: gains.len() - 1,
            gains: gains.to_vec(),
            period,
            integral: 0.0,
            u_limit,
        }
    }

    /// The unsaturated law -K_x x + I.
    fn law(&self, x: &[f64]) -> f64 {
        self.integral - self.state_term(x)
    }

    /// K_x x (the state part of the law, without the integrator).
    fn state_term(&self, x: &[f64]) -> f64 {
        self.gains[..self.n_x]
            .iter()
            .zip(x)
            .map(|(k, xi)| k * xi)
            .sum()
    }

    pub fn integral(&self) -> f64 {
        self.integral
    }
}

impl Controller for StateFeedback {
    fn kind(&self) -> ParamKind {
        ParamKind::StateFeedback
    }
    fn n_params(&self) -> usize {
        self.gains.len()
    }
    fn params(&self) -> &[f64] {
        &self.gains
    }
    fn n_outputs(&self) -> usize {
        1
    }

    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let reference = sp.q[0];
        let raw = self.law(&state.x_true[..self.n_x]);
        let out = match self.u_limit {
            Some(l) => raw.clamp(-l, l),
            None => raw,
        };
        let e = reference - state.y[0];
        let di = -self.gains[self.n_x] * self.period * e;
        let saturated_further = out != raw && di.signum() == raw.signum();
        if !saturated_further {
            self.integral += di;
        }
        u[0] = out;
    }

    fn swap_params(&mut self, new: &[f64], state: &PlantState, _sp: &Setpoint) {
        let x = &state.x_true[..self.n_x];
        let u_old = self.law(x);
        self.gains.copy_from_slice(new);
        // Choose I so that -K_new x + I = u_old on this sample: no step in u.
        self.integral = u_old + self.state_term(x);
    }
}

// ---------------------------------------------------------------- configuration

/// The `[controller.state_feedback]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    gains: Vec<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

/// Validated state-feedback gains [K_x, k_{n+1}] and their bounds.
#[derive(Debug, Clone, Serialize)]
pub struct StateFeedbackSpec {
    #[serde(flatten)]
    pub tunable: Tunable,
}

pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &ControllerContext,
) -> Result<StateFeedbackSpec, ConfigError> {
    // The law needs the full state of a plant with a linear model to check new gains against.
    let Some(model) = cx.plant.config().linear_model() else {
        return check.fail(
            "controller.kind",
            "state_feedback drives a single-input plant with a linear model of at most 8 states \
             (two_mass, or a single-input single-output lti); arms take pd_servo or computed_torque",
        );
    };
    let Some(t) = t else {
        return check.fail(
            "controller.state_feedback",
            "missing table [controller.state_feedback] with `gains`",
        );
    };
    let n_x = model.n();
    let n = n_x + 1;
    if t.gains.len() != n {
        return check.fail(
            "controller.state_feedback.gains",
            format!(
                "needs {n} values (the plant's {n_x} states and the integrator), got {}",
                t.gains.len()
            ),
        );
    }
    Ok(StateFeedbackSpec {
        tunable: check.tunable("controller.state_feedback", t.gains, t.lower, t.upper, 1e3)?,
    })
}

impl ControllerConfig for StateFeedbackSpec {
    fn build(&self, period: f64, u_limit: Option<f64>) -> Box<dyn Controller> {
        Box::new(StateFeedback::new(&self.tunable.gains, period, u_limit))
    }
    fn tunable(&self) -> &Tunable {
        &self.tunable
    }
    fn param_kind(&self) -> ParamKind {
        ParamKind::StateFeedback
    }
    fn checks_stability(&self) -> bool {
        true
    }
}
