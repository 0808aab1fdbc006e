//! The process loops: plant, controller and optimiser. Each is a separate process of a run; the
//! launcher starts them as `evoloop plant|controller|optimiser ...` (its own executable, so one
//! `cargo build` of `evoloop` gives everything a run needs), and the thin `evoloop-plant`,
//! `evoloop-controller` and `evoloop-optimiser` binaries call the same functions for users who
//! start the processes by hand or under their own supervisor.

pub mod args;
pub mod controller;
pub mod external;
pub mod launcher;
pub mod live;
pub mod optimiser;
pub mod plant;
pub mod replay;
pub mod start;
