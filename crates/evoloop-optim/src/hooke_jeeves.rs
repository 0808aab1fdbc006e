//! Hooke-Jeeves pattern search (Hooke & Jeeves 1961; used by the fuzzy-network paper's hybrid and
//! here as an optional local polish after DE): exploratory moves of +-step along each coordinate,
//! pattern moves along the last improvement, step halved when nothing improves. Bounded by
//! clamping to the box.

use super::Optimiser;
use serde::Serialize;

/// Where a Hooke-Jeeves search ended: its best point, that point's value and the cost.
#[derive(Debug, Clone, Serialize)]
pub struct LocalResult {
    /// Best point found (within the box).
    pub x: Vec<f64>,
    /// Its objective value.
    pub value: f64,
    /// Objective evaluations the search made (a known starting value not counted).
    pub evaluations: usize,
}

/// Hooke-Jeeves settings; the defaults are a step of 1 % of the box, a smallest step of
/// 1e-9 of it and 20 000 evaluations.
pub struct HookeJeeves {
    /// Initial step per coordinate, as a fraction of the box width.
    pub initial_step: f64,
    /// Stop when every step is below this fraction of the box width.
    pub min_step: f64,
    /// Evaluation budget: the search stops once it has made this many.
    pub max_evaluations: usize,
}

impl Default for HookeJeeves {
    fn default() -> Self {
        Self {
            initial_step: 0.01,
            min_step: 1e-9,
            max_evaluations: 20_000,
        }
    }
}

impl HookeJeeves {
    /// Minimise `f` in the box `lower..upper` from `x0` (clamped into it); the starting value
    /// is evaluated here.
    pub fn minimise(
        &self,
        f: impl Fn(&[f64]) -> f64,
        x0: &[f64],
        lower: &[f64],
        upper: &[f64],
    ) -> LocalResult {
        self.minimise_from(f, x0, None, lower, upper)
    }

    /// As `minimise`, with the value at x0 already known (`f0`, not re-evaluated when x0 is
    /// inside the box). At most `max_evaluations` calls of `f`. Drives `HjSearch`, the ask/tell
    /// form.
    pub fn minimise_from(
        &self,
        f: impl Fn(&[f64]) -> f64,
        x0: &[f64],
        f0: Option<f64>,
        lower: &[f64],
        upper: &[f64],
    ) -> LocalResult {
        let mut s = HjSearch::new(self, x0, f0, lower, upper);
        while !s.converged() {
            let v: Vec<f64> = s.ask().iter().map(|x| f(x)).collect();
            s.tell(&v);
        }
        LocalResult {
            x: s.base.clone(),
            value: s.fbase,
            evaluations: s.evaluations,
        }
    }
}

/// Where an exploratory sweep is going, and what happens when it ends.
#[derive(Debug, Clone)]
enum Context {
    /// Around the base point: on success a pattern move follows, otherwise the steps halve.
    Base,
    /// Around a pattern point: on success another pattern move, otherwise a new iteration.
    Pattern,
}

#[derive(Debug, Clone)]
enum Phase {
    /// The value of the (clamped) starting point is wanted.
    Start,
    /// An exploratory sweep: point `p` with value `fp`, probing coordinate `i` in direction
    /// `dir` (0: +step, 1: -step); `old` is p[i] before the probe.
    Explore {
        ctx: Context,
        p: Vec<f64>,
        fp: f64,
        i: usize,
        dir: usize,
        old: f64,
    },
    /// The pattern point q = 2 base - prev is being evaluated.
    Pattern {
        q: Vec<f64>,
    },
    Done,
}

/// Hooke-Jeeves as an ask/tell optimiser (one candidate per `ask`), making exactly the
/// evaluations of the loop form: exploratory moves of +-step per coordinate, pattern moves while
/// they pay, steps halved when nothing improves; the budget is strict.
pub struct HjSearch {
    lower: Vec<f64>,
    upper: Vec<f64>,
    width: Vec<f64>,
    step: Vec<f64>,
    min_step: f64,
    max_evaluations: usize,
    base: Vec<f64>,
    fbase: f64,
    evaluations: usize,
    phase: Phase,
    asked: Vec<Vec<f64>>,
}

impl HjSearch {
    /// A search from `x0` (clamped into the box `lower..upper`) with the settings `cfg`; `f0`,
    /// the value at `x0`, is used only when `x0` lies inside the box, otherwise evaluated.
    pub fn new(
        cfg: &HookeJeeves,
        x0: &[f64],
        f0: Option<f64>,
        lower: &[f64],
        upper: &[f64],
    ) -> Self {
        let d = x0.len();
        let width: Vec<f64> = (0..d).map(|i| upper[i] - lower[i]).collect();
        let base: Vec<f64> = (0..d).map(|i| x0[i].clamp(lower[i], upper[i])).collect();
        let known = f0.filter(|_| base == x0);
        let mut s = Self {
            step: width.iter().map(|w| w * cfg.initial_step).collect(),
            width,
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            min_step: cfg.min_step,
            max_evaluations: cfg.max_evaluations,
            fbase: known.unwrap_or(f64::INFINITY),
            base,
            evaluations: 0,
            phase: Phase::Start,
            asked: Vec::new(),
        };
        if known.is_some() {
            s.phase = s.explore(Context::Base, s.base.clone(), s.fbase);
        }
        s.advance();
        s
    }

    /// A new sweep around `x` (value fx), positioned before its first probe.
    fn explore(&self, ctx: Context, x: Vec<f64>, fx: f64) -> Phase {
        let old = x.first().copied().unwrap_or(0.0);
        Phase::Explore {
            ctx,
            p: x,
            fp: fx,
            i: 0,
            dir: 0,
            old,
        }
    }

    /// After an outer iteration: stop on the budget, else sweep around the base again.
    fn next_iteration(&self) -> Phase {
        if self.evaluations >= self.max_evaluations {
            Phase::Done
        } else {
            self.explore(Context::Base, self.base.clone(), self.fbase)
        }
    }

    /// A sweep has ended at (p, fp): the loop form's continuation.
    fn swept(&mut self, ctx: Context, p: Vec<f64>, fp: f64) -> Phase {
        match ctx {
            Context::Base if fp < self.fbase => {
                let prev = std::mem::replace(&mut self.base, p);
                self.fbase = fp;
                self.pattern(prev)
            }
            Context::Base => {
                let mut all_small = true;
                for i in 0..self.step.len() {
                    self.step[i] *= 0.5;
                    if self.step[i] > self.min_step * self.width[i] {
                        all_small = false;
                    }
                }
                if all_small {
                    Phase::Done
                } else {
                    self.next_iteration()
                }
            }
            Context::Pattern if fp < self.fbase => {
                let prev = std::mem::replace(&mut self.base, p);
                self.fbase = fp;
                self.pattern(prev)
            }
            Context::Pattern => self.next_iteration(),
        }
    }

    fn pattern(&self, prev: Vec<f64>) -> Phase {
        let q: Vec<f64> = (0..self.base.len())
            .map(|i| (2.0 * self.base[i] - prev[i]).clamp(self.lower[i], self.upper[i]))
            .collect();
        Phase::Pattern { q }
    }

    /// The point the current phase wants evaluated, moving past sweeps' probes that clamping
    /// makes empty and past sweeps that end; None when done.
    fn probe(&mut self) -> Option<Vec<f64>> {
        loop {
            match &mut self.phase {
                Phase::Done => return None,
                Phase::Start => return Some(self.base.clone()),
                Phase::Pattern { q, .. } => return Some(q.clone()),
                Phase::Explore { p, i, dir, old, .. } => {
                    if *i < p.len() {
                        let step = if *dir == 0 {
                            self.step[*i]
                        } else {
                            -self.step[*i]
                        };
                        *old = p[*i];
                        let x = (*old + step).clamp(self.lower[*i], self.upper[*i]);
                        if x == *old {
                            Self::next_direction(i, dir);
                            continue;
                        }
                        let mut c = p.clone();
                        c[*i] = x;
                        return Some(c);
                    }
                    let Phase::Explore { ctx, p, fp, .. } =
                        std::mem::replace(&mut self.phase, Phase::Done)
                    else {
                        unreachable!()
                    };
                    self.phase = self.swept(ctx, p, fp);
                }
            }
        }
    }

    fn next_direction(i: &mut usize, dir: &mut usize) {
        if *dir == 0 {
            *dir = 1;
        } else {
            *dir = 0;
            *i += 1;
        }
    }

    /// Take the value `v` of the probe `x` (NaN counts as infinite).
    fn take(&mut self, x: Vec<f64>, v: f64) {
        let v = if v.is_nan() { f64::INFINITY } else { v };
        match std::mem::replace(&mut self.phase, Phase::Done) {
            Phase::Start => {
                self.fbase = v;
                self.phase = self.explore(Context::Base, self.base.clone(), v);
            }
            Phase::Pattern { q } => {
                self.phase = self.explore(Context::Pattern, q, v);
            }
            Phase::Explore {
                ctx,
                mut p,
                mut fp,
                mut i,
                mut dir,
                old,
            } => {
                if v < fp {
                    fp = v;
                    p[i] = x[i];
                    i += 1;
                    dir = 0;
                } else {
                    p[i] = old;
                    Self::next_direction(&mut i, &mut dir);
                }
                self.phase = Phase::Explore {
                    ctx,
                    p,
                    fp,
                    i,
                    dir,
                    old,
                };
            }
            Phase::Done => {}
        }
    }

    /// Find the next probe; past the budget a probe counts as "no better" without evaluating,
    /// exactly as in the loop form, until the outer iteration ends.
    fn advance(&mut self) {
        self.asked.clear();
        while let Some(x) = self.probe() {
            if self.evaluations < self.max_evaluations {
                self.asked.push(x);
                return;
            }
            self.take(x, f64::INFINITY);
        }
    }
}

impl Optimiser for HjSearch {
    fn ask(&mut self) -> &[Vec<f64>] {
        &self.asked
    }
    fn candidates(&self) -> &[Vec<f64>] {
        &self.asked
    }
    fn tell(&mut self, values: &[f64]) {
        if let (Some(x), Some(v)) = (self.asked.first().cloned(), values.first()) {
            self.evaluations += 1;
            self.take(x, *v);
        }
        self.advance();
    }
    fn best(&self) -> (&[f64], f64) {
        (&self.base, self.fbase)
    }
    fn generation(&self) -> usize {
        self.evaluations
    }
    fn evaluations(&self) -> usize {
        self.evaluations
    }
    fn converged(&self) -> bool {
        matches!(self.phase, Phase::Done) && self.asked.is_empty()
    }
}
