//! The plant's sample as the controller accepts it. A plant is another process, possibly in
//! another language (the plant contract), so its counts and values are input: a state whose
//! counts differ from the configured plant's, or whose values the law reads are NaN or
//! infinite, is refused. The law does not run on it (its integrators and filters keep their
//! last good values), the plant's safe command is sent in its place, and the cycle counts it.

use crate::msg::PlantState;
use crate::{MAX_JOINTS, MAX_STATES};

/// What every state must have: the configured plant's counts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StateCheck {
    pub n_x: usize,
    pub n_q: usize,
    pub n_y: usize,
    /// The command sent in place of the law's for a refused state (`plant.safe_command`).
    pub safe_command: f64,
}

/// Why a state was refused.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateFault {
    /// A count (`n_x`, `n_q` or `n_y`) is not the configured plant's.
    Count {
        field: Field,
        got: u32,
        expected: u32,
    },
    /// A value is NaN or infinite (`field[index]`; index 0 for `t`).
    NonFinite { field: Field, index: u32 },
}

/// A field of `PlantState`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Field {
    T,
    NX,
    NQ,
    NY,
    XTrue,
    QTrue,
    QdTrue,
    Y,
}

impl Field {
    pub fn name(self) -> &'static str {
        match self {
            Field::T => "t",
            Field::NX => "n_x",
            Field::NQ => "n_q",
            Field::NY => "n_y",
            Field::XTrue => "x_true",
            Field::QTrue => "q_true",
            Field::QdTrue => "qd_true",
            Field::Y => "y",
        }
    }
}

impl std::fmt::Display for StateFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StateFault::Count {
                field,
                got,
                expected,
            } => write!(
                f,
                "{} = {got}, the configured plant has {expected}",
                field.name()
            ),
            StateFault::NonFinite { field, index } => {
                write!(f, "{}[{index}] is not a finite number", field.name())
            }
        }
    }
}

impl StateCheck {
    /// The counts and values the laws read: every count, `t`, and the valid prefix of each
    /// array. Allocation-free, at most 57 comparisons.
    pub fn judge(&self, s: &PlantState) -> Result<(), StateFault> {
        let counts = [
            (Field::NX, s.n_x, self.n_x.min(MAX_STATES)),
            (Field::NQ, s.n_q, self.n_q.min(MAX_JOINTS)),
            (Field::NY, s.n_y, self.n_y.min(MAX_JOINTS)),
        ];
        for (field, got, expected) in counts {
            if got as usize != expected {
                return Err(StateFault::Count {
                    field,
                    got,
                    expected: expected as u32,
                });
            }
        }
        let arrays: [(Field, &[f64]); 5] = [
            (Field::T, std::slice::from_ref(&s.t)),
            (Field::XTrue, &s.x_true[..self.n_x.min(MAX_STATES)]),
            (Field::QTrue, &s.q_true[..self.n_q.min(MAX_JOINTS)]),
            (Field::QdTrue, &s.qd_true[..self.n_q.min(MAX_JOINTS)]),
            (Field::Y, &s.y[..self.n_y.min(MAX_JOINTS)]),
        ];
        for (field, values) in arrays {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(StateFault::NonFinite {
                    field,
                    index: i as u32,
                });
            }
        }
        Ok(())
    }
}

/// The refused states of a run: how many, and the first (its sample and why).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Refused {
    pub count: u64,
    pub first: Option<FirstRefused>,
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FirstRefused {
    pub seq: u64,
    pub fault: StateFault,
}

impl Refused {
    pub fn note(&mut self, seq: u64, fault: StateFault) {
        self.count += 1;
        self.first.get_or_insert(FirstRefused { seq, fault });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check() -> StateCheck {
        StateCheck {
            n_x: 4,
            n_q: 2,
            n_y: 1,
            safe_command: 0.0,
        }
    }

    fn good() -> PlantState {
        PlantState {
            n_x: 4,
            n_q: 2,
            n_y: 1,
            ..Default::default()
        }
    }

    #[test]
    fn a_good_state_passes_and_each_fault_is_named() {
        assert_eq!(check().judge(&good()), Ok(()));
        let mut s = good();
        s.n_y = 2;
        assert_eq!(
            check().judge(&s),
            Err(StateFault::Count {
                field: Field::NY,
                got: 2,
                expected: 1
            })
        );
        let mut s = good();
        s.qd_true[1] = f64::NAN;
        let e = check().judge(&s).unwrap_err();
        assert_eq!(e.to_string(), "qd_true[1] is not a finite number");
        let mut s = good();
        s.t = f64::INFINITY;
        assert!(check().judge(&s).is_err());
        // Beyond the valid prefix nothing is read.
        let mut s = good();
        s.y[1] = f64::NAN;
        s.x_true[4] = f64::NAN;
        assert_eq!(check().judge(&s), Ok(()));
    }
}
