//! The joint-space finite Fourier series of Swevers et al. (1997), the standard periodic
//! excitation trajectory:
//!
//!   q_j(t) = q0_j + sum_{l=1..N} a_jl / (w l) sin(w l t) - b_jl / (w l) cos(w l t),
//!
//! with w = 2 pi / T, so qd_j = sum a_jl cos(w l t) + b_jl sin(w l t) and
//! qdd_j = sum w l (b_jl cos(w l t) - a_jl sin(w l t)). Periodic by construction: repeating it
//! gives a continuous position, velocity and acceleration (the periodic boundary conditions of
//! the paper's eq. 24), so measurements can be averaged over periods and differentiated in the
//! frequency domain. A trajectory *starts at rest* when qd(0) = sum_l a_jl = 0 and
//! qdd(0) = w sum_l l b_jl = 0; `Design` keeps every candidate so by solving for the last
//! harmonic's coefficients, so the arm can be brought to q(0) and started without a jump.

use crate::reference::Reference;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// A finite Fourier series per joint (held joints have zero coefficients).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FourierSeries {
    /// T, s.
    pub period: f64,
    /// q0 per joint.
    pub offsets: Vec<f64>,
    /// a_jl and b_jl: one row per joint, one entry per harmonic.
    pub a: Vec<Vec<f64>>,
    /// b_jl: one row per joint, one entry per harmonic.
    pub b: Vec<Vec<f64>>,
}

impl FourierSeries {
    /// The number of joints.
    pub fn joints(&self) -> usize {
        self.offsets.len()
    }

    /// The number of harmonics N (0 for no joints).
    pub fn harmonics(&self) -> usize {
        self.a.first().map_or(0, |r| r.len())
    }

    /// The fundamental, rad/s.
    pub fn omega(&self) -> f64 {
        TAU / self.period
    }

    /// Joint `j`'s position, velocity and acceleration at time t.
    pub fn joint(&self, j: usize, t: f64) -> (f64, f64, f64) {
        let w = self.omega();
        let (mut q, mut qd, mut qdd) = (self.offsets[j], 0.0, 0.0);
        for l in 0..self.harmonics() {
            let wl = w * (l + 1) as f64;
            let (s, c) = (wl * t).sin_cos();
            let (a, b) = (self.a[j][l], self.b[j][l]);
            q += (a * s - b * c) / wl;
            qd += a * c + b * s;
            qdd += wl * (b * c - a * s);
        }
        (q, qd, qdd)
    }

    /// Every joint at time t into q, qd, qdd.
    pub fn sample(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        for j in 0..self.joints() {
            (q[j], qd[j], qdd[j]) = self.joint(j, t);
        }
    }

    /// The series of `harmonics` harmonics closest (least squares) to uniform samples of one
    /// period: `samples[j][k]` is joint j at time k T / m. A discrete Fourier transform; exact
    /// for band-limited signals with fewer than m / 2 harmonics.
    pub fn fit(period: f64, samples: &[Vec<f64>], harmonics: usize) -> FourierSeries {
        let w = TAU / period;
        let n = samples.len();
        let mut s = FourierSeries {
            period,
            offsets: vec![0.0; n],
            a: vec![vec![0.0; harmonics]; n],
            b: vec![vec![0.0; harmonics]; n],
        };
        for (j, x) in samples.iter().enumerate() {
            let m = x.len();
            s.offsets[j] = x.iter().sum::<f64>() / m as f64;
            for l in 1..=harmonics.min((m - 1) / 2) {
                // x ~ alpha cos(w l t) + beta sin(w l t).
                let (mut alpha, mut beta) = (0.0, 0.0);
                for (k, v) in x.iter().enumerate() {
                    let (sn, cs) = (TAU * (l * k % m) as f64 / m as f64).sin_cos();
                    alpha += v * cs;
                    beta += v * sn;
                }
                let (alpha, beta) = (2.0 * alpha / m as f64, 2.0 * beta / m as f64);
                // a / (w l) sin - b / (w l) cos = beta sin + alpha cos.
                let wl = w * l as f64;
                s.a[j][l - 1] = beta * wl;
                s.b[j][l - 1] = -alpha * wl;
            }
        }
        s
    }

    /// Whether joint `j` moves (any non-zero coefficient).
    pub fn moves(&self, j: usize) -> bool {
        self.a[j].iter().chain(&self.b[j]).any(|v| *v != 0.0)
    }

    /// The same trajectory as a `sines` reference (what a scenario runs):
    /// a / (w l) sin - b / (w l) cos = A sin(w l t + phi), A = hypot(a, b) / (w l),
    /// phi = atan2(-b, a); frequencies l / T in Hz.
    pub fn to_reference(&self) -> Reference {
        let w = self.omega();
        let h = self.harmonics();
        let amp = |j: usize, l: usize| self.a[j][l].hypot(self.b[j][l]) / (w * (l + 1) as f64);
        let phase = |j: usize, l: usize| (-self.b[j][l]).atan2(self.a[j][l]);
        Reference::Sines {
            offsets: self.offsets.clone(),
            amplitudes: (0..self.joints())
                .map(|j| (0..h).map(|l| amp(j, l)).collect())
                .collect(),
            frequencies: (1..=h).map(|l| l as f64 / self.period).collect(),
            phases: (0..self.joints())
                .map(|j| (0..h).map(|l| phase(j, l)).collect())
                .collect(),
        }
    }

    /// The series of a `sines` reference whose frequencies are the harmonics 1/T, 2/T, ... of
    /// one period (what `to_reference` writes); None for any other reference.
    pub fn from_reference(r: &Reference) -> Option<FourierSeries> {
        let Reference::Sines {
            offsets,
            amplitudes,
            frequencies,
            phases,
        } = r
        else {
            return None;
        };
        let f0 = *frequencies.first()?;
        if f0 <= 0.0
            || frequencies
                .iter()
                .enumerate()
                .any(|(l, f)| (f - f0 * (l + 1) as f64).abs() > 1e-9 * f0 * (l + 1) as f64)
        {
            return None;
        }
        let period = 1.0 / f0;
        let w = TAU * f0;
        let h = frequencies.len();
        let coef = |j: usize, l: usize| {
            let (amp, phi) = (amplitudes[j][l], phases[j][l]);
            let wl = w * (l + 1) as f64;
            // A sin(x + phi) = A cos(phi) sin x + A sin(phi) cos x = a/wl sin x - b/wl cos x.
            (amp * phi.cos() * wl, -amp * phi.sin() * wl)
        };
        let n = offsets.len();
        Some(FourierSeries {
            period,
            offsets: offsets.clone(),
            a: (0..n)
                .map(|j| (0..h).map(|l| coef(j, l).0).collect())
                .collect(),
            b: (0..n)
                .map(|j| (0..h).map(|l| coef(j, l).1).collect())
                .collect(),
        })
    }
}

/// How a decision vector (what the optimiser searches) becomes a series: per moving joint the
/// offset q0 and the free coefficients a_1..a_(N-1), b_1..b_(N-1); the last harmonic's a_N, b_N
/// are solved so that the trajectory starts (and, being periodic, ends) at rest.
#[derive(Debug, Clone, PartialEq)]
pub struct Design {
    /// The series' period T, s.
    pub period: f64,
    /// The number of harmonics N per joint (N >= 1): N - 1 free, the last solved for the start at
    /// rest.
    pub harmonics: usize,
    /// Per joint, whether it moves (gets decision variables) or is held.
    pub moving: Vec<bool>,
    /// Per joint, the position it is held at if it does not move (a moving joint's entry is
    /// unused).
    pub hold: Vec<f64>,
}

impl Design {
    /// Decision variables per moving joint.
    pub fn per_joint(&self) -> usize {
        1 + 2 * (self.harmonics - 1)
    }

    /// The length of the decision vector: `per_joint` for each moving joint.
    pub fn dim(&self) -> usize {
        self.moving.iter().filter(|m| **m).count() * self.per_joint()
    }

    /// The box: offsets within [q_lo, q_hi] per joint, coefficients within +-`coef`.
    pub fn bounds(&self, q_lo: &[f64], q_hi: &[f64], coef: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let (mut lo, mut hi) = (Vec::new(), Vec::new());
        for j in (0..self.moving.len()).filter(|&j| self.moving[j]) {
            lo.push(q_lo[j]);
            hi.push(q_hi[j]);
            for _ in 0..2 * (self.harmonics - 1) {
                lo.push(-coef[j]);
                hi.push(coef[j]);
            }
        }
        (lo, hi)
    }

    /// The series decision vector `x` describes (`dim` values): held joints at `hold` with zero
    /// coefficients, and each moving joint's last harmonic solved so that it starts at rest.
    pub fn decode(&self, x: &[f64]) -> FourierSeries {
        let n = self.moving.len();
        let h = self.harmonics;
        let mut s = FourierSeries {
            period: self.period,
            offsets: self.hold.clone(),
            a: vec![vec![0.0; h]; n],
            b: vec![vec![0.0; h]; n],
        };
        let mut k = 0;
        for j in (0..n).filter(|&j| self.moving[j]) {
            s.offsets[j] = x[k];
            k += 1;
            for l in 0..h - 1 {
                s.a[j][l] = x[k + l];
                s.b[j][l] = x[k + h - 1 + l];
            }
            k += 2 * (h - 1);
            // Rest at t = 0: sum_l a_l = 0 and sum_l l b_l = 0.
            s.a[j][h - 1] = -s.a[j][..h - 1].iter().sum::<f64>();
            s.b[j][h - 1] = -(0..h - 1).map(|l| (l + 1) as f64 * s.b[j][l]).sum::<f64>() / h as f64;
            // q0 is where the joint oscillates about; the trajectory starts at q(0).
        }
        s
    }

    /// The decision vector of a series (inverse of `decode` for series it produced).
    pub fn encode(&self, s: &FourierSeries) -> Vec<f64> {
        let h = self.harmonics;
        let mut x = Vec::with_capacity(self.dim());
        for j in (0..self.moving.len()).filter(|&j| self.moving[j]) {
            x.push(s.offsets[j]);
            x.extend_from_slice(&s.a[j][..h - 1]);
            x.extend_from_slice(&s.b[j][..h - 1]);
        }
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::Setpoint;

    fn design() -> Design {
        Design {
            period: 10.0,
            harmonics: 4,
            moving: vec![true, false, true],
            hold: vec![0.0, 0.3, 0.0],
        }
    }

    #[test]
    fn derivatives_match_finite_differences_and_the_start_is_at_rest() {
        let d = design();
        let x: Vec<f64> = (0..d.dim())
            .map(|i| ((i * 7 % 11) as f64 - 5.0) * 0.1)
            .collect();
        let s = d.decode(&x);
        for j in 0..3 {
            let (_, qd0, qdd0) = s.joint(j, 0.0);
            assert!(qd0.abs() < 1e-14 && qdd0.abs() < 1e-14, "joint {j} at rest");
            let (q_t, _, _) = s.joint(j, s.period);
            assert!((q_t - s.joint(j, 0.0).0).abs() < 1e-12, "periodic");
            for t in [0.7, 3.1, 8.9] {
                let h = 1e-5;
                let (qp, qdp, _) = s.joint(j, t + h);
                let (qm, qdm, _) = s.joint(j, t - h);
                let (_, qd, qdd) = s.joint(j, t);
                assert!((qd - (qp - qm) / (2.0 * h)).abs() < 1e-8);
                assert!((qdd - (qdp - qdm) / (2.0 * h)).abs() < 1e-8);
            }
        }
        assert_eq!(s.joint(1, 4.0), (0.3, 0.0, 0.0), "a held joint stays put");
        assert_eq!(d.encode(&s), x);
    }

    #[test]
    fn the_sines_reference_is_the_same_trajectory() {
        let d = design();
        let x: Vec<f64> = (0..d.dim()).map(|i| (i as f64 * 0.37).sin()).collect();
        let s = d.decode(&x);
        let r = s.to_reference();
        let back = FourierSeries::from_reference(&r).expect("harmonic frequencies");
        let mut sp = Setpoint::default();
        for t in [0.0, 1.3, 5.5, 9.99] {
            r.sample(t, &mut sp);
            for j in 0..3 {
                let (q, qd, qdd) = s.joint(j, t);
                assert!((sp.q[j] - q).abs() < 1e-12);
                assert!((sp.qd[j] - qd).abs() < 1e-12);
                assert!((sp.qdd[j] - qdd).abs() < 1e-12);
                let (q2, qd2, qdd2) = back.joint(j, t);
                assert!((q2 - q).abs() < 1e-12 && (qd2 - qd).abs() < 1e-12);
                assert!((qdd2 - qdd).abs() < 1e-12);
            }
        }
    }
}
