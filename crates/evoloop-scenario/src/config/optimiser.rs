//! The `[optimiser]` table. The modes' keys sit flat in it (files and scripts use them as they
//! are), and the modes' code (`node::optimiser`, `indirect`) builds on the scenario, so their
//! settings are validated here rather than next to that code.

use super::{Overrides, Timing};
use crate::check::{Check, ConfigError};
use crate::ipc::MAX_SYNC_SAMPLES;
use serde::{Deserialize, Serialize};

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawOptimiser {
    pub mode: Option<OptimiserMode>,
    pub sync_period: Option<f64>,
    pub nice: Option<i32>,
    pub schedule: Option<Vec<RawScheduled>>,
    pub margin: Option<f64>,
    pub evaluations_per_second: Option<f64>,
    pub epoch_evaluations: Option<usize>,
    pub threads: Option<usize>,
    pub cost_u_weight: Option<f64>,
    pub identify_window: Option<f64>,
    pub identify_fresh: Option<f64>,
    pub identify_every: Option<f64>,
    pub algorithm: Option<String>,
    pub population: Option<usize>,
    pub evaluations: Option<usize>,
    pub repetition: Option<f64>,
    pub first_repetition: Option<f64>,
    pub envelope_error: Option<f64>,
    pub envelope_output: Option<f64>,
    pub envelope_control: Option<f64>,
    pub cost_lag: Option<u32>,
    pub settle: Option<u32>,
    pub settle_band: Option<f64>,
    pub seed_configured: Option<bool>,
    pub phases: Option<[usize; 3]>,
    pub workers: Option<WorkersKind>,
    pub workers_listen: Option<String>,
    pub workers_zenoh_config: Option<std::path::PathBuf>,
    pub workers_expect: Option<usize>,
    /// `[optimiser.model]`, validated with the plant (`config::model_prior`).
    pub model: Option<super::model_prior::RawModel>,
    /// `[optimiser.nominal_plant]`, validated with the plant (`config::nominal_plant`).
    pub nominal_plant: Option<crate::plant::RawPlant>,
    /// `[[optimiser.nominal_alternatives]]`, validated with the plant
    /// (`config::nominal_alternatives`).
    pub nominal_alternatives: Option<Vec<crate::plant::RawPlant>>,
}

/// Where the optimiser's population evaluations run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum WorkersKind {
    /// On this process's threads (`optimiser.threads`).
    #[default]
    Local,
    /// Also on evaluation workers (`evoloop worker --connect ENDPOINT`) over Zenoh.
    Zenoh,
}

/// `optimiser.workers = "zenoh"`: where the optimiser meets its evaluation workers.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WorkersSpec {
    /// The Zenoh endpoint the optimiser listens on; workers give it to `--connect`.
    pub listen: String,
    /// A Zenoh configuration file (TLS, access control), resolved against the scenario file.
    pub zenoh_config: Option<std::path::PathBuf>,
    /// Workers to wait for (up to `WORKERS_WAIT_S`) before the first epoch; 0 starts at once
    /// and takes on workers as they come.
    pub expect: usize,
}

/// The longest the optimiser waits for `workers_expect` workers before going on without them:
/// it waits before its ports exist, within the plant's 10 s wait for its peers.
pub const WORKERS_WAIT_S: f64 = 8.0;
/// The default endpoint of `optimiser.workers_listen`: this host only.
pub const WORKERS_LISTEN: &str = "tcp/127.0.0.1:7448";

/// What the optimiser process does (`optimiser.mode`, `--optimiser`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum OptimiserMode {
    /// Starts, listens to the streams, publishes nothing.
    #[default]
    Off,
    /// Publishes the configured parameter sets at their configured times.
    Schedule,
    /// The indirect scheme: estimates the model online, tunes on it, publishes better sets.
    Indirect,
    /// The indirect scheme for arms (`rkgnn::live`): identifies a model on the latest window
    /// and publishes it when it predicts fresh data better than the model in service.
    Identify,
    /// The direct scheme (`direct`): every candidate tried on the plant for one repetition of
    /// the reference, under the safety envelope.
    Direct,
}

/// The name a scenario and a report use: `optimiser.mode`'s value.
impl std::fmt::Display for OptimiserMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            OptimiserMode::Off => "off",
            OptimiserMode::Schedule => "schedule",
            OptimiserMode::Indirect => "indirect",
            OptimiserMode::Identify => "identify",
            OptimiserMode::Direct => "direct",
        })
    }
}

impl std::str::FromStr for OptimiserMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "off" => Ok(OptimiserMode::Off),
            "schedule" => Ok(OptimiserMode::Schedule),
            "indirect" => Ok(OptimiserMode::Indirect),
            "identify" => Ok(OptimiserMode::Identify),
            "direct" => Ok(OptimiserMode::Direct),
            _ => Err(format!(
                "unknown optimiser mode {s:?} (expected off, schedule, indirect, identify or direct)"
            )),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawScheduled {
    pub at: f64,
    pub values: Option<Vec<f64>>,
    /// "gains" (default: the law's tunable parameters) or "model" (the law's model, e.g. a
    /// computed-torque controller's rigid-body parameters).
    pub kind: Option<SetKind>,
    /// Instead of `values`, a JSON file whose `model_parameters` are the values (a model set
    /// from `evoloop identify lls`), relative to the scenario file.
    pub file: Option<std::path::PathBuf>,
    /// "rejected": a set meant to exercise the controller's refusal (NaN, out of bounds, wrong
    /// length), not checked before the run; every other set is (default "accepted").
    pub expect: Option<Expect>,
}

/// What a scheduled set is meant to meet at the controller.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Expect {
    /// The controller is meant to take it: it is checked against the controller before the run.
    #[default]
    Accepted,
    /// The controller is meant to refuse it (NaN, out of bounds, wrong length): not checked
    /// before the run.
    Rejected,
}

/// What a scheduled set replaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum SetKind {
    /// The law's tunable parameters (gains).
    #[default]
    Gains,
    /// The law's model (a computed-torque controller's rigid-body parameters).
    Model,
}

/// One validated `[[optimiser.schedule]]` entry: a parameter set the optimiser publishes in
/// `schedule` mode.
#[derive(Debug, Clone, Serialize)]
pub struct ScheduledSet {
    /// Run time in s at which the optimiser publishes the set (lockstep: it applies at the
    /// sample of that time).
    pub at: f64,
    /// The set's parameters, from `values` or from the `model_parameters` of `file`
    /// (1 to `MAX_PARAMS` of them).
    pub values: Vec<f64>,
    /// Whether the set replaces the law's tunable parameters or its model.
    pub kind: SetKind,
    /// Whether the controller is meant to accept the set (checked before the run) or refuse it.
    pub expect: Expect,
}

/// The validated `[optimiser]` table: the optimiser process's mode and every mode's settings
/// (those of the modes not run are checked but unused).
#[derive(Debug, Clone, Serialize)]
pub struct OptimiserSpec {
    /// What the optimiser does: `--optimiser`, else `optimiser.mode`, else off.
    pub mode: OptimiserMode,
    /// Lockstep: s between two samples at which the plant waits for the optimiser's
    /// acknowledgement (1 to `MAX_SYNC_SAMPLES` periods; default 100 periods, or in the direct
    /// scheme the largest divisor of the repetition up to 100).
    pub sync_period: f64,
    /// Nice value of the optimiser process (-20 to 19, default 10), so it yields the CPU to the
    /// control loop.
    pub nice: i32,
    /// Schedule: the sets `[[optimiser.schedule]]` publishes, in time order.
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
    /// Identify: seconds of data each identification fits, the fresh seconds after them it is
    /// judged on, and the seconds between attempts.
    pub identify_window: f64,
    /// Identify: seconds of fresh data after the window that an identified model is judged on
    /// against the model in service (default 1).
    pub identify_fresh: f64,
    /// Identify: seconds between identification attempts (default 2).
    pub identify_every: f64,
    /// Direct: the optimiser (`optim::by_name::ALGORITHMS`), its population and the candidates it
    /// tries, one per repetition of `repetition` s, the first starting at `first_repetition` s
    /// (the repetition before it runs the configured set: the baseline).
    pub algorithm: String,
    /// Direct: the optimiser's population size (default 10, 4 to 10 000).
    pub population: usize,
    /// Direct: candidates the optimiser tries in all (default 310, at least `population`).
    pub evaluations: usize,
    /// Direct: length in s of one repetition of the reference, the time each candidate is
    /// tried for (default 1, a whole number of control periods).
    pub repetition: f64,
    /// Direct: start in s of the first trial's repetition (default `repetition`); the
    /// repetition before it runs the configured set, the baseline.
    pub first_repetition: f64,
    /// Direct: the envelope a candidate is aborted outside of.
    pub envelope: crate::law::cycle::Envelope,
    /// Direct: the output at sample k is judged against the reference `cost_lag` samples
    /// earlier (1 for the arsinh plant: eq. 25 compares x_{i+1} with w_i).
    pub cost_lag: u32,
    /// Direct: after each trial, up to this many repetitions under the set in service (its
    /// fallback) before the next trial starts, until the loop is back where that set leaves it
    /// (`settle_band`); 0: trials back to back, each starting where the last left the plant.
    /// Above 0 the controller also isolates each trial from the set in service
    /// (`ControlCycle::with_isolated_trials`).
    pub settle: u32,
    /// Direct: the loop has settled when a repetition under the set in service ends with its
    /// mean output and command (over its last 5 %) within this fraction of those of the last
    /// settle repetition the set served, each scaled by that repetition's peak |y| or |u|.
    pub settle_band: f64,
    /// Direct: the configured set is a member of the GA's initial population (it is tried
    /// again as a candidate, beside the baseline).
    pub seed_configured: bool,
    /// Direct, `algorithm = "hybrid"`: iterations of its three phases (GA; GA with Hooke-Jeeves on
    /// the scaling genes; Hooke-Jeeves on all), two evaluations each.
    pub phases: [usize; 3],
    /// Evaluation workers over Zenoh (`optimiser.workers = "zenoh"`); None: local threads only.
    pub workers: Option<WorkersSpec>,
    /// The general indirect scheme's prior (`[optimiser.model]`, lti and external plants).
    pub model: Option<super::model_prior::ModelPrior>,
    /// The nominal model of the plant as a plant of its own (`[optimiser.nominal_plant]`), the
    /// one `safe_bayes_model` predicts its trials on where it is not a transfer function.
    pub nominal_plant: Option<crate::plant::PlantSpec>,
    /// The plants the nominal model's tolerance allows besides it
    /// (`[[optimiser.nominal_alternatives]]`): `safe_bayes_model` predicts each trial's margin on
    /// every one of them too and believes the least.
    pub nominal_alternatives: Vec<crate::plant::PlantSpec>,
}

pub fn validate(
    o: Option<RawOptimiser>,
    check: &Check,
    timing: &Timing,
    ov: &Overrides,
) -> Result<OptimiserSpec, ConfigError> {
    let mut o = o.unwrap_or_default();
    let mode = ov.optimiser.or(o.mode).unwrap_or(OptimiserMode::Off);
    let sync_period = sync_period(&o, check, timing, mode)?;
    let nice = check.count("optimiser.nice", o.nice.unwrap_or(10), -20, 19)?;
    let schedule = schedule(o.schedule.take().unwrap_or_default(), check)?;
    let epoch_evaluations = o.epoch_evaluations.unwrap_or(150);
    check.count(
        "optimiser.epoch_evaluations",
        epoch_evaluations,
        12,
        100_000,
    )?;
    let threads = check.count("optimiser.threads", o.threads.unwrap_or(2), 1, 64)?;
    // The identification needs enough samples per window for its differences and fit; the
    // lower limits are in control periods and apply only when it runs.
    let periods = |k: f64| {
        if mode == OptimiserMode::Identify {
            k * timing.period
        } else {
            0.0
        }
    };
    let d = direct_settings(&o, check, timing, sync_period, mode)?;
    let workers = workers_settings(&o, check, ov, mode)?;
    let range = |key: &str, v: Option<f64>, default: f64, lo: f64, hi: f64| {
        check.range(&format!("optimiser.{key}"), v.unwrap_or(default), lo, hi)
    };
    Ok(OptimiserSpec {
        model: None,
        nominal_plant: None,
        nominal_alternatives: Vec::new(),
        workers,
        algorithm: d.algorithm,
        population: d.population,
        evaluations: d.evaluations,
        repetition: d.repetition,
        first_repetition: d.first_repetition,
        envelope: d.envelope,
        seed_configured: o.seed_configured.unwrap_or(false),
        phases: d.phases,
        cost_lag: check.count("optimiser.cost_lag", o.cost_lag.unwrap_or(0), 0, 16)?,
        settle: check.count("optimiser.settle", o.settle.unwrap_or(0), 0, 100)?,
        settle_band: range("settle_band", o.settle_band, 0.02, 1e-6, 1.0)?,
        mode,
        sync_period,
        nice,
        schedule,
        margin: range("margin", o.margin, 0.01, 0.0, 0.9)?,
        evaluations_per_second: range(
            "evaluations_per_second",
            o.evaluations_per_second,
            100.0,
            1.0,
            1e6,
        )?,
        epoch_evaluations,
        threads,
        cost_u_weight: range("cost_u_weight", o.cost_u_weight, 1e-3, 0.0, 1e6)?,
        // The identification's low-pass drops SMOOTHING at each end of both windows
        // (`Trajectory::trim`): at least 4 SMOOTHING leaves half of either to compare on.
        identify_window: range(
            "identify_window",
            o.identify_window,
            4.0,
            periods(50.0).max(4.0 * evoloop_rkgnn::SMOOTHING),
            600.0,
        )?,
        identify_fresh: range(
            "identify_fresh",
            o.identify_fresh,
            1.0,
            periods(20.0).max(4.0 * evoloop_rkgnn::SMOOTHING),
            600.0,
        )?,
        identify_every: range("identify_every", o.identify_every, 2.0, periods(1.0), 1e6)?,
    })
}

/// Default: an acknowledgement every 100 periods (a barrier costs two cross-process wake-ups;
/// rarer barriers let lockstep run at hundreds of thousands of samples/s). The direct scheme
/// decides at the sample before each repetition: its acknowledgements are shifted there
/// (`Scenario::is_sync_point`), every largest divisor of the repetition up to 100 periods.
fn sync_period(
    o: &RawOptimiser,
    check: &Check,
    timing: &Timing,
    mode: OptimiserMode,
) -> Result<f64, ConfigError> {
    let sync_period = o.sync_period.unwrap_or_else(|| {
        let rep = o
            .repetition
            .map_or(0, |r| (r / timing.period).round() as u64);
        let every = if mode == OptimiserMode::Direct && rep > 0 {
            (1..=100)
                .rev()
                .find(|d| rep.is_multiple_of(*d))
                .unwrap_or(1)
        } else {
            100
        };
        timing.period * every as f64
    });
    check.positive("optimiser.sync_period", sync_period)?;
    let samples = sync_period / timing.period;
    if samples < 1.0 - 1e-9 || samples > MAX_SYNC_SAMPLES as f64 {
        return check.fail(
            "optimiser.sync_period",
            format!("must be between 1 and {MAX_SYNC_SAMPLES} control periods (got {samples:.1})"),
        );
    }
    Ok(sync_period)
}

/// The scheduled sets, in time order. Their values are checked against the controller
/// (`config::compose`) unless the set is meant to be refused: a scheduled bad set is how that
/// path is exercised end to end.
fn schedule(raw: Vec<RawScheduled>, check: &Check) -> Result<Vec<ScheduledSet>, ConfigError> {
    let mut schedule: Vec<ScheduledSet> = Vec::new();
    for (i, s) in raw.into_iter().enumerate() {
        let key = format!("optimiser.schedule[{i}]");
        // A set scheduled past the end of a (shortened) run is simply never published.
        check.range(&format!("{key}.at"), s.at, 0.0, 1e9)?;
        if schedule.last().is_some_and(|p| s.at < p.at) {
            return check.fail(&format!("{key}.at"), "schedule times must not decrease");
        }
        let values = match (s.values, s.file) {
            (Some(v), None) => v,
            (None, Some(file)) => model_file(&check.resolve(&file))
                .or_else(|e| check.fail(&format!("{key}.file"), e))?,
            _ => {
                return check.fail(
                    &format!("{key}.values"),
                    "give either `values` or `file` (a JSON file with `model_parameters`)",
                )
            }
        };
        if values.is_empty() || values.len() > crate::msg::MAX_PARAMS {
            return check.fail(
                &format!("{key}.values"),
                format!("needs 1..={} values", crate::msg::MAX_PARAMS),
            );
        }
        schedule.push(ScheduledSet {
            at: s.at,
            values,
            kind: s.kind.unwrap_or_default(),
            expect: s.expect.unwrap_or_default(),
        });
    }
    Ok(schedule)
}

/// The evaluation workers' keys (and `--workers-listen`, `--workers-expect`).
fn workers_settings(
    o: &RawOptimiser,
    check: &Check,
    ov: &Overrides,
    mode: OptimiserMode,
) -> Result<Option<WorkersSpec>, ConfigError> {
    let kind = if ov.workers_listen.is_some() {
        WorkersKind::Zenoh
    } else {
        o.workers.unwrap_or_default()
    };
    if kind == WorkersKind::Local {
        let why = "without workers = \"zenoh\"";
        check.unused("optimiser.workers_listen", o.workers_listen.is_some(), why)?;
        let zenoh_config = o.workers_zenoh_config.is_some();
        check.unused("optimiser.workers_zenoh_config", zenoh_config, why)?;
        check.unused("optimiser.workers_expect", o.workers_expect.is_some(), why)?;
        return Ok(None);
    }
    // A build without the network refuses these workers where a scenario is loaded to run
    // (`evoloop_run::node::start::load`), so the loader stays the same in every build.
    // Off and schedule evaluate nothing: the key is harmless there (`--optimiser off` on a
    // scenario with workers). Direct evaluates on the plant itself and identify on the recorded
    // window, neither of which a worker has.
    if matches!(mode, OptimiserMode::Direct | OptimiserMode::Identify) {
        return check.fail(
            "optimiser.workers",
            format!(
                "\"zenoh\" serves the indirect scheme's model evaluations; mode \"{}\" evaluates {}",
                mode,
                if mode == OptimiserMode::Direct {
                    "on the plant itself"
                } else {
                    "on the recorded window, which does not travel"
                }
            ),
        );
    }
    let listen = ov
        .workers_listen
        .clone()
        .or_else(|| o.workers_listen.clone())
        .unwrap_or_else(|| WORKERS_LISTEN.to_string());
    if !listen.contains('/') {
        return check.fail(
            "optimiser.workers_listen",
            format!("{listen:?} is not a Zenoh endpoint (e.g. tcp/0.0.0.0:7448)"),
        );
    }
    let zenoh_config = match &o.workers_zenoh_config {
        Some(f) => {
            let p = check.resolve(f);
            if !p.is_file() {
                return check.fail(
                    "optimiser.workers_zenoh_config",
                    format!("{}: no such file", p.display()),
                );
            }
            Some(p)
        }
        None => None,
    };
    let expect = ov.workers_expect.or(o.workers_expect).unwrap_or(0);
    check.count("optimiser.workers_expect", expect, 0, 256)?;
    Ok(Some(WorkersSpec {
        listen,
        zenoh_config,
        expect,
    }))
}

/// The direct scheme's settings (`OptimiserSpec` has each under the same name).
struct DirectSettings {
    algorithm: String,
    population: usize,
    evaluations: usize,
    repetition: f64,
    first_repetition: f64,
    envelope: crate::law::cycle::Envelope,
    phases: [usize; 3],
}

/// The safe Bayesian optimiser with the plant's nominal model (`[optimiser.model]`) as its prior
/// mean (the schemes' `direct::model`).
pub const SAFE_BAYES_MODEL: &str = "safe_bayes_model";

/// The direct scheme's optimisers: the study's ask/tell ones, the GA/Hooke-Jeeves hybrid and
/// the model-informed safe Bayesian optimiser.
pub fn direct_algorithms() -> Vec<&'static str> {
    let mut a = crate::optim::by_name::all();
    a.extend(["hybrid", SAFE_BAYES_MODEL]);
    a
}

/// The direct scheme's keys: algorithm, population, evaluations, repetition, first repetition
/// and envelope. Checked whatever the mode (a typo should not wait for `mode = "direct"`);
/// the repetition's alignment with the samples and acknowledgements only when it runs.
fn direct_settings(
    o: &RawOptimiser,
    check: &Check,
    timing: &Timing,
    sync_period: f64,
    mode: OptimiserMode,
) -> Result<DirectSettings, ConfigError> {
    let algorithm = o.algorithm.clone().unwrap_or_else(|| "ga".into());
    if !direct_algorithms().contains(&algorithm.as_str()) {
        let known = direct_algorithms().join(", ");
        return check.fail(
            "optimiser.algorithm",
            format!("unknown algorithm {algorithm:?} (known: {known})"),
        );
    }
    let population = check.count(
        "optimiser.population",
        o.population.unwrap_or(10),
        4,
        10_000,
    )?;
    let evaluations = o.evaluations.unwrap_or(310);
    if !(population..=1_000_000).contains(&evaluations) {
        return check.fail(
            "optimiser.evaluations",
            format!("must be at least the population ({population}) and at most 1000000 (got {evaluations})"),
        );
    }
    let bound = |key: &str, v: Option<f64>| -> Result<f64, ConfigError> {
        match v {
            None => Ok(f64::INFINITY),
            Some(x) => check.range(key, x, 1e-12, 1e12),
        }
    };
    let envelope = crate::law::cycle::Envelope {
        error: bound("optimiser.envelope_error", o.envelope_error)?,
        output: bound("optimiser.envelope_output", o.envelope_output)?,
        control: bound("optimiser.envelope_control", o.envelope_control)?,
    };
    if (algorithm == "safe_bayes" || algorithm == SAFE_BAYES_MODEL)
        && [envelope.error, envelope.output, envelope.control]
            .iter()
            .all(|v| v.is_infinite())
    {
        return check.fail(
            "optimiser.algorithm",
            format!("{algorithm} models each trial's margin inside the envelope: set optimiser.envelope_error, envelope_output or envelope_control"),
        );
    }
    let repetition = o.repetition.unwrap_or(1.0);
    check.range("optimiser.repetition", repetition, timing.period, 1e6)?;
    let first = o.first_repetition.unwrap_or(repetition);
    check.range("optimiser.first_repetition", first, repetition, 1e9)?;
    if mode == OptimiserMode::Direct {
        aligned_repetitions(check, timing.period, sync_period, repetition, first)?;
    }
    let phases = hybrid_phases(o, check, &algorithm, population, evaluations)?;
    Ok(DirectSettings {
        algorithm,
        population,
        evaluations,
        repetition,
        first_repetition: first,
        envelope,
        phases,
    })
}

/// The direct scheme's repetitions start on a sample, and (lockstep) the optimiser decides at
/// the sample before each, which must be an acknowledgement: they come every sync_period,
/// shifted onto the first boundary.
fn aligned_repetitions(
    check: &Check,
    period: f64,
    sync_period: f64,
    repetition: f64,
    first: f64,
) -> Result<(), ConfigError> {
    let samples = |s: f64| s / period;
    let whole = |s: f64| (samples(s) - samples(s).round()).abs() < 1e-6;
    if !whole(repetition) || !whole(first) {
        return check.fail(
            "optimiser.repetition",
            format!(
                "repetition ({repetition} s) and first_repetition ({first} s) must be whole numbers of control periods ({period} s)"
            ),
        );
    }
    let sync = samples(sync_period).round() as u64;
    let rep = samples(repetition).round() as u64;
    if !rep.is_multiple_of(sync) {
        return check.fail(
            "optimiser.sync_period",
            format!(
                "the direct scheme decides at the sample before each repetition starts: sync_period ({sync} periods) must divide the repetition ({rep} periods); leave it out for the largest divisor up to 100"
            ),
        );
    }
    Ok(())
}

/// The hybrid's three phases, which spend two evaluations per iteration after its population.
fn hybrid_phases(
    o: &RawOptimiser,
    check: &Check,
    algorithm: &str,
    population: usize,
    evaluations: usize,
) -> Result<[usize; 3], ConfigError> {
    let phases = o
        .phases
        .unwrap_or([evaluations.saturating_sub(population) / 2, 0, 0]);
    if o.phases.is_some() && algorithm != "hybrid" {
        return check.fail(
            "optimiser.phases",
            "only the hybrid has phases (algorithm = \"hybrid\")",
        );
    }
    let spent = population + 2 * phases.iter().sum::<usize>();
    if algorithm == "hybrid" && spent != evaluations {
        return check.fail(
            "optimiser.evaluations",
            format!(
                "the hybrid with population {population} and phases {phases:?} tries {spent} candidates (population + 2 per iteration); set evaluations = {spent}"
            ),
        );
    }
    Ok(phases)
}

/// The `model_parameters` of a JSON file (`evoloop identify lls`'s lls.json).
fn model_file(path: &std::path::Path) -> Result<Vec<f64>, String> {
    let text = crate::files::read_text(path)
        .map_err(|e| format!("{}: cannot read: {e}", path.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    serde_json::from_value(v["model_parameters"].clone()).map_err(|_| {
        format!(
            "{}: no `model_parameters` array of numbers (write one with `evoloop identify lls` \
             on a run where every joint moves)",
            path.display()
        )
    })
}
