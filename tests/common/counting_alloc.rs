//! A global allocator that counts the allocations of the thread that armed it (`arm` ..
//! `disarm`), for the allocation tests. Only that thread: the test harness's own thread may
//! allocate at any moment (e.g. when its wait for the test times out on a loaded machine), and
//! that is not the code under test. Included by path (`#[path = "common/counting_alloc.rs"] mod
//! counting_alloc;`) only in the test binaries that install it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

pub struct Counting;
pub static COUNT: AtomicU64 = AtomicU64::new(0);

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

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if armed() {
            COUNT.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        if armed() {
            COUNT.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(p, l, n) }
    }
}
