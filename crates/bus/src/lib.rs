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
//! Two P series heads and a CCS on one simulated RS-485 line:
//!
//! ```
//! use optobus_bus::{Bus, BusFile, Catalogue, Event};
//!
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
//! let text = "
//! lines:
//!   - name: rs485
//!     simulated: true
//!     baud: 115200
//!     any_format: true
//! devices:
//!   - { name: top, model: p-series, slave: 1, poll: [{ read: measurements, every: 50ms }] }
//!   - { name: bottom, model: p-series, slave: 2, poll: [{ read: measurements, every: 50ms }] }
//!   - { name: confocal, model: ccs, slave: 3, poll: [{ read: measurements }] }
//! ";
//! let file = BusFile::parse("demo.yaml", text, ".".as_ref(), &catalogue)?;
//! let bus = Bus::new(file);
//! let mut events = bus.subscribe();
//! let running = bus.start()?;
//! let mut seen = std::collections::BTreeSet::new();
//! while seen.len() < 3 {
//!     if let Event::Sample(sample) = events.recv().await? {
//!         println!("{} {} = {}", sample.source.device, sample.register.name, sample.value);
//!         seen.insert(sample.source.device.to_string());
//!     }
//! }
//! running.stop();
//! # Ok(())
//! # }
//! ```
#![forbid(unsafe_code)]

mod bus;
mod catalogue;
mod event;
pub mod file;
mod gateway;
mod handle;
mod line;
mod link;
mod policy;
pub mod schedule;
mod trace;

pub use bus::{Bus, Running, StartError, DEFAULT_EVENT_CAPACITY};
pub use catalogue::Catalogue;
pub use event::{rfc3339, DeviceId, ErrorCounts, Event, HealthEvent, LineStats, Sample};
pub use file::{
    BusFile, DeviceConfig, HttpConfig, LineConfig, LoadError, MetricsConfig, MqttConfig, Outputs,
    PollConfig, Port, Rejected, SecretSource, StateEvery, Writable,
};
pub use gateway::GatewayCounts;
pub use handle::{Buffered, Handle, JobError, Source, NETWORK_QUEUE};
pub use line::NETWORK_SHARE;
pub use link::Stream;
pub use policy::{Policy, Refusal, RefusalKind};
pub use schedule::Health;
pub use trace::{Direction, Frame, FRAMES_KEPT};
