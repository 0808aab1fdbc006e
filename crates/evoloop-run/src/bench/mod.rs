//! `evoloop bench ...`: latency benchmarks measured against the machine's own floor in the same
//! run, and the per-call cost of the dynamics algorithms.

pub mod dynamics;
pub mod latency;
pub mod loop_bench;
