//! Arms in the loop: computed torque with the true model against the P-D servo on the RKGNN
//! "new" trajectory, the start-up damping psi(k), and the arm scenarios run by the real
//! processes in lockstep (bit-identical to the in-process simulation) and at 1 kHz realtime, and
//! the 7-DOF arm at 10 kHz in both modes.

mod common;
use common::*;
use evoloop::config::{ControllerModel, Overrides, PlantModel, Scenario};
use evoloop::report::metrics::{tracking, Tracking};
use evoloop::sim::{simulate, JointTraces, SimResult};
use std::path::{Path, PathBuf};

fn load(name: &str, ov: &Overrides) -> Scenario {
    Scenario::load(&config(name), ov).unwrap_or_else(|e| panic!("{e}"))
}

/// Tracking of every joint from sample `from` on.
fn joint_tracking(scn: &Scenario, sim: &SimResult, from: usize) -> Tracking {
    let traces = JointTraces::of(sim, &scn.reference, scn.reference.joints());
    let (r, y) = traces.columns();
    tracking(&r, &y, from)
}

#[test]
fn computed_torque_tracks_the_new_trajectory_an_order_of_magnitude_better_than_the_pd_servo() {
    let _heavy = heavy();
    let ov = Overrides::default();
    let ct = load("arm3/arm3_ct.toml", &ov);
    let pd = load("arm3/arm3_pd.toml", &ov);
    assert_eq!(
        ct.reference, pd.reference,
        "both run the same new trajectory"
    );
    // Past the start-up transient (psi fades the torque in over ~100 samples).
    let from = 1000;
    let e_ct = joint_tracking(&ct, &simulate(&ct), from);
    let e_pd = joint_tracking(&pd, &simulate(&pd), from);
    eprintln!("rms CT {:?} PD {:?}", e_ct.rms, e_pd.rms);
    assert!(
        e_ct.rms_all * 10.0 < e_pd.rms_all,
        "computed torque rms {} vs P-D {}",
        e_ct.rms_all,
        e_pd.rms_all
    );
    for j in 0..3 {
        assert!(
            e_ct.max_abs[j] < 2e-3,
            "joint {j}: max error {}",
            e_ct.max_abs[j]
        );
    }
}

#[test]
fn the_new_trajectory_lies_between_the_two_training_trajectories() {
    let _heavy = heavy();
    let ov = Overrides::default();
    let (a, b, new) = (
        load("arm3/arm3_train1.toml", &ov),
        load("arm3/arm3_train2.toml", &ov),
        load("arm3/arm3_ct.toml", &ov),
    );
    let mut s = [evoloop::reference::Setpoint::default(); 3];
    for k in 0..1000 {
        let t = k as f64 * 0.01;
        a.reference.sample(t, &mut s[0]);
        b.reference.sample(t, &mut s[1]);
        new.reference.sample(t, &mut s[2]);
        for j in 0..3 {
            let (lo, hi) = (s[0].q[j].min(s[1].q[j]), s[0].q[j].max(s[1].q[j]));
            assert!(
                s[2].q[j] >= lo - 1e-12 && s[2].q[j] <= hi + 1e-12,
                "joint {j} at t = {t}"
            );
        }
    }
}

#[test]
fn startup_damping_fades_the_torque_in() {
    let _heavy = heavy();
    let scn = load("arm3/arm3_ct.toml", &Overrides::default());
    let sim = simulate(&scn);
    let u0: Vec<f64> = sim.rows.iter().map(|r| r.telemetry.u[1]).collect();
    // psi(0) = 0: no torque on the first sample; then 1 - exp(-0.03 k).
    assert_eq!(u0[0], 0.0);
    let mut undamped = scn.clone();
    let ControllerModel::ComputedTorque(ct) = &mut undamped.controller.model else {
        unreachable!("arm3_ct runs computed torque")
    };
    ct.startup_rate = 0.0;
    let raw = simulate(&undamped);
    assert!(
        raw.rows[0].telemetry.u[1].abs() > 1.0,
        "gravity alone needs torque on joint 2"
    );
    // The damped run never asks for more torque than the undamped one in its first samples.
    assert!(u0[1].abs() < raw.rows[1].telemetry.u[1].abs());
}

#[test]
fn startup_damping_scales_the_law_by_one_minus_exp_of_minus_0_03_k() {
    let _heavy = heavy();
    // The same controller with and without psi, fed the same state at every sample: the damped
    // torque is exactly (1 - exp(-0.03 k)) times the undamped one (the paper's Section 5.1).
    use evoloop::law::computed_torque::ComputedTorque;
    use evoloop::law::Controller;
    let model = evoloop::dynamics::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/arm3.toml"),
    )
    .unwrap();
    let gains = [400.0, 400.0, 400.0, 40.0, 40.0, 40.0];
    let mut damped = ComputedTorque::new(model.clone(), &gains, 0.03);
    let mut plain = ComputedTorque::new(model, &gains, 0.0);
    let mut state = evoloop::msg::PlantState::default();
    let mut sp = evoloop::reference::Setpoint::default();
    for k in 0..300u64 {
        let t = k as f64 * 1e-3;
        for i in 0..3 {
            state.y[i] = 0.1 * (t + i as f64).sin();
            state.qd_true[i] = 0.1 * (t + i as f64).cos();
            sp.q[i] = 0.12 * (t + i as f64).sin();
            sp.qd[i] = 0.12 * (t + i as f64).cos();
        }
        let (mut a, mut b) = ([0.0; 3], [0.0; 3]);
        damped.step(&state, &sp, &mut a);
        plain.step(&state, &sp, &mut b);
        let psi = 1.0 - (-0.03 * k as f64).exp();
        for i in 0..3 {
            assert!(
                (a[i] - psi * b[i]).abs() <= 1e-12 * b[i].abs().max(1.0),
                "k {k} joint {i}: {} vs psi {psi} x {}",
                a[i],
                b[i]
            );
        }
        if k == 100 {
            // 1 - e^-3 = 0.950: 95 % of the torque after 100 samples.
            assert!((psi - 0.950_212_9).abs() < 1e-6);
        }
    }
}

#[test]
fn the_arm_scenario_through_the_processes_equals_the_in_process_simulation() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(
        &config("arm3/arm3_ct.toml"),
        &out,
        "arm",
        &["--duration", "2"],
    ));
    let scn = load(
        "arm3/arm3_ct.toml",
        &Overrides {
            duration: Some(2.0),
            ..Default::default()
        },
    );
    let sim = simulate(&scn);
    let csv = Csv::read(&out.join("run.csv"));
    assert_eq!(csv.rows.len(), sim.rows.len());
    for j in 0..3 {
        let (y, u) = (csv.col(&format!("y{j}")), csv.col(&format!("u{j}")));
        let r = csv.col(if j == 0 {
            "reference"
        } else {
            ["", "r1", "r2"][j]
        });
        for (i, row) in sim.rows.iter().enumerate() {
            assert_eq!(y[i].to_bits(), row.state.y[j].to_bits(), "y{j} at {i}");
            assert_eq!(u[i].to_bits(), row.telemetry.u[j].to_bits(), "u{j} at {i}");
            if j == 0 {
                assert_eq!(r[i].to_bits(), row.telemetry.reference.to_bits());
            }
        }
    }
    let s = json(&out.join("summary.json"));
    let rms = s["tracking_after_1s"]["rms"].as_array().unwrap();
    assert_eq!(rms.len(), 3, "per-joint tracking in summary.json");
    assert!(rms.iter().all(|v| v.as_f64().unwrap() < 1e-3), "{rms:?}");
    assert_plotted(&out.join("response.png"));
}

/// Run a shipped arm scenario in realtime for `secs`: it ran in realtime mode, kept its rate
/// (judged by the same run's floor; the binary's other tests wait, see `alone`) and tracked
/// loosely (a noisy shared VM can miss deadlines; the lockstep tests pin the numbers). Returns
/// the summary.
fn realtime_arm_keeps_its_rate(file: &str, tag: &str, secs: f64, what: &str) -> serde_json::Value {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(
        &config(file),
        &out,
        tag,
        &["--mode", "realtime", "--duration", &secs.to_string()],
    ));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["mode"], "realtime");
    if let Err(line) = rate_kept(&s, secs) {
        panic!("the {what} controller did not keep its rate: {line}");
    }
    let rms = s["tracking_after_1s"]["rms_all"].as_f64().unwrap();
    assert!(rms < 0.05, "realtime tracking rms {rms}");
    s
}

/// (The rate check replaces the fixed 2000-of-3000-cycles bound an earlier session had loosened
/// from 2900.)
#[test]
fn the_industrial_arm_runs_at_one_kilohertz_in_realtime_mode() {
    realtime_arm_keeps_its_rate("industrial6/industrial6_ct.toml", "arm6rt", 3.0, "6-DOF");
}

#[test]
fn a_urdf_robot_runs_in_a_scenario_like_its_dh_twin() {
    let _heavy = heavy();
    let dh = load(
        "arm3/arm3_ct.toml",
        &Overrides {
            duration: Some(2.0),
            ..Default::default()
        },
    );
    let text = std::fs::read_to_string(config("arm3/arm3_ct.toml"))
        .unwrap()
        .replace("../robots/arm3.toml", "../robots/arm3.urdf");
    let urdf = Scenario::parse(
        &text,
        &config("arm3/arm3_ct_urdf.toml"),
        &Overrides {
            duration: Some(2.0),
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let PlantModel::Arm(arm) = &urdf.plant.model else {
        unreachable!("an arm scenario")
    };
    assert!(arm.robot.ends_with("arm3.urdf"));
    let (a, b) = (simulate(&dh), simulate(&urdf));
    assert_eq!(a.rows.len(), b.rows.len());
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        for j in 0..3 {
            assert!(
                (ra.state.q_true[j] - rb.state.q_true[j]).abs() < 1e-9,
                "joint {j} at t = {}",
                ra.state.t
            );
        }
    }
}

/// `plant.arm.payload_*`: from its time on the arm carries a point mass at `payload_com` on its
/// last link, checked against the point mass's potential energy m g z (independent of the
/// dynamics code) and by holding the arm still with the loaded gravity torque, which the plant
/// obeys after the payload's time and not before.
#[test]
fn a_payload_loads_the_last_link_from_its_time_on() {
    let scn = load("arm3/arm3_payload.toml", &Overrides::default());
    let PlantModel::Arm(arm) = &scn.plant.model else {
        panic!("arm3_payload is an arm scenario")
    };
    assert_eq!(arm.payload, vec![(6.0, 1.0)]);
    let cfg = scn.plant.model.config();
    assert_eq!(cfg.first_change(), Some(6.0));
    assert_eq!(cfg.varying_parameter(5.9), Some(0.0));
    assert_eq!(cfg.varying_parameter(6.0), Some(1.0));
    let (bare, loaded) = (&arm.model, arm.loaded_model(1.0));
    let q = [0.3, 0.5, -0.9];
    let (mut d0, mut d1) = (bare.data(), loaded.data());
    // The payload sits at the last link's D-H frame origin (payload_com = 0): the tip.
    let tip = bare.body_origins(&mut d0, &q).last().copied().unwrap();
    let de = loaded.potential_energy(&mut d1, &q) - bare.potential_energy(&mut d0, &q);
    assert!(
        (de - 1.0 * 9.81 * tip.z).abs() < 1e-12,
        "potential energy grew by {de}, m g z = {}",
        9.81 * tip.z
    );
    let mut hold = [0.0; 3];
    loaded.gravity_torque(&mut d1, &q, &mut hold);
    let plant = scn.build_plant();
    let x = [q[0], q[1], q[2], 0.0, 0.0, 0.0];
    let qdd = |t: f64| {
        let mut dx = [0.0; 6];
        plant.derivative(t, &x, &hold, &mut dx);
        dx[3..].iter().map(|a| a.abs()).fold(0.0, f64::max)
    };
    assert!(qdd(7.0) < 1e-9, "loaded arm accelerates by {}", qdd(7.0));
    assert!(
        qdd(5.0) > 0.1,
        "unloaded arm held by the loaded torque: {}",
        qdd(5.0)
    );
}

#[test]
fn payload_keys_are_checked_with_their_names() {
    let path = config("arm3/arm3_payload.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let err = |from: &str, to: &str| {
        assert!(text.contains(from), "{from}");
        Scenario::parse(&text.replace(from, to), &path, &Overrides::default())
            .expect_err("must be refused")
            .to_string()
    };
    let e = err("payload_values = [1.0]", "payload_values = [1.0, 2.0]");
    assert!(e.contains("plant.arm.payload_values"), "{e}");
    let e = err("payload_values = [1.0]", "");
    assert!(
        e.contains("plant.arm.payload_values") && e.contains("missing"),
        "{e}"
    );
    let e = err("payload_values = [1.0]", "payload_values = [-1.0]");
    assert!(e.contains("plant.arm.payload_values[0]"), "{e}");
    let e = err(
        "payload_com = [0.0, 0.0, 0.0]",
        "payload_com = [0.0, 0.0, 1e6]",
    );
    assert!(e.contains("plant.arm.payload_com[2]"), "{e}");
    let no_payload = text
        .replace("payload_times = [6.0]", "")
        .replace("payload_values = [1.0]", "");
    let e = Scenario::parse(&no_payload, &path, &Overrides::default())
        .expect_err("payload_com alone must be refused")
        .to_string();
    assert!(
        e.contains("plant.arm.payload_com") && e.contains("no payload"),
        "{e}"
    );
}

/// Run the 7-DOF scenario `file` for 2 s in lockstep through the processes twice: the two
/// run.csv are the same byte for byte, and y and u equal the in-process simulation bit for bit.
/// Returns the first run's run.csv and summary.json.
fn seven_dof_lockstep_twice_equals_simulation(file: &str, tag: &str) -> (Csv, serde_json::Value) {
    let tmp = tempfile::tempdir().unwrap();
    let outs = [tmp.path().join("a"), tmp.path().join("b")];
    for (i, out) in outs.iter().enumerate() {
        assert_ok(&run(
            &config(file),
            out,
            &format!("{tag}{i}"),
            &["--duration", "2"],
        ));
    }
    let read = |o: &PathBuf| std::fs::read(o.join("run.csv")).unwrap();
    assert!(read(&outs[0]) == read(&outs[1]), "two lockstep runs differ");
    let scn = load(
        file,
        &Overrides {
            duration: Some(2.0),
            ..Default::default()
        },
    );
    assert_eq!(scn.timing.period, 1e-4);
    let sim = simulate(&scn);
    let csv = Csv::read(&outs[0].join("run.csv"));
    assert_eq!(csv.rows.len(), 20_000);
    assert_eq!(csv.rows.len(), sim.rows.len());
    for j in 0..7 {
        let (y, u) = (csv.col(&format!("y{j}")), csv.col(&format!("u{j}")));
        for (i, row) in sim.rows.iter().enumerate() {
            assert_eq!(y[i].to_bits(), row.state.y[j].to_bits(), "y{j} at {i}");
            assert_eq!(u[i].to_bits(), row.telemetry.u[j].to_bits(), "u{j} at {i}");
        }
    }
    (csv, json(&outs[0].join("summary.json")))
}

/// The 7-DOF arm at 10 kHz through the three processes in lockstep: two runs give the same
/// run.csv byte for byte, and it equals the in-process simulation bit for bit.
#[test]
fn the_seven_dof_arm_at_ten_kilohertz_is_bit_reproducible_in_lockstep() {
    let _heavy = heavy();
    let (_, s) = seven_dof_lockstep_twice_equals_simulation("arm7/arm7_ct.toml", "arm7ls");
    // Computed torque with the true model: after the start-up, the error is the sensor noise
    // (noise_std = 1e-4 rad).
    let rms = s["tracking_after_1s"]["rms"].as_array().unwrap();
    assert_eq!(rms.len(), 7);
    assert!(rms.iter().all(|v| v.as_f64().unwrap() < 2e-4), "{rms:?}");
}

#[test]
fn the_seven_dof_arm_runs_at_ten_kilohertz_in_realtime_mode() {
    let s = realtime_arm_keeps_its_rate("arm7/arm7_ct.toml", "arm7rt", 4.0, "7-DOF 10 kHz");
    assert_eq!(s["wait"]["kind"], "hybrid", "the scenario's wait strategy");
}

/// The fuzzy-selection computed torque (two RKGNN models identified on the 7-DOF arm's own
/// training runs) at 10 kHz through the processes: bit-reproducible in lockstep and equal to the
/// in-process simulation, and the selector uses both models within the first 2 s. Its tracking
/// is the models': the book (Arms) says that, identified from the encoders' positions, they
/// track this trajectory better overall than the P-D servo of the training runs (gain-matched to
/// computed torque at the ready pose), and that they did not when identified on the
/// simulator's velocities (0.103 against 0.024 rad). The test checks the claim as stated against
/// that servo on the same trajectory, so the day it stops holding it fails and the book is
/// corrected. (It once pinned `rms < 0.2`, which passed a controller four times worse.)
#[test]
fn the_fuzzy_selection_controller_runs_the_seven_dof_arm_at_ten_kilohertz() {
    let _heavy = heavy();
    let (csv, s) = seven_dof_lockstep_twice_equals_simulation("arm7/arm7_fuzzy_ct.toml", "arm7fz");
    let chosen = csv.col("fuzzy_model");
    for m in [0.0, 1.0] {
        assert!(chosen.contains(&m), "model {m} never selected");
    }
    let fuzzy = s["tracking_after_1s"]["rms_all"].as_f64().unwrap();
    let pd = arm7_servo_rms(2.0);
    eprintln!("arm7 after 1 s: fuzzy CT rms {fuzzy:.4} rad, P-D servo {pd:.4} rad");
    assert!(
        fuzzy < pd,
        "fuzzy CT ({fuzzy:.4} rad) no longer beats the P-D servo ({pd:.4} rad) on arm7: \
         the book's Arms chapter says it does, correct it"
    );
}

/// config/arm7/arm7_fuzzy_ct.toml with `edits` (text replacements) and run length `duration` s.
fn arm7_fuzzy_variant(edits: &[(&str, &str)], duration: f64) -> Scenario {
    let mut text = std::fs::read_to_string(config("arm7/arm7_fuzzy_ct.toml")).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replace(from, to);
    }
    let ov = Overrides {
        duration: Some(duration),
        ..Default::default()
    };
    Scenario::parse(&text, &config("arm7/arm7_variant.toml"), &ov).unwrap_or_else(|e| panic!("{e}"))
}

/// Tracking RMS after 1 s, all joints, of the P-D servo of config/arm7/arm7_train1.toml (gain-matched
/// to computed torque at the ready pose) on the fuzzy scenario's trajectory and loop.
fn arm7_servo_rms(duration: f64) -> f64 {
    let text = std::fs::read_to_string(config("arm7/arm7_fuzzy_ct.toml")).unwrap();
    let train = std::fs::read_to_string(config("arm7/arm7_train1.toml")).unwrap();
    let section = |t: &str, from: &str, to: &str| {
        let a = t.find(from).unwrap();
        t[a..a + t[a..].find(to).unwrap()].to_string()
    };
    let ours = section(&text, "[controller]", "[reference]");
    let servo = arm7_fuzzy_variant(
        &[(&ours, &section(&train, "[controller]", "[reference]"))],
        duration,
    );
    assert_eq!(servo.controller.kind().name(), "pd_servo");
    joint_tracking(&servo, &simulate(&servo), 10_000).rms_all
}

/// The evidence rule on the shipped arm7 models (`selection = "evidence"`, the book's Arms
/// chapter): below each model alone and below the P-D servo on the 10 s run, lockstep (so the
/// figures are the machine's, not its load's). The day it is not, this fails and the book is
/// corrected.
#[test]
fn on_arm7_the_evidence_rule_tracks_below_each_model_alone_and_the_servo() {
    let _heavy = heavy();
    let rms = |scn: &Scenario| joint_tracking(scn, &simulate(scn), 10_000).rms_all;
    let evidence = rms(&arm7_fuzzy_variant(
        &[("selection = \"max\"", "selection = \"evidence\"")],
        10.0,
    ));
    let models = "models = [\"../models/arm7_train1.json\", \"../models/arm7_train2.json\"]";
    let single = |k: usize| {
        let one = format!("models = [\"../models/arm7_train{k}.json\"]");
        rms(&arm7_fuzzy_variant(&[(models, &one)], 10.0))
    };
    let (one, two) = (single(1), single(2));
    let pd = arm7_servo_rms(10.0);
    eprintln!("arm7, 1-10 s: evidence {evidence:.4}, model 1 {one:.4}, model 2 {two:.4}, servo {pd:.4} rad");
    assert!(
        evidence < one.min(two) && evidence < pd,
        "the evidence rule ({evidence:.4} rad) is no longer below each model alone ({one:.4}, \
         {two:.4}) and the servo ({pd:.4}): correct the book's Arms chapter"
    );
}

/// config/arm3/arm3_train1.toml holding its start pose (amplitudes zero) for 3 s, with `gravity`
/// as `[controller.pd_servo]`'s gravity_model line (or none): the last second's error per
/// joint, rad.
fn held_pose_error(gravity: Option<&str>) -> Result<Vec<f64>, String> {
    let mut text = std::fs::read_to_string(config("arm3/arm3_train1.toml")).unwrap();
    let amps = "amplitudes = [[0.8, 0.2], [0.3, 0.1], [0.5, 0.15]]";
    assert!(text.contains(amps));
    text = text.replace(amps, "amplitudes = [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]]");
    if let Some(line) = gravity {
        text = text.replace(
            "kd = [15.0, 20.0, 8.0]",
            &format!("kd = [15.0, 20.0, 8.0]\n{line}"),
        );
    }
    let ov = Overrides {
        duration: Some(3.0),
        ..Default::default()
    };
    let scn =
        Scenario::parse(&text, &config("arm3/arm3_held.toml"), &ov).map_err(|e| e.to_string())?;
    let sim = simulate(&scn);
    let traces = JointTraces::of(&sim, &scn.reference, 3);
    let (r, y) = traces.columns();
    Ok((0..3)
        .map(|j| {
            let tail = &y[j][2000..];
            let mean = tail.iter().sum::<f64>() / tail.len() as f64;
            (r[j][2000] - mean).abs()
        })
        .collect())
}

#[test]
fn gravity_compensation_removes_the_p_d_servos_droop_and_a_wrong_model_leaves_part_of_it() {
    // Without compensation the servo holds the arm where Kp e = G(q): a droop of centiradians.
    let droop = held_pose_error(None).unwrap();
    assert!(droop[1] > 0.01, "{droop:?}");
    // With the arm's own G(q) the droop is gone (to the encoders' noise).
    let exact = held_pose_error(Some("gravity_model = \"../robots/arm3.toml\"")).unwrap();
    assert!(exact.iter().all(|e| *e < 1e-4), "{exact:?}");
    // With a CAD model 20 % wrong, part of it remains: the baseline is only as good as its model.
    let truth = evoloop::dynamics::load(&config("robots/arm3.toml")).unwrap();
    let errors = vec![
        evoloop::dynamics::nominal::CadError {
            mass: 1.2,
            com: [1.2; 3],
            inertia: 1.0,
        };
        3
    ];
    let nominal = evoloop::dynamics::nominal::perturbed(&truth, &errors);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("nominal.urdf");
    std::fs::write(&file, evoloop::dynamics::urdf::to_urdf(&nominal).unwrap()).unwrap();
    let line = format!("gravity_model = \"{}\"", file.display());
    let wrong = held_pose_error(Some(&line)).unwrap();
    assert!(
        wrong[1] > 10.0 * exact[1] && wrong[1] < 0.8 * droop[1],
        "{wrong:?} {droop:?}"
    );
    // A model of another arm is refused with its key.
    let e = held_pose_error(Some("gravity_model = \"../robots/arm7.urdf\"")).unwrap_err();
    assert!(
        e.contains("controller.pd_servo.gravity_model") && e.contains("7 joints"),
        "{e}"
    );
}
