//! `evoloop optim study`, `bench`, `functions` and `serve` from the command line: files, JSON keys,
//! statistics consistent with the runs, errors naming their flag.

use crate::common;
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
    // Every algorithm measured, and the rates are the real ones: a bookkeeping-only step on a
    // one-line objective runs at tens of thousands of evaluations a second at the least (a
    // value of 0 or a mis-scaled one, per ms say, fails).
    for a in ["emupso", "pso", "de", "gwo", "woa", "goa", "ga", "jade"] {
        let rate = v["evals_per_s"][a]
            .as_f64()
            .unwrap_or_else(|| panic!("{a} missing: {v}"));
        assert!(rate > 1e4 && rate < 1e10, "{a}: {rate} evaluations/s");
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

#[test]
fn functions_lists_the_suite_and_serve_evaluates_it_over_a_pipe() {
    use std::io::{Read, Write};
    let list = stdout_json(&cli(&["optim", "functions", "--json"]));
    let list = list.as_array().unwrap();
    assert_eq!(list.len(), 51, "37 functions and 14 shifted copies");
    let sphere = list.iter().find(|f| f["key"] == "sphere").unwrap();
    assert_eq!(sphere["dim"], 30);
    assert_eq!(sphere["lower"][0], -100.0);
    assert_eq!(sphere["f_min"], 0.0);

    // Two points of the 30-D sphere in one request, then one of Beale's at its minimum (3, 0.5).
    let serve = |key: &str, points: &[Vec<f64>], tail: &[u8]| {
        let mut child = std::process::Command::new(evoloop())
            .args(["optim", "serve", "--function", key])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let mut req = (points.len() as u32).to_le_bytes().to_vec();
        for p in points {
            for x in p {
                req.extend_from_slice(&x.to_le_bytes());
            }
        }
        req.extend_from_slice(tail);
        child.stdin.take().unwrap().write_all(&req).unwrap();
        let mut out = Vec::new();
        child.stdout.take().unwrap().read_to_end(&mut out).unwrap();
        let mut err = String::new();
        child
            .stderr
            .take()
            .unwrap()
            .read_to_string(&mut err)
            .unwrap();
        let status = child.wait().unwrap();
        let values: Vec<f64> = out
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        (status.success(), values, err)
    };
    let (ok, v, _) = serve("sphere", &[vec![0.0; 30], vec![2.0; 30]], &[]);
    assert!(ok);
    assert_eq!(v, [0.0, 120.0]);
    let (ok, v, _) = serve("beale", &[vec![3.0, 0.5]], &[]);
    assert!(ok && v[0].abs() < 1e-15, "{v:?}");
    // A request cut short is an error that says what it was reading.
    let (ok, v, err) = serve("beale", &[vec![1.0, 1.0]], &[2, 0, 0, 0, 1]);
    assert!(
        !ok && v.len() == 1 && err.contains("reading 2 points"),
        "{err}"
    );
}

#[test]
fn a_peers_file_is_compared_per_function_and_a_bad_one_refused_before_the_study() {
    let tmp = tempfile::tempdir().unwrap();
    let peers = tmp.path().join("peers.csv");
    // A peer far worse than eMuPSO on the sphere, and nothing on the other functions.
    let mut text = String::from("function,algorithm,seed,best_value,error,evaluations\n");
    for seed in 0..5 {
        text += &format!("sphere,lib_worse,{seed},1.5,1.5,3000\n");
    }
    std::fs::write(&peers, &text).unwrap();
    let out = tmp.path().join("study");
    let v = stdout_json(&small_study(
        &out,
        &["--json", "--peers", peers.to_str().unwrap()],
    ));
    let c = &v["peers"]["comparison"]["sphere"];
    assert_eq!(c["theirs"]["algorithm"], "lib_worse");
    assert_eq!(c["theirs"]["runs"], 5);
    assert_eq!(c["verdict"], "beats", "{c}");
    assert!(c["test"]["p_two_sided"].as_f64().unwrap() < 0.05);
    assert_eq!(v["peers"]["beats"], serde_json::json!(["sphere"]));
    assert!(v["peers"]["comparison"].get("beale").is_none());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(report.contains("## Against other implementations"));
    assert!(report.contains("| sphere |"));
    // The comparison table's header has as many columns as its rows.
    let section = &report[report.find("## Against other implementations").unwrap()..];
    let cells = |l: &str| l.matches('|').count();
    let header = section
        .lines()
        .find(|l| l.starts_with("| function"))
        .unwrap();
    let row = section
        .lines()
        .find(|l| l.starts_with("| sphere |"))
        .unwrap();
    assert_eq!(cells(header), cells(row), "{header}\n{row}");

    // More evaluations than the study's budget: refused at once, with file and line.
    std::fs::write(&peers, text.replace(",3000\n", ",3001\n")).unwrap();
    let o = small_study(
        &tmp.path().join("bad"),
        &["--peers", peers.to_str().unwrap()],
    );
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("peers.csv:2:") && e.contains("budget"), "{e}");
    assert!(!tmp.path().join("bad").join("runs.csv").exists());
}
