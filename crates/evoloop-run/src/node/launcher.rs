//! The launcher: `evoloop run` starts the plant, controller and optimiser processes with one
//! scenario file, supervises them, stops them all on Ctrl-C/SIGTERM or when the scenario ends,
//! and writes the run report (run.csv, summary.json, response.png); `--seeds` repeats that per
//! seed and writes the study.

use super::args::{override_args, RunArgs};
use super::external::EXTERNAL;
use super::start::stop_flag;
use crate::config::{Mode, Scenario};
use crate::ipc::{Ipc, Topic};
use crate::msg::Telemetry;
use crate::plant::external::ExternalSpec;
use crate::report::Outcome;
use crate::rt::clock::wait_loop_lateness;
use crate::rt::timing::Percentiles;
use crate::rt::WaitStrategy;
use crate::rt::{apply_privileges, RtRequest};
use crate::run_report::build::build_report;
use crate::run_report::summary::{FloorReport, OptimiserLife, Summary};
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitCode};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

const DEFAULT_SCENARIO: &str = "config/two_mass/two_mass.toml";

/// The default scenario, relative to the working directory or to the source tree.
pub fn default_scenario() -> PathBuf {
    shipped(DEFAULT_SCENARIO)
}

/// A file shipped with evoloop (`config/...`), relative to the working directory when it is
/// there, else in the source tree.
pub fn shipped(relative: &str) -> PathBuf {
    let p = PathBuf::from(relative);
    if p.exists() {
        return p;
    }
    source_tree().join(relative)
}

/// The source tree evoloop was built from (this crate lives in its `crates/evoloop-run`).
fn source_tree() -> &'static Path {
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    manifest.ancestors().nth(2).unwrap_or(manifest)
}

/// The bare absolute-deadline loop, in its own thread with the given priority and CPU, waiting
/// as the controller does (`wait`), so the controller's lateness is judged against the same
/// strategy's floor.
pub fn measure_floor(
    period: f64,
    duration: f64,
    fifo: Option<i32>,
    cpu: Option<usize>,
    wait: WaitStrategy,
) -> FloorReport {
    let period_ns = (period * 1e9).round() as u64;
    let cycles = (duration / period).round().max(1.0) as usize;
    std::thread::spawn(move || {
        let rt = apply_privileges(&crate::rt::RtRequest {
            fifo_priority: fifo,
            lock_memory: false,
            cpu,
            wait: wait.kind,
        });
        let late = wait_loop_lateness(period_ns, cycles, wait);
        let lost_periods = late
            .iter()
            .map(|l| (l.max(&0) / period_ns as i64) as u64)
            .sum();
        FloorReport {
            period_s: period,
            rt,
            wait,
            lost_periods,
            lateness: Percentiles::from_samples(late),
            ..Default::default()
        }
    })
    .join()
    .unwrap_or_default()
}

/// Helper processes on this host: evaluation workers (`evoloop worker`: `--workers N` of `run`
/// and `tune`, and `bench workers`) and a run's live view (`evoloop live`, `run --live`). They
/// serve until this is dropped (SIGTERM, then waited for), and die with the process that
/// started them.
#[derive(Default)]
pub struct LocalWorkers(Vec<Child>);

impl LocalWorkers {
    /// `n` workers of `threads` threads at niceness `nice`, connecting to `ep`, named
    /// `<name>-w<i>`.
    pub fn start(
        ep: &str,
        n: usize,
        threads: usize,
        nice: i32,
        name: &str,
    ) -> Result<Self, LocalWorkersError> {
        let mut w = LocalWorkers::default();
        for i in 0..n {
            let args: Vec<String> = [
                "--connect",
                ep,
                "--threads",
                &threads.to_string(),
                "--id",
                &format!("{name}-w{i}"),
                "--nice",
                &nice.to_string(),
                "--quiet",
            ]
            .map(String::from)
            .to_vec();
            let c = spawn_process("evoloop-worker", &args).map_err(LocalWorkersError::Spawn)?;
            w.0.push(c);
        }
        Ok(w)
    }
}

impl Drop for LocalWorkers {
    fn drop(&mut self) {
        for c in &mut self.0 {
            signal(c, libc::SIGTERM);
            let _ = c.wait();
        }
    }
}

/// Why evaluation workers on this host could not be had.
#[derive(Debug)]
pub enum LocalWorkersError {
    /// The kernel gave no free TCP port on 127.0.0.1.
    NoPort(std::io::Error),
    /// An `evoloop-worker` process could not be started.
    Spawn(std::io::Error),
}

impl std::fmt::Display for LocalWorkersError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LocalWorkersError::NoPort(e) => write!(f, "no free port on 127.0.0.1: {e}"),
            LocalWorkersError::Spawn(e) => write!(f, "cannot start evoloop-worker: {e}"),
        }
    }
}

impl std::error::Error for LocalWorkersError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LocalWorkersError::NoPort(e) | LocalWorkersError::Spawn(e) => Some(e),
        }
    }
}

/// A Zenoh endpoint on a free loopback port, for `--workers N`.
pub fn local_workers_endpoint() -> Result<String, LocalWorkersError> {
    Ok(format!("tcp/127.0.0.1:{}", free_port()?))
}

/// A TCP port free on 127.0.0.1 now (the kernel's pick; free until someone else binds it).
pub fn free_port() -> Result<u16, LocalWorkersError> {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .map_err(LocalWorkersError::NoPort)
}

/// The options every process of a run takes (`ProcessArgs`), before the overrides.
pub(crate) fn process_args(config: &Path, run_id: &str, ipc_prefix: &str) -> Vec<String> {
    vec![
        "--config".to_string(),
        config.display().to_string(),
        "--run-id".into(),
        run_id.into(),
        "--ipc-prefix".into(),
        ipc_prefix.into(),
    ]
}

/// Start the process `name` (`evoloop-plant`, ...) of a run: this very executable with the role as
/// its subcommand, so a run needs nothing but the `evoloop` binary (`cargo run` builds only the
/// binary it runs). argv[0] is the process's name, so `ps`, `pgrep -f evoloop-plant` and the
/// tests see `evoloop-plant ...` as they would the stand-alone binary.
pub(crate) fn spawn_process(name: &str, args: &[String]) -> std::io::Result<Child> {
    use std::os::unix::process::CommandExt;
    let role = name.trim_start_matches("evoloop-");
    let mut cmd = std::process::Command::new(std::env::current_exe()?);
    cmd.arg0(name).arg(role).args(args);
    die_with_parent(&mut cmd);
    cmd.spawn()
}

/// Make this process the reaper of its descendants: what a child started and left (a plant
/// script's helper that called setsid, leaving the group the launcher stops) becomes the
/// launcher's own child when its parent ends, not init's, so `reap_orphans` can stop it.
fn adopt_orphans() {
    // SAFETY: prctl with an integer argument; no memory is passed.
    unsafe { libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) };
}

/// Stop and reap every child this process has left once the run's own have ended: the
/// descendants `adopt_orphans` gave it (their children in turn come to it as each ends). Each
/// gets SIGTERM and a second to end (a helper driving hardware may need to make it safe), then
/// SIGKILL; one that does not end even then (stuck in the kernel) is left, never waited on
/// without end. Returns how many it stopped.
fn reap_orphans() -> usize {
    let me = std::process::id();
    let mut tried: Vec<u32> = Vec::new();
    // Bounded: each round reaps a generation.
    for _ in 0..64 {
        let children: Vec<u32> = children_of(me)
            .into_iter()
            .filter(|p| !tried.contains(p))
            .collect();
        if children.is_empty() {
            break;
        }
        let left = end_within(&children, libc::SIGTERM);
        end_within(&left, libc::SIGKILL);
        tried.extend(children);
    }
    tried.len()
}

/// Send `sig` to each of `pids` (children of this process) and reap those that end within a
/// second; the ones still running.
fn end_within(pids: &[u32], sig: i32) -> Vec<u32> {
    let mut left = pids.to_vec();
    // SAFETY: plain syscalls on children of this process: a child's pid is not reused until
    // it is reaped, so the signal cannot reach another process.
    unsafe {
        for &pid in &left {
            libc::kill(pid as i32, sig);
        }
        let until = Instant::now() + Duration::from_secs(1);
        while !left.is_empty() && Instant::now() < until {
            left.retain(|&pid| libc::waitpid(pid as i32, std::ptr::null_mut(), libc::WNOHANG) == 0);
            std::thread::sleep(Duration::from_millis(10));
        }
    }
    left
}

/// The pids whose parent is `parent`, from /proc.
fn children_of(parent: u32) -> Vec<u32> {
    let Ok(rd) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    rd.flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            // The parent is the 2nd field after the command, which ends at the last ')'.
            let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
            let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
            after.split_whitespace().nth(1) == Some(parent.to_string().as_str())
        })
        .collect()
}

/// The descriptor of `listener`, left open across the next exec (Rust opens everything
/// close-on-exec): the live view serves on the port the launcher bound.
fn inheritable(listener: &std::net::TcpListener) -> i32 {
    let fd = std::os::fd::AsRawFd::as_raw_fd(listener);
    // SAFETY: fcntl on a descriptor this process owns; only FD_CLOEXEC is cleared.
    unsafe { libc::fcntl(fd, libc::F_SETFD, 0) };
    fd
}

/// The child gets SIGTERM when this process dies, however it dies (`kill -9` included), and
/// stops as on Ctrl-C (safe command, its shared memory removed): a launcher killed outright
/// leaves no run behind (Linux's PR_SET_PDEATHSIG). The signal follows the *thread* that
/// spawned the child, so children are spawned from the launcher's main thread only. If the
/// launcher died between the fork and the prctl, the child exits at once.
pub fn die_with_parent(cmd: &mut std::process::Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: getpid before the fork; in the child only async-signal-safe calls (prctl,
    // getppid, _exit).
    let parent = unsafe { libc::getpid() };
    // SAFETY: the closure runs in the forked child and calls only prctl, getppid and _exit,
    // all async-signal-safe; it touches no lock or allocation of the parent.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(
                libc::PR_SET_PDEATHSIG,
                libc::SIGTERM as libc::c_ulong,
                0,
                0,
                0,
            ) != 0
            {
                return Err(std::io::Error::last_os_error());
            }
            if libc::getppid() != parent {
                libc::_exit(1);
            }
            Ok(())
        });
    }
}

/// An exclusive lock held for a run's lifetime (flock on a file holding the holder's pid). A
/// run id's lock file is removed when the run ends (they piled up in the per-user folder, one
/// per run); the output directory's stays (one file, in the user's own folder).
struct RunLock {
    _file: std::fs::File,
    remove: Option<PathBuf>,
}

impl RunLock {
    /// Take the lock on `path` or say who holds it; `what` names the resource in the message.
    fn take(path: &Path, what: &str) -> Result<RunLock, String> {
        use std::io::{Read, Seek, Write};
        use std::os::unix::fs::MetadataExt;
        use std::os::unix::io::AsRawFd;
        // A lock file is removed by its holder at the end, so the one opened here may be
        // unlinked between the open and the flock: locked, it must still be the file at the
        // path, or a second run could lock a new one beside it. Try again on a new file.
        for _ in 0..8 {
            let mut f = crate::files::open_in_place(path).map_err(|e| format!("{what}: {e}"))?;
            // SAFETY: flock on a descriptor we own.
            if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } != 0 {
                let mut holder = String::new();
                let _ = f.read_to_string(&mut holder);
                return Err(format!(
                    "{what} is in use by another run (pid {}); wait for it to end or choose another",
                    holder.trim()
                ));
            }
            let same = match (f.metadata(), std::fs::symlink_metadata(path)) {
                (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
                _ => false,
            };
            if !same {
                continue;
            }
            let _ = f.set_len(0);
            let _ = f.rewind();
            let _ = write!(f, "{}", std::process::id());
            return Ok(RunLock {
                _file: f,
                remove: None,
            });
        }
        Err(format!("{what}: its lock file keeps being replaced"))
    }

    /// The lock of run id `run_id` under IPC prefix `prefix`, in this user's private directory
    /// (`<tmp>/evoloop-<uid>/locks`, see `ipc::namespace`). Its name is `PREFIX+RUN_ID.lock`:
    /// neither may hold a '+' (`ipc::parse_prefix`, `ipc::parse_run_id`), so two pairs never
    /// share a file (the old name mapped '.' to '_', and `a.b` locked out `a_b`).
    fn for_run_id(prefix: &str, run_id: &str) -> Result<RunLock, String> {
        let dir = crate::ipc::namespace::user_subdir("locks").map_err(|e| e.to_string())?;
        let path = dir.join(format!("{prefix}+{run_id}.lock"));
        let mut lock = Self::take(&path, &format!("run id `{run_id}`"))?;
        lock.remove = Some(path);
        Ok(lock)
    }
}

impl Drop for RunLock {
    fn drop(&mut self) {
        // Unlinked while still locked: a run opening it now finds it gone after its flock and
        // tries again on a new file (`take`).
        if let Some(p) = &self.remove {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// Send signal `sig` (e.g. `libc::SIGTERM`) to the child process; a failure (a child already
/// reaped) is ignored.
pub fn signal(child: &Child, sig: i32) {
    // SAFETY: plain syscall on our own child's pid.
    unsafe { libc::kill(child.id() as i32, sig) };
}

/// `evoloop run FILE --seeds 1..20`: one launcher run per seed (a child `evoloop run`, so each
/// has its own signal handling and report), then the study of tuning alongside operation
/// (indirect or identify) against the frozen controller over the seeds.
pub fn run_seeds(a: RunArgs) -> ExitCode {
    use crate::run_report::seeds_study::{after_phase, Measure, SeedRun, Study};
    let seeds = a.seeds.clone().map(|s| s.0).unwrap_or_default();
    let file = a.file.clone().unwrap_or_else(default_scenario);
    let scn = match super::start::load(&file, &a.overrides) {
        Ok(s) => s,
        Err(e) => {
            err!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let Some(measure) = Measure::of(scn.optimiser.mode) else {
        err!(
            "error: {}: --seeds compares tuning alongside operation (optimiser.mode = \"indirect\" \
             or \"identify\") with the frozen controller over seeds; this scenario has \
             optimiser.mode = \"{}\" (use --seed N for one run)",
            file.display(),
            scn.optimiser.mode
        );
        return ExitCode::from(2);
    };
    // A plant without a change is compared over the last quarter only.
    let changed = scn.plant.model.config().first_change().is_some();
    let out = scn.output.dir.clone();
    if let Err(e) = std::fs::create_dir_all(&out) {
        err!(
            "error: cannot create output directory {}: {e}",
            out.display()
        );
        return ExitCode::from(2);
    }
    for f in ["seeds.csv", "study.json", "study.md", "study_cost.png"] {
        let _ = std::fs::remove_file(out.join(f));
    }
    let stop = stop_flag();
    let exe = match std::env::current_exe() {
        Ok(e) => e,
        Err(e) => {
            err!("error: cannot find the evoloop executable: {e}");
            return ExitCode::from(1);
        }
    };
    let (mut runs, mut failed) = (Vec::new(), Vec::new());
    let t0 = Instant::now();
    for (i, &seed) in seeds.iter().enumerate() {
        if stop.load(Ordering::SeqCst) {
            break;
        }
        let dir = out.join(format!("seed-{seed}"));
        let mut ov = a.overrides.clone();
        ov.seed = Some(seed);
        ov.out = Some(dir.clone());
        let mut cmd = std::process::Command::new(&exe);
        die_with_parent(&mut cmd);
        cmd.arg("run")
            .arg(&file)
            .args(override_args(&ov))
            .args(["--ipc-prefix", &a.ipc_prefix, "--quiet"])
            .stdin(std::process::Stdio::null());
        if let Some(id) = &a.run_id {
            cmd.args(["--run-id", &format!("{id}-seed{seed}")]);
        }
        let o = cmd.output();
        let result = match o {
            Err(e) => Err(format!("cannot start: {e}")),
            Ok(o) if !o.status.success() => {
                let why = String::from_utf8_lossy(&o.stderr);
                let last = why
                    .lines()
                    .rev()
                    .find(|l| !l.trim().is_empty())
                    .unwrap_or("");
                Err(format!("{}: {last}", o.status))
            }
            Ok(_) => crate::report::read_json::<Summary>(&dir, "summary.json")
                .map_err(|e| e.to_string())
                .and_then(|s| {
                    SeedRun::from_summary(seed, &s, &measure, changed).map_err(|e| e.to_string())
                }),
        };
        match result {
            Ok(r) => {
                if !a.quiet {
                    let before = r.before.map_or(String::new(), |(b, bf)| {
                        format!(", before {b:.1} vs {bf:.1}")
                    });
                    let phase = after_phase(changed);
                    err!(
                        "  seed {seed}: {} {phase} {} {:.1} vs frozen {:.1}{before} ({} of {}, {:.0} s)",
                        measure.what, measure.short, r.after, r.after_frozen, i + 1, seeds.len(),
                        t0.elapsed().as_secs_f64()
                    );
                }
                runs.push(r);
            }
            Err(why) => {
                err!("  seed {seed}: failed: {why}");
                failed.push((seed, why));
            }
        }
    }
    let interrupted = stop.load(Ordering::SeqCst);
    if runs.len() < 2 {
        err!("error: fewer than two seeds completed; no study written");
        return ExitCode::from(if interrupted { 130 } else { 1 });
    }
    let study = Study::new(&scn.name, measure, &runs, failed);
    if let Err(e) = study.write(&out, &runs, scn.output.plots) {
        err!("error: writing the study: {e}");
        return ExitCode::from(1);
    }
    out!("{}", study.markdown());
    out!(
        "  wrote {}/seeds.csv, study.json, study.md{}",
        out.display(),
        if scn.output.plots {
            ", study_cost.png"
        } else {
            ""
        }
    );
    if interrupted {
        ExitCode::from(130)
    } else if study.failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }
}

/// What a run starts from: its scenario loaded with the command line's overrides, its output
/// directory made, locked and cleared of the previous run's files, its run id, and the local
/// evaluation workers it asks for. The locks and the disk reserve are held while this lives.
struct Prepared {
    file: PathBuf,
    scn: Scenario,
    dir: PathBuf,
    run_id: String,
    /// `--workers N`: how many, and the loopback endpoint the optimiser listens on for them.
    local: Option<(usize, String)>,
    // Fields drop in declaration order: the reserves go before the locks, so no run that takes
    // the directory next can have its own reserves removed by this one.
    _reserved: Reserved,
    _locks: (RunLock, RunLock),
}

/// `run`'s set-up, or the exit code of what stopped it (said on stderr).
fn prepare(a: &mut RunArgs) -> Result<Prepared, ExitCode> {
    let file = a.file.clone().unwrap_or_else(default_scenario);
    // `--workers N`: the optimiser listens on a free loopback port and waits for N workers.
    if let (Some(_), Err(e)) = (a.workers, crate::network::required("--workers")) {
        err!("error: {e}");
        return Err(ExitCode::from(2));
    }
    // The workers to start and where: set as the optimiser's overrides.
    let local = match a.workers.map(|n| (n as usize, local_workers_endpoint())) {
        None => None,
        Some((n, Ok(ep))) => Some((n, ep)),
        Some((_, Err(e))) => {
            err!("error: --workers: {e}");
            return Err(ExitCode::from(2));
        }
    };
    if let Some((n, ep)) = &local {
        a.overrides.workers_listen = Some(ep.clone());
        a.overrides.workers_expect = Some(*n);
    }
    let scn = match super::start::load(&file, &a.overrides) {
        Ok(s) => s,
        Err(e) => {
            err!("error: {e}");
            return Err(ExitCode::from(2));
        }
    };
    if !a.quiet {
        for w in &scn.warnings {
            err!("warning: {w}");
        }
    }
    let dir = scn.output.dir.clone();
    if let Err(e) = std::fs::create_dir_all(&dir) {
        err!(
            "error: cannot create output directory {}: {e}",
            dir.display()
        );
        return Err(ExitCode::from(2));
    }
    // One run per output directory and per run id at a time: two runs sharing either would mix
    // their reports or each other's shared memory. The locks are flock()s, released by the
    // kernel however this process ends, so a killed run never leaves a stale one; taking the
    // directory's also proves it is writable before anything starts.
    let run_id = a.run_id.clone().unwrap_or_else(|| {
        format!(
            "{}-{:x}",
            std::process::id(),
            crate::rt::now_ns() & 0xffff_ffff
        )
    });
    let locks = RunLock::take(
        &dir.join(".evoloop.lock"),
        &format!("output directory {}", dir.display()),
    )
    .and_then(|d| Ok((d, RunLock::for_run_id(&a.ipc_prefix, &run_id)?)));
    let locks = match locks {
        Ok(l) => l,
        Err(e) => {
            err!("error: {e}");
            return Err(ExitCode::from(2));
        }
    };
    // Remove the previous run's files so a failed run never leaves a stale report looking fresh.
    // The figures too, all of them: report.html embeds those of the list present after the run.
    let files = [
        "run.csv",
        "timing.csv",
        "summary.json",
        "published.jsonl",
        "estimates.csv",
        "repetitions.csv",
        "controller.json",
        "plant.json",
        "optimiser.json",
        "run.mcap",
        "report.html",
    ];
    for f in files.iter().chain(crate::report::html::RUN_FIGURES.iter()) {
        let _ = std::fs::remove_file(dir.join(f));
    }
    let _ = crate::report::write_json(&dir, "scenario.json", &scn);
    let reserved = Reserved::take(&dir);
    Ok(Prepared {
        file,
        scn,
        dir,
        run_id,
        local,
        _reserved: reserved,
        _locks: locks,
    })
}

/// What the launcher watches while the processes run.
struct Watch<'a> {
    /// The processes' arguments (an optimiser restarted gets them again, with `--rejoin`).
    args: &'a [String],
    ipc: &'a Ipc,
    stop: &'a std::sync::atomic::AtomicBool,
    telemetry: &'a Option<crate::ipc::Sub<Telemetry>>,
    estimate: &'a Option<crate::ipc::Sub<crate::msg::ModelEstimate>>,
    quiet: bool,
    span: &'a str,
    /// How long a plant process of the user's own may outlive the controller and optimiser.
    linger: Duration,
}

/// How the processes ended.
struct Supervised {
    /// A process that failed (exited unexpectedly, could not be restarted), in words.
    failed: Vec<String>,
    /// The user stopped the run (Ctrl-C, SIGTERM).
    interrupted: bool,
    tuner: OptimiserLife,
}

/// Watch the children until every one has exited: restart a crashed optimiser while the run can
/// take it back (`restart_pause`), pass a stop on to all, kill what does not stop within 5 s,
/// and print a progress line a second unless quiet.
fn supervise(children: &mut [(&str, Child)], w: &Watch) -> Supervised {
    let mut last_progress = Instant::now();
    let mut failed: Vec<String> = Vec::new();
    let mut exited = vec![false; children.len()];
    let mut interrupted = false;
    let mut stop_sent: Option<Instant> = None;
    let mut tuner = OptimiserLife::default();
    let mut restart_due: Option<Instant> = None;
    let Watch {
        args,
        ipc,
        stop,
        telemetry,
        estimate,
        quiet,
        span,
        linger,
    } = *w;
    // The plant's place; when the user starts a plant of their own, the controller's stands for
    // it (it ends when the plant's last state comes or the plant falls silent).
    let plant = children
        .iter()
        .position(|(n, _)| *n == PROCESSES[PLANT] || *n == EXTERNAL)
        .or_else(|| {
            children
                .iter()
                .position(|(n, _)| *n == PROCESSES[CONTROLLER])
        });
    // When the controller and the optimiser have ended: a plant process of the user's own still
    // running `linger` after that is stopped.
    let mut others_ended: Option<Instant> = None;
    while exited.iter().any(|e| !e) {
        for (i, (name, c)) in children.iter_mut().enumerate() {
            if exited[i] {
                continue;
            }
            // Not once the plant has ended: there is no run left to rejoin.
            let plant_on = plant.is_none_or(|p| !exited[p]);
            let rejoinable = plant_on && !interrupted && stop_sent.is_none();
            if let Some(due) = restart_due.filter(|_| *name == OPTIMISER) {
                if !rejoinable {
                    (exited[i], restart_due) = (true, None);
                } else if Instant::now() >= due {
                    restart_due = None;
                    let mut again = args.to_vec();
                    again.push("--rejoin".into());
                    match spawn_process(name, &again) {
                        Ok(nc) => (*c, tuner.restarts) = (nc, tuner.restarts + 1),
                        Err(e) => {
                            failed.push(format!("cannot restart {name}: {e}"));
                            exited[i] = true;
                        }
                    }
                }
                continue;
            }
            if let Ok(Some(status)) = c.try_wait() {
                // After a stop request (the user's Ctrl-C reaches every process of the
                // terminal's group; ours follows) a child's exit code is expected, and so is
                // death by that very SIGINT or SIGTERM: a child stopped in its first
                // milliseconds, before its handler was installed, dies of it (the group's signal
                // reached this process too, and its handler raised the flag before this thread
                // ran on). Death by any other signal is still a failure (and an optimiser's, a
                // crash to restart).
                let stopping = interrupted || stop_sent.is_some() || stop.load(Ordering::SeqCst);
                let by_stop = stopping
                    && matches!(
                        status.signal(),
                        Some(libc::SIGINT | libc::SIGTERM | libc::SIGHUP)
                    );
                if *name == OPTIMISER && rejoinable && !by_stop && !status.success() {
                    // Its ports must go before the plant can tell it is absent.
                    ipc.cleanup_dead_nodes();
                    match restart_pause(tuner.restarts) {
                        Some(pause) => {
                            err!("evoloop: {name} exited with {status}; the loop goes on with the set in service; starting it again in {:.1} s", pause.as_secs_f64());
                            restart_due = Some(Instant::now() + pause);
                        }
                        None => {
                            err!("evoloop: {name} exited with {status} after {} restarts: the tuner is lost; the loop runs on with the set in service", tuner.restarts);
                            (tuner.lost, exited[i]) = (true, true);
                        }
                    }
                    continue;
                }
                exited[i] = true;
                let expected = status.success() || by_stop || (stopping && status.code().is_some());
                if !expected {
                    failed.push(format!("{name} exited with {status}"));
                }
            }
        }
        if let Some(p) = plant.filter(|&p| children[p].0 == EXTERNAL && !exited[p]) {
            let others_done = exited.iter().enumerate().all(|(j, e)| j == p || *e);
            let since = *others_ended.get_or_insert_with(Instant::now);
            if !others_done {
                others_ended = None;
            } else if stop_sent.is_none() && since.elapsed() > linger {
                err!(
                    "evoloop: {EXTERNAL} still runs {:.0} s after the run ended; stopping it",
                    linger.as_secs_f64()
                );
                signal_process(EXTERNAL, &children[p].1, libc::SIGTERM);
                stop_sent = Some(Instant::now());
            }
        }
        if stop.load(Ordering::SeqCst) && !interrupted {
            interrupted = true;
            err!("evoloop: stopping all processes");
        }
        if (interrupted || !failed.is_empty()) && stop_sent.is_none() {
            for (i, (name, c)) in children.iter().enumerate() {
                if !exited[i] {
                    signal_process(name, c, libc::SIGTERM);
                }
            }
            stop_sent = Some(Instant::now());
        }
        if stop_sent.is_some_and(|s| s.elapsed() > Duration::from_secs(5)) {
            for (i, (name, c)) in children.iter_mut().enumerate() {
                if !exited[i] {
                    err!("evoloop: {name} did not stop within 5 s; killing it");
                    signal_process(name, c, libc::SIGKILL);
                }
            }
        }
        if !quiet && last_progress.elapsed() >= Duration::from_secs(1) {
            last_progress = Instant::now();
            progress_line(telemetry, estimate, span);
        }
        // Supervision, not the control path: a 5 ms poll of child status costs nothing here.
        std::thread::sleep(Duration::from_millis(5));
    }
    Supervised {
        failed,
        interrupted,
        tuner,
    }
}

/// One progress line from the latest telemetry (and model estimate), if any has come.
fn progress_line(
    telemetry: &Option<crate::ipc::Sub<Telemetry>>,
    estimate: &Option<crate::ipc::Sub<crate::msg::ModelEstimate>>,
    span: &str,
) {
    if let Some(Ok(Some(tel))) = telemetry.as_ref().map(|s| s.latest()) {
        let model = match estimate.as_ref().map(|s| s.latest()) {
            Some(Ok(Some(m))) => format!("   model {:.4} +- {:.4}", m.value, m.std),
            _ => String::new(),
        };
        err!(
            "  t = {:8.2} s of {span}   e = {:+.4}   u = {:+.4}   params v{}   overruns {}   misses {}{model}",
            tel.t, tel.tracking_error, tel.u[0], tel.param_version,
            tel.overruns, tel.missed
        );
    }
}

/// `evoloop run` of one scenario: set up the output directory, start the processes (and the
/// live view and local workers if asked), supervise them to the run's end or a Ctrl-C, then
/// measure the floor (realtime) and write the report. Exit code: 0 for a whole run, 2 for bad
/// options or set-up, 1 when a process failed, the loop degraded or a file was not written,
/// 130 when stopped before its end.
pub fn run(mut a: RunArgs) -> ExitCode {
    // First: a Ctrl-C from here on is an interrupted run, with its summary.
    let stop = stop_flag();
    // The live view's port before anything else: one that cannot be had fails the run before
    // it starts (and before the last run's files are removed).
    let live = match &a.live {
        Some(addr) => match super::live::bind(addr, a.live_remote, "--live-remote") {
            Ok(l) => Some(l),
            Err(e) => {
                err!("error: --live {e}");
                return ExitCode::from(2);
            }
        },
        None => None,
    };
    let p = match prepare(&mut a) {
        Ok(p) => p,
        Err(code) => return code,
    };
    let (scn, dir, run_id) = (&p.scn, &p.dir, &p.run_id);
    let mut r = match Running::start(&p, &a, live) {
        Ok(r) => r,
        Err(code) => return code,
    };
    let span = scn.timing.span();
    if !a.quiet {
        err!(
            "evoloop: run {run_id}: scenario `{}` ({} mode, {} at {} s period), output {}",
            scn.name,
            scn.timing.mode,
            span,
            scn.timing.period,
            dir.display()
        );
    }
    let t0 = Instant::now();
    let watch = Watch {
        args: &r.args,
        ipc: &r.ipc,
        stop: &stop,
        telemetry: &r.telemetry,
        estimate: &r.estimate,
        quiet: a.quiet,
        span: &span,
        linger: Duration::from_secs_f64(scn.timing.lockstep_timeout),
    };
    let Supervised {
        failed,
        interrupted,
        tuner,
    } = supervise(&mut r.children, &watch);
    let cleaned = r.wind_down(a.quiet);
    let wall = t0.elapsed().as_secs_f64();
    // A controller killed between its writer's flushes leaves a row cut short at the end of the
    // logs; every reader refuses such a file, so what was written in full is kept readable.
    for name in ["run.csv", "timing.csv"] {
        if let Err(e) = crate::report::cut_partial_row(&dir.join(name)) {
            err!("evoloop: warning: {name}: {e}");
        }
    }
    if !failed.is_empty() {
        for f in &failed {
            err!("error: {f}");
        }
        say_if_disk_full(dir);
        short_summary(
            scn,
            run_id,
            Outcome::Failed,
            &failed,
            wall,
            interrupted,
            tuner,
        );
        return ExitCode::from(1);
    }
    // A run until stopped ends by being stopped: its floor is measured as any finished run's.
    let ended = !interrupted || scn.timing.until_stopped();
    let floor = (scn.timing.mode == Mode::Realtime && scn.timing.measure_floor && ended)
        .then(|| floor(scn, &a));
    let code = report(&p, wall, floor, cleaned, tuner, interrupted);
    match code {
        Some(code) => code,
        None if ended => ExitCode::SUCCESS,
        None => ExitCode::from(130),
    }
}

/// The processes of a run, started, and the launcher's own node that watches them.
struct Running {
    /// The processes, in `PROCESSES`' order.
    children: Vec<(&'static str, Child)>,
    /// Their arguments (an optimiser restarted gets them again).
    args: Vec<String>,
    workers: LocalWorkers,
    telemetry: Option<crate::ipc::Sub<Telemetry>>,
    estimate: Option<crate::ipc::Sub<crate::msg::ModelEstimate>>,
    ipc: Ipc,
    /// Processes of killed runs whose resources the launcher's node removed at its start.
    cleaned: usize,
}

impl Running {
    fn start(
        p: &Prepared,
        a: &RunArgs,
        live_listener: Option<std::net::TcpListener>,
    ) -> Result<Self, ExitCode> {
        adopt_orphans();
        // The launcher's own node: creating it cleans up what killed runs left behind, and it
        // watches the telemetry for progress lines.
        let ipc = Ipc::with_cleanup("evoloop", &p.run_id, &a.ipc_prefix, false).map_err(|e| {
            err!("error: {e}");
            ExitCode::from(2)
        })?;
        let cleaned = ipc.cleanup_dead_nodes();
        let telemetry = ipc.subscriber::<Telemetry>(Topic::Telemetry, 1, false).ok();
        let estimate = ipc.subscriber(Topic::Estimate, 1, false).ok();
        // The absolute config path and the output dir are passed on so children agree exactly.
        let config = std::fs::canonicalize(&p.file).unwrap_or(p.file.clone());
        let mut child_ov = a.overrides.clone();
        child_ov.out = Some(p.dir.clone());
        let mut args = process_args(&config, &p.run_id, &a.ipc_prefix);
        args.extend(override_args(&child_ov));
        // The evaluation workers first: the optimiser waits for them before the run starts.
        let nice = p.scn.optimiser.nice;
        let workers = match &p.local {
            Some((n, ep)) => LocalWorkers::start(ep, *n, 1, nice, &p.run_id),
            None => Ok(LocalWorkers::default()),
        }
        .map_err(|e| {
            err!("error: {e}");
            ExitCode::from(1)
        })?;
        let mut workers = workers;
        if let Some(listener) = live_listener {
            let fd = inheritable(&listener);
            let mut live: Vec<String> = [
                "--run",
                &p.run_id,
                "--ipc-prefix",
                &a.ipc_prefix,
                "--config",
                &config.display().to_string(),
                "--listen-fd",
                &fd.to_string(),
            ]
            .map(String::from)
            .to_vec();
            // The scenario as the run's processes read it (`--optimiser off` decides whether
            // viewers may set the gains).
            live.extend(override_args(&child_ov));
            let c = spawn_process("evoloop-live", &live).map_err(|e| {
                err!("error: cannot start evoloop-live: {e}");
                ExitCode::from(1)
            })?;
            // Closed here: no process started after the live view inherits the port.
            drop(listener);
            workers.0.push(c);
        }
        let external = p.scn.plant.model.config().external().map(|e| {
            let env = super::external::environment(&p.scn, &config, &p.run_id, &a.ipc_prefix);
            (e, env)
        });
        // Where evoloop's own plant runs: its CPU and priority in realtime, none in lockstep.
        let placement = match p.scn.timing.mode {
            Mode::Realtime => p.scn.plant_rt(),
            Mode::Lockstep => RtRequest::default(),
        };
        let children = spawn_all(
            &args,
            external
                .as_ref()
                .map(|(e, env)| (*e, env.as_slice(), &placement)),
        )?;
        if let Some((_, c)) = children.iter().find(|(n, _)| *n == EXTERNAL) {
            if placement.places() {
                super::external::report_placement(&p.scn, c, &placement, a.quiet);
            }
        }
        Ok(Running {
            children,
            args,
            workers,
            telemetry,
            estimate,
            ipc,
            cleaned,
        })
    }

    /// Wait for every process, stop the workers and leave; the processes whose resources were
    /// cleaned up, at the start and now.
    fn wind_down(mut self, quiet: bool) -> usize {
        for (name, c) in &mut self.children {
            let _ = c.wait();
            // What a plant process of the user's own started and left behind goes with it.
            if *name == EXTERNAL {
                super::external::signal_group(c, libc::SIGKILL);
            }
        }
        // The workers serve until told to stop.
        drop(self.workers);
        let orphans = reap_orphans();
        if orphans > 0 && !quiet {
            err!("evoloop: stopped {orphans} process(es) the run's processes left running");
        }
        drop(self.telemetry);
        drop(self.estimate);
        // A child that died without dropping its ports (killed) left its resources behind:
        // remove them now rather than leave them for the next run.
        let cleaned_after = self.ipc.cleanup_dead_nodes();
        if cleaned_after > 0 && !quiet {
            err!("evoloop: removed the resources of {cleaned_after} dead process(es)");
        }
        self.cleaned
    }
}

/// The processes of a run, in this order.
const PROCESSES: [&str; 3] = ["evoloop-plant", "evoloop-controller", "evoloop-optimiser"];
/// The plant's index in `PROCESSES`: once it has ended there is no run to rejoin.
const PLANT: usize = 0;
/// The controller's: it stands for a plant the user starts.
const CONTROLLER: usize = 1;
const _: () = assert!(matches!(PROCESSES[PLANT].as_bytes(), b"evoloop-plant"));

/// A plant of the user's own: its table, the variables it joins with, and where it runs.
type External<'a> = (&'a ExternalSpec, &'a [(String, String)], &'a RtRequest);

/// The plant (evoloop's, the user's `plant.external.command`, or none when the user starts it),
/// the controller and the optimiser, in that order; if one cannot start, those already started
/// are stopped.
fn spawn_all(
    args: &[String],
    external: Option<External>,
) -> Result<Vec<(&'static str, Child)>, ExitCode> {
    let mut children: Vec<(&'static str, Child)> = Vec::new();
    for name in PROCESSES {
        let (who, started) = match external.filter(|_| name == PROCESSES[PLANT]) {
            Some((e, env, _)) if e.command.is_empty() => {
                super::external::announce(e, env);
                continue;
            }
            Some((e, env, at)) => (EXTERNAL, super::external::spawn(e, env, at)),
            None => (name, spawn_process(name, args)),
        };
        match started {
            Ok(c) => children.push((who, c)),
            Err(e) => {
                err!("error: cannot start {who}: {e}");
                for (n, c) in &mut children {
                    signal_process(n, c, libc::SIGTERM);
                    let _ = c.wait();
                }
                return Err(ExitCode::from(1));
            }
        }
    }
    Ok(children)
}

/// `sig` to a child; to a plant process of the user's own, to its whole process group.
fn signal_process(name: &str, c: &Child, sig: i32) {
    if name == EXTERNAL {
        super::external::signal_group(c, sig);
    } else {
        signal(c, sig);
    }
}

/// The bare loop's floor after a realtime run, as long as `--floor-duration` (default: the
/// run's duration, at most 5 s).
fn floor(scn: &Scenario, a: &RunArgs) -> FloorReport {
    let t = &scn.timing;
    let secs = a.floor_duration.unwrap_or_else(|| t.duration.min(5.0));
    if !a.quiet {
        let wait = t.wait.describe();
        err!("evoloop: measuring the bare loop's floor ({wait} wait) for {secs} s");
    }
    measure_floor(t.period, secs, t.fifo_priority, t.controller_cpu, t.wait)
}

/// The report of a run whose processes ended well; an exit code if it is not whole.
fn report(
    p: &Prepared,
    wall: f64,
    floor: Option<FloorReport>,
    cleaned: usize,
    tuner: OptimiserLife,
    interrupted: bool,
) -> Option<ExitCode> {
    let (scn, dir, run_id) = (&p.scn, &p.dir, &p.run_id);
    match build_report(scn, run_id, wall, floor, cleaned, tuner) {
        Ok(s) => {
            print_summary(&s, dir, scn.output.plots);
            // The page is a view of the files above: a failure loses no data, so it warns.
            match crate::report::html::write(dir) {
                Ok(p) => out!("  open {} (the whole report in one page)", p.display()),
                Err(e) => err!("evoloop: warning: report.html: {e}"),
            }
            for why in &s.degraded {
                err!("error: the loop did not control the plant: {why}");
            }
            if s.write_errors.is_empty() {
                return (s.outcome == Outcome::Degraded).then(|| ExitCode::from(1));
            }
            // The report covers what was written; the run is not whole.
            for e in &s.write_errors {
                err!("error: {e}");
            }
            say_if_disk_full(dir);
            Some(ExitCode::from(1))
        }
        // Stopped before the processes had written their reports: no loop ran to report on.
        Err(e) if interrupted => {
            err!("evoloop: interrupted before the loop ran ({e})");
            short_summary(scn, run_id, Outcome::Interrupted, &[], wall, true, tuner);
            Some(ExitCode::from(130))
        }
        Err(e) => {
            err!("error: report: {e}");
            say_if_disk_full(dir);
            Some(ExitCode::from(1))
        }
    }
}

/// The summary.json of a run that has no full report (failed, or stopped before its loop ran):
/// what ended it and which files it left.
fn short_summary(
    scn: &Scenario,
    run_id: &str,
    outcome: Outcome,
    failures: &[String],
    wall: f64,
    interrupted: bool,
    tuner: OptimiserLife,
) {
    let dir = &scn.output.dir;
    let files: Vec<String> = std::fs::read_dir(dir)
        .map(|rd| {
            let mut v: Vec<String> = rd
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !n.starts_with('.'))
                .collect();
            v.sort();
            v
        })
        .unwrap_or_default();
    let report = serde_json::json!({
        "outcome": outcome,
        "failures": failures,
        "scenario": scn.name,
        "config": scn.source.display().to_string(),
        "run_id": run_id,
        "mode": scn.timing.mode,
        "seed": scn.seed,
        "duration_s": scn.timing.duration_s(),
        "wall_s": wall,
        "interrupted": interrupted,
        "optimiser_restarts": tuner.restarts,
        "optimiser_lost": tuner.lost,
        "files": files,
    });
    if let Err(e) = crate::report::write_json(dir, "summary.json", &report) {
        err!("error: summary.json: {e}");
    }
}

/// The run's JSON reports, which every reader starts from, and the disk set aside for each so
/// that logs filling the disk do not cost them (`files::reserve`); released when the
/// launcher ends, however it ends.
struct Reserved(Vec<PathBuf>);

const REPORTS: [&str; 4] = [
    "summary.json",
    "controller.json",
    "plant.json",
    "optimiser.json",
];
/// Disk set aside per report, bytes (a long tuning run's controller.json lists every set).
const REPORT_RESERVE: u64 = 256 << 10;

impl Reserved {
    fn take(dir: &Path) -> Self {
        let paths: Vec<PathBuf> = REPORTS.iter().map(|n| dir.join(n)).collect();
        for p in &paths {
            if let Err(e) = crate::files::reserve(p, REPORT_RESERVE) {
                err!(
                    "evoloop: warning: cannot set disk aside for {}: {e}",
                    p.display()
                );
            }
        }
        Self(paths)
    }
}

impl Drop for Reserved {
    fn drop(&mut self) {
        self.0.iter().for_each(|p| crate::files::release(p));
    }
}

/// After a failed run: say "no space left" with the folder and what is left, when less than
/// 1 MiB is, the words a user needs when writes failed for want of space.
fn say_if_disk_full(dir: &Path) {
    match crate::files::free_bytes(dir) {
        Some(free) if free < 1 << 20 => err!(
            "error: no space left on the device of {} ({free} bytes free): what was written in full is kept",
            dir.display()
        ),
        _ => {}
    }
}

/// The optimiser's binary: the one process the launcher restarts.
const OPTIMISER: &str = "evoloop-optimiser";
/// Restarts of a dead optimiser before the tuner is given up.
const OPTIMISER_RESTARTS: usize = 5;

/// How long to wait before restart number `done + 1` of a dead optimiser, or None when it has
/// had its `OPTIMISER_RESTARTS`. The optimiser is not on the control path: when it dies the
/// loop goes on with the set in service and it is started again to rejoin the run, after a
/// pause that doubles each time (0.1, 0.2, ... 1.6 s) so that one crashing at start does not
/// spin the machine the loop runs on; once the restarts are spent the run goes on without a
/// tuner and says so (outcome "tuner_lost").
fn restart_pause(done: usize) -> Option<Duration> {
    (done < OPTIMISER_RESTARTS).then(|| Duration::from_millis(100 << done))
}

fn print_summary(s: &Summary, dir: &Path, plots: bool) {
    let r = &s.response;
    out!(
        "evoloop: {} samples in {:.2} s ({:.0} samples/s), {} mode",
        s.samples,
        s.wall_s,
        s.throughput_samples_per_s,
        s.mode
    );
    if s.tracking.rms.len() > 1 {
        // Joint-space trajectories: step-response figures mean nothing, tracking errors do.
        let fmt = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{x:.2e}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let t = &s.tracking_after_1s;
        out!(
            "  tracking after 1 s (rad or m, per joint): rms [{}], max |e| [{}]; whole run rms {:.2e}",
            fmt(&t.rms),
            fmt(&t.max_abs),
            s.tracking.rms_all
        );
    } else {
        out!(
            "  response: settling time {} (2 % band), overshoot {:.2} %, IAE {:.4}, ISE {:.4}, final error {:+.2e}",
            r.settling_time_s
                .map(|v| format!("{v:.2} s"))
                .unwrap_or_else(|| "not settled".into()),
            r.overshoot_pct,
            r.iae,
            r.ise,
            r.final_error
        );
    }
    if let Some(a) = s.cycle_allocations.filter(|a| a.allocations > 0) {
        out!(
            "  warning: the control cycle allocated {} times in {} cycles (it is designed not to: please report it)",
            a.allocations,
            a.cycles
        );
    }
    let l = &s.timing.lateness;
    if s.mode == crate::config::Mode::Realtime {
        out!(
            "  timing: lateness p50 {} ns, p99 {} ns, p99.9 {} ns, max {} ns; overruns {}, missed deadlines {}, stale states {}",
            l.p50_ns, l.p99_ns, l.p99_9_ns, l.max_ns, s.overruns, s.deadline_misses, s.timing.stale_states
        );
        if let Some(f) = &s.floor {
            out!(
                "  floor (bare {} loop, same run): lateness p50 {} ns, p99 {} ns, p99.9 {} ns; controller/floor p99 = {:.2}",
                f.wait.describe(), f.lateness.p50_ns, f.lateness.p99_ns, f.lateness.p99_9_ns, f.ratio_p99
            );
        }
        if s.log_dropped > 0 {
            out!(
                "  log: {} of {} rows not written to run.csv/timing.csv (the log writer, an ordinary-priority thread, fell behind the loop; the timing figures above count every cycle)",
                s.log_dropped,
                s.samples
            );
        }
        let c = &s.realtime_privileges.controller;
        out!(
            "  controller privileges: SCHED_FIFO {} (prio {}), mlockall {}, cpu {:?}",
            c.sched_fifo,
            c.priority,
            c.mlockall,
            c.cpu
        );
        for n in &c.notes {
            out!("    note: {n}");
        }
    }
    if let Some(f) = &s.first_refused_state {
        out!(
            "  plant: {} state(s) refused: the safe command sent for a bad value or count, the \
             last good state used for a sample that broke time (first at sample {}: {})",
            s.refused_states,
            f.seq,
            f.fault
        );
    }
    let pv = &s.parameter_versions;
    out!(
        "  parameters: version {} in service; {} accepted, {} rejected",
        pv.final_version,
        pv.accepted.len(),
        pv.rejected.len()
    );
    if s.optimiser_lost {
        out!(
            "  tuner lost: the optimiser died after {} restarts; the loop ran on with the set in service",
            s.optimiser_restarts
        );
    } else if s.optimiser_restarts > 0 {
        out!("  optimiser restarted {} time(s)", s.optimiser_restarts);
    }
    for p in &pv.rejected {
        out!("    v{} at t = {:.3} s: {}", p.version, p.t, p.outcome);
    }
    if let Some(line) = s.evaluations.summary_line() {
        out!("  {line}");
    }
    if let Some(d) = &s.direct {
        out!(
            "  direct scheme: {} trials of {} on the plant, {} aborted by the envelope; cost {} (configured set) -> {} (best, version {}) (direct.csv{})",
            d.trials,
            d.algorithm,
            d.aborted,
            d.baseline_cost.map_or("-".into(), |c| format!("{c:.4}")),
            d.best_cost.map_or("-".into(), |c| format!("{c:.4}")),
            d.best_version,
            if plots { ", direct.png" } else { "" }
        );
    }
    if let Some(first) = s.optimiser_stalls.first() {
        out!(
            "  optimiser: stalled {} time(s), the loop going on without it (first at sample {first}: reproducible up to there); paced again {} time(s)",
            s.optimiser_stalls.len(),
            s.optimiser_resumed
        );
    }
    if let (Some(a), Some(af)) = (s.tracking_after_change, s.tracking_after_change_frozen) {
        let before = match (s.tracking_before_change, s.tracking_before_change_frozen) {
            (Some(b), Some(bf)) => format!("; before the change {:.2} vs {:.2}", 1e3 * b, 1e3 * bf),
            _ => String::new(),
        };
        out!(
            "  identified alongside operation: tracking RMS over the last quarter {:.2} mrad vs {:.2} with the starting models frozen{before} (identify.png)",
            1e3 * a,
            1e3 * af
        );
    }
    out!(
        "  wrote {}/run.csv, summary.json{}{}",
        dir.display(),
        match (plots, s.tracking.rms.len() > 1) {
            (true, true) => ", response.png, tracking.png",
            (true, false) => ", response.png",
            _ => "",
        },
        if dir.join("run.mcap").is_file() {
            ", run.mcap"
        } else {
            ""
        }
    );
}
