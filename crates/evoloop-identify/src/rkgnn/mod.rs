//! Identification of an arm's dynamics without torque measurements and control by fuzzy
//! selection among the identified models: the RKGNN paper
//! (`../shared/papers/rkgnn-computed-torque-fuzzy-model-selection.md`).
//!
//! The model these fit, its function network N_f of shape-adaptive RBF sub-networks (eqs.
//! 6-10) and its file (`MODEL.json`) are crate `evoloop-rkgnn` (`evoloop::rkgnn_model`), below
//! the control laws that evaluate them.
//!
//! - the evolutionary algorithm of Section 4 (chaotic mutation, strategic moves) is
//!   `optim::chaotic`, beside the other optimisers.
//! - `data`: reference and output data from a run's `run.csv`, never the torques.
//! - `identify`: the RKGNN (Runge-Kutta-Gill around N_f, `plant::gill`) fitted by eq. 13.
//! - `refine`: Levenberg-Marquardt on the free-run output error (after the least squares).
//! - `live`: identification alongside operation (`optimiser.mode = "identify"`).
//! - `model_error`: a model's M, V and G against the arm's along a path.
//! - `study`: Section 5 on any 3-joint arm (`evoloop rkgnn study`, Figs. 7-10).
//! - `selection`: fuzzy selection against every baseline on trajectories that are not
//!   midpoints (`evoloop rkgnn selection`).
//! - `zoo`: the selection study on every arm of a zoo, one table (`evoloop rkgnn zoo`).
//!
//! The controller that uses the models is `law::fuzzy_computed_torque`, the selection rule
//! `law::fuzzy_select`.

pub mod data;
pub(crate) mod error;
pub mod identify;
pub mod live;
pub mod model_error;
pub mod refine;
pub mod selection;
pub mod study;
pub mod zoo;

pub use data::Trajectory;
pub use error::{RkgnnError, StudyError};
