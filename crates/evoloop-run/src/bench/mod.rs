//! `evoloop bench ...`: latency benchmarks measured against the machine's own floor in the same
//! run, and the per-call cost of the dynamics algorithms.

/// `evoloop bench bridge`: the Zenoh bridge's round trip (feature `zenoh`).
#[cfg(feature = "zenoh")]
pub mod bridge;
pub mod dynamics;
pub mod latency;
pub mod loop_bench;
/// `evoloop bench workers`: populations spread over evaluation workers (feature `zenoh`).
#[cfg(feature = "zenoh")]
pub mod workers;
