//! Assemble the run report from what the processes wrote: `summary.json` and `response.png`.

use super::metrics::response_metrics;
use super::plot::{two_panel_png, Panel, Series};
use super::summary::{
    ControllerReport, FloorReport, OptimiserReport, ParamVersions, PlantReport, RealtimePrivileges,
    Summary,
};
use super::Table;
use crate::config::Scenario;
use std::path::Path;

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
) -> Result<Summary, String> {
    let dir = &scn.output.dir;
    let ctrl: ControllerReport = read_json(dir, "controller.json")?;
    let plant: PlantReport = read_json(dir, "plant.json").unwrap_or_default();
    let opt: OptimiserReport = read_json(dir, "optimiser.json").unwrap_or_default();
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
    let summary = Summary {
        scenario: scn.name.clone(),
        config: scn.source.display().to_string(),
        run_id: run_id.to_string(),
        mode: ctrl.mode.clone(),
        seed: scn.seed,
        duration_s: scn.timing.duration,
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
        optimiser_published: opt.published.len(),
        interrupted: ctrl.interrupted || plant.interrupted || opt.interrupted,
        stale_resources_cleaned: cleaned,
    };
    crate::process::write_json(dir, "summary.json", &summary).map_err(|e| e.to_string())?;
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
