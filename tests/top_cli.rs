//! `evoloop top`: attaches read-only to a running realtime run and reports what the run's own
//! report then confirms; refuses a run that is not there, and a screen without a terminal.

mod common;
use common::{alone, cli, evoloop, unique, wait_exit};
use std::process::{Command, Stdio};
use std::time::Duration;

#[test]
fn top_attaches_to_a_running_run_and_its_snapshot_is_the_run_s() {
    let _g = alone();
    let (prefix, id) = unique("top");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let mut run = Command::new(evoloop())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "run",
            "config/two_mass/two_mass_indirect.toml",
            "--mode",
            "realtime",
            "--no-rt",
            "--duration",
            "6",
            "--run-id",
            &id,
            "--ipc-prefix",
            &prefix,
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(2));
    let o = cli(&["top", "--run", &id, "--json", "--duration", "1.5"]);
    let status = wait_exit(&mut run, Duration::from_secs(60));
    assert!(status.success(), "the run failed with top attached");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(s["run_id"], id.as_str());
    let names: Vec<&str> = s["processes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    for p in ["evoloop-controller", "evoloop-plant", "evoloop-optimiser"] {
        assert!(names.contains(&p), "{p} not in {names:?}");
    }
    let c = &s["controller"];
    // Attached from about 2 s to 3.5 s of a 1 kHz run.
    let cycles = c["cycles"].as_u64().unwrap();
    assert!((1500..=6000).contains(&cycles), "{c}");
    let rate = c["cycle_rate_hz"].as_f64().unwrap();
    assert!((500.0..=1500.0).contains(&rate), "{c}");
    assert!(c["seen_last_s"].as_u64().unwrap() > 100, "{c}");
    assert!(c["lateness_last_s"]["count"].as_u64().unwrap() > 100);
    assert!(c["missed_total"].as_u64().unwrap() >= c["missed_last_s"].as_u64().unwrap());
    // What top saw agrees with the run's own report: misses and the version in service only
    // grow, so the snapshot's are at most the final ones.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(
        c["missed_total"].as_u64().unwrap() <= summary["deadline_misses"].as_u64().unwrap(),
        "{c} vs {summary}"
    );
    assert!(
        s["params"]["version_in_service"].as_u64().unwrap()
            <= summary["parameter_versions"]["final_version"]
                .as_u64()
                .unwrap()
    );
    assert!(s["estimate"]["seen"].as_u64().unwrap() >= 1, "{s}");
    // Realtime epochs run back to back: several by 3.5 s, none after the run's last.
    let epochs = s["optimiser"]["epochs"].as_u64().unwrap();
    let optimiser: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("optimiser.json")).unwrap())
            .unwrap();
    assert!(epochs >= 1, "{s}");
    assert!(epochs <= optimiser["epochs"].as_array().unwrap().len() as u64);
}

#[test]
fn a_run_that_is_not_running_and_a_screen_without_a_terminal_are_refused() {
    let o = cli(&["top", "--run", "no-such-run-xyz", "--json"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("no-such-run-xyz"), "{e}");
    let o = cli(&["top"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("terminal") && e.contains("--json"), "{e}");
}

/// `evoloop top --run ID` on a fresh pseudo-terminal (its controlling terminal, as a login
/// shell's would be): the child and the master side of the pty.
fn top_on_a_pty(id: &str) -> (std::process::Child, std::fs::File) {
    use std::os::fd::FromRawFd;
    use std::os::unix::process::CommandExt;
    let (mut master, mut slave) = (0, 0);
    // SAFETY: openpty writes two new descriptors into the two ints; no name, termios or size.
    let r = unsafe {
        libc::openpty(
            &mut master,
            &mut slave,
            std::ptr::null_mut(),
            std::ptr::null(),
            std::ptr::null(),
        )
    };
    assert_eq!(r, 0, "openpty");
    // The child must not inherit the master, or closing ours would not hang the terminal up.
    // SAFETY: fcntl on a descriptor we own.
    unsafe { libc::fcntl(master, libc::F_SETFD, libc::FD_CLOEXEC) };
    // SAFETY: both descriptors were just opened and are owned here alone.
    let (master, slave) = unsafe {
        (
            std::fs::File::from_raw_fd(master),
            std::fs::File::from_raw_fd(slave),
        )
    };
    let mut cmd = Command::new(evoloop());
    cmd.args(["top", "--run", id])
        .stdin(slave.try_clone().unwrap())
        .stdout(slave.try_clone().unwrap())
        .stderr(slave);
    // SAFETY: only async-signal-safe calls between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            if libc::setsid() < 0 || libc::ioctl(0, libc::TIOCSCTTY, 0) < 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    (cmd.spawn().unwrap(), master)
}

/// The child's exit within `limit`, or None (then it is killed).
fn exits_within(
    child: &mut std::process::Child,
    limit: Duration,
) -> Option<std::process::ExitStatus> {
    let t0 = std::time::Instant::now();
    while t0.elapsed() < limit {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

#[test]
fn top_exits_when_its_terminal_goes_away_and_on_sigterm() {
    // Issue 42: with its terminal gone (an SSH drop, a closed tmux window) top kept running at
    // up to a full core, deaf to SIGTERM, until SIGKILL.
    use std::os::unix::process::ExitStatusExt;
    let _g = alone();
    let (prefix, id) = unique("tophup");
    let tmp = tempfile::tempdir().unwrap();
    let mut run = Command::new(evoloop())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "run",
            "config/two_mass/two_mass.toml",
            "--mode",
            "realtime",
            "--no-rt",
        ])
        .args([
            "--duration",
            "20",
            "--run-id",
            &id,
            "--ipc-prefix",
            &prefix,
            "--quiet",
        ])
        .arg("--out")
        .arg(tmp.path().join("run"))
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(2));
    // The terminal goes away: the master side closes.
    let (mut top, master) = top_on_a_pty(&id);
    std::thread::sleep(Duration::from_millis(1500));
    assert!(
        top.try_wait().unwrap().is_none(),
        "top ended while its terminal was there"
    );
    drop(master);
    let status = exits_within(&mut top, Duration::from_secs(5)).expect("top outlived its terminal");
    assert_eq!(status.signal(), None, "top died of a signal: {status:?}");
    // SIGTERM with the terminal still there: top ends, restoring it.
    let (mut top, _master) = top_on_a_pty(&id);
    std::thread::sleep(Duration::from_millis(1500));
    // SAFETY: the pid is our child's, still running (checked above for the first one).
    unsafe { libc::kill(top.id() as i32, libc::SIGTERM) };
    let status = exits_within(&mut top, Duration::from_secs(5)).expect("top ignored SIGTERM");
    assert_eq!(status.code(), Some(0), "{status:?}");
    // SAFETY: kill takes a pid and a signal number; no memory is involved.
    unsafe { libc::kill(run.id() as i32, libc::SIGINT) };
    let _ = wait_exit(&mut run, Duration::from_secs(30));
}
