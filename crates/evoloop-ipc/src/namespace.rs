//! Where a user's runs keep their inter-process files, and who may touch them.
//!
//! iceoryx2's defaults suit one user per machine: every process uses `/tmp/iceoryx2` (created by
//! whoever came first, then unusable by everyone else: a non-root user fails with
//! `InternalError` after root has run) and one global management segment in `/dev/shm` that is
//! readable and writable by all (mode 0666). On a shared machine that lets any local user lock
//! others out or write into their segment. So each user gets their own namespace:
//!
//! - a private directory `<tmp>/evoloop-<uid>` (mode 0700, refused when it belongs to someone
//!   else or is not a plain directory) holding iceoryx2's root (`iceoryx2/`) and the run locks
//!   (`locks/`);
//! - the uid in the prefix of every file in `/dev/shm` (`evoloop_<uid>_...`), so users never
//!   share a segment; a file there under our prefix that belongs to another user is refused
//!   (somebody is squatting on our names), and ours are made owner-only (0600), the global
//!   management segment included.
//!
//! A run can go further and use its own prefix (`--ipc-prefix`), as the tests do.

use super::IpcError;
use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
use std::path::{Path, PathBuf};

/// Where POSIX shared memory objects appear as files (Linux).
pub const SHM_DIR: &str = "/dev/shm";

fn fail(context: impl Into<String>, cause: impl Into<String>) -> IpcError {
    IpcError::reason(context, cause)
}

fn uid() -> u32 {
    // SAFETY: getuid has no preconditions and cannot fail.
    unsafe { libc::getuid() }
}

/// Create `dir` (mode 0700) if missing, then make sure it is a directory (not a symlink) owned
/// by this user with no access for anyone else; a directory of ours that is too open is closed.
fn private_dir(dir: &Path) -> Result<(), IpcError> {
    let what = || format!("private directory {}", dir.display());
    match std::fs::DirBuilder::new().mode(0o700).create(dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(fail(what(), format!("cannot create it: {e}"))),
    }
    let m = std::fs::symlink_metadata(dir).map_err(|e| fail(what(), e.to_string()))?;
    if !m.file_type().is_dir() {
        return Err(fail(
            what(),
            "exists but is not a directory (a symlink or file put there by someone else?); \
             remove it or set TMPDIR elsewhere",
        ));
    }
    if m.uid() != uid() {
        return Err(fail(
            what(),
            format!(
                "belongs to uid {}, not to you (uid {}): another user created it; remove it or \
                 set TMPDIR elsewhere",
                m.uid(),
                uid()
            ),
        ));
    }
    if m.mode() & 0o077 != 0 {
        std::fs::set_permissions(dir, std::fs::Permissions::from_mode(0o700))
            .map_err(|e| fail(what(), format!("cannot make it owner-only: {e}")))?;
    }
    Ok(())
}

/// This user's private directory for evoloop's runtime files, `<tmp>/evoloop-<uid>` (created
/// on first use).
pub fn user_dir() -> Result<PathBuf, IpcError> {
    let dir = std::env::temp_dir().join(format!("evoloop-{}", uid()));
    private_dir(&dir)?;
    Ok(dir)
}

/// A private subdirectory of `user_dir()` (`iceoryx2`, `locks`).
pub fn user_subdir(name: &str) -> Result<PathBuf, IpcError> {
    let dir = user_dir()?.join(name);
    private_dir(&dir)?;
    Ok(dir)
}

/// The prefix iceoryx2's files actually carry: the run's prefix and this user's uid.
pub fn user_prefix(prefix: &str) -> String {
    format!("{prefix}{}_", uid())
}

/// Before and after a node of `prefix` is created: refuse when a file in `/dev/shm` under this
/// user's prefix belongs to someone else, and make ours owner-only.
pub fn claim_shm(prefix: &str) -> Result<(), IpcError> {
    // Without /dev/shm there are no entries: nothing shared through files to guard.
    for path in entries(Path::new(SHM_DIR), &user_prefix(prefix)) {
        // Gone between listing and looking: a run of ours ended meanwhile.
        let Ok(m) = std::fs::symlink_metadata(&path) else {
            continue;
        };
        if m.uid() != uid() {
            return Err(fail(
                format!("shared memory {}", path.display()),
                format!(
                    "belongs to uid {}, not to you (uid {}): another user created a file in \
                     your namespace; remove it, or run with another --ipc-prefix",
                    m.uid(),
                    uid()
                ),
            ));
        }
        // A segment being created has mode 0200 until iceoryx2 has initialised it (its
        // "not ready" marker), so it is never touched here.
        if m.mode() & 0o077 != 0 {
            // Only iceoryx2's global management segment is created world-writable; nobody
            // but this user opens a file under this prefix, so owner-only is enough.
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).map_err(
                |e| {
                    fail(
                        format!("shared memory {}", path.display()),
                        format!("cannot make it owner-only: {e}"),
                    )
                },
            )?;
        }
    }
    Ok(())
}

/// This user's files under `prefix`: in `/dev/shm` and in iceoryx2's root (its `services` and
/// `nodes` directories), as sorted paths.
pub fn files(prefix: &str) -> Vec<String> {
    let full = user_prefix(prefix);
    let mut dirs = vec![PathBuf::from(SHM_DIR)];
    if let Ok(root) = user_subdir("iceoryx2") {
        dirs.extend([root.join("services"), root.join("nodes"), root]);
    }
    let mut v: Vec<String> = dirs
        .iter()
        .flat_map(|d| entries(d, &full))
        .map(|p| p.display().to_string())
        .collect();
    v.sort();
    v
}

/// The entries of `dir` whose names start with `start` (none when `dir` cannot be read).
pub fn entries(dir: &Path, start: &str) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .filter(|e| e.file_name().to_string_lossy().starts_with(start))
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default()
}
