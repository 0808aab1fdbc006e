//! The closed loop in one process: the same `PlantSim` and `ControlCycle` the plant and controller
//! processes run, stepped in lockstep. Tests compare the multi-process lockstep run against it
//! bit for bit, and later optimisers evaluate candidates with it.

pub mod cost;
pub mod maglev;

use crate::config::Scenario;
use crate::law::cycle::{ControlCycle, ParamEvent};
use crate::msg::{ParamSet, PlantState, Telemetry};
use crate::plant::PlantSim;

/// Sequence number of the sample at which a set scheduled for time `at` is applied in lockstep.
pub fn scheduled_seq(at: f64, period: f64) -> u64 {
    ((at / period).round() as u64).max(1)
}

/// Build the parameter-set message of the `i`-th scheduled set (version i + 1).
pub fn scheduled_set(scn: &Scenario, i: usize, apply_at_seq: u64) -> ParamSet {
    let s = &scn.optimiser.schedule[i];
    let kind = match s.kind {
        crate::config::SetKind::Gains => scn.controller.param_kind(),
        // Validation made sure the controller takes model sets.
        crate::config::SetKind::Model => scn
            .controller
            .model_param_kind()
            .unwrap_or_else(|| scn.controller.param_kind()),
    };
    ParamSet::new(i as u64 + 1, apply_at_seq, kind, &s.values)
}

/// One sample of the simulated loop, as the controller logs it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimRow {
    /// The plant's sample as the controller received it.
    pub state: PlantState,
    /// The controller cycle's telemetry for this sample (set-point, command, parameter
    /// version, the law's own values).
    pub telemetry: Telemetry,
}

/// Result of an in-process lockstep simulation.
pub struct SimResult {
    /// Every sample of the loop, in order.
    pub rows: Vec<SimRow>,
    /// Every parameter-set event of the run (a set accepted or refused), in cycle order.
    pub events: Vec<ParamEvent>,
    /// The law's own run.csv columns (`Controller::log_columns`, e.g. a fuzzy selector's active
    /// model); each row's telemetry holds their values (`law_values`).
    pub law_columns: Vec<String>,
}

impl SimResult {
    /// The law's own values at row `i`, one per `law_columns` entry.
    pub fn law_values(&self, i: usize) -> &[f64] {
        let tel = &self.rows[i].telemetry;
        &tel.law[..tel.n_law as usize]
    }

    /// The law's column `name` over the run (None if the law logs no such column).
    pub fn law_column(&self, name: &str) -> Option<Vec<f64>> {
        let k = self.law_columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r.telemetry.law[k]).collect())
    }
}

/// A simulated run per joint, as run.csv has it: times, each joint's set-point (the reference at
/// the sample's time), output and command.
pub struct JointTraces {
    /// Time of each sample, s.
    pub t: Vec<f64>,
    /// Each joint's set-point at each sample, `r[joint][sample]`.
    pub r: Vec<Vec<f64>>,
    /// Each joint's output at each sample, `y[joint][sample]`.
    pub y: Vec<Vec<f64>>,
    /// Each joint's command at each sample, `u[joint][sample]`.
    pub u: Vec<Vec<f64>>,
}

impl JointTraces {
    /// The first `joints` joints of `sim`, whose scenario followed `reference`.
    pub fn of(sim: &SimResult, reference: &crate::reference::Reference, joints: usize) -> Self {
        let rows = sim.rows.len();
        let column = || (0..joints).map(|_| Vec::with_capacity(rows)).collect();
        let mut tr = Self {
            t: Vec::with_capacity(rows),
            r: column(),
            y: column(),
            u: column(),
        };
        let mut sp = crate::reference::Setpoint::default();
        for row in &sim.rows {
            reference.sample(row.state.t, &mut sp);
            tr.t.push(row.state.t);
            for j in 0..joints {
                tr.r[j].push(sp.q[j]);
                tr.y[j].push(row.state.y[j]);
                tr.u[j].push(row.telemetry.u[j]);
            }
        }
        tr
    }

    /// Set-point and output columns as slices (what `report::metrics::tracking` takes).
    pub fn columns(&self) -> (Vec<&[f64]>, Vec<&[f64]>) {
        fn slices(c: &[Vec<f64>]) -> Vec<&[f64]> {
            c.iter().map(Vec::as_slice).collect()
        }
        (slices(&self.r), slices(&self.y))
    }
}

/// What the closed loop of `run_loop` tells its user, sample by sample.
pub trait LoopHook {
    /// Before the cycle of sample `seq`: offer the sets due (now or later) to `cycle`.
    fn before(&mut self, _seq: u64, _cycle: &mut ControlCycle) {}
    /// After it: the sample, the cycle's telemetry and parameter event, and the cycle (its
    /// set-point of this sample, the law).
    fn after(
        &mut self,
        _state: &PlantState,
        _tel: &Telemetry,
        _event: Option<ParamEvent>,
        _cycle: &ControlCycle,
    ) {
    }
}

/// The scenario's closed loop in this process, in lockstep: the same `PlantSim` and
/// `ControlCycle` the plant and controller processes run, for `scn.cycles()` samples, each shown
/// to `hook` and none kept. Returns the control cycle as it ends (the set in service, counts).
pub fn run_loop(scn: &Scenario, hook: &mut impl LoopHook) -> ControlCycle {
    let mut plant = scn.plant.simulation(scn.seed);
    let mut cycle = control_cycle(scn);
    let dt = scn.timing.period;
    let mut state = PlantState::default();
    let mut u = [0.0; crate::msg::MAX_JOINTS];
    let n_u = plant.plant.n_inputs();
    for k in 0..scn.cycles() {
        plant.sample(k, 0, &u[..n_u], &mut state);
        hook.before(k, &mut cycle);
        let mut tel = Telemetry::default();
        let event = cycle.step(&state, &mut tel);
        hook.after(&state, &tel, event, &cycle);
        u = cycle.u;
        plant.advance(&u[..n_u], dt);
    }
    cycle
}

/// The scenario's control cycle, as the controller process and the in-process simulations
/// build it: its law, reference, parameter bounds, stability check (linear plants), trial
/// envelope (direct scheme) and the check of every plant state against the configured plant.
pub fn control_cycle(scn: &Scenario) -> ControlCycle {
    ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds())
        .with_stability_check(scn.linear_model())
        .with_envelope(scn.optimiser.envelope)
        .with_isolated_trials(
            scn.optimiser.mode == crate::config::OptimiserMode::Direct && scn.optimiser.settle > 0,
        )
        .with_state_check(scn.state_check())
}

/// `simulate`'s hook: offers the scheduled sets at their samples and keeps every sample.
pub struct Keep<'a> {
    scn: &'a Scenario,
    schedule_on: bool,
    rows: Vec<SimRow>,
    events: Vec<ParamEvent>,
}

impl LoopHook for Keep<'_> {
    fn before(&mut self, seq: u64, cycle: &mut ControlCycle) {
        if self.schedule_on {
            for (i, s) in self.scn.optimiser.schedule.iter().enumerate() {
                if scheduled_seq(s.at, self.scn.timing.period) == seq {
                    cycle.offer(&scheduled_set(self.scn, i, seq));
                }
            }
        }
    }
    fn after(
        &mut self,
        state: &PlantState,
        tel: &Telemetry,
        event: Option<ParamEvent>,
        _cycle: &ControlCycle,
    ) {
        self.events.extend(event);
        self.rows.push(SimRow {
            state: *state,
            telemetry: *tel,
        });
    }
}

/// Simulate the scenario in lockstep in this process, scheduled parameter sets included when
/// the scenario's optimiser mode is `schedule`. The result holds every sample, so the scenario
/// needs a duration: callers refuse a run until stopped and a plant of the user's own first
/// (`Scenario::require_in_process`).
pub fn simulate(scn: &Scenario) -> SimResult {
    if let Err(e) = scn.require_in_process() {
        panic!("sim::simulate: {e}");
    }
    let mut keep = Keep::new(scn);
    let cycle = run_loop(scn, &mut keep);
    keep.result(&cycle)
}

impl<'a> Keep<'a> {
    /// Keeping every sample of `scn`'s loop, its scheduled sets offered (`schedule` mode).
    pub fn new(scn: &'a Scenario) -> Self {
        Keep {
            scn,
            schedule_on: scn.optimiser.mode == crate::config::OptimiserMode::Schedule,
            rows: Vec::with_capacity(scn.cycles() as usize),
            events: Vec::new(),
        }
    }

    /// What was kept, with the law's log columns of the `cycle` run.
    pub fn result(self, cycle: &ControlCycle) -> SimResult {
        SimResult {
            rows: self.rows,
            events: self.events,
            law_columns: cycle.controller.log_columns(),
        }
    }
}

/// A closed-loop response of `plant` under `controller` to `reference`, sampled every `period`
/// for `duration` s (integration step `step`): times, first outputs and first controls. Stops
/// early (returning what it has, the offending sample last) when the output leaves
/// +-`diverged`. Noise-free, from u = 0; `Run` has the other settings.
pub fn response(
    plant: Box<dyn crate::plant::Plant>,
    controller: Box<dyn crate::law::Controller>,
    reference: &crate::reference::Reference,
    period: f64,
    step: f64,
    duration: f64,
    diverged: f64,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let r = Run {
        reference,
        period,
        step,
        duration,
        diverged,
        noise_std: 0.0,
        seed: 0,
        sensor_delay: 0,
        u0: 0.0,
    }
    .response(plant, controller);
    (r.t, r.y, r.u)
}

/// A single-input, single-output closed-loop run without the scenario's machinery: the loop the
/// tuners and the indirect scheme's models evaluate candidates with.
pub struct Run<'a> {
    /// The reference the loop follows, sampled at each sample's time.
    pub reference: &'a crate::reference::Reference,
    /// Control period, s.
    pub period: f64,
    /// Integration step, s.
    pub step: f64,
    /// Run length, s.
    pub duration: f64,
    /// The output bound past which the run stops (the loop is lost).
    pub diverged: f64,
    /// Output noise (std) and its seed.
    pub noise_std: f64,
    /// Seed of the output noise.
    pub seed: u64,
    /// Samples the measurement lags (`plant.sensor_delay`; the controller's estimator predicts
    /// across the same delay).
    pub sensor_delay: usize,
    /// The command held before the first control step.
    pub u0: f64,
}

/// What a `Run` produced: per sample its time, reference, output and control.
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct Response {
    /// Time of each sample, s.
    pub t: Vec<f64>,
    /// The reference's first set-point at each sample's time.
    pub r: Vec<f64>,
    /// The first output at each sample, noise included.
    pub y: Vec<f64>,
    /// The first command at each sample, as the controller computed it.
    pub u: Vec<f64>,
}

impl Run<'_> {
    /// Run `controller` on `plant` from the command `u0` for `duration` s and return every
    /// sample. Stops early, the offending sample last, when the first output is not finite or
    /// leaves +-`diverged`.
    pub fn response(
        &self,
        plant: Box<dyn crate::plant::Plant>,
        mut controller: Box<dyn crate::law::Controller>,
    ) -> Response {
        let n_u = plant.n_inputs();
        let mut sim =
            PlantSim::new(plant, self.step, self.noise_std, self.seed).delaying(self.sensor_delay);
        let n = (self.duration / self.period).round() as usize;
        let mut out = Response {
            t: Vec::with_capacity(n),
            r: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
            u: Vec::with_capacity(n),
        };
        let mut state = PlantState::default();
        let mut u = [self.u0; crate::msg::MAX_JOINTS];
        for k in 0..n {
            sim.sample(k as u64, 0, &u[..n_u], &mut state);
            let mut sp = crate::reference::Setpoint::default();
            self.reference.sample(state.t, &mut sp);
            controller.step(&state, &sp, &mut u[..n_u]);
            out.t.push(state.t);
            out.r.push(sp.q[0]);
            out.y.push(state.y[0]);
            out.u.push(u[0]);
            if !state.y[0].is_finite() || state.y[0].abs() > self.diverged {
                break;
            }
            sim.advance(&u[..n_u], self.period);
        }
        out
    }
}
