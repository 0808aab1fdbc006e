//! State feedback with integral action (two-mass paper, eq. 2 and Fig. 1):
//!   u = -K x̂,  x̂ = [x; ξ],  ξ' = r - y,
//! with K = [k1, ..., kn, k_{n+1}] in the column order of the paper's Table 9 (so the paper's
//! integral gain k_i equals -k_{n+1}). x is the plant's state in its documented order. By
//! default (`state = "kalman"`) it is a steady-state Kalman filter's estimate from the measured
//! output y and the applied command, designed from the plant's nominal model for its declared
//! sensor (`law::estimator`), as a machine with one position sensor runs this law. The
//! paper assumes the full state measured: `state = "true"` reads the simulator's true state
//! `x_true` instead, for reproducing its tables, and says so. The integrator acts on y.
//!
//! The integrator is stored as its contribution to u, I = -k_{n+1} ξ (as ros2_control stores
//! Ki·∫e), which makes the bumpless swap a one-line re-initialisation of I.
//! Optional output limit with conditional integration (the integrator holds while the output is
//! saturated and the error would drive it further into saturation).

use super::estimator::{Kalman, KalmanDesign, KalmanGains};
use super::{Controller, ControllerConfig, ControllerContext};
use crate::check::{Check, ConfigError, Tunable};
use serde::{Deserialize, Serialize};
use crate::msg::{PlantState, ParamKind};
use crate::reference::Setpoint;

/// State feedback with integral action (see the module docs): the gains K, the integrator kept as
/// its contribution to u, an optional output limit, and the Kalman filter whose estimate it runs on
/// (or none: the true state).
pub struct StateFeedback {
    gains: Vec<f64>,
    n_x: usize,
    /// The state the law runs on: a filter's estimate, or (None) the simulator's truth.
    kalman: Option<Kalman>,
    /// Control period (s): the integrator's step.
    period: f64,
    /// Integral contribution to u.
    integral: f64,
    /// `integral` when the last trial set went in service (`save_state`).
    saved_integral: f64,
    u_limit: Option<f64>,
}

impl StateFeedback {
    /// `gains` has n_x + 1 entries. The law runs on the simulator's true state (the paper's
    /// full-state assumption) until `with_kalman` gives it a filter.
    pub fn new(gains: &[f64], period: f64, u_limit: Option<f64>) -> Self {
        assert!(gains.len() >= 2, "state feedback needs n_x + 1 >= 2 gains");
        Self {
            n_x: gains.len() - 1,
            kalman: None,
            gains: gains.to_vec(),
            period,
            integral: 0.0,
            saved_integral: 0.0,
            u_limit,
        }
    }

    /// The integrator's contribution to u, I = -k_{n+1} ξ, in the command's unit.
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Run on the estimate of a Kalman filter with `gains` (designed for a model with this
    /// law's n_x states), for measurements `sensor_delay` samples old.
    pub fn with_kalman(mut self, gains: &KalmanGains, sensor_delay: usize) -> Self {
        assert_eq!(gains.model.n(), self.n_x, "the filter estimates the law's states");
        self.kalman = Some(Kalman::new(gains, sensor_delay));
        self
    }

    /// The plant state at `state`'s sample as the law knows it. Allocation-free; the filter
    /// takes each sample once however often it is asked.
    fn state_of<'a>(kalman: &'a mut Option<Kalman>, n_x: usize, state: &'a PlantState) -> &'a [f64] {
        match kalman {
            Some(k) => k.update(state),
            None => &state.x_true[..n_x],
        }
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
        let x = Self::state_of(&mut self.kalman, self.n_x, state);
        let raw = self.integral - dot(&self.gains[..self.n_x], x);
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

    fn adopt_model(&mut self, model: &super::LinearModel) -> Option<bool> {
        self.kalman.as_mut().map(|k| k.redesign(model))
    }

    fn swap_params(&mut self, new: &[f64], state: &PlantState, _sp: &Setpoint) {
        let x = Self::state_of(&mut self.kalman, self.n_x, state);
        let u_old = self.integral - dot(&self.gains[..self.n_x], x);
        // Choose I so that -K_new x + I = u_old on this sample: no step in u.
        self.integral = u_old + dot(&new[..self.n_x], x);
        self.gains.copy_from_slice(new);
    }

    fn save_state(&mut self) {
        self.saved_integral = self.integral;
    }

    fn swap_to_saved(&mut self, values: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.gains.copy_from_slice(values);
        self.integral = self.saved_integral;
    }
}

/// K_x x.
fn dot(k: &[f64], x: &[f64]) -> f64 {
    k.iter().zip(x).map(|(k, x)| k * x).sum()
}

// ---------------------------------------------------------------- configuration

/// The `[controller.state_feedback]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    gains: Vec<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
    state: Option<StateSource>,
    process_noise: Option<f64>,
    measurement_noise: Option<f64>,
    state_noise: Option<f64>,
}

/// `controller.state_feedback.state`: where the law's x comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateSource {
    /// A steady-state Kalman filter's estimate from the measured output (the default).
    #[default]
    Kalman,
    /// The simulator's true state `x_true`: the paper's full-state assumption, which no
    /// machine with one position sensor has (paper reproductions only).
    True,
}

/// The filter's design when no key gives it: a disturbance of this standard deviation in the
/// input's units per period, and no less than this measurement error for an ideal sensor.
pub const DEFAULT_PROCESS_NOISE: f64 = 1.0;
/// The least measurement error a filter is designed for by default (output units): what a sensor
/// declared ideal (no noise, no quantisation) is designed with.
pub const IDEAL_SENSOR_NOISE: f64 = 1e-6;

/// Validated state-feedback gains [K_x, k_{n+1}] and their bounds, and the state they act on.
#[derive(Debug, Clone, Serialize)]
pub struct StateFeedbackSpec {
    /// The gains [k1, ..., kn, k_{n+1}] in the paper's Table 9 order, and their bounds.
    #[serde(flatten)]
    pub tunable: Tunable,
    /// Where the law's x comes from (`state`; a Kalman filter by default).
    pub state: StateSource,
    /// The filter's design (`state = "kalman"`), and its error dynamics' slowest pole's radius.
    pub kalman: Option<KalmanDesign>,
    /// The radius of the filter's slowest error pole (`state = "kalman"`): below 1, the nearer 1
    /// the slower the estimate settles.
    pub kalman_slowest_pole: Option<f64>,
    /// Boxed: a designed filter is ten times the size of the other laws' settings.
    #[serde(skip)]
    gains: Option<Box<KalmanGains>>,
    /// The plant's declared sensor delay, samples: the filter predicts across it.
    #[serde(skip)]
    sensor_delay: usize,
}

/// Validate `[controller.state_feedback]` for a plant with a linear model: n_x + 1 gains within
/// their bounds, the state source and, for `state = "kalman"`, a design (noise keys, defaults from
/// the plant's sensor) from which a stable filter comes at the control period. Fails when the plant
/// has no linear model or the table is missing.
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
    let tunable = check.tunable("controller.state_feedback", t.gains, t.lower, t.upper, 1e3)?;
    let state = t.state.unwrap_or_default();
    let design = match state {
        StateSource::True => {
            if t.process_noise.is_some() || t.measurement_noise.is_some() || t.state_noise.is_some()
            {
                return check.fail(
                    "controller.state_feedback.state",
                    "\"true\" reads the true state: process_noise, measurement_noise and \
                     state_noise design the Kalman filter of state = \"kalman\"",
                );
            }
            None
        }
        StateSource::Kalman => Some(KalmanDesign {
            process_noise: check.positive(
                "controller.state_feedback.process_noise",
                t.process_noise.unwrap_or(DEFAULT_PROCESS_NOISE),
            )?,
            measurement_noise: check.positive(
                "controller.state_feedback.measurement_noise",
                t.measurement_noise
                    .unwrap_or(cx.measurement_std.max(IDEAL_SENSOR_NOISE)),
            )?,
            state_noise: check.range(
                "controller.state_feedback.state_noise",
                t.state_noise.unwrap_or(0.0),
                0.0,
                crate::reference::MAX_VALUE,
            )?,
        }),
    };
    let gains = match design {
        Some(d) => match d.gains(&model, cx.period) {
            Ok(g) => Some(Box::new(g)),
            Err(why) => {
                return check.fail(
                    "controller.state_feedback.state",
                    format!("no Kalman filter for this plant's model: {why}"),
                )
            }
        },
        None => None,
    };
    Ok(StateFeedbackSpec {
        tunable,
        state,
        kalman: design,
        kalman_slowest_pole: gains
            .as_ref()
            .map(|g| g.poles.iter().map(|z| z.norm()).fold(0.0, f64::max)),
        gains,
        sensor_delay: cx.sensor_delay,
    })
}

impl StateFeedbackSpec {
    /// The Kalman filter the law runs on (`state = "kalman"`), designed for the plant's model.
    pub fn kalman_gains(&self) -> Option<&KalmanGains> {
        self.gains.as_deref()
    }
}

impl ControllerConfig for StateFeedbackSpec {
    fn build(&self, period: f64, u_limit: Option<f64>) -> Box<dyn Controller> {
        let law = StateFeedback::new(&self.tunable.gains, period, u_limit);
        Box::new(match &self.gains {
            Some(g) => law.with_kalman(g, self.sensor_delay),
            None => law,
        })
    }
    fn reads_truth(&self) -> bool {
        self.state == StateSource::True
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
