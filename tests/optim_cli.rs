//! `evoloop optim study` and `evoloop optim bench` from the command line: files, JSON keys,
//! statistics consistent with the runs, errors naming their flag.

mod common;
use common::*;
use std::collections::HashMap;

/// `optim study` on three functions (one shifted) and three algorithms, 6 runs of 3000.
fn small_study(out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "optim",
        "study",
        "--out",
        out.to_str().unwrap(),
        "--runs",
        "6",
        "--evaluations",
        "3000",
        "--functions",
        "sphere,sphere_shifted,beale",
        "--algorithms",
        "emupso,pso,woa",
    ];
    args.extend_from_slice(extra);
    cli(&args)
}

#[test]
fn a_small_study_writes_tables_tests_plots_and_data_that_agree() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    let o = small_study(&out, &["--json"]);
    let v = stdout_json(&o);
    assert_eq!(v, json(&out.join("results.json")), "stdout = results.json");
    // runs.csv: 3 functions x 3 algorithms x 6 seeds, and results.json's statistics from it.
    let text = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    let mut errors: HashMap<(String, String), Vec<f64>> = HashMap::new();
    for line in text.lines().skip(1) {
        let c: Vec<&str> = line.split(',').collect();
        assert_eq!(c[5], "3000", "every run spends the budget: {line}");
        errors
            .entry((c[0].into(), c[1].into()))
            .or_default()
            .push(c[4].parse().unwrap());
    }
    assert_eq!(errors.len(), 9);
    for ((f, a), e) in &errors {
        assert_eq!(e.len(), 6);
        let cell = &v["results"][f][a];
        for key in [
            "mean_value",
            "mean_error",
            "std_error",
            "min_error",
            "median_error",
        ] {
            assert!(cell[key].is_number(), "{f}/{a}: {key} missing");
        }
        let mean = e.iter().sum::<f64>() / 6.0;
        let min = e.iter().cloned().fold(f64::INFINITY, f64::min);
        let got = cell["mean_error"].as_f64().unwrap();
        assert!(
            (got - mean).abs() <= 1e-6 * mean.abs().max(1e-300),
            "{f}/{a}: {got} vs {mean}"
        );
        // serde_json parses floats to within an ulp or so (no float_roundtrip feature).
        let got_min = cell["min_error"].as_f64().unwrap();
        assert!(
            (got_min - min).abs() <= 1e-14 * min.abs(),
            "{f}/{a}: {got_min} vs {min}"
        );
    }
    // Wilcoxon of eMuPSO against each peer, and the win/tie/loss counts add up per group.
    for f in ["sphere", "sphere_shifted", "beale"] {
        for peer in ["pso", "woa"] {
            let t = &v["wilcoxon"][f][peer];
            assert!(t["p"].as_f64().unwrap() <= 1.0, "{f}/{peer}: {t}");
            assert!(["win", "tie", "loss"].contains(&t["outcome"].as_str().unwrap()));
        }
    }
    let shifted = &v["win_tie_loss"]["shifted"]["woa"];
    let n: u64 = ["win", "tie", "loss"]
        .iter()
        .map(|k| shifted[k].as_u64().unwrap())
        .sum();
    assert_eq!(n, 1);
    assert_eq!(v["functions"]["sphere_shifted"]["shifted"], true);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for heading in ["Table 4", "Table 8", "Table 9", "Shifted and rotated"] {
        assert!(report.contains(heading), "report.md lacks {heading}");
    }
    // The paper's value sits beside ours: its eMuPSO mean on the sphere, 9.46e-8.
    assert!(report.contains("(9.46e-8)"), "paper's value missing");
    for f in ["sphere", "sphere_shifted", "beale"] {
        let png = out.join("convergence").join(format!("{f}.png"));
        assert!(
            std::fs::metadata(&png).unwrap().len() > 1000,
            "{}",
            png.display()
        );
    }
    // Seeded: the same command gives the same runs.
    let again = tmp.path().join("again");
    let o2 = small_study(&again, &["--quiet", "--threads", "1"]);
    assert!(o2.status.success());
    assert_eq!(
        text,
        std::fs::read_to_string(again.join("runs.csv")).unwrap()
    );
}

#[test]
fn bench_reports_evaluations_per_second_for_every_algorithm() {
    let v = stdout_json(&cli(&[
        "optim",
        "bench",
        "--json",
        "--evaluations",
        "3000",
        "--repeats",
        "1",
    ]));
    for a in ["emupso", "pso", "de", "gwo", "woa", "goa", "ga"] {
        assert!(
            v["evals_per_s"][a].as_f64().unwrap() > 0.0,
            "{a} missing: {v}"
        );
    }
}

#[test]
fn bad_arguments_are_refused_with_their_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("x");
    let base = ["optim", "study", "--out", out.to_str().unwrap()];
    for (extra, needle) in [
        (vec!["--algorithms", "emupso,nope"], "--algorithms"),
        (vec!["--functions", "nope"], "unknown function"),
        (vec!["--runs", "1"], "--runs"),
        (
            vec!["--functions", "rosenbrock_shifted"],
            "not origin-centred",
        ),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(extra).collect();
        let o = cli(&args);
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains(needle), "{args:?}: {e}");
    }
}
