//! Scenario configuration: one TOML file per scenario in `config/`.
//!
//! Loading is two-stage. Serde reads the file into raw structs that refuse unknown keys and wrong
//! types; validation then checks ranges and cross-field rules and builds a `Scenario`. Every error
//! names the file, the key (as a dotted path) and the reason, like
//! `config/two_mass/two_mass.toml: key `timing.period`: must be > 0 (got -0.01)`.
//!
//! The loader keeps the shared tables (`[timing]`, `[reference]`, `[optimiser]`, `[output]`) and
//! composes the rest: each plant kind owns its `[plant.<kind>]` table in its module under
//! `plant/`, each control law its `[controller.<kind>]` table under `control/`, registered by
//! one line in `plant::kinds!` / `law::kinds!`.

mod model_prior;
mod optimiser;
mod reference;
mod timing;

pub use crate::check::ConfigError;
pub use crate::law::{ControllerKind, ControllerModel, ControllerSpec};
pub use crate::plant::{PlantKind, PlantModel, PlantSpec};
pub use model_prior::ModelPrior;
pub use optimiser::{
    Expect, OptimiserMode, OptimiserSpec, ScheduledSet, SetKind, WorkersKind, WorkersSpec,
    SAFE_BAYES_MODEL, WORKERS_WAIT_S,
};
pub use timing::{default_margin_us, parse_duration, DurationError, Mode, Timing};

use crate::check::Check;
use crate::law::{Controller, ParamBounds, RawController};
use crate::plant::{Plant, RawPlant};
use crate::reference::Reference;
use crate::rt::RtRequest;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

// ---------------------------------------------------------------- raw file structure

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    name: Option<String>,
    seed: Option<u64>,
    plant: RawPlant,
    controller: RawController,
    reference: reference::RawReference,
    timing: timing::RawTiming,
    optimiser: Option<optimiser::RawOptimiser>,
    output: Option<RawOutput>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOutput {
    dir: Option<PathBuf>,
    plots: Option<bool>,
    mcap: Option<bool>,
}

// ---------------------------------------------------------------- validated scenario

/// A scenario file, read and validated: every table checked, the command-line overrides
/// applied.
#[derive(Debug, Clone, Serialize)]
pub struct Scenario {
    /// Path of the scenario file it was loaded from, as given (named in messages).
    pub source: PathBuf,
    /// The run's name: the `name` key, else the file's stem (output goes to `runs/<name>`).
    pub name: String,
    /// Seed of every random number generator in the run: `--seed`, else `seed`, else 1.
    pub seed: u64,
    /// The validated `[plant]` table.
    pub plant: PlantSpec,
    /// The validated `[controller]` table.
    pub controller: ControllerSpec,
    /// The validated `[reference]` table: the setpoint the loop follows.
    pub reference: Reference,
    /// The validated `[timing]` table, with the command-line overrides applied.
    pub timing: Timing,
    /// The validated `[optimiser]` table, with its nominal plant, alternatives and model.
    pub optimiser: OptimiserSpec,
    /// The validated `[output]` table, with `--out` applied.
    pub output: Output,
    /// What the robot files' loader warned about (physically dubious but simulable), for
    /// `evoloop check` and the launcher to print.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
}

/// The validated `[output]` table: where a run's files go and which ones are written.
#[derive(Debug, Clone, Serialize)]
pub struct Output {
    /// Directory of the run's files: `--out`, else `output.dir`, else `runs/<name>`.
    pub dir: PathBuf,
    /// Draw the plots into `dir` (`output.plots`, default true).
    pub plots: bool,
    /// Record the run's messages into `run.mcap` (`report::record`).
    pub mcap: bool,
}

/// Command-line overrides applied before validation.
#[derive(Debug, Clone, Default)]
pub struct Overrides {
    /// `--mode`: lockstep or realtime, in place of `timing.mode`.
    pub mode: Option<Mode>,
    /// `--duration`: run length in simulated s, in place of `timing.duration`; infinite for
    /// `forever`.
    pub duration: Option<f64>,
    /// `--seed`: the seed of every random number generator, in place of the file's `seed`.
    pub seed: Option<u64>,
    /// `--out`: the output directory, in place of `output.dir`.
    pub out: Option<PathBuf>,
    /// `--optimiser`: the optimiser mode, in place of `optimiser.mode`.
    pub optimiser: Option<OptimiserMode>,
    /// Drop every real-time privilege request (SCHED_FIFO, mlockall, pinning).
    pub no_rt: bool,
    /// `--wait`: how the realtime loops wait for their deadlines.
    pub wait: Option<crate::rt::WaitKind>,
    /// `--workers-listen`: the optimiser takes evaluation workers on this Zenoh endpoint
    /// (`optimiser.workers = "zenoh"`).
    pub workers_listen: Option<String>,
    /// `--workers-expect`: the workers it waits for before its first epoch.
    pub workers_expect: Option<usize>,
}

/// Why a scenario or experiment file cannot be read. A path of the flat layout `config/` had
/// until 2026-12-06 (`config/maglev_direct.toml`) that is gone is answered with the file's place
/// in its plant's folder now, so a user's script or habit finds it.
pub fn unreadable(path: &Path, e: &std::io::Error) -> String {
    match regrouped(path) {
        Some(now) => format!(
            "cannot read: {e}; the shipped scenarios are in one folder per plant since \
             2026-12-06: {}",
            now.display()
        ),
        None => format!("cannot read: {e}"),
    }
}

/// `config/NAME` that is not there but `config/GROUP/NAME` is: the latter.
fn regrouped(path: &Path) -> Option<PathBuf> {
    let (dir, name) = (path.parent()?, path.file_name()?);
    if dir.file_name()? != "config" || path.exists() {
        return None;
    }
    // The plant folders and experiments/, not the files scenarios share (robots/, models/...).
    const SHARED: [&str; 6] = [
        "robots",
        "models",
        "plants",
        "excitation",
        "identified",
        "zenoh",
    ];
    let groups = std::fs::read_dir(dir).ok()?.flatten();
    let groups = groups.filter(|g| !SHARED.iter().any(|s| g.file_name() == *s));
    groups.map(|g| g.path().join(name)).find(|p| p.is_file())
}

impl Scenario {
    /// Read, parse and validate a scenario file.
    pub fn load(path: &Path, ov: &Overrides) -> Result<Scenario, ConfigError> {
        let text = crate::files::read_text(path).map_err(|e| ConfigError {
            file: path.to_path_buf(),
            key: String::new(),
            reason: unreadable(path, &e),
            line: None,
        })?;
        Self::parse(&text, path, ov)
    }

    /// Parse and validate scenario text; `path` is used in messages and to name the run.
    pub fn parse(text: &str, path: &Path, ov: &Overrides) -> Result<Scenario, ConfigError> {
        let raw: RawScenario = crate::files::from_toml(text).map_err(|p| ConfigError {
            file: path.to_path_buf(),
            key: p.key,
            reason: p.reason,
            line: p.line,
        })?;
        compose(raw, &Check::new(path), ov)
    }

    /// Whether evoloop simulates the plant (every kind but a process of the user's own).
    pub fn simulated(&self) -> bool {
        self.plant.model.config().external().is_none()
    }

    /// An in-process simulation simulates the plant and keeps every sample, so it refuses a
    /// plant of the user's own and a run until stopped.
    pub fn require_in_process(&self) -> Result<(), ConfigError> {
        let check = Check::new(&self.source);
        if !self.simulated() {
            return check.fail(
                "plant.kind",
                "\"external\" is simulated by its own process only: run it with `evoloop run`",
            );
        }
        if self.timing.until_stopped() {
            return check.fail(
                "timing.duration",
                "simulated in-process, the scenario needs a duration",
            );
        }
        Ok(())
    }

    /// Number of control cycles in the run.
    pub fn cycles(&self) -> u64 {
        (self.timing.duration / self.timing.period).round() as u64
    }

    /// Samples between two optimiser acknowledgements in lockstep.
    pub fn sync_samples(&self) -> u64 {
        ((self.optimiser.sync_period / self.timing.period).round() as u64).max(1)
    }

    /// Lockstep: whether the plant waits for the optimiser's acknowledgement at sample `k`
    /// (every `sync_samples`; the direct scheme shifts them onto the samples before its
    /// repetition boundaries, where it decides the next trial).
    pub fn is_sync_point(&self, k: u64) -> bool {
        k % self.sync_samples() == self.sync_offset()
    }

    /// Lockstep: the synchronisation points are the samples k with k % `sync_samples` equal to
    /// this (0 but in the direct scheme).
    pub fn sync_offset(&self) -> u64 {
        if self.optimiser.mode == OptimiserMode::Direct {
            let first = (self.optimiser.first_repetition / self.timing.period).round() as u64;
            (first - 1) % self.sync_samples()
        } else {
            0
        }
    }

    /// Lockstep: the first synchronisation point at or after sample `k`.
    pub fn next_sync_point(&self, k: u64) -> u64 {
        (k..k + self.sync_samples())
            .find(|&j| self.is_sync_point(j))
            .unwrap_or(k)
    }

    /// The control period in ns, rounded to the nearest one (the realtime loops' deadline step).
    pub fn period_ns(&self) -> u64 {
        (self.timing.period * 1e9).round() as u64
    }

    /// The plant model, with the configured parameters.
    pub fn build_plant(&self) -> Box<dyn Plant> {
        self.plant.build()
    }

    /// The controller with the configured initial parameters.
    pub fn build_controller(&self) -> Box<dyn Controller> {
        self.controller.build(self.timing.period)
    }

    /// The linear model new parameter sets must stabilise before use (state feedback on a plant
    /// with a linear model, at its nominal parameters; a PID under the general indirect scheme,
    /// on the nominal transfer function of `[optimiser.model]`); None otherwise.
    pub fn linear_model(&self) -> Option<crate::law::LinearModel> {
        if self.controller.model.config().checks_stability() {
            self.plant.model.config().linear_model()
        } else if let (Some(prior), OptimiserMode::Indirect) =
            (&self.optimiser.model, self.optimiser.mode)
        {
            crate::law::LinearModel::sampled_transfer_function(
                &prior.num,
                &prior.den,
                self.timing.period,
            )
        } else {
            None
        }
    }

    /// `linear_model` with the plant's varying parameter at `p` (an estimate of it).
    pub fn linear_model_at(&self, p: f64) -> Option<crate::law::LinearModel> {
        if self.controller.model.config().checks_stability() {
            self.plant.model.config().linear_model_at(p)
        } else {
            None
        }
    }

    /// An arm's joint names (the robot file's), for `joint_states`; empty for other plants.
    pub fn joint_names(&self) -> Vec<String> {
        self.plant
            .model
            .config()
            .rigid_body()
            .map_or_else(Vec::new, |m| {
                m.bodies.iter().map(|b| b.joint.clone()).collect()
            })
    }

    /// How long the controller and the optimiser wait for the plant's first state: a process of
    /// the user's own gets `plant.external.wait`; evoloop's plant, the start-up of the processes
    /// (`timing.lockstep_timeout`, at least 10 s).
    pub fn first_state_wait(&self) -> std::time::Duration {
        let s = match self.plant.model.config().external() {
            Some(e) => e.wait,
            None => self.timing.start_timeout(),
        };
        std::time::Duration::from_secs_f64(s)
    }

    /// What the controller requires of every plant state: the configured plant's counts, and
    /// its safe command to send in place of the law's when a state fails.
    pub fn state_check(&self) -> crate::law::state_check::StateCheck {
        let p = self.build_plant();
        // Within a single input's range, as every law's own command is.
        let safe_command = match self.plant.model.config().scalar_input() {
            Some(s) => self.plant.safe_command.clamp(s.range.0, s.range.1),
            None => self.plant.safe_command,
        };
        crate::law::state_check::StateCheck {
            n_x: p.n_states(),
            n_q: p.n_joints(),
            n_y: p.n_outputs(),
            n_u: p.n_inputs(),
            reads_truth: self.controller.reads_truth(),
            safe_command,
        }
    }

    /// The controller's bounds on its tunable parameters (`lower`, `upper`), which every received
    /// parameter set must respect.
    pub fn bounds(&self) -> ParamBounds {
        self.controller.tunable().bounds.clone()
    }

    /// Real-time requests of the controller process in a realtime run: `timing.fifo_priority`,
    /// `timing.lock_memory`, `timing.controller_cpu` and `timing.wait`.
    pub fn controller_rt(&self) -> RtRequest {
        RtRequest {
            fifo_priority: self.timing.fifo_priority,
            lock_memory: self.timing.lock_memory,
            cpu: self.timing.controller_cpu,
            wait: self.timing.wait.kind,
        }
    }

    /// Real-time requests of evoloop's plant process (and of a plant of the user's own) in a
    /// realtime run: `timing.plant_fifo_priority`, `timing.lock_memory`, `timing.plant_cpu`
    /// and `timing.wait`.
    pub fn plant_rt(&self) -> RtRequest {
        RtRequest {
            fifo_priority: self.timing.plant_fifo_priority,
            lock_memory: self.timing.lock_memory,
            cpu: self.timing.plant_cpu,
            wait: self.timing.wait.kind,
        }
    }
}

/// `[optimiser.nominal_plant]`: the plant as a user's model has it (a datasheet's, a CAD
/// model's, an earlier identification's), a plant table like `[plant]` whose errors name its own
/// keys; read by `safe_bayes_model` only, with the plant's inputs and outputs, and not beside
/// `[optimiser.model]` (`transfer_function`: that table is there).
fn nominal_plant(
    raw: Option<crate::plant::RawPlant>,
    check: &Check,
    context: (&Timing, &crate::reference::Reference, &PlantSpec),
    optimiser: &OptimiserSpec,
    transfer_function: bool,
) -> Result<Option<PlantSpec>, ConfigError> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    const KEY: &str = "optimiser.nominal_plant";
    // Checked whatever the algorithm (a typo should not wait for safe_bayes_model); kept for it
    // only (a comparison of other optimisers on the same file leaves it unused).
    let spec = model_plant(raw, KEY, check, context)?;
    let modelled = optimiser.algorithm == SAFE_BAYES_MODEL;
    if modelled && transfer_function {
        return check.fail(
            KEY,
            "give the nominal model once: [optimiser.nominal_plant] or [optimiser.model], not both",
        );
    }
    Ok(modelled.then_some(spec))
}

/// `[[optimiser.nominal_alternatives]]`: the plants the nominal model's tolerance allows (its
/// pole at either end of a datasheet's +-20 %, say), each a plant table checked as
/// `[optimiser.nominal_plant]` is and with the nominal model's inputs and outputs
/// (`nominal_shape`: None without a nominal model kept); at most `MAX_ALTERNATIVES` (each one is
/// a further simulated trial per prediction). Kept for `safe_bayes_model` only, and only beside
/// a nominal model.
fn nominal_alternatives(
    raw: Option<Vec<crate::plant::RawPlant>>,
    check: &Check,
    context: (&Timing, &crate::reference::Reference, &PlantSpec),
    optimiser: &OptimiserSpec,
    nominal_shape: Option<(usize, usize)>,
) -> Result<Vec<PlantSpec>, ConfigError> {
    const KEY: &str = "optimiser.nominal_alternatives";
    const MAX_ALTERNATIVES: usize = 8;
    let raw = raw.unwrap_or_default();
    if raw.len() > MAX_ALTERNATIVES {
        return check.fail(
            KEY,
            format!(
                "{} plants: at most {MAX_ALTERNATIVES} (each is simulated for every prediction)",
                raw.len()
            ),
        );
    }
    let mut specs = Vec::with_capacity(raw.len());
    for (i, r) in raw.into_iter().enumerate() {
        let key = format!("{KEY}[{i}]");
        let spec = model_plant(r, &key, check, context)?;
        let own = shape(spec.model.config());
        if let Some(nominal) = nominal_shape.filter(|n| *n != own) {
            return check.fail(
                &key,
                format!("has {own:?} inputs and outputs where the nominal model has {nominal:?}"),
            );
        }
        specs.push(spec);
    }
    let modelled = optimiser.algorithm == SAFE_BAYES_MODEL;
    if modelled && !specs.is_empty() && nominal_shape.is_none() {
        return check.fail(
            KEY,
            "alternatives to a nominal model that is not there: give [optimiser.nominal_plant] \
             or [optimiser.model] too",
        );
    }
    Ok(if modelled { specs } else { Vec::new() })
}

/// A plant table that models the plant (`[optimiser.nominal_plant]` and its alternatives),
/// validated as `[plant]` is with its errors under `key`: one evoloop simulates, with the
/// plant's inputs and outputs.
fn model_plant(
    raw: crate::plant::RawPlant,
    key: &str,
    check: &Check,
    (timing, reference, plant): (&Timing, &crate::reference::Reference, &PlantSpec),
) -> Result<PlantSpec, ConfigError> {
    let spec = PlantSpec::validate(raw, check, timing.period, reference, timing.duration).map_err(
        |mut e| {
            if let Some(rest) = e.key.strip_prefix("plant") {
                e.key = format!("{key}{rest}");
            }
            e
        },
    )?;
    let (a, b) = (plant.model.config(), spec.model.config());
    if b.external().is_some() {
        return check.fail(
            &format!("{key}.kind"),
            "a model evoloop simulates (a process of your own is the plant, not its model)",
        );
    }
    if a.external().is_none() && shape(a) != shape(b) {
        return check.fail(
            key,
            format!(
                "has {:?} inputs and outputs where the plant has {:?}",
                shape(b),
                shape(a)
            ),
        );
    }
    Ok(spec)
}

/// A plant's (inputs, outputs).
fn shape(c: &dyn crate::plant::PlantConfig) -> (usize, usize) {
    let p = c.build();
    (p.n_inputs(), p.n_outputs())
}

fn compose(raw: RawScenario, check: &Check, ov: &Overrides) -> Result<Scenario, ConfigError> {
    let path = &check.file;
    let name = raw.name.unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scenario".into())
    });
    let timing = timing::validate(raw.timing, check, ov)?;
    let reference = reference::validate(raw.reference, check, timing.period)?;
    let plant = PlantSpec::validate(raw.plant, check, timing.period, &reference, timing.duration)?;
    if timing.mode == Mode::Realtime {
        if let Some(why) = plant.model.config().realtime_refusal() {
            return check.fail("timing.mode", format!("\"realtime\": {why}"));
        }
    }
    let controller = ControllerSpec::validate(
        raw.controller,
        check,
        &plant,
        &reference,
        timing.duration,
        timing.period,
    )?;
    if !plant.publish_truth && controller.reads_truth() {
        return check.fail(
            "plant.publish_truth",
            format!(
                "false withholds the true state, which controller.kind = \"{}\" reads as this \
                 scenario configures it (a full-state or true-velocity reproduction)",
                controller.kind().name()
            ),
        );
    }
    let mut raw_optimiser = raw.optimiser;
    let raw_model = raw_optimiser.as_mut().and_then(|o| o.model.take());
    let raw_nominal = raw_optimiser.as_mut().and_then(|o| o.nominal_plant.take());
    let raw_alternatives = raw_optimiser
        .as_mut()
        .and_then(|o| o.nominal_alternatives.take());
    let mut optimiser = optimiser::validate(raw_optimiser, check, &timing, ov)?;
    let context = (&timing, &reference, &plant);
    let transfer_function = raw_model.is_some();
    optimiser.nominal_plant =
        nominal_plant(raw_nominal, check, context, &optimiser, transfer_function)?;
    // The nominal model's inputs and outputs: its plant table's, or a transfer function's one
    // and one.
    let nominal_shape = match &optimiser.nominal_plant {
        Some(spec) => Some(shape(spec.model.config())),
        None => transfer_function.then_some((1, 1)),
    };
    optimiser.nominal_alternatives =
        nominal_alternatives(raw_alternatives, check, context, &optimiser, nominal_shape)?;
    optimiser.model = model_prior::validate(
        raw_model,
        check,
        &plant.model,
        &controller,
        model_prior::Use::of(&optimiser),
        timing.period,
    )?;
    if optimiser.mode == OptimiserMode::Identify {
        identify_mode_fits(check, &controller)?;
    }
    if optimiser.model.is_some() && optimiser.workers.is_some() {
        return check.fail(
            "optimiser.workers",
            "the indirect scheme on an lti or external plant evaluates on local threads only \
             (optimiser.threads)",
        );
    }
    if plant.model.config().external().is_some() && optimiser.mode == OptimiserMode::Identify {
        return check.fail(
            "optimiser.mode",
            "\"identify\" fits arm models, and an external plant is simulated by its own \
             process only: \"off\", \"schedule\", \"direct\" or \"indirect\" (with \
             [optimiser.model])",
        );
    }
    if optimiser.mode == OptimiserMode::Direct {
        let b = &controller.tunable().bounds;
        if let Some(i) = (0..b.lower.len()).find(|i| {
            !(b.lower[*i].is_finite() && b.upper[*i].is_finite() && b.lower[*i] < b.upper[*i])
        }) {
            return check.fail(
                "optimiser.mode",
                format!(
                    "\"direct\" searches the controller's parameter bounds, which must be finite \
                     and non-empty: parameter {i} has [{}, {}] (set the controller's lower/upper)",
                    b.lower[i], b.upper[i]
                ),
            );
        }
    }
    for (i, s) in optimiser.schedule.iter().enumerate() {
        if s.kind == SetKind::Model && controller.model_param_kind().is_none() {
            return check.fail(
                &format!("optimiser.schedule[{i}].kind"),
                "\"model\": this controller takes no model sets (computed_torque and \
                 fuzzy_computed_torque do)",
            );
        }
        if s.expect == Expect::Accepted {
            scheduled_set_fits(check, &format!("optimiser.schedule[{i}]"), s, &controller)?;
        }
    }
    let out_raw = raw.output.unwrap_or(RawOutput {
        dir: None,
        plots: None,
        mcap: None,
    });
    let output = Output {
        dir: ov
            .out
            .clone()
            .or(out_raw.dir)
            .unwrap_or_else(|| PathBuf::from("runs").join(&name)),
        plots: out_raw.plots.unwrap_or(true),
        mcap: out_raw.mcap.unwrap_or(true),
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
        warnings: check.take_warnings(),
    })
}

/// A scheduled set the controller is to take, judged by the controller's own validation
/// (`law::validate_params` for gains: kind, length, finiteness, bounds; `validate_model`'s
/// finiteness for model sets, whose law-specific checks need the model): refused here, before
/// the run, rather than 12 s into it. `expect = "rejected"` marks a set meant to be refused.
fn scheduled_set_fits(
    check: &Check,
    key: &str,
    s: &ScheduledSet,
    controller: &ControllerSpec,
) -> Result<(), ConfigError> {
    use crate::law::{validate_model, validate_params};
    let (kind, tunable) = (controller.param_kind(), controller.tunable());
    let set = crate::msg::ParamSet::new(1, 0, kind, &s.values);
    let judged = match s.kind {
        SetKind::Gains => validate_params(&set, kind, tunable.gains.len(), 0, &tunable.bounds),
        SetKind::Model => validate_model(&set, 0),
    };
    let Err(r) = judged else { return Ok(()) };
    let at = match r.code {
        crate::msg::ParamCode::RejectedOutOfBounds | crate::msg::ParamCode::RejectedNonFinite => {
            format!("{key}.values[{}]", r.index)
        }
        _ => format!("{key}.values"),
    };
    let i = r.index as usize;
    let detail = match r.code {
        crate::msg::ParamCode::RejectedOutOfBounds => format!(
            " ({} is outside [{}, {}])",
            s.values[i], tunable.bounds.lower[i], tunable.bounds.upper[i]
        ),
        crate::msg::ParamCode::RejectedWrongLength => format!(
            " ({} values; the controller has {} parameters)",
            s.values.len(),
            tunable.gains.len()
        ),
        _ => String::new(),
    };
    check.fail(
        &at,
        format!(
            "the controller would refuse this set: {}{detail} (expect = \"rejected\" for a set meant to be refused)",
            r.code.reason()
        ),
    )
}

/// `optimiser.mode = "identify"` replaces models of a fuzzy computed-torque controller, each sent
/// as one parameter set [slot, parameters], or in parts where larger (`ParamSet::model_sets`),
/// all of which the controller must be able to queue at once.
fn identify_mode_fits(check: &Check, controller: &ControllerSpec) -> Result<(), ConfigError> {
    let crate::law::ControllerModel::FuzzyComputedTorque(f) = &controller.model else {
        return check.fail(
            "optimiser.mode",
            "\"identify\" identifies models for a fuzzy_computed_torque controller \
             (controller.kind = \"fuzzy_computed_torque\")",
        );
    };
    // The controller's queue of sets and its params subscriber's buffer both hold every part.
    let queue = crate::law::cycle::PENDING_CAPACITY.min(crate::ipc::Topic::Params.max_buffer());
    for (i, m) in f.loaded.iter().enumerate() {
        let sets = crate::msg::ParamSet::model_set_count(1 + m.net.layout.len);
        if sets > queue {
            return check.fail(
                &format!("controller.fuzzy_computed_torque.models[{i}]"),
                format!(
                    "a model of {} parameters travels in {sets} parameter sets; the controller \
                     queues at most {queue}, so optimiser.mode = \"identify\" could not send it",
                    m.net.layout.len
                ),
            );
        }
    }
    Ok(())
}
