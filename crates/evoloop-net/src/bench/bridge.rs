//! `evoloop bench bridge`: how long a parameter set takes to be in service, seen by its sender,
//! over the local path (iceoryx2 in, the controller's telemetry back on iceoryx2) and through a
//! bridge on loopback (Zenoh in through the bridge, the telemetry back through it), on one
//! realtime run.
//!
//! A round trip is the time from the send to the first telemetry whose version in service is
//! the set's. Each set is sent at a random phase of the period, so both paths wait for the
//! controller's next cycle alike (uniform over one period) and the difference of their medians
//! is what the network adds, twice (set in, telemetry out). Besides, one way: a state's age
//! when it reaches the sender, from the plant's stamp (the same clock, one host), on each path. The phases
//! run local, network, local on the same run: the second local phase shows whether the run
//! drifted. They cannot interleave sample by sample: the run's params topic takes two
//! publishers (its optimiser's and one more).

use super::BenchError;
use crate::bridge::BridgeReport;
use crate::error::NetError;
use crate::ipc::{Ipc, Topic};
use crate::msg::{ParamKind, ParamSet, PlantState, Telemetry};
use crate::{key, open, wire, Endpoint};
use evoloop_rt::timing::Percentiles;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use zenoh::handlers::FifoChannelHandler;
use zenoh::pubsub::Subscriber;
use zenoh::sample::Sample;
use zenoh::Wait;

/// Give up on one set after this long (the controller refused it, or the run is gone).
const SET_TIMEOUT: Duration = Duration::from_secs(2);

/// What `evoloop bench bridge` measured (printed, or as JSON with `--json`).
#[derive(Debug, serde::Serialize)]
pub struct BridgeBench {
    /// The scenario of the run (its path).
    pub scenario: String,
    /// Its control period, s.
    pub period_s: f64,
    /// Parameter sets timed in each phase.
    pub sets_per_phase: usize,
    /// Round trips in ns: local, through the bridge, local again.
    pub local: Percentiles,
    /// Round trips through the bridge (Zenoh on loopback, both ways), ns.
    pub bridge: Percentiles,
    /// Round trips on the local path again, after the bridge phase (did the run drift?), ns.
    pub local_again: Percentiles,
    /// bridge p50 - local p50 (both local phases' median), ns: what the network adds, twice.
    pub added_p50_ns: f64,
    /// A state's age on arrival (plant stamp to receipt), ns: iceoryx2 and through the bridge.
    pub state_local: Percentiles,
    /// A state's age on arrival through the bridge, ns.
    pub state_bridge: Percentiles,
    /// What the bridge relayed during its phase.
    pub bridge_report: Option<BridgeReport>,
}

/// Send `sets` sets each way on a realtime run of `scenario` and time them.
pub fn run(scenario: &std::path::Path, sets: usize, port: u16) -> Result<BridgeBench, BenchError> {
    let scn = crate::config::Scenario::load(scenario, &crate::config::Overrides::default())
        .map_err(BenchError::Config)?;
    let kind = scn.controller.param_kind();
    let gains = scn.controller.tunable().gains.clone();
    let pid = std::process::id();
    // One prefix for every run of this bench (iceoryx2 keeps a management file per prefix),
    // a run id of its own per process.
    let (run_id, prefix) = (format!("bb{pid}"), "evoloop_bb_".to_string());
    let out = std::env::temp_dir().join(format!("evoloop-bench-bridge-{pid}"));
    let mut child = start_run(scenario, &run_id, &prefix, &out)?;
    let result = measure(&run_id, &prefix, kind, &gains, sets, port, scn.period_ns());
    evoloop_run::node::launcher::signal(&child, libc::SIGTERM);
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&out);
    let m = result?;
    let p = |v: &[f64]| Percentiles::from_samples(v.iter().map(|x| *x as i64));
    let (l, b, l2) = (p(&m.local), p(&m.bridge), p(&m.local_again));
    Ok(BridgeBench {
        scenario: scenario.display().to_string(),
        period_s: scn.timing.period,
        sets_per_phase: sets,
        added_p50_ns: b.p50_ns as f64 - 0.5 * (l.p50_ns + l2.p50_ns) as f64,
        local: l,
        bridge: b,
        local_again: l2,
        state_local: p(&m.state_local),
        state_bridge: p(&m.state_bridge),
        bridge_report: Some(m.report),
    })
}

fn start_run(
    scenario: &std::path::Path,
    run_id: &str,
    prefix: &str,
    out: &std::path::Path,
) -> Result<Child, BenchError> {
    let exe = std::env::current_exe().map_err(BenchError::Start)?;
    Command::new(exe)
        .arg("run")
        .arg(scenario)
        .args([
            "--mode",
            "realtime",
            "--duration",
            "forever",
            "--optimiser",
            "off",
        ])
        .args([
            "--run-id",
            run_id,
            "--ipc-prefix",
            prefix,
            "--quiet",
            "--out",
        ])
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(BenchError::Start)
}

struct Phases {
    local: Vec<f64>,
    bridge: Vec<f64>,
    local_again: Vec<f64>,
    state_local: Vec<f64>,
    state_bridge: Vec<f64>,
    report: BridgeReport,
}

/// States timed per path for the one-way figure.
const STATES: usize = 2000;

/// Sleep a random part of `period_ns`, so a send falls at any phase of the control period.
fn random_phase(rng: &mut impl rand::Rng, period_ns: u64) {
    std::thread::sleep(Duration::from_nanos(rng.gen_range(0..period_ns.max(1))));
}

/// Poll `next` until it gives something, for at most 20 s (`what` names it in the error).
fn first<T>(
    mut next: impl FnMut() -> Result<Option<T>, BenchError>,
    what: &str,
) -> Result<T, BenchError> {
    let t0 = Instant::now();
    loop {
        if let Some(v) = next()? {
            return Ok(v);
        }
        if t0.elapsed() > Duration::from_secs(20) {
            return Err(BenchError::NotMeasured(format!("{what} within 20 s")));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// One path's round trips: `sets` sets, versions after `version`, each sent by `send` at a
/// random phase of the period and timed until `next` (the path's telemetry) shows it in service.
struct RoundTrips<'a, R> {
    rng: &'a mut R,
    period_ns: u64,
    kind: ParamKind,
    gains: &'a [f64],
    version: u64,
}

impl<R: rand::Rng> RoundTrips<'_, R> {
    fn run(
        &mut self,
        sets: usize,
        mut send: impl FnMut(&ParamSet) -> Result<(), BenchError>,
        mut next: impl FnMut() -> Result<Option<Telemetry>, BenchError>,
    ) -> Result<Vec<f64>, BenchError> {
        let mut out = Vec::with_capacity(sets);
        for _ in 0..sets {
            self.version += 1;
            let v = self.version;
            // Two sets in turn: the scenario's gains and the same scaled by 1.001 (in bounds: a
            // tuner's step), so every version is a real change.
            let f = if v.is_multiple_of(2) { 1.0 } else { 1.001 };
            let values: Vec<f64> = self.gains.iter().map(|g| g * f).collect();
            let set = ParamSet::new(v, 0, self.kind, &values);
            random_phase(self.rng, self.period_ns);
            while next()?.is_some() {}
            let sent = Instant::now();
            send(&set)?;
            loop {
                if next()?.is_some_and(|t| t.param_version >= v) {
                    out.push(sent.elapsed().as_nanos() as f64);
                    break;
                }
                if sent.elapsed() > SET_TIMEOUT {
                    return Err(BenchError::NotMeasured(format!(
                        "set {v} not in service after 2 s"
                    )));
                }
                std::hint::spin_loop();
            }
        }
        Ok(out)
    }
}

/// Ages on arrival of `STATES` states from `next` (the plant's stamp to now, one clock).
fn state_ages(
    mut next: impl FnMut() -> Result<Option<PlantState>, BenchError>,
) -> Result<Vec<f64>, BenchError> {
    let mut ages = Vec::with_capacity(STATES);
    while ages.len() < STATES {
        if let Some(s) = next()? {
            ages.push(evoloop_rt::clock::now_ns().saturating_sub(s.stamp_ns) as f64);
        }
    }
    Ok(ages)
}

/// The next message of `sub` as a `T`, if one has arrived.
fn recv<T: iceoryx2::prelude::ZeroCopySend + Copy>(
    sub: &Subscriber<FifoChannelHandler<Sample>>,
) -> Result<Option<T>, BenchError> {
    match sub
        .try_recv()
        .map_err(NetError::zenoh("Zenoh: receiving through the bridge"))?
    {
        Some(s) => Ok(Some(wire::decode(&s.payload().to_bytes())?)),
        None => Ok(None),
    }
}

fn measure(
    run_id: &str,
    prefix: &str,
    kind: ParamKind,
    gains: &[f64],
    sets: usize,
    port: u16,
    period_ns: u64,
) -> Result<Phases, BenchError> {
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let mut trips = RoundTrips {
        rng: &mut rng,
        period_ns,
        kind,
        gains,
        version: 1_000_000,
    };
    let ipc = Ipc::with_cleanup("evoloop-bench-bridge", run_id, prefix, false)?;
    let telemetry = ipc.subscriber::<Telemetry>(Topic::Telemetry, 64, false)?;
    let local_tel = || Ok(telemetry.next()?);
    // The run is up once its controller's telemetry flows.
    first(local_tel, "no telemetry from the run's controller")?;
    // The local publisher lives for one phase: the params topic takes two publishers, the
    // run's optimiser's and one more (the bridge's in the middle phase).
    let local = |trips: &mut RoundTrips<_>| {
        let params = ipc.publisher::<ParamSet>(Topic::Params, false)?;
        trips.run(sets, |s| Ok(params.send(s)?), local_tel)
    };
    let local_first = local(&mut trips)?;
    let state_local = {
        let states = ipc.subscriber::<PlantState>(Topic::State, 8, false)?;
        state_ages(|| Ok(states.next()?))?
    };
    // Through a bridge of this process (its own thread, as `evoloop bridge` would run).
    let ep = format!("tcp/127.0.0.1:{port}");
    let stop = Arc::new(AtomicBool::new(false));
    let bridge = {
        let (run_id, prefix, ep, stop) = (
            run_id.to_string(),
            prefix.to_string(),
            Endpoint::Listen(ep.clone()),
            stop.clone(),
        );
        std::thread::spawn(move || {
            crate::bridge::run(&run_id, &prefix, &ep, None, None, None, &stop)
        })
    };
    let z = open(&Endpoint::Connect(ep), None)?;
    let zt = crate::bridge::subscriber(&z, key(run_id, Topic::Telemetry, false))?;
    let zp = crate::bridge::publisher(
        &z,
        key(run_id, Topic::Params, false),
        zenoh::qos::CongestionControl::Block,
    )?;
    first(|| recv::<Telemetry>(&zt), "no telemetry through the bridge")?;
    let through = trips.run(
        sets,
        |s| {
            let sent = zp.put(wire::encode(s)).wait();
            Ok(sent.map_err(NetError::zenoh("Zenoh: sending a set to the bridge"))?)
        },
        || recv(&zt),
    )?;
    let state_bridge = {
        let zs = crate::bridge::subscriber(&z, key(run_id, Topic::State, false))?;
        state_ages(|| recv(&zs))?
    };
    stop.store(true, Ordering::SeqCst);
    let report = bridge.join().map_err(|_| BenchError::BridgePanicked)??;
    drop((zt, zp, z));
    let local_again = local(&mut trips)?;
    Ok(Phases {
        local: local_first,
        bridge: through,
        local_again,
        state_local,
        state_bridge,
        report,
    })
}

/// A free TCP port on loopback.
pub use evoloop_run::node::launcher::free_port;

/// The scenario `bench bridge` runs by default.
pub fn default_scenario() -> PathBuf {
    evoloop_run::node::launcher::shipped("config/two_mass/two_mass.toml")
}
