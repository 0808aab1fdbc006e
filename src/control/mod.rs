//! Control laws. A controller is built once (all buffers allocated), then `step`ped once per
//! cycle without allocating. Parameter sets arrive from the optimiser; `validate` checks them at
//! the boundary and `swap_params` puts an accepted set in service without a bump in u.

pub mod state_feedback;
pub mod validate;

pub use state_feedback::StateFeedback;
pub use validate::{validate_params, ParamBounds, Rejection};

use crate::ipc::messages::PlantState;

pub trait Controller: Send {
    /// `ipc::messages::KIND_*` this controller accepts parameter sets for.
    fn kind(&self) -> u32;
    /// Number of tunable parameters.
    fn n_params(&self) -> usize;
    /// The parameters in service.
    fn params(&self) -> &[f64];
    /// Number of control outputs.
    fn n_outputs(&self) -> usize;
    /// One control cycle: read the state sample and reference, write u, advance internal state
    /// (integrators) to the next cycle. Must not allocate.
    fn step(&mut self, state: &PlantState, reference: f64, u: &mut [f64]);
    /// Put a validated parameter set in service at this cycle boundary, before `step`, adjusting
    /// internal state so that `step` on the same sample returns the same u as the old set would
    /// have (bumpless transfer).
    fn swap_params(&mut self, new: &[f64], state: &PlantState, reference: f64);
}

pub mod cycle;
pub use cycle::ControlCycle;
