//! An identified RKGNN model as a file (`evoloop identify rkgnn --out MODEL.json`): the network's
//! shape and parameters, the reference it was identified on (the fuzzy selector's premise z_i,
//! eq. 17) and the identification's report. Loading checks everything a controller relies on.

use crate::network::{Layout, Network, RbfCounts};
use evoloop_msg::MAX_JOINTS;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What an identification reports (`evoloop identify rkgnn --json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Report {
    /// Free-run prediction error over the training window, RMS per joint, rad.
    pub train_rms: Vec<f64>,
    /// The same over the held-out end of the data, predicted from its first measured state.
    pub holdout_rms: Vec<f64>,
    /// Smallest eigenvalue of M-hat over every training sample.
    pub min_eig_m_hat: f64,
    /// Objective evaluations the EA made (0: the start kept, `--evaluations 0`).
    pub evaluations: usize,
    /// Wall-clock time the identification took, s.
    pub seconds: f64,
    /// EA generations run.
    pub generations: usize,
    /// Eq. 13 at the end (with the last generation's s_t).
    pub objective: f64,
    /// The RKGNN's step, s.
    pub h: f64,
    /// Eq. 2's bounds, the identification's only knowledge of the arm besides the data.
    pub m1: f64,
    /// Eq. 2's upper bound: y^T M(q) y <= m_2 ||y||^2 (`m1` is the lower one).
    pub m2: f64,
    /// Where the search started.
    #[serde(default = "Report::random")]
    pub start: Start,
    /// What the identification knew of the servo (files before it: unknown).
    #[serde(default)]
    pub servo: ServoPrior,
    /// Whether the fit weighed each joint's equations by its torque rms (by `weighing`, or
    /// as needed because the unweighted fit found no positive definite M-hat).
    #[serde(default)]
    pub weigh_joints: bool,
    /// When the identification was to weigh them (`Settings::weighing`). None: a file from
    /// before 2026-12-06, whose `weigh_joints` was the setting (always or never).
    #[serde(default)]
    pub weighing: Option<Weighing>,
    /// Half width of the low-pass the joint velocities were estimated with from the measured
    /// positions, s. None: a file from before that, fitted on the simulator's velocities.
    #[serde(default)]
    pub velocity_smoothing: Option<f64>,
    /// Seed of the evolutionary algorithm (`identify rkgnn --seed`).
    pub seed: u64,
    /// Best objective after each generation.
    pub history: Vec<f64>,
}

impl Report {
    /// Reports written before `start` existed came from the paper's start.
    fn random() -> Start {
        Start::Random
    }

    /// When the identification was to weigh the joints' equations; a file from before
    /// `weighing` existed either always did (`weigh_joints`) or never.
    pub fn weighing(&self) -> Weighing {
        self.weighing.unwrap_or(if self.weigh_joints {
            Weighing::Always
        } else {
            Weighing::Never
        })
    }
}

/// When the known-servo least squares weighs each joint's equations by 1 / that joint's torque
/// rms. Unweighted, the equations are in N m and the shoulder's residuals (tens of N m) decide
/// the fit: a wrist carrying a hundredth of that torque is left to round-off and M-hat comes out
/// indefinite (arm7; the zoo's 4-joint arms, whose wrist pitch has 650-3 500 times less inertia
/// than the shoulder). Weighed, each joint is fitted as closely relative to its own torque, at
/// the price of the noise on the small ones (on 3-joint arms whose unweighted fit is fine, it
/// costs models).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Weighing {
    /// Every equation in N m (the recipe before 2026-12-06).
    Never,
    /// In N m; weighed only where that finds no positive definite M-hat (the shipped recipe).
    #[default]
    AsNeeded,
    /// Always weighed (what arm7 needs).
    Always,
}

impl Weighing {
    /// Every policy, as `--weigh-joints` lists them.
    pub const ALL: [Weighing; 3] = [Weighing::Never, Weighing::AsNeeded, Weighing::Always];

    /// Its name as the command line and the model file spell it.
    pub fn name(self) -> &'static str {
        match self {
            Weighing::Never => "never",
            Weighing::AsNeeded => "as-needed",
            Weighing::Always => "always",
        }
    }
}

/// What the identification knows of the servo that ran the training experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum ServoPrior {
    /// Nothing (the paper's premise: an industrial arm's servo is the vendor's): a linear
    /// servo's gains are identified in units of joint 1's k_p and the model is given eq. 2's
    /// scale. Torque-free data cannot fix the relative scale of joints whose inertia does not
    /// couple (the book, "RKGNN").
    #[default]
    Unknown,
    /// The P-D law tau_j = clamp(k_p,j e_j + k_d,j e_j', +-limit_j) with these gains and
    /// limits: the controller's own configuration when the experiment ran under the user's
    /// servo (the paper allows it: "if detailed information of the controller is known, the
    /// structure of the network can be altered accordingly"). Then the servo's torque is known
    /// at every sample and the arm's M-hat, V-hat, G-hat are fitted to it, scale included.
    Known {
        /// Proportional gain k_p,j per joint, N m/rad.
        kp: Vec<f64>,
        /// Derivative gain k_d,j per joint, N m s/rad.
        kd: Vec<f64>,
        /// Torque limits, N m (none = unclamped).
        #[serde(default)]
        limits: Option<Vec<f64>>,
        /// The cutoff of the drive's velocity filter the servo's k_d acted on (the measured
        /// positions differenced and low-passed, a servo's `velocity = "filtered"`), Hz; none:
        /// the joint velocity itself (an ideal sensor, as in the runs before 2026-12-03). Known
        /// to the least-squares start only: the network's free run, which the EA and the
        /// refinement judge a model by, applies k_d to the velocity itself (not yet the filter).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        velocity_cutoff_hz: Option<f64>,
    },
}

impl ServoPrior {
    /// The known servo's torque at reference `r` and state `x` (n each of position and
    /// velocity), or None if unknown.
    pub fn torque(&self, r: &[f64], x: &[f64], tau: &mut [f64]) -> Option<()> {
        let ServoPrior::Known { kp, kd, limits, .. } = self else {
            return None;
        };
        let n = kp.len();
        for j in 0..n {
            let t = kp[j] * (r[j] - x[j]) + kd[j] * (r[n + j] - x[n + j]);
            tau[j] = limits.as_ref().map_or(t, |l| t.clamp(-l[j], l[j]));
        }
        Some(())
    }

    /// Checked against the data's joint count: finite, k_p > 0, k_d >= 0, limits > 0.
    pub fn check(&self, n: usize) -> Result<(), ServoError> {
        let ServoPrior::Known {
            kp,
            kd,
            limits,
            velocity_cutoff_hz,
        } = self
        else {
            return Ok(());
        };
        if kp.len() != n || kd.len() != n || limits.as_ref().is_some_and(|l| l.len() != n) {
            return Err(ServoError::Counts(n));
        }
        let ok = kp.iter().all(|v| v.is_finite() && *v > 0.0)
            && kd.iter().all(|v| v.is_finite() && *v >= 0.0)
            && limits.iter().flatten().all(|v| *v > 0.0);
        if !ok {
            return Err(ServoError::Gains);
        }
        match velocity_cutoff_hz {
            Some(fc) if !(fc.is_finite() && *fc > 0.0) => Err(ServoError::Cutoff(*fc)),
            _ => Ok(()),
        }
    }
}

/// A known servo `ServoPrior::check` refuses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ServoError {
    /// Gains or limits not one per joint (the joint count).
    Counts(usize),
    /// A k_p not above 0, a k_d below 0, a limit not above 0, or a value not finite.
    Gains,
    /// A velocity cutoff that is not a positive frequency (the value given, Hz).
    Cutoff(f64),
}

impl std::fmt::Display for ServoError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ServoError::Counts(n) => write!(
                f,
                "the servo's gains and limits need {n} values each (one per joint)"
            ),
            ServoError::Gains => {
                f.write_str("the servo needs k_p > 0, k_d >= 0 and limits > 0, all finite")
            }
            ServoError::Cutoff(fc) => write!(
                f,
                "the servo's velocity cutoff must be a positive frequency (got {fc} Hz)"
            ),
        }
    }
}

impl std::error::Error for ServoError {}

/// The EA's starting point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Start {
    /// The paper's: `initial` (a stiff critically damped servo, every other weight 0) and a
    /// population scattered about it.
    Random,
    /// `least_squares_start` (linear servo only), the population close about it.
    LeastSquares,
}

impl Start {
    /// Both starts, as `--start` lists them.
    pub const ALL: [Start; 2] = [Start::Random, Start::LeastSquares];

    /// Its name as the command line and the model file spell it.
    pub fn name(self) -> &'static str {
        match self {
            Start::Random => "random",
            Start::LeastSquares => "least-squares",
        }
    }
}

/// Why a model file was not read, written or accepted.
#[derive(Debug)]
pub enum ModelError {
    /// Reading or writing the file failed: the system's error (or the JSON writer's).
    Io(std::io::Error),
    /// Not a model file this build reads: not its JSON layout (the key path in the reason),
    /// another format or another version.
    NotAModelFile(String),
    /// Values that make no model: counts, non-finite values, premise rows.
    Invalid(String),
    /// M-hat is not positive definite on the model's own trajectory: its smallest eigenvalue.
    Indefinite(f64),
    /// The error of the file at this path.
    In(std::path::PathBuf, Box<ModelError>),
}

impl ModelError {
    fn at(self, path: &Path) -> Self {
        ModelError::In(path.to_path_buf(), Box::new(self))
    }
}

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ModelError::Io(e) => e.fmt(f),
            ModelError::NotAModelFile(e) | ModelError::Invalid(e) => f.write_str(e),
            ModelError::Indefinite(lo) => write!(
                f,
                "M-hat is not positive definite on its own trajectory (smallest eigenvalue {lo:.3e})"
            ),
            ModelError::In(path, e) => write!(f, "{}: {e}", path.display()),
        }
    }
}

impl std::error::Error for ModelError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Reads as the system's error: its source is that error's.
            ModelError::Io(e) => e.source(),
            ModelError::In(_, e) => Some(&**e),
            _ => None,
        }
    }
}

/// The `format` value of a model file.
pub const FORMAT: &str = "evoloop-rkgnn";
/// The file layout version this build reads and writes.
pub const VERSION: u32 = 1;

/// A model file's JSON layout, as `RkgnnModel::save` writes it and `RkgnnModel::load` reads
/// it before checking it (`RkgnnModel::from_file`).
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Always `FORMAT`; anything else is refused as not a model file.
    pub format: String,
    /// File layout version; must be `VERSION`.
    pub version: u32,
    /// Joint count n of the arm, 1..=`MAX_JOINTS`.
    pub joints: usize,
    /// RBF counts per sub-network; with `joints` they fix the `Layout` of `params`.
    pub rbf: RbfCounts,
    /// N_f's parameters in `network::Layout` order.
    pub params: Vec<f64>,
    /// Spacing of `premise`, s.
    pub premise_period: f64,
    /// The identification reference, one row [theta_d; theta_d'] per `premise_period` from t = 0.
    pub premise: Vec<Vec<f64>>,
    /// Where the data came from (a run directory or a study).
    pub source: String,
    /// The identification's report, kept with the model it produced.
    pub report: Report,
}

/// A loaded, checked model.
#[derive(Debug, Clone)]
pub struct RkgnnModel {
    /// The identified function network N_f.
    pub net: Network,
    /// Spacing of the premise rows, s.
    pub premise_period: f64,
    /// Premise rows, flat (2n each).
    pub premise: Vec<f64>,
    /// Where the training data came from (a run directory or a study).
    pub source: String,
    /// The identification's report.
    pub report: Report,
}

impl RkgnnModel {
    /// The model `net`, with its premise: the identification reference [theta_d; theta_d'],
    /// flat rows of 2n values every `premise_period` s from t = 0.
    pub fn new(
        net: Network,
        premise_period: f64,
        premise: Vec<f64>,
        source: String,
        report: Report,
    ) -> Self {
        Self {
            net,
            premise_period,
            premise,
            source,
            report,
        }
    }

    /// Joint count n.
    pub fn dof(&self) -> usize {
        self.net.dof()
    }

    /// Premise samples.
    pub fn premise_len(&self) -> usize {
        self.premise.len() / (2 * self.dof())
    }

    /// z_i at time t (eq. 17): the identification reference at the nearest sample, held after
    /// its end.
    pub fn premise_at(&self, t: f64) -> &[f64] {
        let w = 2 * self.dof();
        let i = ((t / self.premise_period).round().max(0.0) as usize).min(self.premise_len() - 1);
        &self.premise[w * i..w * (i + 1)]
    }

    /// Smallest eigenvalue of M-hat over `qs`: > 0 means positive definite there.
    pub fn min_eig<'a>(&self, qs: impl Iterator<Item = &'a [f64]>) -> f64 {
        self.net.min_eig(qs)
    }

    /// The model in its file layout, the premise back in rows of 2n values.
    pub fn to_file(&self) -> ModelFile {
        let w = 2 * self.dof();
        ModelFile {
            format: FORMAT.into(),
            version: VERSION,
            joints: self.dof(),
            rbf: self.net.layout.counts,
            params: self.net.params().to_vec(),
            premise_period: self.premise_period,
            premise: self.premise.chunks(w).map(<[f64]>::to_vec).collect(),
            source: self.source.clone(),
            report: self.report.clone(),
        }
    }

    /// Write the model to `path` as pretty-printed JSON, whole or not at all
    /// (`evoloop_files::write`). Fails with `ModelError::In(path, Io(..))`.
    pub fn save(&self, path: &Path) -> Result<(), ModelError> {
        let s = serde_json::to_string_pretty(&self.to_file())
            .map_err(|e| ModelError::Io(e.into()).at(path))?;
        evoloop_files::write(path, s + "\n").map_err(|e| ModelError::Io(e).at(path))
    }

    /// Read and check a model file: format and version, joint count, parameter count, finite
    /// values, premise rows of 2n values, M-hat positive definite on the premise positions.
    pub fn load(path: &Path) -> Result<RkgnnModel, ModelError> {
        let text = evoloop_files::read_text_up_to(path, evoloop_files::MAX_DATA_BYTES)
            .map_err(|e| ModelError::Io(e).at(path))?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        let f: ModelFile = serde_path_to_error::deserialize(de).map_err(|e| {
            ModelError::NotAModelFile(format!("{} ({})", e.inner(), e.path())).at(path)
        })?;
        Self::from_file(f).map_err(|e| e.at(path))
    }

    /// Check a decoded model file as `load` does (format and version, joint and parameter
    /// counts, finite values, premise rows of 2n values, M-hat positive definite on the premise
    /// positions) and build the model from it. The errors name no path.
    pub fn from_file(f: ModelFile) -> Result<RkgnnModel, ModelError> {
        use ModelError::{Invalid, NotAModelFile};
        if f.format != FORMAT {
            let got = f.format;
            return Err(NotAModelFile(format!(
                "format is {got:?}, expected {FORMAT:?}"
            )));
        }
        if f.version != VERSION {
            let got = f.version;
            return Err(NotAModelFile(format!(
                "version {got} (this build reads {VERSION})"
            )));
        }
        let n = f.joints;
        if !(1..=MAX_JOINTS).contains(&n) {
            return Err(Invalid(format!("joints: {n} (1..={MAX_JOINTS})")));
        }
        let layout = Layout::new(n, f.rbf);
        if f.params.len() != layout.len {
            return Err(Invalid(format!(
                "params: {} values, the network needs {}",
                f.params.len(),
                layout.len
            )));
        }
        if let Some(i) = f.params.iter().position(|v| !v.is_finite()) {
            return Err(Invalid(format!("params[{i}] is not finite")));
        }
        if !(f.premise_period > 0.0 && f.premise_period.is_finite()) {
            return Err(Invalid("premise_period must be > 0".into()));
        }
        if f.premise.is_empty() {
            return Err(Invalid("premise is empty".into()));
        }
        let mut premise = Vec::with_capacity(2 * n * f.premise.len());
        for (i, row) in f.premise.iter().enumerate() {
            if row.len() != 2 * n || row.iter().any(|v| !v.is_finite()) {
                return Err(Invalid(format!(
                    "premise[{i}]: needs {} finite values",
                    2 * n
                )));
            }
            premise.extend_from_slice(row);
        }
        let m = RkgnnModel {
            net: Network::new(layout, f.params),
            premise_period: f.premise_period,
            premise,
            source: f.source,
            report: f.report,
        };
        let w = 2 * n;
        let lo = m.min_eig(m.premise.chunks(w).map(|r| &r[..n]));
        if lo.is_nan() || lo <= 0.0 {
            return Err(ModelError::Indefinite(lo));
        }
        Ok(m)
    }
}
