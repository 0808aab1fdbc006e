//! `evoloop dynamics` and the arm scenario files from the command line: the JSON keys, the
//! URDF's chain order, agreement with the library, and clear errors (exit 2).

use crate::common;
use common::{cli, stdout_json};
use std::path::Path;

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn dynamics_prints_tau_m_g_v_and_forward_dynamics_for_dh_and_urdf_alike() {
    let args = |robot: &'static str| {
        [
            "dynamics",
            "--robot",
            robot,
            "--q",
            "0.3,-0.5,0.8",
            "--qd",
            "0.5,1,-1",
            "--qdd",
            "1,2,-3",
            "--tau",
            "1,12,3",
            "--json",
        ]
    };
    let a = stdout_json(&cli(&args("config/robots/arm3.toml")));
    let b = stdout_json(&cli(&args("config/robots/arm3.urdf")));
    for key in ["tau", "G", "V", "qdd"] {
        let (x, y) = (floats(&a[key]), floats(&b[key]));
        assert_eq!(x.len(), 3, "{key}");
        for i in 0..3 {
            assert!(
                (x[i] - y[i]).abs() < 1e-9 * (1.0 + x[i].abs()),
                "{key}[{i}]: {} vs {}",
                x[i],
                y[i]
            );
        }
    }
    assert_eq!(a["M"].as_array().unwrap().len(), 3);
    assert_eq!(
        b["joints"],
        serde_json::json!(["waist", "shoulder", "elbow"])
    );
    // tau = M qdd + V + G + F, printed parts add up.
    let m: Vec<Vec<f64>> = a["M"].as_array().unwrap().iter().map(floats).collect();
    let (g, v, f, tau) = (
        floats(&a["G"]),
        floats(&a["V"]),
        floats(&a["F"]),
        floats(&a["tau"]),
    );
    let qdd = [1.0, 2.0, -3.0];
    for i in 0..3 {
        let sum: f64 = (0..3).map(|j| m[i][j] * qdd[j]).sum::<f64>() + v[i] + g[i] + f[i];
        assert!((sum - tau[i]).abs() < 1e-9, "row {i}");
    }
    // Forward dynamics of the given tau against the library's inverse dynamics.
    let model = evoloop::dynamics::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/arm3.toml"),
    )
    .unwrap();
    let mut d = model.data();
    let mut back = [0.0; 3];
    model.inverse_dynamics(
        &mut d,
        &[0.3, -0.5, 0.8],
        &[0.5, 1.0, -1.0],
        &floats(&a["qdd"]),
        &mut back,
    );
    for (i, t) in [1.0, 12.0, 3.0].iter().enumerate() {
        assert!((back[i] - t).abs() < 1e-9);
    }
    // Without --tau there is no qdd; the text form prints the same sections.
    let plain = cli(&["dynamics", "--robot", "config/robots/industrial6.toml"]);
    assert!(plain.status.success());
    let text = String::from_utf8_lossy(&plain.stdout);
    for part in ["tau = M qdd", "M(q):", "G(q):", "V(q, qd):"] {
        assert!(text.contains(part), "{part} missing in:\n{text}");
    }
    assert!(!text.contains("forward dynamics"));
}

#[test]
fn dynamics_refuses_bad_input_with_exit_2() {
    let o = cli(&[
        "dynamics",
        "--robot",
        "config/robots/arm3.toml",
        "--q",
        "1,2",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--q needs 3 values"));
    let o = cli(&["dynamics", "--robot", "config/robots/nope.urdf"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot read"));
    let o = cli(&["dynamics", "--robot", "Cargo.toml"]);
    assert_eq!(o.status.code(), Some(2));
}

#[test]
fn arm_scenarios_check_and_bad_ones_name_the_key() {
    for c in [
        "arm3/arm3_ct",
        "arm3/arm3_pd",
        "arm3/arm3_train1",
        "arm3/arm3_train2",
        "industrial6/industrial6_ct",
        "industrial6/industrial6_identify",
        "industrial6/industrial6_identify_wrist",
        "industrial6/industrial6_identify_arm",
    ] {
        let o = cli(&["check", &format!("config/{c}.toml")]);
        assert!(
            o.status.success(),
            "{c}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let tmp = tempfile::tempdir().unwrap();
    let base = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("config/arm3/arm3_ct.toml"),
    )
    .unwrap();
    // Robot paths are relative to the scenario file: point them back at the source tree.
    let robots = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots");
    let base = base.replace("\"../robots/", &format!("\"{}/", robots.display()));
    let cases = [
        (
            base.replace("arm3.toml\"", "missing.toml\""),
            "plant.arm.robot",
            "cannot read",
        ),
        (
            base.replace("kp = [400.0, 400.0, 400.0]", "kp = [400.0, 400.0]"),
            "controller.computed_torque.kp",
            "needs 3 values",
        ),
        (
            base.replace("kp = [400.0, 400.0, 400.0]", "kp = [400.0, -1.0, 400.0]"),
            "controller.computed_torque.kp[1]",
            ">= 0",
        ),
        (
            base.replace("offsets = [0.0, 0.7, -1.3]", "offsets = [0.0, 0.7]"),
            "reference",
            "",
        ),
        (
            base.replace("kind = \"computed_torque\"", "kind = \"state_feedback\""),
            "controller",
            "",
        ),
        (
            base.replace("startup_rate = 0.03", "startup_rate = -1.0"),
            "controller.computed_torque.startup_rate",
            "within",
        ),
        (
            base.replace(
                "frequencies = [0.2, 0.5]",
                "frequencies = [0.2, 0.5]\ntimes = [1.0]",
            ),
            "reference.times",
            "not used by a `sines` reference",
        ),
    ];
    for (i, (text, key, reason)) in cases.iter().enumerate() {
        let f = tmp.path().join(format!("bad{i}.toml"));
        std::fs::write(&f, text).unwrap();
        let o = cli(&["check", f.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "case {i}: {err}");
        assert!(
            err.contains(&format!("bad{i}.toml")) && err.contains(key) && err.contains(reason),
            "case {i}: {err}"
        );
    }
}

/// `dynamics regressor`: keys Y (rows = joints), parameters, pi; Y pi (+ armature qdd) is the
/// rigid-body tau of `dynamics --no-friction`, and with --friction the full tau of `dynamics`.
#[test]
fn regressor_prints_y_parameters_and_pi_that_reproduce_the_dynamics() {
    let state = [
        "--robot",
        "config/robots/industrial6.toml",
        "--q",
        "0.3,-0.5,0.8,0.1,0.2,0.3",
        "--qd",
        "0.5,1,-1,1,1,1",
        "--qdd",
        "1,-0.5,0.3,2,-1,0.5",
        "--json",
    ];
    for (friction, dyn_flag) in [(false, Some("--no-friction")), (true, None)] {
        let mut args = vec!["dynamics", "regressor"];
        args.extend_from_slice(&state);
        if friction {
            args.push("--friction");
        }
        let v = stdout_json(&cli(&args));
        let names: Vec<&str> = v["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap())
            .collect();
        assert_eq!(names.len(), if friction { 72 } else { 60 });
        assert_eq!(&names[..5], ["m1", "mx1", "my1", "mz1", "Ixx1"]);
        assert_eq!(names[59], "Izz6");
        let pi = floats(&v["pi"]);
        let y: Vec<Vec<f64>> = v["Y"].as_array().unwrap().iter().map(floats).collect();
        assert_eq!((y.len(), y[0].len()), (6, names.len()));
        let qdd = floats(&v["qdd"]);
        let armature = floats(&v["armature"]);
        let mut dyn_args = vec!["dynamics"];
        dyn_args.extend_from_slice(&state);
        dyn_args.extend(dyn_flag);
        let tau = floats(&stdout_json(&cli(&dyn_args))["tau"]);
        for j in 0..6 {
            let ypi: f64 = y[j].iter().zip(&pi).map(|(a, b)| a * b).sum();
            let expected = tau[j] - armature[j] * qdd[j];
            assert!(
                (ypi - expected).abs() < 1e-9 * (1.0 + expected.abs()),
                "friction {friction}, joint {j}: {ypi} vs {expected}"
            );
        }
    }
    // The text form and a wrong-length state (exit 2, naming the flag).
    let o = cli(&[
        "dynamics",
        "regressor",
        "--robot",
        "config/robots/arm3.urdf",
    ]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("Izz3"));
    let o = cli(&[
        "dynamics",
        "regressor",
        "--robot",
        "config/robots/arm3.urdf",
        "--q",
        "1",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--q needs 3 values"));
}

/// `identify base`: keys base_count, base, unidentifiable, combined; every parameter is in
/// exactly one list, and the first link of the 6-DOF arm regroups into Izz1.
#[test]
fn identify_base_lists_base_unidentifiable_and_combined_parameters() {
    let v = stdout_json(&cli(&[
        "identify",
        "base",
        "--robot",
        "config/robots/industrial6.toml",
        "--json",
    ]));
    let list = |k: &str| -> Vec<String> {
        v[k].as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap().to_string())
            .collect()
    };
    let (base, zero, combined) = (list("base"), list("unidentifiable"), list("combined"));
    assert_eq!(v["base_count"].as_u64().unwrap() as usize, base.len());
    assert_eq!(base.len() + zero.len() + combined.len(), 60);
    assert!(base.contains(&"Izz1".to_string()) && zero.contains(&"m1".to_string()));
    assert!(v["regrouping"][0].as_str().unwrap().starts_with("Izz1 +"));
    // The column norms: zero exactly for the unidentifiable columns, 1 for the largest.
    let norms = v["column_norms"].as_object().unwrap();
    assert_eq!(norms.len(), 60);
    for (name, n) in norms {
        let n = n.as_f64().unwrap();
        assert_eq!(n < 1e-10, zero.contains(name), "{name}: {n}");
    }
    assert!(norms.values().any(|n| n.as_f64() == Some(1.0)));
    let f = stdout_json(&cli(&[
        "identify",
        "base",
        "--robot",
        "config/robots/industrial6.toml",
        "--friction",
        "--json",
    ]));
    assert_eq!(f["parameters"], 72);
    let o = cli(&[
        "identify",
        "base",
        "--robot",
        "config/robots/industrial6.toml",
        "--states",
        "2",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--states 2"));
}

#[test]
fn bench_dynamics_times_every_algorithm_in_pinocchio_s_json_shape() {
    let out = cli(&[
        "bench",
        "dynamics",
        "--robot",
        "config/robots/arm7.urdf",
        "--calls",
        "2000",
        "--json",
    ]);
    let j = stdout_json(&out);
    assert_eq!(j["library"], "evoloop");
    assert_eq!(j["joints"], 7);
    assert_eq!(j["calls"], 2000);
    // The keys scripts/pinocchio_bench.py pairs with Pinocchio's (rnea, crba, aba), and the
    // plant's route.
    for key in ["rnea", "crba", "aba", "forward_crba"] {
        let ns = j["ns_per_call"][key].as_f64().unwrap();
        assert!(ns.is_finite() && ns > 0.0, "{key}: {ns}");
    }
    let bad = cli(&["bench", "dynamics", "--robot", "no/such.urdf"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("no/such.urdf"));
    let few = cli(&[
        "bench",
        "dynamics",
        "--robot",
        "config/robots/arm7.urdf",
        "--calls",
        "10",
    ]);
    assert_eq!(few.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&few.stderr).contains("--calls"));
}
