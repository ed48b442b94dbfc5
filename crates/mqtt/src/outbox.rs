//! The bounded queue between the bus and the broker, and what the broker has not yet taken.
//!
//! Samples wait here while the broker cannot be reached; past the queue's size the oldest is
//! dropped and counted. A message handed to the client stays *in flight* until the broker
//! acknowledges it (QoS 1) or it is written (QoS 0); when the connection breaks, the samples
//! in flight go back to the front of the queue, in order, so a broker restart loses none of
//! what fits in the queue (a sample may then arrive twice: QoS 1 is at least once).

use std::collections::VecDeque;

use rumqttc::QoS;

/// What a message is for, which decides what a broken connection does to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A sample: queued within the bound, dropped oldest first, sent again after a break.
    Sample,
    /// Availability and discovery: recomputed and published again at every connection, so a
    /// copy waiting from before is dropped.
    Announce,
    /// An answer to a write (`…/error`, `…/state`): kept and sent after a break.
    Reply,
}

/// A message to publish.
#[derive(Clone, Debug)]
pub(crate) struct Message {
    pub(crate) topic: String,
    pub(crate) payload: Vec<u8>,
    pub(crate) qos: QoS,
    pub(crate) retain: bool,
    pub(crate) kind: Kind,
}

/// How the publishing went so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Counts {
    /// Samples the broker took (acknowledged at QoS 1, written at QoS 0).
    pub published: u64,
    /// Samples dropped because the queue was full (oldest first).
    pub dropped: u64,
    /// Samples handed to the client again after a broken connection, the broker not having
    /// acknowledged them: some may have reached it before the break (so a subscriber may get
    /// one twice, or get one counted as dropped if the queue overflowed after the break).
    pub requeued: u64,
    /// Samples waiting now.
    pub queued: usize,
    /// Samples handed to the client and not yet taken by the broker.
    pub in_flight: usize,
    /// Connections made to the broker (1 when it never went away).
    pub connections: u64,
    /// Whether the broker is connected now.
    pub connected: bool,
    /// Bus events the publisher fell too far behind to see.
    pub missed_events: u64,
}

#[derive(Debug)]
pub(crate) struct Outbox {
    capacity: usize,
    control: VecDeque<Message>,
    samples: VecDeque<Message>,
    in_flight: VecDeque<(Option<u16>, Message)>,
    pub(crate) counts: Counts,
}

impl Outbox {
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            control: VecDeque::new(),
            samples: VecDeque::new(),
            in_flight: VecDeque::new(),
            counts: Counts::default(),
        }
    }

    pub(crate) fn push(&mut self, message: Message) {
        match message.kind {
            Kind::Sample => {
                if self.samples.len() >= self.capacity {
                    self.samples.pop_front();
                    self.counts.dropped += 1;
                }
                self.samples.push_back(message);
            }
            Kind::Announce | Kind::Reply => self.control.push_back(message),
        }
    }

    /// The next message to hand to the client (availability, discovery and replies before
    /// samples), kept in flight; none while disconnected.
    pub(crate) fn next(&mut self) -> Option<Message> {
        if !self.counts.connected {
            return None;
        }
        let message = self
            .control
            .pop_front()
            .or_else(|| self.samples.pop_front())?;
        self.in_flight.push_back((None, message.clone()));
        Some(message)
    }

    /// The client could not take the message [`next`](Self::next) gave (its channel was full):
    /// it goes back to the front of its queue.
    pub(crate) fn not_taken(&mut self) {
        if let Some((None, message)) = self.in_flight.pop_back() {
            match message.kind {
                Kind::Sample => self.samples.push_front(message),
                Kind::Announce | Kind::Reply => self.control.push_front(message),
            }
        }
    }

    /// Messages handed to the client that it has not written yet.
    pub(crate) fn unwritten(&self) -> usize {
        self.in_flight.iter().filter(|(id, _)| id.is_none()).count()
    }

    /// The client wrote the oldest message handed to it not yet written, as packet `pkid`.
    pub(crate) fn written(&mut self, pkid: u16) {
        let Some(index) = self.in_flight.iter().position(|(id, _)| id.is_none()) else {
            return;
        };
        if self.in_flight[index].1.qos == QoS::AtMostOnce {
            if let Some((_, message)) = self.in_flight.remove(index) {
                self.taken(&message);
            }
        } else {
            self.in_flight[index].0 = Some(pkid);
        }
    }

    /// The broker acknowledged packet `pkid`.
    pub(crate) fn acknowledged(&mut self, pkid: u16) {
        if let Some(index) = self.in_flight.iter().position(|(id, _)| *id == Some(pkid)) {
            if let Some((_, message)) = self.in_flight.remove(index) {
                self.taken(&message);
            }
        }
    }

    fn taken(&mut self, message: &Message) {
        if message.kind == Kind::Sample {
            self.counts.published += 1;
        }
    }

    /// The connection broke: what was in flight goes back to the front of its queue, in
    /// order; announcements are dropped (the next connection publishes them afresh).
    pub(crate) fn disconnected(&mut self) {
        self.counts.connected = false;
        while let Some((_, message)) = self.in_flight.pop_back() {
            match message.kind {
                Kind::Sample => {
                    self.counts.requeued += 1;
                    self.samples.push_front(message);
                }
                Kind::Reply => self.control.push_front(message),
                Kind::Announce => {}
            }
        }
        self.control.retain(|m| m.kind != Kind::Announce);
        while self.samples.len() > self.capacity {
            self.samples.pop_front();
            self.counts.dropped += 1;
        }
    }

    /// A connection was made: `announcements` go first.
    pub(crate) fn connected(&mut self, announcements: Vec<Message>) {
        self.counts.connected = true;
        self.counts.connections += 1;
        self.control.retain(|m| m.kind != Kind::Announce);
        for message in announcements.into_iter().rev() {
            self.control.push_front(message);
        }
    }

    pub(crate) fn counts(&self) -> Counts {
        Counts {
            queued: self.samples.len(),
            in_flight: self
                .in_flight
                .iter()
                .filter(|(_, m)| m.kind == Kind::Sample)
                .count(),
            ..self.counts
        }
    }

    /// Whether nothing waits and nothing is in flight.
    pub(crate) fn is_idle(&self) -> bool {
        self.control.is_empty() && self.samples.is_empty() && self.in_flight.is_empty()
    }
}

/// A QoS 1 sample on topic `t/<n>` with payload `[n]`, for the tests of the queue and of the
/// publisher.
#[cfg(test)]
pub(crate) fn sample(n: u8) -> Message {
    Message {
        topic: format!("t/{n}"),
        payload: vec![n],
        qos: QoS::AtLeastOnce,
        retain: false,
        kind: Kind::Sample,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topics(outbox: &mut Outbox) -> Vec<String> {
        std::iter::from_fn(|| outbox.next().map(|m| m.topic)).collect()
    }

    #[test]
    fn a_full_queue_drops_the_oldest_and_counts_it() {
        let mut outbox = Outbox::new(2);
        outbox.connected(Vec::new());
        for n in 1..=3 {
            outbox.push(sample(n));
        }
        assert_eq!(outbox.counts().dropped, 1);
        assert_eq!(topics(&mut outbox), ["t/2", "t/3"]);
    }

    #[test]
    fn a_message_the_client_could_not_take_is_handed_again_first() {
        let mut outbox = Outbox::new(10);
        outbox.connected(Vec::new());
        for n in 1..=3 {
            outbox.push(sample(n));
        }
        assert_eq!(outbox.next().map(|m| m.topic).as_deref(), Some("t/1"));
        assert_eq!(outbox.next().map(|m| m.topic).as_deref(), Some("t/2"));
        // The client's channel was full for t/2: it is not in flight, and comes next.
        outbox.not_taken();
        assert_eq!(outbox.counts().in_flight, 1);
        assert_eq!(topics(&mut outbox), ["t/2", "t/3"]);
        // The written ones are matched in order: t/1 as packet 1, t/2 as 2, t/3 as 3.
        outbox.written(1);
        outbox.written(2);
        outbox.written(3);
        outbox.acknowledged(2);
        outbox.disconnected();
        outbox.connected(Vec::new());
        assert_eq!(topics(&mut outbox), ["t/1", "t/3"]);
    }

    #[test]
    fn samples_in_flight_go_back_to_the_front_when_the_connection_breaks() {
        let mut outbox = Outbox::new(10);
        outbox.connected(Vec::new());
        for n in 1..=4 {
            outbox.push(sample(n));
        }
        let handed: Vec<String> = (0..3)
            .filter_map(|_| outbox.next())
            .map(|m| m.topic)
            .collect();
        assert_eq!(handed, ["t/1", "t/2", "t/3"]);
        outbox.written(1);
        outbox.written(2);
        outbox.acknowledged(1);
        outbox.disconnected();
        assert_eq!(
            outbox.next().map(|m| m.topic),
            None,
            "nothing while disconnected"
        );
        outbox.connected(Vec::new());
        assert_eq!(topics(&mut outbox), ["t/2", "t/3", "t/4"]);
        assert_eq!(outbox.counts().published, 1);
    }
}
