//! Assemble the run report from what the processes wrote: `summary.json` and `response.png`.

use super::summary::{
    ControllerReport, DirectSummary, FloorReport, OptimiserLife, OptimiserReport, ParamRecord,
    ParamVersions, PlantReport, RealtimePrivileges, Summary,
};
use crate::config::{OptimiserMode, Scenario};
use crate::msg::ParamCode;
use crate::msg::MAX_JOINTS;
use crate::report::metrics::{ResponseAcc, TrackingAcc};
use crate::report::plot::PlotError;
use crate::report::plot::{two_panel_png, Panel, Series};
use crate::report::scan::{Extent, PlotColumns, Rows};
use crate::report::Csv;
use crate::report::Outcome;
use crate::report::ReadJsonError;
use crate::sim::cost::TrackingCost;
use crate::sim::JointTraces;
use evoloop_schemes::WriteError;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};

/// Why a run's report (`build_report`) could not be made.
#[derive(Debug)]
pub enum ReportError {
    /// The controller's report (controller.json) cannot be read.
    Inputs(ReadJsonError),
    /// run.csv cannot be read.
    RunCsv {
        /// The file.
        file: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// run.csv lacks a column the report reads.
    Column {
        /// The file.
        file: PathBuf,
        /// The column.
        name: String,
    },
    /// A table or figure could not be written.
    Write(WriteError),
}

impl std::fmt::Display for ReportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReportError::Inputs(e) => e.fmt(f),
            ReportError::RunCsv { file, source } => crate::report::with_path(f, file, source),
            ReportError::Column { file, name } => {
                write!(f, "{}: no column {name:?}", file.display())
            }
            ReportError::Write(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for ReportError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ReportError::Inputs(e) => e.source(),
            ReportError::RunCsv { source, .. } => Some(source),
            ReportError::Column { .. } => None,
            ReportError::Write(e) => e.source(),
        }
    }
}

impl From<WriteError> for ReportError {
    fn from(e: WriteError) -> Self {
        ReportError::Write(e)
    }
}

impl From<PlotError> for ReportError {
    fn from(e: PlotError) -> Self {
        ReportError::Write(WriteError::Figure(e))
    }
}

/// Cost per repetition of a repeating (square-wave) reference, one sample at a time:
/// (start, end, sum |e| + w sum |u|) over each whole period.
struct Repetitions {
    period: f64,
    start: f64,
    /// Repetitions ending after this are incomplete (the run ended within them).
    limit: f64,
    w: f64,
    done: bool,
    out: Vec<(f64, f64, TrackingCost)>,
}

impl Repetitions {
    /// None for a reference that does not repeat.
    fn new(scn: &Scenario, t_last: f64) -> Option<Self> {
        let crate::reference::Reference::Square { period, start, .. } = scn.reference else {
            return None;
        };
        Some(Self {
            period,
            start,
            limit: t_last + 1.5 * scn.timing.period,
            w: scn.optimiser.cost_u_weight,
            done: false,
            out: Vec::new(),
        })
    }

    /// One sample: references and outputs pairwise (at most MAX_JOINTS), inputs `u`.
    fn add(&mut self, t: f64, r: &[f64], y: &[f64], u: &[f64]) {
        if self.done || t < self.start {
            return;
        }
        let j = ((t - self.start) / self.period).floor();
        let (a, b) = (
            self.start + j * self.period,
            self.start + (j + 1.0) * self.period,
        );
        if b > self.limit {
            self.done = true; // an incomplete last repetition
            return;
        }
        if self.out.last().is_none_or(|r| r.0 != a) {
            self.out.push((a, b, TrackingCost::new(self.w)));
        }
        let ny = r.len().min(y.len()).min(MAX_JOINTS);
        let nu = u.len().min(MAX_JOINTS);
        let rep = &mut self.out.last_mut().expect("pushed above").2;
        rep.add(&r[..ny], &y[..ny], &u[..nu]);
    }

    fn finish(self) -> Vec<(f64, f64, f64)> {
        self.out
            .into_iter()
            .map(|(a, b, c)| (a, b, c.total))
            .collect()
    }
}

/// The width of the windows of `identify.png`'s tracking RMS, s.
const IDENTIFY_PLOT_WINDOW: f64 = 0.5;

/// Tracking RMS over all joints (rad) from 1 s (past start-up) to the plant's first change
/// (None without one), and over the samples from `quarter` on, one sample at a time.
struct Phases {
    change: Option<f64>,
    quarter: f64,
    before: TrackingAcc,
    after: TrackingAcc,
}

impl Phases {
    fn new(joints: usize, change: Option<f64>, quarter: f64) -> Self {
        Self {
            change,
            quarter,
            before: TrackingAcc::new(joints),
            after: TrackingAcc::new(joints),
        }
    }

    fn add(&mut self, t: f64, e: &[f64]) {
        if self.change.is_some_and(|tc| t >= 1.0 && t < tc) {
            self.before.add(e);
        }
        if t >= self.quarter {
            self.after.add(e);
        }
    }

    fn finish(&self) -> (Option<f64>, Option<f64>) {
        let rms = |a: &TrackingAcc| (a.samples() > 0).then(|| a.finish().rms_all);
        (self.change.and(rms(&self.before)), rms(&self.after))
    }
}

/// Tracking RMS over all joints per window of `width` s, in mrad, one sample at a time: a
/// window starts at a sample and holds the samples before its start + width.
struct WindowedRms {
    width: f64,
    window: TrackingAcc,
    first: f64,
    last: f64,
    centres: Vec<f64>,
    values: Vec<f64>,
}

impl WindowedRms {
    fn new(joints: usize, width: f64) -> Self {
        Self {
            width,
            window: TrackingAcc::new(joints),
            first: 0.0,
            last: 0.0,
            centres: Vec::new(),
            values: Vec::new(),
        }
    }

    fn add(&mut self, t: f64, e: &[f64]) {
        if self.window.samples() > 0 && t >= self.first + self.width - 1e-9 {
            self.close();
        }
        if self.window.samples() == 0 {
            self.first = t;
        }
        self.last = t;
        self.window.add(e);
    }

    fn close(&mut self) {
        self.centres.push(0.5 * (self.first + self.last));
        self.values.push(1e3 * self.window.finish().rms_all);
        self.window.clear();
    }

    /// (window centres, values)
    fn finish(mut self) -> (Vec<f64>, Vec<f64>) {
        if self.window.samples() > 0 {
            self.close();
        }
        (self.centres, self.values)
    }
}

/// What the report reads off the frozen comparison's traces, as off the run's rows.
struct FrozenReadings {
    reps: Vec<(f64, f64, f64)>,
    phases: (Option<f64>, Option<f64>),
    windowed: (Vec<f64>, Vec<f64>),
}

fn frozen_readings(
    scn: &Scenario,
    f: &JointTraces,
    change: Option<f64>,
    quarter: f64,
) -> FrozenReadings {
    let joints = f.r.len().min(f.y.len());
    let t_last = f.t.last().copied().unwrap_or(0.0);
    let mut reps = Repetitions::new(scn, t_last);
    let mut phases = Phases::new(joints, change, quarter);
    let mut windowed = WindowedRms::new(joints, IDENTIFY_PLOT_WINDOW);
    let mut e = vec![0.0; joints];
    for (k, t) in f.t.iter().enumerate() {
        for (j, ej) in e.iter_mut().enumerate() {
            *ej = f.r[j][k] - f.y[j][k];
        }
        phases.add(*t, &e);
        windowed.add(*t, &e);
        if let Some(reps) = reps.as_mut() {
            // The indirect scheme's comparison: joint 0 only, as the run's cost criterion.
            reps.add(*t, &[f.r[0][k]], &[f.y[0][k]], &[f.u[0][k]]);
        }
    }
    FrozenReadings {
        reps: reps.map(Repetitions::finish).unwrap_or_default(),
        phases: phases.finish(),
        windowed: windowed.finish(),
    }
}

/// The longest run the frozen comparison is simulated for, s: the simulation keeps its whole
/// log in memory (about 0.2 KB per sample), so a long run until stopped is reported without it.
pub const FROZEN_LIMIT_S: f64 = 600.0;

/// The scenario with the optimiser off, simulated in-process (the same plant and controller
/// code, bit-identical to a lockstep run of the processes) for `span` s, per joint.
fn frozen_traces(scn: &Scenario, span: f64) -> JointTraces {
    let mut f = scn.clone();
    f.optimiser.mode = OptimiserMode::Off;
    f.timing.duration = span;
    JointTraces::of(
        &crate::sim::simulate(&f),
        &scn.reference,
        scn.reference.joints(),
    )
}

/// A plot's series from named columns.
fn series(c: &[(String, Vec<f64>)]) -> Vec<Series<'_>> {
    c.iter()
        .map(|(name, v)| Series { name, values: v })
        .collect()
}

/// What the report reads off run.csv.
struct Scan {
    /// The last sample's time.
    horizon: f64,
    /// The scenario's duration, or what ran of a run until stopped.
    span: f64,
    /// The start of the run's last quarter.
    quarter: f64,
    /// The plant's first change of parameters.
    change: Option<f64>,
    response: crate::report::metrics::ResponseMetrics,
    tracking: crate::report::metrics::Tracking,
    tracking_after_1s: crate::report::metrics::Tracking,
    reps: Vec<(f64, f64, f64)>,
    /// Tracking RMS before the plant's change and in the last quarter (identification only).
    phases: (Option<f64>, Option<f64>),
    /// Tracking RMS per `IDENTIFY_PLOT_WINDOW` (identification with plots only).
    windowed: Option<(Vec<f64>, Vec<f64>)>,
    plot: Option<RunPlot>,
}

/// The columns of response.png and tracking.png, of bounded length (`scan::PlotColumns`).
struct RunPlot {
    exact: bool,
    t: Vec<f64>,
    /// References and outputs; inputs; tracking errors per joint.
    top: Vec<(String, Vec<f64>)>,
    bottom: Vec<(String, Vec<f64>)>,
    errors: Vec<(String, Vec<f64>)>,
}

/// Read run.csv twice, a row at a time: its extent, then every metric and the plot columns.
/// Memory is bounded whatever the run's length (the repetitions and windows aside, a few
/// numbers per second of the run).
fn scan_run(scn: &Scenario, path: &Path) -> Result<Scan, ReportError> {
    let err = |source| ReportError::RunCsv {
        file: path.to_path_buf(),
        source,
    };
    let extent = Extent::of(path).map_err(err)?;
    let mut rows = Rows::open(path).map_err(err)?;
    let column = |name: &str| {
        rows.index(name).ok_or_else(|| ReportError::Column {
            file: path.to_path_buf(),
            name: name.to_string(),
        })
    };
    let (ti, ri) = (column("t")?, column("reference")?);
    // Joint i's reference: `reference` for joint 0, then r1, r2, ... for trajectories.
    let mut refs = vec![("reference".to_string(), ri)];
    refs.extend(rows.indices_with_prefix("r"));
    let ys = rows.indices_with_prefix("y");
    let us = rows.indices_with_prefix("u");
    let n_track = refs.len().min(ys.len());

    let horizon = extent.last.get(ti).copied().unwrap_or(0.0);
    let span = if scn.timing.until_stopped() {
        horizon
    } else {
        scn.timing.duration
    };
    let quarter = 0.75 * span;
    let change = scn.plant.model.config().first_change();
    let identify = scn.optimiser.mode == OptimiserMode::Identify;
    let mut response = ys.first().map(|_| {
        ResponseAcc::new(
            extent.rows,
            horizon,
            // A run stopped before its first sample has no last row (the launcher's Ctrl-C
            // in the first milliseconds).
            extent.last.get(ri).copied().unwrap_or(0.0),
            scn.timing.period,
            scn.reference.last_change(horizon),
        )
    });
    let mut tracking = TrackingAcc::new(n_track);
    let mut after_1s = TrackingAcc::new(n_track);
    let mut phases = Phases::new(n_track, change, quarter);
    let mut windowed =
        (identify && scn.output.plots).then(|| WindowedRms::new(n_track, IDENTIFY_PLOT_WINDOW));
    let mut reps = Repetitions::new(scn, horizon);
    let errors = if n_track > 1 { n_track } else { 0 };
    let width = refs.len() + ys.len() + us.len() + errors;
    let mut plot = scn
        .output
        .plots
        .then(|| PlotColumns::new(extent.rows, width));
    let (mut e, mut r, mut y, mut u) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut values = Vec::with_capacity(width);
    // A sensor `late` samples late (`plant.sensor_delay`) reads the output of `late` rows
    // before: each reading is judged at that row's time, against that row's reference, and the
    // first `late` readings (of before the run) are not judged.
    let late = scn.plant.sensor_delay as usize;
    let mut earlier: VecDeque<(f64, Vec<f64>)> = VecDeque::with_capacity(late + 1);
    let mut r_then = Vec::new();
    while let Some(row) = rows.next().map_err(err)? {
        let pick = |out: &mut Vec<f64>, cols: &[(String, usize)]| {
            out.clear();
            out.extend(cols.iter().map(|c| row[c.1]));
        };
        pick(&mut r, &refs);
        pick(&mut y, &ys);
        pick(&mut u, &us);
        let t_row = row[ti];
        let judged_at = if late == 0 {
            Some(t_row)
        } else {
            earlier.push_back((t_row, r.clone()));
            (earlier.len() > late)
                .then(|| earlier.pop_front())
                .flatten()
                .map(|(t, r)| {
                    r_then = r;
                    t
                })
        };
        let r_judged = if late == 0 { &r } else { &r_then };
        e.clear();
        match judged_at {
            Some(_) => e.extend((0..n_track).map(|j| r_judged[j] - y[j])),
            None => e.resize(n_track, f64::NAN),
        }
        if let Some(t) = judged_at {
            if let Some(acc) = response.as_mut() {
                acc.add(t, r_judged[0], y[0]);
            }
            tracking.add(&e);
            if t >= 1.0 {
                after_1s.add(&e);
            }
            if identify {
                phases.add(t, &e);
            }
            if let Some(w) = windowed.as_mut() {
                w.add(t, &e);
            }
            if let Some(reps) = reps.as_mut() {
                reps.add(t, r_judged, &y, &u);
            }
        }
        if let Some(p) = plot.as_mut() {
            values.clear();
            values.extend_from_slice(&r);
            values.extend_from_slice(&y);
            values.extend_from_slice(&u);
            values.extend_from_slice(&e[..errors]);
            p.push(t_row, &values);
        }
    }
    let plot = plot.map(|p| {
        let exact = p.exact();
        let (t, columns) = p.finish();
        let mut columns = columns.into_iter();
        let mut named = |names: Vec<String>| -> Vec<(String, Vec<f64>)> {
            names.into_iter().zip(columns.by_ref()).collect()
        };
        let name = |c: &[(String, usize)]| c.iter().map(|c| c.0.clone()).collect::<Vec<_>>();
        let top = named([name(&refs), name(&ys)].concat());
        let bottom = named(name(&us));
        let errors = named((0..errors).map(|j| format!("e{j}")).collect());
        RunPlot {
            exact,
            t,
            top,
            bottom,
            errors,
        }
    });
    Ok(Scan {
        horizon,
        span,
        quarter,
        change,
        response: response.map(ResponseAcc::finish).unwrap_or_default(),
        tracking: tracking.finish(),
        tracking_after_1s: after_1s.finish(),
        reps: reps.map(Repetitions::finish).unwrap_or_default(),
        phases: phases.finish(),
        windowed: windowed.map(WindowedRms::finish),
        plot,
    })
}

/// The processes' own reports in the run directory.
struct Inputs {
    ctrl: ControllerReport,
    plant: PlantReport,
    opt: OptimiserReport,
}

fn read_inputs(dir: &Path) -> Result<Inputs, ReportError> {
    let ctrl: ControllerReport =
        crate::report::read_json(dir, "controller.json").map_err(ReportError::Inputs)?;
    let plant: PlantReport = crate::report::read_json(dir, "plant.json").unwrap_or_default();
    // A missing optimiser.json is normal (it was killed); an unreadable one loses the estimates
    // and epochs from the report, so say so.
    let opt: OptimiserReport = match crate::report::read_json(dir, "optimiser.json") {
        Ok(o) => o,
        Err(e) => {
            if !e.is_missing() {
                eprintln!("evoloop: warning: {e}; the optimiser's estimates and epochs are left out of the report");
            }
            OptimiserReport::default()
        }
    };
    Ok(Inputs { ctrl, plant, opt })
}

/// The parameter events by what became of the set.
struct SetOutcomes {
    accepted: Vec<ParamRecord>,
    rejected: Vec<ParamRecord>,
    /// A trial's end or abort: its fallback back in service, not a refusal.
    trials_ended: Vec<ParamRecord>,
}

impl SetOutcomes {
    fn of(params: &[ParamRecord]) -> Self {
        let (accepted, refused): (Vec<_>, Vec<_>) = params
            .iter()
            .cloned()
            .partition(|p| p.code == ParamCode::Accepted);
        let (trials_ended, rejected) = refused
            .into_iter()
            .partition(|p| matches!(p.code, ParamCode::TrialEnded | ParamCode::TrialAborted));
        Self {
            accepted,
            rejected,
            trials_ended,
        }
    }

    /// When the accepted sets went in service: the plots' marks.
    fn marks(&self) -> Vec<f64> {
        self.accepted.iter().map(|p| p.t).collect()
    }
}

/// The floor's figures with the controller's lateness over them, percentile by percentile.
fn against_floor(mut f: FloorReport, lateness: &crate::rt::timing::Percentiles) -> FloorReport {
    let ratio = |a: i64, b: i64| if b > 0 { a as f64 / b as f64 } else { f64::NAN };
    f.ratio_p50 = ratio(lateness.p50_ns, f.lateness.p50_ns);
    f.ratio_p99 = ratio(lateness.p99_ns, f.lateness.p99_ns);
    f.ratio_p99_9 = ratio(lateness.p99_9_ns, f.lateness.p99_9_ns);
    f
}

/// The frozen comparison of a scheme that tunes alongside operation: the same scenario and seed
/// with the optimiser off, simulated for the run's `span`. The indirect scheme is judged on its
/// cost per repetition, identification on tracking; other modes, and runs longer than
/// `FROZEN_LIMIT_S`, have none.
fn frozen_comparison(
    scn: &Scenario,
    span: f64,
    change: Option<f64>,
    quarter: f64,
) -> Option<FrozenReadings> {
    let compare = matches!(
        scn.optimiser.mode,
        OptimiserMode::Indirect | OptimiserMode::Identify
    );
    if compare && span > FROZEN_LIMIT_S {
        eprintln!("evoloop: note: the run is longer than {FROZEN_LIMIT_S} s; the frozen comparison is left out of the report");
    }
    // A plant of the user's own runs in its own process only: its frozen run is theirs to make
    // (`--optimiser off`).
    let simulated = scn.simulated();
    if compare && !simulated {
        eprintln!("evoloop: note: evoloop cannot simulate this plant; for the frozen comparison run it again with --optimiser off");
    }
    (compare && simulated && span <= FROZEN_LIMIT_S)
        .then(|| frozen_readings(scn, &frozen_traces(scn, span), change, quarter))
}

/// Mean cost of the repetitions before the plant's change (after the first, start-up one; those
/// that end by the change) and after it (those starting in the last quarter of the run).
fn before_and_after(
    reps: &[(f64, f64, f64)],
    change: Option<f64>,
    quarter: f64,
) -> (Option<f64>, Option<f64>) {
    let mean = |v: Vec<f64>| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    let before = change.and_then(|tc| {
        mean(
            reps.iter()
                .skip(1)
                .filter(|r| r.1 <= tc)
                .map(|r| r.2)
                .collect(),
        )
    });
    let after = mean(
        reps.iter()
            .filter(|r| r.0 >= quarter)
            .map(|r| r.2)
            .collect(),
    );
    (before, after)
}

fn direct_summary(d: &crate::direct::DirectReport) -> DirectSummary {
    DirectSummary {
        algorithm: d.algorithm.clone(),
        trials: d.repetitions.iter().filter(|r| r.trial > 0).count(),
        aborted: d.aborted,
        incomplete: d.incomplete,
        baseline_cost: d
            .repetitions
            .iter()
            .find(|r| r.trial == 0)
            .map(|b| b.cost)
            .filter(|c| c.is_finite()),
        best_cost: Some(d.best_cost).filter(|c| c.is_finite()),
        best_version: d.best_version,
    }
}

/// Why the loop did not control the plant for most of the run, if it did not: more than half
/// of its cycles on a refused sample (a NaN, a wrong count, a sample that broke time), or more
/// periods missed than cycles run. A run can then go to its end and still have done nothing a
/// user asked for, which an exit status of 0 would hide.
fn degraded(ctrl: &ControllerReport) -> Vec<String> {
    let cycles = ctrl.cycles;
    let refused = &ctrl.refused_states;
    let missed = ctrl.timing.missed_deadlines;
    let mut why = Vec::new();
    if refused.count > 0 && 2 * refused.count > cycles {
        let first = refused
            .first
            .map(|f| format!(" (the first at seq {}: {})", f.seq, f.fault))
            .unwrap_or_default();
        why.push(format!(
            "{} of the loop's {cycles} cycles had a refused sample{first}",
            refused.count
        ));
    }
    if missed > 0 && missed > cycles {
        why.push(format!(
            "the loop missed {missed} deadlines and ran {cycles} cycles: it did not keep its period"
        ));
    }
    why
}

/// The messages of what could not be written (a full disk): the run is then incomplete.
fn write_errors(ctrl: &ControllerReport, opt: &OptimiserReport) -> Vec<String> {
    ctrl.log_error
        .iter()
        .cloned()
        .chain(opt.journal_error.clone())
        .chain(
            ctrl.mcap
                .as_ref()
                .and_then(|m| m.error.as_ref())
                .map(|e| format!("run.mcap: {e}; messages after it are lost")),
        )
        .collect()
}

/// Build `summary.json` (and `response.png` when plots are on) in the scenario's output dir.
pub fn build_report(
    scn: &Scenario,
    run_id: &str,
    wall_s: f64,
    floor: Option<FloorReport>,
    cleaned: usize,
    optimiser: OptimiserLife,
) -> Result<Summary, ReportError> {
    let dir = &scn.output.dir;
    let inputs = read_inputs(dir)?;
    let scan = scan_run(scn, &dir.join("run.csv"))?;
    let sets = SetOutcomes::of(&inputs.ctrl.params);
    let marks = sets.marks();
    let frozen = frozen_comparison(scn, scan.span, scan.change, scan.quarter);
    let mut summary = loop_summary(scn, run_id, wall_s, &inputs, &scan, sets);
    summary.floor = floor.map(|f| against_floor(f, &inputs.ctrl.timing.lateness));
    processes_summary(&mut summary, &inputs, cleaned, optimiser);
    let frozen_reps = scheme_summary(&mut summary, scn, &inputs.opt, &scan, frozen.as_ref());
    let identify = scn.optimiser.mode == OptimiserMode::Identify;
    if let (Some(f), Some(w), true) = (
        frozen.as_ref().filter(|_| identify),
        scan.windowed.as_ref(),
        scn.output.plots,
    ) {
        write_identify_plot(scn, f, w, &marks, truth(scn))?;
    }
    let opt = &inputs.opt;
    if let Some(d) = &opt.direct {
        crate::direct::write_files(dir, d, scn.output.plots)?;
    }
    if !scan.reps.is_empty() {
        write_repetitions(dir, &scan.reps, &frozen_reps)?;
    }
    if !opt.estimates.is_empty() {
        write_estimates(
            scn,
            &opt.estimates,
            &scan.reps,
            &frozen_reps,
            &marks,
            truth(scn),
        )?;
    }
    crate::report::write_json(dir, "summary.json", &summary)
        .map_err(WriteError::file(&dir.join("summary.json")))?;
    if let Some(p) = &scan.plot {
        write_response_plots(scn, inputs.ctrl.mode, p, &marks)?;
    }
    Ok(summary)
}

/// The true value of the parameter the optimiser estimates (maglev mass, two-mass spring):
/// the report judges the estimate with it; nothing in the run saw it.
fn truth(scn: &Scenario) -> impl Fn(f64) -> Option<f64> + '_ {
    let plant_model = scn.plant.model.config();
    move |t| plant_model.varying_parameter(t)
}

/// What the loop did: the run, its tracking, its timing and its parameter sets.
fn loop_summary(
    scn: &Scenario,
    run_id: &str,
    wall_s: f64,
    inputs: &Inputs,
    scan: &Scan,
    sets: SetOutcomes,
) -> Summary {
    let Inputs { ctrl, plant, .. } = inputs;
    let per_s = |n: f64, s: f64| if s > 0.0 { n / s } else { 0.0 };
    Summary {
        scenario: scn.name.clone(),
        config: scn.source.display().to_string(),
        run_id: run_id.to_string(),
        mode: ctrl.mode,
        seed: scn.seed,
        duration_s: scn.timing.duration_s(),
        ran_s: scan.horizon,
        until_stopped: scn.timing.until_stopped(),
        period_s: scn.timing.period,
        samples: ctrl.cycles,
        wall_s,
        throughput_samples_per_s: per_s(ctrl.cycles as f64, ctrl.wall_s),
        response: scan.response.clone(),
        tracking: scan.tracking.clone(),
        tracking_after_1s: scan.tracking_after_1s.clone(),
        overruns: ctrl.timing.overruns,
        deadline_misses: ctrl.timing.missed_deadlines,
        timing: ctrl.timing.clone(),
        accepted_versions: sets.accepted.len(),
        rejected_versions: sets.rejected.len(),
        parameter_versions: ParamVersions {
            final_version: ctrl.final_version,
            accepted: sets.accepted,
            rejected: sets.rejected,
            trials_ended: sets.trials_ended,
        },
        realtime_privileges: RealtimePrivileges {
            controller: ctrl.rt.clone(),
            plant: plant.rt.clone(),
        },
        wait: (scn.timing.mode == crate::config::Mode::Realtime).then_some(scn.timing.wait),
        log_dropped: ctrl.log_dropped,
        cycle_allocations: ctrl.cycle_allocations,
        plant_safe_samples: plant.safe_samples,
        refused_states: ctrl.refused_states.count,
        first_refused_state: ctrl.refused_states.first,
        plant_samples_before_first_command: plant.samples_before_first_command,
        check_model: ctrl.check_model.clone(),
        ..Summary::default()
    }
}

/// How the processes fared: the optimiser's load and life, what was lost, and the outcome.
fn processes_summary(s: &mut Summary, inputs: &Inputs, cleaned: usize, optimiser: OptimiserLife) {
    let Inputs { ctrl, plant, opt } = inputs;
    s.optimiser_published = opt.published_count as usize;
    s.optimiser_samples_missed = opt.samples_missed;
    s.optimiser_cpu_s = opt.cpu_s;
    s.optimiser_load_cores = if opt.wall_s > 0.0 {
        opt.cpu_s / opt.wall_s
    } else {
        0.0
    };
    s.evaluations = opt.evaluations;
    s.direct = opt.direct.as_ref().map(direct_summary);
    s.interrupted = ctrl.interrupted || plant.interrupted || opt.interrupted;
    s.stale_resources_cleaned = cleaned;
    s.optimiser_restarts = optimiser.restarts;
    s.optimiser_lost = optimiser.lost;
    s.write_errors = write_errors(ctrl, opt);
    s.degraded = degraded(ctrl);
    s.optimiser_stalls = plant.optimiser_stalls.clone();
    s.optimiser_resumed = plant.optimiser_resumed;
    s.outcome = if !s.write_errors.is_empty() {
        Outcome::Incomplete
    } else if s.interrupted && !s.until_stopped {
        Outcome::Interrupted
    } else if !s.degraded.is_empty() {
        Outcome::Degraded
    } else if optimiser.lost {
        Outcome::TunerLost
    } else {
        Outcome::Ok
    };
}

/// The scheme's figures: costs per repetition before and after the plant's change, against
/// the frozen controller's on the same run; the final model estimate; identification's
/// tracking before and after. Returns the frozen controller's repetitions.
fn scheme_summary(
    s: &mut Summary,
    scn: &Scenario,
    opt: &OptimiserReport,
    scan: &Scan,
    frozen: Option<&FrozenReadings>,
) -> Vec<(f64, f64, f64)> {
    let (change, quarter) = (scan.change, scan.quarter);
    let identify = scn.optimiser.mode == OptimiserMode::Identify;
    let frozen_reps = match frozen {
        Some(f) if scn.optimiser.mode == OptimiserMode::Indirect => f.reps.clone(),
        _ => Vec::new(),
    };
    (s.cost_before_change, s.cost_after_change) = before_and_after(&scan.reps, change, quarter);
    (s.cost_before_change_frozen, s.cost_after_change_frozen) =
        before_and_after(&frozen_reps, change, quarter);
    s.cost_per_repetition = scan.reps.iter().map(|r| r.2).collect();
    s.cost_per_repetition_frozen = frozen_reps.iter().map(|r| r.2).collect();
    let last_est = opt.estimates.last().copied();
    s.model_estimate_final = last_est.map(|e| e.value);
    s.model_true_final = last_est.and_then(|e| truth(scn)(e.t));
    s.model_estimate_error = match (s.model_estimate_final, s.model_true_final) {
        (Some(e), Some(tv)) => Some((e - tv) / tv),
        _ => None,
    };
    // Identification alongside operation against the models it started with, kept all run
    // long: tracking RMS before the plant's change and at the end.
    if identify {
        (s.tracking_before_change, s.tracking_after_change) = scan.phases;
        if let Some(f) = frozen {
            (
                s.tracking_before_change_frozen,
                s.tracking_after_change_frozen,
            ) = f.phases;
        }
    }
    frozen_reps
}

/// repetitions.csv: each repetition's cost, and the frozen controller's on the same run.
fn write_repetitions(
    dir: &Path,
    reps: &[(f64, f64, f64)],
    frozen_reps: &[(f64, f64, f64)],
) -> Result<(), ReportError> {
    let mut csv = Csv::new(["repetition", "t_start", "t_end", "cost", "cost_frozen"]);
    for (j, r) in reps.iter().enumerate() {
        let f = frozen_reps.get(j).map_or(f64::NAN, |x| x.2);
        csv.row().put(j).all([r.0, r.1, r.2, f]);
    }
    let file = dir.join("repetitions.csv");
    Ok(csv.write(&file).map_err(WriteError::file(&file))?)
}

/// identify.png: tracking RMS per window, identified alongside operation against the frozen
/// models, over the payload.
fn write_identify_plot(
    scn: &Scenario,
    frozen: &FrozenReadings,
    (tw, run_rms): &(Vec<f64>, Vec<f64>),
    marks: &[f64],
    truth: impl Fn(f64) -> Option<f64>,
) -> Result<(), ReportError> {
    let frozen_rms = &frozen.windowed.1;
    let frozen_rms: Vec<f64> = (0..tw.len())
        .map(|k| frozen_rms.get(k).copied().unwrap_or(f64::NAN))
        .collect();
    let payload: Vec<f64> = tw.iter().map(|x| truth(*x).unwrap_or(0.0)).collect();
    two_panel_png(
        &scn.output.dir.join("identify.png"),
        &format!(
            "{}: tracking RMS per {} s, identified vs frozen models (orange: models swapped in)",
            scn.name, IDENTIFY_PLOT_WINDOW
        ),
        tw,
        Panel {
            series: &[
                Series {
                    name: "identified alongside operation",
                    values: run_rms,
                },
                Series {
                    name: "frozen models",
                    values: &frozen_rms,
                },
            ],
            label: "tracking RMS, mrad",
        },
        Panel {
            series: &[Series {
                name: "payload on the last link",
                values: &payload,
            }],
            label: "payload, kg",
        },
        marks,
    )
    .map_err(ReportError::from)
}

/// estimates.csv and indirect.png: the model estimate against the true value, and the cost per
/// repetition against the frozen parameters'.
fn write_estimates(
    scn: &Scenario,
    estimates: &[crate::indirect::Estimate],
    reps: &[(f64, f64, f64)],
    frozen: &[(f64, f64, f64)],
    marks: &[f64],
    truth: impl Fn(f64) -> Option<f64>,
) -> Result<(), ReportError> {
    let dir = &scn.output.dir;
    let mut csv = Csv::new(["t", "estimate", "std", "true"]);
    for e in estimates {
        csv.row()
            .all([e.t, e.value, e.std, truth(e.t).unwrap_or(f64::NAN)]);
    }
    let file = dir.join("estimates.csv");
    csv.write(&file).map_err(WriteError::file(&file))?;
    if scn.output.plots {
        let te: Vec<f64> = estimates.iter().map(|e| e.t).collect();
        let est: Vec<f64> = estimates.iter().map(|e| e.value).collect();
        let tru: Vec<f64> = te.iter().map(|x| truth(*x).unwrap_or(f64::NAN)).collect();
        let cost: Vec<f64> = te
            .iter()
            .map(|x| {
                reps.iter()
                    .find(|r| *x >= r.0 && *x < r.1)
                    .map_or(f64::NAN, |r| r.2)
            })
            .collect();
        let cost_frozen: Vec<f64> = te
            .iter()
            .map(|x| {
                frozen
                    .iter()
                    .find(|r| *x >= r.0 && *x < r.1)
                    .map_or(f64::NAN, |r| r.2)
            })
            .collect();
        two_panel_png(
            &dir.join("indirect.png"),
            &format!(
                "{}: model estimate vs true value; cost per repetition (orange: sets swapped in)",
                scn.name
            ),
            &te,
            Panel {
                series: &[
                    Series {
                        name: "estimate",
                        values: &est,
                    },
                    Series {
                        name: "true",
                        values: &tru,
                    },
                ],
                label: "model parameter",
            },
            Panel {
                series: &[
                    Series {
                        name: "cost per repetition (tuned)",
                        values: &cost,
                    },
                    Series {
                        name: "frozen parameters",
                        values: &cost_frozen,
                    },
                ],
                label: "cost",
            },
            marks,
        )?;
    }
    Ok(())
}

/// response.png (and tracking.png for joint-space tracking).
fn write_response_plots(
    scn: &Scenario,
    mode: crate::config::Mode,
    p: &RunPlot,
    marks: &[f64],
) -> Result<(), ReportError> {
    let dir = &scn.output.dir;
    let (top, bottom) = (series(&p.top), series(&p.bottom));
    let envelope = if p.exact { "" } else { " (min-max envelope)" };
    two_panel_png(
        &dir.join("response.png"),
        &format!(
            "{} ({} mode): output vs reference, control{envelope}; orange lines = parameter swaps",
            scn.name, mode
        ),
        &p.t,
        Panel {
            series: &top,
            label: "position",
        },
        Panel {
            series: &bottom,
            label: "control u",
        },
        marks,
    )?;
    if p.errors.len() > 1 {
        // Joint-space tracking: the errors are far below what the overlaid curves resolve.
        two_panel_png(
            &dir.join("tracking.png"),
            &format!(
                "{} ({} mode): tracking error r - y per joint, and joint torques{envelope}",
                scn.name, mode
            ),
            &p.t,
            Panel {
                series: &series(&p.errors),
                label: "error (rad or m)",
            },
            Panel {
                series: &bottom,
                label: "torque u",
            },
            marks,
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_run_stopped_before_its_first_sample_scans_without_a_panic() {
        // Ctrl-C in the launcher's first milliseconds leaves run.csv with its header only.
        let scn = crate::config::Scenario::load(
            std::path::Path::new(concat!(
                env!("CARGO_MANIFEST_DIR"),
                "/../../config/two_mass/two_mass.toml"
            )),
            &crate::config::Overrides::default(),
        )
        .unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.csv");
        crate::files::write(&path, "t,reference,y0,u0\n").unwrap();
        let scan = super::scan_run(&scn, &path).expect("a header-only run.csv scans");
        assert_eq!(scan.horizon, 0.0);
        assert!(!scan.tracking.rms.iter().any(|v| v.is_finite() && *v != 0.0));
    }
}
