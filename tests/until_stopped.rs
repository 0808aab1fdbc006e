//! Runs with no end: a scenario without `timing.duration` (or `--duration forever`) runs until
//! it is stopped, and being stopped is its normal end: exit 0, outcome "ok", the report of what
//! ran, the optimiser's histories kept.

use crate::common;
use common::*;
use std::process::Command;
use std::time::Duration;

/// The base scenario in lockstep with no duration.
fn endless(dir: &std::path::Path) -> std::path::PathBuf {
    write(
        dir,
        "endless.toml",
        &scenario(
            "kind = \"step\"\namplitude = 1.0",
            "mode = \"lockstep\"\n# no duration: until stopped",
        ),
    )
}

#[test]
fn check_says_a_scenario_without_a_duration_runs_until_stopped() {
    let tmp = tempfile::tempdir().unwrap();
    let o = cli(&["check", endless(tmp.path()).to_str().unwrap()]);
    assert_ok(&o);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("until stopped (Ctrl-C)"), "{text}");
}

#[test]
fn duration_takes_seconds_or_forever_and_nothing_else() {
    let cfg = "config/two_mass/two_mass.toml";
    for bad in ["0", "-1", "nan", "soon", "inf s"] {
        let o = cli(&["run", cfg, &format!("--duration={bad}"), "--quiet"]);
        assert_eq!(o.status.code(), Some(2), "--duration {bad}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("forever"), "--duration {bad}: {err}");
    }
}

#[test]
fn a_run_until_stopped_ends_ok_at_sigint_with_its_report() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let (prefix, run_id) = unique("endless");
    let mut child = spawn_run_and_wait_for_the_loop(&endless(tmp.path()), &out, &prefix, &run_id);
    // Lockstep runs as fast as it can: seconds of wall time are many simulated seconds.
    std::thread::sleep(Duration::from_secs(2));
    signal(child.id(), libc::SIGINT);
    let status = wait_exit(&mut child, Duration::from_secs(60));
    assert_eq!(status.code(), Some(0), "stopping is how such a run ends");
    wait_gone(&run_id);
    forget_prefix(&prefix);
    let s = json(&out.join("summary.json"));
    assert_eq!(s["outcome"], "ok", "{s}");
    assert_eq!(s["until_stopped"], true);
    assert!(s["duration_s"].is_null(), "{s}");
    let (ran, samples) = (s["ran_s"].as_f64().unwrap(), s["samples"].as_u64().unwrap());
    assert!(ran > 2.0, "{s}");
    // The controller's cycles are the samples of run.csv, at one per period from t = 0.
    let period = s["period_s"].as_f64().unwrap();
    let rows = std::fs::read_to_string(out.join("run.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    assert_eq!(rows as u64, samples, "{s}");
    assert!(
        ((ran / period).round() as u64).abs_diff(samples) <= 1,
        "{s}"
    );
}

/// The optimiser's histories reach its report when the run is stopped, not only at a planned
/// end (they used to be saved only at the plant's last sample).
#[test]
fn a_stopped_indirect_run_keeps_the_optimisers_estimates_and_sets() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let (prefix, run_id) = unique("endless-ind");
    let mut child = Command::new(evoloop())
        .args([
            "run",
            "config/maglev/maglev_indirect.toml",
            "--duration",
            "forever",
        ])
        .arg("--out")
        .arg(&out)
        .args(["--ipc-prefix", &prefix, "--run-id", &run_id, "--quiet"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Past the shipped scenario's first published set (maglev_indirect publishes within 30 s
    // of plant time, a second or two of lockstep).
    let t0 = std::time::Instant::now();
    while std::fs::read_to_string(out.join("published.jsonl")).map_or(0, |t| t.lines().count()) < 2
    {
        assert!(t0.elapsed() < Duration::from_secs(60), "no set published");
        std::thread::sleep(Duration::from_millis(50));
    }
    signal(child.id(), libc::SIGINT);
    let status = wait_exit(&mut child, Duration::from_secs(60));
    assert_eq!(status.code(), Some(0));
    wait_gone(&run_id);
    forget_prefix(&prefix);
    let o = json(&out.join("optimiser.json"));
    assert!(!o["estimates"].as_array().unwrap().is_empty(), "{o}");
    let journal = std::fs::read_to_string(out.join("published.jsonl")).unwrap();
    assert_eq!(
        o["published_count"].as_u64().unwrap(),
        journal.lines().count() as u64
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(s["optimiser_published"], o["published_count"]);
    // The frozen comparison is simulated for what ran.
    assert!(
        !s["cost_per_repetition_frozen"]
            .as_array()
            .unwrap()
            .is_empty(),
        "{s}"
    );
}
