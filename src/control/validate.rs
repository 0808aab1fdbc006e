//! Validation of an incoming parameter set, before it can touch the running loop.

use crate::msg::{ParamCode, ParamSet};

pub use crate::check::ParamBounds;

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
