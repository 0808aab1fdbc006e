//! State-variable filter F(s) = a^N / (s + a)^N of any order N up to `MAX_ORDER`: the filtered
//! derivatives s^j F v (j = 0..N) of a sampled signal that an estimator needs, without
//! differencing noisy samples.
//!
//! A linear relation between signals, a(s) y = b(s) u, holds equally for F y and F u, and the
//! filtered derivatives s^j F v (j < N) are the filter's states (s^N F v its state derivative) —
//! no numerical differentiation. Measurement noise reaches s^j F v with a gain of at most a^j, so
//! `a` sits a few times above the plant's modes and far below the sampling rate. The indirect
//! scheme's estimators use N = 4 (`evoloop-schemes`), the evidence of fuzzy model selection
//! N = 2 (`law::evidence`).
//!
//! Between samples the filter is integrated exactly (one matrix exponential, computed when the
//! design is made): a held command (zero-order hold) exactly as the plant saw it, a sampled
//! output as the straight line between its two samples (first-order hold). Allocation-free per
//! sample.

use nalgebra::SMatrix;

/// The highest order a design takes: s^4 F y is the highest derivative an estimator here uses.
pub const MAX_ORDER: usize = 4;

/// The augmented system's size: the filter's states, the input v and its slope r.
const AUGMENTED: usize = MAX_ORDER + 2;

/// F(s) = a^N / (s + a)^N discretised for one sampling period (shared by every signal it
/// filters).
#[derive(Debug, Clone)]
pub struct SvfDesign<const N: usize> {
    a: f64,
    period: f64,
    /// Denominator (s + a)^N = s^N + c[N-1] s^(N-1) + ... + c[0]; c[0] = a^N is also the input
    /// gain (unit DC gain).
    c: [f64; N],
    /// State transition over one period.
    phi: [[f64; N]; N],
    /// Response to an input held at 1 over the period.
    held: [f64; N],
    /// Response to an input rising linearly from 0 to 1 over the period.
    ramp: [f64; N],
}

impl<const N: usize> SvfDesign<N> {
    /// Filter pole `a` (rad/s), sampling `period` (s).
    ///
    /// # Panics
    ///
    /// If `a` or `period` is not positive (the callers' configurations are checked before).
    pub fn new(a: f64, period: f64) -> Self {
        const {
            assert!(
                N >= 1 && N <= MAX_ORDER,
                "a state-variable filter of order 1 to 4"
            )
        };
        assert!(
            a > 0.0 && period > 0.0,
            "filter pole and period must be positive"
        );
        let c: [f64; N] = std::array::from_fn(|j| coefficient(N, j, a));
        // Companion form: w^(N) = a^N (v - w) - sum_{j>0} c[j] w^(j), with input v, augmented with
        // v' = r, r' = 0 so one exponential gives the held and the ramp response. The unused rows
        // and columns of the fixed-size matrix are zero: its exponential is the identity there,
        // and the filter's block is the exponential of the filter's own augmented matrix.
        let mut m = SMatrix::<f64, AUGMENTED, AUGMENTED>::zeros();
        for i in 0..N - 1 {
            m[(i, i + 1)] = 1.0;
        }
        for j in 0..N {
            m[(N - 1, j)] = -c[j];
        }
        m[(N - 1, N)] = c[0];
        m[(N, N + 1)] = 1.0;
        let e = (m * period).exp();
        Self {
            a,
            period,
            c,
            phi: std::array::from_fn(|i| std::array::from_fn(|j| e[(i, j)])),
            held: std::array::from_fn(|i| e[(i, N)]),
            // The ramp input v = tau / period has r = 1 / period.
            ramp: std::array::from_fn(|i| e[(i, N + 1)] / period),
        }
    }

    /// The filter's pole (rad/s).
    pub fn pole(&self) -> f64 {
        self.a
    }

    /// The sampling period (s).
    pub fn period(&self) -> f64 {
        self.period
    }

    /// Root-mean-square gain from white noise on a sampled input to s^j F of it: the square
    /// root of the energy of the response to a unit sample (first-order hold), summed until the
    /// filter has forgotten it (40 time constants).
    pub fn noise_gain(&self, j: usize) -> f64 {
        let mut f = Svf::<N>::at_rest(0.0);
        let n = (40.0 / (self.a * self.period)).ceil() as usize;
        let mut energy = 0.0;
        for k in 0..n {
            f.sampled(self, if k == 0 { 1.0 } else { 0.0 });
            energy += f.derivative(self, j).powi(2);
        }
        energy.sqrt()
    }

    /// phi w, each row summed in column order.
    fn transition(&self, w: &[f64; N]) -> [f64; N] {
        std::array::from_fn(|i| {
            let mut s = self.phi[i][0] * w[0];
            for (p, x) in self.phi[i][1..].iter().zip(&w[1..]) {
                s += p * x;
            }
            s
        })
    }
}

/// c[j] of (s + a)^n: (n choose j) a^(n - j). The square is taken as (C a) a, the order the
/// order-4 filter was first written in ((6 a) a), so that its design, and every run recorded
/// with it, keeps its bits for any pole (6 (a a) differs in the last bit for about a third of
/// poles).
fn coefficient(n: usize, j: usize, a: f64) -> f64 {
    let b = binomial(n, j);
    match n - j {
        2 => b * a * a,
        k => b * a.powi(k as i32),
    }
}

/// n choose k, as f64 (n <= `MAX_ORDER`).
fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |b, i| b * (n - i) as f64 / (i + 1) as f64)
}

/// One signal through the filter: s^j F v for j < N, and the last input sample.
#[derive(Debug, Clone, Copy)]
pub struct Svf<const N: usize> {
    w: [f64; N],
    last: f64,
}

impl<const N: usize> Default for Svf<N> {
    fn default() -> Self {
        Self::at_rest(0.0)
    }
}

impl<const N: usize> Svf<N> {
    /// Start at rest on the value `v0` (its derivatives zero).
    pub fn at_rest(v0: f64) -> Self {
        let mut w = [0.0; N];
        w[0] = v0;
        Self { w, last: v0 }
    }

    /// Advance one period with the input held at `v` over it (a command).
    pub fn held(&mut self, d: &SvfDesign<N>, v: f64) {
        let pw = d.transition(&self.w);
        self.w = std::array::from_fn(|i| pw[i] + d.held[i] * v);
        self.last = v;
    }

    /// Advance one period with the input moving linearly from the last sample to `v` (a
    /// measurement).
    pub fn sampled(&mut self, d: &SvfDesign<N>, v: f64) {
        let pw = d.transition(&self.w);
        let rise = v - self.last;
        self.w = std::array::from_fn(|i| pw[i] + d.held[i] * self.last + d.ramp[i] * rise);
        self.last = v;
    }

    /// s^j F v at the current sample, j = 0..=N (j = N from the filter equation and the current
    /// input value).
    pub fn derivative(&self, d: &SvfDesign<N>, j: usize) -> f64 {
        if j < N {
            return self.w[j];
        }
        let mut top = d.c[0] * (self.last - self.w[0]);
        for (c, w) in d.c[1..].iter().zip(&self.w[1..]) {
            top -= c * w;
        }
        top
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sine through the filter of each order: after the transient, s^j F sin(wt) equals the
    /// analytic steady-state response (w j)^j a^N / (w j + a)^N applied to the sine.
    #[test]
    fn filtered_derivatives_of_a_sine_match_the_frequency_response() {
        fn check<const N: usize>() {
            let (a, dt, om) = (3.0, 1e-3, 1.7);
            let d = SvfDesign::<N>::new(a, dt);
            let mut f = Svf::<N>::at_rest(0.0);
            let n = 20_000;
            for k in 1..=n {
                f.sampled(&d, (om * k as f64 * dt).sin());
            }
            let t = n as f64 * dt;
            for j in 0..=N {
                // H(jw) = (jw)^j a^N / (jw + a)^N as magnitude and phase.
                let mag =
                    om.powi(j as i32) * a.powi(N as i32) / (om * om + a * a).powf(N as f64 / 2.0);
                let phase = j as f64 * std::f64::consts::FRAC_PI_2 - N as f64 * (om / a).atan();
                let want = mag * (om * t + phase).sin();
                let got = f.derivative(&d, j);
                // First-order hold of a sine: error O(dt^2 w^2) relative.
                assert!(
                    (got - want).abs() < 1e-5 * mag.max(1.0),
                    "N = {N}, j = {j}: {got} vs {want}"
                );
            }
        }
        check::<1>();
        check::<2>();
        check::<3>();
        check::<4>();
    }

    /// A held input reaches its value with unit DC gain and zero derivatives.
    #[test]
    fn a_held_step_settles_at_unit_gain() {
        fn check<const N: usize>() {
            let d = SvfDesign::<N>::new(5.0, 1e-3);
            let mut f = Svf::<N>::at_rest(0.0);
            for _ in 0..20_000 {
                f.held(&d, 2.0);
            }
            assert!((f.derivative(&d, 0) - 2.0).abs() < 1e-12, "N = {N}");
            for j in 1..=N {
                assert!(f.derivative(&d, j).abs() < 1e-9, "N = {N}, j = {j}");
            }
        }
        check::<1>();
        check::<2>();
        check::<4>();
    }

    /// The order-4 design's coefficients are the ones the estimators were first written with,
    /// [a^4, 4 a^3, (6 a) a, 4 a], bit for bit, at poles where 6 (a a) would round otherwise.
    #[test]
    fn the_fourth_order_coefficients_keep_their_bits() {
        for a in [0.3f64, 2.0, 4.2, 12.3, 17.1, 60.0, 59.999999999999986] {
            // (A pole read at run time: a constant's powers could be folded by the compiler
            // with another rounding.)
            let a = std::hint::black_box(a);
            let old = [a.powi(4), 4.0 * a.powi(3), 6.0 * a * a, 4.0 * a];
            let d = SvfDesign::<4>::new(a, 1e-3);
            assert_eq!(d.c.map(f64::to_bits), old.map(f64::to_bits), "a = {a}");
        }
        assert_ne!(
            (6.0 * 4.2) * 4.2,
            6.0 * (4.2 * 4.2),
            "a pole where the order matters"
        );
    }

    /// The second-order design is the closed form the exponential of [[0, 1], [-a^2, -2a]] has:
    /// e^(-ah) [[1 + ah, h], [-a^2 h, 1 - ah]], and a held input's response (I - phi) [1, 0]^T.
    #[test]
    fn the_second_order_design_is_the_closed_form() {
        let (a, h) = (50.0, 1e-3);
        let d = SvfDesign::<2>::new(a, h);
        let e = (-a * h).exp();
        let phi = [
            [e * (1.0 + a * h), e * h],
            [-e * a * a * h, e * (1.0 - a * h)],
        ];
        for (got, want) in d.phi.iter().flatten().zip(phi.iter().flatten()) {
            assert!(
                (got - want).abs() < 1e-14 * (1.0 + want.abs()),
                "{got} vs {want}"
            );
        }
        assert!((d.held[0] - (1.0 - phi[0][0])).abs() < 1e-14);
        assert!((d.held[1] + phi[1][0]).abs() < 1e-12);
    }
}
