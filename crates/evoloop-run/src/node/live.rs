//! `evoloop live`: a running run in Foxglove's WebSocket protocol (`foxglove.websocket.v1`,
//! <https://github.com/foxglove/ws-protocol>), for Foxglove and PlotJuggler: the run's topics as
//! channels (ROS 2 CDR with `ros2msg` schemas, the recording's own encoding, `report::ros2`) and
//! the controller's tunable values as the parameter `gains`, which a viewer may set.
//!
//! Off the control path by construction: its own process (`evoloop run --live` starts it beside
//! the run's), subscribed to the run's topics like `top` (the run's publishers never wait for a
//! subscriber; a full queue loses its oldest sample, counted nowhere on the loop); it publishes
//! only the sets viewers send. One thread
//! polls the topics and hands each encoded message to every client's bounded queue (dropped,
//! and counted, when a viewer is slow); a thread per client writes its frames and reads its
//! requests.
//!
//! A parameter set a viewer sends goes to the controller as any other set (`crate::gains`: its
//! validation, its answer, only where no optimiser publishes). Accepted, the new values come
//! back as `parameterValues`; refused, a `status` error names the reason and the values in
//! service come back.

use crate::config::Scenario;
use crate::gains::{Answer, Gains};
use crate::ipc::{Ipc, Sub, Topic};
use crate::msg::{Command, ParamSet, PlantState, Telemetry};
use crate::report::ros2;
use serde_json::{json, Value};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::sync::mpsc::{channel, sync_channel, Sender, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The WebSocket subprotocol a Foxglove client asks for.
pub const SUBPROTOCOL: &str = "foxglove.websocket.v1";
/// The parameter holding the controller's tunable values.
pub const GAINS: &str = "gains";

/// The options of `evoloop live`: which run to serve, on which address, and to whom.
#[derive(Debug, Clone)]
pub struct LiveArgs {
    /// The run to serve (its run id); default: the only run running.
    pub run: Option<String>,
    /// Address to listen on (Foxglove: "Open connection", Foxglove WebSocket, ws://ADDR).
    pub addr: String,
    /// The run's scenario (default: the one its controller was started with).
    pub config: Option<PathBuf>,
    /// Prefix of iceoryx2's files (default: the run's).
    pub ipc_prefix: Option<String>,
    /// The run's overrides of its scenario (`evoloop run --live` passes its own).
    pub overrides: crate::config::Overrides,
    /// Listen beyond loopback (ADDR on another interface, e.g. 0.0.0.0:8765): anyone who
    /// reaches the port sees the run, and a viewer on another machine sets `gains` only with
    /// the token printed at start (ws://HOST:PORT/?token=TOKEN). Without it such an ADDR is
    /// refused.
    pub remote: bool,
    /// A listening socket already bound, inherited as this descriptor (`evoloop run --live`
    /// binds ADDR itself, so a port it cannot have fails the run before it starts).
    pub listen_fd: Option<i32>,
}

/// The topics served, with the channel ids run.mcap gives them (their place in `ros2::TOPICS`,
/// 1..); `joint_states` for an arm only.
const SERVED: [&str; 5] = ["state", "command", "telemetry", "params", "joint_states"];

fn channel_id(topic: &str) -> u32 {
    ros2::TOPICS
        .iter()
        .position(|(t, _)| *t == topic)
        .expect("served topics are run topics") as u32
        + 1
}

/// What a client thread sends on its connection.
enum Out {
    /// A message on channel `channel` (1..), stamped.
    Data {
        channel: u32,
        stamp_ns: u64,
        payload: Arc<Vec<u8>>,
    },
    Text(String),
}

/// What a client asks of the hub.
enum Ask {
    Get {
        id: Value,
        reply: SyncSender<Out>,
    },
    Set {
        id: Value,
        values: Vec<f64>,
        reply: SyncSender<Out>,
    },
}

/// Messages a client's queue holds before newer ones are dropped for it.
const CLIENT_QUEUE: usize = 4096;
/// Connections served at once, viewers and handshakes in progress together (each has a
/// thread); one more is answered "503" and closed.
const MAX_CLIENTS: usize = 16;
/// The longest a connection may take to finish its WebSocket handshake, however slowly its
/// bytes come.
const HANDSHAKE: Duration = Duration::from_secs(5);
/// The largest message a viewer may send, bytes (a set of gains is < 1 KiB).
const MAX_MESSAGE: usize = 1 << 20;
/// How long a write to a viewer may block before the viewer is dropped.
const WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// How often the hub polls the topics.
const POLL: Duration = Duration::from_millis(2);

/// `evoloop live`: serve the run until it ends (its telemetry silent for 5 s after some came)
/// or this process is stopped (SIGINT, SIGTERM, SIGHUP). Returns the exit code: 0, or 2 when
/// serving could not start (the reason on stderr).
pub fn main(a: &LiveArgs) -> u8 {
    match serve(a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}

fn serve(a: &LiveArgs) -> Result<(), String> {
    // Started by `evoloop run --live`: everything given, the controller perhaps not started yet.
    let run = match (&a.run, &a.ipc_prefix, &a.config) {
        (Some(id), Some(prefix), Some(config)) => crate::run_watch::RunningRun {
            run_id: id.clone(),
            ipc_prefix: prefix.clone(),
            config: Some(config.clone()),
            optimiser: None,
        },
        _ => crate::run_watch::pick_run(a.run.as_deref()).map_err(|e| e.to_string())?,
    };
    let prefix = a.ipc_prefix.clone().unwrap_or(run.ipc_prefix.clone());
    let scn = run
        .scenario(a.config.as_deref(), &a.overrides)
        .map_err(|e| e.to_string())?;
    let listener = match a.listen_fd {
        // SAFETY: the descriptor is the bound listener `evoloop run --live` made for this
        // process and passed on, owned by nothing else here.
        Some(fd) => {
            // SAFETY: as above; fcntl on that descriptor sets close-on-exec again, so nothing
            // this process might start inherits the port.
            unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) };
            // SAFETY: the listener's descriptor, owned by nothing else (above): the listener
            // takes it over.
            unsafe { std::os::fd::FromRawFd::from_raw_fd(fd) }
        }
        None => bind(&a.addr, a.remote, "--remote").map_err(|e| e.to_string())?,
    };
    let access = Access::new(&listener)?;
    let ipc = Ipc::with_cleanup("evoloop-live", &run.run_id, &prefix, false)
        .map_err(|e| format!("attaching to run {}: {e}", run.run_id))?;
    let mut hub = Hub::new(&ipc, &scn).map_err(|e| format!("run {}: {e}", run.run_id))?;
    let (join_tx, join_rx) = channel::<SyncSender<Out>>();
    let (ask_tx, ask_rx) = channel::<Ask>();
    let info = server_info(&run.run_id, &scn);
    let advertise = advertise(!hub.joints.is_empty());
    eprintln!(
        "evoloop live: run {} on ws://{} (Foxglove WebSocket)",
        run.run_id,
        listener.local_addr().map_err(|e| e.to_string())?
    );
    let served = Served {
        info,
        advertise,
        join: join_tx,
        ask: ask_tx,
        access,
    };
    std::thread::Builder::new()
        .name("live-accept".into())
        .spawn(move || accept(listener, served))
        .map_err(|e| e.to_string())?;
    let stop = crate::node::start::stop_flag();
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        // At most MAX_CLIENTS: `accept` admits no more connections than that.
        while let Ok(c) = join_rx.try_recv() {
            hub.clients.push(c);
        }
        while let Ok(ask) = ask_rx.try_recv() {
            hub.ask(ask);
        }
        if !hub.poll() {
            break;
        }
        std::thread::sleep(POLL);
    }
    if hub.dropped > 0 {
        eprintln!(
            "evoloop live: {} messages dropped for viewers that could not keep up",
            hub.dropped
        );
    }
    Ok(())
}

fn server_info(run_id: &str, scn: &Scenario) -> String {
    json!({
        "op": "serverInfo",
        "name": format!("evoloop live: {} ({run_id})", scn.name),
        "capabilities": ["parameters"],
        "supportedEncodings": [],
        "metadata": {"run_id": run_id, "scenario": scn.name, "period_s": scn.timing.period.to_string()},
        "sessionId": run_id,
    })
    .to_string()
}

fn advertise(joints: bool) -> String {
    let channels: Vec<Value> = SERVED
        .iter()
        .filter(|t| joints || **t != "joint_states")
        .map(|topic| {
            let ty = ros2::message_type(topic).expect("served topics are run topics");
            json!({
                "id": channel_id(topic),
                "topic": topic,
                "encoding": ros2::MESSAGE_ENCODING,
                "schemaName": ty.name,
                "schema": ty.schema(),
                "schemaEncoding": ros2::SCHEMA_ENCODING,
            })
        })
        .collect();
    json!({"op": "advertise", "channels": channels}).to_string()
}

/// The run's side: its topics, the parameter and the clients' queues.
struct Hub {
    state: Sub<PlantState>,
    command: Sub<Command>,
    telemetry: Sub<Telemetry>,
    params_in: Sub<ParamSet>,
    /// The parameter `gains`; a set's answer goes back to its viewer (request id, queue).
    gains: Gains<(Value, SyncSender<Out>)>,
    clients: Vec<SyncSender<Out>>,
    joints: Vec<String>,
    /// Messages dropped for slow clients.
    dropped: u64,
    buf: Vec<u8>,
    /// When telemetry was last heard (none yet: the run may still be starting).
    last_heard: Option<Instant>,
    /// The newest state's stamp, and the commands' stamps by cycle (telemetry is stamped with
    /// its cycle's command's, as in run.mcap).
    stamp_ns: u64,
    command_stamps: [(u64, u64); 256],
}

impl Hub {
    fn new(ipc: &Ipc, scn: &Scenario) -> Result<Self, crate::ipc::IpcError> {
        Ok(Self {
            state: ipc.subscriber(Topic::State, 64, false)?,
            command: ipc.subscriber(Topic::Command, 64, false)?,
            telemetry: ipc.subscriber(Topic::Telemetry, 64, false)?,
            params_in: ipc.subscriber(Topic::Params, 16, false)?,
            gains: Gains::new(ipc, scn, &format!("viewers' `{GAINS}`"))?,
            clients: Vec::new(),
            joints: scn.joint_names(),
            dropped: 0,
            buf: Vec::with_capacity(16 << 10),
            last_heard: None,
            stamp_ns: 0,
            command_stamps: [(u64::MAX, 0); 256],
        })
    }

    /// Drain the topics to the clients; false once the run has gone quiet for good (no
    /// telemetry for 5 s after some was heard).
    fn poll(&mut self) -> bool {
        let (state, command, telemetry, params, joints) = (
            channel_id("state"),
            channel_id("command"),
            channel_id("telemetry"),
            channel_id("params"),
            channel_id("joint_states"),
        );
        while let Ok(Some(s)) = self.state.next() {
            self.stamp_ns = s.stamp_ns;
            ros2::encode_state(&mut self.buf, &s);
            self.broadcast(state, s.stamp_ns);
            if !self.joints.is_empty() {
                ros2::encode_joint_state(&mut self.buf, &s, &self.joints);
                self.broadcast(joints, s.stamp_ns);
            }
        }
        while let Ok(Some(c)) = self.command.next() {
            self.command_stamps[c.cycle as usize % 256] = (c.cycle, c.stamp_ns);
            ros2::encode_command(&mut self.buf, &c);
            self.broadcast(command, c.stamp_ns);
        }
        while let Ok(Some(p)) = self.params_in.next() {
            self.gains.saw_set(&p);
            // The cycle that took it is not known here: 0.
            ros2::encode_params(&mut self.buf, &p, 0);
            self.broadcast(params, self.stamp_ns);
        }
        while let Ok(Some(t)) = self.telemetry.next() {
            self.last_heard = Some(Instant::now());
            if let Some(((id, reply), answer)) = self.gains.saw_telemetry(&t) {
                self.reply(&id, &reply, &answer);
            }
            let stamp = match self.command_stamps[t.cycle as usize % 256] {
                (cycle, stamp) if cycle == t.cycle => stamp,
                _ => self.stamp_ns,
            };
            ros2::encode_telemetry(&mut self.buf, &t);
            self.broadcast(telemetry, stamp);
        }
        for ((id, reply), answer) in self.gains.expired() {
            self.reply(&id, &reply, &answer);
        }
        self.last_heard
            .is_none_or(|at| at.elapsed() < Duration::from_secs(5))
    }

    fn broadcast(&mut self, channel: u32, stamp_ns: u64) {
        let payload = Arc::new(self.buf.clone());
        let dropped = &mut self.dropped;
        self.clients.retain(|c| {
            match c.try_send(Out::Data {
                channel,
                stamp_ns,
                payload: payload.clone(),
            }) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    *dropped += 1;
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            }
        });
    }

    fn ask(&mut self, ask: Ask) {
        match ask {
            Ask::Get { id, reply } => {
                let _ = reply.try_send(Out::Text(values_message(self.gains.values(), &id)));
            }
            Ask::Set { id, values, reply } => {
                if let Err(((id, reply), why)) = self.gains.set(values, (id, reply)) {
                    let _ = reply.try_send(Out::Text(status(2, &format!("`{GAINS}`: {why}"))));
                    let _ = reply.try_send(Out::Text(values_message(self.gains.values(), &id)));
                }
            }
        }
    }

    /// A set's answer to its viewer: a status (info when accepted, a warning when unanswered,
    /// an error when refused) and the values in service.
    fn reply(&self, id: &Value, reply: &SyncSender<Out>, answer: &Answer) {
        let level = match answer {
            Answer::Accepted { .. } => 0,
            Answer::NoAnswer { .. } => 1,
            Answer::Refused { .. } => 2,
        };
        let _ = reply.try_send(Out::Text(status(level, &answer.to_string())));
        let _ = reply.try_send(Out::Text(values_message(self.gains.values(), id)));
    }
}

fn values_message(values: &[f64], id: &Value) -> String {
    let mut m = json!({
        "op": "parameterValues",
        "parameters": [{"name": GAINS, "value": values, "type": "float64_array"}],
    });
    if !id.is_null() {
        m["id"] = id.clone();
    }
    m.to_string()
}

/// A status message: level 0 info, 1 warning, 2 error.
fn status(level: u8, message: &str) -> String {
    json!({"op": "status", "level": level, "message": message}).to_string()
}

/// `addr` bound for viewers; an address beyond loopback only with `remote` (the flag that
/// says so is `flag`): anyone who reaches the port sees the run.
pub fn bind(addr: &str, remote: bool, flag: &'static str) -> Result<TcpListener, BindError> {
    use std::net::ToSocketAddrs;
    let system = |source| BindError::System {
        addr: addr.to_string(),
        source,
    };
    let addrs: Vec<_> = addr.to_socket_addrs().map_err(system)?.collect();
    if !remote && addrs.iter().any(|a| !a.ip().to_canonical().is_loopback()) {
        return Err(BindError::BeyondLoopback {
            addr: addr.to_string(),
            flag,
        });
    }
    TcpListener::bind(&addrs[..]).map_err(system)
}

/// Why `bind` gave no listener.
#[derive(Debug)]
pub enum BindError {
    /// The address does not resolve, or the system refused to bind it.
    System {
        /// The address.
        addr: String,
        /// The system's error.
        source: std::io::Error,
    },
    /// The address reaches beyond this machine and the flag that allows it was not given.
    BeyondLoopback {
        /// The address.
        addr: String,
        /// The flag that would allow it.
        flag: &'static str,
    },
}

impl std::fmt::Display for BindError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BindError::System { addr, source } => write!(f, "{addr}: {source}"),
            BindError::BeyondLoopback { addr, flag } => write!(
                f,
                "{addr} listens beyond this machine: anyone who reaches it sees the run; listen \
                 on 127.0.0.1 (the default), or add {flag} to mean it (viewers on other machines \
                 then set gains only with the token it prints)"
            ),
        }
    }
}

impl std::error::Error for BindError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            BindError::System { source, .. } => Some(source),
            BindError::BeyondLoopback { .. } => None,
        }
    }
}

/// Who may set `gains`: a viewer on this machine, and one elsewhere only with the token (made
/// at start where the listener reaches beyond loopback, and printed there).
struct Access {
    token: Option<String>,
}

impl Access {
    fn new(listener: &TcpListener) -> Result<Access, String> {
        let at = listener.local_addr().map_err(|e| e.to_string())?;
        if at.ip().to_canonical().is_loopback() {
            return Ok(Access { token: None });
        }
        let token = format!("{:032x}", rand::random::<u128>());
        eprintln!(
            "evoloop live: warning: listening on {at}, beyond this machine: anyone who reaches \
             it sees the run; a viewer elsewhere sets gains only through \
             ws://HOST:{}/?token={token}",
            at.port()
        );
        Ok(Access { token: Some(token) })
    }

    /// Whether the viewer at `peer`, which asked for `uri`, may set `gains`.
    fn may_set(&self, peer: Option<std::net::SocketAddr>, uri: &tungstenite::http::Uri) -> bool {
        // An IPv4 viewer of this machine on a [::] listener comes as ::ffff:127.0.0.1.
        if peer.is_some_and(|p| p.ip().to_canonical().is_loopback()) {
            return true;
        }
        let Some(token) = &self.token else {
            return false;
        };
        uri.query()
            .into_iter()
            .flat_map(|q| q.split('&'))
            .filter_map(|kv| kv.strip_prefix("token="))
            .any(|t| same(t.as_bytes(), token.as_bytes()))
    }
}

/// `a == b` in a time that does not tell how much of a token was right.
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0, |d, (x, y)| d | (x ^ y)) == 0
}

/// What every connection is served with: the run's description, the hub's queues, who may set.
struct Served {
    info: String,
    advertise: String,
    join: Sender<SyncSender<Out>>,
    ask: Sender<Ask>,
    access: Access,
}

/// One of the MAX_CLIENTS places, given back when its connection's thread ends.
struct Place(Arc<std::sync::atomic::AtomicUsize>);

impl Drop for Place {
    fn drop(&mut self) {
        self.0.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

/// Accept connections for ever: each of at most MAX_CLIENTS at once gets its thread, one more
/// is answered 503 and closed at once (a crowd of idle connections or unfinished handshakes
/// costs a bounded number of threads, and none of them for long: `HANDSHAKE`).
fn accept(listener: TcpListener, served: Served) {
    use std::sync::atomic::Ordering;
    let served = Arc::new(served);
    let taken = Arc::new(std::sync::atomic::AtomicUsize::new(0));
    for stream in listener.incoming().flatten() {
        if taken.fetch_add(1, Ordering::SeqCst) >= MAX_CLIENTS {
            taken.fetch_sub(1, Ordering::SeqCst);
            refuse(stream);
            continue;
        }
        let place = Place(taken.clone());
        let served = served.clone();
        let _ = std::thread::Builder::new()
            .name("live-client".into())
            .spawn(move || {
                let _place = place;
                if let Err(e) = client(stream, &served) {
                    eprintln!("evoloop live: a viewer left: {e}");
                }
            });
    }
}

/// A connection beyond MAX_CLIENTS: told why in HTTP (never waiting on it), and closed.
fn refuse(stream: TcpStream) {
    use std::io::Write;
    let why = format!("{MAX_CLIENTS} viewers are connected already\n");
    let reply = format!(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: text/plain\r\nContent-Length: {}\r\n\
         Connection: close\r\n\r\n{why}",
        why.len()
    );
    use std::io::Read;
    let _ = stream.set_nonblocking(true);
    let _ = (&stream).write(reply.as_bytes());
    // Closed with the request unread, the connection would be reset, and the reply with it:
    // end the writing side, then drop what has come so far.
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let _ = (&stream).read(&mut [0u8; 4096]);
}

/// A connection whose reads end at `until` (the handshake's deadline) however slowly its bytes
/// come; no deadline after the handshake.
struct Timed {
    tcp: TcpStream,
    until: Option<Instant>,
}

impl std::io::Read for Timed {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if let Some(until) = self.until {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    format!("no WebSocket handshake within {HANDSHAKE:?}"),
                ));
            }
            self.tcp.set_read_timeout(Some(left))?;
        }
        self.tcp.read(buf)
    }
}

impl std::io::Write for Timed {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.tcp.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.tcp.flush()
    }
}

type Ws = tungstenite::WebSocket<Timed>;

/// One viewer: the handshake (the subprotocol required, within `HANDSHAKE`), serverInfo and
/// advertise, then its requests read and its queue written until it leaves.
fn client(stream: TcpStream, served: &Served) -> Result<(), String> {
    use tungstenite::handshake::server::{ErrorResponse, Request, Response};
    use tungstenite::Message;
    let peer = stream.peer_addr().ok();
    let mut may_set = false;
    // The signature is tungstenite's handshake callback's.
    #[allow(clippy::result_large_err)]
    let pick = |req: &Request, mut resp: Response| -> Result<Response, ErrorResponse> {
        let offered = req
            .headers()
            .get_all("Sec-WebSocket-Protocol")
            .iter()
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(',').map(str::trim))
            .any(|p| p == SUBPROTOCOL);
        if !offered {
            let mut e = ErrorResponse::new(Some(format!("subprotocol {SUBPROTOCOL} required")));
            *e.status_mut() = tungstenite::http::StatusCode::BAD_REQUEST;
            return Err(e);
        }
        may_set = served.access.may_set(peer, req.uri());
        resp.headers_mut().insert(
            "Sec-WebSocket-Protocol",
            tungstenite::http::HeaderValue::from_static(SUBPROTOCOL),
        );
        Ok(resp)
    };
    let config = tungstenite::protocol::WebSocketConfig::default()
        .max_message_size(Some(MAX_MESSAGE))
        .max_frame_size(Some(MAX_MESSAGE));
    let timed = Timed {
        tcp: stream,
        until: Some(Instant::now() + HANDSHAKE),
    };
    let mut ws = tungstenite::accept_hdr_with_config(timed, pick, Some(config)).map_err(|e| {
        match e {
            // The deadline's read timeout: the handshake did not finish in time.
            tungstenite::HandshakeError::Interrupted(_) => {
                format!("no WebSocket handshake within {HANDSHAKE:?}")
            }
            e => e.to_string(),
        }
    })?;
    ws.get_mut().until = None;
    let tcp = &ws.get_ref().tcp;
    tcp.set_read_timeout(Some(Duration::from_millis(5)))
        .and_then(|()| tcp.set_write_timeout(Some(WRITE_TIMEOUT)))
        .map_err(|e| e.to_string())?;
    let io = |e: tungstenite::Error| e.to_string();
    ws.send(Message::text(served.info.as_str())).map_err(io)?;
    ws.send(Message::text(served.advertise.as_str()))
        .map_err(io)?;
    let (tx, rx) = sync_channel::<Out>(CLIENT_QUEUE);
    served
        .join
        .send(tx.clone())
        .map_err(|_| "the hub has stopped")?;
    // Subscription ids by channel id.
    let mut subscribed: Vec<(u32, u32)> = Vec::new();
    loop {
        match ws.read() {
            Ok(Message::Text(t)) => {
                request(&t, &mut subscribed, &tx, (&served.ask, may_set), &mut ws)?
            }
            Ok(Message::Close(_)) => return Ok(()),
            Ok(_) => {}
            Err(tungstenite::Error::Io(e))
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(tungstenite::Error::ConnectionClosed) => return Ok(()),
            Err(e) => return Err(e.to_string()),
        }
        let mut wrote = false;
        while let Ok(out) = rx.try_recv() {
            let msg = match out {
                Out::Text(t) => Message::text(t),
                Out::Data {
                    channel,
                    stamp_ns,
                    payload,
                } => {
                    let Some(&(_, sub)) = subscribed.iter().find(|(c, _)| *c == channel) else {
                        continue;
                    };
                    let mut frame = Vec::with_capacity(13 + payload.len());
                    frame.push(0x01);
                    frame.extend_from_slice(&sub.to_le_bytes());
                    frame.extend_from_slice(&stamp_ns.to_le_bytes());
                    frame.extend_from_slice(&payload);
                    Message::binary(frame)
                }
            };
            ws.write(msg).map_err(io)?;
            wrote = true;
        }
        if wrote {
            ws.flush().map_err(io)?;
        }
    }
}

/// What a viewer on another machine without the token is told when it asks for `gains`.
const NOT_FROM_HERE: &str = "`gains` is set only from this machine, or with the token the \
                             live view printed at start (ws://HOST:PORT/?token=TOKEN)";

/// One text request of a client (subscribe, unsubscribe, getParameters, setParameters); others
/// are answered with a warning.
/// A viewer that may not set `gains` (`may_set` false: on another machine, without the token)
/// has its sets refused with the reason.
fn request(
    text: &str,
    subscribed: &mut Vec<(u32, u32)>,
    reply: &SyncSender<Out>,
    (ask, may_set): (&Sender<Ask>, bool),
    ws: &mut Ws,
) -> Result<(), String> {
    let warn = |ws: &mut Ws, m: String| {
        ws.send(tungstenite::Message::text(status(1, &m)))
            .map_err(|e| e.to_string())
    };
    let Ok(v) = serde_json::from_str::<Value>(text) else {
        return warn(ws, "not JSON".into());
    };
    let id = v.get("id").cloned().unwrap_or(Value::Null);
    match v["op"].as_str().unwrap_or("") {
        "subscribe" => {
            for s in v["subscriptions"].as_array().into_iter().flatten() {
                let id = |k: &str| s[k].as_u64().and_then(|x| u32::try_from(x).ok());
                let (Some(sub), Some(ch)) = (id("id"), id("channelId")) else {
                    warn(
                        ws,
                        format!("a subscription needs u32 `id` and `channelId`: {s}"),
                    )?;
                    continue;
                };
                if !SERVED.iter().any(|t| channel_id(t) == ch) {
                    warn(ws, format!("no channel {ch}"))?;
                    continue;
                }
                subscribed.retain(|(c, _)| *c != ch);
                subscribed.push((ch, sub));
            }
        }
        "unsubscribe" => {
            let ids: Vec<u64> = v["subscriptionIds"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(Value::as_u64)
                .collect();
            subscribed.retain(|(_, s)| !ids.contains(&(*s as u64)));
        }
        "getParameters" => {
            let _ = ask.send(Ask::Get {
                id,
                reply: reply.clone(),
            });
        }
        "setParameters" => {
            if !may_set {
                let e = tungstenite::Message::text(status(2, NOT_FROM_HERE));
                return ws.send(e).map_err(|e| e.to_string());
            }
            for p in v["parameters"].as_array().into_iter().flatten() {
                if p["name"] != GAINS {
                    warn(
                        ws,
                        format!("no parameter {}; there is `{GAINS}`", p["name"]),
                    )?;
                    continue;
                }
                let values: Option<Vec<f64>> = p["value"]
                    .as_array()
                    .map(|a| a.iter().map(Value::as_f64).collect())
                    .unwrap_or(None);
                match values {
                    Some(values) => {
                        let _ = ask.send(Ask::Set {
                            id: id.clone(),
                            values,
                            reply: reply.clone(),
                        });
                    }
                    None => warn(ws, format!("`{GAINS}` takes an array of numbers"))?,
                }
            }
        }
        op => warn(ws, format!("operation `{op}` is not served"))?,
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Access;

    /// A viewer on this machine may set `gains`; one elsewhere only with the token, which a
    /// listener on loopback has none of (issue 63, item 6).
    #[test]
    fn gains_from_another_machine_need_the_token() {
        let uri = |q: &str| format!("/{q}").parse::<tungstenite::http::Uri>().unwrap();
        let here = Some("127.0.0.1:50000".parse().unwrap());
        let there = Some("192.0.2.7:50000".parse().unwrap());
        let mapped = Some("[::ffff:127.0.0.1]:50000".parse().unwrap());
        let open = Access {
            token: Some("abc123".into()),
        };
        assert!(open.may_set(here, &uri("")));
        assert!(open.may_set(mapped, &uri("")));
        assert!(!open.may_set(there, &uri("")));
        assert!(!open.may_set(there, &uri("?token=abc12")));
        assert!(!open.may_set(None, &uri("?token=")));
        assert!(open.may_set(there, &uri("?x=1&token=abc123")));
        let loopback = Access { token: None };
        assert!(!loopback.may_set(there, &uri("?token=")));
    }

    #[test]
    fn an_address_beyond_loopback_is_refused_without_its_flag() {
        let e = super::bind("0.0.0.0:0", false, "--live-remote").unwrap_err();
        assert!(
            matches!(
                e,
                super::BindError::BeyondLoopback {
                    flag: "--live-remote",
                    ..
                }
            ),
            "{e:?}"
        );
        let said = e.to_string();
        assert!(
            said.contains("beyond this machine") && said.contains("--live-remote"),
            "{said}"
        );
        assert!(super::bind("127.0.0.1:0", false, "--live-remote").is_ok());
        assert!(super::bind("0.0.0.0:0", true, "--live-remote").is_ok());
    }
}
