//! Shared machines: each user's runs live in their own namespace (a private directory for
//! iceoryx2's root and the locks, the uid in every shared-memory name), every file is
//! owner-only, and a namespace somebody else has put files into is refused with a reason.
//!
//! The tests that need a second user (running as uid 65534, `nobody`, or chowning a file to it)
//! need root: a plain `cargo test` lists them as ignored, .ci/run runs them as root with
//! `--ignored`, and run so without root they fail rather than pass unchecked.

use crate::common;
use common::*;
use std::os::unix::fs::{MetadataExt, PermissionsExt};
use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Output};

const NOBODY: u32 = 65534;

fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() == 0 }
}

fn short_run(dir: &Path) -> std::path::PathBuf {
    write(
        dir,
        "short.toml",
        &scenario("kind = \"step\"\namplitude = 1.0", "duration = 0.5"),
    )
}

/// `evoloop run` with its own prefix and run id, `TMPDIR` set to `tmpdir`, optionally as `uid`.
fn run_as(cfg: &Path, out: &Path, prefix: &str, tmpdir: &Path, uid: Option<u32>) -> Output {
    let (_, run_id) = unique("shm");
    let mut c = Command::new(evoloop());
    c.arg("run")
        .arg(cfg)
        .arg("--out")
        .arg(out)
        .args(["--ipc-prefix", prefix, "--run-id", &run_id, "--quiet"])
        .env("TMPDIR", tmpdir);
    if let Some(u) = uid {
        c.uid(u).gid(u);
    }
    c.output().expect("start evoloop")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Files in /dev/shm whose names start with `start`.
fn shm_files(start: &str) -> Vec<std::path::PathBuf> {
    evoloop::ipc::namespace::entries(std::path::Path::new("/dev/shm"), start)
}

#[test]
fn a_run_leaves_only_owner_only_files_in_its_users_namespace() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = short_run(tmp.path());
    let (prefix, _) = unique("own");
    let o = run_as(&cfg, &tmp.path().join("out"), &prefix, tmp.path(), None);
    assert_ok(&o);
    // SAFETY: getuid has no preconditions.
    let uid = unsafe { libc::getuid() };
    let dir = tmp.path().join(format!("evoloop-{uid}"));
    for d in [dir.clone(), dir.join("iceoryx2"), dir.join("locks")] {
        let m = std::fs::symlink_metadata(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display()));
        assert!(m.is_dir(), "{}", d.display());
        assert_eq!(m.mode() & 0o777, 0o700, "{} mode", d.display());
    }
    // iceoryx2 keeps its global management segment after the run; it used to be 0666.
    let kept = shm_files(&format!("{prefix}{uid}_"));
    assert!(
        kept.iter()
            .any(|p| p.to_string_lossy().ends_with(".global_mgmt")),
        "no global management segment under the user's prefix: {kept:?}"
    );
    for p in &kept {
        let m = std::fs::metadata(p).unwrap();
        assert_eq!(m.uid(), uid, "{}", p.display());
        assert_eq!(m.mode() & 0o077, 0, "{} is open to others", p.display());
    }
    // Nothing went to the shared default root or under the bare prefix.
    assert!(shm_files(&prefix)
        .iter()
        .all(|p| p.to_string_lossy().contains(&format!("{prefix}{uid}_"))));
    forget_prefix(&prefix);
}

#[test]
fn a_private_directory_that_is_not_a_directory_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = short_run(tmp.path());
    // SAFETY: getuid has no preconditions.
    let uid = unsafe { libc::getuid() };
    let elsewhere = tmp.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, tmp.path().join(format!("evoloop-{uid}"))).unwrap();
    let (prefix, _) = unique("sym");
    let o = run_as(&cfg, &tmp.path().join("out"), &prefix, tmp.path(), None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains(&format!("evoloop-{uid}")), "{e}");
    assert!(e.contains("is not a directory"), "{e}");
    assert!(
        std::fs::read_dir(&elsewhere).unwrap().next().is_none(),
        "wrote through the symlink"
    );
}

#[test]
#[ignore = "needs root to run as a second user: .ci/run runs it as root with --ignored"]
fn a_second_user_runs_after_root_in_a_namespace_of_its_own() {
    assert!(is_root(), "needs root to run as a second user");
    let tmp = tempfile::tempdir().unwrap();
    let cfg = short_run(tmp.path());
    std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o1777)).unwrap();
    let (prefix, _) = unique("two");
    // Root first, as on the machine of the report.
    assert_ok(&run_as(
        &cfg,
        &tmp.path().join("root"),
        &prefix,
        tmp.path(),
        None,
    ));
    let out = tmp.path().join("nobody");
    std::fs::create_dir(&out).unwrap();
    std::os::unix::fs::chown(&out, Some(NOBODY), Some(NOBODY)).unwrap();
    std::fs::set_permissions(&cfg, std::fs::Permissions::from_mode(0o644)).unwrap();
    let o = run_as(&cfg, &out, &prefix, tmp.path(), Some(NOBODY));
    assert!(
        o.status.success(),
        "the second user's run failed:\n{}",
        stderr(&o)
    );
    assert!(out.join("summary.json").is_file());
    let theirs = shm_files(&format!("{prefix}{NOBODY}_"));
    assert!(!theirs.is_empty(), "no files of the second user");
    for p in &theirs {
        let m = std::fs::metadata(p).unwrap();
        assert_eq!(m.uid(), NOBODY, "{}", p.display());
        assert_eq!(m.mode() & 0o077, 0, "{} is open to others", p.display());
    }
    let dir = tmp.path().join(format!("evoloop-{NOBODY}"));
    assert_eq!(std::fs::metadata(&dir).unwrap().uid(), NOBODY);
    for p in theirs {
        let _ = std::fs::remove_file(p);
    }
    forget_prefix(&prefix);
}

#[test]
#[ignore = "needs root to create files owned by another user: .ci/run runs it as root with --ignored"]
fn files_of_another_user_in_the_namespace_are_refused() {
    assert!(
        is_root(),
        "needs root to create files owned by another user"
    );
    let tmp = tempfile::tempdir().unwrap();
    let cfg = short_run(tmp.path());
    // A squatter's file in /dev/shm under our prefix.
    let (prefix, _) = unique("squat");
    let squat = Path::new("/dev/shm").join(format!("{prefix}0_squatter"));
    std::fs::write(&squat, b"").unwrap();
    std::os::unix::fs::chown(&squat, Some(NOBODY), Some(NOBODY)).unwrap();
    let o = run_as(&cfg, &tmp.path().join("a"), &prefix, tmp.path(), None);
    let _ = std::fs::remove_file(&squat);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains(&squat.display().to_string()), "{e}");
    assert!(e.contains("belongs to uid 65534, not to you"), "{e}");
    forget_prefix(&prefix);

    // iceoryx2's own global management segment, squatted: iceoryx2 fails with a generic
    // error (UnableToGenerateUniqueNodeId); the message names the file and its owner.
    let (prefix, _) = unique("squat");
    assert_ok(&run_as(
        &cfg,
        &tmp.path().join("g"),
        &prefix,
        tmp.path(),
        None,
    ));
    let mgmt = shm_files(&format!("{prefix}0_"))
        .into_iter()
        .find(|p| p.to_string_lossy().ends_with(".global_mgmt"))
        .expect("a global management segment");
    std::fs::remove_file(&mgmt).unwrap();
    std::fs::write(&mgmt, b"").unwrap();
    std::os::unix::fs::chown(&mgmt, Some(NOBODY), Some(NOBODY)).unwrap();
    let o = run_as(&cfg, &tmp.path().join("g"), &prefix, tmp.path(), None);
    let _ = std::fs::remove_file(&mgmt);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains(&mgmt.display().to_string()), "{e}");
    assert!(e.contains("belongs to uid 65534, not to you"), "{e}");
    forget_prefix(&prefix);

    // A private directory somebody else created.
    let dir = tmp.path().join("evoloop-0");
    std::fs::create_dir_all(&dir).unwrap();
    std::os::unix::fs::chown(&dir, Some(NOBODY), Some(NOBODY)).unwrap();
    let (prefix, _) = unique("squat");
    let o = run_as(&cfg, &tmp.path().join("b"), &prefix, tmp.path(), None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("evoloop-0"), "{e}");
    assert!(e.contains("belongs to uid 65534, not to you"), "{e}");
}

/// As `uid`, plant `DIR/name -> target` with ln(1).
fn plant_link(dir: &Path, name: &str, target: &Path, uid: u32) {
    let o = Command::new("ln")
        .arg("-s")
        .arg(target)
        .arg(dir.join(name))
        .uid(uid)
        .gid(uid)
        .output()
        .expect("ln");
    assert!(o.status.success(), "ln as {uid}: {}", stderr(&o));
}

#[test]
#[ignore = "needs root to plant links as a second user: .ci/run runs it as root with --ignored"]
fn root_never_writes_through_links_another_user_planted_in_the_output_directory() {
    assert!(is_root(), "needs root to plant links as a second user");
    let tmp = tempfile::tempdir().unwrap();
    let cfg = short_run(tmp.path());
    // The other user's output folder (not sticky: the kernel's protected_symlinks does not
    // apply) and root's own files the links point at.
    let out = tmp.path().join("shared");
    std::fs::create_dir(&out).unwrap();
    std::os::unix::fs::chown(&out, Some(NOBODY), Some(NOBODY)).unwrap();
    let victims = tmp.path().join("victims");
    std::fs::create_dir(&victims).unwrap();
    let names = [
        "scenario.json",
        "run.mcap",
        "report.html",
        "run.csv",
        "timing.csv",
        "summary.json",
        "controller.json",
        "response.png",
        "tracking.png",
    ];
    let victim = |name: &str| victims.join(format!("{name}.precious"));
    for name in names.iter().chain([&".evoloop.lock"]) {
        std::fs::write(victim(name), "precious").unwrap();
        plant_link(&out, name, &victim(name), NOBODY);
    }
    let (prefix, _) = unique("lnk");
    // The lock cannot be replaced (another run may hold it): refused, with the reason.
    let o = run_as(&cfg, &out, &prefix, tmp.path(), None);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("symbolic link"), "{}", stderr(&o));
    // Without it the run goes ahead and every planted link is replaced by the run's file.
    std::fs::remove_file(out.join(".evoloop.lock")).unwrap();
    let o = run_as(&cfg, &out, &prefix, tmp.path(), None);
    assert_ok(&o);
    for name in names.iter().chain([&".evoloop.lock"]) {
        assert_eq!(
            std::fs::read_to_string(victim(name)).unwrap(),
            "precious",
            "root wrote through the planted {name}"
        );
    }
    // What the run wrote is its own file; a link to a file it does not write is gone.
    let mut written = 0;
    for name in names {
        match std::fs::symlink_metadata(out.join(name)) {
            Ok(m) => {
                assert!(m.is_file(), "{name} is not the run's own file");
                assert_eq!(m.uid(), 0, "{name}");
                written += 1;
            }
            Err(e) => assert_eq!(e.kind(), std::io::ErrorKind::NotFound, "{name}"),
        }
    }
    assert!(written >= 6, "the run wrote only {written} of {names:?}");
    forget_prefix(&prefix);
}
