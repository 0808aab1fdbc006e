//! The tracking cost of a closed-loop run, one definition for every user: the per-repetition
//! cost of the indirect scheme and the report (|e| summed over outputs plus w |u| summed over
//! inputs, per sample), and the maglev's G of eq. 31 (w = 1/1000 per mA), whose two parts
//! G_error and G_current the tuner reports separately.
//!
//! The running sums are kept in one fixed order (per sample: the outputs' errors, then the
//! weighted inputs; then that sample's sum added to the total), so every user's figures are the
//! same bits for the same samples.

/// Running sums over the samples added so far.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct TrackingCost {
    /// Weight of |u|.
    pub w: f64,
    /// sum |r - y| over samples and outputs.
    pub error: f64,
    /// sum w |u| over samples and inputs.
    pub control: f64,
    /// sum over samples of (sum |r - y| + sum w |u|).
    pub total: f64,
}

impl TrackingCost {
    /// Empty sums, with |u| weighted by `w`.
    pub fn new(w: f64) -> Self {
        Self {
            w,
            ..Default::default()
        }
    }

    /// Add one sample: references `r` and outputs `y` pairwise, inputs `u`.
    pub fn add(&mut self, r: &[f64], y: &[f64], u: &[f64]) {
        let (mut e, mut c) = (0.0, 0.0);
        for (ri, yi) in r.iter().zip(y) {
            e += (ri - yi).abs();
        }
        for ui in u {
            c += self.w * ui.abs();
        }
        self.error += e;
        self.control += c;
        self.total += e + c;
    }
}
