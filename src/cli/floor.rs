//! `evoloop floor`: the bare sleep loop's lateness on this machine (what realtime runs are
//! judged against).

use crate::node::launcher::measure_floor;
use std::process::ExitCode;

pub fn main(rate: f64, duration: f64, fifo: Option<i32>, json: bool) -> ExitCode {
    let rate_ok = rate > 0.0 && rate <= 100_000.0;
    let duration_ok = duration > 0.0 && duration <= 3600.0;
    if !rate_ok || !duration_ok {
        err!("error: --rate must be in (0, 100000] Hz and --duration in (0, 3600] s");
        return ExitCode::from(2);
    }
    let f = measure_floor(1.0 / rate, duration, fifo);
    if json {
        super::print_json(&f);
    } else {
        let l = &f.lateness;
        out!(
            "bare sleep loop at {rate} Hz for {duration} s (SCHED_FIFO: {}): lateness p50 {} ns, p90 {} ns, p99 {} ns, p99.9 {} ns, max {} ns over {} cycles",
            f.rt.sched_fifo, l.p50_ns, l.p90_ns, l.p99_ns, l.p99_9_ns, l.max_ns, l.count
        );
        for n in &f.rt.notes {
            out!("note: {n}");
        }
    }
    ExitCode::SUCCESS
}
