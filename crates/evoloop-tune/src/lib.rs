//! `evoloop tune FILE`: the fuzzy-network paper's optimisation experiments from a TOML file.
//! `experiment = "arsinh"` (Section 5.1) or `"maglev"` (Section 5.2); results as JSON/CSV and PNG
//! in the output directory, a summary on stdout (or JSON with --json), progress on a terminal.

#![forbid(unsafe_code)]

pub mod arsinh;
pub mod compare;
pub mod direct;
mod error;
pub mod maglev;

pub use error::TuneError;

use evoloop_control::{fuzzy, law, reference};
use evoloop_files as files;
use evoloop_optim as optim;
use evoloop_report as report;
use evoloop_scenario::{config, sim};
use evoloop_stats as stats;

use crate::optim::hybrid::HybridConfig;
use crate::optim::GaConfig;
use evoloop_control::check::{Check, ConfigError};
use evoloop_schemes::WriteError;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// What to run: the experiment file and the command line's choices.
#[derive(Debug, Clone)]
pub struct TuneRequest {
    /// The experiment file, or a direct-scheme scenario (tuned or compared in this process).
    pub file: PathBuf,
    /// `--seed`: the seed (GA, plant noise), over the file's `seed` (default 1) or the scenario's.
    pub seed: Option<u64>,
    /// Several seeds: the multi-seed study (maglev).
    pub seeds: Option<Vec<u64>>,
    /// `--json`: the result as JSON on stdout instead of the summary, without progress.
    pub json: bool,
    /// `--out`: the output directory, over the file's `output.dir`.
    pub out: Option<PathBuf>,
    /// `--quiet`: no progress bar.
    pub quiet: bool,
    /// `--compare`: the optimisers to compare on a direct scenario.
    pub compare: Option<Vec<String>>,
    /// `--settle`: `optimiser.settle` for every run of the comparison.
    pub settle: Option<u32>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTune {
    experiment: Experiment,
    seed: Option<u64>,
    ga: Option<RawGa>,
    maglev: Option<maglev::RawMaglevTune>,
    output: Option<RawOut>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Experiment {
    Arsinh,
    Maglev,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGa {
    population: Option<usize>,
    p_crossover: Option<f64>,
    p_mutation: Option<f64>,
    phases: Option<[usize; 3]>,
    threads: Option<usize>,
    hj_step: Option<f64>,
    hj_per_candidate: Option<usize>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawOut {
    dir: Option<PathBuf>,
    plots: Option<bool>,
}

/// What every experiment needs to know about the run.
pub struct Run {
    /// The optimiser's settings from the `[ga]` table (GA and Hooke-Jeeves phases).
    pub hybrid: HybridConfig,
    /// The output directory (created before the experiment runs).
    pub out: PathBuf,
    /// Whether to draw the PNG figures (`output.plots`, default true).
    pub plots: bool,
    /// Print the result as JSON on stdout instead of the summary.
    pub json: bool,
    /// Show progress bars (not with `--quiet` or `--json`).
    pub progress: bool,
    /// The run's seed: the GA's, and the maglev tuning run's noise seed.
    pub seed: u64,
}

fn hybrid_config(
    file: &Path,
    g: Option<RawGa>,
    seed: u64,
    default_phases: [usize; 3],
) -> Result<HybridConfig, ConfigError> {
    let g = g.unwrap_or(RawGa {
        population: None,
        p_crossover: None,
        p_mutation: None,
        phases: None,
        threads: None,
        hj_step: None,
        hj_per_candidate: None,
    });
    let check = Check::new(file);
    let population = check.count("ga.population", g.population.unwrap_or(10), 2, 10_000)?;
    let p_crossover = check.range("ga.p_crossover", g.p_crossover.unwrap_or(0.9), 0.0, 1.0)?;
    if let Some(p) = g.p_mutation {
        check.range("ga.p_mutation", p, 0.0, 1.0)?;
    }
    let phases = g.phases.unwrap_or(default_phases);
    let threads = check.count("ga.threads", g.threads.unwrap_or(2), 1, 256)?;
    let hj_step = g.hj_step.unwrap_or(0.05);
    if !(hj_step > 0.0 && hj_step <= 1.0) {
        return check.fail(
            "ga.hj_step",
            format!("must be within (0, 1] (got {hj_step})"),
        );
    }
    Ok(HybridConfig {
        ga: GaConfig {
            population,
            p_crossover,
            p_mutation: g.p_mutation,
            // Mutation steps shrink to local over the GA's phases (1 and 2).
            max_iterations: (phases[0] + phases[1]).max(1),
            seed,
        },
        phases,
        scaling: Vec::new(),
        threads,
        hj_step,
        hj_per_candidate: g.hj_per_candidate.unwrap_or(0),
    })
}

fn read(file: &Path) -> Result<RawTune, ConfigError> {
    let check = Check::new(file);
    let text =
        crate::files::read_text(file).or_else(|e| check.fail("", config::unreadable(file, &e)))?;
    crate::files::from_toml(&text).or_else(|p| check.fail(&p.key, p.reason))
}

/// The experiment file refuses a `[maglev]` table the arsinh experiment does not use.
fn maglev_unused<T>(file: &Path) -> Result<T, ConfigError> {
    Check::new(file).fail("maglev", "not used by the arsinh experiment; remove it")
}

/// Read and validate an experiment file without running it.
pub fn validate_file(file: &Path) -> Result<(), TuneError> {
    let raw = read(file)?;
    let phases = match raw.experiment {
        Experiment::Arsinh => [95, 200, 30],
        Experiment::Maglev => [150, 0, 0],
    };
    hybrid_config(file, raw.ga, 1, phases)?;
    if raw.experiment == Experiment::Maglev {
        maglev::spec(file, raw.maglev)?;
    } else if raw.maglev.is_some() {
        return maglev_unused(file).map_err(TuneError::from);
    }
    Ok(())
}

/// Run the experiment the request names (or a direct-scheme scenario, in this process).
pub fn tune(a: &TuneRequest) -> Result<(), TuneError> {
    if crate::files::read_text(&a.file).is_ok_and(|t| direct::is_scenario(&t)) {
        return direct::run(&a.file, a);
    }
    let raw = read(&a.file)?;
    let seed = a.seed.or(raw.seed).unwrap_or(1);
    let (default_phases, default_dir) = match raw.experiment {
        Experiment::Arsinh => ([95, 200, 30], "runs/arsinh_tune"),
        Experiment::Maglev => ([150, 0, 0], "runs/maglev_tune"),
    };
    let out_raw = raw.output.unwrap_or(RawOut {
        dir: None,
        plots: None,
    });
    let run = Run {
        hybrid: hybrid_config(&a.file, raw.ga, seed, default_phases)?,
        out: a
            .out
            .clone()
            .or(out_raw.dir)
            .unwrap_or_else(|| PathBuf::from(default_dir)),
        plots: out_raw.plots.unwrap_or(true),
        json: a.json,
        progress: !a.quiet && !a.json,
        seed,
    };
    std::fs::create_dir_all(&run.out).map_err(WriteError::file(&run.out))?;
    match raw.experiment {
        Experiment::Arsinh => {
            if raw.maglev.is_some() {
                return maglev_unused(&a.file).map_err(TuneError::from);
            }
            if a.seeds.is_some() {
                return Err(TuneError::option(
                    "--seeds",
                    "the multi-seed study is for the maglev experiment",
                ));
            }
            arsinh::run(run)
        }
        Experiment::Maglev => {
            let spec = maglev::spec(&a.file, raw.maglev)?;
            match &a.seeds {
                Some(seeds) => maglev::study(run, spec, seeds),
                None => maglev::run(run, spec),
            }
        }
    }
}
