//! Times as the bus's outputs write them.

use std::time::SystemTime;

/// A time in RFC 3339, UTC, with microseconds.
pub fn rfc3339(time: SystemTime) -> String {
    jiff::Timestamp::try_from(time)
        .map(|t| format!("{:.6}", t))
        .unwrap_or_else(|_| "out of range".to_owned())
}
