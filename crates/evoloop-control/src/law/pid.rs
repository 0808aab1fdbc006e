//! The PID of the fuzzy-network paper's maglev experiment (eq. 26), in discrete time at the
//! sampling interval T_A, with four ways of handling the integrator while the actuator saturates:
//!   u_k = Kp { e_k + Tv / T_A (e_k - e_{k-1}) } + sum_{n<=k} K_i e_n,   clipped to [u_min, u_max].
//! - `Fuzzy` (eqs. 27-30): K_i(|e|) = C_i (K_i'(|e|') - K_i'(1)), |e|' = min(|e| / C_e, 1), from the
//!   two-rule base "IF |e| small THEN K_i large; IF |e| large THEN K_i small" with Gaussian MFs;
//!   by the centre of gravity of Section 2.1,
//!   `K_i'(x) = 1 / (1 + (v0K/v1K) exp((x / v0e)^2 - ((x - 1) / v1e)^2))`.
//!   (The paper's printed eq. 30 has v0e and v1e the other way round; the form here is what its
//!   own eqs. 28-29 and Section 2.1 give, and `fuzzy_gain_matches_the_two_rule_network` checks
//!   it against the generic fuzzy network.) Parameters [Kp, Tv, v0e, v1e, v0K/v1K, C_i, C_e].
//! - `None`: a constant K_i, no anti-windup. Parameters [Kp, Tv, Ki].
//! - `Clamping`: conditional integration, the integrator holds while the output is saturated and
//!   the error would drive it further. Parameters [Kp, Tv, Ki]. (The key stays `clamping` for the
//!   files and JSON that use it; the plain clamp is the next one.)
//! - `IntegratorClamp`: the plain integrator clamp, the integral state is kept within the output
//!   limits [u_min, u_max]. Parameters [Kp, Tv, Ki].
//! - `BackCalculation`: the saturation excess is fed back into the integrator,
//!   I += Ki e + Kb (u_sat - u_raw). Parameters [Kp, Tv, Ki, Kb].
//!
//! Units as the paper's: e in mm, u in mA, Kp and Ki (per sample) in mA/mm, Tv in s.
//! The integrator starts at `initial_integral` (the holding current, as if the loop had been
//! running: eq. 26 has no separate bias).

use super::{Controller, ControllerConfig, ControllerContext};
use crate::check::{Check, ConfigError, Tunable};
use crate::msg::{ParamKind, PlantState};
use crate::reference::Setpoint;
use serde::{Deserialize, Serialize};

/// How the PID's integrator is handled while the actuator saturates (`controller.pid.anti_windup`;
/// see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AntiWindup {
    /// The paper's fuzzy anti-windup: K_i falls as |e| grows (eqs. 27-30).
    /// Parameters [Kp, Tv, v0e, v1e, v0K/v1K, C_i, C_e].
    Fuzzy,
    /// A constant K_i and no anti-windup. Parameters [Kp, Tv, Ki].
    None,
    /// Conditional integration: the integrator holds while the output is saturated and the error
    /// would drive it further. Parameters [Kp, Tv, Ki].
    Clamping,
    /// The saturation excess fed back into the integrator with gain Kb.
    /// Parameters [Kp, Tv, Ki, Kb].
    BackCalculation,
    /// The plain integrator clamp: the integral kept within the output limits.
    /// Parameters [Kp, Tv, Ki].
    IntegratorClamp,
}

impl AntiWindup {
    /// The paper's parameter ranges (Section 5.2) for the fuzzy anti-windup PID, and the same ranges
    /// for the baselines' common parameters (Ki like C_i; Kb in [0, 1]).
    pub fn paper_ranges(self) -> (Vec<f64>, Vec<f64>) {
        match self {
            AntiWindup::Fuzzy => (
                vec![500.0, 0.01, 0.5, 0.5, 0.5, 0.0, 0.3],
                vec![1500.0, 0.1, 1.2, 1.2, 1.5, 120.0, 1.2],
            ),
            AntiWindup::None | AntiWindup::Clamping | AntiWindup::IntegratorClamp => {
                (vec![500.0, 0.01, 0.0], vec![1500.0, 0.1, 120.0])
            }
            AntiWindup::BackCalculation => {
                (vec![500.0, 0.01, 0.0, 0.0], vec![1500.0, 0.1, 120.0, 1.0])
            }
        }
    }

    /// The number of parameters the scheme's PID takes: 7 fuzzy, 4 back-calculation, else 3.
    pub fn n_params(self) -> usize {
        match self {
            AntiWindup::Fuzzy => 7,
            AntiWindup::None | AntiWindup::Clamping | AntiWindup::IntegratorClamp => 3,
            AntiWindup::BackCalculation => 4,
        }
    }

    /// The `ParamKind` the scheme's sets carry (a set for one scheme is no use to another).
    pub fn kind(self) -> ParamKind {
        match self {
            AntiWindup::Fuzzy => ParamKind::PidFuzzyAntiWindup,
            AntiWindup::None => ParamKind::Pid,
            AntiWindup::Clamping => ParamKind::PidClamping,
            AntiWindup::BackCalculation => ParamKind::PidBackCalculation,
            AntiWindup::IntegratorClamp => ParamKind::PidIntegratorClamp,
        }
    }

    /// The parameters' names in set order, for messages and reports.
    pub fn param_names(self) -> &'static [&'static str] {
        match self {
            AntiWindup::Fuzzy => &["Kp", "Tv", "v0e", "v1e", "v0K/v1K", "C_i", "C_e"],
            AntiWindup::None | AntiWindup::Clamping | AntiWindup::IntegratorClamp => {
                &["Kp", "Tv", "Ki"]
            }
            AntiWindup::BackCalculation => &["Kp", "Tv", "Ki", "Kb"],
        }
    }

    /// The scheme's name in reports, CSV columns and messages: as written in TOML, but `fuzzy_aw`
    /// for `Fuzzy`.
    pub fn name(self) -> &'static str {
        match self {
            AntiWindup::Fuzzy => "fuzzy_aw",
            AntiWindup::None => "none",
            AntiWindup::Clamping => "clamping",
            AntiWindup::BackCalculation => "back_calculation",
            AntiWindup::IntegratorClamp => "integrator_clamp",
        }
    }
}

/// K_i'(x) of the two-rule base (see the module text), x = |e|' in [0, 1].
pub fn fuzzy_ki_normalised(x: f64, v0e: f64, v1e: f64, ratio_k: f64) -> f64 {
    let a = x / v0e;
    let b = (x - 1.0) / v1e;
    1.0 / (1.0 + ratio_k * (a * a - b * b).exp())
}

/// The integral gain (per sample) of scheme `aw` with parameters `p` at error e: K_i, or the
/// fuzzy anti-windup's error-dependent one.
pub fn integral_gain(aw: AntiWindup, p: &[f64], e: f64) -> f64 {
    match aw {
        AntiWindup::Fuzzy => {
            let (v0e, v1e, r, ci, ce) = (p[2], p[3], p[4], p[5], p[6]);
            let x = (e.abs() / ce).min(1.0);
            ci * (fuzzy_ki_normalised(x, v0e, v1e, r) - fuzzy_ki_normalised(1.0, v0e, v1e, r))
        }
        _ => p[2],
    }
}

/// The PID of eq. 26 under one anti-windup scheme: the parameters in service, the output limits,
/// the integrator and the last error.
#[derive(Debug, Clone)]
pub struct Pid {
    /// The anti-windup scheme, which also fixes the parameters' layout.
    pub aw: AntiWindup,
    params: Vec<f64>,
    period: f64,
    u_min: f64,
    u_max: f64,
    integral: f64,
    e_prev: Option<f64>,
    /// The integral when the last trial set went in service (`save_state`).
    saved_integral: f64,
}

impl Pid {
    /// A PID under `aw` with `params` (`aw.n_params()` values, else it panics), sampled every
    /// `period` s, clipping its output to `limits` = (u_min, u_max), its integrator starting at
    /// `initial_integral`.
    pub fn new(
        aw: AntiWindup,
        params: &[f64],
        period: f64,
        limits: (f64, f64),
        initial_integral: f64,
    ) -> Self {
        assert_eq!(params.len(), aw.n_params(), "parameter count for {aw:?}");
        Self {
            aw,
            params: params.to_vec(),
            period,
            u_min: limits.0,
            u_max: limits.1,
            integral: initial_integral,
            e_prev: None,
            saved_integral: initial_integral,
        }
    }

    /// The integral gain at error e (per sample, mA/mm).
    pub fn ki(&self, e: f64) -> f64 {
        integral_gain(self.aw, &self.params, e)
    }

    fn pd(&self, e: f64) -> f64 {
        let de = e - self.e_prev.unwrap_or(e);
        self.params[0] * (e + self.params[1] / self.period * de)
    }

    /// The integrator's state, in the output's unit (mA for the maglev).
    pub fn integral(&self) -> f64 {
        self.integral
    }
}

impl Controller for Pid {
    fn kind(&self) -> ParamKind {
        self.aw.kind()
    }
    fn n_params(&self) -> usize {
        self.params.len()
    }
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn n_outputs(&self) -> usize {
        1
    }

    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let e = sp.q[0] - state.y[0];
        let pd = self.pd(e);
        let di = self.ki(e) * e;
        let out = match self.aw {
            AntiWindup::Fuzzy | AntiWindup::None => {
                self.integral += di;
                (pd + self.integral).clamp(self.u_min, self.u_max)
            }
            AntiWindup::Clamping => {
                let raw = pd + self.integral + di;
                let pushes_up = raw > self.u_max && di > 0.0;
                let pushes_down = raw < self.u_min && di < 0.0;
                if !(pushes_up || pushes_down) {
                    self.integral += di;
                }
                (pd + self.integral).clamp(self.u_min, self.u_max)
            }
            AntiWindup::IntegratorClamp => {
                self.integral = (self.integral + di).clamp(self.u_min, self.u_max);
                (pd + self.integral).clamp(self.u_min, self.u_max)
            }
            AntiWindup::BackCalculation => {
                let raw = pd + self.integral + di;
                let sat = raw.clamp(self.u_min, self.u_max);
                self.integral += di + self.params[3] * (sat - raw);
                sat
            }
        };
        self.e_prev = Some(e);
        u[0] = out;
    }

    fn swap_params(&mut self, new: &[f64], state: &PlantState, sp: &Setpoint) {
        // Keep u continuous: the new P-D part replaces the old one inside the integrator.
        let e = sp.q[0] - state.y[0];
        let old = self.pd(e);
        self.params.copy_from_slice(new);
        self.integral += old - self.pd(e);
    }

    /// The loop as `step` runs it while unsaturated (`LinearModel::stabilised_by_pid`), with
    /// the integral gain at zero error.
    fn stabilises(&self, model: &crate::plant::LinearModel, values: &[f64]) -> bool {
        values.len() == self.aw.n_params()
            && model.stabilised_by_pid(
                values[0],
                values[0] * values[1] / self.period,
                integral_gain(self.aw, values, 0.0),
            )
    }

    fn save_state(&mut self) {
        self.saved_integral = self.integral;
    }

    fn swap_to_saved(&mut self, values: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.params.copy_from_slice(values);
        self.integral = self.saved_integral;
    }
}

// ---------------------------------------------------------------- configuration

/// The `[controller.pid]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    anti_windup: AntiWindup,
    params: Vec<f64>,
    initial_integral: Option<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

/// A validated PID: its anti-windup scheme, parameters with bounds (the paper's ranges unless
/// given), the integrator's start and the actuator's range it clips to.
#[derive(Debug, Clone, Serialize)]
pub struct PidSpec {
    /// The anti-windup scheme (`anti_windup`).
    pub anti_windup: AntiWindup,
    /// The parameters in the scheme's order (`params`) and their bounds.
    #[serde(flatten)]
    pub tunable: Tunable,
    /// The integrator's start, within the output range (default: the plant's holding input).
    pub initial_integral: f64,
    /// The plant's input range (u_min, u_max), which the output is clipped to.
    pub output_range: (f64, f64),
}

/// Validate `[controller.pid]` for a single-input single-output plant: as many `params` as the
/// scheme takes, within their bounds, and an initial integral within the plant's input range. Fails
/// for an arm or when the table is missing.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &ControllerContext,
) -> Result<PidSpec, ConfigError> {
    let Some(input) = cx.plant.config().scalar_input() else {
        return check.fail(
            "controller.kind",
            "the PID of eq. 26 drives a single-input single-output plant (maglev, two_mass, heater, \
             arsinh, or an lti plant with one input and one output), not an arm",
        );
    };
    let Some(t) = t else {
        return check.fail(
            "controller.pid",
            "missing table [controller.pid] with `anti_windup` and `params`",
        );
    };
    let aw = t.anti_windup;
    let n = aw.n_params();
    if t.params.len() != n {
        return check.fail(
            "controller.pid.params",
            format!(
                "{} anti-windup takes {n} values ({}), got {}",
                aw.name(),
                aw.param_names().join(", "),
                t.params.len()
            ),
        );
    }
    let (lo, hi) = aw.paper_ranges();
    let tunable = check.tunable(
        "controller.pid",
        t.params,
        Some(t.lower.unwrap_or(lo)),
        Some(t.upper.unwrap_or(hi)),
        0.0,
    )?;
    let (u_min, u_max) = input.range;
    let key = "controller.pid.initial_integral";
    let initial_integral = check.finite(key, t.initial_integral.unwrap_or(input.hold))?;
    Ok(PidSpec {
        anti_windup: aw,
        tunable,
        initial_integral: check.range(key, initial_integral, u_min, u_max)?,
        output_range: input.range,
    })
}

impl ControllerConfig for PidSpec {
    fn build(&self, period: f64, _u_limit: Option<f64>) -> Box<dyn Controller> {
        Box::new(Pid::new(
            self.anti_windup,
            &self.tunable.gains,
            period,
            self.output_range,
            self.initial_integral,
        ))
    }
    fn tunable(&self) -> &Tunable {
        &self.tunable
    }
    /// A PID's sets are tagged with its scheme (a fuzzy set is no use to a clamping PID).
    fn param_kind(&self) -> ParamKind {
        self.anti_windup.kind()
    }
}
