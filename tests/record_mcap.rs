//! run.mcap: every run records its topics for Foxglove and PlotJuggler as ROS 2 messages in CDR
//! with `ros2msg` schemas; read back with the `mcap` crate's reader, each topic carries the right
//! number of messages, log time is the sample's stamp, and the recorded commands are the run's
//! own, bit for bit. (tests/foxglove_decode.rs decodes them with Foxglove's own Python decoder.)

use crate::common;
use common::*;
use evoloop::report::ros2;
use std::collections::BTreeMap;

fn json(path: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn a_lockstep_run_records_every_topic_with_the_right_counts_and_stamps() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    // The indirect scheme: parameter sets and model estimates flow as well as the loop's topics.
    let o = run(
        std::path::Path::new("config/two_mass/two_mass_indirect.toml"),
        &out,
        "mcap",
        &["--duration", "12"],
    );
    assert_ok(&o);
    let ctrl = json(&out.join("controller.json"));
    let summary = json(&out.join("summary.json"));
    let cycles = ctrl["cycles"].as_u64().unwrap();
    let sets = summary["optimiser_published"].as_u64().unwrap();
    let m = &ctrl["check_model"];
    let estimates = ["adopted", "refused", "dropped"]
        .iter()
        .map(|k| m[k].as_u64().unwrap())
        .sum::<u64>();
    assert!(
        cycles == 12_000 && sets > 0 && estimates > 0,
        "{cycles} {sets} {estimates}"
    );

    let bytes = std::fs::read(out.join("run.mcap")).unwrap();
    let mut count: BTreeMap<String, u64> = BTreeMap::new();
    let mut states = Vec::new();
    let mut commands = Vec::new();
    for msg in mcap::MessageStream::new(&bytes).unwrap() {
        let msg = msg.unwrap();
        let ch = &msg.channel;
        assert_eq!(ch.message_encoding, "cdr");
        let schema = ch.schema.as_ref().expect("every channel has a schema");
        assert_eq!(schema.encoding, "ros2msg");
        *count.entry(ch.topic.clone()).or_default() += 1;
        match ch.topic.as_str() {
            "state" => {
                assert_eq!(schema.name, "evoloop_msgs/msg/PlantState");
                let s = ros2::decode_state(&msg.data).unwrap();
                assert_eq!(msg.log_time, s.stamp_ns);
                states.push(s.seq);
            }
            "command" => {
                assert_eq!(schema.name, "evoloop_msgs/msg/Command");
                let c = ros2::decode_command(&msg.data).unwrap();
                assert_eq!(msg.log_time, c.stamp_ns);
                commands.push(c.u[0]);
            }
            _ => {}
        }
    }
    let expect: BTreeMap<String, u64> = [
        ("state", cycles),
        ("command", cycles),
        ("telemetry", cycles),
        ("params", sets),
        ("estimate", estimates),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    assert_eq!(count, expect);
    // The summary section (what Foxglove reads first) agrees; `joint_states` is there, empty
    // (not an arm).
    let index = mcap::read::Summary::read(&bytes).unwrap().unwrap();
    let topics: Vec<&str> = index.channels.values().map(|c| c.topic.as_str()).collect();
    assert!(topics.contains(&"joint_states"), "{topics:?}");
    let stats = index.stats.unwrap();
    assert_eq!(stats.message_count, 3 * cycles + sets + estimates);
    assert_eq!(
        ctrl["mcap"]["messages"],
        serde_json::json!([cycles, cycles, cycles, sets, estimates, 0, 0])
    );
    assert_eq!(ctrl["mcap"]["dropped"], 0);
    // Every state once, in order; the commands are run.csv's u0, exactly.
    assert_eq!(states, (0..cycles).collect::<Vec<_>>());
    let csv = std::fs::read_to_string(out.join("run.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let u0 = header.iter().position(|h| *h == "u0").unwrap();
    let logged: Vec<f64> = lines
        .map(|l| l.split(',').nth(u0).unwrap().parse().unwrap())
        .collect();
    assert_eq!(logged.len() as u64, cycles);
    if let Some(i) = (0..commands.len()).find(|&i| commands[i].to_bits() != logged[i].to_bits()) {
        panic!(
            "first difference at {i}: {} vs {} (of {} / {})",
            commands[i],
            logged[i],
            commands.len(),
            logged.len()
        );
    }
}

#[test]
fn output_mcap_false_records_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write(
        tmp.path(),
        "s.toml",
        &scenario(
            "kind = \"step\"\namplitude = 1.0",
            "duration = 1.0\n[output]\nmcap = false",
        ),
    );
    let out = tmp.path().join("run");
    // A recording left by an earlier run into the same folder must not pass for this run's.
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("run.mcap"), "an earlier run's recording").unwrap();
    assert_ok(&run(&cfg, &out, "nomcap", &[]));
    assert!(out.join("run.csv").is_file());
    assert!(
        !out.join("run.mcap").exists(),
        "the stale run.mcap was kept"
    );
    assert!(json(&out.join("controller.json"))["mcap"].is_null());
}
