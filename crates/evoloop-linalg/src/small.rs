//! Small dense matrices on the stack (n <= MAX_JOINTS, row-major), allocation-free: what the
//! control cycle and the RKGNN model evaluate every period, where nalgebra's heap matrices would
//! allocate.

use evoloop_msg::MAX_JOINTS;
use nalgebra::{DMatrix, DVector};

/// A small n x n matrix on the stack, row-major.
pub type Mat = [f64; MAX_JOINTS * MAX_JOINTS];

/// A matrix that should be positive definite is not (for an inertia matrix M(q): a body carries
/// no inertia at this configuration).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NotPositiveDefinite {
    /// The first row (joint) whose pivot failed.
    pub joint: usize,
}

/// In-place Cholesky M = L Lᵀ (lower triangle of `a` overwritten by L) and solve of M x = b into
/// `b`. Written out rather than through nalgebra's `Cholesky`, which takes its matrix by value:
/// this keeps the factor in a buffer that lives in `Data` and the call allocation-free.
pub fn cholesky_solve_in_place(
    a: &mut DMatrix<f64>,
    b: &mut DVector<f64>,
) -> Result<(), NotPositiveDefinite> {
    let n = a.nrows();
    for j in 0..n {
        let mut s = a[(j, j)];
        for k in 0..j {
            s -= a[(j, k)] * a[(j, k)];
        }
        if s.is_nan() || s <= 0.0 {
            return Err(NotPositiveDefinite { joint: j });
        }
        let l = s.sqrt();
        a[(j, j)] = l;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / l;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[(i, k)] * b[k];
        }
        b[i] = s / a[(i, i)];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[(k, i)] * b[k];
        }
        b[i] = s / a[(i, i)];
    }
    Ok(())
}

/// Solve m z = b in place (b <- z) by Gaussian elimination with partial pivoting: M-hat may be
/// indefinite while the search explores, so Cholesky would not do. False when a pivot is below
/// 1e-12 of the largest entry (numerically singular).
pub fn solve(n: usize, m: &mut Mat, b: &mut [f64]) -> bool {
    let scale = m[..n * n].iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(scale > 0.0 && scale.is_finite()) {
        return false;
    }
    for c in 0..n {
        let piv = (c..n)
            .max_by(|&i, &j| m[i * n + c].abs().total_cmp(&m[j * n + c].abs()))
            .unwrap_or(c);
        if m[piv * n + c].abs() < 1e-12 * scale {
            return false;
        }
        if piv != c {
            for k in 0..n {
                m.swap(c * n + k, piv * n + k);
            }
            b.swap(c, piv);
        }
        let d = m[c * n + c];
        for i in c + 1..n {
            let f = m[i * n + c] / d;
            if f != 0.0 {
                for k in c..n {
                    m[i * n + k] -= f * m[c * n + k];
                }
                b[i] -= f * b[c];
            }
        }
    }
    for c in (0..n).rev() {
        let mut s = b[c];
        for k in c + 1..n {
            s -= m[c * n + k] * b[k];
        }
        b[c] = s / m[c * n + c];
    }
    true
}

/// The leading principal minors of the n x n matrix m (Sylvester: all > 0 iff positive
/// definite); their minimum is eq. 14's Gamma. By elimination without pivoting: minor k is the
/// product of the first k pivots; a zero pivot ends the sequence with 0.
pub fn min_leading_minor(n: usize, m: &Mat) -> f64 {
    let mut a = *m;
    let mut det = 1.0;
    let mut min = f64::INFINITY;
    for c in 0..n {
        let d = a[c * n + c];
        det *= d;
        min = min.min(det);
        if d == 0.0 {
            return min.min(0.0);
        }
        for i in c + 1..n {
            let f = a[i * n + c] / d;
            for k in c..n {
                a[i * n + k] -= f * a[c * n + k];
            }
        }
    }
    min
}

/// Smallest and largest eigenvalue of a symmetric n x n matrix (cyclic Jacobi; n <= 8, so a few
/// sweeps). Allocation-free.
pub fn sym_eig_range(n: usize, m: &Mat) -> (f64, f64) {
    let mut a = *m;
    for _sweep in 0..50 {
        let mut off = 0.0;
        for i in 0..n {
            for j in i + 1..n {
                off += a[i * n + j] * a[i * n + j];
            }
        }
        if off < 1e-30 {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq.abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum().max(0.0).mul_add(2.0, -1.0)
                    / (theta.abs() + (theta * theta + 1.0).sqrt());
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
            }
        }
    }
    (0..n).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| {
        let d = a[i * n + i];
        (lo.min(d), hi.max(d))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minors_and_eigenvalues_by_hand() {
        let mut m = [0.0; 64];
        // [[2, 1, 0], [1, 2, 0], [0, 0, 0.5]]: minors 2, 3, 1.5; eigenvalues 1, 3, 0.5.
        m[..9].copy_from_slice(&[2.0, 1.0, 0.0, 1.0, 2.0, 0.0, 0.0, 0.0, 0.5]);
        assert!((min_leading_minor(3, &m) - 1.5).abs() < 1e-12);
        let (lo, hi) = sym_eig_range(3, &m);
        assert!(
            (lo - 0.5).abs() < 1e-12 && (hi - 3.0).abs() < 1e-12,
            "{lo} {hi}"
        );
        // Indefinite: [[1, 2], [2, 1]]: minors 1, -3; eigenvalues -1, 3.
        m[..4].copy_from_slice(&[1.0, 2.0, 2.0, 1.0]);
        assert!((min_leading_minor(2, &m) + 3.0).abs() < 1e-12);
        let (lo, hi) = sym_eig_range(2, &m);
        assert!((lo + 1.0).abs() < 1e-12 && (hi - 3.0).abs() < 1e-12);
    }

    /// Against nalgebra's own decompositions (an independent implementation) on random
    /// symmetric positive definite matrices of every size the messages carry.
    #[test]
    fn cholesky_solve_and_eigenvalue_bounds_agree_with_nalgebra() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for n in 1..=MAX_JOINTS {
            for _ in 0..20 {
                let b = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
                let spd = &b * b.transpose() + DMatrix::identity(n, n) * 0.1;
                let rhs = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
                let want = spd.clone().lu().solve(&rhs).unwrap();
                let (mut a, mut x) = (spd.clone(), rhs.clone());
                cholesky_solve_in_place(&mut a, &mut x).unwrap();
                assert!((&x - &want).norm() < 1e-9 * want.norm().max(1.0), "n {n}");
                let mut m: Mat = [0.0; MAX_JOINTS * MAX_JOINTS];
                for i in 0..n {
                    for j in 0..n {
                        m[i * n + j] = spd[(i, j)];
                    }
                }
                let mut y = [0.0; MAX_JOINTS];
                y[..n].copy_from_slice(rhs.as_slice());
                assert!(solve(n, &mut m.clone(), &mut y[..n]));
                assert!(
                    (DVector::from_row_slice(&y[..n]) - &want).norm() < 1e-9 * want.norm().max(1.0)
                );
                let e = spd.clone().symmetric_eigen().eigenvalues;
                let (lo, hi) = sym_eig_range(n, &m);
                assert!(
                    (lo - e.min()).abs() < 1e-10 && (hi - e.max()).abs() < 1e-10,
                    "n {n}"
                );
                assert!(min_leading_minor(n, &m) > 0.0);
            }
        }
        // Not positive definite: the failing row is named.
        let mut a = DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 2.0, 1.0]);
        let mut x = DVector::from_row_slice(&[1.0, 1.0]);
        assert_eq!(
            cholesky_solve_in_place(&mut a, &mut x),
            Err(NotPositiveDefinite { joint: 1 })
        );
    }
}
