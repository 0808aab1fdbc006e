//! The magnetic-levitation experiment of Section 5.2 as a command: the PID with fuzzy
//! anti-windup tuned by the GA alone (150 iterations, 310 evaluations) for the index of eq. 31,
//!   G = sum |e_n| / mm + sum |u_n| / 1000 mA,
//! over a set-point trajectory whose steps drive the coil current into both limits, beside the
//! same PID with no anti-windup, with clamping and with back-calculation, each tuned by the same
//! GA budget. A candidate that loses the ball (leaves +-4.5 mm) is unstable: the GA replaces it
//! by the current best, as the paper does.

use super::{Run, TuneError};
use crate::law::pid::{fuzzy_ki_normalised, AntiWindup};
use crate::optim::hybrid::hybrid;
use crate::reference::Reference;
use crate::report::plot::{two_panel_png, xy_png, Panel, Series, Style, XySeries};
use crate::report::progress::Optimisation;
use crate::report::Csv;
pub use crate::sim::maglev::{
    default_reference, simulate, Cost, Objective, Spec, Trace, PAPER_FUZZY,
};
use evoloop_control::check::{Check, ConfigError};
use evoloop_schemes::WriteError;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::path::Path;

/// The `[maglev]` table of an experiment file as read, every key optional (`spec`
/// checks them and fills in `Spec::default()`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawMaglevTune {
    mass: Option<f64>,
    period: Option<f64>,
    step: Option<f64>,
    noise_mm: Option<f64>,
    duration: Option<f64>,
    times: Option<Vec<f64>>,
    values: Option<Vec<f64>>,
}

/// The experiment's `Spec`: the defaults with the `[maglev]` table's values (ball
/// mass, kg; period, step and duration, s; noise, mm; the set-point steps' `times`,
/// s, and `values`, mm). Fails, naming the key, on a value out of its range, times
/// not strictly increasing, or `times` and `values` not given together.
pub fn spec(file: &Path, raw: Option<RawMaglevTune>) -> Result<Spec, ConfigError> {
    let mut s = Spec::default();
    let Some(r) = raw else { return Ok(s) };
    let file_check = Check::new(file);
    let check =
        |key: &str, v: f64, lo: f64, hi: f64| file_check.range(&format!("maglev.{key}"), v, lo, hi);
    if let Some(m) = r.mass {
        s.plant.mass = check("mass", m, 0.01, 2.0)?;
    }
    if let Some(p) = r.period {
        s.period = check("period", p, 1e-4, 0.01)?;
    }
    if let Some(h) = r.step {
        s.step = check("step", h, 1e-6, s.period)?;
    }
    if let Some(n) = r.noise_mm {
        s.noise_mm = check("noise_mm", n, 0.0, 1.0)?;
    }
    if let Some(d) = r.duration {
        s.duration = check("duration", d, 0.01, 600.0)?;
    }
    match (r.times, r.values) {
        (None, None) => {}
        (Some(t), Some(v)) if !t.is_empty() && t.len() == v.len() => {
            for i in 0..t.len() {
                check(&format!("values[{i}]"), v[i], -4.0, 4.0)?;
                if i > 0 && t[i] <= t[i - 1] {
                    return file_check.fail(
                        &format!("maglev.times[{i}]"),
                        "times must be strictly increasing",
                    );
                }
            }
            s.reference = Reference::Steps {
                times: t,
                values: v,
            };
        }
        _ => {
            return file_check.fail(
                "maglev.values",
                "`times` and `values` go together, same length, at least one step",
            )
        }
    }
    Ok(s)
}

/// One variant tuned: its best parameters and the GA's record.
#[derive(Debug, Clone, Serialize)]
pub struct Tuned {
    /// The anti-windup variant tuned.
    pub anti_windup: AntiWindup,
    /// The best parameters found, in `names`' order.
    pub params: Vec<f64>,
    /// The parameters' names (`AntiWindup::param_names`).
    pub names: Vec<&'static str>,
    /// Eq. 31's G of `params` on the tuning run (noise seed: the run's seed).
    pub g_tuning: f64,
    /// The cost on the test run (noise seed + 1000); None when the ball was lost.
    pub test: Option<Cost>,
    /// Objective evaluations the tuning spent.
    pub evaluations: usize,
    /// The tuning's wall-clock time, s.
    pub seconds: f64,
    /// Best G so far after each evaluation.
    pub best_so_far: Vec<f64>,
}

/// Tune one variant with the GA alone and evaluate it on the test run (another noise seed).
pub fn tune_variant(run: &Run, spec: &Spec, aw: AntiWindup) -> Tuned {
    let (lo, hi) = aw.paper_ranges();
    let obj = Objective {
        spec: spec.clone(),
        aw,
        seed: run.seed,
    };
    let mut cfg = run.hybrid.clone();
    cfg.scaling.clear();
    let total = cfg.ga.population + 2 * cfg.phases.iter().sum::<usize>();
    let bar = Optimisation::new(aw.name(), total, "G", !run.progress);
    let r = hybrid(&cfg, &obj, &lo, &hi, &[], |n, best| bar.tell(n, best));
    drop(bar);
    Tuned {
        anti_windup: aw,
        test: simulate(spec, aw, &r.best, run.seed + 1000, None),
        params: r.best,
        names: aw.param_names().to_vec(),
        g_tuning: r.value,
        evaluations: r.evaluations,
        seconds: r.seconds,
        best_so_far: r.best_so_far,
    }
}

/// Section 5.2's experiment on one seed: each anti-windup variant tuned with the same
/// budget and scored on the test run; writes result.json, response.csv and (with
/// plots) the figures into `run.out`, and prints a summary or the JSON.
pub fn run(run: Run, spec: Spec) -> Result<(), TuneError> {
    let variants = [
        AntiWindup::Fuzzy,
        AntiWindup::Clamping,
        AntiWindup::BackCalculation,
        AntiWindup::None,
        AntiWindup::IntegratorClamp,
    ];
    let tuned: Vec<Tuned> = variants
        .iter()
        .map(|aw| tune_variant(&run, &spec, *aw))
        .collect();
    let fz = &tuned[0];
    let g_of = |t: &Tuned| t.test.map_or(serde_json::Value::Null, |c| json!(c.g));
    let params: serde_json::Map<String, serde_json::Value> = fz
        .names
        .iter()
        .zip(&fz.params)
        .map(|(n, v)| (n.to_string(), json!(v)))
        .collect();
    let paper: serde_json::Map<String, serde_json::Value> = fz
        .names
        .iter()
        .zip(PAPER_FUZZY)
        .map(|(n, v)| (n.to_string(), json!(v)))
        .collect();
    let paper_cost = simulate(
        &spec,
        AntiWindup::Fuzzy,
        &PAPER_FUZZY,
        run.seed + 1000,
        None,
    );
    let result = json!({
        "experiment": "maglev",
        "seed": run.seed,
        "params": params,
        "paper_params": paper,
        "paper_params_G": paper_cost.map(|c| c.g),
        "G": {
            "fuzzy_aw": g_of(&tuned[0]),
            "clamping": g_of(&tuned[1]),
            "back_calculation": g_of(&tuned[2]),
            "none": g_of(&tuned[3]),
            "integrator_clamp": g_of(&tuned[4]),
        },
        "variants": tuned.iter().map(|t| json!({
            "anti_windup": t.anti_windup.name(),
            "params": t.names.iter().zip(&t.params).map(|(n, v)| (n.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "G_tuning": t.g_tuning,
            "test": t.test,
            "evaluations": t.evaluations,
            "seconds": t.seconds,
        })).collect::<Vec<_>>(),
        "spec": spec,
        "unstable_pole_rad_s": spec.plant.unstable_pole(),
    });
    crate::report::write_json(&run.out, "result.json", &result)
        .map_err(WriteError::file(&run.out.join("result.json")))?;
    let mut traces = Vec::new();
    for t in &tuned {
        let mut tr = Trace::default();
        simulate(
            &spec,
            t.anti_windup,
            &t.params,
            run.seed + 1000,
            Some(&mut tr),
        );
        traces.push(tr);
    }
    let mut header = vec!["t".to_string(), "r".to_string()];
    for t in &tuned {
        let name = t.anti_windup.name();
        header.extend([format!("y_{name}"), format!("u_{name}")]);
    }
    let mut csv = Csv::new(header);
    let at = |v: &[f64], k: usize| v.get(k).copied().unwrap_or(f64::NAN);
    for k in 0..traces[0].t.len() {
        csv.row()
            .put(traces[0].t[k])
            .put(traces[0].r[k])
            .all(traces.iter().flat_map(|tr| [at(&tr.y, k), at(&tr.u, k)]));
    }
    let path = run.out.join("response.csv");
    csv.write(&path).map_err(WriteError::file(&path))?;
    if run.plots {
        plots(&run, &tuned, &traces)?;
    }
    if run.json {
        crate::report::print_json(&result);
        return Ok(());
    }
    println!("maglev (Section 5.2): GA alone, {} evaluations per controller, open-loop pole +{:.1} rad/s", fz.evaluations, spec.plant.unstable_pole());
    println!("  fuzzy anti-windup PID, tuned vs the paper's set:");
    for (i, n) in fz.names.iter().enumerate() {
        println!(
            "    {n:>8} = {:>10.4}   (paper {:>10.4})",
            fz.params[i], PAPER_FUZZY[i]
        );
    }
    println!("  eq. 31 index on the test run (same trajectory, another noise seed):");
    for t in &tuned {
        match t.test {
            Some(c) => println!(
                "    {:>16}: G = {:>9.2} (error {:.2} + current {:.2}), tuned in {:.2} s",
                t.anti_windup.name(),
                c.g,
                c.g_error,
                c.g_current,
                t.seconds
            ),
            None => println!(
                "    {:>16}: lost the ball on the test run",
                t.anti_windup.name()
            ),
        }
    }
    if let Some(c) = paper_cost {
        println!("    the paper's set on this plant: G = {:.2}", c.g);
    } else {
        println!("    the paper's set loses the ball on this plant model");
    }
    println!(
        "  wrote {}/result.json, response.csv{}",
        run.out.display(),
        if run.plots {
            ", response.png, comparison.png, ki.png, evolution.png"
        } else {
            ""
        }
    );
    Ok(())
}

fn plots(run: &Run, tuned: &[Tuned], traces: &[Trace]) -> Result<(), WriteError> {
    let f = &traces[0];
    two_panel_png(
        &run.out.join("response.png"),
        "maglev, PID with fuzzy anti-windup (tuned): position and coil current (Fig. 8)",
        &f.t,
        Panel {
            series: &[
                Series {
                    name: "reference (mm)",
                    values: &f.r,
                },
                Series {
                    name: "y (mm)",
                    values: &f.y,
                },
            ],
            label: "position (mm)",
        },
        Panel {
            series: &[Series {
                name: "u (mA)",
                values: &f.u,
            }],
            label: "current (mA)",
        },
        &[],
    )
    .map_err(WriteError::Figure)?;
    let names: Vec<String> = tuned
        .iter()
        .map(|t| t.anti_windup.name().to_string())
        .collect();
    let mut top = vec![Series {
        name: "reference",
        values: &f.r,
    }];
    top.extend(traces.iter().zip(&names).map(|(tr, n)| Series {
        name: n,
        values: &tr.y,
    }));
    let bottom: Vec<Series> = traces
        .iter()
        .zip(&names)
        .map(|(tr, n)| Series {
            name: n,
            values: &tr.u,
        })
        .collect();
    let n = f.t.len();
    let trim = |s: &[Series]| s.iter().all(|x| x.values.len() == n);
    if trim(&top) && trim(&bottom) {
        two_panel_png(
            &run.out.join("comparison.png"),
            "maglev: fuzzy anti-windup vs clamping, back-calculation and none (each GA-tuned)",
            &f.t,
            Panel {
                series: &top,
                label: "position (mm)",
            },
            Panel {
                series: &bottom,
                label: "current (mA)",
            },
            &[],
        )
        .map_err(WriteError::Figure)?;
    }
    let p = &tuned[0].params;
    let e: Vec<f64> = (0..=200).map(|i| 1.5 * p[6] * i as f64 / 200.0).collect();
    let ki: Vec<f64> = e
        .iter()
        .map(|x| {
            let xn = (x / p[6]).min(1.0);
            p[5] * (fuzzy_ki_normalised(xn, p[2], p[3], p[4])
                - fuzzy_ki_normalised(1.0, p[2], p[3], p[4]))
        })
        .collect();
    xy_png(
        &run.out.join("ki.png"),
        "fuzzy integral gain K_i(|e|) of the tuned controller (eqs. 27-30)",
        "|e| (mm)",
        "K_i (mA/mm per sample)",
        &[XySeries {
            name: "K_i",
            x: &e,
            y: &ki,
            style: Style::Line,
        }],
        None,
        None,
    )
    .map_err(WriteError::Figure)?;
    let curves: Vec<(String, Vec<f64>, Vec<f64>)> = tuned
        .iter()
        .map(|t| {
            (
                t.anti_windup.name().to_string(),
                (1..=t.best_so_far.len()).map(|i| i as f64).collect(),
                t.best_so_far.clone(),
            )
        })
        .collect();
    xy_png(
        &run.out.join("evolution.png"),
        "best G so far per evaluation (GA alone)",
        "evaluation",
        "G (eq. 31)",
        &XySeries::from_curves(&curves, Style::Line),
        None,
        None,
    )
    .map_err(WriteError::Figure)
}

/// The variants of the multi-seed study: fuzzy anti-windup and the four baselines.
pub const STUDY_VARIANTS: [AntiWindup; 5] = [
    AntiWindup::Fuzzy,
    AntiWindup::None,
    AntiWindup::IntegratorClamp,
    AntiWindup::Clamping,
    AntiWindup::BackCalculation,
];

/// One comparison of fuzzy anti-windup against a baseline on one part of eq. 31, over seeds.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// The baseline variant's name (`AntiWindup::name`).
    pub baseline: &'static str,
    /// "G", "error", "control".
    pub part: &'static str,
    /// Paired test of fuzzy against the baseline (a = fuzzy).
    pub wilcoxon: crate::stats::Wilcoxon,
    /// Mean of (fuzzy - baseline) over the seeds where both kept the ball, with its 95 % interval.
    pub difference: crate::stats::MeanCi,
    /// What the comparison supports, in words (`comparison_sentence`).
    pub sentence: String,
}

/// The sentence a comparison supports, from its own numbers: lower/higher only when the paired
/// test says so at the 5 % level, otherwise no difference shown.
pub fn comparison_sentence(
    baseline: &str,
    part: &str,
    w: &crate::stats::Wilcoxon,
    d: &crate::stats::MeanCi,
) -> String {
    let what = match part {
        "G" => "eq. 31 index G".to_string(),
        p => format!("{p} term of eq. 31"),
    };
    crate::stats::paired_sentence("Fuzzy anti-windup", "fuzzy", baseline, &what, w, d)
}

/// Tune every variant on every seed and score it on its test run: costs[v][s], None where the
/// variant lost the ball; each row also in seeds.csv.
fn tune_seeds(
    base: &Run,
    spec: &Spec,
    seeds: &[u64],
) -> Result<Vec<Vec<Option<Cost>>>, WriteError> {
    // costs[v][s]: None = lost the ball on the test run.
    let mut costs: Vec<Vec<Option<Cost>>> = vec![Vec::new(); STUDY_VARIANTS.len()];
    let mut csv = Csv::new([
        "seed", "variant", "G", "error", "current", "holding", "control", "lost",
    ]);
    let t0 = std::time::Instant::now();
    for (k, &seed) in seeds.iter().enumerate() {
        let mut hybrid = base.hybrid.clone();
        hybrid.ga.seed = seed;
        let run = Run {
            hybrid,
            out: base.out.clone(),
            plots: false,
            json: false,
            progress: false,
            seed,
        };
        for (v, aw) in STUDY_VARIANTS.iter().enumerate() {
            let t = tune_variant(&run, spec, *aw);
            // A lost ball has no cost: empty fields and lost = 1.
            let c = t.test.as_ref();
            csv.row()
                .put(seed)
                .put(aw.name())
                .all([c.map(|c| c.g), c.map(|c| c.g_error), c.map(|c| c.g_current)])
                .all([c.map(|c| c.g_holding), c.map(|c| c.g_control)])
                .put(c.is_none());
            costs[v].push(t.test);
        }
        if !base.json {
            eprintln!(
                "  seed {seed}: {} of {} seeds done ({:.0} s)",
                k + 1,
                seeds.len(),
                t0.elapsed().as_secs_f64()
            );
        }
    }
    let path = base.out.join("seeds.csv");
    csv.write(&path).map_err(WriteError::file(&path))?;
    Ok(costs)
}

/// One part of a test run's cost (G, its error term or its control term); infinite where the
/// ball was lost.
fn part(c: &Option<Cost>, p: &str) -> f64 {
    match (c, p) {
        (None, _) => f64::INFINITY,
        (Some(c), "G") => c.g,
        (Some(c), "error") => c.g_error,
        (Some(c), _) => c.g_control,
    }
}

/// study_g.png and study_error.png: each variant's cost per seed.
fn study_plots(out: &Path, seeds: &[u64], costs: &[Vec<Option<Cost>>]) -> Result<(), WriteError> {
    let xs: Vec<f64> = seeds.iter().map(|s| *s as f64).collect();
    for (p, file, label) in [
        ("G", "study_g.png", "G on the test run (eq. 31)"),
        ("error", "study_error.png", "error term of eq. 31 (mm)"),
    ] {
        let curves: Vec<crate::report::plot::Curve> = STUDY_VARIANTS
            .iter()
            .enumerate()
            .map(|(v, aw)| {
                let y = costs[v]
                    .iter()
                    .map(|c| part(c, p))
                    .map(|x| if x.is_finite() { x } else { f64::NAN })
                    .collect();
                (aw.name().to_string(), xs.clone(), y)
            })
            .collect();
        crate::report::plot::xy_png(
            &out.join(file),
            &format!("maglev: {label} per seed, each controller tuned with the same budget"),
            "seed",
            label,
            &crate::report::plot::XySeries::from_curves(
                &curves,
                crate::report::plot::Style::Points,
            ),
            None,
            None,
        )
        .map_err(WriteError::Figure)?;
    }
    Ok(())
}

/// `evoloop tune config/experiments/maglev_tune.toml --seeds 1..20`: for every seed, each variant tuned with
/// the same GA budget (tuning noise = the seed) and scored on the test run (noise seed + 1000);
/// per variant the mean and 95 % interval of G and its parts; fuzzy against each baseline by a
/// paired Wilcoxon test on G, the error term and the control term. Writes `seeds.csv`,
/// `study.json`, `study.md` and (with plots) `study_g.png`, `study_error.png`.
pub fn study(base: Run, spec: Spec, seeds: &[u64]) -> Result<(), TuneError> {
    use crate::stats::{mean_ci, wilcoxon};
    let n_v = STUDY_VARIANTS.len();
    let costs = tune_seeds(&base, &spec, seeds)?;
    let parts = ["G", "error", "control"];
    // stats[v][p]: mean and interval of part p over the seeds where variant v kept the ball.
    let stats: Vec<Vec<crate::stats::MeanCi>> = (0..n_v)
        .map(|v| {
            parts
                .iter()
                .map(|p| {
                    let x: Vec<f64> = costs[v]
                        .iter()
                        .map(|c| part(c, p))
                        .filter(|x| x.is_finite())
                        .collect();
                    mean_ci(&x)
                })
                .collect()
        })
        .collect();
    let lost: Vec<usize> = costs
        .iter()
        .map(|c| c.iter().filter(|c| c.is_none()).count())
        .collect();
    let mut variants = serde_json::Map::new();
    for (v, aw) in STUDY_VARIANTS.iter().enumerate() {
        let mut m = serde_json::Map::new();
        for (i, p) in parts.iter().enumerate() {
            m.insert(p.to_string(), json!(stats[v][i]));
        }
        m.insert("lost".into(), json!(lost[v]));
        variants.insert(aw.name().to_string(), serde_json::Value::Object(m));
    }
    let mut comparisons = Vec::new();
    for (v, aw) in STUDY_VARIANTS.iter().enumerate().skip(1) {
        for p in parts {
            let a: Vec<f64> = costs[0].iter().map(|c| part(c, p)).collect();
            let b: Vec<f64> = costs[v].iter().map(|c| part(c, p)).collect();
            let w = wilcoxon(&a, &b);
            let d: Vec<f64> = a
                .iter()
                .zip(&b)
                .map(|(x, y)| x - y)
                .filter(|x| x.is_finite())
                .collect();
            let d = mean_ci(&d);
            comparisons.push(Comparison {
                baseline: aw.name(),
                part: p,
                sentence: comparison_sentence(aw.name(), p, &w, &d),
                wilcoxon: w,
                difference: d,
            });
        }
    }
    let budget = base.hybrid.ga.population + 2 * base.hybrid.phases.iter().sum::<usize>();
    let result = json!({
        "experiment": "maglev",
        "seeds": seeds,
        "evaluations_per_variant": budget,
        "variants": variants,
        "comparisons": comparisons,
    });
    crate::report::write_json(&base.out, "study.json", &result)
        .map_err(WriteError::file(&base.out.join("study.json")))?;
    let mut md = format!(
        "# Maglev: fuzzy anti-windup against four baselines over {} seeds\n\n\
         Each controller tuned by the GA with the same budget ({budget} evaluations) on each seed's \
         noise, scored on a test run (another noise realisation). G = error + current (eq. 31); \
         current = holding (the constant holding current, the same for every controller) + control.\n\n\
         | variant | G mean [95 % CI] | error mean [95 % CI] | control mean [95 % CI] | lost the ball |\n|---|---|---|---|---|\n",
        seeds.len()
    );
    for (v, aw) in STUDY_VARIANTS.iter().enumerate() {
        let f = |m: &crate::stats::MeanCi| {
            format!("{:.2} [{:.2} .. {:.2}]", m.mean, m.ci95[0], m.ci95[1])
        };
        md.push_str(&format!(
            "| {} | {} | {} | {} | {} |\n",
            aw.name(),
            f(&stats[v][0]),
            f(&stats[v][1]),
            f(&stats[v][2]),
            lost[v]
        ));
    }
    md.push_str("\nWhat the data show (each sentence computed from the paired test above it):\n\n");
    for c in &comparisons {
        md.push_str(&format!("- {}\n", c.sentence));
    }
    let path = base.out.join("study.md");
    crate::files::write(&path, &md).map_err(WriteError::file(&path))?;
    if base.plots {
        study_plots(&base.out, seeds, &costs)?;
    }
    if base.json {
        crate::report::print_json(&result);
    } else {
        print!("{md}");
        println!(
            "\n  wrote {}/seeds.csv, study.json, study.md{}",
            base.out.display(),
            if base.plots {
                ", study_g.png, study_error.png"
            } else {
                ""
            }
        );
    }
    Ok(())
}
