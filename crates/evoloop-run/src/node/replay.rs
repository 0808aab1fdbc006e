//! `evoloop replay RUN.mcap`: a recorded run played into a controller over the run's iceoryx2
//! topics, in the plant's place.
//!
//! The replay starts a controller process of the recording's scenario (or of `--scenario FILE`,
//! to try another controller on the recorded plant data) in lockstep, then, for each recorded
//! cycle in order: the parameter sets and model estimates the live controller received in that
//! cycle (published just before, so the controller takes them in the same cycle), then the
//! recorded state; it waits for the controller's command on that state and compares it with the
//! recorded one. At the end an end-of-run state stops the controller, which writes its own
//! run.csv, controller.json and run.mcap in the output directory.
//!
//! A recording of a lockstep run replayed into its own scenario gives the live commands bit for
//! bit (tests/replay.rs). A realtime recording holds the states each cycle used (the latest
//! one, the same one twice when the plant was late); its commands match too unless a set or
//! estimate reached the live controller between samples in a way the recording does not pin.
//!
//! `--speed S` paces the states at S times real time by their own time t (1: as the plant ran,
//! also for a lockstep recording, whose stamps only say how fast the machine was), so a viewer
//! on the topics sees the run at its pace; without it the replay runs as fast as the controller
//! answers.

use crate::config::{Mode, Overrides, Scenario};
use crate::ipc::{Doorbell, Ipc, Pub, Spin, Sub, Topic, Waited};
use crate::msg::{Command, LinearEstimate, ModelEstimate, ParamSet, PlantState, STATE_FLAG_END};
use crate::node::launcher::{process_args, signal, spawn_process};
use crate::node::start::stop_flag;
use crate::node::start::Failure;
use crate::report::plot::{stacked_png, Panel, Series};
use crate::report::recording::{Received, Recording};
use crate::report::RunLog;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The options of `evoloop replay`: the recording, the controller's scenario, the pace and
/// where the results go.
#[derive(Debug, Clone)]
pub struct ReplayArgs {
    /// The recording: a run's run.mcap.
    pub file: PathBuf,
    /// The controller's scenario [default: the recording's own, named in its metadata]. Another
    /// file tries another controller (gains, law) on the recorded plant data.
    pub scenario: Option<PathBuf>,
    /// Play at this multiple of real time, by the states' own time t (1: a 10 s run takes 10 s,
    /// lockstep recordings too) [default: as fast as the controller answers].
    pub speed: Option<f64>,
    /// Output directory: replay.json, replay.csv, replay.png and the controller's own files
    /// [default: replay/ beside the recording].
    pub out: Option<PathBuf>,
    /// Run id of the replay's services (default: generated, unique on this machine).
    pub run_id: Option<String>,
    /// Prefix of iceoryx2's files.
    pub ipc_prefix: String,
    /// Print replay.json on stdout.
    pub json: bool,
    /// No progress lines.
    pub quiet: bool,
}

/// The first cycle whose replayed command differs from the recorded one.
#[derive(Debug, Serialize)]
pub struct Mismatch {
    /// The cycle's place among the recorded states, from 0.
    pub cycle: usize,
    /// The sequence number of the recorded state both commands answer.
    pub state_seq: u64,
    /// The state's time, s.
    pub t: f64,
    /// The recorded command, one value per plant input.
    pub recorded: Vec<f64>,
    /// The replayed controller's command, one value per plant input.
    pub replayed: Vec<f64>,
}

/// replay.json.
#[derive(Debug, Serialize)]
pub struct ReplayReport {
    /// The recording played (the path given).
    pub recording: String,
    /// The controller's scenario file: `--scenario`'s, else the recording's own.
    pub scenario: String,
    /// `--speed`: the multiple of real time played at; `None`: as fast as the controller answered.
    pub speed: Option<f64>,
    /// States the controller answered (all the recorded ones unless the replay was stopped).
    pub states: usize,
    /// Recorded parameter sets sent to the controller.
    pub params_sent: usize,
    /// Recorded model estimates (the changing parameter's value) sent to the controller.
    pub estimates_sent: usize,
    /// Estimated transfer functions (the general indirect scheme) sent to the controller.
    pub linear_estimates_sent: usize,
    /// Cycles whose recorded command exists to compare with.
    pub commands_compared: usize,
    /// Of those, replayed commands equal to the recorded ones bit for bit.
    pub commands_equal: usize,
    /// The largest |replayed - recorded| over the compared commands' inputs; NaN if any is NaN.
    pub max_abs_diff: f64,
    /// The first cycle whose commands differ; `None` when all compared ones are equal.
    pub first_mismatch: Option<Mismatch>,
    /// Wall-clock time of the play, s.
    pub wall_s: f64,
}

struct Ports {
    ready: Doorbell,
    state: Pub<PlantState>,
    params: Pub<ParamSet>,
    estimate: Pub<ModelEstimate>,
    linear: Pub<LinearEstimate>,
    command: Sub<Command>,
}

/// `evoloop replay`: exit code 0 when the recording was played through (whether or not the
/// commands agree: replay.json says), 2 for a bad recording or scenario, 1 when the controller
/// failed.
pub fn main(a: &ReplayArgs) -> i32 {
    match replay(a) {
        Ok(r) => {
            if a.json {
                crate::report::print_json(&r);
            } else if !a.quiet {
                err!(
                    "replayed {} states of {} into the controller of {}: commands equal on {} of {} \
                     (max |du| {:e}), {:.2} s",
                    r.states,
                    r.recording,
                    r.scenario,
                    r.commands_equal,
                    r.commands_compared,
                    r.max_abs_diff,
                    r.wall_s
                );
            }
            0
        }
        Err(e) => {
            err!("error: {e}");
            e.code()
        }
    }
}

fn replay(a: &ReplayArgs) -> Result<ReplayReport, Failure> {
    let rec = Recording::read(&a.file).map_err(|e| Failure::Setup(e.to_string()))?;
    if rec.states.is_empty() {
        return Err(Failure::Setup(format!(
            "{}: no states recorded",
            a.file.display()
        )));
    }
    let config = match &a.scenario {
        Some(f) => f.clone(),
        None => PathBuf::from(rec.meta("config").unwrap_or_default()),
    };
    if !config.is_file() {
        return Err(Failure::Setup(format!(
            "{}: the recording's scenario {} is not here; name one with --scenario FILE",
            a.file.display(),
            config.display()
        )));
    }
    let seed = match rec.meta("seed").map(str::parse::<u64>) {
        Some(Ok(s)) => Some(s),
        _ => None,
    };
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| a.file.parent().unwrap_or(Path::new(".")).join("replay"));
    let ov = Overrides {
        mode: Some(Mode::Lockstep),
        seed,
        out: Some(out.clone()),
        ..Default::default()
    };
    let scn = Scenario::load(&config, &ov).map_err(|e| Failure::Setup(e.to_string()))?;
    let n_u = scn.build_plant().n_inputs();
    if let Some(c) = rec.commands.first() {
        if c.n_u as usize != n_u {
            return Err(Failure::Setup(format!(
                "{} has {n_u} inputs, the recording's commands {}: not the same plant",
                config.display(),
                c.n_u
            )));
        }
    }
    std::fs::create_dir_all(&out).map_err(|e| Failure::Setup(format!("{}: {e}", out.display())))?;
    for f in ["replay.json", "replay.csv", "replay.png"] {
        let _ = std::fs::remove_file(out.join(f));
    }

    let run_id = a.run_id.clone().unwrap_or_else(|| {
        format!(
            "replay-{}-{:x}",
            std::process::id(),
            crate::rt::now_ns() & 0xffff_ffff
        )
    });
    let stop = stop_flag();
    let io = |e: crate::ipc::IpcError| Failure::Failed(e.to_string());
    let ipc = Ipc::new("evoloop-replay", &run_id, &a.ipc_prefix).map_err(io)?;
    let ports = Ports {
        ready: ipc.doorbell(Topic::Ready).map_err(io)?,
        command: ipc.subscriber(Topic::Command, 8, true).map_err(io)?,
        params: ipc.publisher(Topic::Params, false).map_err(io)?,
        estimate: ipc.publisher(Topic::Estimate, false).map_err(io)?,
        linear: ipc.publisher(Topic::LinearEstimate, false).map_err(io)?,
        state: ipc.publisher(Topic::State, true).map_err(io)?,
    };
    let config_abs = std::fs::canonicalize(&config).unwrap_or(config.clone());
    let mut args = process_args(&config_abs, &run_id, &a.ipc_prefix);
    args.extend([
        "--mode".into(),
        "lockstep".into(),
        "--out".into(),
        out.display().to_string(),
    ]);
    if let Some(s) = seed {
        args.extend(["--seed".into(), s.to_string()]);
    }
    let mut child = spawn_process("evoloop-controller", &args)
        .map_err(|e| Failure::Failed(format!("cannot start the controller: {e}")))?;
    let result = play(a, &scn, n_u, &rec, &ports, &mut child, &stop);
    // However the play ended, the controller is told the run is over and waited for.
    let end = PlantState {
        seq: rec.states.last().map_or(0, |s| s.seq + 1),
        flags: STATE_FLAG_END,
        ..Default::default()
    };
    let _ = ports.state.send(&end);
    let t0 = Instant::now();
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break Some(s),
            Ok(None) if t0.elapsed() < Duration::from_secs(30) => {
                std::thread::sleep(Duration::from_millis(5))
            }
            _ => {
                signal(&child, libc::SIGTERM);
                break child.wait().ok();
            }
        }
    };
    let (report, rows) = result?;
    if !status.is_some_and(|s| s.success()) {
        return Err(Failure::Failed(format!(
            "the controller exited with {status:?}"
        )));
    }
    write_outputs(&out, &report, &rows, n_u).map_err(Failure::Failed)?;
    Ok(report)
}

/// Plays the recording's `n_u`-input commands through; the comparison's rows are t, state seq,
/// the recorded u (NaN where the recording has no command), the replayed u.
fn play(
    a: &ReplayArgs,
    scn: &Scenario,
    n_u: usize,
    rec: &Recording,
    ports: &Ports,
    child: &mut Child,
    stop: &AtomicBool,
) -> Result<(ReplayReport, RunLog), Failure> {
    let io = |e: crate::ipc::IpcError| Failure::Failed(e.to_string());
    // The controller is there once it has subscribed to the states and publishes commands.
    let t0 = Instant::now();
    while ports.state.subscribers() < 1 || ports.command.publishers() < 1 {
        if let Ok(Some(s)) = child.try_wait() {
            return Err(Failure::Failed(format!(
                "the controller exited with {s} before the replay"
            )));
        }
        if stop.load(Ordering::SeqCst) || t0.elapsed() > Duration::from_secs(20) {
            return Err(Failure::Failed(
                "the controller did not connect within 20 s".into(),
            ));
        }
        ports.ready.wait(Duration::from_millis(100)).map_err(io)?;
    }
    let mut spin = Spin::new(Duration::from_micros(scn.timing.spin_us));
    let timeout = Duration::from_secs_f64(scn.timing.start_timeout());
    let t_first = rec.states[0].t;
    let progress =
        crate::report::progress::bar(rec.states.len() as u64, "replay", a.quiet || a.json);
    let (mut pi, mut ei, mut li) = (0, 0, 0);
    let mut header = vec!["t".to_string(), "state_seq".to_string()];
    header.extend((0..n_u).map(|i| format!("u{i}_recorded")));
    header.extend((0..n_u).map(|i| format!("u{i}_replayed")));
    let mut rows = RunLog::new(header, rec.states.len());
    let mut row = vec![0.0; 2 + 2 * n_u];
    let mut report = ReplayReport {
        recording: a.file.display().to_string(),
        scenario: a.scenario.as_ref().map_or_else(
            || scn.source.display().to_string(),
            |p| p.display().to_string(),
        ),
        speed: a.speed,
        states: 0,
        params_sent: 0,
        estimates_sent: 0,
        linear_estimates_sent: 0,
        commands_compared: 0,
        commands_equal: 0,
        max_abs_diff: 0.0,
        first_mismatch: None,
        wall_s: 0.0,
    };
    let start = Instant::now();
    for (i, state) in rec.states.iter().enumerate() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        if let Some(speed) = a.speed {
            let at = Duration::from_secs_f64(((state.t - t_first) / speed).max(0.0));
            if let Some(wait) = at.checked_sub(start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
        // What the live controller received in this cycle, before the state that starts it: by
        // the cycle's number where the recording has it (a state two cycles used has one stamp),
        // else by the state's stamp.
        let cycle = rec.commands.get(i).map(|c| c.cycle);
        let due = |r: &Received| match (r.cycle, cycle) {
            (Some(c), Some(now)) => c <= now,
            _ => r.stamp_ns <= state.stamp_ns,
        };
        while let Some((_, p)) = rec.params.get(pi).filter(|(r, _)| due(r)) {
            ports.params.send(p).map_err(io)?;
            pi += 1;
        }
        while let Some((_, e)) = rec.estimates.get(ei).filter(|(r, _)| due(r)) {
            ports.estimate.send(e).map_err(io)?;
            ei += 1;
        }
        while let Some((_, e)) = rec.linear_estimates.get(li).filter(|(r, _)| due(r)) {
            ports.linear.send(e).map_err(io)?;
            li += 1;
        }
        ports.state.send(state).map_err(io)?;
        let cmd = match ports
            .command
            .wait_for(&mut spin, timeout, stop, |c: &Command| {
                c.state_seq == state.seq
            })
            .map_err(io)?
        {
            Waited::Got(c) => c,
            Waited::Stopped => break,
            Waited::TimedOut => {
                return Err(Failure::Failed(format!(
                    "the controller did not answer state {} within {timeout:?}",
                    state.seq
                )))
            }
        };
        report.states += 1;
        let replayed = cmd.u[..n_u].to_vec();
        let recorded = rec.commands.get(i).map(|c| c.u[..n_u].to_vec());
        if let Some(recorded) = &recorded {
            report.commands_compared += 1;
            let equal = recorded
                .iter()
                .zip(&replayed)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            if equal {
                report.commands_equal += 1;
            } else if report.first_mismatch.is_none() {
                report.first_mismatch = Some(Mismatch {
                    cycle: i,
                    state_seq: state.seq,
                    t: state.t,
                    recorded: recorded.clone(),
                    replayed: replayed.clone(),
                });
            }
            for (a, b) in recorded.iter().zip(&replayed) {
                let d = (a - b).abs();
                if d > report.max_abs_diff || d.is_nan() {
                    report.max_abs_diff = d;
                }
            }
        }
        row[0] = state.t;
        row[1] = state.seq as f64;
        let (rec_u, rep_u) = row[2..].split_at_mut(n_u);
        match &recorded {
            Some(u) => rec_u.copy_from_slice(u),
            None => rec_u.fill(f64::NAN),
        }
        rep_u.copy_from_slice(&replayed);
        rows.push(&row);
        progress.inc(1);
    }
    progress.finish_and_clear();
    report.params_sent = pi;
    report.estimates_sent = ei;
    report.linear_estimates_sent = li;
    report.wall_s = start.elapsed().as_secs_f64();
    Ok((report, rows))
}

/// replay.json, replay.csv (t, seq, recorded and replayed command) and replay.png (both
/// commands over time, and their difference).
fn write_outputs(out: &Path, r: &ReplayReport, rows: &RunLog, n_u: usize) -> Result<(), String> {
    crate::report::write_json(out, "replay.json", r).map_err(|e| e.to_string())?;
    let path = out.join("replay.csv");
    rows.write_csv(&path)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let col = |j: usize| {
        (0..rows.len())
            .map(|i| rows.row(i)[j])
            .collect::<Vec<f64>>()
    };
    let (t, recorded, replayed) = (col(0), col(2), col(2 + n_u));
    let diff: Vec<f64> = replayed.iter().zip(&recorded).map(|(a, b)| a - b).collect();
    let title = format!(
        "replay: commands equal on {} of {} cycles (max |du| {:e})",
        r.commands_equal, r.commands_compared, r.max_abs_diff
    );
    stacked_png(
        &out.join("replay.png"),
        &title,
        &t,
        &[
            Panel {
                series: &[
                    Series {
                        name: "u0 recorded",
                        values: &recorded,
                    },
                    Series {
                        name: "u0 replayed",
                        values: &replayed,
                    },
                ],
                label: "command u0",
            },
            Panel {
                series: &[Series {
                    name: "replayed - recorded",
                    values: &diff,
                }],
                label: "difference",
            },
        ],
        &[],
    )
    .map_err(|e| e.to_string())
}
