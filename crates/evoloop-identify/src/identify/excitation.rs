//! Optimal excitation trajectories (the eMuPSO paper, eq. 15 and Section 4.1).
//!
//! The fitness of a trajectory is eq. 15 on its base regressor W_b (the stage's base columns
//! stacked over `samples` instants of one period):
//!
//!   fitness = cond(W_b) + 1 / sigma_min(W_b) + sigma_max(W_b).
//!
//! Our reading, where the paper is silent: W_b is divided by sqrt(samples), so the singular
//! values are root-mean-square torque sensitivities that do not grow with the sampling rate (the
//! condition number is unchanged by it). A trajectory that leaves the joint limits (position with
//! a margin, velocity, acceleration; checked on a grid four times finer than `samples`) is
//! *infeasible*: its value is `PENALTY` (1 + the summed normalised excess), so every feasible
//! trajectory ranks above every infeasible one and among infeasible ones the less violating
//! ranks higher — the paper's "penalties make trajectories that do not satisfy the constraints
//! less likely to be selected as exemplars".
//!
//! The search follows Section 4.1 in two phases:
//! 1. *Initial elite particles*: a canonical PSO swarm of 10 whose fitness is the constraint
//!    excess alone; each particle that satisfies every constraint becomes an elite and is
//!    replaced by a new random particle, until 5 elites exist (or the budget ends: then the
//!    least violating positions fill in, and the outcome says how many were feasible).
//! 2. *Optimisation*: eMuPSO with 20 particles started from the elites and Gaussian offspring
//!    of them (sigma = 10 % of each range), fitness eq. 15, mutation after G = 10 stagnant
//!    iterations, 30 iterations (the paper's settings; all are options).

use super::mfs::MfsDesign;
use super::ExcitationError;
use super::{stage_base, states_needed, Columns, Stacker, Stage};
use crate::dynamics::base::BaseParameters;
use crate::dynamics::Model;
use crate::optim::emupso::{EmuPso, EmuPsoSettings};
use crate::optim::pso::Pso;
use crate::optim::swarm::SwarmConfig;
use crate::optim::{evaluate, Objective, Optimiser};
use crate::reference::series::{Design, FourierSeries};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use serde::Serialize;

/// Value of an infeasible trajectory: PENALTY (1 + excess).
pub const PENALTY: f64 = 1e6;
/// The excess of a Cartesian path the arm cannot reach (worse than any limit violation of
/// a reachable one would normally be).
pub const UNREACHABLE: f64 = 100.0;

/// What the trajectory is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TrajectoryKind {
    /// A joint-space finite Fourier series per moving joint (Swevers).
    Fourier,
    /// The paper's modified Fourier series: a Cartesian path of the wrist centre through
    /// inverse kinematics (arm joints); moving wrist joints follow a joint-space series.
    Mfs,
}

impl TrajectoryKind {
    /// Every kind, as `--trajectory` lists them.
    pub const ALL: [TrajectoryKind; 2] = [TrajectoryKind::Fourier, TrajectoryKind::Mfs];

    /// The kind's name as commands and reports spell it: `fourier` or `mfs`.
    pub fn name(self) -> &'static str {
        match self {
            TrajectoryKind::Fourier => "fourier",
            TrajectoryKind::Mfs => "mfs",
        }
    }
}

/// The limits a trajectory must respect, per joint.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct JointLimits {
    /// Lowest position per joint, rad (m for a prismatic joint), the margin included.
    pub q_lo: Vec<f64>,
    /// Highest position per joint, rad (m), the margin included.
    pub q_hi: Vec<f64>,
    /// Largest speed per joint, rad/s (m/s).
    pub qd_max: Vec<f64>,
    /// Largest acceleration per joint, rad/s^2 (m/s^2).
    pub qdd_max: Vec<f64>,
}

impl JointLimits {
    /// The robot file's limits: positions shrunk by `margin` (rad or m) at each end (+-pi where
    /// the file has none; unshrunk where the range is narrower than two margins), the file's velocity limit or `qd_max`, and `qdd_max`.
    pub fn of(model: &Model, margin: f64, qd_max: f64, qdd_max: f64) -> JointLimits {
        let pos = |b: &crate::dynamics::Body| {
            let (lo, hi) = b.limits.position_span();
            if hi - lo > 2.0 * margin {
                (lo + margin, hi - margin)
            } else {
                (lo, hi)
            }
        };
        JointLimits {
            q_lo: model.bodies.iter().map(|b| pos(b).0).collect(),
            q_hi: model.bodies.iter().map(|b| pos(b).1).collect(),
            qd_max: model
                .bodies
                .iter()
                .map(|b| b.limits.velocity.min(qd_max))
                .collect(),
            qdd_max: vec![qdd_max; model.dof()],
        }
    }
}

/// How a trajectory is designed and judged.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Settings {
    /// Period T, s (the paper: 10 s, fundamental 0.6283 rad/s).
    pub period: f64,
    /// The trajectory's form: a joint-space Fourier series or the paper's MFS.
    pub trajectory: TrajectoryKind,
    /// Harmonics N (the paper's MFS: 3; Swevers: 5).
    pub harmonics: usize,
    /// Instants of one period in the fitness' regressor.
    pub samples: usize,
    /// Position margin inside the joint limits, rad.
    pub margin: f64,
    /// Velocity and acceleration limits where the robot file has none.
    pub qd_max: f64,
    /// Acceleration limit of every joint, rad/s^2 (robot files give none).
    pub qdd_max: f64,
    /// The parameters the base regressor is built from (friction, armature).
    pub columns: Columns,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            period: 10.0,
            trajectory: TrajectoryKind::Fourier,
            harmonics: 5,
            samples: 100,
            margin: 0.05,
            qd_max: 2.0,
            qdd_max: 8.0,
            columns: Columns::PLANT,
        }
    }
}

/// A trajectory's scores.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Criteria {
    /// Condition number of the scaled base regressor: `sigma_max` / `sigma_min`.
    pub cond: f64,
    /// Smallest singular value of W_b / sqrt(samples) (an RMS torque sensitivity).
    pub sigma_min: f64,
    /// Largest singular value of W_b / sqrt(samples).
    pub sigma_max: f64,
    /// Eq. 15.
    pub fitness: f64,
    /// Summed normalised excess over the limits (0: feasible).
    pub excess: f64,
}

impl Criteria {
    /// What the search minimises.
    pub fn value(&self) -> f64 {
        if self.excess > 0.0 {
            PENALTY * (1.0 + self.excess)
        } else {
            self.fitness
        }
    }
}

/// One stage's excitation design problem.
pub struct ExcitationProblem {
    /// The robot whose base parameters the trajectory is to identify.
    pub model: Model,
    /// The experiment: which joints move and where the others are held.
    pub stage: Stage,
    /// How the trajectory is designed and judged.
    pub settings: Settings,
    /// The limits the trajectory must keep (`JointLimits::of` with the settings' values).
    pub limits: JointLimits,
    /// The joint-space Fourier design: how a decision vector becomes a trajectory
    /// (unused with `mfs`).
    pub design: Design,
    /// With `TrajectoryKind::Mfs`: the Cartesian path (and `design` unused).
    pub mfs: Option<MfsDesign>,
    /// The stage's base parameters (from random states).
    pub base: BaseParameters,
}

impl ExcitationProblem {
    /// The problem of designing `stage`'s excitation for `model`: the stage's base
    /// parameters, the joint limits and the trajectory's design. Fails with fewer than 2
    /// harmonics, a period not above 0 s, fewer `samples` x moving joints than base
    /// parameters, or an MFS that cannot be built (the wrist stage, no spherical wrist).
    pub fn new(
        model: Model,
        stage: Stage,
        settings: Settings,
    ) -> Result<ExcitationProblem, ExcitationError> {
        if settings.harmonics < 2 {
            return Err(ExcitationError::setting(
                "harmonics",
                "at least 2 harmonics (the last one brings the start to rest)",
            ));
        }
        if settings.period.is_nan() || settings.period <= 0.0 {
            let reason = format!("period {} s: must be > 0", settings.period);
            return Err(ExcitationError::setting("period", reason));
        }
        let base = stage_base(
            &model,
            settings.columns,
            &stage,
            states_needed(&model, settings.columns, &stage),
            1,
        );
        let rows = stage.rows().len();
        if settings.samples * rows < base.base_count() {
            let reason = format!(
                "{} samples x {rows} torques cannot identify {} base parameters",
                settings.samples,
                base.base_count()
            );
            return Err(ExcitationError::setting("samples", reason));
        }
        let limits = JointLimits::of(&model, settings.margin, settings.qd_max, settings.qdd_max);
        let design = Design {
            period: settings.period,
            harmonics: settings.harmonics,
            moving: stage.moving.clone(),
            hold: stage.hold.clone(),
        };
        let mfs = match settings.trajectory {
            TrajectoryKind::Fourier => None,
            TrajectoryKind::Mfs => {
                let n = model.dof();
                if stage.kind == super::StageKind::Wrist {
                    return Err(ExcitationError::Robot(
                        "the modified Fourier series moves the wrist centre, which the wrist \
                         stage holds: use --trajectory fourier for the wrist"
                            .into(),
                    ));
                }
                // The wrist joints that move follow a joint-space series.
                let wrist_moves = (n.saturating_sub(3)..n).any(|j| stage.moving[j]);
                let joints = wrist_moves.then(|| Design {
                    moving: (0..n).map(|j| j + 3 >= n && stage.moving[j]).collect(),
                    ..design.clone()
                });
                Some(MfsDesign::new(
                    &model,
                    settings.period,
                    settings.harmonics,
                    stage.hold.clone(),
                    joints,
                )?)
            }
        };
        Ok(ExcitationProblem {
            model,
            stage,
            settings,
            limits,
            design,
            mfs,
            base,
        })
    }

    /// The search box: offsets inside the position limits, coefficients up to each joint's
    /// velocity limit (|qd| <= sum |a_l| + |b_l|).
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let coef: Vec<f64> = self
            .limits
            .qd_max
            .iter()
            .map(|v| v.min(1e3) / self.settings.harmonics as f64)
            .collect();
        match &self.mfs {
            None => self
                .design
                .bounds(&self.limits.q_lo, &self.limits.q_hi, &coef),
            Some(m) => m.bounds(
                m.joints
                    .as_ref()
                    .map(|d| d.bounds(&self.limits.q_lo, &self.limits.q_hi, &coef)),
            ),
        }
    }

    /// The trajectory of a decision vector; None for a Cartesian path out of reach.
    pub fn decode(&self, x: &[f64]) -> Option<FourierSeries> {
        match &self.mfs {
            None => Some(self.design.decode(x)),
            Some(m) => m.decode(&self.model, x).map(|(s, _)| s),
        }
    }

    /// The scores of a decision vector (an unreachable path: excess `UNREACHABLE`).
    pub fn criteria_of(&self, x: &[f64]) -> Criteria {
        match self.decode(x) {
            Some(s) => self.criteria(&s),
            None => Criteria {
                cond: f64::NAN,
                sigma_min: f64::NAN,
                sigma_max: f64::NAN,
                fitness: f64::NAN,
                excess: UNREACHABLE,
            },
        }
    }

    /// Summed normalised excess of `s` over the limits (0 when it keeps inside every one).
    pub fn excess(&self, s: &FourierSeries) -> f64 {
        let l = &self.limits;
        let grid = 4 * self.settings.samples;
        let mut total = 0.0;
        for j in (0..s.joints()).filter(|&j| self.stage.moving[j]) {
            let (mut over_q, mut over_qd, mut over_qdd) = (0.0f64, 0.0f64, 0.0f64);
            for k in 0..grid {
                let (q, qd, qdd) = s.joint(j, s.period * k as f64 / grid as f64);
                over_q = over_q.max(q - l.q_hi[j]).max(l.q_lo[j] - q);
                over_qd = over_qd.max(qd.abs() - l.qd_max[j]);
                over_qdd = over_qdd.max(qdd.abs() - l.qdd_max[j]);
            }
            total += over_q.max(0.0) / (l.q_hi[j] - l.q_lo[j])
                + over_qd.max(0.0) / l.qd_max[j]
                + over_qdd.max(0.0) / l.qdd_max[j];
        }
        total
    }

    /// The stage's base regressor over `samples` instants of one period, divided by
    /// sqrt(samples).
    pub fn base_regressor(&self, s: &FourierSeries) -> DMatrix<f64> {
        let n = self.model.dof();
        let k = self.settings.samples;
        let mut stacker = Stacker::new(&self.model, self.settings.columns, &self.stage);
        let per = stacker.rows_per_state();
        let mut w = DMatrix::zeros(k * per, self.settings.columns.count(&self.model));
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for i in 0..k {
            s.sample(s.period * i as f64 / k as f64, &mut q, &mut qd, &mut qdd);
            stacker.put([&q, &qd, &qdd], &mut w, i * per);
        }
        self.base.base_columns(&w) / (k as f64).sqrt()
    }

    /// Eq. 15 and the constraint excess of `s`.
    pub fn criteria(&self, s: &FourierSeries) -> Criteria {
        Criteria {
            excess: self.excess(s),
            ..self.eq15(s)
        }
    }

    /// Eq. 15 alone (excess left at 0).
    fn eq15(&self, s: &FourierSeries) -> Criteria {
        let sv = self.base_regressor(s).singular_values();
        let sigma_max = sv.max();
        let sigma_min = sv.min();
        let cond = sigma_max / sigma_min;
        Criteria {
            cond,
            sigma_min,
            sigma_max,
            fitness: cond + 1.0 / sigma_min + sigma_max,
            excess: 0.0,
        }
    }
}

impl Objective for ExcitationProblem {
    fn value(&self, x: &[f64]) -> f64 {
        let Some(s) = self.decode(x) else {
            return PENALTY * (1.0 + UNREACHABLE);
        };
        // Infeasible trajectories are not worth an SVD.
        let excess = self.excess(&s);
        if excess > 0.0 {
            return PENALTY * (1.0 + excess);
        }
        let v = self.eq15(&s).value();
        if v.is_finite() {
            v
        } else {
            PENALTY
        }
    }
}

/// The feasibility objective of the elite phase.
struct Excess<'a>(&'a ExcitationProblem);

impl Objective for Excess<'_> {
    fn value(&self, x: &[f64]) -> f64 {
        self.0.decode(x).map_or(UNREACHABLE, |s| self.0.excess(&s))
    }
}

/// The search's settings (Section 4.1's values by default).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Search {
    /// Swarm size of the elite phase's canonical PSO (the paper: 10).
    pub elite_population: usize,
    /// Initial elites the first phase collects (the paper: 5); also eMuPSO's elite count
    /// (at most `population` - 1).
    pub elites: usize,
    /// Iterations the elite phase may take at most.
    pub elite_iterations: usize,
    /// Swarm size of the eMuPSO phase (the paper: 20).
    pub population: usize,
    /// eMuPSO iterations after the starting swarm's evaluation (the paper: 30).
    pub iterations: usize,
    /// Stagnant iterations before a mutation (G).
    pub stagnation: usize,
    /// Seed of both swarms, the random particles and the Gaussian offspring.
    pub seed: u64,
    /// Threads that evaluate a swarm's particles.
    pub threads: usize,
}

impl Default for Search {
    fn default() -> Self {
        Self {
            elite_population: 10,
            elites: 5,
            elite_iterations: 200,
            population: 20,
            iterations: 30,
            stagnation: 10,
            seed: 1,
            threads: crate::optim::all_cores(),
        }
    }
}

/// What the search found.
#[derive(Debug, Clone, Serialize)]
pub struct Outcome {
    /// The best decision vector.
    pub x: Vec<f64>,
    /// The best trajectory (`x` decoded).
    pub series: FourierSeries,
    /// The best trajectory's scores.
    pub criteria: Criteria,
    /// The initial elites' scores (the random feasible trajectories the search started from)
    /// and their decision vectors.
    pub initial: Vec<Criteria>,
    /// The initial elites' decision vectors, in the order of `initial`.
    #[serde(skip)]
    pub initial_x: Vec<Vec<f64>>,
    /// How many initial elites were feasible (the rest filled in from the least violating).
    pub feasible_elites: usize,
    /// Best value after each eMuPSO iteration.
    pub history: Vec<f64>,
    /// Objective evaluations of both phases.
    pub evaluations: usize,
    /// Mutations eMuPSO made (each after `stagnation` stagnant iterations).
    pub mutations: usize,
}

/// Progress of `search`: the phase ("elites" or "emupso"), the iteration and the best value.
pub type Progress<'a> = &'a mut dyn FnMut(&str, usize, f64);

/// The two-phase search of Section 4.1 on `problem`.
pub fn search(
    problem: &ExcitationProblem,
    s: &Search,
    progress: Progress,
) -> Result<Outcome, ExcitationError> {
    let (lo, hi) = problem.bounds();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed ^ 0x5eed_e11e);
    let random = |rng: &mut rand_chacha::ChaCha8Rng| -> Vec<f64> {
        lo.iter()
            .zip(&hi)
            .map(|(l, h)| rng.gen_range(*l..*h))
            .collect()
    };
    // Phase 1: initial elite particles.
    let cfg = SwarmConfig {
        lower: lo.clone(),
        upper: hi.clone(),
        population: s.elite_population,
        iterations: s.elite_iterations,
        seed: s.seed,
    };
    let mut pso = Pso::new(cfg)?;
    let mut elites: Vec<Vec<f64>> = Vec::new();
    let mut near: Vec<(f64, Vec<f64>)> = Vec::new();
    let mut evaluations = 0;
    let feasibility = Excess(problem);
    for it in 0..s.elite_iterations {
        let values = evaluate(pso.ask(), None, &feasibility, s.threads);
        evaluations += values.len();
        let found: Vec<usize> = (0..values.len()).filter(|&i| values[i] <= 0.0).collect();
        for (i, v) in values.iter().enumerate() {
            if *v > 0.0 {
                near.push((*v, pso.candidates()[i].clone()));
            }
        }
        for &i in &found {
            if elites.len() < s.elites {
                elites.push(pso.candidates()[i].clone());
            }
        }
        pso.tell(&values);
        for &i in &found {
            let x = random(&mut rng);
            pso.restart_particle(i, &x);
        }
        progress("elites", it + 1, elites.len() as f64);
        if elites.len() >= s.elites {
            break;
        }
    }
    let feasible_elites = elites.len();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    elites.extend(
        near.into_iter()
            .map(|n| n.1)
            .take(s.elites - feasible_elites),
    );
    let initial: Vec<Criteria> = elites.iter().map(|x| problem.criteria_of(x)).collect();
    // Phase 2: eMuPSO from the elites and Gaussian offspring of them.
    let mut start = elites.clone();
    while start.len() < s.population {
        let e = &elites[start.len() % elites.len()];
        let child = e
            .iter()
            .enumerate()
            .map(|(j, v)| {
                let sd = 0.1 * (hi[j] - lo[j]);
                v + Normal::new(0.0, sd).map_or(0.0, |n| n.sample(&mut rng))
            })
            .collect();
        start.push(child);
    }
    let settings = EmuPsoSettings {
        stagnation: s.stagnation,
        elites: s.elites.min(s.population - 1),
        ..EmuPsoSettings::default()
    };
    let cfg = SwarmConfig {
        lower: lo,
        upper: hi,
        population: s.population,
        iterations: s.iterations,
        seed: s.seed,
    };
    let mut opt = EmuPso::new(cfg, settings)?;
    opt.swarm.start_from(&start);
    let mut history = Vec::with_capacity(s.iterations + 1);
    while opt.generation() <= s.iterations {
        let values = evaluate(opt.ask(), None, problem, s.threads);
        evaluations += values.len();
        opt.tell(&values);
        history.push(opt.best().1);
        progress("emupso", opt.generation(), opt.best().1);
    }
    let best = opt.best().0;
    let series = problem.decode(best).ok_or_else(|| {
        ExcitationError::NotFound(
            "no reachable Cartesian path found (widen the search or move the centre)".into(),
        )
    })?;
    Ok(Outcome {
        x: best.to_vec(),
        initial_x: elites,
        criteria: problem.criteria(&series),
        series,
        initial,
        feasible_elites,
        history,
        evaluations,
        mutations: opt.rule.mutations,
    })
}
