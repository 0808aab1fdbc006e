//! `evoloop bench ...`: latency benchmarks measured against the machine's own floor in the same
//! run.

pub mod latency;
pub mod loop_bench;
