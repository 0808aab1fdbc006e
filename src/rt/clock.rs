//! CLOCK_MONOTONIC: one time base shared by every process on the machine, so a state's stamp
//! taken in the plant can be compared with the controller's clock.

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

/// A bare absolute-deadline sleep loop: the machine's timing floor. Returns each cycle's wake-up
/// lateness in ns. Nothing else happens in the loop, so any controller lateness above these
/// figures is evoloop's own.
pub fn sleep_loop_lateness(period_ns: u64, cycles: usize) -> Vec<i64> {
    let mut out = Vec::with_capacity(cycles);
    let start = now_ns() + period_ns;
    for k in 0..cycles as u64 {
        let deadline = start + k * period_ns;
        sleep_until_ns(deadline);
        out.push(now_ns() as i64 - deadline as i64);
    }
    out
}
