//! `evoloop robust ...` from the command line: results, JSON keys, and clear errors with exit 2.

use std::process::Command;

fn evoloop(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .args(args)
        .output()
        .unwrap()
}

fn json(o: &std::process::Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

#[test]
fn radius_reports_the_table_9_defc_row() {
    let v = json(&evoloop(&[
        "robust",
        "radius",
        "--gains",
        "18.49,19.04,47.27,7.30,-10.54",
        "--json",
    ]));
    let rc = v["stability_radius"].as_f64().unwrap();
    assert!((rc - 0.318787).abs() < 1e-5, "{rc}");
    assert_eq!(v["in_wedge"], true);
    assert_eq!(v["poles"].as_array().unwrap().len(), 5);
    assert_eq!(v["wedge_distance"].as_f64().unwrap(), 0.0);
}

#[test]
fn lqr_prints_table_9_lqr2_on_the_collocated_plant() {
    let v = json(&evoloop(&[
        "robust",
        "lqr",
        "--q",
        "100,1,1,1,1000",
        "--r",
        "1",
        "--k",
        "1.2",
        "--collocated",
        "--json",
    ]));
    let k: Vec<f64> = v["gains"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let printed = [8.96, 20.89, 5.95, 6.54, -31.62];
    for i in 0..5 {
        assert!((k[i] - printed[i]).abs() < 0.005, "{k:?}");
    }
}

#[test]
fn tune_reaches_the_optimum_and_reports_its_run() {
    let v = json(&evoloop(&[
        "robust", "tune", "--seed", "2", "--target", "0.3489", "--json",
    ]));
    assert!(v["stability_radius"].as_f64().unwrap() >= 0.3489);
    assert_eq!(v["in_wedge"], true);
    for key in [
        "gains",
        "poles",
        "iterations",
        "evaluations",
        "seconds",
        "stopped_by",
    ] {
        assert!(v.get(key).is_some(), "missing {key}");
    }
}

/// The collocated encoder's filter, designed for the input's disturbance alone, has its error
/// poles on the antiresonance sqrt(k/m2): the DEFC loop at k = 0.5 holds for springs at most 2 %
/// above the one designed for (measured [0.1428, 0.5087]). A state noise of 0.001 moves the poles
/// off it (measured [0.0737, 1.0306]; the Sensors chapter).
#[test]
fn a_state_noise_widens_the_springs_the_collocated_filters_loop_holds_for() {
    let springs = |extra: &[&str]| {
        let mut args = vec![
            "robust",
            "radius",
            "--gains",
            "18.49,19.04,47.27,7.30,-10.54",
            "--k",
            "0.5",
            "--collocated",
            "--observer",
            "--json",
        ];
        args.extend_from_slice(extra);
        let v = json(&evoloop(&args));
        let r = &v["observer"]["spring_ranges"]["sampled"];
        (r[0].as_f64().unwrap(), r[1].as_f64().unwrap())
    };
    let (lo, hi) = springs(&[]);
    assert!(lo > 0.14 && hi < 0.51, "input noise alone: [{lo}, {hi}]");
    let (lo, hi) = springs(&["--state-noise", "0.001"]);
    assert!(lo < 0.08 && hi > 1.0, "with a state noise: [{lo}, {hi}]");
}

#[test]
fn bad_input_is_refused_with_exit_code_2() {
    for (args, needle) in [
        (vec!["robust", "radius", "--gains", "1,2,3"], "5 values"),
        (vec!["robust", "radius", "--gains", "1,a,3,4,5"], "invalid"),
        (
            vec!["robust", "radius", "--gains", "1,2,3,4,5", "--zeta", "1.2"],
            "zeta",
        ),
        (
            vec!["robust", "radius", "--gains", "1,2,3,4,5", "--zeta", "0"],
            "zeta",
        ),
        (
            vec!["robust", "radius", "--gains", "1,2,3,4,5", "--rho", "-1"],
            "rho",
        ),
        (vec!["robust", "lqr", "--q", "1,1,1"], "--q"),
        (vec!["robust", "lqr", "--r", "0"], "--r"),
        (vec!["robust", "tune", "--cr", "1.5"], "CR"),
        (
            vec![
                "robust",
                "radius",
                "--gains",
                "1,2,3,4,5",
                "--observer",
                "--state-noise",
                "-1",
            ],
            "--state-noise",
        ),
    ] {
        let o = evoloop(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn study_writes_the_report_data_and_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("study");
    let o = evoloop(&[
        "robust",
        "study",
        "--out",
        out.to_str().unwrap(),
        "--runs",
        "2",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "report.md",
        "study.json",
        "runs.csv",
        "responses.csv",
        "poles.png",
        "step_defc_described.png",
        "step_lqr2_collocated.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for t in ["Tables 5-8", "Table 9", "Table 10", "Fig. 5"] {
        assert!(report.contains(t), "report lacks {t}");
    }
    let runs = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    assert_eq!(runs.lines().count(), 1 + 4 * 2, "one row per run");
    // Counts come from the run, not from the paper's set-up.
    assert!(
        report.contains("over 2 seeded runs per setting"),
        "{report}"
    );
    assert!(!report.contains("15 runs") && !report.contains("15 DE runs"));
    // The conclusion names the setting this run's own data rank best.
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("study.json")).unwrap()).unwrap();
    let best = v["settings"]
        .as_array()
        .unwrap()
        .iter()
        .min_by(|a, b| {
            a["mean"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["mean"].as_f64().unwrap())
        })
        .unwrap();
    let named = format!(
        "lowest mean f(X) came from F = {}, CR = {}",
        best["f"], best["cr"]
    );
    assert!(report.contains(&named), "{named} not in the report");
}

#[test]
fn the_study_conclusion_follows_the_numbers_not_the_paper() {
    use evoloop::robust::study::{conclusions, SettingStats};
    // Synthetic settings in which F = 0.9, CR = 0.9 is best on the mean and the steadiest, and no
    // run reaches the optimum: the text must say so, and that the paper's finding is not repeated.
    let setting = |f: f64, cr: f64, values: Vec<f64>| {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let std = (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
        SettingStats {
            f,
            cr,
            mean,
            median: mean,
            std,
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            mean_iterations: 300.0,
            mean_seconds: 0.25,
            runs: Vec::new(),
            values,
        }
    };
    let settings = vec![
        setting(0.5, 0.5, vec![-0.30, -0.32, -0.28]),
        setting(0.9, 0.5, vec![-0.29, -0.31, 0.05]),
        setting(0.5, 0.9, vec![-0.31, -0.33, -0.27]),
        setting(0.9, 0.9, vec![-0.340, -0.341, -0.339]),
    ];
    let text = conclusions(&settings);
    assert!(
        text.contains("lowest mean f(X) came from F = 0.9, CR = 0.9"),
        "{text}"
    );
    assert!(
        text.contains("smallest spread from F = 0.9, CR = 0.9"),
        "{text}"
    );
    assert!(text.contains("agrees on neither"), "{text}");
    assert!(text.contains("12 of 12 runs stopped short"), "{text}");
    assert!(
        text.contains("1 run(s) ended infeasible") && text.contains("F = 0.9, CR = 0.5: 1"),
        "{text}"
    );
    assert!(text.contains("0.25 s on average"), "{text}");
    assert!(!text.contains("As in the paper"), "{text}");
    // And when the paper's setting wins both, the text agrees.
    let mut paper_like = settings.clone();
    paper_like[2] = setting(0.5, 0.9, vec![-0.3489, -0.3488, -0.3489]);
    let text = conclusions(&paper_like);
    assert!(
        text.contains("came from F = 0.5, CR = 0.9") && text.contains("agrees on both counts"),
        "{text}"
    );
}

#[test]
fn the_literal_perturbation_reading_is_available_and_differs() {
    let g = "18.49,19.04,47.27,7.30,-10.54";
    let spring = json(&evoloop(&["robust", "radius", "--gains", g, "--json"]));
    let literal = json(&evoloop(&[
        "robust",
        "radius",
        "--gains",
        g,
        "--perturbation",
        "literal",
        "--json",
    ]));
    let (a, b) = (
        spring["stability_radius"].as_f64().unwrap(),
        literal["stability_radius"].as_f64().unwrap(),
    );
    assert!(a > 0.0 && b > 0.0 && (a - b).abs() > 1e-3, "{a} vs {b}");
}
