//! `evoloop worker --connect ENDPOINT`: serve candidate evaluations to an optimiser with
//! `optimiser.workers = "zenoh"` (`evoloop_net::workers`; feature `zenoh`).

use std::path::PathBuf;

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
    #[arg(long, value_parser = |s: &str| evoloop_run::node::args::seconds_in(s, 1e7))]
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
    #[arg(long)]
    pub json: bool,
}

/// `evoloop bench workers`.
#[cfg(feature = "zenoh")]
pub fn bench(a: &BenchWorkersArgs) -> u8 {
    use evoloop_run::bench::workers::{run, Settings};
    if a.workers.is_empty() || a.workers.iter().any(|n| *n > 64) {
        err!("error: --workers: give 0 to 64 workers per phase, e.g. 0,1,2");
        return 2;
    }
    let s = Settings {
        workers: a.workers.clone(),
        population: a.population as usize,
        populations: a.populations as usize,
        threads: a.threads as usize,
        worker_threads: a.worker_threads as usize,
    };
    match run(&s, |line| err!("  {line}")) {
        Ok(r) => {
            if a.json {
                crate::print_json(&r);
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

#[cfg(not(feature = "zenoh"))]
pub fn bench(_: &BenchWorkersArgs) -> u8 {
    err!(
        "error: {}",
        evoloop_run::needs_zenoh("evoloop bench workers")
    );
    2
}

#[cfg(feature = "zenoh")]
pub fn main(a: &WorkerArgs) -> u8 {
    use evoloop_net::{workers, Endpoint};
    if let Some(p) = &a.zenoh_config {
        if !p.is_file() {
            err!("error: --zenoh-config {}: no such file", p.display());
            return 2;
        }
    }
    let threads = a
        .threads
        .map_or_else(evoloop_optim::all_cores, |t| t as usize);
    let id = workers::key_safe(&a.id.clone().unwrap_or_else(workers::default_id));
    let stop = evoloop_run::node::start::stop_flag();
    if let Some(n) = a.nice {
        if !evoloop_rt::privileges::set_nice(n) {
            err!("warning: evoloop worker: cannot set niceness {n}");
        }
    }
    if !a.quiet {
        err!(
            "evoloop worker {id}: {threads} thread(s), build {}, serving on {}",
            workers::build(),
            a.connect
        );
    }
    match workers::serve(
        &Endpoint::Connect(a.connect.clone()),
        a.zenoh_config.as_deref(),
        &id,
        threads,
        a.duration.map(std::time::Duration::from_secs_f64),
        &stop,
    ) {
        Ok(r) => {
            if a.json {
                crate::print_json(&r);
            } else if !a.quiet {
                err!(
                    "evoloop worker {id}: {} runs, {} evaluations, busy {:.2} s of {:.1} s{}",
                    r.batches,
                    r.evaluations,
                    r.busy_s,
                    r.wall_s,
                    if r.refused > 0 {
                        format!("; {} runs refused", r.refused)
                    } else {
                        String::new()
                    }
                );
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

#[cfg(not(feature = "zenoh"))]
pub fn main(_: &WorkerArgs) -> u8 {
    err!("error: {}", evoloop_run::needs_zenoh("evoloop worker"));
    2
}
