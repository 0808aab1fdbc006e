//! Householder reduction of a tall least-squares problem: `a` = Q R and Q^T `b`, without forming Q;
//! and `Ridges`, every ridge solution of such a problem from one SVD of R. nalgebra's `QR` (0.33)
//! is not used: on arm7's identification design (5 376 x 917, rank 265 to 1e-5, 2026-12-03) its Q R
//! did not reproduce the matrix (‖A − QR‖ 180 against ‖A‖ 302) while its SVD did (6.6e-13); the
//! cause was not isolated (random designs with zero, -0.0 and dependent columns factor correctly).
//! Here a column already zero below the diagonal is left as it is (its reflection is the identity).

use nalgebra::{DMatrix, DVector};

/// R (the first min(m, n) rows of the reduced `a`, upper trapezoidal) and the same rows of
/// Q^T `b`: the least-squares problem min ‖a x − b‖ becomes min ‖R x − (Q^T b)‖ up to a
/// constant residual, and R has `a`'s singular values and right singular vectors.
///
/// # Panics
/// If `b` does not have one entry per row of `a`.
pub fn householder_reduce(
    mut a: DMatrix<f64>,
    mut b: DVector<f64>,
) -> (DMatrix<f64>, DVector<f64>) {
    let (m, n) = a.shape();
    assert_eq!(b.len(), m, "one right-hand side entry per row");
    let k = m.min(n);
    let data = a.as_mut_slice();
    let b_col = b.as_mut_slice();
    // Reflection j's v, in the slot j % PANEL, and which reflections of the panel apply.
    let mut vs = vec![0.0; PANEL * m];
    let mut panel = Vec::with_capacity(PANEL);
    for j0 in (0..k).step_by(PANEL) {
        let j1 = (j0 + PANEL).min(k);
        panel.clear();
        // The panel's columns, one reflection at a time, each applied to the panel's later
        // columns only.
        for j in j0..j1 {
            let (done, rest) = data.split_at_mut((j + 1) * m);
            let slot = &mut vs[(j - j0) * m..][..m - j];
            let Some(beta) = reflection(&mut done[j * m..], j, slot) else {
                continue;
            };
            reflect_columns(&mut rest[..(j1 - j - 1) * m], m, slot, beta, j);
            panel.push((j, beta));
        }
        // Then every later column (and b) through the panel's reflections in turn, a few
        // columns at a time while they are in cache: each column meets the same reflections
        // in the same order as if each reflection swept the whole matrix, so R is the same.
        for group in data[j1 * m..n * m].chunks_mut(LANES * m) {
            for &(j, beta) in &panel {
                reflect_columns(group, m, &vs[(j - j0) * m..][..m - j], beta, j);
            }
        }
        for &(j, beta) in &panel {
            reflect_lanes(&vs[(j - j0) * m..][..m - j], beta, [&mut b_col[j..]]);
        }
    }
    let r = a.rows(0, k).upper_triangle();
    (r, b.rows(0, k).into_owned())
}

/// How many reflections `householder_reduce` applies to a group of columns while it is in
/// cache: their v's (8 x 43 kB on arm7's 5 376-row design) and the group fit in L2.
const PANEL: usize = 8;

/// How many columns `householder_reduce` reflects together: enough independent add chains to
/// cover an add's latency.
const LANES: usize = 4;

/// The reflection I - beta v v^T that maps `col`'s rows j.. (of a column-major column starting
/// at `col[0]`, rows 0..m) to alpha e_1: v written into `v`, the column set to alpha and
/// zeros, beta returned; `None` (the identity) where those rows are already zero.
fn reflection(col: &mut [f64], j: usize, v: &mut [f64]) -> Option<f64> {
    let x = &mut col[j..j + v.len()];
    let (alpha, beta) = householder_vector(x, v)?;
    x[0] = alpha;
    x[1..].fill(0.0);
    Some(beta)
}

/// The Householder reflection I - beta v v^T that maps `x` to alpha e_1: v (as long as x)
/// written into `v`, (alpha, beta) returned; `None` (the identity) where x is zero.
pub fn householder_vector(x: &[f64], v: &mut [f64]) -> Option<(f64, f64)> {
    let norm = x.iter().map(|e| e * e).sum::<f64>().sqrt();
    if norm == 0.0 {
        return None;
    }
    // alpha's sign opposes x_0's, so that v_0 = x_0 - alpha does not cancel.
    let alpha = if x[0] >= 0.0 { -norm } else { norm };
    v.copy_from_slice(x);
    v[0] -= alpha;
    Some((alpha, 2.0 / v.iter().map(|e| e * e).sum::<f64>()))
}

/// Rows j.. of each whole column (`m` rows) in `cols` reflected by I - beta v v^T, LANES
/// columns at a time: one column's dot product is a chain of adds each waiting on the last, so
/// several columns' chains run side by side.
fn reflect_columns(cols: &mut [f64], m: usize, v: &[f64], beta: f64, j: usize) {
    for group in cols.chunks_mut(LANES * m) {
        let mut cols = group.chunks_exact_mut(m).map(|c| &mut c[j..]);
        if cols.len() == LANES {
            let full: [&mut [f64]; LANES] =
                std::array::from_fn(|_| cols.next().expect("LANES columns"));
            reflect_lanes(v, beta, full);
        } else {
            cols.for_each(|c| reflect_lanes(v, beta, [c]));
        }
    }
}

/// Each of `cols` reflected by I - beta v v^T: col -= beta (v . col) v, the columns' dot
/// products interleaved (`dots`: bit for bit each column's own in-order sum).
fn reflect_lanes<const L: usize>(v: &[f64], beta: f64, mut cols: [&mut [f64]; L]) {
    let dot = crate::dots(v, cols.each_ref().map(|c| &**c));
    for (c, s) in cols.iter_mut().zip(dot) {
        let d = beta * s;
        c.iter_mut().zip(v).for_each(|(c, p)| *c -= d * p);
    }
}

/// The ridge solutions x(rho) = argmin ‖a x − b‖² + (rho s_max)² ‖x‖² of one least-squares
/// problem, for any rho relative to `a`'s largest singular value s_max, from one SVD:
/// x = V (S² + (rho s_max)²)⁻¹ S U^T b. Built through R (`householder_reduce`), whose SVD has
/// `a`'s S and V and whose U_R^T (Q^T b) is U^T b, so that U never has a row per equation.
pub struct Ridges {
    v_t: DMatrix<f64>,
    s: DVector<f64>,
    ub: DVector<f64>,
}

impl Ridges {
    /// `None` where the SVD gives no singular vectors.
    pub fn new(a: DMatrix<f64>, b: DVector<f64>) -> Option<Self> {
        let (r, qtb) = householder_reduce(a, b);
        Self::from_svd(r.svd(true, true), &qtb)
    }

    fn from_svd(
        svd: nalgebra::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
        b: &DVector<f64>,
    ) -> Option<Self> {
        let ub = svd.u?.tr_mul(b);
        Some(Ridges {
            v_t: svd.v_t?,
            s: svd.singular_values,
            ub,
        })
    }

    /// s_max (NaN where the problem held one).
    pub fn largest_singular_value(&self) -> f64 {
        self.s.max()
    }

    /// x(rho).
    pub fn solution(&self, rho: f64) -> DVector<f64> {
        let l2 = (rho * self.s.max()).powi(2);
        let z = DVector::from_iterator(
            self.s.len(),
            self.s
                .iter()
                .zip(self.ub.iter())
                .map(|(&si, &b)| si / (si * si + l2) * b),
        );
        self.v_t.tr_mul(&z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn xorshift(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        }
    }

    /// A tall design as the RKGNN's: columns over eight decades, zero columns (one of -0.0),
    /// columns that are combinations of others, and one nonzero only in its first rows (zero
    /// below the diagonal once the columns before it are reduced).
    fn design(m: usize, n: usize) -> (DMatrix<f64>, DVector<f64>) {
        let mut next = xorshift(0x2545_f491_4f6c_dd1d);
        let mut a = DMatrix::from_fn(m, n, |_, _| next());
        for c in 0..n {
            a.column_mut(c)
                .scale_mut(10f64.powf(-8.0 * c as f64 / n as f64));
        }
        a.column_mut(7).fill(0.0);
        // Zero times a negative scale gives -0.0.
        a.column_mut(11).fill(-0.0);
        for c in (n / 2..n).step_by(3) {
            let copy = a.column(c - n / 2) * 0.5 + a.column(c - n / 2 + 1) * 0.25;
            a.column_mut(c).copy_from(&copy);
        }
        a.column_mut(n - 1).fill(0.0);
        a[(0, n - 1)] = 1.0;
        a[(3, n - 1)] = -2.0;
        (a, DVector::from_fn(m, |_, _| next()))
    }

    #[test]
    fn r_reproduces_the_matrix_and_keeps_its_singular_values() {
        let (a, b) = design(300, 60);
        let whole = a.clone().svd(false, false).singular_values;
        let (r, qtb) = householder_reduce(a.clone(), b.clone());
        assert_eq!(r.shape(), (60, 60));
        let reduced = r.clone().svd(false, false).singular_values;
        let diff = (&whole - &reduced).norm() / whole.norm();
        assert!(diff < 1e-13, "singular values differ by {diff}");
        // R^T R = A^T A and R^T (Q^T b) = A^T b: the normal equations are the same.
        let gram = (r.tr_mul(&r) - a.tr_mul(&a)).norm() / a.tr_mul(&a).norm();
        assert!(gram < 1e-13, "R^T R differs from A^T A by {gram}");
        let atb = (r.tr_mul(&qtb) - a.tr_mul(&b)).norm() / a.tr_mul(&b).norm();
        assert!(atb < 1e-13, "R^T Q^T b differs from A^T b by {atb}");
    }

    /// The interleaved reflections give R and Q^T b bit for bit as one column at a time does
    /// (the reduction as it was written before the columns were grouped), also with a group
    /// left over, with zero and -0.0 columns, and on shapes smaller than a panel (no column at
    /// all among them): the identification's models do not move.
    #[test]
    fn reflecting_columns_together_changes_no_bit() {
        fn one_at_a_time(mut a: DMatrix<f64>, mut b: DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
            let (m, n) = a.shape();
            let k = m.min(n);
            let mut v = vec![0.0; m];
            let data = a.as_mut_slice();
            for j in 0..k {
                let len = m - j;
                let x = &data[j * m + j..(j + 1) * m];
                let norm = x.iter().map(|e| e * e).sum::<f64>().sqrt();
                if norm == 0.0 {
                    continue;
                }
                let alpha = if x[0] >= 0.0 { -norm } else { norm };
                v[..len].copy_from_slice(x);
                v[0] -= alpha;
                let beta = 2.0 / v[..len].iter().map(|e| e * e).sum::<f64>();
                let reflect = |col: &mut [f64]| {
                    let d = beta
                        * v[..len]
                            .iter()
                            .zip(col.iter())
                            .map(|(p, q)| p * q)
                            .sum::<f64>();
                    col.iter_mut().zip(&v[..len]).for_each(|(c, p)| *c -= d * p);
                };
                for c in j + 1..n {
                    reflect(&mut data[c * m + j..(c + 1) * m]);
                }
                reflect(&mut b.as_mut_slice()[j..]);
                let col = &mut data[j * m + j..(j + 1) * m];
                col[0] = alpha;
                col[1..].fill(0.0);
            }
            (a.rows(0, k).upper_triangle(), b.rows(0, k).into_owned())
        }
        let bits = |x: &[f64]| x.iter().map(|e| e.to_bits()).collect::<Vec<_>>();
        let small = |m: usize, n: usize| {
            let mut next = xorshift(0x9e37_79b9_7f4a_7c15);
            (
                DMatrix::from_fn(m, n, |_, _| next()),
                DVector::from_fn(m, |_, _| next()),
            )
        };
        let designs = [(300, 61), (200, 64), (40, 90)].map(|(m, n)| design(m, n));
        let smalls = [(5, 3), (3, 7), (10, 0)].map(|(m, n)| small(m, n));
        for (a, b) in designs.into_iter().chain(smalls) {
            let (m, n) = a.shape();
            let (r, qtb) = householder_reduce(a.clone(), b.clone());
            let (r0, qtb0) = one_at_a_time(a, b);
            assert_eq!(bits(r.as_slice()), bits(r0.as_slice()), "R of {m} x {n}");
            assert_eq!(
                bits(qtb.as_slice()),
                bits(qtb0.as_slice()),
                "Q^T b of {m} x {n}"
            );
        }
    }

    /// Ridge solutions through R equal those of the whole matrix's SVD (U^T b over every
    /// row), at ridges from 1e-5 to 1 of the largest singular value.
    #[test]
    fn ridge_solutions_through_r_equal_the_whole_matrixs() {
        let (a, b) = design(700, 120);
        let whole = Ridges::from_svd(a.clone().svd(true, true), &b).unwrap();
        let reduced = Ridges::new(a, b).unwrap();
        for rho in [1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0] {
            let (x, y) = (whole.solution(rho), reduced.solution(rho));
            let err = (&x - &y).norm() / x.norm();
            assert!(err < 1e-9, "ridge {rho}: relative difference {err}");
        }
    }

    /// A wide problem (fewer rows than columns) keeps every row.
    #[test]
    fn a_wide_matrix_keeps_its_rows() {
        let (a, b) = design(30, 60);
        let (r, qtb) = householder_reduce(a.clone(), b.clone());
        assert_eq!((r.shape(), qtb.len()), ((30, 60), 30));
        let gram = (r.tr_mul(&r) - a.tr_mul(&a)).norm() / a.tr_mul(&a).norm();
        assert!(gram < 1e-13, "{gram}");
    }
}
