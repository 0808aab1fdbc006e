//! `evoloop worker --connect ENDPOINT`: serve candidate evaluations to an optimiser with
//! `optimiser.workers = "zenoh"` (`evoloop_net::workers`; feature `zenoh`).

use std::path::PathBuf;

/// Options of `evoloop worker`: the optimiser's endpoint to serve, and how many evaluations run at
/// once.
#[derive(clap::Args)]
pub struct WorkerArgs {
    /// The optimiser's endpoint (its `optimiser.workers_listen`), e.g. `tcp/192.0.2.10:7448`;
    /// the worker keeps trying until it is up.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: String,
    /// Evaluations at once [default: every core this process may use].
    #[arg(long, value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub threads: Option<u16>,
    /// The worker's name on the network [default: host name and process id].
    #[arg(long)]
    pub id: Option<String>,
    /// A Zenoh configuration file (JSON5): TLS, access control (see config/zenoh/).
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Seconds to serve, then stop [default: until Ctrl-C].
    #[arg(long, value_parser = |s: &str| crate::args::seconds_in(s, 1e7))]
    pub duration: Option<f64>,
    /// Print what was served as JSON at the end.
    #[arg(long)]
    pub json: bool,
    /// Niceness of the worker (-20..=19): `evoloop run --workers N` gives its workers the
    /// optimiser's `optimiser.nice`, so they yield the CPU to the control loop as it does.
    #[arg(long, allow_hyphen_values = true, value_parser = clap::value_parser!(i32).range(-20..=19))]
    pub nice: Option<i32>,
    /// No start and end lines (a refused run is still reported).
    #[arg(long, short)]
    pub quiet: bool,
}

/// Options of `evoloop bench workers`: the worker counts to measure and the populations each
/// phase evaluates.
#[derive(clap::Args)]
pub struct BenchWorkersArgs {
    /// Worker counts to measure, one phase each (separate `evoloop worker` processes on
    /// loopback).
    #[arg(long, value_delimiter = ',', default_value = "0,1,2")]
    pub workers: Vec<usize>,
    /// Candidates per population.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u16).range(1..=10000))]
    pub population: u16,
    /// Populations measured per phase.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u16).range(1..=10000))]
    pub populations: u16,
    /// This process's evaluation threads (an optimiser's `optimiser.threads`).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub threads: u16,
    /// Threads of each worker.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub worker_threads: u16,
    /// Print the measurement as JSON on stdout
    #[arg(long)]
    pub json: bool,
}

/// `evoloop bench workers` (crate evoloop-net, through `crate::network`).
pub fn bench(a: &BenchWorkersArgs) -> u8 {
    match crate::network::commands("evoloop bench workers") {
        Ok(n) => n.bench_workers(a),
        Err(e) => {
            err!("error: {e}");
            2
        }
    }
}

/// `evoloop worker` (crate evoloop-net, through `crate::network`).
pub fn main(a: &WorkerArgs) -> u8 {
    match crate::network::commands("evoloop worker") {
        Ok(n) => n.worker(a),
        Err(e) => {
            err!("error: {e}");
            2
        }
    }
}
