//! Command-line arguments shared by the launcher and the three process binaries, so the launcher
//! hands each child exactly the options the child parses.

use crate::config::{Mode, OptimiserMode, Overrides};
use clap::Args;
use std::path::PathBuf;

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

/// Install SIGINT/SIGTERM handling that only raises a flag; loops check it once per cycle and
/// exit cleanly, dropping their iceoryx2 ports so nothing is left in shared memory.
pub fn stop_flag() -> std::sync::Arc<std::sync::atomic::AtomicBool> {
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let f = flag.clone();
    // Only fails if a handler is already installed, which the binaries never do twice.
    let _ = ctrlc::set_handler(move || f.store(true, std::sync::atomic::Ordering::SeqCst));
    flag
}
