//! `evoloop identify study`: optimised against random feasible excitation, paired over seeds.

use clap::Args;
use evoloop_identify::identify::excitation::{ExcitationProblem, Search, Settings, TrajectoryKind};
use evoloop_identify::identify::study::{run, SeedResult};
use evoloop_identify::identify::{Stage, StageKind};
use evoloop_report::plot::{xy_png, Curve, Style, XySeries};
use evoloop_scenario::config::{Overrides, Scenario};
use evoloop_stats::{mean_ci, median, paired_sentence, wilcoxon};
use serde_json::json;
use std::path::PathBuf;

/// Options of `evoloop identify study`: the experiment's scenario, the seeds, the searches'
/// settings and the torque noise.
#[derive(Args)]
pub struct StudyArgs {
    /// The identification experiment: an arm scenario whose reference each trajectory replaces
    /// (its duration must hold at least three periods).
    #[arg(long, default_value = "config/industrial6/industrial6_identify.toml")]
    pub scenario: PathBuf,
    /// Seeds 0..N (search, encoder noise and torque noise).
    #[arg(long, default_value_t = 10)]
    pub seeds: u64,
    /// Which joints move: the wrist (last three), the arm (the others) or all.
    #[arg(long, value_parser = crate::choice::choice(&StageKind::ALL, StageKind::name), default_value = "all")]
    pub stage: StageKind,
    /// The trajectory: a joint-space Fourier series, or the paper's modified Fourier series (mfs)
    #[arg(long, value_parser = crate::choice::choice(&TrajectoryKind::ALL, TrajectoryKind::name), default_value = "fourier")]
    pub trajectory: TrajectoryKind,
    /// eMuPSO iterations per search.
    #[arg(long, default_value_t = 30)]
    pub iterations: usize,
    /// Standard deviation of the torque measurement noise, N m.
    #[arg(long, default_value_t = 2.0)]
    pub torque_noise: f64,
    /// Output directory (results.json, report.md, errors.png).
    #[arg(long, default_value = "runs/identify_study")]
    pub out: PathBuf,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
    /// Print results.json on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `evoloop identify study`: run the study, write results.json, report.md and errors.png.
/// Returns the exit code: 0, or 2 with the error on stderr.
pub fn main(a: &StudyArgs) -> i32 {
    match study(a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop identify study: {e}");
            2
        }
    }
}

/// The study's inputs checked, and the excitation problem of its scenario's arm and stage with
/// the scenario's text.
fn prepare(a: &StudyArgs) -> Result<(ExcitationProblem, String), String> {
    if a.seeds < 2 {
        return Err("--seeds must be >= 2 (a paired comparison)".into());
    }
    if a.torque_noise.is_nan() || a.torque_noise < 0.0 {
        return Err(format!("--torque-noise {}: must be >= 0", a.torque_noise));
    }
    let scn = Scenario::load(&a.scenario, &Overrides::default()).map_err(|e| e.to_string())?;
    let text = evoloop_files::read_text(&a.scenario).map_err(|e| e.to_string())?;
    let model = scn
        .plant
        .model
        .config()
        .rigid_body()
        .ok_or("the scenario's plant is not an arm")?
        .clone();
    let settings = Settings {
        trajectory: a.trajectory,
        harmonics: if a.trajectory == TrajectoryKind::Mfs {
            3
        } else {
            5
        },
        ..Settings::default()
    };
    scn.require_in_process().map_err(|e| e.to_string())?;
    if scn.timing.duration < 3.0 * settings.period {
        return Err(format!(
            "{}: timing.duration {} s holds fewer than three {} s periods (one dropped, one \
             averaged, one held out)",
            a.scenario.display(),
            scn.timing.duration,
            settings.period
        ));
    }
    let stage = Stage::new(a.stage, &model).map_err(|e| e.to_string())?;
    let problem = ExcitationProblem::new(model, stage, settings).map_err(|e| e.to_string())?;
    Ok((problem, text))
}

fn study(a: &StudyArgs) -> Result<(), String> {
    let (problem, text) = prepare(a)?;
    let search = Search {
        iterations: a.iterations,
        ..Search::default()
    };
    let seeds: Vec<u64> = (0..a.seeds).collect();
    let bar = evoloop_report::progress::bar(a.seeds, "seeds", a.quiet || a.json);
    let rows = run(
        &problem,
        &text,
        &a.scenario,
        &seeds,
        &search,
        a.torque_noise,
        &mut |r: &SeedResult| {
            bar.inc(1);
            bar.set_message(format!(
                "seed {}: error {:.3} % optimised, {:.3} % initial",
                r.seed, r.error_optimised, r.error_initial
            ));
        },
    )
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let opt: Vec<f64> = rows.iter().map(|r| r.error_optimised).collect();
    let ini: Vec<f64> = rows.iter().map(|r| r.error_initial).collect();
    let w = wilcoxon(&opt, &ini);
    let diff: Vec<f64> = opt.iter().zip(&ini).map(|(o, i)| o - i).collect();
    let d = mean_ci(&diff);
    let sentence = paired_sentence(
        "The optimised trajectory",
        "optimised",
        "the first feasible random one",
        "relative error of the identified base parameters (%)",
        &w,
        &d,
    );
    let cond_o: Vec<f64> = rows.iter().map(|r| r.cond_optimised).collect();
    let cond_i: Vec<f64> = rows.iter().map(|r| r.cond_initial).collect();
    let doc = json!({
        "scenario": a.scenario,
        "stage": problem.stage.name(),
        "trajectory": a.trajectory,
        "torque_noise": a.torque_noise,
        "iterations": a.iterations,
        "seeds": rows,
        "median_error_optimised": median(&opt),
        "median_error_initial": median(&ini),
        "median_cond_optimised": median(&cond_o),
        "median_cond_initial": median(&cond_i),
        "wilcoxon": w,
        "mean_difference": d,
        "sentence": sentence,
    });
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    let path = a.out.join("results.json");
    evoloop_files::write(
        &path,
        serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())? + "\n",
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut md = format!(
        "# Optimised against random excitation ({} stage, {} trajectory)\n\n\
         Experiment `{}`, run in-process per seed with the seed's encoder noise and {} N m torque \
         noise; {} seeds; eMuPSO {} iterations.\n\n{}\n\n\
         Median condition number: optimised {:.1}, initial {:.1}. Median relative error: \
         optimised {:.3} %, initial {:.3} %.\n\n\
         | seed | cond initial | cond optimised | error initial (%) | error optimised (%) |\n\
         |---|---|---|---|---|\n",
        problem.stage.name(),
        serde_json::to_value(a.trajectory)
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
            .unwrap_or_default(),
        a.scenario.display(),
        a.torque_noise,
        a.seeds,
        a.iterations,
        sentence,
        median(&cond_o),
        median(&cond_i),
        median(&opt),
        median(&ini)
    );
    for r in &rows {
        md += &format!(
            "| {} | {:.1} | {:.1} | {:.3} | {:.3} |\n",
            r.seed, r.cond_initial, r.cond_optimised, r.error_initial, r.error_optimised
        );
    }
    evoloop_files::write(a.out.join("report.md"), md).map_err(|e| e.to_string())?;
    let x: Vec<f64> = rows.iter().map(|r| r.seed as f64).collect();
    let curves: Vec<Curve> = vec![
        ("first feasible random".into(), x.clone(), ini.clone()),
        ("optimised".into(), x.clone(), opt.clone()),
    ];
    xy_png(
        &a.out.join("errors.png"),
        "identified base parameters: relative error per seed",
        "seed",
        "relative error (%)",
        &XySeries::from_curves(&curves, Style::Points),
        None,
        None,
    )
    .map_err(|e| e.to_string())?;
    if a.json {
        super::print_json(&doc);
        return Ok(());
    }
    out!("{sentence}");
    out!(
        "median cond: optimised {:.1}, initial {:.1}; median error: optimised {:.3} %, initial {:.3} %",
        median(&cond_o),
        median(&cond_i),
        median(&opt),
        median(&ini)
    );
    out!("wrote {}, report.md, errors.png", path.display());
    Ok(())
}
