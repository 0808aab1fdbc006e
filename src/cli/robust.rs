//! `evoloop robust ...`: the robust-control tools from the command line.

use crate::optim::{run, DeConfig, DifferentialEvolution, Optimiser};
use crate::plant::two_mass::Sensor;
use crate::robust::problem::{Perturbation, RobustProblem};
use crate::robust::study::{lqr_gains, study};
use crate::robust::Wedge;
use clap::{Args, Subcommand, ValueEnum};
use serde_json::json;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum RobustCmd {
    /// Stability radius, closed-loop poles and wedge membership of a gain vector.
    Radius(RadiusArgs),
    /// LQR gains for the augmented two-mass system (u = -K x̂).
    Lqr(LqrArgs),
    /// One DE/rand/1/bin run maximising the stability radius inside the wedge.
    Tune(TuneArgs),
    /// Reproduce the paper's Tables 5-10 and Figs. 5-8 into a directory.
    Study(StudyArgs),
}

#[derive(Args, Clone)]
pub struct PlantArgs {
    /// Spring constant of the nominal plant.
    #[arg(long, default_value_t = 0.5)]
    pub k: f64,
    /// Sensor on the actuated body (the collocated variant) instead of body 2.
    #[arg(long)]
    pub collocated: bool,
}

#[derive(Args, Clone)]
pub struct WedgeArgs {
    /// Minimum damping ratio of the wedge, in (0, 1).
    #[arg(long, default_value_t = 0.7)]
    pub zeta: f64,
    /// Minimum decay rate of the wedge, > 0.
    #[arg(long, default_value_t = 1.0)]
    pub rho: f64,
    /// Perturbation structure: spring (where k enters A) or literal (the text's wording).
    #[arg(long, value_enum, default_value_t = PerturbationArg::Spring)]
    pub perturbation: PerturbationArg,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum PerturbationArg {
    Spring,
    Literal,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct RadiusArgs {
    /// Gains K1,K2,K3,K4,K5 (Table 9 order, u = -K x̂).
    #[arg(
        long,
        value_delimiter = ',',
        allow_hyphen_values = true,
        required = true
    )]
    pub gains: Vec<f64>,
    #[command(flatten)]
    pub plant: PlantArgs,
    #[command(flatten)]
    pub wedge: WedgeArgs,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct LqrArgs {
    /// Diagonal of Q (5 values).
    #[arg(long, value_delimiter = ',', default_value = "10,1,1,1,10")]
    pub q: Vec<f64>,
    /// R (scalar, > 0).
    #[arg(long, default_value_t = 1.0)]
    pub r: f64,
    #[command(flatten)]
    pub plant: PlantArgs,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct TuneArgs {
    /// DE mutation scale F.
    #[arg(long, default_value_t = 0.5)]
    pub f: f64,
    /// DE crossover rate CR.
    #[arg(long, default_value_t = 0.9)]
    pub cr: f64,
    /// Population size.
    #[arg(long, default_value_t = 100)]
    pub np: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Iteration limit.
    #[arg(long, default_value_t = 1000)]
    pub max_iter: usize,
    /// Stop on the paper's diversity rule (Table 3) instead of running to the limit.
    #[arg(long)]
    pub paper_stop: bool,
    /// Stop once this stability radius is reached.
    #[arg(long)]
    pub target: Option<f64>,
    /// Gain bound: every gain in [-bound, bound].
    #[arg(long, default_value_t = 50.0)]
    pub bound: f64,
    /// Threads for the population's evaluations.
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    #[command(flatten)]
    pub plant: PlantArgs,
    #[command(flatten)]
    pub wedge: WedgeArgs,
    #[arg(long)]
    pub json: bool,
}

#[derive(Args)]
pub struct StudyArgs {
    /// Output directory.
    #[arg(long, default_value = "runs/robust_study")]
    pub out: PathBuf,
    /// Seeded runs per (F, CR) setting.
    #[arg(long, default_value_t = 15)]
    pub runs: usize,
    #[arg(long, default_value_t = 2)]
    pub threads: usize,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

fn usage(msg: &str) -> i32 {
    eprintln!("error: {msg}");
    2
}

fn problem(plant: &PlantArgs, w: &WedgeArgs, bound: f64) -> Result<RobustProblem, String> {
    if !(plant.k > 0.0 && plant.k.is_finite()) {
        return Err(format!("--k must be > 0 (got {})", plant.k));
    }
    if !(bound > 0.0 && bound.is_finite()) {
        return Err(format!("--bound must be > 0 (got {bound})"));
    }
    let wedge = Wedge::new(w.zeta, w.rho)
        .map_err(|e| e.replace("zeta", "--zeta").replace("rho", "--rho"))?;
    let sensor = if plant.collocated {
        Sensor::Actuated
    } else {
        Sensor::Far
    };
    let pert = match w.perturbation {
        PerturbationArg::Spring => Perturbation::Spring,
        PerturbationArg::Literal => Perturbation::Literal,
    };
    Ok(RobustProblem::new(plant.k, sensor, pert, wedge, bound))
}

fn poles_json(p: &[(f64, f64)]) -> serde_json::Value {
    json!(p.iter().map(|(re, im)| [*re, *im]).collect::<Vec<_>>())
}

fn print_poles(p: &[(f64, f64)]) {
    for (re, im) in p {
        out!("    {re:+.6} {im:+.6}j");
    }
}

pub fn main(cmd: RobustCmd) -> i32 {
    match cmd {
        RobustCmd::Radius(a) => radius(a),
        RobustCmd::Lqr(a) => lqr_cmd(a),
        RobustCmd::Tune(a) => tune(a),
        RobustCmd::Study(a) => study_cmd(a),
    }
}

fn radius(a: RadiusArgs) -> i32 {
    if a.gains.len() != 5 {
        return usage(&format!(
            "--gains needs 5 values K1,K2,K3,K4,K5 (got {})",
            a.gains.len()
        ));
    }
    if a.gains.iter().any(|g| !g.is_finite()) {
        return usage("--gains must be finite numbers");
    }
    let prob = match problem(&a.plant, &a.wedge, 1e9) {
        Ok(p) => p,
        Err(e) => return usage(&e),
    };
    let ev = match prob.evaluate(&a.gains) {
        Ok(ev) => ev,
        Err(e) => {
            eprintln!("evoloop robust radius: {e}");
            return 1;
        }
    };
    if a.json {
        out!(
            "{}",
            json!({
                "gains": a.gains, "k": a.plant.k, "collocated": a.plant.collocated,
                "zeta": a.wedge.zeta, "rho": a.wedge.rho,
                "stability_radius": ev.stability_radius, "poles": poles_json(&ev.poles),
                "in_wedge": ev.in_wedge, "wedge_distance": ev.wedge_distance,
            })
        );
    } else {
        out!("stability radius r_c = {:.6}", ev.stability_radius);
        out!(
            "poles in wedge: {} (summed distance {:.6})",
            ev.in_wedge,
            ev.wedge_distance
        );
        out!("closed-loop poles:");
        print_poles(&ev.poles);
    }
    0
}

fn lqr_cmd(a: LqrArgs) -> i32 {
    if a.q.len() != 5 || a.q.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
        return usage(&format!("--q needs 5 finite values >= 0 (got {:?})", a.q));
    }
    if !(a.r > 0.0 && a.r.is_finite()) {
        return usage(&format!("--r must be > 0 (got {})", a.r));
    }
    if !(a.plant.k > 0.0 && a.plant.k.is_finite()) {
        return usage(&format!("--k must be > 0 (got {})", a.plant.k));
    }
    let sensor = if a.plant.collocated {
        Sensor::Actuated
    } else {
        Sensor::Far
    };
    let k = match lqr_gains(a.plant.k, sensor, &a.q, a.r) {
        Ok(k) => k,
        Err(e) => {
            eprintln!("error: {e}");
            return 1;
        }
    };
    let poles = RobustProblem::new(
        a.plant.k,
        sensor,
        Perturbation::Spring,
        Wedge {
            zeta: 0.7,
            rho: 1.0,
        },
        1e9,
    )
    .poles(&k)
    .iter()
    .map(|p| (p.re, p.im))
    .collect::<Vec<_>>();
    if a.json {
        out!(
            "{}",
            json!({"gains": k, "q": a.q, "r": a.r, "k": a.plant.k, "collocated": a.plant.collocated, "poles": poles_json(&poles)})
        );
    } else {
        out!(
            "K = [{}]   (u = -K x̂)",
            k.iter()
                .map(|v| format!("{v:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        out!("closed-loop poles:");
        print_poles(&poles);
    }
    0
}

fn tune(a: TuneArgs) -> i32 {
    let prob = match problem(&a.plant, &a.wedge, a.bound) {
        Ok(p) => p,
        Err(e) => return usage(&e),
    };
    let mut cfg = DeConfig::paper(a.f, a.cr, prob.lower.clone(), prob.upper.clone(), a.seed);
    cfg.np = a.np;
    cfg.diversity_stop = a.paper_stop;
    let mut de = match DifferentialEvolution::new(cfg) {
        Ok(d) => d,
        Err(e) => return usage(&e.to_string()),
    };
    if a.max_iter == 0 || a.threads == 0 {
        return usage("--max-iter and --threads must be >= 1");
    }
    let bar = crate::report::progress::bar(a.max_iter as u64, "iterations", a.json);
    let r = run(
        &mut de,
        &prob,
        a.threads,
        a.max_iter,
        a.target.map(|t| -t),
        |o| {
            bar.set_position(o.generation() as u64);
            bar.set_message(format!("best f(X) = {:+.6}", o.best().1));
        },
    );
    bar.abandon();
    let ev = match prob.evaluate(&r.best) {
        Ok(ev) => ev,
        Err(e) => {
            eprintln!("evoloop robust tune: the best set's {e}");
            return 1;
        }
    };
    if a.json {
        out!(
            "{}",
            json!({
                "gains": r.best, "stability_radius": ev.stability_radius, "f_x": r.value,
                "in_wedge": ev.in_wedge, "poles": poles_json(&ev.poles),
                "iterations": r.generations, "evaluations": r.evaluations, "seconds": r.seconds,
                "stopped_by": r.stopped_by, "seed": a.seed, "f": a.f, "cr": a.cr, "np": a.np,
            })
        );
    } else {
        out!(
            "K = [{}]",
            r.best
                .iter()
                .map(|v| format!("{v:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        out!(
            "stability radius r_c = {:.6}, poles in wedge: {}",
            ev.stability_radius,
            ev.in_wedge
        );
        out!(
            "{} iterations, {} evaluations, {:.3} s, stopped by {}",
            r.generations,
            r.evaluations,
            r.seconds,
            r.stopped_by
        );
        out!("closed-loop poles:");
        print_poles(&ev.poles);
    }
    0
}

fn study_cmd(a: StudyArgs) -> i32 {
    if a.runs < 2 || a.threads == 0 {
        return usage("--runs must be >= 2 and --threads >= 1");
    }
    let t0 = std::time::Instant::now();
    let bar = crate::report::progress::bar(0, "runs", a.quiet);
    let mut progress = |done: usize, total: usize, setting: &str| {
        bar.set_length(total as u64);
        bar.set_position(done as u64);
        bar.set_message(setting.to_string());
    };
    let result = study(&a.out, a.runs, a.threads, &mut progress);
    bar.finish_and_clear();
    match result {
        Ok(_) => {
            out!(
                "study done in {:.1} s: {}/report.md, study.json, runs.csv, responses.csv, poles.png, step_*.png",
                t0.elapsed().as_secs_f64(),
                a.out.display()
            );
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            1
        }
    }
}
