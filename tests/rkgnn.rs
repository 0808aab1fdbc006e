//! The RKGNN paper in the loop: identification from a run's reference and output (never its
//! torques), the identified models' M-hat, and computed torque with fuzzy model selection run
//! by the real processes (lockstep equal to the in-process simulation; realtime at 1 kHz).

mod common;
use common::*;
use evoloop::config::{Overrides, Scenario};
use evoloop::rkgnn::Trajectory;
use evoloop::rkgnn_model::network::Part;
use evoloop::rkgnn_model::RkgnnModel;
use evoloop::rkgnn_model::SMOOTHING;
use evoloop::sim::simulate;
use std::path::{Path, PathBuf};

/// A 2-s lockstep run of the first training trajectory through the processes.
fn training_run(dir: &Path, tag: &str) -> PathBuf {
    let out = dir.join("train1");
    assert_ok(&run(
        &config("arm3/arm3_train1.toml"),
        &out,
        tag,
        &["--duration", "2"],
    ));
    out
}

/// Eq. 2's bounds the shipped models were identified with: arm3's M(q) over its joint limits
/// (`evoloop rkgnn prior --robot config/robots/arm3.toml`: 0.0060, 0.552), rounded outward.
const PRIOR: [&str; 4] = ["--m1", "0.005", "--m2", "0.6"];

/// The shipped models' recipe: the training run's own P-D servo, least squares, no search.
const SHIPPED: [&str; 4] = ["--servo", "known", "--start", "least-squares"];

/// `evoloop identify rkgnn` on `data` into `model`, seed 3, with `evaluations`, eq. 2's `PRIOR`,
/// plus `extra`.
fn identify(data: &Path, model: &Path, evaluations: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "identify",
        "rkgnn",
        "--data",
        data.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
        "--evaluations",
        evaluations,
        "--seed",
        "3",
    ];
    args.extend_from_slice(&PRIOR);
    args.extend_from_slice(extra);
    cli(&args)
}

fn min_eig_on(model: &RkgnnModel, data: &Trajectory) -> f64 {
    model.min_eig(data.x.chunks(2 * data.n).map(|x| &x[..data.n]))
}

#[test]
fn the_identifier_reads_reference_and_measured_positions_never_torques_or_true_velocities() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = training_run(tmp.path(), "rk_notau");
    let before = Trajectory::from_run(&out, SMOOTHING).unwrap();
    assert_eq!(before.n, 3);
    assert_eq!(before.len(), 2000);
    // Judged against the simulator's velocities (never given to it), averaged over 21 ms: on its
    // drive's filter the servo passes encoder noise to the torque, and the arm's velocity
    // carries a jitter (22 mrad/s rms on the forearm) that the estimate smooths away as the
    // average does. The estimate from the encoders is within a few mrad/s after the servo's
    // start-up.
    let table = evoloop::report::Table::read(&out.join("run.csv")).unwrap();
    for j in 0..3 {
        let truth = table.col(&format!("qd{j}")).unwrap();
        let mean = |i: usize| truth[i - 10..=i + 10].iter().sum::<f64>() / 21.0;
        let err = (200..1900)
            .map(|i| (before.x_at(i)[3 + j] - mean(i)).powi(2))
            .sum::<f64>()
            / 1700.0;
        assert!(
            err.sqrt() < 5e-3,
            "joint {j}: velocity rms error {}",
            err.sqrt()
        );
    }
    // Overwrite every torque column and the simulator's noise-free velocities `qd*` with NaN:
    // the data read is unchanged (the velocities are estimated from the measured `y*`).
    let path = out.join("run.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let u_cols: Vec<usize> = (0..header.len())
        .filter(|&i| header[i].starts_with('u') || header[i].starts_with("qd"))
        .collect();
    assert_eq!(u_cols.len(), 6);
    let mut rewritten = header.join(",") + "\n";
    for l in lines {
        let mut f: Vec<&str> = l.split(',').collect();
        for &i in &u_cols {
            f[i] = "NaN";
        }
        rewritten += &(f.join(",") + "\n");
    }
    std::fs::write(&path, rewritten).unwrap();
    assert_eq!(Trajectory::from_run(&out, SMOOTHING).unwrap(), before);
    // A run without the velocity columns is refused with the reason.
    let two_mass = tmp.path().join("tm");
    std::fs::create_dir_all(&two_mass).unwrap();
    std::fs::write(two_mass.join("run.csv"), "t,reference,y0,u0\n0,0,0,0\n").unwrap();
    let e = Trajectory::from_run(&two_mass, SMOOTHING).unwrap_err();
    assert!(
        matches!(&e, evoloop::rkgnn::RkgnnError::RunFile { file, .. } if file.ends_with("tm/run.csv")),
        "{e:?}"
    );
    assert!(
        e.to_string().contains("no reference velocity columns rd0"),
        "{e}"
    );
}

#[test]
fn a_run_too_short_for_the_low_pass_is_refused_with_the_reason() {
    // 0.25 s of data: the low-pass (0.08 s) drops 0.08 s at each end of the least squares'
    // part, fewer than 20 rows remain, and the identification says so instead of "no positive
    // definite M-hat".
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = training_run(tmp.path(), "rk_short");
    let path = out.join("run.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let short: Vec<&str> = text.lines().take(251).collect();
    std::fs::write(&path, short.join("\n") + "\n").unwrap();
    let o = identify(&out, &tmp.path().join("m.json"), "0", &SHIPPED);
    assert_refused(&o, "too few samples for the least-squares start");
    assert!(!tmp.path().join("m.json").exists());
}

#[test]
fn identify_rkgnn_from_a_run_gives_a_model_positive_definite_on_every_training_sample() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = training_run(tmp.path(), "rk_ident");
    let model_path = tmp.path().join("model.json");
    let o = identify(&out, &model_path, "600", &["--json"]);
    let r = stdout_json(&o);
    for key in ["train_rms", "holdout_rms"] {
        let v = r[key].as_array().unwrap_or_else(|| panic!("{key}: {r}"));
        assert_eq!(v.len(), 3, "{key} per joint");
        assert!(v.iter().all(|x| x.as_f64().unwrap().is_finite()));
    }
    assert!(r["evaluations"].as_u64().unwrap() >= 600);
    assert!(r["seconds"].as_f64().unwrap() > 0.0);
    let min_eig = r["min_eig_m_hat"].as_f64().unwrap();
    assert!(min_eig > 0.0, "M-hat not positive definite: {min_eig}");
    // The file loads (its own checks) and M-hat is positive definite on every sample, 1 kHz.
    let model = RkgnnModel::load(&model_path).unwrap();
    let data = Trajectory::from_run(&out, SMOOTHING).unwrap();
    assert!(min_eig_on(&model, &data.window(0, 1600)) > 0.0);
    // Seeded: the same command gives the same parameters.
    let again = tmp.path().join("again.json");
    let o2 = identify(&out, &again, "600", &["--threads", "1", "--quiet"]);
    assert!(o2.status.success());
    assert_eq!(
        RkgnnModel::load(&again).unwrap().net.params(),
        model.net.params()
    );
}

#[test]
fn the_shipped_models_are_what_their_command_makes_of_the_training_runs() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    for name in ["arm3_train1", "arm3_train2"] {
        let out = tmp.path().join(name);
        assert_ok(&run(
            &config(&format!("arm3/{name}.toml")),
            &out,
            "rk_ship",
            &[],
        ));
        let model = tmp.path().join(format!("{name}.json"));
        let o = identify(&out, &model, "0", &[&SHIPPED[..], &["--quiet"]].concat());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let shipped = RkgnnModel::load(&config(&format!("models/{name}.json"))).unwrap();
        assert_eq!(
            RkgnnModel::load(&model).unwrap().net.params(),
            shipped.net.params(),
            "{name}"
        );
    }
    // The start needs the linear servo, and no search needs that start.
    let data = tmp.path().join("arm3_train1");
    let model = tmp.path().join("x.json");
    let refused = identify(&data, &model, "600", &["--start", "least-squares"]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("needs --servo linear or known"));
    let refused = identify(&data, &model, "600", &["--servo", "known"]);
    assert!(String::from_utf8_lossy(&refused.stderr).contains("needs --start least-squares"));
    // Eq. 2's bounds are required and checked.
    let mut args = vec!["identify", "rkgnn", "--data", data.to_str().unwrap()];
    args.extend_from_slice(&[
        "--out",
        model.to_str().unwrap(),
        "--m1",
        "0.5",
        "--m2",
        "0.1",
    ]);
    let refused = cli(&args);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("0 < m1 <= m2"));
    let refused = identify(&data, &model, "0", &["--servo", "linear"]);
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("0 only with --start least-squares"));
}

/// A model judged (never fitted) against the true arm at `positions`: the relative errors
/// (Frobenius over all positions) of G-hat and of M-hat.
fn relative_errors(
    m: &RkgnnModel,
    arm: &evoloop::dynamics::Model,
    positions: &[&[f64]],
) -> (f64, f64) {
    let n = arm.dof();
    let mut d = arm.data();
    let (mut g_err, mut g_norm, mut m_err, mut m_norm) = (0.0, 0.0, 0.0, 0.0);
    for q in positions {
        let (mut g, mut truth) = ([0.0; evoloop::MAX_JOINTS], [0.0; evoloop::MAX_JOINTS]);
        m.net.gravity(q, &mut g[..n]);
        arm.gravity_torque(&mut d, q, &mut truth[..n]);
        let mut mh = [0.0; evoloop::MAX_JOINTS * evoloop::MAX_JOINTS];
        m.net.inertia(q, &mut mh);
        let mt = arm.mass_matrix(&mut d, q);
        for a in 0..n {
            g_err += (g[a] - truth[a]).powi(2);
            g_norm += truth[a].powi(2);
            for b in 0..n {
                m_err += (mh[a * n + b] - mt[(a, b)]).powi(2);
                m_norm += mt[(a, b)].powi(2);
            }
        }
    }
    ((g_err / g_norm).sqrt(), (m_err / m_norm).sqrt())
}

#[test]
fn a_servo_behind_a_drives_filter_is_reconstructed_with_its_filters_lag() {
    // arm3_train1's servo acts on its drive's velocity (the encoders' difference, low-passed at
    // 50 Hz: the scenarios' default), late by the low-pass's h / (e^(2 pi 50 h) - 1) and the
    // difference's h / 2, lag = 3.2 ms at h = 1 ms, so it applied
    // k_d lag q'' more torque than k_d on the velocity itself would give. Told the filter (as
    // the run's scenario.json says, or --servo-velocity-cutoff-hz) the identification puts that
    // torque in the equation; told only the gains it fits M-hat to the torque without it, a
    // diagonal smaller by about k_d lag. Measured (2026-12-03): 0.046, 0.059, 0.012 for
    // predicted 0.048, 0.064, 0.026 (the forearm's shortfall unexplained); judged against
    // the true arm the untold M-hat is nearer (0.34 against 0.44 relative error, two biases
    // cancelling: both are worse than a constant), while computed torque on the told models
    // tracks better (the Sensors chapter).
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("train1");
    assert_ok(&run(
        &config("arm3/arm3_train1.toml"),
        &out,
        "rk_drive",
        &[],
    ));
    let gains = ["--servo", "known", "--start", "least-squares"];
    let fit = |name: &str, extra: &[&str]| {
        let model = tmp.path().join(name);
        let o = identify(
            &out,
            &model,
            "0",
            &[&gains[..], extra, &["--quiet"]].concat(),
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        RkgnnModel::load(&model).unwrap()
    };
    let servo = ["--kp", "150,200,100", "--kd", "15,20,8"];
    let told = fit(
        "told.json",
        &[&servo[..], &["--servo-velocity-cutoff-hz", "50"]].concat(),
    );
    let untold = fit("untold.json", &servo);
    let from_run = fit("from_run.json", &[]);
    let cutoff = |m: &RkgnnModel| match &m.report.servo {
        evoloop::rkgnn_model::model::ServoPrior::Known {
            velocity_cutoff_hz, ..
        } => *velocity_cutoff_hz,
        other => panic!("{other:?}"),
    };
    assert_eq!(cutoff(&from_run), Some(50.0));
    assert_eq!(cutoff(&told), Some(50.0));
    assert_eq!(cutoff(&untold), None);
    let bad = tmp.path().join("bad.json");
    let refused = identify(
        &out,
        &bad,
        "0",
        &[&gains[..], &servo, &["--servo-velocity-cutoff-hz=-5"]].concat(),
    );
    assert_refused(&refused, "velocity cutoff must be a positive frequency");
    assert!(!bad.exists());
    // The run's scenario.json gives the same filter, so the same model (its torque limits are
    // not reached on this run).
    assert_eq!(from_run.net.params(), told.net.params());
    let data = Trajectory::from_run(&out, SMOOTHING).unwrap();
    let lag = data.h / ((2.0 * std::f64::consts::PI * 50.0 * data.h).exp() - 1.0) + 0.5 * data.h;
    let mut gap = [0.0; 3];
    let positions: Vec<&[f64]> = data.x.chunks(6).step_by(50).map(|x| &x[..3]).collect();
    for q in &positions {
        let mut a = [0.0; evoloop::MAX_JOINTS * evoloop::MAX_JOINTS];
        let mut b = a;
        told.net.inertia(q, &mut a);
        untold.net.inertia(q, &mut b);
        for j in 0..3 {
            gap[j] += (a[4 * j] - b[4 * j]) / positions.len() as f64;
        }
    }
    println!("M-hat diagonal, told minus untold: {gap:?}");
    for (j, kd) in [15.0, 20.0, 8.0].iter().enumerate() {
        assert!(
            gap[j] > 0.25 * kd * lag,
            "joint {j}: {} against k_d lag {}",
            gap[j],
            kd * lag
        );
    }
}

#[test]
fn a_model_identified_under_the_known_servo_has_the_arms_gravity_and_an_inertia_no_better_than_a_constant(
) {
    // Judged (never fitted) against the true arm: G-hat and M-hat of the shipped model 1 at the
    // training run's positions against the dynamics crate's G and M. The identification saw
    // the reference, the output, the servo's gains and eq. 2's two numbers.
    let m = RkgnnModel::load(&config("models/arm3_train1.json")).unwrap();
    let arm = evoloop::dynamics::load(&config("robots/arm3.toml")).unwrap();
    let scn = Scenario::load(&config("arm3/arm3_train1.toml"), &Overrides::default()).unwrap();
    let sim = simulate(&scn);
    let data = Trajectory::from_sim(&sim.rows, &scn.reference, scn.timing.period, SMOOTHING);
    let mut d = arm.data();
    let positions: Vec<&[f64]> = data.x.chunks(6).step_by(50).map(|x| &x[..3]).collect();
    // The baseline M-hat must beat: the best constant matrix in hindsight (the true M's mean
    // over the same positions), which knows the truth but not how it varies.
    let mut mean = nalgebra::Matrix3::<f64>::zeros();
    for q in &positions {
        let mt = arm.mass_matrix(&mut d, q);
        mean += nalgebra::Matrix3::from_fn(|a, b| mt[(a, b)]) / positions.len() as f64;
    }
    let (g_rel, m_rel) = relative_errors(&m, &arm, &positions);
    let (mut c_err, mut m_norm) = (0.0, 0.0);
    for q in &positions {
        let mt = arm.mass_matrix(&mut d, q);
        for a in 0..3 {
            for b in 0..3 {
                c_err += (mean[(a, b)] - mt[(a, b)]).powi(2);
                m_norm += mt[(a, b)].powi(2);
            }
        }
    }
    let c_rel = (c_err / m_norm).sqrt();
    eprintln!(
        "relative error on train1: G-hat {g_rel:.4}, M-hat {m_rel:.4}, constant M {c_rel:.4}"
    );
    assert!(g_rel < 0.05, "G-hat off by {g_rel}");
    // Measured: G-hat 1.3 %, M-hat 44 % (the book's Arms chapter; 14 % when the fit took the
    // simulator's noise-free velocities), where the best constant matrix in hindsight, which
    // knows the truth, is 12 % off: from encoder data the fit's M-hat does not follow M(q)
    // better than a constant would (issue 41, open). Bounds a little above the measurement, so
    // that a regression shows.
    assert!(
        c_rel < m_rel && m_rel < 0.5,
        "M-hat off by {m_rel}, the best constant by {c_rel}: the book says M-hat is 44 % off, \
         worse than a constant; correct it"
    );
    assert_eq!(
        m.report.servo,
        evoloop::rkgnn_model::model::ServoPrior::Known {
            kp: vec![150.0, 200.0, 100.0],
            kd: vec![15.0, 20.0, 8.0],
            limits: Some(vec![40.0, 60.0, 30.0]),
            velocity_cutoff_hz: Some(50.0),
        }
    );
}

#[test]
fn identification_never_opens_the_robot_file() {
    // The run's scenario.json names its robot; point it at a file that does not exist, and
    // the identification (either servo prior) gives the same model bit for bit.
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = training_run(tmp.path(), "rk_norobot");
    let blind = tmp.path().join("blind");
    std::fs::create_dir_all(&blind).unwrap();
    std::fs::copy(out.join("run.csv"), blind.join("run.csv")).unwrap();
    let mut scn = json(&out.join("scenario.json"));
    assert!(scn["plant"]["robot"].is_string(), "{}", scn["plant"]);
    scn["plant"]["robot"] = "/nonexistent/robot.urdf".into();
    std::fs::write(blind.join("scenario.json"), scn.to_string()).unwrap();
    // The shipped recipe, and the paper's search from its own start (a short one).
    for (evaluations, extra) in [("0", &SHIPPED[..]), ("200", &["--threads", "1"][..])] {
        let (a, b) = (tmp.path().join("a.json"), tmp.path().join("b.json"));
        assert_ok(&identify(&out, &a, evaluations, extra));
        assert_ok(&identify(&blind, &b, evaluations, extra));
        let (a, b) = (RkgnnModel::load(&a).unwrap(), RkgnnModel::load(&b).unwrap());
        assert_eq!(a.net.params(), b.net.params(), "{extra:?}");
    }
}

#[test]
fn the_shipped_models_are_positive_definite_on_every_training_sample() {
    for name in ["arm3_train1", "arm3_train2"] {
        let m = RkgnnModel::load(&config(&format!("models/{name}.json"))).unwrap();
        let scn =
            Scenario::load(&config(&format!("arm3/{name}.toml")), &Overrides::default()).unwrap();
        let sim = simulate(&scn);
        let data = Trajectory::from_sim(&sim.rows, &scn.reference, scn.timing.period, SMOOTHING);
        let lo = min_eig_on(&m, &data);
        assert!(lo > 0.0, "{name}: smallest eigenvalue {lo}");
        assert!(m.report.min_eig_m_hat > 0.0);
    }
}

#[test]
fn rkgnn_eval_prints_a_symmetric_m_hat_v_hat_and_g_hat() {
    let o = cli(&[
        "rkgnn",
        "eval",
        "--model",
        config("models/arm3_train1.json").to_str().unwrap(),
        "--q",
        "0,0.7,-1.3",
        "--qd",
        "0.5,-0.2,0.1",
        "--json",
    ]);
    let v = stdout_json(&o);
    let m = v["M_hat"].as_array().unwrap();
    assert_eq!(m.len(), 3);
    for (a, row) in m.iter().enumerate() {
        for (b, v) in row.as_array().unwrap().iter().enumerate() {
            assert_eq!(*v, m[b][a]);
        }
    }
    assert_eq!(v["V_hat"].as_array().unwrap().len(), 3);
    assert_eq!(v["G_hat"].as_array().unwrap().len(), 3);
    assert!(v["min_eig_m_hat"].as_f64().unwrap() > 0.0);
    let bad = cli(&[
        "rkgnn",
        "eval",
        "--model",
        config("models/arm3_train1.json").to_str().unwrap(),
        "--q",
        "0,0.7",
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--q needs 3 values"));
}

#[test]
fn the_fuzzy_scenario_through_the_processes_equals_the_in_process_simulation() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(
        &config("arm3/arm3_fuzzy_ct.toml"),
        &out,
        "rk_fuzzy",
        &["--duration", "2"],
    ));
    let scn = Scenario::load(
        &config("arm3/arm3_fuzzy_ct.toml"),
        &Overrides {
            duration: Some(2.0),
            ..Default::default()
        },
    )
    .unwrap();
    let csv = assert_same_run(&out, &simulate(&scn));
    // The selector's record: the active model and memberships summing to 1, both models used.
    let active = csv.col("fuzzy_model");
    let (w0, w1) = (csv.col("fuzzy_w0"), csv.col("fuzzy_w1"));
    for i in 0..active.len() {
        assert!((w0[i] + w1[i] - 1.0).abs() < 1e-12);
        assert_eq!(active[i], if w1[i] > w0[i] { 1.0 } else { 0.0 }, "at {i}");
    }
    assert!(active.contains(&0.0) && active.contains(&1.0));
}

#[test]
fn the_fuzzy_scenario_runs_at_one_kilohertz_in_realtime() {
    let _alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(
        &config("arm3/arm3_fuzzy_ct.toml"),
        &out,
        "rk_fuzzy_rt",
        &["--mode", "realtime", "--duration", "3"],
    ));
    let s = json(&out.join("summary.json"));
    assert_eq!(s["mode"], "realtime");
    if let Err(line) = rate_kept(&s, 3.0) {
        panic!("the fuzzy computed-torque controller did not keep its rate: {line}");
    }
}

#[test]
fn the_evidence_rule_takes_its_keys_and_they_are_refused_elsewhere_with_file_key_and_reason() {
    let cfg = config("arm3/arm3_fuzzy_ct.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    let with = |rule: &str| text.replace("selection = \"max\"", rule);
    let parse =
        |t: &str| Scenario::parse(t, &cfg, &Overrides::default()).map_err(|e| e.to_string());
    let scn = parse(&with(
        "selection = \"evidence\"\nevidence_bandwidth = 40.0\nevidence_memory = 1.5",
    ))
    .unwrap();
    let v = serde_json::to_value(&scn.controller).unwrap();
    assert_eq!(
        (
            &v["selection"],
            &v["evidence_bandwidth"],
            &v["evidence_memory"]
        ),
        (&"evidence".into(), &40.0.into(), &1.5.into()),
        "{v}"
    );
    // The defaults.
    let v = serde_json::to_value(parse(&with("selection = \"evidence\"")).unwrap().controller);
    let v = v.unwrap();
    assert_eq!(
        (
            &v["evidence_prior"],
            &v["evidence_bandwidth"],
            &v["evidence_memory"]
        ),
        (&"uniform".into(), &50.0.into(), &0.5.into())
    );
    let scn = parse(&with(
        "selection = \"evidence\"\nevidence_prior = \"memberships\"",
    ));
    let v = serde_json::to_value(scn.unwrap().controller).unwrap();
    assert_eq!(v["evidence_prior"], "memberships");
    let refused = |rule: &str, key: &str, reason: &str| {
        let e = parse(&with(rule)).unwrap_err();
        assert!(e.contains("arm3/arm3_fuzzy_ct.toml"), "{e}");
        assert!(
            e.contains(&format!("controller.fuzzy_computed_torque.{key}")),
            "{e}"
        );
        assert!(e.contains(reason), "{e}");
    };
    // A key that would do nothing under another rule is an error, not ignored.
    refused(
        "selection = \"max\"\nevidence_memory = 1.0",
        "evidence_memory",
        "only with selection = \"evidence\"",
    );
    refused(
        "selection = \"blend\"\nevidence_prior = \"uniform\"",
        "evidence_prior",
        "only with selection = \"evidence\"",
    );
    refused(
        "selection = \"evidence\"\nevidence_bandwidth = -50.0",
        "evidence_bandwidth",
        "> 0",
    );
    refused(
        "selection = \"evidence\"\nevidence_memory = nan",
        "evidence_memory",
        "> 0",
    );
}

#[test]
fn a_model_file_for_another_arm_is_refused_with_file_key_and_reason() {
    let tmp = tempfile::tempdir().unwrap();
    // A 3-joint model file with one parameter too few.
    let text = std::fs::read_to_string(config("models/arm3_train1.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let needs = v["params"].as_array().unwrap().len();
    v["params"].as_array_mut().unwrap().pop();
    let models = tmp.path().join("models");
    std::fs::create_dir_all(&models).unwrap();
    std::fs::write(models.join("short.json"), v.to_string()).unwrap();
    let robots = tmp.path().join("robots");
    std::fs::create_dir_all(&robots).unwrap();
    std::fs::copy(config("robots/arm3.toml"), robots.join("arm3.toml")).unwrap();
    let scn = std::fs::read_to_string(config("arm3/arm3_fuzzy_ct.toml"))
        .unwrap()
        .replace("\"../", "\"")
        .replace("models/arm3_train2.json", "models/short.json")
        .replace(
            "models/arm3_train1.json",
            config("models/arm3_train1.json").to_str().unwrap(),
        );
    let file = write(tmp.path(), "bad.toml", &scn);
    let o = cli(&["check", file.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("bad.toml"), "{e}");
    assert!(
        e.contains("controller.fuzzy_computed_torque.models[1]"),
        "{e}"
    );
    assert!(
        e.contains(&format!(
            "params: {} values, the network needs {needs}",
            needs - 1
        )),
        "{e}"
    );
}

/// The shipped fuzzy scenario's text with its relative paths made absolute and `edit` applied,
/// simulated in process: the RMS tracking error per joint over the whole run (rad).
fn tracking_rms(edit: impl Fn(String) -> String) -> [f64; 3] {
    let dir = config("");
    let text = std::fs::read_to_string(config("arm3/arm3_fuzzy_ct.toml"))
        .unwrap()
        .replace("\"../robots/", &format!("\"{}robots/", dir.display()))
        .replace("\"../models/", &format!("\"{}models/", dir.display()));
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("variant.toml");
    std::fs::write(&path, edit(text)).unwrap();
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let sim = simulate(&scn);
    let mut sp = evoloop::reference::Setpoint::default();
    let mut sum = [0.0; 3];
    for row in &sim.rows {
        scn.reference.sample(row.state.t, &mut sp);
        for (j, s) in sum.iter_mut().enumerate() {
            *s += (sp.q[j] - row.state.y[j]).powi(2);
        }
    }
    sum.map(|s| (s / sim.rows.len() as f64).sqrt())
}

fn overall(rms: [f64; 3]) -> f64 {
    (rms.iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt()
}

#[test]
fn fuzzy_computed_torque_tracks_the_new_trajectory_better_than_the_servo_and_each_single_model() {
    // Over five measurement-noise seeds (the shipped scenario's is 1), every variant on the
    // same seed: a paired comparison.
    for seed in 1..=5 {
        let seeded = move |t: String| t.replacen("seed = 1\n", &format!("seed = {seed}\n"), 1);
        let models = "models = [\"";
        let fuzzy = tracking_rms(seeded);
        let only = |k: usize| {
            tracking_rms(move |t| {
                let t = seeded(t);
                let start = t.find(models).unwrap();
                let end = start + t[start..].find(']').unwrap() + 1;
                let list: Vec<&str> = t[start + models.len() - 1..end - 1].split(", ").collect();
                format!("{}models = [{}]{}", &t[..start], list[k], &t[end..])
            })
        };
        let (one, two) = (only(0), only(1));
        // The P-D servo alone: the training runs' controller on the new trajectory.
        let pd = tracking_rms(move |t| {
            let t = seeded(t);
            let c = t.find("[controller]").unwrap();
            let r = t.find("[reference]").unwrap();
            let servo = std::fs::read_to_string(config("arm3/arm3_train1.toml")).unwrap();
            let (sc, sr) = (
                servo.find("[controller]").unwrap(),
                servo.find("[reference]").unwrap(),
            );
            format!("{}{}{}", &t[..c], &servo[sc..sr], &t[r..])
        });
        let best = overall(one).min(overall(two));
        eprintln!(
            "seed {seed}: rms fuzzy {:.5}, model 1 {:.5}, model 2 {:.5}, servo {:.5} \
             (per joint: fuzzy {fuzzy:.5?}, servo {pd:.5?})",
            overall(fuzzy),
            overall(one),
            overall(two),
            overall(pd)
        );
        assert!(
            overall(fuzzy) < overall(pd),
            "seed {seed}: fuzzy CT vs the P-D servo"
        );
        // The new trajectory is the midpoint of the two training ones (issue 41: a selection
        // study on trajectories that are not is still to come), so this is the paper's claim on
        // the paper's case only.
        assert!(
            overall(fuzzy) < best,
            "seed {seed}: fuzzy CT vs the better single model"
        );
    }
}

/// `evoloop rkgnn study --json` on `robot` into a fresh directory: the JSON and the directory.
fn study(robot: &str) -> (serde_json::Value, tempfile::TempDir) {
    study_with(&["--robot", robot])
}

/// `evoloop rkgnn study --json ARGS` into a fresh directory (`study/` in it).
fn study_with(args: &[&str]) -> (serde_json::Value, tempfile::TempDir) {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    let mut all = vec!["rkgnn", "study", "--out", out.to_str().unwrap(), "--json"];
    all.extend_from_slice(args);
    let o = cli(&all);
    (stdout_json(&o), tmp)
}

const STUDY_KEYS: [&str; 6] = [
    "pd",
    "ct_true",
    "ct_model_1",
    "ct_model_2",
    "ct_fuzzy_max",
    "ct_fuzzy_blend",
];

/// The six per-joint tracking errors of a study, by key.
fn study_rms(v: &serde_json::Value) -> Vec<[f64; 3]> {
    let t = v["tracking_rms"].as_object().expect("tracking_rms");
    assert_eq!(t.len(), 6, "{t:?}");
    STUDY_KEYS
        .iter()
        .map(|k| {
            let row: Vec<f64> = t[*k]
                .as_array()
                .unwrap_or_else(|| panic!("tracking_rms.{k}"))
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            assert_eq!(row.len(), 3, "{k}");
            assert!(
                row.iter().all(|x| x.is_finite() && *x > 0.0),
                "{k}: {row:?}"
            );
            [row[0], row[1], row[2]]
        })
        .collect()
}

/// The paper's ordering: fuzzy CT below the P-D servo and the worse single model, the true model
/// below them all.
fn assert_paper_ordering(rms: &[[f64; 3]]) {
    let o: Vec<f64> = rms.iter().map(|r| overall(*r)).collect();
    let (pd, ct_true, m1, m2, max, blend) = (o[0], o[1], o[2], o[3], o[4], o[5]);
    assert!(max < pd && max < m1.max(m2), "{o:?}");
    assert!(blend < pd && blend < m1.max(m2), "{o:?}");
    assert!(ct_true < max && ct_true < blend, "{o:?}");
}

#[test]
fn rkgnn_study_on_arm3_is_the_shipped_scenarios_and_writes_figures_7_to_10() {
    let (v, tmp) = study("config/robots/arm3.toml");
    let dir = tmp.path().join("study");
    let rms = study_rms(&v);
    assert_paper_ordering(&rms);
    // On arm3 the servo is the training scenarios' own (ratio exactly 1), the models are the
    // shipped ones and the fuzzy case is config/arm3/arm3_fuzzy_ct.toml.
    assert!(v["inertia_ratio"]
        .as_array()
        .unwrap()
        .iter()
        .all(|r| r.as_f64() == Some(1.0)));
    for k in 1..=2 {
        let made = RkgnnModel::load(&dir.join(format!("model_{k}.json"))).unwrap();
        let shipped = RkgnnModel::load(&config(&format!("models/arm3_train{k}.json"))).unwrap();
        assert_eq!(made.net.params(), shipped.net.params(), "model {k}");
    }
    assert_eq!(
        rms[4],
        tracking_rms(|t| t),
        "ct_fuzzy_max vs the shipped scenario"
    );
    for f in [
        "study.json",
        "tracking_rms.csv",
        "report.md",
        "fig7_trajectories.png",
        "fig8_model_1_on_train1.png",
        "fig9_model_2_on_train2.png",
        "fig10_fuzzy_on_new.png",
        "tracking_new.png",
        "runs/ct_fuzzy_max.csv",
    ] {
        let len = std::fs::metadata(dir.join(f)).map_or(0, |m| m.len());
        assert!(len > 0, "{f} missing or empty");
    }
    // Every case's scenario is a valid scenario file a user can rerun.
    for k in STUDY_KEYS {
        let path = dir.join("scenarios").join(format!("{k}.toml"));
        Scenario::load(&path, &Overrides::default()).unwrap_or_else(|e| panic!("{e}"));
    }
    let csv = std::fs::read_to_string(dir.join("tracking_rms.csv")).unwrap();
    assert!(csv.starts_with("controller,joint1,joint2,joint3,overall\npd,"));
    // What the identification was given: the runs and eq. 2's bounds, never the robot file.
    let inputs = &v["identification_inputs"];
    assert_eq!(inputs["runs"], serde_json::json!(["train1", "train2"]));
    assert!(inputs["m1"].as_f64().unwrap() > 0.0 && inputs["m2"].as_f64().unwrap() > 0.0);
    let listed = inputs.to_string();
    for robot in ["arm3.toml", "robots", ".urdf"] {
        assert!(
            !listed.contains(robot),
            "the inputs name the robot: {listed}"
        );
    }
    // Each model's smallest eigenvalue along the new trajectory, where the controller runs it.
    let scn = Scenario::load(
        &dir.join("scenarios/ct_fuzzy_max.toml"),
        &Overrides::default(),
    )
    .unwrap();
    let along = evoloop::law::fuzzy_computed_torque::reference_positions(
        &scn.reference,
        scn.timing.duration,
    );
    for (k, m) in v["models"].as_array().unwrap().iter().enumerate() {
        let model = RkgnnModel::load(&dir.join(format!("model_{}.json", k + 1))).unwrap();
        let on_reference = m["min_eig_on_reference"].as_f64().unwrap();
        // The file's decimal round trip may move the last bits.
        let reloaded = model.min_eig(along.iter().map(Vec::as_slice));
        assert!(
            (on_reference - reloaded).abs() <= 1e-12 * reloaded.abs(),
            "{on_reference} vs {reloaded}"
        );
        assert!(on_reference > 0.0, "model {}: {on_reference}", k + 1);
    }
}

#[test]
fn rkgnn_study_works_on_a_ros_style_urdf_arm_it_was_not_tuned_on() {
    // Heavier, longer links, other torque limits, a massless root, transmissions and
    // ros2_control blocks (tests/robots/rrr_style.urdf).
    let (v, _tmp) = study("tests/robots/rrr_style.urdf");
    assert_paper_ordering(&study_rms(&v));
    let ratio: Vec<f64> = v["inertia_ratio"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r.as_f64().unwrap())
        .collect();
    assert!(
        ratio.iter().all(|r| *r > 1.5),
        "the servo scales with the arm's inertia: {ratio:?}"
    );
    for m in v["models"].as_array().unwrap() {
        assert!(m["min_eig_m_hat"].as_f64().unwrap() > 0.0, "{m}");
    }
}

/// `evoloop rkgnn study` on `robot`, which must refuse it with exit code 2: its stderr.
fn study_refused(robot: &str) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = cli(&[
        "rkgnn",
        "study",
        "--out",
        out.to_str().unwrap(),
        "--robot",
        robot,
    ]);
    assert_eq!(o.status.code(), Some(2));
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn rkgnn_study_refuses_an_arm_that_is_not_three_joints() {
    let e = study_refused("config/robots/industrial6.toml");
    assert!(
        e.contains("industrial6.toml") && e.contains("3-joint"),
        "{e}"
    );
}

#[test]
fn rkgnn_study_refuses_an_arm_whose_joint_limits_the_trajectories_leave() {
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/robots/rrr_style.urdf"),
    )
    .unwrap()
    .replace(r#"lower="-2.9" upper="2.9""#, r#"lower="-1.5" upper="1.5""#);
    let robot = tmp.path().join("narrow.urdf");
    std::fs::write(&robot, text).unwrap();
    let e = study_refused(robot.to_str().unwrap());
    assert!(
        e.contains("narrow.urdf") && e.contains("forearm_joint"),
        "{e}"
    );
}

#[test]
fn identify_mode_publishes_only_models_that_predict_fresh_data_better_and_the_loop_takes_them() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    // arm3_payload: arm3_identify's loop, whose arm changes at 6 s.
    for (out, tag) in [(&a, "rk_ident_a"), (&b, "rk_ident_b")] {
        assert_ok(&run(&config("arm3/arm3_payload.toml"), out, tag, &[]));
    }
    // Lockstep: the attempts are at fixed simulated times, so the run is reproducible.
    let csv = |d: &Path| std::fs::read_to_string(d.join("run.csv")).unwrap();
    assert_eq!(csv(&a), csv(&b), "two lockstep runs of one seed differ");
    // 30 s, a first attempt once 5 s of data are in, then every 2 s.
    assert_published_only_better(&a, 12);
}

/// An identify run in `out` made at least `attempts` attempts, published at least one model,
/// each only when it beat the model in service by the scenarios' margin (0.2), and the loop
/// took every one.
fn assert_published_only_better(out: &Path, attempts: usize) -> serde_json::Value {
    let opt = json(&out.join("optimiser.json"));
    let epochs = opt["epochs"].as_array().unwrap();
    assert!(epochs.len() >= attempts, "{} attempts", epochs.len());
    let published: Vec<&serde_json::Value> =
        epochs.iter().filter(|e| e["published"].is_u64()).collect();
    assert!(!published.is_empty(), "no model published: {epochs:?}");
    for e in &published {
        let (cand, held) = (
            e["best_cost"].as_f64().unwrap(),
            e["in_service_cost"].as_f64().unwrap(),
        );
        assert!(
            cand < 0.8 * held,
            "published without beating the model in service: {e}"
        );
    }
    let summary = json(&out.join("summary.json"));
    assert_eq!(
        summary["accepted_versions"].as_u64(),
        Some(published.len() as u64)
    );
    assert_eq!(summary["rejected_versions"].as_u64(), Some(0));
    summary
}

/// arm7_payload, shortened to 14 s: the 7-DOF arm's models (3395 values, more than one
/// parameter set) are updated alongside operation, travel in parts, are taken whole by the loop,
/// and track the loaded arm better than the starting models do. Fitted from zero, no attempt on
/// this arm was positive definite (the book's Known limits until 2026-11-29).
#[test]
fn identify_mode_updates_arm7s_models_in_parts_and_tracks_the_loaded_arm_better() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("arm7");
    let args = ["--duration", "14"];
    assert_ok(&run(
        &config("arm7/arm7_payload.toml"),
        &out,
        "rk_arm7_ident",
        &args,
    ));
    // A first attempt once 5 s of data are in, then every 2 s.
    let summary = assert_published_only_better(&out, 4);
    let (after, frozen) = (
        summary["tracking_after_change"].as_f64().unwrap(),
        summary["tracking_after_change_frozen"].as_f64().unwrap(),
    );
    assert!(
        after < frozen,
        "identified {after} rad against frozen {frozen}"
    );
}

/// `--seeds` on identification alongside operation whose arm does not change (arm3_identify):
/// the study compares the last quarter, identified against frozen, per seed from the runs' own
/// summaries (before 2026-11-29 every seed "failed" for want of a number before the change).
#[test]
fn a_seeds_study_of_an_unchanging_arm_compares_the_last_quarter() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    assert_ok(&run(
        &config("arm3/arm3_identify.toml"),
        &out,
        "rk_unchanged",
        &["--seeds", "1..3"],
    ));
    let study = json(&out.join("study.json"));
    let comparisons = study["comparisons"].as_array().unwrap();
    assert_eq!(comparisons.len(), 1, "{study}");
    assert_eq!(comparisons[0]["phase"], "over the last quarter");
    assert_eq!(study["failed"].as_array().unwrap().len(), 0, "{study}");
    let rows = Csv::read(&out.join("seeds.csv"));
    for (i, seed) in (1..=3).enumerate() {
        let s = json(&out.join(format!("seed-{seed}/summary.json")));
        assert!(s["tracking_before_change"].is_null());
        let after = 1e3 * s["tracking_after_change"].as_f64().unwrap();
        assert_eq!(rows.col("tracking_mrad_after")[i], after);
        assert!(rows.col("tracking_mrad_before")[i].is_nan());
    }
    let md = std::fs::read_to_string(out.join("study.md")).unwrap();
    assert!(md.contains("does not change"), "{md}");
}

#[test]
fn identify_mode_on_a_controller_without_models_is_refused_with_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().to_str().unwrap();
    let args = [
        "run",
        "config/arm3/arm3_pd.toml",
        "--optimiser",
        "identify",
        "--out",
        out,
    ];
    let o = cli(&args);
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("arm3/arm3_pd.toml") && e.contains("optimiser.mode"),
        "{e}"
    );
}

/// The paired study the book quotes (seeds 1..10): identification alongside operation tracks
/// the arm better after it picks up a payload than the frozen starting models do, on most seeds
/// and significantly, and the frozen comparison in the report is what a lockstep run with the
/// optimiser off gives (recomputed here from that run's run.csv).
#[test]
fn identification_alongside_operation_beats_the_frozen_models_after_a_payload_over_seeds() {
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("study");
    let scn = config("arm3/arm3_payload.toml");
    assert_ok(&run(&scn, &out, "rk_payload", &["--seeds", "1..10"]));
    let study = json(&out.join("study.json"));
    assert_eq!(study["measure"]["column"], "tracking_mrad");
    let after = &study["comparisons"][1];
    assert_eq!(after["phase"], "after the change");
    // Measured (2026-11-29, the update centred on the model in service): lower on 10 of 10
    // seeds, exact two-sided Wilcoxon p = 0.002 (9 of 10, p = 0.010, fitted from zero).
    assert!(
        after["wilcoxon"]["a_lower"].as_u64().unwrap() >= 8,
        "{after}"
    );
    assert!(after["wilcoxon"]["p_two_sided"].as_f64().unwrap() < 0.05);
    let sentence = after["sentence"].as_str().unwrap();
    assert!(
        sentence.starts_with("Identification alongside operation has a lower tracking RMS"),
        "{sentence}"
    );
    // Measured: -73 % [-75, -70] over seeds 1..10 (the book's Arms chapter; -25 % [-41, -9]
    // when each attempt was fitted from zero).
    let rel = after["relative_pct"]["mean"].as_f64().unwrap();
    assert!(rel < -10.0, "identified vs frozen: {rel} %");
    // The study's per-seed numbers are the runs' own summaries, in mrad.
    let rows = Csv::read(&out.join("seeds.csv"));
    for (i, seed) in (1..=10).enumerate() {
        let s = json(&out.join(format!("seed-{seed}/summary.json")));
        for (col, key) in [
            ("tracking_mrad_after", "tracking_after_change"),
            ("tracking_mrad_after_frozen", "tracking_after_change_frozen"),
        ] {
            assert_eq!(rows.col(col)[i], 1e3 * s[key].as_f64().unwrap(), "{col}");
        }
    }
    let seed1 = out.join("seed-1");
    assert_plotted(&seed1.join("identify.png"));

    // The frozen comparison against a lockstep run of the processes with the optimiser off.
    let off = tmp.path().join("off");
    assert_ok(&run(
        &scn,
        &off,
        "rk_payload_off",
        &["--optimiser", "off", "--seed", "1"],
    ));
    let rows = Csv::read(&off.join("run.csv"));
    let t = rows.col("t");
    let (r, y): (Vec<Vec<f64>>, Vec<Vec<f64>>) = (
        vec![rows.col("reference"), rows.col("r1"), rows.col("r2")],
        (0..3).map(|j| rows.col(&format!("y{j}"))).collect(),
    );
    let rms = |a: f64, b: f64| {
        let (mut s, mut c) = (0.0, 0);
        for k in (0..t.len()).filter(|&k| t[k] >= a && t[k] < b) {
            for j in 0..3 {
                s += (r[j][k] - y[j][k]).powi(2);
                c += 1;
            }
        }
        (s / c as f64).sqrt()
    };
    let summary = json(&seed1.join("summary.json"));
    for (key, want) in [
        ("tracking_before_change_frozen", rms(1.0, 6.0)),
        ("tracking_after_change_frozen", rms(22.5, f64::INFINITY)),
    ] {
        let got = summary[key].as_f64().unwrap();
        assert!((got - want).abs() <= 1e-12 * want, "{key}: {got} vs {want}");
    }
}

#[test]
fn a_christoffel_model_has_no_velocity_network_and_its_v_hat_keeps_eq_3() {
    // --velocity christoffel: the model file's velocity network is empty (90 parameters fewer
    // for 3 joints) and V-hat comes from M-hat, so that qd^T V-hat = 1/2 qd^T M-hat' qd (eq. 3),
    // checked here on the written model by central differences of its own M-hat.
    let dir = tempfile::tempdir().unwrap();
    let data = training_run(dir.path(), "rk_chr");
    let (net_file, chr_file) = (dir.path().join("net.json"), dir.path().join("chr.json"));
    assert_ok(&identify(&data, &net_file, "0", &SHIPPED));
    let christoffel = [&SHIPPED[..], &["--velocity", "christoffel"]].concat();
    assert_ok(&identify(&data, &chr_file, "0", &christoffel));
    let (net, chr) = (
        RkgnnModel::load(&net_file).unwrap(),
        RkgnnModel::load(&chr_file).unwrap(),
    );
    assert_eq!(chr.net.layout.counts.velocity, 0);
    assert_eq!(net.net.layout.len - chr.net.layout.len, 90);
    let q = [0.2, 0.6, -1.1];
    let qd = [0.8, -0.5, 0.9];
    let mut v = [0.0; 3];
    chr.net.velocity(&q, &qd, &mut v);
    let h = 1e-6;
    let m_at = |s: f64| {
        let mut m = [0.0; evoloop::MAX_JOINTS * evoloop::MAX_JOINTS];
        let qs: Vec<f64> = (0..3).map(|j| q[j] + s * qd[j]).collect();
        chr.net.inertia(&qs, &mut m);
        m
    };
    let (fwd, back) = (m_at(h), m_at(-h));
    let half_mdot: f64 = (0..3)
        .flat_map(|a| (0..3).map(move |b| (a, b)))
        .map(|(a, b)| 0.5 * qd[a] * (fwd[a * 3 + b] - back[a * 3 + b]) / (2.0 * h) * qd[b])
        .sum();
    let power: f64 = (0..3).map(|i| qd[i] * v[i]).sum();
    assert!(
        (power - half_mdot).abs() < 1e-6 * (1.0 + power.abs()),
        "{power} vs {half_mdot}"
    );
}

#[test]
fn rkgnn_prior_is_the_eigenvalue_range_of_the_robots_mass_matrix() {
    // Judged against the dynamics crate's M(q) directly: over a run's measured positions the
    // command's m1, m2 are the smallest and largest eigenvalue seen (nalgebra's, not ours).
    let dir = tempfile::tempdir().unwrap();
    let data = training_run(dir.path(), "rk_prior");
    let robot = config("robots/arm3.toml");
    let o = cli(&[
        "rkgnn",
        "prior",
        "--robot",
        robot.to_str().unwrap(),
        "--data",
        data.to_str().unwrap(),
        "--json",
    ]);
    assert_ok(&o);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let arm = evoloop::dynamics::load(&robot).unwrap();
    let mut d = arm.data();
    let t = Trajectory::from_run(&data, SMOOTHING).unwrap();
    let (mut lo, mut hi) = (f64::INFINITY, 0.0f64);
    for x in t.x.chunks(6) {
        let m = arm.mass_matrix(&mut d, &x[..3]);
        let e = nalgebra::SymmetricEigen::new(nalgebra::DMatrix::from_fn(3, 3, |a, b| m[(a, b)]));
        lo = lo.min(e.eigenvalues.min());
        hi = hi.max(e.eigenvalues.max());
    }
    assert_eq!(v["positions"].as_u64().unwrap() as usize, t.len());
    assert!(
        (v["m1"].as_f64().unwrap() / lo - 1.0).abs() < 1e-9,
        "{v} vs {lo}"
    );
    assert!(
        (v["m2"].as_f64().unwrap() / hi - 1.0).abs() < 1e-9,
        "{v} vs {hi}"
    );
    let bad = cli(&["rkgnn", "prior", "--robot", "/nonexistent.toml"]);
    assert!(!bad.status.success());
}

/// `evoloop rkgnn selection --out OUT ARGS --json`: selection.json as printed.
fn selection(out: &Path, args: &[&str]) -> serde_json::Value {
    let mut all = vec![
        "rkgnn",
        "selection",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    all.extend_from_slice(args);
    stdout_json(&cli(&all))
}

#[test]
fn the_selection_study_finds_fuzzy_max_above_the_best_single_model_as_the_readme_says() {
    // `evoloop rkgnn selection`: three models, four trajectories that are not midpoints, every
    // baseline. The README reports that the paper's max rule is above the best single model in
    // hindsight on 39 of 40 (seed, trajectory) pairs; seed 1 (the training trajectories as
    // written) is one where it is above on all four, checked here, so that a change that made
    // the claim false would fail until the README says otherwise.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sel");
    let v = selection(&out, &["--seeds", "1"]);
    assert!(out.join("selection.json").is_file() && out.join("report.md").is_file());
    let cells = v["cells"].as_array().unwrap();
    assert_eq!(cells.len(), 4, "one seed, four trajectories");
    // A model the controller refused on a trajectory has no run there (null).
    let rms = |c: &serde_json::Value, key: &str| -> Option<f64> {
        let row = c["rms"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r[0] == key)
            .unwrap_or_else(|| panic!("{key}"));
        serde_json::from_value::<[f64; 3]>(row[1].clone())
            .ok()
            .map(overall)
    };
    let ran = |c: &serde_json::Value, key: &str| rms(c, key).unwrap_or_else(|| panic!("{key}"));
    for c in cells {
        let singles: Vec<f64> = ["ct_model_1", "ct_model_2", "ct_model_3"]
            .iter()
            .filter_map(|k| rms(c, k))
            .collect();
        let best = singles.iter().cloned().fold(f64::INFINITY, f64::min);
        assert_eq!(ran(c, "best_single"), best);
        assert!(
            ran(c, "fuzzy_max") >= best,
            "{}: fuzzy max {} below the best single model {best}: update the README",
            c["trajectory"],
            ran(c, "fuzzy_max")
        );
        // A model not positive definite along the trajectory is refused by the controller and
        // left out (on seed 1: train3's model along beyond2), every other one ran.
        let indefinite = c["min_eig_on_reference"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e.as_f64().unwrap() <= 0.0)
            .count();
        assert_eq!(c["refused"], indefinite, "{c}");
        assert_eq!(singles.len(), 3 - indefinite, "{c}");
        assert!(ran(c, "ct_true") < ran(c, "pd_matched"));
    }
    // (claim_held is false whatever happens with one seed: one seed cannot reach p < 0.05. The
    // per-trajectory checks above are this test's claim.)
    // Five rules (max, blend, uniform blend, evidence on memberships and on a uniform prior),
    // each against the fifteen other controllers, over the seeds and per task.
    assert_eq!(v["comparisons"].as_array().unwrap().len(), 75);
    let tasks = v["tasks"].as_array().unwrap();
    assert_eq!(tasks.len(), 4);
    assert!(tasks
        .iter()
        .all(|t| t["comparisons"].as_array().unwrap().len() == 75));
    assert_eq!(v["comparisons"][0]["pairs"], 1, "pairs are seeds");
}

#[test]
fn a_fit_in_newton_metres_without_a_positive_definite_m_hat_is_weighed_as_needed() {
    // gen3_s28, a development arm (seeds below 1000; the zoo's are fixed in
    // config/robots/zoo.toml), seeds 1 and 2: the known-servo least squares in N m finds a
    // positive definite M-hat for five of the six training runs, not for seed 2's train2. As
    // needed (the default), only that run is fitted again with each joint in units of its own
    // torque rms (`--weigh-joints` alone: always); every other run keeps its fit in N m.
    let tmp = tempfile::tempdir().unwrap();
    let arm = tmp.path().join("gen3_s28.urdf");
    let arm_s = arm.to_str().unwrap();
    let o = cli(&[
        "robot", "generate", "--joints", "3", "--seed", "28", "--out", arm_s,
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let study = |name: &str, weigh: &[&str]| {
        let out = tmp.path().join(name);
        let v = selection(
            &out,
            &[&["--robot", arm_s, "--seeds", "2"][..], weigh].concat(),
        );
        (v, out)
    };
    let names = |v: &serde_json::Value, key: &str| -> Vec<String> {
        let runs = v[key].as_array().unwrap().iter();
        runs.map(|u| u.as_str().unwrap().split(':').next().unwrap().to_string())
            .collect()
    };
    let (never, never_dir) = study("never", &["--weigh-joints", "never"]);
    let (needed, needed_dir) = study("as_needed", &[]);
    let (always, always_dir) = study("always", &["--weigh-joints"]);
    assert_eq!(never["weighing"], "never");
    assert_eq!(needed["weighing"], "as-needed");
    assert_eq!(always["weighing"], "always");
    let failed_in_nm = names(&never, "unidentified");
    assert_eq!(failed_in_nm, ["seed 2, train2"], "update this test's arm");
    // The run that failed in N m, and only it, was weighed, and found a model.
    assert_eq!(names(&needed, "weighed"), failed_in_nm);
    assert!(
        needed["unidentified"].as_array().unwrap().is_empty(),
        "{needed}"
    );
    let params = |dir: &Path, seed: u64, run: &str| {
        let file = dir.join(format!("seed{seed}/model_{run}.json"));
        RkgnnModel::load(&file).map(|m| (m.net.params().to_vec(), m.report.weigh_joints))
    };
    for seed in [1, 2] {
        for run in ["train1", "train2", "train3"] {
            let (p, weighed) = params(&needed_dir, seed, run).unwrap();
            let failed = failed_in_nm.contains(&format!("seed {seed}, {run}"));
            assert_eq!(weighed, failed, "seed {seed}, {run}");
            let same_as = if weighed { &always_dir } else { &never_dir };
            let other = params(same_as, seed, run).ok().map(|m| m.0);
            assert_eq!(Some(p), other, "seed {seed}, {run}");
        }
    }
    // A model file from before the setting was recorded was identified in N m.
    let old = RkgnnModel::load(&config("models/arm3_train1.json")).unwrap();
    assert_eq!(old.report.weighing, None);
    assert_eq!(
        old.report.weighing(),
        evoloop::rkgnn_model::model::Weighing::Never
    );
}

#[test]
fn the_baselines_a_control_engineer_would_use_run_on_a_cad_model_written_down() {
    // pd_gravity (the matched servo with the CAD model's gravity), ct_nominal (computed torque
    // on it) and online_model (one model updated online) ran on every task; the CAD model is
    // the arm's file with its mass properties off by at most 20 %, written to seed1/nominal.urdf
    // with its factors in selection.json; each model is judged against the arm.
    let tmp = tempfile::tempdir().unwrap();
    // An arm whose nominal model URDF cannot carry (armature) is refused before any run.
    let six = config("robots/industrial6.toml");
    let o = tmp.path().join("six");
    let (six, o_str) = (six.to_str().unwrap(), o.to_str().unwrap());
    assert_refused(
        &cli(&["rkgnn", "selection", "--robot", six, "--out", o_str]),
        "industrial6.toml: its nominal model cannot be written as URDF: joint",
    );
    assert!(!o.join("seed1").exists());
    let out = tmp.path().join("sel");
    let v = selection(&out, &["--seeds", "1"]);
    let nominal = &v["nominal"][0];
    let file = nominal["file"].as_str().unwrap();
    assert_eq!(file, out.join("seed1/nominal.urdf").to_str().unwrap());
    let cad = evoloop::dynamics::load(Path::new(file)).unwrap();
    let truth = evoloop::dynamics::load(&config("robots/arm3.toml")).unwrap();
    assert_eq!(v["nominal_spread"], 0.2);
    for (k, e) in nominal["errors"].as_array().unwrap().iter().enumerate() {
        let mass = e["mass"].as_f64().unwrap();
        assert!((0.8..=1.2).contains(&mass), "{e}");
        let (m_cad, m_true) = (cad.bodies[k].inertia.m, truth.bodies[k].inertia.m);
        assert!(
            (m_cad / m_true - mass).abs() < 1e-12,
            "body {k}: {m_cad} / {m_true} != {mass}"
        );
    }
    // A CAD model knows no friction.
    assert!(!cad.has_friction() && truth.has_friction());
    let scenarios = out.join("seed1/scenarios");
    let text = |name: &str| std::fs::read_to_string(scenarios.join(name)).unwrap();
    assert!(text("near1_pd_gravity.toml").contains(&format!("gravity_model = \"{file}\"")));
    assert!(text("near1_ct_nominal.toml").contains(&format!("model = \"{file}\"")));
    assert!(text("near1_online_model.toml").contains("mode = \"identify\""));
    for c in v["cells"].as_array().unwrap() {
        let value = |key: &str| {
            let row = (c["rms"].as_array().unwrap().iter())
                .find(|r| r[0] == key)
                .unwrap();
            overall(serde_json::from_value::<[f64; 3]>(row[1].clone()).unwrap())
        };
        // Gravity compensation from a 20 %-wrong model still takes most of the servo's error.
        assert!(value("pd_gravity") < 0.5 * value("pd_matched"), "{c}");
        assert!(
            value("ct_nominal").is_finite() && value("online_model").is_finite(),
            "{c}"
        );
        // The CAD model is near the arm; the identified models are judged the same way.
        let nominal_error = &c["nominal_error"];
        let m_rel = nominal_error["m_rel"].as_f64().unwrap();
        assert!(m_rel > 0.0 && m_rel < 0.2, "{nominal_error}");
        assert_eq!(c["model_error"].as_array().unwrap().len(), 3);
        assert!(
            c["model_error"][0]["m_scale"].as_f64().unwrap() > 0.0,
            "{c}"
        );
        assert!(c["online_updates"].as_u64().is_some(), "{c}");
    }
}

#[test]
fn identification_alongside_operation_in_this_process_equals_the_processes_in_lockstep() {
    // online_model's runs identify in the study's process (rkgnn::live::simulate): the same
    // attempts at the same samples as the optimiser process, so the same run bit for bit.
    let _heavy = heavy();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    assert_ok(&run(
        &config("arm3/arm3_identify.toml"),
        &out,
        "rk_live_sim",
        &["--duration", "8"],
    ));
    let ov = Overrides {
        duration: Some(8.0),
        ..Default::default()
    };
    let scn = Scenario::load(&config("arm3/arm3_identify.toml"), &ov).unwrap();
    let (sim, epochs) = evoloop::rkgnn::live::simulate(&scn).unwrap();
    let opt = json(&out.join("optimiser.json"));
    let published = |e: &&serde_json::Value| e["published"].is_u64();
    let n_published = opt["epochs"]
        .as_array()
        .unwrap()
        .iter()
        .filter(published)
        .count();
    assert_eq!(opt["epochs"].as_array().unwrap().len(), epochs.len());
    assert!(n_published > 0, "no model published in 8 s: {opt}");
    assert_eq!(
        n_published,
        epochs.iter().filter(|e| e.published.is_some()).count()
    );
    assert_same_run(&out, &sim);
}

/// The run in `out` (a 3-joint arm's) equals `sim` bit for bit, positions and torques; its
/// run.csv.
fn assert_same_run(out: &Path, sim: &evoloop::sim::SimResult) -> Csv {
    let csv = Csv::read(&out.join("run.csv"));
    assert_eq!(csv.rows.len(), sim.rows.len());
    for j in 0..3 {
        let (y, u) = (csv.col(&format!("y{j}")), csv.col(&format!("u{j}")));
        for (i, row) in sim.rows.iter().enumerate() {
            assert_eq!(y[i].to_bits(), row.state.y[j].to_bits(), "y{j} at {i}");
            assert_eq!(u[i].to_bits(), row.telemetry.u[j].to_bits(), "u{j} at {i}");
        }
    }
    csv
}

#[test]
fn over_ten_seeds_the_evidence_rule_beats_the_best_single_model_but_not_gravity_compensation() {
    // The README's claims on arm3 (`evoloop rkgnn selection --seeds 10`), tested over seeds
    // (each seed's mean over the four tasks; seeds re-identify the models): the models weighted
    // per joint by how well each predicts the loop's torque (uniform prior) track below the
    // best single model in hindsight, median lower and exact Wilcoxon p < 0.05; the paper's max
    // rule does not; and neither is below the matched servo with gravity compensation from the
    // CAD model (pd_gravity). Any of these flipping fails here until the README is corrected.
    // One thread: the study's files are the same at any thread count, and beside the binary's
    // other tests two threads oversubscribed the two cores (the binary took 186 s, 173 s with
    // the seeds one at a time).
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sel");
    let v = selection(&out, &["--seeds", "10", "--threads", "1"]);
    let versus = |rule: &str, baseline: &str| {
        v["comparisons"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["rule"] == rule && c["baseline"] == baseline)
            .unwrap()
            .clone()
    };
    let c = versus("uniform_evidence", "best_single");
    eprintln!("uniform evidence vs best single: {c}");
    assert_eq!(v["claim_held_uniform_evidence"], true, "{c}");
    assert_eq!(
        (c["pairs"].as_u64(), c["wilcoxon"]["method"].as_str()),
        (Some(10), Some("exact"))
    );
    assert_eq!(
        v["claim_held"],
        false,
        "{}",
        versus("fuzzy_max", "best_single")
    );
    let gravity = versus("uniform_evidence", "pd_gravity");
    eprintln!("uniform evidence vs pd_gravity: {gravity}");
    assert!(
        gravity["wilcoxon"]["p_two_sided"].as_f64().unwrap() > 0.05,
        "{gravity}"
    );
    // Below the gain-matched servo without gravity compensation on every seed.
    let servo = versus("uniform_evidence", "pd_matched");
    assert_eq!(servo["fuzzy_lower"], servo["pairs"], "{servo}");
}

#[test]
fn a_study_on_an_earlier_studys_models_tracks_as_it_did_and_refuses_another_recipes() {
    // `--models-from DIR` takes each seed's models from an earlier study instead of
    // identifying them: the same models give the same tracking, bit for bit; models
    // identified by another recipe are refused (counted as not identified, with the reason).
    let tmp = tempfile::tempdir().unwrap();
    let (first, again) = (tmp.path().join("first"), tmp.path().join("again"));
    let a = selection(&first, &["--seeds", "1"]);
    let from = first.to_str().unwrap();
    let b = selection(&again, &["--seeds", "1", "--models-from", from]);
    assert_eq!(a["cells"], b["cells"]);
    assert_eq!(b["models_from"], from);
    assert_eq!(a["identification_seconds"], b["identification_seconds"]);
    let other = tmp.path().join("other");
    let v = selection(
        &other,
        &[
            "--seeds",
            "1",
            "--evaluations",
            "300",
            "--models-from",
            from,
        ],
    );
    let text = v["unidentified"].to_string();
    assert!(text.contains("identified otherwise"), "{text}");
    // Models from training runs on the drive's filter are not taken for a study on the ideal
    // sensor.
    let ideal = tmp.path().join("ideal");
    let v = selection(
        &ideal,
        &[
            "--seeds",
            "1",
            "--joint-velocity",
            "true",
            "--models-from",
            from,
        ],
    );
    let text = v["unidentified"].to_string();
    assert!(
        text.contains("its training servo acted on velocity = \\\"filtered\\\""),
        "{text}"
    );
}

#[test]
fn identification_seeds_vary_the_training_data_and_a_refused_model_is_left_out() {
    // Seed 2 moves the training trajectories (offsets, amplitudes), so its models differ from
    // seed 1's by more than noise; on seed 2 with the ideal sensor (the simulator's velocities:
    // with the drive's filter this model is positive definite there) train3's model is not
    // positive definite along near1 (the controller refuses it): its run is missing (null),
    // the fuzzy rules ran on the other two, and the pairs leave it out.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sel");
    let v = selection(&out, &["--seeds", "2", "--joint-velocity", "true"]);
    assert_eq!(v["joint_velocity"], "true");
    let cells = v["cells"].as_array().unwrap();
    let row = |c: &serde_json::Value, key: &str| -> serde_json::Value {
        c["rms"]
            .as_array()
            .unwrap()
            .iter()
            .find(|r| r[0] == key)
            .unwrap()[1]
            .clone()
    };
    let cell = |seed: u64, trajectory: &str| {
        cells
            .iter()
            .find(|c| c["seed"] == seed && c["trajectory"] == trajectory)
            .unwrap()
    };
    assert_ne!(
        row(cell(1, "near1"), "ct_model_1"),
        row(cell(2, "near1"), "ct_model_1"),
        "seed 2's model 1 tracks as seed 1's: the training data did not change"
    );
    let c = cell(2, "near1");
    assert_eq!(c["refused"], 1, "{c}");
    assert!(c["min_eig_on_reference"][2].as_f64().unwrap() <= 0.0, "{c}");
    assert!(row(c, "ct_model_3")
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x.is_null()));
    assert!(row(c, "fuzzy_max")
        .as_array()
        .unwrap()
        .iter()
        .all(|x| x.is_f64()));
    let pairs = v["comparisons"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["rule"] == "fuzzy_max" && c["baseline"] == "ct_model_3")
        .unwrap()["pairs"]
        .as_u64()
        .unwrap();
    // A seed's mean is over the tasks both ran: a seed is left out only where model 3 was
    // refused on every task.
    let mut seeds_ran: Vec<u64> = (cells.iter())
        .filter(|c| c["min_eig_on_reference"][2].as_f64().unwrap() > 0.0)
        .map(|c| c["seed"].as_u64().unwrap())
        .collect();
    seeds_ran.dedup();
    assert_eq!(
        pairs,
        seeds_ran.len() as u64,
        "seeds leave the refused runs out"
    );
}

#[test]
fn arm7_least_squares_without_a_positive_definite_m_hat_is_refused_with_the_reason() {
    // arm7's training run 1 under its known P-D servo (lockstep, in-process), identified by the
    // known-servo least squares with Christoffel V-hat, each joint's equations in N m and in
    // units of its own torque rms (`--weigh-joints`). From the encoders' positions (velocities
    // estimated, never the simulator's) neither finds an M-hat positive definite over the
    // region; the identification says so and writes nothing. (With the simulator's noise-free
    // velocities the weighted fit did, smallest eigenvalue 0.0048: the book's Known limits.)
    use evoloop::rkgnn::identify::{self, Prior, Settings};
    use evoloop::rkgnn_model::model::ServoPrior;
    let scn = Scenario::load(&config("arm7/arm7_train1.toml"), &Overrides::default()).unwrap();
    let sim = simulate(&scn);
    let data = Trajectory::from_sim(&sim.rows, &scn.reference, scn.timing.period, SMOOTHING);
    let prior = Prior::new(0.003532, 3.827894).unwrap(); // `evoloop rkgnn prior --robot arm7.urdf`
    let settings = |weigh| {
        let mut s = Settings::least_squares(7, 1, 0);
        s.counts.velocity = 0;
        s.servo = ServoPrior::Known {
            kp: vec![540.0, 1530.0, 900.0, 720.0, 23.0, 30.0, 4.5],
            kd: vec![36.0, 102.0, 60.0, 48.0, 1.6, 2.0, 0.3],
            limits: Some(vec![87.0, 87.0, 87.0, 87.0, 12.0, 12.0, 12.0]),
            velocity_cutoff_hz: Some(50.0),
        };
        s.weighing = weigh;
        s
    };
    use evoloop::rkgnn_model::model::Weighing;
    for weigh in [Weighing::Never, Weighing::AsNeeded, Weighing::Always] {
        let e = identify::identify_model(&data, &prior, &settings(weigh), "a".into(), |_, _| {})
            .expect_err("least squares found a positive definite M-hat: update the book");
        assert!(matches!(e, evoloop::rkgnn::RkgnnError::NoStart), "{e:?}");
        assert!(e.to_string().contains("positive definite"), "{e}");
    }
    // Without known torques there is nothing to weigh: refused before any data is read.
    let o = cli(&[
        "identify",
        "rkgnn",
        "--data",
        "/nonexistent",
        "--out",
        "/nonexistent/m.json",
        "--m1",
        "0.0035",
        "--m2",
        "3.8",
        "--servo",
        "linear",
        "--weigh-joints",
    ]);
    assert_refused(&o, "--weigh-joints needs --servo known");
}

/// A known servo is held from the paper's start as from least squares: the EA searches the arm,
/// not the gains the identification was given (`--start random` used to search them too).
#[test]
fn a_known_servo_is_not_searched_from_the_papers_start() {
    let (v, tmp) = study_with(&["--start", "random", "--evaluations", "60", "-q"]);
    let out = tmp.path().join("study");
    assert_eq!(v["identification_inputs"]["start"], "random");
    let kp: Vec<f64> = serde_json::from_value(v["servo_kp"].clone()).unwrap();
    let kd: Vec<f64> = serde_json::from_value(v["servo_kd"].clone()).unwrap();
    for k in 1..=2 {
        let model = RkgnnModel::load(&out.join(format!("model_{k}.json"))).unwrap();
        let p = model.net.params();
        let gains = &p[p.len() - 2 * kp.len()..];
        for j in 0..kp.len() {
            assert_eq!(
                (gains[2 * j], gains[2 * j + 1]),
                (kp[j], kd[j]),
                "model {k}"
            );
        }
        assert!(model.report.evaluations >= 60, "model {k}: the EA ran");
    }
}

#[test]
fn the_selection_study_identifies_by_the_papers_recipe_and_tracks_at_its_own_period() {
    // `--servo unknown --start random --evaluations N` is the paper's identification (the
    // shipped arm7 models' recipe), `--period` the tracking runs' loop rate: each model file
    // must say it came from the EA's random start with the servo unknown and the budget spent,
    // the training runs stay at 1 kHz and every tracking run (with computed torque's per-sample
    // start-up rate) runs at the period asked for.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sel");
    let v = selection(
        &out,
        &[
            "--seeds",
            "1",
            "--servo",
            "unknown",
            "--start",
            "random",
            "--evaluations",
            "300",
            "--period",
            "0.0005",
        ],
    );
    assert_eq!(v["servo_known"], false);
    assert_eq!(v["start"], "random");
    assert_eq!(v["evaluations"], 300);
    assert_eq!(v["period"], 0.0005);
    let identified = 3 - v["unidentified"].as_array().unwrap().len();
    assert_eq!(
        v["identification_seconds"].as_array().unwrap().len(),
        identified
    );
    let seed = out.join("seed1");
    let mut models = 0;
    for t in ["train1", "train2", "train3"] {
        let Ok(text) = std::fs::read_to_string(seed.join(format!("model_{t}.json"))) else {
            continue;
        };
        models += 1;
        let m: serde_json::Value = serde_json::from_str(&text).unwrap();
        let r = &m["report"];
        assert_eq!(r["start"], "random", "{t}");
        assert_eq!(r["servo"]["kind"], "unknown", "{t}");
        assert!(r["evaluations"].as_u64().unwrap() >= 300, "{t}: {r}");
    }
    assert_eq!(models, identified);
    let scenario = |name: &str| -> toml::Table {
        std::fs::read_to_string(seed.join("scenarios").join(format!("{name}.toml")))
            .unwrap_or_else(|e| panic!("{name}: {e}"))
            .parse()
            .unwrap()
    };
    let period = |t: &toml::Table| t["timing"]["period"].as_float().unwrap();
    assert_eq!(period(&scenario("train1")), 0.001);
    for k in ["pd", "pd_matched", "ct_true"] {
        assert_eq!(period(&scenario(&format!("near1_{k}"))), 0.0005, "{k}");
    }
    let ct = scenario("near1_ct_true");
    let rate = ct["controller"]["computed_torque"]["startup_rate"]
        .as_float()
        .unwrap();
    assert!((rate - 0.015).abs() < 1e-12, "startup_rate {rate}");
}

/// Data of an "arm" that is one network (`truth`): torques M q'' + V + G along smooth sines of
/// amplitudes `a` at 1 kHz from `t0` for `seconds`, as positions (the velocities estimated from
/// them, as a run's are) and torques.
fn network_arm_data(
    truth: &evoloop::rkgnn_model::Network,
    a: [f64; 3],
    t0: f64,
    seconds: f64,
) -> (Trajectory, Vec<f64>) {
    let (n, h) = (3, 0.001);
    let (off, w) = ([0.1, 0.6, -1.2], [1.9, 3.1, 2.5]);
    let (mut r, mut q, mut tau) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..(seconds / h).round() as usize {
        let t = t0 + i as f64 * h;
        let pos: Vec<f64> = (0..n)
            .map(|j| off[j] + a[j] * (w[j] * t + j as f64).sin())
            .collect();
        let vel: Vec<f64> = (0..n)
            .map(|j| a[j] * w[j] * (w[j] * t + j as f64).cos())
            .collect();
        let acc: Vec<f64> = (0..n)
            .map(|j| -a[j] * w[j] * w[j] * (w[j] * t + j as f64).sin())
            .collect();
        let mut m = [0.0; evoloop::MAX_JOINTS * evoloop::MAX_JOINTS];
        let (mut v, mut g) = ([0.0; 3], [0.0; 3]);
        truth.inertia_and_velocity(&pos, &vel, &mut m, &mut v);
        truth.gravity(&pos, &mut g);
        for j in 0..n {
            let mq: f64 = (0..n).map(|k| m[j * n + k] * acc[k]).sum();
            tau.push(mq + v[j] + g[j]);
        }
        r.extend(pos.iter().chain(&vel));
        q.extend(pos);
    }
    (Trajectory::from_positions(n, h, r, &q, SMOOTHING), tau)
}

/// The live update (`update_with_torques`, identify mode's fit) moves the model in service
/// towards the arm its window comes from: an arm that is the shipped arm3_train1 model, a model
/// in service whose M-hat is 1.3, V-hat 1.5 and G-hat 0.7 times the arm's, 4 s of data with the
/// loop's torques. The update predicts the 2 s after the window
/// better, keeps every centre, width and gain, and keeps M-hat above the floor it is given.
#[test]
fn the_live_update_moves_the_model_in_service_towards_the_arms_data() {
    use evoloop::rkgnn::identify::update_with_torques;
    use evoloop::rkgnn::live::prediction_rms;
    let truth = RkgnnModel::load(&config("models/arm3_train1.json"))
        .unwrap()
        .net;
    let layout = truth.layout.clone();
    let mut p0 = truth.params().to_vec();
    let mut weights = Vec::new();
    for (part, net) in layout.subnets() {
        let off = match part {
            Part::Inertia(..) => 1.3,
            Part::Velocity(_) => 1.5,
            Part::Gravity => 0.7,
            Part::Proportional(_) | Part::Derivative(_) => continue,
        };
        for k in net.all_weights() {
            p0[k] *= off;
            weights.push(k);
        }
    }
    let moving = [0.8, 0.35, 0.5];
    let (window, tau) = network_arm_data(&truth, moving, 0.0, 4.0);
    let (fresh, fresh_tau) = network_arm_data(&truth, moving, 4.0, 2.0);
    let probes: Vec<Vec<f64>> = (0..window.len())
        .step_by(100)
        .map(|i| window.x_at(i)[..3].to_vec())
        .collect();
    let in_service = evoloop::rkgnn_model::Network::new(layout.clone(), p0.clone());
    let floor = 0.1 * in_service.min_eig(probes.iter().map(Vec::as_slice));
    let p = update_with_torques(&layout, &p0, &window, &tau, 5, &probes, floor)
        .expect("an update above the floor");
    let (fresh_tau, fresh) = (fresh.filter_alike(&fresh_tau), fresh.filtered());
    let before = prediction_rms(&layout, &p0, &fresh, &fresh_tau, 5);
    let after = prediction_rms(&layout, &p, &fresh, &fresh_tau, 5);
    let arm = prediction_rms(&layout, truth.params(), &fresh, &fresh_tau, 5);
    assert!(
        after < 0.5 * before,
        "q'' error on fresh data: updated {after}, in service {before}, the arm's own {arm}"
    );
    for k in (0..p.len()).filter(|k| !weights.contains(k)) {
        assert_eq!(
            p[k], p0[k],
            "parameter {k} is not an output weight and moved"
        );
    }
    let updated = evoloop::rkgnn_model::Network::new(layout.clone(), p);
    assert!(updated.min_eig(probes.iter().map(Vec::as_slice)) >= floor);

    // Centred on the model in service: with the third joint at rest its M_33 never enters the
    // torques, and the update leaves M_33's weights as they were (a fit from zero would zero
    // them: M-hat singular).
    let (still, still_tau) = network_arm_data(&truth, [0.8, 0.35, 0.0], 0.0, 4.0);
    let p = update_with_torques(&layout, &p0, &still, &still_tau, 5, &probes, floor)
        .expect("an update above the floor");
    let m33 = layout
        .subnets()
        .find(|(part, _)| *part == Part::Inertia(2, 2))
        .unwrap()
        .1
        .all_weights()
        .collect::<Vec<_>>();
    let moved = m33
        .iter()
        .map(|&k| (p[k] - p0[k]).abs() / p0[k].abs().max(1e-12));
    assert!(
        moved.clone().all(|r| r < 1e-6),
        "M_33 moved: {:?}",
        moved.collect::<Vec<_>>()
    );
    let other = weights.iter().filter(|k| !m33.contains(k));
    assert!(
        other
            .clone()
            .any(|&k| (p[k] - p0[k]).abs() > 1e-3 * p0[k].abs()),
        "nothing moved"
    );
}

#[test]
fn the_zoo_studies_each_listed_arm_and_counts_arms_not_pairs() {
    // `evoloop rkgnn zoo`: each arm of the zoo file (here a development arm, seed < 1000, and
    // one filtered out by --joints) generated, studied in OUT/NAME and summed up in one table.
    let tmp = tempfile::tempdir().unwrap();
    let zoo = tmp.path().join("zoo.toml");
    std::fs::write(
        &zoo,
        "[[arm]]\njoints = 3\nseed = 11\n\n[[arm]]\njoints = 4\nseed = 7\n",
    )
    .unwrap();
    let out = tmp.path().join("zoo");
    let (z, o) = (zoo.to_str().unwrap(), out.to_str().unwrap());
    let args = [
        "rkgnn", "zoo", "--zoo", z, "--joints", "3", "--seeds", "1", "--out", o,
    ];
    let v = stdout_json(&cli(&[&args[..], &["--json"]].concat()));
    let arms = v["arms"].as_array().unwrap();
    assert_eq!(arms.len(), 1, "--joints 3 keeps the 3-joint arm only");
    assert_eq!(arms[0]["arm"], "gen3_s11");
    assert_eq!(arms[0]["training_runs"], 3);
    // Three rules against the five strongest baselines, per arm and across arms.
    assert_eq!(arms[0]["versus"].as_array().unwrap().len(), 15);
    let tallies = v["tallies"].as_array().unwrap();
    assert_eq!(tallies.len(), 15);
    assert!(
        tallies.iter().all(|t| t["arms"] == 1 && t["sign_p"] == 1.0),
        "{tallies:?}"
    );
    assert!(out.join("zoo.md").is_file() && out.join("gen3_s11/selection.json").is_file());
    let generated = tmp.path().join("g.urdf");
    let g = generated.to_str().unwrap();
    assert_ok(&cli(&[
        "robot", "generate", "--joints", "3", "--seed", "11", "--out", g,
    ]));
    let read = |p: &Path| std::fs::read_to_string(p).unwrap();
    assert_eq!(read(&out.join("arms/gen3_s11.urdf")), read(&generated));
    // The zoo's arms come from the zoo file: it has no --robot (nor does its --help offer one),
    // and a filter that keeps none is refused.
    assert_refused(
        &cli(&["rkgnn", "zoo", "--zoo", z, "--robot", g, "--out", o]),
        "unexpected argument '--robot'",
    );
    let help = cli(&["rkgnn", "zoo", "--help"]);
    assert!(!String::from_utf8_lossy(&help.stdout).contains("--robot"));
    assert_refused(
        &cli(&["rkgnn", "zoo", "--zoo", z, "--joints", "6", "--out", o]),
        "no arm with --joints [6]",
    );
}
