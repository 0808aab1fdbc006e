//! Reading the project's text inputs: files bounded in size, and TOML decoded with the key and
//! line of a problem. The configuration checks and the robot loaders (`evoloop-dynamics`) both
//! read through here, so neither needs the other for it.

use std::path::Path;

/// The largest configuration, robot or trajectory file read (16 MiB): a bound, so that
/// `evoloop check /dev/zero` or a wrong path to a huge file fails at once instead of reading
/// without end.
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// A text file, read up to `MAX_FILE_BYTES`.
pub fn read_text(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let mut text = String::new();
    std::fs::File::open(path)?
        .take(MAX_FILE_BYTES + 1)
        .read_to_string(&mut text)?;
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "larger than {} MiB: not a configuration, robot or trajectory file",
                MAX_FILE_BYTES >> 20
            ),
        ));
    }
    Ok(text)
}

/// What went wrong deserialising a TOML or JSON text: the dotted key (empty at file level), the
/// 1-based line when known, and a reason that is never empty.
pub struct Problem {
    pub key: String,
    pub line: Option<usize>,
    pub reason: String,
}

/// Deserialise `text` as TOML into `T`, or say where and why not (every TOML reader of the
/// project goes through here: scenarios, D-H tables, tuning experiments).
pub fn from_toml<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, Problem> {
    serde_path_to_error::deserialize(toml::Deserializer::new(text)).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.into_inner();
        Problem {
            key: if key == "." { String::new() } else { key },
            line: inner
                .span()
                .map(|s| text[..s.start.min(text.len())].lines().count().max(1)),
            // toml gives some syntax errors (a key with nothing after `=` at the end of the
            // file) an empty message.
            reason: match inner.message().trim() {
                "" => "invalid TOML here: a value is missing, or the file is cut short".into(),
                m => m.to_string(),
            },
        }
    })
}

/// Deserialise `text` as JSON into `T`, or say where and why not (model files written by other
/// tools: a linear plant exported from python-control, say).
pub fn from_json<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, Problem> {
    let mut de = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let key = e.path().to_string();
        let inner = e.into_inner();
        Problem {
            key: if key == "." { String::new() } else { key },
            line: (inner.line() > 0).then_some(inner.line()),
            reason: inner.to_string(),
        }
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_file_cut_short_after_an_equals_sign_gets_a_reason() {
        // Found by tests/fuzz_loaders.rs: toml's own message is empty here.
        let p = super::from_toml::<toml::Value>("a = 1\nb =")
            .map(|_| ())
            .expect_err("refused");
        assert_eq!(p.line, Some(2));
        assert!(p.reason.contains("value is missing"), "{}", p.reason);
    }
}
