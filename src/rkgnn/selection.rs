//! A selection study that can fail (`evoloop rkgnn selection`): is fuzzy selection among
//! identified models better than the best single model, on trajectories it was not built for?
//!
//! The study of `study.rs` is the paper's own case, where the new trajectory is the exact
//! midpoint of the two training ones (the memberships tie and the max rule dithers). Here three
//! training trajectories give three models (the shipped recipe: the training servo known, least
//! squares), and four new trajectories are tracked that are not midpoints: two between training
//! regions but nearer one, one partly beyond them, one at other frequencies. On each, per seed:
//! the training P-D servo, a P-D servo gain-matched to computed torque (k_p = M_jj,mid x 900,
//! k_d = M_jj,mid x 60 with the arm's mid-range inertia: the same bandwidth and damping), computed
//! torque on the true model, on each model alone, fuzzy selection (max, blend) and a uniform blend
//! (the blend with memberships flattened, gamma = 1e6). Computed from those: the best single model
//! in hindsight (per trajectory and seed) and a random single model (the mean of the three, what
//! choosing one blindly gives on average). Seeds change the measurement noise of every run and
//! the training trajectories themselves (seed 1: as written; others: offsets and amplitudes
//! moved, `Sines::for_seed`), and the models are re-identified on each seed's training data.
//! The comparisons are paired Wilcoxon signed-rank tests over (seed, trajectory) pairs.

use super::identify::{self, Prior, Settings};
use super::study::{
    case, controller, diagonal_mid, float_list, gains, pd_servo, simulate_all, three_joint_arm,
    trajectory_positions, Case, JOINTS,
};
use crate::control::fuzzy_computed_torque::check_along_reference;
use crate::report::stats::{median, wilcoxon, Wilcoxon};
use crate::rkgnn::Trajectory;
use crate::sim::JointTraces;
use serde::Serialize;
use std::path::{Path, PathBuf};

const BASE: &str = include_str!("../../config/arm3_train1.toml");

/// A sines reference: offsets per joint, amplitudes per joint per frequency, frequencies (Hz).
#[derive(Clone, Copy)]
struct Sines {
    name: &'static str,
    offsets: [f64; 3],
    amplitudes: [[f64; 2]; 3],
    frequencies: [f64; 2],
}

/// The three training trajectories: the paper's two (the shipped `arm3_train1`, `arm3_train2`)
/// and a third nearer the arm's upright pose.
const TRAINING: [Sines; 3] = [
    Sines {
        name: "train1",
        offsets: [0.0, 0.5, -1.0],
        amplitudes: [[0.8, 0.2], [0.3, 0.1], [0.5, 0.15]],
        frequencies: [0.2, 0.5],
    },
    Sines {
        name: "train2",
        offsets: [0.0, 0.9, -1.6],
        amplitudes: [[1.2, 0.3], [0.5, 0.15], [0.7, 0.2]],
        frequencies: [0.2, 0.5],
    },
    Sines {
        name: "train3",
        offsets: [0.4, 0.2, -0.5],
        amplitudes: [[0.6, 0.15], [0.25, 0.1], [0.4, 0.1]],
        frequencies: [0.2, 0.5],
    },
];

/// The new trajectories, none a midpoint of training ones.
const NEW: [Sines; 4] = [
    // Between train1 and train2, a third of the way from train1.
    Sines {
        name: "near1",
        offsets: [0.1, 0.63, -1.2],
        amplitudes: [[0.9, 0.2], [0.35, 0.1], [0.55, 0.2]],
        frequencies: [0.2, 0.5],
    },
    // Between train3 and train1, nearer train3.
    Sines {
        name: "near3",
        offsets: [0.3, 0.3, -0.65],
        amplitudes: [[0.7, 0.2], [0.3, 0.12], [0.45, 0.12]],
        frequencies: [0.2, 0.5],
    },
    // Partly beyond train2: the shoulder higher, the forearm further folded.
    Sines {
        name: "beyond2",
        offsets: [-0.2, 1.1, -1.9],
        amplitudes: [[1.0, 0.3], [0.4, 0.15], [0.5, 0.2]],
        frequencies: [0.2, 0.5],
    },
    // Train1's region at other frequencies (the premises are compared at equal times).
    Sines {
        name: "faster1",
        offsets: [0.0, 0.6, -1.1],
        amplitudes: [[0.6, 0.2], [0.25, 0.1], [0.4, 0.15]],
        frequencies: [0.3, 0.7],
    },
];

/// The controllers run on each new trajectory, in the table's order.
pub const RUN: [&str; 9] = [
    "pd",
    "pd_matched",
    "ct_true",
    "ct_model_1",
    "ct_model_2",
    "ct_model_3",
    "fuzzy_max",
    "fuzzy_blend",
    "uniform_blend",
];
/// ... and those computed from the single models.
pub const DERIVED: [&str; 2] = ["best_single", "random_single"];

/// Computed torque's error dynamics (rad/s^2 per rad and per rad/s) the matched servo copies.
const MATCH: (f64, f64) = (900.0, 60.0);
/// gamma of the uniform blend: memberships within 1e-12 of 1 over any trajectory here.
const UNIFORM_GAMMA: f64 = 1e6;

/// What `evoloop rkgnn selection` is asked for.
#[derive(Debug, Clone)]
pub struct SelectionSettings {
    pub robot: PathBuf,
    pub seeds: u64,
    pub threads: usize,
}

/// One (seed, trajectory): each controller's RMS error per joint and overall.
#[derive(Debug, Clone, Serialize)]
pub struct Cell {
    pub seed: u64,
    pub trajectory: &'static str,
    /// Controller key -> per-joint RMS (rad), `RUN` then `DERIVED` order.
    pub rms: Vec<(String, Vec<f64>)>,
    /// The max rule's model switches per second.
    pub switches_per_s: f64,
    /// Share of samples on which each model was selected (max rule).
    pub share: Vec<f64>,
    /// M-hat's smallest eigenvalue along this trajectory, per model.
    pub min_eig_on_reference: Vec<f64>,
    /// Models the controller refused on this trajectory (not positive definite along it):
    /// left out alone (their rms is null) and from the fuzzy sets.
    pub refused: usize,
}

/// A paired comparison of a fuzzy rule with one baseline over every (seed, trajectory).
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// `fuzzy_max` (the paper's rule) or `fuzzy_blend`.
    pub rule: String,
    pub baseline: String,
    pub median_fuzzy: f64,
    pub median_baseline: f64,
    /// Pairs where fuzzy max is lower.
    pub fuzzy_lower: usize,
    pub pairs: usize,
    pub wilcoxon: Wilcoxon,
}

/// `selection.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SelectionResult {
    pub robot: PathBuf,
    pub seeds: u64,
    pub training: Vec<&'static str>,
    pub trajectories: Vec<&'static str>,
    /// Eq. 2's bounds given to the identification (over the joint limits).
    pub prior: Prior,
    pub cells: Vec<Cell>,
    /// Per trajectory, the median overall RMS of each controller.
    pub medians: Vec<(String, Vec<(String, f64)>)>,
    pub comparisons: Vec<Comparison>,
    /// Whether fuzzy max (the paper's rule) is below the best single model in hindsight:
    /// median lower and Wilcoxon p < 0.05 with fuzzy lower.
    pub claim_held: bool,
    /// The same for the blend.
    pub claim_held_blend: bool,
    pub seconds: f64,
}

fn overall(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

impl Sines {
    /// The training trajectory of identification seed `seed`: seed 1 is the trajectory as
    /// written (the shipped models' data); each other seed moves every offset by up to
    /// +-OFFSET_SPREAD rad and scales every amplitude by 1 +- AMPLITUDE_SPREAD (uniform,
    /// seeded by seed and trajectory), so that each seed identifies its models from other data,
    /// not only other encoder noise.
    fn for_seed(&self, seed: u64, index: usize) -> Sines {
        use rand::{Rng, SeedableRng};
        if seed == 1 {
            return *self;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 * seed + index as u64);
        let mut s = *self;
        for j in 0..JOINTS {
            s.offsets[j] += rng.gen_range(-OFFSET_SPREAD..=OFFSET_SPREAD);
            for a in &mut s.amplitudes[j] {
                *a *= 1.0 + rng.gen_range(-AMPLITUDE_SPREAD..=AMPLITUDE_SPREAD);
            }
        }
        s
    }
}

/// How far an identification seed moves a training trajectory (`Sines::for_seed`): offsets,
/// rad, and amplitudes, relative.
const OFFSET_SPREAD: f64 = 0.1;
const AMPLITUDE_SPREAD: f64 = 0.15;

/// `base` with its reference replaced by `s`.
fn with_reference(s: &Sines) -> Result<String, String> {
    let mut t: toml::Table = BASE
        .parse()
        .map_err(|e| format!("built-in scenario: {e}"))?;
    let mut r = toml::Table::new();
    r.insert("kind".into(), "sines".into());
    r.insert("frequencies".into(), float_list(&s.frequencies));
    r.insert("offsets".into(), float_list(&s.offsets));
    let amps = s.amplitudes.iter().map(|a| float_list(a)).collect();
    r.insert("amplitudes".into(), toml::Value::Array(amps));
    t.insert("reference".into(), r.into());
    toml::to_string(&t).map_err(|e| e.to_string())
}

/// Run the study into `dir`; `progress(done, total, stage)`.
pub fn run(
    s: &SelectionSettings,
    dir: &Path,
    progress: &(dyn Fn(u64, u64, &str) + Sync),
) -> Result<SelectionResult, String> {
    let t0 = std::time::Instant::now();
    if s.seeds == 0 {
        return Err("--seeds must be >= 1".into());
    }
    let (robot, arm) = three_joint_arm(&s.robot, dir)?;
    let g = gains()?;
    let texts: Vec<String> = TRAINING
        .iter()
        .chain(&NEW)
        .map(with_reference)
        .collect::<Result<_, _>>()?;
    let pd = pd_servo;
    // Every trajectory must stay within the arm's limits: `case` parses each probe's
    // scenario, whose check refuses a reference that leaves one (plant::arm).
    let probe: Vec<Case> = texts
        .iter()
        .enumerate()
        .map(|(k, t)| {
            case(
                &format!("probe{k}"),
                t,
                &robot,
                1,
                pd(&g.servo[0], &g.servo[1]),
                dir,
            )
        })
        .collect::<Result<_, _>>()?;
    let qs = trajectory_positions(&probe.iter().map(|c| &c.scenario).collect::<Vec<_>>());
    let mid = diagonal_mid(&arm, &qs);
    let matched = (
        mid.iter().map(|m| m * MATCH.0).collect::<Vec<_>>(),
        mid.iter().map(|m| m * MATCH.1).collect::<Vec<_>>(),
    );
    let workspace = identify::limit_positions(&arm, identify::LIMIT_SAMPLES);
    let prior = Prior::of_model(&arm, workspace.iter().map(Vec::as_slice));
    let (servo_kp, servo_kd) = (&g.servo[0], &g.servo[1]);
    let total = s.seeds * (TRAINING.len() + NEW.len() * RUN.len()) as u64;
    let step = std::sync::atomic::AtomicU64::new(0);
    let tick = |stage: &str| {
        let k = step.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(k, total, stage);
    };
    let mut cells = Vec::new();
    for seed in 1..=s.seeds {
        let sd = dir.join(format!("seed{seed}"));
        std::fs::create_dir_all(&sd).map_err(|e| format!("{}: {e}", sd.display()))?;
        // Training runs (this seed's trajectories) and the three models.
        let training: Vec<Case> = TRAINING
            .iter()
            .enumerate()
            .map(|(k, tr)| {
                let text = with_reference(&tr.for_seed(seed, k))?;
                case(tr.name, &text, &robot, seed, pd(servo_kp, servo_kd), &sd)
            })
            .collect::<Result<_, _>>()?;
        let sims = simulate_all(&training, s.threads, &|| tick("training run"));
        let mut models = Vec::new();
        for (c, sim) in training.iter().zip(&sims) {
            let data =
                Trajectory::from_sim(&sim.rows, &c.scenario.reference, c.scenario.timing.period);
            let mut settings = Settings::least_squares(JOINTS, seed, 0);
            settings.threads = s.threads.max(1);
            settings.servo = identify::ServoPrior::Known {
                kp: servo_kp.clone(),
                kd: servo_kd.clone(),
                limits: Some(arm.bodies.iter().map(|b| b.limits.effort).collect()),
            };
            let model =
                identify::identify_model(&data, &prior, &settings, c.name.clone(), |_, _| {})?;
            let file = sd.join(format!("model_{}.json", c.name));
            model.save(&file)?;
            models.push((file, model));
        }
        let files: Vec<&PathBuf> = models.iter().map(|(f, _)| f).collect();
        let fuzzy = |list: &[&PathBuf], selection: &str, gamma| g.fuzzy(list, selection, gamma);
        let ct_true = controller("computed_torque", g.ct_table());
        for (i, (tr, text)) in NEW.iter().zip(&texts[TRAINING.len()..]).enumerate() {
            // The controller refuses a model whose M-hat is not positive definite along the
            // reference (control::fuzzy_computed_torque): such a model is left out here as a
            // user would leave it out, alone and in the fuzzy sets.
            let reference = &probe[TRAINING.len() + i].scenario;
            let duration = reference.timing.duration;
            let along = crate::control::fuzzy_computed_torque::reference_positions(
                &reference.reference,
                duration,
            );
            // The controller's own check, once per model: it gives the smallest eigenvalue along
            // the reference when the model passes; a refused one's is looked up in full.
            let checked: Vec<Result<f64, String>> = models
                .iter()
                .map(|(_, m)| check_along_reference(m, &along))
                .collect();
            let usable: Vec<bool> = checked.iter().map(Result::is_ok).collect();
            let min_eig_on_reference: Vec<f64> = models
                .iter()
                .zip(&checked)
                .map(|((_, m), c)| match c {
                    Ok(lowest) => *lowest,
                    Err(_) => m.min_eig(along.iter().map(Vec::as_slice)),
                })
                .collect();
            // The usable models' indices: slot k of the fuzzy sets is model kept_idx[k].
            let kept_idx: Vec<usize> = (0..models.len()).filter(|&k| usable[k]).collect();
            let kept: Vec<&PathBuf> = kept_idx.iter().map(|&k| files[k]).collect();
            let single = |k: usize| usable[k].then(|| fuzzy(&files[k..k + 1], "max", None));
            let any = !kept.is_empty();
            let laws = [
                Some(pd(servo_kp, servo_kd)),
                Some(pd(&matched.0, &matched.1)),
                Some(ct_true.clone()),
                single(0),
                single(1),
                single(2),
                any.then(|| fuzzy(&kept, "max", None)),
                any.then(|| fuzzy(&kept, "blend", None)),
                any.then(|| fuzzy(&kept, "blend", Some(UNIFORM_GAMMA))),
            ];
            let runnable: Vec<(&str, toml::Table)> = RUN
                .iter()
                .zip(laws)
                .filter_map(|(k, law)| law.map(|l| (*k, l)))
                .collect();
            let cases: Vec<Case> = runnable
                .iter()
                .map(|(k, law)| {
                    case(
                        &format!("{}_{k}", tr.name),
                        text,
                        &robot,
                        seed,
                        law.clone(),
                        &sd,
                    )
                })
                .collect::<Result<_, _>>()?;
            let sims = simulate_all(&cases, s.threads, &|| tick("tracking run"));
            let ran = |key: &str| runnable.iter().position(|(k, _)| *k == key);
            // A run not made (a refused model) is NaN, left out of every comparison; a run made
            // whose error is not finite (it diverged) is +inf, the worst of all.
            let mut rms: Vec<(String, Vec<f64>)> = RUN
                .iter()
                .map(|k| {
                    let v = ran(k).map_or(vec![f64::NAN; JOINTS], |c| {
                        let v =
                            JointTraces::of(&sims[c], &cases[c].scenario.reference, JOINTS).rms();
                        if overall(&v).is_finite() {
                            v
                        } else {
                            vec![f64::INFINITY; JOINTS]
                        }
                    });
                    (k.to_string(), v)
                })
                .collect();
            let singles: Vec<&Vec<f64>> = rms[3..6]
                .iter()
                .map(|(_, v)| v)
                .filter(|v| !overall(v).is_nan())
                .collect();
            let best = singles
                .iter()
                .min_by(|a, b| overall(a).total_cmp(&overall(b)))
                .map_or(vec![f64::NAN; JOINTS], |v| (*v).clone());
            let random: Vec<f64> = (0..JOINTS)
                .map(|j| singles.iter().map(|v| v[j]).sum::<f64>() / singles.len() as f64)
                .collect();
            rms.push(("best_single".into(), best));
            rms.push(("random_single".into(), random));
            // The max rule's switching, over the models it was given (the usable ones).
            let (switches, share) = match ran("fuzzy_max") {
                Some(c) => {
                    let active = sims[c]
                        .law_column("fuzzy_model")
                        .ok_or("fuzzy run logged no active model")?;
                    let share = (0..models.len())
                        .map(|m| {
                            active
                                .iter()
                                .filter(|&&a| kept_idx.get(a as usize) == Some(&m))
                                .count() as f64
                                / active.len().max(1) as f64
                        })
                        .collect();
                    (active.windows(2).filter(|w| w[0] != w[1]).count(), share)
                }
                None => (0, vec![0.0; models.len()]),
            };
            let refused = usable.iter().filter(|ok| !**ok).count();
            cells.push(Cell {
                seed,
                trajectory: tr.name,
                rms,
                switches_per_s: switches as f64 / duration,
                share,
                min_eig_on_reference,
                refused,
            });
        }
    }
    let result = summarise(s, robot, prior, cells, t0.elapsed().as_secs_f64());
    crate::report::write_json(dir, "selection.json", &result)
        .map_err(|e| format!("{}: {e}", dir.join("selection.json").display()))?;
    let p = dir.join("report.md");
    crate::report::files::write(&p, report_markdown(&result))
        .map_err(|e| format!("{}: {e}", p.display()))?;
    Ok(result)
}

/// Medians per trajectory and the paired comparisons of fuzzy max with every other controller.
fn summarise(
    s: &SelectionSettings,
    robot: PathBuf,
    prior: Prior,
    cells: Vec<Cell>,
    seconds: f64,
) -> SelectionResult {
    let keys: Vec<&str> = RUN.iter().chain(&DERIVED).copied().collect();
    let value = |c: &Cell, k: &str| {
        c.rms
            .iter()
            .find(|(key, _)| key == k)
            .map_or(f64::NAN, |(_, v)| overall(v))
    };
    let medians = NEW
        .iter()
        .map(|tr| {
            let here: Vec<&Cell> = cells.iter().filter(|c| c.trajectory == tr.name).collect();
            let m = keys
                .iter()
                .map(|k| {
                    (
                        k.to_string(),
                        median(
                            &here
                                .iter()
                                .map(|c| value(c, k))
                                .filter(|v| !v.is_nan())
                                .collect::<Vec<_>>(),
                        ),
                    )
                })
                .collect();
            (tr.name.to_string(), m)
        })
        .collect();
    let comparisons: Vec<Comparison> = ["fuzzy_max", "fuzzy_blend"]
        .iter()
        .flat_map(|rule| {
            keys.iter()
                .filter(move |k| *k != rule)
                .map(move |k| (rule, k))
        })
        .map(|(rule, k)| {
            // Pairs where both ran (a refused model's run is missing, NaN).
            let (fuzzy, b): (Vec<f64>, Vec<f64>) = cells
                .iter()
                .map(|c| (value(c, rule), value(c, k)))
                .filter(|(f, b)| !f.is_nan() && !b.is_nan())
                .unzip();
            Comparison {
                rule: rule.to_string(),
                baseline: k.to_string(),
                median_fuzzy: median(&fuzzy),
                median_baseline: median(&b),
                fuzzy_lower: fuzzy.iter().zip(&b).filter(|(f, b)| f < b).count(),
                pairs: b.len(),
                wilcoxon: wilcoxon(&fuzzy, &b),
            }
        })
        .collect();
    let held = |rule: &str| {
        comparisons
            .iter()
            .find(|c| c.rule == rule && c.baseline == "best_single")
            .is_some_and(|c| {
                c.median_fuzzy < c.median_baseline
                    && c.wilcoxon.w_plus < c.wilcoxon.w_minus
                    && c.wilcoxon.p_two_sided < 0.05
            })
    };
    let (claim_held, claim_held_blend) = (held("fuzzy_max"), held("fuzzy_blend"));
    SelectionResult {
        robot,
        seeds: s.seeds,
        training: TRAINING.iter().map(|t| t.name).collect(),
        trajectories: NEW.iter().map(|t| t.name).collect(),
        prior,
        cells,
        medians,
        comparisons,
        claim_held,
        claim_held_blend,
        seconds,
    }
}

fn verdict(held: bool) -> &'static str {
    if held {
        "held (median lower, Wilcoxon p < 0.05)"
    } else {
        "did not hold"
    }
}

/// report.md: the table of medians, the comparisons, the claim, each from this run's numbers.
pub fn report_markdown(r: &SelectionResult) -> String {
    let mut md = format!(
        "# Fuzzy selection on trajectories that are not midpoints\n\n{} on {} new trajectories \
         ({}), three models identified on {} per seed, {} seeds. Median whole-run RMS tracking \
         error over the three joints (rad):\n\n| controller | {} |\n|---|{}\n",
        r.robot.display(),
        r.trajectories.len(),
        r.trajectories.join(", "),
        r.training.join(", "),
        r.seeds,
        r.trajectories.join(" | "),
        "---|".repeat(r.trajectories.len())
    );
    let keys: Vec<&str> = RUN.iter().chain(&DERIVED).copied().collect();
    for k in keys {
        let row: Vec<String> = r
            .medians
            .iter()
            .map(|(_, m)| {
                m.iter()
                    .find(|(key, _)| key == k)
                    .map_or("-".into(), |(_, v)| format!("{v:.4}"))
            })
            .collect();
        md += &format!("| {k} | {} |\n", row.join(" | "));
    }
    md += "\nEach fuzzy rule against each other controller, paired over every (seed, trajectory):\n\n\
           | rule | baseline | median rule | median baseline | rule lower | Wilcoxon p |\n\
           |---|---|---|---|---|---|\n";
    for c in &r.comparisons {
        md += &format!(
            "| {} | {} | {:.4} | {:.4} | {} of {} | {:.2e} |\n",
            c.rule,
            c.baseline,
            c.median_fuzzy,
            c.median_baseline,
            c.fuzzy_lower,
            c.pairs,
            c.wilcoxon.p_two_sided
        );
    }
    let sw = median(&r.cells.iter().map(|c| c.switches_per_s).collect::<Vec<_>>());
    let refused: usize = r.cells.iter().map(|c| c.refused).sum();
    md += &format!(
        "\nThe controller refused {refused} of {} (model, trajectory, seed) cases, a model \
         whose M-hat is not positive definite along the trajectory; those are left out alone \
         and from the fuzzy sets, and the comparisons pair only runs that both ran.\n",
        3 * r.cells.len()
    );
    md += &format!(
        "\nThe max rule switched models {sw:.1} times a second (median over runs).\n\n\
         The paper's claim, fuzzy selection (its max rule) better than the best single model \
         in hindsight, {} here; with the blend it {}.\n",
        verdict(r.claim_held),
        verdict(r.claim_held_blend)
    );
    md
}
