//! The direct scheme (fuzzy-network paper, Section 3.1.1, Fig. 3a; its experiments of Section 5):
//! the optimiser tries its candidates on the plant itself, one repetition of the periodic
//! reference each. At a repetition boundary the next candidate goes to the controller as a
//! trial set (`ParamSet::until_seq`): it serves exactly that repetition, under the safety
//! envelope, and the controller returns to the best set known when it ends or leaves the
//! envelope. The repetition's cost, sum over its samples of sum |r - y| + w sum |u| (eq. 25 with
//! w = 0, eq. 31 with w = 1/1000 per mA), is told to the optimiser, which asks for the next.
//!
//! One `DirectTuner` serves both drivers: the optimiser process, fed from the streams, and
//! `run_in_process` (`evoloop tune` on a direct scenario), fed by the same closed loop the plant
//! and controller processes run (`sim::run_loop`). In lockstep both make every decision at the
//! same sample on the same numbers, so their cost sequences and final sets are equal bit for bit.
//!
//! Choices where the paper is silent:
//! - The repetition before the first trial runs the configured set: its cost is the baseline,
//!   the first "best known" set, and the set a failed first candidate falls back to.
//! - A candidate aborted by the envelope, or whose cost is not finite, scores +infinity (the GA
//!   then replaces it by a copy of its best member, as the paper does for a lost ball).
//! - After the budget the best set (trial or baseline) stays in service for good.
//! - `optimiser.cost_lag`: the output at sample k is judged against the reference `lag` samples
//!   before. Eq. 25 charges |w_i - x_{i+1}|, the output one sample after the set-point it
//!   answers; with lag 1 a repetition's cost runs over its own outputs x_B .. x_{B+N-1}, so its
//!   first term is the predecessor's last answer and its own last answer falls to the successor
//!   (one of N samples; the decision is due before x_{B+N} exists).
//! - Realtime: a candidate starts at the first boundary after its predecessor's cost is known, so
//!   the fallback may serve a repetition between two trials; a trial whose samples did not all
//!   reach the optimiser (queue overflow) is not scored but tried again.
//! - `optimiser.settle` (not the paper's; off by default): back to back, a trial starts where its
//!   predecessor left the plant and the controller's integrator, so the same set scores
//!   differently after a gentle and after a wild predecessor, which a model of cost and safety
//!   over the sets cannot know. With `settle = N` each trial is followed by up to N repetitions
//!   under the set in service (the trial's fallback) until the loop is back on that set's
//!   periodic orbit: the repetition's mean output and command over its last `TAIL` of samples
//!   within `settle_band` of those of the last settle repetition the set served, scaled by that
//!   repetition's peaks (a set's own trial started on another set's orbit: after it, two settle
//!   repetitions at least). The sensor and command only: what the optimiser sees on a real
//!   plant. None after the last trial or before an operator's stop or revert. The baseline
//!   settles too, and its cost is taken on the configured set's orbit, where the trials start
//!   until one beats it (its first repetition starts from rest). With settling on, the controller
//!   isolates each trial (`ControlCycle::with_isolated_trials`): it starts from the integrator
//!   the set in service left, without a bumpless shift, and that set resumes from it after.

pub mod model;

use crate::config::Scenario;
use crate::law::cycle::Envelope;
use crate::msg::{ParamKind, ParamSet};
use crate::optim::Optimiser;
use crate::report::Csv;
use crate::sim::cost::TrackingCost;
use crate::{SchemeError, WriteError};
use serde::Serialize;

/// The direct scheme's settings, from the scenario's `[optimiser]` table.
#[derive(Debug, Clone, Serialize)]
pub struct DirectSpec {
    /// `optim::by_name::build`'s name: ga, de, jade, pso, emupso, gwo, woa, goa, cmaes, bayes,
    /// safe_bayes (or hybrid, or safe_bayes_model: `model`).
    pub algorithm: String,
    /// The optimiser's population size (`optimiser.population`).
    pub population: usize,
    /// Candidates tried (repetitions spent on trials).
    pub evaluations: usize,
    /// Samples per repetition.
    pub repetition: u64,
    /// Sample at which the first trial starts (the baseline repetition ends there).
    pub first: u64,
    /// Weight w of |u| in the repetition's cost, sum |r - y| + w sum |u|
    /// (`optimiser.cost_u_weight`).
    pub u_weight: f64,
    /// Samples between a reference value and the output judged against it.
    pub lag: usize,
    /// The safety envelope a trial is aborted outside of (`optimiser.envelope_*`).
    pub envelope: Envelope,
    /// Seed of the optimiser's random numbers (the scenario's `seed`).
    pub seed: u64,
    /// Settle repetitions after a trial, at most (0: none) and the band they settle to.
    pub settle: u32,
    /// How near a settle repetition's mean output and command must end to those of the last
    /// repetition the set served, as a fraction of its peak |y| and |u| (`optimiser.settle_band`).
    pub settle_band: f64,
}

impl DirectSpec {
    /// The scenario's direct-scheme settings, its repetition and first trial converted from s to
    /// samples of its control period.
    pub fn of(scn: &Scenario) -> Self {
        let o = &scn.optimiser;
        let dt = scn.timing.period;
        Self {
            algorithm: o.algorithm.clone(),
            population: o.population,
            evaluations: o.evaluations,
            repetition: (o.repetition / dt).round() as u64,
            first: (o.first_repetition / dt).round() as u64,
            u_weight: o.cost_u_weight,
            lag: o.cost_lag as usize,
            envelope: o.envelope,
            seed: scn.seed,
            settle: o.settle,
            settle_band: o.settle_band,
        }
    }

    /// The sample at which the `i`-th trial would start back to back (lockstep).
    pub fn boundary(&self, i: u64) -> u64 {
        self.first + i * self.repetition
    }
}

/// One repetition's record: the baseline (trial 0, the configured set) or a trial.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct Repetition {
    /// 0 = the baseline, then 1, 2, ... in the order tried (0 also for a set an operator put
    /// back, or a restarted optimiser restored: measured like the baseline).
    pub trial: usize,
    /// Parameter version the controller ran it under (0 = the configured set).
    pub version: u64,
    /// Sample at which it started.
    pub start_seq: u64,
    /// Time of its first sample, s.
    pub t: f64,
    /// Its cost (+infinity when aborted).
    #[serde(with = "crate::indirect::infinite_as_null")]
    pub cost: f64,
    /// The controller did not run it to its end: it left the envelope, or the set was refused.
    pub aborted: bool,
    /// How far inside the envelope it stayed at its closest, as a fraction of the envelope
    /// (1 = never moved towards it, < 0 = left it; `Envelope::margin`). 0 in files from before.
    #[serde(default)]
    pub margin: f64,
    /// Settle repetitions run under the set in service before it (`optimiser.settle`).
    #[serde(default)]
    pub settle: u32,
    /// It started after the most settle repetitions allowed, the loop not back in the band.
    #[serde(default)]
    pub unsettled: bool,
    /// The best cost known after it.
    #[serde(with = "crate::indirect::infinite_as_null")]
    pub best: f64,
    /// The version of the best set known after it (what a failed trial falls back to).
    pub best_version: u64,
    /// The parameter values it ran.
    pub values: Vec<f64>,
}

/// A trial the tuner has sent, and what it has seen of it so far.
struct Running {
    /// 0 = the baseline, then 1, 2, ...
    trial: usize,
    version: u64,
    /// Index of the candidate in the optimiser's last `ask` (None: the baseline, or a set an
    /// operator put back).
    index: Option<usize>,
    /// The values it runs.
    values: Vec<f64>,
    start: u64,
    until: u64,
    cost: TrackingCost,
    samples: u64,
    aborted: bool,
    t: f64,
    /// The smallest margin inside the envelope over its samples (`Envelope::margin`).
    margin: f64,
    /// A settle repetition under the set in service (not scored as a trial).
    settle: bool,
    /// Where it leaves the loop.
    tail: Tail,
}

/// Where a repetition left the loop: the sums of each output and command over its last `TAIL`
/// of samples, and the peaks of |y| and |u| over all of it that scale a comparison.
#[derive(Debug, Clone, Copy)]
struct Tail {
    from: u64,
    samples: u64,
    joints: usize,
    y: [f64; crate::msg::MAX_JOINTS],
    u: [f64; crate::msg::MAX_JOINTS],
    peak_y: f64,
    peak_u: f64,
}

/// The fraction of a repetition at its end whose means say where the loop is.
const TAIL: f64 = 0.05;

/// The set a settle segment runs and where the last repetition it served left the loop.
#[derive(Debug, Clone, Copy)]
struct SettleTarget {
    version: u64,
    last: Tail,
    /// `last` is a settle repetition's, on the set's orbit; otherwise the set's own trial or
    /// baseline (started from another set's orbit or from rest), which one repetition agreeing
    /// with does not show settled.
    on_orbit: bool,
}

impl Tail {
    fn new(start: u64, until: u64) -> Self {
        let n = until - start;
        let tail = ((n as f64 * TAIL).round() as u64).clamp(1, n.max(1));
        Self {
            from: until - tail,
            samples: 0,
            joints: 0,
            y: [0.0; crate::msg::MAX_JOINTS],
            u: [0.0; crate::msg::MAX_JOINTS],
            peak_y: 0.0,
            peak_u: 0.0,
        }
    }

    fn add(&mut self, seq: u64, y: &[f64], u: &[f64]) {
        let peak = |m: f64, v: &[f64]| v.iter().fold(m, |m, x| m.max(x.abs()));
        self.peak_y = peak(self.peak_y, y);
        self.peak_u = peak(self.peak_u, u);
        if seq < self.from {
            return;
        }
        self.joints = y.len().min(u.len());
        for j in 0..self.joints {
            self.y[j] += y[j];
            self.u[j] += u[j];
        }
        self.samples += 1;
    }

    /// Whether this repetition ends within `band` of where `own` (the last repetition the set
    /// in service ran) ended, each output and command scaled by `own`'s peak. NaN is never near.
    fn near(&self, own: &Tail, band: f64) -> bool {
        let (k, o) = (self.samples.max(1) as f64, own.samples.max(1) as f64);
        let close = |a: f64, b: f64, scale: f64| (a / k - b / o).abs() <= band * scale;
        self.joints == own.joints
            && (0..self.joints).all(|j| {
                close(self.y[j], own.y[j], own.peak_y) && close(self.u[j], own.u[j], own.peak_u)
            })
    }
}

impl Running {
    /// A repetition of `values` from sample `start` (until `start + repetition`), nothing seen.
    fn new(
        trial: usize,
        version: u64,
        index: Option<usize>,
        values: Vec<f64>,
        start: u64,
        repetition: u64,
        u_weight: f64,
    ) -> Self {
        Self {
            settle: false,
            tail: Tail::new(start, start + repetition),
            trial,
            version,
            index,
            values,
            start,
            until: start + repetition,
            cost: TrackingCost::new(u_weight),
            samples: 0,
            aborted: false,
            t: f64::NAN,
            margin: 1.0,
        }
    }
}

/// The direct scheme's tuner: decides which set the controller runs from each repetition
/// boundary (baseline, trial, settle repetition or the final set), scores each repetition from
/// the samples it observes and tells the costs to its optimiser.
pub struct DirectTuner {
    spec: DirectSpec,
    opt: Box<dyn Optimiser + Send>,
    kind: ParamKind,
    /// The configured set (version 0).
    configured: Vec<f64>,
    /// Values of the last `ask`, a flag per candidate (tried and scored), their costs.
    scored: Vec<Option<f64>>,
    /// Their safety margins (`Optimiser::tell_safety`).
    margins: Vec<f64>,
    /// The next candidate of the last `ask` to send.
    next_index: usize,
    running: Option<Running>,
    best: (Vec<f64>, f64, u64),
    next_version: u64,
    tried: usize,
    finished: bool,
    /// The next set to put in service for good, at the next boundary, measured on its first
    /// repetition (a restarted optimiser: the configured parameters; an operator's revert).
    restore: Option<(u64, Vec<f64>)>,
    /// An operator's hold: no trial starts while it lasts.
    held: bool,
    /// An operator's stop: the best set goes in service for good at the next boundary.
    stop: bool,
    /// The version an operator's revert put in service for good (`finish` does not send it
    /// again).
    for_good: Option<u64>,
    /// Every repetition scored, in order (the budget bounds it: `evaluations` + 1).
    pub records: Vec<Repetition>,
    /// Trials not scored because the optimiser missed some of their samples (tried again).
    pub incomplete: u64,
    /// The references of the last samples, by sequence number (`DirectSpec::lag`).
    refs: [[f64; crate::msg::MAX_JOINTS]; LAGS],
    /// Where the last repetition the best set served left the loop, and whether it was a
    /// settle repetition (its orbit) rather than its own trial (which started elsewhere).
    best_tail: Option<(Tail, bool)>,
    /// What the running trial's settle segment settles to: the set in service then.
    fallback: Option<SettleTarget>,
    /// The baseline's settle segment is running (its cost is taken from it).
    baseline_settling: bool,
    /// Settle repetitions run since the last trial ended; whether the last segment settled.
    settling: u32,
    settled: bool,
    /// Settle repetitions over the run.
    pub settle_repetitions: u64,
}

/// An aborted trial's margin is at most minus this.
const ABORTED_MARGIN: f64 = 0.01;

/// Room for `cost_lag` up to 16 samples.
const LAGS: usize = 17;

impl DirectTuner {
    /// A tuner for the scenario: its optimiser over the controller's bounds, seeded with the
    /// scenario's seed. Validation has made sure the bounds are finite.
    pub fn new(scn: &Scenario) -> Result<Self, SchemeError> {
        Ok(Self::with_optimiser(scn, Self::optimiser(scn)?))
    }

    /// The scenario's optimiser (`optimiser.algorithm`) over the controller's bounds.
    fn optimiser(scn: &Scenario) -> Result<Box<dyn Optimiser + Send>, SchemeError> {
        let spec = DirectSpec::of(scn);
        let b = scn.bounds();
        let configured = scn.controller.tunable().gains.clone();
        // The sample-efficient optimisers start from the set in service always (safe_bayes: its
        // known-safe seed); the population methods when `seed_configured` says so.
        let model_informed = spec.algorithm == crate::config::SAFE_BAYES_MODEL;
        let from_service = model_informed
            || crate::optim::by_name::SAMPLE_EFFICIENT.contains(&spec.algorithm.as_str());
        let seeds = if scn.optimiser.seed_configured || from_service {
            vec![configured.clone()]
        } else {
            Vec::new()
        };
        if model_informed {
            let prior = model::ModelTrials::new(scn)?;
            let bayes = crate::optim::by_name::bayes(true, &b.lower, &b.upper, spec.seed, &seeds)
                .map_err(SchemeError::Settings)?;
            return Ok(Box::new(
                bayes.with_prior(Box::new(prior)).with_stop(model::STOP_EI),
            ));
        }
        let opt: Box<dyn Optimiser + Send> = if spec.algorithm == "hybrid" {
            let o = &scn.optimiser;
            let cfg = crate::optim::hybrid::HybridConfig {
                ga: crate::optim::GaConfig {
                    population: spec.population,
                    p_crossover: 0.9,
                    p_mutation: None,
                    max_iterations: (o.phases[0] + o.phases[1]).max(1),
                    seed: spec.seed,
                },
                phases: o.phases,
                scaling: scn.controller.scaling_genes(),
                threads: 1,
                hj_step: 0.05,
                hj_per_candidate: 0,
            };
            Box::new(crate::optim::pull::Pulled::hybrid(
                cfg, &b.lower, &b.upper, &seeds,
            ))
        } else {
            crate::optim::by_name::build_seeded(
                &spec.algorithm,
                &b.lower,
                &b.upper,
                spec.population,
                spec.evaluations,
                spec.seed,
                &seeds,
            )
            .map_err(SchemeError::Optimiser)?
        };
        Ok(opt)
    }

    /// A tuner for the scenario that tries what `opt` asks for (a test's fixed list of sets, an
    /// optimiser built elsewhere).
    pub fn with_optimiser(scn: &Scenario, opt: Box<dyn Optimiser + Send>) -> Self {
        let spec = DirectSpec::of(scn);
        let configured = scn.controller.tunable().gains.clone();
        // Ends at the first trial's boundary (shorter when `first` < one repetition).
        let start = spec.first.saturating_sub(spec.repetition);
        let baseline = Running::new(
            0,
            0,
            None,
            configured.clone(),
            start,
            spec.first - start,
            spec.u_weight,
        );
        Self {
            kind: scn.controller.param_kind(),
            best: (configured.clone(), f64::INFINITY, 0),
            configured,
            opt,
            scored: Vec::new(),
            margins: Vec::new(),
            next_index: 0,
            running: Some(baseline),
            next_version: 1,
            tried: 0,
            finished: false,
            restore: None,
            held: false,
            stop: false,
            for_good: None,
            records: Vec::with_capacity(spec.evaluations + 1),
            incomplete: 0,
            refs: [[0.0; crate::msg::MAX_JOINTS]; LAGS],
            best_tail: None,
            fallback: None,
            baseline_settling: false,
            settling: 0,
            settled: true,
            settle_repetitions: 0,
            spec,
        }
    }

    /// The settings it tunes under.
    pub fn spec(&self) -> &DirectSpec {
        &self.spec
    }

    /// The best set known: values, cost, version.
    pub fn best(&self) -> (&[f64], f64, u64) {
        (&self.best.0, self.best.1, self.best.2)
    }

    /// Whether the budget is spent and the best set sent for good.
    pub fn finished(&self) -> bool {
        self.finished
    }

    /// A restarted optimiser: its versions continue after `version`, the last one published.
    /// The controller's fallback is a set this tuner never saw, so it starts over: no baseline,
    /// and its first set (at the first boundary) puts the configured parameters back for good.
    pub fn resume(&mut self, version: u64) {
        self.next_version = self.next_version.max(version + 1);
        self.running = None;
        let configured = self.configured.clone();
        self.restore_for_good(configured);
    }

    /// An operator's revert: `values` go in service for good at the next boundary (after the
    /// trial under way, which the controller then ends as usual), under the version returned,
    /// and tuning holds. Their first repetition is measured and they become the best set known,
    /// the fallback of any later trial. A revert before the previous one went out replaces it
    /// (that version is never published).
    pub fn revert(&mut self, values: Vec<f64>) -> u64 {
        self.held = true;
        self.restore_for_good(values)
    }

    /// `values` in service for good at the next boundary, under the version returned.
    fn restore_for_good(&mut self, values: Vec<f64>) -> u64 {
        let version = self.next_version;
        self.next_version += 1;
        self.restore = Some((version, values));
        version
    }

    /// An operator's hold (true) or resume (false): while held no trial starts; the one under
    /// way ends at its boundary and the best set known serves.
    pub fn hold(&mut self, held: bool) {
        self.held = held;
    }

    /// An operator's stop: at the next boundary the best set goes in service for good, as after
    /// the budget.
    pub fn stop(&mut self) {
        self.stop = true;
    }

    /// The last version this tuner published or reserved.
    pub fn last_version(&self) -> u64 {
        self.next_version - 1
    }

    /// One sample: its sequence number and time, the references and outputs of the driven
    /// joints, the command the controller answered it with and the parameter version that
    /// command was computed under. In sequence order.
    pub fn observe(&mut self, seq: u64, t: f64, r: &[f64], y: &[f64], u: &[f64], version: u64) {
        let n = r.len();
        self.refs[seq as usize % LAGS][..n].copy_from_slice(r);
        // The reference `lag` samples back (the first samples of a run: the first reference)
        // for the cost; the margin against the set-point the controller's envelope judges.
        let back = seq.saturating_sub(self.spec.lag as u64) as usize % LAGS;
        let (set_point, r) = (r, &self.refs[back][..n]);
        let Some(run) = self.running.as_mut() else {
            return;
        };
        if seq < run.start || seq >= run.until {
            return;
        }
        if run.samples == 0 {
            run.t = t;
        }
        run.cost.add(r, y, u);
        run.tail.add(seq, y, u);
        run.samples += 1;
        if !run.aborted {
            // Through the first sample the trial no longer ran: the one that left the envelope.
            run.margin = run.margin.min(self.spec.envelope.margin(set_point, y, u));
        }
        if version != run.version {
            // The controller is not running this trial (aborted, or never accepted it).
            run.aborted = true;
        }
    }

    /// Called with sample number `next` before its cycle, every sample before it observed:
    /// scores a repetition that ended just before `next`, and returns the set to send when a
    /// trial (or, the budget spent, the final set) starts. Lockstep (`earliest` None): a trial
    /// starts at `next` when it is a boundary, so trials run back to back. Realtime: when nothing
    /// runs, the next trial starts at the first boundary at or after `earliest` (a sample far
    /// enough ahead for the set to reach the controller in time).
    pub fn at(&mut self, next: u64, earliest: Option<u64>) -> Option<ParamSet> {
        if let Some(run) = &self.running {
            if next < run.until {
                return None;
            }
            self.running = self.score(next);
            if self.running.is_some() {
                return None; // settling under the set in service
            }
        }
        if self.finished && self.restore.is_none() {
            return None;
        }
        let start = match earliest {
            Some(e) => self.boundary_at_or_after(e.max(next)),
            None if self.is_boundary(next) => next,
            None => return None,
        };
        if let Some((version, values)) = self.restore.take() {
            // Measured on its first repetition like the baseline; the best known until then.
            self.best = (values.clone(), f64::INFINITY, version);
            self.best_tail = None;
            self.for_good = Some(version);
            self.running = Some(self.repetition(0, version, None, values.clone(), start));
            return Some(self.set(version, start, &values));
        }
        if self.tried >= self.spec.evaluations || self.stop {
            return self.finish(start);
        }
        if self.held {
            return None;
        }
        // None: the optimiser has nothing more to try (a hybrid whose last local search
        // converged before its budget): the best set goes in service as after the budget.
        let Some(index) = self.next_candidate() else {
            return self.finish(start);
        };
        let version = self.next_version;
        self.next_version += 1;
        let until = start + self.spec.repetition;
        let values = self.opt.candidates()[index].clone();
        let mut set = self.set(version, start, &values);
        set.until_seq = until;
        set.fallback_version = self.best.2;
        self.fallback = self.settle_target();
        self.running = Some(self.repetition(self.tried + 1, version, Some(index), values, start));
        self.tried += 1;
        Some(set)
    }

    fn is_boundary(&self, seq: u64) -> bool {
        seq >= self.spec.first && (seq - self.spec.first).is_multiple_of(self.spec.repetition)
    }

    fn boundary_at_or_after(&self, seq: u64) -> u64 {
        if seq <= self.spec.first {
            return self.spec.first;
        }
        let k = (seq - self.spec.first).div_ceil(self.spec.repetition);
        self.spec.boundary(k)
    }

    /// The index of the next candidate to try: the rest of the last `ask`, else a new one once
    /// every candidate of the last is scored (the optimiser told).
    fn next_candidate(&mut self) -> Option<usize> {
        if self.next_index < self.scored.len() {
            self.next_index += 1;
            return Some(self.next_index - 1);
        }
        if self.scored.iter().any(Option::is_none) {
            return None; // a trial of this generation is still out (realtime)
        }
        if !self.scored.is_empty() {
            let values: Vec<f64> = self
                .scored
                .iter()
                .map(|v| v.unwrap_or(f64::INFINITY))
                .collect();
            self.opt.tell_safety(&self.margins);
            self.opt.tell(&values);
        }
        let n = self.opt.ask().len();
        self.scored.clear();
        self.scored.resize(n, None);
        self.margins.clear();
        self.margins.resize(n, f64::NAN);
        self.next_index = 1;
        (n > 0).then_some(0)
    }

    /// Score the repetition that just ended, before sample `next`; returns the settle
    /// repetition to run next, if one is due (`optimiser.settle`).
    fn score(&mut self, next: u64) -> Option<Running> {
        let run = self.running.take()?;
        if run.settle {
            return self.score_settle(run, next);
        }
        let expected = run.until - run.start;
        if run.samples < expected {
            // Samples missed: not scored; a candidate goes back to be tried again.
            self.incomplete += 1;
            if let Some(i) = run.index {
                self.tried -= 1;
                self.requeue(i);
            }
            return self.settle_after(&run, next);
        }
        let cost = if run.aborted || !run.cost.total.is_finite() {
            f64::INFINITY
        } else {
            run.cost.total
        };
        // An aborted trial was unsafe whatever its samples showed (it may have been refused, or
        // left by its command, which the telemetry never shows): below 0, never on it.
        let margin = if run.aborted {
            run.margin.min(-ABORTED_MARGIN)
        } else {
            run.margin
        };
        if let Some(i) = run.index {
            self.scored[i] = Some(cost);
            self.margins[i] = margin;
        }
        if cost < self.best.1 {
            self.best = (run.values.clone(), cost, run.version);
            self.best_tail = Some((run.tail, false));
        }
        let (settle, unsettled) = match run.index {
            Some(_) => (std::mem::take(&mut self.settling), !self.settled),
            None => (0, false),
        };
        let next_settle = self.settle_after(&run, next);
        self.records.push(Repetition {
            trial: run.trial,
            version: run.version,
            start_seq: run.start,
            t: run.t,
            cost,
            aborted: run.aborted,
            margin,
            settle,
            unsettled,
            best: self.best.1,
            best_version: self.best.2,
            values: run.values,
        });
        next_settle
    }

    /// After trial `run` or the baseline (not a restored set), the first settle repetition,
    /// from the first boundary at or after `next`, when settling is on and another trial is
    /// due (not after the last, nor before an operator's stop or revert, which go out at the
    /// next boundary). The baseline settles too: from rest it does not start where the trials
    /// will, on the set's orbit, and its cost is taken there. A trial whose set in service has
    /// no complete repetition to settle to runs unsettled, and says so.
    fn settle_after(&mut self, run: &Running, next: u64) -> Option<Running> {
        self.settling = 0;
        self.settled = true;
        let baseline = run.index.is_none() && run.version == 0 && self.records.is_empty();
        let due = !(self.stop || self.restore.is_some() || self.tried >= self.spec.evaluations);
        if self.spec.settle == 0 || (run.index.is_none() && !baseline) || !due {
            return None;
        }
        if baseline {
            self.fallback = self.settle_target();
            self.baseline_settling = self.fallback.is_some();
        }
        let Some(target) = self.fallback else {
            self.settled = false;
            return None;
        };
        Some(self.settle_repetition(target.version, next))
    }

    /// What a settle segment under the best set settles to.
    fn settle_target(&self) -> Option<SettleTarget> {
        self.best_tail.map(|(last, on_orbit)| SettleTarget {
            version: self.best.2,
            last,
            on_orbit,
        })
    }

    fn settle_repetition(&mut self, version: u64, next: u64) -> Running {
        let start = self.boundary_at_or_after(next);
        self.settling += 1;
        self.settle_repetitions += 1;
        let mut run = self.repetition(0, version, None, Vec::new(), start);
        run.settle = true;
        run
    }

    /// One repetition of `values` from sample `start`, nothing seen yet.
    fn repetition(
        &self,
        trial: usize,
        version: u64,
        index: Option<usize>,
        values: Vec<f64>,
        start: u64,
    ) -> Running {
        let (rep, w) = (self.spec.repetition, self.spec.u_weight);
        Running::new(trial, version, index, values, start, rep, w)
    }

    /// A settle repetition ended: another one, unless the loop is back on the set in service's
    /// periodic orbit, this repetition ending in the band around the last settle repetition it
    /// served (or the most allowed have run, or an operator's stop or revert is due: the next
    /// trial says it started unsettled).
    fn score_settle(&mut self, run: Running, next: u64) -> Option<Running> {
        let target = self.fallback?;
        let complete = run.samples == run.until - run.start;
        self.settled =
            complete && target.on_orbit && run.tail.near(&target.last, self.spec.settle_band);
        if complete {
            self.fallback = Some(SettleTarget {
                last: run.tail,
                on_orbit: true,
                ..target
            });
            if target.version == self.best.2 {
                self.best_tail = Some((run.tail, true));
            }
            if self.baseline_settling && run.cost.total.is_finite() {
                self.baseline_on_orbit(&run);
            }
        }
        let interrupted = self.stop || self.restore.is_some();
        if self.settled || self.settling >= self.spec.settle || interrupted {
            self.baseline_settling = false;
            return None;
        }
        Some(self.settle_repetition(target.version, next))
    }

    /// Before the first trial: the baseline is the configured set on its orbit, measured on
    /// the settle repetition that just ended, the one every first trial is compared with.
    fn baseline_on_orbit(&mut self, run: &Running) {
        let Some(baseline) = self.records.first_mut() else {
            return;
        };
        baseline.cost = run.cost.total;
        baseline.best = run.cost.total;
        baseline.start_seq = run.start;
        baseline.t = run.t;
        baseline.margin = run.margin;
        self.best.1 = run.cost.total;
    }

    /// Put candidate `i` back in line (its trial was not scored). Candidates are sent in order,
    /// so it is the last one sent: step back to it.
    fn requeue(&mut self, i: usize) {
        debug_assert_eq!(self.next_index, i + 1);
        self.next_index = i;
    }

    /// The budget is spent: the best set for good (none if the configured set is still best).
    fn finish(&mut self, start: u64) -> Option<ParamSet> {
        self.finished = true;
        // The configured set, or an operator's revert, is already in service for good.
        if self.best.2 == 0 || Some(self.best.2) == self.for_good {
            return None;
        }
        let version = self.next_version;
        self.next_version += 1;
        let values = self.best.0.clone();
        Some(self.set(version, start, &values))
    }

    fn set(&self, version: u64, apply_at_seq: u64, values: &[f64]) -> ParamSet {
        ParamSet::new(version, apply_at_seq, self.kind, values)
    }
}

/// `direct.csv`: trial, start, cost, best so far, the version in service, the safety margin,
/// the settle repetitions before it, and the values.
fn records_csv(records: &[Repetition]) -> Csv {
    let n = records.first().map_or(0, |r| r.values.len());
    let fixed = [
        "trial",
        "t",
        "start_seq",
        "version",
        "aborted",
        "cost",
        "best",
        "best_version",
        "margin",
        "settle",
        "unsettled",
    ];
    let mut csv = Csv::new(
        fixed
            .map(String::from)
            .into_iter()
            .chain((0..n).map(|i| format!("p{i}"))),
    );
    for r in records {
        csv.row()
            .put(r.trial)
            .put(r.t)
            .put(r.start_seq)
            .put(r.version)
            .put(r.aborted)
            .put(r.cost)
            .put(r.best)
            .put(r.best_version)
            .put(r.margin)
            .put(r.settle)
            .put(r.unsettled)
            .all(&r.values);
    }
    csv
}

/// The direct scheme's part of optimiser.json.
#[derive(Debug, Clone, Default, Serialize, serde::Deserialize, PartialEq)]
pub struct DirectReport {
    /// The optimiser's name (`optimiser.algorithm`).
    pub algorithm: String,
    /// The optimiser's population size (`optimiser.population`).
    pub population: usize,
    /// Candidates the budget allows (repetitions spent on trials).
    pub evaluations: usize,
    /// Samples per repetition and the sample of the first trial.
    pub repetition_samples: u64,
    /// Sample at which the first trial starts (the baseline repetition ends there).
    pub first_seq: u64,
    /// Every repetition scored: the baseline first, then the trials in order.
    pub repetitions: Vec<Repetition>,
    /// The cost of the best set found (JSON null when no repetition was scored).
    #[serde(with = "crate::indirect::infinite_as_null")]
    pub best_cost: f64,
    /// The best set's version (0: the configured set).
    pub best_version: u64,
    /// The best set's parameter values.
    pub best_values: Vec<f64>,
    /// Trials aborted by the envelope (as the optimiser saw them: the controller left them).
    pub aborted: u64,
    /// Trials not scored (samples missed) and tried again.
    pub incomplete: u64,
    /// Repetitions spent settling under the set in service between trials
    /// (`optimiser.settle`), and trials that started before the loop was back in the band.
    #[serde(default)]
    pub settle_repetitions: u64,
    /// Trials that started before the loop was back in the band (`Repetition::unsettled`).
    #[serde(default)]
    pub unsettled: u64,
}

impl DirectTuner {
    /// The direct scheme's part of optimiser.json, as it stands: settings, every repetition
    /// scored, the best set and the counts.
    pub fn report(&self) -> DirectReport {
        DirectReport {
            algorithm: self.spec.algorithm.clone(),
            population: self.spec.population,
            evaluations: self.spec.evaluations,
            repetition_samples: self.spec.repetition,
            first_seq: self.spec.first,
            repetitions: self.records.clone(),
            best_cost: self.best.1,
            best_version: self.best.2,
            best_values: self.best.0.clone(),
            aborted: self.records.iter().filter(|r| r.aborted).count() as u64,
            incomplete: self.incomplete,
            settle_repetitions: self.settle_repetitions,
            unsettled: self.records.iter().filter(|r| r.unsettled).count() as u64,
        }
    }
}

/// What an in-process direct run produced.
pub struct InProcess {
    /// The tuner's report: settings, every repetition scored and the best set.
    pub report: DirectReport,
    /// The set in service at the end and its version.
    pub final_params: Vec<f64>,
    /// The version of the set in service at the end (0: the configured set).
    pub final_version: u64,
    /// Trials the controller aborted for leaving the safety envelope.
    pub trials_aborted: u64,
}

/// The direct scenario in this process, on the closed loop the processes run (lockstep): the
/// fast model of a live direct run, equal to it bit for bit. Keeps no samples (a run of 310
/// repetitions is half a million of them); `progress(repetitions, best)` after each repetition.
pub fn run_in_process(
    scn: &Scenario,
    progress: impl FnMut(usize, f64),
) -> Result<InProcess, SchemeError> {
    run_tuner_in_process(scn, DirectTuner::new(scn)?, progress)
}

/// `run_in_process` with a tuner of the caller's (`DirectTuner::with_optimiser`).
pub fn run_tuner_in_process(
    scn: &Scenario,
    tuner: DirectTuner,
    progress: impl FnMut(usize, f64),
) -> Result<InProcess, SchemeError> {
    scn.require_in_process()
        .map_err(SchemeError::NotInProcess)?;
    struct Hook<P> {
        tuner: DirectTuner,
        n: usize,
        progress: P,
    }
    impl<P: FnMut(usize, f64)> crate::sim::LoopHook for Hook<P> {
        fn before(&mut self, seq: u64, cycle: &mut crate::law::cycle::ControlCycle) {
            let scored = self.tuner.records.len();
            if let Some(set) = self.tuner.at(seq, None) {
                cycle.offer(&set);
            }
            if self.tuner.records.len() > scored {
                (self.progress)(self.tuner.records.len(), self.tuner.best().1);
            }
        }
        fn after(
            &mut self,
            s: &crate::msg::PlantState,
            tel: &crate::msg::Telemetry,
            _event: Option<crate::law::cycle::ParamEvent>,
            cycle: &crate::law::cycle::ControlCycle,
        ) {
            let n = self.n;
            self.tuner.observe(
                s.seq,
                s.t,
                &cycle.setpoint.q[..n],
                &s.y[..n],
                &tel.u[..n],
                tel.param_version,
            );
        }
    }
    let mut hook = Hook {
        tuner,
        n: scn.build_controller().n_outputs(),
        progress,
    };
    let end = crate::sim::run_loop(scn, &mut hook);
    Ok(InProcess {
        report: hook.tuner.report(),
        final_params: end.controller.params().to_vec(),
        final_version: end.version(),
        trials_aborted: end.trials_aborted,
    })
}

/// Write `direct.csv` and, with `plots`, `direct.png` (the paper's Fig. 7b measured: each
/// repetition's cost and the best so far). Returns the names written.
pub fn write_files(
    dir: &std::path::Path,
    report: &DirectReport,
    plots: bool,
) -> Result<Vec<&'static str>, WriteError> {
    let csv = dir.join("direct.csv");
    records_csv(&report.repetitions)
        .write(&csv)
        .map_err(WriteError::file(&csv))?;
    let mut names = vec!["direct.csv"];
    if plots && !report.repetitions.is_empty() {
        use crate::report::plot::{xy_png, Style, XySeries};
        let reps = &report.repetitions;
        let (mut xs, mut ys, mut xa) = (Vec::new(), Vec::new(), Vec::new());
        for r in reps {
            if r.cost.is_finite() {
                xs.push(r.trial as f64);
                ys.push(r.cost);
            } else {
                xa.push(r.trial as f64);
            }
        }
        let (bx, by): (Vec<f64>, Vec<f64>) = reps
            .iter()
            .filter(|r| r.best.is_finite())
            .map(|r| (r.trial as f64, r.best))
            .unzip();
        // Aborted trials on the top edge of the plotted range.
        let top = ys
            .iter()
            .chain(&by)
            .fold(f64::NEG_INFINITY, |m, v| m.max(*v));
        let ya = vec![top; xa.len()];
        let mut series = vec![
            XySeries {
                name: "cost of the repetition",
                x: &xs,
                y: &ys,
                style: Style::Points,
            },
            XySeries {
                name: "best so far",
                x: &bx,
                y: &by,
                style: Style::Line,
            },
        ];
        if !xa.is_empty() {
            series.push(XySeries {
                name: "aborted (safety envelope), drawn at the top",
                x: &xa,
                y: &ya,
                style: Style::Points,
            });
        }
        xy_png(
            &dir.join("direct.png"),
            &format!(
                "direct scheme: {} trials of {} on the plant, one repetition each (0 = the configured set)",
                reps.len().saturating_sub(1),
                report.algorithm
            ),
            "repetition",
            "cost of the repetition",
            &series,
            None,
            None,
        )
        .map_err(WriteError::Figure)?;
        names.push("direct.png");
    }
    Ok(names)
}
