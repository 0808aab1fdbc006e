//! `evoloop bench latency`: every variant measured, percentiles ordered, ratios against the bare
//! iceoryx2 reference present, files written; `bench loop` on the built-in loop and on a given
//! scenario; `bench guard`'s verdicts and exit status. No timing thresholds. Every test takes `alone()`: each starts realtime processes.

mod common;
use common::{alone, assert_plotted, cli};

#[test]
fn bench_latency_reports_every_variant_against_the_bare_reference() {
    let _alone = alone();
    let dir = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .args(["bench", "latency", "--samples", "500", "--json", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for name in ["bare_busy", "evoloop_busy", "bare_event", "evoloop_event"] {
        let r = &v["variants"][name];
        let keys = [
            "min_ns",
            "p50_ns",
            "p90_ns",
            "p99_ns",
            "p99_9_ns",
            "p99_99_ns",
            "max_ns",
        ];
        let vals: Vec<i64> = keys
            .iter()
            .map(|k| r[k].as_i64().unwrap_or_else(|| panic!("{name}.{k}")))
            .collect();
        assert!(vals.windows(2).all(|w| w[0] <= w[1]), "{name}: {vals:?}");
        assert_eq!(r["samples"], 500);
        // Taken in the default five interleaved rounds, each with its own median.
        let p50s = r["p50_rounds_ns"].as_array().unwrap();
        assert_eq!(p50s.len(), 5, "{name}");
        let (lo, hi) = (vals[0], vals[vals.len() - 1]);
        assert!(p50s
            .iter()
            .all(|p| (lo..=hi).contains(&p.as_i64().unwrap())));
    }
    assert_eq!(v["rounds"], 5);
    // Each ratio is evoloop's percentile over the bare loop's of the same wake-up, as the
    // README's table reads it (it was only checked to be > 0).
    for (name, bare) in [
        ("evoloop_busy", "bare_busy"),
        ("evoloop_event", "bare_event"),
    ] {
        for (ratio, p) in [("ratio_p50", "p50_ns"), ("ratio_p99_9", "p99_9_ns")] {
            let r = v["variants"][name][ratio].as_f64().unwrap();
            let q = |n: &str| v["variants"][n][p].as_f64().unwrap();
            let want = q(name) / q(bare).max(1.0);
            assert!(
                (r - want).abs() <= 1e-9 * want,
                "{name}.{ratio} {r} != {want}"
            );
        }
        // Each round's ratio is its p50 over the reference's p50 of the same round.
        let rounds = |n: &str, k: &str| -> Vec<f64> {
            let a = v["variants"][n][k].as_array().unwrap();
            a.iter().map(|x| x.as_f64().unwrap()).collect()
        };
        let (hot, reference) = (rounds(name, "p50_rounds_ns"), rounds(bare, "p50_rounds_ns"));
        let want: Vec<f64> = hot
            .iter()
            .zip(&reference)
            .map(|(h, r)| h / r.max(1.0))
            .collect();
        assert_eq!(rounds(name, "ratio_p50_rounds"), want, "{name}");
        assert!(rounds(bare, "ratio_p50_rounds").is_empty());
    }
    for f in ["latency.json", "latency.csv", "latency_cdf.png"] {
        assert!(dir.path().join(f).is_file(), "{f}");
    }
    for args in [
        &["--samples", "5"][..],
        &["--samples", "500", "--rounds", "10"],
    ] {
        let bad = cli(&[&["bench", "latency"][..], args].concat());
        assert_eq!(bad.status.code(), Some(2), "{args:?}");
    }
}

/// The guard's report holds every hot path, each judged against 1.5x its recorded ratio, and its
/// exit status says whether every path passed (which this test does not require: it would be a
/// timing threshold on a shared machine).
#[test]
fn bench_guard_judges_every_hot_path_by_its_ratio_and_exits_by_its_verdict() {
    let _alone = alone();
    let dir = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .args(["bench", "guard", "--rounds", "3", "--json", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&o.stderr)));
    let file: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("guard.json")).unwrap()).unwrap();
    assert_eq!(v, file);
    let paths = v["paths"].as_object().unwrap();
    let names = [
        "rnea",
        "crba",
        "ct_cycle",
        "pso",
        "de",
        "ga",
        "round_trip_busy",
        "round_trip_event",
    ];
    let keys: std::collections::BTreeSet<&str> = paths.keys().map(|k| k.as_str()).collect();
    assert_eq!(keys, names.into_iter().collect());
    let mut all_pass = true;
    for (name, p) in paths {
        let f = |k: &str| p[k].as_f64().unwrap_or_else(|| panic!("{name}.{k}"));
        assert!((f("limit") - 1.5 * f("recorded")).abs() < 1e-12, "{name}");
        assert_eq!(v["limit_scale"], 1.0);
        let attempts = p["attempts"].as_array().unwrap();
        assert!((1..=3).contains(&attempts.len()), "{name}");
        let lowest = attempts
            .iter()
            .map(|a| {
                let g = |k: &str| a[k].as_f64().unwrap();
                assert!(g("hot_ns") > 0.0 && g("reference_ns") > 0.0, "{name}: {a}");
                assert!((g("ratio") - g("hot_ns") / g("reference_ns")).abs() < 1e-9 * g("ratio"));
                g("ratio")
            })
            .fold(f64::INFINITY, f64::min);
        assert_eq!(f("ratio"), lowest, "{name}");
        let pass = p["pass"].as_bool().unwrap();
        assert_eq!(pass, lowest <= f("limit"), "{name}");
        // Measured again only while over the limit: a pass ends on an attempt within it.
        if pass {
            let last = attempts.last().unwrap()["ratio"].as_f64().unwrap();
            assert!(
                last <= f("limit"),
                "{name}: passed on an attempt over its limit"
            );
        } else {
            assert_eq!(attempts.len(), 3, "{name}: failed before its third attempt");
        }
        all_pass &= pass;
    }
    assert_eq!(v["pass"], all_pass);
    assert_eq!(
        o.status.code(),
        Some(if all_pass { 0 } else { 1 }),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(stderr.contains("hot path slower"), !all_pass, "{stderr}");
    for bad in [
        &["--rounds", "0"][..],
        &["--paths", "rnea,no_such_path"],
        &["--limit-scale", "-1"],
    ] {
        let o = cli(&[&["bench", "guard"][..], bad].concat());
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
    }
}

/// A path over its limit is measured three times and fails the guard with its name: shown on
/// limits scaled far below any ratio (a compute path and a round trip), so that the failure
/// path is checked on any machine without slowing a hot path.
#[test]
fn bench_guard_fails_a_path_over_its_limit_on_every_attempt_and_names_it() {
    let _alone = alone();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .args([
            "bench",
            "guard",
            "--rounds",
            "3",
            "--json",
            "--limit-scale",
            "0.001",
        ])
        .args(["--paths", "rnea,round_trip_busy"])
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["pass"], false);
    assert_eq!(v["limit_scale"], 0.001);
    let paths = v["paths"].as_object().unwrap();
    assert_eq!(paths.len(), 2, "only the paths asked for");
    let stderr = String::from_utf8_lossy(&o.stderr);
    for name in ["rnea", "round_trip_busy"] {
        let p = &paths[name];
        assert_eq!(p["pass"], false, "{name}");
        assert_eq!(p["attempts"].as_array().unwrap().len(), 3, "{name}");
        let limit = p["limit"].as_f64().unwrap();
        assert!((limit - 0.001 * 1.5 * p["recorded"].as_f64().unwrap()).abs() < 1e-12);
        assert!(
            stderr.contains(&format!("error: hot path slower: {name} at ")),
            "{stderr}"
        );
    }
}

#[test]
fn bench_loop_measures_the_loop_and_its_floor_in_the_same_run() {
    // Realtime runs: none of this binary's loops may share the machine with another.
    let _alone = alone();
    let dir = tempfile::tempdir().unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .args([
            "bench",
            "loop",
            "--rate",
            "1000",
            "--duration",
            "1",
            "--load",
            "hog",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let results = v["results"].as_array().unwrap();
    assert_eq!(results.len(), 2, "with and without real-time privileges");
    for r in results {
        let cycles = r["cycles"].as_u64().unwrap();
        let missed = r["deadline_misses"].as_u64().unwrap();
        assert!(
            (990..=1000).contains(&(cycles + missed)),
            "{cycles} + {missed}"
        );
        for k in ["lateness", "floor_lateness"] {
            let p = &r[k];
            let vals: Vec<i64> = ["min_ns", "p50_ns", "p90_ns", "p99_ns", "p99_9_ns", "max_ns"]
                .iter()
                .map(|q| p[q].as_i64().unwrap())
                .collect();
            assert!(vals.windows(2).all(|w| w[0] <= w[1]), "{k}: {vals:?}");
        }
        let want = r["lateness"]["p99_ns"].as_f64().unwrap()
            / r["floor_lateness"]["p99_ns"].as_f64().unwrap().max(1.0);
        let ratio = r["ratio_p99"].as_f64().unwrap();
        assert!(
            (ratio - want).abs() <= 1e-9 * want,
            "ratio_p99 {ratio} != {want}"
        );
    }
    assert_plotted(&dir.path().join("loop_lateness.png"));
    assert!(dir.path().join("loop.json").is_file());
}

/// The optimiser's load during the run is reported: with `--load optimiser` its DE epochs keep
/// it busy (on 2 threads, back to back), far above the idle listener of `--load off` measured
/// in the same sitting.
#[test]
fn bench_loop_reports_the_optimisers_load_during_the_run() {
    let _alone = alone();
    let load = |kind: &str| {
        let dir = tempfile::tempdir().unwrap();
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
            .args(["bench", "loop", "--duration", "2", "--rt-only", "--json"])
            .args(["--load", kind, "--out"])
            .arg(dir.path())
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let r = &v["results"][0];
        (
            r["optimiser_load_cores"].as_f64().unwrap(),
            r["optimiser_cpu_s"].as_f64().unwrap(),
        )
    };
    let (busy, busy_cpu) = load("optimiser");
    let (idle, idle_cpu) = load("off");
    // Ratios to the idle run of the same sitting, not absolute seconds: on a host loaded by
    // others (CI beside two busy loops at nice 4, 2026-12-05) the optimiser, at nice 10, got
    // 0.45 s of CPU in the 2 s where an idle host gives it more than a second.
    assert!(
        busy_cpu > 5.0 * idle_cpu && busy_cpu > 0.05,
        "{busy_cpu} s of CPU in a 2 s run, idle {idle_cpu} s"
    );
    assert!(busy > 5.0 * idle, "busy {busy} cores, idle {idle}");
}

/// `--scenario` runs a shipped scenario (here the 7-DOF arm at 10 kHz) with the chosen wait
/// strategy, and the floor waits the same way; a rate the scenario does not run at is refused.
#[test]
fn bench_loop_runs_a_given_scenario_with_its_wait_strategy() {
    let _alone = alone();
    let dir = tempfile::tempdir().unwrap();
    let arm7 = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/arm7/arm7_ct.toml");
    let bench = |extra: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
            .args(["bench", "loop", "--duration", "1", "--rt-only", "--json"])
            .arg("--scenario")
            .arg(&arm7)
            .arg("--out")
            .arg(dir.path())
            .args(extra)
            .output()
            .unwrap()
    };
    let bad = bench(&["--rate", "1000"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("10000 Hz"),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    let o = bench(&["--rate", "10000", "--wait", "hybrid"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["rate_hz"], 10000.0);
    let r = &v["results"].as_array().unwrap()[0];
    assert_eq!(r["wait"]["kind"], "hybrid");
    let s: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("fifo/summary.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(s["floor"]["wait"]["kind"], "hybrid");
    assert_eq!(s["scenario"], "arm7_ct");
    let cycles = r["cycles"].as_u64().unwrap() + r["deadline_misses"].as_u64().unwrap();
    assert!((9_900..=10_000).contains(&cycles), "{cycles}");
    let misses = r["deadline_misses"].as_f64().unwrap();
    let per_million = r["misses_per_million"].as_f64().unwrap();
    assert!(
        (per_million - 1e6 * misses / r["cycles"].as_f64().unwrap()).abs() < 1e-6,
        "misses_per_million {per_million} for {misses} misses"
    );
}
