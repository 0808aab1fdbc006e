//! `evoloop bench loop`: the real controller loop (plant, controller and optimiser processes in
//! realtime mode, on the two-mass scenario or a given one) at a given rate, under a chosen
//! background load, with and without real-time privileges, with a chosen wait strategy; each
//! run also measures the bare absolute-deadline loop at the same period, priority, CPU and wait
//! strategy under the same load, as the machine's floor.

use crate::node::start::Failure;
use crate::report::plot::{xy_png, Style, XySeries};
use crate::report::Table;
use crate::run_report::summary::Summary;
use serde::Serialize;
use std::path::Path;
use std::process::{Child, Command};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The background load `bench loop` measures the loop under.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Load {
    /// Nothing else running.
    Off,
    /// The live optimiser busy in the run: on the built-in scenario the indirect scheme's DE
    /// epochs on the model, back to back on 2 threads at nice 10 (`optimiser.mode = "indirect"`),
    /// for the whole measurement; with `--scenario`, that scenario's own optimiser.
    Optimiser,
    /// One busy-looping thread per CPU at normal priority.
    Hog,
}

impl Load {
    /// Every load, as `--load` lists them.
    pub const ALL: [Load; 3] = [Load::Off, Load::Optimiser, Load::Hog];

    /// The load's name on the command line and in results: `off`, `optimiser` or `hog`.
    pub fn name(self) -> &'static str {
        match self {
            Load::Off => "off",
            Load::Optimiser => "optimiser",
            Load::Hog => "hog",
        }
    }
}

/// One run of `bench loop`: its setting and the summary.json it wrote.
#[derive(Debug, Clone, Serialize)]
pub struct LoopResult {
    /// `"fifo"` (SCHED_FIFO and mlockall) or `"no_rt"` (run with `--no-rt`): also the name of
    /// the run's directory under `out`.
    pub privileges: String,
    /// The background load it ran under.
    pub load: Load,
    /// The controller's rate, Hz.
    pub rate_hz: f64,
    /// The run's summary.json: its cycles, misses, lateness and the floor measured beside it.
    pub summary: Summary,
}

fn scenario(rate: f64, duration: f64, optimiser_busy: bool) -> String {
    let optimiser = if optimiser_busy {
        "[optimiser]\nmode = \"indirect\"\nnice = 10\nthreads = 2\n"
    } else {
        "[optimiser]\nmode = \"off\"\n"
    };
    format!(
        r#"name = "bench_loop"
[plant]
kind = "two_mass"
step = {step}
[controller]
kind = "state_feedback"
[controller.state_feedback]
gains = [18.49, 19.04, 47.27, 7.30, -10.54]
[reference]
kind = "square"
amplitude = 0.5
offset = 0.5
period = 10.0
[timing]
mode = "realtime"
period = {period}
duration = {duration}
fifo_priority = 80
plant_fifo_priority = 70
lock_memory = true
measure_floor = true
{optimiser}"#,
        period = 1.0 / rate,
        step = (1.0 / rate).min(5e-4),
    )
}

/// Start the background load; the returned guard stops it.
struct LoadGuard {
    stop: Arc<AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
    child: Option<Child>,
}

impl Drop for LoadGuard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        if let Some(c) = &mut self.child {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

fn start_load(load: Load) -> std::io::Result<LoadGuard> {
    let stop = Arc::new(AtomicBool::new(false));
    let mut g = LoadGuard {
        stop: stop.clone(),
        threads: Vec::new(),
        child: None,
    };
    match load {
        Load::Off => {}
        Load::Hog => {
            let n = std::thread::available_parallelism()
                .map(|n| n.get())
                .unwrap_or(2);
            for _ in 0..n {
                let s = stop.clone();
                g.threads.push(std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !s.load(Ordering::Relaxed) {
                        x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                        std::hint::black_box(x);
                    }
                }));
            }
        }
        // The load is the run's own optimiser process (see `scenario`).
        Load::Optimiser => {}
    }
    Ok(g)
}

fn run_once(out: &Path, cfg: &Path, no_rt: bool, spec: &LoopSpec) -> Result<Summary, String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let mut cmd = Command::new(exe);
    cmd.arg("run").arg(cfg).arg("--out").arg(out).arg("--quiet");
    // The floor as long as the run: a stall that comes once a minute must have the same
    // chance to show in both.
    let secs = spec.duration.to_string();
    cmd.args([
        "--mode",
        "realtime",
        "--duration",
        &secs,
        "--floor-duration",
        &secs,
    ]);
    if no_rt {
        cmd.arg("--no-rt");
    }
    if let Some(w) = spec.wait {
        cmd.args(["--wait", w.name()]);
    }
    // A given scenario's optimiser runs only as the `optimiser` load.
    if spec.scenario.is_some() && spec.load != Load::Optimiser {
        cmd.args(["--optimiser", "off"]);
    }
    let o = cmd.output().map_err(|e| e.to_string())?;
    if !o.status.success() {
        return Err(format!(
            "run failed: {}",
            String::from_utf8_lossy(&o.stderr)
        ));
    }
    crate::report::read_json(out, "summary.json").map_err(|e| e.to_string())
}

/// What one `evoloop bench loop` measured, and its JSON report (also written as loop.json).
pub struct Measured {
    /// loop.json's content: the setting, and each run's cycles, misses, lateness and floor.
    pub report: serde_json::Value,
    /// One result per run: `fifo` first, then `no_rt` unless `rt_only`.
    pub results: Vec<LoopResult>,
}

/// What to measure.
#[derive(Debug, Clone)]
pub struct LoopSpec {
    /// Hz; None: 1000 on the built-in scenario, a given scenario's own rate.
    pub rate: Option<f64>,
    /// Length of each run, s, and of the floor measured beside it; in [0.5, 3600].
    pub duration: f64,
    /// The background load to run under.
    pub load: Load,
    /// Only with SCHED_FIFO/mlockall.
    pub rt_only: bool,
    /// The wait strategy; None: the scenario's (`timing.wait`; sleep on the built-in one).
    pub wait: Option<crate::rt::WaitKind>,
    /// A scenario file to run instead of the built-in two-mass loop.
    pub scenario: Option<std::path::PathBuf>,
}

/// The scenario file to run and its rate: the built-in one written to `out`, or the given one
/// (checked: it loads, and runs at `rate` if one is asked for).
fn scenario_file(spec: &LoopSpec, out: &Path) -> Result<(std::path::PathBuf, f64), Failure> {
    let Some(path) = &spec.scenario else {
        let rate = spec.rate.unwrap_or(1000.0);
        let cfg = out.join("bench_loop.toml");
        crate::files::write(
            &cfg,
            scenario(rate, spec.duration, spec.load == Load::Optimiser),
        )
        .map_err(|e| Failure::Failed(e.to_string()))?;
        return Ok((cfg, rate));
    };
    let scn = crate::config::Scenario::load(path, &crate::config::Overrides::default())
        .map_err(|e| Failure::Setup(e.to_string()))?;
    let own = 1.0 / scn.timing.period;
    if let Some(r) = spec.rate {
        if (r - own).abs() > 1e-6 * own {
            return Err(Failure::Setup(format!(
                "--rate {r} Hz, but {} runs at {own} Hz (timing.period = {} s)",
                path.display(),
                scn.timing.period
            )));
        }
    }
    if spec.load == Load::Optimiser && scn.optimiser.mode == crate::config::OptimiserMode::Off {
        return Err(Failure::Setup(format!(
            "--load optimiser, but {} has no optimiser (optimiser.mode = \"off\")",
            path.display()
        )));
    }
    Ok((path.clone(), own))
}

/// Measure the loop as `spec` says, with SCHED_FIFO/mlockall and (unless `rt_only`) without;
/// runs, loop.json and loop_lateness.png go to `out`. `progress` is told each setting as it
/// starts. Errors carry the exit code: 2 for bad arguments.
pub fn measure(spec: &LoopSpec, out: &Path, progress: &dyn Fn(&str)) -> Result<Measured, Failure> {
    let (duration, load, rt_only) = (spec.duration, spec.load, spec.rt_only);
    if let Some(rate) = spec.rate {
        if !(10.0..=20_000.0).contains(&rate) {
            return Err(Failure::Setup(format!(
                "--rate must be in [10, 20000] Hz (got {rate})"
            )));
        }
    }
    if !(0.5..=3600.0).contains(&duration) {
        return Err(Failure::Setup(format!(
            "--duration must be in [0.5, 3600] s (got {duration})"
        )));
    }
    std::fs::create_dir_all(out).map_err(|e| Failure::Failed(format!("{}: {e}", out.display())))?;
    let (cfg, rate) = scenario_file(spec, out)?;
    let _load = start_load(load)
        .map_err(|e| Failure::Failed(format!("cannot start the {load:?} load: {e}")))?;
    let settings: &[(&str, bool)] = if rt_only {
        &[("fifo", false)]
    } else {
        &[("fifo", false), ("no_rt", true)]
    };
    let mut results = Vec::new();
    for (name, no_rt) in settings {
        progress(name);
        let summary = run_once(&out.join(name), &cfg, *no_rt, spec).map_err(Failure::Failed)?;
        results.push(LoopResult {
            privileges: name.to_string(),
            load,
            rate_hz: rate,
            summary,
        });
    }
    let table: Vec<serde_json::Value> = results
        .iter()
        .map(|r| {
            let s = &r.summary;
            let l = &s.timing.lateness;
            let f = s.floor.clone().unwrap_or_default();
            serde_json::json!({
                "privileges": r.privileges, "load": r.load, "rate_hz": r.rate_hz,
                "sched_fifo": s.realtime_privileges.controller.sched_fifo,
                "wait": s.wait,
                "cycles": s.samples, "overruns": s.overruns, "deadline_misses": s.deadline_misses,
                "misses_per_million": per_million(s.deadline_misses, s.samples),
                "floor_lost_per_million": per_million(f.lost_periods, f.lateness.count),
                "stale_states": s.timing.stale_states,
                "lateness": l, "compute": s.timing.compute, "state_age": s.timing.state_age,
                "floor_lateness": f.lateness,
                "ratio_p50": f.ratio_p50, "ratio_p99": f.ratio_p99, "ratio_p99_9": f.ratio_p99_9,
                "optimiser_cpu_s": s.optimiser_cpu_s, "optimiser_load_cores": s.optimiser_load_cores,
            })
        })
        .collect();
    let report = serde_json::json!({
        "rate_hz": rate, "duration_s": duration, "load": load,
        "scenario": spec.scenario.as_ref().map(|p| p.display().to_string()),
        "results": table,
    });
    crate::report::write_json(out, "loop.json", &report)
        .map_err(|e| Failure::Failed(format!("loop.json: {e}")))?;
    plot(out, &results).map_err(|e| Failure::Failed(format!("plot: {e}")))?;
    Ok(Measured { report, results })
}

/// Events per million cycles.
fn per_million(events: u64, cycles: u64) -> f64 {
    if cycles == 0 {
        0.0
    } else {
        events as f64 * 1e6 / cycles as f64
    }
}

/// Lateness over time of each measured run.
fn plot(dir: &Path, results: &[LoopResult]) -> Result<(), String> {
    let mut curves = Vec::new();
    for r in results {
        let t =
            Table::read(&dir.join(&r.privileges).join("timing.csv")).map_err(|e| e.to_string())?;
        let cycle = t.col("cycle").unwrap_or_default();
        let late: Vec<f64> = t
            .col("lateness_ns")
            .unwrap_or_default()
            .iter()
            .map(|v| v / 1000.0)
            .collect();
        let secs: Vec<f64> = cycle.iter().map(|c| c / r.rate_hz).collect();
        curves.push((format!("{} lateness", r.privileges), secs, late));
    }
    let series = XySeries::from_curves(&curves, Style::Points);
    xy_png(
        &dir.join("loop_lateness.png"),
        "Controller wake-up lateness over time",
        "t [s]",
        "lateness [µs]",
        &series,
        None,
        None,
    )
    .map_err(|e| e.to_string())
}
