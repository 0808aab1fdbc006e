//! Does optimising the excitation pay? Over seeds, the same experiment (a scenario run
//! in-process with the trajectory as its reference, encoder and torque noise seeded by the seed)
//! on two trajectories of the same search: the first feasible random trajectory its elite phase
//! found, and the optimised one. The paired relative errors of the identified base parameters
//! are compared by Wilcoxon's signed-rank test.

use super::excitation::{search, ExcitationProblem, Search};
use super::lls::{estimate, Options, Recording};
use super::ExcitationError;
use crate::config::{ConfigError, Overrides, Scenario};
use crate::reference::series::FourierSeries;
use evoloop_control::check::Check;
use serde::Serialize;
use std::path::Path;

/// One seed's pair.
#[derive(Debug, Clone, Serialize)]
pub struct SeedResult {
    /// The search's seed, and the experiment's encoder and torque noise seed.
    pub seed: u64,
    /// Condition number of the first feasible random trajectory's scaled base regressor.
    pub cond_initial: f64,
    /// Condition number of the optimised trajectory's scaled base regressor.
    pub cond_optimised: f64,
    /// Relative error (2-norm) of the identified base parameters, percent.
    pub error_initial: f64,
    /// The same on the optimised trajectory, percent.
    pub error_optimised: f64,
}

/// `scenario_text` (a scenario file's text, at `path`) with `series` as its reference and the
/// arm starting where it starts, under `seed`.
pub fn with_trajectory(
    scenario_text: &str,
    path: &Path,
    series: &FourierSeries,
    seed: u64,
) -> Result<Scenario, ConfigError> {
    let check = Check::new(path);
    let mut doc: toml::Table = match scenario_text.parse() {
        Ok(doc) => doc,
        Err(e) => return check.fail("", e.to_string()),
    };
    let reference = toml::Value::try_from(match series.to_reference() {
        crate::reference::Reference::Sines {
            offsets,
            amplitudes,
            frequencies,
            phases,
        } => serde_json::json!({
            "kind": "sines", "offsets": offsets, "amplitudes": amplitudes,
            "frequencies": frequencies, "phases": phases,
        }),
        _ => unreachable!("a Fourier series is a sines reference"),
    });
    let reference = match reference {
        Ok(r) => r,
        Err(e) => return check.fail("reference", e.to_string()),
    };
    doc.insert("reference".into(), reference);
    doc.insert("seed".into(), toml::Value::Integer(seed as i64));
    if let Some(arm) = doc
        .get_mut("plant")
        .and_then(|p| p.get_mut("arm"))
        .and_then(|a| a.as_table_mut())
    {
        arm.remove("initial_q");
    }
    Scenario::parse(&doc.to_string(), path, &Overrides::default())
}

/// The study: for each seed, a search on `problem` and the experiment on its first feasible
/// initial trajectory and on its optimised one. `progress` sees each finished seed.
pub fn run(
    problem: &ExcitationProblem,
    scenario_text: &str,
    path: &Path,
    seeds: &[u64],
    search_settings: &Search,
    torque_noise: f64,
    progress: &mut dyn FnMut(&SeedResult),
) -> Result<Vec<SeedResult>, ExcitationError> {
    let mut out = Vec::with_capacity(seeds.len());
    for &seed in seeds {
        let o = search(
            problem,
            &Search {
                seed,
                ..search_settings.clone()
            },
            &mut |_, _, _| {},
        )?;
        if o.feasible_elites == 0 {
            return Err(ExcitationError::NotFound(format!(
                "seed {seed}: the elite phase found no feasible trajectory"
            )));
        }
        let initial = problem
            .decode(&o.initial_x[0])
            .ok_or_else(|| ExcitationError::NotFound("the first elite is not reachable".into()))?;
        let error = |s: &FourierSeries| -> Result<f64, ExcitationError> {
            let scn = with_trajectory(scenario_text, path, s, seed)?;
            let sim = crate::sim::simulate(&scn);
            let mut rec = Recording::from_sim(&scn, &sim)?;
            if torque_noise > 0.0 {
                rec.add_torque_noise(torque_noise, seed);
            }
            Ok(100.0 * estimate(&problem.model, &rec, &Options::default())?.relative_error_norm)
        };
        let r = SeedResult {
            seed,
            cond_initial: o.initial[0].cond,
            cond_optimised: o.criteria.cond,
            error_initial: error(&initial)?,
            error_optimised: error(&o.series)?,
        };
        progress(&r);
        out.push(r);
    }
    Ok(out)
}
