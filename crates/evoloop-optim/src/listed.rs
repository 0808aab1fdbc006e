//! An "optimiser" that tries a fixed list of sets, one per `ask`, in order: how a model's trials
//! are predicted (the direct scheme's `safe_bayes_model`) and how a test chooses what runs before
//! what.

use crate::Optimiser;

/// Tries `sets` one per `ask`, in order, keeping the best; converged once every set has
/// been asked for.
pub struct Listed {
    sets: Vec<Vec<f64>>,
    next: usize,
    asked: Vec<Vec<f64>>,
    best: (Vec<f64>, f64),
}

impl Listed {
    /// An optimiser that will try `sets` in the order given.
    pub fn new(sets: Vec<Vec<f64>>) -> Self {
        Self {
            sets,
            next: 0,
            asked: Vec::new(),
            best: (Vec::new(), f64::INFINITY),
        }
    }
}

impl Optimiser for Listed {
    fn ask(&mut self) -> &[Vec<f64>] {
        self.asked = self.sets.get(self.next).cloned().into_iter().collect();
        self.next += 1;
        &self.asked
    }
    fn candidates(&self) -> &[Vec<f64>] {
        &self.asked
    }
    fn tell(&mut self, values: &[f64]) {
        if values[0] < self.best.1 {
            self.best = (self.asked[0].clone(), values[0]);
        }
    }
    fn best(&self) -> (&[f64], f64) {
        (&self.best.0, self.best.1)
    }
    fn generation(&self) -> usize {
        self.next
    }
    fn evaluations(&self) -> usize {
        self.next
    }
    fn converged(&self) -> bool {
        self.next >= self.sets.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn asks_each_set_once_in_order_and_keeps_the_best() {
        let mut l = Listed::new(vec![vec![1.0], vec![2.0]]);
        assert_eq!(l.ask(), &[vec![1.0]]);
        l.tell(&[5.0]);
        assert!(!l.converged());
        assert_eq!(l.ask(), &[vec![2.0]]);
        l.tell(&[3.0]);
        assert!(l.converged());
        assert_eq!(l.best(), (&[2.0][..], 3.0));
        assert!(l.ask().is_empty());
    }
}
