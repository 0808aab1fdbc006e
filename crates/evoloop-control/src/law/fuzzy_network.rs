//! A direct fuzzy controller (fuzzy-network paper, Sections 2 and 5.1): the network of the
//! synthetic experiment, inputs x'_0 = y_k (the measured output) and x'_1 = w_k (the set-point),
//! output u_k; its 3 x 3 rule base is fixed (eq. 15) and its membership functions and scaling
//! factors are the parameters, as genes (`fuzzy::arsinh::codec`). The law has no memory, so a
//! new set switches outright.

use super::{Controller, ControllerConfig, ControllerContext};
use crate::check::{Check, ConfigError, Tunable};
use crate::fuzzy::codec::Codec;
use crate::fuzzy::FuzzyNetwork;
use crate::msg::{PlantState, ParamKind};
use crate::reference::Setpoint;
use serde::{Deserialize, Serialize};

/// The direct fuzzy controller of the module docs: the network the genes in service describe,
/// evaluated on [y, w] each cycle.
pub struct FuzzyNetworkLaw {
    codec: Codec,
    net: FuzzyNetwork,
    params: Vec<f64>,
}

impl FuzzyNetworkLaw {
    /// The law running the network `codec` decodes from `genes`, its first parameter set
    /// (`codec.len()` values).
    pub fn new(codec: Codec, genes: &[f64]) -> Self {
        let net = codec.decode(genes);
        Self {
            codec,
            net,
            params: genes.to_vec(),
        }
    }
}

impl Controller for FuzzyNetworkLaw {
    fn kind(&self) -> ParamKind {
        ParamKind::FuzzyNetwork
    }
    fn n_params(&self) -> usize {
        self.params.len()
    }
    fn params(&self) -> &[f64] {
        &self.params
    }
    fn n_outputs(&self) -> usize {
        1
    }
    fn step(&mut self, state: &PlantState, sp: &Setpoint, u: &mut [f64]) {
        self.net.eval(&[state.y[0], sp.q[0]], &mut u[..1]);
    }
    fn swap_params(&mut self, new: &[f64], _state: &PlantState, _sp: &Setpoint) {
        self.params.copy_from_slice(new);
        self.codec.decode_into(new, &mut self.net);
    }
}

// ---------------------------------------------------------------- configuration

/// Which network structure: the synthetic experiment's is the one there is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Structure {
    /// Section 5.1: inputs x and w with N/Z/P, output u with NG..PG (`fuzzy::arsinh`).
    Arsinh,
}

/// The `[controller.fuzzy_network]` keys.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Table {
    network: Structure,
    /// Genes; default the Fig. 1 controller with medium widths and unit scaling.
    params: Option<Vec<f64>>,
    lower: Option<Vec<f64>>,
    upper: Option<Vec<f64>>,
}

/// Validated `[controller.fuzzy_network]` settings: the structure, and the genes with their bounds.
#[derive(Debug, Clone, Serialize)]
pub struct FuzzyNetworkSpec {
    /// The network's structure (`network`).
    pub network: Structure,
    /// The genes (default: the Fig. 1 controller with medium widths and unit scaling) and their
    /// bounds (default: the codec's).
    #[serde(flatten)]
    pub tunable: Tunable,
}

/// Validate `[controller.fuzzy_network]`: as many genes as the structure's codec has, each within
/// its bounds. Fails when the table is missing.
pub fn validate(
    t: Option<Table>,
    check: &Check,
    _cx: &ControllerContext,
) -> Result<FuzzyNetworkSpec, ConfigError> {
    let Some(t) = t else {
        return check.fail(
            "controller.fuzzy_network",
            "missing table [controller.fuzzy_network] with `network = \"arsinh\"`",
        );
    };
    let codec = crate::fuzzy::arsinh::codec();
    let (lo, hi) = codec.bounds();
    let params = match t.params {
        Some(p) => p,
        None => codec
            .encode(&crate::fuzzy::arsinh::prespecified()[1])
            .expect("the Fig. 1 controller encodes"),
    };
    if params.len() != codec.len() {
        return check.fail(
            "controller.fuzzy_network.params",
            format!("the arsinh network has {} genes, got {}", codec.len(), params.len()),
        );
    }
    let tunable = check.tunable(
        "controller.fuzzy_network",
        params,
        Some(t.lower.unwrap_or(lo)),
        Some(t.upper.unwrap_or(hi)),
        0.0,
    )?;
    Ok(FuzzyNetworkSpec {
        network: t.network,
        tunable,
    })
}

impl ControllerConfig for FuzzyNetworkSpec {
    fn build(&self, _period: f64, _u_limit: Option<f64>) -> Box<dyn Controller> {
        Box::new(FuzzyNetworkLaw::new(
            crate::fuzzy::arsinh::codec(),
            &self.tunable.gains,
        ))
    }
    fn tunable(&self) -> &Tunable {
        &self.tunable
    }
    fn param_kind(&self) -> ParamKind {
        ParamKind::FuzzyNetwork
    }
    /// C_x0, C_x1, C_y0.
    fn scaling_genes(&self) -> Vec<usize> {
        crate::fuzzy::arsinh::codec().scaling_genes()
    }
}
