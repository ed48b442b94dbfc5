//! The bounded queue between the bus and the broker, and what the broker has not yet taken.
//!
//! Samples wait here while the broker cannot be reached; past the queue's size the oldest is
//! dropped and counted. A message handed to the client stays *in flight* until the broker
//! acknowledges it (QoS 1) or it is written (QoS 0); when the connection breaks, the samples
//! in flight go back to the front of the queue, in order, so a broker restart loses none of
//! what fits in the queue (a sample may then arrive twice: QoS 1 is at least once).

use std::collections::VecDeque;

use rumqttc::QoS;

use crate::text::excerpt;

/// What a message is for, which decides what a broken connection does to it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    /// A sample: queued within the bound, dropped oldest first, sent again after a break.
    Sample,
    /// Availability and discovery: recomputed and published again at every connection, so a
    /// copy waiting from before is dropped.
    Announce,
    /// An answer to a write (`…/error`, a read-back): kept and sent after a break.
    Reply,
    /// A register's state for Home Assistant (retained): one per topic (a newer one
    /// replaces it), kept and sent after a break unless a newer one waits.
    State,
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

/// The largest packet the client sends (discovery configurations are a few kilobytes); a
/// message that would make a larger one is dropped and counted rather than handed over,
/// since the client would break the connection on it (and it would be sent again forever).
pub(crate) const MAX_PACKET: usize = 256 * 1024;

/// Answers to writes (`…/error`, read-backs) kept waiting at most; past it the oldest is
/// dropped and counted, so a flood of refused writes cannot flood the outbox.
pub const REPLY_QUEUE: usize = 64;

impl Message {
    /// The size of the PUBLISH packet it makes (fixed header with up to 4 bytes of length,
    /// the topic's length and bytes, a packet id at QoS 1, the payload).
    fn packet_size(&self) -> usize {
        let id = if self.qos == QoS::AtMostOnce { 0 } else { 2 };
        1 + 4 + 2 + self.topic.len() + id + self.payload.len()
    }
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
    /// Writes (`/set`, `/do`) handed to the bus.
    pub writes_taken: u64,
    /// Writes refused because their payload was over [`MAX_WRITE_PAYLOAD`](crate::MAX_WRITE_PAYLOAD).
    pub writes_too_large: u64,
    /// Writes refused as busy: [`WRITE_QUEUE`](crate::WRITE_QUEUE) writes were already
    /// waiting, or the line's queue for MQTT was full.
    pub writes_busy: u64,
    /// Writes refused because they came with the retain flag (a retained command would run
    /// again at every connection).
    pub writes_retained: u64,
    /// Answers to writes dropped, oldest first, because [`REPLY_QUEUE`] were waiting.
    pub replies_dropped: u64,
    /// Messages dropped unsent because their packet would be over the client's limit.
    pub oversize_dropped: u64,
    /// Connections the client broke because the broker sent a packet over its incoming limit
    /// ([`MAX_INCOMING_PACKET`](crate::MAX_INCOMING_PACKET)).
    pub incoming_too_large: u64,
    /// Times Home Assistant announced itself (`online` on its status topic).
    pub homeassistant_births: u64,
    /// Of those, the ones that asked for discovery while a re-announcement was already
    /// waiting: folded into it.
    pub rediscoveries_coalesced: u64,
    /// Control messages (announcements and answers) waiting now.
    pub control_queued: usize,
    /// The most control messages that ever waited at once.
    pub control_peak: usize,
    /// States the broker took on the state topics Home Assistant reads.
    pub states_published: u64,
    /// Samples that never reached a state topic: a newer one came within its interval
    /// (`state_every`). The sample topics carried them.
    pub states_skipped: u64,
    /// Reads made for the state topics (at start and at each refresh).
    pub state_reads: u64,
    /// Of those, the ones the line refused as busy (its queue for MQTT was full): tried
    /// again at the next refresh.
    pub state_reads_busy: u64,
    /// Of those, the ones the device or the line failed (the rest of that device's reads
    /// wait for the next refresh).
    pub state_reads_failed: u64,
    /// Of the reads, the ones made at once because another path (the console, the gateway,
    /// the program's handle) wrote the control.
    pub state_reads_after_writes: u64,
    /// Writes of a control by another path that found its read already due (one read
    /// serves them all).
    pub state_rereads_coalesced: u64,
}

#[derive(Debug)]
pub(crate) struct Outbox {
    capacity: usize,
    /// Status, availability and discovery: one per topic (a newer one replaces it).
    announcements: VecDeque<Message>,
    /// Discovery to publish again once the announcements waiting are out; at most one.
    rediscovery: Option<Vec<Message>>,
    /// Answers to writes, at most [`REPLY_QUEUE`].
    replies: VecDeque<Message>,
    /// States: one per topic (a newer one replaces it), so at most one per state topic.
    states: VecDeque<Message>,
    samples: VecDeque<Message>,
    in_flight: VecDeque<(Option<u16>, Message)>,
    pub(crate) counts: Counts,
    /// Whether a message over the packet limit was said on the log yet.
    warned_oversize: bool,
}

impl Outbox {
    pub(crate) fn new(capacity: usize) -> Self {
        Self {
            capacity: capacity.max(1),
            announcements: VecDeque::new(),
            rediscovery: None,
            replies: VecDeque::new(),
            states: VecDeque::new(),
            samples: VecDeque::new(),
            in_flight: VecDeque::new(),
            counts: Counts::default(),
            warned_oversize: false,
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
            Kind::Announce => {
                // Retained state: only the newest of a topic matters.
                match self
                    .announcements
                    .iter_mut()
                    .find(|waiting| waiting.topic == message.topic)
                {
                    Some(waiting) => *waiting = message,
                    None => self.announcements.push_back(message),
                }
            }
            Kind::Reply => {
                if self.replies.len() >= REPLY_QUEUE {
                    self.replies.pop_front();
                    self.counts.replies_dropped += 1;
                }
                self.replies.push_back(message);
            }
            Kind::State => match self
                .states
                .iter_mut()
                .find(|waiting| waiting.topic == message.topic)
            {
                Some(waiting) => *waiting = message,
                None => self.states.push_back(message),
            },
        }
        self.note_control_peak();
    }

    /// Home Assistant came online: `configs` are published again after the announcements
    /// waiting, unless a re-announcement already waits (then this one is folded into it).
    pub(crate) fn rediscover(&mut self, configs: &[Message]) {
        self.counts.homeassistant_births += 1;
        if self.rediscovery.is_some() {
            self.counts.rediscoveries_coalesced += 1;
        } else {
            self.rediscovery = Some(configs.to_vec());
            self.note_control_peak();
        }
    }

    fn control_len(&self) -> usize {
        self.announcements.len()
            + self.replies.len()
            + self.rediscovery.as_ref().map_or(0, Vec::len)
    }

    fn note_control_peak(&mut self) {
        self.counts.control_peak = self.counts.control_peak.max(self.control_len());
    }

    /// The next message to hand to the client (announcements, then answers to writes, then
    /// states, then samples), kept in flight; none while disconnected. A message whose packet would be
    /// over the client's limit is dropped and counted on the way.
    pub(crate) fn next(&mut self) -> Option<Message> {
        if !self.counts.connected {
            return None;
        }
        loop {
            if self.announcements.is_empty() {
                if let Some(configs) = self.rediscovery.take() {
                    self.announcements.extend(configs);
                }
            }
            let message = self
                .announcements
                .pop_front()
                .or_else(|| self.replies.pop_front())
                .or_else(|| self.states.pop_front())
                .or_else(|| self.samples.pop_front())?;
            if message.packet_size() > MAX_PACKET {
                self.counts.oversize_dropped += 1;
                if !std::mem::replace(&mut self.warned_oversize, true) {
                    tracing::warn!(
                        topic = %excerpt(&message.topic, 100),
                        bytes = message.payload.len(),
                        "an MQTT message over the packet limit of {MAX_PACKET} bytes is dropped \
                         (counted; said once)"
                    );
                }
                continue;
            }
            self.in_flight.push_back((None, message.clone()));
            return Some(message);
        }
    }

    /// The client could not take the message [`next`](Self::next) gave (its channel was full):
    /// it goes back to the front of its queue.
    pub(crate) fn not_taken(&mut self) {
        if let Some((None, message)) = self.in_flight.pop_back() {
            match message.kind {
                Kind::Sample => self.samples.push_front(message),
                Kind::Announce => self.announcements.push_front(message),
                Kind::Reply => self.replies.push_front(message),
                Kind::State => self.states.push_front(message),
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
        match message.kind {
            Kind::Sample => self.counts.published += 1,
            Kind::State => self.counts.states_published += 1,
            Kind::Announce | Kind::Reply => {}
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
                Kind::Reply => self.replies.push_front(message),
                // Sent again unless a newer state of its topic waits.
                Kind::State => {
                    if !self.states.iter().any(|newer| newer.topic == message.topic) {
                        self.states.push_front(message);
                    }
                }
                Kind::Announce => {}
            }
        }
        self.announcements.clear();
        self.rediscovery = None;
        while self.samples.len() > self.capacity {
            self.samples.pop_front();
            self.counts.dropped += 1;
        }
        while self.replies.len() > REPLY_QUEUE {
            self.replies.pop_front();
            self.counts.replies_dropped += 1;
        }
    }

    /// A connection was made: `announcements` go first.
    pub(crate) fn connected(&mut self, announcements: Vec<Message>) {
        self.counts.connected = true;
        self.counts.connections += 1;
        self.announcements = announcements.into();
        self.rediscovery = None;
        self.note_control_peak();
    }

    pub(crate) fn counts(&self) -> Counts {
        Counts {
            queued: self.samples.len(),
            in_flight: self
                .in_flight
                .iter()
                .filter(|(_, m)| m.kind == Kind::Sample)
                .count(),
            control_queued: self.control_len(),
            ..self.counts
        }
    }

    /// Whether nothing waits and nothing is in flight.
    pub(crate) fn is_idle(&self) -> bool {
        self.control_len() == 0
            && self.states.is_empty()
            && self.samples.is_empty()
            && self.in_flight.is_empty()
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

/// A retained QoS 1 announcement.
pub(crate) fn announce(topic: String, payload: impl Into<Vec<u8>>) -> Message {
    Message {
        topic,
        payload: payload.into(),
        qos: QoS::AtLeastOnce,
        retain: true,
        kind: Kind::Announce,
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

    fn reply(n: usize) -> Message {
        Message {
            topic: format!("r/{n}/error"),
            payload: b"busy".to_vec(),
            qos: QoS::AtLeastOnce,
            retain: false,
            kind: Kind::Reply,
        }
    }

    #[test]
    fn a_message_over_the_packet_limit_is_dropped_and_counted_not_handed_over() {
        let mut outbox = Outbox::new(10);
        outbox.connected(Vec::new());
        let mut huge = reply(1);
        huge.payload = vec![b'x'; MAX_PACKET];
        outbox.push(huge);
        outbox.push(sample(2));
        assert_eq!(topics(&mut outbox), ["t/2"]);
        assert_eq!(outbox.counts().oversize_dropped, 1);
        // Nothing of it is in flight, so a broken connection does not send it again.
        outbox.disconnected();
        outbox.connected(Vec::new());
        assert_eq!(topics(&mut outbox), ["t/2"]);
    }

    #[test]
    fn replies_beyond_their_queue_drop_the_oldest_and_count_it() {
        let mut outbox = Outbox::new(10);
        for n in 0..REPLY_QUEUE + 5 {
            outbox.push(reply(n));
        }
        let counts = outbox.counts();
        assert_eq!(
            (counts.replies_dropped, counts.control_queued),
            (5, REPLY_QUEUE)
        );
        outbox.connected(Vec::new());
        let heard = topics(&mut outbox);
        assert_eq!(heard.len(), REPLY_QUEUE);
        assert_eq!(heard[0], "r/5/error");
    }

    #[test]
    fn home_assistant_births_make_at_most_one_waiting_re_announcement() {
        let configs: Vec<Message> = (0..3)
            .map(|n| announce_on(&format!("ha/{n}/config")))
            .collect();
        let mut outbox = Outbox::new(10);
        outbox.connected(vec![announce_on("status")]);
        for _ in 0..1000 {
            outbox.rediscover(&configs);
        }
        let counts = outbox.counts();
        assert_eq!(counts.homeassistant_births, 1000);
        assert_eq!(counts.rediscoveries_coalesced, 999);
        assert_eq!(counts.control_peak, 4);
        assert_eq!(
            topics(&mut outbox),
            ["status", "ha/0/config", "ha/1/config", "ha/2/config"]
        );
        // A birth after the re-announcement went out asks for another.
        outbox.rediscover(&configs);
        assert_eq!(topics(&mut outbox).len(), 3);
    }

    #[test]
    fn a_newer_announcement_replaces_the_one_waiting_on_its_topic() {
        let mut outbox = Outbox::new(10);
        for n in 0..100u8 {
            let mut availability = announce_on("top/availability");
            availability.payload = vec![n];
            outbox.push(availability);
        }
        assert_eq!(outbox.counts().control_queued, 1);
        outbox.connected(Vec::new());
        outbox.push(announce_on("status"));
        let mut availability = announce_on("top/availability");
        availability.payload = b"online".to_vec();
        outbox.push(availability);
        let waiting: Vec<Message> = std::iter::from_fn(|| outbox.next()).collect();
        assert_eq!(waiting.len(), 2);
        assert_eq!(waiting[1].payload, b"online");
    }

    fn announce_on(topic: &str) -> Message {
        Message {
            topic: topic.to_owned(),
            payload: b"{}".to_vec(),
            qos: QoS::AtLeastOnce,
            retain: true,
            kind: Kind::Announce,
        }
    }
}
