//! The arm's hot paths do not allocate: the 6-DOF plant's integration (forward dynamics in every
//! RK4 stage), the computed-torque cycle with a quintic reference and a parameter swap, and the
//! Coriolis matrix, the joint-torque regressor (with friction columns) and ABA, and a model swap
//! (a computed-torque model set checked on its probes). (A separate test binary: the counting allocator is process-global.)

use evoloop::config::{Overrides, Scenario};
use evoloop::control::cycle::ControlCycle;
use evoloop::msg::{ParamSet, PlantState, Telemetry};
use evoloop::plant::PlantSim;
use std::sync::atomic::Ordering;

#[path = "common/counting_alloc.rs"]
mod counting_alloc;
use counting_alloc::COUNT;

#[global_allocator]
static A: counting_alloc::Counting = counting_alloc::Counting;

#[test]
fn arm_plant_and_computed_torque_cycle_allocate_nothing() {
    let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/industrial6_ct.toml");
    let scn = Scenario::load(&cfg, &Overrides::default()).unwrap();
    let model = scn.plant.model.config().rigid_body().unwrap().clone();
    let mut plant = PlantSim::new(scn.build_plant(), scn.plant.step, 1e-4, 3);
    let mut cyc = ControlCycle::new(scn.build_controller(), scn.reference.clone(), scn.bounds());
    let mut set = ParamSet {
        version: 1,
        apply_at_seq: 500,
        kind: scn.controller.param_kind(),
        n: 12,
        ..Default::default()
    };
    set.values[..12].copy_from_slice(&[300.0; 12]);
    cyc.offer(&set);
    // A model set (the controller's rigid-body parameters, checked on its probes) later on.
    let pi = evoloop::identify::Columns::PLANT.values(&model);
    let mut model_set = ParamSet {
        version: 2,
        apply_at_seq: 1000,
        kind: evoloop::msg::KIND_RIGID_BODY_MODEL,
        n: pi.len() as u32,
        ..Default::default()
    };
    model_set.values[..pi.len()].copy_from_slice(&pi);
    cyc.offer(&model_set);
    let mut msg = PlantState::default();
    let mut tel = Telemetry::default();
    let mut d = model.data();
    let mut c = nalgebra::DMatrix::zeros(6, 6);
    let mut y = nalgebra::DMatrix::zeros(6, model.regressor_columns(true));
    let dt = scn.timing.period;
    counting_alloc::arm();
    for k in 0..2000u64 {
        plant.sample(k, 0, &cyc.u[..6], &mut msg);
        cyc.step(&msg, &mut tel);
        let u = cyc.u;
        plant.advance(&u[..6], dt);
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
}
