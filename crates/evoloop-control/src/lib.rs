//! The control layer, without processes or I/O: the plants (two-mass, arm, maglev, heater,
//! arsinh; RK4 and the linear model), the control laws (state feedback, P-D servo, computed
//! torque with fuzzy model selection, PID with anti-windup, fuzzy networks), the signal filters
//! (the state-variable filter, the Savitzky-Golay smoother), the control cycle
//! that validates parameter sets at a cycle boundary, the references, and the configuration
//! checks each kind validates its table with. The same code runs in the controller and plant
//! processes, in an optimiser's model evaluation and in a test; the scenario loader, the
//! in-process loop and the processes are evoloop's, above.

#![forbid(unsafe_code)]

pub mod check;
pub mod filter;
pub mod fuzzy;
pub mod law;
pub mod plant;
pub mod reference;

// The crates below, under the names the modules use (`crate::msg`, `crate::dynamics`, ...).
use evoloop_dynamics as dynamics;
use evoloop_linalg as linalg;
use evoloop_msg as msg;
use evoloop_msg::{MAX_JOINTS, MAX_STATES};
use evoloop_optim as optim;
