//! Eigenvalues of a small real matrix without eigenvectors: Householder reduction to Hessenberg
//! form, then the Francis double-shift QR iteration (the classical `hqr` of EISPACK / Numerical
//! Recipes). It does only what the stability radius needs, several times faster than a full
//! Schur decomposition for the 5x5 closed loops and the Hamiltonians' 5x5 square-reduced blocks
//! here (`hessenberg_eigenvalues` for a matrix already in Hessenberg form); tests check it
//! against nalgebra's Schur-based eigenvalues.

use nalgebra::{Complex, DMatrix};

/// Eigenvalues of the square matrix `a` (any order). None if the QR iteration does not converge.
pub fn eigenvalues(a: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    let n = a.nrows();
    if n == 0 {
        return Some(Vec::new());
    }
    hessenberg_eigenvalues(&a.clone().hessenberg().h())
}

/// Eigenvalues of `h`, which must be upper Hessenberg (zero below its subdiagonal; what lies
/// there is ignored), by the QR iteration alone: for a caller that keeps its matrices in a basis
/// where they are Hessenberg and so pays for no reduction. None if the iteration does not converge.
pub fn hessenberg_eigenvalues(h: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    let n = h.nrows();
    if n == 0 {
        return Some(Vec::new());
    }
    // 1-based working copy, as in the classical formulation.
    let mut m = vec![0.0; (n + 1) * (n + 1)];
    let w = n + 1;
    for i in 0..n {
        for j in i.saturating_sub(1)..n {
            m[(i + 1) * w + j + 1] = h[(i, j)];
        }
    }
    let mut wr = vec![0.0; n + 1];
    let mut wi = vec![0.0; n + 1];
    hqr(&mut m, n, &mut wr, &mut wi)?;
    Some((1..=n).map(|i| Complex::new(wr[i], wi[i])).collect())
}

/// Eigenvalues by `eigenvalues`, falling back to nalgebra's Schur decomposition (of the
/// Hessenberg form) in the (rare) case the QR iteration does not converge.
pub fn eig(a: &DMatrix<f64>) -> Vec<Complex<f64>> {
    if a.nrows() == 0 {
        return Vec::new();
    }
    hessenberg_eig(&a.clone().hessenberg().h())
}

/// Eigenvalues of the upper Hessenberg `h` by `hessenberg_eigenvalues`, falling back to
/// nalgebra's Schur decomposition (of `h` with what lies below its subdiagonal ignored, as the
/// QR iteration ignores it) in the (rare) case the QR iteration does not converge.
pub fn hessenberg_eig(h: &DMatrix<f64>) -> Vec<Complex<f64>> {
    hessenberg_eigenvalues(h).unwrap_or_else(|| {
        let mut upper = h.clone();
        upper.fill_lower_triangle(0.0, 2);
        upper.complex_eigenvalues().iter().copied().collect()
    })
}

/// The 1-based Hessenberg matrix of order `n` stored row by row with stride `n + 1`, as the
/// classical `hqr` indexes it.
struct Hess<'a> {
    a: &'a mut [f64],
    w: usize,
}

impl Hess<'_> {
    fn at(&self, i: usize, j: usize) -> f64 {
        self.a[i * self.w + j]
    }

    fn at_mut(&mut self, i: usize, j: usize) -> &mut f64 {
        &mut self.a[i * self.w + j]
    }
}

/// The classical `hqr`: the eigenvalues of the upper Hessenberg `a` (1-based, order `n`) into
/// `wr` and `wi` (1-based), deflating one or two roots at a time off the bottom of the active
/// block. None after 60 iterations on one root. Each step below is one part of the classical
/// routine, with its arithmetic in the same order (the results are bit for bit those of the
/// single routine they were split from).
fn hqr(a: &mut [f64], n: usize, wr: &mut [f64], wi: &mut [f64]) -> Option<()> {
    let mut h = Hess { a, w: n + 1 };
    let mut anorm = 0.0;
    for i in 1..=n {
        for j in i.saturating_sub(1).max(1)..=n {
            anorm += h.at(i, j).abs();
        }
    }
    let mut nn = n;
    // The shifts accumulated by exceptional shifts, added back to every root.
    let mut t = 0.0;
    while nn >= 1 {
        let mut its = 0;
        loop {
            let nu = nn;
            let l = small_subdiagonal(&mut h, nu, anorm);
            let x = h.at(nu, nu);
            if l == nu {
                // One root found.
                wr[nu] = x + t;
                wi[nu] = 0.0;
                nn -= 1;
                break;
            }
            let y = h.at(nu - 1, nu - 1);
            let ww = h.at(nu, nu - 1) * h.at(nu - 1, nu);
            if l == nu - 1 {
                two_roots(x, y, ww, t, &mut wr[nu - 1..=nu], &mut wi[nu - 1..=nu]);
                nn -= 2;
                break;
            }
            if its == 60 {
                return None;
            }
            let (mut x, mut y, mut wv) = (x, y, ww);
            if its == 10 || its == 20 {
                // Exceptional shift.
                t += x;
                for i in 1..=nu {
                    *h.at_mut(i, i) -= x;
                }
                let s = h.at(nu, nu - 1).abs() + h.at(nu - 1, nu - 2).abs();
                x = 0.75 * s;
                y = x;
                wv = -0.4375 * s * s;
            }
            its += 1;
            let (m, pqr) = shift_start(&mut h, nu, l, x, y, wv);
            double_qr_step(&mut h, nu, l, m, pqr);
            if l >= nu - 1 {
                break;
            }
        }
    }
    Some(())
}

/// The lowest `l` (down from `nu`) whose subdiagonal element is negligible against its two
/// diagonal neighbours (or against `anorm` where both are zero), zeroed; 1 if none is.
fn small_subdiagonal(h: &mut Hess, nu: usize, anorm: f64) -> usize {
    let mut l = nu;
    while l >= 2 {
        let mut s = h.at(l - 1, l - 1).abs() + h.at(l, l).abs();
        if s == 0.0 {
            s = anorm;
        }
        if h.at(l, l - 1).abs() + s == s {
            *h.at_mut(l, l - 1) = 0.0;
            break;
        }
        l -= 1;
    }
    l
}

/// The two roots of the trailing 2x2 block (diagonal `y` above `x`; `ww` the product of its
/// off-diagonal elements), shifted back by `t`, into `wr` and `wi` (two entries each).
fn two_roots(x: f64, y: f64, ww: f64, t: f64, wr: &mut [f64], wi: &mut [f64]) {
    let p = 0.5 * (y - x);
    let q = p * p + ww;
    let mut z = q.abs().sqrt();
    let x = x + t;
    if q >= 0.0 {
        z = p + z.copysign(p);
        wr[0] = x + z;
        wr[1] = x + z;
        if z != 0.0 {
            wr[1] = x - ww / z;
        }
        wi[0] = 0.0;
        wi[1] = 0.0;
    } else {
        wr[0] = x + p;
        wr[1] = x + p;
        wi[0] = -z;
        wi[1] = z;
    }
}

/// Forms the double shift from `x`, `y` and `wv` and looks, from `nu - 2` up to `l`, for two
/// consecutive small subdiagonal elements: the row `m` where the QR step starts and the first
/// column of the shifted matrix there (p, q, r, scaled), with the entries the step would leave
/// below the Hessenberg band zeroed.
fn shift_start(h: &mut Hess, nu: usize, l: usize, x: f64, y: f64, wv: f64) -> (usize, [f64; 3]) {
    let mut m = nu - 2;
    let (mut p, mut q, mut r);
    loop {
        let z = h.at(m, m);
        r = x - z;
        let s = y - z;
        p = (r * s - wv) / h.at(m + 1, m) + h.at(m, m + 1);
        q = h.at(m + 1, m + 1) - z - r - s;
        r = h.at(m + 2, m + 1);
        let s = p.abs() + q.abs() + r.abs();
        p /= s;
        q /= s;
        r /= s;
        if m == l {
            break;
        }
        let u = h.at(m, m - 1).abs() * (q.abs() + r.abs());
        let v = p.abs() * (h.at(m - 1, m - 1).abs() + z.abs() + h.at(m + 1, m + 1).abs());
        if u + v == v {
            break;
        }
        m -= 1;
    }
    for i in (m + 2)..=nu {
        *h.at_mut(i, i - 2) = 0.0;
        if i != m + 2 {
            *h.at_mut(i, i - 3) = 0.0;
        }
    }
    (m, [p, q, r])
}

/// One Francis double-shift QR step on rows `l..=nu` and columns `m..=nu`, starting from the
/// shifted first column `pqr` of `shift_start`: a Householder reflection per column chases the
/// bulge down the band.
fn double_qr_step(h: &mut Hess, nu: usize, l: usize, m: usize, pqr: [f64; 3]) {
    let [mut p, mut q, mut r] = pqr;
    // x carries over from one column's reflection to the next column's first entry.
    let mut x = 0.0;
    for k in m..nu {
        if k != m {
            p = h.at(k, k - 1);
            q = h.at(k + 1, k - 1);
            r = 0.0;
            if k != nu - 1 {
                r = h.at(k + 2, k - 1);
            }
            x = p.abs() + q.abs() + r.abs();
            if x != 0.0 {
                p /= x;
                q /= x;
                r /= x;
            }
        }
        let s = (p * p + q * q + r * r).sqrt().copysign(p);
        if s == 0.0 {
            continue;
        }
        if k == m {
            if l != m {
                *h.at_mut(k, k - 1) = -h.at(k, k - 1);
            }
        } else {
            *h.at_mut(k, k - 1) = -s * x;
        }
        p += s;
        x = p / s;
        let y = q / s;
        let z = r / s;
        q /= p;
        r /= p;
        for j in k..=nu {
            p = h.at(k, j) + q * h.at(k + 1, j);
            if k != nu - 1 {
                p += r * h.at(k + 2, j);
                *h.at_mut(k + 2, j) -= p * z;
            }
            *h.at_mut(k + 1, j) -= p * y;
            *h.at_mut(k, j) -= p * x;
        }
        let mmin = if nu < k + 3 { nu } else { k + 3 };
        for i in l..=mmin {
            p = x * h.at(i, k) + y * h.at(i, k + 1);
            if k != nu - 1 {
                p += z * h.at(i, k + 2);
                *h.at_mut(i, k + 2) -= p * r;
            }
            *h.at_mut(i, k + 1) -= p * q;
            *h.at_mut(i, k) -= p;
        }
    }
}
