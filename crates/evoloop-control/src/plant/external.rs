//! A plant that is the user's own process, in any language, speaking the plant contract
//! (docs/src/plant-contract.md): a rig behind its driver, a simulator evoloop did not write.
//! The scenario declares what the process must send (its counts, names, units) and the
//! actuator's range; `command`, if given, is the process the launcher starts and supervises
//! (otherwise the run waits up to `wait` s for one the user starts). evoloop never simulates it:
//! the in-process loops (the frozen comparison, the in-process tuners) refuse it.

use super::{Plant, PlantConfig, PlantContext, ScalarInput};
use crate::check::{Check, ConfigError};
use crate::{MAX_JOINTS, MAX_STATES};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// The validated `[plant.external]`.
#[derive(Debug, Clone, Serialize)]
pub struct ExternalSpec {
    /// The counts every state must carry (`n_x`, `n_q`, `n_y`) and the command's (`n_u`).
    pub states: usize,
    /// Joints every state must carry (`n_q`; default: as many as outputs).
    pub joints: usize,
    /// Measured outputs every state must carry (`n_y`; default 1), one reference each.
    pub outputs: usize,
    /// Inputs the command has (`n_u`; default 1).
    pub inputs: usize,
    /// The outputs' names as declared, one per output (default `y0`, `y1`, ...).
    pub output_names: Vec<String>,
    /// The outputs' units as declared, one per output (default empty).
    pub output_units: Vec<String>,
    /// The inputs' names as declared, one per input (default `u0`, `u1`, ...).
    pub input_names: Vec<String>,
    /// The inputs' units as declared, one per input (default empty).
    pub input_units: Vec<String>,
    /// The actuator's range per input (the controller's output range).
    pub u_min: Vec<f64>,
    /// The upper end of each input's range, above its `u_min` (default unbounded).
    pub u_max: Vec<f64>,
    /// The plant process: program and arguments as written; empty: the user starts it.
    pub command: Vec<String>,
    /// The program to start, resolved when validated: a path with a `/` against the scenario's
    /// directory, a bare name found on PATH.
    pub program: Option<PathBuf>,
    /// Its working directory: the scenario's.
    pub dir: PathBuf,
    /// s the run waits for the plant's first state.
    pub wait: f64,
    /// An arm's nominal rigid-body model (`robot`, a D-H table or URDF): what a joint-space
    /// controller (computed torque) computes with. The plant process has its own.
    pub robot: Option<(PathBuf, crate::dynamics::Model)>,
}

/// An executable file (any execute bit set).
fn executable(p: &std::path::Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// `path` made absolute against the current directory, its links kept (a linked program runs
/// as the link names it). The launcher starts the plant in the scenario's directory, so a
/// path relative to the launcher's (`config/plants/m.py` of `config/m.toml`) would name
/// another file there: resolved once, here, for `evoloop check` and the run alike.
fn absolute(path: PathBuf) -> PathBuf {
    std::path::absolute(&path).unwrap_or(path)
}

/// `program` as the launcher will start it, absolute: a path with a `/` against the scenario's
/// directory, a bare name on PATH; an error that says which, if it is not an executable file.
fn resolve_program(check: &Check, program: &str) -> Result<PathBuf, ConfigError> {
    let key = "plant.external.command";
    if program.contains('/') {
        let path = absolute(check.resolve(program.as_ref()));
        if !executable(&path) {
            return check.fail(
                key,
                format!(
                    "{} is not an executable file (a program with a / is relative to the \
                     scenario; a script needs its execute bit, or name its interpreter first)",
                    path.display()
                ),
            );
        }
        return Ok(path);
    }
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| absolute(d.join(program)))
        .find(|p| executable(p))
        .map_or_else(
            || check.fail(key, format!("{program} is not on PATH")),
            Ok,
        )
}

/// Never called: evoloop does not simulate an external plant (the configuration keeps it out of
/// every in-process loop). Only its counts are read.
fn not_simulated() -> ! {
    unreachable!("an external plant is simulated by its own process, never in evoloop's")
}

impl Plant for ExternalSpec {
    fn n_states(&self) -> usize {
        self.states
    }
    fn n_inputs(&self) -> usize {
        self.inputs
    }
    fn n_outputs(&self) -> usize {
        self.outputs
    }
    fn n_joints(&self) -> usize {
        self.joints
    }
    fn derivative(&self, _t: f64, _x: &[f64], _u: &[f64], _dx: &mut [f64]) {
        not_simulated()
    }
    fn output(&self, _x: &[f64], _y: &mut [f64]) {
        not_simulated()
    }
    fn joints(&self, _x: &[f64], _q: &mut [f64], _qd: &mut [f64]) {
        not_simulated()
    }
    fn initial_state(&self, _x: &mut [f64]) {
        not_simulated()
    }
}

impl PlantConfig for ExternalSpec {
    fn build(&self) -> Box<dyn Plant> {
        Box::new(self.clone())
    }
    fn scalar_input(&self) -> Option<ScalarInput> {
        (self.inputs == 1 && self.outputs == 1).then(|| ScalarInput::holding_zero(self.u_min[0], self.u_max[0]))
    }
    fn external(&self) -> Option<&ExternalSpec> {
        Some(self)
    }
    fn rigid_body(&self) -> Option<&crate::dynamics::Model> {
        self.robot.as_ref().map(|r| &r.1)
    }
}

// ---------------------------------------------------------------- configuration

/// The `[plant.external]` keys.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    states: Option<usize>,
    joints: Option<usize>,
    outputs: Option<usize>,
    inputs: Option<usize>,
    output_names: Option<Vec<String>>,
    output_units: Option<Vec<String>>,
    input_names: Option<Vec<String>>,
    input_units: Option<Vec<String>>,
    u_min: Option<Vec<f64>>,
    u_max: Option<Vec<f64>>,
    command: Option<Vec<String>>,
    wait: Option<f64>,
    robot: Option<PathBuf>,
}

/// Names (or units) per channel: `n` of them, or `prefix0..` when absent.
fn labels(
    check: &Check,
    key: &str,
    given: Option<Vec<String>>,
    n: usize,
    default: impl Fn(usize) -> String,
) -> Result<Vec<String>, ConfigError> {
    let v = given.unwrap_or_else(|| (0..n).map(default).collect());
    if v.len() != n {
        return check.fail(key, format!("needs {n} entries (one per channel), got {}", v.len()));
    }
    Ok(v)
}

/// An arm's model for the controller: its joints must be the process's joints, outputs (the
/// joint angles) and inputs (torques), its state [q; qd].
fn arm_model(
    check: &Check,
    rel: &std::path::Path,
    [states, joints, outputs, inputs]: [usize; 4],
) -> Result<(PathBuf, crate::dynamics::Model), ConfigError> {
    let (path, model) = check.robot("plant.external.robot", rel)?;
    let n = model.dof();
    if [joints, outputs, inputs] != [n; 3] || states != 2 * n {
        return check.fail(
            "plant.external.robot",
            format!(
                "{} has {n} joints: the process must declare joints = outputs = inputs = {n} and \
                 states = {} ([q; qd]), not {joints}, {outputs}, {inputs} and {states}",
                path.display(),
                2 * n
            ),
        );
    }
    Ok((path, model))
}

/// Validate `[plant.external]`: the counts (`states` is required), the robot model if given (which
/// must match them), one reference per output, the input range, the names and units, the command
/// (its program found and executable) and the wait. Fails when the table or `states` is missing.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    cx: &PlantContext,
) -> Result<ExternalSpec, ConfigError> {
    let Some(t) = t else {
        return check.fail(
            "plant.external",
            "missing table [plant.external]: at least `states`, the length of the state the \
             process sends",
        );
    };
    let Some(states) = t.states else {
        return check.fail("plant.external.states", "missing: the length of x_true the process sends");
    };
    let states = check.count("plant.external.states", states, 1, MAX_STATES)?;
    let outputs = check.count("plant.external.outputs", t.outputs.unwrap_or(1), 1, MAX_JOINTS)?;
    let inputs = check.count("plant.external.inputs", t.inputs.unwrap_or(1), 1, MAX_JOINTS)?;
    let joints = check.count("plant.external.joints", t.joints.unwrap_or(outputs), 0, MAX_JOINTS)?;
    let robot = match &t.robot {
        Some(rel) => Some(arm_model(check, rel, [states, joints, outputs, inputs])?),
        None => None,
    };
    super::one_reference_per_output(check, cx.reference, outputs)?;
    let (u_min, u_max) = super::input_range(check, "plant.external", t.u_min, t.u_max, inputs)?;
    let command = t.command.unwrap_or_default();
    if command.first().is_some_and(|c| c.trim().is_empty()) {
        return check.fail("plant.external.command", "the program (its first entry) is empty");
    }
    let program = match command.first() {
        Some(p) => Some(resolve_program(check, p)?),
        None => None,
    };
    let dir = absolute(check.resolve(".".as_ref()));
    Ok(ExternalSpec {
        states,
        joints,
        outputs,
        inputs,
        output_names: labels(check, "plant.external.output_names", t.output_names, outputs, |i| format!("y{i}"))?,
        output_units: labels(check, "plant.external.output_units", t.output_units, outputs, |_| String::new())?,
        input_names: labels(check, "plant.external.input_names", t.input_names, inputs, |i| format!("u{i}"))?,
        input_units: labels(check, "plant.external.input_units", t.input_units, inputs, |_| String::new())?,
        u_min,
        u_max,
        command,
        program,
        dir,
        wait: check.range("plant.external.wait", t.wait.unwrap_or(60.0), 1.0, 3600.0)?,
        robot,
    })
}
