//! Why an optimiser's settings were refused: the one error of every optimiser's constructor
//! and `validate` (nothing is built from refused settings).

/// An optimiser's settings refused.
#[derive(Debug, Clone, PartialEq)]
pub enum SettingsError {
    /// The search box needs as many lower as upper bounds, at least one: the two lengths.
    BoxShape {
        /// Number of lower bounds (the box's dimension).
        lower: usize,
        /// Number of upper bounds; for a start point that does not fit the box (`bayes`,
        /// `cmaes`), its length.
        upper: usize,
    },
    /// Dimension `dim`'s bounds are not finite and ordered (lower < upper).
    NotABox {
        /// Index of the dimension, from 0.
        dim: usize,
        /// Its lower bound.
        lower: f64,
        /// Its upper bound.
        upper: f64,
    },
    /// A setting outside its range: its name, the range it must lie in, what it was.
    OutOfRange {
        /// The setting's name as the message spells it (`population`, `F`).
        setting: &'static str,
        /// The range it must lie in, in words (`>= 4`, `in (0, 1]`).
        range: &'static str,
        /// The value given, as text.
        got: String,
    },
}

impl SettingsError {
    pub(crate) fn out_of_range(
        setting: &'static str,
        range: &'static str,
        got: impl std::fmt::Display,
    ) -> Self {
        SettingsError::OutOfRange {
            setting,
            range,
            got: got.to_string(),
        }
    }
}

impl std::fmt::Display for SettingsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SettingsError::BoxShape { lower, upper } => write!(
                f,
                "the box needs as many lower as upper bounds, at least one ({lower} and {upper})"
            ),
            SettingsError::NotABox { dim, lower, upper } => {
                write!(
                    f,
                    "dimension {dim}: bounds [{lower}, {upper}] are not a box"
                )
            }
            SettingsError::OutOfRange {
                setting,
                range,
                got,
            } => write!(f, "{setting} must be {range} (got {got})"),
        }
    }
}

impl std::error::Error for SettingsError {}

/// A search box: as many lower as upper bounds, at least one, each pair finite and ordered.
pub fn check_box(lower: &[f64], upper: &[f64]) -> Result<(), SettingsError> {
    if lower.is_empty() || lower.len() != upper.len() {
        return Err(SettingsError::BoxShape {
            lower: lower.len(),
            upper: upper.len(),
        });
    }
    for (dim, (&l, &u)) in lower.iter().zip(upper).enumerate() {
        if !(l.is_finite() && u.is_finite() && l < u) {
            return Err(SettingsError::NotABox {
                dim,
                lower: l,
                upper: u,
            });
        }
    }
    Ok(())
}

/// A point of the box `lower..upper` in the box's unit coordinates [0, 1]^d (clamped), where the
/// model-based optimisers (`cmaes`, `bayes`) search so one step suits gains of any magnitude.
pub(crate) fn to_unit(lower: &[f64], upper: &[f64], x: &[f64]) -> nalgebra::DVector<f64> {
    nalgebra::DVector::from_iterator(
        x.len(),
        (0..x.len()).map(|i| ((x[i] - lower[i]) / (upper[i] - lower[i])).clamp(0.0, 1.0)),
    )
}

/// `to_unit`'s inverse.
pub(crate) fn from_unit(lower: &[f64], upper: &[f64], u: &nalgebra::DVector<f64>) -> Vec<f64> {
    (0..u.len())
        .map(|i| lower[i] + u[i] * (upper[i] - lower[i]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_is_finite_ordered_and_of_one_length() {
        assert_eq!(check_box(&[0.0, 1.0], &[1.0, 2.0]), Ok(()));
        assert_eq!(
            check_box(&[0.0], &[]),
            Err(SettingsError::BoxShape { lower: 1, upper: 0 })
        );
        assert!(matches!(
            check_box(&[0.0, 2.0], &[1.0, 2.0]),
            Err(SettingsError::NotABox { dim: 1, .. })
        ));
        assert!(matches!(
            check_box(&[f64::NAN], &[1.0]),
            Err(SettingsError::NotABox { dim: 0, .. })
        ));
        let e = SettingsError::out_of_range("population", ">= 4", 2);
        assert_eq!(e.to_string(), "population must be >= 4 (got 2)");
    }
}
