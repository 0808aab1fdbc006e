//! The network's benchmarks: `evoloop bench bridge` (a parameter set's round trip through the
//! bridge against the local path) and `evoloop bench workers` (populations spread over
//! evaluation workers).

pub mod bridge;
pub mod workers;

use crate::error::NetError;
use crate::ipc::IpcError;
use crate::wire::WireError;
use evoloop_run::node::launcher::LocalWorkersError;

/// Why a network benchmark stopped before its figures.
#[derive(Debug)]
pub enum BenchError {
    /// The scenario did not load.
    Config(crate::config::ConfigError),
    /// The network refused: a session, a relay, the bridge, the workers' pool.
    Net(NetError),
    /// iceoryx2 refused: the run's services, a port.
    Ipc(IpcError),
    /// A message through the bridge that is not this build's.
    Wire(WireError),
    /// The run under test could not be started.
    Start(std::io::Error),
    /// No free port, or the local workers could not be started.
    Local(LocalWorkersError),
    /// What the bench needed did not happen: telemetry or a set in service within its time,
    /// workers up, a probe run's values.
    NotMeasured(String),
    /// The bridge's thread panicked.
    BridgePanicked,
}

impl std::fmt::Display for BenchError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BenchError::Config(e) => e.fmt(f),
            BenchError::Net(e) => e.fmt(f),
            BenchError::Ipc(e) => e.fmt(f),
            BenchError::Wire(e) => e.fmt(f),
            BenchError::Start(e) => write!(f, "cannot start the run: {e}"),
            BenchError::Local(e) => e.fmt(f),
            BenchError::NotMeasured(what) => f.write_str(what),
            BenchError::BridgePanicked => f.write_str("the bridge thread panicked"),
        }
    }
}

impl std::error::Error for BenchError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // A wrapping variant reads as the error it wraps: its source is that error's.
            BenchError::Config(e) => e.source(),
            BenchError::Net(e) => e.source(),
            BenchError::Ipc(e) => e.source(),
            BenchError::Wire(e) => e.source(),
            BenchError::Local(e) => e.source(),
            BenchError::Start(e) => Some(e),
            BenchError::NotMeasured(_) | BenchError::BridgePanicked => None,
        }
    }
}

impl From<NetError> for BenchError {
    fn from(e: NetError) -> Self {
        BenchError::Net(e)
    }
}

impl From<IpcError> for BenchError {
    fn from(e: IpcError) -> Self {
        BenchError::Ipc(e)
    }
}

impl From<WireError> for BenchError {
    fn from(e: WireError) -> Self {
        BenchError::Wire(e)
    }
}

impl From<LocalWorkersError> for BenchError {
    fn from(e: LocalWorkersError) -> Self {
        BenchError::Local(e)
    }
}
