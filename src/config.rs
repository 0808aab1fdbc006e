//! Scenario configuration: one TOML file per scenario in `config/`.
//!
//! Loading is two-stage. Serde reads the file into raw structs that refuse unknown keys and wrong
//! types; `validate` then checks ranges and cross-field rules and builds a `Scenario`. Every error
//! names the file, the key (as a dotted path) and the reason, like
//! `config/two_mass.toml: key `timing.period`: must be > 0 (got -0.01)`.

use crate::control::{ComputedTorque, Controller, ParamBounds, PdServo, StateFeedback};
use crate::dynamics::Model;
use crate::ipc::MAX_SYNC_SAMPLES;
use crate::plant::two_mass::{Sensor, TwoMass};
use crate::plant::Plant;
use crate::reference::Reference;
use crate::rt::RtRequest;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};

/// A configuration error: file, key and reason.
#[derive(Debug, Clone, PartialEq)]
pub struct ConfigError {
    pub file: PathBuf,
    /// Dotted key path (`plant.two_mass.spring`); empty for file-level errors.
    pub key: String,
    pub reason: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if !self.key.is_empty() {
            write!(f, ": key `{}`", self.key)?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for ConfigError {}

// ---------------------------------------------------------------- raw file structure

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    seed: Option<u64>,
    plant: RawPlant,
    controller: RawController,
    reference: RawReference,
    timing: RawTiming,
    optimiser: Option<RawOptimiser>,
    output: Option<RawOutput>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPlant {
    kind: PlantKind,
    step: Option<f64>,
    noise_std: Option<f64>,
    safe_command: Option<f64>,
    command_timeout_periods: Option<u32>,
    two_mass: Option<RawTwoMass>,
    arm: Option<RawArm>,
    maglev: Option<RawMaglev>,
}

/// The magnetic-levitation plant (src/plant/maglev.rs documents the model and its numbers).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaglev {
    mass: Option<f64>,
    hold_current: Option<f64>,
    i_max: Option<f64>,
    tau: Option<f64>,
    sensor_range_mm: Option<f64>,
    mass_times: Option<Vec<f64>>,
    mass_values: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    TwoMass,
    /// A rigid-body arm from a D-H table or URDF file.
    Arm,
    /// The fuzzy-network paper's magnetic levitation (output mm, input mA).
    Maglev,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawArm {
    /// D-H TOML or URDF, relative to the scenario file.
    robot: PathBuf,
    initial_q: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTwoMass {
    m1: Option<f64>,
    m2: Option<f64>,
    spring: Option<f64>,
    sensor: Option<Sensor>,
    initial_positions: Option<[f64; 2]>,
    spring_times: Option<Vec<f64>>,
    spring_values: Option<Vec<f64>>,
    resolution: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawController {
    kind: ControllerKind,
    u_limit: Option<f64>,
    stale_after_periods: Option<u32>,
    state_feedback: Option<RawStateFeedback>,
    pd_servo: Option<RawJointGains>,
    computed_torque: Option<RawJointGains>,
    pid: Option<RawPid>,
}

/// The PID of eq. 26 with its anti-windup scheme.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawPid {
    anti_windup: crate::control::AntiWindup,
    params: Vec<f64>,
    initial_integral: Option<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    StateFeedback,
    /// Joint P-D servo (RKGNN paper's "actual controller").
    PdServo,
    /// Computed torque with a rigid-body model.
    ComputedTorque,
    /// PID (eq. 26) with fuzzy, clamping, back-calculation or no anti-windup.
    Pid,
}

/// Per-joint gains of the P-D servo (`kp`, `kd`) and of computed torque (`kp`, `kv`, plus the
/// start-up damping rate and an optional model file other than the plant's robot).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawJointGains {
    kp: Vec<f64>,
    kd: Option<Vec<f64>>,
    kv: Option<Vec<f64>>,
    startup_rate: Option<f64>,
    model: Option<PathBuf>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawStateFeedback {
    gains: Vec<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawReference {
    kind: ReferenceKind,
    amplitude: Option<f64>,
    start: Option<f64>,
    period: Option<f64>,
    offset: Option<f64>,
    times: Option<Vec<f64>>,
    values: Option<Vec<f64>>,
    waypoints: Option<Vec<Vec<f64>>>,
    offsets: Option<Vec<f64>>,
    amplitudes: Option<Vec<Vec<f64>>>,
    frequencies: Option<Vec<f64>>,
    phases: Option<Vec<Vec<f64>>>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ReferenceKind {
    Step,
    Square,
    Steps,
    Quintic,
    Sines,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTiming {
    mode: Option<Mode>,
    period: f64,
    duration: f64,
    spin_us: Option<u64>,
    lockstep_timeout: Option<f64>,
    phase: Option<f64>,
    fifo_priority: Option<i32>,
    plant_fifo_priority: Option<i32>,
    lock_memory: Option<bool>,
    controller_cpu: Option<usize>,
    plant_cpu: Option<usize>,
    measure_floor: Option<bool>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Lockstep,
    Realtime,
}

impl std::str::FromStr for Mode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "lockstep" => Ok(Mode::Lockstep),
            "realtime" => Ok(Mode::Realtime),
            _ => Err(format!(
                "unknown mode {s:?} (expected lockstep or realtime)"
            )),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOptimiser {
    mode: Option<OptimiserMode>,
    sync_period: Option<f64>,
    nice: Option<i32>,
    schedule: Option<Vec<RawScheduled>>,
    margin: Option<f64>,
    evaluations_per_second: Option<f64>,
    epoch_evaluations: Option<usize>,
    threads: Option<usize>,
    cost_u_weight: Option<f64>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OptimiserMode {
    /// Starts, listens to the streams, publishes nothing.
    Off,
    /// Publishes the configured parameter sets at their configured times.
    Schedule,
    /// The indirect scheme: estimates the model online, tunes on it, publishes better sets.
    Indirect,
}

impl std::str::FromStr for OptimiserMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(OptimiserMode::Off),
            "schedule" => Ok(OptimiserMode::Schedule),
            "indirect" => Ok(OptimiserMode::Indirect),
            _ => Err(format!(
                "unknown optimiser mode {s:?} (expected off, schedule or indirect)"
            )),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScheduled {
    at: f64,
    values: Vec<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOutput {
    dir: Option<PathBuf>,
    plots: Option<bool>,
}

// ---------------------------------------------------------------- validated scenario

#[derive(Debug, Clone, Serialize)]
pub struct Scenario {
    pub source: PathBuf,
    pub name: String,
    pub seed: u64,
    pub plant: PlantSpec,
    pub controller: ControllerSpec,
    pub reference: Reference,
    pub timing: Timing,
    pub optimiser: OptimiserSpec,
    pub output: Output,
    /// What the robot files' loader warned about (physically dubious but simulable), for
    /// `evoloop check` and the launcher to print.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone, Serialize)]
pub struct PlantSpec {
    pub kind: PlantKind,
    pub step: f64,
    pub noise_std: f64,
    pub safe_command: f64,
    pub command_timeout_periods: u32,
    pub m1: f64,
    pub m2: f64,
    pub spring: f64,
    pub sensor: Sensor,
    pub initial_positions: [f64; 2],
    /// Spring-constant schedule (time, k), linearly interpolated; empty = constant `spring`.
    pub spring_schedule: Vec<(f64, f64)>,
    /// Two-mass position encoder resolution (0: ideal).
    pub resolution: f64,
    /// The arm, for `kind = "arm"`.
    pub arm: Option<ArmSpec>,
    /// The maglev, for `kind = "maglev"`.
    pub maglev: Option<crate::plant::maglev::MaglevParams>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ArmSpec {
    /// The robot file as resolved (relative to the scenario file).
    pub robot: PathBuf,
    pub model: Model,
    pub initial_q: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ControllerSpec {
    pub kind: ControllerKind,
    pub gains: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub u_limit: Option<f64>,
    pub stale_after_periods: u32,
    /// Computed torque: psi's rate per sample (0 = off).
    pub startup_rate: f64,
    /// Computed torque: the controller's model (the plant's robot unless `model` is given).
    pub model: Option<Model>,
    /// Arms: torque limit per joint (from the robot description; infinite where none).
    pub torque_limits: Vec<f64>,
    /// PID: the anti-windup scheme, the integrator's start value and the output range.
    pub anti_windup: Option<crate::control::AntiWindup>,
    pub initial_integral: f64,
    pub output_range: (f64, f64),
}

#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    pub mode: Mode,
    pub period: f64,
    pub duration: f64,
    pub spin_us: u64,
    pub lockstep_timeout: f64,
    pub phase: f64,
    pub fifo_priority: Option<i32>,
    pub plant_fifo_priority: Option<i32>,
    pub lock_memory: bool,
    pub controller_cpu: Option<usize>,
    pub plant_cpu: Option<usize>,
    pub measure_floor: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct ScheduledSet {
    pub at: f64,
    pub values: Vec<f64>,
}

#[derive(Debug, Clone, Serialize)]
pub struct OptimiserSpec {
    pub mode: OptimiserMode,
    pub sync_period: f64,
    pub nice: i32,
    pub schedule: Vec<ScheduledSet>,
    /// Indirect: publish when the candidate's model cost is below the in-service set's by this
    /// fraction.
    pub margin: f64,
    /// Indirect, lockstep: model evaluations per simulated second (paces the optimiser so a seeded
    /// run is reproducible).
    pub evaluations_per_second: f64,
    /// Indirect: evaluations per GA epoch on one model snapshot.
    pub epoch_evaluations: usize,
    /// Indirect: threads evaluating candidates.
    pub threads: usize,
    /// Weight of |u| in the per-repetition cost sum |e| + w sum |u| (eq. 31: 1/1000 per mA).
    pub cost_u_weight: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Output {
    pub dir: PathBuf,
    pub plots: bool,
}

/// Command-line overrides applied before validation.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    pub mode: Option<Mode>,
    pub duration: Option<f64>,
    pub seed: Option<u64>,
    pub out: Option<PathBuf>,
    pub optimiser: Option<OptimiserMode>,
    /// Drop every real-time privilege request (SCHED_FIFO, mlockall, pinning).
    pub no_rt: bool,
}

impl ControllerSpec {
    /// The `KIND_*` this controller's parameter sets carry (a PID's depends on its scheme).
    pub fn param_kind(&self) -> u32 {
        use crate::msg as m;
        match self.kind {
            ControllerKind::StateFeedback => m::KIND_STATE_FEEDBACK,
            ControllerKind::PdServo => m::KIND_PD_SERVO,
            ControllerKind::ComputedTorque => m::KIND_COMPUTED_TORQUE,
            ControllerKind::Pid => self
                .anti_windup
                .expect("validated: a PID has its anti-windup scheme")
                .kind(),
        }
    }
}

impl Scenario {
    /// Read, parse and validate a scenario file.
    pub fn load(path: &Path, ov: &Overrides) -> Result<Scenario, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
            file: path.to_path_buf(),
            key: String::new(),
            reason: format!("cannot read: {e}"),
            line: None,
        })?;
        Self::parse(&text, path, ov)
    }

    /// Parse and validate scenario text; `path` is used in messages and to name the run.
    pub fn parse(text: &str, path: &Path, ov: &Overrides) -> Result<Scenario, ConfigError> {
        let de = toml::Deserializer::new(text);
        let raw: RawScenario = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let inner = e.into_inner();
            let line = inner
                .span()
                .map(|s| text[..s.start.min(text.len())].lines().count().max(1));
            ConfigError {
                file: path.to_path_buf(),
                key: if key == "." { String::new() } else { key },
                reason: inner.message().to_string(),
                line,
            }
        })?;
        let mut v = Validator {
            file: path.to_path_buf(),
            warnings: Default::default(),
        };
        v.scenario(raw, path, ov)
    }

    /// Number of control cycles in the run.
    pub fn cycles(&self) -> u64 {
        (self.timing.duration / self.timing.period).round() as u64
    }

    /// Samples between two optimiser acknowledgements in lockstep.
    pub fn sync_samples(&self) -> u64 {
        ((self.optimiser.sync_period / self.timing.period).round() as u64).max(1)
    }

    pub fn period_ns(&self) -> u64 {
        (self.timing.period * 1e9).round() as u64
    }

    /// The plant model, with the configured parameters.
    pub fn build_plant(&self) -> Box<dyn Plant> {
        match self.plant.kind {
            PlantKind::Maglev => Box::new(crate::plant::maglev::Maglev::new(
                self.plant
                    .maglev
                    .clone()
                    .expect("validated: maglev plants have parameters"),
            )),
            PlantKind::Arm => {
                let arm = self
                    .plant
                    .arm
                    .as_ref()
                    .expect("validated: arm plants have [plant.arm]");
                Box::new(crate::plant::Arm::new(arm.model.clone(), &arm.initial_q))
            }
            PlantKind::TwoMass => {
                let mut p = TwoMass::new(
                    self.plant.m1,
                    self.plant.m2,
                    self.plant.spring,
                    self.plant.sensor,
                );
                p.x0 = self.plant.initial_positions;
                p.resolution = self.plant.resolution;
                Box::new(p.with_spring_schedule(&self.plant.spring_schedule))
            }
        }
    }

    /// The controller with the configured initial parameters.
    pub fn build_controller(&self) -> Box<dyn Controller> {
        match self.controller.kind {
            ControllerKind::StateFeedback => Box::new(StateFeedback::new(
                &self.controller.gains,
                self.timing.period,
                self.controller.u_limit,
            )),
            ControllerKind::PdServo => Box::new(PdServo::new(
                &self.controller.gains,
                &self.controller.torque_limits,
            )),
            ControllerKind::Pid => Box::new(crate::control::Pid::new(
                self.controller
                    .anti_windup
                    .expect("validated: a PID has its scheme"),
                &self.controller.gains,
                self.timing.period,
                self.controller.output_range,
                self.controller.initial_integral,
            )),
            ControllerKind::ComputedTorque => Box::new(ComputedTorque::new(
                self.controller
                    .model
                    .clone()
                    .expect("validated: computed torque has a model"),
                &self.controller.gains,
                self.controller.startup_rate,
            )),
        }
    }

    /// The linear model new state-feedback gains are checked against (the configured two-mass
    /// plant at its nominal spring constant); None for other plants and controllers.
    pub fn linear_model(&self) -> Option<crate::control::LinearModel> {
        (self.plant.kind == PlantKind::TwoMass
            && self.controller.kind == ControllerKind::StateFeedback)
            .then(|| {
                TwoMass::new(
                    self.plant.m1,
                    self.plant.m2,
                    self.plant.spring,
                    self.plant.sensor,
                )
                .linear_model()
            })
    }

    pub fn bounds(&self) -> ParamBounds {
        ParamBounds {
            lower: self.controller.lower.clone(),
            upper: self.controller.upper.clone(),
        }
    }

    pub fn controller_rt(&self) -> RtRequest {
        RtRequest {
            fifo_priority: self.timing.fifo_priority,
            lock_memory: self.timing.lock_memory,
            cpu: self.timing.controller_cpu,
        }
    }

    pub fn plant_rt(&self) -> RtRequest {
        RtRequest {
            fifo_priority: self.timing.plant_fifo_priority,
            lock_memory: self.timing.lock_memory,
            cpu: self.timing.plant_cpu,
        }
    }
}

/// Gains, lower bounds, upper bounds.
type GainsAndBounds = (Vec<f64>, Vec<f64>, Vec<f64>);

struct Validator {
    file: PathBuf,
    /// Robot-file warnings met while validating (interior mutability: the checks take `&self`).
    warnings: std::cell::RefCell<Vec<String>>,
}

impl Validator {
    fn fail<T>(&self, key: &str, reason: impl Into<String>) -> Result<T, ConfigError> {
        Err(ConfigError {
            file: self.file.clone(),
            key: key.to_string(),
            reason: reason.into(),
            line: None,
        })
    }

    fn positive(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if !v.is_finite() || v <= 0.0 {
            return self.fail(key, format!("must be a finite number > 0 (got {v})"));
        }
        Ok(v)
    }

    fn finite(&self, key: &str, v: f64) -> Result<f64, ConfigError> {
        if !v.is_finite() {
            return self.fail(key, format!("must be finite (got {v})"));
        }
        Ok(v)
    }

    fn range(&self, key: &str, v: f64, lo: f64, hi: f64) -> Result<f64, ConfigError> {
        if !(v >= lo && v <= hi) {
            return self.fail(key, format!("must be within [{lo}, {hi}] (got {v})"));
        }
        Ok(v)
    }

    /// `v` has exactly `n` finite values (`what` says what they are per, e.g. " (one per joint)").
    fn finite_values(&self, key: &str, v: &[f64], n: usize, what: &str) -> Result<(), ConfigError> {
        if v.len() != n {
            return self.fail(key, format!("needs {n} values{what}, got {}", v.len()));
        }
        for (i, x) in v.iter().enumerate() {
            self.finite(&format!("{key}[{i}]"), *x)?;
        }
        Ok(())
    }

    fn unused(&self, key: &str, present: bool, why: &str) -> Result<(), ConfigError> {
        if present {
            return self.fail(key, format!("not used {why}; remove it"));
        }
        Ok(())
    }

    fn scenario(
        &mut self,
        raw: RawScenario,
        path: &Path,
        ov: &Overrides,
    ) -> Result<Scenario, ConfigError> {
        let name = raw.name.unwrap_or_else(|| {
            path.file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "scenario".into())
        });
        let timing = self.timing(raw.timing, ov)?;
        let reference = self.reference(raw.reference)?;
        let plant = self.plant(raw.plant, &timing, &reference, path)?;
        let controller = self.controller(raw.controller, &plant, path)?;
        let optimiser = self.optimiser(raw.optimiser, &timing, ov)?;
        let out_raw = raw.output.unwrap_or(RawOutput {
            dir: None,
            plots: None,
        });
        let output = Output {
            dir: ov
                .out
                .clone()
                .or(out_raw.dir)
                .unwrap_or_else(|| PathBuf::from("runs").join(&name)),
            plots: out_raw.plots.unwrap_or(true),
        };
        Ok(Scenario {
            source: path.to_path_buf(),
            name,
            seed: ov.seed.or(raw.seed).unwrap_or(1),
            plant,
            controller,
            reference,
            timing,
            optimiser,
            output,
            warnings: self.warnings.take(),
        })
    }

    fn timing(&self, t: RawTiming, ov: &Overrides) -> Result<Timing, ConfigError> {
        let period = self.range("timing.period", t.period, 1e-5, 10.0)?;
        let duration = ov.duration.unwrap_or(t.duration);
        let key_d = if ov.duration.is_some() {
            "--duration"
        } else {
            "timing.duration"
        };
        self.positive(key_d, duration)?;
        if duration / period > 1e8 {
            return self.fail(
                key_d,
                format!("{duration} s at a {period} s period is over 1e8 cycles"),
            );
        }
        if duration < period {
            return self.fail(key_d, format!("shorter than one period ({period} s)"));
        }
        let prio = |key: &str, p: Option<i32>| -> Result<Option<i32>, ConfigError> {
            match p {
                Some(v) if !(1..=99).contains(&v) => {
                    self.fail(key, format!("SCHED_FIFO priority must be 1..=99 (got {v})"))
                }
                _ => Ok(p),
            }
        };
        let spin_us = t.spin_us.unwrap_or(50);
        if spin_us > 1_000_000 {
            return self.fail("timing.spin_us", format!("at most 1000000 (got {spin_us})"));
        }
        let rt = !ov.no_rt;
        Ok(Timing {
            mode: ov.mode.or(t.mode).unwrap_or(Mode::Lockstep),
            period,
            duration,
            spin_us,
            lockstep_timeout: self.range(
                "timing.lockstep_timeout",
                t.lockstep_timeout.unwrap_or(10.0),
                0.01,
                3600.0,
            )?,
            phase: self.range("timing.phase", t.phase.unwrap_or(0.1), 0.0, 0.95)?,
            fifo_priority: prio("timing.fifo_priority", t.fifo_priority)?.filter(|_| rt),
            plant_fifo_priority: prio("timing.plant_fifo_priority", t.plant_fifo_priority)?
                .filter(|_| rt),
            lock_memory: t.lock_memory.unwrap_or(false) && rt,
            controller_cpu: t.controller_cpu.filter(|_| rt),
            plant_cpu: t.plant_cpu.filter(|_| rt),
            measure_floor: t.measure_floor.unwrap_or(true),
        })
    }

    /// A path from the config, relative to the scenario file's directory.
    fn resolve(scenario: &Path, rel: &Path) -> PathBuf {
        if rel.is_absolute() {
            rel.to_path_buf()
        } else {
            scenario.parent().unwrap_or(Path::new(".")).join(rel)
        }
    }

    /// A robot file named by `key`, loaded and checked; its errors keep their own file and item.
    fn robot(
        &self,
        key: &str,
        scenario: &Path,
        rel: &Path,
    ) -> Result<(PathBuf, Model), ConfigError> {
        let path = Self::resolve(scenario, rel);
        match crate::dynamics::load_with(&path, &Default::default()) {
            Ok(l) => {
                let mut w = self.warnings.borrow_mut();
                for x in l.warnings {
                    let line = format!("{}: {x}", path.display());
                    if !w.contains(&line) {
                        w.push(line);
                    }
                }
                Ok((path, l.model))
            }
            Err(e) => self.fail(key, format!("robot file does not load: {e}")),
        }
    }

    fn plant(
        &self,
        p: RawPlant,
        timing: &Timing,
        reference: &Reference,
        scenario: &Path,
    ) -> Result<PlantSpec, ConfigError> {
        let step = p.step.unwrap_or(timing.period.min(1e-3));
        self.positive("plant.step", step)?;
        if step > timing.period {
            return self.fail(
                "plant.step",
                format!(
                    "integration step {step} s is longer than the control period {} s",
                    timing.period
                ),
            );
        }
        if timing.period / step > 1e5 {
            return self.fail("plant.step", "more than 1e5 sub-steps per period");
        }
        let noise_std = p.noise_std.unwrap_or(0.0);
        if !noise_std.is_finite() || noise_std < 0.0 {
            return self.fail("plant.noise_std", format!("must be >= 0 (got {noise_std})"));
        }
        let safe_command = self.finite("plant.safe_command", p.safe_command.unwrap_or(0.0))?;
        let command_timeout_periods = p.command_timeout_periods.unwrap_or(10);
        if command_timeout_periods == 0 {
            return self.fail("plant.command_timeout_periods", "must be >= 1");
        }
        // Fields every plant kind shares; each kind fills in its own part.
        let base = PlantSpec {
            kind: p.kind,
            step,
            noise_std,
            safe_command,
            command_timeout_periods,
            m1: 0.0,
            m2: 0.0,
            spring: 0.0,
            sensor: Sensor::default(),
            initial_positions: [0.0; 2],
            spring_schedule: Vec::new(),
            resolution: 0.0,
            arm: None,
            maglev: None,
        };
        for (kind, name, present) in [
            (PlantKind::TwoMass, "two_mass", p.two_mass.is_some()),
            (PlantKind::Arm, "arm", p.arm.is_some()),
            (PlantKind::Maglev, "maglev", p.maglev.is_some()),
        ] {
            if kind != p.kind {
                self.unused(&format!("plant.{name}"), present, "by this plant kind")?;
            }
        }
        match p.kind {
            PlantKind::Maglev => {
                if reference.joints() != 1 {
                    return self.fail(
                        "reference",
                        "the maglev follows a scalar height reference (mm)",
                    );
                }
                let raw = p.maglev.unwrap_or(RawMaglev {
                    mass: None,
                    hold_current: None,
                    i_max: None,
                    tau: None,
                    sensor_range_mm: None,
                    mass_times: None,
                    mass_values: None,
                });
                let d = crate::plant::maglev::MaglevParams::default();
                let mg = crate::plant::maglev::MaglevParams {
                    mass: self.range("plant.maglev.mass", raw.mass.unwrap_or(d.mass), 0.01, 2.0)?,
                    hold_current: self.range(
                        "plant.maglev.hold_current",
                        raw.hold_current.unwrap_or(d.hold_current),
                        0.01,
                        100.0,
                    )?,
                    i_max: self.range(
                        "plant.maglev.i_max",
                        raw.i_max.unwrap_or(d.i_max),
                        0.01,
                        100.0,
                    )?,
                    tau: self.range("plant.maglev.tau", raw.tau.unwrap_or(d.tau), 1e-6, 1.0)?,
                    sensor_range_mm: self.range(
                        "plant.maglev.sensor_range_mm",
                        raw.sensor_range_mm.unwrap_or(d.sensor_range_mm),
                        0.1,
                        50.0,
                    )?,
                    mass_steps: self.schedule(
                        "plant.maglev.mass_times",
                        "plant.maglev.mass_values",
                        raw.mass_times,
                        raw.mass_values,
                    )?,
                    ..d
                };
                if step > mg.tau {
                    return self.fail("plant.step", format!("{step} s is longer than the coil lag tau = {} s; the RK4 step must resolve it", mg.tau));
                }
                Ok(PlantSpec {
                    maglev: Some(mg),
                    ..base
                })
            }
            PlantKind::Arm => {
                let Some(arm) = p.arm else {
                    return self.fail("plant.arm", "missing table [plant.arm] with `robot`");
                };
                let (robot, model) = self.robot("plant.arm.robot", scenario, &arm.robot)?;
                let n = model.dof();
                if reference.joints() != n {
                    return self.fail(
                        "reference",
                        format!(
                            "drives {} joint(s) but the robot `{}` has {n}; use a joint-space reference (quintic or sines) with {n} values per point",
                            reference.joints(),
                            model.name
                        ),
                    );
                }
                let initial_q = match arm.initial_q {
                    Some(q) => {
                        if q.len() != n {
                            return self.fail(
                                "plant.arm.initial_q",
                                format!("needs {n} values (one per joint), got {}", q.len()),
                            );
                        }
                        for (i, v) in q.iter().enumerate() {
                            let b = &model.bodies[i].limits;
                            self.range(&format!("plant.arm.initial_q[{i}]"), *v, b.q_min, b.q_max)?;
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
                Ok(PlantSpec {
                    arm: Some(ArmSpec {
                        robot,
                        model,
                        initial_q,
                    }),
                    ..base
                })
            }
            PlantKind::TwoMass => {
                if reference.joints() != 1 {
                    return self.fail(
                        "reference",
                        "the two-mass plant follows a scalar reference (step, square or steps)",
                    );
                }
                let tm = p.two_mass.unwrap_or(RawTwoMass {
                    m1: None,
                    m2: None,
                    spring: None,
                    sensor: None,
                    initial_positions: None,
                    spring_times: None,
                    spring_values: None,
                    resolution: None,
                });
                let spring_schedule = self.schedule(
                    "plant.two_mass.spring_times",
                    "plant.two_mass.spring_values",
                    tm.spring_times,
                    tm.spring_values,
                )?;
                let x0 = tm.initial_positions.unwrap_or([0.0; 2]);
                for (i, v) in x0.iter().enumerate() {
                    self.finite(&format!("plant.two_mass.initial_positions[{i}]"), *v)?;
                }
                Ok(PlantSpec {
                    m1: self.range("plant.two_mass.m1", tm.m1.unwrap_or(1.0), 1e-6, 1e6)?,
                    m2: self.range("plant.two_mass.m2", tm.m2.unwrap_or(1.0), 1e-6, 1e6)?,
                    spring: self.range(
                        "plant.two_mass.spring",
                        tm.spring.unwrap_or(1.0),
                        1e-6,
                        1e6,
                    )?,
                    sensor: tm.sensor.unwrap_or_default(),
                    resolution: self.range(
                        "plant.two_mass.resolution",
                        tm.resolution.unwrap_or(0.0),
                        0.0,
                        1.0,
                    )?,
                    initial_positions: x0,
                    spring_schedule,
                    ..base
                })
            }
        }
    }

    /// A (time, value) schedule from two arrays: same length, at most 8 points, times
    /// increasing, values positive.
    fn schedule(
        &self,
        key_t: &str,
        key_v: &str,
        times: Option<Vec<f64>>,
        values: Option<Vec<f64>>,
    ) -> Result<Vec<(f64, f64)>, ConfigError> {
        let (times, values) = match (times, values) {
            (None, None) => return Ok(Vec::new()),
            (Some(t), Some(v)) => (t, v),
            (Some(_), None) => return self.fail(key_v, "missing (required with its times)"),
            (None, Some(_)) => return self.fail(key_t, "missing (required with its values)"),
        };
        let max = crate::plant::two_mass::MAX_SCHEDULE;
        if times.is_empty() || times.len() > max || times.len() != values.len() {
            return self.fail(
                key_v,
                format!(
                    "needs 1..={max} entries, as many as the times ({} times, {} values)",
                    times.len(),
                    values.len()
                ),
            );
        }
        for i in 0..times.len() {
            self.range(&format!("{key_t}[{i}]"), times[i], 0.0, 1e9)?;
            self.range(&format!("{key_v}[{i}]"), values[i], 1e-6, 1e6)?;
            if i > 0 && times[i] <= times[i - 1] {
                return self.fail(
                    &format!("{key_t}[{i}]"),
                    "times must be strictly increasing",
                );
            }
        }
        Ok(times.into_iter().zip(values).collect())
    }

    /// A tunable gain vector with its bounds: finite, `n` values, lower <= gain <= upper.
    fn gains_in_bounds(
        &self,
        key: &str,
        gains: Vec<f64>,
        lower: Option<Vec<f64>>,
        upper: Option<Vec<f64>>,
        default_bound: f64,
    ) -> Result<GainsAndBounds, ConfigError> {
        let n = gains.len();
        for (i, g) in gains.iter().enumerate() {
            self.finite(&format!("{key}.gains[{i}]"), *g)?;
        }
        let lower = lower.unwrap_or_else(|| vec![-default_bound; n]);
        let upper = upper.unwrap_or_else(|| vec![default_bound; n]);
        for (k, b) in [("lower", &lower), ("upper", &upper)] {
            self.finite_values(&format!("{key}.{k}"), b, n, "")?;
        }
        for i in 0..n {
            if lower[i] > upper[i] {
                return self.fail(
                    &format!("{key}.lower[{i}]"),
                    format!("lower bound {} is above upper bound {}", lower[i], upper[i]),
                );
            }
            if gains[i] < lower[i] || gains[i] > upper[i] {
                return self.fail(
                    &format!("{key}.gains[{i}]"),
                    format!(
                        "{} is outside its bounds [{}, {}]",
                        gains[i], lower[i], upper[i]
                    ),
                );
            }
        }
        Ok((gains, lower, upper))
    }

    fn controller(
        &self,
        c: RawController,
        plant: &PlantSpec,
        scenario: &Path,
    ) -> Result<ControllerSpec, ConfigError> {
        let u_limit = match c.u_limit {
            Some(l) => Some(self.positive("controller.u_limit", l)?),
            None => None,
        };
        let stale = c.stale_after_periods.unwrap_or(3);
        if stale == 0 {
            return self.fail("controller.stale_after_periods", "must be >= 1");
        }
        let tables = [
            (
                ControllerKind::StateFeedback,
                "state_feedback",
                c.state_feedback.is_some(),
            ),
            (ControllerKind::PdServo, "pd_servo", c.pd_servo.is_some()),
            (ControllerKind::Pid, "pid", c.pid.is_some()),
            (
                ControllerKind::ComputedTorque,
                "computed_torque",
                c.computed_torque.is_some(),
            ),
        ];
        for (kind, name, present) in tables {
            if kind != c.kind {
                self.unused(
                    &format!("controller.{name}"),
                    present,
                    "by this controller kind",
                )?;
            }
        }
        let mut spec = ControllerSpec {
            kind: c.kind,
            gains: Vec::new(),
            lower: Vec::new(),
            upper: Vec::new(),
            u_limit,
            stale_after_periods: stale,
            startup_rate: 0.0,
            model: None,
            torque_limits: Vec::new(),
            anti_windup: None,
            initial_integral: 0.0,
            output_range: (f64::NEG_INFINITY, f64::INFINITY),
        };
        match c.kind {
            ControllerKind::Pid => {
                let Some(mg) = plant.maglev.as_ref() else {
                    return self.fail(
                        "controller.kind",
                        "the PID of eq. 26 drives the maglev plant (plant.kind = \"maglev\")",
                    );
                };
                let Some(pid) = c.pid else {
                    return self.fail(
                        "controller.pid",
                        "missing table [controller.pid] with `anti_windup` and `params`",
                    );
                };
                let aw = pid.anti_windup;
                let n = aw.n_params();
                if pid.params.len() != n {
                    return self.fail(
                        "controller.pid.params",
                        format!(
                            "{} anti-windup takes {n} values ({}), got {}",
                            aw.name(),
                            aw.param_names().join(", "),
                            pid.params.len()
                        ),
                    );
                }
                let (lo, hi) = aw.paper_ranges();
                (spec.gains, spec.lower, spec.upper) = self.gains_in_bounds(
                    "controller.pid",
                    pid.params,
                    Some(pid.lower.unwrap_or(lo)),
                    Some(pid.upper.unwrap_or(hi)),
                    0.0,
                )?;
                spec.anti_windup = Some(aw);
                spec.output_range = (0.0, 1000.0 * mg.i_max);
                spec.initial_integral = self.range(
                    "controller.pid.initial_integral",
                    pid.initial_integral
                        .unwrap_or(mg.hold_current_ma(mg.mass_at(0.0))),
                    0.0,
                    1000.0 * mg.i_max,
                )?;
            }
            ControllerKind::StateFeedback => {
                if plant.kind != PlantKind::TwoMass {
                    return self.fail("controller.kind", "state_feedback drives the two_mass plant; arms take pd_servo or computed_torque");
                }
                let Some(sf) = c.state_feedback else {
                    return self.fail(
                        "controller.state_feedback",
                        "missing table [controller.state_feedback] with `gains`",
                    );
                };
                let n_x = 4;
                let n = n_x + 1;
                if sf.gains.len() != n {
                    return self.fail(
                        "controller.state_feedback.gains",
                        format!(
                            "needs {n} values (the plant's {n_x} states and the integrator), got {}",
                            sf.gains.len()
                        ),
                    );
                }
                (spec.gains, spec.lower, spec.upper) = self.gains_in_bounds(
                    "controller.state_feedback",
                    sf.gains,
                    sf.lower,
                    sf.upper,
                    1e3,
                )?;
            }
            ControllerKind::PdServo | ControllerKind::ComputedTorque => {
                let (name, second, table) = if c.kind == ControllerKind::PdServo {
                    ("pd_servo", "kd", c.pd_servo)
                } else {
                    ("computed_torque", "kv", c.computed_torque)
                };
                let key = format!("controller.{name}");
                let Some(arm) = plant.arm.as_ref() else {
                    return self.fail(
                        "controller.kind",
                        format!("{name} drives an arm plant (plant.kind = \"arm\")"),
                    );
                };
                let Some(g) = table else {
                    return self.fail(
                        &key,
                        format!("missing table [{key}] with `kp` and `{second}`"),
                    );
                };
                let n = arm.model.dof();
                let (k2, other) = if c.kind == ControllerKind::PdServo {
                    (g.kd, g.kv.is_some().then_some("kv"))
                } else {
                    (g.kv, g.kd.is_some().then_some("kd"))
                };
                if let Some(o) = other {
                    return self.fail(
                        &format!("{key}.{o}"),
                        format!("unknown here: this controller takes `kp` and `{second}`"),
                    );
                }
                let Some(k2) = k2 else {
                    return self.fail(&format!("{key}.{second}"), "missing");
                };
                for (k, v) in [("kp", &g.kp), (second, &k2)] {
                    if v.len() != n {
                        return self.fail(
                            &format!("{key}.{k}"),
                            format!("needs {n} values (one per joint), got {}", v.len()),
                        );
                    }
                    for (i, x) in v.iter().enumerate() {
                        if !x.is_finite() || *x < 0.0 {
                            return self.fail(
                                &format!("{key}.{k}[{i}]"),
                                format!("must be a finite gain >= 0 (got {x})"),
                            );
                        }
                    }
                }
                let gains: Vec<f64> = g.kp.iter().chain(&k2).copied().collect();
                (spec.gains, spec.lower, spec.upper) =
                    self.gains_in_bounds(&key, gains, g.lower, g.upper, 1e6)?;
                spec.torque_limits = arm.model.bodies.iter().map(|b| b.limits.effort).collect();
                if c.kind == ControllerKind::ComputedTorque {
                    spec.startup_rate = self.range(
                        &format!("{key}.startup_rate"),
                        g.startup_rate.unwrap_or(0.03),
                        0.0,
                        10.0,
                    )?;
                    spec.model = Some(match g.model {
                        Some(rel) => {
                            let (_, m) = self.robot(&format!("{key}.model"), scenario, &rel)?;
                            if m.dof() != n {
                                return self.fail(
                                    &format!("{key}.model"),
                                    format!("has {} joints, the plant {n}", m.dof()),
                                );
                            }
                            m
                        }
                        None => arm.model.clone(),
                    });
                } else {
                    self.unused(
                        &format!("{key}.startup_rate"),
                        g.startup_rate.is_some(),
                        "by the P-D servo",
                    )?;
                    self.unused(
                        &format!("{key}.model"),
                        g.model.is_some(),
                        "by the P-D servo",
                    )?;
                }
            }
        }
        Ok(spec)
    }

    fn reference(&self, r: RawReference) -> Result<Reference, ConfigError> {
        let need = |key: &str, v: Option<f64>| -> Result<f64, ConfigError> {
            match v {
                Some(x) => self.finite(&format!("reference.{key}"), x),
                None => self.fail(
                    &format!("reference.{key}"),
                    "missing (required for this reference kind)",
                ),
            }
        };
        let present = [
            ("amplitude", r.amplitude.is_some()),
            ("start", r.start.is_some()),
            ("period", r.period.is_some()),
            ("offset", r.offset.is_some()),
            ("times", r.times.is_some()),
            ("values", r.values.is_some()),
            ("waypoints", r.waypoints.is_some()),
            ("offsets", r.offsets.is_some()),
            ("amplitudes", r.amplitudes.is_some()),
            ("frequencies", r.frequencies.is_some()),
            ("phases", r.phases.is_some()),
        ];
        let (kind_name, allowed): (&str, &[&str]) = match r.kind {
            ReferenceKind::Step => ("step", &["amplitude", "start"]),
            ReferenceKind::Square => ("square", &["amplitude", "period", "offset", "start"]),
            ReferenceKind::Steps => ("steps", &["times", "values"]),
            ReferenceKind::Quintic => ("quintic", &["times", "waypoints"]),
            ReferenceKind::Sines => ("sines", &["offsets", "amplitudes", "frequencies", "phases"]),
        };
        for (k, p) in present {
            if p && !allowed.contains(&k) {
                return self.fail(
                    &format!("reference.{k}"),
                    format!(
                        "not used by a `{kind_name}` reference (it takes {}); remove it",
                        allowed.join(", ")
                    ),
                );
            }
        }
        let joints = |key: &str, v: &[f64], n: usize| -> Result<(), ConfigError> {
            if n == 0 || n > crate::MAX_JOINTS {
                return self.fail(key, format!("1..={} joints, got {n}", crate::MAX_JOINTS));
            }
            self.finite_values(key, v, n, " (one per joint)")
        };
        match r.kind {
            ReferenceKind::Quintic => {
                let (Some(times), Some(waypoints)) = (r.times, r.waypoints) else {
                    return self.fail("reference.waypoints", "a quintic trajectory needs `times` and `waypoints` (one array of joint values per time)");
                };
                if times.len() < 2 || times.len() != waypoints.len() {
                    return self.fail(
                        "reference.waypoints",
                        format!(
                            "needs at least 2 waypoints, as many as `times` ({}), got {}",
                            times.len(),
                            waypoints.len()
                        ),
                    );
                }
                let n = waypoints[0].len();
                for (k, w) in waypoints.iter().enumerate() {
                    joints(&format!("reference.waypoints[{k}]"), w, n)?;
                }
                for i in 0..times.len() {
                    self.range(&format!("reference.times[{i}]"), times[i], 0.0, 1e9)?;
                    if i > 0 && times[i] <= times[i - 1] {
                        return self.fail(
                            &format!("reference.times[{i}]"),
                            "times must be strictly increasing",
                        );
                    }
                }
                Ok(Reference::Quintic { times, waypoints })
            }
            ReferenceKind::Sines => {
                let (Some(offsets), Some(amplitudes), Some(frequencies)) =
                    (r.offsets, r.amplitudes, r.frequencies)
                else {
                    return self.fail("reference.amplitudes", "a sum of sinusoids needs `offsets` (per joint), `amplitudes` (per joint, per frequency) and `frequencies` (Hz)");
                };
                let n = offsets.len();
                joints("reference.offsets", &offsets, n)?;
                if frequencies.is_empty() {
                    return self.fail("reference.frequencies", "needs at least one frequency");
                }
                for (h, f) in frequencies.iter().enumerate() {
                    self.range(&format!("reference.frequencies[{h}]"), *f, 0.0, 1e4)?;
                }
                let nh = frequencies.len();
                let phases = r.phases.unwrap_or_else(|| vec![vec![0.0; nh]; n]);
                for (key, m) in [("amplitudes", &amplitudes), ("phases", &phases)] {
                    if m.len() != n {
                        return self.fail(
                            &format!("reference.{key}"),
                            format!("needs {n} rows (one per joint), got {}", m.len()),
                        );
                    }
                    for (j, row) in m.iter().enumerate() {
                        self.finite_values(
                            &format!("reference.{key}[{j}]"),
                            row,
                            nh,
                            " (one per frequency)",
                        )?;
                    }
                }
                Ok(Reference::Sines {
                    offsets,
                    amplitudes,
                    frequencies,
                    phases,
                })
            }
            ReferenceKind::Step => Ok(Reference::Step {
                amplitude: need("amplitude", r.amplitude)?,
                start: self.range("reference.start", r.start.unwrap_or(0.0), 0.0, 1e9)?,
            }),
            ReferenceKind::Square => {
                let period = need("period", r.period)?;
                self.positive("reference.period", period)?;
                Ok(Reference::Square {
                    amplitude: need("amplitude", r.amplitude)?,
                    period,
                    offset: self.finite("reference.offset", r.offset.unwrap_or(0.0))?,
                    start: self.range("reference.start", r.start.unwrap_or(0.0), 0.0, 1e9)?,
                })
            }
            ReferenceKind::Steps => {
                let (Some(times), Some(values)) = (r.times, r.values) else {
                    return self.fail(
                        "reference.times",
                        "a step sequence needs `times` and `values` arrays",
                    );
                };
                if times.is_empty() || times.len() != values.len() {
                    return self.fail(
                        "reference.values",
                        format!(
                            "needs as many entries as `times` ({}), got {}",
                            times.len(),
                            values.len()
                        ),
                    );
                }
                for i in 0..times.len() {
                    self.finite(&format!("reference.times[{i}]"), times[i])?;
                    self.finite(&format!("reference.values[{i}]"), values[i])?;
                    if i > 0 && times[i] <= times[i - 1] {
                        return self.fail(
                            &format!("reference.times[{i}]"),
                            "times must be strictly increasing",
                        );
                    }
                }
                Ok(Reference::Steps { times, values })
            }
        }
    }

    fn optimiser(
        &self,
        o: Option<RawOptimiser>,
        timing: &Timing,
        ov: &Overrides,
    ) -> Result<OptimiserSpec, ConfigError> {
        let o = o.unwrap_or(RawOptimiser {
            mode: None,
            sync_period: None,
            nice: None,
            schedule: None,
            margin: None,
            evaluations_per_second: None,
            epoch_evaluations: None,
            threads: None,
            cost_u_weight: None,
        });
        // Default: an acknowledgement every 100 periods (a barrier costs two cross-process
        // wake-ups; rarer barriers let lockstep run at hundreds of thousands of samples/s).
        let sync_period = o.sync_period.unwrap_or(timing.period * 100.0);
        self.positive("optimiser.sync_period", sync_period)?;
        let samples = sync_period / timing.period;
        if samples < 1.0 - 1e-9 || samples > MAX_SYNC_SAMPLES as f64 {
            return self.fail(
                "optimiser.sync_period",
                format!(
                    "must be between 1 and {MAX_SYNC_SAMPLES} control periods (got {samples:.1})"
                ),
            );
        }
        let nice = o.nice.unwrap_or(10);
        if !(-20..=19).contains(&nice) {
            return self.fail(
                "optimiser.nice",
                format!("must be within -20..=19 (got {nice})"),
            );
        }
        let mut schedule = Vec::new();
        for (i, s) in o.schedule.unwrap_or_default().into_iter().enumerate() {
            let key = format!("optimiser.schedule[{i}]");
            // A set scheduled past the end of a (shortened) run is simply never published.
            self.range(&format!("{key}.at"), s.at, 0.0, 1e9)?;
            if i > 0 && s.at < schedule.last().map(|p: &ScheduledSet| p.at).unwrap_or(0.0) {
                return self.fail(&format!("{key}.at"), "schedule times must not decrease");
            }
            // The values are deliberately not range-checked here: the controller validates every
            // set it receives, and a scheduled bad set is how that path is exercised end to end.
            if s.values.is_empty() || s.values.len() > crate::MAX_PARAMS {
                return self.fail(
                    &format!("{key}.values"),
                    format!("needs 1..={} values", crate::MAX_PARAMS),
                );
            }
            schedule.push(ScheduledSet {
                at: s.at,
                values: s.values,
            });
        }
        let epoch_evaluations = o.epoch_evaluations.unwrap_or(150);
        if !(12..=100_000).contains(&epoch_evaluations) {
            return self.fail(
                "optimiser.epoch_evaluations",
                format!("must be 12..=100000 (got {epoch_evaluations})"),
            );
        }
        let threads = o.threads.unwrap_or(2);
        if !(1..=64).contains(&threads) {
            return self.fail(
                "optimiser.threads",
                format!("must be 1..=64 (got {threads})"),
            );
        }
        Ok(OptimiserSpec {
            mode: ov.optimiser.or(o.mode).unwrap_or(OptimiserMode::Off),
            sync_period,
            nice,
            schedule,
            margin: self.range("optimiser.margin", o.margin.unwrap_or(0.01), 0.0, 0.9)?,
            evaluations_per_second: self.range(
                "optimiser.evaluations_per_second",
                o.evaluations_per_second.unwrap_or(100.0),
                1.0,
                1e6,
            )?,
            epoch_evaluations,
            threads,
            cost_u_weight: self.range(
                "optimiser.cost_u_weight",
                o.cost_u_weight.unwrap_or(1e-3),
                0.0,
                1e6,
            )?,
        })
    }
}
