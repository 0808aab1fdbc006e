//! The remote optimiser's side of a bridge: the run's states, commands and telemetry from Zenoh
//! into the iceoryx2 namespace of this host's remote optimisers (`PREFIX`), and the optimiser's parameter sets,
//! estimates and status from there back to the network. The optimiser's own code runs against
//! that namespace as it would inside the run, so nothing of it changes for the network.
//!
//! Losing the link is losing the data: the optimiser sees no state, and ends as it does when
//! the plant goes silent (`no plant state within ...`); the run goes on with the set in service.

use super::bridge::{ipc_err, In, Out};
use super::{key, open, Endpoint, POLL};
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
    handle: Option<JoinHandle<Result<MirrorReport, String>>>,
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
    ) -> Result<Self, String> {
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = sync_channel::<Result<(), String>>(1);
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
                        let _ = ready_tx.send(Err(e.clone()));
                        Err(e)
                    }
                }
            })
            .map_err(|e| format!("cannot start the network mirror: {e}"))?;
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(Self {
                stop,
                handle: Some(handle),
            }),
            Ok(Err(e)) => Err(e),
            Err(_) => Err("the network mirror ended before it was ready".into()),
        }
    }

    /// Stop the mirror and wait for its thread: what it relayed, or the error that ended it (or
    /// that it panicked).
    pub fn join(mut self) -> Result<MirrorReport, String> {
        self.stop.store(true, Ordering::SeqCst);
        match self.handle.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            _ => Err("the network mirror panicked".into()),
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
    ) -> Result<Self, String> {
        let z = open(ep, config).map_err(|e| e.to_string())?;
        let ipc = Ipc::new("evoloop-mirror", run_id, prefix).map_err(ipc_err)?;
        let k = |t: Topic| key(run_id, t, false);
        let kr = |t: Topic| key(run_id, t, true);
        Ok(Self {
            // The optimiser blocks on the state's event: wake it with each state.
            state: In::new(&ipc, &z, k(Topic::State), Topic::State, true)
                .map_err(|e| e.to_string())?,
            // The direct scheme blocks on the command's event.
            command: In::new(&ipc, &z, k(Topic::Command), Topic::Command, true)
                .map_err(|e| e.to_string())?,
            telemetry: In::new(&ipc, &z, k(Topic::Telemetry), Topic::Telemetry, false)
                .map_err(|e| e.to_string())?,
            params: Out::new(&ipc, &z, Topic::Params, k(Topic::Params))
                .map_err(|e| e.to_string())?,
            estimate: Out::new(&ipc, &z, Topic::Estimate, kr(Topic::Estimate))
                .map_err(|e| e.to_string())?,
            estimate_linear: Out::new(&ipc, &z, Topic::LinearEstimate, kr(Topic::LinearEstimate))
                .map_err(|e| e.to_string())?,
            status: Out::new(&ipc, &z, Topic::OptimiserStatus, kr(Topic::OptimiserStatus))
                .map_err(|e| e.to_string())?,
            operator: In::new(&ipc, &z, k(Topic::Operator), Topic::Operator, false)
                .map_err(|e| e.to_string())?,
            operator_ack: Out::new(&ipc, &z, Topic::OperatorAck, kr(Topic::OperatorAck))
                .map_err(|e| e.to_string())?,
            _z: z,
        })
    }

    fn serve(&self, stop: &AtomicBool) -> Result<MirrorReport, String> {
        let mut rep = MirrorReport::default();
        let none = Duration::ZERO;
        while !stop.load(Ordering::Relaxed) {
            // Commands before the state they answer follows: the optimiser reads commands up to
            // each state it takes. Waiting for the next state paces the loop.
            rep.commands_in += self
                .command
                .drain(none, &mut rep.refused)
                .map_err(|e| e.to_string())?;
            rep.states_in += self
                .state
                .drain(POLL, &mut rep.refused)
                .map_err(|e| e.to_string())?;
            rep.telemetry_in += self
                .telemetry
                .drain(none, &mut rep.refused)
                .map_err(|e| e.to_string())?;
            rep.params_out += self.params.drain(|_| {}).map_err(|e| e.to_string())?;
            rep.estimates_out += self.estimate.drain(|_| {}).map_err(|e| e.to_string())?;
            rep.estimates_out += self
                .estimate_linear
                .drain(|_| {})
                .map_err(|e| e.to_string())?;
            self.status.drain(|_| {}).map_err(|e| e.to_string())?;
            rep.operator_in += self
                .operator
                .drain(none, &mut rep.refused)
                .map_err(|e| e.to_string())?;
            rep.operator_acks_out += self.operator_ack.drain(|_| {}).map_err(|e| e.to_string())?;
        }
        // What the optimiser published last.
        rep.params_out += self.params.drain(|_| {}).map_err(|e| e.to_string())?;
        rep.estimates_out += self.estimate.drain(|_| {}).map_err(|e| e.to_string())?;
        rep.estimates_out += self
            .estimate_linear
            .drain(|_| {})
            .map_err(|e| e.to_string())?;
        // The answers to commands the run's end stopped.
        rep.operator_acks_out += self.operator_ack.drain(|_| {}).map_err(|e| e.to_string())?;
        Ok(rep)
    }
}
