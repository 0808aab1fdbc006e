//! `evoloop floor`: the bare loop's lateness on this machine (what realtime runs are judged
//! against), for each wait strategy.

use clap::Args;
use evoloop_rt::{WaitKind, WaitStrategy};
use evoloop_run::node::launcher::measure_floor;
use std::process::ExitCode;

/// Options of `evoloop floor`: the bare absolute-deadline loop's rate, length, wait strategy and
/// scheduling.
#[derive(Debug, Clone, Args)]
pub struct FloorArgs {
    /// Loop rate in Hz.
    #[arg(long, default_value_t = 1000.0)]
    pub rate: f64,
    /// Seconds to run.
    #[arg(long, default_value_t = 5.0)]
    pub duration: f64,
    /// Ask for SCHED_FIFO with this priority (falls back when not permitted).
    #[arg(long)]
    pub fifo: Option<i32>,
    /// Pin the loop to this CPU.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// How the loop waits: sleep, spin or hybrid (as `timing.wait`).
    #[arg(long, value_parser = crate::choice::choice(&WaitKind::ALL, WaitKind::name), default_value = "sleep")]
    pub wait: WaitKind,
    /// Hybrid: stop sleeping this many microseconds before the deadline, then spin (default as
    /// `timing.wait_margin_us`: 100, at most 80 % of the period).
    #[arg(long)]
    pub margin_us: Option<f64>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `evoloop floor`: measure the bare loop's lateness and print it as a line or JSON. Exit code 2
/// when the rate, duration or margin is out of range.
pub fn main(a: &FloorArgs) -> ExitCode {
    let rate_ok = a.rate > 0.0 && a.rate <= 100_000.0;
    let duration_ok = a.duration > 0.0 && a.duration <= 3600.0;
    if !rate_ok || !duration_ok {
        err!("error: --rate must be in (0, 100000] Hz and --duration in (0, 3600] s");
        return ExitCode::from(2);
    }
    let period = 1.0 / a.rate;
    let margin_us = a
        .margin_us
        .unwrap_or_else(|| evoloop_scenario::config::default_margin_us(period));
    if !(margin_us >= 0.0 && margin_us <= period * 1e6) {
        err!(
            "error: --margin-us must be within [0, {}] (the period)",
            period * 1e6
        );
        return ExitCode::from(2);
    }
    let wait = WaitStrategy::new(a.wait, margin_us);
    let f = measure_floor(period, a.duration, a.fifo, a.cpu, wait);
    if a.json {
        super::print_json(&f);
    } else {
        let l = &f.lateness;
        out!(
            "bare {} loop at {} Hz for {} s (SCHED_FIFO: {}, cpu {}): lateness p50 {} ns, p90 {} ns, p99 {} ns, p99.9 {} ns, max {} ns over {} cycles, {} periods lost",
            wait.describe(),
            a.rate,
            a.duration,
            f.rt.sched_fifo,
            f.rt.cpu.map_or("any".into(), |c| c.to_string()),
            l.p50_ns,
            l.p90_ns,
            l.p99_ns,
            l.p99_9_ns,
            l.max_ns,
            l.count,
            f.lost_periods
        );
        for n in &f.rt.notes {
            out!("note: {n}");
        }
    }
    ExitCode::SUCCESS
}
