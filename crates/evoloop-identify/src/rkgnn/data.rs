//! Identification data without torques: the servo's reference (theta_d, theta_d') and the arm's
//! output (theta measured by the encoders, theta' estimated from it), from a run's `run.csv` or
//! from an in-process simulation of the same loop. The torque columns `u*` are never read (the
//! RKGNN paper's premise is that the joint torques of an industrial arm are not available), nor
//! the simulator's noise-free velocities.

use super::RkgnnError;
use crate::report::Table;
use crate::sim::SimRow;
use evoloop_control::filter::smoothing::{half_window, smooth, smooth_where};
use std::path::Path;

/// Samples every `h` seconds: per sample the reference r = [theta_d; theta_d'] and the output
/// x = [theta; theta'] (2n values each, flat, sample-major), theta' estimated from theta.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// Number of joints n.
    pub n: usize,
    /// Sample interval, s.
    pub h: f64,
    /// The reference [theta_d; theta_d'] per sample, rad and rad/s.
    pub r: Vec<f64>,
    /// The output [theta; theta'] per sample, rad and rad/s.
    pub x: Vec<f64>,
    /// Half width of the low-pass the velocities were estimated with (`smooth`), s; the
    /// identification smooths the positions with the same window.
    pub smoothing: f64,
}

impl Trajectory {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.x.len() / (2 * self.n)
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// The reference [theta_d; theta_d'] of sample `i` (2n values).
    pub fn r_at(&self, i: usize) -> &[f64] {
        &self.r[2 * self.n * i..2 * self.n * (i + 1)]
    }

    /// The output [theta; theta'] of sample `i` (2n values).
    pub fn x_at(&self, i: usize) -> &[f64] {
        &self.x[2 * self.n * i..2 * self.n * (i + 1)]
    }

    /// The samples whose q'' `acceleration_at` can estimate (a neighbour on each side), every
    /// `stride`-th: the rows of the inverse-dynamics fits and of their comparisons.
    pub fn interior(&self, stride: usize) -> std::iter::StepBy<std::ops::Range<usize>> {
        (1..self.len().saturating_sub(1)).step_by(stride.max(1))
    }

    /// q'' at interior sample `i`: central differences of the estimated q'.
    pub fn acceleration_at(&self, i: usize) -> [f64; crate::msg::MAX_JOINTS] {
        let n = self.n;
        let mut a = [0.0; crate::msg::MAX_JOINTS];
        let (next, prev) = (&self.x_at(i + 1)[n..], &self.x_at(i - 1)[n..]);
        for (a, (v1, v0)) in a[..n].iter_mut().zip(next.iter().zip(prev)) {
            *a = (v1 - v0) / (2.0 * self.h);
        }
        a
    }

    /// Samples `from..to` as a trajectory of their own.
    pub fn window(&self, from: usize, to: usize) -> Trajectory {
        let w = 2 * self.n;
        Trajectory {
            n: self.n,
            h: self.h,
            r: self.r[w * from..w * to].to_vec(),
            x: self.x[w * from..w * to].to_vec(),
            smoothing: self.smoothing,
        }
    }

    /// Every `stride`-th sample (h grows by `stride`).
    pub fn every(&self, stride: usize) -> Trajectory {
        let w = 2 * self.n;
        let pick = |v: &[f64]| -> Vec<f64> {
            v.chunks(w)
                .step_by(stride)
                .flat_map(|c| c.iter().copied())
                .collect()
        };
        Trajectory {
            n: self.n,
            h: self.h * stride as f64,
            r: pick(&self.r),
            x: pick(&self.x),
            smoothing: self.smoothing,
        }
    }

    /// The trajectory as the equation-error fit sees it: the reference and the measured
    /// positions passed through one low-pass (`smooth` over `smoothing`), each velocity the
    /// derivative of the same fit, and only the samples whose window is centred (the first and
    /// last `smoothing` seconds dropped). Filtering every signal of a linear-in-parameters
    /// equation alike keeps the equation (M q'' + V + G = k_p e + k_d e' holds for the filtered
    /// signals where M varies slowly); the one-sided fits at the ends are another filter, and
    /// over the servo's start-up transient they broke it (M-hat several times M).
    pub fn filtered(&self) -> Trajectory {
        self.filtered_where(|_| true)
    }

    /// `filtered` where a fit at every `stride`-th sample reads it (`interior(stride)` of the
    /// result and each one's neighbours, whose velocities `acceleration_at` differences), NaN
    /// elsewhere: the same numbers there, a small share of the work at a fast control rate.
    pub fn filtered_for(&self, stride: usize) -> Trajectory {
        let rows = self.rows_read(stride, 1);
        self.filtered_where(rows)
    }

    fn filtered_where(&self, wanted: impl Fn(usize) -> bool + Copy) -> Trajectory {
        let (n, len) = (self.n, self.len());
        let mut out = self.clone();
        for (src, dst) in [(&self.r, &mut out.r), (&self.x, &mut out.x)] {
            for j in 0..n {
                let q = column(src, 2 * n, j);
                let value = smooth_where(&q, self.h, self.smoothing, 0, wanted);
                let rate = smooth_where(&q, self.h, self.smoothing, 1, wanted);
                for i in 0..len {
                    dst[2 * n * i + j] = value[i];
                    dst[2 * n * i + n + j] = rate[i];
                }
            }
        }
        let trim = self.trim();
        out.window(trim, len - trim)
    }

    /// Whether sample i of this trajectory is, once `filtered` trims it, within `reach` of a
    /// sample of `interior(stride)` (a row a fit at that stride reads).
    fn rows_read(&self, stride: usize, reach: usize) -> impl Fn(usize) -> bool + Copy {
        let (trim, stride) = (self.trim(), stride.max(1));
        let out_len = self.len().saturating_sub(2 * trim);
        move |i: usize| {
            let Some(o) = i.checked_sub(trim).filter(|&o| o < out_len) else {
                return false;
            };
            (o.saturating_sub(reach)..=o + reach)
                .any(|c| c >= 1 && c + 1 < out_len && (c - 1) % stride == 0)
        }
    }

    /// Samples `filtered` and `filter_alike` drop at each end: the low-pass's half window, where
    /// the fit is one-sided.
    pub fn trim(&self) -> usize {
        half_window(self.len(), self.h, self.smoothing)
    }

    /// `values` (n per sample of this trajectory, as a torque record) through the same low-pass
    /// as `filtered`, trimmed as it is.
    pub fn filter_alike(&self, values: &[f64]) -> Vec<f64> {
        self.filter_alike_where(values, |_| true)
    }

    /// `filter_alike` at the samples a fit at every `stride`-th sample reads
    /// (`interior(stride)` of the result), NaN elsewhere (`filtered_for`).
    pub fn filter_alike_for(&self, values: &[f64], stride: usize) -> Vec<f64> {
        self.filter_alike_where(values, self.rows_read(stride, 0))
    }

    fn filter_alike_where(
        &self,
        values: &[f64],
        wanted: impl Fn(usize) -> bool + Copy,
    ) -> Vec<f64> {
        let (n, len) = (self.n, self.len());
        assert_eq!(values.len(), n * len, "one value per joint and sample");
        let half = self.trim();
        let mut out = vec![0.0; values.len()];
        for j in 0..n {
            for (i, f) in smooth_where(&column(values, n, j), self.h, self.smoothing, 0, wanted)
                .into_iter()
                .enumerate()
            {
                out[n * i + j] = f;
            }
        }
        out[n * half..n * (len - half)].to_vec()
    }

    /// The reference and output of a run directory's `run.csv`: theta_d from `reference`, `r1`,
    /// ..., theta_d' from `rd*`, theta from the measured `y*`; theta' is estimated from `y*`
    /// (`from_positions`). The logged `qd*` (the simulator's noise-free velocities) and the
    /// torques `u*` are never read. `smoothing`: the low-pass's half width, s (`SMOOTHING`).
    pub fn from_run(dir: &Path, smoothing: f64) -> Result<Trajectory, RkgnnError> {
        let path = dir.join("run.csv");
        let t = Table::read(&path).map_err(|e| RkgnnError::RunFile {
            file: path.clone(),
            reason: String::new(),
            source: Some(e),
        })?;
        let col = |name: &str| -> Result<Vec<f64>, RkgnnError> {
            t.col(name).ok_or_else(|| {
                let reason = format!(
                    "no column `{name}` (identification needs the reference, its velocity \
                     and the measured joint positions an arm run logs: reference, r1.., rd*, y*)"
                );
                RkgnnError::run_file(&path, reason)
            })
        };
        let n = t.cols_with_prefix("rd").len();
        if n == 0 {
            return Err(RkgnnError::run_file(
                &path,
                "no reference velocity columns rd0.. (not an arm run, or written before they \
                 were logged)",
            ));
        }
        let time = col("t")?;
        if time.len() < 3 {
            return Err(RkgnnError::run_file(&path, "fewer than 3 samples"));
        }
        let h = time[1] - time[0];
        let mut cols = Vec::with_capacity(3 * n);
        for j in 0..n {
            cols.push(col(&if j == 0 {
                "reference".to_string()
            } else {
                format!("r{j}")
            })?);
        }
        for j in 0..n {
            cols.push(col(&format!("rd{j}"))?);
        }
        for j in 0..n {
            cols.push(col(&format!("y{j}"))?);
        }
        let rows = time.len();
        let mut r = Vec::with_capacity(2 * n * rows);
        let mut q = Vec::with_capacity(n * rows);
        let (rc, qc) = cols.split_at(2 * n);
        for i in 0..rows {
            r.extend(rc.iter().map(|c| c[i]));
            q.extend(qc.iter().map(|c| c[i]));
        }
        if r.iter().chain(&q).any(|v| !v.is_finite()) {
            return Err(RkgnnError::run_file(&path, "non-finite values"));
        }
        Ok(Trajectory::from_positions(n, h, r, &q, smoothing))
    }

    /// The same data from an in-process simulation's rows (what the controller logs), the
    /// reference sampled again at each row's time.
    pub fn from_sim(
        rows: &[SimRow],
        reference: &crate::reference::Reference,
        h: f64,
        smoothing: f64,
    ) -> Self {
        let n = reference.joints();
        let mut sp = crate::reference::Setpoint::default();
        let mut r = Vec::with_capacity(2 * n * rows.len());
        let mut q = Vec::with_capacity(n * rows.len());
        for row in rows {
            reference.sample(row.state.t, &mut sp);
            r.extend_from_slice(&sp.q[..n]);
            r.extend_from_slice(&sp.qd[..n]);
            q.extend_from_slice(&row.state.y[..n]);
        }
        Trajectory::from_positions(n, h, r, &q, smoothing)
    }

    /// Identification data from the reference `r` (2n per sample) and the measured joint
    /// positions `q` (n per sample, every `h` seconds): what an arm's encoders give. The joint
    /// velocities are estimated from the positions (`smooth`, one-sided at the ends): no
    /// tachometer, and never the simulator's noise-free velocity.
    pub fn from_positions(n: usize, h: f64, r: Vec<f64>, q: &[f64], smoothing: f64) -> Self {
        let len = q.len() / n.max(1);
        let mut x = vec![0.0; 2 * n * len];
        for j in 0..n {
            let joint = column(q, n, j);
            let v = smooth(&joint, h, smoothing, 1);
            for i in 0..len {
                x[2 * n * i + j] = joint[i];
                x[2 * n * i + n + j] = v[i];
            }
        }
        Trajectory {
            n,
            h,
            r,
            x,
            smoothing,
        }
    }
}

/// Column `j` of `v`, rows of `width` values each (one joint's samples of a sample-major record).
fn column(v: &[f64], width: usize, j: usize) -> Vec<f64> {
    v.iter().skip(j).step_by(width).copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use evoloop_rkgnn::SMOOTHING;

    /// The filter where a fit reads gives the whole filter's numbers bit for bit at every row
    /// the fit reads (each stride's row, its neighbours' velocities, the torques at the row),
    /// and NaN at the rest, so that a read of another row would show.
    #[test]
    fn filtering_where_a_fit_reads_gives_the_same_numbers_there() {
        let (n, h, len) = (2, 0.001, 700);
        let wave = |i: usize, j: usize| ((i * (j + 3)) as f64 * 0.013).sin() + 0.1 * j as f64;
        let r: Vec<f64> = (0..len)
            .flat_map(|i| (0..2 * n).map(move |j| wave(i, j)))
            .collect();
        let q: Vec<f64> = (0..len)
            .flat_map(|i| (0..n).map(move |j| wave(i, j + 7)))
            .collect();
        let tau: Vec<f64> = (0..len)
            .flat_map(|i| (0..n).map(move |j| wave(i, j + 2)))
            .collect();
        let d = Trajectory::from_positions(n, h, r, &q, 0.02);
        for stride in [1, 2, 7] {
            let (all, some) = (d.filtered(), d.filtered_for(stride));
            let (tau_all, tau_some) = (d.filter_alike(&tau), d.filter_alike_for(&tau, stride));
            assert_eq!(all.len(), some.len());
            let rows: Vec<usize> = all.interior(stride).collect();
            for &i in &rows {
                for k in [i - 1, i, i + 1] {
                    assert_eq!(
                        bits(all.x_at(k)),
                        bits(some.x_at(k)),
                        "stride {stride} row {k}"
                    );
                    assert_eq!(bits(all.r_at(k)), bits(some.r_at(k)));
                }
                assert_eq!(
                    bits(&tau_all[i * n..(i + 1) * n]),
                    bits(&tau_some[i * n..(i + 1) * n])
                );
            }
            if stride == 7 {
                assert!(some.x_at(rows[0] + 3).iter().all(|v| v.is_nan()));
                assert!(tau_some[(rows[0] + 1) * n].is_nan());
            }
        }
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    #[test]
    fn the_velocity_estimate_follows_a_sinusoid_and_cuts_encoder_noise() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        // 0.5 Hz, 0.8 rad at 1 kHz with encoder noise of 1e-4 rad: the velocity within the
        // window's bias (omega T)^2 / 10 of the truth plus the noise it leaves.
        let (h, w, a) = (1e-3, std::f64::consts::TAU * 0.5, 0.8);
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let noise = Normal::new(0.0, 1e-4).unwrap();
        let q: Vec<f64> = (0..4000)
            .map(|i| a * (w * i as f64 * h).sin() + noise.sample(&mut rng))
            .collect();
        let v = smooth(&q, h, SMOOTHING, 1);
        let bias = (w * SMOOTHING).powi(2) / 10.0 * a * w;
        for (i, v) in v.iter().enumerate().skip(200).take(3600) {
            let truth = a * w * (w * i as f64 * h).cos();
            assert!((v - truth).abs() < bias + 1e-3, "at {i}: {v} vs {truth}");
        }
        // Pure noise: the estimate's spread is the predicted 1e-4 / (h sqrt(sum k^2)).
        let pure: Vec<f64> = (0..4000).map(|_| noise.sample(&mut rng)).collect();
        let v = smooth(&pure, h, SMOOTHING, 1);
        let inner = &v[100..3900];
        let sd = (inner.iter().map(|x| x * x).sum::<f64>() / inner.len() as f64).sqrt();
        let m = (SMOOTHING / h).round();
        let want = 1e-4 / (h * (m * (m + 1.0) * (2.0 * m + 1.0) / 3.0).sqrt());
        assert!((sd / want - 1.0).abs() < 0.2, "sd {sd} vs {want}");
    }
}
