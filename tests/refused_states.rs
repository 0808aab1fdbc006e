//! A plant is another process, possibly in another language: the real controller process takes
//! its states as input. A state whose counts are not the configured plant's, or whose values the
//! law reads are NaN, is refused: the safe command goes out for it, the law's own state (here a
//! PID's integrator) is kept as it was, and controller.json and the report count the refusals
//! and name the first.

use crate::common;

use evoloop::ipc::{Ipc, Topic, Wait};
use evoloop::msg::{Command, PlantState, STATE_FLAG_END};
use std::process::{Command as Process, Stdio};
use std::time::Duration;

/// config/linear/lti_motor.toml with a safe command of -3 V and no noise (its simulated state is
/// [x1, x2, the input in force]: 3 states, 1 joint, 1 output).
fn scenario(dir: &std::path::Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(common::config("linear/lti_motor.toml"))
        .unwrap()
        .replace("noise_std = 0.0005", "noise_std = 0.0\nsafe_command = -3.0");
    common::write(dir, "motor.toml", &text)
}

fn state(seq: u64, y: f64) -> PlantState {
    let mut s = PlantState {
        seq,
        t: seq as f64 * 0.001,
        n_x: 3,
        n_q: 1,
        n_y: 1,
        ..Default::default()
    };
    s.x_true[1] = y;
    s.q_true[0] = y;
    s.y[0] = y;
    s
}

#[test]
fn the_controller_refuses_bad_states_sends_the_safe_command_and_keeps_its_law() {
    let dir = tempfile::tempdir().unwrap();
    let config = scenario(dir.path());
    let out = dir.path().join("out");
    let (prefix, run) = common::unique("refuse");
    let plant = Ipc::new("evoloop-plant", &run, &prefix).unwrap();
    let states = plant.publisher::<PlantState>(Topic::State, true).unwrap();
    let commands = plant
        .subscriber::<Command>(Topic::Command, 8, true)
        .unwrap();
    let mut controller = Process::new(common::evoloop())
        .args([
            "controller",
            "--config",
            config.to_str().unwrap(),
            "--run-id",
            &run,
        ])
        .args(["--ipc-prefix", &prefix, "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let answer = |s: PlantState| -> f64 {
        states.send(&s).unwrap();
        loop {
            match commands
                .wait_next(Duration::ZERO, Duration::from_secs(20))
                .unwrap()
            {
                Wait::Got(c) if c.state_seq == s.seq => return c.u[0],
                Wait::Got(_) => {}
                Wait::TimedOut => panic!("no command for sample {}", s.seq),
            }
        }
    };
    // The reference steps to 1 rad at 0.2 s: from sample 300 the PID integrates an error of 1.
    let mut wait = 0;
    while states.subscribers() == 0 && wait < 200 {
        std::thread::sleep(Duration::from_millis(50));
        wait += 1;
    }
    let good = |k| state(k, 0.9);
    let before: Vec<f64> = (300..303).map(|k| answer(good(k))).collect();
    let mut wrong_count = good(303);
    wrong_count.n_y = 2;
    let mut nan = good(304);
    nan.y[0] = f64::NAN;
    let refused = [answer(wrong_count), answer(nan)];
    let after = answer(good(305));
    let mut end = good(306);
    end.flags = STATE_FLAG_END;
    states.send(&end).unwrap();
    let status = controller.wait().unwrap();
    assert!(status.success(), "controller: {status}");

    assert_eq!(
        refused,
        [-3.0, -3.0],
        "the safe command for each refused state"
    );
    // Kp e + Kp Tv/T (e - e_prev) + integral: with e constant at 0.1 only the integral moves,
    // by Ki e a cycle (unsaturated, e = 0.1); the refused cycles did not integrate, so the step is one cycle's.
    let step = before[2] - before[1];
    assert!(step > 0.0);
    assert!(
        (after - before[2] - step).abs() < 1e-12,
        "the integrator kept its value over the refused states: {before:?} then {after}"
    );
    let report = common::json(&out.join("controller.json"));
    let r = &report["refused_states"];
    assert_eq!(r["count"], 2);
    assert_eq!(r["first"]["seq"], 303);
    assert_eq!(r["first"]["fault"]["count"]["field"], "n_y");
}
