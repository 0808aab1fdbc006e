//! The network's benchmarks: `evoloop bench bridge` (a parameter set's round trip through the
//! bridge against the local path) and `evoloop bench workers` (populations spread over
//! evaluation workers).

pub mod bridge;
pub mod workers;
