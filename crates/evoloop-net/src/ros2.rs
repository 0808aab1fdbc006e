//! `evoloop bridge --ros2`: the run as a ROS 2 node over rmw_zenoh (ROS 2's Zenoh middleware),
//! so ROS 2 nodes (`RMW_IMPLEMENTATION=rmw_zenoh_cpp`, connected to the same Zenoh router or
//! peer) see its topics and may set its gains, with no ROS 2 installed here. Names, hashes and
//! bytes are `report::ros2::rmw_zenoh`'s; this is the I/O.
//!
//! Topics, under the node's namespace (`--ros-namespace`, default `/evoloop`):
//!
//! | topic | type | what |
//! |---|---|---|
//! | `joint_states` | `sensor_msgs/msg/JointState` | an arm's joints (as in run.mcap) |
//! | `state`, `command`, `telemetry` | `evoloop_msgs/msg/...` | the run's messages, field for field |
//! | `u` | `std_msgs/msg/Float64MultiArray` | the command's u, for tools without evoloop_msgs |
//! | `gains` | `std_msgs/msg/Float64MultiArray` | the controller's values in service: on a change and every second |
//! | `set_gains` (in) | `std_msgs/msg/Float64MultiArray` | a set of gains, validated by the controller (`crate::gains`) |
//! | `set_gains_result` | `rcl_interfaces/msg/SetParametersResult` | its answer: accepted, or refused with the reason |
//!
//! The streams are declared best effort (Zenoh drops rather than hold up the relay, as the
//! bridge's own keys do); `gains`, `set_gains` and its result reliable. A set is taken from a
//! publisher of any type hash (the type's name must be `Float64MultiArray`'s and the message
//! must read as one): some ROS 2 libraries on Zenoh do not compute hashes.

use crate::config::Scenario;
use crate::gains::{Answer, Gains};
use crate::ipc::{Ipc, Sub, Topic};
use crate::msg::{Command, ParamSet, PlantState, Telemetry, MAX_PARAMS};
use crate::report::ros2::{self, rmw_zenoh as rz, MessageType};
use crate::NetError;
use std::time::{Duration, Instant, SystemTime};
use zenoh::handlers::{FifoChannel, FifoChannelHandler};
use zenoh::liveliness::LivelinessToken;
use zenoh::pubsub::{Publisher, Subscriber};
use zenoh::qos::CongestionControl;
use zenoh::sample::Sample;
use zenoh::Wait as _;

/// What the node did, in the bridge's report.
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct Ros2Report {
    /// The node's full name, `<namespace>/<name>`.
    pub node: String,
    /// Its ROS 2 domain id.
    pub domain: u32,
    /// Messages put on the ROS 2 topics, and of them joint states.
    pub messages_out: u64,
    /// Of them, `joint_states` messages (an arm's run only).
    pub joint_states_out: u64,
    /// Sets of gains from ROS 2, the controller's acceptances and refusals (those refused
    /// before reaching it included), and messages on `set_gains` that did not read.
    pub sets_in: u64,
    /// Sets the controller accepted.
    pub sets_accepted: u64,
    /// Sets refused, by the controller or before reaching it (unreadable ones included).
    pub sets_refused: u64,
    /// Messages on `set_gains` that did not read as a `Float64MultiArray`.
    pub unreadable: u64,
    /// The first put that failed, if any (the others are counted in `put_errors`).
    pub put_errors: u64,
    /// The first failed put: its key and Zenoh's error.
    pub first_error: Option<String>,
}

/// A ROS 2 publisher: its Zenoh publisher, its liveliness token, GID and sequence numbers.
struct RosPub {
    net: Publisher<'static>,
    _token: LivelinessToken,
    gid: [u8; 16],
    seq: i64,
}

/// The run's node.
pub struct Ros2Node {
    _node: LivelinessToken,
    joint_states: Option<RosPub>,
    state: RosPub,
    command: RosPub,
    telemetry: RosPub,
    u: RosPub,
    gains_out: RosPub,
    result: RosPub,
    set_gains: Subscriber<FifoChannelHandler<Sample>>,
    _set_gains_token: LivelinessToken,
    params: Sub<ParamSet>,
    gains: Gains<()>,
    joints: Vec<String>,
    buf: Vec<u8>,
    /// The version last published on `gains`, and when.
    gains_published: Option<(u64, Instant)>,
    /// What the node has done so far (the bridge's report takes it at the end).
    pub report: Ros2Report,
}

/// How often `gains` is published when nothing changes (a late subscriber hears it soon).
const GAINS_EVERY: Duration = Duration::from_secs(1);

fn token(z: &zenoh::Session, key: String) -> Result<LivelinessToken, NetError> {
    z.liveliness()
        .declare_token(key.clone())
        .wait()
        .map_err(NetError::zenoh(format!("Zenoh liveliness token {key}")))
}

impl Ros2Node {
    /// Declare the run's node on `z` under `name`: its liveliness token, its publishers (an
    /// arm's `joint_states` too), its `set_gains` subscription, and a subscriber on the run's
    /// params topic. Fails when Zenoh or iceoryx2 refuses one of them.
    pub fn new(
        z: &zenoh::Session,
        ipc: &Ipc,
        scn: &Scenario,
        name: &rz::NodeName,
    ) -> Result<Self, NetError> {
        let me = rz::Node {
            name: name.clone(),
            zid: z.zid().to_string(),
            id: 0,
        };
        let node = token(z, me.token())?;
        let mut next_id = 0u64;
        let mut entity = |topic: &str, ty: &MessageType, kind, qos| {
            next_id += 1;
            let fq = name.topic(topic)?;
            Ok::<_, NetError>(me.entity(next_id, kind, &fq, ty, qos))
        };
        let stream = rz::Qos::BestEffort { depth: 10 };
        let reliable = rz::Qos::Reliable { depth: 10 };
        let mut publisher = |topic: &str, ty: &MessageType, qos: rz::Qos| {
            let e = entity(topic, ty, rz::EntityKind::Publisher, qos)?;
            let cc = match qos {
                rz::Qos::BestEffort { .. } => CongestionControl::Drop,
                rz::Qos::Reliable { .. } => CongestionControl::Block,
            };
            Ok::<_, NetError>(RosPub {
                net: super::bridge::publisher(z, e.key, cc)?,
                gid: rz::gid(&e.token),
                _token: token(z, e.token)?,
                seq: 0,
            })
        };
        let joints = scn.joint_names();
        let joint_states = if joints.is_empty() {
            None
        } else {
            Some(publisher("joint_states", &ros2::JOINT_STATE, stream)?)
        };
        let state = publisher("state", &ros2::PLANT_STATE, stream)?;
        let command = publisher("command", &ros2::COMMAND, stream)?;
        let telemetry = publisher("telemetry", &ros2::TELEMETRY, stream)?;
        let u = publisher("u", &ros2::FLOAT64_MULTI_ARRAY, stream)?;
        let gains_out = publisher("gains", &ros2::FLOAT64_MULTI_ARRAY, reliable)?;
        let result = publisher("set_gains_result", &ros2::SET_PARAMETERS_RESULT, reliable)?;
        let e = entity(
            "set_gains",
            &ros2::FLOAT64_MULTI_ARRAY,
            rz::EntityKind::Subscription,
            reliable,
        )?;
        // Any hash: the key's last chunk.
        let any_hash = match e.key.rsplit_once('/') {
            Some((head, _)) => format!("{head}/*"),
            None => e.key.clone(),
        };
        let set_gains = z
            .declare_subscriber(any_hash.clone())
            .with(FifoChannel::new(64))
            .wait()
            .map_err(NetError::zenoh(format!("Zenoh subscriber on {any_hash}")))?;
        Ok(Self {
            _node: node,
            joint_states,
            state,
            command,
            telemetry,
            u,
            gains_out,
            result,
            set_gains,
            _set_gains_token: token(z, e.token)?,
            params: ipc.subscriber(Topic::Params, Topic::Params.max_buffer(), false)?,
            gains: Gains::new(ipc, scn, "ROS 2 `set_gains`")?,
            joints,
            buf: Vec::with_capacity(4096),
            gains_published: None,
            report: Ros2Report {
                node: format!("{}/{}", name.namespace.trim_end_matches('/'), name.name),
                domain: name.domain,
                ..Default::default()
            },
        })
    }

    /// Put `self.buf` on `p`, with its attachment; a failure is counted, not fatal (the run
    /// and the bridge's own keys go on).
    fn put(buf: &[u8], p: &mut RosPub, report: &mut Ros2Report) {
        p.seq += 1;
        let now = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos() as i64);
        let attachment = rz::attachment(p.seq, now, &p.gid);
        match p.net.put(buf).attachment(attachment.to_vec()).wait() {
            Ok(()) => report.messages_out += 1,
            Err(e) => {
                report.put_errors += 1;
                report
                    .first_error
                    .get_or_insert_with(|| format!("{}: {e}", p.net.key_expr()));
            }
        }
    }

    /// Put a state on `state` and, for an arm, on `joint_states`.
    pub fn state(&mut self, s: &PlantState) {
        if let Some(p) = self.joint_states.as_mut() {
            ros2::encode_joint_state(&mut self.buf, s, &self.joints);
            Self::put(&self.buf, p, &mut self.report);
            self.report.joint_states_out += 1;
        }
        ros2::encode_state(&mut self.buf, s);
        Self::put(&self.buf, &mut self.state, &mut self.report);
    }

    /// Put a command on `command`, and its `u[..n_u]` on `u`.
    pub fn command(&mut self, c: &Command) {
        ros2::encode_command(&mut self.buf, c);
        Self::put(&self.buf, &mut self.command, &mut self.report);
        ros2::encode_float64_multi_array(&mut self.buf, "u", ros2::first(&c.u, c.n_u));
        Self::put(&self.buf, &mut self.u, &mut self.report);
    }

    /// Put a telemetry sample on `telemetry`; when it shows the controller's answer to a set from
    /// `set_gains`, publish that answer on `set_gains_result`.
    pub fn telemetry(&mut self, t: &Telemetry) {
        ros2::encode_telemetry(&mut self.buf, t);
        Self::put(&self.buf, &mut self.telemetry, &mut self.report);
        if let Some(((), answer)) = self.gains.saw_telemetry(t) {
            self.answer(&answer);
        }
    }

    /// Sets seen on the run's params topic, sets from ROS 2, unanswered ones, and `gains`.
    pub fn poll(&mut self) {
        while let Ok(Some(p)) = self.params.next() {
            self.gains.saw_set(&p);
        }
        while let Ok(Some(sample)) = self.set_gains.try_recv() {
            self.report.sets_in += 1;
            let bytes = sample.payload().to_bytes();
            match ros2::decode_float64_multi_array(&bytes, MAX_PARAMS) {
                Err(e) => {
                    self.report.unreadable += 1;
                    self.refused(&format!("not a std_msgs/msg/Float64MultiArray: {e}"));
                }
                Ok(values) => {
                    if let Err(((), why)) = self.gains.set(values, ()) {
                        self.refused(&why.to_string());
                    }
                }
            }
        }
        for ((), answer) in self.gains.expired() {
            self.answer(&answer);
        }
        let version = self.gains.version();
        let due = match self.gains_published {
            Some((v, at)) => v != version || at.elapsed() >= GAINS_EVERY,
            None => true,
        };
        if due {
            ros2::encode_float64_multi_array(&mut self.buf, "gains", self.gains.values());
            Self::put(&self.buf, &mut self.gains_out, &mut self.report);
            self.gains_published = Some((version, Instant::now()));
        }
    }

    fn answer(&mut self, answer: &Answer) {
        match answer {
            Answer::Accepted { .. } => {
                self.report.sets_accepted += 1;
                ros2::encode_set_parameters_result(&mut self.buf, true, &answer.to_string());
                Self::put(&self.buf, &mut self.result, &mut self.report);
            }
            _ => self.refused(&answer.to_string()),
        }
    }

    fn refused(&mut self, why: &str) {
        self.report.sets_refused += 1;
        ros2::encode_set_parameters_result(&mut self.buf, false, why);
        Self::put(&self.buf, &mut self.result, &mut self.report);
    }
}
