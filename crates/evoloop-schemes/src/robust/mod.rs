//! Robust state feedback for linear plants (two-mass paper, papers/two-mass-robust-de-stability-radius.md):
//! continuous-time LQR, the complex stability radius by an H-infinity norm algorithm, the wedge
//! pole region, and the two-mass design problem that DE solves.

pub mod lqr;
pub mod observer;
pub mod pole_region;
pub mod problem;
pub mod stability_radius;
pub mod study;

pub use lqr::{lqr, LqrError, LqrSolution};
pub use observer::ObserverError;
pub use pole_region::{Wedge, WedgeError};
pub use problem::{augmented, Perturbation, RobustProblem};
pub use stability_radius::{hinf_norm, stability_radius, HinfError};
