//! `optimiser.mode = "identify"`: the indirect scheme for arms. While a fuzzy computed-torque
//! controller runs the arm, the optimiser process records the reference, the output and the
//! torque the loop applied (the controller's own command: known, not measured at the joints),
//! and every `identify_every` seconds identifies a model on the latest `identify_window`
//! seconds:
//!
//! - the slot it may replace is the model the selector chose most often over the window;
//! - under computed torque the "servo" is the controller's law, so the fit is the least
//!   squares of M-hat q'' + V-hat + G-hat = tau on the window
//!   (`identify::update_with_torques`), centred on the slot's model in service;
//! - both models, the candidate and the slot's model in service, predict q'' = M-hat^-1 (tau -
//!   V-hat - G-hat) (N_f's output) on the `identify_fresh` seconds after the window, data the
//!   fit has not seen; the candidate is published (kind `ParamKind::RkgnnModel`, values [slot,
//!   parameters]; in parts, `ParamKind::ModelPart`, when larger than one set) only if its RMS
//!   error there is below the in-service model's by `margin`.
//!
//! The controller checks it again (finite, M-hat positive definite on the slot's probes and at
//! least `MIN_EIG_RATIO` of the model it replaces) before it uses it. In lockstep the attempts
//! are at fixed simulated times, so a seeded run is reproducible.

use crate::indirect::EpochRecord;
use crate::law::fuzzy_computed_torque::{
    model_probes, model_weights, premise_distances, probe_positions, MIN_EIG_RATIO,
};
use crate::law::fuzzy_select;
use crate::msg::MAX_JOINTS;
use crate::msg::{ParamKind, ParamSet, PlantState};
use crate::reference::{Reference, Setpoint};
use crate::rkgnn::identify::update_with_torques;
use crate::rkgnn::Trajectory;
use evoloop_rkgnn::network;
use evoloop_rkgnn::RkgnnModel;
use std::collections::VecDeque;

/// Time between the rows the fit and the comparison use (the identification's step), s: the
/// nearest whole number of periods, at least one (5 samples at 1 kHz, 50 at 10 kHz).
const STEP: f64 = 0.005;

/// One recorded sample: time, reference [theta_d; theta_d'], measured joint positions theta
/// and the torque applied from this sample to the next. The velocities are estimated from the
/// positions per window (`Trajectory::from_positions`), as from a run's file.
#[derive(Clone, Copy)]
struct Sample {
    t: f64,
    r: [f64; 2 * MAX_JOINTS],
    q: [f64; MAX_JOINTS],
    u: [f64; MAX_JOINTS],
}

/// A model to publish: values = [slot, parameters], of any length (a 7-DOF arm's exceed one
/// parameter set: `sets` sends it in parts, which the controller checks and applies whole).
pub struct ModelUpdate {
    /// Parameter-set version: one more than the last this optimiser published.
    pub version: u64,
    /// State sequence number at whose cycle the controller is to apply it.
    pub apply_at_seq: u64,
    /// The candidate's RMS error of q'' on the fresh data (`prediction_rms`), rad/s^2.
    pub expected_cost: f64,
    /// The slot, then the model's network parameters.
    pub values: Vec<f64>,
}

impl ModelUpdate {
    /// The parameter sets that carry it, in order.
    pub fn sets(&self) -> Vec<ParamSet> {
        let (v, at, cost) = (self.version, self.apply_at_seq, self.expected_cost);
        ParamSet::model_sets(v, at, cost, ParamKind::RkgnnModel, &self.values)
    }
}

/// The optimiser process's identification alongside operation: it records every
/// sample and, when an attempt is due, fits a candidate for the busiest slot and
/// publishes it if it predicts the fresh data better.
pub struct LiveIdentify {
    n: usize,
    /// The models in service, as this optimiser last published them.
    models: Vec<RkgnnModel>,
    l: Vec<f64>,
    gamma: f64,
    reference: Reference,
    /// The control period: the samples' spacing.
    dt: f64,
    /// Samples a row apart (`STEP`).
    stride: usize,
    window: usize,
    fresh: usize,
    every: f64,
    margin: f64,
    next_t: f64,
    buf: VecDeque<Sample>,
    prev: Option<PlantState>,
    version: u64,
    /// Per slot, the positions the controller checks a replacement on (`model_probes`).
    checks: Vec<Vec<Vec<f64>>>,
    /// Bounded like the indirect scheme's (`indirect::HISTORY`).
    pub epochs: crate::report::history::History<EpochRecord>,
}

impl LiveIdentify {
    /// The identification for `scn`: its controller's models as loaded, the window, fresh
    /// data and interval from `scn.optimiser`. Fails unless the controller is
    /// `fuzzy_computed_torque`.
    pub fn new(scn: &crate::config::Scenario) -> Result<Self, super::RkgnnError> {
        // The scenario's validation refuses identify mode for other controllers.
        let crate::law::ControllerModel::FuzzyComputedTorque(f) = &scn.controller.model else {
            return Err(super::RkgnnError::NotFuzzy);
        };
        let o = &scn.optimiser;
        let samples = |s: f64| (s / scn.timing.period).round() as usize;
        Ok(Self {
            n: f.loaded[0].dof(),
            l: premise_distances(&f.loaded),
            models: f.loaded.clone(),
            checks: model_probes(&f.loaded, &f.along),
            gamma: f.rule.gamma,
            reference: scn.reference.clone(),
            dt: scn.timing.period,
            stride: ((STEP / scn.timing.period).round() as usize).max(1),
            window: samples(o.identify_window),
            fresh: samples(o.identify_fresh),
            every: o.identify_every,
            margin: o.margin,
            next_t: 0.0,
            buf: VecDeque::new(),
            prev: None,
            version: 0,
            epochs: crate::report::history::History::new(crate::indirect::HISTORY),
        })
    }

    /// Continue after a restart: `version` was the last set published, `values` its values
    /// ([slot, parameters]), which the slot then holds.
    pub fn resume(&mut self, version: u64, values: &[f64]) {
        self.version = version;
        if let Some((&slot, p)) = values.split_first() {
            let slot = slot as usize;
            if slot < self.models.len() && p.len() == self.models[slot].net.layout.len {
                self.models[slot].net.set_params(p);
            }
        }
    }

    /// Feed one state sample. A gap in the sequence restarts the record (differences across it
    /// would be wrong).
    pub fn observe(&mut self, s: &PlantState) {
        let n = self.n;
        match self.prev.filter(|p| s.seq == p.seq + 1) {
            Some(p) => {
                let mut sp = Setpoint::default();
                self.reference.sample(p.t, &mut sp);
                let mut rec = Sample {
                    t: p.t,
                    r: [0.0; 2 * MAX_JOINTS],
                    q: [0.0; MAX_JOINTS],
                    u: [0.0; MAX_JOINTS],
                };
                rec.r[..n].copy_from_slice(&sp.q[..n]);
                rec.r[n..2 * n].copy_from_slice(&sp.qd[..n]);
                rec.q[..n].copy_from_slice(&p.y[..n]);
                rec.u[..n].copy_from_slice(&s.u_applied[..n]);
                self.buf.push_back(rec);
                while self.buf.len() > self.window + self.fresh {
                    self.buf.pop_front();
                }
            }
            None => self.buf.clear(),
        }
        self.prev = Some(*s);
    }

    /// `samples` as identification data and their torques.
    fn data(&self, samples: impl Iterator<Item = Sample>) -> (Trajectory, Vec<f64>) {
        let n = self.n;
        let (mut r, mut q, mut tau) = (Vec::new(), Vec::new(), Vec::new());
        for s in samples {
            r.extend_from_slice(&s.r[..2 * n]);
            q.extend_from_slice(&s.q[..n]);
            tau.extend_from_slice(&s.u[..n]);
        }
        (
            Trajectory::from_positions(n, self.dt, r, &q, evoloop_rkgnn::SMOOTHING),
            tau,
        )
    }

    /// The model the selector chose most often over `d`, whose first sample is at `t0`.
    fn busiest_slot(&self, d: &Trajectory, t0: f64) -> usize {
        let q = self.models.len();
        let mut count = vec![0usize; q];
        let mut w = vec![0.0; q];
        for i in (0..d.len()).step_by(self.stride) {
            let t = t0 + i as f64 * d.h;
            model_weights(&self.models, t, d.r_at(i), &self.l, self.gamma, &mut w);
            count[fuzzy_select::largest(&w)] += 1;
        }
        fuzzy_select::largest(&count)
    }

    /// One attempt if one is due at `t`: a model set to publish when the candidate predicts the
    /// fresh data better than the model in service.
    pub fn attempt(&mut self, t: f64, apply_at_seq: u64) -> Option<ModelUpdate> {
        if t < self.next_t || self.buf.len() < self.window + self.fresh {
            return None;
        }
        self.next_t = t + self.every;
        let started = std::time::Instant::now();
        let n = self.n;
        let (train, tau) = self.data(self.buf.iter().take(self.window).copied());
        let (fresh, fresh_tau) = self.data(self.buf.iter().skip(self.window).copied());
        let t0 = self.buf.front().map_or(0.0, |s| s.t);
        let slot = self.busiest_slot(&train, t0);
        // Positive definite over the window's positions, and on the controller's own checks at
        // least MIN_EIG_RATIO of the model in service (what the controller will demand).
        let check = &self.checks[slot];
        let mut probes = probe_positions(&train.x, n);
        probes.extend(check.iter().cloned());
        let in_service = &self.models[slot].net;
        let floor = MIN_EIG_RATIO * in_service.min_eig(check.iter().map(Vec::as_slice));
        let layout = &in_service.layout;
        let candidate = update_with_torques(
            layout,
            in_service.params(),
            &train,
            &tau,
            self.stride,
            &probes,
            floor,
        );
        // The fresh data through the fit's low-pass too, so that q'' and tau are filtered alike.
        let fresh_tau = fresh.filter_alike_for(&fresh_tau, self.stride);
        let fresh = fresh.filtered_for(self.stride);
        let in_err = prediction_rms(layout, in_service.params(), &fresh, &fresh_tau, self.stride);
        let cand_err = candidate.as_deref().map_or(f64::INFINITY, |p| {
            prediction_rms(layout, p, &fresh, &fresh_tau, self.stride)
        });
        let better = cand_err < in_err * (1.0 - self.margin);
        let mut rec = EpochRecord {
            t,
            model_value: slot as f64,
            best_cost: cand_err,
            in_service_cost: in_err,
            published: None,
            wall_s: started.elapsed().as_secs_f64(),
            model: Vec::new(),
        };
        let out = match candidate {
            Some(p) if better => {
                self.version += 1;
                rec.published = Some(self.version);
                self.models[slot].net.set_params(&p);
                let mut values = vec![slot as f64];
                values.extend_from_slice(&p);
                Some(ModelUpdate {
                    version: self.version,
                    apply_at_seq,
                    expected_cost: cand_err,
                    values,
                })
            }
            _ => None,
        };
        self.epochs.push(rec);
        out
    }
}

/// RMS over joints and samples (every `stride`-th) of q'' (central differences of the estimated
/// q') minus N_f's M-hat^-1 (tau - V-hat - G-hat): how well a model predicts the arm's motion
/// from the torque applied. Infinite where M-hat is singular.
pub fn prediction_rms(
    layout: &network::Layout,
    p: &[f64],
    d: &Trajectory,
    tau: &[f64],
    stride: usize,
) -> f64 {
    let n = d.n;
    let (mut sum, mut count) = (0.0, 0usize);
    for i in d.interior(stride) {
        let mut a = [0.0; MAX_JOINTS];
        a[..n].copy_from_slice(&tau[i * n..(i + 1) * n]);
        if !network::acceleration(layout, p, d.x_at(i), &mut a[..n]) {
            return f64::INFINITY;
        }
        let qdd = d.acceleration_at(i);
        for (qdd, aj) in qdd[..n].iter().zip(&a[..n]) {
            sum += (qdd - aj).powi(2);
            count += 1;
        }
    }
    if count == 0 {
        return f64::INFINITY;
    }
    (sum / count as f64).sqrt()
}

/// `run_loop`'s hook of `simulate`: the optimiser process's identification in this process,
/// at the same samples as in lockstep (it sees each state, attempts at the synchronisation
/// points and its sets are offered before the next sample).
struct Identifying<'a> {
    keep: crate::sim::Keep<'a>,
    live: LiveIdentify,
    scn: &'a crate::config::Scenario,
    due: Vec<ParamSet>,
}

impl crate::sim::LoopHook for Identifying<'_> {
    fn before(&mut self, seq: u64, cycle: &mut crate::law::ControlCycle) {
        self.keep.before(seq, cycle);
        for s in self.due.drain(..) {
            cycle.offer(&s);
        }
    }

    fn after(
        &mut self,
        state: &PlantState,
        tel: &crate::msg::Telemetry,
        event: Option<crate::law::cycle::ParamEvent>,
        cycle: &crate::law::ControlCycle,
    ) {
        self.keep.after(state, tel, event, cycle);
        self.live.observe(state);
        if self.scn.is_sync_point(state.seq) {
            if let Some(m) = self.live.attempt(state.t, state.seq + 1) {
                self.due.extend(m.sets());
            }
        }
    }
}

/// A scenario with `optimiser.mode = "identify"` run in this process, as the processes run it
/// in lockstep: every sample, and the identification's epochs (one per attempt).
pub fn simulate(
    scn: &crate::config::Scenario,
) -> Result<(crate::sim::SimResult, Vec<EpochRecord>), super::RkgnnError> {
    scn.require_in_process()?;
    let mut hook = Identifying {
        keep: crate::sim::Keep::new(scn),
        live: LiveIdentify::new(scn)?,
        scn,
        due: Vec::new(),
    };
    let cycle = crate::sim::run_loop(scn, &mut hook);
    Ok((hook.keep.result(&cycle), hook.live.epochs.into_vec()))
}
