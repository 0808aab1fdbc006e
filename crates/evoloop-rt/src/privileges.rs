//! Real-time privileges: SCHED_FIFO, mlockall and CPU affinity, each tried when asked for and
//! reported honestly, with a clean fallback when the process is not permitted.

use serde::{Deserialize, Serialize};

/// What a process asks for.
#[derive(Debug, Clone, Copy, Default)]
pub struct RtRequest {
    /// SCHED_FIFO priority (1-99); None = stay SCHED_OTHER.
    pub fifo_priority: Option<i32>,
    pub lock_memory: bool,
    /// CPU to pin to; None = no pinning.
    pub cpu: Option<usize>,
    /// How the loop will wait (a spinning SCHED_FIFO loop meets RT throttling: noted).
    pub wait: crate::WaitKind,
}

/// What the process got; goes into summary.json so timing figures can be read in context.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct RtGranted {
    pub sched_fifo: bool,
    pub priority: i32,
    pub mlockall: bool,
    pub cpu: Option<usize>,
    /// Timer slack of the thread, ns (Linux adds up to this much to every timed sleep; the
    /// default 50 µs would dominate a SCHED_OTHER loop's lateness).
    pub timer_slack_ns: u64,
    /// Why something asked for was not granted.
    pub notes: Vec<String>,
}

fn os_error() -> String {
    std::io::Error::last_os_error().to_string()
}

/// Apply the request to the calling thread/process; never fails, reports what it got. The timer
/// slack is always set to 1 ns: a control loop sleeping to absolute deadlines wants no slack.
pub fn apply_privileges(req: &RtRequest) -> RtGranted {
    let mut got = RtGranted::default();
    // SAFETY: prctl with an integer argument; 1 ns is the smallest slack Linux accepts.
    if unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) } == 0 {
        got.timer_slack_ns = 1;
    } else {
        got.notes
            .push(format!("timer slack unchanged: {}", os_error()));
    }
    if req.lock_memory {
        // SAFETY: plain syscall with constant flags.
        if unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) } == 0 {
            got.mlockall = true;
        } else {
            got.notes.push(format!("mlockall refused: {}", os_error()));
        }
    }
    if let Some(cpu) = req.cpu {
        // SAFETY: cpu_set_t is plain data; CPU_SET bounds-checks against its size.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0 {
                got.cpu = Some(cpu);
            } else {
                got.notes
                    .push(format!("affinity to cpu {cpu} refused: {}", os_error()));
            }
        }
    }
    if let Some(prio) = req.fifo_priority {
        let param = libc::sched_param {
            sched_priority: prio,
        };
        // SAFETY: param is valid for the call.
        if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) } == 0 {
            got.sched_fifo = true;
            got.priority = prio;
        } else {
            got.notes.push(format!(
                "SCHED_FIFO priority {prio} refused: {} (running SCHED_OTHER)",
                os_error()
            ));
        }
    }
    if got.sched_fifo && req.wait == crate::WaitKind::Spin {
        if let Some(n) = rt_throttling_note() {
            got.notes.push(n);
        }
    }
    got
}

/// A loop that spins under SCHED_FIFO never yields its CPU; with RT throttling on (Linux's
/// default `kernel.sched_rt_runtime_us` = 950000 of each 1000000) the kernel then takes the CPU
/// away for the rest of every second: a 50 ms stall, measured here as p99 lateness of 38 ms at
/// 10 kHz (`evoloop floor --wait spin --fifo 80`).
fn rt_throttling_note() -> Option<String> {
    let runtime = std::fs::read_to_string("/proc/sys/kernel/sched_rt_runtime_us").ok()?;
    let runtime: i64 = runtime.trim().parse().ok()?;
    (runtime >= 0).then(|| {
        format!(
            "wait = spin under SCHED_FIFO with RT throttling on (kernel.sched_rt_runtime_us = {runtime}): \
             the kernel stops the loop for the rest of each second once it has spun {} ms of it; \
             use wait = hybrid, or set kernel.sched_rt_runtime_us = -1 on a core you can spare",
            runtime / 1000
        )
    })
}

/// Lower the calling process's priority (nice), for background work such as the optimiser.
pub fn set_nice(nice: i32) -> bool {
    // SAFETY: plain syscall.
    unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, nice) == 0 }
}
