//! iceoryx2's per-loan reference count, kept in a recycled pool instead of the heap.
//!
//! iceoryx2 0.10 wraps every loaned sample's bookkeeping (`ChunkMutSharedState`: the chunk's
//! offset, pointer and length, and a handle on the publisher) in its service type's
//! `ArcThreadSafetyPolicy`. For `ipc::Service` that policy is `SingleThreaded`, an `Rc`, so each
//! `loan_uninit` and so each send made one heap allocation (and the matching free), inside the
//! control cycle, three times per cycle (state, command, telemetry). The policy is the only
//! per-send allocation in iceoryx2's publish path, and it is a type parameter of the service:
//! `Pooled` is the same single-threaded reference count, but its blocks come from a per-thread
//! free list and go back to it. After the first loan of each size class on a thread the free
//! list holds a block, and every later loan reuses it: no call into the allocator per cycle
//! (`tests/no_alloc.rs` pins 0, IPC included).
//!
//! Design choices:
//! - **Size classes, not types.** The policy is generic over the iceoryx2-private type it holds,
//!   and Rust has no generic statics, so the pool is a byte pool in power-of-two classes from 32 B
//!   to 4 KiB (the loan state is 40 B with its count; the pool rounds to 64). Larger values (none
//!   in iceoryx2's per-loan path) go to the heap as before.
//! - **Per thread, never shared.** Like `Rc`, a `Pooled` is neither `Send` nor `Sync`, so the
//!   block is freed on the thread that took it and the free list needs no lock or atomic.
//! - **Grows to the peak, never shrinks while the thread lives.** The peak is the number of loans
//!   alive at once (one per publisher here, `max_loaned_samples(1)`), so the pool stays tiny.
//!   The blocks are returned to the heap when the thread ends; a value dropped after that (in
//!   another thread-local's destructor) goes straight to the heap.

use core::cell::Cell;
use core::fmt;
use core::marker::PhantomData;
use core::ops::Deref;
use core::ptr::NonNull;
use iceoryx2_bb_elementary_traits::testing::abandonable::Abandonable;
use iceoryx2_cal::arc_sync_policy::{ArcSyncPolicy, ArcSyncPolicyCreationError, LockGuard};
use std::alloc::{alloc, dealloc, Layout};

const MIN_SHIFT: u32 = 5;
const CLASSES: usize = 8;

/// A block on a free list stores the next free block in itself.
struct Free {
    next: *mut Free,
}

/// This thread's free lists, one per size class, and its counters.
struct Pool {
    heads: [Cell<*mut Free>; CLASSES],
    from_heap: Cell<u64>,
    reused: Cell<u64>,
}

impl Drop for Pool {
    fn drop(&mut self) {
        for (class, head) in self.heads.iter().enumerate() {
            let mut p = head.get();
            while !p.is_null() {
                // SAFETY: every block on list `class` was allocated with `block_layout(class)`
                // and is free (no value lives in it).
                unsafe {
                    let next = (*p).next;
                    dealloc(p.cast(), block_layout(class));
                    p = next;
                }
            }
        }
    }
}

thread_local! {
    static POOL: Pool = const {
        Pool {
            heads: [const { Cell::new(core::ptr::null_mut()) }; CLASSES],
            from_heap: Cell::new(0),
            reused: Cell::new(0),
        }
    };
}

/// The size class of a value's layout, if it is pooled.
fn class_of(layout: Layout) -> Option<usize> {
    let size = layout.size().max(layout.align()).max(1 << MIN_SHIFT);
    let class = (size.next_power_of_two().trailing_zeros() - MIN_SHIFT) as usize;
    (class < CLASSES).then_some(class)
}

/// A class's blocks are aligned to their size, so any value that fits one fits its alignment.
fn block_layout(class: usize) -> Layout {
    let size = 1usize << (class as u32 + MIN_SHIFT);
    Layout::from_size_align(size, size).expect("power-of-two block layout")
}

fn take(layout: Layout) -> *mut u8 {
    let Some(class) = class_of(layout) else {
        // SAFETY: layout has non-zero size (it holds at least the reference count).
        return unsafe { alloc(layout) };
    };
    let reused = POOL
        .try_with(|pool| {
            let head = pool.heads[class].get();
            if head.is_null() {
                pool.from_heap.set(pool.from_heap.get() + 1);
                None
            } else {
                // SAFETY: `head` is a free block of this class, owned by this thread's list.
                pool.heads[class].set(unsafe { (*head).next });
                pool.reused.set(pool.reused.get() + 1);
                Some(head.cast::<u8>())
            }
        })
        .ok()
        .flatten();
    // SAFETY: block layouts have non-zero size.
    reused.unwrap_or_else(|| unsafe { alloc(block_layout(class)) })
}

/// # Safety
/// `p` came from `take(layout)` on this thread and holds no live value.
unsafe fn give_back(p: *mut u8, layout: Layout) {
    let Some(class) = class_of(layout) else {
        // SAFETY: a layout of no class was allocated by `alloc(layout)` in `take`.
        unsafe { dealloc(p, layout) };
        return;
    };
    let kept = POOL.try_with(|pool| {
        let block = p.cast::<Free>();
        // SAFETY: the block is at least 32 bytes, aligned to its size, and free.
        unsafe {
            block.write(Free {
                next: pool.heads[class].get(),
            })
        };
        pool.heads[class].set(block);
    });
    if kept.is_err() {
        // The thread's pool is gone (thread exit): back to the heap.
        // SAFETY: every block of `class` was allocated with `block_layout(class)`.
        unsafe { dealloc(p, block_layout(class)) };
    }
}

/// How this thread's pool has served so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PoolStats {
    /// Blocks the pool had to take from the heap (its peak size, once warm).
    pub from_heap: u64,
    /// Blocks served from the free list, without touching the heap.
    pub reused: u64,
}

/// This thread's pool counters.
pub fn stats() -> PoolStats {
    POOL.try_with(|p| PoolStats {
        from_heap: p.from_heap.get(),
        reused: p.reused.get(),
    })
    .unwrap_or_default()
}

struct Inner<T> {
    count: Cell<usize>,
    value: T,
}

/// A single-threaded reference-counted value in a pooled block (an `Rc` without the heap).
pub struct Pooled<T: Send + fmt::Debug + Abandonable> {
    ptr: NonNull<Inner<T>>,
    // Neither Send nor Sync (the block belongs to this thread's pool), and owns a T.
    _owns: PhantomData<std::rc::Rc<T>>,
}

impl<T: Send + fmt::Debug + Abandonable> Pooled<T> {
    fn inner(&self) -> &Inner<T> {
        // SAFETY: the block lives while any handle does (reference count > 0).
        unsafe { self.ptr.as_ref() }
    }

    /// Drop one handle; the last one hands the value to `finish` and frees the block.
    ///
    /// # Safety
    /// `this` is a live handle that is not used again.
    unsafe fn release(this: NonNull<Self>, finish: impl FnOnce(NonNull<T>)) {
        // SAFETY: `this` is a live handle (the caller's promise).
        let ptr = unsafe { this.as_ref() }.ptr;
        // SAFETY: the block lives while any handle does, and `this` is one.
        let inner = unsafe { ptr.as_ref() };
        let n = inner.count.get() - 1;
        inner.count.set(n);
        if n == 0 {
            // SAFETY: the block is live (the count was 1) and a field's address is not null.
            let value = unsafe { NonNull::new_unchecked(&raw mut (*ptr.as_ptr()).value) };
            finish(value);
            // SAFETY: the last handle is gone and `finish` took the value: the block, taken
            // with this layout on this thread (a `Pooled` is not Send), holds nothing live.
            unsafe { give_back(ptr.as_ptr().cast(), Layout::new::<Inner<T>>()) };
        }
    }
}

impl<T: Send + fmt::Debug + Abandonable> Clone for Pooled<T> {
    fn clone(&self) -> Self {
        let c = &self.inner().count;
        c.set(c.get() + 1);
        Self {
            ptr: self.ptr,
            _owns: PhantomData,
        }
    }
}

impl<T: Send + fmt::Debug + Abandonable> Drop for Pooled<T> {
    fn drop(&mut self) {
        // SAFETY: `self` is live and this is its last use.
        unsafe { Self::release(NonNull::from(&mut *self), |v| v.drop_in_place()) };
    }
}

impl<T: Send + fmt::Debug + Abandonable> fmt::Debug for Pooled<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Pooled")
            .field("value", &self.inner().value)
            .finish()
    }
}

impl<T: Send + fmt::Debug + Abandonable> Abandonable for Pooled<T> {
    /// As iceoryx2's `SingleThreaded`: the last handle abandons the value (its shared resources
    /// are left as they are) instead of dropping it; any other handle is just released.
    unsafe fn abandon_in_place(this: NonNull<Self>) {
        // SAFETY: `this` is live and not used again (abandon_in_place's own contract).
        unsafe { Self::release(this, |v| T::abandon_in_place(v)) };
    }
}

/// Access to a `Pooled` value for as long as the handle is borrowed.
pub struct Guard<'parent, T> {
    value: &'parent T,
}

impl<T> Deref for Guard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        self.value
    }
}

impl<'parent, T: Send + Abandonable> LockGuard<'parent, T> for Guard<'parent, T> {}

impl<T: Send + fmt::Debug + Abandonable> ArcSyncPolicy<T> for Pooled<T> {
    type LockGuard<'parent>
        = Guard<'parent, T>
    where
        Self: 'parent,
        T: 'parent;

    fn new(value: T) -> Result<Self, ArcSyncPolicyCreationError> {
        let layout = Layout::new::<Inner<T>>();
        let Some(ptr) = NonNull::new(take(layout).cast::<Inner<T>>()) else {
            return Err(ArcSyncPolicyCreationError::InsufficientResources);
        };
        // SAFETY: a fresh block of at least `layout`'s size and alignment.
        unsafe {
            ptr.write(Inner {
                count: Cell::new(1),
                value,
            })
        };
        Ok(Self {
            ptr,
            _owns: PhantomData,
        })
    }

    fn lock(&self) -> Guard<'_, T> {
        Guard {
            value: &self.inner().value,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::rc::Rc;

    /// A value that records its drop or abandonment.
    #[derive(Debug)]
    struct Probe {
        dropped: Rc<Cell<u32>>,
        abandoned: Rc<Cell<u32>>,
        payload: [u64; 4],
    }
    // SAFETY: test only; probes (and their Rc counters) never leave their thread.
    unsafe impl Send for Probe {}
    impl Drop for Probe {
        fn drop(&mut self) {
            self.dropped.set(self.dropped.get() + 1);
        }
    }
    impl Abandonable for Probe {
        unsafe fn abandon_in_place(this: NonNull<Self>) {
            // SAFETY: `this` is a live probe (abandon_in_place's contract).
            let p = unsafe { this.as_ref() };
            p.abandoned.set(p.abandoned.get() + 1);
            // Release the probe's own handles without running its Drop.
            // SAFETY: each field is live and dropped once; the probe is not used again.
            unsafe {
                core::ptr::drop_in_place(&raw mut (*this.as_ptr()).dropped);
                core::ptr::drop_in_place(&raw mut (*this.as_ptr()).abandoned);
            }
        }
    }

    fn probe() -> (Probe, Rc<Cell<u32>>, Rc<Cell<u32>>) {
        let d = Rc::new(Cell::new(0));
        let a = Rc::new(Cell::new(0));
        let p = Probe {
            dropped: d.clone(),
            abandoned: a.clone(),
            payload: [1, 2, 3, 4],
        };
        (p, d, a)
    }

    #[test]
    fn the_value_lives_until_the_last_handle_and_is_dropped_once() {
        let (p, dropped, _) = probe();
        let a = Pooled::new(p).unwrap();
        let b = a.clone();
        assert_eq!(a.lock().payload, [1, 2, 3, 4]);
        drop(a);
        assert_eq!(dropped.get(), 0);
        assert_eq!(b.lock().payload[3], 4);
        drop(b);
        assert_eq!(dropped.get(), 1);
    }

    #[test]
    fn a_freed_block_is_reused_without_the_heap() {
        // Warm: the first value of the class may take a block from the heap.
        drop(Pooled::new(probe().0).unwrap());
        let before = stats();
        for _ in 0..100 {
            let x = Pooled::new(probe().0).unwrap();
            let y = x.clone();
            drop((x, y));
        }
        let after = stats();
        assert_eq!(after.from_heap, before.from_heap, "no block from the heap");
        assert_eq!(after.reused - before.reused, 100);
    }

    #[test]
    fn live_values_get_distinct_blocks_and_the_pool_grows_to_the_peak() {
        let before = stats();
        let held: Vec<_> = (0..5).map(|_| Pooled::new(probe().0).unwrap()).collect();
        let mut addrs: Vec<_> = held.iter().map(|h| h.ptr.as_ptr() as usize).collect();
        addrs.sort();
        addrs.dedup();
        assert_eq!(addrs.len(), 5);
        let grown = stats().from_heap - before.from_heap;
        drop(held);
        let again: Vec<_> = (0..5).map(|_| Pooled::new(probe().0).unwrap()).collect();
        assert_eq!(
            stats().from_heap - before.from_heap,
            grown,
            "served from the pool"
        );
        drop(again);
    }

    #[test]
    fn abandoning_the_last_handle_abandons_the_value_instead_of_dropping_it() {
        let (p, dropped, abandoned) = probe();
        let a = Pooled::new(p).unwrap();
        let b = a.clone();
        b.abandon(); // not the last handle: just released
        assert_eq!((dropped.get(), abandoned.get()), (0, 0));
        a.abandon();
        assert_eq!((dropped.get(), abandoned.get()), (0, 1));
    }

    #[test]
    fn size_classes_fit_size_and_alignment() {
        for (size, align) in [(1, 1), (40, 8), (64, 64), (65, 8), (4096, 8), (100, 128)] {
            let l = Layout::from_size_align(size, align).unwrap();
            let b = block_layout(class_of(l).unwrap());
            assert!(
                b.size() >= size && b.align() >= align,
                "{size}/{align} -> {b:?}"
            );
        }
        assert_eq!(class_of(Layout::from_size_align(4097, 8).unwrap()), None);
    }
}
