//! A model larger than one parameter set, gathered from its parts (`ParamKind::ModelPart`, made
//! by `ParamSet::model_sets`) so that the law checks and applies it whole, as one set: a part
//! that comes without the parts before it drops the model, and none of a partial model is ever
//! in service. The buffer is allocated once, at the law's largest model; gathering never
//! allocates.

use crate::msg::{ParamCode, ParamKind, ParamSet, PART_HEADER};

/// What a part added up to.
pub enum Gathered<'a> {
    /// More parts to come. A first part that found another model half gathered drops that one:
    /// its version, to be refused (no model goes without an outcome it could be given).
    Incomplete {
        /// The version of the half-gathered model this part's model displaced, if any.
        dropped: Option<u64>,
    },
    /// The last part: the whole model's values.
    Whole(&'a [f64]),
    /// A later part of a model already refused (refused once, in one event).
    Dropped,
}

/// Where a model sent in parts is gathered (see the module docs): the values so far, the model they
/// belong to, and the last model refused.
pub struct Gather {
    values: Vec<f64>,
    /// The model being gathered: its version and length (0: none).
    version: u64,
    total: usize,
    /// The last version refused: its remaining parts are dropped without a second event.
    refused: Option<u64>,
}

/// A header value that must be a whole number of at most `max`.
fn count(v: f64, max: usize) -> Option<usize> {
    (v >= 0.0 && v.fract() == 0.0 && v <= max as f64).then_some(v as usize)
}

/// A part's offset in the whole model (header value 1), if it is one.
fn offset_of(set: &ParamSet) -> Option<usize> {
    set.values().get(1).and_then(|&v| count(v, usize::MAX))
}

/// A part's header, read and checked on its own: the whole's kind must be `kind`, offset and
/// total whole numbers of at most `max`, and the share must end within the total.
struct Header<'a> {
    offset: usize,
    total: usize,
    share: &'a [f64],
}

impl<'a> Header<'a> {
    fn read(set: &'a ParamSet, kind: ParamKind, max: usize) -> Result<Self, (ParamCode, u32)> {
        let v = set.values();
        let n = v.len();
        if n <= PART_HEADER {
            return Err((ParamCode::RejectedWrongLength, n as u32));
        }
        if v[0] != kind.code() as f64 {
            return Err((ParamCode::RejectedWrongKind, 0));
        }
        let (Some(offset), Some(total)) = (count(v[1], max), count(v[2], max)) else {
            return Err((ParamCode::RejectedWrongLength, 2));
        };
        let share = &v[PART_HEADER..];
        if offset + share.len() > total {
            return Err((ParamCode::RejectedWrongLength, n as u32));
        }
        Ok(Self {
            offset,
            total,
            share,
        })
    }
}

impl Gather {
    /// Room for a model of `capacity` values.
    pub fn new(capacity: usize) -> Self {
        Self {
            values: Vec::with_capacity(capacity),
            version: 0,
            total: 0,
            refused: None,
        }
    }

    /// Whether `set` is a later part of a model refused already (a first part always starts
    /// a model afresh).
    pub fn is_refused(&self, set: &ParamSet) -> bool {
        self.refused == Some(set.version) && offset_of(set) != Some(0)
    }

    /// Drop the model `set` belongs to (a part failed a check). A stray part of another
    /// version (stale, a trial, a lost model's rest) leaves the model being gathered alone.
    pub fn refuse(&mut self, set: &ParamSet) {
        if self.version == set.version {
            self.values.clear();
            self.total = 0;
        }
        self.refused = Some(set.version);
    }

    /// The index in the whole model of value `i` of part `set` (a value of the header: `i`).
    pub fn model_index(set: &ParamSet, i: u32) -> u32 {
        match offset_of(set) {
            Some(o) if i as usize >= PART_HEADER => (o + i as usize - PART_HEADER) as u32,
            _ => i,
        }
    }

    /// Add `set`, a part of a model of `kind` (finite and newer than the set in service already
    /// checked): the whole model at its last part, or the refusal that drops it.
    pub fn add(
        &mut self,
        set: &ParamSet,
        kind: ParamKind,
    ) -> Result<Gathered<'_>, (ParamCode, u32)> {
        if self.is_refused(set) {
            return Ok(Gathered::Dropped);
        }
        let dropped = match self.place(set, kind) {
            Ok(dropped) => dropped,
            Err(e) => {
                self.refuse(set);
                return Err(e);
            }
        };
        if self.values.len() < self.total {
            return Ok(Gathered::Incomplete { dropped });
        }
        self.total = 0;
        Ok(Gathered::Whole(&self.values))
    }

    /// Append `set`'s share once its header agrees with the parts before it (a first part,
    /// offset 0, starts a model afresh): the version of a half-gathered model that start
    /// displaced.
    fn place(&mut self, set: &ParamSet, kind: ParamKind) -> Result<Option<u64>, (ParamCode, u32)> {
        let h = Header::read(set, kind, self.values.capacity())?;
        let mut dropped = None;
        if h.offset == 0 {
            if self.total > 0 && self.version != set.version {
                // Its remaining parts, if they come, are dropped without a second event.
                dropped = Some(self.version);
                self.refused = dropped;
            } else if self.refused == Some(set.version) {
                self.refused = None;
            }
            self.values.clear();
            (self.version, self.total) = (set.version, h.total);
        } else if (self.version, self.total, self.values.len()) != (set.version, h.total, h.offset)
        {
            return Err((ParamCode::RejectedPartMissing, 1));
        }
        self.values.extend_from_slice(h.share);
        Ok(dropped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{MAX_PARAMS, PART_VALUES};

    fn model(len: usize) -> Vec<f64> {
        (0..len).map(|i| i as f64 * 0.5 - 7.0).collect()
    }

    fn parts(version: u64, values: &[f64]) -> Vec<ParamSet> {
        ParamSet::model_sets(version, 0, f64::NAN, ParamKind::RkgnnModel, values)
    }

    /// What one part did, as a test compares it.
    #[derive(Debug, PartialEq)]
    enum Out {
        /// Gathered; the version of a model it displaced.
        Part(Option<u64>),
        Whole(Vec<f64>),
        Dropped,
        Refused(ParamCode),
    }

    fn gather(g: &mut Gather, sets: &[ParamSet]) -> Vec<Out> {
        sets.iter()
            .map(|s| match g.add(s, ParamKind::RkgnnModel) {
                Ok(Gathered::Incomplete { dropped }) => Out::Part(dropped),
                Ok(Gathered::Whole(v)) => Out::Whole(v.to_vec()),
                Ok(Gathered::Dropped) => Out::Dropped,
                Err((code, _)) => Out::Refused(code),
            })
            .collect()
    }

    #[test]
    fn a_model_of_any_length_is_whole_again_bit_for_bit_at_its_last_part() {
        for len in [MAX_PARAMS + 1, 2 * PART_VALUES, 3396] {
            let m = model(len);
            let sets = parts(4, &m);
            assert_eq!(sets.len(), ParamSet::model_set_count(len));
            assert!(sets
                .iter()
                .all(|s| s.param_kind() == Ok(ParamKind::ModelPart)));
            let mut g = Gather::new(len);
            let mut out = gather(&mut g, &sets);
            assert_eq!(out.pop(), Some(Out::Whole(m)));
            assert!(out.iter().all(|o| *o == Out::Part(None)));
        }
        // A model that fits one set travels as that set.
        let sets = parts(1, &model(MAX_PARAMS));
        assert_eq!(sets.len(), 1);
        assert_eq!(sets[0].param_kind(), Ok(ParamKind::RkgnnModel));
    }

    #[test]
    fn a_lost_part_drops_the_model_in_one_refusal_and_the_next_model_still_arrives() {
        let m = model(3000);
        let sets = parts(2, &m);
        assert_eq!(sets.len(), 3);
        let mut g = Gather::new(3000);
        let out = gather(&mut g, &[sets[0], sets[2]]);
        assert_eq!(
            out,
            [
                Out::Part(None),
                Out::Refused(ParamCode::RejectedPartMissing)
            ]
        );
        // Its other parts are dropped without a second event.
        assert_eq!(gather(&mut g, &sets[1..2]), [Out::Dropped]);
        let next = parts(3, &m);
        assert_eq!(gather(&mut g, &next).pop(), Some(Out::Whole(m.clone())));
        // A model whose last parts never came is refused when the next one starts, once.
        let (late, next) = (parts(4, &m), parts(5, &m));
        let out = gather(&mut g, &[late[0], next[0], late[1], next[1], next[2]]);
        let want = [
            Out::Part(None),
            Out::Part(Some(4)),
            Out::Dropped,
            Out::Part(None),
        ];
        assert_eq!(out[..4], want);
        assert_eq!(out[4], Out::Whole(m));
    }

    #[test]
    fn a_stray_part_of_another_version_leaves_the_model_being_gathered_alone() {
        let (a, b) = (
            model(2500),
            model(2500).iter().map(|x| -x).collect::<Vec<_>>(),
        );
        let (pa, pb) = (parts(5, &a), parts(6, &b));
        let mut g = Gather::new(2500);
        // b's first part displaces a, whose second part is then dropped silently; b completes.
        let out = gather(&mut g, &[pa[0], pb[0], pa[1], pb[1], pb[2]]);
        assert_eq!(
            out[..3],
            [Out::Part(None), Out::Part(Some(5)), Out::Dropped]
        );
        assert_eq!(out[3..], [Out::Part(None), Out::Whole(b)]);
        // A part refused by the cycle's common checks (stale, say) of another version.
        let pc = parts(7, &a);
        gather(&mut g, &pc[..1]);
        g.refuse(&parts(3, &a)[1]);
        assert_eq!(gather(&mut g, &pc[1..]).pop(), Some(Out::Whole(a.clone())));
        // A version refused once may come again whole (an optimiser restarted).
        g.refuse(&pc[0]);
        assert_eq!(gather(&mut g, &pc).pop(), Some(Out::Whole(a)));
    }

    #[test]
    fn a_header_that_lies_is_refused() {
        let m = model(2000);
        let mut g = Gather::new(2000);
        let mut wrong_kind = parts(1, &m)[0];
        wrong_kind.values[0] = ParamKind::RigidBodyModel.code() as f64;
        let refused = |c| vec![Out::Refused(c)];
        assert_eq!(
            gather(&mut g, &[wrong_kind]),
            refused(ParamCode::RejectedWrongKind)
        );
        // Longer than the law's largest model, or a fractional offset.
        let mut g = Gather::new(1999);
        let first = parts(2, &m)[0];
        assert_eq!(
            gather(&mut g, &[first]),
            refused(ParamCode::RejectedWrongLength)
        );
        let mut g = Gather::new(2000);
        let mut half = parts(3, &m)[1];
        half.values[1] += 0.5;
        assert_eq!(
            gather(&mut g, &[half]),
            refused(ParamCode::RejectedWrongLength)
        );
        // A part's value index in the whole model.
        let second = parts(4, &m)[1];
        assert_eq!(Gather::model_index(&second, 3), PART_VALUES as u32);
        assert_eq!(Gather::model_index(&second, 1), 1);
    }
}
