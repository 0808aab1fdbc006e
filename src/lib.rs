//! evoloop: soft real-time control loops whose controllers are tuned by evolutionary optimisers
//! while the plant runs.
//!
//! This crate is a facade: one name for each of the workspace's library crates, from the
//! bottom up (the manual's "Layout" chapter draws the graph; the compiler keeps its direction).
//! The algorithms (plants, control laws, references, optimisers, dynamics) know nothing of
//! processes or iceoryx2; `ipc` and `rt` are the only crates that touch shared memory, clocks and
//! scheduling, and `node` wires the two together into the process loops. So a control law runs
//! the same in the controller process, in an optimiser's model evaluation and in a unit test.
//! The command line is crate `evoloop-cli`, which the binaries in `bin/` call.

#![forbid(unsafe_code)]

pub use evoloop_control::{check, filter, fuzzy, law, plant, reference};
pub use evoloop_dynamics as dynamics;
pub use evoloop_files as files;
pub use evoloop_identify::{identify, rkgnn};
pub use evoloop_ipc as ipc;
pub use evoloop_linalg as linalg;
pub use evoloop_msg as msg;
#[cfg(feature = "zenoh")]
pub use evoloop_net as net;
pub use evoloop_optim as optim;
pub use evoloop_report as report;
pub use evoloop_rkgnn as rkgnn_model;
pub use evoloop_rt as rt;
pub use evoloop_run::{bench, needs_zenoh, node, run_report, run_watch, soak};
pub use evoloop_scenario::{config, sim};
pub use evoloop_schemes::{direct, gains, indirect, jobs, robust, SchemeError, WriteError};
pub use evoloop_stats as stats;
pub use evoloop_tune as tune;

pub use evoloop_msg::{MAX_JOINTS, MAX_PARAMS, MAX_STATES};

/// Give this process the network (Eclipse Zenoh: evaluation workers, a remote optimiser, the
/// bridge and worker commands) when built with the `zenoh` feature; every binary calls it
/// first. Without the feature it does nothing, and every network option is refused by name.
pub fn install_network() {
    #[cfg(feature = "zenoh")]
    evoloop_net::install();
}
