//! `evoloop identify lls`: base parameters by least squares from excitation runs.

use clap::Args;
use evoloop_identify::identify::lls::{estimate, Estimate, Options, Recording};
use evoloop_report::plot::{xy_png, Curve, Style, XySeries};
use serde_json::json;
use std::path::PathBuf;

/// Options of `evoloop identify lls`: the robot file to compare with, the excitation runs, and how
/// their data are processed.
#[derive(Args)]
pub struct LlsArgs {
    /// Robot description whose parameters are the truth the estimate is compared with (the
    /// simulated arm's file).
    #[arg(long)]
    pub robot: PathBuf,
    /// Run directory of an excitation run (run.csv and scenario.json). Give it twice for the
    /// paper's two stages, wrist run first then arm run; one run of every joint is one stage.
    #[arg(long, required = true)]
    pub data: Vec<PathBuf>,
    /// Standard deviation of Gaussian noise added to the recorded torques, N m (the positions
    /// carry the run's own `plant.noise_std`).
    #[arg(long, default_value_t = 0.0)]
    pub torque_noise: f64,
    /// Seed of the torque noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Periods dropped at the start of each run (the controller's start-up).
    #[arg(long, default_value_t = 1)]
    pub skip: usize,
    /// Fourier harmonics kept when the positions are differentiated.
    #[arg(long, default_value_t = 20)]
    pub harmonics: usize,
    /// Directory for lls.json and the validation plots (default: the first run directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print JSON (keys base, base_true, base_estimate, relative_error, torque_rms_validation,
    /// stages).
    #[arg(long)]
    pub json: bool,
}

/// `evoloop identify lls`: estimate the base parameters, write lls.json and the validation plots.
/// Returns the exit code: 0, or 2 with the error on stderr.
pub fn main(a: &LlsArgs) -> i32 {
    match run(a) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop identify lls: {e}");
            2
        }
    }
}

fn run(a: &LlsArgs) -> Result<(), String> {
    let model = evoloop_dynamics::load(&a.robot).map_err(|e| e.to_string())?;
    if a.torque_noise.is_nan() || a.torque_noise < 0.0 {
        return Err(format!("--torque-noise {}: must be >= 0", a.torque_noise));
    }
    let o = Options {
        skip: a.skip,
        harmonics: a.harmonics.max(1),
        ..Options::default()
    };
    let mut stages: Vec<Estimate> = Vec::new();
    for (i, dir) in a.data.iter().enumerate() {
        let mut rec = Recording::from_run(dir).map_err(|e| e.to_string())?;
        if a.torque_noise > 0.0 {
            rec.add_torque_noise(a.torque_noise, a.seed.wrapping_add(i as u64));
        }
        let e = estimate(&model, &rec, &o).map_err(|e| format!("{}: {e}", dir.display()))?;
        stages.push(e);
    }
    let out = a.out.clone().unwrap_or_else(|| a.data[0].clone());
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let several = stages.len() > 1;
    let name = |e: &Estimate, b: &str| {
        if several {
            format!("{}:{b}", e.stage)
        } else {
            b.to_string()
        }
    };
    let flat =
        |f: &dyn Fn(&Estimate) -> Vec<f64>| -> Vec<f64> { stages.iter().flat_map(f).collect() };
    // Per joint: the validation RMS of the stage that moved it.
    let n = model.dof();
    let mut rms = vec![None; n];
    for e in &stages {
        for (r, v) in rms.iter_mut().zip(&e.torque_rms_validation) {
            if v.is_some() {
                *r = *v;
            }
        }
    }
    let doc = json!({
        "robot": model.name,
        "data": a.data,
        "base": stages.iter().flat_map(|e| e.base.iter().map(|b| name(e, b))).collect::<Vec<_>>(),
        "base_true": flat(&|e| e.base_true.clone()),
        "base_estimate": flat(&|e| e.base_estimate.clone()),
        "relative_error": stages.iter().flat_map(|e| e.relative_error.clone()).collect::<Vec<_>>(),
        "absolute_error": flat(&|e| e.absolute_error.clone()),
        "torque_rms_validation": rms,
        "model_parameters": stages.iter().find_map(|e| e.model_parameters.clone()),
        "model_parameter_names": o.columns.names(&model),
        "stages": stages,
        "torque_noise": a.torque_noise,
        "options": o,
    });
    let path = out.join("lls.json");
    let text = serde_json::to_string_pretty(&doc).map_err(|e| e.to_string())?;
    evoloop_files::write(&path, text + "\n").map_err(|e| format!("{}: {e}", path.display()))?;
    let mut plots = Vec::new();
    for e in &stages {
        let png = out.join(format!("lls_validation_{}.png", e.stage));
        let v = &e.validation;
        let mut curves: Vec<Curve> = Vec::new();
        for (r, &j) in v.joints.iter().enumerate() {
            let joint = &model.bodies[j].joint;
            curves.push((
                format!("{joint} measured"),
                v.t.clone(),
                v.measured[r].clone(),
            ));
            curves.push((
                format!("{joint} predicted"),
                v.t.clone(),
                v.predicted[r].clone(),
            ));
        }
        xy_png(
            &png,
            &format!("torque on the held-out period ({} stage)", e.stage),
            "t (s)",
            "torque (N m)",
            &XySeries::from_curves(&curves, Style::Line),
            None,
            None,
        )
        .map_err(|e| e.to_string())?;
        plots.push(png);
    }
    if a.json {
        super::print_json(&doc);
        return Ok(());
    }
    for e in &stages {
        out!(
            "{} stage: {} base parameters from {} averaged periods, cond {:.1}; relative error (2-norm) {:.3e}",
            e.stage,
            e.base.len(),
            e.periods,
            e.cond,
            e.relative_error_norm
        );
        out!(
            "  {:<48} {:>14} {:>14} {:>10} {:>10}",
            "base parameter",
            "true",
            "estimate",
            "abs. error",
            "rel. error"
        );
        for i in 0..e.base.len() {
            out!(
                "  {:<48} {:>14.6} {:>14.6} {:>10.2e} {:>10}",
                e.regrouping[i],
                e.base_true[i],
                e.base_estimate[i],
                e.absolute_error[i],
                e.relative_error[i].map_or("-".to_string(), |r| format!("{r:.2e}"))
            );
        }
        let mut line = String::from("  validation torque rms (measured rms) per joint:");
        for (j, v) in e.torque_rms_validation.iter().enumerate() {
            if let (Some(v), Some(m)) = (v, e.torque_rms_measured[j]) {
                line += &format!(" {}: {v:.3} ({m:.2})", model.bodies[j].joint);
            }
        }
        out!("{line}");
    }
    out!("wrote {}", path.display());
    for p in plots {
        out!("wrote {}", p.display());
    }
    Ok(())
}
