//! Identification (issue 17, parts 3-4): stage base parameters, excitation trajectories and
//! least squares on simulated runs.

use evoloop::config::{Overrides, Scenario};
use evoloop::dynamics::{self, Model};
use evoloop::identify::excitation::{search, ExcitationProblem, Search, Settings, TrajectoryKind};
use evoloop::identify::lls::{estimate, Options, Recording};
use evoloop::identify::{stage_base, states_needed, Columns, Stacker, Stage, StageKind};
use nalgebra::{DMatrix, DVector};
use std::path::Path;

fn industrial6() -> Model {
    dynamics::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/industrial6.toml"))
        .unwrap()
}

const STAGES: [StageKind; 3] = [StageKind::Wrist, StageKind::Arm, StageKind::All];

#[test]
fn stage_base_counts_equal_the_rank_of_the_stage_regressor() {
    let model = industrial6();
    for kind in STAGES {
        for columns in [
            Columns::PLANT,
            Columns {
                friction: false,
                armature: false,
            },
        ] {
            let stage = Stage::new(kind, &model).unwrap();
            let states = states_needed(&model, columns, &stage);
            let b = stage_base(&model, columns, &stage, states, 7);
            // The rank of a fresh stacked regressor of the stage (other states, SVD).
            let mut st = Stacker::new(&model, columns, &stage);
            let per = st.rows_per_state();
            let (q, qd, qdd) = (vec![0.0; 6], vec![0.0; 6], vec![0.0; 6]);
            let mut w = DMatrix::zeros(states * per, columns.count(&model));
            for s in 0..states {
                let mut q = q.clone();
                let (mut qd, mut qdd) = (qd.clone(), qdd.clone());
                for j in 0..6 {
                    let x = ((s * 13 + j * 7) as f64 * 0.61).sin();
                    if stage.moving[j] {
                        (q[j], qd[j], qdd[j]) = (x * 1.5, (x * 3.0).cos(), (x * 5.0).sin());
                    } else {
                        q[j] = stage.hold[j];
                    }
                }
                st.put([&q, &qd, &qdd], &mut w, s * per);
            }
            let sv = w.singular_values();
            let rank = sv.iter().filter(|v| **v > 1e-9 * sv.max()).count();
            assert_eq!(b.base_count(), rank, "{kind:?} stage, {columns:?}");
            // Every column is in exactly one list.
            let total = b.base_count() + b.combined.len() + b.unidentifiable.len();
            assert_eq!(total, columns.count(&model));
        }
    }
    // The wrist stage cannot see the arm's parameters at all.
    let wrist = Stage::new(StageKind::Wrist, &model).unwrap();
    let b = stage_base(&model, Columns::PLANT, &wrist, 100, 1);
    for p in ["m1", "Izz1", "mx2", "fv1", "Ia3"] {
        assert!(b.unidentifiable.contains(&p.to_string()), "{p}");
    }
}

#[test]
fn noise_free_least_squares_recovers_the_stage_base_parameters_to_1e_8() {
    // Torques from the model's own inverse dynamics (RNEA with friction and armature), not from
    // the regressor: an independent reference for the columns, the stages and the regrouping.
    let model = industrial6();
    let mut d = model.data();
    for kind in STAGES {
        let stage = Stage::new(kind, &model).unwrap();
        let p = ExcitationProblem::new(model.clone(), stage.clone(), Settings::default()).unwrap();
        let (lo, hi) = p.bounds();
        let x: Vec<f64> = (0..lo.len())
            .map(|i| lo[i] + (hi[i] - lo[i]) * (0.5 + 0.4 * (i as f64 * 1.7).sin()))
            .collect();
        let s = p.decode(&x).unwrap();
        let k = 60;
        let rows = stage.rows();
        let mut tau = DVector::zeros(k * rows.len());
        let (mut q, mut qd, mut qdd, mut t) = (vec![0.0; 6], vec![0.0; 6], vec![0.0; 6], [0.0; 6]);
        for i in 0..k {
            s.sample(s.period * i as f64 / k as f64, &mut q, &mut qd, &mut qdd);
            model.inverse_dynamics(&mut d, &q, &qd, &qdd, &mut t);
            for (r, &j) in rows.iter().enumerate() {
                tau[i * rows.len() + r] = t[j];
            }
        }
        // base_regressor divides by sqrt(samples) with samples = 100; rebuild it at k instants.
        let p = ExcitationProblem::new(
            model.clone(),
            stage.clone(),
            Settings {
                samples: k,
                ..Settings::default()
            },
        )
        .unwrap();
        let wb = p.base_regressor(&s) * (k as f64).sqrt();
        let beta = wb.svd(true, true).solve(&tau, 1e-14).unwrap();
        for (b, est) in p.base.base.iter().zip(beta.iter()) {
            let scale = b.value.abs().max(1.0);
            assert!(
                (est - b.value).abs() < 1e-8 * scale,
                "{kind:?}: {} = {} estimated {est}",
                b.relation(),
                b.value
            );
        }
    }
}

#[test]
fn optimised_excitation_beats_the_random_initial_ones_inside_every_limit() {
    let model = industrial6();
    for (kind, trajectory) in [
        (StageKind::Wrist, TrajectoryKind::Fourier),
        (StageKind::All, TrajectoryKind::Fourier),
        (StageKind::Arm, TrajectoryKind::Mfs),
    ] {
        let stage = Stage::new(kind, &model).unwrap();
        let settings = Settings {
            trajectory,
            harmonics: if trajectory == TrajectoryKind::Mfs {
                3
            } else {
                5
            },
            ..Settings::default()
        };
        let p = ExcitationProblem::new(model.clone(), stage, settings).unwrap();
        let s = Search {
            iterations: 20,
            threads: 2,
            ..Search::default()
        };
        let o = search(&p, &s, &mut |_, _, _| {}).unwrap();
        assert_eq!(o.feasible_elites, 5, "{kind:?}: the elite phase finds 5");
        let initial = o
            .initial
            .iter()
            .map(|c| c.cond)
            .fold(f64::INFINITY, f64::min);
        assert!(
            o.criteria.cond < initial,
            "{kind:?}: optimised cond {} vs best initial {initial}",
            o.criteria.cond
        );
        assert_eq!(o.criteria.excess, 0.0);
        // Inside every limit on a grid 25x finer than the search's (which checks 4 x samples
        // points: between them the top harmonic's peak can rise by < 0.1 %, hence 1 % here for
        // velocity and acceleration; positions keep the 0.05 rad margin and are checked hard
        // against the robot file's own limits).
        let grid = 10_000;
        for j in p.stage.rows() {
            let lim = &model.bodies[j].limits;
            for i in 0..grid {
                let (q, qd, qdd) = o.series.joint(j, o.series.period * i as f64 / grid as f64);
                assert!(q > lim.q_min && q < lim.q_max, "{kind:?} joint {j}: q {q}");
                assert!(qd.abs() <= 1.01 * p.limits.qd_max[j], "joint {j}: qd {qd}");
                assert!(
                    qdd.abs() <= 1.01 * p.limits.qdd_max[j],
                    "joint {j}: qdd {qdd}"
                );
            }
            // At rest at the start: exactly for the joint series; for the Cartesian path the
            // path is at rest and the joint series is a 48-harmonic fit of its inverse
            // kinematics (fit error ~3e-6 rad, whose derivatives scale with the harmonic's
            // frequency: measured 2e-6 rad/s and 5e-5 rad/s^2), so 1e-3 there.
            let tol = if trajectory == TrajectoryKind::Mfs {
                1e-3
            } else {
                1e-12
            };
            let (_, qd0, qdd0) = o.series.joint(j, 0.0);
            assert!(
                qd0.abs() < tol && qdd0.abs() < tol,
                "starts at rest: {qd0} {qdd0}"
            );
        }
    }
}

#[test]
fn identification_errors_shrink_as_the_trajectory_grows() {
    // The shipped one-stage experiment simulated in this process for 9 periods with encoder
    // noise (plant.noise_std) and 2 N m torque noise; the first 3, 5 and 9 periods estimated
    // alone (one dropped, one held out: 1, 3 and 7 averaged).
    let cfg =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/industrial6/industrial6_identify.toml");
    let ov = Overrides {
        duration: Some(90.0),
        ..Overrides::default()
    };
    let scn = Scenario::load(&cfg, &ov).unwrap();
    let sim = evoloop::sim::simulate(&scn);
    let mut rec = Recording::from_sim(&scn, &sim).unwrap();
    rec.add_torque_noise(2.0, 1);
    let model = industrial6();
    let errors: Vec<f64> = [3, 5, 9]
        .iter()
        .map(|&p| {
            let e = estimate(&model, &rec.truncated(p).unwrap(), &Options::default()).unwrap();
            assert_eq!(e.periods, p - 2);
            e.relative_error_norm
        })
        .collect();
    assert!(
        errors[0] > errors[1] && errors[1] > errors[2],
        "errors over 1, 3, 7 averaged periods: {errors:?}"
    );
    assert!(errors[2] < 0.02, "seven periods: {errors:?}");
}

#[test]
fn set_parameters_inverts_parameters_and_keeps_the_torques() {
    let model = industrial6();
    let pi = Columns::PLANT.values(&model);
    let mut other = dynamics::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/industrial6_nominal.toml"),
    )
    .unwrap();
    assert_ne!(Columns::PLANT.values(&other), pi);
    other.set_parameters(&pi, true, true);
    assert_eq!(Columns::PLANT.values(&other), pi);
    let (mut d1, mut d2) = (model.data(), other.data());
    let (q, qd, qdd) = (
        [0.3, -0.5, 0.8, 0.1, 0.2, 0.3],
        [0.5, 1.0, -1.0, 1.0, 1.0, 1.0],
        [1.0, -0.5, 0.3, 2.0, -1.0, 0.5],
    );
    let (mut t1, mut t2) = ([0.0; 6], [0.0; 6]);
    model.inverse_dynamics(&mut d1, &q, &qd, &qdd, &mut t1);
    other.inverse_dynamics(&mut d2, &q, &qd, &qdd, &mut t2);
    for j in 0..6 {
        assert!(
            (t1[j] - t2[j]).abs() < 1e-12 * t1[j].abs().max(1.0),
            "joint {j}"
        );
    }
}

/// Tracking error RMS over all joints of the rows with t in [from, to).
fn rms(sim: &evoloop::sim::SimResult, scn: &Scenario, from: f64, to: f64) -> f64 {
    let mut sp = evoloop::reference::Setpoint::default();
    let (mut s, mut c) = (0.0, 0);
    for r in &sim.rows {
        let t = r.state.t;
        if t >= from && t < to {
            scn.reference.sample(t, &mut sp);
            for j in 0..6 {
                s += (sp.q[j] - r.state.q_true[j]).powi(2);
                c += 1;
            }
        }
    }
    (s / c as f64).sqrt()
}

fn scenario_text(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config")
            .join(name),
    )
    .unwrap()
}

fn parse(text: &str) -> Scenario {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/industrial6/inline.toml");
    Scenario::parse(text, &path, &Overrides::default()).unwrap()
}

#[test]
fn the_identified_model_set_brings_tracking_from_the_nominal_models_to_the_noise_floor() {
    use evoloop::msg::ParamCode;
    // The shipped scenario: the nominal model for the first pass, the identified one (a model
    // set from config/identified/industrial6/lls.json) from 8.25 s on.
    let text = scenario_text("industrial6/industrial6_identified.toml");
    let scn = parse(&text);
    let sim = evoloop::sim::simulate(&scn);
    assert_eq!(sim.events.len(), 1);
    assert_eq!(
        sim.events[0].code,
        ParamCode::Accepted,
        "{:?}",
        sim.events[0]
    );
    // The same moves on the true model and on the nominal model throughout.
    let truth = parse(
        &text
            .replace("model = \"../robots/industrial6_nominal.toml\"\n", "")
            .replace("mode = \"schedule\"", "mode = \"off\""),
    );
    let nominal = parse(&text.replace("mode = \"schedule\"", "mode = \"off\""));
    let sim_true = evoloop::sim::simulate(&truth);
    let sim_nominal = evoloop::sim::simulate(&nominal);
    let second = |s: &evoloop::sim::SimResult| rms(s, &scn, 9.0, 16.5);
    let (identified, true_model, nominal_model) =
        (second(&sim), second(&sim_true), second(&sim_nominal));
    // Measured (seed 1, the law on its observer): nominal 2.3e-2, identified 1.3e-4, true
    // 7.4e-5 rad (on the simulator's velocity 1.9e-2, 1.2e-4, 2.6e-5). The identified
    // model's residual error sits on the wrist joints, whose tiny inertial parameters are the
    // worst identified (the paper's own finding); it is at the encoder noise (1e-4 rad), not at
    // the true model's level, so that is what is asserted.
    let msg = format!(
        "second pass rms: identified {identified:.3e}, true {true_model:.3e}, nominal {nominal_model:.3e}"
    );
    eprintln!("{msg}");
    assert!(identified < 2.0 * scn.plant.noise_std, "{msg}");
    assert!(nominal_model > 20.0 * identified, "{msg}");
    assert!(true_model <= identified, "{msg}");
}

#[test]
fn a_model_set_that_is_not_positive_definite_or_of_the_wrong_length_is_refused() {
    use evoloop::msg::ParamCode;
    let model = industrial6();
    let bad: Vec<String> = Columns::PLANT
        .values(&model)
        .iter()
        .map(|v| format!("{}", -v))
        .collect();
    let text = scenario_text("industrial6/industrial6_identified.toml").replace(
        "{ at = 8.25, kind = \"model\", file = \"../identified/industrial6/lls.json\" },",
        &format!(
            "{{ at = 2.0, kind = \"model\", values = [{}] }}, {{ at = 3.0, kind = \"model\", values = [1.0, 2.0] }},",
            bad.join(", ")
        ),
    );
    let scn = parse(&text.replace("duration = 16.5", "duration = 4.0"));
    let sim = evoloop::sim::simulate(&scn);
    let codes: Vec<ParamCode> = sim.events.iter().map(|e| e.code).collect();
    assert_eq!(
        codes,
        [
            ParamCode::RejectedNotPositiveDefinite,
            ParamCode::RejectedWrongLength
        ]
    );
    // The loop ran on: the arm still tracks on the model it had.
    assert!(rms(&sim, &scn, 3.5, 4.0) < 0.05);
    // A model set for a law that takes none is refused when the file is checked.
    let pd = scenario_text("arm3/arm3_pd.toml").replace(
        "mode = \"off\"",
        "mode = \"schedule\"\nschedule = [{ at = 1.0, kind = \"model\", values = [1.0] }]",
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/industrial6/inline.toml");
    let e = Scenario::parse(&pd, &path, &Overrides::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("optimiser.schedule[0].kind") && e.contains("no model sets"),
        "{e}"
    );
}

#[test]
fn the_papers_cartesian_path_keeps_the_wrist_centre_on_it_and_identifies_the_arm() {
    // The modified Fourier series (eqs. 16-18) for the arm stage: optimised, then run as a
    // scenario's reference in this process and identified.
    let model = industrial6();
    let stage = Stage::new(StageKind::Arm, &model).unwrap();
    let settings = Settings {
        trajectory: TrajectoryKind::Mfs,
        harmonics: 3,
        ..Settings::default()
    };
    let p = ExcitationProblem::new(model.clone(), stage, settings).unwrap();
    let o = search(
        &p,
        &Search {
            iterations: 10,
            threads: 2,
            ..Search::default()
        },
        &mut |_, _, _| {},
    )
    .unwrap();
    let m = p.mfs.as_ref().unwrap();
    let (_, fit) = m.decode(&model, &o.x).unwrap();
    assert!(fit < 1e-5, "joint series fit error {fit} rad");
    let path = m.path(&o.x);
    let mut d = model.data();
    let (mut q, mut qd, mut qdd) = (vec![0.0; 6], vec![0.0; 6], vec![0.0; 6]);
    for k in 0..50 {
        let t = 10.0 * k as f64 / 50.0;
        o.series.sample(t, &mut q, &mut qd, &mut qdd);
        let w = model.body_origins(&mut d, &q)[m.wrist.body];
        let want = glam::DVec3::from_array(path.point(t));
        assert!(
            (w - want).length() < 1e-4,
            "t {t}: wrist centre {w} vs path {want}"
        );
    }
    // Run it (as the `excitation` reference would) and identify the arm stage.
    let dir = tempfile::tempdir().unwrap();
    let traj = dir.path().join("mfs.json");
    std::fs::write(&traj, serde_json::json!({ "series": o.series }).to_string()).unwrap();
    let text = scenario_text("industrial6/industrial6_identify_arm.toml")
        .replace("../excitation/industrial6_arm.json", traj.to_str().unwrap())
        .replace("duration = 60.0", "duration = 40.0");
    let scn = parse(&text);
    let sim = evoloop::sim::simulate(&scn);
    let rec = Recording::from_sim(&scn, &sim).unwrap();
    let e = estimate(&model, &rec, &Options::default()).unwrap();
    assert_eq!(e.stage, "arm");
    assert!(
        e.relative_error_norm < 0.02,
        "arm stage error {}",
        e.relative_error_norm
    );
}
