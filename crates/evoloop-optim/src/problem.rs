//! The benchmark suite's functions as problems over their boxes, plain or as shifted and rotated
//! copies.
//!
//! Shifted copies: GWO and WOA move towards the origin by construction (their updates scale
//! positions towards the leaders and shrink them), so on functions whose minimiser is the
//! origin they are flattered. Every origin-centred function therefore also runs as
//! `<key>_shifted`: g(x) = f(R (x - o)), o uniform in the middle 80 % of the box and R a random
//! rotation, both drawn from a fixed seed per function (the same copy for every algorithm and
//! run). g has f's minimum f_min at x = o.

use crate::suite::{self, Function};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;
use std::cell::RefCell;

/// A shift and rotation: g(x) = f(R (x - o)).
#[derive(Debug, Clone, Serialize)]
pub struct Shift {
    /// o, the shifted copy's minimiser: uniform in the middle 80 % of each dimension's range.
    pub offset: Vec<f64>,
    /// R, row-major, D x D.
    pub rotation: Vec<f64>,
}

/// A function of the suite as the study runs it, plain or shifted.
#[derive(Debug, Clone)]
pub struct Problem {
    /// The problem's key: the function's, with `_shifted` appended for a shifted copy.
    pub key: String,
    /// The suite function it evaluates.
    pub function: &'static Function,
    /// The shift and rotation of a shifted copy; None for the plain function.
    pub shift: Option<Shift>,
}

thread_local! {
    /// R (x - o) of a shifted problem: one buffer per thread, so evaluating allocates nothing.
    static ROTATED: RefCell<Vec<f64>> = const { RefCell::new(Vec::new()) };
}

/// The seed of a function's shifted copy: fixed per key (FNV-1a of it).
fn shift_seed(key: &str) -> u64 {
    key.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A random rotation (Haar-distributed): Gram-Schmidt on a Gaussian matrix, rows orthonormal.
fn rotation(d: usize, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut r: Vec<f64> = (0..d * d).map(|_| StandardNormal.sample(rng)).collect();
    for i in 0..d {
        for k in 0..i {
            let dot: f64 = (0..d).map(|j| r[i * d + j] * r[k * d + j]).sum();
            for j in 0..d {
                r[i * d + j] -= dot * r[k * d + j];
            }
        }
        let norm = (0..d).map(|j| r[i * d + j].powi(2)).sum::<f64>().sqrt();
        for j in 0..d {
            r[i * d + j] /= norm;
        }
    }
    r
}

impl Problem {
    /// The suite function as it is, under its own key.
    pub fn plain(function: &'static Function) -> Self {
        Self {
            key: function.key.into(),
            function,
            shift: None,
        }
    }

    /// The shifted and rotated copy (module docs).
    pub fn shifted(function: &'static Function) -> Self {
        let key = format!("{}_shifted", function.key);
        let mut rng = ChaCha8Rng::seed_from_u64(shift_seed(&key));
        let (lower, upper) = function.bounds();
        let offset = lower
            .iter()
            .zip(&upper)
            .map(|(l, u)| {
                let m = 0.1 * (u - l);
                rng.gen_range(l + m..u - m)
            })
            .collect();
        let rotation = rotation(function.dim, &mut rng);
        Self {
            key,
            function,
            shift: Some(Shift { offset, rotation }),
        }
    }

    /// Whether the function's minimiser is the origin (it gets a shifted copy).
    pub fn origin_centred(function: &Function) -> bool {
        (function.argmin)(function.dim).iter().all(|v| *v == 0.0)
    }

    /// The box as lower and upper bound vectors (the function's own, shifted or not).
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        self.function.bounds()
    }

    /// The global minimum value (a shifted copy keeps the function's).
    pub fn f_min(&self) -> f64 {
        self.function.f_min
    }

    /// The function's group in the paper: "unimodal", "multimodal", "constant" or "extra".
    pub fn group(&self) -> &'static str {
        self.function.group
    }

    /// A minimiser.
    pub fn argmin(&self) -> Vec<f64> {
        match &self.shift {
            Some(s) => s.offset.clone(),
            None => (self.function.argmin)(self.function.dim),
        }
    }

    /// g(x) = f(R (x - o)) for a shifted copy, f(x) for the plain function.
    pub fn value(&self, x: &[f64]) -> f64 {
        let Some(s) = &self.shift else {
            return (self.function.f)(x);
        };
        ROTATED.with(|buf| {
            let mut y = buf.borrow_mut();
            let d = x.len();
            y.resize(d, 0.0);
            for (i, yi) in y.iter_mut().enumerate() {
                let row = &s.rotation[i * d..(i + 1) * d];
                *yi = row
                    .iter()
                    .zip(x.iter().zip(&s.offset))
                    .map(|(r, (xj, oj))| r * (xj - oj))
                    .sum();
            }
            (self.function.f)(&y)
        })
    }
}

/// The problems of a study: the named functions (all when `keys` is None, `<key>_shifted`
/// allowed), each origin-centred one followed by its shifted copy when `shifted` is set and no
/// keys are named.
pub fn problems(keys: Option<&[String]>, shifted: bool) -> Result<Vec<Problem>, ProblemError> {
    let Some(keys) = keys else {
        let mut out = Vec::new();
        for f in suite::all() {
            out.push(Problem::plain(f));
            if shifted && Problem::origin_centred(f) {
                out.push(Problem::shifted(f));
            }
        }
        return Ok(out);
    };
    keys.iter()
        .map(|k| {
            let (base, is_shifted) = match k.strip_suffix("_shifted") {
                Some(b) => (b, true),
                None => (k.as_str(), false),
            };
            let f = suite::get(base).ok_or_else(|| ProblemError::Unknown(k.clone()))?;
            if !is_shifted {
                Ok(Problem::plain(f))
            } else if Problem::origin_centred(f) {
                Ok(Problem::shifted(f))
            } else {
                Err(ProblemError::NoShiftedCopy(k.clone()))
            }
        })
        .collect()
}

/// A function key `problems` refuses.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProblemError {
    /// No function of the suite has this key.
    Unknown(String),
    /// `<key>_shifted` for a function that is not origin-centred, so it has no shifted copy.
    NoShiftedCopy(String),
}

impl std::fmt::Display for ProblemError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ProblemError::Unknown(k) => write!(
                f,
                "unknown function {k:?} (known: {}, and <key>_shifted for origin-centred ones)",
                suite::all()
                    .iter()
                    .map(|f| f.key)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            ProblemError::NoShiftedCopy(k) => {
                let base = k.strip_suffix("_shifted").unwrap_or(k);
                write!(
                    f,
                    "{k:?}: {base} is not origin-centred, it has no shifted copy"
                )
            }
        }
    }
}

impl std::error::Error for ProblemError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shifted_copy_has_its_minimum_at_the_offset_and_is_a_rotation() {
        for f in suite::all().iter().filter(|f| Problem::origin_centred(f)) {
            let p = Problem::shifted(f);
            let o = p.argmin();
            let (lo, hi) = p.bounds();
            assert!(o
                .iter()
                .zip(lo.iter().zip(&hi))
                .all(|(v, (l, h))| l < v && v < h));
            assert!(
                (p.value(&o) - f.f_min).abs() < 1e-12,
                "{}: {}",
                p.key,
                p.value(&o)
            );
            // R is orthonormal: R R^T = I.
            let s = p.shift.as_ref().unwrap();
            let d = f.dim;
            for i in 0..d {
                for k in 0..d {
                    let dot: f64 = (0..d)
                        .map(|j| s.rotation[i * d + j] * s.rotation[k * d + j])
                        .sum();
                    assert!((dot - if i == k { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
            // The sphere's copy is |x - o|^2 (rotation-invariant): checks R (x - o) itself.
            if f.key == "sphere" {
                let x: Vec<f64> = (0..d).map(|j| j as f64 - 10.0).collect();
                let direct: f64 = x.iter().zip(&o).map(|(a, b)| (a - b).powi(2)).sum();
                assert!((p.value(&x) - direct).abs() < 1e-9 * direct);
            }
        }
        // Same key, same copy.
        let a = Problem::shifted(suite::get("rastrigin").unwrap());
        let b = Problem::shifted(suite::get("rastrigin").unwrap());
        assert_eq!(a.argmin(), b.argmin());
    }

    #[test]
    fn the_origin_centred_functions_are_the_expected_ones() {
        let keys: Vec<&str> = suite::all()
            .iter()
            .filter(|f| Problem::origin_centred(f))
            .map(|f| f.key)
            .collect();
        for k in ["sphere", "griewank", "rastrigin", "ackley", "schwefel_1_2"] {
            assert!(keys.contains(&k), "{k} in {keys:?}");
        }
        for k in ["rosenbrock", "beale", "shekel5", "easom"] {
            assert!(!keys.contains(&k), "{k}");
        }
    }

    #[test]
    fn unknown_or_unshiftable_functions_are_refused_by_name() {
        let e = problems(Some(&["nope".into()]), true).unwrap_err();
        assert_eq!(e, ProblemError::Unknown("nope".into()));
        let text = e.to_string();
        assert!(
            text.contains("\"nope\"") && text.contains("sphere"),
            "{text}"
        );
        let e = problems(Some(&["rosenbrock_shifted".into()]), true).unwrap_err();
        assert_eq!(e, ProblemError::NoShiftedCopy("rosenbrock_shifted".into()));
        assert!(
            e.to_string().contains("rosenbrock is not origin-centred"),
            "{e}"
        );
        let all = problems(None, true).unwrap();
        assert!(all.iter().any(|p| p.key == "rastrigin_shifted"));
        assert_eq!(problems(None, false).unwrap().len(), 37);
    }
}
