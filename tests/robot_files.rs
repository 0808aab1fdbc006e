//! Robot files as they come from ROS description packages (`tests/robots/`): what does not matter
//! to dynamics is ignored, what is physically dubious loads with a warning (refused with
//! `strict`), and only what cannot be simulated is refused, naming the link or joint. The same
//! files pass the dynamics property tests in `tests/dynamics.rs`.

use crate::common;
use common::{cli, stdout_json};
use evoloop::dynamics::{self, LoadOptions, Loaded};
use std::path::{Path, PathBuf};

fn path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/robots")
        .join(name)
}

fn load(name: &str, options: LoadOptions) -> Result<Loaded, dynamics::RobotError> {
    dynamics::load_with(&path(name), &options)
}

const STRICT: LoadOptions = LoadOptions {
    strict: true,
    rigid_body_only: false,
};

#[test]
fn ur_style_file_with_transmissions_gazebo_and_ros2_control_loads_cleanly() {
    // Its <transmission> and <ros2_control> blocks hold <joint name=..> elements without a type,
    // and a comment holds a joint of an unknown type: none of them is a joint of the tree.
    let l = load("ur5_style.urdf", STRICT).unwrap_or_else(|e| panic!("{e}"));
    let joints: Vec<&str> = l.model.bodies.iter().map(|b| b.joint.as_str()).collect();
    assert_eq!(
        joints,
        [
            "shoulder_pan_joint",
            "shoulder_lift_joint",
            "elbow_joint",
            "wrist_1_joint",
            "wrist_2_joint",
            "wrist_3_joint"
        ]
    );
    assert!(l.warnings.is_empty(), "{:?}", l.warnings);
    // The world link and base_link are the fixed base; ee_link (no inertial) merges into wrist 3.
    assert!(
        !l.model.has_friction(),
        "the file's damping and friction are 0"
    );
}

#[test]
fn panda_style_file_carries_its_joint_friction_unless_rigid_body_only() {
    let l = load("panda_style.urdf", STRICT).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(l.model.dof(), 7);
    assert!(l.warnings.is_empty(), "{:?}", l.warnings);
    assert!(l.model.has_friction());
    let b = &l.model.bodies[3].friction;
    assert_eq!((b.viscous, b.coulomb), (0.003, 0.2));
    let rigid = load(
        "panda_style.urdf",
        LoadOptions {
            rigid_body_only: true,
            ..Default::default()
        },
    )
    .unwrap()
    .model;
    assert!(!rigid.has_friction());
    // Inverse dynamics of the two differ by exactly F(qd), and nothing else.
    let (q, qd, qdd) = ([0.1; 7], [0.5, -0.4, 0.3, -0.2, 0.6, -0.7, 0.8], [0.2; 7]);
    let (mut with, mut without, mut f) = ([0.0; 7], [0.0; 7], [0.0; 7]);
    l.model
        .inverse_dynamics(&mut l.model.data(), &q, &qd, &qdd, &mut with);
    rigid.inverse_dynamics(&mut rigid.data(), &q, &qd, &qdd, &mut without);
    l.model.friction(&qd, &mut f);
    for i in 0..7 {
        assert!(f[i].abs() > 0.1, "joint {i} has friction");
        assert!((with[i] - without[i] - f[i]).abs() < 1e-12, "joint {i}");
    }
}

#[test]
fn iiwa_style_massless_base_is_ignored_and_massless_flange_is_a_warning() {
    // The root link iiwa_link_0 has zero mass and a non-zero tensor: a fixed base never moves, so
    // it is neither refused nor warned about. The flange link_ee (zero mass, tensor 1e-6) is.
    let l = load("iiwa_style.urdf", LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(l.model.dof(), 7);
    assert_eq!(l.warnings.len(), 1, "{:?}", l.warnings);
    let w = l.warnings[0].to_string();
    assert!(
        w.contains("link `iiwa_link_ee`") && w.contains("zero mass"),
        "{w}"
    );
    let e = load("iiwa_style.urdf", STRICT)
        .expect_err("strict refuses the massless flange")
        .to_string();
    assert!(
        e.contains("iiwa_style.urdf")
            && e.contains("link `iiwa_link_ee`")
            && e.contains("zero mass")
            && e.contains("--strict"),
        "{e}"
    );
    assert!(!e.contains("iiwa_link_0"), "{e}");
}

/// A two-link URDF with `extra` appended inside `<robot>` and `fore`'s inertial replaced.
fn two_links(fore_inertial: &str, elbow_extra: &str, extra: &str) -> String {
    format!(
        r#"<robot name="r">
  <link name="base"/>
  <link name="upper"><inertial><origin xyz="0.15 0 0"/><mass value="1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <link name="fore">{fore_inertial}</link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="5"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.3 0 0"/><axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="50" velocity="5"/>{elbow_extra}</joint>
  {extra}
</robot>"#
    )
}

const FORE: &str = r#"<inertial><origin xyz="0.15 0 0"/><mass value="1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>"#;

fn parse(text: &str, options: LoadOptions) -> Result<Loaded, String> {
    dynamics::urdf::parse_with(text, Path::new("t.urdf"), &options).map_err(|e| e.to_string())
}

#[test]
fn dubious_files_load_with_warnings_and_strict_refuses_them() {
    let cases = [
        (
            "triangle",
            two_links(&FORE.replace(r#"ixx="0.001""#, r#"ixx="0.05""#), "", ""),
            "link `fore`",
            "triangle inequality",
        ),
        (
            "massless with inertia",
            two_links(&FORE.replace(r#"value="1""#, r#"value="0""#), "", ""),
            "link `fore`",
            "zero mass",
        ),
        (
            "mimic",
            two_links(
                FORE,
                r#"<mimic joint="shoulder" multiplier="-1" offset="0.1"/>"#,
                "",
            ),
            "joint `elbow`",
            "mimics joint `shoulder` (multiplier -1, offset 0.1)",
        ),
    ];
    for (what, text, item, reason) in cases {
        let l = parse(&text, LoadOptions::default()).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(l.warnings.len(), 1, "{what}: {:?}", l.warnings);
        let w = l.warnings[0].to_string();
        assert!(w.contains(item) && w.contains(reason), "{what}: {w}");
        let e = parse(&text, STRICT).expect_err(what);
        assert!(
            e.contains(item) && e.contains(reason) && e.contains("--strict"),
            "{what}: {e}"
        );
    }
    // Within the tolerance (rounding of a printed tensor) the triangle inequality holds.
    let rounding = two_links(
        &FORE.replace(r#"ixx="0.001""#, r#"ixx="0.0200000001""#),
        "",
        "",
    );
    assert!(parse(&rounding, STRICT).is_ok());
    // A point mass (zero tensor) and a thin rod (one zero moment) are idealisations, not doubts.
    for tensor in [
        r#"ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0""#,
        r#"ixx="0" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01""#,
    ] {
        let fore = format!(
            r#"<inertial><origin xyz="0.15 0 0"/><mass value="1"/><inertia {tensor}/></inertial>"#
        );
        let l = parse(&two_links(&fore, "", ""), STRICT).unwrap_or_else(|e| panic!("{e}"));
        assert!(l.warnings.is_empty());
    }
}

#[test]
fn what_cannot_be_simulated_is_refused_naming_the_item() {
    let cases = [
        (
            two_links(&FORE.replace(r#"iyy="0.01""#, r#"iyy="-0.01""#), "", ""),
            "link `fore`",
            "not positive (semi-)definite",
        ),
        (
            two_links(&FORE.replace(r#"value="1""#, r#"value="-1""#), "", ""),
            "link `fore`",
            "negative mass",
        ),
        (
            two_links(FORE, "", "").replace(
                r#"<origin xyz="0.3 0 0"/>"#,
                r#"<origin xyz="${upper_length} 0 0"/>"#,
            ),
            "",
            "unprocessed .xacro file",
        ),
        (
            two_links(
                FORE,
                "",
                r#"<xacro:include filename="$(find ur_description)/urdf/common.xacro"/>"#,
            ),
            "",
            "xacro",
        ),
        (
            two_links(FORE, "", "").replace("<robot name=\"r\">", "<robot name=\"r\"><link"),
            "",
            "not a readable URDF",
        ),
        (
            two_links(FORE, "", "").replace(
                r#"<limit lower="-3" upper="3" effort="50" velocity="5"/></joint>
  <joint name="elbow""#,
                r#"<limit lower="3" upper="-3" effort="50" velocity="5"/></joint>
  <joint name="elbow""#,
            ),
            "joint `shoulder`",
            "limit lower 3 is above upper -3",
        ),
        (
            two_links(&FORE.replace(r#"value="1""#, r#"value="1e308""#), "", ""),
            "link `fore`",
            "beyond 1e9",
        ),
        (
            // A fixed joint with a NaN origin before the moving elbow: blamed on itself.
            two_links(FORE, "", "").replace(
                r#"<joint name="elbow" type="revolute"><parent link="upper"/>"#,
                r#"<link name="mid"/><joint name="spacer" type="fixed"><parent link="upper"/><child link="mid"/><origin xyz="NaN 0 0"/></joint>
  <joint name="elbow" type="revolute"><parent link="mid"/>"#,
            ),
            "joint `spacer`",
            "origin xyz and rpy must be finite",
        ),
    ];
    for (text, item, reason) in cases {
        let e = parse(&text, LoadOptions::default()).expect_err(reason);
        assert!(e.contains(item) && e.contains(reason), "{e}");
    }
    // Blocks that only name joints (ros_control) are not joints, whatever they contain.
    let extra = r#"<transmission name="t"><joint name="elbow"><hardwareInterface>x</hardwareInterface></joint></transmission>
  <gazebo reference="fore"><joint name="ghost" type="hinge"/></gazebo>
  <!-- <joint name="old" type="ball"/> -->"#;
    let l = parse(&two_links(FORE, "", extra), STRICT).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(l.model.dof(), 2);
}

#[test]
fn dynamics_cli_says_whether_friction_is_included_and_honours_strict() {
    let robot = path("panda_style.urdf");
    let robot = robot.to_str().unwrap();
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "dynamics",
            "--robot",
            robot,
            "--qd",
            "0.5,-0.4,0.3,-0.2,0.6,-0.7,0.8",
            "--json",
        ];
        a.extend_from_slice(extra);
        a
    };
    let with = stdout_json(&cli(&args(&[])));
    let without = stdout_json(&cli(&args(&["--no-friction"])));
    assert_eq!(with["friction_included"], true);
    assert_eq!(without["friction_included"], false);
    assert!(with["F"].as_array().unwrap()[0].as_f64().unwrap().abs() > 0.1);
    assert!(without["F"]
        .as_array()
        .unwrap()
        .iter()
        .all(|v| v.as_f64() == Some(0.0)));
    assert_eq!(with["warnings"], serde_json::json!([]));
    let text = cli(&["dynamics", "--robot", robot, "--no-friction"]);
    assert!(String::from_utf8_lossy(&text.stdout).contains("rigid body only"));

    let iiwa = path("iiwa_style.urdf");
    let iiwa = iiwa.to_str().unwrap();
    let lenient = cli(&["dynamics", "--robot", iiwa, "--json"]);
    let j = stdout_json(&lenient);
    assert_eq!(j["warnings"].as_array().unwrap().len(), 1);
    assert!(String::from_utf8_lossy(&lenient.stderr).contains("warning"));
    let strict = cli(&["dynamics", "--robot", iiwa, "--strict"]);
    assert_eq!(strict.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&strict.stderr).contains("iiwa_link_ee"));
}

#[test]
fn a_scenario_on_a_ros_style_urdf_warns_and_runs_computed_torque_in_the_processes() {
    let dir = tempfile::tempdir().unwrap();
    let robot = path("iiwa_style.urdf");
    let scenario = common::write(
        dir.path(),
        "iiwa.toml",
        &format!(
            r#"
seed = 1
[plant]
kind = "arm"
step = 0.0005
noise_std = 0.0
[plant.arm]
robot = "{}"
[controller]
kind = "computed_torque"
[controller.computed_torque]
kp = [400.0, 400.0, 400.0, 400.0, 400.0, 400.0, 400.0]
kv = [40.0, 40.0, 40.0, 40.0, 40.0, 40.0, 40.0]
velocity = "observer"
[reference]
kind = "quintic"
times = [0.2, 1.7]
waypoints = [[0.0, 0.3, 0.0, -1.0, 0.0, 0.5, 0.0], [0.8, -0.4, 0.6, -0.5, 0.9, -0.6, 1.2]]
[timing]
period = 0.001
duration = 2.0
"#,
            robot.display()
        ),
    );
    let check = cli(&["check", scenario.to_str().unwrap()]);
    assert!(check.status.success());
    let said = String::from_utf8_lossy(&check.stderr);
    assert!(
        said.contains("warning") && said.contains("iiwa_link_ee"),
        "{said}"
    );
    let out = dir.path().join("run");
    let (prefix, run_id) = common::unique("iiwa");
    let o = std::process::Command::new(common::evoloop())
        .args(["run", scenario.to_str().unwrap(), "--out"])
        .arg(&out)
        .args(["--ipc-prefix", &prefix, "--run-id", &run_id, "--quiet"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
    let rms: Vec<f64> = s["tracking_after_1s"]["rms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(rms.len(), 7);
    eprintln!("rms after 1 s: {rms:?}");
    // The true model in the controller (and in its velocity observer) and no sensor noise: only
    // the zero-order hold separates the arm from the trajectory. Joint 7 moves 1.3e-3 kg m^2 against the file's damping of
    // 0.5 N m s (time constant 2.6 ms, under three periods), so its held damping compensation
    // lags: 1.3e-3 rad rms here, 2e-5 with the damping removed (measured).
    assert!(rms[..6].iter().all(|&e| e < 2e-4), "{rms:?}");
    assert!(rms[6] < 2e-3, "{rms:?}");
}

#[test]
fn a_dh_table_with_a_repeated_joint_name_is_refused() {
    let text = std::fs::read_to_string(path("../../config/robots/arm3.toml")).unwrap();
    let names: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with("name = ") && !l.contains("arm3"))
        .collect();
    assert!(names.len() >= 2, "{names:?}");
    let dup = text.replacen(names[1], names[0], 1);
    let e = dynamics::dh::parse_with(&dup, Path::new("d.toml"), &LoadOptions::default())
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("(row 2)") && e.contains("used by an earlier joint"),
        "{e}"
    );
}

#[test]
fn a_urdf_nested_thousands_deep_or_with_a_name_twice_is_refused_not_a_crash() {
    // Issue 42: 30 000 levels overflowed the stack (exit 134); a duplicate joint name was
    // accepted (the D-H reader refuses one).
    let ok = |text: &str| parse(text, LoadOptions::default()).map(|_| ());
    assert!(ok(&two_links(FORE, "", "")).is_ok());
    let deep = format!("{}{}", "<a>".repeat(30_000), "</a>".repeat(30_000));
    let e = ok(&two_links(&format!("{FORE}{deep}"), "", "")).unwrap_err();
    assert!(e.contains("nested more than"), "{e}");
    let again = r#"<link name="hand"/><joint name="elbow" type="fixed"><parent link="fore"/><child link="hand"/></joint>"#;
    let e = ok(&two_links(FORE, "", again)).unwrap_err();
    assert!(
        e.contains("joint `elbow`") && e.contains("defined twice"),
        "{e}"
    );
    let e = ok(&two_links(FORE, "", r#"<link name="upper"/>"#)).unwrap_err();
    assert!(
        e.contains("link `upper`") && e.contains("defined twice"),
        "{e}"
    );
}
