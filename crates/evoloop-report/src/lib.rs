//! Run records and the report's materials: the fixed-capacity logs the processes fill during a
//! run, CSV writing/reading, the MCAP recording and its reader, response metrics (settling time,
//! overshoot, IAE, ISE), plots, the HTML page and progress bars. A sink: it takes data and never
//! runs a simulation; the run's report (`evoloop::run_report::build`, which does) sits above.

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

use std::io::{BufRead, BufWriter, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

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
pub fn read_json<T: serde::de::DeserializeOwned>(dir: &Path, name: &str) -> Result<T, String> {
    let p = dir.join(name);
    let bytes = evoloop_files::read_own(&p, evoloop_files::MAX_DATA_BYTES).map_err(|e| {
        // The refusals name the file already; "not found" does not.
        if e.kind() == std::io::ErrorKind::NotFound {
            format!("{}: {e}", p.display())
        } else {
            e.to_string()
        }
    })?;
    serde_json::from_slice(&bytes).map_err(|e| format!("{}: {e}", p.display()))
}

/// A table of f64 rows with fixed width and capacity, allocated up front so recording a row
/// never allocates; rows beyond the capacity are counted, not stored. (The control loop streams
/// its log instead: `stream`.)
pub struct RunLog {
    header: Vec<String>,
    data: Vec<f64>,
    capacity_rows: usize,
    /// Rows pushed after the capacity was full, counted and not stored.
    pub dropped: u64,
}

impl RunLog {
    /// An empty log with columns `header`, room for `rows` rows allocated now.
    pub fn new(header: Vec<String>, rows: usize) -> Self {
        Self {
            data: Vec::with_capacity(rows * header.len()),
            header,
            capacity_rows: rows,
            dropped: 0,
        }
    }

    /// Columns per row (the header's length).
    pub fn width(&self) -> usize {
        self.header.len()
    }

    /// Rows stored (the dropped ones not counted).
    pub fn len(&self) -> usize {
        self.data.len() / self.header.len().max(1)
    }

    /// Whether no row is stored.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Append one row (`row.len()` must equal the width). No allocation.
    #[inline]
    pub fn push(&mut self, row: &[f64]) {
        debug_assert_eq!(row.len(), self.header.len());
        if self.len() < self.capacity_rows {
            self.data.extend_from_slice(row);
        } else {
            self.dropped += 1;
        }
    }

    /// Row `i` as a slice of `width()` values; `i` must be below `len()`.
    pub fn row(&self, i: usize) -> &[f64] {
        let w = self.width();
        &self.data[i * w..(i + 1) * w]
    }

    /// Write as CSV with the shortest exact decimal form of each number, so equal runs give
    /// byte-identical files.
    pub fn write_csv(&self, path: &Path) -> std::io::Result<()> {
        let mut w = BufWriter::new(evoloop_files::create(path)?);
        writeln!(w, "{}", self.header.join(","))?;
        for i in 0..self.len() {
            write_row(&mut w, self.row(i))?;
        }
        w.flush()
    }
}

/// One CSV line: each number in its shortest exact decimal form (Rust's `Display` for f64), so
/// equal runs give byte-identical files.
pub fn write_row(w: &mut impl Write, row: &[f64]) -> std::io::Result<()> {
    for (j, v) in row.iter().enumerate() {
        if j > 0 {
            w.write_all(b",")?;
        }
        write!(w, "{v}")?;
    }
    w.write_all(b"\n")
}

/// Drop a last line that does not end in a newline (a row cut short by a kill or a full disk):
/// the file then holds only whole rows. A missing file is left alone. Returns whether it cut.
pub fn cut_partial_row(path: &Path) -> std::io::Result<bool> {
    use std::io::{Read, Seek, SeekFrom};
    let mut f = match std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(path)
    {
        Ok(f) => f,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(false),
        Err(e) => return Err(e),
    };
    let len = f.metadata()?.len();
    // Rows are a few hundred bytes at most; look back far enough for the longest.
    let back = len.min(1 << 16);
    f.seek(SeekFrom::Start(len - back))?;
    let mut tail = Vec::with_capacity(back as usize);
    f.read_to_end(&mut tail)?;
    if tail.last().is_none_or(|&b| b == b'\n') {
        return Ok(false);
    }
    let keep = tail.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    f.set_len(len - back + keep as u64)?;
    Ok(true)
}

/// A CSV table read back: header and columns.
pub struct Table {
    /// Column names, from the file's first line.
    pub header: Vec<String>,
    /// The rows after the header, each with one value per column; blank lines skipped.
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Read the CSV file at `path`: a header line, then rows of numbers.
    ///
    /// # Errors
    ///
    /// The file cannot be read, or a row holds a value that is not a number or a count of values
    /// other than the header's (`InvalidData`, with the line number).
    pub fn read(path: &Path) -> std::io::Result<Table> {
        let f = std::io::BufReader::new(std::fs::File::open(path)?);
        let mut lines = f.lines();
        let header: Vec<String> = match lines.next() {
            Some(h) => h?.split(',').map(str::to_string).collect(),
            None => Vec::new(),
        };
        let mut rows = Vec::new();
        for (i, line) in lines.enumerate() {
            let line = line?;
            if line.is_empty() {
                continue;
            }
            let bad = |why: String| {
                std::io::Error::new(
                    std::io::ErrorKind::InvalidData,
                    format!("{}: line {}: {why}", path.display(), i + 2),
                )
            };
            let row: Vec<f64> = line
                .split(',')
                .map(str::parse::<f64>)
                .collect::<Result<_, _>>()
                .map_err(|e| bad(e.to_string()))?;
            // A row cut short (a full disk, a killed writer) would index past its end later.
            if row.len() != header.len() {
                return Err(bad(format!(
                    "{} values, the header has {} (the file is cut short or damaged)",
                    row.len(),
                    header.len()
                )));
            }
            rows.push(row);
        }
        Ok(Table { header, rows })
    }

    /// Column by header name.
    pub fn col(&self, name: &str) -> Option<Vec<f64>> {
        let j = self.header.iter().position(|h| h == name)?;
        Some(self.rows.iter().map(|r| r[j]).collect())
    }

    /// Columns whose names start with `prefix` followed by a digit (y0, y1, ...).
    pub fn cols_with_prefix(&self, prefix: &str) -> Vec<(String, Vec<f64>)> {
        self.header
            .iter()
            .filter(|h| numbered(h, prefix))
            .map(|h| (h.clone(), self.col(h).unwrap_or_default()))
            .collect()
    }
}

/// Whether column `name` is `prefix` followed by digits (y0, y1, ...).
fn numbered(name: &str, prefix: &str) -> bool {
    name.strip_prefix(prefix)
        .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
}

#[cfg(test)]
mod tests {
    use super::{cut_partial_row, Table};

    #[test]
    fn a_table_with_a_row_cut_short_is_an_error_naming_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("run.csv");
        evoloop_files::write(&path, "t,y0,u0\n0,1,2\n0.001,1.5,2.5\n").unwrap();
        let t = Table::read(&path).unwrap();
        assert_eq!(t.rows.len(), 2);
        assert_eq!(t.col("u0"), Some(vec![2.0, 2.5]));
        // What a full disk leaves: the last row cut inside a field's boundary.
        evoloop_files::write(&path, "t,y0,u0\n0,1,2\n0.001,1.5\n").unwrap();
        let e = Table::read(&path)
            .err()
            .expect("a cut row must be refused")
            .to_string();
        assert!(e.contains("line 3") && e.contains("cut short"), "{e}");
        // What a kill between flushes leaves, and what the launcher does with it after the
        // run: the cut row goes, the whole ones stay readable.
        evoloop_files::write(&path, "t,y0,u0\n0,1,2\n0.001,1.").unwrap();
        assert!(Table::read(&path).is_err());
        assert!(cut_partial_row(&path).unwrap());
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "t,y0,u0\n0,1,2\n");
        assert_eq!(Table::read(&path).unwrap().rows.len(), 1);
        assert!(
            !cut_partial_row(&path).unwrap(),
            "a whole file is left as it is"
        );
        assert!(!cut_partial_row(&dir.path().join("none.csv")).unwrap());
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
