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
    Command, ModelEstimate, OperatorAck, OperatorAction, OperatorCommand, OperatorOutcome,
    OptimiserAck, OptimiserStatus, ParamSet, PlantState, STATE_FLAG_END,
};
use crate::node::start::{fail, leave_and_fail, ports, start, Failure, Started};
use crate::report::history::History;
use crate::report::write_json;
use crate::rt::privileges::set_nice;
use crate::run_report::summary::{OptimiserReport, PublishedSet};
use crate::sim::{scheduled_seq, scheduled_set};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const WHO: &str = "evoloop-optimiser";

/// Gain sets kept for an operator's revert besides version 0 (the set before tuning).
pub const SETS_KEPT: usize = 4096;

struct Ports {
    /// Lockstep: the plant rings at every sample the optimiser must acknowledge.
    sync: Doorbell,
    params: Pub<ParamSet>,
    estimate: Pub<ModelEstimate>,
    /// The general indirect scheme's estimated transfer function.
    estimate_linear: Option<Pub<crate::msg::LinearEstimate>>,
    status: Pub<OptimiserStatus>,
    ack: Pub<OptimiserAck>,
    command: Sub<Command>,
    state: Sub<PlantState>,
    /// An operator's commands (`evoloop operator`, `evoloop top`) and the answers. Only a
    /// tuning scheme listens: an optimiser that only publishes a schedule (or nothing) leaves
    /// the commands to one that tunes the run from another host (`evoloop bridge`), and
    /// without one `evoloop operator` says no optimiser listens.
    operator: Option<Sub<OperatorCommand>>,
    operator_ack: Pub<OperatorAck>,
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
            estimate_linear: match scn.optimiser.model {
                Some(_) => Some(ipc.publisher(Topic::LinearEstimate, false)?),
                None => None,
            },
            status: ipc.publisher(Topic::OptimiserStatus, false)?,
            operator: match scn.optimiser.mode {
                OptimiserMode::Direct | OptimiserMode::Indirect | OptimiserMode::Identify => {
                    Some(ipc.subscriber(Topic::Operator, 4, false)?)
                }
                OptimiserMode::Off | OptimiserMode::Schedule => None,
            },
            operator_ack: ipc.publisher(Topic::OperatorAck, false)?,
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
    // What crossed the network, said and written (network.json).
    match mirror.map(|m| m.finish(&scn.output.dir)) {
        Some(Ok(line)) => eprintln!("{WHO}: over the network: {line}"),
        Some(Err(e)) => eprintln!("{WHO}: network mirror: {e}"),
        None => {}
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
    let mut serve = Serve::new(scn, ports, rejoin)?;
    // The histories go into the report however serving ended.
    let result = serve.serve(stop, report);
    serve.finish(report);
    result
}

/// What the optimiser serves: the scenario's schedule and at most one scheme (its mode's), and
/// every set it has published.
struct Serve<'a> {
    scn: &'a Scenario,
    ports: &'a Ports,
    lockstep: bool,
    /// Lockstep: samples between acknowledgements.
    sync: u64,
    /// Lockstep: the longest wait for the plant or the controller; realtime: the longest silence.
    timeout: Duration,
    /// The next scheduled set to publish (schedule mode).
    next_set: usize,
    indirect: Option<crate::indirect::Indirect>,
    live: Option<crate::rkgnn::live::LiveIdentify>,
    direct: Option<DirectLive>,
    published: History<PublishedSet>,
    journal: Journal,
    /// Epochs told to watchers so far.
    status_epochs: u64,
    /// Every gain set published, by version, for an operator's revert (0: the set before
    /// tuning).
    sets: std::collections::BTreeMap<u64, Vec<f64>>,
    /// An operator's hold or stop is in force.
    held: bool,
    stopped: bool,
    /// The plant's last sample has come: commands are answered `Stopped`.
    ended: bool,
}

fn io(e: IpcError) -> Failure {
    Failure::Setup(e.to_string())
}

impl<'a> Serve<'a> {
    /// The scheme of the optimiser's mode; a rejoining process continues the published versions.
    fn new(scn: &'a Scenario, ports: &'a Ports, rejoin: bool) -> Result<Self, Failure> {
        let mode = scn.optimiser.mode;
        let last = || rejoin.then(|| last_published(&scn.output.dir)).flatten();
        let mut serve = Serve {
            scn,
            ports,
            lockstep: scn.timing.mode == Mode::Lockstep,
            sync: scn.sync_samples(),
            timeout: Duration::from_secs_f64(scn.timing.start_timeout()),
            next_set: 0,
            indirect: None,
            live: None,
            direct: None,
            published: History::new(crate::indirect::HISTORY),
            journal: Journal::open(&scn.output.dir),
            status_epochs: 0,
            sets: [(0, scn.controller.tunable().gains.clone())].into(),
            held: false,
            stopped: false,
            ended: false,
        };
        if let Some((version, values)) = last() {
            // A restarted optimiser keeps the last set it published for an operator's revert.
            serve.sets.insert(version, values);
        }
        if mode == OptimiserMode::Indirect {
            let mut ind =
                crate::indirect::Indirect::new(scn).map_err(|e| Failure::Setup(e.to_string()))?;
            if let Some((version, params)) = last() {
                ind.resume(version, params);
            }
            serve.indirect = Some(ind);
        }
        if mode == OptimiserMode::Identify {
            let mut l = crate::rkgnn::live::LiveIdentify::new(scn)
                .map_err(|e| Failure::Setup(e.to_string()))?;
            if let Some((version, values)) = last() {
                l.resume(version, &values);
            }
            serve.live = Some(l);
        }
        if mode == OptimiserMode::Direct {
            let mut tuner =
                crate::direct::DirectTuner::new(scn).map_err(|e| Failure::Setup(e.to_string()))?;
            if let Some((version, _)) = last() {
                tuner.resume(version);
            }
            serve.direct = Some(DirectLive::new(tuner, scn));
        }
        Ok(serve)
    }

    /// Ends at the plant's last sample, at a stop request (a run until stopped ends so), when
    /// the plant has gone or at an IPC failure.
    fn serve(&mut self, stop: &AtomicBool, report: &mut OptimiserReport) -> Result<(), Failure> {
        let mut last_state = Instant::now();
        let mut first = true;
        while !stop.load(Ordering::Relaxed) {
            let Some(state) = self.receive()? else {
                // In realtime the plant keeps sampling; silence this long means it is gone.
                // The first state may take as long as the plant process's start.
                let timeout = if first {
                    self.scn.first_state_wait().max(self.timeout)
                } else {
                    self.timeout
                };
                if last_state.elapsed() > timeout {
                    return Err(Failure::PeerTimeout(format!(
                        "no plant state within {timeout:?}"
                    )));
                }
                continue;
            };
            last_state = Instant::now();
            first = false;
            report.states_seen += 1;
            self.tell_epochs()?;
            self.observe(&state, report)?;
            if state.flags & STATE_FLAG_END != 0 {
                // Commands still queued are answered, not carried out: the run has ended.
                self.ended = true;
                self.operate(&state, report)?;
                return Ok(());
            }
            if !self.lockstep {
                self.operate(&state, report)?;
                self.free_running(&state)?;
            } else if self.scn.is_sync_point(state.seq) {
                // Lockstep: at synchronisation points only, so a revert's set goes out before
                // the acknowledgement like any other.
                self.operate(&state, report)?;
                self.at_sync_point(&state, report)?;
            }
        }
        Ok(())
    }

    /// The next plant state, or None after a slice of silence.
    fn receive(&self) -> Result<Option<PlantState>, Failure> {
        let slice = Duration::from_millis(100);
        let state = &self.ports.state;
        if !self.lockstep {
            return Ok(match state.wait_next(Duration::ZERO, slice).map_err(io)? {
                Wait::Got(s) => Some(s),
                Wait::TimedOut => None,
            });
        }
        // Lockstep: sleep on the sync bell and catch up on the queue.
        if let Some(s) = state.next().map_err(io)? {
            return Ok(Some(s));
        }
        self.ports.sync.wait(slice).map_err(io)?;
        state.next().map_err(io)
    }

    /// Epochs that ended since the last sample, for watchers.
    fn tell_epochs(&mut self) -> Result<(), Failure> {
        let epochs = self
            .indirect
            .as_ref()
            .map(|i| &i.epochs)
            .or(self.live.as_ref().map(|l| &l.epochs));
        let Some(e) = epochs.filter(|e| e.offered() != self.status_epochs) else {
            return Ok(());
        };
        self.status_epochs = e.offered();
        let Some(last) = e.last() else {
            return Ok(());
        };
        let status = OptimiserStatus {
            t: last.t,
            epochs: self.status_epochs,
            published: self.published.offered(),
            best_cost: last.best_cost,
            in_service_cost: last.in_service_cost,
        };
        self.ports.status.send(&status).map_err(io)
    }

    /// Every scheme sees the state (and the direct one the commands that arrived with it).
    fn observe(&mut self, state: &PlantState, report: &mut OptimiserReport) -> Result<(), Failure> {
        if let Some(d) = self.direct.as_mut() {
            d.push_state(state);
        }
        while let Some(c) = self.ports.command.next().map_err(io)? {
            report.commands_seen += 1;
            if let Some(d) = self.direct.as_mut() {
                d.push_command(&c);
            }
        }
        if let Some(ind) = self.indirect.as_mut() {
            // Each new 10 Hz record goes out as telemetry too.
            if let Some(e) = ind.observe(state) {
                let msg = ModelEstimate {
                    t: e.t,
                    value: e.value,
                    std: e.std,
                    last_version: ind.version(),
                    // Lockstep: delivered before the plant passes the next synchronisation
                    // point, so the controller adopts it at the sample after that one.
                    apply_at_seq: if self.lockstep {
                        self.scn.next_sync_point(state.seq) + 1
                    } else {
                        0
                    },
                };
                self.ports.estimate.send(&msg).map_err(io)?;
                if let (Some(port), Some((num, den))) =
                    (self.ports.estimate_linear.as_ref(), ind.transfer_function())
                {
                    let mut lin = crate::msg::LinearEstimate {
                        t: e.t,
                        apply_at_seq: msg.apply_at_seq,
                        poles: (den.len() - 1) as u32,
                        ..Default::default()
                    };
                    lin.num[..num.len()].copy_from_slice(&num);
                    lin.den[..den.len()].copy_from_slice(&den);
                    port.send(&lin).map_err(io)?;
                }
            }
        }
        if let Some(l) = self.live.as_mut() {
            l.observe(state);
        }
        Ok(())
    }

    /// Lockstep, at a synchronisation point: the sets due go out, then the plant may go on.
    fn at_sync_point(
        &mut self,
        state: &PlantState,
        report: &mut OptimiserReport,
    ) -> Result<(), Failure> {
        let (scn, t, next) = (self.scn, state.t, state.seq + 1);
        let schedule = &scn.optimiser.schedule;
        // Every set due within the next interval.
        while scn.optimiser.mode == OptimiserMode::Schedule && self.next_set < schedule.len() {
            let at = scheduled_seq(schedule[self.next_set].at, scn.timing.period);
            if at > state.seq + self.sync {
                break;
            }
            self.publish_scheduled(at.max(next))?;
        }
        // Paced by simulated time: the plant waits for the acknowledgement, so the epochs
        // run at the same samples in every run of a seed.
        let interval = self.sync as f64 * scn.timing.period;
        let tuning = !self.held;
        if let Some(set) = self
            .indirect
            .as_mut()
            .filter(|_| tuning)
            .and_then(|i| i.paced(t, interval, next))
        {
            self.send(&set, t)?;
        }
        // At fixed simulated times, the plant waiting: reproducible per seed.
        if let Some(m) = self
            .live
            .as_mut()
            .filter(|_| tuning)
            .and_then(|l| l.attempt(t, next))
        {
            self.send_model(&m, t)?;
        }
        // Every sample up to this one seen with its command, the next trial (if one starts
        // at the next sample) goes out before the plant may take that sample.
        if let Some(d) = self.direct.as_mut() {
            let seen = &mut report.commands_seen;
            d.wait_through(state.seq, &self.ports.command, seen, self.timeout)?;
            if let Some(set) = d.tuner.at(next, None) {
                self.send(&set, t)?;
            }
        }
        let ack = OptimiserAck {
            through_seq: state.seq,
        };
        self.ports.ack.send(&ack).map_err(io)
    }

    /// Realtime: the sets due go out as soon as they are known; the controller applies each at
    /// its next cycle.
    fn free_running(&mut self, state: &PlantState) -> Result<(), Failure> {
        let (scn, t) = (self.scn, state.t);
        let schedule = &scn.optimiser.schedule;
        while scn.optimiser.mode == OptimiserMode::Schedule
            && self.next_set < schedule.len()
            && t >= schedule[self.next_set].at
        {
            self.publish_scheduled(0)?;
        }
        // Epochs back to back on the worker thread while this one goes on reading the stream,
        // so an epoch longer than the state queue loses no sample.
        if let Some(set) = self
            .indirect
            .as_mut()
            .and_then(|i| i.finish_epoch(0, false))
        {
            self.send(&set, t)?;
        }
        if let Some(ind) = self.indirect.as_mut().filter(|_| !self.held) {
            ind.start_epoch(t);
        }
        if let Some(d) = self.direct.as_mut() {
            d.join();
            // A trial is sent this far ahead of its first sample (20 ms), so it reaches the
            // controller before that cycle.
            let lead = (0.02 / scn.timing.period).ceil() as u64;
            let set = d
                .through
                .and_then(|s| d.tuner.at(s + 1, Some(s + 1 + lead)));
            if let Some(set) = set {
                self.send(&set, t)?;
            }
        }
        if self.live.is_some() && !self.held && !self.ports.state.has_pending().map_err(io)? {
            if let Some(m) = self.live.as_mut().and_then(|l| l.attempt(t, 0)) {
                self.send_model(&m, t)?;
            }
        }
        Ok(())
    }

    fn send(&mut self, set: &ParamSet, t: f64) -> Result<(), Failure> {
        self.sets.insert(set.version, set.values().to_vec());
        // Bounded for a run without end: version 0 and the latest SETS_KEPT.
        if self.sets.len() > SETS_KEPT + 1 {
            let oldest = self.sets.keys().copied().find(|&v| v != 0);
            oldest.map(|v| self.sets.remove(&v));
        }
        send_set(
            self.ports,
            &[*set],
            set.values(),
            t,
            &mut self.published,
            &mut self.journal,
        )
        .map_err(io)
    }

    /// A model, in as many sets as it needs; journalled and recorded whole.
    fn send_model(&mut self, m: &crate::rkgnn::live::ModelUpdate, t: f64) -> Result<(), Failure> {
        send_set(
            self.ports,
            &m.sets(),
            &m.values,
            t,
            &mut self.published,
            &mut self.journal,
        )
        .map_err(io)
    }

    /// An operator's commands since the last sample: each applied, answered on `operator_ack`
    /// and recorded in the report.
    fn operate(&mut self, state: &PlantState, report: &mut OptimiserReport) -> Result<(), Failure> {
        let Some(sub) = self.ports.operator.as_ref() else {
            return Ok(());
        };
        let mut commands = Vec::new();
        while let Some(c) = sub.next().map_err(io)? {
            commands.push(c);
        }
        for c in commands {
            let action = OperatorAction::try_from(c.action).ok();
            let (outcome, version) = match action {
                Some(_) if self.ended => (OperatorOutcome::Stopped, self.last_version()),
                Some(a) => self.apply(a, c.version, state)?,
                None => (OperatorOutcome::UnknownAction, self.last_version()),
            };
            let ack = OperatorAck {
                id: c.id,
                action: c.action,
                outcome: outcome.code(),
                t: state.t,
                version,
            };
            self.ports.operator_ack.send(&ack).map_err(io)?;
            report
                .operator
                .push(crate::run_report::summary::OperatorEvent {
                    t: state.t,
                    seq: state.seq,
                    action,
                    requested_version: (action == Some(OperatorAction::Revert))
                        .then_some(c.version),
                    outcome,
                    version,
                });
        }
        Ok(())
    }

    /// Realtime: an indirect epoch running on its thread must not publish after a hold, a stop
    /// or a revert. Waiting for it holds up this thread (not the loop) for the rest of the
    /// epoch; the samples it misses meanwhile are counted (`samples_missed`).
    fn discard_epoch(&mut self) {
        if let Some(ind) = self.indirect.as_mut() {
            ind.discard_epoch();
        }
    }

    /// The last version published (a set or a model, by any scheme, or before a restart), or
    /// reserved by the direct scheme for a revert.
    fn last_version(&self) -> u64 {
        let sets = self.sets.keys().next_back().copied().unwrap_or(0);
        let published = self.published.last().map_or(0, |p| p.version);
        let direct = self.direct.as_ref().map_or(0, |d| d.tuner.last_version());
        let indirect = self.indirect.as_ref().map_or(0, |i| i.version());
        sets.max(published).max(direct).max(indirect)
    }

    /// One operator command: what came of it and the version it leaves (see `OperatorAction`).
    fn apply(
        &mut self,
        action: OperatorAction,
        version: u64,
        state: &PlantState,
    ) -> Result<(OperatorOutcome, u64), Failure> {
        use OperatorAction::*;
        if self.direct.is_none() && self.indirect.is_none() && self.live.is_none() {
            // A schedule (or nothing) publishes here: no tuning to hold or revert.
            return Ok((OperatorOutcome::NotHere, self.last_version()));
        }
        if self.stopped && action != Revert {
            return Ok((OperatorOutcome::Stopped, self.last_version()));
        }
        match action {
            Hold | Resume | Stop => {
                if action != Resume {
                    self.discard_epoch();
                }
                self.held = action != Resume;
                self.stopped = action == Stop;
                if let Some(d) = self.direct.as_mut() {
                    d.tuner.hold(self.held);
                    if action == Stop {
                        d.tuner.stop();
                    }
                }
                return Ok((OperatorOutcome::Done, self.last_version()));
            }
            Revert => {}
        }
        if self.live.is_some() {
            return Ok((OperatorOutcome::NotHere, self.last_version()));
        }
        let Some(values) = self.sets.get(&version).cloned() else {
            return Ok((OperatorOutcome::UnknownVersion, self.last_version()));
        };
        self.discard_epoch();
        self.held = true;
        if let Some(d) = self.direct.as_mut() {
            // At the next repetition boundary, through the tuner (a trial may be under way).
            return Ok((OperatorOutcome::Done, d.tuner.revert(values)));
        }
        let new = self.last_version() + 1;
        let at = if self.lockstep { state.seq + 1 } else { 0 };
        let set = ParamSet::new(new, at, self.scn.controller.param_kind(), &values);
        self.send(&set, state.t)?;
        if let Some(ind) = self.indirect.as_mut() {
            // Its next set follows this version, and it judges sets against these values.
            ind.resume(new, values);
        }
        Ok((OperatorOutcome::Done, new))
    }

    /// The next set of the schedule, applied at `apply_at_seq` (0: at once).
    fn publish_scheduled(&mut self, apply_at_seq: u64) -> Result<(), Failure> {
        let (scn, i) = (self.scn, self.next_set);
        let set = scheduled_set(scn, i, apply_at_seq);
        self.send(&set, scn.optimiser.schedule[i].at)?;
        self.next_set += 1;
        Ok(())
    }

    /// The schemes' histories and the published sets into the report.
    fn finish(self, report: &mut OptimiserReport) {
        if let Some(ind) = self.indirect {
            report.samples_missed = ind.samples_missed;
            report.monitor = ind.monitor();
            report.estimates = ind.estimates.into_vec();
            report.epochs = ind.epochs.into_vec();
        }
        if let Some(l) = self.live {
            report.epochs = l.epochs.into_vec();
        }
        if let Some(d) = self.direct {
            report.direct = Some(d.tuner.report());
        }
        report.published_count = self.published.offered();
        report.journal_error = self.journal.error;
        report.published = self.published.into_vec();
    }
}

/// The direct scheme in this process: each state paired with the command that answered it, in
/// sequence order, for the tuner. Fixed-size queues (the plant runs at most a queue ahead).
struct DirectLive {
    tuner: crate::direct::DirectTuner,
    reference: crate::reference::Reference,
    n: usize,
    states: std::collections::VecDeque<(u64, f64, [f64; crate::msg::MAX_JOINTS])>,
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

/// `published.jsonl`, opened once for the run (never through a link, see
/// `evoloop_files::append`) and held: a link planted at the name later in the run is not
/// reopened, so it is never written through. What could not be written is kept for the report.
struct Journal {
    path: std::path::PathBuf,
    file: Option<std::fs::File>,
    error: Option<String>,
}

impl Journal {
    fn open(dir: &std::path::Path) -> Journal {
        let path = dir.join(JOURNAL);
        let (file, error) = match evoloop_files::append(&path) {
            Ok(f) => (Some(f), None),
            Err(e) => {
                eprintln!("{WHO}: {e}; the published sets are not journalled");
                (None, Some(e.to_string()))
            }
        };
        Journal { path, file, error }
    }

    fn add(&mut self, version: u64, values: &[f64], t: f64) {
        use std::io::Write;
        let line = serde_json::json!({"version": version, "t": t, "values": values});
        let Some(f) = &mut self.file else { return };
        if let Err(e) = writeln!(f, "{line}") {
            if self.error.is_none() {
                let e = evoloop_files::named(&self.path, "cannot append to", e).to_string();
                eprintln!("{WHO}: {e}");
                self.error = Some(e);
            }
        }
    }
}

/// The last set in the journal: its version and values.
/// Only the journal's tail is read: it grows with the run, which may have no end. It must hold
/// the longest line: a model is journalled whole (arm7's 3396 values: about 67 kB; the most a
/// controller takes, PENDING_CAPACITY parts, about 16 000 values: under 400 kB).
fn last_published(dir: &std::path::Path) -> Option<(u64, Vec<f64>)> {
    use std::io::{Read, Seek, SeekFrom};
    const TAIL: u64 = 1024 * 1024;
    let mut f = evoloop_files::open_own(&dir.join(JOURNAL)).ok()?;
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

/// One set, or the parts of one model (`sets`, sharing version and `apply_at_seq`), whose
/// values are `values`: journalled and recorded as the one set they are.
fn send_set(
    ports: &Ports,
    sets: &[ParamSet],
    values: &[f64],
    t: f64,
    published: &mut History<PublishedSet>,
    journal: &mut Journal,
) -> Result<(), IpcError> {
    let first = sets[0];
    // Journal first: a set the controller may have received is always on record for a restart.
    journal.add(first.version, values, t);
    for set in sets {
        ports.params.send(set)?;
    }
    published.push(PublishedSet {
        version: first.version,
        at: t,
        apply_at_seq: first.apply_at_seq,
        values: values.to_vec(),
    });
    Ok(())
}

/// User and system CPU time of this process, all threads, s (0 when unknown).
fn process_cpu_seconds() -> f64 {
    // SAFETY: getrusage fills the zeroed struct it is given.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: a valid rusage to fill, for this process.
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
    use crate::run_report::summary::OptimiserReport;
    use std::sync::atomic::AtomicBool;

    /// The workers this optimiser listens for, if any.
    pub type Pool = Option<&'static dyn crate::network::Workers>;

    /// Listen for workers and install them; wait for `workers_expect` of them. (`load` refuses
    /// `workers = "zenoh"` in a binary without the network.)
    pub fn start(scn: &Scenario, stop: &AtomicBool) -> Result<Pool, String> {
        let Some(w) = &scn.optimiser.workers else {
            return Ok(None);
        };
        let net =
            crate::network::required("optimiser.workers = \"zenoh\"").map_err(|e| e.to_string())?;
        net.install_workers(&w.listen, w.zenoh_config.as_deref(), w.expect, stop)
            .map(Some)
            .map_err(|e| e.to_string())
    }

    /// The evaluations by where they ran, and every worker seen, into the report.
    pub fn finish(pool: Pool, report: &mut OptimiserReport) {
        report.evaluations = crate::optim::remote::totals();
        if let Some(z) = pool {
            report.workers = z.stats();
        }
    }
}

/// The optimiser on another host (`--connect`): the run mirrored into the namespace of remote
/// optimisers (`Network::mirror_prefix`).
mod remote {
    use super::{fail, Failure, WHO};
    use crate::node::args::OptimiserArgs;

    /// Start mirroring the run (realtime runs only) and point the process at the mirror's
    /// iceoryx2 namespace.
    pub fn join(cli: &mut OptimiserArgs, ep: String) -> Box<dyn crate::network::Mirror> {
        let net = crate::network::required("--connect")
            .unwrap_or_else(|e| fail(WHO, Failure::Setup(e.to_string())));
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
        cli.args.ipc_prefix = net.mirror_prefix().to_string();
        net.mirror(&cli.args.run_id, ep, cli.zenoh_config.clone())
            .unwrap_or_else(|e| fail(WHO, Failure::Setup(e.to_string())))
    }
}

#[cfg(test)]
mod tests {
    use super::{last_published, Journal, JOURNAL};

    /// A rejoining optimiser continues from the journal's last line, which holds a whole model:
    /// arm7's is longer than the 64 kB tail read before models travelled in parts.
    #[test]
    fn the_last_journalled_model_reads_back_whole_however_long() {
        let dir = tempfile::tempdir().unwrap();
        let gains = [1.0, 2.0];
        let mut journal = Journal::open(dir.path());
        journal.add(1, &gains, 0.5);
        assert_eq!(last_published(dir.path()), Some((1, gains.to_vec())));
        // 3396 values of 17 significant digits, as arm7's models are written.
        let model: Vec<f64> = (0..3396)
            .map(|i| 0.123_456_789_012_345_6 * i as f64)
            .collect();
        journal.add(2, &model, 1.0);
        let (version, values) = last_published(dir.path()).unwrap();
        assert_eq!(version, 2);
        assert_eq!(values, model);
    }

    /// A link planted at the journal's name during the run, after the optimiser opened it, is
    /// never written through: the journal holds its own file, and a restart refuses to read
    /// the link.
    #[test]
    fn a_link_planted_at_the_journal_during_the_run_is_not_written_through() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("root-only.txt");
        std::fs::write(&target, "keep me").unwrap();
        let mut journal = Journal::open(dir.path());
        journal.add(1, &[1.0], 0.1);
        let name = dir.path().join(JOURNAL);
        std::fs::remove_file(&name).unwrap();
        std::os::unix::fs::symlink(&target, &name).unwrap();
        journal.add(2, &[2.0], 0.2);
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
        assert_eq!(last_published(dir.path()), None, "the link is not read");
        let again = Journal::open(dir.path());
        assert!(again.file.is_none());
        let e = again.error.unwrap();
        assert!(e.contains("symbolic link"), "{e}");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
    }
}
