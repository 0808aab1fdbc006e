//! A run's history in bounded memory: a series that keeps every item until it holds `cap`, then
//! drops every other one and keeps one in two from then on, and so on (spacing doubles each
//! time). A run of any length keeps at most `cap` items, evenly spaced over the whole run, plus
//! the latest one exactly. The optimiser's model estimates (10 a second) and tuning epochs go in
//! here: kept in full, they grow with the run's length, which has none on a machine that runs
//! for weeks.

/// A series of at most `cap` items evenly spaced over everything offered, plus the latest one:
/// past `cap`, every other kept item is dropped and the spacing doubles (see the module).
#[derive(Debug, Clone)]
pub struct History<T> {
    items: Vec<T>,
    cap: usize,
    /// Keep one item in `stride` (a power of two).
    stride: u64,
    offered: u64,
    last: Option<T>,
}

impl<T: Clone> History<T> {
    /// `cap` is rounded up to an even number of at least 2, so thinning keeps the spacing even.
    pub fn new(cap: usize) -> Self {
        let cap = cap.max(2).next_multiple_of(2);
        Self {
            items: Vec::new(),
            cap,
            stride: 1,
            offered: 0,
            last: None,
        }
    }

    /// Offer the next item: kept when it falls on the current spacing, always remembered as the
    /// latest. Never holds more than `cap` items.
    pub fn push(&mut self, x: T) {
        if self.offered.is_multiple_of(self.stride) {
            if self.items.len() == self.cap {
                let mut i = 0;
                self.items.retain(|_| {
                    i += 1;
                    i % 2 == 1
                });
                self.stride *= 2;
            }
            if self.offered.is_multiple_of(self.stride) {
                self.items.push(x.clone());
            }
        }
        self.offered += 1;
        self.last = Some(x);
    }

    /// Items offered so far (kept or not).
    pub fn offered(&self) -> u64 {
        self.offered
    }

    /// The latest item offered, kept or not; `None` before the first.
    pub fn last(&self) -> Option<&T> {
        self.last.as_ref()
    }

    /// The kept items, the latest one appended when thinning had left it out.
    pub fn into_vec(mut self) -> Vec<T> {
        if let Some(l) = self.last.take() {
            if !(self.offered - 1).is_multiple_of(self.stride) {
                self.items.push(l);
            }
        }
        self.items
    }
}

#[cfg(test)]
mod tests {
    use super::History;

    #[test]
    fn below_its_cap_it_keeps_everything() {
        let mut h = History::new(8);
        for i in 0..8 {
            h.push(i);
        }
        assert_eq!(h.into_vec(), (0..8).collect::<Vec<_>>());
    }

    #[test]
    fn past_its_cap_it_keeps_an_even_spacing_and_the_latest_item() {
        let mut h = History::new(8);
        for i in 0..1000u64 {
            h.push(i);
        }
        assert_eq!(h.offered(), 1000);
        assert_eq!(h.last(), Some(&999));
        let v = h.into_vec();
        assert!(v.len() <= 9, "{v:?}");
        // Every kept item but the appended last one is on one grid from 0.
        let grid = v[1] - v[0];
        assert!(grid.is_power_of_two() && grid >= 1000 / 8, "{v:?}");
        assert!(
            v[..v.len() - 1]
                .iter()
                .enumerate()
                .all(|(k, x)| *x == k as u64 * grid),
            "{v:?}"
        );
        assert_eq!(*v.last().unwrap(), 999);
    }

    #[test]
    fn memory_stays_bounded_for_any_length() {
        let mut h = History::new(100);
        for i in 0..1_000_000u64 {
            h.push(i);
            assert!(h.items.len() <= 100);
        }
    }
}
