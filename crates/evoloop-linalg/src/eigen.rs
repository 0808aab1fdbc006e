//! Eigenvalues of a small real matrix without eigenvectors: Householder reduction to Hessenberg
//! form, then the Francis double-shift QR iteration (the classical `hqr` of EISPACK / Numerical
//! Recipes). It does only what the stability radius needs, several times faster than a full
//! Schur decomposition for the 5x5 closed loops and 10x10 Hamiltonians here; tests check it
//! against nalgebra's Schur-based eigenvalues.

use nalgebra::{Complex, DMatrix};

/// Eigenvalues of the square matrix `a` (any order). None if the QR iteration does not converge.
pub fn eigenvalues(a: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    let n = a.nrows();
    if n == 0 {
        return Some(Vec::new());
    }
    let h = a.clone().hessenberg().h();
    // 1-based working copy, as in the classical formulation.
    let mut m = vec![0.0; (n + 1) * (n + 1)];
    let w = n + 1;
    for i in 0..n {
        for j in 0..n {
            m[(i + 1) * w + j + 1] = h[(i, j)];
        }
    }
    let mut wr = vec![0.0; n + 1];
    let mut wi = vec![0.0; n + 1];
    hqr(&mut m, n, &mut wr, &mut wi)?;
    Some((1..=n).map(|i| Complex::new(wr[i], wi[i])).collect())
}

/// Eigenvalues by `eigenvalues`, falling back to nalgebra's Schur decomposition in the (rare)
/// case the QR iteration does not converge.
pub fn eig(a: &DMatrix<f64>) -> Vec<Complex<f64>> {
    eigenvalues(a).unwrap_or_else(|| a.complex_eigenvalues().iter().copied().collect())
}

#[allow(clippy::many_single_char_names)]
fn hqr(a: &mut [f64], n: usize, wr: &mut [f64], wi: &mut [f64]) -> Option<()> {
    let w = n + 1;
    let ix = |i: usize, j: usize| i * w + j;
    let mut anorm = 0.0;
    for i in 1..=n {
        for j in i.saturating_sub(1).max(1)..=n {
            anorm += a[ix(i, j)].abs();
        }
    }
    let mut nn = n as isize;
    let mut t = 0.0;
    let (mut p, mut q, mut r, mut s, mut x, mut y, mut z);
    while nn >= 1 {
        let mut its = 0;
        loop {
            let nu = nn as usize;
            // Look for a single small subdiagonal element.
            let mut l = nu;
            while l >= 2 {
                s = a[ix(l - 1, l - 1)].abs() + a[ix(l, l)].abs();
                if s == 0.0 {
                    s = anorm;
                }
                if a[ix(l, l - 1)].abs() + s == s {
                    a[ix(l, l - 1)] = 0.0;
                    break;
                }
                l -= 1;
            }
            x = a[ix(nu, nu)];
            if l == nu {
                // One root found.
                wr[nu] = x + t;
                wi[nu] = 0.0;
                nn -= 1;
                break;
            }
            y = a[ix(nu - 1, nu - 1)];
            let ww = a[ix(nu, nu - 1)] * a[ix(nu - 1, nu)];
            if l == nu - 1 {
                // Two roots found.
                p = 0.5 * (y - x);
                q = p * p + ww;
                z = q.abs().sqrt();
                x += t;
                if q >= 0.0 {
                    z = p + z.copysign(p);
                    wr[nu - 1] = x + z;
                    wr[nu] = x + z;
                    if z != 0.0 {
                        wr[nu] = x - ww / z;
                    }
                    wi[nu - 1] = 0.0;
                    wi[nu] = 0.0;
                } else {
                    wr[nu - 1] = x + p;
                    wr[nu] = x + p;
                    wi[nu - 1] = -z;
                    wi[nu] = z;
                }
                nn -= 2;
                break;
            }
            if its == 60 {
                return None;
            }
            let mut wv = ww;
            if its == 10 || its == 20 {
                // Exceptional shift.
                t += x;
                for i in 1..=nu {
                    a[ix(i, i)] -= x;
                }
                s = a[ix(nu, nu - 1)].abs() + a[ix(nu - 1, nu - 2)].abs();
                x = 0.75 * s;
                y = x;
                wv = -0.4375 * s * s;
            }
            its += 1;
            // Form the shift and look for two consecutive small subdiagonal elements.
            let mut m = nu - 2;
            loop {
                z = a[ix(m, m)];
                r = x - z;
                s = y - z;
                p = (r * s - wv) / a[ix(m + 1, m)] + a[ix(m, m + 1)];
                q = a[ix(m + 1, m + 1)] - z - r - s;
                r = a[ix(m + 2, m + 1)];
                s = p.abs() + q.abs() + r.abs();
                p /= s;
                q /= s;
                r /= s;
                if m == l {
                    break;
                }
                let u = a[ix(m, m - 1)].abs() * (q.abs() + r.abs());
                let v = p.abs() * (a[ix(m - 1, m - 1)].abs() + z.abs() + a[ix(m + 1, m + 1)].abs());
                if u + v == v {
                    break;
                }
                m -= 1;
            }
            for i in (m + 2)..=nu {
                a[ix(i, i - 2)] = 0.0;
                if i != m + 2 {
                    a[ix(i, i - 3)] = 0.0;
                }
            }
            // Double QR step on rows l..nn and columns m..nn.
            let mut k = m;
            while k < nu {
                if k != m {
                    p = a[ix(k, k - 1)];
                    q = a[ix(k + 1, k - 1)];
                    r = 0.0;
                    if k != nu - 1 {
                        r = a[ix(k + 2, k - 1)];
                    }
                    x = p.abs() + q.abs() + r.abs();
                    if x != 0.0 {
                        p /= x;
                        q /= x;
                        r /= x;
                    }
                }
                s = (p * p + q * q + r * r).sqrt().copysign(p);
                if s != 0.0 {
                    if k == m {
                        if l != m {
                            a[ix(k, k - 1)] = -a[ix(k, k - 1)];
                        }
                    } else {
                        a[ix(k, k - 1)] = -s * x;
                    }
                    p += s;
                    x = p / s;
                    y = q / s;
                    z = r / s;
                    q /= p;
                    r /= p;
                    for j in k..=nu {
                        p = a[ix(k, j)] + q * a[ix(k + 1, j)];
                        if k != nu - 1 {
                            p += r * a[ix(k + 2, j)];
                            a[ix(k + 2, j)] -= p * z;
                        }
                        a[ix(k + 1, j)] -= p * y;
                        a[ix(k, j)] -= p * x;
                    }
                    let mmin = if nu < k + 3 { nu } else { k + 3 };
                    for i in l..=mmin {
                        p = x * a[ix(i, k)] + y * a[ix(i, k + 1)];
                        if k != nu - 1 {
                            p += z * a[ix(i, k + 2)];
                            a[ix(i, k + 2)] -= p * r;
                        }
                        a[ix(i, k + 1)] -= p * q;
                        a[ix(i, k)] -= p;
                    }
                }
                k += 1;
            }
            if l >= nu - 1 {
                break;
            }
        }
    }
    Some(())
}
