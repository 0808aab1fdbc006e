//! The one way evoloop creates an output file: never through a link another user planted.
//!
//! An output directory may be writable by someone else (a shared lab folder, /tmp), and evoloop
//! often runs as root (SCHED_FIFO, mlockall). `File::create` follows a symbolic link at the
//! path, so a link `DIR/scenario.json -> /etc/...` planted by another user made root overwrite
//! the link's target (issue 42). Here the old name is removed first (unlinking a link removes
//! the link, never its target) and the file is created afresh with `O_EXCL | O_NOFOLLOW`: if
//! anything reappears at the name in between, the create fails instead of writing through it.
//! A fresh inode also means no planted hard link, FIFO or device is written either.

use std::fs::File;
use std::io::{self, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

/// Create `path` for writing, new and empty, owned by this process's user (mode 0644 less the
/// umask). Whatever was at the name is removed first, a symbolic link as itself. The error
/// names the path.
pub fn create(path: impl AsRef<Path>) -> io::Result<File> {
    let path = path.as_ref();
    create_fresh(path).map_err(|e| named(path, "cannot create", e))
}

/// `create` with the OS's own error, so that `write` can still tell a full disk (ENOSPC) when
/// even the inode cannot be made, and names the path once.
fn create_fresh(path: &Path) -> io::Result<File> {
    match std::fs::remove_file(path) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::NotFound => {}
        Err(e) => return Err(e),
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .mode(0o644)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC)
        .open(path)
}

/// `bytes` into the file at `path`, whole or not at all: written to a hidden sibling (made as
/// `create` makes files) and renamed over the name, so a reader never finds a cut file and a
/// link at the name is replaced, not followed. On a full disk the space `reserve` set aside
/// for this name is given back and the write tried once more: a run's small reports still land
/// after its logs filled the disk. The error names the path ("no space left on the device").
pub fn write(path: impl AsRef<Path>, bytes: impl AsRef<[u8]>) -> io::Result<()> {
    let path = path.as_ref();
    let reserved = sibling(path, "reserved");
    let mut done = write_whole(path, bytes.as_ref());
    if matches!(&done, Err(e) if e.raw_os_error() == Some(libc::ENOSPC))
        && std::fs::remove_file(&reserved).is_ok()
    {
        done = write_whole(path, bytes.as_ref());
    }
    let _ = std::fs::remove_file(&reserved);
    done.map_err(|e| named(path, "cannot write", e))
}

fn write_whole(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = sibling(path, &format!("{}.tmp", std::process::id()));
    let done = create_fresh(&tmp)
        .and_then(|mut f| f.write_all(bytes).and_then(|()| f.flush()))
        .and_then(|()| std::fs::rename(&tmp, path));
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    done
}

/// `.NAME.what` beside `path`: hidden, so listings of a run's files skip it.
fn sibling(path: &Path, what: &str) -> PathBuf {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    path.with_file_name(format!(".{name}.{what}"))
}

/// Set aside `bytes` of disk for a later `write` of `path` (a hidden file of that size, its
/// blocks allocated). Without it a run whose logs fill the disk loses its JSON reports, the
/// small files every reader starts from; `write` frees it when it needs it.
pub fn reserve(path: &Path, bytes: u64) -> io::Result<()> {
    let f = create_fresh(&sibling(path, "reserved"))?;
    let fd = std::os::unix::io::AsRawFd::as_raw_fd(&f);
    // SAFETY: posix_fallocate on a descriptor we own.
    match unsafe { libc::posix_fallocate(fd, 0, bytes as libc::off_t) } {
        0 => Ok(()),
        e => Err(io::Error::from_raw_os_error(e)),
    }
}

/// Give back what `reserve` set aside for `path` and was not used.
pub fn release(path: &Path) {
    let _ = std::fs::remove_file(sibling(path, "reserved"));
}

/// Bytes an unprivileged writer can still put on the file system of `dir`.
pub fn free_bytes(dir: &Path) -> Option<u64> {
    let c = std::ffi::CString::new(dir.as_os_str().as_encoded_bytes()).ok()?;
    // SAFETY: statvfs is plain old data; all-zero is a valid value to be overwritten.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: a valid C string and a statvfs to fill.
    (unsafe { libc::statvfs(c.as_ptr(), &mut st) } == 0)
        .then(|| st.f_bavail as u64 * st.f_frsize as u64)
}

/// Open an existing file that must stay where it is (a lock file: removing it would break the
/// lock another run holds) for reading and writing, creating it if missing, but never through
/// a symbolic link and never anything but a regular file (a FIFO would block, a device would be
/// written). `O_NONBLOCK` only for the open itself.
pub fn open_in_place(path: &Path) -> io::Result<File> {
    let f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .mode(0o600)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC | libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| named(path, "cannot open", e))?;
    vet(f, path, "cannot open", false)
}

/// Open `path` to append to it (a journal the run adds to while it runs), creating it if missing:
/// never through a symbolic link, and only a regular file this user owns with no second name. A link
/// planted at the name, before or during the run, fails the open with the reason instead of
/// being written through; hold the `File` for the run, so a name replaced later is not reopened.
pub fn append(path: &Path) -> io::Result<File> {
    let f = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .mode(0o644)
        .custom_flags(libc::O_NOFOLLOW | libc::O_CLOEXEC | libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| named(path, "cannot append to", e))?;
    vet(f, path, "cannot append to", true)
}

/// `f`, just opened `O_NONBLOCK` at `path`, kept if it is a regular file (and, with `own`, one
/// this run can have made: `not_this_runs`), with `O_NONBLOCK` cleared for its use; else the
/// reason, saying what was being done. Every open of the crate that must not block on a FIFO
/// or go through a planted file ends here.
pub(crate) fn vet(f: File, path: &Path, doing: &str, own: bool) -> io::Result<File> {
    let meta = f.metadata()?;
    let why = match own {
        true => not_this_runs(&meta),
        false => (!meta.is_file()).then(|| "not a regular file".to_string()),
    };
    if let Some(why) = why {
        let kind = match meta.is_file() {
            true => io::ErrorKind::PermissionDenied,
            false => io::ErrorKind::InvalidInput,
        };
        return Err(io::Error::new(
            kind,
            format!("{doing} {}: {why}", path.display()),
        ));
    }
    clear_nonblock(&f);
    Ok(f)
}

/// Why a file is not one this run can have made itself, if it is not: anything but a regular
/// file, a file another user owns (planted), or one with a second name (a hard link to a file
/// the planter could not read). A file whose one name was removed after the open is the run's.
fn not_this_runs(meta: &std::fs::Metadata) -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid has no preconditions.
    let me = unsafe { libc::geteuid() };
    if !meta.is_file() {
        Some("not a regular file".into())
    } else if meta.uid() != me {
        Some(format!(
            "owned by user {}, not by this run's user {me}",
            meta.uid()
        ))
    } else if meta.nlink() > 1 {
        // No name (0) is a file this run opened whose name was removed since, by a planter
        // racing the open: the descriptor is still the run's own file, and writing to it
        // reaches no one else's.
        Some(format!("it has {} names (a hard link)", meta.nlink()))
    } else {
        None
    }
}

/// Clear `O_NONBLOCK`, set only so that opening a FIFO could not block, for the file's use.
fn clear_nonblock(f: &File) {
    // SAFETY: fcntl on a descriptor we own.
    unsafe {
        let fd = std::os::unix::io::AsRawFd::as_raw_fd(f);
        let flags = libc::fcntl(fd, libc::F_GETFL);
        libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK);
    }
}

/// `e` with the path and what was being done, and the reason in words where the OS's is
/// cryptic: ELOOP from O_NOFOLLOW means a symbolic link, ENOSPC a full disk.
pub fn named(path: &Path, doing: &str, e: io::Error) -> io::Error {
    let why = match e.raw_os_error() {
        Some(libc::ELOOP) => "it is a symbolic link (refusing to write through it)".to_string(),
        Some(libc::ENOSPC) => "no space left on the device".to_string(),
        Some(libc::EEXIST) => "a file appeared at the name while it was being replaced".into(),
        _ => e.to_string(),
    };
    io::Error::new(e.kind(), format!("{doing} {}: {why}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_journal_keeps_its_file_when_its_name_is_removed_but_not_when_it_has_two() {
        // A planter that removes the journal's name between the run's open and its check
        // leaves the run its own file with no name: kept (the race report_html's planted-links
        // test met in CI). A second name is a hard link: refused.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("published.jsonl");
        let f = append(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        let kept = vet(f, &path, "cannot append to", true).unwrap();
        assert_eq!(kept.metadata().unwrap().len(), 0);
        let f = append(&path).unwrap();
        std::fs::hard_link(&path, dir.path().join("other")).unwrap();
        let e = vet(f, &path, "cannot append to", true).unwrap_err();
        assert!(e.to_string().contains("2 names (a hard link)"), "{e}");
    }

    #[test]
    fn a_planted_symlink_is_replaced_not_followed() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.txt");
        std::fs::write(&target, "keep me").unwrap();
        let link = dir.path().join("scenario.json");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        write(&link, "report").unwrap();
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
        assert!(!std::fs::symlink_metadata(&link).unwrap().is_symlink());
        assert_eq!(std::fs::read_to_string(&link).unwrap(), "report");
    }

    #[test]
    fn a_write_is_whole_and_uses_its_reservation_and_leaves_nothing_hidden() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("controller.json");
        reserve(&p, 4096).unwrap();
        assert_eq!(
            std::fs::metadata(dir.path().join(".controller.json.reserved"))
                .unwrap()
                .len(),
            4096
        );
        write(&p, "{}").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "{}");
        let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
        assert_eq!(left.len(), 1, "{left:?}");
    }

    #[test]
    fn a_lock_opened_in_place_refuses_a_symlink_and_a_fifo() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("target.txt");
        std::fs::write(&target, "keep me").unwrap();
        let link = dir.path().join(".evoloop.lock");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        let e = open_in_place(&link).unwrap_err().to_string();
        assert!(e.contains("symbolic link"), "{e}");
        let fifo = dir.path().join("fifo");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = open_in_place(&fifo).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep me");
    }
}
