//! `plant.kind = "lti"` against python-control, an independent implementation: the vectors in
//! tests/data/lti/ come from `scripts/lti_reference.py` (c2d, forced_response, and the poles of
//! the sampled state-feedback loop `control.feedback` builds). Each model is loaded the way a
//! user's exported file is, through `plant.lti.file`.
//!
//! Tolerance: 1e-9 of the signal's largest magnitude. Both sides compute in f64 (evoloop's Padé
//! exponential and matrix products, python-control's SciPy `expm` and `lsim`); what they differ
//! by is rounding, 1e-13 here, so 1e-9 fails on any modelling difference (a discretisation off by
//! a sample, a realisation with another gain, a delay one period off) and never on rounding.

use evoloop::check::Check;
use evoloop::plant::lti::{self, LtiSpec};
use evoloop::plant::{PlantContext, PlantSim};
use evoloop::reference::Reference;
use serde_json::Value;
use std::path::{Path, PathBuf};

const TOLERANCE: f64 = 1e-9;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/lti")
}

fn matrix(v: &Value) -> Vec<Vec<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect()
}

struct Case {
    name: String,
    response: Value,
    spec: LtiSpec,
}

fn cases() -> Vec<Case> {
    let mut names: Vec<String> = std::fs::read_dir(data())
        .unwrap()
        .filter_map(|e| {
            let n = e.unwrap().file_name().into_string().unwrap();
            n.strip_suffix(".response.json").map(str::to_string)
        })
        .collect();
    names.sort();
    assert!(
        names.len() >= 5,
        "the reference vectors are missing: {names:?}"
    );
    names.into_iter().map(load).collect()
}

/// The model file through `[plant.lti] file = ...` (with the case's delay and start).
fn load(name: String) -> Case {
    let text = std::fs::read_to_string(data().join(format!("{name}.response.json"))).unwrap();
    let response: Value = serde_json::from_str(&text).unwrap();
    let period = response["period"].as_f64().unwrap();
    let outputs = response["y"][0].as_array().unwrap().len();
    let mut table = format!(
        "file = \"{name}.model.json\"\ninput_delay = {}\n",
        response["input_delay"].as_f64().unwrap()
    );
    if let Some(x0) = response.get("x0") {
        table += &format!("x0 = {x0}\n");
    }
    let table: lti::Table = evoloop::files::from_toml(&table)
        .map_err(|p| p.reason)
        .unwrap();
    let reference = Reference::Sines {
        offsets: vec![0.0; outputs],
        amplitudes: vec![vec![0.0]; outputs],
        frequencies: vec![1.0],
        phases: vec![vec![0.0]; outputs],
    };
    let cx = PlantContext {
        step: period,
        period,
        reference: &reference,
        duration: 1.0,
    };
    // Paths resolve against the scenario's directory: pretend one sits beside the vectors.
    let check = Check::new(&data().join("scenario.toml"));
    let spec = lti::validate(Some(table), &check, &cx).unwrap_or_else(|e| panic!("{name}: {e}"));
    Case {
        name,
        response,
        spec,
    }
}

/// Worst |a - b| over matching rows, relative to the largest |b|.
fn worst(a: &[Vec<f64>], b: &[Vec<f64>]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().flatten().fold(1e-300f64, |m, x| m.max(x.abs()));
    a.iter()
        .zip(b)
        .flat_map(|(r, s)| {
            assert_eq!(r.len(), s.len());
            r.iter().zip(s).map(|(x, y)| (x - y).abs())
        })
        .fold(0.0, f64::max)
        / scale
}

/// evoloop's lockstep simulation of the case's inputs: the states, python-control's output
/// convention y_k = C x_k + D u_k (`output_with`), and the plant's own sample after each period,
/// y_{k+1} = C x_{k+1} + D u_k (the input in force when it is taken).
fn simulate(c: &Case) -> [Vec<Vec<f64>>; 3] {
    let s = &c.spec;
    let period = s.period;
    let mut sim = PlantSim::new(Box::new(s.clone()), period, 0.0, 1);
    let (mut xs, mut ys, mut held) = (vec![], vec![], vec![]);
    for u in matrix(&c.response["u"]) {
        xs.push(sim.x[..s.n].to_vec());
        let mut y = vec![0.0; s.p];
        s.output_with(&sim.x, &u, &mut y);
        ys.push(y);
        sim.advance(&u, period);
        let mut y = vec![0.0; s.p];
        sim.plant.output(&sim.x, &mut y);
        held.push(y);
    }
    [xs, ys, held]
}

/// python-control's outputs in the plant's sampling convention: y_{k+1} - D (u_{k+1} - u_k),
/// for k up to the second-last sample (D: the feedthrough, num[0]/den[0] for a transfer function
/// whatever its realisation).
fn held_reference(c: &Case) -> Vec<Vec<f64>> {
    let (u, y) = (matrix(&c.response["u"]), matrix(&c.response["y"]));
    let (p, m) = (c.spec.p, c.spec.m);
    (0..u.len() - 1)
        .map(|k| {
            (0..p)
                .map(|i| {
                    let du: f64 = (0..m)
                        .map(|j| c.spec.d[i * m + j] * (u[k + 1][j] - u[k][j]))
                        .sum();
                    y[k + 1][i] - du
                })
                .collect()
        })
        .collect()
}

#[test]
fn every_system_responds_as_python_control_computes() {
    let mut report = vec![];
    for c in cases() {
        let [xs, ys, held] = simulate(&c);
        let y_err = worst(&ys, &matrix(&c.response["y"]));
        assert!(y_err < TOLERANCE, "{}: outputs off by {y_err:e}", c.name);
        let expected = held_reference(&c);
        let held_err = worst(&held[..expected.len()], &expected);
        assert!(
            held_err < TOLERANCE,
            "{}: sampled outputs off by {held_err:e}",
            c.name
        );
        let mut line = format!("{}: y {y_err:.1e}, sampled y {held_err:.1e}", c.name);
        // State-space cases keep the user's realisation: states and c2d's matrices compare too.
        if let Some(x) = c.response.get("x") {
            let x_err = worst(&xs, &matrix(x));
            assert!(x_err < TOLERANCE, "{}: states off by {x_err:e}", c.name);
            let (n, m) = (c.spec.n, c.spec.m);
            let rows = |v: &[f64], cols| v.chunks(cols).map(<[f64]>::to_vec).collect::<Vec<_>>();
            let phi = worst(&rows(&c.spec.phi, n), &matrix(&c.response["phi"]));
            let gamma = worst(&rows(&c.spec.gamma, m), &matrix(&c.response["gamma"]));
            assert!(
                phi < TOLERANCE && gamma < TOLERANCE,
                "{}: c2d {phi:e} {gamma:e}",
                c.name
            );
            line += &format!(", x {x_err:.1e}, Phi {phi:.1e}, Gamma {gamma:.1e}");
        }
        report.push(line);
    }
    println!(
        "worst error relative to the largest value:\n  {}",
        report.join("\n  ")
    );
}

/// The controller's stability check on the sampled model agrees with the poles of the loop
/// python-control builds from the same plant and law, gain set by gain set (stable and
/// unstable sets drawn about an LQR gain).
#[test]
fn the_stability_check_agrees_with_python_controls_closed_loop_poles() {
    let mut checked = 0;
    for c in cases() {
        let Some(verdicts) = c.response.get("verdicts") else {
            continue;
        };
        let model = c.spec_model();
        let (mut stable, mut unstable) = (0, 0);
        for v in verdicts.as_array().unwrap() {
            let gains: Vec<f64> = v["gains"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let expect = v["stable"].as_bool().unwrap();
            assert_eq!(
                model.stabilised_by(&gains),
                expect,
                "{}: gains {gains:?}, python-control's spectral radius {}",
                c.name,
                v["radius"]
            );
            if expect {
                stable += 1
            } else {
                unstable += 1
            }
        }
        assert!(stable > 0 && unstable > 0, "{}: one-sided", c.name);
        checked += stable + unstable;
    }
    assert!(checked >= 200, "{checked} gain sets");
}

impl Case {
    fn spec_model(&self) -> evoloop::law::LinearModel {
        use evoloop::plant::PlantConfig;
        self.spec
            .linear_model()
            .unwrap_or_else(|| panic!("{}: a SISO model has a linear model", self.name))
    }
}

use crate::common;

/// The shipped scenarios through the real processes: state feedback holds the open-loop
/// unstable pendulum from its model file and refuses the set that would drop it (checked on the
/// exact sampled model); the PID positions the motor from its transfer function within the
/// amplifier's range. Lockstep reruns are byte-identical.
#[test]
fn the_shipped_lti_scenarios_run_through_the_processes() {
    let dir = tempfile::tempdir().unwrap();
    let pendulum = |out: &str| {
        let out = dir.path().join(out);
        common::assert_ok(&common::run(
            &common::config("linear/lti_pendulum.toml"),
            &out,
            "ltip",
            &[],
        ));
        out
    };
    let (first, again) = (pendulum("p1"), pendulum("p2"));
    let s = common::json(&first.join("summary.json"));
    assert_eq!(s["outcome"], "ok");
    assert_eq!(
        (
            s["accepted_versions"].as_u64(),
            s["rejected_versions"].as_u64()
        ),
        (Some(1), Some(1))
    );
    let err = s["response"]["final_error"].as_f64().unwrap().abs();
    assert!(
        err < 2e-3,
        "the pendulum holds the last reference: final error {err}"
    );
    let csv = |d: &Path| std::fs::read(d.join("run.csv")).unwrap();
    assert!(csv(&first) == csv(&again), "lockstep reruns differ");

    let out = dir.path().join("motor");
    common::assert_ok(&common::run(
        &common::config("linear/lti_motor.toml"),
        &out,
        "ltim",
        &[],
    ));
    let run = common::Csv::read(&out.join("run.csv"));
    let u = run.col("u0");
    let (lo, hi) = u
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(
        lo == -12.0 && hi == 12.0,
        "the 1 rad steps saturate the amplifier: {lo}..{hi}"
    );
    let s = common::json(&out.join("summary.json"));
    assert!(s["response"]["overshoot_pct"].as_f64().unwrap() < 15.0);
    assert!(s["response"]["final_error"].as_f64().unwrap().abs() < 0.02);
}

/// `evoloop check` names the key and both sizes of a wrong matrix, in the scenario or in the
/// model file it points to (then the file is named).
#[test]
fn a_wrong_matrix_size_is_named_with_its_key_and_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = |lti: &str| {
        format!(
            "[plant]\nkind = \"lti\"\n[plant.lti]\n{lti}\n[controller]\nkind = \"pid\"\n\
             [controller.pid]\nanti_windup = \"none\"\nparams = [1.0, 0.0, 0.0]\n\
             lower = [0.0, 0.0, 0.0]\nupper = [10.0, 1.0, 1.0]\n\
             [reference]\nkind = \"step\"\namplitude = 1.0\nstart = 0.0\n\
             [timing]\nperiod = 0.001\nduration = 1.0\n"
        )
    };
    let inline = common::write(
        dir.path(),
        "inline.toml",
        &scenario("a = [[0.0, 1.0], [-1.0, -1.0]]\nb = [[0.0], [1.0], [2.0]]\nc = [[1.0, 0.0]]"),
    );
    let o = common::cli(&["check", inline.to_str().unwrap()]);
    common::assert_refused(
        &o,
        "key `plant.lti.b`: is 3 x 1, must be 2 x 1 (one row per state: A is 2 x 2)",
    );
    common::write(
        dir.path(),
        "m.json",
        r#"{"a": [[-1.0]], "b": [[1.0]], "c": [[1.0, 2.0]]}"#,
    );
    let filed = common::write(dir.path(), "filed.toml", &scenario("file = \"m.json\""));
    let o = common::cli(&["check", filed.to_str().unwrap()]);
    common::assert_refused(&o, "m.json: key `c`: is 1 x 2, must be 1 x 1");
    // A model that moves once a period cannot run where realtime splits periods.
    let delayed = common::write(
        dir.path(),
        "delayed.toml",
        &scenario("num = [1.0]\nden = [1.0, 1.0]\ninput_delay = 0.002")
            .replace("period = 0.001", "period = 0.001\nmode = \"realtime\""),
    );
    let o = common::cli(&["check", delayed.to_str().unwrap()]);
    common::assert_refused(&o, "key `timing.mode`: \"realtime\": an input delay (plant.lti.input_delay) moves once a control period");
    // A huge entry is refused before the exponential, not computed for ever.
    let huge = common::write(
        dir.path(),
        "huge.toml",
        &scenario("a = [[1e42]]\nb = [1.0]\nc = [1.0]"),
    );
    let o = common::cli(&["check", huge.to_str().unwrap()]);
    common::assert_refused(&o, "key `plant.lti.a`: |[A B]| T is about 2.0e39");
    // A model file's own syntax error keeps its line.
    common::write(
        dir.path(),
        "m.json",
        "{\"a\": [[-1.0]],\n \"b\": [[1.0]]\n \"c\": 1}",
    );
    let o = common::cli(&["check", filed.to_str().unwrap()]);
    common::assert_refused(&o, "m.json:3");
}
