//! A single-input plant's linear model and its closed loop under state feedback with integral
//! action (two-mass paper, eq. 2): the integral state xi' = r - y and u = -K [x; xi]. One place
//! builds the closed loop: the controller's stability check, the optimisers' acceptance rule and
//! the robust design all use it.
//!
//! Two forms. `continuous`: x' = A x + B u, y = C x, checked as the paper does (the augmented
//! continuous closed loop, every eigenvalue in the open left half-plane). `sampled`: the exact
//! zero-order-hold model of an `lti` plant at the control period, z+ = A z + B u, checked as the
//! controller really runs it (the integrator summed once a period, the measured output's direct
//! feedthrough acting through the input of the period before), every eigenvalue inside the unit
//! circle.

use nalgebra::{Complex, DMatrix, SMatrix};

/// The most states a linear model checked in the control cycle has (its closed loop is at most
/// 10 x 10, decomposed on the stack).
pub const MAX_LINEAR_STATES: usize = 8;

/// The largest |[A B]| T (max entry times size times period) discretised: e^{1e3} already
/// overflows, and nalgebra's exponential squares ceil(log2 |M|) times (endlessly once |M|
/// overflows), so a larger product is a model far too fast for the control period.
pub const MAX_NORM_PERIOD: f64 = 1e3;

/// |[A B]| T as `MAX_NORM_PERIOD` bounds it: the largest of A's and B's `entries` times `size`
/// (states plus inputs) times `period`.
pub fn norm_period<'a>(
    entries: impl IntoIterator<Item = &'a f64>,
    size: usize,
    period: f64,
) -> f64 {
    let largest = entries.into_iter().fold(0.0f64, |m, v| m.max(v.abs()));
    largest * size as f64 * period
}

/// Continuous time, or sampled at the control period (s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Time {
    /// x' = A x + B u: checked on the continuous closed loop.
    Continuous,
    /// z+ = A z + B u once a control period: checked on the sampled closed loop.
    Sampled {
        /// The control period the model is sampled at, s.
        period: f64,
    },
}

/// The linear model a controller checks state-feedback gains against.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearModel {
    n: usize,
    a: [[f64; MAX_LINEAR_STATES]; MAX_LINEAR_STATES],
    b: [f64; MAX_LINEAR_STATES],
    c: [f64; MAX_LINEAR_STATES],
    /// Sampled only: y_k = C z_k + d v_{k-1}, where v is the input reaching the plant over a
    /// period, v_k = f z_k + g u_k (u itself, or the head of an input delay line).
    d: f64,
    f: [f64; MAX_LINEAR_STATES],
    g: f64,
    time: Time,
}

impl LinearModel {
    /// x' = A x + B u, y = C x with n = `b.len()` states (at most `MAX_LINEAR_STATES`); `a` is
    /// row-major, n x n.
    pub fn continuous(a: &[f64], b: &[f64], c: &[f64]) -> Self {
        let mut m = Self::empty(b.len(), Time::Continuous);
        m.fill(a, b, c);
        m
    }

    /// z_{k+1} = A z_k + B u_k, y_k = C z_k + d v_{k-1}, v_k = f z_k + g u_k, at `period`.
    #[allow(clippy::too_many_arguments)]
    pub fn sampled(
        period: f64,
        a: &[f64],
        b: &[f64],
        c: &[f64],
        d: f64,
        f: &[f64],
        g: f64,
    ) -> Self {
        let mut m = Self::empty(b.len(), Time::Sampled { period });
        m.fill(a, b, c);
        m.f[..f.len()].copy_from_slice(f);
        (m.d, m.g) = (d, g);
        m
    }

    fn empty(n: usize, time: Time) -> Self {
        assert!(
            (1..=MAX_LINEAR_STATES).contains(&n),
            "a linear model has 1..={MAX_LINEAR_STATES} states, got {n}"
        );
        Self {
            n,
            a: [[0.0; MAX_LINEAR_STATES]; MAX_LINEAR_STATES],
            b: [0.0; MAX_LINEAR_STATES],
            c: [0.0; MAX_LINEAR_STATES],
            d: 0.0,
            f: [0.0; MAX_LINEAR_STATES],
            g: 1.0,
            time,
        }
    }

    fn fill(&mut self, a: &[f64], b: &[f64], c: &[f64]) {
        let n = self.n;
        assert!(a.len() == n * n && c.len() == n, "A is n x n and C 1 x n");
        for i in 0..n {
            self.a[i][..n].copy_from_slice(&a[i * n..(i + 1) * n]);
        }
        self.b[..n].copy_from_slice(b);
        self.c[..n].copy_from_slice(c);
    }

    /// The number of plant states (state feedback takes this many gains and the integrator's).
    pub fn n(&self) -> usize {
        self.n
    }

    /// Whether the model is continuous or sampled, and at which period.
    pub fn time(&self) -> Time {
        self.time
    }

    /// A's entry (i, j).
    pub fn a(&self, i: usize, j: usize) -> f64 {
        self.a[i][j]
    }

    /// B's entry i.
    pub fn b(&self, i: usize) -> f64 {
        self.b[i]
    }

    /// C's entry j.
    pub fn c(&self, j: usize) -> f64 {
        self.c[j]
    }

    /// A sampled model's (d, f, g): y_k = C z_k + d v_{k-1}, v_k = f z_k + g u_k; a continuous
    /// one's are (0, 0, 1), the input reaching the plant as it is.
    pub fn feedthrough(&self) -> (f64, &[f64], f64) {
        (self.d, &self.f[..self.n], self.g)
    }

    /// Entry i of the column through which what reaches the plant (v, the input after any
    /// delay line) moves the state: A f' + B g (B for a model without an input delay).
    pub fn input_column(&self, i: usize) -> f64 {
        let n = self.n;
        (0..n).map(|j| self.a[i][j] * self.f[j]).sum::<f64>() + self.b[i] * self.g
    }

    /// The model as a controller running every `period` s sees it: a sampled model at its own
    /// period as it is (None at another), a continuous one discretised exactly with the input
    /// held over the period (the exponential of [[A, B], [0, 0]] T). Off the cycle (allocates);
    /// None when the exponential is not finite or the product of size and period is beyond
    /// `MAX_NORM_PERIOD`.
    pub fn at_period(&self, period: f64) -> Option<LinearModel> {
        let n = self.n;
        self.sample_with(period, |m| {
            let e = DMatrix::from_fn(n + 1, n + 1, m).exp();
            move |i: usize, j: usize| e[(i, j)]
        })
    }

    /// `at_period` without allocating, for the control cycle (a filter designed again on an
    /// estimated model): the same exponential on a fixed-size matrix, zero-padded (the padding
    /// is decoupled from the model's block, which it leaves as it is, to rounding).
    pub fn at_period_fixed(&self, period: f64) -> Option<LinearModel> {
        const S: usize = MAX_LINEAR_STATES + 1;
        self.sample_with(period, |m| {
            let e = SMatrix::<f64, S, S>::from_fn(m).exp();
            move |i: usize, j: usize| e[(i, j)]
        })
    }

    /// The sampled model from `exp`, which gives the exponential of the (n + 1) x (n + 1)
    /// matrix [[A T, B T], [0, 0]] (entries by `m(i, j)`, zero outside it) as a function of
    /// (row, column).
    fn sample_with<E: Fn(usize, usize) -> f64>(
        &self,
        period: f64,
        exp: impl FnOnce(&dyn Fn(usize, usize) -> f64) -> E,
    ) -> Option<LinearModel> {
        let n = self.n;
        match self.time {
            Time::Sampled { period: own } => {
                ((own - period).abs() <= 1e-12 * own.max(period)).then_some(*self)
            }
            Time::Continuous => {
                let entries = (0..n).flat_map(|i| self.a[i][..n].iter().chain([&self.b[i]]));
                let too_fast = norm_period(entries, n + 1, period) > MAX_NORM_PERIOD;
                if period.is_nan() || period <= 0.0 || too_fast {
                    return None;
                }
                let e = exp(&|i, j| match (i < n && j < n, i < n && j == n) {
                    (true, _) => self.a[i][j] * period,
                    (false, true) => self.b[i] * period,
                    _ => 0.0,
                });
                let mut m = Self::empty(n, Time::Sampled { period });
                for i in 0..n {
                    for j in 0..n {
                        m.a[i][j] = e(i, j);
                    }
                    m.b[i] = e(i, n);
                }
                m.c = self.c;
                let finite = (0..n).all(|i| m.a[i][..n].iter().all(|v| v.is_finite()));
                (finite && m.b[..n].iter().all(|v| v.is_finite())).then_some(m)
            }
        }
    }

    /// The augmented continuous open loop (Â, B̂) = ([[A, 0], [-C, 0]], [B; 0]) (the robust
    /// design's, off the control cycle). A continuous model's only: panics on a sampled one,
    /// whose integrator row is another.
    pub fn augmented(&self) -> (DMatrix<f64>, DMatrix<f64>) {
        assert_eq!(
            self.time,
            Time::Continuous,
            "augmented() is the continuous loop's"
        );
        let n = self.n;
        let a = DMatrix::from_fn(n + 1, n + 1, |i, j| self.open_loop(i, j));
        let b = DMatrix::from_fn(n + 1, 1, |i, _| if i < n { self.b[i] } else { 0.0 });
        (a, b)
    }

    fn open_loop(&self, i: usize, j: usize) -> f64 {
        let n = self.n;
        match (i < n, j < n) {
            (true, true) => self.a[i][j],
            (false, true) => -self.c[j],
            _ => 0.0,
        }
    }

    /// Whether u = -K [x; xi] (n + 1 gains) makes the closed loop asymptotically stable.
    /// Stack-only (a fixed-size Schur decomposition), so it can run inside the control cycle.
    pub fn stabilised_by(&self, gains: &[f64]) -> bool {
        let n = self.n;
        if gains.len() != n + 1 {
            return false;
        }
        match self.time {
            // Â - B̂ K, written element by element so the integrator row stays exactly [-C, 0]
            // whatever the gains.
            Time::Continuous => all_eigenvalues(
                n + 1,
                |i, j| {
                    let bk = if i < n { self.b[i] * gains[j] } else { 0.0 };
                    self.open_loop(i, j) - bk
                },
                |l| l.re < 0.0,
            ),
            Time::Sampled { period } => all_eigenvalues(
                n + 2,
                |i, j| self.sampled_closed_loop(gains, period, i, j),
                |l| l.norm() < 1.0,
            ),
        }
    }

    /// Element (i, j) of the sampled closed loop over s = [z; I; v_prev], where the law is
    /// u_k = -K_z z_k + I_k and its integrator I_{k+1} = I_k - k_i T (r - y_k) (`StateFeedback`):
    ///   z+      = (A - B K_z) z + B I
    ///   I+      = k_i T C z + I + k_i T d v_prev
    ///   v_prev+ = (f - g K_z) z + g I
    fn sampled_closed_loop(&self, gains: &[f64], period: f64, i: usize, j: usize) -> f64 {
        let n = self.n;
        let kt = gains[n] * period;
        // Blocks: 0 = z (the first n), 1 = I, 2 = v_prev.
        let block = |k: usize| (k >= n) as u8 + (k > n) as u8;
        match (block(i), block(j)) {
            (0, 0) => self.a[i][j] - self.b[i] * gains[j],
            (0, 1) => self.b[i],
            (1, 0) => kt * self.c[j],
            (1, 1) => 1.0,
            (1, 2) => kt * self.d,
            (2, 0) => self.f[j] - self.g * gains[j],
            (2, 1) => self.g,
            _ => 0.0,
        }
    }
}

impl LinearModel {
    /// The exact zero-order-hold model at `period` of the strictly proper b(s) / a(s) with n
    /// poles (`num`, `den`: n + 1 values each, descending powers, den monic, `num[0] = 0`), in
    /// the controllable canonical form `[plant.lti]` realises a transfer function in.
    /// Allocation-free (the exponential of a padded 5 x 5 matrix on the stack), so a controller
    /// adopts an estimate with it in the cycle. None for more than 4 poles, a model that is not
    /// strictly proper, or one whose exponential is not finite.
    pub fn sampled_transfer_function(num: &[f64], den: &[f64], period: f64) -> Option<Self> {
        const P: usize = 5;
        let n = den.len().checked_sub(1)?;
        let proper = num.len() == n + 1 && num[0] == 0.0 && den[0] == 1.0;
        let period_ok = period.is_finite() && period > 0.0;
        if !(1..P).contains(&n) || !proper || !period_ok {
            return None;
        }
        // A, B = e_0: the entries are den's and 1.
        if norm_period(den[1..].iter().chain(&[1.0]), n + 1, period) > MAX_NORM_PERIOD {
            return None;
        }
        // [[A, B], [0, 0]] T: A's first row -den[1..], ones below the diagonal, B = e_0.
        let m = SMatrix::<f64, P, P>::from_fn(|i, j| match (i, j) {
            (0, j) if j < n => -den[j + 1] * period,
            (0, j) if j == n => period,
            (i, j) if i < n && j + 1 == i => period,
            _ => 0.0,
        });
        let e = m.exp();
        let (mut a, mut b, mut c) = ([0.0; 16], [0.0; 4], [0.0; 4]);
        for i in 0..n {
            for j in 0..n {
                a[i * n + j] = e[(i, j)];
            }
            b[i] = e[(i, n)];
            c[i] = num[i + 1];
        }
        if !a[..n * n].iter().chain(&b[..n]).all(|v| v.is_finite()) {
            return None;
        }
        Some(Self::sampled(
            period,
            &a[..n * n],
            &b[..n],
            &c[..n],
            0.0,
            &[0.0; 4][..n],
            1.0,
        ))
    }

    /// Whether a PID stabilises this sampled model (the loop as `law::Pid` runs it while
    /// unsaturated): u_k = P e_k + I_{k-1} - k_d e_{k-1} with P = k_p + k_d + k_i and
    /// I_k = I_{k-1} + k_i e_k, e_k = r - y_k; `kd` = K_p T_v / T and `ki` per sample. Over
    /// s = [z; I_prev; e_prev; v_prev], every eigenvalue inside the unit circle. A continuous
    /// model is never accepted (the PID is a sampled law).
    pub fn stabilised_by_pid(&self, kp: f64, kd: f64, ki: f64) -> bool {
        if self.time == Time::Continuous || ![kp, kd, ki].iter().all(|v| v.is_finite()) {
            return false;
        }
        let n = self.n;
        let p = kp + kd + ki;
        // Blocks: 0 = z, 1 = I_prev, 2 = e_prev, 3 = v_prev.
        let block = |k: usize| if k < n { 0 } else { k - n + 1 };
        all_eigenvalues(
            n + 3,
            |i, j| {
                let (bi, bj) = (block(i), block(j));
                let b = if bi == 0 { self.b[i] } else { 0.0 };
                let c = if bj == 0 { self.c[j] } else { 0.0 };
                match (bi, bj) {
                    (0, 0) => self.a[i][j] - b * p * c,
                    (0, 1) => b,
                    (0, 2) => -b * kd,
                    (0, 3) => -b * p * self.d,
                    (1, 0) => -ki * c,
                    // Without integral action the integrator holds a constant, an offset and not
                    // a mode: its eigenvalue 1 is left out (written 0).
                    (1, 1) => f64::from(ki != 0.0),
                    (1, 3) => -ki * self.d,
                    (2, 0) => -c,
                    (2, 3) => -self.d,
                    (3, 0) => self.f[j] - self.g * p * c,
                    (3, 1) => self.g,
                    (3, 2) => -self.g * kd,
                    (3, 3) => -self.g * p * self.d,
                    _ => 0.0,
                }
            },
            |l| l.norm() < 1.0,
        )
    }
}

/// Whether every eigenvalue of the k x k matrix `fill(i, j)` (1 <= k <= 11) satisfies `ok`, on
/// a matrix of exactly that size (no padding, so a 5 x 5 loop decomposes as it always did).
/// Stack-only.
pub(crate) fn all_eigenvalues(
    k: usize,
    fill: impl Fn(usize, usize) -> f64,
    ok: impl Fn(Complex<f64>) -> bool,
) -> bool {
    macro_rules! sized {
        ($($n:literal)*) => {
            match k {
                $($n => SMatrix::<f64, $n, $n>::from_fn(&fill)
                    .complex_eigenvalues()
                    .iter()
                    .all(|l| ok(*l)),)*
                _ => false,
            }
        };
    }
    if k == 1 {
        return ok(Complex::new(fill(0, 0), 0.0));
    }
    sized!(2 3 4 5 6 7 8 9 10 11)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// x' = u, y = x under u = -k1 x - k2 xi: poles of s^2 + k1 s - k2, stable iff k1 > 0 and
    /// k2 < 0 (the paper's sign: k_i = -k2).
    #[test]
    fn a_continuous_integrator_is_stable_exactly_where_routh_says() {
        let m = LinearModel::continuous(&[0.0], &[1.0], &[1.0]);
        assert!(m.stabilised_by(&[1.0, -1.0]));
        assert!(!m.stabilised_by(&[-1.0, -1.0]));
        assert!(!m.stabilised_by(&[1.0, 1.0]));
        assert!(!m.stabilised_by(&[1.0]), "wrong gain count");
    }

    /// The sampled integrator z+ = z + T u, y = z: deadbeat-ish gains are stable, but gains
    /// a continuous check accepts become unstable once k1 T > 2 (sampling matters).
    #[test]
    fn a_sampled_loop_goes_unstable_where_the_continuous_one_would_not() {
        let t = 0.1;
        let m = LinearModel::sampled(t, &[1.0], &[t], &[1.0], 0.0, &[0.0], 1.0);
        assert!(m.stabilised_by(&[5.0, -1.0]));
        // k1 T = 2.5: the proportional loop alone has pole 1 - 2.5 = -1.5.
        assert!(!m.stabilised_by(&[25.0, -1.0]));
        assert!(LinearModel::continuous(&[0.0], &[1.0], &[1.0]).stabilised_by(&[25.0, -1.0]));
    }

    /// A proportional controller on the sampled integrator z+ = z + T u: pole 1 - k_p T,
    /// stable for 0 < k_p T < 2. With integral action the poles are the roots of
    /// z^2 - (2 - (k_p + k_i) T) z + (1 - k_p T), checked against the roots directly.
    #[test]
    fn a_pid_on_the_sampled_integrator_is_stable_where_its_poles_say() {
        let t = 0.1;
        let m = LinearModel::sampled(t, &[1.0], &[t], &[1.0], 0.0, &[0.0], 1.0);
        assert!(m.stabilised_by_pid(5.0, 0.0, 0.0));
        assert!(!m.stabilised_by_pid(25.0, 0.0, 0.0));
        assert!(!m.stabilised_by_pid(-1.0, 0.0, 0.0));
        // With integral action: the poles are the roots of z^2 - (2 - (k_p + k_i) T) z + (1 - k_p T).
        for (kp, ki) in [
            (5.0, 1.0),
            (5.0, 12.0),
            (15.0, 4.0),
            (19.0, 2.0),
            (1.0, 0.5),
        ] {
            let (b, c) = (-(2.0 - (kp + ki) * t), 1.0 - kp * t);
            let disc: f64 = b * b - 4.0 * c;
            let largest = if disc >= 0.0 {
                ((-b + disc.sqrt()) / 2.0)
                    .abs()
                    .max(((-b - disc.sqrt()) / 2.0).abs())
            } else {
                c.sqrt()
            };
            assert_eq!(
                m.stabilised_by_pid(kp, 0.0, ki),
                largest < 1.0,
                "{kp} {ki}: {largest}"
            );
        }
        assert!(!LinearModel::continuous(&[0.0], &[1.0], &[1.0]).stabilised_by_pid(1.0, 0.0, 0.0));
    }

    /// The transfer function's sampled model is the integrator's closed form for 1/s (Phi = 1,
    /// Gamma = T), so the PID check on it agrees with the one above; a first-order lag
    /// 2/(s + 2) gives Phi = e^(-2T), Gamma = 1 - e^(-2T) (through C = 2: b = (1 - e^(-2T))).
    #[test]
    fn a_transfer_function_samples_to_its_closed_form() {
        let t = 0.1;
        let m = LinearModel::sampled_transfer_function(&[0.0, 1.0], &[1.0, 0.0], t).unwrap();
        let direct = LinearModel::sampled(t, &[1.0], &[t], &[1.0], 0.0, &[0.0], 1.0);
        assert!(
            (m.a[0][0] - 1.0).abs() < 1e-15 && (m.b[0] - t).abs() < 1e-15,
            "{m:?}"
        );
        for (kp, ki) in [(5.0, 1.0), (5.0, 12.0), (15.0, 4.0), (25.0, 0.0)] {
            assert_eq!(
                m.stabilised_by_pid(kp, 0.0, ki),
                direct.stabilised_by_pid(kp, 0.0, ki)
            );
        }
        let lag = LinearModel::sampled_transfer_function(&[0.0, 2.0], &[1.0, 2.0], t).unwrap();
        let e = (-2.0 * t).exp();
        assert!((lag.a[0][0] - e).abs() < 1e-14);
        assert!((lag.b[0] * lag.c[0] - (1.0 - e)).abs() < 1e-14);
        assert!(LinearModel::sampled_transfer_function(&[1.0, 1.0], &[1.0, 1.0], t).is_none());
        assert!(LinearModel::sampled_transfer_function(&[0.0; 6], &[1.0; 6], t).is_none());
        // Too fast to hold between samples: refused at once, not an endless exponential.
        assert!(LinearModel::sampled_transfer_function(&[0.0, 1.0], &[1.0, 1e60], t).is_none());
    }
}
