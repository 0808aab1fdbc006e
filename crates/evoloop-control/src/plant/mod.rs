//! Plant models and their numerical integration. A plant is a continuous-time model
//! x' = f(t, x, u), y = h(x); the simulator integrates it at a fixed step with RK4 and samples it
//! each control period, applying the latest command as a zero-order hold.
//!
//! The same `PlantSim` runs in the plant process, in the in-process simulation used by tests and
//! (in later issues) in the optimiser's model evaluations.

pub mod delay;
pub mod gill;
pub mod integrator;
pub mod linear;

pub use arm::Arm;
pub use delay::DelayLine;
pub use integrator::Rk4;
pub use linear::{LinearModel, MAX_LINEAR_STATES};
pub use two_mass::TwoMass;

use crate::check::{Check, ConfigError};
use crate::dynamics::Model;
use crate::msg::PlantState;
use crate::reference::Reference;
use crate::{MAX_JOINTS, MAX_STATES};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

// The plant registry: adding a plant is its module (the model, `Table`, `validate` and
// `impl PlantConfig`; see the book's "Extending evoloop") plus one line here.
crate::kinds! {
    family "plant", trait PlantConfig, context PlantContext<'_>;
    /// `plant.kind`: which plant a scenario simulates.
    pub enum PlantKind;
    /// A validated plant: the chosen kind's parameters.
    pub enum PlantModel;
    /// The `[plant]` table as read: the keys every plant shares and one table per kind.
    pub struct RawPlant {
        /// `plant.kind`: which plant the scenario simulates.
        pub kind: PlantKind,
        /// `plant.step`: the integration step, s (default: the control period or 1 ms, the
        /// shorter).
        pub step: Option<f64>,
        /// `plant.noise_std`: standard deviation of the additive output noise (default 0).
        pub noise_std: Option<f64>,
        /// `plant.safe_command`: the command applied when the controller falls silent or refuses a
        /// state (default 0).
        pub safe_command: Option<f64>,
        /// `plant.command_timeout_periods`: periods without a command before the plant applies the
        /// safe command (default 10, >= 1).
        pub command_timeout_periods: Option<u32>,
        /// `plant.publish_truth`: whether samples carry the simulator's truth fields (default true;
        /// not for an external plant).
        pub publish_truth: Option<bool>,
        /// `plant.sensor_delay`: samples the measurement lags the state (default 0, at most
        /// `MAX_SENSOR_DELAY`).
        pub sensor_delay: Option<u32>,
    };
    two_mass => TwoMass(TwoMassSpec),
    arm => Arm(ArmSpec),
    maglev => Maglev(MaglevParams),
    heater => Heater(HeaterSpec),
    arsinh => Arsinh(ArsinhSpec),
    lti => Lti(LtiSpec),
    external => External(ExternalSpec),
}

/// What a plant kind's configuration offers the rest of the system. Besides this, a kind's
/// module has `pub struct Table` (its `[plant.<kind>]` keys) and `pub fn validate`.
pub trait PlantConfig {
    /// The model to simulate, with these parameters.
    fn build(&self) -> Box<dyn Plant>;
    /// The rigid-body model, for arms (joint-space controllers need it).
    fn rigid_body(&self) -> Option<&Model> {
        None
    }
    /// The linearisation state feedback is checked against, where the plant has one.
    fn linear_model(&self) -> Option<LinearModel> {
        None
    }
    /// The linear model with the varying parameter (`varying_parameter`) at `p` instead of its
    /// nominal value: what a controller checks new sets on once it has an estimate of `p`.
    /// Allocation-free (called in the control cycle).
    fn linear_model_at(&self, _p: f64) -> Option<LinearModel> {
        None
    }
    /// For single-input plants: the actuator's range and the input that holds the plant at its
    /// operating point at t = 0 (where an integrator starts).
    fn scalar_input(&self) -> Option<ScalarInput> {
        None
    }
    /// The true value at time t of the parameter that may change in operation (the one an
    /// indirect scheme estimates), for reports; None if the plant has none.
    fn varying_parameter(&self, _t: f64) -> Option<f64> {
        None
    }
    /// When that parameter's schedule starts.
    fn first_change(&self) -> Option<f64> {
        None
    }
    /// The measured output's quantisation step (an encoder's length per count); 0 for none.
    fn quantisation(&self) -> f64 {
        0.0
    }
    /// Why this plant cannot run in realtime (a model that moves once a control period, while
    /// realtime splits a period where a command arrives); None if it can.
    fn realtime_refusal(&self) -> Option<String> {
        None
    }
    /// A plant that is the user's own process (`plant.kind = "external"`): what the launcher
    /// starts and how long the run waits for it. None for the plants evoloop simulates.
    fn external(&self) -> Option<&external::ExternalSpec> {
        None
    }
}

/// A single input as a controller must respect it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScalarInput {
    /// The actuator's range (lo, hi), in the input's unit.
    pub range: (f64, f64),
    /// The input that holds the plant at its operating point at t = 0, within `range`: where an
    /// integrator starts.
    pub hold: f64,
}

impl ScalarInput {
    /// The range [lo, hi], held at 0 (clipped into it): a plant whose operating point is its
    /// origin (a linear model, a process of the user's own).
    pub fn holding_zero(lo: f64, hi: f64) -> Self {
        Self {
            range: (lo, hi),
            hold: 0.0_f64.clamp(lo, hi),
        }
    }
}

/// `[plant.<kind>] u_min`, `u_max` (`table` is `plant.<kind>`): the actuator's range, one value
/// per input each (default unbounded), every lower bound below its upper.
pub(crate) fn input_range(
    check: &Check,
    table: &str,
    lo: Option<Vec<f64>>,
    hi: Option<Vec<f64>>,
    inputs: usize,
) -> Result<(Vec<f64>, Vec<f64>), ConfigError> {
    let read = |key: &str, v: Option<Vec<f64>>, default: f64| {
        let v = v.unwrap_or_else(|| vec![default; inputs]);
        if v.len() != inputs {
            return check.fail(
                &format!("{table}.{key}"),
                format!("needs {inputs} values (one per input), got {}", v.len()),
            );
        }
        Ok(v)
    };
    let lo = read("u_min", lo, f64::NEG_INFINITY)?;
    let hi = read("u_max", hi, f64::INFINITY)?;
    if let Some(i) = (0..inputs).find(|&i| lo[i].is_nan() || hi[i].is_nan() || lo[i] >= hi[i]) {
        return check.fail(
            &format!("{table}.u_min[{i}]"),
            format!("must be below u_max[{i}] (got {} and {})", lo[i], hi[i]),
        );
    }
    Ok((lo, hi))
}

/// A plant of `outputs` outputs follows one reference per output.
pub(crate) fn one_reference_per_output(
    check: &Check,
    reference: &Reference,
    outputs: usize,
) -> Result<(), ConfigError> {
    if reference.joints() != outputs {
        return check.fail(
            "reference",
            format!(
                "the plant has {outputs} output(s) and the reference {} joint(s): one reference \
                 per output",
                reference.joints()
            ),
        );
    }
    Ok(())
}

/// Most points in a parameter schedule (a spring constant, a mass) over a run.
pub const MAX_SCHEDULE: usize = 8;

/// The step of a step schedule (times strictly increasing, `Check::schedule`) in force at `t`:
/// the last one at or before it; None before the first.
pub fn step_at<T>(steps: &[(f64, T)], t: f64) -> Option<&T> {
    steps
        .iter()
        .take_while(|(ts, _)| t >= *ts)
        .last()
        .map(|s| &s.1)
}

/// What a plant kind's validation may look at besides its own table.
pub struct PlantContext<'a> {
    /// The integration step, s (validated: 0 < step <= period).
    pub step: f64,
    /// The control period, s.
    pub period: f64,
    /// The reference the run follows (one per output, for most plants).
    pub reference: &'a Reference,
    /// The run's duration, s (infinite for a run until stopped).
    pub duration: f64,
}

/// A validated plant: the simulation settings every plant shares, and its kind's parameters.
#[derive(Debug, Clone, serde::Serialize)]
pub struct PlantSpec {
    /// Integration step, s.
    pub step: f64,
    /// Standard deviation of the additive output noise.
    pub noise_std: f64,
    /// The command applied when the controller falls silent.
    pub safe_command: f64,
    /// Periods without a command before the plant applies `safe_command`.
    pub command_timeout_periods: u32,
    /// Whether the samples carry the simulator's truth (`x_true`, `q_true`, `qd_true`) for
    /// judging the run; false sends NaN there, as a real plant that has no truth to send, which
    /// proves that no law reads it.
    pub publish_truth: bool,
    /// Samples the measurement lags the state it is of (`plant.sensor_delay`): a sample's `y`
    /// is the reading of `sensor_delay` periods before (a transport or filter delay in the
    /// sensor chain). Simulated by the plants evoloop runs; declared by an external plant for
    /// its controller's estimator, which predicts across it.
    pub sensor_delay: u32,
    /// The kind's own parameters (its `[plant.<kind>]` table, validated).
    #[serde(flatten)]
    pub model: PlantModel,
}

/// The most samples a plant's measurement may lag (`plant.sensor_delay`): the estimators
/// predict across the delay every cycle, one model step a sample.
pub const MAX_SENSOR_DELAY: usize = 1000;

impl PlantSpec {
    /// Validate the `[plant]` table against the control period and the reference.
    pub fn validate(
        mut raw: RawPlant,
        check: &Check,
        period: f64,
        reference: &Reference,
        duration: f64,
    ) -> Result<PlantSpec, ConfigError> {
        let step = raw.step.unwrap_or(period.min(1e-3));
        check.positive("plant.step", step)?;
        if step > period {
            return check.fail(
                "plant.step",
                format!("integration step {step} s is longer than the control period {period} s"),
            );
        }
        if period / step > 1e5 {
            return check.fail("plant.step", "more than 1e5 sub-steps per period");
        }
        // Bounded as a reference value is: 1e300 passed here and a stall on that safe command
        // drove the state to 8e299.
        let max = crate::reference::MAX_VALUE;
        let noise_std = check.range("plant.noise_std", raw.noise_std.unwrap_or(0.0), 0.0, max)?;
        let safe_command = check.range(
            "plant.safe_command",
            raw.safe_command.unwrap_or(0.0),
            -max,
            max,
        )?;
        let command_timeout_periods = raw.command_timeout_periods.unwrap_or(10);
        if command_timeout_periods == 0 {
            return check.fail("plant.command_timeout_periods", "must be >= 1");
        }
        let publish_truth = raw.publish_truth.unwrap_or(true);
        if raw.publish_truth.is_some() && raw.kind == PlantKind::External {
            return check.fail(
                "plant.publish_truth",
                "an external plant's process decides what its samples carry (the plant contract)",
            );
        }
        let sensor_delay = raw.sensor_delay.unwrap_or(0);
        if sensor_delay as usize > MAX_SENSOR_DELAY {
            return check.fail(
                "plant.sensor_delay",
                format!("{sensor_delay} samples: at most {MAX_SENSOR_DELAY}"),
            );
        }
        let kind = raw.kind;
        let cx = PlantContext {
            step,
            period,
            reference,
            duration,
        };
        Ok(PlantSpec {
            step,
            noise_std,
            safe_command,
            command_timeout_periods,
            publish_truth,
            sensor_delay,
            model: raw.validate_kind(kind, check, &cx)?,
        })
    }

    /// Which kind of plant this is.
    pub fn kind(&self) -> PlantKind {
        self.model.kind()
    }

    /// The standard deviation of the measurement error a controller designs for: the additive
    /// noise and the quantisation step q (a uniform error of variance q² / 12) together.
    pub fn measurement_std(&self) -> f64 {
        let q = self.model.config().quantisation();
        (self.noise_std * self.noise_std + q * q / 12.0).sqrt()
    }

    /// The plant model, with the configured parameters.
    pub fn build(&self) -> Box<dyn Plant> {
        self.model.config().build()
    }

    /// The plant simulated as configured: its model, integration step, sensor (noise drawn
    /// from `seed`, delay) and whether samples carry the truth. The one recipe of the plant
    /// process and of the in-process simulation.
    pub fn simulation(&self, seed: u64) -> PlantSim {
        PlantSim::new(self.build(), self.step, self.noise_std, seed)
            .publishing_truth(self.publish_truth)
            .delaying(self.sensor_delay as usize)
    }
}

/// A continuous-time plant model.
pub trait Plant: Send {
    /// Dimension of the state vector x.
    fn n_states(&self) -> usize;
    /// Dimension of the input u.
    fn n_inputs(&self) -> usize;
    /// Dimension of the measured output y.
    fn n_outputs(&self) -> usize;
    /// Number of bodies/joints with a position and velocity.
    fn n_joints(&self) -> usize;
    /// x' = f(t, x, u), written into `dx`. Must not allocate.
    fn derivative(&self, t: f64, x: &[f64], u: &[f64], dx: &mut [f64]);
    /// Noise-free measured outputs y = h(x).
    fn output(&self, x: &[f64], y: &mut [f64]);
    /// Joint positions and velocities from the state.
    fn joints(&self, x: &[f64], q: &mut [f64], qd: &mut [f64]);
    /// Initial state.
    fn initial_state(&self, x: &mut [f64]);
    /// Hard constraints applied after every integration step (e.g. joint stops). Default: none.
    fn constrain(&self, _x: &mut [f64]) {}
    /// The measuring chain after the sensor noise (e.g. an ADC's quantisation). Default: none.
    fn measure(&self, _y: &mut [f64]) {}
    /// A plant that advances itself over `dt` with `u` held (a discrete-time map, once per
    /// control period, or an exact discretisation): advance the state in place and return true;
    /// `PlantSim::advance` then integrates nothing. Default: false (a continuous plant, integrated
    /// with RK4 from `derivative`).
    /// `t` is the time the span starts.
    fn map(&self, _t: f64, _x: &mut [f64], _u: &[f64], _dt: f64) -> bool {
        false
    }
}

/// A plant being simulated: the model plus all the buffers its integration needs, allocated once
/// (Model/Data split), so `advance` never allocates.
///
/// The heated block of the book's worked example, driven at 10 W: the block settles where
/// the ambient plus the power through the resistance to the ambient puts it.
///
/// ```
/// use evoloop_control::plant::{heater::HeaterSpec, PlantSim};
///
/// let spec = HeaterSpec {
///     c_element: 5.0,       // J/K
///     c_block: 50.0,        // J/K
///     r_element_block: 0.5, // K/W
///     r_block_ambient: 2.0, // K/W
///     ambient: 20.0,        // °C
///     p_max: 100.0,         // W
///     initial: 20.0,        // °C
/// };
/// let steady = spec.steady_state(10.0); // 20 + 10 W x 2 K/W = 40 °C
/// // RK4 in steps of at most 10 ms, no sensor noise (seed unused).
/// let mut sim = PlantSim::new(Box::new(spec), 0.01, 0.0, 1);
/// for _ in 0..2000 {
///     sim.advance(&[10.0], 1.0); // one second with 10 W held
/// }
/// assert!((sim.x[1] - steady).abs() < 1e-3, "block at {} °C", sim.x[1]);
/// ```
pub struct PlantSim {
    /// The model being simulated.
    pub plant: Box<dyn Plant>,
    /// The state, in the plant's documented order.
    pub x: Vec<f64>,
    /// The simulated time, s.
    pub t: f64,
    step: f64,
    rk: Rk4,
    noise: Option<(Normal<f64>, ChaCha8Rng)>,
    y_clean: Vec<f64>,
    publish_truth: bool,
    /// The sensor's readings of the last `sensor_delay` samples (`delaying`); none on time.
    readings: DelayLine<[f64; MAX_JOINTS]>,
    /// Whether a reading was taken: before one, the line holds no reading to give.
    read: bool,
}

impl PlantSim {
    /// `step` is the integration step (s); `noise_std` the standard deviation of additive output
    /// noise drawn from a ChaCha RNG seeded with `seed` (0 std = no noise, no RNG draws).
    pub fn new(plant: Box<dyn Plant>, step: f64, noise_std: f64, seed: u64) -> Self {
        let n = plant.n_states();
        let mut x = vec![0.0; n];
        plant.initial_state(&mut x);
        let noise = (noise_std > 0.0).then(|| {
            (
                Normal::new(0.0, noise_std).expect("noise std validated positive and finite"),
                ChaCha8Rng::seed_from_u64(seed),
            )
        });
        Self {
            y_clean: vec![0.0; plant.n_outputs()],
            plant,
            x,
            t: 0.0,
            step,
            rk: Rk4::new(n),
            noise,
            publish_truth: true,
            readings: DelayLine::new(0, [0.0; MAX_JOINTS]),
            read: false,
        }
    }

    /// Each sample's measurement is the reading of `samples` periods before (the sensor's
    /// delay, `plant.sensor_delay`; 0, the default, for none).
    pub fn delaying(mut self, samples: usize) -> Self {
        self.readings = DelayLine::new(samples, [0.0; MAX_JOINTS]);
        self
    }

    /// Samples carry the truth fields (true, the default) or NaN in them (`plant.publish_truth`).
    pub fn publishing_truth(mut self, publish: bool) -> Self {
        self.publish_truth = publish;
        self
    }

    /// Integrate over `dt` with the command `u` held constant (zero-order hold), in fixed
    /// sub-steps of at most `step`. The number of sub-steps depends only on dt and step, so the
    /// result is bit-for-bit reproducible.
    pub fn advance(&mut self, u: &[f64], dt: f64) {
        if dt <= 0.0 {
            return;
        }
        if self.plant.map(self.t, &mut self.x, u, dt) {
            self.t += dt;
            return;
        }
        let n = (dt / self.step - 1e-9).ceil().max(1.0) as usize;
        let h = dt / n as f64;
        for _ in 0..n {
            self.rk.step(self.plant.as_ref(), self.t, &mut self.x, u, h);
            self.plant.constrain(&mut self.x);
            self.t += h;
        }
    }

    /// Sample the plant into a state message: positions, velocities, the full state and the
    /// (noisy) measured outputs. Consumes noise draws only when noise is configured.
    pub fn sample(&mut self, seq: u64, stamp_ns: u64, u_applied: &[f64], msg: &mut PlantState) {
        let p = self.plant.as_ref();
        let (nx, nq, ny) = (p.n_states(), p.n_joints(), p.n_outputs());
        msg.seq = seq;
        msg.stamp_ns = stamp_ns;
        msg.t = self.t;
        msg.n_x = nx as u32;
        msg.n_q = nq as u32;
        msg.n_y = ny as u32;
        if self.publish_truth {
            msg.x_true[..nx.min(MAX_STATES)].copy_from_slice(&self.x[..nx.min(MAX_STATES)]);
            p.joints(&self.x, &mut msg.q_true[..nq], &mut msg.qd_true[..nq]);
        } else {
            msg.x_true[..nx.min(MAX_STATES)].fill(f64::NAN);
            msg.q_true[..nq].fill(f64::NAN);
            msg.qd_true[..nq].fill(f64::NAN);
        }
        p.output(&self.x, &mut self.y_clean);
        for i in 0..ny.min(MAX_JOINTS) {
            let e = match &mut self.noise {
                Some((dist, rng)) => dist.sample(rng),
                None => 0.0,
            };
            msg.y[i] = self.y_clean[i] + e;
        }
        p.measure(&mut msg.y[..ny.min(MAX_JOINTS)]);
        self.delay_reading(&mut msg.y[..ny.min(MAX_JOINTS)]);
        let nu = u_applied.len().min(MAX_JOINTS);
        msg.u_applied[..nu].copy_from_slice(&u_applied[..nu]);
    }

    /// Take the reading `y` into the delay line and leave in it the one of `sensor_delay`
    /// samples before; before a reading is that old, the first one (a sensor at rest before the
    /// run starts reads what it read first).
    fn delay_reading(&mut self, y: &mut [f64]) {
        if self.readings.is_empty() {
            return;
        }
        let mut now = [0.0; MAX_JOINTS];
        now[..y.len()].copy_from_slice(y);
        if !self.read {
            self.readings.fill(now);
            self.read = true;
        }
        y.copy_from_slice(&self.readings.push(now)[..y.len()]);
    }
}
