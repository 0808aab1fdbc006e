//! One controller cycle as the controller process runs it, shared with the in-process simulation
//! so both compute the same numbers: take due parameter sets, validate and swap them in at the
//! cycle boundary, evaluate the reference and the control law, fill the telemetry.

use super::model_parts::{Gather, Gathered};
use super::state_check::{Refused, StateCheck, StateFault};
use super::validate::validate_model;
use super::{validate_params, Controller, LinearModel, ParamBounds};
use crate::msg::{
    ParamCode, ParamKind, ParamSet, PlantState, Telemetry, TELEMETRY_FLAG_REFUSED_STATE,
};
use crate::reference::{Reference, Setpoint};
use crate::MAX_JOINTS;

/// Capacity of the queue of parameter sets waiting for their cycle.
pub const PENDING_CAPACITY: usize = 16;

/// The safety envelope trial sets (the direct scheme's candidates) run under: a trial is aborted,
/// its fallback restored in the same cycle, when any joint's tracking error |r - y| exceeds
/// `error`, any measured output |y| exceeds `output` (e.g. the ball nearing the magnet or its
/// catcher) or any command |u| exceeds `control`. Infinite bounds: no envelope.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Envelope {
    /// The largest tracking error |r - y| a trial may reach on any joint, in the output's unit.
    pub error: f64,
    /// The largest measured output |y| a trial may reach on any joint, in the output's unit.
    pub output: f64,
    /// The largest command |u| a trial may give on any input, in the command's unit (N m, V ...).
    pub control: f64,
}

impl Default for Envelope {
    fn default() -> Self {
        Self {
            error: f64::INFINITY,
            output: f64::INFINITY,
            control: f64::INFINITY,
        }
    }
}

impl Envelope {
    /// How far inside the envelope one sample is, at its closest: the smallest of 1 - |r - y| /
    /// error, 1 - |y| / output and 1 - |u| / control over the joints and inputs (1 with no
    /// limits, 0 on the boundary, negative outside; -1 for a NaN). The direct scheme's safety
    /// measure for an optimiser that models safety.
    pub fn margin(&self, r: &[f64], y: &[f64], u: &[f64]) -> f64 {
        let e = r
            .iter()
            .zip(y)
            .map(|(r, y)| (1.0 - (r - y).abs() / self.error).min(1.0 - y.abs() / self.output));
        let m = e
            .chain(u.iter().map(|u| 1.0 - u.abs() / self.control))
            .fold(1.0f64, |m, v| {
                if v.is_nan() {
                    f64::NEG_INFINITY
                } else {
                    m.min(v)
                }
            });
        m.max(-1.0)
    }

    /// NaN counts as outside.
    fn left_by_error(&self, sp: &Setpoint, state: &PlantState, n: usize) -> bool {
        (0..n).any(|j| {
            let inside =
                (sp.q[j] - state.y[j]).abs() <= self.error && state.y[j].abs() <= self.output;
            !inside
        })
    }
    fn left_by_control(&self, u: &[f64]) -> bool {
        u.iter().any(|v| v.is_nan() || v.abs() > self.control)
    }
}

/// A parameter-set event, for the run's record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamEvent {
    /// The cycle the event happened in (`ControlCycle::next_cycle` before that `step`).
    pub cycle: u64,
    /// The plant time of the state that cycle ran on, s.
    pub t: f64,
    /// The version of the set it concerns: the set received, the trial that ended or was aborted,
    /// or the half-gathered model a newer one displaced.
    pub version: u64,
    /// What happened: accepted, refused (and why), or a trial ended or aborted.
    pub code: ParamCode,
    /// For a refusal, the index of the offending value (the length received, for a wrong length); 0
    /// otherwise.
    pub index: u32,
}

/// One controller's cycle (see the module docs): the law, the reference, the sets waiting for their
/// cycle, the trial in service and its fallback, and the checks a set and a state must pass. Built
/// once; `step` does not allocate.
pub struct ControlCycle {
    /// The control law, stepped once per cycle.
    pub controller: Box<dyn Controller>,
    /// The reference, sampled at each state's time for the cycle's set-point.
    pub reference: Reference,
    bounds: ParamBounds,
    version: u64,
    /// Sets received but not yet due (lockstep: `apply_at_seq` in the future). Preallocated.
    pending: Vec<ParamSet>,
    /// Sets dropped because the queue was full.
    pub pending_dropped: u64,
    /// The command of the last cycle: the law's outputs in the first `n_outputs` entries, or the
    /// safe command for a refused state.
    pub u: [f64; MAX_JOINTS],
    /// The set-point of the last cycle (all joints).
    pub setpoint: Setpoint,
    /// Linear plants: new gains must stabilise this model (the configured plant's) to be
    /// accepted ...
    stability: Option<LinearModel>,
    /// ... and, once the optimiser's estimate of the plant has been adopted, this one too.
    estimated: Option<LinearModel>,
    /// The law's filter designed again on an adopted estimate: how often, and how often no
    /// stable filter came of it (the last one kept).
    pub filters_designed: u64,
    /// How often a redesign gave no stable filter (the last one kept).
    pub filters_refused: u64,
    cycle: u64,
    /// How many values the law logs (`Controller::log_columns`); telemetry carries them all.
    n_law: usize,
    envelope: Envelope,
    /// The set a trial falls back to: the last set put in service for good (at first the
    /// configured parameters, version 0), or a trial a later trial named. Boxed: allocated once.
    fallback: Box<ParamSet>,
    /// The last trial put in service, which the next trial may name as its fallback while
    /// `last_trial_live` (not after a set for good or an abort). Boxed and allocated here, so a
    /// trial never allocates in the cycle.
    last_trial: Box<ParamSet>,
    last_trial_live: bool,
    /// While a trial is in service: the state sequence number at which it ends.
    trial_until: Option<u64>,
    /// Trials isolated from the set in service (`with_isolated_trials`).
    isolated_trials: bool,
    /// Trials aborted for leaving the envelope.
    pub trials_aborted: u64,
    /// A model larger than one set, gathered from its parts.
    parts: Gather,
    /// What each plant state must be to run the law on (none: every state is taken).
    state_check: Option<StateCheck>,
    /// The states refused by `state_check`, and those refused before the cycle (`refuse`).
    pub refused: Refused,
    /// A sample refused before this cycle (realtime: it broke time), its seq and why: the
    /// cycle sends the safe command as for a state `state_check` refuses.
    refuse: Option<(u64, StateFault)>,
}

/// What a due set did.
enum Applied {
    /// Now in service.
    InService,
    /// A part of a model, kept until its last part (no event: the whole gets one), and the
    /// version of a half-gathered model it displaced (refused in this cycle's event).
    Gathered { dropped: Option<u64> },
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

/// The parameters `c` runs now as a set of `version` (the fallback before any set arrives).
fn current_set(c: &dyn Controller, version: u64) -> ParamSet {
    ParamSet::new(version, 0, c.kind(), c.params())
}

impl ControlCycle {
    /// A cycle running `controller` on `reference`, its gain sets checked against `bounds`. The
    /// law's configured parameters are version 0 and the first fallback; there is no state check,
    /// envelope, isolation or stability check until the `with_*` builders add them.
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
            estimated: None,
            filters_designed: 0,
            filters_refused: 0,
            cycle: 0,
            n_law: law_columns(controller.as_ref()),
            envelope: Envelope::default(),
            fallback: Box::new(current_set(controller.as_ref(), 0)),
            last_trial: Box::default(),
            last_trial_live: false,
            trial_until: None,
            isolated_trials: false,
            trials_aborted: 0,
            parts: Gather::new(controller.model_len()),
            state_check: None,
            refused: Refused::default(),
            refuse: None,
            controller,
        }
    }

    /// Refuse states that fail `check` (`state_check`): the law skips them and the plant's safe
    /// command goes out instead.
    pub fn with_state_check(mut self, check: StateCheck) -> Self {
        self.state_check = Some(check);
        self
    }

    /// Run trial sets under `envelope`.
    pub fn with_envelope(mut self, envelope: Envelope) -> Self {
        self.envelope = envelope;
        self
    }

    /// Isolated trials (the direct scheme with settle segments, `optimiser.settle`): a trial
    /// starts from the law's state as the set in service left it (its integrator as it was, no
    /// bumpless transfer moving the P-D difference into it), and when it ends the set in service
    /// resumes from the state it had when the trial began, as after an abort. So a trial's cost
    /// depends on the set tried and the state the set in service settled to, not on the gain
    /// step at its boundaries: with a bumpless swap at a set-point step, and on an integrating
    /// plant, the P difference moved into the integrator is a drift that grows with the step.
    pub fn with_isolated_trials(mut self, isolated: bool) -> Self {
        self.isolated_trials = isolated;
        self
    }

    /// Whether a trial set is in service.
    pub fn in_trial(&self) -> bool {
        self.trial_until.is_some()
    }

    /// Check every new set for closed-loop stability on `model` before it is used.
    pub fn with_stability_check(mut self, model: Option<LinearModel>) -> Self {
        self.stability = model;
        self
    }

    /// Check new sets on `model` too from now on (the latest estimate of the plant adopted),
    /// when sets are checked for stability at all. The configured model stays in the check: an
    /// estimate may be wrong, and the tuner's own robustness margin is narrow (two-mass: stable
    /// at 0.8 to 1.25 times its estimate).
    pub fn check_on(&mut self, model: LinearModel) {
        if self.stability.is_some() {
            self.estimated = Some(model);
        }
    }

    /// A law that runs on a model-based filter designs it again on `model`, the latest estimate
    /// of the plant adopted (`Controller::adopt_model`), for the samples after this one: the
    /// loop calls it once the cycle's command is out, so the design (tens of microseconds)
    /// never delays a command. Allocation-free.
    pub fn redesign_on(&mut self, model: &LinearModel) {
        match self.controller.adopt_model(model) {
            Some(true) => self.filters_designed += 1,
            Some(false) => self.filters_refused += 1,
            None => {}
        }
    }

    /// The number of the next cycle `step` runs (its telemetry's and command's `cycle`).
    pub fn next_cycle(&self) -> u64 {
        self.cycle
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

    /// Have the next `step` refuse its state: sample `seq`, refused before the cycle for
    /// `fault`, is answered with the safe command and counted, as a state `state_check` refuses.
    pub fn refuse(&mut self, seq: u64, fault: StateFault) {
        self.refuse = Some((seq, fault));
    }

    /// Run one cycle on `state`: handle the due set (at most one), end or abort a trial, run the
    /// law into `u` (or the safe command for a refused state) and fill `tel` (all but the timing
    /// fields). Returns the cycle's parameter event, if one happened. At most one set is handled
    /// per cycle, so each accept/reject gets its own telemetry record; a trial's end or abort in
    /// the same cycle shows in the version in service (an abort is recorded in place of the
    /// acceptance).
    pub fn step(&mut self, state: &PlantState, tel: &mut Telemetry) -> Option<ParamEvent> {
        if let Some(check) = self.state_check {
            let refused = self.refuse.take();
            let judged = || check.judge(state).err().map(|f| (state.seq, f));
            if let Some((seq, fault)) = refused.or_else(judged) {
                self.refused.note(seq, fault);
                if state.t.is_finite() {
                    self.reference.sample(state.t, &mut self.setpoint);
                }
                let n_u = self.controller.n_outputs();
                self.u[..n_u].fill(check.safe_command);
                self.telemetry(state, None, tel);
                tel.flags = TELEMETRY_FLAG_REFUSED_STATE;
                self.cycle += 1;
                return None;
            }
        }
        self.reference.sample(state.t, &mut self.setpoint);
        let sp = self.setpoint;
        let mut event = None;
        let cycle = self.cycle;
        let event_of = |code: ParamCode, version: u64, index: u32| ParamEvent {
            cycle,
            t: state.t,
            version,
            code,
            index,
        };
        let due = self
            .pending
            .iter()
            .position(|p| p.apply_at_seq <= state.seq);
        // Isolated trials back to back (a model's predicted trials; the plant's settle between
        // them): the ended trial gives way to the set in service before the next is applied, so
        // the next starts from that set's saved state, not from where the ended trial left it.
        let mut ended = None;
        if self.isolated_trials && due.is_some_and(|i| self.pending[i].until_seq > 0) {
            ended = self.end_trial(state, &sp);
        }
        if let Some(i) = due {
            let set = self.pending.remove(i);
            let outcome = match self.apply(&set, state, &sp) {
                Ok(Applied::InService) => {
                    self.version = set.version;
                    Some((ParamCode::Accepted, set.version, 0))
                }
                Ok(Applied::Gathered { dropped }) => {
                    dropped.map(|v| (ParamCode::RejectedPartMissing, v, 0))
                }
                Err((code, index)) => Some((code, set.version, index)),
            };
            event = outcome.map(|(code, version, index)| event_of(code, version, index));
        }
        // A trial that has served its repetition (and was not replaced by the next just now).
        ended = ended.or_else(|| self.end_trial(state, &sp));
        if let Some(v) = ended {
            event = event.or(Some(event_of(ParamCode::TrialEnded, v, 0)));
        }
        let n_u = self.controller.n_outputs();
        if self.trial_until.is_some() && self.envelope.left_by_error(&sp, state, n_u) {
            event = Some(event_of(ParamCode::TrialAborted, self.version, 0));
            self.abort(state, &sp);
        }
        self.controller.step(state, &sp, &mut self.u[..n_u]);
        if self.trial_until.is_some() && self.envelope.left_by_control(&self.u[..n_u]) {
            // The candidate's command is never sent: the fallback's replaces it.
            event = Some(event_of(ParamCode::TrialAborted, self.version, 0));
            self.abort(state, &sp);
            self.controller.step(state, &sp, &mut self.u[..n_u]);
        }
        self.telemetry(state, event, tel);
        self.cycle += 1;
        event
    }

    /// This cycle's telemetry: its state, set-point, command, law values and parameter event.
    fn telemetry(&self, state: &PlantState, event: Option<ParamEvent>, tel: &mut Telemetry) {
        let (sp, n_u) = (self.setpoint, self.controller.n_outputs());
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
    }

    /// Check a due set and put it in service: a model set (the law's `model_kind`) through the
    /// common checks and the law's own, a gain set through kind, length, bounds and, for linear
    /// plants, stability, and a trial also through its fallback. The refusal's code and
    /// offending index otherwise.
    fn apply(
        &mut self,
        set: &ParamSet,
        state: &PlantState,
        sp: &Setpoint,
    ) -> Result<Applied, (ParamCode, u32)> {
        let c = self.controller.as_ref();
        let refused = |r: super::Rejection| (r.code, r.index);
        let trial = set.until_seq > 0;
        let part = set.param_kind() == Ok(ParamKind::ModelPart);
        match c.model_kind() {
            Some(kind) if part || set.param_kind() == Ok(kind) => {
                return self.apply_model(set, kind);
            }
            // A law that takes no model: a model in parts is refused once, not once per part.
            None if part && self.parts.is_refused(set) => {
                return Ok(Applied::Gathered { dropped: None });
            }
            None if part => {
                self.parts.refuse(set);
                return Err((ParamCode::RejectedWrongKind, 0));
            }
            _ => {}
        }
        validate_params(set, c.kind(), c.n_params(), self.version, &self.bounds)
            .map_err(refused)?;
        if self
            .stability
            .is_some_and(|m| !c.stabilises(&m, set.values()))
        {
            return Err((ParamCode::RejectedUnstable, 0));
        }
        if self
            .estimated
            .is_some_and(|m| !c.stabilises(&m, set.values()))
        {
            return Err((ParamCode::RejectedUnstableOnEstimate, 0));
        }
        if trial {
            // The named fallback: the current one, or the last trial (which then becomes it).
            if set.fallback_version != self.fallback.version {
                if !(self.last_trial_live && self.last_trial.version == set.fallback_version) {
                    return Err((ParamCode::RejectedUnknownFallback, 0));
                }
                std::mem::swap(&mut self.fallback, &mut self.last_trial);
            }
            *self.last_trial = *set;
            self.last_trial_live = true;
            self.trial_until = Some(set.until_seq);
            self.controller.save_state();
        } else {
            *self.fallback = *set;
            self.last_trial_live = false;
            self.trial_until = None;
        }
        // An isolated trial runs from the state just saved: no bumpless shift.
        swap(
            &mut *self.controller,
            set.values(),
            state,
            sp,
            trial && self.isolated_trials,
        );
        Ok(Applied::InService)
    }

    /// A model set of the law's `kind`, whole or one of its parts (`ParamKind::ModelPart`):
    /// checked as a model set (no trial, newer, finite), a part gathered, and the whole checked
    /// by the law and put in service (at a model's last part). A refused part drops its model.
    fn apply_model(
        &mut self,
        set: &ParamSet,
        kind: ParamKind,
    ) -> Result<Applied, (ParamCode, u32)> {
        let part = set.param_kind() == Ok(ParamKind::ModelPart);
        if part && self.parts.is_refused(set) {
            return Ok(Applied::Gathered { dropped: None });
        }
        let common = if set.until_seq > 0 {
            // Trials are gain sets: a model has no fallback to return to.
            Err((ParamCode::RejectedWrongKind, 0))
        } else {
            // A part's offending index is the whole model's.
            let index = |i| if part { Gather::model_index(set, i) } else { i };
            validate_model(set, self.version).map_err(|r| (r.code, index(r.index)))
        };
        if let Err(e) = common {
            if part {
                self.parts.refuse(set);
            }
            return Err(e);
        }
        let values = if part {
            match self.parts.add(set, kind)? {
                Gathered::Whole(values) => values,
                Gathered::Incomplete { dropped } => return Ok(Applied::Gathered { dropped }),
                Gathered::Dropped => return Ok(Applied::Gathered { dropped: None }),
            }
        } else {
            set.values()
        };
        self.controller.swap_model(values)?;
        Ok(Applied::InService)
    }

    /// A trial that has served its repetition gives way to its fallback: the trial's version,
    /// or None when no trial has ended at this state.
    fn end_trial(&mut self, state: &PlantState, sp: &Setpoint) -> Option<u64> {
        let ended = self.version;
        self.trial_until
            .is_some_and(|end| state.seq >= end)
            .then(|| {
                self.restore(state, sp);
                ended
            })
    }

    /// Put the fallback back in service (the trial is over).
    fn restore(&mut self, state: &PlantState, sp: &Setpoint) {
        let values = self.fallback.values();
        swap(
            &mut *self.controller,
            values,
            state,
            sp,
            self.isolated_trials,
        );
        self.version = self.fallback.version;
        self.trial_until = None;
    }

    /// A trial left the envelope: back to the fallback with the law's state of the trial's
    /// start (`Controller::swap_to_saved`), and the trial may not be named again.
    fn abort(&mut self, state: &PlantState, sp: &Setpoint) {
        swap(
            &mut *self.controller,
            self.fallback.values(),
            state,
            sp,
            true,
        );
        self.version = self.fallback.version;
        self.trial_until = None;
        self.last_trial_live = false;
        self.trials_aborted += 1;
    }
}

/// `values` in service: from the state saved when the last trial began (`saved`: an abort, an
/// isolated trial's start or end), or bumpless.
fn swap(
    controller: &mut dyn Controller,
    values: &[f64],
    state: &PlantState,
    sp: &Setpoint,
    saved: bool,
) {
    if saved {
        controller.swap_to_saved(values, state, sp);
    } else {
        controller.swap_params(values, state, sp);
    }
}
