//! Identification data without torques: the servo's reference (theta_d, theta_d') and the arm's
//! output (theta, theta'), from a run's `run.csv` or from an in-process simulation of the same
//! loop. The torque columns `u*` are never read: the RKGNN paper's premise is that the joint
//! torques of an industrial arm are not available.

use crate::report::Table;
use crate::sim::SimRow;
use std::path::Path;

/// Samples every `h` seconds: per sample the reference r = [theta_d; theta_d'] and the output
/// x = [theta; theta'] (2n values each, flat, sample-major).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub n: usize,
    pub h: f64,
    pub r: Vec<f64>,
    pub x: Vec<f64>,
}

impl Trajectory {
    pub fn len(&self) -> usize {
        self.x.len() / (2 * self.n)
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    pub fn r_at(&self, i: usize) -> &[f64] {
        &self.r[2 * self.n * i..2 * self.n * (i + 1)]
    }

    pub fn x_at(&self, i: usize) -> &[f64] {
        &self.x[2 * self.n * i..2 * self.n * (i + 1)]
    }

    /// Samples `from..to` as a trajectory of their own.
    pub fn window(&self, from: usize, to: usize) -> Trajectory {
        let w = 2 * self.n;
        Trajectory {
            n: self.n,
            h: self.h,
            r: self.r[w * from..w * to].to_vec(),
            x: self.x[w * from..w * to].to_vec(),
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
        }
    }

    /// The reference and output of a run directory's `run.csv`: theta_d from `reference`, `r1`,
    /// ..., theta_d' from `rd*`, theta from the measured `y*`, theta' from `qd*`.
    pub fn from_run(dir: &Path) -> Result<Trajectory, String> {
        let path = dir.join("run.csv");
        let t = Table::read(&path).map_err(|e| format!("{}: {e}", path.display()))?;
        let col = |name: &str| -> Result<Vec<f64>, String> {
            t.col(name).ok_or_else(|| {
                format!(
                    "{}: no column `{name}` (identification needs the reference and joint \
                     velocities an arm run logs: reference, r1.., rd*, y*, qd*)",
                    path.display()
                )
            })
        };
        let n = t.cols_with_prefix("qd").len();
        if n == 0 {
            return Err(format!(
                "{}: no joint velocity columns qd0.. (not an arm run, or written before they \
                 were logged)",
                path.display()
            ));
        }
        let time = col("t")?;
        if time.len() < 3 {
            return Err(format!("{}: fewer than 3 samples", path.display()));
        }
        let h = time[1] - time[0];
        let mut cols = Vec::with_capacity(4 * n);
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
        for j in 0..n {
            cols.push(col(&format!("qd{j}"))?);
        }
        let rows = time.len();
        let mut r = Vec::with_capacity(2 * n * rows);
        let mut x = Vec::with_capacity(2 * n * rows);
        let (rc, xc) = cols.split_at(2 * n);
        for i in 0..rows {
            r.extend(rc.iter().map(|c| c[i]));
            x.extend(xc.iter().map(|c| c[i]));
        }
        if r.iter().chain(&x).any(|v| !v.is_finite()) {
            return Err(format!("{}: non-finite values", path.display()));
        }
        Ok(Trajectory { n, h, r, x })
    }

    /// The same data from an in-process simulation's rows (what the controller logs), the
    /// reference sampled again at each row's time.
    pub fn from_sim(rows: &[SimRow], reference: &crate::reference::Reference, h: f64) -> Self {
        let n = reference.joints();
        let mut sp = crate::reference::Setpoint::default();
        let mut r = Vec::with_capacity(2 * n * rows.len());
        let mut x = Vec::with_capacity(2 * n * rows.len());
        for row in rows {
            reference.sample(row.state.t, &mut sp);
            r.extend_from_slice(&sp.q[..n]);
            r.extend_from_slice(&sp.qd[..n]);
            x.extend_from_slice(&row.state.y[..n]);
            x.extend_from_slice(&row.state.qd_true[..n]);
        }
        Trajectory { n, h, r, x }
    }
}
