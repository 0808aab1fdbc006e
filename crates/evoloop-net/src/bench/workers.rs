//! `evoloop bench workers`: evaluations per second of the maglev model with 0, 1, 2, ...
//! evaluation workers (separate `evoloop worker` processes on loopback), the same populations in
//! every phase, and what the remote path costs per run and per evaluation (a run's round trip
//! minus the worker's own compute time), for the scaling model in the book.

use super::BenchError;
use crate::optim::remote::{totals, Workers as _};
use crate::optim::{evaluate, Objective};
use crate::workers::ZenohWorkers;
use serde::Serialize;
use std::time::{Duration, Instant};

/// What to measure.
#[derive(Debug, Clone)]
pub struct Settings {
    /// Worker counts, one phase each.
    pub workers: Vec<usize>,
    /// Candidates per population.
    pub population: usize,
    /// Populations per phase (after one unmeasured warm-up population).
    pub populations: usize,
    /// This process's threads (the optimiser's `optimiser.threads`).
    pub threads: usize,
    /// Each worker's threads.
    pub worker_threads: usize,
}

/// One phase's figures.
#[derive(Debug, Clone, Serialize)]
pub struct Phase {
    /// Evaluation workers up in this phase.
    pub workers: usize,
    /// Candidates evaluated in the measured populations, here and on the workers.
    pub evaluations: u64,
    /// Wall time of the measured populations, s.
    pub seconds: f64,
    /// `evaluations` over `seconds`.
    pub evaluations_per_s: f64,
    /// Of them, those a worker evaluated.
    pub evaluations_remote: u64,
    /// Of them, those this process evaluated (its own share and the reissued ones).
    pub evaluations_local: u64,
    /// Of the local ones, those sent to a worker that failed or did not answer in time.
    pub evaluations_reissued: u64,
    /// Runs the workers answered, their mean length, and what the remote path added per run
    /// (round trip minus the worker's compute time) and per evaluation in them, us.
    pub runs: u64,
    /// Mean candidates per answered run.
    pub run_length: f64,
    /// What the remote path added per answered run (round trip minus compute time), us.
    pub overhead_per_run_us: f64,
    /// The same per evaluation in the answered runs, us.
    pub overhead_per_evaluation_us: f64,
    /// The workers' own compute time per evaluation, us.
    pub worker_us_per_evaluation: f64,
}

/// What `evoloop bench workers` measured.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// CPUs this process may use (`std::thread::available_parallelism`).
    pub machine_cores: usize,
    /// One evaluation in this process, alone, us (median of `population`).
    pub local_us_per_evaluation: f64,
    /// Candidates per population.
    pub population: usize,
    /// Measured populations per phase.
    pub populations: usize,
    /// This process's evaluation threads.
    pub threads: usize,
    /// Each worker's threads.
    pub worker_threads: usize,
    /// One phase per worker count of `Settings::workers`, in that order.
    pub phases: Vec<Phase>,
    /// The remote path alone: runs of one candidate of a near-empty job to one worker, nothing
    /// else running here: round trip minus the worker's compute time, us.
    pub probe: evoloop_rt::timing::Percentiles,
    /// Round trips in `probe` (0 when no phase had exactly one worker).
    pub probe_runs: usize,
}

/// The maglev model every phase evaluates: the fuzzy-network paper's 2.5 s experiment with the
/// fuzzy anti-windup PID.
fn objective() -> evoloop_scenario::sim::maglev::Objective {
    evoloop_scenario::sim::maglev::Objective::fuzzy(
        evoloop_scenario::sim::maglev::Spec::default().duration,
        1,
    )
}

/// `n` sets about the paper's tuned one (+-10 %, seeded).
fn candidates(n: usize, seed: u64) -> Vec<Vec<f64>> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            evoloop_scenario::sim::maglev::PAPER_FUZZY
                .iter()
                .map(|v| v * rng.gen_range(0.9..1.1))
                .collect()
        })
        .collect()
}

/// Runs of the transport probe.
const PROBE_RUNS: usize = 300;

/// `runs` round trips of one candidate of a one-sample maglev job to the one worker up, one at
/// a time: round trip minus the worker's compute time, us each.
fn transport(pool: &ZenohWorkers, runs: usize) -> Result<Vec<f64>, BenchError> {
    use crate::optim::remote::Reply;
    let mut f = objective();
    f.spec.duration = f.spec.period;
    let xs = candidates(1, 7);
    let job = f.describe().expect("the maglev objective describes itself");
    let id = pool
        .live()
        .first()
        .ok_or_else(|| BenchError::NotMeasured("no worker up for the probe".into()))?
        .id
        .clone();
    let mut out = Vec::with_capacity(runs);
    for _ in 0..runs {
        let (stats0, t0) = (pool.stats(), Instant::now());
        let mut pending = pool.send(&id, &job, &[&xs[0]], &[f64::INFINITY]);
        loop {
            match pending.poll(Duration::from_secs(5)) {
                Reply::Waiting if t0.elapsed() < Duration::from_secs(5) => continue,
                Reply::Values(_) => break,
                r => return Err(BenchError::NotMeasured(format!("probe run: {r:?}"))),
            }
        }
        let (w, w0) = (&pool.stats()[&id], &stats0[&id]);
        out.push(((w.round_trip_s - w0.round_trip_s) - (w.compute_s - w0.compute_s)) * 1e6);
    }
    Ok(out)
}

/// Run every phase of `s`: start its workers (`evoloop worker` processes on loopback), time the
/// same populations, and probe the remote path alone in the first phase of one worker.
/// `progress` gets a line per result. Fails when the workers are not up within 20 s or a probe
/// run fails.
pub fn run(s: &Settings, progress: impl Fn(&str)) -> Result<Report, BenchError> {
    let ep = evoloop_run::node::launcher::local_workers_endpoint()?;
    let stop = std::sync::atomic::AtomicBool::new(false);
    let pool = crate::workers::install(&ep, None, 0, &stop)?;
    let f = objective();
    let local_us = {
        let mut t: Vec<f64> = candidates(s.population, 99)
            .iter()
            .map(|x| {
                let t0 = Instant::now();
                std::hint::black_box(f.value(x));
                t0.elapsed().as_secs_f64() * 1e6
            })
            .collect();
        t.sort_by(f64::total_cmp);
        t[t.len() / 2]
    };
    progress(&format!(
        "one maglev evaluation here: {local_us:.0} us (median of {})",
        s.population
    ));
    let mut phases = Vec::new();
    let mut probe = Vec::new();
    for (k, &n) in s.workers.iter().enumerate() {
        let procs = evoloop_run::node::launcher::LocalWorkers::start(
            &ep,
            n,
            s.worker_threads,
            0,
            &format!("bench-{k}"),
        )?;
        let t0 = Instant::now();
        while pool.live().len() != n {
            if t0.elapsed() > Duration::from_secs(20) {
                return Err(BenchError::NotMeasured(format!(
                    "{} of {n} workers up after 20 s",
                    pool.live().len()
                )));
            }
            pool.wait_for(n, Duration::from_millis(50), &stop);
        }
        // A warm-up population: the workers' first job, the pool's threads.
        evaluate(&candidates(s.population, 1000), None, &f, s.threads);
        if n == 1 && probe.is_empty() {
            probe = transport(pool, PROBE_RUNS)?;
        }
        let (before, stats0) = (totals(), pool.stats());
        let t0 = Instant::now();
        for p in 0..s.populations {
            let xs = candidates(s.population, p as u64);
            std::hint::black_box(evaluate(&xs, None, &f, s.threads));
        }
        let seconds = t0.elapsed().as_secs_f64();
        let d = totals().since(before);
        let (mut runs, mut evals, mut rt, mut cs) = (0u64, 0u64, 0.0, 0.0);
        for (id, w) in pool.stats() {
            let w0 = stats0.get(&id).cloned().unwrap_or_default();
            runs += w.answered - w0.answered;
            evals += w.evaluations - w0.evaluations;
            rt += w.round_trip_s - w0.round_trip_s;
            cs += w.compute_s - w0.compute_s;
        }
        let per = |x: f64, k: u64| if k > 0 { x * 1e6 / k as f64 } else { 0.0 };
        let evaluations = d.local + d.remote;
        let phase = Phase {
            workers: n,
            evaluations,
            seconds,
            evaluations_per_s: evaluations as f64 / seconds,
            evaluations_remote: d.remote,
            evaluations_local: d.local,
            evaluations_reissued: d.reissued,
            runs,
            run_length: if runs > 0 {
                evals as f64 / runs as f64
            } else {
                0.0
            },
            overhead_per_run_us: per(rt - cs, runs),
            overhead_per_evaluation_us: per(rt - cs, evals),
            worker_us_per_evaluation: per(cs, evals),
        };
        progress(&format!(
            "{n} worker(s): {:.0} evaluations/s ({} remote, {} reissued); remote path {:.0} us per run of {:.1}, {:.0} us per evaluation",
            phase.evaluations_per_s,
            phase.evaluations_remote,
            phase.evaluations_reissued,
            phase.overhead_per_run_us,
            phase.run_length,
            phase.overhead_per_evaluation_us
        ));
        phases.push(phase);
        drop(procs);
        // The next phase starts from no workers.
        let t0 = Instant::now();
        while !pool.live().is_empty() && t0.elapsed() < Duration::from_secs(10) {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let p = evoloop_rt::timing::Percentiles::from_samples(probe.iter().map(|us| (us * 1e3) as i64));
    if !probe.is_empty() {
        progress(&format!(
            "remote path alone (1 worker, {} runs of 1 near-empty evaluation): {:.0} us median, {:.0} us p90",
            probe.len(),
            p.p50_ns as f64 * 1e-3,
            p.p90_ns as f64 * 1e-3
        ));
    }
    Ok(Report {
        probe_runs: probe.len(),
        probe: p,
        machine_cores: crate::optim::all_cores(),
        local_us_per_evaluation: local_us,
        population: s.population,
        populations: s.populations,
        threads: s.threads,
        worker_threads: s.worker_threads,
        phases,
    })
}
