//! A plant's linearisation, x' = A x + B u, y = C x, and its closed loop under state feedback
//! with integral action (two-mass paper, eq. 2): the integral state xi' = r - y and
//! u = -K [x; xi]. One place builds the augmented matrices: the controller's stability check,
//! the optimisers' acceptance rule and the robust design all use them.

use nalgebra::{Matrix5, Vector5};

/// The linear model a controller checks state-feedback gains against before use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearModel {
    pub a: [[f64; 4]; 4],
    pub b: [f64; 4],
    pub c: [f64; 4],
}

impl LinearModel {
    /// The augmented open loop (Â, B̂) = ([[A, 0], [-C, 0]], [B; 0]).
    pub fn augmented(&self) -> (Matrix5<f64>, Vector5<f64>) {
        let mut ah = Matrix5::zeros();
        for i in 0..4 {
            for j in 0..4 {
                ah[(i, j)] = self.a[i][j];
            }
            ah[(4, i)] = -self.c[i];
        }
        let b = self.b;
        (ah, Vector5::new(b[0], b[1], b[2], b[3], 0.0))
    }

    /// Â - B̂ K: the closed loop under u = -K [x; xi] (5 gains). Written out rather than as a
    /// matrix product so the integrator row stays exactly [-C, 0] whatever the gains.
    pub fn closed_loop(&self, gains: &[f64]) -> Matrix5<f64> {
        let (mut m, b) = self.augmented();
        for i in 0..4 {
            for j in 0..5 {
                m[(i, j)] -= b[i] * gains[j];
            }
        }
        m
    }

    /// Whether u = -K [x; xi] makes the augmented closed loop asymptotically stable (every
    /// eigenvalue in the open left half-plane). Stack-only (a fixed 5 x 5 Schur decomposition),
    /// so it can run inside the control cycle.
    pub fn stabilised_by(&self, gains: &[f64]) -> bool {
        if gains.len() != 5 {
            return false;
        }
        self.closed_loop(gains)
            .complex_eigenvalues()
            .iter()
            .all(|l| l.re < 0.0)
    }
}
