//! The README cannot drift from the CLI: every command in its `sh` code blocks parses with the
//! real parser, and the files it names (scenarios, tune files, robots) exist and load. The first
//! two lines of "The two commands" are what `.ci/run` executes on a clean clone.

use clap::Parser;
use evoloop_cli::{Cli, Cmd};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The Markdown files of a directory of the repository, sorted.
fn markdown_in(dir: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join(dir))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .collect();
    files.sort();
    files
}

/// The README, every chapter of the book (`docs/src`) and every measurement record
/// (`docs/measurements`, which the book's Measurements chapter includes), in that order.
fn documents() -> Vec<PathBuf> {
    std::iter::once(root().join("README.md"))
        .chain(markdown_in("docs/src"))
        .chain(markdown_in("docs/measurements"))
        .collect()
}

/// The commands of every document's ```sh blocks as ("FILE:LINE", command).
fn all_commands() -> Vec<(String, String)> {
    documents()
        .iter()
        .flat_map(|d| {
            let name = d.strip_prefix(root()).unwrap().display().to_string();
            commands_of(d)
                .into_iter()
                .map(move |(line, c)| (format!("{name}:{line}"), c))
        })
        .collect()
}

/// The README's commands.
fn readme_commands() -> Vec<(usize, String)> {
    commands_of(&root().join("README.md"))
}

/// The commands of every ```sh block of `file`: continuation lines joined, comments dropped.
fn commands_of(file: &Path) -> Vec<(usize, String)> {
    let text = std::fs::read_to_string(root().join(file)).unwrap();
    let mut out = Vec::new();
    let mut in_sh = false;
    let mut pending: Option<(usize, String)> = None;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.starts_with("```") {
            in_sh = !in_sh && t == "```sh";
            continue;
        }
        if !in_sh {
            continue;
        }
        // A comment starts at " #" (a `#` inside a word, e.g. a URL fragment, is not one).
        let code = match t.find(" #") {
            Some(at) => &t[..at],
            None if t.starts_with('#') => "",
            None => t,
        };
        let (code, more) = match code.trim_end().strip_suffix('\\') {
            Some(c) => (c.trim_end(), true),
            None => (code.trim_end(), false),
        };
        let entry = pending.get_or_insert((i + 1, String::new()));
        if !entry.1.is_empty() && !code.is_empty() {
            entry.1.push(' ');
        }
        entry.1.push_str(code.trim_start());
        if !more {
            let (l, c) = pending.take().unwrap();
            if !c.is_empty() {
                out.push((l, c));
            }
        }
    }
    out
}

/// The arguments given to `evoloop` by a README command, or None for the cargo and script
/// commands that do not run it (their own check is done by the caller).
fn evoloop_args(cmd: &str) -> Result<Option<Vec<String>>, String> {
    let words: Vec<String> = cmd.split_whitespace().map(String::from).collect();
    let w: Vec<&str> = words.iter().map(|s| s.as_str()).collect();
    match w.as_slice() {
        ["evoloop", rest @ ..] => Ok(Some(rest.iter().map(|s| s.to_string()).collect())),
        ["cargo", "run", "--release"] => Ok(Some(Vec::new())),
        ["cargo", "run", "--release", "--", rest @ ..] => {
            Ok(Some(rest.iter().map(|s| s.to_string()).collect()))
        }
        ["cargo", "test" | "build", "--release"] => Ok(None),
        // CI's own script, as the measurements of its stages name it.
        [".ci/run"] => {
            if root().join(".ci/run").exists() {
                Ok(None)
            } else {
                Err("no file .ci/run".into())
            }
        }
        // A script of the repository (the measurements' regression table).
        [script, ..] if script.starts_with("scripts/") => {
            if root().join(script).exists() {
                Ok(None)
            } else {
                Err(format!("no file {script}"))
            }
        }
        // A build with an optional feature: the feature must be one Cargo.toml declares.
        ["cargo", "build" | "test", "--release", "--features", feature, ..] => {
            let manifest = std::fs::read_to_string(root().join("Cargo.toml")).unwrap();
            let declared = manifest
                .split("[features]")
                .nth(1)
                .is_some_and(|f| f.lines().any(|l| l.starts_with(&format!("{feature} ="))));
            if declared {
                Ok(None)
            } else {
                Err(format!("no feature `{feature}` in Cargo.toml"))
            }
        }
        // One crate of the workspace alone (the book's "Layout").
        ["cargo", "test" | "build", "--release", "-p", name]
        | ["cargo", "tree", "-p", name, ..] => {
            if root().join("crates").join(name).join("Cargo.toml").exists() {
                Ok(None)
            } else {
                Err(format!("no crate `{name}` in crates/"))
            }
        }
        ["cargo", "run", "--release", "--example", name, ..] => {
            if root().join("examples").join(format!("{name}.rs")).exists() {
                Ok(None)
            } else {
                Err(format!("no example `{name}` in examples/"))
            }
        }
        // A test target of its own (Cargo.toml's [[test]]; autotests are off) ...
        ["cargo", "test", "--release", "--test", name]
        | ["cargo", "test", "--release", "--test", name, "--", "--ignored"] => {
            if crate::common::test_targets().iter().any(|t| t == name) {
                Ok(None)
            } else {
                Err(format!("no test target `{name}` in Cargo.toml"))
            }
        }
        // ... or a file of tests/suite.rs, picked by its module's name.
        ["cargo", "test", "--release", "--test", "suite", filter]
        | ["cargo", "test", "--release", "--test", "suite", "--", "--ignored", filter] => {
            let modules = crate::common::suite_modules();
            match filter.strip_suffix("::") {
                Some(module) if modules.iter().any(|m| m == module) => Ok(None),
                _ => Err(format!("`{filter}` is no `module::` of tests/suite.rs")),
            }
        }
        ["cargo", "bench", "--bench", name] => {
            if root().join("benches").join(format!("{name}.rs")).exists() {
                Ok(None)
            } else {
                Err(format!("no benchmark `{name}` in benches/"))
            }
        }
        // A Python package of the repository (python/: the plant package).
        ["pip", "install", dir, ..] if dir.starts_with("./") => {
            if root().join(dir).join("pyproject.toml").exists() {
                Ok(None)
            } else {
                Err(format!("no Python package (pyproject.toml) in {dir}"))
            }
        }
        // The Python comparison's script and its requirements (run outside the test suite).
        ["python3", script, ..] | ["pip", "install", "-r", script] => {
            if root().join(script).exists() {
                Ok(None)
            } else {
                Err(format!("no file {script}"))
            }
        }
        _ => Err("not an `evoloop`, known cargo or scripts/ command".into()),
    }
}

/// The files a parsed command names must exist, and scenarios and robots must load.
fn check_files(cmd: &Cmd) -> Result<(), String> {
    let path = |p: &Path| -> PathBuf { root().join(p) };
    let scenario = |p: &Path| {
        evoloop::config::Scenario::load(&path(p), &Default::default())
            .map(|_| ())
            .map_err(|e| e.to_string())
    };
    match cmd {
        Cmd::Run(a) => match &a.file {
            Some(f) => scenario(f),
            None => scenario(Path::new("config/two_mass/two_mass.toml")),
        },
        Cmd::Check { file } => scenario(file),
        Cmd::Tune(a) if !path(&a.file).exists() => {
            Err(format!("{} does not exist", a.file.display()))
        }
        Cmd::Dynamics(a) => {
            let robot = match &a.cmd {
                Some(evoloop_cli::dynamics::DynamicsCmd::Regressor(r)) => Some(&r.robot),
                None => a.robot.as_ref(),
            };
            let robot = robot.ok_or("no --robot")?;
            evoloop::dynamics::load(&path(robot))
                .map(|_| ())
                .map_err(|e| e.to_string())
        }
        _ => Ok(()),
    }
}

#[test]
fn every_command_in_the_readme_and_the_book_parses_and_its_files_load() {
    let commands = all_commands();
    assert!(
        commands.len() > 20,
        "found only {} commands",
        commands.len()
    );
    let mut bad = Vec::new();
    for (line, cmd) in &commands {
        let args = match evoloop_args(cmd) {
            Ok(Some(a)) => a,
            Ok(None) => continue,
            Err(e) => {
                bad.push(format!("{line}: `{cmd}`: {e}"));
                continue;
            }
        };
        let argv = std::iter::once("evoloop".to_string()).chain(args);
        match Cli::try_parse_from(argv) {
            Ok(cli) => {
                if let Some(c) = &cli.command {
                    if let Err(e) = check_files(c) {
                        bad.push(format!("{line}: `{cmd}`: {e}"));
                    }
                }
            }
            // `--help` parses by printing help: the command exists.
            Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelp => {}
            Err(e) => bad.push(format!(
                "{line}: `{cmd}`: {}",
                e.to_string().lines().next().unwrap_or("")
            )),
        }
    }
    assert!(
        bad.is_empty(),
        "README and book commands that do not parse:\n{}",
        bad.join("\n")
    );
}

#[test]
fn the_two_commands_come_first_and_are_what_ci_runs() {
    let commands = readme_commands();
    assert_eq!(commands[0].1, "cargo run --release");
    assert_eq!(commands[1].1, "cargo test --release");
    let ci = std::fs::read_to_string(root().join(".ci/run")).unwrap();
    assert!(
        ci.contains("readme_command 1") && ci.contains("readme_command 2"),
        ".ci/run runs the README's two commands, read from the README"
    );
    // The cargo commands .ci/run executes, in order: the README's first one must come first,
    // before anything else has built the tree, then the test command as written, its output
    // also copied to the log the background jobs read (and its status kept: pipefail).
    let run: Vec<&str> = ci
        .lines()
        .map(str::trim)
        .filter(|l| l.starts_with("cargo ") || l.starts_with("eval "))
        .collect();
    assert_eq!(run.first(), Some(&"cargo run --release"), "{run:?}");
    assert_eq!(
        run.get(1),
        Some(&r#"cargo test --release 2>&1 | tee "$test_log""#),
        "{run:?}"
    );
    assert!(ci.lines().any(|l| l == "set -euo pipefail"));
}

#[test]
fn the_checker_itself_rejects_what_does_not_parse() {
    // A test that cannot fail proves nothing: feed the checker commands that must fail.
    assert!(evoloop_args("make run").is_err());
    assert!(evoloop_args("cargo bench --bench nonexistent").is_err());
    assert!(evoloop_args("cargo run --release --example nonexistent").is_err());
    assert!(evoloop_args("cargo run --release --example custom_plant").is_ok());
    assert!(evoloop_args("cargo build --release --features no_such_feature").is_err());
    assert!(evoloop_args("cargo build --release --features zenoh").is_ok());
    let parse = |c: &str| {
        let a = evoloop_args(c).unwrap().unwrap();
        Cli::try_parse_from(std::iter::once("evoloop".to_string()).chain(a))
    };
    assert!(parse("evoloop run config/two_mass/two_mass.toml --mode sideways").is_err());
    assert!(parse("evoloop dynamics --robot x.urdf --frobnicate").is_err());
    assert!(parse("evoloop tune config/experiments/arsinh_tune.toml --seed N").is_err());
    let missing = parse("evoloop run config/no_such.toml").unwrap();
    assert!(check_files(missing.command.as_ref().unwrap()).is_err());
}

/// The book's "Extending evoloop" example quotes `crates/evoloop-control/src/plant/heater.rs` and the registry in
/// `crates/evoloop-control/src/plant/mod.rs`: every stretch of its ```rust blocks between `// ...` elisions appears in
/// those files (compared without whitespace, so line breaks may differ).
#[test]
fn the_extending_example_quotes_the_real_files() {
    let text = std::fs::read_to_string(root().join("docs/src/extending.md")).unwrap();
    let squash = |s: &str| s.chars().filter(|c| !c.is_whitespace()).collect::<String>();
    let files = squash(
        &[
            "crates/evoloop-control/src/plant/heater.rs",
            "crates/evoloop-control/src/plant/mod.rs",
        ]
        .map(|f| std::fs::read_to_string(root().join(f)).unwrap())
        .join("\n"),
    );
    let section = text
        .split("# Extending evoloop")
        .nth(1)
        .expect("the book has the extending chapter");
    let mut stretches = 0;
    for block in section.split("```rust").skip(1) {
        let code = block.split("```").next().unwrap();
        let mut stretch = String::new();
        for line in code.lines().chain(["// ..."]) {
            if line.trim_start().starts_with("// ...") {
                if !stretch.trim().is_empty() {
                    assert!(
                        files.contains(&squash(&stretch)),
                        "README quotes what the files do not say:\n{stretch}"
                    );
                    stretches += 1;
                }
                stretch.clear();
            } else {
                stretch.push_str(line);
                stretch.push('\n');
            }
        }
    }
    assert!(stretches >= 5, "only {stretches} quoted stretches found");
}

/// The README is a screenful that points into the book: under 120 lines, every relative link it
/// has exists, and the book's SUMMARY.md lists every chapter in docs/src and nothing else.
#[test]
fn the_readme_is_short_and_the_book_is_whole() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    assert!(
        readme.lines().count() < 120,
        "README.md has {} lines",
        readme.lines().count()
    );
    let links = |text: &str| -> Vec<String> {
        text.split("](")
            .skip(1)
            .map(|rest| rest.split(')').next().unwrap().to_string())
            .filter(|l| !l.starts_with("http"))
            .collect()
    };
    let readme_links = links(&readme);
    assert!(readme_links.len() >= 10, "{readme_links:?}");
    for l in &readme_links {
        assert!(root().join(l).exists(), "README links to a missing {l}");
    }
    let summary = std::fs::read_to_string(root().join("docs/src/SUMMARY.md")).unwrap();
    let mut listed: Vec<String> = links(&summary);
    listed.sort();
    let mut chapters: Vec<String> = markdown_in("docs/src")
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into_owned())
        .filter(|n| n != "SUMMARY.md")
        .collect();
    chapters.sort();
    assert_eq!(listed, chapters, "SUMMARY.md and docs/src disagree");
}

/// Every measurement record says when, where, what was built and how (a command block), and the
/// book's Measurements chapter links and includes each one, so none is left out of the book.
#[test]
fn every_measurement_is_dated_placed_and_in_the_book() {
    let records = markdown_in("docs/measurements");
    assert!(records.len() >= 5, "{records:?}");
    let chapter = std::fs::read_to_string(root().join("docs/src/measurements.md")).unwrap();
    for r in &records {
        let name = r.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(r).unwrap();
        // Named by the date its **Date:** line starts with (YYYY-MM-DD-topic.md).
        let date = name.get(..10).unwrap_or("");
        let shape = date.bytes().enumerate().all(|(i, b)| match i {
            4 | 7 => b == b'-',
            _ => b.is_ascii_digit(),
        });
        assert!(
            shape && date.len() == 10,
            "{name}: not named YYYY-MM-DD-topic.md"
        );
        assert!(
            text.contains(&format!("**Date:** {date}")),
            "{name}: its **Date:** line does not start with {date}"
        );
        for field in ["**Machine:**", "**Build:**", "**Command"] {
            assert!(text.contains(field), "{name} has no {field}");
        }
        assert!(!commands_of(r).is_empty(), "{name} has no ```sh command");
        // The chapter includes the record and its list links the record's heading, by the
        // anchor mdbook (and GitHub) derive from it.
        let heading = text
            .lines()
            .next()
            .unwrap_or("")
            .trim_start_matches('#')
            .trim();
        let anchor: String = heading
            .chars()
            .filter_map(|c| match c {
                c if c.is_alphanumeric() || c == '_' || c == '-' => Some(c.to_ascii_lowercase()),
                c if c.is_whitespace() => Some('-'),
                _ => None,
            })
            .collect();
        assert!(
            chapter.contains(&format!("](#{anchor})"))
                && chapter.contains(&format!("{{{{#include ../measurements/{name}}}}}")),
            "docs/src/measurements.md does not include {name} and link #{anchor}"
        );
    }
}

/// The book quotes evoloop-msg's version (its major version is the plant contract's): each
/// quotation is the version its Cargo.toml says, so a release that bumps it cannot leave the
/// book behind (the book said 1.2.0 for two releases).
#[test]
fn the_book_quotes_the_message_crates_own_version() {
    let manifest = std::fs::read_to_string(root().join("crates/evoloop-msg/Cargo.toml")).unwrap();
    let version = manifest
        .lines()
        .find_map(|l| l.strip_prefix("version = \"")?.strip_suffix('"'))
        .expect("crates/evoloop-msg/Cargo.toml has its own version");
    for (file, quoted) in [
        (
            "docs/src/layout.md",
            format!("Versioned on its own ({version})"),
        ),
        (
            "docs/src/plant-contract.md",
            format!("`evoloop-msg` crate ({version})"),
        ),
    ] {
        let text = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(text.contains(&quoted), "{file} does not say {quoted:?}");
    }
}

/// Every place the docs, the Python package, the interop pins and its test quote iceoryx2's version
/// (`iceoryx2 0.10`, `iceoryx2==0.10.0`) quotes the one Cargo.lock builds against: the Python
/// binding must speak the same wire layout, and a version bump cannot leave a chapter behind.
#[test]
fn every_quoted_iceoryx2_version_is_the_locked_one() {
    let lock = std::fs::read_to_string(root().join("Cargo.lock")).unwrap();
    let locked = lock
        .split("[[package]]")
        .find_map(|p| {
            p.contains("\nname = \"iceoryx2\"\n")
                .then(|| p.split("version = \"").nth(1)?.split('"').next())
                .flatten()
        })
        .expect("Cargo.lock holds iceoryx2");
    // The chapters, not the dated records (docs/measurements keep the version of their day).
    let mut files = markdown_in("docs/src");
    for f in [
        "README.md",
        "python/README.md",
        "python/pyproject.toml",
        "scripts/interop.txt",
        "scripts/stock_plant_interop.py",
        "tests/python_interop.rs",
    ] {
        files.push(root().join(f));
    }
    let mut quoted = 0;
    for file in &files {
        // A line break inside a quotation is a space.
        let text = std::fs::read_to_string(file).unwrap().replace('\n', " ");
        for sep in ["iceoryx2 ", "iceoryx2` ", "iceoryx2=="] {
            for rest in text.split(sep).skip(1) {
                let v: String = rest
                    .chars()
                    .take_while(|c| c.is_ascii_digit() || *c == '.')
                    .collect();
                let v = v.trim_end_matches('.');
                if v.is_empty() || !v.contains('.') {
                    continue; // "iceoryx2 is ...", not a version
                }
                quoted += 1;
                assert!(
                    locked == v || locked.starts_with(&format!("{v}.")),
                    "{} quotes iceoryx2 {v}; Cargo.lock has {locked}",
                    file.display()
                );
            }
        }
    }
    // The quotations there are today: fewer means this check stopped finding one.
    assert!(
        quoted >= 11,
        "expected at least 11 quotations of iceoryx2's version, found {quoted}"
    );
}

/// config/README.md is the index of the shipped scenarios: it names every `.toml` of config/'s
/// plant and experiment folders (`maglev/maglev.toml`, in backticks, as its tables do) and names
/// no file that is not there.
#[test]
fn the_config_index_names_every_scenario_and_only_those() {
    let index = std::fs::read_to_string(root().join("config/README.md")).unwrap();
    let named: std::collections::BTreeSet<String> = index
        .split('`')
        .skip(1)
        .step_by(2)
        // `PLANT/FILE.toml`, not a robot (`robots/arm3.toml`), a path inside a scenario
        // (`../robots/arm3.toml`) or a path from the root (`config/...`).
        .filter(|s| s.ends_with(".toml") && !s.contains(' ') && s.matches('/').count() == 1)
        .filter(|s| {
            !["robots/", "../", "config/"]
                .iter()
                .any(|p| s.starts_with(p))
        })
        .map(str::to_string)
        .collect();
    let config = root().join("config");
    let shipped: std::collections::BTreeSet<String> = crate::common::shipped_files()
        .iter()
        .map(|p| {
            p.strip_prefix(&config)
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    let missing: Vec<_> = shipped.difference(&named).collect();
    let stale: Vec<_> = named.difference(&shipped).collect();
    assert!(
        missing.is_empty(),
        "config/README.md does not name {missing:?}"
    );
    assert!(
        stale.is_empty(),
        "config/README.md names {stale:?}, not in config/"
    );
}
