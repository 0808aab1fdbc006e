//! A run of evoloop: its processes and what measures and reports them.
//!
//! - `node`: the process loops (plant, controller, optimiser), the launcher that starts,
//!   supervises and stops them, the live view's server and the replay.
//! - `run_report`: the report built after a run (report.html, plots, summary.json, seeds).
//! - `bench`: the latency and loop benchmarks, against raw iceoryx2 and the bare loop.
//! - `network`: what a run asks of the network (Zenoh), which crate `evoloop-net` provides.
//! - `soak`, `run_watch`: a long run's accounting, and what `evoloop top` and the live view
//!   gather of a running run.

#[macro_use]
extern crate evoloop_scenario;

pub mod bench;
pub mod network;
pub mod node;
pub mod run_report;
pub mod run_watch;
pub mod soak;

/// The message for `what` (a command, an option, a key) in a build without the `zenoh` feature.
pub fn needs_zenoh(what: &str) -> String {
    format!("{what} needs evoloop built with the zenoh feature (cargo build --release --features zenoh)")
}

use evoloop_control::{law, plant, reference};
use evoloop_dynamics as dynamics;
use evoloop_files as files;
use evoloop_identify::rkgnn;
use evoloop_ipc as ipc;
use evoloop_msg as msg;
use evoloop_optim as optim;
use evoloop_report as report;
use evoloop_rt as rt;
use evoloop_scenario::{config, sim};
use evoloop_schemes::{direct, gains, indirect};
use evoloop_stats as stats;
