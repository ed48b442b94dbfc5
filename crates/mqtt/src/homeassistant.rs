//! What the publisher keeps for Home Assistant: the discovery configurations (made again when
//! a device says who it is), the controls to read again after another path wrote them, and a
//! device's registers read for the state topics (the tasks that use them: `refresh.rs`).

use std::collections::{BTreeSet, HashMap};
use std::sync::Mutex;

use optobus_bus::{BusFile, Written};
use optobus_device::{RegisterInfo, Role};
use tokio::sync::Notify;

use crate::discovery::{self, Identity};
use crate::lock::lock;
use crate::outbox::{announce, Message};

/// Home Assistant discovery: what its configurations are made of, and the configurations.
#[derive(Debug)]
pub(crate) struct Discovery {
    /// Home Assistant's status topic (`<discovery prefix>/status`).
    pub(crate) status: String,
    pub(crate) prefix: String,
    pub(crate) client_id: String,
    pub(crate) file: BusFile,
    /// What devices said about themselves (read once at start).
    pub(crate) identities: Mutex<HashMap<String, Identity>>,
    pub(crate) configs: Mutex<Vec<Message>>,
}

impl Discovery {
    pub(crate) fn configs(&self) -> Vec<Message> {
        lock(&self.configs).clone()
    }

    /// Makes the configurations again, for the publisher's topic `prefix`.
    pub(crate) fn make(&self, prefix: &str) {
        let identities = lock(&self.identities).clone();
        let configs = discovery::configurations_with(
            &self.file,
            &self.prefix,
            &self.client_id,
            prefix,
            &identities,
        )
        .into_iter()
        .map(|(topic, payload)| announce(topic, payload.to_string()))
        .collect();
        *lock(&self.configs) = configs;
    }
}

/// The controls whose state is read again as soon as another path (the console, the gateway,
/// the program's handle) has written them: each at most once however often it was written
/// meanwhile, by the one task that reads the states.
#[derive(Debug, Default)]
pub(crate) struct Rereads {
    /// Each device's controls with a state read from the device.
    pub(crate) controls: Vec<(String, Vec<&'static RegisterInfo>)>,
    /// Which of them are due (device, control), each once.
    pub(crate) due: Mutex<BTreeSet<(usize, usize)>>,
    /// Wakes the reading task.
    pub(crate) wake: Notify,
}

impl Rereads {
    pub(crate) fn new(reads: &[Reads]) -> Self {
        Self {
            controls: reads
                .iter()
                .map(|reads| (reads.device.clone(), reads.controls.clone()))
                .collect(),
            ..Self::default()
        }
    }

    /// Marks the controls `written` covers as due; how many were due already.
    pub(crate) fn written(&self, written: &Written) -> u64 {
        let Some(device) = self
            .controls
            .iter()
            .position(|(name, _)| *name == *written.source.device)
        else {
            return 0;
        };
        let controls = &self.controls[device].1;
        let mut due = lock(&self.due);
        let mut coalesced = 0;
        let mut added = false;
        for register in &written.registers {
            let Some(control) = controls.iter().position(|c| std::ptr::eq(*c, *register)) else {
                continue;
            };
            if due.insert((device, control)) {
                added = true;
            } else {
                coalesced += 1;
            }
        }
        drop(due);
        if added {
            self.wake.notify_one();
        }
        coalesced
    }

    /// The controls due now, taken.
    pub(crate) fn take(&self) -> BTreeSet<(usize, usize)> {
        std::mem::take(&mut *lock(&self.due))
    }
}

/// A device's registers read for the state topics.
#[derive(Debug)]
pub(crate) struct Reads {
    pub(crate) device: String,
    /// The registers that name the device (firmware version, serial number), until each has
    /// been read once.
    pub(crate) identity: Vec<(Role, &'static RegisterInfo)>,
    /// The controls Home Assistant shows, read at start and at each refresh.
    pub(crate) controls: Vec<&'static RegisterInfo>,
}
