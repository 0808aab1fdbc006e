//! Fuzzy networks and the fuzzy-network paper's controllers and experiments.

pub mod arsinh;
pub mod codec;
pub mod network;
pub mod ordered;

pub use network::{default_labels, FuzzyNetwork, FuzzyNetworkError, Mf, Variable, UNCONNECTED};
