//! Assemble the run report from what the processes wrote: `summary.json` and `response.png`.

use super::metrics::response_metrics;
use super::plot::{two_panel_png, Panel, Series};
use super::summary::{
    ControllerReport, FloorReport, OptimiserReport, ParamVersions, PlantReport, RealtimePrivileges,
    Summary,
};
use super::Table;
use crate::config::Scenario;
use crate::sim::cost::TrackingCost;
use crate::sim::JointTraces;
use crate::MAX_JOINTS;
use std::path::Path;

/// Cost per repetition of a repeating (square-wave) reference: (start, end, sum |e| + w sum |u|)
/// over each whole period; empty for other references.
fn repetitions(
    scn: &Scenario,
    t: &[f64],
    refs: &[Vec<f64>],
    ys: &[(String, Vec<f64>)],
    us: &[(String, Vec<f64>)],
) -> Vec<(f64, f64, f64)> {
    let crate::reference::Reference::Square { period, start, .. } = scn.reference else {
        return Vec::new();
    };
    let w = scn.optimiser.cost_u_weight;
    let mut out: Vec<(f64, f64, TrackingCost)> = Vec::new();
    let (mut rk, mut yk, mut uk) = ([0.0; MAX_JOINTS], [0.0; MAX_JOINTS], [0.0; MAX_JOINTS]);
    // Outputs are paired with their references; at most MAX_JOINTS of each.
    let (ny, nu) = (
        refs.len().min(ys.len()).min(MAX_JOINTS),
        us.len().min(MAX_JOINTS),
    );
    for (k, tk) in t.iter().enumerate() {
        if *tk < start {
            continue;
        }
        let j = ((tk - start) / period).floor();
        let (a, b) = (start + j * period, start + (j + 1.0) * period);
        if b > t.last().copied().unwrap_or(0.0) + 1.5 * scn.timing.period {
            break; // an incomplete last repetition
        }
        if out.last().is_none_or(|r| r.0 != a) {
            out.push((a, b, TrackingCost::new(w)));
        }
        for (i, (r, (_, y))) in refs.iter().zip(ys).take(ny).enumerate() {
            (rk[i], yk[i]) = (r[k], y[k]);
        }
        for (i, (_, u)) in us.iter().take(nu).enumerate() {
            uk[i] = u[k];
        }
        let rep = &mut out.last_mut().expect("pushed above").2;
        rep.add(&rk[..ny], &yk[..ny], &uk[..nu]);
    }
    out.into_iter().map(|(a, b, c)| (a, b, c.total)).collect()
}

/// The width of the windows of `identify.png`'s tracking RMS, s.
const IDENTIFY_PLOT_WINDOW: f64 = 0.5;

/// Tracking RMS over all joints (rad) from 1 s (past start-up) to the plant's first change
/// (None without one), and over the samples from `quarter` on.
fn tracking_phases(
    t: &[f64],
    refs: &[&[f64]],
    ys: &[&[f64]],
    change: Option<f64>,
    quarter: f64,
) -> (Option<f64>, Option<f64>) {
    let at = |x: f64| t.partition_point(|s| *s < x);
    let rms =
        |a: usize, b: usize| (b > a).then(|| super::metrics::tracking_in(refs, ys, a..b).rms_all);
    (
        change.and_then(|tc| rms(at(1.0), at(tc))),
        rms(at(quarter), t.len()),
    )
}

/// Tracking RMS over all joints per window of `width` s, in mrad: (window centres, values).
fn windowed_rms(t: &[f64], refs: &[&[f64]], ys: &[&[f64]], width: f64) -> (Vec<f64>, Vec<f64>) {
    let (mut centres, mut values) = (Vec::new(), Vec::new());
    let mut a = 0;
    while a < t.len() {
        let end = t[a] + width;
        let b = a + t[a..].partition_point(|s| *s < end - 1e-9);
        centres.push(0.5 * (t[a] + t[b - 1]));
        values.push(1e3 * super::metrics::tracking_in(refs, ys, a..b).rms_all);
        a = b;
    }
    (centres, values)
}

/// The longest run the frozen comparison is simulated for, s: the simulation keeps its whole
/// log in memory (about 0.2 KB per sample), so a long run until stopped is reported without it.
pub const FROZEN_LIMIT_S: f64 = 600.0;

/// The scenario with the optimiser off, simulated in-process (the same plant and controller
/// code, bit-identical to a lockstep run of the processes) for `span` s, per joint.
fn frozen_traces(scn: &Scenario, span: f64) -> JointTraces {
    let mut f = scn.clone();
    f.optimiser.mode = crate::config::OptimiserMode::Off;
    f.timing.duration = span;
    JointTraces::of(
        &crate::sim::simulate(&f),
        &scn.reference,
        scn.reference.joints(),
    )
}

fn read_json<T: serde::de::DeserializeOwned>(dir: &Path, name: &str) -> Result<T, String> {
    let p = dir.join(name);
    let text = std::fs::read_to_string(&p).map_err(|e| format!("{}: {e}", p.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", p.display()))
}

/// Build `summary.json` (and `response.png` when plots are on) in the scenario's output dir.
pub fn build_report(
    scn: &Scenario,
    run_id: &str,
    wall_s: f64,
    floor: Option<FloorReport>,
    cleaned: usize,
    optimiser_restarts: usize,
) -> Result<Summary, String> {
    let dir = &scn.output.dir;
    let ctrl: ControllerReport = read_json(dir, "controller.json")?;
    let plant: PlantReport = read_json(dir, "plant.json").unwrap_or_default();
    // A missing optimiser.json is normal (it was killed); an unreadable one loses the estimates
    // and epochs from the report, so say so.
    let opt: OptimiserReport = match read_json(dir, "optimiser.json") {
        Ok(o) => o,
        Err(e) => {
            if dir.join("optimiser.json").is_file() {
                eprintln!("evoloop: warning: {e}; the optimiser's estimates and epochs are left out of the report");
            }
            OptimiserReport::default()
        }
    };
    let run = Table::read(&dir.join("run.csv")).map_err(|e| e.to_string())?;
    let t = run.col("t").unwrap_or_default();
    let r = run.col("reference").unwrap_or_default();
    let ys = run.cols_with_prefix("y");
    let us = run.cols_with_prefix("u");
    let y0 = ys.first().map(|c| c.1.clone()).unwrap_or_default();
    let horizon = t.last().copied().unwrap_or(0.0);
    let response = response_metrics(
        &t,
        &r,
        &y0,
        scn.timing.period,
        scn.reference.last_change(horizon),
    );
    // Joint i's reference: `reference` for joint 0, then r1, r2, ... for trajectories.
    let mut refs = vec![r.clone()];
    refs.extend(run.cols_with_prefix("r").into_iter().map(|c| c.1));
    let n_track = refs.len().min(ys.len());
    let ref_cols: Vec<&[f64]> = refs[..n_track].iter().map(|v| v.as_slice()).collect();
    let y_cols: Vec<&[f64]> = ys[..n_track].iter().map(|c| c.1.as_slice()).collect();
    let tracking = super::metrics::tracking(&ref_cols, &y_cols, 0);
    let after_1s = t.iter().position(|x| *x >= 1.0).unwrap_or(t.len());
    let tracking_after_1s = super::metrics::tracking(&ref_cols, &y_cols, after_1s);
    let (accepted, rejected): (Vec<_>, Vec<_>) = ctrl
        .params
        .iter()
        .cloned()
        .partition(|p| p.outcome == "accepted");
    let floor = floor.map(|mut f| {
        let ratio = |a: i64, b: i64| if b > 0 { a as f64 / b as f64 } else { f64::NAN };
        f.ratio_p50 = ratio(ctrl.timing.lateness.p50_ns, f.lateness.p50_ns);
        f.ratio_p99 = ratio(ctrl.timing.lateness.p99_ns, f.lateness.p99_ns);
        f.ratio_p99_9 = ratio(ctrl.timing.lateness.p99_9_ns, f.lateness.p99_9_ns);
        f
    });
    let n_rejected = rejected.len();
    let reps = repetitions(scn, &t, &refs, &ys, &us);
    // The frozen comparison of a scheme that tunes alongside operation: the same scenario and
    // seed with the optimiser off. The indirect scheme is judged on its cost per repetition,
    // identification (below) on tracking.
    use crate::config::OptimiserMode;
    let until_stopped = scn.timing.until_stopped();
    let span = if until_stopped {
        horizon
    } else {
        scn.timing.duration
    };
    let compare = matches!(
        scn.optimiser.mode,
        OptimiserMode::Indirect | OptimiserMode::Identify
    );
    if compare && span > FROZEN_LIMIT_S {
        eprintln!("evoloop: note: the run is longer than {FROZEN_LIMIT_S} s; the frozen comparison is left out of the report");
    }
    let frozen_traces = (compare && span <= FROZEN_LIMIT_S).then(|| frozen_traces(scn, span));
    let frozen: Vec<(f64, f64, f64)> = match &frozen_traces {
        Some(f) if scn.optimiser.mode == OptimiserMode::Indirect => {
            let named = |p: &str, c: &[Vec<f64>]| vec![(format!("{p}0"), c[0].clone())];
            repetitions(scn, &f.t, &f.r[..1], &named("y", &f.y), &named("u", &f.u))
        }
        _ => Vec::new(),
    };
    let plant_model = scn.plant.model.config();
    let change = plant_model.first_change();
    let mean = |v: Vec<f64>| (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64);
    // Before: the repetitions after the first (start-up) that end by the change; after: those
    // starting in the last quarter of the run.
    let before = |reps: &[(f64, f64, f64)]| {
        change.and_then(|tc| {
            mean(
                reps.iter()
                    .skip(1)
                    .filter(|r| r.1 <= tc)
                    .map(|r| r.2)
                    .collect(),
            )
        })
    };
    // The last quarter of the scenario, or of what ran of a run until stopped.
    let quarter = 0.75 * span;
    let after = |reps: &[(f64, f64, f64)]| {
        mean(
            reps.iter()
                .filter(|r| r.0 >= quarter)
                .map(|r| r.2)
                .collect(),
        )
    };
    // Identification alongside operation against the models it started with, kept all run long
    // (the frozen comparison again): tracking RMS before the plant's change and at the end.
    let identify = scn.optimiser.mode == OptimiserMode::Identify;
    let (tracking_before_change, tracking_after_change) =
        tracking_phases(&t, &ref_cols, &y_cols, change, quarter);
    let (tracking_before_change_frozen, tracking_after_change_frozen) = match &frozen_traces {
        Some(f) if identify => {
            let (fr, fy) = f.columns();
            tracking_phases(&f.t, &fr, &fy, change, quarter)
        }
        _ => (None, None),
    };
    let cost_before_change = before(&reps);
    let cost_after_change = after(&reps);
    let cost_before_change_frozen = before(&frozen);
    let cost_after_change_frozen = after(&frozen);
    // The true value of the parameter the optimiser estimates (maglev mass, two-mass spring).
    let truth = |tt: f64| plant_model.varying_parameter(tt);
    let last_est = opt.estimates.last().copied();
    let model_estimate_final = last_est.map(|e| e.value);
    let model_true_final = last_est.and_then(|e| truth(e.t));
    let model_estimate_error = match (model_estimate_final, model_true_final) {
        (Some(e), Some(tv)) => Some((e - tv) / tv),
        _ => None,
    };
    let interrupted = ctrl.interrupted || plant.interrupted || opt.interrupted;
    let summary = Summary {
        outcome: if interrupted && !until_stopped {
            "interrupted"
        } else {
            "ok"
        }
        .into(),
        scenario: scn.name.clone(),
        config: scn.source.display().to_string(),
        run_id: run_id.to_string(),
        mode: ctrl.mode.clone(),
        seed: scn.seed,
        duration_s: scn.timing.duration_s(),
        ran_s: horizon,
        until_stopped,
        period_s: scn.timing.period,
        samples: ctrl.cycles,
        wall_s,
        throughput_samples_per_s: if ctrl.wall_s > 0.0 {
            ctrl.cycles as f64 / ctrl.wall_s
        } else {
            0.0
        },
        response,
        tracking,
        tracking_after_1s,
        overruns: ctrl.timing.overruns,
        deadline_misses: ctrl.timing.missed_deadlines,
        timing: ctrl.timing.clone(),
        parameter_versions: ParamVersions {
            final_version: ctrl.final_version,
            accepted: accepted.clone(),
            rejected,
        },
        realtime_privileges: RealtimePrivileges {
            controller: ctrl.rt.clone(),
            plant: plant.rt.clone(),
        },
        floor,
        plant_safe_samples: plant.safe_samples,
        optimiser_published: opt.published_count as usize,
        interrupted,
        stale_resources_cleaned: cleaned,
        optimiser_restarts,
        optimiser_stalls: plant.optimiser_stalls.clone(),
        optimiser_resumed: plant.optimiser_resumed,
        accepted_versions: accepted.len(),
        rejected_versions: n_rejected,
        cost_per_repetition: reps.iter().map(|r| r.2).collect(),
        cost_before_change,
        cost_after_change,
        cost_before_change_frozen,
        cost_after_change_frozen,
        cost_per_repetition_frozen: frozen.iter().map(|r| r.2).collect(),
        model_estimate_final,
        model_true_final,
        model_estimate_error,
        tracking_before_change: identify.then_some(tracking_before_change).flatten(),
        tracking_after_change: identify.then_some(tracking_after_change).flatten(),
        tracking_before_change_frozen,
        tracking_after_change_frozen,
    };
    if let (Some(f), true) = (
        frozen_traces.as_ref().filter(|_| identify),
        scn.output.plots,
    ) {
        let (tw, run_rms) = windowed_rms(&t, &ref_cols, &y_cols, IDENTIFY_PLOT_WINDOW);
        let (fr, fy) = f.columns();
        let (_, frozen_rms) = windowed_rms(&f.t, &fr, &fy, IDENTIFY_PLOT_WINDOW);
        let frozen_rms: Vec<f64> = (0..tw.len())
            .map(|k| frozen_rms.get(k).copied().unwrap_or(f64::NAN))
            .collect();
        let payload: Vec<f64> = tw.iter().map(|x| truth(*x).unwrap_or(0.0)).collect();
        let marks: Vec<f64> = accepted.iter().map(|p| p.t).collect();
        two_panel_png(
            &dir.join("identify.png"),
            &format!(
                "{}: tracking RMS per {} s, identified vs frozen models (orange: models swapped in)",
                scn.name, IDENTIFY_PLOT_WINDOW
            ),
            &tw,
            Panel {
                series: &[
                    Series { name: "identified alongside operation", values: &run_rms },
                    Series { name: "frozen models", values: &frozen_rms },
                ],
                label: "tracking RMS, mrad",
            },
            Panel {
                series: &[Series { name: "payload on the last link", values: &payload }],
                label: "payload, kg",
            },
            &marks,
        )?;
    }
    if !reps.is_empty() {
        let mut csv = String::from("repetition,t_start,t_end,cost,cost_frozen\n");
        for (j, r) in reps.iter().enumerate() {
            let f = frozen.get(j).map_or(f64::NAN, |x| x.2);
            csv.push_str(&format!("{j},{},{},{},{f}\n", r.0, r.1, r.2));
        }
        std::fs::write(dir.join("repetitions.csv"), csv).map_err(|e| e.to_string())?;
    }
    if !opt.estimates.is_empty() {
        let mut csv = String::from("t,estimate,std,true\n");
        for e in &opt.estimates {
            csv.push_str(&format!(
                "{},{},{},{}\n",
                e.t,
                e.value,
                e.std,
                truth(e.t).unwrap_or(f64::NAN)
            ));
        }
        std::fs::write(dir.join("estimates.csv"), csv).map_err(|e| e.to_string())?;
        if scn.output.plots {
            let te: Vec<f64> = opt.estimates.iter().map(|e| e.t).collect();
            let est: Vec<f64> = opt.estimates.iter().map(|e| e.value).collect();
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
            let marks: Vec<f64> = accepted.iter().map(|p| p.t).collect();
            two_panel_png(
                &dir.join("indirect.png"),
                &format!("{}: model estimate vs true value; cost per repetition (orange: sets swapped in)", scn.name),
                &te,
                Panel { series: &[Series { name: "estimate", values: &est }, Series { name: "true", values: &tru }], label: "model parameter" },
                Panel {
                    series: &[
                        Series { name: "cost per repetition (tuned)", values: &cost },
                        Series { name: "frozen parameters", values: &cost_frozen },
                    ],
                    label: "cost",
                },
                &marks,
            )?;
        }
    }
    crate::report::write_json(dir, "summary.json", &summary).map_err(|e| e.to_string())?;
    if scn.output.plots {
        let ref_names: Vec<String> = (0..refs.len())
            .map(|i| {
                if i == 0 {
                    "reference".into()
                } else {
                    format!("r{i}")
                }
            })
            .collect();
        let mut top: Vec<Series> = refs
            .iter()
            .zip(&ref_names)
            .map(|(v, name)| Series { name, values: v })
            .collect();
        for (name, v) in &ys {
            top.push(Series { name, values: v });
        }
        let bottom: Vec<Series> = us
            .iter()
            .map(|(name, v)| Series { name, values: v })
            .collect();
        let marks: Vec<f64> = accepted.iter().map(|p| p.t).collect();
        two_panel_png(
            &dir.join("response.png"),
            &format!(
                "{} ({} mode): output vs reference, control; orange lines = parameter swaps",
                scn.name, ctrl.mode
            ),
            &t,
            Panel {
                series: &top,
                label: "position",
            },
            Panel {
                series: &bottom,
                label: "control u",
            },
            &marks,
        )?;
        if n_track > 1 {
            // Joint-space tracking: the errors are far below what the overlaid curves resolve.
            let errors: Vec<Vec<f64>> = (0..n_track)
                .map(|j| {
                    ref_cols[j]
                        .iter()
                        .zip(y_cols[j])
                        .map(|(r, y)| r - y)
                        .collect()
                })
                .collect();
            let names: Vec<String> = (0..n_track).map(|j| format!("e{j}")).collect();
            let top: Vec<Series> = errors
                .iter()
                .zip(&names)
                .map(|(v, name)| Series { name, values: v })
                .collect();
            two_panel_png(
                &dir.join("tracking.png"),
                &format!(
                    "{} ({} mode): tracking error r - y per joint, and joint torques",
                    scn.name, ctrl.mode
                ),
                &t,
                Panel {
                    series: &top,
                    label: "error (rad or m)",
                },
                Panel {
                    series: &bottom,
                    label: "torque u",
                },
                &marks,
            )?;
        }
    }
    Ok(summary)
}
