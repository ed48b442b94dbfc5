//! The publisher's state that its tasks share: the outbox, the devices' availability, the
//! topics, and Home Assistant's discovery and state topics when it is on.

use std::sync::{Mutex, MutexGuard};

use rumqttc::QoS;
use tokio::sync::Notify;

use crate::homeassistant::{Discovery, Rereads};
use crate::lock::lock;
use crate::outbox::{announce, Counts, Message, Outbox};
use crate::state::States;
use crate::topics::Topics;

/// A device as the publisher follows it.
#[derive(Debug)]
pub(crate) struct DeviceState {
    pub(crate) name: String,
    /// `None` before its first sample or health event.
    pub(crate) online: Option<bool>,
}

#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) outbox: Mutex<Outbox>,
    pub(crate) wake: Notify,
    pub(crate) devices: Mutex<Vec<DeviceState>>,
    pub(crate) topics: Topics,
    pub(crate) qos: QoS,
    /// Home Assistant discovery, when on.
    pub(crate) discovery: Option<Discovery>,
    /// The state topics Home Assistant reads, when it is on.
    pub(crate) states: Option<Mutex<States>>,
    /// Set by [`Publisher::stop`]: the connection's end is ours, nothing to warn about.
    pub(crate) stopping: std::sync::atomic::AtomicBool,
    /// Set when [`Publisher::stop`] begins: every device is announced `offline`, and no
    /// later sample or health event announces one `online` again.
    pub(crate) closing: std::sync::atomic::AtomicBool,
    /// The controls another path wrote, to be read again at once.
    pub(crate) rereads: Rereads,
}

impl Shared {
    pub(crate) fn outbox(&self) -> MutexGuard<'_, Outbox> {
        lock(&self.outbox)
    }

    pub(crate) fn counts(&self) -> Counts {
        let mut counts = self.outbox().counts();
        if let Some(states) = &self.states {
            counts.states_skipped = lock(states).skipped;
        }
        counts
    }

    pub(crate) fn push(&self, message: Message) {
        self.outbox().push(message);
        self.wake.notify_one();
    }

    /// Publishes the answer to a write (bounded: the oldest waiting is dropped beyond
    /// [`REPLY_QUEUE`](crate::REPLY_QUEUE)), counting the refusal `count` names.
    pub(crate) fn reply(&self, message: Message, count: impl FnOnce(&mut Counts)) {
        {
            let mut outbox = self.outbox();
            count(&mut outbox.counts);
            outbox.push(message);
        }
        self.wake.notify_one();
    }

    /// What every new connection publishes first: the process is online, each device's known
    /// availability, and discovery.
    pub(crate) fn announcements(&self) -> Vec<Message> {
        let mut messages = vec![announce(self.topics.status(), "online")];
        let devices = self.devices.lock().unwrap_or_else(|p| p.into_inner());
        for device in devices.iter() {
            if let Some(online) = device.online {
                messages.push(announce(
                    self.topics.availability(&device.name),
                    availability(online),
                ));
            }
        }
        if let Some(discovery) = &self.discovery {
            messages.extend(discovery.configs());
        }
        messages
    }

    /// Records a device's health; publishes its availability when it changed.
    pub(crate) fn health(&self, device: &str, online: bool) {
        if self.closing.load(std::sync::atomic::Ordering::Relaxed) {
            return;
        }
        let changed = {
            let mut devices = self.devices.lock().unwrap_or_else(|p| p.into_inner());
            match devices.iter_mut().find(|d| d.name == device) {
                Some(state) if state.online != Some(online) => {
                    state.online = Some(online);
                    true
                }
                _ => false,
            }
        };
        if changed {
            self.push(announce(
                self.topics.availability(device),
                availability(online),
            ));
        }
    }
}

pub(crate) fn availability(online: bool) -> &'static str {
    if online {
        "online"
    } else {
        "offline"
    }
}
