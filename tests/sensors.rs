//! The laws read sensors, not the simulator's truth. `plant.publish_truth = false` sends NaN in
//! every truth field (`x_true`, `q_true`, `qd_true`), as a real plant that has no truth to send;
//! a law that reads none of it gives the same commands bit for bit, and a scenario whose law
//! does read it (a paper reproduction's full state, an arm law on true velocities) is refused
//! with the key and the reason instead of running on NaN.

mod common;
use common::*;
use evoloop::config::{OptimiserMode, Overrides, Scenario};
use evoloop::sim::simulate;

/// Every shipped scenario evoloop simulates, as `simulate` runs it: 3 s, optimiser off (the
/// laws and their estimators are what is compared; the schemes' sets arrive the same way).
fn shipped() -> Vec<(String, Scenario)> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "toml").then_some(p)
        })
        // Scenarios, not the tuning experiments beside them (`[experiment]`).
        .filter(|p| {
            std::fs::read_to_string(p)
                .unwrap()
                .lines()
                .any(|l| l == "[plant]")
        })
        .collect();
    names.sort();
    let ov = Overrides {
        duration: Some(3.0),
        optimiser: Some(OptimiserMode::Off),
        ..Default::default()
    };
    names
        .into_iter()
        .map(|p| {
            let scn = Scenario::load(&p, &ov).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p.file_name().unwrap().to_string_lossy().into_owned(), scn)
        })
        .filter(|(_, s)| s.require_in_process().is_ok())
        .collect()
}

#[test]
fn withholding_the_truth_changes_no_command_of_a_law_on_sensors() {
    let (mut compared, mut truth_readers) = (Vec::new(), Vec::new());
    for (name, scn) in shipped() {
        if scn.controller.reads_truth() {
            truth_readers.push(name);
            continue;
        }
        let with = simulate(&scn);
        let mut blind = scn.clone();
        blind.plant.publish_truth = false;
        let without = simulate(&blind);
        assert_eq!(with.rows.len(), without.rows.len(), "{name}");
        for (k, (a, b)) in with.rows.iter().zip(&without.rows).enumerate() {
            assert!(
                b.state.x_true[..b.state.n_x as usize]
                    .iter()
                    .all(|v| v.is_nan()),
                "{name}: the truth was sent"
            );
            let n = a.telemetry.n_u as usize;
            let bits = |t: &evoloop::msg::Telemetry| {
                t.u[..n].iter().map(|v| v.to_bits()).collect::<Vec<_>>()
            };
            assert_eq!(
                bits(&a.telemetry),
                bits(&b.telemetry),
                "{name}: the commands of cycle {k} differ without the truth"
            );
        }
        compared.push(name);
    }
    eprintln!("on sensors, commands identical without the truth: {compared:?}");
    eprintln!("still reading the truth (said in their files or their laws' velocity key): {truth_readers:?}");
    // The default scenario, state feedback on an lti plant, the maglev's fuzzy network and the
    // motor's PID run on their sensors.
    for name in [
        "two_mass.toml",
        "lti_pendulum.toml",
        "maglev.toml",
        "lti_motor.toml",
    ] {
        assert!(compared.iter().any(|c| c == name), "{name} not compared");
    }
    // Only the paper's full-state reproductions among the linear plants read x_true.
    for name in &truth_readers {
        let text = std::fs::read_to_string(config(name)).unwrap();
        let labelled = text.contains("state = \"true\"") || !text.contains("state_feedback");
        assert!(labelled, "{name} reads the truth without saying so");
    }
}

#[test]
fn a_law_that_reads_the_truth_is_refused_when_the_plant_withholds_it() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(config("two_mass_robust.toml"))
        .unwrap()
        .replacen("[plant]\n", "[plant]\npublish_truth = false\n", 1);
    let file = write(dir.path(), "blind.toml", &text);
    let o = cli(&["check", file.to_str().unwrap()]);
    assert_refused(&o, "plant.publish_truth");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("state_feedback") && e.contains("true state"),
        "{e}"
    );
    // The same plant with the law on its filter runs blind.
    let text = text.replace("state = \"true\"\n", "");
    let file = write(dir.path(), "filtered.toml", &text);
    let o = cli(&["check", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
