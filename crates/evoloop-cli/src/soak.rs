//! `evoloop soak`: run a scenario in realtime for a long time with the optimiser tuning, and
//! report per interval the memory of every process, missed deadlines and lateness (see
//! `evoloop_run::soak`).

use evoloop_run::soak::{
    drift, rss_kib, run_processes, write, Interval, IntervalTiming, SoakReport, Tail,
};
use evoloop_scenario::config::{Overrides, Scenario};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

/// Options of `evoloop soak`: the scenario, how long it runs in realtime, how often it is
/// recorded, and where the report goes.
#[derive(clap::Args)]
pub struct SoakArgs {
    /// Seconds to run (the book's figure: 3600).
    #[arg(long)]
    pub duration: f64,
    /// Scenario to run in realtime [default: config/two_mass/two_mass_indirect.toml, the indirect scheme
    /// tuning all run long].
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Seconds between two records.
    #[arg(long, default_value_t = 60.0)]
    pub interval: f64,
    /// Output directory: soak.json, soak.csv, soak_rss.png, soak_timing.png, and the run's own
    /// report in `run/`.
    #[arg(long, default_value = "runs/soak")]
    pub out: PathBuf,
    /// Without SCHED_FIFO, mlockall and CPU pinning (as an unprivileged user gets).
    #[arg(long)]
    pub no_rt: bool,
    /// Print the report as JSON at the end instead of the summary lines.
    #[arg(long)]
    pub json: bool,
}

/// `evoloop soak`: run the scenario in realtime under `evoloop run`, record every process's
/// memory and the loop's timing per interval, write and print the report. Exit code 0 when the run
/// ended normally; 1 when it could not start, did not end normally or the report could not be
/// written; 2 for a bad argument.
pub fn main(a: SoakArgs) -> ExitCode {
    let (file, scn) = match prepare(&a) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let run_dir = a.out.join("run");
    let run_id = format!("soak-{}", std::process::id());
    let prefix = evoloop_ipc::DEFAULT_PREFIX;
    let shm_before = evoloop_ipc::namespace::files(prefix);
    let stop = crate::stop_flag();
    let launcher = match start_run(&a, &file, &run_dir, &run_id) {
        Ok(c) => c,
        Err(e) => {
            err!("error: cannot start the run: {e}");
            return ExitCode::from(1);
        }
    };
    out!(
        "soak: {} for {} s in realtime, a record every {} s; run id {run_id}, output {}",
        file.display(),
        a.duration,
        a.interval,
        a.out.display()
    );
    let watched = watch(launcher, &a, &run_id, scn.period_ns(), &run_dir, &stop);
    let shm_after = evoloop_ipc::namespace::files(prefix);
    let report = soak_report(&a, &file, run_dir, run_id, watched, shm_before, shm_after);
    if let Err(e) = write(&a.out, &report) {
        err!("error: writing the soak report: {e}");
        return ExitCode::from(1);
    }
    if a.json {
        evoloop_report::print_json(&report);
    } else {
        print_report(&report, &a.out);
    }
    match report.exit_code {
        Some(0) => ExitCode::SUCCESS,
        _ => ExitCode::from(1),
    }
}

/// The arguments checked, the scenario loaded and the output directory made.
fn prepare(a: &SoakArgs) -> Result<(PathBuf, Scenario), ExitCode> {
    let refuse = |what: String| {
        err!("error: {what}");
        ExitCode::from(2)
    };
    if !(a.duration.is_finite() && a.duration > 0.0) {
        return Err(refuse(
            "--duration: must be a positive number of seconds".into(),
        ));
    }
    if !(a.interval.is_finite() && a.interval >= 1.0) {
        return Err(refuse("--interval: must be at least 1 s".into()));
    }
    let file = a.scenario.clone().unwrap_or_else(|| {
        evoloop_run::node::launcher::shipped("config/two_mass/two_mass_indirect.toml")
    });
    let ov = Overrides {
        duration: Some(a.duration),
        ..Default::default()
    };
    let scn = Scenario::load(&file, &ov).map_err(|e| refuse(e.to_string()))?;
    std::fs::create_dir_all(&a.out)
        .map_err(|e| refuse(format!("cannot create {}: {e}", a.out.display())))?;
    Ok((file, scn))
}

/// `evoloop run` of the scenario in realtime, as a child that dies with this process.
fn start_run(
    a: &SoakArgs,
    file: &Path,
    run_dir: &Path,
    run_id: &str,
) -> std::io::Result<std::process::Child> {
    let exe = std::env::current_exe().unwrap_or_else(|_| PathBuf::from("evoloop"));
    let mut cmd = std::process::Command::new(exe);
    cmd.arg("run")
        .arg(file)
        .args(["--mode", "realtime", "--duration"])
        .arg(a.duration.to_string())
        .arg("--out")
        .arg(run_dir)
        .args([
            "--run-id",
            run_id,
            "--ipc-prefix",
            evoloop_ipc::DEFAULT_PREFIX,
        ])
        .arg("--quiet");
    if a.no_rt {
        cmd.arg("--no-rt");
    }
    evoloop_run::node::launcher::die_with_parent(&mut cmd);
    cmd.spawn()
}

/// What watching the run gave: how it ended, its intervals, and the timing of the last partial
/// interval.
struct Watched {
    status: std::process::ExitStatus,
    intervals: Vec<Interval>,
    rest: IntervalTiming,
}

/// A record every interval until the run ends (or this process is stopped, which stops it).
fn watch(
    mut launcher: std::process::Child,
    a: &SoakArgs,
    run_id: &str,
    period_ns: u64,
    run_dir: &Path,
    stop: &std::sync::atomic::AtomicBool,
) -> Watched {
    let mut tail = Tail::new(run_dir.join("timing.csv"));
    let mut intervals: Vec<Interval> = Vec::new();
    let t0 = Instant::now();
    let mut next = a.interval;
    let mut timing = IntervalTiming::new(period_ns);
    let status = loop {
        std::thread::sleep(Duration::from_millis(200));
        tail.new_lines(|l| timing.line(l));
        let ended = launcher.try_wait().unwrap_or_else(|e| {
            err!("error: waiting for the run: {e}");
            None
        });
        let t = t0.elapsed().as_secs_f64();
        // A record every interval while the run goes on (not at its end: the processes are
        // gone or going, and the last partial interval would look like a drop in memory).
        if ended.is_none() && t >= next {
            match record(run_id, intervals.len(), t, &timing) {
                Some(iv) => {
                    // The next interval's timing starts now; a run that is ending keeps counting
                    // into this one, which the totals include.
                    timing = IntervalTiming::new(period_ns);
                    print_interval(&iv, a.duration);
                    intervals.push(iv);
                    next += a.interval;
                }
                // Past the loop's end (the launcher measures the floor and writes its report)
                // the processes are leaving: no more records.
                None => next = f64::INFINITY,
            }
        }
        if let Some(s) = ended {
            break s;
        }
        if stop.load(Ordering::Relaxed) {
            // A Ctrl-C at a terminal reaches the launcher too (same process group), a SIGINT or
            // SIGTERM sent to this process alone does not: pass it on, then wait for its report.
            evoloop_run::node::launcher::signal(&launcher, libc::SIGINT);
            if let Ok(s) = launcher.wait() {
                break s;
            }
        }
    };
    // What the controller wrote after the last look (it flushes before it exits).
    tail.new_lines(|l| timing.line(l));
    Watched {
        status,
        intervals,
        rest: timing,
    }
}

/// The soak's report: memory drift, misses per interval and over the whole run (the last
/// partial interval included), and the shared-memory files the run left behind.
fn soak_report(
    a: &SoakArgs,
    file: &Path,
    run_dir: PathBuf,
    run_id: String,
    w: Watched,
    shm_before: Vec<String>,
    shm_after: Vec<String>,
) -> SoakReport {
    let Watched {
        status,
        intervals,
        rest,
    } = w;
    let missed: Vec<u64> = intervals.iter().map(|i| i.missed_deadlines).collect();
    let per: Vec<f64> = missed.iter().map(|&m| m as f64).collect();
    let shm_left = shm_after
        .iter()
        .filter(|f| !shm_before.contains(f))
        .cloned()
        .collect();
    SoakReport {
        scenario: file.display().to_string(),
        duration_s: a.duration,
        interval_s: a.interval,
        run_dir,
        run_id,
        exit_code: status.code(),
        rss: drift(&intervals, |i| &i.rss_kib),
        anon: drift(&intervals, |i| &i.anon_kib),
        misses_per_interval_median: if per.is_empty() {
            0.0
        } else {
            evoloop_stats::median(&per)
        },
        misses_per_interval_max: missed.iter().copied().max().unwrap_or(0),
        missed_deadlines: missed.iter().sum::<u64>() + rest.missed,
        cycles: intervals.iter().map(|i| i.cycles).sum::<u64>() + rest.cycles,
        intervals,
        shm_before,
        shm_after,
        shm_left,
    }
}

/// One interval's record: each process's memory now and the loop's timing since the last record;
/// None once the controller is gone (the run is ending).
fn record(run_id: &str, index: usize, t: f64, done: &IntervalTiming) -> Option<Interval> {
    let memory: BTreeMap<String, (u64, Option<u64>)> = run_processes(run_id)
        .into_iter()
        .filter_map(|(name, pid)| rss_kib(pid).map(|r| (name, r)))
        .collect();
    let rss_kib: BTreeMap<String, u64> = memory.iter().map(|(n, m)| (n.clone(), m.0)).collect();
    if !rss_kib.contains_key("evoloop-controller") {
        return None;
    }
    let anon_kib = memory
        .into_iter()
        .filter_map(|(n, m)| m.1.map(|a| (n, a)))
        .collect();
    Some(Interval {
        index,
        t_s: t,
        rss_kib,
        anon_kib,
        cycles: done.cycles,
        missed_deadlines: done.missed,
        overruns: done.overruns,
        lateness: done.lateness.percentiles(),
    })
}

/// The progress line of one interval.
fn print_interval(iv: &Interval, duration: f64) {
    let mib = |n: &str| {
        iv.rss_kib
            .get(n)
            .map(|v| format!("{:.1}", *v as f64 / 1024.0))
            .unwrap_or_else(|| "-".into())
    };
    out!(
        "  {:>6.1} / {:.1} min  RSS MiB: launcher {} plant {} controller {} optimiser {}  cycles {} missed {} lateness p99 {:.1} us",
        iv.t_s / 60.0,
        duration / 60.0,
        mib("evoloop"),
        mib("evoloop-plant"),
        mib("evoloop-controller"),
        mib("evoloop-optimiser"),
        iv.cycles,
        iv.missed_deadlines,
        iv.lateness.p99_ns as f64 / 1e3
    );
}

/// The soak's findings in words (`--json` prints the report instead).
fn print_report(report: &SoakReport, out: &Path) {
    out!(
        "soak: {} cycles, {} missed deadlines (per interval: median {}, max {}); run exit {:?}",
        report.cycles,
        report.missed_deadlines,
        report.misses_per_interval_median,
        report.misses_per_interval_max,
        report.exit_code
    );
    for (name, d) in &report.rss {
        let anon = report.anon.get(name).map_or(String::new(), |a| {
            format!(
                "; anonymous {:.1} -> {:.1} MiB ({:+} KiB)",
                a.first_kib as f64 / 1024.0,
                a.last_kib as f64 / 1024.0,
                a.drift_kib
            )
        });
        out!(
            "  {name:<19} RSS {:.1} MiB after the first interval, {:.1} MiB at the end ({:+} KiB, {:+.2} %), max {:.1} MiB{anon}",
            d.first_kib as f64 / 1024.0,
            d.last_kib as f64 / 1024.0,
            d.drift_kib,
            d.drift_pct,
            d.max_kib as f64 / 1024.0
        );
    }
    out!(
        "  shared memory: {} file(s) before, {} after, {} left by the run{}",
        report.shm_before.len(),
        report.shm_after.len(),
        report.shm_left.len(),
        if report.shm_left.is_empty() {
            String::new()
        } else {
            format!(": {}", report.shm_left.join(", "))
        }
    );
    out!(
        "  wrote {}/soak.json, soak.csv, soak_rss.png, soak_timing.png; the run's report in {}",
        out.display(),
        report.run_dir.display()
    );
}
