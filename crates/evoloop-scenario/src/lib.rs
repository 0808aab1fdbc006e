//! evoloop's scenarios: `config`, one TOML file per scenario loaded into a checked `Scenario`
//! (every error names file, key and reason), and `sim`, the scenario's loop run in one process
//! (lockstep, no iceoryx2), which the studies, the model costs and the tests share.
//!
//! The lowest crate of evoloop's application layers, so it also holds the two output macros
//! (`out!`, `err!`) the crates above print with.

#![forbid(unsafe_code)]

/// Print a line to stdout, ignoring errors: a closed pipe (`evoloop run | head`) must not kill
/// the launcher while it supervises the processes.
#[macro_export]
macro_rules! out {
    ($($a:tt)*) => {{ use std::io::Write; let _ = writeln!(std::io::stdout(), $($a)*); }};
}
/// Print a line to stderr, ignoring errors (see `out!`).
#[macro_export]
macro_rules! err {
    ($($a:tt)*) => {{ use std::io::Write; let _ = writeln!(std::io::stderr(), $($a)*); }};
}

pub mod config;
pub mod sim;

use evoloop_control::{check, law, plant, reference};
use evoloop_files as files;
use evoloop_ipc as ipc;
use evoloop_msg as msg;
use evoloop_optim as optim;
use evoloop_rt as rt;
