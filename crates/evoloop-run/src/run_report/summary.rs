//! What each process reports at the end of a run (`controller.json`, `plant.json`,
//! `optimiser.json` in the output directory) and the run summary the launcher assembles from them
//! (`summary.json`).

use crate::report::metrics::ResponseMetrics;
use crate::report::Outcome;
use crate::rt::timing::Percentiles;
use crate::rt::{RtGranted, TimingSummary};
use serde::{Deserialize, Serialize};

/// A parameter-set event as controller.json records it: which set, when, and what became
/// of it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
#[serde(try_from = "RecordAsWritten")]
pub struct ParamRecord {
    /// The version of the set it concerns.
    pub version: u64,
    /// The control cycle it happened in.
    pub cycle: u64,
    /// Plant time of the state that cycle ran on, s.
    pub t: f64,
    /// What happened to the set: the report classifies by this.
    pub code: crate::msg::ParamCode,
    /// The code's reason in words ("accepted", or why refused), for readers.
    pub outcome: String,
    /// Offending value index for bounds/non-finite rejections.
    pub index: Option<u32>,
}

/// A parameter event as any build wrote it: reports from before the `code` field have the
/// reason text alone, which names its code exactly (`ParamCode::reason`).
#[derive(Deserialize)]
struct RecordAsWritten {
    version: u64,
    cycle: u64,
    t: f64,
    code: Option<crate::msg::ParamCode>,
    outcome: String,
    index: Option<u32>,
}

impl TryFrom<RecordAsWritten> for ParamRecord {
    type Error = String;
    fn try_from(r: RecordAsWritten) -> Result<Self, String> {
        let code = match r.code {
            Some(c) => c,
            None => *crate::msg::ParamCode::ALL
                .iter()
                .find(|c| c.reason() == r.outcome)
                .ok_or_else(|| {
                    format!(
                        "a parameter event with no code and an unknown outcome {:?}",
                        r.outcome
                    )
                })?,
        };
        Ok(ParamRecord {
            version: r.version,
            cycle: r.cycle,
            t: r.t,
            code,
            outcome: r.outcome,
            index: r.index,
        })
    }
}

/// What the controller process reports at the end of a run: controller.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ControllerReport {
    /// The timing mode it ran in.
    pub mode: crate::config::Mode,
    /// Control cycles it ran.
    pub cycles: u64,
    /// Wall-clock time of its loop, s.
    pub wall_s: f64,
    /// The real-time privileges it was granted (realtime mode; none asked in lockstep).
    pub rt: RtGranted,
    /// Its loop's timing: lateness, compute time and state age percentiles, overruns, misses.
    pub timing: TimingSummary,
    /// The parameter-set events of the run in order: accepted, refused, trial ended or aborted
    /// (events past the list's capacity are dropped and counted in `log_dropped`).
    pub params: Vec<ParamRecord>,
    /// The parameter version in service at the end (0: the configured initial set).
    pub final_version: u64,
    /// The parameter values in service at the end.
    pub final_params: Vec<f64>,
    /// Sets dropped because the queue of received sets not yet due was full.
    pub pending_dropped: u64,
    /// Plant states the controller refused (a count not the configured plant's, or a value the
    /// law reads not finite), sending the safe command instead: how many, and the first.
    #[serde(default)]
    pub refused_states: crate::law::state_check::Refused,
    /// Rows of run.csv / timing.csv dropped because the log writer fell behind, plus
    /// parameter events dropped because the event list was full.
    pub log_dropped: u64,
    /// The first error writing run.csv / timing.csv (a full disk): rows after it are lost.
    #[serde(default)]
    pub log_error: Option<String>,
    /// The model new sets were checked on (linear plants with a varying parameter).
    #[serde(default)]
    pub check_model: Option<crate::law::model_check::ModelCheckReport>,
    /// Set when the run was stopped by a signal before its end.
    pub interrupted: bool,
    /// run.mcap: messages per topic, dropped (realtime, queue full) and the first write error.
    #[serde(default)]
    pub mcap: Option<crate::report::record::Recorded>,
    /// What the control cycle allocated, counted on the loop itself (absent when evoloop's
    /// counting allocator is not the process's).
    #[serde(default)]
    pub cycle_allocations: Option<crate::rt::alloc_count::CycleAllocations>,
    /// Ports attached mid-run (a viewer, a bridge) that the controller could not connect, left
    /// out while the run went on, and the first failure.
    #[serde(default)]
    pub connection_failures: u64,
    /// The first of those failures, in words.
    #[serde(default)]
    pub connection_error: Option<String>,
}

/// What the plant process reports at the end of a run: plant.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct PlantReport {
    /// The timing mode it ran in.
    pub mode: crate::config::Mode,
    /// State samples published, the end-of-run state not counted.
    pub samples: u64,
    /// Wall-clock time of its loop, s.
    pub wall_s: f64,
    /// The real-time privileges it was granted (realtime mode; none asked in lockstep).
    pub rt: RtGranted,
    /// Samples during which the safe command was applied because commands had stopped.
    pub safe_samples: u64,
    /// Realtime: samples before the controller's first command, with the safe command held (a
    /// controller slow to start; not counted in `safe_samples`, which are a lost controller's).
    #[serde(default)]
    pub samples_before_first_command: u64,
    /// Realtime: the first sample at which the safe command was in force, and how many periods
    /// after the last command it took over (the timeout plus the wait for the next sample).
    #[serde(default)]
    pub first_safe_sample: Option<u64>,
    /// Periods from the last command to `first_safe_sample`.
    #[serde(default)]
    pub first_safe_periods: Option<f64>,
    /// Realtime: samples published since the last command arrived, at the end of the run (how
    /// long the plant ran open-loop when its controller died before it was stopped).
    #[serde(default)]
    pub samples_after_last_command: u64,
    /// Lockstep: synchronisation points passed without an optimiser (none connected).
    #[serde(default)]
    pub syncs_without_optimiser: u64,
    /// Lockstep: samples at which a connected optimiser did not acknowledge within
    /// `timing.lockstep_timeout`, so the loop went on without waiting for it. The run is
    /// reproducible up to the first.
    #[serde(default)]
    pub optimiser_stalls: Vec<u64>,
    /// Lockstep: times a stalled optimiser acknowledged again and paced the loop once more.
    #[serde(default)]
    pub optimiser_resumed: u64,
    /// Controller commands the plant received and applied.
    pub commands_received: u64,
    /// Set when it was stopped by a signal (SIGINT, SIGTERM, SIGHUP).
    pub interrupted: bool,
}

/// A parameter set the optimiser published, as optimiser.json lists it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct PublishedSet {
    /// The set's version.
    pub version: u64,
    /// Plant time of the state at which it was published, s.
    pub at: f64,
    /// The state sequence number at whose cycle the controller applies it; 0: the next cycle.
    pub apply_at_seq: u64,
    /// The set's values (a model sent in parts: the whole model's).
    pub values: Vec<f64>,
}

/// One operator command as the optimiser took it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct OperatorEvent {
    /// Plant time and sample at which it was taken.
    pub t: f64,
    /// The state sequence number it was taken at.
    pub seq: u64,
    /// None: an action code this build does not know.
    pub action: Option<crate::msg::OperatorAction>,
    /// Revert: the version asked for (0: the set before tuning).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub requested_version: Option<u64>,
    /// How the optimiser answered it.
    pub outcome: crate::msg::OperatorOutcome,
    /// Revert: the version the earlier values went out under; otherwise the last published.
    pub version: u64,
}

/// What the optimiser process reports at the end of a run: optimiser.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct OptimiserReport {
    /// The optimiser's mode (`optimiser.mode`).
    pub mode: crate::config::OptimiserMode,
    /// Plant states it received.
    pub states_seen: u64,
    /// Controller commands it received.
    pub commands_seen: u64,
    /// The sets published, thinned evenly past `indirect::HISTORY` like the estimates
    /// (`published.jsonl` has every one).
    pub published: Vec<PublishedSet>,
    /// How many sets were published (a model sent in parts counts once).
    #[serde(default)]
    pub published_count: u64,
    /// What could not be appended to `published.jsonl` (a link planted at its name, a full
    /// disk): the run's record of its sets is then incomplete.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub journal_error: Option<String>,
    /// Indirect mode: plant samples the estimator never saw (gaps in the sequence numbers).
    #[serde(default)]
    pub samples_missed: u64,
    /// The niceness it ran at (`optimiser.nice`); `None` when it could not be set.
    pub nice: Option<i32>,
    /// Set when it was stopped by a signal (SIGINT, SIGTERM, SIGHUP).
    pub interrupted: bool,
    /// Indirect mode: the model estimate over time (every 0.1 s of plant time).
    #[serde(default)]
    pub estimates: Vec<crate::indirect::Estimate>,
    /// Indirect mode: every tuning epoch.
    #[serde(default)]
    pub epochs: Vec<crate::indirect::EpochRecord>,
    /// Indirect mode on an lti or external plant: the estimator's excitation and drift
    /// monitors.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monitor: Option<crate::indirect::linear::Monitor>,
    /// Direct mode: every repetition, the best set.
    #[serde(default)]
    pub direct: Option<crate::direct::DirectReport>,
    /// CPU time of the whole process over its run (every thread: epochs, evaluation pool), s,
    /// and the run's wall time: the load the optimiser put on the machine beside the loop.
    #[serde(default)]
    pub cpu_s: f64,
    /// Wall-clock time over which `cpu_s` was taken, s.
    #[serde(default)]
    pub wall_s: f64,
    /// Population evaluations (`optim::evaluate`) by where they were computed:
    /// `evaluations_local`, `evaluations_remote`, `evaluations_reissued`.
    #[serde(flatten)]
    pub evaluations: crate::optim::remote::Tally,
    /// An operator's commands (`evoloop operator`, `evoloop top`) as the optimiser took them.
    #[serde(default)]
    pub operator: Vec<OperatorEvent>,
    /// `optimiser.workers = "zenoh"`: every worker seen, by id (`net::workers::WorkerStats`).
    #[serde(default)]
    pub workers: std::collections::BTreeMap<String, serde_json::Value>,
}

/// What became of a run's optimiser process (the launcher's count).
#[derive(Debug, Clone, Copy, Default)]
pub struct OptimiserLife {
    /// Times it died and was started again.
    pub restarts: usize,
    /// It died after its last restart and the run went on without it.
    pub lost: bool,
}

/// The direct scheme's outcome in summary.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct DirectSummary {
    /// The optimiser's name (`optimiser.algorithm`).
    pub algorithm: String,
    /// Candidates tried on the plant and scored, and how many of them the envelope aborted.
    pub trials: usize,
    /// Of those trials, the ones the safety envelope aborted.
    pub aborted: u64,
    /// Trials whose samples did not all reach the optimiser (tried again).
    pub incomplete: u64,
    /// The configured set's cost on the baseline repetition, and the best cost found.
    pub baseline_cost: Option<f64>,
    /// The best cost found; `None` when nothing was scored.
    pub best_cost: Option<f64>,
    /// The best set's version (0: the configured set).
    pub best_version: u64,
}

/// The bare absolute-deadline sleep loop measured in the same run: the machine's floor.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct FloorReport {
    /// The loop's period, s: the controller's.
    pub period_s: f64,
    /// What the bare loop's thread was granted: the controller's priority and CPU, memory not
    /// locked.
    pub rt: RtGranted,
    /// The wait strategy of the bare loop: the controller's, so the ratios compare like with like.
    #[serde(default)]
    pub wait: crate::rt::WaitStrategy,
    /// The bare loop's wake-up lateness against its absolute deadlines, ns.
    pub lateness: Percentiles,
    /// Whole periods the bare loop lost (sum over its cycles of floor(lateness / period)): what
    /// the machine alone costs a loop at this rate and priority, the yardstick for judging
    /// whether the controller kept its rate.
    #[serde(default)]
    pub lost_periods: u64,
    /// Controller lateness percentile over the floor's, same run.
    pub ratio_p50: f64,
    /// The same at the 99th percentile (NaN when the floor's is 0).
    pub ratio_p99: f64,
    /// The same at the 99.9th percentile (NaN when the floor's is 0).
    pub ratio_p99_9: f64,
}

/// The parameter-set events of a run by what became of the set: summary.json's
/// `parameter_versions`.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct ParamVersions {
    /// The parameter version in service at the end (0: the configured initial set).
    pub final_version: u64,
    /// Sets the controller put in service, in order.
    pub accepted: Vec<ParamRecord>,
    /// Sets the controller refused, in order, each with its reason.
    pub rejected: Vec<ParamRecord>,
    /// Direct scheme: trial sets that ended (their fallback back in service) or were aborted by
    /// the safety envelope after they had been accepted. Not rejections.
    #[serde(default)]
    pub trials_ended: Vec<ParamRecord>,
}

/// The real-time privileges the controller and the plant were granted.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct RealtimePrivileges {
    /// The controller's (`ControllerReport::rt`).
    pub controller: RtGranted,
    /// The plant's (`PlantReport::rt`).
    pub plant: RtGranted,
}

/// The run summary the launcher assembles from the processes' reports and run.csv:
/// summary.json.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct Summary {
    /// How the run ended (`Outcome`); required when read back (a file without it is not taken
    /// for a run that ended well).
    pub outcome: Outcome,
    /// The scenario's name.
    pub scenario: String,
    /// The scenario file, as the run loaded it.
    pub config: String,
    /// The run's id, part of its iceoryx2 service names.
    pub run_id: String,
    /// The timing mode: lockstep or realtime.
    pub mode: crate::config::Mode,
    /// The seed of every random number generator in the run.
    pub seed: u64,
    /// The scenario's duration; null for a run until stopped.
    pub duration_s: Option<f64>,
    /// Simulated seconds that ran: the last sample's time.
    #[serde(default)]
    pub ran_s: f64,
    /// The run had no duration and went on until it was stopped.
    #[serde(default)]
    pub until_stopped: bool,
    /// The control period, s.
    pub period_s: f64,
    /// Control cycles the controller ran.
    pub samples: u64,
    /// Wall-clock time of the run, s: the launcher's, from the processes' start to their end.
    pub wall_s: f64,
    /// Control cycles per wall-clock second across the processes.
    pub throughput_samples_per_s: f64,
    /// The first output's step-response metrics against its reference.
    pub response: ResponseMetrics,
    /// Tracking error per joint (r_i - y_i) over the whole run.
    pub tracking: crate::report::metrics::Tracking,
    /// The same from t = 1 s on (past start-up transients such as computed torque's psi(k)).
    pub tracking_after_1s: crate::report::metrics::Tracking,
    /// The controller loop's timing (`ControllerReport::timing`).
    pub timing: TimingSummary,
    /// Cycles whose lateness plus compute time exceeded the period (`timing.overruns`).
    pub overruns: u64,
    /// Deadlines that passed without a cycle: the whole periods late wake-ups skipped, and those
    /// before the controller's first sample (`timing.missed_deadlines`).
    pub deadline_misses: u64,
    /// The parameter sets the controller put in service, refused, or ended as trials.
    pub parameter_versions: ParamVersions,
    /// The real-time privileges the controller and the plant were granted.
    pub realtime_privileges: RealtimePrivileges,
    /// Rows of run.csv/timing.csv the controller dropped because its log writer fell behind
    /// (realtime only; the timing statistics still count every cycle).
    #[serde(default)]
    pub log_dropped: u64,
    /// What the control cycle allocated, counted on the controller's own loop (0 is the
    /// design; absent when the counting allocator was not installed).
    #[serde(default)]
    pub cycle_allocations: Option<crate::rt::alloc_count::CycleAllocations>,
    /// Realtime: how the controller and the plant waited for their deadlines (`timing.wait`).
    #[serde(default)]
    pub wait: Option<crate::rt::WaitStrategy>,
    /// Realtime with `timing.measure_floor`: the bare loop measured after the run, with the
    /// controller's lateness against it; `None` otherwise, or when the run was stopped before its
    /// end.
    pub floor: Option<FloorReport>,
    /// Samples the plant held its safe command because commands had stopped
    /// (`PlantReport::safe_samples`).
    pub plant_safe_samples: u64,
    /// Plant states the controller refused and answered with the safe command (see
    /// `ControllerReport::refused_states`), and the first of them.
    #[serde(default)]
    pub refused_states: u64,
    /// The first refused state: its sample and why.
    #[serde(default)]
    pub first_refused_state: Option<crate::law::state_check::FirstRefused>,
    /// Realtime: samples the plant held its safe command before the controller's first command
    /// (a controller slow to start, or one that never commanded).
    #[serde(default)]
    pub plant_samples_before_first_command: u64,
    /// Parameter sets the optimiser published (a model sent in parts counts once).
    pub optimiser_published: usize,
    /// Indirect mode: plant samples the optimiser's estimator missed (its queue overflowed).
    #[serde(default)]
    pub optimiser_samples_missed: u64,
    /// The optimiser process's CPU time, s (user and system, all its threads).
    #[serde(default)]
    pub optimiser_cpu_s: f64,
    /// `optimiser_cpu_s` over the optimiser's wall time: the cores it kept busy on average (0
    /// when it had no wall time).
    #[serde(default)]
    pub optimiser_load_cores: f64,
    /// The optimiser's population evaluations by where they ran (`optimiser.workers`):
    /// `evaluations_local`, `evaluations_remote`, `evaluations_reissued`.
    #[serde(flatten)]
    pub evaluations: crate::optim::remote::Tally,
    /// Direct mode: the trials and what they found (every repetition: direct.csv).
    #[serde(default)]
    pub direct: Option<DirectSummary>,
    /// A process was stopped by a signal (as a run until stopped always ends).
    pub interrupted: bool,
    /// Processes of killed runs whose iceoryx2 resources the launcher removed at its start.
    pub stale_resources_cleaned: usize,
    /// Times the optimiser died and was started again to rejoin the run.
    pub optimiser_restarts: usize,
    /// What the run could not write (a full disk): logged rows or recorded messages after the
    /// error are lost, and the outcome is "incomplete".
    #[serde(default)]
    pub write_errors: Vec<String>,
    /// Why the loop did not control the plant for most of the run (most of its samples
    /// refused, most of its deadlines missed): the outcome is then "degraded" and the exit
    /// status 1, though the run went to its end.
    #[serde(default)]
    pub degraded: Vec<String>,
    /// The optimiser died once more after its last restart: the loop ran on with the set in
    /// service, untuned (outcome "tuner_lost").
    #[serde(default)]
    pub optimiser_lost: bool,
    /// Lockstep: samples at which the optimiser stalled and the loop went on without it (the
    /// run is reproducible up to the first), and how often it came back to pace the loop.
    #[serde(default)]
    pub optimiser_stalls: Vec<u64>,
    /// Lockstep: times a stalled optimiser acknowledged again and paced the loop once more.
    #[serde(default)]
    pub optimiser_resumed: u64,
    /// Parameter sets the controller put in service / refused during the run.
    pub accepted_versions: usize,
    /// Parameter sets the controller refused during the run.
    pub rejected_versions: usize,
    /// Cost per repetition of a repeating reference (sum |e| + w sum |u|, `optimiser.cost_u_weight`).
    pub cost_per_repetition: Vec<f64>,
    /// Mean cost per repetition before the plant's parameter change (first repetition excluded:
    /// it starts from rest), and over the last quarter of the run.
    pub cost_before_change: Option<f64>,
    /// Mean cost per repetition over the last quarter of the run.
    pub cost_after_change: Option<f64>,
    /// The same for the frozen comparison (the scenario with the optimiser off, simulated
    /// in-process after an indirect run).
    pub cost_after_change_frozen: Option<f64>,
    /// `cost_before_change` of the frozen comparison.
    #[serde(default)]
    pub cost_before_change_frozen: Option<f64>,
    /// `cost_per_repetition` of the frozen comparison (indirect runs that have one; else empty).
    pub cost_per_repetition_frozen: Vec<f64>,
    /// The optimiser's final model estimate, the true value then, and the relative error.
    pub model_estimate_final: Option<f64>,
    /// The true value of the estimated parameter at the final estimate's time (the plant's,
    /// unseen by the run).
    pub model_true_final: Option<f64>,
    /// The final estimate's relative error: (estimate - true) / true.
    pub model_estimate_error: Option<f64>,
    /// Linear plants under the indirect scheme: the model the controller checked new sets on
    /// (nominal until the first estimate it adopted, then the latest).
    #[serde(default)]
    pub check_model: Option<crate::law::model_check::ModelCheckReport>,
    /// Identification alongside operation (`optimiser.mode = "identify"`): tracking RMS over all
    /// joints (rad) from 1 s to the plant's first change and over the last quarter of the run,
    /// and the same for the frozen comparison (the starting models all run long, simulated
    /// in-process).
    #[serde(default)]
    pub tracking_before_change: Option<f64>,
    /// Identification: tracking RMS over all joints over the last quarter of the run, rad.
    #[serde(default)]
    pub tracking_after_change: Option<f64>,
    /// `tracking_before_change` of the frozen comparison, rad.
    #[serde(default)]
    pub tracking_before_change_frozen: Option<f64>,
    /// `tracking_after_change` of the frozen comparison, rad.
    #[serde(default)]
    pub tracking_after_change_frozen: Option<f64>,
}

#[cfg(test)]
mod record_tests {
    use super::ParamRecord;
    use crate::msg::ParamCode;

    /// Reports written before the `code` field read back with the code their reason names; a
    /// written code wins; a record with neither is refused, not guessed.
    #[test]
    fn a_record_without_its_code_reads_back_by_its_reason() {
        for code in ParamCode::ALL {
            let old = format!(
                r#"{{"version":3,"cycle":10,"t":0.5,"outcome":"{}","index":null}}"#,
                code.reason()
            );
            let r: ParamRecord = serde_json::from_str(&old).unwrap();
            assert_eq!(r.code, *code);
            let again: ParamRecord =
                serde_json::from_str(&serde_json::to_string(&r).unwrap()).unwrap();
            assert_eq!(again, r);
        }
        let coded = r#"{"version":1,"cycle":0,"t":0,"code":"rejected_stale","outcome":"anything","index":2}"#;
        let r: ParamRecord = serde_json::from_str(coded).unwrap();
        assert_eq!((r.code, r.index), (ParamCode::RejectedStale, Some(2)));
        let unknown = r#"{"version":1,"cycle":0,"t":0,"outcome":"exploded","index":null}"#;
        let e = serde_json::from_str::<ParamRecord>(unknown).unwrap_err();
        assert!(
            e.to_string().contains("unknown outcome \"exploded\""),
            "{e}"
        );
    }
}
