//! The `[timing]` table: mode, period, duration and the real-time requests.

use super::Overrides;
use crate::check::{Check, ConfigError};
use crate::rt::{WaitKind, WaitStrategy};
use serde::{Deserialize, Serialize};

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawTiming {
    pub mode: Option<Mode>,
    pub period: f64,
    /// Omitted: the run goes on until it is stopped (Ctrl-C, SIGTERM).
    pub duration: Option<f64>,
    pub spin_us: Option<u64>,
    pub lockstep_timeout: Option<f64>,
    pub phase: Option<f64>,
    pub fifo_priority: Option<i32>,
    pub plant_fifo_priority: Option<i32>,
    pub lock_memory: Option<bool>,
    pub controller_cpu: Option<usize>,
    pub plant_cpu: Option<usize>,
    pub measure_floor: Option<bool>,
    pub wait: Option<WaitKind>,
    pub wait_margin_us: Option<f64>,
}

/// How the plant, the controller and the optimiser keep time (`timing.mode`, `--mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// (The default only of a report built in code with `..Default::default()`; a scenario
    /// always names or defaults its own, and a report read back must have one.)
    #[default]
    Lockstep,
    /// The processes keep wall-clock time: the plant ticks on absolute deadlines and the
    /// controller wakes `phase` of a period after each sample (not reproducible run to run).
    Realtime,
}

/// The name a scenario, a report and the command line use: "lockstep" or "realtime".
impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Mode::Lockstep => "lockstep",
            Mode::Realtime => "realtime",
        })
    }
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

/// The validated `[timing]` table, with `--mode`, `--duration`, `--no-rt` and `--wait`
/// applied.
#[derive(Debug, Clone, Serialize)]
pub struct Timing {
    /// Lockstep or realtime: `--mode`, else `timing.mode`, else lockstep.
    pub mode: Mode,
    /// Control period in s, within [1e-5, 10].
    pub period: f64,
    /// Simulated seconds; infinite for a run that goes on until it is stopped
    /// (`until_stopped`), serialised as null.
    pub duration: f64,
    /// How long in us a waiting process polls before it blocks on an iceoryx2 event (default
    /// 50, at most 1 000 000); in lockstep each waiting place stops polling for a while when its
    /// polls go unanswered (`evoloop_ipc::Spin`).
    pub spin_us: u64,
    /// Longest wait in s for a peer's answer in lockstep (default 10): an optimiser that does
    /// not acknowledge within it stops pacing the loop, which goes on without it.
    pub lockstep_timeout: f64,
    /// Realtime: the fraction of a period after each plant sample at which the controller
    /// wakes, in [0, 0.95] (default 0.1).
    pub phase: f64,
    /// Realtime: the controller's SCHED_FIFO priority (1-99); None stays SCHED_OTHER (always
    /// under `--no-rt`).
    pub fifo_priority: Option<i32>,
    /// Realtime: the plant's SCHED_FIFO priority (1-99); None stays SCHED_OTHER (always
    /// under `--no-rt`).
    pub plant_fifo_priority: Option<i32>,
    /// Realtime: the controller and the plant ask for `mlockall` (default false; false under
    /// `--no-rt`).
    pub lock_memory: bool,
    /// Realtime: CPU the controller is pinned to; None without pinning or under `--no-rt`.
    pub controller_cpu: Option<usize>,
    /// Realtime: CPU the plant process is pinned to; None without pinning or under `--no-rt`.
    pub plant_cpu: Option<usize>,
    /// Realtime: after the run, measure a bare absolute-deadline loop at the same period,
    /// priority, CPU and wait strategy, as the machine's floor to compare with (default true).
    pub measure_floor: bool,
    /// How the realtime controller and plant wait for their deadlines (`timing.wait`,
    /// `timing.wait_margin_us`); the floor is measured with the same strategy.
    pub wait: WaitStrategy,
}

impl Timing {
    /// The longest wait for a peer while the run starts (the processes' start-up): the lockstep
    /// timeout, at least 10 s.
    pub fn start_timeout(&self) -> f64 {
        self.lockstep_timeout.max(10.0)
    }

    /// Whether the run goes on until it is stopped (no duration).
    pub fn until_stopped(&self) -> bool {
        self.duration == f64::INFINITY
    }

    /// How long the run goes, for people: "10 s" or "until stopped (Ctrl-C)".
    pub fn span(&self) -> String {
        if self.until_stopped() {
            "until stopped (Ctrl-C)".into()
        } else {
            format!("{} s", self.duration)
        }
    }

    /// The duration as JSON: null for a run until stopped.
    pub fn duration_s(&self) -> Option<f64> {
        (!self.until_stopped()).then_some(self.duration)
    }
}

/// `--duration`: seconds, or `forever` (also `inf`) for a run until it is stopped.
pub fn parse_duration(s: &str) -> Result<f64, DurationError> {
    match s {
        "forever" | "inf" => Ok(f64::INFINITY),
        _ => match s.parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
            _ => Err(DurationError(s.to_string())),
        },
    }
}

/// A `--duration` that is neither a number of seconds > 0 nor `forever`: the text given.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DurationError(pub String);

impl std::fmt::Display for DurationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{:?}: a number of seconds > 0, or `forever` (until Ctrl-C)",
            self.0
        )
    }
}

impl std::error::Error for DurationError {}

pub fn validate(t: RawTiming, check: &Check, ov: &Overrides) -> Result<Timing, ConfigError> {
    let period = check.range("timing.period", t.period, 1e-5, 10.0)?;
    let duration = ov.duration.or(t.duration).unwrap_or(f64::INFINITY);
    let key_d = if ov.duration.is_some() {
        "--duration"
    } else {
        "timing.duration"
    };
    // Infinity is the one non-finite value allowed: no duration, a run until stopped.
    if duration != f64::INFINITY {
        check.positive(key_d, duration)?;
        if duration / period > 1e8 {
            return check.fail(
                key_d,
                format!("{duration} s at a {period} s period is over 1e8 cycles (for longer, omit the duration or pass `--duration forever`: the run goes on until Ctrl-C)"),
            );
        }
    }
    if duration < period {
        return check.fail(key_d, format!("shorter than one period ({period} s)"));
    }
    // A SCHED_FIFO priority.
    let prio = |key: &str, p: Option<i32>| p.map(|v| check.count(key, v, 1, 99)).transpose();
    let spin_us = t.spin_us.unwrap_or(50);
    if spin_us > 1_000_000 {
        return check.fail("timing.spin_us", format!("at most 1000000 (got {spin_us})"));
    }
    let rt = !ov.no_rt;
    let wait = wait_strategy(&t, check, ov, period)?;
    Ok(Timing {
        mode: ov.mode.or(t.mode).unwrap_or(Mode::Lockstep),
        period,
        duration,
        spin_us,
        lockstep_timeout: check.range(
            "timing.lockstep_timeout",
            t.lockstep_timeout.unwrap_or(10.0),
            0.01,
            3600.0,
        )?,
        phase: check.range("timing.phase", t.phase.unwrap_or(0.1), 0.0, 0.95)?,
        fifo_priority: prio("timing.fifo_priority", t.fifo_priority)?.filter(|_| rt),
        plant_fifo_priority: prio("timing.plant_fifo_priority", t.plant_fifo_priority)?
            .filter(|_| rt),
        lock_memory: t.lock_memory.unwrap_or(false) && rt,
        controller_cpu: t.controller_cpu.filter(|_| rt),
        plant_cpu: t.plant_cpu.filter(|_| rt),
        measure_floor: t.measure_floor.unwrap_or(true),
        wait,
    })
}

/// Default hybrid margin: 100 us, which covers this VM's sleep wake-up p99.9 under SCHED_FIFO
/// (`evoloop floor --fifo 80`), and at most 80 % of the period so a fast loop still sleeps a
/// little each cycle.
pub fn default_margin_us(period: f64) -> f64 {
    100.0f64.min(0.8 * period * 1e6)
}

fn wait_strategy(
    t: &RawTiming,
    check: &Check,
    ov: &Overrides,
    period: f64,
) -> Result<WaitStrategy, ConfigError> {
    // The file is checked as written; `--wait` may then choose another strategy, which leaves
    // the file's hybrid margin unused rather than wrong.
    let file_kind = t.wait.unwrap_or_default();
    let kind = ov.wait.unwrap_or(file_kind);
    let margin_us = match t.wait_margin_us {
        Some(m) => {
            if file_kind != WaitKind::Hybrid {
                return check.fail(
                    "timing.wait_margin_us",
                    format!(
                        "only for timing.wait = \"hybrid\" (the wait is {:?})",
                        file_kind.name()
                    ),
                );
            }
            check.range("timing.wait_margin_us", m, 1.0, period * 1e6)?
        }
        None => default_margin_us(period),
    };
    Ok(WaitStrategy::new(kind, margin_us))
}
