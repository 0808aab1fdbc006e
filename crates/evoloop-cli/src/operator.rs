//! `evoloop operator ACTION [--version N] [--run RUN_ID]`: an operator's command to a running
//! run's tuner (hold, resume, revert, stop), answered by the optimiser on `operator_ack`, which
//! this prints (and records in optimiser.json `operator`). See `msg::OperatorAction`.

use evoloop_ipc::{Ipc, Topic, Wait};
use evoloop_msg::{OperatorAck, OperatorAction, OperatorCommand, OperatorOutcome};
use evoloop_run::run_watch::pick_run;
use std::time::{Duration, Instant};

/// Options of `evoloop operator`: the action, the version a revert puts back, the run, and how
/// long to wait for the optimiser's answer.
#[derive(clap::Args)]
pub struct OperatorArgs {
    /// hold (propose nothing new: the trial or epoch under way ends, the set in service
    /// stays), resume, revert (put an earlier set back in service and hold: --version, 0 = the
    /// set before tuning) or stop (end tuning; the set in service stays, the direct scheme's
    /// best found).
    #[arg(value_parser = parse_action)]
    pub action: OperatorAction,
    /// Revert: the version to put back [default: 0, the set in service before tuning].
    #[arg(long, default_value_t = 0)]
    pub version: u64,
    /// The run: its run id, as `evoloop run` prints it [default: the only running run].
    #[arg(long)]
    pub run: Option<String>,
    /// Seconds to wait for the optimiser's answer.
    #[arg(long, default_value_t = 5.0, value_parser = |s: &str| crate::args::seconds_in(s, 3600.0))]
    pub timeout: f64,
    /// Print the answer as JSON.
    #[arg(long)]
    pub json: bool,
}

fn parse_action(s: &str) -> Result<OperatorAction, String> {
    OperatorAction::ALL
        .iter()
        .copied()
        .find(|a| a.name() == s)
        .ok_or_else(|| format!("unknown action {s:?} (hold, resume, revert, stop)"))
}

/// 0: done; 1: refused (the reason printed); 2: no run, no answer, or an IPC failure.
pub fn main(a: &OperatorArgs) -> u8 {
    match send(a) {
        Ok(ack) => {
            let outcome = OperatorOutcome::try_from(ack.outcome);
            print(a, &ack, outcome);
            u8::from(outcome != Ok(OperatorOutcome::Done))
        }
        Err(e) => {
            err!("error: {e}");
            2
        }
    }
}

/// Send the command and wait for its answer.
pub fn send(a: &OperatorArgs) -> Result<OperatorAck, String> {
    let run = pick_run(a.run.as_deref()).map_err(|e| e.to_string())?;
    let io = |e: evoloop_ipc::IpcError| e.to_string();
    // Nothing of the run's is cleaned up from here.
    let ipc =
        Ipc::with_cleanup("evoloop-operator", &run.run_id, &run.ipc_prefix, false).map_err(io)?;
    let acks = ipc
        .subscriber::<OperatorAck>(Topic::OperatorAck, 4, false)
        .map_err(io)?;
    let commands = ipc
        .publisher::<OperatorCommand>(Topic::Operator, false)
        .map_err(io)?;
    if commands.subscribers() == 0 {
        return Err(format!(
            "run {} has no optimiser listening (optimiser.mode = \"off\", or it has not started)",
            run.run_id
        ));
    }
    // This process's id and the time: one number no other operator of this run sends.
    let id = (u64::from(std::process::id()) << 32) ^ evoloop_rt::clock::now_ns();
    let command = OperatorCommand {
        id,
        action: a.action.code(),
        _pad: 0,
        version: a.version,
    };
    commands.send(&command).map_err(io)?;
    let deadline = Instant::now() + Duration::from_secs_f64(a.timeout);
    while Instant::now() < deadline {
        if let Wait::Got(ack) = acks
            .wait_next(Duration::ZERO, Duration::from_millis(50))
            .map_err(io)?
        {
            if ack.id == id {
                return Ok(ack);
            }
        }
    }
    Err(format!(
        "no answer from run {}'s optimiser within {} s (in lockstep it answers at its next synchronisation point)",
        run.run_id, a.timeout
    ))
}

fn print(
    a: &OperatorArgs,
    ack: &OperatorAck,
    outcome: Result<OperatorOutcome, evoloop_msg::UnknownCode>,
) {
    let reason = outcome.map_or("unknown outcome code", |o| o.reason());
    if a.json {
        let v = serde_json::json!({
            "action": a.action,
            "outcome": outcome.ok(),
            "reason": reason,
            "t": ack.t,
            "version": ack.version,
        });
        println!("{v}");
    } else {
        println!("{}", describe(a.action, ack));
    }
}

/// An answer in one line, as `evoloop operator` prints it and top shows it.
pub fn describe(action: OperatorAction, ack: &OperatorAck) -> String {
    match OperatorOutcome::try_from(ack.outcome) {
        Ok(OperatorOutcome::Done) => format!(
            "{}: done at plant time {:.3} s (version {})",
            action.name(),
            ack.t,
            ack.version
        ),
        Ok(o) => format!("{}: refused: {}", action.name(), o.reason()),
        Err(_) => format!("{}: unknown outcome code {}", action.name(), ack.outcome),
    }
}
