//! The arm's hot paths do not allocate: the 6-DOF plant's integration (forward dynamics in every
//! RK4 stage), the computed-torque cycle with a quintic reference and a parameter swap, and the
//! Coriolis matrix, the joint-torque regressor (with friction columns) and ABA, and a model swap
//! (a computed-torque model set checked on its probes); state, command and telemetry go through
//! iceoryx2 every cycle as in a run, and into run.mcap's recorder. The same for the computed
//! torque with fuzzy model selection, and the P-D servo with gravity compensation.
//! (A separate test binary: the counting allocator is process-global.)

use evoloop::config::{Overrides, Scenario};
use evoloop::ipc::{Ipc, Pub, Sub, Topic};
use evoloop::law::cycle::ControlCycle;
use evoloop::msg::{Command, ParamSet, PlantState, Telemetry};
use evoloop::plant::PlantSim;
use evoloop::report::record::Recorder;
use std::sync::atomic::Ordering;

use evoloop::rt::alloc_count::{self as counting_alloc, COUNT};

#[global_allocator]
static A: counting_alloc::Counting = counting_alloc::Counting;

/// The three streams of a run's control cycle, both ends in this process.
struct Wires {
    state: (Pub<PlantState>, Sub<PlantState>),
    command: (Pub<Command>, Sub<Command>),
    telemetry: (Pub<Telemetry>, Sub<Telemetry>),
    /// run.mcap's recorder, as the controller process feeds it every cycle.
    record: std::cell::RefCell<Recorder>,
    _dir: tempfile::TempDir,
    _ipc: Ipc,
}

impl Wires {
    fn new(tag: &str) -> Wires {
        let run_id = format!("noallocarm{tag}{}", std::process::id());
        let ipc = Ipc::new("noallocarm", &run_id, evoloop::ipc::DEFAULT_PREFIX).unwrap();
        let dir = tempfile::tempdir().unwrap();
        Wires {
            state: (
                ipc.publisher(Topic::State, true).unwrap(),
                ipc.subscriber(Topic::State, 4, true).unwrap(),
            ),
            command: (
                ipc.publisher(Topic::Command, true).unwrap(),
                ipc.subscriber(Topic::Command, 4, true).unwrap(),
            ),
            telemetry: (
                ipc.publisher(Topic::Telemetry, false).unwrap(),
                ipc.subscriber(Topic::Telemetry, 4, false).unwrap(),
            ),
            record: std::cell::RefCell::new(
                Recorder::start(
                    &dir.path().join("run.mcap"),
                    true,
                    Default::default(),
                    None,
                    vec!["j1".into(), "j2".into(), "j3".into()],
                )
                .unwrap(),
            ),
            _dir: dir,
            _ipc: ipc,
        }
    }

    /// Close the recording: messages per topic.
    fn finish(self) -> Vec<u64> {
        let r = self.record.into_inner().finish();
        assert_eq!((r.dropped, r.error), (0, None));
        r.messages
    }

    /// The plant's sample to the controller, its command back, its telemetry out.
    fn cycle(&self, msg: &PlantState, cyc: &mut ControlCycle, tel: &mut Telemetry, u: &mut [f64]) {
        self.state.0.send(msg).unwrap();
        let s = self.state.1.next().unwrap().unwrap();
        let mut record = self.record.borrow_mut();
        record.at_state(&s, s.seq);
        cyc.step(&s, tel);
        let c = Command {
            cycle: s.seq,
            state_seq: s.seq,
            u: cyc.u,
            n_u: u.len() as u32,
            ..Default::default()
        };
        self.command.0.send(&c).unwrap();
        self.telemetry.0.send(tel).unwrap();
        record.cycle(&s, &c, tel);
        let got = self.command.1.next().unwrap().unwrap();
        u.copy_from_slice(&got.u[..u.len()]);
        while self.telemetry.1.next().unwrap().is_some() {}
    }
}

fn scenario(name: &str) -> Scenario {
    let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("config/{name}.toml"));
    Scenario::load(&cfg, &Overrides::default()).unwrap()
}

/// One test: the allocator count is process-global, so the two laws are measured one after the
/// other, never in parallel.
#[test]
fn arm_plant_and_computed_torque_cycles_allocate_nothing() {
    computed_torque();
    fuzzy_computed_torque(scenario("arm3/arm3_fuzzy_ct"), "fuzzy");
    // The evidence rule: its filter, its residuals (a model evaluation and a solve) and the
    // per-joint weights, every cycle.
    let cfg =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/arm3/arm3_fuzzy_ct.toml");
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("selection = \"max\"", "selection = \"evidence\"");
    let scn = Scenario::parse(&text, &cfg, &Overrides::default()).unwrap();
    let rule = serde_json::to_value(&scn.controller).unwrap();
    assert_eq!(rule["selection"], "evidence", "{rule}");
    fuzzy_computed_torque(scn, "evidence");
    pd_servo_with_gravity_compensation();
}

/// The P-D servo with a model's gravity torque (`gravity_model`): G(q) every cycle.
fn pd_servo_with_gravity_compensation() {
    let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/arm3/arm3_train1.toml");
    let text = std::fs::read_to_string(&cfg).unwrap().replace(
        "kd = [15.0, 20.0, 8.0]",
        "kd = [15.0, 20.0, 8.0]\ngravity_model = \"../robots/arm3.urdf\"",
    );
    let scn = Scenario::parse(&text, &cfg, &Overrides::default()).unwrap();
    assert!(serde_json::to_value(&scn.controller).unwrap()["gravity_model"].is_object());
    let mut plant = PlantSim::new(scn.build_plant(), scn.plant.step, 1e-4, 3);
    let mut cyc = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    let (mut msg, mut tel) = (PlantState::default(), Telemetry::default());
    let mut u = [0.0; 3];
    plant.sample(0, 0, &u, &mut msg);
    cyc.step(&msg, &mut tel);
    counting_alloc::arm();
    for k in 1..2000u64 {
        plant.sample(k, 0, &u, &mut msg);
        cyc.step(&msg, &mut tel);
        u.copy_from_slice(&cyc.u[..3]);
        plant.advance(&u, scn.timing.period);
    }
    counting_alloc::disarm();
    assert_eq!(
        COUNT.load(Ordering::SeqCst),
        0,
        "allocations in 2000 P-D + gravity cycles"
    );
}

fn computed_torque() {
    let scn = scenario("industrial6/industrial6_ct");
    let model = scn.plant.model.config().rigid_body().unwrap().clone();
    let mut plant = PlantSim::new(scn.build_plant(), scn.plant.step, 1e-4, 3);
    let mut cyc = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    cyc.offer(&ParamSet::new(
        1,
        500,
        scn.controller.param_kind(),
        &[300.0; 12],
    ));
    // A model set (the controller's rigid-body parameters, checked on its probes) later on.
    let pi = evoloop::identify::Columns::PLANT.values(&model);
    cyc.offer(&ParamSet::new(
        2,
        1000,
        evoloop::msg::ParamKind::RigidBodyModel,
        &pi,
    ));
    let mut msg = PlantState::default();
    let mut tel = Telemetry::default();
    let mut d = model.data();
    let mut c = nalgebra::DMatrix::zeros(6, 6);
    let mut y = nalgebra::DMatrix::zeros(6, model.regressor_columns(true));
    let dt = scn.timing.period;
    let wires = Wires::new("ct");
    let mut u = [0.0; 6];
    // One warm-up cycle: iceoryx2 connects lazily and the loan pool takes its blocks.
    plant.sample(0, 0, &u, &mut msg);
    wires.cycle(&msg, &mut cyc, &mut tel, &mut u);
    counting_alloc::arm();
    for k in 1..2000u64 {
        plant.sample(k, 0, &u, &mut msg);
        wires.cycle(&msg, &mut cyc, &mut tel, &mut u);
        plant.advance(&u, dt);
        if k % 100 == 0 {
            model.coriolis_matrix(&mut d, &msg.q_true[..6], &msg.qd_true[..6], &mut c);
            let (q, qd) = (&msg.q_true[..6], &msg.qd_true[..6]);
            model.regressor(&mut d, q, qd, qd, &mut y);
            let mut qdd = [0.0; 6];
            model
                .forward_dynamics_aba(&mut d, q, qd, &u[..6], &mut qdd)
                .unwrap();
        }
    }
    counting_alloc::disarm();
    assert_eq!(
        cyc.version(),
        2,
        "both swaps (gains, model) happened inside the measured cycles"
    );
    assert_eq!(
        COUNT.load(Ordering::SeqCst),
        0,
        "allocations in 2000 arm cycles"
    );
    // The recorder had every cycle's state, command and telemetry (the warm-up's too).
    let m = wires.finish();
    assert_eq!(
        [m[0], m[1], m[2], m[5]],
        [2000; 4],
        "state, command, telemetry, joint_states"
    );
}

fn fuzzy_computed_torque(scn: Scenario, name: &str) {
    let n = scn.plant.model.config().rigid_body().unwrap().dof();
    let mut plant = PlantSim::new(scn.build_plant(), scn.plant.step, 1e-4, 3);
    let mut cyc = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    let (mut msg, mut tel) = (PlantState::default(), Telemetry::default());
    let wires = Wires::new(name);
    let mut u = vec![0.0; n];
    plant.sample(0, 0, &u, &mut msg);
    wires.cycle(&msg, &mut cyc, &mut tel, &mut u);
    counting_alloc::arm();
    for k in 1..3000u64 {
        plant.sample(k, 0, &u, &mut msg);
        wires.cycle(&msg, &mut cyc, &mut tel, &mut u);
        plant.advance(&u, scn.timing.period);
    }
    counting_alloc::disarm();
    assert!(msg.t > 2.9 * scn.timing.period * 1000.0, "the run advanced");
    assert_eq!(
        COUNT.load(Ordering::SeqCst),
        0,
        "allocations in 3000 fuzzy computed-torque cycles ({name})"
    );
    let m = wires.finish();
    assert_eq!(
        [m[0], m[1], m[2], m[5]],
        [3000; 4],
        "state, command, telemetry, joint_states"
    );
}
