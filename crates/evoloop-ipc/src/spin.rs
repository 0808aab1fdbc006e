//! How long a wait polls before it blocks on its event, adapted to whether polling pays.
//!
//! In lockstep a peer answers within microseconds when it has a core of its own, far sooner than
//! a wake-up through the event (about 50 µs on the development VM), so a wait polls first
//! (`timing.spin_us`). When the peer has no core to run on (more busy processes than cores: two
//! lockstep runs at once, an optimiser computing beside the loop, a loaded machine), the answer
//! cannot come while this process holds the core, and every poll burns its whole window of CPU
//! that the peer needed: two lockstep studies side by side on two cores took 2.3x as long with a
//! fixed 50 µs poll as with this policy (docs/measurements/2026-12-07-adaptive-poll.md). So a wait
//! whose poll went unanswered makes the next waits at that place skip the poll, for 1, 3, 7, ...
//! up to 63 waits as misses pile up, each miss after a probe doubling the pause and each answered
//! probe halving it. A peer that answers in time keeps every wait polling, as before.
//!
//! The values a lockstep run computes do not depend on how its processes wait: only its wall
//! time does.

use std::time::Duration;

/// The most waits a pause skips the poll for: 2^6 - 1.
const MAX_LEVEL: u32 = 6;

/// The poll policy of one waiting place (a loop's wait for its peer's answer): up to `limit`,
/// or none while polls there go unanswered.
// Not Copy: a copy would carry on the pause apart from the place it belongs to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Spin {
    limit: Duration,
    /// 0 while polls are answered; each unanswered probe raises it, each answered one lowers it.
    level: u32,
    /// Waits left that skip the poll before the next probe.
    skip: u32,
}

impl Spin {
    /// Poll for up to `limit` (`timing.spin_us`) while polling pays.
    pub fn new(limit: Duration) -> Spin {
        Spin {
            limit,
            level: 0,
            skip: 0,
        }
    }

    /// Never poll: block on the event at once.
    pub fn none() -> Spin {
        Spin::new(Duration::ZERO)
    }

    /// How long the next wait polls before blocking.
    pub fn poll(&self) -> Duration {
        if self.skip == 0 {
            self.limit
        } else {
            Duration::ZERO
        }
    }

    /// Record a wait that polled for `polled` (what `poll` said) and got its sample after
    /// `waited`: answered within the poll, it lowers the pause; not, it raises it.
    pub fn record(&mut self, polled: Duration, waited: Duration) {
        if polled.is_zero() {
            self.skip = self.skip.saturating_sub(1);
            return;
        }
        self.level = if waited <= polled {
            self.level.saturating_sub(1)
        } else {
            (self.level + 1).min(MAX_LEVEL)
        };
        self.skip = (1 << self.level) - 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const US: Duration = Duration::from_micros(1);

    /// Whether the next wait skips its poll.
    fn pausing(s: &Spin) -> bool {
        s.poll().is_zero()
    }

    /// Polls answered in time keep every wait polling; one unanswered poll skips the next
    /// wait's; misses in a row double the pause up to 63 waits; answered probes shorten it
    /// again until every wait polls.
    #[test]
    fn the_poll_pauses_after_misses_and_resumes_when_answered() {
        let limit = 50 * US;
        let mut s = Spin::new(limit);
        for _ in 0..100 {
            assert_eq!(s.poll(), limit);
            s.record(s.poll(), 3 * US);
        }
        // One miss: the next wait blocks at once, the one after probes.
        s.record(s.poll(), 400 * US);
        assert_eq!(s.poll(), Duration::ZERO);
        s.record(s.poll(), 400 * US);
        assert_eq!(s.poll(), limit);
        // Misses at every probe: pauses of 3, 7, ... 63 waits, and no longer.
        let mut pauses = Vec::new();
        for _ in 0..8 {
            s.record(s.poll(), 400 * US);
            let mut n = 0;
            while pausing(&s) {
                s.record(s.poll(), 400 * US);
                n += 1;
            }
            pauses.push(n);
        }
        assert_eq!(pauses, [3, 7, 15, 31, 63, 63, 63, 63]);
        // Answered probes: 31, 15, 7, 3, 1, then every wait polls again.
        let mut pauses = Vec::new();
        while {
            s.record(s.poll(), 3 * US);
            pausing(&s)
        } {
            let mut n = 0;
            while pausing(&s) {
                s.record(s.poll(), 400 * US);
                n += 1;
            }
            pauses.push(n);
        }
        assert_eq!(pauses, [31, 15, 7, 3, 1]);
        assert_eq!(s.poll(), limit);
    }

    /// A policy without a poll never polls, whatever the waits took.
    #[test]
    fn none_never_polls() {
        let mut s = Spin::none();
        for waited in [0, 5, 500] {
            s.record(s.poll(), waited * US);
            assert_eq!(s.poll(), Duration::ZERO);
        }
    }
}
