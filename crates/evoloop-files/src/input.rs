//! Reading the project's text inputs: files bounded in size, and TOML decoded with the key and
//! line of a problem. The configuration checks and the robot loaders (`evoloop-dynamics`) both
//! read through here, so neither needs the other for it.

use std::path::Path;

/// The largest configuration, robot or trajectory file read (16 MiB): a bound, so that
/// `evoloop check /dev/zero` or a wrong path to a huge file fails at once instead of reading
/// without end.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// The largest data file evoloop writes and reads back (1 GiB): an identified model, whose
/// premise rows grow with its training run, or a run's record of every set it published.
pub const MAX_DATA_BYTES: u64 = 1 << 30;

/// A text file, read up to `MAX_FILE_BYTES`. Anything but a regular file (a FIFO, which would
/// block the reader forever; a device, which has no end) is refused with the reason. Links are
/// followed: a user's configuration may well be one.
pub fn read_text(path: &Path) -> std::io::Result<String> {
    read_text_up_to(path, MAX_FILE_BYTES).map_err(|e| match e.kind() {
        std::io::ErrorKind::FileTooLarge => std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!("{e}: not a configuration, robot or trajectory file"),
        ),
        _ => e,
    })
}

/// A text file as `read_text` reads it, up to `max` bytes (a data file: `MAX_DATA_BYTES`).
pub fn read_text_up_to(path: &Path, max: u64) -> std::io::Result<String> {
    use std::io::Read;
    let f = open_regular(path)?;
    let mut text = String::new();
    f.take(max + 1).read_to_string(&mut text)?;
    if text.len() as u64 > max {
        return Err(std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!("larger than {} MiB", max >> 20),
        ));
    }
    Ok(text)
}

/// A file a run wrote itself, read back (a run's summary, its plots, its journal): up to `max`
/// bytes, and only if the name is not a symbolic link and holds a regular file this user owns
/// with no other name (a hard link). An output directory may be writable by another user, who
/// could plant `DIR/zz.png -> /root/secret` for a report to embed; that is refused here with
/// the reason, never read.
pub fn read_own(path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let f = open_own(path)?;
    let len = f.metadata()?.len();
    if len > max {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "{}: {len} bytes, more than the {max} expected",
                path.display()
            ),
        ));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    f.take(max).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// A file a run wrote itself, opened for reading as `read_own` opens it (for a reader that
/// wants only part of it: a journal's tail).
pub fn open_own(path: &Path) -> std::io::Result<std::fs::File> {
    let f = open_nonblocking(path, libc::O_NOFOLLOW)?;
    crate::output::vet(f, path, "cannot read", true)
}

/// `path` opened for reading if it is a regular file (links followed: a configuration may be
/// one); `O_NONBLOCK` only for the open, so that a FIFO at the name cannot block it.
fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    let f = open_nonblocking(path, 0)?;
    crate::output::vet(f, path, "cannot read", false)
}

/// `path` opened `O_NONBLOCK` for reading with `extra` flags; a refused link said as such.
fn open_nonblocking(path: &Path, extra: i32) -> std::io::Result<std::fs::File> {
    use std::os::unix::fs::OpenOptionsExt;
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(extra | libc::O_NONBLOCK | libc::O_CLOEXEC)
        .open(path)
        .map_err(|e| match e.raw_os_error() {
            Some(libc::ELOOP) if extra & libc::O_NOFOLLOW != 0 => std::io::Error::new(
                e.kind(),
                format!(
                    "{}: a symbolic link (refusing to read through it)",
                    path.display()
                ),
            ),
            _ => e,
        })
}

/// What went wrong deserialising a TOML or JSON text: the dotted key (empty at file level), the
/// 1-based line when known, and a reason that is never empty.
pub struct DecodeError {
    /// Dotted path of the key at fault, as `serde_path_to_error` prints it; empty for a
    /// file-level error.
    pub key: String,
    /// 1-based line of the problem in the text, when the reader gave a position.
    pub line: Option<usize>,
    /// Why it failed, in the reader's words, or a stand-in where those are empty: never empty.
    pub reason: String,
}

/// Deserialise `text` as TOML into `T`, or say where and why not (every TOML reader of the
/// project goes through here: scenarios, D-H tables, tuning experiments).
pub fn from_toml<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, DecodeError> {
    let document =
        toml::Deserializer::parse(text).map_err(|e| toml_error(text, String::new(), &e))?;
    serde_path_to_error::deserialize(document).map_err(|e| {
        let key = e.path().to_string();
        let key = if key == "." { String::new() } else { key };
        toml_error(text, key, &e.into_inner())
    })
}

/// A TOML reader's error at `key`, with the line of its span when it has one.
fn toml_error(text: &str, key: String, e: &toml::de::Error) -> DecodeError {
    DecodeError {
        key,
        line: e
            .span()
            .map(|s| text[..s.start.min(text.len())].lines().count().max(1)),
        // toml gives some syntax errors (a key with nothing after `=` at the end of the file) an
        // empty message.
        reason: match e.message().trim() {
            "" => "invalid TOML here: a value is missing, or the file is cut short".into(),
            m => m.to_string(),
        },
    }
}

/// Deserialise `text` as JSON into `T`, or say where and why not (model files written by other
/// tools: a linear plant exported from python-control, say).
pub fn from_json<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, DecodeError> {
    let mut de = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.into_inner();
        DecodeError {
            key: if key == "." { String::new() } else { key },
            line: (inner.line() > 0).then_some(inner.line()),
            reason: inner.to_string(),
        }
    })
}

#[cfg(test)]
mod tests {
    use std::os::unix::fs::symlink;

    #[test]
    fn a_fifo_is_refused_not_waited_on() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("plant.toml");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let e = super::read_text(&fifo).expect_err("refused");
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let e = super::read_own(&fifo, 10).expect_err("refused");
        assert!(e.to_string().contains("not a regular file"), "{e}");
    }

    #[test]
    fn a_run_file_is_read_only_if_it_is_no_link_and_has_one_name() {
        let dir = tempfile::tempdir().unwrap();
        let own = dir.path().join("response.png");
        std::fs::write(&own, b"ours").unwrap();
        assert_eq!(super::read_own(&own, 10).unwrap(), b"ours");
        let e = super::read_own(&own, 3).expect_err("too long");
        assert!(e.to_string().contains("more than the 3"), "{e}");
        let link = dir.path().join("zz.png");
        symlink(&own, &link).unwrap();
        let e = super::read_own(&link, 10).expect_err("a link");
        assert!(e.to_string().contains("symbolic link"), "{e}");
        let hard = dir.path().join("hard.png");
        std::fs::hard_link(&own, &hard).unwrap();
        let e = super::read_own(&hard, 10).expect_err("a hard link");
        assert!(e.to_string().contains("2 names"), "{e}");
        // Read through a link, a configuration is still fine.
        std::fs::remove_file(&hard).unwrap();
        assert_eq!(super::read_text(&link).unwrap(), "ours");
    }

    #[test]
    fn a_file_cut_short_after_an_equals_sign_gets_a_reason() {
        // Found by tests/fuzz_loaders.rs: toml 0.8's own message was empty here (0.9 says a
        // value is expected); either way the reason is never empty.
        let p = super::from_toml::<toml::Value>("a = 1\nb =")
            .map(|_| ())
            .expect_err("refused");
        assert_eq!(p.line, Some(2));
        assert!(!p.reason.trim().is_empty());
    }
}
