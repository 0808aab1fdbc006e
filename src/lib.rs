//! evoloop: soft real-time control loops whose controllers are tuned by evolutionary optimisers
//! while the plant runs.
//!
//! The library holds everything the processes share. The algorithms (plants, control laws,
//! references) know nothing of processes or iceoryx2; `ipc` and `rt` are the only modules that
//! touch shared memory, clocks and scheduling, and `node` wires the two together into the process loops (the binaries in `bin/` are thin).
//! So a control law runs the same in the controller process, in an optimiser's model evaluation
//! and in a unit test.

/// Print a line to stdout, ignoring errors: a closed pipe (`evoloop run | head`) must not kill
/// the launcher while it supervises the processes.
macro_rules! out {
    ($($a:tt)*) => {{ use std::io::Write; let _ = writeln!(std::io::stdout(), $($a)*); }};
}
/// Print a line to stderr, ignoring errors (see `out!`).
macro_rules! err {
    ($($a:tt)*) => {{ use std::io::Write; let _ = writeln!(std::io::stderr(), $($a)*); }};
}

pub mod bench;
pub mod cli;
pub mod config;
pub mod direct;
pub mod gains;
pub use evoloop_control::{check, control, fuzzy, plant, reference};
pub use evoloop_dynamics as dynamics;
pub use evoloop_files as files;
pub use evoloop_linalg as linalg;
pub use evoloop_stats as stats;
pub mod identify;
pub mod indirect;
pub use evoloop_ipc as ipc;
pub mod jobs;
pub use evoloop_msg as msg;
#[cfg(feature = "zenoh")]
pub mod net;
pub mod node;
pub mod optim;
pub mod report;
pub mod rkgnn;
pub mod robust;
pub use evoloop_rt as rt;
pub mod sim;
pub mod soak;
pub mod top;
pub mod tune;

pub use evoloop_msg::{MAX_JOINTS, MAX_PARAMS, MAX_STATES};

/// The message for `what` (a command, an option, a key) in a build without the `zenoh` feature.
pub fn needs_zenoh(what: &str) -> String {
    format!("{what} needs evoloop built with the zenoh feature (cargo build --release --features zenoh)")
}
