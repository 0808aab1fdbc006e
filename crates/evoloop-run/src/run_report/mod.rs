//! What reads a scenario and its results to build the run's report out of crate
//! `evoloop-report`'s materials: `build` (the report, which also runs the frozen comparison's
//! simulation), `summary` (summary.json) and `seeds_study` (a run over many seeds).

pub mod build;
pub mod seeds_study;
pub mod summary;
