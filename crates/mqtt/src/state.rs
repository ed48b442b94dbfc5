//! The state topics Home Assistant's entities read, `<prefix>/<device>/<register>/state`:
//! retained, each carrying the register's latest value at most once per interval (the bus
//! file's `state_every`), so that a register polled 145 times a second does not make 145
//! states a second in Home Assistant's recorder. The sample topics keep every sample.
//!
//! A sample within the interval of the last state waits as the topic's pending value (a newer
//! one replaces it, counted) and goes out when the interval is over; a value read on purpose
//! (at start, after a write, at each refresh) goes out at once.

use std::collections::HashMap;
use std::time::Duration;

use rumqttc::QoS;
use tokio::time::Instant;

use crate::outbox::{Kind, Message};

/// One state topic.
#[derive(Debug)]
struct Entry {
    every: Duration,
    /// When its last message was handed to the outbox.
    last: Option<Instant>,
    /// The newest sample that came within the interval, waiting for it to end.
    pending: Option<Vec<u8>>,
}

/// Every state topic of a publisher, and its throttle.
#[derive(Debug, Default)]
pub(crate) struct States {
    entries: HashMap<String, Entry>,
    /// Samples replaced by a newer one while they waited: never on the state topic.
    pub(crate) skipped: u64,
}

impl States {
    /// `topic` carries a state, at most one message per `every` (zero: every sample).
    pub(crate) fn add(&mut self, topic: String, every: Duration) {
        let entry = self.entries.entry(topic).or_insert(Entry {
            every,
            last: None,
            pending: None,
        });
        entry.every = entry.every.min(every);
    }

    /// A sample for `topic`: the message to publish now, or none (it waits, or the topic
    /// carries no state).
    pub(crate) fn offer(&mut self, topic: &str, payload: Vec<u8>, now: Instant) -> Option<Message> {
        let entry = self.entries.get_mut(topic)?;
        let due = entry
            .last
            .is_none_or(|last| now.duration_since(last) >= entry.every);
        if due {
            entry.last = Some(now);
            if entry.pending.take().is_some() {
                self.skipped += 1;
            }
            return Some(state(topic, payload));
        }
        if entry.pending.replace(payload).is_some() {
            self.skipped += 1;
        }
        None
    }

    /// A value read on purpose for `topic`: published at once, and newer than any sample
    /// waiting.
    pub(crate) fn now(&mut self, topic: &str, payload: Vec<u8>, now: Instant) -> Option<Message> {
        let entry = self.entries.get_mut(topic)?;
        entry.last = Some(now);
        if entry.pending.take().is_some() {
            self.skipped += 1;
        }
        Some(state(topic, payload))
    }

    /// The waiting samples whose interval is over.
    pub(crate) fn due(&mut self, now: Instant) -> Vec<Message> {
        let mut due = Vec::new();
        for (topic, entry) in &mut self.entries {
            let over = entry
                .last
                .is_none_or(|last| now.duration_since(last) >= entry.every);
            if over {
                if let Some(payload) = entry.pending.take() {
                    entry.last = Some(now);
                    due.push(state(topic, payload));
                }
            }
        }
        due
    }

    /// How often to look for waiting samples whose interval is over: a quarter of the
    /// shortest interval, within 10 ms and 250 ms; none when no topic waits between samples.
    pub(crate) fn tick(&self) -> Option<Duration> {
        let shortest = self
            .entries
            .values()
            .map(|entry| entry.every)
            .filter(|every| !every.is_zero())
            .min()?;
        Some((shortest / 4).clamp(Duration::from_millis(10), Duration::from_millis(250)))
    }
}

/// A retained QoS 1 state.
fn state(topic: &str, payload: Vec<u8>) -> Message {
    Message {
        topic: topic.to_owned(),
        payload,
        qos: QoS::AtLeastOnce,
        retain: true,
        kind: Kind::State,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_within_the_interval_wait_and_the_newest_goes_out_when_it_is_over() {
        let mut states = States::default();
        states.add("s".into(), Duration::from_secs(1));
        let start = Instant::now();
        let at = |ms: u64| start + Duration::from_millis(ms);
        assert!(
            states.offer("s", vec![1], at(0)).is_some(),
            "the first at once"
        );
        for (n, ms) in [(2, 100), (3, 200), (4, 900)] {
            assert!(states.offer("s", vec![n], at(ms)).is_none());
        }
        assert!(states.due(at(999)).is_empty());
        let due = states.due(at(1000));
        assert_eq!(due.len(), 1);
        assert_eq!(due[0].payload, [4]);
        assert!(due[0].retain);
        assert_eq!(states.skipped, 2, "2 and 3 never went out");
        // A read on purpose goes out at once, and replaces a waiting sample.
        assert!(states.offer("s", vec![5], at(1100)).is_none());
        let read = states.now("s", vec![6], at(1200)).unwrap();
        assert_eq!(read.payload, [6]);
        assert!(states.due(at(5000)).is_empty());
        assert!(
            states.offer("other", vec![7], at(0)).is_none(),
            "no such topic"
        );
        assert_eq!(states.tick(), Some(Duration::from_millis(250)));
    }

    #[test]
    fn an_interval_of_zero_passes_every_sample() {
        let mut states = States::default();
        states.add("s".into(), Duration::ZERO);
        let now = Instant::now();
        for n in 0..10 {
            assert!(states.offer("s", vec![n], now).is_some());
        }
        assert_eq!(states.tick(), None);
    }
}
