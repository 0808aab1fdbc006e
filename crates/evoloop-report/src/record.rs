//! `run.mcap`: the run's messages as Foxglove and PlotJuggler open them (MCAP, one channel per
//! topic, ROS 2 messages in CDR with their `ros2msg` definitions, `super::ros2`; LZ4 chunks),
//! written by `report::mcap_file`, whose memory stays flat however long the run. An arm's
//! joints are also on `joint_states` as `sensor_msgs/msg/JointState`. Recordings written
//! before this encoding (up to e8a2f43, 2026-11-28) were JSON; `report::recording` reads both.
//!
//! The controller is the recorder: every topic passes through it. It sees each state it
//! controls on, the command and telemetry it sends, each parameter set it receives and each
//! model estimate it takes. The control cycle only copies the messages into bounded queues
//! allocated at the start (`std::sync::mpsc::sync_channel`: a lock-free `try_send` while the
//! receiver never blocks, and it never does: it polls and sleeps); a writer thread encodes and
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
use super::ros2;
use evoloop_msg::{Command, LinearEstimate, ModelEstimate, ParamSet, PlantState, Telemetry};
use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// The channels, in the order of their ids (1..): `ros2::TOPICS`.
pub use super::ros2::TOPICS;

/// One control cycle's messages.
#[derive(Clone, Copy)]
struct Cycle {
    state: PlantState,
    command: Command,
    telemetry: Telemetry,
}

/// Messages written per topic (in `TOPICS` order) and dropped, and the first write error.
/// controller.json files before `joint_states` have five counts; they read as they are.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize, PartialEq)]
pub struct Recorded {
    /// Messages written per topic, in `TOPICS` order.
    pub messages: Vec<u64>,
    /// What was not written: entries dropped from a full queue in realtime (a cycle's state,
    /// command and telemetry count as one), plus every message after a write error.
    pub dropped: u64,
    /// The first write error (with the file's path), or that the writer panicked; nothing was
    /// written after it.
    pub error: Option<String>,
}

impl Default for Recorded {
    fn default() -> Self {
        Self {
            messages: vec![0; TOPICS.len()],
            dropped: 0,
            error: None,
        }
    }
}

/// The recorder's end in the control cycle.
pub struct Recorder {
    cycles: SyncSender<Cycle>,
    params: SyncSender<(u64, u64, ParamSet)>,
    estimates: SyncSender<(u64, u64, ModelEstimate)>,
    linear: SyncSender<(u64, u64, LinearEstimate)>,
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

/// Why a recording could not be started.
#[derive(Debug)]
pub enum RecorderError {
    /// The file cannot be created (`evoloop_files::create`'s error, which names it).
    Create(std::io::Error),
    /// The file's header, schemas, channels or metadata cannot be written.
    Write {
        /// The recording.
        file: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
    /// The writer's thread cannot be started.
    Thread(std::io::Error),
}

impl std::fmt::Display for RecorderError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RecorderError::Create(e) => e.fmt(f),
            RecorderError::Write { file, source } => write!(f, "{}: {source}", file.display()),
            RecorderError::Thread(e) => write!(f, "cannot start the MCAP writer: {e}"),
        }
    }
}

impl std::error::Error for RecorderError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RecorderError::Create(e) => e.source(),
            RecorderError::Write { source, .. } | RecorderError::Thread(source) => Some(source),
        }
    }
}

impl Recorder {
    /// Create `path` and start the writer. `lockstep`: wait when a queue is full instead of
    /// dropping. `metadata` goes into the file's `evoloop` metadata record. `joints`: an arm's
    /// joint names (the robot file's), recorded on `joint_states`; none for other plants.
    pub fn start(
        path: &Path,
        lockstep: bool,
        metadata: BTreeMap<String, String>,
        avoid_cpu: Option<usize>,
        joints: Vec<String>,
    ) -> Result<Self, RecorderError> {
        let file = evoloop_files::create(path).map_err(RecorderError::Create)?;
        let at = |source| RecorderError::Write {
            file: path.to_path_buf(),
            source,
        };
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
        for (i, (topic, ty)) in TOPICS.iter().enumerate() {
            let schema = w
                .add_schema(ty.name, ros2::SCHEMA_ENCODING, ty.schema().as_bytes())
                .map_err(at)?;
            let id = w
                .add_channel(schema, topic, ros2::MESSAGE_ENCODING)
                .map_err(at)?;
            debug_assert_eq!(id as usize, i + 1, "channel ids are 1.. in TOPICS order");
        }
        w.write_metadata("evoloop", &metadata).map_err(at)?;
        let (cycles, rc) = sync_channel(CYCLES);
        let (params, rp) = sync_channel(SETS);
        let (estimates, re) = sync_channel(ESTIMATES);
        let (linear, rl) = sync_channel(ESTIMATES);
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
                write_all(
                    w,
                    &path,
                    &joints,
                    Queues {
                        cycles: rc,
                        params: rp,
                        estimates: re,
                        linear: rl,
                    },
                    &d,
                )
            })
            .map_err(RecorderError::Thread)?;
        Ok(Self {
            cycles,
            params,
            estimates,
            linear,
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

    /// Queue a parameter set the controller received, logged at the stamp and cycle number of the
    /// last `at_state`.
    pub fn params(&mut self, set: &ParamSet) {
        Self::put(
            &self.params,
            (self.stamp_ns, self.cycle, *set),
            self.wait_when_full,
            &mut self.dropped,
        );
    }

    /// Queue a model estimate the controller took, logged at the stamp and cycle number of the last
    /// `at_state`.
    pub fn estimate(&mut self, e: &ModelEstimate) {
        Self::put(
            &self.estimates,
            (self.stamp_ns, self.cycle, *e),
            self.wait_when_full,
            &mut self.dropped,
        );
    }

    /// Queue a linear-model estimate the controller took (topic `estimate_linear`), logged at the
    /// stamp and cycle number of the last `at_state`.
    pub fn linear_estimate(&mut self, e: &LinearEstimate) {
        Self::put(
            &self.linear,
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

/// The writer's ends of the recorder's queues.
struct Queues {
    cycles: Receiver<Cycle>,
    params: Receiver<(u64, u64, ParamSet)>,
    estimates: Receiver<(u64, u64, ModelEstimate)>,
    linear: Receiver<(u64, u64, LinearEstimate)>,
}

/// The writer thread: drain the queues, encode and write each message, sleep when idle, and
/// after `done` drain the rest and finish the file (summary, indexes).
fn write_all<W: std::io::Write>(
    mut w: McapWriter<W>,
    path: &Path,
    joints: &[String],
    q: Queues,
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
        while let Ok(c) = q.cycles.try_recv() {
            any = true;
            ros2::encode_state(&mut buf, &c.state);
            put(&mut w, &mut r, 0, c.state.stamp_ns, &buf);
            ros2::encode_command(&mut buf, &c.command);
            put(&mut w, &mut r, 1, c.command.stamp_ns, &buf);
            ros2::encode_telemetry(&mut buf, &c.telemetry);
            put(&mut w, &mut r, 2, c.command.stamp_ns, &buf);
            if !joints.is_empty() {
                ros2::encode_joint_state(&mut buf, &c.state, joints);
                put(&mut w, &mut r, 5, c.state.stamp_ns, &buf);
            }
        }
        while let Ok((stamp, cycle, p)) = q.params.try_recv() {
            any = true;
            ros2::encode_params(&mut buf, &p, cycle);
            put(&mut w, &mut r, 3, stamp, &buf);
        }
        while let Ok((stamp, cycle, e)) = q.estimates.try_recv() {
            any = true;
            ros2::encode_estimate(&mut buf, &e, cycle);
            put(&mut w, &mut r, 4, stamp, &buf);
        }
        while let Ok((stamp, cycle, e)) = q.linear.try_recv() {
            any = true;
            ros2::encode_linear_estimate(&mut buf, &e, cycle);
            put(&mut w, &mut r, 6, stamp, &buf);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// controller.json written before `joint_states` (five counts) still reads: `evoloop report`
    /// rebuilds the report of an older run directory.
    #[test]
    fn an_older_count_of_five_topics_reads() {
        let old = r#"{"messages":[12000,12000,12000,3,797],"dropped":0,"error":null}"#;
        let r: Recorded = serde_json::from_str(old).unwrap();
        assert_eq!(r.messages, [12000, 12000, 12000, 3, 797]);
        assert_eq!(Recorded::default().messages.len(), TOPICS.len());
    }
}
