//! evoloop's Kalman filter (`law::estimator`) against python-control: tests/data/kalman.json
//! holds, for five continuous models (the two-mass benchmark with either sensor, and collocated
//! with a state noise in the design; the upright pendulum; a double integrator), `c2d`'s
//! zero-order-hold model at the control period, `dlqe`'s gain L, Riccati solution P and error
//! poles, and the one-step predictions of that filter over a seeded input and noisy output
//! (scripts/kalman_reference.py; CI regenerates them with the pinned python-control and
//! compares). Then the filter in the default scenario: the law on its estimate, the truth
//! withheld.

use evoloop::law::estimator::{Kalman, KalmanDesign};
use evoloop::msg::PlantState;
use evoloop::plant::LinearModel;
use serde_json::Value;

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .flat_map(|x| match x.as_array() {
            Some(row) => row.iter().map(|e| e.as_f64().unwrap()).collect(),
            None => vec![x.as_f64().unwrap()],
        })
        .collect()
}

fn assert_close(what: &str, got: &[f64], want: &[f64], rel: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= rel * w.abs().max(1.0),
            "{what}[{i}]: evoloop {g}, python-control {w}"
        );
    }
}

fn cases() -> Vec<Value> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/kalman.json");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    v["cases"].as_array().unwrap().clone()
}

#[test]
fn the_kalman_filter_is_python_controls_dlqe_on_every_case() {
    let cases = cases();
    // The fifth designs with a state noise as well (python-control's dlqe with G = [B_d I]).
    assert_eq!(cases.len(), 5);
    for c in &cases {
        let name = c["name"].as_str().unwrap();
        let (a, b, cc) = (floats(&c["a"]), floats(&c["b"]), floats(&c["c"]));
        let n = b.len();
        let period = c["period"].as_f64().unwrap();
        let design = KalmanDesign {
            process_noise: c["process_noise"].as_f64().unwrap(),
            measurement_noise: c["measurement_noise"].as_f64().unwrap(),
            state_noise: c["state_noise"].as_f64().unwrap_or(0.0),
        };
        let g = design
            .gains(&LinearModel::continuous(&a, &b, &cc), period)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let ad: Vec<f64> = (0..n * n).map(|k| g.model.a(k / n, k % n)).collect();
        let bd: Vec<f64> = (0..n).map(|i| g.model.b(i)).collect();
        assert_close(&format!("{name} A_d"), &ad, &floats(&c["ad"]), 1e-12);
        assert_close(&format!("{name} B_d"), &bd, &floats(&c["bd"]), 1e-12);
        assert_close(&format!("{name} L"), &g.l, &floats(&c["l"]), 1e-7);
        let p: Vec<f64> = g.p.transpose().iter().copied().collect();
        let p_want = floats(&c["p"]);
        let scale = p_want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let rel: Vec<f64> = p.iter().map(|v| v / scale).collect();
        let rel_want: Vec<f64> = p_want.iter().map(|v| v / scale).collect();
        assert_close(&format!("{name} P / max|P|"), &rel, &rel_want, 1e-7);
        let mut poles = g.poles.clone();
        poles.sort_by(|x, y| (x.re, x.im).partial_cmp(&(y.re, y.im)).unwrap());
        let poles: Vec<f64> = poles.iter().flat_map(|z| [z.re, z.im]).collect();
        assert_close(&format!("{name} poles"), &poles, &floats(&c["poles"]), 1e-9);

        // The filter in the cycle, sample by sample: its x[k|k] moved on by the model is
        // dlqe's predictor x[k+1|k].
        let (u, y) = (floats(&c["u"]), floats(&c["y"]));
        let predicted = floats(&c["predicted"]);
        let mut kf = Kalman::new(&g, 0);
        let mut s = PlantState::default();
        for k in 0..u.len() {
            s.seq = k as u64;
            s.y[0] = y[k];
            s.u_applied[0] = if k == 0 { 0.0 } else { u[k - 1] };
            let x = kf.update(&s).to_vec();
            let next: Vec<f64> = (0..n)
                .map(|i| (0..n).map(|j| ad[i * n + j] * x[j]).sum::<f64>() + bd[i] * u[k])
                .collect();
            assert_close(
                &format!("{name} x[{}|{k}]", k + 1),
                &next,
                &predicted[k * n..(k + 1) * n],
                1e-6,
            );
        }
    }
}
