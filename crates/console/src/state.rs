//! What the console knows of the bus: the latest value of every register polled, each
//! device's health, each line's statistics and each measurement's recent values, kept up to
//! date from the bus's events by one task, which also gathers them into the live stream's batches and hands each batch to every
//! client's own bounded queue (a full queue loses its oldest batch then, counted).

use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};

use optobus_bus::{DeviceId, ErrorCounts, Event, Follower, Handle, Health, HealthEvent};
use optobus_device::DeviceInfo;
use tokio::sync::{broadcast, watch, Notify};

use crate::batch::{Batch, Entry, BATCH_EVERY, BATCH_QUEUE};
use crate::guard::Guard;
use crate::reply::{HealthJson, LimitsJson, LineJson, MeasurementJson, SampleJson};

/// The recent values kept per measurement for its chart (the page keeps its own from then
/// on); the oldest goes beyond.
pub(crate) const MEASUREMENT_HISTORY: usize = 600;

/// Everything the handlers share.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) handle: Handle,
    pub(crate) guard: Arc<Guard>,
    pub(crate) board: Mutex<Board>,
    /// The live stream's clients now, each with its queue of batches.
    pub(crate) clients: Mutex<Vec<Arc<ClientQueue>>>,
    /// Batches dropped for clients that fell behind, counted when dropped.
    pub(crate) dropped: AtomicU64,
    /// Events of the bus the console itself missed (it fell behind the bus).
    pub(crate) missed: AtomicU64,
    /// Set when the server stops: the live streams end (their browsers reconnect).
    pub(crate) stopped: watch::Sender<bool>,
    /// The listener's connection counts, once it serves.
    pub(crate) connections: OnceLock<optobus_http::Tally>,
}

/// One client's batches not yet sent: at most [`BATCH_QUEUE`]; the oldest goes when a new one
/// finds it full.
#[derive(Debug, Default)]
pub(crate) struct ClientQueue {
    queue: Mutex<Queued>,
    /// A batch arrived.
    pub(crate) ready: Notify,
}

#[derive(Debug, Default)]
struct Queued {
    batches: VecDeque<Arc<str>>,
    /// Batches dropped that the client has not been told of yet.
    untold: u64,
}

/// What a client is sent next.
#[derive(Debug, PartialEq)]
pub(crate) enum Next {
    /// How many batches it lost since it was last told.
    Dropped(u64),
    /// A batch.
    Batch(Arc<str>),
}

impl ClientQueue {
    /// Queues `batch`; whether the oldest was dropped to make room.
    fn push(&self, batch: Arc<str>) -> bool {
        let mut queued = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        let full = queued.batches.len() >= BATCH_QUEUE;
        if full {
            queued.batches.pop_front();
            queued.untold += 1;
        }
        queued.batches.push_back(batch);
        drop(queued);
        self.ready.notify_one();
        full
    }

    /// The client's next message, if any: the drops it has not been told of first.
    pub(crate) fn next(&self) -> Option<Next> {
        let mut queued = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        if queued.untold > 0 {
            return Some(Next::Dropped(std::mem::take(&mut queued.untold)));
        }
        queued.batches.pop_front().map(Next::Batch)
    }
}

/// A device's latest state.
#[derive(Debug)]
pub(crate) struct DeviceState {
    pub(crate) id: Arc<DeviceId>,
    pub(crate) info: &'static DeviceInfo,
    pub(crate) health: Health,
    pub(crate) errors: ErrorCounts,
    pub(crate) reason: Option<String>,
    /// The latest sample of each register, as the stream sends it, and whether it is current:
    /// a value stops being current when its device goes down, until it is sampled again.
    pub(crate) values: HashMap<&'static str, (SampleJson, bool)>,
}

/// The latest of everything.
#[derive(Debug)]
pub(crate) struct Board {
    /// In the bus file's order.
    pub(crate) devices: Vec<DeviceState>,
    /// Each line's latest statistics, as the stream sends them.
    pub(crate) lines: Vec<(Arc<str>, LineJson)>,
    /// The bus file's measurements, in the order the bus computes them.
    pub(crate) measurements: Vec<MeasurementState>,
}

/// A measurement's latest value and its recent ones.
#[derive(Debug)]
pub(crate) struct MeasurementState {
    pub(crate) name: String,
    pub(crate) unit: String,
    pub(crate) limits: Option<LimitsJson>,
    pub(crate) latest: Option<MeasurementJson>,
    /// At most [`MEASUREMENT_HISTORY`], oldest first: time (ms since 1970) and number.
    pub(crate) history: VecDeque<(f64, Option<f64>)>,
}

impl DeviceState {
    /// Its health as the stream sends it.
    pub(crate) fn health_json(&self) -> HealthJson {
        HealthJson::new(
            &self.id.device,
            self.health,
            self.errors,
            self.reason.clone(),
        )
    }
}

impl Shared {
    pub(crate) fn new(handle: Handle, guard: Guard) -> Self {
        let devices = handle
            .devices()
            .map(|(id, info)| DeviceState {
                id: Arc::clone(id),
                info,
                health: Health::Online,
                errors: ErrorCounts::default(),
                reason: None,
                values: HashMap::new(),
            })
            .collect();
        let measurements = handle
            .measurements()
            .into_iter()
            .map(|(name, unit)| MeasurementState {
                name: name.to_owned(),
                unit: unit.to_owned(),
                limits: handle.measurement_limits(name).map(LimitsJson::from),
                latest: None,
                history: VecDeque::new(),
            })
            .collect();
        Self {
            handle,
            guard: Arc::new(guard),
            board: Mutex::new(Board {
                devices,
                lines: Vec::new(),
                measurements,
            }),
            clients: Mutex::new(Vec::new()),
            dropped: AtomicU64::new(0),
            missed: AtomicU64::new(0),
            stopped: watch::channel(false).0,
            connections: OnceLock::new(),
        }
    }

    /// A new client of the stream, with its own queue.
    pub(crate) fn join(&self) -> Arc<ClientQueue> {
        let client = Arc::new(ClientQueue::default());
        self.clients().push(Arc::clone(&client));
        client
    }

    /// The client gone.
    pub(crate) fn leave(&self, client: &Arc<ClientQueue>) {
        self.clients().retain(|c| !Arc::ptr_eq(c, client));
    }

    pub(crate) fn clients(&self) -> std::sync::MutexGuard<'_, Vec<Arc<ClientQueue>>> {
        self.clients.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Hands `batch` to every client; a client whose queue is full loses its oldest batch,
    /// counted now rather than when (if ever) it reads again.
    fn publish(&self, batch: Arc<str>) {
        for client in self.clients().iter() {
            if client.push(Arc::clone(&batch)) {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    pub(crate) fn board(&self) -> std::sync::MutexGuard<'_, Board> {
        self.board.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Board {
    fn device(&mut self, name: &str) -> Option<&mut DeviceState> {
        self.devices.iter_mut().find(|d| &*d.id.device == name)
    }

    /// Takes in one event; gives what the stream sends of it.
    fn apply(&mut self, event: &Event) -> Option<Entry> {
        match event {
            Event::Sample(sample) => {
                let json = SampleJson::new(sample);
                let device = self.device(&sample.source.device)?;
                device
                    .values
                    .insert(sample.register.name, (json.clone(), true));
                Some(Entry::Sample(json))
            }
            Event::Health(health) => {
                let HealthEvent {
                    source,
                    health,
                    errors,
                    reason,
                } = &**health;
                let device = self.device(&source.device)?;
                device.health = *health;
                if *health == Health::Offline {
                    // Its last values stand until it answers again, but no longer as current.
                    for (_, current) in device.values.values_mut() {
                        *current = false;
                    }
                }
                device.errors = *errors;
                device.reason.clone_from(reason);
                Some(Entry::Health(device.health_json()))
            }
            Event::Measurement(event) => {
                let json = MeasurementJson::new(event);
                let state = self
                    .measurements
                    .iter_mut()
                    .find(|m| *m.name == *event.measurement)?;
                if state.history.len() == MEASUREMENT_HISTORY {
                    state.history.pop_front();
                }
                state.history.push_back(json.point());
                state.latest = Some(json.clone());
                Some(Entry::Measurement(json))
            }
            Event::Line(stats) => {
                let json = LineJson::new(stats);
                match self.lines.iter_mut().find(|(line, _)| *line == stats.line) {
                    Some((_, latest)) => *latest = json.clone(),
                    None => self.lines.push((Arc::clone(&stats.line), json.clone())),
                }
                Some(Entry::Line(json))
            }
            // The device's next sample shows the new value; a write's own answer went to
            // whoever asked.
            Event::Written(_) => None,
        }
    }
}

/// Follows the bus's events until the bus stops or nothing serves the console any more: the
/// board kept up to date, a batch sent to the stream's clients every [`BATCH_EVERY`] when
/// anything happened.
pub(crate) async fn collect(shared: Weak<Shared>, events: broadcast::Receiver<Event>) {
    let counted = Weak::clone(&shared);
    let mut events = Follower::new(events, |missed| {
        if let Some(shared) = counted.upgrade() {
            shared.missed.fetch_add(missed, Ordering::Relaxed);
        }
    });
    let mut batch = Batch::default();
    let mut tick = tokio::time::interval(BATCH_EVERY);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        let event = tokio::select! {
            event = events.next() => Some(event),
            _ = tick.tick() => None,
        };
        let Some(shared) = shared.upgrade() else {
            break;
        };
        match event {
            Some(Some(event)) => {
                if let Some(entry) = shared.board().apply(&event) {
                    batch.add(entry);
                }
            }
            Some(None) => break,
            None => {
                if let Some(text) = batch.take() {
                    shared.publish(text);
                }
            }
        }
    }
}
