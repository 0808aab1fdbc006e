//! The report after a long run is built in bounded memory: run.csv is read a row at a time and
//! the plots keep the envelope of the run past `scan::PLOT_EXACT` rows. (Its own test binary:
//! the memory figure is the largest of this process's children, so nothing else may run here.)

mod common;
use common::*;

#[test]
fn a_long_runs_report_reads_run_csv_in_bounded_memory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    // 1.2 million rows, about 110 MB of run.csv: read whole, as the report did before, it took
    // some 190 MB (549 MB for an hour).
    let o = cli(&[
        "run",
        "config/two_mass/two_mass.toml",
        "--duration",
        "1200",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert_ok(&o);
    let csv = std::fs::metadata(out.join("run.csv")).unwrap().len();
    assert!(csv > 100_000_000, "run.csv is {csv} B");
    // SAFETY: getrusage fills the struct it is given.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: a valid rusage to fill.
    let got = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) };
    assert_eq!(got, 0);
    // ru_maxrss (KiB): the largest resident set of any process of the run, launcher included.
    let peak_mib = usage.ru_maxrss as f64 / 1024.0;
    assert!(
        peak_mib < 64.0,
        "a process of the run peaked at {peak_mib:.0} MiB"
    );
    let s = json(&out.join("summary.json"));
    assert_eq!(s["samples"], 1_200_000);
    assert_eq!(s["outcome"], "ok");
    assert!(s["tracking"]["rms_all"].as_f64().unwrap() > 0.0, "{s}");
    assert_plotted(&out.join("response.png"));
}
