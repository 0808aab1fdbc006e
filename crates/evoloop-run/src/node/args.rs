//! What a run and each of its processes are started with: the options `evoloop run` takes (parsed
//! by the command line, crate `evoloop-cli`), and the arguments the launcher hands each child,
//! which parses exactly these (`override_args`).

use crate::config::Overrides;
use std::path::PathBuf;

/// `evoloop run`: the scenario file and its overrides, the run's id and IPC prefix, its seeds,
/// its floor, workers on this host and the live view.
#[derive(Debug, Clone)]
pub struct RunArgs {
    /// Scenario file (TOML); `None`: the default scenario, here or in the source tree.
    pub file: Option<PathBuf>,
    /// Overrides of the scenario file; the launcher passes them on to the run's processes.
    pub overrides: Overrides,
    /// Run id used in the service names (`None`: generated, unique on this machine).
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files.
    pub ipc_prefix: String,
    /// No progress lines.
    pub quiet: bool,
    /// Several seeds: one run per seed and a paired study (`--seeds`).
    pub seeds: Option<Seeds>,
    /// Realtime: seconds of the bare loop measured after the run as its floor (`None`: the
    /// run's duration, at most 5 s).
    pub floor_duration: Option<f64>,
    /// Evaluation workers to start on this host, connected over Zenoh on loopback.
    pub workers: Option<u16>,
    /// Serve the run live (Foxglove WebSocket protocol) on this address.
    pub live: Option<String>,
    /// Let `live` listen beyond loopback.
    pub live_remote: bool,
}

/// What every process of a run receives from the launcher.
#[derive(Debug, Clone)]
pub struct ProcessArgs {
    /// Scenario file (TOML).
    pub config: PathBuf,
    /// Run id: part of every service name, so runs never cross-talk.
    pub run_id: String,
    /// Prefix of iceoryx2's files for this run.
    pub ipc_prefix: String,
    /// `evoloop run`'s overrides of the scenario file, with `out` set to the run's directory.
    pub overrides: Overrides,
}

/// What the optimiser process receives: what every process does, and its own options.
#[derive(Debug, Clone)]
pub struct OptimiserArgs {
    /// What every process receives.
    pub args: ProcessArgs,
    /// Rejoin a running run (started again after a crash).
    pub rejoin: bool,
    /// Join the run from another host through its bridge at this Zenoh endpoint.
    pub connect: Option<String>,
    /// A Zenoh configuration file (JSON5) for `connect`.
    pub zenoh_config: Option<PathBuf>,
}

/// `overrides` as the command-line arguments a child process parses back into them (the
/// options `evoloop run` takes of the same names).
pub fn override_args(o: &Overrides) -> Vec<String> {
    let mut a = Vec::new();
    let mut flag = |name: &str, value: Option<String>| {
        a.push(name.to_string());
        a.extend(value);
    };
    if let Some(m) = o.mode {
        flag("--mode", Some(m.to_string()));
    }
    if let Some(d) = o.duration {
        flag("--duration", Some(d.to_string()));
    }
    if let Some(out) = &o.out {
        flag("--out", Some(out.display().to_string()));
    }
    if let Some(s) = o.seed {
        flag("--seed", Some(s.to_string()));
    }
    if let Some(m) = o.optimiser {
        flag("--optimiser", Some(m.to_string()));
    }
    if o.no_rt {
        flag("--no-rt", None);
    }
    if let Some(w) = o.wait {
        flag("--wait", Some(w.name().to_string()));
    }
    if let Some(e) = &o.workers_listen {
        flag("--workers-listen", Some(e.clone()));
    }
    if let Some(n) = o.workers_expect {
        flag("--workers-expect", Some(n.to_string()));
    }
    a
}

/// The seeds of a multi-seed study.
#[derive(Debug, Clone, PartialEq)]
pub struct Seeds(pub Vec<u64>);

/// The most seeds a study takes.
const MAX_SEEDS: u64 = 1000;

/// `A..B` (inclusive) or a comma-separated list of seeds: 2 to `MAX_SEEDS` different ones. The
/// count is checked before anything is built (`0..18446744073709551615` asked for 2^64 seeds).
pub fn parse_seeds(s: &str) -> Result<Seeds, String> {
    let too_many = |n: String| format!("give 2 to {MAX_SEEDS} seeds, e.g. 1..20 (got {n})");
    let seeds: Vec<u64> = if let Some((a, b)) = s.split_once("..") {
        let a: u64 = a.trim().parse().map_err(|e| format!("`{a}`: {e}"))?;
        let b: u64 = b.trim().parse().map_err(|e| format!("`{b}`: {e}"))?;
        if b < a {
            return Err(format!(
                "{a}..{b} is empty: give A..B with A <= B, e.g. 1..20"
            ));
        }
        match (b - a).checked_add(1) {
            Some(n) if n <= MAX_SEEDS => (a..=b).collect(),
            Some(n) => return Err(too_many(n.to_string())),
            None => return Err(too_many("2^64".into())),
        }
    } else {
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() as u64 > MAX_SEEDS {
            return Err(too_many(parts.len().to_string()));
        }
        parts
            .iter()
            .map(|x| x.trim().parse().map_err(|e| format!("`{x}`: {e}")))
            .collect::<Result<_, _>>()?
    };
    if seeds.len() < 2 {
        return Err(too_many(seeds.len().to_string()));
    }
    let mut sorted = seeds.clone();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!(
            "seed {} is given twice: a study's seeds are its independent samples",
            w[0]
        ));
    }
    Ok(Seeds(seeds))
}
