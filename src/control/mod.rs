//! Control laws. A controller is built once (all buffers allocated), then `step`ped once per
//! cycle without allocating. Parameter sets arrive from the optimiser; `validate` checks them at
//! the boundary and `swap_params` puts an accepted set in service without a bump in u.

pub mod computed_torque;
pub mod pd_servo;
pub mod pid;
pub mod state_feedback;
pub mod validate;

pub use computed_torque::ComputedTorque;
pub use pd_servo::PdServo;
pub use pid::{AntiWindup, Pid};
pub use state_feedback::StateFeedback;
pub use validate::{validate_params, LinearModel, ParamBounds, Rejection};

use crate::msg::PlantState;
use crate::reference::Setpoint;

pub trait Controller: Send {
    /// `msg::KIND_*` this controller accepts parameter sets for.
    fn kind(&self) -> u32;
    /// Number of tunable parameters.
    fn n_params(&self) -> usize;
    /// The parameters in service.
    fn params(&self) -> &[f64];
    /// Number of control outputs.
    fn n_outputs(&self) -> usize;
    /// One control cycle: read the state sample and the set-point, write u, advance internal
    /// state (integrators) to the next cycle. Must not allocate.
    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]);
    /// Put a validated parameter set in service at this cycle boundary, before `step`, adjusting
    /// internal state so that `step` on the same sample returns the same u as the old set would
    /// have (bumpless transfer). Laws without internal state cannot absorb the difference; they
    /// switch outright (the jump is proportional to the gain change times the tracking error).
    fn swap_params(&mut self, new: &[f64], state: &PlantState, sp: &Setpoint);
}

pub mod cycle;
pub use cycle::ControlCycle;
