//! The topics a bus publishes under its prefix.

/// Topic names under one prefix.
#[derive(Clone, Debug)]
pub(crate) struct Topics {
    prefix: String,
}

impl Topics {
    pub(crate) fn new(prefix: &str) -> Self {
        Self {
            prefix: prefix.to_owned(),
        }
    }

    pub(crate) fn prefix(&self) -> &str {
        &self.prefix
    }

    /// The process's availability (`online`, and `offline` as its last will).
    pub(crate) fn status(&self) -> String {
        format!("{}/status", self.prefix)
    }

    /// A device's availability (`online` or `offline`, following its health).
    pub(crate) fn availability(&self, device: &str) -> String {
        format!("{}/{device}/availability", self.prefix)
    }

    /// A register's samples.
    pub(crate) fn sample(&self, device: &str, register: &str) -> String {
        format!("{}/{device}/{register}", self.prefix)
    }

    /// A measurement's values (the bus file's `measurements`), as their JSON.
    pub(crate) fn measurement(&self, name: &str) -> String {
        format!("{}/measurements/{name}", self.prefix)
    }

    /// A register's state for Home Assistant: its latest value, retained, at most once per
    /// `state_every`.
    pub(crate) fn state(&self, device: &str, register: &str) -> String {
        format!("{}/{device}/{register}/state", self.prefix)
    }

    /// The filters of the write topics: `<prefix>/<device>/<register>/set` and
    /// `<prefix>/<device>/<command>/do`.
    pub(crate) fn write_filters(&self) -> [String; 2] {
        [
            format!("{}/+/+/set", self.prefix),
            format!("{}/+/+/do", self.prefix),
        ]
    }
}
