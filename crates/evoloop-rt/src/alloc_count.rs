//! A global allocator that counts the allocations of the thread that armed it (`arm` ..
//! `disarm`). Only that thread: another thread may allocate at any moment (the writer threads,
//! a test harness waiting for its test), and that is not the code watched.
//!
//! evoloop's binaries install it, so the controller process counts what its own control cycle
//! allocates (armed around each cycle after the first few, `node::controller`) and reports it
//! in controller.json and summary.json (`cycle_allocations`): the real loop is watched in every
//! run, not a copy of it in a test. The cost when not armed: one thread-local read per
//! allocation. The allocation tests install it too.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};

/// The counting allocator, for `#[global_allocator]`: every call goes to the system allocator,
/// and the armed thread's allocations are counted in `COUNT` and `LIVE`.
pub struct Counting;
/// Allocations (and reallocations) made by an armed thread, since the start (all armed
/// threads together).
pub static COUNT: AtomicU64 = AtomicU64::new(0);
/// Bytes allocated minus bytes freed while armed: what armed code keeps (a memory test's
/// figure; memory freed while armed but allocated before counts negative).
pub static LIVE: AtomicI64 = AtomicI64::new(0);

thread_local! {
    // A const-initialised Cell without a destructor: reading it never allocates.
    static ARMED: Cell<bool> = const { Cell::new(false) };
}

/// Count this thread's allocations from now on.
pub fn arm() {
    ARMED.with(|a| a.set(true));
}

/// Stop counting.
pub fn disarm() {
    ARMED.with(|a| a.set(false));
}

fn armed() -> bool {
    ARMED.try_with(|a| a.get()).unwrap_or(false)
}

// SAFETY: every call is forwarded to the system allocator with the caller's arguments; the
// counting beside it touches only atomics and a thread-local flag, never the heap.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if armed() {
            COUNT.fetch_add(1, Ordering::Relaxed);
            LIVE.fetch_add(l.size() as i64, Ordering::Relaxed);
        }
        // SAFETY: the caller's layout, as GlobalAlloc::alloc requires it.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        if armed() {
            LIVE.fetch_sub(l.size() as i64, Ordering::Relaxed);
        }
        // SAFETY: `p` came from this allocator, hence from System, with layout `l`.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        if armed() {
            COUNT.fetch_add(1, Ordering::Relaxed);
            LIVE.fetch_add(n as i64 - l.size() as i64, Ordering::Relaxed);
        }
        // SAFETY: `p` came from System with layout `l`; the caller guarantees `n`'s validity.
        unsafe { System.realloc(p, l, n) }
    }
}

/// Whether this allocator is the process's (`#[global_allocator]`): a probe allocation while
/// armed is counted only if it is.
pub fn installed() -> bool {
    let before = COUNT.load(Ordering::Relaxed);
    arm();
    drop(std::hint::black_box(Box::new(0u64)));
    disarm();
    let after = COUNT.load(Ordering::Relaxed);
    // Not the probe's: take it back out, so COUNT stays the watched code's. (Called once, by
    // the controller's thread before its loop, when no other thread is armed.)
    let probe = after.saturating_sub(before);
    COUNT.fetch_sub(probe, Ordering::Relaxed);
    probe > 0
}

/// What the controller's cycle allocated, counted on the real loop (controller.json,
/// summary.json).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CycleAllocations {
    /// Cycles watched: all but the first `WARMUP_CYCLES` (their first loans and first set).
    pub cycles: u64,
    /// Allocations and reallocations on the loop's thread during them (0 is the design).
    pub allocations: u64,
}

/// Cycles not watched at the start.
pub const WARMUP_CYCLES: u64 = 10;
