//! `evoloop bridge --run RUN_ID --listen|--connect ENDPOINT`: a running run's topics on a Zenoh
//! network, parameter sets from it into the run (`evoloop_net`; feature `zenoh`).

use std::path::PathBuf;

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
    #[arg(long, value_parser = |s: &str| evoloop_run::node::args::seconds_in(s, 1e6))]
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

/// The ROS 2 domain: `--ros-domain`, else `$ROS_DOMAIN_ID` as ROS 2 reads it, else 0.
#[cfg(feature = "zenoh")]
fn ros_domain(a: &BridgeArgs) -> Result<u32, String> {
    match (a.ros_domain, std::env::var("ROS_DOMAIN_ID")) {
        (Some(d), _) => Ok(d),
        (None, Ok(v)) if !v.trim().is_empty() => v
            .trim()
            .parse()
            .map_err(|_| format!("ROS_DOMAIN_ID={v}: not a domain id")),
        _ => Ok(0),
    }
}

/// How long `--run RUN_ID` waits for that run to start.
#[cfg(feature = "zenoh")]
const RUN_WAIT: std::time::Duration = std::time::Duration::from_secs(10);

#[cfg(feature = "zenoh")]
pub fn main(a: &BridgeArgs) -> u8 {
    use evoloop_net::{bridge, Endpoint};
    // The node's name, checked before anything starts.
    let ros_name = a.ros2.then(|| {
        ros_domain(a).and_then(|d| {
            evoloop_report::ros2::rmw_zenoh::NodeName::new(d, &a.ros_namespace, &a.ros_node)
        })
    });
    let ros_name = match ros_name.transpose() {
        Ok(name) => name,
        Err(e) => {
            err!("error: --ros2: {e}");
            return 2;
        }
    };
    // A named run may be starting with the bridge (a script starts both): wait for it a while.
    let t0 = std::time::Instant::now();
    let run = loop {
        match evoloop_run::run_watch::pick_run(a.run.as_deref()) {
            Ok(r) => break r,
            Err(_) if a.run.is_some() && t0.elapsed() < RUN_WAIT => {
                std::thread::sleep(std::time::Duration::from_millis(50))
            }
            Err(e) => {
                err!("error: {e}");
                return 2;
            }
        }
    };
    // clap takes exactly one of the two.
    let ep = match (&a.listen, &a.connect) {
        (Some(l), _) => Endpoint::Listen(l.clone()),
        (None, c) => Endpoint::Connect(c.clone().unwrap_or_default()),
    };
    if let Some(p) = &a.zenoh_config {
        if !p.is_file() {
            err!("error: --zenoh-config {}: no such file", p.display());
            return 2;
        }
    }
    let duration = a.duration.map(std::time::Duration::from_secs_f64);
    let scenario = match a.ros2 {
        true => match run.scenario(a.config.as_deref(), &Default::default()) {
            Ok(s) => Some(s),
            Err(e) => {
                err!("error: --ros2: {e}");
                return 2;
            }
        },
        false => None,
    };
    let ros = scenario
        .as_ref()
        .zip(ros_name)
        .map(|(scenario, name)| bridge::Ros2Bridge { name, scenario });
    let stop = evoloop_run::node::start::stop_flag();
    err!(
        "evoloop bridge: run {} on Zenoh ({ep:?}), keys evoloop/{}/...",
        run.run_id,
        run.run_id
    );
    if let Some(r) = &ros {
        err!(
            "evoloop bridge: ROS 2 node {} `{}` in domain {} (rmw_zenoh)",
            r.name.namespace,
            r.name.name,
            r.name.domain
        );
    }
    match bridge::run(
        &run.run_id,
        &run.ipc_prefix,
        &ep,
        a.zenoh_config.as_deref(),
        duration,
        ros,
        &stop,
    ) {
        Ok(r) => {
            if a.json {
                crate::print_json(&r);
            } else {
                err!(
                    "evoloop bridge: {} ({:.1} s): out {} states, {} commands, {} telemetry, {} estimates; in {} parameter sets, {} estimates{}",
                    r.ended,
                    r.seconds,
                    r.states,
                    r.commands,
                    r.telemetry,
                    r.estimates_out,
                    r.params_in,
                    r.estimates_in,
                    if r.refused > 0 {
                        format!("; {} messages of another layout refused", r.refused)
                    } else {
                        String::new()
                    }
                );
                if let Some(r2) = &r.ros2 {
                    err!(
                        "evoloop bridge: ROS 2 node {} (domain {}): {} messages out ({} joint states); {} sets of gains in: {} accepted, {} refused{}",
                        r2.node,
                        r2.domain,
                        r2.messages_out,
                        r2.joint_states_out,
                        r2.sets_in,
                        r2.sets_accepted,
                        r2.sets_refused,
                        r2.first_error
                            .as_ref()
                            .map(|e| format!("; {} puts failed, the first: {e}", r2.put_errors))
                            .unwrap_or_default()
                    );
                }
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

#[cfg(not(feature = "zenoh"))]
pub fn main(_: &BridgeArgs) -> u8 {
    err!("error: {}", evoloop_run::needs_zenoh("evoloop bridge"));
    2
}

#[derive(clap::Args)]
pub struct BridgeBenchArgs {
    /// Scenario run in realtime for the measurement [default: config/two_mass.toml].
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Parameter sets per phase (local, through the bridge, local again).
    #[arg(long, default_value_t = 200)]
    pub sets: usize,
    #[arg(long)]
    pub json: bool,
}

/// `evoloop bench bridge`: a parameter set's round trip, local path against the bridge.
#[cfg(feature = "zenoh")]
pub fn bench(a: &BridgeBenchArgs) -> u8 {
    use evoloop_run::bench::bridge as bench;
    if a.sets == 0 {
        err!("error: --sets must be at least 1");
        return 2;
    }
    let scenario = a.scenario.clone().unwrap_or_else(bench::default_scenario);
    let port = match bench::free_port() {
        Ok(p) => p,
        Err(e) => {
            err!("error: {e}");
            return 1;
        }
    };
    match bench::run(&scenario, a.sets, port) {
        Ok(r) => {
            if a.json {
                crate::print_json(&r);
            } else {
                let row = |name: &str, p: &evoloop_rt::timing::Percentiles| {
                    let us = |ns: i64| ns as f64 / 1e3;
                    out!(
                        "  {name:38} p50 {:8.1} us  p90 {:8.1} us  p99 {:8.1} us  max {:8.1} us",
                        us(p.p50_ns),
                        us(p.p90_ns),
                        us(p.p99_ns),
                        us(p.max_ns)
                    );
                };
                out!(
                    "parameter set sent -> in service, seen by the sender ({} sets each, period {} ms):",
                    r.sets_per_phase,
                    r.period_s * 1e3
                );
                row("local (iceoryx2)", &r.local);
                row("through the bridge (Zenoh, loopback)", &r.bridge);
                row("local again", &r.local_again);
                out!(
                    "  the network adds {:.1} us at the median (set in and telemetry out)",
                    r.added_p50_ns / 1e3
                );
                out!("a state's age on arrival (plant stamp -> receipt):");
                row("iceoryx2", &r.state_local);
                row("through the bridge", &r.state_bridge);
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

#[cfg(not(feature = "zenoh"))]
pub fn bench(_: &BridgeBenchArgs) -> u8 {
    err!(
        "error: {}",
        evoloop_run::needs_zenoh("evoloop bench bridge")
    );
    2
}
