//! `evoloop soak`: a long realtime run with the optimiser tuning, watched from outside.
//!
//! Every interval (a minute by default) it records the resident memory of every process of the
//! run (launcher, plant, controller, optimiser: from /proc, found by the run id on their command
//! lines, so a restarted optimiser is followed), and from the lines the controller has streamed
//! to `timing.csv` since the last look: cycles, missed deadlines (whole periods a late wake-up
//! skipped), overruns and lateness percentiles. It lists the run's shared-memory files before
//! the start and after the end. The result: `soak.json`, `soak.csv` (one row per interval),
//! `soak_rss.png` and `soak_timing.png`, beside the run's own report in `<out>/run/`.
//!
//! It watches without touching the run: no iceoryx2 port, only /proc and the streamed file.

use crate::msg::TELEMETRY_FLAG_OVERRUN;
use crate::report::Csv;
use crate::rt::timing::{Accumulator, Percentiles};
use evoloop_schemes::WriteError;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

/// The processes of a run, by the name their command line starts with.
pub const PROCESSES: [&str; 4] = [
    "evoloop",
    "evoloop-plant",
    "evoloop-controller",
    "evoloop-optimiser",
];

/// One interval of the soak.
#[derive(Debug, Clone, Serialize)]
pub struct Interval {
    /// The interval's number, from 0.
    pub index: usize,
    /// Wall time since the start at the end of the interval, s.
    pub t_s: f64,
    /// Resident memory per process (KiB); a process not running at that moment is absent.
    pub rss_kib: BTreeMap<String, u64>,
    /// Anonymous resident memory per process (RssAnon, KiB): the heap and stacks, without the
    /// binary's and libraries' pages, which mlockall makes resident at once; a leak shows here.
    pub anon_kib: BTreeMap<String, u64>,
    /// Control cycles timing.csv recorded in the interval.
    pub cycles: u64,
    /// Whole periods that late wake-ups skipped in the interval: the missed deadlines.
    pub missed_deadlines: u64,
    /// Cycles in the interval whose lateness plus compute time exceeded the period.
    pub overruns: u64,
    /// Wake-up lateness of the interval's cycles, ns.
    pub lateness: Percentiles,
}

/// Resident memory of one process over the soak.
#[derive(Debug, Clone, Serialize)]
pub struct Drift {
    /// At the end of the first interval (after start-up), KiB.
    pub first_kib: u64,
    /// At the end of the last interval, KiB.
    pub last_kib: u64,
    /// The largest over the intervals, KiB.
    pub max_kib: u64,
    /// last - first, KiB and per cent of first.
    pub drift_kib: i64,
    /// `drift_kib` in % of `first_kib` (0 when `first_kib` is 0).
    pub drift_pct: f64,
}

/// What `evoloop soak` reports: soak.json.
#[derive(Debug, Clone, Serialize)]
pub struct SoakReport {
    /// The scenario file run.
    pub scenario: String,
    /// How long the run was asked to last, s (`--duration`).
    pub duration_s: f64,
    /// Seconds between two records (`--interval`).
    pub interval_s: f64,
    /// The run's own output directory (`<out>/run`), with its report.
    pub run_dir: PathBuf,
    /// The run's id (`soak-<pid>`).
    pub run_id: String,
    /// The launcher's exit code (0: the run ended normally).
    pub exit_code: Option<i32>,
    /// One record per whole interval, in order (the last, partial one counts in the totals only).
    pub intervals: Vec<Interval>,
    /// Resident memory's drift (VmRSS) per process, by name.
    pub rss: BTreeMap<String, Drift>,
    /// The same for anonymous memory (RssAnon).
    pub anon: BTreeMap<String, Drift>,
    /// Missed deadlines per interval: median and largest.
    pub misses_per_interval_median: f64,
    /// The most missed deadlines in one interval.
    pub misses_per_interval_max: u64,
    /// Missed deadlines over the whole run, the last partial interval included.
    pub missed_deadlines: u64,
    /// Control cycles over the whole run, the last partial interval included.
    pub cycles: u64,
    /// This user's evoloop files in /dev/shm and iceoryx2's root before the start and after the
    /// end, and those the run left (after but not before).
    pub shm_before: Vec<String>,
    /// The files after the end.
    pub shm_after: Vec<String>,
    /// The files after the end that were not there before: what the run left behind.
    pub shm_left: Vec<String>,
}

/// Resident set size of `pid` (VmRSS) and its anonymous part (RssAnon, absent before Linux
/// 4.5), KiB, if it still runs.
pub fn rss_kib(pid: u32) -> Option<(u64, Option<u64>)> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kib = |key: &str| -> Option<u64> {
        let line = s.lines().find(|l| l.starts_with(key))?;
        line.split_whitespace().nth(1)?.parse().ok()
    };
    Some((kib("VmRSS:")?, kib("RssAnon:")))
}

/// A process of evoloop's on this machine: its name (a role of the one binary, `evoloop plant
/// ...`, counts as `evoloop-plant`), pid and arguments.
pub struct EvoloopProcess {
    /// The process's role, one of `PROCESSES`.
    pub name: String,
    /// Its process id.
    pub pid: u32,
    /// Its command line, the program first.
    pub args: Vec<String>,
}

impl EvoloopProcess {
    /// The value after `flag` on its command line.
    pub fn arg(&self, flag: &str) -> Option<&str> {
        let i = self.args.iter().position(|a| a == flag)?;
        self.args.get(i + 1).map(String::as_str)
    }
}

/// Every process named in `PROCESSES`, from /proc. A zombie has no command line and is not
/// listed.
pub fn evoloop_processes() -> Vec<EvoloopProcess> {
    let mut out = Vec::new();
    let Ok(rd) = std::fs::read_dir("/proc") else {
        return out;
    };
    for e in rd.flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(cmd) = std::fs::read(e.path().join("cmdline")) else {
            continue;
        };
        let args: Vec<String> = cmd
            .split(|b| *b == 0)
            .map(|a| String::from_utf8_lossy(a).into_owned())
            .collect();
        let Some(prog) = args.first() else { continue };
        let base = Path::new(prog)
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let name = match (base.as_str(), args.get(1).map(String::as_str)) {
            ("evoloop", Some(role @ ("plant" | "controller" | "optimiser"))) => {
                format!("evoloop-{role}")
            }
            _ => base,
        };
        if PROCESSES.contains(&name.as_str()) {
            out.push(EvoloopProcess { name, pid, args });
        }
    }
    out
}

/// The processes of run `run_id` (every one, the launcher included, has it as an argument:
/// `--run-id`), by name.
pub fn run_processes(run_id: &str) -> Vec<(String, u32)> {
    evoloop_processes()
        .into_iter()
        .filter(|p| p.args.iter().any(|a| a == run_id))
        .map(|p| (p.name, p.pid))
        .collect()
}

/// Follows a CSV file another process appends to: each call returns the complete lines added
/// since the last (a line still being written is kept for the next call).
pub struct Tail {
    path: PathBuf,
    reader: Option<BufReader<std::fs::File>>,
    partial: String,
}

impl Tail {
    /// A follower of the file at `path`, which need not exist yet; nothing is read until
    /// `new_lines`.
    pub fn new(path: PathBuf) -> Self {
        Self {
            path,
            reader: None,
            partial: String::new(),
        }
    }

    /// Calls `f` on each complete line appended since the last call, its line end trimmed; does
    /// nothing while the file does not exist.
    pub fn new_lines(&mut self, mut f: impl FnMut(&str)) {
        if self.reader.is_none() {
            let Ok(file) = std::fs::File::open(&self.path) else {
                return; // not created yet
            };
            self.reader = Some(BufReader::new(file));
        }
        let r = self.reader.as_mut().expect("opened above");
        loop {
            let mut line = String::new();
            match r.read_line(&mut line) {
                Ok(0) | Err(_) => return,
                Ok(_) => {}
            }
            self.partial.push_str(&line);
            if !self.partial.ends_with('\n') {
                return;
            }
            f(self.partial.trim_end());
            self.partial.clear();
        }
    }
}

/// Timing of the cycles in one interval, from timing.csv's lines.
pub struct IntervalTiming {
    period_ns: u64,
    /// Cycles (lines of timing.csv) read in the interval.
    pub cycles: u64,
    /// Whole periods that late wake-ups skipped: a lateness of k periods or more counts k.
    pub missed: u64,
    /// Cycles flagged `TELEMETRY_FLAG_OVERRUN` (lateness plus compute time over the period).
    pub overruns: u64,
    /// The cycles' wake-up lateness, ns.
    pub lateness: Accumulator,
}

impl IntervalTiming {
    /// No cycles yet, for a loop of period `period_ns`, ns.
    pub fn new(period_ns: u64) -> Self {
        Self {
            period_ns,
            cycles: 0,
            missed: 0,
            overruns: 0,
            lateness: Accumulator::new(),
        }
    }

    /// One line of timing.csv (`cycle,lateness_ns,compute_ns,state_age_ns,flags`); the header
    /// and anything unreadable are skipped.
    pub fn line(&mut self, line: &str) {
        let mut it = line.split(',');
        let (Some(_), Some(late), Some(_), Some(_), Some(flags)) =
            (it.next(), it.next(), it.next(), it.next(), it.next())
        else {
            return;
        };
        let (Ok(late), Ok(flags)) = (late.parse::<f64>(), flags.parse::<f64>()) else {
            return;
        };
        let late = late as i64;
        self.cycles += 1;
        self.lateness.record(late);
        // The loop skips the whole periods a late wake-up passed (controller.rs): those are the
        // missed deadlines.
        if late >= self.period_ns as i64 {
            self.missed += late as u64 / self.period_ns;
        }
        if flags as u32 & TELEMETRY_FLAG_OVERRUN != 0 {
            self.overruns += 1;
        }
    }
}

/// Summarise the intervals: the drift per process of the memory `pick` reads (resident or
/// anonymous).
pub fn drift(
    intervals: &[Interval],
    pick: fn(&Interval) -> &BTreeMap<String, u64>,
) -> BTreeMap<String, Drift> {
    let mut out = BTreeMap::new();
    for name in PROCESSES {
        let series: Vec<u64> = intervals
            .iter()
            .filter_map(|i| pick(i).get(name).copied())
            .collect();
        let (Some(&first), Some(&last)) = (series.first(), series.last()) else {
            continue;
        };
        out.insert(
            name.to_string(),
            Drift {
                first_kib: first,
                last_kib: last,
                max_kib: series.iter().copied().max().unwrap_or(0),
                drift_kib: last as i64 - first as i64,
                drift_pct: if first > 0 {
                    100.0 * (last as f64 - first as f64) / first as f64
                } else {
                    0.0
                },
            },
        );
    }
    out
}

/// Write soak.json, soak.csv and the two plots into `dir`.
pub fn write(dir: &Path, r: &SoakReport) -> Result<(), WriteError> {
    use crate::report::plot::{xy_png, Style, XySeries};
    crate::report::write_json(dir, "soak.json", r)
        .map_err(WriteError::file(&dir.join("soak.json")))?;
    let timing = [
        "cycles",
        "missed_deadlines",
        "overruns",
        "lateness_p50_ns",
        "lateness_p99_ns",
        "lateness_p99_9_ns",
        "lateness_max_ns",
    ];
    let header = ["interval".to_string(), "t_s".to_string()]
        .into_iter()
        .chain(PROCESSES.iter().map(|p| format!("rss_kib_{p}")))
        .chain(PROCESSES.iter().map(|p| format!("anon_kib_{p}")))
        .chain(timing.map(String::from));
    let mut csv = Csv::new(header);
    for i in &r.intervals {
        let l = &i.lateness;
        // A process whose memory was not read in the interval: an empty field.
        csv.row()
            .put(i.index)
            .put(i.t_s)
            .all(PROCESSES.iter().map(|p| i.rss_kib.get(*p)))
            .all(PROCESSES.iter().map(|p| i.anon_kib.get(*p)))
            .all([i.cycles, i.missed_deadlines, i.overruns])
            .all([l.p50_ns, l.p99_ns, l.p99_9_ns, l.max_ns]);
    }
    let file = dir.join("soak.csv");
    csv.write(&file).map_err(WriteError::file(&file))?;
    let minutes: Vec<f64> = r.intervals.iter().map(|i| i.t_s / 60.0).collect();
    let rss: Vec<(String, Vec<f64>, Vec<f64>)> = PROCESSES
        .iter()
        .map(|p| {
            let (x, y): (Vec<f64>, Vec<f64>) = r
                .intervals
                .iter()
                .zip(&minutes)
                .filter_map(|(i, m)| i.rss_kib.get(*p).map(|v| (*m, *v as f64 / 1024.0)))
                .unzip();
            (p.to_string(), x, y)
        })
        .filter(|c| !c.1.is_empty())
        .collect();
    let series: Vec<XySeries> = rss
        .iter()
        .map(|(n, x, y)| XySeries {
            name: n,
            x,
            y,
            style: Style::Line,
        })
        .collect();
    xy_png(
        &dir.join("soak_rss.png"),
        "Resident memory of each process",
        "time (min)",
        "RSS (MiB)",
        &series,
        None,
        None,
    )
    .map_err(WriteError::Figure)?;
    let misses: Vec<f64> = r
        .intervals
        .iter()
        .map(|i| i.missed_deadlines as f64)
        .collect();
    let p99: Vec<f64> = r
        .intervals
        .iter()
        .map(|i| i.lateness.p99_ns as f64 / 1e3)
        .collect();
    let p999: Vec<f64> = r
        .intervals
        .iter()
        .map(|i| i.lateness.p99_9_ns as f64 / 1e3)
        .collect();
    xy_png(
        &dir.join("soak_timing.png"),
        "Per interval: missed deadlines and wake-up lateness (us)",
        "time (min)",
        "count / us",
        &[
            XySeries {
                name: "missed deadlines",
                x: &minutes,
                y: &misses,
                style: Style::Points,
            },
            XySeries {
                name: "lateness p99 (us)",
                x: &minutes,
                y: &p99,
                style: Style::Line,
            },
            XySeries {
                name: "lateness p99.9 (us)",
                x: &minutes,
                y: &p999,
                style: Style::Line,
            },
        ],
        None,
        None,
    )
    .map_err(WriteError::Figure)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tail_returns_whole_lines_only() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        crate::files::write(&p, "a\nb\nc").unwrap();
        let mut t = Tail::new(p.clone());
        let mut got = Vec::new();
        t.new_lines(|l| got.push(l.to_string()));
        assert_eq!(got, ["a", "b"]);
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new().append(true).open(&p).unwrap();
        write!(f, "d\ne\n").unwrap();
        got.clear();
        t.new_lines(|l| got.push(l.to_string()));
        assert_eq!(got, ["cd", "e"]);
    }

    #[test]
    fn missed_deadlines_are_the_whole_periods_a_late_wake_up_skipped() {
        let mut t = IntervalTiming::new(1_000_000);
        t.line("cycle,lateness_ns,compute_ns,state_age_ns,flags");
        t.line("1,5000,800,700,0");
        t.line("2,2500000,800,700,6"); // 2.5 periods late: 2 skipped, overrun
        t.line("3,999999,800,700,2");
        assert_eq!((t.cycles, t.missed, t.overruns), (3, 2, 2));
        assert_eq!(t.lateness.percentiles().max_ns, 2_500_000);
    }

    #[test]
    fn drift_is_last_minus_first_per_process() {
        let iv = |i: usize, rss: &[(&str, u64)]| Interval {
            index: i,
            t_s: 60.0 * (i + 1) as f64,
            rss_kib: rss.iter().map(|(n, v)| (n.to_string(), *v)).collect(),
            anon_kib: BTreeMap::new(),
            cycles: 0,
            missed_deadlines: 0,
            overruns: 0,
            lateness: Percentiles::default(),
        };
        let d = drift(
            &[
                iv(0, &[("evoloop-plant", 1000), ("evoloop-controller", 2000)]),
                iv(1, &[("evoloop-plant", 1100)]),
                iv(2, &[("evoloop-plant", 1050), ("evoloop-controller", 2000)]),
            ],
            |i| &i.rss_kib,
        );
        let p = &d["evoloop-plant"];
        assert_eq!(
            (p.first_kib, p.last_kib, p.max_kib, p.drift_kib),
            (1000, 1050, 1100, 50)
        );
        assert!((p.drift_pct - 5.0).abs() < 1e-12);
        assert_eq!(d["evoloop-controller"].drift_kib, 0);
        assert!(!d.contains_key("evoloop-optimiser"));
    }
}
