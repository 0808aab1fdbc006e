//! The run's messages as ROS 2 messages: their definitions (`ros2msg`, the text `ros2 interface
//! show` prints, dependencies appended as rosbag2 writes them) and their CDR encoding (OMG CDR,
//! little endian, the 4-byte encapsulation header ROS 2's rmw layers put before every message).
//!
//! Why ROS 2 CDR and not protobuf: Foxglove and PlotJuggler decode both from the schema alone,
//! but CDR is also what a ROS 2 node receives over rmw_zenoh or DDS, so one encoding serves the
//! recording, a ROS 2 bridge and the tools of the users' other nodes; it needs no code
//! generator, and its layout (fixed-size fields at natural alignment, sequences as a u32 count and
//! their elements) costs no more to write than a copy.
//!
//! Each of evoloop's topics keeps its own message, field for field as the processes exchange
//! it (the counts become the sequences' lengths), so a recording reads back bit for bit: every
//! f64 is its 8 bytes, NaN payloads and signed zeros included. Where a standard message fits, the
//! recording carries it too: `sensor_msgs/msg/JointState` for an arm's joints.

use evoloop_msg::{Command, LinearEstimate, ModelEstimate, ParamSet, PlantState, Telemetry};

mod hash;
pub mod rmw_zenoh;
pub use hash::{hashed_description, type_hash, DefinitionError};

/// MCAP's names of the message and schema encodings.
pub const MESSAGE_ENCODING: &str = "cdr";
/// MCAP's name of the schema encoding: ROS 2 `.msg` definitions (`MessageType::schema`).
pub const SCHEMA_ENCODING: &str = "ros2msg";

/// The package evoloop's own messages are named in.
pub const PACKAGE: &str = "evoloop_msgs";

/// The separator between a definition and each dependency's (rosbag2's, 80 '=').
const SEPARATOR: &str =
    "================================================================================\n";

/// ROS 2's CDR header: representation CDR_LE (0x0001), options 0.
const CDR_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// A message being written: the header, then fields at their natural alignment, measured from
/// the end of the header (the CDR stream's origin).
pub struct CdrWriter<'a>(&'a mut Vec<u8>);

impl<'a> CdrWriter<'a> {
    /// Start a message in `buf` (cleared).
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&CDR_LE);
        Self(buf)
    }

    fn align(&mut self, n: usize) {
        let pad = (n - (self.0.len() - CDR_LE.len()) % n) % n;
        self.0.resize(self.0.len() + pad, 0);
    }

    /// A `bool`: one byte, 0 or 1 (no alignment).
    pub fn bool(&mut self, v: bool) {
        self.0.push(v as u8);
    }

    /// A `uint32`, aligned to 4 bytes.
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int32`, aligned to 4 bytes.
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// A `uint64`, aligned to 8 bytes.
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// An `int64`, aligned to 8 bytes.
    pub fn i64(&mut self, v: i64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// A `float64`, aligned to 8 bytes: its exact bits.
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }

    /// A string: its length with the terminating NUL, its bytes, the NUL.
    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
    }

    /// A `float64[]`: the count, then (aligned only if there is one, as Fast-CDR writes) the
    /// values.
    pub fn f64s(&mut self, xs: &[f64]) {
        self.u32(xs.len() as u32);
        if !xs.is_empty() {
            self.align(8);
        }
        for x in xs {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }

    /// A `string[]`.
    pub fn strings<'s>(&mut self, items: impl ExactSizeIterator<Item = &'s str>) {
        self.u32(items.len() as u32);
        for s in items {
            self.string(s);
        }
    }

    /// `builtin_interfaces/Time` from CLOCK_MONOTONIC-style nanoseconds.
    pub fn time(&mut self, ns: u64) {
        self.i32((ns / 1_000_000_000).min(i32::MAX as u64) as i32);
        self.u32((ns % 1_000_000_000) as u32);
    }
}

/// Why a CDR message was refused, with the field it happened at: a recording's reader names
/// the damaged message, a bridge drops it and counts it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CdrError {
    /// Shorter than the 4-byte CDR header.
    NoHeader,
    /// Another representation than little-endian plain CDR: its identifier's two bytes.
    Representation([u8; 2]),
    /// The message ends inside `field`, read from byte `at`.
    CutShort {
        /// The field being read.
        field: &'static str,
        /// Its offset in the message, bytes.
        at: usize,
    },
    /// A `bool` that is neither 0 nor 1.
    NotABool {
        /// The field.
        field: &'static str,
        /// Its byte.
        byte: u8,
    },
    /// A string that is not UTF-8.
    NotUtf8 {
        /// The field.
        field: &'static str,
    },
    /// A sequence with more elements than the message type allows.
    TooLong {
        /// The sequence.
        field: &'static str,
        /// Its length on the wire.
        len: usize,
        /// The most the type allows.
        max: usize,
    },
    /// A count no message of this length can hold (each element takes at least a few bytes):
    /// a damaged length, refused before anything is allocated for it.
    Implausible {
        /// The sequence.
        field: &'static str,
        /// The count on the wire.
        count: usize,
        /// What is counted ("strings", "dimensions").
        of: &'static str,
    },
    /// Bytes after the last field, more than a writer's padding.
    Trailing {
        /// How many.
        bytes: usize,
    },
    /// A `PlantState` whose sequences disagree: velocities for every joint, an applied input for
    /// every output or joint.
    Inconsistent {
        /// Entries of `qd_true`.
        velocities: u32,
        /// Entries of `u_applied`.
        inputs: u32,
        /// Entries of `q_true`.
        joints: u32,
        /// Entries of `y`.
        outputs: u32,
    },
}

impl std::fmt::Display for CdrError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CdrError::NoHeader => write!(f, "shorter than a CDR header"),
            CdrError::Representation([a, b]) => write!(
                f,
                "CDR representation {a:02x}{b:02x}: only little-endian CDR (0001) is read"
            ),
            CdrError::CutShort { field, at } => write!(f, "cut short at `{field}` (byte {at})"),
            CdrError::NotABool { field, byte } => write!(f, "`{field}` is {byte}, not a bool"),
            CdrError::NotUtf8 { field } => write!(f, "`{field}` is not UTF-8"),
            CdrError::TooLong { field, len, max } => {
                write!(f, "`{field}` has {len} values, at most {max}")
            }
            CdrError::Implausible { field, count, of } => {
                write!(f, "`{field}` claims {count} {of}")
            }
            CdrError::Trailing { bytes } => {
                write!(f, "{bytes} bytes after the message's last field")
            }
            CdrError::Inconsistent {
                velocities,
                inputs,
                joints,
                outputs,
            } => write!(
                f,
                "{velocities} velocities and {inputs} inputs for {joints} joints and {outputs} outputs"
            ),
        }
    }
}

impl std::error::Error for CdrError {}

/// A message being read; every read checks the bounds and names what ran short.
pub struct CdrReader<'a> {
    b: &'a [u8],
    at: usize,
}

impl<'a> CdrReader<'a> {
    /// Refuse anything but little-endian plain CDR (what `CdrWriter` and ROS 2 write).
    pub fn new(b: &'a [u8]) -> Result<Self, CdrError> {
        match b.get(..4) {
            Some(h) if h[..2] == CDR_LE[..2] => Ok(Self { b, at: 4 }),
            Some(h) => Err(CdrError::Representation([h[0], h[1]])),
            None => Err(CdrError::NoHeader),
        }
    }

    fn align(&mut self, n: usize) {
        self.at += (n - (self.at - 4) % n) % n;
    }

    fn take<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        self.align(N);
        let bytes = self
            .at
            .checked_add(N)
            .and_then(|end| self.b.get(self.at..end))
            .ok_or(CdrError::CutShort {
                field: what,
                at: self.at,
            })?;
        self.at += N;
        Ok(bytes.try_into().expect("N bytes"))
    }

    /// A `bool`: 0 or 1, anything else refused.
    pub fn bool(&mut self, what: &'static str) -> Result<bool, CdrError> {
        match self.take::<1>(what)? {
            [0] => Ok(false),
            [1] => Ok(true),
            [byte] => Err(CdrError::NotABool { field: what, byte }),
        }
    }

    /// A `uint32`; `what` names the field in the error when the message is cut short.
    pub fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        self.take::<4>(what).map(u32::from_le_bytes)
    }

    /// An `int32`; `what` names the field in the error when the message is cut short.
    pub fn i32(&mut self, what: &'static str) -> Result<i32, CdrError> {
        self.take::<4>(what).map(i32::from_le_bytes)
    }

    /// A `uint64`; `what` names the field in the error when the message is cut short.
    pub fn u64(&mut self, what: &'static str) -> Result<u64, CdrError> {
        self.take::<8>(what).map(u64::from_le_bytes)
    }

    /// An `int64`; `what` names the field in the error when the message is cut short.
    pub fn i64(&mut self, what: &'static str) -> Result<i64, CdrError> {
        self.take::<8>(what).map(i64::from_le_bytes)
    }

    /// A `float64`, bit for bit; `what` names the field in the error when the message is cut short.
    pub fn f64(&mut self, what: &'static str) -> Result<f64, CdrError> {
        self.take::<8>(what).map(f64::from_le_bytes)
    }

    /// A `float64[]` into `out`; its length (refused if longer than `out`).
    pub fn f64s(&mut self, what: &'static str, out: &mut [f64]) -> Result<u32, CdrError> {
        let n = self.u32(what)?;
        if n as usize > out.len() {
            return Err(CdrError::TooLong {
                field: what,
                len: n as usize,
                max: out.len(),
            });
        }
        for slot in &mut out[..n as usize] {
            *slot = self.f64(what)?;
        }
        Ok(n)
    }

    /// A `float64[]` of at most `max` values.
    pub fn f64_vec(&mut self, what: &'static str, max: usize) -> Result<Vec<f64>, CdrError> {
        let n = self.u32(what)? as usize;
        if n > max {
            return Err(CdrError::TooLong {
                field: what,
                len: n,
                max,
            });
        }
        (0..n).map(|_| self.f64(what)).collect()
    }

    /// A string (the NUL dropped).
    pub fn string(&mut self, what: &'static str) -> Result<String, CdrError> {
        let n = self.u32(what)? as usize;
        let bytes = self
            .at
            .checked_add(n)
            .and_then(|end| self.b.get(self.at..end))
            .ok_or(CdrError::CutShort {
                field: what,
                at: self.at,
            })?;
        self.at += n;
        let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(text.to_vec()).map_err(|_| CdrError::NotUtf8 { field: what })
    }

    /// The end of the message: at most the padding a writer may add after the last field.
    pub fn end(&self) -> Result<(), CdrError> {
        match self.b.len().saturating_sub(self.at) {
            0..=3 => Ok(()),
            bytes => Err(CdrError::Trailing { bytes }),
        }
    }

    /// A `string[]`.
    pub fn strings(&mut self, what: &'static str) -> Result<Vec<String>, CdrError> {
        let n = self.u32(what)? as usize;
        // Each string takes at least its 4-byte length: a count beyond that is a damaged file.
        if n > self.b.len() / 4 {
            return Err(CdrError::Implausible {
                field: what,
                count: n,
                of: "strings",
            });
        }
        (0..n).map(|_| self.string(what)).collect()
    }
}

/// The first `n` values of a message's array, at most all of them: the counts come from another
/// process (a plant in any language), and a wrong one must not stop the recording.
pub fn first(values: &[f64], n: u32) -> &[f64] {
    &values[..(n as usize).min(values.len())]
}

// ------------------------------------------------------------------ evoloop's messages

/// A topic's message type: its ROS 2 name, definition and the definitions it depends on (in
/// rosbag2's form: each after the separator, headed `MSG: pkg/Type`).
#[derive(Clone, Copy)]
pub struct MessageType {
    /// The ROS 2 type name, e.g. `evoloop_msgs/msg/PlantState`.
    pub name: &'static str,
    /// The `.msg` definition, as `ros2 interface show` prints it.
    pub definition: &'static str,
    /// The definitions of the types it uses, each after the separator headed `MSG: pkg/Type`; empty
    /// when it uses none.
    pub dependencies: &'static str,
}

/// `evoloop_msgs/msg/PlantState`: a plant sample (`PlantState`), topic `state`.
pub const PLANT_STATE: MessageType = MessageType {
    name: "evoloop_msgs/msg/PlantState",
    definition: "\
# A plant sample: noisy outputs y, true positions, velocities and states, the applied input.
uint64 seq
# CLOCK_MONOTONIC ns when the plant produced the sample (the recording's log time)
uint64 stamp_ns
# simulated time, s
float64 t
uint32 flags
float64[] y
float64[] q_true
float64[] qd_true
float64[] x_true
float64[] u_applied
",
    dependencies: "",
};

/// `evoloop_msgs/msg/Command`: the controller's command (`Command`), topic `command`.
pub const COMMAND: MessageType = MessageType {
    name: "evoloop_msgs/msg/Command",
    definition: "\
# The controller's command on state `state_seq`, with the parameter version it ran.
uint64 cycle
uint64 state_seq
uint64 stamp_ns
uint64 param_version
float64[] u
",
    dependencies: "",
};

/// `evoloop_msgs/msg/Telemetry`: the controller's cycle (`Telemetry`), topic `telemetry`.
pub const TELEMETRY: MessageType = MessageType {
    name: "evoloop_msgs/msg/Telemetry",
    definition: "\
# The controller's cycle: timing (ns), tracking, the last parameter event and the law's values.
uint64 cycle
uint64 state_seq
float64 t
int64 lateness_ns
uint64 compute_ns
uint64 state_age_ns
float64 reference
float64 tracking_error
uint32 flags
float64[] u
uint64 param_version
uint64 param_event_version
uint32 param_code
uint32 param_index
uint64 overruns
uint64 missed
float64[] law
",
    dependencies: "",
};

/// `evoloop_msgs/msg/ParamSet`: a parameter set the controller received, with its cycle, topic
/// `params`.
pub const PARAM_SET: MessageType = MessageType {
    name: "evoloop_msgs/msg/ParamSet",
    definition: "\
# A parameter set the controller received, and the controller cycle that received it.
uint64 cycle
uint64 version
uint64 apply_at_seq
float64 expected_cost
uint64 until_seq
uint64 fallback_version
uint32 kind
float64[] values
",
    dependencies: "",
};

/// `evoloop_msgs/msg/ModelEstimate`: a model estimate the controller took, with its cycle, topic
/// `estimate`.
pub const MODEL_ESTIMATE: MessageType = MessageType {
    name: "evoloop_msgs/msg/ModelEstimate",
    definition: "\
# A model estimate the controller took, and the controller cycle that took it.
uint64 cycle
float64 t
float64 value
float64 std
uint64 last_version
uint64 apply_at_seq
",
    dependencies: "",
};

/// `evoloop_msgs/msg/LinearEstimate`: an estimated transfer function the controller took, with
/// its cycle, topic `estimate_linear`.
pub const LINEAR_ESTIMATE: MessageType = MessageType {
    name: "evoloop_msgs/msg/LinearEstimate",
    definition: "\
# An estimated transfer function num(s) / den(s) the controller took (descending powers, the
# first poles + 1 of each in use), and the controller cycle that took it.
uint64 cycle
float64 t
uint64 apply_at_seq
uint32 poles
float64[] num
float64[] den
",
    dependencies: "",
};

/// The standard `sensor_msgs/msg/JointState`: an arm's joints, topic `joint_states`.
pub const JOINT_STATE: MessageType = MessageType {
    name: "sensor_msgs/msg/JointState",
    definition: "\
std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
",
    dependencies: HEADER_DEPENDENCIES,
};

/// `std_msgs/Header` and `builtin_interfaces/Time`, which JointState's definition needs.
const HEADER_DEPENDENCIES: &str = "\
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

/// `std_msgs/msg/Float64MultiArray`: a vector of values for tools that know only the standard
/// messages (the command's u, the gains in service, a set of gains from a ROS 2 node).
pub const FLOAT64_MULTI_ARRAY: MessageType = MessageType {
    name: "std_msgs/msg/Float64MultiArray",
    definition: "\
# Please look at the MultiArrayLayout message definition for
# documentation on all multiarrays.

MultiArrayLayout  layout        # specification of data layout
float64[]         data          # array of data
",
    dependencies: "\
MSG: std_msgs/MultiArrayLayout
MultiArrayDimension[] dim # Array of dimension properties
uint32 data_offset        # padding bytes at front of data
================================================================================
MSG: std_msgs/MultiArrayDimension
string label   # label of given dimension
uint32 size    # size of given dimension (in type units)
uint32 stride  # stride of given dimension
",
};

/// `rcl_interfaces/msg/SetParametersResult`: the controller's answer to a set.
pub const SET_PARAMETERS_RESULT: MessageType = MessageType {
    name: "rcl_interfaces/msg/SetParametersResult",
    definition: "\
# A true value of the same index indicates that the parameter was set
# successfully. A false value indicates the change was rejected.
bool successful

# Reason why the setting was either successful or a failure. This should only be
# used for logging and user interfaces.
string reason
",
    dependencies: "",
};

impl MessageType {
    /// The schema MCAP and Foxglove's WebSocket protocol carry: the definition and its
    /// dependencies' (`ros2msg`).
    pub fn schema(&self) -> String {
        if self.dependencies.is_empty() {
            self.definition.to_string()
        } else {
            format!("{}{SEPARATOR}{}", self.definition, self.dependencies)
        }
    }

    /// Whether `schema` declares the same fields as this type (comments and blank lines aside):
    /// a recording's schema must, for its messages to be read as this type.
    pub fn same_fields(&self, schema: &str) -> bool {
        let fields = |text: &str| -> Vec<String> {
            text.lines()
                .map(|l| l.split('#').next().unwrap_or("").trim().to_string())
                .filter(|l| !l.is_empty())
                .collect()
        };
        fields(schema) == fields(&self.schema())
    }
}

/// The run's topics and their messages, in the order of run.mcap's channel ids (1..): the one
/// table the recorder, its reader and the live view share.
pub const TOPICS: [(&str, MessageType); 7] = [
    ("state", PLANT_STATE),
    ("command", COMMAND),
    ("telemetry", TELEMETRY),
    ("params", PARAM_SET),
    ("estimate", MODEL_ESTIMATE),
    ("joint_states", JOINT_STATE),
    ("estimate_linear", LINEAR_ESTIMATE),
];

/// A topic's message type.
pub fn message_type(topic: &str) -> Option<MessageType> {
    TOPICS.iter().find(|(t, _)| *t == topic).map(|(_, ty)| *ty)
}

/// Encode `s` into `buf` (cleared first) as a `PlantState` message, each array cut to its count.
pub fn encode_state(buf: &mut Vec<u8>, s: &PlantState) {
    let mut w = CdrWriter::new(buf);
    w.u64(s.seq);
    w.u64(s.stamp_ns);
    w.f64(s.t);
    w.u32(s.flags);
    w.f64s(first(&s.y, s.n_y));
    w.f64s(first(&s.q_true, s.n_q));
    w.f64s(first(&s.qd_true, s.n_q));
    w.f64s(first(&s.x_true, s.n_x));
    w.f64s(first(&s.u_applied, s.n_y.max(s.n_q)));
}

/// Decode a `PlantState` message, bit for bit.
///
/// # Errors
///
/// Not little-endian CDR, cut short, an array longer than the message's capacity, velocity or
/// input counts that do not match the joints and outputs, or bytes after the last field.
pub fn decode_state(b: &[u8]) -> Result<PlantState, CdrError> {
    let mut r = CdrReader::new(b)?;
    let mut s = PlantState {
        seq: r.u64("seq")?,
        stamp_ns: r.u64("stamp_ns")?,
        t: r.f64("t")?,
        flags: r.u32("flags")?,
        ..Default::default()
    };
    s.n_y = r.f64s("y", &mut s.y)?;
    s.n_q = r.f64s("q_true", &mut s.q_true)?;
    let qd = r.f64s("qd_true", &mut s.qd_true)?;
    s.n_x = r.f64s("x_true", &mut s.x_true)?;
    let applied = r.f64s("u_applied", &mut s.u_applied)?;
    if qd != s.n_q || applied != s.n_y.max(s.n_q) {
        return Err(CdrError::Inconsistent {
            velocities: qd,
            inputs: applied,
            joints: s.n_q,
            outputs: s.n_y,
        });
    }
    r.end()?;
    Ok(s)
}

/// Encode `c` into `buf` (cleared first) as a `Command` message, `u` cut to its count.
pub fn encode_command(buf: &mut Vec<u8>, c: &Command) {
    let mut w = CdrWriter::new(buf);
    w.u64(c.cycle);
    w.u64(c.state_seq);
    w.u64(c.stamp_ns);
    w.u64(c.param_version);
    w.f64s(first(&c.u, c.n_u));
}

/// Decode a `Command` message, bit for bit.
///
/// # Errors
///
/// Not little-endian CDR, cut short, more inputs than `Command` holds, or bytes after the last
/// field.
pub fn decode_command(b: &[u8]) -> Result<Command, CdrError> {
    let mut r = CdrReader::new(b)?;
    let mut c = Command {
        cycle: r.u64("cycle")?,
        state_seq: r.u64("state_seq")?,
        stamp_ns: r.u64("stamp_ns")?,
        param_version: r.u64("param_version")?,
        ..Default::default()
    };
    c.n_u = r.f64s("u", &mut c.u)?;
    r.end()?;
    Ok(c)
}

/// Encode `t` into `buf` (cleared first) as a `Telemetry` message, each array cut to its count.
pub fn encode_telemetry(buf: &mut Vec<u8>, t: &Telemetry) {
    let mut w = CdrWriter::new(buf);
    w.u64(t.cycle);
    w.u64(t.state_seq);
    w.f64(t.t);
    w.i64(t.lateness_ns);
    w.u64(t.compute_ns);
    w.u64(t.state_age_ns);
    w.f64(t.reference);
    w.f64(t.tracking_error);
    w.u32(t.flags);
    w.f64s(first(&t.u, t.n_u));
    w.u64(t.param_version);
    w.u64(t.param_event_version);
    w.u32(t.param_code);
    w.u32(t.param_index);
    w.u64(t.overruns);
    w.u64(t.missed);
    w.f64s(first(&t.law, t.n_law));
}

/// Decode a `Telemetry` message, bit for bit.
///
/// # Errors
///
/// Not little-endian CDR, cut short, an array longer than `Telemetry` holds, or bytes after the
/// last field.
pub fn decode_telemetry(b: &[u8]) -> Result<Telemetry, CdrError> {
    let mut r = CdrReader::new(b)?;
    let mut t = Telemetry {
        cycle: r.u64("cycle")?,
        state_seq: r.u64("state_seq")?,
        t: r.f64("t")?,
        lateness_ns: r.i64("lateness_ns")?,
        compute_ns: r.u64("compute_ns")?,
        state_age_ns: r.u64("state_age_ns")?,
        reference: r.f64("reference")?,
        tracking_error: r.f64("tracking_error")?,
        flags: r.u32("flags")?,
        ..Default::default()
    };
    t.n_u = r.f64s("u", &mut t.u)?;
    t.param_version = r.u64("param_version")?;
    t.param_event_version = r.u64("param_event_version")?;
    t.param_code = r.u32("param_code")?;
    t.param_index = r.u32("param_index")?;
    t.overruns = r.u64("overruns")?;
    t.missed = r.u64("missed")?;
    t.n_law = r.f64s("law", &mut t.law)?;
    r.end()?;
    Ok(t)
}

/// A set and the controller cycle that received it.
pub fn encode_params(buf: &mut Vec<u8>, p: &ParamSet, cycle: u64) {
    let mut w = CdrWriter::new(buf);
    w.u64(cycle);
    w.u64(p.version);
    w.u64(p.apply_at_seq);
    w.f64(p.expected_cost);
    w.u64(p.until_seq);
    w.u64(p.fallback_version);
    w.u32(p.kind);
    w.f64s(first(&p.values, p.n));
}

/// Decode a `ParamSet` message: the cycle that received the set, and the set.
///
/// # Errors
///
/// Not little-endian CDR, cut short, more values than `ParamSet` holds, or bytes after the last
/// field.
pub fn decode_params(b: &[u8]) -> Result<(u64, ParamSet), CdrError> {
    let mut r = CdrReader::new(b)?;
    let cycle = r.u64("cycle")?;
    let mut p = ParamSet {
        version: r.u64("version")?,
        apply_at_seq: r.u64("apply_at_seq")?,
        expected_cost: r.f64("expected_cost")?,
        until_seq: r.u64("until_seq")?,
        fallback_version: r.u64("fallback_version")?,
        kind: r.u32("kind")?,
        ..Default::default()
    };
    p.n = r.f64s("values", &mut p.values)?;
    r.end()?;
    Ok((cycle, p))
}

/// An estimate and the controller cycle that took it.
pub fn encode_estimate(buf: &mut Vec<u8>, e: &ModelEstimate, cycle: u64) {
    let mut w = CdrWriter::new(buf);
    w.u64(cycle);
    w.f64(e.t);
    w.f64(e.value);
    w.f64(e.std);
    w.u64(e.last_version);
    w.u64(e.apply_at_seq);
}

/// Decode a `ModelEstimate` message: the cycle that took the estimate, and the estimate.
///
/// # Errors
///
/// Not little-endian CDR, cut short, or bytes after the last field.
pub fn decode_estimate(b: &[u8]) -> Result<(u64, ModelEstimate), CdrError> {
    let mut r = CdrReader::new(b)?;
    let cycle = r.u64("cycle")?;
    let e = ModelEstimate {
        t: r.f64("t")?,
        value: r.f64("value")?,
        std: r.f64("std")?,
        last_version: r.u64("last_version")?,
        apply_at_seq: r.u64("apply_at_seq")?,
    };
    r.end()?;
    Ok((cycle, e))
}

/// A linear estimate and the controller cycle that took it (every coefficient, in use or not).
pub fn encode_linear_estimate(buf: &mut Vec<u8>, e: &LinearEstimate, cycle: u64) {
    let mut w = CdrWriter::new(buf);
    w.u64(cycle);
    w.f64(e.t);
    w.u64(e.apply_at_seq);
    w.u32(e.poles);
    w.f64s(&e.num);
    w.f64s(&e.den);
}

/// Decode a `LinearEstimate` message: the cycle that took the estimate, and the estimate.
///
/// # Errors
///
/// Not little-endian CDR, cut short, more coefficients than `LinearEstimate` holds, or bytes after
/// the last field.
pub fn decode_linear_estimate(b: &[u8]) -> Result<(u64, LinearEstimate), CdrError> {
    let mut r = CdrReader::new(b)?;
    let cycle = r.u64("cycle")?;
    let mut e = LinearEstimate {
        t: r.f64("t")?,
        apply_at_seq: r.u64("apply_at_seq")?,
        poles: r.u32("poles")?,
        ..Default::default()
    };
    r.f64s("num", &mut e.num)?;
    r.f64s("den", &mut e.den)?;
    r.end()?;
    Ok((cycle, e))
}

/// An arm's joints as `sensor_msgs/msg/JointState`: stamped with the sample's stamp, position
/// the measured joint angles y (empty if the plant measures fewer outputs than joints: each
/// array is either empty or one per name), velocity the joint velocities the controller reads,
/// effort the torques applied. `names` are the robot file's joint names, one per joint.
pub fn encode_joint_state(buf: &mut Vec<u8>, s: &PlantState, names: &[String]) {
    let n = (s.n_q as usize).min(names.len());
    let y = first(&s.y, s.n_y);
    let mut w = CdrWriter::new(buf);
    w.time(s.stamp_ns);
    w.string("");
    w.strings(names[..n].iter().map(String::as_str));
    w.f64s(if y.len() >= n { &y[..n] } else { &[] });
    w.f64s(first(&s.qd_true, n as u32));
    w.f64s(first(&s.u_applied, n as u32));
}

/// `values` as a `std_msgs/msg/Float64MultiArray` of one dimension labelled `label`.
pub fn encode_float64_multi_array(buf: &mut Vec<u8>, label: &str, values: &[f64]) {
    let mut w = CdrWriter::new(buf);
    w.u32(1);
    w.string(label);
    w.u32(values.len() as u32);
    w.u32(1);
    w.u32(0);
    w.f64s(values);
}

/// A `std_msgs/msg/Float64MultiArray`'s data (at most `max` values; the layout is read and
/// checked for size, not used: the data are taken as one vector).
pub fn decode_float64_multi_array(b: &[u8], max: usize) -> Result<Vec<f64>, CdrError> {
    let mut r = CdrReader::new(b)?;
    let dims = r.u32("layout.dim")?;
    // Each dimension takes at least 12 bytes.
    if dims as usize > b.len() / 12 {
        return Err(CdrError::Implausible {
            field: "layout.dim",
            count: dims as usize,
            of: "dimensions",
        });
    }
    for _ in 0..dims {
        r.string("layout.dim.label")?;
        r.u32("layout.dim.size")?;
        r.u32("layout.dim.stride")?;
    }
    r.u32("layout.data_offset")?;
    let data = r.f64_vec("data", max)?;
    r.end()?;
    Ok(data)
}

/// A `rcl_interfaces/msg/SetParametersResult`.
pub fn encode_set_parameters_result(buf: &mut Vec<u8>, successful: bool, reason: &str) {
    let mut w = CdrWriter::new(buf);
    w.bool(successful);
    w.string(reason);
}

/// Decode a `rcl_interfaces/msg/SetParametersResult`: whether the set succeeded, and the reason.
///
/// # Errors
///
/// Not little-endian CDR, cut short, a `successful` that is neither 0 nor 1, a reason that is not
/// UTF-8, or bytes after the last field.
pub fn decode_set_parameters_result(b: &[u8]) -> Result<(bool, String), CdrError> {
    let mut r = CdrReader::new(b)?;
    let ok = r.bool("successful")?;
    let reason = r.string("reason")?;
    r.end()?;
    Ok((ok, reason))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ros2/evoloop_msgs, the ROS 2 package a ROS 2 user builds to read evoloop's own messages
    /// (from run.mcap or `evoloop bridge --ros2`), has the same definitions, every one listed.
    #[test]
    fn the_ros_2_packages_definitions_are_these() {
        let pkg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../ros2/evoloop_msgs");
        let cmake = std::fs::read_to_string(pkg.join("CMakeLists.txt")).unwrap();
        let mut listed = 0;
        for (_, ty) in TOPICS.iter().filter(|(_, t)| t.name.starts_with(PACKAGE)) {
            let name = ty.name.rsplit('/').next().unwrap();
            let file = pkg.join("msg").join(format!("{name}.msg"));
            let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("{file:?}: {e}"));
            assert_eq!(text, ty.definition, "{file:?}");
            assert!(
                cmake.contains(&format!("\"msg/{name}.msg\"")),
                "{name} not in CMakeLists.txt"
            );
            listed += 1;
        }
        let files = std::fs::read_dir(pkg.join("msg")).unwrap().count();
        assert_eq!((listed, files), (6, 6));
    }

    /// Worked by hand from the CDR rules: header 00 01 00 00; a u32 at 0; a u64 aligned to 8
    /// (4 bytes of padding); an empty float64[] (its count only, no alignment); a float64[] of one
    /// (count at 20, aligned to 24); a string (length with NUL, bytes, NUL).
    #[test]
    fn the_layout_is_cdrs() {
        let mut buf = Vec::new();
        let mut w = CdrWriter::new(&mut buf);
        w.u32(7);
        w.u64(1);
        w.f64s(&[]);
        w.f64s(&[1.0]);
        w.string("ab");
        let mut expect = vec![0, 1, 0, 0, 7, 0, 0, 0, 0, 0, 0, 0];
        expect.extend(1u64.to_le_bytes());
        expect.extend([0, 0, 0, 0]); // the empty sequence's count, at 16
        expect.extend([1, 0, 0, 0]); // the count, at 20
        expect.extend(1.0f64.to_le_bytes()); // at 24
        expect.extend([3, 0, 0, 0, b'a', b'b', 0]);
        assert_eq!(buf, expect);
    }

    #[test]
    fn every_message_reads_back_bit_for_bit() {
        let mut s = PlantState {
            seq: 7,
            stamp_ns: u64::MAX,
            t: 0.1 + 0.2,
            flags: 3,
            n_y: 2,
            n_q: 2,
            n_x: 4,
            ..Default::default()
        };
        s.y[0] = f64::from_bits(0x7ff8_dead_beef_0001); // a NaN with a payload
        s.y[1] = -0.0;
        s.x_true[3] = f64::NEG_INFINITY;
        s.qd_true[1] = 1e-310;
        s.u_applied[0] = -2.5;
        let mut buf = Vec::new();
        encode_state(&mut buf, &s);
        let back = decode_state(&buf).unwrap();
        // PlantState has no padding: its bytes compare every field, NaN payloads included.
        assert_eq!(bytes_of(&back), bytes_of(&s));

        let mut t = Telemetry {
            cycle: 9,
            lateness_ns: -42,
            n_u: 1,
            n_law: 3,
            param_code: 5,
            ..Default::default()
        };
        t.law[2] = f64::NAN;
        t.u[0] = 4.0;
        encode_telemetry(&mut buf, &t);
        assert_eq!(bytes_of(&decode_telemetry(&buf).unwrap()), bytes_of(&t));

        let mut p = ParamSet {
            version: 3,
            n: 5,
            kind: 2,
            expected_cost: f64::INFINITY,
            ..Default::default()
        };
        p.values[4] = 1.25;
        encode_params(&mut buf, &p, 11);
        let (cycle, back) = decode_params(&buf).unwrap();
        assert_eq!((cycle, bytes_of(&back)), (11, bytes_of(&p)));

        let e = ModelEstimate {
            t: 1.0,
            value: 2.0,
            std: f64::NAN,
            last_version: 4,
            apply_at_seq: 5,
        };
        encode_estimate(&mut buf, &e, 12);
        let (cycle, back) = decode_estimate(&buf).unwrap();
        assert_eq!((cycle, bytes_of(&back)), (12, bytes_of(&e)));

        let mut l = LinearEstimate {
            t: 2.5,
            apply_at_seq: 9,
            poles: 2,
            ..Default::default()
        };
        l.num[2] = 40.0;
        l.den[..3].copy_from_slice(&[1.0, 20.0, -0.0]);
        encode_linear_estimate(&mut buf, &l, 13);
        let (cycle, back) = decode_linear_estimate(&buf).unwrap();
        assert_eq!((cycle, bytes_of(&back)), (13, bytes_of(&l)));

        let mut c = Command {
            cycle: 1,
            n_u: 2,
            ..Default::default()
        };
        c.u[1] = -1.0;
        encode_command(&mut buf, &c);
        assert_eq!(bytes_of(&decode_command(&buf).unwrap()), bytes_of(&c));
    }

    fn bytes_of<T: Copy>(v: &T) -> Vec<u8> {
        // SAFETY: the message types are plain `repr(C)` data without padding (evoloop-msg's own
        // layout tests); reading their bytes is reading their fields.
        unsafe { std::slice::from_raw_parts(v as *const T as *const u8, std::mem::size_of::<T>()) }
            .to_vec()
    }

    #[test]
    fn damaged_messages_are_refused_with_the_field() {
        let mut buf = Vec::new();
        let s = PlantState {
            n_y: 3,
            ..Default::default()
        };
        encode_state(&mut buf, &s);
        assert_eq!(decode_state(&buf[..3]), Err(CdrError::NoHeader));
        for cut in [10, buf.len() - 1] {
            let e = decode_state(&buf[..cut]).unwrap_err();
            assert!(matches!(e, CdrError::CutShort { .. }), "cut at {cut}: {e}");
        }
        let mut big = buf.clone();
        big[4 + 28..4 + 32].copy_from_slice(&1000u32.to_le_bytes()); // y's count, far too many
        let e = decode_state(&big).unwrap_err();
        assert_eq!(
            e,
            CdrError::TooLong {
                field: "y",
                len: 1000,
                max: evoloop_msg::MAX_JOINTS
            }
        );
        assert!(e.to_string().contains("`y`"), "{e}");
        let mut be = buf.clone();
        be[1] = 0; // CDR_BE
        let e = decode_state(&be).unwrap_err();
        assert_eq!(e, CdrError::Representation([0, 0]));
        assert!(e.to_string().contains("little-endian"));
    }

    /// Every decoder on damaged bytes (flipped, cut, lengthened, counts made huge) returns an
    /// error or a message, never a panic; and a message with bytes after it is refused.
    #[test]
    fn damaged_bytes_never_panic_a_decoder() {
        let mut s = PlantState {
            n_y: 3,
            n_q: 3,
            n_x: 6,
            ..Default::default()
        };
        s.x_true[5] = 1.5;
        let mut msgs = Vec::new();
        let mut buf = Vec::new();
        encode_state(&mut buf, &s);
        msgs.push(buf.clone());
        encode_telemetry(
            &mut buf,
            &Telemetry {
                n_u: 2,
                n_law: 4,
                ..Default::default()
            },
        );
        msgs.push(buf.clone());
        encode_params(
            &mut buf,
            &ParamSet {
                n: 7,
                ..Default::default()
            },
            3,
        );
        msgs.push(buf.clone());
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for case in 0..20_000 {
            let mut m = msgs[case % msgs.len()].clone();
            match next() % 3 {
                0 => {
                    let i = (next() as usize) % m.len();
                    m[i] ^= 1 << (next() % 8);
                }
                1 => m.truncate((next() as usize) % m.len()),
                _ => m.extend((0..next() % 9).map(|_| next() as u8)),
            }
            let _ = decode_state(&m);
            let _ = decode_telemetry(&m);
            let _ = decode_params(&m);
            let _ = decode_command(&m);
            let _ = decode_estimate(&m);
        }
        let mut long = msgs[0].clone();
        long.extend([0u8; 8]);
        let e = decode_state(&long).unwrap_err();
        assert_eq!(e, CdrError::Trailing { bytes: 8 });
        assert!(e.to_string().contains("after"));
    }

    #[test]
    fn a_schema_is_the_same_type_by_its_fields_not_its_comments() {
        let with_comments = format!("# a comment\n{}\n  # another\n", PLANT_STATE.definition);
        assert!(PLANT_STATE.same_fields(&with_comments));
        assert!(!PLANT_STATE.same_fields(COMMAND.definition));
        let renamed = PLANT_STATE.definition.replace("float64[] y", "float64[] z");
        assert!(!PLANT_STATE.same_fields(&renamed));
        assert!(JOINT_STATE.same_fields(&JOINT_STATE.schema()));
    }

    #[test]
    fn joint_states_carry_the_joints_only_and_the_header_schema() {
        let mut s = PlantState {
            stamp_ns: 3_500_000_001,
            n_y: 2,
            n_q: 2,
            ..Default::default()
        };
        s.y[..2].copy_from_slice(&[0.5, -0.5]);
        s.qd_true[1] = 2.0;
        s.u_applied[0] = 9.0;
        let names = vec!["shoulder".to_string(), "elbow".to_string()];
        let mut buf = Vec::new();
        encode_joint_state(&mut buf, &s, &names);
        let mut r = CdrReader::new(&buf).unwrap();
        assert_eq!(
            (r.i32("sec").unwrap(), r.u32("ns").unwrap()),
            (3, 500_000_001)
        );
        assert_eq!(r.string("frame_id").unwrap(), "");
        assert_eq!(r.strings("name").unwrap(), names);
        let mut v = [0.0; 8];
        assert_eq!(r.f64s("position", &mut v).unwrap(), 2);
        assert_eq!(v[..2], [0.5, -0.5]);
        assert_eq!(r.f64s("velocity", &mut v).unwrap(), 2);
        assert_eq!(v[1], 2.0);
        assert_eq!(r.f64s("effort", &mut v).unwrap(), 2);
        assert_eq!(v[0], 9.0);
        let schema = JOINT_STATE.schema();
        assert!(schema.contains("\nMSG: std_msgs/Header\n") && schema.contains("uint32 nanosec"));
        assert_eq!(PLANT_STATE.schema(), PLANT_STATE.definition);
    }
}
