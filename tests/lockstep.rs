//! The real binaries in lockstep mode: the step response settles, the run files are written,
//! runs are bit-for-bit reproducible, and the multi-process loop computes exactly what the
//! in-process simulation (the one simulation core) computes.

use crate::common;
use common::*;
use evoloop::config::{Overrides, Scenario};

#[test]
fn lockstep_step_response_settles_within_two_percent_and_writes_the_run_files() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(
        tmp.path(),
        "step.toml",
        &scenario(
            "kind = \"step\"\namplitude = 1.0\nstart = 0.5",
            "mode = \"lockstep\"",
        ),
    );
    let out = tmp.path().join("out");
    let o = run(&cfg, &out, "settle", &[]);
    assert_ok(&o);
    for f in [
        "run.csv",
        "summary.json",
        "response.png",
        "timing.csv",
        "controller.json",
        "plant.json",
        "optimiser.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let png = std::fs::read(out.join("response.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "response.png is a PNG");
    assert!(png.len() > 10_000, "response.png has content");

    let csv = Csv::read(&out.join("run.csv"));
    assert_eq!(csv.rows.len(), 25_000, "one row per sample");
    let t = csv.col("t");
    let y = csv.col("y0");
    let body2 = csv.col("q1");
    // Body 2 settles on the reference: inside a 2 % band for the last 5 s.
    for i in 0..t.len() {
        if t[i] >= 20.0 {
            assert!((y[i] - 1.0).abs() <= 0.02, "y = {} at t = {}", y[i], t[i]);
            assert!(
                (body2[i] - 1.0).abs() <= 0.02,
                "body 2 at {} at t = {}",
                body2[i],
                t[i]
            );
        }
    }
    let s = json(&out.join("summary.json"));
    let ts = s["response"]["settling_time_s"].as_f64().expect("settled");
    assert!(ts > 1.0 && ts < 20.0, "settling time {ts}");
    assert_eq!(s["samples"], 25_000);
    assert_eq!(s["mode"], "lockstep");
    assert!(s["throughput_samples_per_s"].as_f64().unwrap() > 0.0);
    for key in [
        "overruns",
        "deadline_misses",
        "timing",
        "parameter_versions",
        "realtime_privileges",
    ] {
        assert!(s.get(key).is_some(), "summary.json lacks {key}");
    }
}

fn noisy_scenario() -> String {
    scenario(
        "kind = \"square\"\namplitude = 0.5\nperiod = 8.0\nstart = 0.5",
        "mode = \"lockstep\"\nduration = 10.0\n[optimiser]\nmode = \"schedule\"\nsync_period = 0.005\n[[optimiser.schedule]]\nat = 4.0\nvalues = [12.1946, 11.7906, 18.7567, 4.958, -10.0]",
    )
    .replace("step = 0.0005", "step = 0.0005\nnoise_std = 0.01")
}

#[test]
fn two_lockstep_runs_with_the_same_seed_give_identical_run_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(tmp.path(), "noisy.toml", &noisy_scenario());
    let mut files = Vec::new();
    for (i, seed) in ["7", "7", "8"].iter().enumerate() {
        let out = tmp.path().join(format!("out{i}"));
        assert_ok(&run(&cfg, &out, "det", &["--seed", seed]));
        files.push(std::fs::read(out.join("run.csv")).unwrap());
    }
    assert!(files[0].len() > 100_000);
    assert!(files[0] == files[1], "same seed, different run.csv");
    // The seed reaches the sensor noise: a different seed gives a different run.
    assert!(files[0] != files[2], "seed has no effect");
}

#[test]
fn the_multi_process_lockstep_run_equals_the_in_process_simulation_bit_for_bit() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(tmp.path(), "noisy.toml", &noisy_scenario());
    let out = tmp.path().join("out");
    assert_ok(&run(&cfg, &out, "sim", &[]));
    let scn = Scenario::load(&cfg, &Overrides::default()).unwrap();
    let sim = evoloop::sim::simulate(&scn);
    let csv = Csv::read(&out.join("run.csv"));
    assert_eq!(csv.rows.len(), sim.rows.len());
    let (t, r, y, u, v) = (
        csv.col("t"),
        csv.col("reference"),
        csv.col("y0"),
        csv.col("u0"),
        csv.col("param_version"),
    );
    for (i, row) in sim.rows.iter().enumerate() {
        assert_eq!(t[i].to_bits(), row.state.t.to_bits(), "t at {i}");
        assert_eq!(
            r[i].to_bits(),
            row.telemetry.reference.to_bits(),
            "r at {i}"
        );
        assert_eq!(y[i].to_bits(), row.state.y[0].to_bits(), "y at {i}");
        assert_eq!(u[i].to_bits(), row.telemetry.u[0].to_bits(), "u at {i}");
        assert_eq!(v[i] as u64, row.telemetry.param_version, "version at {i}");
    }
    assert_eq!(sim.events.len(), 1);
}

#[test]
fn the_robust_scenario_tracks_while_the_spring_drifts_across_its_range() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config/two_mass/two_mass_robust.toml");
    let out = tmp.path().join("out");
    assert_ok(&run(&cfg, &out, "robust", &[]));
    let csv = Csv::read(&out.join("run.csv"));
    let (t, r, y) = (csv.col("t"), csv.col("reference"), csv.col("y0"));
    // At the end of every half-period of the square wave, body 2 is on the reference, whatever
    // the spring constant is at that moment (0.5 .. 2 .. 0.5 over the run).
    for end in [15.9, 30.9, 45.9, 60.9, 75.9, 89.9] {
        let i = t.iter().position(|v| *v >= end).unwrap();
        assert!(
            (y[i] - r[i]).abs() <= 0.02,
            "off the reference at t = {end}: y = {}, r = {}",
            y[i],
            r[i]
        );
    }
    let s = json(&out.join("summary.json"));
    assert_eq!(
        s["parameter_versions"]["accepted"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
}
