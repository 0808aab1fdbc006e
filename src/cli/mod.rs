//! The command line: `evoloop`'s subcommands, and the arguments shared by the launcher and the
//! three processes, so the launcher hands each child exactly the options the child parses. The
//! parser lives in the library so a test can parse every command the README shows.

pub mod dynamics;
pub mod robust;
pub mod tune;

use crate::config::{Mode, OptimiserMode, Overrides};
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "evoloop",
    version,
    about = "Real-time control loops tuned by evolutionary optimisers while the plant runs",
    long_about = "evoloop starts a plant simulator, a fixed-rate controller and an optimiser as separate \
processes that talk over iceoryx2 shared memory.\n\nWithout a subcommand it runs the default scenario \
(config/two_mass.toml) and writes its report to runs/two_mass/."
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Cmd>,
}

#[derive(Subcommand)]
pub enum Cmd {
    /// Run a scenario: start the three processes, supervise them, write the report.
    Run(RunArgs),
    /// Validate a scenario file and print what it resolves to.
    Check {
        /// Scenario file (TOML).
        file: PathBuf,
    },
    /// Robust state feedback for the two-mass benchmark: stability radius, LQR, DE tuning, the
    /// paper's reproduction.
    Robust {
        #[command(subcommand)]
        cmd: robust::RobustCmd,
    },
    /// Rigid-body dynamics of a robot file (D-H TOML or URDF) at one state: tau, M, G, V, and,
    /// given --tau, the forward dynamics.
    Dynamics(dynamics::DynamicsArgs),
    /// The fuzzy-network paper's GA experiments: `tune config/arsinh_tune.toml` (Section 5.1),
    /// `tune config/maglev_tune.toml` (Section 5.2).
    Tune(tune::TuneArgs),
    /// Benchmarks measured against the machine's own floor in the same run.
    Bench {
        #[command(subcommand)]
        cmd: BenchCmd,
    },
    /// The plant simulator process of a run (`evoloop run` starts it; for starting processes by
    /// hand or under your own supervisor).
    Plant(ProcessArgs),
    /// The fixed-rate controller process of a run (`evoloop run` starts it).
    Controller(ProcessArgs),
    /// The optimiser process of a run (`evoloop run` starts it).
    Optimiser(OptimiserArgs),
    /// Measure the machine's timing floor: a bare absolute-deadline sleep loop.
    Floor {
        /// Loop rate in Hz.
        #[arg(long, default_value_t = 1000.0)]
        rate: f64,
        /// Seconds to run.
        #[arg(long, default_value_t = 5.0)]
        duration: f64,
        /// Ask for SCHED_FIFO with this priority (falls back when not permitted).
        #[arg(long)]
        fifo: Option<i32>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Subcommand)]
pub enum BenchCmd {
    /// Round trip plant -> controller -> plant against a bare iceoryx2 ping-pong.
    Latency(crate::bench::latency::LatencyArgs),
    /// The controller loop's timing at a rate, under load, against the bare sleep-loop floor.
    Loop(crate::bench::loop_bench::LoopArgs),
    /// The peer process of `bench latency` (started by it).
    #[command(hide = true)]
    LatencyPeer(crate::bench::latency::PeerArgs),
}

#[derive(clap::Args)]
pub struct RunArgs {
    /// Scenario file (TOML) [default: config/two_mass.toml, here or in the source tree]
    pub file: Option<PathBuf>,
    #[command(flatten)]
    pub overrides: OverrideArgs,
    /// Run id used in the service names (default: generated, unique on this machine).
    #[arg(long)]
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files (separate namespace, e.g. for parallel tests).
    #[arg(long, default_value = crate::ipc::DEFAULT_PREFIX)]
    pub ipc_prefix: String,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
    /// Several seeds, e.g. `1..20` (inclusive) or `1,4,9`, for a scenario with
    /// `optimiser.mode = "indirect"`: one run per seed (in `<out>/seed-<n>/`), each against the
    /// frozen controller on the same seed; statistics and paired tests in `<out>/study.md`,
    /// `study.json`, `seeds.csv`, `study_cost.png`.
    #[arg(long, value_parser = parse_seeds, conflicts_with = "seed")]
    pub seeds: Option<Seeds>,
}

/// Options every process of a run receives from the launcher.
#[derive(Debug, Clone, Args)]
pub struct ProcessArgs {
    /// Scenario file (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// Run id: part of every service name, so runs never cross-talk.
    #[arg(long)]
    pub run_id: String,
    /// Prefix of iceoryx2's files for this run.
    #[arg(long, default_value = crate::ipc::DEFAULT_PREFIX)]
    pub ipc_prefix: String,
    #[command(flatten)]
    pub overrides: OverrideArgs,
}

/// The optimiser process's options: those of every process, and `--rejoin`.
#[derive(Debug, Clone, Args)]
pub struct OptimiserArgs {
    #[command(flatten)]
    pub args: ProcessArgs,
    /// Rejoin a running run (started again after a crash): continue the version numbering and the
    /// set in service from `published.jsonl`, and release the plant's pending lockstep wait.
    #[arg(long)]
    pub rejoin: bool,
}

/// Overrides of the scenario file, accepted by `evoloop run` and passed on to the children.
#[derive(Debug, Clone, Default, Args)]
pub struct OverrideArgs {
    /// Timing mode: lockstep (reproducible, as fast as possible) or realtime (wall clock).
    #[arg(long)]
    pub mode: Option<Mode>,
    /// Run length in simulated seconds.
    #[arg(long)]
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
}

impl OverrideArgs {
    pub fn to_overrides(&self) -> Overrides {
        Overrides {
            mode: self.mode,
            duration: self.duration,
            seed: self.seed,
            out: self.out.clone(),
            optimiser: self.optimiser,
            no_rt: self.no_rt,
        }
    }

    /// The same options as command-line arguments for a child process.
    pub fn to_args(&self) -> Vec<String> {
        let mut a = Vec::new();
        if let Some(m) = self.mode {
            a.push("--mode".into());
            a.push(match m {
                Mode::Lockstep => "lockstep".into(),
                Mode::Realtime => "realtime".into(),
            });
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
            });
        }
        if self.no_rt {
            a.push("--no-rt".into());
        }
        a
    }
}

/// The seeds of a multi-seed study.
#[derive(Debug, Clone, PartialEq)]
pub struct Seeds(pub Vec<u64>);

/// `A..B` (inclusive) or a comma-separated list of seeds.
pub fn parse_seeds(s: &str) -> Result<Seeds, String> {
    let seeds: Vec<u64> = if let Some((a, b)) = s.split_once("..") {
        let a: u64 = a.trim().parse().map_err(|e| format!("`{a}`: {e}"))?;
        let b: u64 = b.trim().parse().map_err(|e| format!("`{b}`: {e}"))?;
        (a..=b).collect()
    } else {
        s.split(',')
            .map(|x| x.trim().parse().map_err(|e| format!("`{x}`: {e}")))
            .collect::<Result<_, _>>()?
    };
    if seeds.len() < 2 || seeds.len() > 1000 {
        return Err(format!(
            "give 2 to 1000 seeds, e.g. 1..20 (got {})",
            seeds.len()
        ));
    }
    Ok(Seeds(seeds))
}

/// Install SIGINT/SIGTERM handling that only raises a flag; loops check it once per cycle and
/// exit cleanly, dropping their iceoryx2 ports so nothing is left in shared memory.
pub fn stop_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let f = flag.clone();
    // Only fails if a handler is already installed, which the binaries never do twice.
    let _ = ctrlc::set_handler(move || f.store(true, std::sync::atomic::Ordering::SeqCst));
    flag
}
