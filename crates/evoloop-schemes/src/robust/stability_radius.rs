//! The complex stability radius (two-mass paper, eqs. 6-7):
//!   r_c(A, E, H) = 1 / sup_w sigma_max(H (jwI - A)^-1 E),
//! computed with the H-infinity norm algorithm of Boyd-Balakrishnan / Bruinsma-Steinbuch: gamma is
//! above the norm exactly when the Hamiltonian
//!   M(gamma) = [[A, E E' / gamma], [-H' H / gamma, -A']]
//! has no eigenvalue on the imaginary axis; its imaginary eigenvalues jw_i bracket the frequency
//! intervals where sigma_max(G(jw)) > gamma, whose midpoints give a better lower bound. The
//! iteration converges quadratically to a relative accuracy `tol`. r_c = 0 when A is not Hurwitz.

use crate::linalg::{eig, hamiltonian_eigenvalues};
use nalgebra::{Complex, DMatrix};
use std::fmt;

/// Why the H-infinity norm (and so r_c) could not be computed.
#[derive(Debug, Clone, PartialEq)]
pub enum HinfError {
    /// A, E and H do not fit together (their shapes).
    Dimensions(String),
    /// A has an eigenvalue with non-negative real part: the norm is infinite.
    NotStable,
    /// The level-set iteration did not settle within 50 steps.
    NoConvergence,
}

impl fmt::Display for HinfError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HinfError::Dimensions(s) => write!(f, "H-infinity norm: dimensions: {s}"),
            HinfError::NotStable => write!(f, "H-infinity norm: A is not Hurwitz"),
            HinfError::NoConvergence => {
                write!(f, "H-infinity norm: level-set iteration did not converge")
            }
        }
    }
}

impl std::error::Error for HinfError {}

/// Relative accuracy of the norm.
pub const HINF_TOL: f64 = 1e-9;

/// A transfer matrix G(s) = H (sI - A)^-1 E reduced to the nonzero columns of E and rows of H,
/// with the workspace its gain evaluations reuse (one H-infinity norm evaluates the gain some
/// 15 to 30 times: none allocates while G is at most 2 x 2; a larger G's singular values do).
pub struct Transfer {
    a: DMatrix<f64>,
    /// E and H as complex matrices, made once for the many gain evaluations.
    e_c: DMatrix<Complex<f64>>,
    h_c: DMatrix<Complex<f64>>,
    /// E E' and H' H, the Hamiltonian's off-diagonal blocks before their division by gamma.
    eet: DMatrix<f64>,
    hth: DMatrix<f64>,
    /// jwI - A and its LU factors, column-major (entry (i, j) at i + j n).
    lu: Vec<Complex<f64>>,
    /// The row swaps of the factorisation, in order: (step, pivot row).
    swaps: Vec<(usize, usize)>,
    /// The right-hand side E, then the solution X = (jwI - A)^-1 E, column-major.
    x: Vec<Complex<f64>>,
    /// G(jw) = H X, column-major.
    g: Vec<Complex<f64>>,
    /// A is upper Hessenberg (exact zeros below its subdiagonal): jwI - A is too, and its LU
    /// looks for each pivot, and eliminates, in the one row below the diagonal only.
    hessenberg: bool,
}

impl Transfer {
    /// G(s) = H (sI - A)^-1 E, the zero columns of E and rows of H dropped; an error when the
    /// shapes do not fit (A n x n, E n rows, H n columns).
    pub fn new(a: &DMatrix<f64>, e: &DMatrix<f64>, h: &DMatrix<f64>) -> Result<Self, HinfError> {
        let n = a.nrows();
        if a.ncols() != n || e.nrows() != n || h.ncols() != n {
            return Err(HinfError::Dimensions(format!(
                "A {:?}, E {:?}, H {:?}",
                a.shape(),
                e.shape(),
                h.shape()
            )));
        }
        let cols: Vec<usize> = (0..e.ncols())
            .filter(|&j| e.column(j).iter().any(|v| *v != 0.0))
            .collect();
        let rows: Vec<usize> = (0..h.nrows())
            .filter(|&i| h.row(i).iter().any(|v| *v != 0.0))
            .collect();
        let e = e.select_columns(&cols);
        let h = h.select_rows(&rows);
        let zero = Complex::new(0.0, 0.0);
        Ok(Self {
            a: a.clone(),
            e_c: e.map(|v| Complex::new(v, 0.0)),
            h_c: h.map(|v| Complex::new(v, 0.0)),
            eet: &e * e.transpose(),
            hth: h.transpose() * &h,
            lu: vec![zero; n * n],
            swaps: Vec::with_capacity(n),
            x: vec![zero; n * e.ncols()],
            g: vec![zero; h.nrows() * e.ncols()],
            hessenberg: (0..n).all(|j| (j + 2..n).all(|i| a[(i, j)] == 0.0)),
        })
    }

    /// sigma_max(G(jw)).
    pub fn gain(&mut self, w: f64) -> f64 {
        let (p, m) = (self.h_c.nrows(), self.e_c.ncols());
        if m == 0 || p == 0 {
            return 0.0;
        }
        if !self.solve(w) {
            return f64::INFINITY; // jw is a pole
        }
        let n = self.a.nrows();
        // G = H X, each entry summed over k in order.
        let h = self.h_c.as_slice(); // column-major: (i, k) at i + k p
        for (j, x) in self.x.chunks_exact(n).enumerate() {
            for i in 0..p {
                let mut sum = h[i] * x[0];
                for k in 1..n {
                    sum += h[i + k * p] * x[k];
                }
                self.g[i + j * p] = sum;
            }
        }
        if p <= 2 && m <= 2 {
            sigma_max_2x2(&self.g, p, m)
        } else {
            DMatrix::from_column_slice(p, m, &self.g)
                .singular_values()
                .max()
        }
    }

    /// X = (jwI - A)^-1 E into `self.x` by LU with partial pivoting (the largest |re| + |im| in
    /// the column, the first of equals); false when jwI - A is singular. The arithmetic is
    /// nalgebra's `LU::new` and `LU::solve` step for step, without the products by an exact
    /// one they make, so every nonzero value is theirs bit for bit (tested against them). For a
    /// Hessenberg A the rows below the subdiagonal, exact zeros in every column the LU reaches,
    /// are left out of the pivot search and of the products (which would add zeros to them).
    fn solve(&mut self, w: f64) -> bool {
        let n = self.a.nrows();
        // One past the last row that can be nonzero below the diagonal in column i.
        let band = |i: usize| if self.hessenberg { (i + 2).min(n) } else { n };
        let lu = &mut self.lu;
        for (k, (l, a)) in lu.iter_mut().zip(self.a.as_slice()).enumerate() {
            *l = Complex::new(-a, if k % (n + 1) == 0 { w } else { 0.0 });
        }
        self.swaps.clear();
        for i in 0..n {
            let mut piv = i;
            for k in i + 1..band(i) {
                if lu[k + i * n].l1_norm() > lu[piv + i * n].l1_norm() {
                    piv = k;
                }
            }
            let diag = lu[piv + i * n];
            if diag.re == 0.0 && diag.im == 0.0 {
                continue;
            }
            if piv != i {
                self.swaps.push((i, piv));
                for j in 0..=i {
                    lu.swap(i + j * n, piv + j * n);
                }
            }
            let inv_diag = Complex::new(1.0, 0.0) / diag;
            for r in i + 1..band(i) {
                lu[r + i * n] *= inv_diag;
            }
            for j in i + 1..n {
                if piv != i {
                    lu.swap(i + j * n, piv + j * n);
                }
                let a = -lu[i + j * n];
                for r in i + 1..band(i) {
                    let l = lu[r + i * n];
                    lu[r + j * n] += a * l;
                }
            }
        }
        for (x, e) in self
            .x
            .chunks_exact_mut(n)
            .zip(self.e_c.as_slice().chunks_exact(n))
        {
            x.copy_from_slice(e);
            for &(i, piv) in &self.swaps {
                x.swap(i, piv);
            }
            // L y = P b, L with a unit diagonal.
            for i in 0..n.saturating_sub(1) {
                let a = -x[i];
                // Not the band: the row swaps after step i move its multiplier further down.
                for r in i + 1..n {
                    x[r] += a * lu[r + i * n];
                }
            }
            // U x = y.
            for i in (0..n).rev() {
                let diag = lu[i + i * n];
                if diag.re == 0.0 && diag.im == 0.0 {
                    return false;
                }
                let c = x[i] / diag;
                x[i] = c;
                for r in 0..i {
                    x[r] += -c * lu[r + i * n];
                }
            }
        }
        true
    }

    fn hamiltonian(&self, gamma: f64) -> DMatrix<f64> {
        let n = self.a.nrows();
        let mut m = DMatrix::zeros(2 * n, 2 * n);
        m.view_mut((0, 0), (n, n)).copy_from(&self.a);
        m.view_mut((0, n), (n, n)).copy_from(&(&self.eet / gamma));
        m.view_mut((n, 0), (n, n)).copy_from(&(-&self.hth / gamma));
        m.view_mut((n, n), (n, n)).copy_from(&(-self.a.transpose()));
        m
    }

    /// Frequencies w >= 0 where jw is an eigenvalue of M(gamma), sorted: from one of each pair
    /// +-lambda by the square-reduced method (a pair off the axis by rounding, a tangency, is
    /// taken as on it), or from all 2n eigenvalues should its QR iteration fail. The method's
    /// error grows as |lambda| shrinks, so a crossing within about sqrt(eps) |M| of w = 0 may be
    /// missed or invented: harmless, as the gain at w = 0 is always evaluated and a crossing only
    /// adds gain evaluations.
    fn crossings(&self, gamma: f64) -> Vec<f64> {
        let m = self.hamiltonian(gamma);
        let on_axis = |z: &Complex<f64>| z.re.abs() <= 1e-7 * z.norm().max(1.0);
        let mut w: Vec<f64> = match hamiltonian_eigenvalues(&m) {
            Some(half) => half
                .iter()
                .filter(|z| on_axis(z))
                .map(|z| z.im.abs())
                .collect(),
            None => eig(&m)
                .iter()
                .filter(|z| on_axis(z) && z.im >= 0.0)
                .map(|z| z.im)
                .collect(),
        };
        w.sort_by(|a, b| a.total_cmp(b));
        w
    }
}

/// Largest singular value of a complex matrix of at most 2 x 2, in closed form:
/// sigma_max^2 = (|G|_F^2 + sqrt(|G|_F^4 - 4 |det G|^2)) / 2 (for 1 x n or n x 1 it is |G|_F).
/// `g` is p x m, column-major.
fn sigma_max_2x2(g: &[Complex<f64>], p: usize, m: usize) -> f64 {
    let fro2: f64 = g.iter().map(|z| z.norm_sqr()).sum();
    if p < 2 || m < 2 {
        return fro2.sqrt();
    }
    let det = g[0] * g[3] - g[2] * g[1];
    let disc = (fro2 * fro2 - 4.0 * det.norm_sqr()).max(0.0);
    (0.5 * (fro2 + disc.sqrt())).sqrt()
}

/// What a bounded norm computation found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bounded {
    /// The norm and a frequency where it is attained.
    Exact(f64, f64),
    /// The norm is proven above the level: this is a lower bound on it that exceeds the level.
    Above(f64),
}

/// The H-infinity norm of G(s) = H (sI - A)^-1 E for Hurwitz A, and a frequency where it is
/// attained.
pub fn hinf_norm(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    h: &DMatrix<f64>,
) -> Result<(f64, f64), HinfError> {
    match hinf_norm_bounded(a, e, h, f64::INFINITY)? {
        Bounded::Exact(n, w) => Ok((n, w)),
        Bounded::Above(lb) => Ok((lb, f64::NAN)), // unreachable: no bound exceeds infinity
    }
}

/// As `hinf_norm`, but stops as soon as a lower bound exceeds `level` (the caller only needs to
/// know the norm is above it): most candidates an optimiser rejects are settled this way without
/// a single Hamiltonian eigenvalue problem.
pub fn hinf_norm_bounded(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    h: &DMatrix<f64>,
    level: f64,
) -> Result<Bounded, HinfError> {
    hinf_from_poles(a, e, h, &eig(a), level)
}

/// The bounded norm when the caller already has A's eigenvalues `poles`; `NotStable` unless
/// they all lie in the open left half-plane.
pub fn hinf_from_poles(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    h: &DMatrix<f64>,
    poles: &[Complex<f64>],
    level: f64,
) -> Result<Bounded, HinfError> {
    if poles.iter().any(|p| p.re >= 0.0) {
        return Err(HinfError::NotStable);
    }
    let mut g = Transfer::new(a, e, h)?;
    // Lower bound from the frequencies where a peak is likely: DC and each pole's natural and
    // damped frequency.
    // Each gain above `level` settles a bounded call at once (its caller needs no more).
    let mut best = (0.0, 0.0);
    let ws: Vec<f64> = std::iter::once(0.0)
        .chain(poles.iter().flat_map(|p| [p.norm(), p.im.abs()]))
        .collect();
    for (i, &w) in ws.iter().enumerate() {
        // A frequency seen before (a conjugate pole's, a real pole's zero imaginary part) gives
        // the same gain again: it cannot raise the bound.
        if ws[..i].contains(&w) {
            continue;
        }
        let v = g.gain(w);
        if v > level {
            return Ok(Bounded::Above(v));
        }
        if v > best.0 {
            best = (v, w);
        }
    }
    if best.0 == 0.0 {
        return Ok(Bounded::Exact(0.0, 0.0));
    }
    // Polish the lower bound on the peak it sits on (a few gain evaluations cost less than one
    // Hamiltonian eigenvalue problem), so the level-set check usually certifies it at once.
    if best.1 > 0.0 {
        best = refine_peak(&mut g, best, level);
        if best.0 > level {
            return Ok(Bounded::Above(best.0));
        }
    }
    for _ in 0..50 {
        let gamma = (1.0 + 2.0 * HINF_TOL) * best.0;
        let w = g.crossings(gamma);
        if w.is_empty() {
            return Ok(Bounded::Exact(best.0, best.1));
        }
        // Midpoints of consecutive crossings (or the crossing itself when it is a tangent).
        let candidates: Vec<f64> = if w.len() == 1 {
            w.clone()
        } else {
            w.windows(2).map(|p| 0.5 * (p[0] + p[1])).collect()
        };
        let mut improved = false;
        for c in candidates {
            let v = g.gain(c);
            if v > best.0 {
                best = (v, c);
                improved = true;
            }
        }
        if !improved {
            // The crossings are numerical noise around the peak: the bound is already tight.
            return Ok(Bounded::Exact(best.0, best.1));
        }
        if best.0 > level {
            return Ok(Bounded::Above(best.0));
        }
    }
    Err(HinfError::NoConvergence)
}

/// Successive parabolic interpolation on sigma_max(G(jw)) around a local peak estimate
/// (gain, w); returns the best point seen, as soon as it is above `level`. Only ever raises the
/// lower bound.
fn refine_peak(g: &mut Transfer, start: (f64, f64), level: f64) -> (f64, f64) {
    let mut best = start;
    let mut d = 0.02 * start.1;
    for _ in 0..6 {
        let w0 = best.1;
        let (a, c) = (w0 - d, w0 + d);
        let (ga, gc) = (g.gain(a.max(0.0)), g.gain(c));
        let denom = ga - 2.0 * best.0 + gc;
        // The peak is bracketed and the parabola's vertex would raise the bound by less than a
        // hundredth of the norm's tolerance: the level-set check will certify the bound as it is
        // (at a tenth, the parabola's error let one loop in 300 end 1.7e-9 below the peak).
        if denom < 0.0
            && ga <= best.0
            && gc <= best.0
            && (gc - ga).powi(2) / (-8.0 * denom) < 0.01 * HINF_TOL * best.0
        {
            break;
        }
        // Vertex of the parabola through the three points (concave: denom < 0).
        let w_new = if denom < 0.0 {
            (w0 - 0.5 * d * (gc - ga) / denom).clamp(a.max(0.0), c)
        } else if ga > gc {
            a.max(0.0)
        } else {
            c
        };
        for (v, w) in [(ga, a.max(0.0)), (gc, c), (g.gain(w_new), w_new)] {
            if v > best.0 {
                best = (v, w);
            }
        }
        if best.0 > level {
            break;
        }
        let moved = (best.1 - w0).abs();
        d = (moved * 0.5).max(d * 0.05);
        if d < 1e-9 * best.1.max(1e-12) {
            break;
        }
    }
    best
}

/// Complex stability radius of the closed loop A under perturbations E Delta H; 0 if A is not
/// Hurwitz (by definition), an error if the norm cannot be computed (never a silent 0).
pub fn stability_radius(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    h: &DMatrix<f64>,
) -> Result<f64, HinfError> {
    radius_from_poles(a, e, h, &eig(a))
}

/// As `stability_radius`, for a caller that already has A's eigenvalues.
pub fn radius_from_poles(
    a: &DMatrix<f64>,
    e: &DMatrix<f64>,
    h: &DMatrix<f64>,
    poles: &[Complex<f64>],
) -> Result<f64, HinfError> {
    match hinf_from_poles(a, e, h, poles, f64::INFINITY) {
        Ok(Bounded::Exact(n, _)) if n > 0.0 => Ok(1.0 / n),
        Ok(Bounded::Exact(..)) => Ok(f64::INFINITY),
        Ok(Bounded::Above(lb)) => Ok(1.0 / lb), // unreachable: no bound exceeds infinity
        Err(HinfError::NotStable) => Ok(0.0),
        Err(e) => Err(e),
    }
}

/// The norm by a dense frequency sweep refined by golden-section search: an independent
/// reference for tests and for `--check`.
pub fn hinf_norm_sweep(a: &DMatrix<f64>, e: &DMatrix<f64>, h: &DMatrix<f64>, points: usize) -> f64 {
    let mut g = match Transfer::new(a, e, h) {
        Ok(g) => g,
        Err(_) => return f64::NAN,
    };
    let (lo, hi) = (-4.0f64, 4.0f64);
    let ws: Vec<f64> = std::iter::once(0.0)
        .chain((0..points).map(|i| 10f64.powf(lo + (hi - lo) * i as f64 / (points - 1) as f64)))
        .collect();
    let vals: Vec<f64> = ws.iter().map(|w| g.gain(*w)).collect();
    let mut best = vals.iter().copied().fold(0.0, f64::max);
    // Refine every local maximum of the grid.
    for i in 1..ws.len() - 1 {
        if vals[i] >= vals[i - 1] && vals[i] >= vals[i + 1] {
            let (mut x0, mut x1) = (ws[i - 1], ws[i + 1]);
            let phi = 0.5 * (5f64.sqrt() - 1.0);
            for _ in 0..100 {
                let a1 = x1 - phi * (x1 - x0);
                let b1 = x0 + phi * (x1 - x0);
                if g.gain(a1) > g.gain(b1) {
                    x1 = b1;
                } else {
                    x0 = a1;
                }
            }
            best = best.max(g.gain(0.5 * (x0 + x1)));
        }
    }
    best
}
