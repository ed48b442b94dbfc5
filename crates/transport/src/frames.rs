//! Frame events for `tracing`: every frame sent and received, at TRACE, target
//! `optobus_transport`, with the slave and, for replies, the time since the request left.
//!
//! The message is the frame as a person reads it (`-> 01 03 00 1F 00 07 …`); the fields carry
//! the same for a program: `slave`, and `elapsed_us` on received bytes.

use std::time::Duration;

use optobus_codec::Hex;

/// The target of every frame event.
pub const TARGET: &str = "optobus_transport";

/// A request left for `slave`.
pub(crate) fn sent(slave: u8, frame: &[u8]) {
    tracing::trace!(target: TARGET, slave, "-> {}", Hex(frame));
}

/// Bytes came back from `slave`, `elapsed` after the request left; `what` says what they
/// were when not a reply (`stale`, `garbled`, `incomplete`).
pub(crate) fn received(slave: u8, bytes: &[u8], elapsed: Duration, what: Option<&str>) {
    let elapsed_us = u64::try_from(elapsed.as_micros()).unwrap_or(u64::MAX);
    match what {
        None => tracing::trace!(target: TARGET, slave, elapsed_us, "<- {}", Hex(bytes)),
        Some(what) => {
            tracing::trace!(target: TARGET, slave, elapsed_us, "<- {} ({what})", Hex(bytes))
        }
    }
}

/// Bytes nobody asked for, thrown away before a request.
pub(crate) fn discarded(bytes: &[u8]) {
    tracing::trace!(target: TARGET, "<- {} (discarded)", Hex(bytes));
}
