//! The robust design problem of the two-mass paper (Sections 2-4), as the paper's tables imply it.
//!
//! Reading (verified against Table 9; see the book and `evoloop robust study`'s report):
//! - state order with the measured body first, x = [x_meas, x_act, v_meas, v_act], force on the
//!   actuated body: `A = [[0,0,1,0],[0,0,0,1],[-k,k,0,0],[k,-k,0,0]]`, `B = [0,0,0,1]'`,
//!   `C = [1,0,0,0]`
//!   (the collocated variant has `C = [0,1,0,0]`);
//! - augmented with the integrator xi' = r - y: `Â = [[A,0],[-C,0]]`, `B̂ = [B;0]`, u = -K x̂ with
//!   K = [k1..k5] in Table 9's column order (the paper's k_i = -k5);
//! - perturbation structure where k enters A (rows 3-4, columns 1-2): Ê = diag(0,0,1,1,0),
//!   Ĥ = diag(1,1,0,0,0) (default); the text's literal "rows 3-4 of Ê, columns 2-3 of Ĥ" is
//!   available as `Perturbation::Literal` (Ĥ = diag(0,1,1,0,0));
//! - the wedge with zeta = 0.7, rho = 1; the nominal plant is the worst case k = 0.5;
//! - the objective of Table 2 (DOCHM): F(X) = summed pole distance to the wedge when positive,
//!   else f(X) = -r_c.

use super::observer::{continuous_loop, sampled_loop, spectral_radius, spring_range, Observer};
use super::pole_region::Wedge;
use super::stability_radius::{hinf_from_poles, radius_from_poles, Bounded, HinfError};
use crate::linalg::{eig, hessenberg_eig, householder_vector};
use crate::optim::Objective;
use crate::plant::linear::LinearModel;
use crate::plant::two_mass::{Sensor, TwoMass};
use nalgebra::{Complex, DMatrix, DVector};
use serde::Serialize;

/// Where the uncertainty Ê Δ Ĥ enters the augmented loop: the structure r_c is computed for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Perturbation {
    /// Ê = diag(0,0,1,1,0), Ĥ = diag(1,1,0,0,0): exactly where the spring constant enters.
    #[default]
    Spring,
    /// Ê = diag(0,0,1,1,0), Ĥ = diag(0,1,1,0,0): the text's literal wording.
    Literal,
}

/// The augmented open loop (Â, B̂) of the two-mass plant with spring `k` (m1 = m2 = 1), as the
/// plant's linear model builds it.
pub fn augmented(k: f64, sensor: Sensor) -> (DMatrix<f64>, DMatrix<f64>) {
    TwoMass::new(1.0, 1.0, k, sensor).linear_model().augmented()
}

impl Objective for RobustProblem {
    fn value(&self, x: &[f64]) -> f64 {
        self.objective(x)
    }
    fn value_below(&self, x: &[f64], threshold: f64) -> f64 {
        self.objective_below(x, threshold)
    }
}

/// The springs a loop stays stable for, around the nominal one.
#[derive(Debug, Clone, Serialize)]
pub struct SpringRanges {
    /// What r_c guarantees under the spring structure (`Perturbation::Spring`, where a spring
    /// change is a perturbation of norm 2|δ|): |δ| < r_c / 2. None under another structure.
    pub guaranteed: Option<(f64, f64)>,
    /// The continuous loop r_c is computed on, by its eigenvalues (None on a side: still
    /// stable at k / 1000 or 1000 k).
    pub continuous: (Option<f64>, Option<f64>),
    /// With a filter: the sampled loop exactly as the controller runs it.
    pub sampled: Option<(Option<f64>, Option<f64>)>,
}

/// Everything one candidate gain vector is judged by.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// The full-state closed loop's poles, as (re, im).
    pub poles: Vec<(f64, f64)>,
    /// F(X): summed distance of the poles to the wedge (0 = feasible).
    pub wedge_distance: f64,
    /// Every pole inside the wedge (F(X) = 0).
    pub in_wedge: bool,
    /// r_c (0 when the closed loop is unstable).
    pub stability_radius: f64,
    /// The DOCHM objective: F(X) if positive, else -r_c.
    pub objective: f64,
}

/// The two-mass paper's robust design problem: the gains K of the augmented loop, judged by
/// the wedge and the stability radius r_c (the DOCHM objective, which DE minimises).
#[derive(Debug, Clone)]
pub struct RobustProblem {
    /// Â, the augmented open loop's state matrix (5 x 5) at the nominal spring. Â, B̂, Ê and Ĥ
    /// are read through their methods: `basis` is made from them once, in `new`.
    a_hat: DMatrix<f64>,
    /// B̂, the augmented open loop's input matrix (5 x 1).
    b_hat: DMatrix<f64>,
    /// Ê of the perturbation Ê Δ Ĥ: diag(0,0,1,1,0).
    e: DMatrix<f64>,
    /// Ĥ of the perturbation Ê Δ Ĥ, as `perturbation` gives it.
    h: DMatrix<f64>,
    /// The nominal spring and the sensor Â and B̂ were built from (changing them rebuilds
    /// nothing: make a new problem).
    pub k: f64,
    /// The position sensor's body (far: body 2, the paper's).
    pub sensor: Sensor,
    /// The perturbation structure `h` follows.
    pub perturbation: Perturbation,
    /// The pole region the state feedback's poles must lie in.
    pub wedge: Wedge,
    /// Lower bounds of the gains searched (-`bound` each).
    pub lower: Vec<f64>,
    /// Upper bounds of the gains searched (+`bound` each).
    pub upper: Vec<f64>,
    /// The filter the feedback acts on (`with_observer`); None: the full state, as the paper.
    pub observer: Option<Observer>,
    /// Â, B̂, Ê and Ĥ in a basis where every full-state closed loop is upper Hessenberg.
    basis: HessenbergBasis,
}

/// A loop r_c is computed on: its state matrix, its poles, and the perturbation's Ê and Ĥ.
struct NormLoop<'a> {
    a: DMatrix<f64>,
    poles: Vec<Complex<f64>>,
    e: &'a DMatrix<f64>,
    h: &'a DMatrix<f64>,
}

/// The full-state loop in an orthonormal basis Q made once per problem, in which Qᵀ B̂ = β e1 and
/// Qᵀ Â Q is upper Hessenberg: Qᵀ (Â - B̂ K) Q = Qᵀ Â Q - β e1 (K Q) changes only the first row,
/// so every candidate's closed loop is Hessenberg as it is built. Its eigenvalues then need no
/// reduction and each of the norm's gain evaluations factorises a Hessenberg jwI - A (a similarity
/// by Q changes neither the poles nor G(s) = Ĥ Q (sI - Qᵀ Ã Q)^-1 Qᵀ Ê, only their rounding).
#[derive(Debug, Clone)]
struct HessenbergBasis {
    /// Q.
    q: DMatrix<f64>,
    /// Qᵀ Â Q.
    a: DMatrix<f64>,
    /// β.
    beta: f64,
    /// Qᵀ Ê.
    e: DMatrix<f64>,
    /// Ĥ Q.
    h: DMatrix<f64>,
}

impl HessenbergBasis {
    /// The basis for (Â, B̂) with the single input B̂: a Householder reflection P takes B̂ to
    /// β e1, then P Â P is reduced to Hessenberg form by reflections that leave e1 alone.
    fn new(a: &DMatrix<f64>, b: &DMatrix<f64>, e: &DMatrix<f64>, h: &DMatrix<f64>) -> Self {
        let n = a.nrows();
        let mut p = DMatrix::identity(n, n);
        let mut v = DVector::zeros(n);
        // B̂ = 0 leaves the identity and beta 0: the closed loop is Â for every K.
        let mut beta = 0.0;
        if let Some((alpha, tau)) = householder_vector(b.column(0).as_slice(), v.as_mut_slice()) {
            beta = alpha;
            p -= tau * &v * v.transpose();
        }
        let (qh, hess) = (&p * a * &p).hessenberg().unpack();
        let q = p * qh;
        Self {
            a: hess,
            beta,
            e: q.transpose() * e,
            h: h * &q,
            q,
        }
    }

    /// Qᵀ (Â - B̂ K) Q; K must have one gain per state.
    fn closed_loop(&self, gains: &[f64]) -> DMatrix<f64> {
        assert_eq!(gains.len(), self.q.nrows(), "one gain per state");
        let mut acl = self.a.clone();
        for j in 0..acl.ncols() {
            let kq: f64 = gains
                .iter()
                .zip(self.q.column(j).iter())
                .map(|(k, q)| k * q)
                .sum();
            acl[(0, j)] -= self.beta * kq;
        }
        acl
    }
}

impl RobustProblem {
    /// The problem at the nominal spring `k` with `sensor`, the given perturbation structure and
    /// wedge, and each gain searched within +-`bound`; the feedback on the full state (see
    /// `with_observer`).
    pub fn new(
        k: f64,
        sensor: Sensor,
        perturbation: Perturbation,
        wedge: Wedge,
        bound: f64,
    ) -> Self {
        let (a_hat, b_hat) = augmented(k, sensor);
        let e = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![0.0, 0.0, 1.0, 1.0, 0.0]));
        let h_diag = match perturbation {
            Perturbation::Spring => vec![1.0, 1.0, 0.0, 0.0, 0.0],
            Perturbation::Literal => vec![0.0, 1.0, 1.0, 0.0, 0.0],
        };
        let h = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(h_diag));
        let basis = HessenbergBasis::new(&a_hat, &b_hat, &e, &h);
        Self {
            basis,
            a_hat,
            b_hat,
            e,
            h,
            k,
            sensor,
            perturbation,
            wedge,
            lower: vec![-bound; 5],
            upper: vec![bound; 5],
            observer: None,
        }
    }

    /// The same problem with the feedback acting on `design`'s Kalman filter, run every
    /// `period` s on the nominal model: the wedge still holds the state feedback's poles (the
    /// loop's others are the filter's, by separation), r_c is the whole loop's.
    pub fn with_observer(
        mut self,
        design: crate::law::estimator::KalmanDesign,
        period: f64,
    ) -> Result<Self, super::observer::ObserverError> {
        let model = self.nominal_model();
        self.observer = Some(Observer::new(&model, (&self.e, &self.h), design, period)?);
        Ok(self)
    }

    /// Â, the augmented open loop's state matrix (5 x 5) at the nominal spring.
    pub fn a_hat(&self) -> &DMatrix<f64> {
        &self.a_hat
    }

    /// B̂, the augmented open loop's input matrix (5 x 1).
    pub fn b_hat(&self) -> &DMatrix<f64> {
        &self.b_hat
    }

    /// Ê of the perturbation Ê Δ Ĥ on the full-state loop: diag(0,0,1,1,0).
    pub fn e(&self) -> &DMatrix<f64> {
        &self.e
    }

    /// Ĥ of the perturbation Ê Δ Ĥ on the full-state loop, as `perturbation` gives it.
    pub fn h(&self) -> &DMatrix<f64> {
        &self.h
    }

    /// The same problem with the feedback on the full state (the filter dropped).
    pub fn without_observer(self) -> Self {
        Self {
            observer: None,
            ..self
        }
    }

    /// The nominal plant's continuous model (A, B, C).
    pub fn nominal_model(&self) -> LinearModel {
        self.plant_at(self.k)
    }

    /// The plant (m1 = m2 = 1, this problem's sensor) with its spring at `k`: Â with it moves
    /// by δ [[-1, 1], [1, -1]] in rows 3-4, columns 1-2 (δ = k - k_nominal), a perturbation of
    /// norm 2|δ|.
    pub fn plant_at(&self, k: f64) -> LinearModel {
        TwoMass::new(1.0, 1.0, k, self.sensor).linear_model()
    }

    /// The springs for which the loop with `gains` stays stable (see `SpringRanges`), `r_c`
    /// being its stability radius.
    pub fn spring_ranges(&self, gains: &[f64], r_c: f64) -> SpringRanges {
        let k = self.k;
        let continuous = spring_range(k, |kk| {
            eig(&self.whole_loop(gains, Some(&self.plant_at(kk).augmented().0)))
                .iter()
                .all(|p| p.re < 0.0)
        });
        let sampled = self.observer.as_ref().map(|o| {
            spring_range(k, |kk| {
                sampled_loop(&self.plant_at(kk), &o.filter, o.period, gains)
                    .is_some_and(|m| spectral_radius(&m) < 1.0)
            })
        });
        SpringRanges {
            guaranteed: (self.perturbation == Perturbation::Spring)
                .then(|| ((k - 0.5 * r_c).max(0.0), k + 0.5 * r_c)),
            continuous,
            sampled,
        }
    }

    /// The loop r_c is computed on: Ã = Â - B̂ K on the full state, or the loop with the
    /// filter's continuous equivalent, [x; ξ; x̂]. `plant` replaces Â in the plant's rows (a
    /// perturbed spring); None: the nominal plant.
    pub fn whole_loop(&self, gains: &[f64], plant: Option<&DMatrix<f64>>) -> DMatrix<f64> {
        let a = plant.unwrap_or(&self.a_hat);
        match &self.observer {
            None => a - &self.b_hat * DMatrix::from_row_slice(1, gains.len(), gains),
            Some(o) => continuous_loop(a, &self.a_hat, &self.b_hat, &o.l_c, gains),
        }
    }

    /// E and H of `whole_loop`: the perturbation reaches the plant, not the filter.
    pub fn loop_perturbation(&self) -> (&DMatrix<f64>, &DMatrix<f64>) {
        match &self.observer {
            None => (&self.e, &self.h),
            Some(o) => (&o.e_loop, &o.h_loop),
        }
    }

    /// The paper's problem: k = 0.5, sensor on body 2, zeta = 0.7, rho = 1, bounds +-50.
    pub fn paper() -> Self {
        Self::new(
            0.5,
            Sensor::Far,
            Perturbation::Spring,
            Wedge {
                zeta: 0.7,
                rho: 1.0,
            },
            50.0,
        )
    }

    /// Ã = Â - B̂ K.
    pub fn closed_loop(&self, gains: &[f64]) -> DMatrix<f64> {
        let k = DMatrix::from_row_slice(1, gains.len(), gains);
        &self.a_hat - &self.b_hat * k
    }

    /// The full-state closed loop's poles: the eigenvalues of Ã = Â - B̂ K (nalgebra's Schur
    /// decomposition: independent of the objective's computation).
    pub fn poles(&self, gains: &[f64]) -> Vec<Complex<f64>> {
        self.closed_loop(gains)
            .complex_eigenvalues()
            .iter()
            .copied()
            .collect()
    }

    /// The DOCHM objective only (what the optimiser minimises): F(X) when infeasible, else
    /// -r_c. The H-infinity norm is computed only for feasible candidates.
    pub fn objective(&self, gains: &[f64]) -> f64 {
        self.objective_below(gains, f64::INFINITY)
    }

    /// The objective, allowed to stop early once it is proven above `threshold` (see
    /// `Objective::value_below`): a feasible candidate only beats a feasible target of value
    /// -r_t if its norm is at most 1/r_t, and one frequency with a larger gain disproves that.
    pub fn objective_below(&self, gains: &[f64], threshold: f64) -> f64 {
        let (acl, poles) = self.full_state_loop(gains);
        let f = self.wedge.total_distance(&poles);
        if f > 0.0 {
            return f;
        }
        // Feasible: every pole has Re <= -rho < 0, so the full-state loop is Hurwitz (with a
        // filter, the loop's other poles are the filter's, stable by its design).
        let NormLoop {
            a: acl,
            poles,
            e,
            h,
        } = self.norm_loop(gains, acl, poles);
        let level = if threshold < 0.0 {
            -1.0 / threshold
        } else {
            f64::INFINITY
        };
        match hinf_from_poles(&acl, e, h, &poles, level) {
            Ok(Bounded::Exact(n, _)) if n > 0.0 => -1.0 / n,
            Ok(Bounded::Exact(..)) => f64::NEG_INFINITY,
            // Above the threshold, strictly: -1/lb may round onto it.
            Ok(Bounded::Above(lb)) => (-1.0 / lb).max(threshold.next_up()),
            // Not computable: the candidate is refused (+inf never wins a DE selection) rather
            // than scored as r_c = 0, which would rank it above every infeasible candidate.
            Err(_) => f64::INFINITY,
        }
    }

    /// The full-state closed loop in the Hessenberg basis and its poles.
    fn full_state_loop(&self, gains: &[f64]) -> (DMatrix<f64>, Vec<Complex<f64>>) {
        let acl = self.basis.closed_loop(gains);
        let poles = hessenberg_eig(&acl);
        (acl, poles)
    }

    /// The loop r_c is computed on: the full-state loop `acl` in the Hessenberg basis with its
    /// `poles`, or, with a filter, `whole_loop` and its eigenvalues.
    fn norm_loop(
        &self,
        gains: &[f64],
        acl: DMatrix<f64>,
        poles: Vec<Complex<f64>>,
    ) -> NormLoop<'_> {
        match self.observer {
            None => NormLoop {
                a: acl,
                poles,
                e: &self.basis.e,
                h: &self.basis.h,
            },
            Some(_) => {
                let (e, h) = self.loop_perturbation();
                let a = self.whole_loop(gains, None);
                let poles = eig(&a);
                NormLoop { a, poles, e, h }
            }
        }
    }

    /// Full evaluation for reports, computed as the objective computes it; an error when r_c
    /// cannot be computed.
    pub fn evaluate(&self, gains: &[f64]) -> Result<Evaluation, HinfError> {
        let (acl, poles) = self.full_state_loop(gains);
        let f = self.wedge.total_distance(&poles);
        let reported = poles.iter().map(|p| (p.re, p.im)).collect();
        let l = self.norm_loop(gains, acl, poles);
        let rc = radius_from_poles(&l.a, l.e, l.h, &l.poles)?;
        Ok(Evaluation {
            poles: reported,
            wedge_distance: f,
            in_wedge: f == 0.0,
            stability_radius: rc,
            objective: if f > 0.0 { f } else { -rc },
        })
    }
}
