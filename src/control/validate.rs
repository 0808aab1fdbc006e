//! Validation of an incoming parameter set, before it can touch the running loop.

use crate::msg::{ParamCode, ParamSet};

/// Per-parameter inclusive bounds from the config.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamBounds {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
}

/// Why a set was refused, and which value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rejection {
    pub code: ParamCode,
    pub index: u32,
}

/// Check kind, version, length, finiteness and bounds, in that order. Allocation-free.
pub fn validate_params(
    set: &ParamSet,
    kind: u32,
    n_params: usize,
    version_in_service: u64,
    bounds: &ParamBounds,
) -> Result<(), Rejection> {
    let reject = |code, index| Err(Rejection { code, index });
    if set.kind != kind {
        return reject(ParamCode::RejectedWrongKind, 0);
    }
    if set.version <= version_in_service {
        return reject(ParamCode::RejectedStale, 0);
    }
    if set.n as usize != n_params {
        return reject(ParamCode::RejectedWrongLength, set.n);
    }
    for (i, v) in set.values().iter().enumerate() {
        if !v.is_finite() {
            return reject(ParamCode::RejectedNonFinite, i as u32);
        }
    }
    for (i, v) in set.values().iter().enumerate() {
        if *v < bounds.lower[i] || *v > bounds.upper[i] {
            return reject(ParamCode::RejectedOutOfBounds, i as u32);
        }
    }
    Ok(())
}

/// The linear plant model a controller checks state-feedback gains against before use:
/// x' = A x + B u, y = C x, with the integral state xi' = r - y and u = -K [x; xi].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearModel {
    pub a: [[f64; 4]; 4],
    pub b: [f64; 4],
    pub c: [f64; 4],
}

impl LinearModel {
    /// Whether u = -K [x; xi] makes the augmented closed loop asymptotically stable (every
    /// eigenvalue of [[A - B K_x, -B k_5], [-C, 0]] in the open left half-plane). Stack-only
    /// (a fixed 5 x 5 Schur decomposition), so it can run inside the control cycle.
    pub fn stabilised_by(&self, gains: &[f64]) -> bool {
        if gains.len() != 5 {
            return false;
        }
        let mut m = nalgebra::Matrix5::<f64>::zeros();
        for i in 0..4 {
            for j in 0..4 {
                m[(i, j)] = self.a[i][j] - self.b[i] * gains[j];
            }
            m[(i, 4)] = -self.b[i] * gains[4];
            m[(4, i)] = -self.c[i];
        }
        m.complex_eigenvalues().iter().all(|l| l.re < 0.0)
    }
}
