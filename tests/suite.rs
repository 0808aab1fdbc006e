//! The integration tests that can share one process, as one test binary: each file below is a
//! module (`cargo test --release --test suite lti::` runs tests/lti.rs alone). One binary instead
//! of one per file: each of these files was linked against the whole library and compiled
//! iceoryx2's generics again (a 3.9 s floor a binary, up to 20 s), and libtest ran the files one
//! after the other, each leaving a core idle behind its slowest test; here all of them share the
//! binary's threads (two a core, below). Files that cannot share a process have targets of their
//! own in Cargo.toml: a counting global allocator (`no_alloc*`, `optim_no_alloc`, `recorder_memory`), a memory peak
//! taken over every child of the process (`long_report`: a spawned child's peak includes its
//! parent's resident set, which a binary of 40 files running beside it makes 180 MiB), the shared
//! memory a soak finds left under the default prefix, which other tests' runs share (`soak`), the
//! `zenoh` feature's (`zenoh_*`, `ros2_bridge`), and those with a realtime run judged on its rate,
//! which keep their binary's other heavy tests from running beside it (`common::alone`).
//! `tests/suite.rs`'s own test checks that every file in tests/ is one or the other.

mod common;

mod config_errors;
mod direct;
mod dynamics;
mod dynamics_cli;
mod estimator;
mod examples;
mod faults;
mod foxglove_decode;
mod full_disk;
mod fuzz_loaders;
mod fuzzy;
mod heater;
mod hooke_jeeves;
mod identify;
mod identify_cli;
mod layers;
mod live_view;
mod lockstep;
mod lti;
mod model_check;
mod model_parts;
mod numerics;
mod operator;
mod optim_cli;
mod param_swap;
mod plant_contract;
mod python_interop;
mod python_plant;
mod readme;
mod record_mcap;
mod refused_states;
mod replay;
mod report_browser;
mod robot_files;
mod robot_generate;
mod robust;
mod robust_cli;
mod sensors;
mod shared_machine;
mod shutdown;
mod small_things;
mod stock_interop;
mod until_stopped;

/// Twice as many tests at once as there are cores. Most of this suite's tests wait: on the
/// processes of a run they start, on a realtime run that lasts seconds, on a child they stopped;
/// with libtest's one test a core the suite used 1.1 of 2 cores and took 88 s, with two a core
/// 1.7 cores and 55-56 s (2026-12-07, docs/measurements/2026-12-07-ci-threads.md). Set before
/// libtest reads it, from the binary's initialisers (Linux runs `.init_array` before `main`), and
/// only where the caller has not set `RUST_TEST_THREADS`; `--test-threads N` still wins over it.
/// The tests judged on a realtime rate are not in this binary (`common::alone`).
#[used]
#[link_section = ".init_array"]
static TWO_TESTS_A_CORE: extern "C" fn() = two_tests_a_core;

use std::sync::atomic::{AtomicUsize, Ordering};

/// What the initialiser did: the count it set, or `CALLER_SET` where the caller had set one.
static SET_TO: AtomicUsize = AtomicUsize::new(0);
const CALLER_SET: usize = usize::MAX;

/// Two tests a core on this machine.
fn two_a_core() -> usize {
    2 * std::thread::available_parallelism().map_or(1, |n| n.get())
}

extern "C" fn two_tests_a_core() {
    if std::env::var_os("RUST_TEST_THREADS").is_some() {
        SET_TO.store(CALLER_SET, Ordering::Relaxed);
        return;
    }
    let threads = two_a_core();
    std::env::set_var("RUST_TEST_THREADS", threads.to_string());
    SET_TO.store(threads, Ordering::Relaxed);
}

/// The initialiser above ran and set twice the cores (a linker that dropped the unreferenced
/// static would leave the suite at one test a core, silently slower); a caller's own count is
/// left alone.
#[test]
fn the_suite_runs_two_tests_a_core() {
    let set = SET_TO.load(Ordering::Relaxed);
    assert_ne!(set, 0, "the initialiser did not run");
    let threads = std::env::var("RUST_TEST_THREADS").expect("RUST_TEST_THREADS is not set");
    if set != CALLER_SET {
        assert_eq!(set, two_a_core());
        assert_eq!(threads, set.to_string());
    }
}

/// Every `tests/*.rs` is a module of this suite or a `[[test]]` target of Cargo.toml: with
/// `autotests = false` a new file that is neither would compile nowhere and pass by silence.
#[test]
fn every_test_file_is_built() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let (modules, targets) = (common::suite_modules(), common::test_targets());
    let mut missing = Vec::new();
    for entry in std::fs::read_dir(root.join("tests")).unwrap() {
        let path = entry.unwrap().path();
        let (Some(stem), Some("rs")) = (
            path.file_stem().and_then(|s| s.to_str()),
            path.extension().and_then(|e| e.to_str()),
        ) else {
            continue;
        };
        let module = modules.iter().any(|m| m == stem);
        let target = targets.iter().any(|t| t == stem);
        if stem != "suite" && module == target {
            missing.push(format!(
                "tests/{stem}.rs (module: {module}, target: {target})"
            ));
        }
    }
    assert!(
        missing.is_empty(),
        "each file must be exactly one of a `mod` in tests/suite.rs or a [[test]] in Cargo.toml: {missing:?}"
    );
}
