//! Run records and the report's materials: the fixed-capacity logs the processes fill during a
//! run, CSV writing/reading, the MCAP recording and its reader, response metrics (settling time,
//! overshoot, IAE, ISE), plots, the HTML page and progress bars. A sink: it takes data and never
//! runs a simulation; the run's report (`evoloop::run_report::build`, which does) sits above.

pub mod csv;
pub mod history;
pub mod html;
pub mod mcap_file;
pub mod metrics;
pub mod plot;
pub mod progress;
pub mod record;
pub mod recording;
pub mod ros2;
pub mod scan;
pub mod stream;

use std::path::Path;

pub use csv::{cut_partial_row, write_row, Csv, RunLog, Table};

/// How a run ended: summary.json's `outcome`, serialised as the strings scripts read.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// It ran to its end (a run until stopped that is stopped: that is its end). The default
    /// only of a `Summary` built in code (`..Default::default()`): when read, `outcome` is
    /// required.
    #[default]
    Ok,
    /// Ctrl-C before the scenario's duration: what ran so far.
    Interrupted,
    /// A process failed; the launcher writes a short summary.json with the reasons.
    Failed,
    /// Something could not be written (a full disk): what was written is whole.
    Incomplete,
    /// The loop ran to its end with its set in service, the optimiser lost on the way.
    TunerLost,
    /// The run went to its end but its loop did not control the plant for most of it (most
    /// samples refused, most deadlines missed); `degraded` in the summary says why.
    Degraded,
}

/// Print `value` as pretty JSON on stdout (for `--json`), ignoring a closed pipe.
pub fn print_json(value: &impl serde::Serialize) {
    use std::io::Write;
    let text = serde_json::to_string_pretty(value).unwrap_or_default();
    let _ = writeln!(std::io::stdout(), "{text}");
}

/// Write `value` as pretty JSON to `dir/name`.
pub fn write_json<T: serde::Serialize>(dir: &Path, name: &str, value: &T) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let text = serde_json::to_string_pretty(value).map_err(std::io::Error::other)?;
    evoloop_files::write(dir.join(name), text + "\n")
}

/// A JSON file a run wrote (`write_json`) read back: only the run's own (no link planted in its
/// directory, a regular file of this user with one name), up to `MAX_DATA_BYTES`. The error
/// names the file.
pub fn read_json<T: serde::de::DeserializeOwned>(
    dir: &Path,
    name: &str,
) -> Result<T, ReadJsonError> {
    let file = dir.join(name);
    match evoloop_files::read_own(&file, evoloop_files::MAX_DATA_BYTES) {
        Ok(bytes) => {
            serde_json::from_slice(&bytes).map_err(|source| ReadJsonError::Parse { file, source })
        }
        Err(source) => Err(ReadJsonError::Read { file, source }),
    }
}

/// `error` on `file`, the file named once: `evoloop_files`' errors name it already (and some
/// system errors do not).
pub fn with_path(
    f: &mut std::fmt::Formatter<'_>,
    file: &Path,
    error: &dyn std::fmt::Display,
) -> std::fmt::Result {
    let (p, message) = (file.display().to_string(), error.to_string());
    if message.contains(&p) {
        f.write_str(&message)
    } else {
        write!(f, "{p}: {message}")
    }
}

/// Why a run's JSON file cannot be read back.
#[derive(Debug)]
pub enum ReadJsonError {
    /// Missing, refused (a link, another user's file, too large) or unreadable.
    Read {
        /// The file.
        file: std::path::PathBuf,
        /// The system's reason, or `evoloop_files::read_own`'s refusal.
        source: std::io::Error,
    },
    /// Not the JSON expected.
    Parse {
        /// The file.
        file: std::path::PathBuf,
        /// The parser's reason.
        source: serde_json::Error,
    },
}

impl ReadJsonError {
    /// Whether the file is not there (a run that stopped before writing it).
    pub fn is_missing(&self) -> bool {
        matches!(self, ReadJsonError::Read { source, .. } if source.kind() == std::io::ErrorKind::NotFound)
    }
}

impl std::fmt::Display for ReadJsonError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadJsonError::Read { file, source } => with_path(f, file, source),
            ReadJsonError::Parse { file, source } => write!(f, "{}: {source}", file.display()),
        }
    }
}

impl std::error::Error for ReadJsonError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ReadJsonError::Read { source, .. } => Some(source),
            ReadJsonError::Parse { source, .. } => Some(source),
        }
    }
}

#[cfg(test)]
mod outcome_tests {
    use super::Outcome;

    #[test]
    fn outcomes_serialise_to_the_strings_scripts_read() {
        for (o, text) in [
            (Outcome::Ok, "ok"),
            (Outcome::Interrupted, "interrupted"),
            (Outcome::Failed, "failed"),
            (Outcome::Incomplete, "incomplete"),
            (Outcome::TunerLost, "tuner_lost"),
            (Outcome::Degraded, "degraded"),
        ] {
            let json = serde_json::to_string(&o).unwrap();
            assert_eq!(json, format!("\"{text}\""));
            assert_eq!(serde_json::from_str::<Outcome>(&json).unwrap(), o);
        }
        assert!(serde_json::from_str::<Outcome>("\"exploded\"").is_err());
    }
}
