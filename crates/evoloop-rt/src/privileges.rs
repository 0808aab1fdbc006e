//! Real-time privileges: SCHED_FIFO, mlockall and CPU affinity, each tried when asked for and
//! reported honestly, with a clean fallback when the process is not permitted.

use serde::{Deserialize, Serialize};

/// What a process asks for.
#[derive(Debug, Clone, Copy, Default)]
pub struct RtRequest {
    /// SCHED_FIFO priority (1-99); None = stay SCHED_OTHER.
    pub fifo_priority: Option<i32>,
    /// Lock the process's current and future memory in RAM (mlockall).
    pub lock_memory: bool,
    /// CPU to pin to; None = no pinning.
    pub cpu: Option<usize>,
    /// How the loop will wait (a spinning SCHED_FIFO loop meets RT throttling: noted).
    pub wait: crate::WaitKind,
}

impl RtRequest {
    /// Whether it asks for a CPU or a SCHED_FIFO priority (what `place_self` gives another process).
    pub fn places(&self) -> bool {
        self.cpu.is_some() || self.fifo_priority.is_some()
    }
}

/// What the process got; goes into summary.json so timing figures can be read in context.
#[derive(Debug, Clone, Default, Serialize, Deserialize, PartialEq)]
pub struct RtGranted {
    /// Whether the process runs SCHED_FIFO.
    pub sched_fifo: bool,
    /// Its SCHED_FIFO priority (0 when not SCHED_FIFO).
    pub priority: i32,
    /// Whether its memory is locked (mlockall succeeded).
    pub mlockall: bool,
    /// The one CPU it is pinned to; None = not pinned.
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
    if least_timer_slack() {
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
        if pin(cpu) {
            got.cpu = Some(cpu);
        } else {
            got.notes
                .push(format!("affinity to cpu {cpu} refused: {}", os_error()));
        }
    }
    if let Some(prio) = req.fifo_priority {
        if fifo(prio) {
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

/// Pin the calling process to `cpu`, take SCHED_FIFO at `priority` and a 1 ns timer slack, with
/// plain syscalls and nothing else: what a child may do between fork and exec
/// (`CommandExt::pre_exec`), where allocating or locking can deadlock a threaded parent's copy.
/// All three survive exec and pass to the threads the program starts; failures are left for
/// `granted_to` to read back and report.
pub fn place_self(cpu: Option<usize>, priority: Option<i32>) {
    least_timer_slack();
    if let Some(cpu) = cpu {
        pin(cpu);
    }
    if let Some(prio) = priority {
        fifo(prio);
    }
}

/// The three placements, each one syscall on the calling process and nothing else (so
/// `place_self` may make them between fork and exec); whether it took (errno says why not).
fn least_timer_slack() -> bool {
    // SAFETY: prctl with an integer argument; 1 ns is the smallest slack Linux accepts.
    unsafe { libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0) == 0 }
}

fn pin(cpu: usize) -> bool {
    if cpu >= libc::CPU_SETSIZE as usize {
        return false;
    }
    // SAFETY: cpu_set_t is plain data and `cpu` is within its size; a call on this process.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

fn fifo(priority: i32) -> bool {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: param is valid for the call; a call on this process.
    unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) == 0 }
}

/// What process `pid` runs with, read from outside (its scheduling policy and priority, the
/// CPUs it may run on, its timer slack from `/proc/<pid>/timerslack_ns`), with a note for each
/// part of `req` it did not get. Memory locking does not survive exec: not granted, not noted.
pub fn granted_to(pid: i32, req: &RtRequest) -> RtGranted {
    let mut got = RtGranted::default();
    // SAFETY: plain syscalls on a process id; the out-parameters are valid for them.
    unsafe {
        let mut param: libc::sched_param = std::mem::zeroed();
        if libc::sched_getscheduler(pid) == libc::SCHED_FIFO
            && libc::sched_getparam(pid, &mut param) == 0
        {
            got.sched_fifo = true;
            got.priority = param.sched_priority;
        }
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(pid, std::mem::size_of::<libc::cpu_set_t>(), &mut set) == 0
            && libc::CPU_COUNT(&set) == 1
        {
            got.cpu = (0..libc::CPU_SETSIZE as usize).find(|c| libc::CPU_ISSET(*c, &set));
        }
    }
    got.timer_slack_ns = std::fs::read_to_string(format!("/proc/{pid}/timerslack_ns"))
        .ok()
        .and_then(|t| t.trim().parse().ok())
        .unwrap_or(0);
    if let Some(prio) = req.fifo_priority {
        if !(got.sched_fifo && got.priority == prio) {
            got.notes.push(format!(
                "SCHED_FIFO priority {prio} for the plant process not granted (running {})",
                if got.sched_fifo {
                    "another priority"
                } else {
                    "SCHED_OTHER"
                }
            ));
        }
    }
    if let Some(cpu) = req.cpu {
        if got.cpu != Some(cpu) {
            got.notes
                .push(format!("the plant process was not pinned to cpu {cpu}"));
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A child placed by `place_self` before exec runs where it was put, as `granted_to` reads
    /// it back (SCHED_FIFO only where this process may grant it: root).
    #[test]
    fn a_child_placed_before_exec_is_read_back_as_placed() {
        use std::os::unix::process::CommandExt;
        // SAFETY: a plain syscall.
        let root = unsafe { libc::geteuid() } == 0;
        let priority = root.then_some(11);
        let mut cmd = std::process::Command::new("sleep");
        cmd.arg("5");
        // SAFETY: `place_self` makes syscalls only.
        unsafe {
            cmd.pre_exec(move || {
                place_self(Some(0), priority);
                Ok(())
            })
        };
        let mut child = cmd.spawn().unwrap();
        let req = RtRequest {
            fifo_priority: priority,
            cpu: Some(0),
            ..RtRequest::default()
        };
        let got = granted_to(child.id() as i32, &req);
        let _ = child.kill();
        let _ = child.wait();
        assert_eq!(got.cpu, Some(0), "{got:?}");
        // 1 ns as set; the kernel keeps none for a SCHED_FIFO process (it reads 0 then).
        assert!(got.timer_slack_ns <= 1, "{got:?}");
        let want = if root { (true, 11) } else { (false, 0) };
        assert_eq!((got.sched_fifo, got.priority), want, "{got:?}");
        assert!(got.notes.is_empty(), "{got:?}");
        // Asked what it did not get, it says so.
        let more = granted_to(
            std::process::id() as i32,
            &RtRequest {
                fifo_priority: Some(12),
                ..RtRequest::default()
            },
        );
        assert!(more.notes[0].contains("SCHED_FIFO priority 12"), "{more:?}");
    }
}
