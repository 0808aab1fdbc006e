//! A run on a full disk (issue 42, item 6): it says "no space", its JSON reports are whole
//! (space was set aside for them), its logs hold whole rows, and the outcome is "incomplete".
//!
//! Needs root to mount a small tmpfs: ignored by a plain `cargo test`, run as root by .ci/run
//! with `--ignored`.

use crate::common;
use common::*;
use std::path::Path;
use std::process::Command;

struct Mounted<'a>(&'a Path);

impl Drop for Mounted<'_> {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(self.0).status();
    }
}

#[test]
#[ignore = "needs root to mount a small tmpfs: .ci/run runs it as root with --ignored"]
fn a_run_that_fills_its_disk_says_so_and_keeps_what_it_wrote_readable() {
    // SAFETY: geteuid has no preconditions.
    let euid = unsafe { libc::geteuid() };
    assert!(euid == 0, "needs root to mount a small tmpfs");
    let tmp = tempfile::tempdir().unwrap();
    let disk = tmp.path().join("disk");
    std::fs::create_dir(&disk).unwrap();
    let mounted = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=1536k", "tmpfs"])
        .arg(&disk)
        .status()
        .unwrap();
    assert!(mounted.success(), "mount tmpfs");
    let _unmount = Mounted(&disk);
    let out = disk.join("out");
    // 30 s of the two-mass run: some 1.4 MB of run.csv and run.mcap, more than the disk holds.
    let o = run(&config("two_mass/two_mass.toml"), &out, "full", &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("no space left"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for name in [
        "summary.json",
        "controller.json",
        "plant.json",
        "optimiser.json",
        "scenario.json",
    ] {
        let text =
            std::fs::read_to_string(out.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        serde_json::from_str::<serde_json::Value>(&text)
            .unwrap_or_else(|e| panic!("{name} is not whole JSON: {e}"));
    }
    let s = json(&out.join("summary.json"));
    assert_eq!(s["outcome"], "incomplete");
    let errors = s["write_errors"].as_array().unwrap();
    assert!(
        errors
            .iter()
            .any(|e| e.as_str().unwrap().starts_with("run.csv")),
        "{errors:?}"
    );
    // The log holds whole rows, fewer than the run's 30 000, and reads as a table.
    let t = evoloop::report::Table::read(&out.join("run.csv")).expect("run.csv reads");
    let rows = t.rows.len();
    assert!(rows > 100 && rows < 30_000, "{rows} rows");
    // No reservation or temporary file is left behind.
    let hidden: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.') && n != ".evoloop.lock")
        .collect();
    assert!(hidden.is_empty(), "{hidden:?}");
}
