//! A model larger than one parameter set (arm7's identified models: 3395 parameters, a set
//! carries 1024 values) over the ports the optimiser and controller processes make: sent as
//! `ParamKind::ModelPart` sets (`rkgnn::live::ModelUpdate::sets`), received in order through
//! the controller's params subscriber, gathered by the controller's cycle and put in service
//! whole, at its last part, after the law's checks.
use crate::common;

use evoloop::config::{Overrides, Scenario};
use evoloop::ipc::{Ipc, Topic};
use evoloop::law::ControlCycle;
use evoloop::msg::{ParamCode, ParamKind, ParamSet, PlantState, Telemetry, MAX_PARAMS};
use evoloop::rkgnn::live::ModelUpdate;
use evoloop::rkgnn_model::RkgnnModel;

fn arm7() -> Scenario {
    Scenario::load(
        &common::config("arm7/arm7_fuzzy_ct.toml"),
        &Overrides::default(),
    )
    .unwrap()
}

/// `cycle` on a state near the reference's start for one cycle per set in `sets`: the events.
fn run(cycle: &mut ControlCycle, scn: &Scenario, sets: &[ParamSet]) -> Vec<Option<ParamCode>> {
    sets.iter().for_each(|s| cycle.offer(s));
    let mut sp = evoloop::reference::Setpoint::default();
    scn.reference.sample(0.0, &mut sp);
    let mut state = PlantState::default();
    state.y[..7].copy_from_slice(&sp.q[..7]);
    state.y[0] += 0.01;
    (0..sets.len())
        .map(|seq| {
            state.seq = seq as u64;
            cycle
                .step(&state, &mut Telemetry::default())
                .map(|e| e.code)
        })
        .collect()
}

#[test]
fn an_arm7_model_crosses_the_processes_ports_in_parts_and_is_applied_whole() {
    let (prefix, run_id) = common::unique("parts");
    let model = RkgnnModel::load(&common::config("models/arm7_train2.json")).unwrap();
    let mut values = vec![0.0];
    values.extend_from_slice(model.net.params());
    assert!(
        values.len() > MAX_PARAMS,
        "{} values fit one set",
        values.len()
    );
    let update = ModelUpdate {
        version: 1,
        apply_at_seq: 0,
        expected_cost: 0.5,
        values: values.clone(),
    };
    // The optimiser's publisher and the controller's subscriber, as the nodes make them.
    let optimiser = Ipc::new("evoloop-optimiser", &run_id, &prefix).unwrap();
    let controller = Ipc::new("evoloop-controller", &run_id, &prefix).unwrap();
    let publisher = optimiser
        .publisher::<ParamSet>(Topic::Params, false)
        .unwrap();
    let subscriber = controller
        .subscriber::<ParamSet>(Topic::Params, evoloop::law::cycle::PENDING_CAPACITY, false)
        .unwrap();
    let sent = update.sets();
    assert_eq!(sent.len(), 4);
    for s in &sent {
        publisher.send(s).unwrap();
    }
    let mut received = Vec::new();
    while let Some(s) = subscriber.next().unwrap() {
        received.push(s);
    }
    assert_eq!(received, sent, "every part, in order, bit for bit");
    // The parts carry the model and nothing else: kind, offset and length, then the values.
    let mut gathered = Vec::new();
    for s in &received {
        let v = s.values();
        assert_eq!(s.param_kind(), Ok(ParamKind::ModelPart));
        assert_eq!((s.version, s.expected_cost), (1, 0.5));
        assert_eq!(v[0], ParamKind::RkgnnModel.code() as f64);
        assert_eq!((v[1], v[2]), (gathered.len() as f64, values.len() as f64));
        gathered.extend_from_slice(&v[3..]);
    }
    assert_eq!(gathered, values);

    // The controller's cycle, built from the scenario as the controller process builds it.
    let scn = arm7();
    let mut cycle = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    let events = run(&mut cycle, &scn, &received);
    assert_eq!(events, [None, None, None, Some(ParamCode::Accepted)]);
    assert_eq!(cycle.version(), 1);
    // The same parts again: stale, refused once; the version in service stays.
    let events = run(&mut cycle, &scn, &received);
    assert_eq!(events, [Some(ParamCode::RejectedStale), None, None, None]);
    assert_eq!(cycle.version(), 1);
}

/// Identification alongside operation takes arm7's models now (it refused them before: "does
/// not fit a parameter set").
#[test]
fn identify_mode_takes_arm7_models_larger_than_a_set() {
    let config = common::config("");
    let text = std::fs::read_to_string(common::config("arm7/arm7_fuzzy_ct.toml"))
        .unwrap()
        .replace("mode = \"off\"", "mode = \"identify\"")
        .replace("\"../models/", &format!("\"{}/models/", config.display()))
        .replace("\"../robots/", &format!("\"{}/robots/", config.display()));
    let dir = tempfile::tempdir().unwrap();
    let path = common::write(dir.path(), "arm7_identify.toml", &text);
    let scn = Scenario::load(&path, &Overrides::default()).unwrap();
    assert_eq!(scn.optimiser.mode, evoloop::config::OptimiserMode::Identify);
}

/// A law that takes no model (arm3's P-D servo) refuses a model in parts once, at its first
/// part, and keeps its gains.
#[test]
fn a_law_without_models_refuses_a_model_in_parts_once() {
    let scn = Scenario::load(&common::config("arm3/arm3_pd.toml"), &Overrides::default()).unwrap();
    let mut cycle = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    let gains = cycle.controller.params().to_vec();
    let sets = ParamSet::model_sets(1, 0, f64::NAN, ParamKind::RkgnnModel, &[0.5; 3000]);
    assert_eq!(sets.len(), 3);
    let mut events = Vec::new();
    for s in &sets {
        cycle.offer(s);
        let e = cycle.step(&PlantState::default(), &mut Telemetry::default());
        events.push(e.map(|e| e.code));
    }
    assert_eq!(events, [Some(ParamCode::RejectedWrongKind), None, None]);
    assert_eq!(cycle.controller.params(), gains);
    assert_eq!(cycle.version(), 0);
}
