//! `evoloop tune SCENARIO` on a scenario with `optimiser.mode = "direct"`: the live direct run
//! simulated in this process (`direct::run_in_process`), the same costs and final set as
//! `evoloop run SCENARIO --mode lockstep` through the processes, in a fraction of the time.

use crate::config::{OptimiserMode, Overrides, Scenario};
use crate::TuneError;
use evoloop_control::check::Check;
use evoloop_schemes::WriteError;
use serde_json::json;
use std::path::Path;

/// Whether `file` is a scenario (it has a `[controller]` table) rather than an experiment file.
pub fn is_scenario(text: &str) -> bool {
    text.parse::<toml::Table>()
        .is_ok_and(|t| t.contains_key("controller") && !t.contains_key("experiment"))
}

/// Tune the direct scenario `file` in this process in lockstep (with `--compare`:
/// compare the optimisers over the seeds); writes direct.json and the scheme's
/// files into its output directory and prints a summary or the JSON. Fails with
/// `--seeds` but no `--compare`, or on a scenario not of the direct scheme.
pub fn run(file: &Path, a: &super::TuneRequest) -> Result<(), TuneError> {
    if let Some(algorithms) = &a.compare {
        let seeds = a.seeds.clone().unwrap_or_else(|| vec![a.seed.unwrap_or(1)]);
        return super::compare::run(file, algorithms, &seeds, a);
    }
    if a.seeds.is_some() {
        return Err(TuneError::option(
            "--seeds",
            "a direct scenario is tuned for one seed at a time (--seed N), or compared over seeds with --compare",
        ));
    }
    let ov = Overrides {
        seed: a.seed,
        out: a.out.clone(),
        ..Overrides::default()
    };
    let scn = Scenario::load(file, &ov)?;
    if scn.optimiser.mode != OptimiserMode::Direct {
        let reason = format!(
            "`evoloop tune` runs scenarios of the direct scheme (\"direct\"); this one is {:?} (run it with `evoloop run`)",
            scn.optimiser.mode
        );
        return Check::new(file)
            .fail("optimiser.mode", reason)
            .map_err(TuneError::from);
    }
    let dir = scn.output.dir.clone();
    std::fs::create_dir_all(&dir).map_err(WriteError::file(&dir))?;
    let total = scn.optimiser.evaluations + 1;
    let t0 = std::time::Instant::now();
    let bar = crate::report::progress::bar(total as u64, "repetitions", a.quiet || a.json);
    bar.set_prefix("direct: ");
    let r = evoloop_schemes::direct::run_in_process(&scn, |n, best| {
        bar.set_position(n as u64);
        bar.set_message(format!("best {best:.4}"));
    });
    bar.abandon();
    let r = r?;
    let seconds = t0.elapsed().as_secs_f64();
    let report = &r.report;
    let baseline = report
        .repetitions
        .iter()
        .find(|r| r.trial == 0)
        .map(|b| b.cost);
    let result = json!({
        "experiment": "direct",
        "scenario": scn.name,
        "seed": scn.seed,
        "direct": report,
        "baseline_cost": baseline,
        "final_version": r.final_version,
        "final_params": r.final_params,
        "trials_aborted": r.trials_aborted,
        "seconds": seconds,
    });
    crate::report::write_json(&dir, "direct.json", &result)
        .map_err(WriteError::file(&dir.join("direct.json")))?;
    let files = evoloop_schemes::direct::write_files(&dir, report, scn.output.plots)?;
    if a.json {
        crate::report::print_json(&result);
    } else {
        println!(
            "{} (direct scheme, in-process lockstep): {} trials of {} on the plant, {} aborted; cost {} (configured set) -> {:.4} (best, version {}), {:.2} s",
            scn.name,
            report.repetitions.len().saturating_sub(1),
            report.algorithm,
            report.aborted,
            baseline.map_or("-".into(), |b| format!("{b:.4}")),
            report.best_cost,
            report.best_version,
            seconds
        );
        println!(
            "  wrote {}/direct.json, {}",
            dir.display(),
            files.join(", ")
        );
    }
    Ok(())
}
