//! An RKGNN-identified arm model as the controller uses it: the function network N_f of
//! shape-adaptive RBF sub-networks (the RKGNN paper's eqs. 6-10: M-hat, V-hat, G-hat and the
//! servo's torque) and the model file that carries it with its premise and the identification's
//! report. Below the control laws (fuzzy computed torque evaluates it every cycle,
//! allocation-free); the identification that fits it is evoloop's `rkgnn` module, above them.

#![forbid(unsafe_code)]

pub mod model;
pub mod network;

pub use model::{ModelFile, Report, RkgnnModel, ServoPrior, Start};
pub use network::{Layout, Network, RbfCounts};

/// Half width T of the identification's low-pass by default, s (`identify rkgnn --smoothing`):
/// a local quadratic fit over +-T (161 samples at 1 kHz), -3 dB near 6.4 Hz on the positions and
/// 3.6 Hz on the velocities. It passes the arms' references (harmonics of 0.1-0.7 Hz: a velocity
/// is underestimated by (omega T)^2 / 10, 1.2 % at 0.7 Hz) and cuts encoder noise of std 1e-4
/// rad to 2e-4 rad/s on the velocity. Chosen from data alone, as a user would: the window with
/// the smallest held-out free-run prediction error (`holdout_rms`) on arm3's training runs over
/// 0.04-0.2 s (the book's Arms chapter has the sweep, and why tracking is not the criterion).
pub const SMOOTHING: f64 = 0.08;
