//! `evoloop replay`: a recorded run played into a controller over iceoryx2 gives the live
//! commands; another controller on the same data gives others; bad input is refused.

use crate::common;
use common::{cli, stdout_json};

/// A lockstep run of the indirect scheme (the optimiser publishes sets and estimates, which the
/// replay must deliver at the cycles the live controller took them; the first three sets are
/// published at 8.9, 11.9 and 14.9 s), recorded.
fn recorded_run(dir: &std::path::Path) {
    recorded(
        "config/two_mass/two_mass_indirect.toml",
        dir,
        &["--duration", "16"],
    );
}

/// `evoloop run CONFIG --out DIR --quiet EXTRA...`, which must succeed.
fn recorded(config: &str, dir: &std::path::Path, extra: &[&str]) {
    let mut args = vec!["run", config, "--out", dir.to_str().unwrap(), "--quiet"];
    args.extend(extra);
    let o = cli(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// `evoloop replay DIR/run.mcap --out OUT --json EXTRA...`: its replay.json.
fn replayed(dir: &std::path::Path, out: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let file = dir.join("run.mcap");
    let mut args = vec![
        "replay",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    args.extend(extra);
    stdout_json(&cli(&args))
}

#[test]
fn replaying_a_lockstep_recording_into_its_controller_gives_the_live_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let live = tmp.path().join("live");
    recorded_run(&live);
    let out = tmp.path().join("replay");
    let r = stdout_json(&cli(&[
        "replay",
        live.join("run.mcap").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(live.join("summary.json")).unwrap()).unwrap();
    let cycles = summary["samples"].as_u64().unwrap();
    assert_eq!(r["states"].as_u64(), Some(cycles), "{r}");
    assert_eq!(r["commands_compared"].as_u64(), Some(cycles));
    assert_eq!(r["commands_equal"].as_u64(), Some(cycles), "{r}");
    assert_eq!(r["max_abs_diff"].as_f64(), Some(0.0));
    assert!(r["first_mismatch"].is_null());
    // The optimiser's sets went through the replay, and the replayed controller took them at the
    // same samples: the live controller's log and the replayed one's are the same bytes.
    assert!(r["params_sent"].as_u64().unwrap() >= 2, "{r}");
    assert!(r["estimates_sent"].as_u64().unwrap() >= 1, "{r}");
    let read = |p: std::path::PathBuf| std::fs::read(&p).unwrap_or_else(|e| panic!("{p:?}: {e}"));
    assert!(read(live.join("run.csv")) == read(out.join("run.csv")));
    for f in ["replay.json", "replay.csv", "replay.png", "controller.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let csv = String::from_utf8(read(out.join("replay.csv"))).unwrap();
    assert!(csv.starts_with("t,state_seq,u0_recorded,u0_replayed\n"));
    assert_eq!(csv.lines().count() as u64, cycles + 1);

    // Another controller on the same plant data: other gains, other commands, and the replay
    // says where they first differ.
    let text = std::fs::read_to_string("config/two_mass/two_mass_indirect.toml").unwrap();
    let other = text.replace(
        "gains = [18.49, 19.04, 47.27, 7.30, -10.54]",
        "gains = [9.0, 19.04, 47.27, 7.30, -10.54]",
    );
    assert_ne!(text, other, "the gains line moved: update this test");
    let file = tmp.path().join("other.toml");
    std::fs::write(&file, other).unwrap();
    let r = stdout_json(&cli(&[
        "replay",
        live.join("run.mcap").to_str().unwrap(),
        "--scenario",
        file.to_str().unwrap(),
        "--out",
        tmp.path().join("other").to_str().unwrap(),
        "--json",
    ]));
    assert_eq!(r["states"].as_u64(), Some(cycles));
    assert!(r["commands_equal"].as_u64().unwrap() < cycles, "{r}");
    assert!(r["max_abs_diff"].as_f64().unwrap() > 0.0);
    assert!(r["first_mismatch"]["state_seq"].is_u64(), "{r}");
}

/// The general indirect scheme: the controller checks sets on the estimated transfer function it
/// took, so the recording carries those estimates (`estimate_linear`) and the replay delivers
/// them at the cycles the live controller took them; the commands are the live ones and the
/// replayed controller adopts the same estimates.
#[test]
fn a_general_indirect_recording_replays_its_linear_estimates() {
    let tmp = tempfile::tempdir().unwrap();
    let live = tmp.path().join("live");
    recorded(
        "config/linear/lti_motor_indirect.toml",
        &live,
        &["--duration", "8"],
    );
    let out = tmp.path().join("replay");
    let r = replayed(&live, &out, &[]);
    let ctrl = |d: &std::path::Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("controller.json")).unwrap()).unwrap()
    };
    let (a, b) = (ctrl(&live), ctrl(&out));
    let adopted = a["check_model"]["adopted"].as_u64().unwrap();
    assert!(adopted > 10, "{}", a["check_model"]);
    assert_eq!(
        r["linear_estimates_sent"].as_u64(),
        a["mcap"]["messages"][6].as_u64(),
        "{r}"
    );
    assert_eq!(b["check_model"]["adopted"].as_u64(), Some(adopted));
    assert_eq!(r["commands_equal"], r["commands_compared"], "{r}");
    assert_eq!(r["states"].as_u64(), Some(8000));
}

#[test]
fn a_file_that_is_not_a_recording_and_a_missing_scenario_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let junk = tmp.path().join("run.mcap");
    std::fs::write(&junk, b"not an mcap file").unwrap();
    let o = cli(&["replay", junk.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains(junk.to_str().unwrap()), "{e}");

    let live = tmp.path().join("live");
    recorded_run(&live);
    let o = cli(&[
        "replay",
        live.join("run.mcap").to_str().unwrap(),
        "--scenario",
        "config/no_such_file.toml",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("no_such_file.toml") && e.contains("--scenario"),
        "{e}"
    );
}

/// A realtime recording holds the state each cycle used; when the plant was late two cycles
/// used one state (same stamp), and a set taken in the second must reach the replayed controller
/// in the second too: the recording names the cycle that took each set and estimate. Replayed,
/// the commands are the live ones, bit for bit. (Whether this run had such cycles depends on
/// the machine: `stale_states` in its controller.json; 11 and 13 in 12 s runs on the development
/// VM without SCHED_FIFO.)
#[test]
fn a_realtime_recording_replays_to_its_live_commands() {
    let tmp = tempfile::tempdir().unwrap();
    let live = tmp.path().join("live");
    recorded(
        "config/two_mass/two_mass_indirect.toml",
        &live,
        &["--mode", "realtime", "--no-rt", "--duration", "4"],
    );
    let controller: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(live.join("controller.json")).unwrap())
            .unwrap();
    assert_eq!(
        controller["mcap"]["dropped"], 0,
        "the recording lost messages"
    );
    let r = replayed(&live, &tmp.path().join("replay"), &[]);
    eprintln!(
        "stale states in the live run: {}",
        controller["timing"]["stale_states"]
    );
    assert_eq!(r["states"], controller["cycles"], "{r}");
    assert_eq!(r["commands_equal"], r["commands_compared"], "{r}");
    assert!(r["first_mismatch"].is_null());
}

/// Recordings evoloop wrote before ROS 2 CDR were JSON (tests/data/json-recording/run.mcap, a
/// run of the scenario beside it written by evoloop at e8a2f43, with `state = "true"` added
/// since: the full-state law it ran then). One still replays to its live
/// commands bit for bit, scheduled set included; and the replayed controller's own recording,
/// now CDR, reads back to the same states, commands and set as the JSON one: every f64 bit for
/// bit through both encodings.
#[test]
fn an_old_json_recording_replays_and_reads_as_its_cdr_re_recording() {
    use evoloop::report::recording::Recording;
    let dir = std::path::Path::new("tests/data/json-recording");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("replay");
    let r = stdout_json(&cli(&[
        "replay",
        dir.join("run.mcap").to_str().unwrap(),
        "--scenario",
        dir.join("scenario.toml").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    assert_eq!(
        (&r["states"], &r["commands_equal"], &r["params_sent"]),
        (&400.into(), &400.into(), &1.into()),
        "{r}"
    );
    assert_eq!(r["max_abs_diff"].as_f64(), Some(0.0));
    let json = Recording::read(&dir.join("run.mcap")).unwrap();
    let cdr = Recording::read(&out.join("run.mcap")).unwrap();
    let encodings = |f: &std::path::Path| {
        let bytes = std::fs::read(f).unwrap();
        let s = mcap::read::Summary::read(&bytes).unwrap().unwrap();
        let mut e: Vec<String> = s
            .channels
            .values()
            .map(|c| c.message_encoding.clone())
            .collect();
        e.dedup();
        e
    };
    assert_eq!(encodings(&dir.join("run.mcap")), ["json"]);
    assert_eq!(encodings(&out.join("run.mcap")), ["cdr"]);
    assert_eq!(json.states.len(), 400);
    assert_eq!(cdr.states.len(), 400);
    for (a, b) in json.states.iter().zip(&cdr.states) {
        common::assert_same_state(b, a);
    }
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (a, b) in json.commands.iter().zip(&cdr.commands) {
        assert_eq!(
            (a.cycle, a.state_seq, a.param_version),
            (b.cycle, b.state_seq, b.param_version)
        );
        assert_eq!(bits(&a.u[..a.n_u as usize]), bits(&b.u[..b.n_u as usize]));
    }
    assert_eq!((json.params.len(), cdr.params.len()), (1, 1));
    let ((at_a, a), (at_b, b)) = (&json.params[0], &cdr.params[0]);
    assert_eq!((at_a.cycle, a.version, a.n), (at_b.cycle, b.version, b.n));
    assert_eq!(
        bits(&a.values[..a.n as usize]),
        bits(&b.values[..b.n as usize])
    );
}
