//! `evoloop run <scenario> --seeds 1..20`: tuning alongside operation against the frozen
//! controller over many seeds, for the indirect scheme (`optimiser.mode = "indirect"`) and for
//! identification alongside operation (`"identify"`). Each seed is a whole run of the processes
//! (plant noise and the optimiser's random streams from the seed); its frozen comparison is the
//! same scenario and seed with the optimiser off (the in-process simulation, bit-identical to a
//! lockstep run of the processes). Per seed, tuned and frozen, the `Measure` of the mode before
//! the plant's change and over the last quarter of the run: the mean cost per repetition
//! (indirect) or the tracking RMS over all joints (identify). Across seeds: mean with a 95 %
//! interval of each, the paired differences, and a paired Wilcoxon test; every sentence of the
//! report follows from those numbers.

use crate::config::OptimiserMode;
use crate::report::Csv;
use crate::run_report::summary::Summary;
use crate::stats::{lower_first, mean_ci, paired_sentence, wilcoxon, MeanCi, Wilcoxon};
use evoloop_schemes::WriteError;
use serde::Serialize;
use std::path::Path;

/// What a study compares: the scheme and the number it is judged by.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Measure {
    /// The scheme, as a sentence's subject.
    pub scheme: &'static str,
    /// The scheme's runs in one word ("tuned" against "frozen").
    pub short: &'static str,
    /// What is compared, lower is better.
    pub what: &'static str,
    /// The prefix of seeds.csv's columns.
    pub column: &'static str,
    /// How the number is taken, for the report.
    #[serde(skip)]
    how: &'static str,
    /// The summary's keys of the number before the change, its frozen twin, after, and its
    /// frozen twin; their values; the factor into the study's unit.
    #[serde(skip)]
    keys: [&'static str; 4],
    #[serde(skip)]
    read: fn(&Summary) -> [Option<f64>; 4],
    #[serde(skip)]
    scale: f64,
    /// Whether the scheme estimates a model parameter (`model_estimate_error`).
    #[serde(skip)]
    estimates: bool,
}

impl Measure {
    /// The indirect scheme's measure: cost per repetition, from `cost_before_change`,
    /// `cost_after_change` and their frozen twins.
    pub const INDIRECT: Measure = Measure {
        scheme: "The indirect scheme",
        short: "tuned",
        what: "cost per repetition",
        column: "cost",
        how: "Cost per repetition of the reference: mean over the repetitions before the plant's \
              change (the first, from rest, left out) and over the last quarter of the run.",
        keys: [
            "cost_before_change",
            "cost_before_change_frozen",
            "cost_after_change",
            "cost_after_change_frozen",
        ],
        read: |s| {
            [
                s.cost_before_change,
                s.cost_before_change_frozen,
                s.cost_after_change,
                s.cost_after_change_frozen,
            ]
        },
        scale: 1.0,
        estimates: true,
    };
    /// Identification alongside operation's measure: tracking RMS over all joints, mrad, from
    /// `tracking_before_change`, `tracking_after_change` and their frozen twins.
    pub const IDENTIFY: Measure = Measure {
        scheme: "Identification alongside operation",
        short: "identified",
        what: "tracking RMS over all joints (mrad)",
        column: "tracking_mrad",
        how: "Tracking RMS over all joints, mrad: from 1 s (past start-up) to the plant's change, \
              and over the last quarter of the run; the frozen controller keeps the models it \
              started with.",
        keys: [
            "tracking_before_change",
            "tracking_before_change_frozen",
            "tracking_after_change",
            "tracking_after_change_frozen",
        ],
        read: |s| {
            [
                s.tracking_before_change,
                s.tracking_before_change_frozen,
                s.tracking_after_change,
                s.tracking_after_change_frozen,
            ]
        },
        scale: 1e3,
        estimates: false,
    };

    /// The measure of a mode that tunes alongside operation; None for the others.
    pub fn of(mode: OptimiserMode) -> Option<Measure> {
        match mode {
            OptimiserMode::Indirect => Some(Self::INDIRECT),
            OptimiserMode::Identify => Some(Self::IDENTIFY),
            _ => None,
        }
    }
}

/// One seed's run, from its summary.json.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct SeedRun {
    /// The seed the run was made with.
    pub seed: u64,
    /// Tuned and frozen before the plant's change; None when the plant does not change.
    pub before: Option<(f64, f64)>,
    /// The scheme's number over the last quarter of the run (after the change, if any), in the
    /// measure's unit.
    pub after: f64,
    /// The frozen controller's number over the same quarter.
    pub after_frozen: f64,
    /// The final model estimate's relative error (the indirect scheme's estimator).
    pub estimate_error: Option<f64>,
    /// Parameter sets the controller put in service during the run.
    pub accepted: u64,
    /// Parameter sets the controller refused during the run.
    pub rejected: u64,
}

/// A seed's summary.json without a number the study reads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MissingNumber {
    /// The seed.
    pub seed: u64,
    /// The summary's key.
    pub key: &'static str,
}

impl std::fmt::Display for MissingNumber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "summary.json of seed {} has no number `{}`",
            self.seed, self.key
        )
    }
}

impl std::error::Error for MissingNumber {}

impl SeedRun {
    /// Take what the study needs from a run's summary, of a scenario whose plant `changed`
    /// (else it has no "before"); an error names what is missing.
    pub fn from_summary(
        seed: u64,
        s: &Summary,
        m: &Measure,
        changed: bool,
    ) -> Result<Self, MissingNumber> {
        let f = |v: Option<f64>, key: &'static str| v.ok_or(MissingNumber { seed, key });
        let [b, bf, a, af] = (m.read)(s);
        let before = match changed {
            true => Some((m.scale * f(b, m.keys[0])?, m.scale * f(bf, m.keys[1])?)),
            false => None,
        };
        let after = m.scale * f(a, m.keys[2])?;
        let after_frozen = m.scale * f(af, m.keys[3])?;
        let estimate_error = if m.estimates {
            Some(f(s.model_estimate_error, "model_estimate_error")?)
        } else {
            None
        };
        Ok(Self {
            seed,
            before,
            after,
            after_frozen,
            estimate_error,
            accepted: s.accepted_versions as u64,
            rejected: s.rejected_versions as u64,
        })
    }
}

/// Tuned against frozen over the seeds, for one phase of the run.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseComparison {
    /// "before the change", "after the change", or "over the last quarter" (a plant without a
    /// change).
    pub phase: &'static str,
    /// The scheme's mean over the seeds, with its 95 % interval.
    pub tuned: MeanCi,
    /// The frozen controller's mean over the seeds, with its 95 % interval.
    pub frozen: MeanCi,
    /// tuned - frozen per seed.
    pub difference: MeanCi,
    /// (tuned - frozen) / frozen per seed, in %.
    pub relative_pct: MeanCi,
    /// The paired Wilcoxon signed-rank test of tuned against frozen.
    pub wilcoxon: Wilcoxon,
    /// What the comparison shows, one sentence computed from `wilcoxon` and `difference`
    /// (`paired_sentence`).
    pub sentence: String,
}

fn compare(m: &Measure, phase: &'static str, tuned: &[f64], frozen: &[f64]) -> PhaseComparison {
    let d: Vec<f64> = tuned.iter().zip(frozen).map(|(a, b)| a - b).collect();
    let rel: Vec<f64> = tuned
        .iter()
        .zip(frozen)
        .map(|(a, b)| 100.0 * (a - b) / b)
        .collect();
    let w = wilcoxon(tuned, frozen);
    let difference = mean_ci(&d);
    PhaseComparison {
        phase,
        tuned: mean_ci(tuned),
        frozen: mean_ci(frozen),
        relative_pct: mean_ci(&rel),
        sentence: paired_sentence(
            m.scheme,
            m.short,
            "the frozen controller",
            &format!("{} {phase}", m.what),
            &w,
            &difference,
        ),
        difference,
        wilcoxon: w,
    }
}

/// The phase before the plant's change.
const BEFORE: &str = "before the change";

/// The last quarter's phase: after the plant's change, if it has one.
pub fn after_phase(changed: bool) -> &'static str {
    if changed {
        "after the change"
    } else {
        "over the last quarter"
    }
}

/// The study over `runs`; `failed` lists seeds whose run did not complete, with the reason.
#[derive(Debug, Clone, Serialize)]
pub struct Study {
    /// The scenario's name.
    pub scenario: String,
    /// What is compared, and how.
    pub measure: Measure,
    /// The seeds whose runs completed, in the order run: the study's samples.
    pub seeds: Vec<u64>,
    /// Seeds whose run did not complete, each with the reason; not in the statistics.
    pub failed: Vec<(u64, String)>,
    /// Tuned against frozen per phase: before the change (when the plant changes), then the
    /// last quarter.
    pub comparisons: Vec<PhaseComparison>,
    /// Over the seeds that report one (the indirect scheme's estimator).
    pub estimate_error_pct: Option<MeanCi>,
    /// Parameter sets accepted per run: mean over the seeds, with its 95 % interval.
    pub accepted: MeanCi,
    /// Parameter sets the controller refused, summed over all runs.
    pub rejected_total: u64,
}

impl Study {
    /// The study of `runs`: a comparison per phase (before the change only when every run has
    /// a `before`), the estimate error when every run reports one, and the sets' counts; `failed`
    /// is kept as given for the report.
    pub fn new(
        scenario: &str,
        measure: Measure,
        runs: &[SeedRun],
        failed: Vec<(u64, String)>,
    ) -> Self {
        let col = |f: fn(&SeedRun) -> f64| runs.iter().map(f).collect::<Vec<f64>>();
        let m = &measure;
        let errors: Vec<f64> = runs.iter().filter_map(|r| r.estimate_error).collect();
        let before: Option<Vec<(f64, f64)>> = runs.iter().map(|r| r.before).collect();
        let mut comparisons = Vec::new();
        if let Some(before) = &before {
            let (tuned, frozen): (Vec<f64>, Vec<f64>) = before.iter().copied().unzip();
            comparisons.push(compare(m, BEFORE, &tuned, &frozen));
        }
        comparisons.push(compare(
            m,
            after_phase(before.is_some()),
            &col(|r| r.after),
            &col(|r| r.after_frozen),
        ));
        Self {
            scenario: scenario.to_string(),
            measure,
            seeds: runs.iter().map(|r| r.seed).collect(),
            failed,
            comparisons,
            estimate_error_pct: (errors.len() == runs.len() && !errors.is_empty())
                .then(|| mean_ci(&errors.iter().map(|e| 100.0 * e).collect::<Vec<f64>>())),
            accepted: mean_ci(&col(|r| r.accepted as f64)),
            rejected_total: runs.iter().map(|r| r.rejected).sum(),
        }
    }

    /// Whether the runs' plant changed: the study then compares before the change too.
    fn changed(&self) -> bool {
        self.comparisons.iter().any(|c| c.phase == BEFORE)
    }

    /// The report as Markdown: the table, then one computed sentence per comparison.
    pub fn markdown(&self) -> String {
        let f = |m: &MeanCi| format!("{:.1} [{:.1} .. {:.1}]", m.mean, m.ci95[0], m.ci95[1]);
        let m = &self.measure;
        let how = m.how;
        let note = match self.changed() {
            true => "",
            false => " The plant does not change: the last quarter alone is compared.",
        };
        let mut md = format!(
            "# {}: {} against the frozen controller over {} seeds\n\n\
             Each seed is a lockstep run of the processes (plant noise and the optimiser's random \
             streams from the seed); its frozen comparison is the same scenario and seed with the \
             optimiser off. {how}{note}\n\n\
             | phase | {s} mean [95 % CI] | frozen mean [95 % CI] | {s} - frozen [95 % CI] | relative, % [95 % CI] |\n|---|---|---|---|---|\n",
            self.scenario,
            lower_first(m.scheme),
            self.seeds.len(),
            s = m.short,
        );
        for c in &self.comparisons {
            md.push_str(&format!(
                "| {} | {} | {} | {} | {:+.2} [{:+.2} .. {:+.2}] |\n",
                c.phase,
                f(&c.tuned),
                f(&c.frozen),
                f(&c.difference),
                c.relative_pct.mean,
                c.relative_pct.ci95[0],
                c.relative_pct.ci95[1]
            ));
        }
        md.push_str("\nWhat the data show (each sentence computed from its paired test):\n\n");
        for c in &self.comparisons {
            md.push_str(&format!("- {}\n", c.sentence));
        }
        if let Some(e) = &self.estimate_error_pct {
            md.push_str(&format!(
                "- Final model estimate error: mean {:+.2} % (95 % CI {:+.2} .. {:+.2}).\n",
                e.mean, e.ci95[0], e.ci95[1],
            ));
        }
        md.push_str(&format!(
            "- Sets accepted per run: mean {:.1}; sets the controller rejected: {} in all runs.\n",
            self.accepted.mean, self.rejected_total
        ));
        if !self.failed.is_empty() {
            md.push_str(&format!(
                "- {} seed(s) did not complete and are not in the statistics: {}.\n",
                self.failed.len(),
                self.failed
                    .iter()
                    .map(|(s, why)| format!("{s} ({why})"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        md
    }

    /// Write `seeds.csv`, `study.json`, `study.md` and (with `plots`) `study_cost.png` to `out`.
    pub fn write(&self, out: &Path, runs: &[SeedRun], plots: bool) -> Result<(), WriteError> {
        let c = self.measure.column;
        let mut csv = Csv::new([
            "seed".to_string(),
            format!("{c}_before"),
            format!("{c}_before_frozen"),
            format!("{c}_after"),
            format!("{c}_after_frozen"),
            "estimate_error".into(),
            "accepted".into(),
            "rejected".into(),
        ]);
        for r in runs {
            let (before, before_frozen) = r.before.unwrap_or((f64::NAN, f64::NAN));
            csv.row()
                .put(r.seed)
                .all([before, before_frozen, r.after, r.after_frozen])
                .put(r.estimate_error.unwrap_or(f64::NAN))
                .put(r.accepted)
                .put(r.rejected);
        }
        let file = out.join("seeds.csv");
        csv.write(&file).map_err(WriteError::file(&file))?;
        crate::report::write_json(out, "study.json", self)
            .map_err(WriteError::file(&out.join("study.json")))?;
        let md = out.join("study.md");
        crate::files::write(&md, self.markdown()).map_err(WriteError::file(&md))?;
        if plots && !runs.is_empty() {
            use crate::report::plot::{xy_png, Curve, Style, XySeries};
            let xs: Vec<f64> = runs.iter().map(|r| r.seed as f64).collect();
            let rel = |ab: &dyn Fn(&SeedRun) -> Option<(f64, f64)>| {
                runs.iter()
                    .filter_map(ab)
                    .map(|(a, b)| 100.0 * (a - b) / b)
                    .collect::<Vec<f64>>()
            };
            let n = xs.len();
            let changed = self.changed();
            let mut curves: Vec<Curve> = vec![(
                after_phase(changed).into(),
                xs.clone(),
                rel(&|r| Some((r.after, r.after_frozen))),
            )];
            if changed {
                curves.push((BEFORE.into(), xs.clone(), rel(&|r| r.before)));
            }
            let mut series = XySeries::from_curves(&curves, Style::Points);
            let zero = vec![0.0; n];
            series.push(XySeries {
                name: "",
                x: &xs,
                y: &zero,
                style: Style::Line,
            });
            xy_png(
                &out.join("study_cost.png"),
                &format!(
                    "{}: {} vs frozen {} per seed (below 0: {} is lower)",
                    self.scenario,
                    self.measure.short,
                    self.measure.what,
                    lower_first(self.measure.scheme)
                ),
                "seed",
                &format!("({} - frozen) / frozen, %", self.measure.short),
                &series,
                None,
                None,
            )
            .map_err(WriteError::Figure)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(seed: u64, after: f64, after_frozen: f64) -> SeedRun {
        SeedRun {
            seed,
            before: Some((100.0 + seed as f64, 100.0 + seed as f64)),
            after,
            after_frozen,
            estimate_error: Some(0.01),
            accepted: 3,
            rejected: 0,
        }
    }

    /// The sentences follow the numbers: tuned cheaper on every seed is "lower"; dearer on every
    /// seed is "HIGHER"; identical before the change is "no difference".
    #[test]
    fn the_report_says_what_its_numbers_say() {
        let better: Vec<SeedRun> = (1..=8)
            .map(|s| run(s, 50.0 + s as f64, 80.0 + 2.0 * s as f64))
            .collect();
        let st = Study::new("x", Measure::INDIRECT, &better, Vec::new());
        assert!(
            st.comparisons[1].sentence.starts_with(
                "The indirect scheme has a lower cost per repetition after the change"
            ),
            "{}",
            st.comparisons[1].sentence
        );
        assert!(
            st.comparisons[0].sentence.starts_with("No difference"),
            "{}",
            st.comparisons[0].sentence
        );
        assert_eq!(st.comparisons[1].wilcoxon.a_lower, 8);
        let worse: Vec<SeedRun> = (1..=8)
            .map(|s| run(s, 90.0 + s as f64, 80.0 + s as f64))
            .collect();
        let st = Study::new(
            "x",
            Measure::INDIRECT,
            &worse,
            vec![(9, "timed out".into())],
        );
        assert!(
            st.comparisons[1].sentence.contains("HIGHER"),
            "{}",
            st.comparisons[1].sentence
        );
        let md = st.markdown();
        assert!(
            md.contains("over 8 seeds") && md.contains("9 (timed out)"),
            "{md}"
        );
        assert!((st.comparisons[1].relative_pct.mean - 100.0 * (10.0 / 84.5f64)).abs() < 1.0);
    }

    #[test]
    fn a_summary_without_the_frozen_comparison_is_refused_by_name() {
        let s = Summary {
            cost_before_change: Some(1.0),
            ..Default::default()
        };
        let e = SeedRun::from_summary(3, &s, &Measure::INDIRECT, true).unwrap_err();
        assert_eq!(e.key, "cost_before_change_frozen");
        let e = e.to_string();
        assert!(
            e.contains("seed 3") && e.contains("cost_before_change_frozen"),
            "{e}"
        );
    }

    /// A plant without a change (arm3_identify): its summary has no "before"; the study
    /// compares the last quarter only, and says so.
    #[test]
    fn a_plant_without_a_change_is_compared_over_the_last_quarter() {
        let s = Summary {
            tracking_after_change: Some(0.002),
            tracking_after_change_frozen: Some(0.003),
            ..Default::default()
        };
        let r = SeedRun::from_summary(1, &s, &Measure::IDENTIFY, false).unwrap();
        assert_eq!(r.before, None);
        assert_eq!((r.after, r.after_frozen), (2.0, 3.0));
        let runs: Vec<SeedRun> = (1..=6)
            .map(|seed| SeedRun {
                seed,
                after: 2.0 + 0.01 * seed as f64,
                ..r.clone()
            })
            .collect();
        let st = Study::new("x", Measure::IDENTIFY, &runs, Vec::new());
        assert_eq!(st.comparisons.len(), 1);
        assert_eq!(st.comparisons[0].phase, "over the last quarter");
        assert_eq!(st.comparisons[0].wilcoxon.a_lower, 6);
        let md = st.markdown();
        assert!(md.contains("| over the last quarter |") && md.contains("does not change"));
        // A plant that changes needs both numbers before the change.
        let half = Summary {
            tracking_before_change: Some(0.002),
            ..s
        };
        let e = SeedRun::from_summary(2, &half, &Measure::IDENTIFY, true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tracking_before_change_frozen"), "{e}");
    }
}
