use evoloop_control::plant::lti::LtiSpec;
use evoloop_control::plant::PlantSim;
use evoloop_control::reference::Reference;
use evoloop_msg::PlantState;
use evoloop_scenario::config::{Overrides, Scenario};
use evoloop_schemes::indirect::linear::*;
use evoloop_schemes::indirect::Estimator;

/// The shipped motor scenario (inertia tripled at 20 s) under its frozen PID with encoder
/// noise `noise`, the estimator fed every sample; returns it and the estimates every 0.1 s
/// as (t, estimate, std, true input gain).
fn estimate_run(noise: f64, seconds: f64) -> (LinearEstimator, Vec<(f64, f64, f64, f64)>) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/linear/lti_motor_indirect.toml");
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let prior = scn
        .optimiser
        .model
        .clone()
        .expect("the general scheme's prior");
    let (mut est, _) = scheme(&scn, &prior).unwrap();
    let evoloop_control::plant::PlantModel::Lti(truth) = &scn.plant.model else {
        unreachable!("an lti scenario")
    };
    let mut sim = PlantSim::new(scn.build_plant(), scn.plant.step, noise, 7);
    let mut ctrl = scn.build_controller();
    let (mut u, mut sp) = ([0.0; 1], evoloop_control::reference::Setpoint::default());
    let (mut s, mut out) = (PlantState::default(), Vec::new());
    for k in 0..(seconds / scn.timing.period).round() as u64 {
        sim.sample(k, 0, &u, &mut s);
        est.push(k > 0, &s);
        if k % 100 == 0 {
            let e = est.estimate(s.t);
            out.push((s.t, e.value, e.std, truth.input_gain_at(s.t).unwrap()));
        }
        scn.reference.sample(s.t, &mut sp);
        ctrl.step(&s, &sp, &mut u);
        sim.advance(&u, scn.timing.period);
    }
    (est, out)
}

/// With an ideal sensor the fit is the motor's transfer function, s^2 + 20 s + 0 over 40,
/// to 1e-4 before the change and 6.667 s, 13.33 after it; no drift alarm before the change,
/// one within 0.5 s after it.
#[test]
fn an_ideal_sensor_gives_the_transfer_function_before_and_after_the_change() {
    let (est, run) = estimate_run(0.0, 19.9);
    let th = &Estimator::monitor(&est).unwrap().theta;
    assert!(
        th[0].abs() < 1e-3 && (th[1] - 20.0).abs() < 2e-3 && (th[2] - 40.0).abs() < 4e-3,
        "{th:?}"
    );
    assert!(
        est.monitor.drift_alarms.is_empty(),
        "{:?}",
        est.monitor.drift_alarms
    );
    assert!(run
        .iter()
        .filter(|r| r.0 > 3.0)
        .all(|r| ((r.1 - r.3) / r.3).abs() < 1e-4));
    let (est, _) = estimate_run(0.0, 40.0);
    let th = &Estimator::monitor(&est).unwrap().theta;
    assert!(
        (th[1] - 6.6667).abs() < 2e-3 && (th[2] - 13.3333).abs() < 2e-3,
        "{th:?}"
    );
    let alarms = &est.monitor.drift_alarms;
    assert!(
        !alarms.is_empty() && alarms[0] >= 20.0 && alarms[0] < 20.5,
        "{alarms:?}"
    );
}

/// With the shipped encoder noise the estimate stays within three of its own standard
/// deviations of the truth, or within the equation error's bias (the noise enters the
/// regressors too; 1e-4 of the gain here), away from the change; raises no false drift
/// alarm in 20 s before the change, and catches up within 2 s after.
#[test]
fn with_encoder_noise_the_error_is_within_the_reported_deviation() {
    let (est, run) = estimate_run(5e-4, 40.0);
    for r in run
        .iter()
        .filter(|r| (3.0..20.0).contains(&r.0) || r.0 >= 22.0)
    {
        assert!(
            (r.1 - r.3).abs() <= (3.0 * r.2).max(2e-4 * r.3) && r.2 < 0.01 * r.3,
            "t = {}: {} vs {} (std {})",
            r.0,
            r.1,
            r.3,
            r.2
        );
    }
    let alarms = &est.monitor.drift_alarms;
    assert!(alarms.iter().all(|t| *t >= 20.0), "false alarm: {alarms:?}");
    assert!(alarms.first().is_some_and(|t| *t < 20.5), "{alarms:?}");
}

/// A loop at rest (no command, the shaft still) does not determine the model: every fit is
/// held and the nominal model stays; `ready` stays false.
#[test]
fn a_plant_at_rest_teaches_nothing_and_the_model_is_held() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/linear/lti_motor_indirect.toml");
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let prior = scn.optimiser.model.clone().unwrap();
    let (mut est, _) = scheme(&scn, &prior).unwrap();
    let mut sim = PlantSim::new(scn.build_plant(), scn.plant.step, 5e-4, 3);
    let mut s = PlantState::default();
    for k in 0..5000u64 {
        sim.sample(k, 0, &[0.0], &mut s);
        est.push(k > 0, &s);
        sim.advance(&[0.0], scn.timing.period);
    }
    assert!(!Estimator::ready(&est));
    assert_eq!(est.monitor.fits_adopted, 0);
    assert!(est.monitor.fits_held >= 49, "{:?}", est.monitor);
    assert_eq!(Estimator::coefficients(&est), vec![0.0, 20.0, 40.0]);
}

/// The tuner's stability check refuses a set that destabilises the estimated loop (too much
/// proportional gain for the sampled motor with no derivative), and such a set costs
/// infinity; the configured set is stable and finite.
#[test]
fn an_unstable_set_costs_infinity_on_the_model() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/linear/lti_motor_indirect.toml");
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let prior = scn.optimiser.model.clone().unwrap();
    let (_, tuner) = scheme(&scn, &prior).unwrap();
    let theta = [0.0, 20.0, 40.0];
    assert!(tuner.model.stable(&theta, &[20.0, 0.02, 0.02]));
    assert!(tuner.model.cost(&theta, &[20.0, 0.02, 0.02]).is_finite());
    // The continuous loop's characteristic polynomial s^3 + 20 s^2 + 40 Kp s + 40 Ki / T
    // is stable for Kp > Ki / (20 T) (Routh): 50 V/rad for Ki = 1 per sample.
    assert!(!tuner.model.stable(&theta, &[10.0, 0.0, 1.0]));
    assert!(tuner.model.stable(&theta, &[60.0, 0.0, 1.0]));
    assert_eq!(tuner.model.cost(&theta, &[10.0, 0.0, 1.0]), f64::INFINITY);
}

/// The controller's own check under the general scheme: a PID set stable on the nominal
/// motor but not on the loaded one (Routh on s^3 + a_1 s^2 + b K_p s + b K_i / T: stable
/// for a_1 K_p > K_i / T, 200 > 100 nominal, 66.7 < 100 loaded) goes into service until
/// the loaded motor's estimate is adopted, and is refused after it with its own reason;
/// a set unstable on the nominal model is refused from the start.
#[test]
fn the_controller_refuses_a_pid_set_unstable_on_the_adopted_estimate() {
    use evoloop_msg::{ParamCode, ParamSet, Telemetry};
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../config/linear/lti_motor_indirect.toml");
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let offer = |cycle: &mut evoloop_control::law::cycle::ControlCycle, v: u64, values: &[f64]| {
        let seq = cycle.next_cycle();
        cycle.offer(&ParamSet::new(v, seq, scn.controller.param_kind(), values));
        let s = PlantState {
            seq,
            t: seq as f64 * 1e-3,
            n_x: 3,
            n_q: 1,
            n_y: 1,
            ..Default::default()
        };
        cycle
            .step(&s, &mut Telemetry::default())
            .expect("an event")
            .code
    };
    let set = [10.0, 0.0, 0.1];
    let mut cycle = evoloop_scenario::sim::control_cycle(&scn);
    assert_eq!(
        offer(&mut cycle, 1, &[1.0, 0.0, 1.0]),
        ParamCode::RejectedUnstable
    );
    assert_eq!(offer(&mut cycle, 1, &set), ParamCode::Accepted);
    let loaded = evoloop_control::law::LinearModel::sampled_transfer_function(
        &[0.0, 0.0, 13.3333],
        &[1.0, 6.6667, 0.0],
        1e-3,
    )
    .unwrap();
    cycle.check_on(loaded);
    assert_eq!(
        offer(&mut cycle, 2, &set),
        ParamCode::RejectedUnstableOnEstimate
    );
    assert_eq!(
        offer(&mut cycle, 2, &[20.0, 0.02, 0.02]),
        ParamCode::Accepted
    );
}

/// `LinearModel::stabilised_by_pid`, derivative and integral columns included, against the
/// loop itself: `law::Pid` on the sampled motor 40 / (s^2 + 20 s) without actuator
/// limits, a unit step, 4 s. Where the simulation is clear (the error's peak over the last
/// half second below 1e-3 of the first half second's, or above it), the check agrees.
#[test]
fn the_pid_check_agrees_with_simulating_the_loop() {
    use evoloop_control::law::{AntiWindup, Controller, Pid};
    let (num, den, t) = ([0.0, 0.0, 40.0], [1.0, 20.0, 0.0], 1e-3);
    let model =
        evoloop_control::law::LinearModel::sampled_transfer_function(&num, &den, t).unwrap();
    let (mut stable, mut unstable) = (0, 0);
    for kp in [1.0, 5.0, 20.0, 60.0, 150.0] {
        for tv in [0.0, 0.005, 0.02, 0.1] {
            for ki in [0.0, 0.01, 0.1, 1.0] {
                let params = [kp, tv, ki];
                let plant = LtiSpec::from_transfer_function(&num, &den, t, (-1e12, 1e12)).unwrap();
                let pid = Pid::new(AntiWindup::None, &params, t, (-1e12, 1e12), 0.0);
                let verdict = pid.stabilises(&model, &params);
                let reference = Reference::Step {
                    amplitude: 1.0,
                    start: 0.0,
                };
                let run = evoloop_scenario::sim::Run {
                    reference: &reference,
                    period: t,
                    step: t,
                    duration: 4.0,
                    diverged: 1e30,
                    noise_std: 0.0,
                    seed: 0,
                    sensor_delay: 0,
                    u0: 0.0,
                }
                .response(Box::new(plant), Box::new(pid));
                let peak = |from: usize, to: usize| {
                    (from..to.min(run.y.len()))
                        .map(|k| (run.r[k] - run.y[k]).abs())
                        .fold(0.0f64, f64::max)
                };
                let n = run.y.len();
                let (early, late) = (peak(0, 500), peak(n.saturating_sub(500), n));
                if n < 4000 || late > early {
                    unstable += 1;
                    assert!(
                        !verdict,
                        "{params:?}: the loop diverges, the check passes it"
                    );
                } else if late < 1e-3 * early {
                    stable += 1;
                    assert!(
                        verdict,
                        "{params:?}: the loop settles, the check refuses it"
                    );
                }
            }
        }
    }
    assert!(
        stable >= 20 && unstable >= 10,
        "{stable} stable, {unstable} unstable"
    );
}
