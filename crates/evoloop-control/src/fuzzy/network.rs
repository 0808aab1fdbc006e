//! Fuzzy networks (fuzzy-network paper, Section 2): N inputs, M outputs, one-dimensional Gaussian
//! membership functions mu(x) = exp(-((x - m) / v)^2) per linguistic label, connection arrays
//! I_i that map each combination of input labels to one output label per output (or leave it
//! unconnected), product AND and implication, sum composition, and the analytic centre of
//! gravity of eqs. 11-12:
//!   y'_i = sum_c gamma_c m^i_{I_i(c)} prod_j v^j_{I_j(c)}  /  sum_c gamma_c prod_j v^j_{I_j(c)},
//! gamma_c the product of the input memberships of combination c (the sqrt(pi) factors of the
//! Gaussian integrals cancel). Inputs are scaled x' = clamp(x / C_x, -1, 1), outputs y = C_y y'.
//! A membership below `epsilon` is not evaluated (|x - m| > v sqrt(-ln epsilon)).

use serde::Serialize;
use std::fmt::Write as _;

/// Most inputs a network may have (`validate`); `eval`'s fixed buffers are this size.
pub const MAX_INPUTS: usize = 4;
/// Most linguistic labels (MFs) a variable may have (`validate`).
pub const MAX_LABELS: usize = 16;
/// Most outputs a network may have (`validate`).
pub const MAX_OUTPUTS: usize = 4;
/// Connection-array entry for an unconnected combination.
pub const UNCONNECTED: u16 = u16::MAX;

/// A Gaussian membership function exp(-((x - m) / v)^2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mf {
    /// The centre m, on the variable's normalised scale.
    pub m: f64,
    /// The width v (> 0): the membership is 1/e at m +- v.
    pub v: f64,
}

impl Mf {
    /// The membership of `x` (on the normalised scale), in [0, 1].
    pub fn at(&self, x: f64) -> f64 {
        let z = (x - self.m) / self.v;
        (-z * z).exp()
    }
}

/// One linguistic variable: its label names and membership functions.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Variable {
    /// The variable's name (`x`, `w`, `u` ...), in messages and printouts.
    pub name: String,
    /// The label names (N, Z, P ...), one per MF.
    pub labels: Vec<String>,
    /// The membership functions, one per label.
    pub mfs: Vec<Mf>,
}

/// A fuzzy network as the module docs describe it: its input and output variables, the connection
/// array and the scaling factors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FuzzyNetwork {
    /// The input variables, in the order `eval`'s `x` gives them.
    pub inputs: Vec<Variable>,
    /// The output variables, in the order `eval` writes `y`.
    pub outputs: Vec<Variable>,
    /// For every input-label combination (input 0's label varying fastest), M output labels or
    /// `UNCONNECTED` (a combination is connected to all outputs or to none).
    pub rules: Vec<u16>,
    /// C_x per input.
    pub input_scale: Vec<f64>,
    /// C_y per output.
    pub output_scale: Vec<f64>,
    /// Memberships below this are not evaluated (0: every one is).
    pub epsilon: f64,
}

/// Labels N, Z, P for three MFs, NG, N, Z, P, PG for five; L0, L1, ... otherwise.
pub fn default_labels(n: usize) -> Vec<String> {
    match n {
        3 => ["N", "Z", "P"].map(String::from).to_vec(),
        5 => ["NG", "N", "Z", "P", "PG"].map(String::from).to_vec(),
        7 => ["NG", "NM", "N", "Z", "P", "PM", "PG"]
            .map(String::from)
            .to_vec(),
        _ => (0..n).map(|i| format!("L{i}")).collect(),
    }
}

/// Why `FuzzyNetwork::validate` refuses a network: the part that is wrong.
#[derive(Debug, Clone, PartialEq)]
pub enum FuzzyNetworkError {
    /// Not 1..=MAX_INPUTS inputs and 1..=MAX_OUTPUTS outputs (inputs, outputs).
    Size(usize, usize),
    /// This variable has no MF, more than MAX_LABELS, or not one label per MF.
    Labels(String),
    /// This variable has an MF centre that is not finite or a width that is not above 0.
    Mf(String),
    /// The connection array does not have this many entries (one per combination and output).
    Rules(usize),
    /// This combination is connected to some outputs but not all.
    PartlyConnected(usize),
    /// This combination names an output label that does not exist.
    NoLabel(usize, u16),
    /// Not one scaling factor per input and per output.
    Scales,
    /// A scaling factor is not finite and above 0.
    Scale,
}

impl std::fmt::Display for FuzzyNetworkError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FuzzyNetworkError::Size(n, m) => write!(
                f,
                "1..={MAX_INPUTS} inputs and 1..={MAX_OUTPUTS} outputs (got {n}, {m})"
            ),
            FuzzyNetworkError::Labels(v) => {
                write!(f, "variable `{v}`: 1..={MAX_LABELS} MFs, one label each")
            }
            FuzzyNetworkError::Mf(v) => write!(
                f,
                "variable `{v}`: MF centres must be finite and widths > 0"
            ),
            FuzzyNetworkError::Rules(k) => write!(f, "connection array needs {k} entries"),
            FuzzyNetworkError::PartlyConnected(c) => write!(
                f,
                "combination {c} is connected to some outputs but not all"
            ),
            FuzzyNetworkError::NoLabel(c, k) => {
                write!(f, "combination {c}: output label {k} does not exist")
            }
            FuzzyNetworkError::Scales => f.write_str("one scaling factor per input and per output"),
            FuzzyNetworkError::Scale => f.write_str("scaling factors must be finite and > 0"),
        }
    }
}

impl std::error::Error for FuzzyNetworkError {}

impl FuzzyNetwork {
    /// Check sizes, label counts and the connection array.
    pub fn validate(&self) -> Result<(), FuzzyNetworkError> {
        let (n, m) = (self.inputs.len(), self.outputs.len());
        if n == 0 || n > MAX_INPUTS || m == 0 || m > MAX_OUTPUTS {
            return Err(FuzzyNetworkError::Size(n, m));
        }
        for v in self.inputs.iter().chain(&self.outputs) {
            if v.mfs.is_empty() || v.mfs.len() > MAX_LABELS || v.labels.len() != v.mfs.len() {
                return Err(FuzzyNetworkError::Labels(v.name.clone()));
            }
            if !(v.mfs.iter()).all(|mf| mf.m.is_finite() && mf.v.is_finite() && mf.v > 0.0) {
                return Err(FuzzyNetworkError::Mf(v.name.clone()));
            }
        }
        if self.rules.len() != self.combinations() * m {
            return Err(FuzzyNetworkError::Rules(self.combinations() * m));
        }
        for (c, chunk) in self.rules.chunks(m).enumerate() {
            let none = chunk.iter().filter(|k| **k == UNCONNECTED).count();
            if none != 0 && none != m {
                return Err(FuzzyNetworkError::PartlyConnected(c));
            }
            for (i, k) in chunk.iter().enumerate() {
                if *k != UNCONNECTED && *k as usize >= self.outputs[i].mfs.len() {
                    return Err(FuzzyNetworkError::NoLabel(c, *k));
                }
            }
        }
        if self.input_scale.len() != n || self.output_scale.len() != m {
            return Err(FuzzyNetworkError::Scales);
        }
        if self
            .input_scale
            .iter()
            .chain(&self.output_scale)
            .any(|c| !(c.is_finite() && *c > 0.0))
        {
            return Err(FuzzyNetworkError::Scale);
        }
        Ok(())
    }

    /// Number of input-label combinations.
    pub fn combinations(&self) -> usize {
        self.inputs.iter().map(|v| v.mfs.len()).product()
    }

    /// The network output for input `x`, into `y`. Allocation-free.
    pub fn eval(&self, x: &[f64], y: &mut [f64]) {
        let n = self.inputs.len();
        let m = self.outputs.len();
        let cut = (-self.epsilon.ln()).max(0.0).sqrt();
        // Memberships of the active labels (those above epsilon) of every input.
        let mut mu = [[0.0; MAX_LABELS]; MAX_INPUTS];
        let mut active = [[0u8; MAX_LABELS]; MAX_INPUTS];
        let mut n_active = [0usize; MAX_INPUTS];
        let mut stride = [0usize; MAX_INPUTS];
        let mut s = 1;
        for j in 0..n {
            stride[j] = s;
            s *= self.inputs[j].mfs.len();
            let xs = (x[j] / self.input_scale[j]).clamp(-1.0, 1.0);
            for (k, mf) in self.inputs[j].mfs.iter().enumerate() {
                if self.epsilon > 0.0 && (xs - mf.m).abs() > mf.v * cut {
                    continue;
                }
                mu[j][n_active[j]] = mf.at(xs);
                active[j][n_active[j]] = k as u8;
                n_active[j] += 1;
            }
            if n_active[j] == 0 {
                y[..m].fill(0.0);
                return;
            }
        }
        let mut num = [0.0; MAX_OUTPUTS];
        let mut den = 0.0;
        // Odometer over the active labels.
        let mut pos = [0usize; MAX_INPUTS];
        loop {
            let mut gamma = 1.0;
            let mut combo = 0;
            for j in 0..n {
                gamma *= mu[j][pos[j]];
                combo += active[j][pos[j]] as usize * stride[j];
            }
            let r = &self.rules[combo * m..combo * m + m];
            if r[0] != UNCONNECTED {
                let mut w = gamma;
                for (i, k) in r.iter().enumerate() {
                    w *= self.outputs[i].mfs[*k as usize].v;
                }
                for (i, k) in r.iter().enumerate() {
                    num[i] += w * self.outputs[i].mfs[*k as usize].m;
                }
                den += w;
            }
            let mut j = 0;
            loop {
                pos[j] += 1;
                if pos[j] < n_active[j] {
                    break;
                }
                pos[j] = 0;
                j += 1;
                if j == n {
                    break;
                }
            }
            if j == n {
                break;
            }
        }
        for i in 0..m {
            y[i] = if den > 0.0 {
                self.output_scale[i] * num[i] / den
            } else {
                0.0
            };
        }
    }

    /// The rule base in control-matrix form (paper Fig. 1): for two inputs a table with input 1's
    /// labels as rows and input 0's as columns; otherwise one line per rule.
    pub fn rule_table(&self) -> String {
        let m = self.outputs.len();
        let name = |c: usize, i: usize| -> String {
            match self.rules[c * m + i] {
                UNCONNECTED => "-".into(),
                k => self.outputs[i].labels[k as usize].clone(),
            }
        };
        let mut out = String::new();
        if self.inputs.len() == 2 {
            let (a, b) = (&self.inputs[0], &self.inputs[1]);
            let _ = write!(out, "{:>8}", format!("{}\\{}", b.name, a.name));
            for l in &a.labels {
                let _ = write!(out, "{l:>8}");
            }
            out.push('\n');
            for (i1, l1) in b.labels.iter().enumerate() {
                let _ = write!(out, "{l1:>8}");
                for i0 in 0..a.labels.len() {
                    let c = i0 + i1 * a.labels.len();
                    let cell: Vec<String> = (0..m).map(|i| name(c, i)).collect();
                    let _ = write!(out, "{:>8}", cell.join("/"));
                }
                out.push('\n');
            }
            return out;
        }
        let mut idx = vec![0usize; self.inputs.len()];
        for c in 0..self.combinations() {
            let mut rest = c;
            for (j, v) in self.inputs.iter().enumerate() {
                idx[j] = rest % v.mfs.len();
                rest /= v.mfs.len();
            }
            if self.rules[c * m] == UNCONNECTED {
                continue;
            }
            let cond: Vec<String> = self
                .inputs
                .iter()
                .zip(&idx)
                .map(|(v, k)| format!("{} is {}", v.name, v.labels[*k]))
                .collect();
            let then: Vec<String> = (0..m)
                .map(|i| format!("{} is {}", self.outputs[i].name, name(c, i)))
                .collect();
            let _ = writeln!(out, "IF {} THEN {}", cond.join(" AND "), then.join(" AND "));
        }
        out
    }

    /// The membership functions, one line per label (centre, width), scaled and normalised.
    pub fn mf_table(&self) -> String {
        let mut out = String::new();
        for (vars, scales, kind) in [
            (&self.inputs, &self.input_scale, "input"),
            (&self.outputs, &self.output_scale, "output"),
        ] {
            for (v, c) in vars.iter().zip(scales.iter()) {
                let _ = writeln!(out, "{kind} {} (scale {c:.4}):", v.name);
                for (l, mf) in v.labels.iter().zip(&v.mfs) {
                    let _ = writeln!(
                        out,
                        "  {l:>4}: centre {:+.4} (x scale {:+.4}), width {:.4}",
                        mf.m,
                        mf.m * c,
                        mf.v
                    );
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_network_is_refused_with_the_part_that_is_wrong() {
        let good = crate::fuzzy::arsinh::initial_network(4.0, 0.5, 0.3);
        assert_eq!(good.validate(), Ok(()));
        let refused = |edit: &dyn Fn(&mut FuzzyNetwork)| {
            let mut net = good.clone();
            edit(&mut net);
            net.validate().unwrap_err()
        };
        assert_eq!(
            refused(&|n| n.inputs.clear()),
            FuzzyNetworkError::Size(0, 1)
        );
        assert_eq!(
            refused(&|n| n.inputs[1].mfs[2].v = 0.0),
            FuzzyNetworkError::Mf("w".into())
        );
        assert_eq!(
            refused(&|n| {
                n.outputs[0].labels.pop();
            }),
            FuzzyNetworkError::Labels("u".into())
        );
        assert_eq!(
            refused(&|n| n.rules.truncate(8)),
            FuzzyNetworkError::Rules(9)
        );
        assert_eq!(
            refused(&|n| n.rules[4] = 5),
            FuzzyNetworkError::NoLabel(4, 5)
        );
        assert_eq!(
            refused(&|n| n.output_scale[0] = f64::NAN),
            FuzzyNetworkError::Scale
        );
        assert_eq!(
            refused(&|n| n.input_scale.push(1.0)),
            FuzzyNetworkError::Scales
        );
        // The message says which variable and what is allowed.
        let e = refused(&|n| n.inputs[1].mfs[2].v = 0.0).to_string();
        assert_eq!(e, "variable `w`: MF centres must be finite and widths > 0");
    }
}
