//! The publisher's tasks for Home Assistant: the controls read for their state topics (at
//! start, every `refresh_every`, and at once after another path wrote them), and the state
//! topics published when their interval is over.

use std::sync::Arc;
use std::time::Duration;

use optobus_bus::{Handle, JobError};
use optobus_device::{RegisterInfo, Role};
use optobus_inspect::Value;

use crate::homeassistant::Reads;
use crate::lock::lock;
use crate::payload::read_json;
use crate::shared::Shared;

/// Reads the controls' values for their state topics at start and every `every`, and what
/// names each device (its registers with a role: firmware version, serial number) once, through `handle` (as MQTT: the line serves them in turn
/// with its polls, in its bounded queue for MQTT). One read at a time; a device the bus has
/// given up on is left for the next round, and so is the rest of a device after a failure or
/// a busy refusal (counted).
///
/// Between rounds it reads at once the controls another path wrote (see [`Rereads`]); a
/// write during a round waits for the round's end.
pub(crate) async fn refresh(
    handle: Handle,
    shared: Arc<Shared>,
    mut reads: Vec<Reads>,
    every: Duration,
) {
    let mut rounds = tokio::time::interval(every);
    rounds.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        // Neither starves the other: select takes either when both are ready.
        tokio::select! {
            () = shared.rereads.wake.notified() => {
                reread(&handle, &shared).await;
                continue;
            }
            _ = rounds.tick() => {}
        }
        for device in &mut reads {
            if shared.offline(&device.device) {
                continue;
            }
            // Each is read until it has been once (an invalid reading is tried again).
            let mut failed = false;
            for (role, register) in std::mem::take(&mut device.identity) {
                if !failed {
                    match read_for_state(&handle, &shared, &device.device, register).await {
                        Some(Value::Invalid) => {}
                        Some(value) => {
                            shared.identified(&device.device, role, value.to_string());
                            continue;
                        }
                        None => failed = true,
                    }
                }
                device.identity.push((role, register));
            }
            if failed {
                continue;
            }
            for register in &device.controls {
                let Some(value) = read_for_state(&handle, &shared, &device.device, register).await
                else {
                    break;
                };
                shared.state_now(
                    &shared.topics.state(&device.device, register.name),
                    read_json(&value),
                );
            }
        }
    }
}

/// Reads the controls other paths wrote since the last time, once each, and publishes their
/// states. One that fails waits for the next round (counted as any state read).
async fn reread(handle: &Handle, shared: &Shared) {
    for (device, control) in shared.rereads.take() {
        let (name, controls) = &shared.rereads.controls[device];
        let register = controls[control];
        if shared.offline(name) {
            continue;
        }
        shared.outbox().counts.state_reads_after_writes += 1;
        if let Some(value) = read_for_state(handle, shared, name, register).await {
            shared.state_now(&shared.topics.state(name, register.name), read_json(&value));
        }
    }
}

/// Reads `register` of `device` for a state topic, counting how it went.
async fn read_for_state(
    handle: &Handle,
    shared: &Shared,
    device: &str,
    register: &'static RegisterInfo,
) -> Option<Value> {
    let result = handle.read_checked(device, register).await;
    let mut outbox = shared.outbox();
    outbox.counts.state_reads += 1;
    match result {
        Ok(value) => Some(value),
        Err(JobError::Busy { .. }) => {
            outbox.counts.state_reads_busy += 1;
            None
        }
        Err(_) => {
            outbox.counts.state_reads_failed += 1;
            None
        }
    }
}

/// Publishes the samples that waited for their state topic's interval to be over.
pub(crate) async fn states_due(shared: Arc<Shared>, tick: Duration) {
    let Some(states) = &shared.states else { return };
    let mut ticks = tokio::time::interval(tick);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        ticks.tick().await;
        let due = lock(states).due(tokio::time::Instant::now());
        for message in due {
            shared.push(message);
        }
    }
}

impl Shared {
    /// A sample of `register` of `device` for its state topic, if it has one: published now
    /// or when its interval is over.
    pub(crate) fn state_sample(&self, device: &str, register: &str, payload: &[u8]) {
        let Some(states) = &self.states else { return };
        let topic = self.topics.state(device, register);
        let now = tokio::time::Instant::now();
        let message = lock(states).offer(&topic, payload.to_vec(), now);
        if let Some(message) = message {
            self.push(message);
        }
    }

    /// A value read on purpose for state topic `topic`: published now.
    pub(crate) fn state_now(&self, topic: &str, payload: Vec<u8>) {
        let Some(states) = &self.states else { return };
        let message = lock(states).now(topic, payload, tokio::time::Instant::now());
        if let Some(message) = message {
            self.push(message);
        }
    }

    /// Whether the bus has given up on `device` for now.
    pub(crate) fn offline(&self, device: &str) -> bool {
        lock(&self.devices)
            .iter()
            .any(|d| d.name == device && d.online == Some(false))
    }

    /// `device` said what its register of `role` holds: its entities' device block carries it
    /// from now.
    pub(crate) fn identified(&self, device: &str, role: Role, text: String) {
        let Some(discovery) = &self.discovery else {
            return;
        };
        lock(&discovery.identities)
            .entry(device.to_owned())
            .or_default()
            .set(role, text);
        discovery.make(self.topics.prefix());
        for config in discovery.configs() {
            self.push(config);
        }
    }
}
