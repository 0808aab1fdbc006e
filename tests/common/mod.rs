//! Helpers for the tests that spawn the real binaries.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::atomic::{AtomicUsize, Ordering};

static COUNTER: AtomicUsize = AtomicUsize::new(0);

/// A unique iceoryx2 prefix and run id for this test, so tests running in parallel never share
/// services and leftovers can be attributed to exactly one test.
pub fn unique(tag: &str) -> (String, String) {
    let n = COUNTER.fetch_add(1, Ordering::SeqCst);
    let id = format!("t{}{}{}", tag, std::process::id(), n);
    (format!("{id}_"), id)
}

/// The shipped file `config/<name>`.
pub fn config(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("config")
        .join(name)
}

/// Every shipped scenario and experiment file: the `.toml` files of config/'s folders (one per
/// plant, and `experiments/`), not the robot files of `config/robots/`. Sorted.
pub fn shipped_files() -> Vec<PathBuf> {
    let root = config("");
    let mut files = Vec::new();
    for group in std::fs::read_dir(&root).unwrap().flatten() {
        let dir = group.path();
        if !dir.is_dir() || dir.ends_with("robots") {
            continue;
        }
        let tomls = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.path());
        files.extend(tomls.filter(|p| p.extension().is_some_and(|e| e == "toml")));
    }
    files.sort();
    files
}

pub fn evoloop() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_evoloop"))
}

/// The base scenario of the tests: the two-mass plant with the Table 9 DEFC gains.
/// `extra` lines go into `[timing]` (and may open further tables); a `duration` in them replaces
/// the default 25 s.
pub fn scenario(reference: &str, extra: &str) -> String {
    let duration = if extra.contains("duration") {
        ""
    } else {
        "duration = 25.0"
    };
    format!(
        r#"
seed = 1
[plant]
kind = "two_mass"
step = 0.0005
[plant.two_mass]
spring = 1.0
[controller]
kind = "state_feedback"
u_limit = 100.0
[controller.state_feedback]
gains = [18.49, 19.04, 47.27, 7.30, -10.54]
lower = [-100.0, -100.0, -100.0, -100.0, -100.0]
upper = [100.0, 100.0, 100.0, 100.0, 100.0]
[reference]
{reference}
[timing]
period = 0.001
{duration}
{extra}
"#
    )
}

pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write scenario");
    p
}

/// `evoloop run FILE --out OUT` with a unique run id (default prefix) plus `args`.
pub fn run(config: &Path, out: &Path, tag: &str, args: &[&str]) -> Output {
    let (_, run_id) = unique(tag);
    let prefix = evoloop::ipc::DEFAULT_PREFIX;
    Command::new(evoloop())
        .arg("run")
        .arg(config)
        .arg("--out")
        .arg(out)
        .args(["--ipc-prefix", prefix, "--run-id", &run_id, "--quiet"])
        .args(args)
        .output()
        .expect("start evoloop")
}

pub fn assert_ok(out: &Output) {
    assert!(
        out.status.success(),
        "evoloop failed: {}\nstdout:\n{}\nstderr:\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

pub fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("valid JSON")
}

/// Files iceoryx2 left in shared memory and its directories under `prefix` (in this user's
/// namespace), apart from the one global management segment per prefix that iceoryx2 keeps on
/// purpose (shared by every run of that prefix, not owned by any one run).
pub fn leftovers(prefix: &str) -> Vec<String> {
    evoloop::ipc::namespace::files(prefix)
        .into_iter()
        .filter(|f| !f.ends_with(".global_mgmt"))
        .collect()
}

/// Pids of the live processes of run `run_id` (launcher and children).
pub fn processes_with(run_id: &str) -> Vec<u32> {
    evoloop::soak::run_processes(run_id)
        .into_iter()
        .map(|(_, pid)| pid)
        .collect()
}

pub struct Csv {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Csv {
    pub fn read(path: &Path) -> Csv {
        let t = evoloop::report::Table::read(path).expect("readable csv");
        Csv {
            header: t.header,
            rows: t.rows,
        }
    }
    pub fn col(&self, name: &str) -> Vec<f64> {
        let j = self
            .header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name} in {:?}", self.header));
        self.rows.iter().map(|r| r[j]).collect()
    }
}

/// Remove the one global management segment iceoryx2 keeps per prefix, once a test that used its
/// own prefix is done with it (so test runs do not pile files up in /dev/shm).
pub fn forget_prefix(prefix: &str) {
    if let Ok(rd) = std::fs::read_dir("/dev/shm") {
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with(&evoloop::ipc::namespace::user_prefix(prefix))
                && name.ends_with(".global_mgmt")
            {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Start `evoloop run` in the background with its own prefix and run id (stdout discarded).
pub fn spawn_run(config: &Path, out: &Path, prefix: &str, run_id: &str) -> std::process::Child {
    // What the run says on stderr, beside its folder, for a test's failure message
    // (`spawned_stderr`): a run that fails says why.
    let log = std::fs::File::create(spawned_log(out)).expect("create the run's stderr log");
    Command::new(evoloop())
        .arg("run")
        .arg(config)
        .arg("--out")
        .arg(out)
        .args(["--ipc-prefix", prefix, "--run-id", run_id, "--quiet"])
        .stdout(std::process::Stdio::null())
        .stderr(log)
        .spawn()
        .expect("start evoloop")
}

fn spawned_log(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_owned();
    name.push(".stderr");
    PathBuf::from(name)
}

/// The stderr of a run started by `spawn_run` into `out`, so far.
pub fn spawned_stderr(out: &Path) -> String {
    std::fs::read_to_string(spawned_log(out)).unwrap_or_default()
}

/// Pid of the run's process whose binary is `binary` (e.g. "evoloop-plant"), waiting up to 20 s
/// for it to appear.
pub fn process_named(run_id: &str, binary: &str) -> u32 {
    let t0 = std::time::Instant::now();
    loop {
        let found = evoloop::soak::run_processes(run_id)
            .into_iter()
            .find(|(name, _)| name == binary);
        if let Some((_, p)) = found {
            return p;
        }
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(20),
            "{binary} did not start"
        );
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
}

/// `evoloop ARGS...` run in the source tree (so `config/...` paths resolve), its output.
pub fn cli(args: &[&str]) -> Output {
    Command::new(evoloop())
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .unwrap()
}

/// `text` without its lines that start with `prefix` (a scenario's own key, before a test
/// writes another value for it).
pub fn without_lines(text: &str, prefix: &str) -> String {
    let kept: Vec<&str> = text.lines().filter(|l| !l.starts_with(prefix)).collect();
    kept.join("\n") + "\n"
}

/// The command was refused as bad input (exit 2) with `reason` in what it said.
pub fn assert_refused(o: &Output, reason: &str) {
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains(reason), "{e}");
}

/// The JSON a successful command printed on stdout.
pub fn stdout_json(o: &Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).expect("JSON on stdout")
}

/// Whether a realtime run kept its rate. Two parts: the controller can (its median compute time
/// is under half a period, which a stall of the machine does not move), and it did, loosely:
/// the cycles it executed against the periods of `duration_s`, allowing 10 % or, when the bare
/// sleep loop measured after the run (`floor.lost_periods`, scaled to the run's length) lost
/// more, three times that plus 1 %. The floor is measured after the run, so a stall of the shared
/// machine during the run is not in it; 10 % is wide enough for the stalls CI has shown (2.1 %
/// lost once, floor 0.00 %) and narrow enough that a controller at half its rate fails. The exact
/// figures are the benchmarks' (`evoloop bench loop`), not a test's.
pub fn rate_kept(s: &serde_json::Value, duration_s: f64) -> Result<String, String> {
    let period = s["floor"]["period_s"]
        .as_f64()
        .ok_or("no floor in the summary: set timing.measure_floor = true")?;
    let floor_cycles = s["floor"]["lateness"]["count"]
        .as_f64()
        .unwrap_or(0.0)
        .max(1.0);
    let floor_lost = s["floor"]["lost_periods"].as_f64().unwrap_or(0.0) / floor_cycles;
    let periods = duration_s / period;
    let executed = s["samples"].as_f64().unwrap_or(0.0);
    let allowed = (0.01 + 3.0 * floor_lost).max(0.10);
    let fraction = executed / periods;
    let compute_p50 = s["timing"]["compute"]["p50_ns"]
        .as_f64()
        .unwrap_or(f64::INFINITY)
        * 1e-9;
    let line = format!(
        "{executed} cycles of {periods} periods ({:.1} %), allowed loss {:.1} % (floor lost {:.2} % of its periods); compute p50 {:.1} us of a {:.1} us period",
        100.0 * fraction,
        100.0 * allowed,
        100.0 * floor_lost,
        compute_p50 * 1e6,
        period * 1e6
    );
    if fraction >= 1.0 - allowed && compute_p50 < 0.5 * period {
        Ok(line)
    } else {
        Err(line)
    }
}

/// Start a run whose launcher prints progress, and wait until the controller's loop is running
/// (the first progress line, which needs telemetry from a cycle). Returns the launcher.
pub fn spawn_run_and_wait_for_the_loop(
    config: &Path,
    out: &Path,
    prefix: &str,
    run_id: &str,
) -> std::process::Child {
    use std::io::BufRead;
    let mut child = Command::new(evoloop())
        .arg("run")
        .arg(config)
        .arg("--out")
        .arg(out)
        .args(["--ipc-prefix", prefix, "--run-id", run_id])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start evoloop");
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            if line.trim_start().starts_with("t =") {
                let _ = tx.send(());
            }
        }
    });
    rx.recv_timeout(std::time::Duration::from_secs(20))
        .expect("the controller loop did not report running within 20 s");
    child
}

/// One realtime run at a time within a test binary: a loop measured at SCHED_FIFO on a 2-vCPU
/// machine beside the binary's other tests (stall tests freezing processes, lockstep runs
/// computing flat out, a throttled controller spinning) is disturbed in the very rate it is
/// judged on, while the floor it is judged against is measured afterwards, alone. A test with a
/// realtime run (or a timing it reports) takes `alone()`; a heavy test of the same binary takes
/// `heavy()`, which runs beside other heavy tests but never beside an `alone()` one (a write
/// and read lock; Linux's std lock lets a waiting writer in before new readers). `heavy()` is
/// used where two at once measured faster than one after the other (tests/rkgnn.rs 174 s
/// against 164 s); tests/indirect.rs keeps `alone()` throughout: its runs spin the processes
/// and an optimiser on both cores, and two at once took 68 s against 40 s.
static ONE_AT_A_TIME: std::sync::RwLock<()> = std::sync::RwLock::new(());

pub fn alone() -> std::sync::RwLockWriteGuard<'static, ()> {
    ONE_AT_A_TIME.write().unwrap_or_else(|e| e.into_inner())
}

pub fn heavy() -> std::sync::RwLockReadGuard<'static, ()> {
    ONE_AT_A_TIME.read().unwrap_or_else(|e| e.into_inner())
}

/// Wait for `child` to exit, failing the test (and killing it) after `limit`.
pub fn wait_exit(
    child: &mut std::process::Child,
    limit: std::time::Duration,
) -> std::process::ExitStatus {
    let t0 = std::time::Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            panic!("the run did not end within {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// Start `evoloop run` in realtime mode and wait until all four processes are up.
pub fn start(
    cfg: &std::path::Path,
    out: &std::path::Path,
    prefix: &str,
    run_id: &str,
) -> std::process::Child {
    let child = spawn_run(cfg, out, prefix, run_id);
    let t0 = std::time::Instant::now();
    while processes_with(run_id).len() < 4 {
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(20),
            "processes did not start"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    // Let the loop run a little.
    std::thread::sleep(std::time::Duration::from_millis(1500));
    child
}

/// Wait (up to 5 s) until no process of the run is left.
pub fn wait_gone(run_id: &str) {
    let t0 = std::time::Instant::now();
    while !processes_with(run_id).is_empty() {
        assert!(
            t0.elapsed() < std::time::Duration::from_secs(5),
            "processes left: {:?}",
            processes_with(run_id)
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// A 60 s realtime step run of the base scenario (no floor measurement), long enough for a test
/// to disturb it and stop it.
pub fn realtime_config(dir: &std::path::Path) -> std::path::PathBuf {
    realtime_config_lasting(dir, 60.0)
}

/// `realtime_config` lasting `seconds`.
pub fn realtime_config_lasting(dir: &std::path::Path, seconds: f64) -> std::path::PathBuf {
    write(
        dir,
        "rt.toml",
        &scenario(
            "kind = \"step\"\namplitude = 1.0",
            &format!("mode = \"realtime\"\nduration = {seconds:?}\nmeasure_floor = false"),
        ),
    )
}

/// Send `sig` to `pid`, a process of the calling test's own run.
pub fn signal(pid: u32, sig: i32) {
    // SAFETY: plain syscall; the tests signal only processes they started (found by run id).
    unsafe { libc::kill(pid as i32, sig) };
}

/// A PNG's pixels as 8-bit RGB, whatever its colour type and depth (the plots are RGB,
/// Chromium's screenshots RGBA), read with the PNG codec's own decoder.
pub struct Rgb {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// Row by row, left to right.
    pub pixels: Vec<[u8; 3]>,
}

/// `path` decoded as a PNG into `Rgb`.
pub fn read_rgb(path: &Path) -> Result<Rgb, String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    // Palette and low bit depths expanded, 16 bits cut to 8: every pixel is 1 to 4 bytes.
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().map_err(|e| e.to_string())?;
    let mut buf = vec![0; reader.output_buffer_size()];
    let frame = reader.next_frame(&mut buf).map_err(|e| e.to_string())?;
    let bytes = &buf[..frame.buffer_size()];
    let pixels = match frame.color_type {
        png::ColorType::Rgb => bytes.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect(),
        png::ColorType::Rgba => bytes.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect(),
        png::ColorType::Grayscale => bytes.iter().map(|&v| [v; 3]).collect(),
        png::ColorType::GrayscaleAlpha => bytes.chunks_exact(2).map(|p| [p[0]; 3]).collect(),
        png::ColorType::Indexed => return Err("an indexed PNG left unexpanded".into()),
    };
    Ok(Rgb {
        width: frame.width,
        height: frame.height,
        pixels,
    })
}

/// A plot that shows data, not only that a file was written: `path` decodes as a PNG of at least
/// 300 x 200 pixels with at least 500 coloured pixels (the plots draw their series in saturated
/// colours; axes, grid and labels are grey or black, so an empty chart has none).
pub fn assert_plotted(path: &Path) {
    let img =
        read_rgb(path).unwrap_or_else(|e| panic!("{}: not a readable PNG: {e}", path.display()));
    assert!(
        img.width >= 300 && img.height >= 200,
        "{}: {} x {} pixels",
        path.display(),
        img.width,
        img.height
    );
    let coloured = img
        .pixels
        .iter()
        .filter(|p| {
            let [r, g, b] = **p;
            r.max(g).max(b) - r.min(g).min(b) > 60
        })
        .count();
    assert!(
        coloured >= 500,
        "{}: {coloured} coloured pixels: no series drawn",
        path.display()
    );
}

/// evoloop's side of the plant contract as the controller makes its ports: the node, the state
/// subscriber and the command publisher, each with its event.
pub struct ControllerPorts {
    pub ipc: evoloop::ipc::Ipc,
    pub state: evoloop::ipc::Sub<evoloop::msg::PlantState>,
    pub command: evoloop::ipc::Pub<evoloop::msg::Command>,
}

pub fn controller_ports(run: &str, prefix: &str) -> ControllerPorts {
    use evoloop::ipc::{Ipc, Topic};
    let ipc = Ipc::new("evoloop-controller", run, prefix).unwrap();
    let state = ipc.subscriber(Topic::State, 8, true).unwrap();
    let command = ipc.publisher(Topic::Command, true).unwrap();
    ControllerPorts {
        ipc,
        state,
        command,
    }
}

/// The plant-contract tests' state: finite, tiny, huge and signed-zero values where a wrong
/// offset or a lossy copy would show. scripts/stock_plant_interop.py sends the same one.
pub fn contract_state() -> evoloop::msg::PlantState {
    let mut s = evoloop::msg::PlantState {
        seq: 7,
        stamp_ns: 123_456_789,
        t: 0.007,
        n_x: 4,
        n_q: 2,
        n_y: 2,
        flags: 0,
        ..Default::default()
    };
    s.x_true[..4].copy_from_slice(&[0.1, -0.2, 1e-300, f64::MAX]);
    s.y[..2].copy_from_slice(&[std::f64::consts::PI, -0.0]);
    s
}

/// The command answering `contract_state`.
pub fn contract_command() -> evoloop::msg::Command {
    let mut c = evoloop::msg::Command {
        cycle: 1,
        state_seq: 7,
        n_u: 2,
        ..Default::default()
    };
    c.u[..2].copy_from_slice(&[0.5, -1.25]);
    c
}

/// `got` is `want` field by field, every f64 bit for bit (-0.0 is not 0.0 here).
pub fn assert_same_state(got: &evoloop::msg::PlantState, want: &evoloop::msg::PlantState) {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        (
            got.seq,
            got.stamp_ns,
            got.t.to_bits(),
            got.n_x,
            got.n_q,
            got.n_y,
            got.flags
        ),
        (
            want.seq,
            want.stamp_ns,
            want.t.to_bits(),
            want.n_x,
            want.n_q,
            want.n_y,
            want.flags
        )
    );
    for (name, g, w) in [
        ("x_true", &got.x_true[..], &want.x_true[..]),
        ("q_true", &got.q_true[..], &want.q_true[..]),
        ("qd_true", &got.qd_true[..], &want.qd_true[..]),
        ("y", &got.y[..], &want.y[..]),
        ("u_applied", &got.u_applied[..], &want.u_applied[..]),
    ] {
        assert_eq!(bits(g), bits(w), "{name}");
    }
}

/// The test targets Cargo.toml declares (`[[test]]`, each named after its file; autotests are
/// off), read from its `path = "tests/NAME.rs"` lines. One reading for tests/suite.rs's check
/// that every file is built and tests/readme.rs's check of the book's `--test NAME`.
pub fn test_targets() -> Vec<String> {
    let manifest =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml")).unwrap();
    manifest
        .lines()
        .filter_map(|l| l.strip_prefix("path = \"tests/")?.strip_suffix(".rs\""))
        .map(String::from)
        .collect()
}

/// The files of tests/ that are modules of tests/suite.rs (its `mod NAME;` lines).
pub fn suite_modules() -> Vec<String> {
    let suite = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/suite.rs");
    let mut modules = declared_modules(&suite).unwrap();
    modules.retain(|m| m != "common");
    modules
}

/// The modules `file` declares from files of their own (its `mod NAME;` lines).
pub fn declared_modules(file: &Path) -> std::io::Result<Vec<String>> {
    Ok(std::fs::read_to_string(file)?
        .lines()
        .filter_map(|l| l.strip_prefix("mod ")?.strip_suffix(';'))
        .map(String::from)
        .collect())
}
