//! The inter-process layer: iceoryx2 nodes, the run's services, and typed publish/subscribe
//! channels paired with events so a waiting process blocks instead of polling.
//!
//! Every service name carries the run id (`evoloop/<run id>/<topic>`) so two runs on one machine
//! never cross-talk, and every file iceoryx2 creates carries the run's prefix (`--ipc-prefix`,
//! default `evoloop_`) so a run's resources can be told apart from other iceoryx2 users.

use iceoryx2::node::NodeView;
use iceoryx2::port::listener::{Listener, ListenerWaitError};
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use std::fmt;
use std::mem::ManuallyDrop;
use std::time::{Duration, Instant};

pub mod namespace;
pub mod pooled;
mod ports;
pub mod service;
pub mod spin;

pub use ports::Message;
use ports::{PubPorts, SubPorts};
pub use spin::Spin;

/// The iceoryx2 service type of every evoloop port (iceoryx2's ipc service, pooled loans).
pub type Svc = service::Service;

/// An IPC failure with what was being done when it happened, and the transport's own error
/// beneath it (`source()`), so a caller can act on iceoryx2's cause.
#[derive(Debug)]
pub struct IpcError {
    /// What was being done when it failed (e.g. `opening service evoloop/<run id>/state`).
    pub context: String,
    /// The cause as text (iceoryx2's error debug-formatted: its variant names say most).
    pub cause: String,
    source: Option<Box<dyn std::error::Error + Send + Sync>>,
}

impl IpcError {
    /// `context` failed because of `cause`, kept as this error's `source()`.
    pub fn new<E>(context: impl Into<String>, cause: E) -> Self
    where
        E: std::error::Error + Send + Sync + 'static,
    {
        IpcError {
            context: context.into(),
            cause: format!("{cause:?}"),
            source: Some(Box::new(cause)),
        }
    }

    /// `context` failed for a reason evoloop found itself (no error beneath it).
    pub fn reason(context: impl Into<String>, why: impl Into<String>) -> Self {
        IpcError {
            context: context.into(),
            cause: why.into(),
            source: None,
        }
    }
}

impl fmt::Display for IpcError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "iceoryx2: {}: {}", self.context, self.cause)
    }
}

impl std::error::Error for IpcError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        let e: &(dyn std::error::Error + 'static) = self.source.as_deref()?;
        Some(e)
    }
}

/// Open or create a service, retrying for up to half a second: peers open the same service
/// concurrently at start-up, and iceoryx2 reports a service that another process is creating or
/// tearing down as an error for a short moment.
fn retry<T, E>(what: &str, mut f: impl FnMut() -> Result<T, E>) -> Result<T, IpcError>
where
    E: std::error::Error + Send + Sync + 'static,
{
    let mut tries = 0;
    loop {
        match f() {
            Ok(v) => return Ok(v),
            Err(e) if tries == 49 => return Err(IpcError::new(what, e)),
            Err(_) => {
                tries += 1;
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    }
}

/// The topics of a run. Each has one QoS, used by whichever process creates the service first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Topic {
    /// The plant's samples (`PlantState`), published every control period.
    State,
    /// The controller's commands (`Command`), one per controller cycle.
    Command,
    /// The controller's record of each cycle (`Telemetry`), for watchers (`evoloop top`, bridges).
    Telemetry,
    /// Parameter sets for the controller (`ParamSet`): the optimiser's, a live view's, a bridge's.
    Params,
    /// The optimiser's lockstep acknowledgements to the plant (`OptimiserAck`).
    OptimiserAck,
    /// The optimiser's online model estimate (indirect scheme).
    Estimate,
    /// The general indirect scheme's estimated transfer function.
    LinearEstimate,
    /// The optimiser's progress after each epoch (for watchers).
    OptimiserStatus,
    /// An operator's command to the tuner (`evoloop operator`, `evoloop top`).
    Operator,
    /// The tuner's answer to it.
    OperatorAck,
    /// Event only: a process has created all its ports.
    Ready,
    /// Event only (lockstep): the plant reached a sample the optimiser must acknowledge.
    Sync,
}

impl Topic {
    /// The topic's part of its service name, `evoloop/<run id>/<name>`.
    pub fn name(self) -> &'static str {
        match self {
            Topic::State => "state",
            Topic::Command => "command",
            Topic::Telemetry => "telemetry",
            Topic::Params => "params",
            Topic::OptimiserAck => "optimiser_ack",
            Topic::Estimate => "estimate",
            Topic::LinearEstimate => "estimate_linear",
            Topic::OptimiserStatus => "optimiser_status",
            Topic::Operator => "operator",
            Topic::OperatorAck => "operator_ack",
            Topic::Ready => "ready",
            Topic::Sync => "sync",
        }
    }
    /// Largest per-subscriber queue. The optimiser reads every state/command sample between its
    /// lockstep acknowledgements, so those queues must hold a whole sync interval.
    pub fn max_buffer(self) -> usize {
        match self {
            Topic::State | Topic::Command => MAX_SYNC_SAMPLES + 8,
            Topic::Telemetry => 64,
            Topic::Params => 16,
            Topic::OptimiserAck
            | Topic::Ready
            | Topic::Sync
            | Topic::Estimate
            | Topic::LinearEstimate
            | Topic::OptimiserStatus
            | Topic::Operator
            | Topic::OperatorAck => 4,
        }
    }
}

impl Topic {
    /// Publishers a service admits: one process and a restarted one, and for parameter sets a
    /// live view's and a ROS 2 bridge's too (`evoloop live`, `evoloop bridge --ros2`), or for an operator's commands several senders at once
    /// (`evoloop operator` and `top` keys).
    pub fn max_publishers(self) -> usize {
        match self {
            Topic::Operator => 8,
            Topic::Params => 4,
            _ => 2,
        }
    }

    /// Subscribers: the run's processes and watchers, or every operator waiting for its answer.
    pub fn max_subscribers(self) -> usize {
        match self {
            Topic::OperatorAck => 10,
            _ => 6,
        }
    }

    /// Nodes on the service: the optimiser and as many operators as may send at once.
    pub fn max_nodes(self) -> usize {
        match self {
            Topic::Operator | Topic::OperatorAck => 12,
            _ => 8,
        }
    }
}

/// Most samples between two optimiser acknowledgements in lockstep (config validation enforces it).
pub const MAX_SYNC_SAMPLES: usize = 256;

/// Default prefix of every file iceoryx2 creates for evoloop.
pub const DEFAULT_PREFIX: &str = "evoloop_";

/// The longest `--ipc-prefix`: iceoryx2 puts the prefix (with this user's uid) into the paths
/// of its Unix sockets, which the kernel caps at 108 bytes; on this project's VM a prefix of 44
/// characters (uid 0) worked and 48 failed to create its listeners, and 150 panicked inside
/// iceoryx2. 32 leaves room for a uid of ten digits.
pub const MAX_PREFIX: usize = 32;

/// `--ipc-prefix` checked: 1 to `MAX_PREFIX` characters of ASCII letters, digits, `_`, `-`
/// and `.` (it becomes part of file names; the kernel caps socket paths at 108 bytes).
pub fn parse_prefix(s: &str) -> Result<String, NameError> {
    checked_name(s, NameKind::Prefix)
}

/// The longest run id: it goes into every service name and the run's lock file name.
pub const MAX_RUN_ID: usize = 64;

/// `--run-id` checked: 1 to `MAX_RUN_ID` ASCII letters, digits, `_` and `-` (no `.`: a lock file
/// and service names must tell every two run ids apart).
pub fn parse_run_id(s: &str) -> Result<String, NameError> {
    checked_name(s, NameKind::RunId)
}

/// The two names that go into iceoryx2's file and service names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NameKind {
    /// `--ipc-prefix` (`parse_prefix`).
    Prefix,
    /// `--run-id` (`parse_run_id`).
    RunId,
}

impl NameKind {
    fn what(self) -> &'static str {
        match self {
            NameKind::Prefix => "an ipc prefix",
            NameKind::RunId => "a run id",
        }
    }

    fn max(self) -> usize {
        match self {
            NameKind::Prefix => MAX_PREFIX,
            NameKind::RunId => MAX_RUN_ID,
        }
    }

    /// The characters allowed beside ASCII letters and digits.
    fn extra(self) -> &'static str {
        match self {
            NameKind::Prefix => "_-.",
            NameKind::RunId => "_-",
        }
    }
}

/// A prefix or run id refused: too short or too long (its length), or holding a character
/// file and service names cannot take.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum NameError {
    /// Empty or longer than the kind's maximum (the length given).
    Length(NameKind, usize),
    /// A character that is not allowed.
    Character(NameKind, char),
}

impl fmt::Display for NameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            NameError::Length(kind, len) => {
                let why = match kind {
                    NameKind::Prefix => {
                        " (it goes into socket paths, which the kernel caps at 108 bytes)"
                    }
                    NameKind::RunId => "",
                };
                write!(
                    f,
                    "{len} characters; {} has 1 to {}{why}",
                    kind.what(),
                    kind.max()
                )
            }
            NameError::Character(kind, c) => {
                let listed: Vec<String> = kind.extra().chars().map(|c| format!("'{c}'")).collect();
                write!(
                    f,
                    "{c:?} is not allowed; {} takes ASCII letters, digits and {}",
                    kind.what(),
                    listed.join(", ")
                )
            }
        }
    }
}

impl std::error::Error for NameError {}

/// `s` if it has 1 to the kind's maximum characters, each an ASCII letter, a digit or one of
/// the kind's extra characters.
fn checked_name(s: &str, kind: NameKind) -> Result<String, NameError> {
    if s.is_empty() || s.len() > kind.max() {
        return Err(NameError::Length(kind, s.len()));
    }
    if let Some(c) = s
        .chars()
        .find(|c| !(c.is_ascii_alphanumeric() || kind.extra().contains(*c)))
    {
        return Err(NameError::Character(kind, c));
    }
    Ok(s.to_string())
}

/// iceoryx2 configuration for a prefix: this user's namespace (see `namespace`), with a
/// separate one per prefix.
pub fn ipc_config(prefix: &str) -> Result<Config, IpcError> {
    let mut cfg = Config::global_config().clone();
    let full = namespace::user_prefix(prefix);
    cfg.global.prefix = FileName::new(full.as_bytes())
        .map_err(|e| IpcError::new(format!("ipc prefix {full:?}"), e))?;
    let root = namespace::user_subdir("iceoryx2")?;
    let root = format!("{}/", root.display());
    let root =
        Path::new(root.as_bytes()).map_err(|e| IpcError::new(format!("ipc root {root:?}"), e))?;
    cfg.global.set_root_path(&root);
    Ok(cfg)
}

/// A node of `prefix` in this user's namespace, with the shared-memory files checked.
pub fn create_node<S: iceoryx2::service::Service>(
    builder: NodeBuilder,
    prefix: &str,
    what: &str,
) -> Result<Node<S>, IpcError> {
    // Before iceoryx2 opens anything: a file of another user in this namespace (its global
    // management segment, say) failed it with a generic error (UnableToGenerateUniqueNodeId)
    // or, as root, which may open anyone's file, had it wait forever for that file to be
    // initialised. Name the file and its owner instead. After: make ours owner-only.
    namespace::claim_shm(prefix)?;
    let node = builder
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<S>()
        .map_err(|e| IpcError::new(what, e))?;
    namespace::claim_shm(prefix)?;
    Ok(node)
}

/// One process's membership in a run: its iceoryx2 node and the run id.
pub struct Ipc {
    /// This process's iceoryx2 node, which owns all its ports.
    pub node: Node<Svc>,
    /// The run id every service name carries (`evoloop/<run id>/<topic>`).
    pub run_id: String,
}

impl Ipc {
    /// Create the process's node. Signal handling is left to the process (`node::start::stop_flag`), so a SIGTERM
    /// mid-wait ends the wait through our own flag and the ports are dropped cleanly.
    /// Node creation also removes the resources of dead nodes of earlier, killed runs.
    pub fn new(process: &str, run_id: &str, prefix: &str) -> Result<Self, IpcError> {
        Self::with_cleanup(process, run_id, prefix, true)
    }

    /// As `new`; with `cleanup_on_create` false, dead nodes are left for an explicit
    /// `cleanup_dead_nodes` call, which reports how many it removed (the launcher does this).
    pub fn with_cleanup(
        process: &str,
        run_id: &str,
        prefix: &str,
        cleanup_on_create: bool,
    ) -> Result<Self, IpcError> {
        set_log_level(LogLevel::Error);
        let mut cfg = ipc_config(prefix)?;
        cfg.global.node.cleanup_dead_nodes_on_creation = cleanup_on_create;
        let name = NodeName::new(process).map_err(|e| IpcError::new("node name", e))?;
        let node = create_node(
            NodeBuilder::new().name(&name).config(&cfg),
            prefix,
            &format!("creating node {process}"),
        )?;
        Ok(Self {
            node,
            run_id: run_id.to_string(),
        })
    }

    /// The service name of `topic` in this run, `evoloop/<run id>/<topic>`; an error if iceoryx2
    /// refuses it as a service name.
    pub fn service_name(&self, topic: Topic) -> Result<ServiceName, IpcError> {
        let s = format!("evoloop/{}/{}", self.run_id, topic.name());
        ServiceName::new(&s).map_err(|e| IpcError::new(format!("service name {s}"), e))
    }

    /// Remove what dead processes of earlier runs left behind; returns how many nodes were cleaned.
    pub fn cleanup_dead_nodes(&self) -> usize {
        // First the nodes iceoryx2 cannot clean: it would count them as cleaned, finding nothing.
        let orphans = self.remove_orphaned_monitors();
        orphans + self.node.try_cleanup_dead_nodes().cleanups as usize
    }

    /// Remove the monitor files of dead nodes whose details are gone, which iceoryx2 0.10 leaves
    /// for good under a prefix of our own. Its cleanup finds a dead node's files through the
    /// configuration recorded in the node's details and, without them, through the global
    /// configuration (another prefix and root). A cleaner killed after removing the details but
    /// before the monitor (a crash-looping optimiser killed while it cleaned up its predecessor)
    /// or a node killed while it was created leaves exactly that: no service or port tag, only
    /// `<prefix><id>.node_monitor`, `_context` and `_owner_lock`, and a next run under the same
    /// prefix would inherit them. Returns how many such nodes were removed.
    fn remove_orphaned_monitors(&self) -> usize {
        let cfg = self.node.config();
        let mut orphans = Vec::new();
        // A listing that fails leaves the files for the next cleanup; nothing else depends on it.
        let _ = Node::<Svc>::list(cfg, |state| {
            if let NodeState::Dead(view) = &state {
                if view.details().is_none() {
                    orphans.push(view.id().value());
                }
            }
            CallbackProgression::Continue
        });
        let dir = std::path::PathBuf::from(cfg.global.node_dir().to_string());
        let (prefix, suffix) = (&cfg.global.prefix, &cfg.global.node.monitor_suffix);
        for id in &orphans {
            let monitor = format!("{prefix}{id}{suffix}");
            for file in namespace::entries(&dir, &monitor) {
                let _ = std::fs::remove_file(file);
            }
            // A node killed while it was created may have left its unfinished details.
            let _ = std::fs::remove_dir_all(dir.join(id.to_string()));
        }
        orphans.len()
    }

    fn event(
        &self,
        topic: Topic,
    ) -> Result<iceoryx2::service::port_factory::event::PortFactory<Svc>, IpcError> {
        let name = self.service_name(topic)?;
        retry(&format!("opening event {}", name.as_str()), || {
            self.node
                .service_builder(&name)
                .event()
                .max_notifiers(4)
                .max_listeners(6)
                .max_nodes(8)
                .open_or_create()
        })
    }

    /// Announce once on an event-only topic (e.g. `Topic::Ready`) that something happened.
    pub fn announce(&self, topic: Topic) -> Result<(), IpcError> {
        self.bell(topic)?.ring()
    }

    /// The ringing end of an event-only topic, kept for repeated use.
    pub fn bell(&self, topic: Topic) -> Result<Bell, IpcError> {
        Ok(Bell {
            notifier: self.notifier(topic)?,
            topic,
        })
    }

    /// A listener on an event-only topic.
    pub fn doorbell(&self, topic: Topic) -> Result<Doorbell, IpcError> {
        Ok(Doorbell {
            listener: self.listener(topic)?,
            topic,
        })
    }

    /// A notifier on `topic`'s event (a bell, or a waking publisher's).
    fn notifier(&self, topic: Topic) -> Result<Notifier<Svc>, IpcError> {
        self.event(topic)?
            .notifier_builder()
            .create()
            .map_err(|e| IpcError::new(format!("notifier on {}", topic.name()), e))
    }

    /// A listener on `topic`'s event (a doorbell, or a waiting subscriber's).
    fn listener(&self, topic: Topic) -> Result<Listener<Svc>, IpcError> {
        self.event(topic)?
            .listener_builder()
            .create()
            .map_err(|e| IpcError::new(format!("listener on {}", topic.name()), e))
    }

    /// A publisher; with `wake` it also notifies listeners after each send.
    pub fn publisher<T: Message>(&self, topic: Topic, wake: bool) -> Result<Pub<T>, IpcError> {
        T::publisher(self, topic, wake)
    }

    /// A subscriber with its own queue depth; with `wake` it can block until a sample arrives.
    pub fn subscriber<T: Message>(
        &self,
        topic: Topic,
        buffer: usize,
        wake: bool,
    ) -> Result<Sub<T>, IpcError> {
        T::subscriber(self, topic, buffer, wake)
    }
}

/// A typed publisher, optionally paired with an event notifier.
pub struct Pub<T: Message> {
    /// iceoryx2's side, dropped by code compiled in this crate (`ports`).
    ports: ManuallyDrop<PubPorts<T>>,
}

impl<T: Message> Drop for Pub<T> {
    fn drop(&mut self) {
        T::drop_publisher(&mut self.ports);
    }
}

impl<T: Message> Pub<T> {
    fn new(ports: PubPorts<T>) -> Self {
        Pub {
            ports: ManuallyDrop::new(ports),
        }
    }

    /// Connect to subscribers that joined since the last call (or send). A loop calls this
    /// between its cycles: connecting maps the newcomer's memory, which allocates and takes
    /// time, and `send` would otherwise do it inside the cycle (a viewer or a bridge that
    /// attaches mid-run).
    pub fn update_connections(&self) -> Result<(), IpcError> {
        T::connect_publisher(&self.ports)
    }

    /// Copy `value` into a shared-memory slot, send it and wake the listeners. No allocation.
    pub fn send(&self, value: &T) -> Result<(), IpcError> {
        T::send(&self.ports, value)
    }

    /// Number of subscribers (all processes) connected to this topic.
    pub fn subscribers(&self) -> usize {
        T::subscribers(&self.ports)
    }
}

/// The ringing end of an event-only topic.
pub struct Bell {
    notifier: Notifier<Svc>,
    topic: Topic,
}

impl Bell {
    /// Notify the topic's listeners once (with the notifier's default event id).
    pub fn ring(&self) -> Result<(), IpcError> {
        self.notifier
            .notify()
            .map(|_| ())
            .map_err(|e| IpcError::new(format!("notify on {}", self.topic.name()), e))
    }
}

/// The listening end of an event-only topic.
pub struct Doorbell {
    listener: Listener<Svc>,
    topic: Topic,
}

impl Doorbell {
    /// Block until an announcement arrives or `timeout` passes (a signal only wakes it early).
    pub fn wait(&self, timeout: Duration) -> Result<(), IpcError> {
        listen(&self.listener, timeout, self.topic)
    }
}

/// Block on `listener` until a notification arrives or `timeout` passes. Every blocking wait of
/// the project goes through here: a signal that interrupts it (SIGCONT after a SIGSTOP, a
/// profiler's) is a spurious wake-up, not an error; the callers loop and check their stop flag.
fn listen(listener: &Listener<Svc>, timeout: Duration, topic: Topic) -> Result<(), IpcError> {
    match listener.timed_wait(|_| {}, timeout) {
        Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
        Err(e) => Err(IpcError::new(format!("wait on {}", topic.name()), e)),
    }
}

/// A typed subscriber, optionally paired with an event listener for blocking waits.
pub struct Sub<T: Message> {
    /// iceoryx2's side, dropped by code compiled in this crate (`ports`).
    ports: ManuallyDrop<SubPorts<T>>,
}

impl<T: Message> Drop for Sub<T> {
    fn drop(&mut self) {
        T::drop_subscriber(&mut self.ports);
    }
}

/// What a bounded wait ended with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Wait<T> {
    /// A sample arrived: the oldest unread one.
    Got(T),
    /// No sample arrived before the timeout.
    TimedOut,
}

/// How `Sub::wait_for` ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Waited<T> {
    /// A sample that satisfied `done` (the samples before it were discarded).
    Got(T),
    /// The stop flag was raised (SIGINT/SIGTERM).
    Stopped,
    /// No sample satisfied `done` before the timeout.
    TimedOut,
}

/// A blocking wait is cut into slices this long so a stop request is noticed even when the peer
/// has gone silent.
const STOP_CHECK: Duration = Duration::from_millis(100);

impl<T: Message> Sub<T> {
    fn new(ports: SubPorts<T>) -> Self {
        Sub {
            ports: ManuallyDrop::new(ports),
        }
    }

    /// Wait up to `timeout` for a sample satisfying `done`, discarding the others, noticing
    /// `stop` within 100 ms. Polls for what `spin` says before blocking on the event, and tells
    /// `spin` whether the poll was answered (`Spin`: a poll that goes unanswered pauses).
    pub fn wait_for(
        &self,
        spin: &mut Spin,
        timeout: Duration,
        stop: &std::sync::atomic::AtomicBool,
        done: impl Fn(&T) -> bool,
    ) -> Result<Waited<T>, IpcError> {
        let t0 = Instant::now();
        let poll = spin.poll();
        loop {
            if stop.load(std::sync::atomic::Ordering::Relaxed) {
                return Ok(Waited::Stopped);
            }
            let waited = t0.elapsed();
            let left = timeout.saturating_sub(waited);
            if left.is_zero() {
                return Ok(Waited::TimedOut);
            }
            let polling = poll.saturating_sub(waited);
            if let Wait::Got(m) = self.wait_next(polling, left.min(STOP_CHECK))? {
                if done(&m) {
                    spin.record(poll, t0.elapsed());
                    return Ok(Waited::Got(m));
                }
            }
        }
    }

    /// Publishers currently connected to this topic (a killed process's stay counted until its
    /// resources are cleaned up).
    pub fn publishers(&self) -> usize {
        T::publishers(&self.ports)
    }

    /// Whether unread samples are waiting.
    pub fn has_pending(&self) -> Result<bool, IpcError> {
        T::has_pending(&self.ports)
    }

    /// Connect to publishers that joined since the last call (or receive): see
    /// `Pub::update_connections`.
    pub fn update_connections(&self) -> Result<(), IpcError> {
        T::connect_subscriber(&self.ports)
    }

    /// The oldest unread sample, if any (in-order consumption).
    pub fn next(&self) -> Result<Option<T>, IpcError> {
        T::receive(&self.ports)
    }

    /// The newest sample, dropping older unread ones (zero-order-hold consumers).
    pub fn latest(&self) -> Result<Option<T>, IpcError> {
        let mut last = None;
        while let Some(v) = self.next()? {
            last = Some(v);
        }
        Ok(last)
    }

    /// Wait for the next sample: poll for up to `spin`, then block on the event until `timeout`
    /// has passed in all. Never sleeps for a fixed time: a notification wakes it at once.
    pub fn wait_next(&self, spin: Duration, timeout: Duration) -> Result<Wait<T>, IpcError> {
        let start = Instant::now();
        loop {
            if let Some(v) = self.next()? {
                return Ok(Wait::Got(v));
            }
            let waited = start.elapsed();
            if waited >= timeout {
                return Ok(Wait::TimedOut);
            }
            if waited < spin {
                std::hint::spin_loop();
                continue;
            }
            match &self.ports.listener {
                Some(l) => listen(l, timeout - waited, self.ports.topic)?,
                None => std::hint::spin_loop(),
            }
        }
    }
}
