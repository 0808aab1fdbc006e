//! Linear least squares on a periodic excitation run (the eMuPSO paper, eqs. 11-13).
//!
//! What a real robot gives: joint positions from the encoders (the run's measured `y*`, with the
//! plant's `noise_std`) and torques from the motor currents (the commands `u*`, optionally with
//! added measurement noise). The velocities and accelerations are not measured; as in Swevers
//! et al. the run is periodic, so
//! 1. the first `skip` periods are dropped (the controller's start-up), the last full period is
//!    held out for validation and the others are averaged sample by sample (noise falls as
//!    1 / sqrt(periods));
//! 2. the averaged positions are expanded in their first `harmonics` Fourier harmonics (a
//!    band-limited, phase-free filter) and differentiated analytically, evaluated half a sample
//!    after each instant, where the zero-order-held torque of that instant acts;
//! 3. the stage's base regressor W_b at those states and the averaged torques give
//!    beta = argmin |W_b beta - tau| (SVD), compared with the base values of the robot file's
//!    own parameters (the simulated arm's truth).
//!
//! The held-out period is processed the same way on its own (no averaging) and its torques
//! predicted with the estimate: the validation RMS per joint.

use super::{stage_base, states_needed, Columns, Stacker, Stage};
use crate::dynamics::Model;
use crate::reference::series::FourierSeries;
use crate::report::Outcome;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Why a periodic run cannot be read, or its parameters estimated from it.
#[derive(Debug)]
pub enum LlsError {
    /// A file of the run directory (scenario.json, run.csv) is missing, unreadable or lacks
    /// what the estimate needs.
    RunFile {
        /// The file.
        file: PathBuf,
        /// What is wrong with it.
        reason: String,
        /// The system's or the parser's error, where there is one.
        source: Option<Box<dyn std::error::Error + Send + Sync>>,
    },
    /// The run's reference is not a periodic excitation (`file`: the run's scenario.json, if
    /// the run was read from one).
    NotExcitation(Option<PathBuf>),
    /// The excitation's period is not a whole number of samples.
    Period {
        /// The period, s.
        period: f64,
        /// The sample interval, s.
        h: f64,
    },
    /// The run's joints are not the robot's.
    Joints {
        /// The run's joints.
        run: usize,
        /// The robot's name.
        robot: String,
        /// Its degrees of freedom.
        dof: usize,
    },
    /// Fewer full periods than the options need.
    Periods {
        /// The full periods recorded.
        recorded: usize,
        /// The period, s.
        period: f64,
        /// The periods skipped at the start.
        skip: usize,
    },
    /// No joint moves in the run.
    NoMotion,
    /// The least-squares solve failed (the SVD's reason).
    Solve(&'static str),
}

impl LlsError {
    fn run_file(file: &Path, reason: impl Into<String>) -> Self {
        LlsError::RunFile {
            file: file.to_path_buf(),
            reason: reason.into(),
            source: None,
        }
    }

    fn run_file_from(
        file: &Path,
        reason: impl Into<String>,
        e: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        LlsError::RunFile {
            file: file.to_path_buf(),
            reason: reason.into(),
            source: Some(Box::new(e)),
        }
    }
}

impl std::fmt::Display for LlsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LlsError::RunFile {
                file,
                reason,
                source,
            } => {
                write!(f, "{}: {reason}", file.display())?;
                match source {
                    Some(e) if reason.is_empty() => write!(f, "{e}"),
                    Some(e) => write!(f, ": {e}"),
                    None => Ok(()),
                }
            }
            LlsError::NotExcitation(Some(file)) => write!(
                f,
                "{}: the run's reference is not a periodic excitation (a `sines` reference \
                 with frequencies 1/T, 2/T, ...; see `evoloop identify excitation`)",
                file.display()
            ),
            LlsError::NotExcitation(None) => {
                f.write_str("the scenario's reference is not a periodic excitation")
            }
            LlsError::Period { period, h } => write!(
                f,
                "the period {period} s is not a whole number of {h} s samples"
            ),
            LlsError::Joints { run, robot, dof } => {
                write!(f, "the run has {run} joints, the robot {robot} has {dof}")
            }
            LlsError::Periods {
                recorded,
                period,
                skip,
            } => write!(
                f,
                "{recorded} full period(s) of {period} s recorded: need {} (skip {skip}, at \
                 least one to average and one to validate on)",
                skip + 2
            ),
            LlsError::NoMotion => f.write_str("no joint moves in the run"),
            LlsError::Solve(e) => write!(f, "the least-squares solve failed: {e}"),
        }
    }
}

impl std::error::Error for LlsError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LlsError::RunFile {
                source: Some(e), ..
            } => Some(e.as_ref()),
            _ => None,
        }
    }
}

/// A periodic run: its sampling, period, which joints moved and the records.
#[derive(Debug, Clone)]
pub struct Recording {
    /// Sample interval, s.
    pub h: f64,
    /// The excitation's period, s.
    pub period: f64,
    /// Per joint, whether the excitation moves it (a non-zero coefficient in the reference).
    pub moving: Vec<bool>,
    /// Held joints' positions (the reference offsets).
    pub hold: Vec<f64>,
    /// Measured positions and torques, one vector per joint.
    pub y: Vec<Vec<f64>>,
    /// Torques, one vector per joint, N m: the commands `u*` (a real robot's motor currents).
    pub u: Vec<Vec<f64>>,
}

impl Recording {
    /// A run directory's run.csv (`t`, `y*`, `u*`) and scenario.json (the reference: a
    /// harmonic `sines` reference, e.g. from `evoloop identify excitation`).
    pub fn from_run(dir: &Path) -> Result<Recording, LlsError> {
        let sj = dir.join("scenario.json");
        let text = crate::files::read_text(&sj)
            .map_err(|e| LlsError::run_file_from(&sj, "cannot read", e))?;
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| LlsError::run_file_from(&sj, "", e))?;
        let reference: crate::reference::Reference = serde_json::from_value(v["reference"].clone())
            .map_err(|e| LlsError::run_file_from(&sj, "reference", e))?;
        let series = FourierSeries::from_reference(&reference)
            .ok_or_else(|| LlsError::NotExcitation(Some(sj.clone())))?;
        let csv = dir.join("run.csv");
        let t =
            crate::report::Table::read(&csv).map_err(|e| LlsError::run_file_from(&csv, "", e))?;
        let n = series.joints();
        let col = |name: String| {
            t.col(&name)
                .ok_or_else(|| LlsError::run_file(&csv, format!("no column `{name}`")))
        };
        let time = col("t".into())?;
        if time.len() < 3 {
            return Err(LlsError::run_file(&csv, "fewer than 3 samples"));
        }
        let y: Vec<Vec<f64>> = (0..n)
            .map(|j| col(format!("y{j}")))
            .collect::<Result<_, _>>()?;
        let u: Vec<Vec<f64>> = (0..n)
            .map(|j| col(format!("u{j}")))
            .collect::<Result<_, _>>()?;
        let h = v["timing"]["period"]
            .as_f64()
            .filter(|h| *h > 0.0)
            .unwrap_or(time[1] - time[0]);
        // A run that ended normally ran its plant to the scenario's duration: a cycle the
        // controller missed at the very end (realtime, a loaded machine) is a gap at the tail.
        let ended = crate::files::read_text(&dir.join("summary.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
            .and_then(|s| serde_json::from_value::<Outcome>(s["outcome"].clone()).ok())
            == Some(Outcome::Ok);
        let until = v["timing"]["duration"].as_f64().filter(|_| ended);
        let (y, u) = regular(&time, h, until, &y, &u);
        Ok(Recording {
            h,
            period: series.period,
            moving: (0..n).map(|j| series.moves(j)).collect(),
            hold: series.offsets.clone(),
            y,
            u,
        })
    }

    /// An in-process simulation of `scn` (`sim::simulate`): the same columns a run logs.
    pub fn from_sim(
        scn: &crate::config::Scenario,
        sim: &crate::sim::SimResult,
    ) -> Result<Recording, LlsError> {
        let series =
            FourierSeries::from_reference(&scn.reference).ok_or(LlsError::NotExcitation(None))?;
        let n = series.joints();
        Ok(Recording {
            h: scn.timing.period,
            period: series.period,
            moving: (0..n).map(|j| series.moves(j)).collect(),
            hold: series.offsets.clone(),
            y: (0..n)
                .map(|j| sim.rows.iter().map(|r| r.state.y[j]).collect())
                .collect(),
            u: (0..n)
                .map(|j| sim.rows.iter().map(|r| r.telemetry.u[j]).collect())
                .collect(),
        })
    }

    /// The first `periods` periods only.
    pub fn truncated(&self, periods: usize) -> Result<Recording, LlsError> {
        let keep = periods * self.per_period()?;
        let cut = |c: &Vec<Vec<f64>>| c.iter().map(|x| x[..keep.min(x.len())].to_vec()).collect();
        Ok(Recording {
            y: cut(&self.y),
            u: cut(&self.u),
            ..self.clone()
        })
    }

    /// Samples per period (the period must be a whole number of samples).
    pub fn per_period(&self) -> Result<usize, LlsError> {
        let m = (self.period / self.h).round();
        if m < 4.0 || (m * self.h - self.period).abs() > 1e-6 * self.period {
            return Err(LlsError::Period {
                period: self.period,
                h: self.h,
            });
        }
        Ok(m as usize)
    }

    /// Add Gaussian noise of `std` to the torques (seeded).
    pub fn add_torque_noise(&mut self, std: f64, seed: u64) {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let Ok(normal) = Normal::new(0.0, std) else {
            return;
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        for c in &mut self.u {
            for v in c.iter_mut() {
                *v += normal.sample(&mut rng);
            }
        }
    }
}

/// Rows stamped `time` put on the regular grid k h, k = 0, 1, ...: a realtime run's log has a
/// row per control cycle, stamped with the time of the state it used, so a cycle that ran late
/// leaves a gap and two cycles on the same state share a stamp. A shared stamp keeps the later
/// row (its command is the one the plant went on with); a gap takes the positions linearly
/// interpolated and the command held (the plant held it). The grid ends at the last row, or at
/// `until` (the run's duration, when it ran to its end) if that is later by at most
/// `MAX_TAIL_SAMPLES`: the tail gap holds the last positions and command (a longer tail is rows
/// the log lost, not to invent). Lockstep logs pass through unchanged.
fn regular(
    time: &[f64],
    h: f64,
    until: Option<f64>,
    y: &[Vec<f64>],
    u: &[Vec<f64>],
) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let last = time.iter().fold(0.0f64, |m, t| m.max(*t));
    let logged = (last / h).round() as usize + 1;
    let m = match until.map(|d| (d / h).round() as usize) {
        Some(end) if end > logged && end - logged <= MAX_TAIL_SAMPLES => end,
        _ => logged,
    };
    let mut at: Vec<Option<usize>> = vec![None; m];
    for (i, t) in time.iter().enumerate() {
        let k = (t / h).round();
        if k >= 0.0 && (k as usize) < m {
            at[k as usize] = Some(i);
        }
    }
    let n = y.len();
    let (mut yr, mut ur) = (vec![vec![0.0; m]; n], vec![vec![0.0; m]; n]);
    let first = at.iter().flatten().next().copied().unwrap_or(0);
    let mut prev: Option<usize> = None;
    for k in 0..m {
        if let Some(i) = at[k] {
            for j in 0..n {
                yr[j][k] = y[j][i];
                ur[j][k] = u[j][i];
            }
            prev = Some(k);
            continue;
        }
        // Between the last grid point filled and the next stamped row.
        let next = at[k..].iter().flatten().next().copied();
        for j in 0..n {
            let (a, ua) = match prev {
                Some(p) => (yr[j][p], ur[j][p]),
                None => (y[j][first], u[j][first]),
            };
            let w = match (prev, next) {
                (Some(p), Some(i)) => {
                    ((k - p) as f64 / (time[i] / h - p as f64).max(1.0)).clamp(0.0, 1.0)
                }
                _ => 0.0,
            };
            let b = next.map_or(a, |i| y[j][i]);
            yr[j][k] = a + (b - a) * w;
            ur[j][k] = ua;
        }
    }
    (yr, ur)
}

/// Missing samples at the end of a run that ended which `regular` fills by holding the last
/// row (cycles a loaded machine missed at the very end).
const MAX_TAIL_SAMPLES: usize = 10;

/// How the estimate is made.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Options {
    /// Periods dropped at the start.
    pub skip: usize,
    /// Fourier harmonics kept of the positions.
    pub harmonics: usize,
    /// Instants per period in the regression (the samples are thinned to about this many).
    pub instants: usize,
    /// The parameters estimated (the base parameters of these columns).
    pub columns: Columns,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            skip: 1,
            harmonics: 20,
            instants: 1000,
            columns: Columns::PLANT,
        }
    }
}

/// One stage's estimate.
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// The stage the run excited: `wrist`, `arm` or `all`.
    pub stage: String,
    /// Base parameter names and the relations regrouped into them.
    pub base: Vec<String>,
    /// Per base parameter, its relation: the parameter plus what is regrouped into it.
    pub regrouping: Vec<String>,
    /// The base values of the robot file's own parameters (the simulated arm's truth).
    pub base_true: Vec<f64>,
    /// The least-squares estimate of each base parameter.
    pub base_estimate: Vec<f64>,
    /// |estimate - true| / |true| per base parameter; None where the true value is zero (below
    /// 1e-9 of the largest: a parameter that is zero in the model, e.g. a product of inertia of
    /// a symmetric link), whose error is in `absolute_error`.
    pub relative_error: Vec<Option<f64>>,
    /// |estimate - true| per base parameter.
    pub absolute_error: Vec<f64>,
    /// |estimate - true| / |true| over the whole vector (2-norms).
    pub relative_error_norm: f64,
    /// Condition number of the (averaged) base regressor.
    pub cond: f64,
    /// Periods averaged.
    pub periods: usize,
    /// Per joint: RMS of measured - predicted torque on the held-out period (None: joint held).
    pub torque_rms_validation: Vec<Option<f64>>,
    /// Per joint: RMS of the measured torque on that period (the scale of the above).
    pub torque_rms_measured: Vec<Option<f64>>,
    /// With every joint moving: a full parameter vector (`Columns` order) with the same torques
    /// as the estimate everywhere — each base estimate on its own column, zero on the columns
    /// regrouped into it or unidentifiable. A computed-torque controller's model set
    /// (`ParamKind::RigidBodyModel`).
    #[serde(skip)]
    pub model_parameters: Option<Vec<f64>>,
    /// The held-out period: time, measured and predicted torque per moving joint (for plots).
    #[serde(skip)]
    pub validation: Validation,
}

/// The held-out period's torques for the validation plot: measured and predicted per
/// moving joint.
#[derive(Debug, Clone, Default)]
pub struct Validation {
    /// Time of each sample of the held-out period in the run, s.
    pub t: Vec<f64>,
    /// The moving joints' indices, one per entry of `measured` and `predicted`.
    pub joints: Vec<usize>,
    /// Per moving joint, the recorded torque at each sample, N m.
    pub measured: Vec<Vec<f64>>,
    /// Per moving joint, the torque the estimate predicts from the period's states, N m.
    pub predicted: Vec<Vec<f64>>,
}

/// Positions, velocities and accelerations of one period of samples `x` (uniform, `m` of them)
/// from its first `harmonics` Fourier harmonics, at the instants (k + 1/2) / m of the period,
/// as derivatives with respect to that phase (the caller divides by the period).
fn differentiate(x: &[f64], harmonics: usize) -> [Vec<f64>; 3] {
    let m = x.len();
    let s = FourierSeries::fit(1.0, &[x.to_vec()], harmonics);
    let [mut x0, mut x1, mut x2] = [vec![0.0; m], vec![0.0; m], vec![0.0; m]];
    for k in 0..m {
        (x0[k], x1[k], x2[k]) = s.joint(0, (k as f64 + 0.5) / m as f64);
    }
    [x0, x1, x2]
}

/// One period's states (per joint, at the middle of each sample interval) and torques.
struct Period {
    q: Vec<Vec<f64>>,
    qd: Vec<Vec<f64>>,
    qdd: Vec<Vec<f64>>,
    u: Vec<Vec<f64>>,
}

fn period_states(
    y: &[Vec<f64>],
    u: &[Vec<f64>],
    moving: &[bool],
    hold: &[f64],
    period: f64,
    harmonics: usize,
) -> Period {
    let n = y.len();
    let m = y[0].len();
    let mut p = Period {
        q: vec![vec![0.0; m]; n],
        qd: vec![vec![0.0; m]; n],
        qdd: vec![vec![0.0; m]; n],
        u: u.to_vec(),
    };
    for j in 0..n {
        if !moving[j] {
            // A held joint: its position is the hold value (its noise carries no information).
            p.q[j].fill(hold[j]);
            continue;
        }
        let [q, dq, ddq] = differentiate(&y[j], harmonics);
        p.q[j] = q;
        p.qd[j] = dq.iter().map(|v| v / period).collect();
        p.qdd[j] = ddq.iter().map(|v| v / (period * period)).collect();
    }
    p
}

/// The stage's base regressor (rows: instants x moving joints) and torques of a period.
fn regression(
    model: &Model,
    columns: Columns,
    stage: &Stage,
    cols: &[usize],
    p: &Period,
    stride: usize,
) -> (DMatrix<f64>, DVector<f64>) {
    let n = model.dof();
    let m = p.q[0].len();
    let instants: Vec<usize> = (0..m).step_by(stride).collect();
    let rows = stage.rows();
    let mut stacker = Stacker::new(model, columns, stage);
    let mut w = DMatrix::zeros(instants.len() * rows.len(), columns.count(model));
    let mut tau = DVector::zeros(instants.len() * rows.len());
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for (i, &k) in instants.iter().enumerate() {
        for j in 0..n {
            (q[j], qd[j], qdd[j]) = (p.q[j][k], p.qd[j][k], p.qdd[j][k]);
        }
        stacker.put([&q, &qd, &qdd], &mut w, i * rows.len());
        for (r, &j) in rows.iter().enumerate() {
            tau[i * rows.len() + r] = p.u[j][k];
        }
    }
    (w.select_columns(cols), tau)
}

/// Estimate the base parameters of `model`'s stage that `rec` excited.
pub fn estimate(model: &Model, rec: &Recording, o: &Options) -> Result<Estimate, LlsError> {
    let n = model.dof();
    if rec.y.len() != n || rec.u.len() != n {
        return Err(LlsError::Joints {
            run: rec.y.len(),
            robot: model.name.clone(),
            dof: n,
        });
    }
    let m = rec.per_period()?;
    let total = rec.y[0].len() / m;
    if total < o.skip + 2 {
        return Err(LlsError::Periods {
            recorded: total,
            period: rec.period,
            skip: o.skip,
        });
    }
    let stage = Stage::from_moving(rec.moving.clone(), rec.hold.clone());
    if stage.rows().is_empty() {
        return Err(LlsError::NoMotion);
    }
    let base = stage_base(
        model,
        o.columns,
        &stage,
        states_needed(model, o.columns, &stage),
        1,
    );
    let cols: Vec<usize> = base.base.iter().map(|b| b.column).collect();
    let fit = total - o.skip - 1;
    let slice = |x: &Vec<f64>, p: usize| x[p * m..(p + 1) * m].to_vec();
    let average = |x: &Vec<f64>| {
        let mut a = vec![0.0; m];
        for p in o.skip..o.skip + fit {
            for (k, v) in x[p * m..(p + 1) * m].iter().enumerate() {
                a[k] += v / fit as f64;
            }
        }
        a
    };
    let y_avg: Vec<Vec<f64>> = rec.y.iter().map(average).collect();
    let u_avg: Vec<Vec<f64>> = rec.u.iter().map(average).collect();
    let stride = (m / o.instants.max(1)).max(1);
    let fit_p = period_states(
        &y_avg,
        &u_avg,
        &rec.moving,
        &rec.hold,
        rec.period,
        o.harmonics,
    );
    let (wb, tau) = regression(model, o.columns, &stage, &cols, &fit_p, stride);
    let svd = wb.clone().svd(true, true);
    let cond = svd.singular_values.max() / svd.singular_values.min();
    let beta = svd.solve(&tau, 1e-12).map_err(LlsError::Solve)?;
    // Validation on the held-out (last) period.
    let last = o.skip + fit;
    let y_last: Vec<Vec<f64>> = rec.y.iter().map(|c| slice(c, last)).collect();
    let u_last: Vec<Vec<f64>> = rec.u.iter().map(|c| slice(c, last)).collect();
    let val_p = period_states(
        &y_last,
        &u_last,
        &rec.moving,
        &rec.hold,
        rec.period,
        o.harmonics,
    );
    let (wv, tv) = regression(model, o.columns, &stage, &cols, &val_p, 1);
    let pred = &wv * &beta;
    let rows = stage.rows();
    let nr = rows.len();
    let mut rms_v = vec![None; n];
    let mut rms_m = vec![None; n];
    let mut val = Validation {
        t: (0..m).map(|k| (last * m + k) as f64 * rec.h).collect(),
        joints: rows.clone(),
        ..Default::default()
    };
    for (r, &j) in rows.iter().enumerate() {
        let meas: Vec<f64> = (0..m).map(|k| tv[k * nr + r]).collect();
        let pr: Vec<f64> = (0..m).map(|k| pred[k * nr + r]).collect();
        let rms = |v: &mut dyn Iterator<Item = f64>| {
            let (s, c) = v.fold((0.0, 0usize), |(s, c), x| (s + x * x, c + 1));
            (s / c.max(1) as f64).sqrt()
        };
        rms_v[j] = Some(rms(&mut meas.iter().zip(&pr).map(|(a, b)| a - b)));
        rms_m[j] = Some(rms(&mut meas.iter().copied()));
        val.measured.push(meas);
        val.predicted.push(pr);
    }
    let truth: Vec<f64> = base.base.iter().map(|b| b.value).collect();
    let est: Vec<f64> = beta.iter().copied().collect();
    let largest = truth.iter().fold(0.0f64, |m, t| m.max(t.abs()));
    let abs: Vec<f64> = truth.iter().zip(&est).map(|(t, e)| (e - t).abs()).collect();
    let rel: Vec<Option<f64>> = truth
        .iter()
        .zip(&abs)
        .map(|(t, a)| (t.abs() > 1e-9 * largest).then(|| a / t.abs()))
        .collect();
    let diff: f64 = truth.iter().zip(&est).map(|(t, e)| (e - t).powi(2)).sum();
    let norm: f64 = truth.iter().map(|t| t * t).sum();
    let model_parameters = (stage.kind == super::StageKind::All).then(|| {
        let mut p = vec![0.0; o.columns.count(model)];
        for (b, v) in base.base.iter().zip(&est) {
            p[b.column] = *v;
        }
        p
    });
    Ok(Estimate {
        model_parameters,
        stage: stage.name().into(),
        regrouping: base.base.iter().map(|b| b.relation()).collect(),
        base: base.base.iter().map(|b| b.name.clone()).collect(),
        base_true: truth,
        base_estimate: est,
        relative_error: rel,
        absolute_error: abs,
        relative_error_norm: (diff / norm).sqrt(),
        cond,
        periods: fit,
        torque_rms_validation: rms_v,
        torque_rms_measured: rms_m,
        validation: val,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    #[test]
    fn a_realtime_log_is_put_on_the_regular_grid() {
        // Stamps 0, 1, 1 (a second cycle on the same state), 4 (two late cycles): the later
        // of a shared stamp is kept, gaps interpolate the positions and hold the command.
        let time = [0.0, 0.001, 0.001, 0.004];
        let y = vec![vec![0.0, 1.0, 1.5, 4.5]];
        let u = vec![vec![10.0, 11.0, 12.0, 14.0]];
        let (yr, ur) = regular(&time, 0.001, None, &y, &u);
        assert_eq!(ur[0], vec![10.0, 12.0, 12.0, 12.0, 14.0]);
        let want = [0.0, 1.5, 2.5, 3.5, 4.5];
        for k in 0..5 {
            assert!((yr[0][k] - want[k]).abs() < 1e-12, "{k}: {:?}", yr[0]);
        }
        // A run of 7 ms that ran to its end but whose last two cycles were missed: the grid
        // still has its 7 samples, the tail holding the last row.
        let (yr, ur) = regular(&time, 0.001, Some(0.007), &y, &u);
        assert_eq!(ur[0], vec![10.0, 12.0, 12.0, 12.0, 14.0, 14.0, 14.0]);
        assert_eq!(yr[0][4..], [4.5, 4.5, 4.5]);
        // A duration shorter than the log changes nothing.
        assert_eq!(regular(&time, 0.001, Some(0.002), &y, &u).0[0].len(), 5);
    }

    #[test]
    fn fourier_differentiation_is_exact_for_band_limited_signals() {
        let m = 200;
        let f = |p: f64| 0.3 + 0.5 * (TAU * p).sin() - 0.2 * (3.0 * TAU * p + 0.4).cos();
        let df = |p: f64| 0.5 * TAU * (TAU * p).cos() + 0.6 * TAU * (3.0 * TAU * p + 0.4).sin();
        let x: Vec<f64> = (0..m).map(|k| f(k as f64 / m as f64)).collect();
        let [q, dq, _] = differentiate(&x, 5);
        for k in [0, 17, 123, 199] {
            let p = (k as f64 + 0.5) / m as f64;
            assert!((q[k] - f(p)).abs() < 1e-12, "value at {k}");
            assert!((dq[k] - df(p)).abs() < 1e-10, "derivative at {k}");
        }
    }
}
