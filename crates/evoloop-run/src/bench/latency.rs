//! `evoloop bench latency`: the round trip plant -> controller -> plant with the real message
//! types and the real control cycle, in two wake-up styles (busy polling; iceoryx2 event
//! wake-up), and in the same run a bare iceoryx2 ping-pong of the same payload size between two
//! processes as the reference. The peer side runs in a child process (`evoloop bench
//! latency-peer`), so every round trip crosses processes as in a real run.

use crate::ipc::{ipc_config, Ipc, IpcError, Topic, Wait};
use crate::law::cycle::ControlCycle;
use crate::law::{ParamBounds, StateFeedback};
use crate::msg::{Command, PlantState, Telemetry, STATE_FLAG_END};
use crate::reference::Reference;
use crate::report::plot::{xy_png, Style, XySeries};
use crate::report::Csv;
use crate::rt::now_ns;
use crate::rt::timing::Percentiles;
use evoloop_schemes::WriteError;
use iceoryx2::prelude::*;
use serde::Serialize;
use std::process::{Child, Command as Proc, Stdio};
use std::time::Duration;

/// One kind of round trip `bench latency` times: evoloop's messages and control law, or the
/// bare iceoryx2 ping-pong it is measured against, each busy-polled or event-woken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Variant {
    /// evoloop state/command with the control law, peers busy-poll.
    EvoloopBusy,
    /// evoloop state/command with the control law, peers block on iceoryx2 events.
    EvoloopEvent,
    /// Bare iceoryx2 byte-slice ping-pong, busy-poll (reference).
    BareBusy,
    /// Bare iceoryx2 byte-slice ping-pong with event wake-ups (reference).
    BareEvent,
}

impl Variant {
    /// Every variant, each reference before the variant it is the reference of: what `bench
    /// latency` measures, in this order.
    pub const ALL: [Variant; 4] = [
        Variant::BareBusy,
        Variant::EvoloopBusy,
        Variant::BareEvent,
        Variant::EvoloopEvent,
    ];

    /// The variant's name on the command line (`--variant evoloop-busy`).
    pub fn arg(self) -> &'static str {
        match self {
            Variant::EvoloopBusy => "evoloop-busy",
            Variant::EvoloopEvent => "evoloop-event",
            Variant::BareBusy => "bare-busy",
            Variant::BareEvent => "bare-event",
        }
    }

    /// The variant's snake_case name: its key in latency.json and its row in latency.csv.
    pub fn name(self) -> &'static str {
        match self {
            Variant::EvoloopBusy => "evoloop_busy",
            Variant::EvoloopEvent => "evoloop_event",
            Variant::BareBusy => "bare_busy",
            Variant::BareEvent => "bare_event",
        }
    }
    fn busy(self) -> bool {
        matches!(self, Variant::EvoloopBusy | Variant::BareBusy)
    }
}

/// One variant's round trips after the warm-up: their percentiles (ns) and, for an evoloop
/// variant, its ratios to the bare reference of the same wake-up style.
#[derive(Debug, Clone, Serialize)]
pub struct VariantResult {
    /// The variant measured.
    pub variant: Variant,
    /// Round trips timed (the `WARMUP` ones before them are not).
    pub samples: u64,
    /// The fastest round trip, ns.
    pub min_ns: i64,
    /// The median round trip, ns (from a histogram of 3 significant digits, as `p90_ns` to
    /// `p99_9_ns`).
    pub p50_ns: i64,
    /// The 90th percentile round trip, ns.
    pub p90_ns: i64,
    /// The 99th percentile round trip, ns.
    pub p99_ns: i64,
    /// The 99.9th percentile round trip, ns.
    pub p99_9_ns: i64,
    /// The 99.99th percentile round trip, ns, read exactly off the sorted samples.
    pub p99_99_ns: i64,
    /// The slowest round trip, ns.
    pub max_ns: i64,
    /// Against the bare ping-pong of the same wake-up style, same run.
    pub ratio_p50: Option<f64>,
    /// `p99_9_ns` against the same reference; `None`, as `ratio_p50`, for a bare variant or
    /// when its reference was not measured.
    pub ratio_p99_9: Option<f64>,
    /// Each round's median round trip, ns, in the order the rounds ran (every variant runs once
    /// a round, right after or before the others: `measure_variants`).
    pub p50_rounds_ns: Vec<i64>,
    /// Each round's p50 over its reference's in the same round; empty where `ratio_p50` is
    /// `None`. Their spread says how far the machine's drift moves the ratio.
    pub ratio_p50_rounds: Vec<f64>,
}

impl VariantResult {
    /// The round-trip figures in table and CSV order, with their CSV names.
    pub const FIGURES: [&'static str; 7] = [
        "min_ns",
        "p50_ns",
        "p90_ns",
        "p99_ns",
        "p99_9_ns",
        "p99_99_ns",
        "max_ns",
    ];
    /// The round-trip figures, ns, in the order of `FIGURES`.
    pub fn figures(&self) -> [i64; 7] {
        [
            self.min_ns,
            self.p50_ns,
            self.p90_ns,
            self.p99_ns,
            self.p99_9_ns,
            self.p99_99_ns,
            self.max_ns,
        ]
    }
}

const WARMUP: usize = 2_000;

/// Why `measure` gave no figures.
#[derive(Debug)]
pub enum LatencyError {
    /// The peer process could not be started.
    Peer(std::io::Error),
    /// iceoryx2 refused, or the peer did not answer in time.
    Ipc(IpcError),
}

impl std::fmt::Display for LatencyError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LatencyError::Peer(e) => write!(f, "cannot start the peer process: {e}"),
            LatencyError::Ipc(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for LatencyError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LatencyError::Peer(e) => Some(e),
            // Reads as the iceoryx2 error: its source is that error's.
            LatencyError::Ipc(e) => e.source(),
        }
    }
}

fn spawn_peer(v: Variant, prefix: &str, run_id: &str, payload: usize) -> std::io::Result<Child> {
    let exe = std::env::current_exe()?;
    Proc::new(exe)
        .args(["bench", "latency-peer", "--variant"])
        .arg(v.arg())
        .args(["--prefix", prefix, "--run-id", run_id, "--payload"])
        .arg(payload.to_string())
        .stdout(Stdio::null())
        .spawn()
}

/// What `measure` found: the JSON report, one result per variant and the raw round trips.
pub struct Measured {
    /// latency.json's content: the payload size, the samples per variant, the rounds they were
    /// taken in and each variant's result under its name.
    pub report: serde_json::Value,
    /// One result per variant measured, in the order measured.
    pub results: Vec<VariantResult>,
    /// Each variant's round trips in ns, in the order taken (latency_cdf.png plots them).
    pub raw: Vec<(Variant, Vec<i64>)>,
}

/// Measure every variant, `samples` round trips each in `rounds` interleaved rounds, with a
/// `payload`-byte bare message; `progress` is told each variant as it starts, with its round.
pub fn measure(
    samples: usize,
    rounds: usize,
    payload: usize,
    progress: &dyn Fn(Variant, usize),
) -> Result<Measured, LatencyError> {
    measure_variants(&Variant::ALL, samples, rounds, payload, progress)
}

/// `measure` for some of the variants (a ratio needs its reference among them), in `rounds`
/// interleaved rounds: each round times every variant once, in the order given, with its share
/// of the `samples` round trips (each after its own warm-up and its own peer process), so a
/// variant and its reference see the same drift of a shared machine; the percentiles pool the
/// rounds. `progress` hears each variant as it starts, with its round.
pub fn measure_variants(
    variants: &[Variant],
    samples: usize,
    rounds: usize,
    payload: usize,
    progress: &dyn Fn(Variant, usize),
) -> Result<Measured, LatencyError> {
    let prefix = crate::ipc::DEFAULT_PREFIX.to_string();
    let rounds = rounds.clamp(1, samples.max(1));
    let mut raw: Vec<(Variant, Vec<i64>)> = variants.iter().map(|&v| (v, Vec::new())).collect();
    let mut p50_rounds: Vec<Vec<i64>> = vec![Vec::new(); variants.len()];
    for round in 0..rounds {
        // The first `samples % rounds` rounds take one more, so the rounds add up to `samples`.
        let share = samples / rounds + usize::from(round < samples % rounds);
        for (i, &v) in variants.iter().enumerate() {
            progress(v, round);
            let s = measure_one(v, &prefix, round, share, payload)?;
            p50_rounds[i].push(Percentiles::from_samples(s.iter().copied()).p50_ns);
            raw[i].1.extend(s);
        }
    }
    let mut results: Vec<VariantResult> = raw
        .iter()
        .zip(p50_rounds)
        .map(|((v, s), p50_rounds_ns)| {
            let p = Percentiles::from_samples(s.iter().copied());
            let mut sorted = s.clone();
            sorted.sort_unstable();
            let p9999 =
                sorted[((sorted.len() as f64 * 0.9999).ceil() as usize).min(sorted.len()) - 1];
            VariantResult {
                variant: *v,
                samples: p.count,
                min_ns: p.min_ns,
                p50_ns: p.p50_ns,
                p90_ns: p.p90_ns,
                p99_ns: p.p99_ns,
                p99_9_ns: p.p99_9_ns,
                p99_99_ns: p9999,
                max_ns: p.max_ns,
                ratio_p50: None,
                ratio_p99_9: None,
                p50_rounds_ns,
                ratio_p50_rounds: Vec::new(),
            }
        })
        .collect();
    for i in 0..results.len() {
        let reference = match results[i].variant {
            Variant::EvoloopBusy => Variant::BareBusy,
            Variant::EvoloopEvent => Variant::BareEvent,
            _ => continue,
        };
        if let Some(r) = results.iter().find(|r| r.variant == reference).cloned() {
            let ratio = |hot: i64, reference: i64| hot as f64 / reference.max(1) as f64;
            let hot = &mut results[i];
            hot.ratio_p50 = Some(ratio(hot.p50_ns, r.p50_ns));
            hot.ratio_p99_9 = Some(ratio(hot.p99_9_ns, r.p99_9_ns));
            hot.ratio_p50_rounds = (hot.p50_rounds_ns.iter().zip(&r.p50_rounds_ns))
                .map(|(&h, &b)| ratio(h, b))
                .collect();
        }
    }
    let report = serde_json::json!({
        "payload_bytes": payload,
        "samples": samples,
        "rounds": rounds,
        "variants": results.iter().map(|r| (r.variant.name().to_string(), serde_json::to_value(r).unwrap_or_default())).collect::<serde_json::Map<_, _>>(),
    });
    Ok(Measured {
        report,
        results,
        raw,
    })
}

/// `samples` timed round trips of variant `v` (after `WARMUP` untimed ones) against a peer
/// process of its own, started for this round and reaped after it.
fn measure_one(
    v: Variant,
    prefix: &str,
    round: usize,
    samples: usize,
    payload: usize,
) -> Result<Vec<i64>, LatencyError> {
    let run_id = format!("{}-{}-{round}", std::process::id(), v.name());
    let mut child = spawn_peer(v, prefix, &run_id, payload).map_err(LatencyError::Peer)?;
    let r = if matches!(v, Variant::BareBusy | Variant::BareEvent) {
        ping_bare(v, prefix, &run_id, payload, samples)
    } else {
        ping_evoloop(v, prefix, &run_id, samples)
    };
    match r {
        Ok(s) => {
            let _ = child.wait();
            Ok(s)
        }
        Err(e) => {
            // Killed before it is reaped: a peer still waiting for its partner would otherwise
            // hold the benchmark until its own timeout.
            let _ = child.kill();
            let _ = child.wait();
            Err(LatencyError::Ipc(e))
        }
    }
}

/// latency.json, latency.csv and latency_cdf.png in `dir`.
pub fn write_out(
    dir: &std::path::Path,
    report: &serde_json::Value,
    results: &[VariantResult],
    raw: &[(Variant, Vec<i64>)],
) -> Result<(), WriteError> {
    crate::report::write_json(dir, "latency.json", report)
        .map_err(WriteError::file(&dir.join("latency.json")))?;
    let mut csv = Csv::new(std::iter::once("variant").chain(VariantResult::FIGURES));
    for r in results {
        csv.row().put(r.variant.name()).all(r.figures());
    }
    let file = dir.join("latency.csv");
    csv.write(&file).map_err(WriteError::file(&file))?;
    // CDF on a log time axis: x = log10(RTT / ns), y = fraction of round trips at or below.
    let curves: Vec<(String, Vec<f64>, Vec<f64>)> = raw
        .iter()
        .map(|(v, s)| {
            let mut s = s.clone();
            s.sort_unstable();
            let n = s.len();
            let step = (n / 2000).max(1);
            let idx: Vec<usize> = (0..n).step_by(step).chain(std::iter::once(n - 1)).collect();
            (
                v.name().to_string(),
                idx.iter().map(|&i| (s[i].max(1) as f64).log10()).collect(),
                idx.iter().map(|&i| (i + 1) as f64 / n as f64).collect(),
            )
        })
        .collect();
    let series = XySeries::from_curves(&curves, Style::Line);
    xy_png(
        &dir.join("latency_cdf.png"),
        "Round-trip latency CDF: evoloop vs bare iceoryx2, busy-poll and event wake-up",
        "log10(round trip / ns)",
        "fraction of round trips",
        &series,
        None,
        Some((0.0, 1.0)),
    )
    .map_err(WriteError::Figure)
}

/// Wait (set-up only, before any timing) until `connected` holds, for up to 10 s.
fn wait_connected(mut connected: impl FnMut() -> bool) -> Result<(), IpcError> {
    let t0 = std::time::Instant::now();
    while !connected() {
        if t0.elapsed() > Duration::from_secs(10) {
            return Err(IpcError::reason(
                "bench",
                "the peer process did not connect within 10 s",
            ));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Ok(())
}

fn ping_evoloop(
    v: Variant,
    prefix: &str,
    run_id: &str,
    samples: usize,
) -> Result<Vec<i64>, IpcError> {
    let ipc = Ipc::new("bench-plant", run_id, prefix)?;
    let busy = v.busy();
    let cmd = ipc.subscriber::<Command>(Topic::Command, 4, !busy)?;
    let state = ipc.publisher::<PlantState>(Topic::State, !busy)?;
    wait_connected(|| state.subscribers() >= 1 && cmd.publishers() >= 1)?;
    let mut msg = PlantState {
        n_x: 4,
        n_y: 1,
        ..Default::default()
    };
    let mut out = Vec::with_capacity(samples);
    let timeout = Duration::from_secs(5);
    for k in 0..(WARMUP + samples) as u64 {
        msg.seq = k;
        msg.x_true[0] = (k % 100) as f64 * 1e-3;
        msg.y[0] = msg.x_true[0];
        let t0 = now_ns();
        msg.stamp_ns = t0;
        state.send(&msg)?;
        // Busy polling has no timed wait of its own: the same deadline, read off the clock.
        let deadline = t0 + timeout.as_nanos() as u64;
        loop {
            let got = if busy {
                cmd.next()?.map(Wait::Got).unwrap_or(Wait::TimedOut)
            } else {
                cmd.wait_next(Duration::ZERO, timeout)?
            };
            match got {
                Wait::Got(c) if c.state_seq == k => break,
                Wait::Got(_) => {}
                Wait::TimedOut if busy && now_ns() < deadline => std::hint::spin_loop(),
                Wait::TimedOut => {
                    return Err(IpcError::reason("bench", "peer did not answer within 5 s"))
                }
            }
        }
        if k as usize >= WARMUP {
            out.push(now_ns() as i64 - t0 as i64);
        }
    }
    msg.flags = STATE_FLAG_END;
    state.send(&msg)?;
    Ok(out)
}

/// The peer side of a variant (the child process of `measure`).
pub fn peer(variant: Variant, prefix: &str, run_id: &str, payload: usize) -> Result<(), IpcError> {
    match variant {
        Variant::EvoloopBusy | Variant::EvoloopEvent => pong_evoloop(variant, prefix, run_id),
        Variant::BareBusy | Variant::BareEvent => pong_bare(variant, prefix, run_id, payload),
    }
}

/// How long a peer waits for the next message before it gives up: busy polling has no timed
/// wait of its own, and a lost message or a peer that is gone must not leave both processes
/// spinning a core for ever (a test run once hung so).
const PEER_TIMEOUT_NS: u64 = 10_000_000_000;

fn pong_evoloop(v: Variant, prefix: &str, run_id: &str) -> Result<(), IpcError> {
    let ipc = Ipc::new("bench-controller", run_id, prefix)?;
    let busy = v.busy();
    let cmd = ipc.publisher::<Command>(Topic::Command, !busy)?;
    let state = ipc.subscriber::<PlantState>(Topic::State, 4, !busy)?;
    let mut cycle = ControlCycle::new(
        Box::new(StateFeedback::new(
            &[18.49, 19.04, 47.27, 7.30, -10.54],
            0.001,
            Some(100.0),
        )),
        Reference::Step {
            amplitude: 1.0,
            start: 0.0,
        },
        ParamBounds {
            lower: vec![-100.0; 5],
            upper: vec![100.0; 5],
        },
    );
    let mut tel = Telemetry::default();
    let mut last = now_ns();
    loop {
        let s = if busy {
            match state.next()? {
                Some(s) => {
                    last = now_ns();
                    s
                }
                None if now_ns() - last > PEER_TIMEOUT_NS => {
                    return Err(IpcError::reason("bench", "no state within 10 s"));
                }
                None => {
                    std::hint::spin_loop();
                    continue;
                }
            }
        } else {
            match state.wait_next(Duration::ZERO, Duration::from_secs(10))? {
                Wait::Got(s) => s,
                Wait::TimedOut => return Err(IpcError::reason("bench", "no state within 10 s")),
            }
        };
        if s.flags & STATE_FLAG_END != 0 {
            return Ok(());
        }
        cycle.step(&s, &mut tel);
        cmd.send(&Command {
            cycle: tel.cycle,
            state_seq: s.seq,
            n_u: 1,
            u: cycle.u,
            ..Default::default()
        })?;
    }
}

type SlicePub = iceoryx2::port::publisher::Publisher<ipc::Service, [u8], ()>;
type SliceSub = iceoryx2::port::subscriber::Subscriber<ipc::Service, [u8], ()>;

/// Bare iceoryx2 ports: a byte-slice publisher on `out`, a subscriber on `inp`, and for the
/// event variant a notifier/listener pair on the same names.
struct Bare {
    _node: Node<ipc::Service>,
    out_svc:
        iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [u8], ()>,
    in_svc: iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [u8], ()>,
    publisher: SlicePub,
    subscriber: SliceSub,
    notifier: Option<iceoryx2::port::notifier::Notifier<ipc::Service>>,
    listener: Option<iceoryx2::port::listener::Listener<ipc::Service>>,
}

fn bare(
    prefix: &str,
    run_id: &str,
    out: &str,
    inp: &str,
    payload: usize,
    events: bool,
) -> Result<Bare, IpcError> {
    set_log_level(LogLevel::Error);
    let cfg = ipc_config(prefix)?;
    let node =
        crate::ipc::create_node::<ipc::Service>(NodeBuilder::new().config(&cfg), prefix, "node")?;
    let name = |t: &str| {
        ServiceName::new(&format!("bench/{run_id}/{t}")).map_err(|e| IpcError::new("name", e))
    };
    let svc = |t: &str| {
        node.service_builder(&name(t)?)
            .publish_subscribe::<[u8]>()
            .open_or_create()
            .map_err(|e| IpcError::new("service", e))
    };
    let out_svc = svc(out)?;
    let in_svc = svc(inp)?;
    let publisher = out_svc
        .publisher_builder()
        .initial_max_slice_len(payload)
        .create()
        .map_err(|e| IpcError::new("publisher", e))?;
    let subscriber = in_svc
        .subscriber_builder()
        .create()
        .map_err(|e| IpcError::new("subscriber", e))?;
    let (notifier, listener) = if events {
        let ev = |t: &str| {
            node.service_builder(&name(t)?)
                .event()
                .open_or_create()
                .map_err(|e| IpcError::new("event", e))
        };
        (
            Some(
                ev(out)?
                    .notifier_builder()
                    .create()
                    .map_err(|e| IpcError::new("notifier", e))?,
            ),
            Some(
                ev(inp)?
                    .listener_builder()
                    .create()
                    .map_err(|e| IpcError::new("listener", e))?,
            ),
        )
    } else {
        (None, None)
    };
    Ok(Bare {
        _node: node,
        out_svc,
        in_svc,
        publisher,
        subscriber,
        notifier,
        listener,
    })
}

impl Bare {
    /// Both directions have their peer port.
    fn connected(&self) -> bool {
        self.out_svc.dynamic_config().number_of_subscribers() >= 1
            && self.in_svc.dynamic_config().number_of_publishers() >= 1
    }

    fn send(&self, fill: u8, payload: usize) -> Result<(), IpcError> {
        let s = self
            .publisher
            .loan_slice_uninit(payload)
            .map_err(|e| IpcError::new("loan", e))?;
        let s = s.write_from_fn(|i| if i == 0 { fill } else { i as u8 });
        s.send().map_err(|e| IpcError::new("send", e))?;
        if let Some(n) = &self.notifier {
            n.notify().map_err(|e| IpcError::new("notify", e))?;
        }
        Ok(())
    }
    /// Wait for the next message, up to `PEER_TIMEOUT_NS`; returns its first byte.
    fn recv(&self) -> Result<u8, IpcError> {
        let deadline = now_ns() + PEER_TIMEOUT_NS;
        loop {
            if let Some(s) = self
                .subscriber
                .receive()
                .map_err(|e| IpcError::new("receive", e))?
            {
                return Ok(s.payload().first().copied().unwrap_or(0));
            }
            if now_ns() > deadline {
                return Err(IpcError::reason(
                    "bench",
                    "no message from the peer within 10 s",
                ));
            }
            match &self.listener {
                Some(l) => {
                    l.timed_wait(|_| {}, Duration::from_secs(5))
                        .map_err(|e| IpcError::new("wait", e))?;
                }
                None => std::hint::spin_loop(),
            }
        }
    }
}

fn ping_bare(
    v: Variant,
    prefix: &str,
    run_id: &str,
    payload: usize,
    samples: usize,
) -> Result<Vec<i64>, IpcError> {
    let b = bare(prefix, run_id, "ping", "pong", payload, !v.busy())?;
    wait_connected(|| b.connected())?;
    let mut out = Vec::with_capacity(samples);
    for k in 0..WARMUP + samples {
        let t0 = now_ns();
        b.send(0, payload)?;
        b.recv()?;
        if k >= WARMUP {
            out.push(now_ns() as i64 - t0 as i64);
        }
    }
    b.send(1, payload)?;
    Ok(out)
}

fn pong_bare(v: Variant, prefix: &str, run_id: &str, payload: usize) -> Result<(), IpcError> {
    let b = bare(prefix, run_id, "pong", "ping", payload, !v.busy())?;
    loop {
        if b.recv()? == 1 {
            return Ok(());
        }
        b.send(0, payload)?;
    }
}
