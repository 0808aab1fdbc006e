//! `evoloop optim study` (the eMuPSO paper's benchmark study, Tables 4-9 and Figs. 5-7) and
//! `evoloop optim bench` (each optimiser's own overhead).

use clap::{Args, Subcommand};
use evoloop_optim::by_name::{self, ALGORITHMS};
use evoloop_optim::peers::{self, Comparison, PeerRuns, Verdict};
use evoloop_optim::problem::{self, Problem};
use evoloop_optim::study::{self, Cell, Outcome, RunResult, SUBJECT};
use evoloop_report::csv::{Csv, Sci};
use evoloop_report::plot::{xy_png, Style, XySeries};
use rayon::prelude::*;
use serde_json::{json, Map, Value};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The subcommands of `evoloop optim`: the eMuPSO paper's optimiser benchmark and its suite.
#[derive(Subcommand)]
pub enum OptimCmd {
    /// The eMuPSO paper's benchmark study: every algorithm on every function (and the shifted,
    /// rotated copies of the origin-centred ones), seeded runs at one evaluation budget.
    /// Writes results.json, runs.csv, report.md (beside the paper's Tables 4-9) and
    /// `convergence/<function>.png`.
    Study(StudyArgs),
    /// Evaluations per second of each algorithm on a trivial objective: the optimiser's own
    /// overhead per evaluation, one thread.
    Bench(BenchArgs),
    /// The suite: every function's key, group, dimension, box and f_min, with the shifted
    /// copies (what another program needs to run its own optimisers on the same problems).
    Functions(FunctionsArgs),
    /// Evaluate one function of the suite for another program, over stdin and stdout in
    /// little-endian binary: each request is a u32 count n followed by n x dim f64 (points,
    /// row by row), each answer n f64. Ends at end of input. scripts/python_peers.py uses it
    /// so that the Python libraries minimise exactly the study's functions.
    Serve(ServeArgs),
}

/// Options of `evoloop optim functions`: list the benchmark suite's functions.
#[derive(Args)]
pub struct FunctionsArgs {
    /// Leave out the shifted copies.
    #[arg(long)]
    pub no_shifted: bool,
    /// Print JSON (a list of {key, group, dim, lower, upper, f_min, shifted}).
    #[arg(long)]
    pub json: bool,
}

/// Options of `evoloop optim serve`: which suite function to evaluate over stdin and stdout.
#[derive(Args)]
pub struct ServeArgs {
    /// The function's key (`<key>_shifted` for a shifted copy).
    #[arg(long)]
    pub function: String,
}

/// Options of `evoloop optim study`: the functions and algorithms, runs per pair, the evaluation
/// budget and the population size.
#[derive(Args)]
pub struct StudyArgs {
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Runs per algorithm and function (seeds 0..runs-1).
    #[arg(long, default_value_t = 30)]
    pub runs: u64,
    /// Objective evaluations per run.
    #[arg(long, default_value_t = 30_000)]
    pub evaluations: usize,
    /// Population size of every algorithm.
    #[arg(long, default_value_t = 30)]
    pub population: usize,
    /// Functions, comma-separated (keys of the suite; `<key>_shifted` for a shifted copy).
    /// Default: all 37 and the shifted copies of the origin-centred ones.
    #[arg(long, value_delimiter = ',')]
    pub functions: Option<Vec<String>>,
    /// Algorithms, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = ALGORITHMS.map(String::from))]
    pub algorithms: Vec<String>,
    /// Leave out the shifted copies (with the default function list).
    #[arg(long)]
    pub no_shifted: bool,
    /// Other implementations' runs in runs.csv format (e.g. from scripts/python_peers.py):
    /// per function, the study's best algorithm against theirs (Mann-Whitney), in report.md
    /// and results.json (`peers`).
    #[arg(long)]
    pub peers: Option<PathBuf>,
    /// Threads (default: every core).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print results.json on stdout instead of the summary.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Options of `evoloop optim bench`: each optimiser's own overhead per evaluation on a trivial
/// objective.
#[derive(Args)]
pub struct BenchArgs {
    /// Dimension of the trivial objective.
    #[arg(long, default_value_t = 30)]
    pub dim: usize,
    /// Evaluations per measurement.
    #[arg(long, default_value_t = 300_000)]
    pub evaluations: usize,
    /// Population size.
    #[arg(long, default_value_t = 30)]
    pub population: usize,
    /// Measurements per algorithm (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Algorithms, comma-separated (default: all of them).
    #[arg(long, value_delimiter = ',')]
    pub algorithms: Option<Vec<String>>,
    /// Print JSON (key `evals_per_s[algorithm]`).
    #[arg(long)]
    pub json: bool,
}

/// `evoloop optim SUBCOMMAND`: run it and return the exit code (0, or 2 with the error on
/// stderr).
pub fn main(cmd: OptimCmd) -> i32 {
    let r = match cmd {
        OptimCmd::Study(a) => run_study(&a),
        OptimCmd::Bench(a) => bench(&a),
        OptimCmd::Functions(a) => functions(&a),
        OptimCmd::Serve(a) => serve(&a),
    };
    match r {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("evoloop optim: {e}");
            2
        }
    }
}

/// Every run of a study, by problem then algorithm, runs in seed order.
pub struct StudyRuns {
    /// The study's problems (suite functions and shifted copies), in the order of `runs`.
    pub problems: Vec<Problem>,
    /// The algorithms' names, in the order of each problem's row of `runs`.
    pub algorithms: Vec<String>,
    /// The results, indexed `[problem][algorithm][seed]`.
    pub runs: Vec<Vec<Vec<RunResult>>>,
}

fn check_args(a: &StudyArgs) -> Result<Vec<String>, String> {
    if a.runs < 2 {
        return Err(format!(
            "--runs {}: at least 2 (a paired test needs pairs)",
            a.runs
        ));
    }
    if a.population < 4 || a.evaluations < 2 * a.population {
        return Err(format!(
            "--population {} and --evaluations {}: need a population >= 4 and a budget of at \
             least two populations",
            a.population, a.evaluations
        ));
    }
    let algorithms = a.algorithms.clone();
    for name in &algorithms {
        if !ALGORITHMS.contains(&name.as_str()) {
            return Err(format!(
                "--algorithms: unknown {name:?} (known: {})",
                ALGORITHMS.join(", ")
            ));
        }
    }
    Ok(algorithms)
}

/// Run every (problem, algorithm, seed) on `threads` threads, ticking `tick` after each.
pub fn execute(
    problems: Vec<Problem>,
    algorithms: Vec<String>,
    runs: u64,
    population: usize,
    evaluations: usize,
    threads: usize,
    tick: &(dyn Fn() + Sync),
) -> Result<StudyRuns, String> {
    let jobs: Vec<(usize, usize, u64)> = (0..problems.len())
        .flat_map(|p| (0..algorithms.len()).flat_map(move |a| (0..runs).map(move |s| (p, a, s))))
        .collect();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| e.to_string())?;
    let done: Vec<Result<RunResult, String>> = pool.install(|| {
        jobs.par_iter()
            .map(|&(p, a, s)| {
                let r = study::run_one(&problems[p], &algorithms[a], population, evaluations, s)
                    .map_err(|e| e.to_string());
                tick();
                r
            })
            .collect()
    });
    let mut out = vec![vec![Vec::with_capacity(runs as usize); algorithms.len()]; problems.len()];
    for (&(p, a, _), r) in jobs.iter().zip(done) {
        out[p][a].push(r?);
    }
    Ok(StudyRuns {
        problems,
        algorithms,
        runs: out,
    })
}

fn run_study(a: &StudyArgs) -> Result<(), String> {
    let algorithms = check_args(a)?;
    let problems =
        problem::problems(a.functions.as_deref(), !a.no_shifted).map_err(|e| e.to_string())?;
    // Read before the study runs: a bad file is refused at once, not after minutes.
    let peers = match &a.peers {
        Some(f) => Some(peers::load(f, a.evaluations, &algorithms).map_err(|e| e.to_string())?),
        None => None,
    };
    std::fs::create_dir_all(a.out.join("convergence"))
        .map_err(|e| format!("creating {}: {e}", a.out.display()))?;
    let total = problems.len() * algorithms.len() * a.runs as usize;
    let bar = evoloop_report::progress::bar(total as u64, "runs", a.quiet || a.json);
    let started = Instant::now();
    let threads = a.threads.unwrap_or_else(evoloop_optim::all_cores);
    let s = execute(
        problems,
        algorithms,
        a.runs,
        a.population,
        a.evaluations,
        threads,
        &|| bar.inc(1),
    )?;
    bar.finish_and_clear();
    let elapsed = started.elapsed().as_secs_f64();
    let mut results = results_json(&s, a, threads, elapsed);
    let comparisons = peers.as_ref().map(|p| against_peers(&s, p));
    if let (Some(p), Some(c)) = (&peers, &comparisons) {
        results["peers"] = peers_json(p, c);
    }
    write(
        &a.out.join("results.json"),
        &serde_json::to_string_pretty(&results).unwrap_or_default(),
    )?;
    let runs = a.out.join("runs.csv");
    runs_csv(&s)
        .write(&runs)
        .map_err(|e| format!("writing {}: {e}", runs.display()))?;
    let mut md = report_md(&s, &results, a);
    if let (Some(p), Some(c)) = (&peers, &comparisons) {
        peers_md(&mut md, p, c);
    }
    write(&a.out.join("report.md"), &md)?;
    for (p, problem) in s.problems.iter().enumerate() {
        convergence_png(&a.out, problem, &s.algorithms, &s.runs[p], a.evaluations)
            .map_err(|e| e.to_string())?;
    }
    if a.json {
        super::print_json(&results);
    } else {
        out!(
            "{} functions x {} algorithms x {} runs ({} evaluations each) in {elapsed:.1} s on {threads} threads",
            s.problems.len(),
            s.algorithms.len(),
            a.runs,
            a.evaluations
        );
        out!("{}", best_per_function_sentence(&s));
        if let Some(c) = &comparisons {
            out!("{}", peers_sentence(c));
        }
        out!(
            "wrote {}/report.md, results.json, runs.csv, convergence/",
            a.out.display()
        );
    }
    Ok(())
}

fn write(path: &Path, text: &str) -> Result<(), String> {
    evoloop_files::write(path, text).map_err(|e| format!("writing {}: {e}", path.display()))
}

fn cells(s: &StudyRuns, p: usize) -> Vec<Cell> {
    s.runs[p].iter().map(|r| Cell::of(r)).collect()
}

/// The algorithms with the lowest mean error on a function (within 1e-9 of it, relative:
/// equal results up to rounding share it).
fn best_algorithms(cells: &[Cell]) -> Vec<usize> {
    let lowest = cells
        .iter()
        .map(|c| c.mean_error)
        .fold(f64::INFINITY, f64::min);
    (0..cells.len())
        .filter(|&i| cells[i].mean_error - lowest <= 1e-9 * lowest.abs())
        .collect()
}

fn best_per_function_sentence(s: &StudyRuns) -> String {
    let mut count = vec![0usize; s.algorithms.len()];
    for p in 0..s.problems.len() {
        for i in best_algorithms(&cells(s, p)) {
            count[i] += 1;
        }
    }
    let mut parts: Vec<(usize, &str)> = count
        .iter()
        .zip(&s.algorithms)
        .map(|(c, n)| (*c, n.as_str()))
        .collect();
    parts.sort_by_key(|p| std::cmp::Reverse(p.0));
    format!(
        "lowest mean error (ties shared) on {} functions: {}",
        s.problems.len(),
        parts
            .iter()
            .map(|(c, n)| format!("{n} {c}"))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

fn results_json(s: &StudyRuns, a: &StudyArgs, threads: usize, elapsed: f64) -> Value {
    let subject = s.algorithms.iter().position(|n| n == SUBJECT);
    let mut results = Map::new();
    let mut tests = Map::new();
    let mut functions = Map::new();
    let mut wtl: BTreeMap<String, BTreeMap<String, [usize; 3]>> = BTreeMap::new();
    for (p, problem) in s.problems.iter().enumerate() {
        let cs = cells(s, p);
        let mut row = Map::new();
        for (name, c) in s.algorithms.iter().zip(&cs) {
            row.insert(name.clone(), serde_json::to_value(c).unwrap_or_default());
        }
        results.insert(problem.key.clone(), Value::Object(row));
        functions.insert(
            problem.key.clone(),
            json!({
                "group": problem.group(),
                "dim": problem.function.dim,
                "f_min": problem.f_min(),
                "shifted": problem.shift.is_some(),
                "best": best_algorithms(&cs).iter().map(|&i| s.algorithms[i].clone()).collect::<Vec<_>>(),
            }),
        );
        let Some(si) = subject else { continue };
        let mut t = Map::new();
        for (ai, name) in s.algorithms.iter().enumerate() {
            if ai == si {
                continue;
            }
            let (w, o) = study::compare(&s.runs[p][si], &s.runs[p][ai]);
            t.insert(
                name.clone(),
                json!({
                    "p": w.p_two_sided, "method": w.method, "pairs": w.n,
                    "emupso_lower": w.a_lower, "emupso_higher": w.a_higher, "outcome": o,
                }),
            );
            let group = if problem.shift.is_some() {
                "shifted".to_string()
            } else {
                problem.group().to_string()
            };
            let e = wtl
                .entry(group)
                .or_default()
                .entry(name.clone())
                .or_default();
            e[match o {
                Outcome::Win => 0,
                Outcome::Tie => 1,
                Outcome::Loss => 2,
            }] += 1;
        }
        tests.insert(problem.key.clone(), Value::Object(t));
    }
    let wtl: BTreeMap<String, BTreeMap<String, Value>> = wtl
        .into_iter()
        .map(|(g, m)| {
            (
                g,
                m.into_iter()
                    .map(|(n, [w, t, l])| (n, json!({"win": w, "tie": t, "loss": l})))
                    .collect(),
            )
        })
        .collect();
    json!({
        "config": {
            "runs": a.runs, "evaluations": a.evaluations, "population": a.population,
            "seeds": format!("0..{}", a.runs), "algorithms": s.algorithms, "threads": threads,
        },
        "elapsed_s": elapsed,
        "functions": functions,
        "results": results,
        "wilcoxon": tests,
        "win_tie_loss": wtl,
    })
}

fn runs_csv(s: &StudyRuns) -> Csv {
    let mut csv = Csv::new([
        "function",
        "algorithm",
        "seed",
        "best_value",
        "error",
        "evaluations",
    ]);
    for (p, problem) in s.problems.iter().enumerate() {
        for (a, name) in s.algorithms.iter().enumerate() {
            for r in &s.runs[p][a] {
                csv.row()
                    .put(&problem.key)
                    .put(name)
                    .put(r.seed)
                    .all([Sci(r.best_value), Sci(r.error)])
                    .put(r.evaluations);
            }
        }
    }
    csv
}

/// The paper's Tables 4-6 and 8 (data/emupso_paper_tables.csv): (key, row) -> six values in
/// the order emupso, pso, woa, gwo, goa, de; None where the paper has NA or NaN.
type PaperTable = BTreeMap<(String, String), Vec<Option<f64>>>;
const PAPER_ALGORITHMS: [&str; 6] = ["emupso", "pso", "woa", "gwo", "goa", "de"];

fn paper_tables() -> PaperTable {
    include_str!("../../../data/emupso_paper_tables.csv")
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("f,"))
        .filter_map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c.len() == 9).then(|| {
                (
                    (c[1].to_string(), c[2].to_string()),
                    c[3..]
                        .iter()
                        .map(|v| v.parse::<f64>().ok().filter(|x| x.is_finite()))
                        .collect(),
                )
            })
        })
        .collect()
}

/// The paper's value of `row` for `algorithm` on the function `key`, where it has one.
fn paper_value(paper: &PaperTable, key: &str, row: &str, algorithm: &str) -> Option<f64> {
    let j = PAPER_ALGORITHMS.iter().position(|n| *n == algorithm)?;
    paper.get(&(key.to_string(), row.to_string()))?[j]
}

/// A markdown table's header: the leading columns, then one per name.
fn header(md: &mut String, leading: &[&str], names: &[&str]) {
    let _ = writeln!(md, "| {} | {} |", leading.join(" | "), names.join(" | "));
    let _ = writeln!(
        md,
        "|{}{}",
        "---|".repeat(leading.len()),
        "---|".repeat(names.len())
    );
}

fn sci(v: f64) -> String {
    if v == 0.0 {
        "0".into()
    } else if v.abs() >= 1e-3 && v.abs() < 1e4 {
        format!("{v:.4}")
    } else {
        format!("{v:.2e}")
    }
}

fn report_md(s: &StudyRuns, results: &Value, a: &StudyArgs) -> String {
    let paper = paper_tables();
    let mut md = String::new();
    let _ = writeln!(md, "# Benchmark study (the eMuPSO paper, Section 4.2)\n");
    let _ = writeln!(
        md,
        "{} runs (seeds 0..{}) of {} evaluations, population {}, per algorithm and function; error = \
         best f found - f_min. Command: `evoloop optim study --out {} --runs {} --evaluations {} --population {}`.\n",
        a.runs, a.runs, a.evaluations, a.population, a.out.display(), a.runs, a.evaluations, a.population
    );
    let _ = writeln!(md, "{}.\n", best_per_function_sentence(s));
    let groups = [
        ("unimodal", "Table 4: unimodal functions"),
        ("multimodal", "Table 5: multimodal functions"),
        ("constant", "Table 6: constant-dimension functions"),
        ("extra", "Ackley (not in the paper)"),
    ];
    for (group, title) in groups {
        let rows: Vec<usize> = (0..s.problems.len())
            .filter(|&p| s.problems[p].group() == group && s.problems[p].shift.is_none())
            .collect();
        table(&mut md, s, &rows, title, &paper);
    }
    let shifted: Vec<usize> = (0..s.problems.len())
        .filter(|&p| s.problems[p].shift.is_some())
        .collect();
    table(
        &mut md,
        s,
        &shifted,
        "Shifted and rotated copies of the origin-centred functions",
        &paper,
    );
    if s.algorithms.iter().any(|n| n == SUBJECT) {
        wilcoxon_md(&mut md, s, results, &paper);
    }
    let _ = writeln!(md, "## Where the paper's tables disagree with ours\n");
    let _ = writeln!(
        md,
        "- The paper's tables mix f and f - f_min and use some wrong f_min values (see the table in \
         `crates/evoloop-optim/src/suite.rs`): an entry below zero cannot be an error. Entries below zero here: {}.",
        negative_paper_entries(&paper)
    );
    let _ = writeln!(
        md,
        "- The paper's Wilcoxon p of 1.73e-6 is the normal approximation (no continuity correction) \
         for 30 pairs all on one side; the exact test used here gives 2/2^30 = 1.86e-9 for that case. \
         The paper compares the best algorithm per function with each other; Table 8 here compares \
         eMuPSO with each peer.\n- Our eMuPSO takes documented choices where the text is silent \
         (`crates/evoloop-optim/src/emupso.rs`), so its numbers are not expected to equal the paper's.\n"
    );
    md
}

fn negative_paper_entries(paper: &PaperTable) -> String {
    let mut v: Vec<String> = paper
        .iter()
        .filter(|((_, row), vals)| row == "min" && vals.iter().flatten().any(|x| *x < 0.0))
        .map(|((k, _), _)| format!("`{k}`"))
        .collect();
    v.dedup();
    if v.is_empty() {
        "none".into()
    } else {
        v.join(", ")
    }
}

/// A table: per function, min / mean / std of the error per algorithm, the lowest mean in
/// bold, and the paper's mean for the same algorithm in brackets where it has one.
fn table(md: &mut String, s: &StudyRuns, rows: &[usize], title: &str, paper: &PaperTable) {
    if rows.is_empty() {
        return;
    }
    let _ = writeln!(md, "## {title}\n");
    let _ = writeln!(
        md,
        "Ours (the paper's value for the same row and algorithm in brackets).\n"
    );
    let names: Vec<&str> = s.algorithms.iter().map(String::as_str).collect();
    header(md, &["function", ""], &names);
    for &p in rows {
        let cs = cells(s, p);
        let best = best_algorithms(&cs);
        let key = &s.problems[p].key;
        for (row, pick) in [
            ("min", (|c: &Cell| c.min_error) as fn(&Cell) -> f64),
            ("mean", |c: &Cell| c.mean_error),
            ("std", |c: &Cell| c.std_error),
        ] {
            let mut line = format!(
                "| {} | {row} |",
                if row == "min" { key.as_str() } else { "" }
            );
            for (i, (name, c)) in s.algorithms.iter().zip(&cs).enumerate() {
                let mut v = sci(pick(c));
                if row == "mean" && best.contains(&i) {
                    v = format!("**{v}**");
                }
                let published = paper_value(paper, key, row, name);
                if let Some(pv) = published {
                    v = format!("{v} ({})", sci(pv));
                }
                let _ = write!(line, " {v} |");
            }
            let _ = writeln!(md, "{line}");
        }
    }
    let _ = writeln!(md);
}

fn wilcoxon_md(md: &mut String, s: &StudyRuns, results: &Value, paper: &PaperTable) {
    let peers: Vec<&str> = s
        .algorithms
        .iter()
        .map(String::as_str)
        .filter(|n| *n != SUBJECT)
        .collect();
    let _ = writeln!(
        md,
        "## Table 8: Wilcoxon signed-rank, eMuPSO against each peer\n"
    );
    let _ = writeln!(
        md,
        "Two-sided p on the paired final errors (same seeds); W / L = eMuPSO significantly lower / \
         higher at 5 %, = no difference shown. The paper's p for that peer in brackets.\n"
    );
    header(md, &["function"], &peers);
    for problem in &s.problems {
        let mut line = format!("| {} |", problem.key);
        for peer in &peers {
            let t = &results["wilcoxon"][&problem.key][*peer];
            let mark = match t["outcome"].as_str() {
                Some("win") => "W",
                Some("loss") => "L",
                _ => "=",
            };
            let mut v = format!("{} {mark}", sci(t["p"].as_f64().unwrap_or(f64::NAN)));
            if let Some(pv) = paper_value(paper, &problem.key, "wilcoxon_p", peer) {
                v = format!("{v} ({})", sci(pv));
            }
            let _ = write!(line, " {v} |");
        }
        let _ = writeln!(md, "{line}");
    }
    let _ = writeln!(
        md,
        "\n## Table 9: eMuPSO's wins / ties / losses against each peer\n"
    );
    header(md, &["group"], &peers);
    if let Some(groups) = results["win_tie_loss"].as_object() {
        for (g, m) in groups {
            let mut line = format!("| {g} |");
            for peer in &peers {
                let e = &m[*peer];
                let _ = write!(line, " {}/{}/{} |", e["win"], e["tie"], e["loss"]);
            }
            let _ = writeln!(md, "{line}");
        }
    }
    let _ = writeln!(md);
}

/// Median best error so far against evaluations, one line per algorithm (log10 scale; a run at
/// the exact minimum counts as 1e-300).
fn convergence_png(
    out: &Path,
    problem: &Problem,
    algorithms: &[String],
    runs: &[Vec<RunResult>],
    evaluations: usize,
) -> Result<(), evoloop_report::plot::PlotError> {
    let x: Vec<f64> = (1..=study::CHECKPOINTS)
        .map(|k| (evaluations * k) as f64 / study::CHECKPOINTS as f64)
        .collect();
    let ys: Vec<Vec<f64>> = runs
        .iter()
        .map(|rs| {
            (0..study::CHECKPOINTS)
                .map(|k| {
                    let mut v: Vec<f64> = rs.iter().map(|r| r.curve[k]).collect();
                    v.sort_by(f64::total_cmp);
                    v[v.len() / 2].max(1e-300).log10()
                })
                .collect()
        })
        .collect();
    let series: Vec<XySeries> = algorithms
        .iter()
        .zip(&ys)
        .map(|(n, y)| XySeries {
            name: n,
            x: &x,
            y,
            style: Style::Line,
        })
        .collect();
    xy_png(
        &out.join("convergence").join(format!("{}.png", problem.key)),
        &format!("{}: median best error over runs", problem.key),
        "evaluations",
        "log10(f - f_min)",
        &series,
        None,
        None,
    )
}

/// Median evaluations per second of each algorithm on f(x) = x_0 (the objective costs about a
/// nanosecond: what is measured is the optimiser).
fn bench(a: &BenchArgs) -> Result<(), String> {
    if a.dim == 0 || a.population < 4 || a.evaluations < 2 * a.population || a.repeats == 0 {
        return Err(
            "--dim >= 1, --population >= 4, --evaluations >= 2 populations, --repeats >= 1".into(),
        );
    }
    let lower = vec![-1.0; a.dim];
    let upper = vec![1.0; a.dim];
    let mut rates = BTreeMap::new();
    let names: Vec<String> = match &a.algorithms {
        Some(v) => v.clone(),
        None => ALGORITHMS.iter().map(|s| s.to_string()).collect(),
    };
    for name in &names {
        let mut samples = Vec::with_capacity(a.repeats);
        for rep in 0..a.repeats {
            let mut opt = by_name::build(
                name,
                &lower,
                &upper,
                a.population,
                a.evaluations,
                rep as u64,
            )
            .map_err(|e| e.to_string())?;
            samples.push(evoloop_optim::overhead_rate(opt.as_mut(), a.evaluations));
        }
        samples.sort_by(f64::total_cmp);
        rates.insert(name.to_string(), samples[samples.len() / 2]);
    }
    if a.json {
        super::print_json(&json!({
            "dim": a.dim, "population": a.population, "evaluations": a.evaluations,
            "repeats": a.repeats, "threads": 1, "evals_per_s": rates,
        }));
    } else {
        out!(
            "optimiser overhead, D = {}, population {}, one thread (median of {}):",
            a.dim,
            a.population,
            a.repeats
        );
        for (n, r) in &rates {
            out!(
                "  {n:8} {:8.2} M evaluations/s  ({:.0} ns per evaluation)",
                r / 1e6,
                1e9 / r
            );
        }
    }
    Ok(())
}

fn functions(a: &FunctionsArgs) -> Result<(), String> {
    let problems = problem::problems(None, !a.no_shifted).map_err(|e| e.to_string())?;
    if a.json {
        let list: Vec<Value> = problems
            .iter()
            .map(|p| {
                let (lower, upper) = p.bounds();
                json!({
                    "key": p.key, "group": p.group(), "dim": p.function.dim,
                    "lower": lower, "upper": upper, "f_min": p.f_min(),
                    "shifted": p.shift.is_some(),
                })
            })
            .collect();
        super::print_json(&list);
        return Ok(());
    }
    out!(
        "{:24} {:12} {:>4}  {:>24}  f_min",
        "key",
        "group",
        "dim",
        "box"
    );
    for p in &problems {
        let (lower, upper) = p.bounds();
        let uniform = lower.iter().all(|l| *l == lower[0]) && upper.iter().all(|u| *u == upper[0]);
        let bx = if uniform {
            format!("[{}, {}]", lower[0], upper[0])
        } else {
            "per dimension".into()
        };
        out!(
            "{:24} {:12} {:>4}  {:>24}  {}",
            p.key,
            p.group(),
            p.function.dim,
            bx,
            p.f_min()
        );
    }
    Ok(())
}

/// The evaluation server of `evoloop optim serve` (protocol in its help).
fn serve(a: &ServeArgs) -> Result<(), String> {
    use std::io::{Read, Write};
    let problem = problem::problems(Some(std::slice::from_ref(&a.function)), false)
        .map_err(|e| e.to_string())?
        .pop()
        .ok_or("no function")?;
    let d = problem.function.dim;
    let (mut input, mut output) = (std::io::stdin().lock(), std::io::stdout().lock());
    let (mut bytes, mut point, mut answer) = (Vec::new(), vec![0.0; d], Vec::new());
    loop {
        let mut count = [0u8; 4];
        match input.read_exact(&mut count) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(format!("reading a request: {e}")),
        }
        let n = u32::from_le_bytes(count) as usize;
        bytes.resize(n * d * 8, 0);
        input
            .read_exact(&mut bytes)
            .map_err(|e| format!("reading {n} points of dimension {d}: {e}"))?;
        answer.clear();
        for row in bytes.chunks_exact(d * 8) {
            for (x, b) in point.iter_mut().zip(row.chunks_exact(8)) {
                *x = f64::from_le_bytes(b.try_into().unwrap_or([0; 8]));
            }
            answer.extend_from_slice(&problem.value(&point).to_le_bytes());
        }
        output
            .write_all(&answer)
            .and_then(|()| output.flush())
            .map_err(|e| format!("writing {n} values: {e}"))?;
    }
}

/// Per function of the study that the peers ran too: our best against theirs.
fn against_peers(s: &StudyRuns, p: &PeerRuns) -> Vec<(String, Comparison)> {
    let errors: Vec<Vec<Vec<f64>>> = s
        .runs
        .iter()
        .map(|by_alg| {
            by_alg
                .iter()
                .map(|runs| runs.iter().map(|r| r.error).collect())
                .collect()
        })
        .collect();
    s.problems
        .iter()
        .enumerate()
        .filter_map(|(i, problem)| {
            let theirs = p.errors.get(&problem.key)?;
            let ours = s
                .algorithms
                .iter()
                .zip(&errors[i])
                .map(|(n, e)| (n.as_str(), &e[..]));
            let c = peers::compare(ours, theirs.iter().map(|(n, e)| (n.as_str(), &e[..])))?;
            Some((problem.key.clone(), c))
        })
        .collect()
}

fn verdict_count(c: &[(String, Comparison)], v: Verdict) -> Vec<&str> {
    c.iter()
        .filter(|(_, c)| c.verdict == v)
        .map(|(k, _)| k.as_str())
        .collect()
}

fn peers_json(p: &PeerRuns, c: &[(String, Comparison)]) -> Value {
    let by_function: Map<String, Value> = c
        .iter()
        .map(|(k, c)| (k.clone(), serde_json::to_value(c).unwrap_or_default()))
        .collect();
    json!({
        "file": p.file,
        "algorithms": p.algorithms,
        "comparison": by_function,
        "beats": verdict_count(c, Verdict::Beats),
        "matches": verdict_count(c, Verdict::Matches),
        "loses": verdict_count(c, Verdict::Loses),
    })
}

fn peers_sentence(c: &[(String, Comparison)]) -> String {
    let loses = verdict_count(c, Verdict::Loses);
    format!(
        "against the peers file on {} functions: lower {}, no difference shown {}, higher {}{}",
        c.len(),
        verdict_count(c, Verdict::Beats).len(),
        verdict_count(c, Verdict::Matches).len(),
        loses.len(),
        if loses.is_empty() {
            String::new()
        } else {
            format!(" ({})", loses.join(", "))
        }
    )
}

fn peers_md(md: &mut String, p: &PeerRuns, c: &[(String, Comparison)]) {
    let _ = writeln!(md, "## Against other implementations ({})\n", p.file);
    let _ = writeln!(
        md,
        "Algorithms: {}. Per function, each side is represented by its algorithm with the lowest \
         mean error; their runs share no seeds with ours, so the test is Mann-Whitney's rank sum \
         (two-sided, 5 %), on the whole distribution (a lower median can win against a lower \
         mean). Errors below {:e} count as 0 (minimum reached; CEC's convention). Result: {}.\n",
        p.algorithms.join(", "),
        peers::SOLVED,
        peers_sentence(c)
    );
    let (leading, names) = (
        ["function", "ours", "mean error", "median"],
        ["theirs", "mean error", "median", "p", "ours is"],
    );
    header(md, &leading, &names);
    for (key, c) in c {
        let verdict = match c.verdict {
            Verdict::Beats => "lower",
            Verdict::Matches => "no difference shown",
            Verdict::Loses => "**higher**",
        };
        let _ = writeln!(
            md,
            "| {key} | {} | {} | {} | {} ({} runs) | {} | {} | {:.2e} | {verdict} |",
            c.ours.algorithm,
            sci(c.ours.mean_error),
            sci(c.ours.median_error),
            c.theirs.algorithm,
            c.theirs.runs,
            sci(c.theirs.mean_error),
            sci(c.theirs.median_error),
            c.test.p_two_sided
        );
    }
    let _ = writeln!(md);
}
