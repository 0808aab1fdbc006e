//! `evoloop robust ...`: the robust-control tools from the command line.

use clap::{Args, Subcommand, ValueEnum};
use evoloop_control::law::estimator::KalmanDesign;
use evoloop_control::plant::two_mass::Sensor;
use evoloop_optim::{run, DeConfig, DifferentialEvolution, Optimiser};
use evoloop_schemes::robust::observer::command_noise;
use evoloop_schemes::robust::problem::{Perturbation, RobustProblem};
use evoloop_schemes::robust::study::{lqr_gains, study};
use evoloop_schemes::robust::Wedge;
use serde_json::json;
use std::path::PathBuf;

/// The subcommands of `evoloop robust`: robust state feedback for the two-mass benchmark.
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

/// The nominal two-mass plant (m1 = m2 = 1): its spring constant and where its sensor sits.
#[derive(Args, Clone)]
pub struct PlantArgs {
    /// Spring constant of the nominal plant.
    #[arg(long, default_value_t = 0.5)]
    pub k: f64,
    /// Sensor on the actuated body (the collocated variant) instead of body 2.
    #[arg(long)]
    pub collocated: bool,
}

/// The wedge the closed-loop poles must lie in (minimum damping ratio and decay rate), and the
/// structure of the perturbation the stability radius is measured against.
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

/// The loop a machine with one position sensor runs (the default scenario's `state = "kalman"`).
#[derive(Args, Clone)]
pub struct ObserverArgs {
    /// Analyse the feedback acting on a steady-state Kalman filter's estimate from the one
    /// measured position, not on the full state the paper assumes: r_c of the loop with the
    /// filter, beside the full-state r_c and the springs the sampled loop stays stable for.
    #[arg(long)]
    pub observer: bool,
    /// The filter's sampling period, s (the scenario's timing.period).
    #[arg(long, default_value_t = 0.001)]
    pub period: f64,
    /// The filter's process noise: std of a disturbance at the input, held over a period.
    #[arg(long, default_value_t = evoloop_control::law::state_feedback::DEFAULT_PROCESS_NOISE)]
    pub process_noise: f64,
    /// The filter's measurement noise std [default: the default scenario's sensor,
    /// sqrt(0.0005² + 0.0001²/12) for noise 0.0005 and resolution 0.0001].
    #[arg(long)]
    pub measurement_noise: Option<f64>,
    /// The filter's state noise: std of a disturbance on every sampled state each period (0:
    /// none; what moves a collocated sensor's filter off the antiresonance).
    #[arg(long, default_value_t = 0.0)]
    pub state_noise: f64,
}

impl ObserverArgs {
    fn design(&self) -> Result<Option<KalmanDesign>, String> {
        if !self.observer {
            return Ok(None);
        }
        let measurement_noise = self
            .measurement_noise
            .unwrap_or_else(|| (0.0005f64.powi(2) + 0.0001f64.powi(2) / 12.0).sqrt());
        for (flag, v) in [
            ("--period", self.period),
            ("--process-noise", self.process_noise),
            ("--measurement-noise", measurement_noise),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("{flag} must be > 0 (got {v})"));
            }
        }
        if !(self.state_noise >= 0.0 && self.state_noise.is_finite()) {
            return Err(format!(
                "--state-noise must be finite and >= 0 (got {})",
                self.state_noise
            ));
        }
        Ok(Some(KalmanDesign {
            process_noise: self.process_noise,
            measurement_noise,
            state_noise: self.state_noise,
        }))
    }
}

/// The perturbation structure of `--perturbation` (`Perturbation` of `evoloop_schemes`).
#[derive(Clone, Copy, ValueEnum)]
pub enum PerturbationArg {
    /// Ê = diag(0,0,1,1,0), Ĥ = diag(1,1,0,0,0): exactly where the spring constant enters A
    Spring,
    /// Ê = diag(0,0,1,1,0), Ĥ = diag(0,1,1,0,0): the text's literal wording
    Literal,
}

/// Options of `evoloop robust radius`: a gain vector and the plant, wedge and filter it is
/// analysed with.
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
    /// The nominal plant the gains act on.
    #[command(flatten)]
    pub plant: PlantArgs,
    /// The pole wedge and the perturbation structure.
    #[command(flatten)]
    pub wedge: WedgeArgs,
    /// The Kalman filter between the one measured position and the gains, if `--observer`.
    #[command(flatten)]
    pub observer: ObserverArgs,
    /// Print the result as JSON
    #[arg(long)]
    pub json: bool,
}

/// Options of `evoloop robust lqr`: the LQR weights and the plant.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct LqrArgs {
    /// Diagonal of Q (5 values).
    #[arg(long, value_delimiter = ',', default_value = "10,1,1,1,10")]
    pub q: Vec<f64>,
    /// R (scalar, > 0).
    #[arg(long, default_value_t = 1.0)]
    pub r: f64,
    /// The nominal plant the LQR gains are designed for.
    #[command(flatten)]
    pub plant: PlantArgs,
    /// Print the gains and the closed-loop poles as JSON
    #[arg(long)]
    pub json: bool,
}

/// Options of `evoloop robust tune`: one DE/rand/1/bin run maximising the stability radius.
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
    /// Seed of the DE run
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
    /// The nominal plant being tuned for.
    #[command(flatten)]
    pub plant: PlantArgs,
    /// The pole wedge the gains must keep the loop in, and the perturbation structure.
    #[command(flatten)]
    pub wedge: WedgeArgs,
    /// The Kalman filter the gains act through, if `--observer`.
    #[command(flatten)]
    pub observer: ObserverArgs,
    /// Print the result as JSON (no progress bar)
    #[arg(long)]
    pub json: bool,
}

/// Options of `evoloop robust study`: the reproduction of the paper's Tables 5-10 and Figs. 5-8.
#[derive(Args)]
pub struct StudyArgs {
    /// Output directory.
    #[arg(long, default_value = "runs/robust_study")]
    pub out: PathBuf,
    /// Seeded runs per (F, CR) setting.
    #[arg(long, default_value_t = 15)]
    pub runs: usize,
    /// Threads evaluating each run's population
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

fn problem(
    plant: &PlantArgs,
    w: &WedgeArgs,
    observer: &ObserverArgs,
    bound: f64,
) -> Result<RobustProblem, String> {
    if !(plant.k > 0.0 && plant.k.is_finite()) {
        return Err(format!("--k must be > 0 (got {})", plant.k));
    }
    if !(bound > 0.0 && bound.is_finite()) {
        return Err(format!("--bound must be > 0 (got {bound})"));
    }
    // The wedge's message names its parameter first: the flag is that name after `--`.
    let wedge = Wedge::new(w.zeta, w.rho).map_err(|e| format!("--{e}"))?;
    let sensor = if plant.collocated {
        Sensor::Actuated
    } else {
        Sensor::Far
    };
    let pert = match w.perturbation {
        PerturbationArg::Spring => Perturbation::Spring,
        PerturbationArg::Literal => Perturbation::Literal,
    };
    let prob = RobustProblem::new(plant.k, sensor, pert, wedge, bound);
    match observer.design()? {
        None => Ok(prob),
        Some(d) => prob
            .with_observer(d, observer.period)
            .map_err(|e| e.to_string()),
    }
}

/// What a loop with a filter adds to a report: the full-state r_c beside the loop's, the
/// filter's poles, and the springs the loop stays stable for. None without a filter.
fn filter_report(prob: &RobustProblem, gains: &[f64], r_c: f64) -> Option<serde_json::Value> {
    let o = prob.observer.as_ref()?;
    let full = prob.clone().without_observer();
    let full_rc = full.evaluate(gains).map(|e| e.stability_radius).ok();
    let full_springs = full_rc.map(|rc| full.spring_ranges(gains, rc).continuous);
    let poles: Vec<(f64, f64)> = o
        .error_poles(&prob.nominal_model())
        .iter()
        .map(|p| (p.re, p.im))
        .collect();
    let springs = prob.spring_ranges(gains, r_c);
    let u_noise = command_noise(
        &prob.nominal_model(),
        &o.filter,
        o.period,
        gains,
        o.design.measurement_noise,
    );
    Some(json!({
        "command_noise": u_noise,
        "full_state_stability_radius": full_rc,
        "full_state_springs": full_springs,
        "filter": {
            "period": o.period, "process_noise": o.design.process_noise,
            "measurement_noise": o.design.measurement_noise,
            "state_noise": o.design.state_noise,
            "poles": poles_json(&poles), "l_c": o.l_c.as_slice(),
        },
        "spring_ranges": springs,
    }))
}

fn print_filter_report(r: &serde_json::Value) {
    let range = |v: &serde_json::Value| {
        if v[0].as_f64().is_some() && v[0] == v[1] {
            return "none: unstable at the nominal spring".to_string();
        }
        format!(
            "[{}, {}]",
            v[0].as_f64()
                .map_or("below k/1000".into(), |x| format!("{x:.4}")),
            v[1].as_f64()
                .map_or("above 1000 k".into(), |x| format!("{x:.4}"))
        )
    };
    match r["full_state_stability_radius"].as_f64() {
        Some(v) => out!("  full state (the paper's assumption): r_c = {v:.6}"),
        None => out!("  full state (the paper's assumption): r_c not computable"),
    }
    let s = &r["spring_ranges"];
    if !s["guaranteed"].is_null() {
        out!("springs the loop is stable for:");
        out!(
            "  guaranteed by r_c (|dk| < r_c/2): {}",
            range(&s["guaranteed"])
        );
    }
    out!(
        "  continuous loop with the filter:  {}",
        range(&s["continuous"])
    );
    out!(
        "  sampled loop, as the controller runs: {}",
        range(&s["sampled"])
    );
    if let Some(v) = r["command_noise"].as_f64() {
        out!(
            "std of u from the sensor's noise ({} std), in steady state: {v:.4}",
            r["filter"]["measurement_noise"]
        );
    }
    out!("filter poles (continuous equivalent, L_c = L/T):");
    for p in r["filter"]["poles"].as_array().into_iter().flatten() {
        out!(
            "    {:+.6} {:+.6}j",
            p[0].as_f64().unwrap_or(f64::NAN),
            p[1].as_f64().unwrap_or(f64::NAN)
        );
    }
}

fn poles_json(p: &[(f64, f64)]) -> serde_json::Value {
    json!(p.iter().map(|(re, im)| [*re, *im]).collect::<Vec<_>>())
}

fn print_poles(p: &[(f64, f64)]) {
    for (re, im) in p {
        out!("    {re:+.6} {im:+.6}j");
    }
}

/// `evoloop robust SUBCOMMAND`: run it and return the exit code: 0, 1 when the computation
/// fails, 2 for a bad argument.
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
    let prob = match problem(&a.plant, &a.wedge, &a.observer, 1e9) {
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
    let filter = filter_report(&prob, &a.gains, ev.stability_radius);
    if a.json {
        let mut v = json!({
            "gains": a.gains, "k": a.plant.k, "collocated": a.plant.collocated,
            "zeta": a.wedge.zeta, "rho": a.wedge.rho,
            "stability_radius": ev.stability_radius, "poles": poles_json(&ev.poles),
            "in_wedge": ev.in_wedge, "wedge_distance": ev.wedge_distance,
        });
        if let Some(f) = filter {
            v["observer"] = f;
        }
        out!("{v}");
    } else {
        match &filter {
            Some(_) => out!(
                "stability radius r_c = {:.6} (the loop with the Kalman filter)",
                ev.stability_radius
            ),
            None => out!("stability radius r_c = {:.6}", ev.stability_radius),
        }
        if let Some(f) = &filter {
            print_filter_report(f);
        }
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
    let prob = match problem(&a.plant, &a.wedge, &a.observer, a.bound) {
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
    let bar = evoloop_report::progress::bar(a.max_iter as u64, "iterations", a.json);
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
    let filter = filter_report(&prob, &r.best, ev.stability_radius);
    if a.json {
        let mut v = json!({
            "gains": r.best, "stability_radius": ev.stability_radius, "f_x": r.value,
            "in_wedge": ev.in_wedge, "poles": poles_json(&ev.poles),
            "iterations": r.generations, "evaluations": r.evaluations, "seconds": r.seconds,
            "stopped_by": r.stopped_by, "seed": a.seed, "f": a.f, "cr": a.cr, "np": a.np,
        });
        if let Some(f) = filter {
            v["observer"] = f;
        }
        out!("{v}");
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
        if let Some(f) = &filter {
            print_filter_report(f);
        }
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
    let bar = evoloop_report::progress::bar(0, "runs", a.quiet);
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
