//! `evoloop tune` and the maglev scenario from the command line: JSON keys, files written,
//! seeds, errors; the maglev in the real processes, lockstep and realtime.

mod common;
use common::*;
use std::path::Path;

#[test]
fn tune_arsinh_reports_the_keys_and_writes_data_and_figures() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("a");
    let v = stdout_json(&cli(&[
        "tune",
        "config/experiments/arsinh_tune.toml",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]));
    for key in [
        "G_initial",
        "G_final",
        "evaluations",
        "C_x0",
        "C_x1",
        "C_y0",
    ] {
        assert!(v[key].is_number(), "{key} missing: {v}");
    }
    assert_eq!(v["evaluations"], 660);
    assert!(v["G_final"].as_f64().unwrap() <= 0.5 * v["G_initial"].as_f64().unwrap());
    for f in [
        "result.json",
        "evolution.csv",
        "tracking.csv",
        "mf_x.png",
        "mf_w.png",
        "mf_u.png",
        "tracking.png",
        "surface.png",
        "evolution.png",
    ] {
        assert!(out.join(f).is_file(), "{f} not written");
    }
    // Seeded: the same seed gives the same result, another seed another one.
    let again = stdout_json(&cli(&[
        "tune",
        "config/experiments/arsinh_tune.toml",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert_eq!(v["G_final"], again["G_final"]);
    let other = stdout_json(&cli(&[
        "tune",
        "config/experiments/arsinh_tune.toml",
        "--json",
        "--seed",
        "2",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert_ne!(v["G_final"], other["G_final"]);
}

#[test]
fn tune_maglev_reports_the_tuned_set_and_g_of_every_variant() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("m");
    let v = stdout_json(&cli(&[
        "tune",
        "config/experiments/maglev_tune.toml",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]));
    for p in ["Kp", "Tv", "v0e", "v1e", "v0K/v1K", "C_i", "C_e"] {
        assert!(v["params"][p].is_number(), "params.{p} missing");
    }
    for g in ["fuzzy_aw", "clamping", "back_calculation", "none"] {
        assert!(v["G"].get(g).is_some(), "G.{g} missing");
    }
    let fz = v["G"]["fuzzy_aw"].as_f64().unwrap();
    for g in ["clamping", "back_calculation", "none"] {
        // A baseline that loses the ball on the test run reports null.
        if let Some(x) = v["G"][g].as_f64() {
            assert!(fz < x, "fuzzy {fz} vs {g} {x}");
        }
    }
    for f in [
        "result.json",
        "response.csv",
        "response.png",
        "comparison.png",
        "ki.png",
        "evolution.png",
    ] {
        assert!(out.join(f).is_file(), "{f} not written");
    }
}

#[test]
fn tune_refuses_bad_files_with_the_key() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            "experiment = \"arsinh\"\n[ga]\npopulation = 1\n",
            "ga.population",
        ),
        (
            "experiment = \"arsinh\"\n[ga]\np_crossover = 1.5\n",
            "ga.p_crossover",
        ),
        ("experiment = \"nope\"\n", "experiment"),
        (
            "experiment = \"maglev\"\n[maglev]\nmass = -1.0\n",
            "maglev.mass",
        ),
        (
            "experiment = \"maglev\"\n[maglev]\ntimes = [1.0]\n",
            "maglev.values",
        ),
        ("experiment = \"arsinh\"\n[ga]\nsize = 3\n", "ga"),
    ];
    for (i, (text, key)) in cases.iter().enumerate() {
        let f = tmp.path().join(format!("t{i}.toml"));
        std::fs::write(&f, text).unwrap();
        let o = cli(&["tune", f.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "case {i}: {err}");
        assert!(
            err.contains(&format!("t{i}.toml")) && err.contains(key),
            "case {i}: {err}"
        );
    }
}

#[test]
fn the_maglev_scenario_runs_in_lockstep_like_the_in_process_simulation_and_in_realtime() {
    let _alone = alone();
    let cfg = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/maglev/maglev.toml");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("lock");
    assert_ok(&run(&cfg, &out, "maglev", &["--duration", "3"]));
    let scn = evoloop::config::Scenario::load(
        &cfg,
        &evoloop::config::Overrides {
            duration: Some(3.0),
            ..Default::default()
        },
    )
    .unwrap();
    let sim = evoloop::sim::simulate(&scn);
    let csv = Csv::read(&out.join("run.csv"));
    let (y, u) = (csv.col("y0"), csv.col("u0"));
    for (i, row) in sim.rows.iter().enumerate() {
        assert_eq!(y[i].to_bits(), row.state.y[0].to_bits(), "y at {i}");
        assert_eq!(u[i].to_bits(), row.telemetry.u[0].to_bits(), "u at {i}");
    }
    // The ball follows the square wave: on the reference at the end of each half period.
    let (t, r) = (csv.col("t"), csv.col("reference"));
    for end in [0.95, 1.75, 2.55] {
        let k = t.iter().position(|x| *x >= end).unwrap();
        assert!(
            (y[k] - r[k]).abs() < 0.05,
            "t = {end}: y {} r {}",
            y[k],
            r[k]
        );
    }
    let out = tmp.path().join("rt");
    assert_ok(&run(
        &cfg,
        &out,
        "maglevrt",
        &["--mode", "realtime", "--duration", "4"],
    ));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["mode"], "realtime");
    // It kept its rate, judged by the same run's floor (replaces the fixed 1300-of-2000 bound
    // an earlier session had loosened from 1900). 4 s, not 2 s, so that one stall of the VM
    // weighs half as much (as in tests/realtime.rs).
    if let Err(line) = rate_kept(&s, 4.0) {
        panic!("the maglev controller did not keep its rate: {line}");
    }
}

#[test]
fn tune_maglev_over_seeds_writes_the_statistics_and_sentences_that_follow_them() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("s");
    let v = stdout_json(&cli(&[
        "tune",
        "config/experiments/maglev_tune.toml",
        "--seeds",
        "1..3",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert_eq!(v["seeds"], serde_json::json!([1, 2, 3]));
    for variant in [
        "fuzzy_aw",
        "none",
        "integrator_clamp",
        "clamping",
        "back_calculation",
    ] {
        for part in ["G", "error", "control"] {
            let m = &v["variants"][variant][part];
            assert!(
                m["mean"].is_number() && m["ci95"].is_array(),
                "{variant} {part}: {m}"
            );
        }
    }
    let comparisons = v["comparisons"].as_array().unwrap();
    assert_eq!(comparisons.len(), 4 * 3, "four baselines, three parts");
    for c in comparisons {
        // Every sentence says what its own numbers support.
        let w = &c["wilcoxon"];
        let p = w["p_two_sided"].as_f64().unwrap();
        let lower = w["w_plus"].as_f64().unwrap() < w["w_minus"].as_f64().unwrap();
        let s = c["sentence"].as_str().unwrap();
        let expect = match (p < 0.05, lower) {
            (true, true) => "has a lower",
            (true, false) => "has a HIGHER",
            (false, _) => "No difference",
        };
        assert!(s.contains(expect), "{s} with p = {p}");
        assert!(s.contains(&format!("of {} seeds", w["n"])), "{s}");
    }
    let csv = std::fs::read_to_string(out.join("seeds.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 3 * 5);
    for f in ["study.json", "study.md", "study_g.png", "study_error.png"] {
        assert!(out.join(f).exists(), "{f}");
    }
    let bad = cli(&[
        "tune",
        "config/experiments/arsinh_tune.toml",
        "--seeds",
        "1..3",
    ]);
    assert_eq!(bad.status.code(), Some(2));
    let bad = cli(&[
        "tune",
        "config/experiments/maglev_tune.toml",
        "--seeds",
        "5",
    ]);
    assert!(!bad.status.success());
}

#[test]
fn study_sentences_follow_the_sign_and_significance_of_the_test() {
    let _heavy = heavy();
    use evoloop::stats::{mean_ci, wilcoxon};
    use evoloop::tune::maglev::comparison_sentence;
    // Fuzzy clearly worse on 12 seeds: the sentence must say HIGHER, never "lower".
    let fuzzy: Vec<f64> = (0..12).map(|i| 110.0 + i as f64).collect();
    let base: Vec<f64> = (0..12).map(|i| 100.0 + 0.5 * i as f64).collect();
    let d: Vec<f64> = fuzzy.iter().zip(&base).map(|(a, b)| a - b).collect();
    let s = comparison_sentence(
        "back_calculation",
        "error",
        &wilcoxon(&fuzzy, &base),
        &mean_ci(&d),
    );
    assert!(s.contains("HIGHER") && s.contains("error term"), "{s}");
    let s = comparison_sentence(
        "back_calculation",
        "G",
        &wilcoxon(&base, &fuzzy),
        &mean_ci(&d),
    );
    assert!(
        s.contains("has a lower") && s.contains("eq. 31 index"),
        "{s}"
    );
    // Mixed signs: no claim.
    let mixed: Vec<f64> = (0..12)
        .map(|i| 100.0 + if i % 2 == 0 { 1.0 } else { -1.0 } * i as f64)
        .collect();
    let flat = vec![100.0; 12];
    let s = comparison_sentence("none", "G", &wilcoxon(&mixed, &flat), &mean_ci(&d));
    assert!(s.starts_with("No difference"), "{s}");
}

/// No progress bar when stderr is not a terminal, so scripts see clean output.
#[test]
fn no_progress_bar_when_stderr_is_not_a_terminal() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("a");
    let piped = cli(&[
        "tune",
        "config/experiments/arsinh_tune.toml",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(piped.status.success());
    assert!(!String::from_utf8_lossy(&piped.stderr).contains("ETA"));
}

/// The progress bar (indicatif) is drawn on a terminal, with the best cost so far, and not at all
/// with --quiet or --json. The terminal is a pseudo-terminal from util-linux `script`: ignored
/// by a plain `cargo test` (not every machine can open one), run by .ci/run where `script`
/// works, and failing, not skipping, where it does not.
#[test]
#[ignore = "needs a pseudo-terminal from util-linux `script`: .ci/run runs it with --ignored"]
fn the_progress_bar_shows_on_a_terminal() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("a");
    let out = out.to_str().unwrap();
    let exe = evoloop();
    let exe = exe.to_str().unwrap();
    let on_tty = |extra: &str| -> Option<String> {
        let o = std::process::Command::new("script")
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args([
                "-qec",
                &format!("{exe} tune config/experiments/arsinh_tune.toml --out {out} {extra}"),
                "/dev/null",
            ])
            .output()
            .ok()?;
        // `script` fails where no pseudo-terminal can be opened (some containers).
        if !o.status.success() {
            eprintln!("`script` failed: {}", String::from_utf8_lossy(&o.stderr));
            return None;
        }
        Some(String::from_utf8_lossy(&o.stdout).into_owned())
    };
    let shown = on_tty("").expect("a terminal from `script` (util-linux)");
    assert!(shown.contains("evaluations, ETA"), "{shown}");
    assert!(shown.contains("best G"), "{shown}");
    for flag in ["--quiet", "--json"] {
        let quiet = on_tty(flag).unwrap();
        assert!(!quiet.contains("ETA"), "{flag}: {quiet}");
    }
}
