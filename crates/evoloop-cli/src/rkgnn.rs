//! `evoloop identify rkgnn` and `evoloop rkgnn eval|study`: the RKGNN paper from the command line.

use clap::{Args, Subcommand};
use evoloop_identify::rkgnn::identify::{self, Prior, Settings};
use evoloop_identify::rkgnn::study::JointVelocity;
use evoloop_identify::rkgnn::Trajectory;
use evoloop_rkgnn::model::{ServoPrior, Start, Weighing};
use evoloop_rkgnn::network::RbfCounts;
use evoloop_rkgnn::RkgnnModel;
use serde_json::json;
use std::path::PathBuf;

/// The subcommands of `evoloop identify`: system identification from run data and robot files.
#[derive(Subcommand)]
pub enum IdentifyCmd {
    /// Identify an arm's dynamics and its servo as an RKGNN from a run's reference and output
    /// (run.csv: reference, r*, rd*, y*, qd*; the torques u* are not read), by the RKGNN paper's
    /// evolutionary algorithm; writes MODEL.json.
    Rkgnn(IdentifyArgs),
    /// The base (identifiable) inertial parameters of a robot file: the regressor stacked over
    /// random states, zero columns (unidentifiable), QR with column pivoting for the rank, and
    /// the regrouping of the dependent parameters into the base ones (printed).
    Base(super::identify_base::BaseArgs),
    /// An optimal excitation trajectory for one identification stage (the eMuPSO paper's
    /// eq. 15 on the stage's base regressor, by its two-phase eMuPSO search): a periodic
    /// joint-space Fourier series inside the joint limits, starting at rest; writes TRAJ.json
    /// (usable as `[reference] kind = "excitation"`) and a plot.
    Excitation(super::identify_excitation::ExcitationArgs),
    /// Least-squares estimate of the base parameters from excitation runs (positions and
    /// torques of run.csv, averaged over periods, differentiated in the frequency domain),
    /// against the robot file's own values, with a held-out period's torque prediction.
    Lls(super::identify_lls::LlsArgs),
    /// Does optimising the excitation pay? Over seeds, the identification experiment on the
    /// first feasible random trajectory of each search and on the optimised one, compared by
    /// Wilcoxon's signed-rank test (results.json, report.md, errors.png).
    Study(super::identify_study::StudyArgs),
}

/// Options of `evoloop identify rkgnn`: the run to learn from, eq. 2's inertia bounds, the model's
/// form (velocity and servo networks) and the evolutionary algorithm's budget.
#[derive(Args)]
pub struct IdentifyArgs {
    /// Run directory holding run.csv (an arm under its servo, e.g. runs/arm3_train1).
    #[arg(long)]
    pub data: PathBuf,
    /// Model file to write.
    #[arg(long)]
    pub out: PathBuf,
    /// Seed of the evolutionary algorithm.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Objective evaluations (the budget).
    #[arg(long, default_value_t = DEFAULT_EVALUATIONS)]
    pub evaluations: usize,
    /// Levenberg-Marquardt steps on the free-run output error after the least-squares start
    /// (with --start least-squares; 0 = none).
    #[arg(long, default_value_t = 0)]
    pub refine: usize,
    /// Use every STRIDE-th sample: the RKGNN's step is STRIDE times the run's period. Keep
    /// h x (servo's k_d / inertia) under 2.78, the Gill step's stability limit: at stride 10
    /// (h = 10 ms) arm3's forearm servo sits at 2.77, at the edge.
    #[arg(long, default_value_t = 5)]
    pub stride: usize,
    /// Half width of the low-pass, s: the joint velocities are estimated from the measured
    /// positions (never the run's logged `qd*`) by a local quadratic fit over this window either
    /// side, and the positions are smoothed with it. 0.08 s passes arm motion below 3.6 Hz (-3 dB
    /// on the velocities) and cuts 1e-4 rad encoder noise to 2e-4 rad/s; widen it for noisier
    /// encoders, narrow it for faster motion.
    #[arg(long, default_value_t = evoloop_rkgnn::SMOOTHING,
          value_parser = |s: &str| crate::args::seconds_in(s, 10.0))]
    pub smoothing: f64,
    /// Eq. 2's lower bound m1 on the arm's inertia matrix (y^T M(q) y >= m1 |y|^2, kg m^2): the
    /// smallest eigenvalue of M(q) over the workspace, from a datasheet, a CAD model
    /// (`evoloop rkgnn prior --robot FILE`) or a conservative bound. With m2 it is all the
    /// identification knows of the arm besides the data; it fixes the model's scale.
    #[arg(long)]
    pub m1: f64,
    /// Eq. 2's upper bound m2 (y^T M(q) y <= m2 |y|^2, kg m^2): the largest eigenvalue of M(q).
    #[arg(long)]
    pub m2: f64,
    /// V-hat: `network` (the paper's velocity network, eqs. 8-10) or `christoffel` (from
    /// M-hat's Christoffel symbols, so that eq. 3 holds; no velocity parameters).
    #[arg(long, value_enum, default_value_t = VelocityKind::Network)]
    pub velocity: VelocityKind,
    /// The servo network: `rbf` (the paper's Fig. 3, 3 RBFs per P and D sub-network),
    /// `linear` (tau_j = k_p e_j + k_d e_j', the P-D servo of the paper's premise, gains
    /// identified; with it gravity is identifiable) or `known` (the P-D servo whose gains the
    /// user set: --kp, --kd, or the run's own scenario.json controller when it is a pd_servo;
    /// then the servo's torque is known and the model's scale with it).
    #[arg(long, value_enum, default_value_t = ServoKind::Rbf)]
    pub servo: ServoKind,
    /// Where the EA starts: `random` (the paper's) or `least-squares` (the inverse-dynamics
    /// equation solved for the output weights; needs --servo linear). With `least-squares`,
    /// --evaluations 0 returns the start itself.
    #[arg(long, value_parser = crate::choice::choice(&Start::ALL, Start::name), default_value = "random")]
    pub start: Start,
    /// With --servo known: the servo's proportional gains, one per joint [default: the run's
    /// scenario.json controller.gains].
    #[arg(long, value_delimiter = ',')]
    pub kp: Option<Vec<f64>>,
    /// With --servo known: the servo's derivative gains, one per joint.
    #[arg(long, value_delimiter = ',')]
    pub kd: Option<Vec<f64>>,
    /// With --kp and --kd: the cutoff of the drive's velocity filter k_d acted on (positions
    /// differenced and low-passed), Hz [default: the joint velocity itself, an ideal sensor].
    /// Without them, the run's scenario.json says (a pd_servo's velocity). The least-squares
    /// start uses it; the EA's and --refine's free run do not yet.
    #[arg(long, requires = "kd")]
    pub servo_velocity_cutoff_hz: Option<f64>,
    /// With --servo known: when to weigh each joint's equations by 1 / its torque rms, so that
    /// joints carrying little torque (a wrist) are fitted as closely, relatively, as the
    /// shoulder: `as-needed` (where the fit in N m finds no positive definite M-hat; the
    /// default), `always` (what `--weigh-joints` alone means; arm7 needs it) or `never` (the
    /// recipe before 2026-12-06)
    #[arg(long, value_parser = crate::choice::choice(&Weighing::ALL, Weighing::name), value_name = "WHEN", num_args = 0..=1,
          default_value = "as-needed", default_missing_value = "always")]
    pub weigh_joints: Weighing,
    /// Evaluation threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print the report as JSON (keys train_rms, holdout_rms, min_eig_m_hat, evaluations,
    /// seconds, ...).
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The servo network of `identify rkgnn --servo`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ServoKind {
    /// The paper's servo network (Fig. 3): 3 RBFs per P and D sub-network
    Rbf,
    /// A P-D servo tau_j = k_p e_j + k_d e_j' whose gains are identified
    Linear,
    /// The P-D servo with the user's gains (--kp, --kd) or the run's scenario.json pd_servo
    Known,
}

/// The form of V-hat, the velocity term of an identified model (`--velocity`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VelocityKind {
    /// The paper's velocity network (eqs. 8-10)
    Network,
    /// From M-hat's Christoffel symbols, so that eq. 3 holds; no velocity parameters
    Christoffel,
}

/// What a study's identification knows of the training runs' P-D servo (`--servo`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StudyServo {
    /// Its gains are known (the shipped recipe)
    Known,
    /// Its gains are identified, the model's scale from eq. 2 (the paper's premise)
    Unknown,
}

/// The default identification budget.
pub const DEFAULT_EVALUATIONS: usize = 20_000;

/// The subcommands of `evoloop rkgnn`: identified RKGNN models and the paper's studies.
#[derive(Subcommand)]
pub enum RkgnnCmd {
    /// Evaluate an identified model at one state: M_hat, V_hat, G_hat.
    Eval(EvalArgs),
    /// Reproduce the paper's Section 5 on a 3-joint arm: identify a model on each training
    /// trajectory (reference and output only), track the new trajectory with the P-D servo, CT
    /// on the true model, on each model alone and by fuzzy selection (max, blend); writes
    /// study.json, tracking_rms.csv, report.md, Figs. 7-10 (PNG), each case's scenario and run.
    Study(StudyArgs),
    /// Eq. 2's bounds m1, m2 from a robot file (a CAD model's inertias): the smallest and
    /// largest eigenvalue of M(q) over a run's measured positions (--data) or over random
    /// positions within the joint limits; what `identify rkgnn --m1 --m2` takes.
    Prior(PriorArgs),
    /// Fuzzy selection against every baseline on four trajectories that are not midpoints:
    /// three models per seed, the training and a gain-matched P-D servo, the servo with gravity
    /// compensation and CT on a CAD model 20 % off (`seed<N>/nominal.urdf`), one model updated
    /// online, CT on the true model and on each model, max, blend, uniform blend and evidence
    /// rules, best single model in hindsight; each model's error against the arm; paired
    /// Wilcoxon tests over seeds; writes selection.json and report.md.
    Selection(SelectionArgs),
    /// The selection study on every arm of a zoo file (config/robots/zoo.toml: arms no setting
    /// was tuned on): each arm written to OUT/arms/, studied in OUT/NAME/, and one table of
    /// each rule against each strongest baseline per arm with the models' errors, and across
    /// arms the count with its sign test; writes zoo.json and zoo.md.
    Zoo(ZooArgs),
}

/// Options of `evoloop rkgnn zoo`: the zoo file, which of its arms, and the selection study's
/// settings for each arm.
#[derive(Args)]
pub struct ZooArgs {
    /// The zoo file (`[[arm]] joints = N, seed = S`).
    #[arg(long, default_value = "config/robots/zoo.toml")]
    pub zoo: PathBuf,
    /// Only the arms with these joint counts (e.g. 3,4) [default: all].
    #[arg(long, value_delimiter = ',')]
    pub joints: Vec<usize>,
    /// The selection study's settings (its arms come from --zoo); --models-from DIR takes
    /// each arm's models from DIR/NAME.
    #[command(flatten)]
    pub selection: StudySettingsArgs,
}

/// Options of `evoloop rkgnn selection`: fuzzy model selection against every baseline, over
/// seeds, on one arm.
#[derive(Args)]
pub struct SelectionArgs {
    /// An arm (D-H TOML or URDF): a 3-joint arm runs the trajectories written for the paper's
    /// arm, any other its trajectories built from its joint limits [default:
    /// config/robots/arm3.toml].
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// The study's settings, shared with `rkgnn zoo`.
    #[command(flatten)]
    pub study: StudySettingsArgs,
}

/// The selection study's settings on any arm: `rkgnn selection`'s on its `--robot`, `rkgnn
/// zoo`'s on each arm of the zoo.
#[derive(Args)]
pub struct StudySettingsArgs {
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Seeds (each: new measurement noise, models re-identified).
    #[arg(long, default_value_t = 10)]
    pub seeds: u64,
    /// When to identify with each joint's equations in units of its own torque rms:
    /// `as-needed` (where the fit in N m finds no positive definite M-hat: the zoo's 4-joint
    /// arms; the default), `always` (what `--weigh-joints` alone means; a 7-DOF arm's least
    /// squares needs it, its shoulder's torques are 100x its wrist's) or `never` (the recipe
    /// before 2026-12-06)
    #[arg(long, value_parser = crate::choice::choice(&Weighing::ALL, Weighing::name), value_name = "WHEN", num_args = 0..=1,
          default_value = "as-needed", default_missing_value = "always")]
    pub weigh_joints: Weighing,
    /// V-hat: `network` (the paper's velocity network; the shipped recipe) or `christoffel`
    /// (from M-hat's Christoffel symbols; 8x faster to fit on a 7-DOF arm).
    #[arg(long, value_enum, default_value_t = VelocityKind::Network)]
    pub velocity: VelocityKind,
    /// What the identification knows of the training runs' P-D servo: `known` (its gains; the
    /// shipped recipe) or `unknown` (the paper's premise: gains identified, scale from eq. 2).
    #[arg(long, value_enum, default_value_t = StudyServo::Known)]
    pub servo: StudyServo,
    /// Where the identification starts: `least-squares` (the shipped recipe) or `random` (the
    /// paper's; give --evaluations).
    #[arg(long, value_parser = crate::choice::choice(&evoloop_rkgnn::model::Start::ALL, evoloop_rkgnn::model::Start::name), default_value = "least-squares")]
    pub start: evoloop_rkgnn::model::Start,
    /// The paper's EA evaluations per model after the start; 0 keeps the start.
    #[arg(long, default_value_t = 0)]
    pub evaluations: usize,
    /// The tracking runs' loop period, s (e.g. 0.0001: a 7-DOF arm's 10 kHz); the training
    /// runs stay at 1 ms [default: 0.001].
    #[arg(long, value_parser = |s: &str| crate::args::seconds_in(s, 0.01))]
    pub period: Option<f64>,
    /// Take each seed's models from an earlier study's --out (its `seed<N>/model_<run>.json`,
    /// identified by the same recipe and seeds) instead of identifying them again: to compare
    /// the rules anew without the identification's minutes.
    #[arg(long)]
    pub models_from: Option<PathBuf>,
    /// The joint velocity the training servo and every tracking law act on: `filtered` (the
    /// measured positions differenced and low-passed at 50 Hz, as a drive does) or `true` (the
    /// simulator's velocities, an ideal sensor no plant has: the figures before 2026-12-03).
    #[arg(long, value_parser = crate::choice::choice(&JointVelocity::ALL, JointVelocity::key), default_value = "filtered")]
    pub joint_velocity: JointVelocity,
    /// Threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print selection.json to stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Options of `evoloop rkgnn prior`: eq. 2's inertia bounds m1, m2 from a robot file.
#[derive(Args)]
pub struct PriorArgs {
    /// Robot file (D-H TOML or URDF).
    #[arg(long)]
    pub robot: PathBuf,
    /// Run directory whose measured positions (run.csv y*) are the workspace [default: random
    /// positions within the joint limits].
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Random positions when no --data.
    #[arg(long, default_value_t = identify::LIMIT_SAMPLES)]
    pub samples: usize,
    /// Print JSON (keys m1, m2, positions).
    #[arg(long)]
    pub json: bool,
}

/// Options of `evoloop rkgnn study`: the paper's Section 5 on a 3-joint arm.
#[derive(Args)]
pub struct StudyArgs {
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// A 3-joint arm (D-H TOML or URDF); any other arm: `evoloop rkgnn selection --robot FILE`.
    #[arg(long, default_value = "config/robots/arm3.toml")]
    pub robot: PathBuf,
    /// Measurement-noise seed of every run, and the EA's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// EA evaluations after the least-squares start; 0 keeps the start (the shipped models'
    /// recipe).
    #[arg(long, default_value_t = 0)]
    pub evaluations: usize,
    /// Levenberg-Marquardt steps on the free-run output error after the least-squares start
    /// (with --start least-squares; 0 = none).
    #[arg(long, default_value_t = 0)]
    pub refine: usize,
    /// What the identification knows of the training runs' P-D servo: `known` (its gains,
    /// the study's own servo; the shipped models' recipe) or `unknown` (the paper's premise:
    /// gains identified, scale from eq. 2).
    #[arg(long, value_enum, default_value_t = StudyServo::Known)]
    pub servo: StudyServo,
    /// Half width of the identification's low-pass, s (as `identify rkgnn --smoothing`).
    #[arg(long, default_value_t = evoloop_rkgnn::SMOOTHING,
          value_parser = |s: &str| crate::args::seconds_in(s, 10.0))]
    pub smoothing: f64,
    /// The joint velocity the training servo and every tracking law act on: `filtered` (the
    /// measured positions differenced and low-passed at 50 Hz, as a drive does) or `true` (the
    /// simulator's velocities, an ideal sensor no plant has: the figures before 2026-12-03).
    #[arg(long, value_parser = crate::choice::choice(&JointVelocity::ALL, JointVelocity::key), default_value = "filtered")]
    pub joint_velocity: JointVelocity,
    /// Where the EA starts: `least-squares` (the shipped models' recipe) or `random` (the
    /// paper's: a stiff critically damped servo, every other weight 0, the population about
    /// it; give --evaluations).
    #[arg(long, value_parser = crate::choice::choice(&evoloop_rkgnn::model::Start::ALL, evoloop_rkgnn::model::Start::name), default_value = "least-squares")]
    pub start: evoloop_rkgnn::model::Start,
    /// Threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print study.json to stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Options of `evoloop rkgnn eval`: an identified model and the state to evaluate it at.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct EvalArgs {
    /// Model file (from `evoloop identify rkgnn`).
    #[arg(long)]
    pub model: PathBuf,
    /// Joint positions, comma separated (rad).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub q: Vec<f64>,
    /// Joint velocities [default: zeros].
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub qd: Option<Vec<f64>>,
    /// Print JSON (keys M_hat, V_hat, G_hat, min_eig_m_hat).
    #[arg(long)]
    pub json: bool,
}

/// The known servo: --kp and --kd if given, else the run's scenario.json controller (a
/// pd_servo's gains = [kp..., kd...], its torque limits and the velocity it acted on).
fn known_servo(a: &IdentifyArgs) -> Result<ServoPrior, String> {
    if let (Some(kp), Some(kd)) = (&a.kp, &a.kd) {
        return Ok(ServoPrior::Known {
            kp: kp.clone(),
            kd: kd.clone(),
            limits: None,
            velocity_cutoff_hz: a.servo_velocity_cutoff_hz,
        });
    }
    if a.kp.is_some() || a.kd.is_some() {
        return Err("--servo known: give both --kp and --kd, or neither".into());
    }
    let p = a.data.join("scenario.json");
    let text = evoloop_files::read_text(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))?;
    let c = &v["controller"];
    if c["kind"] != "pd_servo" {
        return Err(format!(
            "{}: the run's controller is {}, not a pd_servo (give --kp and --kd)",
            p.display(),
            c["kind"]
        ));
    }
    let list =
        |key: &str| -> Option<Vec<f64>> { c[key].as_array()?.iter().map(|x| x.as_f64()).collect() };
    let (Some(gains), limits) = (list("gains"), list("torque_limits")) else {
        return Err(format!(
            "{}: controller.gains is not a list of numbers",
            p.display()
        ));
    };
    // No key: a run from before the servo had a velocity choice, on the true velocity.
    let velocity_cutoff_hz = match &c["velocity"] {
        serde_json::Value::Null => None,
        serde_json::Value::String(s) if s == "true" => None,
        v => Some(v["filtered"]["cutoff_hz"].as_f64().ok_or_else(|| {
            format!(
                "{}: controller.velocity is {v}, not \"true\" or a filter's cutoff",
                p.display()
            )
        })?),
    };
    let n = gains.len() / 2;
    Ok(ServoPrior::Known {
        kp: gains[..n].to_vec(),
        kd: gains[n..].to_vec(),
        limits,
        velocity_cutoff_hz,
    })
}

/// `evoloop identify SUBCOMMAND`: run it and return the exit code (0, or 2 with the error on
/// stderr).
pub fn identify(cmd: IdentifyCmd) -> i32 {
    let a = match cmd {
        IdentifyCmd::Rkgnn(a) => a,
        IdentifyCmd::Base(b) => return super::identify_base::main(&b),
        IdentifyCmd::Excitation(e) => return super::identify_excitation::main(&e),
        IdentifyCmd::Lls(l) => return super::identify_lls::main(&l),
        IdentifyCmd::Study(s) => return super::identify_study::main(&s),
    };
    match identify_rkgnn(&a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop identify rkgnn: {e}");
            2
        }
    }
}

fn identify_rkgnn(a: &IdentifyArgs) -> Result<(), String> {
    if a.stride == 0 {
        return Err("--stride must be >= 1".into());
    }
    if a.start == Start::LeastSquares && a.servo == ServoKind::Rbf {
        return Err("--start least-squares needs --servo linear or known".into());
    }
    if a.servo == ServoKind::Known && a.start != Start::LeastSquares {
        return Err("--servo known needs --start least-squares".into());
    }
    if a.servo != ServoKind::Known && (a.kp.is_some() || a.kd.is_some()) {
        return Err("--kp and --kd go with --servo known".into());
    }
    if a.weigh_joints == Weighing::Always && a.servo != ServoKind::Known {
        return Err("--weigh-joints needs --servo known (it weighs the known torques)".into());
    }
    if a.evaluations == 0 && a.start != Start::LeastSquares {
        return Err("--evaluations must be >= 1 (0 only with --start least-squares)".into());
    }
    let prior = Prior::new(a.m1, a.m2).map_err(|e| format!("--m1, --m2: {e}"))?;
    let data = Trajectory::from_run(&a.data, a.smoothing).map_err(|e| e.to_string())?;
    let mut s = Settings::paper(data.n, a.seed, a.evaluations);
    s.stride = a.stride;
    s.start = a.start;
    s.refine = a.refine;
    s.weighing = a.weigh_joints;
    if a.servo != ServoKind::Rbf {
        s.counts = RbfCounts::linear_servo(data.n);
    }
    if a.servo == ServoKind::Known {
        s.servo = known_servo(a)?;
        s.servo
            .check(data.n)
            .map_err(|e| format!("--servo known: {e}"))?;
    }
    if a.velocity == VelocityKind::Christoffel {
        s.christoffel_velocity();
    }
    if let Some(t) = a.threads {
        s.threads = t.max(1);
    }
    let bar = evoloop_report::progress::bar(a.evaluations as u64, "evaluations", a.quiet || a.json);
    let model = identify::identify_model(
        &data,
        &prior,
        &s,
        a.data.display().to_string(),
        |evals, best| {
            bar.set_position(evals as u64);
            bar.set_message(format!("best J {best:.4}"));
        },
    )
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    model.save(&a.out).map_err(|e| e.to_string())?;
    let r = &model.report;
    if a.json {
        crate::print_json(r);
    } else {
        out!(
            "identified {} joints from {} in {:.1} s ({} evaluations, {} generations)",
            data.n,
            a.data.display(),
            r.seconds,
            r.evaluations,
            r.generations
        );
        let fmt = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.2e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        out!(
            "  free-run prediction rms per joint (rad): train [{}], holdout [{}]",
            fmt(&r.train_rms),
            fmt(&r.holdout_rms)
        );
        out!(
            "  M-hat: smallest eigenvalue over the training samples {:.4} (eq. 2's m1 {:.4}, m2 {:.4})",
            r.min_eig_m_hat,
            r.m1,
            r.m2
        );
        if r.weigh_joints {
            out!(
                "  each joint's equations weighed by its torque rms (--weigh-joints {})",
                r.weighing().name()
            );
        }
        out!("  wrote {}", a.out.display());
    }
    Ok(())
}

/// `evoloop rkgnn SUBCOMMAND`: run it and return the exit code (0, or 2 with the error on
/// stderr).
pub fn main(cmd: RkgnnCmd) -> i32 {
    let r = match cmd {
        RkgnnCmd::Eval(a) => eval(&a),
        RkgnnCmd::Study(a) => study(&a),
        RkgnnCmd::Prior(a) => prior(&a),
        RkgnnCmd::Selection(a) => selection(&a),
        RkgnnCmd::Zoo(a) => zoo(&a),
    };
    match r {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop rkgnn: {e}");
            2
        }
    }
}

fn eval(a: &EvalArgs) -> Result<(), String> {
    let m = RkgnnModel::load(&a.model).map_err(|e| e.to_string())?;
    let n = m.dof();
    let qd = a.qd.clone().unwrap_or_else(|| vec![0.0; n]);
    for (name, v) in [("q", &a.q), ("qd", &qd)] {
        if v.len() != n {
            return Err(format!("--{name} needs {n} values, got {}", v.len()));
        }
        if v.iter().any(|x| !x.is_finite()) {
            return Err(format!("--{name} has a non-finite value"));
        }
    }
    let mut mm = [0.0; evoloop_msg::MAX_JOINTS * evoloop_msg::MAX_JOINTS];
    let (mut v, mut g) = (vec![0.0; n], vec![0.0; n]);
    m.net.inertia_and_velocity(&a.q, &qd, &mut mm, &mut v);
    m.net.gravity(&a.q, &mut g);
    let rows: Vec<Vec<f64>> = (0..n).map(|i| mm[i * n..(i + 1) * n].to_vec()).collect();
    let min_eig = evoloop_linalg::sym_eig_range(n, &mm).0;
    if a.json {
        crate::print_json(&json!({
            "M_hat": rows, "V_hat": v, "G_hat": g, "min_eig_m_hat": min_eig,
        }));
    } else {
        out!("M_hat =");
        for r in &rows {
            out!(
                "  {}",
                r.iter().map(|x| format!("{x:>12.6}")).collect::<String>()
            );
        }
        out!("V_hat = {v:.6?}");
        out!("G_hat = {g:.6?}");
        out!("smallest eigenvalue of M_hat: {min_eig:.6}");
    }
    Ok(())
}

fn prior(a: &PriorArgs) -> Result<(), String> {
    let arm =
        evoloop_dynamics::load(&a.robot).map_err(|e| format!("{}: {e}", a.robot.display()))?;
    let n = arm.dof();
    let (p, positions) = match &a.data {
        Some(dir) => {
            let d =
                Trajectory::from_run(dir, evoloop_rkgnn::SMOOTHING).map_err(|e| e.to_string())?;
            if d.n != n {
                return Err(format!(
                    "{} has {n} joints, the data {}",
                    a.robot.display(),
                    d.n
                ));
            }
            let qs = d.x.chunks(2 * n).map(|x| &x[..n]);
            (Prior::of_model(&arm, qs), d.len())
        }
        None => {
            if a.samples == 0 {
                return Err("--samples must be >= 1".into());
            }
            let qs = identify::limit_positions(&arm, a.samples);
            (
                Prior::of_model(&arm, qs.iter().map(Vec::as_slice)),
                qs.len(),
            )
        }
    };
    if a.json {
        crate::print_json(&json!({"m1": p.m1, "m2": p.m2, "positions": positions}));
    } else {
        out!(
            "eq. 2's bounds of {} over {positions} positions: --m1 {:.6} --m2 {:.6}",
            a.robot.display(),
            p.m1,
            p.m2
        );
    }
    Ok(())
}

/// `run` with a progress bar of `unit` (hidden when `quiet`) fed by its progress callback.
fn with_bar<T>(
    unit: &str,
    quiet: bool,
    run: impl FnOnce(&(dyn Fn(u64, u64, &str) + Sync)) -> Result<T, String>,
) -> Result<T, String> {
    let bar = evoloop_report::progress::bar(0, unit, quiet);
    let r = run(&|done, total, stage| {
        bar.set_length(total);
        bar.set_position(done);
        bar.set_message(stage.to_string());
    });
    bar.finish_and_clear();
    r
}

/// The selection study's settings of `a` on `robot`.
fn selection_settings(
    a: &StudySettingsArgs,
    robot: PathBuf,
) -> evoloop_identify::rkgnn::selection::SelectionSettings {
    evoloop_identify::rkgnn::selection::SelectionSettings {
        robot,
        seeds: a.seeds,
        weighing: a.weigh_joints,
        christoffel: a.velocity == VelocityKind::Christoffel,
        servo_known: a.servo == StudyServo::Known,
        start: a.start,
        evaluations: a.evaluations,
        period: a.period,
        models_from: a.models_from.clone(),
        velocity: a.joint_velocity,
        threads: a.threads.unwrap_or_else(evoloop_optim::all_cores),
    }
}

fn selection(args: &SelectionArgs) -> Result<(), String> {
    use evoloop_identify::rkgnn::selection;
    let robot = (args.robot.clone()).unwrap_or_else(|| PathBuf::from("config/robots/arm3.toml"));
    let a = &args.study;
    let settings = selection_settings(a, robot);
    let r = with_bar("runs", a.quiet || a.json, |p| {
        selection::run(&settings, &a.out, p).map_err(|e| e.to_string())
    })?;
    if a.json {
        crate::print_json(&r);
    } else {
        out!("{}", selection::report_markdown(&r));
        out!("wrote {}/{{selection.json, report.md}}", a.out.display());
    }
    Ok(())
}

fn zoo(a: &ZooArgs) -> Result<(), String> {
    use evoloop_identify::rkgnn::{selection, zoo};
    let t0 = std::time::Instant::now();
    let sel = &a.selection;
    let arms: Vec<_> = (crate::robot::read_zoo(&a.zoo)?.into_iter())
        .filter(|arm| a.joints.is_empty() || a.joints.contains(&arm.joints.len()))
        .collect();
    if arms.is_empty() {
        return Err(format!(
            "{}: no arm with --joints {:?}",
            a.zoo.display(),
            a.joints
        ));
    }
    let dir = sel.out.join("arms");
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot make {}: {e}", dir.display()))?;
    let mut lines = Vec::new();
    for (i, arm) in arms.iter().enumerate() {
        let file = dir.join(format!("{}.urdf", arm.name));
        evoloop_files::write(&file, arm.to_urdf())
            .map_err(|e| format!("{}: {e}", file.display()))?;
        let mut settings = selection_settings(sel, file);
        settings.models_from = sel.models_from.as_ref().map(|d| d.join(&arm.name));
        let label = format!("{} ({} of {})", arm.name, i + 1, arms.len());
        let r = with_bar(&label, sel.quiet || sel.json, |p| {
            selection::run(&settings, &sel.out.join(&arm.name), p).map_err(|e| e.to_string())
        })?;
        let line = zoo::arm_line(&arm.name, &r);
        if !sel.quiet && !sel.json {
            out!(
                "{}: {} joints, {:.0} s",
                line.arm,
                line.joints,
                line.seconds
            );
        }
        lines.push(line);
    }
    let result = zoo::ZooResult {
        zoo: a.zoo.clone(),
        seeds: sel.seeds,
        tallies: zoo::tallies(&lines),
        arms: lines,
        seconds: t0.elapsed().as_secs_f64(),
    };
    zoo::write(&sel.out, &result).map_err(|e| e.to_string())?;
    if sel.json {
        crate::print_json(&result);
    } else {
        out!("{}", zoo::report_markdown(&result));
        out!("wrote {}/{{zoo.json, zoo.md}}", sel.out.display());
    }
    Ok(())
}

fn study(a: &StudyArgs) -> Result<(), String> {
    use evoloop_identify::rkgnn::study;
    let settings = study::StudySettings {
        robot: a.robot.clone(),
        seed: a.seed,
        evaluations: a.evaluations,
        refine: a.refine,
        servo_known: a.servo == StudyServo::Known,
        start: a.start,
        smoothing: a.smoothing,
        velocity: a.joint_velocity,
        threads: a.threads.unwrap_or_else(evoloop_optim::all_cores),
    };
    let r = with_bar("stages", a.quiet || a.json, |p| {
        study::run(&settings, &a.out, p).map_err(|e| e.to_string())
    })?;
    if a.json {
        crate::print_json(&r);
        return Ok(());
    }
    out!(
        "RKGNN study on {} (seed {}, {:.1} s): RMS tracking error on the new trajectory, rad",
        r.robot.display(),
        r.seed,
        r.seconds
    );
    out!(
        "  {:<18} {:>9} {:>9} {:>9}",
        "controller",
        "joint 1",
        "joint 2",
        "joint 3"
    );
    for (_, label, v) in r.tracking_rms.entries() {
        out!("  {label:<18} {:>9.4} {:>9.4} {:>9.4}", v[0], v[1], v[2]);
    }
    out!(
        "  wrote {}/{{study.json, tracking_rms.csv, report.md, fig7..fig10 PNG}}",
        a.out.display()
    );
    Ok(())
}
