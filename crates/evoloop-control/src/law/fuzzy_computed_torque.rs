//! Computed torque on RKGNN-identified models with fuzzy model selection (RKGNN paper, Fig. 6
//! and Section 5.2):
//!   tau_i = M-hat_i(q) (qdd_d + K_v e_dot + K_p e) + V-hat_i(q, qd) + G-hat_i(q)   per model i,
//!   tau   = psi(k) sum_i s_i tau_i,
//! with s the selection of eqs. 19-20 (`fuzzy_select`) on the premises z = [theta; theta']:
//! model i's premise z_i(k) is the reference it was identified on at the same time, the new
//! reference's z_r(k) the set-point. `Selection::Max` (the paper) puts s = 1 on the model of
//! largest weight, `Selection::Blend` weights them all by their normalised memberships, and
//! `Selection::Evidence` weights them per joint by how well each explains the motion under the
//! torque the loop applies, against a uniform prior or the memberships (`evidence`):
//! tau_j = psi sum_i s_ij tau_ij. Each row of the law's effective M-hat is then a convex
//! combination of the models' rows for that joint: not symmetric in general, which computed
//! torque does not need (its error dynamics ask M^-1 M-hat_eff near I, row by row).
//!
//! L_j, "the distance between the j-th premise variables of two adjacent trajectories", varies
//! along the trajectories and vanishes where they cross; we take its RMS over the identification
//! window, averaged over adjacent pairs in the order the models are listed (floored at 1e-6).
//!
//! Positions are the measured outputs y, velocities the joint velocities (as computed torque).
//! The per-cycle cost is one N_f inertia, velocity and gravity evaluation per model in use, with
//! no allocation (`Blend` and `Evidence` evaluate every model, `Evidence` at most one more a
//! cycle for its residual). Logged per cycle: the model of largest weight and the normalised
//! memberships; under `Evidence`, the model of largest weight in the law and each model's
//! weight in it, averaged over the joints.

use super::computed_torque::{damp_and_limit, gains_and_startup, startup_damping};
use super::estimator::{Velocities, VelocitySource};
use super::evidence::{self, Evidence};
use super::fuzzy_select::{self, Selection};
use super::{
    driven_arm, velocity_source, Controller, ControllerConfig, ControllerContext, VelocityKey,
};
use crate::check::{Check, ConfigError, Tunable};
use crate::linalg::Mat;
use crate::msg::{ParamCode, ParamKind, PlantState};
use crate::reference::Setpoint;
use crate::MAX_JOINTS;
use evoloop_rkgnn::RkgnnModel;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Most models a selector chooses among.
pub const MAX_MODELS: usize = 8;

/// What the evidence rule weighs the models' evidence against.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EvidencePrior {
    /// Every model alike: the evidence alone decides (the default).
    Uniform,
    /// The memberships' blend (eqs. 19-20): the model identified nearest the reference first.
    Memberships,
}

/// How the selector weighs the models: the rule, the fuzzy sets' width and, for
/// `Selection::Evidence`, its prior, filter bandwidth (rad/s) and memory (s).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rule {
    /// How the weights become the law's: `Max` (the paper's), `Blend` or `Evidence`.
    pub selection: Selection,
    /// Width of the fuzzy sets of eq. 20 (the paper's 0.66 by default).
    pub gamma: f64,
    /// Under `Evidence`: what the models' evidence is weighed against.
    pub evidence_prior: EvidencePrior,
    /// Under `Evidence`: lambda of the state-variable filter the residuals are taken through,
    /// rad/s.
    pub evidence_bandwidth: f64,
    /// Under `Evidence`: the memory of each model's averaged squared residual, s.
    pub evidence_memory: f64,
}

impl Rule {
    /// `selection` with the paper's gamma and the evidence's defaults.
    pub fn paper(selection: Selection) -> Self {
        Self {
            selection,
            gamma: fuzzy_select::GAMMA,
            evidence_prior: EvidencePrior::Uniform,
            evidence_bandwidth: evidence::BANDWIDTH,
            evidence_memory: evidence::MEMORY,
        }
    }
}

/// Computed torque on RKGNN-identified models with fuzzy model selection (see the module docs): the
/// models, the selection rule and its weights, the gains [Kp; Kv], and each model's probes for
/// checking a replacement. Built once, then stepped without allocating.
pub struct FuzzyComputedTorque {
    models: Vec<RkgnnModel>,
    /// L_j per premise (2n).
    l: Vec<f64>,
    rule: Rule,
    /// Under `Selection::Evidence`: the models' evidence and the per-joint weights it gives
    /// (`s_joint[i * MAX_JOINTS + j]`).
    evidence: Option<Evidence>,
    s_joint: [f64; MAX_MODELS * MAX_JOINTS],
    gains: Vec<f64>,
    startup_rate: f64,
    effort: Vec<f64>,
    k: u64,
    /// Raw weights w_i (eq. 20) and the selection s_i of the last cycle (under `Evidence`, the
    /// memberships' blend, its prior when `evidence_prior = "memberships"`; not computed under
    /// a uniform prior).
    w: [f64; MAX_MODELS],
    s: [f64; MAX_MODELS],
    /// Per model, positions of its identification reference (`probe_positions`) and of the
    /// reference this run tracks (`reference_positions`, thinned to `PROBES`) on which a
    /// replacement model's M-hat is checked, and the in-service model's smallest eigenvalue
    /// there.
    probes: Vec<Vec<Vec<f64>>>,
    min_eig: [f64; MAX_MODELS],
    velocity: Velocities,
}

/// Probe positions per model for checking a replacement.
const PROBES: usize = 24;

/// `PROBES` joint positions spread evenly over recorded states (`states`: rows of [q; qd], n
/// joints each): where a candidate model's M-hat is checked, by the controller on a model's
/// identification reference and by the live identifier on its window.
pub fn probe_positions(states: &[f64], n: usize) -> Vec<Vec<f64>> {
    let rows = (states.len() / (2 * n)).max(1);
    (0..PROBES)
        .map(|k| states[2 * n * (k * rows / PROBES)..][..n].to_vec())
        .collect()
}
/// Spacing of the reference positions a model is checked on, s, and how far ahead a run until
/// stopped is checked.
const REFERENCE_PROBE_DT: f64 = 0.01;
const REFERENCE_HORIZON: f64 = 120.0;

/// The joint positions of `reference` every `REFERENCE_PROBE_DT` over the run's `duration`
/// (at most `REFERENCE_HORIZON`): where the controller will evaluate its models' M-hat.
pub fn reference_positions(
    reference: &crate::reference::Reference,
    duration: f64,
) -> Vec<Vec<f64>> {
    let mut sp = Setpoint::default();
    let n = reference.joints();
    let steps = (duration.min(REFERENCE_HORIZON) / REFERENCE_PROBE_DT).ceil() as usize;
    (0..=steps)
        .map(|k| {
            reference.sample(k as f64 * REFERENCE_PROBE_DT, &mut sp);
            sp.q[..n].to_vec()
        })
        .collect()
}

/// `model` must have a positive definite M-hat at every position of `along`: its smallest
/// eigenvalue along it, or the first position where it fails, with its time.
pub fn check_along_reference(
    model: &RkgnnModel,
    along: &[Vec<f64>],
) -> Result<f64, IndefiniteAlong> {
    let mut lowest = f64::INFINITY;
    for (k, q) in along.iter().enumerate() {
        let e = model.min_eig(std::iter::once(q.as_slice()));
        if e.is_nan() || e <= 0.0 {
            return Err(IndefiniteAlong {
                eigenvalue: e,
                t: k as f64 * REFERENCE_PROBE_DT,
                q: q.clone(),
            });
        }
        lowest = lowest.min(e);
    }
    Ok(lowest)
}

/// A model whose M-hat is not positive definite at a position of the reference a scenario
/// tracks: computed torque on it would not be stable there.
#[derive(Debug, Clone, PartialEq)]
pub struct IndefiniteAlong {
    /// M-hat's smallest eigenvalue there (NaN when it could not be computed).
    pub eigenvalue: f64,
    /// The reference's time of the position, s.
    pub t: f64,
    /// The position, rad (or m for a prismatic joint).
    pub q: Vec<f64>,
}

impl std::fmt::Display for IndefiniteAlong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "M-hat is not positive definite along the reference this scenario tracks: smallest \
             eigenvalue {:.3e} at t = {:.2} s, q = {:.3?} (computed torque on it would not be \
             stable there)",
            self.eigenvalue, self.t, self.q
        )
    }
}

impl std::error::Error for IndefiniteAlong {}

/// Per model, the positions where its M-hat is checked when it is loaded and before a
/// replacement takes its slot: its identification reference (`probe_positions`) and the
/// reference this run tracks (`along`, thinned to `PROBES`). The live identifier checks its
/// candidates on the same positions, so that what it publishes is what the controller takes.
pub fn model_probes(models: &[RkgnnModel], along: &[Vec<f64>]) -> Vec<Vec<Vec<f64>>> {
    let k = PROBES.min(along.len());
    let ahead = (0..k).map(|i| along[i * along.len() / k].clone());
    let ahead: Vec<Vec<f64>> = ahead.collect();
    models
        .iter()
        .map(|m| {
            let mut p = probe_positions(&m.premise, m.dof());
            p.extend(ahead.iter().cloned());
            p
        })
        .collect()
}

/// A replacement model's smallest eigenvalue of M-hat over the probes must reach this fraction
/// of the model in service's: positive definite is not enough, a nearly singular M-hat (which
/// an unconstrained fit can produce off its data) makes computed torque blow up.
pub const MIN_EIG_RATIO: f64 = 0.1;

/// Eq. 20's weight of each model (into `w`) for the premise z_r = [theta_d; theta_d'] at time
/// `t`: each model's premise centre is its identification reference at `t`. Allocation-free.
pub fn model_weights(
    models: &[RkgnnModel],
    t: f64,
    z_r: &[f64],
    l: &[f64],
    gamma: f64,
    w: &mut [f64],
) {
    let mut centres: [&[f64]; MAX_MODELS] = [&[]; MAX_MODELS];
    for (c, m) in centres.iter_mut().zip(models) {
        *c = m.premise_at(t);
    }
    fuzzy_select::weights(&centres[..models.len()], z_r, l, gamma, w);
}

/// L_j of the models' premises (see the module docs).
pub fn premise_distances(models: &[RkgnnModel]) -> Vec<f64> {
    let n = models.first().map_or(0, RkgnnModel::dof);
    let mut l = vec![0.0; 2 * n];
    let pairs = models.len().saturating_sub(1);
    for pair in models.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let samples = a.premise_len().min(b.premise_len());
        for (j, lj) in l.iter_mut().enumerate() {
            let ms: f64 = (0..samples)
                .map(|i| {
                    let t = i as f64 * a.premise_period;
                    (a.premise_at(t)[j] - b.premise_at(t)[j]).powi(2)
                })
                .sum::<f64>()
                / samples.max(1) as f64;
            *lj += ms.sqrt() / pairs as f64;
        }
    }
    l.iter_mut().for_each(|v| *v = v.max(1e-6));
    l
}

impl FuzzyComputedTorque {
    /// `gains` = [Kp; Kv]; `effort` the joints' torque limits.
    /// `along`: positions of the reference the run tracks (`reference_positions`); `period`
    /// the loop's, s.
    pub fn new(
        models: Vec<RkgnnModel>,
        rule: Rule,
        gains: &[f64],
        startup_rate: f64,
        effort: Vec<f64>,
        along: &[Vec<f64>],
        period: f64,
    ) -> Self {
        assert!((1..=MAX_MODELS).contains(&models.len()));
        let n = models[0].dof();
        assert_eq!(gains.len(), 2 * n);
        let probes = model_probes(&models, along);
        let mut min_eig = [0.0; MAX_MODELS];
        for ((e, m), p) in min_eig.iter_mut().zip(&models).zip(&probes) {
            *e = m.net.min_eig(p.iter().map(Vec::as_slice));
        }
        let evidence = (rule.selection == Selection::Evidence).then(|| {
            Evidence::new(
                models.len(),
                n,
                period,
                rule.evidence_bandwidth,
                rule.evidence_memory,
            )
        });
        Self {
            l: premise_distances(&models),
            probes,
            min_eig,
            models,
            rule,
            evidence,
            s_joint: [0.0; MAX_MODELS * MAX_JOINTS],
            gains: gains.to_vec(),
            startup_rate,
            effort,
            k: 0,
            w: [0.0; MAX_MODELS],
            s: [0.0; MAX_MODELS],
            velocity: Velocities::True,
        }
    }

    /// Read velocities from `source` (the true ones until this is called), every `period` s.
    pub fn with_velocity(mut self, source: VelocitySource, period: f64) -> Self {
        self.velocity = Velocities::new(source, self.models[0].dof(), period, None);
        self
    }

    /// Each model's weight in the law averaged over the joints (`Evidence`).
    fn law_weights(&self, out: &mut [f64]) {
        let n = self.models[0].dof();
        for (i, o) in out.iter_mut().enumerate() {
            let row = &self.s_joint[i * MAX_JOINTS..][..n];
            *o = row.iter().sum::<f64>() / n as f64;
        }
    }

    /// This cycle's weight of each model on each joint (`s_joint`): the memberships' selection
    /// (eqs. 19-20) on every joint, or the evidence's per joint against its prior. The
    /// memberships are not computed when nothing uses them (the evidence on a uniform prior).
    fn weigh(&mut self, state: &PlantState, sp: &Setpoint) {
        let n = self.models[0].dof();
        let q_count = self.models.len();
        let uniform = self.evidence.is_some() && self.rule.evidence_prior == EvidencePrior::Uniform;
        if !uniform {
            // Premises: the set-point against each model's identification reference now.
            let mut z_r = [0.0; 2 * MAX_JOINTS];
            z_r[..n].copy_from_slice(&sp.q[..n]);
            z_r[n..2 * n].copy_from_slice(&sp.qd[..n]);
            model_weights(
                &self.models,
                state.t,
                &z_r[..2 * n],
                &self.l,
                self.rule.gamma,
                &mut self.w[..q_count],
            );
            self.s[..q_count].copy_from_slice(&self.w[..q_count]);
            fuzzy_select::select(self.rule.selection, &mut self.s[..q_count]);
        }
        match &mut self.evidence {
            Some(ev) => {
                let mut prior = [1.0 / q_count as f64; MAX_MODELS];
                if !uniform {
                    prior[..q_count].copy_from_slice(&self.s[..q_count]);
                }
                ev.update(
                    &self.models,
                    state.seq,
                    &state.y[..n],
                    &state.u_applied[..n],
                );
                ev.weights(&prior[..q_count], &mut self.s_joint);
            }
            None => {
                for (i, &s) in self.s[..q_count].iter().enumerate() {
                    self.s_joint[i * MAX_JOINTS..][..n].fill(s);
                }
            }
        }
    }
}

impl Controller for FuzzyComputedTorque {
    fn kind(&self) -> ParamKind {
        ParamKind::FuzzyComputedTorque
    }
    fn n_params(&self) -> usize {
        self.gains.len()
    }
    fn params(&self) -> &[f64] {
        &self.gains
    }
    fn n_outputs(&self) -> usize {
        self.models[0].dof()
    }

    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let n = self.models[0].dof();
        self.weigh(state, sp);
        let (kp, kv) = self.gains.split_at(n);
        let (q, qd) = (&state.y[..n], self.velocity.read(state, n, None));
        let mut acc = [0.0; MAX_JOINTS];
        for i in 0..n {
            acc[i] = sp.qdd[i] + kv[i] * (sp.qd[i] - qd[i]) + kp[i] * (sp.q[i] - q[i]);
        }
        u[..n].fill(0.0);
        let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
        let (mut v, mut g) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
        for (i, model) in self.models.iter().enumerate() {
            let s = &self.s_joint[i * MAX_JOINTS..][..n];
            if s.iter().all(|&x| x == 0.0) {
                continue;
            }
            model.net.inertia_and_velocity(q, qd, &mut m, &mut v[..n]);
            model.net.gravity(q, &mut g[..n]);
            for j in 0..n {
                let ma: f64 = (0..n).map(|k| m[j * n + k] * acc[k]).sum();
                u[j] += s[j] * (ma + v[j] + g[j]);
            }
        }
        let psi = startup_damping(self.startup_rate, self.k);
        damp_and_limit(&mut u[..n], psi, self.effort.iter().copied());
        self.k += 1;
    }

    fn swap_params(&mut self, new: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.gains.copy_from_slice(new);
    }

    fn model_kind(&self) -> Option<ParamKind> {
        Some(ParamKind::RkgnnModel)
    }

    fn model_len(&self) -> usize {
        1 + self
            .models
            .iter()
            .map(|m| m.net.layout.len)
            .max()
            .unwrap_or(0)
    }

    /// values = [slot, parameters]: the slot must exist, the parameters fit its layout, and
    /// M-hat be positive definite on the slot's probes, at least MIN_EIG_RATIO of the model in
    /// service there. The premise (the slot's identification reference) stays.
    fn swap_model(&mut self, values: &[f64]) -> Result<(), (ParamCode, u32)> {
        let slot = values.first().copied().unwrap_or(-1.0);
        if slot < 0.0 || slot.fract() != 0.0 || slot as usize >= self.models.len() {
            return Err((ParamCode::RejectedOutOfBounds, 0));
        }
        let slot = slot as usize;
        let p = &values[1..];
        let layout = &self.models[slot].net.layout;
        if p.len() != layout.len {
            return Err((ParamCode::RejectedWrongLength, values.len() as u32));
        }
        let probes = self.probes[slot].iter().map(Vec::as_slice);
        let e = evoloop_rkgnn::network::min_eig(layout, p, probes);
        if !(e > 0.0 && e >= MIN_EIG_RATIO * self.min_eig[slot]) {
            return Err((ParamCode::RejectedNotPositiveDefinite, 0));
        }
        self.models[slot].net.set_params(p);
        self.min_eig[slot] = e;
        Ok(())
    }

    fn log_columns(&self) -> Vec<String> {
        let mut c = vec!["fuzzy_model".to_string()];
        c.extend((0..self.models.len()).map(|i| format!("fuzzy_w{i}")));
        c
    }

    /// The model of largest weight and each model's weight: the memberships (normalised), or
    /// under `Evidence` the law's weights averaged over the joints.
    fn log_values(&self, out: &mut [f64]) {
        let q_count = self.models.len();
        let (active, m) = out.split_at_mut(1);
        let m = &mut m[..q_count];
        if self.evidence.is_some() {
            self.law_weights(m);
            active[0] = fuzzy_select::largest(m) as f64;
        } else {
            active[0] = fuzzy_select::largest(&self.w[..q_count]) as f64;
            m.copy_from_slice(&self.w[..q_count]);
            fuzzy_select::select(Selection::Blend, m);
        }
    }
}

// ---------------------------------------------------------------- configuration

/// The `[controller.fuzzy_computed_torque]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    kp: Vec<f64>,
    kv: Vec<f64>,
    /// psi's rate per sample (default 0.03, the paper's).
    startup_rate: Option<f64>,
    /// Identified model files (`evoloop identify rkgnn`), relative to the scenario, in the order
    /// of their trajectories (adjacent models give L_j).
    models: Vec<PathBuf>,
    /// "max" (the paper's rule, default), "blend" or "evidence".
    selection: Option<Selection>,
    /// Width of the fuzzy sets (default 0.66, the paper's).
    gamma: Option<f64>,
    /// Under "evidence": its prior ("uniform", default, or "memberships"), the filter's
    /// bandwidth, rad/s (default 50), and the memory of the averaged squared residual, s
    /// (default 0.5).
    evidence_prior: Option<EvidencePrior>,
    evidence_bandwidth: Option<f64>,
    evidence_memory: Option<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
    velocity: Option<VelocityKey>,
    velocity_cutoff_hz: Option<f64>,
}

/// Validated settings with the models loaded and checked.
#[derive(Debug, Clone, Serialize)]
pub struct FuzzyComputedTorqueSpec {
    /// The gains [Kp_1..Kp_n, Kv_1..Kv_n] (each >= 0) and their bounds.
    #[serde(flatten)]
    pub tunable: Tunable,
    /// psi's rate per sample (0 = no start-up damping).
    pub startup_rate: f64,
    /// The model files, resolved against the scenario's directory, in their configured order.
    pub models: Vec<PathBuf>,
    /// How the models are weighed (`selection`, `gamma` and the evidence keys).
    #[serde(flatten)]
    pub rule: Rule,
    /// Where the law's joint velocities come from (`velocity`; differenced and low-passed by
    /// default).
    pub velocity: VelocitySource,
    /// The models as loaded from `models`, checked along the run's reference.
    #[serde(skip)]
    pub loaded: Vec<RkgnnModel>,
    /// Each joint's effort limit from the arm's robot file (N m; N for a prismatic joint): the law
    /// clamps its command to it.
    #[serde(skip)]
    pub effort: Vec<f64>,
    /// Positions of the run's reference (`reference_positions`).
    #[serde(skip)]
    pub along: Vec<Vec<f64>>,
}

/// The selection keys: the rule, gamma and, only with "evidence", its prior, bandwidth and
/// memory.
fn rule(check: &Check, t: &Table) -> Result<Rule, ConfigError> {
    let key = |k: &str| format!("controller.fuzzy_computed_torque.{k}");
    let selection = t.selection.unwrap_or(Selection::Max);
    let mut rule = Rule::paper(selection);
    rule.gamma = check.positive(&key("gamma"), t.gamma.unwrap_or(rule.gamma))?;
    let given = [
        ("evidence_prior", t.evidence_prior.is_some()),
        ("evidence_bandwidth", t.evidence_bandwidth.is_some()),
        ("evidence_memory", t.evidence_memory.is_some()),
    ];
    if let Some((name, _)) = given
        .iter()
        .find(|(_, g)| *g && selection != Selection::Evidence)
    {
        return check.fail(&key(name), "applies only with selection = \"evidence\"");
    }
    rule.evidence_prior = t.evidence_prior.unwrap_or(rule.evidence_prior);
    for (name, given, value) in [
        (
            "evidence_bandwidth",
            t.evidence_bandwidth,
            &mut rule.evidence_bandwidth,
        ),
        (
            "evidence_memory",
            t.evidence_memory,
            &mut rule.evidence_memory,
        ),
    ] {
        if let Some(v) = given {
            *value = check.positive(&key(name), v)?;
        }
    }
    Ok(rule)
}

/// Validate `[controller.fuzzy_computed_torque]` for the arm the plant drives: the gains and
/// start-up rate as computed torque's, the selection keys, and 1 to `MAX_MODELS` model files, each
/// with the arm's joints and a positive definite M-hat along the run's reference. Fails when the
/// plant is no arm, the table is missing or a model does not load.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &ControllerContext,
) -> Result<FuzzyComputedTorqueSpec, ConfigError> {
    let law = "fuzzy_computed_torque";
    let arm = driven_arm(check, cx, law)?;
    let Some(t) = t else {
        return check.fail(
            "controller.fuzzy_computed_torque",
            "missing table [controller.fuzzy_computed_torque] with `kp`, `kv` and `models`",
        );
    };
    let n = arm.dof();
    let rule = rule(check, &t)?;
    let (tunable, startup_rate) = gains_and_startup(
        check,
        law,
        n,
        [t.kp, t.kv],
        t.startup_rate,
        t.lower,
        t.upper,
    )?;
    let key = "controller.fuzzy_computed_torque.models";
    if !(1..=MAX_MODELS).contains(&t.models.len()) {
        return check.fail(key, format!("needs 1 to {MAX_MODELS} model files"));
    }
    let mut loaded = Vec::with_capacity(t.models.len());
    let mut models = Vec::with_capacity(t.models.len());
    let along = reference_positions(cx.reference, cx.duration);
    for (i, rel) in t.models.iter().enumerate() {
        let path = check.resolve(rel);
        let m = match RkgnnModel::load(&path) {
            Ok(m) => m,
            Err(e) => return check.fail(&format!("{key}[{i}]"), e.to_string()),
        };
        if m.dof() != n {
            return check.fail(
                &format!("{key}[{i}]"),
                format!("the model has {} joints, the arm {n}", m.dof()),
            );
        }
        if let Err(e) = check_along_reference(&m, &along) {
            return check.fail(&format!("{key}[{i}]"), format!("{}: {e}", path.display()));
        }
        loaded.push(m);
        models.push(path);
    }
    Ok(FuzzyComputedTorqueSpec {
        tunable,
        startup_rate,
        models,
        rule,
        velocity: velocity_source(
            check,
            "fuzzy_computed_torque",
            t.velocity,
            t.velocity_cutoff_hz,
            cx,
            false,
        )?,
        loaded,
        effort: arm.bodies.iter().map(|b| b.limits.effort).collect(),
        along,
    })
}

impl ControllerConfig for FuzzyComputedTorqueSpec {
    fn build(&self, period: f64, _u_limit: Option<f64>) -> Box<dyn Controller> {
        Box::new(
            FuzzyComputedTorque::new(
                self.loaded.clone(),
                self.rule,
                &self.tunable.gains,
                self.startup_rate,
                self.effort.clone(),
                &self.along,
                period,
            )
            .with_velocity(self.velocity, period),
        )
    }
    fn reads_truth(&self) -> bool {
        self.velocity.reads_truth()
    }
    fn tunable(&self) -> &Tunable {
        &self.tunable
    }
    fn param_kind(&self) -> ParamKind {
        ParamKind::FuzzyComputedTorque
    }
    fn model_param_kind(&self) -> Option<ParamKind> {
        Some(ParamKind::RkgnnModel)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::law::cycle::ControlCycle;
    use crate::msg::{ParamSet, Telemetry};

    fn shipped(k: usize) -> RkgnnModel {
        shipped_arm("arm3", k)
    }

    fn shipped_arm(arm: &str, k: usize) -> RkgnnModel {
        // The workspace's shipped models (config/models at its root).
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join(format!("../../config/models/{arm}_train{k}.json"));
        RkgnnModel::load(&p).unwrap()
    }

    fn cycle() -> ControlCycle {
        let law = FuzzyComputedTorque::new(
            vec![shipped(1), shipped(2)],
            Rule::paper(Selection::Max),
            &[900.0, 900.0, 900.0, 60.0, 60.0, 60.0],
            0.0,
            vec![40.0, 60.0, 30.0],
            &[vec![0.2, 0.7, -1.3]],
            0.001,
        );
        let reference = crate::reference::Reference::Quintic {
            times: vec![0.0],
            waypoints: vec![vec![0.2, 0.7, -1.3]],
        };
        let bounds = crate::check::ParamBounds {
            lower: vec![0.0; 6],
            upper: vec![2500.0; 6],
        };
        ControlCycle::new(Box::new(law), reference, bounds)
    }

    /// A model set for `slot` with `params`, version `version`.
    fn model_set(version: u64, slot: f64, params: &[f64]) -> ParamSet {
        let mut s = ParamSet {
            version,
            kind: ParamKind::RkgnnModel.code(),
            n: 1 + params.len() as u32,
            ..Default::default()
        };
        s.values[0] = slot;
        s.values[1..=params.len()].copy_from_slice(params);
        s
    }

    /// Offer `set` and run one cycle: its code and the command.
    fn offer(c: &mut ControlCycle, set: &ParamSet) -> (ParamCode, [f64; 3]) {
        let mut state = PlantState::default();
        state.y[..3].copy_from_slice(&[0.1, 0.6, -1.2]);
        c.offer(set);
        let mut tel = Telemetry::default();
        let e = c.step(&state, &mut tel).expect("a parameter event");
        (e.code, [c.u[0], c.u[1], c.u[2]])
    }

    #[test]
    fn a_model_set_is_checked_and_replaces_its_slot_only_when_sound() {
        let mut c = cycle();
        let (m1, m2) = (shipped(1), shipped(2));
        let p2 = m2.net.params();
        let mut nan = p2.to_vec();
        nan[7] = f64::NAN;
        assert_eq!(
            offer(&mut c, &model_set(1, 0.0, &nan)).0,
            ParamCode::RejectedNonFinite
        );
        assert_eq!(
            offer(&mut c, &model_set(1, 2.0, p2)).0,
            ParamCode::RejectedOutOfBounds
        );
        assert_eq!(
            offer(&mut c, &model_set(1, 0.5, p2)).0,
            ParamCode::RejectedOutOfBounds
        );
        assert_eq!(
            offer(&mut c, &model_set(1, 0.0, &p2[1..])).0,
            ParamCode::RejectedWrongLength
        );
        // M-hat scaled towards zero: positive definite, but far below the model in service.
        let mut weak = m1.net.params().to_vec();
        for (_, net) in &m1.net.layout.inertia {
            net.all_weights().for_each(|w| weak[w] *= 0.01);
        }
        assert_eq!(
            offer(&mut c, &model_set(1, 0.0, &weak)).0,
            ParamCode::RejectedNotPositiveDefinite
        );
        assert_eq!(c.version(), 0, "nothing refused is in service");
        // Model 2's weights into slot 0: accepted, and the law then computes with them.
        let (_, before) = offer(&mut c, &model_set(1, 0.0, m1.net.params()));
        let (code, after) = offer(&mut c, &model_set(2, 0.0, p2));
        assert_eq!(code, ParamCode::Accepted);
        assert_eq!(c.version(), 2);
        assert_ne!(before, after);
        // A stale version is refused.
        assert_eq!(
            offer(&mut c, &model_set(2, 0.0, p2)).0,
            ParamCode::RejectedStale
        );
    }

    /// arm7's fuzzy CT on `models` at config/arm7/arm7_fuzzy_ct.toml's mean position, held there.
    fn arm7_cycle(models: Vec<RkgnnModel>) -> ControlCycle {
        let q = vec![0.15, -0.4, 0.15, -2.0, 0.15, 1.75, 0.8];
        let mut gains = vec![900.0; 7];
        gains.extend([60.0; 7]);
        let law = FuzzyComputedTorque::new(
            models,
            Rule::paper(Selection::Max),
            &gains,
            0.0,
            vec![87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0],
            std::slice::from_ref(&q),
            0.0001,
        );
        let reference = crate::reference::Reference::Quintic {
            times: vec![0.0],
            waypoints: vec![q],
        };
        let bounds = crate::check::ParamBounds {
            lower: vec![0.0; 14],
            upper: vec![2500.0; 14],
        };
        ControlCycle::new(Box::new(law), reference, bounds)
    }

    /// Offer the sets, then run a cycle per set: each cycle's event code (None: no event) and
    /// command followed by the version in service, on a state off the set-point so that the
    /// model matters.
    fn offer_all(c: &mut ControlCycle, sets: &[ParamSet]) -> Vec<(Option<ParamCode>, Vec<f64>)> {
        sets.iter().for_each(|s| c.offer(s));
        let mut state = PlantState::default();
        state.y[..7].copy_from_slice(&[0.16, -0.41, 0.14, -1.99, 0.16, 1.74, 0.81]);
        (0..sets.len())
            .map(|_| {
                let mut tel = Telemetry::default();
                let e = c.step(&state, &mut tel).map(|e| e.code);
                let mut u = c.u[..7].to_vec();
                u.push(tel.param_version as f64);
                (e, u)
            })
            .collect()
    }

    #[test]
    fn an_arm7_model_larger_than_a_set_travels_in_parts_and_is_checked_and_applied_whole() {
        let (m1, m2) = (shipped_arm("arm7", 1), shipped_arm("arm7", 2));
        let whole = |slot: f64, m: &RkgnnModel| {
            let mut v = vec![slot];
            v.extend_from_slice(m.net.params());
            v
        };
        let parts = |version, values: &[f64]| {
            ParamSet::model_sets(version, 0, f64::NAN, ParamKind::RkgnnModel, values)
        };
        let new_model = parts(1, &whole(0.0, &m2));
        assert!(whole(0.0, &m2).len() > crate::msg::MAX_PARAMS);
        assert_eq!(new_model.len(), 4);
        let mut c = arm7_cycle(vec![m1.clone(), m2.clone()]);
        let before = offer_all(&mut c, &[ParamSet::default()])[0].1.clone();
        // Gathering: no event, nothing of the new model in service, until its last part.
        let out = offer_all(&mut c, &new_model);
        for (code, u) in &out[..3] {
            assert_eq!((*code, u), (None, &before));
        }
        assert_eq!(out[3].0, Some(ParamCode::Accepted));
        assert_eq!(c.version(), 1);
        // Slot 0 now computes exactly as model 2 does (the same command, bit for bit).
        let mut reference = arm7_cycle(vec![m2.clone(), m2.clone()]);
        let mut want = offer_all(&mut reference, &[ParamSet::default()])[0]
            .1
            .clone();
        want[7] = 1.0;
        assert_eq!(out[3].1, want);
        assert_ne!(want[..7], before[..7]);
        // A part lost: the model is refused once, whole; the loop keeps model 2.
        let lost = parts(2, &whole(0.0, &m1));
        let out = offer_all(&mut c, &[lost[0], lost[2], lost[3]]);
        let codes: Vec<_> = out.iter().map(|o| o.0).collect();
        assert_eq!(codes, [None, Some(ParamCode::RejectedPartMissing), None]);
        assert!(out.iter().all(|o| o.1 == want));
        // A NaN in the last part: refused at that part; an indefinite whole: refused whole.
        let mut nan = parts(3, &whole(0.0, &m1));
        nan[3].values[9] = f64::NAN;
        let out = offer_all(&mut c, &nan);
        assert_eq!(out[3].0, Some(ParamCode::RejectedNonFinite));
        let mut flipped = whole(0.0, &m1);
        for (_, net) in &m1.net.layout.inertia {
            net.all_weights()
                .for_each(|w| flipped[1 + w] = -flipped[1 + w]);
        }
        let out = offer_all(&mut c, &parts(4, &flipped));
        assert_eq!(out[3].0, Some(ParamCode::RejectedNotPositiveDefinite));
        assert!(out.iter().all(|o| o.1 == want));
        assert_eq!(c.version(), 1);
        // The next whole model is accepted.
        let out = offer_all(&mut c, &parts(5, &whole(0.0, &m1)));
        let mut back = before;
        back[7] = 5.0;
        assert_eq!(out[3], (Some(ParamCode::Accepted), back));
    }

    #[test]
    fn telemetry_carries_the_active_model_and_the_memberships() {
        let mut c = cycle();
        let mut tel = Telemetry::default();
        c.step(&PlantState::default(), &mut tel);
        assert_eq!(tel.n_law, 3);
        let w = &tel.law[1..3];
        assert!((w[0] + w[1] - 1.0).abs() < 1e-12, "{w:?}");
        let active = if w[0] >= w[1] { 0.0 } else { 1.0 };
        assert_eq!(tel.law[0], active);
    }
}
