//! The node's time: simulated time from `/clock`, the system clock, and schedules.

use ros2_client::MessageInfo;
use std::collections::VecDeque;

/// How long the node waits, with `use_sim_time`, before it takes a received message as
/// ordered with the `/clock` messages received before it: RustDDS stamps a sample when it
/// arrives and stores it a moment later, so a clock sample stamped earlier than a state may
/// still be on its way into its reader when the state is taken.
pub(super) const SIM_LATENCY_NS: i64 = 200_000_000;

/// Simulated time as received on `/clock`: values by RustDDS receive time.
///
/// A state has no stamp: it is observed at the node's time when it was received. With the
/// system clock that is the time RustDDS received it. With `use_sim_time` it is the last
/// `/clock` value received before it, so a state published right after a clock message is
/// stamped with that clock even when both are taken in the same round. The node acts on what
/// was received up to [`SIM_LATENCY_NS`] ago (the cutoff): states received before it are
/// learned, and its time for publishing is the clock at the cutoff.
#[derive(Default)]
pub(super) struct SimClock {
    /// The value before the first entry of `history`.
    pub(super) base: Option<f64>,
    /// Receive time (ns) and value, in receive order.
    pub(super) history: VecDeque<(i64, f64)>,
}

impl SimClock {
    /// The clock when something was received at `received` (ns).
    pub(super) fn at(&self, received: i64) -> Option<f64> {
        self.history
            .iter()
            .rev()
            .find(|&&(at, _)| at <= received)
            .map(|&(_, t)| t)
            .or(self.base)
    }

    pub(super) fn push(&mut self, received: i64, value: f64) {
        let at = self.history.partition_point(|&(r, _)| r <= received);
        self.history.insert(at, (received, value));
    }

    /// Forgets what no message received at or after `received` needs.
    pub(super) fn forget_before(&mut self, received: i64) {
        while self.history.len() > 1 && self.history[1].0 <= received {
            self.base = self.history.pop_front().map(|(_, t)| t);
        }
    }
}

/// A state received with `use_sim_time`, waiting for the cutoff.
pub(super) struct Pending {
    /// The state input (topic) it arrived on.
    pub(super) input: usize,
    pub(super) received: i64,
    pub(super) value: f64,
}

/// When RustDDS received a sample (ns since the unix epoch), or now if it does not say.
pub(super) fn received_ns(info: &MessageInfo) -> i64 {
    info.received_timestamp()
        .map_or_else(system_now_ns, |r| r.to_nanos())
}

/// Now as RustDDS stamps receive times (ns since the unix epoch).
pub(super) fn system_now_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
}

/// When something is due next, in the node's time.
#[derive(Default)]
pub(super) struct Schedule {
    pub(super) next: Option<f64>,
}

impl Schedule {
    /// Whether it is due at `now`; if so, the next time is `now + period`. A clock that went
    /// back (a restarted simulation) makes it due at once.
    pub(super) fn due(&mut self, now: f64, period: f64) -> bool {
        match self.next {
            Some(next) if now < next && next - now <= period => false,
            _ => {
                self.next = Some(now + period);
                true
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn a_state_gets_the_last_clock_received_before_it() {
        let mut clock = SimClock::default();
        assert_eq!(clock.at(5), None);
        clock.push(10, 100.0);
        clock.push(30, 300.0);
        clock.push(20, 200.0); // stored in receive order
        assert_eq!(
            [clock.at(5), clock.at(10), clock.at(25), clock.at(99)],
            [None, Some(100.0), Some(200.0), Some(300.0)]
        );
        // Forgetting keeps what a message received at or after 25 needs.
        clock.forget_before(25);
        assert_eq!(clock.history.len(), 2);
        assert_eq!([clock.at(25), clock.at(30)], [Some(200.0), Some(300.0)]);
        assert_eq!(clock.at(0), Some(100.0));
        clock.forget_before(1000);
        assert_eq!((clock.history.len(), clock.at(1000)), (1, Some(300.0)));
    }
    #[test]
    fn schedules_run_once_per_period_and_at_once_after_the_clock_went_back() {
        let mut s = Schedule::default();
        let due: Vec<bool> = [0.0, 0.5, 1.0, 1.2, 2.5, 2.9, 3.5, 0.1, 0.2]
            .iter()
            .map(|&t| s.due(t, 1.0))
            .collect();
        assert_eq!(
            due,
            [true, false, true, false, true, false, true, true, false]
        );
    }
}
