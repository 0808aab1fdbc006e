//! Population evaluations spread over evaluation workers in other processes, on this host or
//! others (`evoloop worker`; the transport is `net::workers`, feature `zenoh`).
//!
//! `optim::evaluate` hands a batch here when workers are installed (`install`), the objective
//! describes itself (`Objective::describe`) and the batch is worth the trip. The batch is shared
//! out in proportion to threads: each live worker gets a contiguous run of candidates, this
//! process keeps the rest and evaluates it while the workers do theirs. A worker that fails,
//! vanishes, or is not back by its deadline has its run evaluated here ("reissued"); a late
//! answer is dropped. Every value is computed from the same bits by the same code wherever it
//! runs, so the values, and the run, do not depend on which worker answered or whether any did.

use super::Job;
use std::ops::Range;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

/// A worker that is up now: its name and how many evaluations it runs at once.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Slot {
    /// The worker's name, which `Workers::send` addresses it by.
    pub id: String,
    /// Evaluations it runs at once; its share of a batch is in proportion to them.
    pub threads: usize,
}

/// Where a batch sent to a worker stands.
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// No answer yet.
    Waiting,
    /// One value per candidate sent, in their order.
    Values(Vec<f64>),
    /// The worker refused the batch, or went away: its candidates must be evaluated elsewhere.
    Failed(String),
}

/// A batch out at a worker.
pub trait Pending: Send {
    /// Its answer, waiting up to `wait` for it.
    fn poll(&mut self, wait: Duration) -> Reply;
}

/// The transport to the workers.
pub trait Workers: Send + Sync {
    /// The workers up now.
    fn live(&self) -> Vec<Slot>;
    /// Send `candidates` (each with the value it must reach, infinite when none) of `job` to
    /// worker `id`.
    fn send(
        &self,
        id: &str,
        job: &Job,
        candidates: &[&[f64]],
        thresholds: &[f64],
    ) -> Box<dyn Pending>;
}

/// Sending a run of candidates pays when the work it takes off this process exceeds this. The
/// remote path alone (query out, answer back, both encoded) costs 0.08-0.2 ms at the median on
/// loopback on the development VM, and 1-3 ms per run when both its cores compute (replies wait
/// for a core; `evoloop bench workers`, the book): a worker gets no run shorter than a
/// millisecond of work.
pub const REMOTE_MIN_SAVING_NS: u64 = 1_000_000;

/// A worker's run is overdue, and reissued here, after this many times its expected time (its
/// length times the locally measured cost of one evaluation, over its threads) plus
/// `REMOTE_GRACE`: generous, as a worker's host may be slower or busier than this one.
pub const REMOTE_SLACK: u32 = 4;
/// Added to every worker run's deadline beyond `REMOTE_SLACK` times its expected time.
pub const REMOTE_GRACE: Duration = Duration::from_millis(200);

/// Evaluations by where they were computed (in optimiser.json and summary.json under these
/// keys).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Tally {
    /// In this process (the reissued ones included).
    #[serde(rename = "evaluations_local", default)]
    pub local: u64,
    /// Answered by a worker.
    #[serde(rename = "evaluations_remote", default)]
    pub remote: u64,
    /// Sent to a worker that failed, vanished or did not answer in time, then evaluated here.
    #[serde(rename = "evaluations_reissued", default)]
    pub reissued: u64,
}

impl Tally {
    /// The evaluations made since `before` was taken.
    pub fn since(self, before: Tally) -> Tally {
        Tally {
            local: self.local - before.local,
            remote: self.remote - before.remote,
            reissued: self.reissued - before.reissued,
        }
    }

    /// The run's summary line for them, when workers took part.
    pub fn summary_line(&self) -> Option<String> {
        (self.remote + self.reissued > 0).then(|| {
            format!(
                "evaluations: {} on workers, {} here ({} of them reissued from a worker that did not answer)",
                self.remote, self.local, self.reissued
            )
        })
    }
}

impl std::ops::AddAssign for Tally {
    fn add_assign(&mut self, t: Tally) {
        self.local += t.local;
        self.remote += t.remote;
        self.reissued += t.reissued;
    }
}

static TOTALS: Mutex<Tally> = Mutex::new(Tally {
    local: 0,
    remote: 0,
    reissued: 0,
});

static WORKERS: OnceLock<&'static dyn Workers> = OnceLock::new();

/// Use `w` for every costly population evaluation of this process from now on (once per
/// process, for the rest of it; a second call is refused).
pub fn install(w: &'static dyn Workers) -> Result<(), AlreadyInstalled> {
    WORKERS.set(w).map_err(|_| AlreadyInstalled)
}

/// `install` was called a second time in one process: the first workers stay.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct AlreadyInstalled;

impl std::fmt::Display for AlreadyInstalled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("evaluation workers are already installed")
    }
}

impl std::error::Error for AlreadyInstalled {}

/// The installed workers, if any.
pub fn installed() -> Option<&'static dyn Workers> {
    WORKERS.get().copied()
}

/// Every evaluation `optim::evaluate` made in this process so far, by where it was computed.
pub fn totals() -> Tally {
    *TOTALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Add one batch's evaluations to the process's totals (`optim::evaluate`, once per batch).
pub(super) fn record(t: Tally) {
    *TOTALS.lock().unwrap_or_else(|e| e.into_inner()) += t;
}

/// The runs of `n` candidates: this process's first, then one per worker, in proportion to
/// threads (largest remainders), where a worker's run must carry at least
/// `REMOTE_MIN_SAVING_NS` of work at `estimate_ns` per evaluation; a run too short stays here.
pub fn plan(
    n: usize,
    local_threads: usize,
    workers: &[Slot],
    estimate_ns: u64,
) -> (Range<usize>, Vec<(usize, Range<usize>)>) {
    let threads: Vec<usize> = std::iter::once(local_threads.max(1))
        .chain(workers.iter().map(|w| w.threads.max(1)))
        .collect();
    let capacity: usize = threads.iter().sum();
    let mut share: Vec<usize> = threads.iter().map(|t| n * t / capacity).collect();
    let left = n - share.iter().sum::<usize>();
    // Largest remainders first (fewer than one per participant are left); the stable sort keeps
    // this process first on a tie, as its share needs no trip.
    let mut order: Vec<usize> = (0..threads.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(n * threads[i] % capacity));
    for &i in order.iter().take(left) {
        share[i] += 1;
    }
    let mut local = share[0];
    let mut shares: Vec<(usize, usize)> = share[1..].iter().copied().enumerate().collect();
    // Runs not worth their trip come back here.
    for s in &mut shares {
        if (s.1 as u64).saturating_mul(estimate_ns) < REMOTE_MIN_SAVING_NS {
            local += s.1;
            s.1 = 0;
        }
    }
    let mut runs = Vec::new();
    let mut at = local;
    for (i, len) in shares {
        if len > 0 {
            runs.push((i, at..at + len));
            at += len;
        }
    }
    (0..local, runs)
}

/// Evaluate candidates `range` of the batch (values come back with their index); this process's
/// evaluator (serial or its thread pool, `optim::evaluate`'s rule).
pub type Local<'a> = dyn Fn(Range<usize>) -> Vec<f64> + 'a;

/// A population of one objective: its description, the candidates, their thresholds.
#[derive(Clone, Copy)]
pub struct Batch<'a> {
    /// The objective, described for the workers to rebuild.
    pub job: &'a Job,
    /// The points to evaluate, in order.
    pub candidates: &'a [Vec<f64>],
    /// For each candidate, the value it must reach to be of any use (`Optimiser::thresholds`);
    /// None when there are none.
    pub thresholds: Option<&'a [f64]>,
}

/// Evaluate `batch` over `workers` (those in `slots`) and this process (`local`, on
/// `local_threads`; `estimate_ns` per evaluation), values in candidate order.
pub fn spread(
    workers: &dyn Workers,
    slots: &[Slot],
    batch: Batch<'_>,
    local_threads: usize,
    estimate_ns: u64,
    local: &Local<'_>,
) -> (Vec<f64>, Tally) {
    let Batch {
        job,
        candidates,
        thresholds,
    } = batch;
    let n = candidates.len();
    let (mine, runs) = plan(n, local_threads, slots, estimate_ns);
    let limit = |i: usize| thresholds.map_or(f64::INFINITY, |t| t[i]);
    let t0 = Instant::now();
    let out: Vec<(Box<dyn Pending>, Range<usize>, Instant)> = runs
        .into_iter()
        .map(|(w, r)| {
            let xs: Vec<&[f64]> = candidates[r.clone()].iter().map(|c| c.as_slice()).collect();
            let ts: Vec<f64> = r.clone().map(limit).collect();
            let expected = Duration::from_nanos(
                estimate_ns.saturating_mul(r.len() as u64) / slots[w].threads.max(1) as u64,
            );
            let deadline = t0 + expected * REMOTE_SLACK + REMOTE_GRACE;
            (workers.send(&slots[w].id, job, &xs, &ts), r, deadline)
        })
        .collect();
    let mut values = vec![f64::NAN; n];
    let mut tally = Tally::default();
    values[mine.clone()].copy_from_slice(&local(mine.clone()));
    tally.local += mine.len() as u64;
    for (mut pending, r, deadline) in out {
        let answer = loop {
            let wait = deadline.saturating_duration_since(Instant::now());
            match pending.poll(wait) {
                Reply::Waiting if wait.is_zero() => break None,
                Reply::Waiting => continue,
                Reply::Values(v) if v.len() == r.len() => break Some(v),
                Reply::Values(_) | Reply::Failed(_) => break None,
            }
        };
        match answer {
            Some(v) => {
                values[r.clone()].copy_from_slice(&v);
                tally.remote += r.len() as u64;
            }
            None => {
                values[r.clone()].copy_from_slice(&local(r.clone()));
                tally.local += r.len() as u64;
                tally.reissued += r.len() as u64;
            }
        }
    }
    (values, tally)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    fn slots(threads: &[usize]) -> Vec<Slot> {
        threads
            .iter()
            .enumerate()
            .map(|(i, t)| Slot {
                id: format!("w{i}"),
                threads: *t,
            })
            .collect()
    }

    #[test]
    fn the_plan_covers_every_candidate_once_in_proportion_to_threads() {
        for n in 0..40 {
            for threads in [&[][..], &[1], &[1, 1], &[2, 1, 4], &[8]] {
                for local in 1..4 {
                    let (mine, runs) = plan(n, local, &slots(threads), 10_000_000);
                    let mut all: Vec<usize> = mine.clone().collect();
                    for (_, r) in &runs {
                        all.extend(r.clone());
                    }
                    assert_eq!(all, (0..n).collect::<Vec<_>>(), "n {n} {threads:?} {local}");
                    let cap = (local + threads.iter().sum::<usize>()) as f64;
                    for (w, r) in &runs {
                        let fair = n as f64 * threads[*w] as f64 / cap;
                        assert!(
                            (r.len() as f64 - fair).abs() < 1.0 + 1e-9,
                            "{n} {threads:?}"
                        );
                    }
                    assert!((mine.len() as f64 - n as f64 * local as f64 / cap).abs() < 1.0 + 1e-9);
                }
            }
        }
        // 2 candidates, two local threads and two one-thread workers: one stays, one goes.
        let (mine, runs) = plan(2, 2, &slots(&[1, 1]), 10_000_000);
        assert_eq!((mine.len(), runs.len()), (1, 1));
    }

    #[test]
    fn a_run_not_worth_its_trip_stays_here() {
        // 10 us per evaluation: a worker's 5 candidates are 50 us of work, far below the trip.
        let (mine, runs) = plan(10, 1, &slots(&[1]), 10_000);
        assert_eq!((mine, runs.len()), (0..10, 0));
        let (mine, runs) = plan(10, 1, &slots(&[1]), REMOTE_MIN_SAVING_NS / 5);
        assert_eq!((mine, runs), (0..5, vec![(0, 5..10)]));
    }

    /// Workers in this process: each answers after `delay`, or fails, or never answers.
    #[derive(Clone, Copy)]
    enum Behaviour {
        Answer,
        Fail,
        Silent,
    }

    struct Fake {
        behaviour: Vec<Behaviour>,
        sent: Mutex<Vec<(String, usize)>>,
    }

    struct FakePending(Option<Vec<f64>>, Behaviour);

    impl Pending for FakePending {
        fn poll(&mut self, wait: Duration) -> Reply {
            match self.1 {
                Behaviour::Answer => Reply::Values(self.0.take().unwrap_or_default()),
                Behaviour::Fail => Reply::Failed("gone".into()),
                Behaviour::Silent => {
                    std::thread::sleep(wait.min(Duration::from_millis(5)));
                    Reply::Waiting
                }
            }
        }
    }

    impl Workers for Fake {
        fn live(&self) -> Vec<Slot> {
            slots(&vec![1; self.behaviour.len()])
        }
        fn send(&self, id: &str, job: &Job, xs: &[&[f64]], ts: &[f64]) -> Box<dyn Pending> {
            self.sent.lock().unwrap().push((id.to_string(), xs.len()));
            let i: usize = id[1..].parse().unwrap();
            let f: Bowl = job.decode().unwrap();
            use crate::Objective;
            let v = xs
                .iter()
                .zip(ts)
                .map(|(x, t)| {
                    if t.is_finite() {
                        f.value_below(x, *t)
                    } else {
                        f.value(x)
                    }
                })
                .collect();
            Box::new(FakePending(Some(v), self.behaviour[i]))
        }
    }

    /// An objective that describes itself, as evoloop's model objectives do (`evoloop::jobs`
    /// rebuilds those): sum of w_i sin(x_i)^2, whose bits depend on every input bit.
    #[derive(serde::Serialize, serde::Deserialize)]
    struct Bowl {
        weights: Vec<f64>,
    }

    impl crate::Objective for Bowl {
        fn value(&self, x: &[f64]) -> f64 {
            x.iter()
                .zip(&self.weights)
                .map(|(x, w)| w * x.sin().powi(2))
                .sum()
        }
        fn describe(&self) -> Option<Job> {
            Job::of("bowl", self)
        }
    }

    #[test]
    fn values_do_not_depend_on_which_worker_answered_or_whether_any_did() {
        use crate::Objective;
        let f = Bowl {
            weights: vec![1.0, 0.3, 2.5, 0.7],
        };
        let job = f.describe().unwrap();
        let base = [0.4, -1.2, 2.0, 0.05];
        let candidates: Vec<Vec<f64>> = (0..9)
            .map(|i| base.iter().map(|v| v * (1.0 + 0.01 * i as f64)).collect())
            .collect();
        let here: Vec<u64> = candidates.iter().map(|c| f.value(c).to_bits()).collect();
        let local = |r: Range<usize>| candidates[r].iter().map(|c| f.value(c)).collect();
        use Behaviour::*;
        for (behaviour, remote, reissued) in [
            (vec![Answer, Answer], 6, 0),
            (vec![Answer, Fail], 3, 3),
            (vec![Silent, Answer], 3, 3),
            (vec![Fail, Silent], 0, 6),
        ] {
            let w = Fake {
                behaviour,
                sent: Mutex::new(Vec::new()),
            };
            let t0 = Instant::now();
            // 1 ms per evaluation: every worker's run of 3 is worth the trip.
            let (v, tally) = spread(
                &w,
                &w.live(),
                Batch {
                    job: &job,
                    candidates: &candidates,
                    thresholds: None,
                },
                1,
                1_000_000,
                &local,
            );
            let bits: Vec<u64> = v.iter().map(|x| x.to_bits()).collect();
            assert_eq!(bits, here);
            assert_eq!(w.sent.lock().unwrap().len(), 2, "both workers got a run");
            assert_eq!(
                (tally.remote, tally.reissued, tally.local),
                (remote, reissued, 9 - remote)
            );
            // A silent worker is given up on at its deadline: 4 x 3 ms + 200 ms.
            assert!(t0.elapsed() < Duration::from_secs(2));
        }
    }
}
