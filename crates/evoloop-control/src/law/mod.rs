//! Control laws. A controller is built once (all buffers allocated), then `step`ped once per
//! cycle without allocating. Parameter sets arrive from the optimiser; `validate` checks them at
//! the boundary and `swap_params` puts an accepted set in service without a bump in u.

pub mod estimator;
pub mod evidence;
pub mod fuzzy_select;
pub mod model_check;
pub mod model_parts;
pub mod state_check;
pub mod validate;

pub use crate::plant::LinearModel;
pub use computed_torque::ComputedTorque;
pub use pd_servo::PdServo;
pub use pid::{AntiWindup, Pid};
pub use state_feedback::StateFeedback;
pub use validate::{validate_model, validate_params, ParamBounds, Rejection};

use crate::check::{Check, ConfigError, Tunable};
use crate::msg::{ParamKind, PlantState};
use crate::plant::PlantModel;
use crate::reference::Setpoint;

// The controller registry: adding a control law is its module (the law, `Table`, `validate`
// and `impl ControllerConfig`) plus one line here.
crate::kinds! {
    family "controller", trait ControllerConfig, context ControllerContext<'_>;
    /// `controller.kind`: which control law runs.
    pub enum ControllerKind;
    /// A validated controller: the chosen law's settings.
    pub enum ControllerModel;
    /// The `[controller]` table as read: the keys every law shares and one table per law.
    pub struct RawController {
        /// `controller.kind`: which control law runs.
        pub kind: ControllerKind,
        /// `controller.u_limit`: the output limit, > 0 (none by default); state feedback saturates
        /// symmetrically at it.
        pub u_limit: Option<f64>,
        /// `controller.stale_after_periods`: periods a state sample may be old before it is
        /// flagged stale (`TELEMETRY_FLAG_STALE`, counted; it is still used) (default 3, >= 1).
        pub stale_after_periods: Option<u32>,
    };
    state_feedback => StateFeedback(StateFeedbackSpec),
    pd_servo => PdServo(PdServoSpec),
    computed_torque => ComputedTorque(ComputedTorqueSpec),
    pid => Pid(PidSpec),
    fuzzy_computed_torque => FuzzyComputedTorque(FuzzyComputedTorqueSpec),
    fuzzy_network => FuzzyNetwork(FuzzyNetworkSpec),
}

/// What a control law's configuration offers the rest of the system. Besides this, a law's
/// module has `pub struct Table` (its `[controller.<kind>]` keys) and `pub fn validate`.
pub trait ControllerConfig {
    /// The law with its configured initial parameters, for control period `period` (s) and the
    /// shared output limit `u_limit`.
    fn build(&self, period: f64, u_limit: Option<f64>) -> Box<dyn Controller>;
    /// The initial parameter set and the bounds every later set must respect.
    fn tunable(&self) -> &Tunable;
    /// The `msg::ParamKind` its parameter sets carry.
    fn param_kind(&self) -> ParamKind;
    /// Indices of the parameters that are scaling factors (the GA/Hooke-Jeeves hybrid's phase 2
    /// searches them); none by default.
    fn scaling_genes(&self) -> Vec<usize> {
        Vec::new()
    }
    /// The `msg::ParamKind` of its model sets, if it takes any (`Controller::model_kind`).
    fn model_param_kind(&self) -> Option<ParamKind> {
        None
    }
    /// Whether a new set must also stabilise the plant's linear model before use.
    fn checks_stability(&self) -> bool {
        false
    }
    /// Whether the law reads the simulator's truth fields (`x_true`, `q_true`, `qd_true`),
    /// which no sensor gives: a paper reproduction's full-state or true-velocity assumption,
    /// said in its file. Such a law's states must carry them (`plant.publish_truth`).
    fn reads_truth(&self) -> bool {
        false
    }
}

/// What a law's validation may look at besides its own table.
pub struct ControllerContext<'a> {
    /// The validated plant the law will drive.
    pub plant: &'a PlantModel,
    /// The reference the controller will track, and for how long (s; infinite for a run until
    /// stopped): a model-based law checks its models where the run will take them.
    pub reference: &'a crate::reference::Reference,
    /// The run's duration, s (infinite for a run until stopped).
    pub duration: f64,
    /// The control period, s (an estimator is designed for it).
    pub period: f64,
    /// The standard deviation of the plant's measurement error as its sensor is declared: the
    /// noise and the quantisation together (`PlantSpec::measurement_std`).
    pub measurement_std: f64,
    /// Samples the measurement lags the state it is of (`PlantSpec::sensor_delay`).
    pub sensor_delay: usize,
}

/// A validated controller: the keys every law shares, and its own settings.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ControllerSpec {
    /// Output limit (state feedback: symmetric saturation with conditional integration).
    pub u_limit: Option<f64>,
    /// Periods a state sample may be old before it is flagged stale (`TELEMETRY_FLAG_STALE`,
    /// counted); the law still uses it.
    pub stale_after_periods: u32,
    /// The chosen law's own settings (its `[controller.<kind>]` table, validated).
    #[serde(flatten)]
    pub model: ControllerModel,
}

impl ControllerSpec {
    /// Validate the `[controller]` table against the plant it drives.
    pub fn validate(
        mut raw: RawController,
        check: &Check,
        plant: &crate::plant::PlantSpec,
        reference: &crate::reference::Reference,
        duration: f64,
        period: f64,
    ) -> Result<ControllerSpec, ConfigError> {
        let u_limit = match raw.u_limit {
            Some(l) => Some(check.positive("controller.u_limit", l)?),
            None => None,
        };
        let stale_after_periods = raw.stale_after_periods.unwrap_or(3);
        if stale_after_periods == 0 {
            return check.fail("controller.stale_after_periods", "must be >= 1");
        }
        let cx = ControllerContext {
            plant: &plant.model,
            reference,
            duration,
            period,
            measurement_std: plant.measurement_std(),
            sensor_delay: plant.sensor_delay as usize,
        };
        let kind = raw.kind;
        Ok(ControllerSpec {
            u_limit,
            stale_after_periods,
            model: raw.validate_kind(kind, check, &cx)?,
        })
    }

    /// Which control law this is.
    pub fn kind(&self) -> ControllerKind {
        self.model.kind()
    }

    /// The law with its configured initial parameters, for control period `period`, s.
    pub fn build(&self, period: f64) -> Box<dyn Controller> {
        self.model.config().build(period, self.u_limit)
    }

    /// The law's initial parameter set and the bounds every later set must respect.
    pub fn tunable(&self) -> &Tunable {
        self.model.config().tunable()
    }

    /// The `ParamKind` the law's parameter sets carry.
    pub fn param_kind(&self) -> ParamKind {
        self.model.config().param_kind()
    }

    /// The `ParamKind` of the law's model sets, if it takes any.
    pub fn model_param_kind(&self) -> Option<ParamKind> {
        self.model.config().model_param_kind()
    }

    /// Indices of the parameters that are scaling factors (the GA/Hooke-Jeeves hybrid's phase 2
    /// searches them).
    pub fn scaling_genes(&self) -> Vec<usize> {
        self.model.config().scaling_genes()
    }

    /// Whether the law reads the simulator's truth fields, which no sensor gives.
    pub fn reads_truth(&self) -> bool {
        self.model.config().reads_truth()
    }
}

/// A control law as the cycle runs it: built once with its buffers, then stepped once per period
/// without allocating, its parameter sets swapped in at cycle boundaries.
pub trait Controller: Send {
    /// The `msg::ParamKind` this controller accepts parameter sets for.
    fn kind(&self) -> ParamKind;
    /// Number of tunable parameters.
    fn n_params(&self) -> usize;
    /// The parameters in service.
    fn params(&self) -> &[f64];
    /// Number of control outputs.
    fn n_outputs(&self) -> usize;
    /// One control cycle: read the state sample and the set-point, write u, advance internal
    /// state (integrators) to the next cycle. Must not allocate.
    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]);
    /// Put a validated parameter set in service at this cycle boundary, before `step`, adjusting
    /// internal state so that `step` on the same sample returns the same u as the old set would
    /// have (bumpless transfer). Laws without internal state cannot absorb the difference; they
    /// switch outright (the jump is proportional to the gain change times the tracking error).
    fn swap_params(&mut self, new: &[f64], state: &PlantState, sp: &Setpoint);
    /// Whether the set `values` keeps this law's loop on the linear `model` stable, the check
    /// a linear plant's new sets pass: state feedback's u = -K [x; xi] unless the law says
    /// otherwise. Allocation-free.
    fn stabilises(&self, model: &LinearModel, values: &[f64]) -> bool {
        model.stabilised_by(values)
    }
    /// A trial set (the direct scheme) is about to go in service: remember the law's internal
    /// state (integrators) as it is, for `swap_to_saved`. Must not allocate.
    fn save_state(&mut self) {}
    /// Put `values` in service with the internal state saved when the last trial began
    /// (`save_state`), not bumpless: a trial's abort back to its fallback (a bumpless transfer
    /// would keep the failing trial's command and move the difference into the integrator,
    /// leaving the fallback the failing trial's windup to undo), and an isolated trial's start
    /// and end (`ControlCycle::with_isolated_trials`). Laws without internal state just switch.
    fn swap_to_saved(&mut self, values: &[f64], state: &PlantState, sp: &Setpoint) {
        self.swap_params(values, state, sp);
    }
    /// The kind of a second sort of set the law takes besides its gains (an identified model),
    /// checked and put in service by `swap_model`; `None` for laws that take gains only.
    fn model_kind(&self) -> Option<ParamKind> {
        None
    }
    /// The number of values of the largest model set the law takes (0 for none): room for a
    /// model sent in parts (`ParamKind::ModelPart`), allocated once.
    fn model_len(&self) -> usize {
        0
    }
    /// The plant's linear model at the latest estimate the loop adopted (the indirect scheme):
    /// a law that estimates its state with a model-based filter designs the filter again on
    /// it. Some(whether it did), None for a law without such a filter. Must not allocate.
    fn adopt_model(&mut self, _model: &LinearModel) -> Option<bool> {
        None
    }
    /// Check a model set's values (finite already) and put it in service at this cycle
    /// boundary, or refuse it with a code and the offending value's index. Must not allocate.
    fn swap_model(&mut self, _values: &[f64]) -> Result<(), (crate::msg::ParamCode, u32)> {
        Err((crate::msg::ParamCode::RejectedWrongKind, 0))
    }
    /// Names of the law's own run.csv columns (diagnostics such as an active model), asked once
    /// before the run; at most `msg::MAX_LAW_VALUES`, since telemetry carries their values.
    fn log_columns(&self) -> Vec<String> {
        Vec::new()
    }
    /// Their values after the last `step`, one per column. Must not allocate.
    fn log_values(&self, out: &mut [f64]) {
        debug_assert!(out.is_empty());
    }
}

pub mod cycle;
pub use cycle::ControlCycle;

/// The robot file `rel` at `key` as a controller's model of an `n`-joint plant.
pub(crate) fn model_file(
    check: &Check,
    key: &str,
    rel: &std::path::Path,
    n: usize,
) -> Result<crate::dynamics::Model, ConfigError> {
    let (path, m) = check.robot(key, rel)?;
    if m.dof() != n {
        let why = format!("{} has {} joints, the plant {n}", path.display(), m.dof());
        return check.fail(key, why);
    }
    Ok(m)
}

/// The arm a joint-space law (`law`) drives; an error on `controller.kind` for other plants.
pub(crate) fn driven_arm<'a>(
    check: &Check,
    cx: &ControllerContext<'a>,
    law: &str,
) -> Result<&'a crate::dynamics::Model, ConfigError> {
    match cx.plant.config().rigid_body() {
        Some(m) => Ok(m),
        None => check.fail(
            "controller.kind",
            format!(
                "{law} drives an arm: plant.kind = \"arm\", or an external plant with its model \
                 in plant.external.robot"
            ),
        ),
    }
}

/// `controller.<law>.velocity` as written: "true", "filtered" or "observer".
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VelocityKey {
    /// `"true"`: the simulator's true joint velocities `qd_true`.
    True,
    /// `"filtered"`: the measured positions differenced and low-passed (the default).
    Filtered,
    /// `"observer"`: predicted by the law's own model from the applied torques, corrected by the
    /// measured positions.
    Observer,
}

/// The cutoff of a joint-space law's velocity filter when `velocity_cutoff_hz` is not given, at
/// control rates of 250 Hz and above (`default_velocity_cutoff_hz`).
pub const DEFAULT_VELOCITY_CUTOFF_HZ: f64 = 50.0;

/// The velocity filter's cutoff when `velocity_cutoff_hz` is not given, for a law sampled every
/// `period` s: 50 Hz, or a fifth of the sampling rate where that is lower (a 100 Hz loop: 20 Hz),
/// so that the default is below the Nyquist frequency at any rate.
pub fn default_velocity_cutoff_hz(period: f64) -> f64 {
    DEFAULT_VELOCITY_CUTOFF_HZ.min(0.2 / period)
}

/// A joint-space law's velocity source from its `velocity` and `velocity_cutoff_hz` keys
/// (under `controller.<law>`): by default "filtered", the measured positions differenced and
/// low-passed as a servo drive does (a law acts on what a plant measures); "observer" or
/// "true" (the simulator's velocities, an ideal sensor no plant has) when written. The cutoff
/// (the low-pass's, or the observer's bandwidth) must lie below the sampling's Nyquist
/// frequency 1 / (2 period). Only a law with a model of its own (`has_model`) runs an observer,
/// which predicts across the plant's declared sensor delay.
pub(crate) fn velocity_source(
    check: &Check,
    law: &str,
    velocity: Option<VelocityKey>,
    cutoff_hz: Option<f64>,
    cx: &ControllerContext,
    has_model: bool,
) -> Result<estimator::VelocitySource, ConfigError> {
    let period = cx.period;
    let key = format!("controller.{law}.velocity_cutoff_hz");
    let velocity = velocity.unwrap_or(VelocityKey::Filtered);
    if velocity == VelocityKey::True {
        return match cutoff_hz {
            Some(_) => check.fail(
                &key,
                "the cutoff of velocity = \"filtered\" or \"observer\"",
            ),
            None => Ok(estimator::VelocitySource::True),
        };
    }
    if velocity == VelocityKey::Observer && !has_model {
        return check.fail(
            &format!("controller.{law}.velocity"),
            format!("\"observer\" predicts with the law's own model, and {law} has no single model in service (use \"filtered\", or computed_torque)"),
        );
    }
    let nyquist = 0.5 / period;
    let fc = cutoff_hz.unwrap_or_else(|| default_velocity_cutoff_hz(period));
    if !(fc > 0.0 && fc < nyquist) {
        return check.fail(
            &key,
            format!("must lie in (0, {nyquist}) Hz, below the control rate's Nyquist frequency (got {fc})"),
        );
    }
    Ok(match velocity {
        VelocityKey::Observer => estimator::VelocitySource::Observer {
            bandwidth_hz: fc,
            delay: cx.sensor_delay,
        },
        _ => estimator::VelocitySource::Filtered { cutoff_hz: fc },
    })
}

/// A joint-space law's gains [K_a; K_b] under `controller.<law>` (one of each per joint of an
/// `n`-joint arm, finite and >= 0) with their bounds; `names` are the two gain keys.
pub(crate) fn joint_gains(
    check: &Check,
    law: &str,
    n: usize,
    names: [&str; 2],
    gains: [Vec<f64>; 2],
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
) -> Result<Tunable, ConfigError> {
    let key = format!("controller.{law}");
    for (k, v) in names.iter().zip(&gains) {
        if v.len() != n {
            return check.fail(
                &format!("{key}.{k}"),
                format!("needs {n} values (one per joint), got {}", v.len()),
            );
        }
        for (i, x) in v.iter().enumerate() {
            if !x.is_finite() || *x < 0.0 {
                return check.fail(
                    &format!("{key}.{k}[{i}]"),
                    format!("must be a finite gain >= 0 (got {x})"),
                );
            }
        }
    }
    let [a, b] = gains;
    check.tunable(&key, a.into_iter().chain(b).collect(), lower, upper, 1e6)
}
