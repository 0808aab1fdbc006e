//! The paper's modified Fourier series (eqs. 16-18): a Cartesian path of the wrist centre,
//! turned into joint motion by inverse kinematics.
//!
//!   W_x(t) = d0 + sum_j [ a_j cos P(t) + F_j(t) ]
//!   W_y(t) = e0 + sum_j [ a_j sin P(t) + F_j(t) ]
//!   W_z(t) = f0 + sum_j F_j(t),      F_j(t) = b_j / (w j) sin(w j t) - c_j / (w j) cos(w j t),
//!
//! a circle of radius sum_j a_j about (d0, e0) swept once per period by P(t) from 0 to 2 pi,
//! disturbed by the finite Fourier series F on all three axes; N = 3 harmonics, w = 2 pi / T
//! (0.6283 rad/s for the paper's 10 s). Where the text is garbled or silent, our reading:
//! - P is "a cubic polynomial" from 0 to 2 pi; a cubic (and any polynomial blend) leaves some
//!   derivative discontinuous where one period meets the next, so the joint motion has slowly
//!   decaying harmonics. We take P(s) = 2 pi s - sin(2 pi s), s = t / T: from 0 to 2 pi with
//!   zero velocity and acceleration at both ends like the rest-to-rest blend, and cos P, sin P
//!   periodic and analytic, so the joint motion's harmonics decay exponentially.
//! - The tables print one c0, eq. 16 indexes it by harmonic: we take c_j per harmonic (Swevers'
//!   series, which the MFS builds on), and solve the last b_N and c_N so the path starts (and
//!   ends) at rest, eq. 24's boundary conditions.
//! - The wrist centre (where the last three joint axes meet) is placed by the joints before the
//!   wrist through Newton's method on the forward kinematics (warm-started along the path, so the
//!   joint motion is continuous and keeps the starting pose's branch); the paper's closed form
//!   for its own arm gives the same point.
//! - The wrist stage's own paths (eqs. 19-23) are not taken over: eq. 23 makes joint 6 turn a
//!   full revolution per period, which breaks both the periodic boundary conditions and joint
//!   6's +-242 degree limit. Moving wrist joints follow the joint-space series instead.
//!
//! The joint motion over one period (`SAMPLES` IK solutions) is then expanded in `HARMONICS`
//! Fourier harmonics (`FourierSeries::fit`): the same representation as the joint-space design,
//! so the limits, the regressor and the scenario reference work on it alike. The fit's largest
//! position error is reported.

use super::ExcitationError;
use crate::dynamics::Model;
use crate::reference::series::{Design, FourierSeries};
use glam::DVec3;
use nalgebra::{Matrix3, Vector3};
use std::f64::consts::TAU;

/// IK solutions per period.
pub const SAMPLES: usize = 512;
/// Harmonics of the joint series fitted to them.
pub const HARMONICS: usize = 48;

/// The Cartesian path's parameters (metres, metres per second).
#[derive(Debug, Clone, PartialEq)]
pub struct Mfs {
    /// Period T, s.
    pub period: f64,
    /// Per harmonic, a_j: their sum is the circle's radius, m.
    pub a: Vec<f64>,
    /// Per harmonic, b_j: the sine coefficient of the disturbance F_j, m/s.
    pub b: Vec<f64>,
    /// Per harmonic, c_j: the cosine coefficient of the disturbance F_j, m/s.
    pub c: Vec<f64>,
    /// The circle's centre (d0, e0, f0), m.
    pub centre: [f64; 3],
}

impl Mfs {
    /// The wrist centre at time t.
    pub fn point(&self, t: f64) -> [f64; 3] {
        let x = TAU * t / self.period;
        let p = x - x.sin();
        let w = TAU / self.period;
        let radius: f64 = self.a.iter().sum();
        let f: f64 = (0..self.b.len())
            .map(|j| {
                let wj = w * (j + 1) as f64;
                let (s, c) = (wj * t).sin_cos();
                (self.b[j] * s - self.c[j] * c) / wj
            })
            .sum();
        [
            self.centre[0] + radius * p.cos() + f,
            self.centre[1] + radius * p.sin() + f,
            self.centre[2] + f,
        ]
    }
}

/// Where the wrist centre is and how the arm joints place it.
#[derive(Debug, Clone)]
pub struct WristCentre {
    /// The body whose frame origin is the wrist centre.
    pub body: usize,
    /// The joints before the wrist (0..arm).
    pub arm: usize,
}

impl WristCentre {
    /// The wrist centre of an arm whose last three joint axes meet in a point: the origin of
    /// the fifth or sixth (of n) body's frame when none of the last three joints moves it (a
    /// body's origin lies on its own joint's axis, so it then lies on the wrist's axes).
    pub fn of(model: &Model) -> Result<WristCentre, ExcitationError> {
        let n = model.dof();
        if n < 4 {
            return Err(ExcitationError::Robot(format!(
                "the modified Fourier series moves a wrist centre: {} has {n} joints (use \
                 --trajectory fourier)",
                model.name
            )));
        }
        let mut d = model.data();
        let base: Vec<f64> = (0..n).map(|j| 0.3 + 0.1 * j as f64).collect();
        let origins = model.body_origins(&mut d, &base);
        for (body, origin) in origins.iter().enumerate().skip(n - 2) {
            let fixed = (0..5).all(|k| {
                let mut q = base.clone();
                for (j, v) in q.iter_mut().enumerate().skip(n - 3) {
                    *v += 0.7 * (k as f64 + 1.0) * (1.0 + j as f64).sin();
                }
                (model.body_origins(&mut d, &q)[body] - *origin).length() < 1e-9
            });
            if fixed {
                return Ok(WristCentre { body, arm: n - 3 });
            }
        }
        Err(ExcitationError::Robot(format!(
            "{}: the last three joint axes do not meet in a point (no spherical wrist), so the \
             modified Fourier series has no wrist centre to move (use --trajectory fourier)",
            model.name
        )))
    }

    /// Arm joints placing the wrist centre at `target`, from `q` (updated in place; the other
    /// joints stay). Newton's method with a finite-difference Jacobian; false if it does not
    /// converge to 1e-9 m (out of reach or singular).
    pub fn solve(&self, model: &Model, q: &mut [f64], target: [f64; 3]) -> bool {
        let mut d = model.data();
        let target = DVec3::from_array(target);
        let at = |d: &mut crate::dynamics::Data, q: &[f64]| model.body_origins(d, q)[self.body];
        for _ in 0..50 {
            let p = at(&mut d, q);
            let e = target - p;
            if e.length() < 1e-9 {
                return true;
            }
            let mut jac = Matrix3::zeros();
            let h = 1e-7;
            for k in 0..self.arm.min(3) {
                q[k] += h;
                let dp = (at(&mut d, q) - p) / h;
                q[k] -= h;
                jac.set_column(k, &Vector3::new(dp.x, dp.y, dp.z));
            }
            // Damped least squares: well behaved near singular poses.
            let lambda = 1e-6;
            let jt = jac.transpose();
            let Some(inv) = (jac * jt + Matrix3::identity() * lambda).try_inverse() else {
                return false;
            };
            let step = jt * inv * Vector3::new(e.x, e.y, e.z);
            let scale = (0.5 / step.norm()).min(1.0);
            for k in 0..self.arm.min(3) {
                q[k] += scale * step[k];
            }
        }
        (target - at(&mut d, q)).length() < 1e-9
    }
}

/// How a decision vector becomes a trajectory through the MFS: the path's a_1..a_N,
/// b_1..b_(N-1), c_1..c_(N-1), d0, e0, f0, then the wrist joints' joint-space series (when they
/// move).
#[derive(Debug, Clone)]
pub struct MfsDesign {
    /// Period T, s.
    pub period: f64,
    /// Harmonics N of the path (at least 2: b_N and c_N are solved to start at rest).
    pub harmonics: usize,
    /// The wrist centre and the arm joints that place it.
    pub wrist: WristCentre,
    /// Where the arm starts its search for the first point (and the held joints).
    pub hold: Vec<f64>,
    /// The wrist joints' series (its `moving` marks only wrist joints), if they move.
    pub joints: Option<Design>,
    /// The wrist centre at the hold pose: the middle of the centre's box.
    pub nominal: [f64; 3],
    /// Half-widths: of the centre's box, and of the a, b, c coefficients.
    pub centre_span: f64,
    /// Half-width of the a, b, c coefficients' box: 0.15 of the arm's size (the wrist
    /// centre's distance from the first joint's origin).
    pub coef_span: f64,
}

impl MfsDesign {
    /// The design for `model` about the hold pose `hold` (the boxes scaled by the arm's
    /// size). Fails with fewer than 2 harmonics or without a spherical wrist
    /// (`WristCentre::of`).
    pub fn new(
        model: &Model,
        period: f64,
        harmonics: usize,
        hold: Vec<f64>,
        joints: Option<Design>,
    ) -> Result<MfsDesign, ExcitationError> {
        if harmonics < 2 {
            return Err(ExcitationError::setting(
                "harmonics",
                "the modified Fourier series needs at least 2 harmonics",
            ));
        }
        let wrist = WristCentre::of(model)?;
        let mut d = model.data();
        let nominal = model.body_origins(&mut d, &hold)[wrist.body].to_array();
        // The arm's size: the wrist centre's distance from the first joint's origin.
        let first = model.body_origins(&mut d, &hold)[0];
        let size = (DVec3::from_array(nominal) - first).length().max(0.1);
        Ok(MfsDesign {
            period,
            harmonics,
            wrist,
            hold,
            joints,
            nominal,
            centre_span: 0.2 * size,
            coef_span: 0.15 * size,
        })
    }

    fn path_dim(&self) -> usize {
        self.harmonics + 2 * (self.harmonics - 1) + 3
    }

    /// Length of a decision vector: the path's 3N + 1 values, then the wrist series' (if any).
    pub fn dim(&self) -> usize {
        self.path_dim() + self.joints.as_ref().map_or(0, |d| d.dim())
    }

    /// The box: the path's coefficients within +-coef_span, the centre within centre_span of
    /// the nominal, then the wrist series' box.
    pub fn bounds(&self, joint_box: Option<(Vec<f64>, Vec<f64>)>) -> (Vec<f64>, Vec<f64>) {
        let coefs = self.harmonics + 2 * (self.harmonics - 1);
        let mut lo = vec![-self.coef_span; coefs];
        let mut hi = vec![self.coef_span; coefs];
        for c in self.nominal {
            lo.push(c - self.centre_span);
            hi.push(c + self.centre_span);
        }
        if let Some((l, h)) = joint_box {
            lo.extend(l);
            hi.extend(h);
        }
        (lo, hi)
    }

    /// The path of a decision vector (rest at the start: b_N and c_N solved).
    pub fn path(&self, x: &[f64]) -> Mfs {
        let h = self.harmonics;
        let a = x[..h].to_vec();
        let mut b = x[h..2 * h - 1].to_vec();
        let mut c = x[2 * h - 1..3 * h - 2].to_vec();
        b.push(-b.iter().sum::<f64>());
        c.push(-(0..h - 1).map(|j| (j + 1) as f64 * c[j]).sum::<f64>() / h as f64);
        let k = 3 * h - 2;
        Mfs {
            period: self.period,
            a,
            b,
            c,
            centre: [x[k], x[k + 1], x[k + 2]],
        }
    }

    /// The joint series of a decision vector and the fit's largest position error, or None
    /// when the path leaves the arm's reach.
    pub fn decode(&self, model: &Model, x: &[f64]) -> Option<(FourierSeries, f64)> {
        let n = model.dof();
        let path = self.path(x);
        let mut q = self.hold.clone();
        let mut samples = vec![vec![0.0; SAMPLES]; self.wrist.arm];
        // The start is found from the hold pose; each later point from the one before.
        for k in 0..SAMPLES {
            let t = self.period * k as f64 / SAMPLES as f64;
            if !self.wrist.solve(model, &mut q, path.point(t)) {
                return None;
            }
            for (j, s) in samples.iter_mut().enumerate() {
                s[k] = q[j];
            }
        }
        let arm = FourierSeries::fit(self.period, &samples, HARMONICS);
        let mut worst = 0.0f64;
        for (j, s) in samples.iter().enumerate() {
            for (k, v) in s.iter().enumerate() {
                let t = self.period * k as f64 / SAMPLES as f64;
                worst = worst.max((arm.joint(j, t).0 - v).abs());
            }
        }
        let wrist = self
            .joints
            .as_ref()
            .map(|d| d.decode(&x[self.path_dim()..]));
        let h = HARMONICS.max(wrist.as_ref().map_or(0, |w| w.harmonics()));
        let mut s = FourierSeries {
            period: self.period,
            offsets: self.hold.clone(),
            a: vec![vec![0.0; h]; n],
            b: vec![vec![0.0; h]; n],
        };
        for j in 0..n {
            let from = if j < self.wrist.arm {
                Some((&arm, j))
            } else {
                wrist.as_ref().filter(|w| w.moves(j)).map(|w| (w, j))
            };
            if let Some((src, i)) = from {
                s.offsets[j] = src.offsets[i];
                s.a[j][..src.harmonics()].copy_from_slice(&src.a[i]);
                s.b[j][..src.harmonics()].copy_from_slice(&src.b[i]);
            }
        }
        Some((s, worst))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn industrial6() -> Model {
        crate::dynamics::load(
            &std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../../config/robots/industrial6.toml"),
        )
        .unwrap()
    }

    #[test]
    fn the_path_starts_at_rest_and_is_periodic() {
        let model = industrial6();
        let d = MfsDesign::new(&model, 10.0, 3, vec![0.0; 6], None).unwrap();
        let x: Vec<f64> = (0..d.dim())
            .map(|i| {
                if i < 7 {
                    0.03 * (i as f64 + 1.0).sin()
                } else {
                    d.nominal[i - 7]
                }
            })
            .collect();
        let p = d.path(&x);
        let h = 1e-4;
        for axis in 0..3 {
            let f = |t: f64| p.point(t)[axis];
            let v0 = (f(h) - f(-h)) / (2.0 * h);
            let a0 = (f(h) - 2.0 * f(0.0) + f(-h)) / (h * h);
            assert!(
                v0.abs() < 1e-6 && a0.abs() < 1e-4,
                "axis {axis}: v {v0} a {a0}"
            );
            assert!((f(10.0) - f(0.0)).abs() < 1e-12, "periodic");
        }
    }

    #[test]
    fn the_joint_series_puts_the_wrist_centre_on_the_path() {
        let model = industrial6();
        let d = MfsDesign::new(&model, 10.0, 3, vec![0.0; 6], None).unwrap();
        assert_eq!(
            (d.wrist.arm, d.wrist.body),
            (3, 4),
            "industrial6's wrist centre"
        );
        let x: Vec<f64> = (0..d.dim())
            .map(|i| {
                if i < 7 {
                    0.04 * (i as f64 * 1.3).cos()
                } else {
                    d.nominal[i - 7]
                }
            })
            .collect();
        let (s, fit) = d.decode(&model, &x).expect("reachable");
        assert!(fit < 1e-6, "fit error {fit}");
        let path = d.path(&x);
        let mut data = model.data();
        let (mut q, mut qd, mut qdd) = (vec![0.0; 6], vec![0.0; 6], vec![0.0; 6]);
        for t in [0.0, 1.7, 4.4, 9.3] {
            s.sample(t, &mut q, &mut qd, &mut qdd);
            let p = model.body_origins(&mut data, &q)[d.wrist.body];
            let want = DVec3::from_array(path.point(t));
            assert!((p - want).length() < 1e-5, "t {t}: {p} vs {want}");
        }
    }
}
