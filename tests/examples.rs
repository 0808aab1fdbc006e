//! The examples (`cargo run --example NAME`) do what they say: each one's `run` is called here
//! and its figures judged against what the example claims.

#[path = "../examples/custom_optimiser.rs"]
mod custom_optimiser;
#[path = "../examples/custom_plant.rs"]
mod custom_plant;
#[path = "../examples/dynamics_library.rs"]
mod dynamics_library;

#[test]
fn a_plant_of_your_own_matches_its_closed_form_and_your_pi_holds_its_set_point_bumplessly() {
    let o = custom_plant::run();
    // RK4 at a quarter of a millisecond on a 0.5 s time constant: far below 1e-9 rad/s.
    assert!(o.open_loop_error < 1e-9, "{o:?}");
    // PI: no steady-state error on a constant set-point (10 rad/s), well within 5 s.
    assert!((o.final_speed - 10.0).abs() < 1e-3, "{o:?}");
    assert!(o.swap_bump < 1e-9, "{o:?}");
}

#[test]
fn an_optimiser_of_your_own_runs_the_ask_tell_loop_as_evoloops_own() {
    let (es, de) = custom_optimiser::run();
    // Both reach the sphere's minimum (0) closely within 20 000 evaluations.
    assert!(es < 1e-10, "(1+1)-ES {es}");
    assert!(de < 1e-6, "DE {de}");
}

#[test]
fn the_dynamics_library_is_consistent_on_the_shipped_7_dof_arm() {
    let robot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("config/robots/arm7.urdf");
    let c = dynamics_library::run(&robot).unwrap();
    assert_eq!(c.joints, 7);
    assert!(c.positive_definite, "{c:?}");
    assert!(c.asymmetry < 1e-12, "{c:?}");
    assert!(c.round_trip < 1e-9, "{c:?}");
    assert!(c.gravity < 1e-12, "{c:?}");
    // A file that is not a robot is refused with a reason, not a panic.
    assert!(dynamics_library::run(std::path::Path::new("no_such.urdf")).is_err());
}
