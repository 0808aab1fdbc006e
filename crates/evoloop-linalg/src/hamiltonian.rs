//! Eigenvalues of a real Hamiltonian matrix M = [[A, G], [Q, -A']] (G, Q symmetric) by Van Loan's
//! square-reduced method (C. Van Loan, "A symplectic method for approximating all the eigenvalues
//! of a Hamiltonian matrix", Linear Algebra Appl. 61, 1984), the method SLICOT's AB13DD uses for
//! the H-infinity norm: N = M^2 is skew-Hamiltonian, an orthogonal symplectic similarity takes it
//! to [[W, X], [0, W']] with W upper Hessenberg (the PVL form), and the eigenvalues of M are
//! +-sqrt(mu) for each eigenvalue mu of W. The QR iteration then runs on W, of order n, instead
//! of on M, of order 2n (about half the sweeps, each on a quarter of the entries; forming M^2
//! and reducing it cost about what M's own Hessenberg reduction did). The price is accuracy for
//! eigenvalues much smaller than |M| (an error of about eps |M|^2 / |lambda|), and it keeps the
//! spectrum's symmetry exactly: an imaginary pair +-jw of M is a real negative mu of W.

use crate::eigen::hessenberg_eigenvalues;
use crate::householder::householder_vector;
use nalgebra::{Complex, DMatrix};

/// One of each pair +-lambda of eigenvalues of the Hamiltonian `m` (order 2n): sqrt(mu), the
/// principal root, for each of the n eigenvalues mu of M^2's PVL block W. An eigenvalue on the
/// imaginary axis comes out as +jw exactly when mu is real and negative. None if `m` is not square of even
/// order or the QR iteration does not converge.
pub fn hamiltonian_eigenvalues(m: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    let nn = m.nrows();
    if m.ncols() != nn || !nn.is_multiple_of(2) {
        return None;
    }
    let mut w = m * m;
    pvl_reduce(&mut w);
    let n = nn / 2;
    let block = w.view((0, 0), (n, n)).into_owned();
    let mu = hessenberg_eigenvalues(&block)?;
    Some(mu.iter().map(|z| z.sqrt()).collect())
}

/// Van Loan's reduction of the skew-Hamiltonian `w` (order 2n) in place, by the similarities of
/// orthogonal symplectic matrices (a reflection acting alike on both halves, a rotation between
/// index i and n + i): column by column, the lower left block's column is cleared below the
/// diagonal (a reflection, then a rotation into the upper left block) and the upper left block's
/// below the subdiagonal (a reflection). The lower left block then is zero (it stays skew), the
/// upper left block W upper Hessenberg; only W is read afterwards.
fn pvl_reduce(w: &mut DMatrix<f64>) {
    let n = w.nrows() / 2;
    let mut v = vec![0.0; n];
    for j in 0..n.saturating_sub(1) {
        // The lower left block's column j below row j + 1, into its row j + 1.
        if reflector(w, n + j + 1, j, n - j - 1, &mut v) {
            reflect_both_halves(w, j + 1, &v[..n - j - 1]);
        }
        // Its row j + 1 into the upper left block.
        rotate(w, j + 1, j);
        // The upper left block's column j below the subdiagonal.
        if reflector(w, j + 1, j, n - j - 1, &mut v) {
            reflect_both_halves(w, j + 1, &v[..n - j - 1]);
        }
    }
}

/// The reflection's vector v, scaled so that P = I - v v', with P x a multiple of e1 for
/// x = w[row.., col] (`len` entries), into v[..len]; false when x already is one.
fn reflector(w: &DMatrix<f64>, row: usize, col: usize, len: usize, v: &mut [f64]) -> bool {
    let start = row + col * w.nrows(); // column-major
    let x = &w.as_slice()[start..start + len];
    if len < 2 || x[1..].iter().all(|t| *t == 0.0) {
        return false;
    }
    let Some((_, beta)) = householder_vector(x, &mut v[..len]) else {
        return false;
    };
    let scale = beta.sqrt();
    v[..len].iter_mut().for_each(|vi| *vi *= scale);
    true
}

/// w <- U w U with U = diag(P, P), P = I - v v' acting on indices `start..start + len` of each
/// half (U is symmetric and orthogonal).
fn reflect_both_halves(w: &mut DMatrix<f64>, start: usize, v: &[f64]) {
    let n = w.nrows() / 2;
    for offset in [start, n + start] {
        // From the left: rows offset.., every column.
        for c in 0..2 * n {
            let d: f64 = v
                .iter()
                .enumerate()
                .map(|(k, vk)| vk * w[(offset + k, c)])
                .sum();
            for (k, vk) in v.iter().enumerate() {
                w[(offset + k, c)] -= vk * d;
            }
        }
        // From the right: columns offset.., every row.
        for r in 0..2 * n {
            let d: f64 = v
                .iter()
                .enumerate()
                .map(|(k, vk)| vk * w[(r, offset + k)])
                .sum();
            for (k, vk) in v.iter().enumerate() {
                w[(r, offset + k)] -= vk * d;
            }
        }
    }
}

/// The rotation in the plane (i, n + i) that zeroes w[(n + i, col)] against w[(i, col)], applied
/// as a similarity.
fn rotate(w: &mut DMatrix<f64>, i: usize, col: usize) {
    let n = w.nrows() / 2;
    let (a, b) = (w[(i, col)], w[(n + i, col)]);
    if b == 0.0 {
        return;
    }
    let r = a.hypot(b);
    let (c, s) = (a / r, b / r);
    for k in 0..2 * n {
        let (x, y) = (w[(i, k)], w[(n + i, k)]);
        w[(i, k)] = c * x + s * y;
        w[(n + i, k)] = c * y - s * x;
    }
    for k in 0..2 * n {
        let (x, y) = (w[(k, i)], w[(k, n + i)]);
        w[(k, i)] = c * x + s * y;
        w[(k, n + i)] = c * y - s * x;
    }
}
