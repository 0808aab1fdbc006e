//! Mutation fuzzing of what users hand evoloop: scenario files, D-H tables, URDFs, recordings
//! (run.mcap, as `evoloop replay` reads them), and the
//! parameter sets a controller is offered. Every shipped file is mutated the way hand edits and
//! broken generators go wrong (numbers replaced by NaN, infinities, huge, negative or zero values,
//! strings for numbers, lines lost or repeated, keys renamed, unknown keys, truncation, stray
//! bytes), and the properties are:
//!
//! - no loader panics;
//! - every refusal names the file and gives a reason;
//! - whatever is accepted can be built and stepped (plant, controller, dynamics) without a panic;
//! - a controller offered any parameter set either takes it (all finite) or refuses it with a
//!   code, and keeps its last good values.
//!
//! Seeded and bounded: `EVOLOOP_FUZZ_CASES` cases per target (default 600, as in CI); the seed is
//! printed with any failure so it can be replayed (`EVOLOOP_FUZZ_SEED`).

use evoloop::config::{Overrides, Scenario};
use evoloop::msg::{ParamCode, ParamSet, PlantState, Telemetry};
use evoloop::MAX_PARAMS;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

fn cases() -> usize {
    std::env::var("EVOLOOP_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(600)
}

fn seed() -> u64 {
    std::env::var("EVOLOOP_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20261124)
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn files(dir: &str, ext: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == ext))
        .collect();
    v.sort();
    v
}

thread_local! {
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Silence the panic message on this test's thread (a caught panic is reported by the test
/// itself). The hook is the process's, and the other tests of tests/suite.rs share the process:
/// their panics still print through the default hook.
fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(|q| q.get()) {
                default(info)
            }
        }))
    });
    QUIET.with(|q| q.set(true));
}

fn panic_text(p: Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(non-string panic)".into())
}

const SPECIALS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "0",
    "-1",
    "1e-300",
    "99999999999",
    "-0.0",
    "3.5",
    "\"x\"",
    "[]",
    "true",
    "[1.0, 2.0]",
    "{}",
    "1e9",
    "-7",
];

/// Byte ranges of the numbers in `text` (a digit run with sign, dot and exponent).
fn numbers(text: &str) -> Vec<(usize, usize)> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts = b[i].is_ascii_digit()
            && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_'));
        if starts {
            let mut s = i;
            if s > 0 && b[s - 1] == b'-' {
                s -= 1;
            }
            let mut e = i;
            while e < b.len() && (b[e].is_ascii_digit() || b".eE+-".contains(&b[e])) {
                e += 1;
            }
            out.push((s, e));
            i = e;
        } else {
            i += 1;
        }
    }
    out
}

fn char_floor(text: &str, mut i: usize) -> usize {
    while !text.is_char_boundary(i) {
        i -= 1;
    }
    i
}

/// One random edit of `text`; `xml` picks the edits that fit a URDF.
fn mutate(text: &str, rng: &mut StdRng, xml: bool) -> String {
    let lines: Vec<&str> = text.lines().collect();
    let pick_line = |rng: &mut StdRng| rng.gen_range(0..lines.len().max(1));
    match rng.gen_range(0..9) {
        // A number replaced by a special value (most common: what validation is for).
        0..=2 => {
            let nums = numbers(text);
            if nums.is_empty() {
                return text.to_string();
            }
            let (s, e) = nums[rng.gen_range(0..nums.len())];
            let mut v = SPECIALS[rng.gen_range(0..SPECIALS.len())].to_string();
            if xml {
                v = v.replace('"', "");
            }
            format!("{}{}{}", &text[..s], v, &text[e..])
        }
        3 => {
            let i = pick_line(rng);
            let mut l = lines.clone();
            if !l.is_empty() {
                l.remove(i);
            }
            l.join("\n")
        }
        4 => {
            let i = pick_line(rng);
            let mut l = lines.clone();
            if let Some(x) = l.get(i).copied() {
                l.insert(i, x);
            }
            l.join("\n")
        }
        // A key or attribute renamed to another one of the file.
        5 => {
            let words: Vec<&str> = text
                .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .filter(|w| w.len() > 2 && !w.as_bytes()[0].is_ascii_digit())
                .collect();
            if words.len() < 2 {
                return text.to_string();
            }
            let a = words[rng.gen_range(0..words.len())];
            let b = words[rng.gen_range(0..words.len())];
            text.replacen(a, b, 1)
        }
        6 => {
            let i = pick_line(rng);
            let mut l = lines.clone();
            let extra = if xml {
                [
                    "<bogus/>",
                    "<joint name=\"x\" type=\"floating\"/>",
                    "<link/>",
                ][rng.gen_range(0..3)]
            } else {
                [
                    "bogus = 1",
                    "[bogus]",
                    "kind = \"nonexistent\"",
                    "joints = []",
                ][rng.gen_range(0..4)]
            };
            l.insert(i.min(l.len()), extra);
            l.join("\n")
        }
        7 => {
            let cut = char_floor(text, rng.gen_range(0..=text.len()));
            text[..cut].to_string()
        }
        _ => {
            if text.is_empty() {
                return String::new();
            }
            let i = char_floor(text, rng.gen_range(0..text.len()));
            let c = [b'"', b'[', b']', b'=', b'<', b'>', b'\n', b'#', b'0', b'x']
                [rng.gen_range(0..10)] as char;
            let mut s = text.to_string();
            let end = i + s[i..].chars().next().map(char::len_utf8).unwrap_or(0);
            s.replace_range(i..end, &c.to_string());
            s
        }
    }
}

fn mutated(text: &str, rng: &mut StdRng, xml: bool) -> String {
    let mut t = text.to_string();
    for _ in 0..rng.gen_range(1..=3) {
        t = mutate(&t, rng, xml);
    }
    t
}

/// A refusal passes when its message names the file and its reason is not empty: Ok(false),
/// i.e. not accepted.
fn refused(path: &Path, msg: &str, reason: &str) -> Result<bool, String> {
    let name = path.file_name().unwrap().to_string_lossy();
    if !msg.contains(name.as_ref()) || reason.trim().is_empty() {
        return Err(format!("refusal without file or reason: {msg}"));
    }
    Ok(false)
}

/// Report the failures, with the mutated texts of the first ones.
fn verdict(what: &str, n: usize, failures: Vec<(PathBuf, String, String)>) {
    eprintln!(
        "{what}: {n} mutated cases, {} failures (seed {})",
        failures.len(),
        seed()
    );
    for (file, _, why) in &failures {
        eprintln!("  {}: {why}", file.display());
    }
    if let Some((file, text, why)) = failures.first() {
        // The quiet hook would swallow this test's own verdict.
        QUIET.with(|q| q.set(false));
        panic!(
            "{what}: {} of {n} cases failed; first: {} ({why}):\n{text}",
            failures.len(),
            file.display()
        );
    }
}

#[test]
fn mutated_scenarios_are_refused_with_file_and_reason_or_run_without_panic() {
    quiet_panics();
    let mut rng = StdRng::seed_from_u64(seed());
    let originals: Vec<(PathBuf, String)> = crate::common::shipped_files()
        .into_iter()
        .map(|p| {
            let t = std::fs::read_to_string(&p).unwrap();
            (p, t)
        })
        .collect();
    let (mut accepted, mut failures) = (0, Vec::new());
    let n = cases();
    for _ in 0..n {
        let (path, text) = &originals[rng.gen_range(0..originals.len())];
        let text = mutated(text, &mut rng, false);
        let r = catch_unwind(AssertUnwindSafe(|| {
            match Scenario::parse(&text, path, &Overrides::default()) {
                Err(e) => refused(path, &e.to_string(), &e.reason),
                Ok(scn) => {
                    if scn.simulated() {
                        step_scenario(&scn);
                    }
                    Ok(true)
                }
            }
        }));
        match r {
            Ok(Ok(true)) => accepted += 1,
            Ok(Ok(false)) => {}
            Ok(Err(why)) => failures.push((path.clone(), text, why)),
            Err(p) => failures.push((path.clone(), text, format!("panic: {}", panic_text(p)))),
        }
    }
    eprintln!("scenarios: {accepted} of {n} mutated files accepted and stepped");
    verdict("scenarios", n, failures);
}

/// Build the accepted scenario's plant and controller and run 20 cycles through them.
fn step_scenario(scn: &Scenario) {
    let mut sim = evoloop::plant::PlantSim::new(
        scn.build_plant(),
        scn.plant.step,
        scn.plant.noise_std,
        scn.seed,
    );
    let mut cycle = evoloop::law::cycle::ControlCycle::new(
        scn.build_controller(),
        scn.reference.clone(),
        scn.bounds(),
    );
    let mut msg = PlantState::default();
    let mut tel = Telemetry::default();
    let n_u = sim.plant.n_inputs();
    let mut u = vec![0.0; n_u];
    for k in 0..20 {
        sim.sample(k, 0, &u, &mut msg);
        cycle.step(&msg, &mut tel);
        u.copy_from_slice(&cycle.u[..n_u]);
        sim.advance(&u, scn.timing.period);
    }
}

fn robot_case(path: &Path, text: &str) -> Result<bool, String> {
    let xml = path.extension().is_some_and(|e| e == "urdf");
    let opts = evoloop::dynamics::LoadOptions::default();
    let r = if xml {
        evoloop::dynamics::urdf::parse_with(text, path, &opts)
    } else {
        evoloop::dynamics::dh::parse_with(text, path, &opts)
    };
    match r {
        Err(e) => refused(path, &e.to_string(), &e.reason),
        Ok(loaded) => {
            let m = &loaded.model;
            let n = m.dof();
            let mut d = m.data();
            let q = vec![0.3; n];
            let mut tau = vec![0.0; n];
            m.rnea(&mut d, &q, &q, &q, &mut tau);
            let _ = m.mass_matrix(&mut d, &q);
            Ok(true)
        }
    }
}

#[test]
fn mutated_robot_files_are_refused_with_file_and_reason_or_load_without_panic() {
    quiet_panics();
    let mut rng = StdRng::seed_from_u64(seed() ^ 0x5eed);
    let mut originals: Vec<(PathBuf, String)> = Vec::new();
    for p in files("config/robots", "toml")
        .into_iter()
        .chain(files("config/robots", "urdf"))
        .chain(files("tests/robots", "urdf"))
    {
        let t = std::fs::read_to_string(&p).unwrap();
        originals.push((p, t));
    }
    let (mut accepted, mut failures) = (0, Vec::new());
    let n = cases();
    for _ in 0..n {
        let (path, text) = &originals[rng.gen_range(0..originals.len())];
        let xml = path.extension().is_some_and(|e| e == "urdf");
        let text = mutated(text, &mut rng, xml);
        match catch_unwind(AssertUnwindSafe(|| robot_case(path, &text))) {
            Ok(Ok(true)) => accepted += 1,
            Ok(Ok(false)) => {}
            Ok(Err(why)) => failures.push((path.clone(), text, why)),
            Err(p) => failures.push((path.clone(), text, format!("panic: {}", panic_text(p)))),
        }
    }
    eprintln!("robot files: {accepted} of {n} mutated files accepted and evaluated");
    verdict("robot files", n, failures);
}

#[test]
fn a_controller_takes_a_set_whole_or_refuses_it_with_a_code_and_keeps_its_last_good_values() {
    quiet_panics();
    let mut rng = StdRng::seed_from_u64(seed() ^ 0xc0de);
    let scenarios: Vec<Scenario> = crate::common::shipped_files()
        .iter()
        .filter_map(|p| Scenario::load(p, &Overrides::default()).ok())
        .collect();
    assert!(scenarios.len() >= 10, "the shipped scenarios load");
    let values = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e308,
        -1e308,
        0.0,
        -1.0,
        1.0,
        1e-300,
        50.0,
        -50.0,
        5.0,
    ];
    let mut failures = Vec::new();
    let n = cases() * 4;
    for case in 0..n {
        let scn = &scenarios[rng.gen_range(0..scenarios.len())];
        let r = catch_unwind(AssertUnwindSafe(|| -> Result<(), String> {
            let mut cycle = evoloop::law::cycle::ControlCycle::new(
                scn.build_controller(),
                scn.reference.clone(),
                scn.bounds(),
            )
            .with_stability_check(scn.linear_model());
            let before = cycle.controller.params().to_vec();
            let own_kind = cycle.controller.kind().code();
            // A model set (computed torque's rigid-body model) is accepted too, and leaves the
            // gains in service as they were.
            let model_kind = cycle.controller.model_kind().map(|k| k.code());
            let len = before.len();
            let mut set = ParamSet {
                version: 1 + rng.gen_range(0..3),
                kind: if rng.gen_bool(0.8) {
                    own_kind
                } else {
                    rng.gen_range(0..20)
                },
                n: if rng.gen_bool(0.8) {
                    len as u32
                } else {
                    rng.gen_range(0..=MAX_PARAMS as u32 + 5)
                },
                ..Default::default()
            };
            // Mostly the set in service, perturbed: some sets pass, some fail one check.
            for i in 0..MAX_PARAMS {
                set.values[i] = before.get(i).copied().unwrap_or(0.0);
            }
            for _ in 0..rng.gen_range(0..4) {
                let i = rng.gen_range(0..len.max(1));
                set.values[i] = if rng.gen_bool(0.5) {
                    values[rng.gen_range(0..values.len())]
                } else {
                    set.values[i] * rng.gen_range(0.5..1.5)
                };
            }
            cycle.offer(&set);
            let mut tel = Telemetry::default();
            let state = PlantState::default();
            let e = cycle.step(&state, &mut tel);
            let after = cycle.controller.params().to_vec();
            // A first part of a model sent in parts (`ParamKind::ModelPart`) is gathered: no
            // event, nothing in service changed.
            let part = set.kind == evoloop::msg::ParamKind::ModelPart.code();
            let Some(e) = e else {
                return match (part, after == before) {
                    (true, true) => Ok(()),
                    (true, false) => Err("a part of a model changed the gains in service".into()),
                    (false, _) => Err("no parameter event".into()),
                };
            };
            if after.iter().any(|v| !v.is_finite()) {
                return Err(format!("non-finite parameters in service: {after:?}"));
            }
            match e.code {
                ParamCode::Accepted => {
                    let n = set.n as usize;
                    if Some(set.kind) == model_kind {
                        if after != before {
                            return Err("a model set changed the gains in service".into());
                        }
                    } else if set.kind != own_kind || n != len {
                        return Err("a set of the wrong kind or length was accepted".into());
                    } else if after != set.values[..n] {
                        return Err("accepted but not in service".into());
                    }
                }
                ParamCode::None => return Err("no outcome".into()),
                code => {
                    if code.reason().is_empty() {
                        return Err(format!("{code:?} without a reason"));
                    }
                    if after != before {
                        return Err(format!("refused ({code:?}) but the values changed"));
                    }
                }
            }
            Ok(())
        }));
        match r {
            Ok(Ok(())) => {}
            Ok(Err(why)) => {
                failures.push((PathBuf::from(format!("case {case}")), String::new(), why))
            }
            Err(p) => failures.push((
                PathBuf::from(format!("case {case}")),
                String::new(),
                format!("panic: {}", panic_text(p)),
            )),
        }
    }
    verdict("parameter sets", n, failures);
}

/// `run.mcap` of a short lockstep run of the base scenario, made once by the real binary.
fn recording() -> Vec<u8> {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_evoloop"))
        .current_dir(root())
        .args([
            "run",
            "config/two_mass/two_mass.toml",
            "--duration",
            "0.3",
            "--quiet",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(out.join("run.mcap")).unwrap()
}

/// One way a recording goes wrong: cut short (a kill, a full disk), bytes flipped, a stretch
/// zeroed or repeated, random bytes in place of a record.
fn mutated_bytes(b: &[u8], rng: &mut StdRng) -> Vec<u8> {
    let mut v = b.to_vec();
    let at = rng.gen_range(0..v.len());
    match rng.gen_range(0..5) {
        0 => v.truncate(at),
        1 => {
            for _ in 0..rng.gen_range(1..8) {
                let i = rng.gen_range(0..v.len());
                v[i] ^= 1 << rng.gen_range(0..8);
            }
        }
        2 => {
            let end = (at + rng.gen_range(1..64)).min(v.len());
            v[at..end].fill(0);
        }
        3 => {
            let end = (at + rng.gen_range(1..256)).min(v.len());
            let piece = v[at..end].to_vec();
            v.splice(at..at, piece);
        }
        _ => {
            let end = (at + rng.gen_range(1..32)).min(v.len());
            for x in &mut v[at..end] {
                *x = rng.gen();
            }
        }
    }
    v
}

#[test]
fn mutated_recordings_are_refused_with_file_and_reason_or_read_without_panic() {
    quiet_panics();
    // Today's recordings (ROS 2 CDR) and one from before (JSON), half the cases each.
    let originals = [
        recording(),
        std::fs::read("tests/data/json-recording/run.mcap").unwrap(),
    ];
    let mut rng = StdRng::seed_from_u64(seed() ^ 0x3ca9);
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("run.mcap");
    let (mut accepted, mut failures) = (0, Vec::new());
    let n = cases();
    for case in 0..n {
        let original = &originals[case % 2];
        let bytes = mutated_bytes(original, &mut rng);
        std::fs::write(&path, &bytes).unwrap();
        let read = catch_unwind(AssertUnwindSafe(|| {
            evoloop::report::recording::Recording::read(&path)
        }));
        let why = match read {
            Ok(Ok(_)) => {
                accepted += 1;
                continue;
            }
            Ok(Err(e))
                if e.file() == path && e.to_string().starts_with(&path.display().to_string()) =>
            {
                continue
            }
            Ok(Err(e)) => format!("refused without naming the file: {e}"),
            Err(p) => format!("panic: {}", panic_text(p)),
        };
        let shown = format!("{} bytes, first difference at {:?}", bytes.len(), {
            bytes.iter().zip(original).position(|(a, b)| a != b)
        });
        failures.push((path.clone(), shown, why));
    }
    eprintln!("recordings: {accepted} of {n} mutated files read whole");
    verdict("recordings", n, failures);
}
