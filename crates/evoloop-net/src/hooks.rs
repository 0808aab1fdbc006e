//! evoloop-run's `Network` (what a run's optimiser and `evoloop tune` ask of the network),
//! implemented on this crate's workers and mirror.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use evoloop_run::network::NetworkError;

/// The network, as evoloop-run calls it.
pub struct Zenoh;

impl evoloop_run::network::Network for Zenoh {
    fn install_workers(
        &self,
        listen: &str,
        zenoh_config: Option<&Path>,
        expect: usize,
        stop: &AtomicBool,
    ) -> Result<&'static dyn evoloop_run::network::Workers, NetworkError> {
        Ok(crate::workers::install(listen, zenoh_config, expect, stop)
            .map_err(NetworkError::failed)?)
    }

    fn mirror(
        &self,
        run_id: &str,
        connect: String,
        zenoh_config: Option<PathBuf>,
    ) -> Result<Box<dyn evoloop_run::network::Mirror>, NetworkError> {
        let ep = crate::Endpoint::Connect(connect);
        let m = crate::mirror::Mirror::start(run_id, crate::mirror::PREFIX, ep, zenoh_config)
            .map_err(NetworkError::failed)?;
        Ok(Box::new(m))
    }

    fn mirror_prefix(&self) -> &'static str {
        crate::mirror::PREFIX
    }
}

impl evoloop_run::network::Workers for crate::workers::ZenohWorkers {
    fn stats(&self) -> BTreeMap<String, serde_json::Value> {
        crate::workers::ZenohWorkers::stats(self)
            .into_iter()
            .map(|(id, s)| (id, serde_json::to_value(s).unwrap_or_default()))
            .collect()
    }
}

impl evoloop_run::network::Mirror for crate::mirror::Mirror {
    fn finish(self: Box<Self>, dir: &Path) -> Result<String, NetworkError> {
        let r = self.join().map_err(NetworkError::failed)?;
        let line = format!(
            "{} states, {} commands in; {} sets, {} estimates out",
            r.states_in, r.commands_in, r.params_out, r.estimates_out
        );
        match crate::report::write_json(dir, "network.json", &r) {
            Ok(()) => Ok(line),
            Err(e) => Err(NetworkError::failed(format!(
                "{line}; cannot write network.json: {e}"
            ))),
        }
    }
}
