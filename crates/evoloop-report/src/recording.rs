//! Reading `run.mcap` back (the writer is `super::record`): the run's metadata and its messages
//! as the typed messages the processes exchanged, for `evoloop replay`.
//!
//! A channel's message encoding says how its messages are read. `cdr` (since 2026-11-28): the
//! ROS 2 messages of `super::ros2`, every f64 its own 8 bytes; the schema's name is checked, so a
//! file of another program's messages on a topic of the same name is refused, not misread.
//! `json` (recordings before): the flat JSON objects the writer then wrote (integers, numbers or
//! null, arrays of numbers), read by a small reader of exactly that form rather than
//! serde_json: numbers go through Rust's `str::parse`, which is correctly rounded, so every
//! recorded number comes back bit for bit; null (how NaN and infinities were written) reads as
//! NaN.

use super::ros2;
use evoloop_msg::{Command, LinearEstimate, ModelEstimate, ParamSet, PlantState};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A recorded run: the `evoloop` metadata record and the messages of each topic in the order
/// they were written. Parameter sets and estimates carry when the controller took them.
#[derive(Debug, Default)]
pub struct Recording {
    /// The file's `evoloop` metadata record: scenario, config, mode, seed, period_s, log_time.
    pub metadata: BTreeMap<String, String>,
    /// The plant states the controller controlled on, in recorded order.
    pub states: Vec<PlantState>,
    /// The commands the controller sent, in recorded order.
    pub commands: Vec<Command>,
    /// The parameter sets the controller received, each with when it took it.
    pub params: Vec<(Received, ParamSet)>,
    /// The model estimates the controller took, each with when it took it.
    pub estimates: Vec<(Received, ModelEstimate)>,
    /// Estimated transfer functions (the general indirect scheme; none before 2026-11-28).
    pub linear_estimates: Vec<(Received, LinearEstimate)>,
}

/// When the controller took a set or an estimate: the stamp of the state of that cycle, and
/// the cycle's number (recordings before the number was written have none).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Received {
    /// The stamp of the cycle's state (CLOCK_MONOTONIC, ns): the message's log time.
    pub stamp_ns: u64,
    /// The cycle's number, as in its command; `None` in the first JSON recordings, which lack it.
    pub cycle: Option<u64>,
}

/// Refuse a damaged chunk before mcap reads it: one declaring more uncompressed bytes than any
/// compression of its size could give (LZ4 expands at most 255 to 1), or whose records do not
/// match its CRC. mcap 0.26 reserves what a chunk or a record inside it declares before it
/// checks anything, so a corrupt size (a flipped bit in a damaged file) aborted the process on
/// an allocation of exabytes instead of returning an error; with the CRC checked here first,
/// the sizes it reads inside a chunk are the ones written. Walks the file's top-level records
/// (opcode u8, length u64 LE, body); one running past the end is left to the reader, which
/// calls the file cut short.
fn check_chunks(bytes: &[u8]) -> Result<(), (usize, String)> {
    use super::mcap_file::{op, MAGIC};
    let mut at = MAGIC.len();
    while let Some(len) = le_u64(bytes, at + 1) {
        let body = at + 9;
        let Some(end) = usize::try_from(len).ok().and_then(|l| body.checked_add(l)) else {
            return Ok(());
        };
        if end > bytes.len() {
            return Ok(());
        }
        if bytes[at] == op::CHUNK {
            check_chunk(&bytes[body..end], len).map_err(|e| (at, e))?;
        }
        at = end;
    }
    Ok(())
}

/// One chunk's body: start and end times (u64 each), uncompressed size (u64), CRC (u32, 0 =
/// none), compression (u32 length + name), records length (u64), records.
fn check_chunk(b: &[u8], len: u64) -> Result<(), String> {
    use std::io::Read;
    let short = || "is cut short".to_string();
    let declared = le_u64(b, 16).ok_or_else(short)?;
    if declared > 256 * len + 4096 {
        return Err(format!("declares {declared} uncompressed bytes from {len}"));
    }
    let crc = u32::from_le_bytes(b.get(24..28).ok_or_else(short)?.try_into().unwrap());
    let name_len = u32::from_le_bytes(b.get(28..32).ok_or_else(short)?.try_into().unwrap());
    let name_end = 32 + name_len as usize;
    let name = b.get(32..name_end).ok_or_else(short)?;
    let n = le_u64(b, name_end).ok_or_else(short)?;
    let records = usize::try_from(n)
        .ok()
        .and_then(|n| b.get(name_end + 8..name_end + 8 + n))
        .ok_or_else(short)?;
    if crc == 0 {
        return Ok(());
    }
    let mut plain = Vec::with_capacity(declared as usize);
    match name {
        b"" => plain.extend_from_slice(records),
        n if n == crate::mcap_file::COMPRESSION.as_bytes() => {
            lz4::Decoder::new(records)
                .and_then(|d| d.take(declared).read_to_end(&mut plain))
                .map_err(|e| format!("does not decompress ({e})"))?;
        }
        // Not one evoloop writes: mcap checks it as it reads.
        _ => return Ok(()),
    }
    if plain.len() as u64 != declared || crc32fast::hash(&plain) != crc {
        return Err("does not match its CRC".into());
    }
    Ok(())
}

/// Why a recording cannot be read; each names the file.
#[derive(Debug)]
pub enum RecordingError {
    /// The file cannot be read.
    Read {
        /// The recording.
        file: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// The MCAP reader refuses it: not an MCAP file, cut short, a record it cannot parse.
    Mcap {
        /// The recording.
        file: PathBuf,
        /// The reader's reason.
        source: mcap::McapError,
    },
    /// An MCAP file but not a run of evoloop's, or one cut short before its summary.
    NotEvoloop {
        /// The recording.
        file: PathBuf,
        /// What it lacks.
        missing: &'static str,
    },
    /// A chunk whose declared size or CRC says the file is damaged.
    Damaged {
        /// The recording.
        file: PathBuf,
        /// The chunk's first byte in the file.
        at: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// A channel a replay reads whose schema is not evoloop's message.
    Schema {
        /// The recording.
        file: PathBuf,
        /// The channel's topic.
        topic: String,
        /// The schema found against the one expected.
        reason: String,
    },
    /// A message that does not decode as its channel's encoding says.
    Message {
        /// The recording.
        file: PathBuf,
        /// The channel's topic.
        topic: String,
        /// The message's sequence number.
        sequence: u32,
        /// Why it does not decode.
        reason: String,
    },
}

impl RecordingError {
    /// The recording the error is about.
    pub fn file(&self) -> &Path {
        match self {
            RecordingError::Read { file, .. }
            | RecordingError::Mcap { file, .. }
            | RecordingError::NotEvoloop { file, .. }
            | RecordingError::Damaged { file, .. }
            | RecordingError::Schema { file, .. }
            | RecordingError::Message { file, .. } => file,
        }
    }
}

impl std::fmt::Display for RecordingError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}: ", self.file().display())?;
        match self {
            RecordingError::Read { source, .. } => source.fmt(f),
            RecordingError::Mcap { source, .. } => source.fmt(f),
            RecordingError::NotEvoloop { missing, .. } => f.write_str(missing),
            RecordingError::Damaged { at, reason, .. } => {
                write!(
                    f,
                    "the chunk at byte {at} {reason}: the recording is damaged"
                )
            }
            RecordingError::Schema { topic, reason, .. } => write!(f, "channel {topic}: {reason}"),
            RecordingError::Message {
                topic,
                sequence,
                reason,
                ..
            } => write!(f, "{topic} message {sequence}: {reason}"),
        }
    }
}

impl std::error::Error for RecordingError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RecordingError::Read { source, .. } => Some(source),
            RecordingError::Mcap { source, .. } => Some(source),
            _ => None,
        }
    }
}

fn le_u64(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}

impl Recording {
    /// Read `path`; the error names the file and what is wrong.
    pub fn read(path: &Path) -> Result<Self, RecordingError> {
        let file = || path.to_path_buf();
        let mcap = |source| RecordingError::Mcap {
            file: file(),
            source,
        };
        let not_evoloop = |missing| RecordingError::NotEvoloop {
            file: file(),
            missing,
        };
        let bytes = std::fs::read(path).map_err(|source| RecordingError::Read {
            file: file(),
            source,
        })?;
        let mut r = Recording::default();
        let summary = mcap::read::Summary::read(&bytes)
            .map_err(mcap)?
            .ok_or_else(|| not_evoloop("no summary section (was the recording cut short?)"))?;
        for index in &summary.metadata_indexes {
            if index.name == "evoloop" {
                r.metadata = mcap::read::metadata(&bytes, index).map_err(mcap)?.metadata;
            }
        }
        if r.metadata.is_empty() {
            return Err(not_evoloop(
                "no `evoloop` metadata record: not a run.mcap of evoloop",
            ));
        }
        // Every chunk's CRC is checked here, once: mcap's own check (ValidateChunkCrcs) would
        // decompress each chunk a second time.
        check_chunks(&bytes).map_err(|(at, reason)| RecordingError::Damaged {
            file: file(),
            at,
            reason,
        })?;
        for ch in summary.channels.values() {
            check_schema(ch).map_err(|reason| RecordingError::Schema {
                file: file(),
                topic: ch.topic.clone(),
                reason,
            })?;
        }
        for msg in mcap::MessageStream::new(&bytes).map_err(mcap)? {
            let msg = msg.map_err(mcap)?;
            r.add(&msg).map_err(|reason| RecordingError::Message {
                file: file(),
                topic: msg.channel.topic.clone(),
                sequence: msg.sequence,
                reason,
            })?;
        }
        Ok(r)
    }

    /// The metadata value of `key` (e.g. "config", "seed"), if the recording has it.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata.get(key).map(String::as_str)
    }
}

/// A CDR channel of a topic a replay reads must carry evoloop's message: its name, encoding and
/// fields (comments aside), so a file of another program's messages on a topic of the same name
/// is refused, not misread.
fn check_schema(ch: &mcap::Channel) -> Result<(), String> {
    if ch.message_encoding != ros2::MESSAGE_ENCODING || !READ.contains(&ch.topic.as_str()) {
        return Ok(());
    }
    let ty = ros2::message_type(&ch.topic).expect("READ's topics are in ros2::TOPICS");
    match ch.schema.as_deref() {
        Some(s) if s.name == ty.name && s.encoding == ros2::SCHEMA_ENCODING => {
            if ty.same_fields(std::str::from_utf8(&s.data).unwrap_or("")) {
                Ok(())
            } else {
                Err(format!(
                    "schema {}'s fields are not evoloop's (a newer or another program's file?)",
                    ty.name
                ))
            }
        }
        s => Err(format!(
            "schema {}, expected {} ({})",
            s.map_or("none", |s| s.name.as_str()),
            ty.name,
            ros2::SCHEMA_ENCODING
        )),
    }
}

/// The topics a replay reads. Telemetry is the controller's own output (a replay makes it
/// again) and joint states repeat the state: neither is read.
const READ: [&str; 5] = ["state", "command", "params", "estimate", "estimate_linear"];

impl Recording {
    /// Add one recorded message, decoded by its channel's message encoding.
    fn add(&mut self, msg: &mcap::Message) -> Result<(), String> {
        let topic = msg.channel.topic.as_str();
        if !READ.contains(&topic) {
            return Ok(());
        }
        let received = |cycle| Received {
            stamp_ns: msg.log_time,
            cycle,
        };
        match msg.channel.message_encoding.as_str() {
            ros2::MESSAGE_ENCODING => {
                let b = &msg.data;
                let cdr = |e: ros2::CdrError| format!("a `{topic}` message: {e}");
                match topic {
                    "state" => self.states.push(ros2::decode_state(b).map_err(cdr)?),
                    "command" => self.commands.push(ros2::decode_command(b).map_err(cdr)?),
                    "params" => {
                        let (cycle, p) = ros2::decode_params(b).map_err(cdr)?;
                        self.params.push((received(Some(cycle)), p));
                    }
                    "estimate" => {
                        let (cycle, e) = ros2::decode_estimate(b).map_err(cdr)?;
                        self.estimates.push((received(Some(cycle)), e));
                    }
                    _ => {
                        let (cycle, e) = ros2::decode_linear_estimate(b).map_err(cdr)?;
                        self.linear_estimates.push((received(Some(cycle)), e));
                    }
                }
            }
            "json" => {
                let text = std::str::from_utf8(&msg.data).map_err(|e| e.to_string())?;
                let f = Fields::parse(text)?;
                // The first JSON recordings did not name the cycle.
                let cycle = f.int("cycle").ok();
                match topic {
                    "state" => self.states.push(f.state()?),
                    "command" => self.commands.push(f.command()?),
                    "params" => self.params.push((received(cycle), f.params()?)),
                    "estimate" => self.estimates.push((received(cycle), f.estimate()?)),
                    // JSON recordings never had it.
                    _ => {}
                }
            }
            other => {
                return Err(format!(
                    "message encoding `{other}` (evoloop writes cdr, once json)"
                ))
            }
        }
        Ok(())
    }
}

/// One flat JSON object: each key's value as text (one token, or an array's tokens), read as
/// an integer or a number when asked for.
struct Fields<'a>(BTreeMap<&'a str, Vec<&'a str>>);

impl<'a> Fields<'a> {
    fn parse(text: &'a str) -> Result<Self, String> {
        let body = text
            .trim()
            .strip_prefix('{')
            .and_then(|s| s.strip_suffix('}'))
            .ok_or("not a JSON object")?;
        let mut fields = BTreeMap::new();
        let mut rest = body.trim_start();
        while !rest.is_empty() {
            let after = rest.strip_prefix('"').ok_or("expected a key")?;
            let close = after.find('"').ok_or("unterminated key")?;
            let key = &after[..close];
            let after = after[close + 1..]
                .trim_start()
                .strip_prefix(':')
                .ok_or("expected ':'")?
                .trim_start();
            let (tokens, tail) = if let Some(a) = after.strip_prefix('[') {
                let end = a.find(']').ok_or("unterminated array")?;
                let items = a[..end].trim();
                let tokens = if items.is_empty() {
                    Vec::new()
                } else {
                    items.split(',').map(str::trim).collect()
                };
                (tokens, &a[end + 1..])
            } else {
                let end = after.find(',').unwrap_or(after.len());
                (vec![after[..end].trim()], &after[end..])
            };
            fields.insert(key, tokens);
            let tail = tail.trim_start();
            rest = match tail.strip_prefix(',') {
                Some(t) => t.trim_start(),
                None if tail.is_empty() => tail,
                None => return Err(format!("unexpected {tail:.20}")),
            };
        }
        Ok(Self(fields))
    }

    /// The single token of `key`.
    fn token(&self, key: &str) -> Result<&'a str, String> {
        match self.0.get(key).map(Vec::as_slice) {
            Some([t]) => Ok(t),
            _ => Err(format!("no single value `{key}`")),
        }
    }

    fn int(&self, key: &str) -> Result<u64, String> {
        let t = self.token(key)?;
        t.parse()
            .map_err(|_| format!("`{key}`: `{t:.24}` is not an integer"))
    }

    fn num(&self, key: &str) -> Result<f64, String> {
        number(self.token(key)?)
    }

    /// Array `key` into `out`; its length.
    fn array(&self, key: &str, out: &mut [f64]) -> Result<usize, String> {
        let v = self.0.get(key).ok_or_else(|| format!("no array `{key}`"))?;
        if v.len() > out.len() {
            return Err(format!(
                "`{key}` has {} values, at most {}",
                v.len(),
                out.len()
            ));
        }
        for (slot, t) in out.iter_mut().zip(v) {
            *slot = number(t)?;
        }
        Ok(v.len())
    }

    fn state(&self) -> Result<PlantState, String> {
        let mut s = PlantState {
            seq: self.int("seq")?,
            stamp_ns: self.int("stamp_ns")?,
            t: self.num("t")?,
            flags: self.int("flags")? as u32,
            ..Default::default()
        };
        s.n_y = self.array("y", &mut s.y)? as u32;
        s.n_q = self.array("q_true", &mut s.q_true)? as u32;
        self.array("qd_true", &mut s.qd_true)?;
        s.n_x = self.array("x_true", &mut s.x_true)? as u32;
        self.array("u_applied", &mut s.u_applied)?;
        Ok(s)
    }

    fn command(&self) -> Result<Command, String> {
        let mut c = Command {
            cycle: self.int("cycle")?,
            state_seq: self.int("state_seq")?,
            stamp_ns: self.int("stamp_ns")?,
            param_version: self.int("param_version")?,
            ..Default::default()
        };
        c.n_u = self.array("u", &mut c.u)? as u32;
        Ok(c)
    }

    fn params(&self) -> Result<ParamSet, String> {
        let mut p = ParamSet {
            version: self.int("version")?,
            apply_at_seq: self.int("apply_at_seq")?,
            expected_cost: self.num("expected_cost")?,
            until_seq: self.int("until_seq")?,
            fallback_version: self.int("fallback_version")?,
            kind: self.int("kind")? as u32,
            ..Default::default()
        };
        p.n = self.array("values", &mut p.values)? as u32;
        Ok(p)
    }

    fn estimate(&self) -> Result<ModelEstimate, String> {
        Ok(ModelEstimate {
            t: self.num("t")?,
            value: self.num("value")?,
            std: self.num("std")?,
            last_version: self.int("last_version")?,
            apply_at_seq: self.int("apply_at_seq")?,
        })
    }
}

/// A JSON number (exactly, by `str::parse`) or null (NaN).
fn number(token: &str) -> Result<f64, String> {
    if token == "null" {
        return Ok(f64::NAN);
    }
    token
        .parse::<f64>()
        .map_err(|_| format!("`{token:.24}` is not a number"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_objects_read_back_exactly() {
        let x = 0.1f64 + 0.2; // 0.30000000000000004: the shortest text must round-trip
        let text = format!(
            r#"{{"seq":7,"stamp_ns":18446744073709551615,"t":{x},"flags":0,"y":[{x},-1e-300],"q_true":[],"qd_true":[],"x_true":[1,2.5],"u_applied":[null]}}"#
        );
        let s = Fields::parse(&text).unwrap().state().unwrap();
        assert_eq!((s.seq, s.stamp_ns), (7, u64::MAX));
        assert_eq!(s.t.to_bits(), x.to_bits());
        assert_eq!(s.n_y, 2);
        assert_eq!(s.y[1], -1e-300);
        assert_eq!((s.n_q, s.n_x), (0, 2));
        assert!(s.u_applied[0].is_nan());
        for bad in ["", "{", r#"{"seq":}"#, r#"{"y":[1,}"#, r#"{"seq":1 "t":2}"#] {
            assert!(
                Fields::parse(bad).and_then(|f| f.state()).is_err(),
                "{bad:?}"
            );
        }
    }
}
