//! Identification of a robot's inertial parameters (the eMuPSO paper, Sections 3.4-4.1): what
//! an experiment can identify, the excitation trajectory that identifies it best, and the linear
//! least squares that estimate it from a run.
//!
//! - `Columns`: the parameters estimated — the ten rigid-body ones per body (the regressor's
//!   order), and per joint the friction (viscous, Coulomb) and the armature the plant simulates;
//! - `Stage`: one experiment — which joints move (the others are held), and so which torques
//!   carry information (the moving joints'). The paper identifies a 6-DOF arm in two stages, the
//!   wrist (joints 4-6, arm held) and then the arm (joints 1-3, wrist held); `all` moves every
//!   joint;
//! - `reference::series` (below the configuration, which loads it): the joint-space finite
//!   Fourier series (Swevers) the trajectories are;
//! - `mfs`: the paper's modified Fourier series, a Cartesian path of the wrist centre through
//!   inverse kinematics;
//! - `excitation`: eq. 15's fitness and the two-stage eMuPSO search of Section 4.1;
//! - `lls`: least squares on a run's recorded positions and torques;
//! - `study`: optimised against random feasible excitation, paired over seeds.

mod error;
pub mod excitation;
pub mod lls;
pub mod mfs;
pub mod study;

pub use error::ExcitationError;

use crate::dynamics::base::{reduce, BaseParameters};
use crate::dynamics::{Data, Model};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use serde::{Deserialize, Serialize};

/// The parameters an identification estimates, in column order: the rigid-body parameters of
/// every body, then (with `friction`) fv, fc per joint, then (with `armature`) Ia per joint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Columns {
    /// Estimate every joint's viscous and Coulomb friction (fv, fc).
    pub friction: bool,
    /// Estimate every joint's armature Ia (the reflected rotor inertia).
    pub armature: bool,
}

impl Columns {
    /// What the plant simulates: friction and armature (the arm plant has both).
    pub const PLANT: Columns = Columns {
        friction: true,
        armature: true,
    };

    /// Number of columns (parameters estimated) for `model`.
    pub fn count(&self, model: &Model) -> usize {
        model.regressor_columns(self.friction) + if self.armature { model.dof() } else { 0 }
    }

    /// The columns' names in column order (the model's parameter names, then Ia1..Ian).
    pub fn names(&self, model: &Model) -> Vec<String> {
        let mut names = model.parameter_names(self.friction);
        if self.armature {
            names.extend((1..=model.dof()).map(|j| format!("Ia{j}")));
        }
        names
    }

    /// The model's own values in column order.
    pub fn values(&self, model: &Model) -> Vec<f64> {
        let mut pi = model.parameters(self.friction);
        if self.armature {
            pi.extend(model.bodies.iter().map(|b| b.armature));
        }
        pi
    }

    /// The regressor at one state into `y` (dof x count) and `scratch` (dof x the rigid-body
    /// and friction columns): tau = y pi is the model's inverse dynamics.
    pub fn regressor(
        &self,
        model: &Model,
        d: &mut Data,
        state: [&[f64]; 3],
        scratch: &mut DMatrix<f64>,
        y: &mut DMatrix<f64>,
    ) {
        let [q, qd, qdd] = state;
        model.regressor(d, q, qd, qdd, scratch);
        let p = scratch.ncols();
        y.view_mut((0, 0), (model.dof(), p)).copy_from(scratch);
        if self.armature {
            let n = model.dof();
            let mut arm = y.view_mut((0, p), (n, n));
            arm.fill(0.0);
            for j in 0..n {
                arm[(j, j)] = qdd[j];
            }
        }
    }
}

/// Which part of the arm an experiment identifies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StageKind {
    /// The last three joints move, the others are held (the paper's first stage).
    Wrist,
    /// All but the last three joints move, the wrist is held (the paper's second stage).
    Arm,
    /// Every joint moves (one-stage identification).
    All,
}

/// One identification experiment: the joints that move and where the others are held.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage {
    /// Which part of the arm moves.
    pub kind: StageKind,
    /// Per joint, whether it moves (its torque row is used); the others are held.
    pub moving: Vec<bool>,
    /// Every joint's position when held (the moving joints' entries are not used).
    pub hold: Vec<f64>,
}

impl Stage {
    /// The stage `kind` of `model`, held joints at zero (or the middle of their range when zero
    /// is outside it). Wrist and arm stages need at least four joints.
    pub fn new(kind: StageKind, model: &Model) -> Result<Stage, ExcitationError> {
        let n = model.dof();
        if kind != StageKind::All && n < 4 {
            let name = if kind == StageKind::Wrist {
                "wrist"
            } else {
                "arm"
            };
            return Err(ExcitationError::Robot(format!(
                "a {name} stage splits the last three joints from the others: {} has {n} \
                 joints (use --stage all)",
                model.name
            )));
        }
        let moving = (0..n)
            .map(|j| match kind {
                StageKind::Wrist => j + 3 >= n,
                StageKind::Arm => j + 3 < n,
                StageKind::All => true,
            })
            .collect();
        let hold = model
            .bodies
            .iter()
            .map(|b| {
                let (lo, hi) = (b.limits.q_min, b.limits.q_max);
                if (lo..=hi).contains(&0.0) {
                    0.0
                } else {
                    0.5 * (lo + hi)
                }
            })
            .collect();
        Ok(Stage { kind, moving, hold })
    }

    /// The stage of a run whose joints `moving` move (from its reference).
    pub fn from_moving(moving: Vec<bool>, hold: Vec<f64>) -> Stage {
        let n = moving.len();
        let wrist = (0..n).all(|j| moving[j] == (j + 3 >= n));
        let arm = (0..n).all(|j| moving[j] == (j + 3 < n));
        let kind = if n >= 4 && wrist {
            StageKind::Wrist
        } else if n >= 4 && arm {
            StageKind::Arm
        } else {
            StageKind::All
        };
        Stage { kind, moving, hold }
    }

    /// The moving joints' indices: the rows of the torques the stage uses.
    pub fn rows(&self) -> Vec<usize> {
        (0..self.moving.len()).filter(|&j| self.moving[j]).collect()
    }

    /// The stage's name as commands and reports spell it: `wrist`, `arm` or `all`.
    pub fn name(&self) -> &'static str {
        self.kind.name()
    }
}

impl StageKind {
    /// Every kind, as `--stage` lists them.
    pub const ALL: [StageKind; 3] = [StageKind::Wrist, StageKind::Arm, StageKind::All];

    /// The kind's name as commands and reports spell it: `wrist`, `arm` or `all`.
    pub fn name(self) -> &'static str {
        match self {
            StageKind::Wrist => "wrist",
            StageKind::Arm => "arm",
            StageKind::All => "all",
        }
    }
}

/// The regressor of `stage` stacked over states: for each state, the moving joints' rows.
pub struct Stacker<'a> {
    model: &'a Model,
    columns: Columns,
    rows: Vec<usize>,
    d: Data,
    scratch: DMatrix<f64>,
    y: DMatrix<f64>,
}

impl<'a> Stacker<'a> {
    /// A stacker of `model`'s regressor in `columns`, keeping `stage`'s moving joints' rows.
    pub fn new(model: &'a Model, columns: Columns, stage: &Stage) -> Self {
        let n = model.dof();
        Self {
            model,
            columns,
            rows: stage.rows(),
            d: model.data(),
            scratch: DMatrix::zeros(n, model.regressor_columns(columns.friction)),
            y: DMatrix::zeros(n, columns.count(model)),
        }
    }

    /// Rows per state.
    pub fn rows_per_state(&self) -> usize {
        self.rows.len()
    }

    /// Write the state's rows into `w` from row `at`.
    pub fn put(&mut self, state: [&[f64]; 3], w: &mut DMatrix<f64>, at: usize) {
        self.columns.regressor(
            self.model,
            &mut self.d,
            state,
            &mut self.scratch,
            &mut self.y,
        );
        for (k, &j) in self.rows.iter().enumerate() {
            w.row_mut(at + k).copy_from(&self.y.row(j));
        }
    }
}

/// The base parameters of `stage`: the regressor of `states` random states (moving joints across
/// their range or +-pi, unit-scale velocities and accelerations; held joints at rest at their
/// hold positions) reduced to its base columns.
pub fn stage_base(
    model: &Model,
    columns: Columns,
    stage: &Stage,
    states: usize,
    seed: u64,
) -> BaseParameters {
    let n = model.dof();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut stacker = Stacker::new(model, columns, stage);
    let per = stacker.rows_per_state();
    let mut w = DMatrix::zeros(states * per, columns.count(model));
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for s in 0..states {
        for j in 0..n {
            if stage.moving[j] {
                let (lo, hi) = model.bodies[j].limits.position_span();
                q[j] = rng.gen_range(lo..hi);
                qd[j] = rng.gen_range(-1.0..1.0);
                qdd[j] = rng.gen_range(-1.0..1.0);
            } else {
                (q[j], qd[j], qdd[j]) = (stage.hold[j], 0.0, 0.0);
            }
        }
        stacker.put([&q, &qd, &qdd], &mut w, s * per);
    }
    reduce(&w, columns.names(model), &columns.values(model))
}

/// Enough random states for `stage_base` to see the rank: the columns over the rows per state,
/// with a margin.
pub fn states_needed(model: &Model, columns: Columns, stage: &Stage) -> usize {
    let rows = stage.rows().len().max(1);
    3 * columns.count(model).div_ceil(rows) + 10
}
