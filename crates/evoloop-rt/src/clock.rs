//! CLOCK_MONOTONIC: one time base shared by every process on the machine, so a state's stamp
//! taken in the plant can be compared with the controller's clock; and the ways a loop waits.

use serde::{Deserialize, Serialize};

/// Nanoseconds of CLOCK_MONOTONIC.
pub fn now_ns() -> u64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: ts is a valid out-pointer; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleep until the absolute CLOCK_MONOTONIC time `deadline_ns` (clock_nanosleep with
/// TIMER_ABSTIME), so wake-up errors never accumulate from cycle to cycle. Returns at once if the
/// deadline has passed. A signal interrupting the sleep resumes it: the caller checks its stop
/// flag once per cycle anyway.
pub fn sleep_until_ns(deadline_ns: u64) {
    let ts = libc::timespec {
        tv_sec: (deadline_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline_ns % 1_000_000_000) as libc::c_long,
    };
    loop {
        // SAFETY: ts is valid; a null remainder is allowed with TIMER_ABSTIME.
        let r = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        if r != libc::EINTR {
            return;
        }
    }
}

/// Spin on the clock until `deadline_ns`: wakes within the clock's read cost (tens of ns) of the
/// deadline, and holds the CPU all the while.
pub fn spin_until_ns(deadline_ns: u64) {
    while now_ns() < deadline_ns {
        std::hint::spin_loop();
    }
}

/// How a realtime loop waits for its next deadline (`timing.wait`).
///
/// - `sleep`: clock_nanosleep to the deadline. Costs no CPU; the wake-up lateness is the
///   kernel's (on this VM tens of µs, p99.9 above 100 µs), a large share of a 100 µs period.
/// - `spin`: read the clock until the deadline. Lateness is the clock read's, but the loop holds
///   its core for the whole run: only with a core to spare (pinned, `timing.controller_cpu`),
///   and under SCHED_FIFO only where RT throttling is off (`sched_rt_runtime_us = -1`), or the
///   kernel takes the core away for 50 ms each second.
/// - `hybrid`: sleep until `margin` before the deadline, then spin. The sleep's lateness is
///   absorbed when it is under the margin; the loop spins about margin - sleep lateness per
///   period. The margin should cover the sleep's p99.9 lateness (`evoloop floor` shows it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WaitKind {
    /// clock_nanosleep to the deadline: no CPU used, the kernel's wake-up lateness
    #[default]
    Sleep,
    /// Read the clock until the deadline: least lateness, but holds its core all the while
    Spin,
    /// Sleep until a margin before the deadline, then spin
    Hybrid,
}

impl WaitKind {
    /// Every strategy, as `--wait` lists them.
    pub const ALL: [WaitKind; 3] = [WaitKind::Sleep, WaitKind::Spin, WaitKind::Hybrid];

    /// The strategy's name as `timing.wait` writes it: "sleep", "spin" or "hybrid".
    pub fn name(self) -> &'static str {
        match self {
            WaitKind::Sleep => "sleep",
            WaitKind::Spin => "spin",
            WaitKind::Hybrid => "hybrid",
        }
    }
}

/// A wait strategy and, for `hybrid`, how long before the deadline the sleep ends.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct WaitStrategy {
    /// How the loop waits.
    pub kind: WaitKind,
    /// `hybrid`: how long before the deadline the sleep ends and the spin begins, ns (0 for the
    /// other kinds).
    pub margin_ns: u64,
}

impl WaitStrategy {
    /// `kind`, with `margin_us` as the hybrid margin (other strategies have none).
    pub fn new(kind: WaitKind, margin_us: f64) -> WaitStrategy {
        WaitStrategy {
            kind,
            margin_ns: if kind == WaitKind::Hybrid {
                (margin_us * 1e3).round() as u64
            } else {
                0
            },
        }
    }

    /// Wait until the absolute CLOCK_MONOTONIC time `deadline_ns`; at once if it has passed.
    pub fn wait_until(&self, deadline_ns: u64) {
        match self.kind {
            WaitKind::Sleep => sleep_until_ns(deadline_ns),
            WaitKind::Spin => spin_until_ns(deadline_ns),
            WaitKind::Hybrid => {
                let wake = deadline_ns.saturating_sub(self.margin_ns);
                if wake > now_ns() {
                    sleep_until_ns(wake);
                }
                spin_until_ns(deadline_ns);
            }
        }
    }

    /// For people: "sleep", "spin", "hybrid (margin 80 us)".
    pub fn describe(&self) -> String {
        match self.kind {
            WaitKind::Hybrid => format!("hybrid (margin {} us)", self.margin_ns / 1000),
            k => k.name().into(),
        }
    }
}

/// A bare absolute-deadline loop, waiting as `wait` does: the machine's timing floor for that
/// strategy. Returns each cycle's wake-up lateness in ns. Nothing else happens in the loop, so
/// any controller lateness above these figures is evoloop's own.
pub fn wait_loop_lateness(period_ns: u64, cycles: usize, wait: WaitStrategy) -> Vec<i64> {
    let mut out = Vec::with_capacity(cycles);
    let start = now_ns() + period_ns;
    for k in 0..cycles as u64 {
        let deadline = start + k * period_ns;
        wait.wait_until(deadline);
        out.push(now_ns() as i64 - deadline as i64);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_strategy_wakes_at_or_after_its_deadline() {
        for kind in [WaitKind::Sleep, WaitKind::Spin, WaitKind::Hybrid] {
            let w = WaitStrategy {
                kind,
                margin_ns: 200_000,
            };
            for late in wait_loop_lateness(500_000, 20, w) {
                assert!(late >= 0, "{kind:?} woke {late} ns early");
            }
        }
    }

    #[test]
    fn a_passed_deadline_returns_at_once() {
        let t0 = now_ns();
        for kind in [WaitKind::Sleep, WaitKind::Spin, WaitKind::Hybrid] {
            WaitStrategy {
                kind,
                margin_ns: 1_000_000,
            }
            .wait_until(t0.saturating_sub(1_000_000));
        }
        assert!(now_ns() - t0 < 50_000_000);
    }
}
