//! The control loop's log, streamed to disk while the run goes on.
//!
//! The control thread puts each cycle's row into a fixed ring (`Ring`: no allocation, no lock,
//! no system call); a writer thread of ordinary priority drains it into CSV files every few
//! milliseconds and flushes them. Memory is the ring's, whatever the run's duration (it used to
//! be the whole run's log, allocated and locked up front: 1.9 GB for 20 000 s), and a killed or
//! failed run leaves on disk everything it logged up to a few milliseconds before its end.
//!
//! When the ring is full (the disk stalled longer than the ring holds), `Overflow::Drop` counts
//! and drops the row, so a real-time loop never waits on the disk; `Overflow::Wait` waits for
//! room, so a lockstep run, whose results must not depend on the writer's speed, loses nothing.

use super::write_row;
use std::io::{BufWriter, Write};
use std::ops::Range;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

/// A single-producer single-consumer ring of fixed-width f64 rows.
pub struct Ring {
    width: usize,
    capacity: u64,
    /// Row-major slots; f64 bits in atomics so both threads may touch them without `unsafe`
    /// (relaxed stores and loads are plain moves on x86-64 and aarch64).
    slots: Box<[AtomicU64]>,
    /// Rows ever pushed (written by the producer only).
    head: AtomicU64,
    /// Rows ever taken (written by the consumer only).
    tail: AtomicU64,
}

impl Ring {
    /// An empty ring of `capacity` rows (at least 1) of `width` values, allocated now.
    pub fn new(width: usize, capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            width,
            capacity: capacity as u64,
            slots: (0..width * capacity).map(|_| AtomicU64::new(0)).collect(),
            head: AtomicU64::new(0),
            tail: AtomicU64::new(0),
        }
    }

    /// Values per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Append a row (`row.len()` is the width); false when the ring is full. Producer only.
    #[inline]
    pub fn try_push(&self, row: &[f64]) -> bool {
        debug_assert_eq!(row.len(), self.width);
        let h = self.head.load(Ordering::Relaxed);
        if h - self.tail.load(Ordering::Acquire) >= self.capacity {
            return false;
        }
        let base = (h % self.capacity) as usize * self.width;
        for (slot, v) in self.slots[base..base + self.width].iter().zip(row) {
            slot.store(v.to_bits(), Ordering::Relaxed);
        }
        // Publishes the row's slots to the consumer.
        self.head.store(h + 1, Ordering::Release);
        true
    }

    /// Take the oldest row into `out`; false when the ring is empty. Consumer only.
    pub fn pop_into(&self, out: &mut [f64]) -> bool {
        let t = self.tail.load(Ordering::Relaxed);
        if t == self.head.load(Ordering::Acquire) {
            return false;
        }
        let base = (t % self.capacity) as usize * self.width;
        for (o, slot) in out.iter_mut().zip(&self.slots[base..base + self.width]) {
            *o = f64::from_bits(slot.load(Ordering::Relaxed));
        }
        // Hands the slot back to the producer.
        self.tail.store(t + 1, Ordering::Release);
        true
    }
}

/// What to do with a row when the ring is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overflow {
    /// Count and drop it (real time: the loop never waits on the disk).
    Drop,
    /// Wait for the writer to make room (lockstep: nothing is lost).
    Wait,
}

/// One CSV file of the stream: its path, header, and the columns of each row it takes.
pub struct CsvPart {
    /// The CSV file to create.
    pub path: PathBuf,
    /// Its column names, written as its first line.
    pub header: Vec<String>,
    /// The range of each logged row's values this file takes, in header order.
    pub columns: Range<usize>,
}

/// How the writer ended.
#[derive(Debug, Default)]
pub struct Written {
    /// Rows taken from the ring, the ones discarded after a write error included.
    pub rows: u64,
    /// The first write error, if any (rows after it were taken from the ring and discarded, so
    /// the loop never blocked on a broken disk).
    pub error: Option<String>,
}

/// A ring drained by a writer thread into CSV files.
pub struct LogStream {
    ring: Arc<Ring>,
    done: Arc<AtomicBool>,
    writer: Option<JoinHandle<Written>>,
    overflow: Overflow,
    /// Rows dropped because the ring was full (`Overflow::Drop` only).
    pub dropped: u64,
}

/// How long the writer sleeps when it finds the ring empty.
const IDLE: Duration = Duration::from_millis(5);

impl LogStream {
    /// Create the files (headers written at once, so an unwritable output fails before the
    /// run starts) and start the writer. Rows are `parts`' columns end to end.
    pub fn start(
        parts: Vec<CsvPart>,
        capacity_rows: usize,
        overflow: Overflow,
    ) -> std::io::Result<Self> {
        let width = parts.iter().map(|p| p.columns.end).max().unwrap_or(0);
        let mut files = Vec::with_capacity(parts.len());
        for p in &parts {
            let f = evoloop_files::create(&p.path)?;
            let mut w = BufWriter::with_capacity(1 << 16, f);
            w.write_all(crate::csv::header_line(&p.header).0.as_bytes())?;
            w.flush()?;
            files.push((w, p.columns.clone()));
        }
        let ring = Arc::new(Ring::new(width, capacity_rows));
        let done = Arc::new(AtomicBool::new(false));
        let (r, d) = (ring.clone(), done.clone());
        let writer = std::thread::Builder::new()
            .name("log-writer".into())
            .spawn(move || drain(&r, &d, files))?;
        Ok(Self {
            ring,
            done,
            writer: Some(writer),
            overflow,
            dropped: 0,
        })
    }

    /// Log one row. No allocation, no lock; with `Overflow::Wait` it may yield while full.
    #[inline]
    pub fn push(&mut self, row: &[f64]) {
        while !self.ring.try_push(row) {
            match self.overflow {
                Overflow::Drop => {
                    self.dropped += 1;
                    return;
                }
                Overflow::Wait => std::thread::yield_now(),
            }
        }
    }

    /// Drain what is left, flush and close the files.
    pub fn finish(mut self) -> Written {
        self.stop()
    }

    fn stop(&mut self) -> Written {
        self.done.store(true, Ordering::Release);
        match self.writer.take().map(JoinHandle::join) {
            Some(Ok(w)) => w,
            Some(Err(_)) => Written {
                rows: 0,
                error: Some("the log writer panicked".into()),
            },
            None => Written::default(),
        }
    }
}

impl Drop for LogStream {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The writer thread: take rows while there are any, flush when the ring runs dry, sleep a
/// little, and after `done` take the rest.
fn drain(
    ring: &Ring,
    done: &AtomicBool,
    mut files: Vec<(BufWriter<std::fs::File>, Range<usize>)>,
) -> Written {
    let mut row = vec![0.0; ring.width()];
    let mut out = Written::default();
    loop {
        // Read before draining: rows pushed before `done` was set are then all visible.
        let last = done.load(Ordering::Acquire);
        let mut took = false;
        while ring.pop_into(&mut row) {
            took = true;
            out.rows += 1;
            if out.error.is_none() {
                for (w, cols) in files.iter_mut() {
                    if let Err(e) = write_row(w, &row[cols.clone()]) {
                        out.error = Some(e.to_string());
                    }
                }
            }
        }
        if took && out.error.is_none() {
            for (w, _) in files.iter_mut() {
                if let Err(e) = w.flush() {
                    out.error = Some(e.to_string());
                }
            }
        }
        if last {
            return out;
        }
        if !took {
            std::thread::sleep(IDLE);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ring_hands_over_rows_in_order_and_refuses_when_full() {
        let r = Ring::new(2, 3);
        let mut out = [0.0; 2];
        assert!(!r.pop_into(&mut out));
        for i in 0..3 {
            assert!(r.try_push(&[i as f64, -(i as f64)]));
        }
        assert!(!r.try_push(&[9.0, 9.0]), "full at its capacity");
        assert!(r.pop_into(&mut out));
        assert_eq!(out, [0.0, -0.0]);
        assert!(r.try_push(&[3.0, -3.0]), "room again after one is taken");
        for i in 1..4 {
            assert!(r.pop_into(&mut out));
            assert_eq!(out, [i as f64, -(i as f64)]);
        }
        assert!(!r.pop_into(&mut out));
    }

    #[test]
    fn a_stream_through_a_small_ring_loses_nothing_when_it_waits() {
        let dir = tempfile::tempdir().unwrap();
        let parts = vec![
            CsvPart {
                path: dir.path().join("a.csv"),
                header: vec!["x".into(), "y".into()],
                columns: 0..2,
            },
            CsvPart {
                path: dir.path().join("b.csv"),
                header: vec!["z".into()],
                columns: 2..3,
            },
        ];
        // 8 rows of room for 100 000 rows: the producer must wait for the writer many times.
        let mut s = LogStream::start(parts, 8, Overflow::Wait).unwrap();
        let n = 100_000;
        for i in 0..n {
            let v = i as f64;
            s.push(&[v, 0.5 * v, -v]);
        }
        let w = s.finish();
        assert_eq!((w.rows, w.error), (n, None));
        let a = std::fs::read_to_string(dir.path().join("a.csv")).unwrap();
        let b = std::fs::read_to_string(dir.path().join("b.csv")).unwrap();
        let a: Vec<&str> = a.lines().collect();
        let b: Vec<&str> = b.lines().collect();
        assert_eq!((a.len(), b.len()), (n as usize + 1, n as usize + 1));
        assert_eq!((a[0], b[0]), ("x,y", "z"));
        assert_eq!(a[77778], "77777,38888.5");
        assert_eq!(b[n as usize], "-99999");
    }

    #[test]
    fn a_full_ring_drops_and_counts_when_told_to() {
        let dir = tempfile::tempdir().unwrap();
        let part = CsvPart {
            path: dir.path().join("a.csv"),
            header: vec!["x".into()],
            columns: 0..1,
        };
        let mut s = LogStream::start(vec![part], 4, Overflow::Drop).unwrap();
        // Faster than any writer: most of a million rows cannot fit in 4 slots.
        for i in 0..1_000_000 {
            s.push(&[i as f64]);
        }
        let dropped = s.dropped;
        let w = s.finish();
        assert!(dropped > 0, "nothing dropped");
        assert_eq!(w.rows + dropped, 1_000_000, "every row written or counted");
        let lines = std::fs::read_to_string(dir.path().join("a.csv"))
            .unwrap()
            .lines()
            .count();
        assert_eq!(lines as u64, w.rows + 1);
    }

    #[test]
    fn an_unwritable_file_is_an_error_at_start() {
        let part = CsvPart {
            path: PathBuf::from("/nonexistent-dir/run.csv"),
            header: vec!["x".into()],
            columns: 0..1,
        };
        let e = LogStream::start(vec![part], 4, Overflow::Drop)
            .err()
            .expect("refused");
        assert!(e.to_string().contains("/nonexistent-dir/run.csv"), "{e}");
    }
}
