//! The network's commands (`evoloop bridge`, `evoloop worker`, `evoloop bench bridge`,
//! `evoloop bench workers`) behind evoloop-cli's `NetworkCommands`: the command line parses their
//! arguments in every build; a binary with the `zenoh` feature installs these bodies (`install`).

use evoloop_cli::bridge::{BridgeArgs, BridgeBenchArgs};
use evoloop_cli::network::NetworkCommands;
use evoloop_cli::worker::{BenchWorkersArgs, WorkerArgs};

/// The commands, as evoloop-cli calls them.
pub struct Commands;

impl NetworkCommands for Commands {
    fn bridge(&self, a: &BridgeArgs) -> u8 {
        bridge(a)
    }
    fn bench_bridge(&self, a: &BridgeBenchArgs) -> u8 {
        bench_bridge(a)
    }
    fn worker(&self, a: &WorkerArgs) -> u8 {
        worker(a)
    }
    fn bench_workers(&self, a: &BenchWorkersArgs) -> u8 {
        bench_workers(a)
    }
}

/// The ROS 2 domain: `--ros-domain`, else `$ROS_DOMAIN_ID` as ROS 2 reads it, else 0.
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
const RUN_WAIT: std::time::Duration = std::time::Duration::from_secs(10);

fn bridge(a: &BridgeArgs) -> u8 {
    use crate::{bridge, Endpoint};
    // The node's name, checked before anything starts.
    let ros_name = a.ros2.then(|| {
        ros_domain(a).and_then(|d| {
            evoloop_report::ros2::rmw_zenoh::NodeName::new(d, &a.ros_namespace, &a.ros_node)
                .map_err(|e| e.to_string())
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
                evoloop_report::print_json(&r);
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

/// `evoloop bench bridge`: a parameter set's round trip, local path against the bridge.
fn bench_bridge(a: &BridgeBenchArgs) -> u8 {
    use crate::bench::bridge as bench;
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
                evoloop_report::print_json(&r);
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

/// `evoloop bench workers`.
fn bench_workers(a: &BenchWorkersArgs) -> u8 {
    use crate::bench::workers::{run, Settings};
    if a.workers.is_empty() || a.workers.iter().any(|n| *n > 64) {
        err!("error: --workers: give 0 to 64 workers per phase, e.g. 0,1,2");
        return 2;
    }
    let s = Settings {
        workers: a.workers.clone(),
        population: a.population as usize,
        populations: a.populations as usize,
        threads: a.threads as usize,
        worker_threads: a.worker_threads as usize,
    };
    match run(&s, |line| err!("  {line}")) {
        Ok(r) => {
            if a.json {
                evoloop_report::print_json(&r);
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}

fn worker(a: &WorkerArgs) -> u8 {
    use crate::{workers, Endpoint};
    if let Some(p) = &a.zenoh_config {
        if !p.is_file() {
            err!("error: --zenoh-config {}: no such file", p.display());
            return 2;
        }
    }
    let threads = a
        .threads
        .map_or_else(evoloop_optim::all_cores, |t| t as usize);
    let id = workers::key_safe(&a.id.clone().unwrap_or_else(workers::default_id));
    let stop = evoloop_run::node::start::stop_flag();
    if let Some(n) = a.nice {
        if !evoloop_rt::privileges::set_nice(n) {
            err!("warning: evoloop worker: cannot set niceness {n}");
        }
    }
    if !a.quiet {
        err!(
            "evoloop worker {id}: {threads} thread(s), build {}, serving on {}",
            workers::build(),
            a.connect
        );
    }
    match workers::serve(
        &Endpoint::Connect(a.connect.clone()),
        a.zenoh_config.as_deref(),
        &id,
        threads,
        a.duration.map(std::time::Duration::from_secs_f64),
        &stop,
    ) {
        Ok(r) => {
            if a.json {
                evoloop_report::print_json(&r);
            } else if !a.quiet {
                err!(
                    "evoloop worker {id}: {} runs, {} evaluations, busy {:.2} s of {:.1} s{}",
                    r.batches,
                    r.evaluations,
                    r.busy_s,
                    r.wall_s,
                    if r.refused > 0 {
                        format!("; {} runs refused", r.refused)
                    } else {
                        String::new()
                    }
                );
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            1
        }
    }
}
