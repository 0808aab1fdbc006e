//! Why a bridge, a ROS 2 node or a Zenoh session could not be set up or went on no longer.

use crate::ipc::IpcError;
use std::path::PathBuf;

/// Why `open`, the bridge's relays, `bridge::run`, `Ros2Node::new` or the evaluation workers'
/// pool (`workers::install`, `ZenohWorkers::start`, `workers::serve`) stopped.
#[derive(Debug)]
pub enum NetError {
    /// Zenoh refused an operation: what (e.g. "Zenoh publisher on KEY"), and Zenoh's error.
    Zenoh {
        /// The operation and its key or endpoint.
        doing: String,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// A Zenoh configuration file that Zenoh does not read.
    ConfigFile {
        /// The file.
        file: PathBuf,
        /// Zenoh's error.
        source: zenoh::Error,
    },
    /// iceoryx2 refused (the run's services, a publisher, a subscriber).
    Ipc(IpcError),
    /// A ROS 2 name refused (a topic under the node's namespace).
    Name(crate::report::ros2::rmw_zenoh::NameError),
    /// This process has evaluation workers already (`optim::remote::install` takes one pool).
    WorkersInstalled(crate::optim::remote::AlreadyInstalled),
    /// A message that postcard could not encode: what it was.
    Encode {
        /// The message.
        what: &'static str,
        /// postcard's error.
        source: postcard::Error,
    },
}

impl NetError {
    /// Zenoh's `source` on `doing`, for `map_err`. `doing` becomes a `String` only on the error: a `&'static str` costs nothing on success,
    /// so a receive in a loop can name its operation without allocating.
    pub(crate) fn zenoh(doing: impl Into<String>) -> impl FnOnce(zenoh::Error) -> NetError {
        move |source| NetError::Zenoh {
            doing: doing.into(),
            source,
        }
    }
}

impl std::fmt::Display for NetError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NetError::Zenoh { doing, source } => write!(f, "{doing}: {source}"),
            NetError::ConfigFile { file, source } => {
                write!(f, "{}: not a Zenoh configuration: {source}", file.display())
            }
            NetError::Ipc(e) => e.fmt(f),
            NetError::Name(e) => e.fmt(f),
            NetError::WorkersInstalled(e) => e.fmt(f),
            NetError::Encode { what, source } => write!(f, "encoding {what}: {source}"),
        }
    }
}

impl std::error::Error for NetError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            NetError::Zenoh { source, .. } | NetError::ConfigFile { source, .. } => {
                Some(source.as_ref())
            }
            NetError::Ipc(e) => e.source(),
            NetError::Name(_) => None,
            NetError::WorkersInstalled(e) => e.source(),
            NetError::Encode { source, .. } => Some(source),
        }
    }
}

impl From<IpcError> for NetError {
    fn from(e: IpcError) -> Self {
        NetError::Ipc(e)
    }
}

impl From<crate::report::ros2::rmw_zenoh::NameError> for NetError {
    fn from(e: crate::report::ros2::rmw_zenoh::NameError) -> Self {
        NetError::Name(e)
    }
}
