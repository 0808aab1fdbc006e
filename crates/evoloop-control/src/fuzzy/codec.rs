//! Genes <-> fuzzy network: how a GA string describes a network's tunable parameters.
//!
//! Per variable (inputs, then outputs): one gene per MF centre in (0, 1), mapped through the
//! order-preserving map (eqs. 20-22) into [centre_lo, centre_hi], then one gene per MF width in
//! [width_lo, width_hi]; then one scaling factor per input and per output. The rule base is fixed
//! (it is the user's knowledge); the GA adapts MFs and scaling only.

use super::network::FuzzyNetwork;
use super::ordered;

/// How a GA string describes a fuzzy network's membership functions and scaling factors, and back
/// (see the module docs).
#[derive(Debug, Clone)]
pub struct Codec {
    /// The network whose structure (labels, rules, epsilon) the genes fill in.
    pub template: FuzzyNetwork,
    /// The range (lo, hi) the ordered centre genes map into.
    pub centre: (f64, f64),
    /// The bounds (lo, hi) of every width gene.
    pub width: (f64, f64),
    /// Bounds of each scaling factor (inputs first, then outputs).
    pub scale_bounds: Vec<(f64, f64)>,
}

/// Keeps genes of ordered centres strictly inside (0, 1).
const GENE_MARGIN: f64 = 1e-6;

impl Codec {
    fn variables(&self) -> impl Iterator<Item = usize> + '_ {
        self.template
            .inputs
            .iter()
            .chain(&self.template.outputs)
            .map(|v| v.mfs.len())
    }

    /// The number of genes: a centre and a width per MF of every variable, then one per scaling
    /// factor.
    pub fn len(&self) -> usize {
        self.variables().map(|n| 2 * n).sum::<usize>() + self.scale_bounds.len()
    }

    /// Whether there are no genes.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Gene indices of the scaling factors (Hooke-Jeeves' subject in the hybrid's phase 2).
    pub fn scaling_genes(&self) -> Vec<usize> {
        let start = self.len() - self.scale_bounds.len();
        (start..self.len()).collect()
    }

    /// The lower and upper bound of every gene, in gene order: centre genes just inside (0, 1),
    /// widths within `width`, scaling factors within `scale_bounds`.
    pub fn bounds(&self) -> (Vec<f64>, Vec<f64>) {
        let (mut lo, mut hi) = (Vec::new(), Vec::new());
        for n in self.variables() {
            lo.extend(std::iter::repeat_n(GENE_MARGIN, n));
            hi.extend(std::iter::repeat_n(1.0 - GENE_MARGIN, n));
            lo.extend(std::iter::repeat_n(self.width.0, n));
            hi.extend(std::iter::repeat_n(self.width.1, n));
        }
        for (l, h) in &self.scale_bounds {
            lo.push(*l);
            hi.push(*h);
        }
        (lo, hi)
    }

    /// Write the network the genes describe into `net` (same structure as the template).
    pub fn decode_into(&self, genes: &[f64], net: &mut FuzzyNetwork) {
        let mut g = 0;
        let mut centres = [0.0; super::network::MAX_LABELS];
        let lo = [self.centre.0; super::network::MAX_LABELS];
        let hi = [self.centre.1; super::network::MAX_LABELS];
        let n_in = net.inputs.len();
        for k in 0..n_in + net.outputs.len() {
            let var = if k < n_in {
                &mut net.inputs[k]
            } else {
                &mut net.outputs[k - n_in]
            };
            let n = var.mfs.len();
            ordered::centres(&genes[g..g + n], &lo[..n], &hi[..n], &mut centres[..n]);
            for (i, mf) in var.mfs.iter_mut().enumerate() {
                mf.m = centres[i];
                mf.v = genes[g + n + i];
            }
            g += 2 * n;
        }
        for (i, s) in net
            .input_scale
            .iter_mut()
            .chain(net.output_scale.iter_mut())
            .enumerate()
        {
            *s = genes[g + i];
        }
    }

    /// A copy of the template with the MFs and scaling factors `genes` describe (`len` values).
    pub fn decode(&self, genes: &[f64]) -> FuzzyNetwork {
        let mut net = self.template.clone();
        self.decode_into(genes, &mut net);
        net
    }

    /// Genes of a network with this structure (centres strictly ordered inside the bounds).
    pub fn encode(&self, net: &FuzzyNetwork) -> Option<Vec<f64>> {
        let mut genes = Vec::with_capacity(self.len());
        for var in net.inputs.iter().chain(&net.outputs) {
            let n = var.mfs.len();
            let m: Vec<f64> = var.mfs.iter().map(|mf| mf.m).collect();
            genes.extend(ordered::genes(
                &m,
                &vec![self.centre.0; n],
                &vec![self.centre.1; n],
            )?);
            genes.extend(var.mfs.iter().map(|mf| mf.v));
        }
        genes.extend(net.input_scale.iter().chain(&net.output_scale));
        Some(genes)
    }
}
