//! Hooke-Jeeves in its ask/tell form (`HjSearch`, which `minimise_from` drives) makes exactly the
//! evaluations of the loop form it replaced (kept here as the reference, verbatim): the same
//! points in the same order, the same result and count, on smooth, clamped, NaN-producing and
//! budget-limited problems.

use evoloop::optim::{HjSearch, HookeJeeves, LocalResult, Optimiser};
use std::cell::RefCell;

#[allow(clippy::needless_range_loop)]
fn reference(
    cfg: &HookeJeeves,
    f: impl Fn(&[f64]) -> f64,
    x0: &[f64],
    f0: Option<f64>,
    lower: &[f64],
    upper: &[f64],
) -> LocalResult {
    let d = x0.len();
    let width: Vec<f64> = (0..d).map(|i| upper[i] - lower[i]).collect();
    let mut step: Vec<f64> = width.iter().map(|w| w * cfg.initial_step).collect();
    let clamp = |x: &mut [f64]| {
        for i in 0..d {
            x[i] = x[i].clamp(lower[i], upper[i]);
        }
    };
    let evals = std::cell::Cell::new(0usize);
    // The budget is strict: past it every probe counts as "no better" without evaluating.
    let eval = |x: &[f64]| {
        if evals.get() >= cfg.max_evaluations {
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
                if step[i] > cfg.min_step * width[i] {
                    all_small = false;
                }
            }
            if all_small {
                break;
            }
        }
        if evals.get() >= cfg.max_evaluations {
            break;
        }
    }
    LocalResult {
        x: base,
        value: fbase,
        evaluations: evals.get(),
    }
}

fn sequences(
    cfg: &HookeJeeves,
    f: &dyn Fn(&[f64]) -> f64,
    x0: &[f64],
    f0: Option<f64>,
    lo: &[f64],
    hi: &[f64],
) {
    let seen_ref = RefCell::new(Vec::new());
    let r = reference(
        cfg,
        |x| {
            seen_ref.borrow_mut().push(x.to_vec());
            f(x)
        },
        x0,
        f0,
        lo,
        hi,
    );
    let mut s = HjSearch::new(cfg, x0, f0, lo, hi);
    let mut seen = Vec::new();
    while !s.converged() {
        let v: Vec<f64> = s
            .ask()
            .iter()
            .map(|x| {
                seen.push(x.clone());
                f(x)
            })
            .collect();
        s.tell(&v);
    }
    assert_eq!(seen, *seen_ref.borrow(), "evaluation sequences differ");
    let (x, v) = s.best();
    assert_eq!(
        (x.to_vec(), v.to_bits(), s.evaluations()),
        (r.x.clone(), r.value.to_bits(), r.evaluations)
    );
    let via: LocalResult = cfg.minimise_from(f, x0, f0, lo, hi);
    assert_eq!(
        (via.x, via.value.to_bits(), via.evaluations),
        (r.x, r.value.to_bits(), r.evaluations)
    );
}

#[test]
fn ask_tell_makes_exactly_the_loop_forms_evaluations() {
    let rosen = |x: &[f64]| {
        (0..x.len() - 1)
            .map(|i| 100.0 * (x[i + 1] - x[i] * x[i]).powi(2) + (1.0 - x[i]).powi(2))
            .sum::<f64>()
    };
    let shifted = |x: &[f64]| {
        x.iter()
            .enumerate()
            .map(|(i, v)| (v - 4.9 + 0.3 * i as f64).powi(2))
            .sum::<f64>()
    };
    let nan_hole = |x: &[f64]| {
        if x[0] > 0.5 {
            f64::NAN
        } else {
            (x[0] - 0.7).powi(2) + x[1] * x[1]
        }
    };
    let default = HookeJeeves::default();
    let coarse = HookeJeeves {
        initial_step: 0.2,
        min_step: 1e-6,
        max_evaluations: 5000,
    };
    let tight = HookeJeeves {
        initial_step: 0.1,
        min_step: 1e-12,
        max_evaluations: 37,
    };
    for cfg in [&default, &coarse, &tight] {
        sequences(cfg, &rosen, &[-1.2, 1.0, 0.5], None, &[-2.0; 3], &[2.0; 3]);
        // The optimum outside the box on some coordinates: clamped probes are skipped.
        sequences(
            cfg,
            &shifted,
            &[0.0, 0.0, 0.0, 0.0],
            None,
            &[-5.0; 4],
            &[4.5; 4],
        );
        sequences(cfg, &nan_hole, &[0.0, 0.3], None, &[-1.0; 2], &[1.0; 2]);
        // A known starting value, and a starting point outside the box (re-evaluated).
        sequences(
            cfg,
            &rosen,
            &[0.5, 0.5, 0.5],
            Some(rosen(&[0.5, 0.5, 0.5])),
            &[-2.0; 3],
            &[2.0; 3],
        );
        sequences(
            cfg,
            &rosen,
            &[3.0, 0.5, 0.5],
            Some(0.0),
            &[-2.0; 3],
            &[2.0; 3],
        );
    }
}
