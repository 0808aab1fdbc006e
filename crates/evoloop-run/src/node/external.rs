//! The launcher's side of a plant that is the user's own process (`plant.kind = "external"`):
//! the variables that tell it how to join the run, starting it in its own process group (so a
//! stop reaches whatever it starts, and nothing it started outlives the run), and what the run
//! says while it waits for one the user starts.

use crate::config::Scenario;
use crate::plant::external::ExternalSpec;
use crate::rt::{RtGranted, RtRequest};
use std::path::Path;
use std::process::Child;

/// The launcher's name for the plant process of the user's own, in messages and the report.
pub const EXTERNAL: &str = "the plant process (plant.external)";

/// What a plant process reads to join the run (the book's plant contract, "A plant of your
/// own"), as (name, value) pairs.
pub fn environment(
    scn: &Scenario,
    config: &Path,
    run_id: &str,
    ipc_prefix: &str,
) -> Vec<(String, String)> {
    let root = crate::ipc::namespace::user_subdir("iceoryx2")
        .map(|p| format!("{}/", p.display()))
        .unwrap_or_default();
    let p = scn.build_plant();
    let samples = if scn.timing.until_stopped() {
        "forever".to_string()
    } else {
        scn.cycles().to_string()
    };
    [
        ("EVOLOOP_RUN_ID", run_id.to_string()),
        (
            "EVOLOOP_IPC_PREFIX",
            crate::ipc::namespace::user_prefix(ipc_prefix),
        ),
        ("EVOLOOP_IPC_ROOT", root),
        ("EVOLOOP_CONFIG", config.display().to_string()),
        // Absolute: the process runs in the scenario's directory, not the launcher's.
        (
            "EVOLOOP_OUT",
            std::path::absolute(&scn.output.dir)
                .unwrap_or(scn.output.dir.clone())
                .display()
                .to_string(),
        ),
        ("EVOLOOP_MODE", scn.timing.mode.to_string()),
        ("EVOLOOP_PERIOD", format!("{:?}", scn.timing.period)),
        ("EVOLOOP_SAMPLES", samples),
        ("EVOLOOP_SYNC_SAMPLES", scn.sync_samples().to_string()),
        ("EVOLOOP_SYNC_OFFSET", scn.sync_offset().to_string()),
        (
            "EVOLOOP_TIMEOUT",
            format!("{:?}", scn.timing.lockstep_timeout),
        ),
        ("EVOLOOP_SPIN_US", scn.timing.spin_us.to_string()),
        (
            "EVOLOOP_SAFE_COMMAND",
            format!("{:?}", scn.plant.safe_command),
        ),
        (
            "EVOLOOP_COMMAND_TIMEOUT_PERIODS",
            scn.plant.command_timeout_periods.to_string(),
        ),
        ("EVOLOOP_SEED", scn.seed.to_string()),
        ("EVOLOOP_STATES", p.n_states().to_string()),
        ("EVOLOOP_JOINTS", p.n_joints().to_string()),
        ("EVOLOOP_OUTPUTS", p.n_outputs().to_string()),
        ("EVOLOOP_INPUTS", p.n_inputs().to_string()),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect()
}

/// Start `command` with `env`, in the scenario's directory, in a process group of its own, with
/// SIGTERM when the launcher dies; in realtime, where evoloop's own plant would run
/// (`placement`: `timing.plant_cpu` and `timing.plant_fifo_priority`), set before the command
/// runs so that every thread it starts runs there too. `granted_to` says what it got.
pub fn spawn(
    e: &ExternalSpec,
    env: &[(String, String)],
    placement: &RtRequest,
) -> std::io::Result<Child> {
    use std::os::unix::process::CommandExt;
    let program = e.program.as_ref().expect("a command to spawn");
    let mut cmd = std::process::Command::new(program);
    cmd.args(&e.command[1..])
        .current_dir(&e.dir)
        .envs(env.iter().map(|(k, v)| (k, v)))
        .process_group(0);
    super::launcher::die_with_parent(&mut cmd);
    let (cpu, priority) = (placement.cpu, placement.fifo_priority);
    if placement.places() {
        // SAFETY: `place_self` makes syscalls only, which a child may between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                crate::rt::privileges::place_self(cpu, priority);
                Ok(())
            })
        };
    }
    cmd.spawn()
        .map_err(|err| std::io::Error::new(err.kind(), format!("{}: {err}", program.display())))
}

/// What the plant process `child` got of `placement`, in plant.json (which evoloop's own plant
/// writes at its end, and a plant of the user's own does not), so the run's report shows it as
/// it shows the controller's; and said, unless `quiet`.
pub fn report_placement(
    scn: &Scenario,
    child: &Child,
    placement: &RtRequest,
    quiet: bool,
) -> RtGranted {
    let got = crate::rt::privileges::granted_to(child.id() as i32, placement);
    let report = crate::run_report::summary::PlantReport {
        mode: scn.timing.mode,
        rt: got.clone(),
        ..Default::default()
    };
    if let Err(e) = crate::report::write_json(&scn.output.dir, "plant.json", &report) {
        eprintln!("evoloop: warning: cannot write plant.json: {e}");
    }
    if !quiet {
        let fifo = if got.sched_fifo {
            format!("SCHED_FIFO {}", got.priority)
        } else {
            "SCHED_OTHER".into()
        };
        let cpu = got.cpu.map_or("any CPU".into(), |c| format!("CPU {c}"));
        eprintln!("evoloop: {EXTERNAL} runs {fifo} on {cpu}");
        for n in &got.notes {
            eprintln!("evoloop: warning: {n}");
        }
    }
    got
}

/// `sig` to the plant process's whole group (it and what it started).
pub fn signal_group(child: &Child, sig: i32) {
    // SAFETY: plain syscall on the process group our own child leads.
    unsafe { libc::kill(-(child.id() as i32), sig) };
}

/// What the run waits for when the user starts the plant: the variables to start it with.
pub fn announce(e: &ExternalSpec, env: &[(String, String)]) {
    eprintln!(
        "evoloop: waiting up to {} s for the plant process: start it with these variables \
         (the book's plant contract, \"A plant of your own\"):",
        e.wait
    );
    for (k, v) in env {
        eprintln!("  export {k}='{}'", v.replace('\'', "'\\''"));
    }
}
