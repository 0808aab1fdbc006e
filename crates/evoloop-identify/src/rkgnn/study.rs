//! The RKGNN paper's Section 5 on any 3-joint arm (`evoloop rkgnn study`): identify a model on
//! each training trajectory from the arm under its P-D servo (reference and output only), then
//! track the new trajectory with the P-D servo alone, computed torque on the true model, on
//! either identified model alone, and on both by fuzzy selection (the paper's "max" rule and our
//! "blend"), and draw Figs. 7-10.
//!
//! The trajectories, servo, computed-torque gains and plant settings are the shipped scenarios'
//! (`config/arm3/arm3_train1.toml`, `config/arm3/arm3_train2.toml` and the new trajectory of
//! `config/arm3/arm3_fuzzy_ct.toml`), compiled in, so the study on `config/robots/arm3.toml` is those
//! scenarios and its models are the shipped models' recipe (`identify::Settings::least_squares`).
//! On another arm only the robot changes, and the servo, which a vendor tunes to its arm: each
//! joint's k_p, k_d scale with the mid-range of the arm's M_jj over the trajectories relative to arm3's (the
//! same closed-loop bandwidth and damping; a factor of exactly 1 on arm3). The computed-torque
//! gains are accelerations per error and carry over unchanged.
//!
//! Every case is a scenario run by `sim::simulate`, the loop the processes run in lockstep; each
//! is written to `scenarios/` so one can be rerun through the processes with `evoloop run`.

use crate::config::{Overrides, Scenario};
use crate::dynamics::Model;
use crate::report::metrics::tracking;
use crate::report::plot::{stacked_png, Panel, PlotError, Series};
use crate::report::Csv;
use crate::report::RunLog;
use crate::rkgnn::identify::{self, Prior, Settings};
use crate::rkgnn::{StudyError, Trajectory};
use crate::sim::{simulate, JointTraces, SimResult};
use evoloop_rkgnn::model::Report;
use evoloop_schemes::WriteError;
use serde::Serialize;
use std::path::{Path, PathBuf};

const TRAIN1: &str = include_str!("../../../../config/arm3/arm3_train1.toml");
const TRAIN2: &str = include_str!("../../../../config/arm3/arm3_train2.toml");
const NEW: &str = include_str!("../../../../config/arm3/arm3_fuzzy_ct.toml");
/// The arm the shipped servo gains are for (its inertia is the gains' unit).
const ARM3: &str = include_str!("../../../../config/robots/arm3.toml");

/// Joints the study's trajectories are written for.
pub const JOINTS: usize = 3;

/// What `evoloop rkgnn study` is asked for.
#[derive(Debug, Clone)]
pub struct StudySettings {
    /// The robot file of the 3-joint arm studied.
    pub robot: PathBuf,
    /// Measurement-noise seed of every run and the EA's seed.
    pub seed: u64,
    /// EA evaluations after the least-squares start (0 = the start itself).
    pub evaluations: usize,
    /// Levenberg-Marquardt steps on the output error after the start (0 = none).
    pub refine: usize,
    /// Whether the identification knows the training servo's gains (the study's own P-D
    /// servo) or, as in the paper's premise, not.
    pub servo_known: bool,
    /// Where the EA starts (the shipped recipe: least squares).
    pub start: evoloop_rkgnn::model::Start,
    /// Half width of the identification's low-pass, s (`evoloop_rkgnn::SMOOTHING` by default).
    pub smoothing: f64,
    /// The joint velocity every run's controller acts on.
    pub velocity: JointVelocity,
    /// Worker threads for the simulations and the identifications.
    pub threads: usize,
}

/// The joint velocity an arm study's controllers act on (the training servo's and every
/// tracking law's `velocity` key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JointVelocity {
    /// The measured positions differenced and low-passed at 50 Hz, as a servo drive does: the
    /// scenarios' default.
    Filtered,
    /// The simulator's velocities, an ideal sensor no plant has: the studies' figures before
    /// 2026-12-03, for comparison.
    True,
}

impl JointVelocity {
    /// Both, as `--joint-velocity` lists them.
    pub const ALL: [JointVelocity; 2] = [JointVelocity::Filtered, JointVelocity::True];

    /// The value of the scenarios' `velocity` key: "filtered" or "true".
    pub fn key(self) -> &'static str {
        match self {
            JointVelocity::Filtered => "filtered",
            JointVelocity::True => "true",
        }
    }

    /// The drive filter's cutoff (the scenarios' default at this control period), if any.
    pub fn drive_cutoff_hz(self, period: f64) -> Option<f64> {
        (self == JointVelocity::Filtered).then(|| crate::law::default_velocity_cutoff_hz(period))
    }
}

/// RMS tracking error per joint (rad) on the new trajectory, one entry per controller.
#[derive(Debug, Clone, Serialize)]
pub struct TrackingRms {
    /// The training P-D servo alone.
    pub pd: Vec<f64>,
    /// Computed torque on the arm's true model.
    pub ct_true: Vec<f64>,
    /// Computed torque on model 1 alone (identified on train1).
    pub ct_model_1: Vec<f64>,
    /// Computed torque on model 2 alone (identified on train2).
    pub ct_model_2: Vec<f64>,
    /// Fuzzy computed torque on both models, the paper's max rule.
    pub ct_fuzzy_max: Vec<f64>,
    /// Fuzzy computed torque on both models, our blend rule.
    pub ct_fuzzy_blend: Vec<f64>,
}

impl TrackingRms {
    /// (key, label, per joint) in the table's order.
    pub fn entries(&self) -> [(&'static str, &'static str, &[f64]); 6] {
        [
            ("pd", "P-D servo alone", &self.pd),
            ("ct_true", "CT, true model", &self.ct_true),
            ("ct_model_1", "CT, model 1 only", &self.ct_model_1),
            ("ct_model_2", "CT, model 2 only", &self.ct_model_2),
            ("ct_fuzzy_max", "fuzzy CT (max)", &self.ct_fuzzy_max),
            ("ct_fuzzy_blend", "fuzzy CT (blend)", &self.ct_fuzzy_blend),
        ]
    }
}

/// One identified model as the study reports it.
#[derive(Debug, Clone, Serialize)]
pub struct ModelSummary {
    /// The model's file (`model_<k>.json` in the study's directory).
    pub file: PathBuf,
    /// The training run it was identified on.
    pub trajectory: String,
    /// Free-run prediction error over the training window, RMS per joint, rad.
    pub train_rms: Vec<f64>,
    /// The same over the held-out end of the run, rad.
    pub holdout_rms: Vec<f64>,
    /// Smallest eigenvalue of M-hat over the model's own training positions.
    pub min_eig_m_hat: f64,
    /// Smallest eigenvalue of M-hat along the new trajectory, where the controller runs it
    /// (the controller refuses a model at or below 0 there).
    pub min_eig_on_reference: f64,
    /// The EA's evaluations in the identification.
    pub evaluations: usize,
}

impl ModelSummary {
    pub(super) fn of(file: PathBuf, trajectory: &str, r: &Report, on_reference: f64) -> Self {
        Self {
            file,
            trajectory: trajectory.to_string(),
            train_rms: r.train_rms.clone(),
            holdout_rms: r.holdout_rms.clone(),
            min_eig_m_hat: r.min_eig_m_hat,
            min_eig_on_reference: on_reference,
            evaluations: r.evaluations,
        }
    }
}

/// Everything the identification was given, per model: the run's signals and eq. 2's bounds;
/// with `servo_known`, the training servo's gains. No robot file: the study reads the robot only
/// to simulate the runs and, like a user's CAD model, to give m1 and m2.
#[derive(Debug, Clone, Serialize)]
pub struct IdentificationInputs {
    /// The training runs fitted, one model each.
    pub runs: Vec<String>,
    /// What of each run the fit reads.
    pub signals: &'static str,
    /// Eq. 2's lower bound m_1.
    pub m1: f64,
    /// Eq. 2's upper bound m_2.
    pub m2: f64,
    /// What the identification was told of the training servo.
    pub servo: evoloop_rkgnn::model::ServoPrior,
    /// Where the identification started.
    pub start: evoloop_rkgnn::model::Start,
    /// Samples per RKGNN step (h = stride x the runs' period).
    pub stride: usize,
    /// The velocity estimate's and position smoothing's half width, s.
    pub smoothing: f64,
    /// The EA's evaluations after the start (0 = the start itself).
    pub evaluations: usize,
    /// Levenberg-Marquardt steps on the output error after the start (0 = none).
    pub refine: usize,
}

/// `study.json`.
#[derive(Debug, Clone, Serialize)]
pub struct StudyResult {
    /// The robot file studied, absolute.
    pub robot: PathBuf,
    /// Measurement-noise seed of every run and the EA's seed.
    pub seed: u64,
    /// The EA's evaluations after the start (0 = the start itself).
    pub evaluations: usize,
    /// The P-D servo's gains on this arm (arm3's scaled by the inertia ratio).
    pub servo_kp: Vec<f64>,
    /// The P-D servo's k_d per joint on this arm.
    pub servo_kd: Vec<f64>,
    /// Per joint, this arm's mid-range M_jj over the trajectories over arm3's: the factor
    /// on the servo's gains.
    pub inertia_ratio: Vec<f64>,
    /// Computed torque's gains.
    pub ct_kp: Vec<f64>,
    /// Computed torque's velocity gains K_v, 1/s (`ct_kp`: K_p, 1/s^2).
    pub ct_kv: Vec<f64>,
    /// Everything the identification was given.
    pub identification_inputs: IdentificationInputs,
    /// The two identified models, train1's then train2's.
    pub models: Vec<ModelSummary>,
    /// The new trajectory.
    pub tracking_rms: TrackingRms,
    /// Figs. 8 and 9: CT with model 1 on trajectory 1 and model 2 on trajectory 2.
    pub own_trajectory_rms: [Vec<f64>; 2],
    /// Fraction of the new trajectory's samples on which each model had the largest weight.
    pub fuzzy_share: Vec<f64>,
    /// Smallest and largest normalised membership of model 1 over the new trajectory.
    pub membership_range: [f64; 2],
    /// The study's wall-clock time, s.
    pub seconds: f64,
}

/// A scenario text edited as TOML and validated like a user's file.
pub(super) struct Case {
    pub(super) name: String,
    text: String,
    pub(super) scenario: Scenario,
}

pub(super) fn table<'a>(
    t: &'a mut toml::Table,
    key: &str,
) -> Result<&'a mut toml::Table, StudyError> {
    t.get_mut(key)
        .and_then(toml::Value::as_table_mut)
        .ok_or_else(|| StudyError::BuiltIn(format!("no table [{key}]")))
}

pub(super) fn floats(v: &toml::Value) -> Result<Vec<f64>, StudyError> {
    v.as_array()
        .and_then(|a| {
            a.iter()
                .map(toml::Value::as_float)
                .collect::<Option<Vec<_>>>()
        })
        .ok_or_else(|| StudyError::BuiltIn(format!("`{v}` is not a list of numbers")))
}

pub(super) fn float_list(v: &[f64]) -> toml::Value {
    toml::Value::Array(v.iter().map(|x| toml::Value::Float(*x)).collect())
}

/// `base` (a built-in scenario) for `robot` with the controller table `controller` acting on
/// `velocity`, validated as `dir/scenarios/NAME.toml` (`write_scenarios` writes it there).
pub(super) fn case(
    name: &str,
    base: &str,
    robot: &Path,
    seed: u64,
    mut controller: toml::Table,
    velocity: JointVelocity,
    dir: &Path,
) -> Result<Case, StudyError> {
    let kind = controller
        .get("kind")
        .and_then(|k| k.as_str())
        .map(str::to_owned);
    let law = kind.ok_or_else(|| StudyError::BuiltIn("a controller without its kind".into()))?;
    table(&mut controller, &law)?.insert("velocity".into(), velocity.key().into());
    let mut t: toml::Table = base
        .parse()
        .map_err(|e: toml::de::Error| StudyError::BuiltIn(e.to_string()))?;
    t.insert("name".into(), format!("rkgnn_study_{name}").into());
    t.insert("seed".into(), toml::Value::Integer(seed as i64));
    let plant = table(&mut t, "plant")?;
    table(plant, "arm")?.insert("robot".into(), robot.display().to_string().into());
    t.insert("controller".into(), controller.into());
    table(&mut t, "output")?.insert(
        "dir".into(),
        dir.join("runs").join(name).display().to_string().into(),
    );
    let text = toml::to_string(&t).map_err(|e| StudyError::BuiltIn(e.to_string()))?;
    let path = dir.join("scenarios").join(format!("{name}.toml"));
    let scenario = Scenario::parse(&text, &path, &Overrides::default())?;
    scenario.require_in_process()?;
    Ok(Case {
        name: name.to_string(),
        text,
        scenario,
    })
}

/// What an identification is told of the training run `case`'s P-D servo: its gains, the arm's
/// torque limits and the velocity it acted on when `known`, nothing (the paper's premise)
/// otherwise.
pub(super) fn servo_prior(
    known: bool,
    [kp, kd]: [&[f64]; 2],
    (velocity, case): (JointVelocity, &Case),
    arm: &crate::dynamics::Model,
) -> evoloop_rkgnn::model::ServoPrior {
    match known {
        true => evoloop_rkgnn::model::ServoPrior::Known {
            kp: kp.to_vec(),
            kd: kd.to_vec(),
            limits: Some(arm.bodies.iter().map(|b| b.limits.effort).collect()),
            velocity_cutoff_hz: velocity.drive_cutoff_hz(case.scenario.timing.period),
        },
        false => evoloop_rkgnn::model::ServoPrior::Unknown,
    }
}

/// Write each case's scenario file, so that it can be rerun through the processes.
pub(super) fn write_scenarios(cases: &[Case]) -> Result<(), StudyError> {
    for c in cases {
        let path = &c.scenario.source;
        std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")))
            .and_then(|_| crate::files::write(path, &c.text))
            .map_err(WriteError::file(path))?;
    }
    Ok(())
}

/// `[controller]` of kind `kind` with its table `body`.
pub(super) fn controller(kind: &str, body: toml::Table) -> toml::Table {
    let mut c = toml::Table::new();
    c.insert("kind".into(), kind.into());
    c.insert("stale_after_periods".into(), toml::Value::Integer(3));
    c.insert(kind.into(), body.into());
    c
}

/// `[controller]` of the P-D servo with these gains.
pub(super) fn pd_servo(kp: &[f64], kd: &[f64]) -> toml::Table {
    let mut t = toml::Table::new();
    t.insert("kp".into(), float_list(kp));
    t.insert("kd".into(), float_list(kd));
    controller("pd_servo", t)
}

impl Gains {
    /// Computed torque's table: its gains and psi rate (both computed-torque laws take them).
    pub(super) fn ct_table(&self) -> toml::Table {
        let mut t = toml::Table::new();
        t.insert("kp".into(), float_list(&self.ct[0]));
        t.insert("kv".into(), float_list(&self.ct[1]));
        t.insert("startup_rate".into(), toml::Value::Float(self.startup_rate));
        t
    }

    /// `[controller]` of fuzzy computed torque on `models` with `selection` and further `keys`
    /// of its table (`gamma`, `evidence_prior`).
    pub(super) fn fuzzy(
        &self,
        models: &[&PathBuf],
        selection: &str,
        keys: &[(&str, toml::Value)],
    ) -> toml::Table {
        let mut t = self.ct_table();
        let list = models
            .iter()
            .map(|f| f.display().to_string().into())
            .collect();
        t.insert("models".into(), toml::Value::Array(list));
        t.insert("selection".into(), selection.into());
        for (k, v) in keys {
            t.insert(k.to_string(), v.clone());
        }
        controller("fuzzy_computed_torque", t)
    }
}

/// The built-in scenarios' gains: the servo's [kp, kd] and computed torque's [kp, kv, rate].
pub(super) struct Gains {
    pub(super) servo: [Vec<f64>; 2],
    pub(super) ct: [Vec<f64>; 2],
    pub(super) startup_rate: f64,
}

pub(super) fn gains() -> Result<Gains, StudyError> {
    let built_in = |e: toml::de::Error| StudyError::BuiltIn(e.to_string());
    let train: toml::Table = TRAIN1.parse().map_err(built_in)?;
    let new: toml::Table = NEW.parse().map_err(built_in)?;
    let get = |t: &toml::Table, law: &str, key: &str| -> Result<toml::Value, StudyError> {
        t.get("controller")
            .and_then(|c| c.get(law))
            .and_then(|l| l.get(key))
            .cloned()
            .ok_or_else(|| StudyError::BuiltIn(format!("no controller.{law}.{key}")))
    };
    let fct = "fuzzy_computed_torque";
    Ok(Gains {
        servo: [
            floats(&get(&train, "pd_servo", "kp")?)?,
            floats(&get(&train, "pd_servo", "kd")?)?,
        ],
        ct: [
            floats(&get(&new, fct, "kp")?)?,
            floats(&get(&new, fct, "kv")?)?,
        ],
        startup_rate: get(&new, fct, "startup_rate")?
            .as_float()
            .ok_or_else(|| StudyError::BuiltIn("startup_rate is not a number".into()))?,
    })
}

/// The positions of the trajectories every 10 ms.
pub(super) fn trajectory_positions(cases: &[&Scenario]) -> Vec<Vec<f64>> {
    (cases.iter())
        .flat_map(|scn| reference_states(scn).into_iter().map(|(q, _)| q))
        .collect()
}

/// A scenario's reference (q, qd) every 10 ms over its duration.
pub(super) fn reference_states(scn: &Scenario) -> Vec<(Vec<f64>, Vec<f64>)> {
    let mut sp = crate::reference::Setpoint::default();
    let steps = (scn.timing.duration / 0.01).round() as usize;
    (0..=steps)
        .map(|k| {
            scn.reference.sample(k as f64 * 0.01, &mut sp);
            (sp.q[..sp.n].to_vec(), sp.qd[..sp.n].to_vec())
        })
        .collect()
}

/// Per joint, the middle of M_jj(q)'s range over `qs`: the simulated vendor tunes its servo to
/// it (the study's plant side; the identification never sees it).
pub(super) fn diagonal_mid(arm: &Model, qs: &[Vec<f64>]) -> Vec<f64> {
    let mut data = arm.data();
    let mut range = vec![[f64::INFINITY, f64::NEG_INFINITY]; arm.dof()];
    for q in qs {
        let m = arm.mass_matrix(&mut data, q);
        for (j, r) in range.iter_mut().enumerate() {
            *r = [r[0].min(m[(j, j)]), r[1].max(m[(j, j)])];
        }
    }
    range.iter().map(|[lo, hi]| 0.5 * (lo + hi)).collect()
}

/// A study's arm (its absolute path and model), and the output directory created.
pub(super) fn arm_of(robot: &Path, dir: &Path) -> Result<(PathBuf, Model), StudyError> {
    let robot = std::path::absolute(robot).map_err(WriteError::file(robot))?;
    let arm = crate::dynamics::load(&robot)?;
    std::fs::create_dir_all(dir).map_err(WriteError::file(dir))?;
    Ok((robot, arm))
}

/// The study's arm as `arm_of`, refused unless it has `JOINTS` joints.
pub(super) fn three_joint_arm(robot: &Path, dir: &Path) -> Result<(PathBuf, Model), StudyError> {
    let (robot, arm) = arm_of(robot, dir)?;
    if arm.dof() != JOINTS {
        return Err(StudyError::Arm(format!(
            "{}: the study's trajectories are for {JOINTS}-joint arms, this one has {} \
             (`evoloop rkgnn selection --robot FILE` builds trajectories for any arm)",
            robot.display(),
            arm.dof()
        )));
    }
    Ok((robot, arm))
}

/// Simulate the cases on the pool of `threads` workers (each takes the next case when it is
/// free), the results in the cases' order; `done` after each.
pub(super) fn simulate_all(
    cases: &[Case],
    threads: usize,
    done: &(dyn Fn() + Sync),
) -> Result<Vec<SimResult>, StudyError> {
    let one = |c: &Case| {
        // A case identifying alongside operation runs the optimiser's identification too.
        let r = match c.scenario.optimiser.mode {
            crate::config::OptimiserMode::Identify => {
                crate::rkgnn::live::simulate(&c.scenario).map(|(r, _)| r)
            }
            _ => Ok(simulate(&c.scenario)),
        };
        done();
        r.map_err(|source| StudyError::Run {
            case: c.name.clone(),
            source,
        })
    };
    // Work-stealing rather than one fixed share per thread: a case identifying alongside
    // operation costs several times a frozen one, and a fixed share left a core idle.
    use rayon::prelude::*;
    crate::optim::in_pool(threads, || cases.par_iter().map(one).collect())
}

/// What the study reads off a simulated case per joint (a trait: the traces are the simulation's
/// type, crate `evoloop-scenario`).
pub(super) trait StudyTraces {
    fn rms(&self) -> Vec<f64>;
    fn error(&self, j: usize) -> Vec<f64>;
    fn write_csv(&self, sim: &SimResult, path: &Path) -> Result<(), StudyError>;
}

impl StudyTraces for JointTraces {
    fn rms(&self) -> Vec<f64> {
        let (r, y) = self.columns();
        tracking(&r, &y, 0).rms
    }

    fn error(&self, j: usize) -> Vec<f64> {
        self.r[j]
            .iter()
            .zip(&self.y[j])
            .map(|(r, y)| r - y)
            .collect()
    }

    /// run CSV: t, r*, y*, u*, then the law's own columns.
    fn write_csv(&self, sim: &SimResult, path: &Path) -> Result<(), StudyError> {
        let mut header = vec!["t".to_string()];
        for p in ["r", "y", "u"] {
            header.extend((0..JOINTS).map(|j| format!("{p}{j}")));
        }
        header.extend(sim.law_columns.iter().cloned());
        let mut log = RunLog::new(header, self.t.len());
        let mut row = Vec::with_capacity(log.width());
        for (i, t) in self.t.iter().enumerate() {
            row.clear();
            row.push(*t);
            for c in [&self.r, &self.y, &self.u] {
                row.extend(c.iter().map(|v| v[i]));
            }
            row.extend_from_slice(sim.law_values(i));
            log.push(&row);
        }
        Ok(log.write_csv(path).map_err(WriteError::file(path))?)
    }
}

/// Run the study into `dir`; `progress(done, total, stage)` after each stage.
pub fn run(
    s: &StudySettings,
    dir: &Path,
    progress: &(dyn Fn(u64, u64, &str) + Sync),
) -> Result<StudyResult, StudyError> {
    let t0 = std::time::Instant::now();
    let (robot, arm) = three_joint_arm(&s.robot, dir)?;
    let g = gains()?;
    let total = 12u64;
    let step = std::sync::atomic::AtomicU64::new(0);
    let tick = |stage: &str| {
        let k = step.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(k, total, stage);
    };

    // Every run of the study: its robot, seed and joint velocity, written under `dir`.
    let at = |name: &str, base: &str, law: toml::Table| {
        case(name, base, &robot, s.seed, law, s.velocity, dir)
    };
    // The servo on this arm: arm3's gains times the inertia ratio over the trajectories.
    let probe = |base: &'static str| at("probe", base, pd_servo(&g.servo[0], &g.servo[1]));
    let probes = [probe(TRAIN1)?, probe(TRAIN2)?, probe(NEW)?];
    let qs = trajectory_positions(&probes.iter().map(|c| &c.scenario).collect::<Vec<_>>());
    // Each probe's scenario was refused above (`case`) if its reference leaves a joint limit.
    let arm3 =
        crate::dynamics::dh::parse_with(ARM3, Path::new("arm3.toml"), &Default::default())?.model;
    let ratio: Vec<f64> = diagonal_mid(&arm, &qs)
        .iter()
        .zip(diagonal_mid(&arm3, &qs))
        .map(|(a, b)| a / b)
        .collect();
    // What the identification may know of the arm: eq. 2's m1, m2 over its joint limits, as a
    // CAD model gives them (`evoloop rkgnn prior`). Nothing else of the robot reaches it.
    let workspace = identify::limit_positions(&arm, identify::LIMIT_SAMPLES);
    let prior = Prior::of_model(&arm, workspace.iter().map(Vec::as_slice));
    let scale = |v: &[f64]| v.iter().zip(&ratio).map(|(g, r)| g * r).collect::<Vec<_>>();
    let (servo_kp, servo_kd) = (scale(&g.servo[0]), scale(&g.servo[1]));
    let pd = pd_servo(&servo_kp, &servo_kd);

    // Training runs and identification.
    let training = [
        at("train1", TRAIN1, pd.clone())?,
        at("train2", TRAIN2, pd.clone())?,
    ];
    write_scenarios(&training)?;
    let train_sims = simulate_all(&training, s.threads, &|| tick("training run"))?;
    // Where the controller will run the models: the new trajectory's positions.
    let new = &probes[2].scenario;
    let along =
        crate::law::fuzzy_computed_torque::reference_positions(&new.reference, new.timing.duration);
    let servo = [servo_kp.as_slice(), servo_kd.as_slice()];
    let (models, summaries, inputs) = identify_each(
        s,
        &training,
        &train_sims,
        (&robot, &arm, &prior),
        servo,
        &along,
        dir,
        &tick,
    )?;

    // The controllers on the new trajectory, and each model on its own trajectory.
    // Both computed-torque laws take the same gains and psi rate.
    let fuzzy = |files: &[&PathBuf], selection: &str| g.fuzzy(files, selection, &[]);
    let ct_true = controller("computed_torque", g.ct_table());
    let (m1, m2) = (&models[0], &models[1]);
    let cases = [
        at("pd", NEW, pd)?,
        at("ct_true", NEW, ct_true)?,
        at("ct_model_1", NEW, fuzzy(&[m1], "max"))?,
        at("ct_model_2", NEW, fuzzy(&[m2], "max"))?,
        at("ct_fuzzy_max", NEW, fuzzy(&[m1, m2], "max"))?,
        at("ct_fuzzy_blend", NEW, fuzzy(&[m1, m2], "blend"))?,
        at("fig8_model_1_on_train1", TRAIN1, fuzzy(&[m1], "max"))?,
        at("fig9_model_2_on_train2", TRAIN2, fuzzy(&[m2], "max"))?,
    ];
    write_scenarios(&cases)?;
    let sims = simulate_all(&cases, s.threads, &|| tick("tracking run"))?;
    let traces = traces_written(&cases, &sims, dir)?;
    let rms: Vec<Vec<f64>> = traces.iter().map(JointTraces::rms).collect();
    let tracking_rms = TrackingRms {
        pd: rms[0].clone(),
        ct_true: rms[1].clone(),
        ct_model_1: rms[2].clone(),
        ct_model_2: rms[3].clone(),
        ct_fuzzy_max: rms[4].clone(),
        ct_fuzzy_blend: rms[5].clone(),
    };
    let fuzzy_sim = &sims[4];
    let (fuzzy_share, membership_range) = fuzzy_usage(fuzzy_sim)?;
    let result = StudyResult {
        robot: robot.clone(),
        seed: s.seed,
        evaluations: s.evaluations,
        servo_kp,
        servo_kd,
        inertia_ratio: ratio,
        ct_kp: g.ct[0].clone(),
        ct_kv: g.ct[1].clone(),
        identification_inputs: inputs,
        models: summaries,
        tracking_rms,
        own_trajectory_rms: [rms[6].clone(), rms[7].clone()],
        fuzzy_share,
        membership_range,
        seconds: t0.elapsed().as_secs_f64(),
    };
    write_outputs(&result, dir, &cases, &traces, fuzzy_sim)?;
    Ok(result)
}

/// Identify a model from each training run: the models' files, their summaries, and what the
/// identification was given.
#[allow(clippy::too_many_arguments)]
fn identify_each(
    s: &StudySettings,
    training: &[Case],
    train_sims: &[SimResult],
    (robot, arm, prior): (&Path, &crate::dynamics::Model, &Prior),
    servo: [&[f64]; 2],
    along: &[Vec<f64>],
    dir: &Path,
    tick: &(dyn Fn(&str) + Sync),
) -> Result<(Vec<PathBuf>, Vec<ModelSummary>, IdentificationInputs), StudyError> {
    let mut models = Vec::new();
    let mut summaries = Vec::new();
    let mut inputs = None;
    for (k, (c, sim)) in training.iter().zip(train_sims).enumerate() {
        let data = Trajectory::from_sim(
            &sim.rows,
            &c.scenario.reference,
            c.scenario.timing.period,
            s.smoothing,
        );
        let mut settings = Settings::least_squares(JOINTS, s.seed, s.evaluations);
        settings.threads = s.threads.max(1);
        settings.refine = s.refine;
        settings.start = s.start;
        settings.servo = servo_prior(s.servo_known, servo, (s.velocity, c), arm);
        let model = identify::identify_model(
            &data,
            prior,
            &settings,
            format!("rkgnn study: {} on {}", c.name, robot.display()),
            |_, _| {},
        )?;
        let file = dir.join(format!("model_{}.json", k + 1));
        model.save(&file)?;
        let on_reference = model.min_eig(along.iter().map(Vec::as_slice));
        summaries.push(ModelSummary::of(
            file.clone(),
            &c.name,
            &model.report,
            on_reference,
        ));
        inputs.get_or_insert_with(|| IdentificationInputs {
            runs: training.iter().map(|c| c.name.clone()).collect(),
            signals: "the reference (q_d, q_d') and the measured joint positions q (with the \
                      run's encoder noise) at every sample; q' estimated from q (a local \
                      quadratic fit over +-smoothing s), never the simulator's velocities",
            m1: prior.m1,
            m2: prior.m2,
            servo: settings.servo.clone(),
            start: settings.start,
            stride: settings.stride,
            smoothing: s.smoothing,
            evaluations: settings.evaluations,
            refine: settings.refine,
        });
        models.push(file);
        tick("identification");
    }
    Ok((
        models,
        summaries,
        inputs.ok_or(StudyError::Data("no training run"))?,
    ))
}

/// Each case's traces per joint, written as runs/NAME.csv.
fn traces_written(
    cases: &[Case],
    sims: &[SimResult],
    dir: &Path,
) -> Result<Vec<JointTraces>, StudyError> {
    let traces: Vec<JointTraces> = cases
        .iter()
        .zip(sims)
        .map(|(c, sim)| JointTraces::of(sim, &c.scenario.reference, JOINTS))
        .collect();
    let runs = dir.join("runs");
    std::fs::create_dir_all(&runs).map_err(WriteError::file(&runs))?;
    for ((c, sim), tr) in cases.iter().zip(sims).zip(&traces) {
        tr.write_csv(sim, &runs.join(format!("{}.csv", c.name)))?;
    }
    Ok(traces)
}

/// How long fuzzy selection kept each of the two models active, and the range of model 0's
/// membership, from the fuzzy run's law columns.
fn fuzzy_usage(sim: &SimResult) -> Result<(Vec<f64>, [f64; 2]), StudyError> {
    let active = sim
        .law_column("fuzzy_model")
        .ok_or(StudyError::Data("fuzzy run logged no active model"))?;
    let membership_range = sim
        .law_column("fuzzy_w0")
        .ok_or(StudyError::Data("fuzzy run logged no memberships"))?
        .iter()
        .fold([f64::INFINITY, f64::NEG_INFINITY], |[lo, hi], w| {
            [lo.min(*w), hi.max(*w)]
        });
    let share = (0..2)
        .map(|i| {
            active.iter().filter(|&&a| a == i as f64).count() as f64 / active.len().max(1) as f64
        })
        .collect();
    Ok((share, membership_range))
}

fn overall(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// study.json, tracking_rms.csv, report.md and the figures.
fn write_outputs(
    r: &StudyResult,
    dir: &Path,
    cases: &[Case],
    traces: &[JointTraces],
    fuzzy: &SimResult,
) -> Result<(), StudyError> {
    crate::report::write_json(dir, "study.json", r)
        .map_err(WriteError::file(&dir.join("study.json")))?;
    let mut csv = Csv::new(["controller", "joint1", "joint2", "joint3", "overall"]);
    for (key, _, v) in r.tracking_rms.entries() {
        csv.row().put(key).all(&v[..3]).put(overall(v));
    }
    let p = dir.join("tracking_rms.csv");
    csv.write(&p).map_err(WriteError::file(&p))?;
    let p = dir.join("report.md");
    crate::files::write(&p, report_markdown(r)).map_err(WriteError::file(&p))?;
    Ok(figures(dir, cases, traces, fuzzy)?)
}

/// The report's sentences, each from this run's numbers.
pub fn report_markdown(r: &StudyResult) -> String {
    let t = &r.tracking_rms;
    let mut s = format!(
        "# RKGNN study: computed torque with fuzzy model selection\n\n\
         Robot `{}`, seed {}, {} EA evaluations after the {} start \
         (0 = the start itself). P-D servo k_p {:?}, k_d {:?} (arm3's times the inertia ratio \
         {:?}); computed torque K_p {:?}, K_v {:?}.\n\n\
         ## Identified models (free-run prediction, rad rms per joint)\n\n\
         | model | trajectory | train | holdout | min eig M-hat (own positions) | min eig M-hat (new trajectory) |\n|---|---|---|---|---|---|\n",
        r.robot.display(),
        r.seed,
        r.evaluations,
        r.identification_inputs.start.name(),
        r.servo_kp.iter().map(|v| round(*v)).collect::<Vec<_>>(),
        r.servo_kd.iter().map(|v| round(*v)).collect::<Vec<_>>(),
        r.inertia_ratio
            .iter()
            .map(|v| round(*v))
            .collect::<Vec<_>>(),
        r.ct_kp,
        r.ct_kv,
    );
    for (i, m) in r.models.iter().enumerate() {
        s += &format!(
            "| {} | {} | {} | {} | {:.4} | {:.4} |\n",
            i + 1,
            m.trajectory,
            sci(&m.train_rms),
            sci(&m.holdout_rms),
            m.min_eig_m_hat,
            m.min_eig_on_reference
        );
    }
    s += "\n## Tracking the new trajectory (rad rms)\n\n\
          | controller | joint 1 | joint 2 | joint 3 | overall |\n|---|---|---|---|---|\n";
    for (_, label, v) in t.entries() {
        s += &format!(
            "| {label} | {:.4} | {:.4} | {:.4} | {:.4} |\n",
            v[0],
            v[1],
            v[2],
            overall(v)
        );
    }
    let (fz, pd) = (overall(&t.ct_fuzzy_max), overall(&t.pd));
    let worse = overall(&t.ct_model_1).max(overall(&t.ct_model_2));
    let cmp = |a: f64, b: f64| if a < b { "below" } else { "not below" };
    s += &format!(
        "\nOn this run fuzzy CT (max) tracks at {fz:.4} rad rms: {:.2} times the P-D servo's \
         {pd:.4} ({} it) and {:.2} times the worse single model's {worse:.4} ({} it); CT on the \
         true model reaches {:.4}. Model 1 had the largest weight on {:.0} % of the samples, \
         model 2 on {:.0} %; model 1's normalised membership ranged over [{:.3}, {:.3}]{}. One seed: `cargo test --release --test rkgnn` checks the ordering on \
         the shipped arm over seeds 1-5.\n\n\
         Figs. 8 and 9 (each model on its own trajectory): {} and {} rad rms overall.\n",
        fz / pd,
        cmp(fz, pd),
        fz / worse,
        cmp(fz, worse),
        overall(&t.ct_true),
        100.0 * r.fuzzy_share[0],
        100.0 * r.fuzzy_share[1],
        r.membership_range[0],
        r.membership_range[1],
        if r.membership_range[0] > 0.4 && r.membership_range[1] < 0.6 {
            " (within 0.1 of 0.5 throughout: the new trajectory is about as far from either \
             training one, and the max rule switches between near-equal models)"
        } else {
            ""
        },
        round4(overall(&r.own_trajectory_rms[0])),
        round4(overall(&r.own_trajectory_rms[1])),
    );
    s
}

fn round(v: f64) -> f64 {
    (v * 1000.0).round() / 1000.0
}

fn round4(v: f64) -> String {
    format!("{v:.4}")
}

fn sci(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.2e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Figs. 7-10 and the six controllers' error norms on the new trajectory.
fn figures(
    dir: &Path,
    cases: &[Case],
    traces: &[JointTraces],
    fuzzy: &SimResult,
) -> Result<(), PlotError> {
    // Fig. 7: the trajectories (training 1 and 2 from Figs. 8, 9's runs, the new one from pd).
    let (tr1, tr2, new) = (&traces[6], &traces[7], &traces[0]);
    let series = per_joint(&[
        ("training 1", &tr1.r),
        ("training 2", &tr2.r),
        ("new", &new.r),
    ]);
    stacked_png(
        &dir.join("fig7_trajectories.png"),
        "Fig. 7: training trajectories 1, 2 and the new trajectory (theta_d)",
        &new.t,
        &joint_panels(&series),
        &[],
    )?;
    tracking_figure(
        &dir.join("fig8_model_1_on_train1.png"),
        "Fig. 8: computed torque with model 1 on training trajectory 1",
        &traces[6],
        None,
    )?;
    tracking_figure(
        &dir.join("fig9_model_2_on_train2.png"),
        "Fig. 9: computed torque with model 2 on training trajectory 2",
        &traces[7],
        None,
    )?;
    tracking_figure(
        &dir.join("fig10_fuzzy_on_new.png"),
        "Fig. 10: computed torque with fuzzy model selection (max) on the new trajectory",
        &traces[4],
        Some(fuzzy),
    )?;
    // Error norm |e|(t) of the six controllers on the new trajectory.
    let norms: Vec<Vec<f64>> = traces[..6]
        .iter()
        .map(|tr| {
            let e: Vec<Vec<f64>> = (0..JOINTS).map(|j| tr.error(j)).collect();
            (0..tr.t.len())
                .map(|i| e.iter().map(|ej| ej[i] * ej[i]).sum::<f64>().sqrt())
                .collect()
        })
        .collect();
    let series: Vec<Series> = cases[..6]
        .iter()
        .zip(&norms)
        .map(|(c, v)| Series {
            name: &c.name,
            values: v,
        })
        .collect();
    stacked_png(
        &dir.join("tracking_new.png"),
        "Tracking error |e| on the new trajectory",
        &new.t,
        &[
            Panel {
                series: &series[..3],
                label: "|e| [rad]",
            },
            Panel {
                series: &series[3..],
                label: "|e| [rad]",
            },
        ],
        &[],
    )
}

/// Per joint, one series per (name, columns per joint).
fn per_joint<'a>(columns: &[(&'a str, &'a Vec<Vec<f64>>)]) -> Vec<Vec<Series<'a>>> {
    (0..JOINTS)
        .map(|j| {
            columns
                .iter()
                .map(|(name, c)| Series {
                    name,
                    values: &c[j],
                })
                .collect()
        })
        .collect()
}

/// One panel per joint.
fn joint_panels<'a>(series: &'a [Vec<Series<'a>>]) -> Vec<Panel<'a>> {
    let names = ["joint 1 [rad]", "joint 2 [rad]", "joint 3 [rad]"];
    series
        .iter()
        .zip(names)
        .map(|(s, label)| Panel { series: s, label })
        .collect()
}

/// Reference and output per joint, the errors, and for a fuzzy run its memberships.
fn tracking_figure(
    path: &Path,
    title: &str,
    tr: &JointTraces,
    fuzzy: Option<&SimResult>,
) -> Result<(), PlotError> {
    let joints = per_joint(&[("theta_d", &tr.r), ("theta", &tr.y)]);
    let errors: Vec<Vec<f64>> = (0..JOINTS).map(|j| tr.error(j)).collect();
    let error_series: Vec<Series> = errors
        .iter()
        .zip(["e1", "e2", "e3"])
        .map(|(v, name)| Series { name, values: v })
        .collect();
    let mut panels = joint_panels(&joints);
    panels.push(Panel {
        series: &error_series,
        label: "error [rad]",
    });
    // The fuzzy_w<i> columns: model i + 1's normalised membership.
    let memberships: Vec<(String, Vec<f64>)> = fuzzy
        .map(|sim| {
            (0..)
                .map_while(|i| {
                    let w = sim.law_column(&format!("fuzzy_w{i}"))?;
                    Some((format!("membership, model {}", i + 1), w))
                })
                .collect()
        })
        .unwrap_or_default();
    let m_series: Vec<Series> = memberships
        .iter()
        .map(|(n, v)| Series { name: n, values: v })
        .collect();
    if !m_series.is_empty() {
        panels.push(Panel {
            series: &m_series,
            label: "normalised weight",
        });
    }
    stacked_png(path, title, &tr.t, &panels, &[])
}
