//! Pieces every process binary shares: loading the scenario the launcher handed over, the exit
//! convention, and writing a JSON report into the run directory.

use super::args::ProcessArgs;
use crate::config::{ConfigError, Overrides, Scenario};
use crate::ipc::{Ipc, IpcError};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Once, OnceLock};

/// Exit code of a process whose peer stopped answering (lockstep timeout).
pub const EXIT_PEER_TIMEOUT: i32 = 3;
/// Exit code of a process that could not set itself up (config, IPC).
pub const EXIT_SETUP: i32 = 2;
/// Exit code of a plant whose state left any physical range (non-finite or beyond `DIVERGED`).
pub const EXIT_DIVERGED: i32 = 4;

/// Why a process (or a tool that drives one) ends early, with the exit code the launcher reads
/// for it. The message says what happened; `code` is the convention above.
#[derive(Debug, Clone, PartialEq)]
pub enum Failure {
    /// It could not set itself up or lost its transport (configuration, arguments, IPC).
    Setup(String),
    /// A peer stopped answering (a lockstep timeout).
    PeerTimeout(String),
    /// The plant's state left any physical range.
    Diverged(String),
    /// Anything else (the replay's controller under test failed): exit 1.
    Failed(String),
}

impl Failure {
    /// The process's exit code for it.
    pub fn code(&self) -> i32 {
        match self {
            Failure::Setup(_) => EXIT_SETUP,
            Failure::PeerTimeout(_) => EXIT_PEER_TIMEOUT,
            Failure::Diverged(_) => EXIT_DIVERGED,
            Failure::Failed(_) => 1,
        }
    }
}

impl std::fmt::Display for Failure {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (Failure::Setup(m)
        | Failure::PeerTimeout(m)
        | Failure::Diverged(m)
        | Failure::Failed(m)) = self;
        f.write_str(m)
    }
}

/// What every process starts with: its scenario, its stop flag (set by SIGINT/SIGTERM) and its
/// iceoryx2 node in the run.
pub struct Started {
    /// The scenario file, loaded with the launcher's overrides.
    pub scenario: Scenario,
    /// Raised by SIGINT, SIGTERM or SIGHUP (`stop_flag`): the loop ends and the process exits
    /// cleanly.
    pub stop: Arc<AtomicBool>,
    /// The process's iceoryx2 node in the run, named by `start`'s `who`.
    pub ipc: Ipc,
}

/// Load the scenario, install the signal flag, join the run; exit with a message on failure.
pub fn start(args: &ProcessArgs, who: &str) -> Started {
    set_thread_name(who);
    let scenario = load_scenario(args, who);
    let stop = stop_flag();
    let ipc = Ipc::new(who, &args.run_id, &args.ipc_prefix)
        .unwrap_or_else(|e| fail(who, Failure::Setup(e.to_string())));
    Started {
        scenario,
        stop,
        ipc,
    }
}

/// Build the process's ports, or exit with the IPC error.
pub fn ports<P>(who: &str, build: impl FnOnce() -> Result<P, IpcError>) -> P {
    build().unwrap_or_else(|e| fail(who, Failure::Setup(e.to_string())))
}

/// Load a scenario to run in this build: the loader's checks, then what this build cannot do.
/// In a binary without the network (`crate::network`), evaluation workers over Zenoh are refused
/// here, naming the key, rather than in the loader, which knows nothing of binaries.
pub fn load(path: &Path, ov: &Overrides) -> Result<Scenario, ConfigError> {
    let scn = Scenario::load(path, ov)?;
    if scn.optimiser.workers.is_some() {
        if let Err(e) = crate::network::required("\"zenoh\"") {
            return Err(ConfigError {
                file: path.to_path_buf(),
                key: "optimiser.workers".into(),
                reason: e.to_string(),
                line: None,
            });
        }
    }
    Ok(scn)
}

/// Load the scenario with the launcher's overrides, or exit with the config error.
pub fn load_scenario(args: &ProcessArgs, who: &str) -> Scenario {
    match load(&args.config, &args.overrides) {
        Ok(s) => s,
        Err(e) => fail(who, Failure::Setup(e.to_string())),
    }
}

/// Print `who: error: ...` to stderr and exit with the failure's code.
pub fn fail(who: &str, failure: Failure) -> ! {
    eprintln!("{who}: error: {failure}");
    std::process::exit(failure.code())
}

/// `fail`, after leaving iceoryx2 cleanly: `exit` skips destructors, so a process failing with its
/// ports and node alive left them for the launcher's (or the next run's) dead-node cleanup, and
/// a remote optimiser has no launcher to clean up after it.
pub fn leave_and_fail<P>(who: &str, ports: P, ipc: Ipc, failure: Failure) -> ! {
    drop(ports);
    drop(ipc);
    fail(who, failure)
}

/// Name the calling thread (the process's main thread: its `comm` in `ps`, `top` and
/// `/proc/PID/comm`, cut to 15 bytes by the kernel), so a role started as `evoloop plant` shows
/// as `evoloop-plant` like the stand-alone binary.
fn set_thread_name(name: &str) {
    let mut buf = [0u8; 16];
    let n = name.len().min(15);
    buf[..n].copy_from_slice(&name.as_bytes()[..n]);
    // SAFETY: PR_SET_NAME reads a NUL-terminated string of at most 16 bytes from `buf`.
    unsafe { libc::prctl(libc::PR_SET_NAME, buf.as_ptr() as libc::c_ulong, 0, 0, 0) };
}

/// The process's stop flag, raised by SIGINT, SIGTERM or SIGHUP; loops check it once per cycle
/// and exit cleanly, dropping their iceoryx2 ports so nothing is left in shared memory. The
/// signal handler raises it itself (an atomic store, async-signal-safe), so the flag is up by
/// the time the interrupted thread runs again: a handler thread (ctrlc's, before) could run
/// after the terminal's Ctrl-C had already killed a child, and the launcher called that death a
/// failure. One flag per process, the handler installed once, however often this is called.
pub fn stop_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    static INSTALL: Once = Once::new();
    extern "C" fn raise(_: libc::c_int) {
        if let Some(f) = FLAG.get() {
            f.store(true, Ordering::SeqCst);
        }
    }
    let flag = FLAG
        .get_or_init(|| Arc::new(AtomicBool::new(false)))
        .clone();
    INSTALL.call_once(|| {
        // SAFETY: a zeroed sigaction is valid; `raise` only loads an initialised OnceLock and
        // stores to an atomic. SA_RESTART: interrupted system calls resume, as they did.
        unsafe {
            let mut sa: libc::sigaction = std::mem::zeroed();
            sa.sa_sigaction = raise as extern "C" fn(libc::c_int) as libc::sighandler_t;
            sa.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut sa.sa_mask);
            for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
                libc::sigaction(sig, &sa, std::ptr::null_mut());
            }
        }
    });
    flag
}
