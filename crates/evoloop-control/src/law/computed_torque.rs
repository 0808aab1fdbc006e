//! Computed-torque control with a rigid-body model (RKGNN paper, Fig. 6 and Section 5.1):
//!   tau = psi(k) [ M(q) (qdd_d + K_v e_dot + K_p e) + V(q, qd) + G(q) + F(qd) ],
//! e = q_d - q, with the start-up damping psi(k) = 1 - exp(-c k) (c = 0.03 per sample in the
//! paper) that fades the torque in over the first samples so the initial transient does not
//! kick the arm. With the true model the error obeys e_dd + K_v e_d + K_p e = 0 between samples.
//!
//! The whole bracket is one recursive Newton-Euler pass with the commanded acceleration
//! (tau = ID(q, qd, a)), a few hundred nanoseconds for six joints and allocation-free.
//! Parameters: [Kp_1..Kp_n, Kv_1..Kv_n]. Positions are the measured outputs y; velocities by
//! default the encoders' differenced and low-passed (`velocity = "filtered"`), or a model-based
//! observer's that predicts with this law's model in service from the applied torques
//! (`velocity = "observer"`), or the simulator's true joint velocities `qd_true` (`velocity =
//! "true"`, as the paper's simulation has them; the programmatic constructor's start).
//!
//! The model itself can be replaced while the loop runs (an identified model, the eMuPSO
//! paper's Section 4.1 put to use): a set of kind `ParamKind::RigidBodyModel` carries the
//! parameters in the regressor's order with friction and armature (13 per joint,
//! `identify::Columns::PLANT`; e.g. `identify lls`'s `model_parameters`). It is checked on a
//! second model kept for the purpose: on `PROBES` fixed positions inside the joint limits,
//! M(q) - floor I must be positive definite (an in-place Cholesky), the floor being
//! `MIN_EIG_RATIO` of the configured model's smallest eigenvalue there; then the two models
//! swap. The floor stays the configured model's, so a series of sets cannot ratchet it down.
//! Nothing is allocated.

use super::estimator::{Velocities, VelocitySource};
use super::{
    driven_arm, joint_gains, model_file, velocity_source, Controller, ControllerConfig,
    ControllerContext, VelocityKey,
};
use crate::check::{Check, ConfigError, Tunable};
use crate::dynamics::{Data, Model};
use crate::linalg::cholesky_solve_in_place;
use crate::msg::{ParamCode, ParamKind, PlantState};
use crate::reference::Setpoint;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The computed-torque law of the module docs: its model in service, a second model on which a
/// replacement is checked, the gains [Kp; Kv] and the velocity source. Built once, then stepped
/// without allocating.
pub struct ComputedTorque {
    model: Model,
    data: Data,
    /// Where a replacement model is checked before it swaps with `model`.
    candidate: Model,
    /// Fixed positions inside the joint limits on which a replacement's M(q) is checked, the
    /// floor its eigenvalues must stay above there, and the Cholesky's buffers.
    probes: Vec<Vec<f64>>,
    floor: f64,
    m: nalgebra::DMatrix<f64>,
    rhs: nalgebra::DVector<f64>,
    gains: Vec<f64>,
    /// psi's rate c per sample; 0 = no start-up damping.
    startup_rate: f64,
    k: u64,
    acc: Vec<f64>,
    q: Vec<f64>,
    qd: Vec<f64>,
    velocity: Velocities,
}

impl ComputedTorque {
    /// `gains` = [Kp; Kv] (2n values).
    pub fn new(model: Model, gains: &[f64], startup_rate: f64) -> Self {
        let n = model.dof();
        assert_eq!(gains.len(), 2 * n, "computed-torque gains are [Kp; Kv]");
        let probes = probe_positions(&model);
        let mut data = model.data();
        let floor = MIN_EIG_RATIO * smallest_eigenvalue(&model, &mut data, &probes);
        Self {
            data,
            candidate: model.clone(),
            probes,
            floor,
            m: nalgebra::DMatrix::zeros(n, n),
            rhs: nalgebra::DVector::zeros(n),
            model,
            gains: gains.to_vec(),
            startup_rate,
            k: 0,
            acc: vec![0.0; n],
            q: vec![0.0; n],
            qd: vec![0.0; n],
            velocity: Velocities::True,
        }
    }

    /// Read velocities from `source` (the true ones until this is called), every `period` s.
    pub fn with_velocity(mut self, source: VelocitySource, period: f64) -> Self {
        self.velocity = Velocities::new(source, self.model.dof(), period, Some(&self.model));
        self
    }

    /// psi(k) = 1 - exp(-c k).
    pub fn psi(&self, k: u64) -> f64 {
        startup_damping(self.startup_rate, k)
    }
}

/// Positions a replacement model's M(q) is checked on.
pub const PROBES: usize = 24;
pub use crate::law::fuzzy_computed_torque::MIN_EIG_RATIO;

/// `PROBES` positions spread over the joint limits (+-pi where there are none) by a fixed
/// low-discrepancy sequence (the golden-ratio additive recurrence per joint): the same probes on
/// every run.
fn probe_positions(model: &Model) -> Vec<Vec<f64>> {
    (0..PROBES)
        .map(|k| {
            model
                .bodies
                .iter()
                .enumerate()
                .map(|(j, b)| {
                    let (lo, hi) = b.limits.position_span();
                    let alpha = (0.618_033_988_749_895 * (j + 1) as f64).fract();
                    let x = (0.5 + alpha * (k + 1) as f64).fract();
                    lo + (hi - lo) * x
                })
                .collect()
        })
        .collect()
}

/// Smallest eigenvalue of M(q) over `probes` (NaN for a NaN matrix).
fn smallest_eigenvalue(model: &Model, d: &mut Data, probes: &[Vec<f64>]) -> f64 {
    let n = model.dof();
    let mut m: crate::linalg::Mat = [0.0; crate::MAX_JOINTS * crate::MAX_JOINTS];
    let mut worst = f64::INFINITY;
    for q in probes {
        let mm = model.mass_matrix(d, q);
        for a in 0..n {
            for b in 0..n {
                m[a * n + b] = mm[(a, b)];
            }
        }
        let e = crate::linalg::sym_eig_range(n, &m).0;
        if e.is_nan() {
            return f64::NAN;
        }
        worst = worst.min(e);
    }
    worst
}

/// The start-up damping psi(k) = 1 - exp(-c k) at sample k for rate c per sample (1 when c = 0).
pub fn startup_damping(rate: f64, k: u64) -> f64 {
    if rate > 0.0 {
        1.0 - (-rate * k as f64).exp()
    } else {
        1.0
    }
}

/// The last step of a computed-torque law: u <- psi u, clamped to each joint's effort limit.
pub(crate) fn damp_and_limit(u: &mut [f64], psi: f64, effort: impl Iterator<Item = f64>) {
    for (ui, limit) in u.iter_mut().zip(effort) {
        *ui = (psi * *ui).clamp(-limit, limit);
    }
}

impl Controller for ComputedTorque {
    fn kind(&self) -> ParamKind {
        ParamKind::ComputedTorque
    }
    fn n_params(&self) -> usize {
        self.gains.len()
    }
    fn params(&self) -> &[f64] {
        &self.gains
    }
    fn n_outputs(&self) -> usize {
        self.model.dof()
    }

    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        let n = self.model.dof();
        let (kp, kv) = self.gains.split_at(n);
        self.qd
            .copy_from_slice(self.velocity.read(state, n, Some(&self.model)));
        // On a late sensor the observer's prediction of the present, else the measurement.
        let q = self.velocity.predicted_positions().unwrap_or(&state.y[..n]);
        for i in 0..n {
            self.q[i] = q[i];
            let e = sp.q[i] - self.q[i];
            let ed = sp.qd[i] - self.qd[i];
            self.acc[i] = sp.qdd[i] + kv[i] * ed + kp[i] * e;
        }
        self.model
            .inverse_dynamics(&mut self.data, &self.q, &self.qd, &self.acc, &mut u[..n]);
        let psi = self.psi(self.k);
        damp_and_limit(
            &mut u[..n],
            psi,
            self.model.bodies.iter().map(|b| b.limits.effort),
        );
        self.k += 1;
    }

    fn swap_params(&mut self, new: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.gains.copy_from_slice(new);
    }

    fn model_kind(&self) -> Option<ParamKind> {
        Some(ParamKind::RigidBodyModel)
    }

    fn model_len(&self) -> usize {
        MODEL_COLUMNS_PER_JOINT * self.model.dof()
    }

    fn swap_model(&mut self, values: &[f64]) -> Result<(), (ParamCode, u32)> {
        let n = self.model.dof();
        if values.len() != MODEL_COLUMNS_PER_JOINT * n {
            return Err((ParamCode::RejectedWrongLength, values.len() as u32));
        }
        self.candidate.set_parameters(values, true, true);
        for q in &self.probes {
            // The candidate's M(q) is computed in the in-service Data: step() refills it.
            self.m
                .copy_from(self.candidate.mass_matrix(&mut self.data, q));
            for j in 0..n {
                self.m[(j, j)] -= self.floor;
            }
            if cholesky_solve_in_place(&mut self.m, &mut self.rhs).is_err() {
                return Err((ParamCode::RejectedNotPositiveDefinite, 0));
            }
        }
        std::mem::swap(&mut self.model, &mut self.candidate);
        Ok(())
    }
}

/// Values per joint of a model set: ten rigid-body parameters, viscous and Coulomb friction and
/// the armature (`identify::Columns::PLANT`'s layout).
pub const MODEL_COLUMNS_PER_JOINT: usize = 13;

// ---------------------------------------------------------------- configuration

/// The `[controller.computed_torque]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    kp: Vec<f64>,
    kv: Vec<f64>,
    /// psi's rate per sample (default 0.03, the paper's).
    startup_rate: Option<f64>,
    /// A robot file for the controller's model other than the plant's (relative to the scenario).
    model: Option<PathBuf>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
    velocity: Option<VelocityKey>,
    velocity_cutoff_hz: Option<f64>,
}

/// Validated computed-torque gains [Kp; Kv] with their bounds, the start-up rate and the model.
#[derive(Debug, Clone, Serialize)]
pub struct ComputedTorqueSpec {
    /// The gains [Kp_1..Kp_n, Kv_1..Kv_n] (each >= 0) and their bounds.
    #[serde(flatten)]
    pub tunable: Tunable,
    /// psi's rate per sample (0 = off).
    pub startup_rate: f64,
    /// The controller's model (the plant's robot unless `model` is given).
    pub model: Model,
    /// Where the law's joint velocities come from (`velocity`; differenced and low-passed by
    /// default).
    pub velocity: VelocitySource,
}

/// Validate `[controller.computed_torque]` for the arm the plant drives: `kp` and `kv` (one per
/// joint, >= 0, within their bounds), the start-up rate, the model (a robot file with as many
/// joints, else the plant's) and the velocity source. Fails when the plant is no arm or the table
/// is missing.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &ControllerContext,
) -> Result<ComputedTorqueSpec, ConfigError> {
    let arm = driven_arm(check, cx, "computed_torque")?;
    let Some(t) = t else {
        return check.fail(
            "controller.computed_torque",
            "missing table [controller.computed_torque] with `kp` and `kv`",
        );
    };
    let n = arm.dof();
    let (tunable, startup_rate) = gains_and_startup(
        check,
        "computed_torque",
        n,
        [t.kp, t.kv],
        t.startup_rate,
        t.lower,
        t.upper,
    )?;
    let model = match t.model {
        Some(rel) => model_file(check, "controller.computed_torque.model", &rel, n)?,
        None => arm.clone(),
    };
    Ok(ComputedTorqueSpec {
        tunable,
        startup_rate,
        model,
        velocity: velocity_source(
            check,
            "computed_torque",
            t.velocity,
            t.velocity_cutoff_hz,
            cx,
            true,
        )?,
    })
}

/// The keys every computed-torque law (`law`) shares: the gains [Kp; Kv] for `n` joints with
/// their bounds, and psi's rate (default 0.03, the paper's).
pub(crate) fn gains_and_startup(
    check: &Check,
    law: &str,
    n: usize,
    gains: [Vec<f64>; 2],
    startup_rate: Option<f64>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
) -> Result<(Tunable, f64), ConfigError> {
    let tunable = joint_gains(check, law, n, ["kp", "kv"], gains, lower, upper)?;
    let rate = check.range(
        &format!("controller.{law}.startup_rate"),
        startup_rate.unwrap_or(0.03),
        0.0,
        10.0,
    )?;
    Ok((tunable, rate))
}

impl ControllerConfig for ComputedTorqueSpec {
    fn build(&self, period: f64, _u_limit: Option<f64>) -> Box<dyn Controller> {
        Box::new(
            ComputedTorque::new(self.model.clone(), &self.tunable.gains, self.startup_rate)
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
        ParamKind::ComputedTorque
    }
    fn model_param_kind(&self) -> Option<ParamKind> {
        Some(ParamKind::RigidBodyModel)
    }
}
