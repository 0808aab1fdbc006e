//! `evoloop bench ...`: latency benchmarks measured against the machine's own floor in the same
//! run, the per-call cost of the dynamics algorithms, and the hot paths' guard.

pub mod dynamics;
pub mod guard;
pub mod latency;
pub mod loop_bench;
