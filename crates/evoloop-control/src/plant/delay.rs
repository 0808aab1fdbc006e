//! A delay line: what a signal `len` samples late reads. One home for the sensor's delay in the
//! simulated plant (`PlantSim::delaying`) and the inputs the estimators predict across
//! (`law::estimator`).

/// The last `len` values pushed, in a ring allocated once (`new`, off the control cycle):
/// `push` is allocation-free.
#[derive(Debug, Clone)]
pub struct DelayLine<T> {
    values: Vec<T>,
    /// The oldest value, the next to be replaced.
    head: usize,
}

impl<T: Copy> DelayLine<T> {
    /// `len` samples of delay, every one `fill` until pushed over.
    pub fn new(len: usize, fill: T) -> Self {
        Self {
            values: vec![fill; len],
            head: 0,
        }
    }

    /// The delay, samples.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Whether the line has no delay (`push` gives back what it is given).
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// Put `v` in and take out the value pushed `len` pushes before (`v` itself without delay).
    pub fn push(&mut self, v: T) -> T {
        let Some(slot) = self.values.get_mut(self.head) else {
            return v;
        };
        let oldest = std::mem::replace(slot, v);
        self.head = (self.head + 1) % self.values.len();
        oldest
    }

    /// Every value in the line `v` (a signal held over a gap).
    pub fn fill(&mut self, v: T) {
        self.values.fill(v);
    }

    /// The `i`-th value, oldest first (`i < len`).
    pub fn get(&self, i: usize) -> T {
        self.values[(self.head + i) % self.values.len()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_push_returns_the_value_of_len_pushes_before_and_get_reads_oldest_first() {
        let mut line = DelayLine::new(3, -1);
        let out: Vec<i32> = (0..6).map(|v| line.push(v)).collect();
        assert_eq!(out, [-1, -1, -1, 0, 1, 2]);
        assert_eq!((0..3).map(|i| line.get(i)).collect::<Vec<_>>(), [3, 4, 5]);
        let mut none = DelayLine::new(0, 0);
        assert_eq!(none.push(7), 7);
        assert!(none.is_empty());
    }
}
