//! `[optimiser.model]`: what the general indirect scheme (`indirect::linear`) knows of a linear
//! single-input plant before it has data: the structure and nominal coefficients of its transfer
//! function, and the estimator's filter and memory. For an `lti` plant the nominal model is the
//! configured one (its changes in operation are the plant's secret); a plant of the user's own
//! (`external`) must name it, as a datasheet or an earlier identification gives it.

use crate::check::{Check, ConfigError};
use crate::law::{ControllerModel, ControllerSpec};
use crate::plant::PlantModel;
use serde::{Deserialize, Serialize};

/// The most poles the estimator fits: its state-variable filter gives four derivatives.
pub const MAX_POLES: usize = 4;

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawModel {
    num: Option<Vec<f64>>,
    den: Option<Vec<f64>>,
    filter_pole: Option<f64>,
    memory: Option<f64>,
}

/// The validated prior: num and den in descending powers, den monic, num padded to den's
/// length (strictly proper: `num[0] = 0`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelPrior {
    /// Nominal numerator of the continuous-time transfer function, descending powers of s,
    /// padded to `den`'s length (from `optimiser.model.num`, or the `lti` plant's own).
    pub num: Vec<f64>,
    /// Nominal denominator of the continuous-time transfer function, descending powers of s,
    /// monic: 1 to `MAX_POLES` poles.
    pub den: Vec<f64>,
    /// Numerator degree: the estimator fits b_0 .. b_zeros.
    pub zeros: usize,
    /// The state-variable filter's pole (rad/s).
    pub filter_pole: f64,
    /// Time constant (s) over which the estimator forgets old data.
    pub memory: f64,
}

impl ModelPrior {
    /// Poles (the denominator's degree).
    pub fn poles(&self) -> usize {
        self.den.len() - 1
    }
}

/// Who reads the prior.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Use {
    /// Nobody (the table is kept but unused).
    None,
    /// The general indirect scheme: its estimator's structure and start.
    Indirect,
    /// The direct scheme's `safe_bayes_model`: the nominal model its trials are predicted on.
    DirectModel,
}

impl Use {
    pub fn of(o: &super::OptimiserSpec) -> Self {
        match o.mode {
            super::OptimiserMode::Indirect => Use::Indirect,
            // A nominal plant of its own, or else a transfer function.
            super::OptimiserMode::Direct
                if o.algorithm == super::SAFE_BAYES_MODEL && o.nominal_plant.is_none() =>
            {
                Use::DirectModel
            }
            _ => Use::None,
        }
    }
}

/// The prior for an indirect run (or a direct run of `safe_bayes_model`) on an `lti` or
/// `external` plant under a PID; None for every other run (the maglev's and the two-mass's
/// schemes know their plants), where the table must not appear.
pub fn validate(
    raw: Option<RawModel>,
    check: &Check,
    plant: &PlantModel,
    controller: &ControllerSpec,
    reader: Use,
    period: f64,
) -> Result<Option<ModelPrior>, ConfigError> {
    let linear = matches!(plant, PlantModel::Lti(_) | PlantModel::External(_));
    if reader == Use::DirectModel && !linear {
        return check.fail(
            "optimiser.nominal_plant",
            "missing: safe_bayes_model predicts its trials on the nominal model you give, here \
             a plant table ([optimiser.model]'s transfer function is for lti and external \
             plants)",
        );
    }
    if !(linear && reader != Use::None) {
        // Kept but unused in another mode (a frozen comparison run with `--optimiser off`).
        return match raw {
            Some(_) if !linear => check.fail(
                "optimiser.model",
                "is the general indirect scheme's (optimiser.mode = \"indirect\" on an lti or \
                 external plant)",
            ),
            _ => Ok(None),
        };
    }
    if !matches!(controller.model, ControllerModel::Pid(_)) {
        return check.fail(
            "controller.kind",
            "the indirect scheme and safe_bayes_model on an lti or external plant tune a PID \
             (state feedback there would need the plant's state coordinates, which input-output \
             data do not give)",
        );
    }
    if reader == Use::DirectModel && raw.as_ref().is_none_or(|r| r.num.is_none()) {
        // Not the simulated plant's own model by default: that is the truth, which a tuner
        // must not be fed.
        return check.fail(
            "optimiser.model.num",
            "missing: safe_bayes_model predicts its trials on the nominal model you give (num \
             and den, descending powers, or a plant table [optimiser.nominal_plant]: a \
             datasheet's, a CAD model's or an earlier identification's)",
        );
    }
    let raw = raw.unwrap_or_default();
    if let (PlantModel::Lti(spec), Use::Indirect) = (plant, reader) {
        if spec.delay > 0 || spec.dt.is_some() {
            return check.fail(
                "optimiser.mode",
                "the indirect scheme estimates a continuous model without delay: the plant's \
                 model is discrete or delayed",
            );
        }
    }
    let (num, den) = match (raw.num, raw.den, plant) {
        (Some(num), Some(den), _) => (num, den),
        (None, None, PlantModel::Lti(spec)) => {
            spec.transfer_function().ok_or_else(|| ConfigError {
                file: check.file.clone(),
                key: "optimiser.mode".into(),
                reason: "the indirect scheme takes a plant with one input and one output".into(),
                line: None,
            })?
        }
        (None, None, _) => {
            return check.fail(
                "optimiser.model.num",
                "missing: a plant of your own needs its nominal transfer function (num and den, \
                 descending powers) for the indirect scheme to start from",
            )
        }
        (num, _, _) => {
            let key = if num.is_none() { "num" } else { "den" };
            return check.fail(
                &format!("optimiser.model.{key}"),
                "give num and den together",
            );
        }
    };
    let (num, den, zeros) = normalised(check, num, den)?;
    let fastest = largest_root(&den);
    let filter_pole = match raw.filter_pole {
        Some(a) => check.range("optimiser.model.filter_pole", a, 1e-3, 0.5 / period)?,
        // A few times the fastest mode, so the filtered signals keep the dynamics, and well
        // below the sampling rate, where the noise would dominate.
        None => (3.0 * fastest).max(5.0).min(0.1 / period),
    };
    let memory = check.range(
        "optimiser.model.memory",
        raw.memory.unwrap_or(5.0),
        0.1,
        3600.0,
    )?;
    // The controller checks sets on this model's sampled loop from the start.
    if crate::law::LinearModel::sampled_transfer_function(&num, &den, period).is_none() {
        return check.fail(
            "optimiser.model.den",
            format!("the model is far too fast to hold between samples of {period} s"),
        );
    }
    Ok(Some(ModelPrior {
        num,
        den,
        zeros,
        filter_pole,
        memory,
    }))
}

/// Leading zeros dropped, den made monic, num padded; refused unless finite, strictly proper
/// and of 1..=MAX_POLES poles.
fn normalised(
    check: &Check,
    num: Vec<f64>,
    den: Vec<f64>,
) -> Result<(Vec<f64>, Vec<f64>, usize), ConfigError> {
    for (key, v) in [("num", &num), ("den", &den)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return check.fail(&format!("optimiser.model.{key}[{i}]"), "must be finite");
        }
    }
    let trim = |v: &[f64]| v[v.iter().position(|x| *x != 0.0).unwrap_or(v.len())..].to_vec();
    let (num, den) = (trim(&num), trim(&den));
    let n = den.len().saturating_sub(1);
    if !(1..=MAX_POLES).contains(&n) {
        return check.fail(
            "optimiser.model.den",
            format!("degree {n}: the estimator fits 1 to {MAX_POLES} poles"),
        );
    }
    if num.is_empty() || num.len() > n {
        return check.fail(
            "optimiser.model.num",
            format!(
                "degree {} with {n} poles: the estimator fits a strictly proper model with an \
                 input gain (a numerator below the denominator's degree, not all zero)",
                num.len() as isize - 1
            ),
        );
    }
    let lead = den[0];
    let mut padded = vec![0.0; n + 1 - num.len()];
    padded.extend(num.iter().map(|x| x / lead));
    let zeros = num.len() - 1;
    Ok((padded, den.iter().map(|x| x / lead).collect(), zeros))
}

/// The largest |root| of a monic polynomial (descending powers): its companion matrix's
/// largest eigenvalue magnitude.
fn largest_root(den: &[f64]) -> f64 {
    let n = den.len() - 1;
    let c = nalgebra::DMatrix::from_fn(n, n, |i, j| match i {
        0 => -den[j + 1],
        _ if j + 1 == i => 1.0,
        _ => 0.0,
    });
    evoloop_linalg::eigen::eigenvalues(&c)
        .map(|ls| ls.iter().map(|l| l.norm()).fold(0.0, f64::max))
        .unwrap_or(0.0)
}
