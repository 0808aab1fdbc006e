//! The commands the network adds (`evoloop bridge`, `evoloop worker`, `evoloop bench bridge`,
//! `evoloop bench workers`): their arguments are parsed here in every build, their bodies are
//! crate `evoloop-net`'s, installed by a binary built with the `zenoh` feature (`install`). So
//! this crate is compiled once for builds with and without the network.

use crate::bridge::{BridgeArgs, BridgeBenchArgs};
use crate::worker::{BenchWorkersArgs, WorkerArgs};
use std::sync::OnceLock;

/// The network's commands; each returns the process's exit code.
pub trait NetworkCommands: Sync {
    /// `evoloop bridge`: relay a running run's topics and parameter sets over Zenoh.
    fn bridge(&self, a: &BridgeArgs) -> u8;
    /// `evoloop bench bridge`: a parameter set's round trip, local path against the bridge.
    fn bench_bridge(&self, a: &BridgeBenchArgs) -> u8;
    /// `evoloop worker`: serve candidate evaluations to an optimiser over Zenoh.
    fn worker(&self, a: &WorkerArgs) -> u8;
    /// `evoloop bench workers`: evaluations per second with 0, 1, 2, ... workers on loopback.
    fn bench_workers(&self, a: &BenchWorkersArgs) -> u8;
}

static COMMANDS: OnceLock<&'static dyn NetworkCommands> = OnceLock::new();

/// Install the network's commands for this process (once; a second call is ignored).
pub fn install(commands: &'static dyn NetworkCommands) {
    let _ = COMMANDS.set(commands);
}

/// The network's commands, or the error that `what` needs them.
pub fn commands(what: &str) -> Result<&'static dyn NetworkCommands, String> {
    COMMANDS
        .get()
        .copied()
        .ok_or_else(|| evoloop_run::needs_zenoh(what))
}
