//! The real controller process's cycle allocates nothing: every shipped scenario, run through
//! the processes, reports what its loop allocated (`cycle_allocations`, counted by the
//! binary's own allocator on the loop's thread, `evoloop::rt::alloc_count`), and it is zero.
//! `tests/no_alloc*.rs` watch the pieces in-process; this watches `node::controller` itself.

mod common;
use common::*;

/// A scenario's `cycle_allocations` from its summary: watched cycles and allocations.
fn allocations(s: &serde_json::Value) -> (u64, u64) {
    let a = &s["cycle_allocations"];
    assert!(
        a.is_object(),
        "no cycle_allocations in summary.json: the counting allocator is not installed"
    );
    (
        a["cycles"].as_u64().unwrap(),
        a["allocations"].as_u64().unwrap(),
    )
}

#[test]
fn every_shipped_scenario_runs_its_control_cycle_without_allocating() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let files: Vec<_> = shipped_files()
        .into_iter()
        // `evoloop tune` experiments (arsinh_tune, maglev_tune) are not runs of the processes;
        // a plant of the user's own needs its process's language (tests/python_plant.rs counts
        // the controller's allocations on external_motor).
        .filter(|p| {
            !std::fs::read_to_string(p)
                .unwrap()
                .lines()
                .any(|l| l.starts_with("experiment") || l.starts_with("kind = \"external\""))
        })
        .collect();
    assert!(files.len() >= 23, "{} shipped scenarios", files.len());
    let mut sets_after_warmup = 0;
    for (i, f) in files.iter().enumerate() {
        let out = tmp.path().join(format!("s{i}"));
        // The tuning scenarios long enough to swap sets in while watched.
        let name = f.file_name().unwrap().to_string_lossy();
        let secs = if name.contains("direct") { "10" } else { "2" };
        let o = run(f, &out, "noallocnode", &["--duration", secs]);
        assert_ok(&o);
        let s = json(&out.join("summary.json"));
        let (cycles, n) = allocations(&s);
        let samples = s["samples"].as_u64().unwrap();
        eprintln!(
            "{}: {n} allocations in {cycles} watched cycles of {samples}",
            f.display()
        );
        assert_eq!(n, 0, "{}: the control cycle allocated", f.display());
        assert!(
            cycles + 11 >= samples && cycles > 0,
            "{}: {cycles} of {samples} cycles watched",
            f.display()
        );
        sets_after_warmup += s["parameter_versions"]["accepted"]
            .as_array()
            .map_or(0, |a| {
                a.iter()
                    .filter(|r| r["cycle"].as_u64().unwrap_or(0) > 10)
                    .count()
            });
    }
    // Sets were swapped in while watched (the direct and indirect scenarios, 10 s each).
    assert!(sets_after_warmup > 10, "{sets_after_warmup} sets accepted");
}

#[test]
fn a_realtime_run_reports_its_cycle_allocations_too() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rt");
    let o = run(
        &config("two_mass/two_mass_indirect.toml"),
        &out,
        "noallocrt",
        &["--mode", "realtime", "--duration", "3"],
    );
    assert_ok(&o);
    let s = json(&out.join("summary.json"));
    assert_eq!(s["mode"], "realtime");
    let (cycles, n) = allocations(&s);
    assert_eq!(n, 0, "the realtime control cycle allocated");
    assert!(cycles > 1000, "{cycles} cycles watched");
}

/// A viewer attaching to a running run (`evoloop live`: a publisher on `params`, subscribers
/// of the streams) makes the controller connect to it; connecting (mapping the newcomer's
/// memory) allocates, and the controller does it just before a cycle (`Ports::update_connections`),
/// not in one. Before, the cycle's own send or receive did it: 99 allocations on this run at
/// 1 kHz. A port that attaches during the microseconds a cycle computes is still connected by
/// that cycle; at 50 Hz (5 us of 20 ms, three ports that matter) that is about one run in a
/// thousand, which this test would then report.
#[test]
fn a_viewer_attaching_mid_run_adds_no_allocation_to_the_cycle() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("rt");
    let (prefix, run_id) = unique("noalloclive");
    let text = std::fs::read_to_string(realtime_config_lasting(tmp.path(), 4.0))
        .unwrap()
        .replace("period = 0.001", "period = 0.02");
    let cfg = write(tmp.path(), "rt50.toml", &text);
    let mut run = start(&cfg, &out, &prefix, &run_id);
    let addr = format!(
        "127.0.0.1:{}",
        evoloop::node::launcher::free_port().unwrap()
    );
    let mut live = std::process::Command::new(evoloop())
        .args(["live", "--run", &run_id, "--addr", &addr])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    assert!(wait_exit(&mut run, std::time::Duration::from_secs(30)).success());
    wait_exit(&mut live, std::time::Duration::from_secs(15));
    let live = live.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&live.stderr);
    assert!(
        said.contains("Foxglove WebSocket"),
        "the viewer did not attach: {said}"
    );
    let s = json(&out.join("summary.json"));
    let (cycles, n) = allocations(&s);
    assert_eq!(n, 0, "the cycle allocated while a viewer attached");
    assert!(cycles > 150, "{cycles} cycles watched");
}
