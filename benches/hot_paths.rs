//! Per-call costs of the hot paths: the control cycle, the plant integration, the stability
//! radius and one DE generation. `cargo bench --bench hot_paths`.

use criterion::{criterion_group, criterion_main, Criterion};
use evoloop::law::cycle::ControlCycle;
use evoloop::law::estimator::{Kalman, KalmanDesign};
use evoloop::law::{ParamBounds, StateFeedback};
use evoloop::msg::{PlantState, Telemetry};
use evoloop::optim::{evaluate, DeConfig, DifferentialEvolution, Optimiser};
use evoloop::plant::two_mass::{Sensor, TwoMass};
use evoloop::plant::PlantSim;
use evoloop::reference::Reference;
use evoloop::robust::stability_radius::{hinf_norm, stability_radius};
use evoloop::robust::RobustProblem;
use std::hint::black_box;

const DEFC: [f64; 5] = [18.49, 19.04, 47.27, 7.30, -10.54];
const TUNED: [f64; 5] = [13.7496, 21.7200, 49.9987, 8.1792, -8.3732];

fn control(c: &mut Criterion) {
    let mut cycle = ControlCycle::new(
        Box::new(StateFeedback::new(&DEFC, 0.001, Some(100.0))),
        Reference::Step {
            amplitude: 1.0,
            start: 0.0,
        },
        ParamBounds {
            lower: vec![-100.0; 5],
            upper: vec![100.0; 5],
        },
    );
    let mut state = PlantState {
        n_x: 4,
        n_y: 1,
        ..Default::default()
    };
    state.x_true[..4].copy_from_slice(&[0.3, 0.2, 0.01, -0.02]);
    state.y[0] = 0.3;
    let mut tel = Telemetry::default();
    c.bench_function("control cycle: state feedback + telemetry", |b| {
        b.iter(|| {
            state.seq += 1;
            black_box(cycle.step(black_box(&state), &mut tel));
        })
    });
    // The indirect scheme's adoption of an estimate: the law's Kalman filter designed again on
    // the model at the estimated spring (`Kalman::redesign`, in the cycle, allocation-free).
    let design = KalmanDesign {
        process_noise: 1.0,
        measurement_noise: 5e-4,
        state_noise: 0.0,
    };
    let nominal = TwoMass::new(1.0, 1.0, 1.0, Sensor::Far).linear_model();
    let mut filter = Kalman::new(&design.gains(&nominal, 0.001).unwrap(), 0);
    let estimate = TwoMass::new(1.0, 1.0, 0.5, Sensor::Far).linear_model();
    c.bench_function(
        "Kalman filter designed again on an estimate (two-mass, in the cycle)",
        |b| b.iter(|| assert!(filter.redesign(black_box(&estimate)))),
    );
    let mut sim = PlantSim::new(
        Box::new(TwoMass::new(1.0, 1.0, 1.0, Sensor::Far)),
        5e-4,
        0.0,
        1,
    );
    c.bench_function("two-mass plant: one 1 ms period (2 RK4 sub-steps)", |b| {
        b.iter(|| sim.advance(black_box(&[0.1]), 0.001))
    });
    let mut msg = PlantState::default();
    c.bench_function("two-mass plant: sample into a state message", |b| {
        b.iter(|| sim.sample(1, 0, &[0.1], black_box(&mut msg)))
    });
}

fn robust(c: &mut Criterion) {
    let prob = RobustProblem::paper();
    let acl = prob.closed_loop(&TUNED);
    c.bench_function(
        "stability radius r_c (5 states, level-set H-infinity)",
        |b| b.iter(|| black_box(stability_radius(black_box(&acl), prob.e(), prob.h()).unwrap())),
    );
    c.bench_function("H-infinity norm (same loop)", |b| {
        b.iter(|| black_box(hinf_norm(black_box(&acl), prob.e(), prob.h()).unwrap()))
    });
    assert!(prob.evaluate(&DEFC).unwrap().in_wedge);
    c.bench_function(
        "DOCHM objective, feasible candidate (poles + wedge + r_c)",
        |b| b.iter(|| black_box(prob.objective(black_box(&DEFC)))),
    );
    c.bench_function(
        "DOCHM objective, infeasible candidate (poles + wedge)",
        |b| b.iter(|| black_box(prob.objective(black_box(&[1.0, 1.0, 1.0, 1.0, -1.0])))),
    );
    let mut group = c.benchmark_group("DE generation (NP = 100)");
    group.sample_size(20);
    for threads in [1, 2] {
        let cfg = DeConfig::paper(0.5, 0.9, prob.lower.clone(), prob.upper.clone(), 1);
        let mut de = DifferentialEvolution::new(cfg).unwrap();
        // Start from a converged-ish population, as in most of a run.
        for _ in 0..200 {
            de.ask();
            let v = evaluate(de.candidates(), de.thresholds(), &prob, 2);
            de.tell(&v);
        }
        group.bench_function(format!("{threads} thread(s)"), |b| {
            b.iter(|| {
                de.ask();
                let v = evaluate(de.candidates(), de.thresholds(), &prob, threads);
                de.tell(&v);
            })
        });
    }
    group.finish();
}

/// Rigid-body dynamics of the 6-DOF industrial arm (config/robots/industrial6.toml) at a generic
/// state; Pinocchio's figures for a 6-DOF arm on a machine like this: RNEA 0.80 us, CRBA 0.47 us,
/// ABA 1.64 us.
fn dynamics(c: &mut Criterion) {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/industrial6.toml");
    let model = evoloop::dynamics::load(&path).expect("robot loads");
    let mut d = model.data();
    let q = [0.3, -0.5, 0.8, 0.1, 0.2, 0.3];
    let qd = [0.5, 1.0, -1.0, 1.0, 1.0, 1.0];
    let qdd = [1.0, -0.5, 0.3, 2.0, -1.0, 0.5];
    let tau = [20.0, -200.0, 20.0, 3.0, 3.0, 1.5];
    let mut out = [0.0; 6];
    c.bench_function("dynamics 6-DOF: inverse dynamics (RNEA + friction)", |b| {
        b.iter(|| {
            model.inverse_dynamics(
                &mut d,
                black_box(&q),
                black_box(&qd),
                black_box(&qdd),
                &mut out,
            )
        })
    });
    c.bench_function(
        "dynamics 6-DOF: inverse dynamics (rigid-body RNEA only)",
        |b| {
            b.iter(|| {
                model.rnea(
                    &mut d,
                    black_box(&q),
                    black_box(&qd),
                    black_box(&qdd),
                    &mut out,
                )
            })
        },
    );
    let mut y = nalgebra::DMatrix::zeros(6, model.regressor_columns(false));
    c.bench_function("dynamics 6-DOF: joint-torque regressor Y (6 x 60)", |b| {
        b.iter(|| {
            model.regressor(
                &mut d,
                black_box(&q),
                black_box(&qd),
                black_box(&qdd),
                &mut y,
            );
            black_box(&y);
        })
    });
    c.bench_function("dynamics 6-DOF: mass matrix M(q) (CRBA)", |b| {
        b.iter(|| {
            black_box(model.mass_matrix(&mut d, black_box(&q)));
        })
    });
    c.bench_function(
        "dynamics 6-DOF: forward dynamics (RNEA + CRBA + Cholesky)",
        |b| {
            b.iter(|| {
                model.forward_dynamics(
                    &mut d,
                    black_box(&q),
                    black_box(&qd),
                    black_box(&tau),
                    &mut out,
                )
            })
        },
    );
    c.bench_function("dynamics 6-DOF: forward dynamics (ABA)", |b| {
        b.iter(|| {
            model.forward_dynamics_aba(
                &mut d,
                black_box(&q),
                black_box(&qd),
                black_box(&tau),
                &mut out,
            )
        })
    });
    // 7 DOF: the Panda-style test arm (full inertia tensors, joint friction).
    let panda = evoloop::dynamics::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/robots/panda_style.urdf"),
    )
    .expect("robot loads");
    let mut d7 = panda.data();
    let q7 = [0.3, -0.5, 0.8, -1.5, 0.2, 1.3, 0.3];
    let qd7 = [0.5, 1.0, -1.0, 1.0, 1.0, 1.0, -0.5];
    let tau7 = [5.0, -20.0, 5.0, 10.0, 1.0, 1.0, 0.5];
    let mut out7 = [0.0; 7];
    c.bench_function(
        "dynamics 7-DOF: forward dynamics (RNEA + CRBA + Cholesky)",
        |b| {
            b.iter(|| {
                panda.forward_dynamics(
                    &mut d7,
                    black_box(&q7),
                    black_box(&qd7),
                    black_box(&tau7),
                    &mut out7,
                )
            })
        },
    );
    c.bench_function("dynamics 7-DOF: forward dynamics (ABA)", |b| {
        b.iter(|| {
            panda.forward_dynamics_aba(
                &mut d7,
                black_box(&q7),
                black_box(&qd7),
                black_box(&tau7),
                &mut out7,
            )
        })
    });
    let mut sim = PlantSim::new(
        Box::new(evoloop::plant::Arm::new(model.clone(), &q)),
        5e-4,
        0.0,
        1,
    );
    c.bench_function(
        "industrial6 plant: one 1 ms period (2 RK4 sub-steps)",
        |b| b.iter(|| sim.advance(black_box(&tau), 0.001)),
    );
    let mut ct = evoloop::law::ComputedTorque::new(model.clone(), &[400.0; 12], 0.03);
    let mut state = PlantState {
        n_q: 6,
        n_y: 6,
        ..Default::default()
    };
    state.y[..6].copy_from_slice(&q);
    state.qd_true[..6].copy_from_slice(&qd);
    let mut sp = evoloop::reference::Setpoint {
        n: 6,
        ..Default::default()
    };
    sp.q[..6].copy_from_slice(&[0.31, -0.49, 0.79, 0.1, 0.21, 0.3]);
    let mut u = [0.0; 6];
    c.bench_function("computed-torque law, 6-DOF", |b| {
        b.iter(|| {
            evoloop::law::Controller::step(&mut ct, black_box(&state), black_box(&sp), &mut u)
        })
    });
    // A model set checked (M(q) on 24 probes) and swapped in: what one identified model costs
    // the control cycle it arrives in.
    let pi = evoloop::identify::Columns::PLANT.values(&model);
    c.bench_function(
        "computed-torque law, 6-DOF: model set check and swap",
        |b| b.iter(|| evoloop::law::Controller::swap_model(&mut ct, black_box(&pi))),
    );
}

/// The fuzzy-network paper's hot paths: one evaluation of the 2-input 3 x 3 network (goal
/// < 100 ns), the whole 660-evaluation synthetic tuning (goal < 1 s) and one 310-evaluation GA
/// tuning of the maglev PID on 2 threads (goal < 10 s).
fn fuzzy(c: &mut Criterion) {
    use evoloop::fuzzy::arsinh;
    use evoloop::optim::hybrid::{hybrid, HybridConfig};
    use evoloop::optim::GaConfig;
    let net = arsinh::initial_network(4.0, 0.5, 0.3);
    let mut y = [0.0];
    let mut k = 0u32;
    c.bench_function(
        "fuzzy network 2 inputs 3x3, 5 output MFs: one evaluation",
        |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let x = (k % 200) as f64 / 100.0 - 1.0;
                net.eval(black_box(&[x, 0.3 - 0.5 * x]), &mut y);
                black_box(y[0])
            })
        },
    );
    let codec = arsinh::codec();
    let (lo, hi) = codec.bounds();
    let seeds: Vec<Vec<f64>> = arsinh::prespecified()
        .iter()
        .map(|n| codec.encode(n).unwrap())
        .collect();
    let obj = arsinh::Objective {
        codec: codec.clone(),
        trajectory: arsinh::default_trajectory(),
    };
    let hybrid_cfg = |threads, phases: [usize; 3], scaling: Vec<usize>| HybridConfig {
        ga: GaConfig {
            seed: 1,
            max_iterations: phases[0] + phases[1],
            ..Default::default()
        },
        phases,
        scaling,
        threads,
        hj_step: 0.05,
        hj_per_candidate: 0,
    };
    let mut group = c.benchmark_group("fuzzy tuning");
    group.sample_size(10);
    for threads in [1, 2] {
        let cfg = hybrid_cfg(threads, [95, 200, 30], codec.scaling_genes());
        group.bench_function(
            format!("arsinh: 660 evaluations, {threads} thread(s)"),
            |b| b.iter(|| black_box(hybrid(&cfg, &obj, &lo, &hi, &seeds, |_, _| {}).value)),
        );
    }
    let spec = evoloop::tune::maglev::Spec::default();
    let aw = evoloop::law::AntiWindup::Fuzzy;
    let (mlo, mhi) = aw.paper_ranges();
    let mobj = evoloop::tune::maglev::Objective {
        spec: spec.clone(),
        aw,
        seed: 1,
    };
    for threads in [1, 2] {
        let cfg = hybrid_cfg(threads, [150, 0, 0], Vec::new());
        group.bench_function(
            format!("maglev fuzzy anti-windup PID: 310 evaluations of 2.5 s, {threads} thread(s)"),
            |b| b.iter(|| black_box(hybrid(&cfg, &mobj, &mlo, &mhi, &[], |_, _| {}).value)),
        );
    }
    group.finish();
}

/// The RKGNN paper's hot paths: one N_f evaluation of the shipped 3-joint model (the paper's RBF
/// counts; goal < 2 us) and one fuzzy computed-torque step with two models (goal < 10 us).
fn rkgnn(c: &mut Criterion) {
    use evoloop::config::{ControllerModel, Overrides, Scenario};
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config");
    let m = evoloop::rkgnn_model::RkgnnModel::load(&root.join("models/arm3_train1.json")).unwrap();
    let x = [0.1, 0.7, -1.3, 0.5, -0.2, 0.3];
    let r = [0.12, 0.72, -1.28, 0.45, -0.25, 0.35];
    let mut dx = [0.0; 6];
    c.bench_function(
        "RKGNN: one N_f evaluation, 3 joints (465 parameters)",
        |b| b.iter(|| m.net.rate(black_box(&x), black_box(&r), &mut dx)),
    );
    // V-hat from M-hat's Christoffel symbols (`--velocity christoffel`): M-hat and V-hat as two
    // calls evaluate the inertia network twice; `inertia_and_velocity` once.
    let layout = evoloop::rkgnn_model::Layout::new(
        3,
        evoloop::rkgnn_model::RbfCounts {
            velocity: 0,
            ..m.net.layout.counts
        },
    );
    let params = (0..layout.len)
        .map(|k| 0.5 + 0.1 * (k as f64).sin())
        .collect();
    let chr = evoloop::rkgnn_model::Network::new(layout, params);
    let mut mm = [0.0; evoloop::MAX_JOINTS * evoloop::MAX_JOINTS];
    let mut v = [0.0; 3];
    c.bench_function("RKGNN Christoffel: M-hat, then V-hat (two passes)", |b| {
        b.iter(|| {
            chr.inertia(black_box(&x[..3]), &mut mm);
            chr.velocity(black_box(&x[..3]), black_box(&x[3..]), &mut v)
        })
    });
    c.bench_function("RKGNN Christoffel: M-hat and V-hat in one pass", |b| {
        b.iter(|| chr.inertia_and_velocity(black_box(&x[..3]), black_box(&x[3..]), &mut mm, &mut v))
    });
    let scn = Scenario::load(&root.join("arm3/arm3_fuzzy_ct.toml"), &Overrides::default()).unwrap();
    assert!(matches!(
        scn.controller.model,
        ControllerModel::FuzzyComputedTorque(_)
    ));
    let mut ctl = scn.build_controller();
    let mut state = PlantState {
        t: 2.5,
        ..Default::default()
    };
    state.y[..3].copy_from_slice(&x[..3]);
    state.qd_true[..3].copy_from_slice(&x[3..]);
    let mut sp = evoloop::reference::Setpoint::default();
    scn.reference.sample(2.5, &mut sp);
    let mut u = [0.0; 3];
    c.bench_function("fuzzy computed torque: one step, two models (max)", |b| {
        b.iter(|| ctl.step(black_box(&state), black_box(&sp), &mut u))
    });
}

/// One fitness evaluation of an excitation trajectory (eq. 15): the 6-DOF arm's base regressor
/// stacked over 100 instants of a 10 s trajectory (600 x 52, every joint moving, friction and
/// armature columns) and its singular values, as the eMuPSO search evaluates it.
fn identify(c: &mut Criterion) {
    use evoloop::identify::excitation::{ExcitationProblem, Settings};
    use evoloop::identify::{Stage, StageKind};
    use evoloop::optim::Objective;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let model = evoloop::dynamics::load(&root.join("config/robots/industrial6.toml")).unwrap();
    let stage = Stage::new(StageKind::All, &model).unwrap();
    let p = ExcitationProblem::new(model, stage, Settings::default()).unwrap();
    // The shipped optimised trajectory (feasible, so the objective does the whole SVD).
    let text =
        std::fs::read_to_string(root.join("config/excitation/industrial6_all.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let s = serde_json::from_value(v["series"].clone()).unwrap();
    let x = p.design.encode(&s);
    c.bench_function(
        "excitation fitness: base regressor of 100 instants (600 x 52)",
        |b| b.iter(|| black_box(p.base_regressor(black_box(&s)))),
    );
    c.bench_function(
        "excitation fitness: eq. 15 with the SVD and the limit check",
        |b| b.iter(|| black_box(p.criteria(black_box(&s)))),
    );
    c.bench_function(
        "excitation fitness: objective value (as the search calls it)",
        |b| b.iter(|| black_box(p.value(black_box(&x)))),
    );
}

criterion_group!(benches, control, robust, dynamics, fuzzy, rkgnn, identify);
criterion_main!(benches);
