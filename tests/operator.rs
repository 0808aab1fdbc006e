//! An operator's controls on a running run (issue 45, item 2): `evoloop operator hold | resume |
//! revert [--version N] | stop`, answered by the optimiser and recorded in optimiser.json. The
//! realtime maglev direct run is driven from outside as an operator would: revert to the set
//! before tuning, then to the first trial's set; the loop keeps running throughout and the
//! controller ends with that set bit for bit.

use crate::common;
use common::*;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn operator(run_id: &str, args: &[&str]) -> serde_json::Value {
    let o = cli(&[
        &["operator", "--run", run_id, "--json", "--timeout", "5"],
        args,
    ]
    .concat());
    // 0: done, 1: refused with the reason; both answer on stdout.
    assert!(
        o.status.code().is_some_and(|c| c <= 1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

fn bits(v: &serde_json::Value) -> Vec<u64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap().to_bits())
        .collect()
}

#[test]
fn revert_restores_an_earlier_set_bit_for_bit_while_the_loop_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let (_, run_id) = unique("operator");
    let mut child = Command::new(evoloop())
        .arg("run")
        .arg(config("maglev/maglev_direct.toml"))
        .args([
            "--mode",
            "realtime",
            "--duration",
            "15",
            "--quiet",
            "--no-rt",
        ])
        .args(["--run-id", &run_id, "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let at = |s: f64| std::thread::sleep(Duration::from_secs_f64(s).saturating_sub(t0.elapsed()));
    // The first trial starts at 3.0 s of plant time (about 4-5 s after the launch here).
    at(6.5);
    let held = operator(&run_id, &["hold"]);
    assert_eq!(held["outcome"], "done", "{held}");
    let back = operator(&run_id, &["revert", "--version", "0"]);
    assert_eq!(back["outcome"], "done", "{back}");
    let unknown = operator(&run_id, &["revert", "--version", "9999"]);
    assert_eq!(unknown["outcome"], "unknown_version", "{unknown}");
    // A boundary (1.6 s) after the trial under way ends: the first revert has gone out (a revert
    // before that would replace it).
    at(11.0);
    let to_first = operator(&run_id, &["revert", "--version", "1"]);
    assert_eq!(to_first["outcome"], "done", "{to_first}");
    let status = child.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(status.success(), "{err}");

    let opt = json(&out.join("optimiser.json"));
    let ctrl = json(&out.join("controller.json"));
    // The operator's commands as the optimiser took them, in order.
    let ops: Vec<&str> = opt["operator"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["outcome"].as_str().unwrap())
        .collect();
    assert_eq!(ops, ["done", "done", "unknown_version", "done"]);
    let published = opt["published"].as_array().unwrap();
    let values_of = |version: u64| {
        published
            .iter()
            .find(|p| p["version"] == version)
            .map(|p| bits(&p["values"]))
    };
    let configured = bits(&opt["direct"]["repetitions"][0]["values"]);
    // The first revert put the configured set back under a new version, bit for bit.
    let v_back = back["version"].as_u64().unwrap();
    assert!(v_back > 1);
    assert_eq!(values_of(v_back).unwrap(), configured);
    // The second put trial 1's values back; the controller ends with them in service.
    let v_first = to_first["version"].as_u64().unwrap();
    assert!(v_first > v_back);
    assert_eq!(values_of(v_first).unwrap(), values_of(1).unwrap());
    assert_eq!(ctrl["final_version"], v_first);
    assert_eq!(bits(&ctrl["final_params"]), values_of(1).unwrap());
    // Both reverts were accepted by the controller, and the loop ran to the end: run.csv has
    // its samples through 15 s with the last set in service at the end.
    let accepted = |v: u64| {
        ctrl["params"]
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["version"] == v && e["code"] == "accepted")
    };
    assert!(accepted(v_back) && accepted(v_first));
    let csv = std::fs::read_to_string(out.join("run.csv")).unwrap();
    let last = csv.lines().last().unwrap();
    let t: f64 = last.split(',').next().unwrap().parse().unwrap();
    assert!(t > 14.9, "{last}");
    assert!(last.ends_with(&format!(",{v_first}")), "{last}");
    // Held after the revert: no trial after the first revert's repetition.
    let trials_after: Vec<_> = opt["direct"]["repetitions"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| r["trial"].as_u64().unwrap() > 0 && r["version"].as_u64().unwrap() > v_back)
        .collect();
    assert!(trials_after.is_empty(), "{trials_after:?}");
}

#[test]
fn an_operator_command_without_a_run_says_so() {
    let o = cli(&["operator", "hold", "--run", "no_such_run_here"]);
    assert_eq!(o.status.code(), Some(2));
    let o = cli(&["operator", "pause"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("hold, resume, revert, stop"));
}
