//! The Savitzky-Golay smoother: a record's values and derivatives by a local polynomial fit over
//! a window either side of each sample. Non-causal and run over a whole record, offline: the
//! identification's velocity estimate and its low-pass of every signal a fit reads
//! (`evoloop-identify`'s RKGNN data), where the loop's estimators filter causally sample by
//! sample (`svf`).

/// The `deriv`-th derivative (0: the value) of `x`, sampled every `h` seconds, by a local
/// quadratic fit over `window` seconds either side (fewer samples if `x` is short).
pub fn smooth(x: &[f64], h: f64, window: f64, deriv: usize) -> Vec<f64> {
    smooth_where(x, h, window, deriv, |_| true)
}

/// `smooth` at the samples `wanted` picks, NaN at the others (`filter_where`).
pub fn smooth_where(
    x: &[f64],
    h: f64,
    window: f64,
    deriv: usize,
    wanted: impl Fn(usize) -> bool,
) -> Vec<f64> {
    let half = half_window(x.len(), h, window);
    let scale = h.powi(-(deriv as i32));
    filter_where(x, half, 2, deriv, wanted)
        .into_iter()
        .map(|v| v * scale)
        .collect()
}

/// Savitzky-Golay weights: fit a polynomial of `degree` by least squares to unit-spaced samples
/// at offsets -half..=half and take its `deriv`-th derivative, per unit spacing, at an offset
/// in -half..=half (`kernel(a)` for offset a - half): the centre's for inner samples, the others
/// for the ends.
/// The least-squares projection is the same for every offset: it is computed once, and a
/// kernel only where a sample needs it (a 1 601-sample window has 1 601 of them, and a filter
/// of the inner samples uses one).
struct SavitzkyGolay {
    half: usize,
    degree: usize,
    deriv: usize,
    /// (V^T V)^-1 V^T, `degree + 1` rows by 2 `half` + 1; `None` where V^T V is singular.
    coef: Option<nalgebra::DMatrix<f64>>,
}

impl SavitzkyGolay {
    fn new(half: usize, degree: usize, deriv: usize) -> Self {
        let m = half as f64;
        // Offsets scaled to [-1, 1] keep the normal equations well conditioned.
        let v = nalgebra::DMatrix::from_fn(2 * half + 1, degree + 1, |k, p| {
            ((k as f64 - m) / m.max(1.0)).powi(p as i32)
        });
        let coef = (v.transpose() * &v)
            .try_inverse()
            .map(|inv| inv * v.transpose());
        SavitzkyGolay {
            half,
            degree,
            deriv,
            coef,
        }
    }

    /// The weights that give the fit's derivative at offset `a` - `half` (a in 0..=2 `half`),
    /// NaN where the fit has no solution.
    fn kernel(&self, a: usize) -> Vec<f64> {
        let (m, width, degree, deriv) =
            (self.half as f64, 2 * self.half + 1, self.degree, self.deriv);
        let Some(coef) = &self.coef else {
            return vec![f64::NAN; width];
        };
        let scale = m.max(1.0).powi(-(deriv as i32));
        let s = (a as f64 - m) / m.max(1.0);
        // d^deriv/ds^deriv of sum_p c_p s^p at s, then per unit spacing (ds/dk = 1/m).
        let basis: Vec<f64> = (0..=degree)
            .map(|p| {
                if p < deriv {
                    0.0
                } else {
                    let falling: f64 = (p - deriv + 1..=p).map(|f| f as f64).product();
                    falling * s.powi((p - deriv) as i32)
                }
            })
            .collect();
        (0..width)
            .map(|k| scale * (0..=degree).map(|p| basis[p] * coef[(p, k)]).sum::<f64>())
            .collect()
    }
}

/// `smooth`'s half width in samples for `len` samples every `h` s: `window` s, at least 1, at
/// most what `len` holds.
pub fn half_window(len: usize, h: f64, window: f64) -> usize {
    ((window / h).round() as usize)
        .max(1)
        .min(len.saturating_sub(1) / 2)
}

/// `x` filtered by `SavitzkyGolay::new(half, degree, deriv)`: centred windows inside, the first
/// and last full window's fit evaluated at the ends, at the samples `wanted` picks only (NaN at
/// the others): the same sums where it is computed, in a fraction of the time where a fit reads
/// every `stride`-th sample of 10 kHz data through a window of 1 601 samples.
fn filter_where(
    x: &[f64],
    half: usize,
    degree: usize,
    deriv: usize,
    wanted: impl Fn(usize) -> bool,
) -> Vec<f64> {
    let len = x.len();
    if len < 2 * half + 1 || len <= degree {
        return if deriv == 0 {
            x.to_vec()
        } else {
            vec![0.0; len]
        };
    }
    let sg = SavitzkyGolay::new(half, degree, deriv);
    let mut kernels: Vec<Option<Vec<f64>>> = vec![None; 2 * half + 1];
    // Sample i's kernel (by offset) and window.
    let window = |i: usize| {
        let c = i.clamp(half, len - 1 - half);
        (i + half - c, &x[c - half..=c + half])
    };
    let mut out = vec![f64::NAN; len];
    let picked: Vec<usize> = (0..len).filter(|&i| wanted(i)).collect();
    // Four samples with one kernel (every inner one has the centre's) at a time: their sums
    // interleaved, each bit for bit its own (`linalg::dots`).
    for group in picked.chunks(LANES) {
        let a = window(group[0]).0;
        if group.len() == LANES && group.iter().all(|&i| window(i).0 == a) {
            let k = kernels[a].get_or_insert_with(|| sg.kernel(a));
            let sums: [f64; LANES] =
                crate::linalg::dots(k, std::array::from_fn(|t| window(group[t]).1));
            group.iter().zip(sums).for_each(|(&i, s)| out[i] = s);
        } else {
            for &i in group {
                let (a, w) = window(i);
                let k = kernels[a].get_or_insert_with(|| sg.kernel(a));
                out[i] = crate::linalg::dots(k, [w])[0];
            }
        }
    }
    out
}

/// How many samples `filter_where` sums side by side.
const LANES: usize = 4;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn savitzky_golay_is_exact_on_polynomials_of_its_degree_also_at_the_ends() {
        // x(k) = 2 - 0.5 k + 0.25 k^2 sampled every h: value and derivatives anywhere.
        let h = 0.01;
        let x: Vec<f64> = (0..50)
            .map(|i| {
                let t = i as f64 * h;
                2.0 - 0.5 * t + 0.25 * t * t
            })
            .collect();
        let want = |deriv: usize, t: f64| match deriv {
            0 => 2.0 - 0.5 * t + 0.25 * t * t,
            1 => -0.5 + 0.5 * t,
            _ => 0.5,
        };
        for deriv in 0..3 {
            let scale = h.powi(-(deriv as i32));
            for (i, g) in filter_where(&x, 7, 2, deriv, |_| true).iter().enumerate() {
                let w = want(deriv, i as f64 * h);
                assert!(
                    (g * scale - w).abs() < 1e-9,
                    "deriv {deriv} at {i}: {} vs {w}",
                    g * scale
                );
            }
        }
    }
}
