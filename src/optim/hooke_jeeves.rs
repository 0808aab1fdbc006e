//! Hooke-Jeeves pattern search (Hooke & Jeeves 1961; used by the fuzzy-network paper's hybrid and
//! here as an optional local polish after DE): exploratory moves of +-step along each coordinate,
//! pattern moves along the last improvement, step halved when nothing improves. Bounded by
//! clamping to the box.

use serde::Serialize;

#[derive(Debug, Clone, Serialize)]
pub struct LocalResult {
    pub x: Vec<f64>,
    pub value: f64,
    pub evaluations: usize,
}

pub struct HookeJeeves {
    /// Initial step per coordinate, as a fraction of the box width.
    pub initial_step: f64,
    /// Stop when every step is below this fraction of the box width.
    pub min_step: f64,
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
    /// inside the box). At most `max_evaluations` calls of `f`.
    pub fn minimise_from(
        &self,
        f: impl Fn(&[f64]) -> f64,
        x0: &[f64],
        f0: Option<f64>,
        lower: &[f64],
        upper: &[f64],
    ) -> LocalResult {
        let d = x0.len();
        let width: Vec<f64> = (0..d).map(|i| upper[i] - lower[i]).collect();
        let mut step: Vec<f64> = width.iter().map(|w| w * self.initial_step).collect();
        let clamp = |x: &mut [f64]| {
            for i in 0..d {
                x[i] = x[i].clamp(lower[i], upper[i]);
            }
        };
        let evals = std::cell::Cell::new(0usize);
        // The budget is strict: past it every probe counts as "no better" without evaluating.
        let eval = |x: &[f64]| {
            if evals.get() >= self.max_evaluations {
                return f64::INFINITY;
            }
            evals.set(evals.get() + 1);
            let v = f(x);
            if v.is_nan() {
                f64::INFINITY
            } else {
                v
            }
        };
        let mut base = x0.to_vec();
        clamp(&mut base);
        let mut fbase = match f0 {
            Some(v) if base == x0 => v,
            _ => eval(&base),
        };
        // Exploratory moves around `x` (value fx); returns the improved point and value.
        let explore = |x: &[f64], fx: f64, step: &[f64], eval: &dyn Fn(&[f64]) -> f64| {
            let mut p = x.to_vec();
            let mut fp = fx;
            for i in 0..d {
                for dir in [1.0, -1.0] {
                    let old = p[i];
                    p[i] = (old + dir * step[i]).clamp(lower[i], upper[i]);
                    if p[i] == old {
                        continue;
                    }
                    let v = eval(&p);
                    if v < fp {
                        fp = v;
                        break;
                    }
                    p[i] = old;
                }
            }
            (p, fp)
        };
        loop {
            let (p, fp) = explore(&base, fbase, &step, &eval);
            if fp < fbase {
                // Pattern moves while they keep paying off.
                let mut prev = base.clone();
                base = p;
                fbase = fp;
                loop {
                    let mut q: Vec<f64> = (0..d).map(|i| 2.0 * base[i] - prev[i]).collect();
                    clamp(&mut q);
                    let fq = eval(&q);
                    let (r, fr) = explore(&q, fq, &step, &eval);
                    if fr < fbase {
                        prev = std::mem::replace(&mut base, r);
                        fbase = fr;
                    } else {
                        break;
                    }
                }
            } else {
                let mut all_small = true;
                for i in 0..d {
                    step[i] *= 0.5;
                    if step[i] > self.min_step * width[i] {
                        all_small = false;
                    }
                }
                if all_small {
                    break;
                }
            }
            if evals.get() >= self.max_evaluations {
                break;
            }
        }
        LocalResult {
            x: base,
            value: fbase,
            evaluations: evals.get(),
        }
    }
}
