//! Runs across hosts over Zenoh (feature `zenoh`), on loopback: a bridge, a remote optimiser and
//! the run as separate processes. Without the feature the commands say what they need.

mod common;
use common::*;
#[cfg(feature = "zenoh")]
use std::path::{Path, PathBuf};
use std::process::Command;
#[cfg(feature = "zenoh")]
use std::process::{Child, Stdio};
#[cfg(feature = "zenoh")]
use std::time::{Duration, Instant};

/// A loopback endpoint on a free port.
#[cfg(feature = "zenoh")]
fn loopback() -> String {
    format!(
        "tcp/127.0.0.1:{}",
        evoloop::node::launcher::free_port().unwrap()
    )
}

#[cfg(feature = "zenoh")]
fn spawn(args: &[&str]) -> Child {
    Command::new(evoloop())
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start evoloop")
}

/// The run on the robot's host: `file` in realtime for `secs`, its own optimiser off.
#[cfg(feature = "zenoh")]
fn spawn_host_run(file: &str, secs: &str, run_id: &str, prefix: &str, out: &Path) -> Child {
    spawn(&[
        "run",
        file,
        "--mode",
        "realtime",
        "--no-rt",
        "--duration",
        secs,
        "--optimiser",
        "off",
        "--run-id",
        run_id,
        "--ipc-prefix",
        prefix,
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ])
}

/// The optimiser of `file` joining run `run_id` over `ep`, as from another host.
#[cfg(feature = "zenoh")]
fn spawn_remote_optimiser(file: &str, secs: &str, run_id: &str, out: &Path, ep: &str) -> Child {
    spawn(&[
        "optimiser",
        "--config",
        file,
        "--run-id",
        run_id,
        "--mode",
        "realtime",
        "--no-rt",
        "--duration",
        secs,
        "--out",
        out.to_str().unwrap(),
        "--connect",
        ep,
    ])
}

/// Wait for `c` (at most `limit`, else it is killed and the test fails), then its outputs.
#[cfg(feature = "zenoh")]
fn finish(mut c: Child, limit: Duration) -> std::process::Output {
    wait_exit(&mut c, limit);
    c.wait_with_output().unwrap()
}

/// Three processes on loopback: a realtime run of maglev_indirect for `secs` with its own
/// optimiser off, its bridge listening (with `bridge_args`), and a remote optimiser joining
/// through it with the indirect scheme. One realtime run at a time on a 2-core machine. A test
/// binds `_alone` and `_tmp` by name: left to `..`, they would go with the temporary at once,
/// the lock and the directory with them.
#[cfg(feature = "zenoh")]
struct RemoteTuning {
    _alone: std::sync::RwLockWriteGuard<'static, ()>,
    _tmp: tempfile::TempDir,
    /// The run's output directory, and the remote optimiser's.
    host: PathBuf,
    remote: PathBuf,
    run: Child,
    bridge: Child,
    optimiser: Child,
    run_id: String,
}

#[cfg(feature = "zenoh")]
fn remote_tuning(tag: &str, secs: &str, bridge_args: &[&str]) -> RemoteTuning {
    let alone = alone();
    let tmp = tempfile::tempdir().unwrap();
    let (prefix, run_id) = unique(tag);
    let ep = loopback();
    let (host, remote) = (tmp.path().join("host"), tmp.path().join("remote"));
    let file = config("maglev/maglev_indirect.toml");
    let file = file.to_str().unwrap();
    let run = spawn_host_run(file, secs, &run_id, &prefix, &host);
    let bridge = spawn(&[&["bridge", "--run", &run_id, "--listen", &ep], bridge_args].concat());
    let optimiser = spawn_remote_optimiser(file, secs, &run_id, &remote, &ep);
    RemoteTuning {
        _alone: alone,
        _tmp: tmp,
        host,
        remote,
        run,
        bridge,
        optimiser,
        run_id,
    }
}

/// A realtime run of the maglev's indirect scenario with its own optimiser off; the bridge
/// listens on loopback and an optimiser process joins over Zenoh with the indirect scheme. The
/// sets it publishes cross the network and the controller accepts them: the scheme runs with
/// its tuner on "another host". An operator on the run's host holds and resumes it: the commands
/// cross to the remote optimiser and its answers come back.
#[cfg(feature = "zenoh")]
#[test]
fn a_remote_optimiser_tunes_a_realtime_run_through_the_bridge() {
    let RemoteTuning {
        _alone,
        _tmp,
        host,
        remote,
        run,
        bridge,
        optimiser,
        run_id,
    } = remote_tuning("znet", "12", &["--json"]);
    let t0 = Instant::now();
    let mut answers = Vec::new();
    for (at, action) in [(7.0, "hold"), (7.5, "resume")] {
        std::thread::sleep(Duration::from_secs_f64(at).saturating_sub(t0.elapsed()));
        let o = cli(&[
            "operator",
            action,
            "--run",
            &run_id,
            "--json",
            "--timeout",
            "5",
        ]);
        assert!(
            o.status.code().is_some_and(|c| c <= 1),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
        answers
            .push(serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("JSON on stdout"));
    }
    assert!(
        answers.iter().all(|a| a["outcome"] == "done"),
        "{answers:?}"
    );
    let run = finish(run, Duration::from_secs(60));
    assert_ok(&run);
    let bridge = finish(bridge, Duration::from_secs(10));
    assert_ok(&bridge);
    let opt = finish(optimiser, Duration::from_secs(10));
    assert_ok(&opt);

    let b: serde_json::Value = serde_json::from_slice(&bridge.stdout).expect("bridge JSON");
    assert_eq!(b["ended"], "run ended");
    assert!(b["states"].as_u64().unwrap() >= 11_000, "{b}");
    assert!(b["params_in"].as_u64().unwrap() >= 1, "{b}");
    assert_eq!(b["refused"], 0);
    assert_eq!(
        (b["operator_out"].as_u64(), b["operator_acks_in"].as_u64()),
        (Some(2), Some(2)),
        "{b}"
    );

    let net = json(&remote.join("network.json"));
    let o = json(&remote.join("optimiser.json"));
    assert!(net["states_in"].as_u64().unwrap() >= 11_000, "{net}");
    assert_eq!(o["mode"], "indirect");
    let ops: Vec<&str> = o["operator"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["action"].as_str().unwrap())
        .collect();
    assert_eq!(ops, ["hold", "resume"], "{}", o["operator"]);
    let published = o["published_count"].as_u64().unwrap();
    assert!(published >= 1, "the remote optimiser published nothing");
    assert_eq!(net["params_out"].as_u64().unwrap(), published);

    // The remote optimiser's namespace is clean after it.
    let left = leftovers(evoloop::net::mirror::PREFIX);
    assert!(left.is_empty(), "{left:?}");

    // Every set the remote optimiser published reached the controller and passed its checks.
    let s = json(&host.join("summary.json"));
    let accepted = s["parameter_versions"]["accepted"]
        .as_array()
        .unwrap()
        .len() as u64;
    assert_eq!(accepted, published, "{}", s["parameter_versions"]);
    assert!(s["parameter_versions"]["rejected"]
        .as_array()
        .unwrap()
        .is_empty());
}

/// Losing the link is losing the remote optimiser, never the loop: the bridge is killed mid-run;
/// the remote optimiser, seeing no state, ends as it does when the plant goes silent (exit 3,
/// "no plant state"), and the run finishes normally on the sets it had accepted.
#[cfg(feature = "zenoh")]
#[test]
fn losing_the_link_ends_the_remote_optimiser_and_the_run_goes_on() {
    let RemoteTuning {
        _alone,
        _tmp,
        host,
        run,
        mut bridge,
        optimiser,
        ..
    } = remote_tuning("zlost", "12", &[]);
    std::thread::sleep(Duration::from_secs(5));
    bridge.kill().unwrap();
    let _ = bridge.wait();
    let killed = Instant::now();
    let opt = finish(optimiser, Duration::from_secs(30));
    let gone_after = killed.elapsed();
    assert_eq!(
        opt.status.code(),
        Some(3),
        "{}",
        String::from_utf8_lossy(&opt.stderr)
    );
    assert!(String::from_utf8_lossy(&opt.stderr).contains("no plant state"));
    assert!(gone_after < Duration::from_secs(15), "{gone_after:?}");
    // It left iceoryx2 cleanly on its way out (no launcher cleans up after a remote optimiser).
    let left = leftovers(evoloop::net::mirror::PREFIX);
    assert!(left.is_empty(), "{left:?}");
    let run = finish(run, Duration::from_secs(60));
    assert_ok(&run);
    let s = json(&host.join("summary.json"));
    assert_eq!(s["outcome"], "ok");
    // The loop ran to its end after the link went (at 5 s of the 12).
    assert!(s["ran_s"].as_f64().unwrap() >= 11.9, "{}", s["ran_s"]);
}

/// A set from the network goes through the controller's validation: a NaN gain is refused with
/// its index, a good set after it is taken.
#[cfg(feature = "zenoh")]
#[test]
fn a_parameter_set_from_the_network_is_validated_by_the_controller() {
    // One realtime run at a time on a 2-core machine.
    let _alone = alone();
    use evoloop::config::{Overrides, Scenario};
    use evoloop::ipc::Topic;
    use evoloop::msg::ParamSet;
    use evoloop::net::{key, open, wire, Endpoint};
    use zenoh::Wait;

    let tmp = tempfile::tempdir().unwrap();
    let (prefix, run_id) = unique("zval");
    let ep = loopback();
    let file = config("maglev/maglev.toml");
    let scn = Scenario::load(&file, &Overrides::default()).unwrap();
    let out = tmp.path().join("host");
    let run = spawn_host_run(file.to_str().unwrap(), "4", &run_id, &prefix, &out);
    let bridge = spawn(&["bridge", "--run", &run_id, "--listen", &ep]);
    let z = open(&Endpoint::Connect(ep.clone()), None).unwrap();
    // Wait for the run's states on the network: the bridge is up and relaying.
    let states = z
        .declare_subscriber(key(&run_id, Topic::State, false))
        .wait()
        .unwrap();
    let t0 = Instant::now();
    while states
        .recv_timeout(Duration::from_millis(100))
        .unwrap()
        .is_none()
    {
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "no state on the network"
        );
    }
    let params = z
        .declare_publisher(key(&run_id, Topic::Params, false))
        .wait()
        .unwrap();
    let good = scn.controller.tunable().gains.clone();
    let mut bad = good.clone();
    bad[1] = f64::NAN;
    let kind = scn.controller.param_kind();
    for (version, values) in [(1, &bad), (2, &good)] {
        let set = ParamSet::new(version, 0, kind, values);
        params.put(wire::encode(&set)).wait().unwrap();
        std::thread::sleep(Duration::from_millis(300));
    }
    assert_ok(&finish(run, Duration::from_secs(60)));
    assert_ok(&finish(bridge, Duration::from_secs(10)));
    let s = json(&out.join("summary.json"));
    let v = &s["parameter_versions"];
    let rejected = v["rejected"].as_array().unwrap();
    assert_eq!(rejected.len(), 1, "{v}");
    assert_eq!(rejected[0]["version"], 1);
    assert!(
        rejected[0]["outcome"].as_str().unwrap().contains("NaN"),
        "{v}"
    );
    assert_eq!(rejected[0]["index"], 1);
    let accepted = v["accepted"].as_array().unwrap();
    assert_eq!(accepted.len(), 1, "{v}");
    assert_eq!(accepted[0]["version"], 2);
}

/// A remote optimiser cannot pace a lockstep run: refused before it touches the network.
#[test]
fn a_remote_optimiser_refuses_a_lockstep_run() {
    let out = Command::new(evoloop())
        .args(["optimiser", "--config"])
        .arg(config("maglev/maglev_indirect.toml"))
        .args(["--run-id", "nolockstep", "--connect", "tcp/127.0.0.1:9"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    if cfg!(feature = "zenoh") {
        assert!(err.contains("realtime runs only"), "{err}");
    } else {
        assert!(err.contains("zenoh feature"), "{err}");
    }
}

/// Without the feature, the bridge says how to get it.
// Compiled in both builds, so the zenoh build's clippy lints it too (CI lints once, with the
// feature); run where the feature is off.
#[cfg_attr(feature = "zenoh", ignore = "this build has the zenoh feature")]
#[test]
fn without_the_zenoh_feature_the_bridge_says_how_to_build_it() {
    let out = Command::new(evoloop())
        .args(["bridge", "--listen", "tcp/127.0.0.1:7447"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--features zenoh"));
}

/// The shipped TLS and access-control examples are valid Zenoh configurations.
#[cfg(feature = "zenoh")]
#[test]
fn the_example_zenoh_configurations_load() {
    for f in ["tls_acl.json5", "tls_optimiser.json5"] {
        let p = config("zenoh").join(f);
        if let Err(e) = zenoh::Config::from_file(&p) {
            panic!("{}: {e}", p.display());
        }
    }
}

/// The network message format (formerly `net::wire`'s unit tests).
#[cfg(feature = "zenoh")]
mod wire {
    use evoloop::msg::{Command, ParamSet, PlantState};
    use evoloop::net::wire::{decode, encode, WireError};

    #[test]
    fn a_message_comes_back_bit_for_bit() {
        let mut s = PlantState {
            seq: 42,
            t: 0.125,
            n_x: 3,
            ..Default::default()
        };
        s.x_true[2] = -1.5e-300;
        s.y[7] = f64::NAN;
        let back: PlantState = decode(&encode(&s)).unwrap();
        assert_eq!(back.seq, 42);
        assert_eq!(back.x_true[2].to_bits(), s.x_true[2].to_bits());
        assert_eq!(back.y[7].to_bits(), s.y[7].to_bits());
        let p = ParamSet::new(
            7,
            0,
            evoloop::msg::ParamKind::ComputedTorque,
            &[1.0, f64::INFINITY],
        );
        let q: ParamSet = decode(&encode(&p)).unwrap();
        assert_eq!((q.version, q.n), (7, 2));
        assert_eq!(q.values()[1], f64::INFINITY);
    }

    #[test]
    fn another_type_or_a_cut_message_is_refused() {
        let bytes = encode(&Command::default());
        let e = decode::<PlantState>(&bytes).unwrap_err();
        assert!(
            matches!(&e, WireError::Type { theirs, .. } if theirs == "evoloop::Command.v1"),
            "{e:?}"
        );
        assert!(e.to_string().contains("evoloop::Command.v1"), "{e}");
        let cut = decode::<Command>(&bytes[..bytes.len() - 1]).unwrap_err();
        assert!(matches!(cut, WireError::Size { .. }), "{cut:?}");
        let hello = decode::<Command>(b"hello").unwrap_err();
        assert!(matches!(hello, WireError::NoHeader { .. }), "{hello:?}");
        let mut other = bytes.clone();
        other[0] = b'X';
        assert!(decode::<Command>(&other).is_err());
        assert!(decode::<Command>(&bytes).is_ok());
    }
}
