//! The Runge-Kutta-Gill method (RKGNN paper, Section 3.1), generic over the right-hand side
//! f(x) and the step h: the integrator the RKGNN wraps around its function network N_f.
//!
//! The paper prints Gill's memory-saving form (Gill 1951):
//!   k0 = h f(x),  x1 = x + k0/2,              q1 = k0
//!   k1 = h f(x1), x2 = x1 + alpha (k1 - q1),  q2 = beta q1 + e k1
//!   k2 = h f(x2), x3 = x2 + d (k2 - q2),      q3 = gamma q2 + g k2
//!   k3 = h f(x3), x(i+1) = x3 + k3/6 - q3/3
//! with alpha = (sqrt2 - 1)/sqrt2 = 1 - 1/sqrt2, beta = -2 + 3/sqrt2, e = 2 - sqrt2,
//! d = (sqrt2 + 1)/sqrt2 = 1 + 1/sqrt2, gamma = -(2 + 3/sqrt2), g = 2 + sqrt2. Checked against
//! the classical statement of Gill's method (Butcher tableau: c = [0, 1/2, 1/2, 1], a32 =
//! 1 - 1/sqrt2, a31 = -1/2 + 1/sqrt2, a43 = 1 + 1/sqrt2, a42 = -1/sqrt2, weights
//! [1, 2 - sqrt2, 2 + sqrt2, 1]/6): the printed constants are those, and the tests show the two
//! forms agree to rounding and that the error falls as h^4. The q registers carry the stage
//! combinations, so one step needs two state-sized buffers besides x, allocated once.
//!
//! The RKGNN's N_f is autonomous (the network sees the state only), so f takes no time.

use std::f64::consts::SQRT_2;

const ALPHA: f64 = (SQRT_2 - 1.0) / SQRT_2;
const BETA: f64 = -2.0 + 3.0 / SQRT_2;
const E: f64 = 2.0 - SQRT_2;
const D: f64 = (SQRT_2 + 1.0) / SQRT_2;
const GAMMA: f64 = -(2.0 + 3.0 / SQRT_2);
const G: f64 = 2.0 + SQRT_2;

/// Runge-Kutta-Gill stepping with its buffers allocated once.
pub struct RungeKuttaGill {
    k: Vec<f64>,
    q: Vec<f64>,
}

impl RungeKuttaGill {
    /// A stepper for states of `n` values.
    pub fn new(n: usize) -> Self {
        Self {
            k: vec![0.0; n],
            q: vec![0.0; n],
        }
    }

    /// One step of width h: x <- x(i+1). `f(x, dx)` writes x' = f(x); it must not allocate for
    /// the step to stay allocation-free.
    pub fn step(&mut self, x: &mut [f64], h: f64, mut f: impl FnMut(&[f64], &mut [f64])) {
        let (k, q) = (&mut self.k, &mut self.q);
        // Step 1.
        f(x, k);
        for (xi, ki) in x.iter_mut().zip(k.iter_mut()) {
            *ki *= h;
            *xi += 0.5 * *ki;
        }
        q.copy_from_slice(k);
        // Steps 2 and 3 share their shape: x += a (k - q), q = b q + c k.
        for (a, b, c) in [(ALPHA, BETA, E), (D, GAMMA, G)] {
            f(x, k);
            for i in 0..x.len() {
                k[i] *= h;
                x[i] += a * (k[i] - q[i]);
                q[i] = b * q[i] + c * k[i];
            }
        }
        // Step 4.
        f(x, k);
        for i in 0..x.len() {
            x[i] += h * k[i] / 6.0 - q[i] / 3.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Gill's method from its Butcher tableau, written independently of the register form.
    fn butcher_step(x: &[f64], h: f64, f: &dyn Fn(&[f64], &mut [f64])) -> Vec<f64> {
        let s = 1.0 / SQRT_2;
        let n = x.len();
        let comb = |terms: &[(f64, &Vec<f64>)]| -> Vec<f64> {
            (0..n)
                .map(|i| x[i] + h * terms.iter().map(|(a, k)| a * k[i]).sum::<f64>())
                .collect()
        };
        let eval = |y: &[f64]| {
            let mut d = vec![0.0; n];
            f(y, &mut d);
            d
        };
        let k1 = eval(x);
        let k2 = eval(&comb(&[(0.5, &k1)]));
        let k3 = eval(&comb(&[(-0.5 + s, &k1), (1.0 - s, &k2)]));
        let k4 = eval(&comb(&[(-s, &k2), (1.0 + s, &k3)]));
        comb(&[
            (1.0 / 6.0, &k1),
            ((2.0 - SQRT_2) / 6.0, &k2),
            ((2.0 + SQRT_2) / 6.0, &k3),
            (1.0 / 6.0, &k4),
        ])
    }

    /// A damped pendulum: non-linear, autonomous.
    fn pendulum(x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -9.81 * x[0].sin() - 0.3 * x[1];
    }

    #[test]
    fn the_printed_register_form_is_gills_method() {
        let mut rkg = RungeKuttaGill::new(2);
        for (x0, h) in [([1.0, 0.0], 0.1), ([-2.5, 3.0], 0.02), ([0.3, -1.0], 0.5)] {
            let mut x = x0;
            rkg.step(&mut x, h, pendulum);
            let y = butcher_step(&x0, h, &pendulum);
            for i in 0..2 {
                assert!((x[i] - y[i]).abs() < 1e-14, "{x:?} vs {y:?}");
            }
        }
    }

    #[test]
    fn the_global_error_falls_as_h_to_the_fourth() {
        // x' = -x + sin(x)^2 has no closed form: judge against a much finer run.
        let f = |x: &[f64], dx: &mut [f64]| dx[0] = -x[0] + x[0].sin().powi(2);
        let run = |n: usize| {
            let mut rkg = RungeKuttaGill::new(1);
            let mut x = [2.0];
            for _ in 0..n {
                rkg.step(&mut x, 2.0 / n as f64, f);
            }
            x[0]
        };
        let exact = run(20_000);
        let errors: Vec<f64> = [10, 20, 40, 80]
            .iter()
            .map(|&n| (run(n) - exact).abs())
            .collect();
        for w in errors.windows(2) {
            let order = (w[0] / w[1]).log2();
            assert!((3.8..4.3).contains(&order), "order {order} from {errors:?}");
        }
    }

    #[test]
    fn a_linear_oscillator_matches_the_exact_solution_to_fourth_order() {
        // x'' = -x from (1, 0): after t = 1, x = cos 1; error ~ h^4 t / 120-ish.
        let f = |x: &[f64], dx: &mut [f64]| {
            dx[0] = x[1];
            dx[1] = -x[0];
        };
        let mut rkg = RungeKuttaGill::new(2);
        let mut x = [1.0, 0.0];
        for _ in 0..100 {
            rkg.step(&mut x, 0.01, f);
        }
        assert!((x[0] - 1f64.cos()).abs() < 1e-10, "{}", x[0] - 1f64.cos());
        assert!((x[1] + 1f64.sin()).abs() < 1e-10);
    }
}
