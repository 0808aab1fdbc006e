//! Pieces every process binary shares: loading the scenario the launcher handed over, the exit
//! convention, and writing a JSON report into the run directory.

use crate::cli::ProcessArgs;
use crate::config::Scenario;
use serde::Serialize;
use std::path::Path;

/// Exit code of a process whose peer stopped answering (lockstep timeout).
pub const EXIT_PEER_TIMEOUT: i32 = 3;
/// Exit code of a process that could not set itself up (config, IPC).
pub const EXIT_SETUP: i32 = 2;

/// Load the scenario with the launcher's overrides, or exit with the config error.
pub fn load_scenario(args: &ProcessArgs, who: &str) -> Scenario {
    match Scenario::load(&args.config, &args.overrides.to_overrides()) {
        Ok(s) => s,
        Err(e) => fail(who, EXIT_SETUP, &e.to_string()),
    }
}

/// Print `who: message` to stderr and exit with `code`.
pub fn fail(who: &str, code: i32, message: &str) -> ! {
    eprintln!("{who}: error: {message}");
    std::process::exit(code)
}

/// Write `value` as pretty JSON to `dir/name`.
pub fn write_json<T: Serialize>(dir: &Path, name: &str, value: &T) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let text = serde_json::to_string_pretty(value).map_err(std::io::Error::other)?;
    std::fs::write(dir.join(name), text + "\n")
}
