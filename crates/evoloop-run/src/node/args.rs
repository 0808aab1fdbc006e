//! The options of a run and of its processes: what `evoloop run` takes and what the launcher
//! hands each child (which parses exactly these), so both sides share one definition.

use crate::config::{Mode, OptimiserMode, Overrides};
use clap::Args;
use std::path::PathBuf;

/// The options of `evoloop run`: the scenario file and its overrides, the run's id and IPC
/// prefix, its seeds, its floor, workers on this host and the live view.
#[derive(clap::Args)]
pub struct RunArgs {
    /// Scenario file (TOML) [default: config/two_mass/two_mass.toml, here or in the source tree]
    pub file: Option<PathBuf>,
    /// Overrides of the scenario file; the launcher passes them on to the run's processes.
    #[command(flatten)]
    pub overrides: OverrideArgs,
    /// Run id used in the service names: ASCII letters, digits, '_' and '-' (default:
    /// generated, unique on this machine).
    #[arg(long, value_parser = crate::ipc::parse_run_id)]
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files (separate namespace, e.g. for parallel tests).
    #[arg(long, default_value = crate::ipc::DEFAULT_PREFIX, value_parser = crate::ipc::parse_prefix)]
    pub ipc_prefix: String,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
    /// Several seeds, e.g. `1..20` (inclusive) or `1,4,9`, for a scenario with
    /// `optimiser.mode = "indirect"` or `"identify"`: one run per seed (in `<out>/seed-<n>/`),
    /// each against the frozen controller on the same seed (cost per repetition, or tracking RMS
    /// for identify); statistics and paired tests in `<out>/study.md`,
    /// `study.json`, `seeds.csv`, `study_cost.png`.
    #[arg(long, value_parser = parse_seeds, conflicts_with = "seed")]
    pub seeds: Option<Seeds>,
    /// Realtime: seconds of the bare loop measured after the run as its floor (default: the
    /// run's duration, at most 5 s). As long as the run, rare stalls of the machine have the
    /// same chance to show in the floor as in the run (`bench loop` does this).
    #[arg(long, value_parser = parse_floor_duration)]
    pub floor_duration: Option<f64>,
    /// Start N evaluation workers on this host (`evoloop worker`, one thread each) connected to
    /// the optimiser over Zenoh on loopback, for trying `optimiser.workers = "zenoh"` on one
    /// machine; summary.json reports `evaluations_remote` and `evaluations_local` (feature
    /// `zenoh`, indirect scenarios).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=64), conflicts_with = "workers_listen")]
    pub workers: Option<u16>,
    /// Serve the run live to Foxglove or PlotJuggler (Foxglove WebSocket protocol) on ADDR
    /// [default ADDR: 127.0.0.1:8765]: `evoloop live` started beside the run's processes, its
    /// own process, stopped with the run.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
    pub live: Option<String>,
    /// Let --live listen beyond loopback (e.g. 0.0.0.0:8765): anyone who reaches the port sees
    /// the run, and a viewer on another machine sets gains only with the token the live view
    /// prints (ws://HOST:PORT/?token=TOKEN). Without it such an ADDR is refused.
    #[arg(long, requires = "live")]
    pub live_remote: bool,
}

fn parse_floor_duration(s: &str) -> Result<f64, String> {
    seconds_in(s, 3600.0)
}

/// A time option's value: seconds in (0, `max`].
pub fn seconds_in(s: &str, max: f64) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v <= max => Ok(v),
        _ => Err(format!("{s:?}: seconds in (0, {max}]")),
    }
}

/// Options every process of a run receives from the launcher.
#[derive(Debug, Clone, Args)]
pub struct ProcessArgs {
    /// Scenario file (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// Run id: part of every service name, so runs never cross-talk.
    #[arg(long, value_parser = crate::ipc::parse_run_id)]
    pub run_id: String,
    /// Prefix of iceoryx2's files for this run.
    #[arg(long, default_value = crate::ipc::DEFAULT_PREFIX, value_parser = crate::ipc::parse_prefix)]
    pub ipc_prefix: String,
    /// `evoloop run`'s overrides of the scenario file, with `--out` set to the run's directory.
    #[command(flatten)]
    pub overrides: OverrideArgs,
}

/// The optimiser process's options: those of every process, and `--rejoin`.
#[derive(Debug, Clone, Args)]
pub struct OptimiserArgs {
    /// The options every process receives.
    #[command(flatten)]
    pub args: ProcessArgs,
    /// Rejoin a running run (started again after a crash): continue the version numbering and the
    /// set in service from `published.jsonl`, and release the plant's pending lockstep wait.
    #[arg(long)]
    pub rejoin: bool,
    /// Join the run from another host through its bridge (`evoloop bridge --run RUN_ID
    /// --listen ENDPOINT` there), e.g. `tcp/192.0.2.10:7447`: realtime runs only; needs the
    /// `zenoh` feature. The run's states, commands and telemetry come in over Zenoh, the sets go
    /// out to its controller, which validates them as any other.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Option<String>,
    /// A Zenoh configuration file (JSON5) for `--connect`: TLS, access control (see
    /// config/zenoh/).
    #[arg(long, value_name = "FILE", requires = "connect")]
    pub zenoh_config: Option<PathBuf>,
}

/// Overrides of the scenario file, accepted by `evoloop run` and passed on to the children.
#[derive(Debug, Clone, Default, Args)]
pub struct OverrideArgs {
    /// Timing mode: lockstep (reproducible, as fast as possible) or realtime (wall clock).
    #[arg(long)]
    pub mode: Option<Mode>,
    /// Run length in simulated seconds, or `forever` to run until Ctrl-C (as a scenario
    /// without `timing.duration` does). Default: the scenario's.
    #[arg(long, value_parser = crate::config::parse_duration)]
    pub duration: Option<f64>,
    /// Output directory for run.csv, summary.json and the plots.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Seed of every random number generator in the run.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Optimiser mode: off (listens only), schedule (publishes the configured sets) or indirect
    /// (estimates the model online, tunes on it, publishes better sets).
    #[arg(long)]
    pub optimiser: Option<OptimiserMode>,
    /// Realtime mode without SCHED_FIFO, mlockall or CPU pinning, whatever the scenario asks.
    #[arg(long)]
    pub no_rt: bool,
    /// How the realtime controller and plant wait for each deadline: sleep (no CPU, the kernel's
    /// wake-up lateness), spin (a core held, clock-read lateness) or hybrid (sleep until
    /// `timing.wait_margin_us` before it, then spin). Default: the scenario's `timing.wait`.
    #[arg(long)]
    pub wait: Option<crate::rt::WaitKind>,
    /// Evaluation workers on other hosts for the optimiser (`--workers-listen`,
    /// `--workers-expect`).
    #[command(flatten)]
    pub remote: WorkersArgs,
}

/// Evaluation workers on other hosts, for `run` (the optimiser) and `tune`.
#[derive(Debug, Clone, Default, Args)]
pub struct WorkersArgs {
    /// Take evaluation workers (`evoloop worker --connect ENDPOINT` on any host) on this Zenoh
    /// endpoint, e.g. `tcp/0.0.0.0:7448`; for a run, `optimiser.workers = "zenoh"` with
    /// `workers_listen` set (feature `zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    pub workers_listen: Option<String>,
    /// Evaluation workers to wait for (up to 8 s) before starting.
    #[arg(long, value_name = "N")]
    pub workers_expect: Option<usize>,
}

impl OverrideArgs {
    /// These options as the `Overrides` a scenario is loaded with.
    pub fn to_overrides(&self) -> Overrides {
        Overrides {
            mode: self.mode,
            duration: self.duration,
            seed: self.seed,
            out: self.out.clone(),
            optimiser: self.optimiser,
            no_rt: self.no_rt,
            wait: self.wait,
            workers_listen: self.remote.workers_listen.clone(),
            workers_expect: self.remote.workers_expect,
        }
    }

    /// The same options as command-line arguments for a child process.
    pub fn to_args(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(m) = self.mode {
            a.push("--mode".into());
            a.push(m.to_string());
        }
        if let Some(d) = self.duration {
            a.push("--duration".into());
            a.push(d.to_string());
        }
        if let Some(o) = &self.out {
            a.push("--out".into());
            a.push(o.display().to_string());
        }
        if let Some(s) = self.seed {
            a.push("--seed".into());
            a.push(s.to_string());
        }
        if let Some(o) = self.optimiser {
            a.push("--optimiser".into());
            a.push(match o {
                OptimiserMode::Off => "off".into(),
                OptimiserMode::Schedule => "schedule".into(),
                OptimiserMode::Indirect => "indirect".into(),
                OptimiserMode::Identify => "identify".into(),
                OptimiserMode::Direct => "direct".into(),
            });
        }
        if self.no_rt {
            a.push("--no-rt".into());
        }
        if let Some(w) = self.wait {
            a.push("--wait".into());
            a.push(w.name().into());
        }
        if let Some(e) = &self.remote.workers_listen {
            a.push("--workers-listen".into());
            a.push(e.clone());
        }
        if let Some(n) = self.remote.workers_expect {
            a.push("--workers-expect".into());
            a.push(n.to_string());
        }
        a
    }
}

/// The seeds of a multi-seed study.
#[derive(Debug, Clone, PartialEq)]
pub struct Seeds(pub Vec<u64>);

/// The most seeds a study takes.
const MAX_SEEDS: u64 = 1000;

/// `A..B` (inclusive) or a comma-separated list of seeds: 2 to `MAX_SEEDS` different ones. The
/// count is checked before anything is built (`0..18446744073709551615` asked for 2^64 seeds).
pub fn parse_seeds(s: &str) -> Result<Seeds, String> {
    let too_many = |n: String| format!("give 2 to {MAX_SEEDS} seeds, e.g. 1..20 (got {n})");
    let seeds: Vec<u64> = if let Some((a, b)) = s.split_once("..") {
        let a: u64 = a.trim().parse().map_err(|e| format!("`{a}`: {e}"))?;
        let b: u64 = b.trim().parse().map_err(|e| format!("`{b}`: {e}"))?;
        if b < a {
            return Err(format!(
                "{a}..{b} is empty: give A..B with A <= B, e.g. 1..20"
            ));
        }
        match (b - a).checked_add(1) {
            Some(n) if n <= MAX_SEEDS => (a..=b).collect(),
            Some(n) => return Err(too_many(n.to_string())),
            None => return Err(too_many("2^64".into())),
        }
    } else {
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() as u64 > MAX_SEEDS {
            return Err(too_many(parts.len().to_string()));
        }
        parts
            .iter()
            .map(|x| x.trim().parse().map_err(|e| format!("`{x}`: {e}")))
            .collect::<Result<_, _>>()?
    };
    if seeds.len() < 2 {
        return Err(too_many(seeds.len().to_string()));
    }
    let mut sorted = seeds.clone();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!(
            "seed {} is given twice: a study's seeds are its independent samples",
            w[0]
        ));
    }
    Ok(Seeds(seeds))
}
