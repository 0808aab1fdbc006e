//! The selection study on every arm of a zoo (`evoloop rkgnn zoo`): arms generated from a
//! fixed list (config/robots/zoo.toml) that no setting was tuned on, each through
//! `selection::run`, and one table of each rule against each strongest baseline per arm, with
//! the models' errors. Across arms the claim is counted, not pooled: arms differ in scale, so
//! the table says on how many arms a rule is lower (each arm's own test over its seeds) and the
//! exact sign test of that count.

use super::selection::{Comparison, SelectionResult, STRONGEST};
use crate::stats::{median_of_numbers, sign_test};
use serde::Serialize;

/// The rules the zoo reports: the paper's max rule and the evidence rules.
pub const ZOO_RULES: [&str; 3] = ["fuzzy_max", "fuzzy_evidence", "uniform_evidence"];

/// One arm's line: what it is, how its identification went, each rule against each strongest
/// baseline over its seeds, its models' errors.
#[derive(Debug, Clone, Serialize)]
pub struct ZooArm {
    /// The arm's name in the zoo file (its study is in the directory of that name).
    pub arm: String,
    /// The arm's joint count.
    pub joints: usize,
    /// Seeds its study ran.
    pub seeds: u64,
    /// Training runs that gave no model, of all.
    pub unidentified: usize,
    /// Training runs in all: training trajectories x seeds.
    pub training_runs: usize,
    /// (model, task, seed) cases the controller refused (not positive definite along the task).
    pub refused: usize,
    /// Each rule against each strongest baseline over the arm's seeds (its study's comparisons).
    pub versus: Vec<Comparison>,
    /// Medians over seeds, tasks and models of the identified models' errors, and the nominal's.
    pub m_rel: f64,
    /// Median tr(M-hat) / tr(M): above 1, inflated models.
    pub m_scale: f64,
    /// Median relative error of G-hat.
    pub g_rel: f64,
    /// Median relative error of the nominal (CAD) model's M.
    pub nominal_m_rel: f64,
    /// Wall-clock time of the arm's selection study, s.
    pub seconds: f64,
}

/// Each rule the zoo reports with each strongest baseline.
fn rule_baselines() -> impl Iterator<Item = (&'static str, &'static str)> {
    (ZOO_RULES.iter()).flat_map(|rule| STRONGEST.iter().map(move |b| (*rule, *b)))
}

/// Across arms, one rule against one baseline.
#[derive(Debug, Clone, Serialize)]
pub struct Tally {
    /// The rule (one of `ZOO_RULES`).
    pub rule: String,
    /// The baseline (one of `STRONGEST`).
    pub baseline: String,
    /// Arms where both ran and their medians differ.
    pub arms: usize,
    /// Arms where the rule's median over seeds is lower.
    pub median_lower: usize,
    /// The exact sign test of `median_lower` of `arms`.
    pub sign_p: f64,
    /// Arms where the rule is lower with p < 0.05, and where the baseline is.
    pub held: usize,
    /// Arms where the baseline is lower with p < 0.05.
    pub lost: usize,
}

/// `zoo.json`.
#[derive(Debug, Clone, Serialize)]
pub struct ZooResult {
    /// The zoo file the arms were generated from.
    pub zoo: std::path::PathBuf,
    /// Seeds each arm's study ran.
    pub seeds: u64,
    /// One line per arm.
    pub arms: Vec<ZooArm>,
    /// Each rule against each strongest baseline, across the arms.
    pub tallies: Vec<Tally>,
    /// The whole zoo's wall-clock time, s.
    pub seconds: f64,
}

/// One arm's line from its selection study.
pub fn arm_line(name: &str, r: &SelectionResult) -> ZooArm {
    let versus = rule_baselines()
        .filter_map(|(rule, b)| {
            (r.comparisons.iter())
                .find(|c| c.rule == rule && c.baseline == b)
                .cloned()
        })
        .collect();
    let errors: Vec<_> = (r.cells.iter())
        .flat_map(|c| c.model_error.iter().flatten())
        .collect();
    let m = |f: &dyn Fn(&super::model_error::ModelError) -> f64| {
        median_of_numbers(errors.iter().map(|e| f(e)))
    };
    ZooArm {
        arm: name.into(),
        joints: r.joints,
        seeds: r.seeds,
        unidentified: r.unidentified.len(),
        training_runs: r.training.len() * r.seeds as usize,
        refused: r.cells.iter().map(|c| c.refused).sum(),
        versus,
        m_rel: m(&|e| e.m_rel),
        m_scale: m(&|e| e.m_scale),
        g_rel: m(&|e| e.g_rel),
        nominal_m_rel: median_of_numbers(r.cells.iter().map(|c| c.nominal_error.m_rel)),
        seconds: r.seconds,
    }
}

/// The tallies across `arms`.
pub fn tallies(arms: &[ZooArm]) -> Vec<Tally> {
    rule_baselines()
        .map(|(rule, b)| {
            // Arms where both ran and the medians differ (a tie, e.g. the evidence rule on a
            // single model against the best single model, counts neither way).
            let here: Vec<&Comparison> = (arms.iter())
                .filter_map(|a| a.versus.iter().find(|v| v.rule == rule && v.baseline == b))
                .filter(|v| !v.median_fuzzy.is_nan() && !v.median_baseline.is_nan())
                .filter(|v| v.median_fuzzy != v.median_baseline)
                .collect();
            let lower = here
                .iter()
                .filter(|v| v.median_fuzzy < v.median_baseline)
                .count();
            Tally {
                rule: rule.into(),
                baseline: b.into(),
                arms: here.len(),
                median_lower: lower,
                sign_p: sign_test(lower, here.len()),
                held: here.iter().filter(|v| v.rule_lower()).count(),
                lost: here.iter().filter(|v| v.baseline_lower()).count(),
            }
        })
        .collect()
}

/// zoo.md: the tallies, then per arm each rule against each baseline and the model errors.
pub fn report_markdown(z: &ZooResult) -> String {
    let mut md = format!(
        "# The arm controllers on the zoo\n\n{} arms of {}, {} seeds each (each seed \
         re-identifies the models and draws a new CAD model). Per arm, each rule against each \
         baseline over its seeds (Wilcoxon signed-rank, exact up to 30 seeds); across arms, on \
         how many arms the rule's median is lower, with the exact sign test of that count, and \
         on how many either side is lower with p < 0.05 on that arm's own seeds.\n\n\
         | rule | baseline | median lower | sign test p | rule lower, p < 0.05 | baseline lower, p < 0.05 |\n\
         |---|---|---|---|---|---|\n",
        z.arms.len(),
        z.zoo.display(),
        z.seeds
    );
    for t in &z.tallies {
        md += &format!(
            "| {} | {} | {} of {} arms | {:.2e} | {} | {} |\n",
            t.rule, t.baseline, t.median_lower, t.arms, t.sign_p, t.held, t.lost
        );
    }
    md += "\nPer arm: median RMS over seeds (rad) of each rule and baseline, seeds where the rule \
           is lower, Wilcoxon p; the identified models' errors along the tasks (medians: M-hat \
           relative error, tr(M-hat) / tr(M), G-hat relative error) and the CAD model's M error.\n\n\
           | arm | joints | no model | refused | rule | baseline | rule | baseline | lower | p |\n\
           |---|---|---|---|---|---|---|---|---|---|\n";
    for a in &z.arms {
        for v in &a.versus {
            md += &format!(
                "| {} | {} | {} of {} | {} | {} | {} | {:.4} | {:.4} | {} of {} | {:.2e} |\n",
                a.arm,
                a.joints,
                a.unidentified,
                a.training_runs,
                a.refused,
                v.rule,
                v.baseline,
                v.median_fuzzy,
                v.median_baseline,
                v.fuzzy_lower,
                v.pairs,
                v.wilcoxon.p_two_sided
            );
        }
    }
    md += "\n| arm | M-hat error | tr(M-hat) / tr(M) | G-hat error | CAD M error | study, s |\n\
           |---|---|---|---|---|---|\n";
    for a in &z.arms {
        md += &format!(
            "| {} | {:.3} | {:.3} | {:.3} | {:.3} | {:.0} |\n",
            a.arm, a.m_rel, a.m_scale, a.g_rel, a.nominal_m_rel, a.seconds
        );
    }
    md
}

/// zoo.json and zoo.md into `dir`.
pub fn write(dir: &std::path::Path, z: &ZooResult) -> Result<(), evoloop_schemes::WriteError> {
    use evoloop_schemes::WriteError;
    crate::report::write_json(dir, "zoo.json", z)
        .map_err(WriteError::file(&dir.join("zoo.json")))?;
    let md = dir.join("zoo.md");
    crate::files::write(&md, report_markdown(z)).map_err(WriteError::file(&md))
}
