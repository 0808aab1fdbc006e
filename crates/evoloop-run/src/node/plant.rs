//! evoloop-plant: plays the hardware. Integrates the plant (RK4, fixed sub-steps), samples it
//! every control period and applies the latest command as a zero-order hold.
//!
//! lockstep: publish sample k, wait for the command answering k, integrate one period, repeat;
//!           every `sync_samples` samples also wait for the optimiser's acknowledgement, so the
//!           optimiser's parameter sets land on the same sample in every run.
//! realtime: tick on absolute deadlines of the wall clock; between ticks, integrate up to the
//!           moment each command arrives and switch to it; fall back to the safe command when
//!           commands stop for `command_timeout_periods`.

use super::args::ProcessArgs;
use crate::config::{Mode, Scenario};
use crate::ipc::{Bell, Doorbell, Pub, Spin, Sub, Topic, Waited};
use crate::msg::MAX_JOINTS;
use crate::msg::{Command, OptimiserAck, PlantState, STATE_FLAG_END, STATE_FLAG_SAFE};
use crate::node::start::{fail, leave_and_fail, ports, start, Failure, Started};
use crate::plant::PlantSim;
use crate::report::write_json;
use crate::rt::{apply_privileges, now_ns};
use crate::run_report::summary::PlantReport;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

const WHO: &str = "evoloop-plant";

struct Ports {
    ready: Doorbell,
    sync: Bell,
    state: Pub<PlantState>,
    command: Sub<Command>,
    ack: Sub<OptimiserAck>,
}

/// The plant process: `evoloop plant ...` or `evoloop-plant ...`.
pub fn main(args: &ProcessArgs) {
    let Started {
        scenario: scn,
        stop,
        ipc,
    } = start(args, WHO);
    let ports = ports(WHO, || {
        Ok(Ports {
            ready: ipc.doorbell(Topic::Ready)?,
            sync: ipc.bell(Topic::Sync)?,
            command: ipc.subscriber(Topic::Command, 8, true)?,
            ack: ipc.subscriber(Topic::OptimiserAck, 4, true)?,
            state: ipc.publisher(Topic::State, true)?,
        })
    });

    let mut sim = scn.plant.simulation(scn.seed);
    let mut report = PlantReport {
        mode: scn.timing.mode,
        ..Default::default()
    };
    if scn.timing.mode == Mode::Realtime {
        report.rt = apply_privileges(&scn.plant_rt());
    }
    // Start only when the controller and the optimiser have subscribed to the state and the
    // optimiser's acknowledgement publisher exists (it creates that last). Without the latter a
    // lockstep plant would not wait for the optimiser and could finish a short run before a
    // starved optimiser ever received: samples of a publisher that is gone before the
    // subscriber's first receive are lost, the end sample with them.
    wait_for_peers(&ports, &stop, scn.timing.start_timeout());
    let t0 = Instant::now();
    let result = match scn.timing.mode {
        Mode::Lockstep => run_lockstep(&scn, &ports, &mut sim, &stop, &mut report),
        Mode::Realtime => run_realtime(&scn, &ports, &mut sim, &stop, &mut report),
    };
    report.wall_s = t0.elapsed().as_secs_f64();
    report.interrupted = stop.load(Ordering::SeqCst);
    if let Err(e) = write_json(&scn.output.dir, "plant.json", &report) {
        eprintln!("{WHO}: cannot write plant.json: {e}");
    }
    if let Err(e) = result {
        leave_and_fail(WHO, ports, ipc, e);
    }
}

fn wait_for_peers(ports: &Ports, stop: &AtomicBool, timeout_s: f64) {
    let t0 = Instant::now();
    while ports.command.publishers() < 1
        || ports.state.subscribers() < 2
        || ports.ack.publishers() < 1
    {
        if stop.load(Ordering::SeqCst) {
            return;
        }
        if t0.elapsed().as_secs_f64() > timeout_s {
            fail(
                WHO,
                Failure::PeerTimeout("controller/optimiser did not connect in time".into()),
            );
        }
        // Each peer announces itself once its ports exist; re-check on every announcement (and
        // every 100 ms, in case one came before this listener existed).
        if let Err(e) = ports.ready.wait(Duration::from_millis(100)) {
            fail(WHO, Failure::Setup(e.to_string()));
        }
    }
}

/// Send the sample, then connect to ports that joined since the last (a viewer, a bridge):
/// after the send, so the mapping a new connection takes never delays a sample. A newcomer
/// that cannot be connected is left out (iceoryx2 does not try it again), not the end of the
/// run.
fn publish(ports: &Ports, msg: &PlantState) -> Result<(), Failure> {
    ports
        .state
        .send(msg)
        .map_err(|e| Failure::Setup(e.to_string()))?;
    for e in [
        ports.state.update_connections(),
        ports.command.update_connections(),
    ]
    .into_iter()
    .filter_map(Result::err)
    {
        eprintln!("plant: {e}; the run goes on without that port");
    }
    Ok(())
}

fn run_lockstep(
    scn: &Scenario,
    ports: &Ports,
    sim: &mut PlantSim,
    stop: &AtomicBool,
    report: &mut PlantReport,
) -> Result<(), Failure> {
    let n = scn.cycles();
    let dt = scn.timing.period;
    // Two waiting places, each polling while its peer answers in time.
    let poll = Duration::from_micros(scn.timing.spin_us);
    let (mut answer, mut ack) = (Spin::new(poll), Spin::new(poll));
    let timeout = Duration::from_secs_f64(scn.timing.lockstep_timeout);
    let n_u = sim.plant.n_inputs();
    let mut u = [0.0; MAX_JOINTS];
    let mut msg = PlantState::default();
    // Whether the optimiser paces the loop: it stops after one missed acknowledgement and comes
    // back with the next one the optimiser sends.
    let mut paced = true;
    for k in 0..=n {
        sim.sample(k, now_ns(), &u[..n_u], &mut msg);
        diverged(sim, k)?;
        let ring = |ports: &Ports| ports.sync.ring().map_err(|e| Failure::Setup(e.to_string()));
        if k == n {
            msg.flags = STATE_FLAG_END;
            publish(ports, &msg)?;
            ring(ports)?;
            break;
        }
        publish(ports, &msg)?;
        report.samples += 1;
        if scn.is_sync_point(k) {
            // The optimiser sleeps between these samples and catches up on the queue here.
            ring(ports)?;
            wait_for_optimiser(ports, k, &mut ack, timeout, stop, &mut paced, report)?;
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                return Ok(());
            }
        }
        let cmd = match ports
            .command
            .wait_for(&mut answer, timeout, stop, |c: &Command| c.state_seq == k)
            .map_err(|e| Failure::Setup(e.to_string()))?
        {
            Waited::Got(c) => c,
            Waited::Stopped => return Ok(()),
            Waited::TimedOut => {
                return Err(Failure::PeerTimeout(format!(
                    "controller did not answer sample {k} within {timeout:?}"
                )))
            }
        };
        report.commands_received += 1;
        u[..n_u].copy_from_slice(&cmd.u[..n_u]);
        sim.advance(&u[..n_u], dt);
    }
    Ok(())
}

/// Beyond any plant's physical range, in the state's own units (m, rad, m/s, K...).
pub const DIVERGED: f64 = 1e9;

/// Err if the state at sample `k` is non-finite or beyond `DIVERGED`: the run must end there as
/// failed, not run on and report "ok" (a stall on a safe command of 1e300 drove a state to
/// 8e299 and the run ended "ok"). A loop over the state, once per sample.
fn diverged(sim: &PlantSim, k: u64) -> Result<(), Failure> {
    match sim
        .x
        .iter()
        .position(|v| !v.is_finite() || v.abs() > DIVERGED)
    {
        None => Ok(()),
        Some(i) => Err(Failure::Diverged(format!(
            "the plant's state diverged at sample {k} (t = {:.4} s): x[{i}] = {:e}",
            sim.t, sim.x[i]
        ))),
    }
}

/// Lockstep: at synchronisation point `k`, wait until the optimiser has seen sample `k`, so its
/// sets land at the same samples in every run of a seed.
///
/// The optimiser is not on the control path. While none is connected (it died and its resources
/// were cleaned up, until a restarted one rejoins) the loop goes on. One that is connected but
/// silent for `timeout` (stopped, swapped out, stuck) is no longer waited for: the loop goes on,
/// the sample is recorded in `optimiser_stalls` (the run is reproducible only up to there), and
/// pacing resumes with the next acknowledgement it sends, which, since its queue holds a whole
/// interval, it will send for the sample the plant is at.
fn wait_for_optimiser(
    ports: &Ports,
    k: u64,
    spin: &mut Spin,
    timeout: Duration,
    stop: &AtomicBool,
    paced: &mut bool,
    report: &mut PlantReport,
) -> Result<(), Failure> {
    let io = |e: crate::ipc::IpcError| Failure::Setup(e.to_string());
    let t_wait = std::time::Instant::now();
    loop {
        if ports.ack.publishers() == 0 {
            report.syncs_without_optimiser += 1;
            return Ok(());
        }
        if !*paced {
            // Not waited for since it stalled: take it back once it acknowledges anything.
            let mut heard = false;
            while ports.ack.next().map_err(io)?.is_some() {
                heard = true;
            }
            if !heard {
                return Ok(());
            }
            *paced = true;
            report.optimiser_resumed += 1;
            eprintln!("plant: the optimiser acknowledges again; pacing it from sample {k}");
        }
        let slice = Duration::from_millis(200).min(timeout);
        match ports
            .ack
            .wait_for(spin, slice, stop, |a: &OptimiserAck| a.through_seq >= k)
            .map_err(io)?
        {
            Waited::Got(_) | Waited::Stopped => return Ok(()),
            Waited::TimedOut if t_wait.elapsed() >= timeout => {
                *paced = false;
                report.optimiser_stalls.push(k);
                eprintln!(
                    "plant: the optimiser did not acknowledge sample {k} within {timeout:?}; going \
                     on without waiting for it (this lockstep run is reproducible up to here)"
                );
                return Ok(());
            }
            Waited::TimedOut => {}
        }
    }
}

fn run_realtime(
    scn: &Scenario,
    ports: &Ports,
    sim: &mut PlantSim,
    stop: &AtomicBool,
    report: &mut PlantReport,
) -> Result<(), Failure> {
    let n = scn.cycles();
    let period = scn.period_ns();
    let n_u = sim.plant.n_inputs();
    let safe = [scn.plant.safe_command; MAX_JOINTS];
    let timeout_ns = scn.plant.command_timeout_periods as u64 * period;
    // Until the controller's first command the plant holds the safe command, as a drive does
    // before its controller is up; the timeout guards a controller that stopped commanding,
    // so it runs only once commands have started.
    let mut u = safe;
    let mut msg = PlantState::default();
    let epoch = now_ns();
    let secs = |ns: u64| (ns - epoch) as f64 * 1e-9;
    let mut last_cmd = None;
    let mut safe_mode = false;
    for k in 0..=n {
        let tick = epoch + k * period;
        scn.timing.wait.wait_until(tick);
        // Each command that arrived since the last sample is applied from the moment it was
        // sent (its stamp), as hardware would apply it on arrival: integrate up to that moment
        // with the command in force, then switch (zero-order hold). Reconstructing the switch
        // times from the stamps needs no sub-period wake-ups, whose timers are coarse.
        loop {
            let cmd = match ports.command.next() {
                Ok(Some(c)) => c,
                Ok(None) => break,
                Err(e) => return Err(Failure::Setup(e.to_string())),
            };
            let at = cmd.stamp_ns.clamp(epoch + (sim.t * 1e9) as u64, tick);
            // The controller is back (if the safe command had taken over).
            safe_mode = false;
            sim.advance(&u[..n_u], secs(at) - sim.t);
            u[..n_u].copy_from_slice(&cmd.u[..n_u]);
            last_cmd = Some(at);
            report.commands_received += 1;
            report.samples_after_last_command = 0;
        }
        // Commands stopped: the safe command from the moment the timeout ran out.
        match last_cmd {
            None => report.samples_before_first_command += 1,
            Some(last) if !safe_mode && tick.saturating_sub(last) > timeout_ns => {
                sim.advance(&u[..n_u], secs(last + timeout_ns) - sim.t);
                u[..n_u].copy_from_slice(&safe[..n_u]);
                safe_mode = true;
                if report.first_safe_sample.is_none() {
                    report.first_safe_sample = Some(k);
                    report.first_safe_periods = Some((tick - last) as f64 / period as f64);
                }
            }
            Some(_) => {}
        }
        sim.advance(&u[..n_u], k as f64 * scn.timing.period - sim.t);
        sim.sample(k, now_ns(), &u[..n_u], &mut msg);
        diverged(sim, k)?;
        if safe_mode {
            msg.flags |= STATE_FLAG_SAFE;
            report.safe_samples += 1;
        }
        if k == n || stop.load(Ordering::Relaxed) {
            msg.flags |= STATE_FLAG_END;
            publish(ports, &msg)?;
            break;
        }
        publish(ports, &msg)?;
        report.samples += 1;
        report.samples_after_last_command += 1;
    }
    Ok(())
}
