//! evoloop-run's `Network` (what a run's optimiser and `evoloop tune` ask of the network),
//! implemented on this crate's workers and mirror.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// The network, as evoloop-run calls it.
pub struct Zenoh;

impl evoloop_run::network::Network for Zenoh {
    fn install_workers(
        &self,
        listen: &str,
        zenoh_config: Option<&Path>,
        expect: usize,
        stop: &AtomicBool,
    ) -> Result<&'static dyn evoloop_run::network::Workers, String> {
        Ok(crate::workers::install(listen, zenoh_config, expect, stop)?)
    }

    fn mirror(
        &self,
        run_id: &str,
        prefix: &str,
        connect: String,
        zenoh_config: Option<PathBuf>,
    ) -> Result<Box<dyn evoloop_run::network::Mirror>, String> {
        let ep = crate::Endpoint::Connect(connect);
        Ok(Box::new(crate::mirror::Mirror::start(
            run_id,
            prefix,
            ep,
            zenoh_config,
        )?))
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
    fn finish(self: Box<Self>, dir: &Path) {
        const WHO: &str = "evoloop-optimiser";
        match self.join() {
            Ok(r) => {
                eprintln!(
                    "{WHO}: over the network: {} states, {} commands in; {} sets, {} estimates out",
                    r.states_in, r.commands_in, r.params_out, r.estimates_out
                );
                if let Err(e) = crate::report::write_json(dir, "network.json", &r) {
                    eprintln!("{WHO}: cannot write network.json: {e}");
                }
            }
            Err(e) => eprintln!("{WHO}: network mirror: {e}"),
        }
    }
}
