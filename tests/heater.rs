//! The heated block (the README's example of adding a plant kind) under the PID of
//! config/heater/heater.toml: the heater only heats, so the integrator winds up on the 20 -> 60 °C step
//! unless the anti-windup scheme stops it; the config's comment quotes these figures.

use evoloop::config::{ControllerModel, Overrides, Scenario};
use evoloop::law::AntiWindup;
use evoloop::sim::simulate;

/// Overshoot of the first step (20 -> 60 °C at 10 s, next change at 400 s), % of the step, and
/// the time the output is back within 2 % of the step for good before 400 s.
fn first_step(aw: AntiWindup) -> (f64, Option<f64>) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/heater/heater.toml");
    let mut scn = Scenario::load(&path, &Overrides::default()).unwrap();
    let ControllerModel::Pid(pid) = &mut scn.controller.model else {
        unreachable!("the heater runs a PID")
    };
    pid.anti_windup = aw;
    let rows = simulate(&scn).rows;
    let step: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r.state.t >= 10.0 && r.state.t < 400.0)
        .map(|r| (r.state.t, r.state.y[0]))
        .collect();
    let peak = step.iter().map(|s| s.1).fold(f64::MIN, f64::max);
    let outside = step.iter().rposition(|s| (s.1 - 60.0).abs() > 0.02 * 40.0);
    let settled = match outside {
        Some(i) if i + 1 < step.len() => Some(step[i + 1].0),
        Some(_) => None,
        None => Some(10.0),
    };
    (100.0 * (peak - 60.0) / 40.0, settled)
}

#[test]
fn conditional_integration_stops_the_windup_that_the_plain_pid_suffers() {
    let (os_clamp, settle_clamp) = first_step(AntiWindup::Clamping);
    let (os_none, settle_none) = first_step(AntiWindup::None);
    assert!(os_clamp < 1.0, "clamping overshoot {os_clamp} %");
    assert!(os_none > 15.0, "plain PID overshoot {os_none} %");
    let settle_clamp = settle_clamp.expect("clamping settles");
    assert!(settle_clamp < 150.0, "clamping settles at {settle_clamp} s");
    assert!(
        settle_none.is_none_or(|t| t > 2.0 * settle_clamp),
        "the wound-up loop takes far longer: {settle_none:?}"
    );
}
