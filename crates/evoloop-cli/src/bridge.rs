//! `evoloop bridge --run RUN_ID --listen|--connect ENDPOINT`: a running run's topics on a Zenoh
//! network, parameter sets from it into the run (`evoloop_net`; feature `zenoh`).

use std::path::PathBuf;

/// Options of `evoloop bridge`: which run to relay, the Zenoh endpoint, and the optional ROS 2
/// node over rmw_zenoh.
#[derive(clap::Args)]
pub struct BridgeArgs {
    /// The run to bridge: its run id, as `evoloop run` prints it (waited for up to 10 s when it is
    /// not running yet) [default: the only running run].
    #[arg(long)]
    pub run: Option<String>,
    /// Listen for peers on this Zenoh endpoint, e.g. `tcp/0.0.0.0:7447` (a remote optimiser then
    /// gives `--connect tcp/THIS_HOST:7447`).
    #[arg(
        long,
        value_name = "ENDPOINT",
        conflicts_with = "connect",
        required_unless_present = "connect"
    )]
    pub listen: Option<String>,
    /// Connect to a peer or router on this endpoint instead.
    #[arg(long, value_name = "ENDPOINT")]
    pub connect: Option<String>,
    /// A Zenoh configuration file (JSON5): TLS, access control (e.g. config/zenoh/tls_acl.json5).
    #[arg(long, value_name = "FILE")]
    pub zenoh_config: Option<PathBuf>,
    /// Seconds to relay, then stop [default: until the run ends or Ctrl-C].
    #[arg(long, value_parser = |s: &str| crate::args::seconds_in(s, 1e6))]
    pub duration: Option<f64>,
    /// Print what was relayed as JSON at the end.
    #[arg(long)]
    pub json: bool,
    /// Be a ROS 2 node too, over rmw_zenoh (ROS 2 nodes with RMW_IMPLEMENTATION=rmw_zenoh_cpp
    /// on the same Zenoh network see it): joint_states, state, command, telemetry, u, gains,
    /// and sets of gains on set_gains, answered on set_gains_result.
    #[arg(long)]
    pub ros2: bool,
    /// The ROS 2 domain id [default: $ROS_DOMAIN_ID, else 0].
    #[arg(long, value_name = "ID", requires = "ros2")]
    pub ros_domain: Option<u32>,
    /// The namespace of the node and its topics.
    #[arg(long, value_name = "NS", default_value = "/evoloop", requires = "ros2")]
    pub ros_namespace: String,
    /// The node's name.
    #[arg(long, value_name = "NAME", default_value = "bridge", requires = "ros2")]
    pub ros_node: String,
    /// The run's scenario, for --ros2 (its joints and gains) [default: the one its controller
    /// was started with].
    #[arg(long, value_name = "FILE", requires = "ros2")]
    pub config: Option<PathBuf>,
}

/// `evoloop bridge` (crate evoloop-net, through `crate::network`).
pub fn main(a: &BridgeArgs) -> u8 {
    match crate::network::commands("evoloop bridge") {
        Ok(n) => n.bridge(a),
        Err(e) => {
            err!("error: {e}");
            2
        }
    }
}

/// Options of `evoloop bench bridge`: a parameter set's round trip on the local path against the
/// path through `evoloop bridge` on loopback.
#[derive(clap::Args)]
pub struct BridgeBenchArgs {
    /// Scenario run in realtime for the measurement [default: config/two_mass/two_mass.toml].
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Parameter sets per phase (local, through the bridge, local again).
    #[arg(long, default_value_t = 200)]
    pub sets: usize,
    /// Print the measurement as JSON on stdout instead of the table
    #[arg(long)]
    pub json: bool,
}

/// `evoloop bench bridge`: a parameter set's round trip, local path against the bridge.
pub fn bench(a: &BridgeBenchArgs) -> u8 {
    match crate::network::commands("evoloop bench bridge") {
        Ok(n) => n.bench_bridge(a),
        Err(e) => {
            err!("error: {e}");
            2
        }
    }
}
