//! The command line: `evoloop`'s subcommands, and the arguments shared by the launcher and the
//! three processes, so the launcher hands each child exactly the options the child parses. The
//! parser lives in its own crate, above every library crate, so a test can parse every command
//! the README and the book show; the terminal view's ratatui is only here.

#[macro_use]
extern crate evoloop_scenario;

pub mod args;
pub mod bench;
pub mod bridge;
pub mod check;
pub mod choice;
pub mod dynamics;
pub mod floor;
pub mod identify_base;
pub mod identify_excitation;
pub mod identify_lls;
pub mod identify_study;
pub mod network;
pub mod operator;
pub mod optim;
pub mod rkgnn;
pub mod robot;
pub mod robust;
pub mod soak;
pub mod top;
pub mod tune;
pub mod worker;

use args::{OptimiserOptions, ProcessOptions, RunOptions};
use clap::{Parser, Subcommand};
use evoloop_run::node::launcher;
pub use evoloop_run::node::start::stop_flag;
use std::path::PathBuf;
use std::process::ExitCode;

/// The `evoloop` command line: real-time control loops tuned by evolutionary optimisers.
#[derive(Parser)]
#[command(
    name = "evoloop",
    version,
    about = "Real-time control loops tuned by evolutionary optimisers while the plant runs",
    long_about = "evoloop starts a plant simulator, a fixed-rate controller and an optimiser as separate \
processes that talk over iceoryx2 shared memory.\n\nWithout a subcommand it runs the default scenario \
(config/two_mass/two_mass.toml) and writes its report to runs/two_mass/."
)]
pub struct Cli {
    /// The subcommand; without one the default scenario runs (config/two_mass/two_mass.toml, report in
    /// runs/two_mass/).
    #[command(subcommand)]
    pub command: Option<Cmd>,
}

/// `evoloop`'s subcommands.
#[derive(Subcommand)]
pub enum Cmd {
    /// Run a scenario: start the three processes, supervise them, write the report.
    Run(RunOptions),
    /// Validate a scenario file and print what it resolves to.
    Check {
        /// Scenario file (TOML).
        file: PathBuf,
    },
    /// The eMuPSO paper's optimiser benchmark: `optim study` (Tables 4-9 on the 36-function
    /// suite and shifted copies), `optim bench` (each optimiser's own overhead).
    Optim {
        /// The `optim` subcommand: `study`, `bench`, `functions` or `serve`.
        #[command(subcommand)]
        cmd: optim::OptimCmd,
    },
    /// Robust state feedback for the two-mass benchmark: stability radius, LQR, DE tuning, the
    /// paper's reproduction.
    Robust {
        /// The `robust` subcommand: `radius`, `lqr`, `tune` or `study`.
        #[command(subcommand)]
        cmd: robust::RobustCmd,
    },
    /// Rigid-body dynamics of a robot file (D-H TOML or URDF) at one state: tau, M, G, V, and,
    /// given --tau, the forward dynamics.
    Dynamics(dynamics::DynamicsArgs),
    /// Arms of one's own to try the controllers on: `robot generate` (a plausible serial arm of
    /// 3-7 joints from a seed, as URDF), `robot zoo` (the fixed unseen arms of a zoo file).
    Robot {
        /// The `robot` subcommand: `generate` or `zoo`.
        #[command(subcommand)]
        cmd: robot::RobotCmd,
    },
    /// The fuzzy-network paper's GA experiments: `tune config/experiments/arsinh_tune.toml` (Section 5.1),
    /// `tune config/experiments/maglev_tune.toml` (Section 5.2).
    Tune(tune::TuneArgs),
    /// System identification from run data: `identify rkgnn` (the RKGNN paper, no torques).
    Identify {
        /// The `identify` subcommand: `rkgnn`, `base`, `excitation`, `lls` or `study`.
        #[command(subcommand)]
        cmd: rkgnn::IdentifyCmd,
    },
    /// Identified RKGNN models: `rkgnn eval` (M_hat, V_hat, G_hat at a state).
    Rkgnn {
        /// The `rkgnn` subcommand: `eval`, `study`, `prior`, `selection` or `zoo`.
        #[command(subcommand)]
        cmd: rkgnn::RkgnnCmd,
    },
    /// Benchmarks measured against the machine's own floor in the same run.
    Bench {
        /// The `bench` subcommand: the benchmark to run.
        #[command(subcommand)]
        cmd: BenchCmd,
    },
    /// The plant simulator process of a run (`evoloop run` starts it; for starting processes by
    /// hand or under your own supervisor).
    Plant(ProcessOptions),
    /// The fixed-rate controller process of a run (`evoloop run` starts it).
    Controller(ProcessOptions),
    /// The optimiser process of a run (`evoloop run` starts it).
    Optimiser(OptimiserOptions),
    /// A long realtime run with the optimiser tuning: memory of every process, missed deadlines
    /// and lateness per minute, shared-memory files before and after (soak.json, soak.csv, plots).
    Soak(soak::SoakArgs),
    /// Measure the machine's timing floor: a bare absolute-deadline loop (sleep, spin or hybrid).
    Floor(floor::FloorArgs),
    /// (Re)build report.html, the one-page report of a finished run, from its directory
    /// (summary.json, scenario.json, the plots, the data files).
    Report(ReportArgs),
    /// Play a recorded run (its run.mcap) into a controller over the run's iceoryx2 topics, in
    /// the plant's place, and compare its commands with the recorded ones (replay.json,
    /// replay.csv, replay.png); `--scenario FILE` tries another controller on the recorded data.
    Replay(args::ReplayOptions),
    /// Serve a running run to Foxglove or PlotJuggler in Foxglove's WebSocket protocol: its
    /// topics (ROS 2 CDR) and the controller's gains as a parameter a viewer may set (checked by
    /// the controller like any set). `evoloop run --live` starts it with the run.
    Live(args::LiveOptions),
    /// A live terminal view of a running run: processes, the controller's rate, lateness and
    /// misses (last second and since start), parameter sets and model estimate, a sparkline of
    /// the tracking error (`--json`: one snapshot for scripts); keys h, g, b, x hold, resume,
    /// revert and stop the tuning as `evoloop operator` does.
    Top(top::TopArgs),
    /// An operator's command to a running run's tuner: hold, resume, revert (to an earlier set,
    /// 0 = the set before tuning) or stop; prints the optimiser's answer.
    Operator(operator::OperatorArgs),
    /// A running run's topics on a Zenoh network (states, commands, telemetry, estimates out;
    /// parameter sets in, validated by the controller as any other), for an optimiser on another
    /// host (`evoloop optimiser --connect`) or a remote monitor. Needs the `zenoh` feature.
    Bridge(bridge::BridgeArgs),
    /// Serve candidate evaluations to an optimiser with `optimiser.workers = "zenoh"` over
    /// Zenoh: model and candidates in, costs out, computed exactly as the optimiser would.
    /// Needs the `zenoh` feature.
    Worker(worker::WorkerArgs),
}

/// Options of `evoloop report`: the finished run's directory.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// The run's output directory (where summary.json is), e.g. runs/two_mass.
    pub dir: std::path::PathBuf,
}

/// The subcommands of `evoloop bench`: benchmarks measured against the machine's own floor.
#[derive(Subcommand)]
pub enum BenchCmd {
    /// Round trip plant -> controller -> plant against a bare iceoryx2 ping-pong.
    Latency(bench::LatencyArgs),
    /// The controller loop's timing at a rate, under load, against the bare sleep-loop floor.
    Loop(bench::LoopArgs),
    /// Nanoseconds per call of RNEA, CRBA, ABA and the CRBA forward dynamics on a robot file
    /// (the JSON scripts/pinocchio_bench.py sets beside Pinocchio's).
    Dynamics(bench::DynamicsArgs),
    /// The hot paths (RNEA, CRBA, the 7-DOF computed-torque cycle, the optimisers' overhead, the
    /// state's round trip) against references timed in the same run: fails (exit 1) when one is
    /// more than 1.5x its recorded ratio, whatever the host's speed.
    Guard(bench::GuardArgs),
    /// A parameter set's round trip (sent -> in service, seen by the sender) on the local path
    /// and through `evoloop bridge` on loopback, on one realtime run (feature `zenoh`).
    Bridge(bridge::BridgeBenchArgs),
    /// Evaluations per second of the maglev model with 0, 1, 2, ... evaluation workers on
    /// loopback, and the remote path's cost per run and per evaluation (feature `zenoh`).
    Workers(worker::BenchWorkersArgs),
    /// The peer process of `bench latency` (started by it).
    #[command(hide = true)]
    LatencyPeer(bench::PeerArgs),
}

/// `evoloop [COMMAND]`: parse the command line and run the command.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    // One-shot commands that start no process end quietly when their reader goes away
    // (`evoloop dynamics ... | head`), like any Unix filter. Commands that supervise processes
    // (run, bench, the roles) keep Rust's ignored SIGPIPE: a closed pipe must not kill a
    // supervisor and orphan its children.
    if matches!(
        cli.command,
        Some(
            Cmd::Check { .. }
                | Cmd::Robust { .. }
                | Cmd::Optim { .. }
                | Cmd::Dynamics(_)
                | Cmd::Robot { .. }
                | Cmd::Tune(_)
                | Cmd::Identify { .. }
                | Cmd::Rkgnn { .. }
                | Cmd::Floor(_)
        )
    ) {
        // SAFETY: resetting a signal disposition before any thread is started.
        unsafe { libc::signal(libc::SIGPIPE, libc::SIG_DFL) };
    }
    run(cli.command)
}

/// Run `command`; none is `evoloop run` with no argument (the same defaults, from its parser).
fn run(command: Option<Cmd>) -> ExitCode {
    let Some(command) = command else {
        let default = options_from::<RunOptions>("evoloop", String::new(), ["evoloop"]);
        return launcher::run(default.into_args());
    };
    match command {
        Cmd::Run(a) if a.seeds.is_some() => launcher::run_seeds(a.into_args()),
        Cmd::Run(a) => launcher::run(a.into_args()),
        Cmd::Check { file } => check::check(&file),
        Cmd::Plant(a) => {
            evoloop_run::node::plant::main(&a.into_args());
            ExitCode::SUCCESS
        }
        Cmd::Controller(a) => {
            evoloop_run::node::controller::main(&a.into_args());
            ExitCode::SUCCESS
        }
        Cmd::Optimiser(a) => {
            evoloop_run::node::optimiser::main(&a.into_args());
            ExitCode::SUCCESS
        }
        Cmd::Bench { cmd } => ExitCode::from(match cmd {
            BenchCmd::Latency(a) => bench::latency(a),
            BenchCmd::LatencyPeer(a) => bench::latency_peer(a),
            BenchCmd::Loop(a) => bench::loop_(a),
            BenchCmd::Dynamics(a) => bench::dynamics(a),
            BenchCmd::Guard(a) => bench::guard(a),
            BenchCmd::Bridge(a) => bridge::bench(&a) as i32,
            BenchCmd::Workers(a) => worker::bench(&a) as i32,
        } as u8),
        Cmd::Optim { cmd } => ExitCode::from(optim::main(cmd) as u8),
        Cmd::Robust { cmd } => ExitCode::from(robust::main(cmd) as u8),
        Cmd::Tune(a) => ExitCode::from(tune::main(a) as u8),
        Cmd::Identify { cmd } => ExitCode::from(rkgnn::identify(cmd) as u8),
        Cmd::Rkgnn { cmd } => ExitCode::from(rkgnn::main(cmd) as u8),
        Cmd::Dynamics(a) => ExitCode::from(dynamics::main(a) as u8),
        Cmd::Robot { cmd } => ExitCode::from(robot::main(cmd) as u8),
        Cmd::Floor(a) => floor::main(&a),
        Cmd::Report(a) => match evoloop_report::html::write(&a.dir) {
            Ok(p) => {
                out!("wrote {}", p.display());
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!(
                    "error: {e} (is {} a finished run's directory?)",
                    a.dir.display()
                );
                ExitCode::from(2)
            }
        },
        Cmd::Soak(a) => soak::main(a),
        Cmd::Replay(a) => ExitCode::from(evoloop_run::node::replay::main(&a.into_args()) as u8),
        Cmd::Live(a) => ExitCode::from(evoloop_run::node::live::main(&a.into_args())),
        Cmd::Top(a) => ExitCode::from(top::main(&a)),
        Cmd::Operator(a) => ExitCode::from(operator::main(&a)),
        Cmd::Bridge(a) => ExitCode::from(bridge::main(&a)),
        Cmd::Worker(a) => ExitCode::from(worker::main(&a)),
    }
}

pub use evoloop_report::print_json;

/// Which process a binary of its own runs (`evoloop-plant`, `evoloop-controller`,
/// `evoloop-optimiser`), for users who start a run's processes by hand or under their own
/// supervisor: the same options and code as `evoloop plant`, `controller` and `optimiser`.
#[derive(Debug, Clone, Copy)]
pub enum Process {
    /// `evoloop-plant`.
    Plant,
    /// `evoloop-controller`.
    Controller,
    /// `evoloop-optimiser`.
    Optimiser,
}

/// The `main` of the binary that runs `process` alone: its command line parsed under the
/// binary's own name, then the process as `evoloop ROLE` runs it.
pub fn process_main(process: Process) -> ExitCode {
    let (name, role) = match process {
        Process::Plant => ("evoloop-plant", "plant"),
        Process::Controller => ("evoloop-controller", "controller"),
        Process::Optimiser => ("evoloop-optimiser", "optimiser"),
    };
    let about = format!(
        "evoloop {role} process (normally started by `evoloop run`; the same as `evoloop {role}`)"
    );
    let args = std::env::args_os();
    run(Some(match process {
        Process::Plant => Cmd::Plant(options_from(name, about, args)),
        Process::Controller => Cmd::Controller(options_from(name, about, args)),
        Process::Optimiser => Cmd::Optimiser(options_from(name, about, args)),
    }))
}

/// `T`'s options read from `args` (the program's name first) as command `name`, described by
/// `about` in its `--help`; a usage error or `--help` ends the process as clap's parser does.
fn options_from<T: clap::Args>(
    name: &'static str,
    about: String,
    args: impl IntoIterator<Item = impl Into<std::ffi::OsString> + Clone>,
) -> T {
    // `about` after the options: their struct's doc would otherwise describe the command.
    let matches = T::augment_args(clap::Command::new(name))
        .about(about)
        .get_matches_from(args);
    T::from_arg_matches(&matches).unwrap_or_else(|e| e.exit())
}
