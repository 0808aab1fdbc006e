//! A port attaching to a running loop (a viewer, a bridge) and the loop's allocations: apart
//! from tests/no_alloc.rs, since the allocation count is the process's and those tests would
//! see this one's deliberate allocation.

use evoloop::ipc::{Ipc, Topic};
use evoloop::msg::{ParamKind, ParamSet, Telemetry};
use evoloop::rt::alloc_count::{self as counting_alloc, COUNT};
use std::sync::atomic::Ordering;

#[global_allocator]
static A: counting_alloc::Counting = counting_alloc::Counting;

/// What a loop does when a port attaches to a running run (a viewer, a bridge): iceoryx2
/// connects on the next send or receive, which allocates, unless the loop has called
/// `update_connections` first, as the controller does just before each cycle. Measured both
/// ways on the same ports, so the test could fail: without the call the send allocates.
#[test]
fn a_port_attaching_is_connected_before_the_cycle_not_in_it() {
    let run_id = format!("noallocattach{}", std::process::id());
    let ipc = Ipc::new("noallocloop", &run_id, evoloop::ipc::DEFAULT_PREFIX).unwrap();
    let tel = ipc.publisher::<Telemetry>(Topic::Telemetry, false).unwrap();
    let params = ipc.subscriber::<ParamSet>(Topic::Params, 4, false).unwrap();
    let viewer = Ipc::new("noallocviewer", &run_id, evoloop::ipc::DEFAULT_PREFIX).unwrap();
    let set = ParamSet::new(1, 0, ParamKind::StateFeedback, &[1.0; 5]);
    let cycle = |what: &mut dyn FnMut()| {
        let before = COUNT.load(Ordering::Relaxed);
        counting_alloc::arm();
        what();
        counting_alloc::disarm();
        COUNT.load(Ordering::Relaxed) - before
    };
    let mut step = || {
        tel.send(&Telemetry::default()).unwrap();
        while params.next().unwrap().is_some() {}
    };
    step();
    assert_eq!(cycle(&mut step), 0, "the warmed-up cycle allocates");

    // A subscriber of telemetry attaches; the cycle's own send connects it.
    let _watcher = viewer
        .subscriber::<Telemetry>(Topic::Telemetry, 4, false)
        .unwrap();
    let unprepared = cycle(&mut step);
    assert!(
        unprepared > 0,
        "connecting allocated nothing: this test shows nothing"
    );

    // Another subscriber and a publisher of sets attach; connected before the cycle.
    let _watcher2 = viewer
        .subscriber::<Telemetry>(Topic::Telemetry, 4, false)
        .unwrap();
    let setter = viewer.publisher::<ParamSet>(Topic::Params, false).unwrap();
    tel.update_connections().unwrap();
    params.update_connections().unwrap();
    assert_eq!(cycle(&mut step), 0, "the cycle connected a port itself");
    // The new publisher's first set is received within a cycle without allocating either.
    setter.send(&set).unwrap();
    assert_eq!(
        cycle(&mut step),
        0,
        "receiving from the new publisher allocated"
    );
}
