//! Base (identifiable) inertial parameters from the regressor (the eMuPSO paper, Section 3.4;
//! Gautier and Khalil's numerical procedure).
//!
//! The regressor is stacked over random states (positions across the joint range or +-pi,
//! velocities and accelerations of unit scale) into W. A column whose norm is negligible
//! against the largest is *unidentifiable* (the parameter never acts on a torque). On the rest,
//! QR with column pivoting gives the rank r. The r *base* columns W_b are then chosen in
//! regressor order, base to tip: a column is kept when it is independent of those kept before
//! it (Gram-Schmidt residual), so a later body's parameters are regrouped into an earlier body's
//! as in Khalil's closed-form rules (e.g. Izz1 absorbs m2 and Iyy2 of a 6R arm), not into
//! whichever column pivoting happened to favour. The others (*identifiable only in
//! combination*) satisfy W_d = W_b K, so tau = W pi = W_b beta with beta = pi_b + K pi_d: each
//! base parameter is its own parameter plus the regrouped ones, with the coefficients printed.

use super::model::Model;
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Relative threshold for a zero column norm and for the rank (|R_ii| against |R_00|).
pub const TOLERANCE: f64 = 1e-10;

/// One base parameter: its column and what is regrouped into it.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Base {
    /// The parameter's own name (e.g. `Izz1`), one of `BaseParameters::names`.
    pub name: String,
    /// Its column in the stacked regressor (an index into `BaseParameters::names`).
    pub column: usize,
    /// (name, coefficient) of the dependent parameters added to it (|coefficient| > 1e-10).
    pub plus: Vec<(String, f64)>,
    /// beta for the model's own parameters.
    pub value: f64,
}

impl Base {
    /// "Izz1 + 0.090000 m2 + 1.000000 Iyy2": the parameter and what is regrouped into it.
    pub fn relation(&self) -> String {
        let mut s = self.name.clone();
        for (n, k) in &self.plus {
            s += &format!(" {} {:.6} {n}", if *k < 0.0 { "-" } else { "+" }, k.abs());
        }
        s
    }
}

/// The base parameters of a stacked regressor (`base_parameters`, `reduce`): which columns form
/// the base, which are regrouped into it and which never act on a torque.
#[derive(Debug, Clone, Serialize)]
pub struct BaseParameters {
    /// Every column's name (regressor order).
    pub names: Vec<String>,
    /// The base parameters, in regressor order (base to tip).
    pub base: Vec<Base>,
    /// Columns that never act on a torque.
    pub unidentifiable: Vec<String>,
    /// Columns identifiable only through the base parameters they are regrouped into.
    pub combined: Vec<String>,
    /// Rows of the stacked regressor (states x joints).
    pub rows: usize,
    /// Every column's norm in the stacked regressor over the largest (the paper's first test:
    /// zero means unidentifiable), in `names` order.
    pub column_norms: Vec<f64>,
}

impl BaseParameters {
    /// How many base parameters there are (the stacked regressor's rank).
    pub fn base_count(&self) -> usize {
        self.base.len()
    }

    /// The base columns of `w` (a stacked regressor), in `base` order.
    pub fn base_columns(&self, w: &DMatrix<f64>) -> DMatrix<f64> {
        let cols: Vec<usize> = self.base.iter().map(|b| b.column).collect();
        w.select_columns(&cols)
    }
}

/// The regressor stacked over `states` random states drawn from `seed`.
pub fn stacked_regressor(model: &Model, friction: bool, states: usize, seed: u64) -> DMatrix<f64> {
    let n = model.dof();
    let p = model.regressor_columns(friction);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut d = model.data();
    let mut y = DMatrix::zeros(n, p);
    let mut w = DMatrix::zeros(states * n, p);
    for s in 0..states {
        let q: Vec<f64> = model
            .bodies
            .iter()
            .map(|b| {
                let (lo, hi) = b.limits.position_span();
                rng.gen_range(lo..hi)
            })
            .collect();
        let qd: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let qdd: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        model.regressor(&mut d, &q, &qd, &qdd, &mut y);
        w.view_mut((s * n, 0), (n, p)).copy_from(&y);
    }
    w
}

/// The base parameters of `model` from its regressor stacked over `states` random states.
pub fn base_parameters(model: &Model, friction: bool, states: usize, seed: u64) -> BaseParameters {
    let w = stacked_regressor(model, friction, states, seed);
    reduce(
        &w,
        model.parameter_names(friction),
        &model.parameters(friction),
    )
}

/// The base parameters of any stacked regressor `w` whose columns are `names` with the values
/// `pi` (an identification experiment's rows and columns: `identify::Stage`).
pub fn reduce(w: &DMatrix<f64>, names: Vec<String>, pi: &[f64]) -> BaseParameters {
    assert_eq!(w.ncols(), names.len(), "one name per column");
    assert_eq!(pi.len(), names.len(), "one value per column");
    let norms: Vec<f64> = w.column_iter().map(|c| c.norm()).collect();
    let largest = norms.iter().cloned().fold(0.0, f64::max);
    let (zero, acting): (Vec<usize>, Vec<usize>) =
        (0..names.len()).partition(|&c| norms[c] <= TOLERANCE * largest);
    let rank = if acting.is_empty() {
        0
    } else {
        let r = w.select_columns(&acting).col_piv_qr().r();
        let r00 = r[(0, 0)].abs();
        (0..r.nrows().min(r.ncols()))
            .take_while(|&i| r[(i, i)].abs() > TOLERANCE * r00)
            .count()
    };
    // Greedy choice in regressor order: keep a column whose residual against the kept ones'
    // orthonormal basis is not negligible (projected twice, for a clean residual).
    let mut basis: Vec<DVector<f64>> = Vec::with_capacity(rank);
    let (mut base_cols, mut dep_cols) = (Vec::new(), Vec::new());
    for &c in &acting {
        let col = w.column(c).into_owned();
        let mut res = col.clone();
        for _ in 0..2 {
            for q in &basis {
                let dot = q.dot(&res);
                res.axpy(-dot, q, 1.0);
            }
        }
        let norm = res.norm();
        if basis.len() < rank && norm > 1e-8 * col.norm() {
            basis.push(res / norm);
            base_cols.push(c);
        } else {
            dep_cols.push(c);
        }
    }
    let wb = w.select_columns(&base_cols);
    let wd = w.select_columns(&dep_cols);
    let k = if dep_cols.is_empty() {
        DMatrix::zeros(rank, 0)
    } else {
        wb.clone()
            .svd(true, true)
            .solve(&wd, 1e-14)
            .unwrap_or_else(|_| DMatrix::zeros(rank, dep_cols.len()))
    };
    let base = base_cols
        .iter()
        .enumerate()
        .map(|(i, &c)| {
            let plus: Vec<(String, f64)> = dep_cols
                .iter()
                .enumerate()
                .filter(|(j, _)| k[(i, *j)].abs() > 1e-10)
                .map(|(j, &d)| (names[d].clone(), k[(i, j)]))
                .collect();
            let value = pi[c]
                + dep_cols
                    .iter()
                    .enumerate()
                    .map(|(j, &d)| k[(i, j)] * pi[d])
                    .sum::<f64>();
            Base {
                name: names[c].clone(),
                column: c,
                plus,
                value,
            }
        })
        .collect();
    BaseParameters {
        unidentifiable: zero.iter().map(|&c| names[c].clone()).collect(),
        combined: dep_cols.iter().map(|&c| names[c].clone()).collect(),
        rows: w.nrows(),
        column_norms: norms
            .iter()
            .map(|v| if largest > 0.0 { v / largest } else { 0.0 })
            .collect(),
        names,
        base,
    }
}
