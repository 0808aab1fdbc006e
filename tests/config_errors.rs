//! A malformed scenario fails with a message naming the file, the key and the reason, both from
//! the library and from `evoloop check`.

use crate::common;
use common::*;
use evoloop::config::{Overrides, Scenario};
use std::path::Path;

fn base() -> String {
    scenario("kind = \"step\"\namplitude = 1.0", "duration = 25.0")
}

fn err_of(text: &str) -> String {
    Scenario::parse(text, Path::new("config/bad.toml"), &Overrides::default())
        .expect_err("config must be refused")
        .to_string()
}

#[test]
fn the_base_scenario_is_valid() {
    Scenario::parse(&base(), Path::new("config/ok.toml"), &Overrides::default()).unwrap();
}

#[test]
fn an_unknown_key_is_named_with_its_path() {
    let e = err_of(&base().replace("spring = 1.0", "sprign = 1.0"));
    assert!(e.starts_with("config/bad.toml"), "{e}");
    assert!(e.contains("plant.two_mass"), "{e}");
    assert!(e.contains("unknown field `sprign`"), "{e}");
    assert!(e.contains("spring"), "lists the expected keys: {e}");
}

#[test]
fn a_wrong_type_is_named_with_its_key() {
    let e = err_of(&base().replace("period = 0.001", "period = \"fast\""));
    assert!(e.contains("config/bad.toml"), "{e}");
    assert!(e.contains("`timing.period`"), "{e}");
    assert!(e.contains("invalid type"), "{e}");
}

#[test]
fn an_out_of_range_value_is_named_with_its_key_and_range() {
    let e = err_of(&base().replace("period = 0.001", "period = -0.01"));
    assert!(e.contains("`timing.period`"), "{e}");
    assert!(e.contains("-0.01"), "{e}");
    let e = err_of(&base().replace("spring = 1.0", "spring = 0.0"));
    assert!(e.contains("`plant.two_mass.spring`"), "{e}");
    let e = err_of(&base().replace("step = 0.0005", "step = 0.01"));
    assert!(
        e.contains("`plant.step`") && e.contains("longer than the control period"),
        "{e}"
    );
}

/// The filter's state noise (issue 64): >= 0 and finite, and a key of the filter only.
#[test]
fn a_filters_state_noise_is_refused_below_zero_and_on_the_true_state() {
    let sf = "[controller.state_feedback]\n";
    for bad in ["-0.001", "nan", "inf", "1e200"] {
        let e = err_of(&base().replace(sf, &format!("{sf}state_noise = {bad}\n")));
        assert!(
            e.contains("`controller.state_feedback.state_noise`") && e.contains("[0,"),
            "{e}"
        );
    }
    let e = err_of(&base().replace(sf, &format!("{sf}state = \"true\"\nstate_noise = 0.001\n")));
    assert!(e.contains("state_noise design the Kalman filter"), "{e}");
    let ok = base().replace(sf, &format!("{sf}state_noise = 0.001\n"));
    Scenario::parse(&ok, Path::new("config/ok.toml"), &Overrides::default()).unwrap();
}

#[test]
fn a_missing_key_and_wrong_lengths_are_reported() {
    let e = err_of(&base().replace("kind = \"state_feedback\"", ""));
    assert!(
        e.contains("missing field `kind`") && e.contains("controller"),
        "{e}"
    );
    let e = err_of(&base().replace(
        "gains = [18.49, 19.04, 47.27, 7.30, -10.54]",
        "gains = [1.0, 2.0]",
    ));
    assert!(
        e.contains("`controller.state_feedback.gains`") && e.contains("needs 5"),
        "{e}"
    );
    let e = err_of(&base().replace("gains = [18.49,", "gains = [180.0,"));
    assert!(
        e.contains("gains[0]") && e.contains("outside its bounds"),
        "{e}"
    );
    let e = err_of(&base().replace(
        "kind = \"step\"\namplitude = 1.0",
        "kind = \"square\"\namplitude = 1.0",
    ));
    assert!(
        e.contains("`reference.period`") && e.contains("missing"),
        "{e}"
    );
}

#[test]
fn evoloop_check_prints_the_error_and_exits_non_zero() {
    let tmp = tempfile::tempdir().unwrap();
    let good = write(tmp.path(), "good.toml", &base());
    let o = std::process::Command::new(evoloop())
        .arg("check")
        .arg(&good)
        .output()
        .unwrap();
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("ok"));

    for (bad, needle) in [
        (base().replace("spring = 1.0", "sprign = 1.0"), "sprign"),
        (
            base().replace("duration = 25.0", "duration = \"long\""),
            "timing.duration",
        ),
        (
            base().replace("duration = 25.0", "duration = -3.0"),
            "timing.duration",
        ),
    ] {
        let f = write(tmp.path(), "bad.toml", &bad);
        let o = std::process::Command::new(evoloop())
            .arg("check")
            .arg(&f)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains("bad.toml") && err.contains(needle), "{err}");
    }
    // `run` refuses the same file before starting anything.
    let o = run(
        &tmp.path().join("bad.toml"),
        &tmp.path().join("out"),
        "cfg",
        &[],
    );
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn the_shipped_scenarios_are_valid() {
    let files = shipped_files();
    for p in &files {
        let text = std::fs::read_to_string(p).unwrap();
        if text.lines().any(|l| l.starts_with("experiment =")) {
            // An `evoloop tune` experiment, not a scenario.
            evoloop::tune::validate_file(p).unwrap_or_else(|e| panic!("{e}"));
        } else {
            Scenario::load(p, &Overrides::default()).unwrap_or_else(|e| panic!("{e}"));
        }
    }
    assert!(files.len() >= 40, "{files:?}");
}

#[test]
fn the_wait_strategy_is_read_checked_and_overridable() {
    use evoloop::rt::WaitKind;
    let parse = |text: &str, ov: &Overrides| {
        Scenario::parse(text, Path::new("config/ok.toml"), ov)
            .unwrap()
            .timing
            .wait
    };
    let ov = Overrides::default();
    // Default: sleep, no margin.
    let w = parse(&base(), &ov);
    assert_eq!((w.kind, w.margin_ns), (WaitKind::Sleep, 0));
    // Hybrid at 1 kHz: the default margin is 100 us; a given one is taken.
    let hybrid = base().replace("period = 0.001", "period = 0.001\nwait = \"hybrid\"");
    assert_eq!(parse(&hybrid, &ov).margin_ns, 100_000);
    let with_margin = hybrid.replace(
        "wait = \"hybrid\"",
        "wait = \"hybrid\"\nwait_margin_us = 40",
    );
    assert_eq!(parse(&with_margin, &ov).margin_ns, 40_000);
    // --wait overrides the file.
    let spin = Overrides {
        wait: Some(WaitKind::Spin),
        ..Default::default()
    };
    assert_eq!(parse(&hybrid, &spin).kind, WaitKind::Spin);
    // ... also where the file gives a hybrid margin, which another strategy leaves unused.
    let sleep = Overrides {
        wait: Some(WaitKind::Sleep),
        ..Default::default()
    };
    let w = parse(&with_margin, &sleep);
    assert_eq!((w.kind, w.margin_ns), (WaitKind::Sleep, 0));
    // Refused: an unknown strategy, a margin without hybrid, a margin longer than the period.
    let e = err_of(&base().replace("period = 0.001", "period = 0.001\nwait = \"nap\""));
    assert!(e.contains("timing") && e.contains("nap"), "{e}");
    let e = err_of(&base().replace("period = 0.001", "period = 0.001\nwait_margin_us = 40"));
    assert!(
        e.contains("`timing.wait_margin_us`") && e.contains("hybrid"),
        "{e}"
    );
    let e = err_of(&hybrid.replace(
        "wait = \"hybrid\"",
        "wait = \"hybrid\"\nwait_margin_us = 2000",
    ));
    assert!(
        e.contains("`timing.wait_margin_us`") && e.contains("2000"),
        "{e}"
    );
}

#[test]
fn an_ipc_prefix_too_long_or_with_a_slash_is_refused_before_iceoryx2_sees_it() {
    // 150 characters panicked inside iceoryx2 (a socket path beyond the kernel's 108 bytes);
    // 48 failed to create the run's listeners.
    for bad in [
        "a".repeat(150),
        "a".repeat(48),
        "a/b".to_string(),
        String::new(),
    ] {
        let o = cli(&[
            "run",
            "config/two_mass/two_mass.toml",
            "--duration",
            "0.01",
            "--ipc-prefix",
            &bad,
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(
            e.contains("--ipc-prefix") && !e.contains("panicked"),
            "{bad:?}: {e}"
        );
    }
}

/// Nonsense `check` used to accept (issue 42, item 7), each refused with its key.
#[test]
fn nonsense_values_are_refused_by_check_with_their_key() {
    let step = "step = 0.0005";
    for (text, key) in [
        (base().replace(step, &format!("{step}\nnoise_std = 1e300")), "plant.noise_std"),
        (base().replace(step, &format!("{step}\nsafe_command = 1e300")), "plant.safe_command"),
        (
            scenario("kind = \"square\"\namplitude = 1.0\nperiod = 1e-12", "duration = 5.0"),
            "reference.period",
        ),
        (
            base().replace(
                "[timing]",
                "[optimiser]\nmode = \"schedule\"\n[[optimiser.schedule]]\nat = 12.0\nvalues = [1.0, nan, 1.0, 1.0, -1.0]\n[timing]",
            ),
            "optimiser.schedule[0].values[1]",
        ),
        (
            base().replace(
                "[timing]",
                "[optimiser]\nmode = \"schedule\"\n[[optimiser.schedule]]\nat = 12.0\nvalues = [1.0, 1.0, 1.0, 500.0, -1.0]\n[timing]",
            ),
            "optimiser.schedule[0].values[3]",
        ),
        (
            base().replace(
                "[timing]",
                "[optimiser]\nmode = \"schedule\"\n[[optimiser.schedule]]\nat = 12.0\nvalues = [1.0, 1.0]\n[timing]",
            ),
            "optimiser.schedule[0].values",
        ),
        (
            // Shorter than the identification's low-pass leaves anything to compare on.
            base().replace("[timing]", "[optimiser]\nidentify_fresh = 0.2\n[timing]"),
            "optimiser.identify_fresh",
        ),
    ] {
        let e = err_of(&text);
        assert!(e.contains(&format!("`{key}`")), "{key}: {e}");
    }
    // A set meant to be refused says so, and then passes check.
    let meant = base().replace(
        "[timing]",
        "[optimiser]\nmode = \"schedule\"\n[[optimiser.schedule]]\nat = 12.0\nvalues = [1.0, nan]\nexpect = \"rejected\"\n[timing]",
    );
    Scenario::parse(&meant, Path::new("config/ok.toml"), &Overrides::default()).unwrap();
}

#[test]
fn an_arm_reference_beyond_a_joint_limit_is_refused_with_the_joint_and_time() {
    // Parsed as config/bad.toml: its robot path relative to config/.
    let text = std::fs::read_to_string(config("arm3/arm3_ct.toml"))
        .unwrap()
        .replace("\"../robots/", "\"robots/");
    // Joint 3's limits are +-2.8 rad: an offset of -2.5 with 0.775 rad of amplitude passes them.
    let bad = text.replace("offsets = [0.0, 0.7, -1.3]", "offsets = [0.0, 0.7, -2.5]");
    assert_ne!(bad, text);
    let e = err_of(&bad);
    assert!(e.contains("`reference`") && e.contains("joint 3"), "{e}");
    assert!(e.contains("outside its limits [-2.8, 2.8]"), "{e}");
}

#[test]
fn a_diverging_plant_fails_the_run_instead_of_ending_ok() {
    // Positive state feedback, no input limit: the two-mass state passes 1e9 in a fraction of
    // a second; the run used to go on and end "ok".
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(
        tmp.path(),
        "diverge.toml",
        &base().replace("u_limit = 100.0\n", "").replace(
            "gains = [18.49, 19.04, 47.27, 7.30, -10.54]",
            "gains = [-100.0, -100.0, -100.0, -100.0, -100.0]",
        ),
    );
    let out = tmp.path().join("out");
    let o = run(&cfg, &out, "diverge", &[]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("state diverged"), "{e}");
    assert_eq!(json(&out.join("summary.json"))["outcome"], "failed");
}

#[test]
fn run_ids_are_checked_so_that_two_never_share_a_lock() {
    // `a.b` and `a_b` mapped to one lock file, so the second was refused as "in use".
    for bad in ["a.b", "a/b", "", &"x".repeat(65)] {
        let o = cli(&[
            "run",
            "config/two_mass/two_mass.toml",
            "--run-id",
            bad,
            "--out",
            "/nonexistent",
        ]);
        assert_eq!(o.status.code(), Some(2), "{bad:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("--run-id"), "{bad:?}: {e}");
    }
}

/// A path of the flat layout config/ had until 2026-12-06 is refused with the file's place now,
/// by `run`, `check` and `tune`; a file that never was shipped only says it cannot be read.
#[test]
fn a_scenario_path_from_before_the_plant_folders_names_the_files_place_now() {
    for (args, now) in [
        (
            ["run", "config/maglev_direct.toml"],
            "config/maglev/maglev_direct.toml",
        ),
        (["check", "config/arm7_ct.toml"], "config/arm7/arm7_ct.toml"),
        (
            ["tune", "config/maglev_tune.toml"],
            "config/experiments/maglev_tune.toml",
        ),
    ] {
        let o = cli(&args);
        assert_refused(&o, "cannot read");
        assert_refused(&o, now);
    }
    let o = cli(&["check", "config/never_shipped.toml"]);
    assert_refused(&o, "cannot read");
    assert!(!String::from_utf8_lossy(&o.stderr).contains("per plant"));
}

/// The indirect scheme's model prior: an lti plant's prior is its own configured model (not its
/// changes); an external plant must give one; the table is refused on a plant with a scheme of
/// its own, and state feedback is refused under the general scheme, each naming its key.
#[test]
fn the_prior_comes_from_the_plant_or_the_table_and_misuse_names_its_key() {
    let s = shipped("linear/lti_motor_indirect.toml", |t| t).unwrap();
    let p = s.optimiser.model.unwrap();
    assert_eq!(p.den.len(), 3);
    assert!(
        p.den
            .iter()
            .zip([1.0, 20.0, 0.0])
            .all(|(a, b)| (a - b).abs() < 1e-9),
        "{p:?}"
    );
    assert!((p.num[2] - 40.0).abs() < 1e-9 && p.zeros == 0, "{p:?}");
    assert!((p.filter_pole - 60.0).abs() < 1e-6, "{}", p.filter_pole);
    let s = shipped("external/external_motor_indirect.toml", |t| t).unwrap();
    assert_eq!(s.optimiser.model.unwrap().den, vec![1.0, 20.0, 0.0]);
    // A slow loop (20 Hz): the default filter pole is capped below the sampling rate.
    let slow = shipped("linear/lti_motor_indirect.toml", |t| {
        t.replace("period = 0.001", "period = 0.05")
    })
    .unwrap();
    assert!((slow.optimiser.model.unwrap().filter_pole - 2.0).abs() < 1e-12);
    let e = shipped("external/external_motor_indirect.toml", |t| {
        t.replace("num = [40.0]", "")
            .replace("den = [1.0, 20.0, 0.0]", "")
    })
    .unwrap_err();
    assert_eq!(e.key, "optimiser.model.num");
    // Kept, unused, when the run is frozen.
    let frozen = Overrides {
        optimiser: Some(evoloop::config::OptimiserMode::Off),
        ..Default::default()
    };
    let path = config("external/external_motor_indirect.toml");
    assert!(Scenario::load(&path, &frozen)
        .unwrap()
        .optimiser
        .model
        .is_none());
    let e = shipped("maglev/maglev_indirect.toml", |t| {
        t.replace("[output]", "[optimiser.model]\nmemory = 2.0\n\n[output]")
    })
    .unwrap_err();
    assert_eq!(e.key, "optimiser.model");
    let e = shipped("linear/lti_pendulum.toml", |t| {
        t.replace("mode = \"schedule\"", "mode = \"indirect\"")
    })
    .unwrap_err();
    assert_eq!(e.key, "controller.kind");
}

/// A prior's transfer function is made monic (num and den divided by den's leading
/// coefficient), num is padded to den's order, its default filter pole is three times den's
/// largest root (here 60 rad/s, inside the bounds the sampling rate sets), and orders it cannot
/// take are refused with the key and index.
#[test]
fn the_prior_is_made_monic_and_padded_and_bad_orders_are_refused() {
    let prior = |num: &str, den: &str| {
        shipped("external/external_motor_indirect.toml", |t| {
            t.replace("num = [40.0]", &format!("num = {num}"))
                .replace("den = [1.0, 20.0, 0.0]", &format!("den = {den}"))
        })
    };
    let p = prior("[4.0]", "[2.0, 40.0, 0.0]")
        .unwrap()
        .optimiser
        .model
        .unwrap();
    assert_eq!(
        (p.num, p.den, p.zeros),
        (vec![0.0, 0.0, 2.0], vec![1.0, 20.0, 0.0], 0)
    );
    assert!((p.filter_pole - 60.0).abs() < 1e-6, "{}", p.filter_pole);
    let key = |num: &str, den: &str| prior(num, den).unwrap_err().key;
    assert_eq!(key("[1.0, 0.0]", "[1.0, 1.0]"), "optimiser.model.num");
    assert_eq!(
        key("[1.0]", "[1.0, 1.0, 1.0, 1.0, 1.0, 1.0]"),
        "optimiser.model.den"
    );
    assert_eq!(key("[nan]", "[1.0, 1.0]"), "optimiser.model.num[0]");
}

#[test]
fn modes_display_as_they_serialise() {
    use evoloop::config::{Mode, OptimiserMode::*};
    for m in [Off, Schedule, Indirect, Identify, Direct] {
        assert_eq!(serde_json::to_string(&m).unwrap(), format!("\"{m}\""));
    }
    for m in [Mode::Lockstep, Mode::Realtime] {
        assert_eq!(serde_json::to_string(&m).unwrap(), format!("\"{m}\""));
        assert_eq!(m.to_string().parse::<Mode>().unwrap(), m);
    }
}

/// The tracking cost's two parts and its total, against a sum written out.
#[test]
fn the_tracking_costs_parts_and_total_agree_with_a_direct_sum() {
    let mut c = evoloop::sim::cost::TrackingCost::new(0.5);
    c.add(&[1.0, 2.0], &[0.5, 3.0], &[-4.0]);
    c.add(&[0.0, 0.0], &[1.0, 0.0], &[2.0]);
    assert_eq!(c.error, 0.5 + 1.0 + 1.0);
    assert_eq!(c.control, 2.0 + 1.0);
    assert_eq!(c.total, 5.5);
}

/// A shipped scenario (`config/FILE`), edited by `edit`, parsed as if it were that file.
fn shipped(
    file: &str,
    edit: impl Fn(String) -> String,
) -> Result<Scenario, evoloop::config::ConfigError> {
    let path = config(file);
    let text = edit(std::fs::read_to_string(&path).unwrap());
    Scenario::parse(&text, &path, &Overrides::default())
}
