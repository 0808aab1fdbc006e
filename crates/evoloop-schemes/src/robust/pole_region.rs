//! The wedge pole region of the two-mass paper (Fig. 2, Fig. 3): Re z <= -rho and
//! |Im z| <= tan(arccos zeta) (-Re z), apex at the origin. Poles inside give damping ratio
//! >= zeta and decay rate >= rho. F(X) of Section 3.3 is the sum of the poles' distances to it.

use nalgebra::Complex;
use serde::Serialize;

/// The wedge pole region: the poles it holds have a damping ratio of at least `zeta` and a
/// decay rate of at least `rho`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Wedge {
    /// Minimum damping ratio, in (0, 1).
    pub zeta: f64,
    /// Minimum decay rate (transient margin), > 0.
    pub rho: f64,
}

/// Why `Wedge::new` makes no wedge: the value refused. Its message begins with the parameter's
/// name (`zeta must ...`, `rho must ...`), which the command line's flags share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WedgeError {
    /// The damping ratio is not in (0, 1).
    Zeta(f64),
    /// The decay rate is not finite and above 0.
    Rho(f64),
}

impl std::fmt::Display for WedgeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            WedgeError::Zeta(z) => write!(f, "zeta must be in (0, 1) (got {z})"),
            WedgeError::Rho(r) => write!(f, "rho must be > 0 (got {r})"),
        }
    }
}

impl std::error::Error for WedgeError {}

impl Wedge {
    /// The wedge for `zeta` and `rho`; an error unless zeta is in (0, 1) and rho finite and > 0.
    pub fn new(zeta: f64, rho: f64) -> Result<Self, WedgeError> {
        if !(zeta > 0.0 && zeta < 1.0) {
            return Err(WedgeError::Zeta(zeta));
        }
        if !(rho > 0.0 && rho.is_finite()) {
            return Err(WedgeError::Rho(rho));
        }
        Ok(Self { zeta, rho })
    }

    /// Slope of the wedge's edges: tan(arccos zeta) = sqrt(1 - zeta^2) / zeta.
    pub fn slope(&self) -> f64 {
        (1.0 - self.zeta * self.zeta).sqrt() / self.zeta
    }

    /// Whether z lies in the region (damping ratio >= zeta, decay rate >= rho).
    pub fn contains(&self, z: Complex<f64>) -> bool {
        self.distance(z) == 0.0
    }

    /// Euclidean distance from z to the region (0 inside). The region is convex, bounded by the
    /// vertical segment Re z = -rho, |Im z| <= slope rho, and two rays from its ends along
    /// (-1, +-slope); outside, the distance is the smallest distance to these three pieces.
    pub fn distance(&self, z: Complex<f64>) -> f64 {
        let t = self.slope();
        let (x, y) = (z.re, z.im);
        if x <= -self.rho && y.abs() <= t * (-x) {
            return 0.0;
        }
        let y = y.abs(); // symmetric about the real axis
        let (x0, y0) = (-self.rho, t * self.rho);
        // Segment from (x0, -y0) to (x0, y0).
        let d_seg = ((x - x0).powi(2) + (y - y.clamp(-y0, y0)).powi(2)).sqrt();
        // Ray from (x0, y0) along (-1, t) / |.|.
        let n = (1.0 + t * t).sqrt();
        let (dx, dy) = (-1.0 / n, t / n);
        let s = ((x - x0) * dx + (y - y0) * dy).max(0.0);
        let d_ray = ((x - x0 - s * dx).powi(2) + (y - y0 - s * dy).powi(2)).sqrt();
        d_seg.min(d_ray)
    }

    /// F(X): the summed distance of all poles to the region.
    pub fn total_distance(&self, poles: &[Complex<f64>]) -> f64 {
        poles.iter().map(|p| self.distance(*p)).sum()
    }
}
