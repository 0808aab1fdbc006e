//! `evoloop tune FILE`: the fuzzy-network paper's GA experiments.

use super::{parse_seeds, Seeds};
use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct TuneArgs {
    /// Experiment file (TOML): config/arsinh_tune.toml or config/maglev_tune.toml; or a scenario
    /// of the direct scheme (config/maglev_direct.toml), run in this process in lockstep.
    pub file: PathBuf,
    /// Seed of the GA (and of the plant's noise) [default: the file's `seed`].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Several seeds, e.g. `1..20` (inclusive) or `1,4,9`: the multi-seed study (maglev): every
    /// controller tuned per seed with the same budget, statistics and paired tests over seeds.
    #[arg(long, value_parser = parse_seeds, conflicts_with = "seed")]
    pub seeds: Option<Seeds>,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Output directory [default: the file's output.dir].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Run it; the exit code (2 with the reason on stderr when the file or a run fails).
pub fn main(a: TuneArgs) -> i32 {
    let r = crate::tune::TuneRequest {
        file: a.file,
        seed: a.seed,
        seeds: a.seeds.map(|s| s.0),
        json: a.json,
        out: a.out,
        quiet: a.quiet,
    };
    match crate::tune::tune(&r) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e}");
            2
        }
    }
}
