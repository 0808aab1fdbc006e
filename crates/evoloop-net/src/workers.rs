//! Evaluation workers over Zenoh: `evoloop worker --connect ENDPOINT` serves candidate
//! evaluations; an optimiser with `optimiser.workers = "zenoh"` listens on its endpoint and
//! spreads each costly population over the workers up (`optim::remote`).
//!
//! - A worker announces itself with a liveliness token `evoloop/workers/<id>/<threads>/<build>`:
//!   the optimiser's view of who is up follows the tokens (a worker that dies or loses the link
//!   drops out of it at once).
//! - It serves a queryable `evoloop/eval/<id>`: a query carries the job (`optim::Job`: the
//!   objective, exactly) and a run of candidates with their thresholds; the reply carries one
//!   value per candidate and the time the worker spent on them. A refused job gets an error
//!   reply with the reason.
//! - `<build>` is the version, the CPU architecture and a hash of the sources, the compiler and
//!   the target (`build.rs`): the same code compiled the same way computes the same bits. The
//!   optimiser uses no worker of another build (it says so once), and a worker refuses a run
//!   from another build.
//!
//! Payloads are postcard (every f64 its 8 bytes), so nothing is lost in transit.

use super::Endpoint;
use crate::error::NetError;
use crate::optim::remote::{Pending, Reply, Slot, Workers};
use crate::optim::Job;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::query::{ConsolidationMode, Reply as ZReply};
use zenoh::Wait as _;

/// Liveliness tokens of the workers up.
pub const TOKENS: &str = "evoloop/workers";
/// A worker's queryable: `evoloop/eval/<id>`.
pub const EVAL: &str = "evoloop/eval";
/// Zenoh gives up on a query after this (the optimiser reissues a run long before, at its
/// deadline: `optim::remote::REMOTE_SLACK`).
const QUERY_TIMEOUT: Duration = Duration::from_secs(120);

/// What a worker and an optimiser must share: the version, the CPU architecture, and the build's
/// identity (a hash of the sources, the lock file, the compiler and the target: `build.rs`).
pub fn build() -> String {
    format!(
        "{}-{}-{}",
        env!("CARGO_PKG_VERSION"),
        std::env::consts::ARCH,
        env!("EVOLOOP_BUILD_ID")
    )
}

/// A run of candidates of one job, as it crosses.
#[derive(Debug, Serialize, Deserialize)]
pub struct Request {
    /// The optimiser's `build()`: a worker refuses a run from another build.
    pub build: String,
    /// The objective, described exactly for the worker to rebuild.
    pub job: Job,
    /// The points to evaluate, in order.
    pub candidates: Vec<Vec<f64>>,
    /// For each candidate, the value it must reach to be of any use (infinite: none); the worker
    /// may stop an evaluation once the value is proven above it.
    pub thresholds: Vec<f64>,
}

/// A worker's values for a run, and the time it spent computing them.
#[derive(Debug, Serialize, Deserialize)]
struct Answer {
    values: Vec<f64>,
    compute_ns: u64,
}

/// One worker as the optimiser saw it.
#[derive(Debug, Clone, Default, Serialize, PartialEq)]
pub struct WorkerStats {
    /// Its threads, from its liveliness token.
    pub threads: usize,
    /// Runs sent, and those answered.
    pub batches: u64,
    /// Runs it answered.
    pub answered: u64,
    /// Candidates it evaluated (answered runs).
    pub evaluations: u64,
    /// Runs it refused or did not answer (the optimiser evaluated them itself).
    pub failed: u64,
    /// Its own compute time, and the round trips of its answered runs, s.
    pub compute_s: f64,
    /// Total round trip of its answered runs, s.
    pub round_trip_s: f64,
}

type Shared<T> = Arc<Mutex<T>>;

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The optimiser's side: the workers up, and the queries to them (`optim::remote::Workers`).
pub struct ZenohWorkers {
    session: zenoh::Session,
    live: Shared<BTreeMap<String, Slot>>,
    stats: Shared<BTreeMap<String, WorkerStats>>,
    _tokens: zenoh::pubsub::Subscriber<()>,
}

/// `id` from a token's key `evoloop/workers/<id>/<threads>/<build>`.
pub fn parse_token(key: &str) -> Option<(String, usize, String)> {
    let rest = key.strip_prefix(TOKENS)?.strip_prefix('/')?;
    let mut parts = rest.split('/');
    let (id, threads, build) = (parts.next()?, parts.next()?, parts.next()?);
    if parts.next().is_some() || id.is_empty() {
        return None;
    }
    Some((id.to_string(), threads.parse().ok()?, build.to_string()))
}

/// Listen for evaluation workers on `listen` and use them for every costly population of this
/// process from now on (`optim::remote::install`); wait up to `config::WORKERS_WAIT_S` for
/// `expect` of them (saying so when fewer came; the others join as they come). The pool, for
/// its statistics.
pub fn install(
    listen: &str,
    zenoh_config: Option<&Path>,
    expect: usize,
    stop: &AtomicBool,
) -> Result<&'static ZenohWorkers, NetError> {
    let z = ZenohWorkers::start(&Endpoint::Listen(listen.to_string()), zenoh_config)?;
    // For the rest of the process: `optim::evaluate` may run on any thread at any time.
    let z: &'static ZenohWorkers = Box::leak(Box::new(z));
    crate::optim::remote::install(z).map_err(NetError::WorkersInstalled)?;
    if expect > 0 {
        let limit = crate::config::WORKERS_WAIT_S;
        let up = z.wait_for(expect, Duration::from_secs_f64(limit), stop);
        if up < expect {
            eprintln!(
                "evoloop: {up} of {expect} evaluation workers up after {limit} s; going on, the rest join as they come"
            );
        }
    }
    Ok(z)
}

impl ZenohWorkers {
    /// Open the optimiser's session on `ep` and follow the workers' tokens.
    pub fn start(ep: &Endpoint, zenoh_config: Option<&Path>) -> Result<Self, NetError> {
        let session = super::open(ep, zenoh_config)?;
        let live: Shared<BTreeMap<String, Slot>> = Default::default();
        let stats: Shared<BTreeMap<String, WorkerStats>> = Default::default();
        let other_builds: Shared<BTreeSet<String>> = Default::default();
        let (l, s) = (live.clone(), stats.clone());
        let mine = build();
        let tokens = session
            .liveliness()
            .declare_subscriber(format!("{TOKENS}/**"))
            .history(true)
            .callback(move |sample| {
                let key = sample.key_expr().as_str();
                let Some((id, threads, b)) = parse_token(key) else {
                    return;
                };
                match sample.kind() {
                    zenoh::sample::SampleKind::Put if b == mine => {
                        lock(&s).entry(id.clone()).or_default().threads = threads;
                        lock(&l).insert(id.clone(), Slot { id, threads });
                    }
                    zenoh::sample::SampleKind::Put => {
                        if lock(&other_builds).insert(id.clone()) {
                            eprintln!(
                                "evoloop-optimiser: worker {id} is build {b}, this is {mine}: not used"
                            );
                        }
                    }
                    zenoh::sample::SampleKind::Delete => {
                        lock(&l).remove(&id);
                    }
                }
            })
            .wait()
            .map_err(NetError::zenoh("Zenoh: following the workers' tokens"))?;
        Ok(Self {
            session,
            live,
            stats,
            _tokens: tokens,
        })
    }

    /// The optimiser's Zenoh session (to query a worker directly).
    pub fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// Wait up to `limit` for `n` workers to be up; how many are.
    pub fn wait_for(&self, n: usize, limit: Duration, stop: &AtomicBool) -> usize {
        let t0 = Instant::now();
        loop {
            let up = lock(&self.live).len();
            if up >= n || t0.elapsed() >= limit || stop.load(Ordering::SeqCst) {
                return up;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Every worker seen, by id.
    pub fn stats(&self) -> BTreeMap<String, WorkerStats> {
        lock(&self.stats).clone()
    }
}

impl Workers for ZenohWorkers {
    fn live(&self) -> Vec<Slot> {
        lock(&self.live).values().cloned().collect()
    }

    fn send(
        &self,
        id: &str,
        job: &Job,
        candidates: &[&[f64]],
        thresholds: &[f64],
    ) -> Box<dyn Pending> {
        let req = Request {
            build: build(),
            job: job.clone(),
            candidates: candidates.iter().map(|c| c.to_vec()).collect(),
            thresholds: thresholds.to_vec(),
        };
        lock(&self.stats).entry(id.to_string()).or_default().batches += 1;
        let sent = Instant::now();
        // The reply is stamped as it arrives (the optimiser may be busy with its own share
        // then); the channel closes when Zenoh ends the query, answered or not.
        let (tx, rx) = std::sync::mpsc::channel();
        let rx = postcard::to_allocvec(&req)
            .map_err(|e| format!("encoding the run: {e}"))
            .and_then(|bytes| {
                self.session
                    .get(format!("{EVAL}/{id}"))
                    .payload(bytes)
                    .consolidation(ConsolidationMode::None)
                    .timeout(QUERY_TIMEOUT)
                    .callback(move |reply| {
                        let _ = tx.send((Instant::now(), reply));
                    })
                    .wait()
                    .map_err(|e| format!("Zenoh query to worker {id}: {e}"))
            })
            .map(|()| rx);
        Box::new(ZenohPending {
            rx,
            id: id.to_string(),
            n: candidates.len(),
            sent,
            stats: self.stats.clone(),
        })
    }
}

/// A run out at a worker: the query's reply channel.
struct ZenohPending {
    rx: Result<std::sync::mpsc::Receiver<(Instant, ZReply)>, String>,
    id: String,
    n: usize,
    sent: Instant,
    stats: Shared<BTreeMap<String, WorkerStats>>,
}

impl ZenohPending {
    /// The run failed: counted against the worker.
    fn failed(&self, why: String) -> Reply {
        lock(&self.stats).entry(self.id.clone()).or_default().failed += 1;
        Reply::Failed(why)
    }

    fn answer(&self, reply: ZReply) -> Result<Answer, String> {
        match reply.into_result() {
            Ok(sample) => postcard::from_bytes::<Answer>(&sample.payload().to_bytes())
                .map_err(|e| format!("worker {}: an answer that does not decode: {e}", self.id)),
            Err(e) => Err(format!(
                "worker {} refused the run: {}",
                self.id,
                String::from_utf8_lossy(&e.payload().to_bytes())
            )),
        }
    }
}

impl Pending for ZenohPending {
    fn poll(&mut self, wait: Duration) -> Reply {
        let rx = match &self.rx {
            Ok(rx) => rx,
            Err(e) => return self.failed(e.clone()),
        };
        use std::sync::mpsc::RecvTimeoutError;
        let (arrived, got) = match rx.recv_timeout(wait) {
            Ok((at, reply)) => (at, self.answer(reply)),
            Err(RecvTimeoutError::Timeout) => return Reply::Waiting,
            // The query ended without an answer: the worker went away mid-run.
            Err(RecvTimeoutError::Disconnected) => (
                Instant::now(),
                Err(format!("worker {} went away without answering", self.id)),
            ),
        };
        match got {
            Ok(a) if a.values.len() == self.n => {
                let mut st = lock(&self.stats);
                let s = st.entry(self.id.clone()).or_default();
                s.answered += 1;
                s.evaluations += self.n as u64;
                s.compute_s += a.compute_ns as f64 * 1e-9;
                s.round_trip_s += arrived.duration_since(self.sent).as_secs_f64();
                Reply::Values(a.values)
            }
            Ok(a) => self.failed(format!(
                "worker {}: {} values for {} candidates",
                self.id,
                a.values.len(),
                self.n
            )),
            Err(e) => self.failed(e),
        }
    }
}

/// What a worker did (printed at its end; `--json`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct WorkerReport {
    /// The worker's id: its key chunk in `evoloop/eval/<id>` (by default host and process id).
    pub id: String,
    /// Threads it evaluates with.
    pub threads: usize,
    /// Its `build()`: the optimisers it serves must have the same.
    pub build: String,
    /// Runs answered, and the candidates in them.
    pub batches: u64,
    /// Candidates in the runs answered.
    pub evaluations: u64,
    /// Runs refused (another build, a job it cannot rebuild, a payload that does not decode).
    pub refused: u64,
    /// Time spent evaluating, s, and the time it was up.
    pub busy_s: f64,
    /// How long it was up, s.
    pub wall_s: f64,
}

/// A name for this worker that is a valid key chunk: host and process id.
pub fn default_id() -> String {
    let mut buf = [0u8; 256];
    // SAFETY: gethostname writes at most buf.len() bytes into buf.
    let host = if unsafe { libc::gethostname(buf.as_mut_ptr().cast(), buf.len()) } == 0 {
        let end = buf.iter().position(|b| *b == 0).unwrap_or(buf.len());
        String::from_utf8_lossy(&buf[..end]).into_owned()
    } else {
        "host".into()
    };
    key_safe(&format!("{host}-{}", std::process::id()))
}

/// `s` with every character a key chunk may not hold replaced by `_`.
pub fn key_safe(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Serve evaluations on `ep` with `threads` threads until `stop` (or `duration`).
pub fn serve(
    ep: &Endpoint,
    zenoh_config: Option<&Path>,
    id: &str,
    threads: usize,
    duration: Option<Duration>,
    stop: &AtomicBool,
) -> Result<WorkerReport, NetError> {
    let session = super::open(ep, zenoh_config)?;
    let queryable = session
        .declare_queryable(format!("{EVAL}/{id}"))
        .wait()
        .map_err(NetError::zenoh(format!("Zenoh: declaring {EVAL}/{id}")))?;
    // The token after the queryable: an optimiser that sees the worker can query it.
    let _token = session
        .liveliness()
        .declare_token(format!("{TOKENS}/{id}/{threads}/{}", build()))
        .wait()
        .map_err(NetError::zenoh("Zenoh: declaring the worker's token"))?;
    let mut report = WorkerReport {
        id: id.to_string(),
        threads,
        build: build(),
        ..Default::default()
    };
    let t0 = Instant::now();
    // The last job's objective, kept while the optimiser sends runs of the same job.
    let mut cached: Option<(Job, Box<dyn crate::optim::Objective + Send>)> = None;
    while !stop.load(Ordering::SeqCst) && duration.is_none_or(|d| t0.elapsed() < d) {
        let query = match queryable
            .recv_timeout(Duration::from_millis(100))
            .map_err(NetError::zenoh("Zenoh: the queryable closed"))?
        {
            Some(q) => q,
            None => continue,
        };
        let started = Instant::now();
        let sent = match evaluate(&query, &mut cached, threads) {
            Ok(values) => {
                report.batches += 1;
                report.evaluations += values.len() as u64;
                let bytes = postcard::to_allocvec(&Answer {
                    compute_ns: started.elapsed().as_nanos() as u64,
                    values,
                })
                .map_err(|source| NetError::Encode {
                    what: "a worker's answer",
                    source,
                })?;
                query.reply(query.key_expr().clone(), bytes).wait()
            }
            Err(why) => {
                report.refused += 1;
                eprintln!("evoloop worker {id}: refused a run: {why}");
                query.reply_err(why).wait()
            }
        };
        report.busy_s += started.elapsed().as_secs_f64();
        if let Err(e) = sent {
            eprintln!("evoloop worker {id}: cannot reply: {e}");
        }
    }
    report.wall_s = t0.elapsed().as_secs_f64();
    Ok(report)
}

/// Values of a query's run.
fn evaluate(
    query: &zenoh::query::Query,
    cached: &mut Option<(Job, Box<dyn crate::optim::Objective + Send>)>,
    threads: usize,
) -> Result<Vec<f64>, String> {
    let bytes = query
        .payload()
        .map(|p| p.to_bytes().into_owned())
        .ok_or("a query without a run")?;
    let req: Request =
        postcard::from_bytes(&bytes).map_err(|e| format!("a run that does not decode: {e}"))?;
    if req.build != build() {
        return Err(format!(
            "the optimiser is build {}, this worker {}: their values could differ",
            req.build,
            build()
        ));
    }
    if req.thresholds.len() != req.candidates.len() {
        return Err("thresholds and candidates differ in number".into());
    }
    if cached.as_ref().is_none_or(|(j, _)| *j != req.job) {
        let f = crate::jobs::rebuild(&req.job).map_err(|e| e.to_string())?;
        *cached = Some((req.job, f));
    }
    let f = &cached.as_ref().expect("just set").1;
    Ok(crate::optim::evaluate(
        &req.candidates,
        Some(&req.thresholds),
        &**f,
        threads,
    ))
}
