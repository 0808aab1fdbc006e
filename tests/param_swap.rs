//! The optimiser-to-controller path end to end: a valid set is accepted at a cycle boundary
//! without a bump in u; a NaN set, an out-of-bounds set and a wrong-length set are rejected with a
//! reason, and the loop keeps running on the set in service.

use crate::common;
use common::*;

const OLD: [f64; 5] = [18.49, 19.04, 47.27, 7.30, -10.54];
const NEW: [f64; 5] = [12.1946, 11.7906, 18.7567, 4.958, -10.0];

#[test]
fn valid_set_is_swapped_in_bumplessly_and_bad_sets_are_rejected_with_a_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let extra = "mode = \"lockstep\"
[optimiser]
mode = \"schedule\"
[[optimiser.schedule]]
at = 15.0
values = [12.1946, 11.7906, 18.7567, 4.958, -10.0]
[[optimiser.schedule]]
at = 16.0
values = [1.0, nan, 1.0, 1.0, -1.0]
expect = \"rejected\"
[[optimiser.schedule]]
at = 17.0
values = [1.0, 1.0, 1.0, 500.0, -1.0]
expect = \"rejected\"
[[optimiser.schedule]]
at = 18.0
values = [1.0, 1.0, 1.0]
expect = \"rejected\"
[[optimiser.schedule]]
at = 19.0
values = [-20.0, 19.04, 47.27, 7.30, -10.54]
";
    let cfg = write(
        tmp.path(),
        "swap.toml",
        &scenario("kind = \"step\"\namplitude = 1.0\nstart = 0.5", extra),
    );
    let out = tmp.path().join("out");
    assert_ok(&run(&cfg, &out, "swap", &[]));

    let c = json(&out.join("controller.json"));
    let p = c["params"].as_array().unwrap();
    assert_eq!(p.len(), 5, "{p:?}");
    assert_eq!(p[0]["version"], 1);
    assert_eq!(p[0]["outcome"], "accepted");
    assert_eq!(p[0]["cycle"], 15_000, "applied at the cycle of its sample");
    assert_eq!(p[1]["version"], 2);
    assert!(
        p[1]["outcome"].as_str().unwrap().contains("NaN"),
        "{}",
        p[1]
    );
    assert_eq!(p[1]["index"], 1);
    assert_eq!(p[2]["version"], 3);
    assert!(
        p[2]["outcome"].as_str().unwrap().contains("bounds"),
        "{}",
        p[2]
    );
    assert_eq!(p[2]["index"], 3);
    assert_eq!(p[3]["version"], 4);
    assert!(
        p[3]["outcome"]
            .as_str()
            .unwrap()
            .contains("number of values"),
        "{}",
        p[3]
    );
    // In bounds and finite, but it would destabilise the loop on the controller's model.
    assert_eq!(p[4]["version"], 5);
    assert!(
        p[4]["outcome"].as_str().unwrap().contains("unstable"),
        "{}",
        p[4]
    );
    // Each event carries its code by name, the report's classification of it.
    let codes: Vec<&str> = p.iter().map(|e| e["code"].as_str().unwrap()).collect();
    assert_eq!(
        codes,
        [
            "accepted",
            "rejected_non_finite",
            "rejected_out_of_bounds",
            "rejected_wrong_length",
            "rejected_unstable"
        ]
    );
    assert_eq!(c["final_version"], 1);
    let fp: Vec<f64> = c["final_params"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(fp, NEW.to_vec(), "the loop runs on the last accepted set");

    let s = json(&out.join("summary.json"));
    assert_eq!(
        s["parameter_versions"]["accepted"]
            .as_array()
            .unwrap()
            .len(),
        1
    );
    assert_eq!(
        s["parameter_versions"]["rejected"]
            .as_array()
            .unwrap()
            .len(),
        4
    );
    assert_eq!(s["accepted_versions"], 1);
    assert_eq!(s["rejected_versions"], 4);

    // The loop ran every cycle; the version column switches exactly once, at t = 15 s.
    let csv = Csv::read(&out.join("run.csv"));
    assert_eq!(csv.rows.len(), 25_000);
    let (t, u, v) = (csv.col("t"), csv.col("u0"), csv.col("param_version"));
    let k = v.iter().position(|&x| x == 1.0).unwrap();
    assert!((t[k] - 15.0).abs() < 1e-9);
    assert!(
        v[k..].iter().all(|&x| x == 1.0),
        "rejected sets never entered service"
    );
    assert!(v[..k].iter().all(|&x| x == 0.0));

    // No bump in u at the swap: the change across the swap is as small as in the steady state
    // around it, while a plain swap (integrator kept) would have jumped by (K_old - K_new) x.
    let (x2, x1) = (csv.col("q1")[k], csv.col("q0")[k]);
    let naive_jump = ((OLD[0] - NEW[0]) * x2 + (OLD[1] - NEW[1]) * x1).abs();
    assert!(
        naive_jump > 1.0,
        "the test state must make a plain swap visible ({naive_jump})"
    );
    let around = (k - 50..k + 50)
        .filter(|&i| i != k)
        .map(|i| (u[i] - u[i - 1]).abs())
        .fold(0.0, f64::max);
    let at_swap = (u[k] - u[k - 1]).abs();
    assert!(
        at_swap <= around.max(1e-6) * 2.0,
        "bump at the swap: |du| = {at_swap}, around it {around}"
    );
}
