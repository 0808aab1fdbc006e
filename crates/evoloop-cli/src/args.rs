//! The options of a run and of its processes as the command line takes them: what `evoloop run`
//! takes and what the launcher hands each child (`evoloop_run::node::args::override_args` writes
//! them, the child parses them here). Each converts into the library's own (`RunArgs`,
//! `ProcessArgs`, `OptimiserArgs`, `Overrides`), which know nothing of clap.

use clap::Args;
use evoloop_run::node::args::{OptimiserArgs, ProcessArgs, RunArgs, Seeds};
use evoloop_run::node::live::LiveArgs;
use evoloop_run::node::replay::ReplayArgs;
use evoloop_scenario::config::{Mode, OptimiserMode, Overrides};
use std::path::PathBuf;

/// The options of `evoloop run`: the scenario file and its overrides, the run's id and IPC
/// prefix, its seeds, its floor, workers on this host and the live view.
#[derive(Debug, Clone, Args)]
pub struct RunOptions {
    /// Scenario file (TOML) [default: config/two_mass/two_mass.toml, here or in the source tree]
    pub file: Option<PathBuf>,
    /// Overrides of the scenario file; the launcher passes them on to the run's processes.
    #[command(flatten)]
    pub overrides: OverrideOptions,
    /// Run id used in the service names: ASCII letters, digits, '_' and '-' (default:
    /// generated, unique on this machine).
    #[arg(long, value_parser = evoloop_ipc::parse_run_id)]
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files (separate namespace, e.g. for parallel tests).
    #[arg(long, default_value = evoloop_ipc::DEFAULT_PREFIX, value_parser = evoloop_ipc::parse_prefix)]
    pub ipc_prefix: String,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
    /// Several seeds, e.g. `1..20` (inclusive) or `1,4,9`, for a scenario with
    /// `optimiser.mode = "indirect"` or `"identify"`: one run per seed (in `<out>/seed-<n>/`),
    /// each against the frozen controller on the same seed (cost per repetition, or tracking RMS
    /// for identify); statistics and paired tests in `<out>/study.md`,
    /// `study.json`, `seeds.csv`, `study_cost.png`.
    #[arg(long, value_parser = evoloop_run::node::args::parse_seeds, conflicts_with = "seed")]
    pub seeds: Option<Seeds>,
    /// Realtime: seconds of the bare loop measured after the run as its floor (default: the
    /// run's duration, at most 5 s). As long as the run, rare stalls of the machine have the
    /// same chance to show in the floor as in the run (`bench loop` does this).
    #[arg(long, value_parser = |s: &str| seconds_in(s, 3600.0))]
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

impl RunOptions {
    /// The run these options ask for.
    pub fn into_args(self) -> RunArgs {
        RunArgs {
            file: self.file,
            overrides: self.overrides.to_overrides(),
            run_id: self.run_id,
            ipc_prefix: self.ipc_prefix,
            quiet: self.quiet,
            seeds: self.seeds,
            floor_duration: self.floor_duration,
            workers: self.workers,
            live: self.live,
            live_remote: self.live_remote,
        }
    }
}

/// A time option's value: seconds in (0, `max`].
pub fn seconds_in(s: &str, max: f64) -> Result<f64, String> {
    positive_up_to(s, max).ok_or_else(|| format!("{s:?}: seconds in (0, {max}]"))
}

/// `s` as a number in (0, `max`].
fn positive_up_to(s: &str, max: f64) -> Option<f64> {
    s.parse::<f64>().ok().filter(|v| *v > 0.0 && *v <= max)
}

/// Options every process of a run receives from the launcher.
#[derive(Debug, Clone, Args)]
pub struct ProcessOptions {
    /// Scenario file (TOML).
    #[arg(long)]
    pub config: PathBuf,
    /// Run id: part of every service name, so runs never cross-talk.
    #[arg(long, value_parser = evoloop_ipc::parse_run_id)]
    pub run_id: String,
    /// Prefix of iceoryx2's files for this run.
    #[arg(long, default_value = evoloop_ipc::DEFAULT_PREFIX, value_parser = evoloop_ipc::parse_prefix)]
    pub ipc_prefix: String,
    /// `evoloop run`'s overrides of the scenario file, with `--out` set to the run's directory.
    #[command(flatten)]
    pub overrides: OverrideOptions,
}

impl ProcessOptions {
    /// What the process is started with.
    pub fn into_args(self) -> ProcessArgs {
        ProcessArgs {
            config: self.config,
            run_id: self.run_id,
            ipc_prefix: self.ipc_prefix,
            overrides: self.overrides.to_overrides(),
        }
    }
}

/// The optimiser process's options: those of every process, and `--rejoin`.
#[derive(Debug, Clone, Args)]
pub struct OptimiserOptions {
    /// The options every process receives.
    #[command(flatten)]
    pub args: ProcessOptions,
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

impl OptimiserOptions {
    /// What the optimiser process is started with.
    pub fn into_args(self) -> OptimiserArgs {
        OptimiserArgs {
            args: self.args.into_args(),
            rejoin: self.rejoin,
            connect: self.connect,
            zenoh_config: self.zenoh_config,
        }
    }
}

/// Overrides of the scenario file, accepted by `evoloop run` and passed on to the children.
#[derive(Debug, Clone, Default, Args)]
pub struct OverrideOptions {
    /// Timing mode: lockstep (reproducible, as fast as possible) or realtime (wall clock).
    #[arg(long)]
    pub mode: Option<Mode>,
    /// Run length in simulated seconds, or `forever` to run until Ctrl-C (as a scenario
    /// without `timing.duration` does). Default: the scenario's.
    #[arg(long, value_parser = evoloop_scenario::config::parse_duration)]
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
    #[arg(long, value_parser = crate::choice::choice(&evoloop_rt::WaitKind::ALL, evoloop_rt::WaitKind::name))]
    pub wait: Option<evoloop_rt::WaitKind>,
    /// Evaluation workers on other hosts for the optimiser (`--workers-listen`,
    /// `--workers-expect`).
    #[command(flatten)]
    pub remote: WorkersOptions,
}

impl OverrideOptions {
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
}

/// Evaluation workers on other hosts, for `run` (the optimiser) and `tune`.
#[derive(Debug, Clone, Default, Args)]
pub struct WorkersOptions {
    /// Take evaluation workers (`evoloop worker --connect ENDPOINT` on any host) on this Zenoh
    /// endpoint, e.g. `tcp/0.0.0.0:7448`; for a run, `optimiser.workers = "zenoh"` with
    /// `workers_listen` set (feature `zenoh`).
    #[arg(long, value_name = "ENDPOINT")]
    pub workers_listen: Option<String>,
    /// Evaluation workers to wait for (up to 8 s) before starting.
    #[arg(long, value_name = "N")]
    pub workers_expect: Option<usize>,
}

/// The options of `evoloop live`: which run to serve, on which address, and to whom.
#[derive(Args, Debug)]
pub struct LiveOptions {
    /// The run to serve (its run id); default: the only run running.
    #[arg(long)]
    pub run: Option<String>,
    /// Address to listen on (Foxglove: "Open connection", Foxglove WebSocket, ws://ADDR).
    #[arg(long, default_value = "127.0.0.1:8765")]
    pub addr: String,
    /// The run's scenario (default: the one its controller was started with).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Prefix of iceoryx2's files (default: the run's).
    #[arg(long)]
    pub ipc_prefix: Option<String>,
    /// The run's overrides of its scenario (`evoloop run --live` passes its own).
    #[command(flatten)]
    pub overrides: OverrideOptions,
    /// Listen beyond loopback (ADDR on another interface, e.g. 0.0.0.0:8765): anyone who
    /// reaches the port sees the run, and a viewer on another machine sets `gains` only with
    /// the token printed at start (ws://HOST:PORT/?token=TOKEN). Without it such an ADDR is
    /// refused.
    #[arg(long)]
    pub remote: bool,
    /// A listening socket already bound, inherited as this descriptor (`evoloop run --live`
    /// binds ADDR itself, so a port it cannot have fails the run before it starts).
    #[arg(long, hide = true)]
    pub listen_fd: Option<i32>,
}

impl LiveOptions {
    /// What the live view is started with.
    pub fn into_args(self) -> LiveArgs {
        LiveArgs {
            run: self.run,
            addr: self.addr,
            config: self.config,
            ipc_prefix: self.ipc_prefix,
            overrides: self.overrides.to_overrides(),
            remote: self.remote,
            listen_fd: self.listen_fd,
        }
    }
}

/// The options of `evoloop replay`: the recording, the controller's scenario, the pace and
/// where the results go.
#[derive(Args, Debug)]
pub struct ReplayOptions {
    /// The recording: a run's run.mcap.
    pub file: PathBuf,
    /// The controller's scenario [default: the recording's own, named in its metadata]. Another
    /// file tries another controller (gains, law) on the recorded plant data.
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Play at this multiple of real time, by the states' own time t (1: a 10 s run takes 10 s,
    /// lockstep recordings too) [default: as fast as the controller answers].
    #[arg(long, value_parser = parse_speed)]
    pub speed: Option<f64>,
    /// Output directory: replay.json, replay.csv, replay.png and the controller's own files
    /// [default: replay/ beside the recording].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Run id of the replay's services (default: generated, unique on this machine).
    #[arg(long)]
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files.
    #[arg(long, default_value = evoloop_ipc::DEFAULT_PREFIX, value_parser = evoloop_ipc::parse_prefix)]
    pub ipc_prefix: String,
    /// Print replay.json on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress lines.
    #[arg(long, short)]
    pub quiet: bool,
}

impl ReplayOptions {
    /// What the replay is started with.
    pub fn into_args(self) -> ReplayArgs {
        ReplayArgs {
            file: self.file,
            scenario: self.scenario,
            speed: self.speed,
            out: self.out,
            run_id: self.run_id,
            ipc_prefix: self.ipc_prefix,
            json: self.json,
            quiet: self.quiet,
        }
    }
}

fn parse_speed(s: &str) -> Result<f64, String> {
    positive_up_to(s, 1e6)
        .ok_or_else(|| format!("{s:?}: a speed in (0, 1e6], e.g. 1 (as recorded)"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Child {
        #[command(flatten)]
        overrides: OverrideOptions,
    }

    /// What the launcher writes for a child (`override_args`) the child reads back as the same
    /// overrides, every one of them set and none.
    #[test]
    fn the_childs_arguments_parse_back_into_the_launchers_overrides() {
        let every = Overrides {
            mode: Some(Mode::Realtime),
            duration: Some(2.5),
            seed: Some(7),
            out: Some("runs/x y".into()),
            optimiser: Some(OptimiserMode::Identify),
            no_rt: true,
            wait: Some(evoloop_rt::WaitKind::Hybrid),
            workers_listen: Some("tcp/127.0.0.1:7448".into()),
            workers_expect: Some(2),
        };
        for o in [every, Overrides::default()] {
            let args = evoloop_run::node::args::override_args(&o);
            let child =
                Child::try_parse_from(std::iter::once("child".to_string()).chain(args)).unwrap();
            assert_eq!(
                format!("{:?}", child.overrides.to_overrides()),
                format!("{o:?}")
            );
        }
    }
}
