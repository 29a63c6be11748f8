//! The log of refused messages: each reason at once, then every 30 s with its count.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// How often a reason already logged for a topic is logged again, with the count since.
pub(super) const REASON_EVERY: Duration = Duration::from_secs(30);
/// Reasons remembered per topic; further new reasons share one entry (bounded memory).
pub(super) const MAX_REASONS: usize = 32;

/// The reasons messages of one input were refused: each distinct reason (its text with the
/// numbers left out) is logged when first seen, then at most once every [`REASON_EVERY`] with
/// the count refused for it since, so no reason vanishes from the log and none floods it.
#[derive(Default)]
pub(super) struct Throttle {
    /// Messages refused.
    pub(super) total: u64,
    pub(super) reasons: BTreeMap<String, Reason>,
}

pub(super) struct Reason {
    pub(super) logged: Instant,
    pub(super) since: u64,
    pub(super) last: String,
}

/// `message` without its numbers (`value 1.5 is not in [0, 1]` → `value # is not in [#, #]`):
/// what makes two refusals the same reason.
pub(super) fn reason_key(message: &str) -> String {
    let mut key = String::with_capacity(message.len());
    let mut in_number = false;
    let mut chars = message.chars().peekable();
    while let Some(c) = chars.next() {
        let sign = c == '-' && !in_number && chars.peek().is_some_and(char::is_ascii_digit);
        if sign || c.is_ascii_digit() || (in_number && c == '.') {
            if !in_number {
                key.push('#');
                in_number = true;
            }
        } else {
            in_number = false;
            key.push(c);
        }
    }
    key
}

impl Throttle {
    /// A refusal at `now`: the line to log, if any.
    pub(super) fn note(&mut self, message: String, now: Instant) -> Option<String> {
        self.total += 1;
        let mut key = reason_key(&message);
        if !self.reasons.contains_key(&key) && self.reasons.len() >= MAX_REASONS {
            key = String::from("(other reasons)");
        }
        match self.reasons.get_mut(&key) {
            None => {
                self.reasons.insert(
                    key,
                    Reason {
                        logged: now,
                        since: 0,
                        last: message.clone(),
                    },
                );
                Some(message)
            }
            Some(r) => {
                r.since += 1;
                r.last = message;
                (now.duration_since(r.logged) >= REASON_EVERY).then(|| r.summary(now))
            }
        }
    }

    /// Lines for reasons with refusals not logged for [`REASON_EVERY`] (or for all of them,
    /// with `all`, when the node stops).
    pub(super) fn due(&mut self, now: Instant, all: bool) -> Vec<String> {
        self.reasons
            .values_mut()
            .filter(|r| r.since > 0 && (all || now.duration_since(r.logged) >= REASON_EVERY))
            .map(|r| r.summary(now))
            .collect()
    }

    /// Logs a refusal of a message of `topic`.
    pub(super) fn error(&mut self, topic: &str, message: impl FnOnce() -> String) {
        if let Some(line) = self.note(message(), Instant::now()) {
            log::error!("{topic}: {line}");
        }
    }
}

impl Reason {
    pub(super) fn summary(&mut self, now: Instant) -> String {
        let line = format!(
            "{} more refused for the same reason in the last {:.0} s (the last: {})",
            self.since,
            now.duration_since(self.logged).as_secs_f64(),
            self.last
        );
        self.since = 0;
        self.logged = now;
        line
    }
}

/// Logs the summaries that are due.
pub(super) fn log_due(throttles: &mut BTreeMap<String, Throttle>, all: bool) {
    let now = Instant::now();
    for (topic, t) in throttles.iter_mut() {
        for line in t.due(now, all) {
            log::error!("{topic}: {line}");
        }
    }
}

/// The throttle of `topic`'s error messages.
pub(super) fn throttle<'t>(
    throttles: &'t mut BTreeMap<String, Throttle>,
    topic: &str,
) -> &'t mut Throttle {
    throttles.entry(topic.to_string()).or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn every_reason_is_logged_first_and_then_every_30_s_with_its_count() {
        let mut t = Throttle::default();
        let start = Instant::now();
        let at = |s: u64| start + Duration::from_secs(s);
        // Values differ, the reason is the same.
        assert_eq!(
            t.note("value 1.5 is not in [0, 1]".into(), at(0))
                .as_deref(),
            Some("value 1.5 is not in [0, 1]")
        );
        assert_eq!(t.note("value 2 is not in [0, 1]".into(), at(1)), None);
        // A sixth, seventh, ... reason still reaches the log at once.
        for k in 0..6 {
            let message = format!(
                "frame \"f{}\" is not \"map\"",
                ["a", "b", "c", "d", "e", "f"][k]
            );
            assert_eq!(t.note(message.clone(), at(2)), Some(message));
        }
        assert_eq!(t.note("value -3 is not in [0, 1]".into(), at(10)), None);
        // Nothing is due before 30 s; then one line with the count and the last message.
        assert!(t.due(at(29), false).is_empty());
        assert_eq!(
            t.due(at(30), false),
            [
                "2 more refused for the same reason in the last 30 s (the last: value -3 is not in [0, 1])"
            ]
        );
        assert!(t.due(at(31), false).is_empty());
        // A repeat 30 s after the last line is logged with its count at once.
        t.note("value 7 is not in [0, 1]".into(), at(45));
        assert_eq!(
            t.note("value 8 is not in [0, 1]".into(), at(61)).as_deref(),
            Some(
                "2 more refused for the same reason in the last 31 s (the last: value 8 is not in [0, 1])"
            )
        );
        assert_eq!(t.total, 11);
        // At the end, whatever is left is logged.
        t.note("value 9 is not in [0, 1]".into(), at(62));
        assert_eq!(t.due(at(62), true).len(), 1);
        assert_eq!(
            reason_key("30 x 20 cells is more than max_map_cells (16.5)"),
            "# x # cells is more than max_map_cells (#)"
        );
    }
    #[test]
    fn distinct_reasons_are_bounded() {
        let mut t = Throttle::default();
        let now = Instant::now();
        for k in 0..100 {
            t.note(
                format!("frame \"{}\" is not \"map\"", "x".repeat(k + 1)),
                now,
            );
        }
        assert_eq!(t.reasons.len(), MAX_REASONS + 1);
        assert_eq!(t.total, 100);
    }
}
