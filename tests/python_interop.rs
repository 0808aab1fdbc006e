//! A plant written in Python from the plant contract alone (scripts/stock_plant_interop.py, PyPI's
//! iceoryx2 0.10, nothing of evoloop) exchanges a state and a command with evoloop's own ports:
//! the contract's services, names, settings and layouts are what another language needs.
//! Ignored where Python's iceoryx2 is not installed (`pip install -r scripts/interop.txt`); CI
//! installs it and runs this with `--ignored`.

use crate::common;

use common::{assert_same_state, contract_command, contract_state};
use evoloop::ipc::namespace::{user_prefix, user_subdir};
use evoloop::ipc::Wait;
use std::process::{Child, Command as Process, Output, Stdio};
use std::time::{Duration, Instant};

/// The Python plant's output once it has exited, killed if it has not within `limit`.
fn finish(mut child: Child, limit: Duration) -> Output {
    let end = Instant::now() + limit;
    while child.try_wait().unwrap().is_none() && Instant::now() < end {
        std::thread::sleep(Duration::from_millis(20));
    }
    if child.try_wait().unwrap().is_none() {
        let _ = child.kill();
    }
    child.wait_with_output().unwrap()
}

#[test]
#[ignore = "needs Python 3 with iceoryx2 0.10: pip install -r scripts/interop.txt"]
fn a_python_plant_written_from_the_contract_joins_evoloops_services() {
    let (prefix, run) = common::unique("py");
    let run = run.as_str();
    let ours = common::controller_ports(run, &prefix);
    let root = format!("{}/", user_subdir("iceoryx2").unwrap().display());
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scripts/stock_plant_interop.py"
    );
    let child = Process::new("python3")
        .args([
            script,
            "--prefix",
            &user_prefix(&prefix),
            "--root",
            &root,
            "--run",
            run,
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("python3");
    let s = match ours
        .state
        .wait_next(Duration::ZERO, Duration::from_secs(20))
        .unwrap()
    {
        Wait::Got(s) => s,
        Wait::TimedOut => {
            let out = finish(child, Duration::from_secs(1));
            panic!(
                "no state from the Python plant: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    };
    // Every field where the contract's table puts it, every f64 bit for bit (the script sends
    // common::contract_state).
    assert_eq!((s.seq, s.stamp_ns, s.t), (7, 123_456_789, 0.007));
    assert_same_state(&s, &contract_state());
    let c = contract_command();
    ours.command.send(&c).unwrap();
    let out = finish(child, Duration::from_secs(20));
    assert!(
        out.status.success(),
        "the Python plant: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(got["state_seq"], 7);
    assert_eq!(got["cycle"], 1);
    assert_eq!(got["n_u"], 2);
    assert_eq!(got["u"][0], 0.5);
    assert_eq!(got["u"][1], -1.25);
}
