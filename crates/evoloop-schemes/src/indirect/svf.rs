//! State-variable filter: the derivatives of a sampled signal that a parameter estimator needs,
//! without differencing noisy samples.
//!
//! A linear plant's input-output relation a(s) y = b(s) u holds equally for the filtered
//! signals F(s) y and F(s) u, and with F(s) = a^4 / (s + a)^4 the filtered derivatives
//! s^j F y (j = 0..4) are the filter's states (and its state derivative) — no numerical
//! differentiation. Measurement noise reaches s^4 F y with a gain of at most a^4, so `a` sits a
//! few times above the plant's modes and far below the sampling rate.
//!
//! Between samples the filter is integrated exactly (matrix exponential, computed once): a held
//! command (zero-order hold) exactly as the plant saw it, a sampled output as the straight line
//! between its two samples (first-order hold). Allocation-free per sample.

use nalgebra::{SMatrix, SVector};

/// Filter order; s^4 F y is the highest derivative the estimators use.
const N: usize = 4;

type Mat = SMatrix<f64, N, N>;
type Vec4 = SVector<f64, N>;

/// Discretised filter a^4 / (s + a)^4 for one sampling period (shared by every signal it filters).
#[derive(Debug, Clone)]
pub struct SvfDesign {
    a: f64,
    period: f64,
    /// Denominator (s + a)^4 = s^4 + c[3] s^3 + c[2] s^2 + c[1] s + c[0]; c[0] = a^4 is also
    /// the input gain (unit DC gain).
    c: [f64; N],
    /// State transition over one period.
    phi: Mat,
    /// Response to an input held at 1 over the period.
    held: Vec4,
    /// Response to an input rising linearly from 0 to 1 over the period.
    ramp: Vec4,
}

impl SvfDesign {
    /// Filter pole `a` (rad/s), sampling `period` (s).
    pub fn new(a: f64, period: f64) -> Self {
        assert!(
            a > 0.0 && period > 0.0,
            "filter pole and period must be positive"
        );
        // Companion form: w'''' = a^4 (v - w) - 4a w''' - 6a^2 w'' - 4a^3 w', with input v.
        // Augmented with v' = r, r' = 0 so one exponential gives the held and the ramp response.
        let mut m = SMatrix::<f64, 6, 6>::zeros();
        for i in 0..N - 1 {
            m[(i, i + 1)] = 1.0;
        }
        let c = [a.powi(4), 4.0 * a.powi(3), 6.0 * a * a, 4.0 * a];
        for j in 0..N {
            m[(N - 1, j)] = -c[j];
        }
        m[(N - 1, N)] = c[0];
        m[(N, N + 1)] = 1.0;
        let e = (m * period).exp();
        let phi = e.fixed_view::<N, N>(0, 0).into_owned();
        let held = e.fixed_view::<N, 1>(0, N).into_owned();
        // The ramp input v = tau / period has r = 1 / period.
        let ramp = e.fixed_view::<N, 1>(0, N + 1).into_owned() / period;
        Self {
            a,
            period,
            c,
            phi,
            held,
            ramp,
        }
    }

    /// The filter's pole (rad/s).
    pub fn pole(&self) -> f64 {
        self.a
    }

    /// Root-mean-square gain from white noise on a sampled input to s^j F of it: the square
    /// root of the energy of the response to a unit sample (first-order hold), summed until the
    /// filter has forgotten it (40 time constants).
    pub fn noise_gain(&self, j: usize) -> f64 {
        let mut f = Svf::at_rest(0.0);
        let n = (40.0 / (self.a * self.period)).ceil() as usize;
        let mut energy = 0.0;
        for k in 0..n {
            f.sampled(self, if k == 0 { 1.0 } else { 0.0 });
            energy += f.derivative(self, j).powi(2);
        }
        energy.sqrt()
    }
}

/// One signal through the filter: s^j F v for j = 0..3 in `w`, and the last input sample.
#[derive(Debug, Clone, Default)]
pub struct Svf {
    w: Vec4,
    last: f64,
}

impl Svf {
    /// Start at rest on the value `v0` (its derivatives zero).
    pub fn at_rest(v0: f64) -> Self {
        let mut w = Vec4::zeros();
        w[0] = v0;
        Self { w, last: v0 }
    }

    /// Advance one period with the input held at `v` over it (a command).
    pub fn held(&mut self, d: &SvfDesign, v: f64) {
        self.w = d.phi * self.w + d.held * v;
        self.last = v;
    }

    /// Advance one period with the input moving linearly from the last sample to `v` (a
    /// measurement).
    pub fn sampled(&mut self, d: &SvfDesign, v: f64) {
        self.w = d.phi * self.w + d.held * self.last + d.ramp * (v - self.last);
        self.last = v;
    }

    /// s^j F v at the current sample, j = 0..=4 (j = 4 from the filter equation and the
    /// current input value).
    pub fn derivative(&self, d: &SvfDesign, j: usize) -> f64 {
        if j < N {
            return self.w[j];
        }
        let c = &d.c;
        c[0] * (self.last - self.w[0]) - c[1] * self.w[1] - c[2] * self.w[2] - c[3] * self.w[3]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sine through the filter: after the transient, s^j F sin(wt) equals the analytic
    /// steady-state response (w j)^j a^4 / (w j + a)^4 applied to the sine.
    #[test]
    fn filtered_derivatives_of_a_sine_match_the_frequency_response() {
        let (a, dt, om) = (3.0, 1e-3, 1.7);
        let d = SvfDesign::new(a, dt);
        let mut f = Svf::at_rest(0.0);
        let n = 20_000;
        for k in 1..=n {
            f.sampled(&d, (om * k as f64 * dt).sin());
        }
        let t = n as f64 * dt;
        for j in 0..=4 {
            // H(jw) = (jw)^j a^4 / (jw + a)^4 as magnitude and phase.
            let mag = om.powi(j as i32) * a.powi(4) / (om * om + a * a).powi(2);
            let phase = j as f64 * std::f64::consts::FRAC_PI_2 - 4.0 * (om / a).atan();
            let want = mag * (om * t + phase).sin();
            let got = f.derivative(&d, j);
            // First-order hold of a sine: error O(dt^2 w^2) relative.
            assert!(
                (got - want).abs() < 1e-5 * mag.max(1.0),
                "j = {j}: {got} vs {want}"
            );
        }
    }

    /// A held input reaches its value with unit DC gain and zero derivatives.
    #[test]
    fn a_held_step_settles_at_unit_gain() {
        let d = SvfDesign::new(5.0, 1e-3);
        let mut f = Svf::at_rest(0.0);
        for _ in 0..20_000 {
            f.held(&d, 2.0);
        }
        assert!((f.derivative(&d, 0) - 2.0).abs() < 1e-12);
        for j in 1..=4 {
            assert!(f.derivative(&d, j).abs() < 1e-9, "j = {j}");
        }
    }
}
