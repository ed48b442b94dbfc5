//! The MQTT output of an optobus bus.
//!
//! [`Publisher`] follows a bus's events and publishes, under the bus file's prefix:
//!
//! - each sample to `<prefix>/<device>/<register>` as JSON: the number for consumers
//!   (`value`), the exact text (`text`), the `unit` and the reply's `time` in RFC 3339; codes as
//!   `code` and `name` (see [`value_json`]);
//! - `<prefix>/<device>/availability`, retained, `online` or `offline` following the device's
//!   health, and `<prefix>/status`, retained, `online` while the process runs (its last will
//!   says `offline`);
//! - with Home Assistant discovery on, a device per sensor and an entity per polled register
//!   under the discovery prefix (see [`discovery`]), again whenever Home Assistant comes online.
//!   Its entities read `<prefix>/<device>/<register>/state`, retained, at most one message per
//!   register per `state_every` (the sample topics keep every sample); the registers it
//!   controls are read for it at start, after each write and every `refresh_every`.
//!
//! While the broker cannot be reached the bus polls on; samples wait in a bounded queue (the
//! oldest dropped and counted beyond its size) and the client reconnects with backoff
//! ([`FIRST_BACKOFF`] doubling up to [`MAX_BACKOFF`]); each new connection publishes the
//! availability and discovery again before the samples that waited.
//!
//! What the broker hands over is bounded too: a write's payload over [`MAX_WRITE_PAYLOAD`] is
//! refused on `…/error` without being repeated; writes wait in a queue of [`WRITE_QUEUE`],
//! done one at a time by one task (one more is refused as busy); answers wait in a queue of
//! [`REPLY_QUEUE`] (the oldest dropped); Home Assistant's births make at most one waiting
//! re-announcement; retained writes are refused. [`Counts`] counts each.
#![forbid(unsafe_code)]

pub mod discovery;
mod homeassistant;
mod lock;
mod outbox;
mod payload;
mod publisher;
mod refresh;
mod secret;
pub mod settings;
mod shared;
mod state;
mod text;
mod tls;
mod topics;
mod writes;

pub use outbox::{Counts, REPLY_QUEUE};
pub use payload::{sample_json, value_json};
pub use publisher::{
    CountsReader, Publisher, StartError, FIRST_BACKOFF, MAX_BACKOFF, MAX_INCOMING_PACKET,
};
pub use secret::{Secret, SecretError};
pub use settings::{MqttConfig, SecretSource, StateEvery};
pub use writes::{MAX_WRITE_PAYLOAD, WRITE_QUEUE};
