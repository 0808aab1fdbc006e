//! One controller cycle as the controller process runs it, shared with the in-process simulation
//! so both compute the same numbers: take due parameter sets, validate and swap them in at the
//! cycle boundary, evaluate the reference and the control law, fill the telemetry.

use super::validate::validate_model;
use super::{validate_params, Controller, LinearModel, ParamBounds};
use crate::msg::{ParamCode, ParamSet, PlantState, Telemetry};
use crate::reference::{Reference, Setpoint};
use crate::MAX_JOINTS;

/// Capacity of the queue of parameter sets waiting for their cycle.
pub const PENDING_CAPACITY: usize = 16;

/// A parameter-set event, for the run's record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamEvent {
    pub cycle: u64,
    pub t: f64,
    pub version: u64,
    pub code: ParamCode,
    pub index: u32,
}

pub struct ControlCycle {
    pub controller: Box<dyn Controller>,
    pub reference: Reference,
    bounds: ParamBounds,
    version: u64,
    /// Sets received but not yet due (lockstep: `apply_at_seq` in the future). Preallocated.
    pending: Vec<ParamSet>,
    /// Sets dropped because the queue was full.
    pub pending_dropped: u64,
    pub u: [f64; MAX_JOINTS],
    /// The set-point of the last cycle (all joints).
    pub setpoint: Setpoint,
    /// Linear plants: new gains must stabilise this model to be accepted.
    stability: Option<LinearModel>,
    cycle: u64,
    /// How many values the law logs (`Controller::log_columns`); telemetry carries them all.
    n_law: usize,
}

/// The number of the law's own values, which telemetry carries (at most `MAX_LAW_VALUES`: a
/// law's contract, checked once here).
fn law_columns(c: &dyn Controller) -> usize {
    let n = c.log_columns().len();
    assert!(
        n <= crate::msg::MAX_LAW_VALUES,
        "a control law logs {n} values, telemetry carries {}",
        crate::msg::MAX_LAW_VALUES
    );
    n
}

impl ControlCycle {
    pub fn new(controller: Box<dyn Controller>, reference: Reference, bounds: ParamBounds) -> Self {
        Self {
            reference,
            bounds,
            version: 0,
            pending: Vec::with_capacity(PENDING_CAPACITY),
            pending_dropped: 0,
            u: [0.0; MAX_JOINTS],
            setpoint: Setpoint::default(),
            stability: None,
            cycle: 0,
            n_law: law_columns(controller.as_ref()),
            controller,
        }
    }

    /// Check every new set for closed-loop stability on `model` before it is used.
    pub fn with_stability_check(mut self, model: Option<LinearModel>) -> Self {
        self.stability = model;
        self
    }

    /// Parameter version in service (0 = the configured initial set).
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Queue a received parameter set; it is looked at in the cycle it is due. Never allocates.
    pub fn offer(&mut self, set: &ParamSet) {
        if self.pending.len() < PENDING_CAPACITY {
            self.pending.push(*set);
        } else {
            self.pending_dropped += 1;
        }
    }

    /// Run one cycle on `state`; returns u and fills `tel` (all but the timing fields), and the
    /// parameter event of this cycle if one happened. At most one set is handled per cycle, so
    /// each accept/reject gets its own telemetry record.
    pub fn step(&mut self, state: &PlantState, tel: &mut Telemetry) -> Option<ParamEvent> {
        self.reference.sample(state.t, &mut self.setpoint);
        let sp = self.setpoint;
        let mut event = None;
        if let Some(i) = self
            .pending
            .iter()
            .position(|p| p.apply_at_seq <= state.seq)
        {
            let set = self.pending.remove(i);
            let (code, index) = match self.apply(&set, state, &sp) {
                Ok(()) => {
                    self.version = set.version;
                    (ParamCode::Accepted, 0)
                }
                Err(refusal) => refusal,
            };
            event = Some(ParamEvent {
                cycle: self.cycle,
                t: state.t,
                version: set.version,
                code,
                index,
            });
        }
        let n_u = self.controller.n_outputs();
        self.controller.step(state, &sp, &mut self.u[..n_u]);
        tel.cycle = self.cycle;
        tel.state_seq = state.seq;
        tel.t = state.t;
        tel.reference = sp.q[0];
        tel.tracking_error = sp.q[0] - state.y[0];
        tel.n_u = n_u as u32;
        tel.u = self.u;
        tel.param_version = self.version;
        tel.n_law = self.n_law as u32;
        self.controller.log_values(&mut tel.law[..self.n_law]);
        match event {
            Some(e) => {
                tel.param_code = e.code as u32;
                tel.param_event_version = e.version;
                tel.param_index = e.index;
            }
            None => {
                tel.param_code = ParamCode::None as u32;
                tel.param_event_version = 0;
                tel.param_index = 0;
            }
        }
        self.cycle += 1;
        event
    }

    /// Check a due set and put it in service: a model set (the law's `model_kind`) through the
    /// common checks and the law's own, a gain set through kind, length, bounds and, for linear
    /// plants, stability. The refusal's code and offending index otherwise.
    fn apply(
        &mut self,
        set: &ParamSet,
        state: &PlantState,
        sp: &Setpoint,
    ) -> Result<(), (ParamCode, u32)> {
        let c = self.controller.as_ref();
        let refused = |r: super::Rejection| (r.code, r.index);
        if c.model_kind() == Some(set.kind) {
            validate_model(set, self.version).map_err(refused)?;
            return self.controller.swap_model(set.values());
        }
        validate_params(set, c.kind(), c.n_params(), self.version, &self.bounds)
            .map_err(refused)?;
        if self
            .stability
            .is_some_and(|m| !m.stabilised_by(set.values()))
        {
            return Err((ParamCode::RejectedUnstable, 0));
        }
        self.controller.swap_params(set.values(), state, sp);
        Ok(())
    }
}
