//! The controller's tunable values as one parameter a process outside the loop may set: the
//! live view's `gains` (`node::live`) and the ROS 2 bridge's `set_gains` (`net::ros2`).
//!
//! A set goes to the controller as any other: a `ParamSet` on the run's `params` topic,
//! version one above the newest the run has seen, checked by the controller's validation
//! (bounds, finiteness, stability where the law checks it). The answer is the controller's own,
//! read from its telemetry's parameter event. Only a run whose optimiser publishes nothing
//! (`optimiser.mode = "off"`) takes sets from outside: an optimiser numbers its own sets (a
//! schedule's i-th is version i, a tuner's the next after its last), and a set in between would
//! make its next one stale.

use crate::config::{OptimiserMode, Scenario};
use crate::ipc::{Ipc, IpcError, Pub, Topic};
use crate::msg::{ParamCode, ParamKind, ParamSet, Telemetry};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How long a set waits for the controller's answer.
pub const ANSWER: Duration = Duration::from_secs(3);

/// The controller's answer to a set, or its absence.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// The controller accepted the set: its values are in service.
    Accepted {
        /// The version the set was sent under.
        version: u64,
    },
    /// The controller refused the set (its validation's verdict); the values in service stay.
    Refused {
        /// The version the set was sent under.
        version: u64,
        /// Why: the controller's reason and the index of the offending value.
        reason: String,
    },
    /// No parameter event for the set within `ANSWER`.
    NoAnswer {
        /// The version the set was sent under.
        version: u64,
    },
}

impl std::fmt::Display for Answer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Answer::Accepted { version } => {
                write!(f, "version {version} accepted by the controller")
            }
            Answer::Refused { version, reason } => {
                write!(f, "version {version} refused by the controller: {reason}")
            }
            Answer::NoAnswer { version } => {
                write!(f, "version {version}: no answer from the controller")
            }
        }
    }
}

/// The values in service and the sets awaiting an answer; `R` is what the asker needs to get
/// its answer back (a viewer's request id and queue, nothing for a topic).
pub struct Gains<R> {
    /// Only where sets may be sent: no optimiser publishes (`mode` off).
    out: Option<Pub<ParamSet>>,
    /// The run's optimiser mode and who asks to set values (`what`), for a refusal's reason.
    mode: OptimiserMode,
    what: String,
    kind: ParamKind,
    /// The values in service (by the controller's telemetry), its version and the newest
    /// version seen; the values of the latest sets seen on the params topic, to know a
    /// version's values when the controller puts it in service.
    values: Vec<f64>,
    in_service: u64,
    newest: u64,
    seen: VecDeque<(u64, Vec<f64>)>,
    /// The controller's newest parameter event: (version, code, index).
    last_event: (u64, u32, u32),
    pending: Vec<Pending<R>>,
}

struct Pending<R> {
    version: u64,
    values: Vec<f64>,
    reply: R,
    since: Instant,
}

/// Why `Gains::set` sends no set.
#[derive(Debug)]
pub enum SetError {
    /// This run's optimiser (in this mode) numbers the parameter sets: `what` (the bridge
    /// that asked) may set them only when it publishes none.
    OptimiserPublishes {
        /// The run's `optimiser.mode`.
        mode: OptimiserMode,
        /// Who asked to set them, in the message.
        what: String,
    },
    /// The controller takes `takes` values; the set had `got`.
    Count {
        /// Values the controller's law takes.
        takes: usize,
        /// Values the set had.
        got: usize,
    },
    /// The params topic did not take the set.
    NotSent(IpcError),
}

impl std::fmt::Display for SetError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SetError::OptimiserPublishes { mode, what } => write!(
                f,
                "this run's optimiser (mode {mode:?}) numbers the parameter sets; {what} may be \
                 set when it publishes none (`--optimiser off`)"
            ),
            SetError::Count { takes, got } => {
                write!(f, "the controller takes {takes} values, not {got}")
            }
            SetError::NotSent(e) => write!(f, "not sent: {e}"),
        }
    }
}

impl std::error::Error for SetError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SetError::NotSent(e) => Some(e),
            _ => None,
        }
    }
}

impl<R> Gains<R> {
    /// For the run of scenario `scn`: its initial values, and a publisher on `params` where
    /// its optimiser publishes nothing.
    pub fn new(ipc: &Ipc, scn: &Scenario, what: &str) -> Result<Self, IpcError> {
        let cfg = scn.controller.model.config();
        let off = scn.optimiser.mode == OptimiserMode::Off;
        Ok(Self {
            out: if off {
                Some(ipc.publisher(Topic::Params, false)?)
            } else {
                None
            },
            mode: scn.optimiser.mode,
            what: what.to_string(),
            kind: cfg.param_kind(),
            values: cfg.tunable().gains.clone(),
            in_service: 0,
            newest: 0,
            seen: VecDeque::new(),
            last_event: (0, 0, 0),
            pending: Vec::new(),
        })
    }

    /// The values in service.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The version in service (0: the scenario's initial values).
    pub fn version(&self) -> u64 {
        self.in_service
    }

    /// A set seen on the run's params topic (anyone's).
    pub fn saw_set(&mut self, p: &ParamSet) {
        self.newest = self.newest.max(p.version);
        if self.seen.len() == 64 {
            self.seen.pop_front();
        }
        self.seen.push_back((p.version, p.values().to_vec()));
    }

    /// The controller's telemetry; the answer to a pending set its event shows, if any.
    pub fn saw_telemetry(&mut self, t: &Telemetry) -> Option<(R, Answer)> {
        self.newest = self.newest.max(t.param_version).max(t.param_event_version);
        if t.param_version != self.in_service {
            if let Some((_, v)) = self.seen.iter().rev().find(|(v, _)| *v == t.param_version) {
                self.values.clone_from(v);
            }
            self.in_service = t.param_version;
        }
        self.last_event = (t.param_event_version, t.param_code, t.param_index);
        self.answer()
    }

    fn answer(&mut self) -> Option<(R, Answer)> {
        let (version, code, index) = self.last_event;
        let at = self.pending.iter().position(|p| p.version == version)?;
        let p = self.pending.remove(at);
        let code = ParamCode::try_from(code).unwrap_or(ParamCode::None);
        let answer = if code == ParamCode::Accepted {
            self.values = p.values;
            self.in_service = version;
            Answer::Accepted { version }
        } else {
            Answer::Refused {
                version,
                // "refused by the controller: rejected: ..." says it twice.
                reason: format!(
                    "{} (value {index})",
                    code.reason().trim_start_matches("rejected: ")
                ),
            }
        };
        Some((p.reply, answer))
    }

    /// Send `values` to the controller; `reply` comes back with its answer. Refused here, with
    /// the reason, when sets may not be sent or the count is not the controller's.
    pub fn set(&mut self, values: Vec<f64>, reply: R) -> Result<u64, (R, SetError)> {
        let Some(out) = &self.out else {
            let (mode, what) = (self.mode, self.what.clone());
            return Err((reply, SetError::OptimiserPublishes { mode, what }));
        };
        if values.len() != self.values.len() {
            let (takes, got) = (self.values.len(), values.len());
            return Err((reply, SetError::Count { takes, got }));
        }
        let version = self.newest + 1;
        let set = ParamSet::new(version, 0, self.kind, &values);
        if let Err(e) = out.send(&set) {
            return Err((reply, SetError::NotSent(e)));
        }
        self.newest = version;
        self.pending.push(Pending {
            version,
            values,
            reply,
            since: Instant::now(),
        });
        Ok(version)
    }

    /// The sets that have waited `ANSWER` without one.
    pub fn expired(&mut self) -> Vec<(R, Answer)> {
        self.pending
            .extract_if(.., |p| p.since.elapsed() >= ANSWER)
            .map(|p| (p.reply, Answer::NoAnswer { version: p.version }))
            .collect()
    }
}
