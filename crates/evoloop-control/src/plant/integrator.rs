//! Classical fourth-order Runge-Kutta with its stage buffers allocated once.

use super::Plant;

/// The classical fourth-order Runge-Kutta integrator, with its stage buffers for an `n`-state
/// plant; `step` never allocates.
pub struct Rk4 {
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    tmp: Vec<f64>,
}

impl Rk4 {
    /// An integrator for plants of `n` states.
    pub fn new(n: usize) -> Self {
        Self {
            k1: vec![0.0; n],
            k2: vec![0.0; n],
            k3: vec![0.0; n],
            k4: vec![0.0; n],
            tmp: vec![0.0; n],
        }
    }

    /// One step of size h from (t, x) with u held; x is updated in place.
    pub fn step(&mut self, p: &dyn Plant, t: f64, x: &mut [f64], u: &[f64], h: f64) {
        fn stage(tmp: &mut [f64], x: &[f64], k: &[f64], a: f64) {
            for ((ti, xi), ki) in tmp.iter_mut().zip(x).zip(k) {
                *ti = xi + a * ki;
            }
        }
        p.derivative(t, x, u, &mut self.k1);
        stage(&mut self.tmp, x, &self.k1, 0.5 * h);
        p.derivative(t + 0.5 * h, &self.tmp, u, &mut self.k2);
        stage(&mut self.tmp, x, &self.k2, 0.5 * h);
        p.derivative(t + 0.5 * h, &self.tmp, u, &mut self.k3);
        stage(&mut self.tmp, x, &self.k3, h);
        p.derivative(t + h, &self.tmp, u, &mut self.k4);
        for (i, xi) in x.iter_mut().enumerate() {
            *xi += h / 6.0 * (self.k1[i] + 2.0 * self.k2[i] + 2.0 * self.k3[i] + self.k4[i]);
        }
    }
}
