//! `evoloop bench latency | latency-peer | loop | dynamics | guard`: the options, and the tables
//! they print. The measurements live in `evoloop_run::bench`.

use clap::Args;
use evoloop_run::bench::guard::HotPath;
use evoloop_run::bench::latency::{self, Variant};
use evoloop_run::bench::loop_bench::{self, Load};
use std::path::PathBuf;

/// Options of `evoloop bench latency`: the plant -> controller -> plant round trip against a bare
/// iceoryx2 ping-pong.
#[derive(Args)]
pub struct LatencyArgs {
    /// Timed round trips per variant.
    #[arg(long, default_value_t = 20_000)]
    pub samples: usize,
    /// Interleaved rounds the round trips are taken in: each round times every variant once,
    /// each evoloop variant right after its bare reference, so both see the same machine.
    #[arg(long, default_value_t = 5)]
    pub rounds: usize,
    /// Payload of the bare ping-pong in bytes (default: the size of the evoloop state message).
    #[arg(long)]
    pub payload: Option<usize>,
    /// Print the report as JSON on stdout instead of the table
    #[arg(long)]
    pub json: bool,
    /// Write latency.json, latency.csv and latency_cdf.png here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Options of the hidden `evoloop bench latency-peer`, the peer process that `bench latency`
/// starts with exactly these arguments.
#[derive(Args)]
pub struct PeerArgs {
    /// Round trip to answer: evoloop state/command or the bare ping-pong, busy-poll or event
    #[arg(long, value_parser = crate::choice::choice(&Variant::ALL, Variant::arg))]
    pub variant: Variant,
    /// Prefix of the iceoryx2 resources of the measuring process, so both open the same services
    #[arg(long)]
    pub prefix: String,
    /// Run id the measuring process chose for this variant, part of every service name
    #[arg(long)]
    pub run_id: String,
    /// Payload of the bare ping-pong in bytes (ignored by the evoloop variants)
    #[arg(long)]
    pub payload: usize,
}

/// `evoloop bench latency`: every variant, then the table (or JSON) and the files.
pub fn latency(a: LatencyArgs) -> i32 {
    if a.samples < 100 || a.samples > 10_000_000 {
        eprintln!("error: --samples must be in 100..=10000000");
        return 2;
    }
    let payload = a
        .payload
        .unwrap_or(std::mem::size_of::<evoloop_msg::PlantState>());
    if payload == 0 || payload > 1 << 20 {
        eprintln!("error: --payload must be in 1..=1048576 bytes");
        return 2;
    }
    if a.rounds == 0 || a.samples / a.rounds < 100 {
        eprintln!("error: --rounds must be at least 1 and leave 100 round trips a round (--samples / --rounds >= 100)");
        return 2;
    }
    let bar = evoloop_report::progress::stages(4 * a.rounds as u64, "variants", a.json);
    let progress = |v: Variant, round: usize| {
        bar.inc_stage(&format!(
            "{} (round {} of {})",
            v.name(),
            round + 1,
            a.rounds
        ));
    };
    let latency::Measured {
        report,
        results,
        raw,
    } = match latency::measure(a.samples, a.rounds, payload, &progress) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return 1;
        }
    };
    if a.json {
        super::print_json(&report);
    } else {
        out!(
            "round trip, {payload}-byte payload, {} samples per variant in {} interleaved rounds (ns):",
            a.samples,
            a.rounds
        );
        out!(
            "{:<14} {:>8} {:>8} {:>8} {:>8} {:>9} {:>9} {:>10}  ratio p50 / p99.9 to bare",
            "variant",
            "min",
            "p50",
            "p90",
            "p99",
            "p99.9",
            "p99.99",
            "max"
        );
        for r in &results {
            let ratio = match (r.ratio_p50, r.ratio_p99_9) {
                (Some(a), Some(b)) => format!("{a:.2} / {b:.2}"),
                _ => "(reference)".into(),
            };
            let [min, p50, p90, p99, p99_9, p99_99, max] = r.figures();
            out!(
                "{:<14} {min:>8} {p50:>8} {p90:>8} {p99:>8} {p99_9:>9} {p99_99:>9} {max:>10}  {ratio}",
                r.variant.name(),
            );
        }
        for r in results.iter().filter(|r| !r.ratio_p50_rounds.is_empty()) {
            let each: Vec<String> = r
                .ratio_p50_rounds
                .iter()
                .map(|x| format!("{x:.2}"))
                .collect();
            out!(
                "{} p50 ratio by round: {}",
                r.variant.name(),
                each.join(" ")
            );
        }
    }
    if let Some(dir) = &a.out {
        if let Err(e) = latency::write_out(dir, &report, &results, &raw) {
            eprintln!("error: {e}");
            return 1;
        }
    }
    0
}

/// `evoloop bench latency-peer` (started by `bench latency`).
pub fn latency_peer(a: PeerArgs) -> i32 {
    match latency::peer(a.variant, &a.prefix, &a.run_id, a.payload) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("latency-peer: error: {e}");
            1
        }
    }
}

/// Options of `evoloop bench loop`: the controller loop's timing at a rate, under load, against the
/// bare sleep-loop floor.
#[derive(Args)]
pub struct LoopArgs {
    /// Loop rate in Hz (1000 and 10000 are the usual ones). Default: 1000 on the built-in
    /// two-mass loop, a `--scenario`'s own rate (which it must match if given).
    #[arg(long)]
    pub rate: Option<f64>,
    /// Run this scenario (realtime, for `--duration`) instead of the built-in two-mass loop,
    /// e.g. config/arm7/arm7_ct.toml for the 7-DOF computed-torque loop at 10 kHz.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// How the controller and the plant wait: sleep, spin or hybrid (default: the scenario's
    /// `timing.wait`; sleep on the built-in loop). The floor waits the same way.
    #[arg(long, value_parser = crate::choice::choice(&evoloop_rt::WaitKind::ALL, evoloop_rt::WaitKind::name))]
    pub wait: Option<evoloop_rt::WaitKind>,
    /// Seconds per measurement.
    #[arg(long, default_value_t = 5.0)]
    pub duration: f64,
    /// What else runs during each measurement: nothing, the live optimiser or a busy thread per CPU
    #[arg(long, value_parser = crate::choice::choice(&Load::ALL, Load::name), default_value = "off")]
    pub load: Load,
    /// Only with SCHED_FIFO/mlockall (default: with and without).
    #[arg(long)]
    pub rt_only: bool,
    /// Print the report as JSON on stdout instead of the table
    #[arg(long)]
    pub json: bool,
    /// Output directory (runs, loop.json, loop_lateness.png).
    #[arg(long, default_value = "runs/bench_loop")]
    pub out: PathBuf,
}

/// `evoloop bench loop`: the measurements, then the table (or JSON).
pub fn loop_(a: LoopArgs) -> i32 {
    let what = a
        .scenario
        .as_ref()
        .map_or("the two-mass loop".to_string(), |p| p.display().to_string());
    let bar = evoloop_report::progress::stages(if a.rt_only { 1 } else { 2 }, "settings", a.json);
    let progress = |name: &str| {
        bar.inc_stage(&format!(
            "{what}, {name}, load {:?}: {} s and the floor after it",
            a.load, a.duration
        ));
    };
    let spec = loop_bench::LoopSpec {
        rate: a.rate,
        duration: a.duration,
        load: a.load,
        rt_only: a.rt_only,
        wait: a.wait,
        scenario: a.scenario.clone(),
    };
    let loop_bench::Measured { report, results } =
        match loop_bench::measure(&spec, &a.out, &progress) {
            Ok(m) => m,
            Err(e) => {
                eprintln!("error: {e}");
                return e.code();
            }
        };
    if a.json {
        super::print_json(&report);
    } else {
        out!(
            "controller loop of {what} at {} Hz for {} s, load {:?} (ns):",
            report["rate_hz"],
            a.duration,
            a.load
        );
        out!("{:<7} {:<9} {:>8} {:>8} {:>9} {:>10} {:>9} {:>9} {:>8} {:>7}  floor p50/p99/p99.9      ratio p99 (p99.9)", "privs", "what", "p50", "p99", "p99.9", "max", "compute50", "age p50", "overrun", "missed");
        for r in &results {
            let s = &r.summary;
            let l = &s.timing.lateness;
            let f = s.floor.clone().unwrap_or_default();
            out!(
                "{:<7} {:<9} {:>8} {:>8} {:>9} {:>10} {:>9} {:>9} {:>8} {:>7}  {}/{}/{}  {:.2} ({:.2})",
                r.privileges, "lateness", l.p50_ns, l.p99_ns, l.p99_9_ns, l.max_ns, s.timing.compute.p50_ns,
                s.timing.state_age.p50_ns, s.overruns, s.deadline_misses,
                f.lateness.p50_ns, f.lateness.p99_ns, f.lateness.p99_9_ns, f.ratio_p99, f.ratio_p99_9
            );
        }
        for (r, row) in results
            .iter()
            .zip(report["results"].as_array().into_iter().flatten())
        {
            let s = &r.summary;
            out!(
                "{:<7} wait {}: misses per 10^6 cycles {:.1} (floor: {:.1} periods lost per 10^6), compute p99 {} ns, controller/floor lateness p99 {:.2}, optimiser {:.2} cores ({:.1} s CPU)",
                r.privileges,
                s.wait.map_or("-".into(), |w| w.describe()),
                row["misses_per_million"].as_f64().unwrap_or(0.0),
                row["floor_lost_per_million"].as_f64().unwrap_or(0.0),
                s.timing.compute.p99_ns,
                row["ratio_p99"].as_f64().unwrap_or(0.0),
                s.optimiser_load_cores,
                s.optimiser_cpu_s,
            );
        }
        out!(
            "wrote {}/loop.json, loop_lateness.png and the runs",
            a.out.display()
        );
    }
    0
}

/// Options of `evoloop bench dynamics`: nanoseconds per call of RNEA, CRBA, ABA and the CRBA
/// forward dynamics on one robot file.
#[derive(Args)]
pub struct DynamicsArgs {
    /// Robot description: a D-H table (.toml) or a URDF file (.urdf).
    #[arg(long)]
    pub robot: PathBuf,
    /// Timed calls per algorithm (64 random states in [-1, 1], cycled).
    #[arg(long, default_value_t = 200_000)]
    pub calls: u64,
    /// Print the timings as JSON on stdout instead of the table
    #[arg(long)]
    pub json: bool,
}

/// `evoloop bench dynamics`: ns per call of each algorithm on one robot.
pub fn dynamics(a: DynamicsArgs) -> i32 {
    if !(1000..=1_000_000_000).contains(&a.calls) {
        eprintln!("error: --calls must be in 1000..=1000000000");
        return 2;
    }
    let model = match evoloop_dynamics::load(&a.robot) {
        Ok(m) => m,
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    };
    let b = evoloop_run::bench::dynamics::measure(&model, a.calls);
    if a.json {
        super::print_json(&b);
    } else {
        let p = &b.ns_per_call;
        out!(
            "{} ({} joints), {} calls each, rigid body (no friction), ns per call:",
            a.robot.display(),
            b.joints,
            b.calls
        );
        out!("  inverse dynamics (RNEA)              {:>8.1}", p.rnea);
        out!("  M(q) (CRBA)                          {:>8.1}", p.crba);
        out!("  forward dynamics (ABA)               {:>8.1}", p.aba);
        out!(
            "  forward dynamics (RNEA+CRBA+Cholesky){:>8.1}",
            p.forward_crba
        );
    }
    0
}

/// Options of `evoloop bench guard`: the hot paths against references timed in the same run.
#[derive(Args)]
pub struct GuardArgs {
    /// Interleaved rounds of short batches per measurement of a compute path (each side's
    /// fastest batch is kept; the round trips always take five rounds of 1000).
    #[arg(long, default_value_t = 101)]
    pub rounds: usize,
    /// Only these paths, comma-separated (default: all).
    #[arg(long, value_parser = crate::choice::described(&HotPath::ALL, HotPath::name, |p| Some(p.what())),
          value_delimiter = ',')]
    pub paths: Option<Vec<HotPath>>,
    /// Every limit times this: the guard's own test of its failure path.
    #[arg(long, default_value_t = 1.0, hide = true)]
    pub limit_scale: f64,
    /// Print the report as JSON on stdout instead of the table
    #[arg(long)]
    pub json: bool,
    /// Write guard.json here.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// `evoloop bench guard`: every hot path's ratio to its reference against its limit; exit 1 if
/// one is over it on every attempt.
pub fn guard(a: GuardArgs) -> i32 {
    use evoloop_run::bench::guard;
    if !(1..=1001).contains(&a.rounds) {
        eprintln!("error: --rounds must be in 1..=1001");
        return 2;
    }
    if !(a.limit_scale.is_finite() && a.limit_scale > 0.0) {
        eprintln!("error: --limit-scale must be a positive number");
        return 2;
    }
    let paths = a.paths.clone().unwrap_or(HotPath::ALL.to_vec());
    let plan = guard::Plan {
        paths: &paths,
        rounds: a.rounds,
        limit_scale: a.limit_scale,
    };
    let bar = evoloop_report::progress::stages(paths.len() as u64, "paths", a.json);
    let progress = |p: HotPath, attempt: usize| {
        if attempt == 1 {
            bar.inc_stage(p.name());
        } else {
            bar.set_message(&format!(
                "{} (attempt {attempt}: the last was over its limit)",
                p.name()
            ));
        }
    };
    let verdicts = match guard::run(&plan, &progress) {
        Ok(v) => v,
        Err(e) => {
            eprintln!("error: {e}");
            return 1;
        }
    };
    let report = guard::report(&plan, &verdicts);
    if a.json {
        super::print_json(&report);
    } else {
        out!(
            "hot paths against references timed in this run (ratio = hot / reference; fails above {}x the recorded ratio):",
            guard::FACTOR * a.limit_scale
        );
        out!(
            "{:<17} {:>11} {:>13} {:>7} {:>9} {:>7}  verdict",
            "path",
            "hot ns",
            "reference ns",
            "ratio",
            "recorded",
            "limit"
        );
        for v in &verdicts {
            let best = v
                .attempts
                .iter()
                .find(|r| r.ratio == v.ratio)
                .copied()
                .unwrap_or(v.attempts[0]);
            out!(
                "{:<17} {:>11.1} {:>13.1} {:>7.3} {:>9.3} {:>7.3}  {}{}",
                v.path.name(),
                best.hot_ns,
                best.reference_ns,
                v.ratio,
                v.recorded,
                v.limit,
                if v.pass { "ok" } else { "SLOWER" },
                if v.attempts.len() > 1 {
                    format!(" ({} attempts)", v.attempts.len())
                } else {
                    String::new()
                }
            );
        }
    }
    if let Some(dir) = &a.out {
        if let Err(e) = evoloop_report::write_json(dir, "guard.json", &report) {
            eprintln!("error: {}: {e}", dir.join("guard.json").display());
            return 1;
        }
    }
    let slower: Vec<String> = verdicts
        .iter()
        .filter(|v| !v.pass)
        .map(|v| {
            format!(
                "{} at {:.3}x its reference on every one of {} attempts, limit {:.3}: {}",
                v.path.name(),
                v.ratio,
                v.attempts.len(),
                v.limit,
                v.what
            )
        })
        .collect();
    for s in &slower {
        eprintln!("error: hot path slower: {s}");
    }
    i32::from(!slower.is_empty())
}
