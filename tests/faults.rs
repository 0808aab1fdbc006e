//! The crash matrix: a process of a running run is killed or paused, and the run does what it
//! should (the loop goes on or stops safely, the report is written, nothing is orphaned, the next
//! run starts clean). The launcher's own SIGKILL and a realtime optimiser's SIGSTOP are in
//! `shutdown.rs`.

mod common;
use common::*;
use std::time::Duration;

fn signal(pid: u32, sig: i32) {
    // SAFETY: signalling a process of this test's own run.
    unsafe { libc::kill(pid as i32, sig) };
}

#[test]
fn a_lockstep_optimiser_paused_past_the_timeout_does_not_fail_the_run() {
    // In lockstep the plant waits at each synchronisation point for the optimiser to have seen
    // the samples. Paused for four timeouts, it used to fail the whole run ("optimiser did not
    // acknowledge"); it is not on the control path, so the loop goes on without it and takes it
    // back when it acknowledges again.
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(
        tmp.path(),
        "long.toml",
        &scenario(
            "kind = \"step\"\namplitude = 1.0",
            // A million samples: unpaced, the plant runs some 300 000 a second here, so the run
            // outlasts the pause by seconds.
            "duration = 2000.0\nlockstep_timeout = 0.3",
        )
        .replace("period = 0.001", "period = 0.002"),
    );
    let out = tmp.path().join("out");
    let (prefix, run_id) = unique("lsstop");
    let mut child = spawn_run(&cfg, &out, &prefix, &run_id);
    let opt = process_named(&run_id, "evoloop-optimiser");
    std::thread::sleep(Duration::from_millis(300));
    signal(opt, libc::SIGSTOP);
    std::thread::sleep(Duration::from_millis(1200));
    signal(opt, libc::SIGCONT);
    let status = wait_exit(&mut child, Duration::from_secs(120));
    assert!(status.success(), "the run failed: {status}");
    let s = json(&out.join("summary.json"));
    assert_eq!(s["outcome"], "ok");
    let stalls = s["optimiser_stalls"].as_array().expect("optimiser_stalls");
    assert!(!stalls.is_empty(), "the pause was not noticed: {s}");
    assert!(
        s["optimiser_resumed"].as_u64().unwrap() >= 1,
        "the optimiser never paced the loop again: {s}"
    );
    assert_eq!(s["optimiser_restarts"], 0, "the same optimiser ran on");
    // Every sample was run and answered.
    let run = Csv::read(&out.join("run.csv"));
    assert_eq!(run.rows.len(), 1_000_000);
    forget_prefix(&prefix);
}
