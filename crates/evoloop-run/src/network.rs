//! The network (Eclipse Zenoh) as seen from a run: what the optimiser process and `evoloop tune`
//! ask of it (evaluation workers, a remote optimiser's mirror of the run), behind a trait that
//! crate `evoloop-net` implements. A binary built with the root package's `zenoh` feature
//! installs it before anything runs (`install`); without it, `get` is None and every network
//! option is refused with `needs_zenoh`'s message. So this crate, and every crate below the
//! network, is compiled once for builds with and without Zenoh.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::OnceLock;

/// Why the network could not do what a run asked of it.
#[derive(Debug)]
pub enum NetworkError {
    /// This binary was built without the network: what needed it.
    NotBuilt(String),
    /// The network refused or failed: its own error.
    Failed(Box<dyn std::error::Error + Send + Sync>),
}

impl NetworkError {
    /// The network's `error`, for `map_err`.
    pub fn failed(error: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        NetworkError::Failed(error.into())
    }
}

impl std::fmt::Display for NetworkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NetworkError::NotBuilt(what) => f.write_str(&crate::needs_zenoh(what)),
            NetworkError::Failed(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for NetworkError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            NetworkError::NotBuilt(_) => None,
            NetworkError::Failed(e) => e.source(),
        }
    }
}

/// What the network offers a run.
pub trait Network: Sync {
    /// Listen for evaluation workers at `listen` (a Zenoh endpoint), install them for
    /// `optim::evaluate`, and wait until `expect` of them have joined (or `stop`).
    fn install_workers(
        &self,
        listen: &str,
        zenoh_config: Option<&Path>,
        expect: usize,
        stop: &AtomicBool,
    ) -> Result<&'static dyn Workers, NetworkError>;

    /// Mirror run `run_id` from the bridge at `connect` into the iceoryx2 namespace of remote
    /// optimisers (`mirror_prefix`), so that an optimiser on this host runs against it unchanged.
    fn mirror(
        &self,
        run_id: &str,
        connect: String,
        zenoh_config: Option<PathBuf>,
    ) -> Result<Box<dyn Mirror>, NetworkError>;

    /// The iceoryx2 prefix of the namespace remote optimisers run in.
    fn mirror_prefix(&self) -> &'static str;
}

/// The workers an optimiser listens for.
pub trait Workers: Sync {
    /// Every worker seen, by id, as the report's JSON (`OptimiserReport::workers`).
    fn stats(&self) -> BTreeMap<String, serde_json::Value>;
}

/// A remote optimiser's mirror of the run, running until `finish`.
pub trait Mirror: Send {
    /// Stop mirroring and write what crossed the network into `dir` (network.json); a line
    /// that says it, or why it could not.
    fn finish(self: Box<Self>, dir: &Path) -> Result<String, NetworkError>;
}

static NETWORK: OnceLock<&'static dyn Network> = OnceLock::new();

/// Install the network for this process (once; a second call is ignored).
pub fn install(network: &'static dyn Network) {
    let _ = NETWORK.set(network);
}

/// The network, if this binary has one.
pub fn get() -> Option<&'static dyn Network> {
    NETWORK.get().copied()
}

/// The network, or the error that `what` needs it.
pub fn required(what: &str) -> Result<&'static dyn Network, NetworkError> {
    get().ok_or_else(|| NetworkError::NotBuilt(what.to_string()))
}
