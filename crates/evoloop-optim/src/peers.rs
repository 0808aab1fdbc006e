//! Other implementations' runs beside the study's: a file in the study's runs.csv format (for
//! instance the Python libraries', from `scripts/python_peers.py`), and per function the study's
//! best algorithm against theirs.
//!
//! Their runs share no random streams with ours, so the samples are independent and the test is
//! Mann-Whitney's rank-sum, not the paired Wilcoxon of Table 8. Each side's best is the algorithm
//! with the lowest mean error (then median) on that function; both sides are picked the same way.
//!
//! An error below `SOLVED` (1e-8, the CEC benchmarks' convention) counts as 0: two
//! implementations that both reach the minimum differ below it only by the order of their
//! floating-point operations (1e-161 against 1e-28 on the sphere, -1.5e-15 against -3.6e-16 on
//! Shekel 7), and a rank test would call that difference significant.

use evoloop_stats::{mann_whitney, median, MannWhitney};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Final errors by function, then algorithm.
pub type Errors = BTreeMap<String, BTreeMap<String, Vec<f64>>>;

/// The runs of a peers file.
#[derive(Debug, Clone)]
pub struct PeerRuns {
    /// The file's path as given, for messages.
    pub file: String,
    /// The file's algorithm names, sorted, each once.
    pub algorithms: Vec<String>,
    /// Each run's final error, by function and algorithm, in file order.
    pub errors: Errors,
}

/// Errors below this count as 0 (the minimum reached).
pub const SOLVED: f64 = 1e-8;

const HEADER: &str = "function,algorithm,seed,best_value,error,evaluations";

/// Reads a peers file. Refused, with file, line and reason: another header, a malformed row, an
/// algorithm named like one of `ours`, a NaN error, or a run that used more than `budget`
/// evaluations (a larger budget is no comparison).
pub fn load(path: &Path, budget: usize, ours: &[String]) -> Result<PeerRuns, PeersError> {
    let file = path.display().to_string();
    let fail = |line: Option<usize>, fault: PeersFault| PeersError {
        file: file.clone(),
        line,
        fault,
    };
    let text = evoloop_files::read_text(path).map_err(|e| fail(None, PeersFault::Unreadable(e)))?;
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == HEADER => {}
        _ => return Err(fail(Some(1), PeersFault::Header)),
    }
    let mut errors = Errors::new();
    for (i, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let at = |fault: PeersFault| fail(Some(i + 1), fault);
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        let [function, algorithm, _seed, _best, error, evaluations] = f[..] else {
            return Err(at(PeersFault::Fields(f.len())));
        };
        if ours.iter().any(|o| o == algorithm) {
            return Err(at(PeersFault::OneOfOurs(algorithm.to_string())));
        }
        let error: f64 = error
            .parse()
            .map_err(|_| at(PeersFault::NotANumber(error.to_string())))?;
        if error.is_nan() {
            return Err(at(PeersFault::NaN));
        }
        let evaluations: usize = evaluations
            .parse()
            .map_err(|_| at(PeersFault::NotACount(evaluations.to_string())))?;
        if evaluations > budget {
            return Err(at(PeersFault::OverBudget {
                evaluations,
                budget,
            }));
        }
        errors
            .entry(function.to_string())
            .or_default()
            .entry(algorithm.to_string())
            .or_default()
            .push(error);
    }
    let mut algorithms: Vec<String> = errors.values().flat_map(|m| m.keys().cloned()).collect();
    algorithms.sort();
    algorithms.dedup();
    if algorithms.is_empty() {
        return Err(fail(None, PeersFault::NoRuns));
    }
    Ok(PeerRuns {
        file,
        algorithms,
        errors,
    })
}

/// A peers file `load` refused: the file, the line (from 1; None for the file as a whole) and
/// what is wrong there.
#[derive(Debug)]
pub struct PeersError {
    /// The file as given.
    pub file: String,
    /// The line, from 1.
    pub line: Option<usize>,
    /// What is wrong.
    pub fault: PeersFault,
}

/// What is wrong with a peers file.
#[derive(Debug)]
pub enum PeersFault {
    /// It cannot be read (missing, not a regular file, too large).
    Unreadable(std::io::Error),
    /// Its first line is not `HEADER`.
    Header,
    /// A row without the header's 6 fields (how many it has).
    Fields(usize),
    /// An algorithm named like one of the study's own.
    OneOfOurs(String),
    /// An error that is not a number.
    NotANumber(String),
    /// An error that is NaN.
    NaN,
    /// Evaluations that are not a count.
    NotACount(String),
    /// A run that used more evaluations than the study's budget.
    OverBudget {
        /// The run's evaluations.
        evaluations: usize,
        /// The study's budget.
        budget: usize,
    },
    /// No row at all.
    NoRuns,
}

impl std::fmt::Display for PeersError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}: ", self.file)?,
            None => write!(f, "{}: ", self.file)?,
        }
        match &self.fault {
            PeersFault::Unreadable(e) => write!(f, "{e}"),
            PeersFault::Header => write!(f, "the header must be `{HEADER}`"),
            PeersFault::Fields(n) => write!(f, "{n} fields, expected 6"),
            PeersFault::OneOfOurs(a) => {
                write!(f, "algorithm {a:?} is also one of the study's; rename it")
            }
            PeersFault::NotANumber(e) => write!(f, "error {e:?} is not a number"),
            PeersFault::NaN => write!(f, "error is NaN"),
            PeersFault::NotACount(e) => write!(f, "evaluations {e:?} is not a count"),
            PeersFault::OverBudget {
                evaluations,
                budget,
            } => write!(
                f,
                "{evaluations} evaluations, more than the study's budget of {budget}"
            ),
            PeersFault::NoRuns => write!(f, "no runs"),
        }
    }
}

impl std::error::Error for PeersError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.fault {
            PeersFault::Unreadable(e) => Some(e),
            _ => None,
        }
    }
}

/// One side's best on a function.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Best {
    /// The algorithm's name.
    pub algorithm: String,
    /// Mean final error over its runs (errors below `SOLVED` as 0).
    pub mean_error: f64,
    /// Median final error over its runs (errors below `SOLVED` as 0).
    pub median_error: f64,
    /// Number of runs.
    pub runs: usize,
}

/// Lower than theirs, no difference shown, or higher (two-sided test at 5 %).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Verdict {
    /// Our best's errors are lower than theirs (significant at 5 %).
    Beats,
    /// No difference shown at the 5 % level.
    Matches,
    /// Our best's errors are higher than theirs (significant at 5 %).
    Loses,
}

/// Our best algorithm against theirs on one function, with the Mann-Whitney test between
/// their errors and its verdict.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// The study's best algorithm on the function.
    pub ours: Best,
    /// The peers file's best algorithm on the function.
    pub theirs: Best,
    /// Mann-Whitney U test of our best's errors (sample a) against theirs (b).
    pub test: MannWhitney,
    /// What the test says at the 5 % level.
    pub verdict: Verdict,
}

/// The algorithm with the lowest mean error (then median), with its errors (below `SOLVED`
/// as 0).
fn best<'a>(side: impl Iterator<Item = (&'a str, &'a [f64])>) -> Option<(Best, Vec<f64>)> {
    side.filter(|(_, e)| !e.is_empty())
        .map(|(name, e)| {
            let e: Vec<f64> = e
                .iter()
                .map(|v| if *v < SOLVED { 0.0 } else { *v })
                .collect();
            let b = Best {
                algorithm: name.to_string(),
                mean_error: e.iter().sum::<f64>() / e.len() as f64,
                median_error: median(&e),
                runs: e.len(),
            };
            (b, e)
        })
        .min_by(|(a, _), (b, _)| {
            a.mean_error
                .total_cmp(&b.mean_error)
                .then(a.median_error.total_cmp(&b.median_error))
        })
}

/// Our best against their best on one function; None when either side has no runs.
pub fn compare<'a>(
    ours: impl Iterator<Item = (&'a str, &'a [f64])>,
    theirs: impl Iterator<Item = (&'a str, &'a [f64])>,
) -> Option<Comparison> {
    let (ours, a) = best(ours)?;
    let (theirs, b) = best(theirs)?;
    let test = mann_whitney(&a, &b);
    let verdict = if test.p_two_sided >= 0.05 {
        Verdict::Matches
    } else if test.a_lower() {
        Verdict::Beats
    } else {
        Verdict::Loses
    };
    Some(Comparison {
        ours,
        theirs,
        test,
        verdict,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(text: &str) -> tempfile::NamedTempFile {
        let f = tempfile::NamedTempFile::new().unwrap();
        std::fs::write(f.path(), text).unwrap();
        f
    }

    #[test]
    fn a_peers_file_is_read_and_bad_rows_are_refused_with_their_line() {
        let ours = vec!["emupso".to_string()];
        let ok = file(&format!(
            "{HEADER}\nsphere,scipy_de,0,1e-3,1e-3,29700\nsphere,scipy_de,1,inf,inf,30000\n\
             rastrigin,mealpy_jade,0,2,2,30000\n"
        ));
        let p = load(ok.path(), 30_000, &ours).unwrap();
        assert_eq!(p.algorithms, ["mealpy_jade", "scipy_de"]);
        assert_eq!(p.errors["sphere"]["scipy_de"], [1e-3, f64::INFINITY]);
        for (body, why) in [
            ("sphere,x,0,1,1,30001\n", "more than the study's budget"),
            ("sphere,emupso,0,1,1,10\n", "also one of the study's"),
            ("sphere,x,0,1,NaN,10\n", "NaN"),
            ("sphere,x,0,1\n", "4 fields"),
        ] {
            let bad = file(&format!("{HEADER}\n{body}"));
            let e = load(bad.path(), 30_000, &ours).unwrap_err();
            assert_eq!(e.line, Some(2), "{e}");
            let text = e.to_string();
            assert!(text.contains(":2: ") && text.contains(why), "{text}");
        }
        let e = load(file("a,b\n").path(), 30_000, &ours).unwrap_err();
        assert!(matches!(e.fault, PeersFault::Header), "{e}");
        assert!(e.to_string().contains(":1: the header"), "{e}");
    }

    #[test]
    fn each_side_is_represented_by_its_lowest_mean_and_the_verdict_follows_the_test() {
        let low: Vec<f64> = (0..30).map(|i| i as f64 * 1e-3).collect();
        let high: Vec<f64> = (0..10).map(|i| 1.0 + i as f64).collect();
        let worse: Vec<f64> = high.iter().map(|v| v * 10.0).collect();
        let ours = [("a", &low[..]), ("b", &worse[..])];
        let theirs = [("x", &high[..]), ("y", &worse[..])];
        let c = compare(ours.into_iter(), theirs.into_iter()).unwrap();
        assert_eq!(
            (c.ours.algorithm.as_str(), c.theirs.algorithm.as_str()),
            ("a", "x")
        );
        assert_eq!(c.verdict, Verdict::Beats);
        let c = compare(theirs.into_iter(), ours.into_iter()).unwrap();
        assert_eq!(c.verdict, Verdict::Loses);
        // The same distribution on both sides: no difference shown.
        let c = compare(
            [("a", &high[..])].into_iter(),
            [("x", &high[..])].into_iter(),
        )
        .unwrap();
        assert_eq!(c.verdict, Verdict::Matches);
        assert!(compare([("a", &high[..])].into_iter(), std::iter::empty()).is_none());
        // Both at the minimum to within rounding (or far below 1e-8): no difference.
        let (tiny, tinier) = ([1e-161; 10], [-3e-16; 10]);
        let c = compare(
            [("a", &tiny[..])].into_iter(),
            [("x", &tinier[..])].into_iter(),
        )
        .unwrap();
        assert_eq!((c.verdict, c.ours.mean_error), (Verdict::Matches, 0.0));
    }
}
