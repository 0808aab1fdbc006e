//! Optimisers. Every global optimiser is an ask/tell object over the `Optimiser` trait: it
//! proposes a generation of candidates, the caller evaluates them (in parallel, on whatever
//! model), and tells it the objective values (minimised). Seeded for reproducibility. The local
//! refinement of a least-squares fit, which needs the residual vector and not only its sum, is
//! `levenberg_marquardt`.
//!
//! ```
//! use evoloop_optim::{DeConfig, DifferentialEvolution};
//! use evoloop_optim::{run, Optimiser};
//!
//! // Any `Fn(&[f64]) -> f64 + Sync` is an objective: here the sphere on [-5, 5]^3.
//! let sphere = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>();
//! // The two-mass paper's DE settings (Table 4: 100 members, its stopping rule), F 0.5, CR 0.9.
//! let cfg = DeConfig::paper(0.5, 0.9, vec![-5.0; 3], vec![5.0; 3], 7);
//! let mut de = DifferentialEvolution::new(cfg).unwrap();
//! // Generations evaluated on 1 thread, at most 300 of them, no target value, no progress.
//! let r = run(&mut de, &sphere, 1, 300, None, |_| {});
//! assert!(r.value < 1e-3, "{}", r.value);
//! assert_eq!(de.best().1, r.value);
//! ```

pub mod bayes;
pub mod by_name;
pub mod chaotic;
pub mod cmaes;
pub mod de;
pub mod emupso;
pub mod ga;
pub mod hooke_jeeves;
pub mod hybrid;
pub mod jade;
pub mod levenberg_marquardt;
pub mod listed;
pub mod peers;
pub mod problem;
pub mod pso;
pub mod pull;
pub mod remote;
pub mod rng;
pub mod settings;
pub mod study;
pub mod suite;
pub mod swarm;
pub mod wolves;

pub use de::{DeConfig, DifferentialEvolution};
pub use ga::{Ga, GaConfig};
pub use hooke_jeeves::{HjSearch, HookeJeeves, LocalResult};
pub use settings::SettingsError;

use std::time::Instant;

/// An ask/tell optimiser: `ask` proposes a generation of candidates, the caller evaluates them
/// (in parallel, on any model) and `tell` takes their values, which it minimises. `run` drives
/// any of them to its end.
pub trait Optimiser {
    /// Candidates to evaluate now.
    fn ask(&mut self) -> &[Vec<f64>];
    /// The candidates the last `ask` returned.
    fn candidates(&self) -> &[Vec<f64>];
    /// Their objective values (minimised), in the order `ask` gave them.
    fn tell(&mut self, values: &[f64]);
    /// Best candidate so far and its value.
    fn best(&self) -> (&[f64], f64);
    /// Completed generations (iterations).
    fn generation(&self) -> usize;
    /// Objective evaluations so far.
    fn evaluations(&self) -> usize;
    /// The optimiser's own stopping rule says stop.
    fn converged(&self) -> bool;
    /// For each candidate of the last `ask`, the value it must reach (<=) to be of any use, when
    /// the optimiser knows one (DE: its target's value). Lets an objective stop early.
    fn thresholds(&self) -> Option<&[f64]> {
        None
    }
    /// Before `tell`: each candidate's safety margin (> 0: the experiment stayed safe; evoloop's
    /// direct scheme measures how far inside the envelope a trial stayed, as a fraction of it).
    /// An optimiser that does not model safety ignores it (the default).
    fn tell_safety(&mut self, margins: &[f64]) {
        let _ = margins;
    }
}

/// A function to minimise. `value_below` may stop early once it has proven the value is above
/// `threshold`, returning any number above it; the optimiser then makes the same decision as
/// with the exact value.
pub trait Objective: Sync {
    /// The objective's value at `x` (minimised).
    fn value(&self, x: &[f64]) -> f64;
    /// The value at `x`, or any number above `threshold` once it is proven to be above it. The
    /// default computes the exact value.
    fn value_below(&self, x: &[f64], threshold: f64) -> f64 {
        let _ = threshold;
        self.value(x)
    }
    /// The objective described exactly, for an evaluation worker of the same build to rebuild
    /// (`evoloop::jobs::rebuild`); None for one that stays in this process (closures, objectives
    /// over data too large to ship).
    fn describe(&self) -> Option<Job> {
        None
    }
}

/// An objective as it crosses to an evaluation worker: its kind (`evoloop::jobs` knows them all)
/// and its fields in postcard, where every f64 is its 8 bytes, so the rebuilt objective holds
/// the same bits and computes the same values.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Job {
    /// Which objective it is: the name `evoloop::jobs::rebuild` knows it by.
    pub kind: String,
    /// The objective's fields, postcard-encoded.
    pub bytes: Vec<u8>,
}

impl Job {
    /// `value` encoded as job `kind` (None when it cannot be encoded).
    pub fn of<T: serde::Serialize>(kind: &str, value: &T) -> Option<Job> {
        postcard::to_allocvec(value).ok().map(|bytes| Job {
            kind: kind.to_string(),
            bytes,
        })
    }

    /// The objective back from its bytes.
    pub fn decode<T: serde::de::DeserializeOwned>(&self) -> Result<T, JobDecodeError> {
        postcard::from_bytes(&self.bytes).map_err(|source| JobDecodeError {
            kind: self.kind.clone(),
            bytes: self.bytes.len(),
            source,
        })
    }
}

/// A job whose bytes do not decode as the objective its kind names: a worker or an optimiser
/// of another version, or damaged bytes. The decoder's own error is the `source()`.
#[derive(Debug)]
pub struct JobDecodeError {
    /// The job's kind.
    pub kind: String,
    /// Its length, bytes.
    pub bytes: usize,
    source: postcard::Error,
}

impl std::fmt::Display for JobDecodeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "job `{}`: cannot decode its {} bytes: {}",
            self.kind, self.bytes, self.source
        )
    }
}

impl std::error::Error for JobDecodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

impl<F: Fn(&[f64]) -> f64 + Sync> Objective for F {
    fn value(&self, x: &[f64]) -> f64 {
        self(x)
    }
}

/// The default thread count of population evaluations: every core this process may use.
pub fn all_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Going parallel pays when the work other threads take over exceeds this: waking a pool worker
/// on another vCPU costs about 20 us one way on the development VM (and the results come back the
/// same way). So the arsinh GA's two 13 us evaluations per iteration stay in one thread, while a
/// DE generation of 100 r_c evaluations (20-30 us each) or two 1 ms maglev runs go to the pool.
pub const PARALLEL_MIN_SAVING_NS: u64 = 50_000;

/// A persistent pool of `threads` workers, built once per thread count and kept for the process:
/// no thread is started per generation.
fn pool(threads: usize) -> std::sync::Arc<rayon::ThreadPool> {
    use std::collections::HashMap;
    use std::sync::{Arc, Mutex, OnceLock};
    static POOLS: OnceLock<Mutex<HashMap<usize, Arc<rayon::ThreadPool>>>> = OnceLock::new();
    let mut pools = POOLS
        .get_or_init(Default::default)
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    pools
        .entry(threads)
        .or_insert_with(|| {
            Arc::new(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .thread_name(|i| format!("evoloop-eval-{i}"))
                    .build()
                    .expect("a thread pool"),
            )
        })
        .clone()
}

/// Run `f` on the persistent pool of `threads` workers: parallel iterators inside it share those
/// workers (nested ones too, by work stealing), so a study that runs its seeds side by side and
/// each seed's simulations side by side keeps `threads` busy and never more.
pub fn in_pool<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    pool(threads.max(1)).install(f)
}

/// The measured cost of one evaluation per objective type (ns, last call's mean), so that even a
/// GA asking for two candidates at a time can decide before evaluating whether to go parallel.
type CostTable = std::sync::Mutex<std::collections::HashMap<&'static str, u64>>;

fn cost_estimates() -> &'static CostTable {
    static COST: std::sync::OnceLock<CostTable> = std::sync::OnceLock::new();
    COST.get_or_init(Default::default)
}

/// Whether `rest` evaluations of about `estimate_ns` each are worth handing to `threads`
/// threads: the work the other threads would take off this one (the estimate times their share)
/// must exceed `PARALLEL_MIN_SAVING_NS`.
fn parallel_pays(estimate_ns: u64, rest: usize, threads: usize) -> bool {
    let saving = estimate_ns as f64 * rest as f64 * (1.0 - 1.0 / threads.max(1) as f64);
    threads > 1 && saving >= PARALLEL_MIN_SAVING_NS as f64
}

/// Evaluate `candidates` with `f` on up to `threads` threads, each against its threshold when
/// given. Serial or parallel is decided by the measured cost of one evaluation of this objective
/// type (the first ever is evaluated here and timed) times the batch: when the work other threads
/// would take over is below `PARALLEL_MIN_SAVING_NS` everything runs in this thread (the hand-off
/// would cost more than it saves), otherwise on a persistent pool. With evaluation workers
/// installed (`remote::install`) and an objective that describes itself, the batch is shared
/// with the workers up (`remote::spread`). The result does not depend on the thread count, the
/// workers or the timing: each value is computed independently, from the same bits.
pub fn evaluate<F: Objective + ?Sized>(
    candidates: &[Vec<f64>],
    thresholds: Option<&[f64]>,
    f: &F,
    threads: usize,
) -> Vec<f64> {
    use rayon::prelude::*;
    let n = candidates.len();
    let key = std::any::type_name::<F>();
    let limit = |i: usize| thresholds.map_or(f64::INFINITY, |t| t[i]);
    // One evaluation and its duration.
    let one = |i: usize| {
        let t0 = std::time::Instant::now();
        let (c, t) = (&candidates[i], limit(i));
        let v = if t.is_finite() {
            f.value_below(c, t)
        } else {
            f.value(c)
        };
        (v, t0.elapsed().as_nanos() as u64)
    };
    if n == 0 {
        return Vec::new();
    }
    let known = cost_estimates()
        .lock()
        .map(|m| m.get(key).copied())
        .unwrap_or(None);
    // The first evaluation ever of this objective type is made here, timed: the estimate.
    let timed_first = known.is_none().then(|| one(0));
    let estimate = known.or(timed_first.map(|t| t.1)).unwrap_or(0);
    let first = timed_first.is_some() as usize;
    // Time spent and evaluations made here, for the cost estimate.
    let spent = std::cell::Cell::new(timed_first.map_or((0, 0), |t| (t.1, 1)));
    // This process's evaluator over a run of the batch: serial or on the pool, by the rule
    // above.
    let local = |r: std::ops::Range<usize>| -> Vec<f64> {
        let threads = threads.max(1).min(r.len());
        let done: Vec<(f64, u64)> = if !parallel_pays(estimate, r.len(), threads) {
            r.map(one).collect()
        } else {
            pool(threads).install(|| r.into_par_iter().map(one).collect())
        };
        let (ns, k) = spent.get();
        spent.set((ns + done.iter().map(|d| d.1).sum::<u64>(), k + done.len()));
        done.into_iter().map(|d| d.0).collect()
    };
    let mut values: Vec<f64> = timed_first.map(|t| t.0).into_iter().collect();
    // Evaluation workers take part when there are any up, and the objective can travel.
    let workers = remote::installed()
        .filter(|_| n > first)
        .map(|w| (w, w.live()))
        .filter(|(_, live)| !live.is_empty())
        .and_then(|(w, live)| Some((w, live, f.describe()?)));
    let tally = match workers {
        Some((w, live, job)) => {
            let shifted = |r: std::ops::Range<usize>| local(r.start + first..r.end + first);
            let batch = remote::Batch {
                job: &job,
                candidates: &candidates[first..],
                thresholds: thresholds.map(|t| &t[first..]),
            };
            let (v, t) = remote::spread(w, &live, batch, threads, estimate, &shifted);
            values.extend(v);
            remote::Tally {
                local: t.local + first as u64,
                ..t
            }
        }
        None => {
            values.extend(local(first..n));
            remote::Tally {
                local: n as u64,
                ..Default::default()
            }
        }
    };
    remote::record(tally);
    let (ns, k) = spent.get();
    if k > 0 {
        if let Ok(mut m) = cost_estimates().lock() {
            m.insert(key, ns / k as u64);
        }
    }
    values
}

/// Why `run` stopped; in JSON and CSV its snake_case name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The optimiser's own stopping rule.
    Converged,
    /// The generation limit `max_generations` was reached.
    MaxGenerations,
    /// The best value reached the target.
    Target,
}

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StopReason::Converged => "converged",
            StopReason::MaxGenerations => "max_generations",
            StopReason::Target => "target",
        })
    }
}

/// Result of running an optimiser to its end.
#[derive(Debug, Clone, serde::Serialize)]
pub struct RunResult {
    /// Best candidate found.
    pub best: Vec<f64>,
    /// Its objective value.
    pub value: f64,
    /// Generations completed.
    pub generations: usize,
    /// Objective evaluations made.
    pub evaluations: usize,
    /// Wall-clock time of the run, s.
    pub seconds: f64,
    /// Why it stopped.
    pub stopped_by: StopReason,
    /// Best value after each generation.
    pub history: Vec<f64>,
}

/// Run `opt` on `f` until its stopping rule, `max_generations`, or (when given) `target` is
/// reached; `progress` is called after each generation.
pub fn run<O: Optimiser, F: Objective + ?Sized>(
    opt: &mut O,
    f: &F,
    threads: usize,
    max_generations: usize,
    target: Option<f64>,
    mut progress: impl FnMut(&O),
) -> RunResult {
    let t0 = Instant::now();
    let mut history = Vec::new();
    let stopped_by = loop {
        opt.ask();
        let values = evaluate(opt.candidates(), opt.thresholds(), f, threads);
        opt.tell(&values);
        history.push(opt.best().1);
        progress(opt);
        if target.is_some_and(|t| opt.best().1 <= t) {
            break StopReason::Target;
        }
        if opt.converged() {
            break StopReason::Converged;
        }
        if opt.generation() >= max_generations {
            break StopReason::MaxGenerations;
        }
    };
    let (best, value) = opt.best();
    RunResult {
        best: best.to_vec(),
        value,
        generations: opt.generation(),
        evaluations: opt.evaluations(),
        seconds: t0.elapsed().as_secs_f64(),
        stopped_by,
        history,
    }
}

/// Defines method `$name`, which runs the `#[inline(always)]` method `$body` compiled four lanes
/// wide (as `$avx2`) where the CPU has AVX2, else as built (baseline x86-64, two lanes): the
/// release build runs anywhere and uses the wider unit where there is one. FMA is deliberately
/// not enabled: the compiler could then fuse a multiply and an add into one rounding and seeded
/// results would depend on the machine; without it the operations, and so the results, are the
/// same on every x86-64.
macro_rules! wide_method {
    ($(#[$m:meta])* fn $name:ident, $avx2:ident => $body:ident($($arg:ident: $ty:ty),*)) => {
        $(#[$m])*
        fn $name(&self, $($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has just been checked for AVX2.
                return unsafe { self.$avx2($($arg),*) };
            }
            self.$body($($arg),*)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        unsafe fn $avx2(&self, $($arg: $ty),*) {
            self.$body($($arg),*)
        }
    };
}
use wide_method;

/// Ask, evaluate in this thread, tell, until the optimiser stops or the next batch would
/// exceed `evaluations`; `after` sees the optimiser after each tell. The loop for objectives
/// that cost nanoseconds (benchmark functions, `optim bench`), where `run`'s timing and
/// hand-off decision per generation would cost more than the evaluations; and a budget in
/// evaluations, not generations, because the methods count generations differently (a GA
/// generation is two evaluations, a swarm's a population).
pub fn drive(
    opt: &mut dyn Optimiser,
    evaluations: usize,
    f: impl Fn(&[f64]) -> f64,
    mut after: impl FnMut(&dyn Optimiser),
) {
    let mut values = Vec::new();
    while !opt.converged() {
        let done = opt.evaluations();
        let asked = opt.ask();
        if done + asked.len() > evaluations {
            break;
        }
        values.clear();
        values.extend(asked.iter().map(|x| f(x)));
        opt.tell(&values);
        after(&*opt);
    }
}

/// Evaluations per second of `opt` driven `evaluations` times on a function that costs nothing
/// (x -> x_0): the optimiser's own overhead per evaluation, one thread (`evoloop optim bench`,
/// and CI's measure of a host's speed). Timed here, where `drive` and the function are
/// compiled with the optimisers, whatever the calling crate's optimisation level.
pub fn overhead_rate(opt: &mut dyn Optimiser, evaluations: usize) -> f64 {
    let t = std::time::Instant::now();
    drive(opt, evaluations, |x| x[0], |_| {});
    opt.evaluations() as f64 / t.elapsed().as_secs_f64()
}

#[cfg(test)]
mod evaluate_tests {
    use super::*;
    use std::collections::HashSet;
    use std::sync::Mutex;
    use std::thread::ThreadId;

    /// An objective that records which threads evaluated it and costs `spin_ns` each.
    struct Probe {
        spin_ns: u64,
        threads: Mutex<HashSet<ThreadId>>,
    }
    impl Objective for Probe {
        fn value(&self, x: &[f64]) -> f64 {
            self.threads
                .lock()
                .unwrap()
                .insert(std::thread::current().id());
            let t0 = std::time::Instant::now();
            while (t0.elapsed().as_nanos() as u64) < self.spin_ns {}
            x.iter().map(|v| v * v).sum()
        }
    }
    struct Costly(Probe);
    impl Objective for Costly {
        fn value(&self, x: &[f64]) -> f64 {
            self.0.value(x)
        }
    }

    /// The decision itself, without timing: the arsinh GA's two 13 us evaluations stay serial;
    /// a DE generation of 100 r_c evaluations (25 us) and two 1 ms maglev runs go parallel.
    #[test]
    fn parallel_pays_only_beyond_the_hand_off_cost() {
        assert!(!parallel_pays(13_000, 1, 2));
        assert!(!parallel_pays(13_000, 2, 2));
        assert!(parallel_pays(25_000, 99, 2));
        assert!(parallel_pays(1_000_000, 2, 2));
        assert!(!parallel_pays(1_000_000, 2, 1));
    }

    #[test]
    fn cheap_objectives_stay_in_this_thread_costly_ones_use_the_pool_and_values_agree() {
        let candidates: Vec<Vec<f64>> = (0..16).map(|i| vec![i as f64, 1.0]).collect();
        let expect: Vec<f64> = candidates.iter().map(|c| c[0] * c[0] + 1.0).collect();
        let cheap = Probe {
            spin_ns: 0,
            threads: Default::default(),
        };
        // The decision is made from the cost estimate before each batch; the estimates are
        // set here, as earlier batches would have measured them, because one measured on a
        // loaded machine is whatever the scheduler made it (a cold evaluation of a cheap
        // function preempted for a time slice measured 100 us and sent this batch to the pool).
        let estimate = |key: &'static str, ns: u64| {
            cost_estimates().lock().unwrap().insert(key, ns);
        };
        // Which threads evaluated: this one alone (serial), or the pool's only (a batch handed
        // to the pool never runs on the caller's thread). How many pool threads took part is
        // the scheduler's business on a loaded machine, so it is not asserted.
        let here = std::thread::current().id();
        let ran = |p: &Probe| p.threads.lock().unwrap().clone();
        // Two at a time, as the arsinh GA asks, at 1 us each: serial.
        estimate(std::any::type_name::<Probe>(), 1_000);
        assert_eq!(evaluate(&candidates[..2], None, &cheap, 2), expect[..2]);
        assert_eq!(ran(&cheap), HashSet::from([here]), "cheap: this thread");
        let costly = Costly(Probe {
            spin_ns: 200_000,
            threads: Default::default(),
        });
        for _ in 0..2 {
            estimate(std::any::type_name::<Costly>(), 200_000);
            assert_eq!(evaluate(&candidates, None, &costly, 2), expect);
        }
        assert!(!ran(&costly.0).contains(&here), "costly: on the pool");
        // Two candidates at a time (the steady-state GA): the known cost sends both to the pool.
        costly.0.threads.lock().unwrap().clear();
        for _ in 0..4 {
            estimate(std::any::type_name::<Costly>(), 200_000);
            evaluate(&candidates[..2], None, &costly, 2);
        }
        assert!(!ran(&costly.0).contains(&here), "costly pairs: on the pool");
    }
}
