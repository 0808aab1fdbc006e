//! Beyond one machine (feature `zenoh`): a run's topics on an Eclipse Zenoh network, so that an
//! optimiser on another host can join a run. Inside one host everything stays on iceoryx2.
//!
//! - `evoloop bridge --run RUN_ID --listen|--connect ENDPOINT` (`bridge`) relays a running
//!   run's topics between iceoryx2 and Zenoh key expressions `evoloop/<run id>/<topic>`.
//! - `evoloop optimiser ... --connect ENDPOINT` (`mirror`) runs the optimiser on another host:
//!   the run's topics are mirrored into that host's iceoryx2 namespace for remote optimisers
//!   (`mirror::PREFIX`), and the optimiser's own code runs against it unchanged.
//! - `evoloop worker --connect ENDPOINT` (`workers`) serves candidate evaluations to an optimiser
//!   with `optimiser.workers = "zenoh"`, which spreads its costly populations over the workers up
//!   (`optim::remote`); `evoloop bench workers` (`bench::workers`) measures it; `evoloop bench
//!   bridge` (`bench::bridge`) the bridge.
//! - `install` gives a binary all of it: evoloop-run's `network::Network` (workers and the
//!   mirror for the optimiser process and `evoloop tune`) and evoloop-cli's `NetworkCommands`
//!   (the commands above). This crate sits above both, so neither is compiled again for it.
//!
//! What crosses and which way (`ROUTES`):
//!
//! | key under `evoloop/<run id>/` | from | to |
//! |---|---|---|
//! | `state`, `command`, `telemetry` | the run (iceoryx2) | the network: monitors, a remote optimiser |
//! | `estimate`, `optimiser_status` | the run: its optimiser's, or a remote one's coming back | the network (monitoring) |
//! | `params` | the network: a remote optimiser | the run's params topic: the controller validates each set as any other (bounds, finiteness, stability, version order) |
//! | `remote/estimate`, `remote/optimiser_status` | a remote optimiser | the run's topics |
//!
//! A remote optimiser's estimates come in on their own keys, so what the bridge sends out
//! never comes back in: no message can circle.
//!
//! Security: a run is on the network only while a bridge runs, and a bridge only listens on or
//! connects to the endpoint it is given. Multicast and gossip scouting are off: no peer is
//! discovered, none is announced. For anything beyond a trusted network, give a Zenoh
//! configuration file (`--zenoh-config`) with TLS and access control
//! (`config/zenoh/tls_acl.json5` is an example); see the book (docs/).
//!
//! With `--ros2` the bridge is also a ROS 2 node over rmw_zenoh (`ros2`): the run's topics in
//! rmw_zenoh's keys, tokens and CDR, and sets of gains from a ROS 2 topic.
//!
//! Wire format (`wire`): the message's fixed-size `#[repr(C)]` bytes as they are in shared
//! memory, behind a header with the type's versioned iceoryx2 name and size, so a peer of
//! another build refuses a layout it does not share instead of misreading it.

#[macro_use]
extern crate evoloop_scenario;

pub mod bench;
pub mod bridge;
pub mod cli;
mod error;
mod hooks;
pub mod mirror;
pub mod ros2;
pub mod wire;
pub mod workers;

pub use error::NetError;
use std::path::Path;
use std::time::Duration;
use zenoh::Wait;

use crate::ipc::Topic;

/// Install the network into this process: call first thing in `main`.
pub fn install() {
    evoloop_run::network::install(&hooks::Zenoh);
    evoloop_cli::network::install(&cli::Commands);
}
use evoloop_ipc as ipc;
use evoloop_msg as msg;
use evoloop_optim as optim;
use evoloop_report as report;
use evoloop_scenario::config;
use evoloop_schemes::{gains, jobs};

/// Where a process meets the network: it listens on an endpoint (the host others connect to)
/// or connects to one. Zenoh endpoints: `tcp/127.0.0.1:7447`, `tls/host:7447`, ...
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// Listen on this endpoint: the host others connect to.
    Listen(String),
    /// Connect to this endpoint, trying until it answers.
    Connect(String),
}

/// Open a Zenoh session in peer mode on `ep` alone: scouting off (nothing discovered, nothing
/// announced), the configuration file's settings (TLS, access control) first when given.
pub fn open(ep: &Endpoint, config_file: Option<&Path>) -> Result<zenoh::Session, NetError> {
    let mut cfg = match config_file {
        Some(p) => zenoh::Config::from_file(p).map_err(|source| NetError::ConfigFile {
            file: p.to_path_buf(),
            source,
        })?,
        None => zenoh::Config::default(),
    };
    let set = |cfg: &mut zenoh::Config, key: &str, value: &str| {
        cfg.insert_json5(key, value)
            .map_err(NetError::zenoh(format!(
                "Zenoh configuration {key} = {value}"
            )))
    };
    set(&mut cfg, "mode", "\"peer\"")?;
    set(&mut cfg, "scouting/multicast/enabled", "false")?;
    set(&mut cfg, "scouting/gossip/enabled", "false")?;
    let (key, endpoint) = match ep {
        Endpoint::Listen(e) => ("listen/endpoints", e),
        Endpoint::Connect(e) => ("connect/endpoints", e),
    };
    let list = serde_json::to_string(&[endpoint]).expect("a list of one string");
    set(&mut cfg, key, &list)?;
    if matches!(ep, Endpoint::Connect(_)) {
        // Keep trying to reach the endpoint (a bridge started after its optimiser) rather than
        // failing the open: the caller decides how long to wait for data.
        set(&mut cfg, "connect/timeout_ms", "-1")?;
        set(&mut cfg, "connect/exit_on_failure", "false")?;
    }
    zenoh::open(cfg).wait().map_err(NetError::zenoh(format!(
        "opening a Zenoh session on {endpoint}"
    )))
}

/// The Zenoh key of `topic` of run `run_id` (see the module docs for `remote`).
pub fn key(run_id: &str, topic: Topic, remote: bool) -> String {
    if remote {
        format!("evoloop/{run_id}/remote/{}", topic.name())
    } else {
        format!("evoloop/{run_id}/{}", topic.name())
    }
}

/// The relays poll their ports this often (a sleep of 100 us is ~0.1-0.15 ms on this VM; the
/// CPU it costs is a wake-up per poll, ~1 % of a core).
pub const POLL: Duration = Duration::from_micros(100);
