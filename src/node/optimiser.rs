//! evoloop-optimiser: the tuner's process. This first cut subscribes to the state and command
//! streams and publishes parameter sets on the path real tuning will use: in `schedule` mode it
//! publishes the scenario's configured sets at their configured times.
//!
//! lockstep: it consumes every sample in order and acknowledges every `sync_samples`-th one; a set
//!           due within the next interval is published before the acknowledgement with
//!           `apply_at_seq`, so the controller applies it on the same sample in every run.
//! realtime: it runs free at lower priority (nice) and publishes a set as soon as the plant's
//!           time passes the set's time; the controller applies it at its next cycle.

use super::args::OptimiserArgs;
use crate::config::{Mode, OptimiserMode, Scenario};
use crate::ipc::{Doorbell, IpcError, Pub, Sub, Topic, Wait};
use crate::msg::{
    Command, ModelEstimate, OptimiserAck, OptimiserStatus, ParamSet, PlantState, STATE_FLAG_END,
};
use crate::node::start::{fail, leave_and_fail, ports, start, Failure, Started};
use crate::report::history::History;
use crate::report::summary::{OptimiserReport, PublishedSet};
use crate::report::write_json;
use crate::rt::privileges::set_nice;
use crate::sim::{scheduled_seq, scheduled_set};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const WHO: &str = "evoloop-optimiser";

struct Ports {
    /// Lockstep: the plant rings at every sample the optimiser must acknowledge.
    sync: Doorbell,
    params: Pub<ParamSet>,
    estimate: Pub<ModelEstimate>,
    status: Pub<OptimiserStatus>,
    ack: Pub<OptimiserAck>,
    command: Sub<Command>,
    state: Sub<PlantState>,
}

/// The optimiser process: `evoloop optimiser ...` or `evoloop-optimiser ...`.
pub fn main(cli: &OptimiserArgs) {
    let mut cli = cli.clone();
    let mirror = cli.connect.take().map(|ep| remote::join(&mut cli, ep));
    let Started {
        scenario: scn,
        stop,
        ipc,
    } = start(&cli.args, WHO);
    // Before the ports: the plant starts once they exist, and the workers are waited for first.
    let pool = workers::start(&scn, &stop).unwrap_or_else(|e| fail(WHO, Failure::Setup(e)));
    let buffer = crate::ipc::MAX_SYNC_SAMPLES + 8;
    let lockstep = scn.timing.mode == Mode::Lockstep;
    let ports = ports(WHO, || {
        Ok(Ports {
            sync: ipc.doorbell(Topic::Sync)?,
            params: ipc.publisher(Topic::Params, false)?,
            estimate: ipc.publisher(Topic::Estimate, false)?,
            status: ipc.publisher(Topic::OptimiserStatus, false)?,
            // The direct scheme waits for the command answering a boundary's last sample.
            command: ipc.subscriber(
                Topic::Command,
                buffer,
                scn.optimiser.mode == OptimiserMode::Direct,
            )?,
            // The plant starts the run once it sees this subscriber and the ready event.
            // In lockstep the optimiser sleeps on the sync bell and catches up on the queue,
            // instead of being woken (or spinning) for every sample.
            state: ipc.subscriber(Topic::State, buffer, !lockstep)?,
            // After the state subscriber: a plant that sees this publisher may count on the
            // optimiser receiving every sample from then on (it waits for its acknowledgements).
            ack: ipc.publisher(Topic::OptimiserAck, true)?,
        })
    });
    if let Err(e) = ipc.announce(Topic::Ready) {
        fail(WHO, Failure::Setup(e.to_string()));
    }
    let mut report = OptimiserReport {
        mode: scn.optimiser.mode,
        ..Default::default()
    };
    // The optimiser yields the CPU to the control loop.
    if set_nice(scn.optimiser.nice) {
        report.nice = Some(scn.optimiser.nice);
    }
    if cli.rejoin && lockstep {
        // The plant may be waiting at a sample this process never saw: release it once.
        if let Err(e) = ports.ack.send(&OptimiserAck {
            through_seq: u64::MAX,
        }) {
            fail(WHO, Failure::Setup(e.to_string()));
        }
    }
    // The load over the run itself: CPU and wall time from the same moment.
    let (t0, cpu0) = (Instant::now(), process_cpu_seconds());
    let result = run(&scn, &ports, &stop, &mut report, cli.rejoin);
    report.interrupted = stop.load(Ordering::SeqCst);
    report.wall_s = t0.elapsed().as_secs_f64();
    report.cpu_s = process_cpu_seconds() - cpu0;
    workers::finish(pool, &mut report);
    if let Err(e) = write_json(&scn.output.dir, "optimiser.json", &report) {
        eprintln!("{WHO}: cannot write optimiser.json: {e}");
    }
    if let Some(m) = mirror {
        remote::finish(m, &scn.output.dir);
    }
    if let Err(e) = result {
        leave_and_fail(WHO, ports, ipc, e);
    }
}

fn run(
    scn: &Scenario,
    ports: &Ports,
    stop: &AtomicBool,
    report: &mut OptimiserReport,
    rejoin: bool,
) -> Result<(), Failure> {
    let lockstep = scn.timing.mode == Mode::Lockstep;
    let schedule_on = scn.optimiser.mode == OptimiserMode::Schedule;
    let sync = scn.sync_samples();
    let dt = scn.timing.period;
    let timeout = Duration::from_secs_f64(scn.timing.lockstep_timeout.max(10.0));
    let mut next_set = 0usize;
    let mut indirect = if scn.optimiser.mode == OptimiserMode::Indirect {
        let mut ind = crate::indirect::Indirect::new(scn).map_err(Failure::Setup)?;
        if rejoin {
            if let Some((version, params)) = last_published(&scn.output.dir) {
                ind.resume(version, params);
            }
        }
        Some(ind)
    } else {
        None
    };
    let mut live = if scn.optimiser.mode == OptimiserMode::Identify {
        let mut l = crate::rkgnn::live::LiveIdentify::new(scn).map_err(Failure::Setup)?;
        if rejoin {
            if let Some((version, values)) = last_published(&scn.output.dir) {
                l.resume(version, &values);
            }
        }
        Some(l)
    } else {
        None
    };
    let mut direct = if scn.optimiser.mode == OptimiserMode::Direct {
        let mut tuner = crate::direct::DirectTuner::new(scn).map_err(Failure::Setup)?;
        if rejoin {
            if let Some((version, _)) = last_published(&scn.output.dir) {
                tuner.resume(version);
            }
        }
        Some(DirectLive::new(tuner, scn))
    } else {
        None
    };
    // Realtime: a trial is sent this far ahead of its first sample (20 ms), so it reaches the
    // controller before that cycle.
    let lead = (0.02 / dt).ceil() as u64;
    let mut published = History::new(crate::indirect::HISTORY);
    let mut last_state = Instant::now();
    let mut status_epochs = 0;
    let io = |e: IpcError| Failure::Setup(e.to_string());
    // Ends at the plant's last sample, at a stop request (a run until stopped ends so), when
    // the plant has gone or at an IPC failure; the histories go into the report in every case.
    let mut serve = || loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let slice = Duration::from_millis(100);
        let got = if lockstep {
            match ports.state.next().map_err(io)? {
                Some(s) => Wait::Got(s),
                None => {
                    ports.sync.wait(slice).map_err(io)?;
                    match ports.state.next().map_err(io)? {
                        Some(s) => Wait::Got(s),
                        None => Wait::TimedOut,
                    }
                }
            }
        } else {
            ports.state.wait_next(Duration::ZERO, slice).map_err(io)?
        };
        let state = match got {
            Wait::Got(s) => s,
            Wait::TimedOut => {
                // In realtime the plant keeps sampling; silence this long means it is gone.
                if last_state.elapsed() > timeout {
                    return Err(Failure::PeerTimeout(format!(
                        "no plant state within {timeout:?}"
                    )));
                }
                continue;
            }
        };
        last_state = Instant::now();
        report.states_seen += 1;
        // Epochs that ended since the last sample, for watchers.
        let epochs = indirect
            .as_ref()
            .map(|i| &i.epochs)
            .or(live.as_ref().map(|l| &l.epochs));
        if let Some(e) = epochs.filter(|e| e.offered() != status_epochs) {
            status_epochs = e.offered();
            if let Some(last) = e.last() {
                let status = OptimiserStatus {
                    t: last.t,
                    epochs: status_epochs,
                    published: published.offered(),
                    best_cost: last.best_cost,
                    in_service_cost: last.in_service_cost,
                };
                ports.status.send(&status).map_err(io)?;
            }
        }
        if let Some(d) = direct.as_mut() {
            d.push_state(&state);
        }
        while let Some(c) = ports.command.next().map_err(io)? {
            report.commands_seen += 1;
            if let Some(d) = direct.as_mut() {
                d.push_command(&c);
            }
        }
        if let Some(ind) = indirect.as_mut() {
            // Each new 10 Hz record goes out as telemetry too.
            if let Some(e) = ind.observe(&state) {
                let msg = ModelEstimate {
                    t: e.t,
                    value: e.value,
                    std: e.std,
                    last_version: ind.version(),
                    // Lockstep: delivered before the plant passes the next synchronisation
                    // point, so the controller adopts it at the sample after that one.
                    apply_at_seq: if lockstep {
                        scn.next_sync_point(state.seq) + 1
                    } else {
                        0
                    },
                };
                ports.estimate.send(&msg).map_err(io)?;
            }
        }
        if let Some(l) = live.as_mut() {
            l.observe(&state);
        }
        if state.flags & STATE_FLAG_END != 0 {
            return Ok(());
        }
        let schedule = &scn.optimiser.schedule;
        if lockstep {
            if !scn.is_sync_point(state.seq) {
                continue;
            }
            // Publish every set due within the next interval, then let the plant go on.
            while schedule_on && next_set < schedule.len() {
                let at = scheduled_seq(schedule[next_set].at, dt);
                if at > state.seq + sync {
                    break;
                }
                publish(scn, ports, next_set, at.max(state.seq + 1), &mut published).map_err(io)?;
                next_set += 1;
            }
            // Paced by simulated time: the plant waits for the acknowledgement, so the epochs
            // run at the same samples in every run of a seed.
            if let Some(ind) = indirect.as_mut() {
                if let Some(set) = ind.paced(state.t, sync as f64 * dt, state.seq + 1) {
                    send_set(ports, &set, state.t, &mut published, &scn.output.dir).map_err(io)?;
                }
            }
            // At fixed simulated times, the plant waiting: reproducible per seed.
            if let Some(l) = live.as_mut() {
                if let Some(set) = l.attempt(state.t, state.seq + 1) {
                    send_set(ports, &set, state.t, &mut published, &scn.output.dir).map_err(io)?;
                }
            }
            // Every sample up to this one seen with its command, the next trial (if one starts
            // at the next sample) goes out before the plant may take that sample.
            if let Some(d) = direct.as_mut() {
                d.wait_through(
                    state.seq,
                    &ports.command,
                    &mut report.commands_seen,
                    timeout,
                )?;
                if let Some(set) = d.tuner.at(state.seq + 1, None) {
                    send_set(ports, &set, state.t, &mut published, &scn.output.dir).map_err(io)?;
                }
            }
            ports
                .ack
                .send(&OptimiserAck {
                    through_seq: state.seq,
                })
                .map_err(io)?;
        } else {
            while schedule_on && next_set < schedule.len() && state.t >= schedule[next_set].at {
                publish(scn, ports, next_set, 0, &mut published).map_err(io)?;
                next_set += 1;
            }
            // Free-running: epochs back to back on the worker thread while this one goes on
            // reading the stream, so an epoch longer than the state queue loses no sample.
            if let Some(ind) = indirect.as_mut() {
                if let Some(set) = ind.finish_epoch(0, false) {
                    send_set(ports, &set, state.t, &mut published, &scn.output.dir).map_err(io)?;
                }
                ind.start_epoch(state.t);
            }
            if let Some(d) = direct.as_mut() {
                d.join();
                if let Some(next) = d.through.map(|s| s + 1) {
                    if let Some(set) = d.tuner.at(next, Some(next + lead)) {
                        send_set(ports, &set, state.t, &mut published, &scn.output.dir)
                            .map_err(io)?;
                    }
                }
            }
            if let Some(l) = live.as_mut() {
                if !ports.state.has_pending().map_err(io)? {
                    if let Some(set) = l.attempt(state.t, 0) {
                        send_set(ports, &set, state.t, &mut published, &scn.output.dir)
                            .map_err(io)?;
                    }
                }
            }
        }
    };
    let result = serve();
    if let Some(ind) = indirect {
        report.samples_missed = ind.samples_missed;
        report.estimates = ind.estimates.into_vec();
        report.epochs = ind.epochs.into_vec();
    }
    if let Some(l) = live {
        report.epochs = l.epochs.into_vec();
    }
    if let Some(d) = direct {
        report.direct = Some(d.tuner.report());
    }
    report.published_count = published.offered();
    report.published = published.into_vec();
    result
}

/// The direct scheme in this process: each state paired with the command that answered it, in
/// sequence order, for the tuner. Fixed-size queues (the plant runs at most a queue ahead).
struct DirectLive {
    tuner: crate::direct::DirectTuner,
    reference: crate::reference::Reference,
    n: usize,
    states: std::collections::VecDeque<(u64, f64, [f64; crate::MAX_JOINTS])>,
    commands: std::collections::VecDeque<Command>,
    /// The last sample observed (paired with its command).
    through: Option<u64>,
    /// The last command joined: realtime, a state the controller skipped (it ran its cycle on
    /// an older one) had this command applied over its interval.
    last: Option<Command>,
}

impl DirectLive {
    fn new(tuner: crate::direct::DirectTuner, scn: &Scenario) -> Self {
        let cap = 2 * (crate::ipc::MAX_SYNC_SAMPLES + 8);
        Self {
            tuner,
            reference: scn.reference.clone(),
            n: scn.build_controller().n_outputs(),
            states: std::collections::VecDeque::with_capacity(cap),
            commands: std::collections::VecDeque::with_capacity(cap),
            through: None,
            last: None,
        }
    }

    fn push_state(&mut self, s: &PlantState) {
        if self.states.len() == self.states.capacity() {
            self.states.pop_front();
        }
        self.states.push_back((s.seq, s.t, s.y));
        self.join();
    }

    fn push_command(&mut self, c: &Command) {
        if self.commands.len() == self.commands.capacity() {
            self.commands.pop_front();
        }
        self.commands.push_back(*c);
        self.join();
    }

    /// Pair the queued states and commands by sequence number. Realtime only (lockstep answers
    /// every state once): a command for a state already paired (the controller ran a cycle on a
    /// stale state) is dropped; a state no command answered (the controller skipped it) is
    /// paired with the command before it, which the plant kept applying.
    fn join(&mut self) {
        let mut sp = crate::reference::Setpoint::default();
        while let (Some(s), Some(c)) = (self.states.front(), self.commands.front()) {
            let c = if c.state_seq < s.0 {
                self.last = self.commands.pop_front();
                continue;
            } else if s.0 < c.state_seq {
                match self.last {
                    Some(last) => last,
                    None => {
                        self.states.pop_front();
                        continue;
                    }
                }
            } else {
                let c = *c;
                self.commands.pop_front();
                self.last = Some(c);
                c
            };
            let s = self.states.pop_front().expect("a front state");
            self.reference.sample(s.1, &mut sp);
            let n = self.n;
            self.tuner
                .observe(s.0, s.1, &sp.q[..n], &s.2[..n], &c.u[..n], c.param_version);
            self.through = Some(s.0);
        }
    }

    /// Lockstep: wait for the controller's answer to sample `seq` (it comes without the
    /// optimiser's acknowledgement, which the plant waits for).
    fn wait_through(
        &mut self,
        seq: u64,
        commands: &Sub<Command>,
        seen: &mut u64,
        timeout: Duration,
    ) -> Result<(), Failure> {
        let t0 = Instant::now();
        while self.through.is_none_or(|s| s < seq) {
            match commands
                .wait_next(Duration::from_micros(50), Duration::from_millis(100))
                .map_err(|e| Failure::Setup(e.to_string()))?
            {
                Wait::Got(c) => {
                    *seen += 1;
                    self.push_command(&c);
                }
                Wait::TimedOut if t0.elapsed() > timeout => {
                    return Err(Failure::PeerTimeout(format!(
                        "no command for sample {seq} within {timeout:?}"
                    )))
                }
                Wait::TimedOut => {}
            }
        }
        Ok(())
    }
}

/// Every published set is appended to this journal at once (a killed optimiser writes no
/// report), so a restarted one continues the versions and knows the set in service.
const JOURNAL: &str = "published.jsonl";

fn journal(dir: &std::path::Path, set: &ParamSet, t: f64) {
    use std::io::Write;
    let line = serde_json::json!({"version": set.version, "t": t, "values": set.values()});
    let f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(dir.join(JOURNAL));
    if let Ok(mut f) = f {
        let _ = writeln!(f, "{line}");
    }
}

/// The last set in the journal: its version and values.
/// Only the journal's tail is read: it grows with the run, which may have no end.
fn last_published(dir: &std::path::Path) -> Option<(u64, Vec<f64>)> {
    use std::io::{Read, Seek, SeekFrom};
    const TAIL: u64 = 64 * 1024;
    let mut f = std::fs::File::open(dir.join(JOURNAL)).ok()?;
    let len = f.metadata().ok()?.len();
    f.seek(SeekFrom::Start(len.saturating_sub(TAIL))).ok()?;
    let mut tail = Vec::new();
    f.take(TAIL).read_to_end(&mut tail).ok()?;
    let text = String::from_utf8_lossy(&tail);
    let v: serde_json::Value = serde_json::from_str(text.lines().last()?).ok()?;
    let values = v["values"]
        .as_array()?
        .iter()
        .filter_map(|x| x.as_f64())
        .collect();
    Some((v["version"].as_u64()?, values))
}

fn send_set(
    ports: &Ports,
    set: &ParamSet,
    t: f64,
    published: &mut History<PublishedSet>,
    dir: &std::path::Path,
) -> Result<(), IpcError> {
    // Journal first: a set the controller may have received is always on record for a restart.
    journal(dir, set, t);
    ports.params.send(set)?;
    published.push(PublishedSet {
        version: set.version,
        at: t,
        apply_at_seq: set.apply_at_seq,
        values: set.values().to_vec(),
    });
    Ok(())
}

fn publish(
    scn: &Scenario,
    ports: &Ports,
    i: usize,
    apply_at_seq: u64,
    published: &mut History<PublishedSet>,
) -> Result<(), IpcError> {
    let set = scheduled_set(scn, i, apply_at_seq);
    send_set(
        ports,
        &set,
        scn.optimiser.schedule[i].at,
        published,
        &scn.output.dir,
    )
}

/// User and system CPU time of this process, all threads, s (0 when unknown).
fn process_cpu_seconds() -> f64 {
    // SAFETY: getrusage fills the zeroed struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return 0.0;
    }
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    s(u.ru_utime) + s(u.ru_stime)
}

/// Evaluation workers (`optimiser.workers = "zenoh"`): the optimiser listens for them and
/// `optim::evaluate` spreads its costly populations over them.
mod workers {
    use crate::config::Scenario;
    use crate::report::summary::OptimiserReport;
    use std::sync::atomic::AtomicBool;

    /// The workers this optimiser listens for, if any.
    #[derive(Default)]
    pub struct Pool {
        #[cfg(feature = "zenoh")]
        zenoh: Option<&'static crate::net::workers::ZenohWorkers>,
    }

    /// Listen for workers and install them; wait for `workers_expect` of them.
    #[cfg(feature = "zenoh")]
    pub fn start(scn: &Scenario, stop: &AtomicBool) -> Result<Pool, String> {
        let Some(w) = &scn.optimiser.workers else {
            return Ok(Pool::default());
        };
        let z = crate::net::workers::install(&w.listen, w.zenoh_config.as_deref(), w.expect, stop)?;
        Ok(Pool { zenoh: Some(z) })
    }

    /// None in this build: the configuration refuses `workers = "zenoh"` without the feature.
    #[cfg(not(feature = "zenoh"))]
    pub fn start(_: &Scenario, _: &AtomicBool) -> Result<Pool, String> {
        Ok(Pool::default())
    }

    /// The evaluations by where they ran, and every worker seen, into the report.
    pub fn finish(pool: Pool, report: &mut OptimiserReport) {
        report.evaluations = crate::optim::remote::totals();
        #[cfg(feature = "zenoh")]
        if let Some(z) = pool.zenoh {
            report.workers = z
                .stats()
                .into_iter()
                .map(|(id, s)| (id, serde_json::to_value(s).unwrap_or_default()))
                .collect();
        }
        #[cfg(not(feature = "zenoh"))]
        let Pool {} = pool;
    }
}

/// The optimiser on another host (`--connect`): the run mirrored into the namespace of remote
/// optimisers (`net::mirror::PREFIX`).
mod remote {
    use super::{fail, Failure, WHO};
    use crate::node::args::OptimiserArgs;

    #[cfg(feature = "zenoh")]
    pub type Mirror = crate::net::mirror::Mirror;
    #[cfg(not(feature = "zenoh"))]
    pub type Mirror = ();

    /// Start mirroring the run (realtime runs only) and point the process at the mirror's
    /// iceoryx2 namespace.
    #[cfg(feature = "zenoh")]
    pub fn join(cli: &mut OptimiserArgs, ep: String) -> Mirror {
        // Checked before `start` creates this process's iceoryx2 node: a refused optimiser
        // leaves nothing in the namespace (the scenario is loaded again there, as always).
        let scn = crate::node::start::load_scenario(&cli.args, WHO);
        if scn.timing.mode != crate::config::Mode::Realtime {
            fail(
                WHO,
                Failure::Setup(
                    "--connect joins realtime runs only (give --mode realtime): in lockstep the \
                     plant waits for the optimiser's acknowledgements, which do not cross the \
                     network"
                        .into(),
                ),
            );
        }
        if cli.rejoin {
            fail(
                WHO,
                Failure::Setup("--rejoin is for a run's own optimiser, not with --connect".into()),
            );
        }
        // A namespace of its own (the run's id may also be running on this host), one for
        // every remote optimiser of this user: iceoryx2 keeps a small management file per
        // prefix, and a node created here cleans up what a killed predecessor left.
        cli.args.ipc_prefix = crate::net::mirror::PREFIX.to_string();
        let ep = crate::net::Endpoint::Connect(ep);
        crate::net::mirror::Mirror::start(
            &cli.args.run_id,
            &cli.args.ipc_prefix,
            ep,
            cli.zenoh_config.clone(),
        )
        .unwrap_or_else(|e| fail(WHO, Failure::Setup(e)))
    }

    #[cfg(not(feature = "zenoh"))]
    pub fn join(_: &mut OptimiserArgs, _: String) -> Mirror {
        fail(WHO, Failure::Setup(crate::needs_zenoh("--connect")))
    }

    /// Stop the mirror and write what crossed the network (network.json).
    #[cfg(feature = "zenoh")]
    pub fn finish(m: Mirror, dir: &std::path::Path) {
        match m.join() {
            Ok(r) => {
                eprintln!(
                    "{WHO}: over the network: {} states, {} commands in; {} sets, {} estimates out",
                    r.states_in, r.commands_in, r.params_out, r.estimates_out
                );
                if let Err(e) = crate::report::write_json(dir, "network.json", &r) {
                    eprintln!("{WHO}: cannot write network.json: {e}");
                }
            }
            Err(e) => eprintln!("{WHO}: network mirror: {e}"),
        }
    }

    #[cfg(not(feature = "zenoh"))]
    pub fn finish(_: Mirror, _: &std::path::Path) {}
}
