//! `run.mcap`: the run's messages as Foxglove and PlotJuggler open them (MCAP, one channel per
//! topic, JSON messages with a JSON Schema each, LZ4 chunks), written by `report::mcap_file`,
//! whose memory stays flat however long the run.
//!
//! The controller is the recorder: every topic passes through it. It sees each state it
//! controls on, the command and telemetry it sends, each parameter set it receives and each
//! model estimate it takes. The control cycle only copies the messages into bounded queues
//! allocated at the start (`std::sync::mpsc::sync_channel`: a lock-free `try_send` while the
//! receiver never blocks, and it never does: it polls and sleeps); a writer thread formats and
//! writes them. In lockstep a full queue makes the cycle wait (nothing is lost, the run is only
//! slower); in realtime the message is dropped and counted (`mcap.dropped` in controller.json), as
//! the CSV log does.
//!
//! Log time is the sample's stamp (CLOCK_MONOTONIC ns, `stamp_ns` of the state, the command's
//! own for commands and telemetry); parameter sets and estimates carry no stamp of their own and
//! are logged at the stamp of the state of the cycle that received them, with that cycle's
//! number (`cycle`, as in its command) in the message. In realtime the states
//! are those the controller used (the latest at each cycle), which is what a replay into a
//! controller needs.

use super::mcap_file::McapWriter;
use evoloop_msg::{Command, ModelEstimate, ParamSet, PlantState, Telemetry};
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// The channels, in the order of their ids (1..).
pub const TOPICS: [&str; 5] = ["state", "command", "telemetry", "params", "estimate"];

/// One control cycle's messages.
#[derive(Clone, Copy)]
struct Cycle {
    state: PlantState,
    command: Command,
    telemetry: Telemetry,
}

/// Messages written per topic (in `TOPICS` order) and dropped, and the first write error.
#[derive(Debug, Default, Clone, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct Recorded {
    pub messages: [u64; 5],
    pub dropped: u64,
    pub error: Option<String>,
}

/// The recorder's end in the control cycle.
pub struct Recorder {
    cycles: SyncSender<Cycle>,
    params: SyncSender<(u64, u64, ParamSet)>,
    estimates: SyncSender<(u64, u64, ModelEstimate)>,
    /// The stamp params and estimates are logged at (the current cycle's state's) and the
    /// cycle's number, which they carry: a state used by two cycles (realtime, the plant late)
    /// has one stamp, and a replay needs to know which of the two took the set.
    stamp_ns: u64,
    cycle: u64,
    wait_when_full: bool,
    dropped: u64,
    done: Arc<AtomicBool>,
    writer: Option<JoinHandle<Recorded>>,
}

/// Cycles the queue holds (about 1 KB each): 0.8 s at 10 kHz.
const CYCLES: usize = 8192;
/// Parameter sets (8 KB each) and estimates the queues hold.
const SETS: usize = 32;
const ESTIMATES: usize = 256;
/// Bytes per MCAP chunk and per write to the file.
const CHUNK: usize = 64 << 10;
/// How long the writer sleeps when it finds every queue empty.
const IDLE: Duration = Duration::from_millis(2);

impl Recorder {
    /// Create `path` and start the writer. `lockstep`: wait when a queue is full instead of
    /// dropping. `metadata` goes into the file's `evoloop` metadata record.
    pub fn start(
        path: &Path,
        lockstep: bool,
        metadata: BTreeMap<String, String>,
        avoid_cpu: Option<usize>,
    ) -> Result<Self, String> {
        let file = evoloop_files::create(path).map_err(|e| e.to_string())?;
        let at = |e: std::io::Error| format!("{}: {e}", path.display());
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        // Small chunks and buffer: each write(2) copies at most ~64 KiB into the page cache.
        // A non-preemptible copy of a whole default chunk (~768 KiB) on the controller's CPU
        // delayed its wake-ups at 10 kHz (measured: misses 163-230 per 50 000 cycles against
        // 18-36 without recording, 3 of 4 pairs).
        let mut w = McapWriter::new(
            BufWriter::with_capacity(CHUNK, file),
            "",
            concat!("evoloop ", env!("CARGO_PKG_VERSION")),
            CHUNK,
            dir,
        )
        .map_err(at)?;
        for (i, topic) in TOPICS.iter().enumerate() {
            let schema = w
                .add_schema(
                    &format!("evoloop.{topic}"),
                    "jsonschema",
                    schema(topic).as_bytes(),
                )
                .map_err(at)?;
            let id = w.add_channel(schema, topic, "json").map_err(at)?;
            debug_assert_eq!(id as usize, i + 1, "channel ids are 1.. in TOPICS order");
        }
        w.write_metadata("evoloop", &metadata).map_err(at)?;
        let (cycles, rc) = sync_channel(CYCLES);
        let (params, rp) = sync_channel(SETS);
        let (estimates, re) = sync_channel(ESTIMATES);
        let done = Arc::new(AtomicBool::new(false));
        let d = done.clone();
        let path: PathBuf = path.to_path_buf();
        let writer = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || {
                // Background work: nice 10, below the loop's other threads (as the optimiser),
                // so formatting and disk writes yield to them even without SCHED_FIFO.
                // SAFETY: plain syscalls on this thread's own id.
                unsafe {
                    libc::setpriority(libc::PRIO_PROCESS, libc::gettid() as libc::id_t, 10);
                }
                // Off the controller's CPU: its write(2)s copy into the page cache without
                // preemption points, which delayed the 10 kHz loop's wake-ups there.
                if let Some(cpu) = avoid_cpu {
                    avoid(cpu);
                }
                write_all(w, &path, rc, rp, re, &d)
            })
            .map_err(|e| format!("cannot start the MCAP writer: {e}"))?;
        Ok(Self {
            cycles,
            params,
            estimates,
            stamp_ns: 0,
            cycle: 0,
            wait_when_full: lockstep,
            dropped: 0,
            done,
            writer: Some(writer),
        })
    }

    /// Queue `v` on `tx`: wait while full in lockstep, drop and count in realtime. No allocation.
    fn put<T>(tx: &SyncSender<T>, mut v: T, wait: bool, dropped: &mut u64) {
        loop {
            match tx.try_send(v) {
                Ok(()) => return,
                Err(TrySendError::Full(back)) if wait => {
                    v = back;
                    std::thread::yield_now();
                }
                // Full in realtime, or the writer is gone (its error is in its report).
                Err(_) => {
                    *dropped += 1;
                    return;
                }
            }
        }
    }

    /// The state cycle `cycle` starts from: later sets and estimates of the cycle are logged at
    /// its stamp, with the cycle's number.
    pub fn at_state(&mut self, state: &PlantState, cycle: u64) {
        self.stamp_ns = state.stamp_ns;
        self.cycle = cycle;
    }

    pub fn params(&mut self, set: &ParamSet) {
        Self::put(
            &self.params,
            (self.stamp_ns, self.cycle, *set),
            self.wait_when_full,
            &mut self.dropped,
        );
    }

    pub fn estimate(&mut self, e: &ModelEstimate) {
        Self::put(
            &self.estimates,
            (self.stamp_ns, self.cycle, *e),
            self.wait_when_full,
            &mut self.dropped,
        );
    }

    /// The cycle's state, command and telemetry.
    pub fn cycle(&mut self, state: &PlantState, command: &Command, telemetry: &Telemetry) {
        let c = Cycle {
            state: *state,
            command: *command,
            telemetry: *telemetry,
        };
        Self::put(&self.cycles, c, self.wait_when_full, &mut self.dropped);
    }

    /// Write what is queued, close the file and report.
    pub fn finish(mut self) -> Recorded {
        self.done.store(true, Ordering::Release);
        let mut r = match self.writer.take().map(JoinHandle::join) {
            Some(Ok(r)) => r,
            _ => Recorded {
                error: Some("the MCAP writer panicked".into()),
                ..Recorded::default()
            },
        };
        r.dropped += self.dropped;
        r
    }
}

impl Drop for Recorder {
    /// Dropped without `finish` (an error ended the loop): still close the file properly.
    fn drop(&mut self) {
        self.done.store(true, Ordering::Release);
        if let Some(w) = self.writer.take() {
            let _ = w.join();
        }
    }
}

/// Take `cpu` out of this thread's affinity (kept when it is the only CPU allowed).
fn avoid(cpu: usize) {
    // SAFETY: cpu_set_t is plain data; the calls read and write it for this thread only.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        let size = std::mem::size_of::<libc::cpu_set_t>();
        if libc::sched_getaffinity(0, size, &mut set) != 0 || cpu >= libc::CPU_SETSIZE as usize {
            return;
        }
        if libc::CPU_ISSET(cpu, &set) && libc::CPU_COUNT(&set) > 1 {
            libc::CPU_CLR(cpu, &mut set);
            libc::sched_setaffinity(0, size, &set);
        }
    }
}

/// The writer thread: drain the queues, format and write each message, sleep when idle, and
/// after `done` drain the rest and finish the file (summary, indexes).
fn write_all<W: std::io::Write>(
    mut w: McapWriter<W>,
    path: &Path,
    cycles: Receiver<Cycle>,
    params: Receiver<(u64, u64, ParamSet)>,
    estimates: Receiver<(u64, u64, ModelEstimate)>,
    done: &AtomicBool,
) -> Recorded {
    let mut r = Recorded::default();
    let mut buf = Vec::with_capacity(16 << 10);
    let put = |w: &mut McapWriter<W>, r: &mut Recorded, ch: usize, stamp: u64, buf: &[u8]| {
        if r.error.is_some() {
            r.dropped += 1;
            return;
        }
        match w.write_message(ch as u16 + 1, r.messages[ch] as u32, stamp, stamp, buf) {
            Ok(()) => r.messages[ch] += 1,
            Err(e) => r.error = Some(format!("{}: {e}", path.display())),
        }
    };
    loop {
        let finishing = done.load(Ordering::Acquire);
        let mut any = false;
        while let Ok(c) = cycles.try_recv() {
            any = true;
            json_state(&mut buf, &c.state);
            put(&mut w, &mut r, 0, c.state.stamp_ns, &buf);
            json_command(&mut buf, &c.command);
            put(&mut w, &mut r, 1, c.command.stamp_ns, &buf);
            json_telemetry(&mut buf, &c.telemetry);
            put(&mut w, &mut r, 2, c.command.stamp_ns, &buf);
        }
        while let Ok((stamp, cycle, p)) = params.try_recv() {
            any = true;
            json_params(&mut buf, &p, cycle);
            put(&mut w, &mut r, 3, stamp, &buf);
        }
        while let Ok((stamp, cycle, e)) = estimates.try_recv() {
            any = true;
            json_estimate(&mut buf, &e, cycle);
            put(&mut w, &mut r, 4, stamp, &buf);
        }
        if finishing && !any {
            break;
        }
        if !any {
            std::thread::sleep(IDLE);
        }
    }
    if r.error.is_none() {
        if let Err(e) = w.finish() {
            r.error = Some(format!("{}: {e}", path.display()));
        }
    }
    r
}

/// A JSON number (the shortest text that reads back to the same f64, by ryu, as serde_json
/// writes it); NaN and infinities (not JSON) as null.
fn num(buf: &mut Vec<u8>, x: f64) {
    if x.is_finite() {
        buf.extend_from_slice(ryu::Buffer::new().format_finite(x).as_bytes());
    } else {
        buf.extend_from_slice(b"null");
    }
}

fn key(buf: &mut Vec<u8>, name: &str) {
    buf.push(b'"');
    buf.extend_from_slice(name.as_bytes());
    buf.extend_from_slice(b"\":");
}

fn field(buf: &mut Vec<u8>, name: &str, x: f64) {
    key(buf, name);
    num(buf, x);
    buf.push(b',');
}

fn int(buf: &mut Vec<u8>, name: &str, x: impl itoa::Integer) {
    key(buf, name);
    buf.extend_from_slice(itoa::Buffer::new().format(x).as_bytes());
    buf.push(b',');
}

fn array(buf: &mut Vec<u8>, name: &str, xs: &[f64]) {
    key(buf, name);
    buf.push(b'[');
    for (i, x) in xs.iter().enumerate() {
        if i > 0 {
            buf.push(b',');
        }
        num(buf, *x);
    }
    buf.extend_from_slice(b"],");
}

/// Close an object: the last field's comma becomes the closing brace.
fn end(buf: &mut Vec<u8>) {
    if buf.last() == Some(&b',') {
        buf.pop();
    }
    buf.push(b'}');
}

/// The first `n` values of a message's array, at most all of them: the counts come from another
/// process (a plant in any language), and a wrong one must not stop the recording.
fn first(values: &[f64], n: u32) -> &[f64] {
    &values[..(n as usize).min(values.len())]
}

fn json_state(buf: &mut Vec<u8>, s: &PlantState) {
    buf.clear();
    buf.push(b'{');
    int(buf, "seq", s.seq);
    int(buf, "stamp_ns", s.stamp_ns);
    field(buf, "t", s.t);
    int(buf, "flags", s.flags);
    array(buf, "y", first(&s.y, s.n_y));
    array(buf, "q_true", first(&s.q_true, s.n_q));
    array(buf, "qd_true", first(&s.qd_true, s.n_q));
    array(buf, "x_true", first(&s.x_true, s.n_x));
    array(buf, "u_applied", first(&s.u_applied, s.n_y.max(s.n_q)));
    end(buf);
}

fn json_command(buf: &mut Vec<u8>, c: &Command) {
    buf.clear();
    buf.push(b'{');
    int(buf, "cycle", c.cycle);
    int(buf, "state_seq", c.state_seq);
    int(buf, "stamp_ns", c.stamp_ns);
    int(buf, "param_version", c.param_version);
    array(buf, "u", first(&c.u, c.n_u));
    end(buf);
}

fn json_telemetry(buf: &mut Vec<u8>, t: &Telemetry) {
    buf.clear();
    buf.push(b'{');
    int(buf, "cycle", t.cycle);
    int(buf, "state_seq", t.state_seq);
    field(buf, "t", t.t);
    int(buf, "lateness_ns", t.lateness_ns);
    int(buf, "compute_ns", t.compute_ns);
    int(buf, "state_age_ns", t.state_age_ns);
    field(buf, "reference", t.reference);
    field(buf, "tracking_error", t.tracking_error);
    int(buf, "flags", t.flags);
    array(buf, "u", first(&t.u, t.n_u));
    int(buf, "param_version", t.param_version);
    int(buf, "param_event_version", t.param_event_version);
    int(buf, "param_code", t.param_code);
    int(buf, "param_index", t.param_index);
    int(buf, "overruns", t.overruns);
    int(buf, "missed", t.missed);
    array(buf, "law", first(&t.law, t.n_law));
    end(buf);
}

/// A set and the controller cycle that received it.
fn json_params(buf: &mut Vec<u8>, p: &ParamSet, cycle: u64) {
    buf.clear();
    buf.push(b'{');
    int(buf, "cycle", cycle);
    int(buf, "version", p.version);
    int(buf, "apply_at_seq", p.apply_at_seq);
    field(buf, "expected_cost", p.expected_cost);
    int(buf, "until_seq", p.until_seq);
    int(buf, "fallback_version", p.fallback_version);
    int(buf, "kind", p.kind);
    array(
        buf,
        "values",
        &p.values[..(p.n as usize).min(p.values.len())],
    );
    end(buf);
}

/// An estimate and the controller cycle that took it.
fn json_estimate(buf: &mut Vec<u8>, e: &ModelEstimate, cycle: u64) {
    buf.clear();
    buf.push(b'{');
    int(buf, "cycle", cycle);
    field(buf, "t", e.t);
    field(buf, "value", e.value);
    field(buf, "std", e.std);
    int(buf, "last_version", e.last_version);
    int(buf, "apply_at_seq", e.apply_at_seq);
    end(buf);
}

/// The JSON Schema of a topic's messages (what Foxglove uses to list the fields), read off the
/// topic's own writer: one default message is written and each field's value typed, so the
/// schema cannot drift from what is written.
fn schema(topic: &str) -> String {
    let mut buf = Vec::new();
    let title = match topic {
        "state" => {
            json_state(&mut buf, &PlantState::default());
            "Plant state sample (noisy outputs y, true positions, velocities and states)"
        }
        "command" => {
            json_command(&mut buf, &Command::default());
            "Controller command"
        }
        "telemetry" => {
            json_telemetry(&mut buf, &Telemetry::default());
            "Controller telemetry (timing, tracking, parameter events)"
        }
        "params" => {
            json_params(&mut buf, &ParamSet::default(), 0);
            "Parameter set received by the controller"
        }
        _ => {
            json_estimate(&mut buf, &ModelEstimate::default(), 0);
            "Model estimate taken by the controller"
        }
    };
    let sample: serde_json::Map<String, serde_json::Value> =
        serde_json::from_slice(&buf).expect("the writers write JSON objects");
    // Floats may be written as null (NaN, infinities); integers never are.
    let number = serde_json::json!({"type": ["number", "null"]});
    let properties: serde_json::Map<String, serde_json::Value> = sample
        .iter()
        .map(|(k, v)| {
            let ty = match v {
                serde_json::Value::Array(_) => {
                    serde_json::json!({"type": "array", "items": number})
                }
                serde_json::Value::Number(n) if n.is_f64() => number.clone(),
                _ => serde_json::json!({"type": "integer"}),
            };
            (k.clone(), ty)
        })
        .collect();
    serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "type": "object",
        "properties": properties,
    })
    .to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_are_json_with_only_the_valid_entries_and_schemas_parse() {
        let mut s = PlantState {
            seq: 7,
            stamp_ns: 123,
            t: 0.007,
            n_y: 2,
            n_q: 2,
            n_x: 4,
            ..Default::default()
        };
        s.y[0] = f64::NAN;
        s.y[1] = 1.5;
        let mut buf = Vec::new();
        json_state(&mut buf, &s);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["seq"], 7);
        assert_eq!(v["y"], serde_json::json!([null, 1.5]));
        assert_eq!(v["x_true"].as_array().unwrap().len(), 4);
        for topic in TOPICS {
            let sch: serde_json::Value = serde_json::from_str(&schema(topic)).unwrap();
            assert_eq!(sch["type"], "object", "{topic}");
        }
        let sch: serde_json::Value = serde_json::from_str(&schema("state")).unwrap();
        let p = &sch["properties"];
        assert_eq!(
            (&p["seq"]["type"], &p["y"]["type"]),
            (&"integer".into(), &"array".into())
        );
        assert_eq!(p["t"]["type"], serde_json::json!(["number", "null"]));
        assert_eq!(p.as_object().unwrap().len(), v.as_object().unwrap().len());
    }

    /// A plant in another language may send any count: one past the array records the whole
    /// array (it used to panic the writer thread and lose run.mcap while the loop ran on).
    #[test]
    fn a_count_beyond_the_array_records_the_array_not_a_panic() {
        let s = PlantState {
            n_y: 1000,
            n_q: u32::MAX,
            n_x: 33,
            ..Default::default()
        };
        let mut buf = Vec::new();
        json_state(&mut buf, &s);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["y"].as_array().unwrap().len(), evoloop_msg::MAX_JOINTS);
        assert_eq!(v["x_true"].as_array().unwrap().len(), 32);
        assert_eq!(
            v["u_applied"].as_array().unwrap().len(),
            evoloop_msg::MAX_JOINTS
        );
        let c = Command {
            n_u: 9,
            ..Default::default()
        };
        json_command(&mut buf, &c);
        let v: serde_json::Value = serde_json::from_slice(&buf).unwrap();
        assert_eq!(v["u"].as_array().unwrap().len(), evoloop_msg::MAX_JOINTS);
    }
}
