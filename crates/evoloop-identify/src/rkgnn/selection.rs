//! A selection study that can fail (`evoloop rkgnn selection`): is fuzzy selection among
//! identified models better than the best single model, on trajectories it was not built for?
//!
//! The study of `study.rs` is the paper's own case, where the new trajectory is the exact
//! midpoint of the two training ones (the memberships tie and the max rule dithers). Here three
//! training trajectories give three models (the shipped recipe: the training servo known, least
//! squares), and four new trajectories are tracked that are not midpoints: two between training
//! regions but nearer one, one partly beyond them, one at other frequencies (written for the
//! paper's 3-joint arm, built from the joint limits by the same pattern on any other arm,
//! `generated`). On each, per seed:
//! the training P-D servo, a P-D servo gain-matched to computed torque (k_p = M_jj,mid x 900,
//! k_d = M_jj,mid x 60 with the arm's mid-range inertia: the same bandwidth and damping), computed
//! torque on the true model, on each model alone, fuzzy selection (max, blend) and a uniform blend
//! (the blend with memberships flattened, gamma = 1e6). Computed from those: the best single model
//! in hindsight (per trajectory and seed) and a random single model (the mean of the three, what
//! choosing one blindly gives on average). The baselines a control engineer would use beside
//! them: the matched servo with gravity compensation from the nominal model (`pd_gravity`),
//! computed torque on the nominal model (`ct_nominal`), the nominal model being the arm's file
//! with its masses, centres of mass and inertias off by up to `NOMINAL_SPREAD` (a CAD model,
//! drawn per arm and seed and written to `seed<N>/nominal.urdf`), and one model updated online
//! from the applied torques (`online_model`: the seed's first usable model under identification
//! alongside operation, `rkgnn::live`). Seeds change the measurement noise of every run and
//! the training trajectories themselves (seed 1: as written; others: offsets and amplitudes
//! moved, `Sines::for_seed`), and the models are re-identified on each seed's training data.
//! The comparisons are paired Wilcoxon signed-rank tests over seeds (each seed's mean over the
//! four tasks: a seed's tasks share its models), overall and per task. Each model's M-hat, V-hat
//! and G-hat are judged against the arm along each task (`model_error`).

use super::identify::{self, Prior, Settings};
use super::study::StudyTraces;
use super::study::{
    arm_of, case, controller, diagonal_mid, float_list, gains, pd_servo, reference_states,
    servo_prior, simulate_all, table, trajectory_positions, write_scenarios, Case, JointVelocity,
    JOINTS,
};
use crate::dynamics::Model;
use crate::law::fuzzy_computed_torque::check_along_reference;
use crate::rkgnn::model_error::{model_error, ModelError, RigidBody};
use crate::rkgnn::{StudyError, Trajectory};
use crate::sim::{JointTraces, SimResult};
use crate::stats::{median, median_of_numbers, wilcoxon, Wilcoxon};
use evoloop_rkgnn::model::{ServoPrior, Weighing};
use evoloop_schemes::WriteError;
use serde::Serialize;
use std::path::{Path, PathBuf};

const BASE: &str = include_str!("../../../../config/arm3/arm3_train1.toml");

/// A sines reference: offsets per joint, amplitudes per joint per frequency, frequencies (Hz).
#[derive(Clone, Debug)]
struct Sines {
    name: &'static str,
    offsets: Vec<f64>,
    amplitudes: Vec<[f64; 2]>,
    frequencies: [f64; 2],
}

const SLOW: [f64; 2] = [0.2, 0.5];
const FAST: [f64; 2] = [0.3, 0.7];

/// The study's trajectories on a 3-joint arm, as written for the paper's arm: the paper's two
/// (the shipped `arm3_train1`, `arm3_train2`) and a third nearer the upright pose; then the new
/// ones, none a midpoint of training ones: near1 a third of the way from train1 to train2, near3
/// between train3 and train1 nearer train3, beyond2 partly beyond train2 (the shoulder higher, the
/// forearm further folded), faster1 train1's region at other frequencies.
fn written() -> (Vec<Sines>, Vec<Sines>) {
    let s = |name, offsets: [f64; 3], amplitudes: [[f64; 2]; 3], frequencies| Sines {
        name,
        offsets: offsets.to_vec(),
        amplitudes: amplitudes.to_vec(),
        frequencies,
    };
    let training = vec![
        s(
            "train1",
            [0.0, 0.5, -1.0],
            [[0.8, 0.2], [0.3, 0.1], [0.5, 0.15]],
            SLOW,
        ),
        s(
            "train2",
            [0.0, 0.9, -1.6],
            [[1.2, 0.3], [0.5, 0.15], [0.7, 0.2]],
            SLOW,
        ),
        s(
            "train3",
            [0.4, 0.2, -0.5],
            [[0.6, 0.15], [0.25, 0.1], [0.4, 0.1]],
            SLOW,
        ),
    ];
    let new = vec![
        s(
            "near1",
            [0.1, 0.63, -1.2],
            [[0.9, 0.2], [0.35, 0.1], [0.55, 0.2]],
            SLOW,
        ),
        s(
            "near3",
            [0.3, 0.3, -0.65],
            [[0.7, 0.2], [0.3, 0.12], [0.45, 0.12]],
            SLOW,
        ),
        s(
            "beyond2",
            [-0.2, 1.1, -1.9],
            [[1.0, 0.3], [0.4, 0.15], [0.5, 0.2]],
            SLOW,
        ),
        s(
            "faster1",
            [0.0, 0.6, -1.1],
            [[0.6, 0.2], [0.25, 0.1], [0.4, 0.15]],
            FAST,
        ),
    ];
    (training, new)
}

/// Where the study's trajectories come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrajectorySource {
    /// As written for the paper's 3-joint arm.
    Paper,
    /// Built from the arm's joint limits (`generated`).
    Limits,
}

/// The written trajectories on a 3-joint arm whose limits hold them;
/// trajectories built from the limits on any other arm, and on a 3-joint arm the written ones
/// would take past a limit (a generated arm's elbow may turn less than the paper's).
fn trajectories_for(arm: &Model) -> (Vec<Sines>, Vec<Sines>, TrajectorySource) {
    if arm.dof() == JOINTS {
        let (training, new) = written();
        if training.iter().chain(&new).all(|s| holds(arm, s)) {
            return (training, new, TrajectorySource::Paper);
        }
    }
    let (training, new) = generated(arm);
    (training, new, TrajectorySource::Limits)
}

/// Each joint's lowest and highest position along `s` (offset -+ both harmonics).
fn reach(s: &Sines) -> Vec<(f64, f64)> {
    s.offsets
        .iter()
        .zip(&s.amplitudes)
        .map(|(o, a)| (o - a[0] - a[1], o + a[0] + a[1]))
        .collect()
}

/// Whether `s` as written stays strictly within `arm`'s limits, its harmonics' peaks added (a
/// bound on its excursion). Without a seed's spread (`Sines::for_seed`), as the probe scenarios
/// check it: with the spread, arm3's own beyond2 would fail at its elbow by 5 mrad.
fn holds(arm: &Model, s: &Sines) -> bool {
    arm.bodies.iter().zip(reach(s)).all(|(b, (lo, hi))| {
        let (q_min, q_max) = b.limits.position_span();
        lo > q_min && hi < q_max
    })
}

/// The study's trajectories on an arm of any other joint count, built from its joint limits by
/// the written ones' pattern: about the middle c of each joint's range (half-range r, at most
/// pi; a joint without limits: -pi..pi), train1 at c - d and train2 at c + d (d = 0.15 r, at
/// most 0.5 rad) with train2 moving 1.4 times as far, train3 at c + d on even joints and c - d on
/// odd ones moving 0.75 times as far; every joint's first harmonic 0.2 r (at most 0.6 rad), its
/// second a quarter of that. The new ones are placed as the written ones are: near1 a third of
/// the way from train1 to train2, near3 a third of the way from train3 to train1, beyond2 half
/// train2's distance from train1 beyond train2 (with train2's amplitudes), faster1 train1's
/// offsets with 0.75 of its amplitudes at 0.3 and 0.7 Hz. The furthest any of them reaches from
/// c is 0.65 r (beyond2).
fn generated(arm: &Model) -> (Vec<Sines>, Vec<Sines>) {
    let (mut c, mut d, mut a) = (Vec::new(), Vec::new(), Vec::new());
    for b in &arm.bodies {
        let (lo, hi) = b.limits.position_span();
        let half = (0.5 * (hi - lo)).min(std::f64::consts::PI);
        c.push(0.5 * (lo + hi));
        d.push((0.15 * half).min(0.5));
        a.push((0.2 * half).min(0.6));
    }
    let sines = |name, side: &dyn Fn(usize) -> f64, scale: f64| Sines {
        name,
        offsets: (0..c.len()).map(|j| c[j] + side(j) * d[j]).collect(),
        amplitudes: a.iter().map(|a| [scale * a, 0.25 * scale * a]).collect(),
        frequencies: SLOW,
    };
    let t1 = sines("train1", &|_| -1.0, 1.0);
    let t2 = sines("train2", &|_| 1.0, 1.4);
    let t3 = sines("train3", &|j| if j % 2 == 0 { 1.0 } else { -1.0 }, 0.75);
    let beyond2 = Sines {
        amplitudes: t2.amplitudes.clone(),
        ..t1.towards(&t2, 1.5, "beyond2")
    };
    let faster1 = Sines {
        name: "faster1",
        amplitudes: t1
            .amplitudes
            .iter()
            .map(|[x, y]| [0.75 * x, 0.75 * y])
            .collect(),
        frequencies: FAST,
        ..t1.clone()
    };
    let new = vec![
        t1.towards(&t2, 1.0 / 3.0, "near1"),
        t3.towards(&t1, 1.0 / 3.0, "near3"),
        beyond2,
        faster1,
    ];
    (vec![t1, t2, t3], new)
}

/// The controllers run on each new trajectory, in the table's order.
pub const RUN: [&str; 14] = [
    "pd",
    "pd_matched",
    "ct_true",
    "ct_model_1",
    "ct_model_2",
    "ct_model_3",
    "fuzzy_max",
    "fuzzy_blend",
    "uniform_blend",
    "fuzzy_evidence",
    "uniform_evidence",
    "pd_gravity",
    "ct_nominal",
    "online_model",
];
/// The single identified models (the best and the random single are computed from them).
const SINGLES: [&str; 3] = ["ct_model_1", "ct_model_2", "ct_model_3"];
/// The rules compared with every other controller: the fuzzy rules, the uniform blend (all
/// models at equal weight), the rule that selects nothing, and the evidence rule (each model
/// weighted per joint by how well it predicts the applied torque) on the memberships and on a
/// uniform prior.
const RULES: [&str; 5] = [
    "fuzzy_max",
    "fuzzy_blend",
    "uniform_blend",
    "fuzzy_evidence",
    "uniform_evidence",
];
/// ... and those computed from the single models.
pub const DERIVED: [&str; 2] = ["best_single", "random_single"];

/// Computed torque's error dynamics (rad/s^2 per rad and per rad/s) the matched servo copies.
const MATCH: (f64, f64) = (900.0, 60.0);
/// The training servo's error dynamics on an arm other than the paper's (k_p and k_d per unit
/// of M_jj,mid): 20 rad/s, critically damped, slower than computed torque's 30 rad/s.
const VENDOR: (f64, f64) = (400.0, 40.0);
/// P-D gains [k_p; k_d] of the error dynamics `(kp, kd)` (per unit of inertia) on joints of
/// inertia `mid`.
fn per_inertia(mid: &[f64], (kp, kd): (f64, f64)) -> [Vec<f64>; 2] {
    [
        mid.iter().map(|m| m * kp).collect(),
        mid.iter().map(|m| m * kd).collect(),
    ]
}

/// gamma of the uniform blend: memberships within 1e-12 of 1 over any trajectory here.
const UNIFORM_GAMMA: f64 = 1e6;

/// What `evoloop rkgnn selection` is asked for.
#[derive(Debug, Clone)]
pub struct SelectionSettings {
    /// The arm's robot file.
    pub robot: PathBuf,
    /// Seeds to run: 1 to `seeds` (each with its own training data, models and CAD model).
    pub seeds: u64,
    /// When each joint's equations are put in units of its own torque rms
    /// (`identify::Settings::weighing`).
    pub weighing: Weighing,
    /// V-hat from M-hat's Christoffel symbols instead of the velocity network.
    pub christoffel: bool,
    /// Whether the identification knows the training servo's gains (the shipped recipe) or,
    /// as in the paper's premise, identifies them (a linear servo network, scale from eq. 2).
    pub servo_known: bool,
    /// Where the identification starts: least squares (the shipped recipe) or the paper's
    /// random start (give `evaluations`).
    pub start: evoloop_rkgnn::model::Start,
    /// The paper's EA evaluations after the start (0 = the start itself).
    pub evaluations: usize,
    /// The tracking runs' loop period, s (None: the training runs', 1 ms). The training runs
    /// stay at 1 kHz, a vendor servo's log; a 7-DOF arm's computed torque runs at 10 kHz.
    pub period: Option<f64>,
    /// Take each seed's models from an earlier study's output (`<dir>/seed<N>/model_<run>.json`,
    /// identified by the same recipe) instead of identifying them.
    pub models_from: Option<PathBuf>,
    /// The joint velocity the training servo and every tracking law act on.
    pub velocity: JointVelocity,
    /// Worker threads shared by the seeds' simulations and identifications.
    pub threads: usize,
}

/// One (seed, trajectory): each controller's RMS error per joint and overall.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    /// The seed: its training data, models, CAD model and measurement noise.
    pub seed: u64,
    /// The new trajectory tracked (near1, near3, beyond2 or faster1).
    pub trajectory: &'static str,
    /// Controller key -> per-joint RMS (rad), `RUN` then `DERIVED` order.
    pub rms: Vec<(String, Vec<f64>)>,
    /// The max rule's model switches per second.
    pub switches_per_s: f64,
    /// Share of samples on which each model was selected (max rule).
    pub share: Vec<f64>,
    /// M-hat's smallest eigenvalue along this trajectory, per model.
    pub min_eig_on_reference: Vec<f64>,
    /// Models the controller refused on this trajectory (not positive definite along it):
    /// left out alone (their rms is null) and from the fuzzy sets, as models not identified are.
    pub refused: usize,
    /// Each identified model's M-hat, V-hat and G-hat against the arm along this trajectory
    /// (null: not identified), and the nominal (CAD) model's.
    pub model_error: Vec<Option<ModelError>>,
    /// The nominal (CAD) model's M, V and G against the arm along this trajectory.
    pub nominal_error: ModelError,
    /// Models the online identification put in service during online_model's run (null: not
    /// run, no usable model to start from).
    pub online_updates: Option<usize>,
}

/// A paired comparison of a rule (`RULES`) with one baseline over the seeds: per seed the mean
/// over the tasks both ran of the overall RMS (seeds re-identify, so they are the independent
/// units; the tasks of a seed share its models). The Wilcoxon test is exact up to 30 seeds.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// One of `RULES`: `fuzzy_max` (the paper's rule), `fuzzy_blend`, `uniform_blend`,
    /// `fuzzy_evidence` or `uniform_evidence`.
    pub rule: String,
    /// The controller key the rule is compared with (from `RUN` or `DERIVED`).
    pub baseline: String,
    /// Median over the seeds of the rule's per-seed mean overall RMS, rad.
    pub median_fuzzy: f64,
    /// The same for the baseline, rad.
    pub median_baseline: f64,
    /// Seeds where the rule is lower.
    pub fuzzy_lower: usize,
    /// Seeds compared.
    pub pairs: usize,
    /// The paired signed-rank test of the rule's per-seed means against the baseline's.
    pub wilcoxon: Wilcoxon,
}

/// `selection.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SelectionResult {
    /// The arm's robot file, absolute.
    pub robot: PathBuf,
    /// The arm's joint count.
    pub joints: usize,
    /// Seeds run (1 to `seeds`).
    pub seeds: u64,
    /// The training trajectories' names.
    pub training: Vec<&'static str>,
    /// The new trajectories' names: the tasks tracked.
    pub trajectories: Vec<&'static str>,
    /// Where the trajectories come from: `paper` (the RKGNN paper's arm, written) or `limits`
    /// (built from this arm's joint limits).
    pub trajectory_source: TrajectorySource,
    /// Eq. 2's bounds given to the identification (over the joint limits).
    pub prior: Prior,
    /// How the models were identified: what of the servo was known, the start, the EA's
    /// evaluations, the joints' weighing, V-hat's form.
    pub servo_known: bool,
    /// Where each identification started.
    pub start: evoloop_rkgnn::model::Start,
    /// The EA's evaluations after the start (0 = the start itself).
    pub evaluations: usize,
    /// When each joint's equations were to be weighed by its torque rms (`never`, `as-needed`,
    /// `always`).
    pub weighing: Weighing,
    /// Training runs whose model needed them weighed (`as-needed`) or had them (`always`), as
    /// "seed N, name".
    pub weighed: Vec<String>,
    /// Whether V-hat came from M-hat's Christoffel symbols (no velocity network).
    pub christoffel: bool,
    /// The tracking runs' loop period, s (the training runs': 1 ms).
    pub period: f64,
    /// Training runs that gave no model (no positive definite M-hat), with the reason: left
    /// out alone and from the fuzzy sets.
    pub unidentified: Vec<String>,
    /// Each identified model's identification time, s (wall clock, every thread; for models
    /// taken from an earlier study, that study's).
    pub identification_seconds: Vec<f64>,
    /// The earlier study the models were taken from (`--models-from`), if any.
    pub models_from: Option<PathBuf>,
    /// The joint velocity the training servo and every tracking law acted on: `filtered` (a
    /// drive's, from the encoders) or `true` (the simulator's, an ideal sensor).
    pub joint_velocity: JointVelocity,
    /// How far each seed's nominal (CAD) model is off (factors within 1 +- this), and each
    /// seed's nominal model as written: pd_gravity and ct_nominal use it.
    pub nominal_spread: f64,
    /// Per seed, its nominal model's file and errors.
    pub nominal: Vec<NominalWritten>,
    /// online_model's identification settings (`optimiser` keys).
    pub online: Vec<(&'static str, f64)>,
    /// One per (seed, task), seed by seed.
    pub cells: Vec<Cell>,
    /// Per trajectory, the median overall RMS of each controller.
    pub medians: Medians,
    /// Each rule against each controller over the seeds (the claims' test).
    pub comparisons: Vec<Comparison>,
    /// The same per task (trajectory), over the seeds.
    pub tasks: Vec<TaskComparisons>,
    /// Whether fuzzy max (the paper's rule) is below the best single model in hindsight:
    /// median lower and Wilcoxon p < 0.05 with fuzzy lower.
    pub claim_held: bool,
    /// The same for the blend.
    pub claim_held_blend: bool,
    /// The same for the uniform blend (every model at equal weight: no selection at all).
    pub claim_held_uniform: bool,
    /// The same for the evidence rule, on the memberships and on a uniform prior.
    pub claim_held_evidence: bool,
    /// The same for the evidence rule on a uniform prior.
    pub claim_held_uniform_evidence: bool,
    /// The study's wall-clock time, s.
    pub seconds: f64,
}

fn overall(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

impl Sines {
    /// The trajectory `f` of the way from this one to `other` (offsets and amplitudes; beyond
    /// it for f > 1), at this one's frequencies.
    fn towards(&self, other: &Sines, f: f64, name: &'static str) -> Sines {
        let lerp = |x: f64, y: f64| x + f * (y - x);
        Sines {
            name,
            offsets: (self.offsets.iter().zip(&other.offsets))
                .map(|(x, y)| lerp(*x, *y))
                .collect(),
            amplitudes: (self.amplitudes.iter().zip(&other.amplitudes))
                .map(|(x, y)| [lerp(x[0], y[0]), lerp(x[1], y[1])])
                .collect(),
            frequencies: self.frequencies,
        }
    }

    /// The training trajectory of identification seed `seed`: seed 1 is the trajectory as
    /// written (the shipped models' data); each other seed moves every offset by up to
    /// +-OFFSET_SPREAD rad and scales every amplitude by 1 +- AMPLITUDE_SPREAD (uniform,
    /// seeded by seed and trajectory), so that each seed identifies its models from other data,
    /// not only other encoder noise.
    fn for_seed(&self, seed: u64, index: usize) -> Sines {
        use rand::{Rng, SeedableRng};
        let mut s = self.clone();
        if seed == 1 {
            return s;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 * seed + index as u64);
        for j in 0..s.offsets.len() {
            s.offsets[j] += rng.gen_range(-OFFSET_SPREAD..=OFFSET_SPREAD);
            for a in &mut s.amplitudes[j] {
                *a *= 1.0 + rng.gen_range(-AMPLITUDE_SPREAD..=AMPLITUDE_SPREAD);
            }
        }
        s
    }
}

/// How far an identification seed moves a training trajectory (`Sines::for_seed`): offsets,
/// rad, and amplitudes, relative.
const OFFSET_SPREAD: f64 = 0.1;
const AMPLITUDE_SPREAD: f64 = 0.15;

/// `t[section][key]`, a number, made at most `max`.
fn at_most(t: &mut toml::Table, section: &str, key: &str, max: f64) -> Result<(), StudyError> {
    let s = table(t, section)?;
    let v = s.get(key).and_then(toml::Value::as_float);
    let v = v.ok_or_else(|| StudyError::BuiltIn(format!("no {section}.{key}")))?;
    s.insert(key.into(), toml::Value::Float(v.min(max)));
    Ok(())
}

/// `base` with its reference replaced by `s`, run at `period` (None: the base's 1 ms): the
/// plant's RK4 step at most the period.
fn with_reference(s: &Sines, period: Option<f64>) -> Result<String, StudyError> {
    let mut t: toml::Table = BASE
        .parse()
        .map_err(|e: toml::de::Error| StudyError::BuiltIn(e.to_string()))?;
    if let Some(p) = period {
        table(&mut t, "timing")?.insert("period".into(), toml::Value::Float(p));
        at_most(&mut t, "plant", "step", p)?;
        // The (idle) optimiser's sync period stays within its 256 periods.
        let sync = crate::ipc::MAX_SYNC_SAMPLES as f64 * p;
        at_most(&mut t, "optimiser", "sync_period", sync)?;
    }
    let mut r = toml::Table::new();
    r.insert("kind".into(), "sines".into());
    r.insert("frequencies".into(), float_list(&s.frequencies));
    r.insert("offsets".into(), float_list(&s.offsets));
    let amps = s.amplitudes.iter().map(|a| float_list(a)).collect();
    r.insert("amplitudes".into(), toml::Value::Array(amps));
    t.insert("reference".into(), r.into());
    toml::to_string(&t).map_err(|e| StudyError::BuiltIn(e.to_string()))
}

/// Run the study into `dir`; `progress(done, total, stage)`.
pub fn run(
    s: &SelectionSettings,
    dir: &Path,
    progress: &(dyn Fn(u64, u64, &str) + Sync),
) -> Result<SelectionResult, StudyError> {
    let t0 = std::time::Instant::now();
    if s.seeds == 0 {
        return Err(StudyError::Setting("--seeds must be >= 1".into()));
    }
    let (robot, arm) = arm_of(&s.robot, dir)?;
    // Every file the scenarios name (models, the nominal model) absolute: a scenario resolves a
    // relative path against its own directory, not the working directory.
    let dir = &std::path::absolute(dir).map_err(WriteError::file(dir))?;
    let n = arm.dof();
    // The nominal model must be writable before any run is made (URDF has no armature).
    crate::dynamics::urdf::writable(&arm).map_err(|e| {
        StudyError::Arm(format!(
            "{}: its nominal model cannot be written as URDF: {e}",
            robot.display()
        ))
    })?;
    let (training_set, new_set, trajectory_source) = trajectories_for(&arm);
    let mut g = gains()?;
    // Computed torque's gains are accelerations per error: the same on every arm.
    g.ct = [vec![MATCH.0; n], vec![MATCH.1; n]];
    let texts: Vec<String> = training_set
        .iter()
        .map(|t| with_reference(t, None))
        .chain(new_set.iter().map(|t| with_reference(t, s.period)))
        .collect::<Result<_, _>>()?;
    let probe = probes(&texts, &robot, n, s.velocity, dir)?;
    let qs = trajectory_positions(&probe.iter().map(|c| &c.scenario).collect::<Vec<_>>());
    // Computed torque's start-up rate is per sample: the same 33 ms at any period.
    let base_period = probe[0].scenario.timing.period;
    let period = s.period.unwrap_or(base_period);
    g.startup_rate *= period / base_period;
    let mid = diagonal_mid(&arm, &qs);
    let matched = per_inertia(&mid, MATCH);
    let workspace = identify::limit_positions(&arm, identify::LIMIT_SAMPLES);
    let prior = Prior::of_model(&arm, workspace.iter().map(Vec::as_slice));
    // The training servo: the written one on the paper's 3-joint arm; on another arm a vendor's
    // servo tuned as the matched one is but slower (VENDOR: 20 rad/s, critically damped).
    if n != JOINTS {
        g.servo = per_inertia(&mid, VENDOR);
    }
    let (servo_kp, servo_kd) = (&g.servo[0], &g.servo[1]);
    let total = s.seeds * (2 * training_set.len() + new_set.len() * RUN.len()) as u64;
    let step = std::sync::atomic::AtomicU64::new(0);
    let tick = |stage: &str| {
        let k = step.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(k, total, stage);
    };
    let training = Training {
        s,
        set: &training_set,
        robot: &robot,
        arm: &arm,
        prior: &prior,
        servo: [servo_kp, servo_kd],
    };
    let first_new = training_set.len();
    let one_seed = |seed: u64| -> Result<SeedOut, StudyError> {
        let sd = dir.join(format!("seed{seed}"));
        std::fs::create_dir_all(&sd).map_err(WriteError::file(&sd))?;
        let found = training.models(seed, &sd, &tick)?;
        let models = found.models;
        // This seed's CAD model: the arm with its mass properties off (`nominal`), written
        // down beside the models; the gravity compensation and ct_nominal use it.
        let nominal = nominal_model(&arm, seed, &sd)?;
        // pd_gravity is tuned as the matched servo is, on the CAD model (what its user has).
        let cad_matched = per_inertia(&diagonal_mid(&nominal.model, &qs), MATCH);
        let seed_run = SeedRun {
            s,
            g: &g,
            robot: &robot,
            arm: &arm,
            dir: &sd,
            seed,
            models: &models,
            servo: [servo_kp, servo_kd],
            matched: [&matched[0], &matched[1]],
            cad_matched: [&cad_matched[0], &cad_matched[1]],
            nominal: &nominal,
        };
        let cells = new_set
            .iter()
            .zip(&texts[first_new..])
            .enumerate()
            .map(|(i, (tr, text))| {
                seed_run.track(tr.name, text, &probe[first_new + i].scenario, &tick)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SeedOut {
            cells,
            unidentified: found.unidentified,
            weighed: found.weighed,
            seconds: found.seconds,
            nominal: nominal.written,
        })
    };
    // Seeds are independent (each identifies its own models into its own folder), so they run
    // side by side on the `threads` workers, sharing them with each seed's simulations; the
    // results are taken in seed order, so the study's files do not depend on the thread count.
    let per_seed: Vec<SeedOut> = crate::optim::in_pool(s.threads, || {
        use rayon::prelude::*;
        (1..=s.seeds)
            .into_par_iter()
            .map(one_seed)
            .collect::<Result<_, _>>()
    })?;
    let names = |v: &[Sines]| v.iter().map(|t| t.name).collect::<Vec<_>>();
    let frame = Frame {
        robot,
        joints: n,
        training: names(&training_set),
        trajectories: names(&new_set),
        trajectory_source,
        prior,
        period,
    };
    let result = assemble(s, frame, per_seed, t0.elapsed().as_secs_f64());
    crate::report::write_json(dir, "selection.json", &result)
        .map_err(WriteError::file(&dir.join("selection.json")))?;
    let p = dir.join("report.md");
    crate::files::write(&p, report_markdown(&result)).map_err(WriteError::file(&p))?;
    Ok(result)
}

/// What the study ran on, the same for every seed.
struct Frame {
    robot: PathBuf,
    joints: usize,
    training: Vec<&'static str>,
    trajectories: Vec<&'static str>,
    trajectory_source: TrajectorySource,
    prior: Prior,
    period: f64,
}

/// The study's result from its seeds' outputs (taken in seed order): the cells, their medians
/// and comparisons, and each claim's verdict.
fn assemble(
    s: &SelectionSettings,
    frame: Frame,
    per_seed: Vec<SeedOut>,
    seconds: f64,
) -> SelectionResult {
    let (mut cells, mut unidentified, mut weighed, mut identification_seconds, mut nominals) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for o in per_seed {
        cells.extend(o.cells);
        unidentified.extend(o.unidentified);
        weighed.extend(o.weighed);
        identification_seconds.extend(o.seconds);
        nominals.push(o.nominal);
    }
    let (medians, comparisons, tasks) = summarise(&cells, &frame.trajectories);
    SelectionResult {
        robot: frame.robot,
        joints: frame.joints,
        seeds: s.seeds,
        training: frame.training,
        trajectories: frame.trajectories,
        trajectory_source: frame.trajectory_source,
        prior: frame.prior,
        servo_known: s.servo_known,
        start: s.start,
        evaluations: s.evaluations,
        weighing: s.weighing,
        weighed,
        christoffel: s.christoffel,
        period: frame.period,
        unidentified,
        identification_seconds,
        models_from: s.models_from.clone(),
        joint_velocity: s.velocity,
        nominal_spread: NOMINAL_SPREAD,
        nominal: nominals,
        online: ONLINE.to_vec(),
        cells,
        medians,
        tasks,
        claim_held: claim_held(&comparisons, "fuzzy_max"),
        claim_held_blend: claim_held(&comparisons, "fuzzy_blend"),
        claim_held_uniform: claim_held(&comparisons, "uniform_blend"),
        claim_held_evidence: claim_held(&comparisons, "fuzzy_evidence"),
        claim_held_uniform_evidence: claim_held(&comparisons, "uniform_evidence"),
        comparisons,
        seconds,
    }
}

/// Every trajectory as a scenario that is never run, to check it: `case` parses each, and the
/// scenario's check refuses a reference that leaves a joint limit (plant::arm). Their servo (unit
/// gains) only makes them whole scenarios.
fn probes(
    texts: &[String],
    robot: &Path,
    n: usize,
    velocity: JointVelocity,
    dir: &Path,
) -> Result<Vec<Case>, StudyError> {
    let unit = vec![1.0; n];
    texts
        .iter()
        .enumerate()
        .map(|(k, t)| {
            case(
                &format!("probe{k}"),
                t,
                robot,
                1,
                pd_servo(&unit, &unit),
                velocity,
                dir,
            )
        })
        .collect()
}

/// What every seed's training runs and identification share.
struct Training<'a> {
    s: &'a SelectionSettings,
    set: &'a [Sines],
    robot: &'a Path,
    arm: &'a Model,
    prior: &'a Prior,
    servo: [&'a [f64]; 2],
}

/// The models one seed's training runs yield (None where identification found none), why not,
/// and how long each identification took.
struct SeedModels {
    models: Vec<Option<(PathBuf, evoloop_rkgnn::RkgnnModel)>>,
    unidentified: Vec<String>,
    weighed: Vec<String>,
    seconds: Vec<f64>,
}

/// One seed's share of the study: its cells (one per task), the models it could not identify,
/// how long each identification took and its CAD model as written.
struct SeedOut {
    cells: Vec<Cell>,
    unidentified: Vec<String>,
    weighed: Vec<String>,
    seconds: Vec<f64>,
    nominal: NominalWritten,
}

impl Training<'_> {
    /// Run this seed's training trajectories under the servo and identify a model from each.
    fn models(
        &self,
        seed: u64,
        sd: &Path,
        tick: &(dyn Fn(&str) + Sync),
    ) -> Result<SeedModels, StudyError> {
        let (s, arm, n) = (self.s, self.arm, self.arm.dof());
        let [servo_kp, servo_kd] = self.servo;
        let training: Vec<Case> = self
            .set
            .iter()
            .enumerate()
            .map(|(k, tr)| {
                let text = with_reference(&tr.for_seed(seed, k), None)?;
                case(
                    tr.name,
                    &text,
                    self.robot,
                    seed,
                    pd_servo(servo_kp, servo_kd),
                    s.velocity,
                    sd,
                )
            })
            .collect::<Result<_, _>>()?;
        write_scenarios(&training)?;
        let sims = simulate_all(&training, s.threads, &|| tick("training run"))?;
        let mut out = SeedModels {
            models: Vec::new(),
            unidentified: Vec::new(),
            weighed: Vec::new(),
            seconds: Vec::new(),
        };
        for (c, sim) in training.iter().zip(&sims) {
            let data = Trajectory::from_sim(
                &sim.rows,
                &c.scenario.reference,
                c.scenario.timing.period,
                evoloop_rkgnn::SMOOTHING,
            );
            let mut settings = Settings::least_squares(n, seed, s.evaluations);
            settings.threads = s.threads.max(1);
            settings.weighing = s.weighing;
            settings.start = s.start;
            if s.christoffel {
                settings.christoffel_velocity();
            }
            settings.servo = servo_prior(s.servo_known, self.servo, (s.velocity, c), arm);
            // A training run from which least squares finds no positive definite M-hat gives
            // no model: it is left out as a refused one is (and counted), not the study ended.
            let found = match &s.models_from {
                Some(from) => earlier_model(from, seed, &c.name, &settings, s.velocity),
                None => identify::identify_model(
                    &data,
                    self.prior,
                    &settings,
                    c.name.clone(),
                    |_, _| {},
                )
                .map_err(StudyError::from),
            };
            tick("identification");
            match found {
                Ok(model) => {
                    out.seconds.push(model.report.seconds);
                    if model.report.weigh_joints {
                        out.weighed.push(format!("seed {seed}, {}", c.name));
                    }
                    let file = sd.join(format!("model_{}.json", c.name));
                    model.save(&file)?;
                    out.models.push(Some((file, model)));
                }
                Err(e) => {
                    out.unidentified
                        .push(format!("seed {seed}, {}: {e}", c.name));
                    out.models.push(None);
                }
            }
        }
        Ok(out)
    }
}

/// How far the nominal (CAD) model's mass properties are off: each factor within 1 +- this.
pub const NOMINAL_SPREAD: f64 = 0.2;

/// online_model's identification alongside operation (`optimiser.mode = "identify"`): the
/// shipped settings of config/arm3/arm3_identify.toml (4 s window, 1 s fresh, every 2 s) halved to
/// fit a 10 s task, set before any run of this baseline; the margin as shipped.
const ONLINE: [(&str, f64); 5] = [
    ("identify_window", 2.0),
    ("identify_fresh", 0.5),
    ("identify_every", 1.0),
    ("margin", 0.2),
    ("sync_period", 0.1),
];

/// A seed's nominal model as written down: its file, the seed its errors were drawn from and
/// the errors (per body, factors on mass, centre of mass and inertia).
#[derive(Debug, Clone, Serialize)]
pub struct NominalWritten {
    /// The study's seed the model belongs to.
    pub seed: u64,
    /// Where it is written (`seed<N>/nominal.urdf`).
    pub file: PathBuf,
    /// The seed its errors were drawn from (`nominal_seed`: the arm's name and `seed`).
    pub drawn_from: u64,
    /// Per body, the factors on mass, centre of mass and inertia.
    pub errors: Vec<crate::dynamics::nominal::CadError>,
}

/// The nominal model in memory and as written.
struct Nominal {
    model: Model,
    written: NominalWritten,
}

/// The seed the nominal model's errors are drawn from: the arm's name and the study's seed, so
/// that two arms of one study, and two seeds of one arm, have other errors (FNV-1a of the name).
fn nominal_seed(arm: &Model, seed: u64) -> u64 {
    let name = arm.name.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    });
    name ^ seed.wrapping_mul(0x9e37_79b9_7f4a_7c15)
}

/// `arm` as its CAD model has it for `seed` (mass properties off, no friction), written to
/// `dir/nominal.urdf`.
fn nominal_model(arm: &Model, seed: u64, dir: &Path) -> Result<Nominal, StudyError> {
    use crate::dynamics::nominal;
    let drawn_from = nominal_seed(arm, seed);
    let errors = nominal::draw(arm.dof(), NOMINAL_SPREAD, drawn_from);
    // A CAD model knows the masses, roughly, and nothing of the joints' friction.
    let mut model = nominal::perturbed(arm, &errors);
    model.clear_friction();
    let file = dir.join("nominal.urdf");
    let text = crate::dynamics::urdf::to_urdf(&model)
        .map_err(|e| StudyError::Arm(format!("the nominal model: {e}")))?;
    crate::files::write(&file, text).map_err(WriteError::file(&file))?;
    Ok(Nominal {
        model,
        written: NominalWritten {
            seed,
            file,
            drawn_from,
            errors,
        },
    })
}

/// `[controller]` with `key = file` added to its law's table.
fn with_file(mut c: toml::Table, key: &str, file: &Path) -> Result<toml::Table, StudyError> {
    let law = c.get("kind").and_then(|k| k.as_str()).map(str::to_owned);
    let law = law.ok_or_else(|| StudyError::BuiltIn("a controller without its kind".into()))?;
    table(&mut c, &law)?.insert(key.into(), file.display().to_string().into());
    Ok(c)
}

/// A tracking scenario's text with identification alongside operation (`ONLINE`).
fn identifying(text: &str) -> Result<String, StudyError> {
    let mut t: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| StudyError::BuiltIn(e.to_string()))?;
    let o = table(&mut t, "optimiser")?;
    o.insert("mode".into(), "identify".into());
    for (k, v) in ONLINE {
        o.insert(k.into(), toml::Value::Float(v));
    }
    toml::to_string(&t).map_err(|e| StudyError::BuiltIn(e.to_string()))
}

/// One seed's tracking: what every trajectory's runs share.
struct SeedRun<'a> {
    s: &'a SelectionSettings,
    g: &'a super::study::Gains,
    robot: &'a Path,
    arm: &'a Model,
    dir: &'a Path,
    seed: u64,
    /// The three training runs' models (None: not identified) and their files.
    models: &'a [Option<(PathBuf, evoloop_rkgnn::RkgnnModel)>],
    servo: [&'a [f64]; 2],
    matched: [&'a [f64]; 2],
    /// The matched servo's gains tuned on the nominal model (pd_gravity's).
    cad_matched: [&'a [f64]; 2],
    nominal: &'a Nominal,
}

impl SeedRun<'_> {
    /// Every controller of `RUN` on the trajectory `name` (scenario `text`, parsed as
    /// `reference`): one cell.
    fn track(
        &self,
        name: &'static str,
        text: &str,
        reference: &crate::config::Scenario,
        tick: &(dyn Fn(&str) + Sync),
    ) -> Result<Cell, StudyError> {
        let (s, g, n) = (self.s, self.g, self.arm.dof());
        let models = self.models;
        // The controller refuses a model whose M-hat is not positive definite along the
        // reference (law::fuzzy_computed_torque): such a model is left out here as a
        // user would leave it out, alone and in the fuzzy sets.
        let duration = reference.timing.duration;
        let along =
            crate::law::fuzzy_computed_torque::reference_positions(&reference.reference, duration);
        // The controller's own check, once per model: it gives the smallest eigenvalue along
        // the reference when the model passes; a refused one's is looked up in full.
        let checked: Vec<Option<Result<f64, _>>> = models
            .iter()
            .map(|m| m.as_ref().map(|(_, m)| check_along_reference(m, &along)))
            .collect();
        let usable: Vec<bool> = checked.iter().map(|c| matches!(c, Some(Ok(_)))).collect();
        // NaN for a model not identified.
        let min_eig_on_reference: Vec<f64> = models
            .iter()
            .zip(&checked)
            .map(|(m, c)| match (m, c) {
                (_, Some(Ok(lowest))) => *lowest,
                (Some((_, m)), _) => m.min_eig(along.iter().map(Vec::as_slice)),
                (None, _) => f64::NAN,
            })
            .collect();
        // The truth judges the models along the reference (after the fact).
        let path = reference_states(reference);
        let models_error = models
            .iter()
            .map(|m| {
                m.as_ref()
                    .map(|(_, m)| model_error(self.arm, &path, &mut &m.net))
            })
            .collect();
        let nominal_error = model_error(self.arm, &path, &mut RigidBody::new(&self.nominal.model));
        // The usable models' indices: slot k of the fuzzy sets is model kept_idx[k].
        let kept_idx: Vec<usize> = (0..models.len()).filter(|&k| usable[k]).collect();
        let file = |k: usize| models[k].as_ref().map(|(f, _)| f);
        let kept: Vec<&PathBuf> = kept_idx.iter().filter_map(|&k| file(k)).collect();
        let single = |k: usize| {
            let f = file(k).filter(|_| usable[k])?;
            Some(g.fuzzy(&[f], "max", &[]))
        };
        let any = !kept.is_empty();
        let uniform = [("gamma", toml::Value::Float(UNIFORM_GAMMA))];
        let memberships = [("evidence_prior", "memberships".into())];
        let ct = || controller("computed_torque", g.ct_table());
        let nominal_file = &self.nominal.written.file;
        let [kp, kd] = self.matched;
        let [cad_kp, cad_kd] = self.cad_matched;
        let laws = [
            Some(pd_servo(self.servo[0], self.servo[1])),
            Some(pd_servo(kp, kd)),
            Some(ct()),
            single(0),
            single(1),
            single(2),
            any.then(|| g.fuzzy(&kept, "max", &[])),
            any.then(|| g.fuzzy(&kept, "blend", &[])),
            any.then(|| g.fuzzy(&kept, "blend", &uniform)),
            any.then(|| g.fuzzy(&kept, "evidence", &memberships)),
            any.then(|| g.fuzzy(&kept, "evidence", &[])),
            Some(with_file(
                pd_servo(cad_kp, cad_kd),
                "gravity_model",
                nominal_file,
            )?),
            Some(with_file(ct(), "model", nominal_file)?),
            // One model, updated online: the first usable one.
            kept.first().map(|f| g.fuzzy(&[f], "max", &[])),
        ];
        let runnable: Vec<(&str, toml::Table)> = RUN
            .iter()
            .zip(laws)
            .filter_map(|(k, law)| law.map(|l| (*k, l)))
            .collect();
        let online = identifying(text)?;
        let cases: Vec<Case> = runnable
            .iter()
            .map(|(k, law)| {
                let text = if *k == "online_model" { &online } else { text };
                case(
                    &format!("{name}_{k}"),
                    text,
                    self.robot,
                    self.seed,
                    law.clone(),
                    s.velocity,
                    self.dir,
                )
            })
            .collect::<Result<_, _>>()?;
        write_scenarios(&cases)?;
        let sims = simulate_all(&cases, s.threads, &|| tick("tracking run"))?;
        let ran = |key: &str| runnable.iter().position(|(k, _)| *k == key);
        let rms = tracking_rms(&ran, &sims, &cases, n);
        // The max rule's switching, over the models it was given (the usable ones).
        let (switches, share) = match ran("fuzzy_max") {
            Some(c) => {
                let active = sims[c]
                    .law_column("fuzzy_model")
                    .ok_or(StudyError::Data("fuzzy run logged no active model"))?;
                let share = (0..models.len())
                    .map(|m| {
                        active
                            .iter()
                            .filter(|&&a| kept_idx.get(a as usize) == Some(&m))
                            .count() as f64
                            / active.len().max(1) as f64
                    })
                    .collect();
                (active.windows(2).filter(|w| w[0] != w[1]).count(), share)
            }
            None => (0, vec![0.0; models.len()]),
        };
        // The models the online identification put in service (accepted sets).
        let online_updates = ran("online_model").map(|c| {
            let accepted =
                |e: &&crate::law::cycle::ParamEvent| e.code == crate::msg::ParamCode::Accepted;
            sims[c].events.iter().filter(accepted).count()
        });
        let refused = (0..models.len())
            .filter(|&k| models[k].is_some() && !usable[k])
            .count();
        Ok(Cell {
            seed: self.seed,
            trajectory: name,
            rms,
            switches_per_s: switches as f64 / duration,
            share,
            min_eig_on_reference,
            refused,
            model_error: models_error,
            nominal_error,
            online_updates,
        })
    }
}

/// Each law's rms tracking error per joint (`ran` says which case ran it), then the best and
/// the average single model. A run not made (a refused model) is NaN, left out of every
/// comparison; a run made whose error is not finite (it diverged) is +inf, the worst of all.
fn tracking_rms(
    ran: &dyn Fn(&str) -> Option<usize>,
    sims: &[SimResult],
    cases: &[Case],
    n: usize,
) -> Vec<(String, Vec<f64>)> {
    let mut rms: Vec<(String, Vec<f64>)> = RUN
        .iter()
        .map(|k| {
            let v = ran(k).map_or(vec![f64::NAN; n], |c| {
                let v = JointTraces::of(&sims[c], &cases[c].scenario.reference, n).rms();
                if overall(&v).is_finite() {
                    v
                } else {
                    vec![f64::INFINITY; n]
                }
            });
            (k.to_string(), v)
        })
        .collect();
    let singles: Vec<&Vec<f64>> = rms
        .iter()
        .filter(|(k, _)| SINGLES.contains(&k.as_str()))
        .map(|(_, v)| v)
        .filter(|v| !overall(v).is_nan())
        .collect();
    let best = singles
        .iter()
        .min_by(|a, b| overall(a).total_cmp(&overall(b)))
        .map_or(vec![f64::NAN; n], |v| (*v).clone());
    let random: Vec<f64> = (0..n)
        .map(|j| singles.iter().map(|v| v[j]).sum::<f64>() / singles.len() as f64)
        .collect();
    rms.push(("best_single".into(), best));
    rms.push(("random_single".into(), random));
    rms
}

/// Seed `seed`'s model of training run `name` from the earlier study in `from`, which must have
/// been identified as `settings` would: the same seed, start, servo prior, joints' weighing
/// and at least the EA evaluations, from a training run whose servo acted on `velocity`. None
/// there: an error, counted as a run not identified.
fn earlier_model(
    from: &Path,
    seed: u64,
    name: &str,
    settings: &Settings,
    velocity: JointVelocity,
) -> Result<evoloop_rkgnn::RkgnnModel, StudyError> {
    let seed_dir = from.join(format!("seed{seed}"));
    let file = seed_dir.join(format!("model_{name}.json"));
    if !file.is_file() {
        return Err(StudyError::Setting(format!(
            "no model in {}",
            file.display()
        )));
    }
    let training = seed_dir.join("scenarios").join(format!("{name}.toml"));
    let trained_on = training_velocity(&training)?;
    if trained_on != velocity.key() {
        return Err(StudyError::Setting(format!(
            "{}: its training servo acted on velocity = \"{trained_on}\", this study's on \"{}\"",
            training.display(),
            velocity.key()
        )));
    }
    let model = evoloop_rkgnn::RkgnnModel::load(&file)?;
    let r = &model.report;
    let known = matches!(settings.servo, ServoPrior::Known { .. });
    let same = r.seed == settings.ea.seed
        && r.start == settings.start
        && (!known || same_weighing(settings.weighing, r))
        && std::mem::discriminant(&r.servo) == std::mem::discriminant(&settings.servo)
        && r.evaluations >= settings.evaluations;
    if !same {
        return Err(StudyError::Setting(format!(
            "{}: identified otherwise (seed {}, {} start, {} evaluations, joints weighed: {}) \
             than this study asks",
            file.display(),
            r.seed,
            r.start.name(),
            r.evaluations,
            r.weighing().name()
        )));
    }
    Ok(model)
}

/// Whether a known servo's model `r` is the one `setting` would have identified: a fit in N m is
/// also what `as-needed` keeps (the weighing is tried only where it fails), a weighed fit also
/// what `always` gives; a weighed fit under `always` need not be `as-needed`'s.
fn same_weighing(setting: Weighing, r: &evoloop_rkgnn::model::Report) -> bool {
    match setting {
        Weighing::Never => !r.weigh_joints,
        Weighing::AsNeeded => !r.weigh_joints || r.weighing() == Weighing::AsNeeded,
        Weighing::Always => r.weigh_joints,
    }
}

/// The `velocity` key of a training run's servo as its scenario file says: "true" where the file
/// has none (studies written before the scenarios' default became "filtered").
fn training_velocity(scenario: &Path) -> Result<String, StudyError> {
    let refused =
        |e: &dyn std::fmt::Display| StudyError::Setting(format!("{}: {e}", scenario.display()));
    let text = crate::files::read_text(scenario).map_err(|e| refused(&e))?;
    let t: toml::Table = text.parse().map_err(|e| refused(&e))?;
    let servo = t.get("controller").and_then(|c| c.get("pd_servo"));
    Ok(servo
        .and_then(|s| s.get("velocity"))
        .and_then(|v| v.as_str())
        .unwrap_or("true")
        .to_string())
}

/// Per trajectory, each controller's median tracking RMS over the seeds.
pub type Medians = Vec<(String, Vec<(String, f64)>)>;

/// A cell's overall RMS of controller `k` (NaN: not run).
fn value(c: &Cell, k: &str) -> f64 {
    c.rms
        .iter()
        .find(|(key, _)| key == k)
        .map_or(f64::NAN, |(_, v)| overall(v))
}

/// Every controller key, run and derived.
fn keys() -> Vec<&'static str> {
    RUN.iter().chain(&DERIVED).copied().collect()
}

/// Per seed, the mean over `cells` of that seed of the (rule, baseline) overall RMS, on the
/// tasks both ran. Seeds are the independent units: a seed's models are identified anew, the
/// four tasks of a seed share them. Both diverged on a task: a tie, left out.
fn per_seed(cells: &[&Cell], rule: &str, baseline: &str) -> (Vec<f64>, Vec<f64>) {
    let mut seeds: Vec<u64> = cells.iter().map(|c| c.seed).collect();
    seeds.sort_unstable();
    seeds.dedup();
    seeds
        .iter()
        .filter_map(|&seed| {
            let both: Vec<(f64, f64)> = (cells.iter())
                .filter(|c| c.seed == seed)
                .map(|c| (value(c, rule), value(c, baseline)))
                .filter(|(f, b)| !f.is_nan() && !b.is_nan())
                .filter(|(f, b)| !(f.is_infinite() && b.is_infinite()))
                .collect();
            let k = both.len() as f64;
            (k > 0.0).then(|| {
                let (f, b): (Vec<f64>, Vec<f64>) = both.into_iter().unzip();
                (f.iter().sum::<f64>() / k, b.iter().sum::<f64>() / k)
            })
        })
        .unzip()
}

/// Each rule against every other controller over the seeds of `cells`.
fn compare_all(cells: &[&Cell]) -> Vec<Comparison> {
    let keys = keys();
    RULES
        .iter()
        .flat_map(|rule| {
            keys.iter()
                .filter(move |k| *k != rule)
                .map(move |k| (rule, k))
        })
        .map(|(rule, k)| {
            let (fuzzy, b) = per_seed(cells, rule, k);
            Comparison {
                rule: rule.to_string(),
                baseline: k.to_string(),
                median_fuzzy: median(&fuzzy),
                median_baseline: median(&b),
                fuzzy_lower: fuzzy.iter().zip(&b).filter(|(f, b)| f < b).count(),
                pairs: b.len(),
                wilcoxon: wilcoxon(&fuzzy, &b),
            }
        })
        .collect()
}

/// One task's (trajectory's) comparisons over the seeds.
#[derive(Debug, Clone, Serialize)]
pub struct TaskComparisons {
    /// The task's (new trajectory's) name.
    pub trajectory: String,
    /// Each rule against every other controller on this task, over the seeds.
    pub comparisons: Vec<Comparison>,
}

/// Medians per trajectory, the comparisons over seeds (each seed's mean over the tasks) and
/// per task.
fn summarise(
    cells: &[Cell],
    trajectories: &[&str],
) -> (Medians, Vec<Comparison>, Vec<TaskComparisons>) {
    let keys = keys();
    let medians = trajectories
        .iter()
        .map(|name| {
            let here: Vec<&Cell> = cells.iter().filter(|c| c.trajectory == *name).collect();
            let m = keys
                .iter()
                .map(|k| {
                    (
                        k.to_string(),
                        median_of_numbers(here.iter().map(|c| value(c, k))),
                    )
                })
                .collect();
            (name.to_string(), m)
        })
        .collect();
    let all: Vec<&Cell> = cells.iter().collect();
    let tasks = trajectories
        .iter()
        .map(|name| TaskComparisons {
            trajectory: name.to_string(),
            comparisons: compare_all(
                &all.iter()
                    .copied()
                    .filter(|c| c.trajectory == *name)
                    .collect::<Vec<_>>(),
            ),
        })
        .collect();
    (medians, compare_all(&all), tasks)
}

/// Whether `rule` is below the best single model in hindsight: median lower and Wilcoxon
/// p < 0.05 with the rule lower.
fn claim_held(comparisons: &[Comparison], rule: &str) -> bool {
    comparisons
        .iter()
        .find(|c| c.rule == rule && c.baseline == "best_single")
        .is_some_and(Comparison::rule_lower)
}

impl Comparison {
    /// The rule below the baseline: median lower, the signed ranks its way, Wilcoxon p < 0.05.
    pub fn rule_lower(&self) -> bool {
        let w = &self.wilcoxon;
        self.median_fuzzy < self.median_baseline && w.w_plus < w.w_minus && w.p_two_sided < 0.05
    }

    /// The baseline below the rule, the same way.
    pub fn baseline_lower(&self) -> bool {
        let w = &self.wilcoxon;
        self.median_baseline < self.median_fuzzy && w.w_minus < w.w_plus && w.p_two_sided < 0.05
    }
}

/// The baselines a control engineer would set a rule against: the best single model in
/// hindsight, the servo with gravity compensation and computed torque on the CAD model, one
/// model identified online, and computed torque on the true arm (the bound).
pub const STRONGEST: [&str; 5] = [
    "best_single",
    "pd_gravity",
    "ct_nominal",
    "online_model",
    "ct_true",
];

/// A comparison's table row (from its rule on).
fn comparison_row(c: &Comparison) -> String {
    format!(
        "| {} | {} | {:.4} | {:.4} | {} of {} seeds | {:.2e} ({}) |\n",
        c.rule,
        c.baseline,
        c.median_fuzzy,
        c.median_baseline,
        c.fuzzy_lower,
        c.pairs,
        c.wilcoxon.p_two_sided,
        c.wilcoxon.method
    )
}

/// The models' errors against the arm along the tasks: medians over seeds and tasks.
fn model_error_table(r: &SelectionResult) -> String {
    let mut md =
        format!(
        "\nThe models against the arm along the tasks (medians over seeds and tasks; the arm's \
         own smallest eigenvalue of M along them {:.3}): relative errors of M-hat (Frobenius), \
         V-hat (Coriolis, centrifugal and friction) and G-hat, and tr(M-hat) / tr(M) (above 1: \
         an inflated model, a stiffer loop). The nominal model is the arm's file with its masses, \
         centres of mass and inertias off by up to {:.0} %, fixed per seed:\n\n\
         | model | M-hat error | tr ratio | V-hat error | G-hat error | smallest eigenvalue |\n\
         |---|---|---|---|---|---|\n",
        median(&r.cells.iter().map(|c| c.nominal_error.min_eig_arm).collect::<Vec<_>>()),
        100.0 * r.nominal_spread
    );
    let row = |name: String, e: Vec<ModelError>| {
        let m = |f: fn(&ModelError) -> f64| median_of_numbers(e.iter().map(f));
        format!(
            "| {name} | {:.3} | {:.3} | {:.3} | {:.3} | {:.3} |\n",
            m(|e| e.m_rel),
            m(|e| e.m_scale),
            m(|e| e.v_rel),
            m(|e| e.g_rel),
            m(|e| e.min_eig)
        )
    };
    for (k, name) in r.training.iter().enumerate() {
        let e = r
            .cells
            .iter()
            .filter_map(|c| c.model_error.get(k).copied().flatten());
        md += &row(format!("model {} ({name})", k + 1), e.collect());
    }
    md += &row(
        "nominal".into(),
        r.cells.iter().map(|c| c.nominal_error).collect(),
    );
    let updates: Vec<f64> = (r.cells.iter().filter_map(|c| c.online_updates))
        .map(|u| u as f64)
        .collect();
    md += &format!(
        "\nonline_model: computed torque on the seed's first model usable on the task, which identification \
         alongside operation updates from the applied torques ({}); it put a median of {} \
         models in service a run.\n",
        r.online
            .iter()
            .map(|(k, v)| format!("{k} = {v}"))
            .collect::<Vec<_>>()
            .join(", "),
        median(&updates)
    );
    md
}

fn verdict(held: bool) -> &'static str {
    if held {
        "held (median lower over the seeds, Wilcoxon p < 0.05)"
    } else {
        "did not hold"
    }
}

/// report.md: the table of medians, the comparisons, the claim, each from this run's numbers.
pub fn report_markdown(r: &SelectionResult) -> String {
    let mut md =
        format!(
        "# Fuzzy selection on trajectories that are not midpoints\n\n{} on {} new trajectories \
         ({}), three models identified on {} per seed, {} seeds. Median whole-run RMS tracking \
         error over the {} joints (rad), tracking at {} Hz; identification: servo {}, {} start, \
         {} EA evaluations per model{}{}:\n\n| controller | {} |\n|---|{}\n",
        r.robot.display(),
        r.trajectories.len(),
        r.trajectories.join(", "),
        r.training.join(", "),
        r.seeds,
        r.joints,
        (1.0 / r.period).round(),
        if r.servo_known { "known" } else { "unknown" },
        r.start.name(),
        r.evaluations,
        match r.weighing {
            _ if !r.servo_known => String::new(),
            Weighing::Never => String::new(),
            Weighing::AsNeeded => format!(
                ", joints weighed as needed ({} of {} models)",
                r.weighed.len(),
                r.training.len() as u64 * r.seeds - r.unidentified.len() as u64
            ),
            Weighing::Always => ", joints weighed".into(),
        },
        if r.christoffel { ", Christoffel V-hat" } else { "" },
        r.trajectories.join(" | "),
        "---|".repeat(r.trajectories.len())
    );
    let keys: Vec<&str> = RUN.iter().chain(&DERIVED).copied().collect();
    for k in keys {
        let row: Vec<String> = r
            .medians
            .iter()
            .map(|(_, m)| {
                m.iter()
                    .find(|(key, _)| key == k)
                    .map_or("-".into(), |(_, v)| format!("{v:.4}"))
            })
            .collect();
        md += &format!("| {k} | {} |\n", row.join(" | "));
    }
    md += "\nEach rule (the fuzzy rules, the uniform blend and the evidence rules) against each \
           other controller, paired over the seeds (per seed the mean over the tasks both ran; \
           seeds re-identify their models, so they are the independent units), Wilcoxon \
           signed-rank test (exact up to 30 seeds):\n\n\
           | rule | baseline | median rule | median baseline | rule lower | Wilcoxon p |\n\
           |---|---|---|---|---|---|\n";
    for c in &r.comparisons {
        md += &comparison_row(c);
    }
    md += "\nPer task (trajectory), over the seeds, each rule against the strongest baselines:\n\n\
           | task | rule | baseline | median rule | median baseline | rule lower | Wilcoxon p |\n\
           |---|---|---|---|---|---|---|\n";
    for t in &r.tasks {
        for c in t
            .comparisons
            .iter()
            .filter(|c| STRONGEST.contains(&c.baseline.as_str()))
        {
            md += &format!("| {} {}", t.trajectory, comparison_row(c));
        }
    }
    md += &model_error_table(r);
    let sw = median(&r.cells.iter().map(|c| c.switches_per_s).collect::<Vec<_>>());
    let refused: usize = r.cells.iter().map(|c| c.refused).sum();
    md += &format!(
        "\nThe controller refused {refused} of {} (model, trajectory, seed) cases, a model \
         whose M-hat is not positive definite along the trajectory; those are left out alone \
         and from the fuzzy sets, and the comparisons pair only runs that both ran.\n",
        r.training.len() * r.cells.len()
    );
    if !r.unidentified.is_empty() {
        md += &format!(
            "\n{} of {} training runs gave no model (least squares found no positive definite \
             M-hat); they are left out the same way:\n\n",
            r.unidentified.len(),
            r.training.len() as u64 * r.seeds
        );
        for u in &r.unidentified {
            md += &format!("- {u}\n");
        }
    }
    md += &format!(
        "\nThe max rule switched models {sw:.1} times a second (median over runs).\n\n\
         The paper's claim, fuzzy selection (its max rule) better than the best single model \
         in hindsight, {} here; with the blend it {}; the uniform blend's (no selection) {}. \
         Weighted per joint by each model's evidence (how well it explains the motion under \
         the torque applied), on the memberships it {}, on a uniform prior {}.\n",
        verdict(r.claim_held),
        verdict(r.claim_held_blend),
        verdict(r.claim_held_uniform),
        verdict(r.claim_held_evidence),
        verdict(r.claim_held_uniform_evidence)
    );
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    fn arm(file: &str) -> Model {
        crate::dynamics::load(Path::new(&format!(
            "{}/../../config/robots/{file}",
            env!("CARGO_MANIFEST_DIR")
        )))
        .unwrap()
    }

    /// arm3 (as D-H table and as URDF) runs the paper's trajectories; gen3_s11, whose elbow turns
    /// less, runs its own, within its limits.
    #[test]
    fn the_paper_arm_keeps_the_written_trajectories_and_an_arm_they_leave_gets_its_own() {
        for file in ["arm3.toml", "arm3.urdf"] {
            let (_, _, source) = trajectories_for(&arm(file));
            assert_eq!(source, TrajectorySource::Paper, "{file}");
        }
        let tight = crate::dynamics::load(Path::new(&format!(
            "{}/../../tests/robots/gen3_s11.urdf",
            env!("CARGO_MANIFEST_DIR")
        )))
        .unwrap();
        let (training, new, source) = trajectories_for(&tight);
        assert_eq!(source, TrajectorySource::Limits);
        assert!(training.iter().chain(&new).all(|s| holds(&tight, s)));
    }

    #[test]
    fn generated_trajectories_stay_within_the_limits_and_no_new_one_is_a_midpoint() {
        let panda = arm("arm7.urdf");
        let (training, new) = generated(&panda);
        assert_eq!((training.len(), new.len()), (3, 4));
        for s in training.iter().chain(&new) {
            assert_eq!(s.offsets.len(), 7);
            // Seeds move offsets by up to 0.1 rad and amplitudes by 15 %: still inside.
            for (b, (lo, hi)) in panda.bodies.iter().zip(reach(s)) {
                let (q_min, q_max) = b.limits.position_span();
                let margin = 0.1 + 0.15 * (hi - lo) / 2.0;
                assert!(
                    lo - margin > q_min && hi + margin < q_max,
                    "{}: {s:?}",
                    b.joint
                );
            }
        }
        for n in &new {
            for (i, a) in training.iter().enumerate() {
                for b in &training[i + 1..] {
                    let mid_off = a.offsets.iter().zip(&b.offsets).map(|(x, y)| 0.5 * (x + y));
                    let off: f64 = mid_off.zip(&n.offsets).map(|(m, o)| (m - o).abs()).sum();
                    assert!(
                        off > 0.05,
                        "{} is the midpoint of {} and {}",
                        n.name,
                        a.name,
                        b.name
                    );
                }
            }
        }
        // The paper's arm keeps the trajectories written for it.
        let (written_training, _) = written();
        assert_eq!(written_training[0].offsets, vec![0.0, 0.5, -1.0]);
    }
}
