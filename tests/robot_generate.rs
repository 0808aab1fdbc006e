//! `evoloop robot generate` and `evoloop robot zoo`: the arms load in strict mode, their mass
//! matrix is positive definite over their limits, their efforts hold them against gravity, one
//! seed gives one file, and bad input is refused with the file, key and reason. That their
//! dynamics are Pinocchio's is tests/dynamics.rs's check on the generated files in tests/robots
//! (regenerated here from their seeds, so the check is on what the generator writes).

use crate::common::cli;
use evoloop::dynamics::{load_with, LoadOptions};
use nalgebra::SymmetricEigen;
use rand::{Rng, SeedableRng};
use std::path::Path;

/// `evoloop robot generate --joints JOINTS --seed SEED --out OUT`, as a user types it.
fn run_generate(joints: &str, seed: &str, out: &Path) -> std::process::Output {
    cli(&[
        "robot",
        "generate",
        "--joints",
        joints,
        "--seed",
        seed,
        "--out",
        out.to_str().unwrap(),
    ])
}

fn generate(dir: &Path, joints: usize, seed: u64) -> std::path::PathBuf {
    let out = dir.join(format!("gen{joints}_s{seed}.urdf"));
    let o = run_generate(&joints.to_string(), &seed.to_string(), &out);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains(&format!("{joints} joints")), "{said}");
    out
}

/// Loads without a warning (strict), has `joints` joints, and over 200 states drawn within its
/// limits M is positive definite and the static torque of every joint is within its effort.
fn assert_plausible(file: &Path, joints: usize) {
    let strict = LoadOptions {
        strict: true,
        rigid_body_only: false,
    };
    let model = load_with(file, &strict)
        .unwrap_or_else(|e| panic!("{}: {e}", file.display()))
        .model;
    assert_eq!(model.dof(), joints);
    let mut d = model.data();
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    let mut g = vec![0.0; joints];
    for _ in 0..200 {
        let q: Vec<f64> = model
            .bodies
            .iter()
            .map(|b| rng.gen_range(b.limits.q_min..b.limits.q_max))
            .collect();
        let m = model.mass_matrix(&mut d, &q).clone();
        let low = SymmetricEigen::new(m).eigenvalues.min();
        assert!(
            low > 1e-6,
            "{}: M's smallest eigenvalue {low} at {q:?}",
            file.display()
        );
        model.gravity_torque(&mut d, &q, &mut g);
        for (b, t) in model.bodies.iter().zip(&g) {
            assert!(
                t.abs() < b.limits.effort,
                "{}: {}'s gravity torque {t} beyond its effort {}",
                file.display(),
                b.joint,
                b.limits.effort
            );
        }
    }
}

#[test]
fn generated_arms_of_three_to_seven_joints_load_and_are_plausible_over_their_limits() {
    let dir = tempfile::tempdir().unwrap();
    for joints in 3..=7 {
        for seed in [1, 2, 3] {
            assert_plausible(&generate(dir.path(), joints, seed), joints);
        }
    }
}

#[test]
fn one_seed_gives_one_file_and_the_files_pinocchio_checked_are_the_generators() {
    let dir = tempfile::tempdir().unwrap();
    let a = std::fs::read(generate(dir.path(), 6, 5)).unwrap();
    let second = tempfile::tempdir().unwrap();
    assert_eq!(a, std::fs::read(generate(second.path(), 6, 5)).unwrap());
    assert_ne!(a, std::fs::read(generate(dir.path(), 6, 6)).unwrap());
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (joints, seed) in [(3, 11), (6, 12), (7, 13)] {
        let name = format!("gen{joints}_s{seed}.urdf");
        let made = std::fs::read_to_string(generate(dir.path(), joints, seed)).unwrap();
        let kept = std::fs::read_to_string(root.join("tests/robots").join(&name)).unwrap();
        assert!(
            made == kept,
            "tests/robots/{name} is not what `evoloop robot generate` writes now: regenerate it \
             and Pinocchio's vectors (scripts/pinocchio_regressor.py)"
        );
    }
}

#[test]
fn the_zoo_is_ten_small_and_five_large_arms_written_whole() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("zoo");
    let o = cli(&["robot", "zoo", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut counts = [0usize; 8];
    for entry in std::fs::read_dir(&out).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let joints: usize = name[3..4].parse().unwrap();
        assert_plausible(&path, joints);
        counts[joints] += 1;
    }
    assert!(
        counts[3] + counts[4] >= 10 && counts[6] + counts[7] >= 5,
        "{counts:?}"
    );
}

#[test]
fn bad_joint_counts_and_zoo_files_are_refused_with_file_key_and_reason() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.urdf");
    for joints in ["2", "8", "x"] {
        let o = run_generate(joints, "1", &out);
        assert_eq!(o.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&o.stderr).contains("--joints"));
        assert!(!out.exists());
    }
    for (text, key) in [
        ("[[arm]]\njoints = 9\nseed = 1\n", "arm[0].joints"),
        (
            "[[arm]]\njoints = 3\nseed = 1\n[[arm]]\njoints = 3\nseed = 1\n",
            "arm[1]",
        ),
        ("[[arm]]\njoints = 3\nseed = 1\nmass = 2\n", "arm[0]"),
        ("[[arm]]\njoints = 3\nseed = -1\n", "arm[0].seed"),
    ] {
        let file = dir.path().join("zoo.toml");
        std::fs::write(&file, text).unwrap();
        let o = cli(&[
            "robot",
            "zoo",
            "--file",
            file.to_str().unwrap(),
            "--out",
            dir.path().join("z").to_str().unwrap(),
        ]);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{text}");
        assert!(
            e.contains("zoo.toml") && e.contains(&format!("`{key}")),
            "{text}: {e}"
        );
        assert!(
            !dir.path().join("z").exists(),
            "{text}: written although refused"
        );
    }
}

#[test]
fn a_link_planted_at_the_out_name_is_replaced_not_followed() {
    let dir = tempfile::tempdir().unwrap();
    let victim = dir.path().join("victim");
    std::fs::write(&victim, "keep").unwrap();
    let out = dir.path().join("arm.urdf");
    std::os::unix::fs::symlink(&victim, &out).unwrap();
    let o = run_generate("3", "1", &out);
    assert!(o.status.success());
    assert_eq!(std::fs::read_to_string(&victim).unwrap(), "keep");
    assert!(!std::fs::symlink_metadata(&out)
        .unwrap()
        .file_type()
        .is_symlink());
}

#[test]
fn the_selection_study_runs_on_a_generated_arm_on_trajectories_within_its_limits() {
    // gen3_s11's elbow turns +-2.45 rad, less than the paper's arm3 (+-2.8) whose written
    // trajectories take it to -2.6: the study builds its trajectories from the arm's limits and
    // says so, where it refused the arm before.
    let _heavy = crate::common::heavy();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sel");
    let v = crate::common::stdout_json(&cli(&[
        "rkgnn",
        "selection",
        "--robot",
        "tests/robots/gen3_s11.urdf",
        "--seeds",
        "1",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]));
    assert_eq!(v["trajectory_source"], "limits");
    assert_eq!(v["joints"], 3);
    assert!(!v["cells"].as_array().unwrap().is_empty());
}
