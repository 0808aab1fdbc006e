//! CSV, in one place: the tables evoloop writes (`Csv`, every study's and report's table;
//! `RunLog`, a run's fixed-capacity log; `write_row`, the streamed loop log's rows) and reads
//! back (`Table`). A number is written in its shortest exact decimal form (f64's `Display`), so
//! equal runs give byte-identical files and a reader gets the value back bit for bit; text is
//! quoted where RFC 4180 asks (a comma, a quote or a line break in it).

use std::fmt::Write as _;
use std::io::{BufRead, BufWriter, Write};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// One field of a `Csv` row.
pub trait Field {
    /// Append this field's text to `out`.
    fn put(&self, out: &mut String);
}

macro_rules! displayed {
    ($($t:ty),*) => {$(
        impl Field for $t {
            fn put(&self, out: &mut String) {
                let _ = write!(out, "{self}");
            }
        }
    )*};
}
// f64's Display is its shortest exact decimal form (NaN and inf as Rust spells them).
displayed!(f64, u8, u32, u64, usize, i32, i64);

/// A flag as 0 or 1.
impl Field for bool {
    fn put(&self, out: &mut String) {
        out.push(if *self { '1' } else { '0' });
    }
}

/// Text, quoted (its quotes doubled) where it holds a comma, a quote or a line break.
impl Field for str {
    fn put(&self, out: &mut String) {
        if self.contains([',', '"', '\n', '\r']) {
            out.push('"');
            out.push_str(&self.replace('"', "\"\""));
            out.push('"');
        } else {
            out.push_str(self);
        }
    }
}

impl Field for String {
    fn put(&self, out: &mut String) {
        self.as_str().put(out);
    }
}

impl<T: Field + ?Sized> Field for &T {
    fn put(&self, out: &mut String) {
        (**self).put(out);
    }
}

/// An empty field where there is no value.
impl<T: Field> Field for Option<T> {
    fn put(&self, out: &mut String) {
        if let Some(v) = self {
            v.put(out);
        }
    }
}

/// A number in scientific notation (`1.5e-9`): for columns whose values span many decades.
#[derive(Debug, Clone, Copy)]
pub struct Sci(pub f64);

impl Field for Sci {
    fn put(&self, out: &mut String) {
        let _ = write!(out, "{:e}", self.0);
    }
}

/// A CSV table built in memory and written whole (`evoloop_files::write`: never a cut file, no
/// link followed): a header, then rows of the header's width.
#[derive(Debug, Clone)]
pub struct Csv {
    text: String,
    width: usize,
    rows: usize,
    /// The first row whose width is not the header's, and its width.
    misshapen: Option<(usize, usize)>,
}

impl Csv {
    /// An empty table with the columns `header`.
    pub fn new<S: AsRef<str>>(header: impl IntoIterator<Item = S>) -> Self {
        let (text, width) = header_line(header);
        Self {
            text,
            width,
            rows: 0,
            misshapen: None,
        }
    }

    /// Start a row: its fields follow (`Row::put`, `Row::all`), and it ends where the `Row` is
    /// dropped (at the end of the statement that built it).
    pub fn row(&mut self) -> Row<'_> {
        Row {
            table: self,
            fields: 0,
        }
    }

    /// The table as text (header first, every row ended by a line break).
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// Write the table to `path`, whole.
    ///
    /// # Errors
    ///
    /// A row whose width is not the header's (`InvalidData`, naming the row; nothing written),
    /// or the write's error, which names the path.
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        if let Some((row, width)) = self.misshapen {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "{}: row {} has {width} fields, the header {}",
                    path.display(),
                    row + 1,
                    self.width
                ),
            ));
        }
        evoloop_files::write(path, &self.text)
    }
}

/// A header line of `names` (quoted where they must be, ended by a line break), and how many:
/// every table's, the streamed loop log's too.
pub fn header_line<S: AsRef<str>>(names: impl IntoIterator<Item = S>) -> (String, usize) {
    let mut text = String::new();
    let mut width = 0;
    for name in names {
        if width > 0 {
            text.push(',');
        }
        name.as_ref().put(&mut text);
        width += 1;
    }
    text.push('\n');
    (text, width)
}

/// One row of a `Csv` being written; it ends when dropped.
pub struct Row<'a> {
    table: &'a mut Csv,
    fields: usize,
}

impl Row<'_> {
    /// The next field.
    pub fn put(mut self, value: impl Field) -> Self {
        self.push(&value);
        self
    }

    /// The next fields, in order.
    pub fn all<T: Field>(mut self, values: impl IntoIterator<Item = T>) -> Self {
        for v in values {
            self.push(&v);
        }
        self
    }

    fn push(&mut self, value: &dyn Field) {
        if self.fields > 0 {
            self.table.text.push(',');
        }
        value.put(&mut self.table.text);
        self.fields += 1;
    }
}

impl Drop for Row<'_> {
    fn drop(&mut self) {
        let t = &mut *self.table;
        t.text.push('\n');
        if self.fields != t.width && t.misshapen.is_none() {
            t.misshapen = Some((t.rows, self.fields));
        }
        t.rows += 1;
    }
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
        w.write_all(header_line(&self.header).0.as_bytes())?;
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
pub(crate) fn numbered(name: &str, prefix: &str) -> bool {
    name.strip_prefix(prefix)
        .is_some_and(|rest| !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers come back bit for bit, text is quoted only where it must be, an absent value is
    /// an empty field, and a table with a row of the wrong width is refused, nothing written.
    #[test]
    fn a_table_writes_numbers_exactly_and_refuses_a_misshapen_row() {
        let mut csv = Csv::new(["name", "x", "n", "flag", "maybe", "sci"]);
        let x = 0.1 + 0.2;
        csv.row()
            .put("plain")
            .put(x)
            .put(3usize)
            .put(true)
            .put(None::<f64>)
            .put(Sci(1.5e-9));
        csv.row()
            .put("a, \"b\"")
            .put(f64::NAN)
            .put(0u64)
            .put(false)
            .put(Some(-2.5))
            .put(Sci(0.0));
        assert_eq!(
            csv.as_str(),
            "name,x,n,flag,maybe,sci\nplain,0.30000000000000004,3,1,,1.5e-9\n\"a, \"\"b\"\"\",NaN,0,0,-2.5,0e0\n"
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.csv");
        csv.write(&path).unwrap();
        let mut numbers = Csv::new(["a", "b"]);
        numbers.row().all([x, 1e300]);
        numbers.write(&path).unwrap();
        let back = Table::read(&path).unwrap();
        assert_eq!(back.rows[0][0].to_bits(), x.to_bits());
        numbers.row().put(1.0);
        numbers.row().all([1.0, 2.0]);
        let e = numbers.write(&dir.path().join("bad.csv")).unwrap_err();
        assert!(
            e.to_string().contains("row 2 has 1 fields, the header 2"),
            "{e}"
        );
        assert!(!dir.path().join("bad.csv").exists());
    }

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
