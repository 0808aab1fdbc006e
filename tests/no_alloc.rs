//! The control cycle does not allocate: a counting global allocator watches the plant step, the
//! controller cycle (state feedback on its Kalman filter, with a parameter swap in it), the run log streamed to disk, the timing
//! statistics and the iceoryx2 send/receive of state, command and telemetry, after the set-up
//! allocated everything once; and, as for a linear plant under the indirect scheme, the
//! optimiser's model estimates received and adopted, and every set checked for stability on the
//! configured model and on the adopted estimate.
//!
//! IPC included: iceoryx2 0.10's stock `ipc::Service` allocates one reference-count block per
//! loaned sample (`ChunkMutSharedState::new`, an `Rc`); evoloop's service type keeps those blocks
//! in a per-thread pool (`evoloop::ipc::pooled`), so after the warm-up cycle no send touches the
//! heap. The pool's own counters show every loan served from its free list.

use evoloop::ipc::{Ipc, Topic};
use evoloop::law::cycle::ControlCycle;
use evoloop::law::model_check::ModelCheck;
use evoloop::law::{ParamBounds, StateFeedback};
use evoloop::msg::{Command, ModelEstimate, ParamCode, ParamKind, ParamSet, PlantState, Telemetry};
use evoloop::plant::two_mass::{Sensor, TwoMass};
use evoloop::plant::PlantSim;
use evoloop::reference::Reference;
use evoloop::report::stream::{CsvPart, LogStream, Overflow};
use evoloop::rt::{CycleTiming, TimingStats};
use std::sync::atomic::{AtomicU64, Ordering};

static SENDS: AtomicU64 = AtomicU64::new(0);

/// Send through iceoryx2, counting the sends (each is one loan from the pool).
fn send<T: evoloop::ipc::Message>(p: &evoloop::ipc::Pub<T>, v: &T) {
    SENDS.fetch_add(1, Ordering::Relaxed);
    p.send(v).unwrap();
}

use evoloop::rt::alloc_count::{self as counting_alloc, COUNT};

#[global_allocator]
static A: counting_alloc::Counting = counting_alloc::Counting;

#[test]
fn the_control_cycle_allocates_nothing() {
    let run_id = format!("noalloc{}", std::process::id());
    let ipc = Ipc::new("noalloc", &run_id, evoloop::ipc::DEFAULT_PREFIX).unwrap();
    let st_pub = ipc.publisher::<PlantState>(Topic::State, true).unwrap();
    let st_sub = ipc.subscriber::<PlantState>(Topic::State, 4, true).unwrap();
    let cmd_pub = ipc.publisher::<Command>(Topic::Command, true).unwrap();
    let cmd_sub = ipc.subscriber::<Command>(Topic::Command, 4, true).unwrap();
    let tel_pub = ipc.publisher::<Telemetry>(Topic::Telemetry, false).unwrap();
    let par_sub = ipc.subscriber::<ParamSet>(Topic::Params, 4, false).unwrap();
    let est_pub = ipc
        .publisher::<ModelEstimate>(Topic::Estimate, false)
        .unwrap();
    let est_sub = ipc
        .subscriber::<ModelEstimate>(Topic::Estimate, 4, false)
        .unwrap();
    let scn = evoloop::config::Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("config/two_mass/two_mass_indirect.toml"),
        &evoloop::config::Overrides::default(),
    )
    .unwrap();
    let mut model_check = ModelCheck::new(&scn.plant.model).unwrap();

    let dt = 0.001;
    let gains = [18.49, 19.04, 47.27, 7.30, -10.54];
    let mut plant = PlantSim::new(
        Box::new(TwoMass::new(1.0, 1.0, 1.0, Sensor::Far)),
        5e-4,
        0.01,
        1,
    );
    let bounds = ParamBounds {
        lower: vec![-100.0; 5],
        upper: vec![100.0; 5],
    };
    // The law on the default scenario's filter, as its controller runs it, told of a sensor
    // 100 samples late (the filter's input ring and its prediction across them).
    let default = evoloop::config::Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/two_mass/two_mass.toml"),
        &evoloop::config::Overrides::default(),
    )
    .unwrap();
    let kalman = match &default.controller.model {
        evoloop::law::ControllerModel::StateFeedback(sf) => sf
            .kalman_gains()
            .expect("two_mass runs on its filter")
            .clone(),
        _ => unreachable!("two_mass is state feedback"),
    };
    let mut cyc = ControlCycle::new(
        Box::new(StateFeedback::new(&gains, dt, Some(100.0)).with_kalman(&kalman, 100)),
        Reference::Steps {
            times: vec![0.1, 1.0],
            values: vec![1.0, 0.5],
        },
        bounds,
    )
    .with_stability_check(Some(
        TwoMass::new(1.0, 1.0, 1.0, Sensor::Far).linear_model(),
    ));
    let n = 3000;
    // The log streamed to disk as the controller does it (its writer thread allocates as it
    // formats; the counter watches this thread only, the control thread).
    let dir = tempfile::tempdir().unwrap();
    let part = CsvPart {
        path: dir.path().join("run.csv"),
        header: (0..7).map(|i| format!("c{i}")).collect(),
        columns: 0..7,
    };
    let mut log = LogStream::start(vec![part], 256, Overflow::Wait).unwrap();
    let mut timing = TimingStats::default();
    let mut row = [0.0; 7];
    let set = ParamSet::new(
        1,
        1500,
        ParamKind::StateFeedback,
        &[12.1946, 11.7906, 18.7567, 4.958, -10.0],
    );
    let mut msg = PlantState::default();
    let mut tel = Telemetry::default();
    let mut u = [0.0];
    let mut trials_ended = 0;

    // One warm-up cycle lets iceoryx2 set up its connections (lazily, on first send/receive).
    let mut cycle = |k: u64, cyc: &mut ControlCycle, plant: &mut PlantSim| {
        plant.sample(k, evoloop::rt::now_ns(), &u, &mut msg);
        send(&st_pub, &msg);
        let s = st_sub.next().unwrap().unwrap();
        while let Some(p) = par_sub.next().unwrap() {
            cyc.offer(&p);
        }
        // The optimiser's 10 Hz estimate (sent here, outside what the controller does).
        if k.is_multiple_of(100) {
            let e = ModelEstimate {
                value: 1.0 + k as f64 * 1e-4,
                apply_at_seq: k + 1,
                ..Default::default()
            };
            send(&est_pub, &e);
        }
        while let Some(e) = est_sub.next().unwrap() {
            model_check.offer(&e);
        }
        let adopted = model_check.due(s.seq);
        if let Some(m) = adopted {
            cyc.check_on(m);
        }
        if cyc.step(&s, &mut tel).map(|e| e.code) == Some(ParamCode::TrialEnded) {
            trials_ended += 1;
        }
        // The law's filter designed again on the adopted estimate, as the controller does
        // once the command is out.
        if let Some(m) = adopted {
            cyc.redesign_on(&m);
        }
        let c = Command {
            cycle: k,
            state_seq: s.seq,
            u: cyc.u,
            n_u: 1,
            ..Default::default()
        };
        send(&cmd_pub, &c);
        send(&tel_pub, &tel);
        let got = cmd_sub.next().unwrap().unwrap();
        u[0] = got.u[0];
        plant.advance(&u, dt);
        row[0] = s.t;
        row[1] = tel.reference;
        row[2] = s.y[0];
        row[3] = u[0];
        log.push(&row);
        timing.record(&CycleTiming {
            cycle: k,
            lateness_ns: 1000 + k as i64,
            ..Default::default()
        });
    };
    cycle(0, &mut cyc, &mut plant);
    cyc.offer(&set);
    // A trial (the direct scheme's) of one 500-sample repetition falling back to it: taking the
    // trial in, saving the law's state and restoring the fallback allocate nothing either.
    let trial = ParamSet {
        until_seq: 2500,
        fallback_version: 1,
        ..ParamSet::new(
            2,
            2000,
            ParamKind::StateFeedback,
            &[15.0, 15.0, 30.0, 6.0, -10.0],
        )
    };
    cyc.offer(&trial);
    SENDS.store(0, Ordering::SeqCst);
    let pool_before = evoloop::ipc::pooled::stats();
    counting_alloc::arm();
    for k in 1..n as u64 {
        cycle(k, &mut cyc, &mut plant);
    }
    counting_alloc::disarm();
    let allocations = COUNT.load(Ordering::SeqCst);
    let sends = SENDS.load(Ordering::SeqCst);
    let pool = evoloop::ipc::pooled::stats();
    assert_eq!(
        cyc.version(),
        1,
        "the swap happened inside the measured cycles, and the trial ended back on it"
    );
    assert_eq!(trials_ended, 1);
    assert_eq!(sends, 3 * (n as u64 - 1) + (n as u64 - 1) / 100);
    // 29 in the measured cycles, one in the warm-up; and the filter designed on each.
    assert_eq!(model_check.report().adopted, 30);
    assert_eq!((cyc.filters_designed, cyc.filters_refused), (30, 0));
    assert_eq!(timing.cycles(), n as u64);
    assert_eq!(log.finish().rows, n as u64, "every row reached the file");
    assert_eq!(
        pool.reused - pool_before.reused,
        sends,
        "every send's loan state came from the pool"
    );
    assert_eq!(pool.from_heap, pool_before.from_heap);
    assert_eq!(
        allocations,
        0,
        "{allocations} allocations in {} control cycles with {sends} iceoryx2 sends",
        n - 1
    );
}

/// An arm's computed torque on velocities it estimates from its encoders (`velocity =
/// "filtered"`) or by its model-based observer (`velocity = "observer"`, a forward-dynamics
/// pass of the law's model each cycle): neither estimator's update allocates in the cycle.
#[test]
fn computed_torque_on_estimated_velocities_allocates_nothing() {
    use evoloop::law::estimator::VelocitySource;
    use evoloop::law::{ComputedTorque, Controller};
    let scn = evoloop::config::Scenario::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/arm3/arm3_ct.toml"),
        &evoloop::config::Overrides::default(),
    )
    .unwrap();
    let model = match &scn.controller.model {
        evoloop::law::ControllerModel::ComputedTorque(spec) => spec.model.clone(),
        _ => unreachable!("arm3_ct is computed torque"),
    };
    let n = model.dof();
    for source in [
        VelocitySource::Filtered { cutoff_hz: 50.0 },
        VelocitySource::Observer {
            bandwidth_hz: 50.0,
            delay: 0,
        },
        // Across a late sensor: the torque ring and the prediction to the present.
        VelocitySource::Observer {
            bandwidth_hz: 50.0,
            delay: 10,
        },
    ] {
        let mut ct = ComputedTorque::new(model.clone(), &vec![100.0; 2 * n], 0.03)
            .with_velocity(source, 0.001);
        let mut state = PlantState {
            n_q: n as u32,
            n_y: n as u32,
            ..Default::default()
        };
        let sp = evoloop::reference::Setpoint {
            n,
            ..Default::default()
        };
        let mut u = vec![0.0; n];
        let mut step = |k: u64, ct: &mut ComputedTorque, state: &mut PlantState| {
            state.seq = k;
            for (i, y) in state.y[..n].iter_mut().enumerate() {
                *y = 0.1 * (i as f64 + 1.0) * (k as f64 * 1e-3).sin();
            }
            state.u_applied[..n].copy_from_slice(&u);
            ct.step(state, &sp, &mut u);
        };
        step(0, &mut ct, &mut state);
        let before = COUNT.load(Ordering::SeqCst);
        counting_alloc::arm();
        for k in 1..2000 {
            step(k, &mut ct, &mut state);
        }
        counting_alloc::disarm();
        assert_eq!(
            COUNT.load(Ordering::SeqCst) - before,
            0,
            "{source:?}: allocations in 1999 cycles"
        );
    }
}
