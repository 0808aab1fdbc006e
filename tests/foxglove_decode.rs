//! run.mcap decoded by Foxglove's own readers (PyPI's `mcap` and `mcap-ros2-support`, through
//! scripts/decode_mcap.py), not by evoloop: what a viewer or a user's script gets from the file
//! is the run's data bit for bit.
//!
//! - An arm: `joint_states` (`sensor_msgs/msg/JointState`) carries the robot file's joint names,
//!   position = run.csv's measured y, velocity = its qd, effort = the torque applied over the
//!   step, the previous row's u; `command` carries run.csv's u.
//! - Two masses: every state, command and parameter set as Foxglove decodes it equals what
//!   evoloop's own reader (`Recording`, what `evoloop replay` plays) reads, field for field.
//! - States made to show CDR's corners (empty sequences between others, where alignment rules
//!   differ between writers; NaN with a payload, -0.0, infinities, a subnormal), recorded by the
//!   recorder itself: Foxglove's decoder reads each value's bits.
//!
//! Ignored where those packages are not installed (`pip install mcap mcap-ros2-support`); CI
//! installs them into target/pymcap and runs this with `--ignored` and PYTHONPATH set.

use crate::common;
use common::*;
use evoloop::report::recording::Recording;
use serde_json::Value;
use std::path::Path;

/// Every message of `topics` in `file` as Foxglove's decoder gives it.
fn decode(file: &Path, topics: &[&str]) -> Vec<Value> {
    let mut cmd = std::process::Command::new("python3");
    cmd.arg("scripts/decode_mcap.py").arg(file);
    for t in topics {
        cmd.args(["--topic", t]);
    }
    let o = cmd.output().expect("python3");
    assert!(
        o.status.success(),
        "decode_mcap.py failed (pip install mcap mcap-ros2-support?): {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// A decoded float64[] (bits) as f64s.
fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|b| f64::from_bits(b.as_u64().unwrap()))
        .collect()
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// run.csv's columns `prefix0..prefix{n-1}`, row by row.
fn columns(csv: &str, prefix: &str, n: usize) -> Vec<Vec<f64>> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let at: Vec<usize> = (0..n)
        .map(|j| {
            let name = format!("{prefix}{j}");
            header.iter().position(|h| *h == name).unwrap()
        })
        .collect();
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            at.iter().map(|&i| f[i].parse().unwrap()).collect()
        })
        .collect()
}

#[test]
#[ignore = "needs Python 3 with mcap and mcap-ros2-support: pip install mcap mcap-ros2-support"]
fn an_arms_joint_states_and_commands_decode_to_run_csv() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("arm");
    assert_ok(&run(
        &config("arm3/arm3_pd.toml"),
        &out,
        "fgarm",
        &["--duration", "1"],
    ));
    let csv = std::fs::read_to_string(out.join("run.csv")).unwrap();
    let (y, qd, u) = (
        columns(&csv, "y", 3),
        columns(&csv, "qd", 3),
        columns(&csv, "u", 3),
    );
    let joints = decode(&out.join("run.mcap"), &["joint_states"]);
    assert_eq!(joints.len(), y.len(), "one JointState per cycle");
    for (k, m) in joints.iter().enumerate() {
        assert_eq!(m["schema"], "sensor_msgs/msg/JointState");
        let js = &m["msg"];
        assert_eq!(
            js["name"],
            serde_json::json!(["waist", "shoulder", "elbow"])
        );
        let stamp = &js["header"]["stamp"];
        let ns =
            stamp["sec"].as_u64().unwrap() * 1_000_000_000 + stamp["nanosec"].as_u64().unwrap();
        assert_eq!(ns, m["log_time"].as_u64().unwrap(), "row {k}");
        assert_eq!(
            bits(&floats(&js["position"])),
            bits(&y[k]),
            "position, row {k}"
        );
        assert_eq!(
            bits(&floats(&js["velocity"])),
            bits(&qd[k]),
            "velocity, row {k}"
        );
        let applied = if k == 0 {
            vec![0.0; 3]
        } else {
            u[k - 1].clone()
        };
        assert_eq!(
            bits(&floats(&js["effort"])),
            bits(&applied),
            "effort, row {k}"
        );
    }
    let commands = decode(&out.join("run.mcap"), &["command"]);
    assert_eq!(commands.len(), u.len());
    for (k, m) in commands.iter().enumerate() {
        assert_eq!(bits(&floats(&m["msg"]["u"])), bits(&u[k]), "u, row {k}");
    }
}

#[test]
#[ignore = "needs Python 3 with mcap and mcap-ros2-support: pip install mcap mcap-ros2-support"]
fn foxgloves_decoder_and_evoloops_reader_agree_on_every_field() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("tm");
    // The scheduled set goes out at 12 s.
    assert_ok(&run(
        &config("two_mass/two_mass.toml"),
        &out,
        "fgtm",
        &["--duration", "12.5"],
    ));
    let file = out.join("run.mcap");
    let rec = Recording::read(&file).unwrap();
    let decoded = decode(&file, &["state", "command", "params"]);
    let (mut states, mut commands, mut params) = (0, 0, 0);
    for m in &decoded {
        let v = &m["msg"];
        let n = |k: &str| v[k].as_u64().unwrap();
        match m["topic"].as_str().unwrap() {
            "state" => {
                let s = &rec.states[states];
                assert_eq!(m["schema"], "evoloop_msgs/msg/PlantState");
                assert_eq!(
                    (n("seq"), n("stamp_ns"), n("flags")),
                    (s.seq, s.stamp_ns, s.flags as u64)
                );
                assert_eq!(n("t"), s.t.to_bits());
                assert_eq!(bits(&floats(&v["y"])), bits(&s.y[..s.n_y as usize]));
                assert_eq!(
                    bits(&floats(&v["q_true"])),
                    bits(&s.q_true[..s.n_q as usize])
                );
                assert_eq!(
                    bits(&floats(&v["qd_true"])),
                    bits(&s.qd_true[..s.n_q as usize])
                );
                assert_eq!(
                    bits(&floats(&v["x_true"])),
                    bits(&s.x_true[..s.n_x as usize])
                );
                assert_eq!(
                    bits(&floats(&v["u_applied"])),
                    bits(&s.u_applied[..s.n_y.max(s.n_q) as usize])
                );
                states += 1;
            }
            "command" => {
                let c = &rec.commands[commands];
                assert_eq!(
                    (n("cycle"), n("state_seq"), n("param_version")),
                    (c.cycle, c.state_seq, c.param_version)
                );
                assert_eq!(bits(&floats(&v["u"])), bits(&c.u[..c.n_u as usize]));
                commands += 1;
            }
            _ => {
                let (at, p) = &rec.params[params];
                assert_eq!(m["schema"], "evoloop_msgs/msg/ParamSet");
                assert_eq!(
                    (n("cycle"), n("version"), n("apply_at_seq")),
                    (at.cycle.unwrap(), p.version, p.apply_at_seq)
                );
                assert_eq!(n("kind"), p.kind as u64);
                assert_eq!(n("expected_cost"), p.expected_cost.to_bits());
                assert_eq!(bits(&floats(&v["values"])), bits(&p.values[..p.n as usize]));
                params += 1;
            }
        }
    }
    assert_eq!((states, commands), (rec.states.len(), rec.commands.len()));
    assert_eq!(
        (states, params),
        (12_500, 1),
        "every state, and the scheduled set"
    );
}

#[test]
#[ignore = "needs Python 3 with mcap and mcap-ros2-support: pip install mcap mcap-ros2-support"]
fn empty_sequences_and_special_floats_decode_bit_for_bit() {
    use evoloop::msg::{Command, PlantState, Telemetry};
    use evoloop::report::record::Recorder;
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("run.mcap");
    let mut rec = Recorder::start(
        &file,
        true,
        [("config".to_string(), "-".to_string())].into(),
        None,
        vec![],
    )
    .unwrap();
    let specials = [
        f64::from_bits(0x7ff8_0000_dead_beef),
        -0.0,
        f64::INFINITY,
        f64::NEG_INFINITY,
        4e-320,
        0.1 + 0.2,
    ];
    let mut states = Vec::new();
    for k in 0..6u32 {
        // Odd counts and empty sequences in turn: y empty on even k, joints empty on odd k.
        let mut s = PlantState {
            seq: k as u64,
            stamp_ns: 1_000 + k as u64,
            t: specials[k as usize],
            flags: k,
            n_y: if k % 2 == 0 { 0 } else { 3 },
            n_q: if k % 2 == 1 { 0 } else { 1 + k % 3 },
            n_x: k,
            ..Default::default()
        };
        for (i, x) in
            s.y.iter_mut()
                .chain(s.q_true.iter_mut())
                .chain(s.qd_true.iter_mut())
                .chain(s.x_true.iter_mut())
                .chain(s.u_applied.iter_mut())
                .enumerate()
        {
            *x = specials[(i + k as usize) % specials.len()];
        }
        rec.at_state(&s, k as u64);
        rec.cycle(&s, &Command::default(), &Telemetry::default());
        states.push(s);
    }
    let r = rec.finish();
    assert_eq!((r.messages[0], r.error), (6, None));
    let decoded = decode(&file, &["state"]);
    assert_eq!(decoded.len(), 6);
    for (m, s) in decoded.iter().zip(&states) {
        let v = &m["msg"];
        let (nq, ny) = (s.n_q as usize, s.n_y as usize);
        assert_eq!(v["t"].as_u64().unwrap(), s.t.to_bits(), "t of {}", s.seq);
        assert_eq!(bits(&floats(&v["y"])), bits(&s.y[..ny]), "y of {}", s.seq);
        assert_eq!(bits(&floats(&v["q_true"])), bits(&s.q_true[..nq]));
        assert_eq!(bits(&floats(&v["qd_true"])), bits(&s.qd_true[..nq]));
        assert_eq!(
            bits(&floats(&v["x_true"])),
            bits(&s.x_true[..s.n_x as usize])
        );
        assert_eq!(
            bits(&floats(&v["u_applied"])),
            bits(&s.u_applied[..ny.max(nq)])
        );
    }
}
