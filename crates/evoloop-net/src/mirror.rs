//! The remote optimiser's side of a bridge: the run's states, commands and telemetry from Zenoh
//! into the iceoryx2 namespace of this host's remote optimisers (`PREFIX`), and the optimiser's parameter sets,
//! estimates and status from there back to the network. The optimiser's own code runs against
//! that namespace as it would inside the run, so nothing of it changes for the network.
//!
//! Losing the link is losing the data: the optimiser sees no state, and ends as it does when
//! the plant goes silent (`no plant state within ...`); the run goes on with the set in service.

use super::bridge::{In, Out};
use super::{key, open, Endpoint, NetError, POLL};
use crate::ipc::{Ipc, Topic};
use crate::msg::{Command, ModelEstimate, OptimiserStatus, ParamSet, PlantState, Telemetry};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// The iceoryx2 prefix of the mirrored runs on a remote optimiser's host.
pub const PREFIX: &str = "evoloop_net_";

/// A running mirror: stop it with `stop` and `join`.
pub struct Mirror {
    /// Raised to end the mirror (`join` raises it too).
    pub stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<MirrorReport, NetError>>>,
}

/// Why a mirror did not start, or how it ended.
#[derive(Debug)]
pub enum MirrorError {
    /// Zenoh or iceoryx2 refused its ports, or a relay.
    Net(NetError),
    /// Its thread could not be started.
    Thread(std::io::Error),
    /// Its thread ended before its ports were ready, or panicked.
    Died(&'static str),
}

impl std::fmt::Display for MirrorError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MirrorError::Net(e) => e.fmt(f),
            MirrorError::Thread(e) => write!(f, "cannot start the network mirror: {e}"),
            MirrorError::Died(why) => write!(f, "the network mirror {why}"),
        }
    }
}

impl std::error::Error for MirrorError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MirrorError::Net(e) => e.source(),
            MirrorError::Thread(e) => Some(e),
            MirrorError::Died(_) => None,
        }
    }
}

/// What a mirror relayed (`Mirror::join`).
#[derive(Debug, Default, Clone, Copy, serde::Serialize)]
pub struct MirrorReport {
    /// States in from the network.
    pub states_in: u64,
    /// Commands in from the network.
    pub commands_in: u64,
    /// Telemetry samples in from the network.
    pub telemetry_in: u64,
    /// The optimiser's parameter sets out to the run.
    pub params_out: u64,
    /// The optimiser's model estimates and transfer functions out to the run.
    pub estimates_out: u64,
    /// An operator's commands in from the run's host, and the optimiser's answers out.
    pub operator_in: u64,
    /// The optimiser's answers to operators out to the run.
    pub operator_acks_out: u64,
    /// Messages from the network dropped because their layout is not this build's.
    pub refused: u64,
}

impl Mirror {
    /// Start mirroring run `run_id` over `ep` into iceoryx2 prefix `prefix`; returns once the
    /// ports exist (so the optimiser's ports find them), or with the error that prevented it.
    pub fn start(
        run_id: &str,
        prefix: &str,
        ep: Endpoint,
        config: Option<PathBuf>,
    ) -> Result<Self, MirrorError> {
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = sync_channel::<Result<(), NetError>>(1);
        let (run_id, prefix, s) = (run_id.to_string(), prefix.to_string(), stop.clone());
        let handle = std::thread::Builder::new()
            .name("net-mirror".into())
            .spawn(move || {
                let ports = Ports::new(&run_id, &prefix, &ep, config.as_deref());
                match ports {
                    Ok(p) => {
                        let _ = ready_tx.send(Ok(()));
                        p.serve(&s)
                    }
                    Err(e) => {
                        // `start` returns the error and drops this thread's handle: nothing
                        // reads what the thread returns.
                        let _ = ready_tx.send(Err(e));
                        Ok(MirrorReport::default())
                    }
                }
            })
            .map_err(MirrorError::Thread)?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(Self {
                stop,
                handle: Some(handle),
            }),
            Ok(Err(e)) => Err(MirrorError::Net(e)),
            Err(_) => Err(MirrorError::Died("ended before it was ready")),
        }
    }

    /// Stop the mirror and wait for its thread: what it relayed, or the error that ended it (or
    /// that it panicked).
    pub fn join(mut self) -> Result<MirrorReport, MirrorError> {
        self.stop.store(true, Ordering::SeqCst);
        match self.handle.take().map(JoinHandle::join) {
            Some(Ok(r)) => r.map_err(MirrorError::Net),
            _ => Err(MirrorError::Died("panicked")),
        }
    }
}

struct Ports {
    _z: zenoh::Session,
    state: In<PlantState>,
    command: In<Command>,
    telemetry: In<Telemetry>,
    params: Out<ParamSet>,
    estimate: Out<ModelEstimate>,
    /// The general indirect scheme's transfer function, which the controller checks sets on.
    estimate_linear: Out<crate::msg::LinearEstimate>,
    status: Out<OptimiserStatus>,
    operator: In<crate::msg::OperatorCommand>,
    operator_ack: Out<crate::msg::OperatorAck>,
}

impl Ports {
    fn new(
        run_id: &str,
        prefix: &str,
        ep: &Endpoint,
        config: Option<&std::path::Path>,
    ) -> Result<Self, NetError> {
        let z = open(ep, config)?;
        let ipc = Ipc::new("evoloop-mirror", run_id, prefix)?;
        let k = |t: Topic| key(run_id, t, false);
        let kr = |t: Topic| key(run_id, t, true);
        Ok(Self {
            // The optimiser blocks on the state's event: wake it with each state.
            state: In::new(&ipc, &z, k(Topic::State), Topic::State, true)?,
            // The direct scheme blocks on the command's event.
            command: In::new(&ipc, &z, k(Topic::Command), Topic::Command, true)?,
            telemetry: In::new(&ipc, &z, k(Topic::Telemetry), Topic::Telemetry, false)?,
            params: Out::new(&ipc, &z, Topic::Params, k(Topic::Params))?,
            estimate: Out::new(&ipc, &z, Topic::Estimate, kr(Topic::Estimate))?,
            estimate_linear: Out::new(&ipc, &z, Topic::LinearEstimate, kr(Topic::LinearEstimate))?,
            status: Out::new(&ipc, &z, Topic::OptimiserStatus, kr(Topic::OptimiserStatus))?,
            operator: In::new(&ipc, &z, k(Topic::Operator), Topic::Operator, false)?,
            operator_ack: Out::new(&ipc, &z, Topic::OperatorAck, kr(Topic::OperatorAck))?,
            _z: z,
        })
    }

    fn serve(&self, stop: &AtomicBool) -> Result<MirrorReport, NetError> {
        let mut rep = MirrorReport::default();
        let none = Duration::ZERO;
        while !stop.load(Ordering::Relaxed) {
            // Commands before the state they answer follows: the optimiser reads commands up to
            // each state it takes. Waiting for the next state paces the loop.
            rep.commands_in += self.command.drain(none, &mut rep.refused)?;
            rep.states_in += self.state.drain(POLL, &mut rep.refused)?;
            rep.telemetry_in += self.telemetry.drain(none, &mut rep.refused)?;
            rep.params_out += self.params.drain(|_| {})?;
            rep.estimates_out += self.estimate.drain(|_| {})?;
            rep.estimates_out += self.estimate_linear.drain(|_| {})?;
            self.status.drain(|_| {})?;
            rep.operator_in += self.operator.drain(none, &mut rep.refused)?;
            rep.operator_acks_out += self.operator_ack.drain(|_| {})?;
        }
        // What the optimiser published last.
        rep.params_out += self.params.drain(|_| {})?;
        rep.estimates_out += self.estimate.drain(|_| {})?;
        rep.estimates_out += self.estimate_linear.drain(|_| {})?;
        // The answers to commands the run's end stopped.
        rep.operator_acks_out += self.operator_ack.drain(|_| {})?;
        Ok(rep)
    }
}
