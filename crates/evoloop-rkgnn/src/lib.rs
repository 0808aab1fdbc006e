//! An RKGNN-identified arm model as the controller uses it: the function network N_f of
//! shape-adaptive RBF sub-networks (the RKGNN paper's eqs. 6-10: M-hat, V-hat, G-hat and the
//! servo's torque) and the model file that carries it with its premise and the identification's
//! report. Below the control laws (fuzzy computed torque evaluates it every cycle,
//! allocation-free); the identification that fits it is evoloop's `rkgnn` module, above them.

pub mod model;
pub mod network;

pub use model::{ModelFile, Report, RkgnnModel, ServoPrior, Start};
pub use network::{Layout, Network, RbfCounts};
