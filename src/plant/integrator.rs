//! Classical fourth-order Runge-Kutta with its stage buffers allocated once.

use super::Plant;

pub struct Rk4 {
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    tmp: Vec<f64>,
}

impl Rk4 {
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
        let n = x.len();
        p.derivative(t, x, u, &mut self.k1);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * h * self.k1[i];
        }
        p.derivative(t + 0.5 * h, &self.tmp, u, &mut self.k2);
        for i in 0..n {
            self.tmp[i] = x[i] + 0.5 * h * self.k2[i];
        }
        p.derivative(t + 0.5 * h, &self.tmp, u, &mut self.k3);
        for i in 0..n {
            self.tmp[i] = x[i] + h * self.k3[i];
        }
        p.derivative(t + h, &self.tmp, u, &mut self.k4);
        for i in 0..n {
            x[i] += h / 6.0 * (self.k1[i] + 2.0 * self.k2[i] + 2.0 * self.k3[i] + self.k4[i]);
        }
    }
}
