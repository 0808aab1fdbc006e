//! A ROS 2 node on rmw_zenoh's protocol, built on ros2-client's Zenoh backend (not on evoloop's
//! code): it finds evoloop's node on the ROS 2 graph, takes `joint_states`, sends sets of gains
//! on `set_gains` and reads the answers on `set_gains_result`. What it received is printed as
//! JSON lines (floats as their bits), for tests/ros2_bridge.rs to judge against run.csv.
//!
//!     ros2-peer --connect tcp/127.0.0.1:7447 [--namespace /evoloop] [--joint-states 300]
//!               [--set 1,2,3 ...] [--timeout 30]

use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, NodeName, NodeOptions, QosProfile,
};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::time::{Duration, Instant};

#[derive(Deserialize)]
struct Time {
    sec: i32,
    nanosec: u32,
}

#[derive(Deserialize)]
struct Header {
    stamp: Time,
    frame_id: String,
}

/// sensor_msgs/msg/JointState
#[derive(Deserialize)]
struct JointState {
    header: Header,
    name: Vec<String>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
}

/// std_msgs/msg/MultiArrayDimension, MultiArrayLayout, Float64MultiArray
#[derive(Serialize)]
struct MultiArrayDimension {
    label: String,
    size: u32,
    stride: u32,
}

#[derive(Serialize)]
struct MultiArrayLayout {
    dim: Vec<MultiArrayDimension>,
    data_offset: u32,
}

#[derive(Serialize)]
struct Float64MultiArray {
    layout: MultiArrayLayout,
    data: Vec<f64>,
}

/// rcl_interfaces/msg/SetParametersResult
#[derive(Deserialize)]
struct SetParametersResult {
    successful: bool,
    reason: String,
}

struct Args {
    connect: String,
    namespace: String,
    joint_states: usize,
    sets: Vec<Vec<f64>>,
    timeout: Duration,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        connect: String::new(),
        namespace: "/evoloop".into(),
        joint_states: 300,
        sets: Vec::new(),
        timeout: Duration::from_secs(30),
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--connect" => a.connect = value()?,
            "--namespace" => a.namespace = value()?,
            "--joint-states" => a.joint_states = value()?.parse().map_err(|e| format!("{e}"))?,
            "--timeout" => {
                a.timeout = Duration::from_secs_f64(value()?.parse().map_err(|e| format!("{e}"))?)
            }
            "--set" => a.sets.push(
                value()?
                    .split(',')
                    .map(|v| {
                        v.trim()
                            .parse::<f64>()
                            .map_err(|e| format!("--set {v}: {e}"))
                    })
                    .collect::<Result<_, _>>()?,
            ),
            other => return Err(format!("unknown argument {other}")),
        }
    }
    if a.connect.is_empty() {
        return Err("--connect ENDPOINT is required".into());
    }
    Ok(a)
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn main() {
    if let Err(e) = peer() {
        eprintln!("ros2-peer: {e}");
        std::process::exit(1);
    }
}

fn peer() -> Result<(), String> {
    let a = args()?;
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let mut cfg = zenoh::Config::default();
    for (key, value) in [
        ("mode", "\"peer\"".to_string()),
        ("scouting/multicast/enabled", "false".into()),
        ("connect/endpoints", format!("[\"{}\"]", a.connect)),
    ] {
        cfg.insert_json5(key, &value).map_err(|x| e(&x))?;
    }
    let ctx = Context::with_options(ContextOptions::new().zenoh_config(cfg)).map_err(|x| e(&x))?;
    let node = ctx
        .new_node(
            NodeName::new("/", "ros2_peer").map_err(|x| e(&x))?,
            NodeOptions::new(),
        )
        .map_err(|x| e(&x))?;
    let ns = a.namespace.as_str();
    let topic = |name: &str, pkg: &str, ty: &str| -> Result<ros2_client::Topic, String> {
        Ok(node.create_topic(
            &Name::new(ns, name).map_err(|x| e(&x))?,
            MessageTypeName::new(pkg, ty),
            &QosProfile::default(),
        ))
    };
    let joints = node
        .create_subscription::<JointState>(
            &topic("joint_states", "sensor_msgs", "JointState")?,
            None,
        )
        .map_err(|x| e(&x))?;
    let results = node
        .create_subscription::<SetParametersResult>(
            &topic("set_gains_result", "rcl_interfaces", "SetParametersResult")?,
            None,
        )
        .map_err(|x| e(&x))?;
    let sets = node
        .create_publisher::<Float64MultiArray>(
            &topic("set_gains", "std_msgs", "Float64MultiArray")?,
            None,
        )
        .map_err(|x| e(&x))?;
    let deadline = Instant::now() + a.timeout;
    let late = || Instant::now() > deadline;

    // evoloop's node on the graph, by its liveliness tokens as ros2-client reads them.
    let js_topic = format!("{}/joint_states", ns.trim_end_matches('/'));
    let set_topic = format!("{}/set_gains", ns.trim_end_matches('/'));
    while ctx.publisher_count(&js_topic) == 0 || ctx.subscription_count(&set_topic) == 0 {
        if late() {
            return Err(format!(
                "no publisher of {js_topic} or subscriber of {set_topic} appeared"
            ));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let graph = json!({"graph": {
        "nodes": ctx.node_names(),
        "joint_states_publishers": ctx.publisher_count(&js_topic),
        "set_gains_subscriptions": ctx.subscription_count(&set_topic),
    }});
    println!("{graph}");

    let mut got = 0;
    while got < a.joint_states {
        match joints.try_take() {
            Ok(Some((js, info))) => {
                got += 1;
                let line = json!({"joint_state": {
                    "sec": js.header.stamp.sec,
                    "nanosec": js.header.stamp.nanosec,
                    "frame_id": js.header.frame_id,
                    "name": js.name,
                    "position": bits(&js.position),
                    "velocity": bits(&js.velocity),
                    "effort": bits(&js.effort),
                    "seq": info.sequence_number(),
                }});
                println!("{line}");
            }
            Ok(None) => std::thread::sleep(Duration::from_micros(200)),
            Err(x) => return Err(format!("joint_states: {}", e(&x))),
        }
        if late() {
            return Err(format!(
                "{got} of {} joint states before the timeout",
                a.joint_states
            ));
        }
    }

    for values in &a.sets {
        let msg = Float64MultiArray {
            layout: MultiArrayLayout {
                dim: vec![MultiArrayDimension {
                    label: "gains".into(),
                    size: values.len() as u32,
                    stride: values.len() as u32,
                }],
                data_offset: 0,
            },
            data: values.clone(),
        };
        sets.publish(msg).map_err(|x| format!("set_gains: {x}"))?;
        loop {
            match results.try_take() {
                Ok(Some((r, _))) => {
                    let line = json!({"result": {"set": values, "successful": r.successful, "reason": r.reason}});
                    println!("{line}");
                    break;
                }
                Ok(None) => std::thread::sleep(Duration::from_millis(1)),
                Err(x) => return Err(format!("set_gains_result: {}", e(&x))),
            }
            if late() {
                return Err(format!("no answer to the set {values:?}"));
            }
        }
    }
    Ok(())
}
