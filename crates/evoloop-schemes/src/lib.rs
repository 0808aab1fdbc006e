//! evoloop's tuning schemes, the layer between a scenario and the processes:
//!
//! - `direct`: the optimiser's experiments run on the plant itself (hold, resume, revert).
//! - `indirect`: the plant estimated online (RLS, state-variable filters, Kalman) and the
//!   controller tuned on the estimate; only a better, validated set reaches the loop.
//! - `robust`: robust state feedback by DE (the two-mass paper): LQR, observers, pole regions,
//!   stability radii.
//! - `jobs`: the model costs an evaluation worker can rebuild from their description.
//! - `gains`: the controller's tunable values as one parameter a process outside the loop sets.

#![forbid(unsafe_code)]

pub mod direct;
pub mod error;
pub mod gains;
pub mod indirect;
pub mod jobs;
pub mod robust;

pub use error::{SchemeError, WriteError};

use evoloop_control::{check, filter, law, plant, reference};
use evoloop_files as files;
use evoloop_ipc as ipc;
use evoloop_linalg as linalg;
use evoloop_msg as msg;
use evoloop_optim as optim;
use evoloop_report as report;
use evoloop_scenario::{config, sim};
