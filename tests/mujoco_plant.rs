//! MuJoCo as the plant (PyPI `mujoco`, through the evoloop_plant package): two independent
//! simulators of arm3 agree given the same torques, and evoloop's computed torque runs against
//! the MuJoCo arm through the real processes, reproducibly, with and without a wall evoloop's
//! own plant could not simulate. Ignored where Python lacks mujoco or the package's deps
//! (`pip install ./python mujoco`); CI installs them and runs these with `--ignored`.

mod common;

use std::path::Path;
use std::process::Command as Process;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The worst joint-angle difference over `seconds` of MuJoCo replaying `run`'s torques.
fn crosscheck(run: &Path, seconds: f64, coulomb: bool) -> serde_json::Value {
    let mut cmd = Process::new("python3");
    cmd.arg(root().join("scripts/mujoco_crosscheck.py"))
        .args(["--run", run.to_str().unwrap()])
        .args([
            "--urdf",
            root().join("config/robots/arm3.urdf").to_str().unwrap(),
        ])
        .args(["--step", "0.0005", "--seconds", &seconds.to_string()]);
    if !coulomb {
        cmd.arg("--no-coulomb");
    }
    let o = cmd.output().expect("python3");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// arm3_ct in lockstep without encoder noise, and without Coulomb friction where asked (the
/// one term the two simulators model differently), written into `dir`.
fn evoloop_arm(dir: &Path, coulomb: bool) -> std::path::PathBuf {
    let robot = std::fs::read_to_string(root().join("config/robots/arm3.toml")).unwrap();
    let robot = if coulomb {
        robot
    } else {
        robot.replace("coulomb = 0.1", "coulomb = 0.0")
    };
    common::write(dir, "arm3.toml", &robot);
    let scenario = std::fs::read_to_string(common::config("arm3/arm3_ct.toml"))
        .unwrap()
        .replace("noise_std = 0.0001", "noise_std = 0.0")
        .replace("../robots/arm3.toml", "arm3.toml");
    let config = common::write(dir, "arm3_ct.toml", &scenario);
    let out = dir.join(if coulomb { "with" } else { "without" });
    common::assert_ok(&common::run(&config, &out, "mjarm", &[]));
    out
}

/// Shipped scenario `name`'s text, its robot and plant paths absolute, computed torque on the
/// drive's filtered velocity whatever the file chose (arm3_ct's own arm runs its observer), so
/// that the MuJoCo arm and evoloop's are compared on the same sensor.
fn on_filtered_velocity(name: &str) -> String {
    let abs = |p: &str| root().join("config").join(p).display().to_string();
    let text = std::fs::read_to_string(common::config(name))
        .unwrap()
        .replace("\"../robots/", &format!("\"{}/", abs("robots")))
        .replace("\"../plants/", &format!("\"{}/", abs("plants")));
    common::without_lines(&text, "velocity = ").replace(
        "[controller.computed_torque]\n",
        "[controller.computed_torque]\nvelocity = \"filtered\"\n",
    )
}

/// Same torques, same step: without Coulomb friction the two simulators differ only by
/// rounding, which the open-loop arm (unstable under gravity without its controller) amplifies:
/// 6e-13 rad at 2 s measured; the bound, 1e-9, is far below any modelling difference (a wrong
/// inertia or damping shows at 1e-6 within 10 ms) and far above the rounding. With Coulomb
/// friction (evoloop smooths it, MuJoCo enforces it as a constraint) they differ by 1e-6 rad from
/// the first step and diverge: reported, not bounded.
#[test]
#[ignore = "needs Python 3 with mujoco and the evoloop_plant package's deps: pip install ./python mujoco"]
fn mujoco_and_evoloop_agree_on_the_same_torques() {
    let dir = tempfile::tempdir().unwrap();
    let without = crosscheck(&evoloop_arm(dir.path(), false), 2.0, false);
    let worst = without["max_abs_q_error_rad"].as_f64().unwrap();
    assert!(worst < 1e-9, "without Coulomb friction: {without}");
    let with = crosscheck(&evoloop_arm(dir.path(), true), 2.0, true);
    println!("without Coulomb friction: {without}\nwith it: {with}");
}

/// Computed torque against the MuJoCo arm through the processes: lockstep reruns are
/// byte-identical, it tracks as on evoloop's own arm plant, and a wall it presses against costs
/// tracking while the ball touches it.
#[test]
#[ignore = "needs Python 3 with mujoco and the evoloop_plant package's deps: pip install ./python mujoco"]
fn computed_torque_runs_against_the_mujoco_arm_reproducibly() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, out: &str| {
        let out = dir.path().join(out);
        common::assert_ok(&common::run(&common::config(name), &out, "mjct", &[]));
        out
    };
    let (a, b) = (
        run("arm3/arm3_mujoco.toml", "a"),
        run("arm3/arm3_mujoco.toml", "b"),
    );
    let csv = |d: &Path| std::fs::read(d.join("run.csv")).unwrap();
    assert!(csv(&a) == csv(&b), "lockstep reruns against MuJoCo differ");
    let rms = |d: &Path| {
        common::json(&d.join("summary.json"))["tracking"]["rms_all"]
            .as_f64()
            .unwrap()
    };
    // Per joint after the start-up ramp (whose transient dominates the whole run's rms and is
    // alike on any arm near this one), both on the drive's filtered velocity (arm3_mujoco's
    // default; arm3_ct's own file runs the observer): 0.60, 0.34, 0.52 mrad against 0.62, 0.34,
    // 0.55 measured (2026-12-02); a mass 20 % off gives 10-100 times more.
    let settled = |d: &Path| -> Vec<f64> {
        let s = common::json(&d.join("summary.json"));
        let rms = s["tracking_after_1s"]["rms"].as_array().unwrap().clone();
        rms.iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let own_file = common::write(
        dir.path(),
        "own.toml",
        &on_filtered_velocity("arm3/arm3_ct.toml"),
    );
    let own_out = dir.path().join("own");
    common::assert_ok(&common::run(&own_file, &own_out, "mjct", &[]));
    let own = settled(&own_out);
    let on_mujoco = settled(&a);
    println!("tracking rms after 1 s: MuJoCo arm {on_mujoco:?}, evoloop's arm {own:?}");
    for (j, (m, o)) in on_mujoco.iter().zip(&own).enumerate() {
        assert!(
            *m < 4.0 * o && *o < 4.0 * m,
            "joint {j}: computed torque tracks the two simulators' arm alike: {m} vs {o}"
        );
    }
    let mujoco = rms(&a);
    let wall = rms(&run("arm3/arm3_mujoco_wall.toml", "wall"));
    println!("with the wall: {wall}");
    assert!(
        wall > 10.0 * mujoco,
        "the wall stops the arm: {wall} vs {mujoco}"
    );
    let s = common::json(&a.join("summary.json"));
    assert_eq!(s["cycle_allocations"]["allocations"], 0);
}

/// arm3_mujoco with the Python plant sending no truth (`--no-truth`: NaN in x_true, q_true and
/// qd_true, as a real arm has none to send) and computed torque on velocities from its encoders
/// (`velocity = "filtered"`): the run is ok, its commands are bit for bit those of the same run
/// with the truth sent (the law read none of it), and it tracks as the same law does on
/// evoloop's own arm with the same encoders.
#[test]
#[ignore = "needs Python 3 with mujoco and the evoloop_plant package's deps: pip install ./python mujoco"]
fn computed_torque_runs_the_mujoco_arm_on_its_encoders_alone() {
    let dir = tempfile::tempdir().unwrap();
    let config = |name: &str, truth: bool| {
        let text = on_filtered_velocity(name).replace(
            "\"--noise\", \"0.0001\"]",
            if truth {
                "\"--noise\", \"0.0001\"]"
            } else {
                "\"--noise\", \"0.0001\", \"--no-truth\"]"
            },
        );
        let file = format!("{truth}-{}", name.replace('/', "-"));
        common::write(dir.path(), &file, &text)
    };
    let run = |file: &Path, out: &str| {
        let out = dir.path().join(out);
        common::assert_ok(&common::run(file, &out, "mjblind", &[]));
        out
    };
    let blind = run(&config("arm3/arm3_mujoco.toml", false), "blind");
    let seen = run(&config("arm3/arm3_mujoco.toml", true), "seen");
    let rows = |d: &Path| common::Csv::read(&d.join("run.csv"));
    let (b, s) = (rows(&blind), rows(&seen));
    for j in 0..3 {
        let u = format!("u{j}");
        let (ub, us) = (b.col(&u), s.col(&u));
        assert_eq!(ub.len(), us.len());
        assert!(
            ub.iter().zip(&us).all(|(x, y)| x.to_bits() == y.to_bits()),
            "{u}: the commands differ with the truth withheld"
        );
    }
    let truth: Vec<String> = b
        .header
        .iter()
        .filter(|n| n.starts_with('q')) // q0.., qd0..: the plant's q_true and qd_true
        .cloned()
        .collect();
    assert!(!truth.is_empty(), "run.csv records the truth columns");
    for c in &truth {
        assert!(
            b.col(c).iter().all(|v| v.is_nan()),
            "{c} is NaN when not sent"
        );
    }
    let settled = |d: &Path| -> Vec<f64> {
        let s = common::json(&d.join("summary.json"));
        let rms = s["tracking_after_1s"]["rms"].as_array().unwrap().clone();
        rms.iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let own = settled(&run(&config("arm3/arm3_ct.toml", true), "own"));
    let on_mujoco = settled(&blind);
    println!(
        "filtered velocity, rms after 1 s: MuJoCo arm blind {on_mujoco:?}, evoloop's arm {own:?}"
    );
    for (j, (m, o)) in on_mujoco.iter().zip(&own).enumerate() {
        assert!(
            *m < 4.0 * o && *o < 4.0 * m,
            "joint {j}: computed torque on encoders tracks the two simulators' arm alike: {m} vs {o}"
        );
    }
    let s = common::json(&blind.join("summary.json"));
    assert_eq!(s["cycle_allocations"]["allocations"], 0);
}
