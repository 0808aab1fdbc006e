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
    /// The configured plant's state count, which every sample's `n_x` must equal.
    pub n_x: usize,
    /// The configured plant's joint count, which every sample's `n_q` must equal.
    pub n_q: usize,
    /// The configured plant's measured-output count, which every sample's `n_y` must equal.
    pub n_y: usize,
    /// The commands the law sends: the applied command's valid prefix (`u_applied`), which
    /// an estimator reads.
    pub n_u: usize,
    /// Whether the law reads the truth fields (`ControllerConfig::reads_truth`): only then must
    /// they be finite (a plant may withhold them as NaN, `plant.publish_truth = false`).
    pub reads_truth: bool,
    /// The command sent in place of the law's for a refused state (`plant.safe_command`).
    pub safe_command: f64,
}

/// Why a state was refused.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StateFault {
    /// A count (`n_x`, `n_q` or `n_y`) is not the configured plant's.
    Count {
        /// Which count differs.
        field: Field,
        /// The count the sample has.
        got: u32,
        /// The configured plant's count.
        expected: u32,
    },
    /// A value is NaN or infinite (`field[index]`; index 0 for `t`).
    NonFinite {
        /// The field holding the value.
        field: Field,
        /// The value's index in it.
        index: u32,
    },
    /// The sample breaks time (realtime): its stamp or sequence number cannot follow the last
    /// good sample's.
    Time(TimeFault),
}

/// How a sample breaks time. The plant contract's `stamp_ns` is CLOCK_MONOTONIC of this
/// machine at the sample and `seq` counts the plant's periods; the realtime loop schedules its
/// cycles on them, so one bad pair (a stamp of 0, a seq jumping by 10^6, a plant ticking ten
/// times too fast) would otherwise move every later deadline.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeFault {
    /// `seq` is not after the last good sample's `last`.
    SeqNotAfter {
        /// The sample's `seq`.
        seq: u64,
        /// The last good sample's `seq`.
        last: u64,
    },
    /// `stamp_ns` is `by_ns` before the last good sample's.
    StampBehind {
        /// How far behind, ns.
        by_ns: u64,
    },
    /// `stamp_ns` is `by_ns` ahead of this machine's clock.
    StampAhead {
        /// How far ahead of the clock when the sample was read, ns.
        by_ns: u64,
    },
    /// `seq` is further on than the time since the first sample allows: its period would have
    /// begun `by_ns` before the plant's first period did (a jump, or a plant ticking faster
    /// than the period).
    SeqAhead {
        /// How long before the first period's start its period would have begun, ns.
        by_ns: u64,
    },
}

/// A field of `PlantState`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Field {
    /// `t`: the sample's simulated time, s.
    T,
    /// `n_x`: the number of valid states.
    NX,
    /// `n_q`: the number of joints.
    NQ,
    /// `n_y`: the number of measured outputs.
    NY,
    /// `x_true`: the simulator's true state.
    XTrue,
    /// `q_true`: the simulator's true joint positions.
    QTrue,
    /// `qd_true`: the simulator's true joint velocities.
    QdTrue,
    /// `y`: the measured outputs.
    Y,
    /// `u_applied`: the command applied over the interval that ended at the sample.
    UApplied,
}

impl Field {
    /// The field's name in `PlantState`, as messages give it.
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
            Field::UApplied => "u_applied",
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
            StateFault::Time(t) => write!(f, "{t}"),
        }
    }
}

impl std::fmt::Display for TimeFault {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ms = |ns: &u64| *ns as f64 * 1e-6;
        match self {
            TimeFault::SeqNotAfter { seq, last } => {
                write!(f, "seq {seq} is not after the last good sample's {last}")
            }
            TimeFault::StampBehind { by_ns } => write!(
                f,
                "stamp_ns is {:.3} ms before the last good sample's",
                ms(by_ns)
            ),
            TimeFault::StampAhead { by_ns } => write!(
                f,
                "stamp_ns is {:.3} ms ahead of this machine's CLOCK_MONOTONIC",
                ms(by_ns)
            ),
            TimeFault::SeqAhead { by_ns } => write!(
                f,
                "seq is {:.3} ms of periods further on than its stamp allows",
                ms(by_ns)
            ),
        }
    }
}

/// The plant's sample clock as the realtime loop follows it: when sample 0 was due (`epoch`),
/// and whether each new sample keeps time with the good ones before it. Allocation-free.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleTime {
    period_ns: u64,
    /// How far a sample's period may seem to begin before the first sample's (the first
    /// sample's own wake-up latency, which the estimate then sheds).
    allowance_ns: u64,
    /// `first`'s epoch: no good sample's period begins more than `allowance_ns` before it
    /// (unless a run of samples agrees on an earlier one: `late_first`).
    anchor: u64,
    /// The first sample's epoch and stamp: the anchor never leaves the epoch by more than
    /// `MAX_FOLLOW_NS` and `FOLLOW_RATE` of the time since.
    first: u64,
    first_stamp: u64,
    epoch: u64,
    last_seq: u64,
    last_stamp: u64,
    /// Samples in a row whose period begins before the anchor's (refused or not) that agree
    /// with each other on it: (how many, earliest, latest).
    ahead: (u32, u64, u64),
}

/// Samples in a row that must agree on periods beginning before the anchor allows for the
/// clock to follow them: the first sample was late (a plant's slow wake-up), not the rest
/// early. A plant ticking fast or whose seq jumped never gives as many that agree.
const FOLLOW_AFTER: u32 = 64;
/// The most the clock follows such samples, from the first sample's epoch: 1 s, and 1 ms for
/// each second since (a plant whose timer runs up to 1000 ppm fast against this machine's
/// clock). A seq jump beyond it is never taken for a late first sample.
const MAX_FOLLOW_NS: u64 = 1_000_000_000;
const FOLLOW_RATE: u64 = 1000;

impl SampleTime {
    /// Following `first`, a sample already judged against this machine's clock.
    pub fn new(first: &PlantState, period_ns: u64, allowance_ns: u64) -> SampleTime {
        let anchor = plant_epoch(first, period_ns);
        SampleTime {
            period_ns,
            allowance_ns,
            anchor,
            first: anchor,
            first_stamp: first.stamp_ns,
            epoch: anchor,
            last_seq: first.seq,
            last_stamp: first.stamp_ns,
            ahead: (0, 0, 0),
        }
    }

    /// When sample 0 was taken, as the good samples tell it: a sample's stamp is its tick plus
    /// the plant's wake-up latency, so the earliest `stamp - seq * period` is the best estimate.
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// Whether `s`, read at `now_ns`, keeps time with the good samples before it; if it does,
    /// it is the last good sample from now on.
    pub fn judge(&mut self, s: &PlantState, now_ns: u64) -> Result<(), TimeFault> {
        if s.seq <= self.last_seq {
            return Err(TimeFault::SeqNotAfter {
                seq: s.seq,
                last: self.last_seq,
            });
        }
        if s.stamp_ns < self.last_stamp {
            return Err(TimeFault::StampBehind {
                by_ns: self.last_stamp - s.stamp_ns,
            });
        }
        if s.stamp_ns > now_ns.saturating_add(self.allowance_ns) {
            return Err(TimeFault::StampAhead {
                by_ns: s.stamp_ns - now_ns,
            });
        }
        let epoch = plant_epoch(s, self.period_ns);
        let followed = epoch < self.anchor && self.late_first(epoch, s.stamp_ns);
        if epoch >= self.anchor {
            self.ahead.0 = 0;
        }
        if epoch < self.anchor.saturating_sub(self.allowance_ns) && !followed {
            return Err(TimeFault::SeqAhead {
                by_ns: self.anchor - epoch,
            });
        }
        self.epoch = self.epoch.min(epoch);
        self.last_seq = s.seq;
        self.last_stamp = s.stamp_ns;
        Ok(())
    }
}

impl SampleTime {
    /// Whether `epoch`, earlier than the anchor's, ends a run of `FOLLOW_AFTER` such samples
    /// (taken or refused) that agree within the allowance and lie within the follow limit of
    /// the first sample's: the first sample was late, and the anchor moves to the run's
    /// earliest.
    fn late_first(&mut self, epoch: u64, stamp_ns: u64) -> bool {
        let (n, lo, hi) = self.ahead;
        let agrees = n > 0 && hi.max(epoch) - lo.min(epoch) <= self.allowance_ns;
        self.ahead = if agrees {
            (n.saturating_add(1), lo.min(epoch), hi.max(epoch))
        } else {
            (1, epoch, epoch)
        };
        let (n, lo, _) = self.ahead;
        let since = stamp_ns.saturating_sub(self.first_stamp);
        let limit = MAX_FOLLOW_NS.saturating_add(since / FOLLOW_RATE);
        if n >= FOLLOW_AFTER && self.first - lo <= limit {
            self.anchor = lo;
            return true;
        }
        false
    }
}

/// When sample 0 would have been taken, as `s` tells it: its stamp less `seq` periods. The
/// numbers come from another process (any language), so neither the product nor the difference
/// may wrap.
fn plant_epoch(s: &PlantState, period_ns: u64) -> u64 {
    s.stamp_ns.saturating_sub(s.seq.saturating_mul(period_ns))
}

impl StateCheck {
    /// The counts and values the laws read: every count, `t`, and the valid prefix of `y`,
    /// `u_applied` and, for a law that reads them, the truth fields. Allocation-free, at most
    /// 65 comparisons.
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
        let truth = |n: usize| if self.reads_truth { n } else { 0 };
        let arrays: [(Field, &[f64]); 6] = [
            (Field::T, std::slice::from_ref(&s.t)),
            (Field::XTrue, &s.x_true[..truth(self.n_x.min(MAX_STATES))]),
            (Field::QTrue, &s.q_true[..truth(self.n_q.min(MAX_JOINTS))]),
            (Field::QdTrue, &s.qd_true[..truth(self.n_q.min(MAX_JOINTS))]),
            (Field::Y, &s.y[..self.n_y.min(MAX_JOINTS)]),
            (Field::UApplied, &s.u_applied[..self.n_u.min(MAX_JOINTS)]),
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
    /// How many states were refused.
    pub count: u64,
    /// The first refused state, if any.
    pub first: Option<FirstRefused>,
}

/// The first state refused in a run: its sample and why.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FirstRefused {
    /// The refused sample's `seq`.
    pub seq: u64,
    /// Why it was refused.
    pub fault: StateFault,
}

impl Refused {
    /// Count a refused state, sample `seq`, refused for `fault`; the first one is kept.
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
            n_u: 1,
            reads_truth: true,
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
        s.u_applied[1] = f64::NAN;
        assert_eq!(check().judge(&s), Ok(()));
        // The applied command an estimator reads.
        let mut s = good();
        s.u_applied[0] = f64::NAN;
        let e = check().judge(&s).unwrap_err();
        assert_eq!(e.to_string(), "u_applied[0] is not a finite number");
    }

    /// A plant that withholds its truth (NaN in every truth field) is judged on its readings
    /// alone when the law reads none of it, and refused for a law that does.
    #[test]
    fn withheld_truth_is_refused_only_for_a_law_that_reads_it() {
        let mut s = good();
        s.x_true = [f64::NAN; MAX_STATES];
        s.q_true = [f64::NAN; MAX_JOINTS];
        s.qd_true = [f64::NAN; MAX_JOINTS];
        let readings_only = StateCheck {
            reads_truth: false,
            ..check()
        };
        assert_eq!(readings_only.judge(&s), Ok(()));
        assert_eq!(
            check().judge(&s),
            Err(StateFault::NonFinite {
                field: Field::XTrue,
                index: 0
            })
        );
    }

    fn sample(seq: u64, stamp_ns: u64) -> PlantState {
        PlantState {
            seq,
            stamp_ns,
            ..PlantState::default()
        }
    }

    /// The third hostile probe's samples: a stamp of 0, a seq jump of 10^6, a seq going back,
    /// a stamp ahead of the clock, a plant ticking ten times faster than the period; each is
    /// refused and the estimate of when sample 0 was due does not move, while good samples
    /// (late ones too) go on being taken.
    #[test]
    fn a_sample_that_breaks_time_is_refused_and_moves_nothing() {
        let ms = 1_000_000;
        let t0 = 1_000_000 * ms;
        // The first sample woke 0.4 ms late.
        let mut c = SampleTime::new(&sample(0, t0 + 400_000), ms, 3 * ms);
        assert_eq!(c.epoch(), t0 + 400_000);
        assert_eq!(c.judge(&sample(1, t0 + ms + 10_000), t0 + 2 * ms), Ok(()));
        assert_eq!(
            c.epoch(),
            t0 + 10_000,
            "the estimate sheds the first sample's latency"
        );
        // Late, and skipping two samples: still good.
        assert_eq!(
            c.judge(&sample(4, t0 + 4 * ms + 900_000), t0 + 5 * ms),
            Ok(())
        );
        let now = t0 + 6 * ms;
        let bad = [
            (sample(5, 0), "stamp 0"),
            (sample(1_000_005, t0 + 5 * ms), "seq + 10^6"),
            (sample(3, t0 + 5 * ms), "seq back"),
            (sample(4, t0 + 5 * ms), "seq repeated"),
            (sample(5, now + 10 * ms), "stamp ahead of the clock"),
        ];
        for (s, what) in bad {
            assert!(c.judge(&s, now).is_err(), "{what}");
            assert_eq!(c.epoch(), t0 + 10_000, "{what}");
        }
        assert!(matches!(
            c.judge(&sample(0, 0), now),
            Err(TimeFault::SeqNotAfter { .. })
        ));
        assert!(matches!(
            c.judge(&sample(5, 0), now),
            Err(TimeFault::StampBehind { .. })
        ));
        assert!(matches!(
            c.judge(&sample(5, now + 10 * ms), now),
            Err(TimeFault::StampAhead { .. })
        ));
        assert!(matches!(
            c.judge(&sample(1_000_005, t0 + 5 * ms), now),
            Err(TimeFault::SeqAhead { .. })
        ));
        // A plant ticking every 0.1 ms: taken while within the allowance, then refused, and
        // the estimate never moves more than the allowance.
        let mut refused = 0;
        for i in 1..=100u64 {
            let stamp = t0 + 5 * ms + i * ms / 10;
            if c.judge(&sample(4 + i, stamp), stamp).is_err() {
                refused += 1;
            }
            assert!(c.epoch() + 3 * ms >= t0 + 400_000);
        }
        assert!(refused > 90, "{refused}");
        // A good sample after them is taken.
        assert_eq!(
            c.judge(&sample(200, t0 + 200 * ms + 5_000), t0 + 201 * ms),
            Ok(())
        );
        // A seq that jumped by 10^6 for good stays refused, however many samples agree on it.
        for i in 201..1000u64 {
            let stamp = t0 + i * ms + 5_000;
            assert!(c.judge(&sample(1_000_000 + i, stamp), stamp).is_err());
        }
    }

    /// A first sample 40 ms late (a plant's slow first wake-up, after which it publishes the
    /// overdue ticks at once and then keeps time) refuses samples only until `FOLLOW_AFTER`
    /// on-time ones agree: then the clock follows them, and takes every sample after.
    #[test]
    fn a_late_first_sample_is_outgrown() {
        let ms = 1_000_000;
        let t0 = 1_000_000 * ms;
        let stamp = |k: u64| (t0 + k * ms + 20_000).max(t0 + 40 * ms + k * 10_000);
        let mut c = SampleTime::new(&sample(0, stamp(0)), ms, 3 * ms);
        let refused: Vec<u64> = (1..300u64)
            .filter(|&k| c.judge(&sample(k, stamp(k)), stamp(k)).is_err())
            .collect();
        // The overdue ticks the anchor cannot tell from early ones, then FOLLOW_AFTER - 1
        // on-time ones: about a tenth of a second of this 1 kHz plant.
        assert!(refused.len() < 41 + FOLLOW_AFTER as usize, "{refused:?}");
        assert!(
            refused.iter().all(|&k| k < 41 + FOLLOW_AFTER as u64),
            "{refused:?}"
        );
        assert_eq!(c.epoch(), t0 + 20_000);
    }

    #[test]
    fn a_foreign_sequence_number_does_not_wrap_the_epoch() {
        assert_eq!(plant_epoch(&sample(3, 10_000), 1_000), 7_000);
        assert_eq!(plant_epoch(&sample(u64::MAX, 10_000), 1_000), 0);
        assert_eq!(plant_epoch(&sample(20, 10_000), 1_000), 0);
    }
}
