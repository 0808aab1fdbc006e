//! Statistics for claims over many seeds (the studies and reports of every crate above): mean with
//! a 95 % t interval, the paired Wilcoxon signed-rank test (exact null distribution for up to 30
//! untied pairs, normal approximation with tie and continuity corrections beyond that or with
//! ties), and the Mann-Whitney U test for unpaired samples.

#![forbid(unsafe_code)]

use serde::Serialize;

/// Mean, sample standard deviation and 95 % confidence interval of the mean (Student t).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct MeanCi {
    /// Number of values.
    pub n: usize,
    /// Arithmetic mean of the values (NaN for none).
    pub mean: f64,
    /// Sample standard deviation (divisor n - 1; NaN for fewer than two values).
    pub std: f64,
    /// Lower and upper ends of the 95 % Student t interval of the mean (NaN for fewer than
    /// two values).
    pub ci95: [f64; 2],
}

/// t_{0.975, df} for df = 1..=30; beyond, the normal quantile with a 1/df correction.
fn t975(df: usize) -> f64 {
    const T: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => f64::NAN,
        1..=30 => T[df - 1],
        _ => 1.959964 + 2.37 / df as f64,
    }
}

/// Mean, sample standard deviation and 95 % t interval of the mean of `x`. The spread and
/// interval are NaN for fewer than two values, and the mean too for none.
pub fn mean_ci(x: &[f64]) -> MeanCi {
    let n = x.len();
    let mean = x.iter().sum::<f64>() / n as f64;
    let var = if n > 1 {
        x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64
    } else {
        f64::NAN
    };
    let std = var.sqrt();
    let half = t975(n.saturating_sub(1)) * std / (n as f64).sqrt();
    MeanCi {
        n,
        mean,
        std,
        ci95: [mean - half, mean + half],
    }
}

/// A paired Wilcoxon signed-rank test of a against b (differences d = a - b; zero differences
/// dropped, as Wilcoxon does). `p` is two-sided; `w_minus` small means a is mostly below b.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Wilcoxon {
    /// Pairs with a non-zero difference.
    pub n: usize,
    /// Rank sums of the positive and negative differences.
    pub w_plus: f64,
    /// Rank sum of the negative differences (a below b); `w_plus + w_minus` is n (n + 1) / 2.
    pub w_minus: f64,
    /// Two-sided p value, capped at 1 (1 when no pair differs).
    pub p_two_sided: f64,
    /// "exact" or "normal".
    pub method: &'static str,
    /// Pairs where a < b, and where a > b.
    pub a_lower: usize,
    /// Pairs where a > b; with `a_lower` it sums to `n`.
    pub a_higher: usize,
}

/// Average ranks (1-based) of `v` sorted ascending; ties share their mean rank. Also returns
/// the tie correction sum of (t^3 - t).
fn ranks(v: &[f64]) -> (Vec<f64>, f64) {
    let mut idx: Vec<usize> = (0..v.len()).collect();
    idx.sort_by(|a, b| v[*a].total_cmp(&v[*b]));
    let mut r = vec![0.0; v.len()];
    let mut ties = 0.0;
    let mut i = 0;
    while i < idx.len() {
        let mut j = i;
        while j + 1 < idx.len() && v[idx[j + 1]] == v[idx[i]] {
            j += 1;
        }
        let avg = (i + j) as f64 / 2.0 + 1.0;
        for k in &idx[i..=j] {
            r[*k] = avg;
        }
        let t = (j - i + 1) as f64;
        ties += t * t * t - t;
        i = j + 1;
    }
    (r, ties)
}

/// Number of subsets of {1..n} with each rank sum (the exact null distribution of W+).
fn signed_rank_counts(n: usize) -> Vec<f64> {
    let max = n * (n + 1) / 2;
    let mut c = vec![0.0; max + 1];
    c[0] = 1.0;
    for k in 1..=n {
        for s in (k..=max).rev() {
            c[s] += c[s - k];
        }
    }
    c
}

/// The median (the mean of the middle two for an even count; NaN for none).
pub fn median(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => s[n / 2],
        _ => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// The median of the values that are numbers (NaN marks one missing: a run not made, an error
/// undefined); NaN if none is.
pub fn median_of_numbers(v: impl IntoIterator<Item = f64>) -> f64 {
    median(&v.into_iter().filter(|x| !x.is_nan()).collect::<Vec<_>>())
}

/// Standard normal density phi(z).
pub fn normal_pdf(z: f64) -> f64 {
    (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt()
}

/// Standard normal distribution function Phi(z) (relative error < 1.2e-7, `erfc`'s).
pub fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z / std::f64::consts::SQRT_2)
}

/// Standard normal upper tail.
fn normal_sf(z: f64) -> f64 {
    0.5 * erfc(z / std::f64::consts::SQRT_2)
}

/// erfc by the Numerical Recipes Chebyshev fit (relative error < 1.2e-7).
fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let r = t
        * (-z * z - 1.26551223
            + t * (1.00002368
                + t * (0.37409196
                    + t * (0.09678418
                        + t * (-0.18628806
                            + t * (0.27886807
                                + t * (-1.13520398
                                    + t * (1.48851587 + t * (-0.82215223 + t * 0.17087277)))))))))
            .exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Paired Wilcoxon signed-rank test. Infinite values (a failed run) are allowed: a pair where
/// only one side failed has an infinite difference (the largest rank); both failed is a tie.
pub fn wilcoxon(a: &[f64], b: &[f64]) -> Wilcoxon {
    assert_eq!(a.len(), b.len());
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .filter_map(|(x, y)| {
            let d = if x == y { 0.0 } else { x - y };
            (d != 0.0 && !d.is_nan()).then_some(d)
        })
        .collect();
    let n = d.len();
    let (r, ties) = ranks(&d.iter().map(|v| v.abs()).collect::<Vec<_>>());
    let w_plus: f64 = d
        .iter()
        .zip(&r)
        .filter(|(v, _)| **v > 0.0)
        .map(|(_, r)| r)
        .sum();
    let total = (n * (n + 1)) as f64 / 2.0;
    let w_minus = total - w_plus;
    let a_lower = d.iter().filter(|v| **v < 0.0).count();
    let (p, method) = if n == 0 {
        (1.0, "exact")
    } else if n <= 30 && ties == 0.0 {
        let c = signed_rank_counts(n);
        let all = 2f64.powi(n as i32);
        let w = w_plus.min(w_minus).round() as usize;
        let tail: f64 = c[..=w].iter().sum::<f64>() / all;
        ((2.0 * tail).min(1.0), "exact")
    } else {
        let mean = total / 2.0;
        let var = (n * (n + 1) * (2 * n + 1)) as f64 / 24.0 - ties / 48.0;
        let z = ((w_plus - mean).abs() - 0.5).max(0.0) / var.sqrt();
        ((2.0 * normal_sf(z)).min(1.0), "normal")
    };
    Wilcoxon {
        n,
        w_plus,
        w_minus,
        p_two_sided: p,
        method,
        a_lower,
        a_higher: n - a_lower,
    }
}

/// Mann-Whitney U (Wilcoxon rank-sum) test of two independent samples: for comparing runs that
/// share no seeds (another library's random streams). SciPy's `mannwhitneyu` choices: exact null
/// distribution when a sample has fewer than 8 values and there are no ties, otherwise the
/// normal approximation with tie and continuity corrections. `p` is two-sided.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct MannWhitney {
    /// Number of values in sample a.
    pub n_a: usize,
    /// Number of values in sample b.
    pub n_b: usize,
    /// U of sample a: pairs (x in a, y in b) with x > y, ties counting one half.
    pub u_a: f64,
    /// Two-sided p value, capped at 1 (1 when either sample is empty).
    pub p_two_sided: f64,
    /// "exact" or "normal".
    pub method: &'static str,
}

impl MannWhitney {
    /// Whether a tends to be lower than b (U below its null mean n_a n_b / 2).
    pub fn a_lower(&self) -> bool {
        self.u_a < (self.n_a * self.n_b) as f64 / 2.0
    }
}

/// Number of arrangements of m values of a among m + n with each U (the exact null).
fn rank_sum_counts(m: usize, n: usize) -> Vec<f64> {
    // c[j][u] for the current i: arrangements of i values of a and j of b with U = u.
    let max = m * n;
    let mut c = vec![vec![0.0; max + 1]; n + 1];
    for row in c.iter_mut() {
        row[0] = 1.0; // i = 0: U = 0 whatever j
    }
    for _i in 1..=m {
        let mut next = vec![vec![0.0; max + 1]; n + 1];
        next[0][0] = 1.0; // j = 0: U = 0
        for j in 1..=n {
            for u in 0..=max {
                // The largest of the i + j values is from a (it beats the j of b) or from b.
                let from_a = if u >= j { c[j][u - j] } else { 0.0 };
                next[j][u] = from_a + next[j - 1][u];
            }
        }
        c = next;
    }
    c.swap_remove(n)
}

/// Mann-Whitney U test of sample `a` against sample `b` (see `MannWhitney` for the choice
/// between the exact and the normal p value).
pub fn mann_whitney(a: &[f64], b: &[f64]) -> MannWhitney {
    let (m, n) = (a.len(), b.len());
    let all: Vec<f64> = a.iter().chain(b).copied().collect();
    let (r, ties) = ranks(&all);
    let rank_sum_a: f64 = r[..m].iter().sum();
    let u_a = rank_sum_a - (m * (m + 1)) as f64 / 2.0;
    let (mf, nf) = (m as f64, n as f64);
    let u = u_a.max(mf * nf - u_a);
    let (p, method) = if m == 0 || n == 0 {
        (1.0, "exact")
    } else if m.min(n) < 8 && ties == 0.0 {
        let c = rank_sum_counts(m, n);
        let total: f64 = c.iter().sum();
        let upper: f64 = c[u.round() as usize..].iter().sum();
        ((2.0 * upper / total).min(1.0), "exact")
    } else {
        let all_n = mf + nf;
        let var = mf * nf / 12.0 * ((all_n + 1.0) - ties / (all_n * (all_n - 1.0)));
        let z = (u - mf * nf / 2.0 - 0.5) / var.sqrt();
        ((2.0 * normal_sf(z)).min(1.0), "normal")
    };
    MannWhitney {
        n_a: m,
        n_b: n,
        u_a,
        p_two_sided: p,
        method,
    }
}

/// `s` with its first letter in lower case (a sentence's subject inside a sentence).
pub fn lower_first(s: &str) -> String {
    let mut s = s.to_string();
    if let Some(c) = s.get_mut(0..1) {
        c.make_ascii_lowercase();
    }
    s
}

/// The sentence a paired comparison supports, from its own numbers: "lower"/"HIGHER" only
/// when the two-sided Wilcoxon test `w` says so at the 5 % level, otherwise "no difference
/// shown". `a` is the subject ("Fuzzy anti-windup"), `a_short` its name in the counts
/// ("fuzzy"), `b` what it is compared with, `what` the measure ("eq. 31 index G"), `d` the
/// mean of a - b with its interval.
pub fn paired_sentence(
    a: &str,
    a_short: &str,
    b: &str,
    what: &str,
    w: &Wilcoxon,
    d: &MeanCi,
) -> String {
    let p = if w.p_two_sided >= 0.001 {
        format!("{:.3}", w.p_two_sided)
    } else {
        format!("{:.1e}", w.p_two_sided)
    };
    let numbers = format!(
        "{a_short} lower in {} of {} seeds, mean difference {:+.2} (95 % CI {:+.2} .. {:+.2}), Wilcoxon p = {p}",
        w.a_lower, w.n, d.mean, d.ci95[0], d.ci95[1]
    );
    let lower_a = lower_first(a);
    if w.p_two_sided < 0.05 && w.w_plus < w.w_minus {
        format!("{a} has a lower {what} than {b} ({numbers}).")
    } else if w.p_two_sided < 0.05 {
        format!("{a} has a HIGHER {what} than {b} ({numbers}).")
    } else {
        format!("No difference in the {what} between {lower_a} and {b} is shown at the 5 % level ({numbers}).")
    }
}

/// The exact two-sided sign test: `lower` of `n` untied units one way, under the null that each
/// goes either way with probability 1/2 (a binomial tail, doubled, at most 1). For counts over
/// units too few or too unlike for a signed-rank test, e.g. arms of a zoo.
pub fn sign_test(lower: usize, n: usize) -> f64 {
    assert!(lower <= n, "sign test: {lower} of {n}");
    let k = lower.min(n - lower);
    // sum_{i <= k} C(n, i) / 2^n, each term in logarithms (exact enough for any n).
    let ln_half = n as f64 * 0.5f64.ln();
    let (mut ln_c, mut tail) = (0.0f64, 0.0f64);
    for i in 0..=k {
        if i > 0 {
            ln_c += ((n - i + 1) as f64 / i as f64).ln();
        }
        tail += (ln_c + ln_half).exp();
    }
    (2.0 * tail).min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_differences_one_sign_give_the_smallest_exact_p() {
        // n = 10, every a below b: W+ = 0, P(W+ <= 0) = 1/2^10, two-sided 2/1024.
        let a: Vec<f64> = (0..10).map(|i| i as f64).collect();
        let b: Vec<f64> = (0..10).map(|i| i as f64 + 1.0 + 0.1 * i as f64).collect();
        let w = wilcoxon(&a, &b);
        assert_eq!((w.n, w.w_plus, w.w_minus), (10, 0.0, 55.0));
        assert!((w.p_two_sided - 2.0 / 1024.0).abs() < 1e-15);
        assert_eq!((w.a_lower, w.a_higher), (10, 0));
    }

    #[test]
    fn exact_distribution_matches_enumeration_and_table_values() {
        // Counts of rank sums for n = 4 by enumerating all 16 sign patterns.
        let c = signed_rank_counts(4);
        let mut e = [0.0; 11];
        for mask in 0..16u32 {
            let s: usize = (1..=4).filter(|k| mask & (1 << (k - 1)) != 0).sum();
            e[s] += 1.0;
        }
        assert_eq!(c, e.to_vec());
        // Published critical value: n = 20, two-sided alpha 0.05 -> W = 52 (p just below 0.05),
        // W = 53 just above.
        let c = signed_rank_counts(20);
        let p = |w: usize| 2.0 * c[..=w].iter().sum::<f64>() / 2f64.powi(20);
        assert!(p(52) < 0.05 && p(53) > 0.05, "{} {}", p(52), p(53));
    }

    #[test]
    fn normal_approximation_agrees_with_exact_for_moderate_n_and_handles_failures() {
        // 30 untied pairs (exact), then the same with two more pairs that tie (normal): p close.
        let d: Vec<f64> = (0..30)
            .map(|i| (i + 1) as f64 * if i % 3 == 0 { 1.0 } else { -1.0 })
            .collect();
        let zero = vec![0.0; 30];
        let exact = wilcoxon(&d, &zero);
        assert_eq!(exact.method, "exact");
        let (mut d2, mut z2) = (d.clone(), zero.clone());
        d2.extend([-0.5, 0.5]);
        z2.extend([0.0, 0.0]);
        let approx = wilcoxon(&d2, &z2);
        assert_eq!(approx.method, "normal");
        let ratio = exact.p_two_sided / approx.p_two_sided;
        assert!((0.67..1.5).contains(&ratio), "{exact:?} {approx:?}");
        // Failures: a lost run on one side is the largest difference; on both sides a tie.
        let w = wilcoxon(
            &[1.0, 2.0, f64::INFINITY],
            &[f64::INFINITY, 3.0, f64::INFINITY],
        );
        assert_eq!((w.n, w.a_lower, w.w_plus), (2, 2, 0.0));
    }

    /// Reference implementations on known inputs. SciPy's documented example (Fisher's 15
    /// paired differences): `scipy.stats.wilcoxon(d)` gives statistic 24, p = 0.041259765625
    /// (exact, 1352 / 2^15). MATLAB's `signrank` on 30 pairs all on one side (the eMuPSO paper's
    /// Table 8, 1.73e-6) is the normal approximation without continuity correction; the exact
    /// value is 2 / 2^30.
    #[test]
    fn matches_reference_implementations_on_known_inputs() {
        let d = [
            6.0, 8.0, 14.0, 16.0, 23.0, 24.0, 28.0, 29.0, 41.0, -48.0, 49.0, 56.0, 60.0, -67.0,
            75.0,
        ];
        let w = wilcoxon(&d, &[0.0; 15]);
        assert_eq!(w.method, "exact");
        assert_eq!(w.w_plus.min(w.w_minus), 24.0);
        assert!((w.p_two_sided - 0.041259765625).abs() < 1e-15, "{w:?}");
        let a: Vec<f64> = (1..=30).map(|i| i as f64).collect();
        let w = wilcoxon(&a, &[0.0; 30]);
        assert!((w.p_two_sided - 2.0 / 2f64.powi(30)).abs() < 1e-24);
        let (n, mean) = (30.0, 30.0 * 31.0 / 4.0);
        let z = mean / (n * (n + 1.0) * (2.0 * n + 1.0) / 24.0f64).sqrt();
        assert!(
            (2.0 * normal_sf(z) - 1.73e-6).abs() < 0.01e-6,
            "{}",
            2.0 * normal_sf(z)
        );
    }

    /// SciPy 1.17's `mannwhitneyu` (method "auto") on the same inputs: a tied sample (normal
    /// approximation with tie and continuity corrections) and two untied ones with a sample of
    /// fewer than 8 (exact).
    #[test]
    fn mann_whitney_matches_scipy_on_known_inputs() {
        let a = [1.83, 0.50, 1.62, 2.48, 1.68, 1.88, 1.55, 3.06, 1.30];
        let b = [0.878, 0.647, 0.598, 2.05, 1.06, 1.29, 1.06, 3.15, 1.29];
        let t = mann_whitney(&a, &b);
        assert_eq!((t.method, t.u_a), ("normal", 58.0));
        assert!((t.p_two_sided - 0.13291945818531892).abs() < 1e-6, "{t:?}");
        let a = [0.8, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46];
        let b = [1.15, 0.88, 0.90, 0.74, 1.21];
        let t = mann_whitney(&a, &b);
        assert_eq!((t.method, t.u_a), ("exact", 35.0));
        assert!((t.p_two_sided - 0.2544122544122544).abs() < 1e-12, "{t:?}");
        let a: Vec<f64> = (0..30).map(|i| i as f64).collect();
        let t = mann_whitney(&a, &[2.5, 7.5, 100.0, 101.0, 102.0]);
        assert_eq!(t.u_a, 49.0);
        assert!((t.p_two_sided - 0.23748120949259466).abs() < 1e-12, "{t:?}");
        assert!(t.a_lower());
        // Completely separated samples of 5 and 30: the smallest exact p, 2 / C(35, 5).
        let t = mann_whitney(&[-5.0, -4.0, -3.0, -2.0, -1.0], &a);
        assert!((t.p_two_sided - 2.0 / 324_632.0).abs() < 1e-15 && t.a_lower());
    }

    #[test]
    fn mean_ci_uses_the_t_quantile() {
        let m = mean_ci(&[1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(m.mean, 3.0);
        let half = 2.776 * (2.5f64).sqrt() / 5f64.sqrt();
        assert!((m.ci95[1] - 3.0 - half).abs() < 1e-12);
        assert!((erfc(0.0) - 1.0).abs() < 1e-7 && (normal_sf(1.959964) - 0.025).abs() < 1e-6);
    }

    #[test]
    fn the_sign_test_matches_the_binomial_tables() {
        // 10 of 10 one way: 2 / 1024; 8 of 10: 2 * 56 / 1024; 5 of 10: 1.
        assert!((sign_test(10, 10) - 2.0 / 1024.0).abs() < 1e-15);
        assert!((sign_test(0, 10) - 2.0 / 1024.0).abs() < 1e-15);
        // Beyond 2^1024: 1000 of 2000 is an even split, 0 of 2000 vanishingly rare.
        assert_eq!(sign_test(1000, 2000), 1.0);
        assert!(sign_test(0, 2000) < 1e-300);
        assert!((sign_test(8, 10) - 112.0 / 1024.0).abs() < 1e-15);
        assert_eq!(sign_test(5, 10), 1.0);
        assert_eq!(sign_test(0, 0), 1.0);
    }
}
