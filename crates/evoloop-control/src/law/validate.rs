//! Validation of an incoming parameter set, before it can touch the running loop.

use crate::msg::{ParamCode, ParamKind, ParamSet};

pub use crate::check::ParamBounds;

/// Why a set was refused, and which value.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rejection {
    /// Why: one of the `ParamCode::Rejected*` codes.
    pub code: ParamCode,
    /// The offending value's index: the length received for a wrong length, 0 when no one value is
    /// at fault.
    pub index: u32,
}

/// Check kind, version, length, finiteness and bounds, in that order. Allocation-free.
pub fn validate_params(
    set: &ParamSet,
    kind: ParamKind,
    n_params: usize,
    version_in_service: u64,
    bounds: &ParamBounds,
) -> Result<(), Rejection> {
    let reject = |code, index| Err(Rejection { code, index });
    // An unknown code reads as an error, never as this kind.
    if set.param_kind() != Ok(kind) {
        return reject(ParamCode::RejectedWrongKind, 0);
    }
    newer(set, version_in_service)?;
    if set.n as usize != n_params {
        return reject(ParamCode::RejectedWrongLength, set.n);
    }
    finite(set)?;
    for (i, v) in set.values().iter().enumerate() {
        if *v < bounds.lower[i] || *v > bounds.upper[i] {
            return reject(ParamCode::RejectedOutOfBounds, i as u32);
        }
    }
    Ok(())
}

/// The checks every set passes whatever its kind: newer than the one in service, every value
/// finite. A model set (`Controller::model_kind`) gets these, then the law's own
/// (`Controller::swap_model`: slot, length, M-hat positive definite). Allocation-free.
pub fn validate_model(set: &ParamSet, version_in_service: u64) -> Result<(), Rejection> {
    newer(set, version_in_service)?;
    finite(set)
}

fn newer(set: &ParamSet, version_in_service: u64) -> Result<(), Rejection> {
    if set.version <= version_in_service {
        return Err(Rejection {
            code: ParamCode::RejectedStale,
            index: 0,
        });
    }
    Ok(())
}

fn finite(set: &ParamSet) -> Result<(), Rejection> {
    match set.values().iter().position(|v| !v.is_finite()) {
        Some(i) => Err(Rejection {
            code: ParamCode::RejectedNonFinite,
            index: i as u32,
        }),
        None => Ok(()),
    }
}
