//! The synthetic experiment of Section 5.1 as a command: tune, report, plot.

use super::{Run, TuneError};
use crate::fuzzy::arsinh as exp;
use crate::fuzzy::FuzzyNetwork;
use crate::optim::hybrid::hybrid;
use crate::report::plot::{heatmap_png, two_panel_png, xy_png, Panel, Series, Style, XySeries};
use crate::report::progress::Optimisation;
use crate::report::Csv;
use evoloop_schemes::WriteError;
use serde_json::json;

/// The paper's scaling factors after its optimisation.
pub const PAPER_SCALING: [f64; 3] = [1.0046, 1.0012, 4.00597];

/// MF curves of one variable on the normalised axis, one series per label.
fn mf_curves(net: &FuzzyNetwork, var: usize, grid: &[f64]) -> Vec<(String, Vec<f64>)> {
    let n_in = net.inputs.len();
    let v = if var < n_in {
        &net.inputs[var]
    } else {
        &net.outputs[var - n_in]
    };
    v.labels
        .iter()
        .zip(&v.mfs)
        .map(|(l, mf)| (l.clone(), grid.iter().map(|x| mf.at(*x)).collect()))
        .collect()
}

/// Section 5.1's experiment: the hybrid tunes the fuzzy controller from the
/// prespecified sets (and random ones); writes result.json, evolution.csv,
/// tracking.csv and (with plots) the figures into `run.out`, and prints a summary
/// or the JSON.
pub fn run(run: Run) -> Result<(), TuneError> {
    let codec = exp::codec();
    let (lo, hi) = codec.bounds();
    let initial = exp::prespecified();
    let seeds: Vec<Vec<f64>> = initial
        .iter()
        .map(|n| {
            codec
                .encode(n)
                .expect("the paper's prespecified sets lie within the codec's bounds")
        })
        .collect();
    let trajectory = exp::default_trajectory();
    let objective = exp::Objective {
        codec: codec.clone(),
        trajectory: trajectory.clone(),
    };
    let mut cfg = run.hybrid.clone();
    cfg.scaling = codec.scaling_genes();
    let total = cfg.ga.population + 2 * cfg.phases.iter().sum::<usize>();
    let bar = Optimisation::new("arsinh", total, "G", !run.progress);
    let r = hybrid(&cfg, &objective, &lo, &hi, &seeds, |n, best| {
        bar.tell(n, best)
    });
    drop(bar);
    // The best initial set (prespecified or random) and the optimum.
    let (pop0_best, _) = r.values.iter().take(cfg.ga.population).enumerate().fold(
        (0, f64::INFINITY),
        |acc, (i, v)| if *v < acc.1 { (i, *v) } else { acc },
    );
    let start_net = if pop0_best < initial.len() {
        initial[pop0_best].clone()
    } else {
        // A random set was the best start: show the best prespecified one in the figures.
        initial[1].clone()
    };
    let net = codec.decode(&r.best);
    let g_start_shown = exp::run(&start_net, &trajectory, None);
    let (mut x0, mut x1) = (Vec::new(), Vec::new());
    exp::run(&start_net, &trajectory, Some(&mut x0));
    let g_final = exp::run(&net, &trajectory, Some(&mut x1));
    let scaling = [net.input_scale[0], net.input_scale[1], net.output_scale[0]];
    let result = json!({
        "experiment": "arsinh",
        "seed": run.seed,
        "G_initial": r.initial_best,
        "G_final": g_final,
        "G_ratio": g_final / r.initial_best,
        "evaluations": r.evaluations,
        "phase_evaluations": r.phase_evaluations,
        "phases": cfg.phases,
        "ga_iterations": r.ga_iterations,
        "seconds": r.seconds,
        "C_x0": scaling[0], "C_x1": scaling[1], "C_y0": scaling[2],
        "paper": {"C_x0": PAPER_SCALING[0], "C_x1": PAPER_SCALING[1], "C_y0": PAPER_SCALING[2]},
        "prespecified_G": initial.iter().map(|n| exp::run(n, &trajectory, None)).collect::<Vec<_>>(),
        "network": net,
        "rule_base": net.rule_table(),
    });
    crate::report::write_json(&run.out, "result.json", &result)
        .map_err(WriteError::file(&run.out.join("result.json")))?;
    let mut csv = Csv::new(["evaluation", "G", "best_G"]);
    for (i, (v, b)) in r.values.iter().zip(&r.best_so_far).enumerate() {
        csv.row().put(i + 1).put(v).put(b);
    }
    let path = run.out.join("evolution.csv");
    csv.write(&path).map_err(WriteError::file(&path))?;
    let mut tr = Csv::new(["k", "w", "x_initial", "x_optimised"]);
    for k in 0..trajectory.len() {
        tr.row()
            .put(k)
            .put(trajectory[k])
            .put(x0.get(k + 1).copied().unwrap_or(f64::NAN))
            .put(x1[k + 1]);
    }
    let path = run.out.join("tracking.csv");
    tr.write(&path).map_err(WriteError::file(&path))?;
    if run.plots {
        plots(
            &run,
            &start_net,
            &net,
            &trajectory,
            &x0,
            &x1,
            &r.best_so_far,
            g_start_shown,
            g_final,
        )?;
    }
    if run.json {
        crate::report::print_json(&result);
    } else {
        println!(
            "arsinh (Section 5.1): G {:.4} (best initial set) -> {:.4} ({:.1} % of it) in {} evaluations ({} + {} + {}), {:.3} s",
            r.initial_best,
            g_final,
            100.0 * g_final / r.initial_best,
            r.evaluations,
            r.phase_evaluations[0],
            r.phase_evaluations[1],
            r.phase_evaluations[2],
            r.seconds
        );
        println!(
            "  scaling: C_x0 = {:.4}, C_x1 = {:.4}, C_y0 = {:.4} (paper: {}, {}, {})",
            scaling[0],
            scaling[1],
            scaling[2],
            PAPER_SCALING[0],
            PAPER_SCALING[1],
            PAPER_SCALING[2]
        );
        println!("  rule base (control-matrix form, Fig. 1):");
        for l in net.rule_table().lines() {
            println!("    {l}");
        }
        print!("{}", net.mf_table());
        println!(
            "  wrote {}/result.json, evolution.csv, tracking.csv{}",
            run.out.display(),
            if run.plots {
                ", mf_*.png, tracking.png, surface.png, evolution.png"
            } else {
                ""
            }
        );
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn plots(
    run: &Run,
    before: &FuzzyNetwork,
    after: &FuzzyNetwork,
    w: &[f64],
    x0: &[f64],
    x1: &[f64],
    best_so_far: &[f64],
    g0: f64,
    g1: f64,
) -> Result<(), WriteError> {
    let grid: Vec<f64> = (0..=250).map(|i| -1.25 + 2.5 * i as f64 / 250.0).collect();
    for (var, name) in [(0, "x"), (1, "w"), (2, "u")] {
        let b = mf_curves(before, var, &grid);
        let a = mf_curves(after, var, &grid);
        let top: Vec<Series> = b
            .iter()
            .map(|(n, v)| Series { name: n, values: v })
            .collect();
        let bottom: Vec<Series> = a
            .iter()
            .map(|(n, v)| Series { name: n, values: v })
            .collect();
        two_panel_png(
            &run.out.join(format!("mf_{name}.png")),
            &format!("membership functions of {name} (normalised axis): initial (top), optimised (bottom)"),
            &grid,
            Panel { series: &top, label: "initial" },
            Panel { series: &bottom, label: "optimised" },
            &[],
        )
        .map_err(WriteError::Figure)?;
    }
    let k: Vec<f64> = (0..w.len()).map(|i| i as f64).collect();
    let xb: Vec<f64> = x0.iter().skip(1).copied().collect();
    let xa: Vec<f64> = x1.iter().skip(1).copied().collect();
    let top = [
        Series {
            name: "w (desired)",
            values: w,
        },
        Series {
            name: "x (initial)",
            values: &xb,
        },
    ];
    let bottom = [
        Series {
            name: "w (desired)",
            values: w,
        },
        Series {
            name: "x (optimised)",
            values: &xa,
        },
    ];
    two_panel_png(
        &run.out.join("tracking.png"),
        &format!("tracking x_(k+1) vs w_k: initial controller G = {g0:.3} (top), optimised G = {g1:.3} (bottom)"),
        &k,
        Panel { series: &top, label: "initial" },
        Panel { series: &bottom, label: "optimised" },
        &[],
    )
    .map_err(WriteError::Figure)?;
    let axis: Vec<f64> = (0..=40).map(|i| -1.0 + 2.0 * i as f64 / 40.0).collect();
    let mut u = [0.0];
    let z: Vec<Vec<f64>> = axis
        .iter()
        .map(|wv| {
            axis.iter()
                .map(|xv| {
                    after.eval(&[*xv, *wv], &mut u);
                    u[0]
                })
                .collect()
        })
        .collect();
    heatmap_png(
        &run.out.join("surface.png"),
        "control surface u(x_k, w_k) of the optimised controller",
        "x_k",
        "w_k",
        &axis,
        &axis,
        &z,
    )
    .map_err(WriteError::Figure)?;
    let n: Vec<f64> = (1..=best_so_far.len()).map(|i| i as f64).collect();
    xy_png(
        &run.out.join("evolution.png"),
        "best G so far per evaluation (Fig. 7b)",
        "evaluation",
        "G",
        &[XySeries {
            name: "best G",
            x: &n,
            y: best_so_far,
            style: Style::Line,
        }],
        None,
        None,
    )
    .map_err(WriteError::Figure)
}
