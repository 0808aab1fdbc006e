//! The signal filters, in one home: the causal state-variable filter a^N / (s + a)^N that the
//! estimators run sample by sample in the loop (`svf`: the indirect scheme's estimators at order
//! 4, the evidence of fuzzy model selection at order 2), and the Savitzky-Golay smoother that the
//! identification runs offline over a whole record (`smoothing`).

pub mod smoothing;
pub mod svf;

pub use smoothing::smooth;
pub use svf::{Svf, SvfDesign};
