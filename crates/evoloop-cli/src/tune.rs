//! `evoloop tune FILE`: the fuzzy-network paper's GA experiments.

use clap::Args;
use evoloop_run::node::args::{parse_seeds, Seeds};
use std::path::PathBuf;

/// Options of `evoloop tune`: the experiment file or direct scenario, its seed(s), the optimisers
/// to compare and the evaluation workers.
#[derive(Args)]
pub struct TuneArgs {
    /// Experiment file (TOML): config/experiments/arsinh_tune.toml or config/experiments/maglev_tune.toml; or a scenario
    /// of the direct scheme (config/maglev/maglev_direct.toml), run in this process in lockstep.
    pub file: PathBuf,
    /// Seed of the GA (and of the plant's noise) [default: the file's `seed`].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Several seeds, e.g. `1..20` (inclusive) or `1,4,9`: the multi-seed study (maglev): every
    /// controller tuned per seed with the same budget, statistics and paired tests over seeds.
    #[arg(long, value_parser = parse_seeds, conflicts_with = "seed")]
    pub seeds: Option<Seeds>,
    /// On a direct scenario: compare these optimisers (e.g. `ga,de,jade,cmaes,bayes,safe_bayes`,
    /// the GA included as the yardstick) over --seeds, each from the configured set with the
    /// scenario's budget: experiments until the best cost is within 1 % of the GA's final cost,
    /// aborts and final cost, paired tests; writes compare.json, compare.csv, report.md and
    /// convergence.png.
    #[arg(long, value_delimiter = ',', value_name = "ALGORITHMS")]
    pub compare: Option<Vec<String>>,
    /// With --compare: every run with up to N settle repetitions after each trial
    /// (`optimiser.settle`, isolated trials), the run lengthened to fit its budget.
    #[arg(long, value_name = "N", requires = "compare")]
    pub settle: Option<u32>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Output directory [default: the file's output.dir].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
    /// Start N evaluation workers on this host (`evoloop worker`, one thread each) over Zenoh on
    /// loopback and spread the maglev experiment's GA populations over them (the results are the
    /// same bits; the other experiments' evaluations stay here). Feature `zenoh`.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=64), conflicts_with = "workers_listen")]
    pub workers: Option<u16>,
    /// Evaluation workers on other hosts: `--workers-listen` and `--workers-expect`.
    #[command(flatten)]
    pub remote: crate::args::WorkersOptions,
}

/// Evaluation workers for the experiment, when asked for: those started here (kept until the
/// experiment ends) and the pool installed for `optim::evaluate`.
fn workers(a: &TuneArgs) -> Result<evoloop_run::node::launcher::LocalWorkers, String> {
    use evoloop_run::node::launcher::{local_workers_endpoint, LocalWorkers};
    let listen = match (a.workers, &a.remote.workers_listen) {
        (None, None) if a.remote.workers_expect.is_some() => {
            return Err("--workers-expect goes with --workers-listen".into())
        }
        (None, None) => return Ok(LocalWorkers::default()),
        (Some(_), _) => local_workers_endpoint().map_err(|e| e.to_string())?,
        (None, Some(ep)) => ep.clone(),
    };
    let net = evoloop_run::network::required("--workers (or --workers-listen)")
        .map_err(|e| e.to_string())?;
    // Niceness 10, the optimiser's default: they yield to whatever else runs here.
    let local = LocalWorkers::start(&listen, a.workers.unwrap_or(0) as usize, 1, 10, "tune")
        .map_err(|e| e.to_string())?;
    let expect = a
        .workers
        .map(usize::from)
        .or(a.remote.workers_expect)
        .unwrap_or(0);
    let stop = std::sync::atomic::AtomicBool::new(false);
    net.install_workers(&listen, None, expect, &stop)
        .map_err(|e| e.to_string())?;
    Ok(local)
}

/// Run it; the exit code (2 with the reason on stderr when the file or a run fails).
pub fn main(a: TuneArgs) -> i32 {
    let _workers = match workers(&a) {
        Ok(w) => w,
        Err(e) => {
            eprintln!("error: {e}");
            return 2;
        }
    };
    let r = evoloop_tune::TuneRequest {
        file: a.file,
        seed: a.seed,
        seeds: a.seeds.map(|s| s.0),
        compare: a.compare,
        settle: a.settle,
        json: a.json,
        out: a.out,
        quiet: a.quiet,
    };
    match evoloop_tune::tune(&r) {
        Ok(()) => {
            if let Some(line) = evoloop_optim::remote::totals().summary_line() {
                eprintln!("  {line}");
            }
            0
        }
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}
