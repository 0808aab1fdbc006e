//! The run's report: the materials of crate `evoloop-report` (logs, CSV, the recording, metrics,
//! plots, the HTML page), re-exported whole, and here what reads a scenario and its results to
//! build the report (`build`, which also runs the frozen comparison's simulation), summary.json
//! (`summary`) and multi-seed studies (`seeds_study`).

pub use evoloop_report::*;

pub mod build;
pub mod seeds_study;
pub mod summary;
