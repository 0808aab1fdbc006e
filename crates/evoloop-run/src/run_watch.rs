//! What `evoloop top` shows of a running run, gathered read-only: the controller's telemetry,
//! the parameter sets and model estimates on the run's topics (iceoryx2 subscribers of their
//! own: the publishers never wait for a subscriber, their services overwrite the oldest sample
//! when a queue is full), and the processes from /proc.
//!
//! Counts that telemetry carries as running totals (cycles, missed deadlines, overruns, the
//! parameter version in service) are exact whatever top receives. Lateness and compute
//! percentiles are over the telemetry samples received in the last second: all of them when
//! top keeps up (its queue holds 64 samples and it drains every 2 ms), a sample otherwise, and
//! the snapshot says how many cycles it saw (`seen_last_s`).

use crate::msg::{ModelEstimate, OptimiserStatus, ParamCode, ParamSet, Telemetry};
use crate::rt::timing::Percentiles;
use serde::Serialize;
use std::collections::VecDeque;

/// Seconds of tracking error the sparkline spans, and its buckets.
pub const SPARK_SECONDS: f64 = 10.0;
/// Buckets of the sparkline: 100, each `SPARK_SECONDS` / 100 = 0.1 s of run time.
pub const SPARK_BUCKETS: usize = 100;

/// A running run, as found in /proc: its controller's `--run-id`, `--ipc-prefix`, `--config`
/// (the scenario, resolved against the controller's working directory) and `--optimiser`.
#[derive(Debug, Clone, PartialEq)]
pub struct RunningRun {
    /// The run's id (the controller's `--run-id`).
    pub run_id: String,
    /// Prefix of the run's iceoryx2 files (`--ipc-prefix`, else the default).
    pub ipc_prefix: String,
    /// The scenario file, resolved; `None` without `--config` or when the controller's working
    /// directory cannot be read.
    pub config: Option<std::path::PathBuf>,
    /// The optimiser mode the controller was started with (`--optimiser`), if any.
    pub optimiser: Option<crate::config::OptimiserMode>,
}

impl RunningRun {
    /// The run's scenario: `config` or the controller's, with `ov` over it; the optimiser mode
    /// the controller was started with unless `ov` names one (what a set from outside the
    /// loop may do depends on it).
    pub fn scenario(
        &self,
        config: Option<&std::path::Path>,
        ov: &crate::config::Overrides,
    ) -> Result<crate::config::Scenario, PickError> {
        let file = config
            .or(self.config.as_deref())
            .ok_or(PickError::UnknownScenario)?;
        let mut ov = ov.clone();
        ov.optimiser = ov.optimiser.or(self.optimiser);
        crate::config::Scenario::load(file, &ov).map_err(PickError::Config)
    }
}

/// Why no one running run was picked, or its scenario could not be had.
#[derive(Debug)]
pub enum PickError {
    /// No run of the id asked for is running: the id, and the ids of those that are.
    NotRunning {
        /// The id asked for.
        id: String,
        /// The runs that are running.
        running: Vec<String>,
    },
    /// No evoloop run is running.
    NoneRunning,
    /// Several are running and none was named: their ids.
    Several(Vec<String>),
    /// The run's controller was started without `--config`, and none was given.
    UnknownScenario,
    /// The run's scenario did not load.
    Config(crate::config::ConfigError),
}

impl std::fmt::Display for PickError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PickError::NotRunning { id, running } if running.is_empty() => {
                write!(f, "no run `{id}` is running (no evoloop run is)")
            }
            PickError::NotRunning { id, running } => {
                write!(
                    f,
                    "no run `{id}` is running (running: {})",
                    running.join(", ")
                )
            }
            PickError::NoneRunning => {
                f.write_str("no evoloop run is running (start one with `evoloop run`)")
            }
            PickError::Several(ids) => write!(
                f,
                "several runs are running, name one with --run: {}",
                ids.join(", ")
            ),
            PickError::UnknownScenario => {
                f.write_str("the run's scenario is unknown: give --config")
            }
            PickError::Config(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for PickError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Reads as the scenario's error: its source is that error's.
            PickError::Config(e) => e.source(),
            _ => None,
        }
    }
}

/// The runs with a live controller process of this user's.
pub fn running_runs() -> Vec<RunningRun> {
    let mut out: Vec<RunningRun> = crate::soak::evoloop_processes()
        .into_iter()
        .filter(|p| p.name == "evoloop-controller" && ours(p.pid))
        .filter_map(|p| {
            Some(RunningRun {
                run_id: p.arg("--run-id")?.to_string(),
                ipc_prefix: p
                    .arg("--ipc-prefix")
                    .unwrap_or(crate::ipc::DEFAULT_PREFIX)
                    .to_string(),
                config: p.arg("--config").and_then(|c| {
                    let cwd = std::fs::read_link(format!("/proc/{}/cwd", p.pid)).ok()?;
                    Some(cwd.join(c))
                }),
                optimiser: p.arg("--optimiser").and_then(|m| m.parse().ok()),
            })
        })
        .collect();
    out.sort_by(|a, b| a.run_id.cmp(&b.run_id));
    out
}

/// The run `run` names, or the only one running.
pub fn pick_run(run: Option<&str>) -> Result<RunningRun, PickError> {
    let runs = running_runs();
    let ids = || runs.iter().map(|r| r.run_id.clone()).collect::<Vec<_>>();
    match run {
        Some(id) => runs
            .iter()
            .find(|r| r.run_id == id)
            .cloned()
            .ok_or_else(|| PickError::NotRunning {
                id: id.to_string(),
                running: ids(),
            }),
        None => match runs.len() {
            0 => Err(PickError::NoneRunning),
            1 => Ok(runs[0].clone()),
            _ => Err(PickError::Several(ids())),
        },
    }
}

/// Whether process `pid` is this user's (another user's runs live in their own namespace).
fn ours(pid: u32) -> bool {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: getuid has no preconditions.
    let uid = unsafe { libc::getuid() };
    std::fs::metadata(format!("/proc/{pid}")).is_ok_and(|m| m.uid() == uid)
}

/// One process of the run.
#[derive(Debug, Clone, Serialize)]
pub struct ProcessView {
    /// The process's role: one of `soak::PROCESSES`.
    pub name: String,
    /// Its process id.
    pub pid: u32,
    /// The kernel's state letter (R running, S sleeping, T stopped, ...).
    pub state: String,
    /// CPU time over the last interval, % of one core.
    pub cpu_pct: f64,
    /// Resident memory (VmRSS), KiB; 0 when it could not be read.
    pub rss_kib: u64,
}

/// CPU time (utime + stime, clock ticks) and state of a process, from /proc/PID/stat.
fn proc_stat(pid: u32) -> Option<(u64, String)> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name is in parentheses and may hold spaces: fields count from after it.
    let rest = &s[s.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some((ticks, f.first()?.to_string()))
}

/// The controller's view over the last second and since top attached.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ControllerView {
    /// Cycles the controller has run (the newest telemetry's cycle + 1).
    pub cycles: u64,
    /// Cycles per second over the last second, by top's clock.
    pub cycle_rate_hz: f64,
    /// Plant time of the state the newest telemetry's cycle used, s.
    pub t: f64,
    /// Missed deadlines since the run's start (the controller's running count).
    pub missed_total: u64,
    /// Missed deadlines in the last second.
    pub missed_last_s: u64,
    /// Overruns since the run's start (the controller's running count).
    pub overruns_total: u64,
    /// Overruns in the last second.
    pub overruns_last_s: u64,
    /// Cycles whose telemetry top received in the last second.
    pub seen_last_s: u64,
    /// Wake-up lateness over the telemetry received in the last second, ns.
    pub lateness_last_s: Percentiles,
    /// Compute time over the same samples, ns.
    pub compute_last_s: Percentiles,
    /// The newest telemetry's tracking error: the first reference minus the first output.
    pub tracking_error: f64,
}

/// The parameter sets as top sees them: the version in service, and counts since it attached.
#[derive(Debug, Clone, Default, Serialize)]
pub struct ParamsView {
    /// The parameter version in service, as the newest telemetry gives it.
    pub version_in_service: u64,
    /// Parameter events in the telemetry top received since it attached.
    pub accepted_seen: u64,
    /// Of those, the rejections.
    pub rejected_seen: u64,
    /// Events whose code this build does not know (a controller of another version).
    pub unknown_codes_seen: u64,
    /// Sets published on the run's topic since top attached, and the last one.
    pub sets_seen: u64,
    /// The last set's version.
    pub last_set_version: Option<u64>,
    /// The last set's expected cost on the optimiser's model; `None` when not finite (unknown).
    pub last_set_expected_cost: Option<f64>,
}

/// The newest model estimate on the run's topic, and how many came.
#[derive(Debug, Clone, Serialize)]
pub struct EstimateView {
    /// The estimated parameter, in its own unit (maglev: ball mass, kg; two-mass: spring constant).
    pub value: f64,
    /// Its standard deviation, same unit; infinite while no fit has been adopted.
    pub std: f64,
    /// Plant time of the estimate, s.
    pub t: f64,
    /// Estimates received since top attached.
    pub seen: u64,
}

/// Everything top shows at one moment.
#[derive(Debug, Clone, Serialize)]
pub struct Snapshot {
    /// The run watched.
    pub run_id: String,
    /// The snapshot's time: seconds since top attached, by its own clock.
    pub attached_s: f64,
    /// Telemetry samples received since top attached.
    pub telemetry_received: u64,
    /// The run's processes found in /proc, sorted by name.
    pub processes: Vec<ProcessView>,
    /// Plant samples per second over the last second (by the states the telemetry names).
    pub plant_sample_rate_hz: f64,
    /// The controller over the last second and in total.
    pub controller: ControllerView,
    /// The parameter sets and their events.
    pub params: ParamsView,
    /// The newest model estimate; `None` before the first.
    pub estimate: Option<EstimateView>,
    /// The optimiser's last epoch (indirect and identify schemes); costs are null when
    /// infinite (the set loses the plant).
    pub optimiser: Option<OptimiserStatus>,
    /// Mean |tracking error| per bucket over the last `SPARK_SECONDS` of run time, oldest
    /// first (NaN: no sample in the bucket).
    pub tracking_sparkline: Vec<f64>,
}

/// What one telemetry sample leaves behind for the windows.
#[derive(Debug, Clone, Copy)]
struct Seen {
    at_s: f64,
    cycle: u64,
    state_seq: u64,
    lateness_ns: i64,
    compute_ns: u64,
    missed: u64,
    overruns: u64,
}

/// Top's state: fed telemetry, sets and estimates as they arrive (`at_s`: seconds since top
/// attached, by its own clock), asked for snapshots.
pub struct Watch {
    run_id: String,
    recent: VecDeque<Seen>,
    /// |tracking error| by run time, for the sparkline.
    errors: VecDeque<(f64, f64)>,
    last: Option<Telemetry>,
    received: u64,
    params: ParamsView,
    estimate: Option<EstimateView>,
    optimiser: Option<OptimiserStatus>,
    cpu: Vec<(u32, u64, f64)>,
}

impl Watch {
    /// Top's state for run `run_id`, before anything has arrived.
    pub fn new(run_id: &str) -> Self {
        Self {
            run_id: run_id.to_string(),
            recent: VecDeque::new(),
            errors: VecDeque::new(),
            last: None,
            received: 0,
            params: ParamsView::default(),
            estimate: None,
            optimiser: None,
            cpu: Vec::new(),
        }
    }

    /// Take a telemetry sample received at `at_s`: count its parameter event, and keep it for
    /// the last second's window and the sparkline.
    pub fn telemetry(&mut self, tel: &Telemetry, at_s: f64) {
        self.received += 1;
        if tel.param_event_version != 0 {
            match ParamCode::try_from(tel.param_code) {
                Ok(ParamCode::Accepted) => self.params.accepted_seen += 1,
                Ok(code) if code.is_rejection() => self.params.rejected_seen += 1,
                Ok(_) => {}
                Err(_) => self.params.unknown_codes_seen += 1,
            }
        }
        self.params.version_in_service = tel.param_version;
        self.recent.push_back(Seen {
            at_s,
            cycle: tel.cycle,
            state_seq: tel.state_seq,
            lateness_ns: tel.lateness_ns,
            compute_ns: tel.compute_ns,
            missed: tel.missed,
            overruns: tel.overruns,
        });
        while self.recent.front().is_some_and(|s| at_s - s.at_s > 1.0) {
            self.recent.pop_front();
        }
        self.errors.push_back((tel.t, tel.tracking_error.abs()));
        while self
            .errors
            .front()
            .is_some_and(|(t, _)| tel.t - t > SPARK_SECONDS)
        {
            self.errors.pop_front();
        }
        self.last = Some(*tel);
    }

    /// Take a parameter set seen on the run's topic.
    pub fn params(&mut self, set: &ParamSet) {
        self.params.sets_seen += 1;
        self.params.last_set_version = Some(set.version);
        self.params.last_set_expected_cost =
            set.expected_cost.is_finite().then_some(set.expected_cost);
    }

    /// Take a model estimate seen on the run's topic.
    pub fn estimate(&mut self, e: &ModelEstimate) {
        let seen = self.estimate.as_ref().map_or(0, |v| v.seen) + 1;
        self.estimate = Some(EstimateView {
            value: e.value,
            std: e.std,
            t: e.t,
            seen,
        });
    }

    /// Take the optimiser's status, published after each epoch.
    pub fn optimiser(&mut self, st: &OptimiserStatus) {
        self.optimiser = Some(*st);
    }

    /// The snapshot at `at_s`, with the run's processes (`name`, pid) read from /proc: CPU %
    /// over the time since the last snapshot.
    pub fn snapshot(&mut self, at_s: f64, processes: &[(String, u32)]) -> Snapshot {
        let tick = clock_ticks();
        let mut views = Vec::new();
        let mut cpu = Vec::new();
        for (name, pid) in processes {
            let Some((ticks, state)) = proc_stat(*pid) else {
                continue;
            };
            let cpu_pct = self
                .cpu
                .iter()
                .find(|(p, _, _)| p == pid)
                .map_or(0.0, |(_, t0, s0)| {
                    let dt = at_s - s0;
                    if dt > 0.0 {
                        100.0 * (ticks.saturating_sub(*t0)) as f64 / tick / dt
                    } else {
                        0.0
                    }
                });
            cpu.push((*pid, ticks, at_s));
            views.push(ProcessView {
                name: name.clone(),
                pid: *pid,
                state,
                cpu_pct,
                rss_kib: crate::soak::rss_kib(*pid).map_or(0, |m| m.0),
            });
        }
        self.cpu = cpu;
        views.sort_by(|a, b| a.name.cmp(&b.name));

        let mut c = ControllerView::default();
        let mut plant_rate = 0.0;
        if let (Some(last), Some(first)) = (self.last, self.recent.front()) {
            c.cycles = last.cycle + 1;
            c.t = last.t;
            c.missed_total = last.missed;
            c.overruns_total = last.overruns;
            c.tracking_error = last.tracking_error;
            c.missed_last_s = last.missed - first.missed;
            c.overruns_last_s = last.overruns - first.overruns;
            c.seen_last_s = self.recent.len() as u64;
            let newest = self.recent.back().copied().unwrap_or(*first);
            let span = newest.at_s - first.at_s;
            if span > 0.0 {
                c.cycle_rate_hz = (newest.cycle - first.cycle) as f64 / span;
                plant_rate = newest.state_seq.saturating_sub(first.state_seq) as f64 / span;
            }
            c.lateness_last_s =
                Percentiles::from_samples(self.recent.iter().map(|s| s.lateness_ns));
            c.compute_last_s =
                Percentiles::from_samples(self.recent.iter().map(|s| s.compute_ns as i64));
        }
        Snapshot {
            run_id: self.run_id.clone(),
            attached_s: at_s,
            telemetry_received: self.received,
            processes: views,
            plant_sample_rate_hz: plant_rate,
            controller: c,
            params: self.params.clone(),
            estimate: self.estimate.clone(),
            optimiser: self.optimiser,
            tracking_sparkline: self.sparkline(),
        }
    }

    fn sparkline(&self) -> Vec<f64> {
        let Some(&(t_end, _)) = self.errors.back() else {
            return Vec::new();
        };
        let t0 = t_end - SPARK_SECONDS;
        let mut sum = vec![0.0; SPARK_BUCKETS];
        let mut n = vec![0u32; SPARK_BUCKETS];
        for &(t, e) in &self.errors {
            let b = (((t - t0) / SPARK_SECONDS) * SPARK_BUCKETS as f64) as usize;
            let b = b.min(SPARK_BUCKETS - 1);
            sum[b] += e;
            n[b] += 1;
        }
        sum.iter()
            .zip(&n)
            .map(|(s, k)| if *k > 0 { s / *k as f64 } else { f64::NAN })
            .collect()
    }
}

/// Clock ticks per second (`/proc/PID/stat` counts CPU time in them).
fn clock_ticks() -> f64 {
    // SAFETY: sysconf has no preconditions.
    let t = unsafe { libc::sysconf(libc::_SC_CLK_TCK) };
    if t > 0 {
        t as f64
    } else {
        100.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tel(cycle: u64, missed: u64, lateness: i64) -> Telemetry {
        Telemetry {
            cycle,
            state_seq: cycle,
            t: cycle as f64 * 1e-3,
            lateness_ns: lateness,
            missed,
            param_version: 3,
            tracking_error: -0.5,
            ..Default::default()
        }
    }

    /// Totals come from the newest sample, the last second's counts from its differences, the
    /// percentiles from the samples of the last second only; older samples leave the window.
    #[test]
    fn the_window_holds_the_last_second_and_totals_are_the_telemetry_s() {
        let mut w = Watch::new("r");
        // 2 s of a 1 kHz loop seen at 1 kHz; lateness 1 us in the first second, 5 us after.
        // The running miss count steps at cycles 334, 667, 1000, 1500 and 2000 (never
        // reached): 4 in all, and 2 between cycle 999 (one second before the newest sample,
        // the window's first) and cycle 1999.
        for k in 0..2000u64 {
            let missed = if k < 1000 {
                k * 3 / 1000
            } else {
                3 + (k - 1000) * 2 / 1000
            };
            let lateness = if k < 1000 { 1000 } else { 5000 };
            w.telemetry(&tel(k, missed, lateness), k as f64 * 1e-3);
        }
        let s = w.snapshot(2.0, &[]);
        let c = &s.controller;
        assert_eq!(c.cycles, 2000);
        assert_eq!(c.missed_total, 4);
        assert_eq!(c.missed_last_s, 2, "{c:?}");
        assert_eq!(c.seen_last_s, 1001);
        assert!(
            (c.cycle_rate_hz - 1000.0).abs() < 1e-6,
            "{}",
            c.cycle_rate_hz
        );
        assert!(
            (c.lateness_last_s.p50_ns - 5000).abs() <= 5,
            "{:?}",
            c.lateness_last_s
        );
        assert_eq!(s.params.version_in_service, 3);
        assert_eq!(s.tracking_sparkline.len(), SPARK_BUCKETS);
        // 2 s of run time fill the last fifth of the 10 s the sparkline spans; the rest has
        // no sample (NaN).
        let filled: Vec<f64> = s
            .tracking_sparkline
            .iter()
            .copied()
            .filter(|v| v.is_finite())
            .collect();
        assert_eq!(filled.len(), SPARK_BUCKETS / 5);
        assert!(s.tracking_sparkline[..SPARK_BUCKETS * 4 / 5]
            .iter()
            .all(|v| v.is_nan()));
        assert!(filled.iter().all(|v| (*v - 0.5).abs() < 1e-12));
    }

    /// A set's events are counted by their code; the sets and estimates on the topics by
    /// arrival.
    #[test]
    fn parameter_events_sets_and_estimates_are_counted() {
        let mut w = Watch::new("r");
        let mut t = tel(1, 0, 0);
        t.param_event_version = 4;
        t.param_code = ParamCode::Accepted as u32;
        w.telemetry(&t, 0.0);
        t.param_code = ParamCode::RejectedUnstable as u32;
        w.telemetry(&t, 0.001);
        // A code this build does not know is counted as such, not as "no event".
        t.param_code = 99;
        w.telemetry(&t, 0.002);
        w.params(&ParamSet {
            version: 5,
            expected_cost: 2.5,
            ..Default::default()
        });
        w.estimate(&ModelEstimate {
            value: 0.7,
            std: 0.01,
            t: 3.0,
            last_version: 4,
            apply_at_seq: 0,
        });
        let s = w.snapshot(0.01, &[]);
        assert_eq!((s.params.accepted_seen, s.params.rejected_seen), (1, 1));
        assert_eq!(s.params.unknown_codes_seen, 1);
        assert_eq!(s.params.last_set_version, Some(5));
        assert_eq!(s.params.last_set_expected_cost, Some(2.5));
        assert_eq!(
            s.estimate.as_ref().map(|e| (e.value, e.seen)),
            Some((0.7, 1))
        );
    }

    #[test]
    fn this_process_s_stat_reads() {
        let (ticks, state) = proc_stat(std::process::id()).unwrap();
        assert!(state == "R" || state == "S", "{state}");
        let _ = ticks;
    }
}
