//! The publisher: a task that turns bus events into messages, one that hands them to the MQTT
//! client, and one that drives the connection (reconnecting with backoff).

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use optobus_bus::{BusFile, Event, Follower, Handle, Health, Source, Writer};

use crate::settings::MqttConfig;
use rumqttc::{
    AsyncClient, ConnectionError, Event as MqttEvent, EventLoop, LastWill, MqttOptions, Outgoing,
    Packet, QoS, StateError, TlsConfiguration, Transport,
};
use tokio::sync::broadcast;
use tokio::sync::{mpsc, Notify};
use tokio::task::JoinHandle;

use crate::discovery::{self, measurements};
use crate::homeassistant::{Discovery, Reads, Rereads};
use crate::lock::lock;
use crate::outbox::{announce, Counts, Kind, Message, Outbox, MAX_PACKET};
use crate::payload::sample_json;
use crate::refresh::{refresh, states_due};
use crate::secret::{Secret, SecretError};
use crate::shared::{availability, DeviceState, Shared};
use crate::state::States;
use crate::topics::Topics;
use crate::writes::{Taken, Write, WRITE_QUEUE};

/// The first wait before connecting again; it doubles after each failure.
pub const FIRST_BACKOFF: Duration = Duration::from_millis(100);
/// The longest wait between connection attempts.
pub const MAX_BACKOFF: Duration = Duration::from_secs(30);
/// Requests the MQTT client holds between our queue and the socket.
const CLIENT_CHANNEL: usize = 64;
/// The largest packet the client reads. A larger one (the broker hands over whatever was
/// published on a subscribed topic) makes the client break the connection before reading it;
/// counted, and the next connection is made only after the backoff, which then keeps growing
/// (a retained one comes again at every subscription). Below it, a write's payload over
/// [`MAX_WRITE_PAYLOAD`](crate::MAX_WRITE_PAYLOAD) is refused on `…/error`.
pub const MAX_INCOMING_PACKET: usize = 1024 * 1024;

/// Why publishing could not start.
#[derive(Debug)]
#[non_exhaustive]
pub enum StartError {
    /// The user name or password could not be read.
    Secret(&'static str, SecretError),
    /// The CA file cannot be used.
    Tls(String),
}

impl std::fmt::Display for StartError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Secret(what, error) => write!(f, "MQTT {what}: {error}"),
            Self::Tls(why) => write!(f, "MQTT TLS: {why}"),
        }
    }
}

impl std::error::Error for StartError {}

/// A running MQTT output of a bus. Dropping it stops publishing (the broker then publishes
/// the last will: the process is `offline`); [`Publisher::stop`] says so itself first.
pub struct Publisher {
    shared: Arc<Shared>,
    client: AsyncClient,
    tasks: Vec<JoinHandle<()>>,
}

/// Shows the topics and counts; never the credentials.
impl std::fmt::Debug for Publisher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Publisher")
            .field("prefix", &self.shared.topics.prefix())
            .field("counts", &self.counts())
            .finish_non_exhaustive()
    }
}

impl Publisher {
    /// Starts publishing what `events` (a subscription to the bus of `file`) carries to the
    /// broker `config` names. Connecting happens in the background, again and again with
    /// backoff while the broker cannot be reached; samples wait in the queue meanwhile.
    /// With `handle`, writes come from `<prefix>/<device>/<register>/set` and
    /// `<prefix>/<device>/<command>/do` for what the file's `writable` lists (see the crate's
    /// README). Fails only when a secret or the CA file cannot be read.
    pub fn start(
        config: &MqttConfig,
        file: &BusFile,
        events: broadcast::Receiver<Event>,
        handle: Option<Handle>,
    ) -> Result<Self, StartError> {
        let options = options(config)?;
        let topics = Topics::new(&config.prefix);
        let qos = if config.qos == 0 {
            QoS::AtMostOnce
        } else {
            QoS::AtLeastOnce
        };
        let discovery = config.homeassistant.as_ref().map(|prefix| {
            let discovery = Discovery {
                status: format!("{prefix}/status"),
                prefix: prefix.clone(),
                client_id: config.client_id.clone(),
                file: file.clone(),
                identities: Mutex::new(HashMap::new()),
                configs: Mutex::new(Vec::new()),
            };
            discovery.make(&config.prefix);
            discovery
        });
        // Home Assistant's entities read state topics: each register's latest value, at most
        // once per `state_every`.
        let states = config.homeassistant.as_ref().map(|_| {
            let mut states = States::default();
            for device in &file.devices {
                let every = config.state_every.of(&device.name);
                for register in discovery::state_registers(device) {
                    states.add(topics.state(&device.name, register.name), every);
                }
            }
            Mutex::new(states)
        });
        // What is read for them: what names each device once, the controls periodically.
        let reads: Vec<Reads> = match &config.homeassistant {
            Some(_) => file
                .devices
                .iter()
                .map(|device| Reads {
                    device: device.name.clone(),
                    identity: discovery::identity_registers(device.device),
                    controls: discovery::read_for_state(device),
                })
                .filter(|reads| !reads.identity.is_empty() || !reads.controls.is_empty())
                .collect(),
            None => Vec::new(),
        };
        let rereads = Rereads::new(&reads);
        let shared = Arc::new(Shared {
            rereads,
            outbox: Mutex::new(Outbox::new(config.queue)),
            wake: Notify::new(),
            devices: Mutex::new(
                file.devices
                    .iter()
                    .map(|d| DeviceState {
                        name: d.name.clone(),
                        online: None,
                    })
                    .collect(),
            ),
            topics,
            qos,
            discovery,
            states,
            stopping: Default::default(),
            closing: Default::default(),
        });
        let (client, eventloop) = AsyncClient::new(options, CLIENT_CHANNEL);
        let mut tasks = Vec::new();
        if let (Some(handle), false) = (&handle, reads.is_empty()) {
            tasks.push(tokio::spawn(refresh(
                handle.for_source(Source::Mqtt),
                Arc::clone(&shared),
                reads,
                config.refresh_every,
            )));
        }
        let tick = shared
            .states
            .as_ref()
            .and_then(|states| lock(states).tick());
        if let Some(tick) = tick {
            tasks.push(tokio::spawn(states_due(Arc::clone(&shared), tick)));
        }
        // Write topics are listened to only when the file lets something be written.
        let handle = handle.filter(|_| file.devices.iter().any(|d| !d.writable.is_empty()));
        let writes = handle.map(|handle| {
            // One task does the writes, one at a time: a flood of them waits in a bounded
            // queue (or is refused) instead of becoming a task each.
            let (queue, waiting) = mpsc::channel(WRITE_QUEUE);
            tasks.push(tokio::spawn(write(
                waiting,
                handle.for_source(Source::Mqtt),
                Arc::clone(&shared),
            )));
            queue
        });
        tasks.extend([
            tokio::spawn(follow(events, Arc::clone(&shared))),
            tokio::spawn(send(client.clone(), Arc::clone(&shared))),
            tokio::spawn(drive(
                eventloop,
                client.clone(),
                Arc::clone(&shared),
                writes,
            )),
        ]);
        Ok(Self {
            shared,
            client,
            tasks,
        })
    }

    /// How publishing has gone so far.
    pub fn counts(&self) -> Counts {
        self.shared.counts()
    }

    /// A handle that reads [`counts`](Self::counts) from elsewhere (a metrics exporter's
    /// scrape); after the publisher stops, it reads the last counts.
    pub fn counts_reader(&self) -> CountsReader {
        CountsReader {
            shared: Arc::clone(&self.shared),
        }
    }

    /// Says the process and every device are going `offline` (the devices' availability
    /// follows: nobody will tell their health any more), waits up to `within` for what is
    /// queued to reach the broker, and disconnects.
    pub async fn stop(self, within: Duration) {
        self.shared
            .closing
            .store(true, std::sync::atomic::Ordering::Relaxed);
        let devices: Vec<String> = {
            let mut devices = lock(&self.shared.devices);
            for device in devices.iter_mut() {
                device.online = Some(false);
            }
            devices.iter().map(|device| device.name.clone()).collect()
        };
        for device in devices {
            self.shared.push(announce(
                self.shared.topics.availability(&device),
                availability(false),
            ));
        }
        self.shared
            .push(announce(self.shared.topics.status(), "offline"));
        let deadline = tokio::time::Instant::now() + within;
        while !self.shared.outbox().is_idle() && tokio::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        self.shared
            .stopping
            .store(true, std::sync::atomic::Ordering::Relaxed);
        let _ = self.client.disconnect().await;
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        for task in &self.tasks {
            task.abort();
        }
    }
}

/// Reads a [`Publisher`]'s counts; cheap to clone, and to keep after the publisher stops.
#[derive(Clone)]
pub struct CountsReader {
    shared: Arc<Shared>,
}

impl CountsReader {
    /// How publishing has gone so far (see [`Publisher::counts`]).
    pub fn counts(&self) -> Counts {
        self.shared.counts()
    }
}

/// Shows the counts; never the credentials.
impl std::fmt::Debug for CountsReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CountsReader")
            .field("counts", &self.counts())
            .finish()
    }
}

fn options(config: &MqttConfig) -> Result<MqttOptions, StartError> {
    let topics = Topics::new(&config.prefix);
    let mut options = MqttOptions::new(&config.client_id, &config.host, config.port);
    options
        .set_keep_alive(config.keep_alive)
        .set_clean_session(true)
        .set_max_packet_size(MAX_INCOMING_PACKET, MAX_PACKET)
        .set_inflight(100)
        .set_last_will(LastWill::new(
            topics.status(),
            "offline",
            QoS::AtLeastOnce,
            true,
        ));
    if let Some(source) = &config.username {
        let username = Secret::read(source).map_err(|e| StartError::Secret("username", e))?;
        let password = match &config.password {
            Some(source) => {
                Some(Secret::read(source).map_err(|e| StartError::Secret("password", e))?)
            }
            None => None,
        };
        options.set_credentials(
            username.expose(),
            password.as_ref().map_or("", Secret::expose),
        );
    }
    if let Some(ca) = &config.ca {
        let tls = crate::tls::client_config(ca).map_err(StartError::Tls)?;
        options.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(
            Arc::new(tls),
        )));
    }
    Ok(options)
}

/// Bus events into messages.
async fn follow(events: broadcast::Receiver<Event>, shared: Arc<Shared>) {
    let mut events = Follower::new(events, |missed| {
        shared.outbox().counts.missed_events += missed;
    });
    while let Some(event) = events.next().await {
        match event {
            Event::Sample(sample) => {
                shared.health(&sample.source.device, true);
                let payload = sample_json(&sample).to_string().into_bytes();
                shared.state_sample(&sample.source.device, sample.register.name, &payload);
                shared.push(Message {
                    topic: shared
                        .topics
                        .sample(&sample.source.device, sample.register.name),
                    payload,
                    qos: shared.qos,
                    retain: false,
                    kind: Kind::Sample,
                });
            }
            Event::Health(health) => {
                shared.health(&health.source.device, health.health == Health::Online);
            }
            // MQTT's own writes are read back by the write itself.
            Event::Written(written) if written.by != Writer::Job(Source::Mqtt) => {
                let coalesced = shared.rereads.written(&written);
                shared.outbox().counts.state_rereads_coalesced += coalesced;
            }
            Event::Written(_) | Event::Line(_) => {}
            Event::Measurement(measurement) => {
                let Ok(payload) = serde_json::to_vec(&*measurement) else {
                    continue;
                };
                shared.push(Message {
                    topic: shared.topics.measurement(&measurement.measurement),
                    payload,
                    qos: shared.qos,
                    retain: false,
                    kind: Kind::Sample,
                });
            }
        }
    }
}

/// Does the writes taken from the write topics, one at a time, and publishes their answers.
async fn write(mut waiting: mpsc::Receiver<Write>, handle: Handle, shared: Arc<Shared>) {
    while let Some(write) = waiting.recv().await {
        let done = crate::writes::carry_out(&handle, &shared.topics, write).await;
        if let Some((topic, payload)) = done.state {
            shared.state_now(&topic, payload);
        }
        let count = |counts: &mut Counts| {
            if done.busy {
                counts.writes_busy += 1;
            } else {
                counts.writes_taken += 1;
            }
        };
        match done.reply {
            Some(reply) => shared.reply(reply, count),
            None => count(&mut shared.outbox().counts),
        }
    }
}

/// Messages from the queue to the client, in order. A message is marked in flight and handed
/// to the client's channel under the outbox's lock, so that a broken
/// connection (which empties that channel under the same lock) never finds one in the channel
/// that the outbox does not count as in flight, or the other way round.
async fn send(client: AsyncClient, shared: Arc<Shared>) {
    loop {
        // As many as the channel takes, under one lock.
        {
            let mut outbox = shared.outbox();
            while let Some(message) = outbox.next() {
                let taken = client
                    .try_publish(message.topic, message.qos, message.retain, message.payload)
                    .is_ok();
                if !taken {
                    outbox.not_taken();
                    break;
                }
            }
        }
        // More to send, or room in the channel again (the event loop wrote one).
        shared.wake.notified().await;
    }
}

/// Drives the connection: reconnects with backoff, publishes the announcements at each
/// connection, tracks what the broker took, and answers Home Assistant and writes.
async fn drive(
    mut eventloop: EventLoop,
    client: AsyncClient,
    shared: Arc<Shared>,
    writes: Option<mpsc::Sender<Write>>,
) {
    let mut backoff = FIRST_BACKOFF;
    let mut failures = 0u64;
    // The last break came from a packet over the incoming limit: the backoff is not reset
    // at the next connection, so that a retained one does not break every connection at once.
    let mut broken_by_size = false;
    loop {
        match eventloop.poll().await {
            Ok(MqttEvent::Incoming(Packet::ConnAck(_))) => {
                let (host, port) = eventloop.mqtt_options.broker_address();
                match failures {
                    0 => tracing::info!("MQTT: connected to the broker at {host}:{port}"),
                    n => tracing::info!(
                        "MQTT: connected to the broker at {host}:{port} again, after {n} attempts"
                    ),
                }
                if !std::mem::take(&mut broken_by_size) {
                    backoff = FIRST_BACKOFF;
                }
                failures = 0;
                let announcements = shared.announcements();
                shared.outbox().connected(announcements);
                shared.wake.notify_one();
                let mut subscriptions = Vec::new();
                if let Some(discovery) = &shared.discovery {
                    subscriptions.push(discovery.status.clone());
                    // What a former run announced for measurements this file has not.
                    subscriptions.push(measurements::filter(
                        &discovery.prefix,
                        &discovery.client_id,
                    ));
                }
                if writes.is_some() {
                    subscriptions.extend(shared.topics.write_filters());
                }
                // Queued behind what the client holds, so not awaited here (this task is
                // the one that empties the client's queue).
                let client = client.clone();
                tokio::spawn(async move {
                    for topic in subscriptions {
                        let _ = client.subscribe(topic, QoS::AtLeastOnce).await;
                    }
                });
            }
            Ok(event) => take_in(&shared, writes.as_ref(), event),
            Err(error) => {
                if shared.stopping.load(std::sync::atomic::Ordering::Relaxed) {
                    // The publisher disconnected on purpose: the end of the run, not a loss.
                    return;
                }
                broke(&mut eventloop, &shared, writes.as_ref());
                if let ConnectionError::MqttState(StateError::Deserialization(
                    rumqttc::Error::PayloadSizeLimitExceeded(size),
                )) = error
                {
                    broken_by_size = true;
                    shared.outbox().counts.incoming_too_large += 1;
                    tracing::warn!(
                        size,
                        limit = MAX_INCOMING_PACKET,
                        "the MQTT broker sent a packet over the client's limit; the connection \
                         is made again after {backoff:?}"
                    );
                } else if failures == 0 {
                    let (host, port) = eventloop.mqtt_options.broker_address();
                    tracing::warn!(
                        "MQTT: the broker at {host}:{port} cannot be reached ({error}); samples \
                         wait in the queue, trying again with backoff (told again once connected)"
                    );
                }
                failures += 1;
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(MAX_BACKOFF);
            }
        }
    }
}

/// The connection broke: what was not acknowledged goes back to the queue, to be sent again.
fn broke(eventloop: &mut EventLoop, shared: &Arc<Shared>, writes: Option<&mpsc::Sender<Write>>) {
    // The event loop keeps the events it made before the break and had not given yet (a
    // PUBLISH written, PUBACKs read) and gives them after the reconnection, where a PUBLISH
    // written would be matched to the next connection's first message. They belong to the
    // connection that broke: taken in now.
    let before_break: Vec<MqttEvent> = eventloop.state.events.drain(..).collect();
    for event in before_break {
        take_in(shared, writes, event);
    }
    // The event loop dropped what its channel held when the connection broke (a clean
    // session starts empty); a message handed to it since then is dropped too, under the
    // lock the sender hands messages under, so that the outbox sends again exactly what the
    // broker may not have.
    let mut outbox = shared.outbox();
    eventloop.clean();
    outbox.disconnected();
}

/// What the connection did besides connecting: a message written, acknowledged or received.
fn take_in(shared: &Arc<Shared>, writes: Option<&mpsc::Sender<Write>>, event: MqttEvent) {
    match event {
        MqttEvent::Outgoing(Outgoing::Publish(pkid)) => {
            let room = {
                let mut outbox = shared.outbox();
                outbox.written(pkid);
                outbox.unwritten() <= CLIENT_CHANNEL / 2
            };
            // The client's channel half empty: the sender fills it again.
            if room {
                shared.wake.notify_one();
            }
        }
        MqttEvent::Incoming(Packet::PubAck(ack)) => shared.outbox().acknowledged(ack.pkid),
        MqttEvent::Incoming(Packet::Publish(publish)) => {
            incoming(
                shared,
                writes,
                &publish.topic,
                &publish.payload,
                publish.retain,
            );
        }
        _ => {}
    }
}

/// A message on a topic the publisher subscribed to.
fn incoming(
    shared: &Arc<Shared>,
    writes: Option<&mpsc::Sender<Write>>,
    topic: &str,
    payload: &[u8],
    retained: bool,
) {
    if let Some(discovery) = &shared.discovery {
        if topic == discovery.status {
            if payload == b"online" {
                // Home Assistant (re)started: it forgets entities not announced again. Many
                // births in a row make one re-announcement.
                let configs = discovery.configs();
                shared.outbox().rediscover(&configs);
                shared.wake.notify_one();
            }
            return;
        }
        if !payload.is_empty() && retained {
            let current: Vec<String> = discovery.configs().into_iter().map(|c| c.topic).collect();
            if measurements::is_stale(topic, &discovery.prefix, &discovery.client_id, &current) {
                // A measurement gone from the bus file: its entities go from Home Assistant.
                shared.push(announce(topic.to_owned(), Vec::new()));
                return;
            }
        }
    }
    let Some(queue) = writes else {
        return;
    };
    match crate::writes::take(&shared.topics, queue, topic, payload, retained) {
        Taken::NotAWrite | Taken::Queued => {}
        Taken::TooLarge(reply) => shared.reply(reply, |c| c.writes_too_large += 1),
        Taken::Retained(reply) => shared.reply(reply, |c| c.writes_retained += 1),
        Taken::Busy(reply) => shared.reply(reply, |c| c.writes_busy += 1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outbox::sample;
    use rumqttc::PubAck;

    fn shared() -> Arc<Shared> {
        Arc::new(Shared {
            outbox: Mutex::new(Outbox::new(10)),
            wake: Notify::new(),
            devices: Mutex::new(Vec::new()),
            topics: Topics::new("t"),
            qos: QoS::AtLeastOnce,
            discovery: None,
            states: None,
            stopping: Default::default(),
            closing: Default::default(),
            rereads: Rereads::default(),
        })
    }

    #[tokio::test]
    async fn what_the_event_loop_did_before_a_break_counts_for_the_connection_that_broke() {
        let shared = shared();
        let (_client, mut eventloop) =
            AsyncClient::new(MqttOptions::new("test", "127.0.0.1", 1), 8);
        {
            let mut outbox = shared.outbox();
            outbox.connected(Vec::new());
            outbox.push(sample(1));
            outbox.push(sample(2));
            assert_eq!(outbox.next().map(|m| m.topic).as_deref(), Some("t/1"));
            assert_eq!(outbox.next().map(|m| m.topic).as_deref(), Some("t/2"));
        }
        take_in(&shared, None, MqttEvent::Outgoing(Outgoing::Publish(1)));
        // The event loop read the PUBACK of t/1 and wrote t/2 as packet 2, and the connection
        // broke before it gave those events.
        let events = &mut eventloop.state.events;
        events.push_back(MqttEvent::Incoming(Packet::PubAck(PubAck::new(1))));
        events.push_back(MqttEvent::Outgoing(Outgoing::Publish(2)));
        broke(&mut eventloop, &shared, None);
        assert!(
            eventloop.state.events.is_empty(),
            "nothing left for the next connection"
        );
        let counts = shared.outbox().counts();
        assert_eq!((counts.published, counts.requeued), (1, 1), "{counts:?}");
        // The next connection sends t/2 again, as its packet 3, and its PUBACK takes it.
        shared.outbox().connected(Vec::new());
        assert_eq!(
            shared.outbox().next().map(|m| m.topic).as_deref(),
            Some("t/2")
        );
        take_in(&shared, None, MqttEvent::Outgoing(Outgoing::Publish(3)));
        take_in(
            &shared,
            None,
            MqttEvent::Incoming(Packet::PubAck(PubAck::new(3))),
        );
        let outbox = shared.outbox();
        assert_eq!(outbox.counts().published, 2);
        assert!(outbox.is_idle());
    }
}
