//! A bus of optobus sensors: several devices on shared Modbus lines, polled on schedule.
//!
//! A [bus file](mod@file) names the lines (a serial port, Modbus TCP, RTU over TCP, or a simulated
//! line), the devices on them (a built-in model or a spec file, a slave address, timeouts and
//! silences) and what to poll, and is checked as a whole with located diagnostics before
//! anything is opened. [`Bus::start`] then runs one task per line; each line takes its due
//! polls earliest deadline first (see [`schedule`](mod@schedule)), keeps t3.5 of its format (or a
//! device's extra silence) between frames, gives up on a device that keeps failing and probes
//! it with backoff, and sends what it read as [`Event`]s: typed, timestamped samples in the
//! drivers' serde shapes, health changes and line statistics.
//!
//! The crate's README has a complete program (two P series heads and a CCS on one simulated
//! RS-485 line, with the dependencies it needs), compiled and run as a doctest of this crate;
//! it also holds the bus file's schema ([`file::SCHEMA`]).
#![forbid(unsafe_code)]

mod bus;
mod event;
pub mod file;
mod follow;
mod gateway;
mod handle;
mod line;
mod link;
mod measurement;
mod measurement_unit;
mod measuring;
mod policy;
pub mod schedule;
mod source;
mod time;
mod trace;
mod turns;

pub use bus::{Bus, Running, StartError, DEFAULT_EVENT_CAPACITY};
pub use event::{
    rfc3339, DeviceId, ErrorCounts, Event, HealthEvent, LineStats, Sample, Writer, Written,
};
pub use file::{
    BusFile, DeviceConfig, GatewayMoveError, LineConfig, LinePickError, LoadError, OutputSettings,
    Outputs, PollConfig, Port, ReadOutputs, Rejected, Writable,
};
pub use follow::Follower;
pub use gateway::GatewayCounts;
pub use handle::{Buffered, Handle, JobError, AUDIT_TARGET};
pub use measurement::{InputValue, MeasurementEvent};
/// The models a bus file may name: one catalogue, shared with the `optobus` tool.
pub use optobus_spec::Catalogue;
pub use optobus_transport::Stream;
pub use policy::{Policy, Refusal, RefusalKind};
pub use schedule::Health;
pub use source::{Source, NETWORK_QUEUE};
pub use trace::{Direction, Frame, FRAMES_KEPT};
pub use turns::NETWORK_SHARE;

/// The README's examples, compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
struct ReadmeExamples;
