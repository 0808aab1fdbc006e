//! run.csv read in bounded memory: the report after a run (which may have had no end) reads the
//! rows one at a time, twice (first its extent, then the metrics), and keeps for its plots at
//! most `PLOT_EXACT` rows, or past that the envelope of each column over `PLOT_BUCKETS` buckets.

use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Runs up to this many rows are plotted sample by sample.
pub const PLOT_EXACT: usize = 200_000;
/// Longer runs are plotted as this many buckets (the plots are 1200 px wide), each drawn as its
/// first and last time with each column's minimum and maximum over the bucket, in the order
/// they occurred (a monotone stretch stays a monotone line): the envelope a full-resolution
/// line would paint.
pub const PLOT_BUCKETS: usize = 4096;

/// A CSV of numbers with a header line, one row at a time.
pub struct Rows {
    path: PathBuf,
    lines: std::io::Lines<std::io::BufReader<std::fs::File>>,
    /// Column names, from the file's first line (empty for an empty file).
    pub header: Vec<String>,
    row: Vec<f64>,
    line: usize,
}

impl Rows {
    /// Open the CSV at `path` and read its header line; rows are read by `next`.
    ///
    /// # Errors
    ///
    /// The file cannot be opened or its first line read.
    pub fn open(path: &Path) -> std::io::Result<Self> {
        let mut lines = std::io::BufReader::new(std::fs::File::open(path)?).lines();
        let header = match lines.next() {
            Some(h) => h?.split(',').map(str::to_string).collect(),
            None => Vec::new(),
        };
        Ok(Self {
            path: path.to_path_buf(),
            lines,
            header,
            row: Vec::new(),
            line: 1,
        })
    }

    /// The next row (blank lines skipped), or None at the end.
    #[allow(clippy::should_implement_trait)] // lends its buffer: not an Iterator
    pub fn next(&mut self) -> std::io::Result<Option<&[f64]>> {
        match self.next_line()? {
            Some(line) => {
                self.parse(&line)?;
                Ok(Some(&self.row))
            }
            None => Ok(None),
        }
    }

    /// The next non-blank line, unparsed.
    fn next_line(&mut self) -> std::io::Result<Option<String>> {
        for line in self.lines.by_ref() {
            let line = line?;
            self.line += 1;
            if !line.is_empty() {
                return Ok(Some(line));
            }
        }
        Ok(None)
    }

    /// `line` (number `self.line`) into `self.row`.
    fn parse(&mut self, line: &str) -> std::io::Result<()> {
        let bad = |why: String| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{}: line {}: {why}", self.path.display(), self.line),
            )
        };
        self.row.clear();
        for field in line.split(',') {
            self.row
                .push(field.parse::<f64>().map_err(|e| bad(e.to_string()))?);
        }
        if self.row.len() != self.header.len() {
            return Err(bad(format!(
                "{} fields under a header of {}",
                self.row.len(),
                self.header.len()
            )));
        }
        Ok(())
    }

    /// The index of the column named `name`, if there is one.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.header.iter().position(|h| h == name)
    }

    /// Columns named `prefix` and digits (y0, y1, ...), in header order: (name, index).
    pub fn indices_with_prefix(&self, prefix: &str) -> Vec<(String, usize)> {
        self.header
            .iter()
            .enumerate()
            .filter(|(_, h)| crate::csv::numbered(h, prefix))
            .map(|(i, h)| (h.clone(), i))
            .collect()
    }
}

/// What the first pass learns: the number of rows and the last one.
#[derive(Debug, Clone, Default)]
pub struct Extent {
    /// Rows in the file (the header and blank lines not counted).
    pub rows: usize,
    /// The last row's values (empty when there is no row).
    pub last: Vec<f64>,
}

impl Extent {
    /// Counts the lines and parses only the last (the second pass parses every row).
    pub fn of(path: &Path) -> std::io::Result<Self> {
        let mut rows = Rows::open(path)?;
        let (mut count, mut last) = (0, None);
        while let Some(line) = rows.next_line()? {
            count += 1;
            last = Some((rows.line, line));
        }
        if let Some((number, line)) = last {
            rows.line = number;
            rows.parse(&line)?;
        }
        Ok(Extent {
            rows: count,
            last: rows.row,
        })
    }
}

/// Columns for a plot over a shared time axis, of bounded length whatever the run's.
pub struct PlotColumns {
    /// Rows per bucket (1: every row as it is).
    bucket: usize,
    /// The time axis: every row's time, or each bucket's first and last time.
    pub t: Vec<f64>,
    /// Each column's values at the times of `t`: every row's, or each bucket's minimum and maximum
    /// in the order they occurred.
    pub columns: Vec<Vec<f64>>,
    in_bucket: usize,
    t_first: f64,
    t_last: f64,
    lo: Vec<f64>,
    hi: Vec<f64>,
    /// Whether each column's maximum so far came after its minimum.
    rising: Vec<bool>,
}

impl PlotColumns {
    /// For `columns` columns of a run of `rows` rows.
    pub fn new(rows: usize, columns: usize) -> Self {
        let bucket = if rows <= PLOT_EXACT {
            1
        } else {
            rows.div_ceil(PLOT_BUCKETS)
        };
        let points = if bucket == 1 { rows } else { 2 * PLOT_BUCKETS };
        Self {
            bucket,
            t: Vec::with_capacity(points),
            columns: (0..columns).map(|_| Vec::with_capacity(points)).collect(),
            in_bucket: 0,
            t_first: 0.0,
            t_last: 0.0,
            lo: vec![f64::INFINITY; columns],
            hi: vec![f64::NEG_INFINITY; columns],
            rising: vec![true; columns],
        }
    }

    /// Whether the columns are every row as it is.
    pub fn exact(&self) -> bool {
        self.bucket == 1
    }

    /// Add the next row: its time `t` and the plotted columns' `values`, one per column.
    pub fn push(&mut self, t: f64, values: &[f64]) {
        if self.bucket == 1 {
            self.t.push(t);
            for (c, v) in self.columns.iter_mut().zip(values) {
                c.push(*v);
            }
            return;
        }
        if self.in_bucket == 0 {
            self.t_first = t;
        }
        self.t_last = t;
        for (((lo, hi), rising), v) in self
            .lo
            .iter_mut()
            .zip(&mut self.hi)
            .zip(&mut self.rising)
            .zip(values)
        {
            if *v < *lo {
                *lo = *v;
                *rising = false;
            }
            if *v > *hi {
                *hi = *v;
                *rising = true;
            }
        }
        self.in_bucket += 1;
        if self.in_bucket == self.bucket {
            self.flush();
        }
    }

    fn flush(&mut self) {
        if self.in_bucket == 0 {
            return;
        }
        self.t.push(self.t_first);
        self.t.push(self.t_last);
        for (((c, lo), hi), rising) in self
            .columns
            .iter_mut()
            .zip(&mut self.lo)
            .zip(&mut self.hi)
            .zip(&self.rising)
        {
            let (first, second) = if *rising { (*lo, *hi) } else { (*hi, *lo) };
            c.push(first);
            c.push(second);
            *lo = f64::INFINITY;
            *hi = f64::NEG_INFINITY;
        }
        self.in_bucket = 0;
    }

    /// The time axis and the columns, the last partial bucket included.
    pub fn finish(mut self) -> (Vec<f64>, Vec<Vec<f64>>) {
        self.flush();
        (self.t, self.columns)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_runs_are_plotted_as_they_are() {
        let mut p = PlotColumns::new(5, 2);
        for k in 0..5 {
            p.push(k as f64, &[k as f64, -(k as f64)]);
        }
        let (t, c) = p.finish();
        assert_eq!(t, vec![0.0, 1.0, 2.0, 3.0, 4.0]);
        assert_eq!(c[1], vec![0.0, -1.0, -2.0, -3.0, -4.0]);
    }

    #[test]
    fn long_runs_keep_each_columns_envelope_in_bounded_points() {
        let rows = 3 * PLOT_EXACT + 7;
        let mut p = PlotColumns::new(rows, 1);
        assert!(!p.exact());
        // Spikes every 7th row, which a thinned series (every k-th row) would mostly miss.
        let v = |k: usize| if k % 7 == 3 { 1000.0 } else { -1.0 };
        for k in 0..rows {
            p.push(k as f64, &[v(k)]);
        }
        let (t, c) = p.finish();
        assert!(t.len() <= 2 * PLOT_BUCKETS, "{}", t.len());
        assert_eq!(t.len(), c[0].len());
        assert_eq!(t[0], 0.0);
        assert_eq!(*t.last().unwrap(), (rows - 1) as f64);
        assert!(t.windows(2).all(|w| w[0] <= w[1]));
        // Every bucket spans both extremes of the signal.
        for pair in c[0].chunks(2) {
            let (lo, hi) = (pair[0].min(pair[1]), pair[0].max(pair[1]));
            assert_eq!((lo, hi), (-1.0, 1000.0), "{pair:?}");
        }
    }

    #[test]
    fn a_monotone_stretch_stays_monotone_in_the_envelope() {
        let rows = 2 * PLOT_EXACT;
        let mut p = PlotColumns::new(rows, 2);
        for k in 0..rows {
            let x = k as f64;
            p.push(x, &[x, -x]);
        }
        let (_, c) = p.finish();
        assert!(c[0].windows(2).all(|w| w[0] <= w[1]), "rising");
        assert!(c[1].windows(2).all(|w| w[0] >= w[1]), "falling");
    }

    #[test]
    fn rows_are_read_one_at_a_time_with_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("run.csv");
        evoloop_files::write(&p, "t,y0,y1,u0\n0,1,2,3\n\n0.5,4,5,6\n1,x,2,3\n").unwrap();
        let mut r = Rows::open(&p).unwrap();
        assert_eq!(
            r.indices_with_prefix("y"),
            vec![("y0".into(), 1), ("y1".into(), 2)]
        );
        assert_eq!(r.next().unwrap(), Some(&[0.0, 1.0, 2.0, 3.0][..]));
        assert_eq!(r.next().unwrap(), Some(&[0.5, 4.0, 5.0, 6.0][..]));
        let e = r.next().unwrap_err().to_string();
        assert!(e.contains("run.csv: line 5"), "{e}");
        evoloop_files::write(&p, "t,y0\n0,1,2\n").unwrap();
        let e = Extent::of(&p).unwrap_err().to_string();
        assert!(e.contains("3 fields under a header of 2"), "{e}");
    }
}
