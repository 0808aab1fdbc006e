//! The optimisers by name, as a configuration or a command line names them: one constructor for
//! a box, a population and an evaluation budget.

use crate::bayes::{Bayes, BayesConfig, Safety};
use crate::cmaes::{Cmaes, CmaesConfig};
use crate::emupso::{EmuPso, EmuPsoSettings};
use crate::jade::{Jade, JadeConfig};
use crate::pso::Pso;
use crate::swarm::SwarmConfig;
use crate::wolves::{Goa, Gwo, Woa};
use crate::{DeConfig, DifferentialEvolution, Ga, GaConfig, Optimiser, SettingsError};

/// The study's algorithms: the paper's six, then the real-coded GA of the fuzzy-network paper
/// and JADE, the adaptive DE the Python libraries offer (`crate::jade`). (Hooke-Jeeves is a
/// local search from one point, not a population method; it is left out.)
pub const ALGORITHMS: [&str; 8] = ["emupso", "pso", "woa", "gwo", "goa", "de", "ga", "jade"];

/// The sample-efficient optimisers for experiments on a running plant (`crate::cmaes`,
/// `crate::bayes`): each starts from the first seed set, the set in service (`safe_bayes` needs
/// one: it is its known-safe seed). Not in the benchmark study's list: they are built for tens
/// to hundreds of costly evaluations, not for the study's thousands of cheap ones.
pub const SAMPLE_EFFICIENT: [&str; 3] = ["cmaes", "bayes", "safe_bayes"];

/// Every name `build_seeded` knows.
pub fn all() -> Vec<&'static str> {
    ALGORITHMS
        .iter()
        .chain(&SAMPLE_EFFICIENT)
        .copied()
        .collect()
}

/// CMA-ES's first step as a fraction of the box.
const CMAES_SIGMA: f64 = 0.2;
/// Random experiments after the start before Bayesian optimisation's model decides.
const BAYES_INITIAL: usize = 4;
/// The safe variant's confidence multiplier: a one-sided 99.87 % bound under its model. On
/// arsinh's seed 1 it and 2 sigma both aborted 2 trials of 660 at `bayes::SAFE_LENGTH`; 3 ended
/// lower (the record, docs/measurements/2026-11-28-optimisers.md, has all seven settings tried).
const SAFE_BETA: f64 = 3.0;

/// An optimiser of the study over a box, for a population and an evaluation budget.
/// DE is DE/rand/1/bin with F = 0.5, CR = 0.9 (Storn and Price's standard; the paper gives no
/// settings) and no stopping rule; the GA's mutation steps shrink to zero at the end of the
/// budget (N_max of its eq. 19 = its iterations: two evaluations each after the first
/// population).
pub fn build(
    name: &str,
    lower: &[f64],
    upper: &[f64],
    population: usize,
    evaluations: usize,
    seed: u64,
) -> Result<Box<dyn Optimiser + Send>, BuildError> {
    build_seeded(name, lower, upper, population, evaluations, seed, &[])
}

/// Why an optimiser could not be built by name.
#[derive(Debug, Clone, PartialEq)]
pub enum BuildError {
    /// No optimiser has this name.
    Unknown(String),
    /// The optimiser refused its settings (box, population, budget).
    Settings(SettingsError),
}

impl std::fmt::Display for BuildError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BuildError::Unknown(name) => {
                write!(
                    f,
                    "unknown algorithm {name:?} (known: {})",
                    all().join(", ")
                )
            }
            BuildError::Settings(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for BuildError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            BuildError::Unknown(_) => None,
            BuildError::Settings(e) => Some(e),
        }
    }
}

impl From<SettingsError> for BuildError {
    fn from(e: SettingsError) -> Self {
        BuildError::Settings(e)
    }
}

/// `build`, with user-specified sets placed in the GA's initial population (the fuzzy-network
/// paper's GA starts from prespecified sets; the swarms and DE start at random and ignore them).
pub fn build_seeded(
    name: &str,
    lower: &[f64],
    upper: &[f64],
    population: usize,
    evaluations: usize,
    seed: u64,
    seeds: &[Vec<f64>],
) -> Result<Box<dyn Optimiser + Send>, BuildError> {
    let swarm = || {
        SwarmConfig::for_budget(
            lower.to_vec(),
            upper.to_vec(),
            population,
            evaluations,
            seed,
        )
    };
    Ok(match name {
        "emupso" => Box::new(EmuPso::new(swarm(), EmuPsoSettings::default())?),
        "pso" => Box::new(Pso::new(swarm())?),
        "gwo" => Box::new(Gwo::new(swarm())?),
        "woa" => Box::new(Woa::new(swarm())?),
        "goa" => Box::new(Goa::new(swarm())?),
        "de" => Box::new(DifferentialEvolution::new(DeConfig {
            np: population,
            f: 0.5,
            cr: 0.9,
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            seed,
            diversity_stop: false,
            eta: 1,
            epsilon: 0.0,
        })?),
        "jade" => Box::new(Jade::new(JadeConfig::new(
            population,
            lower.to_vec(),
            upper.to_vec(),
            seed,
        ))?),
        "ga" => Box::new(Ga::new(
            GaConfig {
                population,
                p_crossover: 0.9,
                p_mutation: None,
                max_iterations: (evaluations.saturating_sub(population) / 2).max(1),
                seed,
            },
            lower,
            upper,
            seeds,
        )),
        "cmaes" => Box::new(Cmaes::new(CmaesConfig {
            lower: lower.to_vec(),
            upper: upper.to_vec(),
            population,
            sigma: CMAES_SIGMA,
            start: seeds.first().cloned(),
            seed,
        })?),
        "bayes" | "safe_bayes" => Box::new(bayes(name == "safe_bayes", lower, upper, seed, seeds)?),
        other => return Err(BuildError::Unknown(other.to_string())),
    })
}

/// `bayes` or (`safe`) `safe_bayes` as `build_seeded` makes them, for a caller that adds a model
/// of the plant (`Bayes::with_prior`).
pub fn bayes(
    safe: bool,
    lower: &[f64],
    upper: &[f64],
    seed: u64,
    seeds: &[Vec<f64>],
) -> Result<Bayes, SettingsError> {
    Bayes::new(BayesConfig {
        lower: lower.to_vec(),
        upper: upper.to_vec(),
        seed,
        start: seeds.first().cloned(),
        initial: BAYES_INITIAL,
        safety: safe.then_some(Safety { beta: SAFE_BETA }),
    })
}
