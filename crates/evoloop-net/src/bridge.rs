//! `evoloop bridge`: a running run's iceoryx2 topics on Zenoh, and parameter sets from Zenoh
//! into the run (see the crate docs for what crosses which way).
//!
//! The bridge is one more process of the run, outside the control path: it subscribes like
//! `evoloop top` (publishers never wait for it) and publishes parameter sets like the optimiser
//! (the controller validates them as any other). Each iceoryx2 sample becomes one Zenoh put;
//! states and commands are relayed in order, every one (a remote optimiser's estimator counts
//! gaps), telemetry as it comes.

use super::{key, open, wire, Endpoint, NetError, POLL};
use crate::ipc::{Ipc, Message, Pub, Sub, Topic};
use crate::msg::{
    Command, ModelEstimate, OptimiserStatus, ParamSet, PlantState, Telemetry, STATE_FLAG_END,
};
use std::fmt::Debug;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;
use zenoh::Wait as _;

/// Samples a network subscriber holds before Zenoh drops: 0.4 s of a 10 kHz run's states.
const NET_QUEUE: usize = 4096;

/// An iceoryx2 topic relayed to a Zenoh key.
pub(crate) struct Out<T: Message> {
    pub sub: Sub<T>,
    pub net: Publisher<'static>,
}

impl<T: Message> Out<T> {
    pub fn new(ipc: &Ipc, z: &zenoh::Session, topic: Topic, key: String) -> Result<Self, NetError> {
        Ok(Self {
            sub: ipc.subscriber(topic, topic.max_buffer(), false)?,
            // A parameter set must not be dropped (the sender's version numbering goes on
            // from it); the streams may be, rather than hold up the relay.
            net: publisher(
                z,
                key,
                if topic == Topic::Params {
                    CongestionControl::Block
                } else {
                    CongestionControl::Drop
                },
            )?,
        })
    }

    /// Relay what is waiting; calls `seen` on each sample. Returns how many went out.
    pub fn drain(&self, mut seen: impl FnMut(&T)) -> Result<u64, NetError> {
        let mut n = 0;
        while let Some(v) = self.sub.next()? {
            self.net
                .put(wire::encode(&v))
                .wait()
                .map_err(NetError::zenoh(format!(
                    "Zenoh put on {}",
                    self.net.key_expr()
                )))?;
            seen(&v);
            n += 1;
        }
        Ok(n)
    }
}

/// A Zenoh key relayed to an iceoryx2 topic.
pub(crate) struct In<T: Message> {
    pub net: Subscriber<FifoChannelHandler<Sample>>,
    pub publ: Pub<T>,
}

impl<T: Message> In<T> {
    pub fn new(
        ipc: &Ipc,
        z: &zenoh::Session,
        key: String,
        topic: Topic,
        wake: bool,
    ) -> Result<Self, NetError> {
        Ok(Self {
            net: subscriber(z, key)?,
            publ: ipc.publisher(topic, wake)?,
        })
    }

    /// Publish what has arrived, after waiting up to `wait` for the first message. A message
    /// of another layout is dropped and counted in `refused`. Returns how many went in.
    pub fn drain(&self, wait: Duration, refused: &mut u64) -> Result<u64, NetError> {
        let err = |e| NetError::zenoh(format!("Zenoh receive on {}", self.net.key_expr()))(e);
        let mut next = if wait.is_zero() {
            self.net.try_recv().map_err(err)?
        } else {
            self.net.recv_timeout(wait).map_err(err)?
        };
        let mut n = 0;
        while let Some(s) = next {
            match wire::decode::<T>(&s.payload().to_bytes()) {
                Ok(v) => {
                    self.publ.send(&v)?;
                    n += 1;
                }
                Err(e) => {
                    if *refused == 0 {
                        eprintln!("evoloop: {}: {e}; dropped", s.key_expr());
                    }
                    *refused += 1;
                }
            }
            next = self.net.try_recv().map_err(err)?;
        }
        Ok(n)
    }
}

/// A Zenoh publisher on `key` with congestion control `cc` (`Block` for what must not be
/// dropped, as parameter sets; `Drop` for streams); an error if Zenoh refuses it.
pub fn publisher(
    z: &zenoh::Session,
    key: String,
    cc: CongestionControl,
) -> Result<Publisher<'static>, NetError> {
    z.declare_publisher(key.clone())
        .congestion_control(cc)
        .wait()
        .map_err(NetError::zenoh(format!("Zenoh publisher on {key}")))
}

/// A Zenoh subscriber on `key` whose queue holds 4096 samples (0.4 s of a 10 kHz run's states);
/// an error if Zenoh refuses it.
pub fn subscriber(
    z: &zenoh::Session,
    key: String,
) -> Result<Subscriber<FifoChannelHandler<Sample>>, NetError> {
    z.declare_subscriber(key.clone())
        .with(FifoChannel::new(NET_QUEUE))
        .wait()
        .map_err(NetError::zenoh(format!("Zenoh subscriber on {key}")))
}

/// What a bridge did, printed and returned at its end.
#[derive(Debug, Default, serde::Serialize)]
pub struct BridgeReport {
    /// The run relayed.
    pub run_id: String,
    /// States relayed out to Zenoh.
    pub states: u64,
    /// Commands relayed out.
    pub commands: u64,
    /// Telemetry samples relayed out.
    pub telemetry: u64,
    /// The run's optimiser's model estimates relayed out.
    pub estimates_out: u64,
    /// The run's optimiser's status messages relayed out.
    pub status_out: u64,
    /// Parameter sets relayed in from the network to the run's params topic.
    pub params_in: u64,
    /// A remote optimiser's model estimates and transfer functions relayed in.
    pub estimates_in: u64,
    /// An operator's commands out to a remote optimiser, and its answers in.
    #[serde(default)]
    pub operator_out: u64,
    /// A remote optimiser's answers to operators relayed in.
    #[serde(default)]
    pub operator_acks_in: u64,
    /// Messages from the network dropped because their layout is not this build's.
    pub refused: u64,
    /// The ROS 2 node's (`--ros2`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ros2: Option<super::ros2::Ros2Report>,
    /// How long the bridge ran, s.
    pub seconds: f64,
    /// Why it ended: "run ended", "stopped" or "duration".
    pub ended: String,
}

/// The run as a ROS 2 node too (`--ros2`): where on the ROS 2 graph, and the run's scenario
/// (its joints, its gains, its optimiser's mode).
pub struct Ros2Bridge<'a> {
    /// The node's ROS 2 domain, namespace and name.
    pub name: crate::report::ros2::rmw_zenoh::NodeName,
    /// The run's scenario.
    pub scenario: &'a crate::config::Scenario,
}

/// Relay run `run_id` (iceoryx2 prefix `prefix`) until its last state, a stop request or
/// `duration`.
pub fn run(
    run_id: &str,
    prefix: &str,
    ep: &Endpoint,
    config: Option<&Path>,
    duration: Option<Duration>,
    ros: Option<Ros2Bridge>,
    stop: &AtomicBool,
) -> Result<BridgeReport, NetError> {
    let z = open(ep, config)?;
    // No clean-up of dead nodes from here: the bridge changes nothing of the run's.
    let ipc = Ipc::with_cleanup("evoloop-bridge", run_id, prefix, false)?;
    let mut ros = match ros {
        Some(r) => Some(super::ros2::Ros2Node::new(&z, &ipc, r.scenario, &r.name)?),
        None => None,
    };
    let k = |t: Topic| key(run_id, t, false);
    let kr = |t: Topic| key(run_id, t, true);
    let state = Out::<PlantState>::new(&ipc, &z, Topic::State, k(Topic::State))?;
    let command = Out::<Command>::new(&ipc, &z, Topic::Command, k(Topic::Command))?;
    let telemetry = Out::<Telemetry>::new(&ipc, &z, Topic::Telemetry, k(Topic::Telemetry))?;
    let estimate = Out::<ModelEstimate>::new(&ipc, &z, Topic::Estimate, k(Topic::Estimate))?;
    let status =
        Out::<OptimiserStatus>::new(&ipc, &z, Topic::OptimiserStatus, k(Topic::OptimiserStatus))?;
    let params = In::<ParamSet>::new(&ipc, &z, k(Topic::Params), Topic::Params, false)?;
    let estimate_in =
        In::<ModelEstimate>::new(&ipc, &z, kr(Topic::Estimate), Topic::Estimate, false)?;
    let operator =
        Out::<crate::msg::OperatorCommand>::new(&ipc, &z, Topic::Operator, k(Topic::Operator))?;
    let operator_ack_in = In::<crate::msg::OperatorAck>::new(
        &ipc,
        &z,
        kr(Topic::OperatorAck),
        Topic::OperatorAck,
        false,
    )?;
    let estimate_linear_in = In::<crate::msg::LinearEstimate>::new(
        &ipc,
        &z,
        kr(Topic::LinearEstimate),
        Topic::LinearEstimate,
        false,
    )?;
    let status_in = In::<OptimiserStatus>::new(
        &ipc,
        &z,
        kr(Topic::OptimiserStatus),
        Topic::OptimiserStatus,
        false,
    )?;
    let mut rep = BridgeReport {
        run_id: run_id.to_string(),
        ..Default::default()
    };
    let t0 = Instant::now();
    let mut ended = false;
    rep.ended = loop {
        if stop.load(Ordering::Relaxed) {
            break "stopped";
        }
        if duration.is_some_and(|d| t0.elapsed() >= d) {
            break "duration";
        }
        // A short sleep, not a timed wait on the state's event: iceoryx2's timed waits wake on
        // this kernel's timer tick (milliseconds), clock_nanosleep within ~0.1 ms.
        std::thread::sleep(POLL);
        rep.states += state.drain(|s| {
            ended |= s.flags & STATE_FLAG_END != 0;
            if let Some(r) = ros.as_mut() {
                r.state(s);
            }
        })?;
        rep.commands += command.drain(|c| ros.iter_mut().for_each(|r| r.command(c)))?;
        rep.telemetry += telemetry.drain(|t| ros.iter_mut().for_each(|r| r.telemetry(t)))?;
        if let Some(r) = ros.as_mut() {
            r.poll();
        }
        rep.estimates_out += estimate.drain(|_| {})?;
        rep.status_out += status.drain(|_| {})?;
        rep.params_in += params.drain(Duration::ZERO, &mut rep.refused)?;
        rep.estimates_in += estimate_in.drain(Duration::ZERO, &mut rep.refused)?;
        rep.estimates_in += estimate_linear_in.drain(Duration::ZERO, &mut rep.refused)?;
        rep.operator_out += operator.drain(|_| {})?;
        rep.operator_acks_in += operator_ack_in.drain(Duration::ZERO, &mut rep.refused)?;
        status_in.drain(Duration::ZERO, &mut rep.refused)?;
        if ended {
            // The controller's last command and telemetry follow the plant's last state.
            std::thread::sleep(Duration::from_millis(50));
            rep.commands += command.drain(|c| ros.iter_mut().for_each(|r| r.command(c)))?;
            rep.telemetry += telemetry.drain(|t| ros.iter_mut().for_each(|r| r.telemetry(t)))?;
            break "run ended";
        }
    }
    .to_string();
    rep.seconds = t0.elapsed().as_secs_f64();
    rep.ros2 = ros.map(|r| r.report);
    Ok(rep)
}
