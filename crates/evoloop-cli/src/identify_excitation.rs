//! `evoloop identify excitation`: an optimal excitation trajectory for one identification stage.

use clap::Args;
use evoloop_identify::identify::excitation::{
    search, ExcitationProblem, Search, Settings, TrajectoryKind,
};
use evoloop_identify::identify::{Stage, StageKind};
use evoloop_report::plot::{xy_png, Curve, Style, XySeries};
use serde_json::json;
use std::path::PathBuf;

/// Options of `evoloop identify excitation`: the robot and stage, the trajectory's form and
/// limits, and the eMuPSO search.
#[derive(Args)]
pub struct ExcitationArgs {
    /// Robot description: a D-H table (.toml) or a URDF file (.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// Where to write the trajectory (JSON; a plot of it is written beside, same stem, .png).
    #[arg(long)]
    pub out: PathBuf,
    /// Which joints move: the wrist (last three), the arm (the others) or all.
    #[arg(long, value_parser = crate::choice::choice(&StageKind::ALL, StageKind::name), default_value = "all")]
    pub stage: StageKind,
    /// Seed of the search.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Period T of the trajectory, s (the paper: 10 s, fundamental 0.6283 rad/s).
    #[arg(long, default_value_t = 10.0)]
    pub period: f64,
    /// The trajectory: a joint-space Fourier series, or the paper's modified Fourier series (a
    /// Cartesian path of the wrist centre through inverse kinematics; arm and all stages).
    #[arg(long, value_parser = crate::choice::choice(&TrajectoryKind::ALL, TrajectoryKind::name), default_value = "fourier")]
    pub trajectory: TrajectoryKind,
    /// Harmonics (the last one brings the start to rest); default 5 for fourier, 3 (the
    /// paper's) for mfs.
    #[arg(long)]
    pub harmonics: Option<usize>,
    /// Instants of one period in the regressor whose condition number is minimised.
    #[arg(long, default_value_t = 100)]
    pub samples: usize,
    /// eMuPSO iterations after the elite phase (the paper: 30).
    #[arg(long, default_value_t = 30)]
    pub iterations: usize,
    /// eMuPSO particles (the paper: 20).
    #[arg(long, default_value_t = 20)]
    pub population: usize,
    /// Velocity limit, rad/s, for joints whose robot file gives none.
    #[arg(long, default_value_t = 2.0)]
    pub qd_max: f64,
    /// Acceleration limit, rad/s^2.
    #[arg(long, default_value_t = 8.0)]
    pub qdd_max: f64,
    /// Margin kept inside the position limits, rad.
    #[arg(long, default_value_t = 0.05)]
    pub margin: f64,
    /// Threads evaluating a swarm (default: every core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Print the result as JSON (the file's contents; key `cond`).
    #[arg(long)]
    pub json: bool,
}

/// `evoloop identify excitation`: search the trajectory, write it (JSON) and its plot (PNG).
/// Returns the exit code: 0, or 2 with the error on stderr.
pub fn main(a: &ExcitationArgs) -> i32 {
    match run(a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop identify excitation: {e}");
            2
        }
    }
}

fn run(a: &ExcitationArgs) -> Result<(), String> {
    let model = evoloop_dynamics::load(&a.robot).map_err(|e| e.to_string())?;
    for (key, v) in [
        ("--qd-max", a.qd_max),
        ("--qdd-max", a.qdd_max),
        ("--period", a.period),
    ] {
        if v.is_nan() || v <= 0.0 {
            return Err(format!("{key} {v}: must be > 0"));
        }
    }
    if a.margin.is_nan() || a.margin < 0.0 {
        return Err(format!("--margin {}: must be >= 0", a.margin));
    }
    if a.population < 2 || a.iterations == 0 {
        return Err("--population must be >= 2 and --iterations >= 1".into());
    }
    let stage = Stage::new(a.stage, &model).map_err(|e| e.to_string())?;
    let harmonics = a.harmonics.unwrap_or(match a.trajectory {
        TrajectoryKind::Fourier => 5,
        TrajectoryKind::Mfs => 3,
    });
    let settings = Settings {
        period: a.period,
        trajectory: a.trajectory,
        harmonics,
        samples: a.samples,
        margin: a.margin,
        qd_max: a.qd_max,
        qdd_max: a.qdd_max,
        ..Settings::default()
    };
    let problem = ExcitationProblem::new(model, stage, settings).map_err(|e| e.to_string())?;
    let s = Search {
        population: a.population,
        iterations: a.iterations,
        seed: a.seed,
        threads: a.threads.unwrap_or_else(evoloop_optim::all_cores).max(1),
        ..Search::default()
    };
    let hidden = a.quiet || a.json;
    let bar = evoloop_report::progress::bar(s.iterations as u64 + 1, "iterations", hidden);
    let mut progress = |phase: &str, it: usize, best: f64| {
        if phase == "elites" {
            bar.set_message(format!("elite phase: iteration {it}, {best} elites"));
        } else {
            bar.set_position(it as u64);
            bar.set_message(format!("best fitness {best:.4}"));
        }
    };
    let t0 = std::time::Instant::now();
    let o = search(&problem, &s, &mut progress).map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    let c = o.criteria;
    let model = &problem.model;
    let initial_cond_best = o
        .initial
        .iter()
        .map(|i| i.cond)
        .fold(f64::INFINITY, f64::min);
    let mut doc = json!({
        "robot": model.name,
        "robot_file": a.robot,
        "stage": problem.stage.name(),
        "kind": a.trajectory,
        "period": a.period,
        "harmonics": harmonics,
        "moving": problem.stage.moving,
        "hold": problem.stage.hold,
        "series": o.series,
        "reference": o.series.to_reference(),
        "cond": c.cond,
        "sigma_min": c.sigma_min,
        "sigma_max": c.sigma_max,
        "fitness": c.fitness,
        "excess": c.excess,
        "feasible": c.excess == 0.0,
        "initial": o.initial,
        "initial_cond_best": initial_cond_best,
        "feasible_elites": o.feasible_elites,
        "base_count": problem.base.base_count(),
        "base": problem.base.base.iter().map(|b| b.name.clone()).collect::<Vec<_>>(),
        "columns": problem.settings.columns,
        "limits": problem.limits,
        "settings": problem.settings,
        "search": s,
        "history": o.history,
        "evaluations": o.evaluations,
        "mutations": o.mutations,
        "seconds": t0.elapsed().as_secs_f64(),
    });
    if let Some(m) = &problem.mfs {
        let p = m.path(&o.x);
        doc["path"] = json!({
            "a": p.a, "b": p.b, "c": p.c, "centre": p.centre,
            "wrist_centre_body": m.wrist.body,
        });
        doc["fit_error"] = json!(m.decode(&problem.model, &o.x).map(|d| d.1));
    }
    let text = serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?;
    evoloop_files::write(&a.out, text + "\n").map_err(|e| format!("{}: {e}", a.out.display()))?;
    let png = a.out.with_extension("png");
    plot(&problem, &o.series, &png)?;
    if a.json {
        super::print_json(&doc);
        return Ok(());
    }
    out!(
        "{} stage of {}: {} base parameters, {} joints moving",
        problem.stage.name(),
        model.name,
        problem.base.base_count(),
        problem.stage.rows().len()
    );
    out!(
        "elites: {} of {} feasible; best initial cond {:.3}",
        o.feasible_elites,
        o.initial.len(),
        initial_cond_best
    );
    out!(
        "optimised: cond {:.3}, sigma_min {:.4}, sigma_max {:.4}, fitness (eq. 15) {:.3}{} ({} evaluations, {} mutations, {:.1} s)",
        c.cond,
        c.sigma_min,
        c.sigma_max,
        c.fitness,
        if c.excess > 0.0 {
            format!(", INFEASIBLE (excess {:.3e})", c.excess)
        } else {
            String::new()
        },
        o.evaluations,
        o.mutations,
        t0.elapsed().as_secs_f64()
    );
    out!("wrote {} and {}", a.out.display(), png.display());
    out!(
        "run it: [reference] kind = \"excitation\", file = \"{}\"",
        a.out.display()
    );
    Ok(())
}

/// The moving joints' positions over one period.
fn plot(
    problem: &ExcitationProblem,
    s: &evoloop_control::reference::series::FourierSeries,
    png: &std::path::Path,
) -> Result<(), String> {
    let k = 400;
    let t: Vec<f64> = (0..=k).map(|i| s.period * i as f64 / k as f64).collect();
    let curves: Vec<Curve> = problem
        .stage
        .rows()
        .into_iter()
        .map(|j| {
            let name = problem.model.bodies[j].joint.clone();
            (
                name,
                t.clone(),
                t.iter().map(|&x| s.joint(j, x).0).collect(),
            )
        })
        .collect();
    xy_png(
        png,
        &format!("excitation ({} stage, one period)", problem.stage.name()),
        "t (s)",
        "q (rad)",
        &XySeries::from_curves(&curves, Style::Line),
        None,
        None,
    )
    .map_err(|e| e.to_string())
}
