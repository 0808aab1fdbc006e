//! Continuous-time LQR: the stabilising solution P of the algebraic Riccati equation
//!   A'P + PA - P B R^-1 B' P + Q = 0,  K = R^-1 B' P,  u = -K x,
//! by the matrix sign function of the Hamiltonian (with determinant scaling), refined by
//! Newton-Kleinman steps, and checked by its residual.

use nalgebra::DMatrix;
use std::fmt;

/// The continuous-time LQR design: gain, Riccati solution and its residual.
#[derive(Debug, Clone)]
pub struct LqrSolution {
    /// The optimal gain K = R^-1 B' P (m x n), for u = -K x.
    pub k: DMatrix<f64>,
    /// The stabilising solution P of the Riccati equation (n x n, symmetric).
    pub p: DMatrix<f64>,
    /// ||A'P + PA - PBR^-1B'P + Q||_F / max(1, ||Q||_F).
    pub residual: f64,
}

/// Why `lqr` found no gain.
#[derive(Debug, Clone, PartialEq)]
pub enum LqrError {
    /// A, B, Q and R do not fit together (their shapes).
    Dimensions(String),
    /// R is not symmetric positive definite.
    RNotPositiveDefinite,
    /// The Hamiltonian has eigenvalues on the imaginary axis (no stabilising solution: the
    /// pair (A, B) is not stabilisable or (Q, A) has unobservable modes on the axis).
    NoStabilisingSolution,
    /// The solution does not satisfy the equation to the required accuracy.
    Inaccurate(f64),
}

impl fmt::Display for LqrError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LqrError::Dimensions(s) => write!(f, "LQR: dimensions: {s}"),
            LqrError::RNotPositiveDefinite => {
                write!(f, "LQR: R must be symmetric positive definite")
            }
            LqrError::NoStabilisingSolution => write!(
                f,
                "LQR: no stabilising solution ((A, B) not stabilisable or (Q, A) not detectable)"
            ),
            LqrError::Inaccurate(r) => write!(f, "LQR: Riccati residual {r:e} too large"),
        }
    }
}

impl std::error::Error for LqrError {}

/// Solve the continuous-time LQR problem.
pub fn lqr(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
) -> Result<LqrSolution, LqrError> {
    let n = a.nrows();
    let m = b.ncols();
    if a.ncols() != n || b.nrows() != n || q.shape() != (n, n) || r.shape() != (m, m) {
        return Err(LqrError::Dimensions(format!(
            "A {:?}, B {:?}, Q {:?}, R {:?}",
            a.shape(),
            b.shape(),
            q.shape(),
            r.shape()
        )));
    }
    let r_inv = r
        .clone()
        .cholesky()
        .ok_or(LqrError::RNotPositiveDefinite)?
        .inverse();
    let s = b * &r_inv * b.transpose();
    // Hamiltonian H = [[A, -S], [-Q, -A']].
    let mut h = DMatrix::zeros(2 * n, 2 * n);
    h.view_mut((0, 0), (n, n)).copy_from(a);
    h.view_mut((0, n), (n, n)).copy_from(&(-&s));
    h.view_mut((n, 0), (n, n)).copy_from(&(-q));
    h.view_mut((n, n), (n, n)).copy_from(&(-a.transpose()));
    let w = matrix_sign(h).ok_or(LqrError::NoStabilisingSolution)?;
    // P solves [W12; W22 + I] P = -[W11 + I; W21] (least squares, 2n x n).
    let eye = DMatrix::<f64>::identity(n, n);
    let mut lhs = DMatrix::zeros(2 * n, n);
    lhs.view_mut((0, 0), (n, n))
        .copy_from(&w.view((0, n), (n, n)));
    lhs.view_mut((n, 0), (n, n))
        .copy_from(&(w.view((n, n), (n, n)) + &eye));
    let mut rhs = DMatrix::zeros(2 * n, n);
    rhs.view_mut((0, 0), (n, n))
        .copy_from(&(-(w.view((0, 0), (n, n)) + &eye)));
    rhs.view_mut((n, 0), (n, n))
        .copy_from(&(-w.view((n, 0), (n, n))));
    let svd = lhs.svd(true, true);
    let mut p = svd
        .solve(&rhs, 1e-14)
        .map_err(|_| LqrError::NoStabilisingSolution)?;
    p = (&p + p.transpose()) * 0.5;
    // Newton-Kleinman refinement: each step solves a Lyapunov equation for the closed loop.
    for _ in 0..3 {
        let k = &r_inv * b.transpose() * &p;
        let acl = a - b * &k;
        let rhs = -(q + k.transpose() * r * &k);
        match lyapunov(&acl, &rhs) {
            Some(pn) => p = (&pn + pn.transpose()) * 0.5,
            None => break,
        }
    }
    let residual = riccati_residual(a, &s, q, &p);
    // NaN counts as too large.
    if residual.is_nan() || residual >= 1e-8 {
        return Err(LqrError::Inaccurate(residual));
    }
    Ok(LqrSolution {
        k: &r_inv * b.transpose() * &p,
        p,
        residual,
    })
}

/// ||A'P + PA - PSP + Q||_F / max(1, ||Q||_F).
pub fn riccati_residual(
    a: &DMatrix<f64>,
    s: &DMatrix<f64>,
    q: &DMatrix<f64>,
    p: &DMatrix<f64>,
) -> f64 {
    let res = a.transpose() * p + p * a - p * s * p + q;
    res.norm() / q.norm().max(1.0)
}

/// sign(H) by the scaled Newton iteration Z <- (Z/c + c Z^-1) / 2, c = |det Z|^(1/N).
/// None when Z becomes singular (eigenvalues on the imaginary axis) or it does not converge.
fn matrix_sign(mut z: DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = z.nrows() as f64;
    for _ in 0..100 {
        let lu = z.clone().lu();
        let det = lu.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let zi = lu.try_inverse()?;
        let c = det.abs().powf(1.0 / n);
        let next = (&z / c + zi * c) * 0.5;
        let change = (&next - &z).norm();
        let size = next.norm();
        z = next;
        if change <= 1e-13 * size {
            return Some(z);
        }
    }
    None
}

/// Solve A'X + XA = C (C symmetric) by the Kronecker form; fine for the small systems here.
pub fn lyapunov(a: &DMatrix<f64>, c: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = a.nrows();
    let eye = DMatrix::<f64>::identity(n, n);
    // vec(A'X + XA) = (I kron A' + A' kron I) vec(X)
    let at = a.transpose();
    let m = eye.kronecker(&at) + at.kronecker(&eye);
    let v = DMatrix::from_column_slice(n * n, 1, c.as_slice());
    let x = m.lu().solve(&v)?;
    Some(DMatrix::from_column_slice(n, n, x.as_slice()))
}
