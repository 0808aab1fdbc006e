//! An identified RKGNN model as a file (`evoloop identify rkgnn --out MODEL.json`): the network's
//! shape and parameters, the reference it was identified on (the fuzzy selector's premise z_i,
//! eq. 17) and the identification's report. Loading checks everything a controller relies on.

use super::identify::Report;
use super::network::{Layout, Network, RbfCounts};
use crate::MAX_JOINTS;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The `format` value of a model file.
pub const FORMAT: &str = "evoloop-rkgnn";
/// The file layout version this build reads and writes.
pub const VERSION: u32 = 1;

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    pub format: String,
    pub version: u32,
    pub joints: usize,
    pub rbf: RbfCounts,
    /// N_f's parameters in `network::Layout` order.
    pub params: Vec<f64>,
    /// Spacing of `premise`, s.
    pub premise_period: f64,
    /// The identification reference, one row [theta_d; theta_d'] per `premise_period` from t = 0.
    pub premise: Vec<Vec<f64>>,
    /// Where the data came from (a run directory or a study).
    pub source: String,
    pub report: Report,
}

/// A loaded, checked model.
#[derive(Debug, Clone)]
pub struct RkgnnModel {
    pub net: Network,
    pub premise_period: f64,
    /// Premise rows, flat (2n each).
    pub premise: Vec<f64>,
    pub source: String,
    pub report: Report,
}

impl RkgnnModel {
    /// The model `net` identified on `data` at `stride`: its premise is the data's reference at
    /// the RKGNN's step.
    pub fn new(
        data: &super::Trajectory,
        stride: usize,
        net: Network,
        source: String,
        report: Report,
    ) -> Self {
        let d = data.every(stride.max(1));
        Self {
            net,
            premise_period: d.h,
            premise: d.r,
            source,
            report,
        }
    }

    pub fn dof(&self) -> usize {
        self.net.dof()
    }

    /// Premise samples.
    pub fn premise_len(&self) -> usize {
        self.premise.len() / (2 * self.dof())
    }

    /// z_i at time t (eq. 17): the identification reference at the nearest sample, held after
    /// its end.
    pub fn premise_at(&self, t: f64) -> &[f64] {
        let w = 2 * self.dof();
        let i = ((t / self.premise_period).round().max(0.0) as usize).min(self.premise_len() - 1);
        &self.premise[w * i..w * (i + 1)]
    }

    /// Smallest eigenvalue of M-hat over `qs`: > 0 means positive definite there.
    pub fn min_eig<'a>(&self, qs: impl Iterator<Item = &'a [f64]>) -> f64 {
        self.net.min_eig(qs)
    }

    pub fn to_file(&self) -> ModelFile {
        let w = 2 * self.dof();
        ModelFile {
            format: FORMAT.into(),
            version: VERSION,
            joints: self.dof(),
            rbf: self.net.layout.counts,
            params: self.net.params().to_vec(),
            premise_period: self.premise_period,
            premise: self.premise.chunks(w).map(<[f64]>::to_vec).collect(),
            source: self.source.clone(),
            report: self.report.clone(),
        }
    }

    pub fn save(&self, path: &Path) -> Result<(), String> {
        let s = serde_json::to_string_pretty(&self.to_file()).map_err(|e| e.to_string())?;
        crate::files::write(path, s + "\n").map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Read and check a model file: format and version, joint count, parameter count, finite
    /// values, premise rows of 2n values, M-hat positive definite on the premise positions.
    pub fn load(path: &Path) -> Result<RkgnnModel, String> {
        let at = |e: String| format!("{}: {e}", path.display());
        let text = std::fs::read_to_string(path).map_err(|e| at(e.to_string()))?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        let f: ModelFile = serde_path_to_error::deserialize(de)
            .map_err(|e| at(format!("{} ({})", e.inner(), e.path())))?;
        Self::from_file(f).map_err(at)
    }

    pub fn from_file(f: ModelFile) -> Result<RkgnnModel, String> {
        if f.format != FORMAT {
            return Err(format!("format is {:?}, expected {FORMAT:?}", f.format));
        }
        if f.version != VERSION {
            return Err(format!(
                "version {} (this build reads {VERSION})",
                f.version
            ));
        }
        let n = f.joints;
        if !(1..=MAX_JOINTS).contains(&n) {
            return Err(format!("joints: {n} (1..={MAX_JOINTS})"));
        }
        let layout = Layout::new(n, f.rbf);
        if f.params.len() != layout.len {
            return Err(format!(
                "params: {} values, the network needs {}",
                f.params.len(),
                layout.len
            ));
        }
        if let Some(i) = f.params.iter().position(|v| !v.is_finite()) {
            return Err(format!("params[{i}] is not finite"));
        }
        if !(f.premise_period > 0.0 && f.premise_period.is_finite()) {
            return Err("premise_period must be > 0".into());
        }
        if f.premise.is_empty() {
            return Err("premise is empty".into());
        }
        let mut premise = Vec::with_capacity(2 * n * f.premise.len());
        for (i, row) in f.premise.iter().enumerate() {
            if row.len() != 2 * n || row.iter().any(|v| !v.is_finite()) {
                return Err(format!("premise[{i}]: needs {} finite values", 2 * n));
            }
            premise.extend_from_slice(row);
        }
        let m = RkgnnModel {
            net: Network::new(layout, f.params),
            premise_period: f.premise_period,
            premise,
            source: f.source,
            report: f.report,
        };
        let w = 2 * n;
        let lo = m.min_eig(m.premise.chunks(w).map(|r| &r[..n]));
        if lo.is_nan() || lo <= 0.0 {
            return Err(format!(
                "M-hat is not positive definite on its own trajectory (smallest eigenvalue {lo:.3e})"
            ));
        }
        Ok(m)
    }
}
