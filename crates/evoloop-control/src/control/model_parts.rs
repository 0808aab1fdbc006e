//! A model larger than one parameter set, gathered from its parts (`ParamKind::ModelPart`, made
//! by `ParamSet::model_sets`) so that the law checks and applies it whole, as one set: a part
//! that comes without the parts before it drops the model, and none of a partial model is ever
//! in service. The buffer is allocated once, at the law's largest model; gathering never
//! allocates.

use crate::msg::{ParamCode, ParamKind, ParamSet, PART_HEADER};

/// What a part added up to.
pub enum Gathered<'a> {
    /// More parts to come.
    Incomplete,
    /// The last part: the whole model's values.
    Whole(&'a [f64]),
    /// A later part of a model already refused (refused once, in one event).
    Dropped,
}

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

    /// Whether `set` belongs to a model refused already.
    pub fn is_refused(&self, set: &ParamSet) -> bool {
        self.refused == Some(set.version)
    }

    /// Drop the model `set` belongs to (a part failed the common checks).
    pub fn refuse(&mut self, set: &ParamSet) {
        self.values.clear();
        self.total = 0;
        self.refused = Some(set.version);
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
        match self.check(set, kind) {
            Ok(chunk) => {
                self.values.extend_from_slice(chunk);
                if self.values.len() < self.total {
                    return Ok(Gathered::Incomplete);
                }
                self.total = 0;
                Ok(Gathered::Whole(&self.values))
            }
            Err(e) => {
                self.refuse(set);
                Err(e)
            }
        }
    }

    /// `set`'s share of the model, once its header agrees with the parts before it (a first
    /// part, offset 0, starts a model afresh).
    fn check<'s>(
        &mut self,
        set: &'s ParamSet,
        kind: ParamKind,
    ) -> Result<&'s [f64], (ParamCode, u32)> {
        let v = set.values();
        let n = v.len();
        if n <= PART_HEADER {
            return Err((ParamCode::RejectedWrongLength, n as u32));
        }
        if v[0] != kind.code() as f64 {
            return Err((ParamCode::RejectedWrongKind, 0));
        }
        let cap = self.values.capacity();
        let (Some(offset), Some(total)) = (count(v[1], cap), count(v[2], cap)) else {
            return Err((ParamCode::RejectedWrongLength, 2));
        };
        let chunk = &v[PART_HEADER..];
        if offset + chunk.len() > total {
            return Err((ParamCode::RejectedWrongLength, n as u32));
        }
        if offset == 0 {
            self.values.clear();
            (self.version, self.total) = (set.version, total);
        } else if (self.version, self.total, self.values.len()) != (set.version, total, offset) {
            return Err((ParamCode::RejectedPartMissing, 1));
        }
        Ok(chunk)
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

    /// Feed `sets` in order; the whole model if one completed.
    fn gather(g: &mut Gather, sets: &[ParamSet]) -> Vec<Result<Option<Vec<f64>>, ParamCode>> {
        sets.iter()
            .map(|s| match g.add(s, ParamKind::RkgnnModel) {
                Ok(Gathered::Whole(v)) => Ok(Some(v.to_vec())),
                Ok(_) => Ok(None),
                Err((code, _)) => Err(code),
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
            let out = gather(&mut g, &sets);
            let (last, before) = out.split_last().unwrap();
            assert!(before.iter().all(|r| *r == Ok(None)));
            assert_eq!(*last, Ok(Some(m)));
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
        assert_eq!(out, vec![Ok(None), Err(ParamCode::RejectedPartMissing)]);
        // Its other parts are dropped without a second event.
        assert_eq!(gather(&mut g, &sets[1..2]), vec![Ok(None)]);
        let next = parts(3, &m);
        assert_eq!(gather(&mut g, &next).pop().unwrap(), Ok(Some(m)));
    }

    #[test]
    fn parts_of_two_models_interleaved_are_refused_not_mixed() {
        let (a, b) = (
            model(2500),
            model(2500).iter().map(|x| -x).collect::<Vec<_>>(),
        );
        let (pa, pb) = (parts(5, &a), parts(6, &b));
        let mut g = Gather::new(2500);
        let out = gather(&mut g, &[pa[0], pb[0], pa[1]]);
        // b's first part restarts the gathering; a's second no longer fits.
        assert_eq!(
            out,
            vec![Ok(None), Ok(None), Err(ParamCode::RejectedPartMissing)]
        );
        // b's rest completes nothing now: its gathering was dropped with a's refusal.
        assert_eq!(
            gather(&mut g, &pb[1..])[0],
            Err(ParamCode::RejectedPartMissing)
        );
    }

    #[test]
    fn a_header_that_lies_is_refused() {
        let m = model(2000);
        let mut g = Gather::new(2000);
        let mut wrong_kind = parts(1, &m)[0];
        wrong_kind.values[0] = ParamKind::RigidBodyModel.code() as f64;
        assert_eq!(
            gather(&mut g, &[wrong_kind]),
            vec![Err(ParamCode::RejectedWrongKind)]
        );
        // Longer than the law's largest model, or a fractional offset.
        let mut g = Gather::new(1999);
        assert_eq!(
            gather(&mut g, &parts(2, &m)[..1]),
            vec![Err(ParamCode::RejectedWrongLength)]
        );
        let mut g = Gather::new(2000);
        let mut half = parts(3, &m)[1];
        half.values[1] += 0.5;
        assert_eq!(
            gather(&mut g, &[half]),
            vec![Err(ParamCode::RejectedWrongLength)]
        );
    }
}
