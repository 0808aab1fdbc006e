//! The workspace's layers, read from `cargo metadata`: the compiler forbids cycles between crates,
//! not a crate that reaches up a layer, nor one namespace built out of two crates. This holds the
//! design the book's "Layout" chapter draws.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::Command;

/// The layers, bottom first: a crate of `crates/` depends only on crates of lower layers (the
/// root package `evoloop`, a facade above them all, on any). A new crate must be placed here.
const LAYERS: &[&[&str]] = &[
    &[
        "evoloop-msg",
        "evoloop-files",
        "evoloop-stats",
        "evoloop-rt",
        "evoloop-workspace-hack",
    ],
    &[
        "evoloop-linalg",
        "evoloop-ipc",
        "evoloop-report",
        "evoloop-optim",
    ],
    &["evoloop-dynamics", "evoloop-rkgnn"],
    &["evoloop-control"],
    &["evoloop-scenario"],
    &["evoloop-schemes"],
    &["evoloop-identify", "evoloop-tune"],
    &["evoloop-run"],
    &["evoloop-cli"],
    // The network above the command line: it implements evoloop-run's `Network` and
    // evoloop-cli's `NetworkCommands`, so that neither has a `zenoh` feature to build twice.
    &["evoloop-net"],
];

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Every `.rs` file under `dir`, with its text.
fn rust_sources(dir: &Path) -> Vec<(std::path::PathBuf, String)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(rust_sources(&p));
        } else if p.extension().is_some_and(|x| x == "rs") {
            let text = std::fs::read_to_string(&p).unwrap();
            out.push((p, text));
        }
    }
    out
}

/// Every `.rs` file of the library crates (`crates/*/src`), with its text.
fn crate_sources() -> Vec<(std::path::PathBuf, String)> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(root().join("crates")).unwrap() {
        let src = e.unwrap().path().join("src");
        if src.is_dir() {
            out.extend(rust_sources(&src));
        }
    }
    out
}

/// Each package of the workspace but the test peers under `tests/`: its name, its manifest and
/// its normal dependencies' names.
fn packages() -> Vec<(String, std::path::PathBuf, Vec<String>)> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let out = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(root())
        .output()
        .expect("cargo metadata runs");
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let mut packages = Vec::new();
    for p in meta["packages"].as_array().unwrap() {
        let manifest = Path::new(p["manifest_path"].as_str().unwrap());
        if manifest.starts_with(root().join("tests")) {
            continue; // the ROS 2 peer
        }
        let deps = p["dependencies"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|d| d["kind"].is_null()) // normal, not dev or build
            .map(|d| d["name"].as_str().unwrap().to_string())
            .collect();
        let name = p["name"].as_str().unwrap().to_string();
        packages.push((name, manifest.to_path_buf(), deps));
    }
    packages
}

/// Each package of `crates/`: its normal dependencies' names.
fn crate_graph() -> BTreeMap<String, Vec<String>> {
    let crates = root().join("crates");
    packages()
        .into_iter()
        .filter(|(_, manifest, _)| manifest.starts_with(&crates)) // not the root facade
        .map(|(name, _, deps)| (name, deps))
        .collect()
}

#[test]
fn every_crate_is_in_a_layer_and_depends_only_on_lower_ones() {
    let g = crate_graph();
    let layer: BTreeMap<&str, usize> = LAYERS
        .iter()
        .enumerate()
        .flat_map(|(i, names)| names.iter().map(move |n| (*n, i)))
        .collect();
    let mut bad = Vec::new();
    for (name, deps) in &g {
        let Some(&mine) = layer.get(name.as_str()) else {
            bad.push(format!("{name}: not placed in LAYERS"));
            continue;
        };
        for d in deps {
            if let Some(&theirs) = layer.get(d.as_str()) {
                if theirs >= mine {
                    bad.push(format!("{name} (layer {mine}) -> {d} (layer {theirs})"));
                }
            }
        }
    }
    for name in layer.keys() {
        if !g.contains_key(*name) {
            bad.push(format!("{name}: in LAYERS but no crate of crates/"));
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
    // The graph was read, not empty: the command line sits on the run.
    assert!(g["evoloop-cli"].iter().any(|d| d == "evoloop-run"));
}

/// Only the command line's crate parses a command line or draws a terminal: no library crate
/// pulls clap or ratatui (the libraries' enums that flags take list their values, `ALL`, and
/// evoloop-cli's `choice` hands them to clap), nor the root package, whose mains call
/// evoloop-cli.
/// (`evoloop-workspace-hack` names clap only to pin its features for every build.)
#[test]
fn the_command_line_and_the_terminal_view_are_the_command_lines_crate_alone() {
    let packages = packages();
    for dep in ["clap", "ratatui"] {
        let with: Vec<_> = packages
            .iter()
            .filter(|(name, _, deps)| {
                name != "evoloop-workspace-hack" && deps.iter().any(|d| d == dep)
            })
            .map(|(name, _, _)| name.as_str())
            .collect();
        assert_eq!(with, ["evoloop-cli"], "{dep}");
    }
}

/// No module re-exports a crate whole (`pub use evoloop_x::*;`): each namespace is one crate's.
#[test]
fn no_module_re_exports_a_crate_whole() {
    let mut found = Vec::new();
    for (p, text) in rust_sources(&root().join("src"))
        .into_iter()
        .chain(crate_sources())
    {
        for (i, line) in text.lines().enumerate() {
            let l = line.trim();
            if l.starts_with("pub use evoloop_") && l.ends_with("::*;") {
                found.push(format!("{}:{}", p.display(), i + 1));
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}

/// No module of a library crate holds another crate's module beside its own: a file that
/// declares modules (`mod x;`) re-exports no module of another crate (`pub use
/// evoloop_y::{model, network};` made `evoloop::rkgnn` out of two crates' directories). The
/// facade (`src/lib.rs`, which declares no module) names each crate, or a crate's module, once.
#[test]
fn no_module_holds_another_crates_module_beside_its_own() {
    let mut found = Vec::new();
    for (p, text) in crate_sources() {
        let declares = text.lines().any(|l| {
            let l = l.trim_start();
            let l = ["pub ", "pub(crate) "]
                .iter()
                .find_map(|v| l.strip_prefix(v))
                .unwrap_or(l);
            l.starts_with("mod ") && l.ends_with(';')
        });
        if !declares {
            continue;
        }
        for (i, path) in re_exported_paths(&text) {
            if is_module_of_another_crate(&path) {
                found.push(format!("{}:{}: {path}", p.display(), i + 1));
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}

/// Each path a `pub use evoloop_...;` statement names (`a::b::{c, d as e}` gives `a::b::c` and
/// `a::b::d`; a statement may span lines, as rustfmt writes long ones), with the index of the
/// line it starts on.
fn re_exported_paths(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let lines: Vec<&str> = text.lines().collect();
    for (i, line) in lines.iter().enumerate() {
        if !line.trim_start().starts_with("pub use evoloop_") {
            continue;
        }
        // The statement up to its `;`, its lines joined.
        let mut statement = String::new();
        for l in &lines[i..] {
            statement.push_str(l.trim());
            statement.push(' ');
            if l.contains(';') {
                break;
            }
        }
        let body = statement.trim_start_matches("pub use ");
        let body = body.split(';').next().unwrap_or_default().trim();
        let named = |item: &str| {
            item.split(" as ")
                .next()
                .unwrap_or_default()
                .trim()
                .to_string()
        };
        match body.split_once("::{") {
            Some((head, list)) => {
                for item in list.trim_end_matches('}').split(',') {
                    let item = named(item);
                    if !item.is_empty() {
                        out.push((i, format!("{head}::{item}")));
                    }
                }
            }
            None if body.contains(" as ") && !body.contains("::") => {} // a crate renamed
            None => out.push((i, named(body))),
        }
    }
    out
}

/// Whether `evoloop_x::a::b` is a module of crate `evoloop-x` (its file or directory exists).
fn is_module_of_another_crate(path: &str) -> bool {
    let mut parts = path.split("::");
    let krate = parts.next().unwrap().replace('_', "-");
    let mut dir = root().join("crates").join(krate).join("src");
    let rest: Vec<&str> = parts.collect();
    for p in &rest[..rest.len().saturating_sub(1)] {
        dir = dir.join(p);
    }
    let Some(last) = rest.last() else {
        return false;
    };
    dir.join(format!("{last}.rs")).is_file() || dir.join(last).join("mod.rs").is_file()
}

/// The house rules the compiler keeps, taken by every crate: the workspace's lints (every public
/// item documented, every unsafe block with the reason it is sound; warnings are errors in CI),
/// and `#![forbid(unsafe_code)]` in each crate with no unsafe code, so that adding some is a
/// change its lib.rs shows. No source turns a rule off with an `allow`.
#[test]
fn every_crate_takes_the_house_rules() {
    let table = |path: &Path| -> toml::Table {
        let text = std::fs::read_to_string(path).unwrap();
        text.parse()
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    };
    let workspace = table(&root().join("Cargo.toml"));
    let lints = &workspace["workspace"]["lints"];
    assert_eq!(lints["rust"]["missing_docs"].as_str(), Some("warn"));
    assert_eq!(
        lints["clippy"]["undocumented_unsafe_blocks"].as_str(),
        Some("warn")
    );
    // CI's clippy makes the warnings errors.
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    assert!(ci.contains("cargo clippy --release --features zenoh --all-targets -- -D warnings"));
    let unsafe_code = |lines: &[(String, String)]| {
        lines.iter().any(|(_, code)| {
            ["unsafe {", "unsafe impl", "unsafe fn", "unsafe extern"]
                .iter()
                .any(|k| code.contains(k))
        })
    };
    let mut bad = Vec::new();
    let mut packages: Vec<(String, std::path::PathBuf)> = crate_graph()
        .into_keys()
        .map(|name| (name.clone(), root().join("crates").join(&name)))
        .collect();
    packages.push(("evoloop".into(), root().to_path_buf()));
    for (name, dir) in &packages {
        let manifest = table(&dir.join("Cargo.toml"));
        let takes = manifest
            .get("lints")
            .and_then(|l| l.get("workspace"))
            .and_then(|w| w.as_bool());
        if takes != Some(true) {
            bad.push(format!("{name}: no `[lints] workspace = true`"));
        }
        // Each source file's code lines: comments and string literals' lines left out.
        let mut lines = Vec::new();
        let subs = ["src", "bin", "examples", "benches"].map(|s| dir.join(s));
        for sub in subs.iter().filter(|d| d.is_dir()) {
            for (p, text) in rust_sources(sub) {
                for l in text.lines() {
                    let code = l.split("//").next().unwrap_or("").trim();
                    if !code.is_empty() && !code.starts_with('"') && !code.starts_with('*') {
                        lines.push((p.display().to_string(), code.to_string()));
                    }
                }
            }
        }
        for (file, code) in &lines {
            let rule_off = ["missing_docs", "undocumented_unsafe_blocks", "unsafe_code"]
                .iter()
                .any(|r| code.contains("allow(") && code.contains(r));
            if rule_off {
                bad.push(format!("{file}: `{code}` turns a house rule off"));
            }
        }
        let lib = std::fs::read_to_string(dir.join("src/lib.rs")).unwrap();
        let forbids = lib.lines().any(|l| l.trim() == "#![forbid(unsafe_code)]");
        match (unsafe_code(&lines), forbids) {
            (false, false) => bad.push(format!(
                "{name}: no unsafe code, and no forbid(unsafe_code)"
            )),
            (true, true) => bad.push(format!("{name}: forbids unsafe code it has")),
            _ => {}
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}

/// A crate without a unit-test target (`[lib] test = false`: evoloop-scenario, whose tests are the
/// root package's, and evoloop-schemes and evoloop-tune, whose tests are their `tests/unit/`)
/// holds no unit test: one added there would compile in no target and pass by never running. And
/// every file of a crate's `tests/unit/` is a module of its `main.rs`, where a file it does not
/// declare would compile nowhere.
#[test]
fn a_crate_without_a_unit_test_target_holds_no_unit_test() {
    let mut checked = 0;
    let mut bad = Vec::new();
    for e in std::fs::read_dir(root().join("crates")).unwrap() {
        let dir = e.unwrap().path();
        let Ok(text) = std::fs::read_to_string(dir.join("Cargo.toml")) else {
            continue;
        };
        let manifest: toml::Table = text.parse().unwrap();
        let no_tests = manifest
            .get("lib")
            .and_then(|l| l.get("test"))
            .and_then(|t| t.as_bool())
            == Some(false);
        bad.extend(undeclared_unit_tests(&dir.join("tests/unit")));
        if !no_tests {
            continue;
        }
        checked += 1;
        for (p, src) in rust_sources(&dir.join("src")) {
            if src.contains("#[test]") || src.contains("cfg(test)") {
                bad.push(p.display().to_string());
            }
        }
    }
    assert!(
        checked >= 3,
        "only {checked} crates have `[lib] test = false`"
    );
    assert!(
        bad.is_empty(),
        "unit tests in a crate that never runs them, or not declared in tests/unit/main.rs: {bad:?}"
    );
}

/// The files of `unit` (a crate's `tests/unit/`) that its `main.rs` does not declare as `mod`.
fn undeclared_unit_tests(unit: &Path) -> Vec<String> {
    let Ok(declared) = crate::common::declared_modules(&unit.join("main.rs")) else {
        return Vec::new();
    };
    let mut bad = Vec::new();
    for e in std::fs::read_dir(unit).unwrap() {
        let path = e.unwrap().path();
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if path.extension().is_some_and(|x| x == "rs")
            && stem != "main"
            && !declared.iter().any(|m| m == stem)
        {
            bad.push(path.display().to_string());
        }
    }
    bad
}
