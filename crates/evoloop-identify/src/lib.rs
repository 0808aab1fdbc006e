//! evoloop's identification of a plant from what its sensors recorded:
//!
//! - `identify`: an arm's base parameters by linear least squares from a run's recording, the
//!   excitation that makes them identifiable, and the study of both.
//! - `rkgnn`: the RKGNN paper's identification without torque measurements (the network fitted
//!   through Runge-Kutta-Gill by the paper's EA), identification alongside operation, and the
//!   studies of fuzzy selection among the identified models.

#![forbid(unsafe_code)]

pub mod identify;
pub mod rkgnn;

use evoloop_control::{law, plant, reference};
use evoloop_dynamics as dynamics;
use evoloop_files as files;
use evoloop_ipc as ipc;
use evoloop_linalg as linalg;
use evoloop_msg as msg;
use evoloop_optim as optim;
use evoloop_report as report;
use evoloop_scenario::{config, sim};
use evoloop_schemes::indirect;
use evoloop_stats as stats;
