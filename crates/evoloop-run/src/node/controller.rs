//! evoloop-controller: the fixed-rate control loop.
//!
//! Each cycle: take the newest plant state, take any parameter set that is due (validated, then
//! swapped in bumplessly at the cycle boundary), compute the control law, publish the command,
//! publish telemetry. The loop allocates nothing: logs and queues are sized before it starts.
//!
//! lockstep: a cycle per state sample, woken by the plant's event.
//! realtime: a cycle per period on absolute deadlines (clock_nanosleep TIMER_ABSTIME), aligned
//!           to the plant's first sample plus a small phase; lateness, compute time and state age
//!           are measured every cycle, overruns and missed deadlines counted.

use super::args::ProcessArgs;
use crate::config::{Mode, Scenario};
use crate::ipc::{IpcError, Pub, Spin, Sub, Topic, Waited};
use crate::law::cycle::{ControlCycle, ParamEvent};
use crate::law::model_check::{ModelCheck, ModelCheckReport};
use crate::law::state_check::{SampleTime, StateFault};
use crate::msg::{
    Command, ModelEstimate, ParamCode, ParamSet, PlantState, Telemetry, STATE_FLAG_END,
    TELEMETRY_FLAG_MISSED, TELEMETRY_FLAG_OVERRUN, TELEMETRY_FLAG_STALE,
};
use crate::node::start::{leave_and_fail, ports, start, Failure, Started};
use crate::report::record::Recorder;
use crate::report::stream::{CsvPart, LogStream, Overflow};
use crate::report::write_json;
use crate::rt::{alloc_count, apply_privileges, now_ns, CycleTiming, TimingStats, TimingSummary};
use crate::run_report::summary::{ControllerReport, ParamRecord};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const WHO: &str = "evoloop-controller";

/// timing.csv's columns, logged after run.csv's in each row of the stream.
const TIMING_COLUMNS: [&str; 5] = [
    "cycle",
    "lateness_ns",
    "compute_ns",
    "state_age_ns",
    "flags",
];

/// How a cycle started: when it woke (`woke_ns`), how late that was against its deadline, the
/// flags it starts with (missed, stale) and the period (0 in lockstep: no deadline).
#[derive(Clone, Copy)]
struct Wake {
    woke_ns: u64,
    lateness_ns: i64,
    flags: u32,
    period_ns: u64,
}

struct Ports {
    params: Sub<ParamSet>,
    /// The optimiser's model estimate, when new sets are checked on a model of the plant.
    estimate: Option<EstimatePort>,
    command: Pub<Command>,
    telemetry: Pub<Telemetry>,
    state: Sub<PlantState>,
}

impl Ports {
    /// Connect to the ports that joined since the last cycle (a viewer, a bridge, a restarted
    /// optimiser), just before a cycle rather than in it, where the cycle's own receive or send
    /// would (connecting allocates). A port that attaches during the microseconds of the
    /// cycle's own computation is still connected by it. Checking costs a lock and a load per
    /// port when nothing changed: about 2 % of a lockstep two-mass run's throughput (median
    /// ratio 0.98 over eight interleaved pairs of 600 s runs, 2026-11-28), nothing a realtime
    /// period notices.
    fn update_connections(&self) -> Result<(), IpcError> {
        // Every port, whatever one of them says: a newcomer that could not be connected is
        // left out (iceoryx2 does not try it again), the others are connected.
        let estimate = match &self.estimate {
            Some(EstimatePort::Parameter(s)) => s.update_connections(),
            Some(EstimatePort::Linear(s)) => s.update_connections(),
            None => Ok(()),
        };
        // The state's port is not here: the wait for the state, just before, receives on it.
        [
            self.params.update_connections(),
            estimate,
            self.command.update_connections(),
            self.telemetry.update_connections(),
        ]
        .into_iter()
        .collect()
    }
}

/// The estimates a controller checks new sets on: a plant parameter (`ModelCheck`: the
/// two-mass's spring) or a whole transfer function (`LinearCheck`: the general scheme's).
enum EstimatePort {
    Parameter(Sub<ModelEstimate>),
    Linear(Sub<crate::msg::LinearEstimate>),
}

enum EstimateCheck {
    /// Boxed: it holds the plant's whole model (allocated once, before the loop).
    Parameter(Box<ModelCheck>),
    Linear(crate::law::model_check::LinearCheck),
}

impl EstimateCheck {
    /// For the scenario: the general scheme's transfer function, or the plant parameter when
    /// the plant has a linear model at any value of it; None when nothing is re-checked.
    fn of(scn: &crate::config::Scenario) -> Option<Self> {
        scn.linear_model()?;
        match scn.optimiser.model {
            Some(_) => Some(Self::Linear(crate::law::model_check::LinearCheck::new(
                scn.timing.period,
            ))),
            None => ModelCheck::new(&scn.plant.model).map(|m| Self::Parameter(Box::new(m))),
        }
    }

    /// The subscriber to the estimates this check adopts.
    fn subscribe(&self, ipc: &crate::ipc::Ipc) -> Result<EstimatePort, IpcError> {
        Ok(match self {
            Self::Parameter(_) => {
                EstimatePort::Parameter(ipc.subscriber(Topic::Estimate, 4, false)?)
            }
            Self::Linear(_) => {
                EstimatePort::Linear(ipc.subscriber(Topic::LinearEstimate, 4, false)?)
            }
        })
    }

    fn report(&self) -> crate::law::model_check::ModelCheckReport {
        match self {
            Self::Parameter(m) => m.report().clone(),
            Self::Linear(l) => l.report().clone(),
        }
    }
}

/// Everything the loop writes into, allocated before it starts.
struct Loop {
    cycle: ControlCycle,
    model_check: Option<EstimateCheck>,
    /// run.csv's columns, then timing.csv's: streamed to disk by a writer thread.
    log: LogStream,
    /// run.mcap's recorder (`output.mcap`).
    record: Option<Recorder>,
    timing: TimingStats,
    events: Vec<ParamEvent>,
    events_dropped: u64,
    overruns: u64,
    missed: u64,
    stale: u64,
    /// Ports attached mid-run that could not be connected (left out; the run goes on), and the
    /// first failure.
    connection_failures: u64,
    connection_error: Option<String>,
    n_y: usize,
    n_u: usize,
    n_q: usize,
    n_r: usize,
    /// Arms: reference and joint velocities are logged too (rd*, qd*), for identification
    /// from the reference and output alone (the RKGNN paper's data).
    n_vel: usize,
    /// Columns the control law adds (e.g. the fuzzy selector's active model and memberships).
    n_law: usize,
    row: Vec<f64>,
    /// Count what the cycle allocates (when evoloop's allocator is the process's).
    watch_allocations: bool,
}

impl Loop {
    /// The loop, with run.csv and timing.csv created (an unwritable output directory is an
    /// error here, before the run starts).
    fn new(scn: &Scenario, model_check: Option<EstimateCheck>) -> Result<Self, String> {
        let plant = scn.build_plant();
        let (n_y, n_u, n_q) = (plant.n_outputs(), plant.n_inputs(), plant.n_joints());
        // Joint 0's reference keeps the name `reference`; joint-space trajectories add r1, r2, ...
        let n_r = scn.reference.joints();
        let mut header = vec!["t".to_string(), "reference".to_string()];
        header.extend((1..n_r).map(|i| format!("r{i}")));
        header.extend((0..n_y).map(|i| format!("y{i}")));
        header.extend((0..n_u).map(|i| format!("u{i}")));
        header.extend((0..n_q).map(|i| format!("q{i}")));
        header.push("param_version".into());
        let n_vel = if scn.plant.model.config().rigid_body().is_some() {
            n_q
        } else {
            0
        };
        header.extend((0..n_vel).map(|i| format!("rd{i}")));
        header.extend((0..n_vel).map(|i| format!("qd{i}")));
        // The cycle the loop runs, built once: its law names the columns it logs.
        let cycle = crate::sim::control_cycle(scn);
        let law = cycle.controller.log_columns();
        let n_law = law.len();
        header.extend(law);
        let dir = &scn.output.dir;
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let w = header.len();
        let timing_header: Vec<String> = TIMING_COLUMNS.iter().map(|s| s.to_string()).collect();
        let width = w + timing_header.len();
        let parts = vec![
            CsvPart {
                path: dir.join("run.csv"),
                header,
                columns: 0..w,
            },
            CsvPart {
                path: dir.join("timing.csv"),
                header: timing_header,
                columns: w..width,
            },
        ];
        // A second of cycles (at least 4096 rows), at most 16 MiB: the writer drains it every
        // few milliseconds, so only a disk stalled for about a second costs rows. Lockstep
        // waits for room instead, so its logs never depend on the writer's speed.
        let rows = ((1.0 / scn.timing.period) as usize)
            .max(4096)
            .min((16 << 20) / (8 * width));
        let overflow = match scn.timing.mode {
            Mode::Lockstep => Overflow::Wait,
            Mode::Realtime => Overflow::Drop,
        };
        let log = LogStream::start(parts, rows, overflow).map_err(|e| e.to_string())?;
        let record = if scn.output.mcap {
            let meta = [
                ("scenario", scn.name.clone()),
                ("config", scn.source.display().to_string()),
                ("mode", scn.timing.mode.to_string()),
                ("seed", scn.seed.to_string()),
                ("period_s", scn.timing.period.to_string()),
                (
                    "log_time",
                    "CLOCK_MONOTONIC ns of the sample's stamp".to_string(),
                ),
            ];
            let meta = meta.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
            Some(
                Recorder::start(
                    &dir.join("run.mcap"),
                    scn.timing.mode == Mode::Lockstep,
                    meta,
                    match scn.timing.mode {
                        Mode::Realtime => scn.timing.controller_cpu,
                        Mode::Lockstep => None,
                    },
                    scn.joint_names(),
                )
                .map_err(|e| e.to_string())?,
            )
        } else {
            None
        };
        Ok(Self {
            record,
            cycle,
            model_check,
            row: vec![0.0; width],
            log,
            timing: TimingStats::default(),
            // A direct run has up to three events per trial (accepted, ended or aborted).
            events: Vec::with_capacity(
                if scn.optimiser.mode == crate::config::OptimiserMode::Direct {
                    1024 + 3 * scn.optimiser.evaluations
                } else {
                    1024
                },
            ),
            events_dropped: 0,
            overruns: 0,
            missed: 0,
            stale: 0,
            connection_failures: 0,
            connection_error: None,
            n_y,
            n_u,
            n_q,
            n_r,
            n_vel,
            n_law,
            watch_allocations: alloc_count::installed(),
        })
    }

    /// Connect the ports attached since the last cycle, before this one. One that cannot be
    /// connected is left out and counted, not the end of the run: a viewer's or a bridge's
    /// failure is not the loop's.
    fn connect(&mut self, ports: &Ports) {
        if let Err(e) = ports.update_connections() {
            self.connection_failures += 1;
            if self.connection_error.is_none() {
                eprintln!("controller: {e}; the run goes on without that port");
                self.connection_error = Some(e.to_string());
            }
        }
    }

    /// One cycle (`step`), its allocations counted after the warm-up.
    fn cycle(&mut self, ports: &Ports, state: &PlantState, wake: Wake) -> Result<(), IpcError> {
        let watch = self.watch_allocations && self.cycle.next_cycle() >= alloc_count::WARMUP_CYCLES;
        if watch {
            alloc_count::arm();
        }
        let r = self.step(ports, state, wake);
        if watch {
            alloc_count::disarm();
        }
        r
    }

    /// One cycle on `state`: parameters, law, command, telemetry, log.
    fn step(&mut self, ports: &Ports, state: &PlantState, wake: Wake) -> Result<(), IpcError> {
        let Wake {
            woke_ns,
            lateness_ns,
            flags: flags_in,
            period_ns,
        } = wake;
        if let Some(r) = self.record.as_mut() {
            r.at_state(state, self.cycle.next_cycle());
        }
        while let Some(p) = ports.params.next()? {
            self.cycle.offer(&p);
            if let Some(r) = self.record.as_mut() {
                r.params(&p);
            }
        }
        // The port is the check's own (`EstimateCheck::subscribe`): the pairs always match.
        let adopted = match (self.model_check.as_mut(), ports.estimate.as_ref()) {
            (Some(EstimateCheck::Parameter(mc)), Some(EstimatePort::Parameter(sub))) => {
                while let Some(e) = sub.next()? {
                    mc.offer(&e);
                    if let Some(r) = self.record.as_mut() {
                        r.estimate(&e);
                    }
                }
                mc.due(state.seq)
            }
            (Some(EstimateCheck::Linear(lc)), Some(EstimatePort::Linear(sub))) => {
                while let Some(e) = sub.next()? {
                    lc.offer(&e);
                    if let Some(r) = self.record.as_mut() {
                        r.linear_estimate(&e);
                    }
                }
                lc.due(state.seq)
            }
            _ => None,
        };
        if let Some(m) = adopted {
            self.cycle.check_on(m);
        }
        let mut tel = Telemetry::default();
        if let Some(e) = self.cycle.step(state, &mut tel) {
            if self.events.len() < self.events.capacity() {
                self.events.push(e);
            } else {
                self.events_dropped += 1;
            }
        }
        let cmd = Command {
            cycle: tel.cycle,
            state_seq: state.seq,
            stamp_ns: now_ns(),
            param_version: tel.param_version,
            n_u: self.n_u as u32,
            _pad: 0,
            u: self.cycle.u,
        };
        ports.command.send(&cmd)?;
        // The filter designed again on the adopted estimate, for the next sample: after the
        // command, so the design does not delay it (`compute` below includes it).
        if let Some(m) = adopted {
            self.cycle.redesign_on(&m);
        }
        let done = now_ns();
        let compute = done.saturating_sub(woke_ns);
        let mut flags = flags_in | tel.flags;
        if lateness_ns.max(0) as u64 + compute > period_ns && period_ns > 0 {
            flags |= TELEMETRY_FLAG_OVERRUN;
            self.overruns += 1;
        }
        tel.lateness_ns = lateness_ns;
        tel.compute_ns = compute;
        tel.state_age_ns = woke_ns.saturating_sub(state.stamp_ns);
        tel.flags = flags;
        tel.overruns = self.overruns;
        tel.missed = self.missed;
        ports.telemetry.send(&tel)?;
        if let Some(r) = self.record.as_mut() {
            r.cycle(state, &cmd, &tel);
        }
        let timing = CycleTiming {
            cycle: tel.cycle,
            lateness_ns,
            compute_ns: compute,
            state_age_ns: tel.state_age_ns,
            flags,
        };
        self.timing.record(&timing);
        let r = &mut self.row;
        r[0] = state.t;
        r[1] = tel.reference;
        let mut j = 2;
        for i in 1..self.n_r {
            r[j] = self.cycle.setpoint.q[i];
            j += 1;
        }
        for i in 0..self.n_y {
            r[j] = state.y[i];
            j += 1;
        }
        for i in 0..self.n_u {
            r[j] = self.cycle.u[i];
            j += 1;
        }
        for i in 0..self.n_q {
            r[j] = state.q_true[i];
            j += 1;
        }
        r[j] = tel.param_version as f64;
        j += 1;
        for i in 0..self.n_vel {
            r[j] = self.cycle.setpoint.qd[i];
            r[j + self.n_vel] = state.qd_true[i];
            j += 1;
        }
        j += self.n_vel;
        r[j..j + self.n_law].copy_from_slice(&tel.law[..self.n_law]);
        j += self.n_law;
        r[j] = timing.cycle as f64;
        r[j + 1] = timing.lateness_ns as f64;
        r[j + 2] = timing.compute_ns as f64;
        r[j + 3] = timing.state_age_ns as f64;
        r[j + 4] = timing.flags as f64;
        self.log.push(&self.row);
        Ok(())
    }
}

/// The controller process: `evoloop controller ...` or `evoloop-controller ...`.
pub fn main(args: &ProcessArgs) {
    let Started {
        scenario: scn,
        stop,
        ipc,
    } = start(args, WHO);
    let model_check = EstimateCheck::of(&scn);
    let ports = ports(WHO, || {
        Ok(Ports {
            params: ipc.subscriber(Topic::Params, crate::law::cycle::PENDING_CAPACITY, false)?,
            // The estimates of the check the loop makes, and no others.
            estimate: model_check
                .as_ref()
                .map(|c| c.subscribe(&ipc))
                .transpose()?,
            command: ipc.publisher(Topic::Command, true)?,
            telemetry: ipc.publisher(Topic::Telemetry, false)?,
            // Last: the plant starts the run once it sees this subscriber.
            state: ipc.subscriber(Topic::State, 8, true)?,
        })
    });
    if let Err(e) = ipc.announce(Topic::Ready) {
        leave_and_fail(WHO, ports, ipc, Failure::Setup(e.to_string()));
    }

    let mut lp = match Loop::new(&scn, model_check) {
        Ok(lp) => lp,
        Err(e) => leave_and_fail(
            WHO,
            ports,
            ipc,
            Failure::Setup(format!("cannot log the run: {e}")),
        ),
    };
    let mut report = ControllerReport {
        mode: scn.timing.mode,
        ..Default::default()
    };
    if scn.timing.mode == Mode::Realtime {
        report.rt = apply_privileges(&scn.controller_rt());
    }
    let t0 = Instant::now();
    let result = match scn.timing.mode {
        Mode::Lockstep => run_lockstep(&scn, &ports, &mut lp, &stop),
        Mode::Realtime => run_realtime(&scn, &ports, &mut lp, &stop),
    };
    report.wall_s = t0.elapsed().as_secs_f64();
    report.interrupted = stop.load(Ordering::SeqCst);
    finish(&scn, lp, &mut report);
    if let Err(e) = result {
        leave_and_fail(WHO, ports, ipc, e);
    }
}

/// Wait for the next state, in slices so a signal is noticed. Ok(None): stopped by a signal.
fn next_state(
    ports: &Ports,
    spin: &mut Spin,
    timeout: Duration,
    stop: &AtomicBool,
) -> Result<Option<PlantState>, Failure> {
    match ports.state.wait_for(spin, timeout, stop, |_| true) {
        Ok(Waited::Got(s)) => Ok(Some(s)),
        Ok(Waited::Stopped) => Ok(None),
        Ok(Waited::TimedOut) => Err(Failure::PeerTimeout(format!(
            "no plant state within {timeout:?}"
        ))),
        Err(e) => Err(Failure::Setup(e.to_string())),
    }
}

fn run_lockstep(
    scn: &Scenario,
    ports: &Ports,
    lp: &mut Loop,
    stop: &AtomicBool,
) -> Result<(), Failure> {
    let mut spin = Spin::new(Duration::from_micros(scn.timing.spin_us));
    let timeout = Duration::from_secs_f64(scn.timing.lockstep_timeout);
    // The first sample may take as long as the start-up of all processes. After that the plant
    // may itself wait up to `timeout` for a stalled optimiser before it goes on without it, so
    // the controller gives it twice that before calling it gone.
    let mut first = true;
    loop {
        let wait = if first {
            scn.first_state_wait()
        } else {
            2 * timeout
        };
        let Some(state) = next_state(ports, &mut spin, wait, stop)? else {
            return Ok(());
        };
        first = false;
        if state.flags & STATE_FLAG_END != 0 {
            return Ok(());
        }
        let woke = now_ns();
        let wake = Wake {
            woke_ns: woke,
            lateness_ns: 0,
            flags: 0,
            period_ns: 0,
        };
        lp.connect(ports);
        lp.cycle(ports, &state, wake)
            .map_err(|e| Failure::Setup(e.to_string()))?;
    }
}

/// How far the first state's stamp may lie behind this machine's clock, beyond the periods its
/// queue holds: the oldest queued sample is read first, and the controller may have been slow
/// to start on a loaded machine; a plant stamping with another clock is off by years or by the
/// machine's uptime.
const PLANT_CLOCK_TOLERANCE_NS: u64 = 2_000_000_000;
/// Samples the controller's state queue holds (`ports`: the subscriber's buffer), and more.
const QUEUED_PERIODS: u64 = 16;

/// The plant contract's stamps are CLOCK_MONOTONIC of this machine (the controller schedules its
/// cycles on them): a stamp from another clock would have the loop wait for years or run at
/// once on every cycle, so it is refused with what was seen.
fn plant_clock(stamp_ns: u64, now_ns: u64, period_ns: u64) -> Result<(), String> {
    let behind = now_ns as i128 - stamp_ns as i128;
    let tolerance = PLANT_CLOCK_TOLERANCE_NS as i128 + (QUEUED_PERIODS * period_ns) as i128;
    if (0..=tolerance).contains(&behind) {
        return Ok(());
    }
    Err(format!(
        "the plant's first state is stamped {:.3} s {} this machine's CLOCK_MONOTONIC: the plant \
         contract's stamp_ns is CLOCK_MONOTONIC ns of the machine the run is on",
        (behind.unsigned_abs() as f64) * 1e-9,
        if behind < 0 { "ahead of" } else { "behind" }
    ))
}

fn run_realtime(
    scn: &Scenario,
    ports: &Ports,
    lp: &mut Loop,
    stop: &AtomicBool,
) -> Result<(), Failure> {
    let period = scn.period_ns();
    let stale_ns = scn.controller.stale_after_periods as u64 * period;
    let Some(mut state) = next_state(ports, &mut Spin::none(), scn.first_state_wait(), stop)?
    else {
        return Ok(());
    };
    // Align to the plant's sample clock: cycle k runs `phase` of a period after sample k. A
    // sample's stamp is its tick plus the plant's wake-up latency, so the earliest
    // stamp - seq * period among the good samples is the best estimate of the plant's epoch.
    plant_clock(state.stamp_ns, now_ns(), period).map_err(Failure::Failed)?;
    // A later END sample ends the loop where it is read; only the first is looked at here.
    if state.flags & STATE_FLAG_END != 0 {
        return Ok(());
    }
    // How far a sample's period may seem to begin before the first sample's: the first
    // sample's wake-up latency, up to the age at which a state is stale, and at least 2 ms (a
    // loaded machine's wake-up).
    let mut clock = SampleTime::new(&state, period, stale_ns.max(2_000_000));
    let phase = (scn.timing.phase * period as f64) as u64;
    let n = scn.cycles();
    let mut k = state.seq;
    // Periods that passed before the controller had its first sample had no cycle: missed.
    lp.missed += state.seq;
    while k < n {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let deadline = clock.epoch() + k * period + phase;
        scn.timing.wait.wait_until(deadline);
        let woke = now_ns();
        let lateness = woke as i64 - deadline as i64;
        let mut flags = 0;
        if lateness >= period as i64 {
            // Whole periods passed without a cycle: count them as missed and skip them, so the
            // loop keeps to its grid instead of running a burst of catch-up cycles.
            // Periods past the run's end are not missed: they were never due.
            let skipped = (lateness as u64 / period).min(n - k);
            lp.missed += skipped;
            k += skipped;
            flags |= TELEMETRY_FLAG_MISSED;
            if k >= n {
                break;
            }
        }
        match ports.state.latest() {
            // The plant's last sample ends the loop, whatever its stamp.
            Ok(Some(s)) if s.flags & STATE_FLAG_END != 0 => return Ok(()),
            // A sample that breaks time is refused like one whose values are not finite: the
            // cycle sends the safe command (on the last good state's record) and counts it.
            Ok(Some(s)) => match clock.judge(&s, now_ns()) {
                Ok(()) => state = s,
                Err(fault) => lp.cycle.refuse(s.seq, StateFault::Time(fault)),
            },
            Ok(None) => {}
            Err(e) => return Err(Failure::Setup(e.to_string())),
        }
        if woke.saturating_sub(state.stamp_ns) > stale_ns {
            flags |= TELEMETRY_FLAG_STALE;
            lp.stale += 1;
        }
        let wake = Wake {
            woke_ns: woke,
            lateness_ns: lateness,
            flags,
            period_ns: period,
        };
        lp.connect(ports);
        lp.cycle(ports, &state, wake)
            .map_err(|e| Failure::Setup(e.to_string()))?;
        k += 1;
    }
    Ok(())
}

fn finish(scn: &Scenario, lp: Loop, report: &mut ControllerReport) {
    let dir = &scn.output.dir;
    let t = &lp.timing;
    report.cycles = t.cycles();
    report.timing = TimingSummary {
        cycles: t.cycles(),
        lateness: t.lateness.percentiles(),
        compute: t.compute.percentiles(),
        state_age: t.state_age.percentiles(),
        overruns: lp.overruns,
        missed_deadlines: lp.missed,
        stale_states: lp.stale,
    };
    report.params = lp
        .events
        .iter()
        .map(|e| ParamRecord {
            version: e.version,
            cycle: e.cycle,
            t: e.t,
            code: e.code,
            outcome: e.code.reason().into(),
            index: matches!(
                e.code,
                ParamCode::RejectedOutOfBounds | ParamCode::RejectedNonFinite
            )
            .then_some(e.index),
        })
        .collect();
    report.final_version = lp.cycle.version();
    report.final_params = lp.cycle.controller.params().to_vec();
    report.pending_dropped = lp.cycle.pending_dropped;
    report.connection_failures = lp.connection_failures;
    report.connection_error = lp.connection_error.clone();
    report.refused_states = lp.cycle.refused;
    report.check_model = lp.model_check.as_ref().map(|c| ModelCheckReport {
        filters_designed: lp.cycle.filters_designed,
        filters_refused: lp.cycle.filters_refused,
        ..c.report()
    });
    report.cycle_allocations = lp.watch_allocations.then(|| alloc_count::CycleAllocations {
        cycles: lp
            .cycle
            .next_cycle()
            .saturating_sub(alloc_count::WARMUP_CYCLES),
        allocations: alloc_count::COUNT.load(Ordering::Relaxed),
    });
    let dropped = lp.log.dropped;
    let written = lp.log.finish();
    if let Some(e) = &written.error {
        eprintln!("{WHO}: writing run.csv / timing.csv failed: {e}; rows after the error are lost");
        report.log_error = Some(format!("run.csv / timing.csv: {e}; rows after it are lost"));
    }
    report.log_dropped = dropped + lp.events_dropped;
    if let Some(r) = lp.record {
        let recorded = r.finish();
        if let Some(e) = &recorded.error {
            eprintln!("{WHO}: writing run.mcap failed: {e}");
        }
        report.mcap = Some(recorded);
    }
    if let Err(e) = write_json(dir, "controller.json", report) {
        eprintln!("{WHO}: cannot write controller.json: {e}");
    }
}

#[cfg(test)]
mod clock_tests {
    use super::plant_clock;

    #[test]
    fn a_stamp_from_another_clock_is_refused_with_what_was_seen() {
        let now = 5_000_000_000_000; // 5 000 s of uptime
        let ms = 1_000_000;
        assert!(plant_clock(now, now, ms).is_ok());
        assert!(plant_clock(now - 1_500_000_000, now, ms).is_ok());
        // A slow period: the queued samples' age is allowed for.
        assert!(plant_clock(now - 9_000_000_000, now, 500 * ms).is_ok());
        assert!(plant_clock(now - 2_100_000_000, now, ms).is_err());
        // CLOCK_REALTIME (about 1.8e18 ns): decades ahead.
        let e = plant_clock(1_800_000_000_000_000_000, now, ms).unwrap_err();
        assert!(
            e.contains("ahead of") && e.contains("CLOCK_MONOTONIC"),
            "{e}"
        );
        // Zero, or a clock that started with the plant: the uptime behind.
        let e = plant_clock(0, now, ms).unwrap_err();
        assert!(e.contains("5000.000 s behind"), "{e}");
        assert!(plant_clock(now + 1, now, ms).is_err());
    }
}
