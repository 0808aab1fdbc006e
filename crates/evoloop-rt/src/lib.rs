//! Timing and scheduling: the monotonic clock, absolute-deadline sleeping, the real-time
//! privileges a process may get (SCHED_FIFO, mlockall, CPU affinity) and the cycle timing record.

pub mod alloc_count;
pub mod clock;
pub mod privileges;
pub mod timing;

pub use clock::{now_ns, WaitKind, WaitStrategy};
pub use privileges::{apply_privileges, RtGranted, RtRequest};
pub use timing::{CycleTiming, TimingStats, TimingSummary};
