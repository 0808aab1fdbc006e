//! Scenario configuration: one TOML file per scenario in `config/`.
//!
//! Loading is two-stage. Serde reads the file into raw structs that refuse unknown keys and wrong
//! types; `validate` then checks ranges and cross-field rules and builds a `Scenario`. Every error
//! names the file, the key (as a dotted path) and the reason, like
//! `config/two_mass.toml: key `timing.period`: must be > 0 (got -0.01)`.

use crate::control::{Controller, ParamBounds, StateFeedback};
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
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlantKind {
    TwoMass,
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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawController {
    kind: ControllerKind,
    u_limit: Option<f64>,
    stale_after_periods: Option<u32>,
    state_feedback: Option<RawStateFeedback>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ControllerKind {
    StateFeedback,
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
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum ReferenceKind {
    Step,
    Square,
    Steps,
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
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OptimiserMode {
    /// Starts, listens to the streams, publishes nothing.
    Off,
    /// Publishes the configured parameter sets at their configured times.
    Schedule,
}

impl std::str::FromStr for OptimiserMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(OptimiserMode::Off),
            "schedule" => Ok(OptimiserMode::Schedule),
            _ => Err(format!(
                "unknown optimiser mode {s:?} (expected off or schedule)"
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
}

#[derive(Debug, Clone, Serialize)]
pub struct ControllerSpec {
    pub kind: ControllerKind,
    pub gains: Vec<f64>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub u_limit: Option<f64>,
    pub stale_after_periods: u32,
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
            PlantKind::TwoMass => {
                let mut p = TwoMass::new(
                    self.plant.m1,
                    self.plant.m2,
                    self.plant.spring,
                    self.plant.sensor,
                );
                p.x0 = self.plant.initial_positions;
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
        }
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

struct Validator {
    file: PathBuf,
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
        let plant = self.plant(raw.plant, &timing)?;
        let controller = self.controller(raw.controller, &plant)?;
        let reference = self.reference(raw.reference)?;
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

    fn plant(&self, p: RawPlant, timing: &Timing) -> Result<PlantSpec, ConfigError> {
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
        match p.kind {
            PlantKind::TwoMass => {
                let tm = p.two_mass.unwrap_or(RawTwoMass {
                    m1: None,
                    m2: None,
                    spring: None,
                    sensor: None,
                    initial_positions: None,
                    spring_times: None,
                    spring_values: None,
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
                    kind: p.kind,
                    step,
                    noise_std,
                    safe_command,
                    command_timeout_periods,
                    m1: self.range("plant.two_mass.m1", tm.m1.unwrap_or(1.0), 1e-6, 1e6)?,
                    m2: self.range("plant.two_mass.m2", tm.m2.unwrap_or(1.0), 1e-6, 1e6)?,
                    spring: self.range(
                        "plant.two_mass.spring",
                        tm.spring.unwrap_or(1.0),
                        1e-6,
                        1e6,
                    )?,
                    sensor: tm.sensor.unwrap_or_default(),
                    initial_positions: x0,
                    spring_schedule,
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

    fn controller(
        &self,
        c: RawController,
        plant: &PlantSpec,
    ) -> Result<ControllerSpec, ConfigError> {
        let u_limit = match c.u_limit {
            Some(l) => Some(self.positive("controller.u_limit", l)?),
            None => None,
        };
        let n_x = match plant.kind {
            PlantKind::TwoMass => 4,
        };
        match c.kind {
            ControllerKind::StateFeedback => {
                let Some(sf) = c.state_feedback else {
                    return self.fail(
                        "controller.state_feedback",
                        "missing table [controller.state_feedback] with `gains`",
                    );
                };
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
                for (i, g) in sf.gains.iter().enumerate() {
                    self.finite(&format!("controller.state_feedback.gains[{i}]"), *g)?;
                }
                let lower = sf.lower.unwrap_or_else(|| vec![-1e3; n]);
                let upper = sf.upper.unwrap_or_else(|| vec![1e3; n]);
                for (key, b) in [
                    ("controller.state_feedback.lower", &lower),
                    ("controller.state_feedback.upper", &upper),
                ] {
                    if b.len() != n {
                        return self.fail(key, format!("needs {n} values, got {}", b.len()));
                    }
                    for (i, v) in b.iter().enumerate() {
                        self.finite(&format!("{key}[{i}]"), *v)?;
                    }
                }
                for i in 0..n {
                    if lower[i] > upper[i] {
                        return self.fail(
                            &format!("controller.state_feedback.lower[{i}]"),
                            format!("lower bound {} is above upper bound {}", lower[i], upper[i]),
                        );
                    }
                    if sf.gains[i] < lower[i] || sf.gains[i] > upper[i] {
                        return self.fail(
                            &format!("controller.state_feedback.gains[{i}]"),
                            format!(
                                "{} is outside its bounds [{}, {}]",
                                sf.gains[i], lower[i], upper[i]
                            ),
                        );
                    }
                }
                let stale = c.stale_after_periods.unwrap_or(3);
                if stale == 0 {
                    return self.fail("controller.stale_after_periods", "must be >= 1");
                }
                Ok(ControllerSpec {
                    kind: c.kind,
                    gains: sf.gains,
                    lower,
                    upper,
                    u_limit,
                    stale_after_periods: stale,
                })
            }
        }
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
        match r.kind {
            ReferenceKind::Step => {
                self.unused("reference.period", r.period.is_some(), "by a step")?;
                self.unused("reference.times", r.times.is_some(), "by a step")?;
                self.unused("reference.values", r.values.is_some(), "by a step")?;
                self.unused("reference.offset", r.offset.is_some(), "by a step")?;
                Ok(Reference::Step {
                    amplitude: need("amplitude", r.amplitude)?,
                    start: self.range("reference.start", r.start.unwrap_or(0.0), 0.0, 1e9)?,
                })
            }
            ReferenceKind::Square => {
                self.unused("reference.times", r.times.is_some(), "by a square wave")?;
                self.unused("reference.values", r.values.is_some(), "by a square wave")?;
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
                for (k, present) in [
                    ("amplitude", r.amplitude.is_some()),
                    ("start", r.start.is_some()),
                    ("period", r.period.is_some()),
                    ("offset", r.offset.is_some()),
                ] {
                    self.unused(&format!("reference.{k}"), present, "by a step sequence")?;
                }
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
        Ok(OptimiserSpec {
            mode: ov.optimiser.or(o.mode).unwrap_or(OptimiserMode::Off),
            sync_period,
            nice,
            schedule,
        })
    }
}
